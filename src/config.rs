//! The service's settings. Each comes from, in rising precedence: the built-in default, the
//! config file (`--config`, TOML), the environment (`ASBUILT_*`), then the command line.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context};
use serde::Deserialize;

/// Every setting, resolved.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// Where to listen. Without API keys the host is forced to loopback.
    pub listen: SocketAddr,
    /// Root of the database file and blobs.
    pub data_dir: PathBuf,
    /// The job database; default `sqlite://<data_dir>/asbuilt.db`; `postgres://...` to share
    /// jobs between processes on many hosts.
    pub database_url: Option<String>,
    /// Where blobs live: default `<data_dir>/blobs`; `s3://bucket/prefix` for S3-compatible
    /// storage shared between processes.
    pub storage: Option<String>,
    /// S3 endpoint (MinIO, Ceph, ...); default `AWS_ENDPOINT`, else AWS itself.
    pub s3_endpoint: Option<String>,
    /// S3 region; default `AWS_REGION`.
    pub s3_region: Option<String>,
    /// S3 credentials; default `AWS_ACCESS_KEY_ID` and `AWS_SECRET_ACCESS_KEY`. Config file only,
    /// so secrets never show on a command line.
    pub s3_access_key_id: Option<String>,
    pub s3_secret_access_key: Option<String>,
    /// Allow a plain-HTTP S3 endpoint; default `AWS_ALLOW_HTTP`.
    pub s3_allow_http: bool,
    /// Serve results as redirects to pre-signed S3 URLs valid this long, seconds; 0 streams them.
    pub presign_secs: u64,
    /// Pipeline workers in this process (0: API only).
    pub workers: usize,
    /// Largest accepted upload, bytes.
    pub max_upload_bytes: u64,
    /// Largest accepted pose/trajectory sidecar or params part, bytes.
    pub max_sidecar_bytes: u64,
    /// Largest cloud a job may read, points.
    pub max_points: u64,
    /// Wall-clock limit of one job attempt, seconds.
    pub job_timeout_secs: u64,
    /// How long a finished job's uploads and results are kept, hours.
    pub retention_hours: u64,
    /// How long a resumable upload session (`/v1/uploads`) lives, seconds; then the sweeper
    /// removes it and its bytes.
    pub upload_session_secs: u64,
    /// A worker's lease; a job whose worker is silent this long is retried, seconds.
    pub lease_secs: u64,
    /// Claims a job may use before it fails with `worker_lost`.
    pub max_attempts: u32,
    /// How long shutdown waits for running jobs before handing them back to the queue, seconds.
    pub shutdown_timeout_secs: u64,
    /// API keys as `tenant:key`. None (and no keys file): development mode (loopback only, one
    /// tenant `dev`).
    pub api_keys: Vec<String>,
    /// A file of `tenant:key` lines (`#` comments), re-read when it changes: keys are added
    /// and revoked without a restart.
    pub api_keys_file: Option<PathBuf>,
    /// The key `/metrics` wants on the API listener (`Authorization: Bearer`). Without it (and
    /// with API keys), `/metrics` is served only on `metrics_listen`.
    pub metrics_key: Option<String>,
    /// A second listener serving only `/metrics`, without a key (a private scrape network).
    pub metrics_listen: Option<SocketAddr>,
    /// Requests per second each tenant may make on average (0: no limit).
    pub rate_limit: f64,
    /// Requests a tenant may make at once above the average.
    pub rate_burst: u32,
    /// Queued jobs a tenant may have at once (0: no cap).
    pub max_queued: u32,
    /// An upload that sends nothing for this long is dropped, seconds.
    pub upload_idle_timeout_secs: u64,
    /// An upload slower than this on average (after its first `upload_idle_timeout_secs`) is
    /// dropped, bytes per second (0: no minimum).
    pub upload_min_rate: u64,
    /// A connection with no traffic either way for this long is closed, seconds (slow or
    /// silent clients, half-sent headers).
    pub idle_timeout_secs: u64,
    /// Webhook signing secrets as `tenant:secret` (at least 16 characters): a tenant's
    /// callbacks are signed with its secret, and a tenant without one cannot register any.
    pub webhook_secrets: Vec<String>,
    /// A tenant's default callback URL, `tenant:url`, for jobs created without `callback_url`.
    pub webhook_urls: Vec<String>,
    /// What callbacks may reach: `public` (any public address), host names and CIDR ranges.
    pub webhook_allow: Vec<String>,
    /// Attempts per webhook before giving up.
    pub webhook_attempts: u32,
    /// The wait after a failed attempt, milliseconds; it doubles after each (at most an hour).
    pub webhook_backoff_ms: u64,
    /// Origins whose browser pages may call the API (CORS): `https://host[:port]` each, or
    /// `*` for any. None: no CORS headers, so browsers allow only this server's own page.
    pub cors_origins: Vec<String>,
    /// Testing aid: replace the pipeline with a synthetic one taking this many ms per stage.
    #[serde(skip)]
    pub fake_pipeline_ms: Option<u64>,
    /// Testing aid: the synthetic pipeline burns CPU instead of sleeping.
    #[serde(skip)]
    pub fake_pipeline_spin: bool,
    /// Serve the v1 API (`serve`); false for `asbuilt worker`, which serves only its health
    /// and metrics endpoints.
    #[serde(skip)]
    pub serve_api: bool,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            listen: "127.0.0.1:8080".parse().expect("literal address"),
            data_dir: PathBuf::from("asbuilt-data"),
            database_url: None,
            storage: None,
            s3_endpoint: None,
            s3_region: None,
            s3_access_key_id: None,
            s3_secret_access_key: None,
            s3_allow_http: false,
            presign_secs: 0,
            workers: 2,
            max_upload_bytes: 8 << 30,
            max_sidecar_bytes: 16 << 20,
            max_points: 200_000_000,
            job_timeout_secs: 3600,
            retention_hours: 24 * 7,
            upload_session_secs: 24 * 3600,
            lease_secs: 30,
            max_attempts: 3,
            shutdown_timeout_secs: 30,
            api_keys: Vec::new(),
            api_keys_file: None,
            metrics_key: None,
            metrics_listen: None,
            rate_limit: 20.0,
            rate_burst: 40,
            max_queued: 100,
            upload_idle_timeout_secs: 30,
            upload_min_rate: 4096,
            idle_timeout_secs: 120,
            webhook_secrets: vec![],
            webhook_urls: vec![],
            webhook_allow: vec!["public".into()],
            webhook_attempts: 8,
            webhook_backoff_ms: 10_000,
            cors_origins: vec![],
            fake_pipeline_ms: None,
            fake_pipeline_spin: false,
            serve_api: true,
        }
    }
}

