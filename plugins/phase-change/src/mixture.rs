//! `phase_mixture`: a material whose stress moves from a viscous fluid to an elastic solid
//! as its solid fraction (from the phase-change physics) rises.
//!
//! σ = σ_solid + (1 − f)·(2η·dev D + q·I). The solid part is incremental
//! (hypoelastic, Jaumann-rotated): each step adds f·(λ tr Δε I + 2μ Δε), so a particle that
//! solidifies carries no stress until it deforms after solidifying, and only strain after
//! gelation loads a curing resin. The laws see the mechanical F (free strains removed).
//!
//! The liquid's mean stress q is K_l·ln J of the whole volume change, or, with
//! `liquid.pressure_relaxation_time` τ, a Maxwell pressure that relaxes over τ (the flow
//! that drains or fills a gap is far faster than a cure step, and no static step resolves
//! it): q_{n+1} = a q_n + b K_l (ln J_{n+1} − ln J_n) with a = e^{−dt/τ} and
//! b = (τ/dt)(1 − a), exact for a constant volume rate over the step. For dt ≪ τ it is the
//! elastic K_l ln J; for dt ≫ τ a bulk viscosity K_l τ, and the liquid keeps next to no
//! pressure from one static step to the next.
//!
//! With `solid.plasticity` the solid stress is returned onto a Johnson–Cook yield surface
//! after each increment and damages to failure (`mixture_plasticity.rs`).
//!
//! In 2D (plane strain) the law is its 3D self at F = [[F, 0], [0, s]], s the stretch across
//! the plane (1 unless a free strain acts there): the solid stress keeps its zz part in slot
//! 8 of `solid_stress`, and `previous_F`'s slot 8 keeps s − 1 of the last update (so its
//! zero start is the unstretched state).

use crate::mixture_plasticity::{self, PlasticState, SolidPlasticity};
use mpm_core::material::{
    AveragedState, BatchStats, ConstitutiveLaw, FieldInit, FieldSpec, SharedRead, StressBatch,
    TangentBatch, lame_parameters, out_of_plane_stretch,
};
use mpm_core::math::{Matrix, cofactor, determinant, inverse};
use mpm_core::plugin::check_elastic_constants;
use mpm_core::scene::Issue;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Scene section of a `phase_mixture` material.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PhaseMixtureParameters {
    /// Mass density, kg/m³ (of the starting phase).
    pub density: f64,
    /// Elastic constants of the solid.
    pub solid: SolidPhase,
    /// The liquid.
    pub liquid: LiquidPhase,
}

/// Elastic constants of the solid phase.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SolidPhase {
    /// Young's modulus, Pa.
    pub youngs_modulus: f64,
    /// Poisson's ratio, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// J2 plasticity and damage of the solid (`mixture_plasticity.rs`); absent: elastic.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plasticity: Option<SolidPlasticity>,
}

/// The liquid phase: Newtonian viscosity and a bulk modulus (weak compressibility).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LiquidPhase {
    /// Dynamic viscosity, Pa·s.
    pub viscosity: f64,
    /// Bulk modulus, Pa.
    pub bulk_modulus: f64,
    /// Seconds over which the liquid's pressure relaxes (see the module documentation);
    /// absent: no relaxation, the pressure is K_l ln J of the whole volume change.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pressure_relaxation_time: Option<f64>,
}

impl PhaseMixtureParameters {
    /// Problems at `path`.
    pub fn check(&self, path: &str) -> Vec<Issue> {
        let mut issues = check_elastic_constants(
            path,
            self.density,
            self.solid.youngs_modulus,
            self.solid.poisson_ratio,
        );
        for i in &mut issues {
            if !i.path.ends_with(".density") {
                i.path = i.path.replacen(path, &format!("{path}.solid"), 1);
            }
        }
        for (name, v) in [
            ("viscosity", self.liquid.viscosity),
            ("bulk_modulus", self.liquid.bulk_modulus),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                issues.push(Issue::new(
                    format!("{path}.liquid.{name}"),
                    format!("must be a finite number >= 0 (got {v})"),
                ));
            }
        }
        if let Some(p) = &self.solid.plasticity {
            issues.extend(p.check(&format!("{path}.solid.plasticity")));
        }
        if let Some(tau) = self.liquid.pressure_relaxation_time
            && !(tau.is_finite() && tau > 0.0)
        {
            issues.push(Issue::new(
                format!("{path}.liquid.pressure_relaxation_time"),
                format!("must be a finite number > 0 seconds (got {tau})"),
            ));
        }
        issues
    }
}

