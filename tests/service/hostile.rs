//! The hostile-client suite: each case drives a real `asbuilt serve` process the way a careless
//! or hostile client would, on SQLite and on PostgreSQL, and asserts the outcome (the job ends,
//! the worker is free, the process exits, the connection closes, the request is refused).
//! How long each outcome took is printed as `hostile: CASE [BACKEND] WHAT: N ms`, a benchmark
//! figure and not an assertion (`cargo test --test service hostile:: -- --nocapture`; with
//! `ASBUILT_HOSTILE_REPORT=FILE` the lines are also appended to FILE).
//!
//! Jobs run on the fake pipeline (`--fake-pipeline-ms`; `#hang:SECS` in a cloud makes it stick
//! in the fit stage without looking at its stop token), except one case that stops the real
//! pipeline at its time limit.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use crate::support::engines::{postgres_only, Engines};
use crate::support::files_under;
use crate::support::process::{fake_cloud, run_to_exit, serve, Client, Server};
use crate::support::wait::{drain_jobs, eventually};
use reqwest::Method;
use serde_json::Value;

const ACME: &str = "acme-key-0000000000001";
const BOLT: &str = "bolt-key-0000000000002";

/// Where a case's server keeps its jobs.
struct Env {
    backend: &'static str,
    dir: tempfile::TempDir,
    pg: Option<(Engines, String)>,
}

impl Env {
    fn sqlite() -> Env {
        Env {
            backend: "sqlite",
            dir: tempfile::tempdir().unwrap(),
            pg: None,
        }
    }

    /// A schema of its own, migrated; `None` when PostgreSQL is not configured.
    async fn postgres(test: &str) -> Option<Env> {
        let engines = postgres_only(test)?;
        let schema = engines.new_schema("hostile").await;
        let env = Env {
            backend: "postgres",
            dir: tempfile::tempdir().unwrap(),
            pg: Some((engines, schema)),
        };
        let mut args = vec!["migrate".to_string()];
        args.extend(env.db_args());
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (out, _) = run_to_exit(&args, Duration::from_secs(60));
        assert!(out.status.success(), "{out:?}");
        Some(env)
    }

    fn db_args(&self) -> Vec<String> {
        match &self.pg {
            Some((e, schema)) => vec!["--database-url".into(), e.url_in(schema)],
            None => vec![],
        }
    }

    /// A server on this backend with `args`, keeping its data in `name` under the case's dir.
    fn serve(&self, name: &str, args: &[&str]) -> Server {
        let mut all: Vec<String> = self.db_args();
        all.extend(args.iter().map(|s| s.to_string()));
        let all: Vec<&str> = all.iter().map(String::as_str).collect();
        serve(&self.dir.path().join(name), &all)
    }

    /// Prints (and records) how long an outcome took.
    fn took(&self, case: &str, what: &str, d: Duration) {
        let line = format!(
            "hostile: {case} [{}] {what}: {:.0} ms",
            self.backend,
            d.as_secs_f64() * 1e3
        );
        eprintln!("{line}");
        if let Ok(path) = std::env::var("ASBUILT_HOSTILE_REPORT") {
            if let Ok(mut f) = std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(path)
            {
                let _ = writeln!(f, "{line}");
            }
        }
    }

    async fn finish(self) {
        if let Some((e, schema)) = &self.pg {
            e.drop_schema(schema).await;
        }
    }
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
    unbounded_parameters_are_refused_up_front,
    the_job_timeout_holds_and_frees_the_worker,
    the_real_pipeline_stops_inside_a_stage_at_its_time_limit,
    cancel_under_load_frees_the_worker,
    sigterm_mid_fit_exits_in_time_and_hands_back_once,
    a_stalled_upload_is_dropped_and_its_blob_removed,
    duplicate_or_short_keys_refuse_to_start,
    metrics_need_their_own_key_or_address,
    keys_are_added_and_revoked_without_a_restart,
    rate_limits_answer_429_with_retry_after,
    a_tenant_flood_is_capped_and_claimed_fairly,
    every_error_is_json,
);

