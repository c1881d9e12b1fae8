//! The consistent tangent of the Johnson–Cook update for the implicit mode: the exact
//! derivative of `update_stress` from the step's starting state (Fp⁻¹, plastic strain,
//! temperature, damage) along a change δF of the deformation gradient.
//!
//! With be = Fe Feᵀ (Fe = F Fp⁻¹) and the trial logarithmic strain ε = ½ ln be:
//! - δε in the principal axes of be: δε'ᵢⱼ = ½ (Nᵀ δbe N)ᵢⱼ (ln bᵢ − ln bⱼ)/(bᵢ − bⱼ)
//!   (1/bᵢ on the diagonal), δbe = δFe Feᵀ + Fe δFeᵀ (`mpm_core::log_strain`);
//! - the radial return scales the deviatoric trial strain e = dev ε: τ_dev = s·2μe with
//!   s = 1 − 3μΔγ/q_trial and q_trial − 3μΔγ = σ_y(εₚ + Δγ, Δγ/dt, T), so
//!   δq_trial = 6μ² e:δε / q_trial and δΔγ = δq_trial / (3μ + H), H = ∂σ_y/∂εₚ + ∂σ_y/∂ε̇ / dt;
//! - σ = τ_dev/J − p(J, E) I, with the internal energy E raised by the plastic work when the
//!   law heats itself (no thermal physics).
//!
//! Damage changes the stress only where it reaches 1 (the particle fails): the tangent
//! follows the branch the update takes there, as at the yield point.

use crate::damage::FailureMode;
use crate::johnson_cook::JohnsonCook;
use mpm_core::log_strain::{deviator, elastic_trial_change};
use mpm_core::material::{TangentBatch, out_of_plane_stretch};
use mpm_core::math::{embed3, top_left};
use nalgebra::Matrix3;

/// dσ = ∂σ/∂F : δF of every particle of the batch (see the module documentation).
pub(crate) fn stress_derivative<const D: usize>(law: &JohnsonCook, batch: TangentBatch<'_, D>) {
    let p = &law.params;
    let (mu, bulk, rho0) = (law.shear, law.bulk, p.density);
    let flow = &p.flow_stress;
    let heat_per_work = p.taylor_quinney / (rho0 * p.specific_heat);
    let t0 = p.initial_temperature();
    let [strain_f, damage_f, temp_f, _, inverse_f, ..] = batch.state.fields;
    let shared_temperature = batch.shared[0];
    let conducted = !shared_temperature.is_empty();
    let failure = p.damage.map(|d| d.failure).unwrap_or_default();
    let averaged = p.damage.and_then(|d| d.averaging_radius);
    for (k, ((f, df), out)) in batch
        .deformation_gradient
        .iter()
        .zip(batch.direction)
        .zip(batch.stress_change.iter_mut())
        .enumerate()
    {
        out.fill(0.0);
        // In 2D the stretch across the plane is held: δF_zz = 0.
        let fp_inv = Matrix3::from_row_slice(&inverse_f[9 * k..9 * k + 9]);
        let Some(trial) = elastic_trial_change(
            &embed3(f, out_of_plane_stretch(batch.out_of_plane_stretch, k)),
            &embed3(df, 0.0),
            &fp_inv,
        ) else {
            continue;
        };
        let (j, dj, e, d_strain) = (trial.j, trial.dj, trial.strain, trial.change);
        let q_trial = trial.equivalent_stress(mu);

        let temperature = if conducted {
            shared_temperature[k]
        } else {
            temp_f[k]
        };
        let mut failed = damage_f[k] >= 1.0;
        let thermal = flow.thermal_factor(temperature);
        let (mut increment, mut scale, mut d_increment, mut d_scale, mut d_q_trial) =
            (0.0, 1.0, 0.0, 0.0, 0.0);
        if failed {
            scale = 0.0;
        } else if q_trial > flow.evaluate(strain_f[k], 0.0, thermal).0 {
            increment = law.return_map(q_trial, strain_f[k], thermal, batch.dt);
            let raw = 1.0 - 3.0 * mu * increment / q_trial;
            scale = raw.max(0.0);
            let (_, h_strain, h_rate) =
                flow.evaluate(strain_f[k] + increment, increment / batch.dt, thermal);
            let hardening = h_strain + h_rate / batch.dt;
            d_q_trial = 6.0 * mu * mu * e.dot(&d_strain) / q_trial;
            d_increment = if hardening.is_finite() {
                d_q_trial / (3.0 * mu + hardening)
            } else {
                0.0
            };
            if raw > 0.0 {
                d_scale = -3.0 * mu * (d_increment * q_trial - increment * d_q_trial)
                    / (q_trial * q_trial);
            }
        }
        let q = q_trial * scale;
        let d_q = d_q_trial * scale + q_trial * d_scale;
        let work = q * increment;
        let d_work = d_q * increment + q * d_increment;
        let (new_temperature, d_energy) = if conducted {
            (temperature, 0.0)
        } else {
            (
                temperature + heat_per_work * work,
                rho0 * p.specific_heat * heat_per_work * d_work,
            )
        };
        let energy = rho0 * p.specific_heat * (new_temperature - t0);
        let eos = &p.equation_of_state;
        let pressure = eos.pressure(j, rho0, bulk, energy);
        let (dp_dj, dp_denergy) = eos.pressure_slopes(j, rho0, bulk);
        let mut d_pressure = dp_dj * dj + dp_denergy * d_energy;
        // The update's damage: the particle fails in this update when it reaches 1 (with
        // an averaging radius only the core's average, after the step, fails it).
        if !failed && averaged.is_none() {
            failed = damage_f[k]
                + law.damage_increment(increment, batch.dt, pressure * j, q, new_temperature)
                >= 1.0;
        }
        let d_deviatoric = if failed {
            d_pressure = match failure {
                FailureMode::NoTension if pressure > 0.0 => d_pressure,
                _ => 0.0,
            };
            Matrix3::zeros()
        } else {
            let tau = e * (2.0 * mu * scale);
            let d_tau = (e * d_scale + deviator(&d_strain) * scale) * (2.0 * mu);
            d_tau / j - tau * (dj / (j * j))
        };
        let d_sigma = d_deviatoric - Matrix3::identity() * d_pressure;
        *out = top_left(&d_sigma);
    }
}
