//! Server processes for the tests that need a real `asbuilt serve`: start one and read the
//! address it prints, send it signals, wait for it to exit, and talk to it as one tenant.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::Value;

/// A running `asbuilt serve`, killed when dropped so a failing test leaves nothing running.
pub struct Server {
    pub child: Child,
    /// `http://127.0.0.1:PORT`
    pub base: String,
    pub data: PathBuf,
    log: Arc<Mutex<Vec<String>>>,
}

/// Starts `asbuilt serve --data-dir DATA ARGS` (on a free loopback port unless ARGS has
/// `--listen`) and waits until it listens.
pub fn serve(data: &Path, args: &[&str]) -> Server {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_asbuilt"));
    cmd.arg("serve").arg("--data-dir").arg(data).args(args);
    if !args.contains(&"--listen") {
        cmd.args(["--listen", "127.0.0.1:0"]);
    }
    let mut child = cmd
        .env("ASBUILT_LOG", "info")
        .env_remove("ASBUILT_API_KEYS")
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let (tx, rx) = mpsc::channel();
    let stderr = child.stderr.take().unwrap();
    let log = Arc::new(Mutex::new(Vec::new()));
    let keep = log.clone();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            keep.lock().unwrap().push(line.clone());
            let _ = tx.send(line);
        }
    });
    let end = Instant::now() + Duration::from_secs(30);
    let base = loop {
        let Ok(line) = rx.recv_timeout(end.saturating_duration_since(Instant::now())) else {
            let _ = child.kill();
            panic!("no listening line; log: {:#?}", log.lock().unwrap());
        };
        if let Some(at) = line.find("listening on ") {
            break line[at + "listening on ".len()..].trim().to_string();
        }
    };
    // The reader thread keeps draining the pipe; the channel's other end is dropped here.
    Server {
        child,
        base,
        data: data.to_path_buf(),
        log,
    }
}

/// Runs `asbuilt ARGS` to its end (a start that must be refused), at most `timeout`.
pub fn run_to_exit(args: &[&str], timeout: Duration) -> (Output, Duration) {
    let start = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_asbuilt"))
        .args(args)
        .env_remove("ASBUILT_API_KEYS")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    loop {
        if child.try_wait().unwrap().is_some() {
            return (child.wait_with_output().unwrap(), start.elapsed());
        }
        if start.elapsed() > timeout {
            let _ = child.kill();
            panic!(
                "`asbuilt {}` still running after {timeout:?}",
                args.join(" ")
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

impl Server {
    /// `PATH` on this server.
    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// `host:port`, for raw connections.
    pub fn addr(&self) -> String {
        self.base.trim_start_matches("http://").to_string()
    }

    /// Everything it has logged so far.
    pub fn log(&self) -> String {
        self.log.lock().unwrap().join("\n")
    }

    /// Sends SIGTERM.
    pub fn terminate(&self) {
        let ok = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .unwrap()
            .success();
        assert!(ok, "kill -TERM failed");
    }

    /// Waits for the process to exit, at most `timeout`; its status and how long it took.
    pub fn wait_exit(&mut self, timeout: Duration) -> Option<(ExitStatus, Duration)> {
        let start = Instant::now();
        while start.elapsed() < timeout {
            if let Some(status) = self.child.try_wait().unwrap() {
                return Some((status, start.elapsed()));
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        None
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// An HTTP client for one tenant's key (none in development mode).
#[derive(Clone)]
pub struct Client {
    pub http: reqwest::Client,
    pub base: String,
    pub key: Option<String>,
}

impl Client {
    pub fn new(base: &str, key: Option<&str>) -> Client {
        Client {
            http: reqwest::Client::new(),
            base: base.to_string(),
            key: key.map(str::to_string),
        }
    }

    pub fn req(&self, method: reqwest::Method, path: &str) -> reqwest::RequestBuilder {
        let r = self.http.request(method, format!("{}{path}", self.base));
        match &self.key {
            Some(k) => r.bearer_auth(k),
            None => r,
        }
    }

    pub async fn get_json(&self, path: &str) -> Value {
        let res = self.req(reqwest::Method::GET, path).send().await.unwrap();
        assert!(res.status().is_success(), "GET {path}: {}", res.status());
        res.json().await.unwrap()
    }

    /// Uploads `body` raw; the answer's status and JSON.
    pub async fn upload(&self, query: &str, body: String) -> (u16, Value) {
        let res = self
            .req(reqwest::Method::POST, &format!("/v1/jobs{query}"))
            .body(body)
            .send()
            .await
            .unwrap();
        let status = res.status().as_u16();
        (status, res.json().await.unwrap_or(Value::Null))
    }

    /// The job as `GET /v1/jobs/{id}` shows it.
    pub async fn job(&self, id: &str) -> Value {
        self.get_json(&format!("/v1/jobs/{id}")).await
    }

    /// Every job of this tenant (up to 100), newest first.
    pub async fn jobs(&self) -> Vec<Value> {
        self.get_json("/v1/jobs?limit=100").await["jobs"]
            .as_array()
            .unwrap()
            .clone()
    }
}

/// A small cloud for the fake pipeline: `n` points, and any marker lines (`#hang:5`).
pub fn fake_cloud(n: usize, markers: &[&str]) -> String {
    let mut text: String = (0..n).map(|i| format!("{i} {i} {i}\n")).collect();
    for m in markers {
        text.push_str(m);
        text.push('\n');
    }
    text
}
