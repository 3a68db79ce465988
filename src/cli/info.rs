//! `asbuilt info`: what a point cloud holds, read once, without running the pipeline.

use std::fmt::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use asbuilt_plan::cloud::{PointCloud, Viewpoints};

#[derive(clap::Args)]
pub struct InfoArgs {
    /// The point cloud: PLY, E57, LAS/LAZ, XYZ or PTS.
    pub input: PathBuf,
    /// Static scanner poses to attach and check against the cloud's scans.
    #[arg(long, value_name = "FILE", conflicts_with = "trajectory")]
    pub poses: Option<PathBuf>,
    /// A mobile scanner's path to attach and check against the points' times.
    #[arg(long, value_name = "FILE")]
    pub trajectory: Option<PathBuf>,
    #[command(flatten)]
    pub read: super::plan::ReadArgs,
}

pub fn run(args: InfoArgs) -> anyhow::Result<ExitCode> {
    let sidecar = super::plan::sidecar(args.poses.as_deref(), args.trajectory.as_deref());
    let cloud = asbuilt_plan::io::read_scan(&args.input, sidecar, &args.read.options())?;
    print!("{}", describe(&args.input.display().to_string(), &cloud));
    Ok(ExitCode::SUCCESS)
}

/// Lists this many ids or positions at most; the counts are always complete.
const SHOWN: usize = 20;

/// The report, one `name: value` line per fact, in world coordinates.
pub fn describe(name: &str, cloud: &PointCloud) -> String {
    let mut s = String::new();
    let src = &cloud.source;
    let _ = writeln!(s, "file: {name}");
    let _ = writeln!(s, "format: {} ({})", src.format, src.details);
    let _ = writeln!(s, "points: {}", cloud.len());
    match &src.skipped_reason {
        Some(why) => {
            let _ = writeln!(s, "skipped: {} ({why})", src.skipped);
        }
        None => {
            let _ = writeln!(s, "skipped: {}", src.skipped);
        }
    }
    let units = if src.units.is_empty() {
        "m"
    } else {
        &src.units
    };
    let _ = writeln!(s, "units: {units}");
    if let Err(e) = asbuilt_plan::io::check_units(cloud) {
        let _ = writeln!(s, "units warning: {e}");
    }
    let _ = writeln!(s, "crs: {}", cloud.crs.as_deref().unwrap_or("none"));
    let o = cloud.origin;
    let _ = writeln!(s, "local origin: {:.3} {:.3} {:.3}", o[0], o[1], o[2]);
    match cloud.local_bounds() {
        Some((lo, hi)) => {
            let w = |k: usize, v: f32| o[k] + f64::from(v);
            let _ = writeln!(
                s,
                "bounds min: {:.3} {:.3} {:.3}",
                w(0, lo[0]),
                w(1, lo[1]),
                w(2, lo[2])
            );
            let _ = writeln!(
                s,
                "bounds max: {:.3} {:.3} {:.3}",
                w(0, hi[0]),
                w(1, hi[1]),
                w(2, hi[2])
            );
            let _ = writeln!(
                s,
                "size: {:.3} x {:.3} x {:.3} m",
                hi[0] - lo[0],
                hi[1] - lo[1],
                hi[2] - lo[2]
            );
        }
        None => {
            let _ = writeln!(s, "bounds: none (no points)");
        }
    }
    let _ = writeln!(
        s,
        "scans: {}{}",
        cloud.scan_ids.len(),
        listed(cloud.scan_ids.iter().map(|i| i.to_string()))
    );
    match &cloud.viewpoints {
        Viewpoints::None => {
            let _ = writeln!(s, "viewpoints: none");
        }
        Viewpoints::Static(poses) => {
            let _ = writeln!(s, "poses: {}", poses.len());
            for p in poses.iter().take(SHOWN) {
                let q = p.position;
                let _ = writeln!(
                    s,
                    "  scan {}: {:.3} {:.3} {:.3}",
                    p.index,
                    q[0] + o[0],
                    q[1] + o[1],
                    q[2] + o[2]
                );
            }
            if poses.len() > SHOWN {
                let _ = writeln!(s, "  … {} more", poses.len() - SHOWN);
            }
        }
        Viewpoints::Trajectory(samples) => {
            let _ = write!(s, "trajectory: {} samples", samples.len());
            if let (Some(a), Some(b)) = (samples.first(), samples.last()) {
                let _ = write!(s, ", t {} .. {}", a.t, b.t);
            }
            s.push('\n');
        }
    }
    if !cloud.time.is_empty() {
        let (lo, hi) = cloud
            .time
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| {
                (lo.min(t), hi.max(t))
            });
        let _ = writeln!(s, "point times: {lo} .. {hi}");
    }
    s
}

/// `" (a, b, c, … n more)"`, or nothing for an empty list.
fn listed(items: impl ExactSizeIterator<Item = String>) -> String {
    let n = items.len();
    if n == 0 {
        return String::new();
    }
    let shown: Vec<String> = items.take(SHOWN).collect();
    let more = if n > SHOWN {
        format!(", … {} more", n - SHOWN)
    } else {
        String::new()
    };
    format!(" ({}{more})", shown.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use asbuilt_plan::cloud::ScanPose;

    #[test]
    fn describes_counts_bounds_scans_and_poses_in_world_frame() {
        let mut cloud =
            PointCloud::from_world(&[[500_000.0, 10.0, 100.0], [500_004.0, 13.0, 102.5]]);
        cloud.scan = vec![0, 1];
        cloud.scan_ids = vec![7, 9];
        cloud.viewpoints = Viewpoints::Static(vec![
            ScanPose {
                index: 7,
                position: [1.0, 2.0, 1.5],
                quaternion: [1.0, 0.0, 0.0, 0.0],
            },
            ScanPose {
                index: 9,
                position: [3.0, 2.0, 1.5],
                quaternion: [1.0, 0.0, 0.0, 0.0],
            },
        ]);
        cloud.source.format = "ply".into();
        cloud.source.details = "ascii 1.0".into();
        cloud.crs = Some("EPSG:25832".into());
        let text = describe("room.ply", &cloud);
        assert!(text.contains("points: 2\n"), "{text}");
        assert!(text.contains("format: ply (ascii 1.0)\n"));
        assert!(text.contains("crs: EPSG:25832\n"));
        assert!(text.contains("units: m\n"));
        assert!(
            text.contains("bounds min: 500000.000 10.000 100.000\n"),
            "{text}"
        );
        assert!(
            text.contains("bounds max: 500004.000 13.000 102.500\n"),
            "{text}"
        );
        assert!(text.contains("scans: 2 (7, 9)\n"));
        assert!(text.contains("poses: 2\n"));
        // Pose positions are local; the report adds the origin back.
        let origin = cloud.origin;
        let line = format!(
            "  scan 9: {:.3} {:.3} {:.3}\n",
            3.0 + origin[0],
            2.0 + origin[1],
            1.5 + origin[2]
        );
        assert!(text.contains(&line), "{text}");
    }

    #[test]
    fn long_lists_are_cut() {
        let s = listed((0..25).map(|i| i.to_string()));
        assert!(s.ends_with(", 19, … 5 more)"), "{s}");
        assert_eq!(listed(std::iter::empty()), "");
    }
}
