//! Constitutive tests of the Johnson–Cook update alone (single particles, strain paths
//! driven through F), against closed forms.

use super::*;
use crate::johnson_cook::embed;
use mpm_core::material::{ConstitutiveLaw, MAX_STATE_FIELDS, StateSlices, StressBatch};
use mpm_core::math::Matrix;

/// OFHC copper (Johnson & Cook 1983 constants), isothermal unless a test says otherwise.
fn copper() -> JohnsonCookParameters {
    serde_json::from_value(serde_json::json!({
        "density": 8960.0,
        "youngs_modulus": 124e9,
        "poisson_ratio": 0.34,
        "specific_heat": 383.0,
        "taylor_quinney": 0.0,
        "flow_stress": {
            "yield_stress": 90e6, "hardening_modulus": 292e6, "hardening_exponent": 0.31,
            "strain_rate_sensitivity": 0.025, "thermal_softening_exponent": 1.09,
            "reference_strain_rate": 1.0, "room_temperature": 294.0, "melt_temperature": 1356.0
        }
    }))
    .unwrap()
}

/// One particle driven through a sequence of deformation gradients.
struct Point<const D: usize> {
    law: JohnsonCook,
    state: Vec<Vec<f64>>,
    stress: Matrix<D>,
}

impl<const D: usize> Point<D> {
    fn new(params: JohnsonCookParameters) -> Self {
        let law = JohnsonCook::new(params);
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
            stress: Matrix::<D>::zeros(),
        }
    }

    fn step(&mut self, f: Matrix<D>, dt: f64) {
        self.step_stretched(f, 1.0, dt);
    }

    /// A step with a stretch across the plane (2D); returns σzz (NaN in 3D).
    fn step_stretched(&mut self, f: Matrix<D>, stretch: f64, dt: f64) -> f64 {
        let mut zz = [f64::NAN];
        let mut iter = self.state.iter_mut();
        let fields: [&mut [f64]; MAX_STATE_FIELDS] =
            std::array::from_fn(|_| iter.next().map_or(&mut [][..], |v| &mut v[..]));
        let batch = StressBatch {
            out_of_plane_stretch: if D == 2 { &[stretch][..] } else { &[] },
            out_of_plane_stress: if D == 2 { &mut zz[..] } else { &mut [] },
            dt,
            deformation_gradient: std::slice::from_ref(&f),
            velocity_gradient: &[],
            volume0: &[1.0],
            stress: std::slice::from_mut(&mut self.stress),
            state: StateSlices { fields },
            shared: [&[]; 4],
            plastic_work: &mut [],
        };
        self.law.update_stress::<D>(batch);
        zz[0]
    }

    fn field(&self, name: &str) -> f64 {
        let k = ConstitutiveLaw::state_fields(&self.law)
            .iter()
            .position(|s| s.name == name)
            .unwrap();
        self.state[k][0]
    }

    /// Von Mises stress of the Cauchy stress (3D).
    fn von_mises(&self) -> f64 {
        let s = embed(&self.stress);
        let dev = s - Matrix3::identity() * (s.trace() / 3.0);
        (1.5 * dev.norm_squared()).sqrt()
    }
}

use mpm_core::material::FieldInit;
use nalgebra::Matrix3;

/// The volume-preserving stretch of logarithmic strain `stretch` along x.
fn uniaxial_isochoric(stretch: f64) -> Matrix3<f64> {
    Matrix3::from_diagonal(&nalgebra::Vector3::new(
        stretch.exp(),
        (-0.5 * stretch).exp(),
        (-0.5 * stretch).exp(),
    ))
}

