//! The HTTP API, versioned under /v1; described in api/openapi.yaml (a test keeps the two in
//! step through [`ROUTES`]).

mod access;
mod frames;
mod page;
mod submit;
mod submit_from;

use access::{Caller, authorize, forbidden, log_request, metrics};
use submit::submit;

use crate::error::ApiError;
use crate::{State, db};
use axum::extract::{DefaultBodyLimit, Path, Query};
use axum::http::{StatusCode, header};
use axum::middleware;
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Extension, Json, Router};
use futures_util::stream::{self, Stream};
use serde::Deserialize;
use std::convert::Infallible;
use std::path::{Component, Path as FilePath};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::watch;

/// Every route: (method, path as in the OpenAPI file).
pub const ROUTES: &[(&str, &str)] = &[
    ("get", "/v1/health"),
    ("get", "/metrics"),
    ("get", "/v1/plugins"),
    ("post", "/v1/jobs"),
    ("get", "/v1/jobs"),
    ("get", "/v1/jobs/{id}"),
    ("delete", "/v1/jobs/{id}"),
    ("get", "/v1/jobs/{id}/events"),
    ("get", "/v1/jobs/{id}/scene"),
    ("get", "/v1/jobs/{id}/frames/{frame}"),
    ("get", "/v1/jobs/{id}/files"),
    ("get", "/v1/jobs/{id}/results"),
    ("get", "/v1/jobs/{id}/results/{path}"),
];

type Shared = Arc<State>;

/// Builds the router: the API behind the token check, the page without it.
pub fn router(state: Shared, stop: watch::Receiver<bool>) -> Router {
    let limit = state.config.max_body_bytes;
    let api = Router::new()
        .route("/v1/health", get(health))
        .route("/metrics", get(metrics))
        .route("/v1/plugins", get(plugins))
        .route("/v1/jobs", get(list_jobs).post(submit))
        .route("/v1/jobs/{id}", get(get_job).delete(cancel_job))
        .route("/v1/jobs/{id}/events", get(events))
        .route("/v1/jobs/{id}/scene", get(frames::scene))
        .route("/v1/jobs/{id}/frames/{frame}", get(frames::frame_png))
        .route("/v1/jobs/{id}/files", get(files))
        .route("/v1/jobs/{id}/results", get(results_root))
        .route("/v1/jobs/{id}/results/{*path}", get(results))
        .fallback(|| async { ApiError::not_found("no such route") })
        .layer(middleware::from_fn_with_state(state.clone(), authorize));
    page::routes()
        .merge(api)
        .layer(middleware::from_fn_with_state(state.clone(), log_request))
        .layer(DefaultBodyLimit::max(limit))
        .layer(Extension(stop))
        .with_state(state)
}

async fn health() -> Json<serde_json::Value> {
    Json(serde_json::json!({ "status": "ok", "version": mpm_core::VERSION }))
}

async fn plugins(
    axum::extract::State(state): axum::extract::State<Shared>,
) -> Json<serde_json::Value> {
    Json(state.registry.catalogue())
}

#[derive(Deserialize)]
struct ListQuery {
    status: Option<String>,
    owner: Option<String>,
    limit: Option<i64>,
    offset: Option<i64>,
}

async fn list_jobs(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
    query: Result<Query<ListQuery>, axum::extract::rejection::QueryRejection>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let Query(q) =
        query.map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, "bad_query", e.body_text()))?;
    if let Some(s) = &q.status
        && !matches!(
            s.as_str(),
            "queued" | "running" | "succeeded" | "failed" | "cancelled"
        )
    {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            "bad_query",
            format!("unknown status `{s}` (queued, running, succeeded, failed, cancelled)"),
        ));
    }
    // A user lists their own jobs; an admin every job, or one owner's.
    let owner = match (&caller.name, caller.admin) {
        (_, true) => q.owner.clone(),
        (Some(me), false) => {
            if q.owner.as_ref().is_some_and(|o| o != me) {
                return Err(forbidden("a user may list only their own jobs"));
            }
            Some(me.clone())
        }
        (None, false) => return Err(forbidden("no user")),
    };
    let limit = q.limit.unwrap_or(100).clamp(1, 1000);
    let offset = q.offset.unwrap_or(0).max(0);
    let (rows, total) = state
        .db
        .list(q.status.as_deref(), owner.as_deref(), limit, offset)
        .await?;
    let jobs: Vec<_> = rows.iter().map(|r| r.view()).collect();
    Ok(Json(
        serde_json::json!({ "jobs": jobs, "total": total, "limit": limit, "offset": offset }),
    ))
}

