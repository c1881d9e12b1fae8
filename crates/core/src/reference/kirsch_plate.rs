//! A plate with a circular hole under uniaxial tension σ (Kirsch 1898): in polar
//! coordinates about the hole's centre, with θ measured from the load axis,
//!
//! σ_rr = σ/2 (1 − a²/r²) + σ/2 (1 − 4a²/r² + 3a⁴/r⁴) cos 2θ,
//! σ_θθ = σ/2 (1 + a²/r²) − σ/2 (1 + 3a⁴/r⁴) cos 2θ,
//! σ_rθ = −σ/2 (1 + 2a²/r² − 3a⁴/r⁴) sin 2θ,
//!
//! so the stress along the load reaches 3σ at the hole's edge across the load. The field is
//! the same in plane strain and plane stress (2D only).
//!
//! The nominal stress σ is measured, not given: the mean stress along the load of the
//! particles in a band across the whole plate (`nominal_band`, two coordinates along the
//! load axis clear of the hole), which equilibrium makes the load over the gross section
//! whatever the hole does. The error is the relative L2 difference between the particles'
//! stress along the load and Kirsch's at their positions, over the near field
//! a < r < `near_field`·a. An infinite plate's field: a finite plate of width W raises the
//! edge stress (Heywood: K = (2 + (1 − 2a/W)³)/(1 − 2a/W) on the gross section); the metrics
//! give that comparison when `width` is set.

use super::{Frame, Reference, ReferenceFactory, ReferenceLaw, TypedReferenceFactory};
use crate::output::Comparison;
use crate::scene::{Issue, Scene};
use crate::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// Parameters of the `kirsch_plate` reference.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct KirschPlateParams {
    /// Centre of the hole, m.
    pub center: [f64; 2],
    /// Radius of the hole, m.
    pub hole_radius: f64,
    /// Axis of the applied tension.
    pub load_axis: usize,
    /// Two coordinates along the load axis bounding the band whose mean stress is the
    /// nominal stress (the band must span the plate's whole width and miss the hole).
    pub nominal_band: [f64; 2],
    /// Outer radius of the compared near field, in hole radii.
    #[serde(default = "default_near_field")]
    pub near_field: f64,
    /// Full width of the plate across the load (the whole plate, not a symmetric part), m,
    /// for Heywood's finite-width edge stress in the metrics.
    #[serde(default)]
    pub width: Option<f64>,
}

fn default_near_field() -> f64 {
    3.0
}

