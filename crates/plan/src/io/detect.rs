//! Choosing the reader from a file's first bytes, so that a wrong extension still reads.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

/// The point-cloud formats asbuilt reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// ASTM E57.
    E57,
    /// LAS.
    Las,
    /// LAZ (compressed LAS).
    Laz,
    /// PLY, ASCII or binary.
    Ply,
    /// Plain x y z text.
    Xyz,
    /// Leica PTS text.
    Pts,
}

impl Format {
    /// The short name used in reports and errors.
    pub fn name(self) -> &'static str {
        match self {
            Format::E57 => "e57",
            Format::Las => "las",
            Format::Laz => "laz",
            Format::Ply => "ply",
            Format::Xyz => "xyz",
            Format::Pts => "pts",
        }
    }

    /// The format an extension usually means, if any.
    pub fn from_extension(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        ext.parse().ok()
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Format {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "e57" => Ok(Format::E57),
            "las" => Ok(Format::Las),
            "laz" => Ok(Format::Laz),
            "ply" => Ok(Format::Ply),
            "xyz" | "txt" | "csv" => Ok(Format::Xyz),
            "pts" => Ok(Format::Pts),
            other => Err(format!(
                "unknown format `{other}` (expected e57, las, laz, ply, xyz or pts)"
            )),
        }
    }
}

/// How many leading bytes [`detect`] wants to see.
pub const SNIFF_LEN: usize = 4096;

/// Detects the format from the first bytes of a file (up to [`SNIFF_LEN`]).
/// Text that is not PLY is XYZ, or PTS when it starts with a lone point count.
pub fn detect(head: &[u8]) -> Result<Format, String> {
    if head.is_empty() {
        return Err("the file is empty".into());
    }
    if head.starts_with(b"ASTM-E57") {
        return Ok(Format::E57);
    }
    if head.starts_with(b"LASF") {
        // Byte 104 is the point data format; LASzip sets bit 7 (or bit 6) on compressed files.
        return Ok(match head.get(104) {
            Some(&id) if id & 0xC0 != 0 => Format::Laz,
            _ => Format::Las,
        });
    }
    if head.starts_with(b"ply\n") || head.starts_with(b"ply\r\n") {
        return Ok(Format::Ply);
    }
    if !looks_like_text(head) {
        let shown: Vec<String> = head.iter().take(8).map(|b| format!("{b:02x}")).collect();
        return Err(format!(
            "binary content that is not E57, LAS/LAZ or PLY (first bytes {})",
            shown.join(" ")
        ));
    }
    if !has_point_row(head) {
        return Err("text without a row of x y z numbers in its first lines".into());
    }
    Ok(if starts_with_count_line(head) {
        Format::Pts
    } else {
        Format::Xyz
    })
}

/// Point text has a row of at least three numbers among its first few lines (after an
/// optional header or count line), so prose, STL or JSON is not mistaken for a cloud.
fn has_point_row(head: &[u8]) -> bool {
    let text = String::from_utf8_lossy(head);
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .take(4)
        .any(|l| {
            let tokens: Vec<&str> = l
                .split(|c: char| c.is_whitespace() || c == ',' || c == ';')
                .filter(|t| !t.is_empty())
                .collect();
            tokens.len() >= 3 && tokens[..3].iter().all(|t| t.parse::<f64>().is_ok())
        })
}

/// Text has no NUL bytes and few control characters; a cut-off UTF-8 sequence at the end is fine.
fn looks_like_text(head: &[u8]) -> bool {
    let controls = head
        .iter()
        .filter(|&&b| b < 0x20 && !matches!(b, b'\n' | b'\r' | b'\t' | 0x0c))
        .count();
    !head.contains(&0) && controls * 100 <= head.len()
}

/// PTS files begin with a line holding only the point count.
fn starts_with_count_line(head: &[u8]) -> bool {
    let text = String::from_utf8_lossy(head);
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    let Some(first) = lines.next() else {
        return false;
    };
    let is_count = first.parse::<u64>().is_ok();
    let next_has_point = lines.next().is_some_and(|l| {
        l.split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
            .count()
            >= 3
    });
    is_count && next_has_point
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn magic_bytes_choose_the_reader() {
        assert_eq!(detect(b"ASTM-E57\x00\x00"), Ok(Format::E57));
        assert_eq!(detect(b"ply\nformat ascii 1.0\n"), Ok(Format::Ply));
        assert_eq!(detect(b"ply\r\nformat ascii 1.0\r\n"), Ok(Format::Ply));
        let mut las = b"LASF".to_vec();
        las.resize(120, 0);
        assert_eq!(detect(&las), Ok(Format::Las));
        las[104] = 0x83;
        assert_eq!(detect(&las), Ok(Format::Laz));
    }

    #[test]
    fn text_is_xyz_or_pts() {
        assert_eq!(detect(b"1.0 2.0 3.0\n4 5 6\n"), Ok(Format::Xyz));
        assert_eq!(detect(b"x,y,z\n1,2,3\n"), Ok(Format::Xyz));
        assert_eq!(
            detect(b"2\n1 2 3 10 0 0 0\n4 5 6 10 0 0 0\n"),
            Ok(Format::Pts)
        );
        // A lone number followed by something that is not a point is not a PTS count.
        assert_eq!(detect(b"2\nhello\n1 2 3\n"), Ok(Format::Xyz));
        // Text without a row of numbers is no cloud at all.
        assert!(detect(b"solid cube\nfacet normal 0 0 1\n").is_err());
    }

    #[test]
    fn empty_and_unknown_binary_are_errors() {
        assert_eq!(detect(b""), Err("the file is empty".into()));
        let err = detect(b"\x89PNG\r\n\x1a\n\0\0\0").unwrap_err();
        assert!(err.contains("89 50 4e 47"), "{err}");
    }

    #[test]
    fn names_parse_back() {
        for f in [
            Format::E57,
            Format::Las,
            Format::Laz,
            Format::Ply,
            Format::Xyz,
            Format::Pts,
        ] {
            assert_eq!(f.name().parse::<Format>(), Ok(f));
        }
        assert_eq!(
            Format::from_extension(Path::new("a/b.LAZ")),
            Some(Format::Laz)
        );
        assert!("obj".parse::<Format>().is_err());
    }
}
