//! Crafted bad PLY files: each gets a clean error naming the file and the problem, no panic,
//! no hang, no huge allocation.

use std::path::PathBuf;

use asbuilt_plan::io::{ply::read_ply, read_cloud, ReadError};

/// Writes `bytes` to a fresh file named after the test, and returns its path.
fn file(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("asbuilt-bad-ply-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.ply"));
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Reads the file and checks the error is `Invalid`, names the file and contains `want`.
fn expect_error(name: &str, bytes: &[u8], want: &str) -> String {
    let path = file(name, bytes);
    let err = read_ply(&path).expect_err("a bad file must not read");
    assert!(matches!(err, ReadError::Invalid { .. }), "{err:?}");
    let text = err.to_string();
    assert!(text.contains(&path.display().to_string()), "{text}");
    assert!(text.contains("(ply)"), "{text}");
    assert!(text.contains(want), "{text:?} should mention {want:?}");
    text
}

const XYZ: &str = "property float x\nproperty float y\nproperty float z\n";

fn header(format: &str, count: u64, props: &str) -> String {
    format!("ply\nformat {format} 1.0\nelement vertex {count}\n{props}end_header\n")
}

#[test]
fn empty_file() {
    expect_error("empty", b"", "the file is empty");
}

#[test]
fn wrong_magic() {
    let text = expect_error("magic", b"PLX\nformat ascii 1.0\n", "not a PLY file");
    assert!(text.contains("byte offset 0"), "{text}");
    // Through format detection the file is not taken for PLY at all.
    let path = file("magic2", b"solid cube\n");
    assert!(matches!(
        read_cloud(&path),
        Err(ReadError::UnknownFormat { .. })
    ));
}

#[test]
fn truncated_binary_body() {
    let mut bytes = header("binary_little_endian", 3, XYZ).into_bytes();
    let header_len = bytes.len();
    for v in [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0] {
        bytes.extend(v.to_le_bytes());
    }
    let text = expect_error("truncated", &bytes, "truncated");
    assert!(
        text.contains(&format!("byte offset {header_len}")),
        "{text}"
    );
}

#[test]
fn truncated_binary_body_found_while_reading() {
    // The size check passes (a face element after the vertices is not counted), so the
    // truncation shows up while decoding.
    let props = format!("{XYZ}element face 1\nproperty list uchar int vertex_indices\n");
    let mut bytes = header("binary_little_endian", 200_000, &props).into_bytes();
    bytes.extend(vec![0u8; 12 * 199_999 + 5]);
    let text = expect_error("truncated-late", &bytes, "truncated");
    assert!(text.contains("byte offset"), "{text}");
}

#[test]
fn header_without_end() {
    let text = expect_error(
        "no-end",
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n",
        "without `end_header`",
    );
    assert!(text.contains("line 5"), "{text}");
}

#[test]
fn billions_of_vertices() {
    let mut bytes = header("binary_little_endian", 4_000_000_000, XYZ).into_bytes();
    bytes.extend([0u8; 120]);
    let start = std::time::Instant::now();
    expect_error("billions", &bytes, "declares 4000000000 vertices");
    assert!(
        start.elapsed().as_secs() < 2,
        "must fail at once, not read or allocate"
    );
}

#[test]
fn missing_z() {
    let props = "property float x\nproperty float y\nproperty uchar red\n";
    let mut bytes = header("ascii", 1, props).into_bytes();
    bytes.extend(b"1 2 3\n");
    expect_error("no-z", &bytes, "no scalar `z` property");
}

#[test]
fn absurd_property_count() {
    let props: String = (0..5000)
        .map(|k| format!("property float p{k}\n"))
        .collect();
    expect_error(
        "many-props",
        header("ascii", 1, &props).as_bytes(),
        "more than 1024 properties",
    );
}

#[test]
fn not_a_number_names_the_line() {
    let mut bytes = header("ascii", 2, XYZ).into_bytes();
    bytes.extend(b"1 2 3\n4 five 6\n");
    let text = expect_error("nan-text", &bytes, "vertex 1: property `y` is not a number");
    // Seven header lines, then vertex 0 on line 8 and vertex 1 on line 9.
    assert!(text.contains("line 9"), "{text}");
}

#[test]
fn short_ascii_line() {
    let mut bytes = header("ascii", 2, XYZ).into_bytes();
    bytes.extend(b"10 20 30\n40 50\n");
    let text = expect_error("short-line", &bytes, "the line ends before property `z`");
    assert!(text.contains("line 9"), "{text}");
}

#[test]
fn ascii_ends_early() {
    // Enough bytes for the declared count to be plausible, but the lines stop early.
    let mut bytes = header("ascii", 3, XYZ).into_bytes();
    bytes.extend(b"100 200 300\n400 500 600\n");
    let text = expect_error(
        "ascii-early",
        &bytes,
        "truncated: it ends before vertex 2 of 3",
    );
    assert!(text.contains("line 10"), "{text}");
    // Too few bytes for the count at all: caught before reading.
    let mut short = header("ascii", 30, XYZ).into_bytes();
    short.extend(b"1 2 3\n4 5 6\n");
    expect_error("ascii-count", &short, "declares 30 vertices");
}

#[test]
fn unknown_format_and_type() {
    expect_error(
        "format",
        header("binary_middle_endian", 1, XYZ).as_bytes(),
        "unknown PLY format `binary_middle_endian`",
    );
    expect_error(
        "type",
        header(
            "ascii",
            1,
            "property float x\nproperty float y\nproperty quad z\n",
        )
        .as_bytes(),
        "unknown property type `quad`",
    );
}

#[test]
fn huge_list_before_the_vertices() {
    // A face whose list claims 4 billion items: skipped in bounded steps, then truncation.
    let mut bytes = "ply\nformat binary_little_endian 1.0\nelement face 1\nproperty list uint int vertex_indices\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n".as_bytes().to_vec();
    bytes.extend(u32::MAX.to_le_bytes());
    bytes.extend([0u8; 64]);
    expect_error("huge-list", &bytes, "truncated");
}

#[test]
fn endless_header() {
    let mut bytes = b"ply\nformat ascii 1.0\ncomment ".to_vec();
    bytes.extend(vec![b'a'; 3 << 20]);
    expect_error("endless", &bytes, "header is longer than");
}

#[test]
fn bad_scan_index() {
    let props = format!("{XYZ}property float scan_index\n");
    let mut bytes = header("ascii", 2, &props).into_bytes();
    bytes.extend(b"1 2 3 0\n4 5 6 1.5\n");
    let text = expect_error(
        "scan",
        &bytes,
        "vertex 1: scan index 1.5 is not a whole number",
    );
    assert!(text.contains("line 10"), "{text}");
}

#[test]
fn non_finite_points_are_skipped_and_counted() {
    let mut bytes = header("ascii", 3, XYZ).into_bytes();
    bytes.extend(b"1 2 3\nnan 5 6\n7 8 inf\n");
    let path = file("nan-points", &bytes);
    let cloud = read_ply(&path).expect("NaN points are skipped, not fatal");
    assert_eq!(cloud.len(), 1);
    assert_eq!(cloud.source.skipped, 2);
    assert!(cloud
        .source
        .skipped_reason
        .as_deref()
        .unwrap()
        .contains("non-finite"));
}
