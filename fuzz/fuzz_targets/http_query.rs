#![no_main]
//! The query string of `POST /v1/jobs` (parameter overrides, `filename`) and `GET /v1/jobs`
//! (`status`, `cursor`, `limit`), through the service's router. The first byte picks the
//! request; the rest is the query string as sent.

#[path = "service.rs"]
mod service;

use axum::body::Body;
use axum::http::Request;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    let Ok(query) = std::str::from_utf8(rest) else {
        return;
    };
    let (method, path) = match pick % 3 {
        0 => ("POST", "/v1/jobs"),
        1 => ("GET", "/v1/jobs"),
        _ => ("GET", "/v1/jobs/0190c1d2-7a3b-7c00-8000-000000000000"),
    };
    // A URI the HTTP parser would refuse never reaches the router.
    let Ok(uri) = format!("{path}?{query}").parse::<axum::http::Uri>() else {
        return;
    };
    let body = if method == "POST" {
        Body::from("0 0 0\n1 0 0\n0 1 0\n")
    } else {
        Body::empty()
    };
    let req = Request::builder()
        .method(method)
        .uri(uri)
        .header("authorization", format!("Bearer {}", service::KEY))
        .body(body)
        .unwrap();
    service::harness().send(req);
});
