//! The queue and storage suite, run on both backends: SQLite with a local directory (the
//! embedded default) and PostgreSQL with S3 (scale-out). Every test runs once per backend, on
//! real engines; the PostgreSQL + S3 half skips without `ASBUILT_TEST_POSTGRES` and
//! `ASBUILT_TEST_S3_ENDPOINT` (see support/engines.rs), and fails without them under CI.

use std::collections::BTreeSet;
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::support::engines::{engines, unique, Engines};
use asbuilt::queue::postgres::PgJobStore;
use asbuilt::queue::sqlite::SqliteJobStore;
use asbuilt::queue::{
    Beat, Delivery, Heartbeat, Idempotency, Inserted, JobError, JobId, JobMeta, JobOutcome,
    JobStatus, JobStore, ListQuery, NewJob, UploadInfo, WORKER_LOST,
};
use asbuilt::storage::{local, s3, BlobError, BlobStore, ByteStream};
use bytes::Bytes;
use futures_util::StreamExt;
use sha2::{Digest, Sha256};

/// One backend pair, fresh for one test.
struct Backend {
    name: &'static str,
    store: Arc<dyn JobStore>,
    blobs: Arc<dyn BlobStore>,
    /// Opens a second, independent handle on the same database, as another process would.
    reopen: Box<dyn Fn() -> futures_util::future::BoxFuture<'static, Arc<dyn JobStore>> + Send>,
    cleanup: Cleanup,
}

enum Cleanup {
    Dir(#[allow(dead_code)] tempfile::TempDir),
    Schema(Engines, String),
}

impl Backend {
    async fn sqlite_local() -> Backend {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("jobs.db");
        let store = SqliteJobStore::open(&db).await.unwrap();
        store.migrate().await.unwrap();
        let blobs = local::open(&dir.path().join("blobs")).unwrap();
        Backend {
            name: "sqlite+local",
            store: Arc::new(store),
            blobs: Arc::new(blobs),
            reopen: Box::new(move || {
                let db = db.clone();
                Box::pin(async move {
                    Arc::new(SqliteJobStore::open(&db).await.unwrap()) as Arc<dyn JobStore>
                })
            }),
            cleanup: Cleanup::Dir(dir),
        }
    }

    /// `None` when the engines are not configured (and CI is not set).
    async fn postgres_s3(test: &str) -> Option<Backend> {
        let engines = engines(test)?;
        let schema = engines.new_schema("suite").await;
        let url = engines.url_in(&schema);
        let store = PgJobStore::connect(&url).await.unwrap();
        store.migrate().await.unwrap();
        engines.ensure_bucket("asbuilt-suite").await;
        let blobs = s3::open(
            &format!("s3://asbuilt-suite/{}", unique("t")),
            &engines.s3_options(),
        )
        .unwrap();
        Some(Backend {
            name: "postgres+s3",
            store: Arc::new(store),
            blobs: Arc::new(blobs),
            reopen: Box::new(move || {
                let url = url.clone();
                Box::pin(async move {
                    Arc::new(PgJobStore::connect(&url).await.unwrap()) as Arc<dyn JobStore>
                })
            }),
            cleanup: Cleanup::Schema(engines, schema),
        })
    }

    async fn finish(self) {
        if let Cleanup::Schema(engines, schema) = &self.cleanup {
            engines.drop_schema(schema).await;
        }
    }
}

/// Runs a suite function on both backends.
macro_rules! on_both_backends {
    ($($name:ident),* $(,)?) => {
        mod sqlite_local {
            $(#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn $name() {
                let b = super::Backend::sqlite_local().await;
                super::$name(&b).await;
                b.finish().await;
            })*
        }
        mod postgres_s3 {
            $(#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn $name() {
                let Some(b) = super::Backend::postgres_s3(stringify!($name)).await else {
                    return;
                };
                super::$name(&b).await;
                b.finish().await;
            })*
        }
    };
}