/// The status a job shows now.
async fn status(c: &Client, id: &str) -> String {
    c.job(id).await["status"].as_str().unwrap().to_string()
}

async fn upload_ok(c: &Client, body: String) -> String {
    let (st, job) = c.upload("", body).await;
    assert_eq!(st, 202, "{job}");
    job["id"].as_str().unwrap().to_string()
}

/// A job's RFC 3339 time in Unix milliseconds.
fn rfc3339_ms(t: &Value) -> i64 {
    chrono::DateTime::parse_from_rfc3339(t.as_str().expect("a time"))
        .expect("RFC 3339")
        .timestamp_millis()
}

async fn unbounded_parameters_are_refused_up_front(env: &Env) {
    let case = "unbounded parameters";
    let s = env.serve(
        "d",
        &[
            "--api-key",
            &format!("acme:{ACME}"),
            "--fake-pipeline-ms",
            "10",
        ],
    );
    let c = Client::new(&s.base, Some(ACME));
    for (query, param, range) in [
        (
            "?fitting.iterations=1000000000000",
            "fitting.iterations",
            "1..=100000",
        ),
        (
            "?fitting.iterations=18446744073709551615",
            "fitting.iterations",
            "1..=100000",
        ),
        (
            "?samples.cell_size=1000000000",
            "samples.cell_size",
            "0.01..=0.5",
        ),
        (
            "?labeling.dense_below=100000000",
            "labeling.dense_below",
            "0..=2000",
        ),
    ] {
        let start = Instant::now();
        let (st, body) = c.upload(query, fake_cloud(1000, &[])).await;
        env.took(case, &format!("{param} refused"), start.elapsed());
        assert_eq!(st, 422, "{query}: {body}");
        assert_eq!(body["error"]["code"], "invalid_parameter");
        assert_eq!(body["error"]["param"], param);
        let msg = body["error"]["message"].as_str().unwrap();
        assert!(msg.contains(range), "{msg}");
    }
    // The same in a `params` part.
    let form = reqwest::multipart::Form::new()
        .text(
            "params",
            r#"{"fitting": {"iterations": 18446744073709551615}}"#,
        )
        .part(
            "cloud",
            reqwest::multipart::Part::text(fake_cloud(10, &[])).file_name("c.xyz"),
        );
    let res = c
        .req(Method::POST, "/v1/jobs")
        .multipart(form)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 422);
    let body: Value = res.json().await.unwrap();
    assert_eq!(body["error"]["param"], "fitting.iterations", "{body}");
    assert!(c.jobs().await.is_empty(), "no job was created");
    assert!(
        files_under(&s.data.join("blobs")).is_empty(),
        "nothing was kept"
    );
}

async fn the_job_timeout_holds_and_frees_the_worker(env: &Env) {
    let case = "job timeout";
    let s = env.serve(
        "d",
        &[
            "--job-timeout",
            "1",
            "--workers",
            "1",
            "--fake-pipeline-ms",
            "100",
        ],
    );
    let c = Client::new(&s.base, None);
    // Stuck in fit from 0.5 s on, without looking at its stop token, for a minute.
    let stuck = upload_ok(&c, fake_cloud(10, &["#hang:60"])).await;
    let next = upload_ok(&c, fake_cloud(10, &[])).await;
    let (job, _) = eventually("the stuck job fails", Duration::from_secs(20), || async {
        let j = c.job(&stuck).await;
        (j["status"] == "failed").then_some(j)
    })
    .await;
    assert_eq!(job["error"]["code"], "time_limit", "{job}");
    assert_eq!(job["stage"], "fit", "the stage it stopped in");
    let over = rfc3339_ms(&job["finished_at"]) - rfc3339_ms(&job["started_at"]) - 1000;
    env.took(
        case,
        "stuck job failed after its 1 s limit",
        Duration::from_millis(over.max(0) as u64),
    );
    let (j, _) = eventually(
        "the worker takes the next job",
        Duration::from_secs(20),
        || async {
            let j = c.job(&next).await;
            (j["status"] == "succeeded").then_some(j)
        },
    )
    .await;
    let free = rfc3339_ms(&j["started_at"]) - rfc3339_ms(&job["finished_at"]);
    env.took(
        case,
        "next job started after the failure",
        Duration::from_millis(free.max(0) as u64),
    );
}

