//! LAZ decoded while its file arrives (an upload being received), so that little is left to
//! decode when the last byte lands.
//!
//! The header and VLRs come first. Then the chunks are decoded front to back as their bytes
//! arrive: a fixed-size chunk's decoder needs no chunk table, and where it ends the next chunk
//! begins. When bytes arrive faster than one thread decodes them, a second lane finds where a
//! chunk starts further on (a layered chunk declares its size; a point-wise chunk's start is
//! guessed from its first record) and decodes from there; its chunks count only once the
//! first lane reaches exactly that byte. Once every byte is in, the file gets the whole-file
//! read's checks (`check_header`, the header as the `las` crate parses it, the chunk table) and
//! the chunks left are decoded in parallel from the table.
//!
//! The cloud is exactly [`super::read_las`]'s for the whole file. Every chunk decoded front to
//! back must have ended where the table says it does, so both reads decoded the same bytes;
//! every chunk is decoded whole (the table's last until its bytes end), as the parallel reader
//! decodes them, so a damaged tail fails both; the records become points through the code of
//! uncompressed LAS ([`super::decode_las_block`]) with the LAZ rule that a point outside the
//! header's bounds is an error. Whatever this read cannot vouch for (variable-sized or huge
//! chunks, extended VLRs, a chunk table the whole-file read would not use) and every error
//! fails it: the caller then reads the whole file, whose read gives the cloud or the error.

use std::io::{BufReader, Cursor, Read, Seek, SeekFrom};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use laz::las::selective::DecompressionSelection;
use laz::laszip::{ChunkTable, ChunkTableEntry};
use laz::record::{
    LayeredPointRecordDecompressor, RecordDecompressor, SequentialPointRecordDecompressor,
};
use laz::{LazItem, LazVlr};
use rayon::prelude::*;

use super::{
    check_header, decode_las_block, decode_las_piece, finish_las, layered_shape, record_of,
    settle_las_pieces, BoundsGuard, Layout, CHUNK, LAYERED_CHUNKED, LAZ_RESERVE_POINTS_PER_BYTE,
    MAX_LAZ_POINTS_PER_BYTE, MAX_PARALLEL_BATCH, POINTWISE_CHUNKED,
};
use crate::cloud::PointCloud;
use crate::io::assemble::{split_out, CloudBuilder, Out};
use crate::io::{ReadError, ReadOptions};

/// A file still arriving: a read past what has arrived waits for it.
pub trait Arriving: Read + Seek {
    /// True once every byte has arrived, so reads no longer wait.
    fn arrived(&self) -> bool;
    /// How many bytes have arrived so far.
    fn available(&self) -> u64;
    /// Another handle on the same file with a position of its own, for a second decoding lane.
    fn another(&self) -> std::io::Result<Self>
    where
        Self: Sized;
}

/// Chunks of more points than this are left to the whole-file read: the parallel decode holds
/// whole chunks' records.
const MAX_CHUNK: u64 = 1 << 20;

/// Headers and VLRs larger than this are left to the whole-file read: they are held in memory.
const MAX_HEAD: u64 = 16 << 20;

/// The most points decoded in place between two waits for every chunk to be in: it bounds the
/// buffers of records (one a chunk decoded at once). Small in the tests, so that they cross
/// windows.
const WINDOW: u64 = if cfg!(test) {
    1 << 18
} else {
    MAX_PARALLEL_BATCH
};

/// The most bytes of records the second lane holds before the first lane has reached them.
const MAX_HELD: usize = 64 << 20;

/// Reads the LAZ file `source` of `len` bytes while it arrives.
pub fn read_laz_arriving<R>(
    source: R,
    len: u64,
    name: &str,
    options: &ReadOptions,
) -> Result<PointCloud, ReadError>
where
    R: Arriving + Send + Sync,
{
    read_counted(source, len, name, options).map(|(cloud, _)| cloud)
}

/// Reads the LAZ file `source` of `len` bytes, all there: the chunks are decoded in parallel
/// from the chunk table, straight into the cloud's arrays. The cloud is [`super::read_las`]'s
/// through the `las` crate, which is faster to reach this way; whatever this read refuses, or
/// fails on, is left to that one.
pub(super) fn read_laz_whole<R>(
    source: &mut R,
    len: u64,
    name: &str,
    options: &ReadOptions,
) -> Result<PointCloud, ReadError>
where
    R: Read + Seek + Send + Sync,
{
    source
        .seek(SeekFrom::Start(0))
        .map_err(|e| ReadError::io(name, e))?;
    read_laz_arriving(Whole(source, len), len, name, options)
}

/// A file that has arrived whole: no read waits, and no second lane is asked for.
struct Whole<'a, R>(&'a mut R, u64);

impl<R: Read> Read for Whole<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(buf)
    }
}

impl<R: Seek> Seek for Whole<'_, R> {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.0.seek(pos)
    }
}

impl<R: Read + Seek> Arriving for Whole<'_, R> {
    fn arrived(&self) -> bool {
        true
    }

    fn available(&self) -> u64 {
        self.1
    }

    fn another(&self) -> std::io::Result<Self> {
        Err(std::io::Error::other("a whole file has one lane"))
    }
}

/// The chunks decoded before the last byte arrived, and how many of them the second lane
/// decoded.
#[derive(Debug, Clone, Copy)]
// Only the tests look: they check how the lanes shared the work.
#[cfg_attr(not(test), allow(dead_code))]
struct Early {
    chunks: usize,
    ahead: usize,
}

/// [`read_laz_arriving`], and what it decoded before the last byte arrived.
fn read_counted<R>(
    mut source: R,
    len: u64,
    name: &str,
    options: &ReadOptions,
) -> Result<(PointCloud, Early), ReadError>
where
    R: Arriving + Send + Sync,
{
    let start = Start::read(&mut source, len, name, options.keep_time)?;
    let layout = Layout::new(&start.header, options.keep_time);
    let guard = BoundsGuard::new(&start.header);
    let count = start.header.number_of_points();
    // As the whole-file read reserves: a LAZ count is only loosely checked.
    let reserve = count.min(len.saturating_mul(LAZ_RESERVE_POINTS_PER_BYTE)) as usize;
    let mut b = CloudBuilder::new("laz", reserve, None, options.keep_time);
    let mut points = Points {
        layout: &layout,
        guard: &guard,
        written: 0,
        name,
    };
    let (source, spans, ahead) = decode_front(source, &start, &mut points, &mut b, len, name)?;
    let early = Early {
        chunks: spans.len(),
        ahead,
    };
    // The decoder's threads are the pool's: run the rest there.
    crate::io::pool::install(|| {
        decode_rest(source, &start, spans, &mut points, &mut b, len, name)
    })?;
    let c = b.cloud_mut();
    let written = points.written;
    c.xyz.truncate(written);
    c.scan.truncate(written);
    c.time.truncate(written);
    let cloud = finish_las(b, &start.header, count, count, 0, name, "laz")?;
    Ok((cloud, early))
}

