//! PLY: ASCII and binary (both endiannesses), streamed, with optional `scan_index` and `time`.
//!
//! The reader never parses the whole file at once: it reads the header, skips the elements before
//! `vertex` (lists included), then decodes vertices in chunks from a `BufReader` straight into the
//! cloud's compact arrays. The header's counts are checked against the file's size before anything
//! is allocated, so a header claiming billions of vertices is an error, not an allocation.
//! Points with a non-finite coordinate are skipped and counted in `SourceInfo::skipped`.

mod chunks;
mod header;
mod write;

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use rayon::prelude::*;

use super::pages::Mapped;
use super::ReadError;
use crate::cloud::{local_origin, to_local, PointCloud, SourceInfo};
use crate::io::assemble::{decode_pieces, settle, LocalSlots, Out};
use header::{describe, read_header, vertices, Element, Header, Kind, Layout, Scalar};

pub use chunks::PlyChunks;
pub use header::Encoding;
pub use write::{write_ply, write_ply_to, WriteError};

/// Vertices decoded per chunk on the binary path.
const CHUNK_VERTICES: usize = 1 << 16;
/// Binary vertices are read in blocks of this many chunks per thread, each block decoded in
/// as many parts as threads.
const CHUNKS_PER_THREAD: usize = 4;
/// ASCII vertices are read in blocks of about this many bytes per vertex of a binary block.
const ASCII_BYTES_PER_VERTEX: usize = 32;
/// Never reserve room for more points than this up front. Counts below it are reserved exactly
/// (after the file's size has confirmed them), so the arrays never grow by doubling.
const MAX_RESERVE: usize = 1 << 30;
/// Property names that give a point's scan index, in order of preference.
pub(super) const SCAN_NAMES: [&str; 3] = ["scan_index", "scan", "point_source_id"];

const FORMAT: &str = "ply";

/// Reads a PLY file, with its points' times when it has them.
pub fn read_ply(path: &Path) -> Result<PointCloud, ReadError> {
    let file = File::open(path).map_err(|e| io_error(path, e))?;
    let file_len = file.metadata().map_err(|e| io_error(path, e))?.len();
    read_ply_from(file, file_len, &path.display().to_string(), true)
}

/// The vertex count the header declares, or `None` when the header does not parse.
pub(crate) fn declared_vertices(mut reader: impl BufRead) -> Option<u64> {
    let header = read_header(&mut reader, Path::new("cloud")).ok()?;
    header
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .map(|e| e.count)
}

/// Reads PLY from any source of `len` bytes (a file, an upload in memory); `name` is used in
/// errors. The source is read once, front to back, through a buffer. A `time` property is
/// read only with `keep_time` (8 bytes a point).
pub fn read_ply_from<R: Read + Send>(
    source: R,
    len: u64,
    name: &str,
    keep_time: bool,
) -> Result<PointCloud, ReadError> {
    read_ply_split(source, len, name, Split::parallel(), None, keep_time)
}

/// [`read_ply_from`] of a file also mapped as `map`: fixed-size binary vertices are decoded
/// straight from the map, everything else is read from `source`.
pub(crate) fn read_ply_mapped<R: Read + Send>(
    source: R,
    map: &Mapped,
    name: &str,
    keep_time: bool,
) -> Result<PointCloud, ReadError> {
    read_ply_split(
        source,
        map.len(),
        name,
        Split::parallel(),
        Some(map),
        keep_time,
    )
}

/// How binary vertices are read: `block` records at a time, each block decoded in `parts`;
/// with `direct`, straight into the cloud's arrays, the next block read meanwhile.
#[derive(Debug, Clone, Copy)]
struct Split {
    block: usize,
    parts: usize,
    direct: bool,
}

impl Split {
    /// Blocks of a few chunks per thread, each decoded in a part per thread.
    fn parallel() -> Split {
        let parts = super::pool::threads();
        Split {
            block: CHUNK_VERTICES * CHUNKS_PER_THREAD * parts,
            parts,
            direct: true,
        }
    }

    /// A chunk at a time, on the calling thread, through the point sink.
    const SERIAL: Split = Split {
        block: CHUNK_VERTICES,
        parts: 1,
        direct: false,
    };
}

fn read_ply_split<R: Read + Send>(
    source: R,
    len: u64,
    name: &str,
    split: Split,
    map: Option<&Mapped>,
    keep_time: bool,
) -> Result<PointCloud, ReadError> {
    let path = Path::new(name);
    let file_len = len;
    let mut reader = BufReader::with_capacity(1 << 20, source);
    let header = read_header(&mut reader, path)?;
    let (vertex_pos, vertex, layout) = vertices(&header, file_len, path, keep_time)?;

    let mut sink = Sink::new(vertex.count, layout);
    let mut body = Body {
        path,
        header: &header,
        reader: &mut reader,
        offset: header.len,
        line: header.lines,
        text: String::new(),
        split,
        map,
    };
    for element in &header.elements[..vertex_pos] {
        body.skip_element(element)?;
    }
    body.read_vertices(vertex, layout, &mut sink)?;
    Ok(sink.finish(describe(&header, vertex)))
}

/// A scan index read as a number, as a scan id; an error unless a whole number in range.
#[inline]
fn scan_id(s: f64) -> Result<u32, String> {
    // In range, a whole number is one its integer cast gives back (cheaper than `fract`).
    if !(s >= 0.0 && s <= f64::from(u32::MAX) && f64::from(s as u32) == s) {
        return Err(format!(
            "scan index {s} is not a whole number from 0 to {}",
            u32::MAX
        ));
    }
    Ok(s as u32)
}

/// Accumulates decoded vertices into the cloud's compact arrays.
struct Sink {
    cloud: PointCloud,
    origin: Option<[f64; 3]>,
    slots: HashMap<u32, u16>,
    last: Option<(u32, u16)>,
    skipped: u64,
}

impl Sink {
    /// `count` must already be checked against the file's size.
    fn new(count: u64, layout: Layout) -> Sink {
        let reserve = (count as usize).min(MAX_RESERVE);
        let maybe = |wanted: bool| if wanted { reserve } else { 0 };
        Sink {
            cloud: PointCloud {
                xyz: Vec::with_capacity(reserve),
                scan: Vec::with_capacity(maybe(layout.scan.is_some())),
                time: Vec::with_capacity(maybe(layout.time.is_some())),
                ..Default::default()
            },
            origin: None,
            slots: HashMap::new(),
            last: None,
            skipped: 0,
        }
    }

