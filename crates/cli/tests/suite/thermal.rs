//! Heat conduction (plugins/thermal) end to end: convergence against the slab and
//! semi-infinite closed forms with both integrators, the implicit integrator at steps far
//! above the explicit limit, the explicit step choice, input errors with their JSON paths,
//! and thermal expansion of a free block under quasi-static mechanics.
//!
//! Measured figures in the comments come from release builds on a 2-core machine.

use crate::common;

use common::*;
use mpm_core::output::{NullSink, Outcome};
use mpm_core::scene::Issue;
use mpm_core::solver::{Control, Progress, RunError, run_scene};
use mpm_io::ResultStore;

const SLAB: &str = "heat-slab.json";
const SEMI_INFINITE: &str = "heat-semi-infinite.json";
const EXPLICIT: &str = r#"physics.thermal.integrator="explicit""#;

/// Steel of both examples: ρc, J/(m³ K), and k, W/(m K).
const RHO_C: f64 = 7800.0 * 500.0;
const CONDUCTIVITY: f64 = 50.0;

/// Explicit stable step ρc·h²/(2·dim·k) of the 2D examples at cell size `h`.
fn explicit_stable_step(h: f64) -> f64 {
    RHO_C * h * h / (2.0 * 2.0 * CONDUCTIVITY)
}

/// Runs an example with overrides; the run must finish and report an error.
fn finished_error(example: &str, overrides: &[String]) -> f64 {
    let o: Vec<&str> = overrides.iter().map(String::as_str).collect();
    let m = run(&load_example(example, &o));
    assert_eq!(
        m.outcome,
        Some(Outcome::Finished),
        "{example} {overrides:?}: {:?}",
        m.diagnostic
    );
    m.error.expect("the example has a reference")
}

/// Errors at cell sizes `h` and `h/2` with a fixed step `dt` (and any extra overrides),
/// checked to fall by at least `ratio`, the fine one below `fine_bound`.
fn check_refinement(
    example: &str,
    h: f64,
    dt: f64,
    extra: &[&str],
    ratio: f64,
    fine_bound: f64,
) -> [f64; 2] {
    let errors = [h, h / 2.0].map(|cell| {
        let mut o = vec![
            format!("domain.cell_size={cell}"),
            format!("solver.dt={dt}"),
        ];
        o.extend(extra.iter().map(|s| s.to_string()));
        finished_error(example, &o)
    });
    println!(
        "{example} {extra:?}: errors at h = {h}, {}: {errors:?}",
        h / 2.0
    );
    assert!(
        errors[1] < ratio * errors[0],
        "{example} {extra:?}: refining h {h} -> {} took the error from {} to {} (want < {ratio}x)",
        h / 2.0,
        errors[0],
        errors[1]
    );
    assert!(
        errors[1] < fine_bound,
        "{example} {extra:?}: error {} at h = {} >= {fine_bound}",
        errors[1],
        h / 2.0
    );
    errors
}

/// Slab, implicit, dt = 0.02 s (the example's): errors 0.0338 (h = 1 mm) and 0.0128
/// (0.5 mm), ratio 0.38. Bounds: ratio < 0.6, fine < 0.02.
#[test]
fn slab_implicit_error_falls_with_the_cell_size() {
    check_refinement(SLAB, 1e-3, 0.02, &[], 0.6, 0.02);
}

/// Slab, explicit, dt = 2 ms (0.41 of the stable step at 0.5 mm): errors 0.0304 and 0.0101,
/// ratio 0.33. Bounds: ratio < 0.6, fine < 0.015.
#[test]
fn slab_explicit_error_falls_with_the_cell_size() {
    assert!(2e-3 < explicit_stable_step(5e-4));
    check_refinement(SLAB, 1e-3, 2e-3, &[EXPLICIT], 0.6, 0.015);
}

/// Semi-infinite bar, implicit, dt = 0.01 s (the example's): errors 0.0255 (h = 1 mm) and
/// 0.0095 (0.5 mm, the example), ratio 0.37. Bounds: ratio < 0.6, fine < 0.015.
#[test]
fn semi_infinite_implicit_error_falls_with_the_cell_size() {
    check_refinement(SEMI_INFINITE, 1e-3, 0.01, &[], 0.6, 0.015);
}