on_both_backends!(
    claims_are_fair_across_tenants,
    queued_caps_hold_and_release_all_hands_back_once,
    claim_heartbeat_complete,
    expired_leases_requeue_then_fail,
    release_cancel_and_delete,
    lists_newest_first_with_pages_and_counts,
    concurrent_claims_take_each_job_once,
    idle_workers_wake_when_a_job_is_queued,
    schema_is_checked,
    blobs_stream_in_and_out_in_parts,
    oversized_and_broken_uploads_leave_nothing,
    delete_prefix_removes_only_that_job,
    results_are_whole_or_absent,
    presigned_urls_fetch_the_object_when_configured,
    keyed_replanned_tagged_and_expired_jobs,
    webhooks_are_claimed_once_and_recorded,
    ranged_reads_return_the_bytes_asked_for,
);

fn new_job(tenant: &str, max_attempts: u32) -> NewJob {
    NewJob {
        id: JobId::new(),
        tenant: tenant.into(),
        params: serde_json::json!({"samples": {"cell_size": 0.05}}),
        upload: UploadInfo {
            filename: Some("scan.ply".into()),
            bytes: 3,
            sha256: "ab".into(),
            format: "ply".into(),
            sidecar: None,
            georeference: None,
        },
        max_attempts,
        ..Default::default()
    }
}

fn beat(stage: &str, progress: f64) -> Beat {
    Beat {
        stage: Some(stage.into()),
        progress,
        input: None,
        detail: Some(serde_json::json!({"read": null, "story": {"number": 2, "count": 3}})),
    }
}

fn outcome(points: u64) -> JobOutcome {
    JobOutcome {
        input: serde_json::json!({"points": points, "format": "ply", "scans": 2}),
        timings: serde_json::json!({"stories": 3, "total": 10}),
    }
}

/// One tenant's flood does not starve another's single job: with one worker, the second
/// tenant's job is claimed right after the flood's first, though 99 older jobs wait.
async fn claims_are_fair_across_tenants(b: &Backend) {
    let s = &b.store;
    // Start times are in milliseconds: claims are kept apart so they differ.
    let pause = || tokio::time::sleep(Duration::from_millis(5));
    for _ in 0..100 {
        s.create(new_job("flood", 3)).await.unwrap();
    }
    let single = s.create(new_job("single", 3)).await.unwrap();
    // Nobody has started anything: the oldest job goes first.
    let first = s.claim("w", 10_000).await.unwrap().unwrap();
    assert_eq!(first.tenant, "flood");
    pause().await;
    // `flood` has a job running, `single` none.
    let second = s.claim("w", 10_000).await.unwrap().unwrap();
    assert_eq!(second.id, single.id, "the single job is not starved");
    s.complete(first.id, "w", &outcome(1)).await.unwrap();
    s.complete(second.id, "w", &outcome(1)).await.unwrap();
    pause().await;
    // Nothing running: the tenant whose last job started longest ago goes first.
    let late = s.create(new_job("single", 3)).await.unwrap();
    let third = s.claim("w", 10_000).await.unwrap().unwrap();
    assert_eq!(third.tenant, "flood", "flood last started before single");
    pause().await;
    let fourth = s.claim("w", 10_000).await.unwrap().unwrap();
    assert_eq!(fourth.id, late.id, "flood has one running, single none");
}

async fn queued_caps_hold_and_release_all_hands_back_once(b: &Backend) {
    let s = &b.store;
    for _ in 0..3 {
        assert!(s.create_within(new_job("a", 3), 3).await.unwrap().is_some());
    }
    assert!(s.create_within(new_job("a", 3), 3).await.unwrap().is_none());
    assert!(s.create_within(new_job("b", 3), 3).await.unwrap().is_some());
    assert!(s.create_within(new_job("a", 3), 0).await.unwrap().is_some());
    assert_eq!(s.queued_count("a").await.unwrap(), 4);
    assert_eq!(s.queued_count("c").await.unwrap(), 0);
    // Concurrent uploads from another handle cannot slip past the cap together.
    let other = (b.reopen)().await;
    let tries: Vec<_> = (0..6)
        .map(|i| {
            let st = if i % 2 == 0 { s.clone() } else { other.clone() };
            tokio::spawn(async move { st.create_within(new_job("c", 3), 2).await.unwrap() })
        })
        .collect();
    let mut made = 0;
    for t in tries {
        made += usize::from(t.await.unwrap().is_some());
    }
    assert_eq!(made, 2);
    assert_eq!(s.queued_count("c").await.unwrap(), 2);

    let x = s.claim("proc-1/0", 10_000).await.unwrap().unwrap();
    let y = s.claim("proc-1/1", 10_000).await.unwrap().unwrap();
    let z = s.claim("proc-2/0", 10_000).await.unwrap().unwrap();
    let mut back = s.release_all("proc-1/").await.unwrap();
    back.sort();
    let mut want = vec![x.id, y.id];
    want.sort();
    assert_eq!(back, want);
    assert!(s.release_all("proc-1/").await.unwrap().is_empty(), "once");
    let again = s.get(None, x.id).await.unwrap().unwrap();
    assert_eq!((again.status, again.attempts), (JobStatus::Queued, 0));
    assert_eq!(
        s.get(None, z.id).await.unwrap().unwrap().status,
        JobStatus::Running
    );
}

