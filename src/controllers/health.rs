//! Liveness and readiness.

use axum::extract::State;
use axum::Json;
use serde_json::{json, Value};

use crate::app::AppState;
use crate::errors::{ApiError, Code};

/// The process answers.
pub async fn healthz() -> Json<Value> {
    Json(json!({"status": "ok"}))
}

/// The database and blob store answer, and the server is not shutting down.
pub async fn readyz(State(state): State<AppState>) -> Result<Json<Value>, ApiError> {
    if state.shutdown.is_cancelled() {
        return Err(ApiError::new(Code::Unavailable, "shutting down"));
    }
    state
        .store
        .ping()
        .await
        .map_err(|e| ApiError::new(Code::Unavailable, format!("job store: {e}")))?;
    state
        .blobs
        .ping()
        .await
        .map_err(|e| ApiError::new(Code::Unavailable, format!("blob store: {e}")))?;
    Ok(Json(json!({"status": "ready"})))
}
