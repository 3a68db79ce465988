//! Request handlers, one module per resource.

pub mod health;
pub mod jobs;
pub mod metrics;
pub mod openapi;
pub mod page;
pub mod parameters;

use crate::errors::ApiError;

/// Any path not in the router.
pub async fn route_not_found() -> ApiError {
    ApiError::new("route_not_found", "no such endpoint; see /openapi.json")
}

/// A known path with the wrong method.
pub async fn method_not_allowed() -> ApiError {
    ApiError::new(
        "method_not_allowed",
        "this endpoint does not take that method; see /openapi.json",
    )
}
