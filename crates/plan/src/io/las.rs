//! LAS 1.0 to 1.4 and LAZ, through the `las` crate: scale and offset applied, `point_source_id`
//! as the scan index, `gps_time` as the point time, the CRS from WKT or GeoTIFF keys.
//!
//! The header is checked against the file's size before the crate sees it, because the crate
//! trusts the header's counts and lengths when it allocates.

use std::io::{Read, Seek, SeekFrom};

use las::{LazParallelism, PointData, PointDataBuilder, Reader, ReaderOptions};
use laz::laszip::ChunkTableEntry;

mod arriving;
mod chunks;

pub use arriving::{read_laz_arriving, Arriving};
pub use chunks::LasChunks;

use super::assemble::{decode_pieces, settle, CloudBuilder, LocalSlots, Out};
use super::pages::Mapped;
use super::{ReadError, ReadOptions};
use crate::cloud::{to_local, PointCloud};

/// Points decoded per chunk: small enough to stay in cache, large enough to amortise calls.
const CHUNK: u64 = 64 * 1024;

/// Uncompressed LAS is decoded in groups of this many batches per thread.
const GROUP_PER_THREAD: usize = 4;

/// The most points a parallel LAZ decode takes at a time (a few chunks per thread), however
/// large a damaged header says a chunk is.
const MAX_PARALLEL_BATCH: u64 = 1 << 21;

/// The largest fixed-size chunk, in bytes of records, decoded in parallel: the `laz` crate's
/// parallel decoder allocates a whole chunk's records for the end of the last one. LASzip
/// writes 50,000 points a chunk (1.8 MB at 36 bytes a point).
const MAX_PARALLEL_CHUNK_BYTES: u64 = 64 << 20;

/// LASzip's chunked compressors, whose chunks decode independently: point-wise, and layered
/// (point formats 6 to 10).
const POINTWISE_CHUNKED: u16 = 2;
const LAYERED_CHUNKED: u16 = 3;

/// No LAZ file holds more points per byte than this; a header that claims more is corrupt.
const MAX_LAZ_POINTS_PER_BYTE: u64 = 64;

/// Scanner LAZ files take 3 to 10 bytes a point; reserve for no more than this many per byte.
const LAZ_RESERVE_POINTS_PER_BYTE: u64 = 1;

/// Reads LAS or LAZ from a seekable source of `len` bytes; LAZ chunks are decoded in parallel
/// when the file has a sound chunk table.
pub fn read_las<R>(
    source: R,
    len: u64,
    name: &str,
    options: &ReadOptions,
) -> Result<PointCloud, ReadError>
where
    R: Read + Seek + Send + Sync + 'static,
{
    read_las_with(source, len, name, options, true, None)
}

/// [`read_las`] of a file also mapped as `map`: uncompressed records are decoded straight from
/// the map, everything else is read from `source`.
pub(crate) fn read_las_mapped<R>(
    source: R,
    len: u64,
    name: &str,
    options: &ReadOptions,
    map: &Mapped,
) -> Result<PointCloud, ReadError>
where
    R: Read + Seek + Send + Sync + 'static,
{
    read_las_with(source, len, name, options, true, Some(map))
}

/// [`read_las`], with parallel decoding allowed or not, from a map of the file when given.
fn read_las_with<R>(
    mut source: R,
    len: u64,
    name: &str,
    options: &ReadOptions,
    parallel: bool,
    map: Option<&Mapped>,
) -> Result<PointCloud, ReadError>
where
    R: Read + Seek + Send + Sync + 'static,
{
    let plan = check_header(&mut source, len, name)?;
    let threads = super::pool::threads();
    if parallel && plan.laz_chunk.is_some() {
        // Fixed-size chunks go straight into the cloud; the rest, and every error, through
        // the `las` crate, whose read gives the same cloud or the error to report.
        if let Ok(cloud) = arriving::read_laz_whole(&mut source, len, name, options) {
            return Ok(cloud);
        }
        options
            .cancel
            .check()
            .map_err(|c| ReadError::Cancelled(c, name.into()))?;
        source
            .seek(SeekFrom::Start(0))
            .map_err(|e| ReadError::io(name, e))?;
        // The decoder's threads are the pool's: run the whole read there.
        super::pool::install(|| decode_las(source, len, name, options, &plan, true))
    } else if parallel && plan.format == "las" {
        let group = GROUP_PER_THREAD * threads;
        super::pool::install(|| {
            decode_las_direct(source, name, options, &plan, CHUNK, group, threads, map)
        })
    } else {
        decode_las(source, len, name, options, &plan, false)
    }
}

fn decode_las<R>(
    source: R,
    len: u64,
    name: &str,
    options: &ReadOptions,
    plan: &HeaderCheck,
    parallel: bool,
) -> Result<PointCloud, ReadError>
where
    R: Read + Seek + Send + Sync + 'static,
{
    let fname = plan.format;
    let batch = plan.batch(parallel);
    let err = |e: las::Error| ReadError::named(name, fname, e.to_string());
    let mut reader = open_reader(source, plan, parallel).map_err(err)?;
    let header = reader.header().clone();
    let count = header.number_of_points();
    // The first point chooses the local origin: header bounds may be stale or zero. LAS counts
    // are checked exactly against the file's size; a LAZ count only loosely, so its reservation
    // is capped and the array grows (by a quarter at a time) past that.
    let reserve = match fname {
        "laz" => count.min(len.saturating_mul(LAZ_RESERVE_POINTS_PER_BYTE)),
        _ => count,
    };
    let mut b = CloudBuilder::new(fname, reserve as usize, None, options.keep_time);
    let guard = BoundsGuard::new(&header);
    let mut pd = PointDataBuilder::new().for_header(&header).build();
    let mut done = 0u64;
    let mut outside = 0u64;
    if parallel {
        // Two batches in turn: the decoder's threads fill one while this thread takes the
        // other's records into the cloud, which would otherwise leave them idle.
        let mut next = PointDataBuilder::new().for_header(&header).build();
        let mut n = fill(&mut reader, batch, &mut pd, done, count, name, fname)?;
        while n > 0 {
            let (mut taken, mut filled) = (Ok(0), Ok(0));
            // In place: the reader stays on this thread (it cannot move to another).
            rayon::in_place_scope(|s| {
                s.spawn(|_| taken = decode_batch(&mut b, &pd, &guard, done, name, fname));
                filled = fill(&mut reader, batch, &mut next, done + n, count, name, fname);
            });
            // As the serial read: a damaged batch fails before the next is looked at.
            outside += taken?;
            done += n;
            n = filled?;
            std::mem::swap(&mut pd, &mut next);
        }
        return finish_las(b, &header, done, count, outside, name, fname);
    }
    loop {
        let n = fill(&mut reader, batch, &mut pd, done, count, name, fname)?;
        if n == 0 {
            break;
        }
        outside += decode_batch(&mut b, &pd, &guard, done, name, fname)?;
        done += n;
    }
    finish_las(b, &header, done, count, outside, name, fname)
}

