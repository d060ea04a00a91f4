-- wavrad cluster mode: the jobs table is the queue (src/service/cluster/db.rs).
-- Applied at start under an advisory lock, once (wavrad_migrations records it).
CREATE TABLE IF NOT EXISTS jobs (
    id               text PRIMARY KEY,
    seq              bigserial NOT NULL,
    name             text,
    created          timestamptz NOT NULL DEFAULT now(),
    params           jsonb NOT NULL,
    state            text NOT NULL DEFAULT 'queued'
                     CHECK (state IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
    -- the latest claim's number (0: never claimed); every write of a claim carries it (fencing)
    attempt          integer NOT NULL DEFAULT 0,
    -- claims that ended without finishing (lease expired); failed at --max-attempts
    failures         integer NOT NULL DEFAULT 0,
    replica          text,
    lease_until      timestamptz,
    cancel_requested boolean NOT NULL DEFAULT false,
    progress         jsonb,
    error            jsonb,
    stop_reason      text,
    -- the attempt whose outputs are in the object store (jobs/{id}/attempt-{n}/)
    result_attempt   integer,
    -- the names of the multipart upload's extra files, by URI -> object name
    parts            jsonb NOT NULL DEFAULT '{}'::jsonb,
    input_name       text NOT NULL,
    idempotency_key  text UNIQUE,
    request_hash     text
);
CREATE INDEX IF NOT EXISTS jobs_queue ON jobs (seq) WHERE state IN ('queued', 'running');

-- one row per claim: who ran which attempt, and how it ended
CREATE TABLE IF NOT EXISTS job_attempts (
    job_id   text NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    attempt  integer NOT NULL,
    replica  text NOT NULL,
    started  timestamptz NOT NULL DEFAULT now(),
    finished timestamptz,
    outcome  text,
    PRIMARY KEY (job_id, attempt)
);
