//! The point cloud as the pipeline holds it, and the scanner viewpoints that came with it.
//!
//! Coordinates are stored as `f32` relative to a local `origin` (12 bytes a point), so that
//! georeferenced clouds with large offsets keep millimetre precision without doubling memory.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// A point cloud in a local frame: world = `origin` + local.
#[derive(Debug, Clone, Default)]
pub struct PointCloud {
    /// World coordinates of the local frame's origin.
    pub origin: [f64; 3],
    /// Local x, y, z of every point, in metres.
    pub xyz: Vec<[f32; 3]>,
    /// Per point: a scan slot, indexing `scan_ids` (and `Viewpoints::Static` when poses are known).
    /// Empty when the cloud names no scans.
    pub scan: Vec<u16>,
    /// Per scan slot: the scan's index as the user names it (PLY `scan_index`, LAS
    /// `point_source_id`, E57 scan number, sidecar `index`).
    pub scan_ids: Vec<u32>,
    /// Per point: acquisition time, for mobile scans. Empty when unknown.
    pub time: Vec<f64>,
    /// Where the scanner stood, when known.
    pub viewpoints: Viewpoints,
    /// The input's coordinate reference system (WKT or `EPSG:nnnn`), when declared.
    pub crs: Option<String>,
    /// What was read, for reports.
    pub source: SourceInfo,
}

/// A summary of the file a cloud came from.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct SourceInfo {
    /// Short format name: `ply`, `e57`, `las`, `laz`, `xyz`, `pts`, `memory`.
    pub format: String,
    /// Human-readable format details (version, encoding, point layout).
    pub details: String,
    /// Points skipped while reading (invalid or non-finite), with the reason.
    pub skipped: u64,
    /// Why points were skipped, when any were.
    pub skipped_reason: Option<String>,
    /// The units assumed for the coordinates.
    pub units: String,
}

/// Scanner positions: none, one pose per static scan, or a mobile trajectory.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum Viewpoints {
    /// Nothing is known about where the scanner was.
    #[default]
    None,
    /// One pose per scan slot, aligned with `PointCloud::scan_ids`.
    Static(Vec<ScanPose>),
    /// A time-ordered path; `PointCloud::time` locates each point on it.
    Trajectory(Vec<TrajectorySample>),
}

/// A static scan's pose, in local coordinates (same frame as `PointCloud::xyz`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScanPose {
    /// The scan's index as the user names it (sidecar `index`, LAS `point_source_id`, E57 scan number).
    pub index: u32,
    /// Scanner origin, local frame.
    pub position: [f64; 3],
    /// Rotation scanner → cloud frame, as `[w, x, y, z]`.
    pub quaternion: [f64; 4],
}

/// One sample of a mobile scanner's path, in local coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrajectorySample {
    /// Time of the sample, seconds, on the same clock as the points' times.
    pub t: f64,
    /// Scanner origin, local frame.
    pub position: [f64; 3],
    /// Rotation scanner → cloud frame, a unit quaternion.
    pub quaternion: [f64; 4],
}

impl PointCloud {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.xyz.len()
    }

    /// True when the cloud holds no points.
    pub fn is_empty(&self) -> bool {
        self.xyz.is_empty()
    }

    /// True when the points came from one moving scanner: they have times and at most one scan.
    pub fn is_mobile(&self) -> bool {
        !self.time.is_empty() && self.scan_ids.len() <= 1
    }

    /// Builds a cloud from world coordinates, choosing the origin at the first point's floor
    /// so that `f32` local coordinates stay small.
    pub fn from_world(points: &[[f64; 3]]) -> Self {
        let origin = local_origin(points.first().copied());
        let xyz = points.iter().map(|p| to_local(origin, *p)).collect();
        PointCloud {
            origin,
            xyz,
            ..Default::default()
        }
    }

    /// Axis-aligned bounds of the local coordinates, `None` when empty. Blocks of points
    /// on every core, their bounds merged in order (non-finite values are passed over).
    pub fn local_bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let widen = |(mut lo, mut hi): ([f32; 3], [f32; 3]), b: ([f32; 3], [f32; 3])| {
            for k in 0..3 {
                lo[k] = lo[k].min(b.0[k]);
                hi[k] = hi[k].max(b.1[k]);
            }
            (lo, hi)
        };
        self.xyz
            .par_chunks(CHECK_BLOCK)
            .map(block_bounds)
            .reduce_with(widen)
    }

    /// Checks the cross-field invariants readers must uphold.
    pub fn check(&self) -> Result<(), String> {
        self.check_arrays()?;
        if self.xyz.par_chunks(CHECK_BLOCK).any(|b| !all_finite(b)) {
            return Err(NON_FINITE.into());
        }
        Ok(())
    }

    /// [`Self::check`] but for the finiteness of the coordinates, for a caller that tests it
    /// in a pass over the points of its own (and then fails with [`NON_FINITE`]).
    pub fn check_arrays(&self) -> Result<(), String> {
        if !self.scan.is_empty() && self.scan.len() != self.xyz.len() {
            return Err(format!(
                "{} scan indices for {} points",
                self.scan.len(),
                self.xyz.len()
            ));
        }
        if !self.time.is_empty() && self.time.len() != self.xyz.len() {
            return Err(format!(
                "{} times for {} points",
                self.time.len(),
                self.xyz.len()
            ));
        }
        // Both scans over the points run on every core, in blocks: rayon's per-item `find` and
        // `any` pay for a shared stop flag on every point.
        let slots = self.scan_ids.len();
        if let Some(bad) = self
            .scan
            .par_chunks(CHECK_BLOCK)
            .filter_map(|b| b.iter().copied().max())
            .max()
            .filter(|&s| s as usize >= slots)
        {
            return Err(format!("scan slot {bad} but only {slots} scans"));
        }
        if let Viewpoints::Static(poses) = &self.viewpoints {
            if poses.len() != self.scan_ids.len() {
                return Err(format!(
                    "{} poses for {} scans",
                    poses.len(),
                    self.scan_ids.len()
                ));
            }
        }
        Ok(())
    }
}

