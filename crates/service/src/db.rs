//! The job table: opening (WAL, migrations), claiming, progress and final states.

use crate::ServiceError;
use serde::Serialize;
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use sqlx::{FromRow, SqlitePool};
use std::path::Path;
use std::time::Duration;

/// Opens (creating if needed) the job database and applies the embedded migrations.
pub async fn open(path: &Path) -> Result<SqlitePool, ServiceError> {
    let options = SqliteConnectOptions::new()
        .filename(path)
        .create_if_missing(true)
        .journal_mode(SqliteJournalMode::Wal)
        .synchronous(SqliteSynchronous::Normal)
        .busy_timeout(Duration::from_secs(10));
    let pool = SqlitePoolOptions::new()
        .max_connections(8)
        .connect_with(options)
        .await?;
    sqlx::migrate!("./migrations").run(&pool).await?;
    Ok(pool)
}

/// Jobs that were running when the service last stopped go back to the queue (they rerun
/// from the start; the solver is deterministic, so the results are the same). Jobs whose
/// cancellation was requested are cancelled instead. Returns how many were requeued.
pub async fn requeue_interrupted(db: &SqlitePool) -> Result<u64, ServiceError> {
    sqlx::query(
        "UPDATE jobs SET status = 'cancelled', finished_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now') \
         WHERE status = 'running' AND cancel_requested = 1",
    )
    .execute(db)
    .await?;
    let done = sqlx::query(
        "UPDATE jobs SET status = 'queued', step = 0, sim_time = 0, wall_seconds = 0 \
         WHERE status = 'running'",
    )
    .execute(db)
    .await?;
    Ok(done.rows_affected())
}

/// A job row as the API shows it.
#[derive(Clone, Debug, FromRow)]
pub struct JobRow {
    pub id: String,
    pub name: String,
    pub status: String,
    pub particles: i64,
    pub end_time: f64,
    pub created_at: String,
    pub started_at: Option<String>,
    pub finished_at: Option<String>,
    pub step: i64,
    pub sim_time: f64,
    pub wall_seconds: f64,
    pub attempts: i64,
    pub metrics: Option<String>,
    pub failure: Option<String>,
}

const COLUMNS: &str = "id, name, status, particles, end_time, created_at, started_at, finished_at, \
                       step, sim_time, wall_seconds, attempts, metrics, failure";

/// Whether a status is final.
pub fn is_final(status: &str) -> bool {
    matches!(status, "succeeded" | "failed" | "cancelled")
}

/// The job as JSON for the API.
#[derive(Debug, Serialize)]
pub struct JobView {
    pub id: String,
    pub name: String,
    pub status: String,
    pub particles: i64,
    pub created_at: String,
    pub started_at: Option<String>,
    pub finished_at: Option<String>,
    pub attempts: i64,
    pub progress: Progress,
    pub metrics: Option<serde_json::Value>,
    pub failure: Option<serde_json::Value>,
    pub links: Links,
}

/// Progress of a job.
#[derive(Debug, Serialize)]
pub struct Progress {
    pub steps: i64,
    pub time: f64,
    pub end_time: f64,
    pub fraction: f64,
    pub wall_seconds: f64,
    pub eta_seconds: Option<f64>,
}

/// Where to find the rest of a job.
#[derive(Debug, Serialize)]
pub struct Links {
    #[serde(rename = "self")]
    pub this: String,
    pub events: String,
    pub results: String,
    pub files: String,
}

impl JobRow {
    /// The API view of this row.
    pub fn view(&self) -> JobView {
        let fraction = if self.status == "succeeded" {
            1.0
        } else {
            (self.sim_time / self.end_time).clamp(0.0, 1.0)
        };
        let eta = (self.status == "running" && fraction > 0.0)
            .then(|| self.wall_seconds * (1.0 - fraction) / fraction);
        let base = format!("/v1/jobs/{}", self.id);
        JobView {
            id: self.id.clone(),
            name: self.name.clone(),
            status: self.status.clone(),
            particles: self.particles,
            created_at: self.created_at.clone(),
            started_at: self.started_at.clone(),
            finished_at: self.finished_at.clone(),
            attempts: self.attempts,
            progress: Progress {
                steps: self.step,
                time: self.sim_time,
                end_time: self.end_time,
                fraction,
                wall_seconds: self.wall_seconds,
                eta_seconds: eta,
            },
            metrics: self
                .metrics
                .as_deref()
                .and_then(|m| serde_json::from_str(m).ok()),
            failure: self
                .failure
                .as_deref()
                .and_then(|m| serde_json::from_str(m).ok()),
            links: Links {
                events: format!("{base}/events"),
                results: format!("{base}/results"),
                files: format!("{base}/files"),
                this: base,
            },
        }
    }
}

