//! A cloud's sidecar: where the scanner stood, as static poses or a mobile trajectory
//! (`docs/contract.md` §2). One type for every front end: read with the size cap, scaled with
//! the cloud, attached to it.

use std::path::Path;
use std::str::FromStr;

use super::poses::{self, attach_poses, attach_trajectory, PosesError};
use super::ReadError;
use crate::cloud::{PointCloud, ScanPose, TrajectorySample};

/// Which kind of sidecar came with the cloud.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SidecarKind {
    /// Static scan poses, `{"scans": [...]}`.
    Poses,
    /// A mobile scanner's path, `{"samples": [...]}`.
    Trajectory,
}

impl SidecarKind {
    /// The name used by the service's multipart part and upload record.
    pub fn name(self) -> &'static str {
        match self {
            SidecarKind::Poses => "poses",
            SidecarKind::Trajectory => "trajectory",
        }
    }
}

impl FromStr for SidecarKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "poses" => Ok(SidecarKind::Poses),
            "trajectory" => Ok(SidecarKind::Trajectory),
            other => Err(format!(
                "unknown sidecar `{other}` (expected poses or trajectory)"
            )),
        }
    }
}

/// Scanner positions from a sidecar, in world coordinates.
#[derive(Debug, Clone, PartialEq)]
pub enum Sidecar {
    /// Static scans: one pose per scan.
    Poses(Vec<ScanPose>),
    /// A mobile scan: the scanner's path, in time order.
    Trajectory(Vec<TrajectorySample>),
}

impl Sidecar {
    /// Reads and parses the sidecar file (refusing one over the size cap); errors name it.
    pub fn read(kind: SidecarKind, path: &Path) -> Result<Sidecar, ReadError> {
        Ok(match kind {
            SidecarKind::Poses => Sidecar::Poses(poses::read_poses(path)?),
            SidecarKind::Trajectory => Sidecar::Trajectory(poses::read_trajectory(path)?),
        })
    }

    /// Which kind of sidecar this is.
    pub fn kind(&self) -> SidecarKind {
        match self {
            Sidecar::Poses(_) => SidecarKind::Poses,
            Sidecar::Trajectory(_) => SidecarKind::Trajectory,
        }
    }

    /// Multiplies every position by `s`: a sidecar is in its cloud's units, so it takes the
    /// cloud's scale.
    pub fn scale(&mut self, s: f64) {
        let positions: Box<dyn Iterator<Item = &mut [f64; 3]>> = match self {
            Sidecar::Poses(p) => Box::new(p.iter_mut().map(|p| &mut p.position)),
            Sidecar::Trajectory(t) => Box::new(t.iter_mut().map(|t| &mut t.position)),
        };
        for p in positions {
            *p = p.map(|c| c * s);
        }
    }

    /// Attaches the positions to `cloud` (see [`attach_poses`], [`attach_trajectory`]).
    pub fn attach(self, cloud: &mut PointCloud) -> Result<(), PosesError> {
        match self {
            Sidecar::Poses(p) => attach_poses(cloud, p),
            Sidecar::Trajectory(t) => attach_trajectory(cloud, t),
        }
    }
}

/// Reads a sidecar, scaled by the cloud's `scale`, naming the file in errors.
pub(crate) fn read_scaled(
    kind: SidecarKind,
    path: &Path,
    scale: Option<f64>,
) -> Result<Sidecar, ReadError> {
    let mut sidecar = Sidecar::read(kind, path)?;
    if let Some(s) = scale {
        sidecar.scale(s);
    }
    Ok(sidecar)
}

/// A sidecar that does not fit its cloud, as a read error naming the sidecar.
pub(crate) fn misfit(path: &Path, e: PosesError) -> ReadError {
    ReadError::Poses {
        path: path.display().to_string(),
        why: e.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaling_reaches_every_position_and_names_parse_back() {
        let mut s = Sidecar::Trajectory(vec![
            TrajectorySample {
                t: 0.0,
                position: [1000.0, 2000.0, 1500.0],
                quaternion: [1.0, 0.0, 0.0, 0.0],
            },
            TrajectorySample {
                t: 1.0,
                position: [3000.0, 0.0, 1500.0],
                quaternion: [1.0, 0.0, 0.0, 0.0],
            },
        ]);
        s.scale(0.001);
        let Sidecar::Trajectory(t) = &s else {
            panic!("kind changed")
        };
        assert_eq!(t[0].position, [1.0, 2.0, 1.5]);
        assert_eq!(t[1].position, [3.0, 0.0, 1.5]);
        for k in [SidecarKind::Poses, SidecarKind::Trajectory] {
            assert_eq!(k.name().parse::<SidecarKind>(), Ok(k));
        }
        assert!("cloud".parse::<SidecarKind>().is_err());
    }
}
