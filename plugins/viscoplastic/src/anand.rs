//! Anand's viscoplastic law at finite strain: F = Fe·Fp with logarithmic (Hencky) elastic
//! strain, as the Johnson–Cook law has it, but no yield surface: the plastic strain rate
//! is A·exp(−Q/RT)·sinh(ξσ/s)^(1/m) at every stress, and the deformation resistance s
//! hardens towards its saturation s* = ŝ·(ε̇ₚ/(A·exp(−Q/RT)))ⁿ at the rate
//! h₀·|1 − s/s*|ᵃ per unit plastic strain (Brown, Kim & Anand 1989).
//!
//! The step is backward Euler in the stress: the equivalent plastic strain increment Δ
//! solves Δ = dt·rate(q_trial − 3μΔ, s(Δ)) (found by bisection, so any step is stable, from
//! a microsecond of impact to a minute of a thermal cycle), with s(Δ) the exact solution of
//! the hardening equation over the step at the step's rate Δ/dt. The return is radial in
//! principal logarithmic strains (exact for an isotropic J2 flow); plastic flow is
//! isochoric. In 2D (plane strain) the update runs in 3D with F_zz = 1. The implicit mode
//! gets the update's exact derivative (`tangent.rs`).

use crate::AnandParameters;
use mpm_core::log_strain::{ElasticTrial, elastic_trial};
use mpm_core::material::{
    BatchStats, ConstitutiveLaw, FieldInit, FieldSpec, INELASTIC_WORK, SharedRead, StressBatch,
    TangentBatch, lame_parameters, out_of_plane_stretch,
};
use mpm_core::math::{embed3, top_left};
use nalgebra::Matrix3;

const IDENTITY3: [f64; 9] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];

/// Anand viscoplasticity (plane strain in 2D).
#[derive(Clone, Debug)]
pub struct Anand {
    pub(crate) params: AnandParameters,
    pub(crate) shear: f64,
    pub(crate) bulk: f64,
    fields: [FieldSpec; 5],
}

impl Anand {
    /// From checked parameters.
    pub fn new(params: AnandParameters) -> Self {
        let (lambda, shear) = lame_parameters(params.youngs_modulus, params.poisson_ratio);
        let scalar = |name, initial| FieldSpec {
            name,
            components: 1,
            initial,
        };
        // Order matters: `update_stress` destructures the slices in this order.
        let fields = [
            scalar("plastic_strain", FieldInit::Zero),
            scalar(
                "deformation_resistance",
                FieldInit::Constant(params.initial_resistance),
            ),
            scalar("plastic_strain_rate", FieldInit::Zero),
            scalar(INELASTIC_WORK, FieldInit::Zero),
            FieldSpec {
                name: "plastic_deformation_inverse",
                components: 9,
                initial: FieldInit::Values(&IDENTITY3),
            },
        ];
        Self {
            params,
            shear,
            bulk: lambda + 2.0 / 3.0 * shear,
            fields,
        }
    }

    /// A·exp(−Q/RT) at `temperature`, 1/s: the rate scale of the flow rule.
    pub(crate) fn rate_scale(&self, temperature: f64) -> f64 {
        self.params.pre_exponential * (-self.params.activation_temperature / temperature).exp()
    }

    /// The deformation resistance after plastic strain `increment` from `start` at the
    /// constant rate `increment / dt`: the exact solution of ds/dεₚ = h₀|1 − s/s*|ᵃ·sign.
    pub(crate) fn resistance_after(
        &self,
        start: f64,
        increment: f64,
        dt: f64,
        rate_scale: f64,
    ) -> f64 {
        if increment <= 0.0 {
            return start;
        }
        let p = &self.params;
        let saturated =
            p.saturation_coefficient * (increment / (dt * rate_scale)).powf(p.saturation_exponent);
        let gap = (saturated - start).abs();
        if gap == 0.0 {
            return saturated;
        }
        let a = p.hardening_exponent;
        let approach = p.hardening / saturated.powf(a) * increment;
        let remaining = if a == 1.0 {
            gap * (-approach).exp()
        } else {
            let base = gap.powf(1.0 - a) + (a - 1.0) * approach;
            if base > 0.0 {
                base.powf(1.0 / (1.0 - a))
            } else {
                0.0
            }
        };
        saturated + (start - saturated) / gap * remaining
    }

    /// The equivalent plastic strain increment of one step from trial von Mises (Kirchhoff)
    /// stress `q_trial` and resistance `resistance`: the root of Δ = dt·rate(q(Δ), s(Δ)),
    /// bracketed in [0, q_trial/(3μ)] (where the stress has relaxed to zero) and found to
    /// 1e-14 of the bracket (a stress error of 1e-14 of the trial stress).
    pub(crate) fn plastic_increment(
        &self,
        q_trial: f64,
        resistance: f64,
        dt: f64,
        rate_scale: f64,
    ) -> f64 {
        let p = &self.params;
        let three_mu = 3.0 * self.shear;
        let (mut lo, mut hi) = (0.0, q_trial / three_mu);
        if !(hi > 0.0 && dt > 0.0 && rate_scale > 0.0) {
            return 0.0;
        }
        let ln_scale = (dt * rate_scale).ln();
        // Too small an increment: the flow rule at the stress it leaves asks for more.
        let below_root = |increment: f64| {
            let q = q_trial - three_mu * increment;
            if q <= 0.0 {
                return false;
            }
            let s = self.resistance_after(resistance, increment, dt, rate_scale);
            let x = p.stress_multiplier * q / s;
            increment.ln() < ln_scale + ln_sinh(x) / p.rate_sensitivity
        };
        let tolerance = 1e-14 * hi;
        for _ in 0..64 {
            let mid = 0.5 * (lo + hi);
            if below_root(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
            if hi - lo <= tolerance {
                break;
            }
        }
        0.5 * (lo + hi)
    }
}

/// ln sinh x for x > 0, without overflow for large x.
fn ln_sinh(x: f64) -> f64 {
    if x > 20.0 {
        x - std::f64::consts::LN_2 + (-2.0 * x).exp().ln_1p()
    } else {
        x.sinh().ln()
    }
}

impl ConstitutiveLaw for Anand {
    fn density(&self) -> f64 {
        self.params.density
    }

