//! The projection onto the latent coordinates: q and q̇ fitted by least squares through
//! the Jacobian ∂g/∂q (Gauss–Newton for the neural map), and the normal equations and
//! their regularised Cholesky solve.

use super::setup::Reduced;
use crate::RomError;
use mpm_core::kernels::Kernel;
use mpm_core::material::Material;
use mpm_core::solver::DimensionDispatch;

impl<const D: usize, K: Kernel> Reduced<'_, D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// Initial q (the model's undeformed code, refined onto the scene's positions at the
    /// samples) and q̇ (least squares of the initial velocities of every particle).
    pub(super) fn initialise(&mut self) -> Result<(), RomError> {
        for (k, &p) in self.samples.iter().enumerate() {
            let x = self.sim.particles.position[p as usize];
            self.sample_target[k * D..(k + 1) * D].copy_from_slice(x.as_slice());
        }
        self.project_positions()?;
        let n = self.all.len();
        let l = self.latent;
        // Once per run: the Jacobian of every particle, to fit q̇ to the initial velocities.
        let mut jacobians = vec![0.0; n * D * l];
        self.map.jacobians(&self.q, &self.all, &mut jacobians)?;
        self.normal.fill(0.0);
        self.rhs.fill(0.0);
        for p in 0..n {
            let j = &jacobians[p * D * l..(p + 1) * D * l];
            let v = self.sim.particles.velocity[p];
            accumulate_normal(j, v.as_slice(), D, l, &mut self.normal, &mut self.rhs);
        }
        solve_regularised(&mut self.normal, &mut self.rhs, l);
        self.q_rate.copy_from_slice(&self.rhs);
        Ok(())
    }

    /// Gauss–Newton fit of q to `sample_target` (one iteration is exact for the linear map).
    pub(super) fn project_positions(&mut self) -> Result<(), RomError> {
        let l = self.latent;
        self.q_next.copy_from_slice(&self.q);
        let iterations = if self.linear { 1 } else { self.iterations };
        for _ in 0..iterations {
            self.map
                .positions(&self.q_next, &self.samples, &mut self.sample_x)?;
            self.map
                .jacobians(&self.q_next, &self.samples, &mut self.sample_jac)?;
            self.normal.fill(0.0);
            self.rhs.fill(0.0);
            let mut residual = [0.0; 3];
            for k in 0..self.samples.len() {
                for (d, r) in residual.iter_mut().take(D).enumerate() {
                    *r = self.sample_target[k * D + d] - self.sample_x[k * D + d];
                }
                let j = &self.sample_jac[k * D * l..(k + 1) * D * l];
                accumulate_normal(j, &residual[..D], D, l, &mut self.normal, &mut self.rhs);
            }
            solve_regularised(&mut self.normal, &mut self.rhs, l);
            for (q, dq) in self.q_next.iter_mut().zip(&self.rhs) {
                *q += dq;
            }
        }
        if self.q_next.iter().any(|v| !v.is_finite()) {
            return Err(RomError::Option(
                "the projection onto the map failed (q not finite)".into(),
            ));
        }
        self.q.copy_from_slice(&self.q_next);
        Ok(())
    }

    /// Least-squares q̇ from the sampled particles' velocities `sample_v`.
    pub(super) fn project_velocities(&mut self) -> Result<(), RomError> {
        let l = self.latent;
        if !self.linear {
            self.map
                .jacobians(&self.q, &self.samples, &mut self.sample_jac)?;
        }
        self.normal.fill(0.0);
        self.rhs.fill(0.0);
        for k in 0..self.samples.len() {
            let j = &self.sample_jac[k * D * l..(k + 1) * D * l];
            let v = &self.sample_v[k * D..(k + 1) * D];
            accumulate_normal(j, v, D, l, &mut self.normal, &mut self.rhs);
        }
        solve_regularised(&mut self.normal, &mut self.rhs, l);
        self.q_rate.copy_from_slice(&self.rhs);
        Ok(())
    }
}

/// Adds `Jᵀ J` and `Jᵀ r` of one point (J row-major `dim × latent`) to the normal equations.
#[inline]
fn accumulate_normal(
    j: &[f64],
    r: &[f64],
    dim: usize,
    latent: usize,
    normal: &mut [f64],
    rhs: &mut [f64],
) {
    for d in 0..dim {
        let row = &j[d * latent..(d + 1) * latent];
        for a in 0..latent {
            rhs[a] += row[a] * r[d];
            for b in 0..latent {
                normal[a * latent + b] += row[a] * row[b];
            }
        }
    }
}

/// Solves `(A + εI) x = b` in place (x in `b`) for a symmetric positive semi-definite `A`,
/// ε a tiny multiple of its mean diagonal so near-singular systems stay solvable.
fn solve_regularised(a: &mut [f64], b: &mut [f64], n: usize) {
    let mean = (0..n).map(|i| a[i * n + i]).sum::<f64>() / n as f64;
    let eps = 1e-12 * mean.max(1e-300);
    for i in 0..n {
        a[i * n + i] += eps;
    }
    // Cholesky: A = L Lᵀ, L stored in the lower triangle.
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        let d = d.max(eps).sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= a[i * n + k] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[k * n + i] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regularised_solve_matches_a_known_solution() {
        let mut a = vec![4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let x = [1.0, -2.0, 0.5];
        let mut b: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| a[i * 3 + j] * x[j]).sum())
            .collect();
        solve_regularised(&mut a, &mut b, 3);
        for (got, want) in b.iter().zip(x) {
            assert!((got - want).abs() < 1e-10, "{b:?}");
        }
    }
}
