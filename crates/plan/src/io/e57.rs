//! E57 through the `e57` crate: every Data3D scan with its pose applied, the poses kept as
//! scanner origins (so labeling has lines of sight without a sidecar), cartesian or spherical
//! coordinates, and points the file marks invalid skipped.
//!
//! The 48-byte header and each scan's point count are checked against the file's size first,
//! so a corrupt header gives an error instead of a huge allocation or a long empty loop.

use std::error::Error as _;
use std::io::{Read, Seek, SeekFrom};

use e57::{CartesianCoordinate, E57Reader, RecordDataType, RecordName};

use super::assemble::CloudBuilder;
use super::poses::QUATERNION_TOLERANCE;
use super::{ReadError, ReadOptions};
use crate::cloud::{PointCloud, ScanPose, Viewpoints};

const FORMAT: &str = "e57";

/// The `e57` crate parses the XML section whole (it refuses more than 50 MiB); real sections
/// are kilobytes to a few megabytes even with hundreds of scans.
const MAX_XML: u64 = 50 << 20;

/// Reads an E57 file of `len` bytes.
pub fn read_e57<R: Read + Seek>(
    mut source: R,
    len: u64,
    name: &str,
    _options: &ReadOptions,
) -> Result<PointCloud, ReadError> {
    check_header(&mut source, len, name)?;
    let mut reader = E57Reader::new(source).map_err(|e| ReadError::named(name, FORMAT, why(&e)))?;
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
    let mut poses = Vec::with_capacity(scans.len());
    let mut invalid = 0u64;
    for (i, pc) in scans.iter().enumerate() {
        let slot = b
            .scan_slot(i as u32)
            .map_err(|w| ReadError::named(name, FORMAT, w))?;
        let pose = pose_of(pc, i as u32)
            .map_err(|why| ReadError::at(name, FORMAT, why, format!("scan {i}")))?;
        let (r, t) = (rotation_matrix(pose.2), pose.1);
        poses.push(pose);
        let mut points = reader
            .pointcloud_simple(pc)
            .map_err(|e| ReadError::at(name, FORMAT, why(&e), format!("scan {i}")))?;
        // The pose is applied here, with the renormalised rotation.
        points.apply_pose(false);
        points.spherical_to_cartesian(true);
        // Colour and intensity are not used downstream; skip their conversions.
        points.intensity_to_color(false);
        points.normalize_color(false);
        points.normalize_intensity(false);
        for (k, p) in points.enumerate() {
            let p = p.map_err(|e| {
                ReadError::at(name, FORMAT, why(&e), format!("scan {i}, point {k}"))
            })?;
            match p.cartesian {
                CartesianCoordinate::Valid { x, y, z } => {
                    let world = [0, 1, 2].map(|k| r[k][0] * x + r[k][1] * y + r[k][2] * z + t[k]);
                    b.push(world, Some(slot), None)
                }
                _ => invalid += 1,
            }
        }
    }
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
fn pose_of(pc: &e57::PointCloud, index: u32) -> Result<(u32, [f64; 3], [f64; 4]), String> {
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
