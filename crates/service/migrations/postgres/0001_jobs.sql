-- The same schema as migrations/sqlite (0001 and 0002 together). Times shown to clients are
-- text in the same format as SQLite's; `lease_until` is seconds since the epoch on the
-- database's clock, so workers on different machines agree on expiry.
CREATE TABLE jobs (
    seq              BIGINT GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
    id               TEXT    NOT NULL UNIQUE,
    name             TEXT    NOT NULL,
    status           TEXT    NOT NULL CHECK (status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
    scene            TEXT    NOT NULL,
    particles        BIGINT  NOT NULL,
    end_time         DOUBLE PRECISION NOT NULL,
    created_at       TEXT    NOT NULL DEFAULT (to_char(clock_timestamp() AT TIME ZONE 'UTC', 'YYYY-MM-DD"T"HH24:MI:SS.MS"Z"')),
    started_at       TEXT,
    finished_at      TEXT,
    step             BIGINT  NOT NULL DEFAULT 0,
    sim_time         DOUBLE PRECISION NOT NULL DEFAULT 0,
    wall_seconds     DOUBLE PRECISION NOT NULL DEFAULT 0,
    attempts         BIGINT  NOT NULL DEFAULT 0,
    cancel_requested BIGINT  NOT NULL DEFAULT 0,
    metrics          TEXT,
    failure          TEXT,
    worker           TEXT,
    lease_until      DOUBLE PRECISION,
    owner            TEXT
);
CREATE INDEX jobs_by_status ON jobs (status, seq);
CREATE INDEX jobs_by_owner ON jobs (owner, seq);
CREATE TABLE job_runs (
    job_id     TEXT    NOT NULL,
    attempt    BIGINT  NOT NULL,
    worker     TEXT    NOT NULL,
    claimed_at TEXT    NOT NULL DEFAULT (to_char(clock_timestamp() AT TIME ZONE 'UTC', 'YYYY-MM-DD"T"HH24:MI:SS.MS"Z"')),
    ended_at   TEXT,
    outcome    TEXT,
    PRIMARY KEY (job_id, attempt)
);
CREATE TABLE workers (
    name       TEXT PRIMARY KEY,
    started_at TEXT NOT NULL DEFAULT (to_char(clock_timestamp() AT TIME ZONE 'UTC', 'YYYY-MM-DD"T"HH24:MI:SS.MS"Z"')),
    last_seen  DOUBLE PRECISION NOT NULL
);