/// Parses a job id; anything that is not a UUID is an unknown job.
fn job_id(raw: &str) -> Result<String, ApiError> {
    uuid::Uuid::parse_str(raw)
        .map(|u| u.to_string())
        .map_err(|_| ApiError::not_found(format!("no job `{raw}`")))
}

/// The job `raw` if the caller may see it; another user's job is as unknown as a missing
/// one (404), so ids say nothing about other users.
pub(super) async fn find(
    state: &State,
    raw: &str,
    caller: &Caller,
) -> Result<db::JobRow, ApiError> {
    let id = job_id(raw)?;
    state
        .db
        .get(&id)
        .await?
        .filter(|row| caller.may_see(row.owner.as_deref()))
        .ok_or_else(|| ApiError::not_found(format!("no job `{raw}`")))
}

async fn get_job(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
    Path(id): Path<String>,
) -> Result<Json<db::JobView>, ApiError> {
    Ok(Json(find(&state, &id, &caller).await?.view()))
}

async fn cancel_job(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
    Path(id): Path<String>,
) -> Result<Json<db::JobView>, ApiError> {
    let row = find(&state, &id, &caller).await?;
    if db::is_final(&row.status) {
        return Err(ApiError::new(
            StatusCode::CONFLICT,
            "already_finished",
            format!("job {} is already {}", row.id, row.status),
        ));
    }
    if !state.db.cancel_queued(&row.id).await? {
        // Running: ask it to stop; it ends within one step and keeps what it wrote.
        state.db.request_cancel(&row.id).await?;
        state.jobs.cancel(&row.id);
        for _ in 0..100 {
            let now = find(&state, &row.id, &caller).await?;
            if db::is_final(&now.status) {
                return Ok(Json(now.view()));
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
    Ok(Json(find(&state, &row.id, &caller).await?.view()))
}

async fn events(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
    Extension(stop): Extension<watch::Receiver<bool>>,
    Path(id): Path<String>,
) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, ApiError> {
    let row = find(&state, &id, &caller).await?;
    // Sends the job whenever its status or step changed; ends at a final state or when the
    // server shuts down (an open stream would otherwise hold the shutdown).
    let stream = stream::unfold(
        (
            state.clone(),
            row.id.clone(),
            None::<(String, i64)>,
            false,
            stop,
        ),
        |(state, id, last, done, mut stop)| async move {
            if done || *stop.borrow() {
                return None;
            }
            loop {
                let row = match state.db.get(&id).await {
                    Ok(Some(r)) => r,
                    _ => return None,
                };
                let key = (row.status.clone(), row.step);
                if last.as_ref() != Some(&key) {
                    let finished = db::is_final(&row.status);
                    let kind = if finished { "final" } else { "progress" };
                    let event = Event::default()
                        .event(kind)
                        .json_data(row.view())
                        .unwrap_or_else(|_| Event::default().data("{}"));
                    return Some((Ok(event), (state, id, Some(key), finished, stop)));
                }
                tokio::select! {
                    _ = tokio::time::sleep(Duration::from_millis(200)) => {}
                    _ = stop.changed() => return None,
                }
            }
        },
    );
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

/// Every file of a job's result store, as paths relative to `results/`.
async fn files(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
    Path(id): Path<String>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let row = find(&state, &id, &caller).await?;
    let list = state
        .results
        .list(&row.id)
        .await
        .map_err(ApiError::internal)?;
    Ok(Json(serde_json::json!({ "files": list })))
}

async fn results_root(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    serve_file(&state, &id, "zarr.json", &caller).await
}

async fn results(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
    Path((id, path)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    serve_file(&state, &id, &path, &caller).await
}

/// Serves one file of a job's store; any path that could leave the store is a 404.
async fn serve_file(
    state: &State,
    id: &str,
    path: &str,
    caller: &Caller,
) -> Result<Response, ApiError> {
    let row = find(state, id, caller).await?;
    let relative = FilePath::new(path);
    let safe = !path.is_empty()
        && !path.contains('\\')
        && !path.contains('\0')
        && relative
            .components()
            .all(|c| matches!(c, Component::Normal(_)));
    if !safe {
        return Err(ApiError::not_found(format!(
            "no file `{path}` in the results"
        )));
    }
    match state
        .results
        .read(&row.id, path)
        .await
        .map_err(ApiError::internal)?
    {
        Some(bytes) => {
            let kind = if path.ends_with(".json") {
                "application/json"
            } else {
                "application/octet-stream"
            };
            Ok(([(header::CONTENT_TYPE, kind)], bytes).into_response())
        }
        None => Err(ApiError::not_found(format!(
            "no file `{path}` in the results"
        ))),
    }
}
