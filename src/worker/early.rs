//! Reading an upload while it arrives, so that when its last byte lands only the stages after
//! reading remain.
//!
//! It is only a head start. The upload is stored whole as before, and the job runs from the
//! stored file whenever the early read is missing (another process, a restart, a retry, a
//! re-plan), failed (a truncated or corrupt file: the stored file's read then gives the usual
//! error), or saw other bytes than were stored. One upload at a time is read early, and only
//! while a worker of this process is idle, so the process holds at most one decoded cloud that
//! no worker has taken yet.
//!
//! The bytes go to an unlinked scratch file as the request body passes (the reader may seek),
//! and a reader thread follows them: a read past what has arrived waits for more. LAZ chunks
//! are decoded front to back as they come, and those left when the last byte is in are decoded
//! in parallel from the chunk table at the file's end (`io::read_laz_arriving`). Formats whose
//! reader needs the end of the file first (E57's XML) are left to the worker.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use std::os::unix::fs::FileExt;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use asbuilt_plan::io::detect::{detect, Format, SNIFF_LEN};
use asbuilt_plan::io::{
    declared_points_in_head, read_cloud_from, read_laz_arriving, Arriving, ReadOptions,
};
use asbuilt_plan::PointCloud;

use crate::queue::JobId;

/// Formats whose readers go from the front of the file to its end (`las` covers LAZ).
const FRONT_TO_BACK: [&str; 4] = ["ply", "las", "xyz", "pts"];

/// The bytes a header's count is looked for in.
const HEAD: u64 = 64 << 10;

/// The shortest line a point takes in a text cloud: `0 0 0\n`.
const MIN_TEXT_POINT: u64 = 6;

/// An early read no worker took within this time (its job was cancelled, or waits behind
/// others) gives way to the next upload.
const UNCLAIMED: Duration = Duration::from_secs(600);

/// The process's early reads: at most one.
pub struct Early {
    enabled: bool,
    /// This process's workers, and how many are running a job: a cloud read while every
    /// worker is busy would wait in memory beside the clouds being planned.
    workers: usize,
    busy: AtomicUsize,
    dir: PathBuf,
    max_points: u64,
    slot: Mutex<Option<Pending>>,
}

/// A read begun for one job's upload.
#[derive(Debug)]
pub struct Pending {
    job: JobId,
    begun: Instant,
    growth: Arc<Growth>,
    /// The cloud and when the read ended.
    reader: JoinHandle<(Result<PointCloud, String>, Instant)>,
}

/// A decoded cloud handed to the pipeline with the job's inputs; the pipeline takes it once.
#[derive(Clone, Default)]
pub struct EarlyCloud(Arc<Mutex<Option<Decoded>>>);

impl EarlyCloud {
    pub fn new(decoded: Decoded) -> EarlyCloud {
        EarlyCloud(Arc::new(Mutex::new(Some(decoded))))
    }

    pub fn take(&self) -> Option<Decoded> {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).take()
    }
}

impl std::fmt::Debug for EarlyCloud {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("EarlyCloud")
    }
}

/// What an early read gave the worker.
pub struct Decoded {
    pub cloud: PointCloud,
    /// The upload's size as the read saw it.
    pub bytes: u64,
    /// From the last byte's arrival to the end of the read (0 when the read kept up).
    pub read_ms: u64,
}

impl Early {
    /// `enabled` when this process runs workers that can use a decoded cloud; scratch files go
    /// in `dir`; clouds over `max_points` are left to the worker, which refuses them.
    pub fn new(enabled: bool, dir: PathBuf, max_points: u64, workers: usize) -> Early {
        Early {
            enabled,
            workers,
            busy: AtomicUsize::new(0),
            dir,
            max_points,
            slot: Mutex::new(None),
        }
    }

    /// A worker starts (`true`) or ends (`false`) a job.
    pub fn working(&self, started: bool) {
        match started {
            true => self.busy.fetch_add(1, Ordering::Relaxed),
            false => self.busy.fetch_sub(1, Ordering::Relaxed),
        };
    }

