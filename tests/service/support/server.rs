//! The service in process: a server on a free port with a temporary data directory.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use asbuilt::app::{self, Running};
use asbuilt::config::Config;
use asbuilt::worker::pipeline::Pipeline;
use serde_json::Value;

pub struct Server {
    pub base: String,
    pub running: Option<Running>,
    pub dir: tempfile::TempDir,
    pub client: reqwest::Client,
    pub key: Option<String>,
}

/// Test settings: a free loopback port, a temporary data dir, short leases.
pub fn config(dir: &std::path::Path) -> Config {
    Config {
        listen: "127.0.0.1:0".parse().unwrap(),
        data_dir: dir.to_path_buf(),
        workers: 2,
        lease_secs: 2,
        shutdown_timeout_secs: 5,
        // These tests poll fast; the limits have tests of their own (the `hostile` module).
        rate_limit: 0.0,
        ..Config::default()
    }
}

pub async fn start(pipeline: Arc<dyn Pipeline>, tweak: impl FnOnce(&mut Config)) -> Server {
    let dir = tempfile::tempdir().unwrap();
    let mut c = config(dir.path());
    tweak(&mut c);
    let key = c
        .api_keys
        .first()
        .map(|k| k.split_once(':').unwrap().1.to_string());
    let running = app::start(c, pipeline).await.unwrap();
    Server {
        base: format!("http://{}", running.addr),
        running: Some(running),
        dir,
        client: reqwest::Client::new(),
        key,
    }
}

impl Server {
    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    pub fn get(&self, path: &str) -> reqwest::RequestBuilder {
        self.auth(self.client.get(self.url(path)))
    }

    pub fn post(&self, path: &str) -> reqwest::RequestBuilder {
        self.auth(self.client.post(self.url(path)))
    }

    pub fn delete(&self, path: &str) -> reqwest::RequestBuilder {
        self.auth(self.client.delete(self.url(path)))
    }

    fn auth(&self, r: reqwest::RequestBuilder) -> reqwest::RequestBuilder {
        match &self.key {
            Some(k) => r.bearer_auth(k),
            None => r,
        }
    }

    /// Uploads `body` raw; returns the 202 job.
    pub async fn upload(&self, body: impl Into<reqwest::Body>) -> Value {
        let res = self.post("/v1/jobs").body(body).send().await.unwrap();
        assert_eq!(res.status(), 202, "{:?}", res.text().await);
        res.json().await.unwrap()
    }

    pub async fn job(&self, id: &str) -> Value {
        let res = self.get(&format!("/v1/jobs/{id}")).send().await.unwrap();
        assert_eq!(res.status(), 200);
        res.json().await.unwrap()
    }

    /// Polls until the job reaches a terminal status.
    pub async fn wait_done(&self, id: &str, within: Duration) -> Value {
        let end = Instant::now() + within;
        loop {
            let job = self.job(id).await;
            if ["succeeded", "failed", "cancelled"].contains(&job["status"].as_str().unwrap()) {
                return job;
            }
            assert!(
                Instant::now() < end,
                "job still {} after {within:?}",
                job["status"]
            );
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }

    pub fn blobs(&self) -> PathBuf {
        self.dir.path().join("blobs")
    }

    pub async fn stop(&mut self) {
        if let Some(r) = self.running.take() {
            r.stop().await.unwrap();
        }
    }
}

/// A small XYZ cloud of `n` points (the fake pipeline counts lines).
pub fn xyz(n: usize) -> String {
    (0..n)
        .map(|i| format!("{}.0 {}.5 1.25\n", i % 7, i % 5))
        .collect()
}

/// Asserts an error response's status, code and (optionally) param.
pub async fn expect_error(res: reqwest::Response, status: u16, code: &str) -> Value {
    assert_eq!(res.status().as_u16(), status);
    let body: Value = res.json().await.unwrap();
    assert_eq!(body["error"]["code"], code, "{body}");
    assert!(body["error"]["message"]
        .as_str()
        .is_some_and(|m| !m.is_empty()));
    body
}

/// Why the browser test cannot run here, if it cannot: node, chromium or the npm packages
/// missing. Under CI (`CI` set) that is a failure, not a skip.
pub fn browser_missing() -> Option<String> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser");
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    let why = if std::process::Command::new("node")
        .arg("--version")
        .output()
        .is_err()
    {
        Some("node is not installed".to_string())
    } else if !std::path::Path::new(&chromium).exists() {
        Some(format!("{chromium} is not installed"))
    } else if !dir.join("node_modules/playwright-core").is_dir() {
        Some("tests/browser/node_modules is missing (run .ci/install-service-deps.sh)".into())
    } else {
        None
    };
    if let Some(why) = &why {
        assert!(
            std::env::var_os("CI").is_none(),
            "browser test cannot run under CI: {why}"
        );
        eprintln!("skipping the browser test: {why}");
    }
    why
}

/// Uploads `cloud` through the page at `base` in headless chromium and saves a screenshot.
/// Returns what the page showed (the script's checks already passed).
pub async fn browser_upload(
    base: &str,
    cloud: &std::path::Path,
    poses: Option<&std::path::Path>,
    shot: &std::path::Path,
    key: Option<&str>,
) -> Value {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser");
    let mut cmd = tokio::process::Command::new("node");
    cmd.current_dir(&dir)
        .arg("upload.mjs")
        .arg(base)
        .arg(cloud)
        .arg(shot);
    if let Some(k) = key {
        cmd.arg(k);
    }
    if let Some(p) = poses {
        cmd.env("POSES", p);
    }
    let out = tokio::time::timeout(Duration::from_secs(180), cmd.output())
        .await
        .expect("browser run timed out")
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "browser checks failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(stdout.lines().last().unwrap_or_default()).unwrap()
}

/// Reads a DXF with ezdxf, the independent Python DXF library, and summarises it: version,
/// `$INSUNITS`, layers, audit errors, and entity counts by `TYPE@LAYER`. `None` (after saying
/// why) when python3 with ezdxf is missing, except under CI, where that fails.
pub fn ezdxf_summary(dxf: &[u8]) -> Option<Value> {
    let probe = std::process::Command::new("python3")
        .args(["-c", "import ezdxf"])
        .output();
    if !probe.is_ok_and(|o| o.status.success()) {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must have python3 with ezdxf (pip install ezdxf)"
        );
        eprintln!("skipping the ezdxf check: python3 with ezdxf is not available");
        return None;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plan.dxf");
    std::fs::write(&path, dxf).unwrap();
    let script = r#"
import json, sys, ezdxf
doc = ezdxf.readfile(sys.argv[1])
auditor = doc.audit()
counts = {}
for e in doc.modelspace():
    key = e.dxftype() + "@" + e.dxf.layer
    counts[key] = counts.get(key, 0) + 1
print(json.dumps({
    "version": doc.dxfversion,
    "insunits": doc.header.get("$INSUNITS"),
    "layers": sorted(l.dxf.name for l in doc.layers),
    "errors": len(auditor.errors),
    "counts": counts,
    "arc_radii": [a.dxf.radius for a in doc.modelspace().query("ARC")],
}))
"#;
    let out = std::process::Command::new("python3")
        .args(["-c", script])
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "ezdxf could not read the DXF: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(serde_json::from_slice(&out.stdout).unwrap())
}
