//! Scale-out across processes: 1 API process and 3 worker processes share PostgreSQL and S3.
//! 30 jobs go in; one worker is SIGKILLed in the middle of a job and replaced. Every job must
//! succeed with a valid result, no job may run to completion twice, and deleting the jobs must
//! leave nothing in storage.
//!
//! The workers run the service's synthetic pipeline (`--fake-pipeline-ms`): a fixed time per
//! stage, a plan made by the real writers, and a log line per completed run, which is how
//! completions are counted. Needs `ASBUILT_TEST_POSTGRES` and `ASBUILT_TEST_S3_ENDPOINT`.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::support::engines::{engines, unique, Engines};
use futures_util::TryStreamExt;
use object_store::ObjectStore;
use sqlx::Row;

const JOBS: usize = 30;
const STAGE_MS: &str = "250";

/// A child process, killed when dropped so a failing test leaves nothing running.
struct Proc {
    child: Child,
    data_dir: PathBuf,
    log: PathBuf,
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

struct Cluster {
    engines: Engines,
    schema: String,
    database: String,
    storage: String,
    bucket: String,
    prefix: String,
    root: tempfile::TempDir,
}

impl Cluster {
    /// Starts a process on a port of its own choosing: a port picked free here could be taken
    /// by a parallel test before the child binds it.
    fn spawn(&self, name: &str, role: &[&str]) -> Proc {
        let data_dir = self.root.path().join(name);
        std::fs::create_dir_all(&data_dir).unwrap();
        let log_path = self.root.path().join(format!("{name}.log"));
        let log = std::fs::File::create(&log_path).unwrap();
        let child = Command::new(env!("CARGO_BIN_EXE_asbuilt"))
            .args(role)
            .args(["--listen", "127.0.0.1:0"])
            .arg("--data-dir")
            .arg(&data_dir)
            .args(["--database-url", &self.database])
            .args(["--storage", &self.storage])
            .args(["--lease", "1", "--workers", "1"])
            .args(["--fake-pipeline-ms", STAGE_MS])
            .envs(self.engines.s3_env())
            .env("RUST_LOG", "info")
            .stdin(Stdio::null())
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .spawn()
            .expect("starting asbuilt");
        Proc {
            child,
            data_dir,
            log: log_path,
        }
    }

    fn logs(&self) -> String {
        let mut out = String::new();
        for entry in std::fs::read_dir(self.root.path()).unwrap().flatten() {
            let p = entry.path();
            if p.extension().is_some_and(|e| e == "log") {
                out.push_str(&format!("--- {}\n", p.display()));
                out.push_str(&std::fs::read_to_string(&p).unwrap_or_default());
            }
        }
        out
    }

    async fn pg(&self) -> sqlx::PgPool {
        sqlx::postgres::PgPoolOptions::new()
            .max_connections(2)
            .connect(&self.database)
            .await
            .unwrap()
    }

