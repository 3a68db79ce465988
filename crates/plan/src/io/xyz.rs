//! PTS and XYZ text: one point a line, `x y z` then anything, separated by whitespace, commas
//! or semicolons. An optional header line; PTS count lines (one per scan block); a chosen
//! column as the scan index. Errors give the line number.

use std::io::{BufRead, Read};

use rayon::prelude::*;

use super::assemble::CloudBuilder;
use super::{Format, ReadError, ReadOptions};
use crate::cloud::PointCloud;

/// Longer lines are not points; the limit also stops a file without newlines from filling memory.
pub const MAX_LINE: usize = 64 * 1024;

/// Text read per thread at a time by the parallel reader.
const BLOCK_PER_THREAD: usize = 4 << 20;

/// Reads PTS or XYZ text. `len` is the file's size, for reserving the point array. Blocks of
/// lines are parsed in parallel when the readers' pool has more than one thread.
pub fn read_xyz<R: BufRead + Send>(
    mut input: R,
    len: u64,
    name: &str,
    format: Format,
    options: &ReadOptions,
) -> Result<PointCloud, ReadError> {
    let threads = super::pool::threads();
    let mut parser = Parser::new(len, name, format, options);
    if threads > 1 {
        let split = Split {
            block: BLOCK_PER_THREAD * threads,
            parts: threads,
        };
        super::pool::install(|| parser.run_split(input, split))?;
    } else {
        parser.run(&mut input, false)?;
    }
    parser.finish()
}

/// How the parallel reader cuts the text: `block` bytes read at a time (whole lines), each
/// block parsed in `parts` pieces.
#[derive(Debug, Clone, Copy)]
struct Split {
    block: usize,
    parts: usize,
}

/// The reader's state between lines: everything the serial read knows.
struct Parser<'a> {
    name: &'a str,
    fname: &'static str,
    pts: bool,
    len: u64,
    scan_column: Option<usize>,
    b: CloudBuilder,
    line: Vec<u8>,
    spans: Vec<(usize, usize)>,
    state: State,
    line_no: u64,
    bytes_read: u64,
    options: &'a ReadOptions,
}

