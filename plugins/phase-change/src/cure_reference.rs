//! The cure references: isothermal cure against the Kamal–Sourour closed form (m = n = 1),
//! and adiabatic cure, where all the heat of reaction stays (T = T0 + (H/c)·α).

use mpm_core::reference::{
    Frame, Reference, ReferenceFactory, ReferenceLaw, TypedReferenceFactory,
};
use mpm_core::scene::{Issue, Scene};
use mpm_core::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// Isothermal cure with Kamal–Sourour kinetics, m = n = 1, at the rate constants
/// `k1`, `k2` of the scene's temperature; error: RMS over the output frames of the mean
/// degree of cure minus the closed form.
#[derive(Clone, Copy, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct IsothermalCureParams {
    /// Rate constant k1 at the cure temperature, 1/s.
    pub k1: f64,
    /// Rate constant k2 at the cure temperature, 1/s.
    pub k2: f64,
}

/// Adiabatic cure: all the heat of reaction stays, so T = T0 + (H/c)·α; error: the
/// largest |T − T0 − (H/c)·α| over particles and frames, divided by H/c.
#[derive(Clone, Copy, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct AdiabaticCureParams {
    /// Temperature at t = 0, K.
    pub initial_temperature: f64,
    /// Total heat of reaction, J/kg.
    pub heat_of_reaction: f64,
    /// Specific heat, J/(kg K).
    pub specific_heat: f64,
}

/// The mean cure's squared error accumulated over frames.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct IsothermalCure {
    p: IsothermalCureParams,
    squared_error: f64,
    frames: f64,
    measured: Option<f64>,
    expected: Option<f64>,
}

impl ReferenceLaw for IsothermalCure {
    fn kind(&self) -> &'static str {
        "RMS error of the mean degree of cure over frames (Kamal-Sourour m = n = 1 closed form)"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        let Some(cure) = frame.particles.shared.get("cure") else {
            return;
        };
        if frame.time <= 0.0 {
            return;
        }
        let mean = cure.iter().sum::<f64>() / cure.len().max(1) as f64;
        let exact = kamal_sourour_isothermal(self.p.k1, self.p.k2, frame.time);
        self.squared_error += (mean - exact).powi(2);
        self.frames += 1.0;
        self.measured = Some(mean);
        self.expected = Some(exact);
    }

    fn error(&self) -> Option<f64> {
        (self.frames > 0.0).then(|| (self.squared_error / self.frames).sqrt())
    }

    fn expected(&self) -> Option<f64> {
        self.expected
    }

    fn measured(&self) -> Option<f64> {
        self.measured
    }
}

/// The largest energy-balance misfit seen.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct AdiabaticCure {
    p: AdiabaticCureParams,
    largest: Option<f64>,
}

impl ReferenceLaw for AdiabaticCure {
    fn kind(&self) -> &'static str {
        "largest |T - T0 - (H/c) alpha| over particles and frames, divided by H/c"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        let shared = &frame.particles.shared;
        let (Some(cure), Some(temperature)) = (shared.get("cure"), shared.get("temperature"))
        else {
            return;
        };
        let rise = self.p.heat_of_reaction / self.p.specific_heat;
        let mut largest = self.largest.unwrap_or(0.0);
        for (a, t) in cure.iter().zip(temperature) {
            largest = largest.max((t - self.p.initial_temperature - rise * a).abs() / rise);
        }
        self.largest = Some(largest);
    }

    fn error(&self) -> Option<f64> {
        self.largest
    }
}

fn build_isothermal(
    p: IsothermalCureParams,
    path: &str,
    _scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    c.positive("k1", p.k1);
    if !(p.k2.is_finite() && p.k2 >= 0.0) {
        c.error("k2", "must be a finite number >= 0");
    }
    c.finish()?;
    Ok(Arc::new(IsothermalCure {
        p,
        squared_error: 0.0,
        frames: 0.0,
        measured: None,
        expected: None,
    }))
}

fn build_adiabatic(
    p: AdiabaticCureParams,
    path: &str,
    _scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    c.positive("initial_temperature", p.initial_temperature);
    c.positive("heat_of_reaction", p.heat_of_reaction);
    c.positive("specific_heat", p.specific_heat);
    c.finish()?;
    Ok(Arc::new(AdiabaticCure { p, largest: None }))
}

/// The `isothermal_cure` and `adiabatic_cure` reference types.
pub fn factories() -> Vec<Box<dyn ReferenceFactory>> {
    vec![
        Box::new(TypedReferenceFactory::new(
            "isothermal_cure",
            build_isothermal,
        )),
        Box::new(TypedReferenceFactory::new(
            "adiabatic_cure",
            build_adiabatic,
        )),
    ]
}

/// Degree of cure of Kamal–Sourour kinetics with m = n = 1 at constant temperature,
/// `dα/dt = (k1 + k2 α)(1 − α)`, from α(0) = 0:
/// `α = k1 (e^{(k1+k2)t} − 1) / (k2 + k1 e^{(k1+k2)t})`.
pub fn kamal_sourour_isothermal(k1: f64, k2: f64, t: f64) -> f64 {
    let e = ((k1 + k2) * t).exp();
    if !e.is_finite() {
        return 1.0;
    }
    k1 * (e - 1.0) / (k2 + k1 * e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kamal_sourour_closed_form_solves_its_ode() {
        let (k1, k2) = (1e-3, 2e-2);
        let (mut a, dt) = (0.0, 0.01);
        for i in 0..20_000 {
            let t = i as f64 * dt;
            let f = |a: f64| (k1 + k2 * a) * (1.0 - a);
            let k_1 = f(a);
            let k_2 = f(a + 0.5 * dt * k_1);
            let k_3 = f(a + 0.5 * dt * k_2);
            let k_4 = f(a + dt * k_3);
            a += dt / 6.0 * (k_1 + 2.0 * k_2 + 2.0 * k_3 + k_4);
            let _ = t;
        }
        assert!((a - kamal_sourour_isothermal(k1, k2, 200.0)).abs() < 1e-9);
    }
}
