//! Recognising a cloud's format from its first bytes, before storing it.

use bytes::{Bytes, BytesMut};
use futures_util::StreamExt;

use crate::errors::{ApiError, Code};
use crate::storage::ByteStream;

/// Bytes looked at to recognise a format.
const HEAD: usize = 1024;

/// The format of a file starting with `head`, if asbuilt reads it.
pub fn detect(head: &[u8]) -> Option<&'static str> {
    if head.starts_with(b"ply\n") || head.starts_with(b"ply\r\n") {
        return Some("ply");
    }
    if head.starts_with(b"ASTM-E57") {
        return Some("e57");
    }
    if head.starts_with(b"LASF") {
        return Some("las");
    }
    // Text: the first data line (after `#` or `//` comments) holds three or more numbers, or a
    // point count (PTS) followed by such a line.
    let text: &[u8] = match head.iter().position(|&b| b == 0) {
        Some(_) => return None,
        None => head,
    };
    let text = std::str::from_utf8(text)
        .or_else(|e| std::str::from_utf8(&text[..e.valid_up_to()]))
        .ok()?;
    let mut lines = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#') && !l.starts_with("//"));
    let numbers = |l: &str| -> Option<usize> {
        let fields: Vec<&str> = l
            .split(|c: char| c.is_whitespace() || c == ',' || c == ';')
            .filter(|f| !f.is_empty())
            .collect();
        fields
            .iter()
            .all(|f| f.parse::<f64>().is_ok_and(f64::is_finite))
            .then_some(fields.len())
    };
    match numbers(lines.next()?)? {
        n if n >= 3 => Some("xyz"),
        1 => match lines.next().and_then(numbers) {
            Some(n) if n >= 3 => Some("pts"),
            _ => None,
        },
        _ => None,
    }
}

/// Reads the start of `body`, recognises the format, and returns a stream of the whole body.
pub async fn sniff(mut body: ByteStream<'_>) -> Result<(&'static str, ByteStream<'_>), ApiError> {
    let mut head = BytesMut::new();
    let mut chunks: Vec<Bytes> = vec![];
    while head.len() < HEAD {
        match body.next().await {
            None => break,
            Some(Ok(chunk)) => {
                head.extend_from_slice(&chunk);
                chunks.push(chunk);
            }
            Some(Err(e)) => {
                return Err(ApiError::new(
                    Code::InvalidRequest,
                    format!("the upload was interrupted: {e}"),
                ))
            }
        }
    }
    if head.is_empty() {
        return Err(ApiError::new(Code::MissingCloud, "the cloud is empty"));
    }
    let format = detect(&head).ok_or_else(|| {
        ApiError::new(
            Code::UnsupportedFormat,
            "the upload is not a point cloud asbuilt reads: PLY, E57, LAS/LAZ, XYZ or PTS",
        )
    })?;
    let start = futures_util::stream::iter(chunks.into_iter().map(Ok));
    Ok((format, start.chain(body).boxed()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_by_content() {
        assert_eq!(
            detect(b"ply\nformat binary_little_endian 1.0\n"),
            Some("ply")
        );
        assert_eq!(detect(b"ASTM-E57\0\0\0"), Some("e57"));
        assert_eq!(detect(b"LASF\x00\x00"), Some("las"));
        assert_eq!(detect(b"# x y z\n1.0 2.0 3.5\n4 5 6\n"), Some("xyz"));
        assert_eq!(detect(b"1,2,3,200\n"), Some("xyz"));
        assert_eq!(detect(b"2\n1 2 3 0 9 9 9\n4 5 6 0 9 9 9\n"), Some("pts"));
        assert_eq!(detect(b"\x89PNG\r\n\x1a\n\0\0"), None);
        assert_eq!(detect(b"hello world, this is text\n"), None);
        assert_eq!(detect(b"1 2\n"), None);
        assert_eq!(detect(b"{\"type\": \"FeatureCollection\"}"), None);
        assert_eq!(detect(b"nan nan nan\n"), None);
    }
}
