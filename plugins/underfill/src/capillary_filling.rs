//! Capillary filling of a parallel-plate gap (Washburn/Lucas law): the closed form and the
//! reference that compares the measured liquid front and fill time with it.

use mpm_core::output::Comparison;
use mpm_core::particles::Particles;
use mpm_core::reference::{
    Frame, Reference, ReferenceFactory, ReferenceLaw, RelativeL2, TypedReferenceFactory, compare,
};
use mpm_core::scene::{Issue, Scene};
use mpm_core::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// Capillary filling of a parallel-plate gap from a reservoir (Washburn/Lucas law): the
/// front is `x = √(h σ cosθ t / (3μ))` from the entrance, held at `length` once the gap
/// is full (fill time `3μL²/(hσ cosθ)`). The measured front is `length × (liquid volume /
/// gap volume)` from the shared particle field `fill` of the particles in the gap (the
/// gap-averaged mode), or, for liquid particles (no `fill` field), the volume of the
/// particles past the entrance over the gap's cross-section (`gap` times the domain's
/// extent along the axes other than `axis` and `across`, capped at `length`); error:
/// relative L2 error of the front over the output frames after t = 0. The comparison
/// `fill_time` appears once the front reached the end.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct CapillaryFillingParams {
    /// Axis along the gap (the flow direction).
    pub axis: usize,
    /// Coordinate of the gap's entrance along the axis (where the reservoir is).
    pub entrance: f64,
    /// Length of the gap along the axis, m.
    pub length: f64,
    /// Height of the gap between the plates, m.
    pub gap: f64,
    /// Surface tension of the liquid, N/m.
    pub surface_tension: f64,
    /// Contact angle of the liquid on the plates, degrees, 0 <= θ < 90 (wetting).
    pub contact_angle: f64,
    /// Dynamic viscosity of the liquid, Pa s.
    pub viscosity: f64,
    /// Axis across the gap, normal to the plates (liquid particles in 3D: the gap's
    /// cross-section spans the other one); default: the first axis other than `axis`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub across: Option<usize>,
    /// Materials whose particles make up the gap (empty: every particle), when the scene
    /// has other bodies too (the die and substrate of a package's cross-section).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub materials: Vec<String>,
    /// Navier slip length b of both plates, m (> 0), when they have one: the flow between
    /// them carries 1 + 6b/h times the no-slip flux, so x² grows by that factor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slip_length: Option<f64>,
}

/// The front error accumulated over frames, and the front history until the gap filled.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct CapillaryFilling {
    p: CapillaryFillingParams,
    /// For liquid particles: the gap's extent along the axes other than `axis` and
    /// `across` (1 in 2D), m.
    #[serde(default = "unit_depth")]
    depth: f64,
    error: RelativeL2,
    measured: Option<f64>,
    expected: Option<f64>,
    /// Time and measured front of every frame observed so far, until the front reached
    /// the end.
    fronts: Vec<(f64, f64)>,
    comparisons: Vec<Comparison>,
}

impl ReferenceLaw for CapillaryFilling {
    fn kind(&self) -> &'static str {
        "relative L2 error of the liquid front position over frames (capillary filling between plates, x² = hσcosθ t/(3μ), × (1 + 6b/h) with Navier plates)"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        let CapillaryFillingParams {
            length,
            gap,
            surface_tension,
            contact_angle,
            viscosity,
            slip_length,
            ..
        } = self.p;
        // Slipping plates: the no-slip law with the viscosity over 1 + 6b/h.
        let viscosity = viscosity / (1.0 + 6.0 * slip_length.unwrap_or(0.0) / gap);
        let gauge = FrontGauge {
            axis: self.p.axis,
            entrance: self.p.entrance,
            length,
            gap,
            depth: self.depth,
            materials: &self.p.materials,
        };
        let front = gauge.front(frame.particles);
        let t_fill = capillary_fill_time(length, gap, surface_tension, contact_angle, viscosity);
        if let Some(c) = observe_front(&mut self.fronts, frame.time, front, length, t_fill) {
            self.comparisons.push(c);
        }
        if frame.time <= 0.0 {
            return;
        }
        let exact = capillary_front(
            frame.time,
            length,
            gap,
            surface_tension,
            contact_angle,
            viscosity,
        );
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

/// Where the liquid front of a filling gap is: the gap's axis and entrance, its length,
/// height and extent along the other axes, and the materials that fill it.
pub(crate) struct FrontGauge<'a> {
    pub(crate) axis: usize,
    pub(crate) entrance: f64,
    pub(crate) length: f64,
    pub(crate) gap: f64,
    /// The gap's extent along the axes other than `axis` and across (1 in 2D), m.
    pub(crate) depth: f64,
    /// Materials whose particles make up the gap (empty: every particle).
    pub(crate) materials: &'a [String],
}

