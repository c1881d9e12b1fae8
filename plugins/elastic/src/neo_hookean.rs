//! Compressible neo-Hookean hyperelasticity:
//! ψ = μ/2 (tr(FᵀF) − d) − μ ln J + λ/2 (ln J)², σ = μ/J (F Fᵀ − I) + λ ln J / J · I.

use crate::ElasticParameters;
use mpm_core::material::{
    BatchStats, ConstitutiveLaw, StressBatch, TangentBatch, lame_parameters, out_of_plane_stretch,
};
use mpm_core::math::{Matrix, cofactor, determinant};

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

    /// 1 + ν: the plane-strain expansion of an isotropic elastic solid.
    fn plane_strain_expansion(&self) -> f64 {
        1.0 + self.params.poisson_ratio
    }

    /// In 2D, F is [[F, 0], [0, s]] with s the stretch across the plane.
    fn plane_strain_stress(&self) -> bool {
        true
    }

    fn update_stress<const D: usize>(&self, batch: StressBatch<'_, D>) -> BatchStats {
        let identity = Matrix::<D>::identity();
        let (lambda, mu) = (self.lambda, self.mu);
        let mut energy = 0.0;
        let mut min_j = f64::INFINITY;
        for (k, ((f, stress), v0)) in batch
            .deformation_gradient
            .iter()
            .zip(batch.stress.iter_mut())
            .zip(batch.volume0)
            .enumerate()
        {
            let s = out_of_plane_stretch(batch.out_of_plane_stretch, k);
            let j = determinant(f) * s;
            let log_j = j.ln();
            let b = f * f.transpose();
            *stress = (b - identity) * (mu / j) + identity * (lambda * log_j / j);
            if let Some(out) = batch.out_of_plane_stress.get_mut(k) {
                *out = (mu * (s * s - 1.0) + lambda * log_j) / j;
            }
            // tr(FᵀF) − d of the whole F: the plane's part and the stretch's.
            let tr_c = f.norm_squared() - D as f64 + (s * s - 1.0);
            energy += v0 * (0.5 * mu * tr_c - mu * log_j + 0.5 * lambda * log_j * log_j);
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

    fn has_stress_derivative(&self) -> bool {
        true
    }

    /// dσ = −t σ + μ/J (δF Fᵀ + F δFᵀ) + λ t / J · I with t = tr(F⁻¹ δF) = dJ / J (the
    /// stretch across the plane held).
    fn stress_derivative<const D: usize>(&self, batch: TangentBatch<'_, D>) {
        let identity = Matrix::<D>::identity();
        let (lambda, mu) = (self.lambda, self.mu);
        for (k, (((f, df), stress), out)) in batch
            .deformation_gradient
            .iter()
            .zip(batch.direction)
            .zip(batch.stress)
            .zip(batch.stress_change.iter_mut())
            .enumerate()
        {
            let j_plane = determinant(f);
            let t = cofactor(f).component_mul(df).sum() / j_plane;
            let j = j_plane * out_of_plane_stretch(batch.out_of_plane_stretch, k);
            let db = df * f.transpose() + f * df.transpose();
            *out = stress * (-t) + db * (mu / j) + identity * (lambda * t / j);
        }
    }
}
