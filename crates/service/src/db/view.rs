//! A job row as read from the database, and its JSON view for the API.

use serde::Serialize;
use sqlx::FromRow;

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
    pub owner: Option<String>,
    pub worker: Option<String>,
    /// A staged scene's stages as JSON `[[name, end_time], ...]`.
    pub stages: Option<String>,
    /// The job whose stored state this one starts from.
    pub from_job: Option<String>,
    /// The stage it starts at (a staged scene).
    pub from_stage: Option<String>,
    /// The simulated time it starts at (0 for a job that starts from its scene).
    pub start_time: f64,
}

pub(crate) const COLUMNS: &str = "id, name, status, particles, end_time, created_at, started_at, finished_at, \
                       step, sim_time, wall_seconds, attempts, metrics, failure, owner, worker, stages, \
                       from_job, from_stage, start_time";

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
    /// The user who submitted it (when the service has users).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub owner: Option<String>,
    /// The worker running it, or that ran it last.
    pub worker: Option<String>,
    /// The stored state it starts from (a job submitted with `from`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub from: Option<StartView>,
    pub progress: Progress,
    pub metrics: Option<serde_json::Value>,
    pub failure: Option<serde_json::Value>,
    pub links: Links,
}

/// Where a job starts: another job's stored state.
#[derive(Debug, Serialize)]
pub struct StartView {
    /// The job whose store holds the state.
    pub job: String,
    /// The stage the run starts at, from the end of the stage before (a staged scene);
    /// absent: from that job's latest checkpoint.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stage: Option<String>,
    /// The simulated time it starts at.
    pub time: f64,
}

/// Progress of a job.
#[derive(Debug, Serialize)]
pub struct Progress {
    pub steps: i64,
    pub time: f64,
    /// The simulated time the run started at (not 0 for a job started from another's state).
    pub start_time: f64,
    pub end_time: f64,
    pub fraction: f64,
    pub wall_seconds: f64,
    pub eta_seconds: Option<f64>,
    /// The stage the run is in (a staged scene only): the first whose end time it has not
    /// passed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stage: Option<String>,
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
    /// The stage a staged job's clock is in.
    fn stage(&self) -> Option<String> {
        let stages: Vec<(String, f64)> = serde_json::from_str(self.stages.as_deref()?).ok()?;
        let tolerance = 1e-9 * self.end_time.abs();
        stages
            .iter()
            .find(|(_, end)| self.sim_time < end - tolerance)
            .or(stages.last())
            .map(|(name, _)| name.clone())
    }

    /// The API view of this row.
    pub fn view(&self) -> JobView {
        let fraction = if self.status == "succeeded" {
            1.0
        } else {
            let span = self.end_time - self.start_time;
            match self.sim_time > self.start_time && span > 0.0 {
                true => ((self.sim_time - self.start_time) / span).clamp(0.0, 1.0),
                false => 0.0,
            }
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
            owner: self.owner.clone(),
            worker: self.worker.clone(),
            from: self.from_job.as_ref().map(|job| StartView {
                job: job.clone(),
                stage: self.from_stage.clone(),
                time: self.start_time,
            }),
            progress: Progress {
                steps: self.step,
                time: self.sim_time,
                start_time: self.start_time,
                end_time: self.end_time,
                fraction,
                wall_seconds: self.wall_seconds,
                eta_seconds: eta,
                stage: self.stage(),
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