/// Reads the next `batch` points into `pd`; 0 at the end. Errors say which points.
fn fill(
    reader: &mut Reader,
    batch: u64,
    pd: &mut PointData,
    done: u64,
    count: u64,
    name: &str,
    fname: &'static str,
) -> Result<u64, ReadError> {
    let at = || {
        let end = (done + batch).min(count).max(done + 1) - 1;
        format!("points {done} to {end} of {count}")
    };
    // The LAZ decoder asserts on some damaged chunks; catching the panic here, rather than
    // in the reader thread, tells the user where the damage starts.
    let filled = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        reader.fill_points(batch, pd)
    }));
    match filled {
        Ok(Ok(n)) => Ok(n),
        Ok(Err(e)) => Err(ReadError::at(name, fname, e.to_string(), at())),
        Err(panic) => Err(ReadError::at(
            name,
            fname,
            format!(
                "the decoder failed ({}): the point data is damaged",
                super::panic_text(&panic)
            ),
            at(),
        )),
    }
}

/// Pushes a batch of decoded records, the first of which is point `done`; returns how many
/// lie outside the header's bounds (kept in a LAS, an error in a LAZ).
fn decode_batch(
    b: &mut CloudBuilder,
    pd: &PointData,
    guard: &BoundsGuard,
    done: u64,
    name: &str,
    fname: &'static str,
) -> Result<u64, ReadError> {
    let mut outside = 0;
    let mut times = pd.gps_time();
    for (i, (((x, y), z), id)) in pd
        .x()
        .zip(pd.y())
        .zip(pd.z())
        .zip(pd.point_source_id())
        .enumerate()
    {
        let p = [x, y, z];
        // Out-of-bounds points in a LAZ mean a damaged chunk decoded to garbage; in a
        // plain LAS the integers are what was written, and stale header bounds are common
        // in real files, so those points are kept and the details say so.
        if !guard.contains(p) && fname == "las" {
            outside += 1;
        } else if !guard.contains(p) {
            return Err(ReadError::at(
                name,
                fname,
                format!(
                    "({x}, {y}, {z}) lies outside the header's bounding box; the point data is corrupt{}",
                    " (a damaged compressed chunk?)"
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
    Ok(outside)
}

/// Uncompressed LAS decoded straight from the file's bytes into the cloud's arrays: batches
/// of `batch` points are read as [`decode_las`] reads them, `group` at a time (from `map`, the
/// source's map, when given; else from the source, the next group read while this one is
/// decoded when `parts` > 1), and each group is decoded in `parts` pieces, with exactly the
/// serial read's points, slots, counts and errors.
#[allow(clippy::too_many_arguments)]
fn decode_las_direct<R>(
    mut source: R,
    name: &str,
    options: &ReadOptions,
    plan: &HeaderCheck,
    batch: u64,
    group: usize,
    parts: usize,
    map: Option<&Mapped>,
) -> Result<PointCloud, ReadError>
where
    R: Read + Seek + Send,
{
    let fname = plan.format;
    // The header as the `las` reader parses it; that leaves the source at the point data.
    let header =
        las::Header::new(&mut source).map_err(|e| ReadError::named(name, fname, e.to_string()))?;
    let start = source
        .stream_position()
        .map_err(|e| ReadError::io(name, e))?;
    let count = header.number_of_points();
    let layout = Layout::new(&header, options.keep_time);
    // The header check confirmed the count against the file's size.
    let n = count as usize;
    let mut b = CloudBuilder::new(fname, 0, None, options.keep_time);
    let c = b.cloud_mut();
    c.xyz = vec![[0.0; 3]; n];
    c.scan = vec![0; n];
    c.time = vec![0.0; if layout.time.is_some() { n } else { 0 }];
    let guard = BoundsGuard::new(&header);
    let (batch, size) = (batch.max(1) as usize, layout.size);
    let block = batch * group.max(1);
    let blocks = n.div_ceil(block);
    let len = |k: usize| (n - k * block).min(block) * size;
    let mut written = 0;
    let mut outside = 0u64;
    // `filled` fails with the index of the first batch not read whole.
    let mut use_block = |k: usize, buf: &[u8], filled: Result<(), (usize, std::io::Error)>| {
        // Batches before a failed one are decoded first, as the serial read does.
        let whole = match &filled {
            Ok(()) => buf.len(),
            Err((j, _)) => j * batch * size,
        };
        if whole > 0 {
            let (kept, out) =
                decode_las_block(&mut b, &layout, &guard, &buf[..whole], written, parts)
                    .map_err(|why| ReadError::named(name, fname, why))?;
            written += kept;
            outside += out;
        }
        filled.map_err(|(j, e)| {
            let done = (k * block + j * batch) as u64;
            let end = (done + batch as u64).min(count).max(done + 1) - 1;
            ReadError::at(
                name,
                fname,
                las::Error::from(e).to_string(),
                format!("points {done} to {end} of {count}"),
            )
        })
    };
    match map {
        Some(map) => map.blocks(start, blocks, len, |k, buf, filled| {
            // A short block holds whole batches up to the first one the file cut.
            use_block(k, buf, filled.map_err(|e| (buf.len() / (batch * size), e)))
        })?,
        None => super::pool::read_ahead(
            &mut source,
            blocks,
            parts > 1,
            |reader, k, buf| {
                buf.resize(len(k), 0);
                for (j, part) in buf.chunks_mut(batch * size).enumerate() {
                    reader.read_exact(part).map_err(|e| (j, e))?;
                }
                Ok(())
            },
            use_block,
        )?,
    }
    let c = b.cloud_mut();
    c.xyz.truncate(written);
    c.scan.truncate(written);
    c.time.truncate(written);
    finish_las(b, &header, count, count, outside, name, fname)
}

/// Where a point record's fields are: x, y, z are the first three `i32`s of every format.
struct Layout {
    size: usize,
    scan: usize,
    time: Option<usize>,
    transforms: las::Vector<las::Transform>,
}

impl Layout {
    /// The record layout of `header`'s point format; the time only when kept.
    fn new(header: &las::Header, keep_time: bool) -> Layout {
        let f = header.point_format();
        // Formats 6 to 10 put a byte more of flags and a wider scan angle first.
        let (scan, time) = if f.is_extended { (20, 22) } else { (18, 20) };
        Layout {
            size: usize::from(f.len()),
            scan,
            time: (f.has_gps_time && keep_time).then_some(time),
            transforms: *header.transforms(),
        }
    }
}

/// Decodes whole records into the builder's arrays from point `at` on, in `parts` pieces;
/// returns the points kept and how many lie outside the header's bounds.
fn decode_las_block(
    b: &mut CloudBuilder,
    layout: &Layout,
    guard: &BoundsGuard,
    buf: &[u8],
    at: usize,
    parts: usize,
) -> Result<(usize, u64), String> {
    let size = layout.size;
    let n = buf.len() / size;
    // The first finite point fixes the local frame every piece needs.
    if !b.has_origin() {
        if let Some(p) = buf.chunks_exact(size).map(|r| layout.point(r)).find(finite) {
            b.fix_origin(p);
        }
    }
    let origin = b.origin().unwrap_or_default();
    let per = n.div_ceil(parts.max(1)).max(1);
    let out = Out::of(b.cloud_mut(), at, n);
    let pieces = decode_pieces(out, buf, size, per, |recs, out| {
        decode_las_piece(layout, guard, recs, origin, out)
    });
    settle_las_pieces(b, at, n, per, &pieces)
}

/// After `pieces` of `per` points each were decoded into points `at..at + n` of the builder's
/// arrays, in order: gives their scans the cloud's slots and closes the gaps skipped points
/// left. Returns the points kept and how many lie outside the header's bounds.
fn settle_las_pieces(
    b: &mut CloudBuilder,
    at: usize,
    n: usize,
    per: usize,
    pieces: &[LasPiece],
) -> Result<(usize, u64), String> {
    // Pieces' scans take the cloud's slots in order, as a serial read would give them.
    let mut maps = Vec::with_capacity(pieces.len());
    for piece in pieces {
        let map = piece.slots.ids.iter().map(|&id| b.scan_slot(id));
        maps.push((piece.kept, map.collect::<Result<Vec<u16>, String>>()?));
    }
    b.skip(pieces.iter().map(|p| p.skipped).sum());
    let kept = settle(Out::of(b.cloud_mut(), at, n), per, &maps);
    Ok((kept, pieces.iter().map(|p| p.outside).sum()))
}

impl Layout {
    /// A record's point in world coordinates, as the `las` crate computes it.
    #[inline(always)]
    fn point(&self, rec: &[u8]) -> [f64; 3] {
        let t = &self.transforms;
        [
            t.x.direct(i32::from_le_bytes(take(rec, 0))),
            t.y.direct(i32::from_le_bytes(take(rec, 4))),
            t.z.direct(i32::from_le_bytes(take(rec, 8))),
        ]
    }
}

/// `N` bytes of a record from offset `o`: one bounds check and one load, not one a byte.
#[inline(always)]
fn take<const N: usize>(rec: &[u8], o: usize) -> [u8; N] {
    let mut a = [0; N];
    a.copy_from_slice(&rec[o..o + N]);
    a
}

#[inline(always)]
fn finite(p: &[f64; 3]) -> bool {
    p[0].is_finite() && p[1].is_finite() && p[2].is_finite()
}

/// What a piece decoded.
struct LasPiece {
    kept: usize,
    skipped: u64,
    outside: u64,
    slots: LocalSlots,
}

/// Decodes the records `recs` into the start of `out` as [`decode_batch`] pushes them: every
/// record's scan takes a slot and is checked against the bounds; non-finite points are skipped.
fn decode_las_piece(
    layout: &Layout,
    guard: &BoundsGuard,
    recs: &[u8],
    origin: [f64; 3],
    out: Out<'_>,
) -> LasPiece {
    match layout.time {
        Some(g) => decode_las_piece_with::<true>(layout, g, guard, recs, origin, out),
        None => decode_las_piece_with::<false>(layout, 0, guard, recs, origin, out),
    }
}

/// [`decode_las_piece`] with or without the time at offset `g`, the loop's state (the last
/// scan's slot among it) in registers.
#[inline(always)]
fn decode_las_piece_with<const TIME: bool>(
    layout: &Layout,
    g: usize,
    guard: &BoundsGuard,
    recs: &[u8],
    origin: [f64; 3],
    out: Out<'_>,
) -> LasPiece {
    let mut slots = LocalSlots::new();
    let (xyz, scan, time) = (out.xyz, out.scan, out.time);
    let (ps, mut w, mut skipped, mut outside) = (layout.scan, 0, 0, 0);
    let mut last: Option<(u16, u16)> = None;
    for rec in recs.chunks_exact(layout.size) {
        let p = layout.point(rec);
        // Stale bounds are common in plain LAS: such points are kept and counted.
        outside += u64::from(!guard.contains(p));
        let id = u16::from_le_bytes(take(rec, ps));
        let slot = match last {
            Some((l, slot)) if l == id => slot,
            // A `u16` id never runs out of slots.
            _ => {
                let slot = slots.slot(u32::from(id)).unwrap_or_default();
                last = Some((id, slot));
                slot
            }
        };
        if !finite(&p) {
            skipped += 1;
            continue;
        }
        xyz[w] = to_local(origin, p);
        scan[w] = slot;
        if TIME {
            time[w] = f64::from_le_bytes(take(rec, g));
        }
        w += 1;
    }
    LasPiece {
        kept: w,
        skipped,
        outside,
        slots,
    }
}

/// Checks every point came, and records the CRS and what was read.
fn finish_las(
    mut b: CloudBuilder,
    header: &las::Header,
    done: u64,
    count: u64,
    outside: u64,
    name: &str,
    fname: &'static str,
) -> Result<PointCloud, ReadError> {
    if done < count {
        return Err(ReadError::at(
            name,
            fname,
            format!("the header claims {count} points but the data ends after {done}"),
            format!("point {done}"),
        ));
    }
    let crs = crs_of(header);
    let mut details = describe(header, crs.as_ref().map(|c| c.1));
    if outside > 0 {
        details +=
            &format!("; {outside} points lie outside the header's bounding box (stale bounds)");
    }
    let c = b.cloud_mut();
    c.crs = crs.map(|c| c.0);
    Ok(b.finish(details))
}

/// What the header check learned.
struct HeaderCheck {
    format: &'static str,
    /// For a LAZ file whose chunks can be decoded in parallel (a chunked compressor and a
    /// sound chunk table), the points per chunk (a guess for variable-sized chunks).
    laz_chunk: Option<u64>,
}

impl HeaderCheck {
    /// Points to ask the decoder for at a time: with parallel LAZ, a few chunks per thread, so
    /// every thread has whole chunks to decode; otherwise a cache-sized batch.
    fn batch(&self, parallel: bool) -> u64 {
        match self.laz_chunk {
            // Capped: a damaged header's huge chunk size must not size the buffers.
            Some(chunk) if parallel => chunk
                .saturating_mul(4 * super::pool::threads() as u64)
                .min(MAX_PARALLEL_BATCH),
            _ => CHUNK,
        }
    }
}

/// The `las` crate's reader over `source`, decoding LAZ chunks in parallel when `parallel`
/// and the file allows it.
fn open_reader<R>(source: R, plan: &HeaderCheck, parallel: bool) -> las::Result<Reader>
where
    R: Read + Seek + Send + Sync + 'static,
{
    let laz = if parallel && plan.laz_chunk.is_some() {
        LazParallelism::Yes
    } else {
        LazParallelism::No
    };
    Reader::with_options(source, ReaderOptions::default().with_laz_parallelism(laz))
}

/// The header's point count: the legacy 32-bit field, or the 64-bit one when that is zero.
fn point_count(raw: &las::raw::Header) -> u64 {
    let legacy = u64::from(raw.number_of_point_records);
    match raw.large_file {
        Some(lf) if legacy == 0 => lf.number_of_point_records,
        _ => legacy,
    }
}

/// The point count the public header declares, as the reader takes it, or `None` when the
/// header does not parse.
pub(crate) fn declared_points<R: Read>(source: &mut R) -> Option<u64> {
    las::raw::Header::read_from(source)
        .ok()
        .map(|raw| point_count(&raw))
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
    let mut laz_chunk = None;
    let format = if compressed { "laz" } else { "las" };
    check_transforms(&raw, name, format)?;
    let points = point_count(&raw);
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
        let laszip = laszip_items(source, &raw, name)?;
        // Variable-sized chunks (chunk size 0 or u32::MAX) take their point counts from the table.
        let variable = matches!(&laszip, Some((_, 0 | u32::MAX, _)));
        let fixed = match &laszip {
            Some((POINTWISE_CHUNKED | LAYERED_CHUNKED, size, _)) if !variable => {
                Some(u64::from(*size))
            }
            _ => None,
        };
        let table = check_chunk_table(source, start, len, points, variable, fixed, name)?;
        // Only the chunked compressors (1 is point-wise, 2 and 3 chunked) decode in parallel.
        if let Some((POINTWISE_CHUNKED | LAYERED_CHUNKED, size, _)) = &laszip {
            let chunk = match *size {
                0 | u32::MAX => 50_000,
                n => u64::from(n),
            };
            // The parallel decoder holds the rest of a fixed-size chunk, sized by the chunk
            // size whatever the points in the file: a huge one is decoded serially.
            let bytes = chunk.saturating_mul(u64::from(raw.point_data_record_length));
            if table.is_some() && (variable || bytes <= MAX_PARALLEL_CHUNK_BYTES) {
                laz_chunk = Some(chunk);
            }
        }
        match laszip {
            Some((_, _, items)) if items.is_empty() => {
                return Err(ReadError::named(
                    name,
                    "laz",
                    "the LASzip VLR lists no point items, so nothing can be decoded",
                ))
            }
            // The decoder writes records of its items' size into buffers of the header's
            // record length, and asserts that they fit a whole number of times.
            Some((_, _, items)) if record_of(&items) != u64::from(raw.point_data_record_length) => {
                return Err(ReadError::at(
                    name,
                    "laz",
                    format!(
                        "the LASzip VLR's point items make {}-byte records, but the header says \
                         {} bytes",
                        record_of(&items),
                        raw.point_data_record_length
                    ),
                    "byte 105",
                ))
            }
            Some((LAYERED_CHUNKED, _, items)) => {
                let chunks = Chunks {
                    fixed,
                    table: table.as_deref(),
                };
                check_layered_chunks(source, start, len, points, chunks, &items, name)?
            }
            _ => {}
        }
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
        if !fits {
            return Err(ReadError::at(
                name,
                format,
                format!(
                    "the first extended VLR's 60-byte header does not fit in the {len}-byte file"
                ),
                format!("byte {at}"),
            ));
        }
        if at.saturating_add(60).saturating_add(body) > len {
            return Err(ReadError::at(
                name,
                format,
                format!("an extended VLR of {body} bytes does not fit in the {len}-byte file"),
                format!("byte {at}"),
            ));
        }
    }
    source.seek(SeekFrom::Start(0)).map_err(io)?;
    Ok(HeaderCheck { format, laz_chunk })
}

/// Scale factors must be finite and non-zero and offsets finite, or every point is garbage.
fn check_transforms(
    raw: &las::raw::Header,
    name: &str,
    format: &'static str,
) -> Result<(), ReadError> {
    let fields = [
        ("x scale factor", raw.x_scale_factor, 131, true),
        ("y scale factor", raw.y_scale_factor, 139, true),
        ("z scale factor", raw.z_scale_factor, 147, true),
        ("x offset", raw.x_offset, 155, false),
        ("y offset", raw.y_offset, 163, false),
        ("z offset", raw.z_offset, 171, false),
    ];
    for (what, v, at, scale) in fields {
        if !v.is_finite() || (scale && v == 0.0) {
            return Err(ReadError::at(
                name,
                format,
                format!(
                    "the {what} is {v}; it must be a finite{} number",
                    if scale { ", non-zero" } else { "" }
                ),
                format!("byte {at}"),
            ));
        }
    }
    Ok(())
}

/// LAZ keeps a chunk table whose entry count the decoder allocates from. Returns its entries
/// when the table is whole and consistent with the file, so the chunks can be decoded in
/// parallel.
/// Chunks of `fixed` points (a chunked compressor's) must cover the header's points too.
fn check_chunk_table<R: Read + Seek>(
    source: &mut R,
    start: u64,
    len: u64,
    points: u64,
    variable: bool,
    fixed: Option<u64>,
    name: &str,
) -> Result<Option<Vec<ChunkTableEntry>>, ReadError> {
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
            return Ok(None);
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
    // The parallel decoder reads the table too, and allocates from its byte and point counts.
    source.seek(SeekFrom::Start(table)).map_err(io)?;
    // The table is itself compressed, and its decoder panics on some damaged ones.
    let read = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        laz::laszip::ChunkTable::read(&mut *source, variable)
    }));
    let entries = match read {
        Ok(Ok(entries)) => entries,
        // The sequential decoder of fixed-size chunks never reads the table.
        Ok(Err(_)) | Err(_) if !variable => return Ok(None),
        Ok(Err(e)) => {
            return Err(ReadError::at(
                name,
                "laz",
                format!("the chunk table cannot be read ({e})"),
                format!("byte {table}"),
            ))
        }
        Err(panic) => {
            return Err(ReadError::at(
                name,
                "laz",
                format!(
                    "the chunk table cannot be read: it is damaged ({})",
                    super::panic_text(&panic)
                ),
                format!("byte {table}"),
            ))
        }
    };
    // The parallel decoder takes only the table's chunks: they must cover every point.
    let covered = match fixed {
        _ if variable => Some(
            entries
                .as_ref()
                .iter()
                .fold(0u64, |n, e| n.saturating_add(e.point_count)),
        ),
        Some(size) => Some(chunks.saturating_mul(size)),
        None => None,
    };
    if let Some(covered) = covered.filter(|&c| c < points) {
        return Err(ReadError::at(
            name,
            "laz",
            format!(
                "the chunk table's {chunks} chunks hold {covered} points, fewer than the {points} the header claims"
            ),
            format!("byte {table}"),
        ));
    }
    let bytes = entries
        .as_ref()
        .iter()
        .fold(0u64, |n, e| n.saturating_add(e.byte_count));
    let sane = entries
        .as_ref()
        .iter()
        .all(|e| e.point_count <= points.max(1) && e.byte_count <= len);
    Ok((sane && bytes <= table.saturating_sub(start)).then(|| entries.as_ref().to_vec()))
}

/// The bytes of a record of point items (type, size).
fn record_of(items: &[(u16, u16)]) -> u64 {
    items.iter().map(|&(_, size)| u64::from(size)).sum()
}

/// The compressor, chunk size and item list (type, size) of a LAZ file's LASzip VLR; `None`
/// when there is no readable such VLR (the decoder then says so).
#[allow(clippy::type_complexity)]
fn laszip_items<R: Read + Seek>(
    source: &mut R,
    raw: &las::raw::Header,
    name: &str,
) -> Result<Option<(u16, u32, Vec<(u16, u16)>)>, ReadError> {
    let io = |e: std::io::Error| ReadError::io(name, e);
    let end = u64::from(raw.offset_to_point_data);
    // The decoder reads the version's whole header even when `header_size` says less, and
    // the VLRs after it: look where it looks, or a VLR it finds is missed here.
    let mut at = u64::from(raw.header_size.max(raw.version.header_size()));
    for _ in 0..raw.number_of_variable_length_records {
        if at + 54 > end {
            break;
        }
        let mut head = [0u8; 54];
        source.seek(SeekFrom::Start(at)).map_err(io)?;
        source.read_exact(&mut head).map_err(io)?;
        let user = &head[2..18];
        let record_id = u16::from_le_bytes([head[18], head[19]]);
        let length = u64::from(u16::from_le_bytes([head[20], head[21]]));
        if user.starts_with(b"laszip encoded") && record_id == 22204 {
            if length < 34 || at + 54 + length > end {
                return Ok(None);
            }
            let mut data = vec![0u8; length as usize];
            source.read_exact(&mut data).map_err(io)?;
            let compressor = u16::from_le_bytes([data[0], data[1]]);
            let count = usize::from(u16::from_le_bytes([data[32], data[33]]));
            if data.len() < 34 + 6 * count {
                return Ok(None);
            }
            let items = (0..count)
                .map(|i| {
                    let o = 34 + 6 * i;
                    (
                        u16::from_le_bytes([data[o], data[o + 1]]),
                        u16::from_le_bytes([data[o + 2], data[o + 3]]),
                    )
                })
                .collect();
            let chunk_size = u32::from_le_bytes([data[12], data[13], data[14], data[15]]);
            return Ok(Some((compressor, chunk_size, items)));
        }
        at += 54 + length;
    }
    Ok(None)
}

/// A layered chunk's shape for item list `items` (type, size): its layer count and the bytes
/// of its first point, which is stored raw; `None` when an item is not a layered one.
fn layered_shape(items: &[(u16, u16)]) -> Option<(u64, u64)> {
    let mut layers = 0u64;
    let mut first_point = 0u64;
    for &(kind, size) in items {
        layers += match kind {
            10 => 9,               // Point14
            11 | 13 => 1,          // RGB14, WavePacket14
            12 => 2,               // RGBNIR14
            14 => u64::from(size), // Byte14: a layer per byte
            _ => return None,
        };
        first_point += u64::from(size);
    }
    Some((layers, first_point))
}

/// Where a layered file's chunks lie, as the decoders see them.
#[derive(Clone, Copy)]
struct Chunks<'a> {
    /// Points per chunk, when the chunks are of fixed size: the decoder takes this many from
    /// each, whatever count the chunk itself declares.
    fixed: Option<u64>,
    /// The chunk table, when it is sound: the parallel decoders cut the chunks by it.
    table: Option<&'a [ChunkTableEntry]>,
}

