//! Who is asking and what they may see: bearer tokens (users of a token file, or the one
//! `--token`), one log line per request, and the admin's `/metrics`.

use super::Shared;
use crate::error::ApiError;
use axum::Extension;
use axum::extract::Request;
use axum::http::{StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

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
    pub(super) fn may_see(&self, owner: Option<&str>) -> bool {
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
pub(super) async fn authorize(
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

pub(super) fn forbidden(message: impl Into<String>) -> ApiError {
    ApiError::new(StatusCode::FORBIDDEN, "forbidden", message)
}

/// One log line per request (method, path, status, duration, user), and the request count
/// for `/metrics`. The user is what [`authorize`] found, passed back in the response's
/// extensions.
pub(super) async fn log_request(
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
pub(super) async fn metrics(
    axum::extract::State(state): axum::extract::State<Shared>,
    Extension(caller): Extension<Caller>,
) -> Result<Response, ApiError> {
    if !caller.admin {
        return Err(forbidden("/metrics is for admin tokens"));
    }
    let (workers, now) = state.db.workers().await?;
    let snapshot = crate::metrics::Snapshot {
        by_state: state.db.count_by_status().await?,
        running: state.db.running_leases().await?,
        workers,
        now,
        jobs: state.db.job_times().await?,
    };
    let text = state.metrics.render(&snapshot);
    Ok((
        [(
            header::CONTENT_TYPE,
            "text/plain; version=0.0.4; charset=utf-8",
        )],
        text,
    )
        .into_response())
}
