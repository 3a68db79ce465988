//! API keys and tenants. A request names its key in `Authorization: Bearer <key>`; the key
//! belongs to one tenant, and every job query is filtered by that tenant.

use std::collections::HashMap;

use axum::extract::FromRequestParts;
use axum::http::header::AUTHORIZATION;
use axum::http::request::Parts;
use sha2::{Digest, Sha256};

use crate::app::AppState;
use crate::errors::ApiError;

/// The tenant of development mode, when no keys are configured.
pub const DEV_TENANT: &str = "dev";

/// The configured keys, held as SHA-256 digests so lookups do not compare secrets directly.
#[derive(Debug, Clone, Default)]
pub struct Keys {
    by_digest: HashMap<[u8; 32], String>,
}

impl Keys {
    /// From `tenant:key` strings (already checked by the config).
    pub fn new(entries: &[String]) -> Keys {
        let by_digest = entries
            .iter()
            .filter_map(|e| e.split_once(':'))
            .map(|(tenant, key)| (Sha256::digest(key.as_bytes()).into(), tenant.to_string()))
            .collect();
        Keys { by_digest }
    }

    /// True when no keys are configured (development mode).
    pub fn is_empty(&self) -> bool {
        self.by_digest.is_empty()
    }

    /// The tenant an `Authorization` header value authenticates.
    pub fn tenant(&self, authorization: Option<&str>) -> Result<String, ApiError> {
        if self.is_empty() {
            return Ok(DEV_TENANT.to_string());
        }
        let key = authorization
            .and_then(|h| h.strip_prefix("Bearer "))
            .map(str::trim)
            .ok_or_else(|| {
                ApiError::new("unauthorized", "send `Authorization: Bearer <API key>`")
            })?;
        let digest: [u8; 32] = Sha256::digest(key.as_bytes()).into();
        self.by_digest
            .get(&digest)
            .cloned()
            .ok_or_else(|| ApiError::new("unauthorized", "unknown API key"))
    }
}

/// The calling tenant, as an extractor.
pub struct Tenant(pub String);

impl FromRequestParts<AppState> for Tenant {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> Result<Self, ApiError> {
        let header = parts
            .headers
            .get(AUTHORIZATION)
            .and_then(|v| v.to_str().ok());
        state.keys.tenant(header).map(Tenant)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_name_their_tenant() {
        let keys = Keys::new(&["acme:key-one-1234".into(), "bolt:key-two-1234".into()]);
        assert_eq!(keys.tenant(Some("Bearer key-two-1234")).unwrap(), "bolt");
        assert_eq!(
            keys.tenant(Some("Bearer nope")).unwrap_err().code,
            "unauthorized"
        );
        assert_eq!(
            keys.tenant(Some("key-one-1234")).unwrap_err().code,
            "unauthorized"
        );
        assert_eq!(keys.tenant(None).unwrap_err().status, 401);
        assert_eq!(Keys::new(&[]).tenant(None).unwrap(), DEV_TENANT);
    }
}
