//! Webhooks: when a job with a callback URL finishes (succeeded, failed or cancelled), its
//! result is POSTed there, signed with the tenant's secret ([`sign`]), to a target the
//! allow-list permits ([`allow`]). Each attempt is recorded (`GET /v1/jobs/{id}/deliveries`);
//! a failed one is retried with a doubling wait, up to `webhook_attempts` attempts.
//!
//! What is owed lives in the job row (`hook_due`, `hook_attempts`), so any process may deliver
//! it, a restart loses nothing, and a process that dies mid-delivery leaves it to another
//! after a lease.

pub mod allow;
pub mod sign;

use std::collections::HashMap;
use std::time::{Duration, Instant};

use tokio_util::sync::CancellationToken;

use crate::app::AppState;
use crate::config::Config;
use crate::queue::{now_ms, Delivery, Job, JobStatus};
use crate::views::JobView;
use allow::Allow;

/// How long a claimed delivery is this process's: well past the request timeout.
const LEASE_MS: i64 = 60_000;
/// A receiver must answer within this.
const TIMEOUT: Duration = Duration::from_secs(10);
/// How often due deliveries are looked for.
const POLL: Duration = Duration::from_millis(500);
/// The longest wait between attempts.
const MAX_BACKOFF_MS: u64 = 3_600_000;
/// The longest callback URL accepted.
pub const MAX_URL: usize = 2048;

/// The webhook settings, parsed and checked.
#[derive(Debug, Clone)]
pub struct Settings {
    secrets: HashMap<String, String>,
    urls: HashMap<String, String>,
    pub allow: Allow,
    pub attempts: u32,
    pub backoff_ms: u64,
}

/// Splits `tenant:value` entries; an error names the setting.
fn pairs(entries: &[String], setting: &str) -> Result<HashMap<String, String>, String> {
    let mut map = HashMap::new();
    for e in entries {
        let (tenant, value) = e
            .split_once(':')
            .filter(|(t, v)| !t.is_empty() && !v.is_empty())
            .ok_or_else(|| {
                format!(
                    "{setting}: `{}` is not TENANT:VALUE",
                    e.split(':').next().unwrap_or_default()
                )
            })?;
        if map.insert(tenant.to_string(), value.to_string()).is_some() {
            return Err(format!("{setting}: tenant `{tenant}` is given twice"));
        }
    }
    Ok(map)
}

impl Settings {
    pub fn from_config(c: &Config) -> Result<Settings, String> {
        let secrets = pairs(&c.webhook_secrets, "webhook_secrets")?;
        if let Some((t, _)) = secrets.iter().find(|(_, s)| s.chars().count() < 16) {
            return Err(format!(
                "webhook_secrets: tenant `{t}`'s secret is shorter than 16 characters"
            ));
        }
        let urls = pairs(&c.webhook_urls, "webhook_urls")?;
        for (t, u) in &urls {
            let url =
                reqwest::Url::parse(u).map_err(|e| format!("webhook_urls: tenant `{t}`: {e}"))?;
            if !matches!(url.scheme(), "http" | "https") {
                return Err(format!("webhook_urls: tenant `{t}`: http:// or https://"));
            }
            if !secrets.contains_key(t) {
                return Err(format!("webhook_urls: tenant `{t}` has no webhook secret"));
            }
        }
        Ok(Settings {
            secrets,
            urls,
            allow: Allow::parse(&c.webhook_allow)?,
            attempts: c.webhook_attempts.max(1),
            backoff_ms: c.webhook_backoff_ms,
        })
    }

    /// The tenant's signing secret.
    pub fn secret(&self, tenant: &str) -> Option<&str> {
        self.secrets.get(tenant).map(String::as_str)
    }

    /// The tenant's default callback URL.
    pub fn default_url(&self, tenant: &str) -> Option<&str> {
        self.urls.get(tenant).map(String::as_str)
    }

    /// The wait after failed attempt number `attempt` (1 for the first).
    pub fn backoff(&self, attempt: u32) -> u64 {
        let doubled = self
            .backoff_ms
            .saturating_mul(1u64 << attempt.saturating_sub(1).min(20));
        doubled.min(MAX_BACKOFF_MS)
    }

    /// Checks a callback URL given at creation: its form, that the tenant can sign, and that
    /// the allow-list permits it now.
    pub async fn check_callback(&self, tenant: &str, raw: &str) -> Result<String, String> {
        if raw.len() > MAX_URL {
            return Err(format!("at most {MAX_URL} characters"));
        }
        let url = reqwest::Url::parse(raw).map_err(|e| format!("not a URL: {e}"))?;
        if self.secret(tenant).is_none() {
            return Err(
                "this API key's tenant has no webhook secret (--webhook-secret), so \
                        callbacks cannot be signed"
                    .into(),
            );
        }
        self.allow.check(&url).await?;
        Ok(url.to_string())
    }
}

/// The event a finished job's webhook carries.
pub fn event(status: JobStatus) -> Option<&'static str> {
    match status {
        JobStatus::Succeeded => Some("job.succeeded"),
        JobStatus::Failed => Some("job.failed"),
        JobStatus::Cancelled => Some("job.cancelled"),
        _ => None,
    }
}

