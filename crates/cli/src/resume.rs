//! `mpm run --resume STORE`: the scene stored in a result store and its latest checkpoint,
//! ready to continue the run.

use crate::exit_status::ExitStatus;
use mpm_core::checkpoint::Checkpoint;
use mpm_core::plugin::Registry;
use mpm_core::scene::{ValidatedScene, parse_scene_value};
use std::path::Path;

/// The stored scene (validated again) and the latest checkpoint of `store`; on failure the
/// reason is printed and the exit status returned.
pub(crate) fn load(
    store: &Path,
    registry: &Registry,
) -> Result<(ValidatedScene, Checkpoint), ExitStatus> {
    let fail = |message: String, status: ExitStatus| {
        eprintln!("error: {}: {message}", store.display());
        status
    };
    let opened = mpm_io::ResultStore::open(store)
        .map_err(|e| fail(format!("cannot resume: {e}"), ExitStatus::InvalidInput))?;
    let scene = opened.attributes().get("scene").cloned().ok_or_else(|| {
        fail(
            "cannot resume: the store holds no scene".into(),
            ExitStatus::InvalidInput,
        )
    })?;
    let checkpoint = mpm_io::read_checkpoint(store)
        .map_err(|e| fail(format!("cannot resume: {e}"), ExitStatus::InvalidInput))?;
    let validated = parse_scene_value(scene, registry, Path::new(".")).map_err(|e| {
        fail(
            format!("cannot resume: the stored scene is no longer valid: {e}"),
            ExitStatus::InvalidInput,
        )
    })?;
    Ok((validated, checkpoint))
}