async fn claim_heartbeat_complete(b: &Backend) {
    let s = &b.store;
    let job = s.create(new_job("a", 3)).await.unwrap();
    assert_eq!(job.status, JobStatus::Queued, "{}", b.name);
    assert_eq!(job.params["samples"]["cell_size"], 0.05);
    assert_eq!(job.upload.filename.as_deref(), Some("scan.ply"));
    let claimed = s.claim("w1", 10_000).await.unwrap().unwrap();
    assert_eq!((claimed.id, claimed.attempts), (job.id, 1));
    assert_eq!(claimed.status, JobStatus::Running);
    assert!(claimed.started_at.is_some());
    assert!(s.claim("w2", 10_000).await.unwrap().is_none());
    assert_eq!(
        s.heartbeat(job.id, "w2", 10_000, &beat("samples", 0.5))
            .await
            .unwrap(),
        Heartbeat::Lost
    );
    assert_eq!(
        s.heartbeat(job.id, "w1", 10_000, &beat("samples", 1.5))
            .await
            .unwrap(),
        Heartbeat::Held
    );
    let got = s.get(Some("a"), job.id).await.unwrap().unwrap();
    // Progress is clamped to 0..1.
    assert_eq!((got.stage.as_deref(), got.progress), (Some("samples"), 1.0));
    // The story running is kept with it.
    assert_eq!(
        got.progress_detail.unwrap()["story"],
        serde_json::json!({"number": 2, "count": 3})
    );
    assert!(!s.complete(job.id, "w2", &outcome(9)).await.unwrap());
    assert!(s.complete(job.id, "w1", &outcome(9)).await.unwrap());
    // A second completion of the same run is refused: the lease is gone.
    assert!(!s.complete(job.id, "w1", &outcome(9)).await.unwrap());
    let got = s.get(None, job.id).await.unwrap().unwrap();
    assert_eq!(got.status, JobStatus::Succeeded);
    assert_eq!(got.input.unwrap()["points"], 9);
    assert_eq!(got.timings.unwrap()["total"], 10);
    assert!(got.finished_at.unwrap() >= got.started_at.unwrap());
    assert!(s.get(Some("b"), job.id).await.unwrap().is_none());
}

async fn expired_leases_requeue_then_fail(b: &Backend) {
    let s = &b.store;
    let job = s.create(new_job("a", 2)).await.unwrap();
    for attempt in 1..=2 {
        let c = s.claim("w", 1).await.unwrap().unwrap();
        assert_eq!(c.attempts, attempt);
        tokio::time::sleep(Duration::from_millis(20)).await;
        let e = s.requeue_expired().await.unwrap();
        if attempt == 1 {
            assert_eq!((e.requeued, e.failed), (vec![job.id], vec![]));
            // The dead worker's late heartbeat is refused.
            let late = s.heartbeat(job.id, "w", 10_000, &beat("x", 0.1)).await;
            assert_eq!(late.unwrap(), Heartbeat::Lost);
        } else {
            assert_eq!((e.requeued, e.failed), (vec![], vec![job.id]));
        }
    }
    let got = s.get(None, job.id).await.unwrap().unwrap();
    assert_eq!(got.status, JobStatus::Failed);
    assert_eq!(got.error.unwrap().code, WORKER_LOST);
    let e = s.requeue_expired().await.unwrap();
    assert!(e.requeued.is_empty() && e.failed.is_empty());
}

