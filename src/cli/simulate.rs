//! `asbuilt simulate`: build a synthetic building, scan it, and write what a surveyor would hand
//! over plus the exact answer.
//!
//! Files written to `--out DIR`:
//! - `cloud.ply`: the points in world coordinates (binary little-endian, or ASCII with
//!   `--ascii`), with `scan_index` for static scans or `time` for a mobile scan. Coordinates are
//!   `double` when `--offset` is given, `float` otherwise.
//! - `poses.json` (static) or `trajectory.json` (`--mobile`): the sidecars of
//!   `docs/contract.md` §2, world frame. With `--registration-error` the poses are the
//!   registered (erroneous) ones, consistent with the points.
//!   They are written in every `--keep` mode: with `scan-ids` or `plain` the cloud does not
//!   point to them, and they are the truth to compare estimated viewpoints against.
//! - `truth.json`: the ground truth as a floor-plan GeoJSON in the contract of §1 (one `story`
//!   feature per story with `floor_z`, `ceiling_z` and `area_m2`; one `wall` feature per wall
//!   face, `model` `line` or `arc` with `center` and `radius`; `floorplan.input.format` is
//!   `truth`), plus a foreign member `truth`:
//!   `{"building": NAME, "origin": [x, y, z], "stories": [{"level", "floor_z", "ceiling_z",
//!   "walls": [{"model": "line", "a": [x, y], "b": [x, y]} | {"model": "arc", "center": [x, y],
//!   "radius", "start", "sweep"}]}]}` with the exact walls in world coordinates (heights world
//!   too; arc angles in radians, counter-clockwise from +x, a negative sweep runs clockwise).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context};
use asbuilt_plan::cloud::Viewpoints;
use asbuilt_plan::io::{geojson, ply, poses};
use asbuilt_plan::simulate::{simulate, BuildingKind, Keep, ScanOptions, Truth, TruthWall};
use serde_json::json;

