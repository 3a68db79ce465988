//! PLY read a batch at a time ([`crate::io::chunks`]), through the whole-file reader's header
//! checks, element skipping and point sink, so the points are exactly those [`super::read_ply`]
//! reads.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use super::header::{describe, read_header, vertices, Element, Header, Kind, Layout, Scalar};
use super::{
    fast_layout, invalid, io_error, truncated_vertices, Body, Encoding, Sink, Split, FORMAT,
};
use crate::cloud::{PointCloud, SourceInfo};
use crate::io::chunks::{hand_over, PointChunk, PointChunks, CHUNK_POINTS};
use crate::io::ReadError;

/// A PLY file being read in batches.
pub struct PlyChunks {
    path: PathBuf,
    reader: BufReader<File>,
    header: Header,
    vertex: Element,
    layout: Layout,
    sink: Sink,
    /// Where the body reader is, for error messages.
    offset: u64,
    line: u64,
    /// Vertices read so far.
    done: u64,
    /// Fixed-size binary records: the record size, and each property's offset and type.
    fixed: Option<(usize, Vec<(usize, Scalar)>)>,
    buf: Vec<u8>,
}

impl PlyChunks {
    /// Reads the header and skips the elements before `vertex`; points' times are read only
    /// with `keep_time`.
    pub fn open(path: &Path, keep_time: bool) -> Result<PlyChunks, ReadError> {
        let file = File::open(path).map_err(|e| io_error(path, e))?;
        let file_len = file.metadata().map_err(|e| io_error(path, e))?.len();
        let mut reader = BufReader::with_capacity(1 << 20, file);
        let header = read_header(&mut reader, path)?;
        let (vertex_pos, vertex, layout) = vertices(&header, file_len, path, keep_time)?;
        let vertex = vertex.clone();
        let (offset, line) = {
            let mut body = Body {
                path,
                header: &header,
                reader: &mut reader,
                offset: header.len,
                line: header.lines,
                text: String::new(),
                split: Split::SERIAL,
                map: None,
            };
            for element in &header.elements[..vertex_pos] {
                body.skip_element(element)?;
            }
            (body.offset, body.line)
        };
        let fixed = match (header.encoding, vertex.fixed_size()) {
            (Encoding::Ascii, _) | (_, None) => None,
            (_, Some(size)) => {
                let mut at = 0;
                let fields = vertex
                    .properties
                    .iter()
                    .map(|p| {
                        let s = match p.kind {
                            Kind::Scalar(s) => s,
                            Kind::List { .. } => unreachable!("fixed-size records hold no lists"),
                        };
                        let field = (at, s);
                        at += s.size();
                        field
                    })
                    .collect();
                Some((size, fields))
            }
        };
        Ok(PlyChunks {
            path: path.to_path_buf(),
            reader,
            sink: Sink::new(0, layout),
            header,
            vertex,
            layout,
            offset,
            line,
            done: 0,
            fixed,
            buf: Vec::new(),
        })
    }