async fn release_cancel_and_delete(b: &Backend) {
    let s = &b.store;
    let job = s.create(new_job("a", 3)).await.unwrap();
    s.claim("w", 10_000).await.unwrap().unwrap();
    assert!(!s.release(job.id, "other").await.unwrap());
    assert!(s.release(job.id, "w").await.unwrap());
    let again = s.claim("w", 10_000).await.unwrap().unwrap();
    assert_eq!(again.attempts, 1, "release gives the attempt back");
    assert!(s.cancel("b", job.id).await.unwrap().is_none());
    let c = s.cancel("a", job.id).await.unwrap().unwrap();
    assert_eq!(c.status, JobStatus::Cancelled);
    assert_eq!(
        s.heartbeat(job.id, "w", 10_000, &beat("x", 0.2))
            .await
            .unwrap(),
        Heartbeat::Lost
    );
    let err = JobError {
        code: "x".into(),
        message: "y".into(),
    };
    assert!(!s.fail(job.id, "w", &err, Some("fit")).await.unwrap());
    assert!(s.delete(job.id).await.unwrap());
    assert!(!s.delete(job.id).await.unwrap());
    assert!(s.get(None, job.id).await.unwrap().is_none());

    let failing = s.create(new_job("a", 3)).await.unwrap();
    s.claim("w", 10_000).await.unwrap().unwrap();
    assert!(s.fail(failing.id, "w", &err, Some("fit")).await.unwrap());
    let got = s.get(None, failing.id).await.unwrap().unwrap();
    assert_eq!((got.status, got.error), (JobStatus::Failed, Some(err)));
    let old = s.finished_before(super_now() + 1000, 10).await.unwrap();
    assert_eq!(old, vec![failing.id]);
    assert!(s.finished_before(0, 10).await.unwrap().is_empty());
}

fn super_now() -> i64 {
    asbuilt::queue::now_ms()
}

async fn lists_newest_first_with_pages_and_counts(b: &Backend) {
    let s = &b.store;
    let mut ids = vec![];
    for _ in 0..5 {
        ids.push(s.create(new_job("a", 3)).await.unwrap().id);
    }
    s.create(new_job("b", 3)).await.unwrap();
    let mut q = ListQuery {
        tenant: "a".into(),
        limit: 2,
        ..Default::default()
    };
    let mut seen = vec![];
    loop {
        let page = s.list(&q).await.unwrap();
        if page.is_empty() {
            break;
        }
        assert!(page.len() <= 2);
        q.before = Some(page.last().unwrap().id);
        seen.extend(page.into_iter().map(|j| j.id));
    }
    ids.sort();
    ids.reverse();
    assert_eq!(seen, ids, "{}", b.name);
    s.claim("w", 10_000).await.unwrap();
    q.before = None;
    q.limit = 10;
    q.status = Some(JobStatus::Running);
    assert_eq!(s.list(&q).await.unwrap().len(), 1);
    let counts = s.counts_by_status().await.unwrap();
    assert_eq!(counts.len(), JobStatus::ALL.len());
    assert_eq!(counts[0], (JobStatus::Queued, 5));
    assert_eq!(counts[1], (JobStatus::Running, 1));
    assert_eq!(counts[2], (JobStatus::Succeeded, 0));
}

/// Eight claimers on two independent handles race for 24 jobs: each job is taken exactly once.
async fn concurrent_claims_take_each_job_once(b: &Backend) {
    let mut created = BTreeSet::new();
    for _ in 0..24 {
        created.insert(b.store.create(new_job("a", 3)).await.unwrap().id);
    }
    let other = (b.reopen)().await;
    let mut tasks = vec![];
    for w in 0..8 {
        let store = if w % 2 == 0 {
            b.store.clone()
        } else {
            other.clone()
        };
        tasks.push(tokio::spawn(async move {
            let owner = format!("w{w}");
            let mut mine = vec![];
            while let Some(job) = store.claim(&owner, 10_000).await.unwrap() {
                assert!(store.complete(job.id, &owner, &outcome(1)).await.unwrap());
                mine.push(job.id);
            }
            mine
        }));
    }
    let mut claimed = vec![];
    for t in tasks {
        claimed.extend(t.await.unwrap());
    }
    assert_eq!(
        claimed.len(),
        24,
        "{}: a job was claimed twice or lost",
        b.name
    );
    assert_eq!(claimed.into_iter().collect::<BTreeSet<_>>(), created);
}

