//! PTS and XYZ text: one point a line, `x y z` then anything, separated by whitespace, commas
//! or semicolons. An optional header line; PTS count lines (one per scan block); a chosen
//! column as the scan index. Errors give the line number.

use std::io::{BufRead, Read};

use super::assemble::CloudBuilder;
use super::{Format, ReadError, ReadOptions};
use crate::cloud::PointCloud;

/// Longer lines are not points; the limit also stops a file without newlines from filling memory.
pub const MAX_LINE: usize = 64 * 1024;

/// Reads PTS or XYZ text. `len` is the file's size, for reserving the point array.
pub fn read_xyz<R: BufRead>(
    mut input: R,
    len: u64,
    name: &str,
    format: Format,
    options: &ReadOptions,
) -> Result<PointCloud, ReadError> {
    let fname = format.name();
    let pts = format == Format::Pts;
    let mut b = CloudBuilder::new(fname, 0, None, false);
    let mut line = Vec::with_capacity(256);
    let mut spans: Vec<(usize, usize)> = Vec::with_capacity(16);
    let mut state = State::default();
    let mut line_no = 0u64;
    let mut bytes_read = 0u64;
    loop {
        line.clear();
        let n = input
            .by_ref()
            .take(MAX_LINE as u64 + 1)
            .read_until(b'\n', &mut line)
            .map_err(|e| ReadError::io(name, e))?;
        if n == 0 {
            break;
        }
        line_no += 1;
        bytes_read += n as u64;
        if n > MAX_LINE && line.last() != Some(&b'\n') {
            return Err(ReadError::at(
                name,
                fname,
                format!("a line longer than {MAX_LINE} bytes; this is not point text"),
                format!("line {line_no}"),
            ));
        }
        split_fields(&line, &mut spans);
        let fields = Fields {
            line: &line,
            spans: &spans,
        };
        if fields.is_empty() || fields.at(0).starts_with(b"#") || fields.at(0).starts_with(b"//") {
            continue;
        }
        if !state.reserved && !pts {
            // Reserve once, from the first line's length: untouched capacity costs no memory.
            state.reserved = true;
            b.reserve((len / n.max(6) as u64) as usize * 11 / 10);
        }
        let at = || format!("line {line_no}");
        // A lone integer starts a PTS block (a scan) and gives its point count.
        if pts && fields.len() == 1 {
            let count = parse_count(fields.at(0)).ok_or_else(|| {
                ReadError::at(name, fname, "expected a point count or x y z", at())
            })?;
            if count.saturating_mul(6) > len {
                return Err(ReadError::at(
                    name,
                    fname,
                    format!("the count line claims {count} points, more than a {len}-byte file can hold"),
                    at(),
                ));
            }
            state.close_block(name, fname)?;
            state.block = Some(Block {
                count,
                line: line_no,
                seen: 0,
            });
            b.reserve(count as usize);
            state.blocks += 1;
            state.block_slot = Some(
                b.scan_slot(state.blocks - 1)
                    .map_err(|why| ReadError::at(name, fname, why, at()))?,
            );
            continue;
        }
        let parsed = parse_point(&fields, options.scan_column);
        let (p, scan) = match parsed {
            Ok(v) => v,
            // The first content line may be a header such as `x,y,z,scan`.
            Err(_)
                if !state.seen_content && (0..fields.len()).any(|i| !is_number(fields.at(i))) =>
            {
                state.seen_content = true;
                state.header = Some(String::from_utf8_lossy(&line).trim().to_string());
                continue;
            }
            Err(why) => return Err(ReadError::at(name, fname, why, at())),
        };
        state.seen_content = true;
        if let Some(block) = &mut state.block {
            block.seen += 1;
            if block.seen > block.count {
                return Err(ReadError::at(
                    name,
                    fname,
                    format!(
                        "more points than the count line (line {}) says ({})",
                        block.line, block.count
                    ),
                    at(),
                ));
            }
        }
        let slot = match scan {
            Some(id) => Some(
                b.scan_slot(id)
                    .map_err(|why| ReadError::at(name, fname, why, at()))?,
            ),
            None => state.block_slot,
        };
        b.push(p, slot, None);
    }
    if line_no == 0 {
        return Err(ReadError::named(name, fname, "the file is empty"));
    }
    state.close_block(name, fname)?;
    if pts && state.blocks < 2 && options.scan_column.is_none() {
        // One block is one unnamed scan: no scan index worth keeping.
        let c = b.cloud_mut();
        c.scan = Vec::new();
        c.scan_ids.clear();
    }
    let details = describe(&state, options, line_no, bytes_read);
    Ok(b.finish(details))
}

