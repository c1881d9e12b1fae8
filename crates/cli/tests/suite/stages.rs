//! Staged scenes: stages run one after another on the same particles, each its own scene
//! (a merge patch of the one before), taking over the state the stage before left.

use crate::common;

use common::{example, mpm, text, write_scene};
use mpm_io::ResultStore;
use serde_json::{Value, json};

fn scene(name: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(example(name)).unwrap()).unwrap()
}

/// Runs `scene` with `mpm run --json` in `dir`; returns the metrics.
fn run(dir: &std::path::Path, file: &str, scene: &Value) -> Value {
    let path = write_scene(dir, file, scene);
    let out = mpm(
        &["run", path.to_str().unwrap(), "--out", "r", "-q", "--json"],
        dir,
    );
    assert!(out.status.success(), "{}", text(&out));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn stages_that_change_nothing_follow_the_unstaged_run() {
    // The vibrating bar to 0.8 s in one run and in two stages of 0.4 s with the same frame
    // times: the stages hand over positions, velocities, F, stress, APIC's matrices and the
    // clock. Equal to round-off, not bit for bit: the second stage spaces its frames from
    // its own start (0.4 + k·0.04 is not always k'·0.04 in floating point), and the time
    // step lands on those frame times.
    let dir = tempfile::tempdir().unwrap();
    let mut plain = scene("vibrating-bar.json");
    plain["solver"]["end_time"] = json!(0.8);
    plain["output"]["frames"] = json!(20);
    let whole = run(dir.path(), "plain.json", &plain);
    let mut staged = plain.clone();
    staged["name"] = json!("bar-staged");
    staged["output"]["frames"] = json!(10);
    staged["stages"] = json!([
        {"name": "first", "changes": {"solver": {"end_time": 0.4}}},
        {"name": "second", "changes": {"solver": {"end_time": 0.8}}}
    ]);
    let metrics = run(dir.path(), "staged.json", &staged);
    assert_eq!(metrics["steps"], whole["steps"]);
    let stages = metrics["stages"].as_array().unwrap();
    assert_eq!(stages.len(), 2);
    assert_eq!(stages[0]["name"], "first");
    assert_eq!(stages[1]["start_time"], 0.4);
    assert_eq!(stages[1]["end_time"], 0.8);
    let steps: u64 = stages.iter().map(|s| s["steps"].as_u64().unwrap()).sum();
    assert_eq!(steps, whole["steps"].as_u64().unwrap());

    let a = ResultStore::open(dir.path().join("r/vibrating-bar.zarr")).unwrap();
    let b = ResultStore::open(dir.path().join("r/bar-staged.zarr")).unwrap();
    assert_eq!(b.stages(), ["0-first", "1-second"]);
    let (first, second) = (
        ResultStore::open_stage(dir.path().join("r/bar-staged.zarr"), Some("first")).unwrap(),
        b.stage("second").unwrap(),
    );
    assert_eq!(first.frame_count().unwrap(), 11);
    assert_eq!(second.times().unwrap()[0], 0.4);
    for (store, frame, whole_frame) in [(&first, 10, 10), (&second, 0, 10), (&second, 10, 20)] {
        let (_, x) = store.frame("x", frame).unwrap();
        let (_, y) = a.frame("x", whole_frame).unwrap();
        let worst = x
            .iter()
            .zip(&y)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max);
        assert!(
            worst < 1e-12,
            "frame {whole_frame}: positions differ by {worst:e}"
        );
    }
}

/// The bimaterial strip heated by 100 K, in stages.
fn strip_stages(stages: Value) -> Value {
    let mut s = scene("bimaterial-strip.json");
    s["name"] = json!("strip-staged");
    s["stages"] = stages;
    s
}

#[test]
fn a_stage_takes_over_the_temperature_and_the_bent_shape() {
    // Stage `hot` holds the strip at 400 K with mechanics off; stage `bend` solves the
    // static equilibrium and names 300 K as the thermal section's initial temperature: the
    // temperature carried over (400 K) must win, or the strip would not bend, and the
    // stress is taken afresh at the hand-over (a mechanics-off stage never updates it), so
    // `bend` is the one-step run exactly. Stage `hold` changes nothing: it is the second
    // step of a two-step run (a second static step moves the curvature by 3e-4 relative:
    // the particles are mapped onto the grid at their bent positions).
    let dir = tempfile::tempdir().unwrap();
    let single = run(dir.path(), "single.json", &scene("bimaterial-strip.json"));
    let mut two_steps = scene("bimaterial-strip.json");
    two_steps["name"] = json!("two-steps");
    two_steps["solver"]["end_time"] = json!(2.0);
    two_steps["output"]["frames"] = json!(2);
    let double = run(dir.path(), "double.json", &two_steps);
    let cold = json!({"steel": {"initial_temperature": 300.0},
                      "aluminium": {"initial_temperature": 300.0}});
    let staged = strip_stages(json!([
        {"name": "hot", "changes": {"solver": {"end_time": 1.0, "mechanics": "off"}}},
        {"name": "bend", "changes": {"solver": {"end_time": 2.0,
            "mechanics": {"implicit": {"form": "static"}}},
            "physics": {"thermal": {"materials": cold}}}},
        {"name": "hold", "changes": {"solver": {"end_time": 3.0}}}
    ]));
    let metrics = run(dir.path(), "staged.json", &staged);
    let stages = metrics["stages"].as_array().unwrap();
    assert!(
        stages.iter().all(|s| s["outcome"] == "finished"),
        "{metrics}"
    );
    for (stage, alone) in [(&stages[1], &single), (&stages[2], &double)] {
        // The strip's curvature error against Timoshenko, as the unstaged run has it.
        let (error, expected) = (
            stage["error"].as_f64().unwrap(),
            alone["error"].as_f64().unwrap(),
        );
        assert!(
            (error - expected).abs() < 1e-12,
            "{}: error {error} against the unstaged run's {expected}",
            stage["name"]
        );
    }
}

