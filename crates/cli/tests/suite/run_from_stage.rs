//! `mpm run SCENE --from STORE --stage NAME`: a staged scene that starts at one of its
//! stages from the state the stored run's stage before it ended with, so the later stages of
//! a process (cool-down, cycling) can be run again without the earlier ones.

use crate::common;

use common::{example, mpm, text, write_scene};
use mpm_io::ResultStore;
use serde_json::{Value, json};

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// The cure–cool–cycles chain with a checkpoint every 10 steps, so each stage keeps the
/// state it ended with.
fn chain() -> Value {
    let path = example("underfill-cure-cycles.json");
    let mut scene: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    scene["output"]["checkpoint"] = json!({ "steps": 10 });
    scene
}

/// Runs `scene` (written as `file`) into `out`, with `extra` arguments; the output.
fn run(
    dir: &std::path::Path,
    file: &str,
    scene: &Value,
    out: &str,
    extra: &[&str],
) -> std::process::Output {
    let file = write_scene(dir, file, scene);
    let mut args = vec!["run", file.to_str().unwrap(), "--out", out, "-q", "--json"];
    args.extend(extra);
    mpm(&args, dir)
}

#[test]
fn a_chain_started_at_a_later_stage_gives_the_whole_runs_frames() {
    let dir = tempfile::tempdir().unwrap();
    let scene = chain();
    let whole = run(dir.path(), "chain.json", &scene, "whole", &[]);
    assert!(whole.status.success(), "{}", text(&whole));
    let whole_metrics: Value = serde_json::from_slice(&whole.stdout).unwrap();
    let store = "whole/underfill-cure-cycles.zarr";
    // Each finished stage kept its end state.
    for group in ["0-cure", "1-cool", "2-cycles"] {
        let end = dir
            .path()
            .join(store)
            .join("stages")
            .join(group)
            .join("end_state");
        assert!(
            end.join("zarr.json").is_file(),
            "{group} keeps no end state"
        );
    }
    for (stage, later) in [
        ("cool", &["cool", "cycles"][..]),
        ("cycles", &["cycles"][..]),
    ] {
        let mut again = scene.clone();
        again["name"] = json!(format!("from-{stage}"));
        let out = run(
            dir.path(),
            "again.json",
            &again,
            "again",
            &["--from", store, "--stage", stage],
        );
        assert!(out.status.success(), "{stage}: {}", text(&out));
        let metrics: Value = serde_json::from_slice(&out.stdout).unwrap();
        // The metrics list every stage, the earlier ones as the stored run ran them.
        let names: Vec<&str> = metrics["stages"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s["name"].as_str().unwrap())
            .collect();
        assert_eq!(names, ["cure", "cool", "cycles"], "{stage}");
        assert_eq!(
            metrics["stages"][0], whole_metrics["stages"][0],
            "{stage}: cure's summary"
        );
        assert_eq!(metrics["steps"], whole_metrics["steps"], "{stage}: steps");
        let started_path = dir.path().join(format!("again/from-{stage}.zarr"));
        let started = || ResultStore::open(&started_path).unwrap();
        assert!(
            started().stage("cure").is_err(),
            "{stage}: the earlier stages' frames stay in the stored run"
        );
        for name in later {
            let (a, b) = (
                ResultStore::open(dir.path().join(store))
                    .unwrap()
                    .stage(name)
                    .unwrap(),
                started().stage(name).unwrap(),
            );
            assert_eq!(
                bits(&a.times().unwrap()),
                bits(&b.times().unwrap()),
                "{stage}: {name}'s frame times"
            );
            for frame in 0..a.frame_count().unwrap() {
                for field in ["x", "stress", "temperature", "cure"] {
                    assert_eq!(
                        bits(&a.frame(field, frame).unwrap().1),
                        bits(&b.frame(field, frame).unwrap().1),
                        "from {stage}: {name}'s {field} differs at frame {frame}"
                    );
                }
            }
        }
    }
    // A later stage changed: the cycles end after one cycle instead of three.
    let mut shorter = scene.clone();
    shorter["name"] = json!("shorter");
    let cycles = &mut shorter["stages"][2]["changes"];
    assert!(cycles.is_object());
    cycles["solver"]["end_time"] = json!(8400.0);
    let out = run(
        dir.path(),
        "shorter.json",
        &shorter,
        "again",
        &["--from", store, "--stage", "cycles"],
    );
    assert!(out.status.success(), "{}", text(&out));
    let (a, b) = (
        ResultStore::open(dir.path().join(store))
            .unwrap()
            .stage("cycles")
            .unwrap(),
        ResultStore::open(dir.path().join("again/shorter.zarr"))
            .unwrap()
            .stage("cycles")
            .unwrap(),
    );
    assert_eq!(
        bits(&a.frame("stress", 0).unwrap().1),
        bits(&b.frame("stress", 0).unwrap().1),
        "the changed stage starts from the stored cool-down's residual stress"
    );
    assert!(b.times().unwrap().last().unwrap() <= &8400.0);
}

