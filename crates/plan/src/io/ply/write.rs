//! Writing a cloud as PLY: binary (either endianness) or ASCII, with `scan_index` and `time`.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use super::header::Encoding;
use crate::cloud::PointCloud;

/// Why a PLY file could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot write {path}: {source}")]
pub struct WriteError {
    /// The file.
    pub path: String,
    /// The underlying error.
    pub source: std::io::Error,
}

/// Writes a cloud as PLY in world coordinates (local + origin), with `scan_index` (the scan's
/// user-facing id) and `time` when the cloud has them. Coordinates are `float` when the origin is
/// zero and `double` otherwise, so georeferenced clouds keep their precision.
pub fn write_ply(path: &Path, cloud: &PointCloud, encoding: Encoding) -> Result<(), WriteError> {
    let file = File::create(path).map_err(|source| WriteError {
        path: path.display().to_string(),
        source,
    })?;
    let mut out = BufWriter::with_capacity(1 << 20, file);
    write_ply_to(&mut out, cloud, encoding)
        .and_then(|()| out.flush())
        .map_err(|source| WriteError {
            path: path.display().to_string(),
            source,
        })
}

/// Writes a cloud as PLY to any writer (see [`write_ply`]).
pub fn write_ply_to(
    out: &mut impl Write,
    cloud: &PointCloud,
    encoding: Encoding,
) -> std::io::Result<()> {
    let double = cloud.origin != [0.0; 3];
    let has_scan = !cloud.scan.is_empty();
    let has_time = !cloud.time.is_empty();
    let coord = if double { "double" } else { "float" };
    writeln!(out, "ply")?;
    writeln!(out, "format {} 1.0", encoding.name())?;
    writeln!(out, "comment written by asbuilt")?;
    writeln!(out, "element vertex {}", cloud.len())?;
    for axis in ["x", "y", "z"] {
        writeln!(out, "property {coord} {axis}")?;
    }
    if has_scan {
        writeln!(out, "property uint scan_index")?;
    }
    if has_time {
        writeln!(out, "property double time")?;
    }
    writeln!(out, "end_header")?;
    let o = cloud.origin;
    for (i, p) in cloud.xyz.iter().enumerate() {
        let scan = has_scan.then(|| cloud.scan_ids[cloud.scan[i] as usize]);
        let time = has_time.then(|| cloud.time[i]);
        let world = [0, 1, 2].map(|k| o[k] + f64::from(p[k]));
        match encoding {
            Encoding::Ascii => {
                if double {
                    write!(out, "{} {} {}", world[0], world[1], world[2])?;
                } else {
                    write!(out, "{} {} {}", p[0], p[1], p[2])?;
                }
                if let Some(s) = scan {
                    write!(out, " {s}")?;
                }
                if let Some(t) = time {
                    write!(out, " {t}")?;
                }
                writeln!(out)?;
            }
            Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => {
                let big = encoding == Encoding::BinaryBigEndian;
                macro_rules! put {
                    ($v:expr) => {
                        if big {
                            out.write_all(&$v.to_be_bytes())?
                        } else {
                            out.write_all(&$v.to_le_bytes())?
                        }
                    };
                }
                if double {
                    for v in world {
                        put!(v);
                    }
                } else {
                    for v in p {
                        put!(v);
                    }
                }
                if let Some(s) = scan {
                    put!(s);
                }
                if let Some(t) = time {
                    put!(t);
                }
            }
        }
    }
    Ok(())
}