/// A read refused for a reason of its own: the whole-file read decides.
fn not_here(name: &str, why: impl std::fmt::Display) -> ReadError {
    ReadError::named(name, "laz", format!("not decoded as it arrives: {why}"))
}

/// What the front of the file says.
struct Start {
    header: las::Header,
    codec: Codec,
    /// Where the point data starts (its first 8 bytes are the chunk table's offset).
    data: u64,
    chunk: u64,
    /// A layered chunk's layer count and raw first point's size.
    layered: Option<(u64, u64)>,
}

impl Start {
    /// Reads the header and VLRs (waiting for them) and refuses what this read does not decode.
    /// The points' times are decoded only when `keep_time` asks for them.
    fn read<R: Read + Seek>(
        source: &mut R,
        len: u64,
        name: &str,
        keep_time: bool,
    ) -> Result<Start, ReadError> {
        let io = |e: std::io::Error| ReadError::io(name, e);
        let raw = las::raw::Header::read_from(&mut *source)
            .map_err(|e| ReadError::at(name, "laz", e.to_string(), "byte 0"))?;
        if raw.point_data_record_format & 0xC0 == 0 {
            return Err(not_here(name, "the points are not compressed"));
        }
        // Extended VLRs lie after the points: the header is known only at the end.
        if raw.evlr.is_some() {
            return Err(not_here(name, "extended VLRs"));
        }
        let data = u64::from(raw.offset_to_point_data);
        if data > len.min(MAX_HEAD) {
            return Err(not_here(name, format!("the points start at byte {data}")));
        }
        let mut head = vec![0; data as usize];
        source.seek(SeekFrom::Start(0)).map_err(io)?;
        source.read_exact(&mut head).map_err(io)?;
        // The header as the whole-file read's `las` reader parses it (which at the end must
        // parse the whole file to this same header).
        let header = las::Header::new(Cursor::new(head))
            .map_err(|e| ReadError::named(name, "laz", e.to_string()))?;
        let vlr = header
            .laz_vlr()
            .map_err(|e| ReadError::named(name, "laz", e.to_string()))?;
        let compressor = header
            .vlrs()
            .iter()
            .find(|v| las::laz::is_laszip_vlr(v))
            .and_then(|v| v.data.get(..2))
            .map_or(0, |c| u16::from_le_bytes([c[0], c[1]]));
        let items: Vec<(u16, u16)> = vlr
            .items()
            .iter()
            .map(|i: &LazItem| (u16::from(i.item_type()), i.size()))
            .collect();
        let record = record_of(&items);
        let versions_ok = match compressor {
            POINTWISE_CHUNKED => vlr.items().iter().all(|i| matches!(i.version(), 1 | 2)),
            LAYERED_CHUNKED => vlr.items().iter().all(|i| matches!(i.version(), 3 | 4)),
            _ => false,
        };
        let chunk = u64::from(vlr.chunk_size());
        let layered = layered_shape(&items);
        let refusal = if !versions_ok || items.is_empty() {
            Some(format!("compressor {compressor} with its items"))
        } else if vlr.uses_variable_size_chunks() || chunk == 0 || chunk > MAX_CHUNK {
            Some(format!("chunks of {chunk} points"))
        } else if record != u64::from(header.point_format().len()) {
            Some(format!("records of {record} bytes"))
        } else if compressor == LAYERED_CHUNKED && layered.is_none() {
            Some("layered chunks of unknown items".into())
        } else if header.number_of_points() > len.saturating_mul(MAX_LAZ_POINTS_PER_BYTE) {
            Some(format!("{} points", header.number_of_points()))
        } else {
            None
        };
        if let Some(why) = refusal {
            return Err(not_here(name, why));
        }
        Ok(Start {
            header,
            codec: Codec::new(vlr, keep_time),
            data,
            chunk,
            layered: layered.filter(|_| compressor == LAYERED_CHUNKED),
        })
    }
}

/// Decoded records becoming the cloud's points.
struct Points<'a> {
    layout: &'a Layout,
    guard: &'a BoundsGuard,
    written: usize,
    name: &'a str,
}

impl Points<'_> {
    /// Appends whole records, decoded on `parts` threads; a point outside the header's bounds
    /// fails the read, as in the whole-file read of a LAZ.
    fn push(&mut self, b: &mut CloudBuilder, recs: &[u8], parts: usize) -> Result<(), ReadError> {
        let n = recs.len() / self.layout.size;
        room(b, self.written + n, self.layout.time.is_some());
        let settled = decode_las_block(b, self.layout, self.guard, recs, self.written, parts);
        self.settle(settled)
    }

    /// Counts a settled block's kept points as written, or fails the read with why it could
    /// not settle; a point outside the header's bounds fails it too.
    fn settle(&mut self, settled: Result<(usize, u64), String>) -> Result<(), ReadError> {
        let (kept, outside) = settled.map_err(|why| ReadError::named(self.name, "laz", why))?;
        if outside > 0 {
            return Err(not_here(
                self.name,
                "points outside the header's bounding box",
            ));
        }
        self.written += kept;
        Ok(())
    }
}

/// Makes the cloud's arrays `n` long, growing by a quarter at least, as `CloudBuilder::push`
/// grows, so they never double.
fn room(b: &mut CloudBuilder, n: usize, time: bool) {
    let c = b.cloud_mut();
    if c.xyz.capacity() < n {
        let len = c.xyz.len();
        c.xyz.reserve_exact((n - len).max(len / 4).max(1 << 16));
    }
    let cap = c.xyz.capacity();
    c.scan.reserve_exact(cap - c.scan.len());
    c.xyz.resize(n, [0.0; 3]);
    c.scan.resize(n, 0);
    if time {
        c.time.reserve_exact(cap - c.time.len());
        c.time.resize(n, 0.0);
    }
}

/// The point data read front to back with no seeking: the sequential decoder, denied the
/// chunk table, reads on from the start of the data. Counts the bytes it took.
struct Front<R> {
    buf: BufReader<R>,
    at: u64,
}

impl<R: Read> Read for Front<R> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        let n = self.buf.read(out)?;
        self.at += n as u64;
        Ok(n)
    }
}

impl<R> Seek for Front<R> {
    fn seek(&mut self, _: SeekFrom) -> std::io::Result<u64> {
        Err(std::io::Error::new(
            std::io::ErrorKind::Unsupported,
            "read front to back",
        ))
    }
}

impl<R: Read + Seek> Front<R> {
    /// Reads `out` at byte `at` of the file, leaving the reading where it was.
    fn peek(&mut self, at: u64, out: &mut [u8]) -> std::io::Result<()> {
        let inner = self.buf.get_mut();
        let back = inner.stream_position()?;
        inner.seek(SeekFrom::Start(at))?;
        inner.read_exact(out)?;
        inner.seek(SeekFrom::Start(back))?;
        Ok(())
    }
}