    /// Adds one vertex; `scan` and `time` are present when the layout has them.
    /// Returns an error message for a scan index that is not a whole number.
    fn push(&mut self, p: [f64; 3], scan: Option<f64>, time: Option<f64>) -> Result<(), String> {
        if !p.iter().all(|c| c.is_finite()) || time.is_some_and(|t| !t.is_finite()) {
            self.skipped += 1;
            return Ok(());
        }
        let origin = *self.origin.get_or_insert_with(|| local_origin(Some(p)));
        if let Some(s) = scan {
            let slot = self.slot(s)?;
            self.cloud.scan.push(slot);
        }
        if let Some(t) = time {
            self.cloud.time.push(t);
        }
        self.cloud.xyz.push(to_local(origin, p));
        Ok(())
    }

    fn slot(&mut self, s: f64) -> Result<u16, String> {
        self.slot_of_id(scan_id(s)?)
    }

    /// The slot of scan index `id`, assigned in order of first appearance.
    #[inline]
    fn slot_of_id(&mut self, id: u32) -> Result<u16, String> {
        if let Some((last_id, slot)) = self.last {
            if last_id == id {
                return Ok(slot);
            }
        }
        let next = self.cloud.scan_ids.len();
        let slot = match self.slots.get(&id) {
            Some(&slot) => slot,
            None => {
                if next > u16::MAX as usize {
                    return Err(format!("more than {} distinct scan indices", next));
                }
                self.cloud.scan_ids.push(id);
                self.slots.insert(id, next as u16);
                next as u16
            }
        };
        self.last = Some((id, slot));
        Ok(slot)
    }

    /// [`Self::push`] for a batch of records of the commonest layout: little-endian `float`
    /// x, y, z at `xyz` offsets and, when `scan` is given, a `uint` scan index there; no time.
    /// Decoding straight into the arrays is several times faster than going through `f64`
    /// values one by one. On error, returns the record's index in `buf` and why.
    fn push_f32_records(
        &mut self,
        buf: &[u8],
        size: usize,
        xyz: [usize; 3],
        scan: Option<usize>,
    ) -> Result<(), (usize, String)> {
        let f =
            |rec: &[u8], o: usize| f32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]);
        for (i, rec) in buf.chunks_exact(size).enumerate() {
            let (x, y, z) = (f(rec, xyz[0]), f(rec, xyz[1]), f(rec, xyz[2]));
            if !(x.is_finite() && y.is_finite() && z.is_finite()) {
                self.skipped += 1;
                continue;
            }
            let p = [f64::from(x), f64::from(y), f64::from(z)];
            let origin = *self.origin.get_or_insert_with(|| local_origin(Some(p)));
            if let Some(o) = scan {
                let id = u32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]);
                let slot = self.slot_of_id(id).map_err(|why| (i, why))?;
                self.cloud.scan.push(slot);
            }
            self.cloud.xyz.push(to_local(origin, p));
        }
        Ok(())
    }

    /// Appends a part decoded on its own (same origin, its own scan slots) as if its records
    /// had been pushed here. False, with the points not added, when its scans do not fit.
    fn absorb(&mut self, part: &Sink) -> bool {
        let mut slots = Vec::with_capacity(part.cloud.scan_ids.len());
        for &id in &part.cloud.scan_ids {
            match self.slot_of_id(id) {
                Ok(slot) => slots.push(slot),
                Err(_) => return false,
            }
        }
        let c = &mut self.cloud;
        c.xyz.extend_from_slice(&part.cloud.xyz);
        c.scan
            .extend(part.cloud.scan.iter().map(|&s| slots[usize::from(s)]));
        c.time.extend_from_slice(&part.cloud.time);
        self.skipped += part.skipped;
        true
    }

    /// Forgets the scans first named after the first `known`.
    fn forget_scans(&mut self, known: usize) {
        for id in self.cloud.scan_ids.drain(known..) {
            self.slots.remove(&id);
        }
        self.last = None;
    }

    fn finish(mut self, details: String) -> PointCloud {
        self.cloud.origin = self.origin.unwrap_or_default();
        // Only worth a reallocation when many points were skipped.
        if self.cloud.xyz.capacity() > self.cloud.xyz.len() + self.cloud.xyz.len() / 8 {
            self.cloud.xyz.shrink_to_fit();
            self.cloud.scan.shrink_to_fit();
            self.cloud.time.shrink_to_fit();
        }
        self.cloud.source = SourceInfo {
            format: FORMAT.into(),
            details,
            skipped: self.skipped,
            skipped_reason: (self.skipped > 0)
                .then(|| "non-finite coordinate or time (NaN or infinite)".to_string()),
            units: String::new(),
        };
        self.cloud
    }
}

/// The body reader: the stream, and where it is for error messages.
struct Body<'a, R: BufRead> {
    path: &'a Path,
    header: &'a Header,
    reader: &'a mut R,
    offset: u64,
    line: u64,
    text: String,
    split: Split,
    /// The whole file, when it is mapped: fixed-size vertices are then decoded from here.
    map: Option<&'a Mapped>,
}