/// Delivers due webhooks until `stop` is cancelled.
pub async fn run(state: AppState, stop: CancellationToken) {
    loop {
        match state.store.claim_hooks(LEASE_MS, 16).await {
            Ok(due) => {
                let sends = due
                    .into_iter()
                    .map(|(job, attempts)| deliver(&state, job, attempts));
                futures_util::future::join_all(sends).await;
            }
            Err(e) => tracing::warn!(error = %e, "looking for due webhooks"),
        }
        tokio::select! {
            _ = tokio::time::sleep(POLL) => {}
            _ = stop.cancelled() => return,
        }
    }
}

/// One attempt at a job's webhook, recorded; then the next one scheduled, or none.
async fn deliver(state: &AppState, job: Job, attempts: u32) {
    let settings = &state.webhooks;
    let attempt = attempts + 1;
    let (Some(event), Some(url)) = (event(job.status), job.callback_url.clone()) else {
        let _ = state.store.hook_tried(job.id, attempts, None).await;
        return;
    };
    let body = serde_json::json!({
        "event": event,
        "job": JobView::new(&job, &state.config),
    })
    .to_string();
    let started = Instant::now();
    let at = now_ms();
    let (status, error, retry) = match settings.secret(&job.tenant) {
        None => (
            None,
            Some("the tenant has no webhook secret any more".to_string()),
            false,
        ),
        Some(secret) => send(settings, &url, secret, event, &job, &body).await,
    };
    let delivery = Delivery {
        id: uuid::Uuid::now_v7(),
        job: job.id,
        event: event.to_string(),
        url,
        attempt,
        at,
        status,
        error: error.clone(),
        duration_ms: started.elapsed().as_millis() as i64,
    };
    if let Err(e) = state.store.record_delivery(&delivery).await {
        tracing::warn!(job = %job.id, error = %e, "recording a webhook delivery");
    }
    let next = match &error {
        None => None,
        Some(_) if retry && attempt < settings.attempts => {
            Some(now_ms() + settings.backoff(attempt) as i64)
        }
        Some(_) => None,
    };
    match (&error, next) {
        (None, _) => tracing::info!(job = %job.id, event, attempt, "webhook delivered"),
        (Some(e), Some(_)) => {
            tracing::info!(job = %job.id, event, attempt, error = %e, "webhook failed; will retry")
        }
        (Some(e), None) => {
            tracing::warn!(job = %job.id, event, attempt, error = %e, "webhook failed; giving up")
        }
    }
    if let Err(e) = state.store.hook_tried(job.id, attempt, next).await {
        tracing::warn!(job = %job.id, error = %e, "recording a webhook attempt");
    }
}

/// POSTs `body`; the receiver's status, the error if it failed, and whether to retry.
async fn send(
    settings: &Settings,
    url: &str,
    secret: &str,
    event: &str,
    job: &Job,
    body: &str,
) -> (Option<u16>, Option<String>, bool) {
    let Ok(parsed) = reqwest::Url::parse(url) else {
        return (None, Some("not a URL".into()), false);
    };
    // Checked again now: DNS may have changed since the job was created.
    let addr = match settings.allow.check(&parsed).await {
        Ok(a) => a,
        Err(e) => return (None, Some(format!("target refused: {e}")), false),
    };
    let host = parsed.host_str().unwrap_or_default().to_string();
    let client = match reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .timeout(TIMEOUT)
        // Connect to the address just checked, whatever DNS says next.
        .resolve(&host, addr)
        .build()
    {
        Ok(c) => c,
        Err(e) => return (None, Some(e.to_string()), true),
    };
    let t = now_ms() / 1000;
    let sent = client
        .post(parsed)
        .header("content-type", "application/json")
        .header("user-agent", concat!("asbuilt/", env!("CARGO_PKG_VERSION")))
        .header("asbuilt-event", event)
        .header("asbuilt-job", job.id.to_string())
        .header(sign::HEADER, sign::header(secret, t, body.as_bytes()))
        .body(body.to_string())
        .send()
        .await;
    match sent {
        Ok(res) if res.status().is_success() => (Some(res.status().as_u16()), None, false),
        Ok(res) => {
            let status = res.status().as_u16();
            (
                Some(status),
                Some(format!("the receiver answered {status}")),
                true,
            )
        }
        Err(e) => (None, Some(format!("no answer: {e}")), true),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_are_checked_and_backoff_doubles() {
        let mut c = Config {
            webhook_secrets: vec!["acme:0123456789abcdef".into()],
            webhook_urls: vec!["acme:https://hooks.example.com/asbuilt".into()],
            ..Config::default()
        };
        let s = Settings::from_config(&c).unwrap();
        assert_eq!(s.secret("acme"), Some("0123456789abcdef"));
        assert_eq!(
            s.default_url("acme"),
            Some("https://hooks.example.com/asbuilt")
        );
        assert_eq!(
            (s.backoff(1), s.backoff(2), s.backoff(3)),
            (10_000, 20_000, 40_000)
        );
        assert_eq!(s.backoff(40), MAX_BACKOFF_MS);
        c.webhook_secrets = vec!["acme:short".into()];
        assert!(Settings::from_config(&c).unwrap_err().contains("16"));
        c.webhook_secrets = vec!["bolt:0123456789abcdef".into()];
        assert!(Settings::from_config(&c)
            .unwrap_err()
            .contains("no webhook secret"));
        c.webhook_secrets = vec!["nocolon".into()];
        assert!(Settings::from_config(&c).is_err());
    }
}
