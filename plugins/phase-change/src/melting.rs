//! Melting and solidification at a melting temperature, with latent heat.

use mpm_core::scene::Issue;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Thermal properties of one phase.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PhaseProperties {
    /// Thermal conductivity, W/(m K).
    pub conductivity: f64,
    /// Specific heat, J/(kg K).
    pub specific_heat: f64,
    /// Density, kg/m³.
    pub density: f64,
}

/// Melting and solidification of one material.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Melting {
    /// Melting (and freezing) temperature, K.
    pub melt_temperature: f64,
    /// Latent heat of fusion, J/kg.
    pub latent_heat: f64,
    /// Solid phase properties.
    pub solid: PhaseProperties,
    /// Liquid phase properties.
    pub liquid: PhaseProperties,
    /// Solid fraction of particles that start exactly at the melting temperature (others
    /// start solid below it and liquid above it).
    #[serde(default = "one")]
    pub initial_solid_fraction: f64,
}

fn one() -> f64 {
    1.0
}

impl Melting {
    /// Problems at `path`.
    pub fn check(&self, path: &str) -> Vec<Issue> {
        let mut issues = Vec::new();
        let mut positive = |p: String, v: f64| {
            if !(v.is_finite() && v > 0.0) {
                issues.push(Issue::new(
                    p,
                    format!("must be a finite number > 0 (got {v})"),
                ));
            }
        };
        positive(format!("{path}.melt_temperature"), self.melt_temperature);
        positive(format!("{path}.latent_heat"), self.latent_heat);
        for (name, ph) in [("solid", &self.solid), ("liquid", &self.liquid)] {
            positive(format!("{path}.{name}.conductivity"), ph.conductivity);
            positive(format!("{path}.{name}.specific_heat"), ph.specific_heat);
            positive(format!("{path}.{name}.density"), ph.density);
        }
        if !(0.0..=1.0).contains(&self.initial_solid_fraction) {
            issues.push(Issue::new(
                format!("{path}.initial_solid_fraction"),
                format!("must lie in [0, 1] (got {})", self.initial_solid_fraction),
            ));
        }
        issues
    }

    /// Solid fraction of a particle starting at temperature `t`.
    pub fn initial_fraction(&self, t: f64) -> f64 {
        if t < self.melt_temperature {
            1.0
        } else if t > self.melt_temperature {
            0.0
        } else {
            self.initial_solid_fraction
        }
    }

    /// Mixed (conductivity, specific heat, density) at solid fraction `f`.
    pub fn mix(&self, f: f64) -> (f64, f64, f64) {
        let m = |s: f64, l: f64| f * s + (1.0 - f) * l;
        (
            m(self.solid.conductivity, self.liquid.conductivity),
            m(self.solid.specific_heat, self.liquid.specific_heat),
            m(self.solid.density, self.liquid.density),
        )
    }

    /// Enthalpy method at one particle: sensible heat carried past the melting point by
    /// conduction melts (or freezes) the particle at constant temperature. Conserves
    /// `c·T + (1 − f)·L` per unit mass; returns the new (temperature, solid fraction).
    pub fn recover(&self, temperature: f64, fraction: f64, specific_heat: f64) -> (f64, f64) {
        let (tm, l) = (self.melt_temperature, self.latent_heat);
        if temperature > tm && fraction > 0.0 {
            let excess = specific_heat * (temperature - tm);
            let melted = (excess / l).min(fraction);
            (
                tm + (excess - melted * l) / specific_heat,
                fraction - melted,
            )
        } else if temperature < tm && fraction < 1.0 {
            let deficit = specific_heat * (tm - temperature);
            let frozen = (deficit / l).min(1.0 - fraction);
            (
                tm - (deficit - frozen * l) / specific_heat,
                fraction + frozen,
            )
        } else {
            (temperature, fraction)
        }
    }
}
