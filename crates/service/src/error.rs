//! Errors of the service, and the JSON error body every failed request gets.

use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde::Serialize;

/// Failures starting or running the service.
#[derive(Debug, thiserror::Error)]
pub enum ServiceError {
    /// A file or socket operation failed.
    #[error("{path}: {source}")]
    Io {
        /// What was being accessed.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The job database failed.
    #[error("job database: {0}")]
    Database(#[from] sqlx::Error),
    /// A migration failed.
    #[error("job database migration: {0}")]
    Migration(#[from] sqlx::migrate::MigrateError),
    /// The result store could not be opened (a missing bucket, an unreachable server, a
    /// folder that cannot be created). Its message already holds its causes (no `source`,
    /// so that `{:#}` does not print them twice).
    #[error("result store: {0}")]
    Store(crate::StoreError),
}

impl From<crate::StoreError> for ServiceError {
    fn from(e: crate::StoreError) -> Self {
        Self::Store(e)
    }
}

/// One problem in a request, at a JSON path of the submitted scene when there is one.
#[derive(Debug, Serialize)]
pub struct Problem {
    /// JSON path (`materials.steel.poisson_ratio`), or `$` for the whole body.
    pub path: String,
    /// What is wrong.
    pub message: String,
}

/// The body of every error response: `{"error": {"code", "message", "problems"}}`.
#[derive(Debug, Serialize)]
pub struct ApiError {
    #[serde(skip)]
    pub status: StatusCode,
    /// Short machine-readable code (`invalid_scene`, `not_found`, ...).
    pub code: &'static str,
    /// A sentence for people.
    pub message: String,
    /// Details, for invalid scenes.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub problems: Vec<Problem>,
}

impl ApiError {
    /// An error with no details.
    pub fn new(status: StatusCode, code: &'static str, message: impl Into<String>) -> Self {
        Self {
            status,
            code,
            message: message.into(),
            problems: Vec::new(),
        }
    }

    /// 404 with a JSON body.
    pub fn not_found(what: impl Into<String>) -> Self {
        Self::new(StatusCode::NOT_FOUND, "not_found", what)
    }

    /// 500 for a failure of the service itself (details are logged, not sent).
    pub fn internal(e: impl std::fmt::Display) -> Self {
        tracing::error!(error = %e, "internal error");
        Self::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            "internal",
            "the service failed to handle the request",
        )
    }
}

impl From<sqlx::Error> for ApiError {
    fn from(e: sqlx::Error) -> Self {
        Self::internal(e)
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let status = self.status;
        (status, axum::Json(serde_json::json!({ "error": self }))).into_response()
    }
}
