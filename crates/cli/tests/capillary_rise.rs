//! Contact angles on obstacles (`obstacles[].contact_angle`): capillary rise between two
//! plate obstacles dipping into a pool against Jurin's height, and the refusals.

mod common;

use common::{comparison, invalid_example, load_example, run};

#[test]
fn liquid_rises_between_plates_to_jurins_height() {
    // examples/capillary-rise.json: plates 5 mm thick (10 cells), 3 mm apart (6 cells),
    // θ = 30°, σ = 0.07 N/m, μ = 0.3 Pa·s, 0.8 s. Jurin: 2σ cos θ/(ρ g w) = 4.12 mm.
    // Measured: 4.0625 mm, −1.4% (60°: −6.9%). Bound 3%. With plates 3 mm thick (6 cells)
    // the same run read 0.13% at 30° but −45% at 60°: a node inside a plate thinner than
    // about 8 cells takes the image across the nearer face, and past the middle that is
    // the far side's (air in docs/wip/meniscus-obstacle-plates.json, whose thin plates
    // fail). With the pool's level measured within 3 mm of the plates' outer menisci the
    // 30° run read 3.7 mm, so the pool reaches 12 mm beyond each plate.
    let m = run(&load_example("capillary-rise.json", &[]));
    let error = m.error.expect("error");
    assert!(error < 0.03, "rise error {error}: {m:?}");
    let (rise, jurin) = comparison(&m, "jurin_rise");
    assert!((jurin - 4.121e-3).abs() < 1e-5, "Jurin's height {jurin}");
    assert!(rise > 0.0, "{rise}");
}

#[test]
fn obstacle_contact_angles_are_checked() {
    for angle in ["0", "180", "-10", "200"] {
        let issues = invalid_example(
            "capillary-rise.json",
            &[&format!("obstacles[1].contact_angle={angle}")],
        );
        assert!(
            issues
                .iter()
                .any(|i| i.starts_with("obstacles[1].contact_angle")),
            "{angle}: {issues:?}"
        );
    }
    let issues = invalid_example(
        "capillary-rise.json",
        &["materials.water.surface_tension=0", "reference=null"],
    );
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("obstacles[0].contact_angle")),
        "{issues:?}"
    );
}

#[test]
fn liquid_particles_inside_an_obstacle_are_refused() {
    // Without the holes the pool's particles fill the plates' lower ends (320 in each).
    let issues = invalid_example("capillary-rise.json", &["bodies[0].holes=[]"]);
    for k in 0..2 {
        assert!(
            issues.iter().any(|i| i.starts_with("bodies[0]")
                && i.contains("320 of its liquid particles")
                && i.contains(&format!("obstacles[{k}]"))),
            "{issues:?}"
        );
    }
}

#[test]
fn the_capillary_rise_reference_is_checked() {
    for (overrides, path) in [
        (
            &["reference.contact_angle=90"][..],
            "reference.contact_angle",
        ),
        (&["reference.pool=[[0.018,0.019]]"][..], "reference.pool[0]"),
        (&["reference.pool=[]"][..], "reference.pool"),
        (&["reference.plates=[0.018,0.015]"][..], "reference.plates"),
        (&["solver.gravity=[0,0]"][..], "reference.up"),
        (&["reference.density=0"][..], "reference.density"),
    ] {
        let issues = invalid_example("capillary-rise.json", overrides);
        assert!(
            issues.iter().any(|i| i.starts_with(path)),
            "{overrides:?}: {issues:?}"
        );
    }
}
