//! Bad bodies, parameters, identifiers and hostile requests: JSON errors with stable codes.

use std::time::Duration;

use serde_json::Value;

use super::fake;
use crate::support::files_under;
use crate::support::server::{expect_error, start, xyz};

#[tokio::test]
async fn bad_bodies_and_parameters_get_stable_codes() {
    let s = start(fake(1), |c| c.workers = 0).await;
    let png = b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR".to_vec();
    expect_error(
        s.post("/v1/jobs").body(png).send().await.unwrap(),
        415,
        "unsupported_format",
    )
    .await;
    expect_error(
        s.post("/v1/jobs").body("").send().await.unwrap(),
        422,
        "missing_cloud",
    )
    .await;
    let body = expect_error(
        s.post("/v1/jobs?samples.cell_sise=1")
            .body(xyz(3))
            .send()
            .await
            .unwrap(),
        422,
        "invalid_parameter",
    )
    .await;
    assert_eq!(body["error"]["param"], "samples.cell_sise");
    let body = expect_error(
        s.post("/v1/jobs?samples.cell_size=abc")
            .body(xyz(3))
            .send()
            .await
            .unwrap(),
        422,
        "invalid_parameter",
    )
    .await;
    assert_eq!(body["error"]["param"], "samples.cell_size");
    // A well-formed value out of range is refused up front, named, before any job exists.
    for (query, param) in [
        ("samples.cell_size=-1", "samples.cell_size"),
        ("fitting.inlier_angle=7", "fitting.inlier_angle"),
    ] {
        let body = expect_error(
            s.post(&format!("/v1/jobs?{query}"))
                .body(xyz(3))
                .send()
                .await
                .unwrap(),
            422,
            "invalid_parameter",
        )
        .await;
        assert_eq!(body["error"]["param"], param, "{body}");
    }
    // Hostile JSON in the params part: deep nesting, wrong types, unknown fields.
    let deep = "[".repeat(100_000);
    for (params, param) in [
        (deep.as_str(), None),
        (r#"{"samples": {"cell_size": "big"}}"#, None),
        (r#"{"samples": {"bogus": 1}}"#, Some("bogus")),
        ("\u{0}\u{1}", None),
    ] {
        let form = reqwest::multipart::Form::new()
            .part("cloud", reqwest::multipart::Part::text(xyz(3)))
            .part("params", reqwest::multipart::Part::text(params.to_string()));
        let body = expect_error(
            s.post("/v1/jobs").multipart(form).send().await.unwrap(),
            422,
            "invalid_parameter",
        )
        .await;
        if let Some(p) = param {
            assert_eq!(body["error"]["param"], p);
        }
    }
    let form = reqwest::multipart::Form::new()
        .part("cloud", reqwest::multipart::Part::text(xyz(3)))
        .part("poses", reqwest::multipart::Part::text("[1, 2"));
    expect_error(
        s.post("/v1/jobs").multipart(form).send().await.unwrap(),
        422,
        "invalid_sidecar",
    )
    .await;
    let form = reqwest::multipart::Form::new()
        .part("poses", reqwest::multipart::Part::text(r#"{"scans": []}"#));
    expect_error(
        s.post("/v1/jobs").multipart(form).send().await.unwrap(),
        422,
        "missing_cloud",
    )
    .await;
    let form =
        reqwest::multipart::Form::new().part("../../x", reqwest::multipart::Part::text("{}"));
    expect_error(
        s.post("/v1/jobs").multipart(form).send().await.unwrap(),
        400,
        "invalid_multipart",
    )
    .await;
    let res = s
        .post("/v1/jobs")
        .header("content-type", "multipart/form-data; boundary=zz")
        .body("--zz\r\nbroken")
        .send()
        .await
        .unwrap();
    expect_error(res, 400, "invalid_multipart").await;
    // Nothing refused was kept, and the server still answers.
    assert!(
        files_under(&s.blobs()).is_empty(),
        "{:?}",
        files_under(&s.blobs())
    );
    assert_eq!(s.get("/healthz").send().await.unwrap().status(), 200);
}

#[tokio::test]
async fn identifiers_are_validated() {
    let s = start(fake(1), |_| {}).await;
    for id in [
        "..%2F..%2Fetc%2Fpasswd",
        "not-a-uuid",
        "%2e%2e%2f%2e%2e",
        "00000000-0000-0000-0000-00000000000Z",
    ] {
        expect_error(
            s.get(&format!("/v1/jobs/{id}")).send().await.unwrap(),
            404,
            "not_found",
        )
        .await;
        expect_error(
            s.get(&format!("/v1/jobs/{id}/plan.svg"))
                .send()
                .await
                .unwrap(),
            404,
            "not_found",
        )
        .await;
        expect_error(
            s.delete(&format!("/v1/jobs/{id}")).send().await.unwrap(),
            404,
            "not_found",
        )
        .await;
    }
    // Dot segments are resolved by the client; whatever they resolve to, nothing is served.
    let res = s.get("/v1/jobs/../../../etc/passwd").send().await.unwrap();
    assert_eq!(res.status(), 404);
    let unknown = uuid_like();
    expect_error(
        s.get(&format!("/v1/jobs/{unknown}")).send().await.unwrap(),
        404,
        "not_found",
    )
    .await;
    expect_error(
        s.get("/v1/nope").send().await.unwrap(),
        404,
        "route_not_found",
    )
    .await;
    expect_error(
        s.client.put(s.url("/v1/jobs")).send().await.unwrap(),
        405,
        "method_not_allowed",
    )
    .await;
}

fn uuid_like() -> String {
    asbuilt::queue::JobId::new().to_string()
}

/// Hostile requests: bad UTF-8, absurd and huge values, deep JSON, oversized parts, traversal in
/// ids and names. Each gets a JSON error with a stable code; the job stored before is untouched.
#[tokio::test]
async fn hostile_requests_get_json_errors_and_lose_nothing() {
    let s = start(fake(1), |c| {
        c.workers = 1;
        c.max_upload_bytes = 1 << 20;
        c.max_sidecar_bytes = 4 << 10;
    })
    .await;
    let kept = s.upload(xyz(20)).await["id"].as_str().unwrap().to_string();
    let done = s.wait_done(&kept, Duration::from_secs(20)).await;
    assert_eq!(done["status"], "succeeded");
    let before: Vec<(std::path::PathBuf, Vec<u8>)> = files_under(&s.blobs())
        .into_iter()
        .map(|p| {
            let bytes = std::fs::read(&p).unwrap();
            (p, bytes)
        })
        .collect();
    assert_eq!(
        before.len(),
        1 + asbuilt_plan::io::outputs::OUTPUTS.len(),
        "the cloud and every result"
    );

    let huge = "9".repeat(30_000);
    let long = "x".repeat(30_000);
    // (query, expected param) on POST /v1/jobs with a good cloud.
    for (query, param) in [
        ("samples.cell_size=%FF%FE", "samples.cell_size"),
        ("%FF%FE=1", "\u{fffd}\u{fffd}"),
        (
            &format!("samples.cell_size={huge}") as &str,
            "samples.cell_size",
        ),
        (&format!("{long}=1"), ""),
        ("samples=1", "samples"),
        ("samples.cell_size.x=1", "samples.cell_size.x"),
        ("=1", ""),
    ] {
        let body = expect_error(
            s.post(&format!("/v1/jobs?{query}"))
                .body(xyz(3))
                .send()
                .await
                .unwrap(),
            422,
            "invalid_parameter",
        )
        .await;
        let got = body["error"]["param"].as_str().unwrap();
        if !param.is_empty() {
            assert_eq!(got, param, "{query}");
        }
        assert!(got.len() < 1000 && body["error"]["message"].as_str().unwrap().len() < 4000);
    }
    for (query, param) in [
        ("limit=99999999999999999999999", "limit"),
        ("limit=-1", "limit"),
        ("limit=1e3", "limit"),
        ("limit=NaN", "limit"),
        (&format!("status={long}") as &str, "status"),
        (&format!("cursor={long}"), "cursor"),
        ("cursor=%00", "cursor"),
        ("status=%FF", "status"),
    ] {
        let body = expect_error(
            s.get(&format!("/v1/jobs?{query}")).send().await.unwrap(),
            422,
            "invalid_parameter",
        )
        .await;
        assert_eq!(body["error"]["param"], param, "{query}");
        assert!(body.to_string().len() < 2000, "the answer stays small");
    }
    // Multipart parts: oversized, deeply nested, not UTF-8, not JSON.
    let nested = format!("{}1{}", "{\"samples\":".repeat(50_000), "}".repeat(50_000));
    for (part, bytes, status, code) in [
        ("params", vec![b' '; 5 << 10], 413, "payload_too_large"),
        (
            "params",
            nested.clone().into_bytes(),
            413,
            "payload_too_large",
        ),
        (
            "params",
            b"{\"samples\":{}}\xff".to_vec(),
            422,
            "invalid_parameter",
        ),
        (
            "params",
            b"[[[[[[[[[[[[[[[[[[[[".repeat(200),
            422,
            "invalid_parameter",
        ),
        ("poses", b"\xff\xfe{}".to_vec(), 422, "invalid_sidecar"),
        ("poses", vec![b'['; 4000], 422, "invalid_sidecar"),
        ("trajectory", vec![b' '; 5 << 10], 413, "payload_too_large"),
    ] {
        let form = reqwest::multipart::Form::new()
            .part("cloud", reqwest::multipart::Part::text(xyz(3)))
            .part(part, reqwest::multipart::Part::bytes(bytes));
        expect_error(
            s.post("/v1/jobs").multipart(form).send().await.unwrap(),
            status,
            code,
        )
        .await;
    }
    // A params part within the size limit but nested past the parser's depth limit.
    let deep = format!("{}1{}", "{\"a\":".repeat(600), "}".repeat(600));
    let form = reqwest::multipart::Form::new()
        .part("cloud", reqwest::multipart::Part::text(xyz(3)))
        .part("params", reqwest::multipart::Part::text(deep));
    expect_error(
        s.post("/v1/jobs").multipart(form).send().await.unwrap(),
        422,
        "invalid_parameter",
    )
    .await;
    // Bodies that are not clouds: bad UTF-8 text, NUL bytes, a JSON document.
    for body in [
        b"\xff\xfe\xfd 1 2 3\n".to_vec(),
        b"1 2 3\n\0\0\0\n".to_vec(),
        br#"{"type": "FeatureCollection"}"#.to_vec(),
    ] {
        expect_error(
            s.post("/v1/jobs").body(body).send().await.unwrap(),
            415,
            "unsupported_format",
        )
        .await;
    }
    // Traversal and junk in ids: never found, never a file.
    let long_id = "a".repeat(10_000);
    for id in [
        "%2e%2e%2f%2e%2e%2fasbuilt.db",
        "..%5C..%5Casbuilt.db",
        "%00",
        &long_id as &str,
        "0190c1d2-7a3b-7c00-8000-000000000000%00",
        &format!("{kept}%2F..%2F{kept}"),
    ] {
        for path in ["", "/plan.geojson", "/events"] {
            expect_error(
                s.get(&format!("/v1/jobs/{id}{path}")).send().await.unwrap(),
                404,
                "not_found",
            )
            .await;
        }
        expect_error(
            s.delete(&format!("/v1/jobs/{id}")).send().await.unwrap(),
            404,
            "not_found",
        )
        .await;
    }
    // A hostile display name is cut to its last segment, without control characters.
    let named = s
        .post(&format!(
            "/v1/jobs?filename=..%2F..%2Fetc%2Fpass%00wd%0A{}",
            "n".repeat(5000)
        ))
        .body(xyz(3))
        .send()
        .await
        .unwrap();
    assert_eq!(named.status(), 202);
    let named: Value = named.json().await.unwrap();
    let name = named["upload"]["filename"].as_str().unwrap();
    assert!(
        name.starts_with("passwd") && name.chars().count() == 200,
        "{name}"
    );
    s.wait_done(named["id"].as_str().unwrap(), Duration::from_secs(20))
        .await;

    // The job stored before is whole, its files unchanged, and the server still answers.
    let again = s.job(&kept).await;
    assert_eq!(again["status"], "succeeded");
    for (path, bytes) in &before {
        assert_eq!(&std::fs::read(path).unwrap(), bytes, "{}", path.display());
    }
    let plan = s
        .get(&format!("/v1/jobs/{kept}/plan.geojson"))
        .send()
        .await
        .unwrap();
    assert_eq!(plan.status(), 200);
    let list: Value = s
        .get("/v1/jobs")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(list["jobs"].as_array().unwrap().len(), 2, "{list}");
    assert_eq!(
        files_under(&s.blobs()).len(),
        2 * (1 + asbuilt_plan::io::outputs::OUTPUTS.len()),
        "two jobs' files, nothing else"
    );
}