#[derive(Default)]
struct State {
    seen_content: bool,
    reserved: bool,
    header: Option<String>,
    blocks: u32,
    block_slot: Option<u16>,
    /// The PTS block being read.
    block: Option<Block>,
}

/// A PTS block: the points its count line announced, and how many have come.
struct Block {
    count: u64,
    line: u64,
    seen: u64,
}

impl State {
    /// A block that ends short of its count means a truncated or spliced file.
    fn close_block(&mut self, name: &str, fname: &'static str) -> Result<(), ReadError> {
        match self.block.take() {
            Some(b) if b.seen < b.count => Err(ReadError::at(
                name,
                fname,
                format!(
                    "the count line says {} points but {} follow: the file is truncated",
                    b.count, b.seen
                ),
                format!("line {}", b.line),
            )),
            _ => Ok(()),
        }
    }
}

fn describe(state: &State, options: &ReadOptions, lines: u64, bytes: u64) -> String {
    let mut d = format!("text, {lines} lines, {bytes} bytes");
    if let Some(h) = &state.header {
        d += &format!(", header `{}`", h.chars().take(80).collect::<String>());
    }
    if state.blocks > 0 {
        d += &format!(", {} count line(s)", state.blocks);
    }
    if let Some(c) = options.scan_column {
        d += &format!(", scan index in column {c}");
    }
    d
}

/// A line's fields, as byte ranges into it (no allocation per line).
struct Fields<'a> {
    line: &'a [u8],
    spans: &'a [(usize, usize)],
}

impl Fields<'_> {
    fn len(&self) -> usize {
        self.spans.len()
    }

    fn is_empty(&self) -> bool {
        self.spans.is_empty()
    }

    fn at(&self, i: usize) -> &[u8] {
        let (a, b) = self.spans[i];
        &self.line[a..b]
    }

    fn get(&self, i: usize) -> Option<&[u8]> {
        (i < self.len()).then(|| self.at(i))
    }
}

