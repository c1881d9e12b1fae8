//! The consistent tangent of the Anand update for the implicit mode: the exact derivative
//! of `update_stress` from the step's starting state (Fp⁻¹, deformation resistance) along
//! a change δF of the deformation gradient.
//!
//! The trial strain's change δε comes from `mpm_core::log_strain`. The return scales the
//! deviatoric trial strain e by r = 1 − 3μΔ/q_trial, where Δ solves
//! G = ln Δ − ln(dt·A·e^(−Q/RT)) − (1/m)·ln sinh(ξq/s(Δ)) = 0 with q = q_trial − 3μΔ; by
//! the implicit function theorem δΔ = δq_trial/(3μ + H) with
//! H = q·s'(Δ)/s + 1/(kΔ), k = ξ·coth(ξq/s)/(m·s): the slope of the flow rule's stress in
//! Δ, as the hardening modulus is for a rate-independent law. s'(Δ) (through the
//! hardening over the step and the rate in s*) is a central difference of the exact
//! resistance update, a scalar function.

use crate::anand::Anand;
use mpm_core::log_strain::{deviator, elastic_trial_change};
use mpm_core::material::{TangentBatch, out_of_plane_stretch};
use mpm_core::math::{embed3, top_left};
use nalgebra::Matrix3;

/// dσ = ∂σ/∂F : δF of every particle of the batch (see the module documentation).
pub(crate) fn stress_derivative<const D: usize>(law: &Anand, batch: TangentBatch<'_, D>) {
    let p = &law.params;
    let (mu, bulk) = (law.shear, law.bulk);
    let [_, resistance_f, _, _, inverse_f, ..] = batch.state.fields;
    let shared_temperature = batch.shared[0];
    let fixed_scale = law.rate_scale(p.temperature);
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

        let rate_scale = match shared_temperature.get(k) {
            Some(&t) => law.rate_scale(t),
            None => fixed_scale,
        };
        let start = resistance_f[k];
        let increment = law.plastic_increment(q_trial, start, batch.dt, rate_scale);
        let (mut scale, mut d_scale) = (1.0, 0.0);
        if increment > 0.0 {
            let raw = 1.0 - 3.0 * mu * increment / q_trial;
            scale = raw.max(0.0);
            let q = q_trial - 3.0 * mu * increment;
            if raw > 0.0 && q > 0.0 {
                let resistance = |d: f64| law.resistance_after(start, d, batch.dt, rate_scale);
                let s = resistance(increment);
                let h = 1e-6 * increment;
                let ds = (resistance(increment + h) - resistance(increment - h)) / (2.0 * h);
                let x = p.stress_multiplier * q / s;
                let k_flow = p.stress_multiplier / (p.rate_sensitivity * s * x.tanh());
                let slope = q * ds / s + 1.0 / (k_flow * increment);
                let d_q_trial = 6.0 * mu * mu * e.dot(&d_strain) / q_trial;
                let d_increment = d_q_trial / (3.0 * mu + slope);
                d_scale = -3.0 * mu * (d_increment * q_trial - increment * d_q_trial)
                    / (q_trial * q_trial);
            }
        }
        // σ = τ/J with τ = 2μ·r·e + K ln J I.
        let tau = e * (2.0 * mu * scale) + Matrix3::identity() * (bulk * j.ln());
        let d_tau = (e * d_scale + deviator(&d_strain) * scale) * (2.0 * mu)
            + Matrix3::identity() * (bulk * dj / j);
        let d_sigma = d_tau / j - tau * (dj / (j * j));
        *out = top_left(&d_sigma);
    }
}
