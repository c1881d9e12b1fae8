//! Compressible neo-Hookean hyperelasticity:
//! ψ = μ/2 (tr(FᵀF) − d) − μ ln J + λ/2 (ln J)², σ = μ/J (F Fᵀ − I) + λ ln J / J · I.

use crate::ElasticParameters;
use mpm_core::material::{BatchStats, ConstitutiveLaw, StressBatch, lame_parameters};
use mpm_core::math::{Matrix, determinant};

/// Compressible neo-Hookean solid (plane strain in 2D).
#[derive(Clone, Debug)]
pub struct NeoHookean {
    params: ElasticParameters,
    lambda: f64,
    mu: f64,
}

impl NeoHookean {
    /// From density, Young's modulus and Poisson's ratio.
    pub fn new(params: ElasticParameters) -> Self {
        let (lambda, mu) = lame_parameters(params.youngs_modulus, params.poisson_ratio);
        Self { params, lambda, mu }
    }
}

impl ConstitutiveLaw for NeoHookean {
    fn density(&self) -> f64 {
        self.params.density
    }

    fn update_stress<const D: usize>(&self, batch: StressBatch<'_, D>) -> BatchStats {
        let identity = Matrix::<D>::identity();
        let (lambda, mu) = (self.lambda, self.mu);
        let mut energy = 0.0;
        let mut min_j = f64::INFINITY;
        for ((f, stress), v0) in batch
            .deformation_gradient
            .iter()
            .zip(batch.stress.iter_mut())
            .zip(batch.volume0)
        {
            let j = determinant(f);
            let log_j = j.ln();
            let b = f * f.transpose();
            *stress = (b - identity) * (mu / j) + identity * (lambda * log_j / j);
            let tr_c = f.norm_squared();
            energy +=
                v0 * (0.5 * mu * (tr_c - D as f64) - mu * log_j + 0.5 * lambda * log_j * log_j);
            min_j = min_j.min(j);
        }
        // Tangent stiffness grows under compression: (λ + 2μ − 2λ ln J) / J per unit
        // reference density; take the worst particle of the batch.
        let modulus = if min_j.is_finite() && min_j > 0.0 {
            ((lambda + 2.0 * mu - 2.0 * lambda * min_j.ln().min(0.0)) / min_j)
                .max(lambda + 2.0 * mu)
        } else {
            lambda + 2.0 * mu
        };
        BatchStats {
            strain_energy: energy,
            max_wave_speed: (modulus / self.params.density).sqrt(),
        }
    }
}
