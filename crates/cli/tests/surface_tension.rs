//! Surface tension of liquid particles (`liquid.surface_tension`): the drop at rest against
//! Laplace's law, and the refusals.

mod common;

use common::{comparison, invalid_example, load_example, run};

#[test]
fn a_drop_at_rest_carries_the_laplace_pressure() {
    // Radius 10 cells, 0.05 s (1.2 capillary times): pressure within R/2 of the centre
    // 0.58% (relative L2) from σ/R = 14 Pa, largest speed 7.1e-4 m/s (1.0e-4 of σ/μ), the
    // farthest particle 5.01 mm from the centre (R = 5 mm). Bounds: 1.5%, 1e-3 of σ/μ, 2%.
    let m = run(&load_example("liquid-drop.json", &[]));
    assert_eq!(m.simulated_time, 0.05, "{m:?}");
    let error = m.error.expect("error");
    assert!(error < 0.015, "pressure error {error}");
    let (pressure, exact) = comparison(&m, "laplace_pressure");
    assert!(
        (pressure / exact - 1.0).abs() < 0.015,
        "{pressure} vs {exact}"
    );
    let (speed, capillary) = comparison(&m, "spurious_speed");
    assert!(speed < 1e-3 * capillary, "spurious speed {speed}");
    let (radius, r) = comparison(&m, "radius");
    assert!((radius / r - 1.0).abs() < 0.02, "radius {radius}");
}

#[test]
fn walls_are_not_free_surfaces_for_surface_tension() {
    // The hydrostatic tank (slip walls on three sides) with surface tension and quadratic
    // B-splines: the flat surface has no curvature, walls included, because the colour is
    // mirrored across them. Measured: pressure 1.5e-15 from ρgh, largest speed 1e-14 m/s;
    // before the mirror the walls looked like free surfaces: 2.8e-2 m/s, and the liquid
    // drooped 4 mm at the walls. Bounds 1e-6.
    let m = run(&load_example(
        "hydrostatic-tank.json",
        &[
            "materials.water.surface_tension=0.07",
            "solver.kernel=\"bspline2\"",
        ],
    ));
    let error = m.error.expect("error");
    assert!(error < 1e-6, "pressure error {error}");
    let (speed, _) = comparison(&m, "spurious_speed");
    assert!(speed < 1e-6, "spurious speed {speed}");
}

#[test]
fn a_coarse_drop_is_within_five_percent() {
    // Radius 5 cells: 4.9% (the curvature of a surface 5 cells round, from a colour field
    // smoothed over about two cells). Bound 7%.
    let m = run(&load_example(
        "liquid-drop.json",
        &["domain.cell_size=0.001"],
    ));
    let error = m.error.expect("error");
    assert!(error < 0.07, "pressure error {error}");
}

#[test]
fn surface_tension_is_checked() {
    let issues = invalid_example("liquid-drop.json", &["materials.water.surface_tension=-1"]);
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("materials.water.surface_tension")),
        "{issues:?}"
    );
    let issues = invalid_example(
        "liquid-drop.json",
        &[
            r#"materials.oil={"type": "liquid", "density": 900, "viscosity": {"newtonian": 0.1}, "surface_tension": 0.03}"#,
        ],
    );
    assert!(
        issues
            .iter()
            .any(|i| i.contains("surface_tension") && i.contains("one surface tension per scene")),
        "{issues:?}"
    );
    let issues = invalid_example(
        "liquid-drop-oscillation.json",
        &[r#"bodies[0].velocity={"affine": {"center": [0, 0], "gradient": [1, 2, 3]}}"#],
    );
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("bodies[0].velocity.affine.gradient")),
        "{issues:?}"
    );
    let issues = invalid_example(
        "liquid-drop.json",
        &[r#"solver.mechanics={"incompressible": {"viscosity": "implicit"}}"#],
    );
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("solver.mechanics.incompressible.viscosity")),
        "{issues:?}"
    );
    let issues = invalid_example("liquid-drop.json", &["reference.radius=0"]);
    assert!(
        issues.iter().any(|i| i.starts_with("reference.radius")),
        "{issues:?}"
    );
}

#[test]
fn a_drop_oscillates_with_the_lamb_period_and_converges() {
    // Second mode of a 2D drop, 0.25 s (2.3 periods): the period is 7.1% longer than
    // Lamb's inviscid 0.1084 s at 10 cells per radius and 13.1% at 5 (first order: the
    // Laplace pressure sits on the nodes of the surface cells, not on the surface). At 20
    // cells it is 4.0% (README), with half periods scattered by ±10%. Bounds: 10% at 10
    // cells, and the error must fall from 5 to 10 cells.
    let fine = run(&load_example("liquid-drop-oscillation.json", &[]));
    let coarse = run(&load_example(
        "liquid-drop-oscillation.json",
        &["domain.cell_size=0.001"],
    ));
    let (fine_error, coarse_error) = (fine.error.expect("error"), coarse.error.expect("error"));
    assert!(fine_error < 0.10, "period error {fine_error}");
    assert!(
        fine_error < coarse_error,
        "no convergence: {fine_error} at 10 cells, {coarse_error} at 5"
    );
    let (period, exact) = comparison(&fine, "period");
    assert!(period > exact, "{period} vs {exact}");
}
