//! E57 through the `e57` crate: every Data3D scan with its pose applied, the poses kept as
//! scanner origins (so labeling has lines of sight without a sidecar), cartesian or spherical
//! coordinates, and points the file marks invalid skipped.
//!
//! The 48-byte header and each scan's point count are checked against the file's size first,
//! so a corrupt header gives an error instead of a huge allocation or a long empty loop.

use std::error::Error as _;
use std::io::{Read, Seek, SeekFrom};
use std::sync::{Arc, Mutex};

use rayon::prelude::*;

use e57::{CartesianCoordinate, E57Reader, RecordDataType, RecordName};

use super::assemble::CloudBuilder;
use super::poses::QUATERNION_TOLERANCE;
use super::{ReadError, ReadOptions};
use crate::cloud::{to_local, PointCloud, ScanPose, Viewpoints};

const FORMAT: &str = "e57";

/// The `e57` crate parses the XML section whole (it refuses more than 50 MiB); real sections
/// are kilobytes to a few megabytes even with hundreds of scans.
const MAX_XML: u64 = 50 << 20;

/// Bytes a source handle reads at a time: the decoder asks for 1 KiB pages, one seek each.
const SOURCE_BLOCK: usize = 1 << 16;

/// A scan's index, scanner origin (world) and unit rotation `[w, x, y, z]`.
type Pose = (u32, [f64; 3], [f64; 4]);

/// Reads an E57 file of `len` bytes; with more than one thread in the readers' pool, its scans
/// are decoded in parallel.
pub fn read_e57<R: Read + Seek + Send>(
    source: R,
    len: u64,
    name: &str,
    _options: &ReadOptions,
) -> Result<PointCloud, ReadError> {
    read_e57_with(source, len, name, super::pool::threads() > 1)
}

fn read_e57_with<R: Read + Seek + Send>(
    mut source: R,
    len: u64,
    name: &str,
    parallel: bool,
) -> Result<PointCloud, ReadError> {
    check_header(&mut source, len, name)?;
    let shared = Arc::new(Mutex::new(source));
    let mut reader = E57Reader::new(Handle::new(&shared, len))
        .map_err(|e| ReadError::named(name, FORMAT, why(&e)))?;
    let scans = reader.pointclouds();
    // The E57 standard's coordinateMetadata: the CRS, as WKT or a code such as `EPSG:32633`.
    let crs = reader
        .coordinate_metadata()
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(String::from);
    let mut total = 0u64;
    for (i, pc) in scans.iter().enumerate() {
        check_scan(pc, i, len, name)?;
        total = total.saturating_add(pc.records);
    }
    // Each scan's count fits the file, but the scans share it.
    if total > len.saturating_mul(8) {
        return Err(ReadError::named(
            name,
            FORMAT,
            format!("the scans claim {total} points in all, more than a {len}-byte file can hold"),
        ));
    }
    let mut b = CloudBuilder::new(FORMAT, total as usize, None, false);
    let (poses, invalid) = if parallel && scans.len() > 1 {
        let shared = &shared;
        super::pool::install(|| {
            decode_parallel(&mut reader, &scans, &mut b, name, || {
                E57Reader::new(Handle::new(shared, len))
            })
        })?
    } else {
        decode_serial(&mut reader, &scans, &mut b, name)?
    };
    let details = describe(&scans);
    {
        let c = b.cloud_mut();
        c.source.units = "m (E57 is metric)".into();
        if invalid > 0 {
            c.source.skipped = invalid;
            c.source.skipped_reason = Some("marked invalid in the file, or non-finite".into());
        }
    }
    let mut cloud = b.finish(details);
    cloud.crs = crs;
    let origin = cloud.origin;
    cloud.viewpoints = Viewpoints::Static(
        poses
            .into_iter()
            .map(|(index, position, quaternion)| ScanPose {
                index,
                position: [0, 1, 2].map(|k| position[k] - origin[k]),
                quaternion,
            })
            .collect(),
    );
    Ok(cloud)
}

