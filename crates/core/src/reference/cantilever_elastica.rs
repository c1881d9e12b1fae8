//! Static tip deflection of a cantilever under its own weight (the heavy elastica).

use super::{Frame, Reference, ReferenceFactory, ReferenceLaw, TypedReferenceFactory};
use crate::scene::{Issue, Scene};
use crate::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// Static tip deflection of a cantilever under its own weight, from the large-deflection
/// elastica; error: relative error of the tip deflection at the end time.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct CantileverElasticaParams {
    /// Axis along the beam (0 = x); gravity acts along the other in-plane axis.
    pub axis: usize,
    /// Coordinate of the clamped end along the axis.
    pub clamped_end: f64,
    /// Beam length.
    pub length: f64,
    /// Beam thickness (in the direction of gravity).
    pub thickness: f64,
    /// Young's modulus, Pa.
    pub youngs_modulus: f64,
    /// Poisson ratio (plane strain uses E/(1-ν²)).
    pub poisson_ratio: f64,
    /// Density, kg/m³.
    pub density: f64,
    /// Gravity magnitude, m/s².
    pub gravity: f64,
}

/// The tip deflection measured at the last frame against the elastica's.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct CantileverElastica {
    axis: usize,
    clamped_end: f64,
    expected: f64,
    measured: Option<f64>,
}

impl ReferenceLaw for CantileverElastica {
    fn kind(&self) -> &'static str {
        "relative error of the tip deflection at the end time against the heavy elastica"
    }

    fn needs_initial_positions(&self) -> bool {
        true
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        if !frame.last {
            return;
        }
        // Mean deflection of the particles in the free end's last layer.
        let particles = frame.particles;
        let axis = self.axis;
        let tip = (0..particles.len())
            .map(|p| particles.initial_position[p][axis])
            .fold(f64::NEG_INFINITY, f64::max);
        let across = if axis == 0 { 1 } else { 0 };
        let (mut sum, mut count) = (0.0, 0usize);
        for p in 0..particles.len() {
            if tip - particles.initial_position[p][axis] < 1e-9 * (tip - self.clamped_end).abs() {
                sum += particles.initial_position[p][across] - particles.position[p][across];
                count += 1;
            }
        }
        self.measured = Some(sum / count.max(1) as f64);
    }

    fn error(&self) -> Option<f64> {
        let m = self.measured?;
        Some((m - self.expected).abs() / self.expected.abs())
    }

    fn expected(&self) -> Option<f64> {
        Some(self.expected)
    }

    fn measured(&self) -> Option<f64> {
        self.measured
    }
}

fn build(
    p: CantileverElasticaParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    c.axis("axis", p.axis, scene.dimension as usize);
    c.finite("clamped_end", p.clamped_end);
    c.positive("length", p.length);
    c.positive("thickness", p.thickness);
    c.positive("youngs_modulus", p.youngs_modulus);
    c.positive("density", p.density);
    c.positive("gravity", p.gravity);
    if !(p.poisson_ratio > -1.0 && p.poisson_ratio < 0.5) {
        c.error("poisson_ratio", "must be in (-1, 0.5)");
    }
    c.finish()?;
    let e_plane = p.youngs_modulus / (1.0 - p.poisson_ratio * p.poisson_ratio);
    let inertia = p.thickness.powi(3) / 12.0;
    let load = p.density * p.gravity * p.thickness;
    let alpha = load * p.length.powi(3) / (e_plane * inertia);
    Ok(Arc::new(CantileverElastica {
        axis: p.axis,
        clamped_end: p.clamped_end,
        expected: heavy_elastica_tip_deflection(alpha) * p.length,
        measured: None,
    }))
}

/// The `cantilever_elastica` reference type.
pub fn factory() -> Box<dyn ReferenceFactory> {
    Box::new(TypedReferenceFactory::new("cantilever_elastica", build))
}

/// Tip deflection over length of a clamped heavy elastica (inextensible beam under its own
/// uniform weight), with `alpha = w L³ / (E I)`.
///
/// Solves θ'' = −α (1 − s) cos θ on s ∈ [0, 1] with θ(0) = 0, θ'(1) = 0 by shooting on θ'(0)
/// (bisection; the end moment grows monotonically with it) and RK4, then integrates sin θ.
pub fn heavy_elastica_tip_deflection(alpha: f64) -> f64 {
    const STEPS: usize = 4000;
    let integrate = |k: f64| -> (f64, f64) {
        let h = 1.0 / STEPS as f64;
        let (mut th, mut om, mut defl) = (0.0f64, k, 0.0f64);
        let rhs = |s: f64, th: f64, om: f64| (om, -alpha * (1.0 - s) * th.cos(), th.sin());
        for i in 0..STEPS {
            let s = i as f64 * h;
            let k1 = rhs(s, th, om);
            let k2 = rhs(s + h / 2.0, th + h / 2.0 * k1.0, om + h / 2.0 * k1.1);
            let k3 = rhs(s + h / 2.0, th + h / 2.0 * k2.0, om + h / 2.0 * k2.1);
            let k4 = rhs(s + h, th + h * k3.0, om + h * k3.1);
            th += h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
            om += h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
            defl += h / 6.0 * (k1.2 + 2.0 * k2.2 + 2.0 * k3.2 + k4.2);
        }
        (om, defl)
    };
    integrate(crate::math::bisect(
        |x| integrate(x).0 < 0.0,
        0.0,
        alpha.max(1e-300),
    ))
    .1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elastica_matches_linear_beam_theory_for_small_loads() {
        // Small deflection: δ/L = α/8.
        let alpha = 1e-3;
        let d = heavy_elastica_tip_deflection(alpha);
        assert!((d - alpha / 8.0).abs() / (alpha / 8.0) < 1e-4, "{d}");
    }

    #[test]
    fn elastica_is_below_linear_theory_for_large_loads() {
        // Large loads: the beam hangs, δ/L < 1 and below α/8.
        let d = heavy_elastica_tip_deflection(10.0);
        assert!(d < 10.0 / 8.0 && d > 0.5 && d < 1.0, "{d}");
    }
}
