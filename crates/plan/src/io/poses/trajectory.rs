//! Mobile trajectories: `{"samples": [{"t", "position", "quaternion"}]}`, deserialised straight
//! into typed samples since they can be long.

use std::path::Path;

use serde_json::Value;

use super::{
    finite, local_to_world, open_sidecar, sidecar_error, unit_quaternion, world_to_local,
    write_text, PosesError,
};
use crate::cloud::{PointCloud, TrajectorySample, Viewpoints};
use crate::io::ReadError;

/// A trajectory longer than this is not a plausible path (a day at 100 Hz is 8.6 M samples).
pub const MAX_TRAJECTORY_SAMPLES: usize = 50_000_000;

/// A trajectory sidecar larger than this is refused (about 9 M samples).
pub const MAX_TRAJECTORY_BYTES: u64 = 1 << 30;

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

/// Reads and parses a trajectory sidecar, streaming from the file; errors name the file.
pub fn read_trajectory(path: &Path) -> Result<Vec<TrajectorySample>, ReadError> {
    let file = open_sidecar(path, MAX_TRAJECTORY_BYTES)?;
    let doc: TrajectoryDoc = serde_json::from_reader(std::io::BufReader::new(file))
        .map_err(|e| sidecar_error(path, PosesError::Json(e.to_string())))?;
    check_trajectory(doc.samples).map_err(|e| sidecar_error(path, e))
}

/// Reads a trajectory sidecar and attaches it to `cloud` (see [`attach_trajectory`]).
pub fn load_trajectory(cloud: &mut PointCloud, path: &Path) -> Result<(), ReadError> {
    let samples = read_trajectory(path)?;
    attach_trajectory(cloud, samples).map_err(|e| sidecar_error(path, e))
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

/// Writes a trajectory sidecar (see [`trajectory_to_json`]).
pub fn write_trajectory(
    path: &Path,
    samples: &[TrajectorySample],
    origin: [f64; 3],
) -> Result<(), PosesError> {
    write_text(path, &trajectory_to_json(samples, origin))
}
