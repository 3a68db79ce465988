//! The pose sidecars of `docs/contract.md` §2: static scan poses and mobile trajectories.
//! Sidecar positions are in the cloud's world frame; attaching converts them to the local frame.
//!
//! Parsing checks every entry: finite numbers, three-element positions, unit quaternions
//! (within [`QUATERNION_TOLERANCE`], then renormalised), unique scan indices and increasing times.
//! Unknown keys are ignored, as the contract promises.

use std::collections::HashMap;
use std::path::Path;

use serde_json::Value;

use super::ReadError;
use crate::cloud::{PointCloud, ScanPose, TrajectorySample, Viewpoints};

/// How far a quaternion's norm may stray from 1 before it is an error rather than rounding.
pub const QUATERNION_TOLERANCE: f64 = 1.0e-3;

/// More scans than this cannot be told apart (`PointCloud::scan` holds `u16` slots).
pub const MAX_SCANS: usize = u16::MAX as usize + 1;

/// A trajectory longer than this is not a plausible path (a day at 100 Hz is 8.6 M samples).
pub const MAX_TRAJECTORY_SAMPLES: usize = 50_000_000;

/// Positions farther than this from zero, in metres, are not on this planet.
const MAX_COORDINATE: f64 = 1.0e9;

/// Why a sidecar could not be used. Messages name the offending index.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PosesError {
    #[error("not valid pose JSON: {0}")]
    Json(String),
    /// One entry is malformed; the message names the entry and the field.
    #[error("{0}")]
    Invalid(String),
    #[error("{0}")]
    Mismatch(String),
    #[error("cannot write {path}: {why}")]
    Write { path: String, why: String },
}

/// Parses `{"scans": [{"index", "position", "quaternion"}]}` (world frame).
pub fn parse_poses(text: &str) -> Result<Vec<ScanPose>, PosesError> {
    let entries = top_level_array(text, "scans")?;
    if entries.len() > MAX_SCANS {
        return Err(PosesError::Invalid(format!(
            "{} scans, more than the {MAX_SCANS} a cloud can name",
            entries.len()
        )));
    }
    let mut seen: HashMap<u32, usize> = HashMap::with_capacity(entries.len());
    let mut poses = Vec::with_capacity(entries.len());
    for (k, entry) in entries.iter().enumerate() {
        let raw_index = field(entry, "index", || format!("scans[{k}]"))?;
        let index = raw_index
            .as_u64()
            .filter(|&i| i <= u64::from(u32::MAX))
            .ok_or_else(|| {
                PosesError::Invalid(format!(
                    "scans[{k}]: `index` must be a whole number from 0 to {}, not {raw_index}",
                    u32::MAX
                ))
            })? as u32;
        let at = || format!("scans[{k}] (index {index})");
        if let Some(first) = seen.insert(index, k) {
            return Err(PosesError::Invalid(format!(
                "{}: duplicate index, already given by scans[{first}]",
                at()
            )));
        }
        let position = position_of(entry, &at)?;
        let quaternion = quaternion_of(entry, &at)?;
        poses.push(ScanPose {
            index,
            position,
            quaternion,
        });
    }
    Ok(poses)
}

/// Parses `{"samples": [{"t", "position", "quaternion"}]}` (world frame). Times must increase.
///
/// Trajectories can be long, so they are deserialised straight into typed samples (about 64
/// bytes each) rather than through a JSON tree; type errors name the line and column.
pub fn parse_trajectory(text: &str) -> Result<Vec<TrajectorySample>, PosesError> {
    let doc: TrajectoryDoc =
        serde_json::from_str(text).map_err(|e| PosesError::Json(e.to_string()))?;
    check_trajectory(doc.samples)
}

#[derive(serde::Deserialize)]
struct TrajectoryDoc {
    samples: Vec<RawSample>,
}

#[derive(serde::Deserialize)]
struct RawSample {
    t: f64,
    position: [f64; 3],
    quaternion: [f64; 4],
}

fn check_trajectory(raw: Vec<RawSample>) -> Result<Vec<TrajectorySample>, PosesError> {
    if raw.is_empty() {
        return Err(PosesError::Invalid("the trajectory has no samples".into()));
    }
    if raw.len() > MAX_TRAJECTORY_SAMPLES {
        return Err(PosesError::Invalid(format!(
            "{} trajectory samples, more than the limit of {MAX_TRAJECTORY_SAMPLES}",
            raw.len()
        )));
    }
    let mut samples: Vec<TrajectorySample> = Vec::with_capacity(raw.len());
    for (k, r) in raw.into_iter().enumerate() {
        let at = || format!("samples[{k}]");
        let t = finite(r.t, &|| format!("{}.t", at()))?;
        if let Some(prev) = samples.last() {
            if t <= prev.t {
                return Err(PosesError::Invalid(format!(
                    "{}: time {t} does not come after the previous sample's {}; samples must be in increasing time order",
                    at(),
                    prev.t
                )));
            }
        }
        let mut position = [0.0; 3];
        for (i, c) in r.position.into_iter().enumerate() {
            position[i] = finite(c, &|| format!("{}.position[{i}]", at()))?;
        }
        let quaternion = unit_quaternion(r.quaternion, &at)?;
        samples.push(TrajectorySample {
            t,
            position,
            quaternion,
        });
    }
    Ok(samples)
}

