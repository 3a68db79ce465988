//! Crafted bad E57, LAS, LAZ, XYZ/PTS files and pose sidecars (PLY has its own suite in
//! `bad_ply.rs`). Each gets a clean error naming the file, the format and what is wrong (with
//! the byte offset or line where that helps): no panic, no hang, no huge allocation.
//!
//! The whole test binary runs under an allocation cap: a reader that trusted a header's count
//! and reserved for it would abort the run instead of passing.
//!
//! Non-finite coordinates are skipped and counted, never an error (E57, PLY, XYZ); LAS stores
//! integers, so there a non-finite scale or offset in the header is the error.

use std::alloc::System;
use std::path::{Path, PathBuf};

use asbuilt_plan::cloud::{PointCloud, ScanPose, Viewpoints};
use asbuilt_plan::io::{self, export, poses, Format, ReadError, ReadOptions};

/// Far more than any case here needs (the largest file is a few megabytes), far less than a
/// trusted "billions of points" header would reserve.
#[global_allocator]
static ALLOCATOR: cap::Cap<System> = cap::Cap::new(System, 256 << 20);

fn dir() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("asbuilt-bad-files-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn file(name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir().join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn forced(format: Format) -> ReadOptions {
    ReadOptions {
        format: Some(format),
        ..Default::default()
    }
}

/// Reads `bytes` as the file `name` and checks the error names the file, the format (as
/// `(las)` or, for undetectable content, `unrecognised format`) and every `want`.
fn expect(name: &str, bytes: &[u8], options: &ReadOptions, format: &str, want: &[&str]) -> String {
    let path = file(name, bytes);
    let err = io::read_cloud_with(&path, options).expect_err("a bad file must not read");
    check(&path, &err, format, want)
}

fn check(path: &Path, err: &ReadError, format: &str, want: &[&str]) -> String {
    let text = err.to_string();
    assert!(text.contains(&path.display().to_string()), "{text}");
    assert!(text.contains(format), "{text:?} should name {format:?}");
    for w in want {
        assert!(text.contains(w), "{text:?} should mention {w:?}");
    }
    eprintln!("{text}");
    text
}

/// A cloud of `n` points on a helix in three scans, with poses.
fn helix(n: usize) -> PointCloud {
    let pts: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let t = i as f64 * 0.01;
            [
                5.0 + 4.0 * t.cos(),
                5.0 + 4.0 * t.sin(),
                (i % 300) as f64 * 0.01,
            ]
        })
        .collect();
    let mut c = PointCloud::from_world(&pts);
    c.scan = (0..n).map(|i| (i * 3 / n) as u16).collect();
    c.scan_ids = vec![0, 1, 2];
    c.viewpoints = Viewpoints::Static(
        (0..3)
            .map(|k| ScanPose {
                index: k,
                position: [5.0, 5.0, 1.5],
                quaternion: [1.0, 0.0, 0.0, 0.0],
            })
            .collect(),
    );
    c
}

/// Writes a valid file with `write` and returns its bytes. Tests run in parallel, so every
/// call gets a file of its own.
fn written(name: &str, write: impl Fn(&Path)) -> Vec<u8> {
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let path = dir().join(format!("valid-{k}-{name}"));
    write(&path);
    std::fs::read(&path).unwrap()
}

