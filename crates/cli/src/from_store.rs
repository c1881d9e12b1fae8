//! `mpm run SCENE --from STORE`: a scene that starts where another run left its particles
//! (the store's latest checkpoint), as a stage takes over from the stage before. Each stage
//! of a process can so be run as a scene of its own, each from the store of the one before.

use crate::exit_status::ExitStatus;
use mpm_core::checkpoint::Checkpoint;
use mpm_core::plugin::Registry;
use mpm_core::scene::{FIXED_ACROSS_STAGES, ValidatedScene, parse_scene_value};
use std::path::Path;

/// The latest checkpoint of `store`, checked against `scene`: the store's run was not
/// staged, it had the same dimension, domain, materials, bodies, contact and loads (what
/// stages share), and `scene` ends after the checkpoint's time. On failure the reason is
/// printed and the exit status returned.
pub(crate) fn load(store: &Path, scene: &ValidatedScene) -> Result<Checkpoint, ExitStatus> {
    let fail = |message: String| {
        eprintln!(
            "error: {}: cannot start from it: {message}",
            store.display()
        );
        ExitStatus::InvalidInput
    };
    let opened = mpm_io::ResultStore::open(store).map_err(|e| fail(e.to_string()))?;
    let stored = opened
        .attributes()
        .get("scene")
        .cloned()
        .ok_or_else(|| fail("the store holds no scene".into()))?;
    if stored
        .get("stages")
        .and_then(|s| s.as_array())
        .is_some_and(|s| !s.is_empty())
    {
        return Err(fail(
            "its run was staged (a stage's bodies may have changed material): start a staged \
             scene with the same earlier stages at one of its stages, with `--stage NAME`"
                .into(),
        ));
    }
    if let Some(key) = shared_key_that_differs(&stored, &scene.json) {
        return Err(fail(format!(
            "`{key}` differs from the stored scene's: a run taken over must have the same \
             dimension, domain, materials, bodies, contact and loads (what stages share)"
        )));
    }
    let checkpoint = mpm_io::read_checkpoint(store).map_err(|e| fail(e.to_string()))?;
    let time = checkpoint.state("time").as_f64().unwrap_or(f64::NAN);
    let end = scene.scene.solver.end_time;
    if time.is_nan() || time >= end {
        return Err(fail(format!(
            "its latest checkpoint is at t = {time} s, not before the scene's solver.end_time \
             ({end} s): set the end time the scene runs to (absolute, not its duration)"
        )));
    }
    Ok(checkpoint)
}

/// Where a staged `scene` starts with `--from STORE --stage NAME`: the index of its stage
/// `stage` and the state the stored run's stage before it ended with. The stored run must be
/// staged, share what stages share, and have run the same stages before `stage` (names,
/// hand-over rules and each stage's scene but its name), the last of them to its end with
/// `output.checkpoint`. On failure the reason is printed and the exit status returned.
pub(crate) fn load_stage(
    store: &Path,
    scene: &ValidatedScene,
    stage: &str,
    registry: &Registry,
) -> Result<(usize, Checkpoint), ExitStatus> {
    let fail = |message: String| {
        eprintln!(
            "error: {}: cannot start stage `{stage}` from it: {message}",
            store.display()
        );
        ExitStatus::InvalidInput
    };
    let names: Vec<&str> = scene.stages.iter().map(|s| s.name.as_str()).collect();
    let index = names
        .iter()
        .position(|n| *n == stage)
        .ok_or_else(|| match names.is_empty() {
            true => fail("the scene has no `stages`".into()),
            false => fail(format!("the scene's stages are {}", names.join(", "))),
        })?;
    if index == 0 {
        return Err(fail(
            "it is the scene's first stage, which starts from the scene itself: run the scene \
             without --from"
                .into(),
        ));
    }
    let opened = mpm_io::ResultStore::open(store).map_err(|e| fail(e.to_string()))?;
    let stored_json = opened
        .attributes()
        .get("scene")
        .cloned()
        .ok_or_else(|| fail("the store holds no scene".into()))?;
    let stored = parse_scene_value(stored_json.clone(), registry, Path::new("."))
        .map_err(|e| fail(format!("the stored scene is no longer valid: {e}")))?;
    if stored.stages.len() < index {
        return Err(fail(format!(
            "its run had {} stages, fewer than the {index} before `{stage}`",
            stored.stages.len()
        )));
    }
    if let Some(key) = shared_key_that_differs(&stored_json, &scene.json) {
        return Err(fail(format!(
            "`{key}` differs from the stored scene's (stages share the dimension, domain, \
             materials, bodies, contact and loads)"
        )));
    }
    let raw_stage = |json: &serde_json::Value, i: usize, key: &str| {
        json.pointer(&format!("/stages/{i}/{key}"))
            .cloned()
            .unwrap_or(serde_json::Value::Null)
    };
    for i in 0..index {
        let (old, new) = (&stored.stages[i], &scene.stages[i]);
        if old.name != new.name {
            return Err(fail(format!(
                "stage {i} is `{}` in the stored run and `{}` here: the stages before `{stage}` \
                 must be the stored run's",
                old.name, new.name
            )));
        }
        for rule in ["remove", "convert"] {
            if raw_stage(&stored_json, i, rule) != raw_stage(&scene.json, i, rule) {
                return Err(fail(format!(
                    "stage `{}`'s `{rule}` differs from the stored run's: the stages before \
                     `{stage}` must be the stored run's",
                    new.name
                )));
            }
        }
        let differs = first_difference(&old.scene.json, &new.scene.json);
        if let Some(key) = differs {
            return Err(fail(format!(
                "stage `{}` runs with another `{key}` than in the stored run: the stages \
                 before `{stage}` must be the stored run's (change `{stage}` or a later stage)",
                new.name
            )));
        }
    }
    let before = &scene.stages[index - 1].name;
    let state =
        mpm_io::read_stage_end(store, index - 1, before).map_err(|e| fail(e.to_string()))?;
    let time = state.state("time").as_f64().unwrap_or(f64::NAN);
    let end = scene.stages[index].scene.scene.solver.end_time;
    if time.is_nan() || time >= end {
        return Err(fail(format!(
            "stage `{before}` ended at t = {time} s, not before `{stage}`'s solver.end_time \
             ({end} s)"
        )));
    }
    Ok((index, state))
}

/// The first of the keys stages share (`FIXED_ACROSS_STAGES` but name and stages) in which
/// a stored scene and a new one differ.
fn shared_key_that_differs(
    stored: &serde_json::Value,
    scene: &serde_json::Value,
) -> Option<&'static str> {
    let null = serde_json::Value::Null;
    FIXED_ACROSS_STAGES
        .iter()
        .filter(|k| !matches!(**k, "name" | "stages"))
        .find(|k| stored.get(**k).unwrap_or(&null) != scene.get(**k).unwrap_or(&null))
        .copied()
}

/// The first top-level key (but `name`) in which two stage scenes differ.
fn first_difference(a: &serde_json::Value, b: &serde_json::Value) -> Option<String> {
    let empty = serde_json::Map::new();
    let (a, b) = (
        a.as_object().unwrap_or(&empty),
        b.as_object().unwrap_or(&empty),
    );
    let null = serde_json::Value::Null;
    a.keys()
        .chain(b.keys())
        .filter(|k| k.as_str() != "name")
        .find(|k| a.get(*k).unwrap_or(&null) != b.get(*k).unwrap_or(&null))
        .cloned()
}
