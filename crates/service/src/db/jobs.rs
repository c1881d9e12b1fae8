//! Queries on the job table: submission, listing, claims with a lease, heartbeats, progress,
//! final states, cancellation and requeueing. Every write that belongs to a run is guarded
//! by the claiming worker's name and a live lease, so a worker that lost its job (its lease
//! expired and another worker took it) can change nothing.

use super::{COLUMNS, Db, JobRow, on_backend};
use sqlx::Row as _;

/// What an insertion did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Inserted {
    /// The job is queued.
    Queued,
    /// The whole queue is full.
    QueueFull,
    /// The submitting user's share of the queue is full.
    UserQueueFull,
}

/// A job to queue: what the submission checked.
#[derive(Debug, Clone, Copy)]
pub struct NewJob<'a> {
    /// Job id.
    pub id: &'a str,
    /// The scene's name.
    pub name: &'a str,
    /// The validated scene (JSON text).
    pub scene: &'a str,
    /// Particle count.
    pub particles: usize,
    /// The simulated time the run ends at.
    pub end_time: f64,
    /// A staged scene's `[[name, end_time], ...]` (JSON text).
    pub stages: Option<&'a str>,
    /// The submitting user.
    pub owner: Option<&'a str>,
    /// Where the run starts from, when not from the scene itself.
    pub start: Option<StartFrom<'a>>,
}

/// A job's start from another job's stored state.
#[derive(Debug, Clone, Copy)]
pub struct StartFrom<'a> {
    /// The job whose store holds the state.
    pub job: &'a str,
    /// The stage the run starts at (a staged scene; `None`: the latest checkpoint).
    pub stage: Option<&'a str>,
    /// The simulated time of the state.
    pub time: f64,
}

/// A job a worker has just claimed.
#[derive(Debug, Clone)]
pub struct Claimed {
    /// Job id.
    pub id: String,
    /// The validated scene (JSON text).
    pub scene: String,
    /// Which run of the job this is (1 for the first).
    pub attempt: i64,
    /// Particle count, for the particle-steps rate.
    pub particles: i64,
    /// Seconds the job waited in the queue (from submission, or from its requeueing).
    pub waited: f64,
    /// The job whose stored state the run starts from, if any.
    pub from_job: Option<String>,
    /// The stage it starts at (with `from_job`, a staged scene).
    pub from_stage: Option<String>,
}

/// One job requeued (or cancelled) because its worker's lease ran out.
#[derive(Debug, Clone)]
pub struct Requeued {
    /// Job id.
    pub id: String,
    /// The worker that lost it.
    pub worker: Option<String>,
    /// The state it went to: `queued`, or `cancelled` when a cancel was pending.
    pub status: String,
}

impl Db {
    /// Inserts a queued job unless the queue (`max_queued`) or the owner's share of it
    /// (`max_per_user`, for owned jobs) is full.
    pub async fn insert(
        &self,
        job: &NewJob<'_>,
        max_queued: usize,
        max_per_user: Option<usize>,
    ) -> Result<Inserted, sqlx::Error> {
        let count =
            "SELECT COUNT(*) FROM jobs WHERE status = 'queued' AND (?1 IS NULL OR owner = ?1)";
        let insert = "INSERT INTO jobs (id, name, status, scene, particles, end_time, owner, stages, \
             from_job, from_stage, start_time) \
             SELECT ?1, ?2, 'queued', ?3, ?4, ?5, ?6, ?9, ?10, ?11, ?12 \
             WHERE (SELECT COUNT(*) FROM jobs WHERE status = 'queued') < ?7 \
             AND (?8 < 0 OR (SELECT COUNT(*) FROM jobs WHERE status = 'queued' AND owner = ?6) < ?8)";
        let per_user = max_per_user.map_or(-1, |m| m as i64);
        let done = on_backend!(self, pool, sql = insert, {
            // Counting and inserting must not interleave with another submission's: SQLite
            // runs one writer at a time; PostgreSQL takes a transaction-scoped lock.
            let mut tx = pool.begin().await?;
            if matches!(self, Db::Postgres(_)) {
                sqlx::query("SELECT pg_advisory_xact_lock(2727)")
                    .execute(&mut *tx)
                    .await?;
            }
            let done = sqlx::query(&sql)
                .bind(job.id)
                .bind(job.name)
                .bind(job.scene)
                .bind(job.particles as i64)
                .bind(job.end_time)
                .bind(job.owner)
                .bind(max_queued as i64)
                .bind(per_user)
                .bind(job.stages)
                .bind(job.start.map(|s| s.job))
                .bind(job.start.and_then(|s| s.stage))
                .bind(job.start.map_or(0.0, |s| s.time))
                .execute(&mut *tx)
                .await?;
            tx.commit().await?;
            done.rows_affected()
        });
        if done == 1 {
            return Ok(Inserted::Queued);
        }
        let total: i64 = on_backend!(self, pool, sql = count, {
            sqlx::query_scalar(&sql)
                .bind(None::<&str>)
                .fetch_one(pool)
                .await?
        });
        Ok(if total as usize >= max_queued {
            Inserted::QueueFull
        } else {
            Inserted::UserQueueFull
        })
    }