fn put_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn put_u64(b: &mut [u8], at: usize, v: u64) {
    b[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

fn get_u64(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap())
}

// ---------------------------------------------------------------- E57

fn e57() -> Vec<u8> {
    written("small.e57", |p| export::write_e57(p, &helix(300)).unwrap())
}

/// CRC-32C (Castagnoli), as E57 pages carry it (stored big-endian).
fn crc32c(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0x82F6_3B78
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn fix_page_crc(b: &mut [u8], page: usize) {
    let start = page * 1024;
    let crc = crc32c(&b[start..start + 1020]);
    b[start + 1020..start + 1024].copy_from_slice(&crc.to_be_bytes());
}

/// The logical XML section of an E57 file.
fn e57_xml(b: &[u8]) -> String {
    let (at, len) = (get_u64(b, 24) as usize, get_u64(b, 32) as usize);
    let mut xml = Vec::new();
    let mut off = at;
    while xml.len() < len {
        let (page, o) = (off / 1024, off % 1024);
        let take = (1020 - o).min(len - xml.len());
        xml.extend(&b[page * 1024 + o..page * 1024 + o + take]);
        off = (page + 1) * 1024;
    }
    String::from_utf8(xml).unwrap()
}

/// Appends `xml` as a new XML section in fresh pages and points the header at it, with every
/// checksum valid, so only the XML's content is wrong.
fn with_xml(mut b: Vec<u8>, xml: &str) -> Vec<u8> {
    let at = b.len();
    for chunk in xml.as_bytes().chunks(1020) {
        let page = b.len() / 1024;
        b.extend(chunk);
        b.resize(page * 1024 + 1024, 0);
        fix_page_crc(&mut b, page);
    }
    let len = b.len() as u64;
    put_u64(&mut b, 16, len);
    put_u64(&mut b, 24, at as u64);
    put_u64(&mut b, 32, xml.len() as u64);
    fix_page_crc(&mut b, 0);
    b
}

fn e57_edit(edit: impl Fn(String) -> String) -> Vec<u8> {
    let b = e57();
    let xml = edit(e57_xml(&b));
    with_xml(b, &xml)
}

#[test]
fn e57_the_rewriting_helper_keeps_a_valid_file_valid() {
    // The XML-editing cases below rely on this: an unchanged rewrite still reads.
    let path = file("rewritten.e57", &e57_edit(|x| x));
    assert_eq!(io::read_cloud(&path).unwrap().len(), 300);
}

#[test]
fn e57_empty() {
    expect(
        "empty.e57",
        b"",
        &forced(Format::E57),
        "(e57)",
        &["ends inside the 48-byte header (0 bytes)"],
    );
}

#[test]
fn e57_truncated() {
    let b = e57();
    let text = expect(
        "truncated.e57",
        &b[..b.len() / 2],
        &Default::default(),
        "(e57)",
        &["truncated", "at byte 16"],
    );
    assert!(text.contains(&format!("has {} bytes", b.len())), "{text}");
}

#[test]
fn e57_wrong_magic() {
    let mut b = e57();
    b[..8].copy_from_slice(b"ASTM-E58");
    expect(
        "magic.e57",
        &b,
        &forced(Format::E57),
        "(e57)",
        &["wrong signature", "at byte 0"],
    );
    // Detected from the content, it is no known format; the name's claim is reported.
    expect(
        "magic2.e57",
        &b,
        &Default::default(),
        "unrecognised format",
        &["the name says .e57"],
    );
}

#[test]
fn e57_wrong_version_and_page_size() {
    let mut b = e57();
    put_u32(&mut b, 8, 2);
    expect(
        "version.e57",
        &b,
        &Default::default(),
        "(e57)",
        &["version 2.0", "at byte 8"],
    );
    let mut b = e57();
    put_u64(&mut b, 40, 4096);
    expect(
        "page.e57",
        &b,
        &Default::default(),
        "(e57)",
        &["page size 4096", "at byte 40"],
    );
}

#[test]
fn e57_huge_xml_section() {
    let mut b = e57();
    put_u64(&mut b, 32, 1 << 40);
    expect(
        "huge-xml.e57",
        &b,
        &Default::default(),
        "(e57)",
        &["XML section claims 1099511627776 bytes", "at byte 32"],
    );
    // Under the cap but beyond the file.
    let mut b = e57();
    put_u64(&mut b, 32, 40 << 20);
    expect(
        "outside-xml.e57",
        &b,
        &Default::default(),
        "(e57)",
        &["does not fit", "at byte 24"],
    );
}

#[test]
fn e57_billions_of_points() {
    let b = e57_edit(|x| x.replacen("recordCount=\"100\"", "recordCount=\"5000000000\"", 1));
    expect(
        "billions.e57",
        &b,
        &Default::default(),
        "(e57)",
        &["5000000000 points of 192 bits claimed", "at scan 0"],
    );
}

#[test]
fn e57_missing_z() {
    let b = e57_edit(|x| x.replace("<cartesianZ type=\"Float\">0</cartesianZ>", ""));
    expect(
        "no-z.e57",
        &b,
        &Default::default(),
        "(e57)",
        &["no x/y/z", "at scan 0"],
    );
}

#[test]
fn e57_constant_prototype() {
    // Zero bits a point: the crate would otherwise generate points without reading any data.
    let b = e57_edit(|x| {
        x.replace(
            "<cartesianX type=\"Float\">0</cartesianX>",
            "<cartesianX type=\"Integer\" minimum=\"0\" maximum=\"0\"/>",
        )
        .replace(
            "<cartesianY type=\"Float\">0</cartesianY>",
            "<cartesianY type=\"Integer\" minimum=\"0\" maximum=\"0\"/>",
        )
        .replace(
            "<cartesianZ type=\"Float\">0</cartesianZ>",
            "<cartesianZ type=\"Integer\" minimum=\"0\" maximum=\"0\"/>",
        )
    });
    expect(
        "constant.e57",
        &b,
        &Default::default(),
        "(e57)",
        &["zero bits a point", "at scan 0"],
    );
}

#[test]
fn e57_malformed_xml() {
    let b = e57_edit(|x| x.replacen("</data3D>", "", 1));
    expect("bad-xml.e57", &b, &Default::default(), "(e57)", &["XML"]);
}

#[test]
fn e57_bad_checksum() {
    let mut b = e57();
    b[600] ^= 0xff;
    expect(
        "checksum.e57",
        &b,
        &Default::default(),
        "(e57)",
        &["checksum", "page 0", "at scan 0"],
    );
}

#[test]
fn e57_pose_that_is_not_a_rotation() {
    let b = e57_edit(|x| x.replacen("<w type=\"Float\">1</w>", "<w type=\"Float\">2</w>", 1));
    expect(
        "scaled-pose.e57",
        &b,
        &Default::default(),
        "(e57)",
        &["has norm 2", "at scan 0"],
    );
    let b = e57_edit(|x| {
        let at = x.find("<translation").unwrap();
        let (head, tail) = x.split_at(at);
        format!("{head}{}", tail.replacen(">5</x>", ">nan</x>", 1))
    });
    expect(
        "nan-pose.e57",
        &b,
        &Default::default(),
        "(e57)",
        &["translation", "not finite", "at scan 0"],
    );
}

#[test]
fn e57_non_finite_points_are_skipped_and_counted() {
    let mut c = helix(30);
    c.xyz[3][0] = f32::NAN;
    c.xyz[7][2] = f32::INFINITY;
    let path = dir().join("nan.e57");
    export::write_e57(&path, &c).unwrap();
    let read = io::read_cloud(&path).unwrap();
    assert_eq!(read.len(), 28);
    assert_eq!(read.source.skipped, 2);
    assert!(read.source.skipped_reason.unwrap().contains("non-finite"));
}

// ---------------------------------------------------------------- LAS

fn las() -> Vec<u8> {
    written("small.las", |p| {
        export::write_las(p, &helix(50), false).unwrap()
    })
}

#[test]
fn las_empty_and_truncated_header() {
    expect(
        "empty.las",
        b"",
        &Default::default(),
        "unrecognised format",
        &["the file is empty", "the name says .las"],
    );
    let b = las();
    expect(
        "header.las",
        &b[..100],
        &Default::default(),
        "(las)",
        &["ends inside the header (100 bytes)", "at byte 0"],
    );
}

#[test]
fn las_wrong_magic() {
    let mut b = las();
    b[..4].copy_from_slice(b"LASG");
    expect(
        "magic.las",
        &b,
        &forced(Format::Las),
        "(las)",
        &["signature", "at byte 0"],
    );
}

#[test]
fn las_billions_of_points() {
    let mut b = las();
    put_u32(&mut b, 107, 4_000_000_000);
    expect(
        "billions.las",
        &b,
        &Default::default(),
        "(las)",
        &[
            "claims 4000000000 points of 20 bytes",
            "truncated, or a bad point count",
        ],
    );
}

#[test]
fn las_truncated_points() {
    let b = las();
    expect(
        "truncated.las",
        &b[..b.len() - 30],
        &Default::default(),
        "(las)",
        &["claims 50 points", "truncated"],
    );
}

#[test]
fn las_point_data_past_the_end() {
    let mut b = las();
    put_u32(&mut b, 96, 1_000_000_000);
    expect(
        "offset.las",
        &b,
        &Default::default(),
        "(las)",
        &["starts at byte 1000000000, past the end", "at byte 96"],
    );
}

#[test]
fn las_non_finite_scale_and_zero_scale() {
    let mut b = las();
    b[131..139].copy_from_slice(&f64::NAN.to_le_bytes());
    expect(
        "nan-scale.las",
        &b,
        &Default::default(),
        "(las)",
        &["x scale factor is NaN", "at byte 131"],
    );
    let mut b = las();
    b[139..147].copy_from_slice(&0.0f64.to_le_bytes());
    expect(
        "zero-scale.las",
        &b,
        &Default::default(),
        "(las)",
        &["y scale factor is 0", "at byte 139"],
    );
    let mut b = las();
    b[171..179].copy_from_slice(&f64::INFINITY.to_le_bytes());
    expect(
        "inf-offset.las",
        &b,
        &Default::default(),
        "(las)",
        &["z offset is inf", "at byte 171"],
    );
}

#[test]
fn las_unknown_point_format() {
    let mut b = las();
    b[104] = 42;
    expect("format.las", &b, &Default::default(), "(las)", &["42"]);
}

#[test]
fn las_absurd_vlr_count() {
    let mut b = las();
    put_u32(&mut b, 100, u32::MAX);
    expect("vlrs.las", &b, &Default::default(), "(las)", &[]);
}

#[test]
fn las_points_outside_stale_header_bounds_are_kept_and_told() {
    // Max x (byte 179) far below the points. In a plain LAS the integers are what was written,
    // and real files often carry stale bounds, so the points read and the details say so.
    let mut b = las();
    b[179..187].copy_from_slice(&(-100.0f64).to_le_bytes());
    b[187..195].copy_from_slice(&(-200.0f64).to_le_bytes());
    let c = io::read_cloud(&file("bounds.las", &b)).unwrap();
    assert!(!c.is_empty());
    assert!(
        c.source
            .details
            .contains("outside the header's bounding box"),
        "{}",
        c.source.details
    );
}

/// Writes LAS 1.4 point format 6 (compressed or not): `n` points along x, `dx` apart, each
/// with its GPS time.
fn las14_points(path: &Path, compressed: bool, n: u32, dx: f64) {
    let mut b = las::Builder::from((1, 4));
    b.point_format = las::point::Format::new(6).unwrap();
    b.point_format.is_compressed = compressed;
    let mut w = las::Writer::from_path(path, b.into_header().unwrap()).unwrap();
    for i in 0..n {
        w.write_point(las::Point {
            x: f64::from(i) * dx,
            y: 1.0,
            z: 2.0,
            gps_time: Some(f64::from(i)),
            return_number: 1,
            number_of_returns: 1,
            ..Default::default()
        })
        .unwrap();
    }
    w.close().unwrap();
}

fn las14() -> Vec<u8> {
    written("small14.las", |p| las14_points(p, false, 20, 1.0))
}

#[test]
fn las14_billions_of_points_and_an_evlr_outside() {
    let mut b = las14();
    put_u32(&mut b, 107, 0);
    put_u64(&mut b, 247, 1 << 40);
    expect(
        "billions14.las",
        &b,
        &Default::default(),
        "(las)",
        &["claims 1099511627776 points"],
    );
    let mut b = las14();
    let near_end = b.len() as u64 - 10;
    put_u64(&mut b, 235, near_end);
    put_u32(&mut b, 243, 1);
    expect(
        "evlr.las",
        &b,
        &Default::default(),
        "(las)",
        &["extended VLR", "does not fit", "at byte"],
    );
}

// ---------------------------------------------------------------- LAZ

/// Three chunks of 50,000 points.
fn laz() -> Vec<u8> {
    written("big.laz", |p| {
        export::write_las(p, &helix(120_000), true).unwrap()
    })
}

#[test]
fn laz_corrupt_chunk() {
    let mut b = laz();
    let start = u32::from_le_bytes(b[96..100].try_into().unwrap()) as usize;
    let table = get_u64(&b, start) as usize;
    // Scribble over the middle of the second chunk.
    let mid = start + (table - start) / 2;
    for (i, byte) in b[mid..mid + 64].iter_mut().enumerate() {
        *byte = (i as u8).wrapping_mul(37) ^ 0x5a;
    }
    expect(
        "corrupt.laz",
        &b,
        &Default::default(),
        "(laz)",
        &["damaged", "of 120000"],
    );
}

#[test]
fn laz_truncated() {
    let b = laz();
    expect(
        "truncated.laz",
        &b[..b.len() * 3 / 5],
        &Default::default(),
        "(laz)",
        &[],
    );
}

#[test]
fn laz_chunk_table_past_the_end_and_absurd() {
    let b0 = laz();
    let start = u32::from_le_bytes(b0[96..100].try_into().unwrap()) as usize;
    let mut b = b0.clone();
    put_u64(&mut b, start, 1 << 50);
    expect(
        "table-offset.laz",
        &b,
        &Default::default(),
        "(laz)",
        &["chunk table offset 1125899906842624 is past the end"],
    );
    let mut b = b0.clone();
    let table = get_u64(&b, start) as usize;
    put_u32(&mut b, table + 4, 2_000_000_000);
    expect(
        "table-count.laz",
        &b,
        &Default::default(),
        "(laz)",
        &["chunk table claims 2000000000 chunks for 120000 points"],
    );
}

#[test]
fn laz_billions_of_points() {
    let mut b = laz();
    put_u32(&mut b, 107, 4_000_000_000);
    expect(
        "billions.laz",
        &b,
        &Default::default(),
        "(laz)",
        &["claims 4000000000 points, more than a"],
    );
}

#[test]
fn laz_flag_without_laszip_data() {
    // A plain LAS file whose point format claims compression.
    let mut b = las();
    b[104] |= 0x80;
    expect("flag.laz", &b, &Default::default(), "(laz)", &[]);
}

/// LAS 1.4 point format 6, compressed: the layered LAZ of terrestrial scanners.
fn layered_laz() -> Vec<u8> {
    written("layered.laz", |p| las14_points(p, true, 1000, 0.01))
}

#[test]
fn laz_layer_of_four_gigabytes() {
    let b0 = layered_laz();
    let path = file("layered-ok.laz", &b0);
    assert_eq!(io::read_cloud(&path).unwrap().len(), 1000);
    // The chunk: the table offset (8 bytes), the first point raw (30 bytes), the count, then
    // nine layer sizes. The decoder would zero a buffer of each size before reading it.
    let start = u32::from_le_bytes(b0[96..100].try_into().unwrap()) as usize;
    let mut b = b0.clone();
    put_u32(&mut b, start + 8 + 30 + 4, 0xFFFF_FFF0);
    expect(
        "layer.laz",
        &b,
        &Default::default(),
        "(laz)",
        &["chunk 0 declares a layer of 4294967280 bytes", "at byte"],
    );
}

#[test]
fn laz_layers_larger_than_their_chunk_are_refused_before_the_decoder_allocates_them() {
    // The serial decoder takes a fixed-size chunk's points from the chunk size, not from the
    // count the chunk declares; a fuzzed file whose counts were larger hid a chunk declaring
    // a 1.6 GB layer from the check, and the read took 1.6 GB for 2,716 bytes.
    finding_fails(
        "las-oom-layer-size-past-declared-count.laz",
        "(laz)",
        &["compressed chunk 11 declares a layer of 1604696076 bytes, past the end of the 2716-byte file"],
    );
    // The parallel decoders cut the chunks by the table: a layer may fit in the file and
    // still run past its chunk's bytes. The last chunk's last layer, 8 bytes longer, ends
    // inside the chunk table that follows it.
    let b0 = layered_laz();
    let start = u32::from_le_bytes(b0[96..100].try_into().unwrap()) as usize;
    let last = start + 8 + 30 + 4 + 4 * 8;
    let size = u32::from_le_bytes(b0[last..last + 4].try_into().unwrap());
    let mut b = b0.clone();
    put_u32(&mut b, last, size + 8);
    expect(
        "layer-past-chunk.laz",
        &b,
        &Default::default(),
        "(laz)",
        &[
            "compressed chunk 0 declares",
            "more than the",
            "bytes the chunk table gives it",
        ],
    );
}

#[test]
fn a_laszip_vlr_behind_a_short_header_size_is_checked_where_the_decoder_finds_it() {
    // The header says 371 bytes, short of LAS 1.4's 375. The decoder reads all 375 and finds
    // the LASzip VLR after them; the checks looked at byte 371, found none, and let the
    // decoder zero 60 MB of layers for a 2,723-byte file.
    finding_fails(
        "las-oom-header-size-short-of-its-version.laz",
        "(laz)",
        &["the chunk table's 0 chunks hold 0 points, fewer than the 60 the header claims"],
    );
}

/// Reads the fuzz finding `name` (in `tests/fuzz_regressions/`), which must fail with `want`.
fn finding_fails(name: &str, format: &str, want: &[&str]) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_regressions")
        .join(name);
    let err = io::read_cloud(&path).expect_err("a fuzz finding must not read");
    check(&path, &err, format, want);
}

/// Inputs the fuzz targets found (`fuzz/`), kept as files: each must give a clean error.
#[test]
fn fuzz_findings_stay_fixed() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let format = path.extension().unwrap().to_str().unwrap().to_string();
        let err = io::read_cloud(&path).expect_err("a fuzz finding must not read");
        let text = check(&path, &err, &format!("({format})"), &[]);
        // Found as panics or huge allocations: the reader must now refuse them itself, not
        // leave it to the reader thread's panic net.
        assert!(!text.contains("the decoder failed"), "{text}");
        n += 1;
    }
    assert!(n >= 1, "the findings are in {}", dir.display());
}