/// A scan's points in the file's frame, as the crate decodes them.
fn open_points<'r, T: Read + Seek>(
    reader: &'r mut E57Reader<T>,
    pc: &e57::PointCloud,
    i: usize,
    name: &str,
) -> Result<e57::PointCloudReaderSimple<'r, T>, ReadError> {
    let mut points = reader
        .pointcloud_simple(pc)
        .map_err(|e| ReadError::at(name, FORMAT, why(&e), format!("scan {i}")))?;
    // The pose is applied by `world`, with the renormalised rotation.
    points.apply_pose(false);
    points.spherical_to_cartesian(true);
    // Colour and intensity are not used downstream; skip their conversions.
    points.intensity_to_color(false);
    points.normalize_color(false);
    points.normalize_intensity(false);
    Ok(points)
}

/// A scan point in world coordinates, or `None` when the file marks it invalid.
fn world(pose: &Pose, p: &e57::Point) -> Option<[f64; 3]> {
    let (r, t) = (rotation_matrix(pose.2), pose.1);
    match p.cartesian {
        CartesianCoordinate::Valid { x, y, z } => {
            Some([0, 1, 2].map(|k| r[k][0] * x + r[k][1] * y + r[k][2] * z + t[k]))
        }
        _ => None,
    }
}

/// Every scan in order on this thread: the poses, and how many points are marked invalid.
fn decode_serial<T: Read + Seek>(
    reader: &mut E57Reader<T>,
    scans: &[e57::PointCloud],
    b: &mut CloudBuilder,
    name: &str,
) -> Result<(Vec<Pose>, u64), ReadError> {
    let mut poses = Vec::with_capacity(scans.len());
    let mut invalid = 0u64;
    for (i, pc) in scans.iter().enumerate() {
        let slot = b
            .scan_slot(i as u32)
            .map_err(|w| ReadError::named(name, FORMAT, w))?;
        let pose = pose_of(pc, i as u32)
            .map_err(|why| ReadError::at(name, FORMAT, why, format!("scan {i}")))?;
        for (k, p) in open_points(reader, pc, i, name)?.enumerate() {
            let p = p.map_err(|e| {
                ReadError::at(name, FORMAT, why(&e), format!("scan {i}, point {k}"))
            })?;
            match world(&pose, &p) {
                Some(w) => b.push(w, Some(slot), None),
                None => invalid += 1,
            }
        }
        poses.push(pose);
    }
    Ok((poses, invalid))
}

/// What a scan decoded on its own thread gave: points placed, non-finite points skipped,
/// points marked invalid.
type ScanDone = Result<(usize, u64, u64), ReadError>;