/// Attaches world-frame static poses to a cloud whose points name their scans.
///
/// Every scan the cloud names needs a pose and every pose must name a scan of the cloud. A cloud
/// that names no scans takes exactly one pose, which then applies to every point.
pub fn attach_poses(cloud: &mut PointCloud, poses: Vec<ScanPose>) -> Result<(), PosesError> {
    if poses.is_empty() {
        return Err(PosesError::Mismatch("the pose file lists no scans".into()));
    }
    if cloud.scan_ids.is_empty() {
        if poses.len() != 1 {
            return Err(PosesError::Mismatch(format!(
                "the cloud's points name no scans (no scan_index property) but the pose file lists {} scans; \
                 give one pose, or a cloud whose points carry their scan index",
                poses.len()
            )));
        }
        cloud.scan = vec![0; cloud.len()];
        cloud.scan_ids = vec![poses[0].index];
    }
    let by_index: HashMap<u32, &ScanPose> = poses.iter().map(|p| (p.index, p)).collect();
    if let Some(missing) = cloud.scan_ids.iter().find(|i| !by_index.contains_key(i)) {
        return Err(PosesError::Mismatch(format!(
            "the cloud has points of scan {missing} but the pose file has no scan with index {missing}"
        )));
    }
    if poses.len() > cloud.scan_ids.len() {
        let ids: std::collections::HashSet<u32> = cloud.scan_ids.iter().copied().collect();
        let extra = poses
            .iter()
            .find(|p| !ids.contains(&p.index))
            .map(|p| p.index)
            .unwrap_or_default();
        return Err(PosesError::Mismatch(format!(
            "the pose file has scan index {extra} but no point of the cloud belongs to scan {extra}"
        )));
    }
    let local = cloud
        .scan_ids
        .iter()
        .map(|i| {
            let p = by_index[i];
            ScanPose {
                position: world_to_local(cloud.origin, p.position),
                ..*p
            }
        })
        .collect();
    cloud.viewpoints = Viewpoints::Static(local);
    Ok(())
}

/// Attaches a world-frame trajectory to a cloud whose points carry times.
///
/// Every point's time must fall within the trajectory's time span, give or take one sample
/// interval, since the scanner's position is interpolated there.
pub fn attach_trajectory(
    cloud: &mut PointCloud,
    samples: Vec<TrajectorySample>,
) -> Result<(), PosesError> {
    if samples.is_empty() {
        return Err(PosesError::Mismatch("the trajectory has no samples".into()));
    }
    if cloud.time.is_empty() {
        return Err(PosesError::Mismatch(
            "the cloud's points carry no time (no `time` property), so a trajectory cannot place them"
                .into(),
        ));
    }
    let t0 = samples[0].t;
    let t1 = samples[samples.len() - 1].t;
    let slack = samples
        .windows(2)
        .map(|w| w[1].t - w[0].t)
        .fold(0.0_f64, f64::max);
    if let Some((k, t)) = cloud
        .time
        .iter()
        .enumerate()
        .find(|(_, &t)| !(t >= t0 - slack && t <= t1 + slack))
    {
        return Err(PosesError::Mismatch(format!(
            "point {k} has time {t}, outside the trajectory's span {t0} to {t1}"
        )));
    }
    let local = samples
        .into_iter()
        .map(|s| TrajectorySample {
            position: world_to_local(cloud.origin, s.position),
            ..s
        })
        .collect();
    cloud.viewpoints = Viewpoints::Trajectory(local);
    Ok(())
}

/// The scanner position at time `t`, linearly interpolated (clamped at the ends).
/// `samples` must be non-empty and in increasing time order.
pub fn position_at(samples: &[TrajectorySample], t: f64) -> [f64; 3] {
    let k = samples.partition_point(|s| s.t <= t);
    if k == 0 {
        return samples[0].position;
    }
    if k == samples.len() {
        return samples[k - 1].position;
    }
    let (a, b) = (&samples[k - 1], &samples[k]);
    let f = (t - a.t) / (b.t - a.t);
    std::array::from_fn(|i| a.position[i] + f * (b.position[i] - a.position[i]))
}

/// A static pose sidecar larger than this is no sidecar: 65,536 scans take about 10 MB.
pub const MAX_POSES_BYTES: u64 = 64 << 20;
/// A trajectory sidecar larger than this is refused (about 9 M samples).
pub const MAX_TRAJECTORY_BYTES: u64 = 1 << 30;

/// Reads and parses a static pose sidecar; errors name the file.
pub fn read_poses(path: &Path) -> Result<Vec<ScanPose>, ReadError> {
    let text = read_sidecar(path, MAX_POSES_BYTES)?;
    parse_poses(&text).map_err(|e| sidecar_error(path, e))
}

