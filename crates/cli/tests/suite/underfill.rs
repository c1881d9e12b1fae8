//! Underfill flow end to end: capillary filling against the parallel-plate law in both
//! modes, plane Poiseuille start-up against its series solution, the bump-array trend,
//! voids in the result store, and input errors.

use crate::common;

use common::{load_example, run, run_to_store};
use mpm_core::output::{Metrics, Outcome};

fn finished(name: &str, overrides: &[&str]) -> Metrics {
    let m = run(&load_example(name, overrides));
    assert_eq!(
        m.outcome,
        Some(Outcome::Finished),
        "{name} {overrides:?}: {:?}",
        m.diagnostic
    );
    m
}

fn fill_time(m: &Metrics) -> f64 {
    *m.physics
        .get("underfill.fill_time")
        .expect("the gap filled")
}

/// Gap-averaged capillary filling of a 10 mm gap (examples/capillary-gap.json). Measured:
/// front error 8.9e-4, fill time 69.24 s against 69.28 s. Bounds: the issue's 5% on both,
/// and 1% on the front (ten times the measured error).
#[test]
fn gap_averaged_filling_follows_the_parallel_plate_law() {
    let m = finished("capillary-gap.json", &[]);
    let error = m.error.expect("reference");
    assert!(error < 1e-2, "{error}");
    let c = m
        .comparisons
        .iter()
        .find(|c| c.quantity == "fill_time")
        .expect("fill time compared");
    assert!(c.relative_difference.abs() < 0.05, "{c:?}");
    assert!(
        (fill_time(&m) - 69.28).abs() < 0.05 * 69.28,
        "{:?}",
        m.physics
    );
    // Liquid volume is conserved to within what overflows into no room.
    assert!(
        m.physics["underfill.lost_volume_fraction"] < 5e-3,
        "{:?}",
        m.physics
    );
}

/// Capillary filling resolved across the gap (Stokes with inertia, 10 cells across), on a
/// 1 mm channel. Measured: front error 2.4% on the 2 mm example. Bound: the issue's 5%.
#[test]
fn cross_section_filling_follows_the_parallel_plate_law() {
    let m = finished(
        "capillary-cross-section.json",
        &[
            "domain.max=[0.001,5e-5]",
            r#"bodies[0].shape={"box":{"min":[0,0],"max":[0.001,5e-5]}}"#,
            "reference.length=0.001",
            "solver.end_time=0.8",
            "output.frames=16",
        ],
    );
    let error = m.error.expect("reference");
    assert!(error < 0.05, "{error}");
    // 3μL²/(hσcosθ) = 0.693 s for the 1 mm channel.
    assert!(
        (fill_time(&m) - 0.6928).abs() < 0.05 * 0.6928,
        "{:?}",
        m.physics
    );
}

/// Plane Poiseuille start-up from rest against the series solution (implicit viscosity
/// and pressure at 100 steps per viscous time ρh²/μ). Measured 4.4e-3; bound 1e-2.
#[test]
fn poiseuille_start_up_matches_the_series_solution() {
    let m = finished("poiseuille-startup.json", &[]);
    let error = m.error.expect("reference");
    assert!(error < 1e-2, "{error}");
}

/// The step is not limited by the viscosity: at an underfill viscosity of 3 Pa·s in 5 µm
/// cells an explicit viscous step ρdx²/(4μ) would be 2e-9 s; the run takes steps of
/// 1e-4 s (50 000 times longer) and still matches the series solution.
#[test]
fn viscous_flow_takes_steps_far_beyond_the_explicit_limit() {
    let m = finished(
        "poiseuille-startup.json",
        &[
            r#"physics.underfill.fluid.viscosity={"newtonian":3.0}"#,
            "reference.viscosity=3.0",
            "solver.dt=1e-4",
            "solver.end_time=0.005",
            "output.frames=5",
        ],
    );
    assert!(m.steps <= 55, "{}", m.steps);
    // Steady within the first step (viscous time 8e-7 s): the error is the steady
    // discretisation error only.
    assert!(m.error.unwrap() < 1e-2, "{:?}", m.error);
}

