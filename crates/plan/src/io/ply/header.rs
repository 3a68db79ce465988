//! The PLY header: formats, elements and properties, read with caps on every size, and the
//! checks that happen before any vertex is read.

use std::io::{BufRead, Read};
use std::path::Path;

use super::{invalid, io_error};
use crate::io::ReadError;

/// The header may not be longer than this; real headers are a few hundred bytes.
const MAX_HEADER_BYTES: usize = 1 << 20;
/// Elements in the header, properties per element: beyond these the header is not plausible.
const MAX_ELEMENTS: usize = 64;
const MAX_PROPERTIES: usize = 1024;

/// How a PLY file's body is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// `format ascii 1.0`.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

impl Encoding {
    pub(super) fn name(self) -> &'static str {
        match self {
            Encoding::Ascii => "ascii",
            Encoding::BinaryLittleEndian => "binary_little_endian",
            Encoding::BinaryBigEndian => "binary_big_endian",
        }
    }
}

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Scalar {
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
    pub(super) fn parse(name: &str) -> Option<Scalar> {
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

    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    pub(super) fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Decodes one value from the start of `b` (at least `size()` bytes).
    pub(super) fn decode(self, b: &[u8], big: bool) -> f64 {
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
pub(super) enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
pub(super) struct Property {
    pub(super) name: String,
    pub(super) kind: Kind,
}

#[derive(Debug, Clone)]
pub(super) struct Element {
    pub(super) name: String,
    pub(super) count: u64,
    pub(super) properties: Vec<Property>,
}

impl Element {
    /// Bytes per record when no property is a list.
    pub(super) fn fixed_size(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(s) => Some(s.size()),
                Kind::List { .. } => None,
            })
            .sum()
    }

    /// The fewest bytes one record can take in this encoding (lists may be empty).
    pub(super) fn min_size(&self, encoding: Encoding) -> usize {
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
pub(super) struct Header {
    pub(super) encoding: Encoding,
    pub(super) elements: Vec<Element>,
    /// Header length in bytes, where the body starts.
    pub(super) len: u64,
    /// Header lines, so ASCII line numbers continue from here.
    pub(super) lines: u64,
    /// `comment` and `obj_info` lines, shown in the format details.
    pub(super) comments: Vec<String>,
}

/// Where the vertex fields the cloud needs sit in a record.
#[derive(Debug, Clone, Copy)]
pub(super) struct Layout {
    pub(super) xyz: [usize; 3],
    pub(super) scan: Option<usize>,
    pub(super) time: Option<usize>,
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
pub(super) fn read_header(reader: &mut impl BufRead, path: &Path) -> Result<Header, ReadError> {
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

/// The `vertex` element, its index among the header's elements and its layout (with the time
/// only when `keep_time` asks for it), once the counts are known to fit in a file of
/// `file_len` bytes.
pub(super) fn vertices<'h>(
    header: &'h Header,
    file_len: u64,
    path: &Path,
    keep_time: bool,
) -> Result<(usize, &'h Element, Layout), ReadError> {
    let (vertex_pos, vertex) = header
        .elements
        .iter()
        .enumerate()
        .find(|(_, e)| e.name == "vertex")
        .ok_or_else(|| invalid(path, "the header declares no `vertex` element", None))?;
    let layout = layout(vertex, path, keep_time)?;
    check_counts(header, vertex_pos, file_len, path)?;
    Ok((vertex_pos, vertex, layout))
}

/// Finds x, y, z and the optional scan and time properties of the vertex element. Without
/// `keep_time` a time property is left unread, as any other property the cloud does not hold.
pub(super) fn layout(vertex: &Element, path: &Path, keep_time: bool) -> Result<Layout, ReadError> {
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
        scan: super::SCAN_NAMES.iter().find_map(|n| find(n)),
        time: find("time").filter(|_| keep_time),
    })
}

/// Rejects counts the file cannot hold, before anything is allocated.
pub(super) fn check_counts(
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

pub(super) fn describe(header: &Header, vertex: &Element) -> String {
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
