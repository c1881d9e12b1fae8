//! Reference for the static contact angle of liquid particles (`domain.walls[].contact_angle`,
//! `obstacles[].contact_angle`): the meniscus at rest between two parallel plates without
//! gravity. Young–Laplace with the angle as the boundary condition makes the surface a
//! circular arc of radius R = w/(2|cos θ|) meeting each plate at θ, and the liquid below
//! it carries the pressure −σ/R = −2σ·cos θ/w (plates w apart; the same in 2D and for a
//! cylindrical meniscus between plates in 3D).

use mpm_core::output::Comparison;
use mpm_core::reference::{
    Frame, Reference, ReferenceFactory, ReferenceLaw, RelativeL2, TypedReferenceFactory, compare,
};
use mpm_core::scene::{Issue, Scene};
use mpm_core::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// A meniscus at rest between plates at `plates[0]` and `plates[1]` along `across`, its
/// surface facing +`up`. Error: relative L2 error, at the last frame, of the `pressure` of
/// the particles between the plates below `below` (along `up`) against −2σ·cos θ/w.
/// Comparisons: `laplace_pressure` (their mean against −2σ·cos θ/w) and `meniscus_depth`
/// (the height of the surface at the plates above its height midway, w(1 − sin θ)/(2 cos θ),
/// negative for a non-wetting liquid; measured as the amplitude of the exact arc that best
/// fits, by least squares, the top particle of each particle-wide column, so the half
/// spacing between the top particles and the surface and the columns' distance from the
/// plates do not bias it).
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct MeniscusParams {
    /// Positions of the two plates along `across`, m (lower first).
    pub plates: [f64; 2],
    /// Axis normal to the plates (default 0).
    #[serde(default)]
    pub across: usize,
    /// Axis the liquid's surface faces (default 1).
    #[serde(default = "default_up")]
    pub up: usize,
    /// Surface tension σ, N/m.
    pub surface_tension: f64,
    /// Static contact angle θ on both plates, degrees, through the liquid (not 90).
    pub contact_angle: f64,
    /// Particles below this height along `up`, m, are compared (away from the surface band
    /// the curvature is taken from).
    pub below: f64,
}

fn default_up() -> usize {
    1
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct Meniscus {
    p: MeniscusParams,
    error: Option<f64>,
    comparisons: Vec<Comparison>,
}

impl Meniscus {
    /// Width w, cos θ, the arc's radius R and the exact depth w(1 − sin θ)/(2|cos θ|).
    fn geometry(&self) -> (f64, f64, f64, f64) {
        let w = self.p.plates[1] - self.p.plates[0];
        let cos = self.p.contact_angle.to_radians().cos();
        let radius = w / (2.0 * cos.abs());
        let depth = radius - (radius * radius - 0.25 * w * w).max(0.0).sqrt();
        (w, cos, radius, depth)
    }

    /// The fitted arc amplitude times the exact depth (signed like cos θ), from the top
    /// particle of each column one particle spacing wide.
    fn measured_depth<const D: usize>(&self, frame: &Frame<'_, D>) -> Option<f64> {
        let p = &self.p;
        let particles = frame.particles;
        let (w, cos, radius, depth) = self.geometry();
        let n = particles.len();
        if n == 0 {
            return None;
        }
        let volume = particles.volume0.iter().sum::<f64>() / n as f64;
        let spacing = volume.powf(1.0 / D as f64);
        let columns = ((w / spacing).round() as usize).clamp(1, 100_000);
        let width = w / columns as f64;
        let mut tops = vec![f64::NEG_INFINITY; columns];
        for x in &particles.position {
            let s = (x[p.across] - p.plates[0]) / width;
            if s >= 0.0 && s < columns as f64 {
                let top = &mut tops[s as usize];
                *top = top.max(x[p.up]);
            }
        }
        // Least squares t_j = y0 + a·shape_j, shape = sign(cos θ)·(R − √(R² − (x − c)²)).
        let centre = 0.5 * (p.plates[0] + p.plates[1]);
        let (mut points, mut sum_s, mut sum_t, mut sum_ss, mut sum_st) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (j, top) in tops.iter().enumerate() {
            if !top.is_finite() {
                continue;
            }
            let offset = p.plates[0] + (j as f64 + 0.5) * width - centre;
            let shape = cos.signum() * (radius - (radius * radius - offset * offset).sqrt());
            points += 1.0;
            sum_s += shape;
            sum_t += top;
            sum_ss += shape * shape;
            sum_st += shape * top;
        }
        let variance = sum_ss - sum_s * sum_s / points;
        (points >= 3.0 && variance > 0.0).then(|| {
            let amplitude = (sum_st - sum_s * sum_t / points) / variance;
            amplitude * depth * cos.signum()
        })
    }
}

impl ReferenceLaw for Meniscus {
    fn kind(&self) -> &'static str {
        "relative L2 error of the pressure below a meniscus at rest between plates against Young-Laplace, last frame"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        if frame.time <= 0.0 {
            return;
        }
        let p = &self.p;
        let (w, cos, _, depth) = self.geometry();
        let exact = -2.0 * p.surface_tension * cos / w;
        let particles = frame.particles;
        let mut l2 = RelativeL2::default();
        let (mut sum, mut count) = (0.0, 0usize);
        for (i, pressure) in crate::liquid_references::pressures(particles) {
            let x = &particles.position[i];
            if x[p.up] < p.below && x[p.across] > p.plates[0] && x[p.across] < p.plates[1] {
                l2.add((pressure - exact).powi(2), exact * exact);
                sum += pressure;
                count += 1;
            }
        }
        self.error = l2.value();
        self.comparisons.clear();
        if count > 0 {
            self.comparisons
                .push(compare("laplace_pressure", sum / count as f64, exact));
        }
        if let Some(measured) = self.measured_depth(&frame) {
            self.comparisons
                .push(compare("meniscus_depth", measured, depth * cos.signum()));
        }
    }

    fn error(&self) -> Option<f64> {
        self.error
    }

    fn comparisons(&self) -> Vec<Comparison> {
        self.comparisons.clone()
    }
}