/// The scans decoded in parallel, each by a reader of its own (`open` makes one), straight into
/// its stretch of the point array (sized by its record count, reserved but untouched until
/// written), then closed up in order: exactly the points, slots, counts and first error of
/// [`decode_serial`].
fn decode_parallel<T: Read + Seek>(
    reader: &mut E57Reader<T>,
    scans: &[e57::PointCloud],
    b: &mut CloudBuilder,
    name: &str,
    open: impl Fn() -> e57::Result<E57Reader<T>> + Sync + Send,
) -> Result<(Vec<Pose>, u64), ReadError> {
    // What the serial read checks before each scan's points; a failure ends the scans read.
    let mut slots = Vec::with_capacity(scans.len());
    let mut poses = Vec::with_capacity(scans.len());
    let mut stop = None;
    for (i, pc) in scans.iter().enumerate() {
        let checked = b
            .scan_slot(i as u32)
            .map_err(|w| ReadError::named(name, FORMAT, w))
            .and_then(|slot| {
                pose_of(pc, i as u32)
                    .map(|pose| (slot, pose))
                    .map_err(|why| ReadError::at(name, FORMAT, why, format!("scan {i}")))
            });
        match checked {
            Ok((slot, pose)) => {
                slots.push(slot);
                poses.push(pose);
            }
            Err(e) => {
                stop = Some(e);
                break;
            }
        }
    }
    let n = slots.len();
    // The first finite point fixes the local frame; its scans' errors come first, as serially.
    'frame: for (i, pc) in scans[..n].iter().enumerate() {
        for (k, p) in open_points(reader, pc, i, name)?.enumerate() {
            let p = p.map_err(|e| {
                ReadError::at(name, FORMAT, why(&e), format!("scan {i}, point {k}"))
            })?;
            if let Some(w) = world(&poses[i], &p).filter(|w| w.iter().all(|c| c.is_finite())) {
                b.fix_origin(w);
                break 'frame;
            }
        }
    }
    let Some(origin) = b.origin() else {
        // No finite point at all: nothing to share out.
        return decode_serial(reader, scans, b, name);
    };
    let records: Vec<usize> = scans[..n].iter().map(|pc| pc.records as usize).collect();
    let total: usize = records.iter().sum();
    // Zeroed memory comes from the allocator untouched: a stretch costs memory once written.
    let mut xyz = vec![[0.0f32; 3]; total];
    let mut stretches = Vec::with_capacity(n);
    let mut rest = xyz.as_mut_slice();
    for &r in &records {
        let (stretch, tail) = rest.split_at_mut(r);
        stretches.push(stretch);
        rest = tail;
    }
    let done: Vec<ScanDone> = stretches
        .into_par_iter()
        .enumerate()
        .map_init(open, |reader, (i, stretch)| {
            let reader = reader
                .as_mut()
                .map_err(|e| ReadError::at(name, FORMAT, why(e), format!("scan {i}")))?;
            let (mut placed, mut skipped, mut invalid) = (0usize, 0u64, 0u64);
            for (k, p) in open_points(reader, &scans[i], i, name)?.enumerate() {
                let p = p.map_err(|e| {
                    ReadError::at(name, FORMAT, why(&e), format!("scan {i}, point {k}"))
                })?;
                match world(&poses[i], &p) {
                    Some(w) if w.iter().all(|c| c.is_finite()) => {
                        // The iterator gives at most the scan's record count.
                        stretch[placed] = to_local(origin, w);
                        placed += 1;
                    }
                    Some(_) => skipped += 1,
                    None => invalid += 1,
                }
            }
            Ok((placed, skipped, invalid))
        })
        .collect();
    let mut invalid = 0u64;
    let (mut write, mut start) = (0usize, 0usize);
    let mut scan: Vec<u16> = Vec::with_capacity(total);
    let mut outcome = Ok(());
    for (i, d) in done.into_iter().enumerate() {
        let (placed, skipped, inv) = match d {
            Ok(d) => d,
            Err(e) => {
                outcome = Err(e);
                break;
            }
        };
        xyz.copy_within(start..start + placed, write);
        scan.extend(std::iter::repeat_n(slots[i], placed));
        b.skip(skipped);
        invalid += inv;
        write += placed;
        start += records[i];
    }
    outcome?;
    if let Some(e) = stop {
        return Err(e);
    }
    xyz.truncate(write);
    let c = b.cloud_mut();
    c.xyz = xyz;
    c.scan = scan;
    Ok((poses, invalid))
}

/// One reader's handle on a source several readers share: its own position, and a block
/// read ahead, so a page costs one locked read per block rather than a seek and a read.
struct Handle<R> {
    shared: Arc<Mutex<R>>,
    len: u64,
    pos: u64,
    block: Vec<u8>,
    block_at: u64,
}

impl<R> Handle<R> {
    fn new(shared: &Arc<Mutex<R>>, len: u64) -> Handle<R> {
        Handle {
            shared: Arc::clone(shared),
            len,
            pos: 0,
            block: Vec::new(),
            block_at: 0,
        }
    }
}

