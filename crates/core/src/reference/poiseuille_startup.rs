//! Plane Poiseuille flow starting from rest: the series solution and the reference that
//! compares a run's flow velocity with it.

use super::poiseuille_slip::poiseuille_slip_startup_profile;
use super::{Frame, Reference, ReferenceFactory, ReferenceLaw, TypedReferenceFactory};
use crate::scene::{Issue, Scene};
use crate::section::Checks;
use serde::Deserialize;
use std::f64::consts::PI;
use std::sync::Arc;

/// Plane Poiseuille flow starting from rest under a constant pressure gradient between
/// plates at `wall` and `wall + gap` on `cross_axis` (Fourier series solution): no-slip
/// plates, or plates with Navier slip of `slip_length` (`poiseuille_slip.rs`).
/// The measured velocity is the shared particle field `flow_velocity_x`, `_y` or `_z`
/// for `axis` 0, 1 or 2 where a physics (underfill's cross-section mode) creates it, else
/// the particles' own velocity along `axis` (liquid particles moved by the mechanics);
/// error: RMS velocity error over particles and output frames
/// after t = 0, divided by the steady centre-line velocity (`G h²/(8μ)` without slip,
/// `G(h²/4 + b·h)/(2μ)` with it).
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct PoiseuilleStartupParams {
    /// Axis of the flow (the direction of the pressure drop).
    pub axis: usize,
    /// Axis across the plates.
    pub cross_axis: usize,
    /// Coordinate of the lower plate on `cross_axis`.
    pub wall: f64,
    /// Distance between the plates, m.
    pub gap: f64,
    /// Pressure gradient G = −dp/dx along the flow axis, > 0, Pa/m.
    pub pressure_gradient: f64,
    /// Dynamic viscosity, Pa s.
    pub viscosity: f64,
    /// Density, kg/m³.
    pub density: f64,
    /// Navier slip length b of both plates, m (> 0); without it the plates are no-slip.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slip_length: Option<f64>,
}

/// The velocity error accumulated over frames.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct PoiseuilleStartup {
    p: PoiseuilleStartupParams,
    squared_error: f64,
    count: f64,
    measured: Option<f64>,
    expected: Option<f64>,
}

impl ReferenceLaw for PoiseuilleStartup {
    fn kind(&self) -> &'static str {
        "RMS flow velocity error over particles and frames / steady centre-line velocity (plane Poiseuille start-up, series solution)"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        let p = &self.p;
        let name = ["flow_velocity_x", "flow_velocity_y", "flow_velocity_z"];
        let particles = frame.particles;
        if frame.time <= 0.0 || p.cross_axis >= D || p.axis >= D || particles.is_empty() {
            return;
        }
        let shared = name.get(p.axis).and_then(|n| particles.shared.get(n));
        let velocity = |i: usize| match shared {
            Some(field) => field[i],
            None => particles.velocity[i][p.axis],
        };
        let (t, h, g, mu, rho) = (
            frame.time,
            p.gap,
            p.pressure_gradient,
            p.viscosity,
            p.density,
        );
        let exact: Box<dyn Fn(f64) -> f64> = match p.slip_length {
            Some(b) => Box::new(poiseuille_slip_startup_profile(t, h, g, mu, rho, b)),
            None => Box::new(poiseuille_startup_profile(t, h, g, mu, rho)),
        };
        let slip = p.slip_length.unwrap_or(0.0);
        let centre = g * (h * h / 4.0 + slip * h) / (2.0 * mu);
        let (mut sum, mut sum_exact, mut n) = (0.0, 0.0, 0.0);
        for (i, x) in particles.position.iter().enumerate() {
            // Particles without volume (an inlet's waiting ones) are no liquid.
            if particles.volume0[i] <= 0.0 {
                continue;
            }
            n += 1.0;
            let u = velocity(i);
            let u_exact = exact(x[p.cross_axis] - p.wall);
            self.squared_error += ((u - u_exact) / centre).powi(2);
            self.count += 1.0;
            sum += u;
            sum_exact += u_exact;
        }
        if n > 0.0 {
            self.measured = Some(sum / n);
            self.expected = Some(sum_exact / n);
        }
    }

    fn error(&self) -> Option<f64> {
        (self.count > 0.0).then(|| (self.squared_error / self.count).sqrt())
    }

    fn expected(&self) -> Option<f64> {
        self.expected
    }

    fn measured(&self) -> Option<f64> {
        self.measured
    }
}