/// Semi-infinite bar, explicit, dt = 2 ms: errors 0.0246 and 0.0084, ratio 0.34. Bounds:
/// ratio < 0.6, fine < 0.013.
#[test]
fn semi_infinite_explicit_error_falls_with_the_cell_size() {
    check_refinement(SEMI_INFINITE, 1e-3, 2e-3, &[EXPLICIT], 0.6, 0.013);
}

/// The bar is long enough to be semi-infinite: the squared error summed over particles
/// (error² × length, the RMS being over all particles) is the same for 20 mm and 40 mm.
/// Measured at h = 1 mm: 1.298e-5 for 15, 20, 30 and 40 mm, 1.374e-5 for 10 mm (too short:
/// the far end warms). Bound: within 1% (measured 0.02%).
#[test]
fn semi_infinite_bar_is_long_enough() {
    let summed = |length: f64| {
        let o = [
            "domain.cell_size=0.001".to_string(),
            format!("domain.max=[{length},0.002]"),
            format!("bodies[0].shape.box.max=[{length},0.002]"),
        ];
        finished_error(SEMI_INFINITE, &o).powi(2) * length
    };
    let (example, longer) = (summed(0.02), summed(0.04));
    println!("error^2 x length: 20 mm {example:e}, 40 mm {longer:e}");
    assert!(
        (example - longer).abs() < 0.01 * longer,
        "20 mm {example:e} vs 40 mm {longer:e}: the far end matters"
    );
}

/// Backward Euler at 100 times the explicit stable step of the slab at 0.5 mm
/// (dt = 0.4875 s, 10 steps to 4.875 s): finishes with error 0.0505 (0.0051 at dt/100 over
/// the same time) and at most 10 conjugate-gradient iterations per step. Bounds: error
/// < 0.08, iterations <= 20.
#[test]
fn implicit_conduction_is_stable_far_above_the_explicit_step() {
    let dt = 100.0 * explicit_stable_step(5e-4);
    let o = [
        "domain.cell_size=0.0005".to_string(),
        format!("solver.dt={dt}"),
        format!("solver.end_time={}", 10.0 * dt),
    ];
    let o: Vec<&str> = o.iter().map(String::as_str).collect();
    let m = run(&load_example(SLAB, &o));
    println!(
        "dt {dt}: {:?}, error {:?}, steps {}, physics {:?}",
        m.outcome, m.error, m.steps, m.physics
    );
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    assert_eq!(m.steps, 10);
    let error = m.error.unwrap();
    assert!(error < 0.08, "error {error} at dt = {dt}");
    let iterations = m.physics["thermal.solver_iterations"];
    assert!(iterations <= 20.0, "{iterations} CG iterations per step");
}

/// Forward Euler at 10 times its stable step (allowed by max_cfl = 1000) diverges: the run
/// stops with a temperature diagnostic (measured: at step 11 of 41, t = 0.449 s, a particle
/// at -31 K). It is stable at 3 times the estimate (measured): the estimate is conservative.
#[test]
fn explicit_conduction_above_its_stable_step_stops_with_a_temperature_diagnostic() {
    let dt = 10.0 * explicit_stable_step(5e-4);
    let o = [
        "domain.cell_size=0.0005".to_string(),
        format!("solver.dt={dt}"),
        "solver.max_cfl=1000".to_string(),
        EXPLICIT.to_string(),
    ];
    let o: Vec<&str> = o.iter().map(String::as_str).collect();
    let m = run(&load_example(SLAB, &o));
    assert_eq!(m.outcome, Some(Outcome::Stopped));
    let d = m.diagnostic.expect("a stopped run says why");
    println!("{d:?}");
    assert_eq!(d.field, "temperature", "{d:?}");
    assert!(d.message.contains("diverged"), "{}", d.message);
    assert!(m.simulated_time < 2.0);
}

/// Without `solver.dt` the explicit run takes cfl × the thermal stable step: at 0.5 mm,
/// 2 s / (0.3 × 4.875 ms) = 1367.5 steps; measured 1370 (landing on the 10 output times
/// adds up to one step each), error 0.0101 as with the fixed 2 ms step. Bounds: steps in
/// [1368, 1378], error < 0.015.
#[test]
fn explicit_conduction_picks_its_step_from_the_thermal_stable_step() {
    let m = run(&load_example(SLAB, &["solver.dt=null", EXPLICIT]));
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let expected = 2.0 / (0.3 * explicit_stable_step(5e-4));
    println!(
        "steps {} (expected {expected}), error {:?}",
        m.steps, m.error
    );
    assert!(
        m.steps as f64 >= expected.ceil() && m.steps as f64 <= expected.ceil() + 10.0,
        "{} steps, expected about {expected}",
        m.steps
    );
    assert!(m.error.unwrap() < 0.015, "error {:?}", m.error);
}

