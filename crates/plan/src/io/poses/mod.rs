//! The pose sidecars of `docs/contract.md` §2: static scan poses and mobile trajectories.
//! Sidecar positions are in the cloud's world frame; attaching converts them to the local frame.
//!
//! Parsing checks every entry: finite numbers, three-element positions, unit quaternions
//! (within [`QUATERNION_TOLERANCE`], then renormalised), unique scan indices and increasing times.
//! Unknown keys are ignored, as the contract promises. Static poses (`scans.rs`) are few and read
//! through a JSON tree; trajectories (`trajectory.rs`) can be long and are deserialised straight
//! into typed samples.

use std::path::Path;

use super::ReadError;

mod scans;
mod trajectory;

pub use scans::{
    attach_poses, load_poses, parse_poses, poses_to_json, read_poses, write_poses, MAX_POSES_BYTES,
    MAX_SCANS,
};
pub use trajectory::{
    attach_trajectory, load_trajectory, parse_trajectory, position_at, read_trajectory,
    trajectory_to_json, write_trajectory, MAX_TRAJECTORY_BYTES, MAX_TRAJECTORY_SAMPLES,
};

/// How far a quaternion's norm may stray from 1 before it is an error rather than rounding.
pub const QUATERNION_TOLERANCE: f64 = 1.0e-3;

/// Positions farther than this from zero, in metres, are not on this planet.
const MAX_COORDINATE: f64 = 1.0e9;

/// Why a sidecar could not be used. Messages name the offending index.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PosesError {
    /// The text is not JSON of the expected shape.
    #[error("not valid pose JSON: {0}")]
    Json(String),
    /// One entry is malformed; the message names the entry and the field.
    #[error("{0}")]
    Invalid(String),
    /// The sidecar does not fit the cloud (scans without poses, times outside the path).
    #[error("{0}")]
    Mismatch(String),
    /// The sidecar could not be written.
    #[error("cannot write {path}: {why}")]
    Write {
        /// The file.
        path: String,
        /// The system's reason.
        why: String,
    },
}

fn sidecar_error(path: &Path, e: PosesError) -> ReadError {
    ReadError::Poses {
        path: path.display().to_string(),
        why: e.to_string(),
    }
}

fn open_sidecar(path: &Path, max: u64) -> Result<std::fs::File, ReadError> {
    let name = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|e| ReadError::io(&name, e))?;
    let len = file.metadata().map_err(|e| ReadError::io(&name, e))?.len();
    if len > max {
        return Err(ReadError::Poses {
            path: name,
            why: format!("the file has {len} bytes, more than the {max} a sidecar may have"),
        });
    }
    Ok(file)
}

fn read_sidecar(path: &Path, max: u64) -> Result<String, ReadError> {
    use std::io::Read;
    let mut text = String::new();
    open_sidecar(path, max)?
        .take(max)
        .read_to_string(&mut text)
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::InvalidData => {
                sidecar_error(path, PosesError::Json("the file is not UTF-8 text".into()))
            }
            _ => ReadError::io(&path.display().to_string(), e),
        })?;
    Ok(text)
}

fn write_text(path: &Path, text: &str) -> Result<(), PosesError> {
    std::fs::write(path, text).map_err(|e| PosesError::Write {
        path: path.display().to_string(),
        why: e.to_string(),
    })
}

fn world_to_local(origin: [f64; 3], p: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| p[i] - origin[i])
}

fn local_to_world(origin: [f64; 3], p: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| p[i] + origin[i])
}

fn finite(v: f64, at: &dyn Fn() -> String) -> Result<f64, PosesError> {
    if v.is_finite() && v.abs() <= MAX_COORDINATE {
        Ok(v)
    } else {
        Err(PosesError::Invalid(format!(
            "{}: expected a finite number of at most {MAX_COORDINATE:e}, not {v}",
            at()
        )))
    }
}

