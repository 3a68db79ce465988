//! Request handlers, one module per resource.

pub mod health;
pub mod jobs;
pub mod metrics;
pub mod openapi;
pub mod page;
pub mod parameters;

use crate::errors::{ApiError, Code};

/// Any path not in the router.
pub async fn route_not_found() -> ApiError {
    ApiError::new(Code::RouteNotFound, "no such endpoint; see /openapi.json")
}

/// A known path with the wrong method.
pub async fn method_not_allowed() -> ApiError {
    ApiError::new(
        Code::MethodNotAllowed,
        "this endpoint does not take that method; see /openapi.json",
    )
}