async fn the_real_pipeline_stops_inside_a_stage_at_its_time_limit(env: &Env) {
    let case = "real pipeline time limit";
    // A scan the debug build plans in several seconds; a fixed 1 cm grid makes every stage heavier.
    let sim = env.dir.path().join("sim");
    let (out, _) = run_to_exit(
        &[
            "simulate",
            "--building",
            "office_3story",
            "--points",
            "600000",
            "--seed",
            "5",
            "--out",
            sim.to_str().unwrap(),
        ],
        Duration::from_secs(120),
    );
    assert!(out.status.success(), "{out:?}");
    let cloud = std::fs::read(sim.join("cloud.ply")).unwrap();
    let s = env.serve("d", &["--job-timeout", "1", "--workers", "1"]);
    let c = Client::new(&s.base, None);
    let res = c
        .req(
            Method::POST,
            "/v1/jobs?samples.cell_size=0.01&samples.derive_cell_size=false",
        )
        .body(cloud)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 202);
    let id = res.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let (job, _) = eventually(
        "the job fails at its limit",
        Duration::from_secs(60),
        || async {
            let j = c.job(&id).await;
            matches!(j["status"].as_str(), Some("failed" | "succeeded")).then_some(j)
        },
    )
    .await;
    assert_eq!(job["status"], "failed", "{job}");
    assert_eq!(job["error"]["code"], "time_limit", "{job}");
    let stage = job["stage"].as_str().expect("the stage it stopped in");
    let over = rfc3339_ms(&job["finished_at"]) - rfc3339_ms(&job["started_at"]) - 1000;
    env.took(
        case,
        &format!("stopped in `{stage}` after its 1 s limit"),
        Duration::from_millis(over.max(0) as u64),
    );
    // The worker is free: a tiny job goes through.
    let next = upload_ok(&c, "0 0 0\n1 0 0\n0 1 0\n".into()).await;
    let (_, took) = eventually(
        "the worker takes the next job",
        Duration::from_secs(30),
        || async { (status(&c, &next).await != "queued").then_some(()) },
    )
    .await;
    env.took(case, "next job claimed", took);
}

async fn cancel_under_load_frees_the_worker(env: &Env) {
    let case = "cancel under load";
    let s = env.serve(
        "d",
        &[
            "--workers",
            "1",
            "--fake-pipeline-ms",
            "300",
            "--fake-pipeline-spin",
        ],
    );
    let c = Client::new(&s.base, None);
    let busy = upload_ok(&c, fake_cloud(10, &[])).await;
    let stuck = upload_ok(&c, fake_cloud(10, &["#hang:60"])).await;
    let last = upload_ok(&c, fake_cloud(10, &[])).await;
    eventually("the first job runs", Duration::from_secs(20), || async {
        (status(&c, &busy).await == "running").then_some(())
    })
    .await;
    let res = c
        .req(Method::DELETE, &format!("/v1/jobs/{busy}"))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 204);
    let (_, took) = eventually(
        "the worker takes the next job",
        Duration::from_secs(20),
        || async { (status(&c, &stuck).await == "running").then_some(()) },
    )
    .await;
    env.took(case, "busy job deleted, next job started", took);
    let gone = c
        .req(Method::GET, &format!("/v1/jobs/{busy}"))
        .send()
        .await
        .unwrap();
    assert_eq!(gone.status(), 404, "a deleted job is gone");
    eventually(
        "the stuck job reaches fit",
        Duration::from_secs(20),
        || async { (c.job(&stuck).await["stage"] == "fit").then_some(()) },
    )
    .await;
    let res = c
        .req(Method::DELETE, &format!("/v1/jobs/{stuck}"))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 204);
    let (_, took) = eventually(
        "the worker leaves the stuck pipeline",
        Duration::from_secs(20),
        || async { (status(&c, &last).await != "queued").then_some(()) },
    )
    .await;
    env.took(case, "stuck job deleted, next job started", took);
    let jobs = drain_jobs(&c, Duration::from_secs(30)).await;
    assert_eq!(jobs.len(), 1, "{jobs:?}");
    assert_eq!(jobs[0]["id"], Value::from(last.clone()));
    assert_eq!(jobs[0]["status"], "succeeded");
    // The deleted jobs left nothing behind, not even the abandoned pipeline's results.
    let left: Vec<_> = files_under(&s.data.join("blobs"))
        .into_iter()
        .filter(|p| !p.to_string_lossy().contains(&last))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

