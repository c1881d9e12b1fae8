//! F-bar anti-locking for the implicit mode (`solver.anti_locking: "fbar"`), after de Souza
//! Neto, Perić, Dutko & Owen (1996). Particles of one material whose stencils start at the
//! same grid node share every node of their stencils: a *patch* (with 2 particles per cell
//! and direction, the 2^D particles of one cell-sized box). A patch never mixes materials:
//! averaging a die's volume change with its underfill's would stiffen the one and soften the
//! other at every interface. Within a patch, each particle's volume change of
//! the step, J_p = det A_p with A_p = I + ∇Δu_p, is replaced by the patch's volume-weighted
//! mean J̄ = Σ_q Vₙ_q J_q / Σ_q Vₙ_q: the law sees F̄_p = (J̄/J_p)^(1/D) A_p Fₙ. That leaves
//! one volume constraint per patch (about one per node) instead of one per particle, so a
//! body with ν → 1/2, or a liquid, bends and flows instead of locking.
//!
//! The internal force keeps the particle's own cofactor of A_p (the standard, non-symmetric
//! F-bar: Σ_p Vₙ σ(F̄_p) cof(A_p) ∇w), and the tangent is its exact derivative: along a
//! direction with gradient δA_p, δF̄_p = s_p (δA_p + c_p A_p) Fₙ with s_p = (J̄/J_p)^(1/D) and
//! c_p = (δJ̄/J̄ − δJ_p/J_p)/D, δJ_p = cof(A_p) : δA_p. GMRES takes the non-symmetry.
//!
//! The averaging is over the increment (Fₙ keeps what earlier steps averaged), as the
//! explicit mode's `volume_averaging.rs` does, so it does not compound from step to step.

use super::super::parallel::{SharedSlice, chunk_count, chunk_range};
use crate::math::{Matrix, cofactor, determinant};
use crate::physics::Interpolation;
use rayon::prelude::*;

/// Patch membership and the averaged volume changes of the last trial increment; sized once
/// per step and reused (nothing is allocated per iteration once the sizes are reached).
#[derive(Default)]
pub(super) struct PatchAverage {
    /// Each particle's patch: (the unknown of its stencil's first node) × groups + its
    /// material group.
    patch: Vec<u32>,
    /// Σ Vₙ per patch.
    weight: Vec<f64>,
    /// Per-patch sums (scratch).
    sum: Vec<f64>,
    /// J_p and J̄ of each particle at the last [`PatchAverage::average`].
    local: Vec<f64>,
    bar: Vec<f64>,
    /// δJ_p of each particle along the last direction (scratch).
    change: Vec<f64>,
}

impl PatchAverage {
    /// Sets the patches of this step's stencils; `unknowns` is the number of grid nodes with
    /// unknowns, `volume` the particles' volume at the start of the step, `groups` the
    /// particle ranges of the material groups (covering every particle, in order).
    pub(super) fn prepare<const D: usize>(
        &mut self,
        interp: &Interpolation<D>,
        entry_dof: &[u32],
        volume: &[f64],
        unknowns: usize,
        groups: impl ExactSizeIterator<Item = std::ops::Range<usize>>,
    ) {
        let count = groups.len().max(1);
        self.patch.clear();
        for (g, range) in groups.enumerate() {
            self.patch
                .extend(range.map(|p| entry_dof[p * interp.stencil] * count as u32 + g as u32));
        }
        let n = volume.len();
        debug_assert_eq!(self.patch.len(), n);
        let patches = unknowns * count;
        self.weight.clear();
        self.weight.resize(patches, 0.0);
        for (&k, &v) in self.patch.iter().zip(volume) {
            self.weight[k as usize] += v;
        }
        self.sum.clear();
        self.sum.resize(patches, 0.0);
        self.local.clear();
        self.local.resize(n, 1.0);
        self.bar.clear();
        self.bar.resize(n, 1.0);
        self.change.clear();
        self.change.resize(n, 0.0);
    }

    /// The patch of particle `p` (the preconditioner groups its volumetric block by it).
    #[inline]
    pub(super) fn patch(&self, p: usize) -> u32 {
        self.patch[p]
    }

    /// Averages the volume changes of the increment gradients `grad` over the patches.
    pub(super) fn average<const D: usize>(&mut self, grad: &[Matrix<D>], volume: &[f64]) {
        let identity = Matrix::<D>::identity();
        self.local
            .par_iter_mut()
            .zip(grad.par_iter())
            .for_each(|(j, g)| *j = determinant(&(identity + g)));
        self.patch_mean(volume, Which::Local);
    }

    /// The factor s_p = (J̄/J_p)^(1/D) that turns particle `p`'s A_p into Ā_p (1 where a
    /// volume change is not positive: the evaluation is then invalid anyway).
    #[inline]
    pub(super) fn scale<const D: usize>(&self, p: usize) -> f64 {
        let (j, bar) = (self.local[p], self.bar[p]);
        if j > 0.0 && bar > 0.0 {
            (bar / j).powf(1.0 / D as f64)
        } else {
            1.0
        }
    }

