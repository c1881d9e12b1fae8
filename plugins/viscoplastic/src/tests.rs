//! Tests of the Anand update alone (one particle driven through F), against the closed
//! form of `anand_reference.rs` and the energy balance of a relaxation.

use super::*;
use mpm_core::material::{ConstitutiveLaw, FieldInit, MAX_STATE_FIELDS, StateSlices, StressBatch};
use mpm_core::math::Matrix;
use nalgebra::{Matrix3, Vector3};

/// SAC305 (Sn-3.0Ag-0.5Cu), the Anand constants of Motalab, Cai, Suhling & Lall (2012),
/// "Determination of Anand constants for SAC solders using stress-strain or creep data",
/// ITherm 2012, as the examples use them.
fn sac305() -> AnandParameters {
    serde_json::from_value(serde_json::json!({
        "density": 7380.0,
        "youngs_modulus": 51e9,
        "poisson_ratio": 0.36,
        "pre_exponential": 3501.0,
        "activation_temperature": 9320.0,
        "stress_multiplier": 4.0,
        "rate_sensitivity": 0.25,
        "hardening": 180000e6,
        "hardening_exponent": 1.78,
        "saturation_coefficient": 30.2e6,
        "saturation_exponent": 0.01,
        "initial_resistance": 21.0e6
    }))
    .unwrap()
}

/// One particle driven through a sequence of deformation gradients, at the temperature
/// a thermal physics would share.
struct Point {
    law: Anand,
    state: Vec<Vec<f64>>,
    stress: Matrix<3>,
    temperature: f64,
    work: f64,
    energy: f64,
}

impl Point {
    fn new(params: AnandParameters, temperature: f64) -> Self {
        let law = Anand::new(params);
        let state = ConstitutiveLaw::state_fields(&law)
            .iter()
            .map(|s| match s.initial {
                FieldInit::Constant(v) => vec![v; s.components],
                FieldInit::Values(v) => v.to_vec(),
                _ => vec![0.0; s.components],
            })
            .collect();
        Self {
            law,
            state,
            stress: Matrix::<3>::zeros(),
            temperature,
            work: 0.0,
            energy: 0.0,
        }
    }

    fn step(&mut self, f: Matrix3<f64>, dt: f64) {
        let mut iter = self.state.iter_mut();
        let fields: [&mut [f64]; MAX_STATE_FIELDS] =
            std::array::from_fn(|_| iter.next().map_or(&mut [][..], |v| &mut v[..]));
        let mut work = [0.0];
        let temperature = [self.temperature];
        let batch = StressBatch {
            out_of_plane_stretch: &[],
            out_of_plane_stress: &mut [],
            dt,
            deformation_gradient: std::slice::from_ref(&f),
            velocity_gradient: &[],
            volume0: &[1.0],
            stress: std::slice::from_mut(&mut self.stress),
            state: StateSlices { fields },
            shared: [&temperature, &[], &[], &[]],
            plastic_work: &mut work,
        };
        self.energy = self.law.update_stress::<3>(batch).strain_energy;
        self.work += work[0];
    }

    fn field(&self, name: &str) -> f64 {
        let k = ConstitutiveLaw::state_fields(&self.law)
            .iter()
            .position(|s| s.name == name)
            .unwrap();
        self.state[k][0]
    }

    fn von_mises(&self) -> f64 {
        let s = self.stress;
        let dev = s - Matrix3::identity() * (s.trace() / 3.0);
        (1.5 * dev.norm_squared()).sqrt()
    }
}

/// The volume-preserving stretch of logarithmic strain `strain` along x: its equivalent
/// (von Mises) strain is `strain`.
fn isochoric_stretch(strain: f64) -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(
        strain.exp(),
        (-0.5 * strain).exp(),
        (-0.5 * strain).exp(),
    ))
}

/// Drives `point` at the constant equivalent strain rate `rate` to `strain` in `steps`
/// steps, calling `check` after each.
fn stretch(point: &mut Point, rate: f64, strain: f64, steps: usize, mut check: impl FnMut(&Point)) {
    let dt = strain / rate / steps as f64;
    for step in 1..=steps {
        point.step(isochoric_stretch(rate * dt * step as f64), dt);
        check(point);
    }
}

