//! Pressure-driven filling of a parallel-plate gap: liquid pushed in from a reservoir at a
//! gauge pressure Δp above the flow front's (a pressure inlet, `inflow.pressure`), slow
//! enough that the flow behind the front is plane Poiseuille flow. The mean velocity
//! h²Δp/(12μx) over the filled length x gives x·dx/dt = h²Δp/(12μ), so
//! x² = h²Δp·t/(6μ): the capillary law of `capillary_filling` with the meniscus's
//! 2σcosθ/h replaced by the inlet's Δp.

use crate::capillary_filling::{FrontGauge, check_gap, gap_depth, observe_front};
use mpm_core::output::Comparison;
use mpm_core::reference::{
    Frame, Reference, ReferenceFactory, ReferenceLaw, RelativeL2, TypedReferenceFactory,
};
use mpm_core::scene::{Issue, Scene};
use mpm_core::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// Pressure-driven filling of a parallel-plate gap from an inlet at its entrance: the front
/// is `x = √(h² Δp t / (6μ))` from the entrance, held at `length` once the gap is full
/// (fill time `6μL²/(h²Δp)`), t from `start`. The measured front is the volume of the
/// liquid particles past the entrance over the gap's cross-section (`gap` times the
/// domain's extent along the axes other than `axis` and `across`), at most `length`;
/// error: relative L2 error of the front over the output frames after `start`. The
/// comparison `fill_time` appears once the front reached the end.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct PressureFillingParams {
    /// Axis along the gap (the flow direction).
    pub axis: usize,
    /// Coordinate of the gap's entrance along the axis (the inlet face).
    pub entrance: f64,
    /// Length of the gap along the axis, m.
    pub length: f64,
    /// Height of the gap between the plates, m.
    pub gap: f64,
    /// Gauge pressure Δp of the inlet above the front's, Pa.
    pub pressure: f64,
    /// Dynamic viscosity of the liquid, Pa s.
    pub viscosity: f64,
    /// Time the flow starts (the inlet's `start`), s.
    #[serde(default)]
    pub start: f64,
    /// Axis across the gap, normal to the plates; default: the first axis other than
    /// `axis`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub across: Option<usize>,
    /// Materials whose particles make up the gap (empty: every particle).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub materials: Vec<String>,
}

/// The front error accumulated over frames, and the front history until the gap filled.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct PressureFilling {
    p: PressureFillingParams,
    /// The gap's extent along the axes other than `axis` and `across` (1 in 2D), m.
    depth: f64,
    error: RelativeL2,
    measured: Option<f64>,
    expected: Option<f64>,
    /// Time and measured front of every frame observed so far, until the front reached
    /// the end.
    fronts: Vec<(f64, f64)>,
    comparisons: Vec<Comparison>,
}

impl ReferenceLaw for PressureFilling {
    fn kind(&self) -> &'static str {
        "relative L2 error of the liquid front position over frames (pressure-driven filling between plates, x² = h²Δp t/(6μ))"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        let p = &self.p;
        let gauge = FrontGauge {
            axis: p.axis,
            entrance: p.entrance,
            length: p.length,
            gap: p.gap,
            depth: self.depth,
            materials: &p.materials,
        };
        let front = gauge.front(frame.particles);
        let t = frame.time - p.start;
        let t_fill = pressure_fill_time(p.length, p.gap, p.pressure, p.viscosity);
        if t < 0.0 {
            return;
        }
        if let Some(c) = observe_front(&mut self.fronts, t, front, p.length, t_fill) {
            self.comparisons.push(c);
        }
        if t <= 0.0 {
            return;
        }
        let exact = pressure_front(t, p.length, p.gap, p.pressure, p.viscosity);
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

    fn comparisons(&self) -> Vec<Comparison> {
        self.comparisons.clone()
    }
}

/// The problems of a `pressure_filling` section in a scene.
fn check(p: &PressureFillingParams, path: &str, scene: &Scene) -> Result<(), Vec<Issue>> {
    let mut c = Checks::new(path);
    check_gap(
        &mut c,
        scene,
        p.axis,
        p.across,
        &p.materials,
        p.entrance,
        p.length,
        p.gap,
    );
    c.positive("pressure", p.pressure);
    c.positive("viscosity", p.viscosity);
    if !(p.start.is_finite() && p.start >= 0.0) {
        c.error("start", "must be a finite time >= 0");
    }
    c.finish()
}

fn build(
    p: PressureFillingParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    check(&p, path, scene)?;
    let depth = gap_depth(scene, p.axis, p.across);
    Ok(Arc::new(PressureFilling {
        p,
        depth,
        error: RelativeL2::default(),
        measured: None,
        expected: None,
        fronts: Vec::new(),
        comparisons: Vec::new(),
    }))
}

