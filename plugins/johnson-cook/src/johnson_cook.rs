//! The Johnson–Cook material: finite-strain J2 plasticity, multiplicative (F = Fe·Fp) with
//! logarithmic (Hencky) elastic strain and radial return in principal stretches, a
//! Johnson–Cook flow stress, an equation of state for the pressure, adiabatic heating, and
//! Johnson–Cook damage with failure.
//!
//! Each particle keeps Fp⁻¹ as a 3×3 matrix (in 2D plane strain the out-of-plane stretch
//! matters for J2 plasticity, so the update always runs in 3D with F_zz = 1). The trial
//! elastic strain is ε = ½ ln(Fe Feᵀ) with Fe = F Fp⁻¹; its deviatoric part gives the trial
//! Kirchhoff stress 2μ dev ε; the return map scales it back onto the yield surface along
//! the same principal directions (exact for isotropic J2 in logarithmic strain); J = det F
//! alone sets the pressure, so plastic flow is exactly isochoric.

use crate::JohnsonCookParameters;
use crate::damage::FailureMode;
use mpm_core::log_strain::{ElasticTrial, elastic_trial};
use mpm_core::material::{
    AveragedState, BatchStats, ConstitutiveLaw, FieldInit, FieldSpec, SharedRead, StressBatch,
    TangentBatch, lame_parameters, out_of_plane_stretch,
};
#[cfg(test)]
use mpm_core::math::Matrix;
use mpm_core::math::{embed3, top_left};
use nalgebra::{Matrix3, Vector3};

const IDENTITY3: [f64; 9] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];

/// Johnson–Cook plasticity and damage (plane strain in 2D).
#[derive(Clone, Debug)]
pub struct JohnsonCook {
    pub(crate) params: JohnsonCookParameters,
    pub(crate) shear: f64,
    pub(crate) bulk: f64,
    /// The five fields every particle keeps, then `local_damage` with
    /// `damage.averaging_radius` ([`LOCAL_DAMAGE`]).
    fields: Vec<FieldSpec>,
}

/// Index of `local_damage` among the state fields, when the damage is averaged.
pub(crate) const LOCAL_DAMAGE: usize = 5;

impl JohnsonCook {
    /// From checked parameters.
    pub fn new(params: JohnsonCookParameters) -> Self {
        let (lambda, shear) = lame_parameters(params.youngs_modulus, params.poisson_ratio);
        let bulk = lambda + 2.0 / 3.0 * shear;
        let t0 = params.initial_temperature();
        let scalar = |name, initial| FieldSpec {
            name,
            components: 1,
            initial,
        };
        // Order matters: `update_stress` destructures the slices in this order.
        let mut fields = vec![
            scalar("plastic_strain", FieldInit::Zero),
            scalar("damage", FieldInit::Zero),
            scalar("temperature", FieldInit::Constant(t0)),
            scalar("plastic_strain_rate", FieldInit::Zero),
            FieldSpec {
                name: "plastic_deformation_inverse",
                components: 9,
                initial: FieldInit::Values(&IDENTITY3),
            },
        ];
        if params.damage.is_some_and(|d| d.averaging_radius.is_some()) {
            fields.push(scalar("local_damage", FieldInit::Zero));
        }
        Self {
            params,
            shear,
            bulk,
            fields,
        }
    }

    /// The damage a plastic strain `increment` over `dt` adds: Δεₚ / ε_f at the triaxiality
    /// of Kirchhoff pressure `kirchhoff_pressure` and von Mises stress `q`, at `temperature`
    /// (0 without a damage model or without plastic flow).
    pub(crate) fn damage_increment(
        &self,
        increment: f64,
        dt: f64,
        kirchhoff_pressure: f64,
        q: f64,
        temperature: f64,
    ) -> f64 {
        let (Some(d), true) = (&self.params.damage, increment > 0.0) else {
            return 0.0;
        };
        let flow = &self.params.flow_stress;
        let triaxiality = if q > 0.0 {
            (-kirchhoff_pressure / q).clamp(-10.0, 10.0)
        } else {
            0.0
        };
        increment
            / d.failure_strain(
                triaxiality,
                increment / dt / flow.reference_strain_rate,
                flow.homologous_temperature(temperature),
            )
    }

    /// Plastic strain increment that brings trial von Mises (Kirchhoff) stress `q_trial`
    /// back to the flow stress: q_trial − 3μΔε = σ_y(εₚ + Δε, Δε/dt, T)
    /// ([`crate::FlowStress::radial_return`]).
    pub(crate) fn return_map(&self, q_trial: f64, strain: f64, thermal: f64, dt: f64) -> f64 {
        self.params
            .flow_stress
            .radial_return(q_trial, 3.0 * self.shear, 1.0, strain, thermal, dt)
    }
}

impl ConstitutiveLaw for JohnsonCook {
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

    /// With `damage.averaging_radius`: `damage` is `local_damage` averaged over it.
    fn averaged_state(&self) -> Option<AveragedState> {
        let radius = self.params.damage?.averaging_radius?;
        Some(AveragedState {
            local: LOCAL_DAMAGE,
            averaged: 1,
            radius,
            cap: 1.0,
        })
    }

    fn shared_reads(&self) -> &[SharedRead] {
        // With a thermal physics the temperature is shared (conducted); without one the
        // law heats its own `temperature` adiabatically.
        &[SharedRead {
            name: "temperature",
            required: false,
        }]
    }

    fn has_stress_derivative(&self) -> bool {
        true
    }

    fn reports_plastic_work(&self) -> bool {
        true
    }