impl<R: BufRead + Send> Body<'_, R> {
    fn big(&self) -> bool {
        self.header.encoding == Encoding::BinaryBigEndian
    }

    fn fill(&mut self, buf: &mut [u8], what: &str) -> Result<(), ReadError> {
        self.reader
            .read_exact(buf)
            .map_err(|e| fill_error(self.path, e, what, self.offset))?;
        self.offset += buf.len() as u64;
        Ok(())
    }

    /// The next ASCII line, or a truncation error naming `what` was expected.
    fn next_line(&mut self, what: &dyn Fn() -> String) -> Result<(), ReadError> {
        self.text.clear();
        let n = self.reader.read_line(&mut self.text).map_err(|e| {
            invalid(
                self.path,
                e.to_string(),
                Some(format!("line {}", self.line + 1)),
            )
        })?;
        self.line += 1;
        self.offset += n as u64;
        if n == 0 {
            return Err(invalid(
                self.path,
                format!("the file is truncated: it ends before {}", what()),
                Some(format!("line {}", self.line)),
            ));
        }
        Ok(())
    }

    fn skip_element(&mut self, element: &Element) -> Result<(), ReadError> {
        match (self.header.encoding, element.fixed_size()) {
            (Encoding::Ascii, _) => {
                for k in 0..element.count {
                    self.next_line(&|| format!("{} {k} of {}", element.name, element.count))?;
                }
                Ok(())
            }
            (_, Some(size)) => {
                let bytes = size as u64 * element.count;
                let copied = std::io::copy(&mut self.reader.take(bytes), &mut std::io::sink())
                    .map_err(|e| invalid(self.path, e.to_string(), None))?;
                if copied < bytes {
                    return Err(invalid(
                        self.path,
                        format!(
                            "the file is truncated: it ends inside element `{}`",
                            element.name
                        ),
                        Some(format!("byte offset {}", self.offset + copied)),
                    ));
                }
                self.offset += bytes;
                Ok(())
            }
            (_, None) => {
                let mut scratch = Vec::new();
                for _ in 0..element.count {
                    self.read_record(element, &mut scratch, &mut Vec::new())?;
                }
                Ok(())
            }
        }
    }

    /// Reads one binary record with lists, leaving each property's first value in `values`.
    fn read_record(
        &mut self,
        element: &Element,
        scratch: &mut Vec<u8>,
        values: &mut Vec<f64>,
    ) -> Result<(), ReadError> {
        let big = self.big();
        values.clear();
        let what = format!("element `{}`", element.name);
        for p in &element.properties {
            match p.kind {
                Kind::Scalar(s) => {
                    let mut b = [0u8; 8];
                    self.fill(&mut b[..s.size()], &what)?;
                    values.push(s.decode(&b, big));
                }
                Kind::List { count, item } => {
                    let mut b = [0u8; 8];
                    self.fill(&mut b[..count.size()], &what)?;
                    let n = count.decode(&b, big);
                    if !(n >= 0.0 && n.fract() == 0.0 && n <= u32::MAX as f64) {
                        return Err(invalid(
                            self.path,
                            format!("list property `{}` has an invalid length {n}", p.name),
                            Some(format!("byte offset {}", self.offset)),
                        ));
                    }
                    // Skip the items in bounded steps so a huge length cannot allocate.
                    let mut left = n as u64 * item.size() as u64;
                    while left > 0 {
                        let step = left.min(1 << 16) as usize;
                        scratch.resize(step, 0);
                        let mut buf = std::mem::take(scratch);
                        self.fill(&mut buf, &what)?;
                        *scratch = buf;
                        left -= step as u64;
                    }
                    values.push(f64::NAN);
                }
            }
        }
        Ok(())
    }

    fn read_vertices(
        &mut self,
        vertex: &Element,
        layout: Layout,
        sink: &mut Sink,
    ) -> Result<(), ReadError> {
        match (self.header.encoding, vertex.fixed_size()) {
            (Encoding::Ascii, _) if self.split.parts > 1 => {
                self.read_ascii_split(vertex, layout, sink)
            }
            (Encoding::Ascii, _) => self.read_ascii_vertices(vertex, layout, sink, 0, vertex.count),
            (_, Some(size)) => self.read_fixed_vertices(vertex, size, layout, sink),
            (_, None) => {
                let mut scratch = Vec::new();
                let mut values = Vec::with_capacity(vertex.properties.len());
                for k in 0..vertex.count {
                    let start = self.offset;
                    self.read_record(vertex, &mut scratch, &mut values)?;
                    self.push(sink, &values, layout, k, start)?;
                }
                Ok(())
            }
        }
    }

    /// The fast path: fixed-size binary records read a block at a time, each block decoded
    /// in parallel parts.
    fn read_fixed_vertices(
        &mut self,
        vertex: &Element,
        size: usize,
        layout: Layout,
        sink: &mut Sink,
    ) -> Result<(), ReadError> {
        let records = Records::new(vertex, size, layout, self.big());
        if self.split.direct && sink.cloud.xyz.is_empty() && vertex.count <= MAX_RESERVE as u64 {
            return self.read_fixed_direct(vertex, &records, sink);
        }
        let block = self.split.block.max(1);
        let mut buf = vec![0u8; size * block.min(vertex.count as usize).max(1)];
        let mut done = 0u64;
        while done < vertex.count {
            let n = ((vertex.count - done) as usize).min(block);
            let start = self.offset;
            self.fill(&mut buf[..n * size], "the vertex data")
                .map_err(|e| truncated_vertices(e, done, vertex.count, block))?;
            records
                .decode_parts(sink, &buf[..n * size], self.split.parts)
                .map_err(|(i, why)| {
                    invalid(
                        self.path,
                        format!("vertex {}: {why}", done + i as u64),
                        Some(format!("byte offset {}", start + (i * size) as u64)),
                    )
                })?;
            done += n as u64;
        }
        Ok(())
    }

    /// The fixed-size records decoded in parallel pieces straight into the cloud's arrays,
    /// sized to the header's count (checked against the file's size) and zeroed lazily, so
    /// pages are first touched by the thread that fills them. A mapped file's blocks are
    /// decoded from the map; a stream's next block is read while this one is decoded.
    fn read_fixed_direct(
        &mut self,
        vertex: &Element,
        records: &Records,
        sink: &mut Sink,
    ) -> Result<(), ReadError> {
        let count = vertex.count as usize;
        let size = records.size;
        let block = self.split.block.max(1);
        let parts = self.split.parts.max(1);
        let c = &mut sink.cloud;
        c.xyz = vec![[0.0; 3]; count];
        c.scan = vec![0; if records.scan.is_some() { count } else { 0 }];
        c.time = vec![0.0; if records.time.is_some() { count } else { 0 }];
        let (path, base) = (self.path, self.offset);
        let mut written = 0;
        let blocks = count.div_ceil(block);
        let len = |k: usize| (count - k * block).min(block) * size;
        let use_block = |k: usize, buf: &[u8], filled: std::io::Result<()>| {
            let done = (k * block) as u64;
            let start = base + done * size as u64;
            filled.map_err(|e| {
                let e = fill_error(path, e, "the vertex data", start);
                truncated_vertices(e, done, vertex.count, block)
            })?;
            records
                .decode_direct(sink, &mut written, buf, parts)
                .map_err(|(i, why)| {
                    invalid(
                        path,
                        format!("vertex {}: {why}", done + i as u64),
                        Some(format!("byte offset {}", start + (i * size) as u64)),
                    )
                })
        };
        match self.map {
            Some(map) => map.blocks(base, blocks, len, use_block)?,
            None => crate::io::pool::read_ahead(
                &mut *self.reader,
                blocks,
                parts > 1,
                |reader, k, buf| {
                    buf.resize(len(k), 0);
                    reader.read_exact(buf)
                },
                use_block,
            )?,
        }
        self.offset = base + (count * size) as u64;
        let c = &mut sink.cloud;
        c.xyz.truncate(written);
        c.scan.truncate(written);
        c.time.truncate(written);
        Ok(())
    }

    /// ASCII vertices `first..first + n` of `vertex`, one a line.
    fn read_ascii_vertices(
        &mut self,
        vertex: &Element,
        layout: Layout,
        sink: &mut Sink,
        first: u64,
        n: u64,
    ) -> Result<(), ReadError> {
        let mut values = Vec::with_capacity(vertex.properties.len());
        for k in first..first + n {
            self.next_line(&|| format!("vertex {k} of {}", vertex.count))?;
            values.clear();
            let mut tokens = self.text.split_ascii_whitespace();
            for p in &vertex.properties {
                // `what` names the value only when there is an error: no formatting per value.
                let mut next = |what: &dyn Fn() -> String| -> Result<f64, ReadError> {
                    let token = tokens.next().ok_or_else(|| {
                        invalid(
                            self.path,
                            format!("vertex {k}: the line ends before {}", what()),
                            Some(format!("line {}", self.line)),
                        )
                    })?;
                    parse_number(token).ok_or_else(|| {
                        invalid(
                            self.path,
                            format!("vertex {k}: {} is not a number: {token:?}", what()),
                            Some(format!("line {}", self.line)),
                        )
                    })
                };
                match p.kind {
                    Kind::Scalar(_) => values.push(next(&|| format!("property `{}`", p.name))?),
                    Kind::List { .. } => {
                        let n = next(&|| format!("the length of list `{}`", p.name))?;
                        if !(n >= 0.0 && n.fract() == 0.0 && n <= 1.0e6) {
                            return Err(invalid(
                                self.path,
                                format!("vertex {k}: list `{}` has an invalid length {n}", p.name),
                                Some(format!("line {}", self.line)),
                            ));
                        }
                        for _ in 0..n as usize {
                            next(&|| format!("an item of list `{}`", p.name))?;
                        }
                        values.push(f64::NAN);
                    }
                }
            }
            let line = self.line;
            let get = |i: usize| values[i];
            sink.push(
                layout.xyz.map(get),
                layout.scan.map(get),
                layout.time.map(get),
            )
            .map_err(|why| {
                invalid(
                    self.path,
                    format!("vertex {k}: {why}"),
                    Some(format!("line {line}")),
                )
            })?;
        }
        Ok(())
    }

    /// ASCII vertices read a block of whole lines at a time, each block parsed in parallel
    /// pieces; exactly the serial read's points and errors. A piece is parsed ahead only as
    /// far as its lines parse cleanly; the rest of it, and a piece whose scans would not fit,
    /// is read by the serial code.
    fn read_ascii_split(
        &mut self,
        vertex: &Element,
        layout: Layout,
        sink: &mut Sink,
    ) -> Result<(), ReadError> {
        let block = self
            .split
            .block
            .max(1)
            .saturating_mul(ASCII_BYTES_PER_VERTEX);
        let parts = self.split.parts.max(1);
        let mut done = 0u64;
        let mut text = Vec::new();
        while done < vertex.count {
            let want = vertex.count - done;
            let (lines, ended) = self.take_lines(&mut text, want, block);
            let partial = !text.is_empty() && !text.ends_with(b"\n");
            if partial && !ended {
                // A read failed inside a line: whole lines only; the serial read meets the error.
                let whole = text.iter().rposition(|&c| c == b'\n').map_or(0, |i| i + 1);
                text.truncate(whole);
            }
            // At the end, a last line without its newline is a line too, as `read_line` reads it.
            let mut n = lines + u64::from(partial && ended);
            if n == 0 {
                // The input ended or failed here: the serial read says how.
                return self.read_ascii_vertices(vertex, layout, sink, done, want);
            }
            let mut rest: &[u8] = &text;
            // The first kept point fixes the local frame every piece needs.
            while sink.origin.is_none() && n > 0 {
                self.ascii_serial(&mut rest, vertex, layout, sink, done, 1)?;
                done += 1;
                n -= 1;
            }
            let pieces = crate::io::xyz::cut_lines(rest, parts);
            let origin = sink.origin;
            let parsed: Vec<(Sink, u64, usize)> = pieces
                .par_iter()
                .map(|piece| ascii_piece(piece, vertex, layout, origin))
                .collect();
            for (piece, (part, taken, bytes)) in pieces.iter().zip(parsed) {
                let lines = piece.iter().filter(|&&c| c == b'\n').count() as u64
                    + u64::from(!piece.ends_with(b"\n"));
                let (mut tail, mut left) = (*piece, lines);
                if sink.absorb(&part) {
                    self.line += taken;
                    self.offset += bytes as u64;
                    done += taken;
                    tail = &piece[bytes..];
                    left -= taken;
                }
                self.ascii_serial(&mut tail, vertex, layout, sink, done, left)?;
                done += left;
            }
        }
        Ok(())
    }

    /// Moves whole lines into `text` (cleared first): at most `want`, and about `block` bytes
    /// unless a line is longer. Returns the newlines taken, and whether the input ended; a
    /// read error stops early, for the serial read to meet.
    fn take_lines(&mut self, text: &mut Vec<u8>, want: u64, block: usize) -> (u64, bool) {
        text.clear();
        let mut lines = 0u64;
        while lines < want && (text.len() < block || !text.ends_with(b"\n")) {
            let Ok(avail) = self.reader.fill_buf() else {
                break;
            };
            if avail.is_empty() {
                return (lines, true);
            }
            let mut take = avail.len();
            for (i, &c) in avail.iter().enumerate() {
                if c == b'\n' {
                    lines += 1;
                    if lines == want || (text.len() + i >= block) {
                        take = i + 1;
                        break;
                    }
                }
            }
            text.extend_from_slice(&avail[..take]);
            self.reader.consume(take);
        }
        (lines, false)
    }

    /// The serial read of vertices `first..first + n` from `text`, keeping this reader's place.
    fn ascii_serial(
        &mut self,
        text: &mut &[u8],
        vertex: &Element,
        layout: Layout,
        sink: &mut Sink,
        first: u64,
        n: u64,
    ) -> Result<(), ReadError> {
        let mut body = Body {
            path: self.path,
            header: self.header,
            reader: text,
            offset: self.offset,
            line: self.line,
            text: std::mem::take(&mut self.text),
            split: Split::SERIAL,
            map: None,
        };
        let result = body.read_ascii_vertices(vertex, layout, sink, first, n);
        self.offset = body.offset;
        self.line = body.line;
        self.text = body.text;
        result
    }

    fn push(
        &self,
        sink: &mut Sink,
        values: &[f64],
        layout: Layout,
        k: u64,
        start: u64,
    ) -> Result<(), ReadError> {
        let get = |i: usize| values[i];
        sink.push(
            layout.xyz.map(get),
            layout.scan.map(get),
            layout.time.map(get),
        )
        .map_err(|why| {
            invalid(
                self.path,
                format!("vertex {k}: {why}"),
                Some(format!("byte offset {start}")),
            )
        })
    }
}

