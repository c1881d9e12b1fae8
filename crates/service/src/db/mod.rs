//! The job queue's database: SQLite (the default, one file, nothing to install) or
//! PostgreSQL (`postgres://...`, shared by an API and workers on several machines).
//!
//! One query layer over both: [`Db`] is an enum of the two pools, and every query is written
//! once with `?N` placeholders and the tokens `{now}` (a timestamp as text) and `{epoch}`
//! (seconds since the epoch, on the database's clock), translated for the backend by
//! [`on_backend!`]. Where the SQL must differ (the claim), the query says so in one `match`.
//! An enum rather than sqlx's `Any` driver: `Any` loses `RETURNING` column types and
//! PostgreSQL's row locks; rather than a trait: two backends, and each query stays readable
//! in one place.

mod jobs;
mod stats;
mod view;

pub use jobs::*;
pub use stats::*;
pub use view::*;

use crate::ServiceError;
use sqlx::postgres::{PgConnectOptions, PgPoolOptions};
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use sqlx::{PgPool, SqlitePool};
use std::path::Path;
use std::str::FromStr;
use std::time::Duration;

/// A connection pool to the job database, of either backend.
#[derive(Clone, Debug)]
pub enum Db {
    /// A local SQLite file (WAL).
    Sqlite(SqlitePool),
    /// A PostgreSQL server.
    Postgres(PgPool),
}

/// Whether a `--database` value names a PostgreSQL server.
pub fn is_postgres_url(url: &str) -> bool {
    url.starts_with("postgres://") || url.starts_with("postgresql://")
}

impl Db {
    /// Opens (creating if needed) the database named by `url`: `postgres://...` or
    /// `postgresql://...` for PostgreSQL, otherwise a SQLite file path (`sqlite://` optional);
    /// applies the backend's embedded migrations.
    pub async fn open(url: &str) -> Result<Db, ServiceError> {
        if is_postgres_url(url) {
            let options = PgConnectOptions::from_str(url)?;
            let pool = PgPoolOptions::new()
                .max_connections(8)
                .acquire_timeout(Duration::from_secs(30))
                .connect_with(options)
                .await?;
            sqlx::migrate!("./migrations/postgres").run(&pool).await?;
            Ok(Db::Postgres(pool))
        } else {
            let path = url.strip_prefix("sqlite://").unwrap_or(url);
            Self::open_sqlite(Path::new(path)).await
        }
    }

    /// Opens a SQLite file (WAL, normal sync, 10 s busy timeout).
    pub async fn open_sqlite(path: &Path) -> Result<Db, ServiceError> {
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
        sqlx::migrate!("./migrations/sqlite").run(&pool).await?;
        Ok(Db::Sqlite(pool))
    }

    /// A query's text translated for this backend (for a second query inside
    /// [`on_backend!`]).
    pub(crate) fn text(&self, sql: &str) -> String {
        match self {
            Db::Sqlite(_) => sqlite_text(sql),
            Db::Postgres(_) => postgres_text(sql),
        }
    }

    /// `sqlite` or `postgres`, for logs.
    pub fn backend(&self) -> &'static str {
        match self {
            Db::Sqlite(_) => "sqlite",
            Db::Postgres(_) => "postgres",
        }
    }
}

/// A timestamp as text, `2026-11-24T03:00:00.000Z`, in SQLite.
const SQLITE_NOW: &str = "strftime('%Y-%m-%dT%H:%M:%fZ', 'now')";
/// Seconds since the epoch (fractional) in SQLite.
const SQLITE_EPOCH: &str = "((julianday('now') - 2440587.5) * 86400.0)";
/// The same timestamp text in PostgreSQL.
const POSTGRES_NOW: &str =
    "to_char(clock_timestamp() AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS.MS\"Z\"')";
/// Seconds since the epoch in PostgreSQL.
const POSTGRES_EPOCH: &str = "extract(epoch from clock_timestamp())::double precision";

/// The query text for SQLite: tokens replaced, `?N` kept.
pub(crate) fn sqlite_text(sql: &str) -> String {
    sql.replace("{now}", SQLITE_NOW)
        .replace("{epoch}", SQLITE_EPOCH)
}

/// The query text for PostgreSQL: tokens replaced, `?N` turned into `$N` (the queries hold
/// no other `?`).
pub(crate) fn postgres_text(sql: &str) -> String {
    sql.replace("{now}", POSTGRES_NOW)
        .replace("{epoch}", POSTGRES_EPOCH)
        .replace('?', "$")
}

/// Runs `$body` once per backend with `$pool` bound to the pool and `$sql` to the query text
/// translated for it; the body is the same tokens for both, type-checked per backend.
macro_rules! on_backend {
    ($db:expr, $pool:ident, $sql:ident = $text:expr, $body:expr) => {
        match $db {
            $crate::db::Db::Sqlite($pool) => {
                let $sql = $crate::db::sqlite_text($text);
                $body
            }
            $crate::db::Db::Postgres($pool) => {
                let $sql = $crate::db::postgres_text($text);
                $body
            }
        }
    };
}
pub(crate) use on_backend;