#[test]
fn the_cure_starts_from_a_kept_gap_averaged_fill_as_in_one_run() {
    // The gap-averaged fill keeps state outside the particles, so it may not checkpoint;
    // `output.end_state` keeps what the cure takes over, and the cure's `remove` rule (the
    // voids) applies to it as in one run. Fill and 10 minutes of cure only.
    let dir = tempfile::tempdir().unwrap();
    let path = example("underfill-process-2d.json");
    let mut scene: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    scene["output"]["end_state"] = json!(true);
    scene["stages"].as_array_mut().unwrap().truncate(2);
    scene["stages"][1]["changes"]["solver"]["end_time"] = json!(600.0);
    let whole = run(dir.path(), "process.json", &scene, "whole", &[]);
    assert!(whole.status.success(), "{}", text(&whole));
    let store = "whole/underfill-process-2d.zarr";
    let mut again = scene.clone();
    again["name"] = json!("again");
    let out = run(
        dir.path(),
        "again.json",
        &again,
        "again",
        &["--from", store, "--stage", "cure"],
    );
    assert!(out.status.success(), "{}", text(&out));
    let metrics: Value = serde_json::from_slice(&out.stdout).unwrap();
    let removed = metrics["stages"][1]["removed_particles"].as_u64().unwrap();
    assert!(
        removed > 0,
        "the voids' particles were removed at the hand-over"
    );
    let (a, b) = (
        ResultStore::open(dir.path().join(store))
            .unwrap()
            .stage("cure")
            .unwrap(),
        ResultStore::open(dir.path().join("again/again.zarr"))
            .unwrap()
            .stage("cure")
            .unwrap(),
    );
    assert_eq!(bits(&a.times().unwrap()), bits(&b.times().unwrap()));
    for frame in 0..a.frame_count().unwrap() {
        for field in ["x", "stress", "temperature", "cure", "material"] {
            assert_eq!(
                bits(&a.frame(field, frame).unwrap().1),
                bits(&b.frame(field, frame).unwrap().1),
                "the cure's {field} differs at frame {frame}"
            );
        }
    }
}

#[test]
fn a_stage_start_is_refused_where_the_store_cannot_give_it() {
    let dir = tempfile::tempdir().unwrap();
    let scene = chain();
    let out = run(dir.path(), "chain.json", &scene, "s", &[]);
    assert!(out.status.success(), "{}", text(&out));
    let store = "s/underfill-cure-cycles.zarr";
    let refused = |scene: &Value, from: &str, stage: &str, expected: &str| {
        let mut scene = scene.clone();
        scene["name"] = json!("other");
        let out = run(
            dir.path(),
            "other.json",
            &scene,
            "o",
            &["--from", from, "--stage", stage],
        );
        assert_eq!(out.status.code(), Some(2), "{expected}: {}", text(&out));
        assert!(text(&out).contains(expected), "{expected}: {}", text(&out));
        assert!(
            !dir.path().join("o/other.zarr").exists(),
            "{expected}: a store was written"
        );
    };
    refused(
        &scene,
        store,
        "warm",
        "the scene's stages are cure, cool, cycles",
    );
    refused(&scene, store, "cure", "it is the scene's first stage");
    let mut changed = scene.clone();
    changed["stages"][0]["changes"]["solver"]["end_time"] = json!(2400.0);
    refused(
        &changed,
        store,
        "cycles",
        "stage `cure` runs with another `solver`",
    );
    let mut renamed = scene.clone();
    renamed["stages"][1]["name"] = json!("chill");
    refused(
        &renamed,
        store,
        "cycles",
        "stage 1 is `cool` in the stored run and `chill` here",
    );
    let mut other_bodies = scene.clone();
    other_bodies["bodies"][0]["particles_per_cell"] = json!(3);
    refused(
        &other_bodies,
        store,
        "cool",
        "`bodies` differs from the stored scene's",
    );
    // Without checkpoints no stage keeps its end state.
    let mut plain = scene.clone();
    plain["name"] = json!("plain");
    plain["output"]
        .as_object_mut()
        .unwrap()
        .remove("checkpoint");
    let out = run(dir.path(), "plain.json", &plain, "p", &[]);
    assert!(out.status.success(), "{}", text(&out));
    refused(
        &plain,
        "p/plain.zarr",
        "cool",
        "keeps no end state of stage 0 `cure`",
    );
    // An unstaged scene has no stage to start at.
    let mut single = scene.clone();
    single.as_object_mut().unwrap().remove("stages");
    refused(&single, store, "cool", "the scene has no `stages`");
    // --stage needs --from.
    let file = write_scene(dir.path(), "chain.json", &scene);
    let out = mpm(
        &["run", file.to_str().unwrap(), "--stage", "cool"],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
}
