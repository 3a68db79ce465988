//! How many points a cloud file holds, found without reading the points: from the header (PLY,
//! LAS/LAZ, E57) or by counting lines (XYZ/PTS). The point-count limit is checked with it before
//! the reader allocates a cloud, so an over-limit file fails fast instead of exhausting memory.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use asbuilt_plan::io::detect::{self, Format};

/// Bytes of a PLY header looked at; a longer header is left to the reader.
const PLY_HEADER_MAX: u64 = 64 << 10;

/// The largest E57 XML section parsed here; a larger one is left to the reader.
const E57_XML_MAX: u64 = 64 << 20;

/// Text read between cancellation checks while counting lines.
const TEXT_STEP: u64 = 8 << 20;

/// Why counting stopped early.
#[derive(Debug, PartialEq, Eq)]
pub enum CountStop {
    /// `cancelled` said so.
    Cancelled,
}

/// The number of points `path` declares, or `None` when its header cannot tell (the reader
/// then checks the limit after reading, and reports any damage itself). `cancelled` is asked
/// now and then during a long line count.
pub fn declared(path: &Path, cancelled: &dyn Fn() -> bool) -> Result<Option<u64>, CountStop> {
    let Ok(mut file) = File::open(path) else {
        return Ok(None);
    };
    let mut head = Vec::with_capacity(detect::SNIFF_LEN);
    if (&mut file)
        .take(detect::SNIFF_LEN as u64)
        .read_to_end(&mut head)
        .is_err()
    {
        return Ok(None);
    }
    Ok(match detect::detect(&head) {
        Ok(Format::Ply) => ply_vertices(&mut file),
        Ok(Format::Las | Format::Laz) => las_points(&mut file),
        Ok(Format::E57) => e57_points(file),
        Ok(Format::Xyz | Format::Pts) => return text_points(file, cancelled),
        Err(_) => None,
    })
}

/// `element vertex N` from the ASCII header.
fn ply_vertices(file: &mut File) -> Option<u64> {
    file.seek(SeekFrom::Start(0)).ok()?;
    let reader = BufReader::new(file.take(PLY_HEADER_MAX));
    for line in reader.split(b'\n') {
        let line = line.ok()?;
        let line = String::from_utf8_lossy(&line);
        let mut words = line.split_whitespace();
        match (words.next(), words.next(), words.next()) {
            (Some("element"), Some("vertex"), Some(n)) => return n.parse().ok(),
            (Some("end_header"), _, _) => return None,
            _ => {}
        }
    }
    None
}

/// The public header's point count: the legacy 32-bit field, or from LAS 1.4 the 64-bit one.
fn las_points(file: &mut File) -> Option<u64> {
    let mut h = [0u8; 255];
    file.seek(SeekFrom::Start(0)).ok()?;
    let n = read_up_to(file, &mut h)?;
    if n < 111 {
        return None;
    }
    let legacy = u32::from_le_bytes([h[107], h[108], h[109], h[110]]) as u64;
    let (major, minor) = (h[24], h[25]);
    if (major, minor) >= (1, 4) && n >= 255 {
        let mut b = [0u8; 8];
        b.copy_from_slice(&h[247..255]);
        return Some(legacy.max(u64::from_le_bytes(b)));
    }
    Some(legacy)
}

/// The sum of every scan's record count, from the XML section (through the `e57` crate).
fn e57_points(mut file: File) -> Option<u64> {
    let len = file.metadata().ok()?.len();
    let mut h = [0u8; 48];
    file.seek(SeekFrom::Start(0)).ok()?;
    file.read_exact(&mut h).ok()?;
    let u64_at = |o: usize| u64::from_le_bytes(h[o..o + 8].try_into().expect("8 bytes"));
    let (xml_at, xml_len) = (u64_at(24), u64_at(32));
    // The crate reads the XML whole: only let it when the header's sizes are believable.
    if xml_len > E57_XML_MAX || xml_at.checked_add(xml_len).is_none_or(|end| end > len) {
        return None;
    }
    file.seek(SeekFrom::Start(0)).ok()?;
    let reader = e57::E57Reader::new(BufReader::new(file)).ok()?;
    Some(reader.pointclouds().iter().map(|pc| pc.records).sum())
}

