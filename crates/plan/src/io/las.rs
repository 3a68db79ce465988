//! LAS 1.0 to 1.4 and LAZ, through the `las` crate: scale and offset applied, `point_source_id`
//! as the scan index, `gps_time` as the point time, the CRS from WKT or GeoTIFF keys.
//!
//! The header is checked against the file's size before the crate sees it, because the crate
//! trusts the header's counts and lengths when it allocates.

use std::io::{Read, Seek, SeekFrom};

use las::{PointDataBuilder, Reader};

mod chunks;

pub use chunks::LasChunks;

use super::assemble::CloudBuilder;
use super::{ReadError, ReadOptions};
use crate::cloud::PointCloud;

/// Points decoded per chunk: small enough to stay in cache, large enough to amortise calls.
const CHUNK: u64 = 64 * 1024;

/// No LAZ file holds more points per byte than this; a header that claims more is corrupt.
const MAX_LAZ_POINTS_PER_BYTE: u64 = 64;

/// Reads LAS or LAZ from a seekable source of `len` bytes.
pub fn read_las<R>(
    mut source: R,
    len: u64,
    name: &str,
    options: &ReadOptions,
) -> Result<PointCloud, ReadError>
where
    R: Read + Seek + Send + Sync + 'static,
{
    let plan = check_header(&mut source, len, name)?;
    let fname = plan.format;
    let err = |e: las::Error| ReadError::named(name, fname, e.to_string());
    let mut reader = Reader::new(source).map_err(err)?;
    let header = reader.header().clone();
    let count = header.number_of_points();
    // The first point chooses the local origin: header bounds may be stale or zero.
    let mut b = CloudBuilder::new(fname, count as usize, None, options.keep_time);
    let guard = BoundsGuard::new(&header);
    let mut pd = PointDataBuilder::new().for_header(&header).build();
    let mut done = 0u64;
    loop {
        let n = reader.fill_points(CHUNK, &mut pd).map_err(|e| {
            ReadError::at(
                name,
                fname,
                e.to_string(),
                format!("point {done} of {count}"),
            )
        })?;
        if n == 0 {
            break;
        }
        let mut times = pd.gps_time();
        for (i, (((x, y), z), id)) in pd
            .x()
            .zip(pd.y())
            .zip(pd.z())
            .zip(pd.point_source_id())
            .enumerate()
        {
            let p = [x, y, z];
            if !guard.contains(p) {
                return Err(ReadError::at(
                    name,
                    fname,
                    format!(
                        "({x}, {y}, {z}) lies outside the header's bounding box; the point data is corrupt{}",
                        if fname == "laz" { " (a damaged compressed chunk?)" } else { "" }
                    ),
                    format!("point {}", done + i as u64),
                ));
            }
            let slot = b
                .scan_slot(u32::from(id))
                .map_err(|why| ReadError::named(name, fname, why))?;
            let t = times.as_mut().and_then(|t| t.next());
            b.push(p, Some(slot), t);
        }
        done += n;
    }
    if done < count {
        return Err(ReadError::at(
            name,
            fname,
            format!("the header claims {count} points but the data ends after {done}"),
            format!("point {done}"),
        ));
    }
    let crs = crs_of(&header);
    let details = describe(&header, crs.as_ref().map(|c| c.1));
    let c = b.cloud_mut();
    c.crs = crs.map(|c| c.0);
    Ok(b.finish(details))
}

/// What the header check learned.
struct HeaderCheck {
    format: &'static str,
}

/// Checks the counts and offsets the `las` and `laz` crates allocate from against the file size.
fn check_header<R: Read + Seek>(
    source: &mut R,
    len: u64,
    name: &str,
) -> Result<HeaderCheck, ReadError> {
    let io = |e: std::io::Error| ReadError::io(name, e);
    let raw = las::raw::Header::read_from(&mut *source).map_err(|e| {
        let why = match &e {
            las::Error::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
                format!("the file ends inside the header ({len} bytes)")
            }
            other => other.to_string(),
        };
        ReadError::at(name, "las", why, "byte 0")
    })?;
    let compressed = raw.point_data_record_format & 0xC0 != 0;
    let format = if compressed { "laz" } else { "las" };
    let legacy = u64::from(raw.number_of_point_records);
    let points = match raw.large_file {
        Some(lf) if legacy == 0 => lf.number_of_point_records,
        _ => legacy,
    };
    let start = u64::from(raw.offset_to_point_data);
    if start > len {
        return Err(ReadError::at(
            name,
            format,
            format!("the point data starts at byte {start}, past the end of the {len}-byte file"),
            "byte 96",
        ));
    }
    if compressed {
        if points > len.saturating_mul(MAX_LAZ_POINTS_PER_BYTE) {
            return Err(ReadError::named(
                name,
                format,
                format!(
                    "the header claims {points} points, more than a {len}-byte LAZ file can hold"
                ),
            ));
        }
        check_chunk_table(source, start, len, points, name)?;
    } else {
        let record = u64::from(raw.point_data_record_length);
        let need = points.saturating_mul(record).saturating_add(start);
        if need > len {
            return Err(ReadError::named(
                name,
                format,
                format!(
                    "the header claims {points} points of {record} bytes from byte {start}, \
                     {need} bytes in all, but the file has {len}: truncated, or a bad point count"
                ),
            ));
        }
    }
    if let Some(evlr) = raw
        .evlr
        .filter(|e| e.start_of_first_evlr > 0 && e.number_of_evlrs > 0)
    {
        let at = evlr.start_of_first_evlr;
        let mut size = [0u8; 8];
        let fits = at.checked_add(60).is_some_and(|end| end <= len);
        if fits {
            source.seek(SeekFrom::Start(at + 20)).map_err(io)?;
            source.read_exact(&mut size).map_err(io)?;
        }
        let body = u64::from_le_bytes(size);
        if !fits || at + 60 + body > len {
            return Err(ReadError::at(
                name,
                format,
                format!("an extended VLR of {body} bytes does not fit in the {len}-byte file"),
                format!("byte {at}"),
            ));
        }
    }
    source.seek(SeekFrom::Start(0)).map_err(io)?;
    Ok(HeaderCheck { format })
}