/// The `pressure_filling` reference type.
pub fn factory() -> Box<dyn ReferenceFactory> {
    Box::new(TypedReferenceFactory::new("pressure_filling", build))
}

/// Liquid front of pressure-driven filling between parallel plates `gap` apart:
/// `√(h² Δp t / (6μ))` from the entrance at time `t` after the flow started, held at
/// `length` once the gap is full.
pub fn pressure_front(t: f64, length: f64, gap: f64, pressure: f64, viscosity: f64) -> f64 {
    if t <= 0.0 {
        return 0.0;
    }
    (gap * gap * pressure * t / (6.0 * viscosity))
        .sqrt()
        .min(length)
}

/// Time pressure-driven filling between parallel plates takes to reach `length` (see
/// [`pressure_front`]): `6 μ L² / (h² Δp)`.
pub fn pressure_fill_time(length: f64, gap: f64, pressure: f64, viscosity: f64) -> f64 {
    6.0 * viscosity * length * length / (gap * gap * pressure)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capillary_filling::{capillary_fill_time, capillary_front};
    use mpm_core::reference::{assert_each_names_its_path, test_particles};
    use mpm_core::scene::test_scene;

    fn settings(overrides: serde_json::Value) -> serde_json::Value {
        let mut r = serde_json::json!({
            "type": "pressure_filling", "axis": 0, "entrance": 0.0, "length": 8e-3,
            "gap": 1e-3, "pressure": 100.0, "viscosity": 1.0
        });
        for (k, v) in overrides.as_object().expect("an object") {
            r[k] = v.clone();
        }
        r
    }

    #[test]
    fn pressure_filling_checks_name_their_json_paths() {
        let cases = [
            (serde_json::json!({"axis": 2}), "reference.axis", "below 2"),
            (serde_json::json!({"gap": 0.0}), "reference.gap", "> 0"),
            (
                serde_json::json!({"pressure": -1.0}),
                "reference.pressure",
                "> 0",
            ),
            (
                serde_json::json!({"viscosity": 0.0}),
                "reference.viscosity",
                "> 0",
            ),
            (
                serde_json::json!({"start": -1.0}),
                "reference.start",
                ">= 0",
            ),
            (
                serde_json::json!({"materials": ["glue"]}),
                "reference.materials[0]",
                "no material",
            ),
        ];
        assert_each_names_its_path(factory().as_ref(), &settings(serde_json::json!({})), &cases);
    }

    /// The law is the capillary one with the meniscus's pressure 2σcosθ/h for Δp.
    #[test]
    fn the_law_is_the_capillary_law_with_the_inlet_pressure() {
        let (gap, sigma, theta, mu, length) = (5e-5, 0.03, 30.0, 2.0, 4e-3);
        let dp = 2.0 * sigma * f64::cos(f64::to_radians(theta)) / gap;
        for t in [0.5, 3.0, 40.0] {
            let a = pressure_front(t, length, gap, dp, mu);
            let b = capillary_front(t, length, gap, sigma, theta, mu);
            assert!((a - b).abs() < 1e-12 * b, "{a} {b}");
        }
        let a = pressure_fill_time(length, gap, dp, mu);
        let b = capillary_fill_time(length, gap, sigma, theta, mu);
        assert!((a - b).abs() < 1e-12 * b);
    }

    /// Liquid particles past the entrance: the front is their volume over the gap, and a
    /// front on the law reads no error; the full gap gives the fill time.
    #[test]
    fn pressure_filling_reads_the_front_from_the_particles() {
        let json = settings(serde_json::json!({"start": 0.5}));
        let mut r = factory()
            .build(&json, "reference", &test_scene(2))
            .expect("a valid reference")
            .start();
        let (gap, length) = (1e-3, 8e-3);
        let t_fill = pressure_fill_time(length, gap, 100.0, 1.0);
        // Four particles of volume gap × length / 4 each; one waits before the entrance
        // until the front needs it. Frames at a quarter and at the whole fill time.
        let volume = gap * length / 4.0;
        for (k, t) in [0.25 * t_fill, t_fill].into_iter().enumerate() {
            let front = pressure_front(t, length, gap, 100.0, 1.0);
            let inside = front / length * 4.0;
            let volumes: Vec<f64> = (0..4)
                .map(|i| volume * (inside - i as f64).clamp(0.0, 1.0))
                .collect();
            let p = test_particles(&[[1e-3, 0.0]; 4], &volumes, &[]);
            r.observe_2d(mpm_core::reference::Frame {
                particles: &p,
                time: 0.5 + t,
                last: k == 1,
            });
        }
        assert!(r.error().unwrap() < 1e-12, "{:?}", r.error());
        let c = r.comparisons();
        assert_eq!(c.len(), 1);
        assert!(c[0].relative_difference.abs() < 1e-9, "{:?}", c[0]);
    }
}
