//! The HTTP API, versioned under /v1; described in api/openapi.yaml (a test keeps the two in
//! step through [`ROUTES`]).

use crate::error::{ApiError, Problem};
use crate::{State, db, worker};
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{DefaultBodyLimit, Path, Query, Request};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Extension, Json, Router};
use futures_util::stream::{self, Stream};
use serde::Deserialize;
use std::convert::Infallible;
use std::path::{Component, PathBuf};
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
    ("get", "/v1/jobs/{id}/files"),
    ("get", "/v1/jobs/{id}/results"),
    ("get", "/v1/jobs/{id}/results/{path}"),
];

type Shared = Arc<State>;

/// Builds the router.
pub fn router(state: Shared, stop: watch::Receiver<bool>) -> Router {
    let limit = state.config.max_body_bytes;
    Router::new()
        .route("/v1/health", get(health))
        .route("/metrics", get(metrics))
        .route("/v1/plugins", get(plugins))
        .route("/v1/jobs", get(list_jobs).post(submit))
        .route("/v1/jobs/{id}", get(get_job).delete(cancel_job))
        .route("/v1/jobs/{id}/events", get(events))
        .route("/v1/jobs/{id}/files", get(files))
        .route("/v1/jobs/{id}/results", get(results_root))
        .route("/v1/jobs/{id}/results/{*path}", get(results))
        .fallback(|| async { ApiError::not_found("no such route") })
        .layer(middleware::from_fn_with_state(state.clone(), authorize))
        .layer(middleware::from_fn_with_state(state.clone(), log_request))
        .layer(DefaultBodyLimit::max(limit))
        .layer(Extension(stop))
        .with_state(state)
}

/// Who is asking: a user of the token file, or (without one) the single-token or open
/// service's one anonymous caller, who sees everything as before users existed.
#[derive(Clone, Debug)]
pub(crate) struct Caller {
    /// The user's name; `None` without a token file.
    pub name: Option<String>,
    /// Sees and cancels every job, reads `/metrics`.
    pub admin: bool,
}

impl Caller {
    /// Whether this caller may see a job owned by `owner`.
    fn may_see(&self, owner: Option<&str>) -> bool {
        self.admin || (self.name.is_some() && self.name.as_deref() == owner)
    }
}

fn unauthorized() -> Response {
    ApiError::new(
        StatusCode::UNAUTHORIZED,
        "unauthorized",
        "a valid `Authorization: Bearer <token>` header is required",
    )
    .into_response()
}

/// Finds the caller from the bearer token (a token file's users, or the one `--token`), or
/// answers 401; `/v1/health` needs no token.
async fn authorize(
    axum::extract::State(state): axum::extract::State<Shared>,
    mut request: Request,
    next: Next,
) -> Response {
    let presented = request
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|h| h.to_str().ok())
        .and_then(|h| h.strip_prefix("Bearer "))
        .map(str::to_string);
    let health = request.uri().path() == "/v1/health";
    let caller = if let Some(users) = &state.config.users {
        match presented.as_deref().and_then(|t| users.authenticate(t)) {
            Some(user) => Caller {
                name: Some(user.name.clone()),
                admin: user.admin,
            },
            None if health => Caller {
                name: None,
                admin: false,
            },
            None => return unauthorized(),
        }
    } else {
        if let Some(token) = &state.config.token
            && !health
        {
            use subtle::ConstantTimeEq;
            let expected = crate::users::token_hash(token);
            let given = crate::users::token_hash(presented.as_deref().unwrap_or(""));
            if presented.is_none() || !bool::from(expected.ct_eq(&given)) {
                return unauthorized();
            }
        }
        Caller {
            name: None,
            admin: true,
        }
    };
    let logged = LoggedUser(caller.name.clone().unwrap_or_else(|| "-".into()));
    request.extensions_mut().insert(caller);
    let mut response = next.run(request).await;
    response.extensions_mut().insert(logged);
    response
}

fn forbidden(message: impl Into<String>) -> ApiError {
    ApiError::new(StatusCode::FORBIDDEN, "forbidden", message)
}

