//! Reading clouds and pose sidecars, and writing plans. The only module that touches files.

mod assemble;
pub mod chunks;
mod count;
pub mod detect;
pub(crate) mod dxf;
pub(crate) mod e57;
pub mod export;
pub mod geojson;
pub(crate) mod las;
pub mod outputs;
mod pages;
pub mod ply;
mod pool;
pub mod poses;
pub(crate) mod sidecar;
pub(crate) mod spill;
pub(crate) mod svg;
mod units;
pub mod wgs84;
pub(crate) mod xyz;

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use crate::cancel::{Cancel, Cancelled};
use crate::cloud::{PointCloud, Viewpoints};
pub use count::{declared_points, declared_points_in_head};
pub use detect::Format;
pub use las::Arriving;
pub use pages::keep_freed_memory;
pub use sidecar::{Sidecar, SidecarKind};
pub use units::{check_units, UnitsError};

/// Why a file could not be read. Every variant names the file and, where it helps, the place.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// Opening or reading the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file is none of the formats read.
    #[error("{path}: unrecognised format ({why})")]
    UnknownFormat {
        /// The file.
        path: String,
        /// What was seen.
        why: String,
    },
    /// The file is malformed for its format.
    #[error("{path} ({format}): {why}{}", at.as_ref().map(|a| format!(" at {a}")).unwrap_or_default())]
    Invalid {
        /// The file.
        path: String,
        /// The format it was read as.
        format: &'static str,
        /// What is wrong.
        why: String,
        /// Where, when known (a line, a record).
        at: Option<String>,
    },
    /// The pose sidecar is malformed.
    #[error("{path}: poses: {why}")]
    Poses {
        /// The file.
        path: String,
        /// What is wrong.
        why: String,
    },
    /// The read options do not suit the file.
    #[error("{path}: {why}")]
    Options {
        /// The file.
        path: String,
        /// What is wrong.
        why: String,
    },
    /// `ReadOptions::cancel` stopped the read.
    #[error("{1}: reading stopped: {0}")]
    Cancelled(Cancelled, String),
}

impl ReadError {
    /// Shorthand for a format error without a location.
    pub fn invalid(path: &Path, format: &'static str, why: impl Into<String>) -> ReadError {
        ReadError::Invalid {
            path: path.display().to_string(),
            format,
            why: why.into(),
            at: None,
        }
    }

    /// A format error at a place in the file (`byte 1234`, `line 57`, `scan 3`).
    pub fn at(
        name: &str,
        format: &'static str,
        why: impl Into<String>,
        at: impl Into<String>,
    ) -> ReadError {
        ReadError::Invalid {
            path: name.to_string(),
            format,
            why: why.into(),
            at: Some(at.into()),
        }
    }

    /// A format error without a location, for a file known by name.
    pub fn named(name: &str, format: &'static str, why: impl Into<String>) -> ReadError {
        ReadError::Invalid {
            path: name.to_string(),
            format,
            why: why.into(),
            at: None,
        }
    }

    /// An I/O error while reading the named file.
    pub fn io(name: &str, source: std::io::Error) -> ReadError {
        ReadError::Io {
            path: name.to_string(),
            source,
        }
    }

    /// A stable machine-readable code for the service's error bodies.
    pub fn code(&self) -> &'static str {
        match self {
            ReadError::Io { .. } => "io_error",
            ReadError::UnknownFormat { .. } => "unknown_format",
            ReadError::Invalid { .. } => "invalid_file",
            ReadError::Poses { .. } => "invalid_poses",
            ReadError::Options { .. } => "invalid_options",
            ReadError::Cancelled(c, _) => c.code(),
        }
    }
}

/// How to read a cloud: everything here has a safe default.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadOptions {
    /// Multiply coordinates by this to get metres (0.001 for millimetres). `None` keeps them.
    pub scale: Option<f64>,
    /// XYZ/PTS: the zero-based column holding each point's scan index (x is column 0).
    pub scan_column: Option<usize>,
    /// Use this reader instead of detecting the format from the content.
    pub format: Option<Format>,
    /// Keep per-point acquisition times (LAS `gps_time`, PLY `time`). They cost 8 bytes a point,
    /// so callers without a trajectory may turn them off.
    pub keep_time: bool,
    /// Stops the read (checked every time the reader asks its source for bytes, about every
    /// megabyte); the read then fails with [`ReadError::Cancelled`].
    pub cancel: Cancel,
    /// Counts how far into the file the reader has got, for progress reports.
    pub bytes: BytesRead,
}

/// How far into a cloud's file its reader has got (the furthest byte asked for), shared with
/// whoever reports progress: the reader runs on a thread of its own. The default counts
/// nothing.
#[derive(Debug, Clone, Default)]
pub struct BytesRead(Option<Arc<AtomicU64>>);

