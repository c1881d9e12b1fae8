//! `POST /v1/jobs?from=JOB[&stage=NAME]`: a job that starts from another job's stored state,
//! as `mpm run SCENE --from STORE [--stage NAME]` does locally: a plain scene takes over the
//! latest checkpoint, a staged scene starts at its stage NAME from the end state of the stage
//! before. The checks are `mpm_io::start_from`'s, on the source job's scene from the
//! database and on its stored state's clock, read from the result store.

use super::Shared;
use super::access::Caller;
use crate::db;
use crate::error::{ApiError, Problem};
use axum::http::StatusCode;
use mpm_core::plugin::Registry;
use mpm_core::scene::ValidatedScene;
use mpm_io::start_from::{self, StartRefused};
use serde::Deserialize;

/// The query of a submission.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SubmitQuery {
    /// The job whose stored state the new one starts from.
    pub from: Option<String>,
    /// With `from`: the stage of a staged scene to start at.
    pub stage: Option<String>,
}

/// The job a submission starts from, as found and checked before the scene is validated.
pub(super) struct Source {
    /// Its id.
    pub id: String,
    /// Its validated scene.
    pub scene: serde_json::Value,
    /// The stage to start at, if any.
    pub stage: Option<String>,
}

/// What the start checks found: the stage's index in the new scene, if any.
pub(super) type StageIndex = Option<usize>;

/// A 422 naming the source job and why the new one cannot start from it.
fn refused(source: &str, stage: Option<&str>, why: impl std::fmt::Display) -> ApiError {
    let what = match stage {
        Some(stage) => format!("cannot start stage `{stage}` from it"),
        None => "cannot start from it".to_string(),
    };
    let mut e = ApiError::new(
        StatusCode::UNPROCESSABLE_ENTITY,
        "cannot_start_from",
        format!("job `{source}`: {what}: {why}"),
    );
    e.problems = vec![Problem {
        path: if stage.is_some() { "stage" } else { "from" }.into(),
        message: why.to_string(),
    }];
    e
}

/// The job the query names, when it names one: visible to the caller (else 422, as unknown),
/// ended (else 409: its store may still change), with its scene.
pub(super) async fn source(
    state: &Shared,
    query: &SubmitQuery,
    caller: &Caller,
) -> Result<Option<Source>, ApiError> {
    let Some(raw) = &query.from else {
        if query.stage.is_some() {
            return Err(ApiError::new(
                StatusCode::BAD_REQUEST,
                "bad_query",
                "`stage` needs `from`, the job whose stored stage the run starts after",
            ));
        }
        return Ok(None);
    };
    let stage = query.stage.as_deref();
    let row = match super::find(state, raw, caller).await {
        Ok(row) => row,
        Err(e) if e.status == StatusCode::NOT_FOUND => {
            return Err(refused(raw, stage, "there is no such job"));
        }
        Err(e) => return Err(e),
    };
    if !db::is_final(&row.status) {
        return Err(ApiError::new(
            StatusCode::CONFLICT,
            "source_not_ended",
            format!(
                "job `{}` is {}: a job starts from another's stored state once that one has \
                 ended",
                row.id, row.status
            ),
        ));
    }
    let text = state
        .db
        .scene(&row.id)
        .await?
        .ok_or_else(|| ApiError::internal("the job's scene vanished"))?;
    let scene = serde_json::from_str(&text).map_err(ApiError::internal)?;
    Ok(Some(Source {
        id: row.id,
        scene,
        stage: query.stage.clone(),
    }))
}

/// The checks on the scenes (on the validation thread): a staged scene's stages before the
/// one named are the source's, a plain one shares what stages share with it.
pub(super) fn check_scenes(
    source: &Source,
    scene: &ValidatedScene,
    registry: &Registry,
) -> Result<StageIndex, ApiError> {
    let stage = source.stage.as_deref();
    match stage {
        Some(name) => start_from::check_stage_start(&source.scene, scene, name, registry).map(Some),
        None => start_from::check_take_over(&source.scene, scene).map(|()| None),
    }
    .map_err(|e| refused(&source.id, stage, e))
}

/// The simulated time the new job starts at, read from the source's stored state (the end
/// state of the stage before, or the latest checkpoint), checked to be before the new run's
/// (stage's) end time.
pub(super) async fn start_time(
    state: &Shared,
    source: &Source,
    scene: &ValidatedScene,
    index: StageIndex,
) -> Result<f64, ApiError> {
    let stage = source.stage.as_deref();
    let fail = |e: StartRefused| refused(&source.id, stage, e);
    let (key, missing) = match index {
        Some(i) => (
            format!("{}/zarr.json", start_from::stage_end_group(scene, i)),
            format!(
                "its store keeps no end state of stage {} `{}` (the stage did not finish, or \
                 ran without `output.end_state` or `output.checkpoint`)",
                i - 1,
                scene.stages[i - 1].name
            ),
        ),
        None => (
            "zarr.json".to_string(),
            "its store has no checkpoint (run it with `output.checkpoint`)".to_string(),
        ),
    };
    let bytes = state
        .results
        .read(&source.id, &key)
        .await
        .map_err(ApiError::internal)?
        .ok_or_else(|| fail(StartRefused(missing.clone())))?;
    let node: serde_json::Value = serde_json::from_slice(&bytes).map_err(ApiError::internal)?;
    let attributes = &node["attributes"];
    match index {
        Some(i) => {
            let time = attributes["state"]["time"].as_f64();
            start_from::check_stage_start_time(time, scene, i).map_err(fail)?;
            Ok(time.unwrap_or_default())
        }
        None => {
            let checkpoint = &attributes["checkpoint"];
            if checkpoint.is_null() {
                return Err(fail(StartRefused(missing)));
            }
            let time = checkpoint["time"].as_f64();
            start_from::check_take_over_time(time, scene).map_err(fail)?;
            Ok(time.unwrap_or_default())
        }
    }
}
