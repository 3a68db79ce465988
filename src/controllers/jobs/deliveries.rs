//! `GET /v1/jobs/{id}/deliveries`: every attempt at the job's webhook, oldest first.

use axum::extract::{Path, State};
use axum::Json;
use serde::Serialize;

use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::ApiError;
use crate::views::DeliveryView;

#[derive(Serialize)]
pub struct Deliveries {
    pub callback_url: Option<String>,
    pub deliveries: Vec<DeliveryView>,
}

pub async fn deliveries(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(id): Path<String>,
) -> Result<Json<Deliveries>, ApiError> {
    let job = super::load(&state, &tenant, &id).await?;
    let attempts = state.store.deliveries(job.id).await?;
    Ok(Json(Deliveries {
        callback_url: job.callback_url,
        deliveries: attempts.iter().map(DeliveryView::from).collect(),
    }))
}
