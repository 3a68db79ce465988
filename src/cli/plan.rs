//! `asbuilt plan`: read a cloud, attach its scanner poses, run the pipeline, write the plan.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{bail, Context};
use asbuilt_plan::io::outputs::{Output, OUTPUTS};
use asbuilt_plan::io::{Format, ReadOptions, SidecarKind};
use asbuilt_plan::streaming::StreamingParams;
use asbuilt_plan::{FloorPlan, Params, Planned, RunError, Scan};

use super::progress::Bar;

#[derive(clap::Args)]
pub struct PlanArgs {
    /// The point cloud: PLY, E57, LAS/LAZ, XYZ or PTS (chosen from the file's content).
    pub input: PathBuf,
    /// Write the GeoJSON plan here instead of standard output.
    #[arg(short, long, visible_alias = "geojson", value_name = "FILE")]
    pub output: Option<PathBuf>,
    // `--svg FILE`, `--dxf FILE`, `--ifc FILE`, ...: one flag per output of the list.
    #[command(flatten)]
    pub outputs: OutputFlags,
    /// Static scanner poses, `{"scans": [{"index", "position", "quaternion"}]}`.
    #[arg(long, value_name = "FILE", conflicts_with = "trajectory")]
    pub poses: Option<PathBuf>,
    /// A mobile scanner's path, `{"samples": [{"t", "position", "quaternion"}]}`.
    #[arg(long, value_name = "FILE")]
    pub trajectory: Option<PathBuf>,
    /// Parameters from a TOML or JSON file; `--param` overrides them.
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Override one parameter, e.g. `--param samples.cell_size=0.05`. Repeatable.
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub overrides: Vec<String>,
    /// Expected registration error between scans, metres (turns on sample smoothing).
    #[arg(long, value_name = "M")]
    pub registration_error: Option<f64>,
    #[command(flatten)]
    pub read: ReadArgs,
    #[command(flatten)]
    pub georef: GeorefArgs,
    /// Include each story's wall samples in the outputs.
    #[arg(long)]
    pub emit_samples: bool,
    /// Draw each story's points at mid-height (the underlay) under the SVG plan.
    #[arg(long)]
    pub svg_underlay: bool,
    /// No progress bar, timings or notes on standard error.
    #[arg(short, long)]
    pub quiet: bool,
    /// Stream the cloud instead of holding it in memory, keeping the run's data within SIZE
    /// (e.g. `1GiB`, `512MiB`): for scans larger than memory. PLY, LAS and LAZ; the plan is
    /// the in-memory one. Tile files go to the system's temporary folder (`TMPDIR`).
    #[arg(long, value_name = "SIZE")]
    pub max_memory: Option<String>,
    /// Write every stage's time, writing included, as a JSON object (for `asbuilt bench`).
    #[arg(long, value_name = "FILE", hide = true)]
    pub timings: Option<PathBuf>,
}

/// The files asked for with `--NAME FILE`, one flag per output of [`OUTPUTS`] (GeoJSON has
/// `-o` instead), so a new format gets its flag from its row.
#[derive(Clone, Debug, Default)]
pub struct OutputFlags(pub Vec<(&'static Output, PathBuf)>);

impl OutputFlags {
    /// Every output but the GeoJSON, which `-o` names.
    fn flagged() -> impl Iterator<Item = &'static Output> {
        OUTPUTS.iter().filter(|o| o.name != "geojson")
    }
}

impl clap::FromArgMatches for OutputFlags {
    fn from_arg_matches(matches: &clap::ArgMatches) -> Result<Self, clap::Error> {
        let mut flags = OutputFlags::default();
        flags.update_from_arg_matches(matches)?;
        Ok(flags)
    }

    fn update_from_arg_matches(&mut self, matches: &clap::ArgMatches) -> Result<(), clap::Error> {
        for output in OutputFlags::flagged() {
            if let Some(path) = matches.get_one::<PathBuf>(output.name) {
                self.0.retain(|(o, _)| o.name != output.name);
                self.0.push((output, path.clone()));
            }
        }
        Ok(())
    }
}

impl clap::Args for OutputFlags {
    fn augment_args(cmd: clap::Command) -> clap::Command {
        OutputFlags::flagged().fold(cmd, |cmd, o| {
            cmd.arg(
                clap::Arg::new(o.name)
                    .long(o.name)
                    .value_name("FILE")
                    .value_parser(clap::value_parser!(PathBuf))
                    .help(format!("Also write {} ({})", o.about, o.file)),
            )
        })
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        OutputFlags::augment_args(cmd)
    }
}

/// Where the scan lies on the earth, given or overriding what the file declares: a CRS, or a
/// local frame placed by an anchor. The fields are those of the API's `georeference`.
#[derive(clap::Args, Clone, Default)]
pub struct GeorefArgs {
    /// The projected CRS of the scan's coordinates, `EPSG:n` or WKT (replaces the file's own).
    #[arg(long, value_name = "EPSG:N|WKT", conflicts_with = "anchor")]
    pub crs: Option<String>,
    /// A local frame: the WGS84 longitude and latitude (degrees) and the height (metres above
    /// `--height-datum`) of the local point `--anchor-at`.
    #[arg(long, value_name = "LON,LAT,H", value_parser = triple, allow_hyphen_values = true)]
    pub anchor: Option<[f64; 3]>,
    /// The local point the anchor places (default 0,0,0).
    #[arg(long, value_name = "X,Y,Z", value_parser = triple, allow_hyphen_values = true, requires = "anchor")]
    pub anchor_at: Option<[f64; 3]>,
    /// Degrees clockwise from true north to the local +y axis (default 0).
    #[arg(
        long,
        value_name = "DEG",
        allow_hyphen_values = true,
        requires = "anchor"
    )]
    pub north_rotation: Option<f64>,
    /// What heights are measured from: a vertical CRS (`EPSG:n`) or a name; declared in the plan.
    #[arg(long, value_name = "DATUM")]
    pub height_datum: Option<String>,
}