impl FrontGauge<'_> {
    /// The front: `length × (liquid volume / gap volume)` from the shared particle field
    /// `fill` (the gap-averaged mode), or for liquid particles the volume of those past the
    /// entrance over the gap's cross-section, at most `length`.
    pub(crate) fn front<const D: usize>(&self, particles: &Particles<D>) -> f64 {
        let fill = particles.shared.get("fill");
        let (mut liquid, mut total) = (0.0, 0.0);
        let (axis, entrance) = (self.axis, self.entrance);
        let mut add = |k: usize| match fill {
            Some(fill) => {
                liquid += fill[k] * particles.volume0[k];
                total += particles.volume0[k];
            }
            None if particles.position[k][axis] > entrance => liquid += particles.volume0[k],
            None => {}
        };
        if self.materials.is_empty() {
            (0..particles.len()).for_each(&mut add);
        } else {
            for group in &particles.groups {
                if self.materials.contains(&group.name) {
                    group.range.clone().for_each(&mut add);
                }
            }
        }
        if fill.is_some() {
            self.length * liquid / total.max(1e-300)
        } else {
            (liquid / (self.gap * self.depth)).min(self.length)
        }
    }
}

/// Records one frame's front in `fronts` and, the first time it reaches the end of the
/// gap, returns the comparison `fill_time` against `reference`.
///
/// Under the fill laws x² grows linearly in time, and the measured front stops at the end
/// of the gap, so the frame that reached the end says only that the gap filled before it.
/// The fill time is where the chord of x² through the last two frames before it reaches
/// `length²` (kept between those frames), or with a single frame before it, where the
/// chord from that frame to the full one does.
pub(crate) fn observe_front(
    fronts: &mut Vec<(f64, f64)>,
    time: f64,
    front: f64,
    length: f64,
    reference: f64,
) -> Option<Comparison> {
    let full = length * (1.0 - 1e-6);
    if fronts.last().is_some_and(|&(_, x)| x >= full) {
        return None;
    }
    fronts.push((time, front));
    if front < full {
        return None;
    }
    let k = fronts.len() - 1;
    if k == 0 {
        // Full at the first frame observed: when it filled is unknown.
        return None;
    }
    let target = length * length;
    let (t_b, _) = fronts[k];
    let (t_a, x_a) = fronts[k - 1];
    let chord = |(t0, x0): (f64, f64), (t1, x1): (f64, f64)| {
        let slope = (x1 * x1 - x0 * x0) / (t1 - t0);
        (slope > 0.0 && slope.is_finite()).then(|| t1 + (target - x1 * x1) / slope)
    };
    let before = (k >= 2)
        .then(|| chord(fronts[k - 2], (t_a, x_a)))
        .flatten()
        .map(|t| t.max(t_a).min(t_b));
    let measured = before.or_else(|| chord((t_a, x_a), fronts[k]))?;
    Some(compare("fill_time", measured, reference))
}

/// Checks a filling gap's place in a `scene`: `axis`, `across` (another axis) and the
/// `materials` that fill it, and its `entrance`, `length` and `gap` numbers.
#[allow(clippy::too_many_arguments)]
pub(crate) fn check_gap(
    c: &mut Checks,
    scene: &Scene,
    axis: usize,
    across: Option<usize>,
    materials: &[String],
    entrance: f64,
    length: f64,
    gap: f64,
) {
    let dim = scene.dimension as usize;
    c.axis("axis", axis, dim);
    if let Some(across) = across {
        c.axis("across", across, dim);
        if across == axis {
            c.error("across", "must differ from `axis`");
        }
    }
    for (i, m) in materials.iter().enumerate() {
        if !scene.materials.contains_key(m) {
            c.error(
                &format!("materials[{i}]"),
                format!("no material `{m}` in the scene's `materials`"),
            );
        }
    }
    c.finite("entrance", entrance);
    c.positive("length", length);
    c.positive("gap", gap);
}

