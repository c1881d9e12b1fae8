//! Contact angles on obstacles (`obstacles[].contact_angle`): capillary rise between two
//! plate obstacles dipping into a pool against Jurin's height, and the refusals.

use crate::common;

use common::{comparison, invalid_example, load_example, run, run_fields};

#[test]
fn liquid_rises_between_plates_to_jurins_height() {
    // examples/capillary-rise.json: plates 5 mm thick (10 cells), 3 mm apart (6 cells),
    // θ = 30°, σ = 0.07 N/m, μ = 0.3 Pa·s, with `volume_correction`, 0.8 s. Jurin:
    // 2σ cos θ/(ρ g w) = 4.12 mm. Measured 4.063 mm, −1.39%. Bound 3%. With the pool's
    // level measured within 3 mm of the plates' outer menisci the run read 3.7 mm, so the
    // pool reaches 12 mm beyond each plate.
    //
    // Without the correction the column's liquid thins (the particles drift apart, as in
    // the capillary fill): by volume 3.840 mm (−6.8%) where its free surface stands
    // 4.029 mm (−2.2%). The reference read that run 4.0625 mm (−1.4%) until its pool
    // stretches took particles by their share across their inner ends (stop 84): counted
    // whole by centre, a 2 mm stretch gained or lost a whole column of particles as the
    // pool's lattice sheared, and the pool read 0.2 mm low.
    //
    // The figure depends on where the cell faces fall: the column's top sits on one, and
    // with the pool started 0.125 / 0.25 / 0.375 mm higher the rise reads +4.8% / −1.5% /
    // −1.5% (README, "The 60° rise"). The bound holds this alignment's figure.
    let scene = load_example("capillary-rise.json", &[]);
    let (m, frames) = run_fields(&scene, &["x"]);
    let error = m.error.expect("error");
    assert!(error < 0.03, "rise error {error}: {m:?}");
    let (rise, jurin) = comparison(&m, "jurin_rise");
    assert!((jurin - 4.121e-3).abs() < 1e-5, "Jurin's height {jurin}");
    assert!(rise > 0.0, "{rise}");
    // The free surface's own rise (mean top of the column over the pool's): 4.043 mm,
    // −1.85%. Without the correction it moved between 3.83 and 4.00 mm over 0.9–1.6 s as
    // the pool sloshed (README). Bound 5%.
    let (surface, _) = comparison(&m, "surface_rise");
    assert!(
        (surface / jurin - 1.0).abs() < 0.05,
        "surface rise {surface} vs {jurin}"
    );
    // The source once put energy in by stirring the liquid: counting each particle whole
    // in its cell, it answered the count's jumps as particles crossed cell faces with
    // currents of mm/s that never settled, drift +1.69 at 0.8 s and the column 3.74 mm by
    // volume. Counted with tent weights (stop 83): +0.071 (+0.19 without the correction).
    // Bound 0.3.
    assert!(
        m.energy_drift.abs() < 0.3,
        "energy drift {} with the correction",
        m.energy_drift
    );
    // A particle that strayed into a plate's cell once made it a liquid cell short of
    // volume, which the correction then filled: 99 particles inside the plates at 0.8 s
    // (stop 81), 4 without the correction. Solid cells take no source: at most 2 over
    // 0.8 s (stop 82); since the tent-weighted count (stop 83) 5 at 0.8 s (6 at 0.2 s), all
    // within 0.3 mm of the plates' lower inner corners. Bound 8 (was 5 at 0.3 s): the
    // dozens of stop 81 are what it guards against.
    let x = frames.values[0].last().expect("a frame");
    let inside = x
        .chunks(2)
        .filter(|p| {
            p[1] > 0.004 && ((p[0] > 0.012 && p[0] < 0.017) || (p[0] > 0.020 && p[0] < 0.025))
        })
        .count();
    assert!(inside <= 8, "{inside} particles inside the plates");
}

/// Overrides that make the capillary-rise plates `cells` cells (0.5 mm) thick, keeping
/// their inner faces 3 mm apart, and set the contact angle `angle` on both.
fn thin_plates(cells: u32, angle: u32) -> Vec<String> {
    let (left, right) = (
        0.017 - 5e-4 * f64::from(cells),
        0.02 + 5e-4 * f64::from(cells),
    );
    vec![
        format!("obstacles[0].shape.box.min=[{left},0.004]"),
        format!("bodies[0].holes[0].box.min=[{left},0.004]"),
        format!("obstacles[1].shape.box.max=[{right},0.02]"),
        format!("bodies[0].holes[1].box.max=[{right},0.02]"),
        format!("obstacles[0].contact_angle={angle}"),
        format!("obstacles[1].contact_angle={angle}"),
        format!("reference.contact_angle={angle}"),
    ]
}

#[test]
fn liquid_rises_between_thin_plates_to_jurins_height() {
    // Plates 6 cells thick at 60°, wetted inside up to the column and outside up to the
    // pool's meniscus: a node inside takes the wetter of the images across its two faces.
    // Run without the example's `volume_correction`, as measured when the wetter image
    // came in: −1.1% by volume since the pool's stretches ramp (stop 84; 0.29% counted
    // whole; −44% with the nearer face's image alone; at 30° +1.9%, 4.3% counted whole;
    // plates 4 cells thick, counted whole: 0.9% at 30° and 21% at 60°, against 13% and
    // 65%). Bound 3%. At 60° the free surface stands 14.4% short here, 15.4% with thick
    // plates, and with the correction the volume reads −21%: the 60° shortfall is open
    // (README), and this test is of the thin plates' image, against the thick plates'.
    let mut overrides = thin_plates(6, 60);
    overrides.push(r#"solver.mechanics={"incompressible":{}}"#.into());
    let overrides: Vec<&str> = overrides.iter().map(String::as_str).collect();
    let m = run(&load_example("capillary-rise.json", &overrides));
    let error = m.error.expect("error");
    assert!(error < 0.03, "rise error {error}: {m:?}");
}

#[test]
fn a_meniscus_between_thin_plates_wetted_on_one_side_holds_its_pressure() {
    // examples/liquid-meniscus.json with its wetting walls replaced by box obstacles 4
    // cells thick, dry outside: 30°, pressure below the meniscus against Young-Laplace.
    // Measured 1.1% (60°: 1.7%; 118% and 127% with the nearer face's image alone, which
    // past a plate's middle is the dry side). At 90° the surface stays within 0.41 mm/s
    // of rest (7.8 mm/s before). Bound 3%.
    let m = run(&load_example(
        "liquid-meniscus.json",
        &[
            "domain.max=[0.014,0.02]",
            r#"domain.walls=[{"sides":["y-"],"condition":"slip"}]"#,
            "bodies[0].shape.box.min=[0.002,0.0]",
            "bodies[0].shape.box.max=[0.012,0.01]",
            r#"obstacles=[{"shape":{"box":{"min":[0.0,0.0],"max":[0.002,0.02]}},"condition":"slip","contact_angle":30.0},{"shape":{"box":{"min":[0.012,0.0],"max":[0.014,0.02]}},"condition":"slip","contact_angle":30.0}]"#,
            "reference.plates=[0.002,0.012]",
        ],
    ));
    let error = m.error.expect("error");
    assert!(error < 0.03, "pressure error {error}: {m:?}");
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