fn triple(s: &str) -> Result<[f64; 3], String> {
    let nums: Vec<f64> = s
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("three comma-separated numbers: {e}"))?;
    <[f64; 3]>::try_from(nums)
        .map_err(|n| format!("three comma-separated numbers, not {}", n.len()))
}

impl GeorefArgs {
    /// The georeference the flags give, checked; `None` when none was given.
    pub fn georeference(&self) -> anyhow::Result<Option<asbuilt_plan::georef::Georeference>> {
        if self.crs.is_none() && self.anchor.is_none() && self.height_datum.is_none() {
            return Ok(None);
        }
        let g = asbuilt_plan::georef::Georeference {
            crs: self.crs.clone(),
            anchor: self.anchor,
            anchor_at: self.anchor_at,
            north_rotation: self.north_rotation,
            height_datum: self.height_datum.clone(),
        };
        g.check()
            .map_err(|e| anyhow::anyhow!("--{}: {}", e.field.replace('_', "-"), e.message))?;
        Ok(Some(g))
    }
}

/// How to read the input; shared by `plan` and `info`.
#[derive(clap::Args, Clone, Default)]
pub struct ReadArgs {
    /// Multiply input coordinates (and sidecar positions) by S to get metres, e.g. 0.001 for
    /// millimetres.
    #[arg(long, value_name = "S")]
    pub scale: Option<f64>,
    /// XYZ/PTS: the zero-based column holding each point's scan index (x is column 0).
    #[arg(long, value_name = "N")]
    pub scan_column: Option<usize>,
    /// Read as this format instead of detecting it from the content: e57, las, laz, ply, xyz, pts.
    #[arg(long, value_name = "FORMAT")]
    pub format: Option<Format>,
}

impl ReadArgs {
    /// The reader's options. Point times are kept, as the service's worker keeps them: without
    /// a trajectory they give the mobile scanner's estimated path. (A streamed run drops them
    /// itself unless a trajectory is given.)
    pub fn options(&self) -> ReadOptions {
        ReadOptions {
            scale: self.scale,
            scan_column: self.scan_column,
            format: self.format,
            ..ReadOptions::default()
        }
    }
}

