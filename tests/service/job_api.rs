//! The integrator's job API (issue 16), end to end against a real server in process, on both
//! job stores: SQLite (embedded) and PostgreSQL (`ASBUILT_TEST_POSTGRES`; skipped without it,
//! a failure under CI). Blobs stay in a local directory. Every answer is also checked against
//! the published OpenAPI document.

use std::sync::Arc;
use std::time::{Duration, Instant};

use asbuilt::config::Config;
use asbuilt::worker::fake::FakePipeline;
use asbuilt::worker::pipeline::Pipeline;
use serde_json::Value;

use crate::support::contract::Contract;
use crate::support::engines::{engines, postgres_only, unique, Engines};

/// The S3 bucket the suites share (each test under a prefix of its own).
const SUITE_BUCKET: &str = "asbuilt-suite";
use crate::support::server::{self, expect_error, xyz, Server};

/// Where a case's server keeps its jobs.
struct Env {
    backend: &'static str,
    pg: Option<(Engines, String)>,
    /// Blobs in S3 (moto in tests) under this prefix of the `asbuilt-suite` bucket.
    s3: Option<String>,
}

impl Env {
    fn sqlite() -> Env {
        Env {
            backend: "sqlite",
            pg: None,
            s3: None,
        }
    }

    /// PostgreSQL and S3 (`ASBUILT_TEST_S3_ENDPOINT` too); skipped without them.
    async fn postgres_s3(test: &str) -> Option<Env> {
        let engines = engines(test)?;
        engines.ensure_bucket(SUITE_BUCKET).await;
        let schema = engines.new_schema("jobapi").await;
        Some(Env {
            backend: "postgres+s3",
            pg: Some((engines, schema)),
            s3: Some(unique("jobapi")),
        })
    }

    /// Every blob the server keeps: files under its directory, or objects under its prefix.
    async fn blobs(&self, s: &Server) -> Vec<String> {
        let (Some(prefix), Some((engines, _))) = (&self.s3, &self.pg) else {
            return crate::support::files_under(&s.blobs())
                .into_iter()
                .map(|p| p.display().to_string())
                .collect();
        };
        use futures_util::TryStreamExt;
        use object_store::ObjectStore;
        let store = object_store::aws::AmazonS3Builder::new()
            .with_endpoint(&engines.s3_endpoint)
            .with_allow_http(true)
            .with_region("us-east-1")
            .with_access_key_id("asbuilt-test")
            .with_secret_access_key("asbuilt-test")
            .with_bucket_name(SUITE_BUCKET)
            .build()
            .unwrap();
        let prefix = object_store::path::Path::from(prefix.as_str());
        store
            .list(Some(&prefix))
            .map_ok(|m| m.location.to_string())
            .try_collect()
            .await
            .unwrap()
    }

    async fn postgres(test: &str) -> Option<Env> {
        let engines = postgres_only(test)?;
        let schema = engines.new_schema("jobapi").await;
        Some(Env {
            backend: "postgres",
            pg: Some((engines, schema)),
            s3: None,
        })
    }

    /// A server on this backend with the fake pipeline taking `ms` per stage.
    async fn start(&self, ms: u64, tweak: impl FnOnce(&mut Config)) -> Server {
        self.start_with(fake(ms), tweak).await
    }

    async fn start_with(
        &self,
        pipeline: Arc<dyn Pipeline>,
        tweak: impl FnOnce(&mut Config),
    ) -> Server {
        let url = self.pg.as_ref().map(|(e, s)| e.url_in(s));
        if let Some(url) = &url {
            // A shared database is migrated by `asbuilt migrate`, not by the server.
            let c = Config {
                database_url: Some(url.clone()),
                ..Config::default()
            };
            asbuilt::app::open_store(&c).await.unwrap();
        }
        let s3 = self.pg.as_ref().map(|(e, _)| e.s3_options());
        let storage = self.s3.clone();
        server::start(pipeline, |c| {
            c.database_url = url;
            if let (Some(prefix), Some(o)) = (storage, s3) {
                c.storage = Some(format!("s3://{SUITE_BUCKET}/{prefix}"));
                c.s3_endpoint = o.endpoint;
                c.s3_region = o.region;
                c.s3_access_key_id = o.access_key_id;
                c.s3_secret_access_key = o.secret_access_key;
                c.s3_allow_http = true;
            }
            tweak(c);
        })
        .await
    }

    async fn finish(self) {
        if let Some((e, schema)) = &self.pg {
            e.drop_schema(schema).await;
        }
    }
}

fn fake(ms: u64) -> Arc<dyn Pipeline> {
    Arc::new(FakePipeline {
        stage_time: Duration::from_millis(ms),
        completions: None,
        spin: false,
    })
}

macro_rules! on_both_backends {
    ($($name:ident),* $(,)?) => {
        mod sqlite {
            $(#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn $name() {
                let env = super::Env::sqlite();
                super::$name(&env).await;
                env.finish().await;
            })*
        }
        mod postgres {
            $(#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn $name() {
                let Some(env) = super::Env::postgres(stringify!($name)).await else {
                    return;
                };
                super::$name(&env).await;
                env.finish().await;
            })*
        }
    };
}

on_both_backends!(
    cancel_stops_the_job_and_keeps_it_readable,
    expired_jobs_answer_410_and_unknown_ones_404,
    idempotency_keys_return_the_first_job,
    metadata_is_kept_shown_and_filtered,
    replans_reuse_the_upload_and_share_it_safely,
    webhooks_are_signed_retried_and_recorded,
    results_revalidate_and_serve_ranges_and_other_origins,
    events_resume_after_the_last_event_id,
    sidecars_are_checked_before_the_cloud_is_kept,
    resumable_uploads_resume_after_a_drop_and_expire,
    georeferences_are_checked_stored_and_used,
    direct_uploads_answer_that_they_need_s3,
);

/// The sidecar checks again with blobs in S3, where a refused cloud is an object to remove.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sidecars_are_checked_before_the_cloud_is_kept_in_s3() {
    let Some(env) = Env::postgres_s3("sidecars_are_checked_before_the_cloud_is_kept_in_s3").await
    else {
        return;
    };
    sidecars_are_checked_before_the_cloud_is_kept(&env).await;
    env.finish().await;
}

/// Resumable uploads with blobs in S3, where each PATCH is an object of its own.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn resumable_uploads_resume_after_a_drop_and_expire_in_s3() {
    let test = "resumable_uploads_resume_after_a_drop_and_expire_in_s3";
    let Some(env) = Env::postgres_s3(test).await else {
        return;
    };
    resumable_uploads_resume_after_a_drop_and_expire(&env).await;
    env.finish().await;
}

/// Every example in the document matches its schema, and every operation of the job API has
/// an example of its request (where it takes one) and of its successful answer.
#[test]
fn the_documents_examples_are_valid() {
    let mut contract = Contract::load();
    let n = contract.check_examples();
    assert!(n >= 20, "{n} examples");
    let doc: Value = serde_yaml::from_str(asbuilt::openapi::YAML).unwrap();
    for (path, method, status) in [
        ("/v1/jobs", "post", "202"),
        ("/v1/jobs", "post", "200"),
        ("/v1/jobs/{id}/replan", "post", "202"),
        ("/v1/jobs/{id}/cancel", "post", "200"),
    ] {
        let op = &doc["paths"][path][method];
        let content = &op["responses"][status]["content"]["application/json"];
        assert!(
            content.get("example").is_some() || content.get("examples").is_some(),
            "{method} {path} {status} has no example"
        );
        for (media, c) in op["requestBody"]["content"]
            .as_object()
            .into_iter()
            .flatten()
        {
            assert!(
                c.get("example").is_some(),
                "{method} {path}: {media} has no example"
            );
        }
    }
}

/// Sends a request, checks the answer against the document; its status, headers and body.
async fn call(
    contract: &mut Contract,
    method: &str,
    path: &str,
    req: reqwest::RequestBuilder,
) -> (u16, reqwest::header::HeaderMap, Vec<u8>) {
    let res = req.send().await.unwrap();
    let status = res.status().as_u16();
    let headers = res.headers().clone();
    let media = headers
        .get("content-type")
        .map(|v| v.to_str().unwrap().to_string())
        .unwrap_or_default();
    let body = res.bytes().await.unwrap().to_vec();
    contract.answer(method, path, status, &media, &body);
    (status, headers, body)
}

fn json(body: &[u8]) -> Value {
    serde_json::from_slice(body).unwrap()
}

