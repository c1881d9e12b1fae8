-- A job that starts from another job's stored state (`mpm submit --from JOB [--stage
-- NAME]`): that job, the stage it starts at (a staged scene) and the simulated time it
-- starts at, so that its progress runs from there.
ALTER TABLE jobs ADD COLUMN from_job TEXT;
ALTER TABLE jobs ADD COLUMN from_stage TEXT;
ALTER TABLE jobs ADD COLUMN start_time REAL NOT NULL DEFAULT 0;