pub fn run(args: PlanArgs) -> anyhow::Result<ExitCode> {
    let start = Instant::now();
    // Everything that can be checked cheaply is checked before the long run.
    let params = params(&args)?;
    let georeference = args.georef.georeference()?;
    if let Some(s) = args.read.scale {
        check_scale(s)?;
    }
    let paths = args.outputs.0.iter().map(|(_, p)| p);
    for out in args.output.iter().chain(paths) {
        check_writable(out)?;
    }
    let stream = match &args.max_memory {
        Some(budget) => Some(StreamingParams {
            max_memory: parse_size(budget)?,
            ..Default::default()
        }),
        None => None,
    };
    let scan = Scan {
        cloud: &args.input,
        sidecar: sidecar(args.poses.as_deref(), args.trajectory.as_deref()),
        read: args.read.options(),
        params: &params,
        stream,
        max_points: None,
        georeference,
    };
    let mut bar = Bar::new(args.quiet);
    let result = asbuilt_plan::plan_scan(&scan, &mut bar);
    bar.finish();
    let Planned { plan, streamed } = match result {
        // Read errors name the file at fault (the cloud or its sidecar) themselves.
        Err(e @ RunError::Read(_)) => return Err(e.into()),
        other => other.with_context(|| format!("{}", args.input.display()))?,
    };

    let write_start = Instant::now();
    write_outputs(&args, &plan)?;
    let write_ms = write_start.elapsed().as_millis() as u64;

    let total_ms = start.elapsed().as_millis() as u64;
    if let Some(path) = &args.timings {
        write_timings(path, &plan, write_ms, total_ms)?;
    }
    if !args.quiet {
        if let Some(report) = streamed {
            eprintln!(
                "streamed {} points in {} × {} tiles (at most {} points each, halo included), {:.0} MB of tile files",
                report.points,
                report.tiles.0,
                report.tiles.1,
                report.max_tile_points,
                report.spilled_bytes as f64 / 1e6
            );
        }
        report_plan(&plan, write_ms, total_ms);
    }
    Ok(ExitCode::SUCCESS)
}

/// The sidecar the flags name (clap lets at most one through).
pub(super) fn sidecar<'a>(
    poses: Option<&'a Path>,
    trajectory: Option<&'a Path>,
) -> Option<(SidecarKind, &'a Path)> {
    match (poses, trajectory) {
        (Some(p), _) => Some((SidecarKind::Poses, p)),
        (None, Some(t)) => Some((SidecarKind::Trajectory, t)),
        (None, None) => None,
    }
}

/// `1GiB`, `512MiB`, `2G` (binary), `1.5GB` (decimal), or plain bytes.
fn parse_size(text: &str) -> anyhow::Result<u64> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let mult: f64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kib" => 1024.0,
        "kb" => 1e3,
        "m" | "mib" => 1024.0 * 1024.0,
        "mb" => 1e6,
        "g" | "gib" => 1024.0 * 1024.0 * 1024.0,
        "gb" => 1e9,
        "t" | "tib" => 1024f64.powi(4),
        "tb" => 1e12,
        _ => bail!("--max-memory: unknown unit in {text:?} (use e.g. 1GiB, 512MiB, 2GB)"),
    };
    let v: f64 = num
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite() && *v > 0.0)
        .with_context(|| format!("--max-memory: {text:?} is not a size like 1GiB"))?;
    Ok((v * mult) as u64)
}

/// Defaults, then the file, then `--param`s in order, then the dedicated flags.
fn params(args: &PlanArgs) -> anyhow::Result<Params> {
    let mut params = match &args.params {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            Params::from_file_text(&text)
                .map_err(|e| anyhow::anyhow!(one_line(&e.to_string())))
                .with_context(|| format!("{}", path.display()))?
        }
        None => Params::default(),
    };
    for assignment in &args.overrides {
        params
            .set(assignment)
            .with_context(|| format!("--param {assignment}"))?;
    }
    if let Some(e) = args.registration_error {
        if !(e.is_finite() && e >= 0.0) {
            bail!("--registration-error must be a non-negative number of metres, not {e}");
        }
        params.smoothing.registration_error = Some(e);
    }
    if args.emit_samples {
        params.emit_samples = true;
    }
    if args.svg_underlay {
        params.svg_underlay = true;
    }
    params.check()?;
    Ok(params)
}

/// Parser errors (TOML's) quote the offending source over several lines; a CLI error is one
/// line, so the quoted snippet goes and the remaining lines are joined.
fn one_line(message: &str) -> String {
    let snippet = |l: &str| {
        let t = l.trim_start_matches(|c: char| c.is_ascii_digit() || c == ' ');
        t.starts_with('|')
    };
    message
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !snippet(l))
        .collect::<Vec<_>>()
        .join(": ")
}

/// Fails early when an output's folder does not exist, rather than after the run.
fn check_writable(path: &Path) -> anyhow::Result<()> {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() && !dir.is_dir() => {
            bail!(
                "{}: folder {} does not exist",
                path.display(),
                dir.display()
            )
        }
        _ => Ok(()),
    }
}

fn check_scale(s: f64) -> anyhow::Result<()> {
    if !(s.is_finite() && s > 0.0) {
        bail!("--scale must be a positive number, not {s}");
    }
    Ok(())
}

