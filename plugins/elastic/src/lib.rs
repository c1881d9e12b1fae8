//! Elastic materials for mpm: linear elastic (small strain, for verification), compressible
//! neo-Hookean and fixed-corotated (hyperelastic, for large deformation).

mod fixed_corotated;
mod linear_elastic;
mod neo_hookean;

pub use fixed_corotated::FixedCorotated;
pub use linear_elastic::LinearElastic;
pub use neo_hookean::NeoHookean;

use mpm_core::material::Material;
use mpm_core::plugin::{MaterialFactory, Plugin, TypedMaterialFactory, check_elastic_constants};
use mpm_core::scene::Issue;
use schemars::JsonSchema;
use serde::Deserialize;
use std::sync::Arc;

/// Parameters shared by the three elastic laws.
#[derive(Clone, Copy, Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ElasticParameters {
    /// Mass density, kg/m³.
    pub density: f64,
    /// Young's modulus, Pa.
    pub youngs_modulus: f64,
    /// Poisson's ratio, in (-1, 0.5).
    pub poisson_ratio: f64,
}

impl ElasticParameters {
    /// Checks the constants, with JSON paths below `path`.
    pub fn check(&self, path: &str) -> Result<(), Vec<Issue>> {
        let issues =
            check_elastic_constants(path, self.density, self.youngs_modulus, self.poisson_ratio);
        if issues.is_empty() {
            Ok(())
        } else {
            Err(issues)
        }
    }

    /// P-wave speed sqrt((λ + 2μ)/ρ) in the reference state.
    pub fn wave_speed(&self) -> f64 {
        let (lambda, mu) =
            mpm_core::material::lame_parameters(self.youngs_modulus, self.poisson_ratio);
        ((lambda + 2.0 * mu) / self.density).sqrt()
    }
}

/// The elastic plugin.
pub struct ElasticPlugin;

fn build_linear(p: ElasticParameters, path: &str) -> Result<Arc<dyn Material>, Vec<Issue>> {
    p.check(path)?;
    Ok(Arc::new(LinearElastic::new(p)))
}

fn build_neo_hookean(p: ElasticParameters, path: &str) -> Result<Arc<dyn Material>, Vec<Issue>> {
    p.check(path)?;
    Ok(Arc::new(NeoHookean::new(p)))
}

fn build_corotated(p: ElasticParameters, path: &str) -> Result<Arc<dyn Material>, Vec<Issue>> {
    p.check(path)?;
    Ok(Arc::new(FixedCorotated::new(p)))
}

impl Plugin for ElasticPlugin {
    fn name(&self) -> &'static str {
        "elastic"
    }

    fn description(&self) -> &'static str {
        "linear elastic (small strain), compressible neo-Hookean and fixed-corotated solids"
    }

    fn materials(&self) -> Vec<Box<dyn MaterialFactory>> {
        vec![
            Box::new(TypedMaterialFactory::new("linear_elastic", build_linear)),
            Box::new(TypedMaterialFactory::new("neo_hookean", build_neo_hookean)),
            Box::new(TypedMaterialFactory::new(
                "fixed_corotated",
                build_corotated,
            )),
        ]
    }
}

#[cfg(test)]
mod tests;