async fn sigterm_mid_fit_exits_in_time_and_hands_back_once(env: &Env) {
    let case = "SIGTERM mid-fit";
    let args = [
        "--workers",
        "2",
        "--shutdown-timeout",
        "1",
        // Long enough that the normal job is still running when the shutdown gives up.
        "--fake-pipeline-ms",
        "800",
    ];
    let mut s = env.serve("d", &args);
    let c = Client::new(&s.base, None);
    let stuck = upload_ok(&c, fake_cloud(10, &["#hang:60"])).await;
    let normal = upload_ok(&c, fake_cloud(10, &[])).await;
    eventually(
        "both run, one stuck in fit",
        Duration::from_secs(20),
        || async {
            let stuck_fit = c.job(&stuck).await["stage"] == "fit";
            (stuck_fit && status(&c, &normal).await == "running").then_some(())
        },
    )
    .await;
    s.terminate();
    let (exit, took) = s
        .wait_exit(Duration::from_secs(30))
        .expect("the process exits");
    env.took(case, "SIGTERM to exit (--shutdown-timeout 1)", took);
    assert!(exit.success(), "{exit:?}\n{}", s.log());
    let log = s.log();
    drop(s);
    // Both jobs are queued again, their attempts given back.
    let quiet = env.serve("d", &["--workers", "0"]);
    let q = Client::new(&quiet.base, None);
    for id in [&stuck, &normal] {
        let j = q.job(id).await;
        assert_eq!(
            (j["status"].as_str(), j["attempts"].as_u64()),
            (Some("queued"), Some(0)),
            "{j}\n{log}"
        );
    }
    drop(quiet);
    // Restarted, the normal job runs to completion once; the stuck one is claimed again.
    let again = env.serve("d", &args);
    let a = Client::new(&again.base, None);
    eventually(
        "the normal job completes",
        Duration::from_secs(30),
        || async { (status(&a, &normal).await == "succeeded").then_some(()) },
    )
    .await;
    assert_eq!(a.job(&stuck).await["attempts"], 1);
    let done = std::fs::read_to_string(again.data.join("fake-completions.log")).unwrap();
    assert_eq!(
        done.lines().filter(|l| *l == normal).count(),
        1,
        "ran to completion exactly once"
    );
    assert!(!done.contains(&stuck));
}

