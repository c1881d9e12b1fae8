//! The stored state a job submitted with `from` starts from, made a local store for its
//! run: the source job's store in place (a folder of stores), or the one group the run reads
//! downloaded from the bucket (S3): the end state of the stage before the one it starts at,
//! or the source's latest checkpoint.

use crate::State;
use std::path::PathBuf;

/// Where a job's run starts, when not from its scene: a local store holding the state, and
/// the stage a staged scene starts at (`None`: a plain scene takes over the latest
/// checkpoint).
#[derive(Clone, Debug)]
pub struct JobStart {
    /// The store (only the group read need be there, with the root `zarr.json`).
    pub store: PathBuf,
    /// The stage to start at.
    pub stage: Option<String>,
}

/// Makes the state job `id` (scene `scene`, JSON text) starts from local: the group of job
/// `source`'s store that its run reads. The message says what is missing.
pub(crate) async fn fetch(
    state: &State,
    id: &str,
    scene: &str,
    source: &str,
    stage: Option<&str>,
) -> Result<JobStart, String> {
    let group = match stage {
        Some(name) => {
            let value: serde_json::Value = serde_json::from_str(scene)
                .map_err(|e| format!("the job's scene is not JSON: {e}"))?;
            mpm_io::start_from::stage_end_group_in(&value, name)
                .ok_or_else(|| format!("the job's scene has no stage `{name}` after its first"))?
        }
        None => latest_checkpoint(state, source).await?,
    };
    let store = state
        .results
        .start_state(id, source, &group)
        .await
        .map_err(|e| format!("fetching `{group}` of job {source}'s store failed: {e}"))?;
    Ok(JobStart {
        store,
        stage: stage.map(str::to_string),
    })
}

/// The group of job `source`'s latest checkpoint, as its store's root names it.
async fn latest_checkpoint(state: &State, source: &str) -> Result<String, String> {
    let root = state
        .results
        .read(source, "zarr.json")
        .await
        .map_err(|e| format!("reading job {source}'s store failed: {e}"))?
        .ok_or_else(|| format!("job {source} has no store"))?;
    let node: serde_json::Value = serde_json::from_slice(&root)
        .map_err(|e| format!("job {source}'s store root is not JSON: {e}"))?;
    node.pointer("/attributes/checkpoint/path")
        .and_then(|p| p.as_str())
        .filter(|p| p.starts_with("checkpoints/") && !p.contains(".."))
        .map(str::to_string)
        .ok_or_else(|| format!("job {source}'s store has no checkpoint"))
}