impl BytesRead {
    /// A counter that counts.
    pub fn counting() -> BytesRead {
        BytesRead(Some(Arc::default()))
    }

    /// Bytes read so far (0 for a counter that does not count).
    pub fn get(&self) -> u64 {
        self.0.as_ref().map_or(0, |c| c.load(Ordering::Relaxed))
    }

    fn reached(&self, position: u64) {
        if let Some(c) = &self.0 {
            c.fetch_max(position, Ordering::Relaxed);
        }
    }
}

/// Any two counters are equal, as [`Cancel`]s are: options holding one still compare by what
/// they say about the file.
impl PartialEq for BytesRead {
    fn eq(&self, _: &BytesRead) -> bool {
        true
    }
}

impl Default for ReadOptions {
    fn default() -> Self {
        ReadOptions {
            scale: None,
            scan_column: None,
            format: None,
            keep_time: true,
            cancel: Cancel::never(),
            bytes: BytesRead::default(),
        }
    }
}

/// Reads a point cloud, choosing the reader from the file's content.
pub fn read_cloud(path: &Path) -> Result<PointCloud, ReadError> {
    read_cloud_with(path, &ReadOptions::default())
}

/// Reads a point cloud with options; the format comes from the content unless `options` names it.
pub fn read_cloud_with(path: &Path, options: &ReadOptions) -> Result<PointCloud, ReadError> {
    let name = path.display().to_string();
    let mut file = File::open(path).map_err(|e| ReadError::io(&name, e))?;
    let head = sniff(&mut file, &name)?;
    let format = choose_format(&name, &head, options)?;
    // Fixed-size records are decoded straight from a map of the file, without a copy.
    let map = match format {
        Format::Ply | Format::Las => pages::Mapped::new(&file, options),
        _ => None,
    };
    let file = Checked::new(file, options);
    let read = match (format, map) {
        (Format::Ply, Some(map)) => ply::read_ply_mapped(file, &map, &name, options.keep_time),
        (Format::Ply, None) => {
            let len = file
                .inner
                .metadata()
                .map_err(|e| ReadError::io(&name, e))?
                .len();
            ply::read_ply_from(file, len, &name, options.keep_time)
        }
        (_, map) => read_stream(file, &name, format, options, map),
    };
    let mut cloud = stopped(read, &name, options)?;
    if let Some(named) = Format::from_extension(path) {
        let same = named == format || matches!((named, format), (Format::Las, Format::Laz));
        if !same && options.format.is_none() {
            cloud.source.details +=
                &format!("; read as {format} from its content, although the name says .{named}");
        }
    }
    finish(cloud, &name, options)
}

/// Reads a point cloud and attaches its sidecar, scaled as the cloud is; errors name the file
/// at fault. Static poses make the points' times useless, so they are not kept.
pub fn read_scan(
    path: &Path,
    sidecar: Option<(SidecarKind, &Path)>,
    options: &ReadOptions,
) -> Result<PointCloud, ReadError> {
    let posed = matches!(sidecar, Some((SidecarKind::Poses, _)));
    let options = &ReadOptions {
        keep_time: options.keep_time && !posed,
        ..options.clone()
    };
    let mut cloud = read_cloud_with(path, options)?;
    if let Some((kind, file)) = sidecar {
        sidecar::read_scaled(kind, file, options.scale)?
            .attach(&mut cloud)
            .map_err(|e| sidecar::misfit(file, e))?;
    }
    Ok(cloud)
}

/// Reads a point cloud from any seekable source (an upload held in memory, say); `name` is
/// used in errors.
pub fn read_cloud_from<R>(
    mut source: R,
    name: &str,
    options: &ReadOptions,
) -> Result<PointCloud, ReadError>
where
    R: Read + Seek + Send + Sync + 'static,
{
    let head = sniff(&mut source, name)?;
    let format = choose_format(name, &head, options)?;
    let source = Checked::new(source, options);
    let cloud = stopped(
        read_stream(source, name, format, options, None),
        name,
        options,
    )?;
    finish(cloud, name, options)
}