/// Decodes whole chunks front to back while bytes are still arriving, never the last chunk the
/// points need (it may be short, and is decoded as the table says). Returns the source, the
/// bytes each decoded chunk took, and how many of those chunks the second lane decoded.
///
/// When more has arrived than one lane has decoded, a second lane starts where a chunk seems to
/// start halfway along what is waiting (see [`chunk_start_after`]) and decodes on from there,
/// holding its records, while the first lane decodes up to it. Its chunks count only when the
/// first lane's last chunk ends exactly where the second lane began: the second lane then
/// decoded true chunks, and the points go in in file order. Otherwise its work is dropped.
fn decode_front<R>(
    mut source: R,
    start: &Start,
    points: &mut Points<'_>,
    b: &mut CloudBuilder,
    len: u64,
    name: &str,
) -> Result<(R, Vec<u64>, usize), ReadError>
where
    R: Arriving + Send + Sync,
{
    let io = |e: std::io::Error| ReadError::io(name, e);
    let needed = start.header.number_of_points().div_ceil(start.chunk);
    let mut spans = Vec::new();
    let mut second_lane = 0;
    if needed < 2 || source.arrived() {
        return Ok((source, spans, second_lane));
    }
    // Past the chunk table's offset, the first chunk.
    let mut at = start.data + 8;
    source.seek(SeekFrom::Start(at)).map_err(io)?;
    let mut lane = Lane::new(source, at, &start.codec).map_err(io)?;
    let size = points.layout.size;
    let mut raw = Vec::new();
    // A layered chunk says where it ends; a point-wise one opens with a record as it is,
    // which only real bounds tell from compressed bytes.
    let second = start.layered.is_some() || points.guard.active;
    while (spans.len() as u64) + 1 < needed && !lane.arrived() {
        let waiting = lane.available().saturating_sub(at);
        let typical = spans.iter().sum::<u64>() / (spans.len() as u64).max(1);
        let guess = match (
            second && typical > 0 && waiting >= 4 * typical,
            start.layered,
        ) {
            (false, _) => None,
            (true, Some((layers, first))) => {
                lane.hop_layered(at, at + waiting / 2, layers, first, len)
            }
            // Only a guess: a start that cannot be looked for is no start.
            (true, None) => lane
                .find_start(
                    at + waiting / 2,
                    2 * typical,
                    &start.codec,
                    points.layout,
                    points.guard,
                )
                .unwrap_or(None),
        };
        let second_handle = guess.and_then(|s| lane.another().ok().map(|h| (s, h)));
        let Some((s, other)) = second_handle else {
            spans.push(front_chunk(
                &mut lane, start, points, b, &mut raw, len, name,
            )?);
            at = lane.at();
            continue;
        };
        let stop = AtomicBool::new(false);
        let (first, held) = std::thread::scope(|scope| {
            let behind = scope.spawn(|| decode_ahead(other, s, start, size, len, &stop));
            let mut first = Ok(());
            while lane.at() < s && (spans.len() as u64) + 1 < needed {
                match front_chunk(&mut lane, start, points, b, &mut raw, len, name) {
                    Ok(bytes) => spans.push(bytes),
                    Err(e) => {
                        first = Err(e);
                        break;
                    }
                }
            }
            stop.store(true, Ordering::Relaxed);
            (first, behind.join().unwrap_or_default())
        });
        first?;
        at = lane.at();
        if at != s {
            continue;
        }
        for (bytes, recs) in held {
            if (spans.len() as u64) + 1 >= needed {
                break;
            }
            points.push(b, &recs, 1)?;
            spans.push(bytes);
            at += bytes;
            second_lane += 1;
        }
        lane = lane.jump(at, &start.codec).map_err(io)?;
    }
    Ok((lane.into_source(), spans, second_lane))
}

/// The first lane's next chunk, its points pushed as they are decoded; a layered chunk's
/// declared sizes are checked first.
fn front_chunk<'a, R: Arriving + Send + Sync + 'a>(
    lane: &mut Lane<'a, R>,
    start: &Start,
    points: &mut Points<'_>,
    b: &mut CloudBuilder,
    raw: &mut Vec<u8>,
    len: u64,
    name: &str,
) -> Result<u64, ReadError> {
    if let Some((layers, first)) = start.layered {
        lane.layered_end(layers, first, len, name)?;
    }
    lane.chunk(start.chunk, &start.codec, |r| points.push(b, r, 1), raw)
        .map_err(|e| e.into_error(name))
}

/// Why a lane's chunk failed.
enum ChunkError {
    Io(std::io::Error),
    Panicked,
    Points(ReadError),
}

impl ChunkError {
    fn into_error(self, name: &str) -> ReadError {
        match self {
            ChunkError::Io(e) => ReadError::io(name, e),
            // The decoder asserts on some damaged chunks.
            ChunkError::Panicked => not_here(name, "the decoder failed"),
            ChunkError::Points(e) => e,
        }
    }
}

/// One lane's decoding: the chunks from a chunk's start on, front to back, with no seeking.
struct Lane<'a, R> {
    dec: Box<dyn RecordDecompressor<Front<R>> + Send + Sync + 'a>,
}

