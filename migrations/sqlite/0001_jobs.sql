-- Jobs: one row per upload, from queued to a terminal state. Times are Unix milliseconds.
CREATE TABLE jobs (
    id            TEXT PRIMARY KEY NOT NULL,   -- UUIDv7: sorts by creation time
    tenant        TEXT NOT NULL,
    status        TEXT NOT NULL CHECK (status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
    stage         TEXT,
    progress      REAL NOT NULL DEFAULT 0,
    params        TEXT NOT NULL,               -- JSON: the caller's parameter overrides
    upload        TEXT NOT NULL,               -- JSON: filename, bytes, sha256, format, sidecar
    input         TEXT,                        -- JSON: points, format, scans (after reading)
    timings       TEXT,                        -- JSON: stage -> ms, pipeline order
    error_code    TEXT,
    error_message TEXT,
    attempts      INTEGER NOT NULL DEFAULT 0,
    max_attempts  INTEGER NOT NULL,
    lease_owner   TEXT,
    lease_until   INTEGER,
    created_at    INTEGER NOT NULL,
    started_at    INTEGER,
    finished_at   INTEGER,
    updated_at    INTEGER NOT NULL
);

CREATE INDEX jobs_tenant_id ON jobs (tenant, id DESC);
CREATE INDEX jobs_status_id ON jobs (status, id);
CREATE INDEX jobs_finished ON jobs (finished_at) WHERE finished_at IS NOT NULL;
