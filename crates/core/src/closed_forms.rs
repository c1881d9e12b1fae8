//! Closed-form solutions the heat, phase-change, cure and flow references compare with.

use std::f64::consts::PI;

/// Complementary error function, relative error below 1.2e-7 everywhere (Chebyshev fit of
/// Press et al., Numerical Recipes §6.2).
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 { r } else { 2.0 - r }
}

/// Error function (see [`erfc`]).
pub fn erf(x: f64) -> f64 {
    1.0 - erfc(x)
}

/// Temperature in a slab `0 <= s <= length` at `initial` whose two faces are held at
/// `surface` from t = 0 (Fourier series; terms until they fall below 1e-12).
pub fn slab_temperature(
    s: f64,
    t: f64,
    length: f64,
    diffusivity: f64,
    initial: f64,
    surface: f64,
) -> f64 {
    if t <= 0.0 {
        return initial;
    }
    let mut sum = 0.0;
    for k in 0..10_000 {
        let n = (2 * k + 1) as f64;
        let decay = (-(n * PI / length).powi(2) * diffusivity * t).exp();
        if decay < 1e-14 {
            break;
        }
        sum += 4.0 / (n * PI) * (n * PI * s / length).sin() * decay;
    }
    surface + (initial - surface) * sum
}

/// Temperature at depth `s` in a semi-infinite body at `initial` whose surface is held at
/// `surface` from t = 0: `T_s + (T_0 − T_s) erf(s / 2√(αt))`.
pub fn semi_infinite_temperature(
    s: f64,
    t: f64,
    diffusivity: f64,
    initial: f64,
    surface: f64,
) -> f64 {
    if t <= 0.0 {
        return initial;
    }
    surface + (initial - surface) * erf(s / (2.0 * (diffusivity * t).sqrt()))
}

/// Neumann's similarity constant λ of the two-phase Stefan (melting) problem: the front is
/// at `2λ√(α_l t)`. `stefan_liquid` = c_l (T_surface − T_melt)/L, `stefan_solid` =
/// c_s (T_melt − T_initial)/L, `ratio` = √(α_l/α_s); equal densities. Solves
/// `St_l e^{−λ²}/erf λ − St_s e^{−ν²λ²}/(ν erfc νλ) = λ√π` by bisection (the left side
/// falls and the right side rises with λ). `stefan_solid = 0` is the one-phase problem.
pub fn neumann_lambda(stefan_liquid: f64, stefan_solid: f64, ratio: f64) -> f64 {
    let residual = |l: f64| {
        stefan_liquid * (-l * l).exp() / erf(l)
            - stefan_solid * (-(ratio * l).powi(2)).exp() / (ratio * erfc(ratio * l))
            - l * PI.sqrt()
    };
    let (mut lo, mut hi) = (1e-9, 10.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if residual(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Degree of cure of Kamal–Sourour kinetics with m = n = 1 at constant temperature,
/// `dα/dt = (k1 + k2 α)(1 − α)`, from α(0) = 0:
/// `α = k1 (e^{(k1+k2)t} − 1) / (k2 + k1 e^{(k1+k2)t})`.
pub fn kamal_sourour_isothermal(k1: f64, k2: f64, t: f64) -> f64 {
    let e = ((k1 + k2) * t).exp();
    if !e.is_finite() {
        return 1.0;
    }
    k1 * (e - 1.0) / (k2 + k1 * e)
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

    #[test]
    fn erf_matches_tabulated_values() {
        // Abramowitz & Stegun table 7.1.
        for (x, v) in [
            (0.1, 0.112_462_916),
            (0.5, 0.520_499_878),
            (1.0, 0.842_700_793),
            (2.0, 0.995_322_265),
        ] {
            assert!((erf(x) - v).abs() < 2e-7, "{x}");
            assert!((erf(-x) + v).abs() < 2e-7, "{x}");
        }
    }

    #[test]
    fn slab_series_starts_at_the_initial_value_and_tends_to_the_surface() {
        let mid = slab_temperature(0.5, 1e-6, 1.0, 1.0, 300.0, 400.0);
        assert!((mid - 300.0).abs() < 1e-6);
        let late = slab_temperature(0.5, 10.0, 1.0, 1.0, 300.0, 400.0);
        assert!((late - 400.0).abs() < 1e-6);
        // Fundamental mode only at late times: T - Ts = (T0 - Ts) 4/π e^{-π² t} at s = L/2.
        let t = 0.2;
        let expect = 400.0 - 100.0 * 4.0 / PI * (-PI * PI * t).exp();
        assert!((slab_temperature(0.5, t, 1.0, 1.0, 300.0, 400.0) - expect).abs() < 1e-3);
    }

    #[test]
    fn neumann_one_phase_matches_the_small_stefan_number_limit() {
        // λ ≈ √(St/2) for small St.
        let st = 0.01;
        let l = neumann_lambda(st, 0.0, 1.0);
        assert!((l - (st / 2.0).sqrt()).abs() / l < 0.01, "{l}");
        // A subcooled solid slows the front.
        assert!(neumann_lambda(st, 0.05, 1.0) < l);
    }

    #[test]
    fn kamal_sourour_closed_form_solves_its_ode() {
        let (k1, k2) = (1e-3, 2e-2);
        let (mut a, dt) = (0.0, 0.01);
        for i in 0..20_000 {
            let t = i as f64 * dt;
            let f = |a: f64| (k1 + k2 * a) * (1.0 - a);
            let k_1 = f(a);
            let k_2 = f(a + 0.5 * dt * k_1);
            let k_3 = f(a + 0.5 * dt * k_2);
            let k_4 = f(a + dt * k_3);
            a += dt / 6.0 * (k_1 + 2.0 * k_2 + 2.0 * k_3 + k_4);
            let _ = t;
        }
        assert!((a - kamal_sourour_isothermal(k1, k2, 200.0)).abs() < 1e-9);
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