#[test]
fn a_nearly_rigid_solder_follows_the_closed_form_curve_at_constant_rate() {
    // The closed form is rigid-viscoplastic (all strain plastic from the start), so the
    // update is checked in that limit: Young's modulus 100x SAC305's, where the elastic
    // strain at saturation is 0.0007% and the plastic rate is the applied one within 1%
    // once εp > 0.001. Three temperatures of a thermal cycle, two rates.
    let mut params = sac305();
    params.youngs_modulus *= 100.0;
    let mut worst: f64 = 0.0;
    for temperature in [233.15, 298.15, 398.15] {
        for rate in [1e-4, 1e-2] {
            let mut point = Point::new(params, temperature);
            let mut checkpoints = vec![0.05, 0.01, 0.004, 0.002, 0.001];
            stretch(&mut point, rate, 0.06, 60_000, |p| {
                let ep = p.field("plastic_strain");
                if checkpoints.last().is_some_and(|&c| ep >= c) {
                    checkpoints.pop();
                    let expected = anand_reference::stress(&params, rate, temperature, ep);
                    let error = (p.von_mises() - expected).abs() / expected;
                    worst = worst.max(error);
                    assert!(
                        error < 0.01,
                        "T = {temperature} K, rate {rate}/s, εp = {ep:.4}: σ = {:.4e}, closed form {expected:.4e} ({:.2}%)",
                        p.von_mises(),
                        100.0 * error
                    );
                }
            });
            assert!(checkpoints.is_empty(), "the stretch reached every check");
        }
    }
    eprintln!(
        "largest deviation from the closed form: {:.3}%",
        100.0 * worst
    );
}

#[test]
fn sac305_saturates_at_the_closed_form_stress_with_small_and_large_steps() {
    // SAC305 as it is: at saturation the stress no longer changes, so the plastic rate is
    // the applied one exactly and σ* = c·s* holds whatever the elasticity. 2,000 steps and
    // 20 steps (a strain increment of 0.5% each, 60x the elastic strain) must both land on it.
    let params = sac305();
    for (temperature, rate) in [(233.15, 1e-3), (298.15, 1e-5), (398.15, 1e-3)] {
        let expected = anand_reference::saturation_stress(&params, rate, temperature);
        for steps in [2000, 20] {
            let mut point = Point::new(params, temperature);
            stretch(&mut point, rate, 0.1, steps, |_| {});
            let error = (point.von_mises() - expected).abs() / expected;
            eprintln!(
                "T = {temperature} K, {rate}/s, {steps} steps: σ* {expected:.4e}, {:+.3}%",
                100.0 * (point.von_mises() - expected) / expected
            );
            assert!(
                error < 0.005,
                "T = {temperature} K, rate {rate}/s, {steps} steps: σ = {:.4e}, σ* = {expected:.4e}",
                point.von_mises()
            );
        }
    }
    // The constants give the strengths SAC305 is known for: about 40 MPa at room
    // temperature and 1e-3/s, softer hot.
    let room = anand_reference::saturation_stress(&params, 1e-3, 298.15);
    let hot = anand_reference::saturation_stress(&params, 1e-3, 398.15);
    assert!(
        (30e6..50e6).contains(&room) && hot < 0.8 * room,
        "{room:e} {hot:e}"
    );
}

#[test]
fn a_held_strain_relaxes_and_the_lost_elastic_energy_is_the_inelastic_work() {
    // Stretch to 0.2% at 125 °C, then hold for ten minutes (a thermal cycle's dwell).
    // The stress relaxes monotonically and stays positive; the elastic energy lost
    // equals the inelastic work dissipated, up to backward Euler's own dissipation of
    // 3μΔ²/2 per step. At 36 MPa and 125 °C SAC305 creeps at some 1e4/s, so the first
    // relaxation takes well under a microsecond: with steps of 1 s that dissipation was
    // 22% of the energy, with 0.01 s 6%; the hold below grows its steps from 1e-10 s by
    // 2% each, which follows the relaxation at every time scale.
    let mut point = Point::new(sac305(), 398.15);
    stretch(&mut point, 1.0, 0.002, 20, |_| {});
    let (energy0, work0, sigma0) = (point.energy, point.work, point.von_mises());
    let held = isochoric_stretch(0.002);
    let mut last = sigma0;
    let (mut t, mut dt) = (0.0, 1e-10);
    while t < 600.0 {
        point.step(held, dt);
        t += dt;
        dt *= 1.02;
        let s = point.von_mises();
        assert!(s <= last * (1.0 + 1e-12) && s > 0.0, "{s} after {last}");
        last = s;
    }
    assert!(last < 0.5 * sigma0, "relaxed from {sigma0:e} to {last:e}");
    let lost = energy0 - point.energy;
    let dissipated = point.work - work0;
    eprintln!(
        "relaxed {sigma0:.4e} -> {last:.4e} Pa; energy lost {lost:.6e}, work {dissipated:.6e}"
    );
    assert!(
        (lost - dissipated).abs() < 0.01 * lost,
        "elastic energy lost {lost:e} J, inelastic work {dissipated:e} J"
    );
    assert!(
        (point.field("inelastic_work") - point.work).abs() <= 1e-9 * point.work,
        "the state keeps the same work as the ledger"
    );
}