    fn slot(&self) -> MutexGuard<'_, Option<Pending>> {
        self.slot.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Starts reading `job`'s upload of `format` and `total` bytes, when it can be read from
    /// the front and no other early read holds the slot. The returned [`Feed`] takes the bytes.
    pub fn begin(&self, job: JobId, format: &str, total: Option<u64>) -> Option<Feed> {
        let total = total.filter(|&t| t > 0)?;
        if !self.enabled || !FRONT_TO_BACK.contains(&format) {
            return None;
        }
        if self.busy.load(Ordering::Relaxed) >= self.workers {
            return None;
        }
        // Text declares no count: the read starts only when the file cannot hold more points
        // than the limit (a point's line has at least 6 bytes).
        if matches!(format, "xyz" | "pts") && total / MIN_TEXT_POINT > self.max_points {
            return None;
        }
        let mut slot = self.slot();
        if slot.as_ref().is_some_and(|p| p.begun.elapsed() < UNCLAIMED) {
            return None;
        }
        // An unclaimed read is dropped; its thread ends when its feed does.
        *slot = None;
        let file = scratch_file(&self.dir, job)
            .map_err(|e| tracing::warn!(job = %job, error = %e, "no early read: scratch file"))
            .ok()?;
        let source = file.try_clone().ok()?;
        let growth = Arc::new(Growth::default());
        let follow = Growing {
            file: source,
            growth: growth.clone(),
            total,
            position: 0,
        };
        let max_points = self.max_points;
        let reader = std::thread::Builder::new()
            .name("asbuilt-early-read".into())
            .spawn(move || (read(follow, max_points), Instant::now()))
            .ok()?;
        *slot = Some(Pending {
            job,
            begun: Instant::now(),
            growth: growth.clone(),
            reader,
        });
        Some(Feed {
            file: Mutex::new(file),
            growth,
            total,
            finished: false,
        })
    }

    /// Drops `job`'s early read (its upload was refused).
    pub fn forget(&self, job: JobId) {
        let mut slot = self.slot();
        if slot.as_ref().is_some_and(|p| p.job == job) {
            *slot = None;
        }
    }

    /// Takes `job`'s early read, if this process began one.
    pub fn take(&self, job: JobId) -> Option<Pending> {
        let mut slot = self.slot();
        match slot.as_ref() {
            Some(p) if p.job == job => slot.take(),
            _ => None,
        }
    }
}

impl Pending {
    /// Waits for the read to end (blocking): the cloud, or why the read failed.
    pub fn finish(self) -> Result<Decoded, String> {
        let (cloud, ended) = self
            .reader
            .join()
            .unwrap_or_else(|_| (Err("the early read panicked".into()), Instant::now()));
        let cloud = cloud?;
        let state = self.growth.state();
        let End::Whole(at) = state.end else {
            return Err("the upload did not arrive whole".into());
        };
        Ok(Decoded {
            cloud,
            bytes: state.written,
            read_ms: ended.saturating_duration_since(at).as_millis() as u64,
        })
    }
}

/// The early read: the header's count against the limit first, as `plan_scan` does before it
/// allocates, then the cloud.
fn read(mut source: Growing, max_points: u64) -> Result<PointCloud, String> {
    let mut head = vec![0; source.total.min(HEAD) as usize];
    source
        .read_exact(&mut head)
        .and_then(|_| source.seek(SeekFrom::Start(0)))
        .map_err(|e| e.to_string())?;
    if let Some(n) = declared_points_in_head(&head).filter(|&n| n > max_points) {
        return Err(format!("{n} points, over the limit"));
    }
    let options = ReadOptions::default();
    match detect(&head[..head.len().min(SNIFF_LEN)]) {
        Ok(Format::Laz) => read_laz_arriving(source, "cloud", &options),
        _ => read_cloud_from(source, "cloud", &options),
    }
    .map_err(|e| e.to_string())
}

/// An unlinked file: it goes when the last handle closes, whatever happens to the process.
fn scratch_file(dir: &std::path::Path, job: JobId) -> std::io::Result<File> {
    std::fs::create_dir_all(dir)?;
    let path = dir.join(format!("early-{job}"));
    let file = File::options()
        .read(true)
        .write(true)
        .create(true)
        .truncate(true)
        .open(&path)?;
    std::fs::remove_file(&path)?;
    Ok(file)
}