#[derive(clap::Args)]
pub struct SimulateArgs {
    /// The building: square_room, office_3story, curved_lobby, rotated_l, attic_house,
    /// mezzanine_hall, dense_office, dense_office_voxels, ceiling_only or partitions.
    #[arg(long, value_name = "NAME")]
    pub building: String,
    /// Points to generate.
    #[arg(long, value_name = "N", default_value_t = 1_000_000)]
    pub points: usize,
    /// Random seed; the same seed gives the same files.
    #[arg(long, value_name = "S", default_value_t = 1)]
    pub seed: u64,
    /// Per-scan registration error: T metres of shift and R degrees of yaw, e.g. `0.01,0.1`.
    #[arg(long, value_name = "T,R")]
    pub registration_error: Option<String>,
    /// Range noise standard deviation, metres.
    #[arg(long, value_name = "SIGMA", default_value_t = 0.0)]
    pub noise: f64,
    /// A mobile scanner walking through the rooms instead of static stations.
    #[arg(long)]
    pub mobile: bool,
    /// World coordinates of the building's origin, e.g. `500000,4100000,120`.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub offset: Option<String>,
    /// Reduce the cloud to the centres of the occupied voxels of this size, metres.
    #[arg(long, value_name = "METRES")]
    pub voxel: Option<f64>,
    /// Write the cloud as ASCII PLY instead of binary.
    #[arg(long)]
    pub ascii: bool,
    /// What the cloud keeps of how it was scanned: `poses` (scan ids or times; the sidecar
    /// fits them), `scan-ids` (the same cloud, meant to be planned without the sidecar) or
    /// `plain` (x, y, z only, shuffled).
    #[arg(long, value_name = "MODE", default_value = "poses")]
    pub keep: String,
    /// The folder to write into (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

pub fn run(args: SimulateArgs) -> anyhow::Result<ExitCode> {
    let kind = BuildingKind::from_name(&args.building).with_context(|| {
        let names: Vec<&str> = BuildingKind::ALL.iter().map(|(n, _)| *n).collect();
        format!(
            "unknown building `{}`; choose one of {}",
            args.building,
            names.join(", ")
        )
    })?;
    let registration = match &args.registration_error {
        Some(text) => {
            let [t, r] = numbers::<2>(text, "--registration-error")?;
            Some((t, r))
        }
        None => None,
    };
    let offset = match &args.offset {
        Some(text) => numbers::<3>(text, "--offset")?,
        None => [0.0; 3],
    };
    let keep = Keep::from_name(&args.keep).with_context(|| {
        let names: Vec<&str> = Keep::ALL.iter().map(|(n, _)| *n).collect();
        format!(
            "unknown --keep `{}`; choose one of {}",
            args.keep,
            names.join(", ")
        )
    })?;
    let options = ScanOptions {
        points: args.points,
        seed: args.seed,
        noise: args.noise,
        registration,
        mobile: args.mobile,
        offset,
        voxel: args.voxel,
        keep,
    };
    let sim = simulate(kind, &options)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let encoding = if args.ascii {
        ply::Encoding::Ascii
    } else {
        ply::Encoding::BinaryLittleEndian
    };
    let cloud_path = args.out.join("cloud.ply");
    ply::write_ply(&cloud_path, &sim.cloud, encoding)?;
    let sidecar = match &sim.scanners {
        Viewpoints::Static(p) => {
            let path = args.out.join("poses.json");
            poses::write_poses(&path, p, sim.cloud.origin)?;
            path
        }
        Viewpoints::Trajectory(s) => {
            let path = args.out.join("trajectory.json");
            poses::write_trajectory(&path, s, sim.cloud.origin)?;
            path
        }
        Viewpoints::None => bail!("the simulator produced no viewpoints"),
    };
    let truth_path = args.out.join("truth.json");
    std::fs::write(&truth_path, format!("{}\n", truth_json(&sim.truth)))
        .with_context(|| format!("writing {}", truth_path.display()))?;
    println!(
        "{}: {} points, {} stories, {}",
        kind.name(),
        sim.cloud.len(),
        sim.truth.stories.len(),
        match &sim.scanners {
            Viewpoints::Static(p) => format!("{} static scans", p.len()),
            Viewpoints::Trajectory(s) =>
                format!("a {} s trajectory", s.last().map_or(0.0, |s| s.t)),
            Viewpoints::None => String::new(),
        }
    );
    for p in [&cloud_path, &sidecar, &truth_path] {
        println!("wrote {}", p.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// `N` comma-separated finite numbers.
fn numbers<const N: usize>(text: &str, option: &str) -> anyhow::Result<[f64; N]> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != N {
        bail!("{option} takes {N} comma-separated numbers, not {text:?}");
    }
    let mut out = [0.0; N];
    for (slot, part) in out.iter_mut().zip(parts) {
        *slot = part
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .with_context(|| format!("{option}: {part:?} is not a number"))?;
    }
    Ok(out)
}

/// The truth as contract GeoJSON plus the exact walls (see the module doc).
fn truth_json(truth: &Truth) -> serde_json::Value {
    let o = truth.origin;
    let w = |p: [f64; 2]| [p[0] + o[0], p[1] + o[1]];
    let mut doc = geojson::to_geojson(&truth.to_floor_plan());
    let stories: Vec<_> = truth
        .stories
        .iter()
        .map(|s| {
            let walls: Vec<_> = s
                .walls
                .iter()
                .map(|wall| match *wall {
                    TruthWall::Line { a, b } => json!({"model": "line", "a": w(a), "b": w(b)}),
                    TruthWall::Arc {
                        center,
                        radius,
                        start,
                        sweep,
                    } => json!({"model": "arc", "center": w(center), "radius": radius, "start": start, "sweep": sweep}),
                })
                .collect();
            json!({
                "level": s.level,
                "floor_z": s.floor_z + o[2],
                "ceiling_z": s.ceiling_z + o[2],
                "walls": walls,
            })
        })
        .collect();
    doc["truth"] = json!({"building": truth.building, "origin": o, "stories": stories});
    doc
}