/// Two of the fuzz findings, refused by what is wrong with them: a header whose record length
/// is not its LASzip items', and a chunk table of fixed-size chunks too short for the header's
/// point count (both reached assertions in the `laz` decoder).
#[test]
fn laz_headers_that_disagree_with_their_items_or_chunk_table_are_named() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let cases: [(&str, &[&str]); 2] = [
        (
            "las-panic-record-length.laz",
            &[
                "point items make 28-byte records",
                "the header says 24604 bytes",
            ],
        ),
        (
            "las-panic-short-chunk-table.laz",
            &["15 chunks hold 60 points, fewer than the 188"],
        ),
    ];
    for (file, want) in cases {
        let path = dir.join(file);
        let err = io::read_cloud(&path).expect_err("a fuzz finding must not read");
        check(&path, &err, "(laz)", want);
    }
}

// ---------------------------------------------------------------- XYZ and PTS

#[test]
fn xyz_empty_and_binary() {
    expect(
        "empty.xyz",
        b"",
        &Default::default(),
        "unrecognised format",
        &["the file is empty", "the name says .xyz"],
    );
    expect(
        "empty2.xyz",
        b"",
        &forced(Format::Xyz),
        "(xyz)",
        &["the file is empty"],
    );
    expect(
        "binary.xyz",
        &[0x00, 0x9c, 0xff, 0x10, 0x00, 0x00, 0x01, 0x02, 0x03],
        &Default::default(),
        "unrecognised format",
        &["binary content", "00 9c ff 10"],
    );
}

