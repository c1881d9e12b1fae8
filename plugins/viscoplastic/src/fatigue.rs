//! An energy-based fatigue law for solder joints: cycles to crack initiation from the
//! inelastic work density of one thermal cycle, N = C·ΔWᵏ (Syed 2004 and Darveaux 2000
//! have this form; their constants are fitted to board-level tests of one joint geometry),
//! and optionally Darveaux's crack growth, da/dN = K·ΔWᵐ, across a joint of crack length
//! a: cycles to failure N + a/(da/dN).

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
    /// Crack growth after initiation (none: the law gives initiation only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub growth: Option<CrackGrowth>,
}

/// Darveaux's crack growth: da/dN = coefficient · (ΔW in J/m³)^exponent, m per cycle,
/// across `crack_length`.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CrackGrowth {
    /// K, m per cycle at ΔW = 1 J/m³.
    pub coefficient: f64,
    /// m (positive: more work per cycle, faster growth).
    pub exponent: f64,
    /// The length the crack crosses to fail the joint, m (the joint's width at the
    /// interface it runs along).
    pub crack_length: f64,
}

impl FatigueLaw {
    /// Cycles to crack initiation at inelastic work `work_per_cycle`, J/m³ (`None` at no
    /// work: the joint does not crack).
    pub fn cycles(&self, work_per_cycle: f64) -> Option<f64> {
        (work_per_cycle > 0.0).then(|| self.coefficient * work_per_cycle.powf(self.exponent))
    }

    /// Cycles to failure, initiation and then growth across the crack length (`None`
    /// without a growth law or at no work).
    pub fn cycles_to_failure(&self, work_per_cycle: f64) -> Option<f64> {
        let g = self.growth?;
        let rate = g.coefficient * work_per_cycle.powf(g.exponent);
        Some(self.cycles(work_per_cycle)? + g.crack_length / rate)
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
        if let Some(g) = &self.growth {
            let path = format!("{path}.growth");
            for (name, value) in [
                ("coefficient", g.coefficient),
                ("crack_length", g.crack_length),
            ] {
                if !(value.is_finite() && value > 0.0) {
                    issues.push(Issue::new(
                        format!("{path}.{name}"),
                        format!("must be a finite number > 0 (got {value})"),
                    ));
                }
            }
            if !(g.exponent.is_finite() && g.exponent > 0.0) {
                issues.push(Issue::new(
                    format!("{path}.exponent"),
                    format!(
                        "must be a finite number > 0 (got {}): more work per cycle must mean faster growth",
                        g.exponent
                    ),
                ));
            }
        }
        issues
    }
}