    /// The consistent tangent of this update (`tangent.rs`).
    fn stress_derivative<const D: usize>(&self, batch: TangentBatch<'_, D>) {
        crate::tangent::stress_derivative(self, batch);
    }

    fn update_stress<const D: usize>(&self, batch: StressBatch<'_, D>) -> BatchStats {
        let p = &self.params;
        let (mu, bulk, rho0) = (self.shear, self.bulk, p.density);
        let flow = &p.flow_stress;
        let heat_per_work = p.taylor_quinney / (rho0 * p.specific_heat);
        let t0 = p.initial_temperature();
        let [strain_f, damage_f, temp_f, rate_f, inverse_f, local_f, ..] = batch.state.fields;
        // With an averaging radius the plastic strain drives `local_damage`; the core
        // averages it into `damage` after the step.
        let mut local_damage = (self.fields.len() > LOCAL_DAMAGE).then_some(local_f);
        let shared_temperature = batch.shared[0];
        let conducted = !shared_temperature.is_empty();
        let mut energy = 0.0;
        // Volume ratios that bound the wave speed: of intact particles, and of failed ones
        // in compression (failed particles in tension carry no stress, and must not shrink
        // the time step as a crack opens).
        let (mut min_j, mut max_j, mut min_j_failed) = (1.0f64, 1.0f64, 1.0f64);
        for (k, ((f, stress), v0)) in batch
            .deformation_gradient
            .iter()
            .zip(batch.stress.iter_mut())
            .zip(batch.volume0)
            .enumerate()
        {
            let fp_inv_slot = &mut inverse_f[9 * k..9 * k + 9];
            let fp_inv = Matrix3::from_row_slice(fp_inv_slot);
            let Some(elastic) = elastic_trial(
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
            } = elastic;
            let trial = deviatoric * (2.0 * mu);
            let q_trial = (1.5 * trial.norm_squared()).sqrt();

            let temperature = if conducted {
                shared_temperature[k]
            } else {
                temp_f[k]
            };
            let failed = damage_f[k] >= 1.0;
            let thermal = flow.thermal_factor(temperature);
            let (increment, scale) = if failed {
                (0.0, 0.0)
            } else if q_trial > flow.evaluate(strain_f[k], 0.0, thermal).0 {
                let dep = self.return_map(q_trial, strain_f[k], thermal, batch.dt);
                (dep, (1.0 - 3.0 * mu * dep / q_trial).max(0.0))
            } else {
                (0.0, 1.0)
            };
            let mut deviatoric_stress = trial * scale;
            let q = q_trial * scale;
            strain_f[k] += increment;
            rate_f[k] = increment / batch.dt;
            // Plastic work per reference volume (τ : dεp with Kirchhoff stress).
            let work = q * increment;
            if let Some(w) = batch.plastic_work.get_mut(k) {
                *w = work;
            }
            let new_temperature = if conducted {
                temperature
            } else {
                temperature + heat_per_work * work
            };
            temp_f[k] = new_temperature;

            let internal_energy = rho0 * p.specific_heat * (new_temperature - t0);
            let mut pressure = p.equation_of_state.pressure(j, rho0, bulk, internal_energy);
            if !failed {
                let added =
                    self.damage_increment(increment, batch.dt, pressure * j, q, new_temperature);
                match local_damage.as_deref_mut() {
                    Some(local) => local[k] += added,
                    None => damage_f[k] = (damage_f[k] + added).min(1.0),
                }
            }
            if damage_f[k] >= 1.0 {
                deviatoric_stress = Vector3::zeros();
                let mode = p.damage.map(|d| d.failure).unwrap_or_default();
                pressure = match mode {
                    FailureMode::NoTension => pressure.max(0.0),
                    FailureMode::NoStress => 0.0,
                };
            }

            // Cauchy stress σ = τ/J, principal directions from the trial elastic strain.
            let principal = deviatoric_stress.map(|s| s / j - pressure);
            let full = axes * Matrix3::from_diagonal(&principal) * axes.transpose();
            *stress = top_left(&full);
            if let Some(out) = batch.out_of_plane_stress.get_mut(k) {
                *out = full[(2, 2)];
            }

            // Return the elastic stretch along the same axes (Fp⁻¹ row-major in its slot).
            let new_deviatoric = deviatoric_stress / (2.0 * mu);
            if scale != 1.0 {
                let fp_inv_new = elastic.plastic_inverse_after(&new_deviatoric);
                fp_inv_slot.copy_from_slice(fp_inv_new.transpose().as_slice());
            }
            let ln_j = j.ln();
            if damage_f[k] >= 1.0 {
                if j < 1.0 {
                    min_j_failed = min_j_failed.min(j);
                    energy += v0 * 0.5 * bulk * ln_j * ln_j;
                }
            } else {
                min_j = min_j.min(j);
                max_j = max_j.max(j);
                energy += v0 * (mu * new_deviatoric.norm_squared() + 0.5 * bulk * ln_j * ln_j);
            }
        }
        let eos = &p.equation_of_state;
        let speed2 = |jj: f64, shear: f64| {
            (eos.tangent_bulk_modulus(jj, rho0, bulk) + 4.0 / 3.0 * shear) * jj / rho0
        };
        let speed2 = speed2(min_j, mu)
            .max(speed2(max_j, mu))
            .max(speed2(min_j_failed, 0.0));
        BatchStats {
            strain_energy: energy,
            max_wave_speed: speed2.sqrt(),
        }
    }
}

/// 3×3 view of a `D`×`D` matrix (used by tests).
#[cfg(test)]
pub(crate) fn embed<const D: usize>(m: &Matrix<D>) -> Matrix3<f64> {
    embed3(m, 1.0)
}