#[test]
fn uniaxial_strain_follows_the_closed_form_flow_stress() {
    // Compression at a constant log strain rate, isothermal at 600 K. Once plastic, the
    // equivalent plastic strain is εₚ = (2/3)|ε| − q/(3μ) and its rate (2/3)|ε̇| (up to the
    // hardening's share, 0.3% here), so q = σ_y(εₚ, (2/3)|ε̇|, T) closes in εₚ alone.
    let mut params = copper();
    params.initial_temperature = Some(600.0);
    let (_, mu) = mpm_core::material::lame_parameters(params.youngs_modulus, params.poisson_ratio);
    let rate = 1e4;
    let dt = 1e-8;
    let mut point = Point::<3>::new(params);
    let mut checked = 0;
    for step in 1..=5000 {
        let strain = -rate * dt * step as f64;
        let f = Matrix::<3>::from_diagonal(&nalgebra::Vector3::new(strain.exp(), 1.0, 1.0));
        point.step(f, dt);
        if step % 1000 == 0 {
            let q = point.von_mises() * strain.exp(); // Kirchhoff = J × Cauchy
            // Solve εₚ = (2/3)|ε| − σ_y(εₚ)/(3μ) by bisection.
            let plastic_rate = 2.0 / 3.0 * rate;
            let (mut lo, mut hi) = (0.0, 2.0 / 3.0 * strain.abs());
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                let g = 2.0 / 3.0 * strain.abs()
                    - params.flow_stress.value(mid, plastic_rate, 600.0) / (3.0 * mu)
                    - mid;
                if g > 0.0 { lo = mid } else { hi = mid }
            }
            let expected = params.flow_stress.value(lo, plastic_rate, 600.0);
            let plastic = point.field("plastic_strain");
            assert!(
                (q - expected).abs() < 5e-3 * expected,
                "step {step}: q {q} vs {expected}"
            );
            assert!((plastic - lo).abs() < 5e-3 * lo, "εₚ {plastic} vs {lo}");
            checked += 1;
        }
    }
    assert_eq!(checked, 5);
    // Pressure from the linear equation of state, p = −K ln J / J.
    let j = (-rate * dt * 5000.0f64).exp();
    let bulk = params.youngs_modulus / (3.0 * (1.0 - 2.0 * params.poisson_ratio));
    let pressure = -point.stress.trace() / 3.0;
    assert!(
        (pressure - (-bulk * j.ln() / j)).abs() < 1e-9 * bulk,
        "{pressure}"
    );
}

#[test]
fn flow_stress_closed_form_at_rate_and_temperature() {
    let f = copper().flow_stress;
    let expected = (90e6 + 292e6 * 0.5f64.powf(0.31))
        * (1.0 + 0.025 * 1e3f64.ln())
        * (1.0 - ((700.0 - 294.0) / (1356.0 - 294.0f64)).powf(1.09));
    assert!((f.value(0.5, 1e3, 700.0) - expected).abs() < 1e-6);
    // Below the reference rate and at room temperature: the quasi-static curve.
    assert_eq!(f.value(0.0, 0.1, 294.0), 90e6);
    // At and above melt: no strength.
    assert_eq!(f.value(0.3, 1e3, 1400.0), 0.0);
}

#[test]
fn damage_at_constant_triaxiality_matches_the_integral() {
    // Perfectly plastic, rate independent, isothermal: under an isochoric stretch on top of a
    // held volume change the triaxiality σ_m/σ_eq stays constant, so D = εₚ/ε_f exactly and
    // the particle fails when εₚ reaches ε_f.
    for (j, label) in [
        (1.0, "shear-free"),
        (1.0005, "tension"),
        (0.99993, "compression"),
    ] {
        let mut params = copper();
        params.flow_stress.hardening_modulus = 0.0;
        params.flow_stress.strain_rate_sensitivity = 0.0;
        params.damage = Some(Damage {
            d1: 0.54,
            d2: 4.89,
            d3: -3.03,
            d4: 0.014,
            d5: 1.12,
            failure: FailureMode::NoTension,
            averaging_radius: None,
        });
        let bulk = params.youngs_modulus / (3.0 * (1.0 - 2.0 * params.poisson_ratio));
        let pressure = -bulk * f64::ln(j) / j;
        // Cauchy von Mises = A / J on the yield surface.
        let triaxiality = -pressure / (90e6 / j);
        let d = params.damage.unwrap();
        let failure_strain = d.failure_strain(triaxiality, 1.0, 0.0);
        let mut point = Point::<3>::new(params);
        let dt = 1.0; // rate 1e-3/s: below the reference rate
        let mut failed_at = None;
        for step in 1..=8000 {
            let f = uniaxial_isochoric(1e-3 * step as f64) * j.powf(1.0 / 3.0);
            point.step(f, dt);
            let plastic = point.field("plastic_strain");
            let damage = point.field("damage");
            if damage < 1.0 && plastic > 0.0 {
                // Yield happens within the first steps; from then on D = εₚ/ε_f.
                assert!(
                    (damage - plastic / failure_strain).abs() < 1e-9,
                    "{label}: D {damage} vs {}",
                    plastic / failure_strain
                );
            }
            if damage >= 1.0 && failed_at.is_none() {
                failed_at = Some(plastic);
                // Failed: no shear, and no tension.
                assert!(
                    point.von_mises() < 1e-6 * 90e6,
                    "{label}: shear after failure"
                );
                assert!(
                    -point.stress.trace() / 3.0 >= 0.0,
                    "{label}: tension after failure"
                );
            }
        }
        let at = failed_at.unwrap_or_else(|| panic!("{label}: never failed"));
        assert!(
            (at - failure_strain).abs() < 1.5e-3,
            "{label}: failed at εₚ {at}, expected {failure_strain}"
        );
    }
}