    /// Writes δĀ_p = s_p (δA_p + c_p A_p) for every particle into `out`, from the iterate's
    /// increment gradients `grad` (as last averaged) and the direction's gradients `dgrad`.
    pub(super) fn direction<const D: usize>(
        &mut self,
        grad: &[Matrix<D>],
        dgrad: &[Matrix<D>],
        volume: &[f64],
        out: &mut [Matrix<D>],
    ) {
        let identity = Matrix::<D>::identity();
        self.change
            .par_iter_mut()
            .zip(grad.par_iter().zip(dgrad.par_iter()))
            .for_each(|(dj, (g, dg))| *dj = cofactor(&(identity + g)).component_mul(dg).sum());
        self.patch_mean(volume, Which::Change);
        let n = grad.len();
        let out_slice = SharedSlice::new(out);
        (0..chunk_count(n)).into_par_iter().for_each(|chunk| {
            for p in chunk_range(chunk, n) {
                let a = identity + grad[p];
                let (j, bar) = (self.local[p], self.bar[p]);
                let value = if j > 0.0 && bar > 0.0 {
                    // `sum` holds δJ̄ per patch after `patch_mean`.
                    let bar_change = self.sum[self.patch[p] as usize];
                    let c = (bar_change / bar - self.change[p] / j) / D as f64;
                    (dgrad[p] + a * c) * self.scale::<D>(p)
                } else {
                    dgrad[p]
                };
                // SAFETY: chunks are disjoint particle ranges.
                unsafe { *out_slice.get(p) = value };
            }
        });
    }

    /// Volume-weighted patch means: of J_p into `bar` (per particle), or of δJ_p into `sum`
    /// (per patch).
    fn patch_mean(&mut self, volume: &[f64], which: Which) {
        self.sum.fill(0.0);
        let values = match which {
            Which::Local => &self.local,
            Which::Change => &self.change,
        };
        for ((&k, &v), &x) in self.patch.iter().zip(volume).zip(values) {
            self.sum[k as usize] += v * x;
        }
        for (s, &w) in self.sum.iter_mut().zip(&self.weight) {
            if w > 0.0 {
                *s /= w;
            }
        }
        if let Which::Local = which {
            for (b, &k) in self.bar.iter_mut().zip(&self.patch) {
                *b = self.sum[k as usize];
            }
        }
    }
}

/// Which per-particle value [`PatchAverage::patch_mean`] averages.
#[derive(Clone, Copy)]
enum Which {
    Local,
    Change,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two particles in one patch and one alone: the averaged J of the pair is their
    /// volume-weighted mean, the lone particle keeps its own, and the direction matches a
    /// central difference of Ā_p = s_p A_p.
    #[test]
    fn patch_mean_and_its_derivative_match_differences() {
        let interp = Interpolation::<2> {
            stencil: 1,
            node: vec![0, 0, 1],
            weight: vec![1.0; 3],
            gradient: vec![Default::default(); 3],
            ..Interpolation::default()
        };
        let entry_dof = [0u32, 0, 1];
        let volume = [1.0, 3.0, 2.0];
        let grad = [
            Matrix::<2>::new(0.01, 0.002, -0.003, 0.02),
            Matrix::<2>::new(-0.02, 0.001, 0.004, 0.005),
            Matrix::<2>::new(0.03, 0.0, 0.0, -0.01),
        ];
        let mut avg = PatchAverage::default();
        avg.prepare(&interp, &entry_dof, &volume, 2, std::iter::once(0..3));
        avg.average(&grad, &volume);
        let j: Vec<f64> = grad
            .iter()
            .map(|g| determinant(&(Matrix::<2>::identity() + g)))
            .collect();
        let pair = (j[0] + 3.0 * j[1]) / 4.0;
        assert!((avg.bar[0] - pair).abs() < 1e-15 && (avg.bar[1] - pair).abs() < 1e-15);
        assert!((avg.scale::<2>(2) - 1.0).abs() < 1e-15);
        // Split the pair into two materials: each keeps its own J.
        let mut split = PatchAverage::default();
        split.prepare(&interp, &entry_dof, &volume, 2, [0..1, 1..3].into_iter());
        split.average(&grad, &volume);
        assert!((split.bar[0] - j[0]).abs() < 1e-15 && (split.bar[1] - j[1]).abs() < 1e-15);
        let dgrad = [
            Matrix::<2>::new(0.3, -0.1, 0.2, 0.5),
            Matrix::<2>::new(-0.4, 0.2, 0.1, 0.3),
            Matrix::<2>::new(0.1, 0.1, -0.2, 0.2),
        ];
        let mut out = [Matrix::<2>::zeros(); 3];
        avg.direction(&grad, &dgrad, &volume, &mut out);
        let h = 1e-6;
        let abar = |sign: f64| -> Vec<Matrix<2>> {
            let g: Vec<Matrix<2>> = grad
                .iter()
                .zip(&dgrad)
                .map(|(g, d)| g + d * (sign * h))
                .collect();
            let mut a = PatchAverage::default();
            a.prepare(&interp, &entry_dof, &volume, 2, std::iter::once(0..3));
            a.average(&g, &volume);
            (0..3)
                .map(|p| (Matrix::<2>::identity() + g[p]) * a.scale::<2>(p))
                .collect()
        };
        let (plus, minus) = (abar(1.0), abar(-1.0));
        for p in 0..3 {
            let difference = (plus[p] - minus[p]) / (2.0 * h);
            assert!(
                (difference - out[p]).norm() < 1e-8,
                "particle {p}: {difference} against {}",
                out[p]
            );
        }
    }
}
