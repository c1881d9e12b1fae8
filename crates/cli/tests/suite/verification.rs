//! Verification against reference solutions, conservation checks and allocation checks.

use crate::common;

use common::*;
use mpm_core::output::Outcome;

/// Error of the vibrating bar at a cell size, with optional extra overrides.
fn bar_error(cell: f64, extra: &[&str]) -> f64 {
    let mut o = vec![format!("domain.cell_size={cell}")];
    o.extend(extra.iter().map(|s| s.to_string()));
    let m = run(&load(&example("vibrating-bar.json"), &o));
    assert_eq!(m.outcome, Some(Outcome::Finished));
    m.error.expect("the bar has a reference")
}

#[test]
fn vibrating_bar_converges_at_second_order_with_quadratic_bsplines_and_apic() {
    let cells = [0.1, 0.05, 0.025, 0.0125];
    let errors: Vec<f64> = cells.iter().map(|&h| bar_error(h, &[])).collect();
    let orders: Vec<f64> = errors.windows(2).map(|e| (e[0] / e[1]).log2()).collect();
    println!("errors {errors:?}\norders {orders:?}");
    for pair in errors.windows(2) {
        assert!(
            pair[1] < pair[0],
            "refining must lower the error: {errors:?}"
        );
    }
    // The issue asks for at least 1.5; measured 2.0 on every refinement.
    for order in &orders {
        assert!(*order >= 1.5, "observed order {order} < 1.5 ({errors:?})");
    }
    assert!(errors[3] < 5e-4, "finest error {}", errors[3]);
}

#[test]
fn every_kernel_transfer_and_scheme_reproduces_the_bar() {
    // Bounds from measurements at cell 0.05 (see the issue note): PIC is dissipative by
    // design; USF carries a first-order time error from its stale velocity.
    for kernel in ["linear", "gimp", "bspline2", "bspline3"] {
        for transfer in ["pic", "flip", "apic", "xpic"] {
            for scheme in ["usf", "usl", "musl"] {
                let sets = [
                    format!("solver.kernel={kernel}"),
                    format!("solver.transfer={transfer}"),
                    format!("solver.scheme={scheme}"),
                ];
                let m = run(&load(&example("vibrating-bar.json"), &sets));
                let error = m.error.unwrap();
                // XPIC(2) keeps 2–3% of PIC's energy loss at this cell: measured up to
                // 0.0105 with cubic B-splines and MUSL, 0.0257 with USF.
                let bound = match (transfer, scheme) {
                    ("pic", _) => 0.25,
                    (_, "usf") => 0.04,
                    ("xpic", _) => 0.015,
                    _ => 0.01,
                };
                assert_eq!(m.outcome, Some(Outcome::Finished), "{sets:?}");
                assert!(error < bound, "{sets:?}: error {error} >= {bound}");
                assert!(
                    m.energy_drift <= 1e-6,
                    "{sets:?}: energy grew by {}",
                    m.energy_drift
                );
            }
        }
    }
}

#[test]
fn xpic_converges_at_second_order_and_keeps_what_pic_loses() {
    // Hammerquist & Nairn 2017: XPIC(1) is PIC, higher orders keep the velocity modes the
    // grid resolves. PIC's bar is first order and loses half its energy at cell 0.05.
    let bar = |cell: f64, sets: &[&str]| {
        let mut o = vec![format!("domain.cell_size={cell}")];
        o.extend(sets.iter().map(|s| s.to_string()));
        let m = run(&load(&example("vibrating-bar.json"), &o));
        assert_eq!(m.outcome, Some(Outcome::Finished), "{o:?}");
        (m.error.unwrap(), m.energy_drift)
    };
    let pic = bar(0.05, &["solver.transfer=pic"]);
    let xpic1 = bar(0.05, &["solver.transfer=xpic", "solver.xpic_order=1"]);
    println!("pic {pic:?}, xpic(1) {xpic1:?}");
    // Order 1 is PIC, up to the sums' order (measured 2e-14 apart).
    assert!(
        (xpic1.0 - pic.0).abs() <= 1e-9 * pic.0,
        "{xpic1:?} vs {pic:?}"
    );
    let cells = [0.1, 0.05, 0.025];
    let xpic2: Vec<(f64, f64)> = cells
        .iter()
        .map(|&h| bar(h, &["solver.transfer=xpic"]))
        .collect();
    let xpic4 = bar(0.05, &["solver.transfer=xpic", "solver.xpic_order=4"]);
    println!("xpic(2) {xpic2:?}, xpic(4) {xpic4:?}");
    // Measured orders 2.03 and 2.01 (errors 0.0319, 0.00781, 0.00193).
    for pair in xpic2.windows(2) {
        let order = (pair[0].0 / pair[1].0).log2();
        assert!(order >= 1.8, "XPIC(2) order {order} < 1.8: {xpic2:?}");
    }
    // Energy lost at cell 0.05: PIC 49%, XPIC(2) 2.3%, XPIC(4) 0.52% (measured).
    assert!(pic.1 < -0.4, "PIC kept more than expected: {pic:?}");
    assert!(
        xpic2[1].1 > -0.03 && xpic2[1].1 < 0.0,
        "XPIC(2) drift {:?}",
        xpic2[1]
    );
    assert!(xpic4.1 > -0.007 && xpic4.1 < 0.0, "XPIC(4) drift {xpic4:?}");
    assert!(
        xpic4.0 < xpic2[1].0,
        "order 4 must beat order 2: {xpic4:?} {xpic2:?}"
    );
}

