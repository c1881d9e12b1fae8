//! Thermoset cure: Kamal–Sourour kinetics, DiBenedetto glass transition, gelation and
//! chemical shrinkage.

use mpm_core::scene::Issue;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Gas constant, J/(mol K).
const GAS_CONSTANT: f64 = 8.314_462_618;

/// Kamal–Sourour kinetics `dα/dt = (k1 + k2 α^m)(1 − α)^n` with Arrhenius rate constants
/// `k_i = A_i exp(−E_i / (R T))`.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CureKinetics {
    /// Pre-exponential factor A1, 1/s.
    pub a1: f64,
    /// Activation energy E1, J/mol.
    pub e1: f64,
    /// Pre-exponential factor A2, 1/s (0: n-th order kinetics).
    pub a2: f64,
    /// Activation energy E2, J/mol.
    pub e2: f64,
    /// Autocatalytic exponent m.
    pub m: f64,
    /// Reaction order n.
    pub n: f64,
}

/// A particle's temperature over a step as the cure kinetics see it: linear from `start`
/// to `end` (the conducted temperatures, which carry the heat of a predicted cure
/// `released` spread evenly over the step), plus the heat of the cure that departs from
/// that prediction, which stays in the particle: T(s) = start + (end − start)·s/dt +
/// heating·(α(s) − α₀ − released·s/dt).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TemperaturePath {
    /// Temperature at the step's start, K.
    pub start: f64,
    /// Conducted temperature at the step's end, K.
    pub end: f64,
    /// Temperature rise per unit of cure, heat of reaction over specific heat, K.
    pub heating: f64,
    /// The cure whose heat `end` carries (spread evenly over the step).
    pub released: f64,
}

impl TemperaturePath {
    /// A temperature held at `t` (the kinetics' predictor).
    pub fn constant(t: f64) -> Self {
        Self::adiabatic(t, 0.0)
    }

    /// A particle alone with its reaction heat from `start` (the adiabatic cell).
    pub fn adiabatic(start: f64, heating: f64) -> Self {
        Self {
            start,
            end: start,
            heating,
            released: 0.0,
        }
    }
}

impl CureKinetics {
    /// Rate constants (k1, k2) at temperature `t`.
    pub fn rate_constants(&self, t: f64) -> (f64, f64) {
        let first = (-self.e1 / (GAS_CONSTANT * t)).exp();
        // One exponential when both reactions share their activation energy (common in
        // fits of underfill resins); the kinetics' sub-steps evaluate this many times.
        let second = if self.e2 == self.e1 {
            first
        } else {
            (-self.e2 / (GAS_CONSTANT * t)).exp()
        };
        (self.a1 * first, self.a2 * second)
    }

    /// dα/dt at temperature `t` and cure `alpha`.
    pub fn rate(&self, t: f64, alpha: f64) -> f64 {
        let (k1, k2) = self.rate_constants(t);
        let a = alpha.clamp(0.0, 1.0);
        (k1 + k2 * a.powf(self.m)) * (1.0 - a).powf(self.n)
    }
}

/// DiBenedetto's glass transition: `(Tg − Tg0)/(Tg∞ − Tg0) = λα / (1 − (1 − λ)α)`.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GlassTransition {
    /// Glass transition of the uncured resin, K.
    pub tg0: f64,
    /// Glass transition of the fully cured resin, K.
    pub tg_inf: f64,
    /// DiBenedetto's λ in (0, 1].
    pub lambda: f64,
}

impl GlassTransition {
    /// Tg at cure `alpha`.
    pub fn at(&self, alpha: f64) -> f64 {
        let l = self.lambda;
        self.tg0 + (self.tg_inf - self.tg0) * l * alpha / (1.0 - (1.0 - l) * alpha)
    }
}

/// Cure of one material.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CureParameters {
    /// Reaction kinetics.
    pub kinetics: CureKinetics,
    /// Total heat of reaction, J/kg, released in proportion to the cure.
    pub heat_of_reaction: f64,
    /// Degree of cure at t = 0.
    #[serde(default)]
    pub initial_cure: f64,
    /// Degree of cure at gelation: from there the particle is a solid (solid fraction 1).
    pub gel_point: f64,
    /// Glass transition as cure proceeds (reported in the `glass_transition` field).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub glass_transition: Option<GlassTransition>,
    /// Volumetric chemical shrinkage at full cure (0.03 = 3 %); the linear free strain is
    /// −shrinkage·α/3.
    #[serde(default)]
    pub shrinkage: f64,
}

