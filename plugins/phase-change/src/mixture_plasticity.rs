//! Plasticity and damage of the cured solid of `phase_mixture` (`solid.plasticity`): J2
//! plasticity with a Johnson–Cook flow stress and, optionally, Johnson–Cook damage, so one
//! law carries a thermoset from liquid through cure to the ductile failure its cured solid
//! shows in thermal cycling (a crack from a void, say).
//!
//! The solid stress is hypoelastic (see `mixture.rs`), so the return is the small-strain
//! radial return on it: the trial stress's deviator is scaled back onto the yield surface
//! q = φ·σ_y(εₚ, ε̇ₚ, T), the solid's share φ of the flow stress, with the solid's shear
//! modulus φμ (the share its stress increments carry). Its mean stress is left as it is
//! (J2 flow is isochoric). Damage grows by Δεₚ/ε_f at the triaxiality mean/q; a particle at
//! damage 1 keeps only a compressive mean stress (`no_tension`) or none (`no_stress`), as the
//! `johnson_cook` law's failed particles do.
//!
//! A 2D solid needs its out-of-plane stress for the von Mises stress of plane strain: the
//! law keeps σ_zz in the last slot of its `solid_stress` state (unused by the 2×2 stress),
//! raised by φλ·tr(Δε) per step (Δε_zz = 0) and returned with the rest. Under
//! `solver.free_strain_2d: "plane_strain"` the held out-of-plane free strain reaches σ_zz
//! only through the in-plane (1 + ν) factor, so σ_zz is then approximate.

use mpm_core::math::Matrix;
use mpm_core::scene::Issue;
use mpm_johnson_cook::{Damage, FailureMode, FlowStress};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The share of its stress increments a failed particle keeps beyond what its failure mode
/// allows: without it a node among failed particles in tension has no stiffness at all and
/// an implicit static step cannot converge.
pub const RESIDUAL_STIFFNESS: f64 = 1e-3;

/// Scene section `solid.plasticity` of a `phase_mixture` material.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SolidPlasticity {
    /// Johnson–Cook flow stress of the fully cured solid (the law takes the solid
    /// fraction's share of it); its temperatures are the scene's (K).
    pub flow_stress: FlowStress,
    /// Johnson–Cook damage and failure; without it no particle fails.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damage: Option<Damage>,
    /// Seconds over which a failed particle sheds the stress its failure mode does not
    /// allow (a viscous regularisation: an implicit static step cannot follow a stress
    /// that drops at once, as a crack that opens does); absent: at once.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failure_time: Option<f64>,
}

impl SolidPlasticity {
    /// Every problem with the constants, with JSON paths below `path`.
    pub fn check(&self, path: &str) -> Vec<Issue> {
        let mut issues = self.flow_stress.check(&format!("{path}.flow_stress"));
        if let Some(d) = &self.damage {
            issues.extend(d.check(&format!("{path}.damage")));
        }
        if let Some(t) = self.failure_time {
            if !(t.is_finite() && t > 0.0) {
                issues.push(Issue::new(
                    format!("{path}.failure_time"),
                    format!("must be a finite number > 0 seconds (got {t})"),
                ));
            } else if self.damage.is_none() {
                issues.push(Issue::new(
                    format!("{path}.failure_time"),
                    "needs `damage`: without it no particle fails".to_string(),
                ));
            }
        }
        issues
    }
}

/// What one particle's return starts from and keeps.
pub(crate) struct PlasticState<'a> {
    /// Accumulated equivalent plastic strain.
    pub strain: &'a mut f64,
    /// Damage in [0, 1]; `None` without a damage model. With an averaging radius it is
    /// the averaged damage, which the law reads and the core writes.
    pub damage: Option<&'a mut f64>,
    /// The damage the particle's own plastic strain drives, unbounded, with an averaging
    /// radius (`None` without).
    pub local_damage: Option<&'a mut f64>,
}