/// The Maxwell factors (a, b) of the liquid pressure over a step `dt` with relaxation time
/// `tau` (see the module documentation); (1, 1) without relaxation or for dt = 0.
fn relaxation(tau: Option<f64>, dt: f64) -> (f64, f64) {
    match tau {
        Some(tau) if dt > 0.0 => {
            let x = dt / tau;
            let a = (-x).exp();
            // (1 − e^{−x})/x, with its series where x is too small for the quotient.
            let b = if x < 1e-8 {
                1.0 - 0.5 * x
            } else {
                -(-x).exp_m1() / x
            };
            (a, b)
        }
        _ => (1.0, 1.0),
    }
}

/// A D×D matrix from a 9-number state slot (row-major, D per row).
fn load<const D: usize>(slot: &[f64]) -> Matrix<D> {
    let mut m = Matrix::<D>::zeros();
    for r in 0..D {
        for c in 0..D {
            m[(r, c)] = slot[r * D + c];
        }
    }
    m
}

/// Writes a D×D matrix into a 9-number state slot, as [`load`] reads it.
fn store<const D: usize>(slot: &mut [f64], m: &Matrix<D>) {
    for r in 0..D {
        for c in 0..D {
            slot[r * D + c] = m[(r, c)];
        }
    }
}

/// In 2D, the stretch across the plane now and at the last update (`previous_F`'s slot 8
/// holds s − 1); in 3D, 1 and 1 (slot 8 there is F_zz itself).
fn stretches<const D: usize>(stretch: &[f64], previous: &[f64], k: usize) -> (f64, f64) {
    if D == 2 {
        (out_of_plane_stretch(stretch, k), 1.0 + previous[9 * k + 8])
    } else {
        (1.0, 1.0)
    }
}

/// The law (see the module documentation).
pub struct PhaseMixture {
    params: PhaseMixtureParameters,
    lambda: f64,
    mu: f64,
    /// `previous_F`, `solid_stress`, then `liquid_pressure` with relaxation, then
    /// `plastic_strain`, `damage` and `local_damage` as the solid's plasticity asks.
    fields: Vec<FieldSpec>,
    /// Where the optional fields sit in `fields`.
    slots: Slots,
    /// `solid_fraction`, and `temperature` with plasticity.
    reads: Vec<SharedRead>,
}

/// Positions of the optional state fields.
#[derive(Clone, Copy, Debug)]
struct Slots {
    pressure: Option<usize>,
    plastic_strain: Option<usize>,
    damage: Option<usize>,
    local_damage: Option<usize>,
}

impl PhaseMixture {
    /// The law for checked parameters.
    pub fn new(params: PhaseMixtureParameters) -> Self {
        let (lambda, mu) = lame_parameters(params.solid.youngs_modulus, params.solid.poisson_ratio);
        let field = |name, components, initial| FieldSpec {
            name,
            components,
            initial,
        };
        let mut fields = vec![
            field("previous_F", 9, FieldInit::Identity),
            field("solid_stress", 9, FieldInit::Zero),
        ];
        let mut add = |wanted: bool, name| {
            wanted.then(|| {
                fields.push(field(name, 1, FieldInit::Zero));
                fields.len() - 1
            })
        };
        let plastic = params.solid.plasticity;
        let slots = Slots {
            pressure: add(
                params.liquid.pressure_relaxation_time.is_some(),
                "liquid_pressure",
            ),
            plastic_strain: add(plastic.is_some(), "plastic_strain"),
            damage: add(plastic.is_some_and(|p| p.damage.is_some()), "damage"),
            local_damage: add(
                plastic.is_some_and(|p| p.damage.is_some_and(|d| d.averaging_radius.is_some())),
                "local_damage",
            ),
        };
        let mut reads = vec![SharedRead {
            name: "solid_fraction",
            required: true,
        }];
        if plastic.is_some() {
            reads.push(SharedRead {
                name: "temperature",
                required: false,
            });
        }
        Self {
            params,
            lambda,
            mu,
            fields,
            slots,
            reads,
        }
    }
}