/// How much of the upload has arrived, and whether it ended.
#[derive(Debug, Default)]
struct Growth {
    state: Mutex<Arrived>,
    more: Condvar,
}

#[derive(Debug, Default, Clone, Copy)]
struct Arrived {
    written: u64,
    end: End,
}

#[derive(Debug, Default, Clone, Copy)]
enum End {
    #[default]
    Open,
    /// Every byte arrived, at this instant.
    Whole(Instant),
    /// The upload failed or was refused, or the scratch file could not be written.
    Broken,
}

impl Growth {
    fn state(&self) -> Arrived {
        *self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn update(&self, f: impl FnOnce(&mut Arrived)) {
        f(&mut self.state.lock().unwrap_or_else(|p| p.into_inner()));
        self.more.notify_all();
    }
}

/// The request's side: appends the body's bytes as they pass on their way to storage.
pub struct Feed {
    file: Mutex<File>,
    growth: Arc<Growth>,
    total: u64,
    finished: bool,
}

impl Feed {
    /// Appends a chunk of the body.
    pub fn push(&self, chunk: &[u8]) {
        let state = self.growth.state();
        if !matches!(state.end, End::Open) {
            return;
        }
        let fits = state.written + chunk.len() as u64 <= self.total;
        let written = fits
            && self
                .file
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .write_all(chunk)
                .is_ok();
        self.growth.update(|s| match written {
            true => s.written += chunk.len() as u64,
            false => s.end = End::Broken,
        });
    }

    /// The upload was stored as `bytes`: the read may finish, if it saw exactly those bytes.
    pub fn finish(mut self, bytes: u64) {
        self.finished = true;
        self.growth.update(|s| {
            s.end = match s.end {
                End::Open if s.written == bytes && bytes == self.total => {
                    End::Whole(Instant::now())
                }
                _ => End::Broken,
            }
        });
    }
}

impl Drop for Feed {
    /// A feed dropped unfinished (a refused or interrupted upload) ends its read with an error.
    fn drop(&mut self) {
        if !self.finished {
            self.growth.update(|s| s.end = End::Broken);
        }
    }
}

/// The reader's side: the upload as a file of its declared length whose reads wait for the
/// bytes to arrive.
struct Growing {
    file: File,
    growth: Arc<Growth>,
    total: u64,
    position: u64,
}

impl Read for Growing {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if buf.is_empty() || self.position >= self.total {
            return Ok(0);
        }
        let guard = self.growth.state.lock().unwrap_or_else(|p| p.into_inner());
        let guard = self
            .growth
            .more
            .wait_while(guard, |s| {
                s.written <= self.position && matches!(s.end, End::Open)
            })
            .unwrap_or_else(|p| p.into_inner());
        let arrived = *guard;
        drop(guard);
        if matches!(arrived.end, End::Broken) {
            return Err(std::io::Error::other("the upload did not arrive whole"));
        }
        if arrived.written <= self.position {
            // Ended whole but shorter than declared.
            return Ok(0);
        }
        let n = (arrived.written - self.position).min(buf.len() as u64) as usize;
        let n = self.file.read_at(&mut buf[..n], self.position)?;
        self.position += n as u64;
        Ok(n)
    }
}

impl Arriving for Growing {
    fn arrived(&self) -> bool {
        let state = self.growth.state();
        state.written >= self.total || !matches!(state.end, End::Open)
    }

    fn available(&self) -> u64 {
        self.growth.state().written
    }

    fn another(&self) -> std::io::Result<Self> {
        Ok(Growing {
            file: self.file.try_clone()?,
            growth: self.growth.clone(),
            total: self.total,
            position: 0,
        })
    }
}

