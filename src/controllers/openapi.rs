//! `GET /openapi.json`: the published contract, `openapi/asbuilt.yaml`, as JSON.

use axum::Json;

pub async fn document() -> Json<serde_json::Value> {
    Json(crate::openapi::document().clone())
}
