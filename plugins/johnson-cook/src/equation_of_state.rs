//! Pressure from the volume ratio J = det F: the volumetric half of the material, apart from
//! the deviatoric plasticity.

use schemars::JsonSchema;
use serde::Deserialize;

/// Equation of state of a Johnson–Cook material.
#[derive(Clone, Copy, Debug, Default, Deserialize, JsonSchema)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum EquationOfState {
    /// Hencky bulk response: Kirchhoff pressure −K ln J, with K from Young's modulus and
    /// Poisson's ratio (or `bulk_modulus` when given).
    #[default]
    Linear,
    /// Mie–Grüneisen with a linear shock velocity–particle velocity fit Us = c0 + s·up, for
    /// shocks: compression follows the Hugoniot, heating adds Γ0·E.
    MieGruneisen {
        /// Bulk sound speed c0, m/s.
        sound_speed: f64,
        /// Slope s of the Us–up fit.
        slope: f64,
        /// Grüneisen coefficient Γ0.
        gruneisen: f64,
    },
}

impl EquationOfState {
    /// Cauchy pressure (positive in compression) at volume ratio `j`, for reference density
    /// `density`, bulk modulus `bulk` and internal energy per reference volume `energy`.
    pub fn pressure(&self, j: f64, density: f64, bulk: f64, energy: f64) -> f64 {
        match *self {
            EquationOfState::Linear => -bulk * j.ln() / j,
            EquationOfState::MieGruneisen {
                sound_speed,
                slope,
                gruneisen,
            } => {
                let rho_c2 = density * sound_speed * sound_speed;
                let (cold, _) = hugoniot_cold(1.0 / j - 1.0, rho_c2, slope, gruneisen);
                cold + gruneisen * energy
            }
        }
    }

    /// The slopes of [`EquationOfState::pressure`]: (∂p/∂J, ∂p/∂energy) at the same
    /// arguments, in closed form (the implicit mode's tangent).
    pub fn pressure_slopes(&self, j: f64, density: f64, bulk: f64) -> (f64, f64) {
        match *self {
            EquationOfState::Linear => (-bulk * (1.0 - j.ln()) / (j * j), 0.0),
            EquationOfState::MieGruneisen {
                sound_speed,
                slope,
                gruneisen,
            } => {
                let rho_c2 = density * sound_speed * sound_speed;
                let (_, d_cold) = hugoniot_cold(1.0 / j - 1.0, rho_c2, slope, gruneisen);
                let dmu_dj = -1.0 / (j * j);
                (d_cold * dmu_dj, gruneisen)
            }
        }
    }

    /// Bulk modulus at zero pressure, Pa.
    pub fn reference_bulk_modulus(&self, density: f64, bulk: f64) -> f64 {
        match *self {
            EquationOfState::Linear => bulk,
            EquationOfState::MieGruneisen { sound_speed, .. } => {
                density * sound_speed * sound_speed
            }
        }
    }

    /// Tangent bulk modulus −J dp/dJ at `j` (by a central difference), never below the
    /// reference one; it sets the wave speed and so the time step.
    pub fn tangent_bulk_modulus(&self, j: f64, density: f64, bulk: f64) -> f64 {
        let h = 1e-6;
        let dp = self.pressure(j * (1.0 + h), density, bulk, 0.0)
            - self.pressure(j * (1.0 - h), density, bulk, 0.0);
        let tangent = -dp / (2.0 * h);
        tangent.max(self.reference_bulk_modulus(density, bulk))
    }
}

/// The Mie–Grüneisen cold pressure at compression μ = 1/J − 1 and its slope in μ: the
/// Hugoniot fit in compression (its denominator 1 − (s−1)μ kept at 0.1 or more, away from
/// its pole), linear ρc²μ in tension.
fn hugoniot_cold(mu: f64, rho_c2: f64, slope: f64, gruneisen: f64) -> (f64, f64) {
    if mu <= 0.0 {
        return (rho_c2 * mu, rho_c2);
    }
    let raw = 1.0 - (slope - 1.0) * mu;
    let (denominator, d_denominator) = if raw > 0.1 {
        (raw, -(slope - 1.0))
    } else {
        (0.1, 0.0)
    };
    let a = 1.0 - 0.5 * gruneisen;
    let numerator = mu * (1.0 + a * mu);
    let d_numerator = 1.0 + 2.0 * a * mu;
    let d2 = denominator * denominator;
    (
        rho_c2 * numerator / d2,
        rho_c2 * (d_numerator / d2 - 2.0 * numerator * d_denominator / (d2 * denominator)),
    )
}