/// Kirsch's stress along the load axis at distance `r` from the hole's centre and angle
/// `theta` from the load axis, per unit nominal stress.
pub fn kirsch_stress_along_load(hole_radius: f64, r: f64, theta: f64) -> f64 {
    let q = (hole_radius / r).powi(2);
    let (s2, c2) = (2.0 * theta).sin_cos();
    let rr = 0.5 * (1.0 - q) + 0.5 * (1.0 - 4.0 * q + 3.0 * q * q) * c2;
    let tt = 0.5 * (1.0 + q) - 0.5 * (1.0 + 3.0 * q * q) * c2;
    let rt = -0.5 * (1.0 + 2.0 * q - 3.0 * q * q) * s2;
    let (s, c) = theta.sin_cos();
    rr * c * c + tt * s * s - 2.0 * rt * s * c
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct KirschPlate {
    p: KirschPlateParams,
    /// (nominal stress, relative L2 error, peak stress concentration and Kirsch's at the
    /// same particle) of the last frame.
    measured: Option<(f64, f64, f64, f64)>,
}

impl ReferenceLaw for KirschPlate {
    fn kind(&self) -> &'static str {
        "relative L2 error of the stress along the load near a circular hole in a plate under tension (Kirsch 1898)"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        if !frame.last || D != 2 {
            return;
        }
        let p = &self.p;
        let (l, t) = (p.load_axis, 1 - p.load_axis);
        let particles = frame.particles;
        let [lo, hi] = [
            p.nominal_band[0].min(p.nominal_band[1]),
            p.nominal_band[0].max(p.nominal_band[1]),
        ];
        let (mut sum, mut count) = (0.0, 0usize);
        for i in 0..particles.len() {
            let x = particles.position[i][l];
            if x >= lo && x <= hi {
                sum += particles.stress[i][(l, l)];
                count += 1;
            }
        }
        if count == 0 {
            return;
        }
        let nominal = sum / count as f64;
        let a = p.hole_radius;
        let (mut num, mut den) = (0.0, 0.0);
        let mut peak = (f64::NEG_INFINITY, 0.0);
        for i in 0..particles.len() {
            let x = particles.position[i];
            let (dl, dt) = (x[l] - p.center[l], x[t] - p.center[t]);
            let r = dl.hypot(dt);
            if r <= a || r > p.near_field * a {
                continue;
            }
            let theta = dt.abs().atan2(dl.abs());
            let kirsch = nominal * kirsch_stress_along_load(a, r, theta);
            let s = particles.stress[i][(l, l)];
            num += (s - kirsch).powi(2);
            den += kirsch * kirsch;
            if s > peak.0 {
                peak = (s, kirsch);
            }
        }
        if den > 0.0 && nominal != 0.0 {
            self.measured = Some((
                nominal,
                (num / den).sqrt(),
                peak.0 / nominal,
                peak.1 / nominal,
            ));
        }
    }

    fn error(&self) -> Option<f64> {
        self.measured.map(|m| m.1)
    }

    fn expected(&self) -> Option<f64> {
        self.measured.map(|m| m.3)
    }

    fn measured(&self) -> Option<f64> {
        self.measured.map(|m| m.2)
    }

    fn comparisons(&self) -> Vec<Comparison> {
        let Some((_, _, peak, _)) = self.measured else {
            return Vec::new();
        };
        let compare = |quantity: &str, reference: f64| Comparison {
            quantity: quantity.into(),
            measured: peak,
            reference,
            relative_difference: (peak - reference) / reference,
        };
        let mut out = vec![compare("peak_stress_concentration_vs_kirsch_edge", 3.0)];
        if let Some(w) = self.p.width {
            let ratio = 2.0 * self.p.hole_radius / w;
            let heywood = (2.0 + (1.0 - ratio).powi(3)) / (1.0 - ratio);
            out.push(compare(
                "peak_stress_concentration_vs_heywood_edge",
                heywood,
            ));
        }
        out
    }
}

fn build(
    p: KirschPlateParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    if scene.dimension != 2 {
        c.error("", "the kirsch_plate reference is two-dimensional");
    }
    c.axis("load_axis", p.load_axis, 2);
    c.finite("center[0]", p.center[0]);
    c.finite("center[1]", p.center[1]);
    c.positive("hole_radius", p.hole_radius);
    c.finite("nominal_band[0]", p.nominal_band[0]);
    c.finite("nominal_band[1]", p.nominal_band[1]);
    if p.load_axis < 2 {
        let from_centre = [
            p.nominal_band[0] - p.center[p.load_axis],
            p.nominal_band[1] - p.center[p.load_axis],
        ];
        if from_centre[0] * from_centre[1] < 0.0
            || from_centre[0].abs().min(from_centre[1].abs()) <= p.hole_radius
        {
            c.error(
                "nominal_band",
                "must lie clear of the hole along the load axis",
            );
        }
    }
    if !(p.near_field > 1.0 && p.near_field.is_finite()) {
        c.error("near_field", "must be a finite number above 1 (hole radii)");
    }
    if let Some(w) = p.width
        && !(w.is_finite() && w > 2.0 * p.hole_radius)
    {
        c.error("width", "must be finite and wider than the hole");
    }
    c.finish()?;
    Ok(Arc::new(KirschPlate { p, measured: None }))
}

/// The `kirsch_plate` reference type.
pub fn factory() -> Box<dyn ReferenceFactory> {
    Box::new(TypedReferenceFactory::new("kirsch_plate", build))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn kirsch_gives_three_at_the_edge_across_the_load_and_minus_one_along_it() {
        let a = 1e-3;
        assert!((kirsch_stress_along_load(a, a, FRAC_PI_2) - 3.0).abs() < 1e-12);
        // Along the load axis at the edge the hoop stress is −σ, but the stress along the
        // load there is the radial one: zero (a free surface).
        assert!(kirsch_stress_along_load(a, a, 0.0).abs() < 1e-12);
        // Far away the plate carries the nominal stress.
        assert!((kirsch_stress_along_load(a, 1e3 * a, 0.3) - 1.0).abs() < 1e-5);
    }
}
