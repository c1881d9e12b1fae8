//! Johnson–Cook plasticity and damage for mpm, for high-rate impact and ductile failure:
//! finite-strain J2 plasticity with a rate- and temperature-dependent flow stress, adiabatic
//! heating from plastic work, a linear or Mie–Grüneisen equation of state, and Johnson–Cook
//! damage after which a particle carries no tension and no shear.

mod damage;
mod equation_of_state;
mod flow_stress;
mod johnson_cook;
mod tangent;
mod taylor_bar;

pub use damage::{Damage, FailureMode};
pub use equation_of_state::EquationOfState;
pub use flow_stress::FlowStress;
pub use johnson_cook::JohnsonCook;

use mpm_core::material::Material;
use mpm_core::plugin::{MaterialFactory, Plugin, TypedMaterialFactory, check_elastic_constants};
use mpm_core::reference::ReferenceFactory;
use mpm_core::scene::Issue;
use schemars::JsonSchema;
use serde::Deserialize;
use std::sync::Arc;

/// Scene section of a `johnson_cook` material.
#[derive(Clone, Copy, Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct JohnsonCookParameters {
    /// Mass density, kg/m³.
    pub density: f64,
    /// Young's modulus, Pa (with Poisson's ratio it gives the shear modulus, and the bulk
    /// modulus of the linear equation of state).
    pub youngs_modulus: f64,
    /// Poisson's ratio, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// Specific heat, J/(kg·K), for heating by plastic work.
    pub specific_heat: f64,
    /// Taylor–Quinney factor: the share of plastic work that turns into heat (0 for
    /// isothermal, typically 0.9).
    #[serde(default = "default_taylor_quinney")]
    pub taylor_quinney: f64,
    /// Temperature at the start, K (default: the flow stress's room temperature).
    #[serde(default)]
    pub initial_temperature: Option<f64>,
    /// Johnson–Cook flow stress constants.
    pub flow_stress: FlowStress,
    /// Pressure response (default: linear, from Young's modulus and Poisson's ratio).
    #[serde(default)]
    pub equation_of_state: EquationOfState,
    /// Johnson–Cook damage and failure; without it particles never fail.
    #[serde(default)]
    pub damage: Option<Damage>,
}

fn default_taylor_quinney() -> f64 {
    0.9
}

impl JohnsonCookParameters {
    /// Starting temperature (see the field).
    pub fn initial_temperature(&self) -> f64 {
        self.initial_temperature
            .unwrap_or(self.flow_stress.room_temperature)
    }

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
        positive("specific_heat", self.specific_heat);
        if let EquationOfState::MieGruneisen {
            sound_speed,
            slope,
            gruneisen,
        } = self.equation_of_state
        {
            positive("equation_of_state.sound_speed", sound_speed);
            positive("equation_of_state.slope", slope);
            positive("equation_of_state.gruneisen", gruneisen);
        }
        if !(0.0..=1.0).contains(&self.taylor_quinney) {
            issues.push(Issue::new(
                format!("{path}.taylor_quinney"),
                format!("must lie in [0, 1] (got {})", self.taylor_quinney),
            ));
        }
        if let Some(t) = self.initial_temperature
            && !(t.is_finite() && t > 0.0)
        {
            issues.push(Issue::new(
                format!("{path}.initial_temperature"),
                format!("must be a finite temperature > 0 K (got {t})"),
            ));
        }
        issues.extend(self.flow_stress.check(&format!("{path}.flow_stress")));
        if let Some(d) = &self.damage {
            issues.extend(d.check(&format!("{path}.damage")));
        }
        issues
    }
}

fn build(p: JohnsonCookParameters, path: &str) -> Result<Arc<dyn Material>, Vec<Issue>> {
    let issues = p.check(path);
    if issues.is_empty() {
        Ok(Arc::new(JohnsonCook::new(p)))
    } else {
        Err(issues)
    }
}

/// The Johnson–Cook plugin.
pub struct JohnsonCookPlugin;

impl Plugin for JohnsonCookPlugin {
    fn name(&self) -> &'static str {
        "johnson-cook"
    }

    fn description(&self) -> &'static str {
        "Johnson–Cook plasticity (rate, temperature, adiabatic heating, equation of state) and damage"
    }

    fn materials(&self) -> Vec<Box<dyn MaterialFactory>> {
        vec![Box::new(TypedMaterialFactory::new("johnson_cook", build))]
    }

    fn references(&self) -> Vec<Box<dyn ReferenceFactory>> {
        vec![taylor_bar::factory()]
    }
}

#[cfg(test)]
mod tests;
