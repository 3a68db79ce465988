//! Static scan poses: `{"scans": [{"index", "position", "quaternion"}]}`, read through a JSON
//! tree so that each error names the entry and the field.

use std::collections::HashMap;
use std::path::Path;

use serde_json::Value;

use super::{
    local_to_world, read_sidecar, sidecar_error, unit_quaternion, world_to_local, write_text,
    PosesError, MAX_COORDINATE,
};
use crate::cloud::{PointCloud, ScanPose, Viewpoints};
use crate::io::ReadError;

/// More scans than this cannot be told apart (`PointCloud::scan` holds `u16` slots).
pub const MAX_SCANS: usize = u16::MAX as usize + 1;

/// A static pose sidecar larger than this is no sidecar: 65,536 scans take about 10 MB.
pub const MAX_POSES_BYTES: u64 = 64 << 20;

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

/// Attaches world-frame static poses to a cloud whose points name their scans.
///
/// Every scan the cloud names needs a pose and every pose must name a scan of the cloud. A cloud
/// that names no scans takes exactly one pose, which then applies to every point. The points'
/// times are dropped.
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
    // Posed scanners stood still: their points' times say nothing the poses do not, and a
    // single posed scan with times must not be taken for a moving scanner's.
    cloud.time = Vec::new();
    Ok(())
}

/// Reads and parses a static pose sidecar; errors name the file.
pub fn read_poses(path: &Path) -> Result<Vec<ScanPose>, ReadError> {
    let text = read_sidecar(path, MAX_POSES_BYTES)?;
    parse_poses(&text).map_err(|e| sidecar_error(path, e))
}

/// Reads a static pose sidecar and attaches it to `cloud` (see [`attach_poses`]).
pub fn load_poses(cloud: &mut PointCloud, path: &Path) -> Result<(), ReadError> {
    let poses = read_poses(path)?;
    attach_poses(cloud, poses).map_err(|e| sidecar_error(path, e))
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

/// Writes a static pose sidecar (see [`poses_to_json`]).
pub fn write_poses(path: &Path, poses: &[ScanPose], origin: [f64; 3]) -> Result<(), PosesError> {
    write_text(path, &poses_to_json(poses, origin))
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
