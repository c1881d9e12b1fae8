//! Reference for a drop spreading (or beading up) on a wall to its static contact angle
//! (`domain.walls[].contact_angle`) without gravity: at rest, Young–Laplace makes its
//! surface a circular arc (2D) or a spherical cap (3D) of radius R meeting the wall at θ,
//! with the volume the liquid started with, and the liquid inside carries σ/R (2D) or
//! 2σ/R (3D) above the air. The cap's centroid height above the wall is fixed by θ and the
//! volume alone, so it measures the shape the contact angle gave without picking a surface
//! out of the particles.

use crate::meniscus_reference::check_angle_range;
use mpm_core::output::Comparison;
use mpm_core::reference::{
    Frame, Reference, ReferenceFactory, ReferenceLaw, TypedReferenceFactory, compare,
};
use mpm_core::scene::{Issue, Scene};
use mpm_core::section::Checks;
use serde::Deserialize;
use std::f64::consts::PI;
use std::sync::Arc;

/// A drop at rest on the wall at `floor` along `up`. Error: relative error, at the last
/// frame, of the liquid's centroid height above the wall (its particles weighted by their
/// volume; solid particles, a held body under the drop, left out) against the equilibrium
/// cap's with the liquid's total volume. Comparisons: `centroid_height`, `contact_angle`
/// (degrees: the angle of the cap with the measured volume and centroid height) and
/// `laplace_pressure` (the mean `pressure` of the particles in the drop's core, below half
/// the cap's height and within half its base radius of the centroid across the wall,
/// against σ/R in 2D, 2σ/R in 3D).
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct SessileDropParams {
    /// Position of the wall along `up`, m.
    pub floor: f64,
    /// Axis normal to the wall, pointing into the liquid (default 1).
    #[serde(default = "default_up")]
    pub up: usize,
    /// Surface tension σ, N/m.
    pub surface_tension: f64,
    /// Static contact angle θ on the wall, degrees, through the liquid.
    pub contact_angle: f64,
}

fn default_up() -> usize {
    1
}

/// The equilibrium cap on a wall: radius R and centroid height above the wall, for a
/// volume (an area in 2D) and a contact angle θ in radians.
fn cap(dimension: usize, volume: f64, theta: f64) -> (f64, f64) {
    let (sin, cos) = theta.sin_cos();
    if dimension == 2 {
        // Circular segment of half-angle θ: area R²(θ − sin θ cos θ); its centroid lies
        // 2R sin³θ / (3(θ − sin θ cos θ)) from the circle's centre, which is R cos θ
        // below the wall.
        let shape = theta - sin * cos;
        let radius = (volume / shape).sqrt();
        let from_centre = 2.0 * radius * sin.powi(3) / (3.0 * shape);
        (radius, from_centre - radius * cos)
    } else {
        // Spherical cap of height h = R(1 − cos θ): volume πh²(3R − h)/3; its centroid lies
        // 3(2R − h)²/(4(3R − h)) from the sphere's centre.
        let shape = PI * (2.0 + cos) * (1.0 - cos).powi(2) / 3.0;
        let radius = (volume / shape).cbrt();
        let h = radius * (1.0 - cos);
        let from_centre = 3.0 * (2.0 * radius - h).powi(2) / (4.0 * (3.0 * radius - h));
        (radius, from_centre - radius * cos)
    }
}