/// Checks the layer sizes of a layered LAZ file's chunks. The decoder allocates (and zeroes) a
/// buffer of each declared size before reading it, so a damaged size of 4 GB would otherwise
/// cost 4 GB. A chunk is its first point raw, the point count, one `u32` size per layer, then
/// the layers.
/// - The serial decoder goes from chunk to chunk by those sizes: every chunk it meets must fit
///   in the file.
/// - The parallel decoders cut the chunks by the table: each chunk's layers must fit in the
///   bytes the table gives it.
fn check_layered_chunks<R: Read + Seek>(
    source: &mut R,
    start: u64,
    len: u64,
    points: u64,
    chunks: Chunks<'_>,
    items: &[(u16, u16)],
    name: &str,
) -> Result<(), ReadError> {
    // Not layered: the decoder refuses it.
    let Some((layers, first_point)) = layered_shape(items) else {
        return Ok(());
    };
    let mut at = start + 8;
    let mut left = points;
    let mut chunk = 0u64;
    while left > 0 {
        let head = layered_head(source, at, len, layers, first_point, chunk, name)?;
        if head.count == 0 {
            return Err(ReadError::at(
                name,
                "laz",
                format!("compressed chunk {chunk} holds no points, with {left} still to come"),
                format!("byte {}", head.sizes_at),
            ));
        }
        if let Some((i, size)) = head.past(len) {
            return Err(ReadError::at(
                name,
                "laz",
                format!(
                    "compressed chunk {chunk} declares a layer of {size} bytes, past the end of the {len}-byte file"
                ),
                format!("byte {}", head.sizes_at + 4 * (i as u64 + 1)),
            ));
        }
        left = left.saturating_sub(chunks.fixed.unwrap_or(head.count));
        at = head.end;
        chunk += 1;
    }
    let mut at = start + 8;
    for (chunk, e) in chunks.table.unwrap_or_default().iter().enumerate() {
        let head = layered_head(source, at, len, layers, first_point, chunk as u64, name)?;
        let end = at.saturating_add(e.byte_count);
        if head.end > end {
            return Err(ReadError::at(
                name,
                "laz",
                format!(
                    "compressed chunk {chunk} declares {} bytes of layers, more than the {} \
                     bytes the chunk table gives it",
                    head.end - (head.sizes_at + 4 + 4 * layers),
                    e.byte_count
                ),
                format!("byte {}", head.sizes_at),
            ));
        }
        at = end;
    }
    Ok(())
}

