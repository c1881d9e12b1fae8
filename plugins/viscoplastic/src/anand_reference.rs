//! Anand's law at a constant plastic strain rate in closed form (Brown, Kim & Anand 1989,
//! eqs. for "constant strain-rate, isothermal" loading; rigid-viscoplastic, i.e. the
//! elastic strain neglected): σ = c·s with c = (1/ξ)·asinh((ε̇ₚ/(A·e^(−Q/RT)))^m), and
//! for a ≠ 1, s = s* − [(s* − s₀)^(1−a) + (a − 1)·h₀·(s*)^(−a)·εₚ]^(1/(1−a)), which
//! saturates at σ* = c·s*. The tests drive the finite-strain update at a constant stretch
//! rate and compare with it.

use crate::AnandParameters;

/// (c, s*): the stress-to-resistance ratio and the saturated resistance, Pa, at plastic
/// strain rate `rate`, 1/s, and `temperature`, K.
fn rate_factors(p: &AnandParameters, rate: f64, temperature: f64) -> (f64, f64) {
    let z = rate / p.pre_exponential * (p.activation_temperature / temperature).exp();
    let c = (z.powf(p.rate_sensitivity)).asinh() / p.stress_multiplier;
    (c, p.saturation_coefficient * z.powf(p.saturation_exponent))
}

/// The saturation (steady-state) von Mises stress σ* = c·s*, Pa.
pub fn saturation_stress(p: &AnandParameters, rate: f64, temperature: f64) -> f64 {
    let (c, s_star) = rate_factors(p, rate, temperature);
    c * s_star
}

/// The von Mises stress after plastic strain `plastic_strain` at the constant `rate`, Pa.
pub fn stress(p: &AnandParameters, rate: f64, temperature: f64, plastic_strain: f64) -> f64 {
    let (c, s_star) = rate_factors(p, rate, temperature);
    let a = p.hardening_exponent;
    let s0 = p.initial_resistance;
    // Below saturation s rises to s*; above it (a softened start) s falls to it.
    let sign = if s0 <= s_star { 1.0 } else { -1.0 };
    let distance0 = (s_star - s0).abs();
    let distance = if a == 1.0 {
        distance0 * (-p.hardening * plastic_strain / s_star).exp()
    } else {
        let inner =
            distance0.powf(1.0 - a) + (a - 1.0) * p.hardening * s_star.powf(-a) * plastic_strain;
        inner.max(0.0).powf(1.0 / (1.0 - a))
    };
    c * (s_star - sign * distance)
}