impl ConstitutiveLaw for PhaseMixture {
    fn density(&self) -> f64 {
        self.params.density
    }

    /// 1 + ν of the solid: the liquid carries (next to) no stress from free strain once
    /// its pressure relaxes, and after the gel the solid does.
    fn plane_strain_expansion(&self) -> f64 {
        1.0 + self.params.solid.poisson_ratio
    }

    fn state_fields(&self) -> &[FieldSpec] {
        &self.fields
    }

    fn shared_reads(&self) -> &[SharedRead] {
        &self.reads
    }

    /// With `solid.plasticity.damage.averaging_radius`: `damage` is `local_damage`
    /// averaged over the radius.
    fn averaged_state(&self) -> Option<AveragedState> {
        let radius = self.params.solid.plasticity?.damage?.averaging_radius?;
        Some(AveragedState {
            local: self.slots.local_damage?,
            averaged: self.slots.damage?,
            radius,
            cap: 1.0,
        })
    }

    /// With `solid.plasticity`: the solid's plastic work, for the energy ledger (and as
    /// heat where the thermal physics gives the material a Taylor–Quinney factor).
    fn reports_plastic_work(&self) -> bool {
        self.params.solid.plasticity.is_some()
    }

    /// See the module documentation: the solid keeps σzz, the liquid's pressure sees the
    /// whole volume change.
    fn plane_strain_stress(&self) -> bool {
        true
    }