/// One log line per request (method, path, status, duration, user), and the request count
/// for `/metrics`. The user is what [`authorize`] found, passed back in the response's
/// extensions.
async fn log_request(
    axum::extract::State(state): axum::extract::State<Shared>,
    request: Request,
    next: Next,
) -> Response {
    let start = std::time::Instant::now();
    let method = request.method().clone();
    let path = request.uri().path().to_string();
    let response = next.run(request).await;
    let status = response.status().as_u16();
    let user = response
        .extensions()
        .get::<LoggedUser>()
        .map_or("-", |u| u.0.as_str())
        .to_string();
    state.metrics.request(method.as_str(), status);
    tracing::info!(
        method = %method,
        path = %path,
        status,
        duration_ms = start.elapsed().as_secs_f64() * 1000.0,
        user = %user,
        "request"
    );
    response
}

/// The user a request was made as, for the request's log line.
#[derive(Clone)]
pub(crate) struct LoggedUser(pub String);

/// Prometheus text exposition of the queue (from the database) and this process's counters.
async fn metrics(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
) -> Result<Response, ApiError> {
    if !caller.admin {
        return Err(forbidden("/metrics is for admin tokens"));
    }
    let by_state = state.db.count_by_status().await?;
    let running = state.db.running_leases().await?;
    let text = state.metrics.render(&by_state, &running);
    Ok((
        [(
            header::CONTENT_TYPE,
            "text/plain; version=0.0.4; charset=utf-8",
        )],
        text,
    )
        .into_response())
}

async fn health() -> Json<serde_json::Value> {
    Json(serde_json::json!({ "status": "ok", "version": mpm_core::VERSION }))
}

async fn plugins(
    axum::extract::State(state): axum::extract::State<Shared>,
) -> Json<serde_json::Value> {
    Json(state.registry.catalogue())
}

/// Turns a body rejection (too large, unreadable) into a JSON error.
fn body_error(e: BytesRejection) -> ApiError {
    let status = e.status();
    let code = if status == StatusCode::PAYLOAD_TOO_LARGE {
        "body_too_large"
    } else {
        "bad_body"
    };
    ApiError::new(status, code, e.body_text())
}

async fn submit(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let body = body.map_err(body_error)?;
    let json_type = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.split(';').next().unwrap_or("").trim() == "application/json");
    if !json_type {
        return Err(ApiError::new(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "unsupported_media_type",
            "send the scene as `Content-Type: application/json`",
        ));
    }
    let value: serde_json::Value = serde_json::from_slice(&body).map_err(|e| {
        ApiError::new(
            StatusCode::BAD_REQUEST,
            "bad_json",
            format!("the body is not valid JSON: {e}"),
        )
    })?;
    let checked = validate_within_budget(&state, value).await?;
    if checked.particles > state.config.max_particles {
        return Err(too_many_particles(
            checked.particles.to_string(),
            state.config.max_particles,
        ));
    }
    let id = uuid::Uuid::new_v4().to_string();
    let inserted = state
        .db
        .insert(
            &id,
            &checked.name,
            &checked.scene,
            checked.particles,
            checked.end_time,
            caller.name.as_deref(),
            state.config.max_queued,
            state
                .config
                .users
                .as_ref()
                .map(|_| state.config.max_queued_per_user),
        )
        .await?;
    match inserted {
        db::Inserted::Queued => {}
        db::Inserted::UserQueueFull => {
            return Err(ApiError::new(
                StatusCode::TOO_MANY_REQUESTS,
                "user_queue_full",
                format!(
                    "you have {} jobs queued, the most a user may have; try later",
                    state.config.max_queued_per_user
                ),
            ));
        }
        db::Inserted::QueueFull => {
            return Err(ApiError::new(
                StatusCode::TOO_MANY_REQUESTS,
                "queue_full",
                format!(
                    "the queue holds its maximum of {} jobs; try later",
                    state.config.max_queued
                ),
            ));
        }
    }
    state.jobs.wake.notify_one();
    tracing::info!(
        job = %id,
        name = %checked.name,
        particles = checked.particles,
        owner = caller.name.as_deref().unwrap_or("-"),
        "job queued"
    );
    let row = state
        .db
        .get(&id)
        .await?
        .ok_or_else(|| ApiError::internal("job vanished"))?;
    let location = format!("/v1/jobs/{id}");
    let mut response = (StatusCode::ACCEPTED, Json(row.view())).into_response();
    response.headers_mut().insert(
        header::LOCATION,
        HeaderValue::from_str(&location).map_err(ApiError::internal)?,
    );
    Ok(response)
}