/// The checks of two plates' positions along `across` and the `up` axis, shared by the
/// references between plates (`meniscus`, `capillary_rise`).
pub(crate) fn check_plates(
    c: &mut Checks,
    plates: [f64; 2],
    across: usize,
    up: usize,
    dimension: usize,
) {
    if !(plates.iter().all(|x| x.is_finite()) && plates[1] > plates[0]) {
        c.error("plates", "must be two finite positions, the lower first");
    }
    if across >= dimension {
        c.error("across", format!("must be an axis below {dimension}"));
    }
    if up >= dimension || up == across {
        c.error(
            "up",
            format!("must be an axis below {dimension} other than `across`"),
        );
    }
}

/// The check of a contact angle in (0, 180) degrees; whether it passed.
pub(crate) fn check_angle_range(c: &mut Checks, angle: f64) -> bool {
    let inside = angle.is_finite() && angle > 0.0 && angle < 180.0;
    if !inside {
        c.error(
            "contact_angle",
            "must lie strictly between 0 and 180 degrees",
        );
    }
    inside
}

/// The check of a contact angle in (0, 180) degrees and not 90 (`why_not_90` says what 90
/// would leave to compare).
pub(crate) fn check_angle(c: &mut Checks, angle: f64, why_not_90: &str) {
    if !check_angle_range(c, angle) {
        return;
    }
    if angle.to_radians().cos().abs() < 1e-6 {
        c.error(
            "contact_angle",
            format!("must differ from 90 degrees: {why_not_90}"),
        );
    }
}

fn build_meniscus(
    p: MeniscusParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    let dimension = scene.dimension as usize;
    check_plates(&mut c, p.plates, p.across, p.up, dimension);
    c.positive("surface_tension", p.surface_tension);
    check_angle(
        &mut c,
        p.contact_angle,
        "a flat surface has no pressure to compare",
    );
    if !p.below.is_finite() {
        c.error("below", "must be a finite height");
    }
    c.finish()?;
    Ok(Arc::new(Meniscus {
        p,
        error: None,
        comparisons: Vec::new(),
    }))
}

/// The `meniscus` reference type.
pub fn factories() -> Vec<Box<dyn ReferenceFactory>> {
    vec![Box::new(TypedReferenceFactory::new(
        "meniscus",
        build_meniscus,
    ))]
}
