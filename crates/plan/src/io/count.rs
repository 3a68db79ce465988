//! How many points a cloud file declares, found without reading the points: from the header,
//! parsed by the format's own reader code (PLY, LAS/LAZ, E57), or by counting lines (XYZ/PTS).
//! A caller with a point limit checks it before the reader allocates a cloud, so an over-limit
//! file fails fast instead of exhausting memory.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use super::detect::{self, Format};
use crate::cancel::{Cancel, Cancelled};

/// Text read between cancellation checks while counting lines.
const TEXT_STEP: u64 = 8 << 20;

/// The number of points `path` declares, or `None` when its header cannot tell (the reader
/// then reports any damage itself, and the caller checks its limit after reading). `cancel`
/// is checked now and then during a long line count.
pub fn declared_points(path: &Path, cancel: &Cancel) -> Result<Option<u64>, Cancelled> {
    let Ok(mut file) = File::open(path) else {
        return Ok(None);
    };
    let Ok(len) = file.metadata().map(|m| m.len()) else {
        return Ok(None);
    };
    let mut head = Vec::with_capacity(detect::SNIFF_LEN);
    if (&mut file)
        .take(detect::SNIFF_LEN as u64)
        .read_to_end(&mut head)
        .and_then(|_| file.seek(SeekFrom::Start(0)))
        .is_err()
    {
        return Ok(None);
    }
    Ok(match detect::detect(&head) {
        Ok(Format::Ply) => super::ply::declared_vertices(BufReader::new(file)),
        Ok(Format::Las | Format::Laz) => super::las::declared_points(&mut file),
        Ok(Format::E57) => super::e57::declared_points(BufReader::new(file), len),
        Ok(Format::Xyz | Format::Pts) => return text_points(file, cancel),
        Err(_) => None,
    })
}

/// The number of points a cloud's first bytes declare (PLY and LAS/LAZ headers), for a caller
/// that has only the start of the file (the service, while the upload arrives). `None` for other
/// formats and for a head that does not hold the whole header.
pub fn declared_points_in_head(head: &[u8]) -> Option<u64> {
    match detect::detect(head) {
        Ok(Format::Ply) => super::ply::declared_vertices(head),
        Ok(Format::Las | Format::Laz) => super::las::declared_points(&mut &head[..]),
        _ => None,
    }
}

/// Lines that hold a point: at least three fields, the first a number. Comments, column names
/// and PTS count lines do not count.
fn text_points(file: File, cancel: &Cancel) -> Result<Option<u64>, Cancelled> {
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
            cancel.check()?;
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

#[cfg(test)]
mod tests {
    use super::*;

    fn count(bytes: &[u8]) -> Option<u64> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cloud");
        std::fs::write(&path, bytes).unwrap();
        declared_points(&path, &Cancel::never()).unwrap()
    }

    /// Files from the project's own writers declare exactly the points written.
    #[test]
    fn every_format_declares_its_points() {
        use crate::io::{export, ply};
        let world: Vec<[f64; 3]> = (0..1000)
            .map(|i| [i as f64 * 0.01, (i % 7) as f64, (i % 3) as f64])
            .collect();
        let cloud = crate::cloud::PointCloud::from_world(&world);
        let dir = tempfile::tempdir().unwrap();
        let at = |name: &str| dir.path().join(name);
        ply::write_ply(&at("a.ply"), &cloud, ply::Encoding::BinaryLittleEndian).unwrap();
        ply::write_ply(&at("b.ply"), &cloud, ply::Encoding::Ascii).unwrap();
        export::write_las(&at("a.las"), &cloud, false).unwrap();
        export::write_las(&at("a.laz"), &cloud, true).unwrap();
        export::write_e57(&at("a.e57"), &cloud).unwrap();
        export::write_xyz(&at("a.xyz"), &cloud).unwrap();
        for name in ["a.ply", "b.ply", "a.las", "a.laz", "a.e57", "a.xyz"] {
            let n = declared_points(&at(name), &Cancel::never());
            assert_eq!(n, Ok(Some(1000)), "{name}");
        }
        // The headers tell from the file's first bytes; E57 (its XML is last) and text do not.
        for (name, declared) in [
            ("a.ply", Some(1000)),
            ("b.ply", Some(1000)),
            ("a.las", Some(1000)),
            ("a.laz", Some(1000)),
            ("a.e57", None),
            ("a.xyz", None),
        ] {
            let bytes = std::fs::read(at(name)).unwrap();
            let head = &bytes[..bytes.len().min(4096)];
            assert_eq!(declared_points_in_head(head), declared, "{name}");
        }
        let ply = std::fs::read(at("a.ply")).unwrap();
        assert_eq!(declared_points_in_head(&ply[..30]), None);
    }

    #[test]
    fn ply_headers_declare_their_vertices() {
        let ply = b"ply\nformat binary_little_endian 1.0\ncomment x\nelement vertex 4000000000\n\
                    property float x\nproperty float y\nproperty float z\nend_header\n";
        assert_eq!(count(ply), Some(4_000_000_000));
        assert_eq!(count(b"ply\nformat ascii 1.0\nend_header\n"), None);
    }

    #[test]
    fn las_headers_declare_their_points() {
        let mut las = Vec::new();
        let cloud = crate::cloud::PointCloud::from_world(&[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.las");
        crate::io::export::write_las(&path, &cloud, false).unwrap();
        las.extend(std::fs::read(&path).unwrap());
        // The legacy 32-bit count at byte 107; the reader's header code reads it.
        las[107..111].copy_from_slice(&123u32.to_le_bytes());
        assert_eq!(count(&las), Some(123));
        assert_eq!(count(&las[..60]), None);
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
        let stop = Cancel::new();
        stop.cancel();
        assert_eq!(declared_points(&path, &stop), Err(Cancelled::ByCaller));
        assert_eq!(declared_points(&path, &Cancel::never()), Ok(Some(1 << 20)));
    }
}
