//! Starting a run from another run's stored state, checked in one place for the CLI (`mpm
//! run SCENE --from STORE [--stage NAME]`) and the job service (a job submitted with
//! `from` and `stage`): a plain scene takes over the latest checkpoint, a staged scene
//! starts at a later stage from the state the stored run's stage before it ended with.
//!
//! The checks on the scenes read only the stored scene (JSON), so the service can make them
//! at submission from its database; the checks on the state read its clock.

use crate::IoError;
use mpm_core::checkpoint::Checkpoint;
use mpm_core::plugin::Registry;
use mpm_core::scene::{FIXED_ACROSS_STAGES, ValidatedScene, parse_scene_value};
use serde_json::Value;
use std::path::Path;

/// Why a run cannot start from the stored state: the message says what differs or is
/// missing and what to change.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct StartRefused(pub String);

impl From<IoError> for StartRefused {
    fn from(e: IoError) -> Self {
        Self(e.to_string())
    }
}

/// Checks that a plain `scene` may take over a run of the stored scene `stored` (its
/// validated JSON): the stored run was not staged and shares what stages share.
pub fn check_take_over(stored: &Value, scene: &ValidatedScene) -> Result<(), StartRefused> {
    if stored
        .get("stages")
        .and_then(|s| s.as_array())
        .is_some_and(|s| !s.is_empty())
    {
        return Err(StartRefused(
            "its run was staged (a stage's bodies may have changed material): start a staged \
             scene with the same earlier stages at one of its stages, with `--stage NAME`"
                .into(),
        ));
    }
    if let Some(key) = shared_key_that_differs(stored, &scene.json) {
        return Err(StartRefused(format!(
            "`{key}` differs from the stored scene's: a run taken over must have the same \
             dimension, domain, materials, bodies, contact and loads (what stages share)"
        )));
    }
    Ok(())
}

/// Checks that a taken-over checkpoint at `time` is before `scene`'s end time.
pub fn check_take_over_time(time: Option<f64>, scene: &ValidatedScene) -> Result<(), StartRefused> {
    let time = time.unwrap_or(f64::NAN);
    let end = scene.scene.solver.end_time;
    if time.is_nan() || time >= end {
        return Err(StartRefused(format!(
            "its latest checkpoint is at t = {time} s, not before the scene's solver.end_time \
             ({end} s): set the end time the scene runs to (absolute, not its duration)"
        )));
    }
    Ok(())
}

/// The latest checkpoint of the store at `store`, checked against a plain `scene` (see
/// [`check_take_over`] and [`check_take_over_time`]).
pub fn load_take_over(store: &Path, scene: &ValidatedScene) -> Result<Checkpoint, StartRefused> {
    let stored = stored_scene(store)?;
    check_take_over(&stored, scene)?;
    let checkpoint = crate::read_checkpoint(store)?;
    check_take_over_time(checkpoint.state("time").as_f64(), scene)?;
    Ok(checkpoint)
}

/// Checks that the staged `scene` may start at its stage `stage` from a run of the stored
/// scene `stored` (its validated JSON), and returns the stage's index: the stored run was
/// staged, shares what stages share and ran the same stages before `stage` (names, raw
/// `remove` and `convert` rules, and each stage's merged scene but its name).
pub fn check_stage_start(
    stored: &Value,
    scene: &ValidatedScene,
    stage: &str,
    registry: &Registry,
) -> Result<usize, StartRefused> {
    let fail = |message: String| Err(StartRefused(message));
    let index = stage_index(scene, stage)?;
    let old = parse_scene_value(stored.clone(), registry, Path::new("."))
        .map_err(|e| StartRefused(format!("the stored scene is no longer valid: {e}")))?;
    if old.stages.len() < index {
        return fail(format!(
            "its run had {} stages, fewer than the {index} before `{stage}`",
            old.stages.len()
        ));
    }
    if let Some(key) = shared_key_that_differs(stored, &scene.json) {
        return fail(format!(
            "`{key}` differs from the stored scene's (stages share the dimension, domain, \
             materials, bodies, contact and loads)"
        ));
    }
    let raw_stage = |json: &Value, i: usize, key: &str| {
        json.pointer(&format!("/stages/{i}/{key}"))
            .cloned()
            .unwrap_or(Value::Null)
    };
    for i in 0..index {
        let (was, now) = (&old.stages[i], &scene.stages[i]);
        if was.name != now.name {
            return fail(format!(
                "stage {i} is `{}` in the stored run and `{}` here: the stages before `{stage}` \
                 must be the stored run's",
                was.name, now.name
            ));
        }
        for rule in ["remove", "convert"] {
            if raw_stage(stored, i, rule) != raw_stage(&scene.json, i, rule) {
                return fail(format!(
                    "stage `{}`'s `{rule}` differs from the stored run's: the stages before \
                     `{stage}` must be the stored run's",
                    now.name
                ));
            }
        }
        if let Some(key) = first_difference(&was.scene.json, &now.scene.json) {
            return fail(format!(
                "stage `{}` runs with another `{key}` than in the stored run: the stages \
                 before `{stage}` must be the stored run's (change `{stage}` or a later stage)",
                now.name
            ));
        }
    }
    Ok(index)
}

