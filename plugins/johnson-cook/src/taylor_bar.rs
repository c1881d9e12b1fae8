//! Taylor impact reference: a bar hits a rigid wall; its final length, impact-face
//! (mushroom) diameter and peak plastic strain are compared with published values.

use mpm_core::output::Comparison;
use mpm_core::particles::Particles;
use mpm_core::reference::{
    Frame, Reference, ReferenceFactory, ReferenceLaw, TypedReferenceFactory, compare,
};
use mpm_core::scene::{Issue, Scene};
use mpm_core::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// Taylor impact: a bar hits a rigid wall; the run compares its final length, the
/// diameter of its impact face (mushroom) and its peak plastic strain with published
/// values; error: relative error of the final length.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct TaylorBarParams {
    /// Axis of the bar (the impact direction).
    pub axis: usize,
    /// Coordinate of the wall along the axis.
    pub wall: f64,
    /// Coordinates of the bar's centre line in the other directions, in axis order
    /// (a quarter-symmetry model puts it on the symmetry planes).
    pub center: Vec<f64>,
    /// Published final length, m.
    pub final_length: f64,
    /// Published final diameter of the impact face, m.
    pub mushroom_diameter: f64,
    /// Published peak equivalent plastic strain, if given.
    #[serde(default)]
    pub peak_plastic_strain: Option<f64>,
    /// Where the published values come from (for the reader of the scene and its results;
    /// the run does not use it).
    #[allow(dead_code)]
    pub source: String,
}

/// The bar's shape measured at the last frame.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct TaylorBar {
    p: TaylorBarParams,
    measured: Option<f64>,
    comparisons: Vec<Comparison>,
}

impl ReferenceLaw for TaylorBar {
    fn kind(&self) -> &'static str {
        "relative error of the final bar length against the published Taylor impact value"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        if !frame.last {
            return;
        }
        let p = &self.p;
        let shape = taylor_bar_shape(frame.particles, p.axis, p.wall, &p.center);
        self.measured = Some(shape.length);
        self.comparisons = vec![
            compare("final_length", shape.length, p.final_length),
            compare(
                "mushroom_diameter",
                shape.impact_diameter,
                p.mushroom_diameter,
            ),
        ];
        if let Some(e) = p.peak_plastic_strain {
            self.comparisons
                .push(compare("peak_plastic_strain", shape.peak_plastic_strain, e));
        }
    }

    fn error(&self) -> Option<f64> {
        let m = self.measured?;
        Some((m - self.p.final_length).abs() / self.p.final_length.abs())
    }

    fn expected(&self) -> Option<f64> {
        Some(self.p.final_length)
    }

    fn measured(&self) -> Option<f64> {
        self.measured
    }

    fn comparisons(&self) -> Vec<Comparison> {
        self.comparisons.clone()
    }
}

fn build(p: TaylorBarParams, path: &str, scene: &Scene) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let dim = scene.dimension as usize;
    let mut c = Checks::new(path);
    c.axis("axis", p.axis, dim);
    c.finite("wall", p.wall);
    if p.center.len() != dim - 1 || !p.center.iter().all(|c| c.is_finite()) {
        c.error("center", format!("must hold {} finite numbers", dim - 1));
    }
    c.positive("final_length", p.final_length);
    c.positive("mushroom_diameter", p.mushroom_diameter);
    if let Some(e) = p.peak_plastic_strain {
        c.positive("peak_plastic_strain", e);
    }
    c.finish()?;
    Ok(Arc::new(TaylorBar {
        p,
        measured: None,
        comparisons: Vec::new(),
    }))
}

/// The `taylor_bar` reference type.
pub fn factory() -> Box<dyn ReferenceFactory> {
    Box::new(TypedReferenceFactory::new("taylor_bar", build))
}

/// Measured shape of an impacted bar.
struct BarShape {
    length: f64,
    impact_diameter: f64,
    peak_plastic_strain: f64,
}

/// Length, impact-face diameter and peak plastic strain of a bar standing on a wall.
///
/// Particle centres sit half a particle spacing inside the surface, so half the spacing
/// (from the particle's reference volume) is added at each measured surface. The impact
/// face is the particles within one spacing of the lowest one, and the length is measured
/// from there, so a bar that has rebounded off the wall measures true. The plastic strain is the state
/// field `plastic_strain` of whichever material has one (0 when none does).
fn taylor_bar_shape<const D: usize>(
    particles: &Particles<D>,
    axis: usize,
    wall: f64,
    center: &[f64],
) -> BarShape {
    let mut far = 0.0f64;
    let mut radius = 0.0f64;
    // The bar may have rebounded off the wall: the impact face is its lowest layer.
    let lowest = (0..particles.len())
        .map(|p| (particles.position[p][axis] - wall).abs())
        .fold(f64::INFINITY, f64::min);
    for p in 0..particles.len() {
        let x = particles.position[p];
        let half = 0.5 * particles.volume0[p].powf(1.0 / D as f64);
        let height = (x[axis] - wall).abs();
        far = far.max(height - lowest + 2.0 * half);
        if height - lowest < 2.0 * half {
            let mut r2 = 0.0;
            for (k, d) in (0..D).filter(|&d| d != axis).enumerate() {
                r2 += (x[d] - center.get(k).copied().unwrap_or(0.0)).powi(2);
            }
            radius = radius.max(r2.sqrt() + half);
        }
    }
    let mut peak = 0.0f64;
    for group in &particles.groups {
        let specs = group.material.state_fields();
        if let Some(f) = specs.iter().position(|s| s.name == "plastic_strain") {
            let c = specs[f].components;
            for value in group.state[f].iter().step_by(c) {
                peak = peak.max(*value);
            }
        }
    }
    BarShape {
        length: far,
        impact_diameter: 2.0 * radius,
        peak_plastic_strain: peak,
    }
}
