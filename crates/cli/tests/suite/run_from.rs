//! `mpm run SCENE --from STORE`: a scene that starts where another run left its particles.
//! The process chain's stages, each run as a scene of its own from the store of the one
//! before, give the staged run's results.

use crate::common;

use common::{example, mpm, text, write_scene};
use mpm_core::scene::merge_patch;
use mpm_io::ResultStore;
use serde_json::{Value, json};

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// The scene of each stage of `staged` on its own: the base with every change up to the
/// stage, named after the stage, checkpointed every `every` steps (a checkpoint at the
/// stage's last step is what the next one starts from).
fn stage_scenes(staged: &Value, every: u64) -> Vec<(String, Value)> {
    let mut current = staged.clone();
    current.as_object_mut().unwrap().remove("stages");
    let mut out = Vec::new();
    for stage in staged["stages"].as_array().unwrap() {
        merge_patch(&mut current, &stage["changes"]);
        let name = stage["name"].as_str().unwrap().to_string();
        let mut scene = current.clone();
        scene["name"] = json!(name);
        scene["output"]["checkpoint"] = json!({ "steps": every });
        out.push((name, scene));
    }
    out
}

#[test]
fn the_stages_run_one_by_one_from_each_others_stores_equal_the_staged_run() {
    let dir = tempfile::tempdir().unwrap();
    let path = example("underfill-cure-cycles.json");
    let staged: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let out = mpm(
        &["run", path.to_str().unwrap(), "--out", "staged", "-q"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out));
    // The cure stage ends at step 70, the cool-down at 100, the cycles at 280.
    let mut before: Option<String> = None;
    let scenes = stage_scenes(&staged, 10);
    for (name, scene) in &scenes {
        let file = write_scene(dir.path(), &format!("{name}.json"), scene);
        let mut args = vec!["run", file.to_str().unwrap(), "--out", "alone", "-q"];
        let from = before.as_ref().map(|b| format!("alone/{b}.zarr"));
        if let Some(from) = &from {
            args.extend(["--from", from.as_str()]);
        }
        let out = mpm(&args, dir.path());
        assert!(out.status.success(), "{name}: {}", text(&out));
        before = Some(name.clone());
    }
    for (name, _) in &scenes {
        let staged = ResultStore::open(dir.path().join("staged/underfill-cure-cycles.zarr"))
            .unwrap()
            .stage(name)
            .unwrap();
        let alone = ResultStore::open(dir.path().join(format!("alone/{name}.zarr"))).unwrap();
        assert_eq!(
            bits(&staged.times().unwrap()),
            bits(&alone.times().unwrap()),
            "{name}: frame times"
        );
        for frame in 0..staged.frame_count().unwrap() {
            for field in ["x", "stress", "temperature", "cure"] {
                let (a, b) = (
                    staged.frame(field, frame).unwrap().1,
                    alone.frame(field, frame).unwrap().1,
                );
                assert_eq!(
                    bits(&a),
                    bits(&b),
                    "{name}: {field} differs at frame {frame}"
                );
            }
        }
    }
}

#[test]
fn a_run_from_a_store_is_refused_where_it_cannot_take_over() {
    let dir = tempfile::tempdir().unwrap();
    let path = example("underfill-cure-cycles.json");
    let staged: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let scenes = stage_scenes(&staged, 10);
    let (cure, cool) = (&scenes[0].1, &scenes[1].1);
    let file = write_scene(dir.path(), "cure.json", cure);
    let out = mpm(
        &["run", file.to_str().unwrap(), "--out", "r", "-q"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out));
    let refused = |scene: &Value, from: &str, expected: &str| {
        let file = write_scene(dir.path(), "next.json", scene);
        let out = mpm(
            &[
                "run",
                file.to_str().unwrap(),
                "--out",
                "r",
                "-q",
                "--from",
                from,
            ],
            dir.path(),
        );
        assert_eq!(out.status.code(), Some(2), "{expected}: {}", text(&out));
        assert!(text(&out).contains(expected), "{expected}: {}", text(&out));
    };
    let mut other = cool.clone();
    other["bodies"][0]["particles_per_cell"] = json!(3);
    refused(
        &other,
        "r/cure.zarr",
        "`bodies` differs from the stored scene's",
    );
    let mut early = cool.clone();
    early["solver"]["end_time"] = json!(2000.0);
    refused(
        &early,
        "r/cure.zarr",
        "not before the scene's solver.end_time",
    );
    refused(
        cure,
        "r/cure.zarr",
        "would write over the store it starts from",
    );
    refused(cool, "r/none.zarr", "cannot start from it");
    let out = mpm(&["run", "--from", "r/cure.zarr", "--out", "r"], dir.path());
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    // A staged store may have converted its bodies' materials: refused.
    let staged_file = write_scene(dir.path(), "staged.json", &staged);
    let out = mpm(
        &["run", staged_file.to_str().unwrap(), "--out", "s", "-q"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out));
    let mut after = cool.clone();
    after["solver"]["end_time"] = json!(20000.0);
    refused(&after, "s/underfill-cure-cycles.zarr", "its run was staged");
    // A staged scene starts from its own first stage.
    refused(
        &staged,
        "r/cure.zarr",
        "a staged scene starts from its own first stage",
    );
}
