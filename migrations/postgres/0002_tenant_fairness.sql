-- Fair claiming and per-tenant caps: each tenant's oldest queued job, its running jobs and the
-- last time one of its jobs started are index lookups, not scans of the whole table.
CREATE INDEX jobs_queued_tenant ON jobs (tenant, id) WHERE status = 'queued';
CREATE INDEX jobs_running_tenant ON jobs (tenant) WHERE status = 'running';
CREATE INDEX jobs_tenant_started ON jobs (tenant, started_at) WHERE started_at IS NOT NULL;