/// The problems of a `capillary_filling` section in a `dimension`-D scene.
fn check(p: &CapillaryFillingParams, path: &str, scene: &Scene) -> Result<(), Vec<Issue>> {
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
    c.positive("surface_tension", p.surface_tension);
    if !(p.contact_angle >= 0.0 && p.contact_angle < 90.0) {
        c.error(
            "contact_angle",
            format!(
                "must be at least 0 and below 90 degrees (a wetting liquid; got {})",
                p.contact_angle
            ),
        );
    }
    c.positive("viscosity", p.viscosity);
    if let Some(b) = p.slip_length {
        c.positive("slip_length", b);
    }
    c.finish()
}

fn build(
    p: CapillaryFillingParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    check(&p, path, scene)?;
    let depth = gap_depth(scene, p.axis, p.across);
    Ok(Arc::new(CapillaryFilling {
        p,
        depth,
        error: RelativeL2::default(),
        measured: None,
        expected: None,
        fronts: Vec::new(),
        comparisons: Vec::new(),
    }))
}

/// The extent of a gap along `axis` with its plates normal to `across` (default: the first
/// axis other than `axis`) along the scene's other axes: 1 in 2D, the domain's depth in 3D.
pub(crate) fn gap_depth(scene: &Scene, axis: usize, across: Option<usize>) -> f64 {
    let across = across.unwrap_or(if axis == 0 { 1 } else { 0 });
    (0..scene.dimension as usize)
        .filter(|&d| d != axis && d != across)
        .map(|d| scene.domain.max[d] - scene.domain.min[d])
        .product()
}

fn unit_depth() -> f64 {
    1.0
}

/// The `capillary_filling` reference type.
pub fn factory() -> Box<dyn ReferenceFactory> {
    Box::new(TypedReferenceFactory::new("capillary_filling", build))
}

/// Liquid front of capillary filling between parallel plates (Washburn/Lucas law): the
/// distance `√(h σ cosθ t / (3μ))` from the entrance at time `t`, held at `length` once the
/// gap is full; `contact_angle` in degrees.
pub fn capillary_front(
    t: f64,
    length: f64,
    gap: f64,
    surface_tension: f64,
    contact_angle: f64,
    viscosity: f64,
) -> f64 {
    if t <= 0.0 {
        return 0.0;
    }
    let cos = contact_angle.to_radians().cos();
    (gap * surface_tension * cos * t / (3.0 * viscosity))
        .sqrt()
        .min(length)
}

/// Time capillary filling between parallel plates takes to reach `length` (see
/// [`capillary_front`]): `3 μ L² / (h σ cosθ)`; `contact_angle` in degrees.
pub fn capillary_fill_time(
    length: f64,
    gap: f64,
    surface_tension: f64,
    contact_angle: f64,
    viscosity: f64,
) -> f64 {
    3.0 * viscosity * length * length / (gap * surface_tension * contact_angle.to_radians().cos())
}

#[cfg(test)]
mod tests {
    use super::*;
    use mpm_core::particles::Particles;
    use mpm_core::reference::{assert_each_names_its_path, section_issues, test_particles};
    use mpm_core::scene::test_scene;

    fn settings(overrides: serde_json::Value) -> serde_json::Value {
        let mut r = serde_json::json!({
            "type": "capillary_filling", "axis": 0, "entrance": 0.0, "length": 5e-3,
            "gap": 5e-5, "surface_tension": 0.03, "contact_angle": 30.0, "viscosity": 2.0
        });
        for (k, v) in overrides.as_object().expect("an object") {
            r[k] = v.clone();
        }
        r
    }

    /// The issues the factory finds with a reference given as JSON, in a `dim`-D scene.
    fn issues(dim: usize, json: serde_json::Value) -> Vec<(String, String)> {
        section_issues(factory().as_ref(), &json, dim)
    }