/// 422 for a scene with more particles than the server accepts.
fn too_many_particles(count: String, max: usize) -> ApiError {
    ApiError::new(
        StatusCode::UNPROCESSABLE_ENTITY,
        "too_many_particles",
        format!("the scene has {count} particles; this server accepts at most {max}"),
    )
}

/// Validates a scene on a blocking thread, at most `max_validations` at once and within
/// `validation_timeout` (waiting for a turn included). A validation past its budget keeps
/// its permit until it ends, so stragglers cannot pile up.
async fn validate_within_budget(
    state: &Shared,
    value: serde_json::Value,
) -> Result<CheckedScene, ApiError> {
    let budget = state.config.validation_timeout;
    let deadline = tokio::time::Instant::now() + budget;
    let permit = tokio::time::timeout_at(deadline, state.validations.clone().acquire_owned())
        .await
        .map_err(|_| {
            ApiError::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "busy",
                format!(
                    "{} validations are running and none ended within the budget of {} s; try later",
                    state.config.max_validations,
                    budget.as_secs_f64()
                ),
            )
        })?
        .map_err(ApiError::internal)?;
    let registry = state.registry.clone();
    let data_dir = state.config.data_dir.clone();
    let mut limits = state.config.limits;
    limits.max_particles = limits.max_particles.min(state.config.max_particles as u64);
    let bounds = JobBounds {
        max_particles: state.config.max_particles,
        max_grid_bytes: state.config.max_grid_bytes,
        max_steps: state.config.max_steps,
    };
    let task = tokio::task::spawn_blocking(move || {
        let _permit = permit;
        check_scene(value, &registry, &data_dir, &limits, &bounds)
    });
    match tokio::time::timeout_at(deadline, task).await {
        Ok(joined) => joined.map_err(ApiError::internal)?,
        Err(_) => Err(ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "validation_budget",
            format!(
                "validating the scene took longer than this server's budget of {} s; make it \
                 smaller (fewer particles, holes or frames)",
                budget.as_secs_f64()
            ),
        )),
    }
}

struct CheckedScene {
    name: String,
    scene: String,
    particles: usize,
    end_time: f64,
}

/// The service's own bounds on a job's work, beyond the scene limits.
struct JobBounds {
    max_particles: usize,
    max_grid_bytes: Option<u64>,
    max_steps: Option<u64>,
}

/// Bytes of grid storage per node: mass, momentum, force and the previous velocity.
fn grid_bytes_per_node(dimension: u8) -> f64 {
    8.0 * (1.0 + 3.0 * f64::from(dimension))
}