impl CureParameters {
    /// Problems at `path`.
    pub fn check(&self, path: &str) -> Vec<Issue> {
        let mut issues = Vec::new();
        let k = &self.kinetics;
        let kp = format!("{path}.kinetics");
        let mut nonneg = |p: String, v: f64| {
            if !(v.is_finite() && v >= 0.0) {
                issues.push(Issue::new(
                    p,
                    format!("must be a finite number >= 0 (got {v})"),
                ));
            }
        };
        nonneg(format!("{kp}.a1"), k.a1);
        nonneg(format!("{kp}.e1"), k.e1);
        nonneg(format!("{kp}.a2"), k.a2);
        nonneg(format!("{kp}.e2"), k.e2);
        nonneg(format!("{kp}.m"), k.m);
        nonneg(format!("{kp}.n"), k.n);
        nonneg(format!("{path}.heat_of_reaction"), self.heat_of_reaction);
        nonneg(format!("{path}.shrinkage"), self.shrinkage);
        if k.a1 == 0.0 && k.a2 == 0.0 {
            issues.push(Issue::new(
                kp,
                "a1 and a2 are both 0: the resin never cures",
            ));
        } else if k.a1 == 0.0 && self.initial_cure == 0.0 {
            issues.push(Issue::new(
                format!("{path}.kinetics.a1"),
                "with a1 = 0 and no initial cure, autocatalytic kinetics never start",
            ));
        }
        for (name, v) in [
            ("initial_cure", self.initial_cure),
            ("gel_point", self.gel_point),
        ] {
            if !(0.0..1.0).contains(&v) {
                issues.push(Issue::new(
                    format!("{path}.{name}"),
                    format!("must lie in [0, 1) (got {v})"),
                ));
            }
        }
        if self.shrinkage >= 0.5 {
            issues.push(Issue::new(
                format!("{path}.shrinkage"),
                format!("must be below 0.5 (got {})", self.shrinkage),
            ));
        }
        if let Some(g) = &self.glass_transition
            && !(g.tg0 > 0.0 && g.tg_inf > g.tg0 && g.lambda > 0.0 && g.lambda <= 1.0)
        {
            issues.push(Issue::new(
                format!("{path}.glass_transition"),
                "needs 0 < tg0 < tg_inf and 0 < lambda <= 1",
            ));
        }
        issues
    }

    /// Advances the cure over `dt` from `alpha` along `path`, with RK4 sub-steps of at
    /// most 1 % of cure each at the hotter end. Returns the new cure.
    pub fn advance_along(&self, alpha: f64, path: TemperaturePath, dt: f64) -> f64 {
        let rate = |a: f64, t: f64| self.kinetics.rate(t, a);
        let (k1, k2) = self.kinetics.rate_constants(path.start.max(path.end));
        let steps = ((dt * (k1 + k2) / 0.01).ceil() as usize).clamp(1, 10_000);
        let h = dt / steps as f64;
        let at = |s: f64, a: f64| {
            path.start
                + (path.end - path.start) * s / dt
                + path.heating * (a - alpha - path.released * s / dt)
        };
        let mut a = alpha;
        for i in 0..steps {
            let s = i as f64 * h;
            let r1 = rate(a, at(s, a));
            let a2 = a + 0.5 * h * r1;
            let r2 = rate(a2, at(s + 0.5 * h, a2));
            let a3 = a + 0.5 * h * r2;
            let r3 = rate(a3, at(s + 0.5 * h, a3));
            let a4 = a + h * r3;
            let r4 = rate(a4, at(s + h, a4));
            a += (h / 6.0 * (r1 + 2.0 * r2 + 2.0 * r3 + r4))
                .min(1.0 - a)
                .max(0.0);
        }
        a
    }

    /// Advances cure and temperature together over `dt` as an adiabatic cell (the heat of
    /// reaction stays in the particle). Returns the new (cure, temperature).
    pub fn advance(&self, alpha: f64, temperature: f64, specific_heat: f64, dt: f64) -> (f64, f64) {
        let heating = self.heat_of_reaction / specific_heat;
        let a = self.advance_along(alpha, TemperaturePath::adiabatic(temperature, heating), dt);
        (a, temperature + heating * (a - alpha))
    }
}
