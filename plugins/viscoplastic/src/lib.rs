//! Viscoplastic materials for mpm: Anand's law, one flow rule for creep and rate-dependent
//! plasticity with a single internal variable (the deformation resistance), the standard
//! model of solder joints in packaging, and an energy-based fatigue law on its inelastic
//! work per thermal cycle.

mod anand;
pub mod anand_reference;
mod fatigue;
mod tangent;

pub use anand::Anand;
pub use fatigue::{CrackGrowth, FatigueLaw};

use mpm_core::material::Material;
use mpm_core::plugin::{MaterialFactory, Plugin, TypedMaterialFactory, check_elastic_constants};
use mpm_core::scene::Issue;
use schemars::JsonSchema;
use serde::Deserialize;
use std::sync::Arc;

/// Scene section of an `anand` material. The symbols are those of Brown, Kim & Anand
/// (1989), "An internal variable constitutive model for hot working of metals".
#[derive(Clone, Copy, Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AnandParameters {
    /// Mass density, kg/m³.
    pub density: f64,
    /// Young's modulus, Pa.
    pub youngs_modulus: f64,
    /// Poisson's ratio, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// Temperature, K, where no thermal physics conducts one (default 298.15).
    #[serde(default = "room_temperature")]
    pub temperature: f64,
    /// A: pre-exponential factor of the flow rule, 1/s.
    pub pre_exponential: f64,
    /// Q/R: activation energy over the gas constant, K.
    pub activation_temperature: f64,
    /// ξ: stress multiplier (dimensionless).
    pub stress_multiplier: f64,
    /// m: strain-rate sensitivity of the stress (dimensionless, in (0, 1]).
    pub rate_sensitivity: f64,
    /// h₀: hardening constant, Pa.
    pub hardening: f64,
    /// a: exponent of the hardening's approach to saturation (dimensionless, > 0).
    pub hardening_exponent: f64,
    /// ŝ: coefficient of the saturated deformation resistance, Pa.
    pub saturation_coefficient: f64,
    /// n: strain-rate exponent of the saturated deformation resistance.
    pub saturation_exponent: f64,
    /// s₀: deformation resistance at the start, Pa.
    pub initial_resistance: f64,
    /// Cycles to crack initiation from the inelastic work per cycle; without it the stage
    /// figures give the work but no life.
    #[serde(default)]
    pub fatigue: Option<FatigueLaw>,
}

fn room_temperature() -> f64 {
    298.15
}

impl AnandParameters {
    /// Every problem with the constants, with JSON paths below `path`.
    pub fn check(&self, path: &str) -> Vec<Issue> {
        let mut issues =
            check_elastic_constants(path, self.density, self.youngs_modulus, self.poisson_ratio);
        let mut positive = |name: &str, value: f64| {
            if !(value.is_finite() && value > 0.0) {
                issues.push(Issue::new(
                    format!("{path}.{name}"),
                    format!("must be a finite number > 0 (got {value})"),
                ));
            }
        };
        positive("temperature", self.temperature);
        positive("pre_exponential", self.pre_exponential);
        positive("stress_multiplier", self.stress_multiplier);
        positive("rate_sensitivity", self.rate_sensitivity);
        positive("hardening_exponent", self.hardening_exponent);
        positive("saturation_coefficient", self.saturation_coefficient);
        positive("initial_resistance", self.initial_resistance);
        let mut at_least_zero = |name: &str, value: f64| {
            if !(value.is_finite() && value >= 0.0) {
                issues.push(Issue::new(
                    format!("{path}.{name}"),
                    format!("must be a finite number >= 0 (got {value})"),
                ));
            }
        };
        at_least_zero("activation_temperature", self.activation_temperature);
        at_least_zero("hardening", self.hardening);
        at_least_zero("saturation_exponent", self.saturation_exponent);
        if self.rate_sensitivity > 1.0 {
            issues.push(Issue::new(
                format!("{path}.rate_sensitivity"),
                format!(
                    "must lie in (0, 1] (got {}): the flow rule raises sinh to 1/m",
                    self.rate_sensitivity
                ),
            ));
        }
        if let Some(f) = &self.fatigue {
            issues.extend(f.check(&format!("{path}.fatigue")));
        }
        issues
    }
}

fn build(p: AnandParameters, path: &str) -> Result<Arc<dyn Material>, Vec<Issue>> {
    let issues = p.check(path);
    if issues.is_empty() {
        Ok(Arc::new(Anand::new(p)))
    } else {
        Err(issues)
    }
}

/// The viscoplastic plugin.
pub struct ViscoplasticPlugin;

impl Plugin for ViscoplasticPlugin {
    fn name(&self) -> &'static str {
        "viscoplastic"
    }

    fn description(&self) -> &'static str {
        "Anand viscoplasticity (solders: creep and rate-dependent plasticity) with an energy-based fatigue life"
    }

    fn materials(&self) -> Vec<Box<dyn MaterialFactory>> {
        vec![Box::new(TypedMaterialFactory::new("anand", build))]
    }
}

#[cfg(test)]
mod tests;