/// Where the flags send each output of the list; the GeoJSON goes to standard output without
/// `--output`.
fn destination<'a>(args: &'a PlanArgs, output: &Output) -> Option<&'a PathBuf> {
    match output.name {
        "geojson" => args.output.as_ref(),
        name => args
            .outputs
            .0
            .iter()
            .find(|(o, _)| o.name == name)
            .map(|(_, p)| p),
    }
}

fn write_outputs(args: &PlanArgs, plan: &FloorPlan) -> anyhow::Result<()> {
    for output in &OUTPUTS {
        let to_stdout = output.name == "geojson" && args.output.is_none();
        let path = destination(args, output);
        if path.is_none() && !to_stdout {
            continue;
        }
        let bytes = (output.write)(plan).map_err(|e| anyhow::anyhow!(e))?;
        match path {
            Some(path) => std::fs::write(path, bytes)
                .with_context(|| format!("writing {}", path.display()))?,
            None => {
                let mut out = std::io::stdout().lock();
                out.write_all(&bytes)
                    .and_then(|()| out.flush())
                    .context("writing the plan to standard output")?;
            }
        }
    }
    Ok(())
}

/// The plan's stage times, then `write` and the run's `total`, as one JSON object.
fn write_timings(
    path: &Path,
    plan: &FloorPlan,
    write_ms: u64,
    total_ms: u64,
) -> anyhow::Result<()> {
    let mut map = serde_json::Map::new();
    for (name, ms) in plan.timings_ms.iter().filter(|(n, _)| n != "total") {
        map.insert(name.clone(), (*ms).into());
    }
    map.insert("write".into(), write_ms.into());
    map.insert("total".into(), total_ms.into());
    std::fs::write(path, serde_json::Value::Object(map).to_string())
        .with_context(|| format!("writing {}", path.display()))
}

