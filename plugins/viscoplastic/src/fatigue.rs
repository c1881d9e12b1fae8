//! An energy-based fatigue law for solder joints: cycles to crack initiation from the
//! inelastic work density of one thermal cycle, N = C·ΔWᵏ (Syed 2004 and Darveaux 2000
//! have this form; their constants are fitted to board-level tests of one joint geometry).

use mpm_core::scene::Issue;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// N = coefficient · (ΔW in J/m³)^exponent.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FatigueLaw {
    /// C, cycles at ΔW = 1 J/m³.
    pub coefficient: f64,
    /// k (negative: more work per cycle, fewer cycles).
    pub exponent: f64,
}

impl FatigueLaw {
    /// Cycles to crack initiation at inelastic work `work_per_cycle`, J/m³ (`None` at no
    /// work: the joint does not crack).
    pub fn cycles(&self, work_per_cycle: f64) -> Option<f64> {
        (work_per_cycle > 0.0).then(|| self.coefficient * work_per_cycle.powf(self.exponent))
    }

    /// Every problem with the constants, with JSON paths below `path`.
    pub fn check(&self, path: &str) -> Vec<Issue> {
        let mut issues = Vec::new();
        if !(self.coefficient.is_finite() && self.coefficient > 0.0) {
            issues.push(Issue::new(
                format!("{path}.coefficient"),
                format!("must be a finite number > 0 (got {})", self.coefficient),
            ));
        }
        if !(self.exponent.is_finite() && self.exponent < 0.0) {
            issues.push(Issue::new(
                format!("{path}.exponent"),
                format!(
                    "must be a finite number < 0 (got {}): more work per cycle must mean fewer cycles",
                    self.exponent
                ),
            ));
        }
        issues
    }
}