/// The problems of a `poiseuille_startup` section in a `dimension`-D scene.
fn check(p: &PoiseuilleStartupParams, path: &str, dimension: usize) -> Result<(), Vec<Issue>> {
    let mut c = Checks::new(path);
    c.axis("axis", p.axis, dimension);
    if p.cross_axis >= dimension {
        c.error("cross_axis", format!("must be below {dimension}"));
    } else if p.cross_axis == p.axis {
        c.error("cross_axis", "must differ from reference.axis");
    }
    c.finite("wall", p.wall);
    c.positive("gap", p.gap);
    c.positive("pressure_gradient", p.pressure_gradient);
    c.positive("viscosity", p.viscosity);
    c.positive("density", p.density);
    if let Some(b) = p.slip_length {
        c.positive("slip_length", b);
    }
    c.finish()
}

fn build(
    p: PoiseuilleStartupParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    check(&p, path, scene.dimension as usize)?;
    Ok(Arc::new(PoiseuilleStartup {
        p,
        squared_error: 0.0,
        count: 0.0,
        measured: None,
        expected: None,
    }))
}

/// The `poiseuille_startup` reference type.
pub fn factory() -> Box<dyn ReferenceFactory> {
    Box::new(TypedReferenceFactory::new("poiseuille_startup", build))
}

/// Most odd terms summed by [`poiseuille_startup_profile`] (reached only at times so early
/// that the remaining terms are below 1e-9 of the steady centre-line velocity).
const POISEUILLE_TERMS: usize = 10_000;

/// Velocity profile at time `t` of plane Poiseuille flow starting from rest under a constant
/// pressure gradient `G = −dp/dx > 0` between no-slip plates at y = 0 and y = `gap`:
/// `u = G y (h − y)/(2μ) − (4Gh²/(μπ³)) Σ_{n odd} sin(nπy/h)/n³ · exp(−n²π²μt/(ρh²))`.
///
/// The series coefficients are computed once per time, so evaluate many positions with one
/// profile; odd terms are summed until they fall below 1e-12 of the steady centre-line
/// velocity `Gh²/(8μ)`. Positions outside the gap are clamped onto the plates (u = 0).
pub fn poiseuille_startup_profile(
    t: f64,
    gap: f64,
    pressure_gradient: f64,
    viscosity: f64,
    density: f64,
) -> impl Fn(f64) -> f64 {
    let amplitude = 4.0 * pressure_gradient * gap * gap / (viscosity * PI.powi(3));
    let steady_centre = pressure_gradient * gap * gap / (8.0 * viscosity);
    let rate = PI * PI * viscosity / (density * gap * gap);
    let mut coefficients = Vec::new();
    if t > 0.0 {
        for k in 0..POISEUILLE_TERMS {
            let n = (2 * k + 1) as f64;
            let c = amplitude / (n * n * n) * (-n * n * rate * t).exp();
            if c.abs() < 1e-12 * steady_centre {
                break;
            }
            coefficients.push(c);
        }
    }
    move |y: f64| {
        if t <= 0.0 {
            return 0.0;
        }
        let y = y.clamp(0.0, gap);
        let mut series = 0.0;
        for (k, c) in coefficients.iter().enumerate() {
            series += c * ((2 * k + 1) as f64 * PI * y / gap).sin();
        }
        pressure_gradient / (2.0 * viscosity) * y * (gap - y) - series
    }
}

