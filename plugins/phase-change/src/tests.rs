//! Unit tests of the phase-change pieces against closed forms.

use crate::cure::{CureKinetics, CureParameters, GlassTransition};
use crate::kamal_sourour_isothermal;
use crate::melting::{Melting, PhaseProperties};

fn wax() -> Melting {
    let phase = PhaseProperties {
        conductivity: 1.0,
        specific_heat: 2000.0,
        density: 900.0,
    };
    Melting {
        melt_temperature: 300.0,
        latent_heat: 2e5,
        solid: phase,
        liquid: phase,
        initial_solid_fraction: 1.0,
    }
}

/// The enthalpy update conserves c·T + (1 − f)·L and melts at constant temperature.
#[test]
fn latent_heat_is_conserved_while_melting_and_freezing() {
    let m = wax();
    let c = 2000.0;
    let h = |t: f64, f: f64| c * t + (1.0 - f) * m.latent_heat;
    // 10 K of superheat melts 10·2000/2e5 = 0.1 of the particle.
    let (t, f) = m.recover(310.0, 1.0, c);
    assert_eq!(t, 300.0);
    assert!((f - 0.9).abs() < 1e-12);
    assert!((h(t, f) - h(310.0, 1.0)).abs() < 1e-6);
    // Far past melting: all melts, the rest heats the liquid.
    let (t, f) = m.recover(500.0, 1.0, c);
    assert_eq!(f, 0.0);
    assert!((h(t, f) - h(500.0, 1.0)).abs() < 1e-6);
    // Freezing gives the heat back.
    let (t, f) = m.recover(295.0, 0.5, c);
    assert_eq!(t, 300.0);
    assert!((f - 0.55).abs() < 1e-12);
}

fn resin() -> CureParameters {
    CureParameters {
        kinetics: CureKinetics {
            a1: 2e5,
            e1: 6e4,
            a2: 5e6,
            e2: 6e4,
            m: 1.0,
            n: 1.0,
        },
        heat_of_reaction: 4e5,
        initial_cure: 0.0,
        gel_point: 0.6,
        glass_transition: Some(GlassTransition {
            tg0: 250.0,
            tg_inf: 420.0,
            lambda: 0.4,
        }),
        shrinkage: 0.03,
    }
}

/// Isothermal cure (no heat of reaction) follows the m = n = 1 closed form.
#[test]
fn isothermal_cure_matches_the_closed_form() {
    let mut c = resin();
    c.heat_of_reaction = 0.0;
    let t = 420.0;
    let (k1, k2) = c.kinetics.rate_constants(t);
    let (mut a, mut temp) = (0.0, t);
    let dt = 5.0;
    for step in 1..=200 {
        (a, temp) = c.advance(a, temp, 1500.0, dt);
        let exact = kamal_sourour_isothermal(k1, k2, step as f64 * dt);
        assert!((a - exact).abs() < 1e-6, "step {step}: {a} vs {exact}");
    }
    assert_eq!(temp, t);
    assert!(a > 0.9, "{a}");
}

/// Adiabatic cure: T rises by H/c per unit of cure.
#[test]
fn adiabatic_cure_heats_by_the_heat_of_reaction() {
    let c = resin();
    let cp = 1500.0;
    let (mut a, mut t) = (0.0, 380.0);
    for _ in 0..400 {
        (a, t) = c.advance(a, t, cp, 2.0);
    }
    assert!(a > 0.95, "{a}");
    assert!((t - 380.0 - c.heat_of_reaction / cp * a).abs() < 1e-9);
}

/// DiBenedetto: Tg0 at no cure, Tg∞ at full cure, λ sets the curvature.
#[test]
fn glass_transition_spans_its_limits() {
    let g = resin().glass_transition.unwrap();
    assert_eq!(g.at(0.0), 250.0);
    assert!((g.at(1.0) - 420.0).abs() < 1e-9);
    assert!(g.at(0.5) < 250.0 + 0.5 * 170.0);
}

/// The underfill-like mixture of the law's tests (a 8 GPa solid, a 10 Pa·s liquid of bulk
/// modulus 2 GPa) with the liquid pressure relaxation time `tau`.
fn test_mixture(tau: Option<f64>) -> crate::mixture::PhaseMixture {
    use crate::mixture::{LiquidPhase, PhaseMixture, PhaseMixtureParameters, SolidPhase};
    PhaseMixture::new(PhaseMixtureParameters {
        density: 1600.0,
        solid: SolidPhase {
            youngs_modulus: 8e9,
            poisson_ratio: 0.3,
            plasticity: None,
        },
        liquid: LiquidPhase {
            viscosity: 10.0,
            bulk_modulus: 2e9,
            pressure_relaxation_time: tau,
        },
    })
}