#[test]
fn adiabatic_heating_follows_the_plastic_work() {
    // Perfectly plastic with m = 1: dT/dεₚ = χ A (1 − T*)/(ρ c), so
    // T − T_room = (T_melt − T_room)(1 − exp(−χ A εₚ / (ρ c (T_melt − T_room)))).
    let mut params = copper();
    params.taylor_quinney = 0.9;
    params.flow_stress.hardening_modulus = 0.0;
    params.flow_stress.strain_rate_sensitivity = 0.0;
    params.flow_stress.thermal_softening_exponent = 1.0;
    params.flow_stress.yield_stress = 2e9; // strong, to heat a lot
    let mut point = Point::<3>::new(params);
    for step in 1..=4000 {
        let stretch: f64 = 5e-4 * step as f64;
        let f = Matrix3::from_diagonal(&nalgebra::Vector3::new(
            stretch.exp(),
            (-0.5 * stretch).exp(),
            (-0.5 * stretch).exp(),
        ));
        point.step(f, 1.0);
    }
    let plastic = point.field("plastic_strain");
    let range = 1356.0 - 294.0;
    let expected = 294.0 + range * (1.0 - (-0.9 * 2e9 * plastic / (8960.0 * 383.0 * range)).exp());
    let t = point.field("temperature");
    assert!(plastic > 1.5, "{plastic}");
    assert!(
        (t - expected).abs() < 2e-3 * (expected - 294.0),
        "T {t} vs {expected}"
    );
}

#[test]
fn plane_strain_equals_3d_with_no_out_of_plane_stretch() {
    let params = copper();
    let mut flat = Point::<2>::new(params);
    let mut full = Point::<3>::new(params);
    for step in 1..=200 {
        let s = 1e-3 * step as f64;
        let f2 = Matrix::<2>::new(1.0 + s, 0.4 * s, 0.1 * s, 1.0 - 0.5 * s);
        flat.step(f2, 1e-6);
        full.step(embed(&f2), 1e-6);
    }
    let diff = (embed(&flat.stress) - full.stress)
        .fixed_view::<2, 2>(0, 0)
        .norm();
    assert!(diff < 1e-9 * full.stress.norm(), "{diff}");
    assert!(flat.field("plastic_strain") > 0.05);
    assert_eq!(flat.field("plastic_strain"), full.field("plastic_strain"));
}

#[test]
fn rigid_rotation_rotates_the_stress() {
    // Objectivity: after plastic straining, rotating the body rigidly rotates the stress and
    // changes nothing else (rate independent here: with rate sensitivity a pause relaxes
    // the stress, as it should).
    let mut params = copper();
    params.flow_stress.strain_rate_sensitivity = 0.0;
    let mut point = Point::<3>::new(params);
    let f = Matrix3::new(1.2, 0.3, 0.0, 0.0, 0.9, 0.1, 0.0, 0.0, 0.95);
    for step in 1..=100 {
        let t = step as f64 / 100.0;
        point.step(Matrix3::identity() * (1.0 - t) + f * t, 1e-6);
    }
    let (stress, plastic) = (point.stress, point.field("plastic_strain"));
    let r = *nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::z_axis(), 0.8).matrix();
    point.step(r * f, 1e-6);
    assert!((point.stress - r * stress * r.transpose()).norm() < 1e-6 * stress.norm());
    assert!((point.field("plastic_strain") - plastic).abs() < 1e-12);
}