    #[test]
    fn capillary_filling_reference_checks_name_their_json_paths() {
        assert!(issues(2, settings(serde_json::json!({}))).is_empty());
        assert!(issues(3, settings(serde_json::json!({"axis": 2}))).is_empty());
        assert!(issues(2, settings(serde_json::json!({"contact_angle": 0.0}))).is_empty());
        let cases = [
            (serde_json::json!({"axis": 2}), "reference.axis", "below 2"),
            (
                serde_json::json!({"length": 0.0}),
                "reference.length",
                "> 0",
            ),
            (serde_json::json!({"gap": -1e-5}), "reference.gap", "> 0"),
            (
                serde_json::json!({"surface_tension": 0.0}),
                "reference.surface_tension",
                "> 0",
            ),
            (
                serde_json::json!({"contact_angle": 90.0}),
                "reference.contact_angle",
                "below 90",
            ),
            (
                serde_json::json!({"contact_angle": -1.0}),
                "reference.contact_angle",
                "at least 0",
            ),
            (
                serde_json::json!({"viscosity": -2.0}),
                "reference.viscosity",
                "> 0",
            ),
            (
                serde_json::json!({"slip_length": 0.0}),
                "reference.slip_length",
                "> 0",
            ),
        ];
        assert_each_names_its_path(factory().as_ref(), &settings(serde_json::json!({})), &cases);
        // Non-finite numbers cannot be written in JSON; check the typed value directly.
        let typed = CapillaryFillingParams {
            axis: 0,
            entrance: f64::NAN,
            length: f64::INFINITY,
            gap: 5e-5,
            surface_tension: 0.03,
            contact_angle: f64::NAN,
            viscosity: 2.0,
            across: None,
            materials: Vec::new(),
            slip_length: None,
        };
        let found = check(&typed, "reference", &test_scene(2)).unwrap_err();
        let paths: Vec<&str> = found.iter().map(|i| i.path.as_str()).collect();
        assert_eq!(
            paths,
            [
                "reference.entrance",
                "reference.length",
                "reference.contact_angle"
            ]
        );
    }

    /// A fresh tracker of a 4 mm gap, 50 µm high, μ = 2 Pa s, fully wetting.
    fn capillary() -> Box<dyn Reference> {
        let json = serde_json::json!({
            "type": "capillary_filling", "axis": 0, "entrance": 0.0, "length": 4e-3,
            "gap": 5e-5, "surface_tension": 0.03, "contact_angle": 0.0, "viscosity": 2.0
        });
        factory()
            .build(&json, "reference", &test_scene(2))
            .expect("a valid reference")
            .start()
    }