    /// One job.
    pub async fn get(&self, id: &str) -> Result<Option<JobRow>, sqlx::Error> {
        let text = format!("SELECT {COLUMNS} FROM jobs WHERE id = ?1");
        Ok(on_backend!(self, pool, sql = &text, {
            sqlx::query_as::<_, JobRow>(&sql)
                .bind(id)
                .fetch_optional(pool)
                .await?
        }))
    }

    /// The scene (JSON text) of job `id`.
    pub async fn scene(&self, id: &str) -> Result<Option<String>, sqlx::Error> {
        let text = "SELECT scene FROM jobs WHERE id = ?1";
        Ok(on_backend!(self, pool, sql = text, {
            sqlx::query_scalar::<_, String>(&sql)
                .bind(id)
                .fetch_optional(pool)
                .await?
        }))
    }

    /// A page of jobs in submission order, optionally of one status and one owner; and the
    /// total count.
    pub async fn list(
        &self,
        status: Option<&str>,
        owner: Option<&str>,
        limit: i64,
        offset: i64,
    ) -> Result<(Vec<JobRow>, i64), sqlx::Error> {
        let filter = "(?1 IS NULL OR status = ?1) AND (?2 IS NULL OR owner = ?2)";
        let rows_text =
            format!("SELECT {COLUMNS} FROM jobs WHERE {filter} ORDER BY seq LIMIT ?3 OFFSET ?4");
        let count_text = format!("SELECT COUNT(*) FROM jobs WHERE {filter}");
        Ok(on_backend!(self, pool, sql = &rows_text, {
            let rows = sqlx::query_as::<_, JobRow>(&sql)
                .bind(status)
                .bind(owner)
                .bind(limit)
                .bind(offset)
                .fetch_all(pool)
                .await?;
            let count_sql = self.text(&count_text);
            let total: i64 = sqlx::query_scalar(&count_sql)
                .bind(status)
                .bind(owner)
                .fetch_one(pool)
                .await?;
            (rows, total)
        }))
    }

    /// Counts jobs by status (for `/metrics`).
    pub async fn count_by_status(&self) -> Result<Vec<(String, i64)>, sqlx::Error> {
        Ok(on_backend!(
            self,
            pool,
            sql = "SELECT status, COUNT(*) FROM jobs GROUP BY status",
            {
                sqlx::query_as::<_, (String, i64)>(&sql)
                    .fetch_all(pool)
                    .await?
            }
        ))
    }

    /// The worker and seconds left of the lease of every running job (for `/metrics`).
    pub async fn running_leases(&self) -> Result<Vec<(String, f64)>, sqlx::Error> {
        let text = "SELECT COALESCE(worker, ''), COALESCE(lease_until, 0) - {epoch} FROM jobs \
                    WHERE status = 'running' ORDER BY seq";
        Ok(on_backend!(self, pool, sql = text, {
            sqlx::query_as::<_, (String, f64)>(&sql)
                .fetch_all(pool)
                .await?
        }))
    }

    /// Takes the oldest queued job for `worker` with a lease of `lease_seconds`, and records
    /// the run. SQLite: one autocommit `UPDATE ... WHERE id = (SELECT ... LIMIT 1) AND status =
    /// 'queued'` (one writer at a time). PostgreSQL: the sub-select locks its row with `FOR
    /// UPDATE SKIP LOCKED`, so concurrent workers each take a different job without waiting.
    pub async fn claim(
        &self,
        worker: &str,
        lease_seconds: f64,
    ) -> Result<Option<Claimed>, sqlx::Error> {
        let lock = match self {
            Db::Sqlite(_) => "",
            Db::Postgres(_) => "FOR UPDATE SKIP LOCKED",
        };
        let text = format!(
            "UPDATE jobs SET status = 'running', attempts = attempts + 1, started_at = {{now}}, \
             worker = ?1, lease_until = {{epoch}} + ?2 \
             WHERE id = (SELECT id FROM jobs WHERE status = 'queued' ORDER BY seq LIMIT 1 {lock}) \
             AND status = 'queued' RETURNING id, scene, attempts, particles, created_at, from_job, from_stage"
        );
        let run = "INSERT INTO job_runs (job_id, attempt, worker) VALUES (?1, ?2, ?3)";
        let claimed = on_backend!(self, pool, sql = &text, {
            let row = sqlx::query(&sql)
                .bind(worker)
                .bind(lease_seconds)
                .fetch_optional(pool)
                .await?;
            match row {
                None => None,
                Some(row) => {
                    let id: String = row.try_get(0)?;
                    let attempt: i64 = row.try_get(2)?;
                    let run_sql = self.text(run);
                    sqlx::query(&run_sql)
                        .bind(&id)
                        .bind(attempt)
                        .bind(worker)
                        .execute(pool)
                        .await?;
                    Some(Claimed {
                        id,
                        scene: row.try_get(1)?,
                        attempt,
                        particles: row.try_get(3)?,
                        waited: seconds_since(&row.try_get::<String, _>(4)?),
                        from_job: row.try_get(5)?,
                        from_stage: row.try_get(6)?,
                    })
                }
            }
        });
        Ok(claimed)
    }

