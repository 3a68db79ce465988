//! The service end to end, in process, with a synthetic pipeline (the real stages are tested in
//! `service_plan.rs`): uploads, limits, auth, listing, events, cancel, failures, leases,
//! retention, shutdown, metrics, OpenAPI and the page.

mod common;

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use asbuilt::errors::{CODES, JOB_CODES};
use asbuilt::queue::JobStatus;
use asbuilt::router::ROUTES;
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
        let outcome = r.as_ref().map(|_| ()).map_err(|e| e.code.clone());
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
        c.api_keys = vec!["acme:acme-secret-1".into(), "bolt:bolt-secret-2".into()]
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
    s.key = Some("bolt-secret-2".into());
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
    s.key = Some("acme-secret-1".into());
    assert_eq!(s.job(id).await["id"], id);
    // Health, metrics, the page and the document need no key.
    for path in [
        "/healthz",
        "/readyz",
        "/metrics",
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
        assert!(JOB_CODES.iter().any(|(k, _)| k == c), "{c} is documented");
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
    // Stop the live worker from racing the ghost: the ghost claims from the store directly,
    // before the job is even announced.
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
    let claimed = state.store.claim("ghost", 100).await.unwrap();
    if claimed.is_none() {
        // The live worker was quicker; nothing to test about leases this time.
        return;
    }
    state
        .blobs
        .put(&asbuilt::storage::keys::cloud(id), xyz(4).into())
        .await
        .unwrap();
    let done = s.wait_done(&id.to_string(), Duration::from_secs(10)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["attempts"], 2);
    assert_eq!(probe.ended.lock().unwrap().len(), 1);
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
    let mut routed: Vec<(String, String)> = ROUTES
        .iter()
        .map(|(m, p)| (m.to_string(), p.to_string()))
        .collect();
    documented.sort();
    routed.sort();
    assert_eq!(
        documented, routed,
        "every route documented, nothing documented that is not routed"
    );
    // Every listed route reaches a handler (not the fallbacks).
    let id = asbuilt::queue::JobId::new().to_string();
    for (method, path) in ROUTES {
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
        CODES.iter().map(|c| c.0.to_string()).collect::<Vec<_>>()
    );
    assert_eq!(
        enum_of("JobErrorCode"),
        JOB_CODES
            .iter()
            .map(|c| c.0.to_string())
            .collect::<Vec<_>>()
    );
    let statuses: Vec<String> = JobStatus::ALL
        .iter()
        .map(|s| s.as_str().to_string())
        .collect();
    assert_eq!(enum_of("Status"), statuses);
    // Each error status a code uses is answered by some operation.
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