/// `asbuilt serve` and `asbuilt migrate` flags. Each has an `ASBUILT_*` environment twin.
#[derive(clap::Args, Debug, Default)]
pub struct ConfigArgs {
    /// A TOML file with any of the settings below (snake_case keys).
    #[arg(long, env = "ASBUILT_CONFIG", value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Listen address [default: 127.0.0.1:8080].
    #[arg(long, env = "ASBUILT_LISTEN", value_name = "ADDR")]
    pub listen: Option<SocketAddr>,
    /// Data directory for the database and blobs [default: ./asbuilt-data].
    #[arg(long, env = "ASBUILT_DATA_DIR", value_name = "DIR")]
    pub data_dir: Option<PathBuf>,
    /// Job database URL: sqlite://PATH or postgres://... [default: sqlite://DATA_DIR/asbuilt.db].
    #[arg(
        long,
        visible_alias = "database",
        env = "ASBUILT_DATABASE_URL",
        value_name = "URL"
    )]
    pub database_url: Option<String>,
    /// Blob storage: a local directory, or s3://BUCKET/PREFIX [default: DATA_DIR/blobs].
    #[arg(long, env = "ASBUILT_STORAGE", value_name = "URL")]
    pub storage: Option<String>,
    /// S3-compatible endpoint, e.g. http://minio:9000 [default: AWS_ENDPOINT, else AWS].
    #[arg(long, env = "ASBUILT_S3_ENDPOINT", value_name = "URL")]
    pub s3_endpoint: Option<String>,
    /// S3 region [default: AWS_REGION].
    #[arg(long, env = "ASBUILT_S3_REGION", value_name = "REGION")]
    pub s3_region: Option<String>,
    /// Serve results through pre-signed S3 URLs valid SECS seconds (0: stream them) [default: 0].
    #[arg(long, env = "ASBUILT_PRESIGN_SECONDS", value_name = "SECS")]
    pub presign: Option<u64>,
    /// Pipeline workers [default: 2].
    #[arg(long, env = "ASBUILT_WORKERS", value_name = "N")]
    pub workers: Option<usize>,
    /// Upload size limit, bytes or with K/M/G/T [default: 8G].
    #[arg(long, env = "ASBUILT_MAX_UPLOAD", value_name = "SIZE", value_parser = parse_size)]
    pub max_upload: Option<u64>,
    /// Sidecar and params part size limit [default: 16M].
    #[arg(long, env = "ASBUILT_MAX_SIDECAR", value_name = "SIZE", value_parser = parse_size)]
    pub max_sidecar: Option<u64>,
    /// Point-count limit per job [default: 200000000].
    #[arg(long, env = "ASBUILT_MAX_POINTS", value_name = "N")]
    pub max_points: Option<u64>,
    /// Time limit per job attempt, seconds [default: 3600].
    #[arg(long, env = "ASBUILT_JOB_TIMEOUT", value_name = "SECS")]
    pub job_timeout: Option<u64>,
    /// Retention of finished jobs' data, hours [default: 168].
    #[arg(long, env = "ASBUILT_RETENTION_HOURS", value_name = "HOURS")]
    pub retention_hours: Option<u64>,
    /// Lifetime of a resumable upload session, seconds [default: 86400].
    #[arg(long, env = "ASBUILT_UPLOAD_SESSION", value_name = "SECS")]
    pub upload_session: Option<u64>,
    /// Worker lease, seconds [default: 30].
    #[arg(long, env = "ASBUILT_LEASE", value_name = "SECS")]
    pub lease: Option<u64>,
    /// Attempts per job before it fails with worker_lost [default: 3].
    #[arg(long, env = "ASBUILT_MAX_ATTEMPTS", value_name = "N")]
    pub max_attempts: Option<u32>,
    /// Graceful shutdown timeout, seconds [default: 30].
    #[arg(long, env = "ASBUILT_SHUTDOWN_TIMEOUT", value_name = "SECS")]
    pub shutdown_timeout: Option<u64>,
    /// API keys, `tenant:key`, comma-separated or repeated. None: development mode.
    #[arg(
        long = "api-key",
        env = "ASBUILT_API_KEYS",
        value_name = "TENANT:KEY",
        value_delimiter = ','
    )]
    pub api_keys: Vec<String>,
    /// A file of `tenant:key` lines, re-read when it changes (keys added and revoked live).
    #[arg(long, env = "ASBUILT_API_KEYS_FILE", value_name = "FILE")]
    pub api_keys_file: Option<PathBuf>,
    /// The key /metrics wants on the API port; without it, /metrics is only on --metrics-listen.
    #[arg(long, env = "ASBUILT_METRICS_KEY", value_name = "KEY")]
    pub metrics_key: Option<String>,
    /// Also serve /metrics, without a key, on this address (a private network).
    #[arg(long, env = "ASBUILT_METRICS_LISTEN", value_name = "ADDR")]
    pub metrics_listen: Option<SocketAddr>,
    /// Requests per second per tenant, on average (0: no limit) [default: 20].
    #[arg(long, env = "ASBUILT_RATE_LIMIT", value_name = "PER_SEC")]
    pub rate_limit: Option<f64>,
    /// Requests per tenant allowed at once above the average [default: 40].
    #[arg(long, env = "ASBUILT_RATE_BURST", value_name = "N")]
    pub rate_burst: Option<u32>,
    /// Queued jobs per tenant (0: no cap) [default: 100].
    #[arg(long, env = "ASBUILT_MAX_QUEUED", value_name = "N")]
    pub max_queued: Option<u32>,
    /// Drop an upload that sends nothing for this long, seconds [default: 30].
    #[arg(long, env = "ASBUILT_UPLOAD_IDLE_TIMEOUT", value_name = "SECS")]
    pub upload_idle_timeout: Option<u64>,
    /// Drop an upload slower than this on average, bytes/s with K/M/G (0: none) [default: 4K].
    #[arg(long, env = "ASBUILT_UPLOAD_MIN_RATE", value_name = "RATE", value_parser = parse_size)]
    pub upload_min_rate: Option<u64>,
    /// Close a connection with no traffic for this long, seconds [default: 120].
    #[arg(long, env = "ASBUILT_IDLE_TIMEOUT", value_name = "SECS")]
    pub idle_timeout: Option<u64>,
    /// Webhook signing secrets, `tenant:secret`, comma-separated or repeated.
    #[arg(
        long = "webhook-secret",
        env = "ASBUILT_WEBHOOK_SECRETS",
        value_name = "TENANT:SECRET",
        value_delimiter = ','
    )]
    pub webhook_secrets: Vec<String>,
    /// A tenant's default callback URL, `tenant:url`, comma-separated or repeated.
    #[arg(
        long = "webhook-url",
        env = "ASBUILT_WEBHOOK_URLS",
        value_name = "TENANT:URL",
        value_delimiter = ','
    )]
    pub webhook_urls: Vec<String>,
    /// What callbacks may reach: `public`, host names, CIDR ranges [default: public].
    #[arg(
        long = "webhook-allow",
        env = "ASBUILT_WEBHOOK_ALLOW",
        value_name = "HOST|CIDR|public",
        value_delimiter = ','
    )]
    pub webhook_allow: Vec<String>,
    /// Attempts per webhook before giving up [default: 8].
    #[arg(long, env = "ASBUILT_WEBHOOK_ATTEMPTS", value_name = "N")]
    pub webhook_attempts: Option<u32>,
    /// Wait after a failed webhook attempt, ms, doubling each time [default: 10000].
    #[arg(long, env = "ASBUILT_WEBHOOK_BACKOFF_MS", value_name = "MS")]
    pub webhook_backoff_ms: Option<u64>,
    /// Origins whose pages may call the API (CORS), comma-separated or repeated; `*` for any.
    #[arg(
        long = "cors-origin",
        env = "ASBUILT_CORS_ORIGINS",
        value_name = "ORIGIN",
        value_delimiter = ','
    )]
    pub cors_origins: Vec<String>,
    /// Testing aid: a synthetic pipeline taking MS per stage instead of the real one.
    #[arg(long, env = "ASBUILT_FAKE_PIPELINE_MS", value_name = "MS", hide = true)]
    pub fake_pipeline_ms: Option<u64>,
    /// Testing aid: the synthetic pipeline burns CPU instead of sleeping.
    #[arg(long, hide = true)]
    pub fake_pipeline_spin: bool,
}

