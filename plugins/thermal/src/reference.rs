//! The heat-conduction references: a slab whose faces are stepped in temperature (Fourier
//! series), a semi-infinite body whose surface is (erf solution), with their closed forms,
//! and two slabs joined by a contact conductance (`interface_reference.rs`).

use crate::interface_reference::InterfaceTemperatureParams;
use mpm_core::math::{Vector, erf};
use mpm_core::reference::{
    Frame, Reference, ReferenceFactory, ReferenceLaw, RelativeL2, TypedReferenceFactory,
};
use mpm_core::scene::{Issue, Scene};
use mpm_core::section::Checks;
use serde::Deserialize;
use std::f64::consts::PI;
use std::sync::Arc;

/// Transient conduction in a slab between `min` and `max` along `axis` whose two faces
/// step from `initial_temperature` to `surface_temperature` at t = 0 (Fourier series);
/// error: RMS temperature error over particles and output frames after t = 0, divided
/// by the temperature step.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct SlabTemperatureParams {
    /// Axis across the slab.
    pub axis: usize,
    /// Coordinate of the lower face.
    pub min: f64,
    /// Coordinate of the upper face.
    pub max: f64,
    /// Uniform temperature at t = 0, K.
    pub initial_temperature: f64,
    /// Temperature both faces are held at, K.
    pub surface_temperature: f64,
    /// Thermal diffusivity k/(ρc), m²/s.
    pub diffusivity: f64,
}

/// A semi-infinite body (deeper than the heat reaches in the run) whose surface at
/// `surface` steps to `surface_temperature` at t = 0 (erf solution); error as for
/// `slab_temperature`.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct SemiInfiniteTemperatureParams {
    /// Axis into the body.
    pub axis: usize,
    /// Coordinate of the heated surface; the body lies above it along the axis.
    pub surface: f64,
    /// Uniform temperature at t = 0, K.
    pub initial_temperature: f64,
    /// Temperature of the surface, K.
    pub surface_temperature: f64,
    /// Thermal diffusivity k/(ρc), m²/s.
    pub diffusivity: f64,
}

/// Which closed form a [`TemperatureError`] compares with.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
enum Geometry {
    Slab(SlabTemperatureParams),
    SemiInfinite(SemiInfiniteTemperatureParams),
    Interface(InterfaceTemperatureParams),
}

/// Squared temperature errors over particles and frames, each relative to the step.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct TemperatureError {
    geometry: Geometry,
    error: RelativeL2,
}

impl TemperatureError {
    /// The closed-form temperature at `x` and time `t`, and the temperature step.
    fn exact<const D: usize>(&self, x: &Vector<D>, t: f64) -> (f64, f64) {
        match &self.geometry {
            Geometry::Slab(p) => (
                slab_temperature(
                    x[p.axis] - p.min,
                    t,
                    p.max - p.min,
                    p.diffusivity,
                    p.initial_temperature,
                    p.surface_temperature,
                ),
                p.initial_temperature - p.surface_temperature,
            ),
            Geometry::SemiInfinite(p) => (
                semi_infinite_temperature(
                    (x[p.axis] - p.surface).abs(),
                    t,
                    p.diffusivity,
                    p.initial_temperature,
                    p.surface_temperature,
                ),
                p.initial_temperature - p.surface_temperature,
            ),
            Geometry::Interface(p) => (
                p.temperature(x[p.axis], t),
                p.lower_temperature - p.upper_temperature,
            ),
        }
    }
}

impl ReferenceLaw for TemperatureError {
    fn kind(&self) -> &'static str {
        match self.geometry {
            Geometry::Slab(_) => {
                "RMS temperature error over particles and frames / temperature step (slab, Fourier series)"
            }
            Geometry::SemiInfinite(_) => {
                "RMS temperature error over particles and frames / temperature step (semi-infinite body, erf solution)"
            }
            Geometry::Interface(_) => {
                "RMS temperature error over particles and frames / temperature difference (two slabs joined by a contact conductance, series solution)"
            }
        }
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        let particles = frame.particles;
        let Some(temperature) = particles.shared.get("temperature") else {
            return;
        };
        if frame.time <= 0.0 {
            return;
        }
        for (x, t) in particles.position.iter().zip(temperature) {
            let (exact, step) = self.exact(x, frame.time);
            self.error.add((t - exact).powi(2), step * step);
        }
    }

    fn error(&self) -> Option<f64> {
        self.error.value()
    }
}

