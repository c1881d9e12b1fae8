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
mod view;

pub use jobs::*;
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