/// Inserts a queued job unless the queue is full; returns false when it is.
pub async fn insert(
    db: &SqlitePool,
    id: &str,
    name: &str,
    scene: &str,
    particles: usize,
    end_time: f64,
    max_queued: usize,
) -> Result<bool, sqlx::Error> {
    let done = sqlx::query(
        "INSERT INTO jobs (id, name, status, scene, particles, end_time) \
         SELECT ?1, ?2, 'queued', ?3, ?4, ?5 \
         WHERE (SELECT COUNT(*) FROM jobs WHERE status = 'queued') < ?6",
    )
    .bind(id)
    .bind(name)
    .bind(scene)
    .bind(particles as i64)
    .bind(end_time)
    .bind(max_queued as i64)
    .execute(db)
    .await?;
    Ok(done.rows_affected() == 1)
}

/// One job.
pub async fn get(db: &SqlitePool, id: &str) -> Result<Option<JobRow>, sqlx::Error> {
    sqlx::query_as::<_, JobRow>(&format!("SELECT {COLUMNS} FROM jobs WHERE id = ?1"))
        .bind(id)
        .fetch_optional(db)
        .await
}

/// A page of jobs in submission order, optionally of one status; and the total count.
pub async fn list(
    db: &SqlitePool,
    status: Option<&str>,
    limit: i64,
    offset: i64,
) -> Result<(Vec<JobRow>, i64), sqlx::Error> {
    let rows = sqlx::query_as::<_, JobRow>(&format!(
        "SELECT {COLUMNS} FROM jobs WHERE (?1 IS NULL OR status = ?1) ORDER BY seq LIMIT ?2 OFFSET ?3"
    ))
    .bind(status)
    .bind(limit)
    .bind(offset)
    .fetch_all(db)
    .await?;
    let total: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM jobs WHERE (?1 IS NULL OR status = ?1)")
            .bind(status)
            .fetch_one(db)
            .await?;
    Ok((rows, total))
}

/// Takes the oldest queued job, atomically (one autocommit statement), and returns its id
/// and scene.
pub async fn claim(db: &SqlitePool) -> Result<Option<(String, String)>, sqlx::Error> {
    sqlx::query_as::<_, (String, String)>(
        "UPDATE jobs SET status = 'running', attempts = attempts + 1, \
         started_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now') \
         WHERE id = (SELECT id FROM jobs WHERE status = 'queued' ORDER BY seq LIMIT 1) \
         AND status = 'queued' RETURNING id, scene",
    )
    .fetch_optional(db)
    .await
}

/// Records progress of a running job.
pub async fn progress(
    db: &SqlitePool,
    id: &str,
    step: u64,
    time: f64,
    wall: f64,
) -> Result<(), sqlx::Error> {
    sqlx::query("UPDATE jobs SET step = ?2, sim_time = ?3, wall_seconds = ?4 WHERE id = ?1 AND status = 'running'")
        .bind(id)
        .bind(step as i64)
        .bind(time)
        .bind(wall)
        .execute(db)
        .await?;
    Ok(())
}

/// Puts a running job in a final state with its metrics and failure (JSON texts).
pub async fn finish(
    db: &SqlitePool,
    id: &str,
    status: &str,
    metrics: Option<String>,
    failure: Option<String>,
    progress: Option<(u64, f64, f64)>,
) -> Result<(), sqlx::Error> {
    let (step, time, wall) = progress.unwrap_or((0, 0.0, 0.0));
    sqlx::query(
        "UPDATE jobs SET status = ?2, metrics = ?3, failure = ?4, \
         step = CASE WHEN ?5 THEN ?6 ELSE step END, sim_time = CASE WHEN ?5 THEN ?7 ELSE sim_time END, \
         wall_seconds = CASE WHEN ?5 THEN ?8 ELSE wall_seconds END, \
         finished_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now') WHERE id = ?1 AND status = 'running'",
    )
    .bind(id)
    .bind(status)
    .bind(metrics)
    .bind(failure)
    .bind(progress.is_some())
    .bind(step as i64)
    .bind(time)
    .bind(wall)
    .execute(db)
    .await?;
    Ok(())
}

/// Cancels a queued job; returns whether it was queued.
pub async fn cancel_queued(db: &SqlitePool, id: &str) -> Result<bool, sqlx::Error> {
    let done = sqlx::query(
        "UPDATE jobs SET status = 'cancelled', finished_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now') \
         WHERE id = ?1 AND status = 'queued'",
    )
    .bind(id)
    .execute(db)
    .await?;
    Ok(done.rows_affected() == 1)
}

/// Marks a running job's cancellation as requested (survives a restart).
pub async fn request_cancel(db: &SqlitePool, id: &str) -> Result<bool, sqlx::Error> {
    let done =
        sqlx::query("UPDATE jobs SET cancel_requested = 1 WHERE id = ?1 AND status = 'running'")
            .bind(id)
            .execute(db)
            .await?;
    Ok(done.rows_affected() == 1)
}
