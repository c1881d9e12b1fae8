//! Voids among liquid particles (`physics.liquid_voids`): air the liquid closes off from
//! every vent, in the `underfill_voids` table, checked against free fall and the geometry
//! of the air it encloses; and the section's refusals.

use crate::common;

use common::{
    PIT_3D, PIT_FILL_REGION, PIT_STAGES_FILL_THEN_REST, invalid_example, load_example, run,
    run_to_store,
};

/// The row of void `id` in the `underfill_voids` table, by column name.
fn void_row(m: &mpm_core::output::Metrics, id: usize) -> impl Fn(&str) -> f64 + '_ {
    let table = &m.tables["underfill_voids"];
    move |column: &str| {
        let k = table
            .columns
            .iter()
            .position(|c| c == column)
            .unwrap_or_else(|| panic!("no column {column}: {:?}", table.columns));
        table.rows[id][k]
    }
}

/// Free-fall time of the slab's lowest particles (0.125 mm above its base) into the cell
/// row above the blocks (6.5 mm): √(2 · 4.625 mm / g).
fn free_fall() -> f64 {
    (2.0 * 4.625e-3 / 9.81f64).sqrt()
}

#[test]
fn a_falling_slab_closes_the_pits_air_at_the_free_fall_time() {
    // examples/liquid-void-pit.json. Measured: closed at 30.0 ms against 30.7 ms (−2.2%:
    // the positions follow v_{n+1}, which runs ahead of ½gt² by ½g·t·dt ≈ 0.09 mm at the
    // 0.6 ms step, and the void is found at the end of a step); 24 mm², the whole pit
    // (8 × 12 cells); filled at 47.7 ms. Bounds: 3% on the time, the pit's area to
    // round-off.
    let m = run(&load_example("liquid-void-pit.json", &[]));
    let void = void_row(&m, 0);
    let closed = void("closed_time");
    assert!(
        (closed / free_fall() - 1.0).abs() < 0.03,
        "closed at {closed} s against {} s",
        free_fall()
    );
    assert!(
        (void("closed_area") - 24e-6).abs() < 1e-12,
        "{}",
        void("closed_area")
    );
    let filled = void("filled_time");
    assert!(filled > closed && filled < 0.08, "filled at {filled}");
    assert!(m.physics["underfill.voids"] >= 1.0, "{:?}", m.physics);
}

#[test]
fn the_pit_in_3d_closes_with_its_volume() {
    // The same, 4 mm (8 cells) deep between slip walls: the void holds the pit's
    // 4 × 6 × 4 mm = 96 mm³ and closes at the same time (measured 30.0 ms).
    let overrides: Vec<&str> = PIT_3D
        .into_iter()
        .chain(["solver.end_time=0.035"])
        .collect();
    let m = run(&load_example("liquid-void-pit.json", &overrides));
    let void = void_row(&m, 0);
    assert!(
        (void("closed_time") / free_fall() - 1.0).abs() < 0.03,
        "closed at {}",
        void("closed_time")
    );
    assert!(
        (void("closed_volume") - 96e-9).abs() < 1e-15,
        "{}",
        void("closed_volume")
    );
    assert!((void("z") - 0.002).abs() < 1e-9, "{}", void("z"));
}

#[test]
fn a_bubble_at_rest_is_a_void_from_the_start() {
    // A pool with a 2 × 2 mm hole and nothing to move it (no gravity): the void closes at
    // time 0 with the hole's area and centre, and holds them.
    let m = run(&load_example(
        "liquid-void-pit.json",
        &[
            "obstacles=[]",
            "solver.gravity=[0,0]",
            r#"bodies[0].shape={"box":{"min":[0,0],"max":[0.02,0.01]}}"#,
            r#"bodies[0].holes=[{"box":{"min":[0.009,0.004],"max":[0.011,0.006]}}]"#,
            "solver.end_time=0.01",
        ],
    ));
    let void = void_row(&m, 0);
    assert_eq!(void("closed_time"), 0.0);
    assert!((void("area") - 4e-6).abs() < 1e-12, "{}", void("area"));
    assert!((void("x") - 0.01).abs() < 1e-12 && (void("y") - 0.005).abs() < 1e-12);
    assert!(void("filled_time").is_nan());
    assert_eq!(m.tables["underfill_voids"].rows.len(), 1);
}

