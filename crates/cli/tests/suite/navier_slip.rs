//! Navier slip on walls (`"condition": {"navier": {"slip_length": b}}`): the Poiseuille
//! start-up between slipping plates against its series solution (`poiseuille_slip.rs`),
//! with explicit and implicit viscosity, and where such a wall is refused.

use crate::common;

use common::{invalid_example, load_example, run};

/// The example's plates with Navier slip of length `b` (m), and the reference told so.
fn navier_plates(b: f64) -> [String; 2] {
    [
        format!(
            r#"domain.walls=[{{"sides": ["y-", "y+"], "condition": {{"navier": {{"slip_length": {b}}}}}}}]"#
        ),
        format!("reference.slip_length={b}"),
    ]
}

#[test]
fn a_channel_between_navier_plates_follows_the_slip_series() {
    // b = 2 mm = 2 cells (the plates slip at 55% of the mean flow at steady state), 10
    // cells across, 3 decay times: RMS error 0.0125 of the steady centre-line velocity
    // (0.0074 between stick plates, whose ghosts fold exactly; Navier ghosts are not
    // folded, boundary/mod.rs). Bound 0.02. The plates' drag takes more of the work than
    // the shear does (6b/h = 1.2 times it at steady state), so the energy balance holds
    // only with it booked: drift −0.084 of the largest kinetic energy (−0.117 between
    // stick plates). Bound: the stick channel's 0.15 (energy_ledger.rs).
    let [walls, reference] = navier_plates(0.002);
    let m = run(&load_example(
        "liquid-poiseuille.json",
        &[&walls, &reference],
    ));
    assert_eq!(m.simulated_time, 0.03, "{m:?}");
    let error = m.error.expect("error");
    assert!(error < 0.02, "velocity error {error}");
    assert!(m.energy_drift.abs() < 0.15, "drift {}", m.energy_drift);
}

#[test]
fn implicit_viscosity_holds_a_navier_plate_inside_its_solve() {
    // At the explicit viscous step (1.25e-4 s) as the stick test in liquid.rs: RMS error
    // 0.0080 with b = 2 mm, 0.0041 with b = 5 mm, and 0.0081 with b = 1 µm, where the
    // plate holds as a stick plate does (0.0090). Bound: the stick test's 0.012.
    for b in [0.002, 1e-6] {
        let [walls, reference] = navier_plates(b);
        let m = run(&load_example(
            "liquid-poiseuille.json",
            &[
                &walls,
                &reference,
                r#"solver.mechanics={"incompressible": {"viscosity": "implicit"}}"#,
                "solver.dt=1.25e-4",
            ],
        ));
        assert_eq!((m.simulated_time, m.steps), (0.03, 240), "{m:?}");
        let error = m.error.expect("error");
        assert!(error < 0.012, "b = {b}: velocity error {error}");
    }
}

#[test]
fn navier_plate_obstacles_hold_the_channel_by_their_drag() {
    // The same channel between two box obstacles (their faces on node planes, the domain
    // grown by 2 mm across, no walls): obstacles have no ghosts, only the drag on their
    // surface nodes. Implicit viscosity at 1.25e-4 s, b = 2 mm: RMS error 0.0135 (0.0111
    // at b = 0.5 mm; explicit viscosity 0.0129 at 2 mm, 0.0138 at 0.5 mm). Bound 0.02.
    let navier = r#"{"navier": {"slip_length": 0.002}}"#;
    let obstacles = format!(
        r#"obstacles=[{{"shape": {{"box": {{"min": [-0.01, -0.01], "max": [0.1, 0.0]}}}}, "condition": {navier}}},
                     {{"shape": {{"box": {{"min": [-0.01, 0.01], "max": [0.1, 0.03]}}}}, "condition": {navier}}}]"#
    );
    let m = run(&load_example(
        "liquid-poiseuille.json",
        &[
            "domain.min=[0, -0.002]",
            "domain.max=[0.082, 0.012]",
            "domain.walls=[]",
            &obstacles,
            "reference.slip_length=0.002",
            r#"solver.mechanics={"incompressible": {"viscosity": "implicit"}}"#,
            "solver.dt=1.25e-4",
        ],
    ));
    assert_eq!(m.simulated_time, 0.03, "{m:?}");
    let error = m.error.expect("error");
    assert!(error < 0.02, "velocity error {error}");
}

#[test]
fn navier_slip_is_refused_where_no_liquid_solve_reads_it() {
    let issues = invalid_example(
        "vibrating-bar.json",
        &[r#"domain.walls=[{"sides": ["y-"], "condition": {"navier": {"slip_length": 1e-3}}}]"#],
    );
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("domain.walls[0].condition") && i.contains("incompressible")),
        "{issues:?}"
    );
    let [walls, _] = navier_plates(0.0);
    let issues = invalid_example("liquid-poiseuille.json", &[&walls]);
    assert!(
        issues.iter().any(
            |i| i.starts_with("domain.walls[0].condition.navier.slip_length") && i.contains("> 0")
        ),
        "{issues:?}"
    );
}