#[test]
fn mls_force_matches_the_standard_force() {
    let standard = bar_error(0.05, &[]);
    let mls = bar_error(0.05, &["solver.mls=true"]);
    assert!(
        (mls - standard).abs() < 0.2 * standard,
        "mls {mls} vs standard {standard}"
    );
}

#[test]
fn three_dimensional_bar_matches_the_two_dimensional_one() {
    let mut scene = bar_json();
    scene["dimension"] = 3.into();
    scene["domain"]["min"] = serde_json::json!([0, 0, 0]);
    scene["domain"]["max"] = serde_json::json!([1.5, 0.2, 0.2]);
    scene["domain"]["cell_size"] = 0.1.into();
    scene["domain"]["walls"][1]["sides"] = serde_json::json!(["y-", "y+", "z-", "z+"]);
    scene["bodies"][0]["shape"]["box"] =
        serde_json::json!({"min": [0, 0, 0], "max": [1, 0.2, 0.2]});
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(dir.path(), "bar3d.json", &scene);
    let three = run(&load(&path, &[])).error.unwrap();
    let two = bar_error(0.1, &[]);
    // The strip is one-dimensional (ν = 0): both runs solve the same problem.
    assert!((three - two).abs() < 1e-6 * two, "3D {three} vs 2D {two}");
}

#[test]
fn two_disks_conserve_momentum_and_lose_bounded_energy() {
    let m = run(&load_example("two-disks.json", &[]));
    assert_eq!(m.outcome, Some(Outcome::Finished));
    // Initial momentum is zero (equal and opposite); each disk carries m·|v| ≈ 17.8 kg·m/s,
    // so 1e-10 is round-off.
    assert!(m.max_momentum < 1e-10, "momentum {}", m.max_momentum);
    // APIC dissipates some energy at this resolution (measured 14.7% at cell 0.025, 5.6% at
    // 0.0125); it never grows.
    assert!(m.energy_drift < 0.0, "energy grew: {}", m.energy_drift);
    assert!(m.energy_drift > -0.20, "energy lost: {}", m.energy_drift);
}

#[test]
fn clamped_cantilever_matches_beam_theory_under_a_small_load() {
    // Small load: the elastica reduces to δ = wL⁴/(8EI); this checks the stick wall (a
    // true clamp) and gravity. Measured 0.71% at 4 cells through the thickness.
    let m = run(&load_example(
        "cantilever.json",
        &["solver.gravity=[0,-0.1]", "reference.gravity=0.1"],
    ));
    let error = m.error.unwrap();
    println!(
        "tip deflection {:?} vs {:?}",
        m.measured_value, m.reference_value
    );
    assert!(error < 0.02, "tip deflection error {error}");
}

#[test]
fn scenes_allocate_only_what_they_need() {
    let pic = mpm_core::solver::bytes_per_particle(&load_example(
        "vibrating-bar.json",
        &["solver.transfer=pic", "reference=null"],
    ));
    let apic = mpm_core::solver::bytes_per_particle(&load_example(
        "vibrating-bar.json",
        &["reference=null"],
    ));
    // 2D: position, velocity (2×8 each), mass, volume, σzz (8 each), F, stress (4×8 each),
    // id (4).
    let base = 2.0 * 16.0 + 3.0 * 8.0 + 2.0 * 32.0 + 4.0;
    assert_eq!(pic, base, "PIC allocates exactly the core fields");
    // APIC adds the affine matrix and nothing else: no plugin fields for elastic materials.
    assert_eq!(apic, base + 32.0);
    // A reference needing initial positions adds them.
    let with_reference =
        mpm_core::solver::bytes_per_particle(&load_example("vibrating-bar.json", &[]));
    assert_eq!(with_reference, base + 32.0 + 16.0);
}