async fn a_stalled_upload_is_dropped_and_its_blob_removed(env: &Env) {
    let case = "stalled upload";
    let s = env.serve(
        "d",
        &[
            "--api-key",
            &format!("acme:{ACME}"),
            "--upload-idle-timeout",
            "1",
            "--workers",
            "0",
        ],
    );
    let addr = s.addr();
    let stall = tokio::task::spawn_blocking(move || {
        let mut tcp = TcpStream::connect(addr).unwrap();
        tcp.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
        let head = format!(
            "POST /v1/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {ACME}\r\n\
             Content-Length: 2000000\r\n\r\n"
        );
        tcp.write_all(head.as_bytes()).unwrap();
        let body = fake_cloud(10_000, &[]);
        tcp.write_all(&body.as_bytes()[..100_000.min(body.len())])
            .unwrap();
        let sent = Instant::now();
        let mut answer = Vec::new();
        let mut buf = [0u8; 4096];
        let mut answered = None;
        // Read until the server closes the connection.
        loop {
            match tcp.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => {
                    answered.get_or_insert(sent.elapsed());
                    answer.extend_from_slice(&buf[..n]);
                }
                Err(e) => panic!("no close: {e}; got {}", String::from_utf8_lossy(&answer)),
            }
        }
        (
            String::from_utf8_lossy(&answer).to_string(),
            answered,
            sent.elapsed(),
        )
    });
    let (answer, answered, closed) = stall.await.unwrap();
    env.took(case, "stall to answer", answered.expect("an answer"));
    env.took(case, "stall to connection closed", closed);
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    let body = answer.split_once("\r\n\r\n").unwrap().1;
    let v: Value = serde_json::from_str(body).unwrap();
    assert_eq!(v["error"]["code"], "upload_timeout");
    let c = Client::new(&s.base, Some(ACME));
    assert!(c.jobs().await.is_empty());
    assert!(
        files_under(&s.data.join("blobs")).is_empty(),
        "the partial blob is gone"
    );
}

async fn duplicate_or_short_keys_refuse_to_start(env: &Env) {
    let case = "bad keys";
    let data = env.dir.path().join("d");
    let db = env.db_args();
    let data_s = data.to_str().unwrap().to_string();
    let run = |extra: &[&str]| {
        let mut args: Vec<&str> = vec!["serve", "--data-dir", &data_s];
        args.extend(db.iter().map(String::as_str));
        args.extend(extra);
        run_to_exit(&args, Duration::from_secs(30))
    };
    let dup = format!("acme:{ACME},bolt:{ACME}");
    let (out, took) = run(&["--api-key", &dup]);
    env.took(case, "duplicate key refused", took);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("`acme`") && err.contains("`bolt`") && err.contains("same key"),
        "{err}"
    );
    assert!(!err.contains(ACME), "the key is not echoed: {err}");
    let (out, _) = run(&["--api-key", "acme:0123456789abcde"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("shorter than 16"), "{err}");
    let file = env.dir.path().join("keys");
    std::fs::write(&file, format!("# keys\nacme:{ACME}\nbolt:{ACME}\n")).unwrap();
    let (out, _) = run(&["--api-keys-file", file.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("same key"), "{err}");
}

async fn metrics_need_their_own_key_or_address(env: &Env) {
    let case = "metrics";
    let s = env.serve(
        "a",
        &["--api-key", &format!("acme:{ACME}"), "--workers", "0"],
    );
    let http = reqwest::Client::new();
    let start = Instant::now();
    let res = http.get(s.url("/metrics")).send().await.unwrap();
    env.took(case, "metrics without a key refused", start.elapsed());
    assert_eq!(res.status(), 401);
    assert!(res.headers().contains_key("www-authenticate"));
    let v: Value = res.json().await.unwrap();
    assert_eq!(v["error"]["code"], "unauthorized");
    let res = http
        .get(s.url("/metrics"))
        .bearer_auth(ACME)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 401, "a tenant's key is not the metrics key");
    drop(s);

    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let listen = format!("127.0.0.1:{port}");
    let metrics_key = "metrics-key-00000000001";
    let s = env.serve(
        "b",
        &[
            "--api-key",
            &format!("acme:{ACME}"),
            "--metrics-key",
            metrics_key,
            "--metrics-listen",
            &listen,
            "--workers",
            "0",
        ],
    );
    let res = http
        .get(s.url("/metrics"))
        .bearer_auth(metrics_key)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    assert!(res.text().await.unwrap().contains("asbuilt_queue_depth"));
    let res = http
        .get(s.url("/metrics"))
        .bearer_auth(ACME)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 401);
    let (res, _) = eventually(
        "the metrics listener answers",
        Duration::from_secs(10),
        || async {
            http.get(format!("http://{listen}/metrics"))
                .send()
                .await
                .ok()
        },
    )
    .await;
    assert_eq!(res.status(), 200);
    let res = http
        .get(format!("http://{listen}/v1/jobs"))
        .bearer_auth(ACME)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 404, "only /metrics on the metrics address");
}