impl<'a, R: Arriving + Send + Sync + 'a> Lane<'a, R> {
    /// A lane from byte `at` of `source`, which stands there.
    fn new(source: R, at: u64, codec: &Codec) -> std::io::Result<Lane<'a, R>> {
        let front = Front {
            buf: BufReader::with_capacity(1 << 16, source),
            at,
        };
        Ok(Lane {
            dec: codec.decoder(front)?,
        })
    }

    /// Where the next chunk starts.
    fn at(&self) -> u64 {
        self.dec.get().at
    }

    fn arrived(&self) -> bool {
        self.dec.get().buf.get_ref().arrived()
    }

    fn available(&self) -> u64 {
        self.dec.get().buf.get_ref().available()
    }

    fn another(&self) -> std::io::Result<R> {
        self.dec.get().buf.get_ref().another()
    }

    /// Where the layered chunk the lane is at ends, by the sizes it declares. The decoder
    /// allocates each layer's declared size before reading it, so each must fit in the file
    /// (as `check_chunk_table` checks the whole file's).
    fn layered_end(
        &mut self,
        layers: u64,
        first: u64,
        len: u64,
        name: &str,
    ) -> Result<u64, ReadError> {
        let (from, front) = (self.at(), self.dec.get_mut());
        layered_chunk_end(
            |at, out| front.peek(at, out),
            from,
            layers,
            first,
            len,
            name,
        )
    }

    /// The lane going on from byte `at`, a chunk's start.
    fn jump(self, at: u64, codec: &Codec) -> std::io::Result<Lane<'a, R>> {
        if at == self.at() {
            return Ok(self);
        }
        let mut source = self.into_source();
        source.seek(SeekFrom::Start(at))?;
        Lane::new(source, at, codec)
    }

    fn into_source(self) -> R {
        self.dec.box_into_inner().buf.into_inner()
    }

    /// Decodes the next chunk of `chunk` records, in pieces of at most [`CHUNK`] handed to
    /// `take`; returns the bytes the chunk took.
    fn chunk(
        &mut self,
        chunk: u64,
        codec: &Codec,
        mut take: impl FnMut(&[u8]) -> Result<(), ReadError>,
        raw: &mut Vec<u8>,
    ) -> Result<u64, ChunkError> {
        let from = self.at();
        codec.restart(&mut *self.dec).map_err(ChunkError::Io)?;
        let size = self.dec.record_size();
        let mut left = chunk;
        while left > 0 {
            let n = left.min(CHUNK);
            raw.resize(n as usize * size, 0);
            let dec = &mut self.dec;
            match catch_unwind(AssertUnwindSafe(|| dec.decompress_many(raw))) {
                Ok(Ok(())) => {}
                Ok(Err(e)) => return Err(ChunkError::Io(e)),
                Err(_) => return Err(ChunkError::Panicked),
            }
            take(raw).map_err(ChunkError::Points)?;
            left -= n;
        }
        Ok(self.at() - from)
    }

    /// The start of the first layered chunk at or past `target`, hopping from the chunk that
    /// starts at `at` by the sizes each declares, over bytes that have arrived; `None` when a
    /// chunk's header has not arrived or is unsound (the first lane then meets it itself).
    fn hop_layered(&self, at: u64, target: u64, layers: u64, first: u64, len: u64) -> Option<u64> {
        let mut peek = self.another().ok()?;
        let available = self.available();
        let mut s = at;
        while s < target {
            if s + first + 4 + 4 * layers > available {
                return None;
            }
            let read = |at: u64, out: &mut [u8]| {
                peek.seek(SeekFrom::Start(at))?;
                peek.read_exact(out)
            };
            s = layered_chunk_end(read, s, layers, first, len, "").ok()?;
        }
        (s < available).then_some(s)
    }

    /// A byte at or after `from`, within `window`, where a chunk seems to start (see
    /// [`chunk_start_after`]). Only bytes that have arrived are looked at.
    fn find_start(
        &self,
        from: u64,
        window: u64,
        codec: &Codec,
        layout: &Layout,
        guard: &BoundsGuard,
    ) -> std::io::Result<Option<u64>> {
        let end = (from + window + PROBE_BYTES).min(self.available());
        if end <= from + layout.size as u64 {
            return Ok(None);
        }
        let mut bytes = vec![0; (end - from) as usize];
        let mut peek = self.another()?;
        peek.seek(SeekFrom::Start(from))?;
        peek.read_exact(&mut bytes)?;
        let last = (window as usize).min(bytes.len());
        Ok(chunk_start_after(&bytes, last, codec, layout, guard).map(|k| from + k as u64))
    }
}

/// Records a likely chunk start must decode to, all within the header's bounds.
const PROBE: usize = 64;

/// Bytes read past a window so that a start near its end can be probed.
const PROBE_BYTES: u64 = 16 << 10;

/// The first offset before `last` in `bytes` where a point-wise chunk seems to start: its
/// first record, which such a chunk holds as it is, is a finite point within `guard`'s bounds,
/// and so are the next [`PROBE`] records decoded from there (an offset too near the end of
/// `bytes` to decode them is passed over). A coordinate of
/// compressed bytes lands within real bounds about once in 10^5 tries, a whole point about
/// once in 10^15, but a record's bytes shifted by a coordinate are often a point too, hence
/// the records decoded after it. A wrong guess only costs the second lane's work.
fn chunk_start_after(
    bytes: &[u8],
    last: usize,
    codec: &Codec,
    layout: &Layout,
    guard: &BoundsGuard,
) -> Option<usize> {
    let size = layout.size;
    let inside = |rec: &[u8]| {
        let p = layout.point(rec);
        super::finite(&p) && guard.contains(p)
    };
    let sound = |k: usize| {
        let mut recs = vec![0u8; PROBE * size];
        let decoded = catch_unwind(AssertUnwindSafe(|| {
            let mut dec = codec.decoder(Cursor::new(&bytes[k..]))?;
            dec.decompress_many(&mut recs)
        }));
        matches!(decoded, Ok(Ok(()))) && recs.chunks_exact(size).all(inside)
    };
    (0..last.min(bytes.len().checked_sub(size)? + 1))
        .find(|&k| inside(&bytes[k..k + size]) && sound(k))
}

/// The second lane: chunks from byte `s` of `source` on, their records held, until `stop` is
/// set (checked between chunks) or a chunk fails (a wrong start gives garbage or an error).
/// Returns each whole chunk's bytes and records, in order.
fn decode_ahead<R: Arriving + Send + Sync>(
    mut source: R,
    s: u64,
    start: &Start,
    size: usize,
    len: u64,
    stop: &AtomicBool,
) -> Vec<(u64, Vec<u8>)> {
    let mut held = Vec::new();
    if source.seek(SeekFrom::Start(s)).is_err() {
        return held;
    }
    let Ok(mut lane) = Lane::new(source, s, &start.codec) else {
        return held;
    };
    let mut total = 0usize;
    // At least one chunk, however soon the first lane is done: the lane is worth its start.
    while held.is_empty() || !stop.load(Ordering::Relaxed) && total < MAX_HELD {
        if let Some((layers, first)) = start.layered {
            if lane.layered_end(layers, first, len, "").is_err() {
                break;
            }
        }
        let mut recs = Vec::with_capacity(start.chunk as usize * size);
        let mut raw = Vec::new();
        let got = lane.chunk(
            start.chunk,
            &start.codec,
            |piece| {
                recs.extend_from_slice(piece);
                Ok(())
            },
            &mut raw,
        );
        match got {
            Ok(bytes) => {
                total += recs.len();
                held.push((bytes, recs));
            }
            Err(_) => break,
        }
    }
    held
}

/// Where the layered chunk starting at `from` ends, by the sizes it declares (read with
/// `peek`); an error when they run past the file's `len` bytes.
fn layered_chunk_end(
    mut peek: impl FnMut(u64, &mut [u8]) -> std::io::Result<()>,
    from: u64,
    layers: u64,
    first: u64,
    len: u64,
    name: &str,
) -> Result<u64, ReadError> {
    let sizes_at = from + first;
    let mut buf = vec![0u8; 4 + 4 * layers as usize];
    if sizes_at + buf.len() as u64 > len {
        return Err(not_here(name, "a chunk ends inside its header"));
    }
    peek(sizes_at, &mut buf).map_err(|e| ReadError::io(name, e))?;
    let words = buf
        .chunks_exact(4)
        .map(|w| u64::from(u32::from_le_bytes([w[0], w[1], w[2], w[3]])));
    let end = words
        .skip(1)
        .fold(sizes_at + buf.len() as u64, u64::saturating_add);
    if end > len {
        return Err(not_here(name, "a chunk's layers end past the file"));
    }
    Ok(end)
}

