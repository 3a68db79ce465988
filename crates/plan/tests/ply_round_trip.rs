//! PLY written by `write_ply` reads back equal (within f32 precision) in every encoding, and the
//! reader takes layouts other writers produce.

use std::path::PathBuf;

use asbuilt_plan::cloud::PointCloud;
use asbuilt_plan::io::ply::{read_ply, write_ply, Encoding};
use asbuilt_plan::io::read_cloud;

fn path(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("asbuilt-ply-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn cloud(origin: [f64; 3]) -> PointCloud {
    let n = 5000;
    PointCloud {
        origin,
        xyz: (0..n)
            .map(|i| {
                let f = i as f32;
                [f * 0.001 - 2.0, (f * 0.37).sin() * 10.0, 1.0 / (1.0 + f)]
            })
            .collect(),
        scan: (0..n).map(|i| (i % 3) as u16).collect(),
        scan_ids: vec![7, 3, 40_000],
        time: (0..n).map(|i| 1.0e5 + i as f64 * 0.0013).collect(),
        ..Default::default()
    }
}

fn assert_same(a: &PointCloud, b: &PointCloud, tolerance: f64) {
    assert_eq!(a.len(), b.len());
    for (p, q) in a.xyz.iter().zip(&b.xyz) {
        for k in 0..3 {
            let wp = a.origin[k] + f64::from(p[k]);
            let wq = b.origin[k] + f64::from(q[k]);
            assert!((wp - wq).abs() <= tolerance, "{wp} vs {wq}");
        }
    }
    let ids = |c: &PointCloud| {
        c.scan
            .iter()
            .map(|&s| c.scan_ids[s as usize])
            .collect::<Vec<_>>()
    };
    assert_eq!(ids(a), ids(b));
    assert_eq!(a.time, b.time);
    b.check().unwrap();
}

#[test]
fn round_trip_every_encoding() {
    for (encoding, name) in [
        (Encoding::BinaryLittleEndian, "le.ply"),
        (Encoding::BinaryBigEndian, "be.ply"),
        (Encoding::Ascii, "ascii.ply"),
    ] {
        let c = cloud([0.0; 3]);
        let p = path(name);
        write_ply(&p, &c, encoding).unwrap();
        let back = read_cloud(&p).unwrap();
        assert_same(&c, &back, 1e-6);
        assert_eq!(back.source.format, "ply");
        assert!(
            back.source.details.contains("scan_index"),
            "{}",
            back.source.details
        );
    }
}

#[test]
fn georeferenced_round_trip_keeps_millimetres() {
    for encoding in [Encoding::BinaryLittleEndian, Encoding::Ascii] {
        let c = cloud([512_345.0, 5_432_100.0, 250.0]);
        let p = path("utm.ply");
        write_ply(&p, &c, encoding).unwrap();
        let back = read_ply(&p).unwrap();
        // The reader picks its own origin; world coordinates agree to f32 rounding of the locals.
        assert_same(&c, &back, 2e-3);
        assert!(back.origin[0].abs() > 1.0e5);
    }
}

#[test]
fn other_layouts_read() {
    // Doubles, an unknown colour property between the coordinates, a `scan` name, faces before
    // the vertices with lists, and a trailing edge element.
    let mut bytes = b"ply\nformat binary_big_endian 1.0\ncomment made by hand\nelement face 2\nproperty list uchar int vertex_indices\nproperty uchar flags\nelement vertex 2\nproperty double x\nproperty uchar red\nproperty double y\nproperty double z\nproperty short scan\nproperty list uchar float normals\nelement edge 1\nproperty int a\nend_header\n".to_vec();
    for face in [[1i32, 2, 3], [4, 5, 6]] {
        bytes.push(3);
        for i in face {
            bytes.extend(i.to_be_bytes());
        }
        bytes.push(9);
    }
    for (x, y, z, s) in [(1.5f64, 2.5f64, 3.5f64, 4i16), (-1.0, -2.0, -3.0, 9)] {
        bytes.extend(x.to_be_bytes());
        bytes.push(255);
        bytes.extend(y.to_be_bytes());
        bytes.extend(z.to_be_bytes());
        bytes.extend(s.to_be_bytes());
        bytes.push(2);
        bytes.extend(0.5f32.to_be_bytes());
        bytes.extend(0.25f32.to_be_bytes());
    }
    bytes.extend(7i32.to_be_bytes());
    let p = path("layout.ply");
    std::fs::write(&p, &bytes).unwrap();
    let c = read_ply(&p).unwrap();
    assert_eq!(c.xyz, vec![[1.5, 2.5, 3.5], [-1.0, -2.0, -3.0]]);
    assert_eq!(c.scan_ids, vec![4, 9]);
    assert_eq!(c.scan, vec![0, 1]);
    assert!(c.time.is_empty());
}

#[test]
fn ascii_with_lists_and_crlf() {
    let text = "ply\r\nformat ascii 1.0\r\nelement vertex 2\r\nproperty float x\r\nproperty list uchar int idx\r\nproperty float y\r\nproperty float z\r\nproperty double time\r\nend_header\r\n1 2 7 8 2 3 0.5\r\n4 0 5 6 0.75\r\n";
    let p = path("crlf.ply");
    std::fs::write(&p, text).unwrap();
    let c = read_ply(&p).unwrap();
    assert_eq!(c.xyz, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    assert_eq!(c.time, vec![0.5, 0.75]);
}