#[test]
fn plane_strain_runs_the_same_update_with_the_held_third_direction() {
    // A 2D particle is the 3D one with F_zz its stretch across the plane (0.996: a cooling
    // free strain): plane-strain shear gives the 3D stress, σzz included.
    let params = sac305();
    let flat = Anand::new(params);
    let gamma = 0.01;
    let stretch = 0.996;
    let f2 = Matrix::<2>::new(1.0, gamma, 0.0, 1.0);
    let f3 = Matrix3::new(1.0, gamma, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, stretch);
    let mut zz = [f64::NAN];
    let mut point = Point::new(params, params.temperature);
    point.step(f3, 1.0);
    let mut state: Vec<Vec<f64>> = point
        .state
        .iter()
        .map(|v| v.iter().map(|_| 0.0).collect())
        .collect();
    state[1][0] = params.initial_resistance;
    state[4].copy_from_slice(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    let mut iter = state.iter_mut();
    let fields: [&mut [f64]; MAX_STATE_FIELDS] =
        std::array::from_fn(|_| iter.next().map_or(&mut [][..], |v| &mut v[..]));
    let mut stress = Matrix::<2>::zeros();
    ConstitutiveLaw::update_stress::<2>(
        &flat,
        StressBatch {
            out_of_plane_stretch: &[stretch],
            out_of_plane_stress: &mut zz,
            dt: 1.0,
            deformation_gradient: std::slice::from_ref(&f2),
            velocity_gradient: &[],
            volume0: &[1.0],
            stress: std::slice::from_mut(&mut stress),
            state: StateSlices { fields },
            shared: [&[]; 4],
            plastic_work: &mut [],
        },
    );
    for r in 0..2 {
        for c in 0..2 {
            assert!((stress[(r, c)] - point.stress[(r, c)]).abs() <= 1e-9 * point.von_mises());
        }
    }
    assert!((zz[0] - point.stress[(2, 2)]).abs() <= 1e-9 * point.von_mises());
    assert!(
        point.stress[(2, 2)].abs() > 0.1 * point.von_mises(),
        "the stretch must load zz"
    );
}

#[test]
fn bad_constants_are_refused_at_their_paths() {
    let mut p = sac305();
    p.rate_sensitivity = 1.5;
    p.initial_resistance = -1.0;
    p.fatigue = Some(FatigueLaw {
        coefficient: 5e8,
        exponent: 1.0,
        growth: Some(CrackGrowth {
            coefficient: 2.6e-12,
            exponent: -0.98,
            crack_length: 0.0,
        }),
    });
    let paths: Vec<String> = p
        .check("materials.solder")
        .into_iter()
        .map(|i| i.path)
        .collect();
    for expected in [
        "materials.solder.rate_sensitivity",
        "materials.solder.initial_resistance",
        "materials.solder.fatigue.exponent",
        "materials.solder.fatigue.growth.exponent",
        "materials.solder.fatigue.growth.crack_length",
    ] {
        assert!(
            paths.iter().any(|p| p == expected),
            "{expected} in {paths:?}"
        );
    }
}

#[test]
fn the_fatigue_law_gives_fewer_cycles_for_more_work() {
    // Syed (2004) for SAC joints, N = (0.0019 ΔW[MPa])⁻¹, in J/m³: C = 1e6/0.0019, k = −1.
    let law = FatigueLaw {
        coefficient: 1e6 / 0.0019,
        exponent: -1.0,
        growth: None,
    };
    let n = law.cycles(0.1e6).unwrap();
    assert!((n - 1.0 / 0.00019).abs() < 1e-9 * n, "{n}");
    assert!(law.cycles(0.2e6).unwrap() < n);
    assert_eq!(law.cycles(0.0), None);
    assert_eq!(law.cycles_to_failure(0.1e6), None, "no growth law");
}

#[test]
fn darveaux_growth_adds_the_cycles_to_cross_the_joint() {
    // da/dN = K ΔW^m: at ΔW = 0.2 MJ/m³, K = 2.6e-12, m = 0.98, 4.07e-7 m a cycle, so
    // 80 µm takes 196.4 cycles after initiation; twice the work, fewer of both.
    let law = FatigueLaw {
        coefficient: 1e6 / 0.0019,
        exponent: -1.0,
        growth: Some(CrackGrowth {
            coefficient: 2.6e-12,
            exponent: 0.98,
            crack_length: 80e-6,
        }),
    };
    let work: f64 = 0.2e6;
    let rate = 2.6e-12 * work.powf(0.98);
    let expected = law.cycles(work).unwrap() + 80e-6 / rate;
    let n = law.cycles_to_failure(work).unwrap();
    assert!((n - expected).abs() < 1e-12 * n, "{n} against {expected}");
    assert!((80e-6 / rate - 196.4).abs() < 0.1, "{}", 80e-6 / rate);
    assert!(law.cycles_to_failure(2.0 * work).unwrap() < n);
    assert_eq!(law.cycles_to_failure(0.0), None);
}

/// The analytic tangent after driving a point through `history` (steps of `dt`), at `f`
/// along `df`, against a central difference of the update from the same state; relative.
fn tangent_error(
    temperature: f64,
    history: &[Matrix3<f64>],
    f: Matrix3<f64>,
    df: Matrix3<f64>,
    dt: f64,
) -> f64 {
    use mpm_core::material::{StateView, TangentBatch};
    let mut point = Point::new(sac305(), temperature);
    for g in history {
        point.step(*g, dt);
    }
    let start = point.state.clone();
    let mut stress_at = |g: Matrix3<f64>| {
        point.state = start.clone();
        point.step(g, dt);
        point.stress
    };
    let stress = stress_at(f);
    let h = 1e-7;
    let numeric = (stress_at(f + df * h) - stress_at(f - df * h)) / (2.0 * h);
    let fields: [&[f64]; MAX_STATE_FIELDS] =
        std::array::from_fn(|k| start.get(k).map_or(&[][..], |v| &v[..]));
    let mut analytic = [Matrix::<3>::zeros()];
    ConstitutiveLaw::stress_derivative::<3>(
        &point.law,
        TangentBatch {
            out_of_plane_stretch: &[],
            dt,
            deformation_gradient: &[f],
            direction: &[df],
            stress: &[stress],
            state: StateView { fields },
            shared: [&[temperature], &[], &[], &[]],
            stress_change: &mut analytic,
        },
    );
    (analytic[0] - numeric).norm() / numeric.norm()
}

#[test]
fn consistent_tangent_matches_differences_of_the_update() {
    // A shear-stretch path into creep, then a step further along it, one back towards the
    // start, and a nearly elastic state; cold and hot, steps of a thermal cycle (60 s) and
    // of an impact (1 µs).
    let path = |s: f64| {
        Matrix3::new(
            1.0 + 0.1 * s,
            0.6 * s,
            0.0,
            0.1 * s,
            1.0,
            0.2 * s,
            0.0,
            0.0,
            1.0 - 0.05 * s,
        )
    };
    let d = Matrix3::new(0.3, -0.2, 0.1, 0.05, 0.4, -0.1, 0.2, 0.1, -0.3);
    let history: Vec<_> = (1..=10).map(|i| path(0.001 * i as f64)).collect();
    let mut worst: f64 = 0.0;
    for temperature in [233.15, 398.15] {
        for dt in [60.0, 1e-6] {
            for (name, f, past) in [
                ("loading", path(0.011), &history[..]),
                ("unloading", path(0.009), &history[..]),
                ("nearly elastic", path(1e-5), &[][..]),
            ] {
                let error = tangent_error(temperature, past, f, d, dt);
                worst = worst.max(error);
                assert!(
                    error < 1e-5,
                    "{name}, T = {temperature} K, dt = {dt} s: {error:e}"
                );
            }
        }
    }
    eprintln!("largest relative tangent error: {worst:.2e}");
}