impl<'a> Parser<'a> {
    fn new(len: u64, name: &'a str, format: Format, options: &'a ReadOptions) -> Parser<'a> {
        Parser {
            name,
            fname: format.name(),
            pts: format == Format::Pts,
            len,
            scan_column: options.scan_column,
            b: CloudBuilder::new(format.name(), 0, None, false),
            line: Vec::with_capacity(256),
            spans: Vec::with_capacity(16),
            state: State::default(),
            line_no: 0,
            bytes_read: 0,
            options,
        }
    }

    /// Reads lines until the input ends or, with `until_origin`, until a point has fixed the
    /// local frame.
    fn run<R: BufRead>(&mut self, input: &mut R, until_origin: bool) -> Result<(), ReadError> {
        loop {
            if until_origin && self.b.has_origin() {
                return Ok(());
            }
            self.line.clear();
            let n = input
                .by_ref()
                .take(MAX_LINE as u64 + 1)
                .read_until(b'\n', &mut self.line)
                .map_err(|e| ReadError::io(self.name, e))?;
            if n == 0 {
                return Ok(());
            }
            self.take_line(n)?;
        }
    }

    /// One line of `n` bytes, in `self.line`.
    fn take_line(&mut self, n: usize) -> Result<(), ReadError> {
        let (name, fname, len, pts) = (self.name, self.fname, self.len, self.pts);
        let b = &mut self.b;
        let state = &mut self.state;
        let line = &self.line;
        self.line_no += 1;
        self.bytes_read += n as u64;
        let line_no = self.line_no;
        if n > MAX_LINE && line.last() != Some(&b'\n') {
            return Err(ReadError::at(
                name,
                fname,
                format!("a line longer than {MAX_LINE} bytes; this is not point text"),
                format!("line {line_no}"),
            ));
        }
        split_fields(line, &mut self.spans);
        let fields = Fields {
            line,
            spans: &self.spans,
        };
        if fields.is_empty() || fields.at(0).starts_with(b"#") || fields.at(0).starts_with(b"//") {
            return Ok(());
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
            return Ok(());
        }
        let parsed = parse_point(&fields, self.scan_column);
        let (p, scan) = match parsed {
            Ok(v) => v,
            // The first content line may be a header such as `x,y,z,scan`.
            Err(_)
                if !state.seen_content && (0..fields.len()).any(|i| !is_number(fields.at(i))) =>
            {
                state.seen_content = true;
                state.header = Some(String::from_utf8_lossy(line).trim().to_string());
                return Ok(());
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
        Ok(())
    }

    /// The scan id points without a scan column take: their PTS block's.
    fn block_scan(&self) -> Option<u32> {
        match (self.scan_column, self.state.block_slot) {
            (None, Some(_)) => Some(self.state.blocks - 1),
            _ => None,
        }
    }

    /// Reads the whole input a block of lines at a time, each block parsed in parallel pieces
    /// whose points are appended in order; exactly the serial read's points and errors. A piece
    /// is parsed ahead only as far as its lines are plain points (or blank, or comments); the
    /// rest of it, and any piece that would not fit the state the lines before it left (a PTS
    /// block's count, scan slots), is read here by the serial code.
    fn run_split<R: BufRead>(&mut self, mut input: R, split: Split) -> Result<(), ReadError> {
        let block = split.block.max(1);
        let mut buf: Vec<u8> = Vec::new();
        let mut end_of_input = false;
        while !end_of_input {
            // Fill the block; keep reading while it holds no whole line, up to a line too long.
            let mut failed = None;
            loop {
                let have = buf.len();
                buf.resize(have + block, 0);
                let mut got = 0;
                while have + got < buf.len() {
                    match input.read(&mut buf[have + got..]) {
                        Ok(0) => {
                            end_of_input = true;
                            break;
                        }
                        Ok(k) => got += k,
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                        Err(e) => {
                            failed = Some(e);
                            break;
                        }
                    }
                }
                buf.truncate(have + got);
                let whole = buf.contains(&b'\n');
                if end_of_input || failed.is_some() || whole || buf.len() > MAX_LINE {
                    break;
                }
            }
            // Whole lines only, unless the input ended or no line fits in `MAX_LINE`.
            let cut = match memrchr_newline(&buf) {
                _ if end_of_input => buf.len(),
                Some(i) => i + 1,
                None if failed.is_none() => buf.len(),
                None => 0,
            };
            self.lines_split(&buf[..cut], split.parts)?;
            if let Some(e) = failed {
                return Err(ReadError::io(self.name, e));
            }
            buf.drain(..cut);
        }
        Ok(())
    }

    /// Parses `text` (whole lines, or the input's end) in `parts` pieces.
    fn lines_split(&mut self, text: &[u8], parts: usize) -> Result<(), ReadError> {
        let mut rest = text;
        // The first finite point fixes the local frame every piece needs.
        if !self.b.has_origin() {
            self.run(&mut rest, true)?;
        }
        if rest.is_empty() {
            return Ok(());
        }
        let pieces = cut_lines(rest, parts.max(1));
        let (pts, scan_column, block_scan) = (self.pts, self.scan_column, self.block_scan());
        let b = &self.b;
        let parsed: Vec<Part> = pieces
            .par_iter()
            .map(|piece| Part::parse(piece, b, pts, scan_column, block_scan))
            .collect();
        for (piece, part) in pieces.iter().zip(&parsed) {
            let mut tail: &[u8] = piece;
            if self.accept(part) {
                tail = &piece[part.bytes..];
            }
            self.run(&mut tail, false)?;
        }
        Ok(())
    }

    /// Appends a piece's points when the state the lines before it left is the one it was
    /// parsed for; false, with nothing appended, otherwise.
    fn accept(&mut self, part: &Part) -> bool {
        if part.block_scan != self.block_scan() {
            return false;
        }
        if let Some(block) = &self.state.block {
            if block.seen.saturating_add(part.points) > block.count {
                return false;
            }
        }
        // On error nothing is appended; the scans it gave slots are given them, in the same
        // order, by the serial read of the piece too.
        if self.b.absorb(&part.b).is_err() {
            return false;
        }
        if let Some(block) = &mut self.state.block {
            block.seen += part.points;
        }
        self.state.seen_content |= part.points > 0;
        self.line_no += part.lines;
        self.bytes_read += part.bytes as u64;
        true
    }

    fn finish(mut self) -> Result<PointCloud, ReadError> {
        let (name, fname) = (self.name, self.fname);
        if self.line_no == 0 {
            return Err(ReadError::named(name, fname, "the file is empty"));
        }
        self.state.close_block(name, fname)?;
        if self.pts && self.state.blocks < 2 && self.options.scan_column.is_none() {
            // One block is one unnamed scan: no scan index worth keeping.
            let c = self.b.cloud_mut();
            c.scan = Vec::new();
            c.scan_ids.clear();
        }
        let details = describe(&self.state, self.options, self.line_no, self.bytes_read);
        Ok(self.b.finish(details))
    }
}

/// The plain point lines at the start of a piece, parsed on their own thread.
struct Part {
    b: CloudBuilder,
    /// Point lines taken (non-finite ones included, as PTS counts them).
    points: u64,
    lines: u64,
    /// Bytes of the lines taken; the serial code reads on from there.
    bytes: usize,
    /// The PTS block's scan the points were given, when there is no scan column.
    block_scan: Option<u32>,
}

impl Part {
    fn parse(
        piece: &[u8],
        base: &CloudBuilder,
        pts: bool,
        scan_column: Option<usize>,
        block_scan: Option<u32>,
    ) -> Part {
        let mut part = Part {
            b: base.part(piece.len() / 24),
            points: 0,
            lines: 0,
            bytes: 0,
            block_scan,
        };
        let mut spans = Vec::with_capacity(16);
        let mut pos = 0;
        while pos < piece.len() {
            let end = piece[pos..]
                .iter()
                .position(|&c| c == b'\n')
                .map_or(piece.len(), |i| pos + i + 1);
            let line = &piece[pos..end];
            if line.len() > MAX_LINE {
                break;
            }
            split_fields(line, &mut spans);
            let fields = Fields {
                line,
                spans: &spans,
            };
            let blank = fields.is_empty()
                || fields.at(0).starts_with(b"#")
                || fields.at(0).starts_with(b"//");
            if !blank {
                if pts && fields.len() == 1 {
                    break;
                }
                let Ok((p, scan)) = parse_point(&fields, scan_column) else {
                    break;
                };
                let slot = match scan.or(block_scan) {
                    Some(id) => match part.b.scan_slot(id) {
                        Ok(slot) => Some(slot),
                        Err(_) => break,
                    },
                    None => None,
                };
                part.b.push(p, slot, None);
                part.points += 1;
            }
            part.lines += 1;
            pos = end;
        }
        part.bytes = pos;
        part
    }
}

/// Cuts whole lines into about `parts` pieces of similar size.
pub(super) fn cut_lines(text: &[u8], parts: usize) -> Vec<&[u8]> {
    let mut pieces = Vec::with_capacity(parts);
    let mut start = 0;
    for k in 1..parts {
        let target = (text.len() * k / parts).max(start);
        let Some(i) = text[target..].iter().position(|&c| c == b'\n') else {
            break;
        };
        let end = target + i + 1;
        pieces.push(&text[start..end]);
        start = end;
    }
    if start < text.len() {
        pieces.push(&text[start..]);
    }
    pieces
}

/// The index of the last newline.
fn memrchr_newline(text: &[u8]) -> Option<usize> {
    text.iter().rposition(|&c| c == b'\n')
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

    /// Reads `text` serially and in parallel pieces of every given split; the clouds, or the
    /// errors, must be the same.
    fn same_split(text: &str, format: Format, scan_column: Option<usize>) {
        let opts = ReadOptions {
            scan_column,
            ..Default::default()
        };
        let len = text.len() as u64;
        let finish = |p: Parser| p.finish();
        let serial = {
            let mut p = Parser::new(len, "t.txt", format, &opts);
            p.run(&mut text.as_bytes(), false).and_then(|()| finish(p))
        };
        let splits = [
            (1, 2),
            (7, 3),
            (40, 2),
            (64, 5),
            (1_000, 3),
            (1 << 20, 2),
            (1 << 20, 1),
        ];
        for (block, parts) in splits {
            let mut p = Parser::new(len, "t.txt", format, &opts);
            let parallel = p
                .run_split(text.as_bytes(), Split { block, parts })
                .and_then(|()| finish(p));
            match (&serial, &parallel) {
                (Ok(a), Ok(b)) => {
                    let bits = |c: &PointCloud| -> Vec<[u32; 3]> {
                        c.xyz.iter().map(|p| p.map(f32::to_bits)).collect()
                    };
                    assert!(bits(a) == bits(b), "points differ at split {block}/{parts}");
                    assert_eq!(a.scan, b.scan, "split {block}/{parts}");
                    assert_eq!(a.scan_ids, b.scan_ids);
                    assert_eq!(a.origin, b.origin);
                    assert_eq!(a.source, b.source);
                }
                (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string()),
                _ => panic!("split {block}/{parts}: {serial:?} vs {parallel:?}"),
            }
        }
    }

    /// `n` lines of `x y z scan`, with far coordinates, comments, blanks and non-finite values.
    fn lines(n: usize, scans: u32) -> String {
        let mut t = String::from("x y z scan\n");
        for i in 0..n {
            let f = i as f64;
            match i % 97 {
                5 => t += "# a comment\n",
                9 => t += "\r\n",
                13 => t += "nan 1 2 0\n",
                _ => {}
            }
            let scan = (i / 31) as u32 % scans;
            t += &format!(
                "{} {:.3} {} {scan}\n",
                500_000.0 + f * 0.01,
                (f * 0.37).sin(),
                2.5
            );
        }
        t
    }

    #[test]
    fn parallel_pieces_read_exactly_the_serial_points() {
        let text = lines(3_001, 5);
        same_split(&text, Format::Xyz, Some(3));
        same_split(&text, Format::Xyz, None);
        // No newline at the end.
        same_split(text.trim_end(), Format::Xyz, Some(3));
        // PTS blocks, one and several.
        let block = |n: usize, from: usize| -> String {
            let mut t = format!("{n}\n");
            for i in from..from + n {
                t += &format!("{} {} 3 10 1 2 3\n", i as f64 * 0.5, 7);
            }
            t
        };
        same_split(&block(500, 0), Format::Pts, None);
        let several = block(500, 0) + &block(1, 500) + &block(1_200, 501) + &block(3, 2_000);
        same_split(&several, Format::Pts, None);
        same_split(&several, Format::Pts, Some(3));
    }

    #[test]
    fn parallel_pieces_fail_as_the_serial_read_does() {
        let text = lines(2_000, 3);
        // A bad number, a short line and a missing scan column late in the file.
        let at = text.len() * 3 / 4;
        let cut = at + text[at..].find('\n').unwrap() + 1;
        for bad in ["1 two 3 0\n", "1 2\n", "1 2 3\n", "1 2 3 -4\n"] {
            let broken = format!("{}{bad}{}", &text[..cut], &text[cut..]);
            same_split(&broken, Format::Xyz, Some(3));
        }
        // A line too long, in the middle and at the end without a newline.
        let long = "1".repeat(MAX_LINE + 10);
        same_split(
            &format!("{}{long}\n{}", &text[..cut], &text[cut..]),
            Format::Xyz,
            None,
        );
        same_split(&format!("{text}{long}"), Format::Xyz, None);
        // A line of exactly the longest length is not refused.
        let longest = format!("1 2 3 {}\n", "4".repeat(MAX_LINE - 6));
        same_split(&format!("{text}{longest}{text}"), Format::Xyz, None);
        // PTS blocks with more and fewer points than their count lines say.
        let pts = |count: usize, n: usize| -> String {
            let mut t = String::from("3\n1 2 3\n4 5 6\n7 8 9\n");
            t += &format!("{count}\n");
            for i in 0..n {
                t += &format!("{i} 1 2\n");
            }
            t + "2\n1 1 1\n2 2 2\n"
        };
        same_split(&pts(300, 301), Format::Pts, None);
        same_split(&pts(300, 299), Format::Pts, None);
        same_split(&pts(300, 300), Format::Pts, None);
        // More distinct scans than slots.
        let mut many = String::new();
        for i in 0..(crate::io::assemble::MAX_SCANS + 5) {
            many += &format!("1 2 3 {i}\n");
        }
        same_split(&many, Format::Xyz, Some(3));
        same_split("", Format::Xyz, None);
        same_split("\n\n# only comments\n", Format::Xyz, None);
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
