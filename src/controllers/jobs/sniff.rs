//! Recognising a cloud's format from its first bytes, before storing it. The decision is the
//! readers' own (`asbuilt_plan::io::detect`, on the same bytes), so an upload is refused here
//! exactly when the worker's reader would refuse its format.

use asbuilt_plan::io::detect::{self, Format};
use bytes::{Bytes, BytesMut};
use futures_util::StreamExt;

use crate::errors::{ApiError, Code};
use crate::storage::ByteStream;

/// The format of a file starting with `head`, if asbuilt reads it, as the upload record names
/// it (`las` covers LAZ).
pub fn detect(head: &[u8]) -> Option<&'static str> {
    let head = &head[..head.len().min(detect::SNIFF_LEN)];
    match detect::detect(head).ok()? {
        Format::Las | Format::Laz => Some("las"),
        f => Some(f.name()),
    }
}

/// Reads the start of `body`, recognises the format, and returns a stream of the whole body.
pub async fn sniff(mut body: ByteStream<'_>) -> Result<(&'static str, ByteStream<'_>), ApiError> {
    let mut head = BytesMut::new();
    let mut chunks: Vec<Bytes> = vec![];
    while head.len() < detect::SNIFF_LEN {
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
        // Non-finite rows are the reader's to skip (and count), not a format question.
        assert_eq!(detect(b"nan nan nan\n"), Some("xyz"));
    }

    /// The two files the old screen judged differently from the reader (issue 14).
    #[test]
    fn the_screen_agrees_with_the_reader() {
        // A column-name header: the reader reads it, so the upload is accepted.
        let named = b"x y z\n1.0 2.0 3.0\n4.0 5.0 6.0\n";
        assert_eq!(detect(named), Some("xyz"));
        // Four comment lines before the first point: the reader cannot place the format, so
        // the upload is refused up front rather than failing as `unknown_format` after a 202.
        let comments = b"# a\n# b\n# c\n# d\n1 2 3\n";
        assert_eq!(detect(comments), None);
        for (bytes, accepted) in [(&named[..], true), (&comments[..], false)] {
            let read = asbuilt_plan::io::read_cloud_from(
                std::io::Cursor::new(bytes.to_vec()),
                "upload",
                &Default::default(),
            );
            assert_eq!(read.is_ok(), accepted, "{:?}", read.err());
        }
    }
}
