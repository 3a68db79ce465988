//! `GET /v1/jobs?status=&cursor=&limit=&external_ref=&tag=`: the caller's jobs, newest first;
//! `tag` may repeat, and a job must carry every tag asked for.

use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, State};
use axum::Json;
use serde::Serialize;

use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::{ApiError, Code};
use crate::queue::{JobId, ListQuery};
use crate::views::JobView;

use super::submit;

/// Page size when none is asked for, and the largest allowed.
const DEFAULT_LIMIT: u32 = 20;
const MAX_LIMIT: u32 = 100;

#[derive(Serialize)]
pub struct Page {
    pub jobs: Vec<JobView>,
    /// Pass as `cursor` for the next page; null on the last page.
    pub next_cursor: Option<String>,
}

pub async fn list(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    query: Result<Query<Vec<(String, String)>>, QueryRejection>,
) -> Result<Json<Page>, ApiError> {
    let Query(pairs) = query.map_err(|e| ApiError::new(Code::InvalidRequest, e.body_text()))?;
    let mut q = ListQuery {
        tenant,
        limit: DEFAULT_LIMIT,
        ..Default::default()
    };
    for (key, value) in pairs {
        match key.as_str() {
            "status" => {
                q.status = Some(value.parse().map_err(|_: String| {
                    ApiError::param(
                        "status",
                        "unknown status; use queued, running, succeeded, failed or cancelled",
                    )
                })?)
            }
            "cursor" => {
                q.before = Some(value.parse::<JobId>().map_err(|_| {
                    ApiError::param("cursor", "not a cursor from a previous page's next_cursor")
                })?)
            }
            "limit" => {
                q.limit = value
                    .parse::<u32>()
                    .ok()
                    .filter(|n| (1..=MAX_LIMIT).contains(n))
                    .ok_or_else(|| {
                        ApiError::param(
                            "limit",
                            format!("must be a whole number from 1 to {MAX_LIMIT}"),
                        )
                    })?
            }
            "external_ref" => q.external_ref = Some(submit::check_external_ref(&value)?),
            "tag" => submit::add_tag(&mut q.tags, &value)?,
            other => {
                return Err(ApiError::param(
                    other,
                    "unknown query parameter; use status, cursor, limit, external_ref or tag",
                ))
            }
        }
    }
    // One extra row says whether another page exists.
    let wanted = q.limit as usize;
    q.limit += 1;
    let mut jobs = state.store.list(&q).await?;
    let more = jobs.len() > wanted;
    jobs.truncate(wanted);
    let next_cursor = if more {
        jobs.last().map(|j| j.id.to_string())
    } else {
        None
    };
    Ok(Json(Page {
        jobs: jobs
            .iter()
            .map(|j| JobView::new(j, &state.config))
            .collect(),
        next_cursor,
    }))
}
