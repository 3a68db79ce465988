-- Jobs: one row per upload, from queued to a terminal state. Times are Unix milliseconds.
CREATE TABLE jobs (
    id            UUID PRIMARY KEY,            -- UUIDv7: sorts by creation time
    tenant        TEXT NOT NULL,
    status        TEXT NOT NULL CHECK (status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
    stage         TEXT,
    progress      DOUBLE PRECISION NOT NULL DEFAULT 0,
    params        JSONB NOT NULL,              -- the caller's parameter overrides
    upload        JSONB NOT NULL,              -- filename, bytes, sha256, format, sidecar
    input         JSONB,                       -- points, format, scans (after reading)
    timings       JSONB,                       -- stage -> ms, pipeline order
    error_code    TEXT,
    error_message TEXT,
    attempts      INTEGER NOT NULL DEFAULT 0,
    max_attempts  INTEGER NOT NULL,
    lease_owner   TEXT,
    lease_until   BIGINT,
    created_at    BIGINT NOT NULL,
    started_at    BIGINT,
    finished_at   BIGINT,
    updated_at    BIGINT NOT NULL
);

CREATE INDEX jobs_tenant_id ON jobs (tenant, id DESC);
-- The claim scans only queued rows, oldest first.
CREATE INDEX jobs_queued ON jobs (id) WHERE status = 'queued';
CREATE INDEX jobs_running_lease ON jobs (lease_until) WHERE status = 'running';
CREATE INDEX jobs_finished ON jobs (finished_at) WHERE finished_at IS NOT NULL;

-- Wakes idle workers: every time a job becomes queued, notify the schema's channel.
CREATE FUNCTION asbuilt_notify_queued() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    PERFORM pg_notify('asbuilt_jobs_' || TG_TABLE_SCHEMA, NEW.id::text);
    RETURN NULL;
END
$$;

CREATE TRIGGER jobs_notify_queued
    AFTER INSERT OR UPDATE OF status ON jobs
    FOR EACH ROW WHEN (NEW.status = 'queued')
    EXECUTE FUNCTION asbuilt_notify_queued();
