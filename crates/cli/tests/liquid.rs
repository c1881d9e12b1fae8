//! Liquid particles with incompressible mechanics (fractional-step projection): the
//! hydrostatic tank, the dam break against Martin & Moyce (1952), and the checks.

mod common;

use common::{invalid_example, load_example, run};

fn comparison(m: &mpm_core::output::Metrics, name: &str) -> (f64, f64) {
    let c = m
        .comparisons
        .iter()
        .find(|c| c.quantity == name)
        .unwrap_or_else(|| panic!("no comparison {name}: {:?}", m.comparisons));
    (c.measured, c.reference)
}

#[test]
fn hydrostatic_tank_has_rho_g_h_and_no_spurious_flow() {
    // 0.05 m of water, 10 cells deep, 0.5 s (50 steps at the velocity/gravity CFL).
    let m = run(&load_example("hydrostatic-tank.json", &[]));
    assert_eq!(m.simulated_time, 0.5, "{m:?}");
    let error = m.error.expect("error");
    assert!(error < 1e-6, "pressure error {error}");
    let (bottom, exact) = comparison(&m, "bottom_pressure");
    assert!((bottom - exact).abs() < 1e-6 * exact, "{bottom} vs {exact}");
    let (speed, _) = comparison(&m, "spurious_speed");
    assert!(speed < 1e-6, "largest spurious speed {speed} m/s");
}

#[test]
fn dam_break_front_follows_martin_moyce_at_coarse_resolution() {
    // a/8 cells (the example): relative L2 error of z/a over 0.41 <= T <= 3.33 was 0.120.
    let m = run(&load_example("dam-break.json", &[]));
    assert_eq!(m.simulated_time, 0.18, "{m:?}");
    let error = m.error.expect("error");
    assert!(error < 0.15, "front error {error}");
    let (z, exact) = comparison(&m, "front_z_over_a");
    assert!(
        z > 3.0 && (z - exact).abs() < 0.25 * exact,
        "{z} vs {exact}"
    );
}

#[test]
fn incompressible_mechanics_and_liquids_go_together() {
    let issues = invalid_example("hydrostatic-tank.json", &["solver.mechanics=\"dynamic\""]);
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("materials.water.type") && i.contains("incompressible")),
        "{issues:?}"
    );
    let issues = invalid_example(
        "hydrostatic-tank.json",
        &[
            r#"materials.water={"type": "linear_elastic", "density": 1000, "youngs_modulus": 1e6, "poisson_ratio": 0.3}"#,
        ],
    );
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("materials.water.type") && i.contains("liquids only")),
        "{issues:?}"
    );
    let issues = invalid_example(
        "hydrostatic-tank.json",
        &[
            "solver.mechanics.incompressible.tolerance=2",
            "solver.mechanics.incompressible.max_iterations=0",
            "materials.water.viscosity.newtonian=-1",
        ],
    );
    for path in [
        "solver.mechanics.incompressible.tolerance",
        "solver.mechanics.incompressible.max_iterations",
        "materials.water.viscosity.newtonian",
    ] {
        assert!(
            issues.iter().any(|i| i.starts_with(path)),
            "{path}: {issues:?}"
        );
    }
}
