//! A job's run, continued from its store's checkpoint when an earlier attempt of the same
//! job left one (its worker died and the lease ran out), or started afresh.

use mpm_core::output::Metrics;
use mpm_core::scene::ValidatedScene;
use mpm_core::solver::{RunError, RunObserver, resume_scene, run_scene};
use std::path::Path;

/// Runs `scene` into `store`: from the store's latest checkpoint when the store was written
/// by this same scene (an interrupted attempt), otherwise from the start (replacing what is
/// there).
pub(crate) fn run_or_resume(
    scene: &ValidatedScene,
    store: &Path,
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
    run_scene(scene, &mut mpm_io::ZarrSink::new(store), observer)
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