impl Seek for Growing {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        let to = match pos {
            SeekFrom::Start(p) => Some(p),
            SeekFrom::End(d) => self.total.checked_add_signed(d),
            SeekFrom::Current(d) => self.position.checked_add_signed(d),
        };
        self.position =
            to.ok_or_else(|| std::io::Error::other("a seek before the start of the upload"))?;
        Ok(self.position)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use asbuilt_plan::io::ply::{write_ply, Encoding};
    use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};

    fn ply_bytes() -> Vec<u8> {
        let options = ScanOptions {
            points: 20_000,
            seed: 2,
            ..Default::default()
        };
        let sim = simulate(BuildingKind::SquareRoom, &options).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("room.ply");
        write_ply(&path, &sim.cloud, Encoding::BinaryLittleEndian).unwrap();
        std::fs::read(path).unwrap()
    }

    #[test]
    fn a_read_that_follows_the_bytes_gives_the_files_points() {
        let bytes = ply_bytes();
        let dir = tempfile::tempdir().unwrap();
        let early = Early::new(true, dir.path().into(), 1_000_000, 1);
        let job = JobId::new();
        let feed = early
            .begin(job, "ply", Some(bytes.len() as u64))
            .expect("an early read");
        // A second upload waits its turn.
        assert!(early.begin(JobId::new(), "ply", Some(10)).is_none());
        let sender = std::thread::spawn(move || {
            for chunk in bytes.chunks(7_919) {
                feed.push(chunk);
            }
            feed.finish(bytes.len() as u64);
            bytes
        });
        let bytes = sender.join().unwrap();
        let decoded = early.take(job).unwrap().finish().unwrap();
        let whole = asbuilt_plan::io::read_cloud_from(
            std::io::Cursor::new(bytes.clone()),
            "cloud",
            &ReadOptions::default(),
        )
        .unwrap();
        assert_eq!(decoded.bytes, bytes.len() as u64);
        assert_eq!(decoded.cloud.xyz, whole.xyz);
        assert_eq!(decoded.cloud.origin, whole.origin);
        // The slot is free again, and nothing is left in the scratch folder.
        assert!(early.take(job).is_none());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    /// A simulated room as LAZ: three chunks of 50 000 points, the last short.
    fn laz_bytes() -> Vec<u8> {
        let options = ScanOptions {
            points: 120_000,
            seed: 3,
            ..Default::default()
        };
        let sim = simulate(BuildingKind::SquareRoom, &options).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("room.laz");
        asbuilt_plan::io::export::write_las(&path, &sim.cloud, true).unwrap();
        std::fs::read(path).unwrap()
    }

    /// Uploads `bytes` declared as `total` through an early read, in pieces of random sizes
    /// with pauses between them, and gives what the read made of them.
    fn upload(bytes: Vec<u8>, total: u64, seed: u64) -> Result<Decoded, String> {
        let dir = tempfile::tempdir().unwrap();
        let early = Early::new(true, dir.path().into(), 10_000_000, 1);
        let job = JobId::new();
        let feed = early.begin(job, "las", Some(total)).expect("an early read");
        let sender = std::thread::spawn(move || {
            let (mut state, mut at) = (seed | 1, 0);
            while at < bytes.len() {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let n = (1 + (state % 20_000) as usize).min(bytes.len() - at);
                feed.push(&bytes[at..at + n]);
                at += n;
                std::thread::sleep(Duration::from_micros(200));
            }
            feed.finish(bytes.len() as u64);
        });
        sender.join().unwrap();
        early.take(job).unwrap().finish()
    }

    #[test]
    fn a_laz_read_as_it_arrives_gives_the_files_cloud() {
        let bytes = laz_bytes();
        let whole = read_cloud_from(
            std::io::Cursor::new(bytes.clone()),
            "cloud",
            &ReadOptions::default(),
        )
        .unwrap();
        for seed in [1, 2] {
            let decoded = upload(bytes.clone(), bytes.len() as u64, seed).unwrap();
            let c = &decoded.cloud;
            assert_eq!(decoded.bytes, bytes.len() as u64);
            assert_eq!(c.xyz, whole.xyz);
            assert_eq!(c.scan, whole.scan);
            assert_eq!(c.scan_ids, whole.scan_ids);
            assert_eq!(c.time, whole.time);
            assert_eq!(c.origin, whole.origin);
            assert_eq!(c.source, whole.source);
        }
    }

    #[test]
    fn a_cut_or_damaged_laz_fails_its_early_read_or_reads_as_the_stored_file() {
        let bytes = laz_bytes();
        let len = bytes.len();
        // Cut: the stored file fails too, and the worker reports its error.
        let cut = bytes[..len * 2 / 3].to_vec();
        let stored = read_cloud_from(
            std::io::Cursor::new(cut.clone()),
            "cloud",
            &ReadOptions::default(),
        );
        assert!(stored.is_err());
        assert!(upload(cut.clone(), cut.len() as u64, 4).is_err());
        // A damaged chunk table: the early read may only give what the stored read gives.
        for back in [2, 5, 9] {
            let mut damaged = bytes.clone();
            damaged[len - back] ^= 0x5a;
            let stored = read_cloud_from(
                std::io::Cursor::new(damaged.clone()),
                "cloud",
                &ReadOptions::default(),
            );
            match (upload(damaged, len as u64, 5), stored) {
                (Ok(early), Ok(stored)) => {
                    assert_eq!(early.cloud.xyz, stored.xyz);
                    assert_eq!(early.cloud.source, stored.source);
                }
                (Ok(_), Err(e)) => panic!("read early, but the stored file fails: {e}"),
                (Err(_), _) => {}
            }
        }
    }

    #[test]
    fn a_cut_or_refused_upload_ends_the_read_with_an_error() {
        let bytes = ply_bytes();
        let dir = tempfile::tempdir().unwrap();
        let early = Early::new(true, dir.path().into(), 1_000_000, 1);
        // Stored shorter than declared.
        let job = JobId::new();
        let feed = early.begin(job, "ply", Some(bytes.len() as u64)).unwrap();
        feed.push(&bytes[..bytes.len() / 2]);
        feed.finish(bytes.len() as u64 / 2);
        assert!(early.take(job).unwrap().finish().is_err());
        // Dropped mid-way (the request went away).
        let job = JobId::new();
        let feed = early.begin(job, "ply", Some(bytes.len() as u64)).unwrap();
        feed.push(&bytes[..1000]);
        drop(feed);
        assert!(early.take(job).unwrap().finish().is_err());
        // Longer than declared.
        let job = JobId::new();
        let feed = early.begin(job, "ply", Some(100)).unwrap();
        feed.push(&bytes[..200]);
        feed.finish(200);
        assert!(early.take(job).unwrap().finish().is_err());
    }

    #[test]
    fn a_header_over_the_limit_ends_the_read_before_it_allocates() {
        let bytes = ply_bytes();
        let dir = tempfile::tempdir().unwrap();
        let early = Early::new(true, dir.path().into(), 100, 1);
        let job = JobId::new();
        let feed = early.begin(job, "ply", Some(bytes.len() as u64)).unwrap();
        feed.push(&bytes);
        feed.finish(bytes.len() as u64);
        let why = early.take(job).unwrap().finish().err().unwrap();
        assert!(why.ends_with("points, over the limit"), "{why}");
    }

    #[test]
    fn only_formats_read_front_to_back_are_read_early() {
        let dir = tempfile::tempdir().unwrap();
        let early = Early::new(true, dir.path().into(), 1_000_000, 1);
        for format in ["e57", "laz"] {
            assert!(early.begin(JobId::new(), format, Some(1000)).is_none());
        }
        assert!(early.begin(JobId::new(), "las", None).is_none());
        // Text that could hold more points than the limit.
        assert!(early.begin(JobId::new(), "xyz", Some(6_000_007)).is_none());
        let off = Early::new(false, dir.path().into(), 1_000_000, 1);
        assert!(off.begin(JobId::new(), "ply", Some(1000)).is_none());
        // Not while every worker is busy, nor after a cancelled job's read was forgotten.
        let early = Early::new(true, dir.path().into(), 1_000_000, 1);
        early.working(true);
        assert!(early.begin(JobId::new(), "ply", Some(1000)).is_none());
        early.working(false);
        let job = JobId::new();
        let feed = early.begin(job, "ply", Some(1000));
        assert!(feed.is_some());
        early.forget(job);
        assert!(early.take(job).is_none());
        assert!(early.begin(JobId::new(), "ply", Some(1000)).is_some());
    }
}