#[test]
fn xyz_missing_z() {
    expect(
        "two-columns.xyz",
        b"1 2 3\n4 5\n",
        &Default::default(),
        "(xyz)",
        &["expected at least x y z, found 2 value(s)", "at line 2"],
    );
    // With no full row at all, it is not taken for a point file.
    expect(
        "pairs.xyz",
        b"1 2\n3 4\n",
        &Default::default(),
        "unrecognised format",
        &["without a row of x y z numbers"],
    );
}

#[test]
fn xyz_not_a_number_names_the_line() {
    expect(
        "word.csv",
        b"x,y,z\n1,2,3\n4,5,6\n7,eight,9\n",
        &Default::default(),
        "(xyz)",
        &["`eight` in column 1 is not a number", "at line 4"],
    );
    let mut bytes = b"1 2 3\n4 5 ".to_vec();
    bytes.extend([0xff, 0xfe, b'\n']);
    expect(
        "utf8.xyz",
        &bytes,
        &Default::default(),
        "(xyz)",
        &["column 2 is not a number", "at line 2"],
    );
}

#[test]
fn xyz_endless_line() {
    let bytes = b"1 2 3 ".repeat(20_000);
    expect(
        "endless.xyz",
        &bytes,
        &Default::default(),
        "(xyz)",
        &["a line longer than 65536 bytes", "at line 1"],
    );
}