impl Db {
    /// Runs a statement whose one parameter (`?1`) is `arg`; returns the rows it changed.
    pub(crate) async fn execute_with(&self, text: &str, arg: &str) -> Result<u64, sqlx::Error> {
        Ok(on_backend!(self, pool, sql = text, {
            sqlx::query(&sql)
                .bind(arg)
                .execute(pool)
                .await?
                .rows_affected()
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placeholders_and_tokens_translate() {
        let q = "UPDATE jobs SET t = {now} WHERE id = ?1 AND lease_until < {epoch} + ?2";
        let pg = postgres_text(q);
        assert!(pg.contains("$1") && pg.contains("$2") && !pg.contains('?'));
        assert!(pg.contains("clock_timestamp()"));
        let lite = sqlite_text(q);
        assert!(lite.contains("?1") && lite.contains("julianday"));
    }
}

#[cfg(test)]
mod lease_tests {
    use super::*;
    use std::time::Duration;

    /// The lease rules on a real SQLite file (the PostgreSQL side runs in the mpm-cli test
    /// `service_postgres`): writes need the claiming worker and a live lease, a lost lease is
    /// never renewed, and an expired job is requeued with its run marked.
    #[tokio::test]
    async fn leases_guard_every_write_and_expired_jobs_are_requeued() {
        let dir = tempfile::tempdir().unwrap();
        let db = Db::open_sqlite(&dir.path().join("q.sqlite")).await.unwrap();
        let insert = |id: &'static str, owner: &'static str| {
            let db = db.clone();
            async move {
                let job = NewJob {
                    id,
                    name: "n",
                    scene: "{}",
                    particles: 1,
                    end_time: 1.0,
                    stages: None,
                    owner: Some(owner),
                    start: None,
                };
                db.insert(&job, 10, Some(1)).await.unwrap()
            }
        };
        assert_eq!(insert("a", "alice").await, Inserted::Queued);
        assert_eq!(insert("b", "alice").await, Inserted::UserQueueFull);
        assert_eq!(insert("c", "bob").await, Inserted::Queued);

        let a = db.claim("w1", 0.5).await.unwrap().unwrap();
        assert_eq!((a.id.as_str(), a.attempt), ("a", 1));
        let c = db.claim("w2", 30.0).await.unwrap().unwrap();
        assert_eq!(c.id, "c");
        assert!(db.claim("w3", 30.0).await.unwrap().is_none());

        assert_eq!(
            db.heartbeat("a", "w2", 0.5).await.unwrap(),
            None,
            "not w2's"
        );
        assert_eq!(db.heartbeat("a", "w1", 0.5).await.unwrap(), Some(false));
        assert!(db.request_cancel("c").await.unwrap());
        assert_eq!(db.heartbeat("c", "w2", 30.0).await.unwrap(), Some(true));

        tokio::time::sleep(Duration::from_millis(700)).await;
        assert_eq!(db.heartbeat("a", "w1", 0.5).await.unwrap(), None, "lost");
        assert!(
            !db.finish("a", "w1", 1, "succeeded", None, None, None)
                .await
                .unwrap(),
            "a run past its lease records nothing"
        );
        let requeued = db.requeue_expired().await.unwrap();
        assert_eq!(requeued.len(), 1);
        assert_eq!(
            (requeued[0].id.as_str(), requeued[0].worker.as_deref()),
            ("a", Some("w1"))
        );
        assert_eq!(requeued[0].status, "queued");

        let again = db.claim("w2", 30.0).await.unwrap().unwrap();
        assert_eq!((again.id.as_str(), again.attempt), ("a", 2));
        assert!(
            db.finish("a", "w2", 2, "succeeded", None, None, Some((5, 0.1, 0.2)))
                .await
                .unwrap()
        );
        let row = db.get("a").await.unwrap().unwrap();
        assert_eq!(
            (row.status.as_str(), row.attempts, row.step),
            ("succeeded", 2, 5)
        );

        let Db::Sqlite(pool) = &db else {
            unreachable!()
        };
        let runs: Vec<(String, i64, String, Option<String>)> = sqlx::query_as(
            "SELECT job_id, attempt, worker, outcome FROM job_runs ORDER BY job_id, attempt",
        )
        .fetch_all(pool)
        .await
        .unwrap();
        assert_eq!(
            runs,
            vec![
                ("a".into(), 1, "w1".into(), Some("lease_expired".into())),
                ("a".into(), 2, "w2".into(), Some("succeeded".into())),
                ("c".into(), 1, "w2".into(), None),
            ]
        );
        let times = db.job_times().await.unwrap();
        let a_times = times.iter().find(|t| t.status == "succeeded").unwrap();
        assert_eq!((a_times.wall_seconds, a_times.particle_steps), (0.2, 5.0));
        assert!(a_times.waited.unwrap() >= 0.7, "{a_times:?}");
        db.worker_seen("w1").await.unwrap();
        db.worker_seen("w2").await.unwrap();
        db.worker_gone("w1").await.unwrap();
        let (workers, now) = db.workers().await.unwrap();
        assert_eq!(workers.len(), 1);
        assert_eq!(workers[0].0, "w2");
        assert!((now - workers[0].1).abs() < 5.0);
        // A clean stop gives the running job back; its pending cancel makes it cancelled.
        let released = db.release("w2").await.unwrap();
        assert_eq!(released.len(), 1);
        assert_eq!(
            (released[0].id.as_str(), released[0].status.as_str()),
            ("c", "cancelled")
        );
    }
}
