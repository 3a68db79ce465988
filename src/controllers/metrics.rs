//! `GET /metrics`, Prometheus text format. The counts cover every tenant, so on the API
//! listener they need the metrics key (`--metrics-key`); `--metrics-listen` serves them without
//! one on an address of their own, for a private scrape network.

use axum::extract::State;
use axum::http::header::{AUTHORIZATION, CONTENT_TYPE};
use axum::http::HeaderMap;
use axum::response::IntoResponse;
use sha2::{Digest, Sha256};

use crate::app::AppState;
use crate::auth::bearer;
use crate::errors::{ApiError, Code};

/// On the API (or worker) listener: development mode, a worker-only process (which serves no
/// tenant's API) or the metrics key.
pub async fn metrics(
    State(state): State<AppState>,
    headers: HeaderMap,
) -> Result<impl IntoResponse, ApiError> {
    let config = &state.config;
    let open = state.keys.is_dev() || (!config.serve_api && config.metrics_key.is_none());
    if !open {
        let Some(want) = &config.metrics_key else {
            return Err(ApiError::new(
                Code::Unauthorized,
                "/metrics is not served on this port without a metrics key; scrape the --metrics-listen address",
            ));
        };
        let got = bearer(headers.get(AUTHORIZATION).and_then(|v| v.to_str().ok()));
        // Compared as digests, as API keys are.
        let same = got.is_some_and(|k| Sha256::digest(k) == Sha256::digest(want));
        if !same {
            return Err(ApiError::new(
                Code::Unauthorized,
                "/metrics needs `Authorization: Bearer <metrics key>`",
            ));
        }
    }
    render(&state).await
}

/// On the metrics listener: no key.
pub async fn metrics_open(State(state): State<AppState>) -> Result<impl IntoResponse, ApiError> {
    render(&state).await
}

async fn render(state: &AppState) -> Result<impl IntoResponse, ApiError> {
    let counts = state.store.counts_by_status().await?;
    Ok((
        [(CONTENT_TYPE, "text/plain; version=0.0.4; charset=utf-8")],
        state.metrics.render(&counts),
    ))
}