/// Validates a submitted scene exactly as `mpm validate` does, then against the service's
/// bounds (particles, grid bytes, steps); particle files are refused (a request must not read
/// files of the server).
fn check_scene(
    value: serde_json::Value,
    registry: &mpm_core::plugin::Registry,
    data_dir: &std::path::Path,
    limits: &mpm_core::scene::Limits,
    bounds: &JobBounds,
) -> Result<CheckedScene, ApiError> {
    let max_particles = bounds.max_particles;
    let invalid = |problems: Vec<Problem>| {
        let mut e = ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_scene",
            "the scene is invalid; see `problems`",
        );
        e.problems = problems;
        e
    };
    if let Some(bodies) = value.get("bodies").and_then(|b| b.as_array()) {
        let problems: Vec<Problem> = bodies
            .iter()
            .enumerate()
            .filter(|(_, b)| b.pointer("/shape/file").is_some())
            .map(|(i, _)| Problem {
                path: format!("bodies[{i}].shape.file"),
                message: "particle files are not accepted by the job service; submit shapes".into(),
            })
            .collect();
        if !problems.is_empty() {
            return Err(invalid(problems));
        }
    }
    // The particle count is estimated from the shapes before any is generated.
    if let Ok(scene) = mpm_core::scene::deserialize_at::<mpm_core::scene::Scene>(&value, "$") {
        let estimated = mpm_core::scene::estimate(&scene);
        let estimate = estimated.particles();
        if estimate > max_particles as f64 {
            return Err(too_many_particles(
                format!("about {estimate:.3e} (estimated from its shapes)"),
                max_particles,
            ));
        }
        if let Some(max) = bounds.max_grid_bytes {
            let bytes = estimated.grid_nodes * grid_bytes_per_node(scene.dimension);
            if bytes > max as f64 {
                return Err(invalid(vec![Problem {
                    path: "domain.cell_size".into(),
                    message: format!(
                        "the grid would take about {bytes:.3e} bytes ({:.3e} nodes of {} bytes); \
                         this server accepts at most {max} (--max-grid-bytes): a larger cell size \
                         or a smaller domain",
                        estimated.grid_nodes,
                        grid_bytes_per_node(scene.dimension)
                    ),
                }]));
            }
        }
    }
    let validated = mpm_core::scene::parse_scene_value_limited(value, registry, data_dir, limits)
        .map_err(|e| {
        invalid(
            e.issues
                .into_iter()
                .map(|i| Problem {
                    path: i.path,
                    message: i.message,
                })
                .collect(),
        )
    })?;
    if let Err(e) = mpm_core::solver::preflight(&validated) {
        let (path, message) = match e {
            mpm_core::solver::RunError::Refused { path, message } => (path, message),
            other => ("$".to_string(), other.to_string()),
        };
        return Err(invalid(vec![Problem { path, message }]));
    }
    if let Some(max) = bounds.max_steps {
        let steps = mpm_core::solver::estimated_steps(&validated);
        if steps > max as f64 {
            let path = if validated.scene.solver.dt.is_some() {
                "solver.dt"
            } else {
                "solver.end_time"
            };
            return Err(invalid(vec![Problem {
                path: path.into(),
                message: format!(
                    "the run would take about {steps:.3e} time steps (end_time over the initial \
                     step); this server accepts at most {max} per job (--max-steps)"
                ),
            }]));
        }
    }
    Ok(CheckedScene {
        name: validated.scene.name.clone(),
        scene: validated.json.to_string(),
        particles: validated.particle_count(),
        end_time: validated.scene.solver.end_time,
    })
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
async fn find(state: &State, raw: &str, caller: &Caller) -> Result<db::JobRow, ApiError> {
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
    let root = worker::results_path(&state, &row.id);
    let list = tokio::task::spawn_blocking(move || {
        let mut out = Vec::new();
        let mut stack = vec![root.clone()];
        while let Some(dir) = stack.pop() {
            let Ok(entries) = std::fs::read_dir(&dir) else {
                continue;
            };
            for entry in entries.flatten() {
                let path = entry.path();
                if path.is_dir() {
                    stack.push(path);
                } else if let Ok(rel) = path.strip_prefix(&root) {
                    out.push(rel.to_string_lossy().replace('\\', "/"));
                }
            }
        }
        out.sort();
        out
    })
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
    let relative = PathBuf::from(path);
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
    let full = worker::results_path(state, &row.id).join(&relative);
    match tokio::fs::read(&full).await {
        Ok(bytes) => {
            let kind = if path.ends_with(".json") {
                "application/json"
            } else {
                "application/octet-stream"
            };
            Ok(([(header::CONTENT_TYPE, kind)], bytes).into_response())
        }
        Err(_) => Err(ApiError::not_found(format!(
            "no file `{path}` in the results"
        ))),
    }
}