#[test]
fn pts_count_lines() {
    expect(
        "billions.pts",
        b"9999999999\n1 2 3 0 0 0 0\n",
        &Default::default(),
        "(pts)",
        &["claims 9999999999 points", "at line 1"],
    );
    expect(
        "short.pts",
        b"5\n1 2 3 0 0 0 0\n4 5 6 0 0 0 0\n",
        &Default::default(),
        "(pts)",
        &["the count line says 5 points but 2 follow", "at line 1"],
    );
    expect(
        "long.pts",
        b"1\n1 2 3 0 0 0 0\n4 5 6 0 0 0 0\n",
        &Default::default(),
        "(pts)",
        &["more points than the count line (line 1) says", "at line 3"],
    );
}

#[test]
fn xyz_scan_column() {
    let opts = ReadOptions {
        scan_column: Some(3),
        ..Default::default()
    };
    expect(
        "no-scan.xyz",
        b"1 2 3 0\n4 5 6\n",
        &opts,
        "(xyz)",
        &["no column 3 for the scan index", "at line 2"],
    );
    expect(
        "half-scan.xyz",
        b"1 2 3 0\n4 5 6 1.5\n",
        &opts,
        "(xyz)",
        &[
            "scan index `1.5` in column 3 is not a non-negative integer",
            "at line 2",
        ],
    );
}