/// The mixture's analytic stress derivative after a step from a prestressed state, against
/// central differences of its own update from that state; relative error.
fn mixture_tangent_error<const D: usize>(
    tau: Option<f64>,
    phi: f64,
    f_prev: mpm_core::math::Matrix<D>,
    f: mpm_core::math::Matrix<D>,
    df: mpm_core::math::Matrix<D>,
) -> f64 {
    use mpm_core::material::{
        ConstitutiveLaw, MAX_STATE_FIELDS, StateSlices, StateView, StressBatch, TangentBatch,
    };
    use mpm_core::math::Matrix;
    let law = test_mixture(tau);
    let dt = 30.0;
    let fraction = [phi];
    let pressure = vec![3e5];
    // The state a step starts from: F₀ and a solid stress already carried.
    let mut previous = vec![0.0; 9];
    let mut solid = vec![0.0; 9];
    for r in 0..D {
        for c in 0..D {
            previous[r * D + c] = f_prev[(r, c)];
            solid[r * D + c] = 1e7 * (1.0 + r as f64) * if r == c { 1.0 } else { 0.3 };
        }
    }
    let stress_at = |g: Matrix<D>| {
        let (mut p, mut s, mut q) = (previous.clone(), solid.clone(), pressure.clone());
        let mut stress = [Matrix::<D>::zeros()];
        let mut fields: [&mut [f64]; MAX_STATE_FIELDS] = Default::default();
        fields[0] = &mut p;
        fields[1] = &mut s;
        if tau.is_some() {
            fields[2] = &mut q;
        }
        law.update_stress(StressBatch {
            out_of_plane_stretch: &[],
            out_of_plane_stress: &mut [],
            dt,
            deformation_gradient: &[g],
            velocity_gradient: &[],
            volume0: &[1.0],
            stress: &mut stress,
            state: StateSlices { fields },
            shared: [&fraction[..], &[], &[], &[]],
            plastic_work: &mut [],
        });
        stress[0]
    };
    let stress = stress_at(f);
    let h = 1e-6;
    let numeric = (stress_at(f + df * h) - stress_at(f - df * h)) / (2.0 * h);
    let mut fields: [&[f64]; MAX_STATE_FIELDS] = [&[]; MAX_STATE_FIELDS];
    fields[0] = &previous;
    fields[1] = &solid;
    if tau.is_some() {
        fields[2] = &pressure;
    }
    let mut analytic = [Matrix::<D>::zeros()];
    law.stress_derivative(TangentBatch {
        out_of_plane_stretch: &[],
        dt,
        deformation_gradient: &[f],
        direction: &[df],
        stress: &[stress],
        state: StateView { fields },
        shared: [&fraction[..], &[], &[], &[]],
        stress_change: &mut analytic,
    });
    (analytic[0] - numeric).norm() / numeric.norm()
}

/// The `phase_mixture` law's analytic tangent (what the implicit mode's Krylov products
/// use) equals differences of its update: liquid, half gelled and solid, 2D and 3D.
#[test]
fn mixture_tangent_matches_differences_of_the_update() {
    use mpm_core::math::Matrix;
    let f_prev3 = Matrix::<3>::new(1.01, 0.02, 0.0, -0.01, 0.99, 0.01, 0.0, 0.005, 1.0);
    let f3 = Matrix::<3>::new(1.02, 0.05, 0.01, -0.02, 0.97, 0.02, 0.01, 0.0, 1.01);
    let d3 = Matrix::<3>::new(0.3, -0.2, 0.1, 0.05, 0.4, -0.1, 0.2, 0.1, -0.3);
    let f_prev2 = Matrix::<2>::new(1.01, 0.02, -0.01, 0.99);
    let f2 = Matrix::<2>::new(1.02, 0.05, -0.02, 0.97);
    let d2 = Matrix::<2>::new(-0.2, 0.3, 0.1, 0.4);
    for tau in [None, Some(1e-3), Some(30.0)] {
        for phi in [0.0, 0.5, 1.0] {
            let e3 = mixture_tangent_error(tau, phi, f_prev3, f3, d3);
            let e2 = mixture_tangent_error(tau, phi, f_prev2, f2, d2);
            // Central differences of a smooth update at h = 1e-6: about 1e-9 relative.
            assert!(
                e3 < 1e-6,
                "3D, τ {tau:?}, solid fraction {phi}: relative error {e3}"
            );
            assert!(
                e2 < 1e-6,
                "2D, τ {tau:?}, solid fraction {phi}: relative error {e2}"
            );
        }
    }
}

