//! Linear elasticity with the small-strain tensor ε = sym(F) − I: exact for verification
//! problems with small displacements, wrong under large rotations.

use crate::ElasticParameters;
use mpm_core::material::{
    BatchStats, ConstitutiveLaw, StressBatch, TangentBatch, lame_parameters, out_of_plane_stretch,
};
use mpm_core::math::{Matrix, trace};

/// σ = λ tr(ε) I + 2 μ ε.
#[derive(Clone, Debug)]
pub struct LinearElastic {
    params: ElasticParameters,
    lambda: f64,
    mu: f64,
}

impl LinearElastic {
    /// From density, Young's modulus and Poisson's ratio.
    pub fn new(params: ElasticParameters) -> Self {
        let (lambda, mu) = lame_parameters(params.youngs_modulus, params.poisson_ratio);
        Self { params, lambda, mu }
    }
}

impl ConstitutiveLaw for LinearElastic {
    fn density(&self) -> f64 {
        self.params.density
    }

    /// 1 + ν: the plane-strain expansion of an isotropic elastic solid.
    fn plane_strain_expansion(&self) -> f64 {
        1.0 + self.params.poisson_ratio
    }

    /// In 2D the strain across the plane is the stretch there less 1 (0 without a free
    /// strain across the plane).
    fn plane_strain_stress(&self) -> bool {
        true
    }

    fn update_stress<const D: usize>(&self, batch: StressBatch<'_, D>) -> BatchStats {
        let identity = Matrix::<D>::identity();
        let mut energy = 0.0;
        for (k, ((f, stress), v0)) in batch
            .deformation_gradient
            .iter()
            .zip(batch.stress.iter_mut())
            .zip(batch.volume0)
            .enumerate()
        {
            let strain = (f + f.transpose()) * 0.5 - identity;
            let zz = out_of_plane_stretch(batch.out_of_plane_stretch, k) - 1.0;
            let tr = trace(&strain) + zz;
            *stress = identity * (self.lambda * tr) + strain * (2.0 * self.mu);
            if let Some(out) = batch.out_of_plane_stress.get_mut(k) {
                *out = self.lambda * tr + 2.0 * self.mu * zz;
            }
            energy +=
                v0 * (0.5 * self.lambda * tr * tr + self.mu * (strain.norm_squared() + zz * zz));
        }
        BatchStats {
            strain_energy: energy,
            max_wave_speed: self.params.wave_speed(),
        }
    }

    fn has_stress_derivative(&self) -> bool {
        true
    }

    /// dσ = λ tr(dε) I + 2μ dε with dε = sym(δF): the law is linear in F.
    fn stress_derivative<const D: usize>(&self, batch: TangentBatch<'_, D>) {
        let identity = Matrix::<D>::identity();
        for (df, out) in batch.direction.iter().zip(batch.stress_change.iter_mut()) {
            let strain = (df + df.transpose()) * 0.5;
            *out = identity * (self.lambda * trace(&strain)) + strain * (2.0 * self.mu);
        }
    }
}
