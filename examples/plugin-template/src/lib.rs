//! A minimal mpm plugin to copy: a Kelvin–Voigt viscoelastic solid,
//! σ = λ tr(ε) I + 2 μ ε + 2 η sym(L), with ε the small strain and L the velocity gradient.
//!
//! Everything a plugin needs is here: a parameter struct (serde + schemars gives JSON-path
//! errors and a schema), checks that name the offending field, a [`ConstitutiveLaw`] that
//! updates a whole batch of particles per call, a reference solution that verifies it
//! (`reference.rs`), and a [`Plugin`] value to register.

mod reference;

use mpm_core::material::{BatchStats, ConstitutiveLaw, Material, StressBatch, lame_parameters};
use mpm_core::math::{Matrix, trace};
use mpm_core::plugin::{MaterialFactory, Plugin, TypedMaterialFactory, check_elastic_constants};
use mpm_core::reference::ReferenceFactory;
use mpm_core::scene::Issue;
use schemars::JsonSchema;
use serde::Deserialize;
use std::sync::Arc;

/// Scene section of a `kelvin_voigt` material.
#[derive(Clone, Copy, Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct KelvinVoigtParameters {
    /// Mass density, kg/m³.
    pub density: f64,
    /// Young's modulus of the spring, Pa.
    pub youngs_modulus: f64,
    /// Poisson's ratio of the spring.
    pub poisson_ratio: f64,
    /// Shear viscosity of the dashpot, Pa·s.
    pub viscosity: f64,
}

/// The Kelvin–Voigt law.
#[derive(Clone, Debug)]
pub struct KelvinVoigt {
    params: KelvinVoigtParameters,
    lambda: f64,
    mu: f64,
}

impl KelvinVoigt {
    /// From checked parameters.
    pub fn new(params: KelvinVoigtParameters) -> Self {
        let (lambda, mu) = lame_parameters(params.youngs_modulus, params.poisson_ratio);
        Self { params, lambda, mu }
    }
}

impl ConstitutiveLaw for KelvinVoigt {
    fn density(&self) -> f64 {
        self.params.density
    }

    // The dashpot needs the velocity gradient; the core allocates it only because we ask.
    fn needs_velocity_gradient(&self) -> bool {
        true
    }

    fn update_stress<const D: usize>(&self, batch: StressBatch<'_, D>) -> BatchStats {
        let identity = Matrix::<D>::identity();
        let mut energy = 0.0;
        for (p, stress) in batch.stress.iter_mut().enumerate() {
            let f = &batch.deformation_gradient[p];
            let strain = (f + f.transpose()) * 0.5 - identity;
            let tr = trace(&strain);
            let l = &batch.velocity_gradient[p];
            let rate = (l + l.transpose()) * 0.5;
            *stress = identity * (self.lambda * tr)
                + strain * (2.0 * self.mu)
                + rate * (2.0 * self.params.viscosity);
            energy +=
                batch.volume0[p] * (0.5 * self.lambda * tr * tr + self.mu * strain.norm_squared());
        }
        BatchStats {
            strain_energy: energy,
            max_wave_speed: ((self.lambda + 2.0 * self.mu) / self.params.density).sqrt(),
        }
    }
}

fn build(p: KelvinVoigtParameters, path: &str) -> Result<Arc<dyn Material>, Vec<Issue>> {
    let mut issues = check_elastic_constants(path, p.density, p.youngs_modulus, p.poisson_ratio);
    if !(p.viscosity.is_finite() && p.viscosity >= 0.0) {
        issues.push(Issue::new(
            format!("{path}.viscosity"),
            "must be a finite number >= 0",
        ));
    }
    if issues.is_empty() {
        Ok(Arc::new(KelvinVoigt::new(p)))
    } else {
        Err(issues)
    }
}

/// The plugin value to register: `registry.register(Box::new(TemplatePlugin))`.
pub struct TemplatePlugin;

impl Plugin for TemplatePlugin {
    fn name(&self) -> &'static str {
        "template"
    }

    fn description(&self) -> &'static str {
        "example plugin: Kelvin-Voigt viscoelastic solid"
    }

    fn materials(&self) -> Vec<Box<dyn MaterialFactory>> {
        vec![Box::new(TypedMaterialFactory::new("kelvin_voigt", build))]
    }

    // The reference that verifies the material, registered like the material itself.
    fn references(&self) -> Vec<Box<dyn ReferenceFactory>> {
        vec![reference::factory()]
    }
}
