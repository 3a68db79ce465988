-- The integrator's job API (issue 16).
-- A job removed by retention leaves its id and tenant here, so it answers 410, not 404.
CREATE TABLE job_tombstones (
    id         UUID PRIMARY KEY,
    tenant     TEXT NOT NULL,
    expired_at BIGINT NOT NULL
);
CREATE INDEX job_tombstones_expired ON job_tombstones (expired_at);

-- What the client attached: its reference and tags (a JSON array of strings).
ALTER TABLE jobs ADD COLUMN external_ref TEXT;
ALTER TABLE jobs ADD COLUMN tags JSONB NOT NULL DEFAULT '[]';
CREATE INDEX jobs_tenant_external_ref ON jobs (tenant, external_ref) WHERE external_ref IS NOT NULL;
-- Idempotency-Key: one job per key and tenant; the hash is what the first request asked for.
ALTER TABLE jobs ADD COLUMN idempotency_key TEXT;
ALTER TABLE jobs ADD COLUMN request_hash TEXT;
CREATE UNIQUE INDEX jobs_tenant_idempotency_key ON jobs (tenant, idempotency_key)
    WHERE idempotency_key IS NOT NULL;
-- A re-plan reads another job's upload (jobs/<input_job>/input/cloud); NULL means its own.
ALTER TABLE jobs ADD COLUMN input_job UUID;
CREATE INDEX jobs_input_job ON jobs (input_job) WHERE input_job IS NOT NULL;
-- Where completion and failure are POSTed (webhooks).
ALTER TABLE jobs ADD COLUMN callback_url TEXT;