/// Fill time through a square bump array (D = 100 µm) falls as the pitch grows and tends
/// to the parallel-plate law (3μL²/(hσcosθ) = 2.77 s for 2 mm) for sparse bumps.
#[test]
fn bump_arrays_slow_the_fill_less_as_the_pitch_grows() {
    let strip = |pitch: Option<f64>| {
        let mut o = vec![
            "domain.max=[0.002,0.0012]".to_string(),
            r#"bodies[0].shape={"box":{"min":[0,0],"max":[0.002,0.0012]}}"#.to_string(),
            "domain.cell_size=2e-5".to_string(),
            "solver.end_time=12".to_string(),
            "output.frames=4".to_string(),
            "reference.length=0.002".to_string(),
        ];
        if let Some(p) = pitch {
            o.push(format!(
                r#"physics.underfill.bumps={{"diameter":1e-4,"pitch":{p},"min":[0,0],"max":[0.002,0.0012]}}"#
            ));
        }
        let refs: Vec<&str> = o.iter().map(|s| s.as_str()).collect();
        fill_time(&finished("capillary-gap.json", &refs))
    };
    let dense = strip(Some(2e-4));
    let medium = strip(Some(3e-4));
    let sparse = strip(Some(6e-4));
    let plain = strip(None);
    assert!(
        dense > medium && medium > sparse && sparse > plain,
        "{dense} {medium} {sparse} {plain}"
    );
    assert!((plain - 2.771).abs() < 0.05 * 2.771, "{plain}");
    assert!(sparse < 1.15 * plain, "{sparse} vs {plain}");
}

/// The gap-averaged closure's permeability ratio K/K0 = φ·t0/t (fill time t with the
/// bumps' wetting off, so the capillary pressure is the plates'; t0 from the plate law)
/// against the resolved 3D bump cell's (docs/wip/bump-cell-150.json and README, "The bump
/// closure"): 0.383 at 150 µm pitch and 0.801 at 300 µm. Measured on this 2 mm strip:
/// 0.340 and 0.758 (−11%, −5.4%; on the README's 4 mm strip with the old drag coefficient
/// 0.63: 0.157 and 0.680).
/// Bound 15%: the lattice's staircased bumps lose up to 12% of potential flow.
#[test]
fn the_bump_closure_matches_the_resolved_cell() {
    for (pitch, resolved) in [(1.5e-4, 0.383), (3e-4, 0.801)] {
        let bumps = format!(
            r#"physics.underfill.bumps={{"diameter":1e-4,"pitch":{pitch},"min":[0,0],"max":[0.002,0.0012],"wetting":false}}"#
        );
        let t = fill_time(&finished(
            "capillary-gap.json",
            &[
                "domain.max=[0.002,0.0012]",
                r#"bodies[0].shape={"box":{"min":[0,0],"max":[0.002,0.0012]}}"#,
                "domain.cell_size=2e-5",
                "solver.end_time=20",
                "output.frames=4",
                "reference.length=0.002",
                &bumps,
            ],
        ));
        // The plate law's fill time over 2 mm: 3μL²/(hσcosθ) with the example's liquid.
        let t0 = 11.08 / 4.0;
        let open = 1.0 - std::f64::consts::PI * 1e-8 / (4.0 * pitch * pitch);
        let ratio = open * t0 / t;
        assert!(
            (ratio / resolved - 1.0).abs() < 0.15,
            "pitch {pitch}: K/K0 {ratio} against the resolved {resolved} (fill {t} s)"
        );
    }
}

/// A die dispensed on two edges with a bump-free margin: the liquid races along the
/// margins and encloses air; the void is in the metrics and in `/tables/underfill_voids`
/// of the result store, and the fill history ends filled.
#[test]
fn edge_racing_traps_a_void_that_the_store_reports() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("fc.zarr");
    let scene = load_example(
        "flip-chip-underfill.json",
        &[
            "domain.max=[0.004,0.004]",
            r#"bodies[0].shape={"box":{"min":[0,0],"max":[0.004,0.004]}}"#,
            "domain.cell_size=5e-5",
            r#"physics.underfill.bumps={"diameter":1e-4,"pitch":2.5e-4,"pattern":"staggered","min":[0.0005,0.0005],"max":[0.0035,0.0035]}"#,
            "solver.end_time=12",
            "output.frames=4",
        ],
    );
    let m = run_to_store(&scene, &store);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    assert!(m.physics["underfill.voids"] >= 1.0, "{:?}", m.physics);
    assert!(fill_time(&m) > 0.0);
    let voids = &m.tables["underfill_voids"];
    let area = voids.columns.iter().position(|c| c == "area").unwrap();
    let closed = voids
        .columns
        .iter()
        .position(|c| c == "closed_time")
        .unwrap();
    let big = voids
        .rows
        .iter()
        .find(|r| r[area] > 1e-7)
        .expect("a void above 0.1 mm²");
    assert!(big[closed] > 0.0 && big[closed] < fill_time(&m), "{big:?}");
    let reader = mpm_io::ResultStore::open(&store).unwrap();
    let (columns, rows) = reader
        .table("underfill_voids")
        .unwrap()
        .expect("table in the store");
    assert_eq!(columns, voids.columns);
    assert_eq!(rows.len(), voids.rows.len());
    let (_, history) = reader
        .table("underfill_fill")
        .unwrap()
        .expect("fill history");
    assert!(history.len() > 10);
    let last = history.last().unwrap();
    assert!(last[1] > 0.5 && last[1] < 1.0, "{last:?}");
}