impl SolidPlasticity {
    /// Returns the trial solid stress `s` (3×3; in 2D with σ_zz in place) onto the yield
    /// surface of solid fraction `phi` with shear modulus `mu` at `temperature` over `dt`,
    /// then applies damage and failure. Leaves an elastic stress below yield unchanged.
    /// Returns the plastic work of the step per unit current volume, q·Δεₚ with q the
    /// returned equivalent stress (the backward-Euler dissipation; 0 below yield and for a
    /// failed particle, whose shed stress is not booked as plastic work).
    pub(crate) fn apply(
        &self,
        s: &mut Matrix<3>,
        phi: f64,
        mu: f64,
        temperature: Option<f64>,
        dt: f64,
        state: PlasticState<'_>,
    ) -> f64 {
        let PlasticState {
            strain,
            damage,
            local_damage,
        } = state;
        let failed = damage.as_deref().is_some_and(|d| *d >= 1.0);
        let mean = s.trace() / 3.0;
        let deviator = *s - Matrix::<3>::identity() * mean;
        if failed {
            *s = self.failed_stress(s, dt);
            return 0.0;
        }
        // A particle with next to no solid carries next to no solid stress.
        if phi <= 1e-9 {
            return 0.0;
        }
        let flow = &self.flow_stress;
        let thermal = temperature.map_or(1.0, |t| flow.thermal_factor(t));
        let q_trial = (1.5 * deviator.norm_squared()).sqrt();
        let yield_now = phi * flow.evaluate(*strain, 0.0, thermal).0;
        if q_trial <= yield_now {
            return 0.0;
        }
        let increment = flow.radial_return(q_trial, 3.0 * phi * mu, phi, *strain, thermal, dt);
        let scale = (1.0 - 3.0 * phi * mu * increment / q_trial).max(0.0);
        let q = q_trial * scale;
        *strain += increment;
        *s = deviator * scale + Matrix::<3>::identity() * mean;
        let work = q * increment;
        let (Some(d), Some(model)) = (damage, &self.damage) else {
            return work;
        };
        let triaxiality = if q > 0.0 {
            (mean / q).clamp(-10.0, 10.0)
        } else {
            0.0
        };
        let rate_ratio = if dt > 0.0 {
            increment / dt / flow.reference_strain_rate
        } else {
            1.0
        };
        let homologous = temperature.map_or(0.0, |t| flow.homologous_temperature(t));
        let failure_strain = model.failure_strain(triaxiality, rate_ratio, homologous);
        if let Some(local) = local_damage {
            // The core averages it into `damage` after the step.
            *local += increment / failure_strain;
            return work;
        }
        *d = (*d + increment / failure_strain).min(1.0);
        if *d >= 1.0 {
            *s = self.failed_stress(s, dt);
        }
        work
    }

