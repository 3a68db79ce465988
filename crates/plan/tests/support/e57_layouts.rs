//! An E57 file with the record layouts beyond plain cartesian doubles, shared by the reader's
//! test (`e57_records.rs`) and the fuzz seed corpus (`fuzz/examples/make_seeds.rs`).

/// Writes two scans to `path`. Scan 0: 8 spherical points (single precision, with intensity and
/// colour), the one at i = 5 marked invalid. Scan 1: 8 scaled-integer cartesian points under a
/// pose turning 180° about z and moving by (10, 20, 1.5), the one at i = 3 marked invalid.
pub fn write_layouts(path: &std::path::Path) {
    let mut w = e57::E57Writer::from_file(path, "asbuilt").unwrap();
    let prototype = vec![
        e57::Record::SPHERICAL_RANGE_F32,
        e57::Record::SPHERICAL_AZIMUTH_F32,
        e57::Record::SPHERICAL_ELEVATION_F32,
        e57::Record::SPHERICAL_INVALID_STATE,
        e57::Record::INTENSITY_U16,
        e57::Record::COLOR_RED_U8,
        e57::Record::COLOR_GREEN_U8,
        e57::Record::COLOR_BLUE_U8,
    ];
    let mut pc = w.add_pointcloud("sph", prototype).unwrap();
    for i in 0..8 {
        let f = i as f32;
        use e57::RecordValue::*;
        pc.add_point(vec![
            Single(1.0 + f),
            Single(f * 0.3),
            Single(f * 0.1 - 0.3),
            Integer(i64::from(i == 5)),
            Integer(i64::from(i) * 100),
            Integer(200),
            Integer(100),
            Integer(i64::from(i)),
        ])
        .unwrap();
    }
    pc.finalize().unwrap();
    // A second scan with scaled-integer cartesian coordinates and a pose.
    let scaled = |name| e57::Record {
        name,
        data_type: e57::RecordDataType::ScaledInteger {
            min: -100_000,
            max: 100_000,
            scale: 0.001,
            offset: 0.0,
        },
    };
    let prototype = vec![
        scaled(e57::RecordName::CartesianX),
        scaled(e57::RecordName::CartesianY),
        scaled(e57::RecordName::CartesianZ),
        e57::Record::CARTESIAN_INVALID_STATE,
    ];
    let mut pc = w.add_pointcloud("scaled", prototype).unwrap();
    pc.set_transform(Some(e57::Transform {
        rotation: e57::Quaternion {
            w: 0.0,
            x: 0.0,
            y: 0.0,
            z: 1.0,
        },
        translation: e57::Translation {
            x: 10.0,
            y: 20.0,
            z: 1.5,
        },
    }));
    for i in 0..8i64 {
        use e57::RecordValue::*;
        pc.add_point(vec![
            ScaledInteger(i * 1000),
            ScaledInteger(-i * 500),
            ScaledInteger(1200),
            Integer(i64::from(i == 3) * 2),
        ])
        .unwrap();
    }
    pc.finalize().unwrap();
    w.finalize().unwrap();
}