/// LAZ keeps a chunk table whose entry count the decoder allocates from.
fn check_chunk_table<R: Read + Seek>(
    source: &mut R,
    start: u64,
    len: u64,
    points: u64,
    name: &str,
) -> Result<(), ReadError> {
    let io = |e: std::io::Error| ReadError::io(name, e);
    let read_u64_at = |s: &mut R, at: u64| -> Result<Option<i64>, ReadError> {
        if at.checked_add(8).is_none_or(|end| end > len) {
            return Ok(None);
        }
        let mut buf = [0u8; 8];
        s.seek(SeekFrom::Start(at)).map_err(io)?;
        s.read_exact(&mut buf).map_err(io)?;
        Ok(Some(i64::from_le_bytes(buf)))
    };
    let Some(mut offset) = read_u64_at(source, start)? else {
        return Err(ReadError::at(
            name,
            "laz",
            "the file ends before the compressed point data",
            format!("byte {start}"),
        ));
    };
    if offset <= start as i64 {
        // Writers that could not seek back leave the offset in the last 8 bytes.
        offset = read_u64_at(source, len.saturating_sub(8))?.unwrap_or(-1);
        if offset <= start as i64 {
            return Ok(());
        }
    }
    let table = offset as u64;
    let mut head = [0u8; 8];
    if table.checked_add(8).is_none_or(|end| end > len) {
        return Err(ReadError::at(
            name,
            "laz",
            format!("the chunk table offset {table} is past the end of the {len}-byte file"),
            format!("byte {start}"),
        ));
    }
    source.seek(SeekFrom::Start(table)).map_err(io)?;
    source.read_exact(&mut head).map_err(io)?;
    let chunks = u64::from(u32::from_le_bytes([head[4], head[5], head[6], head[7]]));
    if chunks > points.max(1) || chunks > len {
        return Err(ReadError::at(
            name,
            "laz",
            format!("the chunk table claims {chunks} chunks for {points} points"),
            format!("byte {table}"),
        ));
    }
    Ok(())
}

/// Header bounds, widened by 1 % and a few scale steps, when the header has any.
struct BoundsGuard {
    lo: [f64; 3],
    hi: [f64; 3],
    active: bool,
}

impl BoundsGuard {
    fn new(header: &las::Header) -> Self {
        let b = header.bounds();
        let t = header.transforms();
        let (lo, hi) = ([b.min.x, b.min.y, b.min.z], [b.max.x, b.max.y, b.max.z]);
        let scales = [t.x.scale, t.y.scale, t.z.scale];
        let set = lo.iter().chain(&hi).any(|&v| v != 0.0);
        let sane = (0..3).all(|k| lo[k].is_finite() && hi[k].is_finite() && lo[k] <= hi[k]);
        let pad = |k: usize| (hi[k] - lo[k]) * 0.01 + 3.0 * scales[k].abs();
        BoundsGuard {
            lo: [0, 1, 2].map(|k| lo[k] - pad(k)),
            hi: [0, 1, 2].map(|k| hi[k] + pad(k)),
            active: set && sane && header.number_of_points() > 0,
        }
    }

    #[inline]
    fn contains(&self, p: [f64; 3]) -> bool {
        !self.active || (0..3).all(|k| p[k] >= self.lo[k] && p[k] <= self.hi[k])
    }
}

/// The CRS as WKT, or `EPSG:nnnn` from GeoTIFF keys, with where it came from.
fn crs_of(header: &las::Header) -> Option<(String, &'static str)> {
    if let Some(bytes) = header.get_wkt_crs_bytes() {
        let wkt = String::from_utf8_lossy(bytes)
            .trim_end_matches('\0')
            .trim()
            .to_string();
        if !wkt.is_empty() {
            return Some((wkt, "WKT"));
        }
    }
    let keys = header.get_geotiff_crs().ok()??;
    // 0 is undefined and 32767 user-defined: neither names an EPSG code.
    let code = [
        keys.get_projected_crs_geo_key_value(),
        keys.get_geodetic_crs_geo_key_value(),
    ]
    .into_iter()
    .flatten()
    .find(|&c| c != 0 && c != 32767)?;
    Some((format!("EPSG:{code}"), "GeoTIFF keys"))
}

fn describe(header: &las::Header, crs_from: Option<&str>) -> String {
    let f = header.point_format();
    let t = header.transforms();
    let mut d = format!(
        "LAS {}, point format {}, {} points, scale {} {} {}",
        header.version(),
        f.to_u8().unwrap_or(0),
        header.number_of_points(),
        t.x.scale,
        t.y.scale,
        t.z.scale
    );
    if f.has_gps_time {
        d += ", gps time";
    }
    if f.has_color {
        d += ", RGB";
    }
    if let Some(from) = crs_from {
        d += &format!(", CRS from {from}");
    }
    d
}