/// Runs a scene that must be refused before its first step; returns the refusal's path.
fn refused(overrides: &[&str]) -> (String, String) {
    let scene = load_example(SLAB, overrides);
    match run_scene(&scene, &mut NullSink, &mut |_: &Progress| Control::Continue) {
        Err(RunError::Refused { path, message }) => (path, message),
        Err(e) => panic!("{overrides:?}: unexpected error {e}"),
        Ok(m) => panic!("{overrides:?}: ran ({:?})", m.outcome),
    }
}

/// Settings that cannot start: an implicit run without a step (nothing bounds it), and an
/// explicit step above the stable one.
#[test]
fn runs_without_a_usable_step_are_refused_at_solver_dt() {
    let (path, message) = refused(&["solver.dt=null"]);
    assert_eq!(path, "solver.dt");
    assert!(message.contains("give the step size"), "{message}");
    let (path, message) = refused(&["solver.dt=0.01", EXPLICIT]);
    assert_eq!(path, "solver.dt");
    assert!(message.contains("stable step"), "{message}");
}

/// The issues of a heat-slab variant that must not load.
fn issues(overrides: &[&str]) -> Vec<Issue> {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    match mpm_cli::load_scene(&example(SLAB), &o, &mpm_cli::default_registry()) {
        Err(mpm_cli::LoadError::Invalid(e)) => e.issues,
        Err(e) => panic!("{overrides:?}: not a scene error: {e:?}"),
        Ok(_) => panic!("{overrides:?}: accepted"),
    }
}

/// Asserts that the variant has an issue at `path` whose message contains `words`.
fn assert_issue(overrides: &[&str], path: &str, words: &str) {
    let issues = issues(overrides);
    assert!(
        issues
            .iter()
            .any(|i| i.path == path && i.message.contains(words)),
        "{overrides:?}: no issue at `{path}` mentioning `{words}` in {issues:#?}"
    );
}