/// The liquid's relaxing pressure (`liquid.pressure_relaxation_time` τ) against the
/// Maxwell solution: a step of dt = τ that expands a liquid particle by ln J gives
/// q = K ln J (1 − e^{−1}); held at that volume for another τ, q falls by e^{−1}. Without
/// relaxation q = K ln J, and with τ ≫ dt the same to first order in dt/τ.
#[test]
fn relaxing_liquid_pressure_follows_the_maxwell_solution() {
    use mpm_core::math::Matrix;
    // The bulk modulus of `test_mixture`.
    let bulk = 2e9;
    let f = Matrix::<2>::new(1.001, 0.0, 0.0, 1.0);
    let ln_j = 1.001f64.ln();
    // Two steps of `dt` (expand, then hold); the liquid mean stress after each.
    let run = |tau: Option<f64>, dt: f64| -> [f64; 2] {
        let law = test_mixture(tau);
        let mut previous = vec![0.0; 9];
        previous[0] = 1.0;
        previous[3] = 1.0;
        let mut state = [previous, vec![0.0; 9], vec![0.0]];
        let mut out = [0.0; 2];
        for o in &mut out {
            let stress = mixture_step(&law, tau, &mut state, f, &[], &mut [], &[0.0], dt);
            // The viscous part adds 2η tr D/3 (the in-plane share of a plane-strain
            // deviator), about 2e-4 Pa here against the pressure's 2e6: below the bounds.
            *o = stress.trace() / 2.0;
        }
        out
    };
    let [q1, q2] = run(Some(30.0), 30.0);
    let e = (-1.0f64).exp();
    let expected = bulk * ln_j * (1.0 - e);
    assert!(
        (q1 / expected - 1.0).abs() < 1e-9,
        "{q1} against {expected}"
    );
    assert!(
        (q2 / (expected * e) - 1.0).abs() < 1e-9,
        "{q2} against {}",
        expected * e
    );
    let [p1, p2] = run(None, 30.0);
    assert!((p1 / (bulk * ln_j) - 1.0).abs() < 1e-9 && (p2 - p1).abs() < 1e-9 * p1);
    let [s1, _] = run(Some(3e6), 30.0);
    assert!((s1 / (bulk * ln_j) - 1.0).abs() < 1e-5, "{s1}");
}

/// A fully cured `phase_mixture` with `solid.plasticity` sheared past yield and back: the
/// work done on it equals the energy it stores plus the plastic work it reports, so the
/// energy ledger closes. Without the plastic work the balance would miss by more than a
/// third of the work.
#[test]
fn mixture_plastic_work_closes_the_energy_balance_in_shear() {
    use crate::mixture::{LiquidPhase, PhaseMixture, PhaseMixtureParameters, SolidPhase};
    use crate::mixture_plasticity::SolidPlasticity;
    use mpm_core::material::{
        ConstitutiveLaw, FieldInit, MAX_STATE_FIELDS, StateSlices, StressBatch,
    };
    use mpm_core::math::{Matrix, determinant, inverse};
    use mpm_johnson_cook::FlowStress;
    let law = PhaseMixture::new(PhaseMixtureParameters {
        density: 1600.0,
        solid: SolidPhase {
            youngs_modulus: 8e9,
            poisson_ratio: 0.3,
            plasticity: Some(SolidPlasticity {
                flow_stress: FlowStress {
                    yield_stress: 50e6,
                    hardening_modulus: 200e6,
                    hardening_exponent: 1.0,
                    strain_rate_sensitivity: 0.0,
                    thermal_softening_exponent: 1.0,
                    reference_strain_rate: 1.0,
                    room_temperature: 293.15,
                    melt_temperature: 600.0,
                },
                damage: None,
                failure_time: None,
            }),
        },
        liquid: LiquidPhase {
            viscosity: 10.0,
            bulk_modulus: 2e9,
            pressure_relaxation_time: None,
        },
    });
    assert!(law.reports_plastic_work());
    let mut state: Vec<Vec<f64>> = law
        .state_fields()
        .iter()
        .map(|spec| match spec.initial {
            FieldInit::Identity => vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            _ => vec![0.0; spec.components],
        })
        .collect();
    let fraction = [1.0];
    let volume0 = 2e-9;
    // Simple shear to γ = 0.03 (yield near 0.009) and back, in 600 steps of 1 s.
    let steps = 600;
    let gamma = |k: usize| 0.03 * (1.0 - (2.0 * k as f64 / steps as f64 - 1.0).abs());
    let shear = |g: f64| {
        let mut f = Matrix::<3>::identity();
        f[(0, 1)] = g;
        f
    };
    let (mut work_done, mut plastic) = (0.0, 0.0);
    let mut stress_before = Matrix::<3>::zeros();
    let mut f_before = Matrix::<3>::identity();
    let mut stored = 0.0;
    for k in 1..=steps {
        let f = shear(gamma(k));
        let mut stress = [Matrix::<3>::zeros()];
        let mut work = [0.0];
        let mut fields: [&mut [f64]; MAX_STATE_FIELDS] = Default::default();
        for (slot, field) in fields.iter_mut().zip(state.iter_mut()) {
            *slot = field;
        }
        let stats = law.update_stress(StressBatch {
            out_of_plane_stretch: &[],
            out_of_plane_stress: &mut [],
            dt: 1.0,
            deformation_gradient: &[f],
            velocity_gradient: &[],
            volume0: &[volume0],
            stress: &mut stress,
            state: StateSlices { fields },
            shared: [&fraction[..], &[], &[], &[]],
            plastic_work: &mut work,
        });
        // Work of the step: the mean Cauchy stress on the rate of deformation, times the
        // current volume (trapezoid).
        let l = (f - f_before) * inverse(&f).unwrap();
        let d = (l + l.transpose()) * 0.5;
        work_done += 0.5 * (stress[0] + stress_before).dot(&d) * determinant(&f) * volume0;
        plastic += work[0] * volume0;
        stored = stats.strain_energy;
        (stress_before, f_before) = (stress[0], f);
    }
    let missing = work_done - stored - plastic;
    assert!(
        plastic > 0.35 * work_done,
        "plastic {plastic:e} of {work_done:e}"
    );
    assert!(
        missing.abs() < 0.01 * work_done,
        "work {work_done:e} = stored {stored:e} + plastic {plastic:e} + {missing:e}"
    );
}