/// Reads a LAZ file while it arrives (an upload being received): its chunks are decoded front
/// to back as their bytes come, and those left when the last byte is in are decoded in
/// parallel. The cloud is exactly [`read_cloud_from`]'s for the whole file. A file this read
/// does not decode (not LAZ, variable-sized chunks, extended VLRs, a chunk table the whole-file
/// read would not use) or any error fails it: read the whole file then, for the cloud or the
/// error.
pub fn read_laz_arriving<R>(
    mut source: R,
    name: &str,
    options: &ReadOptions,
) -> Result<PointCloud, ReadError>
where
    R: Arriving + Send + Sync + 'static,
{
    const STACK: usize = 1 << 30;
    let len = source
        .seek(SeekFrom::End(0))
        .and_then(|len| source.seek(SeekFrom::Start(0)).map(|_| len))
        .map_err(|e| ReadError::io(name, e))?;
    let source = Checked::new(source, options);
    let (owned_name, opts) = (name.to_string(), options.clone());
    // A thread with a large stack, as for the whole-file read: the LAZ decoder recurses.
    let worker = std::thread::Builder::new()
        .name("asbuilt-read".into())
        .stack_size(STACK)
        .spawn(move || las::read_laz_arriving(source, len, &owned_name, &opts))
        .map_err(|e| ReadError::io(name, e))?;
    let read = worker.join().unwrap_or_else(|panic| {
        Err(ReadError::named(
            name,
            "laz",
            format!("the decoder failed ({})", panic_text(&panic)),
        ))
    });
    let cloud = stopped(read, name, options)?;
    finish(cloud, name, options)
}

/// A read that failed because `options.cancel` stopped it, whatever error the reader made of
/// the refused bytes, becomes [`ReadError::Cancelled`].
fn stopped(
    read: Result<PointCloud, ReadError>,
    name: &str,
    options: &ReadOptions,
) -> Result<PointCloud, ReadError> {
    match (read, options.cancel.check()) {
        (Err(_), Err(c)) => Err(ReadError::Cancelled(c, name.to_string())),
        (read, _) => read,
    }
}

/// A source that refuses to give more bytes once its [`Cancel`] says stop: every reader asks
/// its source for the next buffer, so this puts a check in every reader's loop. It also
/// tells its [`BytesRead`] how far the reader has got.
struct Checked<R> {
    inner: R,
    cancel: Cancel,
    bytes: BytesRead,
    position: u64,
}

impl<R> Checked<R> {
    fn new(inner: R, options: &ReadOptions) -> Checked<R> {
        Checked {
            inner,
            cancel: options.cancel.clone(),
            bytes: options.bytes.clone(),
            position: 0,
        }
    }
}

impl<R: Read> Read for Checked<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.cancel.check().map_err(std::io::Error::other)?;
        let n = self.inner.read(buf)?;
        self.position += n as u64;
        self.bytes.reached(self.position);
        Ok(n)
    }
}

impl<R: Arriving> Arriving for Checked<R> {
    fn arrived(&self) -> bool {
        self.inner.arrived()
    }

    fn available(&self) -> u64 {
        self.inner.available()
    }

    fn another(&self) -> std::io::Result<Self> {
        Ok(Checked {
            inner: self.inner.another()?,
            cancel: self.cancel.clone(),
            bytes: self.bytes.clone(),
            position: 0,
        })
    }
}

impl<R: Seek> Seek for Checked<R> {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.position = self.inner.seek(pos)?;
        Ok(self.position)
    }
}

/// The first bytes, for detection; the source is rewound afterwards.
fn sniff<R: Read + Seek>(source: &mut R, name: &str) -> Result<Vec<u8>, ReadError> {
    let mut head = Vec::with_capacity(detect::SNIFF_LEN);
    source
        .by_ref()
        .take(detect::SNIFF_LEN as u64)
        .read_to_end(&mut head)
        .and_then(|_| source.seek(SeekFrom::Start(0)))
        .map_err(|e| ReadError::io(name, e))?;
    Ok(head)
}

fn choose_format(name: &str, head: &[u8], options: &ReadOptions) -> Result<Format, ReadError> {
    if let Some(s) = options.scale {
        if !(s.is_finite() && s > 0.0) {
            return Err(ReadError::Options {
                path: name.into(),
                why: format!("the scale must be a positive number, not {s}"),
            });
        }
    }
    match options.format {
        Some(f) => Ok(f),
        None => detect::detect(head).map_err(|why| {
            // Say what the name promised, so a wrong or damaged file is easy to place.
            let ext = Path::new(name).extension().and_then(|e| e.to_str());
            let why = match ext {
                Some(e) if e.parse::<Format>().is_ok() => format!("{why}; the name says .{e}"),
                _ => why,
            };
            ReadError::UnknownFormat {
                path: name.into(),
                why,
            }
        }),
    }
}