/// Polls the job until `pred` holds.
async fn wait_for(s: &Server, id: &str, what: &str, pred: impl Fn(&Value) -> bool) -> Value {
    let end = Instant::now() + Duration::from_secs(20);
    loop {
        let job = s.job(id).await;
        if pred(&job) {
            return job;
        }
        assert!(Instant::now() < end, "{what}: job is {job}");
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
}

async fn cancel_stops_the_job_and_keeps_it_readable(env: &Env) {
    let mut s = env.start(400, |c| c.workers = 1).await;
    let mut contract = Contract::load();
    let running = s.upload(xyz(5)).await["id"].as_str().unwrap().to_string();
    let queued = s.upload(xyz(5)).await["id"].as_str().unwrap().to_string();
    wait_for(&s, &running, "running", |j| j["status"] == "running").await;

    let path = format!("/v1/jobs/{running}/cancel");
    let t0 = Instant::now();
    let (status, _, body) = call(&mut contract, "POST", &path, s.post(&path)).await;
    assert_eq!(status, 200, "{}", env.backend);
    let job = json(&body);
    assert_eq!(job["status"], "cancelled");
    assert!(job["finished_at"].is_string());
    // Still readable, still listed, and the worker moves on to the queued job.
    assert_eq!(s.job(&running).await["status"], "cancelled");
    let list: Value = s
        .get("/v1/jobs")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(list["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .any(|j| j["id"] == running.as_str()));
    let next = wait_for(&s, &queued, "the next job starts", |j| {
        j["status"] != "queued"
    })
    .await;
    assert!(
        t0.elapsed() < Duration::from_secs(3),
        "the worker was not freed: {:?}, {next}",
        t0.elapsed()
    );
    // Cancelling again answers the same job; its results never appear.
    let (status, _, body) = call(&mut contract, "POST", &path, s.post(&path)).await;
    assert_eq!(
        (status, json(&body)["status"].clone()),
        (200, "cancelled".into())
    );
    let geojson = format!("/v1/jobs/{running}/plan.geojson");
    expect_error(
        s.get(&geojson).send().await.unwrap(),
        409,
        "result_not_ready",
    )
    .await;
    // A queued job is cancelled before it ever runs.
    let third = s.upload(xyz(5)).await["id"].as_str().unwrap().to_string();
    let p3 = format!("/v1/jobs/{third}/cancel");
    let (status, _, body) = call(&mut contract, "POST", &p3, s.post(&p3)).await;
    assert_eq!((status, json(&body)["attempts"].clone()), (200, 0.into()));
    // A finished job cannot be cancelled: 409, and it stays succeeded.
    let done = s.wait_done(&queued, Duration::from_secs(20)).await;
    assert_eq!(done["status"], "succeeded");
    let p2 = format!("/v1/jobs/{queued}/cancel");
    let (status, _, body) = call(&mut contract, "POST", &p2, s.post(&p2)).await;
    assert_eq!(status, 409);
    assert_eq!(json(&body)["error"]["code"], "job_finished");
    assert_eq!(s.job(&queued).await["status"], "succeeded");
    // Unknown ids are 404, and DELETE still removes a cancelled job.
    let nope = format!("/v1/jobs/{}/cancel", asbuilt::queue::JobId::new());
    assert_eq!(
        call(&mut contract, "POST", &nope, s.post(&nope)).await.0,
        404
    );
    let del = s
        .delete(&format!("/v1/jobs/{running}"))
        .send()
        .await
        .unwrap();
    assert_eq!(del.status(), 204);
    expect_error(
        s.get(&format!("/v1/jobs/{running}")).send().await.unwrap(),
        404,
        "not_found",
    )
    .await;
    s.stop().await;
}

/// RFC 3339 to Unix milliseconds.
fn ms(t: &Value) -> i64 {
    chrono::DateTime::parse_from_rfc3339(t.as_str().expect("a time"))
        .unwrap()
        .timestamp_millis()
}

async fn expired_jobs_answer_410_and_unknown_ones_404(env: &Env) {
    let mut contract = Contract::load();
    // A week's retention: `expires_at` is null while the job runs, then a week after its end.
    let mut s = env.start(1, |_| {}).await;
    let job = s.upload(xyz(5)).await;
    assert!(job["expires_at"].is_null(), "{job}");
    let id = job["id"].as_str().unwrap().to_string();
    let done = s.wait_done(&id, Duration::from_secs(20)).await;
    assert_eq!(
        ms(&done["expires_at"]) - ms(&done["finished_at"]),
        168 * 3_600_000,
        "{}",
        env.backend
    );
    contract.job(&done);
    let list: Value = s
        .get("/v1/jobs")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(list["jobs"][0]["expires_at"], done["expires_at"]);
    s.stop().await;

    // No retention: the sweeper removes a finished job at once, leaving a tombstone.
    let mut s = env
        .start(1, |c| {
            c.retention_hours = 0;
            c.api_keys = vec![
                "acme:acme-secret-key-0001".into(),
                "bolt:bolt-secret-key-0002".into(),
            ];
        })
        .await;
    let id = s.upload(xyz(5)).await["id"].as_str().unwrap().to_string();
    let end = Instant::now() + Duration::from_secs(20);
    let gone = loop {
        let path = format!("/v1/jobs/{id}");
        let (status, _, body) = call(&mut contract, "GET", &path, s.get(&path)).await;
        if status == 410 {
            break json(&body);
        }
        assert!(status == 200 && Instant::now() < end, "{status}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    assert_eq!(gone["error"]["code"], "expired");
    assert!(gone["error"]["message"]
        .as_str()
        .unwrap()
        .contains("retention"));
    // Every per-job call says the same; its blobs are gone.
    for (method, path) in [
        ("GET", format!("/v1/jobs/{id}/plan.geojson")),
        ("GET", format!("/v1/jobs/{id}/events")),
        ("POST", format!("/v1/jobs/{id}/cancel")),
        ("DELETE", format!("/v1/jobs/{id}")),
    ] {
        let req = match method {
            "GET" => s.get(&path),
            "POST" => s.post(&path),
            _ => s.delete(&path),
        };
        let (status, _, body) = call(&mut contract, method, &path, req).await;
        assert_eq!(
            (status, json(&body)["error"]["code"].clone()),
            (410, "expired".into()),
            "{method} {path}"
        );
    }
    assert!(crate::support::files_under(&s.blobs()).is_empty());
    // A job that never existed is still 404.
    let never = format!("/v1/jobs/{}", asbuilt::queue::JobId::new());
    let (status, _, body) = call(&mut contract, "GET", &never, s.get(&never)).await;
    assert_eq!(
        (status, json(&body)["error"]["code"].clone()),
        (404, "not_found".into())
    );
    // Another tenant never learns that the job existed: a tombstone is the tenant's own.
    let bolt = s
        .client
        .get(s.url(&format!("/v1/jobs/{id}")))
        .bearer_auth("bolt-secret-key-0002");
    let (status, _, _) = call(&mut contract, "GET", &format!("/v1/jobs/{id}"), bolt).await;
    assert_eq!(status, 404);
    s.stop().await;
}

/// Every job row the tenant can list (up to 100).
async fn listed(s: &Server, query: &str) -> Vec<Value> {
    let res = s
        .get(&format!("/v1/jobs?limit=100{query}"))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200, "{query}");
    let page: Value = res.json().await.unwrap();
    page["jobs"].as_array().unwrap().clone()
}

async fn idempotency_keys_return_the_first_job(env: &Env) {
    let mut s = env
        .start(1, |c| {
            c.max_queued = 2;
            c.workers = 0;
        })
        .await;
    let mut contract = Contract::load();
    let path = "/v1/jobs?samples.cell_size=0.1";
    let send = |key: &str, body: String| {
        s.post(path)
            .header("Idempotency-Key", key.to_string())
            .body(body)
    };
    let (status, headers, body) = call(&mut contract, "POST", path, send("order-7", xyz(9))).await;
    assert_eq!(status, 202, "{}", env.backend);
    let first = json(&body);
    assert!(headers.get("idempotent-replayed").is_none());
    // The retry answers the first job: 200, the same id, nothing new stored or listed.
    let (status, headers, body) = call(&mut contract, "POST", path, send("order-7", xyz(9))).await;
    assert_eq!(status, 200);
    assert_eq!(headers["idempotent-replayed"], "true");
    assert_eq!(
        headers["location"],
        format!("/v1/jobs/{}", first["id"].as_str().unwrap())
    );
    assert_eq!(json(&body)["id"], first["id"]);
    assert_eq!(listed(&s, "").await.len(), 1);
    let blobs = crate::support::files_under(&s.blobs());
    assert_eq!(blobs.len(), 1, "{blobs:?}");
    // The same key with another cloud, or other parameters: 422, nothing stored.
    let (status, _, body) = call(&mut contract, "POST", path, send("order-7", xyz(10))).await;
    assert_eq!(
        (status, json(&body)["error"]["code"].clone()),
        (422, "idempotency_key_reused".into())
    );
    let other = "/v1/jobs?samples.cell_size=0.2";
    let req = s
        .post(other)
        .header("Idempotency-Key", "order-7")
        .body(xyz(9));
    let (status, _, body) = call(&mut contract, "POST", other, req).await;
    assert_eq!(
        (status, json(&body)["error"]["code"].clone()),
        (422, "idempotency_key_reused".into())
    );
    assert_eq!(crate::support::files_under(&s.blobs()).len(), 1);
    // Keys are per key holder; a new key is a new job; a retry is answered even at the cap.
    let (status, _, _) = call(&mut contract, "POST", path, send("order-8", xyz(9))).await;
    assert_eq!(status, 202);
    let (status, _, body) = call(&mut contract, "POST", path, send("order-9", xyz(9))).await;
    assert_eq!(
        (status, json(&body)["error"]["code"].clone()),
        (429, "queue_full".into())
    );
    let (status, _, _) = call(&mut contract, "POST", path, send("order-7", xyz(9))).await;
    assert_eq!(status, 200, "a retry is not a new job");
    // Concurrent retries of one new key make one job.
    let jobs_before = listed(&s, "").await.len();
    s.stop().await;
    let mut s = env.start(1, |c| c.workers = 0).await;
    // On PostgreSQL the first server's jobs are still in the database.
    let existing = listed(&s, "").await.len();
    let tries: Vec<_> = (0..6)
        .map(|_| {
            let req = s
                .post("/v1/jobs")
                .header("Idempotency-Key", "burst-1")
                .body(xyz(20));
            tokio::spawn(async move {
                let res = req.send().await.unwrap();
                let status = res.status().as_u16();
                (status, res.json::<Value>().await.unwrap()["id"].clone())
            })
        })
        .collect();
    let mut ids = std::collections::BTreeSet::new();
    let mut created = 0;
    for t in tries {
        let (status, id) = t.await.unwrap();
        assert!(status == 200 || status == 202, "{status}");
        created += usize::from(status == 202);
        ids.insert(id.as_str().unwrap().to_string());
    }
    assert_eq!((created, ids.len()), (1, 1), "{}", env.backend);
    assert_eq!(listed(&s, "").await.len(), existing + 1);
    assert_eq!(crate::support::files_under(&s.blobs()).len(), 1);
    assert!(jobs_before == 2);
    // Bad keys are refused before the upload.
    for bad in ["", &"k".repeat(256), "naïve"] {
        let req = s
            .post("/v1/jobs")
            .header("Idempotency-Key", bad)
            .body(xyz(3));
        let res = req.send().await.unwrap();
        let body = expect_error(res, 422, "invalid_parameter").await;
        assert_eq!(body["error"]["param"], "Idempotency-Key");
    }
    s.stop().await;
}

async fn metadata_is_kept_shown_and_filtered(env: &Env) {
    let mut s = env.start(1, |_| {}).await;
    let mut contract = Contract::load();
    let path = "/v1/jobs?external_ref=building-42%2Flevel-3&tag=fm&tag=north-wing&tag=fm";
    let (status, _, body) = call(&mut contract, "POST", path, s.post(path).body(xyz(5))).await;
    assert_eq!(status, 202, "{}", env.backend);
    let job = json(&body);
    assert_eq!(job["external_ref"], "building-42/level-3");
    assert_eq!(job["tags"], serde_json::json!(["fm", "north-wing"]));
    let id = job["id"].as_str().unwrap().to_string();
    // Multipart: the metadata is in the query string too.
    let form =
        reqwest::multipart::Form::new().part("cloud", reqwest::multipart::Part::text(xyz(5)));
    let m = "/v1/jobs?external_ref=building-7&tag=fm";
    let (status, _, body) = call(&mut contract, "POST", m, s.post(m).multipart(form)).await;
    assert_eq!(status, 202);
    let other = json(&body)["id"].as_str().unwrap().to_string();
    s.upload(xyz(5)).await;
    // Every read shows it: the job, the list, the events.
    let done = s.wait_done(&id, Duration::from_secs(20)).await;
    assert_eq!(
        (done["external_ref"].clone(), done["tags"].clone()),
        (job["external_ref"].clone(), job["tags"].clone())
    );
    let events = s
        .get(&format!("/v1/jobs/{id}/events"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        events.contains("\"external_ref\":\"building-42/level-3\""),
        "{events}"
    );
    // Filters: by reference, by one tag, by every tag asked, and both.
    let ids = |jobs: Vec<Value>| -> Vec<String> {
        jobs.iter()
            .map(|j| j["id"].as_str().unwrap().to_string())
            .collect()
    };
    assert_eq!(listed(&s, "").await.len(), 3);
    assert_eq!(
        ids(listed(&s, "&external_ref=building-42%2Flevel-3").await),
        vec![id.clone()]
    );
    assert_eq!(
        ids(listed(&s, "&tag=fm").await),
        vec![other.clone(), id.clone()]
    );
    assert_eq!(
        ids(listed(&s, "&tag=fm&tag=north-wing").await),
        vec![id.clone()]
    );
    assert_eq!(
        ids(listed(&s, "&tag=north-wing&external_ref=building-7").await),
        Vec::<String>::new()
    );
    assert!(listed(&s, "&tag=nope").await.is_empty());
    let q = "/v1/jobs?tag=fm&external_ref=building-7";
    let (status, _, body) = call(&mut contract, "GET", q, s.get(q)).await;
    assert_eq!(status, 200);
    assert_eq!(
        ids(json(&body)["jobs"].as_array().unwrap().clone()),
        vec![other]
    );
    // Hostile values: refused with 422 naming the field, before anything is stored.
    let many: String = (0..21).map(|i| format!("&tag=t{i}")).collect();
    let long_ref = format!("&external_ref={}", "r".repeat(201));
    let long_tag = format!("&tag={}", "t".repeat(65));
    for (query, param) in [
        (many.as_str(), "tag"),
        (long_ref.as_str(), "external_ref"),
        (long_tag.as_str(), "tag"),
        ("&tag=a%20b", "tag"),
        ("&tag=", "tag"),
        ("&external_ref=a%0Ab", "external_ref"),
        ("&external_ref=a&external_ref=b", "external_ref"),
    ] {
        let path = format!("/v1/jobs?x=1{query}").replace("?x=1&", "?");
        let (status, _, body) =
            call(&mut contract, "POST", &path, s.post(&path).body(xyz(3))).await;
        assert_eq!(status, 422, "{query}");
        assert_eq!(json(&body)["error"]["param"], param, "{query}");
        if param != "external_ref" || !query.contains("&external_ref=b") {
            let list = format!("/v1/jobs?x=1{query}").replace("?x=1&", "?");
            let (status, _, _) = call(&mut contract, "GET", &list, s.get(&list)).await;
            assert_eq!(status, 422, "list {query}");
        }
    }
    assert_eq!(listed(&s, "").await.len(), 3);
    s.stop().await;
}

async fn replans_reuse_the_upload_and_share_it_safely(env: &Env) {
    let mut s = env.start(1, |_| {}).await;
    let mut contract = Contract::load();
    let form = reqwest::multipart::Form::new()
        .part("cloud", reqwest::multipart::Part::text(xyz(12)))
        .part("poses", reqwest::multipart::Part::text("{\"scans\": []}"));
    let res = s
        .post("/v1/jobs?samples.cell_size=0.1&tag=first")
        .multipart(form)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 202);
    let first: Value = res.json().await.unwrap();
    let a = first["id"].as_str().unwrap().to_string();
    s.wait_done(&a, Duration::from_secs(20)).await;
    let stored = crate::support::files_under(&s.blobs()).len();

    // Other parameters, the same upload: no cloud is sent, none is stored.
    let path = format!("/v1/jobs/{a}/replan?fitting.iterations=50&tag=second");
    let (status, headers, body) = call(&mut contract, "POST", &path, s.post(&path)).await;
    assert_eq!(
        status,
        202,
        "{}: {}",
        env.backend,
        String::from_utf8_lossy(&body)
    );
    let b_job = json(&body);
    let b = b_job["id"].as_str().unwrap().to_string();
    assert_eq!(headers["location"], format!("/v1/jobs/{b}"));
    assert_eq!(b_job["source_job"], a.as_str());
    assert_eq!(
        b_job["upload"], first["upload"],
        "the same upload, sidecar included"
    );
    assert_eq!(
        b_job["parameters"]["samples"]["cell_size"], 0.1,
        "inherited"
    );
    assert_eq!(
        b_job["parameters"]["fitting"]["iterations"], 50,
        "overridden"
    );
    assert_eq!(b_job["tags"], serde_json::json!(["second"]));
    let done_b = s.wait_done(&b, Duration::from_secs(20)).await;
    assert_eq!(done_b["status"], "succeeded", "{done_b}");
    assert_eq!(
        done_b["input"]["points"], 12,
        "it read the first job's cloud"
    );
    assert!(first["source_job"].is_null());

    // Other poses and a params part, re-planning the re-plan: still the first upload.
    let form = reqwest::multipart::Form::new()
        .part(
            "trajectory",
            reqwest::multipart::Part::text(
                "{\"samples\": [{\"t\": 0, \"position\": [1, 1, 1], \"quaternion\": [1, 0, 0, 0]}]}",
            ),
        )
        .part(
            "params",
            reqwest::multipart::Part::text("{\"samples\": {\"cell_size\": 0.2}}"),
        );
    let path = format!("/v1/jobs/{b}/replan");
    let (status, _, body) = call(&mut contract, "POST", &path, s.post(&path).multipart(form)).await;
    assert_eq!(status, 202, "{}", String::from_utf8_lossy(&body));
    let c_job = json(&body);
    let c = c_job["id"].as_str().unwrap().to_string();
    assert_eq!(c_job["source_job"], a.as_str());
    assert_eq!(c_job["upload"]["sidecar"], "trajectory");
    assert_eq!(c_job["parameters"]["samples"]["cell_size"], 0.2);
    assert_eq!(
        c_job["parameters"]["fitting"]["iterations"],
        Value::from(asbuilt_plan::Params::default().fitting.iterations)
    );
    assert_eq!(
        s.wait_done(&c, Duration::from_secs(20)).await["status"],
        "succeeded"
    );

    // Deleting the first job keeps the upload the others read; the last one takes it along.
    assert_eq!(
        s.delete(&format!("/v1/jobs/{a}"))
            .send()
            .await
            .unwrap()
            .status(),
        204
    );
    let cloud = s.blobs().join(format!("jobs/{a}/input/cloud"));
    assert!(
        cloud.is_file(),
        "the shared upload was deleted with its first job"
    );
    let again = format!("/v1/jobs/{b}/replan");
    let (status, _, body) = call(&mut contract, "POST", &again, s.post(&again)).await;
    assert_eq!(status, 202);
    let d = json(&body)["id"].as_str().unwrap().to_string();
    let done_d = s.wait_done(&d, Duration::from_secs(20)).await;
    assert_eq!(
        (done_d["status"].clone(), done_d["input"]["points"].clone()),
        ("succeeded".into(), 12.into())
    );
    for id in [&b, &c] {
        assert_eq!(
            s.delete(&format!("/v1/jobs/{id}"))
                .send()
                .await
                .unwrap()
                .status(),
            204
        );
        assert!(cloud.is_file());
    }
    assert_eq!(
        s.delete(&format!("/v1/jobs/{d}"))
            .send()
            .await
            .unwrap()
            .status(),
        204
    );
    let left = crate::support::files_under(&s.blobs());
    assert!(
        left.is_empty(),
        "{left:?} (a first upload stored {stored} files)"
    );

    // Refusals: a cloud part, a body, an unknown job, a filename.
    let e = s.upload(xyz(4)).await["id"].as_str().unwrap().to_string();
    let path = format!("/v1/jobs/{e}/replan");
    let form =
        reqwest::multipart::Form::new().part("cloud", reqwest::multipart::Part::text(xyz(4)));
    let (status, _, body) = call(&mut contract, "POST", &path, s.post(&path).multipart(form)).await;
    assert_eq!(
        (status, json(&body)["error"]["code"].clone()),
        (400, "invalid_multipart".into())
    );
    let (status, _, _) = call(&mut contract, "POST", &path, s.post(&path).body(xyz(4))).await;
    assert_eq!(status, 400);
    let bad = format!("{path}?samples.cell_size=9");
    let (status, _, body) = call(&mut contract, "POST", &bad, s.post(&bad)).await;
    assert_eq!(
        (status, json(&body)["error"]["param"].clone()),
        (422, "samples.cell_size".into())
    );
    let nope = format!("/v1/jobs/{}/replan", asbuilt::queue::JobId::new());
    assert_eq!(
        call(&mut contract, "POST", &nope, s.post(&nope)).await.0,
        404
    );
    // Idempotency holds for re-plans too.
    let keyed = |k: &str| s.post(&path).header("Idempotency-Key", k.to_string());
    let (status, _, body) = call(&mut contract, "POST", &path, keyed("rp-1")).await;
    assert_eq!(status, 202);
    let (status, _, again) = call(&mut contract, "POST", &path, keyed("rp-1")).await;
    assert_eq!(
        (status, json(&again)["id"].clone()),
        (200, json(&body)["id"].clone())
    );
    s.stop().await;
}

/// A webhook receiver: records every request; `/fail-once/...` answers 500 to its first
/// request, `/down/...` always 503, anything else 204.
struct Receiver {
    base: String,
    got: Arc<std::sync::Mutex<Vec<Received>>>,
}

#[derive(Clone, Debug)]
struct Received {
    path: String,
    headers: axum::http::HeaderMap,
    body: bytes::Bytes,
}

impl Receiver {
    async fn start() -> Receiver {
        use axum::http::StatusCode;
        let got: Arc<std::sync::Mutex<Vec<Received>>> = Default::default();
        let keep = got.clone();
        let app = axum::Router::new().fallback(
            move |uri: axum::http::Uri, headers: axum::http::HeaderMap, body: bytes::Bytes| {
                let keep = keep.clone();
                async move {
                    let path = uri.path().to_string();
                    let mut all = keep.lock().unwrap();
                    let before = all.iter().filter(|r| r.path == path).count();
                    all.push(Received {
                        path: path.clone(),
                        headers,
                        body,
                    });
                    if path.starts_with("/down/") {
                        StatusCode::SERVICE_UNAVAILABLE
                    } else if path.starts_with("/fail-once/") && before == 0 {
                        StatusCode::INTERNAL_SERVER_ERROR
                    } else {
                        StatusCode::NO_CONTENT
                    }
                }
            },
        );
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let base = format!("http://{}", listener.local_addr().unwrap());
        tokio::spawn(async move { axum::serve(listener, app).await.unwrap() });
        Receiver { base, got }
    }

    fn at(&self, path: &str) -> Vec<Received> {
        self.got
            .lock()
            .unwrap()
            .iter()
            .filter(|r| r.path == path)
            .cloned()
            .collect()
    }

    async fn wait(&self, path: &str, n: usize) -> Vec<Received> {
        let end = Instant::now() + Duration::from_secs(20);
        loop {
            let got = self.at(path);
            if got.len() >= n {
                return got;
            }
            assert!(
                Instant::now() < end,
                "{path}: {} of {n} requests",
                got.len()
            );
            tokio::time::sleep(Duration::from_millis(25)).await;
        }
    }
}

const SECRET: &str = "whsec-acme-0123456789";

/// Checks a delivery's signature with Python's `hmac` (an implementation independent of the
/// server's), and that it is fresh; returns the body as JSON.
fn verify(r: &Received) -> Value {
    let header = r.headers["asbuilt-signature"].to_str().unwrap().to_string();
    let (t, v1) = header
        .split_once(',')
        .and_then(|(t, v)| Some((t.strip_prefix("t=")?, v.strip_prefix("v1=")?)))
        .unwrap_or_else(|| panic!("signature header {header}"));
    let t: i64 = t.parse().unwrap();
    assert!(
        (chrono::Utc::now().timestamp() - t).abs() < 120,
        "stale t={t}"
    );
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("body");
    std::fs::write(&file, &r.body).unwrap();
    let script = "import hmac, hashlib, sys\n\
        body = open(sys.argv[3], 'rb').read()\n\
        mac = hmac.new(sys.argv[1].encode(), sys.argv[2].encode() + b'.' + body, hashlib.sha256)\n\
        print(mac.hexdigest())";
    let out = std::process::Command::new("python3")
        .args(["-c", script, SECRET, &t.to_string()])
        .arg(&file)
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let expected = String::from_utf8(out.stdout).unwrap().trim().to_string();
    assert_eq!(v1, expected, "the signature does not verify");
    // A tampered body does not verify: the check can fail.
    let mut forged = r.body.to_vec();
    forged.push(b' ');
    assert_ne!(asbuilt::webhooks::sign::digest(SECRET, t, &forged), v1);
    assert_eq!(r.headers["content-type"], "application/json");
    serde_json::from_slice(&r.body).unwrap()
}

async fn webhooks_are_signed_retried_and_recorded(env: &Env) {
    let rx = Receiver::start().await;
    let mut s = env
        .start(1, |c| {
            c.api_keys = vec![
                "acme:acme-secret-key-0001".into(),
                "bolt:bolt-secret-key-0002".into(),
            ];
            c.webhook_secrets = vec![format!("acme:{SECRET}")];
            c.webhook_urls = vec![format!("acme:{}/default/hook", rx.base)];
            c.webhook_allow = vec!["127.0.0.1/32".into()];
            c.webhook_backoff_ms = 150;
            c.webhook_attempts = 3;
        })
        .await;
    let mut contract = Contract::load();
    let cb = |path: &str| {
        format!("{}{path}", rx.base)
            .replace(':', "%3A")
            .replace('/', "%2F")
    };

    // Succeeded, after one failed attempt: two signed POSTs, both recorded.
    let path = format!("/v1/jobs?callback_url={}", cb("/fail-once/a"));
    let (status, _, body) = call(&mut contract, "POST", &path, s.post(&path).body(xyz(5))).await;
    assert_eq!(
        status,
        202,
        "{}: {}",
        env.backend,
        String::from_utf8_lossy(&body)
    );
    let job = json(&body);
    assert_eq!(job["callback_url"], format!("{}/fail-once/a", rx.base));
    let id = job["id"].as_str().unwrap().to_string();
    let got = rx.wait("/fail-once/a", 2).await;
    for r in &got {
        let event = verify(r);
        assert_eq!(event["event"], "job.succeeded");
        assert_eq!(event["job"]["id"], id.as_str());
        assert_eq!(event["job"]["status"], "succeeded");
        contract.job(&event["job"]);
        assert_eq!(r.headers["asbuilt-event"], "job.succeeded");
        assert_eq!(r.headers["asbuilt-job"], id.as_str());
    }
    let dpath = format!("/v1/jobs/{id}/deliveries");
    let end = Instant::now() + Duration::from_secs(10);
    let deliveries = loop {
        let (status, _, body) = call(&mut contract, "GET", &dpath, s.get(&dpath)).await;
        assert_eq!(status, 200);
        let d = json(&body);
        if d["deliveries"].as_array().unwrap().len() == 2 {
            break d;
        }
        assert!(Instant::now() < end, "{d}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    let list = deliveries["deliveries"].as_array().unwrap();
    assert_eq!(
        (list[0]["attempt"].clone(), list[0]["status"].clone()),
        (1.into(), 500.into())
    );
    assert!(list[0]["error"].as_str().unwrap().contains("500"));
    assert_eq!(
        (list[1]["attempt"].clone(), list[1]["status"].clone()),
        (2.into(), 204.into())
    );
    assert!(list[1]["error"].is_null());
    let gap = ms(&list[1]["at"]) - ms(&list[0]["at"]);
    assert!(gap >= 150, "the retry waited {gap} ms");

    // Failed and cancelled jobs are delivered too; the tenant's default URL applies.
    let path = format!("/v1/jobs?callback_url={}", cb("/ok/failed"));
    let failing = s
        .post(&path)
        .body(format!("{}#fail:no_stories\n", xyz(3)))
        .send()
        .await
        .unwrap();
    assert_eq!(failing.status(), 202);
    let event = verify(&rx.wait("/ok/failed", 1).await[0]);
    assert_eq!(
        (
            event["event"].clone(),
            event["job"]["error"]["code"].clone()
        ),
        ("job.failed".into(), "no_stories".into())
    );
    let mut slow = s.post("/v1/jobs").body(xyz(3));
    slow = slow.query(&[("tag", "slow")]);
    let queued: Value = slow.send().await.unwrap().json().await.unwrap();
    assert_eq!(queued["callback_url"], format!("{}/default/hook", rx.base));
    let qid = queued["id"].as_str().unwrap();
    let cancel = s
        .post(&format!("/v1/jobs/{qid}/cancel"))
        .send()
        .await
        .unwrap();
    let cancelled: Value = cancel.json().await.unwrap();
    // Cancelled, or finished first (the fake pipeline is quick): either way, one event.
    let event = verify(&rx.wait("/default/hook", 1).await[0]);
    assert_eq!(event["job"]["id"], qid);
    let expected = if cancelled["status"] == "cancelled" {
        "job.cancelled"
    } else {
        "job.succeeded"
    };
    assert_eq!(event["event"], expected, "{cancelled}");

    // A receiver that stays down gets `webhook_attempts` attempts, then no more.
    let path = format!("/v1/jobs?callback_url={}", cb("/down/x"));
    let down: Value = s
        .post(&path)
        .body(xyz(3))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    rx.wait("/down/x", 3).await;
    tokio::time::sleep(Duration::from_millis(1500)).await;
    assert_eq!(rx.at("/down/x").len(), 3);
    let dpath = format!("/v1/jobs/{}/deliveries", down["id"].as_str().unwrap());
    let d: Value = s.get(&dpath).send().await.unwrap().json().await.unwrap();
    let statuses: Vec<Value> = d["deliveries"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x["status"].clone())
        .collect();
    assert_eq!(statuses, vec![Value::from(503); 3]);

    // Refused before anything is stored: targets off the allow-list, other schemes, and a
    // tenant with no secret to sign with.
    for (url, why) in [
        ("http://10.0.0.1/hook", "allow-list"),
        ("http://127.0.0.2:9/hook", "allow-list"),
        ("ftp://127.0.0.1/hook", "http"),
        ("not a url", "URL"),
    ] {
        let path = format!(
            "/v1/jobs?callback_url={}",
            url.replace(':', "%3A")
                .replace('/', "%2F")
                .replace(' ', "%20")
        );
        let (status, _, body) =
            call(&mut contract, "POST", &path, s.post(&path).body(xyz(3))).await;
        let e = json(&body);
        assert_eq!(
            (status, e["error"]["param"].clone()),
            (422, "callback_url".into()),
            "{url}: {e}"
        );
        assert!(
            e["error"]["message"].as_str().unwrap().contains(why),
            "{url}: {e}"
        );
    }
    let path = format!("/v1/jobs?callback_url={}", cb("/ok/bolt"));
    let bolt = s
        .client
        .post(s.url(&path))
        .bearer_auth("bolt-secret-key-0002")
        .body(xyz(3));
    let (status, _, body) = call(&mut contract, "POST", &path, bolt).await;
    assert_eq!(status, 422);
    assert!(json(&body)["error"]["message"]
        .as_str()
        .unwrap()
        .contains("secret"));
    s.stop().await;

    // By default only public addresses may be called back: loopback is refused.
    let mut s = env
        .start(1, |c| c.webhook_secrets = vec![format!("dev:{SECRET}")])
        .await;
    let path = format!("/v1/jobs?callback_url={}", cb("/ok/default-deny"));
    let res = s.post(&path).body(xyz(3)).send().await.unwrap();
    let e = expect_error(res, 422, "invalid_parameter").await;
    assert_eq!(e["error"]["param"], "callback_url");
    s.stop().await;
}

async fn results_revalidate_and_serve_ranges_and_other_origins(env: &Env) {
    let mut s = env
        .start(1, |c| {
            c.cors_origins = vec!["https://portal.example.com".into()]
        })
        .await;
    let mut contract = Contract::load();
    let id = s.upload(xyz(8)).await["id"].as_str().unwrap().to_string();
    s.wait_done(&id, Duration::from_secs(20)).await;
    let path = format!("/v1/jobs/{id}/plan.svg");
    let (status, headers, whole) = call(&mut contract, "GET", &path, s.get(&path)).await;
    assert_eq!(status, 200, "{}", env.backend);
    assert_eq!(headers["accept-ranges"], "bytes");
    let tag = headers["etag"].to_str().unwrap().to_string();
    assert!(
        tag.starts_with('"') && tag.ends_with('"') && tag.len() > 10,
        "{tag}"
    );
    let n = whole.len();
    assert!(n > 100, "{n}");
    // The tag is the file's: the other results have others, and it does not change.
    let dxf = s
        .get(&format!("/v1/jobs/{id}/plan.dxf"))
        .send()
        .await
        .unwrap();
    assert_ne!(dxf.headers()["etag"].to_str().unwrap(), tag);
    let again = s.get(&path).send().await.unwrap();
    assert_eq!(again.headers()["etag"].to_str().unwrap(), tag);
    // Revalidation: 304 without a body; another tag gets the file.
    let (status, headers, body) = call(
        &mut contract,
        "GET",
        &path,
        s.get(&path).header("If-None-Match", &tag),
    )
    .await;
    assert_eq!((status, body.len()), (304, 0));
    assert_eq!(headers["etag"].to_str().unwrap(), tag);
    let list = format!("\"nope\", {tag}");
    assert_eq!(
        s.get(&path)
            .header("If-None-Match", list)
            .send()
            .await
            .unwrap()
            .status(),
        304
    );
    let stale = s
        .get(&path)
        .header("If-None-Match", "\"nope\"")
        .send()
        .await
        .unwrap();
    assert_eq!(stale.status(), 200);
    // Ranges: the bytes asked for, exactly.
    for (range, first, last) in [
        ("bytes=0-9".to_string(), 0, 9),
        (format!("bytes={}-", n - 7), n - 7, n - 1),
        ("bytes=-5".to_string(), n - 5, n - 1),
        (format!("bytes=10-{}", n + 100), 10, n - 1),
    ] {
        let (status, headers, body) = call(
            &mut contract,
            "GET",
            &path,
            s.get(&path).header("Range", &range),
        )
        .await;
        assert_eq!(status, 206, "{range}");
        assert_eq!(body, whole[first..=last].to_vec(), "{range}");
        assert_eq!(
            headers["content-range"],
            format!("bytes {first}-{last}/{n}"),
            "{range}"
        );
        assert_eq!(headers["content-length"], (last - first + 1).to_string());
    }
    let past = format!("bytes={n}-");
    let (status, headers, body) = call(
        &mut contract,
        "GET",
        &path,
        s.get(&path).header("Range", &past),
    )
    .await;
    assert_eq!(
        (status, json(&body)["error"]["code"].clone()),
        (416, "range_not_satisfiable".into())
    );
    assert_eq!(headers["content-range"], format!("bytes */{n}"));
    // A stale If-Range gets the whole file; a current one the part.
    let r = s
        .get(&path)
        .header("Range", "bytes=0-9")
        .header("If-Range", "\"old\"");
    assert_eq!(r.send().await.unwrap().status(), 200);
    let r = s
        .get(&path)
        .header("Range", "bytes=0-9")
        .header("If-Range", &tag);
    assert_eq!(r.send().await.unwrap().status(), 206);
    // Several ranges are not served as such: the whole file.
    let r = s
        .get(&path)
        .header("Range", "bytes=0-1,4-5")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);

    // gzip for clients that accept it: the same bytes once inflated (by Python's gzip), another
    // tag, and both tags revalidate. Ranges and event streams are never compressed.
    let geo = format!("/v1/jobs/{id}/plan.geojson");
    let plain = s.get(&geo).send().await.unwrap();
    assert!(plain.headers().get("content-encoding").is_none());
    let plain_tag = plain.headers()["etag"].to_str().unwrap().to_string();
    let plain = plain.bytes().await.unwrap();
    // (Not through the contract check: the body is gzip, not JSON, until inflated.)
    let res = s
        .get(&geo)
        .header("Accept-Encoding", "gzip")
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    let headers = res.headers().clone();
    let zipped = res.bytes().await.unwrap();
    assert_eq!(headers["content-encoding"], "gzip");
    assert!(headers["vary"]
        .to_str()
        .unwrap()
        .to_ascii_lowercase()
        .contains("accept-encoding"));
    let zipped_tag = headers["etag"].to_str().unwrap().to_string();
    assert_eq!(
        zipped_tag,
        format!("{}-gzip\"", plain_tag.trim_end_matches('"'))
    );
    assert_eq!(&zipped[..2], b"\x1f\x8b", "a gzip stream");
    assert!(
        zipped.len() < plain.len(),
        "{} vs {}",
        zipped.len(),
        plain.len()
    );
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("z"), &zipped).unwrap();
    let out = std::process::Command::new("python3")
        .args(["-c", "import gzip, sys; sys.stdout.buffer.write(gzip.decompress(open(sys.argv[1], 'rb').read()))"])
        .arg(dir.path().join("z"))
        .output()
        .unwrap();
    assert!(out.status.success());
    assert_eq!(out.stdout, plain.to_vec(), "inflated, the same bytes");
    for tag in [&plain_tag, &zipped_tag] {
        let r = s
            .get(&geo)
            .header("Accept-Encoding", "gzip")
            .header("If-None-Match", tag.as_str());
        assert_eq!(r.send().await.unwrap().status(), 304, "{tag}");
    }
    let r = s
        .get(&geo)
        .header("Accept-Encoding", "gzip")
        .header("Range", "bytes=0-9");
    let r = r.send().await.unwrap();
    assert_eq!(r.status(), 206);
    assert!(r.headers().get("content-encoding").is_none());
    let events = format!("/v1/jobs/{id}/events");
    let r = s
        .get(&events)
        .header("Accept-Encoding", "gzip")
        .send()
        .await
        .unwrap();
    assert!(r.headers().get("content-encoding").is_none());

    // CORS: a listed origin's preflight and request are allowed, others are not.
    let preflight = s
        .client
        .request(reqwest::Method::OPTIONS, s.url("/v1/jobs"))
        .header("Origin", "https://portal.example.com")
        .header("Access-Control-Request-Method", "POST")
        .header(
            "Access-Control-Request-Headers",
            "authorization, idempotency-key",
        )
        .send()
        .await
        .unwrap();
    assert!(preflight.status().is_success(), "{}", preflight.status());
    let h = preflight.headers();
    assert_eq!(
        h["access-control-allow-origin"],
        "https://portal.example.com"
    );
    let allowed = h["access-control-allow-headers"]
        .to_str()
        .unwrap()
        .to_ascii_lowercase();
    assert!(
        allowed.contains("idempotency-key") && allowed.contains("authorization"),
        "{allowed}"
    );
    let res = s
        .get(&path)
        .header("Origin", "https://portal.example.com")
        .send()
        .await
        .unwrap();
    assert_eq!(
        res.headers()["access-control-allow-origin"],
        "https://portal.example.com"
    );
    let exposed = res.headers()["access-control-expose-headers"]
        .to_str()
        .unwrap()
        .to_ascii_lowercase();
    assert!(
        exposed.contains("etag") && exposed.contains("location"),
        "{exposed}"
    );
    let res = s
        .get(&path)
        .header("Origin", "https://evil.example.net")
        .send()
        .await
        .unwrap();
    assert!(res.headers().get("access-control-allow-origin").is_none());
    s.stop().await;
    // Without --cors-origin, no CORS headers at all.
    let mut s = env.start(1, |_| {}).await;
    let res = s
        .get("/v1/jobs")
        .header("Origin", "https://portal.example.com")
        .send()
        .await
        .unwrap();
    assert!(res.headers().get("access-control-allow-origin").is_none());
    s.stop().await;
}

/// The `id:` and `data:` of each `job` event in an event stream's text.
fn sse_events(text: &str) -> Vec<(String, Value)> {
    text.split("\n\n")
        .filter(|b| b.contains("event: job"))
        .map(|b| {
            let id = b
                .lines()
                .find_map(|l| l.strip_prefix("id: "))
                .unwrap_or_default();
            let data: String = b.lines().filter_map(|l| l.strip_prefix("data: ")).collect();
            (id.to_string(), serde_json::from_str(&data).unwrap())
        })
        .collect()
}

async fn events_resume_after_the_last_event_id(env: &Env) {
    let mut s = env.start(100, |_| {}).await;
    let mut contract = Contract::load();
    let id = s.upload(xyz(8)).await["id"].as_str().unwrap().to_string();
    let path = format!("/v1/jobs/{id}/events");
    let (status, _, body) = call(&mut contract, "GET", &path, s.get(&path)).await;
    assert_eq!(status, 200, "{}", env.backend);
    let events = sse_events(&String::from_utf8(body).unwrap());
    assert!(events.len() >= 2, "{events:?}");
    let ids: Vec<&str> = events.iter().map(|(i, _)| i.as_str()).collect();
    assert!(
        ids.iter().all(|i| !i.is_empty()),
        "every job event has an id: {ids:?}"
    );
    let unique: std::collections::BTreeSet<&&str> = ids.iter().collect();
    assert_eq!(unique.len(), ids.len(), "ids name distinct states: {ids:?}");
    let (last_id, last) = events.last().unwrap();
    assert_eq!(last["status"], "succeeded");
    // Reconnecting after the final state: 204, nothing to resend.
    let (status, _, body) = call(
        &mut contract,
        "GET",
        &path,
        s.get(&path).header("Last-Event-ID", last_id),
    )
    .await;
    assert_eq!((status, body.len()), (204, 0));
    // Reconnecting after an earlier state: the current state, not the one already seen.
    let (status, _, body) = call(
        &mut contract,
        "GET",
        &path,
        s.get(&path).header("Last-Event-ID", &events[0].0),
    )
    .await;
    assert_eq!(status, 200);
    let resumed = sse_events(&String::from_utf8(body).unwrap());
    assert_eq!(resumed.len(), 1, "{resumed:?}");
    assert_eq!(&resumed[0].0, last_id);
    s.stop().await;
}

/// A multipart form of named text parts, in the order given.
fn form(parts: &[(&str, String)]) -> reqwest::multipart::Form {
    parts
        .iter()
        .fold(reqwest::multipart::Form::new(), |f, (n, v)| {
            f.part(n.to_string(), reqwest::multipart::Part::text(v.clone()))
        })
}

/// A bad sidecar is refused with 422 naming the entry at fault, before the cloud is stored
/// when it comes first, and with the cloud's blob removed when it came first. An E57 sent with
/// a sidecar is refused as `docs/contract.md` §2 says (it carries its own poses), on create and
/// on re-plan, in either order of the parts.
async fn sidecars_are_checked_before_the_cloud_is_kept(env: &Env) {
    // Clouds over this many bytes are refused with 413 once read: a 422 for a bigger cloud
    // sent after a bad sidecar shows the cloud was never read.
    let mut s = env.start(1, |c| c.max_upload_bytes = 4_000).await;
    let mut contract = Contract::load();
    let bad_quaternion =
        r#"{"scans": [{"index": 0, "position": [0, 0, 1], "quaternion": [2, 0, 0, 0]}]}"#;
    let good_poses =
        r#"{"scans": [{"index": 0, "position": [0, 0, 1], "quaternion": [1, 0, 0, 0]}]}"#;
    let backwards = r#"{"samples": [
        {"t": 1, "position": [0, 0, 1], "quaternion": [1, 0, 0, 0]},
        {"t": 0.5, "position": [0, 0, 1], "quaternion": [1, 0, 0, 0]}]}"#;
    let e57 = format!("ASTM-E57\0\0\0\0{}", "\0".repeat(200));
    let small = xyz(20);
    let big = xyz(2_000);
    assert!(big.len() > 4_000 && small.len() < 4_000);

    // What is sent, the parts in order, and what the refusal must name.
    type Case<'a> = (&'a str, Vec<(&'a str, String)>, &'a str);
    let cases: Vec<Case> = vec![
        (
            "cloud first, bad poses",
            vec![("cloud", small.clone()), ("poses", bad_quaternion.into())],
            "scans[0]",
        ),
        (
            "bad poses first, a cloud over the limit",
            vec![("poses", bad_quaternion.into()), ("cloud", big.clone())],
            "scans[0]",
        ),
        (
            "a trajectory out of time order",
            vec![("trajectory", backwards.into()), ("cloud", small.clone())],
            "samples[1]",
        ),
        (
            "a sidecar that is not JSON",
            vec![("cloud", small.clone()), ("poses", "scans: []".into())],
            "not valid pose JSON",
        ),
        (
            "an E57, then poses",
            vec![("cloud", e57.clone()), ("poses", good_poses.into())],
            "carries its own scan poses",
        ),
        (
            "poses, then an E57",
            vec![("poses", good_poses.into()), ("cloud", e57.clone())],
            "carries its own scan poses",
        ),
    ];
    for (what, parts, names) in cases {
        let (status, _, body) = call(
            &mut contract,
            "POST",
            "/v1/jobs",
            s.post("/v1/jobs").multipart(form(&parts)),
        )
        .await;
        let text = String::from_utf8_lossy(&body);
        assert_eq!(status, 422, "{}: {what}: {text}", env.backend);
        let e = json(&body);
        assert_eq!(e["error"]["code"], "invalid_sidecar", "{what}: {e}");
        let message = e["error"]["message"].as_str().unwrap();
        assert!(message.contains(names), "{what}: {message}");
        if what == "cloud first, bad poses" {
            // The document's example is this very answer.
            assert_eq!(
                message,
                "the `poses` part: scans[0] (index 0): `quaternion` has norm 2.000000, not 1 \
                 (a rotation's quaternion [w, x, y, z] is unit)"
            );
        }
        let left = env.blobs(&s).await;
        assert!(left.is_empty(), "{what}: blobs left behind: {left:?}");
    }
    assert!(listed(&s, "").await.is_empty(), "no job was made");

    // A good sidecar still makes a job; an E57 alone too; a re-plan of the E57 with poses not.
    let (status, _, body) = call(
        &mut contract,
        "POST",
        "/v1/jobs",
        s.post("/v1/jobs")
            .multipart(form(&[("poses", good_poses.into()), ("cloud", small)])),
    )
    .await;
    assert_eq!(status, 202, "{}", String::from_utf8_lossy(&body));
    let posed = json(&body);
    assert_eq!(posed["upload"]["sidecar"], "poses");
    let (status, _, body) = call(
        &mut contract,
        "POST",
        "/v1/jobs",
        s.post("/v1/jobs").multipart(form(&[("cloud", e57)])),
    )
    .await;
    assert_eq!(status, 202, "{}", String::from_utf8_lossy(&body));
    let e57_job = json(&body)["id"].as_str().unwrap().to_string();
    // Both jobs finish first, so their results are not counted as the re-plan's blobs.
    for id in [posed["id"].as_str().unwrap(), e57_job.as_str()] {
        s.wait_done(id, Duration::from_secs(20)).await;
    }
    let before = env.blobs(&s).await.len();
    assert!(before >= 2, "the two jobs' clouds are seen: {before}");
    let path = format!("/v1/jobs/{e57_job}/replan");
    let (status, _, body) = call(
        &mut contract,
        "POST",
        &path,
        s.post(&path)
            .multipart(form(&[("poses", good_poses.into())])),
    )
    .await;
    assert_eq!(status, 422, "{}", String::from_utf8_lossy(&body));
    assert_eq!(json(&body)["error"]["code"], "invalid_sidecar");
    assert_eq!(
        env.blobs(&s).await.len(),
        before,
        "the refused re-plan kept nothing"
    );
    assert_eq!(listed(&s, "").await.len(), 2);
    s.stop().await;
}

/// The objects of upload sessions the server still keeps.
async fn session_blobs(env: &Env, s: &Server) -> Vec<String> {
    env.blobs(s)
        .await
        .into_iter()
        .filter(|k| k.contains("uploads/"))
        .collect()
}

async fn offset(s: &Server, location: &str) -> (u16, Option<u64>) {
    let res = s
        .client
        .head(s.url(location))
        .header("Tus-Resumable", "1.0.0")
        .send()
        .await
        .unwrap();
    let offset = res
        .headers()
        .get("upload-offset")
        .map(|v| v.to_str().unwrap().parse().unwrap());
    (res.status().as_u16(), offset)
}

fn patch(s: &Server, location: &str, at: u64, body: reqwest::Body) -> reqwest::RequestBuilder {
    s.client
        .patch(s.url(location))
        .header("Tus-Resumable", "1.0.0")
        .header("Content-Type", "application/offset+octet-stream")
        .header("Upload-Offset", at.to_string())
        .body(body)
}

/// tus: open a session, send half and drop the connection, ask where to resume, send the
/// rest, and make a job of it that plans; wrong offsets and early commits are refused; an
/// abandoned session expires and the sweeper removes its bytes.
async fn resumable_uploads_resume_after_a_drop_and_expire(env: &Env) {
    let mut s = env.start(1, |c| c.upload_session_secs = 10).await;
    let cloud = xyz(3_000).into_bytes();
    let total = cloud.len() as u64;
    let mut contract = Contract::load();
    let (status, headers, body) = call(
        &mut contract,
        "POST",
        "/v1/uploads",
        s.post("/v1/uploads")
            .header("Tus-Resumable", "1.0.0")
            .header("Upload-Length", total.to_string()),
    )
    .await;
    assert_eq!(status, 201, "{}", env.backend);
    let location = headers["location"].to_str().unwrap().to_string();
    assert_eq!(headers["upload-offset"], "0");
    assert_eq!(json(&body)["length"], total);

    // Half of a PATCH that declares the whole rest, then the connection drops.
    let half = cloud.len() / 2;
    {
        use tokio::io::AsyncWriteExt;
        let addr = s.url("").trim_start_matches("http://").to_string();
        let mut tcp = tokio::net::TcpStream::connect(addr).await.unwrap();
        let head = format!(
            "PATCH {location} HTTP/1.1\r\nHost: asbuilt\r\nTus-Resumable: 1.0.0\r\n\
             Content-Type: application/offset+octet-stream\r\nUpload-Offset: 0\r\n\
             Content-Length: {total}\r\n\r\n"
        );
        tcp.write_all(head.as_bytes()).await.unwrap();
        tcp.write_all(&cloud[..half]).await.unwrap();
        tcp.flush().await.unwrap();
        tokio::time::sleep(Duration::from_millis(200)).await;
        // Dropped here: the server sees the body end early.
    }
    // The server finishes storing what arrived shortly after the drop.
    let end = Instant::now() + Duration::from_secs(10);
    let at = loop {
        let (status, at) = offset(&s, &location).await;
        assert_eq!(status, 200);
        if at == Some(half as u64) || Instant::now() > end {
            break at.unwrap();
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    assert_eq!(at, half as u64, "{}: resume where it stopped", env.backend);

    // A PATCH at another offset, and a job of an incomplete upload, are conflicts.
    let res = patch(&s, &location, 0, cloud[..10].to_vec().into())
        .send()
        .await
        .unwrap();
    expect_error(res, 409, "upload_conflict").await;
    let path = format!("{location}/job");
    let (status, _, body) = call(&mut contract, "POST", &path, s.post(&path)).await;
    assert_eq!(status, 409);
    assert_eq!(json(&body)["error"]["code"], "upload_conflict");

    let res = patch(&s, &location, at, cloud[half..].to_vec().into())
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 204);
    assert_eq!(res.headers()["upload-offset"], total.to_string().as_str());

    let path = format!("{location}/job?tag=resumed&filename=room.xyz");
    let (status, _, body) = call(&mut contract, "POST", &path, s.post(&path)).await;
    assert_eq!(status, 202, "{}", env.backend);
    let job = json(&body);
    assert_eq!(job["upload"]["bytes"], total);
    assert_eq!(job["upload"]["format"], "xyz");
    assert_eq!(job["tags"], serde_json::json!(["resumed"]));
    let id = job["id"].as_str().unwrap();
    let done = s.wait_done(id, Duration::from_secs(20)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["input"]["points"], 3_000, "the whole cloud, in order");
    assert_eq!(offset(&s, &location).await.0, 404, "the session is used up");
    assert!(session_blobs(env, &s).await.is_empty());

    // An abandoned session: its bytes go when it expires.
    let res = s
        .post("/v1/uploads")
        .header("Upload-Length", total.to_string())
        .send()
        .await
        .unwrap();
    let abandoned = res.headers()["location"].to_str().unwrap().to_string();
    let res = patch(&s, &abandoned, 0, cloud[..100].to_vec().into())
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 204);
    assert_eq!(session_blobs(env, &s).await.len(), 2, "record and one part");
    let end = Instant::now() + Duration::from_secs(30);
    while !session_blobs(env, &s).await.is_empty() {
        assert!(Instant::now() < end, "the sweeper left the session");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert_eq!(offset(&s, &abandoned).await.0, 404);
    s.stop().await;
}

/// WGS84 degrees to metres, near `lat` (a local flat earth: enough for a few metres).
fn metres_between(a: &Value, b: [f64; 2]) -> (f64, f64) {
    let (lon, lat) = (a[0].as_f64().unwrap(), a[1].as_f64().unwrap());
    let east = (lon - b[0]).to_radians() * 6_378_137.0 * lat.to_radians().cos();
    let north = (lat - b[1]).to_radians() * 6_356_752.0;
    (east, north)
}

/// The story outline's exterior ring of a plan GeoJSON.
fn story_ring(doc: &Value) -> Vec<Value> {
    let story = doc["features"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["properties"]["kind"] == "story")
        .unwrap_or_else(|| panic!("no story feature: {doc}"));
    let coords = &story["geometry"]["coordinates"];
    // A Polygon's or a MultiPolygon's first exterior ring.
    let ring = if coords[0][0][0].is_array() {
        &coords[0][0]
    } else {
        &coords[0]
    };
    ring.as_array().unwrap().clone()
}

/// A client's georeference: refused with the field named before anything is stored; kept
/// on the job and shown on every read; carried by re-plans unless replaced; and used for the
/// plan's CRS and its WGS84 copy (the fake plan's corner (0, 0) lands on the anchor).
async fn georeferences_are_checked_stored_and_used(env: &Env) {
    let mut s = env.start(1, |_| {}).await;
    let mut contract = Contract::load();
    let cloud = xyz(40);
    for (query, param) in [
        ("crs=EPSG:4326", "crs"),
        ("crs=EPSG:99999", "crs"),
        ("crs=PROJCS%5B%22broken", "crs"),
        ("anchor=8.5,95,0", "anchor"),
        ("anchor=8.5,47", "anchor"),
        ("crs=EPSG:25832&north_rotation=5", "north_rotation"),
        ("crs=EPSG:25832&anchor=8.5,47.3,400", "anchor"),
        ("anchor=8.5,47.3,400&north_rotation=north", "north_rotation"),
        ("height_datum=EPSG:5728", "crs"),
    ] {
        let path = format!("/v1/jobs?{query}");
        let (status, _, body) = call(
            &mut contract,
            "POST",
            &path,
            s.post(&path).body(cloud.clone()),
        )
        .await;
        assert_eq!(status, 422, "{query}");
        let body = json(&body);
        assert_eq!(
            body["error"]["code"], "invalid_parameter",
            "{query}: {body}"
        );
        assert_eq!(body["error"]["param"], param, "{query}: {body}");
    }
    assert!(env.blobs(&s).await.is_empty(), "refusals kept nothing");

    // A local frame: +y points east (90°), so local +x points south.
    let path = "/v1/jobs?anchor=8.5417,47.3769,408&north_rotation=90&height_datum=EPSG:5728";
    let (status, _, body) = call(
        &mut contract,
        "POST",
        path,
        s.post(path).body(cloud.clone()),
    )
    .await;
    assert_eq!(status, 202, "{}", env.backend);
    let given = serde_json::json!({
        "anchor": [8.5417, 47.3769, 408.0],
        "north_rotation": 90.0,
        "height_datum": "EPSG:5728"
    });
    let job = json(&body);
    assert_eq!(job["georeference"], given);
    assert!(job["upload"].get("georeference").is_none(), "{job}");
    let id = job["id"].as_str().unwrap().to_string();
    let done = s.wait_done(&id, Duration::from_secs(20)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["georeference"], given, "stored and read back");
    let listed = listed(&s, "").await;
    assert_eq!(listed[0]["georeference"], given);

    let path = format!("/v1/jobs/{id}/plan.geojson");
    let (status, _, body) = call(&mut contract, "GET", &path, s.get(&path)).await;
    assert_eq!(status, 200);
    let plan = json(&body);
    let meta = &plan["floorplan"];
    assert_eq!(meta["georeference"]["source"], "given", "{meta}");
    assert_eq!(meta["georeference"]["height_datum"], "EPSG:5728");
    assert!(
        meta["crs"].as_str().unwrap().starts_with("+proj=ortho "),
        "{meta}"
    );
    let path = format!("/v1/jobs/{id}/plan.wgs84.geojson");
    let (status, _, body) = call(&mut contract, "GET", &path, s.get(&path)).await;
    assert_eq!(status, 200);
    let copy = json(&body);
    assert_eq!(
        copy["floorplan"]["georeferenced"], true,
        "{}",
        copy["floorplan"]
    );
    assert_eq!(copy["floorplan"]["crs"], "OGC:CRS84");
    let ring = story_ring(&copy);
    let local = story_ring(&plan);
    for (w, l) in ring.iter().zip(&local) {
        let (x, y) = (l[0].as_f64().unwrap(), l[1].as_f64().unwrap());
        // With +y east: east = y, north = -x.
        let (east, north) = metres_between(w, [8.5417, 47.3769]);
        assert!(
            (east - y).abs() < 0.01 && (north + x).abs() < 0.01,
            "local ({x}, {y}) landed {east:.3} m east, {north:.3} m north"
        );
    }

    // A re-plan keeps the georeference; one with a CRS replaces it.
    let path = format!("/v1/jobs/{id}/replan");
    let (status, _, body) = call(&mut contract, "POST", &path, s.post(&path)).await;
    assert_eq!(status, 202);
    assert_eq!(json(&body)["georeference"], given);
    let path = format!("/v1/jobs/{id}/replan?crs=EPSG:25832");
    let (status, _, body) = call(&mut contract, "POST", &path, s.post(&path)).await;
    assert_eq!(status, 202);
    let replan = json(&body);
    assert_eq!(
        replan["georeference"],
        serde_json::json!({"crs": "EPSG:25832"})
    );
    let rid = replan["id"].as_str().unwrap();
    let done = s.wait_done(rid, Duration::from_secs(20)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let copy = json(
        &s.get(&format!("/v1/jobs/{rid}/plan.wgs84.geojson"))
            .send()
            .await
            .unwrap()
            .bytes()
            .await
            .unwrap(),
    );
    assert_eq!(copy["floorplan"]["source_crs"], "EPSG:25832");
    assert_eq!(copy["floorplan"]["georeferenced"], true);

    // As a multipart part; not with query fields too; a bad part is named.
    let part = r#"{"crs": "EPSG:2056", "height_datum": "EPSG:5728"}"#;
    let res = s
        .post("/v1/jobs")
        .multipart(form(&[
            ("georeference", part.to_string()),
            ("cloud", cloud.clone()),
        ]))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 202);
    let job: Value = res.json().await.unwrap();
    assert_eq!(
        job["georeference"],
        serde_json::json!({"crs": "EPSG:2056", "height_datum": "EPSG:5728"})
    );
    // Its results written first, so the count below sees only what the refusals keep.
    let done = s
        .wait_done(job["id"].as_str().unwrap(), Duration::from_secs(20))
        .await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let before = env.blobs(&s).await.len();
    for (query, part, param) in [
        ("?crs=EPSG:25832", part, "georeference"),
        ("", r#"{"crs": "EPSG:25832", "north": 3}"#, "georeference"),
        ("", r#"{"anchor": [8, 47]}"#, "georeference"),
        ("", r#"{"crs": "EPSG:4258"}"#, "crs"),
    ] {
        let res = s
            .post(&format!("/v1/jobs{query}"))
            .multipart(form(&[
                ("cloud", cloud.clone()),
                ("georeference", part.to_string()),
            ]))
            .send()
            .await
            .unwrap();
        let body = expect_error(res, 422, "invalid_parameter").await;
        assert_eq!(body["error"]["param"], param, "{part}: {body}");
    }
    assert_eq!(
        env.blobs(&s).await.len(),
        before,
        "refused clouds were removed"
    );

    // A resumable upload takes the same query.
    let res = s
        .post("/v1/uploads")
        .header("Upload-Length", cloud.len().to_string())
        .send()
        .await
        .unwrap();
    let location = res.headers()["location"].to_str().unwrap().to_string();
    let res = patch(&s, &location, 0, cloud.clone().into())
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 204);
    let path = format!("{location}/job?crs=EPSG:25832");
    let (status, _, body) = call(&mut contract, "POST", &path, s.post(&path)).await;
    assert_eq!(status, 202);
    assert_eq!(json(&body)["georeference"]["crs"], "EPSG:25832");
    s.stop().await;
}

/// With blobs in a local directory, every direct-upload call says it needs S3.
async fn direct_uploads_answer_that_they_need_s3(env: &Env) {
    let mut s = env.start(1, |_| {}).await;
    let mut contract = Contract::load();
    let id = "0190c1d2-7a3b-7c00-8000-0000000000bb";
    for (method, path) in [
        ("POST", "/v1/direct-uploads".to_string()),
        ("GET", format!("/v1/direct-uploads/{id}")),
        ("DELETE", format!("/v1/direct-uploads/{id}")),
        ("POST", format!("/v1/direct-uploads/{id}/job")),
    ] {
        let req = match method {
            "POST" => s.post(&path).body(r#"{"length": 100}"#),
            "GET" => s.get(&path),
            _ => s.delete(&path),
        };
        let (status, _, body) = call(&mut contract, method, &path, req).await;
        assert_eq!(status, 501, "{method} {path}");
        let body = json(&body);
        assert_eq!(body["error"]["code"], "needs_s3");
        assert!(
            body["error"]["message"]
                .as_str()
                .unwrap()
                .contains("/v1/uploads"),
            "{body}"
        );
    }
    s.stop().await;
}

/// S3 direct uploads: pre-signed part URLs that take the parts without an API key, a job
/// from their ETags whose cloud is the whole file, the refusals, the idempotent retry, and an
/// abandoned upload aborted when it expires.
async fn direct_uploads_go_straight_to_s3(env: &Env) {
    let mut s = env.start(1, |c| c.upload_session_secs = 10).await;
    let mut contract = Contract::load();
    // Three parts of 5 MiB, S3's smallest, the last shorter.
    let cloud = xyz(900_000).into_bytes();
    let part = 5u64 << 20;
    assert!(cloud.len() as u64 > 2 * part && (cloud.len() as u64) < 3 * part);
    for (body, param) in [
        (r#"{"length": 0}"#.to_string(), "length"),
        (
            format!(r#"{{"length": {}, "part_size": 1000}}"#, cloud.len()),
            "part_size",
        ),
    ] {
        let res = s
            .post("/v1/direct-uploads")
            .body(body)
            .send()
            .await
            .unwrap();
        let body = expect_error(res, 422, "invalid_parameter").await;
        assert_eq!(body["error"]["param"], param);
    }
    let res = s
        .post("/v1/direct-uploads")
        .body("{}")
        .send()
        .await
        .unwrap();
    expect_error(res, 400, "invalid_request").await;

    let open = format!(r#"{{"length": {}, "part_size": {part}}}"#, cloud.len());
    let (status, headers, body) = call(
        &mut contract,
        "POST",
        "/v1/direct-uploads",
        s.post("/v1/direct-uploads").body(open.clone()),
    )
    .await;
    assert_eq!(status, 201, "{}", String::from_utf8_lossy(&body));
    let upload = json(&body);
    let id = upload["id"].as_str().unwrap().to_string();
    assert_eq!(
        headers["location"],
        format!("/v1/direct-uploads/{id}").as_str()
    );
    let parts = upload["parts"].as_array().unwrap().clone();
    assert_eq!(parts.len(), 3);
    assert!(parts
        .iter()
        .all(|p| p["url"].as_str().unwrap().contains("X-Amz-Signature=")));

    // The parts go straight to the store: a plain client, no API key.
    let plain = reqwest::Client::new();
    let mut etags = vec![];
    for p in &parts {
        let (at, n) = (
            p["offset"].as_u64().unwrap() as usize,
            p["length"].as_u64().unwrap() as usize,
        );
        let res = plain
            .put(p["url"].as_str().unwrap())
            .body(cloud[at..at + n].to_vec())
            .send()
            .await
            .unwrap();
        assert_eq!(res.status(), 200, "{}", res.text().await.unwrap());
        let etag = res.headers()["etag"].to_str().unwrap().to_string();
        etags.push(serde_json::json!({"number": p["number"], "etag": etag}));
    }
    // Fresh URLs for the same upload.
    let path = format!("/v1/direct-uploads/{id}");
    let (status, _, body) = call(&mut contract, "GET", &path, s.get(&path)).await;
    assert_eq!(status, 200);
    assert_eq!(json(&body)["parts"].as_array().unwrap().len(), 3);

    // A part left out, or an ETag that is not the part's: conflicts, and the upload stays.
    let job_path = format!("/v1/direct-uploads/{id}/job?crs=EPSG:25832&tag=direct");
    let two = serde_json::json!({"parts": &etags[..2]}).to_string();
    let (status, _, body) = call(
        &mut contract,
        "POST",
        &job_path,
        s.post(&job_path).body(two),
    )
    .await;
    assert_eq!(status, 409, "{}", String::from_utf8_lossy(&body));
    assert_eq!(json(&body)["error"]["code"], "upload_conflict");

    let all = serde_json::json!({"parts": etags}).to_string();
    let (status, headers, body) = call(
        &mut contract,
        "POST",
        &job_path,
        s.post(&job_path)
            .header("Idempotency-Key", "direct-1")
            .body(all.clone()),
    )
    .await;
    assert_eq!(status, 202, "{}", String::from_utf8_lossy(&body));
    let job = json(&body);
    assert_eq!(job["id"], id.as_str(), "the job has the upload's id");
    assert_eq!(headers["location"], format!("/v1/jobs/{id}").as_str());
    assert_eq!(job["upload"]["bytes"], cloud.len());
    use sha2::Digest;
    let sha: String = sha2::Sha256::digest(&cloud)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(job["upload"]["sha256"], sha);
    assert_eq!(job["upload"]["format"], "xyz");
    assert_eq!(job["georeference"]["crs"], "EPSG:25832");
    assert_eq!(job["tags"], serde_json::json!(["direct"]));
    let done = s.wait_done(&id, Duration::from_secs(60)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(
        done["input"]["points"], 900_000,
        "the whole cloud, in order"
    );
    // The upload is used up; a retry with its key answers the job.
    assert_eq!(s.get(&path).send().await.unwrap().status(), 404);
    let res = s
        .post(&job_path)
        .header("Idempotency-Key", "direct-1")
        .body(all)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    assert_eq!(res.json::<Value>().await.unwrap()["id"], id.as_str());
    assert!(session_blobs(env, &s).await.is_empty());

    // Not a cloud: refused once joined, and nothing is kept.
    let (status, _, body) = call(
        &mut contract,
        "POST",
        "/v1/direct-uploads",
        s.post("/v1/direct-uploads").body(r#"{"length": 11}"#),
    )
    .await;
    assert_eq!(status, 201);
    let junk = json(&body);
    let jid = junk["id"].as_str().unwrap().to_string();
    let res = plain
        .put(junk["parts"][0]["url"].as_str().unwrap())
        .body(b"\x00\x01garbage\xff\xfe".to_vec())
        .send()
        .await
        .unwrap();
    let etag = res.headers()["etag"].to_str().unwrap().to_string();
    let res = s
        .post(&format!("/v1/direct-uploads/{jid}/job"))
        .body(serde_json::json!({"parts": [{"number": 1, "etag": etag}]}).to_string())
        .send()
        .await
        .unwrap();
    expect_error(res, 415, "unsupported_format").await;
    assert!(
        !env.blobs(&s).await.iter().any(|k| k.contains(&jid)),
        "the refused object was removed"
    );

    // Abandoned: the sweeper aborts it when it expires, and the record goes.
    let res = s
        .post("/v1/direct-uploads")
        .body(open)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 201);
    let abandoned: Value = res.json().await.unwrap();
    let aid = abandoned["id"].as_str().unwrap();
    assert_eq!(session_blobs(env, &s).await.len(), 1, "its record");
    let end = Instant::now() + Duration::from_secs(30);
    while !session_blobs(env, &s).await.is_empty() {
        assert!(Instant::now() < end, "the sweeper left the direct upload");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let res = s
        .get(&format!("/v1/direct-uploads/{aid}"))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 404);
    s.stop().await;
}

/// Georeferences with blobs in S3 too.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn georeferences_are_checked_stored_and_used_in_s3() {
    let test = "georeferences_are_checked_stored_and_used_in_s3";
    let Some(env) = Env::postgres_s3(test).await else {
        return;
    };
    georeferences_are_checked_stored_and_used(&env).await;
    env.finish().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn direct_uploads_go_straight_to_s3_with_presigned_parts() {
    let test = "direct_uploads_go_straight_to_s3_with_presigned_parts";
    let Some(env) = Env::postgres_s3(test).await else {
        return;
    };
    direct_uploads_go_straight_to_s3(&env).await;
    env.finish().await;
}

const BOTOCORE_PRESIGN: &str = r#"
import datetime, sys
from unittest import mock
import botocore.auth
from botocore.auth import S3SigV4QueryAuth
from botocore.awsrequest import AWSRequest
from botocore.credentials import Credentials
url, key, secret, region, stamp, expires = sys.argv[1:7]
when = datetime.datetime.strptime(stamp, "%Y%m%dT%H%M%SZ")
req = AWSRequest(method="PUT", url=url)
auth = S3SigV4QueryAuth(Credentials(key, secret), "s3", region, expires=int(expires))
with mock.patch.object(botocore.auth, "get_current_datetime", return_value=when):
    auth.add_auth(req)
print(req.prepare().url)
"#;

/// The part URLs' signatures equal botocore's (the AWS SDK's own signer; moto, the test S3
/// server, does not check signatures), for paths and upload ids that need encoding.
#[test]
fn part_urls_are_signed_as_the_aws_sdk_signs_them() {
    use asbuilt::storage::presign::{presign, SigningKey};
    let probe = std::process::Command::new("python3")
        .args(["-c", "import botocore"])
        .output();
    if !matches!(&probe, Ok(o) if o.status.success()) {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must have botocore (moto's, .ci/backends.sh)"
        );
        eprintln!("skipping: python3 has no botocore");
        return;
    }
    let date = chrono::DateTime::parse_from_rfc3339("2026-12-04T20:00:00Z")
        .unwrap()
        .with_timezone(&chrono::Utc);
    for (url, upload_id, part, region) in [
        (
            "http://127.0.0.1:5555/asbuilt-suite/jobs/0190c1d2-7a3b-7c00-8000-0000000000bb/input/cloud",
            "2~abc+def/ghi=",
            "1",
            "us-east-1",
        ),
        (
            "https://data.s3.eu-central-1.amazonaws.com/pre%20fix/jobs/x/input/cloud",
            "VXBsb2FkIElE",
            "10000",
            "eu-central-1",
        ),
    ] {
        let key = SigningKey {
            key_id: "AKIAEXAMPLE",
            secret: "wJalrXUtnFEMI/K7MDENG+bPxRfiCYEXAMPLEKEY",
            token: None,
            region,
            date,
        };
        let base = reqwest::Url::parse(url).unwrap();
        let ours = presign(
            "PUT",
            &base,
            &[("partNumber", part), ("uploadId", upload_id)],
            &key,
            3600,
        );
        let mut unsigned = base.clone();
        unsigned
            .query_pairs_mut()
            .append_pair("partNumber", part)
            .append_pair("uploadId", upload_id);
        let out = std::process::Command::new("python3")
            .args(["-c", BOTOCORE_PRESIGN, unsigned.as_str(), key.key_id, key.secret])
            .args([region, "20261204T200000Z", "3600"])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let theirs = reqwest::Url::parse(String::from_utf8(out.stdout).unwrap().trim()).unwrap();
        let signature = |u: &reqwest::Url| {
            u.query_pairs()
                .find(|(k, _)| k == "X-Amz-Signature")
                .map(|(_, v)| v.to_string())
                .unwrap()
        };
        assert_eq!(signature(&ours), signature(&theirs), "{url}");
    }
}