#[test]
fn mie_gruneisen_follows_the_hugoniot_in_compression() {
    let eos = EquationOfState::MieGruneisen {
        sound_speed: 3940.0,
        slope: 1.489,
        gruneisen: 2.02,
    };
    let (rho, j) = (8930.0, 0.8);
    let mu = 1.0 / j - 1.0;
    let expected =
        rho * 3940.0f64.powi(2) * mu * (1.0 + (1.0 - 1.01) * mu) / (1.0 - 0.489 * mu).powi(2);
    assert!((eos.pressure(j, rho, 0.0, 0.0) - expected).abs() < 1e-6 * expected);
    // Heating adds Γ0·E; tension is linear.
    assert!((eos.pressure(1.0, rho, 0.0, 1e6) - 2.02e6).abs() < 1e-6);
    assert!(eos.pressure(1.1, rho, 0.0, 0.0) < 0.0);
    assert!(eos.tangent_bulk_modulus(0.8, rho, 0.0) > rho * 3940.0f64.powi(2));
}

#[test]
fn bad_constants_are_named_by_path() {
    let mut p = copper();
    p.flow_stress.melt_temperature = 200.0;
    p.taylor_quinney = 1.5;
    p.specific_heat = -1.0;
    let issues = p.check("materials.steel");
    let paths: Vec<_> = issues.iter().map(|i| i.path.as_str()).collect();
    for want in [
        "materials.steel.flow_stress.melt_temperature",
        "materials.steel.taylor_quinney",
        "materials.steel.specific_heat",
    ] {
        assert!(paths.contains(&want), "{paths:?}");
    }
}

/// The analytic tangent after driving a point through `history` (steps of `dt`), at `f`
/// along `df`, against a central difference of the update from the same state; relative.
fn tangent_error<const D: usize>(
    params: JohnsonCookParameters,
    history: &[Matrix<D>],
    f: Matrix<D>,
    df: Matrix<D>,
    dt: f64,
) -> f64 {
    use mpm_core::material::{StateView, TangentBatch};
    let mut point = Point::<D>::new(params);
    for g in history {
        point.step(*g, dt);
    }
    let start = point.state.clone();
    let mut stress_at = |g: Matrix<D>| {
        point.state = start.clone();
        point.step(g, dt);
        point.stress
    };
    let stress = stress_at(f);
    let h = 1e-6;
    let numeric = (stress_at(f + df * h) - stress_at(f - df * h)) / (2.0 * h);
    let fields: [&[f64]; MAX_STATE_FIELDS] =
        std::array::from_fn(|k| start.get(k).map_or(&[][..], |v| &v[..]));
    let mut analytic = [Matrix::<D>::zeros()];
    point.law.stress_derivative(TangentBatch {
        out_of_plane_stretch: &[],
        dt,
        deformation_gradient: &[f],
        direction: &[df],
        stress: &[stress],
        state: StateView { fields },
        shared: [&[]; 4],
        stress_change: &mut analytic,
    });
    (analytic[0] - numeric).norm() / numeric.norm()
}

#[test]
fn consistent_tangent_matches_differences_of_the_update() {
    // A shear-compression path into the plastic range, then a step further along it
    // (plastic loading), back towards the start (elastic unloading from a plastic state),
    // and an elastic state; isothermal copper, and self-heating copper with Mie–Grüneisen.
    let path3 = |s: f64| {
        Matrix::<3>::new(
            1.0 - 0.4 * s,
            0.6 * s,
            0.0,
            0.1 * s,
            1.0,
            0.2 * s,
            0.0,
            0.0,
            1.0 + 0.1 * s,
        )
    };
    let path2 = |s: f64| Matrix::<2>::new(1.0 - 0.4 * s, 0.6 * s, 0.1 * s, 1.0);
    let d3 = Matrix::<3>::new(0.3, -0.2, 0.1, 0.05, 0.4, -0.1, 0.2, 0.1, -0.3);
    let d2 = Matrix::<2>::new(-0.2, 0.3, 0.1, 0.4);
    let history3: Vec<_> = (1..=10).map(|i| path3(0.01 * i as f64)).collect();
    let history2: Vec<_> = (1..=10).map(|i| path2(0.01 * i as f64)).collect();
    let mut heating = copper();
    heating.taylor_quinney = 0.9;
    heating.equation_of_state = EquationOfState::MieGruneisen {
        sound_speed: 3940.0,
        slope: 1.49,
        gruneisen: 2.0,
    };
    let dt = 1e-6;
    let cases = [
        (
            "3D plastic",
            tangent_error(copper(), &history3, path3(0.11), d3, dt),
        ),
        (
            "3D unloading",
            tangent_error(copper(), &history3, path3(0.09), d3, dt),
        ),
        (
            "3D elastic",
            tangent_error(copper(), &[], path3(1e-4), d3, dt),
        ),
        (
            "2D plastic",
            tangent_error(copper(), &history2, path2(0.11), d2, dt),
        ),
        (
            "2D unloading",
            tangent_error(copper(), &history2, path2(0.09), d2, dt),
        ),
        (
            "3D heating, Mie–Grüneisen",
            tangent_error(heating, &history3, path3(0.11), d3, dt),
        ),
    ];
    for (name, error) in cases {
        // Central differences of an update whose return map converges to 1e-12 of the
        // stress: about 1e-6 relative noise at this step.
        assert!(error < 1e-5, "{name}: relative error {error}");
    }
}

