//! `GET /v1/parameters`: every pipeline parameter with its default (the paper's).

use axum::Json;

pub async fn defaults() -> Json<serde_json::Value> {
    Json(asbuilt_plan::Params::default().to_json())
}