fn unit_quaternion(q: [f64; 4], at: &dyn Fn() -> String) -> Result<[f64; 4], PosesError> {
    let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    if norm.is_nan() || (norm - 1.0).abs() > QUATERNION_TOLERANCE {
        return Err(PosesError::Invalid(format!(
            "{}: `quaternion` has norm {norm:.6}, not 1 (a rotation's quaternion [w, x, y, z] is unit)",
            at()
        )));
    }
    Ok(q.map(|c| c / norm))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::{PointCloud, ScanPose, TrajectorySample, Viewpoints};

    const ID: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

    fn cloud_with_scans(ids: &[u32], origin: [f64; 3]) -> PointCloud {
        PointCloud {
            origin,
            xyz: vec![[0.0; 3]; ids.len()],
            scan: (0..ids.len() as u16).collect(),
            scan_ids: ids.to_vec(),
            ..Default::default()
        }
    }

    #[test]
    fn parses_poses_and_ignores_unknown_keys() {
        let text = r#"{"scans": [{"index": 7, "position": [1, 2, 3], "quaternion": [1, 0, 0, 0], "name": "a"}],
                       "software": "x"}"#;
        let poses = parse_poses(text).unwrap();
        assert_eq!(poses.len(), 1);
        assert_eq!(poses[0].index, 7);
        assert_eq!(poses[0].position, [1.0, 2.0, 3.0]);
    }

    #[test]
    fn bad_entries_name_the_entry_and_field() {
        let cases = [
            (
                r#"{"scans": [{"index": 0, "position": [0,0], "quaternion": [1,0,0,0]}]}"#,
                "scans[0] (index 0): `position`",
            ),
            (
                r#"{"scans": [{"index": 0, "position": [0,0,0], "quaternion": [2,0,0,0]}]}"#,
                "norm 2",
            ),
            (
                r#"{"scans": [{"index": 0, "position": [0,0,0], "quaternion": [1,0,0,0]},
                           {"index": 0, "position": [0,0,0], "quaternion": [1,0,0,0]}]}"#,
                "scans[1] (index 0): duplicate index",
            ),
            (
                r#"{"scans": [{"index": -1, "position": [0,0,0], "quaternion": [1,0,0,0]}]}"#,
                "scans[0]: `index`",
            ),
            (
                r#"{"scans": [{"position": [0,0,0], "quaternion": [1,0,0,0]}]}"#,
                "scans[0]: no `index`",
            ),
            (
                r#"{"scans": [{"index": 1, "position": [0,"a",0], "quaternion": [1,0,0,0]}]}"#,
                "position[1]",
            ),
        ];
        for (text, want) in cases {
            let err = parse_poses(text).unwrap_err().to_string();
            assert!(err.contains(want), "{err:?} should contain {want:?}");
        }
        assert!(matches!(parse_poses("[1]"), Err(PosesError::Json(_))));
        assert!(matches!(
            parse_poses("{\"scans\": 3}"),
            Err(PosesError::Json(_))
        ));
        assert!(matches!(parse_poses("{"), Err(PosesError::Json(_))));
    }

    #[test]
    fn near_unit_quaternions_are_renormalised() {
        let text =
            r#"{"scans": [{"index": 0, "position": [0,0,0], "quaternion": [1.0002,0,0,0]}]}"#;
        assert_eq!(parse_poses(text).unwrap()[0].quaternion, ID);
    }

    #[test]
    fn attach_converts_to_local_and_orders_by_scan_slot() {
        let mut cloud = cloud_with_scans(&[5, 2], [1000.0, 2000.0, 10.0]);
        let poses = vec![
            ScanPose {
                index: 2,
                position: [1001.0, 2002.0, 11.5],
                quaternion: ID,
            },
            ScanPose {
                index: 5,
                position: [1003.0, 2004.0, 11.5],
                quaternion: ID,
            },
        ];
        attach_poses(&mut cloud, poses).unwrap();
        let Viewpoints::Static(p) = &cloud.viewpoints else {
            panic!("no poses")
        };
        assert_eq!(p[0].index, 5);
        assert_eq!(p[0].position, [3.0, 4.0, 1.5]);
        assert_eq!(p[1].position, [1.0, 2.0, 1.5]);
        cloud.check().unwrap();
    }

    #[test]
    fn a_posed_scan_with_times_is_not_taken_for_a_moving_scanner() {
        let mut cloud = PointCloud {
            xyz: vec![[0.0; 3]; 3],
            time: vec![1.0, 2.0, 3.0],
            ..Default::default()
        };
        assert!(
            cloud.is_mobile(),
            "times and no scans: a mobile scan until posed"
        );
        let pose = ScanPose {
            index: 0,
            position: [0.0, 0.0, 1.5],
            quaternion: ID,
        };
        attach_poses(&mut cloud, vec![pose]).unwrap();
        assert!(!cloud.is_mobile());
        assert!(
            cloud.time.is_empty(),
            "the times a posed scan no longer needs are kept"
        );
        cloud.check().unwrap();
    }

    #[test]
    fn mismatched_sidecars_name_the_index() {
        let pose = |index| ScanPose {
            index,
            position: [0.0; 3],
            quaternion: ID,
        };
        let mut cloud = cloud_with_scans(&[0, 1], [0.0; 3]);
        let err = attach_poses(&mut cloud, vec![pose(0)]).unwrap_err();
        assert!(err.to_string().contains("scan 1"), "{err}");
        let err = attach_poses(&mut cloud, vec![pose(0), pose(1), pose(9)]).unwrap_err();
        assert!(err.to_string().contains("index 9"), "{err}");
        let mut plain = PointCloud {
            xyz: vec![[0.0; 3]; 3],
            ..Default::default()
        };
        assert!(attach_poses(&mut plain, vec![pose(0), pose(1)]).is_err());
        attach_poses(&mut plain, vec![pose(4)]).unwrap();
        assert_eq!(plain.scan_ids, vec![4]);
        plain.check().unwrap();
    }

    #[test]
    fn trajectory_round_trip_and_interpolation() {
        let origin = [500_000.0, 4_000_000.0, 100.0];
        let samples = vec![
            TrajectorySample {
                t: 0.0,
                position: [0.0, 0.0, 1.0],
                quaternion: ID,
            },
            TrajectorySample {
                t: 2.0,
                position: [2.0, 4.0, 1.0],
                quaternion: ID,
            },
        ];
        let parsed = parse_trajectory(&trajectory_to_json(&samples, origin)).unwrap();
        assert_eq!(parsed[1].position, [500_002.0, 4_000_004.0, 101.0]);
        let mut cloud = PointCloud {
            origin,
            xyz: vec![[0.0; 3]; 2],
            time: vec![0.5, 1.5],
            ..Default::default()
        };
        attach_trajectory(&mut cloud, parsed).unwrap();
        let Viewpoints::Trajectory(local) = &cloud.viewpoints else {
            panic!("no path")
        };
        assert_eq!(local, &samples);
        assert_eq!(position_at(local, 1.0), [1.0, 2.0, 1.0]);
        assert_eq!(position_at(local, -1.0), [0.0, 0.0, 1.0]);
        assert_eq!(position_at(local, 9.0), [2.0, 4.0, 1.0]);
    }

    #[test]
    fn trajectory_errors() {
        let text = r#"{"samples": [{"t": 1, "position": [0,0,0], "quaternion": [1,0,0,0]},
                                   {"t": 1, "position": [0,0,0], "quaternion": [1,0,0,0]}]}"#;
        assert!(parse_trajectory(text)
            .unwrap_err()
            .to_string()
            .contains("samples[1]"));
        assert!(parse_trajectory(r#"{"samples": []}"#).is_err());
        let samples = vec![
            TrajectorySample {
                t: 0.0,
                position: [0.0; 3],
                quaternion: ID,
            },
            TrajectorySample {
                t: 1.0,
                position: [0.0; 3],
                quaternion: ID,
            },
        ];
        let mut cloud = PointCloud {
            xyz: vec![[0.0; 3]; 2],
            time: vec![0.5, 9.0],
            ..Default::default()
        };
        let err = attach_trajectory(&mut cloud, samples.clone()).unwrap_err();
        assert!(err.to_string().contains("point 1"), "{err}");
        let mut untimed = PointCloud {
            xyz: vec![[0.0; 3]; 2],
            ..Default::default()
        };
        assert!(attach_trajectory(&mut untimed, samples).is_err());
    }

    #[test]
    fn poses_round_trip_through_json() {
        let poses = vec![ScanPose {
            index: 3,
            position: [1.0, 2.0, 3.0],
            quaternion: [0.0, 0.0, 0.0, 1.0],
        }];
        let text = poses_to_json(&poses, [10.0, 20.0, 30.0]);
        let back = parse_poses(&text).unwrap();
        assert_eq!(back[0].position, [11.0, 22.0, 33.0]);
        assert_eq!(back[0].quaternion, [0.0, 0.0, 0.0, 1.0]);
    }
}