/// Bad input is named by JSON path.
#[test]
fn underfill_input_errors_name_their_path() {
    let issues = |overrides: &[&str]| common::invalid_example("capillary-gap.json", overrides);
    let has = |lines: &[String], needle: &str| lines.iter().any(|l| l.contains(needle));
    let e = issues(&["physics.underfill.fluid.contact_angle=95"]);
    assert!(has(&e, "physics.underfill.fluid.contact_angle"), "{e:?}");
    let e = issues(&["physics.underfill.gap=-1"]);
    assert!(has(&e, "physics.underfill.gap"), "{e:?}");
    let e = issues(&[
        r#"physics.underfill.fluid.viscosity={"cross":{"zero_shear":1,"critical_stress":0,"index":0.5}}"#,
    ]);
    assert!(
        has(
            &e,
            "physics.underfill.fluid.viscosity.cross.critical_stress"
        ),
        "{e:?}"
    );
    let e = issues(&[
        r#"physics.underfill.bumps={"diameter":2e-4,"pitch":1e-4,"min":[0,0],"max":[0.01,0.001]}"#,
    ]);
    assert!(has(&e, "physics.underfill.bumps.pitch"), "{e:?}");
    let e = issues(&[r#"physics.underfill.vents=["x-"]"#]);
    assert!(has(&e, "physics.underfill.vents[0]"), "{e:?}");
    // A vent region is a cross-section's; capillary-gap is gap-averaged.
    let e = issues(&[r#"physics.underfill.vent_regions=[{"min":[0,0],"max":[1e-3,1e-3]}]"#]);
    assert!(has(&e, "physics.underfill.vent_regions[0]"), "{e:?}");
    let e = common::invalid_example(
        "underfill-process-2d.json",
        &[r#"physics.underfill.vent_regions=[{"min":[0,0],"max":[0,1e-3]}]"#],
    );
    assert!(has(&e, "physics.underfill.vent_regions[0].max[0]"), "{e:?}");
    let e = issues(&[r#"solver.mechanics="dynamic""#]);
    assert!(has(&e, "solver.mechanics"), "{e:?}");
    let e = issues(&["physics.underfill.reservoirs=[]"]);
    assert!(has(&e, "physics.underfill.reservoirs"), "{e:?}");
}

/// A flow-only scene names each property of its liquid once: the gap's material is the
/// `liquid` (density, viscosity, surface tension) and `fluid` adds the contact angle; the
/// section's own values win where given, and a gap of any other material must give them.
#[test]
fn the_fluid_comes_from_the_gaps_liquid() {
    // examples/capillary-gap.json takes everything but the angle from its liquid; the fill
    // time is the same as with the properties in the section (69.18 s both ways).
    let from_material = common::run(&common::load_example("capillary-gap.json", &[]));
    let in_section = common::run(&common::load_example(
        "capillary-gap.json",
        &[
            r#"physics.underfill.fluid={"density":1100,"viscosity":{"newtonian":0.3},"surface_tension":0.03,"contact_angle":30}"#,
            "solver.end_time=10",
        ],
    ));
    let short = common::run(&common::load_example(
        "capillary-gap.json",
        &["solver.end_time=10"],
    ));
    assert_eq!(short.error, in_section.error);
    assert!(from_material.error.expect("error") < 0.01);
    // The section's viscosity wins over the liquid's.
    let thicker = common::run(&common::load_example(
        "capillary-gap.json",
        &[
            r#"physics.underfill.fluid.viscosity={"newtonian":3.0}"#,
            "solver.end_time=10",
        ],
    ));
    assert_ne!(thicker.error, short.error);
    // A gap of another material must give them in the section.
    let e = common::invalid_example(
        "capillary-gap.json",
        &[
            r#"materials.underfill={"type":"linear_elastic","density":1100,"youngs_modulus":3e9,"poisson_ratio":0.35}"#,
        ],
    );
    for field in ["density", "viscosity", "surface_tension"] {
        assert!(
            e.iter()
                .any(|l| l.starts_with(&format!("physics.underfill.fluid.{field}"))),
            "{field}: {e:?}"
        );
    }
}