#[test]
fn xyz_non_finite_points_are_skipped_and_counted() {
    let path = file("nan.xyz", b"1 2 3\nnan 1 2\n1 inf 2\n-inf 0 0\n4 5 6\n");
    let c = io::read_cloud(&path).unwrap();
    assert_eq!(c.len(), 2);
    assert_eq!(c.source.skipped, 3);
    assert_eq!(
        c.source.skipped_reason.as_deref(),
        Some("non-finite coordinates")
    );
}

// ---------------------------------------------------------------- pose sidecars

fn cloud_with_scans(ids: &[u32]) -> PointCloud {
    PointCloud {
        xyz: vec![[0.0; 3]; ids.len()],
        scan: (0..ids.len() as u16).collect(),
        scan_ids: ids.to_vec(),
        ..Default::default()
    }
}

fn pose_json(indices: &[u32]) -> String {
    let poses: Vec<ScanPose> = indices
        .iter()
        .map(|&index| ScanPose {
            index,
            position: [1.0, 2.0, 1.5],
            quaternion: [1.0, 0.0, 0.0, 0.0],
        })
        .collect();
    poses::poses_to_json(&poses, [0.0; 3])
}

fn expect_sidecar(name: &str, text: &[u8], cloud: &mut PointCloud, want: &[&str]) -> String {
    let path = file(name, text);
    let err = poses::load_poses(cloud, &path).expect_err("a bad sidecar must not attach");
    assert!(
        matches!(err, ReadError::Poses { .. } | ReadError::Io { .. }),
        "{err:?}"
    );
    check(&path, &err, "poses", want)
}

