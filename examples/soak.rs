//! A soak benchmark: mixed traffic against an API process and worker processes sharing a
//! PostgreSQL schema and a blob directory, for a set time, then an account of every job.
//!
//! ```sh
//! cargo build --release --bin asbuilt --example soak
//! ASBUILT_TEST_POSTGRES=postgres://postgres@127.0.0.1:5432/test \
//!   nice target/release/examples/soak --bin target/release/asbuilt --minutes 30 --workers 2
//! ```
//!
//! Traffic: uploads of real scans (`../shared/data/real`) and of bad files (garbage, a cut PLY,
//! parameters out of range, an upload that stalls), status polling at `--poll-rate` requests a
//! second, deletes of running, queued and finished jobs, and a worker process killed with
//! SIGKILL (and restarted) every `--kill-every` seconds. Then the traffic stops, the queue
//! drains, and it counts: jobs lost (accepted, not deleted, and not finished), jobs completed
//! more than once (`job succeeded` in the worker logs), blobs left for jobs that no longer
//! exist, and each process's resident memory over time.

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::Value;
use sqlx::Connection;

const KEYS: [(&str, &str); 2] = [
    ("acme", "soak-acme-key-000000001"),
    ("bolt", "soak-bolt-key-000000002"),
];

struct Args {
    bin: PathBuf,
    minutes: f64,
    workers: usize,
    poll_rate: u64,
    kill_every: u64,
    upload_every_ms: u64,
}

fn args() -> Args {
    let mut a = Args {
        bin: PathBuf::from("target/release/asbuilt"),
        minutes: 30.0,
        workers: 2,
        poll_rate: 200,
        kill_every: 120,
        upload_every_ms: 1500,
    };
    let v: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < v.len() {
        let next = v.get(i + 1).cloned().unwrap_or_default();
        match v[i].as_str() {
            "--bin" => a.bin = next.into(),
            "--minutes" => a.minutes = next.parse().expect("--minutes"),
            "--workers" => a.workers = next.parse().expect("--workers"),
            "--poll-rate" => a.poll_rate = next.parse().expect("--poll-rate"),
            "--kill-every" => a.kill_every = next.parse().expect("--kill-every"),
            "--upload-every-ms" => a.upload_every_ms = next.parse().expect("--upload-every-ms"),
            other => panic!("unknown argument {other}"),
        }
        i += 2;
    }
    a
}

/// A child process whose log is kept.
struct Proc {
    name: String,
    child: Child,
    log: Arc<Mutex<Vec<String>>>,
}