    fn update_stress<const D: usize>(&self, batch: StressBatch<'_, D>) -> BatchStats {
        let mut fields = batch.state.fields;
        let mut take = |slot: Option<usize>| slot.map(|i| std::mem::take(&mut fields[i]));
        let pressure = take(self.slots.pressure).unwrap_or_default();
        let plastic_strain = take(self.slots.plastic_strain).unwrap_or_default();
        let damage = take(self.slots.damage).unwrap_or_default();
        let local_damage = take(self.slots.local_damage).unwrap_or_default();
        let [previous, solid, ..] = fields;
        let fraction = batch.shared[0];
        let temperature = batch.shared[1];
        let plasticity = self.params.solid.plasticity;
        let (lambda, mu) = (self.lambda, self.mu);
        let (eta, bulk) = (
            self.params.liquid.viscosity,
            self.params.liquid.bulk_modulus,
        );
        let tau = self.params.liquid.pressure_relaxation_time;
        let (decay, gain) = relaxation(tau, batch.dt);
        let identity = Matrix::<D>::identity();
        let mut energy = 0.0;
        let mut stiffest = 0.0f64;
        for (k, (f, stress)) in batch
            .deformation_gradient
            .iter()
            .zip(batch.stress.iter_mut())
            .enumerate()
        {
            let phi = fraction.get(k).copied().unwrap_or(1.0).clamp(0.0, 1.0);
            let f_prev: Matrix<D> = load(&previous[9 * k..9 * k + 9]);
            let (stretch, stretch_prev) = stretches::<D>(batch.out_of_plane_stretch, previous, k);
            let increment = inverse(&f_prev).map_or(identity, |inv| f * inv);
            let strain = (increment + increment.transpose()) * 0.5 - identity;
            let spin = (increment - increment.transpose()) * 0.5;
            // The strain across the plane (0 in 3D) and the whole trace.
            let strain_zz = stretch / stretch_prev - 1.0;
            let trace = strain.trace() + strain_zz;
            let mut s: Matrix<D> = load(&solid[9 * k..9 * k + 9]);
            s += spin * s - s * spin;
            s += (identity * (lambda * trace) + strain * (2.0 * mu)) * phi;
            // σzz of the solid (2D; unused in 3D).
            let mut zz = solid[9 * k + 8] + phi * (lambda * trace + 2.0 * mu * strain_zz);
            if let Some(plastic) = &plasticity {
                let mut s3 = mixture_plasticity::embed(&s, zz);
                let work = plastic.apply(
                    &mut s3,
                    phi,
                    mu,
                    temperature.get(k).copied(),
                    batch.dt,
                    PlasticState {
                        strain: &mut plastic_strain[k],
                        damage: damage.get_mut(k),
                        local_damage: local_damage.get_mut(k),
                    },
                );
                if let Some(w) = batch.plastic_work.get_mut(k) {
                    // Per reference volume, as the ledger and the heat source count it.
                    *w = work * determinant(f);
                }
                let (in_plane, out_of_plane) = mixture_plasticity::project::<D>(&s3);
                s = in_plane;
                zz = out_of_plane;
            }
            let slot = &mut solid[9 * k..9 * k + 9];
            store(slot, &s);
            if D == 2 {
                slot[8] = zz;
                previous[9 * k + 8] = stretch - 1.0;
            }
            let ln_j = (determinant(f) * stretch).max(1e-300).ln();
            let mean = if tau.is_some() {
                let ln_j_prev = (determinant(&f_prev) * stretch_prev).max(1e-300).ln();
                let q = decay * pressure[k] + gain * bulk * (ln_j - ln_j_prev);
                pressure[k] = q;
                q
            } else {
                bulk * ln_j
            };
            store(&mut previous[9 * k..9 * k + 9], f);
            let rate = if batch.dt > 0.0 {
                strain / batch.dt
            } else {
                Matrix::<D>::zeros()
            };
            let rate_zz = if batch.dt > 0.0 {
                strain_zz / batch.dt
            } else {
                0.0
            };
            let rate_trace = rate.trace() + rate_zz;
            let deviatoric_rate = rate - identity * (rate_trace / 3.0);
            let fluid = deviatoric_rate * (2.0 * eta) + identity * mean;
            *stress = s + fluid * (1.0 - phi);
            if let Some(out) = batch.out_of_plane_stress.get_mut(k) {
                let fluid_zz = 2.0 * eta * (rate_zz - rate_trace / 3.0) + mean;
                *out = zz + fluid_zz * (1.0 - phi);
            }
            let liquid_energy = if bulk > 0.0 {
                0.5 * mean * mean / bulk
            } else {
                0.0
            };
            let zz2 = if D == 2 { zz * zz } else { 0.0 };
            energy += batch.volume0[k]
                * ((s.norm_squared() + zz2) / (4.0 * mu) + (1.0 - phi) * liquid_energy);
            stiffest = stiffest.max(phi * (lambda + 2.0 * mu) + (1.0 - phi) * bulk);
        }
        BatchStats {
            strain_energy: energy,
            max_wave_speed: (stiffest / self.params.density).sqrt(),
        }
    }

    fn has_stress_derivative(&self) -> bool {
        true
    }