fn build_slab(
    p: SlabTemperatureParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    c.axis("axis", p.axis, scene.dimension as usize);
    if !(p.min.is_finite() && p.max.is_finite() && p.max > p.min) {
        c.error("max", "must be finite and above reference.min");
    }
    c.positive("initial_temperature", p.initial_temperature);
    c.positive("surface_temperature", p.surface_temperature);
    c.positive("diffusivity", p.diffusivity);
    c.finish()?;
    Ok(Arc::new(TemperatureError {
        geometry: Geometry::Slab(p),
        error: RelativeL2::default(),
    }))
}

fn build_semi_infinite(
    p: SemiInfiniteTemperatureParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    c.axis("axis", p.axis, scene.dimension as usize);
    c.finite("surface", p.surface);
    c.positive("initial_temperature", p.initial_temperature);
    c.positive("surface_temperature", p.surface_temperature);
    c.positive("diffusivity", p.diffusivity);
    c.finish()?;
    Ok(Arc::new(TemperatureError {
        geometry: Geometry::SemiInfinite(p),
        error: RelativeL2::default(),
    }))
}

fn build_interface(
    p: InterfaceTemperatureParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    c.axis("axis", p.axis, scene.dimension as usize);
    c.finite("interface", p.interface);
    c.positive("thickness", p.thickness);
    c.positive("lower_temperature", p.lower_temperature);
    c.positive("upper_temperature", p.upper_temperature);
    c.positive("conductivity", p.conductivity);
    c.positive("diffusivity", p.diffusivity);
    c.positive("coefficient", p.coefficient);
    if p.lower_temperature == p.upper_temperature {
        c.error("upper_temperature", "must differ from lower_temperature");
    }
    c.finish()?;
    Ok(Arc::new(TemperatureError {
        geometry: Geometry::Interface(p),
        error: RelativeL2::default(),
    }))
}

/// The `slab_temperature`, `semi_infinite_temperature` and `interface_temperature`
/// reference types.
pub fn factories() -> Vec<Box<dyn ReferenceFactory>> {
    vec![
        Box::new(TypedReferenceFactory::new(
            "interface_temperature",
            build_interface,
        )),
        Box::new(TypedReferenceFactory::new("slab_temperature", build_slab)),
        Box::new(TypedReferenceFactory::new(
            "semi_infinite_temperature",
            build_semi_infinite,
        )),
    ]
}

/// Temperature in a slab `0 <= s <= length` at `initial` whose two faces are held at
/// `surface` from t = 0 (Fourier series; terms until they fall below 1e-12).
pub fn slab_temperature(
    s: f64,
    t: f64,
    length: f64,
    diffusivity: f64,
    initial: f64,
    surface: f64,
) -> f64 {
    if t <= 0.0 {
        return initial;
    }
    let mut sum = 0.0;
    for k in 0..10_000 {
        let n = (2 * k + 1) as f64;
        let decay = (-(n * PI / length).powi(2) * diffusivity * t).exp();
        if decay < 1e-14 {
            break;
        }
        sum += 4.0 / (n * PI) * (n * PI * s / length).sin() * decay;
    }
    surface + (initial - surface) * sum
}

/// Temperature at depth `s` in a semi-infinite body at `initial` whose surface is held at
/// `surface` from t = 0: `T_s + (T_0 − T_s) erf(s / 2√(αt))`.
pub fn semi_infinite_temperature(
    s: f64,
    t: f64,
    diffusivity: f64,
    initial: f64,
    surface: f64,
) -> f64 {
    if t <= 0.0 {
        return initial;
    }
    surface + (initial - surface) * erf(s / (2.0 * (diffusivity * t).sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slab_series_starts_at_the_initial_value_and_tends_to_the_surface() {
        let mid = slab_temperature(0.5, 1e-6, 1.0, 1.0, 300.0, 400.0);
        assert!((mid - 300.0).abs() < 1e-6);
        let late = slab_temperature(0.5, 10.0, 1.0, 1.0, 300.0, 400.0);
        assert!((late - 400.0).abs() < 1e-6);
        // Fundamental mode only at late times: T - Ts = (T0 - Ts) 4/π e^{-π² t} at s = L/2.
        let t = 0.2;
        let expect = 400.0 - 100.0 * 4.0 / PI * (-PI * PI * t).exp();
        assert!((slab_temperature(0.5, t, 1.0, 1.0, 300.0, 400.0) - expect).abs() < 1e-3);
    }
}
