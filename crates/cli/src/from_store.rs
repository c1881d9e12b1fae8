//! `mpm run SCENE --from STORE`: a scene that starts where another run left its particles
//! (the store's latest checkpoint), as a stage takes over from the stage before. Each stage
//! of a process can so be run as a scene of its own, each from the store of the one before.

use crate::exit_status::ExitStatus;
use mpm_core::checkpoint::Checkpoint;
use mpm_core::scene::{FIXED_ACROSS_STAGES, ValidatedScene};
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
            "its run was staged (a stage's bodies may have changed material); continue it with \
             a stage of its own scene instead"
                .into(),
        ));
    }
    for key in FIXED_ACROSS_STAGES
        .iter()
        .filter(|k| !matches!(**k, "name" | "stages"))
    {
        let (before, now) = (
            stored.get(*key).unwrap_or(&serde_json::Value::Null),
            scene.json.get(*key).unwrap_or(&serde_json::Value::Null),
        );
        if before != now {
            return Err(fail(format!(
                "`{key}` differs from the stored scene's: a run taken over must have the same \
                 dimension, domain, materials, bodies, contact and loads (what stages share)"
            )));
        }
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