    /// 1 + ν: the plane-strain expansion of an isotropic elastic solid.
    fn plane_strain_expansion(&self) -> f64 {
        1.0 + self.params.poisson_ratio
    }

    /// In 2D the law works on [[F, 0], [0, s]], s the stretch across the plane, and gives
    /// σzz from its 3D stress.
    fn plane_strain_stress(&self) -> bool {
        true
    }

    fn state_fields(&self) -> &[FieldSpec] {
        &self.fields
    }

    fn shared_reads(&self) -> &[SharedRead] {
        // With a thermal physics the flow rule reads the conducted temperature; without one
        // it holds the section's `temperature`.
        &[SharedRead {
            name: "temperature",
            required: false,
        }]
    }

    fn reports_plastic_work(&self) -> bool {
        true
    }

    fn has_stress_derivative(&self) -> bool {
        true
    }

    /// The consistent tangent of this update (`tangent.rs`).
    fn stress_derivative<const D: usize>(&self, batch: TangentBatch<'_, D>) {
        crate::tangent::stress_derivative(self, batch);
    }

    fn cycles_to_crack(&self, work_per_cycle: f64) -> Option<f64> {
        self.params.fatigue?.cycles(work_per_cycle)
    }

    fn cycles_to_failure(&self, work_per_cycle: f64) -> Option<f64> {
        self.params.fatigue?.cycles_to_failure(work_per_cycle)
    }

    fn update_stress<const D: usize>(&self, batch: StressBatch<'_, D>) -> BatchStats {
        let (mu, bulk) = (self.shear, self.bulk);
        let [strain_f, resistance_f, rate_f, work_f, inverse_f, ..] = batch.state.fields;
        let shared_temperature = batch.shared[0];
        let fixed_scale = self.rate_scale(self.params.temperature);
        let mut energy = 0.0;
        let mut min_j = 1.0f64;
        for (k, ((f, stress), v0)) in batch
            .deformation_gradient
            .iter()
            .zip(batch.stress.iter_mut())
            .zip(batch.volume0)
            .enumerate()
        {
            let fp_inv_slot = &mut inverse_f[9 * k..9 * k + 9];
            let fp_inv = Matrix3::from_row_slice(fp_inv_slot);
            let Some(trial) = elastic_trial(
                &embed3(f, out_of_plane_stretch(batch.out_of_plane_stretch, k)),
                &fp_inv,
            ) else {
                // The solver stops the run at det F <= 0; leave the stress unchanged.
                continue;
            };
            let ElasticTrial {
                j,
                axes,
                deviatoric,
                ..
            } = trial;
            let q_trial = trial.equivalent_stress(mu);

            let rate_scale = match shared_temperature.get(k) {
                Some(&t) => self.rate_scale(t),
                None => fixed_scale,
            };
            let increment = self.plastic_increment(q_trial, resistance_f[k], batch.dt, rate_scale);
            let scale = if increment > 0.0 {
                (1.0 - 3.0 * mu * increment / q_trial).max(0.0)
            } else {
                1.0
            };
            let q = q_trial * scale;
            resistance_f[k] =
                self.resistance_after(resistance_f[k], increment, batch.dt, rate_scale);
            strain_f[k] += increment;
            rate_f[k] = increment / batch.dt;
            // Plastic work per reference volume (τ : dεp with Kirchhoff stress).
            let work = q * increment;
            work_f[k] += work;
            if let Some(w) = batch.plastic_work.get_mut(k) {
                *w = work;
            }

            // Cauchy stress σ = τ/J along the trial principal directions.
            let new_deviatoric = deviatoric * scale;
            let ln_j = j.ln();
            let principal = new_deviatoric.map(|e| (2.0 * mu * e + bulk * ln_j) / j);
            let full = axes * Matrix3::from_diagonal(&principal) * axes.transpose();
            *stress = top_left(&full);
            if let Some(out) = batch.out_of_plane_stress.get_mut(k) {
                *out = full[(2, 2)];
            }
            if scale != 1.0 {
                // Row-major, as the slot keeps it.
                let fp_inv_new = trial.plastic_inverse_after(&new_deviatoric);
                fp_inv_slot.copy_from_slice(fp_inv_new.transpose().as_slice());
            }
            min_j = min_j.min(j);
            energy += v0 * (mu * new_deviatoric.norm_squared() + 0.5 * bulk * ln_j * ln_j);
        }
        // Compression raises the Cauchy stiffness by 1/J (the density rises with it, but
        // bound the speed from above).
        let speed2 = (bulk + 4.0 / 3.0 * mu) / self.params.density / min_j.min(1.0);
        BatchStats {
            strain_energy: energy,
            max_wave_speed: speed2.sqrt(),
        }
    }
}
