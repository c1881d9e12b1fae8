//! The Stefan problem: a solid melts from a heated surface; Neumann's similarity solution
//! puts the front at 2λ√(α_l t). The reference and its closed form.

use mpm_core::math::{bisect, erf, erfc};
use mpm_core::reference::{
    Frame, Reference, ReferenceFactory, ReferenceLaw, RelativeL2, TypedReferenceFactory,
};
use mpm_core::scene::{Issue, Scene};
use mpm_core::section::Checks;
use serde::Deserialize;
use std::f64::consts::PI;
use std::sync::Arc;

/// Stefan problem: a solid at `initial_temperature` (the melting point for the
/// one-phase problem, below it for the two-phase one) melts from a surface held at
/// `surface_temperature`; Neumann's solution puts the front at 2λ√(α_l t). The measured
/// front is `surface + length × (liquid volume / body volume)`; error: relative L2
/// error of the front position over the output frames after t = 0.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct StefanParams {
    /// Axis into the body.
    pub axis: usize,
    /// Coordinate of the heated surface.
    pub surface: f64,
    /// Length of the body along the axis.
    pub length: f64,
    /// Melting temperature, K.
    pub melt_temperature: f64,
    /// Temperature of the heated surface, K.
    pub surface_temperature: f64,
    /// Uniform temperature of the solid at t = 0, K.
    pub initial_temperature: f64,
    /// Latent heat, J/kg.
    pub latent_heat: f64,
    /// Liquid properties.
    pub liquid: StefanPhase,
    /// Solid properties (the density must equal the liquid's for Neumann's solution).
    pub solid: StefanPhase,
}

/// Thermal properties of one phase in a Stefan reference.
#[derive(Clone, Copy, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct StefanPhase {
    /// Thermal conductivity, W/(m K).
    pub conductivity: f64,
    /// Specific heat, J/(kg K).
    pub specific_heat: f64,
    /// Density, kg/m³.
    pub density: f64,
}

impl StefanPhase {
    fn diffusivity(&self) -> f64 {
        self.conductivity / (self.density * self.specific_heat)
    }
}

/// The front position error accumulated over frames.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct Stefan {
    length: f64,
    liquid_diffusivity: f64,
    /// Neumann's constant λ.
    lambda: f64,
    error: RelativeL2,
    measured: Option<f64>,
    expected: Option<f64>,
}

impl ReferenceLaw for Stefan {
    fn kind(&self) -> &'static str {
        "relative L2 error of the melting front position over frames (Neumann solution)"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        let particles = frame.particles;
        let Some(solid_fraction) = particles.shared.get("solid_fraction") else {
            return;
        };
        if frame.time <= 0.0 {
            return;
        }
        let (mut melted, mut total) = (0.0, 0.0);
        for (f, v) in solid_fraction.iter().zip(&particles.volume0) {
            melted += (1.0 - f) * v;
            total += v;
        }
        let front = self.length * melted / total.max(1e-300);
        let exact = 2.0 * self.lambda * (self.liquid_diffusivity * frame.time).sqrt();
        self.error.add((front - exact).powi(2), exact * exact);
        self.measured = Some(front);
        self.expected = Some(exact);
    }

    fn error(&self) -> Option<f64> {
        self.error.value()
    }

    fn expected(&self) -> Option<f64> {
        self.expected
    }

    fn measured(&self) -> Option<f64> {
        self.measured
    }
}

fn build(p: StefanParams, path: &str, scene: &Scene) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    c.axis("axis", p.axis, scene.dimension as usize);
    c.finite("surface", p.surface);
    c.positive("length", p.length);
    c.positive("latent_heat", p.latent_heat);
    if p.surface_temperature.is_nan() || p.surface_temperature <= p.melt_temperature {
        c.error(
            "surface_temperature",
            "must be above the melting temperature (the body melts)",
        );
    }
    if !(p.initial_temperature <= p.melt_temperature && p.initial_temperature > 0.0) {
        c.error(
            "initial_temperature",
            "must be positive and at most the melting temperature",
        );
    }
    for (name, phase) in [("liquid", &p.liquid), ("solid", &p.solid)] {
        c.positive(&format!("{name}.conductivity"), phase.conductivity);
        c.positive(&format!("{name}.specific_heat"), phase.specific_heat);
        c.positive(&format!("{name}.density"), phase.density);
    }
    if (p.liquid.density - p.solid.density).abs() > 1e-9 * p.liquid.density {
        c.error(
            "solid.density",
            "Neumann's solution needs equal liquid and solid densities",
        );
    }
    c.finish()?;
    let lambda = neumann_lambda(
        p.liquid.specific_heat * (p.surface_temperature - p.melt_temperature) / p.latent_heat,
        p.solid.specific_heat * (p.melt_temperature - p.initial_temperature) / p.latent_heat,
        (p.liquid.diffusivity() / p.solid.diffusivity()).sqrt(),
    );
    Ok(Arc::new(Stefan {
        length: p.length,
        liquid_diffusivity: p.liquid.diffusivity(),
        lambda,
        error: RelativeL2::default(),
        measured: None,
        expected: None,
    }))
}

/// The `stefan` reference type.
pub fn factory() -> Box<dyn ReferenceFactory> {
    Box::new(TypedReferenceFactory::new("stefan", build))
}

/// Neumann's similarity constant λ of the two-phase Stefan (melting) problem: the front is
/// at `2λ√(α_l t)`. `stefan_liquid` = c_l (T_surface − T_melt)/L, `stefan_solid` =
/// c_s (T_melt − T_initial)/L, `ratio` = √(α_l/α_s); equal densities. Solves
/// `St_l e^{−λ²}/erf λ − St_s e^{−ν²λ²}/(ν erfc νλ) = λ√π` by bisection (the left side
/// falls and the right side rises with λ). `stefan_solid = 0` is the one-phase problem.
pub fn neumann_lambda(stefan_liquid: f64, stefan_solid: f64, ratio: f64) -> f64 {
    let residual = |l: f64| {
        stefan_liquid * (-l * l).exp() / erf(l)
            - stefan_solid * (-(ratio * l).powi(2)).exp() / (ratio * erfc(ratio * l))
            - l * PI.sqrt()
    };
    bisect(|l| residual(l) > 0.0, 1e-9, 10.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neumann_one_phase_matches_the_small_stefan_number_limit() {
        // λ ≈ √(St/2) for small St.
        let st = 0.01;
        let l = neumann_lambda(st, 0.0, 1.0);
        assert!((l - (st / 2.0).sqrt()).abs() / l < 0.01, "{l}");
        // A subcooled solid slows the front.
        assert!(neumann_lambda(st, 0.05, 1.0) < l);
    }
}