/// The index of `scene`'s stage `stage`, which must be a stage after the first.
pub fn stage_index(scene: &ValidatedScene, stage: &str) -> Result<usize, StartRefused> {
    let names: Vec<&str> = scene.stages.iter().map(|s| s.name.as_str()).collect();
    match names.iter().position(|n| *n == stage) {
        None if names.is_empty() => Err(StartRefused("the scene has no `stages`".into())),
        None => Err(StartRefused(format!(
            "the scene's stages are {}",
            names.join(", ")
        ))),
        Some(0) => Err(StartRefused(
            "it is the scene's first stage, which starts from the scene itself: run the scene \
             without --from"
                .into(),
        )),
        Some(index) => Ok(index),
    }
}

/// Checks that the stage before `scene`'s stage `index`, which ended at `time`, ended
/// before that stage's end time.
pub fn check_stage_start_time(
    time: Option<f64>,
    scene: &ValidatedScene,
    index: usize,
) -> Result<(), StartRefused> {
    let time = time.unwrap_or(f64::NAN);
    let (before, stage) = (&scene.stages[index - 1].name, &scene.stages[index]);
    let end = stage.scene.scene.solver.end_time;
    if time.is_nan() || time >= end {
        return Err(StartRefused(format!(
            "stage `{before}` ended at t = {time} s, not before `{}`'s solver.end_time ({end} s)",
            stage.name
        )));
    }
    Ok(())
}

/// Where the staged `scene` starts with `--from STORE --stage NAME`: the index of its stage
/// `stage` and the state the stored run's stage before it ended with (see
/// [`check_stage_start`] and [`check_stage_start_time`]).
pub fn load_stage_start(
    store: &Path,
    scene: &ValidatedScene,
    stage: &str,
    registry: &Registry,
) -> Result<(usize, Checkpoint), StartRefused> {
    stage_index(scene, stage)?;
    let stored = stored_scene(store)?;
    let index = check_stage_start(&stored, scene, stage, registry)?;
    let state = crate::read_stage_end(store, index - 1, &scene.stages[index - 1].name)?;
    check_stage_start_time(state.state("time").as_f64(), scene, index)?;
    Ok((index, state))
}

/// The group of a store that holds the end state of `scene`'s stage before its stage
/// `index` (relative to the store's root), for copying it alone.
pub fn stage_end_group(scene: &ValidatedScene, index: usize) -> String {
    end_group(index - 1, &scene.stages[index - 1].name)
}

/// The same group read from a scene's JSON (`stages[].name`): the end state of the stage
/// before the stage `stage`; `None` when the scene has no such stage after its first.
pub fn stage_end_group_in(scene: &Value, stage: &str) -> Option<String> {
    let names: Vec<&str> = scene
        .get("stages")?
        .as_array()?
        .iter()
        .map(|s| s.get("name").and_then(|n| n.as_str()).unwrap_or(""))
        .collect();
    let index = names.iter().position(|n| *n == stage).filter(|&i| i > 0)?;
    Some(end_group(index - 1, names[index - 1]))
}

/// `stages/<index>-<name>/end_state`.
fn end_group(index: usize, name: &str) -> String {
    format!("stages/{index}-{name}/{}", crate::STAGE_END)
}

/// The scene kept in the store at `store` (its root attribute `scene`).
fn stored_scene(store: &Path) -> Result<Value, StartRefused> {
    let opened = crate::ResultStore::open(store)?;
    opened
        .attributes()
        .get("scene")
        .cloned()
        .ok_or_else(|| StartRefused("the store holds no scene".into()))
}

/// The first of the keys stages share (`FIXED_ACROSS_STAGES` but name and stages) in which
/// a stored scene and a new one differ.
fn shared_key_that_differs(stored: &Value, scene: &Value) -> Option<&'static str> {
    let null = Value::Null;
    FIXED_ACROSS_STAGES
        .iter()
        .filter(|k| !matches!(**k, "name" | "stages"))
        .find(|k| stored.get(**k).unwrap_or(&null) != scene.get(**k).unwrap_or(&null))
        .copied()
}

/// The first top-level key (but `name`) in which two stage scenes differ.
fn first_difference(a: &Value, b: &Value) -> Option<String> {
    let empty = serde_json::Map::new();
    let (a, b) = (
        a.as_object().unwrap_or(&empty),
        b.as_object().unwrap_or(&empty),
    );
    let null = Value::Null;
    a.keys()
        .chain(b.keys())
        .filter(|k| k.as_str() != "name")
        .find(|k| a.get(*k).unwrap_or(&null) != b.get(*k).unwrap_or(&null))
        .cloned()
}
