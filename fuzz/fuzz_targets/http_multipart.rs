#![no_main]
//! A `multipart/form-data` upload body (boundary `fuzzboundary`: parts `cloud`, `poses`,
//! `trajectory`, `params`, anything else), through the service's router.

#[path = "service.rs"]
mod service;

use axum::body::Body;
use axum::http::Request;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let req = Request::post("/v1/jobs")
        .header("authorization", format!("Bearer {}", service::KEY))
        .header(
            "content-type",
            "multipart/form-data; boundary=fuzzboundary",
        )
        .body(Body::from(data.to_vec()))
        .unwrap();
    service::harness().send(req);
});
