//! References for surface tension of liquid particles (`liquid.surface_tension`): the
//! drop at rest, whose inside carries the Laplace pressure σ/R (a 2D cylinder) or 2σ/R
//! (a sphere) above the void's, and the oscillating drop, whose second mode has Rayleigh's
//! (1879) and Lamb's period.

use mpm_core::output::Comparison;
use mpm_core::reference::{
    Frame, Reference, ReferenceFactory, ReferenceLaw, RelativeL2, TypedReferenceFactory, compare,
};
use mpm_core::scene::{Issue, Scene};
use mpm_core::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// A drop at rest without gravity: the particles' `pressure` within `inner_fraction` of the
/// radius from the centre against the Laplace pressure (D − 1)·σ/R. Error: relative L2
/// error of those pressures at the last frame. Comparisons: `laplace_pressure` (their
/// mean against (D − 1)·σ/R), `spurious_speed` (the largest particle speed against the
/// capillary velocity σ/μ, which sets the spurious currents of surface-tension schemes)
/// and `radius` (the farthest particle's distance from the centre against R: the drop
/// keeps its shape).
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct LaplaceDropParams {
    /// Centre of the drop, m.
    pub center: Vec<f64>,
    /// Radius of the drop, m.
    pub radius: f64,
    /// Surface tension σ, N/m.
    pub surface_tension: f64,
    /// Dynamic viscosity μ of the liquid, Pa·s (for the capillary velocity σ/μ).
    pub viscosity: f64,
    /// Particles within this fraction of the radius are compared (default 0.5: away from
    /// the surface band the curvature is taken from).
    #[serde(default = "default_inner_fraction")]
    pub inner_fraction: f64,
}

