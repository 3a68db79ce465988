//! The HTTP routes. [`routes`] lists them for the OpenAPI test; [`build`] wires them.

use axum::extract::DefaultBodyLimit;
use axum::http::{header, HeaderName, HeaderValue, Method};
use axum::response::Response;
use axum::routing::{get, post};
use axum::Router;
use tower_http::compression::CompressionLayer;
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::trace::TraceLayer;

use crate::app::AppState;
use crate::controllers::{self, jobs};

/// The fixed routes, as (method, OpenAPI path); [`routes`] adds the results. The OpenAPI test
/// checks the document against them, and that each reaches a handler.
pub const ROUTES: &[(&str, &str)] = &[
    ("GET", "/"),
    ("GET", "/healthz"),
    ("GET", "/readyz"),
    ("GET", "/metrics"),
    ("GET", "/openapi.json"),
    ("GET", "/v1/parameters"),
    ("POST", "/v1/jobs"),
    ("GET", "/v1/jobs"),
    ("GET", "/v1/jobs/{id}"),
    ("DELETE", "/v1/jobs/{id}"),
    ("GET", "/v1/jobs/{id}/events"),
    ("POST", "/v1/jobs/{id}/cancel"),
    ("POST", "/v1/jobs/{id}/replan"),
    ("GET", "/v1/jobs/{id}/deliveries"),
    ("POST", "/v1/uploads"),
    ("HEAD", "/v1/uploads/{id}"),
    ("GET", "/v1/uploads/{id}"),
    ("PATCH", "/v1/uploads/{id}"),
    ("DELETE", "/v1/uploads/{id}"),
    ("POST", "/v1/uploads/{id}/job"),
    ("POST", "/v1/direct-uploads"),
    ("GET", "/v1/direct-uploads/{id}"),
    ("DELETE", "/v1/direct-uploads/{id}"),
    ("POST", "/v1/direct-uploads/{id}/job"),
];

/// Every route: [`ROUTES`], then a download per result of `asbuilt_plan::io::outputs::OUTPUTS`
/// (all served by one `/v1/jobs/{id}/{file}` route).
pub fn routes() -> Vec<(&'static str, String)> {
    let results = asbuilt_plan::io::outputs::OUTPUTS
        .iter()
        .map(|o| ("GET", format!("/v1/jobs/{{id}}/{}", o.file)));
    ROUTES
        .iter()
        .map(|(m, p)| (*m, p.to_string()))
        .chain(results)
        .collect()
}

/// A worker-only process's router: liveness, readiness and metrics for probes and scrapers.
pub fn worker(state: AppState) -> Router {
    Router::new()
        .route("/healthz", get(controllers::health::healthz))
        .route("/readyz", get(controllers::health::readyz))
        .route("/metrics", get(controllers::metrics::metrics))
        .fallback(controllers::route_not_found)
        .with_state(state)
}

/// The `--metrics-listen` router: `/metrics` without a key, and nothing else.
pub fn metrics_only(state: AppState) -> Router {
    Router::new()
        .route("/metrics", get(controllers::metrics::metrics_open))
        .fallback(controllers::route_not_found)
        .with_state(state)
}

/// The CORS layer for `origins` (`--cors-origin`); `None` when none are set. An origin is
/// `scheme://host[:port]`, or `*` for any (then without credentials, as browsers require).
pub fn cors(origins: &[String]) -> Result<Option<CorsLayer>, String> {
    if origins.is_empty() {
        return Ok(None);
    }
    let allow = if origins.iter().any(|o| o == "*") {
        AllowOrigin::any()
    } else {
        let mut list = vec![];
        for o in origins {
            let ok = (o.starts_with("https://") || o.starts_with("http://"))
                && !o.trim_end_matches('/').contains(['?', '#'])
                && o.split("://")
                    .nth(1)
                    .is_some_and(|h| !h.is_empty() && !h.contains('/'));
            if !ok {
                return Err(format!(
                    "cors_origins: `{o}` is not an origin such as https://app.example.com or *"
                ));
            }
            list.push(HeaderValue::from_str(o).map_err(|e| format!("cors_origins: {e}"))?);
        }
        AllowOrigin::list(list)
    };
    let expose = [
        header::LOCATION,
        header::ETAG,
        header::CONTENT_RANGE,
        header::RETRY_AFTER,
        HeaderName::from_static("idempotent-replayed"),
        HeaderName::from_static("tus-resumable"),
        HeaderName::from_static("upload-length"),
        HeaderName::from_static("upload-offset"),
    ];
    Ok(Some(
        CorsLayer::new()
            .allow_origin(allow)
            .allow_methods([
                Method::GET,
                Method::HEAD,
                Method::POST,
                Method::PATCH,
                Method::DELETE,
            ])
            .allow_headers([
                header::AUTHORIZATION,
                header::CONTENT_TYPE,
                header::RANGE,
                header::IF_NONE_MATCH,
                header::IF_RANGE,
                HeaderName::from_static("idempotency-key"),
                HeaderName::from_static("last-event-id"),
                HeaderName::from_static("tus-resumable"),
                HeaderName::from_static("upload-length"),
                HeaderName::from_static("upload-offset"),
            ])
            .expose_headers(expose)
            .max_age(std::time::Duration::from_secs(3600)),
    ))
}

