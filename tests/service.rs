//! The service end to end, in process, with a synthetic pipeline (the real stages are tested in
//! `service_plan.rs`): uploads, limits, auth, listing, events, cancel, failures, leases,
//! retention, shutdown, metrics, OpenAPI and the page.

mod common;

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use asbuilt::errors::{CODES, JOB_CODES};
use asbuilt::queue::JobStatus;
use asbuilt::router::routes;
use asbuilt::worker::fake::FakePipeline;
use asbuilt::worker::pipeline::{JobInput, JobResults, Pipeline, PipelineFailure};
use asbuilt_plan::progress::Progress;
use common::{expect_error, files_under, start, xyz};
use futures_util::StreamExt;
use serde_json::Value;
use sha2::{Digest, Sha256};

fn fake(ms: u64) -> Arc<dyn Pipeline> {
    Arc::new(FakePipeline {
        stage_time: Duration::from_millis(ms),
        completions: None,
        spin: false,
    })
}

/// Wraps a pipeline and records when and how each run ended.
#[derive(Default)]
struct Probe {
    ended: Mutex<Vec<(Instant, Result<(), String>)>>,
}

struct Probed(Arc<Probe>, FakePipeline);

impl Pipeline for Probed {
    fn run(
        &self,
        input: &JobInput,
        progress: &mut dyn Progress,
    ) -> Result<JobResults, PipelineFailure> {
        let r = self.1.run(input, progress);
        let outcome = r
            .as_ref()
            .map(|_| ())
            .map_err(|e| e.code.as_str().to_string());
        self.0.ended.lock().unwrap().push((Instant::now(), outcome));
        r
    }
}

fn probed(ms: u64) -> (Arc<Probe>, Arc<dyn Pipeline>) {
    let probe = Arc::new(Probe::default());
    let p = Probed(
        probe.clone(),
        FakePipeline {
            stage_time: Duration::from_millis(ms),
            completions: None,
            spin: false,
        },
    );
    (probe, Arc::new(p))
}