fn default_inner_fraction() -> f64 {
    0.5
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct LaplaceDrop {
    p: LaplaceDropParams,
    error: Option<f64>,
    comparisons: Vec<Comparison>,
}

impl ReferenceLaw for LaplaceDrop {
    fn kind(&self) -> &'static str {
        "relative L2 error of the pressure inside a drop at rest against the Laplace pressure, last frame"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        if frame.time <= 0.0 {
            return;
        }
        let p = &self.p;
        let exact = (D as f64 - 1.0) * p.surface_tension / p.radius;
        let particles = frame.particles;
        let distance = |i: usize| {
            let x = &particles.position[i];
            (0..D)
                .map(|d| (x[d] - p.center[d]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let mut l2 = RelativeL2::default();
        let (mut sum, mut count) = (0.0, 0usize);
        for (i, pressure) in crate::liquid_references::pressures(particles) {
            if distance(i) < p.inner_fraction * p.radius {
                l2.add((pressure - exact).powi(2), exact * exact);
                sum += pressure;
                count += 1;
            }
        }
        let farthest = (0..particles.len()).map(distance).fold(0.0, f64::max);
        let speed = particles
            .velocity
            .iter()
            .map(|v| v.norm())
            .fold(0.0, f64::max);
        self.error = l2.value();
        self.comparisons.clear();
        if count > 0 {
            self.comparisons
                .push(compare("laplace_pressure", sum / count as f64, exact));
        }
        self.comparisons.push(compare(
            "spurious_speed",
            speed,
            p.surface_tension / p.viscosity,
        ));
        self.comparisons.push(compare("radius", farthest, p.radius));
    }

    fn error(&self) -> Option<f64> {
        self.error
    }

    fn comparisons(&self) -> Vec<Comparison> {
        self.comparisons.clone()
    }
}

fn build_laplace_drop(
    p: LaplaceDropParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    if p.center.len() != scene.dimension as usize || p.center.iter().any(|x| !x.is_finite()) {
        c.error(
            "center",
            format!("must be {} finite numbers", scene.dimension),
        );
    }
    c.positive("radius", p.radius);
    c.positive("surface_tension", p.surface_tension);
    c.positive("viscosity", p.viscosity);
    if !(p.inner_fraction > 0.0 && p.inner_fraction <= 1.0) {
        c.error("inner_fraction", "must lie in (0, 1]");
    }
    c.finish()?;
    Ok(Arc::new(LaplaceDrop {
        p,
        error: None,
        comparisons: Vec::new(),
    }))
}

/// A drop set oscillating in its second mode (e.g. by the velocity v = a·(x, −y) on a
/// circle): the quadrupole moment Σ m·((x − c)² − (y − c)²) changes sign every half
/// period. Error: the relative difference of the measured period (from the first to the
/// last sign change, interpolated between frames) from the inviscid one, 2π/ω with
/// ω² = (n³ − n)·σ/(ρR³) for a 2D cylinder (Lamb 1932, §275) and n(n − 1)(n + 2)·σ/(ρR³)
/// for a sphere (Rayleigh 1879), n = 2. Comparison `period`. Viscosity lowers ω by a
/// relative γ²/(2ω²) with γ the damping rate: state it with the scene when it matters.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct DropOscillationParams {
    /// Radius of the drop at rest, m.
    pub radius: f64,
    /// Surface tension σ, N/m.
    pub surface_tension: f64,
    /// Density ρ of the liquid, kg/m³.
    pub density: f64,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct DropOscillation {
    p: DropOscillationParams,
    /// Quadrupole moment of the last frame (time, value).
    last: Option<(f64, f64)>,
    /// Times the moment changed sign.
    crossings: Vec<f64>,
    /// The inviscid period 2π/ω (set at the first frame, when the dimension is known).
    exact: Option<f64>,
}

impl ReferenceLaw for DropOscillation {
    fn kind(&self) -> &'static str {
        "relative error of the second-mode oscillation period of a drop against Rayleigh/Lamb"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        let p = &self.p;
        let n: f64 = 2.0;
        let factor = if D == 2 {
            n * n * n - n
        } else {
            n * (n - 1.0) * (n + 2.0)
        };
        let omega = (factor * p.surface_tension / (p.density * p.radius.powi(3))).sqrt();
        self.exact = Some(2.0 * std::f64::consts::PI / omega);
        let particles = frame.particles;
        let total: f64 = particles.mass.iter().sum();
        if total <= 0.0 {
            return;
        }
        let mut centre = [0.0; 2];
        for (x, m) in particles.position.iter().zip(&particles.mass) {
            centre[0] += m * x[0] / total;
            centre[1] += m * x[1] / total;
        }
        let moment: f64 = particles
            .position
            .iter()
            .zip(&particles.mass)
            .map(|(x, m)| m * ((x[0] - centre[0]).powi(2) - (x[1] - centre[1]).powi(2)))
            .sum();
        if let Some((t0, q0)) = self.last
            && q0 != 0.0
            && q0.signum() != moment.signum()
        {
            self.crossings
                .push(t0 + (frame.time - t0) * q0 / (q0 - moment));
        }
        self.last = Some((frame.time, moment));
    }

    fn error(&self) -> Option<f64> {
        let (measured, exact) = (self.period()?, self.exact?);
        Some((measured / exact - 1.0).abs())
    }

    fn comparisons(&self) -> Vec<Comparison> {
        match (self.period(), self.exact) {
            (Some(measured), Some(exact)) => vec![compare("period", measured, exact)],
            _ => Vec::new(),
        }
    }
}

impl DropOscillation {
    /// Twice the mean spacing of the sign changes (needs at least two).
    fn period(&self) -> Option<f64> {
        let (first, last) = (self.crossings.first()?, self.crossings.last()?);
        let halves = self.crossings.len() - 1;
        (halves > 0).then(|| 2.0 * (last - first) / halves as f64)
    }
}

fn build_drop_oscillation(
    p: DropOscillationParams,
    path: &str,
    _scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    c.positive("radius", p.radius);
    c.positive("surface_tension", p.surface_tension);
    c.positive("density", p.density);
    c.finish()?;
    Ok(Arc::new(DropOscillation {
        p,
        last: None,
        crossings: Vec::new(),
        exact: None,
    }))
}

/// The `laplace_drop` and `drop_oscillation` reference types.
pub fn factories() -> Vec<Box<dyn ReferenceFactory>> {
    vec![
        Box::new(TypedReferenceFactory::new(
            "laplace_drop",
            build_laplace_drop,
        )),
        Box::new(TypedReferenceFactory::new(
            "drop_oscillation",
            build_drop_oscillation,
        )),
    ]
}