/// A gzipped answer is another representation, so a strong `ETag` gets a `-gzip` suffix
/// (`results.rs` accepts both forms in `If-None-Match`).
async fn tag_encoding(mut response: Response) -> Response {
    let gzipped = response
        .headers()
        .get(header::CONTENT_ENCODING)
        .is_some_and(|e| e == "gzip");
    if gzipped {
        let tagged = response
            .headers()
            .get(header::ETAG)
            .and_then(|t| t.to_str().ok())
            .filter(|t| t.starts_with('"') && t.ends_with('"') && t.len() >= 2)
            .map(|t| format!("\"{}-gzip\"", &t[1..t.len() - 1]));
        if let Some(v) = tagged.and_then(|t| HeaderValue::from_str(&t).ok()) {
            response.headers_mut().insert(header::ETAG, v);
        }
    }
    response
}

/// The application's router.
pub fn build(state: AppState) -> Router {
    let cors = cors(&state.config.cors_origins).ok().flatten();
    let router = Router::new()
        .route("/", get(controllers::page::index))
        .route("/healthz", get(controllers::health::healthz))
        .route("/readyz", get(controllers::health::readyz))
        .route("/metrics", get(controllers::metrics::metrics))
        .route("/openapi.json", get(controllers::openapi::document))
        .route("/v1/parameters", get(controllers::parameters::defaults))
        .route(
            "/v1/jobs",
            // Uploads stream with their own limit; the default 2 MB body limit must not apply.
            post(jobs::create::create)
                .layer(DefaultBodyLimit::disable())
                .get(jobs::list::list),
        )
        .route(
            "/v1/jobs/{id}",
            get(jobs::show::show).delete(jobs::delete::delete),
        )
        .route("/v1/jobs/{id}/events", get(jobs::events::events))
        .route("/v1/jobs/{id}/cancel", post(jobs::cancel::cancel))
        .route("/v1/jobs/{id}/replan", post(jobs::replan::replan))
        .route(
            "/v1/jobs/{id}/deliveries",
            get(jobs::deliveries::deliveries),
        )
        .route("/v1/uploads", post(jobs::uploads::open))
        .route(
            "/v1/uploads/{id}",
            get(jobs::uploads::show)
                .head(jobs::uploads::head)
                .patch(jobs::uploads::append)
                .delete(jobs::uploads::remove)
                .layer(DefaultBodyLimit::disable()),
        )
        .route("/v1/uploads/{id}/job", post(jobs::uploads::commit))
        .route("/v1/direct-uploads", post(jobs::direct::open))
        .route(
            "/v1/direct-uploads/{id}",
            get(jobs::direct::show).delete(jobs::direct::remove),
        )
        .route("/v1/direct-uploads/{id}/job", post(jobs::direct::commit))
        // Every result file (`plan.geojson`, ...); `events` is matched first as the fixed path.
        .route("/v1/jobs/{id}/{file}", get(jobs::results::file))
        .fallback(controllers::route_not_found)
        .method_not_allowed_fallback(controllers::method_not_allowed)
        // gzip when the client accepts it; not for event streams, images or byte ranges.
        .layer(CompressionLayer::new().gzip(true))
        .layer(axum::middleware::map_response(tag_encoding))
        .layer(TraceLayer::new_for_http())
        .with_state(state);
    match cors {
        Some(layer) => router.layer(layer),
        None => router,
    }
}
