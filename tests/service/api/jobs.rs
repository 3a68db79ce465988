//! A job as a client sees it: upload, results, multipart, events, listing, cancel, tenants.

use std::time::{Duration, Instant};

use futures_util::StreamExt;
use serde_json::Value;
use sha2::{Digest, Sha256};

use super::{fake, probed};
use crate::support::files_under;
use crate::support::server::{expect_error, start, xyz};

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
    if let Some(v) = crate::support::server::ezdxf_summary(dxf.as_bytes()) {
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
    // Every output of the list is linked and served with its media type; the files that do
    // not carry timings are exactly what the writer makes of the fake plan.
    let links = done["links"].as_object().unwrap();
    assert_eq!(links.len(), 2 + asbuilt_plan::io::outputs::OUTPUTS.len());
    let plan = asbuilt::worker::fake::square_plan(42);
    for o in &asbuilt_plan::io::outputs::OUTPUTS {
        let link = links[o.name].as_str().unwrap();
        assert_eq!(link, format!("/v1/jobs/{id}/{}", o.file));
        let res = s.get(link).send().await.unwrap();
        assert_eq!(res.status(), 200, "{link}");
        assert_eq!(res.headers()["content-type"], o.media_type, "{link}");
        let body = res.bytes().await.unwrap();
        if matches!(o.name, "ifc" | "rooms") {
            assert_eq!(body, (o.write)(&plan).unwrap(), "{link}");
        }
    }
    let csv = s
        .get(&format!("/v1/jobs/{id}/rooms.csv"))
        .send()
        .await
        .unwrap();
    let csv = csv.text().await.unwrap();
    assert_eq!(csv.lines().count(), 3, "{csv}");
    assert!(csv.contains("\r\n0,L0-R1,7.35,"), "{csv}");
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
    // Three stories: the per-story stages run three times, each time with its story's number.
    let cloud = format!("#stories:3\n{}", xyz(5));
    let job = s.upload(cloud.clone()).await;
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
    // "Story k of n" from the server, rising to the last story.
    let numbers: Vec<u64> = jobs
        .iter()
        .filter_map(|j| j["story"]["number"].as_u64())
        .collect();
    assert!(numbers.windows(2).all(|w| w[0] <= w[1]), "{numbers:?}");
    assert_eq!(numbers.last(), Some(&3), "{text}");
    assert!(jobs
        .iter()
        .filter(|j| !j["story"].is_null())
        .all(|j| j["story"]["count"] == 3));
    // The bytes read, where seen, are of the upload; none once the job ended.
    for j in jobs.iter().filter(|j| !j["read"].is_null()) {
        assert_eq!(j["read"]["total"], cloud.len(), "{j}");
        assert!(j["read"]["bytes"].as_u64().unwrap() <= cloud.len() as u64);
    }
    let last = jobs.last().unwrap();
    assert!(last["read"].is_null() && last["story"].is_null(), "{last}");
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
    let results = asbuilt_plan::io::outputs::OUTPUTS
        .iter()
        .map(|o| format!("/{}", o.file));
    for path in ["".to_string(), "/events".to_string()]
        .into_iter()
        .chain(results)
    {
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