/// Once every byte is in: the whole-file read's checks, then the chunks after the `spans.len()`
/// decoded ones, in parallel from the chunk table.
fn decode_rest<R>(
    mut source: R,
    start: &Start,
    spans: Vec<u64>,
    points: &mut Points<'_>,
    b: &mut CloudBuilder,
    len: u64,
    name: &str,
) -> Result<(), ReadError>
where
    R: Arriving + Send + Sync,
{
    let io = |e: std::io::Error| ReadError::io(name, e);
    let decoder = |e: laz::LasZipError| ReadError::named(name, "laz", e.to_string());
    // The whole-file read decodes in parallel only with a sound table; else it goes on
    // serially, and so had better do it itself.
    source.seek(SeekFrom::Start(0)).map_err(io)?;
    let plan = check_header(&mut source, len, name)?;
    if plan.laz_chunk.is_none() {
        return Err(not_here(name, "no chunk table to decode in parallel from"));
    }
    source.seek(SeekFrom::Start(0)).map_err(io)?;
    let header =
        las::Header::new(&mut source).map_err(|e| ReadError::named(name, "laz", e.to_string()))?;
    if header != start.header {
        return Err(not_here(name, "the header changed"));
    }
    // As the parallel decoder reads it, from the start of the point data.
    let table = ChunkTable::read_from(&mut source, &start.codec.vlr).map_err(decoder)?;
    let entries = table.as_ref();
    let before_last = |i: usize| i + 1 < entries.len();
    if !spans
        .iter()
        .enumerate()
        .all(|(i, &s)| before_last(i) && entries[i].byte_count == s)
    {
        return Err(not_here(
            name,
            "the chunks decoded do not end where the chunk table says",
        ));
    }
    let count = start.header.number_of_points();
    let size = points.layout.size;
    let mut done = spans.len() as u64 * start.chunk;
    let mut at = start.data + 8 + spans.iter().sum::<u64>();
    let mut next = spans.len();
    let threads = crate::io::pool::threads();
    let (mut packed, mut raw) = (Vec::new(), Vec::new());
    // The cloud's frame is its first finite point's: until one is in, the chunks go in a few
    // at a time, as the early read pushes them.
    while done < count && !b.has_origin() {
        let needed = (count - done).div_ceil(start.chunk) as usize;
        let group = chunks_within(entries, next, needed.min(threads), at, len, name)?;
        let bytes = group.iter().map(|e| e.byte_count).sum::<u64>();
        packed.resize(bytes as usize, 0);
        source.seek(SeekFrom::Start(at)).map_err(io)?;
        source.read_exact(&mut packed).map_err(io)?;
        let last = next + group.len() == entries.len();
        // The decoder asserts on some damaged chunks.
        let got = catch_unwind(AssertUnwindSafe(|| {
            decode_chunks(&packed, group, last, &start.codec, size, &mut raw)
        }))
        .map_err(|_| not_here(name, "the decoder failed"))?
        .map_err(io)?;
        // Only the table's last chunk may come short; the loop then finds no more chunks.
        let take = got.min(count - done);
        points.push(b, &raw[..take as usize * size], threads)?;
        done += take;
        at += bytes;
        next += group.len();
    }
    if done < count {
        let needed = (count - done).div_ceil(start.chunk) as usize;
        let list = chunks_within(entries, next, needed, at, len, name)?;
        let last = next + list.len() == entries.len();
        let rest = Rest {
            list,
            at,
            last,
            points: count - done,
        };
        decode_in_place(source, &rest, start, points, b, name)?;
    }
    Ok(())
}

/// The `n` chunks of the table from entry `next` on, whose bytes start at `at`; an error when
/// the table or the file ends first.
fn chunks_within<'e>(
    entries: &'e [ChunkTableEntry],
    next: usize,
    n: usize,
    at: u64,
    len: u64,
    name: &str,
) -> Result<&'e [ChunkTableEntry], ReadError> {
    let list = &entries[next.min(entries.len())..(next + n).min(entries.len())];
    if list.len() < n {
        return Err(not_here(name, "the chunk table ends before the points"));
    }
    let bytes = list
        .iter()
        .fold(0u64, |s, e| s.saturating_add(e.byte_count));
    if at.saturating_add(bytes) > len {
        return Err(not_here(name, "the chunks end past the file"));
    }
    Ok(list)
}

/// The chunks left once the cloud's frame is fixed.
struct Rest<'e> {
    list: &'e [ChunkTableEntry],
    /// Where the first one's bytes start.
    at: u64,
    /// Whether the list ends with the table's last chunk (decoded until its bytes end).
    last: bool,
    /// The points still to come: the last chunk's records past them are not points.
    points: u64,
}

/// Decodes `rest`'s chunks on the pool's threads, each straight into its own stretch of the
/// cloud's arrays, so no chunk waits for others to finish: chunk `i` takes points from
/// `i * chunk` on, and the gaps skipped points leave are closed after, as for a block of
/// uncompressed records. The chunks go in windows of at most [`WINDOW`] points,
/// so a few buffers of records serve them all however large the chunks and many the threads.
fn decode_in_place<R: Read + Seek + Send>(
    source: R,
    rest: &Rest<'_>,
    start: &Start,
    points: &mut Points<'_>,
    b: &mut CloudBuilder,
    name: &str,
) -> Result<(), ReadError> {
    let (size, chunk) = (points.layout.size, start.chunk as usize);
    let mut offsets = Vec::with_capacity(rest.list.len());
    let mut at = rest.at;
    for e in rest.list {
        // Fixed-size chunks: the table gives each one the chunk's points.
        if e.point_count != start.chunk {
            return Err(not_here(name, "a chunk of another size"));
        }
        offsets.push(at);
        at += e.byte_count;
    }
    let window = (WINDOW / start.chunk).max(1) as usize;
    // One pair of buffers a chunk decoded at once, made up front and handed from chunk to
    // chunk, so their pages are faulted in once.
    let most = rest.list.iter().map(|e| e.byte_count).max().unwrap_or(0) as usize;
    let busy = crate::io::pool::threads().min(window).min(rest.list.len());
    let shelf = (0..busy)
        .map(|_| (Vec::with_capacity(most), Vec::with_capacity(chunk * size)))
        .collect::<Vec<(Vec<u8>, Vec<u8>)>>();
    let job = Job {
        source: Mutex::new(source),
        size,
        shelf: Mutex::new(shelf),
        rest,
        start,
        name,
    };
    let mut taken = 0;
    for (w, list) in rest.list.chunks(window).enumerate() {
        let first = w * window;
        taken += job.window(first, list.len(), &offsets[first..], points, b)?;
    }
    // Only the table's last chunk may come short, and then the points are missing.
    if taken < rest.points {
        return Err(not_here(name, "the chunk table ends before the points"));
    }
    Ok(())
}

