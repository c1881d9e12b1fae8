//! `POST /v1/jobs`: the body read by hand (every rejection gets the JSON error body), the
//! scene validated on a blocking thread within a budget and against the service's bounds,
//! then queued (with its owner) unless the queue or the user's share of it is full. A job
//! may start from another job's stored state (`?from=JOB[&stage=NAME]`, `submit_from.rs`).

use super::Shared;
use super::access::Caller;
use super::submit_from::{self, Source, StageIndex, SubmitQuery};
use crate::db;
use crate::error::{ApiError, Problem};
use axum::Extension;
use axum::Json;
use axum::body::Bytes;
use axum::extract::Query;
use axum::extract::rejection::{BytesRejection, QueryRejection};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};

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

pub(super) async fn submit(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
    query: Result<Query<SubmitQuery>, QueryRejection>,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let Query(query) =
        query.map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, "bad_query", e.body_text()))?;
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
    let source = submit_from::source(&state, &query, &caller).await?;
    let (checked, source) = validate_within_budget(&state, value, source).await?;
    if checked.particles > state.config.max_particles {
        return Err(too_many_particles(
            checked.particles.to_string(),
            state.config.max_particles,
        ));
    }
    let start_time = match &source {
        Some(source) => Some(
            submit_from::start_time(&state, source, &checked.validated, checked.stage_index)
                .await?,
        ),
        None => None,
    };
    let id = uuid::Uuid::new_v4().to_string();
    let job = db::NewJob {
        id: &id,
        name: &checked.name,
        scene: &checked.scene,
        particles: checked.particles,
        end_time: checked.end_time,
        stages: checked.stages.as_deref(),
        owner: caller.name.as_deref(),
        start: source
            .as_ref()
            .zip(start_time)
            .map(|(s, time)| db::StartFrom {
                job: &s.id,
                stage: s.stage.as_deref(),
                time,
            }),
    };
    let inserted = state
        .db
        .insert(
            &job,
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
        from = source.as_ref().map_or("-", |s| s.id.as_str()),
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
/// `validation_timeout` (waiting for a turn included), with the checks of a start from
/// `source`'s stored state. A validation past its budget keeps its permit until it ends, so
/// stragglers cannot pile up.
async fn validate_within_budget(
    state: &Shared,
    value: serde_json::Value,
    source: Option<Source>,
) -> Result<(CheckedScene, Option<Source>), ApiError> {
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
        let mut checked = check_scene(value, &registry, &data_dir, &limits, &bounds)?;
        if let Some(source) = &source {
            checked.stage_index = submit_from::check_scenes(source, &checked.validated, &registry)?;
        }
        let first = checked.stage_index.unwrap_or(0);
        check_steps(&checked.validated, first, bounds.max_steps)?;
        Ok((checked, source))
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
    /// The scene as validated (for the start checks).
    validated: mpm_core::scene::ValidatedScene,
    /// With `stage`: that stage's index.
    stage_index: StageIndex,
    name: String,
    scene: String,
    particles: usize,
    end_time: f64,
    /// A staged scene's `[[name, end_time], ...]` (JSON).
    stages: Option<String>,
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

/// Checks the time steps a job would take against the server's bound (`--max-steps`): a
/// staged scene's stages from `first` on (the stage a job starts at from a stored state).
fn check_steps(
    validated: &mpm_core::scene::ValidatedScene,
    first: usize,
    max: Option<u64>,
) -> Result<(), ApiError> {
    let Some(max) = max else { return Ok(()) };
    let steps = mpm_core::solver::estimated_steps_from(validated, first);
    if steps <= max as f64 {
        return Ok(());
    }
    let path = if validated.scene.solver.dt.is_some() {
        "solver.dt"
    } else {
        "solver.end_time"
    };
    let mut e = ApiError::new(
        StatusCode::UNPROCESSABLE_ENTITY,
        "invalid_scene",
        "the scene is invalid; see `problems`",
    );
    e.problems = vec![Problem {
        path: path.into(),
        message: format!(
            "the run would take about {steps:.3e} time steps (end_time over the initial step); \
             this server accepts at most {max} per job (--max-steps)"
        ),
    }];
    Err(e)
}

/// Validates a submitted scene exactly as `mpm validate` does, then against the service's
/// bounds (particles, grid bytes; the steps are [`check_steps`]'s); particle files are refused (a request must not read
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
        let estimated = mpm_core::scene::estimate(&scene, registry);
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
    Ok(CheckedScene {
        stage_index: None,
        name: validated.scene.name.clone(),
        scene: validated.json.to_string(),
        particles: validated.particle_count(),
        end_time: validated.end_time(),
        stages: (!validated.stages.is_empty()).then(|| {
            let list: Vec<(&str, f64)> = validated
                .stages
                .iter()
                .map(|s| (s.name.as_str(), s.scene.scene.solver.end_time))
                .collect();
            serde_json::to_string(&list).unwrap_or_default()
        }),
        validated,
    })
}