/// A worker waiting for work wakes soon after another handle queues a job. On PostgreSQL the
/// wake-up is a notification; elsewhere the wait ends by polling within its timeout.
async fn idle_workers_wake_when_a_job_is_queued(b: &Backend) {
    let waiter = b.store.clone();
    let timeout = Duration::from_secs(2);
    // The first wait sets up any listener; make sure nothing is pending before measuring.
    waiter.wait_for_work(Duration::from_millis(50)).await;
    let start = Instant::now();
    let waiting = tokio::spawn(async move {
        waiter.wait_for_work(timeout).await;
        start.elapsed()
    });
    tokio::time::sleep(Duration::from_millis(200)).await;
    let other = (b.reopen)().await;
    other.create(new_job("a", 3)).await.unwrap();
    let waited = waiting.await.unwrap();
    assert!(waited <= timeout + Duration::from_millis(500), "{waited:?}");
    if b.name == "postgres+s3" {
        assert!(
            waited < Duration::from_millis(1500),
            "LISTEN/NOTIFY did not wake the worker ({waited:?})"
        );
    }
}

async fn schema_is_checked(b: &Backend) {
    b.store.check_schema().await.unwrap();
    if let Cleanup::Schema(engines, _) = &b.cleanup {
        // A schema nobody migrated is refused with the command that fixes it.
        let empty = engines.new_schema("empty").await;
        let store = PgJobStore::connect(&engines.url_in(&empty)).await.unwrap();
        let err = store.check_schema().await.unwrap_err().to_string();
        assert!(err.contains("asbuilt migrate"), "{err}");
        store.migrate().await.unwrap();
        store.migrate().await.unwrap();
        store.check_schema().await.unwrap();
        engines.drop_schema(&empty).await;
    }
}