/// Reads and parses a trajectory sidecar, streaming from the file; errors name the file.
pub fn read_trajectory(path: &Path) -> Result<Vec<TrajectorySample>, ReadError> {
    let file = open_sidecar(path, MAX_TRAJECTORY_BYTES)?;
    let doc: TrajectoryDoc = serde_json::from_reader(std::io::BufReader::new(file))
        .map_err(|e| sidecar_error(path, PosesError::Json(e.to_string())))?;
    check_trajectory(doc.samples).map_err(|e| sidecar_error(path, e))
}

/// Reads a static pose sidecar and attaches it to `cloud` (see [`attach_poses`]).
pub fn load_poses(cloud: &mut PointCloud, path: &Path) -> Result<(), ReadError> {
    let poses = read_poses(path)?;
    attach_poses(cloud, poses).map_err(|e| sidecar_error(path, e))
}

/// Reads a trajectory sidecar and attaches it to `cloud` (see [`attach_trajectory`]).
pub fn load_trajectory(cloud: &mut PointCloud, path: &Path) -> Result<(), ReadError> {
    let samples = read_trajectory(path)?;
    attach_trajectory(cloud, samples).map_err(|e| sidecar_error(path, e))
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

/// Static poses as a §2 sidecar, in world coordinates (local + `origin`).
pub fn poses_to_json(poses: &[ScanPose], origin: [f64; 3]) -> String {
    let scans: Vec<Value> = poses
        .iter()
        .map(|p| {
            serde_json::json!({
                "index": p.index,
                "position": local_to_world(origin, p.position),
                "quaternion": p.quaternion,
            })
        })
        .collect();
    format!("{}\n", serde_json::json!({ "scans": scans }))
}

/// A trajectory as a §2 sidecar, in world coordinates (local + `origin`).
pub fn trajectory_to_json(samples: &[TrajectorySample], origin: [f64; 3]) -> String {
    let samples: Vec<Value> = samples
        .iter()
        .map(|s| {
            serde_json::json!({
                "t": s.t,
                "position": local_to_world(origin, s.position),
                "quaternion": s.quaternion,
            })
        })
        .collect();
    format!("{}\n", serde_json::json!({ "samples": samples }))
}

/// Writes a static pose sidecar (see [`poses_to_json`]).
pub fn write_poses(path: &Path, poses: &[ScanPose], origin: [f64; 3]) -> Result<(), PosesError> {
    write_text(path, &poses_to_json(poses, origin))
}

/// Writes a trajectory sidecar (see [`trajectory_to_json`]).
pub fn write_trajectory(
    path: &Path,
    samples: &[TrajectorySample],
    origin: [f64; 3],
) -> Result<(), PosesError> {
    write_text(path, &trajectory_to_json(samples, origin))
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

/// The array under `key` in the top-level object.
fn top_level_array(text: &str, key: &str) -> Result<Vec<Value>, PosesError> {
    let root: Value = serde_json::from_str(text).map_err(|e| PosesError::Json(e.to_string()))?;
    let Value::Object(mut map) = root else {
        return Err(PosesError::Json(format!(
            "expected an object with a `{key}` array at the top level"
        )));
    };
    match map.remove(key) {
        Some(Value::Array(entries)) => Ok(entries),
        Some(other) => Err(PosesError::Json(format!(
            "`{key}` must be an array, not {}",
            kind(&other)
        ))),
        None => Err(PosesError::Json(format!(
            "no `{key}` array at the top level"
        ))),
    }
}

fn field<'a>(
    entry: &'a Value,
    name: &str,
    at: impl Fn() -> String,
) -> Result<&'a Value, PosesError> {
    entry
        .as_object()
        .ok_or_else(|| PosesError::Invalid(format!("{}: not an object", at())))?
        .get(name)
        .ok_or_else(|| PosesError::Invalid(format!("{}: no `{name}`", at())))
}

fn number(value: &Value, at: &dyn Fn() -> String) -> Result<f64, PosesError> {
    value
        .as_f64()
        .filter(|v| v.is_finite() && v.abs() <= MAX_COORDINATE)
        .ok_or_else(|| {
            PosesError::Invalid(format!("{}: expected a finite number, not {value}", at()))
        })
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

fn numbers<const N: usize>(
    entry: &Value,
    name: &str,
    at: &dyn Fn() -> String,
) -> Result<[f64; N], PosesError> {
    let value = field(entry, name, at)?;
    let items = value.as_array().filter(|a| a.len() == N).ok_or_else(|| {
        PosesError::Invalid(format!(
            "{}: `{name}` must be an array of {N} numbers, not {value}",
            at()
        ))
    })?;
    let mut out = [0.0; N];
    for (k, item) in items.iter().enumerate() {
        out[k] = number(item, &|| format!("{}.{name}[{k}]", at()))?;
    }
    Ok(out)
}

fn position_of(entry: &Value, at: &dyn Fn() -> String) -> Result<[f64; 3], PosesError> {
    numbers::<3>(entry, "position", at)
}

/// A `[w, x, y, z]` unit quaternion, renormalised when within tolerance of unit length.
fn quaternion_of(entry: &Value, at: &dyn Fn() -> String) -> Result<[f64; 4], PosesError> {
    unit_quaternion(numbers::<4>(entry, "quaternion", at)?, at)
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

fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
