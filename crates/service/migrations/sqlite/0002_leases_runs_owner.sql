-- Leases (several worker processes share one queue), owners (users), one row per run of
-- a job (a claim), so that a rerun after a dead worker is visible and counted, and the workers.
ALTER TABLE jobs ADD COLUMN worker TEXT;
ALTER TABLE jobs ADD COLUMN lease_until REAL;
ALTER TABLE jobs ADD COLUMN owner TEXT;
CREATE INDEX jobs_by_owner ON jobs (owner, seq);
CREATE TABLE job_runs (
    job_id     TEXT    NOT NULL,
    attempt    INTEGER NOT NULL,
    worker     TEXT    NOT NULL,
    claimed_at TEXT    NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now')),
    ended_at   TEXT,
    outcome    TEXT,
    PRIMARY KEY (job_id, attempt)
);
-- Workers seen by the queue: each refreshes `last_seen` (seconds since the epoch) as its loop
-- turns and as it renews a lease, so /metrics shows every worker's heartbeat on any machine.
CREATE TABLE workers (
    name       TEXT PRIMARY KEY,
    started_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now')),
    last_seen  REAL NOT NULL
);
