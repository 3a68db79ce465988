//! PLY: ASCII and binary (both endiannesses), streamed, with optional `scan_index` and `time`.
//!
//! The reader never parses the whole file at once: it reads the header, skips the elements before
//! `vertex` (lists included), then decodes vertices in chunks from a `BufReader` straight into the
//! cloud's compact arrays. The header's counts are checked against the file's size before anything
//! is allocated, so a header claiming billions of vertices is an error, not an allocation.
//! Points with a non-finite coordinate are skipped and counted in `SourceInfo::skipped`.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::Path;

use super::ReadError;
use crate::cloud::{local_origin, to_local, PointCloud, SourceInfo};

/// The header may not be longer than this; real headers are a few hundred bytes.
const MAX_HEADER_BYTES: usize = 1 << 20;
/// Elements in the header, properties per element: beyond these the header is not plausible.
const MAX_ELEMENTS: usize = 64;
const MAX_PROPERTIES: usize = 1024;
/// Vertices decoded per chunk on the binary path.
const CHUNK_VERTICES: usize = 1 << 16;
/// Never reserve room for more points than this up front. Counts below it are reserved exactly
/// (after the file's size has confirmed them), so the arrays never grow by doubling.
const MAX_RESERVE: usize = 1 << 30;
/// Property names that give a point's scan index, in order of preference.
const SCAN_NAMES: [&str; 3] = ["scan_index", "scan", "point_source_id"];

const FORMAT: &str = "ply";

/// How a PLY file's body is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

impl Encoding {
    fn name(self) -> &'static str {
        match self {
            Encoding::Ascii => "ascii",
            Encoding::BinaryLittleEndian => "binary_little_endian",
            Encoding::BinaryBigEndian => "binary_big_endian",
        }
    }
}

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Decodes one value from the start of `b` (at least `size()` bytes).
    fn decode(self, b: &[u8], big: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                if big {
                    <$t>::from_be_bytes(a) as f64
                } else {
                    <$t>::from_le_bytes(a) as f64
                }
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => get!(i16, 2),
            Scalar::U16 => get!(u16, 2),
            Scalar::I32 => get!(i32, 4),
            Scalar::U32 => get!(u32, 4),
            Scalar::F32 => get!(f32, 4),
            Scalar::F64 => get!(f64, 8),
        }
    }
}

/// A property: a scalar, or a list with its count and item types.
#[derive(Debug, Clone, PartialEq)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

impl Element {
    /// Bytes per record when no property is a list.
    fn fixed_size(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(s) => Some(s.size()),
                Kind::List { .. } => None,
            })
            .sum()
    }

    /// The fewest bytes one record can take in this encoding (lists may be empty).
    fn min_size(&self, encoding: Encoding) -> usize {
        self.properties
            .iter()
            .map(|p| match (encoding, &p.kind) {
                // A digit and a separator per value.
                (Encoding::Ascii, _) => 2,
                (_, Kind::Scalar(s)) => s.size(),
                (_, Kind::List { count, .. }) => count.size(),
            })
            .sum()
    }
}

#[derive(Debug)]
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Header length in bytes, where the body starts.
    len: u64,
    /// Header lines, so ASCII line numbers continue from here.
    lines: u64,
    /// `comment` and `obj_info` lines, shown in the format details.
    comments: Vec<String>,
}

/// Where the vertex fields the cloud needs sit in a record.
#[derive(Debug, Clone, Copy)]
struct Layout {
    xyz: [usize; 3],
    scan: Option<usize>,
    time: Option<usize>,
}

/// Reads a PLY file.
pub fn read_ply(path: &Path) -> Result<PointCloud, ReadError> {
    let file = File::open(path).map_err(|e| io_error(path, e))?;
    let file_len = file.metadata().map_err(|e| io_error(path, e))?.len();
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let header = read_header(&mut reader, path)?;
    let (vertex_pos, vertex) = header
        .elements
        .iter()
        .enumerate()
        .find(|(_, e)| e.name == "vertex")
        .ok_or_else(|| invalid(path, "the header declares no `vertex` element", None))?;
    let layout = layout(vertex, path)?;
    check_counts(&header, vertex_pos, file_len, path)?;

    let mut sink = Sink::new(vertex.count, layout);
    let mut body = Body {
        path,
        header: &header,
        reader: &mut reader,
        offset: header.len,
        line: header.lines,
        text: String::new(),
    };
    for element in &header.elements[..vertex_pos] {
        body.skip_element(element)?;
    }
    body.read_vertices(vertex, layout, &mut sink)?;
    Ok(sink.finish(describe(&header, vertex)))
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
        if !(s >= 0.0 && s <= f64::from(u32::MAX) && s.fract() == 0.0) {
            return Err(format!(
                "scan index {s} is not a whole number from 0 to {}",
                u32::MAX
            ));
        }
        let id = s as u32;
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
            units: "m".into(),
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
}

