//! Writing a cloud back out as E57 (one Data3D per scan, with its pose), LAS, LAZ or XYZ, so
//! tests and benchmarks can put one building through every reader.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use crate::cloud::{PointCloud, ScanPose, Viewpoints};

/// Why a cloud could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// Creating or writing the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The plan cannot be put in the format; `why` says what.
    #[error("{path}: {why}")]
    Format {
        /// The file.
        path: String,
        /// What cannot be written.
        why: String,
    },
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> ExportError + '_ {
    move |source| ExportError::Io {
        path: path.display().to_string(),
        source,
    }
}

fn fmt_err(path: &Path) -> impl Fn(String) -> ExportError + '_ {
    move |why| ExportError::Format {
        path: path.display().to_string(),
        why,
    }
}

/// World coordinates of point `i`.
fn world(cloud: &PointCloud, i: usize) -> [f64; 3] {
    let p = cloud.xyz[i];
    [0, 1, 2].map(|k| cloud.origin[k] + f64::from(p[k]))
}

/// Rotates `v` by the unit quaternion `[w, x, y, z]`, or by its inverse.
fn rotate(q: [f64; 4], v: [f64; 3], inverse: bool) -> [f64; 3] {
    let [w, x, y, z] = q;
    let (x, y, z) = if inverse { (-x, -y, -z) } else { (x, y, z) };
    // v' = v + 2w (u × v) + 2 u × (u × v), u = (x, y, z).
    let u = [x, y, z];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let t = cross(u, v).map(|c| 2.0 * c);
    let ut = cross(u, t);
    [0, 1, 2].map(|k| v[k] + w * t[k] + ut[k])
}

/// Writes E57: one Data3D per scan slot, points in scanner-local coordinates, the pose in the
/// file, the CRS (if any) as coordinate metadata. Without static poses the whole cloud is one scan with the identity pose.
/// Coordinates are doubles, so applying the pose on reading gives back the very same `f32`
/// points (single precision would move them by rounding).
pub fn write_e57(path: &Path, cloud: &PointCloud) -> Result<(), ExportError> {
    let fe = fmt_err(path);
    let e = |e: e57::Error| fe(e.to_string());
    let poses: Vec<ScanPose> = match &cloud.viewpoints {
        Viewpoints::Static(p) => p.clone(),
        _ => vec![ScanPose {
            index: 0,
            position: [0.0; 3],
            quaternion: [1.0, 0.0, 0.0, 0.0],
        }],
    };
    let mut writer = e57::E57Writer::from_file(path, "asbuilt-export").map_err(e)?;
    // The cloud's CRS travels as the file's coordinateMetadata, where E57 readers look for it.
    writer.set_coordinate_metadata(cloud.crs.clone());
    let prototype = vec![
        e57::Record::CARTESIAN_X_F64,
        e57::Record::CARTESIAN_Y_F64,
        e57::Record::CARTESIAN_Z_F64,
    ];
    for (slot, pose) in poses.iter().enumerate() {
        let mut pc = writer
            .add_pointcloud(&format!("scan-{slot}"), prototype.clone())
            .map_err(e)?;
        let t = [0, 1, 2].map(|k| cloud.origin[k] + pose.position[k]);
        let q = pose.quaternion;
        pc.set_transform(Some(e57::Transform {
            rotation: e57::Quaternion {
                w: q[0],
                x: q[1],
                y: q[2],
                z: q[3],
            },
            translation: e57::Translation {
                x: t[0],
                y: t[1],
                z: t[2],
            },
        }));
        for i in 0..cloud.len() {
            if !cloud.scan.is_empty() && cloud.scan[i] as usize != slot {
                continue;
            }
            let w = world(cloud, i);
            let local = rotate(q, [0, 1, 2].map(|k| w[k] - t[k]), true);
            pc.add_point(local.map(e57::RecordValue::Double).to_vec())
                .map_err(e)?;
        }
        pc.finalize().map_err(e)?;
    }
    writer.finalize().map_err(e)
}

/// Writes LAS 1.2 (or LAZ when `compressed`) at millimetre resolution, with `point_source_id`
/// from the scan indices and, when the cloud has times, `gps_time` (point format 1).
pub fn write_las(path: &Path, cloud: &PointCloud, compressed: bool) -> Result<(), ExportError> {
    let has_time = !cloud.time.is_empty();
    write_las_as(
        path,
        cloud,
        compressed,
        (1, 2),
        if has_time { 1 } else { 0 },
    )
}

/// [`write_las`] as LAS 1.4 point format 6, whose LAZ keeps each field in layers of its own.
/// The format always has a time: 0 where the cloud has none.
pub fn write_las14(path: &Path, cloud: &PointCloud, compressed: bool) -> Result<(), ExportError> {
    write_las_as(path, cloud, compressed, (1, 4), 6)
}

fn write_las_as(
    path: &Path,
    cloud: &PointCloud,
    compressed: bool,
    version: (u8, u8),
    format: u8,
) -> Result<(), ExportError> {
    let fe = fmt_err(path);
    let e = |e: las::Error| fe(e.to_string());
    let mut builder = las::Builder::from(version);
    builder.point_format = las::point::Format::new(format).map_err(e)?;
    let has_time = builder.point_format.has_gps_time;
    builder.point_format.is_compressed = compressed;
    let t = |offset: f64| las::Transform {
        scale: 0.001,
        offset,
    };
    builder.transforms = las::Vector {
        x: t(cloud.origin[0]),
        y: t(cloud.origin[1]),
        z: t(cloud.origin[2]),
    };
    let header = builder.into_header().map_err(e)?;
    let file = File::create(path).map_err(io_err(path))?;
    let mut writer = las::Writer::new(BufWriter::new(file), header).map_err(e)?;
    for i in 0..cloud.len() {
        let [x, y, z] = world(cloud, i);
        let point_source_id = match cloud.scan.get(i) {
            Some(&s) => u16::try_from(cloud.scan_ids[s as usize]).map_err(|_| {
                fe(format!(
                    "scan index {} does not fit LAS",
                    cloud.scan_ids[s as usize]
                ))
            })?,
            None => 0,
        };
        writer
            .write_point(las::Point {
                x,
                y,
                z,
                point_source_id,
                gps_time: has_time.then(|| cloud.time.get(i).copied().unwrap_or(0.0)),
                return_number: 1,
                number_of_returns: 1,
                ..Default::default()
            })
            .map_err(e)?;
    }
    writer.close().map_err(e)
}

/// Writes `x y z` lines (world coordinates), with the scan index as a fourth column when the
/// cloud has one (read it back with `scan_column = Some(3)`).
pub fn write_xyz(path: &Path, cloud: &PointCloud) -> Result<(), ExportError> {
    let file = File::create(path).map_err(io_err(path))?;
    let mut out = BufWriter::with_capacity(1 << 20, file);
    for i in 0..cloud.len() {
        let [x, y, z] = world(cloud, i);
        match cloud.scan.get(i) {
            Some(&s) => writeln!(out, "{x} {y} {z} {}", cloud.scan_ids[s as usize]),
            None => writeln!(out, "{x} {y} {z}"),
        }
        .map_err(io_err(path))?;
    }
    out.flush().map_err(io_err(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_and_its_inverse_cancel() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let q = [h, 0.0, 0.0, h]; // 90° about z
        let v = rotate(q, [1.0, 0.0, 0.0], false);
        assert!((v[0]).abs() < 1e-12 && (v[1] - 1.0).abs() < 1e-12);
        let back = rotate(q, v, true);
        assert!((back[0] - 1.0).abs() < 1e-12 && back[1].abs() < 1e-12);
    }
}