/// Runs the reader on a thread of its own. The LAZ arithmetic decoder recurses deeply enough to
/// overflow the main thread's stack on some files, so the thread gets a large stack (reserved,
/// not committed); and a panic in a decoder becomes an error naming the file, not a crash.
/// An uncompressed LAS file's records are decoded from `map`, the source's map, when given.
fn read_stream<R>(
    mut source: R,
    name: &str,
    format: Format,
    options: &ReadOptions,
    map: Option<pages::Mapped>,
) -> Result<PointCloud, ReadError>
where
    R: Read + Seek + Send + Sync + 'static,
{
    const STACK: usize = 1 << 30;
    let len = source
        .seek(SeekFrom::End(0))
        .and_then(|len| source.seek(SeekFrom::Start(0)).map(|_| len))
        .map_err(|e| ReadError::io(name, e))?;
    let owned_name = name.to_string();
    let opts = options.clone();
    let worker = std::thread::Builder::new()
        .name("asbuilt-read".into())
        .stack_size(STACK)
        .spawn(move || {
            let name = owned_name.as_str();
            match format {
                Format::E57 => e57::read_e57(source, len, name, &opts),
                // The LAZ decoder reads a byte at a time: buffer it.
                Format::Las | Format::Laz => {
                    let source = BufReader::with_capacity(1 << 16, source);
                    match &map {
                        Some(map) => las::read_las_mapped(source, len, name, &opts, map),
                        None => las::read_las(source, len, name, &opts),
                    }
                }
                Format::Xyz | Format::Pts => xyz::read_xyz(
                    BufReader::with_capacity(1 << 20, source),
                    len,
                    name,
                    format,
                    &opts,
                ),
                Format::Ply => ply::read_ply_from(source, len, name, opts.keep_time),
            }
        })
        .map_err(|e| ReadError::io(name, e))?;
    worker.join().unwrap_or_else(|panic| {
        Err(ReadError::named(
            name,
            format.name(),
            format!(
                "the decoder failed ({}); the file is probably corrupt",
                panic_text(&panic)
            ),
        ))
    })
}

/// A caught panic's message.
fn panic_text(panic: &Box<dyn std::any::Any + Send>) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_default()
}

/// Applies the scale, records the units and checks the reader's invariants.
fn finish(
    mut cloud: PointCloud,
    name: &str,
    options: &ReadOptions,
) -> Result<PointCloud, ReadError> {
    match options.scale {
        Some(s) => {
            scale_cloud(&mut cloud, s);
            let was = if cloud.source.units.is_empty() {
                String::new()
            } else {
                format!(", read as {}", cloud.source.units)
            };
            cloud.source.units = format!("m (coordinates multiplied by {s}{was})");
        }
        None if cloud.source.units.is_empty() => cloud.source.units = "m (assumed)".into(),
        None => {}
    }
    let format: &'static str = match cloud.source.format.as_str() {
        "e57" => "e57",
        "las" => "las",
        "laz" => "laz",
        "ply" => "ply",
        "pts" => "pts",
        _ => "xyz",
    };
    cloud
        .check()
        .map_err(|why| ReadError::named(name, format, why))?;
    Ok(cloud)
}

/// Scales a whole cloud (origin, points, scanner positions) about the world origin, so that a
/// file in other units becomes metres.
pub fn scale_cloud(cloud: &mut PointCloud, s: f64) {
    cloud.origin = cloud.origin.map(|c| c * s);
    let sf = s as f32;
    for p in &mut cloud.xyz {
        *p = p.map(|c| c * sf);
    }
    match &mut cloud.viewpoints {
        Viewpoints::None => {}
        Viewpoints::Static(poses) => {
            for p in poses {
                p.position = p.position.map(|c| c * s);
            }
        }
        Viewpoints::Trajectory(samples) => {
            for p in samples {
                p.position = p.position.map(|c| c * s);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::ScanPose;

    #[test]
    fn scale_multiplies_origin_points_and_poses() {
        let mut cloud = PointCloud::from_world(&[[20_000.0, 0.0, 0.0], [20_001.0, 2.0, 3.0]]);
        cloud.viewpoints = Viewpoints::Static(vec![ScanPose {
            index: 0,
            position: [10.0, 20.0, 30.0],
            quaternion: [1.0, 0.0, 0.0, 0.0],
        }]);
        scale_cloud(&mut cloud, 0.001);
        let world: Vec<[f64; 3]> = cloud
            .xyz
            .iter()
            .map(|p| [0, 1, 2].map(|k| cloud.origin[k] + f64::from(p[k])))
            .collect();
        assert!((world[1][0] - 20.001).abs() < 1e-9);
        assert!((world[1][2] - 0.003).abs() < 1e-9);
        let Viewpoints::Static(p) = &cloud.viewpoints else {
            panic!("poses lost")
        };
        assert!((p[0].position[1] - 0.02).abs() < 1e-12);
    }

    #[test]
    fn in_memory_sources_read_and_bad_scales_are_refused() {
        let text = b"1 2 3\n4 5 6\n".to_vec();
        let c = read_cloud_from(
            std::io::Cursor::new(text.clone()),
            "mem",
            &Default::default(),
        )
        .unwrap();
        assert_eq!(c.len(), 2);
        assert_eq!(c.source.units, "m (assumed)");
        let opts = ReadOptions {
            scale: Some(-1.0),
            ..Default::default()
        };
        let err = read_cloud_from(std::io::Cursor::new(text), "mem", &opts).unwrap_err();
        assert_eq!(err.code(), "invalid_options");
    }
}
