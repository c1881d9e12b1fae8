//! `GET /v1/jobs/{id}/frames/{frame}`: a PNG of one frame of a job's store (a 3D one seen along z), drawn as
//! `mpm render` draws it (by the binary's [`FrameRenderer`](crate::FrameRenderer)), and
//! `GET /v1/jobs/{id}/scene`, the scene a job runs.

use super::access::Caller;
use super::{Shared, find};
use crate::error::ApiError;
use crate::frames::{FrameError, FrameRequest};
use axum::Extension;
use axum::extract::{Path, Query};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use std::time::Duration;

/// The query of a frame picture.
#[derive(Deserialize)]
pub(super) struct FrameQuery {
    /// Field to colour by (default `x`, which every store has).
    field: Option<String>,
    /// Component of a vector or tensor field (default 0).
    component: Option<usize>,
}

/// Longest a picture may wait for a free drawing slot.
const WAIT: Duration = Duration::from_secs(10);

fn bad(message: impl Into<String>) -> ApiError {
    ApiError::new(StatusCode::BAD_REQUEST, "bad_frame", message)
}

pub(super) async fn frame_png(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
    Path((id, frame)): Path<(String, String)>,
    query: Result<Query<FrameQuery>, axum::extract::rejection::QueryRejection>,
) -> Result<Response, ApiError> {
    let row = find(&state, &id, &caller).await?;
    let Query(q) = query.map_err(|e| bad(e.body_text()))?;
    let frame_text = frame.strip_suffix(".png").unwrap_or(&frame);
    let frame: i64 = frame_text.parse().map_err(|_| {
        bad(format!(
            "frame `{frame_text}` is not an integer (0, 1, ...; -1 is the last)"
        ))
    })?;
    let field = q.field.unwrap_or_else(|| "x".into());
    if field.is_empty() || field.len() > 100 {
        return Err(bad("`field` must name a stored field"));
    }
    let Some(renderer) = state.config.frame_renderer.clone() else {
        return Err(ApiError::new(
            StatusCode::NOT_IMPLEMENTED,
            "no_renderer",
            "this service draws no pictures",
        ));
    };
    if !state
        .results
        .has_results(&row.id)
        .await
        .map_err(ApiError::internal)?
    {
        return Err(ApiError::not_found(format!(
            "job {} has no results yet ({})",
            row.id, row.status
        )));
    }
    let _permit = tokio::time::timeout(WAIT, state.renders.clone().acquire_owned())
        .await
        .map_err(|_| {
            ApiError::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "busy",
                "too many pictures are being drawn; try again",
            )
        })?
        .map_err(ApiError::internal)?;
    let request = FrameRequest {
        field,
        frame,
        component: q.component.unwrap_or(0),
    };
    // The store as a local folder (in place, or copied down from a bucket).
    let store = state
        .results
        .local_copy(&row.id, crate::db::is_final(&row.status))
        .await
        .map_err(ApiError::internal)?;
    // Drawing reads the store and rasterises: off the async threads. A panic in it ends
    // this request with a 500, not the service.
    let drawn = tokio::task::spawn_blocking(move || renderer.render_png(&store.path, &request))
        .await
        .map_err(ApiError::internal)?;
    match drawn {
        Ok(png) => Ok((
            [
                (header::CONTENT_TYPE, "image/png"),
                (header::CACHE_CONTROL, "no-store"),
            ],
            png,
        )
            .into_response()),
        Err(FrameError::Invalid(message)) => Err(ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "cannot_render",
            message,
        )),
        Err(FrameError::Failed(message)) => Err(ApiError::internal(message)),
    }
}

/// The scene a job runs (as validated, with its defaults), as JSON.
pub(super) async fn scene(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let row = find(&state, &id, &caller).await?;
    let text = state
        .db
        .scene(&row.id)
        .await?
        .ok_or_else(|| ApiError::not_found(format!("no job `{id}`")))?;
    Ok(([(header::CONTENT_TYPE, "application/json")], text).into_response())
}
