//! Johnson–Cook flow stress σ_y = (A + B εₚⁿ)(1 + C ln ε̇*)(1 − T*ᵐ).

use mpm_core::scene::Issue;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Constants of the Johnson–Cook flow stress.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FlowStress {
    /// A: initial yield stress at the reference rate and room temperature, Pa.
    pub yield_stress: f64,
    /// B: hardening modulus, Pa.
    pub hardening_modulus: f64,
    /// n: hardening exponent.
    pub hardening_exponent: f64,
    /// C: strain-rate sensitivity (dimensionless).
    pub strain_rate_sensitivity: f64,
    /// m: thermal softening exponent.
    pub thermal_softening_exponent: f64,
    /// Reference plastic strain rate ε̇₀, 1/s (rates below it count as ε̇₀).
    #[serde(default = "one")]
    pub reference_strain_rate: f64,
    /// Room (reference) temperature, K: T* = (T − T_room)/(T_melt − T_room).
    pub room_temperature: f64,
    /// Melting temperature, K: the flow stress vanishes there.
    pub melt_temperature: f64,
}

fn one() -> f64 {
    1.0
}

impl FlowStress {
    /// Every problem with the constants, with JSON paths below `path` (the section's own).
    pub fn check(&self, path: &str) -> Vec<Issue> {
        let mut issues = Vec::new();
        let mut require = |name: &str, value: f64, zero_allowed: bool| {
            let ok = value.is_finite() && (value > 0.0 || (zero_allowed && value == 0.0));
            if !ok {
                let bound = if zero_allowed { ">= 0" } else { "> 0" };
                issues.push(Issue::new(
                    format!("{path}.{name}"),
                    format!("must be a finite number {bound} (got {value})"),
                ));
            }
        };
        require("yield_stress", self.yield_stress, false);
        require("hardening_exponent", self.hardening_exponent, false);
        require(
            "thermal_softening_exponent",
            self.thermal_softening_exponent,
            false,
        );
        require("reference_strain_rate", self.reference_strain_rate, false);
        require("room_temperature", self.room_temperature, false);
        require("melt_temperature", self.melt_temperature, false);
        require("hardening_modulus", self.hardening_modulus, true);
        require(
            "strain_rate_sensitivity",
            self.strain_rate_sensitivity,
            true,
        );
        if self.melt_temperature <= self.room_temperature {
            issues.push(Issue::new(
                format!("{path}.melt_temperature"),
                format!(
                    "must exceed room_temperature ({} K) (got {} K)",
                    self.room_temperature, self.melt_temperature
                ),
            ));
        }
        issues
    }

    /// Homologous temperature T*, clamped to [0, 1].
    pub fn homologous_temperature(&self, temperature: f64) -> f64 {
        ((temperature - self.room_temperature) / (self.melt_temperature - self.room_temperature))
            .clamp(0.0, 1.0)
    }

    /// Thermal softening factor 1 − T*ᵐ.
    pub fn thermal_factor(&self, temperature: f64) -> f64 {
        let t = self.homologous_temperature(temperature);
        if t <= 0.0 {
            1.0
        } else {
            1.0 - t.powf(self.thermal_softening_exponent)
        }
    }

    /// Flow stress at plastic strain `strain`, plastic strain rate `rate` and the thermal
    /// factor from [`FlowStress::thermal_factor`], with its derivatives in strain and rate.
    pub fn evaluate(&self, strain: f64, rate: f64, thermal: f64) -> (f64, f64, f64) {
        let n = self.hardening_exponent;
        let strain = strain.max(0.0);
        let hardening = self.yield_stress + self.hardening_modulus * strain.powf(n);
        let d_hardening = if strain > 0.0 {
            self.hardening_modulus * n * strain.powf(n - 1.0)
        } else if n < 1.0 {
            f64::INFINITY
        } else {
            self.hardening_modulus * n * if n == 1.0 { 1.0 } else { 0.0 }
        };
        let ratio = rate / self.reference_strain_rate;
        let (rate_factor, d_rate) = if ratio > 1.0 {
            (
                1.0 + self.strain_rate_sensitivity * ratio.ln(),
                self.strain_rate_sensitivity / rate,
            )
        } else {
            (1.0, 0.0)
        };
        (
            hardening * rate_factor * thermal,
            d_hardening * rate_factor * thermal,
            hardening * d_rate * thermal,
        )
    }

    /// The plastic strain increment x of a radial return: solves
    /// q_trial − stiffness·x = share·σ_y(strain + x, x/dt) (stiffness 3μ, or 3φμ for a
    /// solid fraction φ with share φ) by Newton's method kept inside a bracket (the left
    /// side falls, the right side rises with x); `dt` = 0 counts no rate.
    pub fn radial_return(
        &self,
        q_trial: f64,
        stiffness: f64,
        share: f64,
        strain: f64,
        thermal: f64,
        dt: f64,
    ) -> f64 {
        let yield0 = share * self.evaluate(strain, 0.0, thermal).0;
        // Perfectly plastic estimate: an upper bound, since the flow stress only rises.
        let mut hi = ((q_trial - yield0) / stiffness).max(0.0);
        let mut lo = 0.0;
        let mut x = hi;
        for _ in 0..60 {
            let rate = if dt > 0.0 { x / dt } else { 0.0 };
            let (s, ds_dstrain, ds_drate) = self.evaluate(strain + x, rate, thermal);
            let g = q_trial - stiffness * x - share * s;
            if g.abs() <= 1e-12 * q_trial {
                break;
            }
            if g > 0.0 {
                lo = x;
            } else {
                hi = x;
            }
            let d_rate = if dt > 0.0 { ds_drate / dt } else { 0.0 };
            let slope = -stiffness - share * ds_dstrain - share * d_rate;
            let mut next = x - g / slope;
            if !(next.is_finite() && next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            x = next;
            if hi - lo <= 1e-15 * hi {
                break;
            }
        }
        x
    }

    /// Flow stress alone (see [`FlowStress::evaluate`]).
    pub fn value(&self, strain: f64, rate: f64, temperature: f64) -> f64 {
        self.evaluate(strain, rate, self.thermal_factor(temperature))
            .0
    }
}