async fn keys_are_added_and_revoked_without_a_restart(env: &Env) {
    let case = "live keys";
    let file = env.dir.path().join("keys");
    std::fs::write(&file, format!("acme:{ACME}\n")).unwrap();
    let s = env.serve(
        "d",
        &["--api-keys-file", file.to_str().unwrap(), "--workers", "0"],
    );
    let http = reqwest::Client::new();
    let code = |key: &'static str| {
        let http = http.clone();
        let url = s.url("/v1/jobs");
        async move {
            http.get(url)
                .bearer_auth(key)
                .send()
                .await
                .unwrap()
                .status()
                .as_u16()
        }
    };
    assert_eq!(code(ACME).await, 200);
    assert_eq!(code(BOLT).await, 401);
    std::fs::write(&file, format!("acme:{ACME}\nbolt:{BOLT}\n")).unwrap();
    let (_, took) = eventually("bolt's key works", Duration::from_secs(15), || async {
        // Slowly: 20 unknown keys in a row would brake this address.
        tokio::time::sleep(Duration::from_millis(200)).await;
        (code(BOLT).await == 200).then_some(())
    })
    .await;
    env.took(case, "key added to working", took);
    std::fs::write(&file, format!("bolt:{BOLT}\n")).unwrap();
    let (_, took) = eventually("acme's key is revoked", Duration::from_secs(15), || async {
        (code(ACME).await == 401).then_some(())
    })
    .await;
    env.took(case, "key removed to refused", took);
    // A broken edit keeps the keys in force.
    std::fs::write(&file, format!("bolt:{BOLT}\ncarl:{BOLT}\n")).unwrap();
    eventually(
        "the bad edit is reported",
        Duration::from_secs(15),
        || async { s.log().contains("not reloaded").then_some(()) },
    )
    .await;
    assert_eq!(code(BOLT).await, 200);
}

async fn rate_limits_answer_429_with_retry_after(env: &Env) {
    let case = "rate limits";
    let s = env.serve(
        "d",
        &[
            "--api-key",
            &format!("acme:{ACME},bolt:{BOLT}"),
            "--rate-limit",
            "2",
            "--rate-burst",
            "5",
            "--workers",
            "0",
        ],
    );
    let http = reqwest::Client::new();
    let start = Instant::now();
    let mut first_429 = None;
    let mut codes = vec![];
    for _ in 0..15 {
        let res = http
            .get(s.url("/v1/jobs"))
            // The scheme in lower case is as good.
            .header("authorization", format!("bearer {ACME}"))
            .send()
            .await
            .unwrap();
        codes.push(res.status().as_u16());
        if res.status() == 429 && first_429.is_none() {
            first_429 = Some(start.elapsed());
            let retry: u64 = res.headers()["retry-after"]
                .to_str()
                .unwrap()
                .parse()
                .unwrap();
            assert!(retry >= 1);
            let v: Value = res.json().await.unwrap();
            assert_eq!(v["error"]["code"], "rate_limited");
        }
    }
    env.took(
        case,
        "tenant over its burst to 429",
        first_429.expect("a 429"),
    );
    assert!(codes[..5].iter().all(|&c| c == 200), "{codes:?}");
    let other = http
        .get(s.url("/v1/jobs"))
        .bearer_auth(BOLT)
        .send()
        .await
        .unwrap();
    assert_eq!(other.status(), 200, "another tenant is unaffected");

    // Unknown keys: 401 with WWW-Authenticate, then the address is braked.
    let mut codes = vec![];
    let start = Instant::now();
    let mut braked = None;
    for i in 0..40 {
        let res = http
            .get(s.url("/v1/jobs"))
            .bearer_auth(format!("wrong-key-{i:012}"))
            .send()
            .await
            .unwrap();
        let st = res.status().as_u16();
        if st == 401 {
            assert!(res.headers().contains_key("www-authenticate"));
        }
        if st == 429 && braked.is_none() {
            braked = Some(start.elapsed());
            assert!(res.headers().contains_key("retry-after"));
        }
        codes.push(st);
    }
    env.took(
        case,
        "unknown keys to a braked address",
        braked.expect("braked"),
    );
    let refused = codes.iter().filter(|&&c| c == 401).count();
    assert_eq!(
        refused,
        asbuilt::limits::FAILED_KEYS_BURST as usize,
        "{codes:?}"
    );
    assert!(codes[20..].iter().all(|&c| c == 429), "{codes:?}");
}