impl<R: Read + Seek> Read for Handle<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let end = self.block_at + self.block.len() as u64;
        if self.pos < self.block_at || self.pos >= end {
            self.block.resize(SOURCE_BLOCK, 0);
            let mut source = self
                .shared
                .lock()
                .map_err(|_| std::io::Error::other("another reader of the file failed"))?;
            source.seek(SeekFrom::Start(self.pos))?;
            let mut got = 0;
            while got < SOURCE_BLOCK {
                match source.read(&mut self.block[got..]) {
                    Ok(0) => break,
                    Ok(k) => got += k,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) => return Err(e),
                }
            }
            self.block.truncate(got);
            self.block_at = self.pos;
            if got == 0 {
                return Ok(0);
            }
        }
        let from = (self.pos - self.block_at) as usize;
        let n = buf.len().min(self.block.len() - from);
        buf[..n].copy_from_slice(&self.block[from..from + n]);
        self.pos += n as u64;
        Ok(n)
    }
}

impl<R> Seek for Handle<R> {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        let pos = match to {
            SeekFrom::Start(p) => Some(p),
            SeekFrom::End(d) => self.len.checked_add_signed(d),
            SeekFrom::Current(d) => self.pos.checked_add_signed(d),
        };
        self.pos = pos.ok_or_else(|| {
            std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "a seek before the start of the file",
            )
        })?;
        Ok(self.pos)
    }
}

/// The sum of every scan's record count, or `None` when the header or the XML section does
/// not pass the reader's checks.
pub(crate) fn declared_points<R: Read + Seek>(mut source: R, len: u64) -> Option<u64> {
    check_header(&mut source, len, FORMAT).ok()?;
    let reader = E57Reader::new(source).ok()?;
    Some(reader.pointclouds().iter().map(|pc| pc.records).sum())
}

/// The crate's message with its causes, which carry the useful detail.
fn why(e: &e57::Error) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        text += &format!(": {c}");
        cause = c.source();
    }
    text
}

/// Checks the fixed header: signature, version, page size, and that the XML section fits.
fn check_header<R: Read + Seek>(source: &mut R, len: u64, name: &str) -> Result<(), ReadError> {
    let mut h = [0u8; 48];
    if len < 48 {
        return Err(ReadError::named(
            name,
            FORMAT,
            format!("the file ends inside the 48-byte header ({len} bytes)"),
        ));
    }
    source
        .read_exact(&mut h)
        .and_then(|()| source.seek(SeekFrom::Start(0)).map(|_| ()))
        .map_err(|e| ReadError::io(name, e))?;
    let u64_at = |o: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&h[o..o + 8]);
        u64::from_le_bytes(b)
    };
    if &h[..8] != b"ASTM-E57" {
        return Err(ReadError::at(
            name,
            FORMAT,
            "wrong signature (not ASTM-E57)",
            "byte 0",
        ));
    }
    let (major, minor) = (
        u32::from_le_bytes([h[8], h[9], h[10], h[11]]),
        u32::from_le_bytes([h[12], h[13], h[14], h[15]]),
    );
    if (major, minor) != (1, 0) {
        return Err(ReadError::at(
            name,
            FORMAT,
            format!("version {major}.{minor} is not E57 1.0"),
            "byte 8",
        ));
    }
    let (phys_len, xml_at, xml_len, page) = (u64_at(16), u64_at(24), u64_at(32), u64_at(40));
    if xml_len > MAX_XML {
        return Err(ReadError::at(
            name,
            FORMAT,
            format!("the XML section claims {xml_len} bytes, more than the {MAX_XML} this reader parses"),
            "byte 32",
        ));
    }
    if xml_len == 0 {
        return Err(ReadError::at(
            name,
            FORMAT,
            "the XML section is empty",
            "byte 32",
        ));
    }
    if page != 1024 {
        return Err(ReadError::at(
            name,
            FORMAT,
            format!("page size {page} is not 1024"),
            "byte 40",
        ));
    }
    if phys_len != len {
        return Err(ReadError::at(
            name,
            FORMAT,
            format!("the header says the file has {phys_len} bytes but it has {len}: truncated or padded"),
            "byte 16",
        ));
    }
    // Each 1024-byte page carries 1020 bytes of data and a checksum.
    let xml_phys = xml_len.saturating_mul(1024) / 1020;
    if xml_at.saturating_add(xml_phys) > len {
        return Err(ReadError::at(
            name,
            FORMAT,
            format!("the XML section ({xml_len} bytes at byte {xml_at}) does not fit in the {len}-byte file"),
            "byte 24",
        ));
    }
    Ok(())
}