    /// Decodes the next `n` fixed-size records into the sink.
    fn read_fixed(&mut self, n: usize) -> Result<(), ReadError> {
        let (size, fields) = self.fixed.as_ref().expect("fixed layout");
        let size = *size;
        let big = self.header.encoding == Encoding::BinaryBigEndian;
        let field = |k: usize| fields[k];
        let [x, y, z] = self.layout.xyz.map(field);
        let scan = self.layout.scan.map(field);
        let time = self.layout.time.map(field);
        self.buf.resize(n * size, 0);
        let start = self.offset;
        let mut body = Body {
            path: &self.path,
            header: &self.header,
            reader: &mut self.reader,
            offset: self.offset,
            line: self.line,
            text: String::new(),
            split: Split::SERIAL,
            map: None,
        };
        body.fill(&mut self.buf, "the vertex data")
            .map_err(|e| truncated_vertices(e, self.done, self.vertex.count, n))?;
        self.offset = body.offset;
        if let Some(scan) = fast_layout([x, y, z], scan, time, big) {
            let done = self.done;
            return self
                .sink
                .push_f32_records(&self.buf, size, [x.0, y.0, z.0], scan)
                .map_err(|(i, why)| {
                    invalid(
                        &self.path,
                        format!("vertex {}: {why}", done + i as u64),
                        Some(format!("byte offset {}", start + (i * size) as u64)),
                    )
                });
        }
        for (i, rec) in self.buf.chunks_exact(size).enumerate() {
            let get = |(o, s): (usize, Scalar)| s.decode(&rec[o..], big);
            let p = [get(x), get(y), get(z)];
            self.sink
                .push(p, scan.map(get), time.map(get))
                .map_err(|why| {
                    invalid(
                        &self.path,
                        format!("vertex {}: {why}", self.done + i as u64),
                        Some(format!("byte offset {}", start + (i * size) as u64)),
                    )
                })?;
        }
        Ok(())
    }

    /// Decodes the next `n` ASCII lines or binary records with lists into the sink.
    fn read_general(&mut self, n: usize) -> Result<(), ReadError> {
        let one = Element {
            count: n as u64,
            ..self.vertex.clone()
        };
        let mut body = Body {
            path: &self.path,
            header: &self.header,
            reader: &mut self.reader,
            offset: self.offset,
            line: self.line,
            text: String::new(),
            split: Split::SERIAL,
            map: None,
        };
        let result = body.read_vertices(&one, self.layout, &mut self.sink);
        self.offset = body.offset;
        self.line = body.line;
        // Vertex numbers in errors count from the start of the chunk; name the true one.
        result.map_err(|e| renumber(e, self.done))
    }
}

/// Adds `base` to the `vertex K` an error names, so chunked errors match whole-file ones.
fn renumber(e: ReadError, base: u64) -> ReadError {
    match e {
        ReadError::Invalid {
            path,
            format,
            why,
            at,
        } => {
            let why = match why.strip_prefix("vertex ").and_then(|rest| {
                let end = rest.find(|c: char| !c.is_ascii_digit())?;
                let k: u64 = rest[..end].parse().ok()?;
                Some(format!("vertex {}{}", base + k, &rest[end..]))
            }) {
                Some(w) => w,
                None => why,
            };
            ReadError::Invalid {
                path,
                format,
                why,
                at,
            }
        }
        other => other,
    }
}

impl PointChunks for PlyChunks {
    fn next_chunk(&mut self, chunk: &mut PointChunk) -> Result<bool, ReadError> {
        let left = self.vertex.count - self.done;
        if left == 0 {
            chunk.xyz.clear();
            chunk.scan.clear();
            chunk.time.clear();
            return Ok(false);
        }
        let n = (left as usize).min(CHUNK_POINTS);
        // The sink and the chunk swap buffers each time, so both keep their capacity.
        if self.fixed.is_some() {
            self.read_fixed(n)?;
        } else {
            self.read_general(n)?;
        }
        self.done += n as u64;
        let c = &mut self.sink.cloud;
        hand_over(chunk, &mut c.xyz, &mut c.scan, &mut c.time);
        Ok(true)
    }

    fn skeleton(&self) -> Result<PointCloud, ReadError> {
        // What `Sink::finish` records, without the points.
        let skipped = self.sink.skipped;
        Ok(PointCloud {
            origin: self.sink.origin.unwrap_or_default(),
            scan_ids: self.sink.cloud.scan_ids.clone(),
            source: SourceInfo {
                format: FORMAT.into(),
                details: describe(&self.header, &self.vertex),
                skipped,
                skipped_reason: (skipped > 0)
                    .then(|| "non-finite coordinate or time (NaN or infinite)".to_string()),
                units: String::new(),
            },
            ..Default::default()
        })
    }
}