/// The ASCII vertex lines at the start of `piece` that parse cleanly, into a sink of their
/// own in the frame `origin`: the sink, the lines taken and their bytes.
fn ascii_piece(
    piece: &[u8],
    vertex: &Element,
    layout: Layout,
    origin: Option<[f64; 3]>,
) -> (Sink, u64, usize) {
    let mut part = Sink::new((piece.len() / 24) as u64, layout);
    part.origin = origin;
    let mut values = Vec::with_capacity(vertex.properties.len());
    let (mut taken, mut pos) = (0u64, 0usize);
    while pos < piece.len() {
        let end = piece[pos..]
            .iter()
            .position(|&c| c == b'\n')
            .map_or(piece.len(), |i| pos + i + 1);
        let Ok(line) = std::str::from_utf8(&piece[pos..end]) else {
            break;
        };
        if !ascii_values(line, vertex, &mut values) {
            break;
        }
        let get = |i: usize| values[i];
        let pushed = part.push(
            layout.xyz.map(get),
            layout.scan.map(get),
            layout.time.map(get),
        );
        if pushed.is_err() {
            break;
        }
        taken += 1;
        pos = end;
    }
    (part, taken, pos)
}

/// A vertex line's values as the serial read takes them (a list's is NaN); false where the
/// serial read would fail.
fn ascii_values(line: &str, vertex: &Element, values: &mut Vec<f64>) -> bool {
    values.clear();
    let mut tokens = line.split_ascii_whitespace();
    let mut next = || tokens.next().and_then(parse_number);
    for p in &vertex.properties {
        match p.kind {
            Kind::Scalar(_) => match next() {
                Some(v) => values.push(v),
                None => return false,
            },
            Kind::List { .. } => {
                let Some(n) = next() else {
                    return false;
                };
                if !(n >= 0.0 && n.fract() == 0.0 && n <= 1.0e6) {
                    return false;
                }
                for _ in 0..n as usize {
                    if next().is_none() {
                        return false;
                    }
                }
                values.push(f64::NAN);
            }
        }
    }
    true
}

