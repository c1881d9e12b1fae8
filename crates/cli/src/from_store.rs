//! `mpm run SCENE --from STORE [--stage NAME]`: a scene that starts where another run left
//! its particles (the store's latest checkpoint, or the end of a stage), as a stage takes
//! over from the stage before. The checks live in `mpm_io::start_from`, shared with the job
//! service; here they are printed with the store's path.

use crate::exit_status::ExitStatus;
use mpm_core::checkpoint::Checkpoint;
use mpm_core::plugin::Registry;
use mpm_core::scene::ValidatedScene;
use std::path::Path;

/// The latest checkpoint of `store`, checked against `scene` (`mpm_io::start_from::
/// load_take_over`). On failure the reason is printed and the exit status returned.
pub(crate) fn load(store: &Path, scene: &ValidatedScene) -> Result<Checkpoint, ExitStatus> {
    mpm_io::start_from::load_take_over(store, scene).map_err(|e| {
        eprintln!("error: {}: cannot start from it: {e}", store.display());
        ExitStatus::InvalidInput
    })
}

/// Where a staged `scene` starts with `--from STORE --stage NAME`: the index of its stage
/// `stage` and the state the stored run's stage before it ended with (`mpm_io::start_from::
/// load_stage_start`). On failure the reason is printed and the exit status returned.
pub(crate) fn load_stage(
    store: &Path,
    scene: &ValidatedScene,
    stage: &str,
    registry: &Registry,
) -> Result<(usize, Checkpoint), ExitStatus> {
    mpm_io::start_from::load_stage_start(store, scene, stage, registry).map_err(|e| {
        eprintln!(
            "error: {}: cannot start stage `{stage}` from it: {e}",
            store.display()
        );
        ExitStatus::InvalidInput
    })
}