/// Lines that hold a point: at least three fields, the first a number. Comments, column names
/// and PTS count lines do not count.
fn text_points(mut file: File, cancelled: &dyn Fn() -> bool) -> Result<Option<u64>, CountStop> {
    if file.seek(SeekFrom::Start(0)).is_err() {
        return Ok(None);
    }
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let mut line = Vec::new();
    let (mut points, mut read, mut next_check) = (0u64, 0u64, TEXT_STEP);
    loop {
        line.clear();
        match reader.read_until(b'\n', &mut line) {
            Ok(0) => return Ok(Some(points)),
            Err(_) => return Ok(None),
            Ok(n) => read += n as u64,
        }
        if holds_point(&line) {
            points += 1;
        }
        if read >= next_check {
            next_check += TEXT_STEP;
            if cancelled() {
                return Err(CountStop::Cancelled);
            }
        }
    }
}

fn holds_point(line: &[u8]) -> bool {
    let sep = |b: &u8| b.is_ascii_whitespace() || *b == b',' || *b == b';';
    let mut fields = line.split(sep).filter(|f| !f.is_empty());
    let starts_numeric = fields
        .next()
        .is_some_and(|f| matches!(f[0], b'0'..=b'9' | b'-' | b'+' | b'.'));
    starts_numeric && fields.nth(1).is_some()
}

fn read_up_to(file: &mut File, buf: &mut [u8]) -> Option<usize> {
    let mut n = 0;
    while n < buf.len() {
        match file.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(_) => return None,
        }
    }
    Some(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn count(bytes: &[u8]) -> Option<u64> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cloud");
        std::fs::write(&path, bytes).unwrap();
        declared(&path, &|| false).unwrap()
    }

    /// Files from the project's own writers declare exactly the points written.
    #[test]
    fn every_format_declares_its_points() {
        use asbuilt_plan::io::{export, ply};
        let world: Vec<[f64; 3]> = (0..1000)
            .map(|i| [i as f64 * 0.01, (i % 7) as f64, (i % 3) as f64])
            .collect();
        let cloud = asbuilt_plan::cloud::PointCloud::from_world(&world);
        let dir = tempfile::tempdir().unwrap();
        let at = |name: &str| dir.path().join(name);
        ply::write_ply(&at("a.ply"), &cloud, ply::Encoding::BinaryLittleEndian).unwrap();
        export::write_las(&at("a.las"), &cloud, false).unwrap();
        export::write_las(&at("a.laz"), &cloud, true).unwrap();
        export::write_e57(&at("a.e57"), &cloud).unwrap();
        export::write_xyz(&at("a.xyz"), &cloud).unwrap();
        for name in ["a.ply", "a.las", "a.laz", "a.e57", "a.xyz"] {
            assert_eq!(declared(&at(name), &|| false), Ok(Some(1000)), "{name}");
        }
    }

    #[test]
    fn ply_headers_declare_their_vertices() {
        let ply = b"ply\nformat binary_little_endian 1.0\ncomment x\nelement vertex 4000000000\n\
                    property float x\nend_header\n";
        assert_eq!(count(ply), Some(4_000_000_000));
        assert_eq!(count(b"ply\nformat ascii 1.0\nend_header\n"), None);
    }

    #[test]
    fn las_headers_declare_their_points() {
        let mut h = vec![0u8; 375];
        h[..4].copy_from_slice(b"LASF");
        h[24] = 1;
        h[25] = 2;
        h[107..111].copy_from_slice(&123u32.to_le_bytes());
        assert_eq!(count(&h), Some(123));
        // LAS 1.4 keeps large counts in the 64-bit field and zero in the legacy one.
        h[25] = 4;
        h[107..111].copy_from_slice(&0u32.to_le_bytes());
        h[247..255].copy_from_slice(&9_000_000_000u64.to_le_bytes());
        assert_eq!(count(&h), Some(9_000_000_000));
        assert_eq!(count(&h[..60]), None);
    }

    #[test]
    fn text_counts_point_lines_only() {
        let text = b"# comment\nx y z\n3\n1 2 3\n4,5,6,7\n\n-1 -2 -3\n1 2\n";
        assert_eq!(count(text), Some(3));
    }

    #[test]
    fn damaged_e57_headers_are_left_to_the_reader() {
        let mut h = vec![0u8; 48];
        h[..8].copy_from_slice(b"ASTM-E57");
        h[8] = 1;
        h[32..40].copy_from_slice(&u64::MAX.to_le_bytes());
        h[40] = 4; // page size 1024
        assert_eq!(count(&h), None);
    }

    #[test]
    fn a_long_count_stops_when_cancelled() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cloud.xyz");
        let line = b"1.0 2.0 3.0\n".repeat(1 << 20);
        std::fs::write(&path, line).unwrap();
        assert_eq!(declared(&path, &|| true), Err(CountStop::Cancelled));
        assert_eq!(declared(&path, &|| false), Ok(Some(1 << 20)));
    }
}
