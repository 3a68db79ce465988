//! Metrics, the OpenAPI document against the routes and every answer, health and the page.

use std::time::{Duration, Instant};

use asbuilt::errors::{CODES, JOB_CODES};
use asbuilt::queue::JobStatus;
use asbuilt::router::routes;
use serde_json::Value;

use super::fake;
use crate::support::server::{start, xyz};

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
        for method in ["get", "head", "post", "put", "delete", "patch"] {
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
    let mut contract = crate::support::contract::Contract::load();
    let anon = reqwest::Client::new();
    // Sends a request, checks the answer against the document, returns status and body.
    async fn call(
        contract: &mut crate::support::contract::Contract,
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
        .part("poses", reqwest::multipart::Part::text(r#"{"scans": []}"#));
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
    for file in asbuilt_plan::io::outputs::OUTPUTS.iter().map(|o| o.file) {
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
