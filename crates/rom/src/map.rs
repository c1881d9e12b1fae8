//! The reduced deformation map x = g(X, q) as the stepper sees it: bound once to a fixed
//! set of reference points, then evaluated for many q. Both the linear (POD) and the neural
//! map implement it, so the stepper is the same for both.

use crate::RomError;

/// A deformation map x = g(X, q) with `latent` generalised coordinates q.
pub trait ReducedMap: Send + Sync {
    /// Spatial dimension (2 or 3).
    fn dimension(&self) -> usize;
    /// Number of generalised coordinates.
    fn latent(&self) -> usize;
    /// Prepares evaluation at fixed reference points `reference` (`dimension` numbers per
    /// point), so per-step evaluation can reuse whatever depends on X only.
    fn bind(&self, reference: &[f64]) -> Result<Box<dyn PointMap + '_>, RomError>;
}

/// A [`ReducedMap`] bound to fixed reference points. `which` lists point indices into the
/// bound set; outputs hold one block per listed point, in that order.
pub trait PointMap {
    /// Number of bound points.
    fn len(&self) -> usize;
    /// Whether no point is bound.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Positions x = g(X, q): `dimension` numbers per point.
    fn positions(&mut self, q: &[f64], which: &[u32], out: &mut [f64]) -> Result<(), RomError>;
    /// Deformation gradients F = ∂g/∂X, row-major (`F[i][j] = ∂x_i/∂X_j`).
    fn gradients(&mut self, q: &[f64], which: &[u32], out: &mut [f64]) -> Result<(), RomError>;
    /// Jacobians ∂g/∂q, row-major `[i][k] = ∂x_i/∂q_k` (`dimension × latent` per point).
    fn jacobians(&mut self, q: &[f64], which: &[u32], out: &mut [f64]) -> Result<(), RomError>;
    /// Velocities dx/dt = ∂g/∂q · q̇: `dimension` numbers per point. The default goes
    /// through [`PointMap::jacobians`].
    fn velocities(
        &mut self,
        q: &[f64],
        q_rate: &[f64],
        which: &[u32],
        out: &mut [f64],
    ) -> Result<(), RomError> {
        let latent = q_rate.len();
        let dim = out.len() / which.len().max(1);
        let mut jacobians = vec![0.0; which.len() * dim * latent];
        self.jacobians(q, which, &mut jacobians)?;
        for (o, j) in out
            .chunks_exact_mut(dim)
            .zip(jacobians.chunks_exact(dim * latent))
        {
            for (i, v) in o.iter_mut().enumerate() {
                *v = (0..latent).map(|m| j[i * latent + m] * q_rate[m]).sum();
            }
        }
        Ok(())
    }
    /// Rates of the deformation gradient, dF/dt = Σ_k ∂F/∂q_k · q̇_k, row-major. The
    /// default takes a central difference of [`PointMap::gradients`] along q̇.
    fn gradient_rates(
        &mut self,
        q: &[f64],
        q_rate: &[f64],
        which: &[u32],
        out: &mut [f64],
    ) -> Result<(), RomError> {
        let norm = q_rate.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm == 0.0 {
            out.fill(0.0);
            return Ok(());
        }
        let scale = q.iter().map(|v| v * v).sum::<f64>().sqrt().max(1.0);
        let h = 1e-5 * scale / norm;
        let plus: Vec<f64> = q.iter().zip(q_rate).map(|(a, b)| a + h * b).collect();
        let minus: Vec<f64> = q.iter().zip(q_rate).map(|(a, b)| a - h * b).collect();
        let mut back = vec![0.0; out.len()];
        self.gradients(&plus, which, out)?;
        self.gradients(&minus, which, &mut back)?;
        for (o, b) in out.iter_mut().zip(&back) {
            *o = (*o - b) / (2.0 * h);
        }
        Ok(())
    }
}
