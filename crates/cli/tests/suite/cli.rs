//! End-to-end tests of the `mpm` binary: validation errors, runs, stops, export, schema.

use crate::common;

use common::*;
use serde_json::json;
use std::path::Path;

/// A bad scene: `mpm validate` and `mpm run` both exit 2, name `path`, and write nothing.
fn assert_rejected(scene: serde_json::Value, path: &str) {
    let dir = tempfile::tempdir().unwrap();
    let file = write_scene(dir.path(), "bad.json", &scene);
    let f = file.to_str().unwrap();
    for args in [vec!["validate", f], vec!["run", f, "--out", "out"]] {
        let o = mpm(&args, dir.path());
        let t = text(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {t}");
        assert!(t.contains(path), "{args:?}: expected `{path}` in: {t}");
    }
    assert!(
        !dir.path().join("out").exists(),
        "nothing may be written for a bad scene"
    );
}

#[test]
fn invalid_scenes_are_rejected_with_json_paths() {
    let mut s = bar_json();
    s["solver"]["colour"] = json!("blue");
    assert_rejected(s, "solver");

    let mut s = bar_json();
    s["solver"]["end_time"] = json!("long");
    assert_rejected(s, "solver.end_time");

    let mut s = bar_json();
    s["materials"]["bar"]["density"] = json!(-1.0);
    assert_rejected(s, "materials.bar.density");

    let mut s = bar_json();
    s["materials"]["bar"]["poisson_ratio"] = json!(0.5);
    assert_rejected(s, "materials.bar.poisson_ratio");

    let mut s = bar_json();
    s["materials"]["bar"]["stiffness"] = json!(1.0);
    assert_rejected(s, "materials.bar");

    let mut s = bar_json();
    s["materials"]["bar"]["type"] = json!("jelly");
    assert_rejected(s, "materials.bar.type");

    let mut s = bar_json();
    s["bodies"][0]["shape"]["box"]["max"] = json!([3.0, 0.2]);
    assert_rejected(s, "bodies[0].shape");

    let mut s = bar_json();
    s["bodies"][0]["shape"] = json!({"sphere": {"center": [0.5, 0.1], "radius": 0.001}});
    assert_rejected(s, "bodies[0].shape");

    let mut s = bar_json();
    s["bodies"][0]["material"] = json!("steel");
    assert_rejected(s, "bodies[0].material");

    let mut s = bar_json();
    s["domain"]["min"] = json!([0.0, 0.0, 0.0]);
    assert_rejected(s, "domain.min");

    let mut s = bar_json();
    s["output"]["fields"] = json!(["x", "temperature"]);
    assert_rejected(s, "output.fields[1]");

    let mut s = bar_json();
    s["solver"]["mls"] = json!(true);
    s["solver"]["kernel"] = json!("linear");
    assert_rejected(s, "solver.mls");

    // XPIC: an order out of range, and the modes it does not work with.
    let mut s = bar_json();
    s["solver"]["transfer"] = json!("xpic");
    s["solver"]["xpic_order"] = json!(0);
    assert_rejected(s, "solver.xpic_order");
    let mut s = bar_json();
    s["solver"]["transfer"] = json!("xpic");
    s["solver"]["mechanics"] = json!({"implicit": {"form": "dynamic"}});
    assert_rejected(s, "solver.transfer");
    let contact = std::fs::read_to_string(example("two-disks-contact.json")).unwrap();
    let mut s: serde_json::Value = serde_json::from_str(&contact).unwrap();
    s["solver"]["transfer"] = json!("xpic");
    assert_rejected(s, "solver.transfer");

    // A fixed time step far above the stable one is refused before anything runs.
    let mut s = bar_json();
    s["solver"]["dt"] = json!(0.1);
    assert_rejected(s, "solver.dt");

    // Not JSON at all.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.json"), "{ \"name\": ").unwrap();
    let o = mpm(&["validate", "bad.json"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("not valid JSON"), "{}", text(&o));
}

#[test]
fn run_writes_a_store_and_export_writes_vtk() {
    let dir = tempfile::tempdir().unwrap();
    let scene = example("vibrating-bar.json");
    let o = mpm(
        &["run", scene.to_str().unwrap(), "--out", "res"],
        dir.path(),
    );
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("outcome        Finished"), "{t}");
    assert!(t.contains("error "), "{t}");
    let store_path = dir.path().join("res/vibrating-bar.zarr");
    let store = mpm_io::ResultStore::open(&store_path).unwrap();
    let times = store.times().unwrap();
    assert_eq!(times.len(), 41);
    assert!((times[40] - 0.4).abs() < 1e-12);
    let (shape, x) = store.frame("x", 40).unwrap();
    assert_eq!(shape, vec![320, 2]);
    assert_eq!(x.len(), 640);
    let (shape, _) = store.frame("stress", 0).unwrap();
    assert_eq!(shape, vec![320, 2, 2]);
    let metrics = &store.attributes()["metrics"];
    assert_eq!(metrics["outcome"], "finished");
    assert!(metrics["error"].as_f64().unwrap() < 0.01);
    assert!(metrics["particle_steps_per_second"].as_f64().unwrap() > 0.0);

    let o = mpm(
        &["export", "res/vibrating-bar.zarr", "--vtk", "vtk"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", text(&o));
    let pvd = std::fs::read_to_string(dir.path().join("vtk/vibrating-bar.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 41);
    let vtu = std::fs::read_to_string(dir.path().join("vtk/vibrating-bar_00040.vtu")).unwrap();
    assert!(vtu.contains("NumberOfPoints=\"320\"") && vtu.contains("Name=\"stress\""));
    // Components per particle (σ is 2×2 in 2D, v has 2), not per frame.
    assert!(
        vtu.contains("Name=\"stress\" NumberOfComponents=\"4\"")
            && vtu.contains("Name=\"v\" NumberOfComponents=\"2\""),
        "{}",
        &vtu[vtu.find("<PointData>").unwrap_or(0)..][..400]
    );
}

#[test]
fn an_unstable_run_stops_with_a_diagnostic_and_keeps_its_frames() {
    let dir = tempfile::tempdir().unwrap();
    let scene = example("vibrating-bar.json");
    // Five times the stable step, allowed explicitly: the run must stop, not write NaN.
    let o = mpm(
        &[
            "run",
            scene.to_str().unwrap(),
            "--out",
            "res",
            "--set",
            "solver.dt=0.0125",
            "--set",
            "solver.max_cfl=10",
            "--set",
            "output.frames=10",
        ],
        dir.path(),
    );
    let t = text(&o);
    assert_eq!(o.status.code(), Some(3), "{t}");
    assert!(
        t.contains("outcome        Stopped") && t.contains("diagnostic     step"),
        "{t}"
    );
    let store = mpm_io::ResultStore::open(dir.path().join("res/vibrating-bar.zarr")).unwrap();
    let metrics = &store.attributes()["metrics"];
    assert_eq!(metrics["outcome"], "stopped");
    let diagnostic = &metrics["diagnostic"];
    assert!(diagnostic["step"].as_u64().unwrap() > 0, "{diagnostic}");
    let frames = store.frame_count().unwrap();
    assert!((1..11).contains(&frames), "{frames} frames");
    for frame in 0..frames {
        let (_, v) = store.frame("v", frame).unwrap();
        assert!(v.iter().all(|x| x.is_finite()), "frame {frame} holds NaN");
    }
}

#[test]
fn bodies_can_come_from_csv_and_from_a_result_store() {
    let dir = tempfile::tempdir().unwrap();
    // CSV: the bar's particles at cell 0.05, two per cell.
    let mut csv = String::from("x,y\n");
    for i in 0..40 {
        for j in 0..8 {
            csv += &format!(
                "{},{}\n",
                0.0125 + 0.025 * i as f64,
                0.0125 + 0.025 * j as f64
            );
        }
    }
    std::fs::write(dir.path().join("bar.csv"), csv).unwrap();
    let mut s = bar_json();
    s["bodies"][0]["shape"] = json!({"file": {"path": "bar.csv", "format": "csv"}});
    s["bodies"][0]["particles_per_cell"] = json!(2);
    let path = write_scene(dir.path(), "csv.json", &s);
    let m = run(&load(&path, &[]));
    assert_eq!(m.particles, 320);
    assert!(m.error.unwrap() < 0.01, "{:?}", m.error);

    // Zarr: start a body from the last frame of a run.
    let o = mpm(
        &[
            "run",
            "csv.json",
            "--out",
            "res",
            "--set",
            "solver.end_time=0.01",
            "-q",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", text(&o));
    let mut s = bar_json();
    s["bodies"][0]["shape"] = json!({"file": {"path": "res/vibrating-bar.zarr", "format": "zarr"}});
    let path = write_scene(dir.path(), "zarr.json", &s);
    let v = load(&path, &[]);
    assert_eq!(v.particle_count(), 320);

    // A broken CSV names the file problem at the body's path.
    std::fs::write(dir.path().join("bad.csv"), "x,y\n0.1,oops\n").unwrap();
    let mut s = bar_json();
    s["bodies"][0]["shape"] = json!({"file": {"path": "bad.csv", "format": "csv"}});
    let path = write_scene(dir.path(), "badcsv.json", &s);
    let o = mpm(&["validate", path.to_str().unwrap()], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o).contains("bodies[0].shape.file.path"),
        "{}",
        text(&o)
    );
}

#[test]
fn checked_in_scene_schema_is_current() {
    let schema = mpm_cli::scene_schema(&mpm_cli::default_registry());
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../api/scene.schema.json");
    let current = serde_json::to_string_pretty(&schema).unwrap() + "\n";
    let stored = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        stored == current,
        "api/scene.schema.json is stale: regenerate it with `cargo run -p mpm-cli -- schema > api/scene.schema.json`"
    );
}

#[test]
fn every_example_scene_validates() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "json") {
            let o = mpm(&["validate", path.to_str().unwrap()], &dir);
            assert!(o.status.success(), "{}: {}", path.display(), text(&o));
            count += 1;
        }
    }
    assert!(count >= 4);
}

#[test]
fn study_writes_table_and_plot_with_the_observed_order() {
    let dir = tempfile::tempdir().unwrap();
    let scene = example("vibrating-bar.json");
    let o = mpm(
        &[
            "study",
            scene.to_str().unwrap(),
            "--vary",
            "cell_size=0.1,0.05,0.025",
            "--vary",
            "transfer=pic,apic",
            "--vary",
            "solver.mls=false,true",
            "--parallel",
            "2",
            "--out",
            "st",
        ],
        dir.path(),
    );
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    let csv = std::fs::read_to_string(dir.path().join("st/study.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(
        lines[0],
        "cell_size,transfer,solver.mls,outcome,wall_seconds,steps,particles,error,energy_drift,message"
    );
    assert_eq!(lines.len(), 1 + 12);
    // MLS with PIC is refused by validation; the study records it and goes on.
    assert_eq!(csv.matches(",invalid,").count(), 3, "{csv}");
    assert_eq!(csv.matches(",finished,").count(), 9, "{csv}");
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("st/study.json")).unwrap())
            .unwrap();
    assert_eq!(rows.as_array().unwrap().len(), 12);
    assert!(
        t.contains("observed order 2.0") || t.contains("observed order 1.9"),
        "{t}"
    );
    let png = std::fs::read(dir.path().join("st/study.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let svg = std::fs::read_to_string(dir.path().join("st/study.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("Pareto front"));
}

#[test]
fn stability_suite_outcomes_do_not_change() {
    let dir = tempfile::tempdir().unwrap();
    let o = mpm(&["check-stability", "--json", "stability.json"], dir.path());
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("stability.json")).unwrap())
            .unwrap();
    let results = results.as_array().unwrap();
    assert!(results.len() >= 13);
    for r in results {
        assert_eq!(r["pass"], true, "{r}");
        // Nothing that finished or stopped may have produced NaN in its figures.
        if r["outcome"] != "refused" {
            assert!(r["min_det_f"].as_f64().is_some_and(f64::is_finite), "{r}");
        }
    }
    assert!(t.contains("0 failed"), "{t}");
}