    /// The derivative of [`SolidPlasticity::apply`] at the trial stress `trial` along the
    /// trial's change `d_trial`, from the step's starting plastic strain `strain` and
    /// damage `damage`: the consistent tangent of the radial return (δx from
    /// δq = (3φμ + φh)δx, h the flow stress's slope), or of a failed particle's shedding.
    /// A particle that fails within the step gets the tangent of its return.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn derivative(
        &self,
        trial: &Matrix<3>,
        d_trial: &Matrix<3>,
        phi: f64,
        mu: f64,
        temperature: Option<f64>,
        dt: f64,
        strain: f64,
        damage: Option<f64>,
    ) -> Matrix<3> {
        let identity = Matrix::<3>::identity();
        let mean = trial.trace() / 3.0;
        let d_mean = d_trial.trace() / 3.0;
        if damage.is_some_and(|d| d >= 1.0) {
            let mode = self.damage.map(|d| d.failure).unwrap_or_default();
            let d_kept = match mode {
                FailureMode::NoTension if mean < 0.0 => identity * d_mean,
                _ => Matrix::<3>::zeros(),
            };
            let decay = self.failure_time.map_or(0.0, |t| (-dt / t).exp());
            return d_kept + (d_trial - d_kept) * decay.max(RESIDUAL_STIFFNESS);
        }
        if phi <= 1e-9 {
            return *d_trial;
        }
        let flow = &self.flow_stress;
        let thermal = temperature.map_or(1.0, |t| flow.thermal_factor(t));
        let deviator = trial - identity * mean;
        let q = (1.5 * deviator.norm_squared()).sqrt();
        if q <= phi * flow.evaluate(strain, 0.0, thermal).0 {
            return *d_trial;
        }
        let stiffness = 3.0 * phi * mu;
        let x = flow.radial_return(q, stiffness, phi, strain, thermal, dt);
        let theta = 1.0 - stiffness * x / q;
        if theta <= 0.0 {
            return identity * d_mean;
        }
        let rate = if dt > 0.0 { x / dt } else { 0.0 };
        let (_, slope_strain, slope_rate) = flow.evaluate(strain + x, rate, thermal);
        let slope = slope_strain + if dt > 0.0 { slope_rate / dt } else { 0.0 };
        let d_deviator = d_trial - identity * d_mean;
        let d_q = 1.5 * deviator.dot(&d_deviator) / q;
        let d_x = d_q / (stiffness + phi * slope);
        let d_theta = -stiffness * (d_x / q - x * d_q / (q * q));
        identity * d_mean + deviator * d_theta + d_deviator * theta
    }

    /// The stress a failed particle keeps of its trial stress `s` over a step `dt`: the
    /// compressive mean stress (`no_tension`) or nothing (`no_stress`), plus of the rest
    /// e^(−dt/failure_time) (without `failure_time`, nothing), and never less than
    /// [`RESIDUAL_STIFFNESS`] of it.
    fn failed_stress(&self, s: &Matrix<3>, dt: f64) -> Matrix<3> {
        let mode = self.damage.map(|d| d.failure).unwrap_or_default();
        let kept = match mode {
            FailureMode::NoTension => Matrix::<3>::identity() * (s.trace() / 3.0).min(0.0),
            FailureMode::NoStress => Matrix::<3>::zeros(),
        };
        let decay = self.failure_time.map_or(0.0, |t| (-dt / t).exp());
        kept + (s - kept) * decay.max(RESIDUAL_STIFFNESS)
    }
}

/// The 3×3 solid stress of a D×D one and its out-of-plane slot (2D: σ_zz; 3D: unused).
pub(crate) fn embed<const D: usize>(s: &Matrix<D>, zz: f64) -> Matrix<3> {
    mpm_core::math::embed3(s, zz)
}