/// Each bad input is refused with an issue at the JSON path of the offending value.
#[test]
fn bad_thermal_input_names_its_json_path() {
    assert_issue(
        &["physics.thermal.materials.steel.conductivity=-5"],
        "physics.thermal.materials.steel.conductivity",
        "got -5",
    );
    assert_issue(
        &[r#"physics.thermal.boundaries=[{"sides":["x-"],"temperature":400,"heat_flux":1000}]"#],
        "physics.thermal.boundaries[0]",
        "exactly one",
    );
    assert_issue(
        &["physics.thermal.materials={}"],
        "physics.thermal.materials",
        "`steel`",
    );
    assert_issue(&["physics.foo={}"], "physics.foo", "unknown physics `foo`");
    assert_issue(
        &[r#"physics.thermal.integrator="bogus""#],
        "physics.thermal.integrator",
        "bogus",
    );
    assert_issue(
        &[r#"physics.thermal.boundaries[0].sides=["z-"]"#],
        "physics.thermal.boundaries[0].sides[0]",
        "no such face",
    );
    assert_issue(
        &["physics.thermal.materials.steel.specific_heat=[[400,500],[300,600]]"],
        "physics.thermal.materials.steel.specific_heat[1][0]",
        "increase",
    );
    assert_issue(
        &["physics.thermal.materials.steel.conductivity_typo=1"],
        "physics.thermal.materials.steel.conductivity_typo",
        "unknown field",
    );
}

/// A free 4 mm steel block (no walls, 64 particles) heated uniformly by a source Q =
/// 3.9e8 W/m³ for 1 s (ΔT = Q t / ρc = 100 K), quasi-static mechanics, expansion 1e-5/K.
/// Measured: T = 400.090 K, uniform to 6.2e-6 K (the source is per current volume, which
/// grows by 0.2%), width growth 1.00123e-3 against expansion × ΔT = 1.00090e-3 (0.033% apart),
/// largest |stress| 1.88e5 Pa = 9.4e-4 of E·α·ΔT (what a clamped block would carry),
/// at most 69 relaxation iterations per step. Bounds: ΔT within 0.2% of 100 K and uniform
/// to 1.2e-5 K, growth within 0.07% of expansion × ΔT, stress < 2e-3 E·α·ΔT.
#[test]
fn uniformly_heated_free_block_expands_freely() {
    let (alpha, source, end) = (1e-5, 3.9e8, 1.0);
    let scene = serde_json::json!({
        "name": "heated-block",
        "dimension": 2,
        "domain": { "min": [0.0, 0.0], "max": [0.01, 0.01], "cell_size": 0.001 },
        "solver": { "end_time": end, "mechanics": { "quasi_static": {} }, "dt": 0.1 },
        "materials": { "steel": {
            "type": "linear_elastic", "density": 7800.0,
            "youngs_modulus": 200e9, "poisson_ratio": 0.3
        } },
        "physics": { "thermal": { "materials": { "steel": {
            "conductivity": CONDUCTIVITY, "specific_heat": 500.0,
            "initial_temperature": 300.0, "expansion": alpha, "heat_source": source
        } } } },
        "bodies": [{
            "material": "steel",
            "shape": { "box": { "min": [0.003, 0.003], "max": [0.007, 0.007] } }
        }],
        "output": { "frames": 2, "fields": ["x", "temperature", "stress"] }
    });
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(dir.path(), "block.json", &scene);
    let store = dir.path().join("block.zarr");
    let m = run_to_store(&load(&path, &[]), &store);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let r = ResultStore::open(&store).unwrap();
    let last = r.frame_count().unwrap() - 1;
    let extent = |x: &[f64], axis: usize| {
        let c = x.iter().skip(axis).step_by(2);
        c.clone().copied().fold(f64::MIN, f64::max) - c.copied().fold(f64::MAX, f64::min)
    };
    let (_, x0) = r.frame("x", 0).unwrap();
    let (_, x1) = r.frame("x", last).unwrap();
    let (_, t) = r.frame("temperature", last).unwrap();
    let (_, stress) = r.frame("stress", last).unwrap();
    let t_min = t.iter().copied().fold(f64::MAX, f64::min);
    let t_max = t.iter().copied().fold(f64::MIN, f64::max);
    let rise = t_min - 300.0;
    let free = alpha * rise;
    let growth = [0, 1].map(|axis| extent(&x1, axis) / extent(&x0, axis) - 1.0);
    let clamped = 200e9 * free;
    let peak = stress.iter().fold(0.0f64, |a, s| a.max(s.abs()));
    println!(
        "T [{t_min}, {t_max}], growth {growth:?} vs {free:e}, |stress| {peak:e} Pa = {:e} E a dT",
        peak / clamped
    );
    println!("{:?}", m.physics);
    let nominal = source * end / RHO_C;
    assert!(
        (rise - nominal).abs() < 2e-3 * nominal,
        "ΔT {rise} vs {nominal}"
    );
    assert!(t_max - t_min < 1.2e-5, "not uniform: [{t_min}, {t_max}]");
    for g in growth {
        assert!(
            (g - free).abs() < 7e-4 * free,
            "grew by {g:e}, expansion × ΔT = {free:e}"
        );
    }
    assert!(peak < 2e-3 * clamped, "stress {peak:e} Pa in a free block");
}

/// Known problem (see the report with this file): the temperature change is gathered from
/// the nodes, and at a held face the nodal "old" temperature is a projection that lags the
/// particles, so particles next to the face overshoot the face temperature: in heat-slab at
/// dt = 2 ms (either integrator) the first particle layer reaches 415 K at t = 0.02 s and
/// 404.7 K at t = 0.2 s (the first output frame) with the faces at 400 K. Conduction from a
/// held face must not overshoot it.
#[test]
#[ignore = "known limit: the FLIP temperature update overshoots a held face early on (see the thermal plugin)"]
fn temperatures_stay_between_the_initial_and_the_face_temperature() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("slab.zarr");
    let scene = load_example(SLAB, &["solver.dt=0.002"]);
    run_to_store(&scene, &store);
    let r = ResultStore::open(&store).unwrap();
    for f in 0..r.frame_count().unwrap() {
        let (_, t) = r.frame("temperature", f).unwrap();
        for (p, t) in t.iter().enumerate() {
            assert!(
                (300.0 - 1e-6..=400.0 + 1e-6).contains(t),
                "frame {f}: particle {p} at {t} K"
            );
        }
    }
}