/// A block sliding on a floor with Coulomb friction μ = 0.3 under gravity.
fn sliding_block(floor: &str) -> serde_json::Value {
    let mut scene = serde_json::json!({
        "name": "slide", "dimension": 2,
        "domain": {"min": [0, -0.2], "max": [2, 0.5], "cell_size": 0.025},
        "solver": {"end_time": 0.2, "gravity": [0, -9.81], "cfl": 0.3},
        "materials": {"block": {"type": "neo_hookean", "density": 1000, "youngs_modulus": 1e6, "poisson_ratio": 0.3}},
        "bodies": [{"material": "block", "shape": {"box": {"min": [0.2, 0.0], "max": [0.6, 0.1]}},
                    "velocity": {"uniform": [1.0, 0.0]}}],
        "output": {"frames": 4, "fields": ["x", "v"]}
    });
    let friction = serde_json::json!({"friction": {"coefficient": 0.3}});
    match floor {
        "wall" => {
            scene["domain"]["min"] = serde_json::json!([0, 0]);
            scene["domain"]["walls"] =
                serde_json::json!([{"sides": ["y-"], "condition": friction}]);
        }
        _ => {
            scene["obstacles"] = serde_json::json!([{"shape": {"plane": {"point": [0, 0], "normal": [0, 1]}}, "condition": friction}]);
        }
    }
    scene
}

fn mean_velocity_x(store: &std::path::Path, frame: u64) -> f64 {
    let (_, v) = mpm_io::ResultStore::open(store)
        .unwrap()
        .frame("v", frame)
        .unwrap();
    v.chunks(2).map(|c| c[0]).sum::<f64>() / (v.len() / 2) as f64
}

#[test]
fn coulomb_friction_decelerates_a_sliding_block_at_mu_g() {
    for floor in ["wall", "obstacle"] {
        let dir = tempfile::tempdir().unwrap();
        let path = write_scene(dir.path(), "slide.json", &sliding_block(floor));
        let scene = load(&path, &[]);
        let store = dir.path().join("slide.zarr");
        let m = run_to_store(&scene, &store);
        assert_eq!(m.outcome, Some(Outcome::Finished), "{floor}");
        for frame in 1..=4u64 {
            let t = 0.05 * frame as f64;
            let expected = 1.0 - 0.3 * 9.81 * t;
            let got = mean_velocity_x(&store, frame);
            // Measured within 0.003 m/s of μ g deceleration for both floors.
            assert!(
                (got - expected).abs() < 0.01,
                "{floor} t={t}: {got} vs {expected}"
            );
        }
        // Friction dissipates, and the ledger books it (`energy_ledger.friction`), so the
        // drift left is the method's own error.
        println!(
            "{floor}: friction {:.4e}, drift {:.3e}",
            m.energy_ledger.friction, m.energy_drift
        );
        assert!(m.energy_ledger.friction > 0.0, "{floor}: nothing booked");
        assert!(m.energy_drift.abs() < 0.05, "{floor}: {}", m.energy_drift);
    }
}

#[test]
fn a_moving_stick_obstacle_carries_the_body_with_it() {
    let mut scene = sliding_block("obstacle");
    scene["obstacles"][0]["condition"] = serde_json::json!("stick");
    scene["obstacles"][0]["velocity"] = serde_json::json!([0, 0.5]);
    scene["bodies"][0]["velocity"] = serde_json::json!({"uniform": [0, 0]});
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(dir.path(), "lift.json", &scene);
    let store = dir.path().join("slide.zarr");
    let m = run_to_store(&load(&path, &[]), &store);
    // The plane does work on the block; the energy balance accounts for it, so the run is
    // not stopped for energy growth.
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    assert!(m.boundary_work > 0.0);
    let r = mpm_io::ResultStore::open(&store).unwrap();
    let bottom = |frame: u64| {
        let (_, x) = r.frame("x", frame).unwrap();
        x.chunks(2).map(|c| c[1]).fold(f64::INFINITY, f64::min)
    };
    let gap0 = bottom(0);
    for frame in 1..=4u64 {
        let plane = 0.5 * 0.05 * frame as f64;
        let gap = bottom(frame) - plane;
        assert!(
            (gap - gap0).abs() < 0.5 * 0.025,
            "frame {frame}: gap {gap} vs {gap0}"
        );
    }
}

#[test]
fn fbar_removes_volumetric_locking_of_a_near_incompressible_beam() {
    // A short cantilever (L = 0.5, h = 0.1, 4 cells thick) under a small load, ν = 0.499.
    // Measured: 10.9% too stiff without anti-locking, 0.50% with F-bar.
    let tip_error = |anti_locking: &str| {
        let m = run(&short_cantilever(
            0.499,
            &[
                "solver.end_time=0.6",
                "solver.damping=40",
                &format!("solver.anti_locking={anti_locking}"),
            ],
        ));
        assert_eq!(m.outcome, Some(Outcome::Finished));
        (
            m.error.unwrap(),
            m.measured_value.unwrap(),
            m.reference_value.unwrap(),
        )
    };
    let (locked, measured, reference) = tip_error("none");
    assert!(
        locked > 0.05 && measured < reference,
        "expected locking: {locked}"
    );
    let (fbar, _, _) = tip_error("fbar");
    assert!(fbar < 0.02, "F-bar error {fbar}");
}
