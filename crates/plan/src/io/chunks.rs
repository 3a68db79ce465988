//! Reading a cloud a batch of points at a time, for clouds larger than memory
//! ([`crate::streaming`]).
//!
//! A chunked read yields exactly the points, local frame, scan slots and times that the
//! whole-cloud reader of the same file builds, in the same order: each format's chunk reader
//! drives that reader's own point sink and hands its arrays over a batch at a time. PLY (binary
//! and ASCII) and LAS/LAZ read in chunks; other formats are refused with a clear error.

use std::fs::File;
use std::path::Path;

use super::{Format, ReadError, ReadOptions};
use crate::cloud::PointCloud;

/// Points per batch: big enough to amortise calls, small enough to stay in cache.
pub const CHUNK_POINTS: usize = 1 << 16;

/// A batch of points in the local frame every batch of the read shares.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct PointChunk {
    /// Local x, y, z.
    pub xyz: Vec<[f32; 3]>,
    /// Per point, its scan slot (indexing the skeleton's `scan_ids`); empty when the file names
    /// no scans.
    pub scan: Vec<u16>,
    /// Per point, its time; empty when the file has none or times are not kept.
    pub time: Vec<f64>,
}

impl PointChunk {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.xyz.len()
    }

    /// True when the batch holds no points.
    pub fn is_empty(&self) -> bool {
        self.xyz.is_empty()
    }

    fn clear(&mut self) {
        self.xyz.clear();
        self.scan.clear();
        self.time.clear();
    }
}

/// A cloud read a batch at a time.
pub trait PointChunks {
    /// Fills `chunk` (cleared first) with the next batch of points. Returns false, with
    /// `chunk` empty, once every point has been read.
    fn next_chunk(&mut self, chunk: &mut PointChunk) -> Result<bool, ReadError>;

    /// The cloud without its points: origin, scan ids, viewpoints, CRS and source summary, as
    /// far as they are known; complete once `next_chunk` has returned false.
    fn skeleton(&self) -> Result<PointCloud, ReadError>;
}

/// Opens `path` for a chunked read, choosing the reader from the file's content (or
/// `options.format`). The points come out scaled by `options.scale`, as
/// [`super::read_cloud_with`] scales them.
///
/// The file is decoded on a thread of its own, a few batches ahead of the caller, with the
/// large stack and the panic guard of the whole-file readers.
pub fn open_chunks(path: &Path, options: &ReadOptions) -> Result<Box<dyn PointChunks>, ReadError> {
    let name = path.display().to_string();
    let mut file = File::open(path).map_err(|e| ReadError::io(&name, e))?;
    let head = super::sniff(&mut file, &name)?;
    let format = super::choose_format(&name, &head, options)?;
    if !matches!(format, Format::Ply | Format::Las | Format::Laz) {
        return Err(ReadError::Options {
            path: name,
            why: format!(
                "{} cannot be read in chunks yet (PLY, LAS and LAZ can); read it whole, or convert it",
                format.name()
            ),
        });
    }
    let len = file.metadata().map_err(|e| ReadError::io(&name, e))?.len();
    let mut note = String::new();
    if let Some(named) = Format::from_extension(path) {
        let same = named == format || matches!((named, format), (Format::Las, Format::Laz));
        if !same && options.format.is_none() {
            note = format!("; read as {format} from its content, although the name says .{named}");
        }
    }
    let owned = path.to_path_buf();
    let opts = options.clone();
    let open = move || -> Result<Box<dyn PointChunks>, ReadError> {
        Ok(match format {
            Format::Ply => Box::new(super::ply::PlyChunks::open(&owned, opts.keep_time)?),
            // The LAZ decoder reads a byte at a time: buffer it.
            _ => Box::new(super::las::LasChunks::open(
                std::io::BufReader::with_capacity(1 << 16, file),
                len,
                &owned.display().to_string(),
                &opts,
            )?),
        })
    };
    let inner = Threaded::spawn(open, name.clone(), format)?;
    Ok(Box::new(Finished {
        inner: Box::new(inner),
        name,
        options: options.clone(),
        note,
    }))
}

/// What the decoding thread sends.
enum Msg {
    Chunk(PointChunk),
    Done(Result<PointCloud, ReadError>),
    Failed(ReadError),
}

/// Batches decoded on another thread; used batches go back to it for reuse.
struct Threaded {
    rx: std::sync::mpsc::Receiver<Msg>,
    back: std::sync::mpsc::SyncSender<PointChunk>,
    worker: Option<std::thread::JoinHandle<()>>,
    skeleton: Option<Result<PointCloud, ReadError>>,
    name: String,
    format: Format,
}

impl Threaded {
    /// Batches in flight between the threads.
    const AHEAD: usize = 3;
    /// As for the whole-file readers: the LAZ decoder recurses deeply on some files.
    const STACK: usize = 1 << 30;