impl ConfigArgs {
    /// Defaults, then the file, then environment and flags (clap has merged those two).
    pub fn resolve(&self) -> anyhow::Result<Config> {
        let mut c = match &self.config {
            Some(path) => load_file(path)?,
            None => Config::default(),
        };
        macro_rules! take {
            ($($flag:ident => $field:ident),*) => {
                $(if let Some(v) = self.$flag.clone() { c.$field = v; })*
            };
        }
        take!(listen => listen, data_dir => data_dir, workers => workers,
            max_upload => max_upload_bytes, max_sidecar => max_sidecar_bytes,
            max_points => max_points, job_timeout => job_timeout_secs,
            retention_hours => retention_hours, lease => lease_secs,
            upload_session => upload_session_secs,
            max_attempts => max_attempts, shutdown_timeout => shutdown_timeout_secs,
            presign => presign_secs, rate_limit => rate_limit, rate_burst => rate_burst,
            max_queued => max_queued, upload_idle_timeout => upload_idle_timeout_secs,
            upload_min_rate => upload_min_rate, idle_timeout => idle_timeout_secs);
        if self.api_keys_file.is_some() {
            c.api_keys_file = self.api_keys_file.clone();
        }
        if self.metrics_key.is_some() {
            c.metrics_key = self.metrics_key.clone();
        }
        if self.metrics_listen.is_some() {
            c.metrics_listen = self.metrics_listen;
        }
        for (flag, field) in [
            (&self.storage, &mut c.storage),
            (&self.s3_endpoint, &mut c.s3_endpoint),
            (&self.s3_region, &mut c.s3_region),
        ] {
            if flag.is_some() {
                field.clone_from(flag);
            }
        }
        if self.database_url.is_some() {
            c.database_url = self.database_url.clone();
        }
        if !self.api_keys.is_empty() {
            c.api_keys = self.api_keys.clone();
        }
        for (flag, field) in [
            (&self.webhook_secrets, &mut c.webhook_secrets),
            (&self.webhook_urls, &mut c.webhook_urls),
            (&self.webhook_allow, &mut c.webhook_allow),
            (&self.cors_origins, &mut c.cors_origins),
        ] {
            if !flag.is_empty() {
                field.clone_from(flag);
            }
        }
        take!(webhook_attempts => webhook_attempts, webhook_backoff_ms => webhook_backoff_ms);
        c.fake_pipeline_ms = self.fake_pipeline_ms;
        c.fake_pipeline_spin = self.fake_pipeline_spin;
        c.check()?;
        Ok(c)
    }
}