    /// The derivative of the update from the step's starting state (F₀ = `previous_F`,
    /// s₀ = `solid_stress`): with δL = δF F₀⁻¹, δε = sym δL and δω = skew δL,
    /// δσ = δω s₀ − s₀ δω + φ (λ tr δε I + 2μ δε) + (1 − φ)(2η dev δε / dt + b K tr(F⁻¹δF) I)
    /// (b = 1 without pressure relaxation). Exact, and a product costs no stress update (the
    /// differences it replaces were accurate enough: the same Newton and Krylov counts on
    /// the cure example).
    /// With `solid.plasticity` the solid part is the consistent tangent of its return
    /// (`SolidPlasticity::derivative`) at the trial stress the update reaches.
    fn stress_derivative<const D: usize>(&self, batch: TangentBatch<'_, D>) {
        let fields = batch.state.fields;
        let [previous, solid, ..] = fields;
        let plastic_strain = self.slots.plastic_strain.map(|i| fields[i]);
        let damage = self.slots.damage.map(|i| fields[i]);
        let plasticity = self.params.solid.plasticity;
        let fraction = batch.shared[0];
        let temperature = batch.shared[1];
        let (lambda, mu) = (self.lambda, self.mu);
        let (eta, bulk) = (
            self.params.liquid.viscosity,
            self.params.liquid.bulk_modulus,
        );
        let (_, gain) = relaxation(self.params.liquid.pressure_relaxation_time, batch.dt);
        let identity = Matrix::<D>::identity();
        for (k, ((f, df), out)) in batch
            .deformation_gradient
            .iter()
            .zip(batch.direction)
            .zip(batch.stress_change.iter_mut())
            .enumerate()
        {
            let phi = fraction.get(k).copied().unwrap_or(1.0).clamp(0.0, 1.0);
            let f_prev: Matrix<D> = load(&previous[9 * k..9 * k + 9]);
            let (stretch, stretch_prev) = stretches::<D>(batch.out_of_plane_stretch, previous, k);
            let s0: Matrix<D> = load(&solid[9 * k..9 * k + 9]);
            // Without an inverse the update takes the increment as I: no change.
            let f_prev_inverse = inverse(&f_prev);
            let d_increment = f_prev_inverse.map_or(Matrix::<D>::zeros(), |inv| df * inv);
            let d_strain = (d_increment + d_increment.transpose()) * 0.5;
            let d_spin = (d_increment - d_increment.transpose()) * 0.5;
            let mut d_solid = d_spin * s0 - s0 * d_spin
                + (identity * (lambda * d_strain.trace()) + d_strain * (2.0 * mu)) * phi;
            if let (Some(plastic), Some(strains)) = (&plasticity, plastic_strain) {
                // The update's trial stress at F, as `update_stress` builds it.
                let increment = f_prev_inverse.map_or(identity, |inv| f * inv);
                let strain = (increment + increment.transpose()) * 0.5 - identity;
                let spin = (increment - increment.transpose()) * 0.5;
                let strain_zz = stretch / stretch_prev - 1.0;
                let trace = strain.trace() + strain_zz;
                let trial = s0 + spin * s0 - s0 * spin
                    + (identity * (lambda * trace) + strain * (2.0 * mu)) * phi;
                let zz = solid[9 * k + 8] + phi * (lambda * trace + 2.0 * mu * strain_zz);
                let trial3 = mixture_plasticity::embed(&trial, zz);
                let d_trial3 = mixture_plasticity::embed(&d_solid, phi * lambda * d_strain.trace());
                let d3 = plastic.derivative(
                    &trial3,
                    &d_trial3,
                    phi,
                    mu,
                    temperature.get(k).copied(),
                    batch.dt,
                    strains[k],
                    damage.map(|d| d[k]),
                );
                d_solid = mixture_plasticity::project::<D>(&d3).0;
            }
            let j = determinant(f);
            // d ln J = tr(F⁻¹ δF) = cof(F) : δF / J (the update clamps J at 1e-300).
            let d_ln_j = if j > 1e-300 {
                cofactor(f).component_mul(df).sum() / j
            } else {
                0.0
            };
            let d_rate = if batch.dt > 0.0 {
                d_strain / batch.dt
            } else {
                Matrix::<D>::zeros()
            };
            let d_deviatoric = d_rate - identity * (d_rate.trace() / 3.0);
            let d_fluid = d_deviatoric * (2.0 * eta) + identity * (gain * bulk * d_ln_j);
            *out = d_solid + d_fluid * (1.0 - phi);
        }
    }
}