/// `n` chunks of `size` bytes with distinct contents.
fn chunks(n: usize, size: usize) -> (ByteStream<'static>, Vec<u8>) {
    let all: Vec<u8> = (0..n * size).map(|i| (i * 7 % 251) as u8).collect();
    let parts: Vec<Bytes> = all.chunks(size).map(Bytes::copy_from_slice).collect();
    let stream = futures_util::stream::iter(parts.into_iter().map(Ok)).boxed();
    (stream, all)
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

async fn read_all(b: &Backend, key: &str) -> Option<Vec<u8>> {
    let blob = b.blobs.get(key).await.unwrap()?;
    let size = blob.size;
    let bytes: Vec<u8> = blob.stream.map(|c| c.unwrap().to_vec()).concat().await;
    assert_eq!(bytes.len() as u64, size);
    Some(bytes)
}

/// 12 MiB in 1 MiB chunks: on S3 that is a real multipart upload of three parts.
async fn blobs_stream_in_and_out_in_parts(b: &Backend) {
    b.blobs.ping().await.unwrap();
    let id = JobId::new();
    let key = format!("jobs/{id}/input/cloud");
    let (stream, expected) = chunks(12, 1 << 20);
    let stored = b.blobs.put_stream(&key, stream, 64 << 20).await.unwrap();
    assert_eq!(stored.bytes, expected.len() as u64, "{}", b.name);
    assert_eq!(stored.sha256, sha256_hex(&expected));
    assert_eq!(read_all(b, &key).await.unwrap(), expected);
    let dir = tempfile::tempdir().unwrap();
    let to = dir.path().join("cloud");
    assert_eq!(
        b.blobs.download(&key, &to).await.unwrap(),
        expected.len() as u64
    );
    assert_eq!(std::fs::read(&to).unwrap(), expected);
    assert!(b
        .blobs
        .get(&format!("jobs/{id}/nothing"))
        .await
        .unwrap()
        .is_none());
}

async fn oversized_and_broken_uploads_leave_nothing(b: &Backend) {
    let key = format!("jobs/{}/input/cloud", JobId::new());
    let (stream, _) = chunks(8, 1 << 20);
    let err = b.blobs.put_stream(&key, stream, 6 << 20).await.unwrap_err();
    assert!(
        matches!(err, BlobError::TooLarge { .. }),
        "{}: {err}",
        b.name
    );
    assert!(b.blobs.get(&key).await.unwrap().is_none());

    // The client goes away after 6 MiB: more than one part was already sent on S3.
    let parts: Vec<Result<Bytes, std::io::Error>> = (0..6)
        .map(|_| Ok(Bytes::from(vec![1u8; 1 << 20])))
        .chain([Err(std::io::Error::other("connection reset"))])
        .collect();
    let err = b
        .blobs
        .put_stream(&key, futures_util::stream::iter(parts).boxed(), 64 << 20)
        .await
        .unwrap_err();
    assert!(matches!(err, BlobError::Source(_)), "{err}");
    assert!(b.blobs.get(&key).await.unwrap().is_none());
}

async fn delete_prefix_removes_only_that_job(b: &Backend) {
    let (a, other) = (JobId::new(), JobId::new());
    for (id, name) in [
        (a, "result/plan.svg"),
        (a, "input/cloud"),
        (other, "input/cloud"),
    ] {
        b.blobs
            .put(&format!("jobs/{id}/{name}"), Bytes::from_static(b"x"))
            .await
            .unwrap();
    }
    b.blobs.delete_prefix(&format!("jobs/{a}")).await.unwrap();
    assert!(b
        .blobs
        .get(&format!("jobs/{a}/result/plan.svg"))
        .await
        .unwrap()
        .is_none());
    assert!(b
        .blobs
        .get(&format!("jobs/{a}/input/cloud"))
        .await
        .unwrap()
        .is_none());
    assert!(b
        .blobs
        .get(&format!("jobs/{other}/input/cloud"))
        .await
        .unwrap()
        .is_some());
    // Deleting nothing is not an error.
    b.blobs.delete_prefix(&format!("jobs/{a}")).await.unwrap();
}

/// Readers racing a writer that replaces a result see the old whole object or the new whole
/// object, never a mix or a prefix.
async fn results_are_whole_or_absent(b: &Backend) {
    let key = format!("jobs/{}/result/plan.geojson", JobId::new());
    let old = Bytes::from(vec![b'a'; 256 << 10]);
    let new = Bytes::from(vec![b'b'; 512 << 10]);
    b.blobs.put(&key, old.clone()).await.unwrap();
    let blobs = b.blobs.clone();
    let (k2, n2) = (key.clone(), new.clone());
    let writer = tokio::spawn(async move {
        for _ in 0..5 {
            blobs.put(&k2, n2.clone()).await.unwrap();
        }
    });
    for _ in 0..10 {
        let got = read_all(b, &key)
            .await
            .expect("the result exists throughout");
        assert!(got == old || got == new, "{}: a torn read", b.name);
    }
    writer.await.unwrap();
    assert_eq!(read_all(b, &key).await.unwrap(), new);
}

/// The local store never presigns; S3 does when asked to, and the URL works without credentials.
async fn presigned_urls_fetch_the_object_when_configured(b: &Backend) {
    let key = format!("jobs/{}/result/plan.svg", JobId::new());
    b.blobs
        .put(&key, Bytes::from_static(b"<svg/>"))
        .await
        .unwrap();
    assert_eq!(
        b.blobs.presigned_get(&key).await.unwrap(),
        None,
        "{}",
        b.name
    );
    let Cleanup::Schema(engines, _) = &b.cleanup else {
        return;
    };
    let prefix = unique("p");
    let mut options = engines.s3_options();
    options.presign = Some(Duration::from_secs(60));
    let signing = s3::open(&format!("s3://asbuilt-suite/{prefix}"), &options).unwrap();
    signing
        .put(&key, Bytes::from_static(b"<svg/>"))
        .await
        .unwrap();
    let url = signing.presigned_get(&key).await.unwrap().expect("a URL");
    assert!(url.contains("X-Amz-Signature="), "{url}");
    assert!(
        url.contains(&prefix),
        "the URL must include the prefix: {url}"
    );
    let body = reqwest::get(&url).await.unwrap();
    assert_eq!(body.status().as_u16(), 200);
    assert_eq!(body.text().await.unwrap(), "<svg/>");
    signing.delete_prefix("jobs").await.unwrap();
}

fn created(i: Inserted) -> asbuilt::queue::Job {
    match i {
        Inserted::Created(job) => *job,
        other => panic!("not created: {other:?}"),
    }
}

/// The job API's store steps: idempotency keys, re-plans sharing an upload, metadata filters,
/// and tombstones of expired jobs.
async fn keyed_replanned_tagged_and_expired_jobs(b: &Backend) {
    let s = &b.store;
    let keyed = |key: &str| NewJob {
        idempotency: Some(Idempotency {
            key: key.into(),
            request_hash: "h1".into(),
        }),
        meta: JobMeta {
            external_ref: Some("b-42".into()),
            tags: vec!["fm".into(), "north".into()],
        },
        ..new_job("a", 3)
    };
    let first = created(s.insert(keyed("k1"), 0).await.unwrap());
    assert!(
        matches!(s.insert(keyed("k1"), 0).await.unwrap(), Inserted::KeyTaken),
        "{}",
        b.name
    );
    // Keys are per tenant.
    let other = NewJob {
        tenant: "b".into(),
        ..keyed("k1")
    };
    created(s.insert(other, 0).await.unwrap());
    let found = s.by_idempotency_key("a", "k1").await.unwrap().unwrap();
    assert_eq!(
        (found.id, found.idempotency.unwrap().request_hash),
        (first.id, "h1".into())
    );
    assert!(s.by_idempotency_key("a", "k2").await.unwrap().is_none());
    assert_eq!(first.meta.tags, vec!["fm".to_string(), "north".to_string()]);
    assert_eq!(first.input_job, first.id);
    // Filters: every tag asked for, and the reference.
    created(s.insert(new_job("a", 3), 0).await.unwrap());
    let q = |external_ref: Option<&str>, tags: &[&str]| ListQuery {
        tenant: "a".into(),
        limit: 10,
        external_ref: external_ref.map(str::to_string),
        tags: tags.iter().map(|t| t.to_string()).collect(),
        ..Default::default()
    };
    let ids = |jobs: Vec<asbuilt::queue::Job>| jobs.into_iter().map(|j| j.id).collect::<Vec<_>>();
    assert_eq!(s.list(&q(None, &[])).await.unwrap().len(), 2);
    assert_eq!(
        ids(s.list(&q(None, &["fm"])).await.unwrap()),
        vec![first.id]
    );
    assert_eq!(
        ids(s.list(&q(None, &["north", "fm"])).await.unwrap()),
        vec![first.id]
    );
    assert!(s.list(&q(None, &["fm", "south"])).await.unwrap().is_empty());
    assert_eq!(
        ids(s.list(&q(Some("b-42"), &[])).await.unwrap()),
        vec![first.id]
    );
    assert!(s.list(&q(Some("b-43"), &[])).await.unwrap().is_empty());

    // A re-plan reads the first upload; the upload is in use while either row exists.
    let replan = NewJob {
        replan_of: Some((first.id, first.input_job)),
        ..new_job("a", 3)
    };
    let r = created(s.insert(replan, 0).await.unwrap());
    assert_eq!(r.input_job, first.id);
    assert!(r.is_replan() && !first.is_replan());
    assert!(s.delete(first.id).await.unwrap());
    assert!(
        s.upload_in_use(first.id).await.unwrap(),
        "the re-plan still reads it"
    );
    let gone = NewJob {
        replan_of: Some((first.id, first.id)),
        ..new_job("a", 3)
    };
    assert!(matches!(
        s.insert(gone, 0).await.unwrap(),
        Inserted::SourceGone
    ));
    assert!(s.delete(r.id).await.unwrap());
    assert!(!s.upload_in_use(first.id).await.unwrap());

    // Expiry leaves a tombstone for the job's tenant only, until it is forgotten.
    let old = s.create(new_job("a", 3)).await.unwrap();
    assert!(s.expire(old.id).await.unwrap());
    assert!(!s.expire(old.id).await.unwrap());
    assert!(s.get(None, old.id).await.unwrap().is_none());
    let at = s
        .expired_at("a", old.id)
        .await
        .unwrap()
        .expect("a tombstone");
    assert!(at > 0);
    assert!(s.expired_at("b", old.id).await.unwrap().is_none());
    assert!(s.expired_at("a", JobId::new()).await.unwrap().is_none());
    assert_eq!(s.forget_expired(at + 1).await.unwrap(), 1);
    assert!(s.expired_at("a", old.id).await.unwrap().is_none());
}

async fn webhooks_are_claimed_once_and_recorded(b: &Backend) {
    let s = &b.store;
    let hooked = NewJob {
        callback_url: Some("https://hooks.example.com/x".into()),
        ..new_job("a", 3)
    };
    let job = s.create(hooked).await.unwrap();
    s.create(new_job("a", 3)).await.unwrap();
    // Not before it ends.
    assert!(
        s.claim_hooks(60_000, 10).await.unwrap().is_empty(),
        "{}",
        b.name
    );
    for _ in 0..2 {
        let c = s.claim("w", 10_000).await.unwrap().unwrap();
        assert!(s.complete(c.id, "w", &outcome(1)).await.unwrap());
    }
    // Only the job with a callback, once, while leased.
    let other = (b.reopen)().await;
    let got = s.claim_hooks(60_000, 10).await.unwrap();
    assert_eq!(
        got.iter().map(|(j, n)| (j.id, *n)).collect::<Vec<_>>(),
        vec![(job.id, 0)]
    );
    assert!(other.claim_hooks(60_000, 10).await.unwrap().is_empty());
    // A failed attempt due again is claimed again, with its count; a finished one never.
    s.hook_tried(job.id, 1, Some(0)).await.unwrap();
    let again = other.claim_hooks(60_000, 10).await.unwrap();
    assert_eq!(
        again.iter().map(|(j, n)| (j.id, *n)).collect::<Vec<_>>(),
        vec![(job.id, 1)]
    );
    s.hook_tried(job.id, 2, None).await.unwrap();
    assert!(s.claim_hooks(0, 10).await.unwrap().is_empty());
    for attempt in [1u32, 2] {
        s.record_delivery(&Delivery {
            id: uuid::Uuid::now_v7(),
            job: job.id,
            event: "job.succeeded".into(),
            url: "https://hooks.example.com/x".into(),
            attempt,
            at: 1000 * attempt as i64,
            status: if attempt == 1 { Some(503) } else { Some(204) },
            error: (attempt == 1).then(|| "the receiver answered 503".into()),
            duration_ms: 12,
        })
        .await
        .unwrap();
    }
    let d = s.deliveries(job.id).await.unwrap();
    assert_eq!(
        d.iter().map(|x| (x.attempt, x.status)).collect::<Vec<_>>(),
        vec![(1, Some(503)), (2, Some(204))]
    );
    assert_eq!(d[0].error.as_deref(), Some("the receiver answered 503"));
    // Deleting the job takes its deliveries along.
    assert!(s.delete(job.id).await.unwrap());
    assert!(s.deliveries(job.id).await.unwrap().is_empty());
}

async fn ranged_reads_return_the_bytes_asked_for(b: &Backend) {
    let key = format!("jobs/{}/result/plan.svg", JobId::new());
    let bytes: Vec<u8> = (0..1000u32).map(|i| (i % 251) as u8).collect();
    b.blobs.put(&key, Bytes::from(bytes.clone())).await.unwrap();
    assert_eq!(b.blobs.size(&key).await.unwrap(), Some(1000), "{}", b.name);
    for range in [0..10u64, 990..1000, 100..101, 500..1000] {
        let (blob, total) = b
            .blobs
            .get_part(&key, range.clone())
            .await
            .unwrap()
            .unwrap();
        assert_eq!((blob.size, total), (range.end - range.start, 1000));
        let got: Vec<u8> = blob.stream.map(|c| c.unwrap().to_vec()).concat().await;
        assert_eq!(
            got,
            bytes[range.start as usize..range.end as usize].to_vec(),
            "{range:?}"
        );
    }
    let missing = format!("jobs/{}/result/plan.svg", JobId::new());
    assert!(b.blobs.get_part(&missing, 0..1).await.unwrap().is_none());
    assert_eq!(b.blobs.size(&missing).await.unwrap(), None);
}

/// A database that cannot be reached is named with the cause, not only the pool's timeout.
#[tokio::test]
async fn an_unreachable_database_is_named_with_its_cause() {
    // A port nothing listens on: taken from the system, then let go.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let url = format!("postgres://asbuilt@127.0.0.1:{port}/test");
    let err = match PgJobStore::connect(&url).await {
        Err(e) => e.to_string(),
        Ok(_) => panic!("nothing listens on port {port}"),
    };
    assert!(err.contains(&format!("127.0.0.1:{port}")), "{err}");
    assert!(err.to_lowercase().contains("refused"), "{err}");
}
