//! Surface tension of liquid particles (`liquid.surface_tension`): the drop at rest against
//! Laplace's law, the oscillating drop against Lamb, the meniscus between walls with a
//! static contact angle against Young–Laplace, a drop spreading or beading up on a wall to
//! its contact angle, and the refusals.

use crate::common;

use common::{comparison, invalid_example, load_example, run};

#[test]
fn a_drop_at_rest_carries_the_laplace_pressure() {
    // Radius 10 cells, 0.05 s (1.2 capillary times): pressure within R/2 of the centre
    // 0.78% (relative L2) from σ/R = 14 Pa, largest speed 4.0e-4 m/s (0.6e-4 of σ/μ), the
    // farthest particle 4.998 mm from the centre (R = 5 mm). Bounds: 1.5%, 1e-3 of σ/μ, 2%.
    // (With the flat 5-node band mean before the triangular one: 0.58%, 7.1e-4 m/s, 5.01 mm.)
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
    // Radius 5 cells: 1.5% (the curvature of a surface 5 cells round, from a colour field
    // smoothed over about two cells; 4.9% with the flat 5-node band mean). Bound 7%.
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
    let issues = invalid_example("liquid-drop.json", &["reference.radius=0"]);
    assert!(
        issues.iter().any(|i| i.starts_with("reference.radius")),
        "{issues:?}"
    );
}

#[test]
fn a_drop_oscillates_with_the_lamb_period() {
    // Second mode of a 2D drop, 0.25 s (2.3 periods): the period is 8.4% longer than
    // Lamb's inviscid 0.1084 s at 10 cells per radius, 5.9% at 5 and 3.5% at 20 (README;
    // 92 s, too long for here). Not monotone at these resolutions since the band mean is
    // triangular (flat, it was 13.1%, 7.1%, 4.0%; the flat mean let surface waves 2.5–5
    // cells long grow and broke a meniscus up): this test asserted that the error falls
    // from 5 to 10 cells and no longer does. Bounds: 10% at 5 and at 10 cells, and the
    // period longer than Lamb's (the pressure sits on the surface cells' nodes).
    let fine = run(&load_example("liquid-drop-oscillation.json", &[]));
    let coarse = run(&load_example(
        "liquid-drop-oscillation.json",
        &["domain.cell_size=0.001"],
    ));
    let (fine_error, coarse_error) = (fine.error.expect("error"), coarse.error.expect("error"));
    assert!(fine_error < 0.10, "period error {fine_error} at 10 cells");
    assert!(
        coarse_error < 0.10,
        "period error {coarse_error} at 5 cells"
    );
    let (period, exact) = comparison(&fine, "period");
    assert!(period > exact, "{period} vs {exact}");
}

#[test]
fn a_meniscus_meets_the_walls_at_the_contact_angle() {
    // Water between walls 10 mm apart, θ = 30°, no gravity, 0.3 s from a flat start
    // (examples/liquid-meniscus.json). Young–Laplace: −2σ cos θ/w = −12.12 Pa below the
    // surface, an arc 2.89 mm deep. Measured at 20 cells across: pressure 3.1% (relative
    // L2), depth 3.07 mm (6.3%); at 10 cells 4.0% and 19.4%; at 40 cells (README) 1.9% and
    // 1.0%. Without the contact angle the walls are mirrors and the surface stays flat.
    // Bounds: 5% and 10% at 20 cells, 6% at 10 cells, and the depth error must fall.
    let fine = run(&load_example("liquid-meniscus.json", &[]));
    let error = fine.error.expect("error");
    assert!(error < 0.05, "pressure error {error}");
    let (depth, exact) = comparison(&fine, "meniscus_depth");
    assert!(
        (depth / exact - 1.0).abs() < 0.10,
        "depth {depth} vs {exact}"
    );
    let coarse = run(&load_example(
        "liquid-meniscus.json",
        &["domain.cell_size=0.001"],
    ));
    assert!(coarse.error.expect("error") < 0.06, "{coarse:?}");
    let (coarse_depth, _) = comparison(&coarse, "meniscus_depth");
    assert!(
        (depth / exact - 1.0).abs() < (coarse_depth / exact - 1.0).abs(),
        "depth {depth} at 20 cells, {coarse_depth} at 10, exact {exact}"
    );
}

