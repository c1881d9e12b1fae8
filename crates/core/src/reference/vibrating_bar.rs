//! First axial mode of a fixed–free elastic bar: displacement u = (A/ω) sin(π s / 2L) sin(ω t).

use super::{Frame, Reference, ReferenceFactory, ReferenceLaw, RelativeL2, TypedReferenceFactory};
use crate::math::Vector;
use crate::scene::{Issue, Scene};
use crate::section::Checks;
use serde::Deserialize;
use std::f64::consts::PI;
use std::sync::Arc;

/// First axial mode of a fixed–free elastic bar; error: relative L2 error of particle
/// displacement over all output frames.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct VibratingBarParams {
    /// Axis of the bar.
    pub axis: usize,
    /// Coordinate of the fixed end.
    pub fixed_end: f64,
    /// Length of the bar.
    pub length: f64,
    /// Peak velocity amplitude at the free end (as in the initial velocity).
    pub amplitude: f64,
    /// Young's modulus, Pa (with ν = 0 the strip is one-dimensional).
    pub youngs_modulus: f64,
    /// Density, kg/m³.
    pub density: f64,
}

/// The bar's displacement error accumulated over frames.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct VibratingBar {
    p: VibratingBarParams,
    error: RelativeL2,
}

impl ReferenceLaw for VibratingBar {
    fn kind(&self) -> &'static str {
        "relative L2 error of particle displacement over all output frames (vibrating bar, first mode)"
    }

    fn needs_initial_positions(&self) -> bool {
        true
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        // Displacement rather than velocity: the explicit update's velocity is second-order
        // accurate only at half steps, its positions at whole steps.
        let p = &self.p;
        let particles = frame.particles;
        let omega = PI * (p.youngs_modulus / p.density).sqrt() / (2.0 * p.length);
        let phase = (omega * frame.time).sin() * p.amplitude / omega;
        for i in 0..particles.len() {
            let x0 = particles.initial_position[i];
            let s = x0[p.axis] - p.fixed_end;
            let mut u_ref = Vector::<D>::zeros();
            u_ref[p.axis] = (PI * s / (2.0 * p.length)).sin() * phase;
            let u = particles.position[i] - x0;
            let m = particles.mass[i];
            self.error
                .add(m * (u - u_ref).norm_squared(), m * u_ref.norm_squared());
        }
    }

    fn error(&self) -> Option<f64> {
        self.error.value()
    }
}

fn build(
    p: VibratingBarParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    c.axis("axis", p.axis, scene.dimension as usize);
    if !p.fixed_end.is_finite() || !p.amplitude.is_finite() {
        c.error("", "fixed_end and amplitude must be finite");
    }
    c.positive("length", p.length);
    c.positive("youngs_modulus", p.youngs_modulus);
    c.positive("density", p.density);
    c.finish()?;
    Ok(Arc::new(VibratingBar {
        p,
        error: RelativeL2::default(),
    }))
}

/// The `vibrating_bar` reference type.
pub fn factory() -> Box<dyn ReferenceFactory> {
    Box::new(TypedReferenceFactory::new("vibrating_bar", build))
}