#[tokio::test]
async fn upload_queue_work_and_fetch_results() {
    let s = start(fake(5), |_| {}).await;
    let cloud = xyz(42);
    let res = s
        .post("/v1/jobs?filename=../../room.xyz&samples.cell_size=0.1")
        .body(cloud.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 202);
    let location = res.headers()["location"].to_str().unwrap().to_string();
    let job: Value = res.json().await.unwrap();
    let id = job["id"].as_str().unwrap();
    assert_eq!(location, format!("/v1/jobs/{id}"));
    assert_eq!(job["status"], "queued");
    assert_eq!(job["upload"]["bytes"], cloud.len());
    let sha: String = Sha256::digest(cloud.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(job["upload"]["sha256"], sha);
    assert_eq!(job["upload"]["format"], "xyz");
    // A client's path never becomes a path here: only its last segment is kept, for display.
    assert_eq!(job["upload"]["filename"], "room.xyz");
    assert_eq!(job["parameters"]["samples"]["cell_size"], 0.1);

    let done = s.wait_done(id, Duration::from_secs(20)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["progress"], 1.0);
    assert_eq!(done["input"]["points"], 42);
    assert_eq!(done["attempts"], 1);
    let timings = done["timings_ms"].as_object().unwrap();
    assert_eq!(timings.keys().next().unwrap(), "read");
    assert_eq!(timings.keys().next_back().unwrap(), "total");
    assert!(done["finished_at"].as_str().unwrap() >= done["started_at"].as_str().unwrap());

    let res = s
        .get(done["links"]["geojson"].as_str().unwrap())
        .send()
        .await
        .unwrap();
    assert_eq!(res.headers()["content-type"], "application/geo+json");
    let doc: Value = res.json().await.unwrap();
    assert_eq!(doc["type"], "FeatureCollection");
    assert_eq!(doc["floorplan"]["version"], 1);
    let res = s
        .get(&format!("/v1/jobs/{id}/plan.svg"))
        .send()
        .await
        .unwrap();
    assert_eq!(res.headers()["content-type"], "image/svg+xml");
    assert!(res.text().await.unwrap().contains("<svg"));
    let dxf = s
        .get(&format!("/v1/jobs/{id}/plan.dxf"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(dxf.contains("AC1009") && dxf.contains("ARC") && dxf.ends_with("EOF\n"));
    // An independent reader opens the served file: R12, metres, a story layer and a walls
    // layer, the arc wall as a real ARC.
    if let Some(v) = common::ezdxf_summary(dxf.as_bytes()) {
        assert_eq!(v["version"], "AC1009", "{v}");
        assert_eq!(v["insunits"], 6, "metres: {v}");
        assert_eq!(v["errors"], 0, "{v}");
        for layer in ["STORY_0", "WALLS_0"] {
            assert!(
                v["layers"].as_array().unwrap().iter().any(|l| l == layer),
                "{v}"
            );
        }
        assert_eq!(v["counts"]["ARC@WALLS_0"], 1, "{v}");
        assert_eq!(v["arc_radii"][0], 0.5, "{v}");
        assert!(
            v["counts"]["POLYLINE@STORY_0"].as_u64().unwrap() >= 1,
            "{v}"
        );
    }
}

#[tokio::test]
async fn multipart_with_poses_and_params() {
    let s = start(fake(1), |_| {}).await;
    let form = reqwest::multipart::Form::new()
        .part(
            "cloud",
            reqwest::multipart::Part::text(xyz(10)).file_name("scan.xyz"),
        )
        .part("poses", reqwest::multipart::Part::text(r#"{"scans": []}"#))
        .part(
            "params",
            reqwest::multipart::Part::text(r#"{"fitting": {"circles": false}}"#),
        );
    let res = s
        .post("/v1/jobs?stories.min_wall_height=2.5")
        .multipart(form)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 202);
    let job: Value = res.json().await.unwrap();
    assert_eq!(job["upload"]["filename"], "scan.xyz");
    assert_eq!(job["upload"]["sidecar"], "poses");
    assert_eq!(job["parameters"]["fitting"]["circles"], false);
    assert_eq!(job["parameters"]["stories"]["min_wall_height"], 2.5);
    let id = job["id"].as_str().unwrap();
    assert!(s
        .blobs()
        .join(format!("jobs/{id}/input/sidecar.json"))
        .is_file());
    // The fake pipeline ignores sidecars; the real one attaches them (service_plan.rs).
    assert_eq!(
        s.wait_done(id, Duration::from_secs(20)).await["status"],
        "succeeded"
    );
}

#[tokio::test]
async fn events_stream_progress_until_done() {
    let s = start(fake(150), |_| {}).await;
    let job = s.upload(xyz(5)).await;
    let id = job["id"].as_str().unwrap();
    let res = s
        .get(&format!("/v1/jobs/{id}/events"))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    assert!(res.headers()["content-type"]
        .to_str()
        .unwrap()
        .starts_with("text/event-stream"));
    let mut text = String::new();
    let mut body = res.bytes_stream();
    let end = Instant::now() + Duration::from_secs(20);
    // The stream ends by itself after the terminal event.
    while let Some(chunk) = tokio::time::timeout_at(end.into(), body.next())
        .await
        .expect("stream did not end")
    {
        text.push_str(&String::from_utf8_lossy(&chunk.unwrap()));
    }
    let jobs: Vec<Value> = text
        .split("\n\n")
        .filter(|b| b.contains("event: job"))
        .map(|b| {
            let data: String = b.lines().filter_map(|l| l.strip_prefix("data: ")).collect();
            serde_json::from_str(&data).unwrap()
        })
        .collect();
    assert!(jobs.len() >= 3, "{text}");
    assert_eq!(jobs.last().unwrap()["status"], "succeeded");
    let stages: Vec<&str> = jobs.iter().filter_map(|j| j["stage"].as_str()).collect();
    assert!(stages.len() >= 2, "several stages seen: {stages:?}");
    let progress: Vec<f64> = jobs
        .iter()
        .map(|j| j["progress"].as_f64().unwrap())
        .collect();
    assert!(progress.windows(2).all(|w| w[0] <= w[1]), "{progress:?}");
}

#[tokio::test]
async fn lists_newest_first_with_cursor_and_status_filter() {
    let s = start(fake(1), |c| c.workers = 0).await;
    let mut ids = vec![];
    for _ in 0..5 {
        ids.push(s.upload(xyz(3)).await["id"].as_str().unwrap().to_string());
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
    ids.reverse();
    let mut seen = vec![];
    let mut cursor: Option<String> = None;
    let mut pages = 0;
    loop {
        let path = match &cursor {
            Some(c) => format!("/v1/jobs?limit=2&cursor={c}"),
            None => "/v1/jobs?limit=2".into(),
        };
        let page: Value = s.get(&path).send().await.unwrap().json().await.unwrap();
        pages += 1;
        seen.extend(
            page["jobs"]
                .as_array()
                .unwrap()
                .iter()
                .map(|j| j["id"].as_str().unwrap().to_string()),
        );
        match page["next_cursor"].as_str() {
            Some(c) => cursor = Some(c.to_string()),
            None => break,
        }
    }
    assert_eq!(pages, 3);
    assert_eq!(seen, ids);
    let queued: Value = s
        .get("/v1/jobs?status=queued")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(queued["jobs"].as_array().unwrap().len(), 5);
    let none: Value = s
        .get("/v1/jobs?status=succeeded")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(none["jobs"].as_array().unwrap().is_empty());
    for (q, param) in [
        ("limit=0", "limit"),
        ("limit=x", "limit"),
        ("status=done", "status"),
        ("cursor=..%2F", "cursor"),
        ("sort=asc", "sort"),
    ] {
        let body = expect_error(
            s.get(&format!("/v1/jobs?{q}")).send().await.unwrap(),
            422,
            "invalid_parameter",
        )
        .await;
        assert_eq!(body["error"]["param"], param);
    }
}

#[tokio::test]
async fn delete_cancels_a_running_job_within_two_seconds_and_removes_its_data() {
    let (probe, pipeline) = probed(3000);
    let s = start(pipeline, |c| c.workers = 1).await;
    let running = s.upload(xyz(3)).await["id"].as_str().unwrap().to_string();
    let queued = s.upload(xyz(3)).await["id"].as_str().unwrap().to_string();
    let end = Instant::now() + Duration::from_secs(10);
    while s.job(&running).await["status"] != "running" {
        assert!(Instant::now() < end);
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert_eq!(s.job(&queued).await["status"], "queued");
    let t0 = Instant::now();
    assert_eq!(
        s.delete(&format!("/v1/jobs/{running}"))
            .send()
            .await
            .unwrap()
            .status(),
        204
    );
    expect_error(
        s.get(&format!("/v1/jobs/{running}")).send().await.unwrap(),
        404,
        "not_found",
    )
    .await;
    assert_eq!(
        s.delete(&format!("/v1/jobs/{queued}"))
            .send()
            .await
            .unwrap()
            .status(),
        204
    );
    // The pipeline stops at its next progress check.
    let end = Instant::now() + Duration::from_secs(5);
    let stopped = loop {
        if let Some((at, outcome)) = probe.ended.lock().unwrap().first().cloned() {
            break (at, outcome);
        }
        assert!(Instant::now() < end, "pipeline still running");
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    assert!(
        stopped.0.duration_since(t0) < Duration::from_secs(2),
        "{:?}",
        stopped.0.duration_since(t0)
    );
    assert_eq!(stopped.1, Err("cancelled".to_string()));
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert!(
        files_under(&s.blobs()).is_empty(),
        "{:?}",
        files_under(&s.blobs())
    );
    // The queued job never ran, and a deleted job is gone for good.
    assert_eq!(probe.ended.lock().unwrap().len(), 1);
    expect_error(
        s.delete(&format!("/v1/jobs/{queued}"))
            .send()
            .await
            .unwrap(),
        404,
        "not_found",
    )
    .await;
}

#[tokio::test]
async fn api_keys_separate_tenants() {
    let mut s = start(fake(1), |c| {
        c.api_keys = vec![
            "acme:acme-secret-key-0001".into(),
            "bolt:bolt-secret-key-0002".into(),
        ]
    })
    .await;
    let job = s.upload(xyz(3)).await;
    let id = job["id"].as_str().unwrap();
    let anon = reqwest::Client::new();
    expect_error(
        anon.get(s.url("/v1/jobs")).send().await.unwrap(),
        401,
        "unauthorized",
    )
    .await;
    expect_error(
        anon.get(s.url("/v1/jobs"))
            .bearer_auth("wrong-key-123")
            .send()
            .await
            .unwrap(),
        401,
        "unauthorized",
    )
    .await;
    expect_error(
        anon.post(s.url("/v1/jobs"))
            .body(xyz(3))
            .send()
            .await
            .unwrap(),
        401,
        "unauthorized",
    )
    .await;
    s.key = Some("bolt-secret-key-0002".into());
    for path in ["", "/events", "/plan.geojson", "/plan.svg", "/plan.dxf"] {
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
    let list: Value = s
        .get("/v1/jobs")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(list["jobs"].as_array().unwrap().is_empty());
    s.key = Some("acme-secret-key-0001".into());
    assert_eq!(s.job(id).await["id"], id);
    // Health, the page and the document need no key; metrics, with keys configured, want
    // the metrics key, and a tenant's key is not it.
    for path in [
        "/healthz",
        "/readyz",
        "/openapi.json",
        "/",
        "/v1/parameters",
    ] {
        assert_eq!(
            anon.get(s.url(path)).send().await.unwrap().status(),
            200,
            "{path}"
        );
    }
    for key in [None, Some("acme-secret-key-0001")] {
        let mut req = anon.get(s.url("/metrics"));
        if let Some(k) = key {
            req = req.bearer_auth(k);
        }
        assert_eq!(req.send().await.unwrap().status(), 401, "{key:?}");
    }
    s.stop().await;
}

#[tokio::test]
async fn oversized_uploads_get_413_and_leave_nothing() {
    let s = start(fake(1), |c| c.max_upload_bytes = 10_000).await;
    // Declared too large: refused before reading.
    let res = s.post("/v1/jobs").body(xyz(2000)).send().await.unwrap();
    expect_error(res, 413, "payload_too_large").await;
    // Streamed without a length: refused when the limit is crossed, partial data removed.
    let chunks: Vec<Result<String, std::io::Error>> = (0..50).map(|_| Ok(xyz(20))).collect();
    let body = reqwest::Body::wrap_stream(futures_util::stream::iter(chunks));
    expect_error(
        s.post("/v1/jobs").body(body).send().await.unwrap(),
        413,
        "payload_too_large",
    )
    .await;
    let form =
        reqwest::multipart::Form::new().part("cloud", reqwest::multipart::Part::text(xyz(2000)));
    expect_error(
        s.post("/v1/jobs").multipart(form).send().await.unwrap(),
        413,
        "payload_too_large",
    )
    .await;
    assert!(
        files_under(&s.blobs()).is_empty(),
        "{:?}",
        files_under(&s.blobs())
    );
    let list: Value = s
        .get("/v1/jobs")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(list["jobs"].as_array().unwrap().is_empty());
    let metrics = s
        .get("/metrics")
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        metrics.contains("asbuilt_uploads_rejected_total{code=\"payload_too_large\"} 3"),
        "{metrics}"
    );
}

/// The two uploads the old screen judged unlike the reader (issue 14).
#[tokio::test]
async fn the_upload_screen_is_the_readers_detector() {
    let s = start(fake(1), |c| c.workers = 0).await;
    // The screen is the reader's own detector: text the reader cannot place is refused up
    // front, and a column-name header the reader skips is accepted.
    expect_error(
        s.post("/v1/jobs")
            .body("# a\n# b\n# c\n# d\n1 2 3\n")
            .send()
            .await
            .unwrap(),
        415,
        "unsupported_format",
    )
    .await;
    let named = s
        .post("/v1/jobs")
        .body(format!("x y z\n{}", xyz(3)))
        .send()
        .await
        .unwrap();
    assert_eq!(named.status(), 202);
    let job: Value = named.json().await.unwrap();
    assert_eq!(job["upload"]["format"], "xyz", "{job}");
}

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
    let form = reqwest::multipart::Form::new().part("poses", reqwest::multipart::Part::text("{}"));
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

#[tokio::test]
async fn failures_carry_codes() {
    let s = start(fake(200), |c| {
        c.max_points = 10;
        c.job_timeout_secs = 1;
    })
    .await;
    let fail = s.upload(format!("{}#fail:no_stories\n", xyz(3))).await;
    let panic = s.upload(format!("{}#panic\n", xyz(3))).await;
    let big = s.upload(xyz(11)).await;
    // Seven stages of 200 ms: past the 1 s limit.
    let slow = s.upload(xyz(3)).await;
    let mut codes = vec![];
    for j in [&fail, &panic, &big, &slow] {
        let done = s
            .wait_done(j["id"].as_str().unwrap(), Duration::from_secs(20))
            .await;
        assert_eq!(done["status"], "failed", "{done}");
        codes.push(done["error"]["code"].as_str().unwrap().to_string());
        assert!(!done["error"]["message"].as_str().unwrap().is_empty());
    }
    assert_eq!(
        codes,
        [
            "no_stories",
            "pipeline_panic",
            "too_many_points",
            "time_limit"
        ]
    );
    let res = s
        .get(&format!(
            "/v1/jobs/{}/plan.geojson",
            fail["id"].as_str().unwrap()
        ))
        .send()
        .await
        .unwrap();
    expect_error(res, 409, "result_not_ready").await;
    let metrics = s
        .get("/metrics")
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    for code in &codes {
        assert!(
            metrics.contains(&format!("asbuilt_job_failures_total{{code=\"{code}\"}} 1")),
            "{metrics}"
        );
    }
    assert!(
        metrics.contains("asbuilt_jobs{status=\"failed\"} 4"),
        "{metrics}"
    );
    for c in &codes {
        assert!(
            JOB_CODES.iter().any(|k| k.as_str() == c),
            "{c} is documented"
        );
    }
}

#[tokio::test]
async fn a_job_whose_worker_died_is_retried_then_fails_with_worker_lost() {
    let s = start(fake(1), |c| c.workers = 0).await;
    let state = s.running.as_ref().unwrap().state.clone();
    let retried = s.upload(xyz(3)).await["id"].as_str().unwrap().to_string();
    // A worker that claims the job and vanishes.
    let ghost = state.store.claim("ghost", 50).await.unwrap().unwrap();
    assert_eq!(ghost.id.to_string(), retried);
    let end = Instant::now() + Duration::from_secs(10);
    while s.job(&retried).await["status"] != "queued" {
        assert!(Instant::now() < end, "expired lease not requeued");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    // Every attempt lost: the job fails with a clear code.
    for _ in 0..3 {
        while let Some(j) = state.store.claim("ghost", 50).await.unwrap() {
            assert_eq!(j.id.to_string(), retried);
        }
        tokio::time::sleep(Duration::from_millis(1200)).await;
    }
    let job = s.job(&retried).await;
    assert_eq!(job["status"], "failed", "{job}");
    assert_eq!(job["error"]["code"], "worker_lost");
    assert_eq!(job["attempts"], 3);
}

#[tokio::test]
async fn a_requeued_job_runs_on_a_live_worker() {
    let (probe, pipeline) = probed(1);
    let s = start(pipeline, |c| c.workers = 1).await;
    let state = s.running.as_ref().unwrap().state.clone();
    // The ghost claims from the store directly, before the job is even announced; the live
    // worker may still poll in between and win. Then that job fails (it has no cloud) without
    // reaching the pipeline, and a new one is tried, so the test never passes untested.
    let mut ghosted = None;
    for _ in 0..50 {
        let id = asbuilt::queue::JobId::new();
        state
            .store
            .create(asbuilt::queue::NewJob {
                id,
                tenant: "dev".into(),
                params: asbuilt_plan::Params::default().to_json(),
                upload: Default::default(),
                max_attempts: 3,
            })
            .await
            .unwrap();
        if let Some(job) = state.store.claim("ghost", 100).await.unwrap() {
            assert_eq!(job.id, id);
            ghosted = Some(id);
            break;
        }
    }
    let id = ghosted.expect("the ghost won at least one of 50 claims");
    state
        .blobs
        .put(&asbuilt::storage::keys::cloud(id), xyz(4).into())
        .await
        .unwrap();
    let done = s.wait_done(&id.to_string(), Duration::from_secs(10)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["attempts"], 2);
    let ended = probe.ended.lock().unwrap();
    assert_eq!(ended.iter().filter(|(_, r)| r.is_ok()).count(), 1);
}

#[tokio::test]
async fn retention_deletes_finished_jobs_and_their_data() {
    let s = start(fake(1), |c| c.retention_hours = 0).await;
    let id = s.upload(xyz(3)).await["id"].as_str().unwrap().to_string();
    let end = Instant::now() + Duration::from_secs(15);
    loop {
        let res = s.get(&format!("/v1/jobs/{id}")).send().await.unwrap();
        if res.status() == 404 {
            break;
        }
        assert!(Instant::now() < end, "job not swept");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(
        files_under(&s.blobs()).is_empty(),
        "{:?}",
        files_under(&s.blobs())
    );
}

#[tokio::test]
async fn shutdown_timeout_hands_running_jobs_back() {
    let mut s = start(fake(5000), |c| {
        c.workers = 1;
        c.shutdown_timeout_secs = 0;
    })
    .await;
    let id = s.upload(xyz(3)).await["id"].as_str().unwrap().to_string();
    let end = Instant::now() + Duration::from_secs(10);
    while s.job(&id).await["status"] != "running" {
        assert!(Instant::now() < end);
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let state = s.running.as_ref().unwrap().state.clone();
    let t0 = Instant::now();
    s.stop().await;
    assert!(t0.elapsed() < Duration::from_secs(4), "{:?}", t0.elapsed());
    let job = state
        .store
        .get(None, id.parse().unwrap())
        .await
        .unwrap()
        .unwrap();
    assert_eq!(job.status, JobStatus::Queued);
    // Handing back does not spend an attempt.
    assert_eq!(job.attempts, 0);
}

#[tokio::test]
async fn metrics_count_uploads_jobs_and_stage_times() {
    let s = start(fake(1), |_| {}).await;
    let body = xyz(10);
    let id = s.upload(body.clone()).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    s.wait_done(&id, Duration::from_secs(20)).await;
    let res = s.get("/metrics").send().await.unwrap();
    assert!(res.headers()["content-type"]
        .to_str()
        .unwrap()
        .starts_with("text/plain"));
    let text = res.text().await.unwrap();
    assert!(text.contains("asbuilt_queue_depth 0\n"), "{text}");
    assert!(
        text.contains("asbuilt_jobs{status=\"succeeded\"} 1\n"),
        "{text}"
    );
    assert!(
        text.contains(&format!("asbuilt_upload_bytes_total {}\n", body.len())),
        "{text}"
    );
    assert!(
        text.contains("asbuilt_stage_duration_seconds_count{stage=\"total\"} 1\n"),
        "{text}"
    );
    assert!(
        text.contains("asbuilt_stage_duration_seconds_count{stage=\"label\"} 1\n"),
        "{text}"
    );
}

#[tokio::test]
async fn openapi_document_matches_the_file_routes_and_codes() {
    let s = start(fake(1), |c| c.workers = 0).await;
    let served: Value = s
        .get("/openapi.json")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let file =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/openapi/asbuilt.yaml"))
            .unwrap();
    let published: Value = serde_yaml::from_str(&file).unwrap();
    assert_eq!(
        served, published,
        "the served document is the published file"
    );
    let paths = served["paths"].as_object().unwrap();
    let mut documented = vec![];
    for (path, item) in paths {
        for method in ["get", "post", "put", "delete", "patch"] {
            if item.get(method).is_some() {
                documented.push((method.to_uppercase(), path.clone()));
            }
        }
    }
    let mut routed: Vec<(String, String)> = routes()
        .into_iter()
        .map(|(m, p)| (m.to_string(), p))
        .collect();
    documented.sort();
    routed.sort();
    assert_eq!(
        documented, routed,
        "every route documented, nothing documented that is not routed"
    );
    // Every listed route reaches a handler (not the fallbacks).
    let id = asbuilt::queue::JobId::new().to_string();
    for (method, path) in routes() {
        let url = s.url(&path.replace("{id}", &id));
        let res = s
            .client
            .request(method.parse().unwrap(), url)
            .send()
            .await
            .unwrap();
        let status = res.status();
        let body: Value = res.json().await.unwrap_or(Value::Null);
        let code = body["error"]["code"].as_str().unwrap_or_default();
        assert!(
            code != "route_not_found" && code != "method_not_allowed",
            "{method} {path}: {status} {code}"
        );
    }
    let enum_of = |name: &str| -> Vec<String> {
        served["components"]["schemas"][name]["enum"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap().to_string())
            .collect()
    };
    assert_eq!(
        enum_of("ErrorCode"),
        CODES
            .iter()
            .map(|c| c.as_str().to_string())
            .collect::<Vec<_>>()
    );
    assert_eq!(
        enum_of("JobErrorCode"),
        JOB_CODES
            .iter()
            .map(|c| c.as_str().to_string())
            .collect::<Vec<_>>()
    );
    let statuses: Vec<String> = JobStatus::ALL
        .iter()
        .map(|s| s.as_str().to_string())
        .collect();
    assert_eq!(enum_of("Status"), statuses);
    // Each error code's status is answered by some operation, whose response names the code;
    // and no operation documents an error status that no code has.
    let mut documented: std::collections::BTreeMap<String, Vec<String>> = Default::default();
    for item in paths.values() {
        for op in item.as_object().unwrap().values() {
            for (status, r) in op["responses"].as_object().into_iter().flatten() {
                let r = match r["$ref"].as_str() {
                    Some(name) => {
                        &served["components"]["responses"][name.rsplit('/').next().unwrap()]
                    }
                    None => r,
                };
                let text = r["description"].as_str().unwrap_or_default().to_string();
                documented.entry(status.clone()).or_default().push(text);
            }
        }
    }
    for code in CODES {
        let (code, status) = (&code.as_str(), code.status().as_u16());
        // Answered by the router or the HTTP framing, not by one operation.
        let outside = [
            "route_not_found",
            "method_not_allowed",
            "uri_too_long",
            "header_too_large",
        ];
        if outside.contains(code) {
            let intro = served["info"]["description"].as_str().unwrap();
            assert!(
                intro.contains(&format!("{status} {code}")),
                "{code} is described"
            );
            continue;
        }
        let texts = documented
            .get(&status.to_string())
            .unwrap_or_else(|| panic!("{status}"));
        assert!(
            texts.iter().any(|t| t.contains(&format!("`{code}`"))),
            "no {status} response names `{code}`"
        );
    }
    for status in documented.keys().filter(|s| s.as_str() >= "400") {
        assert!(
            CODES
                .iter()
                .any(|c| c.status().as_u16().to_string() == *status),
            "{status} is documented but no code has it"
        );
    }
    let job = s.upload(xyz(3)).await;
    let required: Vec<&str> = served["components"]["schemas"]["Job"]["required"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    let keys: Vec<&String> = job.as_object().unwrap().keys().collect();
    for field in &required {
        assert!(job.get(*field).is_some(), "Job lacks required {field}");
    }
    let props = served["components"]["schemas"]["Job"]["properties"]
        .as_object()
        .unwrap();
    for k in keys {
        assert!(props.contains_key(k), "Job field {k} undocumented");
    }
}

#[tokio::test]
async fn health_and_the_page() {
    let s = start(fake(1), |c| c.workers = 0).await;
    assert_eq!(s.get("/healthz").send().await.unwrap().status(), 200);
    let ready: Value = s.get("/readyz").send().await.unwrap().json().await.unwrap();
    assert_eq!(ready["status"], "ready");
    let res = s.get("/").send().await.unwrap();
    assert!(res.headers()["content-type"]
        .to_str()
        .unwrap()
        .starts_with("text/html"));
    let csp = res.headers()["content-security-policy"]
        .to_str()
        .unwrap()
        .to_string();
    assert!(csp.contains("default-src 'self'"));
    let page = res.text().await.unwrap();
    assert!(page.contains("Drop a point cloud here"));
    // No CDN, no external asset.
    for external in ["src=\"http", "href=\"http", "@import", "url(http"] {
        assert!(!page.contains(external), "{external}");
    }
    let defaults: Value = s
        .get("/v1/parameters")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(defaults["samples"]["cell_size"].as_f64().unwrap() > 0.0);
}

/// Sends a whole chunked upload before reading the answer, as simple clients (curl) do; an
/// error means the server closed on the client mid-send, losing its answer.
async fn post_all_then_read(
    addr: &str,
    key: Option<&str>,
    body: &[u8],
) -> std::io::Result<(u16, Value)> {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut tcp = tokio::net::TcpStream::connect(addr).await?;
    let auth = key
        .map(|k| format!("Authorization: Bearer {k}\r\n"))
        .unwrap_or_default();
    let head = format!(
        "POST /v1/jobs HTTP/1.1\r\nHost: test\r\n{auth}Transfer-Encoding: chunked\r\n\
         Connection: close\r\n\r\n"
    );
    tcp.write_all(head.as_bytes()).await?;
    for c in body.chunks(64 << 10) {
        tcp.write_all(format!("{:x}\r\n", c.len()).as_bytes())
            .await?;
        tcp.write_all(c).await?;
        tcp.write_all(b"\r\n").await?;
    }
    tcp.write_all(b"0\r\n\r\n").await?;
    let mut answer = Vec::new();
    tcp.read_to_end(&mut answer).await?;
    let text = String::from_utf8_lossy(&answer);
    let status = text.get(9..12).and_then(|s| s.parse().ok()).unwrap_or(0);
    let json = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
    Ok((status, serde_json::from_str(json).unwrap_or(Value::Null)))
}

/// A client still sending when the upload is refused reads the JSON error, not a reset
/// connection: the server reads and drops the rest for a bounded time. 32 MiB is well past what
/// loopback socket buffers absorb.
#[tokio::test]
async fn refused_uploads_are_answered_while_the_client_still_sends() {
    let s = start(fake(1), |c| {
        c.workers = 0;
        c.max_upload_bytes = 64 << 10;
        c.api_keys = vec!["acme:acme-secret-key-0001".into()];
    })
    .await;
    let addr = s.base.trim_start_matches("http://").to_string();
    let key = Some("acme-secret-key-0001");
    let cloud = b"1.5 2.5 3.5\n".repeat(3 << 20);
    let mut junk = vec![0u8; 32 << 20];
    junk[..4].copy_from_slice(b"\x89PNG");
    for (key, body, status, code) in [
        // Over the limit once 64 KiB have arrived.
        (key, &cloud[..], 413, "payload_too_large"),
        // Not a cloud: refused at the first kilobyte.
        (key, &junk[..], 415, "unsupported_format"),
        // No key: refused before a byte of the body is read.
        (None, &cloud[..], 401, "unauthorized"),
    ] {
        let (got, answer) = post_all_then_read(&addr, key, body)
            .await
            .unwrap_or_else(|e| panic!("{code}: the connection failed mid-upload: {e}"));
        assert_eq!(
            (got, answer["error"]["code"].as_str()),
            (status, Some(code))
        );
    }
    // Declared too large: refused before reading, and answered.
    expect_error(
        s.post("/v1/jobs").body(cloud.clone()).send().await.unwrap(),
        413,
        "payload_too_large",
    )
    .await;
    assert!(files_under(&s.blobs()).is_empty());
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
    assert_eq!(before.len(), 4, "cloud and three results");

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
        8,
        "two jobs' files, nothing else"
    );
}

/// Every kind of answer, from every route, matches the published document: the status is listed
/// for the operation, the media type too, and JSON bodies validate against their schemas
/// (jobs queued, running, succeeded and failed; pages; errors; events).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_answer_matches_the_document() {
    let s = start(fake(60), |c| {
        c.workers = 1;
        c.max_upload_bytes = 64 << 10;
        c.max_sidecar_bytes = 4 << 10;
        c.api_keys = vec![
            "acme:acme-secret-key-0001".into(),
            "bolt:bolt-secret-key-0002".into(),
        ];
        c.metrics_key = Some("metrics-key-00000000001".into());
    })
    .await;
    let mut contract = common::contract::Contract::load();
    let anon = reqwest::Client::new();
    // Sends a request, checks the answer against the document, returns status and body.
    async fn call(
        contract: &mut common::contract::Contract,
        method: &str,
        path: &str,
        req: reqwest::RequestBuilder,
    ) -> (u16, Vec<u8>) {
        let res = req.send().await.unwrap();
        let status = res.status().as_u16();
        let media = res
            .headers()
            .get("content-type")
            .map(|v| v.to_str().unwrap().to_string())
            .unwrap_or_default();
        if status == 202 {
            assert!(res.headers().contains_key("location"));
        }
        let body = res.bytes().await.unwrap().to_vec();
        contract.answer(method, path, status, &media, &body);
        (status, body)
    }
    let job_of = |body: &[u8]| -> String {
        let v: Value = serde_json::from_slice(body).unwrap();
        v["id"].as_str().unwrap().to_string()
    };

    for path in [
        "/",
        "/healthz",
        "/readyz",
        "/openapi.json",
        "/v1/parameters",
    ] {
        let (status, _) = call(&mut contract, "GET", path, anon.get(s.url(path))).await;
        assert_eq!(status, 200, "{path}");
    }
    let metrics = anon
        .get(s.url("/metrics"))
        .bearer_auth("metrics-key-00000000001");
    let (status, _) = call(&mut contract, "GET", "/metrics", metrics).await;
    assert_eq!(status, 200);
    let (status, _) = call(
        &mut contract,
        "GET",
        "/metrics",
        anon.get(s.url("/metrics")),
    )
    .await;
    assert_eq!(status, 401);
    // Uploads: accepted (raw and multipart) and each kind of refusal.
    let (status, body) = call(
        &mut contract,
        "POST",
        "/v1/jobs",
        s.post("/v1/jobs?filename=a.xyz").body(xyz(10)),
    )
    .await;
    assert_eq!(status, 202);
    let good = job_of(&body);
    let form = reqwest::multipart::Form::new()
        .part(
            "cloud",
            reqwest::multipart::Part::text(format!("{}#fail:no_stories\n", xyz(3))),
        )
        .part("poses", reqwest::multipart::Part::text("{}"));
    let (status, body) = call(
        &mut contract,
        "POST",
        "/v1/jobs",
        s.post("/v1/jobs").multipart(form),
    )
    .await;
    assert_eq!(status, 202);
    let failing = job_of(&body);
    let bad_form = || {
        reqwest::multipart::Form::new()
            .part("cloud", reqwest::multipart::Part::text(xyz(3)))
            .part("clouds", reqwest::multipart::Part::text(xyz(3)))
    };
    let big_params = || {
        reqwest::multipart::Form::new()
            .part("cloud", reqwest::multipart::Part::text(xyz(3)))
            .part(
                "params",
                reqwest::multipart::Part::text(" ".repeat(5 << 10)),
            )
    };
    let bad_poses = || {
        reqwest::multipart::Form::new()
            .part("cloud", reqwest::multipart::Part::text(xyz(3)))
            .part("poses", reqwest::multipart::Part::text("[]"))
    };
    for (req, expected) in [
        (s.post("/v1/jobs").multipart(bad_form()), 400),
        (anon.post(s.url("/v1/jobs")).body(xyz(3)), 401),
        (s.post("/v1/jobs").body(xyz(10_000)), 413),
        (s.post("/v1/jobs").multipart(big_params()), 413),
        (s.post("/v1/jobs").body(b"\x89PNG\r\n".to_vec()), 415),
        (s.post("/v1/jobs?samples.nope=1").body(xyz(3)), 422),
        (s.post("/v1/jobs").body(""), 422),
        (s.post("/v1/jobs").multipart(bad_poses()), 422),
    ] {
        let (status, _) = call(&mut contract, "POST", "/v1/jobs", req).await;
        assert_eq!(status, expected);
    }
    // Jobs in each state, as they pass.
    let mut seen = std::collections::BTreeSet::new();
    let end = Instant::now() + Duration::from_secs(20);
    while seen.len() < 3 || !seen.contains("succeeded") {
        for id in [&good, &failing] {
            let path = format!("/v1/jobs/{id}");
            let (_, body) = call(&mut contract, "GET", &path, s.get(&path)).await;
            let job: Value = serde_json::from_slice(&body).unwrap();
            seen.insert(job["status"].as_str().unwrap().to_string());
        }
        assert!(Instant::now() < end, "saw only {seen:?}");
        tokio::time::sleep(Duration::from_millis(15)).await;
    }
    let done = s.wait_done(&failing, Duration::from_secs(20)).await;
    assert_eq!(done["status"], "failed");
    contract.job(&done);
    // The schema is strict: an extra field, a failed job without its error, or a queued job
    // with result links does not pass.
    let job = "/components/schemas/Job";
    let mut extra = done.clone();
    extra["surprise"] = Value::Bool(true);
    let mut silent = done.clone();
    silent["error"] = Value::Null;
    let mut early = s.wait_done(&good, Duration::from_secs(20)).await;
    early["status"] = "queued".into();
    for wrong in [extra, silent, early] {
        assert!(!contract.accepts(job, &wrong), "{wrong}");
    }
    for q in [
        "",
        "?limit=1",
        "?status=failed",
        "?limit=0",
        "?status=nope",
        "?cursor=x",
    ] {
        let path = format!("/v1/jobs{q}");
        call(&mut contract, "GET", &path, s.get(&path)).await;
    }
    call(
        &mut contract,
        "GET",
        "/v1/jobs",
        anon.get(s.url("/v1/jobs")),
    )
    .await;
    // Results, and their refusals: not ready, other tenant, bad id, no key.
    let bolt = |p: &str| anon.get(s.url(p)).bearer_auth("bolt-secret-key-0002");
    for file in ["plan.geojson", "plan.svg", "plan.dxf"] {
        let ok = format!("/v1/jobs/{good}/{file}");
        let (status, _) = call(&mut contract, "GET", &ok, s.get(&ok)).await;
        assert_eq!(status, 200);
        let not_ready = format!("/v1/jobs/{failing}/{file}");
        assert_eq!(
            call(&mut contract, "GET", &not_ready, s.get(&not_ready))
                .await
                .0,
            409
        );
        assert_eq!(call(&mut contract, "GET", &ok, bolt(&ok)).await.0, 404);
        assert_eq!(
            call(&mut contract, "GET", &ok, anon.get(s.url(&ok)))
                .await
                .0,
            401
        );
        let bad = format!("/v1/jobs/nope/{file}");
        assert_eq!(call(&mut contract, "GET", &bad, s.get(&bad)).await.0, 404);
    }
    // Events: each `job` event's data is a Job.
    let events = format!("/v1/jobs/{good}/events");
    let (status, body) = call(&mut contract, "GET", &events, s.get(&events)).await;
    assert_eq!(status, 200);
    let text = String::from_utf8(body).unwrap();
    let mut n = 0;
    for block in text.split("\n\n").filter(|b| b.contains("event: job")) {
        let data: String = block
            .lines()
            .filter_map(|l| l.strip_prefix("data: "))
            .collect();
        contract.job(&serde_json::from_str(&data).unwrap());
        n += 1;
    }
    assert!(n >= 1, "{text}");
    assert_eq!(
        call(&mut contract, "GET", &events, bolt(&events)).await.0,
        404
    );
    // Delete, twice; the router's fallbacks.
    let path = format!("/v1/jobs/{good}");
    assert_eq!(
        call(&mut contract, "DELETE", &path, s.delete(&path))
            .await
            .0,
        204
    );
    assert_eq!(
        call(&mut contract, "DELETE", &path, s.delete(&path))
            .await
            .0,
        404
    );
    assert_eq!(
        call(&mut contract, "GET", "/v1/nope", s.get("/v1/nope"))
            .await
            .0,
        404
    );
    let put = s.client.put(s.url("/v1/jobs"));
    assert_eq!(call(&mut contract, "PUT", "/v1/jobs", put).await.0, 405);
}

/// Shutdown does not wait forever on a client that stalls mid-upload: open connections get
/// the shutdown timeout too, then are closed.
#[tokio::test]
async fn shutdown_does_not_wait_for_a_stalled_upload() {
    use tokio::io::AsyncWriteExt;
    let mut s = start(fake(1), |c| {
        c.workers = 1;
        c.shutdown_timeout_secs = 1;
    })
    .await;
    let addr = s.base.trim_start_matches("http://").to_string();
    let mut tcp = tokio::net::TcpStream::connect(&addr).await.unwrap();
    tcp.write_all(
        b"POST /v1/jobs HTTP/1.1\r\nHost: test\r\nContent-Length: 1000000\r\n\r\n1 2 3\n",
    )
    .await
    .unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    let t0 = Instant::now();
    tokio::time::timeout(Duration::from_secs(10), s.stop())
        .await
        .expect("shutdown hung on the stalled upload");
    assert!(t0.elapsed() < Duration::from_secs(4), "{:?}", t0.elapsed());
    assert!(
        files_under(&s.blobs()).is_empty(),
        "the partial upload was kept"
    );
    drop(tcp);
}