fn load_file(path: &Path) -> anyhow::Result<Config> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    toml::from_str(&text).with_context(|| format!("{}", path.display()))
}

impl Config {
    /// Rejects settings that cannot work, naming the setting.
    pub fn check(&self) -> anyhow::Result<()> {
        if let Some(url) = &self.database_url {
            let known = ["sqlite:", "postgres://", "postgresql://"];
            if url.contains("://") && !known.iter().any(|k| url.starts_with(k)) {
                bail!("database_url `{url}`: expected sqlite://PATH or postgres://...");
            }
        }
        if let Some(url) = self.storage.as_deref().filter(|u| u.contains("://")) {
            crate::storage::s3::S3Url::parse(url)?;
        }
        if self.lease_secs == 0 {
            bail!("lease_secs must be at least 1");
        }
        if self.max_attempts == 0 {
            bail!("max_attempts must be at least 1");
        }
        if self.job_timeout_secs == 0 {
            bail!("job_timeout_secs must be at least 1");
        }
        if self.upload_idle_timeout_secs == 0 || self.idle_timeout_secs == 0 {
            bail!("upload_idle_timeout_secs and idle_timeout_secs must be at least 1");
        }
        if !(self.rate_limit.is_finite() && self.rate_limit >= 0.0) {
            bail!("rate_limit must be a number of requests per second, 0 or more");
        }
        if self.rate_limit > 0.0 && self.rate_burst == 0 {
            bail!("rate_burst must be at least 1 when rate_limit is set");
        }
        crate::auth::parse_keys(self.api_keys.iter().map(String::as_str), "--api-key")
            .map_err(|e| anyhow::anyhow!(e))?;
        if let Some(path) = &self.api_keys_file {
            // Refuse to start on a bad file; a later bad edit is logged and the old keys kept.
            crate::auth::read_keys_file(path).map_err(|e| anyhow::anyhow!(e))?;
        }
        crate::webhooks::Settings::from_config(self).map_err(|e| anyhow::anyhow!(e))?;
        crate::router::cors(&self.cors_origins).map_err(|e| anyhow::anyhow!(e))?;
        if self.webhook_attempts == 0 {
            bail!("webhook_attempts must be at least 1");
        }
        if let Some(k) = &self.metrics_key {
            if k.chars().count() < crate::auth::MIN_KEY_LEN {
                bail!(
                    "metrics_key: at least {} characters",
                    crate::auth::MIN_KEY_LEN
                );
            }
        }
        Ok(())
    }