async fn a_tenant_flood_is_capped_and_claimed_fairly(env: &Env) {
    let case = "tenant flood";
    let s = env.serve(
        "d",
        &[
            "--api-key",
            &format!("acme:{ACME},bolt:{BOLT}"),
            "--workers",
            "1",
            "--fake-pipeline-ms",
            "30",
            "--max-queued",
            "20",
            "--rate-limit",
            "0",
        ],
    );
    let flood = Client::new(&s.base, Some(ACME));
    let single = Client::new(&s.base, Some(BOLT));
    let mut ids = vec![];
    for _ in 0..20 {
        ids.push(upload_ok(&flood, fake_cloud(10, &[])).await);
    }
    // Two or three have started meanwhile; fill up to the cap again, then one more.
    let mut capped = None;
    for _ in 0..10 {
        let (st, body) = flood.upload("", fake_cloud(10, &[])).await;
        if st == 429 {
            assert_eq!(body["error"]["code"], "queue_full");
            capped = Some(body);
            break;
        }
        ids.push(body["id"].as_str().unwrap().to_string());
    }
    assert!(capped.is_some(), "the cap of 20 queued jobs held");
    let start = Instant::now();
    let mine = upload_ok(&single, fake_cloud(10, &[])).await;
    let (job, _) = eventually("the single job starts", Duration::from_secs(30), || async {
        let j = single.job(&mine).await;
        (j["status"] != "queued").then_some(j)
    })
    .await;
    env.took(
        case,
        "single job's wait behind a 20-job flood",
        start.elapsed(),
    );
    let started = rfc3339_ms(&job["started_at"]);
    let mut before = 0;
    for id in &ids {
        let j = flood.job(id).await;
        if j["started_at"].is_string() && rfc3339_ms(&j["started_at"]) < started {
            before += 1;
        }
    }
    // Those that ran before the upload, plus at most the one running when it came.
    let queued_then: usize = ids.len() - before;
    assert!(queued_then >= 15, "{before} flood jobs ran before it");
    let jobs = drain_jobs(&flood, Duration::from_secs(60)).await;
    assert!(jobs.iter().all(|j| j["status"] == "succeeded"));
}

/// Sends raw bytes and returns the whole answer (until the server closes or 3 s pass).
fn raw(addr: &str, bytes: &[u8]) -> String {
    let mut tcp = TcpStream::connect(addr).unwrap();
    tcp.set_read_timeout(Some(Duration::from_secs(3))).unwrap();
    let _ = tcp.write_all(bytes);
    let mut out = Vec::new();
    let mut buf = [0u8; 8192];
    while let Ok(n) = tcp.read(&mut buf) {
        if n == 0 {
            break;
        }
        out.extend_from_slice(&buf[..n]);
        // One answer is enough.
        let text = String::from_utf8_lossy(&out);
        if let Some((head, body)) = text.split_once("\r\n\r\n") {
            let len = head.lines().find_map(|l| {
                l.to_ascii_lowercase()
                    .strip_prefix("content-length: ")
                    .map(|v| v.trim().parse::<usize>().unwrap_or(0))
            });
            if len.is_some_and(|n| body.len() >= n) {
                break;
            }
        }
    }
    String::from_utf8_lossy(&out).to_string()
}