/// A scan needs coordinates, and no more points than its file can hold (a point takes at
/// least one bit unless every field is constant, which is no scan at all).
fn check_scan(pc: &e57::PointCloud, i: usize, len: u64, name: &str) -> Result<(), ReadError> {
    let has = |n: RecordName| pc.prototype.iter().any(|r| r.name == n);
    let cartesian =
        has(RecordName::CartesianX) && has(RecordName::CartesianY) && has(RecordName::CartesianZ);
    let spherical = has(RecordName::SphericalRange)
        && has(RecordName::SphericalAzimuth)
        && has(RecordName::SphericalElevation);
    if !cartesian && !spherical {
        return Err(ReadError::at(
            name,
            FORMAT,
            "no x/y/z (cartesianX/Y/Z) nor spherical coordinates in the point prototype",
            format!("scan {i}"),
        ));
    }
    let bits: u64 = pc.prototype.iter().map(|r| record_bits(&r.data_type)).sum();
    if bits == 0 && pc.records > 0 {
        return Err(ReadError::at(
            name,
            FORMAT,
            "every field of the point prototype is constant (zero bits a point), so the point count cannot be checked",
            format!("scan {i}"),
        ));
    }
    if pc.records > len.saturating_mul(8) / bits.max(1) {
        return Err(ReadError::at(
            name,
            FORMAT,
            format!(
                "{} points of {bits} bits claimed, more than a {len}-byte file can hold",
                pc.records
            ),
            format!("scan {i}"),
        ));
    }
    Ok(())
}

/// Bits a value of this type takes in a compressed vector (as E57 packs them).
fn record_bits(t: &RecordDataType) -> u64 {
    let int_bits = |min: i64, max: i64| {
        let range = i128::from(max) - i128::from(min);
        if range > 0 {
            u64::from(range.ilog2()) + 1
        } else {
            0
        }
    };
    match *t {
        RecordDataType::Single { .. } => 32,
        RecordDataType::Double { .. } => 64,
        RecordDataType::ScaledInteger { min, max, .. } | RecordDataType::Integer { min, max } => {
            int_bits(min, max)
        }
    }
}

/// A scan's index, scanner origin (world) and rotation `[w, x, y, z]`. The rotation must be a
/// unit quaternion (within the sidecars' tolerance, then renormalised): the crate applies it
/// as given, and any other length would scale the scan.
fn pose_of(pc: &e57::PointCloud, index: u32) -> Result<Pose, String> {
    let Some(t) = &pc.transform else {
        return Ok((index, [0.0; 3], [1.0, 0.0, 0.0, 0.0]));
    };
    let (p, q) = (&t.translation, &t.rotation);
    let position = [p.x, p.y, p.z];
    if !position.iter().all(|c| c.is_finite()) {
        return Err(format!("the pose's translation {position:?} is not finite"));
    }
    let q = [q.w, q.x, q.y, q.z];
    let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    if norm.is_nan() || (norm - 1.0).abs() > QUATERNION_TOLERANCE {
        return Err(format!(
            "the pose's rotation quaternion {q:?} has norm {norm}, not 1"
        ));
    }
    Ok((index, position, q.map(|c| c / norm)))
}

/// The rotation matrix (rows) of a unit quaternion `[w, x, y, z]`.
fn rotation_matrix(q: [f64; 4]) -> [[f64; 3]; 3] {
    let [w, x, y, z] = q;
    [
        [
            w * w + x * x - y * y - z * z,
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            w * w + y * y - x * x - z * z,
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            w * w + z * z - x * x - y * y,
        ],
    ]
}

