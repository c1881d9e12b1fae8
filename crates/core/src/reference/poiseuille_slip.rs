//! Plane Poiseuille flow starting from rest between plates with Navier slip (u = b·∂u/∂n on
//! both): the series solution the `poiseuille_startup` reference uses when it is given a
//! `slip_length`.
//!
//! With s = y − h/2 and H = h/2 the steady profile is u_s = (G/2μ)(H² − s² + b·h). The
//! start-up is u = u_s − Σ_n a_n cos(λ_n s) e^(−μλ_n²t/ρ), where x_n = λ_n H are the roots of
//! x·tan x = H/b in (nπ, nπ + π/2) (the Robin condition on cos(λs)), and
//! a_n = 4 (G/2μ) sin x_n / (λ_n³ (H + sin(2x_n)/(2λ_n))) (the projection of u_s on the
//! eigenfunctions; the slip terms cancel). As b → 0 this is the no-slip series.

/// Most terms summed (reached only at times so early that the rest are below 1e-12 of the
/// steady centre-line velocity).
const TERMS: usize = 10_000;

/// The root of x·tan x = `biot` in (nπ, nπ + π/2), by bisection (x·tan x rises from 0 to
/// +∞ there).
fn root(n: usize, biot: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI};
    let (mut lo, mut hi) = (n as f64 * PI, n as f64 * PI + FRAC_PI_2);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid == lo || mid == hi {
            break;
        }
        if mid * mid.tan() < biot {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Velocity profile at time `t` of plane Poiseuille flow starting from rest under a
/// constant pressure gradient `G = −dp/dx > 0` between plates at y = 0 and y = `gap` with
/// Navier slip of length `slip_length` (> 0) on both (module docs). Positions outside the
/// gap are clamped onto the plates.
pub fn poiseuille_slip_startup_profile(
    t: f64,
    gap: f64,
    pressure_gradient: f64,
    viscosity: f64,
    density: f64,
    slip_length: f64,
) -> impl Fn(f64) -> f64 {
    let half = 0.5 * gap;
    let a = pressure_gradient / (2.0 * viscosity);
    let steady_centre = a * (half * half + slip_length * gap);
    let biot = half / slip_length;
    let mut terms = Vec::new();
    if t > 0.0 {
        for n in 0..TERMS {
            let x = root(n, biot);
            let lambda = x / half;
            let norm = half + (2.0 * x).sin() / (2.0 * lambda);
            let amplitude = 4.0 * a * x.sin() / (lambda.powi(3) * norm);
            let c = amplitude * (-viscosity * lambda * lambda * t / density).exp();
            if c.abs() < 1e-12 * steady_centre {
                break;
            }
            terms.push((c, lambda));
        }
    }
    move |y: f64| {
        if t <= 0.0 {
            return 0.0;
        }
        let s = y.clamp(0.0, gap) - half;
        let series: f64 = terms.iter().map(|(c, l)| c * (l * s).cos()).sum();
        a * (half * half - s * s + slip_length * gap) - series
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::poiseuille_startup_profile;

    const H: f64 = 1e-3;
    const G: f64 = 1e4;
    const MU: f64 = 0.5;
    const RHO: f64 = 1000.0;

    #[test]
    fn a_vanishing_slip_length_gives_the_no_slip_series() {
        let centre = G * H * H / (8.0 * MU);
        for t in [1e-4, 1e-3, 1e-2] {
            let slip = poiseuille_slip_startup_profile(t, H, G, MU, RHO, 1e-12);
            let stick = poiseuille_startup_profile(t, H, G, MU, RHO);
            for k in 0..=10 {
                let y = H * k as f64 / 10.0;
                assert!((slip(y) - stick(y)).abs() < 1e-7 * centre, "{t} {y}");
            }
        }
    }

    #[test]
    fn the_plates_slip_by_the_slip_length_times_the_shear_rate() {
        let b = 0.2 * H;
        for t in [2e-4, 1e-3, 1.0] {
            let u = poiseuille_slip_startup_profile(t, H, G, MU, RHO, b);
            // u(0) = b·u'(0) and u(h) = b·(−u'(h)), the derivative by a central difference
            // of the series continued past the plate (the clamp is undone by taking the
            // derivative just inside).
            let e = 1e-7 * H;
            let slope = (u(2.0 * e) - u(0.0)) / (2.0 * e);
            assert!(
                (u(0.0) - b * slope).abs() < 1e-4 * u(0.5 * H),
                "{t}: {} {}",
                u(0.0),
                b * slope
            );
            assert!((u(0.3 * H) - u(0.7 * H)).abs() < 1e-12 * u(0.5 * H));
        }
        // Steady: the parabola lifted by the slip, (G/2μ)(y(h − y) + b·h).
        let u = poiseuille_slip_startup_profile(10.0, H, G, MU, RHO, b);
        for y in [0.0, 0.2e-3, 0.5e-3, 1e-3] {
            let steady = G / (2.0 * MU) * (y * (H - y) + b * H);
            assert!((u(y) - steady).abs() < 1e-12 * steady, "{y}");
        }
    }

    #[test]
    fn a_long_slip_length_lets_the_liquid_accelerate_as_a_plug() {
        // b = 1000 h: the plates hardly hold it; early on u = G t / ρ everywhere.
        let t = 1e-3;
        let u = poiseuille_slip_startup_profile(t, H, G, MU, RHO, 1.0);
        for y in [0.0, 0.5e-3, 1e-3] {
            assert!((u(y) / (G * t / RHO) - 1.0).abs() < 2e-3, "{y} {}", u(y));
        }
    }
}