#[test]
fn sidecar_not_json() {
    expect_sidecar(
        "broken.json",
        b"{\"scans\": [{\"index\": 0,",
        &mut cloud_with_scans(&[0]),
        &["not valid pose JSON", "line 1 column"],
    );
    expect_sidecar(
        "binary.json",
        &[0xff, 0xfe, 0x00, 0x7b],
        &mut cloud_with_scans(&[0]),
        &["not UTF-8"],
    );
    let deep = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
    expect_sidecar(
        "deep.json",
        deep.as_bytes(),
        &mut cloud_with_scans(&[0]),
        &["recursion limit"],
    );
}

#[test]
fn sidecar_missing_a_scan_of_the_cloud() {
    expect_sidecar(
        "missing.json",
        pose_json(&[0, 1]).as_bytes(),
        &mut cloud_with_scans(&[0, 1, 2]),
        &["the cloud has points of scan 2 but the pose file has no scan with index 2"],
    );
}

#[test]
fn sidecar_with_a_scan_the_cloud_lacks() {
    expect_sidecar(
        "extra.json",
        pose_json(&[0, 1, 9]).as_bytes(),
        &mut cloud_with_scans(&[0, 1]),
        &["scan index 9 but no point of the cloud belongs to scan 9"],
    );
    expect_sidecar(
        "unscanned.json",
        pose_json(&[0, 1, 2]).as_bytes(),
        &mut PointCloud {
            xyz: vec![[0.0; 3]; 5],
            ..Default::default()
        },
        &["name no scans", "lists 3 scans"],
    );
}