/// The D×D part of a 3×3 stress, and its σ_zz (for a 2D law's state).
pub(crate) fn project<const D: usize>(s: &Matrix<3>) -> (Matrix<D>, f64) {
    (mpm_core::math::top_left(s), s[(2, 2)])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Damage failing at plastic strain `strain` whatever the triaxiality, keeping only
    /// compressive mean stress.
    fn constant_failure_strain(strain: f64) -> Damage {
        Damage {
            d1: strain,
            d2: 0.0,
            d3: 0.0,
            d4: 0.0,
            d5: 0.0,
            failure: FailureMode::NoTension,
            averaging_radius: None,
        }
    }

    fn law(damage: Option<Damage>) -> SolidPlasticity {
        SolidPlasticity {
            flow_stress: FlowStress {
                yield_stress: 50e6,
                hardening_modulus: 0.0,
                hardening_exponent: 1.0,
                strain_rate_sensitivity: 0.0,
                thermal_softening_exponent: 1.0,
                reference_strain_rate: 1.0,
                room_temperature: 298.0,
                melt_temperature: 423.0,
            },
            damage,
            failure_time: None,
        }
    }

    fn elastic_state(strain: &mut f64) -> PlasticState<'_> {
        PlasticState {
            strain,
            damage: None,
            local_damage: None,
        }
    }

    fn von_mises(s: &Matrix<3>) -> f64 {
        let dev = s - Matrix::<3>::identity() * (s.trace() / 3.0);
        (1.5 * dev.norm_squared()).sqrt()
    }

    /// Perfect plasticity: a trial stress above yield comes back to the yield surface with
    /// its mean stress, and the plastic strain is the overshoot over 3φμ.
    #[test]
    fn the_return_lands_on_the_yield_surface_with_the_mean_stress_kept() {
        let (mu, phi) = (3e9, 0.8);
        let mut s = Matrix::<3>::new(120e6, 30e6, 0.0, 30e6, -40e6, 0.0, 0.0, 0.0, 10e6);
        let mean = s.trace() / 3.0;
        let q_trial = von_mises(&s);
        let mut strain = 0.0;
        law(None).apply(
            &mut s,
            phi,
            mu,
            None,
            1.0,
            PlasticState {
                strain: &mut strain,
                damage: None,
                local_damage: None,
            },
        );
        assert!((von_mises(&s) - phi * 50e6).abs() < 1e-6 * 50e6);
        assert!((s.trace() / 3.0 - mean).abs() < 1e-6);
        let expected = (q_trial - phi * 50e6) / (3.0 * phi * mu);
        assert!((strain - expected).abs() < 1e-9 * expected);
    }

    /// Below yield nothing changes; softening near the "melt" temperature brings the
    /// same stress to yield.
    #[test]
    fn an_elastic_stress_stays_and_heat_softens_the_solid() {
        let s0 = Matrix::<3>::new(40e6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let mut strain = 0.0;
        let mut s = s0;
        law(None).apply(
            &mut s,
            1.0,
            3e9,
            Some(298.0),
            1.0,
            elastic_state(&mut strain),
        );
        assert_eq!(s, s0);
        assert_eq!(strain, 0.0);
        // T* = 0.5 halves the flow stress to 25 MPa.
        law(None).apply(
            &mut s,
            1.0,
            3e9,
            Some(360.5),
            1.0,
            elastic_state(&mut strain),
        );
        assert!((von_mises(&s) - 25e6).abs() < 1e-6 * 25e6);
        assert!(strain > 0.0);
    }

    /// Damage adds Δεₚ/ε_f; at 1 the particle keeps only a compressive mean stress.
    #[test]
    fn damage_accumulates_and_a_failed_particle_holds_no_tension() {
        let damage = constant_failure_strain(0.01);
        let law = law(Some(damage));
        let mu = 3e9;
        // Uniaxial tension trial 53 MPa: overshoot 3 MPa, Δεₚ = 3e6/9e9.
        let mut s = Matrix::<3>::new(53e6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut strain, mut d) = (0.0, 0.0);
        law.apply(
            &mut s,
            1.0,
            mu,
            None,
            1.0,
            PlasticState {
                strain: &mut strain,
                damage: Some(&mut d),
                local_damage: None,
            },
        );
        assert!((d - strain / 0.01).abs() < 1e-12);
        assert!(d > 0.0 && d < 1.0);
        // A large overshoot fails it: tension and shear gone but for the residual share.
        let mut s = Matrix::<3>::new(900e6, 5e6, 0.0, 5e6, 0.0, 0.0, 0.0, 0.0, 0.0);
        law.apply(
            &mut s,
            1.0,
            mu,
            None,
            1.0,
            PlasticState {
                strain: &mut strain,
                damage: Some(&mut d),
                local_damage: None,
            },
        );
        assert_eq!(d, 1.0);
        assert!(von_mises(&s) <= RESIDUAL_STIFFNESS * 50e6 * (1.0 + 1e-9));
        assert!((s.trace() / 3.0 - RESIDUAL_STIFFNESS * 300e6).abs() < 1e-3);
        // In compression a failed particle keeps its mean stress (and the residual share).
        let trial = Matrix::<3>::new(-90e6, 5e6, 0.0, 5e6, -30e6, 0.0, 0.0, 0.0, 0.0);
        let mut s = trial;
        law.apply(
            &mut s,
            1.0,
            mu,
            None,
            1.0,
            PlasticState {
                strain: &mut strain,
                damage: Some(&mut d),
                local_damage: None,
            },
        );
        let kept = Matrix::<3>::identity() * (-40e6);
        assert!((s - (kept + (trial - kept) * RESIDUAL_STIFFNESS)).norm() < 1e-6);
    }

    /// With `failure_time` τ a failed particle sheds what its failure mode does not allow
    /// by e^(−dt/τ) per step, instead of at once.
    #[test]
    fn a_failed_particle_sheds_its_tension_over_the_failure_time() {
        let mut law = law(Some(constant_failure_strain(0.01)));
        law.failure_time = Some(2.0);
        let trial = Matrix::<3>::new(30e6, 5e6, 0.0, 5e6, -6e6, 0.0, 0.0, 0.0, 0.0);
        let mut s = trial;
        let (mut strain, mut d) = (0.5, 1.0);
        law.apply(
            &mut s,
            1.0,
            3e9,
            None,
            1.0,
            PlasticState {
                strain: &mut strain,
                damage: Some(&mut d),
                local_damage: None,
            },
        );
        // Mean 8 MPa is tension: nothing is kept, the whole trial decays by e^(−1/2).
        assert!((s - trial * (-0.5f64).exp()).norm() < 1e-6);
        let issues = SolidPlasticity {
            failure_time: Some(-1.0),
            ..law
        }
        .check("p");
        assert_eq!(issues[0].path, "p.failure_time");
    }

    /// With an averaging radius the return drives the local damage past 1 and leaves the
    /// (averaged) damage and the stress's failure to the core's average.
    #[test]
    fn averaged_damage_leaves_failure_to_the_average() {
        let model = constant_failure_strain(0.001);
        let law = law(Some(Damage {
            averaging_radius: Some(2e-5),
            ..model
        }));
        let trial = Matrix::<3>::from_diagonal(&mpm_core::math::Vector::<3>::new(80e6, 0.0, 0.0));
        let (mut strain, mut d, mut local) = (0.0, 0.5, 0.0);
        let mut s = trial;
        law.apply(
            &mut s,
            1.0,
            1e9,
            None,
            1.0,
            PlasticState {
                strain: &mut strain,
                damage: Some(&mut d),
                local_damage: Some(&mut local),
            },
        );
        assert!(strain > 0.0);
        assert!(
            (local - strain / 0.001).abs() < 1e-9 * local,
            "{local} {strain}"
        );
        assert!(local > 1.0, "the local damage is not capped: {local}");
        assert_eq!(d, 0.5, "the law does not write the averaged damage");
        assert!((von_mises(&s) - 50e6).abs() < 1.0, "returned, not failed");
        let bad = SolidPlasticity {
            damage: Some(Damage {
                averaging_radius: Some(0.0),
                ..model
            }),
            ..law
        };
        assert_eq!(bad.check("p")[0].path, "p.damage.averaging_radius");
    }

    /// The consistent tangent equals central differences of the return: below yield, on
    /// the yield surface with hardening and heat, and for a failed particle shedding.
    #[test]
    fn the_tangent_matches_differences_of_the_return() {
        let mut law = law(Some(constant_failure_strain(0.5)));
        law.flow_stress.hardening_modulus = 4e7;
        law.flow_stress.hardening_exponent = 0.4;
        law.failure_time = Some(3.0);
        let (mu, phi, dt, t) = (3e9, 0.9, 1.0, Some(330.0));
        let direction = Matrix::<3>::new(2e6, 1e6, -5e5, 1e6, -3e6, 7e5, -5e5, 7e5, 1.5e6);
        let cases = [
            (
                Matrix::<3>::new(20e6, 3e6, 0.0, 3e6, -5e6, 0.0, 0.0, 0.0, 4e6),
                0.0,
                0.0,
            ),
            (
                Matrix::<3>::new(95e6, 20e6, 5e6, 20e6, -30e6, 0.0, 5e6, 0.0, 10e6),
                0.01,
                0.2,
            ),
            (
                Matrix::<3>::new(40e6, 5e6, 0.0, 5e6, -80e6, 0.0, 0.0, 0.0, 10e6),
                0.02,
                1.0,
            ),
        ];
        for (trial, strain0, damage0) in cases {
            let at = |s0: Matrix<3>| {
                let (mut s, mut strain, mut d) = (s0, strain0, damage0);
                law.apply(
                    &mut s,
                    phi,
                    mu,
                    t,
                    dt,
                    PlasticState {
                        strain: &mut strain,
                        damage: Some(&mut d),
                        local_damage: None,
                    },
                );
                s
            };
            let h = 1e-3;
            let numeric = (at(trial + direction * h) - at(trial - direction * h)) / (2.0 * h);
            let analytic =
                law.derivative(&trial, &direction, phi, mu, t, dt, strain0, Some(damage0));
            let error = (analytic - numeric).norm() / numeric.norm();
            assert!(error < 1e-6, "{trial:?}: {error:e}");
        }
    }
}
