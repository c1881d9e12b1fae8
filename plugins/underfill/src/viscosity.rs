//! Generalised Newtonian viscosity: Newtonian, Cross (shear thinning) and Castro–Macosko
//! (shear thinning, Arrhenius in temperature, rising with the degree of cure to gelation).

use mpm_core::physics::Property;
use mpm_core::scene::Issue;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Ceiling on the viscosity, Pa·s: a gelled liquid stops flowing without making the flow
/// solve singular.
pub const MAX_VISCOSITY: f64 = 1e9;

/// A viscosity law μ(T, γ̇, α).
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Viscosity {
    /// Constant viscosity, Pa·s: a number or a `[[T, μ], ...]` table in kelvin.
    Newtonian(Property),
    /// Cross model μ = μ0 / (1 + (μ0·γ̇/τ*)^(1−n)).
    Cross(CrossParameters),
    /// Castro–Macosko model for curing resins:
    /// μ = μ0(T) / (1 + (μ0·γ̇/τ*)^(1−n)) · (α_g / (α_g − α))^(C1 + C2·α), μ0 = B·exp(T_b/T).
    CastroMacosko(CastroMacoskoParameters),
}

/// Parameters of the Cross model.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CrossParameters {
    /// Zero-shear viscosity μ0, Pa·s: a number or a `[[T, μ0], ...]` table in kelvin.
    pub zero_shear: Property,
    /// Shear stress τ* where thinning sets in, Pa.
    pub critical_stress: f64,
    /// Power-law index n (1: Newtonian, below 1: thinning).
    pub index: f64,
}

/// Parameters of the Castro–Macosko model.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CastroMacoskoParameters {
    /// Pre-factor B of μ0 = B·exp(T_b/T), Pa·s.
    pub b: f64,
    /// Activation temperature T_b, K.
    pub tb: f64,
    /// Shear stress τ* where thinning sets in, Pa.
    pub critical_stress: f64,
    /// Power-law index n.
    pub index: f64,
    /// Degree of cure at gelation α_g (the viscosity diverges there).
    pub gel_point: f64,
    /// Exponent constant C1.
    pub c1: f64,
    /// Exponent constant C2.
    pub c2: f64,
}

impl Viscosity {
    /// The viscosity at temperature `t` (K), shear rate `shear_rate` (1/s) and degree of
    /// cure `cure`, Pa·s, capped at [`MAX_VISCOSITY`].
    #[inline]
    pub fn at(&self, t: f64, shear_rate: f64, cure: f64) -> f64 {
        let thin = |mu0: f64, tau: f64, n: f64| {
            if n == 1.0 || shear_rate <= 0.0 {
                mu0
            } else {
                mu0 / (1.0 + (mu0 * shear_rate / tau).powf(1.0 - n))
            }
        };
        let mu = match self {
            Viscosity::Newtonian(mu) => mu.at(t),
            Viscosity::Cross(c) => thin(c.zero_shear.at(t), c.critical_stress, c.index),
            Viscosity::CastroMacosko(c) => {
                if cure >= c.gel_point {
                    return MAX_VISCOSITY;
                }
                let mu0 = c.b * (c.tb / t).exp();
                let gel = (c.gel_point / (c.gel_point - cure.max(0.0))).powf(c.c1 + c.c2 * cure);
                thin(mu0, c.critical_stress, c.index) * gel
            }
        };
        if mu.is_finite() {
            mu.min(MAX_VISCOSITY)
        } else {
            MAX_VISCOSITY
        }
    }

    /// Whether the viscosity depends on the shear rate (then it lags one step).
    pub fn shear_thinning(&self) -> bool {
        match self {
            Viscosity::Newtonian(_) => false,
            Viscosity::Cross(c) => c.index != 1.0,
            Viscosity::CastroMacosko(c) => c.index != 1.0,
        }
    }

    /// Whether the viscosity reads the degree of cure.
    pub fn uses_cure(&self) -> bool {
        matches!(self, Viscosity::CastroMacosko(_))
    }