#[test]
fn sidecar_bad_entries() {
    expect_sidecar(
        "quaternion.json",
        br#"{"scans": [{"index": 0, "position": [0, 0, 0], "quaternion": [0, 0, 0, 0]}]}"#,
        &mut cloud_with_scans(&[0]),
        &["scans[0] (index 0)", "norm 0"],
    );
    expect_sidecar(
        "duplicate.json",
        br#"{"scans": [{"index": 4, "position": [0, 0, 0], "quaternion": [1, 0, 0, 0]},
                       {"index": 4, "position": [1, 0, 0], "quaternion": [1, 0, 0, 0]}]}"#,
        &mut cloud_with_scans(&[4]),
        &["scans[1] (index 4): duplicate index"],
    );
}

#[test]
fn sidecar_too_large() {
    let path = dir().join("huge.json");
    let f = std::fs::File::create(&path).unwrap();
    // Sparse: no disk is written.
    f.set_len(poses::MAX_POSES_BYTES + 1).unwrap();
    let err = poses::read_poses(&path).unwrap_err();
    check(
        &path,
        &err,
        "poses",
        &["more than the 67108864 a sidecar may have"],
    );
}

#[test]
fn trajectory_that_does_not_match_the_cloud() {
    let path = file(
        "trajectory.json",
        br#"{"samples": [{"t": 0, "position": [0, 0, 0], "quaternion": [1, 0, 0, 0]},
                         {"t": 1, "position": [1, 0, 0], "quaternion": [1, 0, 0, 0]}]}"#,
    );
    let mut cloud = PointCloud {
        xyz: vec![[0.0; 3]; 3],
        time: vec![0.5, 0.7, 9.0],
        ..Default::default()
    };
    let err = poses::load_trajectory(&mut cloud, &path).unwrap_err();
    check(&path, &err, "poses", &["point 2 has time 9"]);
    let path = file(
        "backwards.json",
        br#"{"samples": [{"t": 1, "position": [0, 0, 0], "quaternion": [1, 0, 0, 0]},
                         {"t": 0.5, "position": [1, 0, 0], "quaternion": [1, 0, 0, 0]}]}"#,
    );
    let err = poses::read_trajectory(&path).unwrap_err();
    check(
        &path,
        &err,
        "poses",
        &["samples[1]: time 0.5 does not come after"],
    );
    let path = file("typed.json", br#"{"samples": [{"t": "soon"}]}"#);
    let err = poses::read_trajectory(&path).unwrap_err();
    check(&path, &err, "poses", &["line 1 column"]);
}
