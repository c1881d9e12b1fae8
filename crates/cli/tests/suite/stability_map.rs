//! `mpm check-stability --map` end to end: a small map of the vibrating bar (three rows,
//! two CFL factors) through the binary: the outcomes measured, one JSON record per run,
//! the picture decoded; and the errors for bad options and an unwritable picture folder.

use crate::common;

use common::*;
use serde_json::Value;

/// The record of `row` at CFL factor `cfl`.
fn cell<'a>(cells: &'a [Value], row: &str, cfl: f64) -> &'a Value {
    cells
        .iter()
        .find(|c| c["row"] == row && c["cfl"].as_f64() == Some(cfl))
        .unwrap_or_else(|| panic!("no record of {row} at CFL {cfl}"))
}

#[test]
fn a_small_bar_map_measures_where_explicit_steps_blow_up() {
    let dir = tempfile::tempdir().unwrap();
    let o = mpm(
        &[
            "check-stability",
            "--map",
            "--only",
            "bar",
            "--rows",
            "apic/usl/bspline2,pic/usl/linear,implicit/bspline2",
            "--cfl",
            "0.5,2",
            "--json",
            "map.json",
            "--map-dir",
            "pictures",
        ],
        dir.path(),
    );
    let t = text(&o);
    assert_eq!(o.status.code(), Some(0), "{t}");
    assert!(t.contains("| apic/usl/bspline2 |"), "{t}");
    let cells: Vec<Value> =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("map.json")).unwrap())
            .unwrap();
    // One record per run: three rows, two factors, one case.
    assert_eq!(cells.len(), 6, "{cells:#?}");
    assert!(cells.iter().all(|c| c["case"] == "bar"), "{cells:#?}");

    // APIC at half the stable step keeps the energy to 1% (measured -3.4e-3) and the bar's
    // motion to 1% of the analytic solution.
    let apic = cell(&cells, "apic/usl/bspline2", 0.5);
    assert_eq!(apic["outcome"], "finished", "{apic}");
    assert!(
        apic["energy_drift"].as_f64().unwrap().abs() < 1e-2,
        "{apic}"
    );
    assert!(apic["reference_error"].as_f64().unwrap() < 1e-2, "{apic}");
    // At twice the stable step explicit MPM runs away within a few steps, whatever the
    // transfer: the run's energy check stops it (energy grew 0.95 at step 5).
    for row in ["apic/usl/bspline2", "pic/usl/linear"] {
        let c = cell(&cells, row, 2.0);
        assert_eq!(c["outcome"], "blow_up", "{c}");
        assert!(c["energy_drift"].as_f64().unwrap() > 0.5, "{c}");
        assert!(c["steps"].as_u64().unwrap() < 20, "{c}");
    }
    // PIC loses energy where it finishes: 17% at half the stable step.
    let pic = cell(&cells, "pic/usl/linear", 0.5);
    assert_eq!(pic["outcome"], "finished", "{pic}");
    assert!(pic["energy_drift"].as_f64().unwrap() < -0.05, "{pic}");
    // Implicit Newmark (average acceleration) is unconditionally stable: CFL 2 finishes and
    // keeps the energy (measured -3.1e-3).
    let implicit = cell(&cells, "implicit/bspline2", 2.0);
    assert_eq!(implicit["outcome"], "finished", "{implicit}");
    assert!(
        implicit["energy_drift"].as_f64().unwrap().abs() < 1e-2,
        "{implicit}"
    );

    // The picture: a grid with red (blown up) and green (finished) cells.
    let (w, h, pixels) = decode_png(&dir.path().join("pictures/bar.png"));
    assert!(w >= 400 && h >= 150, "{w} x {h}");
    let count = |rgb: [u8; 3]| pixels.iter().filter(|p| **p == rgb).count();
    assert!(count([215, 48, 39]) > 1000, "no blow-up cells drawn");
    assert!(
        count([26, 152, 80]) + count([102, 189, 99]) > 1000,
        "no finished cells drawn"
    );
}

#[test]
fn bad_map_options_exit_2_and_an_unwritable_picture_folder_1() {
    let dir = tempfile::tempdir().unwrap();
    for (args, needle) in [
        (&["--cfl", "0.5,-1"][..], "must be a number in (0, 100]"),
        (&["--cfl", "NaN"][..], "must be a number in (0, 100]"),
        (&["--cfl", "fast"][..], "invalid"),
        (&["--rows", "rk4"][..], "names no row of the map"),
        (&["--only", "cube"][..], "no map case has that in its name"),
    ] {
        let mut all = vec!["check-stability", "--map"];
        all.extend_from_slice(args);
        let o = mpm(&all, dir.path());
        let t = text(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {t}");
        assert!(t.contains(needle), "{args:?}: {t}");
    }
    // A picture folder that cannot be made is an operational failure, before any run.
    std::fs::write(dir.path().join("taken"), "a file").unwrap();
    let o = mpm(
        &["check-stability", "--map", "--map-dir", "taken/maps"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("taken/maps"), "{}", text(&o));
    // The map's options need --map.
    let o = mpm(&["check-stability", "--cfl", "1"], dir.path());
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(!dir.path().join("stability-map").exists());
}