    /// Problems with the law at `path`.
    pub fn check(&self, path: &str) -> Vec<Issue> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let mut issues = Vec::new();
        let index = |issues: &mut Vec<Issue>, p: String, n: f64| {
            if !(n.is_finite() && n > 0.0 && n <= 1.0) {
                issues.push(Issue::new(
                    p,
                    format!("the power-law index must lie in (0, 1] (got {n})"),
                ));
            }
        };
        match self {
            Viscosity::Newtonian(mu) => issues.extend(mu.check(
                &format!("{path}.newtonian"),
                "a finite number > 0",
                positive,
            )),
            Viscosity::Cross(c) => {
                let p = format!("{path}.cross");
                issues.extend(c.zero_shear.check(
                    &format!("{p}.zero_shear"),
                    "a finite number > 0",
                    positive,
                ));
                if !positive(c.critical_stress) {
                    issues.push(Issue::new(
                        format!("{p}.critical_stress"),
                        format!("must be a finite number > 0 Pa (got {})", c.critical_stress),
                    ));
                }
                index(&mut issues, format!("{p}.index"), c.index);
            }
            Viscosity::CastroMacosko(c) => {
                let p = format!("{path}.castro_macosko");
                for (name, v) in [("b", c.b), ("critical_stress", c.critical_stress)] {
                    if !positive(v) {
                        issues.push(Issue::new(
                            format!("{p}.{name}"),
                            format!("must be a finite number > 0 (got {v})"),
                        ));
                    }
                }
                if !c.tb.is_finite() {
                    issues.push(Issue::new(format!("{p}.tb"), "must be finite"));
                }
                index(&mut issues, format!("{p}.index"), c.index);
                if !(c.gel_point > 0.0 && c.gel_point <= 1.0) {
                    issues.push(Issue::new(
                        format!("{p}.gel_point"),
                        format!("must lie in (0, 1] (got {})", c.gel_point),
                    ));
                }
                for (name, v) in [("c1", c.c1), ("c2", c.c2)] {
                    if !v.is_finite() {
                        issues.push(Issue::new(format!("{p}.{name}"), "must be finite"));
                    }
                }
            }
        }
        issues
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn castro() -> Viscosity {
        Viscosity::CastroMacosko(CastroMacoskoParameters {
            b: 1e-3,
            tb: 2000.0,
            critical_stress: 1e4,
            index: 0.8,
            gel_point: 0.3,
            c1: 1.5,
            c2: 1.0,
        })
    }

    #[test]
    fn cross_model_thins_with_shear_and_is_newtonian_at_rest() {
        let v = Viscosity::Cross(CrossParameters {
            zero_shear: Property::Constant(2.0),
            critical_stress: 100.0,
            index: 0.5,
        });
        assert_eq!(v.at(300.0, 0.0, 0.0), 2.0);
        // μ0·γ̇/τ* = 1 at γ̇ = 50: μ = μ0 / 2.
        assert!((v.at(300.0, 50.0, 0.0) - 1.0).abs() < 1e-12);
        assert!(v.at(300.0, 5000.0, 0.0) < 0.2);
    }

    #[test]
    fn castro_macosko_rises_with_cure_and_falls_with_temperature() {
        let v = castro();
        let cold = v.at(300.0, 0.0, 0.0);
        assert!((cold - 1e-3 * (2000.0f64 / 300.0).exp()).abs() < 1e-12 * cold);
        assert!(v.at(350.0, 0.0, 0.0) < cold);
        let a = 0.15;
        let expected = cold * (0.3f64 / 0.15).powf(1.5 + a);
        assert!((v.at(300.0, 0.0, a) - expected).abs() < 1e-9 * expected);
        assert_eq!(v.at(300.0, 0.0, 0.3), MAX_VISCOSITY);
    }

    #[test]
    fn bad_parameters_are_named() {
        let v = Viscosity::Cross(CrossParameters {
            zero_shear: Property::Constant(-1.0),
            critical_stress: 0.0,
            index: 1.5,
        });
        let paths: Vec<String> = v.check("v").into_iter().map(|i| i.path).collect();
        assert_eq!(
            paths,
            vec![
                "v.cross.zero_shear",
                "v.cross.critical_stress",
                "v.cross.index"
            ]
        );
    }
}