#[test]
fn air_beside_a_held_body_is_a_void_not_a_way_out_through_the_body() {
    // The bubble of the test above, with a held post two cells wide standing in it and
    // rising out of the pool: the post is a held obstacle whose cells are closed, not air,
    // so the bubble is still cut off from the open top, and its area is the hole's less
    // the post's 2 × 2 cells inside it (a die or bump beside a pocket must not vent it).
    let m = run(&load_example(
        "liquid-void-pit.json",
        &[
            "obstacles=[]",
            "solver.gravity=[0,0]",
            r#"materials.steel={"type":"linear_elastic","density":7800,"youngs_modulus":2e11,"poisson_ratio":0.3}"#,
            concat!(
                r#"bodies=[{"name":"pool","material":"water","shape":{"box":{"min":[0,0],"max":[0.02,0.01]}},"#,
                r#""holes":[{"box":{"min":[0.009,0.004],"max":[0.011,0.006]}},{"box":{"min":[0.0095,0.005],"max":[0.0105,0.014]}}]},"#,
                r#"{"name":"post","material":"steel","shape":{"box":{"min":[0.0095,0.005],"max":[0.0105,0.014]}},"held":{}}]"#
            ),
            "solver.end_time=0.005",
        ],
    ));
    let void = void_row(&m, 0);
    assert_eq!(void("closed_time"), 0.0);
    assert!((void("area") - 3e-6).abs() < 1e-12, "{}", void("area"));
    assert!(void("filled_time").is_nan());
    assert_eq!(m.tables["underfill_voids"].rows.len(), 1);
}

#[test]
fn the_pit_as_a_fill_region_is_filled_when_its_air_is_cut_off() {
    // The falling slab with the pit as the fill region: the pit's air has its way out
    // through the open top until the slab closes over it, so the fill time is the void's
    // closing time (the same labelling), while the pit holds no liquid yet; the water then
    // pours in and the filled fraction reaches 1 when the void is gone (47.7 ms).
    let m = run(&load_example("liquid-void-pit.json", &[PIT_FILL_REGION]));
    let void = void_row(&m, 0);
    let fill_time = m.physics["underfill.fill_time"];
    assert_eq!(fill_time, void("closed_time"));
    assert!(void("filled_time") > fill_time);
    assert!(
        (m.physics["underfill.fill_fraction"] - 1.0).abs() < 1e-12,
        "{:?}",
        m.physics
    );
    let history = &m.tables["underfill_fill"];
    assert_eq!(history.columns[1], "fill_fraction");
    let at_fill = history
        .rows
        .iter()
        .find(|r| r[0] == fill_time)
        .expect("a row at the fill time");
    assert!(at_fill[1] < 0.05, "filled {} when cut off", at_fill[1]);
    assert_eq!(at_fill[2], 0.0, "vented air left in the pit");
    assert!(history.rows.windows(2).all(|w| w[0][0] < w[1][0]));
}

#[test]
fn a_stage_that_ends_when_filled_hands_over_at_the_fill_time() {
    // `solver.end_when: "underfill.fill_time"` on the falling slab's first stage: the stage
    // ends at the end of the step at which the pit's air was cut off (its fill time), with
    // a last frame there (not at its end time, 0.08 s), and the second stage takes over from
    // that time to its own end.
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("pit.zarr");
    let m = run_to_store(
        &load_example(
            "liquid-void-pit.json",
            &[PIT_FILL_REGION, PIT_STAGES_FILL_THEN_REST],
        ),
        &store,
    );
    let [first, second] = &m.stages[..] else {
        panic!("{:?}", m.stages)
    };
    let fill_time = first.physics["underfill.fill_time"];
    assert!(
        fill_time > 0.02 && fill_time < 0.04,
        "filled at {fill_time}"
    );
    assert_eq!(first.end_time, fill_time);
    assert_eq!(second.start_time, fill_time);
    assert!(
        (second.end_time - 0.09).abs() < 1e-12,
        "{}",
        second.end_time
    );
    let times = mpm_io::ResultStore::open_stage(&store, Some("fill"))
        .unwrap()
        .times()
        .unwrap();
    assert_eq!(times.last().copied(), Some(fill_time), "{times:?}");
}

#[test]
fn the_liquid_voids_section_is_checked() {
    for (overrides, path) in [
        (
            &["physics.liquid_voids.materials=[\"oil\"]"][..],
            "physics.liquid_voids.materials[0]",
        ),
        (
            &["physics.liquid_voids.vents=[\"z-\"]"][..],
            "physics.liquid_voids.vents[0]",
        ),
        (
            &["physics.liquid_voids.min_void_cells=0"][..],
            "physics.liquid_voids.min_void_cells",
        ),
        (
            &["solver.mechanics=\"dynamic\""][..],
            "physics.liquid_voids",
        ),
        (
            &[r#"physics.liquid_voids.fill_region={"min":[0,0,0],"max":[1,1]}"#][..],
            "physics.liquid_voids.fill_region.min",
        ),
        (
            &[r#"physics.liquid_voids.fill_region={"min":[0.01,0],"max":[0.005,0.006]}"#][..],
            "physics.liquid_voids.fill_region.max",
        ),
        (
            &[r#"physics.liquid_voids.fill_region={"min":[1,1],"max":[2,2]}"#][..],
            "physics.liquid_voids.fill_region",
        ),
        (
            &[
                r#"physics.liquid_voids.fill_region={"min":[0,0],"max":[0.01,0.01],"vented_air_tolerance":1}"#,
            ][..],
            "physics.liquid_voids.fill_region.vented_air_tolerance",
        ),
    ] {
        let issues = invalid_example("liquid-void-pit.json", overrides);
        assert!(
            issues.iter().any(|i| i.starts_with(path)),
            "{overrides:?}: {issues:?}"
        );
    }
}