/// Velocity at height `y` above the lower plate and time `t` of plane Poiseuille start-up
/// (see [`poiseuille_startup_profile`], which is cheaper for many positions).
pub fn poiseuille_startup_velocity(
    y: f64,
    t: f64,
    gap: f64,
    pressure_gradient: f64,
    viscosity: f64,
    density: f64,
) -> f64 {
    poiseuille_startup_profile(t, gap, pressure_gradient, viscosity, density)(y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::Particles;
    use crate::reference::{assert_each_names_its_path, section_issues, test_particles};
    use crate::scene::test_scene;

    fn poiseuille(overrides: serde_json::Value) -> serde_json::Value {
        let mut r = serde_json::json!({
            "type": "poiseuille_startup", "axis": 0, "cross_axis": 1, "wall": 0.0,
            "gap": 1e-3, "pressure_gradient": 1e4, "viscosity": 0.5, "density": 1000.0
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
    fn poiseuille_startup_reference_checks_name_their_json_paths() {
        assert!(issues(2, poiseuille(serde_json::json!({}))).is_empty());
        assert!(
            issues(
                3,
                poiseuille(serde_json::json!({"axis": 2, "cross_axis": 0}))
            )
            .is_empty()
        );
        let cases = [
            (serde_json::json!({"axis": 2}), "reference.axis", "below 2"),
            (
                serde_json::json!({"cross_axis": 2}),
                "reference.cross_axis",
                "below 2",
            ),
            (
                serde_json::json!({"cross_axis": 0}),
                "reference.cross_axis",
                "differ",
            ),
            (serde_json::json!({"gap": 0.0}), "reference.gap", "> 0"),
            (
                serde_json::json!({"pressure_gradient": -1e4}),
                "reference.pressure_gradient",
                "> 0",
            ),
            (
                serde_json::json!({"viscosity": 0.0}),
                "reference.viscosity",
                "> 0",
            ),
            (
                serde_json::json!({"density": -1.0}),
                "reference.density",
                "> 0",
            ),
            (
                serde_json::json!({"slip_length": 0.0}),
                "reference.slip_length",
                "> 0",
            ),
        ];
        assert_each_names_its_path(
            factory().as_ref(),
            &poiseuille(serde_json::json!({})),
            &cases,
        );
        // Non-finite numbers cannot be written in JSON; check the typed value directly.
        let typed = PoiseuilleStartupParams {
            axis: 0,
            cross_axis: 1,
            wall: f64::INFINITY,
            gap: 1e-3,
            pressure_gradient: f64::NAN,
            viscosity: 0.5,
            density: 1000.0,
            slip_length: None,
        };
        let found = check(&typed, "reference", 2).unwrap_err();
        let paths: Vec<&str> = found.iter().map(|i| i.path.as_str()).collect();
        assert_eq!(paths, ["reference.wall", "reference.pressure_gradient"]);
    }

    #[test]
    fn poiseuille_startup_error_is_relative_to_the_centre_line_velocity() {
        let (h, g, mu, rho) = (1e-3, 1e4, 0.5, 1000.0);
        let json = serde_json::json!({
            "type": "poiseuille_startup", "axis": 0, "cross_axis": 1, "wall": 2e-3,
            "gap": h, "pressure_gradient": g, "viscosity": mu, "density": rho
        });
        let ys = [0.125e-3, 0.375e-3, 0.625e-3, 0.875e-3];
        let positions: Vec<[f64; 2]> = ys.iter().map(|y| [0.0, 2e-3 + y]).collect();
        let mut p = test_particles(&positions, &[1.0; 4], &["flow_velocity_x"]);
        let mut r = factory()
            .build(&json, "reference", &test_scene(2))
            .expect("a valid reference")
            .start();
        fn frame(particles: &Particles<2>, time: f64, last: bool) -> Frame<'_, 2> {
            Frame {
                particles,
                time,
                last,
            }
        }
        r.observe_2d(frame(&p, 0.0, false));
        assert!(r.error().is_none());
        let t = 0.1 * rho * h * h / mu;
        let exact = poiseuille_startup_profile(t, h, g, mu, rho);
        let centre = g * h * h / (8.0 * mu);
        let u: Vec<f64> = ys.iter().map(|&y| exact(y) + 0.01 * centre).collect();
        p.shared
            .get_mut("flow_velocity_x")
            .unwrap()
            .copy_from_slice(&u);
        r.observe_2d(frame(&p, t, true));
        assert!((r.error().unwrap() - 0.01).abs() < 1e-12, "{:?}", r.error());
        let mean_exact = ys.iter().map(|&y| exact(y)).sum::<f64>() / 4.0;
        assert!((r.expected().unwrap() - mean_exact).abs() < 1e-12 * centre);
        assert!((r.measured().unwrap() - mean_exact - 0.01 * centre).abs() < 1e-12 * centre);
    }

    #[test]
    fn poiseuille_startup_reads_the_particle_velocity_without_a_flow_field() {
        let (h, g, mu, rho) = (1e-3, 1e4, 0.5, 1000.0);
        let json = poiseuille(serde_json::json!({}));
        let ys = [0.25e-3, 0.75e-3];
        let positions: Vec<[f64; 2]> = ys.iter().map(|y| [0.0, *y]).collect();
        let mut p = test_particles(&positions, &[1.0; 2], &[]);
        let t = 0.1 * rho * h * h / mu;
        let exact = poiseuille_startup_profile(t, h, g, mu, rho);
        let centre = g * h * h / (8.0 * mu);
        for (v, y) in p.velocity.iter_mut().zip(ys) {
            v[0] = exact(y) - 0.02 * centre;
            v[1] = centre;
        }
        let mut r = factory()
            .build(&json, "reference", &test_scene(2))
            .expect("a valid reference")
            .start();
        r.observe_2d(Frame {
            particles: &p,
            time: t,
            last: true,
        });
        assert!((r.error().unwrap() - 0.02).abs() < 1e-12, "{:?}", r.error());
    }

    #[test]
    fn poiseuille_startup_tends_to_the_parabola() {
        let (h, g, mu, rho) = (1e-3, 1e4, 0.5, 1000.0);
        // Slowest mode decays as exp(−π² μ t/(ρ h²)); after 40 such times it is gone.
        let t = 40.0 * rho * h * h / (PI * PI * mu);
        let profile = poiseuille_startup_profile(t, h, g, mu, rho);
        let centre = g * h * h / (8.0 * mu);
        for y in [0.0, 0.1e-3, 0.25e-3, 0.5e-3, 0.9e-3, 1e-3] {
            let steady = g / (2.0 * mu) * y * (h - y);
            assert!((profile(y) - steady).abs() < 1e-12 * centre, "{y}");
        }
        assert!((profile(0.5e-3) - centre).abs() < 1e-12 * centre);
        assert_eq!(poiseuille_startup_velocity(0.5e-3, 0.0, h, g, mu, rho), 0.0);
        // Earlier, only the slowest mode is left: the centre line lags the parabola by
        // (32/π³) e^{−π² μ t/(ρ h²)} of the steady centre-line velocity (third mode: e^{−45}).
        let t = 5.0 * rho * h * h / (PI * PI * mu);
        let lag = centre - poiseuille_startup_velocity(0.5e-3, t, h, g, mu, rho);
        let expect = 32.0 / PI.powi(3) * (-5.0f64).exp() * centre;
        assert!((lag - expect).abs() < 1e-12 * centre, "{lag} {expect}");
    }

    #[test]
    fn poiseuille_startup_accelerates_freely_before_viscosity_reaches_the_centre() {
        let (h, g, mu, rho) = (1e-3, 1e4, 0.5, 1000.0);
        // Diffusion length √(μt/ρ) = h/100: the centre line feels no wall yet, u = G t / ρ.
        let t = 1e-4 * rho * h * h / mu;
        let u = poiseuille_startup_velocity(0.5 * h, t, h, g, mu, rho);
        assert!((u - g * t / rho).abs() < 1e-6 * g * t / rho, "{u}");
        // Near the wall the fluid lags behind.
        let near_wall = poiseuille_startup_velocity(0.01 * h, t, h, g, mu, rho);
        assert!(
            near_wall > 0.0 && near_wall < 0.8 * g * t / rho,
            "{near_wall}"
        );
        // The profile is symmetric about the centre line and zero on the plates.
        let profile = poiseuille_startup_profile(10.0 * t, h, g, mu, rho);
        assert!((profile(0.3 * h) - profile(0.7 * h)).abs() < 1e-12 * g * t / rho);
        assert!(profile(0.0).abs() < 1e-9 * g * t / rho && profile(h).abs() < 1e-9 * g * t / rho);
    }
}