    fn frame(p: &Particles<2>, time: f64, last: bool) -> Frame<'_, 2> {
        Frame {
            particles: p,
            time,
            last,
        }
    }

    /// Sets the fill of four equal-volume particles so the measured front is `front` of
    /// `length` (the first particles full, the next one partly).
    fn set_front(p: &mut Particles<2>, front: f64, length: f64) {
        let fill = p.shared.get_mut("fill").unwrap();
        let filled = 4.0 * front / length;
        for (i, f) in fill.iter_mut().enumerate() {
            *f = (filled - i as f64).clamp(0.0, 1.0);
        }
    }

    #[test]
    fn capillary_filling_tracks_the_front_and_the_fill_time() {
        let (length, t_fill) = (4e-3, capillary_fill_time(4e-3, 5e-5, 0.03, 0.0, 2.0));
        let mut p = test_particles(&[[0.0; 2]; 4], &[1.0, 1.0, 1.0, 1.0], &["fill"]);
        let mut r = capillary();
        // Frames every t_fill/8, the front following the law exactly (held at the end).
        for k in 0..=12 {
            let t = k as f64 * t_fill / 8.0;
            set_front(&mut p, length * (t / t_fill).sqrt().min(1.0), length);
            r.observe_2d(frame(&p, t, k == 12));
            if k < 8 {
                assert!(r.comparisons().is_empty(), "{k}");
            }
        }
        assert!(r.error().unwrap() < 1e-12, "{:?}", r.error());
        assert_eq!(r.measured(), Some(length));
        assert!((r.expected().unwrap() - length).abs() < 1e-12 * length);
        let c = r.comparisons();
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].quantity, "fill_time");
        assert!((c[0].reference - t_fill).abs() < 1e-12 * t_fill);
        assert!(c[0].relative_difference.abs() < 1e-9, "{:?}", c[0]);

        // Filling between frames (at 7.5 of 8 frame intervals): the frame after says only
        // "full"; the chord of the frames before still finds the fill time.
        let mut r = capillary();
        let slow = t_fill * 8.0 / 7.5;
        for k in 0..=10 {
            let t = k as f64 * t_fill / 8.0;
            set_front(&mut p, length * (t / slow).sqrt().min(1.0), length);
            r.observe_2d(frame(&p, t, k == 10));
        }
        let c = r.comparisons();
        assert_eq!(c.len(), 1);
        assert!((c[0].measured - slow).abs() < 1e-9 * slow, "{:?}", c[0]);
        // The front lags the law, and the error says by how much.
        assert!(r.error().unwrap() > 0.01);
    }

    #[test]
    fn capillary_filling_without_reaching_the_end_has_no_fill_time() {
        let t_fill = capillary_fill_time(4e-3, 5e-5, 0.03, 0.0, 2.0);
        let mut p = test_particles(&[[0.0; 2]; 4], &[1.0, 1.0, 1.0, 1.0], &["fill"]);
        let mut r = capillary();
        r.observe_2d(frame(&p, 0.0, false));
        assert!(r.error().is_none());
        // A front at half the exact one: relative L2 error 0.5.
        set_front(&mut p, 0.5 * 4e-3 * 0.5f64.sqrt(), 4e-3);
        r.observe_2d(frame(&p, 0.5 * t_fill, true));
        assert!((r.error().unwrap() - 0.5).abs() < 1e-12);
        assert!(r.comparisons().is_empty());
    }

    #[test]
    fn capillary_front_reaches_the_end_at_the_fill_time() {
        let (length, gap, sigma, theta, mu) = (5e-3, 50e-6, 0.03, 30.0, 2.0);
        let t_fill = capillary_fill_time(length, gap, sigma, theta, mu);
        // 3 μ L² / (h σ cos 30°) = 3·2·25e-6 / (50e-6·0.03·0.8660254) = 115.47 s.
        assert!((t_fill - 115.470_053_837_925_15).abs() < 1e-9, "{t_fill}");
        let front = |t| capillary_front(t, length, gap, sigma, theta, mu);
        assert!((front(t_fill) - length).abs() < 1e-12 * length);
        // x² grows linearly in time: a quarter of the fill time reaches half the length.
        assert!((front(0.25 * t_fill) - 0.5 * length).abs() < 1e-12 * length);
        assert_eq!(front(2.0 * t_fill), length);
        assert_eq!(front(0.0), 0.0);
        // A wetting angle closer to 90° pulls more weakly.
        assert!(capillary_fill_time(length, gap, sigma, 60.0, mu) > t_fill);
    }

    #[test]
    fn slipping_plates_fill_faster_by_the_flux_they_add() {
        // b = h/4: the flux and so x² grow by 1 + 6b/h = 2.5.
        let (length, gap, sigma, mu, b) = (4e-3, 5e-5, 0.03, 2.0, 1.25e-5);
        let json = serde_json::json!({
            "type": "capillary_filling", "axis": 0, "entrance": 0.0, "length": length,
            "gap": gap, "surface_tension": sigma, "contact_angle": 0.0, "viscosity": mu,
            "slip_length": b
        });
        let mut r = factory()
            .build(&json, "reference", &test_scene(2))
            .expect("a valid reference")
            .start();
        let mut p = test_particles(&[[0.0; 2]; 4], &[1.0, 1.0, 1.0, 1.0], &["fill"]);
        let t = 0.1 * capillary_fill_time(length, gap, sigma, 0.0, mu);
        let front = capillary_front(t, length, gap, sigma, 0.0, mu) * 2.5f64.sqrt();
        set_front(&mut p, front, length);
        r.observe_2d(frame(&p, t, true));
        assert!(r.error().unwrap() < 1e-12, "{:?}", r.error());
        assert!((r.expected().unwrap() - front).abs() < 1e-12 * front);
    }
}
