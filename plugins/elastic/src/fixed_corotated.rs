//! Fixed-corotated hyperelasticity (Stomakhin et al. 2012):
//! ψ = μ ‖F − R‖² + λ/2 (J − 1)², P = 2μ (F − R) + λ (J − 1) J F⁻ᵀ, with R the rotation of
//! the polar decomposition F = R S.

use crate::ElasticParameters;
use mpm_core::material::{
    BatchStats, ConstitutiveLaw, StressBatch, lame_parameters, out_of_plane_stretch,
};
use mpm_core::math::{Matrix, determinant, polar_rotation};

/// Fixed-corotated solid (plane strain in 2D).
#[derive(Clone, Debug)]
pub struct FixedCorotated {
    params: ElasticParameters,
    lambda: f64,
    mu: f64,
}

impl FixedCorotated {
    /// From density, Young's modulus and Poisson's ratio.
    pub fn new(params: ElasticParameters) -> Self {
        let (lambda, mu) = lame_parameters(params.youngs_modulus, params.poisson_ratio);
        Self { params, lambda, mu }
    }
}

impl ConstitutiveLaw for FixedCorotated {
    fn density(&self) -> f64 {
        self.params.density
    }

    /// 1 + ν: the plane-strain expansion of an isotropic elastic solid.
    fn plane_strain_expansion(&self) -> f64 {
        1.0 + self.params.poisson_ratio
    }

    /// In 2D, F is [[F, 0], [0, s]] with s the stretch across the plane, whose rotation is
    /// [[R, 0], [0, 1]].
    fn plane_strain_stress(&self) -> bool {
        true
    }

    fn update_stress<const D: usize>(&self, batch: StressBatch<'_, D>) -> BatchStats {
        let identity = Matrix::<D>::identity();
        let (lambda, mu) = (self.lambda, self.mu);
        let mut energy = 0.0;
        let mut max_j = 1.0f64;
        for (k, ((f, stress), v0)) in batch
            .deformation_gradient
            .iter()
            .zip(batch.stress.iter_mut())
            .zip(batch.volume0)
            .enumerate()
        {
            let s = out_of_plane_stretch(batch.out_of_plane_stretch, k);
            let j = determinant(f) * s;
            let r = polar_rotation(f);
            let fr = f - r;
            // σ = (1/J) P Fᵀ = (1/J) [2μ (F − R) Fᵀ + λ (J − 1) J I]
            *stress = (fr * f.transpose() * (2.0 * mu) + identity * (lambda * (j - 1.0) * j)) / j;
            if let Some(out) = batch.out_of_plane_stress.get_mut(k) {
                *out = (2.0 * mu * (s - 1.0) * s + lambda * (j - 1.0) * j) / j;
            }
            energy += v0
                * (mu * (fr.norm_squared() + (s - 1.0) * (s - 1.0))
                    + 0.5 * lambda * (j - 1.0) * (j - 1.0));
            max_j = max_j.max(j);
        }
        // The volumetric tangent λ J² grows with expansion; stay conservative.
        let modulus = lambda * max_j * max_j + 2.0 * mu;
        BatchStats {
            strain_energy: energy,
            max_wave_speed: (modulus / self.params.density).sqrt(),
        }
    }
}
