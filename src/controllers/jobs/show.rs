//! `GET /v1/jobs/{id}`.

use axum::extract::{Path, State};
use axum::Json;

use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::ApiError;
use crate::views::JobView;

pub async fn show(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(id): Path<String>,
) -> Result<Json<JobView>, ApiError> {
    let job = super::load(&state, &tenant, &id).await?;
    Ok(Json(JobView::new(&job, &state.config)))
}