impl Proc {
    fn spawn(bin: &Path, name: &str, args: &[String]) -> Proc {
        let mut child = Command::new(bin)
            .args(args)
            .env("ASBUILT_LOG", "info")
            .stderr(Stdio::piped())
            .stdout(Stdio::null())
            .spawn()
            .expect("starting asbuilt");
        let log = Arc::new(Mutex::new(Vec::new()));
        let keep = log.clone();
        let stderr = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                keep.lock().unwrap().push(line);
            }
        });
        Proc {
            name: name.to_string(),
            child,
            log,
        }
    }

    fn rss_kb(&self) -> Option<u64> {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).ok()?;
        status
            .lines()
            .find(|l| l.starts_with("VmRSS:"))?
            .split_whitespace()
            .nth(1)?
            .parse()
            .ok()
    }

    fn terminate(&mut self) {
        // A killed worker is already gone; `kill` would only say so.
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .stderr(Stdio::null())
            .status();
        let end = Instant::now() + Duration::from_secs(60);
        while Instant::now() < end {
            if self.child.try_wait().ok().flatten().is_some() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[derive(Default)]
struct Tally {
    /// Jobs accepted (202), by id, with their tenant.
    accepted: BTreeMap<String, usize>,
    /// Jobs deleted by us (204).
    deleted: BTreeSet<String>,
    refused: BTreeMap<u16, u64>,
    uploads: u64,
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    let a = args();
    let pg = std::env::var("ASBUILT_TEST_POSTGRES").expect("ASBUILT_TEST_POSTGRES");
    let schema = format!("soak_{}", std::process::id());
    let mut conn = sqlx::PgConnection::connect(&pg).await.unwrap();
    sqlx::query(&format!("CREATE SCHEMA \"{schema}\""))
        .execute(&mut conn)
        .await
        .unwrap();
    let db = format!("{pg}?options=-c%20search_path%3D{schema}");
    let dir = tempfile::tempdir().unwrap();
    let blobs = dir.path().join("blobs");
    let bin = a.bin.canonicalize().expect("--bin");
    let shared: Vec<String> = vec![
        "--database-url".into(),
        db.clone(),
        "--storage".into(),
        blobs.display().to_string(),
        "--api-key".into(),
        KEYS.iter()
            .map(|(t, k)| format!("{t}:{k}"))
            .collect::<Vec<_>>()
            .join(","),
        "--lease".into(),
        "5".into(),
        "--max-attempts".into(),
        "5".into(),
        "--job-timeout".into(),
        "120".into(),
        "--rate-limit".into(),
        "1000".into(),
        "--rate-burst".into(),
        "500".into(),
        "--upload-idle-timeout".into(),
        "3".into(),
    ];
    let root = dir.path().to_path_buf();
    let common = move |data: &str| -> Vec<String> {
        let mut v = shared.clone();
        v.extend(["--data-dir".into(), root.join(data).display().to_string()]);
        v
    };
    let out = Command::new(&bin)
        .arg("migrate")
        .args(["--database-url", &db])
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let port = free_port();
    let mut api_args = vec!["serve".to_string(), "--no-workers".into()];
    api_args.extend(common("api"));
    api_args.extend(["--listen".into(), format!("127.0.0.1:{port}")]);
    let api = Arc::new(Mutex::new(Proc::spawn(&bin, "api", &api_args)));
    let worker_args = move |i: usize| {
        let mut w = vec!["worker".to_string()];
        w.extend(common(&format!("worker{i}")));
        w.extend([
            "--workers".into(),
            "1".into(),
            "--listen".into(),
            format!("127.0.0.1:{}", free_port()),
        ]);
        w
    };
    let workers: Arc<Mutex<Vec<Proc>>> = Arc::new(Mutex::new(
        (0..a.workers)
            .map(|i| Proc::spawn(&bin, &format!("worker{i}"), &worker_args(i)))
            .collect(),
    ));
    let base = format!("http://127.0.0.1:{port}");
    let http = reqwest::Client::builder()
        .timeout(Duration::from_secs(30))
        .build()
        .unwrap();
    // Up?
    let up = Instant::now();
    while http.get(format!("{base}/readyz")).send().await.is_err() {
        assert!(
            up.elapsed() < Duration::from_secs(30),
            "the API did not start"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }

    let real = real_files();
    let bad_ply = {
        let mut b = std::fs::read(&real[0].1).unwrap();
        b.truncate(b.len() / 3);
        b
    };
    let tally = Arc::new(Mutex::new(Tally::default()));
    let end = Instant::now() + Duration::from_secs_f64(a.minutes * 60.0);
    let polls = Arc::new(AtomicU64::new(0));
    let poll_errors = Arc::new(AtomicU64::new(0));
    let mut tasks = vec![];

    // Uploads: mostly real scans, now and then a bad one.
    {
        let (http, base, tally) = (http.clone(), base.clone(), tally.clone());
        let every = a.upload_every_ms;
        tasks.push(tokio::spawn(async move {
            let mut n = 0u64;
            while Instant::now() < end {
                n += 1;
                let (tenant, key) = KEYS[(n % 2) as usize];
                let kind = n % 10;
                let (query, body): (&str, Vec<u8>) = match kind {
                    0 => ("", b"\x00\x01\x02 not a point cloud".to_vec()),
                    1 => ("", bad_ply.clone()),
                    2 => (
                        "?fitting.iterations=1000000000000",
                        std::fs::read(&real[0].1).unwrap(),
                    ),
                    3 if n % 30 == 3 => {
                        stall(&base, key).await;
                        tally.lock().unwrap().uploads += 1;
                        continue;
                    }
                    _ => (
                        "",
                        std::fs::read(&real[(n as usize) % real.len()].1).unwrap(),
                    ),
                };
                let res = http
                    .post(format!("{base}/v1/jobs{query}"))
                    .bearer_auth(key)
                    .body(body)
                    .send()
                    .await;
                let (status, v) = match res {
                    Ok(r) => {
                        let status = r.status().as_u16();
                        (status, r.json::<Value>().await.unwrap_or_default())
                    }
                    Err(_) => (0, Value::Null),
                };
                {
                    let mut t = tally.lock().unwrap();
                    t.uploads += 1;
                    match (status, v["id"].as_str()) {
                        (202, Some(id)) => {
                            t.accepted.insert(id.to_string(), (n % 2) as usize);
                        }
                        _ => *t.refused.entry(status).or_default() += 1,
                    }
                }
                let _ = tenant;
                tokio::time::sleep(Duration::from_millis(every)).await;
            }
        }));
    }
    // Status polling at a fixed rate, each request on its own schedule.
    {
        let (http, base, tally) = (http.clone(), base.clone(), tally.clone());
        let (polls, errors) = (polls.clone(), poll_errors.clone());
        let rate = a.poll_rate;
        tasks.push(tokio::spawn(async move {
            let start = Instant::now();
            let mut i = 0u64;
            while Instant::now() < end {
                i += 1;
                let due = start + Duration::from_micros(i * 1_000_000 / rate);
                tokio::time::sleep_until(due.into()).await;
                let pick = {
                    let t = tally.lock().unwrap();
                    let n = t.accepted.len();
                    (n > 0).then(|| {
                        let (id, tenant) = t.accepted.iter().nth((i as usize * 7919) % n).unwrap();
                        (id.clone(), *tenant)
                    })
                };
                let Some((id, tenant)) = pick else { continue };
                let (http, base, polls, errors) =
                    (http.clone(), base.clone(), polls.clone(), errors.clone());
                tokio::spawn(async move {
                    let r = http
                        .get(format!("{base}/v1/jobs/{id}"))
                        .bearer_auth(KEYS[tenant].1)
                        .send()
                        .await;
                    polls.fetch_add(1, Ordering::Relaxed);
                    // A job we deleted answers 404; anything else but 200 is an error.
                    match r {
                        Ok(r) if r.status() == 200 || r.status() == 404 => {}
                        _ => {
                            errors.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                });
            }
        }));
    }
    // Deletes: every 7 s the newest job (often queued or running), every 11 s an old one.
    {
        let (http, base, tally) = (http.clone(), base.clone(), tally.clone());
        tasks.push(tokio::spawn(async move {
            let mut n = 0u64;
            while Instant::now() < end {
                tokio::time::sleep(Duration::from_secs(if n.is_multiple_of(2) {
                    7
                } else {
                    11
                }))
                .await;
                n += 1;
                let pick = {
                    let t = tally.lock().unwrap();
                    let live: Vec<(&String, &usize)> = t
                        .accepted
                        .iter()
                        .filter(|(id, _)| !t.deleted.contains(*id))
                        .collect();
                    let chosen = if n.is_multiple_of(2) {
                        live.last()
                    } else {
                        live.first()
                    };
                    chosen.map(|(id, tenant)| ((*id).clone(), **tenant))
                };
                let Some((id, tenant)) = pick else { continue };
                let r = http
                    .delete(format!("{base}/v1/jobs/{id}"))
                    .bearer_auth(KEYS[tenant].1)
                    .send()
                    .await;
                if matches!(&r, Ok(r) if r.status() == 204 || r.status() == 404) {
                    tally.lock().unwrap().deleted.insert(id);
                }
            }
        }));
    }
    // Worker kills.
    let kills = Arc::new(AtomicU64::new(0));
    {
        let (workers, kills) = (workers.clone(), kills.clone());
        let bin = bin.clone();
        let every = a.kill_every;
        let n = a.workers;
        tasks.push(tokio::spawn(async move {
            let mut k = 0usize;
            while Instant::now() + Duration::from_secs(every) < end {
                tokio::time::sleep(Duration::from_secs(every)).await;
                let i = k % n;
                k += 1;
                {
                    let mut ws = workers.lock().unwrap();
                    let _ = ws[i].child.kill();
                    let _ = ws[i].child.wait();
                }
                kills.fetch_add(1, Ordering::Relaxed);
                tokio::time::sleep(Duration::from_secs(2)).await;
                let fresh = Proc::spawn(&bin, &format!("worker{i}"), &worker_args(i));
                let mut ws = workers.lock().unwrap();
                let old = std::mem::replace(&mut ws[i], fresh);
                // Keep the killed one's log for the count of completions.
                ws.push(Proc {
                    name: format!("{} (killed)", old.name),
                    ..old
                });
            }
        }));
    }
    // Memory, every 10 s.
    let samples: Arc<Mutex<Vec<(f64, u64, u64)>>> = Arc::default();
    {
        let (api, workers, samples) = (api.clone(), workers.clone(), samples.clone());
        let start = Instant::now();
        let n = a.workers;
        tasks.push(tokio::spawn(async move {
            while Instant::now() < end {
                let api_kb = api.lock().unwrap().rss_kb().unwrap_or(0);
                let workers_kb = workers.lock().unwrap()[..n]
                    .iter()
                    .filter_map(Proc::rss_kb)
                    .max()
                    .unwrap_or(0);
                samples
                    .lock()
                    .unwrap()
                    .push((start.elapsed().as_secs_f64(), api_kb, workers_kb));
                tokio::time::sleep(Duration::from_secs(10)).await;
            }
        }));
    }
    for t in tasks {
        t.await.unwrap();
    }

    // Drain: every accepted job not deleted reaches a terminal status.
    let drained = Instant::now();
    let t = std::mem::take(&mut *tally.lock().unwrap());
    let mut statuses: BTreeMap<String, String> = BTreeMap::new();
    loop {
        statuses.clear();
        for (id, tenant) in &t.accepted {
            if t.deleted.contains(id) {
                continue;
            }
            let r = http
                .get(format!("{base}/v1/jobs/{id}"))
                .bearer_auth(KEYS[*tenant].1)
                .send()
                .await
                .unwrap();
            let st = if r.status() == 404 {
                "missing".to_string()
            } else {
                let v = r.json::<Value>().await.unwrap();
                match v["error"]["code"].as_str() {
                    Some(code) => format!("failed:{code}"),
                    None => v["status"].as_str().unwrap().to_string(),
                }
            };
            statuses.insert(id.clone(), st);
        }
        let open = statuses
            .values()
            .filter(|s| *s == "queued" || *s == "running")
            .count();
        if open == 0 || drained.elapsed() > Duration::from_secs(900) {
            break;
        }
        tokio::time::sleep(Duration::from_secs(5)).await;
    }
    let drain_secs = drained.elapsed().as_secs_f64();

    // Stop everything, then count.
    api.lock().unwrap().terminate();
    let mut ws = std::mem::take(&mut *workers.lock().unwrap());
    for w in &mut ws {
        w.terminate();
    }
    let mut by_status: BTreeMap<String, u64> = BTreeMap::new();
    for s in statuses.values() {
        *by_status.entry(s.clone()).or_default() += 1;
    }
    let lost = statuses
        .values()
        .filter(|s| !(s.as_str() == "succeeded" || s.starts_with("failed:")))
        .count();
    let mut completions: BTreeMap<String, u64> = BTreeMap::new();
    for w in &ws {
        for line in w.log.lock().unwrap().iter() {
            if line.contains("job succeeded") {
                if let Some(id) = line
                    .split("job=")
                    .nth(1)
                    .and_then(|r| r.split_whitespace().next())
                {
                    *completions
                        .entry(id.trim_matches('"').to_string())
                        .or_default() += 1;
                }
            }
        }
    }
    let doubles = completions.values().filter(|&&n| n > 1).count();
    let live: BTreeSet<String> = statuses.keys().cloned().collect();
    let jobs_dir = blobs.join("jobs");
    // A job folder left without a job, with the files in it (an empty folder holds none).
    let leaked: Vec<(String, usize)> = std::fs::read_dir(&jobs_dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| {
            let files = count_files(&e.path());
            (e.file_name().to_string_lossy().to_string(), files)
        })
        .filter(|(id, _)| !live.contains(id))
        .collect();
    let scratch: usize = (0..a.workers)
        .map(|i| {
            std::fs::read_dir(dir.path().join(format!("worker{i}")).join("work"))
                .map(|d| d.count())
                .unwrap_or(0)
        })
        .sum();
    let mem = samples.lock().unwrap().clone();
    let window = |from: f64, to: f64| {
        let sel: Vec<&(f64, u64, u64)> = mem.iter().filter(|s| s.0 >= from && s.0 < to).collect();
        let avg = |f: fn(&(f64, u64, u64)) -> u64| {
            sel.iter().map(|s| f(s)).sum::<u64>() as f64 / sel.len().max(1) as f64 / 1024.0
        };
        (avg(|s| s.1), avg(|s| s.2))
    };
    let total = a.minutes * 60.0;
    let (api_first, w_first) = window(60.0, 360.0f64.min(total / 3.0 + 60.0));
    let (api_last, w_last) = window(total - 300.0f64.min(total / 3.0), total + 1.0);
    let api_max = mem.iter().map(|s| s.1).max().unwrap_or(0) as f64 / 1024.0;

    println!(
        "soak: {:.0} min, {} workers, poll {} req/s",
        a.minutes, a.workers, a.poll_rate
    );
    println!(
        "uploads sent: {} (accepted {}, refused {:?})",
        t.uploads,
        t.accepted.len(),
        t.refused
    );
    println!(
        "status polls: {} ({:.1}/s), errors {}",
        polls.load(Ordering::Relaxed),
        polls.load(Ordering::Relaxed) as f64 / total,
        poll_errors.load(Ordering::Relaxed)
    );
    println!(
        "deleted: {}; worker kills: {}",
        t.deleted.len(),
        kills.load(Ordering::Relaxed)
    );
    println!("final statuses (not deleted): {by_status:?}; drain took {drain_secs:.0} s");
    println!("lost jobs: {lost}");
    println!(
        "double completions: {doubles} (jobs completed: {})",
        completions.len()
    );
    let leaked_files: usize = leaked.iter().map(|l| l.1).sum();
    println!(
        "leaked blobs: {leaked_files} files in {} job folders without a job ({leaked:?}); \
         scratch entries left: {scratch}",
        leaked.len()
    );
    println!(
        "memory (RSS, MB): API {api_first:.1} in minutes 1-6, {api_last:.1} in the last 5, max {api_max:.1}; \
         largest worker {w_first:.1} then {w_last:.1}"
    );
    let _ = sqlx::query(&format!("DROP SCHEMA \"{schema}\" CASCADE"))
        .execute(&mut conn)
        .await;
    if lost > 0 || doubles > 0 || !leaked.is_empty() {
        std::process::exit(1);
    }
}

fn count_files(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| {
            if e.path().is_dir() {
                count_files(&e.path())
            } else {
                1
            }
        })
        .sum()
}

/// An upload that sends a little and then stops (the server drops it).
async fn stall(base: &str, key: &str) {
    let addr = base.trim_start_matches("http://").to_string();
    let key = key.to_string();
    let _ = tokio::task::spawn_blocking(move || {
        let mut tcp = std::net::TcpStream::connect(addr).ok()?;
        tcp.set_read_timeout(Some(Duration::from_secs(30))).ok()?;
        let head = format!(
            "POST /v1/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {key}\r\nContent-Length: 1000000\r\n\r\n0 0 0\n1 1 1\n"
        );
        tcp.write_all(head.as_bytes()).ok()?;
        let mut buf = Vec::new();
        let _ = tcp.read_to_end(&mut buf);
        Some(())
    })
    .await;
}

/// The real scans small enough to plan in seconds, with their format.
fn real_files() -> Vec<(String, PathBuf)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real");
    // The consumer-LiDAR rooms have no floor and the voxel office no wall cells at the default
    // settings: they fail (`no_stories`, `no_plan`), as real uploads do; the apartment plans.
    let names = [
        "ipad-room430.ply",
        "apartment-merged.laz",
        "ipad-room470.ply",
        "apartment-16scans.e57",
        "ipad-room560.ply",
        "apartment-merged.laz",
        "office-fr079-voxels8cm.laz",
        "apartment-16scans.e57",
    ];
    names
        .iter()
        .map(|n| (n.to_string(), dir.join(n)))
        .filter(|(_, p)| p.is_file())
        .collect()
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}