async fn every_error_is_json(env: &Env) {
    let case = "JSON errors";
    let s = env.serve(
        "d",
        &["--api-key", &format!("acme:{ACME}"), "--workers", "0"],
    );
    let addr = s.addr();
    let auth = format!("Authorization: Bearer {ACME}\r\n");
    let big_header = format!("X-Big: {}\r\n", "a".repeat(600_000));
    let cases: Vec<(&str, Vec<u8>, u16)> = vec![
        (
            "overflowing Content-Length",
            format!("POST /v1/jobs HTTP/1.1\r\nHost: x\r\n{auth}Content-Length: 99999999999999999999999\r\n\r\n").into_bytes(),
            400,
        ),
        (
            "two Content-Lengths",
            format!("POST /v1/jobs HTTP/1.1\r\nHost: x\r\n{auth}Content-Length: 5\r\nContent-Length: 6\r\n\r\nhello").into_bytes(),
            400,
        ),
        ("garbage request line", b"GARBAGE\r\n\r\n".to_vec(), 400),
        (
            "headers too large",
            format!("GET /v1/jobs HTTP/1.1\r\nHost: x\r\n{big_header}\r\n").into_bytes(),
            431,
        ),
        (
            "bad chunked body",
            format!("POST /v1/jobs HTTP/1.1\r\nHost: x\r\n{auth}Transfer-Encoding: chunked\r\n\r\nzz\r\n").into_bytes(),
            400,
        ),
        ("no key", b"GET /v1/jobs HTTP/1.1\r\nHost: x\r\n\r\n".to_vec(), 401),
        (
            "unknown route",
            format!("GET /v2/nothing HTTP/1.1\r\nHost: x\r\n{auth}\r\n").into_bytes(),
            404,
        ),
        (
            "wrong method",
            format!("PUT /v1/jobs HTTP/1.1\r\nHost: x\r\n{auth}Content-Length: 0\r\n\r\n").into_bytes(),
            405,
        ),
        (
            "bad query",
            format!("GET /v1/jobs?limit=abc HTTP/1.1\r\nHost: x\r\n{auth}\r\n").into_bytes(),
            422,
        ),
        (
            "broken multipart",
            format!("POST /v1/jobs HTTP/1.1\r\nHost: x\r\n{auth}Content-Type: multipart/form-data; boundary=zz\r\nContent-Length: 9\r\n\r\n--zz\r\nxx\r\n").into_bytes(),
            400,
        ),
        (
            "not a cloud",
            format!("POST /v1/jobs HTTP/1.1\r\nHost: x\r\n{auth}Content-Length: 9\r\n\r\n\x00\x01\x02binary").into_bytes(),
            415,
        ),
        (
            "empty body",
            format!("POST /v1/jobs HTTP/1.1\r\nHost: x\r\n{auth}Content-Length: 0\r\n\r\n").into_bytes(),
            422,
        ),
        (
            "bad job id",
            format!("GET /v1/jobs/..%2F..%2Fetc HTTP/1.1\r\nHost: x\r\n{auth}\r\n").into_bytes(),
            404,
        ),
    ];
    let codes: Vec<&str> = asbuilt::errors::CODES.iter().map(|c| c.as_str()).collect();
    for (what, bytes, want) in cases {
        let addr = addr.clone();
        let start = Instant::now();
        let answer = tokio::task::spawn_blocking(move || raw(&addr, &bytes))
            .await
            .unwrap();
        env.took(case, what, start.elapsed());
        let status: u16 = answer
            .get(9..12)
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("{what}: no status: {answer:?}"));
        assert_eq!(status, want, "{what}: {answer}");
        let (head, body) = answer.split_once("\r\n\r\n").unwrap();
        assert!(
            head.to_ascii_lowercase()
                .contains("content-type: application/json"),
            "{what}: {head}"
        );
        let v: Value =
            serde_json::from_str(body).unwrap_or_else(|e| panic!("{what}: {e}: {body:?}"));
        let code = v["error"]["code"].as_str().unwrap();
        assert!(codes.contains(&code), "{what}: {code}");
        assert!(!v["error"]["message"].as_str().unwrap().is_empty());
        if want == 401 {
            assert!(
                head.to_ascii_lowercase()
                    .contains("www-authenticate: bearer"),
                "{head}"
            );
        }
    }
}