/// A 2D mixture particle is the 3D law at F = [[F, 0], [0, s]]: along a path of steps that
/// stretches the plane and shrinks the third direction (a cure shrinkage acting across the
/// plane), half gelled, with and without the liquid's pressure relaxation, the 2D stress
/// and σzz follow the 3D stress.
#[test]
fn a_2d_mixture_is_the_3d_law_with_its_stretch_across_the_plane() {
    use mpm_core::math::{Matrix, embed3};
    for tau in [None, Some(5.0)] {
        let law = test_mixture(tau);
        let fraction = [0.5];
        let dt = 2.0;
        // 2D state: F₀ row-major by 2 with s − 1 in slot 8; 3D: the 3×3 identity.
        let mut state2 = [
            vec![1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            vec![0.0; 9],
            vec![0.0],
        ];
        let mut state3 = [
            vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            vec![0.0; 9],
            vec![0.0],
        ];
        for n in 1..=10 {
            let t = n as f64 / 10.0;
            let f = Matrix::<2>::new(1.0 + 0.003 * t, 0.002 * t, -0.001 * t, 1.0 - 0.002 * t);
            let s = 1.0 - 0.004 * t;
            let mut zz = [f64::NAN];
            let stress2 = mixture_step(&law, tau, &mut state2, f, &[s], &mut zz, &fraction, dt);
            let full = mixture_step(
                &law,
                tau,
                &mut state3,
                embed3(&f, s),
                &[],
                &mut [],
                &fraction,
                dt,
            );
            let scale = full.norm();
            for r in 0..2 {
                for c in 0..2 {
                    assert!(
                        (stress2[(r, c)] - full[(r, c)]).abs() < 1e-9 * scale,
                        "τ {tau:?}, step {n}: σ{r}{c} {} against {}",
                        stress2[(r, c)],
                        full[(r, c)]
                    );
                }
            }
            assert!(
                (zz[0] - full[(2, 2)]).abs() < 1e-9 * scale,
                "τ {tau:?}, step {n}: σzz {} against {}",
                zz[0],
                full[(2, 2)]
            );
        }
    }
}

/// One step of a single mixture particle with state `[previous_F, solid_stress, pressure]`
/// (the pressure only with `tau`), stretch across the plane and σzz as in `StressBatch`.
#[allow(clippy::too_many_arguments)]
fn mixture_step<const D: usize>(
    law: &crate::mixture::PhaseMixture,
    tau: Option<f64>,
    state: &mut [Vec<f64>; 3],
    f: mpm_core::math::Matrix<D>,
    stretch: &[f64],
    zz: &mut [f64],
    fraction: &[f64],
    dt: f64,
) -> mpm_core::math::Matrix<D> {
    use mpm_core::material::{ConstitutiveLaw, MAX_STATE_FIELDS, StateSlices, StressBatch};
    let [p, q, r] = state;
    let mut fields: [&mut [f64]; MAX_STATE_FIELDS] = Default::default();
    fields[0] = p;
    fields[1] = q;
    if tau.is_some() {
        fields[2] = r;
    }
    let mut stress = [mpm_core::math::Matrix::<D>::zeros()];
    law.update_stress(StressBatch {
        out_of_plane_stretch: stretch,
        out_of_plane_stress: zz,
        dt,
        deformation_gradient: &[f],
        velocity_gradient: &[],
        volume0: &[1.0],
        stress: &mut stress,
        state: StateSlices { fields },
        shared: [fraction, &[], &[], &[]],
        plastic_work: &mut [],
    });
    stress[0]
}