impl<R: BufRead> Body<'_, R> {
    fn big(&self) -> bool {
        self.header.encoding == Encoding::BinaryBigEndian
    }

    fn fill(&mut self, buf: &mut [u8], what: &str) -> Result<(), ReadError> {
        self.reader.read_exact(buf).map_err(|e| {
            let why = if e.kind() == std::io::ErrorKind::UnexpectedEof {
                format!("the file is truncated: it ends inside {what}")
            } else {
                e.to_string()
            };
            invalid(self.path, why, Some(format!("byte offset {}", self.offset)))
        })?;
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
            (Encoding::Ascii, _) => self.read_ascii_vertices(vertex, layout, sink),
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

    /// The fast path: fixed-size binary records decoded a chunk at a time.
    fn read_fixed_vertices(
        &mut self,
        vertex: &Element,
        size: usize,
        layout: Layout,
        sink: &mut Sink,
    ) -> Result<(), ReadError> {
        let big = self.big();
        let mut offsets = Vec::with_capacity(vertex.properties.len());
        let mut at = 0;
        let mut types = Vec::with_capacity(vertex.properties.len());
        for p in &vertex.properties {
            offsets.push(at);
            if let Kind::Scalar(s) = p.kind {
                types.push(s);
                at += s.size();
            }
        }
        let field = |k: usize| (offsets[k], types[k]);
        let [x, y, z] = layout.xyz.map(field);
        let scan = layout.scan.map(field);
        let time = layout.time.map(field);
        let mut buf = vec![0u8; size * CHUNK_VERTICES.min(vertex.count as usize).max(1)];
        let mut done = 0u64;
        while done < vertex.count {
            let n = ((vertex.count - done) as usize).min(CHUNK_VERTICES);
            let start = self.offset;
            self.fill(&mut buf[..n * size], "the vertex data")
                .map_err(|e| truncated_vertices(e, done, vertex.count))?;
            for (i, rec) in buf[..n * size].chunks_exact(size).enumerate() {
                let get = |(o, s): (usize, Scalar)| s.decode(&rec[o..], big);
                let p = [get(x), get(y), get(z)];
                sink.push(p, scan.map(get), time.map(get)).map_err(|why| {
                    invalid(
                        self.path,
                        format!("vertex {}: {why}", done + i as u64),
                        Some(format!("byte offset {}", start + (i * size) as u64)),
                    )
                })?;
            }
            done += n as u64;
        }
        Ok(())
    }

    fn read_ascii_vertices(
        &mut self,
        vertex: &Element,
        layout: Layout,
        sink: &mut Sink,
    ) -> Result<(), ReadError> {
        let mut values = Vec::with_capacity(vertex.properties.len());
        for k in 0..vertex.count {
            self.next_line(&|| format!("vertex {k} of {}", vertex.count))?;
            values.clear();
            let mut tokens = self.text.split_ascii_whitespace();
            for p in &vertex.properties {
                let mut next = |what: &str| -> Result<f64, ReadError> {
                    let token = tokens.next().ok_or_else(|| {
                        invalid(
                            self.path,
                            format!("vertex {k}: the line ends before {what}"),
                            Some(format!("line {}", self.line)),
                        )
                    })?;
                    parse_number(token).ok_or_else(|| {
                        invalid(
                            self.path,
                            format!("vertex {k}: {what} is not a number: {token:?}"),
                            Some(format!("line {}", self.line)),
                        )
                    })
                };
                match p.kind {
                    Kind::Scalar(_) => values.push(next(&format!("property `{}`", p.name))?),
                    Kind::List { .. } => {
                        let n = next(&format!("the length of list `{}`", p.name))?;
                        if !(n >= 0.0 && n.fract() == 0.0 && n <= 1.0e6) {
                            return Err(invalid(
                                self.path,
                                format!("vertex {k}: list `{}` has an invalid length {n}", p.name),
                                Some(format!("line {}", self.line)),
                            ));
                        }
                        for _ in 0..n as usize {
                            next(&format!("an item of list `{}`", p.name))?;
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

/// ASCII numbers, including the `nan` and `inf` spellings some writers use.
fn parse_number(token: &str) -> Option<f64> {
    token.parse::<f64>().ok()
}

fn truncated_vertices(e: ReadError, done: u64, count: u64) -> ReadError {
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
                done + CHUNK_VERTICES.min((count - done) as usize) as u64
            ),
            at,
        },
        other => other,
    }
}

/// Reads header lines, counting bytes and lines, with a cap on the header's size.
struct HeaderLines<'a> {
    path: &'a Path,
    len: u64,
    lines: u64,
    raw: Vec<u8>,
}

impl HeaderLines<'_> {
    fn next(&mut self, reader: &mut impl BufRead) -> Result<Option<String>, ReadError> {
        self.raw.clear();
        let n = reader
            .take((MAX_HEADER_BYTES as u64).saturating_sub(self.len) + 1)
            .read_until(b'\n', &mut self.raw)
            .map_err(|e| io_error(self.path, e))?;
        self.len += n as u64;
        self.lines += 1;
        if n == 0 {
            return Ok(None);
        }
        if self.len as usize > MAX_HEADER_BYTES {
            return Err(invalid(
                self.path,
                format!("the header is longer than {MAX_HEADER_BYTES} bytes without `end_header`"),
                None,
            ));
        }
        let text = std::str::from_utf8(&self.raw).map_err(|_| {
            invalid(
                self.path,
                "the header is not text",
                Some(format!("line {}", self.lines)),
            )
        })?;
        Ok(Some(text.trim_end_matches(['\n', '\r']).to_string()))
    }
}

/// Reads and validates the header, leaving `reader` at the first body byte.
fn read_header(reader: &mut impl BufRead, path: &Path) -> Result<Header, ReadError> {
    let mut h = HeaderLines {
        path,
        len: 0,
        lines: 0,
        raw: Vec::new(),
    };
    let at = |line: u64| Some(format!("line {line}"));
    match h.next(reader)? {
        None => return Err(invalid(path, "the file is empty", None)),
        Some(magic) if magic.trim_end() == "ply" => {}
        Some(other) => {
            let shown: String = other.chars().take(16).collect();
            return Err(invalid(
                path,
                format!("not a PLY file: it must start with `ply`, not {shown:?}"),
                Some("byte offset 0".into()),
            ));
        }
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut comments = Vec::new();
    loop {
        let line_no = h.lines + 1;
        let Some(line) = h.next(reader)? else {
            return Err(invalid(
                path,
                "the file is truncated: the header ends without `end_header`",
                at(line_no),
            ));
        };
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        match words.as_slice() {
            [] => {}
            ["end_header"] => break,
            ["comment", ..] | ["obj_info", ..] => {
                comments.push(line.split_once(' ').map_or("", |x| x.1).trim().to_string())
            }
            ["format", name, version] => {
                if !version.starts_with('1') {
                    return Err(invalid(
                        path,
                        format!("unsupported PLY version {version}"),
                        at(line_no),
                    ));
                }
                encoding = Some(match *name {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::BinaryLittleEndian,
                    "binary_big_endian" => Encoding::BinaryBigEndian,
                    other => {
                        return Err(invalid(
                            path,
                            format!("unknown PLY format `{other}`"),
                            at(line_no),
                        ))
                    }
                });
            }
            ["element", name, count] => {
                if elements.len() >= MAX_ELEMENTS {
                    return Err(invalid(
                        path,
                        format!("more than {MAX_ELEMENTS} elements in the header"),
                        at(line_no),
                    ));
                }
                let count = count.parse::<u64>().map_err(|_| {
                    invalid(
                        path,
                        format!("element `{name}` has an invalid count {count:?}"),
                        at(line_no),
                    )
                })?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", rest @ ..] => {
                let element = elements.last_mut().ok_or_else(|| {
                    invalid(path, "a property comes before any element", at(line_no))
                })?;
                if element.properties.len() >= MAX_PROPERTIES {
                    return Err(invalid(
                        path,
                        format!(
                            "element `{}` declares more than {MAX_PROPERTIES} properties",
                            element.name
                        ),
                        at(line_no),
                    ));
                }
                let scalar = |t: &str| {
                    Scalar::parse(t).ok_or_else(|| {
                        invalid(path, format!("unknown property type `{t}`"), at(line_no))
                    })
                };
                let property = match rest {
                    ["list", count, item, name] => Property {
                        name: name.to_string(),
                        kind: Kind::List {
                            count: scalar(count)?,
                            item: scalar(item)?,
                        },
                    },
                    [t, name] => Property {
                        name: name.to_string(),
                        kind: Kind::Scalar(scalar(t)?),
                    },
                    _ => {
                        return Err(invalid(
                            path,
                            format!("malformed property line {line:?}"),
                            at(line_no),
                        ))
                    }
                };
                if let Kind::List { count, .. } = property.kind {
                    if count.is_float() {
                        return Err(invalid(
                            path,
                            format!("list `{}` has a floating-point length type", property.name),
                            at(line_no),
                        ));
                    }
                }
                if element.properties.iter().any(|p| p.name == property.name) {
                    return Err(invalid(
                        path,
                        format!(
                            "element `{}` declares property `{}` twice",
                            element.name, property.name
                        ),
                        at(line_no),
                    ));
                }
                element.properties.push(property);
            }
            _ => {
                let shown: String = line.chars().take(60).collect();
                return Err(invalid(
                    path,
                    format!("unknown header line {shown:?}"),
                    at(line_no),
                ));
            }
        }
    }
    let encoding =
        encoding.ok_or_else(|| invalid(path, "the header has no `format` line", None))?;
    Ok(Header {
        encoding,
        elements,
        len: h.len,
        lines: h.lines,
        comments,
    })
}

/// Finds x, y, z and the optional scan and time properties of the vertex element.
fn layout(vertex: &Element, path: &Path) -> Result<Layout, ReadError> {
    let find = |name: &str| {
        vertex
            .properties
            .iter()
            .position(|p| p.name == name && matches!(p.kind, Kind::Scalar(_)))
    };
    let mut xyz = [0; 3];
    for (k, name) in ["x", "y", "z"].into_iter().enumerate() {
        xyz[k] = find(name).ok_or_else(|| {
            invalid(
                path,
                format!("the vertex element has no scalar `{name}` property"),
                None,
            )
        })?;
    }
    Ok(Layout {
        xyz,
        scan: SCAN_NAMES.iter().find_map(|n| find(n)),
        time: find("time"),
    })
}

/// Rejects counts the file cannot hold, before anything is allocated.
fn check_counts(
    header: &Header,
    vertex_pos: usize,
    file_len: u64,
    path: &Path,
) -> Result<(), ReadError> {
    let body = file_len.saturating_sub(header.len);
    let mut need: u64 = 0;
    for e in &header.elements[..=vertex_pos] {
        let min = e.min_size(header.encoding) as u64;
        need = need.saturating_add(min.saturating_mul(e.count));
    }
    if need > body {
        let vertex = &header.elements[vertex_pos];
        return Err(invalid(
            path,
            format!(
                "the header declares {} vertices, which need at least {need} bytes, but only {body} bytes follow the header (truncated file or bad count)",
                vertex.count
            ),
            Some(format!("byte offset {}", header.len)),
        ));
    }
    Ok(())
}

fn describe(header: &Header, vertex: &Element) -> String {
    let props: Vec<String> = vertex
        .properties
        .iter()
        .map(|p| match &p.kind {
            Kind::Scalar(s) => format!("{} {}", scalar_name(*s), p.name),
            Kind::List { count, item } => {
                format!(
                    "list {} {} {}",
                    scalar_name(*count),
                    scalar_name(*item),
                    p.name
                )
            }
        })
        .collect();
    let mut details = format!(
        "{} 1.0, {} vertices ({})",
        header.encoding.name(),
        vertex.count,
        props.join(", ")
    );
    if let Some(c) = header.comments.iter().find(|c| !c.is_empty()) {
        let c: String = c.chars().take(80).collect();
        details.push_str(&format!("; comment: {c}"));
    }
    details
}

fn scalar_name(s: Scalar) -> &'static str {
    match s {
        Scalar::I8 => "char",
        Scalar::U8 => "uchar",
        Scalar::I16 => "short",
        Scalar::U16 => "ushort",
        Scalar::I32 => "int",
        Scalar::U32 => "uint",
        Scalar::F32 => "float",
        Scalar::F64 => "double",
    }
}

fn invalid(path: &Path, why: impl Into<String>, at: Option<String>) -> ReadError {
    ReadError::Invalid {
        path: path.display().to_string(),
        format: FORMAT,
        why: why.into(),
        at,
    }
}

fn io_error(path: &Path, source: std::io::Error) -> ReadError {
    ReadError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// Why a PLY file could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot write {path}: {source}")]
pub struct WriteError {
    pub path: String,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalar_decoding_both_endiannesses() {
        assert_eq!(Scalar::F32.decode(&1.5f32.to_le_bytes(), false), 1.5);
        assert_eq!(Scalar::F32.decode(&1.5f32.to_be_bytes(), true), 1.5);
        assert_eq!(Scalar::I16.decode(&(-3i16).to_be_bytes(), true), -3.0);
        assert_eq!(Scalar::U32.decode(&7u32.to_le_bytes(), false), 7.0);
        assert_eq!(Scalar::I8.decode(&[0xff], false), -1.0);
    }

    #[test]
    fn header_parses_lists_and_skips_comments() {
        let text = "ply\nformat ascii 1.0\ncomment hi\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
        let h = read_header(&mut text.as_bytes(), Path::new("t.ply")).unwrap();
        assert_eq!(h.elements.len(), 2);
        assert_eq!(h.elements[1].fixed_size(), None);
        assert_eq!(h.elements[0].fixed_size(), Some(12));
        assert_eq!(h.len, text.len() as u64);
        assert_eq!(h.comments, vec!["hi".to_string()]);
    }
}
