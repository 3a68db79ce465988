//! API keys and tenants. A request names its key in `Authorization: Bearer <key>` (the scheme
//! in any case, RFC 7235); the key belongs to one tenant, and every job query is filtered by
//! that tenant. Keys come from `--api-key` and from a keys file that is re-read when it
//! changes, so keys are added and revoked without a restart.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::path::Path;
use std::sync::RwLock;

use axum::extract::{ConnectInfo, FromRequestParts};
use axum::http::header::AUTHORIZATION;
use axum::http::request::Parts;
use sha2::{Digest, Sha256};

use crate::app::AppState;
use crate::errors::{ApiError, Code};

/// The tenant of development mode, when no keys are configured.
pub const DEV_TENANT: &str = "dev";

/// The shortest key accepted: 16 characters of a random key are beyond guessing, and a short
/// key is more likely a typo or a placeholder.
pub const MIN_KEY_LEN: usize = 16;

/// The `tenant:key` lines of a keys file: blank lines and `#` comments skipped.
pub fn key_lines(text: &str) -> Vec<String> {
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(str::to_string)
        .collect()
}

/// Checks `tenant:key` entries: a tenant name, a key of at least [`MIN_KEY_LEN`] characters,
/// and no key given twice (a typo that would hand one tenant's jobs to another). Messages name
/// the tenants, never the keys.
pub fn parse_keys<'a>(
    entries: impl IntoIterator<Item = &'a str>,
    source: &str,
) -> Result<Vec<(String, String)>, String> {
    let mut out: Vec<(String, String)> = Vec::new();
    let mut owner: HashMap<&str, &str> = HashMap::new();
    let entries: Vec<&str> = entries.into_iter().collect();
    for e in &entries {
        let Some((tenant, key)) = e.split_once(':') else {
            return Err(format!(
                "{source}: an entry is not TENANT:KEY (it has no `:`)"
            ));
        };
        let (tenant, key) = (tenant.trim(), key.trim());
        if tenant.is_empty()
            || !tenant
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
        {
            return Err(format!(
                "{source}: tenant `{tenant}`: use letters, digits, `-`, `_` and `.`"
            ));
        }
        if key.chars().count() < MIN_KEY_LEN {
            return Err(format!(
                "{source}: the key of tenant `{tenant}` is shorter than {MIN_KEY_LEN} characters"
            ));
        }
        if let Some(first) = owner.insert(key, tenant) {
            return Err(format!(
                "{source}: tenants `{first}` and `{tenant}` are given the same key; each key must be unique"
            ));
        }
        out.push((tenant.to_string(), key.to_string()));
    }
    Ok(out)
}

/// Reads and checks a keys file.
pub fn read_keys_file(path: &Path) -> Result<Vec<(String, String)>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let lines = key_lines(&text);
    parse_keys(
        lines.iter().map(String::as_str),
        &path.display().to_string(),
    )
}

fn digest(key: &str) -> [u8; 32] {
    Sha256::digest(key.as_bytes()).into()
}

/// The configured keys, held as SHA-256 digests so lookups do not compare secrets directly.
/// Replaced whole when the keys file changes.
#[derive(Debug, Default)]
pub struct Keys {
    /// Development mode: no keys configured at start-up, every caller is [`DEV_TENANT`].
    /// Fixed for the process's life: revoking every key of a keys file does not open the API.
    dev: bool,
    by_digest: RwLock<HashMap<[u8; 32], String>>,
}

impl Keys {
    /// From checked `(tenant, key)` pairs; `dev` when none were configured at all.
    pub fn new(entries: &[(String, String)], dev: bool) -> Keys {
        let keys = Keys {
            dev,
            by_digest: RwLock::default(),
        };
        keys.replace(entries);
        keys
    }

    /// Swaps in a new set of keys (the keys file changed).
    pub fn replace(&self, entries: &[(String, String)]) {
        let map = entries
            .iter()
            .map(|(tenant, key)| (digest(key), tenant.clone()))
            .collect();
        *self.by_digest.write().expect("keys lock") = map;
    }

    /// How many keys are held.
    pub fn len(&self) -> usize {
        self.by_digest.read().expect("keys lock").len()
    }

    /// True when no keys are held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// True in development mode.
    pub fn is_dev(&self) -> bool {
        self.dev
    }

    /// The tenant an `Authorization` header value authenticates.
    pub fn tenant(&self, authorization: Option<&str>) -> Result<String, ApiError> {
        if self.dev {
            return Ok(DEV_TENANT.to_string());
        }
        let key = bearer(authorization).ok_or_else(|| {
            ApiError::new(Code::Unauthorized, "send `Authorization: Bearer <API key>`")
        })?;
        self.by_digest
            .read()
            .expect("keys lock")
            .get(&digest(key))
            .cloned()
            .ok_or_else(|| ApiError::new(Code::Unauthorized, "unknown API key"))
    }
}

