//! The `asbuilt serve` process: durability across SIGKILL, development mode, `migrate`.

use std::process::Command;
use std::time::{Duration, Instant};

use crate::support::process::serve;
use serde_json::Value;

fn get(url: &str) -> Value {
    reqwest::blocking_get(url)
}

mod reqwest {
    //! A tiny blocking client over the async one, for these process tests.
    pub fn blocking_get(url: &str) -> serde_json::Value {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async { ::reqwest::get(url).await.unwrap().json().await.unwrap() })
    }

    pub fn blocking_post(url: &str, body: String) -> serde_json::Value {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async {
            let res = ::reqwest::Client::new()
                .post(url)
                .body(body)
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 202);
            res.json().await.unwrap()
        })
    }
}

fn statuses(base: &str) -> Vec<String> {
    let page = get(&format!("{base}/v1/jobs?limit=100"));
    page["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j["status"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn queued_jobs_survive_sigkill_and_run_exactly_once() {
    let dir = tempfile::tempdir().unwrap();
    // Seven stages of 250 ms: each job runs ~1.75 s; two workers; 2 s leases.
    let args = [
        "--workers",
        "2",
        "--lease",
        "2",
        "--fake-pipeline-ms",
        "250",
    ];
    let mut first = serve(dir.path(), &args);
    let mut ids = vec![];
    for i in 0..5 {
        let job = reqwest::blocking_post(
            &format!("{}/v1/jobs", first.base),
            format!("{i} 0 0\n1 1 1\n2 2 2\n"),
        );
        ids.push(job["id"].as_str().unwrap().to_string());
    }
    // Kill while work is in flight: some jobs done, some running, some queued. The running
    // ones must be in an early stage: a kill after a pipeline has finished but before its
    // results are committed rightly runs it again, which this test would count twice.
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        let page = get(&format!("{}/v1/jobs?limit=100", first.base));
        let jobs = page["jobs"].as_array().unwrap();
        let early = |j: &serde_json::Value| {
            matches!(j["stage"].as_str(), Some("read" | "stories" | "samples"))
        };
        let running: Vec<_> = jobs.iter().filter(|j| j["status"] == "running").collect();
        if jobs.iter().any(|j| j["status"] == "succeeded")
            && !running.is_empty()
            && running.iter().all(|j| early(j))
        {
            break;
        }
        assert!(Instant::now() < end, "no progress: {jobs:?}");
        std::thread::sleep(Duration::from_millis(50));
    }
    first.child.kill().unwrap(); // SIGKILL
    first.child.wait().unwrap();

    let mut second = serve(dir.path(), &args);
    let end = Instant::now() + Duration::from_secs(60);
    loop {
        let s = statuses(&second.base);
        if s.len() == 5 && s.iter().all(|x| x == "succeeded") {
            break;
        }
        assert!(!s.iter().any(|x| x == "failed"), "{s:?}");
        assert!(Instant::now() < end, "not all succeeded: {s:?}");
        std::thread::sleep(Duration::from_millis(100));
    }
    second.child.kill().unwrap();
    second.child.wait().unwrap();
    let log = std::fs::read_to_string(dir.path().join("fake-completions.log")).unwrap();
    let mut done: Vec<&str> = log.lines().collect();
    done.sort();
    let mut expected: Vec<&str> = ids.iter().map(String::as_str).collect();
    expected.sort();
    assert_eq!(done, expected, "every job ran to completion exactly once");
}

#[test]
fn without_keys_it_binds_loopback_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let mut p = serve(dir.path(), &["--listen", "0.0.0.0:0", "--workers", "0"]);
    assert!(p.base.starts_with("http://127.0.0.1:"), "{}", p.base);
    assert_eq!(get(&format!("{}/healthz", p.base))["status"], "ok");
    p.child.kill().unwrap();
    p.child.wait().unwrap();
    let log = p.log();
    assert!(
        log.contains("development mode binds to loopback only"),
        "{log}"
    );
}

#[test]
fn migrate_creates_the_database_and_is_idempotent() {
    let dir = tempfile::tempdir().unwrap();
    for _ in 0..2 {
        let out = Command::new(env!("CARGO_BIN_EXE_asbuilt"))
            .args(["migrate", "--data-dir"])
            .arg(dir.path())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(String::from_utf8_lossy(&out.stderr).contains("migrated"));
    }
    assert!(dir.path().join("asbuilt.db").is_file());
}

#[test]
fn bad_settings_are_refused_naming_the_setting() {
    let out = Command::new(env!("CARGO_BIN_EXE_asbuilt"))
        .args(["serve", "--api-key", "acme:tinykey", "--data-dir"])
        .arg(tempfile::tempdir().unwrap().path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("tenant `acme`") && err.contains("16"), "{err}");
    assert!(
        !err.contains("tinykey"),
        "the key itself is not echoed: {err}"
    );
}