    /// All configured keys: flags and config file, then the keys file. Checked for short and
    /// duplicate keys.
    pub fn all_keys(&self) -> Result<Vec<(String, String)>, String> {
        let mut lines: Vec<String> = self.api_keys.clone();
        if let Some(path) = &self.api_keys_file {
            let text =
                std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
            lines.extend(crate::auth::key_lines(&text));
        }
        crate::auth::parse_keys(lines.iter().map(String::as_str), "API keys")
    }

    /// The database URL, defaulting to a file in the data directory.
    pub fn database_url(&self) -> String {
        self.database_url
            .clone()
            .unwrap_or_else(|| format!("sqlite://{}", self.data_dir.join("asbuilt.db").display()))
    }

    /// True when jobs live in a database other processes share (PostgreSQL): its schema is
    /// migrated by `asbuilt migrate`, not at start-up.
    pub fn shared_database(&self) -> bool {
        let url = self.database_url();
        url.starts_with("postgres://") || url.starts_with("postgresql://")
    }

    /// How to reach S3, from the config with the `AWS_*` environment as the fallback.
    pub fn s3_options(&self) -> crate::storage::s3::S3Options {
        crate::storage::s3::S3Options {
            endpoint: self.s3_endpoint.clone(),
            region: self.s3_region.clone(),
            access_key_id: self.s3_access_key_id.clone(),
            secret_access_key: self.s3_secret_access_key.clone(),
            allow_http: self.s3_allow_http,
            presign: (self.presign_secs > 0).then(|| Duration::from_secs(self.presign_secs)),
        }
    }