/// With `damage.averaging_radius` the update drives `local_damage` (past 1) and leaves
/// `damage`, which the core averages from it, and so the particle's failure alone.
#[test]
fn averaged_damage_is_driven_through_the_local_field() {
    let mut params = copper();
    params.flow_stress.hardening_modulus = 0.0;
    params.flow_stress.strain_rate_sensitivity = 0.0;
    let model = Damage {
        d1: 0.01,
        d2: 0.0,
        d3: 0.0,
        d4: 0.0,
        d5: 0.0,
        failure: FailureMode::NoTension,
        averaging_radius: Some(1e-3),
    };
    params.damage = Some(model);
    let law = JohnsonCook::new(params);
    let averaged = ConstitutiveLaw::averaged_state(&law).unwrap();
    let names: Vec<&str> = ConstitutiveLaw::state_fields(&law)
        .iter()
        .map(|f| f.name)
        .collect();
    assert_eq!(
        (names[averaged.local], names[averaged.averaged]),
        ("local_damage", "damage")
    );
    assert_eq!(averaged.radius, 1e-3);
    let mut point = Point::<3>::new(params);
    for step in 1..=100 {
        point.step(uniaxial_isochoric(1e-3 * step as f64), 1.0);
    }
    let (plastic, local) = (point.field("plastic_strain"), point.field("local_damage"));
    assert!(plastic > 0.05, "{plastic}");
    assert!(
        (local - plastic / 0.01).abs() < 1e-9 * local,
        "{local} {plastic}"
    );
    assert_eq!(point.field("damage"), 0.0);
    assert!(point.von_mises() > 0.9 * 90e6, "the particle did not fail");
    // Without the radius the same constants give no `local_damage` field.
    let mut local_only = copper();
    local_only.damage = Some(Damage {
        averaging_radius: None,
        ..model
    });
    let plain = JohnsonCook::new(local_only);
    assert!(ConstitutiveLaw::averaged_state(&plain).is_none());
    assert_eq!(ConstitutiveLaw::state_fields(&plain).len(), 5);
}

#[test]
fn a_2d_point_is_the_3d_law_with_its_stretch_across_the_plane() {
    // Plastic shear and stretch in the plane while the third direction shrinks (a cooling
    // free strain): the 2D update, σzz included, follows the 3D update at
    // F = [[F, 0], [0, s]] step by step.
    let mut plane = Point::<2>::new(copper());
    let mut solid = Point::<3>::new(copper());
    let dt = 1e-6;
    for n in 1..=40 {
        let t = n as f64 / 40.0;
        let f = Matrix::<2>::new(1.0 + 0.02 * t, 0.03 * t, 0.0, 1.0 - 0.01 * t);
        let s = 1.0 - 0.004 * t;
        let zz = plane.step_stretched(f, s, dt);
        solid.step(mpm_core::math::embed3(&f, s), dt);
        let scale = solid.stress.norm();
        for r in 0..2 {
            for c in 0..2 {
                assert!(
                    (plane.stress[(r, c)] - solid.stress[(r, c)]).abs() < 1e-9 * scale,
                    "step {n}: σ{r}{c} {} against {}",
                    plane.stress[(r, c)],
                    solid.stress[(r, c)]
                );
            }
        }
        assert!(
            (zz - solid.stress[(2, 2)]).abs() < 1e-9 * scale,
            "step {n}: σzz {zz} against {}",
            solid.stress[(2, 2)]
        );
    }
    assert!(plane.field("plastic_strain") > 0.0, "the path must yield");
    assert!(
        (plane.field("plastic_strain") - solid.field("plastic_strain")).abs()
            < 1e-9 * solid.field("plastic_strain")
    );
}