/// The contact angle, radians, whose cap of `volume` has its centroid at `height`: the
/// centroid rises with θ at a fixed volume, so bisection finds it; `None` outside the
/// heights a cap can have.
fn angle_of(dimension: usize, volume: f64, height: f64) -> Option<f64> {
    let (mut lo, mut hi) = (1e-4, PI - 1e-4);
    let at = |theta: f64| cap(dimension, volume, theta).1;
    if !(height > at(lo) && height < at(hi)) {
        return None;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if at(mid) < height {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct SessileDrop {
    p: SessileDropParams,
    error: Option<f64>,
    comparisons: Vec<Comparison>,
}

impl ReferenceLaw for SessileDrop {
    fn kind(&self) -> &'static str {
        "relative error of a drop's centroid height above the wall against the Young-Laplace cap at the contact angle, last frame"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        if frame.time <= 0.0 {
            return;
        }
        let p = &self.p;
        let particles = frame.particles;
        // The liquid's particles only: a held solid under the drop is no part of it.
        let mut volume = 0.0;
        let mut centre = [0.0; 3];
        let liquid = particles
            .groups
            .iter()
            .filter(|g| g.material.liquid_viscosity().is_some())
            .flat_map(|g| g.range.clone());
        for i in liquid {
            let (x, v) = (&particles.position[i], particles.volume0[i]);
            volume += v;
            for (d, c) in centre.iter_mut().enumerate().take(D) {
                *c += v * x[d];
            }
        }
        if volume <= 0.0 {
            return;
        }
        for c in &mut centre {
            *c /= volume;
        }
        let height = centre[p.up] - p.floor;
        let theta = p.contact_angle.to_radians();
        let (radius, exact) = cap(D, volume, theta);
        self.error = Some((height / exact - 1.0).abs());
        self.comparisons.clear();
        self.comparisons
            .push(compare("centroid_height", height, exact));
        if let Some(angle) = angle_of(D, volume, height) {
            self.comparisons.push(compare(
                "contact_angle",
                angle.to_degrees(),
                p.contact_angle,
            ));
        }
        // The core: away from the surface band the curvature is taken from.
        let cap_height = radius * (1.0 - theta.cos());
        let base = radius * theta.sin();
        let (mut sum, mut count) = (0.0, 0usize);
        for (i, pressure) in crate::liquid_references::pressures(particles) {
            let x = &particles.position[i];
            let mut across = 0.0;
            for (d, c) in centre.iter().enumerate().take(D) {
                if d != p.up {
                    across += (x[d] - c).powi(2);
                }
            }
            if x[p.up] - p.floor < 0.5 * cap_height && across.sqrt() < 0.5 * base {
                sum += pressure;
                count += 1;
            }
        }
        if count > 0 {
            let laplace = if D == 2 { 1.0 } else { 2.0 } * p.surface_tension / radius;
            self.comparisons
                .push(compare("laplace_pressure", sum / count as f64, laplace));
        }
    }

    fn error(&self) -> Option<f64> {
        self.error
    }

    fn comparisons(&self) -> Vec<Comparison> {
        self.comparisons.clone()
    }
}

fn build_sessile_drop(
    p: SessileDropParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    let dimension = scene.dimension as usize;
    if !p.floor.is_finite() {
        c.error("floor", "must be a finite position");
    }
    if p.up >= dimension {
        c.error("up", format!("must be an axis below {dimension}"));
    }
    c.positive("surface_tension", p.surface_tension);
    check_angle_range(&mut c, p.contact_angle);
    c.finish()?;
    Ok(Arc::new(SessileDrop {
        p,
        error: None,
        comparisons: Vec::new(),
    }))
}

/// The `sessile_drop` reference type.
pub fn factories() -> Vec<Box<dyn ReferenceFactory>> {
    vec![Box::new(TypedReferenceFactory::new(
        "sessile_drop",
        build_sessile_drop,
    ))]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn caps_have_the_textbook_limits() {
        // 2D half disc (θ = 90°): area πR²/2, centroid 4R/(3π).
        let (r, y) = cap(2, PI / 2.0, PI / 2.0);
        assert!((r - 1.0).abs() < 1e-14 && (y - 4.0 / (3.0 * PI)).abs() < 1e-14);
        // 3D hemisphere: volume 2πR³/3, centroid 3R/8.
        let (r, y) = cap(3, 2.0 * PI / 3.0, PI / 2.0);
        assert!((r - 1.0).abs() < 1e-14 && (y - 0.375).abs() < 1e-14);
        // Nearly a whole disc or sphere resting on the wall: the centroid at R.
        let (r, y) = cap(2, PI, PI - 1e-6);
        assert!((y / r - 1.0).abs() < 1e-5, "{y} {r}");
        let (r, y) = cap(3, 4.0 * PI / 3.0, PI - 1e-6);
        assert!((y / r - 1.0).abs() < 1e-5, "{y} {r}");
        // A flat film: the centroid at half its thickness R(1 − cos θ).
        let theta: f64 = 0.01;
        for d in [2, 3] {
            let (r, y) = cap(d, 1.0, theta);
            let h = r * (1.0 - theta.cos());
            let share = if d == 2 { 0.4 } else { 1.0 / 3.0 };
            assert!((y / h - share).abs() < 1e-3, "{d}: {}", y / h);
        }
    }

    #[test]
    fn the_angle_is_recovered_from_the_centroid() {
        for d in [2, 3] {
            for degrees in [15.0f64, 60.0, 90.0, 120.0, 170.0] {
                let theta = degrees.to_radians();
                let (_, y) = cap(d, 2.5e-5, theta);
                let back = angle_of(d, 2.5e-5, y).expect("angle");
                assert!((back - theta).abs() < 1e-9, "{d} {degrees}");
            }
        }
        assert!(angle_of(2, 1.0, -1.0).is_none());
    }
}