#[test]
fn a_physics_a_later_stage_adds_starts_from_its_initial_state() {
    // Stage `cold` has no thermal physics (nothing loads the strip); stage `heat` adds it:
    // its temperature field did not exist, so the operator sets its initial 400 K, and the
    // strip bends as the one-stage run does.
    let dir = tempfile::tempdir().unwrap();
    let single = run(dir.path(), "single.json", &scene("bimaterial-strip.json"));
    let thermal = scene("bimaterial-strip.json")["physics"].clone();
    let staged = strip_stages(json!([
        {"name": "cold", "changes": {"solver": {"end_time": 1.0}, "physics": {"thermal": null}}},
        {"name": "heat", "changes": {"solver": {"end_time": 2.0}, "physics": thermal}}
    ]));
    let metrics = run(dir.path(), "staged.json", &staged);
    let stages = metrics["stages"].as_array().unwrap();
    assert_eq!(stages.len(), 2, "{metrics}");
    assert!(
        stages.iter().all(|s| s["outcome"] == "finished"),
        "{metrics}"
    );
    let error = metrics["error"].as_f64().unwrap();
    assert!(
        (error - single["error"].as_f64().unwrap()).abs() < 1e-9,
        "{error} vs {}",
        single["error"]
    );
    let store = dir.path().join("r/strip-staged.zarr");
    let cold = ResultStore::open_stage(&store, Some("cold")).unwrap();
    assert!(!cold.fields().unwrap().contains(&"temperature".to_string()));
}

#[test]
fn staged_stores_render_and_export_by_stage() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = scene("vibrating-bar.json");
    s["name"] = json!("bar-staged");
    s["output"]["frames"] = json!(2);
    s["stages"] = json!([
        {"name": "a", "changes": {"solver": {"end_time": 0.1}}},
        {"name": "b", "changes": {"solver": {"end_time": 0.2}}}
    ]);
    run(dir.path(), "staged.json", &s);
    let out = mpm(
        &[
            "render",
            "r/bar-staged.zarr",
            "--field",
            "v",
            "--component",
            "0",
            "--stage",
            "a",
            "--out",
            "a.png",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out));
    assert!(dir.path().join("a.png").is_file());
    let out = mpm(&["export", "r/bar-staged.zarr", "--vtk", "vtk"], dir.path());
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        dir.path().join("vtk/bar-staged-1-b.pvd").is_file(),
        "{}",
        text(&out)
    );
    let out = mpm(
        &[
            "render",
            "r/bar-staged.zarr",
            "--field",
            "v",
            "--stage",
            "c",
            "--out",
            "c.png",
        ],
        dir.path(),
    );
    assert!(!out.status.success());
    assert!(text(&out).contains("no stage `c`"), "{}", text(&out));
}

#[test]
fn stage_problems_are_named_by_their_path() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            json!([{"name": "a", "changes": {"bodies": []}}]),
            "stages[0].changes.bodies: a stage may not change `bodies`",
        ),
        (
            json!([{"name": "a", "changes": {"solver": {"end_time": 0.2}}},
                   {"name": "b", "changes": {"solver": {"end_time": 0.1}}}]),
            "stages[1].changes.solver.end_time: the stage must end later than the previous",
        ),
        (
            json!([{"name": "a", "changes": {"solver": {"end_time": 0.2, "cfl": -1}}}]),
            "stages[0].changes.solver.cfl",
        ),
        (
            json!([{"name": "a b", "changes": {"solver": {"end_time": 0.2}}}]),
            "stages[0].name",
        ),
        (
            json!([{"name": "a", "changes": {"solver": {"end_time": 0.2}}},
                   {"name": "a", "changes": {"solver": {"end_time": 0.3}}}]),
            "stages[1].name: a stage named `a` comes earlier",
        ),
    ];
    for (stages, expected) in cases {
        let mut s = scene("vibrating-bar.json");
        s["stages"] = stages.clone();
        let path = write_scene(dir.path(), "bad.json", &s);
        let out = mpm(&["validate", path.to_str().unwrap()], dir.path());
        assert_eq!(out.status.code(), Some(2), "{stages}: {}", text(&out));
        assert!(text(&out).contains(expected), "{stages}: {}", text(&out));
    }
}

#[test]
fn progress_lines_count_each_stage_from_0_to_100_percent() {
    // `mpm run` without a terminal prints a line per tenth of the run; a staged run's
    // stages each count from 0 to 100% (before, the percentage was the time over the last
    // end time, so a stage after the first printed at most one line).
    let dir = tempfile::tempdir().unwrap();
    let scene = example("underfill-cure-cycles.json");
    let o = mpm(
        &["run", scene.to_str().unwrap(), "--out", "out"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let stderr = String::from_utf8_lossy(&o.stderr);
    let lines: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("progress"))
        .collect();
    let stages = 3;
    assert_eq!(lines.len(), 10 * stages, "{lines:#?}");
    let full = lines
        .iter()
        .filter(|l| l.starts_with("progress 100%"))
        .count();
    assert_eq!(full, stages, "{lines:#?}");
}