    /// Renews a running job's lease for `worker`. `None`: the lease was lost (expired, or the
    /// job is no longer this worker's) and the worker must stop the run; `Some(cancel)`:
    /// renewed, with whether a cancellation was requested (from any API process).
    pub async fn heartbeat(
        &self,
        id: &str,
        worker: &str,
        lease_seconds: f64,
    ) -> Result<Option<bool>, sqlx::Error> {
        let text = "UPDATE jobs SET lease_until = {epoch} + ?3 \
                    WHERE id = ?1 AND worker = ?2 AND status = 'running' AND lease_until >= {epoch} \
                    RETURNING cancel_requested";
        let row: Option<i64> = on_backend!(self, pool, sql = text, {
            sqlx::query_scalar(&sql)
                .bind(id)
                .bind(worker)
                .bind(lease_seconds)
                .fetch_optional(pool)
                .await?
        });
        Ok(row.map(|c| c != 0))
    }

    /// Records progress of a running job.
    pub async fn progress(
        &self,
        id: &str,
        worker: &str,
        step: u64,
        time: f64,
        wall: f64,
    ) -> Result<(), sqlx::Error> {
        let text = "UPDATE jobs SET step = ?3, sim_time = ?4, wall_seconds = ?5 \
                    WHERE id = ?1 AND worker = ?2 AND status = 'running'";
        on_backend!(self, pool, sql = text, {
            sqlx::query(&sql)
                .bind(id)
                .bind(worker)
                .bind(step as i64)
                .bind(time)
                .bind(wall)
                .execute(pool)
                .await?
                .rows_affected()
        });
        Ok(())
    }

    /// Puts a running job in a final state with its metrics and failure (JSON texts), if
    /// `worker` still holds its lease; returns whether it did. The run's row gets the same
    /// outcome.
    #[allow(clippy::too_many_arguments)]
    pub async fn finish(
        &self,
        id: &str,
        worker: &str,
        attempt: i64,
        status: &str,
        metrics: Option<String>,
        failure: Option<String>,
        progress: Option<(u64, f64, f64)>,
    ) -> Result<bool, sqlx::Error> {
        let (step, time, wall) = progress.unwrap_or((0, 0.0, 0.0));
        let text = "UPDATE jobs SET status = ?2, metrics = ?3, failure = ?4, \
             step = CASE WHEN ?5 THEN ?6 ELSE step END, \
             sim_time = CASE WHEN ?5 THEN ?7 ELSE sim_time END, \
             wall_seconds = CASE WHEN ?5 THEN ?8 ELSE wall_seconds END, \
             lease_until = NULL, finished_at = {now} \
             WHERE id = ?1 AND worker = ?9 AND status = 'running' AND lease_until >= {epoch}";
        let run =
            "UPDATE job_runs SET outcome = ?3, ended_at = {now} WHERE job_id = ?1 AND attempt = ?2";
        let done = on_backend!(self, pool, sql = text, {
            let mut tx = pool.begin().await?;
            let done = sqlx::query(&sql)
                .bind(id)
                .bind(status)
                .bind(metrics)
                .bind(failure)
                .bind(progress.is_some())
                .bind(step as i64)
                .bind(time)
                .bind(wall)
                .bind(worker)
                .execute(&mut *tx)
                .await?
                .rows_affected()
                == 1;
            if done {
                let run_sql = self.text(run);
                sqlx::query(&run_sql)
                    .bind(id)
                    .bind(attempt)
                    .bind(status)
                    .execute(&mut *tx)
                    .await?;
            }
            tx.commit().await?;
            done
        });
        Ok(done)
    }

    /// Cancels a queued job; returns whether it was queued.
    pub async fn cancel_queued(&self, id: &str) -> Result<bool, sqlx::Error> {
        let text = "UPDATE jobs SET status = 'cancelled', finished_at = {now} \
                    WHERE id = ?1 AND status = 'queued'";
        Ok(self.execute_with(text, id).await? == 1)
    }

