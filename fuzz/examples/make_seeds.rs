//! Writes the seed corpus (`fuzz/corpus/<target>/`): small valid files of every layout the
//! readers take. Run from `fuzz/`: `cargo run --example make_seeds`.

use std::path::{Path, PathBuf};

use asbuilt_plan::cloud::{PointCloud, ScanPose, TrajectorySample, Viewpoints};
use asbuilt_plan::io::{export, ply, poses};

#[path = "../../crates/plan/tests/support/e57_layouts.rs"]
mod e57_layouts;

fn out(target: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("corpus")
        .join(target);
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Twelve points in two scans, with times, poses at the scanners.
fn cloud() -> PointCloud {
    let pts: Vec<[f64; 3]> = (0..12)
        .map(|i| {
            let f = f64::from(i);
            [f * 0.5, (f * 0.37).sin() * 3.0, f * 0.25]
        })
        .collect();
    let mut c = PointCloud::from_world(&pts);
    c.scan = (0..12).map(|i| u16::from(i >= 6)).collect();
    c.scan_ids = vec![3, 7];
    c.time = (0..12).map(|i| f64::from(i) * 0.1).collect();
    c.viewpoints = Viewpoints::Static(vec![
        ScanPose {
            index: 3,
            position: [1.0, 0.0, 1.5],
            quaternion: [1.0, 0.0, 0.0, 0.0],
        },
        ScanPose {
            index: 7,
            position: [4.0, 1.0, 1.5],
            quaternion: [0.9238795325112867, 0.0, 0.0, 0.3826834323650898],
        },
    ]);
    c
}

fn ply_seeds(c: &PointCloud) {
    use ply::Encoding::*;
    for (enc, name) in [
        (Ascii, "ascii.ply"),
        (BinaryLittleEndian, "le.ply"),
        (BinaryBigEndian, "be.ply"),
    ] {
        ply::write_ply(&out("ply", name), c, enc).unwrap();
    }
    let mut geo = c.clone();
    geo.origin = [512_000.0, 5_400_000.0, 200.0];
    ply::write_ply(&out("ply", "double.ply"), &geo, BinaryLittleEndian).unwrap();
    let faces = "ply\r\nformat ascii 1.0\r\ncomment faces first\r\nelement face 1\r\n\
        property list uchar int vertex_indices\r\nelement vertex 3\r\nproperty uchar red\r\n\
        property float x\r\nproperty float y\r\nproperty float z\r\nproperty int scan\r\nend_header\r\n\
        3 0 1 2\r\n255 0 0 0 1\r\n0 1 0 0 1\r\n0 0 1 nan 2\r\n";
    std::fs::write(out("ply", "faces.ply"), faces).unwrap();
    let mut le = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty short x\n\
        property int y\nproperty double z\nproperty list uchar float n\nend_header\n"
        .to_vec();
    for (x, y, z) in [(1i16, 2i32, 3.5f64), (-4, 5, 6.25)] {
        le.extend(x.to_le_bytes());
        le.extend(y.to_le_bytes());
        le.extend(z.to_le_bytes());
        le.push(1);
        le.extend(0.5f32.to_le_bytes());
    }
    std::fs::write(out("ply", "lists.ply"), le).unwrap();
}

fn e57_seeds(c: &PointCloud) {
    export::write_e57(&out("e57", "cartesian.e57"), c).unwrap();
    e57_layouts::write_layouts(&out("e57", "spherical.e57"));
}

fn las_seeds(c: &PointCloud) {
    export::write_las(&out("las", "las12.las"), c, false).unwrap();
    export::write_las(&out("las", "laz12.laz"), c, true).unwrap();
    for (minor, format, compressed, name) in [
        (0, 0, false, "las10.las"),
        (3, 3, false, "las13.las"),
        (4, 6, false, "las14.las"),
        (4, 7, true, "laz14.laz"),
    ] {
        let mut b = las::Builder::from((1, minor));
        b.point_format = las::point::Format::new(format).unwrap();
        b.point_format.is_compressed = compressed;
        b.transforms = las::Vector {
            x: las::Transform {
                scale: 0.001,
                offset: 500_000.0,
            },
            y: las::Transform {
                scale: 0.001,
                offset: 5_000_000.0,
            },
            z: las::Transform {
                scale: 0.01,
                offset: 0.0,
            },
        };
        let mut header = b.into_header().unwrap();
        if minor == 4 {
            header
                .set_wkt_crs(b"PROJCS[\"ETRS89 / UTM zone 32N\",AUTHORITY[\"EPSG\",\"25832\"]]".to_vec())
                .unwrap();
        }
        let file = std::fs::File::create(out("las", name)).unwrap();
        let mut w = las::Writer::new(std::io::BufWriter::new(file), header).unwrap();
        for i in 0..10 {
            let f = f64::from(i);
            w.write_point(las::Point {
                x: 500_010.0 + f,
                y: 5_000_020.0 - f,
                z: 1.0 + f * 0.1,
                point_source_id: (i % 3) as u16,
                gps_time: w.header().point_format().has_gps_time.then_some(f),
                color: w.header().point_format().has_color.then_some(las::Color::new(1, 2, 3)),
                return_number: 1,
                number_of_returns: 1,
                ..Default::default()
            })
            .unwrap();
        }
        w.close().unwrap();
    }
    small_chunks_laz(&out("las", "laz12-chunks4.laz"), (1, 2), 1);
    small_chunks_laz(&out("las", "laz14-chunks4.laz"), (1, 4), 6);
}

/// A LAZ of 60 points in 15 chunks of 4, small enough for the fuzzer's inputs: the parallel
/// reader decodes the first group of chunks together and the rest each straight into place,
/// which the exporter's 50,000-point chunks never reach in a small file. Made from the `las`
/// crate's uncompressed file: its records compressed by `laz`, and a LASzip record added.
/// Point format 6 (LAS 1.4) makes layered chunks, whose reader skips the layers of fields it
/// does not keep, so those fields have values here.
fn small_chunks_laz(path: &Path, version: (u8, u8), format: u8) {
    let mut b = las::Builder::from(version);
    b.point_format = las::point::Format::new(format).unwrap();
    let tmp = std::env::temp_dir().join("asbuilt-seed-plain.las");
    {
        let mut w = las::Writer::from_path(&tmp, b.into_header().unwrap()).unwrap();
        for i in 0..60 {
            let f = f64::from(i);
            w.write_point(las::Point {
                x: f * 0.05,
                y: (f * 0.3).sin(),
                z: f * 0.02,
                point_source_id: (i / 20) as u16,
                gps_time: Some(f * 0.01),
                return_number: 1,
                number_of_returns: 1,
                intensity: (i * 997 % 4096) as u16,
                classification: las::point::Classification::new(1 + (i % 6) as u8).unwrap(),
                scan_angle: (i % 30) as f32,
                user_data: (i % 7) as u8,
                ..Default::default()
            })
            .unwrap();
        }
        w.close().unwrap();
    }
    let plain = std::fs::read(&tmp).unwrap();
    let u16_at = |at: usize| u16::from_le_bytes([plain[at], plain[at + 1]]);
    let u32_at = |at: usize| u32::from_le_bytes(plain[at..at + 4].try_into().unwrap());
    // Header fields (at the same places in LAS 1.2 and 1.4): header size, offset to the
    // points, VLR count, record length.
    let (head, data) = (usize::from(u16_at(94)), u32_at(96) as usize);
    let (vlrs, size) = (u32_at(100), u16_at(105));
    let base = if format == 6 { 30 } else { 28 };
    let vlr = laz::LazVlrBuilder::default()
        .with_point_format(format, size - base)
        .unwrap()
        .with_fixed_chunk_size(4)
        .build();
    let mut record = Vec::new();
    vlr.write_to(&mut record).unwrap();
    let mut file = plain[..data].to_vec();
    let vlr_len = 54 + record.len();
    file[96..100].copy_from_slice(&((data + vlr_len) as u32).to_le_bytes());
    file[100..104].copy_from_slice(&(vlrs + 1).to_le_bytes());
    file[104] |= 0x80;
    file.extend(0u16.to_le_bytes());
    file.extend(b"laszip encoded\0\0");
    file.extend(22204u16.to_le_bytes());
    file.extend((record.len() as u16).to_le_bytes());
    file.extend([0u8; 32]);
    file.extend(&record);
    // The LASzip record goes right after the header: the writer put no records and no gap there.
    assert_eq!((vlrs, head, file.len()), (0, data, data + vlr_len));
    // The compressor writes the chunk table's offset as a position in its output: it writes
    // after the header, so that is the position in the file.
    let mut out = std::io::Cursor::new(file);
    out.set_position(out.get_ref().len() as u64);
    let mut packed = laz::LasZipCompressor::new(out, vlr).unwrap();
    packed.compress_many(&plain[data..]).unwrap();
    packed.done().unwrap();
    let file = packed.into_inner().into_inner();
    std::fs::write(path, file).unwrap();
}

fn xyz_seeds(c: &PointCloud) {
    // The target's first byte chooses the reader: even = XYZ, odd = PTS; bit 1 asks for a
    // scan column, bits 2.. give it.
    let seed = |name: &str, mode: u8, text: &str| {
        let mut bytes = vec![mode];
        bytes.extend(text.as_bytes());
        std::fs::write(out("xyz", name), bytes).unwrap();
    };
    let path = std::env::temp_dir().join("asbuilt-seed.xyz");
    export::write_xyz(&path, c).unwrap();
    let written = std::fs::read_to_string(&path).unwrap();
    seed("written.xyz", 2 | (3 << 2), &written);
    seed("csv.xyz", 0, "x,y,z,intensity\n1.5,2.5,3.5,10\n4,5,6,11\n-1e3,2E-2,nan,0\n");
    seed("tabs.xyz", 0, "# comment\n1\t2\t3\n\n4 5 6 ; extra\r\n7;8;9\n");
    seed(
        "blocks.pts",
        1,
        "2\n1 2 3 -1200 10 20 30\n4 5 6 -1100 10 20 30\n1\n7 8 9 -1000 1 2 3\n",
    );
    seed("scan.pts", 1 | 2 | (4 << 2), "3\n1 2 3 5 0\n4 5 6 5 1\n7 8 9 5 1\n");
}

fn poses_seeds(c: &PointCloud) {
    let Viewpoints::Static(p) = &c.viewpoints else {
        unreachable!()
    };
    std::fs::write(out("poses", "poses.json"), poses::poses_to_json(p, c.origin)).unwrap();
    let small = [ScanPose {
        index: 0,
        position: [0.0, 0.0, 1.5],
        quaternion: [1.0, 0.0, 0.0, 0.0],
    }, ScanPose {
        index: 1,
        position: [2.0, 0.0, 1.5],
        quaternion: [0.0, 0.0, 0.0, 1.0],
    }];
    std::fs::write(out("poses", "two.json"), poses::poses_to_json(&small, [0.0; 3])).unwrap();
    let samples: Vec<TrajectorySample> = (0..4)
        .map(|i| TrajectorySample {
            t: f64::from(i) * 0.5,
            position: [f64::from(i), 0.0, 1.2],
            quaternion: [1.0, 0.0, 0.0, 0.0],
        })
        .collect();
    std::fs::write(
        out("poses", "trajectory.json"),
        poses::trajectory_to_json(&samples, [0.0; 3]),
    )
    .unwrap();
}

/// Requests for the HTTP targets: query strings, multipart bodies, parameter files.
fn http_seeds() {
    let queries: [&[u8]; 5] = [
        b"\x00samples.cell_size=0.1&filename=../room.xyz",
        b"\x00fitting.iterations=1000000000000",
        b"\x00labeling.solver=harmonic&smoothing.registration_error=0.01&emit_samples=true",
        b"\x01status=queued&limit=5&cursor=0190c1d2-7a3b-7c00-8000-000000000000",
        b"\x02",
    ];
    for (i, q) in queries.iter().enumerate() {
        std::fs::write(out("http_query", &format!("q{i}")), q).unwrap();
    }
    let part = |name: &str, file: Option<&str>, body: &str| {
        let disposition = match file {
            Some(f) => format!("form-data; name=\"{name}\"; filename=\"{f}\""),
            None => format!("form-data; name=\"{name}\""),
        };
        format!("--fuzzboundary\r\nContent-Disposition: {disposition}\r\n\r\n{body}\r\n")
    };
    let cloud = "0 0 0\n1 0 0\n0 1 0\n1 1 1\n";
    let poses = r#"{"poses": [{"index": 0, "position": [0.5, 0.5, 1.5]}]}"#;
    let bodies = [
        format!("{}--fuzzboundary--\r\n", part("cloud", Some("c.xyz"), cloud)),
        format!(
            "{}{}{}--fuzzboundary--\r\n",
            part("params", None, r#"{"samples": {"cell_size": 0.1}}"#),
            part("poses", Some("p.json"), poses),
            part("cloud", Some("c.xyz"), cloud)
        ),
        format!(
            "{}{}--fuzzboundary--\r\n",
            part("params", None, "[fitting]\niterations = 200\n"),
            part("cloud", None, cloud)
        ),
        format!("{}--fuzzboundary--\r\n", part("clouds", None, cloud)),
    ];
    for (i, b) in bodies.iter().enumerate() {
        std::fs::write(out("http_multipart", &format!("m{i}")), b).unwrap();
    }
    let params = [
        r#"{"samples": {"cell_size": 0.1, "min_points": 20}, "fitting": {"circles": false}}"#,
        "[stories]\nmin_wall_height = 2.5\n[labeling]\nsolver = \"harmonic\"\n",
        "samples.cell_size=0.1",
        "fitting.iterations=100001",
    ];
    for (i, p) in params.iter().enumerate() {
        std::fs::write(out("http_params", &format!("p{i}")), p).unwrap();
    }
}

fn main() {
    http_seeds();
    let c = cloud();
    ply_seeds(&c);
    e57_seeds(&c);
    las_seeds(&c);
    xyz_seeds(&c);
    poses_seeds(&c);
}
