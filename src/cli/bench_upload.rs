//! `asbuilt bench`'s upload table: the time from an upload's last byte to its job's
//! `succeeded`, with the upload read as it arrives (`worker::early`) and without (the job reads
//! the stored file). The service runs in this process on a fresh data folder with one worker;
//! the upload is a raw `POST /v1/jobs` written to the socket, at a given rate or as fast as the
//! server takes it.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use asbuilt_plan::progress::Progress;
use serde::Serialize;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use asbuilt::app;
use asbuilt::config::Config;
use asbuilt::worker::pipeline::{JobInput, JobResults, Pipeline, PipelineFailure, PlanPipeline};

/// One upload's figures.
#[derive(Debug, Serialize)]
pub struct UploadRun {
    pub points: u64,
    pub format: &'static str,
    /// Read as it arrived.
    pub early: bool,
    pub file_bytes: u64,
    /// The upload rate asked for, MB/s (0: as fast as the server takes it).
    pub rate_mb_s: f64,
    /// From the first byte sent to the last.
    pub upload_ms: f64,
    /// From the last byte sent to the job's `succeeded`.
    pub last_byte_to_done_ms: f64,
    /// The job's own `read` time (after the last byte when read early).
    pub read_ms: u64,
    /// The job's whole plan (its `total`, read included); the rest of `last_byte_to_done_ms`
    /// is the service's: storing the upload, queueing, writing the results.
    pub plan_ms: u64,
}

/// What one timed upload measured.
#[derive(Debug, Clone, Copy)]
pub struct Timed {
    pub upload_ms: f64,
    pub done_ms: f64,
    pub read_ms: u64,
    pub plan_ms: u64,
}

/// The real pipeline with early reads turned off.
struct StoredOnly;

impl Pipeline for StoredOnly {
    fn run(
        &self,
        input: &JobInput,
        progress: &mut dyn Progress,
    ) -> Result<JobResults, PipelineFailure> {
        PlanPipeline.run(input, progress)
    }
}

/// Uploads `file` to a fresh service and times it (see the module's doc).
pub fn time_upload(file: &Path, early: bool, rate_mb_s: f64) -> anyhow::Result<Timed> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    runtime.block_on(async {
        let dir = tempfile::tempdir()?;
        let config = Config {
            listen: "127.0.0.1:0".parse()?,
            data_dir: dir.path().to_path_buf(),
            workers: 1,
            rate_limit: 0.0,
            ..Config::default()
        };
        let pipeline: Arc<dyn Pipeline> = match early {
            true => Arc::new(PlanPipeline),
            false => Arc::new(StoredOnly),
        };
        let running = app::start(config, pipeline).await?;
        let addr = running.addr;
        let outcome = upload_and_wait(addr, file, rate_mb_s).await;
        running.stop().await?;
        outcome
    })
}

async fn upload_and_wait(
    addr: std::net::SocketAddr,
    file: &Path,
    rate_mb_s: f64,
) -> anyhow::Result<Timed> {
    let len = std::fs::metadata(file)?.len();
    let mut source = tokio::fs::File::open(file).await?;
    let mut socket = TcpStream::connect(addr).await?;
    let head = format!(
        "POST /v1/jobs HTTP/1.1\r\nHost: {addr}\r\nContent-Length: {len}\r\n\
         Content-Type: application/octet-stream\r\nConnection: close\r\n\r\n"
    );
    socket.write_all(head.as_bytes()).await?;
    let start = Instant::now();
    let mut sent = 0u64;
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = source.read(&mut buf).await?;
        if n == 0 {
            break;
        }
        socket.write_all(&buf[..n]).await?;
        sent += n as u64;
        if rate_mb_s > 0.0 {
            let due = Duration::from_secs_f64(sent as f64 / (rate_mb_s * 1e6));
            tokio::time::sleep_until((start + due).into()).await;
        }
    }
    socket.flush().await?;
    let last_byte = Instant::now();
    let upload_ms = (last_byte - start).as_secs_f64() * 1e3;
    let mut answer = String::new();
    socket.read_to_string(&mut answer).await?;
    let body = answer.split("\r\n\r\n").nth(1).unwrap_or_default();
    let job: serde_json::Value =
        serde_json::from_str(body).with_context(|| format!("the upload's answer: {answer}"))?;
    let id = job["id"]
        .as_str()
        .with_context(|| format!("no job in the answer: {answer}"))?;
    let job = loop {
        let job = get_job(addr, id).await?;
        match job["status"].as_str() {
            Some("succeeded") => break job,
            Some("failed" | "cancelled") => bail!("the job ended {}: {}", job["status"], job),
            _ => tokio::time::sleep(Duration::from_millis(10)).await,
        }
    };
    let done_ms = last_byte.elapsed().as_secs_f64() * 1e3;
    let ms = |stage: &str| job["timings_ms"][stage].as_u64().unwrap_or(0);
    Ok(Timed {
        upload_ms,
        done_ms,
        read_ms: ms("read"),
        plan_ms: ms("total"),
    })
}

async fn get_job(addr: std::net::SocketAddr, id: &str) -> anyhow::Result<serde_json::Value> {
    let mut socket = TcpStream::connect(addr).await?;
    let request =
        format!("GET /v1/jobs/{id} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n");
    socket.write_all(request.as_bytes()).await?;
    let mut answer = String::new();
    socket.read_to_string(&mut answer).await?;
    let body = answer.split("\r\n\r\n").nth(1).unwrap_or_default();
    serde_json::from_str(body).with_context(|| format!("the job's answer: {answer}"))
}
