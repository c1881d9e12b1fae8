-- One row per submitted job. `seq` gives submission order; `id` is what clients see.
CREATE TABLE jobs (
    seq              INTEGER PRIMARY KEY AUTOINCREMENT,
    id               TEXT    NOT NULL UNIQUE,
    name             TEXT    NOT NULL,
    status           TEXT    NOT NULL CHECK (status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
    scene            TEXT    NOT NULL,
    particles        INTEGER NOT NULL,
    end_time         REAL    NOT NULL,
    created_at       TEXT    NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now')),
    started_at       TEXT,
    finished_at      TEXT,
    step             INTEGER NOT NULL DEFAULT 0,
    sim_time         REAL    NOT NULL DEFAULT 0,
    wall_seconds     REAL    NOT NULL DEFAULT 0,
    attempts         INTEGER NOT NULL DEFAULT 0,
    cancel_requested INTEGER NOT NULL DEFAULT 0,
    metrics          TEXT,
    failure          TEXT
);
CREATE INDEX jobs_by_status ON jobs (status, seq);