/// Splits on whitespace, commas and semicolons, dropping empty fields; gives byte ranges.
fn split_fields(line: &[u8], out: &mut Vec<(usize, usize)>) {
    out.clear();
    let mut start = None;
    for (i, &c) in line.iter().enumerate() {
        let sep = matches!(c, b' ' | b'\t' | b',' | b';' | b'\r' | b'\n');
        match (sep, start) {
            (false, None) => start = Some(i),
            (true, Some(s)) => {
                out.push((s, i));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((s, line.len()));
    }
}

fn parse_f64(field: &[u8]) -> Option<f64> {
    std::str::from_utf8(field).ok()?.parse().ok()
}

fn is_number(field: &[u8]) -> bool {
    parse_f64(field).is_some()
}

fn parse_count(field: &[u8]) -> Option<u64> {
    std::str::from_utf8(field).ok()?.parse().ok()
}

/// x, y, z from the first three fields and, when asked, a scan index from another.
fn parse_point(
    fields: &Fields,
    scan_column: Option<usize>,
) -> Result<([f64; 3], Option<u32>), String> {
    if fields.len() < 3 {
        return Err(format!(
            "expected at least x y z, found {} value(s)",
            fields.len()
        ));
    }
    let mut p = [0.0; 3];
    for (k, v) in p.iter_mut().enumerate() {
        let field = fields.at(k);
        *v = parse_f64(field).ok_or_else(|| {
            format!(
                "`{}` in column {k} is not a number",
                String::from_utf8_lossy(&field[..field.len().min(40)])
            )
        })?;
    }
    let scan = match scan_column {
        None => None,
        Some(c) => {
            let field = fields.get(c).ok_or_else(|| {
                format!(
                    "no column {c} for the scan index (the line has {} columns)",
                    fields.len()
                )
            })?;
            let v = parse_f64(field)
                .filter(|v| v.fract() == 0.0 && (0.0..=u32::MAX as f64).contains(v));
            Some(v.ok_or_else(|| {
                format!(
                    "scan index `{}` in column {c} is not a non-negative integer",
                    String::from_utf8_lossy(&field[..field.len().min(40)])
                )
            })? as u32)
        }
    };
    Ok((p, scan))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(
        text: &str,
        format: Format,
        scan_column: Option<usize>,
    ) -> Result<PointCloud, ReadError> {
        let opts = ReadOptions {
            scan_column,
            ..Default::default()
        };
        read_xyz(text.as_bytes(), text.len() as u64, "t.txt", format, &opts)
    }

    #[test]
    fn reads_whitespace_and_commas_with_a_header() {
        let c = read(
            "x,y,z\n1,2,3\n4.5\t5 6 extra\n\n# note\n",
            Format::Xyz,
            None,
        )
        .unwrap();
        assert_eq!(c.xyz, vec![[1.0, 2.0, 3.0], [4.5, 5.0, 6.0]]);
        assert!(
            c.source.details.contains("header `x,y,z`"),
            "{}",
            c.source.details
        );
        assert!(c.scan.is_empty());
    }

    #[test]
    fn a_chosen_column_names_the_scan() {
        let c = read("0 0 0 7\n1 1 1 9\n2 2 2 7\n", Format::Xyz, Some(3)).unwrap();
        assert_eq!(c.scan_ids, vec![7, 9]);
        assert_eq!(c.scan, vec![0, 1, 0]);
        let err = read("0 0 0 7\n1 1 1\n", Format::Xyz, Some(3)).unwrap_err();
        assert_eq!(
            err.to_string(),
            "t.txt (xyz): no column 3 for the scan index (the line has 3 columns) at line 2"
        );
    }

    #[test]
    fn pts_count_lines_start_scans() {
        let one = read("2\n1 2 3 50 1 2 3\n4 5 6 50 1 2 3\n", Format::Pts, None).unwrap();
        assert_eq!(one.len(), 2);
        assert!(one.scan_ids.is_empty(), "a single block names no scan");
        let two = read("1\n1 2 3\n2\n4 5 6\n7 8 9\n", Format::Pts, None).unwrap();
        assert_eq!(two.scan_ids, vec![0, 1]);
        assert_eq!(two.scan, vec![0, 1, 1]);
    }

    #[test]
    fn bad_lines_are_named_by_number() {
        let err = read("1 2 3\n4 five 6\n", Format::Xyz, None).unwrap_err();
        assert_eq!(
            err.to_string(),
            "t.txt (xyz): `five` in column 1 is not a number at line 2"
        );
        let err = read("1 2 3\n4 5\n", Format::Xyz, None).unwrap_err();
        assert!(
            err.to_string().contains("found 2 value(s) at line 2"),
            "{err}"
        );
        let err = read("999999999\n1 2 3\n", Format::Pts, None).unwrap_err();
        assert!(err.to_string().contains("claims 999999999 points"), "{err}");
    }

    #[test]
    fn non_finite_points_are_skipped_and_counted() {
        let c = read("1 2 3\nnan 1 1\n1 inf 1\n4 5 6\n", Format::Xyz, None).unwrap();
        assert_eq!(c.len(), 2);
        assert_eq!(c.source.skipped, 2);
    }

    #[test]
    fn endless_lines_are_refused() {
        let text = "1".repeat(MAX_LINE + 10);
        let err = read(&text, Format::Xyz, None).unwrap_err();
        assert_eq!(
            err.to_string(),
            "t.txt (xyz): a line longer than 65536 bytes; this is not point text at line 1"
        );
    }
}