/// What every chunk of [`decode_in_place`] shares.
struct Job<'a, R> {
    source: Mutex<R>,
    /// A record's bytes.
    size: usize,
    shelf: Mutex<Vec<(Vec<u8>, Vec<u8>)>>,
    rest: &'a Rest<'a>,
    start: &'a Start,
    name: &'a str,
}

impl<R: Read + Seek + Send> Job<'_, R> {
    /// Decodes the `n` chunks of the rest from chunk `first` on, whose bytes start at
    /// `offsets`, into the cloud; returns the records taken.
    fn window(
        &self,
        first: usize,
        n: usize,
        offsets: &[u64],
        points: &mut Points<'_>,
        b: &mut CloudBuilder,
    ) -> Result<u64, ReadError> {
        let (layout, guard) = (points.layout, points.guard);
        let chunk = self.start.chunk as usize;
        let total = n * chunk;
        room(b, points.written + total, layout.time.is_some());
        let origin = b.origin().unwrap_or_default();
        let out = Out::of(b.cloud_mut(), points.written, total);
        let pieces = split_out(out.xyz, out.scan, out.time, chunk)
            .into_par_iter()
            .zip(&self.rest.list[first..first + n])
            .zip(offsets)
            .enumerate()
            .map(|(k, ((out, e), &at))| {
                let i = first + k;
                let lock = || self.shelf.lock().unwrap_or_else(|p| p.into_inner());
                let (mut packed, mut raw) = lock().pop().unwrap_or_default();
                let decoded = self.decode(i, e, at, &mut packed, &mut raw);
                let piece = decoded.map(|short| {
                    let before = (i * chunk) as u64;
                    let take =
                        (chunk - short).min(self.rest.points.saturating_sub(before) as usize);
                    let recs = &raw[..take * layout.size];
                    (
                        decode_las_piece(layout, guard, recs, origin, out),
                        take as u64,
                    )
                });
                lock().push((packed, raw));
                piece
            })
            .collect::<Result<Vec<_>, ReadError>>()?;
        let taken = pieces.iter().map(|p| p.1).sum();
        let pieces: Vec<_> = pieces.into_iter().map(|p| p.0).collect();
        points.settle(settle_las_pieces(b, points.written, total, chunk, &pieces))?;
        Ok(taken)
    }

    /// Reads chunk `i` (table entry `e`, from byte `at`) into `packed` and decodes its records
    /// into `raw`; returns how many records it came short.
    fn decode(
        &self,
        i: usize,
        e: &ChunkTableEntry,
        at: u64,
        packed: &mut Vec<u8>,
        raw: &mut Vec<u8>,
    ) -> Result<usize, ReadError> {
        let io = |e: std::io::Error| ReadError::io(self.name, e);
        packed.resize(e.byte_count as usize, 0);
        {
            let mut s = self.source.lock().unwrap_or_else(|p| p.into_inner());
            s.seek(SeekFrom::Start(at)).map_err(io)?;
            s.read_exact(packed).map_err(io)?;
        }
        let size = self.size;
        raw.resize(self.start.chunk as usize * size, 0);
        let until_end = self.rest.last && i + 1 == self.rest.list.len();
        // The decoder asserts on some damaged chunks.
        catch_unwind(AssertUnwindSafe(|| {
            decode_chunk(packed, raw, &self.start.codec, until_end, size)
        }))
        .map_err(|_| not_here(self.name, "the decoder failed"))?
        .map_err(io)
    }
}

/// Decodes the chunks `packed` holds, described by `group`, in parallel into `raw`; the table's
/// `last` chunk is decoded until its bytes end, as the parallel reader decodes it. Returns the
/// points decoded (only the last chunk may come short).
fn decode_chunks(
    packed: &[u8],
    group: &[ChunkTableEntry],
    last: bool,
    codec: &Codec,
    size: usize,
    raw: &mut Vec<u8>,
) -> std::io::Result<u64> {
    let points: u64 = group.iter().map(|e| e.point_count).sum();
    raw.resize(points as usize * size, 0);
    let mut jobs = Vec::with_capacity(group.len());
    let (mut input, mut output) = (packed, raw.as_mut_slice());
    for (i, e) in group.iter().enumerate() {
        let (chunk, rest) = input.split_at(e.byte_count as usize);
        let (out, more) = std::mem::take(&mut output).split_at_mut(e.point_count as usize * size);
        jobs.push((chunk, out, last && i + 1 == group.len()));
        (input, output) = (rest, more);
    }
    let short = jobs
        .into_par_iter()
        .map(|(chunk, out, until_end)| decode_chunk(chunk, out, codec, until_end, size))
        .collect::<std::io::Result<Vec<usize>>>()?;
    Ok(points - short.iter().sum::<usize>() as u64)
}

/// Decodes one chunk's bytes into the records `out`; the table's last chunk (`until_end`) until
/// its bytes end, as the parallel reader decodes it. Returns how many records it came short.
fn decode_chunk(
    chunk: &[u8],
    out: &mut [u8],
    codec: &Codec,
    until_end: bool,
    size: usize,
) -> std::io::Result<usize> {
    let mut dec = codec.decoder(Cursor::new(chunk))?;
    if until_end {
        let n = dec.decompress_until_end_of_file(out)?;
        Ok((out.len() - n) / size)
    } else {
        dec.decompress_many(out).map(|_| 0)
    }
}

/// How this read decodes chunks: the file's items, and which of their fields it needs.
struct Codec {
    vlr: LazVlr,
    /// A layered chunk (LAS 1.4 formats) keeps each field in layers of its own, and the
    /// decoder skips the layers left out: the read needs only x, y, z, the scan (the point
    /// source id) and the time. Point-wise chunks decode every field whatever this says.
    fields: DecompressionSelection,
}

impl Codec {
    fn new(vlr: LazVlr, keep_time: bool) -> Codec {
        let fields = DecompressionSelection::base()
            .decompress_z()
            .decompress_point_source_id();
        Codec {
            vlr,
            fields: if keep_time {
                fields.decompress_gps_time()
            } else {
                fields
            },
        }
    }