    fn spawn(
        open: impl FnOnce() -> Result<Box<dyn PointChunks>, ReadError> + Send + 'static,
        name: String,
        format: Format,
    ) -> Result<Threaded, ReadError> {
        let (tx, rx) = std::sync::mpsc::sync_channel(Self::AHEAD);
        let (back, spare) = std::sync::mpsc::sync_channel::<PointChunk>(Self::AHEAD + 2);
        let worker = std::thread::Builder::new()
            .name("asbuilt-chunks".into())
            .stack_size(Self::STACK)
            .spawn(move || {
                let mut reader = match open() {
                    Ok(r) => r,
                    Err(e) => {
                        let _ = tx.send(Msg::Failed(e));
                        return;
                    }
                };
                loop {
                    let mut chunk = spare.try_recv().unwrap_or_default();
                    match reader.next_chunk(&mut chunk) {
                        Ok(true) => {
                            if tx.send(Msg::Chunk(chunk)).is_err() {
                                return;
                            }
                        }
                        Ok(false) => {
                            let _ = tx.send(Msg::Done(reader.skeleton()));
                            return;
                        }
                        Err(e) => {
                            let _ = tx.send(Msg::Failed(e));
                            return;
                        }
                    }
                }
            })
            .map_err(|e| ReadError::io(&name, e))?;
        Ok(Threaded {
            rx,
            back,
            worker: Some(worker),
            skeleton: None,
            name,
            format,
        })
    }

    /// The decoder's panic, as an error naming the file.
    fn crashed(&mut self) -> ReadError {
        let what = self
            .worker
            .take()
            .and_then(|w| w.join().err())
            .map(|panic| {
                panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_default()
            })
            .unwrap_or_default();
        ReadError::named(
            &self.name,
            self.format.name(),
            format!("the decoder failed ({what}); the file is probably corrupt"),
        )
    }
}

impl PointChunks for Threaded {
    fn next_chunk(&mut self, chunk: &mut PointChunk) -> Result<bool, ReadError> {
        if self.skeleton.is_some() {
            chunk.clear();
            return Ok(false);
        }
        match self.rx.recv() {
            Ok(Msg::Chunk(mut c)) => {
                std::mem::swap(chunk, &mut c);
                let _ = self.back.try_send(c);
                Ok(true)
            }
            Ok(Msg::Done(skeleton)) => {
                if let Some(w) = self.worker.take() {
                    let _ = w.join();
                }
                self.skeleton = Some(skeleton);
                chunk.clear();
                Ok(false)
            }
            Ok(Msg::Failed(e)) => Err(e),
            Err(_) => Err(self.crashed()),
        }
    }

    fn skeleton(&self) -> Result<PointCloud, ReadError> {
        match &self.skeleton {
            Some(Ok(c)) => Ok(c.clone()),
            Some(Err(e)) => Err(ReadError::named(
                &self.name,
                self.format.name(),
                e.to_string(),
            )),
            None => Err(ReadError::named(
                &self.name,
                self.format.name(),
                "the skeleton was asked for before the last batch",
            )),
        }
    }
}

/// Scales every batch, and finishes the skeleton as the whole-file reader finishes a cloud
/// (scale, units, details, checks).
struct Finished {
    inner: Box<dyn PointChunks>,
    name: String,
    options: ReadOptions,
    note: String,
}

impl PointChunks for Finished {
    fn next_chunk(&mut self, chunk: &mut PointChunk) -> Result<bool, ReadError> {
        let more = self.inner.next_chunk(chunk)?;
        if let Some(s) = self.options.scale {
            let sf = s as f32;
            for p in &mut chunk.xyz {
                *p = p.map(|c| c * sf);
            }
        }
        Ok(more)
    }

    fn skeleton(&self) -> Result<PointCloud, ReadError> {
        let mut cloud = self.inner.skeleton()?;
        cloud.source.details += &self.note;
        super::finish(cloud, &self.name, &self.options)
    }
}

/// Moves a sink's accumulated arrays into `chunk`, leaving the sink empty arrays of the
/// same capacity, so batches reuse their buffers.
pub(crate) fn hand_over(
    chunk: &mut PointChunk,
    xyz: &mut Vec<[f32; 3]>,
    scan: &mut Vec<u16>,
    time: &mut Vec<f64>,
) {
    chunk.clear();
    std::mem::swap(&mut chunk.xyz, xyz);
    std::mem::swap(&mut chunk.scan, scan);
    std::mem::swap(&mut chunk.time, time);
}

/// Reads every batch of `reader` into one cloud: what the whole-file reader gives, for tests.
pub fn collect(mut reader: Box<dyn PointChunks>) -> Result<PointCloud, ReadError> {
    let mut chunk = PointChunk::default();
    let mut xyz = Vec::new();
    let mut scan = Vec::new();
    let mut time = Vec::new();
    while reader.next_chunk(&mut chunk)? {
        xyz.extend_from_slice(&chunk.xyz);
        scan.extend_from_slice(&chunk.scan);
        time.extend_from_slice(&chunk.time);
    }
    let mut cloud = reader.skeleton()?;
    cloud.xyz = xyz;
    cloud.scan = scan;
    cloud.time = time;
    Ok(cloud)
}