#[test]
fn references_are_listed_under_the_crate_that_owns_them_and_checked_by_it() {
    let dir = tempfile::tempdir().unwrap();
    let o = mpm(&["plugins"], dir.path());
    assert!(o.status.success(), "{}", text(&o));
    let listing = String::from_utf8_lossy(&o.stdout).to_string();
    // The reference a plugin registers is listed in that plugin's block: the lines after
    // `owner: description` that are indented.
    let block = |owner: &str| -> String {
        let mut lines = listing
            .lines()
            .skip_while(|l| !l.starts_with(&format!("{owner}: ")));
        lines
            .next()
            .unwrap_or_else(|| panic!("no `{owner}` block in:\n{listing}"));
        lines
            .take_while(|l| l.starts_with("  "))
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert!(
        block("johnson-cook").contains("reference `taylor_bar`"),
        "{listing}"
    );
    assert!(
        block("thermal").contains("reference `slab_temperature`"),
        "{listing}"
    );
    assert!(
        block("phase-change").contains("reference `stefan`"),
        "{listing}"
    );
    assert!(
        block("underfill").contains("reference `capillary_filling`"),
        "{listing}"
    );
    assert!(
        block("core").contains("reference `vibrating_bar`"),
        "{listing}"
    );

    // An unknown reference type, and a bad value the owning plugin checks, name their paths.
    let mut s = bar_json();
    s["reference"]["type"] = json!("tuning_fork");
    assert_rejected(s, "reference.type");
    let mut s = bar_json();
    s["reference"] = json!({
        "type": "taylor_bar", "axis": 1, "wall": 0.0, "center": [0.0],
        "final_length": -1.0, "mushroom_diameter": 0.01, "source": "test"
    });
    assert_rejected(s, "reference.final_length");
}