/// A decode's outcome: on error, the record's index and why.
type Decoded = Result<(), (usize, String)>;

/// How to decode fixed-size binary vertex records: the record size, and the offset and type
/// of x, y, z and the optional scan index and time.
struct Records {
    size: usize,
    xyz: [(usize, Scalar); 3],
    scan: Option<(usize, Scalar)>,
    time: Option<(usize, Scalar)>,
    big: bool,
    layout: Layout,
}

impl Records {
    fn new(vertex: &Element, size: usize, layout: Layout, big: bool) -> Records {
        let mut fields = Vec::with_capacity(vertex.properties.len());
        let mut at = 0;
        for p in &vertex.properties {
            if let Kind::Scalar(s) = p.kind {
                fields.push((at, s));
                at += s.size();
            }
        }
        Records {
            size,
            xyz: layout.xyz.map(|k| fields[k]),
            scan: layout.scan.map(|k| fields[k]),
            time: layout.time.map(|k| fields[k]),
            big,
            layout,
        }
    }

    /// Decodes whole records into `sink`; on error, the record's index in `buf` and why.
    fn decode(&self, sink: &mut Sink, buf: &[u8]) -> Result<(), (usize, String)> {
        let [x, y, z] = self.xyz;
        if let Some(scan) = fast_layout(self.xyz, self.scan, self.time, self.big) {
            return sink.push_f32_records(buf, self.size, [x.0, y.0, z.0], scan);
        }
        for (i, rec) in buf.chunks_exact(self.size).enumerate() {
            let get = |(o, s): (usize, Scalar)| s.decode(&rec[o..], self.big);
            sink.push(
                [get(x), get(y), get(z)],
                self.scan.map(get),
                self.time.map(get),
            )
            .map_err(|why| (i, why))?;
        }
        Ok(())
    }

    /// Decodes whole records straight into the cloud's arrays from point `*written` on, in
    /// `parts` pieces on rayon's threads, with exactly [`Self::decode`]'s result. Each piece
    /// writes its kept points at the start of its own stretch with slots of its own; the
    /// stretches are then renumbered and closed up in order. A block where a piece fails, or
    /// whose scans do not fit, is decoded again serially, so an error is the serial one.
    fn decode_direct(
        &self,
        sink: &mut Sink,
        written: &mut usize,
        buf: &[u8],
        parts: usize,
    ) -> Decoded {
        match fast_layout(self.xyz, self.scan, self.time, self.big) {
            Some(scan) => self.decode_direct_with(
                &F32Fields {
                    xyz: self.xyz.map(|f| f.0),
                    scan,
                },
                sink,
                written,
                buf,
                parts,
            ),
            None => self.decode_direct_with(self, sink, written, buf, parts),
        }
    }

    fn decode_direct_with<D: Fields>(
        &self,
        fields: &D,
        sink: &mut Sink,
        written: &mut usize,
        buf: &[u8],
        parts: usize,
    ) -> Decoded {
        let size = self.size;
        let n = buf.len() / size;
        // The first kept point fixes the local frame every piece needs; without one, every
        // point of the block is skipped and the frame is never used.
        if sink.origin.is_none() {
            sink.origin = buf
                .chunks_exact(size)
                .map(|rec| (fields.point(rec), fields.time(rec)))
                .find(|(p, t)| kept(p, *t))
                .map(|(p, _)| local_origin(Some(p)));
        }
        let origin = sink.origin.unwrap_or_default();
        let at = *written;
        let per = n.div_ceil(parts.max(1)).max(1);
        let out = Out::of(&mut sink.cloud, at, n);
        let pieces = decode_pieces(out, buf, size, per, |recs, out| {
            fields.piece(recs, size, origin, out)
        });
        // Pieces' scans take the cloud's slots in order, as a serial read would give them.
        let known = sink.cloud.scan_ids.len();
        let mut maps = Vec::with_capacity(pieces.len());
        for piece in &pieces {
            let map = match piece.failed {
                false => piece
                    .slots
                    .ids
                    .iter()
                    .map(|&id| sink.slot_of_id(id))
                    .collect(),
                true => Err(String::new()),
            };
            match map {
                Ok(map) => maps.push((piece.kept, map)),
                Err(_) => {
                    sink.forget_scans(known);
                    return self.decode_block_serially(sink, written, buf);
                }
            }
        }
        sink.skipped += pieces.iter().map(|p| p.skipped).sum::<u64>();
        *written += settle(Out::of(&mut sink.cloud, at, n), per, &maps);
        Ok(())
    }

    /// [`Self::decode`] of a block into a sink of its own that starts from this one's scans
    /// and frame, copied in when it succeeds: the exact serial result or error.
    fn decode_block_serially(&self, sink: &mut Sink, written: &mut usize, buf: &[u8]) -> Decoded {
        let mut part = Sink {
            cloud: PointCloud {
                scan_ids: sink.cloud.scan_ids.clone(),
                ..Default::default()
            },
            origin: sink.origin,
            slots: sink.slots.clone(),
            last: None,
            skipped: 0,
        };
        self.decode(&mut part, buf)?;
        let (at, n) = (*written, part.cloud.xyz.len());
        let c = &mut sink.cloud;
        c.xyz[at..at + n].copy_from_slice(&part.cloud.xyz);
        if !c.scan.is_empty() {
            c.scan[at..at + n].copy_from_slice(&part.cloud.scan);
        }
        if !c.time.is_empty() {
            c.time[at..at + n].copy_from_slice(&part.cloud.time);
        }
        c.scan_ids = part.cloud.scan_ids;
        sink.slots = part.slots;
        sink.last = None;
        sink.skipped += part.skipped;
        sink.origin = part.origin;
        *written += n;
        Ok(())
    }

