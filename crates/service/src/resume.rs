//! A job's run, continued from its store's checkpoint when an earlier attempt of the same
//! job left one (its worker died and the lease ran out), else started from another job's
//! stored state (a job submitted with `from`) or afresh.

use crate::start_state::JobStart;
use mpm_core::output::Metrics;
use mpm_core::plugin::Registry;
use mpm_core::scene::ValidatedScene;
use mpm_core::solver::{
    RunError, RunObserver, resume_scene, run_scene, run_scene_from, run_scene_from_stage,
};
use mpm_io::start_from::{load_stage_start, load_take_over};
use std::path::Path;

/// Runs `scene` into `store`: from the store's latest checkpoint when the store was written
/// by this same scene (an interrupted attempt), otherwise from `start` (checked as `mpm run
/// --from` checks it) or from the scene, replacing what is there.
pub(crate) fn run_or_resume(
    scene: &ValidatedScene,
    store: &Path,
    start: Option<&JobStart>,
    registry: &Registry,
    observer: &mut dyn RunObserver,
) -> Result<Metrics, RunError> {
    if let Some(checkpoint) = checkpoint_of_same_scene(store, &scene.json) {
        let frames = checkpoint.state("frames").as_u64().unwrap_or(0) as usize;
        let mut sink = mpm_io::ZarrSink::resume(store, frames);
        tracing::info!(
            store = %store.display(),
            step = checkpoint.state("step").as_u64().unwrap_or(0),
            "job resumed from its checkpoint"
        );
        return resume_scene(scene, &checkpoint, &mut sink, observer);
    }
    let refused = |e: mpm_io::start_from::StartRefused| RunError::Refused {
        path: "from".into(),
        message: e.to_string(),
    };
    let mut sink = mpm_io::ZarrSink::new(store);
    match start {
        None => run_scene(scene, &mut sink, observer),
        Some(JobStart {
            store: from,
            stage: Some(stage),
        }) => {
            let (index, state) = load_stage_start(from, scene, stage, registry).map_err(refused)?;
            run_scene_from_stage(scene, index, &state, &mut sink, observer)
        }
        Some(JobStart {
            store: from,
            stage: None,
        }) => {
            let checkpoint = load_take_over(from, scene).map_err(refused)?;
            run_scene_from(scene, &checkpoint, &mut sink, observer)
        }
    }
}

/// The store's checkpoint, if it has one and was written for `scene`.
fn checkpoint_of_same_scene(
    store: &Path,
    scene: &serde_json::Value,
) -> Option<mpm_core::checkpoint::Checkpoint> {
    let stored = mpm_io::ResultStore::open(store).ok()?;
    if stored.attributes().get("scene") != Some(scene) {
        return None;
    }
    mpm_io::read_checkpoint(store).ok()
}