/// What a layered chunk's header declares.
struct LayeredHead {
    /// Where its point count is, after the raw first point.
    sizes_at: u64,
    count: u64,
    sizes: Vec<u64>,
    /// Where its last layer ends, by the sizes (saturating).
    end: u64,
}

impl LayeredHead {
    /// The first layer that ends past `len`, and its size.
    fn past(&self, len: u64) -> Option<(usize, u64)> {
        let mut end = self.sizes_at + 4 + 4 * self.sizes.len() as u64;
        self.sizes.iter().enumerate().find_map(|(i, &size)| {
            end = end.saturating_add(size);
            (end > len).then_some((i, size))
        })
    }
}

/// Reads the header of the layered chunk at byte `at` (chunk number `chunk`, for messages).
fn layered_head<R: Read + Seek>(
    source: &mut R,
    at: u64,
    len: u64,
    layers: u64,
    first_point: u64,
    chunk: u64,
    name: &str,
) -> Result<LayeredHead, ReadError> {
    let io = |e: std::io::Error| ReadError::io(name, e);
    let sizes_at = at.saturating_add(first_point);
    let mut buf = vec![0u8; 4 + 4 * layers as usize];
    if sizes_at.saturating_add(buf.len() as u64) > len {
        return Err(ReadError::at(
            name,
            "laz",
            format!("compressed chunk {chunk} ends inside its header: the file is truncated"),
            format!("byte {at}"),
        ));
    }
    source.seek(SeekFrom::Start(sizes_at)).map_err(io)?;
    source.read_exact(&mut buf).map_err(io)?;
    let mut words = buf
        .chunks_exact(4)
        .map(|w| u64::from(u32::from_le_bytes([w[0], w[1], w[2], w[3]])));
    let count = words.next().unwrap_or(0);
    let sizes: Vec<u64> = words.collect();
    let end = sizes
        .iter()
        .fold(sizes_at + buf.len() as u64, |end, &s| end.saturating_add(s));
    Ok(LayeredHead {
        sizes_at,
        count,
        sizes,
        end,
    })
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

    #[inline(always)]
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    /// A source that fails once `limit` bytes have been read, as a failing disk would.
    struct Failing {
        inner: Cursor<Vec<u8>>,
        limit: u64,
    }

    impl Read for Failing {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.inner.position() >= self.limit {
                return Err(std::io::Error::other("the disk failed"));
            }
            let room = (self.limit - self.inner.position()) as usize;
            let n = buf.len().min(room);
            self.inner.read(&mut buf[..n])
        }
    }

    impl Seek for Failing {
        fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
            self.inner.seek(pos)
        }
    }

    #[test]
    fn parallel_las_reads_exactly_the_serial_points_and_errors() {
        // Three batches of `CHUNK`, the last one short.
        let n = 150_011;
        let mut c = PointCloud {
            origin: [500_000.0, 5_400_000.0, 0.0],
            scan_ids: vec![4, 9, 2, 7],
            ..Default::default()
        };
        for i in 0..n {
            let f = i as f32;
            c.xyz
                .push([f * 0.001, (f * 0.37).sin() * 20.0, (i % 300) as f32 * 0.01]);
            // Scans in runs that come back, so parts meet scans in another order.
            c.scan.push(((i / 3_001) % 4) as u16);
            c.time.push(i as f64 * 1e-3);
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.las");
        crate::io::export::write_las(&path, &c, false).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let len = bytes.len() as u64;
        // The same points with an x scale so large that most overflow to infinity: skipped
        // points leave gaps for the pieces to close.
        let mut huge = bytes.clone();
        huge[131..139].copy_from_slice(&1e305f64.to_le_bytes());
        for (bytes, skips) in [(&bytes, false), (&huge, true)] {
            let serial = read_las_with(
                Cursor::new(bytes.clone()),
                len,
                "t.las",
                &ReadOptions::default(),
                false,
                None,
            )
            .unwrap();
            let skipped = serial.source.skipped as usize;
            assert_eq!((skipped > 0, serial.len()), (skips, n - skipped));
            assert!(serial.len() > 1_000, "some points are still kept");
            let map = mapped(&dir.path().join("m.las"), bytes);
            let direct = |batch: u64, group: usize, parts: usize, map: Option<&Mapped>| {
                let mut source = Cursor::new(bytes.clone());
                let plan = check_header(&mut source, len, "t.las").unwrap();
                let options = ReadOptions::default();
                decode_las_direct(source, "t.las", &options, &plan, batch, group, parts, map)
            };
            let cases = [
                (13, 3, 2),
                (1_000, 8, 3),
                (4_099, 5, 1),
                (CHUNK, 4, 2),
                (CHUNK, 1, 1),
                (n as u64, 2, 2),
            ];
            for (batch, group, parts) in cases {
                let parallel = direct(batch, group, parts, None).unwrap();
                assert_same(&serial, &parallel);
                // From a map, blocks end inside pages and records cross page ends.
                let parallel = direct(batch, group, parts, Some(&map)).unwrap();
                assert_same(&serial, &parallel);
            }
        }
        // A read that fails part way names the same points whether decoded in parallel or not.
        let failing = || Failing {
            inner: Cursor::new(bytes.clone()),
            limit: len - 40_000,
        };
        let options = ReadOptions::default();
        let serial = read_las_with(failing(), len, "t.las", &options, false, None)
            .unwrap_err()
            .to_string();
        assert!(
            serial.contains("points 131072 to 150010 of 150011"),
            "{serial}"
        );
        let plan = check_header(&mut failing(), len, "t.las").unwrap();
        for (group, parts) in [(3, 2), (1, 1), (8, 3)] {
            let parallel = decode_las_direct(
                failing(),
                "t.las",
                &options,
                &plan,
                CHUNK,
                group,
                parts,
                None,
            )
            .unwrap_err()
            .to_string();
            assert_eq!(parallel, serial);
        }
        // A file that shrank after its size was checked ends inside a batch: the map gives
        // the error the serial read of the shorter file gives, for the same points.
        let cut = &bytes[..bytes.len() - 40_000];
        let serial = decode_las(
            Cursor::new(cut.to_vec()),
            len,
            "t.las",
            &options,
            &plan,
            false,
        )
        .unwrap_err()
        .to_string();
        assert!(
            serial.contains("points 131072 to 150010 of 150011"),
            "{serial}"
        );
        let map = mapped(&dir.path().join("cut.las"), cut);
        for (batch, group, parts) in [(CHUNK, 3, 2), (CHUNK, 1, 1), (CHUNK, 8, 3)] {
            let source = Cursor::new(bytes.clone());
            let parallel = decode_las_direct(
                source,
                "t.las",
                &options,
                &plan,
                batch,
                group,
                parts,
                Some(&map),
            )
            .unwrap_err()
            .to_string();
            assert_eq!(parallel, serial);
        }
    }

    /// `bytes` written to `path`, mapped.
    fn mapped(path: &std::path::Path, bytes: &[u8]) -> Mapped {
        std::fs::write(path, bytes).unwrap();
        let file = std::fs::File::open(path).unwrap();
        Mapped::new(&file, &ReadOptions::default()).expect("a file maps")
    }

    /// A cloud of `n` points in runs of three scans, with times (the LAZ tests' cloud).
    pub(super) fn cloud(n: usize) -> PointCloud {
        let mut c = PointCloud {
            origin: [500_000.0, 5_400_000.0, 0.0],
            scan_ids: vec![4, 9, 2],
            ..Default::default()
        };
        for i in 0..n {
            let f = i as f32;
            c.xyz
                .push([f * 0.001, (f * 0.37).sin() * 20.0, (i % 300) as f32 * 0.01]);
            c.scan.push(((i / 7_000) % 3) as u16);
            c.time.push(i as f64 * 1e-3);
        }
        c
    }

    #[test]
    fn parallel_laz_reads_exactly_the_serial_points() {
        // Several batches of compressed chunks (one batch decoded while the next is filled),
        // the last chunk short.
        let n = 1_000_003;
        let c = cloud(n);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.laz");
        crate::io::export::write_las(&path, &c, true).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let len = bytes.len() as u64;
        let plan = check_header(&mut Cursor::new(bytes.clone()), len, "t.laz").unwrap();
        let chunk = plan.laz_chunk.expect("the file has a chunk table");
        assert!(chunk < n as u64, "one chunk only: nothing to split");
        assert!(
            n as u64 > 2 * plan.batch(true),
            "fewer than three batches: nothing is decoded while another fills"
        );
        let read = |bytes: &[u8], parallel: bool| {
            let source = Cursor::new(bytes.to_vec());
            read_las_with(
                source,
                len,
                "t.laz",
                &ReadOptions::default(),
                parallel,
                None,
            )
        };
        let (serial, parallel) = (read(&bytes, false).unwrap(), read(&bytes, true).unwrap());
        assert_eq!(serial.len(), n);
        assert_same(&serial, &parallel);
        // The parallel read took the path straight into the cloud, not the `las` crate's.
        let straight = arriving::read_laz_whole(
            &mut Cursor::new(bytes.clone()),
            len,
            "t.laz",
            &ReadOptions::default(),
        )
        .expect("fixed-size chunks are decoded straight into the cloud");
        assert_same(&serial, &straight);
        // Damage in the second batch fails the read, in parallel as in series, and the error
        // names points from the damaged batch on.
        let at = (plan.batch(true) + chunk / 2) as f64 / n as f64;
        let mut damaged = bytes.clone();
        let offset = 400 + ((len - 400) as f64 * at) as usize;
        damaged[offset..offset + 64]
            .iter_mut()
            .for_each(|b| *b ^= 0x5a);
        for parallel in [false, true] {
            let e = read(&damaged, parallel).expect_err("damaged chunk read");
            // "points 400000 to ..." or "point 412345".
            let first = match &e {
                ReadError::Invalid { at: Some(at), .. } => at
                    .split_whitespace()
                    .nth(1)
                    .and_then(|k| k.parse::<u64>().ok()),
                _ => None,
            };
            let first = first.unwrap_or_else(|| panic!("no point named: {e}"));
            assert!(
                first >= plan.batch(true) - chunk,
                "parallel {parallel}: {e}"
            );
        }
    }

    /// Where the chunk size of `laz`'s LASzip VLR lies in the file.
    fn laszip_chunk_size_at(laz: &[u8]) -> usize {
        let u16_at = |k: usize| u16::from_le_bytes([laz[k], laz[k + 1]]) as usize;
        let vlrs = u32::from_le_bytes(laz[100..104].try_into().unwrap());
        let mut at = u16_at(94);
        for _ in 0..vlrs {
            if laz[at + 2..at + 18].starts_with(b"laszip encoded") {
                // Compressor, coder, version (4 bytes), options, then the chunk size.
                return at + 54 + 12;
            }
            at += 54 + u16_at(at + 20);
        }
        panic!("no LASzip VLR")
    }

    #[test]
    fn a_huge_fixed_chunk_size_is_decoded_serially_to_the_same_points() {
        // Found by fuzzing: the `laz` crate's parallel decoder allocates the last chunk's
        // records by the chunk size, 154 GB for a 10-point file whose header said 4.3 G points
        // a chunk. Such a file holds one chunk, which the serial decoder reads as it is.
        let c = cloud(1_000);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.laz");
        crate::io::export::write_las(&path, &c, true).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let len = bytes.len() as u64;
        let at = laszip_chunk_size_at(&bytes);
        assert_eq!(&bytes[at..at + 4], &50_000u32.to_le_bytes());
        let mut huge = bytes.clone();
        huge[at..at + 4].copy_from_slice(&0xFF00_0000u32.to_le_bytes());
        let plan = check_header(&mut Cursor::new(huge.clone()), len, "t.laz").unwrap();
        assert_eq!(plan.laz_chunk, None, "decoded in parallel");
        let read = |bytes: &[u8]| {
            read_las_with(
                Cursor::new(bytes.to_vec()),
                len,
                "t.laz",
                &ReadOptions::default(),
                true,
                None,
            )
            .unwrap()
        };
        let (normal, huge) = (read(&bytes), read(&huge));
        assert_eq!(normal.len(), 1_000);
        assert_same(&normal, &huge);
    }

    #[test]
    fn laz_chunks_decoded_in_place_give_the_serial_reads_scans_in_its_order() {
        // Chunks of 50 000 points decoded each straight into its stretch of the cloud, in
        // windows of five chunks in the tests: scans first seen in later chunks (chunks 3 and
        // 6, after the first group, in two windows) must still take their slots in file order,
        // and the short last chunk must end the cloud.
        let n = 450_001;
        let mut c = cloud(n);
        c.scan_ids = vec![30, 7, 19, 3, 25, 11];
        for (i, s) in c.scan.iter_mut().enumerate() {
            *s = ((i / 150_000 + (i / 3_000) % 2 * 3) % 6) as u16;
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.laz");
        crate::io::export::write_las(&path, &c, true).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        // With and without times (the records are the same; only the arrays differ).
        for serial in straight_reads_match_serial(&bytes) {
            assert_eq!(serial.len(), n);
            assert_eq!(serial.scan_ids, [30, 3, 7, 25, 19, 11]);
        }
    }

    /// Reads a LAZ file's bytes straight into place and through the `las` crate's serial
    /// reader, with times kept and not: both must give the same cloud, bit for bit, with times
    /// only when kept. Returns the serial reads.
    pub(super) fn straight_reads_match_serial(bytes: &[u8]) -> Vec<PointCloud> {
        let len = bytes.len() as u64;
        [true, false]
            .into_iter()
            .map(|keep_time| {
                let options = ReadOptions {
                    keep_time,
                    ..ReadOptions::default()
                };
                let source = Cursor::new(bytes.to_vec());
                let serial = read_las_with(source, len, "t.laz", &options, false, None).unwrap();
                let mut source = Cursor::new(bytes.to_vec());
                let straight = arriving::read_laz_whole(&mut source, len, "t.laz", &options)
                    .expect("fixed-size chunks are decoded straight into the cloud");
                assert_eq!(
                    straight.time.is_empty(),
                    !keep_time,
                    "keep_time {keep_time}"
                );
                assert_same(&serial, &straight);
                serial
            })
            .collect()
    }

    /// Two reads of one file gave the same cloud, bit for bit.
    fn assert_same(a: &PointCloud, b: &PointCloud) {
        let bits = |c: &PointCloud| -> Vec<[u32; 3]> {
            c.xyz.iter().map(|p| p.map(f32::to_bits)).collect()
        };
        assert!(bits(a) == bits(b), "points differ");
        assert_eq!(a.scan, b.scan);
        assert_eq!(a.scan_ids, b.scan_ids);
        assert_eq!(a.time, b.time);
        assert_eq!(a.origin, b.origin);
        assert_eq!(a.source, b.source);
    }
}