    /// [`Self::decode`] in `parts` pieces on rayon's threads, with exactly its result: each
    /// piece collects its points and scan slots on its own, in the shared local frame, and
    /// the pieces are then appended in order. A piece that fails, or whose scans would not
    /// fit, is decoded again here, so an error is the one a one-piece read gives.
    fn decode_parts(
        &self,
        sink: &mut Sink,
        buf: &[u8],
        parts: usize,
    ) -> Result<(), (usize, String)> {
        let size = self.size;
        let records = buf.len() / size;
        // The first kept point fixes the local frame, which every piece needs.
        let mut first = 0;
        while sink.origin.is_none() && first < records {
            self.decode(sink, &buf[first * size..(first + 1) * size])
                .map_err(|(_, why)| (first, why))?;
            first += 1;
        }
        let rest = &buf[first * size..records * size];
        let left = records - first;
        if parts <= 1 || left < 2 {
            return self.decode(sink, rest).map_err(|(i, why)| (first + i, why));
        }
        let per = left.div_ceil(parts);
        let origin = sink.origin;
        let pieces: Vec<(Sink, Decoded)> = rest
            .par_chunks(per * size)
            .map(|piece| {
                let mut part = Sink::new((piece.len() / size) as u64, self.layout);
                part.origin = origin;
                let result = self.decode(&mut part, piece);
                (part, result)
            })
            .collect();
        for (k, (part, result)) in pieces.iter().enumerate() {
            if result.is_ok() && sink.absorb(part) {
                continue;
            }
            let at = first + k * per;
            let piece = &rest[k * per * size..((k + 1) * per).min(left) * size];
            self.decode(sink, piece).map_err(|(i, why)| (at + i, why))?;
        }
        Ok(())
    }
}

/// A point is kept when its coordinates and time (if any) are finite.
#[inline(always)]
fn kept(p: &[f64; 3], t: Option<f64>) -> bool {
    p.iter().all(|c| c.is_finite()) && t.is_none_or(f64::is_finite)
}

/// How a piece decoder reads a record's fields.
trait Fields: Sync {
    fn point(&self, rec: &[u8]) -> [f64; 3];
    fn time(&self, rec: &[u8]) -> Option<f64>;
    /// The scan id, if the layout has one; an error when it is not a whole number.
    fn scan(&self, rec: &[u8]) -> Option<Result<u32, String>>;

    /// Decodes the records `recs` into the start of `out`: [`decode_piece`] unless a layout
    /// knows a faster way to the same result.
    fn piece(&self, recs: &[u8], size: usize, origin: [f64; 3], out: Out<'_>) -> Piece
    where
        Self: Sized,
    {
        decode_piece(self, recs, size, origin, out)
    }
}

/// Any fixed layout, each field decoded by its type.
impl Fields for Records {
    #[inline]
    fn point(&self, rec: &[u8]) -> [f64; 3] {
        self.xyz.map(|(o, s)| s.decode(&rec[o..], self.big))
    }

    #[inline]
    fn time(&self, rec: &[u8]) -> Option<f64> {
        self.time.map(|(o, s)| s.decode(&rec[o..], self.big))
    }

    #[inline]
    fn scan(&self, rec: &[u8]) -> Option<Result<u32, String>> {
        self.scan
            .map(|(o, s)| scan_id(s.decode(&rec[o..], self.big)))
    }
}

/// The commonest layout ([`fast_layout`]): little-endian `float` x, y, z at these offsets and
/// an optional `uint` scan index; no time. Fixed types keep the loop free of type dispatch.
struct F32Fields {
    xyz: [usize; 3],
    scan: Option<usize>,
}

/// Four bytes of a record from offset `o`: one bounds check and one load, not one a byte.
#[inline(always)]
fn le4(rec: &[u8], o: usize) -> [u8; 4] {
    let mut a = [0; 4];
    a.copy_from_slice(&rec[o..o + 4]);
    a
}

impl Fields for F32Fields {
    #[inline(always)]
    fn point(&self, rec: &[u8]) -> [f64; 3] {
        self.xyz.map(|o| f64::from(f32::from_le_bytes(le4(rec, o))))
    }

    #[inline]
    fn time(&self, _: &[u8]) -> Option<f64> {
        None
    }

    #[inline(always)]
    fn scan(&self, rec: &[u8]) -> Option<Result<u32, String>> {
        self.scan.map(|o| Ok(u32::from_le_bytes(le4(rec, o))))
    }