#[test]
fn a_non_wetting_meniscus_bulges() {
    // θ = 150° on both walls: the surface bulges up (depth −2.89 mm) and the liquid below
    // carries +12.12 Pa. Measured at 20 cells: pressure 2.0%, depth −3.37 mm (16.6%: the
    // non-wetting arc is the less resolved one). Bounds 5% and 25%.
    let m = run(&load_example(
        "liquid-meniscus.json",
        &[
            "domain.walls[0].contact_angle=150",
            "reference.contact_angle=150",
        ],
    ));
    let error = m.error.expect("error");
    assert!(error < 0.05, "pressure error {error}");
    let (depth, exact) = comparison(&m, "meniscus_depth");
    assert!(exact < 0.0 && depth < 0.0, "{depth} vs {exact}");
    assert!(
        (depth / exact - 1.0).abs() < 0.25,
        "depth {depth} vs {exact}"
    );
}

#[test]
fn a_drop_spreads_on_a_wall_to_its_contact_angle() {
    // A 10 mm × 5 mm block on a slip floor at 60°, no gravity, 0.5 s, 20 cells under the
    // cap's base (examples/sessile-drop.json): at rest it is the circular cap of the same
    // area meeting the floor at θ. Measured: centroid height −0.14% (1.8473 against
    // 1.8498 mm), the angle of the cap with that centroid 59.86°, the core's pressure
    // −0.61% from σ/R = 7.76 Pa. At 120° (beading up from the same block): +0.70%, 121.01°,
    // −1.65%. Bounds: 2%, 3° and 3%; the drop must also have left the block's centroid
    // (2.5 mm) by far more than the bound.
    for (angle, spread) in [(60.0, true), (120.0, false)] {
        let m = run(&load_example(
            "sessile-drop.json",
            &[
                &format!("domain.walls[0].contact_angle={angle}"),
                &format!("reference.contact_angle={angle}"),
            ],
        ));
        let error = m.error.expect("error");
        assert!(error < 0.02, "{angle}°: centroid error {error}");
        let (height, _) = comparison(&m, "centroid_height");
        assert_eq!(height < 0.0025 * 0.9, spread, "{angle}°: centroid {height}");
        assert!(
            (height / 0.0025 - 1.0).abs() > 0.1,
            "{angle}°: centroid {height}"
        );
        let (measured, exact) = comparison(&m, "contact_angle");
        assert!((measured - exact).abs() < 3.0, "{measured}° vs {exact}°");
        let (pressure, laplace) = comparison(&m, "laplace_pressure");
        assert!(
            (pressure / laplace - 1.0).abs() < 0.03,
            "{angle}°: {pressure} vs {laplace} Pa"
        );
    }
    // The floor an obstacle box 10 cells deep instead of the domain's wall (the obstacles'
    // contact angle, which held bodies share): 0.19%, 60.19°, −0.12%.
    let m = run(&load_example(
        "sessile-drop.json",
        &[
            "domain.min=[0,-0.005]",
            "domain.walls=[]",
            r#"obstacles=[{"shape":{"box":{"min":[-0.001,-0.006],"max":[0.041,0.0]}},"condition":"slip","contact_angle":60}]"#,
        ],
    ));
    assert!(m.error.expect("error") < 0.02, "{m:?}");
    let (measured, _) = comparison(&m, "contact_angle");
    assert!((measured - 60.0).abs() < 3.0, "obstacle floor: {measured}°");
    let issues = invalid_example("sessile-drop.json", &["reference.contact_angle=180"]);
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("reference.contact_angle")),
        "{issues:?}"
    );
}

#[test]
fn contact_angles_are_checked() {
    for angle in ["0", "180", "-10", "200"] {
        let issues = invalid_example(
            "liquid-meniscus.json",
            &[&format!("domain.walls[0].contact_angle={angle}")],
        );
        assert!(
            issues
                .iter()
                .any(|i| i.starts_with("domain.walls[0].contact_angle")),
            "{angle}: {issues:?}"
        );
    }
    let issues = invalid_example(
        "liquid-meniscus.json",
        &["materials.water.surface_tension=0", "reference=null"],
    );
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("domain.walls[0].contact_angle")),
        "{issues:?}"
    );
    let issues = invalid_example("liquid-meniscus.json", &["reference.contact_angle=90"]);
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("reference.contact_angle")),
        "{issues:?}"
    );
}
