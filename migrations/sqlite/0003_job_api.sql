-- The integrator's job API (issue 16).
-- A job removed by retention leaves its id and tenant here, so it answers 410, not 404.
CREATE TABLE job_tombstones (
    id         TEXT PRIMARY KEY NOT NULL,
    tenant     TEXT NOT NULL,
    expired_at INTEGER NOT NULL
);
CREATE INDEX job_tombstones_expired ON job_tombstones (expired_at);

-- What the client attached: its reference and tags (a JSON array of strings).
ALTER TABLE jobs ADD COLUMN external_ref TEXT;
ALTER TABLE jobs ADD COLUMN tags TEXT NOT NULL DEFAULT '[]';
CREATE INDEX jobs_tenant_external_ref ON jobs (tenant, external_ref) WHERE external_ref IS NOT NULL;
-- Idempotency-Key: one job per key and tenant; the hash is what the first request asked for.
ALTER TABLE jobs ADD COLUMN idempotency_key TEXT;
ALTER TABLE jobs ADD COLUMN request_hash TEXT;
CREATE UNIQUE INDEX jobs_tenant_idempotency_key ON jobs (tenant, idempotency_key)
    WHERE idempotency_key IS NOT NULL;
-- A re-plan reads another job's upload (jobs/<input_job>/input/cloud); NULL means its own.
ALTER TABLE jobs ADD COLUMN input_job TEXT;
CREATE INDEX jobs_input_job ON jobs (input_job) WHERE input_job IS NOT NULL;
-- Where completion and failure are POSTed (webhooks).
ALTER TABLE jobs ADD COLUMN callback_url TEXT;
-- The webhook still owed for a finished job: due then (Unix ms), after so many attempts.
-- Set at creation when there is a callback URL; cleared once delivered or given up.
ALTER TABLE jobs ADD COLUMN hook_due INTEGER;
ALTER TABLE jobs ADD COLUMN hook_attempts INTEGER NOT NULL DEFAULT 0;
CREATE INDEX jobs_hook_due ON jobs (hook_due) WHERE hook_due IS NOT NULL;
-- Every webhook delivery attempt, as the API shows it.
CREATE TABLE webhook_deliveries (
    id          TEXT PRIMARY KEY NOT NULL,
    job_id      TEXT NOT NULL,
    event       TEXT NOT NULL,
    url         TEXT NOT NULL,
    attempt     INTEGER NOT NULL,
    at          INTEGER NOT NULL,
    status_code INTEGER,
    error       TEXT,
    duration_ms INTEGER NOT NULL
);
CREATE INDEX webhook_deliveries_job ON webhook_deliveries (job_id, at);