    /// Lifetime of an upload session, milliseconds.
    pub fn upload_session_ms(&self) -> i64 {
        i64::try_from(self.upload_session_secs.saturating_mul(1000)).unwrap_or(i64::MAX)
    }

    /// Retention of finished jobs, milliseconds.
    pub fn retention_ms(&self) -> i64 {
        i64::try_from(self.retention_hours.saturating_mul(3_600_000)).unwrap_or(i64::MAX)
    }

    /// True when no API keys are configured (neither listed nor in a keys file).
    pub fn dev_mode(&self) -> bool {
        self.api_keys.is_empty() && self.api_keys_file.is_none()
    }
}

/// Parses `123`, `64K`, `512M`, `2G`, `1T` (binary multiples).
pub fn parse_size(s: &str) -> Result<u64, String> {
    let s = s.trim();
    let (digits, shift) = match s.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let shift = match c.to_ascii_uppercase() {
                'K' => 10,
                'M' => 20,
                'G' => 30,
                'T' => 40,
                _ => {
                    return Err(format!(
                        "`{s}`: unknown size suffix `{c}` (use K, M, G or T)"
                    ))
                }
            };
            (&s[..i], shift)
        }
        _ => (s, 0),
    };
    let n: u64 = digits
        .parse()
        .map_err(|_| format!("`{s}` is not a size such as 512M or 2G"))?;
    n.checked_mul(1u64 << shift)
        .ok_or_else(|| format!("`{s}` is too large"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes() {
        assert_eq!(parse_size("123"), Ok(123));
        assert_eq!(parse_size("64K"), Ok(65536));
        assert_eq!(parse_size("2g"), Ok(2 << 30));
        assert!(parse_size("2X").is_err());
        assert!(parse_size("lots").is_err());
        assert!(parse_size("99999999999T").is_err());
    }

    #[test]
    fn flags_override_the_file_which_overrides_defaults() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("asbuilt.toml");
        std::fs::write(
            &file,
            "workers = 5\nmax_points = 10\napi_keys = [\"acme:0123456789abcdef\"]\n",
        )
        .unwrap();
        let args = ConfigArgs {
            config: Some(file.clone()),
            workers: Some(7),
            ..Default::default()
        };
        let c = args.resolve().unwrap();
        assert_eq!((c.workers, c.max_points), (7, 10));
        assert_eq!(c.lease_secs, Config::default().lease_secs);
        assert!(!c.dev_mode());
        std::fs::write(&file, "wrokers = 5\n").unwrap();
        let err = format!("{:#}", args.resolve().unwrap_err());
        assert!(err.contains("wrokers"), "{err}");
    }

    #[test]
    fn short_and_duplicate_keys_are_refused() {
        let c = Config {
            api_keys: vec!["acme:short-key-15chr".into()],
            ..Default::default()
        };
        let e = c.check().unwrap_err().to_string();
        assert!(e.contains("acme") && e.contains("16"), "{e}");
        let c = Config {
            api_keys: vec![
                "acme:0123456789abcdef".into(),
                "bolt:0123456789abcdef".into(),
            ],
            ..Default::default()
        };
        let e = c.check().unwrap_err().to_string();
        assert!(
            e.contains("acme") && e.contains("bolt") && e.contains("same key"),
            "{e}"
        );
        let ok = Config {
            api_keys: vec!["acme:0123456789abcdef".into()],
            ..Default::default()
        };
        assert!(ok.check().is_ok());
    }
}