    fn piece(&self, recs: &[u8], size: usize, origin: [f64; 3], out: Out<'_>) -> Piece {
        match self.scan {
            Some(o) => self.piece_with::<true>(o, recs, size, origin, out),
            None => self.piece_with::<false>(0, recs, size, origin, out),
        }
    }
}

impl F32Fields {
    /// [`decode_piece`] for this layout, with or without the scan index at `so`: the same
    /// points, slots and failure from a loop that keeps its state (the last scan's slot
    /// among it) in registers.
    #[inline(always)]
    fn piece_with<const SCAN: bool>(
        &self,
        so: usize,
        recs: &[u8],
        size: usize,
        origin: [f64; 3],
        out: Out<'_>,
    ) -> Piece {
        let mut slots = LocalSlots::new();
        let [ox, oy, oz] = self.xyz;
        let (xyz, scan) = (out.xyz, out.scan);
        let (mut w, mut skipped, mut failed) = (0, 0, false);
        let mut last: Option<(u32, u16)> = None;
        for rec in recs.chunks_exact(size) {
            let f = |o: usize| f32::from_le_bytes(le4(rec, o));
            let (x, y, z) = (f(ox), f(oy), f(oz));
            if !(x.is_finite() & y.is_finite() & z.is_finite()) {
                skipped += 1;
                continue;
            }
            if SCAN {
                let id = u32::from_le_bytes(le4(rec, so));
                let slot = match last {
                    Some((l, slot)) if l == id => slot,
                    _ => match slots.slot(id) {
                        Some(slot) => {
                            last = Some((id, slot));
                            slot
                        }
                        None => {
                            failed = true;
                            break;
                        }
                    },
                };
                scan[w] = slot;
            }
            xyz[w] = to_local(origin, [f64::from(x), f64::from(y), f64::from(z)]);
            w += 1;
        }
        Piece {
            kept: w,
            skipped,
            slots,
            failed,
        }
    }
}

/// What a piece decoded: its kept points, skipped points and scans, or that it failed.
struct Piece {
    kept: usize,
    skipped: u64,
    slots: LocalSlots,
    failed: bool,
}

/// Decodes the records `recs` into the start of `out`, as [`Sink::push`] would push them.
fn decode_piece<D: Fields>(
    fields: &D,
    recs: &[u8],
    size: usize,
    origin: [f64; 3],
    out: Out<'_>,
) -> Piece {
    let mut piece = Piece {
        kept: 0,
        skipped: 0,
        slots: LocalSlots::new(),
        failed: false,
    };
    let mut w = 0;
    for rec in recs.chunks_exact(size) {
        let p = fields.point(rec);
        let t = fields.time(rec);
        if !kept(&p, t) {
            piece.skipped += 1;
            continue;
        }
        if let Some(id) = fields.scan(rec) {
            match id.ok().and_then(|id| piece.slots.slot(id)) {
                Some(slot) => out.scan[w] = slot,
                None => {
                    piece.failed = true;
                    break;
                }
            }
        }
        if let Some(t) = t {
            out.time[w] = t;
        }
        out.xyz[w] = to_local(origin, p);
        w += 1;
    }
    piece.kept = w;
    piece
}

/// For the layout [`Sink::push_f32_records`] decodes (little-endian `float` x, y, z, an
/// optional `uint` scan index, no time): `Some` with the scan index's offset, if any.
#[allow(clippy::type_complexity)]
fn fast_layout(
    xyz: [(usize, Scalar); 3],
    scan: Option<(usize, Scalar)>,
    time: Option<(usize, Scalar)>,
    big: bool,
) -> Option<Option<usize>> {
    let floats = !big && xyz.iter().all(|f| f.1 == Scalar::F32) && time.is_none();
    match scan {
        _ if !floats => None,
        None => Some(None),
        Some((o, Scalar::U32)) => Some(Some(o)),
        Some(_) => None,
    }
}

/// ASCII numbers, including the `nan` and `inf` spellings some writers use.
fn parse_number(token: &str) -> Option<f64> {
    token.parse::<f64>().ok()
}

/// A truncation error while reading a `block` of vertices, said in vertices.
fn truncated_vertices(e: ReadError, done: u64, count: u64, block: usize) -> ReadError {
    match e {
        ReadError::Invalid {
            path,
            format,
            why,
            at,
        } if why.starts_with("the file is truncated") => ReadError::Invalid {
            path,
            format,
            why: format!(
                "the file is truncated: it ends inside the vertex data, after fewer than {} of the {count} vertices the header declares",
                done + block.min((count - done) as usize) as u64
            ),
            at,
        },
        other => other,
    }
}

/// A failed read of `what` from byte `offset`, as the reader reports it.
fn fill_error(path: &Path, e: std::io::Error, what: &str, offset: u64) -> ReadError {
    let why = if e.kind() == std::io::ErrorKind::UnexpectedEof {
        format!("the file is truncated: it ends inside {what}")
    } else {
        e.to_string()
    };
    invalid(path, why, Some(format!("byte offset {offset}")))
}

pub(super) fn invalid(path: &Path, why: impl Into<String>, at: Option<String>) -> ReadError {
    ReadError::Invalid {
        path: path.display().to_string(),
        format: FORMAT,
        why: why.into(),
        at,
    }
}

pub(super) fn io_error(path: &Path, source: std::io::Error) -> ReadError {
    ReadError::Io {
        path: path.display().to_string(),
        source,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cloud of `n` points over several scans, with non-finite points at the start and
    /// scattered, so the first piece and later ones both skip points.
    fn cloud(n: usize, with_time: bool) -> PointCloud {
        let mut c = PointCloud {
            scan_ids: vec![40, 7, 12, 99, 3],
            ..Default::default()
        };
        for i in 0..n {
            let f = i as f32;
            let bad = i < 3 || i % 977 == 0;
            let x = if bad { f32::NAN } else { f * 0.01 };
            c.xyz
                .push([x, (f * 0.37).sin() * 20.0, (i % 300) as f32 * 0.01]);
            // Scans appear in runs, some coming back, so slots merge across pieces.
            c.scan.push(((i / 1_300) % 5) as u16);
            if with_time {
                c.time.push(i as f64 * 1e-3);
            }
        }
        c
    }

    fn read(bytes: &[u8], split: Split) -> Result<PointCloud, ReadError> {
        read_claiming(bytes, bytes.len() as u64, split, false)
    }

    /// [`read`] of `bytes` written to a file, the vertices decoded from its map.
    fn read_mapped(bytes: &[u8], split: Split) -> Result<PointCloud, ReadError> {
        read_claiming(bytes, bytes.len() as u64, split, true)
    }

    /// Reads `bytes` as a file of `len` bytes (more, for a file that shrank after its size
    /// was taken), from a map of them or as a stream.
    fn read_claiming(
        bytes: &[u8],
        len: u64,
        split: Split,
        mapped: bool,
    ) -> Result<PointCloud, ReadError> {
        let source = std::io::Cursor::new(bytes.to_vec());
        if !mapped {
            return read_ply_split(source, len, "t.ply", split, None, true);
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.ply");
        std::fs::write(&path, bytes).unwrap();
        let file = File::open(&path).unwrap();
        let map = Mapped::new(&file, &Default::default()).expect("a file maps");
        read_ply_split(source, len, "t.ply", split, Some(&map), true)
    }

    fn same(a: &PointCloud, b: &PointCloud) {
        assert_eq!(a.len(), b.len());
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

    #[test]
    fn parallel_pieces_read_exactly_the_serial_points() {
        for with_time in [false, true] {
            let c = cloud(20_011, with_time);
            let mut bytes = Vec::new();
            write_ply_to(&mut bytes, &c, Encoding::BinaryLittleEndian).unwrap();
            let serial = read(&bytes, Split::SERIAL).unwrap();
            assert_eq!(serial.len(), 20_011 - 3 - 20);
            assert_eq!(serial.scan_ids, vec![40, 7, 12, 99, 3]);
            // Blocks and pieces that split the file at odd records.
            // Pieces through a sink each, and straight into the arrays.
            for direct in [false, true] {
                for (block, parts) in [(997, 3), (4_099, 7), (20_011, 2), (1 << 20, 5), (1, 2)] {
                    let split = Split {
                        block,
                        parts,
                        direct,
                    };
                    same(&serial, &read(&bytes, split).unwrap());
                    // From a map, blocks end inside pages and records cross page ends.
                    same(&serial, &read_mapped(&bytes, split).unwrap());
                }
            }
            // A file that shrank after its size was checked ends inside a block: the map
            // gives the error the stream gives, at the same vertex.
            let cut = &bytes[..bytes.len() - 5_000];
            for (block, parts) in [(997, 3), (4_099, 2), (1 << 20, 2)] {
                let split = Split {
                    block,
                    parts,
                    direct: true,
                };
                let len = bytes.len() as u64;
                let stream = read_claiming(cut, len, split, false).unwrap_err();
                assert!(stream.to_string().contains("truncated"), "{stream}");
                let mapped = read_claiming(cut, len, split, true).unwrap_err();
                assert_eq!(stream.to_string(), mapped.to_string());
            }
        }
    }

    /// Times cost 8 bytes a point: a read that is not asked for them (a scan with static poses)
    /// leaves them out, on every path (mapped, streamed, chunked, binary and ASCII), and
    /// otherwise reads the same points.
    #[test]
    fn times_are_read_only_when_asked_for() {
        use crate::io::chunks::{open_chunks, PointChunk};
        use crate::io::{read_cloud_from, read_cloud_with, ReadOptions};
        let c = cloud(5_003, true);
        for encoding in [Encoding::BinaryLittleEndian, Encoding::Ascii] {
            let mut bytes = Vec::new();
            write_ply_to(&mut bytes, &c, encoding).unwrap();
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("t.ply");
            std::fs::write(&path, &bytes).unwrap();
            for keep_time in [true, false] {
                let options = ReadOptions {
                    keep_time,
                    ..Default::default()
                };
                let mapped = read_cloud_with(&path, &options).unwrap();
                let streamed =
                    read_cloud_from(std::io::Cursor::new(bytes.clone()), "t.ply", &options)
                        .unwrap();
                let mut chunks = open_chunks(&path, &options).unwrap();
                let (mut chunk, mut xyz, mut time) = (PointChunk::default(), vec![], vec![]);
                while chunks.next_chunk(&mut chunk).unwrap() {
                    xyz.extend_from_slice(&chunk.xyz);
                    time.extend_from_slice(&chunk.time);
                }
                let kept: Vec<f64> = (0..5_003)
                    .filter(|&i| c.xyz[i][0].is_finite())
                    .map(|i| c.time[i])
                    .collect();
                assert_eq!(kept.len(), 5_003 - 8);
                for (read, got) in [("mapped", &mapped), ("streamed", &streamed)] {
                    assert_eq!(got.len(), kept.len(), "{encoding:?} {read}");
                    let want = if keep_time { &kept[..] } else { &[] };
                    assert_eq!(got.time, want, "{encoding:?} {read} keep_time {keep_time}");
                }
                let want = if keep_time { &kept[..] } else { &[] };
                assert_eq!(time, want, "{encoding:?} chunked keep_time {keep_time}");
                assert!(xyz == mapped.xyz && streamed.xyz == mapped.xyz);
                assert_eq!(streamed.scan, mapped.scan);
            }
        }
    }

    /// Reads ASCII `text` serially and at several splits: the same cloud or the same error.
    fn same_ascii(text: &[u8]) {
        let serial = read(text, Split::SERIAL);
        for (block, parts) in [(1, 2), (3, 3), (97, 2), (4_099, 5), (1 << 20, 2)] {
            let split = Split {
                block,
                parts,
                direct: true,
            };
            let parallel = read(text, split);
            match (&serial, &parallel) {
                (Ok(a), Ok(b)) => same(a, b),
                (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string()),
                _ => panic!("split {block}/{parts}: {serial:?} vs {parallel:?}"),
            }
        }
    }

    #[test]
    fn parallel_ascii_pieces_read_exactly_the_serial_points_and_errors() {
        for with_time in [false, true] {
            let c = cloud(5_003, with_time);
            let mut bytes = Vec::new();
            write_ply_to(&mut bytes, &c, Encoding::Ascii).unwrap();
            assert_eq!(read(&bytes, Split::SERIAL).unwrap().len(), 5_003 - 3 - 5);
            same_ascii(&bytes);
            // No newline after the last vertex.
            same_ascii(bytes.strip_suffix(b"\n").unwrap());
            // Damage late in the file: a word, a fractional scan index, bad UTF-8, a short
            // line, and the file cut short.
            let at = bytes.len() * 3 / 4;
            let cut = at + bytes[at..].iter().position(|&b| b == b'\n').unwrap() + 1;
            for bad in [&b"1 two 3 0"[..], b"1 2 3 0.5", b"1 2 \xff 0", b"1 2"] {
                let mut broken = bytes[..cut].to_vec();
                broken.extend_from_slice(bad);
                broken.push(b'\n');
                broken.extend_from_slice(&bytes[cut..]);
                same_ascii(&broken);
            }
            same_ascii(&bytes[..cut]);
            same_ascii(&bytes[..cut + 3]);
        }
        // Vertices with a list, then another element the vertex reader must not read.
        let mut t = String::from(
            "ply\nformat ascii 1.0\nelement vertex 400\nproperty float x\nproperty list uchar int n\n\
             property float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n",
        );
        for i in 0..400 {
            t += &format!("{i}.5 2 7 8 {} 3\n", i % 7);
        }
        t += "3 0 1 2\n3 1 2 3\n";
        same_ascii(t.as_bytes());
        assert_eq!(read(t.as_bytes(), Split::SERIAL).unwrap().len(), 400);
    }

    #[test]
    fn parallel_pieces_fail_as_the_serial_read_does() {
        // Every vertex a scan of its own: more scans than slots, found while merging pieces.
        let n = 70_000u32;
        let mut bytes = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\n\
             property float y\nproperty float z\nproperty uint scan_index\nend_header\n"
        )
        .into_bytes();
        for i in 0..n {
            for v in [i as f32, 1.0, 2.0] {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
            bytes.extend_from_slice(&i.to_le_bytes());
        }
        let serial = read(&bytes, Split::SERIAL).unwrap_err().to_string();
        assert!(serial.contains("distinct scan indices"), "{serial}");
        for direct in [false, true] {
            for (block, parts) in [(9_999, 3), (1 << 20, 2), (9_999, 1)] {
                let split = Split {
                    block,
                    parts,
                    direct,
                };
                assert_eq!(read(&bytes, split).unwrap_err().to_string(), serial);
                assert_eq!(read_mapped(&bytes, split).unwrap_err().to_string(), serial);
            }
            // A truncated body is still an error, not a panic.
            let cut = &bytes[..bytes.len() - 7];
            let split = Split {
                block: 9_999,
                parts: 3,
                direct,
            };
            let err = read(cut, split).unwrap_err();
            assert!(err.to_string().contains("truncated"), "{err}");
            assert_eq!(
                read_mapped(cut, split).unwrap_err().to_string(),
                err.to_string()
            );
        }
    }
}
