//! The closed form the contact conductance is checked against: two equal slabs of one
//! material, one hot and one cold, insulated on their outer faces and joined at a plane
//! with a heat transfer coefficient h. By symmetry the interface mean stays at the mean of
//! the two temperatures, so each slab cools or warms towards it as a slab with one face
//! insulated and the other convecting with coefficient 2h (Carslaw & Jaeger §3.11):
//! θ/θ₀ = Σ Cₙ cos(λₙ ξ) exp(−λₙ² α t / L²), Cₙ = 4 sin λₙ / (2λₙ + sin 2λₙ),
//! λₙ tan λₙ = Bi = 2hL/k, with ξ the distance from the insulated face over L.

use mpm_core::math::bisect;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Two slabs of one material, each `thickness` thick, either side of the plane at
/// `interface` along `axis`: the lower one at `lower_temperature`, the upper one at
/// `upper_temperature` at t = 0, joined with the contact conductance `coefficient`;
/// error: RMS temperature error over particles and output frames after t = 0, divided by
/// the temperature difference.
#[derive(Clone, Debug, Deserialize, JsonSchema, Serialize)]
#[serde(deny_unknown_fields)]
pub struct InterfaceTemperatureParams {
    /// Axis across the interface.
    pub axis: usize,
    /// Coordinate of the interface.
    pub interface: f64,
    /// Thickness of each slab, m.
    pub thickness: f64,
    /// Temperature of the slab below the interface at t = 0, K.
    pub lower_temperature: f64,
    /// Temperature of the slab above the interface at t = 0, K.
    pub upper_temperature: f64,
    /// Thermal conductivity of both slabs, W/(m K).
    pub conductivity: f64,
    /// Thermal diffusivity k/(ρc) of both slabs, m²/s.
    pub diffusivity: f64,
    /// Heat transfer coefficient across the interface, W/(m² K).
    pub coefficient: f64,
}

impl InterfaceTemperatureParams {
    /// The closed-form temperature at coordinate `s` along the axis and time `t`.
    pub fn temperature(&self, s: f64, t: f64) -> f64 {
        let mean = 0.5 * (self.lower_temperature + self.upper_temperature);
        let own = if s < self.interface {
            self.lower_temperature
        } else {
            self.upper_temperature
        };
        let depth = (self.thickness - (s - self.interface).abs()).max(0.0) / self.thickness;
        let biot = 2.0 * self.coefficient * self.thickness / self.conductivity;
        mean + (own - mean)
            * convecting_slab(
                depth,
                self.diffusivity * t / (self.thickness * self.thickness),
                biot,
            )
    }
}

/// θ/θ₀ at `xi` (0 at the insulated face, 1 at the convecting one) and Fourier number `fo`
/// in a slab with Biot number `biot`; terms until they fall below 1e-14 (at most 2000).
pub fn convecting_slab(xi: f64, fo: f64, biot: f64) -> f64 {
    if fo <= 0.0 {
        return 1.0;
    }
    let mut sum = 0.0;
    for n in 0..2000 {
        let lambda = eigenvalue(n, biot);
        let decay = (-lambda * lambda * fo).exp();
        if decay < 1e-14 {
            break;
        }
        let c = 4.0 * lambda.sin() / (2.0 * lambda + (2.0 * lambda).sin());
        sum += c * (lambda * xi).cos() * decay;
    }
    sum
}

/// The root of λ tan λ = Bi in (nπ, nπ + π/2), by bisection.
fn eigenvalue(n: usize, biot: f64) -> f64 {
    // At nπ the function is −Bi cos nπ: negative below the root for even n.
    let even = n.is_multiple_of(2);
    bisect(
        |l: f64| (l * l.sin() - biot * l.cos() < 0.0) == even,
        n as f64 * PI,
        n as f64 * PI + 0.5 * PI,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_eigenvalues_solve_their_equation() {
        // λ₁ for Bi = 1 is 0.8603 (Incropera's table).
        assert!((eigenvalue(0, 1.0) - 0.8603).abs() < 1e-4);
        for n in 0..5 {
            let l = eigenvalue(n, 2.5);
            assert!((l * l.tan() - 2.5).abs() < 1e-9, "{n}: {l}");
        }
    }

    #[test]
    fn the_slabs_start_at_their_temperatures_and_meet_in_the_middle() {
        let p = InterfaceTemperatureParams {
            axis: 0,
            interface: 0.01,
            thickness: 0.01,
            lower_temperature: 400.0,
            upper_temperature: 300.0,
            conductivity: 20.0,
            diffusivity: 2e-5,
            coefficient: 1000.0,
        };
        assert!((p.temperature(0.005, 1e-3) - 400.0).abs() < 1e-6);
        assert!((p.temperature(0.015, 1e-3) - 300.0).abs() < 1e-6);
        assert!((p.temperature(0.005, 1e4) - 350.0).abs() < 1e-9);
        // Energy: the mean over both slabs stays 350 K.
        let t = 3.0;
        let mean: f64 = (0..2000)
            .map(|i| p.temperature((i as f64 + 0.5) * 1e-5, t))
            .sum::<f64>()
            / 2000.0;
        assert!((mean - 350.0).abs() < 1e-6, "{mean}");
        // Across the interface the jump carries the flux: k ∂T/∂x = h ΔT on both sides.
        let (a, b) = (p.temperature(0.01 - 1e-7, t), p.temperature(0.01 + 1e-7, t));
        let slope = (p.temperature(0.01 - 1e-7, t) - p.temperature(0.01 - 2e-7, t)) / 1e-7;
        assert!(((-p.conductivity * slope) / (p.coefficient * (a - b)) - 1.0).abs() < 1e-3);
    }

    #[test]
    fn a_large_biot_number_tends_to_the_held_face() {
        // Bi → ∞: the convecting face is held at the ambient; the series then is the slab
        // whose faces are held (half of it, by symmetry).
        let late = convecting_slab(0.0, 0.2, 1e9);
        let expect = 4.0 / PI * (-PI * PI / 4.0 * 0.2).exp()
            - 4.0 / (3.0 * PI) * (-9.0 * PI * PI / 4.0 * 0.2).exp()
            + 4.0 / (5.0 * PI) * (-25.0 * PI * PI / 4.0 * 0.2).exp();
        assert!((late - expect).abs() < 1e-3, "{late} vs {expect}");
    }
}
