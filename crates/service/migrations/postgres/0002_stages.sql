-- The stages of a staged scene, as JSON [[name, end_time], ...], so a job's progress can
-- name the stage it is in.
ALTER TABLE jobs ADD COLUMN stages TEXT;
