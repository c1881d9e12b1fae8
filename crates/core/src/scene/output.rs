//! The `output` section (frames and fields) and the `stop` section (bounds that stop a
//! run going wrong); their types and checks.

use super::validator::Validator;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Output schedule and fields.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Output {
    /// Number of frames after the initial one, evenly spaced over `end_time`.
    #[serde(default = "default_frames")]
    pub frames: u32,
    /// Particle fields to store: `x`, `v`, `stress`, `F`, `J`, `mass`, `volume`, `material`,
    /// plus any field a material declares.
    #[serde(default = "default_fields")]
    pub fields: Vec<String>,
}

fn default_frames() -> u32 {
    20
}
fn default_fields() -> Vec<String> {
    vec!["x".into(), "v".into()]
}

impl Default for Output {
    fn default() -> Self {
        Self {
            frames: default_frames(),
            fields: default_fields(),
        }
    }
}

/// Bounds that stop a run going wrong; NaN/inf and det F <= 0 always stop it.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StopCriteria {
    /// Largest particle speed allowed, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_speed: Option<f64>,
    /// Largest allowed growth of the total energy, as a fraction of the largest mechanical
    /// energy (kinetic + strain) seen so far.
    #[serde(default = "default_energy_growth")]
    pub max_energy_growth: f64,
    /// Smallest time step allowed before the run stops, seconds.
    #[serde(default = "default_min_dt")]
    pub min_dt: f64,
}

fn default_energy_growth() -> f64 {
    0.5
}
fn default_min_dt() -> f64 {
    1e-14
}

impl Default for StopCriteria {
    fn default() -> Self {
        Self {
            max_speed: None,
            max_energy_growth: default_energy_growth(),
            min_dt: default_min_dt(),
        }
    }
}

impl Output {
    /// Checks the output schedule.
    pub(super) fn validate(&self, v: &mut Validator) {
        if self.frames == 0 {
            v.err("output.frames", "must be at least 1");
        }
    }
}

impl StopCriteria {
    /// Checks the stop bounds.
    pub(super) fn validate(&self, v: &mut Validator) {
        if let Some(m) = self.max_speed {
            v.positive("stop.max_speed", m);
        }
        v.positive("stop.max_energy_growth", self.max_energy_growth);
        if !(self.min_dt.is_finite() && self.min_dt >= 0.0) {
            v.err("stop.min_dt", "must be a finite number >= 0");
        }
    }
}