/// What [`PointCloud::check`] says of a cloud with a non-finite coordinate.
pub const NON_FINITE: &str = "non-finite coordinate";

/// Points per parallel block of [`PointCloud::check`] and [`PointCloud::local_bounds`].
const CHECK_BLOCK: usize = 1 << 16;

/// The bounds of a non-empty block of points, as a fold over them from the first gives them.
/// Four points at a time in twelve lanes, which compile to vector instructions, then each lane
/// into its coordinate: min and max give the same result in any order.
fn block_bounds(block: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let first = block[0];
    let mut lo: [f32; 12] = std::array::from_fn(|i| first[i % 3]);
    let mut hi = lo;
    let mut quads = block.as_flattened().chunks_exact(12);
    for q in &mut quads {
        for i in 0..12 {
            lo[i] = lo[i].min(q[i]);
            hi[i] = hi[i].max(q[i]);
        }
    }
    let (mut l, mut h) = (first, first);
    for i in 0..12 {
        l[i % 3] = l[i % 3].min(lo[i]);
        h[i % 3] = h[i % 3].max(hi[i]);
    }
    for p in quads.remainder().chunks_exact(3) {
        for k in 0..3 {
            l[k] = l[k].min(p[k]);
            h[k] = h[k].max(p[k]);
        }
    }
    (l, h)
}

/// True when every coordinate of `block` is finite: one flag over all of them, with no early
/// exit inside the block, so the test compiles to vector instructions.
fn all_finite(block: &[[f32; 3]]) -> bool {
    let bad = block
        .as_flattened()
        .iter()
        .fold(0u32, |bad, c| bad | u32::from(!c.is_finite()));
    bad == 0
}

/// Picks a local origin near `first`, rounded to whole kilometres so nearby clouds share it.
pub fn local_origin(first: Option<[f64; 3]>) -> [f64; 3] {
    match first {
        Some(p) if p.iter().any(|c| c.abs() > 1.0e4) => p.map(|c| (c / 1000.0).round() * 1000.0),
        _ => [0.0; 3],
    }
}

/// World → local `f32` coordinates.
pub fn to_local(origin: [f64; 3], p: [f64; 3]) -> [f32; 3] {
    [
        (p[0] - origin[0]) as f32,
        (p[1] - origin[1]) as f32,
        (p[2] - origin[2]) as f32,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_in_blocks_are_the_bounds_in_one_pass() {
        let n = 3 * CHECK_BLOCK + 17;
        let mut xyz: Vec<[f32; 3]> = (0..n)
            .map(|k| {
                let v = (k as f32 * 0.618).sin();
                [v * 40.0, (k % 977) as f32 * -0.01, v * v]
            })
            .collect();
        xyz[5] = [f32::NAN, 1e6, f32::NAN];
        xyz[2 * CHECK_BLOCK] = [-7e5, f32::INFINITY, -3.0];
        let cloud = PointCloud {
            xyz: xyz.clone(),
            ..Default::default()
        };
        let first = xyz[0];
        let serial = xyz.iter().fold((first, first), |(mut lo, mut hi), p| {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
            (lo, hi)
        });
        assert_eq!(cloud.local_bounds(), Some(serial));
        assert_eq!(PointCloud::default().local_bounds(), None);
    }

    #[test]
    fn check_finds_a_non_finite_coordinate_anywhere() {
        let n = 2 * CHECK_BLOCK + 7;
        let good = PointCloud {
            xyz: (0..n).map(|k| [k as f32, -1.0, 0.5]).collect(),
            ..Default::default()
        };
        assert_eq!(good.check(), Ok(()));
        // In a block's vector part, its last point, and the last block's short tail.
        for at in [0, 5, CHECK_BLOCK - 1, CHECK_BLOCK + 12, n - 1] {
            for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                let mut c = good.clone();
                c.xyz[at][at % 3] = bad;
                assert_eq!(c.check(), Err(NON_FINITE.to_string()), "{at} {bad}");
            }
        }
    }
}