/// The credentials of a `Bearer` authorization value; the scheme is case-insensitive.
pub fn bearer(authorization: Option<&str>) -> Option<&str> {
    let (scheme, rest) = authorization?.trim_start().split_once([' ', '\t'])?;
    let key = rest.trim();
    (scheme.eq_ignore_ascii_case("bearer") && !key.is_empty()).then_some(key)
}

/// Keeps the keys in step with the keys file: checks its modification time and size every
/// `every`, and on a change reads it again. A file that fails the checks is logged and the
/// keys in force are kept.
pub async fn watch_keys_file(state: AppState, every: std::time::Duration) {
    let Some(path) = state.config.api_keys_file.clone() else {
        return;
    };
    let stamp = |p: &Path| {
        std::fs::metadata(p)
            .ok()
            .map(|m| (m.modified().ok(), m.len()))
    };
    let mut last = stamp(&path);
    loop {
        tokio::select! {
            _ = tokio::time::sleep(every) => {}
            _ = state.shutdown.cancelled() => return,
        }
        let now = stamp(&path);
        if now == last {
            continue;
        }
        last = now;
        match state.config.all_keys() {
            Ok(entries) => {
                state.keys.replace(&entries);
                tracing::info!(keys = entries.len(), file = %path.display(), "API keys reloaded");
            }
            Err(e) => {
                tracing::error!(error = %e, "API keys file not reloaded; the keys in force stay")
            }
        }
    }
}

/// The calling tenant, as an extractor: authenticates the key, then applies the tenant's rate
/// limit. Addresses that keep sending unknown keys are refused for a while without a lookup.
pub struct Tenant(pub String);

impl FromRequestParts<AppState> for Tenant {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> Result<Self, ApiError> {
        let addr = parts
            .extensions
            .get::<ConnectInfo<SocketAddr>>()
            .map(|c| c.0.ip());
        if let Some(ip) = addr {
            state.limits.check_address(ip)?;
        }
        let header = parts
            .headers
            .get(AUTHORIZATION)
            .and_then(|v| v.to_str().ok());
        match state.keys.tenant(header) {
            Ok(tenant) => {
                // Development mode is one local caller: nothing to share fairly.
                if !state.keys.is_dev() {
                    state.limits.check_tenant(&tenant)?;
                }
                Ok(Tenant(tenant))
            }
            Err(e) => {
                if let Some(ip) = addr {
                    // Past the burst, this one is already answered with the brake.
                    state.limits.failed_auth(ip)?;
                }
                Err(e)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pairs(entries: &[&str]) -> Vec<(String, String)> {
        parse_keys(entries.iter().copied(), "test").unwrap()
    }

    #[test]
    fn keys_name_their_tenant_and_the_scheme_is_case_insensitive() {
        let keys = Keys::new(
            &pairs(&["acme:key-one-1234567890", "bolt:key-two-1234567890"]),
            false,
        );
        assert_eq!(
            keys.tenant(Some("Bearer key-two-1234567890")).unwrap(),
            "bolt"
        );
        assert_eq!(
            keys.tenant(Some("bearer key-two-1234567890")).unwrap(),
            "bolt"
        );
        assert_eq!(
            keys.tenant(Some("BEARER   key-one-1234567890 ")).unwrap(),
            "acme"
        );
        assert_eq!(
            keys.tenant(Some("Bearer nope")).unwrap_err().code,
            Code::Unauthorized
        );
        assert_eq!(
            keys.tenant(Some("key-one-1234567890")).unwrap_err().code,
            Code::Unauthorized
        );
        assert_eq!(
            keys.tenant(Some("Basic key-one-1234567890"))
                .unwrap_err()
                .code,
            Code::Unauthorized
        );
        assert_eq!(keys.tenant(None).unwrap_err().status, 401);
        assert_eq!(Keys::new(&[], true).tenant(None).unwrap(), DEV_TENANT);
        // Revoking every key does not open the API.
        keys.replace(&[]);
        assert!(keys.tenant(Some("Bearer key-one-1234567890")).is_err());
    }

    #[test]
    fn short_duplicate_and_malformed_keys_are_refused_naming_tenants_only() {
        let e = parse_keys(["acme:tiny-key"], "x").unwrap_err();
        assert!(
            e.contains("acme") && e.contains("16") && !e.contains("tiny-key"),
            "{e}"
        );
        let e = parse_keys(["acme:0123456789abcdef", "bolt:0123456789abcdef"], "x").unwrap_err();
        assert!(e.contains("`acme`") && e.contains("`bolt`"), "{e}");
        assert!(!e.contains("0123456789abcdef"), "{e}");
        assert!(parse_keys(["no-colon-0123456789abcdef"], "x").is_err());
        assert!(parse_keys([":0123456789abcdef"], "x").is_err());
        assert!(parse_keys(["a b:0123456789abcdef"], "x").is_err());
        assert_eq!(
            key_lines("# tenants\n\nacme:0123456789abcdef\n  bolt:fedcba9876543210  \n"),
            vec!["acme:0123456789abcdef", "bolt:fedcba9876543210"]
        );
    }
}