    /// A record decompressor for one chunk, as the `laz` crate makes it for the items'
    /// version.
    fn decoder<'a, S>(
        &self,
        source: S,
    ) -> std::io::Result<Box<dyn RecordDecompressor<S> + Send + Sync + 'a>>
    where
        S: Read + Seek + Send + Sync + 'a,
    {
        let mut dec: Box<dyn RecordDecompressor<S> + Send + Sync + 'a> =
            match self.vlr.items().first().map(LazItem::version) {
                Some(1 | 2) => Box::new(SequentialPointRecordDecompressor::new(source)),
                _ => Box::new(LayeredPointRecordDecompressor::new(source)),
            };
        self.restart(&mut *dec)?;
        Ok(dec)
    }

    /// Readies `dec` for a new chunk. The selection is applied after the fields are set,
    /// since it goes to each field's decoder.
    fn restart<S>(
        &self,
        dec: &mut (dyn RecordDecompressor<S> + Send + Sync + '_),
    ) -> std::io::Result<()> {
        dec.reset();
        dec.set_fields_from(self.vlr.items())
            .map_err(std::io::Error::other)?;
        dec.set_selection(self.fields);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::cloud;
    use super::*;
    use std::sync::{Arc, Condvar, Mutex};

    /// A file arriving in pieces from another thread: reads wait for their bytes.
    struct Trickle {
        bytes: Arc<Vec<u8>>,
        arrived: Arc<(Mutex<usize>, Condvar)>,
        position: u64,
    }

    impl Read for Trickle {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let len = self.bytes.len();
            let at = self.position as usize;
            if buf.is_empty() || at >= len {
                return Ok(0);
            }
            let (lock, more) = &*self.arrived;
            let guard = lock.lock().unwrap();
            let arrived = *more.wait_while(guard, |n| *n <= at).unwrap();
            let n = (arrived - at).min(buf.len());
            buf[..n].copy_from_slice(&self.bytes[at..at + n]);
            self.position += n as u64;
            Ok(n)
        }
    }

    impl Seek for Trickle {
        fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
            self.position = match pos {
                SeekFrom::Start(p) => p,
                SeekFrom::End(d) => (self.bytes.len() as u64).saturating_add_signed(d),
                SeekFrom::Current(d) => self.position.saturating_add_signed(d),
            };
            Ok(self.position)
        }
    }

    impl Arriving for Trickle {
        fn arrived(&self) -> bool {
            *self.arrived.0.lock().unwrap() >= self.bytes.len()
        }

        fn available(&self) -> u64 {
            *self.arrived.0.lock().unwrap() as u64
        }

        fn another(&self) -> std::io::Result<Self> {
            Ok(Trickle {
                bytes: self.bytes.clone(),
                arrived: self.arrived.clone(),
                position: 0,
            })
        }
    }

    /// How the bytes come: all at once, in small pieces, or half first and the rest later.
    #[derive(Clone, Copy, Debug)]
    enum Pace {
        AtOnce,
        Slow,
        HalfThenRest,
    }

    /// Reads `bytes` while another thread hands them over at `pace`, in pieces of random sizes.
    fn read_arriving(
        bytes: &[u8],
        pace: Pace,
        seed: u64,
    ) -> Result<(PointCloud, Early), ReadError> {
        let bytes = Arc::new(bytes.to_vec());
        let arrived = Arc::new((Mutex::new(0usize), Condvar::new()));
        let len = bytes.len();
        let feeder = {
            let arrived = arrived.clone();
            std::thread::spawn(move || {
                let give = |n: usize| {
                    let (lock, more) = &*arrived;
                    *lock.lock().unwrap() = n;
                    more.notify_all();
                };
                let mut state = seed | 1;
                let mut random = |max: u64| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    1 + (state % max) as usize
                };
                match pace {
                    Pace::AtOnce => give(len),
                    Pace::Slow => {
                        let mut n = 0;
                        while n < len {
                            n = (n + random(8_192)).min(len);
                            give(n);
                            std::thread::sleep(std::time::Duration::from_millis(1));
                        }
                    }
                    Pace::HalfThenRest => {
                        let mut n = 0;
                        while n < len / 2 {
                            n = (n + random(65_536)).min(len / 2);
                            give(n);
                        }
                        std::thread::sleep(std::time::Duration::from_millis(300));
                        give(len);
                    }
                }
            })
        };
        if matches!(pace, Pace::AtOnce) {
            // Wait until it all came, so nothing is decoded front to back.
            feeder.join().unwrap();
        }
        let source = Trickle {
            bytes,
            arrived,
            position: 0,
        };
        let read = read_counted(source, len as u64, "t.laz", &ReadOptions::default());
        read.and_then(|(cloud, early)| {
            let cloud = crate::io::finish(cloud, "t.laz", &ReadOptions::default())?;
            Ok((cloud, early))
        })
    }

    /// The whole file's cloud, as the worker's read of the stored upload gives it.
    fn whole(bytes: &[u8]) -> Result<PointCloud, ReadError> {
        crate::io::read_cloud_from(
            Cursor::new(bytes.to_vec()),
            "t.laz",
            &ReadOptions::default(),
        )
    }

    /// LAZ of point format 1 (point-wise chunks, 50 000 points each) as the exporter writes it.
    fn laz_bytes(n: usize) -> Vec<u8> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.laz");
        crate::io::export::write_las(&path, &cloud(n), true).unwrap();
        std::fs::read(&path).unwrap()
    }

    /// LAZ of point format 6 (layered chunks), LAS 1.4. Every field has values, as a
    /// scanner's have, so the layers the read skips are not empty.
    fn layered_bytes(n: usize) -> Vec<u8> {
        let c = cloud(n);
        let mut builder = las::Builder::from((1, 4));
        builder.point_format = las::point::Format::new(6).unwrap();
        builder.point_format.is_compressed = true;
        let t = |offset: f64| las::Transform {
            scale: 0.001,
            offset,
        };
        builder.transforms = las::Vector {
            x: t(c.origin[0]),
            y: t(c.origin[1]),
            z: t(c.origin[2]),
        };
        let header = builder.into_header().unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.laz");
        {
            let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
            let mut writer = las::Writer::new(file, header).unwrap();
            for (i, p) in c.xyz.iter().enumerate() {
                writer
                    .write_point(las::Point {
                        x: c.origin[0] + f64::from(p[0]),
                        y: c.origin[1] + f64::from(p[1]),
                        z: c.origin[2] + f64::from(p[2]),
                        point_source_id: c.scan_ids[usize::from(c.scan[i])] as u16,
                        gps_time: Some(c.time[i]),
                        return_number: 1,
                        number_of_returns: 1,
                        intensity: (i * 7919 % 65_521) as u16,
                        classification: las::point::Classification::new(
                            [1, 2, 3, 4, 5, 6, 7, 9, 17, 18][i % 10],
                        )
                        .unwrap(),
                        is_synthetic: i % 3 == 0,
                        scan_angle: (i % 180) as f32 - 90.0,
                        user_data: (i % 251) as u8,
                        ..Default::default()
                    })
                    .unwrap();
            }
            writer.close().unwrap();
        }
        std::fs::read(&path).unwrap()
    }

    /// Two reads gave the same cloud, bit for bit.
    fn assert_same(a: &PointCloud, b: &PointCloud) {
        let bits = |c: &PointCloud| -> Vec<[u32; 3]> {
            c.xyz.iter().map(|p| p.map(f32::to_bits)).collect()
        };
        assert!(bits(a) == bits(b), "points differ");
        assert_eq!(a.scan, b.scan);
        assert_eq!(a.scan_ids, b.scan_ids);
        assert_eq!(a.time.len(), b.time.len());
        assert!(a
            .time
            .iter()
            .zip(&b.time)
            .all(|(x, y)| x.to_bits() == y.to_bits()));
        assert_eq!(a.origin, b.origin);
        assert_eq!(a.source, b.source);
        assert_eq!(a.crs, b.crs);
    }

    #[test]
    fn laz_read_as_it_arrives_is_the_whole_files_cloud() {
        // Seven chunks, the last of 7 points; five whole chunks; layered chunks.
        let files = [
            ("format 1", laz_bytes(300_007), 7),
            ("whole chunks", laz_bytes(250_000), 5),
            ("format 6", layered_bytes(160_001), 4),
        ];
        for (what, bytes, chunks) in files {
            let stored = whole(&bytes).unwrap();
            assert!(stored.source.details.contains("point format"), "{what}");
            for (k, pace) in [Pace::AtOnce, Pace::Slow, Pace::HalfThenRest]
                .into_iter()
                .enumerate()
            {
                let (early, front) = read_arriving(&bytes, pace, 7 + k as u64)
                    .unwrap_or_else(|e| panic!("{what}, {pace:?}: {e}"));
                assert_same(&early, &stored);
                // Never the last chunk the points need: the table says how it ends.
                assert!(front.chunks < chunks, "{what}, {pace:?}");
                match pace {
                    Pace::AtOnce => assert_eq!(front.chunks, 0, "{what}"),
                    Pace::Slow | Pace::HalfThenRest => {
                        assert!(front.chunks > 0, "{what}, {pace:?}")
                    }
                }
            }
        }
    }

    #[test]
    fn a_damaged_laz_read_as_it_arrives_fails_or_gives_the_whole_files_cloud() {
        let bytes = laz_bytes(300_007);
        let len = bytes.len();
        let data = u32::from_le_bytes(bytes[96..100].try_into().unwrap()) as usize;
        let table = u64::from_le_bytes(bytes[data..data + 8].try_into().unwrap()) as usize;
        assert!(table > len / 2 && table < len, "the chunk table's offset");
        let mut cases: Vec<(&str, Vec<u8>)> = vec![
            ("cut in the points", bytes[..len / 2].to_vec()),
            ("cut in the table", bytes[..len - 3].to_vec()),
        ];
        for at in [table + 8, table + 9, len - 2] {
            let mut damaged = bytes.clone();
            damaged[at] ^= 0x5a;
            cases.push(("a damaged chunk table", damaged));
        }
        for at in [data + 18, len / 3, table - 5] {
            let mut damaged = bytes.clone();
            damaged[at] ^= 0xff;
            cases.push(("a damaged chunk", damaged));
        }
        let mut offset = bytes.clone();
        offset[data..data + 8].copy_from_slice(&0i64.to_le_bytes());
        cases.push(("no table offset", offset));
        for (what, bytes) in &cases {
            for pace in [Pace::AtOnce, Pace::Slow] {
                let early = read_arriving(bytes, pace, 3);
                match (early, whole(bytes)) {
                    (Ok((early, _)), Ok(stored)) => assert_same(&early, &stored),
                    (Ok(_), Err(e)) => {
                        panic!("{what}, {pace:?}: read early, but the file fails: {e}")
                    }
                    (Err(_), _) => {}
                }
            }
        }
        // A cut file fails early, as it fails whole.
        for (what, bytes) in &cases[..2] {
            assert!(whole(bytes).is_err(), "{what}");
            assert!(read_arriving(bytes, Pace::Slow, 5).is_err(), "{what}");
        }
        // Damage where a second lane reads: in layered chunks' declared sizes and layers, and
        // in point-wise chunks, past the half that arrives at once.
        for bytes in [layered_bytes(1_000_003), laz_bytes(1_000_003)] {
            let len = bytes.len();
            for at in [
                len * 6 / 10,
                len * 7 / 10 + 3,
                len * 8 / 10 + 7,
                len * 9 / 10,
            ] {
                let mut damaged = bytes.clone();
                damaged[at] ^= 0xff;
                match (
                    read_arriving(&damaged, Pace::HalfThenRest, 9),
                    whole(&damaged),
                ) {
                    (Ok((early, _)), Ok(stored)) => assert_same(&early, &stored),
                    (Ok(_), Err(e)) => panic!("byte {at}: read early, but the file fails: {e}"),
                    (Err(_), _) => {}
                }
            }
        }
    }

    #[test]
    fn layered_chunks_decode_the_fields_the_cloud_keeps_as_the_las_crate_does() {
        // The straight read skips the layers of intensity, classification, flags, scan angle
        // and user data, and of the time when it is not kept; what it keeps is the `las`
        // crate's serial read, which decodes every layer.
        for serial in super::super::tests::straight_reads_match_serial(&layered_bytes(160_001)) {
            assert_eq!(serial.len(), 160_001);
        }
    }

    #[test]
    fn a_second_lane_decodes_ahead_and_changes_nothing() {
        // 21 chunks, the last of 3 points; half arrive at once, so a second lane has work. It
        // finds a point-wise chunk's start by its first record, a layered one's by hopping.
        for (what, bytes) in [
            ("format 1", laz_bytes(1_000_003)),
            ("format 6", layered_bytes(1_000_003)),
        ] {
            let stored = whole(&bytes).unwrap();
            let (early, front) = read_arriving(&bytes, Pace::HalfThenRest, 11).unwrap();
            assert_same(&early, &stored);
            assert!(front.ahead > 0 && front.chunks < 21, "{what}: {front:?}");
        }
    }

    #[test]
    fn chunk_starts_are_found_where_the_chunk_table_puts_them() {
        let bytes = laz_bytes(300_007);
        let start =
            Start::read(&mut Cursor::new(&bytes), bytes.len() as u64, "t.laz", false).unwrap();
        let mut source = Cursor::new(&bytes);
        source.seek(SeekFrom::Start(start.data)).unwrap();
        let table = ChunkTable::read_from(&mut source, &start.codec.vlr).unwrap();
        let (layout, guard) = (
            Layout::new(&start.header, false),
            BoundsGuard::new(&start.header),
        );
        let mut at = start.data + 8;
        let starts: Vec<u64> = table
            .as_ref()
            .iter()
            .map(|e| {
                at += e.byte_count;
                at - e.byte_count
            })
            .collect();
        assert_eq!(starts.len(), 7);
        // The last chunk, of 7 points, is too short to probe; the second lane never needs it.
        for w in starts[..6].windows(2) {
            // From just past a chunk's start, and from its middle: the next chunk's start, and
            // none of the bytes between, however many of them look like a point.
            for from in [w[0] + 1, (w[0] + w[1]) / 2] {
                let last = (w[1] - from) as usize + 1;
                let found =
                    chunk_start_after(&bytes[from as usize..], last, &start.codec, &layout, &guard);
                assert_eq!(found.map(|k| from + k as u64), Some(w[1]), "from {from}");
            }
        }
        // The first chunk's own start is found from there.
        let first = &bytes[starts[0] as usize..];
        assert_eq!(
            chunk_start_after(first, 1, &start.codec, &layout, &guard),
            Some(0)
        );
    }
}
