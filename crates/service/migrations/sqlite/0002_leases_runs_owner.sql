-- Leases (several worker processes share one queue), owners (users), and one row per run of
-- a job (a claim), so that a rerun after a dead worker is visible and counted.
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
