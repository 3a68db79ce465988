//! Uploads read as they arrive (`worker::early`), with the real pipeline: the plan is the
//! stored file's, a cut upload fails as it does from the stored file, and a job that outlives
//! its process (a restart) runs from the stored upload.

use crate::support::server::{self, Server};

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use asbuilt::app;
use asbuilt::worker::pipeline::{JobInput, JobResults, Pipeline, PipelineFailure, PlanPipeline};
use asbuilt_plan::io::ply::{write_ply, Encoding};
use asbuilt_plan::progress::Progress;
use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};
use serde_json::Value;

/// The real pipeline, without early reads: every job runs from the stored file.
struct FromStored;

impl Pipeline for FromStored {
    fn run(
        &self,
        input: &JobInput,
        progress: &mut dyn Progress,
    ) -> Result<JobResults, PipelineFailure> {
        assert!(input.early.is_none());
        PlanPipeline.run(input, progress)
    }
}

/// Takes the early read and then runs until stopped, as a process that dies mid-job would.
struct Stall(Arc<AtomicBool>);

impl Pipeline for Stall {
    fn reads_early(&self) -> bool {
        true
    }

    fn run(
        &self,
        input: &JobInput,
        progress: &mut dyn Progress,
    ) -> Result<JobResults, PipelineFailure> {
        self.0.store(input.early.is_some(), Ordering::SeqCst);
        while progress.cancel().check().is_ok() {
            std::thread::sleep(Duration::from_millis(20));
        }
        Err(PipelineFailure::cancelled())
    }
}

/// A simulated room as binary PLY bytes.
fn room_ply() -> Vec<u8> {
    let options = ScanOptions {
        points: 80_000,
        seed: 4,
        ..Default::default()
    };
    let sim = simulate(BuildingKind::SquareRoom, &options).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("room.ply");
    write_ply(&path, &sim.cloud, Encoding::BinaryLittleEndian).unwrap();
    std::fs::read(path).unwrap()
}

/// The GeoJSON without its timings.
fn untimed(v: Value) -> Value {
    match v {
        Value::Object(m) => Value::Object(
            m.into_iter()
                .filter(|(k, _)| !k.contains("timing"))
                .map(|(k, v)| (k, untimed(v)))
                .collect(),
        ),
        Value::Array(a) => Value::Array(a.into_iter().map(untimed).collect()),
        v => v,
    }
}

/// Uploads `body` raw, waits for the job's end; the job and its GeoJSON when it succeeded.
async fn plan(s: &Server, body: Vec<u8>) -> (Value, Option<Value>) {
    let job = s.upload(body).await;
    let id = job["id"].as_str().unwrap();
    let done = s.wait_done(id, Duration::from_secs(300)).await;
    if done["status"] != "succeeded" {
        return (done, None);
    }
    let doc: Value = s
        .get(&format!("/v1/jobs/{id}/plan.geojson"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    (done, Some(doc))
}

async fn early_reads(s: &Server, outcome: &str) -> u64 {
    let text = s
        .get("/metrics")
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    let key = format!("asbuilt_early_reads_total{{outcome=\"{outcome}\"}} ");
    text.lines()
        .find_map(|l| l.strip_prefix(&key))
        .map_or(0, |n| n.parse().unwrap())
}

#[tokio::test(flavor = "multi_thread")]
async fn an_upload_read_as_it_arrives_plans_as_the_stored_file_and_fails_as_it() {
    let ply = room_ply();
    let early = server::start(Arc::new(PlanPipeline), |c| c.workers = 1).await;
    let stored = server::start(Arc::new(FromStored), |c| c.workers = 1).await;

    let (job, doc) = plan(&early, ply.clone()).await;
    assert_eq!(job["status"], "succeeded", "{job}");
    assert_eq!(early_reads(&early, "used").await, 1);
    let (job, reference) = plan(&stored, ply.clone()).await;
    assert_eq!(job["status"], "succeeded", "{job}");
    assert_eq!(early_reads(&stored, "used").await, 0);
    let (doc, reference) = (untimed(doc.unwrap()), untimed(reference.unwrap()));
    assert!(doc["features"].as_array().unwrap().len() > 1);
    assert_eq!(doc, reference);

    // Cut in the middle of the points, and with the header damaged: the early read fails,
    // the stored file is read, and the job fails as it does without the early read.
    let cut = ply[..ply.len() / 2].to_vec();
    let mut damaged = ply.clone();
    let at = String::from_utf8_lossy(&ply[..200])
        .find("element vertex")
        .unwrap();
    damaged[at..at + 7].copy_from_slice(b"elemant");
    for (i, body) in [cut, damaged].into_iter().enumerate() {
        let (failed, _) = plan(&early, body.clone()).await;
        let (reference, _) = plan(&stored, body).await;
        assert_eq!(failed["status"], "failed", "{failed}");
        assert_eq!(failed["error"], reference["error"]);
        assert_eq!(early_reads(&early, "failed").await, i as u64 + 1);
    }
    assert_eq!(early_reads(&early, "used").await, 1);
}

#[tokio::test(flavor = "multi_thread")]
async fn a_job_whose_process_stopped_runs_from_the_stored_upload() {
    let ply = room_ply();
    let dir = tempfile::tempdir().unwrap();
    let took_early = Arc::new(AtomicBool::new(false));
    let mut config = server::config(dir.path());
    config.workers = 1;
    config.shutdown_timeout_secs = 1;
    let first = app::start(config.clone(), Arc::new(Stall(took_early.clone())))
        .await
        .unwrap();
    let client = reqwest::Client::new();
    let base = format!("http://{}", first.addr);
    let job: Value = client
        .post(format!("{base}/v1/jobs"))
        .body(ply.clone())
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let id = job["id"].as_str().unwrap().to_string();
    crate::support::wait::eventually("the job runs", Duration::from_secs(60), || async {
        took_early.load(Ordering::SeqCst).then_some(())
    })
    .await;
    first.stop().await.unwrap();

    // The next process on the same store has no early read: it plans the stored upload.
    let second = app::start(config, Arc::new(PlanPipeline)).await.unwrap();
    let s = Server {
        base: format!("http://{}", second.addr),
        running: Some(second),
        dir: tempfile::tempdir().unwrap(),
        client,
        key: None,
    };
    let done = s.wait_done(&id, Duration::from_secs(300)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(early_reads(&s, "used").await, 0);
    let doc: Value = s
        .get(&format!("/v1/jobs/{id}/plan.geojson"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let reference = server::start(Arc::new(FromStored), |c| c.workers = 1).await;
    let (_, expected) = plan(&reference, ply).await;
    assert_eq!(untimed(doc), untimed(expected.unwrap()));
}
