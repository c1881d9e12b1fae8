//! Johnson–Cook damage: D grows by Δεₚ/ε_f with the failure strain
//! ε_f = [D1 + D2 exp(D3 σ*)][1 + D4 ln ε̇*][1 + D5 T*].

use mpm_core::scene::Issue;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// What a particle does once its damage reaches 1.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, JsonSchema, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum FailureMode {
    /// Keeps only compressive pressure: no tension and no shear (the usual choice; failed
    /// particles still resist being pushed into each other).
    #[default]
    NoTension,
    /// Carries no stress at all (debris); its mass and momentum stay in the simulation.
    NoStress,
}

/// Johnson–Cook failure constants (D1…D5 in the literature).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Damage {
    /// D1: failure strain offset.
    pub d1: f64,
    /// D2: failure strain factor of the triaxiality term.
    pub d2: f64,
    /// D3: triaxiality exponent (negative: tension fails sooner).
    pub d3: f64,
    /// D4: strain-rate factor.
    #[serde(default)]
    pub d4: f64,
    /// D5: temperature factor.
    #[serde(default)]
    pub d5: f64,
    /// Behaviour after failure.
    #[serde(default)]
    pub failure: FailureMode,
    /// Radius, m, over which the damage is averaged (a material length): each particle's
    /// plastic strain drives its `local_damage`, and its `damage`, which fails it at 1, is
    /// the mean of that over its material within the radius (the core's
    /// `solver/state_averaging.rs`), so where and when a crack starts does not depend on
    /// the cell. Absent: each particle's own damage.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub averaging_radius: Option<f64>,
}

/// Smallest failure strain used, so that a damage increment stays finite.
const MIN_FAILURE_STRAIN: f64 = 1e-6;

impl Damage {
    /// Every problem with the constants, with JSON paths below `path` (the section's own).
    pub fn check(&self, path: &str) -> Vec<Issue> {
        let mut issues = Vec::new();
        for (name, value) in [
            ("d1", self.d1),
            ("d2", self.d2),
            ("d3", self.d3),
            ("d4", self.d4),
            ("d5", self.d5),
        ] {
            if !value.is_finite() {
                issues.push(Issue::new(
                    format!("{path}.{name}"),
                    format!("must be finite (got {value})"),
                ));
            }
        }
        if let Some(r) = self
            .averaging_radius
            .filter(|r| !(r.is_finite() && *r > 0.0))
        {
            issues.push(Issue::new(
                format!("{path}.averaging_radius"),
                format!("must be a finite number > 0 metres (got {r})"),
            ));
        }
        if self.d1 + self.d2 <= 0.0 {
            issues.push(Issue::new(
                path.to_string(),
                format!(
                    "d1 + d2 is the failure strain in pure shear and must be > 0 (got {})",
                    self.d1 + self.d2
                ),
            ));
        }
        issues
    }

    /// Failure strain at stress triaxiality `triaxiality` (mean stress over von Mises
    /// stress), plastic strain rate ratio `rate_ratio` = ε̇/ε̇₀ and homologous temperature.
    pub fn failure_strain(&self, triaxiality: f64, rate_ratio: f64, homologous: f64) -> f64 {
        let stress_term = self.d1 + self.d2 * (self.d3 * triaxiality).exp();
        let rate_term = 1.0 + self.d4 * rate_ratio.max(1.0).ln();
        let temperature_term = 1.0 + self.d5 * homologous;
        (stress_term * rate_term * temperature_term).max(MIN_FAILURE_STRAIN)
    }
}
