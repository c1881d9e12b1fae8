//! What `/metrics` reads from the database, so that any process (an API without workers
//! included) shows every worker and every job: workers' heartbeats, and the times of the jobs
//! that ran.

use super::jobs::epoch_of;
use super::{Db, on_backend};

/// Times of one job that a worker claimed.
#[derive(Debug, Clone)]
pub struct JobTimes {
    /// Its status now.
    pub status: String,
    /// Seconds from submission to its (last) claim.
    pub waited: Option<f64>,
    /// Wall seconds of its (last) run.
    pub wall_seconds: f64,
    /// Particles times steps of its (last) run.
    pub particle_steps: f64,
}

impl Db {
    /// Records that `worker` is alive now (its loop turned or it renewed a lease).
    pub async fn worker_seen(&self, worker: &str) -> Result<(), sqlx::Error> {
        let text = "INSERT INTO workers (name, last_seen) VALUES (?1, {epoch}) \
                    ON CONFLICT (name) DO UPDATE SET last_seen = excluded.last_seen";
        self.execute_with(text, worker).await?;
        Ok(())
    }

    /// Forgets a worker that stopped cleanly (a dead one keeps its last heartbeat).
    pub async fn worker_gone(&self, worker: &str) -> Result<(), sqlx::Error> {
        self.execute_with("DELETE FROM workers WHERE name = ?1", worker)
            .await?;
        Ok(())
    }

    /// Every known worker with the seconds since the epoch of its last heartbeat, and the
    /// database's clock now.
    pub async fn workers(&self) -> Result<(Vec<(String, f64)>, f64), sqlx::Error> {
        Ok(on_backend!(
            self,
            pool,
            sql = "SELECT name, last_seen FROM workers ORDER BY name",
            {
                let rows = sqlx::query_as::<_, (String, f64)>(&sql)
                    .fetch_all(pool)
                    .await?;
                let now: f64 = sqlx::query_scalar(&self.text("SELECT {epoch}"))
                    .fetch_one(pool)
                    .await?;
                (rows, now)
            }
        ))
    }

    /// The times of every job a worker claimed.
    pub async fn job_times(&self) -> Result<Vec<JobTimes>, sqlx::Error> {
        let text = "SELECT status, created_at, started_at, wall_seconds, particles, step \
                    FROM jobs WHERE started_at IS NOT NULL AND status <> 'queued'";
        let rows: Vec<(String, String, String, f64, i64, i64)> =
            on_backend!(self, pool, sql = text, {
                sqlx::query_as(&sql).fetch_all(pool).await?
            });
        Ok(rows
            .into_iter()
            .map(
                |(status, created, started, wall, particles, step)| JobTimes {
                    status,
                    waited: epoch_of(&started)
                        .zip(epoch_of(&created))
                        .map(|(s, c)| (s - c).max(0.0)),
                    wall_seconds: wall,
                    particle_steps: particles as f64 * step as f64,
                },
            )
            .collect())
    }
}