/// Stories, per-stage timings and notes, on standard error so stdout stays pure GeoJSON.
fn report_plan(plan: &FloorPlan, write_ms: u64, total_ms: u64) {
    let mut err = std::io::stderr().lock();
    let _ = writeln!(
        err,
        "{} points ({}), {} stor{}:",
        plan.input.points,
        plan.input.format,
        plan.stories.len(),
        if plan.stories.len() == 1 { "y" } else { "ies" }
    );
    for s in &plan.stories {
        let _ = writeln!(
            err,
            "  level {}: floor z {:.2} m, ceiling z {:.2} m, {:.1} m², {} walls, {} samples",
            s.level,
            s.floor_z + plan.origin[2],
            s.ceiling_z + plan.origin[2],
            s.area(),
            s.walls.len(),
            s.samples.len()
        );
    }
    let _ = writeln!(err, "timings (ms):");
    for (name, ms) in plan.timings_ms.iter().filter(|(n, _)| n != "total") {
        let _ = writeln!(err, "  {name:<10} {ms:>8}");
    }
    let _ = writeln!(err, "  {:<10} {write_ms:>8}", "write");
    let _ = writeln!(err, "  {:<10} {total_ms:>8}", "total");
    for note in &plan.notes {
        let _ = writeln!(err, "note: {note}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cli_reads_points_as_the_worker_does() {
        // The worker reads with the defaults: times kept, so a mobile scan without its
        // trajectory plans the same in both.
        let read = ReadArgs::default();
        assert_eq!(read.options(), ReadOptions::default());
        assert!(read.options().keep_time);
    }

    #[test]
    fn multi_line_parser_errors_become_one_line() {
        let text = "TOML parse error at line 2, column 1\n  |\n2 | bogus = 1\n  | ^^^^^\nunknown field `bogus`\n";
        assert_eq!(
            one_line(text),
            "TOML parse error at line 2, column 1: unknown field `bogus`"
        );
    }

    fn square_plan() -> FloorPlan {
        use asbuilt_plan::plan::{Polygon, StoryPlan, Wall, WallModel};
        FloorPlan {
            origin: [100.0, 200.0, 10.0],
            crs: None,
            georeference: None,
            input: Default::default(),
            parameters: Params::default().to_json(),
            timings_ms: vec![("total".into(), 1)],
            stories: vec![StoryPlan {
                level: 0,
                floor_z: 0.0,
                ceiling_z: 2.5,
                polygons: vec![Polygon {
                    exterior: vec![[0.0, 0.0], [3.0, 0.0], [3.0, 2.0], [0.0, 2.0]],
                    holes: vec![],
                }],
                walls: vec![Wall {
                    model: WallModel::Line,
                    points: vec![[0.0, 0.0], [3.0, 0.0]],
                    support: 5,
                }],
                samples: vec![],
                spaces: Default::default(),
                underlay: None,
            }],
            notes: vec![],
        }
    }

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        plan: PlanArgs,
    }

    fn parse(args: &[&str]) -> Result<PlanArgs, clap::Error> {
        use clap::Parser;
        Cli::try_parse_from(std::iter::once("asbuilt").chain(args.iter().copied())).map(|c| c.plan)
    }

    /// `-o`, `--svg` and `--dxf` work as before, and every other output of the list has its
    /// own `--NAME FILE` flag.
    #[test]
    fn writes_every_requested_output() {
        let dir = tempfile::tempdir().unwrap();
        let path = |f: &str| dir.path().join(f).to_str().unwrap().to_string();
        let mut argv = vec!["in.ply".to_string(), "-o".into(), path("plan.geojson")];
        for o in OUTPUTS.iter().filter(|o| o.name != "geojson") {
            argv.push(format!("--{}", o.name));
            argv.push(path(o.file));
        }
        let argv: Vec<&str> = argv.iter().map(String::as_str).collect();
        let args = parse(&argv).unwrap();
        assert_eq!(args.outputs.0.len(), OUTPUTS.len() - 1);
        write_outputs(&args, &square_plan()).unwrap();
        for o in &OUTPUTS {
            let bytes = std::fs::read(dir.path().join(o.file)).unwrap();
            assert_eq!(bytes, (o.write)(&square_plan()).unwrap(), "{}", o.name);
        }
        let text = std::fs::read_to_string(dir.path().join("plan.geojson")).unwrap();
        let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(
            doc["features"][0]["geometry"]["coordinates"][0][0][0],
            100.0
        );
        assert_eq!(doc["features"][0]["properties"]["area_m2"], 6.0);
        let svg = std::fs::read_to_string(dir.path().join("plan.svg")).unwrap();
        assert!(svg.contains("Level 0, floor z = 10.00 m, area 6.0 m²"));
        let dxf = std::fs::read_to_string(dir.path().join("plan.dxf")).unwrap();
        assert!(dxf.contains("AC1009") && dxf.contains("STORY_0") && dxf.ends_with("EOF\n"));
        let ifc = std::fs::read_to_string(dir.path().join("plan.ifc")).unwrap();
        assert!(ifc.starts_with("ISO-10303-21;") && ifc.contains("IFCBUILDINGSTOREY("));
        let csv = std::fs::read_to_string(dir.path().join("rooms.csv")).unwrap();
        assert!(csv.starts_with("level,room,area_m2,"));
    }

    #[test]
    fn only_the_named_outputs_are_written() {
        let dir = tempfile::tempdir().unwrap();
        let ifc = dir.path().join("model.ifc");
        let geojson = dir.path().join("plan.geojson");
        let args = parse(&[
            "in.ply",
            "--ifc",
            ifc.to_str().unwrap(),
            "--output",
            geojson.to_str().unwrap(),
        ])
        .unwrap();
        write_outputs(&args, &square_plan()).unwrap();
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, ["model.ifc", "plan.geojson"]);
        // `--geojson` is `--output`'s other name, so every output has its `--NAME`.
        assert_eq!(
            parse(&["in.ply", "--geojson", "x"]).unwrap().output,
            Some(PathBuf::from("x"))
        );
        assert!(parse(&["in.ply", "--pdf", "x"]).is_err());
    }

    #[test]
    fn outputs_need_an_existing_folder() {
        let dir = tempfile::tempdir().unwrap();
        assert!(check_writable(&dir.path().join("plan.svg")).is_ok());
        assert!(check_writable(Path::new("plan.svg")).is_ok());
        let err = check_writable(&dir.path().join("nope").join("plan.svg")).unwrap_err();
        assert!(err.to_string().contains("nope"), "{err}");
    }

    #[test]
    fn sizes_parse_with_binary_and_decimal_units() {
        assert_eq!(parse_size("1GiB").unwrap(), 1 << 30);
        assert_eq!(parse_size("512MiB").unwrap(), 512 << 20);
        assert_eq!(parse_size("2G").unwrap(), 2 << 30);
        assert_eq!(parse_size("1.5GB").unwrap(), 1_500_000_000);
        assert_eq!(parse_size("4096").unwrap(), 4096);
        assert!(parse_size("lots").is_err());
        assert!(parse_size("1 parsec").is_err());
        assert!(parse_size("0").is_err());
    }
}