    /// Marks a running job's cancellation as requested; its worker sees it at its next
    /// heartbeat (and survives a restart).
    pub async fn request_cancel(&self, id: &str) -> Result<bool, sqlx::Error> {
        let text = "UPDATE jobs SET cancel_requested = 1 WHERE id = ?1 AND status = 'running'";
        Ok(self.execute_with(text, id).await? == 1)
    }

    /// Requeues running jobs whose lease has run out (their worker died or lost the
    /// database): back to `queued` to rerun from the start, or `cancelled` when a cancel was
    /// pending. Their run rows end `lease_expired`. A lease that has run out is never renewed
    /// (heartbeat and finish check it), so the two statements see the same jobs.
    pub async fn requeue_expired(&self) -> Result<Vec<Requeued>, sqlx::Error> {
        let runs = "UPDATE job_runs SET outcome = 'lease_expired', ended_at = {now} \
             WHERE outcome IS NULL AND EXISTS (SELECT 1 FROM jobs j WHERE j.id = job_runs.job_id \
             AND j.attempts = job_runs.attempt AND j.status = 'running' AND j.lease_until < ?1)";
        let jobs = "UPDATE jobs SET \
             status = CASE WHEN cancel_requested = 1 THEN 'cancelled' ELSE 'queued' END, \
             finished_at = CASE WHEN cancel_requested = 1 THEN {now} ELSE NULL END, \
             step = 0, sim_time = 0, wall_seconds = 0, lease_until = NULL \
             WHERE status = 'running' AND lease_until < ?1 RETURNING id, worker, status";
        Ok(on_backend!(self, pool, sql = jobs, {
            let cutoff_sql = self.text("SELECT {epoch}");
            let cutoff: f64 = sqlx::query_scalar(&cutoff_sql).fetch_one(pool).await?;
            let runs_sql = self.text(runs);
            sqlx::query(&runs_sql).bind(cutoff).execute(pool).await?;
            sqlx::query_as::<_, (String, Option<String>, String)>(&sql)
                .bind(cutoff)
                .fetch_all(pool)
                .await?
                .into_iter()
                .map(|(id, worker, status)| Requeued { id, worker, status })
                .collect()
        }))
    }

    /// Gives back the running jobs of `worker` at once (a clean shutdown): they are
    /// requeued as if their lease had run out.
    pub async fn release(&self, worker: &str) -> Result<Vec<Requeued>, sqlx::Error> {
        let text = "UPDATE jobs SET lease_until = 0 WHERE worker = ?1 AND status = 'running'";
        self.execute_with(text, worker).await?;
        self.requeue_expired().await
    }

    /// Every job left running when a single-process SQLite service stopped goes back to the
    /// queue at its next start (or to `cancelled`), whatever its lease: with SQLite, the
    /// service's own workers are the only ones. Returns how many were requeued.
    pub async fn requeue_interrupted(&self) -> Result<u64, sqlx::Error> {
        let text = "UPDATE jobs SET lease_until = 0 WHERE status = 'running'";
        on_backend!(self, pool, sql = text, {
            sqlx::query(&sql).execute(pool).await?.rows_affected()
        });
        Ok(self
            .requeue_expired()
            .await?
            .iter()
            .filter(|r| r.status == "queued")
            .count() as u64)
    }
}

/// Seconds since the epoch of a stored timestamp (`%Y-%m-%dT%H:%M:%S.fffZ`, UTC).
pub(crate) fn epoch_of(stamp: &str) -> Option<f64> {
    let (date, time) = stamp.trim_end_matches('Z').split_once('T')?;
    let mut d = date.split('-').map(|p| p.parse::<i64>());
    let (y, m, day) = (d.next()?.ok()?, d.next()?.ok()?, d.next()?.ok()?);
    let mut t = time.split(':');
    let (h, min) = (
        t.next()?.parse::<f64>().ok()?,
        t.next()?.parse::<f64>().ok()?,
    );
    let s = t.next()?.parse::<f64>().ok()?;
    // Days from the civil date (Howard Hinnant's algorithm).
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = era * 146_097 + doe - 719_468;
    Some(days as f64 * 86_400.0 + h * 3600.0 + min * 60.0 + s)
}

/// Seconds from a stored timestamp to now; 0 if unreadable.
fn seconds_since(stamp: &str) -> f64 {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64());
    epoch_of(stamp).map_or(0.0, |t| (now - t).max(0.0))
}

#[cfg(test)]
mod tests {
    #[test]
    fn timestamps_read_back() {
        assert!(super::seconds_since("1970-01-01T00:00:00.000Z") > 1.7e9);
        assert_eq!(super::seconds_since("garbage"), 0.0);
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_secs_f64();
        // 2001-09-09T01:46:40Z is 1e9 s.
        let since = super::seconds_since("2001-09-09T01:46:40.000Z");
        assert!((now - since - 1e9).abs() < 5.0, "{since}");
    }
}