fn describe(scans: &[e57::PointCloud]) -> String {
    let count = |f: fn(&e57::PointCloud) -> bool| scans.iter().filter(|s| f(s)).count();
    let mut d = format!(
        "E57 1.0, {} scan(s), {} with poses",
        scans.len(),
        count(|s| s.transform.is_some())
    );
    let (cart, sph) = (count(|s| s.has_cartesian()), count(|s| s.has_spherical()));
    d += &format!(", {cart} cartesian, {sph} spherical");
    if count(|s| s.has_color()) > 0 {
        d += ", colour";
    }
    if count(|s| s.has_intensity()) > 0 {
        d += ", intensity";
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    /// Five scans, the first empty, with far coordinates and turned poses.
    fn file() -> Vec<u8> {
        let mut c = PointCloud {
            origin: [500_000.0, 5_400_000.0, 10.0],
            scan_ids: vec![0, 1, 2, 3, 4],
            ..Default::default()
        };
        let h = std::f64::consts::FRAC_1_SQRT_2;
        c.viewpoints = Viewpoints::Static(
            (0..5)
                .map(|i| ScanPose {
                    index: i,
                    position: [i as f64 * 3.0, 1.0, 1.5],
                    quaternion: if i % 2 == 0 {
                        [1.0, 0.0, 0.0, 0.0]
                    } else {
                        [h, 0.0, 0.0, h]
                    },
                })
                .collect(),
        );
        for i in 0..20_003 {
            let f = i as f32;
            c.xyz
                .push([f * 0.001, (f * 0.37).sin() * 20.0, (i % 300) as f32 * 0.01]);
            c.scan.push(1 + (i % 4) as u16);
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.e57");
        crate::io::export::write_e57(&path, &c).unwrap();
        std::fs::read(&path).unwrap()
    }

    fn read(bytes: &[u8], parallel: bool) -> Result<PointCloud, ReadError> {
        let len = bytes.len() as u64;
        read_e57_with(Cursor::new(bytes.to_vec()), len, "t.e57", parallel)
    }

    #[test]
    fn parallel_scans_read_exactly_the_serial_points() {
        let bytes = file();
        let (serial, parallel) = (read(&bytes, false).unwrap(), read(&bytes, true).unwrap());
        assert_eq!(serial.len(), 20_003);
        let bits = |c: &PointCloud| -> Vec<[u32; 3]> {
            c.xyz.iter().map(|p| p.map(f32::to_bits)).collect()
        };
        assert!(bits(&serial) == bits(&parallel), "points differ");
        assert_eq!(serial.scan, parallel.scan);
        assert_eq!(serial.scan_ids, parallel.scan_ids);
        assert_eq!(serial.origin, parallel.origin);
        assert_eq!(serial.viewpoints, parallel.viewpoints);
        assert_eq!(serial.source, parallel.source);
        assert_eq!(serial.crs, parallel.crs);
    }

    #[test]
    fn parallel_scans_fail_as_the_serial_read_does() {
        let bytes = file();
        // A damaged page early (the XML or the first scans) and late (the last scans).
        let mut failures = 0;
        for at in [1_500, bytes.len() / 3, bytes.len() / 2, bytes.len() - 3_000] {
            let mut bad = bytes.clone();
            bad[at] ^= 0x5a;
            let serial = read(&bad, false).map(|c| c.len());
            let parallel = read(&bad, true).map(|c| c.len());
            match (&serial, &parallel) {
                (Err(a), Err(b)) => {
                    assert_eq!(a.to_string(), b.to_string());
                    // The pages' checksums (CRC-32C, by the `crc32c` crate) catch the damage.
                    assert!(a.to_string().contains("checksum"), "byte {at}: {a}");
                    failures += 1;
                }
                (Ok(a), Ok(b)) => assert_eq!(a, b),
                _ => panic!("byte {at}: {serial:?} vs {parallel:?}"),
            }
        }
        assert!(failures >= 3, "damaged pages must fail checksums");
    }
}