    /// Every object under the test's prefix.
    async fn objects(&self) -> Vec<String> {
        let s3 = object_store::aws::AmazonS3Builder::new()
            .with_endpoint(&self.engines.s3_endpoint)
            .with_allow_http(true)
            .with_region("us-east-1")
            .with_access_key_id("asbuilt-test")
            .with_secret_access_key("asbuilt-test")
            .with_bucket_name(&self.bucket)
            .build()
            .unwrap();
        let prefix = object_store::path::Path::from(self.prefix.as_str());
        s3.list(Some(&prefix))
            .map_ok(|m| m.location.to_string())
            .try_collect()
            .await
            .unwrap()
    }
}

/// Waits until the process has printed the port it listens on and answers ready there;
/// returns the port.
async fn wait_ready(http: &reqwest::Client, proc: &mut Proc, cluster: &Cluster) -> u16 {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        if let Some(port) = listening_port(&proc.log) {
            let url = format!("http://127.0.0.1:{port}/readyz");
            if let Ok(r) = http.get(&url).send().await {
                if r.status().is_success() {
                    return port;
                }
            }
        }
        if let Some(status) = proc.child.try_wait().unwrap() {
            panic!(
                "{} exited ({status}) before it was ready\n{}",
                proc.log.display(),
                cluster.logs()
            );
        }
        assert!(
            Instant::now() < deadline,
            "{} never became ready\n{}",
            proc.log.display(),
            cluster.logs()
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// The port in the process's `listening on http://127.0.0.1:PORT` line, once printed.
fn listening_port(log: &std::path::Path) -> Option<u16> {
    let text = std::fs::read_to_string(log).ok()?;
    let line = text.lines().find(|l| l.contains("listening on http://"))?;
    let after = &line[line.find("127.0.0.1:")? + "127.0.0.1:".len()..];
    let digits: String = after.chars().take_while(char::is_ascii_digit).collect();
    digits.parse().ok()
}

/// A small XYZ cloud; the synthetic pipeline counts its lines as points.
fn cloud(i: usize) -> String {
    (0..50)
        .map(|k| format!("{}.{} {}.5 1.25\n", k % 7, i, k % 5))
        .collect()
}

/// Reads the synthetic pipeline's completion logs: job id → completed runs.
fn completions(dirs: &[PathBuf]) -> BTreeMap<String, usize> {
    let mut runs = BTreeMap::new();
    for dir in dirs {
        let text = std::fs::read_to_string(dir.join("fake-completions.log")).unwrap_or_default();
        for id in text.lines().map(str::trim).filter(|l| !l.is_empty()) {
            *runs.entry(id.to_string()).or_insert(0) += 1;
        }
    }
    runs
}

/// The pid in a lease owner (`<pid>-<uuid>/<task>`).
fn owner_pid(owner: &str) -> u32 {
    owner.split('-').next().unwrap().parse().unwrap()
}

fn check_geojson(body: &str) {
    let v: serde_json::Value = serde_json::from_str(body).expect("plan.geojson is JSON");
    assert_eq!(v["type"], "FeatureCollection");
    let features = v["features"].as_array().expect("features");
    let mut rings = 0;
    for f in features {
        if f["geometry"]["type"] == "Polygon" {
            for ring in f["geometry"]["coordinates"].as_array().unwrap() {
                let ring = ring.as_array().unwrap();
                assert!(ring.len() >= 4, "a ring needs 4 positions");
                assert_eq!(ring.first(), ring.last(), "an open ring");
                rings += 1;
            }
        }
    }
    assert!(rings > 0, "no polygon in {body}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_api_three_workers_survive_a_killed_worker() {
    let Some(engines) = engines("scale_out") else {
        return;
    };
    let schema = engines.new_schema("scale").await;
    let bucket = "asbuilt-scale".to_string();
    engines.ensure_bucket(&bucket).await;
    let prefix = unique("run");
    let cluster = Cluster {
        database: engines.url_in(&schema),
        storage: format!("s3://{bucket}/{prefix}"),
        engines: engines.clone(),
        schema,
        bucket,
        prefix,
        root: tempfile::tempdir().unwrap(),
    };
    let status = Command::new(env!("CARGO_BIN_EXE_asbuilt"))
        .args(["migrate", "--database-url", &cluster.database])
        .status()
        .unwrap();
    assert!(status.success(), "asbuilt migrate failed");

    let http = reqwest::Client::builder()
        .timeout(Duration::from_secs(20))
        .build()
        .unwrap();
    let mut api = cluster.spawn("api", &["serve", "--no-workers"]);
    let mut workers: Vec<Proc> = (0..3)
        .map(|w| cluster.spawn(&format!("worker{w}"), &["worker"]))
        .collect();
    let api_port = wait_ready(&http, &mut api, &cluster).await;
    for w in &mut workers {
        wait_ready(&http, w, &cluster).await;
    }
    let api = format!("http://127.0.0.1:{api_port}");

    let mut ids = vec![];
    for i in 0..JOBS {
        let r = http
            .post(format!("{api}/v1/jobs?filename=scan{i}.xyz"))
            .body(cloud(i))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status().as_u16(), 202, "{}", r.text().await.unwrap());
        let job: serde_json::Value = r.json().await.unwrap();
        ids.push(job["id"].as_str().unwrap().to_string());
    }

    // Kill a worker while its job is in an early stage, so the run cannot have completed.
    let pg = cluster.pg().await;
    let deadline = Instant::now() + Duration::from_secs(60);
    let (victim, victim_job) = loop {
        let rows = sqlx::query(
            "SELECT id::text AS id, lease_owner, stage FROM jobs WHERE status = 'running' \
             AND (stage IS NULL OR stage IN ('read', 'stories'))",
        )
        .fetch_all(&pg)
        .await
        .unwrap();
        if let Some(row) = rows.first() {
            let owner: String = row.get("lease_owner");
            let pid = owner_pid(&owner);
            if let Some(i) = workers.iter().position(|p| p.child.id() == pid) {
                break (i, row.get::<String, _>("id"));
            }
        }
        assert!(
            Instant::now() < deadline,
            "no job started\n{}",
            cluster.logs()
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    workers[victim].child.kill().unwrap(); // SIGKILL
    workers[victim].child.wait().unwrap();
    workers.push(cluster.spawn("worker3", &["worker"]));
    let replacement = workers.last_mut().unwrap();
    wait_ready(&http, replacement, &cluster).await;

    // Every job succeeds.
    let deadline = Instant::now() + Duration::from_secs(180);
    for id in &ids {
        loop {
            let job: serde_json::Value = http
                .get(format!("{api}/v1/jobs/{id}"))
                .send()
                .await
                .unwrap()
                .json()
                .await
                .unwrap();
            match job["status"].as_str().unwrap() {
                "succeeded" => break,
                "queued" | "running" => {}
                other => panic!("job {id} {other}: {job}\n{}", cluster.logs()),
            }
            assert!(
                Instant::now() < deadline,
                "job {id} still {}\n{}",
                job["status"],
                cluster.logs()
            );
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    }

    // The killed worker's job was retried; no job ran to completion twice.
    let attempts: i32 = sqlx::query_scalar("SELECT attempts FROM jobs WHERE id = $1::uuid")
        .bind(&victim_job)
        .fetch_one(&pg)
        .await
        .unwrap();
    assert!(attempts >= 2, "the killed job was not retried ({attempts})");
    let dirs: Vec<PathBuf> = workers.iter().map(|p| p.data_dir.clone()).collect();
    let runs = completions(&dirs);
    assert_eq!(runs.len(), JOBS, "completed jobs: {runs:?}");
    for id in &ids {
        assert_eq!(
            runs.get(id),
            Some(&1),
            "job {id} completed {:?} times",
            runs.get(id)
        );
    }
    // Every process saw work: the queue was shared, not drained by one worker.
    let per_worker: Vec<usize> = dirs
        .iter()
        .map(|d| completions(std::slice::from_ref(d)).values().sum())
        .collect();
    eprintln!("completions per worker (worker0-2, replacement): {per_worker:?}");
    let busy = per_worker.iter().filter(|&&n| n > 0).count();
    assert!(
        busy >= 3,
        "only {busy} workers completed jobs: {per_worker:?} (worker0-2, replacement)\n{}",
        cluster.logs()
    );

    // Each result is valid.
    for id in &ids {
        let geojson = http
            .get(format!("{api}/v1/jobs/{id}/plan.geojson"))
            .send()
            .await
            .unwrap();
        assert_eq!(geojson.status().as_u16(), 200);
        check_geojson(&geojson.text().await.unwrap());
        let svg = http
            .get(format!("{api}/v1/jobs/{id}/plan.svg"))
            .send()
            .await
            .unwrap();
        let svg = svg.text().await.unwrap();
        assert!(
            svg.contains("<svg") && svg.trim_end().ends_with("</svg>"),
            "{id}: svg"
        );
        let dxf = http
            .get(format!("{api}/v1/jobs/{id}/plan.dxf"))
            .send()
            .await
            .unwrap();
        let dxf = dxf.text().await.unwrap();
        assert!(
            dxf.contains("SECTION") && dxf.trim_end().ends_with("EOF"),
            "{id}: dxf"
        );
    }

    // Queue depth by status, read from the shared database, is on /metrics.
    let metrics = http.get(format!("{api}/metrics")).send().await.unwrap();
    let metrics = metrics.text().await.unwrap();
    assert!(
        metrics.contains(&format!("asbuilt_jobs{{status=\"succeeded\"}} {JOBS}")),
        "{metrics}"
    );
    assert!(metrics.contains("asbuilt_queue_depth 0"), "{metrics}");

    // Deleting the jobs leaves nothing in storage or in the database.
    assert!(!cluster.objects().await.is_empty());
    for id in &ids {
        let r = http
            .delete(format!("{api}/v1/jobs/{id}"))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status().as_u16(), 204);
    }
    let left = cluster.objects().await;
    assert!(left.is_empty(), "left in storage: {left:?}");
    let rows: i64 = sqlx::query_scalar("SELECT count(*) FROM jobs")
        .fetch_one(&pg)
        .await
        .unwrap();
    assert_eq!(rows, 0);

    pg.close().await;
    drop(workers);
    drop(api);
    cluster.engines.drop_schema(&cluster.schema).await;
}

/// A serving process or worker refuses to start on a database nobody migrated, naming the
/// command that fixes it; after `asbuilt migrate` it starts.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn processes_refuse_an_unmigrated_database() {
    let Some(engines) = engines("processes_refuse_an_unmigrated_database") else {
        return;
    };
    let schema = engines.new_schema("unmigrated").await;
    let database = engines.url_in(&schema);
    let data = tempfile::tempdir().unwrap();
    for role in [&["serve", "--no-workers"][..], &["worker"]] {
        let out = Command::new(env!("CARGO_BIN_EXE_asbuilt"))
            .args(role)
            .args(["--listen", "127.0.0.1:0", "--database-url", &database])
            .arg("--data-dir")
            .arg(data.path())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{role:?} started: {err}");
        assert!(err.contains("run `asbuilt migrate`"), "{role:?}: {err}");
    }
    let status = Command::new(env!("CARGO_BIN_EXE_asbuilt"))
        .args(["migrate", "--database-url", &database])
        .status()
        .unwrap();
    assert!(status.success());
    let config = asbuilt::config::Config {
        listen: "127.0.0.1:0".parse().unwrap(),
        data_dir: data.path().to_path_buf(),
        database_url: Some(database),
        workers: 0,
        ..Default::default()
    };
    config.check().unwrap();
    let pipeline = asbuilt::app::pipeline_for(&config);
    let running = asbuilt::app::start(config, pipeline).await.unwrap();
    running.stop().await.unwrap();
    engines.drop_schema(&schema).await;
}

/// With `--presign`, results are answered as redirects to pre-signed S3 URLs that fetch the
/// same bytes without credentials; without it they stream through the API.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn results_redirect_to_presigned_urls_when_configured() {
    let Some(engines) = engines("results_redirect_to_presigned_urls_when_configured") else {
        return;
    };
    let schema = engines.new_schema("presign").await;
    let database = engines.url_in(&schema);
    let migrated = Command::new(env!("CARGO_BIN_EXE_asbuilt"))
        .args(["migrate", "--database-url", &database])
        .status()
        .unwrap();
    assert!(migrated.success());
    engines.ensure_bucket("asbuilt-suite").await;
    let prefix = unique("presign");
    let data = tempfile::tempdir().unwrap();
    let s3 = engines.s3_options();
    let config = asbuilt::config::Config {
        listen: "127.0.0.1:0".parse().unwrap(),
        data_dir: data.path().to_path_buf(),
        database_url: Some(database),
        storage: Some(format!("s3://asbuilt-suite/{prefix}")),
        s3_endpoint: s3.endpoint,
        s3_region: s3.region,
        s3_access_key_id: s3.access_key_id,
        s3_secret_access_key: s3.secret_access_key,
        s3_allow_http: true,
        presign_secs: 60,
        workers: 1,
        lease_secs: 2,
        fake_pipeline_ms: Some(1),
        ..Default::default()
    };
    let pipeline = asbuilt::app::pipeline_for(&config);
    let running = asbuilt::app::start(config, pipeline).await.unwrap();
    let base = format!("http://{}", running.addr);
    let http = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .unwrap();
    let job: serde_json::Value = http
        .post(format!("{base}/v1/jobs"))
        .body(cloud(1))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let id = job["id"].as_str().unwrap().to_string();
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let job: serde_json::Value = http
            .get(format!("{base}/v1/jobs/{id}"))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        if job["status"] == "succeeded" {
            break;
        }
        assert!(
            job["status"] == "queued" || job["status"] == "running",
            "{job}"
        );
        assert!(Instant::now() < deadline, "{job}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    for file in asbuilt_plan::io::outputs::OUTPUTS.iter().map(|o| o.file) {
        let res = http
            .get(format!("{base}/v1/jobs/{id}/{file}"))
            .send()
            .await
            .unwrap();
        assert_eq!(res.status().as_u16(), 307, "{file}");
        let url = res.headers()["location"].to_str().unwrap().to_string();
        assert!(
            url.contains("X-Amz-Signature=") && url.contains(&prefix),
            "{url}"
        );
        let direct = reqwest::get(&url).await.unwrap();
        assert_eq!(direct.status().as_u16(), 200, "{url}");
        let body = direct.text().await.unwrap();
        match file {
            "plan.geojson" => check_geojson(&body),
            "plan.svg" => assert!(body.contains("<svg")),
            "plan.dxf" => assert!(body.trim_end().ends_with("EOF")),
            "plan.ifc" => assert!(body.trim_end().ends_with("END-ISO-10303-21;")),
            "rooms.csv" => assert!(body.starts_with("level,room,")),
            // A format added to the list is at least served whole.
            _ => assert!(!body.is_empty(), "{file}"),
        }
    }
    // A job that has no result yet is still refused by the API, not redirected.
    let missing = asbuilt::queue::JobId::new();
    let res = http
        .get(format!("{base}/v1/jobs/{missing}/plan.svg"))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status().as_u16(), 404);
    let res = http
        .delete(format!("{base}/v1/jobs/{id}"))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status().as_u16(), 204);
    running.stop().await.unwrap();
    engines.drop_schema(&schema).await;
}
