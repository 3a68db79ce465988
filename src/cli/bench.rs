//! `asbuilt bench`: paper-scale timings. Generates (and caches) simulated three-story buildings,
//! then times `asbuilt plan` and `asbuilt info` on them in child processes, per stage, with each
//! child's peak resident memory, beside `cat FILE > /dev/null`.
//!
//! Every timed command is a fresh process, so its peak memory (`VmHWM`, which the child writes
//! where `ASBUILT_PEAK_RSS_FILE` says) is its own. Files are read from the page cache: each is
//! read once before its runs are timed.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::time::Instant;

use anyhow::{bail, Context};
use asbuilt_plan::cloud::{PointCloud, Viewpoints};
use asbuilt_plan::io::{export, ply, poses};
use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};
use serde::Serialize;

/// The environment variable naming the file a process writes its peak resident memory to.
pub const PEAK_RSS_ENV: &str = "ASBUILT_PEAK_RSS_FILE";

/// The stages reported per run, in pipeline order (`timings_ms` keys): the pipeline's table.
static STAGES: std::sync::LazyLock<Vec<&'static str>> =
    std::sync::LazyLock::new(|| asbuilt_plan::progress::timing_keys().collect());

#[derive(clap::Args)]
pub struct BenchArgs {
    /// Cloud sizes in points, comma-separated; `k` and `M` suffixes allowed.
    #[arg(long, value_delimiter = ',', default_value = "1M,4M,17.4M,70M")]
    pub sizes: Vec<String>,
    /// Formats to run the whole pipeline on.
    #[arg(long, value_delimiter = ',', default_value = "ply,laz")]
    pub formats: Vec<BenchFormat>,
    /// Thread counts (RAYON_NUM_THREADS) to run each plan and each read with; empty = rayon's
    /// default.
    #[arg(long, value_delimiter = ',')]
    pub threads: Vec<usize>,
    /// Also run the streaming mode (`plan --max-memory SIZE`) on every size and format.
    #[arg(long, value_name = "SIZE")]
    pub max_memory: Option<String>,
    /// Skip the pipeline table (`--sizes` by `--formats`).
    #[arg(long)]
    pub no_plan_table: bool,
    /// Skip the in-memory pipeline runs (with `--max-memory`: streaming runs only).
    #[arg(long)]
    pub no_in_memory: bool,
    /// Formats of the read-throughput table.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "e57,las,laz,laz14,ply,ply-ascii,xyz"
    )]
    pub read_formats: Vec<BenchFormat>,
    /// Points of the read-throughput table's cloud.
    #[arg(long, default_value = "17.4M")]
    pub read_size: String,
    /// Skip the read-throughput table.
    #[arg(long)]
    pub no_read_table: bool,
    /// Formats of the upload table: from an upload's last byte to its job's `succeeded`, read
    /// as it arrived and from the stored file (the service in this process, one worker).
    #[arg(long, value_delimiter = ',', default_value = "ply,las,laz")]
    pub upload_formats: Vec<BenchFormat>,
    /// Points of the upload table's cloud.
    #[arg(long, default_value = "17.4M")]
    pub upload_size: String,
    /// The upload table's rate in MB/s (0: as fast as the server takes it).
    #[arg(long, default_value_t = 0.0)]
    pub upload_rate: f64,
    /// Skip the upload table.
    #[arg(long)]
    pub no_upload_table: bool,
    /// Points of the fitting table's building: `dense_office`, two stories of about 30 rooms
    /// each, planned with and without its scanner poses.
    #[arg(long, default_value = "1.14M")]
    pub fit_size: String,
    /// Skip the fitting table.
    #[arg(long)]
    pub no_fit_table: bool,
    /// Time each command this many times and keep the fastest run.
    #[arg(long, default_value_t = 1)]
    pub repeat: usize,
    /// Where generated clouds are cached, one folder per size.
    #[arg(long, value_name = "DIR", default_value = "bench-cache")]
    pub cache: PathBuf,
    /// Where the JSON copy of the figures goes.
    #[arg(long, value_name = "FILE", default_value = "bench.json")]
    pub json: PathBuf,
}

/// A cloud file format the bench writes and reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum BenchFormat {
    /// Binary little-endian PLY (float x, y, z and uint scan_index).
    Ply,
    /// ASCII PLY.
    PlyAscii,
    Las,
    Laz,
    /// LAS 1.4 point format 6 compressed: layered LAZ, as terrestrial scanners' software
    /// writes it.
    Laz14,
    /// E57 with one Data3D and pose per scan.
    E57,
    /// `x y z scan` text lines.
    Xyz,
}

impl BenchFormat {
    fn file_name(self) -> &'static str {
        match self {
            BenchFormat::Ply => "cloud.ply",
            BenchFormat::PlyAscii => "cloud-ascii.ply",
            BenchFormat::Las => "cloud.las",
            BenchFormat::Laz => "cloud.laz",
            BenchFormat::Laz14 => "cloud14.laz",
            BenchFormat::E57 => "cloud.e57",
            BenchFormat::Xyz => "cloud.xyz",
        }
    }

    fn name(self) -> &'static str {
        match self {
            BenchFormat::Ply => "ply",
            BenchFormat::PlyAscii => "ply-ascii",
            BenchFormat::Las => "las",
            BenchFormat::Laz => "laz",
            BenchFormat::Laz14 => "laz14",
            BenchFormat::E57 => "e57",
            BenchFormat::Xyz => "xyz",
        }
    }

    /// Reader arguments: the pose sidecar (E57 carries its own poses) and the XYZ scan column.
    fn read_args(self, dir: &Path) -> Vec<OsString> {
        let mut args = Vec::new();
        if self != BenchFormat::E57 {
            args.push("--poses".into());
            args.push(dir.join("poses.json").into());
        }
        if self == BenchFormat::Xyz {
            args.push("--scan-column".into());
            args.push("3".into());
        }
        args
    }
}

/// One timed pipeline run.
#[derive(Debug, Serialize)]
struct PlanRun {
    points: u64,
    format: BenchFormat,
    /// `memory`, or `stream SIZE`.
    mode: String,
    /// RAYON_NUM_THREADS, or `None` for rayon's default.
    threads: Option<usize>,
    file_bytes: u64,
    cat_ms: f64,
    info_ms: f64,
    info_cpu_ms: f64,
    info_peak_rss_bytes: u64,
    plan_ms: f64,
    plan_cpu_ms: f64,
    /// Per stage, from the plan's own report (`read` .. `write`, plus `total`).
    stages_ms: BTreeMap<String, u64>,
    points_per_second: f64,
    peak_rss_bytes: u64,
    /// x, y, z as f32 (12 bytes) plus a u16 scan slot (2 bytes) per point.
    compact_bytes: u64,
}

/// One row of the read-throughput table.
#[derive(Debug, Serialize)]
struct ReadRun {
    points: u64,
    format: BenchFormat,
    /// RAYON_NUM_THREADS, or `None` for rayon's default.
    threads: Option<usize>,
    file_bytes: u64,
    cat_ms: f64,
    info_ms: f64,
    info_cpu_ms: f64,
    mpts_per_second: f64,
    cat_mb_per_second: f64,
    peak_rss_bytes: u64,
    compact_bytes: u64,
}

/// One row of the fitting table: how much of a plan of many rooms the fitting takes.
#[derive(Debug, Serialize)]
struct FitRun {
    building: &'static str,
    points: u64,
    /// Planned with the scanner poses; without them the scanners are located first.
    poses: bool,
    /// RAYON_NUM_THREADS, or `None` for rayon's default.
    threads: Option<usize>,
    plan_ms: f64,
    /// The plan's own total (`total`) and fitting (`fit`) times, ms.
    total_ms: u64,
    fit_ms: u64,
    /// `fit_ms / total_ms`.
    fit_share: f64,
    /// The stage that took longest, and its time, ms.
    largest_stage: String,
    largest_ms: u64,
}

impl FitRun {
    fn of(
        building: &'static str,
        points: u64,
        poses: bool,
        threads: Option<usize>,
        run: &ChildRun,
    ) -> FitRun {
        let get = |k: &str| run.stages.get(k).copied().unwrap_or(0);
        let (total_ms, fit_ms) = (get("total"), get("fit"));
        let (largest_stage, largest_ms) = run
            .stages
            .iter()
            .filter(|(k, _)| k.as_str() != "total")
            .max_by_key(|(_, &v)| v)
            .map_or((String::new(), 0), |(k, &v)| (k.clone(), v));
        FitRun {
            building,
            points,
            poses,
            threads,
            plan_ms: run.wall_ms,
            total_ms,
            fit_ms,
            fit_share: fit_ms as f64 / total_ms.max(1) as f64,
            largest_stage,
            largest_ms,
        }
    }
}

#[derive(Debug, Serialize)]
struct Report {
    machine: String,
    /// The 1-minute load average when the bench finished: other work on the machine slows it.
    load_average: String,
    /// The share of the CPUs' time, in per cent, that a virtual machine's host gave to other
    /// work while the bench ran (`steal` in `/proc/stat`); `None` where it cannot be read.
    steal_percent: Option<f64>,
    plan_runs: Vec<PlanRun>,
    /// Per format, mode and thread count: the slope of log(plan time) over log(points).
    exponents: Vec<Exponent>,
    /// Per size, format and mode run at more than one thread count: each stage's speedup.
    speedups: Vec<Speedup>,
    read_runs: Vec<ReadRun>,
    upload_runs: Vec<super::bench_upload::UploadRun>,
    fit_runs: Vec<FitRun>,
}

/// How much faster each stage ran with `threads` threads than with `base_threads`.
#[derive(Debug, Serialize)]
struct Speedup {
    points: u64,
    format: BenchFormat,
    mode: String,
    base_threads: usize,
    threads: usize,
    /// Whole run (wall time), then stage name → base time / time; stages under 1 ms are left out.
    plan: f64,
    stages: BTreeMap<String, f64>,
}

#[derive(Debug, Serialize)]
struct Exponent {
    format: BenchFormat,
    mode: String,
    threads: Option<usize>,
    exponent: f64,
    from_points: u64,
    to_points: u64,
}

pub fn run(args: BenchArgs) -> anyhow::Result<ExitCode> {
    let cpu_at_start = cpu_times();
    let exe = std::env::current_exe().context("finding the asbuilt binary")?;
    let sizes: Vec<u64> = args
        .sizes
        .iter()
        .map(|s| parse_count(s))
        .collect::<anyhow::Result<_>>()?;
    let read_size = parse_count(&args.read_size)?;
    if args.repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    if args.no_in_memory && args.max_memory.is_none() {
        bail!("--no-in-memory leaves nothing to run without --max-memory");
    }
    std::fs::create_dir_all(&args.cache)
        .with_context(|| format!("creating {}", args.cache.display()))?;
    let threads: Vec<Option<usize>> = if args.threads.is_empty() {
        vec![None]
    } else {
        args.threads.iter().map(|&t| Some(t)).collect()
    };
    let mut modes = Vec::new();
    if !args.no_in_memory {
        modes.push(None);
    }
    if let Some(m) = &args.max_memory {
        modes.push(Some(m.clone()));
    }

    let mut plan_runs = Vec::new();
    let plan_sizes = if args.no_plan_table {
        &[][..]
    } else {
        &sizes[..]
    };
    for &n in plan_sizes {
        let dir = ensure_files(&args.cache, n, &args.formats)?;
        for &format in &args.formats {
            let file = dir.join(format.file_name());
            let file_bytes = file_len(&file)?;
            let cat_ms = time_cat(&file, args.repeat)?;
            let info = best_of(args.repeat, || info_run(&exe, &file, format, &dir, None))?;
            for mode in &modes {
                for &t in &threads {
                    let out = best_of(args.repeat, || {
                        plan_run(&exe, &file, format.read_args(&dir), mode.as_deref(), t)
                    })?;
                    let run = PlanRun {
                        points: n,
                        format,
                        mode: mode
                            .as_ref()
                            .map_or("memory".into(), |m| format!("stream {m}")),
                        threads: t,
                        file_bytes,
                        cat_ms,
                        info_ms: info.wall_ms,
                        info_cpu_ms: info.cpu_ms,
                        info_peak_rss_bytes: info.peak_rss,
                        plan_ms: out.wall_ms,
                        plan_cpu_ms: out.cpu_ms,
                        points_per_second: n as f64 / (out.wall_ms / 1e3),
                        stages_ms: out.stages,
                        peak_rss_bytes: out.peak_rss,
                        compact_bytes: n * 14,
                    };
                    eprintln!(
                        "bench: {} points, {}, {}, threads {}: plan {:.0} ms, info {:.0} ms, peak {:.0} MB",
                        n,
                        format.name(),
                        run.mode,
                        t.map_or("default".into(), |t| t.to_string()),
                        run.plan_ms,
                        run.info_ms,
                        mb(run.peak_rss_bytes)
                    );
                    plan_runs.push(run);
                }
            }
        }
    }

    let mut read_runs = Vec::new();
    if !args.no_read_table {
        let dir = ensure_files(&args.cache, read_size, &args.read_formats)?;
        for &format in &args.read_formats {
            let file = dir.join(format.file_name());
            let file_bytes = file_len(&file)?;
            let cat_ms = time_cat(&file, args.repeat)?;
            for &t in &threads {
                let info = best_of(args.repeat, || info_run(&exe, &file, format, &dir, t))?;
                eprintln!(
                    "bench: read {} points of {}, threads {}: {:.0} ms",
                    read_size,
                    format.name(),
                    t.map_or("default".to_string(), |t| t.to_string()),
                    info.wall_ms
                );
                read_runs.push(ReadRun {
                    points: read_size,
                    format,
                    threads: t,
                    file_bytes,
                    cat_ms,
                    info_ms: info.wall_ms,
                    info_cpu_ms: info.cpu_ms,
                    mpts_per_second: read_size as f64 / 1e6 / (info.wall_ms / 1e3),
                    cat_mb_per_second: file_bytes as f64 / 1e6 / (cat_ms / 1e3),
                    peak_rss_bytes: info.peak_rss,
                    compact_bytes: read_size * 14,
                });
            }
        }
    }

    let mut upload_runs = Vec::new();
    if !args.no_upload_table {
        let upload_size = parse_count(&args.upload_size)?;
        let dir = ensure_files(&args.cache, upload_size, &args.upload_formats)?;
        for &format in &args.upload_formats {
            let file = dir.join(format.file_name());
            time_cat(&file, 1)?;
            for early in [false, true] {
                let mut best: Option<super::bench_upload::Timed> = None;
                for _ in 0..args.repeat {
                    let t = super::bench_upload::time_upload(&file, early, args.upload_rate)?;
                    if best.is_none_or(|b| t.done_ms < b.done_ms) {
                        best = Some(t);
                    }
                }
                let t = best.expect("at least one run");
                eprintln!(
                    "bench: upload {} points of {}, read early {early}: last byte to succeeded {:.0} ms",
                    upload_size,
                    format.name(),
                    t.done_ms
                );
                upload_runs.push(super::bench_upload::UploadRun {
                    points: upload_size,
                    format: format.name(),
                    early,
                    file_bytes: file_len(&file)?,
                    rate_mb_s: args.upload_rate,
                    upload_ms: t.upload_ms,
                    last_byte_to_done_ms: t.done_ms,
                    read_ms: t.read_ms,
                    plan_ms: t.plan_ms,
                });
            }
        }
    }

    let mut fit_runs = Vec::new();
    if !args.no_fit_table {
        let n = parse_count(&args.fit_size)?;
        let kind = BuildingKind::DenseOffice;
        let dir = ensure_building(&args.cache, kind, FIT_SEED, n, &[BenchFormat::Ply])?;
        let file = dir.join(BenchFormat::Ply.file_name());
        time_cat(&file, 1)?;
        for poses in [true, false] {
            let read_args = if poses {
                BenchFormat::Ply.read_args(&dir)
            } else {
                Vec::new()
            };
            for &t in &threads {
                let out = best_of(args.repeat, || {
                    plan_run(&exe, &file, read_args.clone(), None, t)
                })?;
                let row = FitRun::of(kind.name(), n, poses, t, &out);
                eprintln!(
                    "bench: {} {} points, poses {poses}, threads {}: fit {} of {} ms",
                    row.building,
                    n,
                    t.map_or("default".into(), |t| t.to_string()),
                    row.fit_ms,
                    row.total_ms
                );
                fit_runs.push(row);
            }
        }
    }

    let report = Report {
        fit_runs,
        upload_runs,
        machine: machine(),
        load_average: std::fs::read_to_string("/proc/loadavg")
            .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
            .unwrap_or_default(),
        steal_percent: cpu_at_start
            .zip(cpu_times())
            .and_then(|(a, b)| a.steal_percent_until(&b)),
        exponents: exponents(&plan_runs),
        speedups: speedups(&plan_runs),
        plan_runs,
        read_runs,
    };
    print!("{}", markdown(&report));
    let json = serde_json::to_string_pretty(&report)?;
    std::fs::write(&args.json, json + "\n")
        .with_context(|| format!("writing {}", args.json.display()))?;
    eprintln!("bench: wrote {}", args.json.display());
    Ok(ExitCode::SUCCESS)
}

/// `17.4M`, `200k`, `1000000`.
fn parse_count(text: &str) -> anyhow::Result<u64> {
    let t = text.trim();
    let (num, mult) = match t.char_indices().last() {
        Some((i, 'M' | 'm')) => (&t[..i], 1e6),
        Some((i, 'k' | 'K')) => (&t[..i], 1e3),
        _ => (t, 1.0),
    };
    let v: f64 = num
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite() && *v >= 1.0)
        .with_context(|| format!("{text:?} is not a point count (like 17.4M or 200k)"))?;
    Ok((v * mult).round() as u64)
}

/// The seed of the fitting table's building (the one `examples/score` was first timed on).
const FIT_SEED: u64 = 33;

/// The folder of the `n`-point office, with every file in `formats` written (once).
fn ensure_files(cache: &Path, n: u64, formats: &[BenchFormat]) -> anyhow::Result<PathBuf> {
    ensure_building(cache, BuildingKind::Office3Story, 1, n, formats)
}

/// The folder of building `kind` scanned with `n` points from `seed`, with every file in
/// `formats` and the pose sidecar written (once).
fn ensure_building(
    cache: &Path,
    kind: BuildingKind,
    seed: u64,
    n: u64,
    formats: &[BenchFormat],
) -> anyhow::Result<PathBuf> {
    let dir = cache.join(format!("{}-{n}", kind.name()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let poses_path = dir.join("poses.json");
    let missing: Vec<BenchFormat> = formats
        .iter()
        .copied()
        .filter(|f| !dir.join(f.file_name()).exists())
        .collect();
    if missing.is_empty() && poses_path.exists() {
        return Ok(dir);
    }
    eprintln!(
        "bench: simulating {} with {n} points into {}",
        kind.name(),
        dir.display()
    );
    let start = Instant::now();
    let sim = simulate(
        kind,
        &ScanOptions {
            points: usize::try_from(n).context("too many points")?,
            seed,
            ..Default::default()
        },
    )?;
    let cloud = sim.cloud;
    eprintln!(
        "bench: simulated {} points in {:.1} s",
        cloud.len(),
        start.elapsed().as_secs_f64()
    );
    if let Viewpoints::Static(p) = &cloud.viewpoints {
        poses::write_poses(&poses_path, p, cloud.origin)?;
    }
    for format in missing {
        let path = dir.join(format.file_name());
        let part = dir.join(format!("{}.part", format.file_name()));
        let start = Instant::now();
        write_format(&part, &cloud, format)
            .with_context(|| format!("writing {}", part.display()))?;
        std::fs::rename(&part, &path).with_context(|| format!("renaming {}", part.display()))?;
        eprintln!(
            "bench: wrote {} in {:.1} s",
            path.display(),
            start.elapsed().as_secs_f64()
        );
    }
    Ok(dir)
}

fn write_format(path: &Path, cloud: &PointCloud, format: BenchFormat) -> anyhow::Result<()> {
    match format {
        BenchFormat::Ply => ply::write_ply(path, cloud, ply::Encoding::BinaryLittleEndian)?,
        BenchFormat::PlyAscii => ply::write_ply(path, cloud, ply::Encoding::Ascii)?,
        BenchFormat::Las => export::write_las(path, cloud, false)?,
        BenchFormat::Laz => export::write_las(path, cloud, true)?,
        BenchFormat::Laz14 => export::write_las14(path, cloud, true)?,
        BenchFormat::E57 => export::write_e57(path, cloud)?,
        BenchFormat::Xyz => export::write_xyz(path, cloud)?,
    }
    Ok(())
}

fn file_len(path: &Path) -> anyhow::Result<u64> {
    Ok(std::fs::metadata(path)
        .with_context(|| format!("{}", path.display()))?
        .len())
}

/// `cat FILE > /dev/null`, after one untimed read that brings the file into the page cache.
fn time_cat(file: &Path, repeat: usize) -> anyhow::Result<f64> {
    let cat = || -> anyhow::Result<f64> {
        let start = Instant::now();
        let status = Command::new("cat")
            .arg(file)
            .stdout(Stdio::null())
            .status()
            .context("running cat")?;
        if !status.success() {
            bail!("cat {} failed", file.display());
        }
        Ok(start.elapsed().as_secs_f64() * 1e3)
    };
    cat()?;
    let mut best = f64::INFINITY;
    for _ in 0..repeat {
        best = best.min(cat()?);
    }
    Ok(best)
}

/// What a child run reports.
struct ChildRun {
    wall_ms: f64,
    /// User + system CPU time of the child, all threads.
    cpu_ms: f64,
    peak_rss: u64,
    stages: BTreeMap<String, u64>,
}

fn best_of(
    repeat: usize,
    mut f: impl FnMut() -> anyhow::Result<ChildRun>,
) -> anyhow::Result<ChildRun> {
    let mut best: Option<ChildRun> = None;
    for _ in 0..repeat {
        let run = f()?;
        if best.as_ref().is_none_or(|b| run.wall_ms < b.wall_ms) {
            best = Some(run);
        }
    }
    best.context("no run")
}

/// Runs `exe args` with its stdout discarded, timing it and reading its peak memory.
fn child(exe: &Path, args: &[OsString], threads: Option<usize>) -> anyhow::Result<(f64, u64, f64)> {
    let rss_file = tempfile::NamedTempFile::new().context("creating a temporary file")?;
    let mut cmd = Command::new(exe);
    cmd.args(args)
        .env(PEAK_RSS_ENV, rss_file.path())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    if let Some(t) = threads {
        cmd.env("RAYON_NUM_THREADS", t.to_string());
    }
    let start = Instant::now();
    let out = cmd.output().context("running asbuilt")?;
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    if !out.status.success() {
        bail!(
            "asbuilt {:?} failed: {}",
            args,
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let text = std::fs::read_to_string(rss_file.path()).unwrap_or_default();
    let mut fields = text.split_whitespace().map(str::parse::<u64>);
    let (Some(Ok(peak)), Some(Ok(cpu_ms))) = (fields.next(), fields.next()) else {
        bail!("the child reported no peak memory ({text:?})");
    };
    Ok((wall_ms, peak, cpu_ms as f64))
}

fn info_run(
    exe: &Path,
    file: &Path,
    format: BenchFormat,
    dir: &Path,
    threads: Option<usize>,
) -> anyhow::Result<ChildRun> {
    let mut args: Vec<OsString> = vec!["info".into(), file.into()];
    args.extend(format.read_args(dir));
    let (wall_ms, peak_rss, cpu_ms) = child(exe, &args, threads)?;
    Ok(ChildRun {
        wall_ms,
        cpu_ms,
        peak_rss,
        stages: BTreeMap::new(),
    })
}

fn plan_run(
    exe: &Path,
    file: &Path,
    read_args: Vec<OsString>,
    max_memory: Option<&str>,
    threads: Option<usize>,
) -> anyhow::Result<ChildRun> {
    let work = tempfile::tempdir().context("creating a temporary folder")?;
    let timings = work.path().join("timings.json");
    let mut args: Vec<OsString> = vec![
        "plan".into(),
        file.into(),
        "-o".into(),
        work.path().join("plan.geojson").into(),
        "--quiet".into(),
        "--timings".into(),
        timings.clone().into(),
    ];
    args.extend(read_args);
    if let Some(m) = max_memory {
        args.push("--max-memory".into());
        args.push(m.into());
    }
    let (wall_ms, peak_rss, cpu_ms) = child(exe, &args, threads)?;
    let text = std::fs::read_to_string(&timings)
        .with_context(|| format!("reading {}", timings.display()))?;
    let stages: BTreeMap<String, u64> =
        serde_json::from_str(&text).with_context(|| format!("parsing {}", timings.display()))?;
    Ok(ChildRun {
        wall_ms,
        cpu_ms,
        peak_rss,
        stages,
    })
}

/// Least-squares slope of ln(time) over ln(points), per format, mode and thread count.
fn exponents(runs: &[PlanRun]) -> Vec<Exponent> {
    type Group = (BenchFormat, String, Option<usize>);
    let mut groups: BTreeMap<Group, Vec<(f64, f64)>> = BTreeMap::new();
    for r in runs {
        groups
            .entry((r.format, r.mode.clone(), r.threads))
            .or_default()
            .push(((r.points as f64).ln(), r.plan_ms.ln()));
    }
    groups
        .into_iter()
        .filter(|(_, xy)| xy.len() >= 2)
        .map(|((format, mode, threads), xy)| {
            let n = xy.len() as f64;
            let mx = xy.iter().map(|p| p.0).sum::<f64>() / n;
            let my = xy.iter().map(|p| p.1).sum::<f64>() / n;
            let sxy: f64 = xy.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
            let sxx: f64 = xy.iter().map(|p| (p.0 - mx).powi(2)).sum();
            let range = |f: fn(f64, f64) -> f64| xy.iter().map(|p| p.0).fold(mx, f).exp().round();
            Exponent {
                format,
                mode,
                threads,
                exponent: sxy / sxx,
                from_points: range(f64::min) as u64,
                to_points: range(f64::max) as u64,
            }
        })
        .collect()
}

/// For runs that differ only in thread count, each one's speedup over the fewest threads.
fn speedups(runs: &[PlanRun]) -> Vec<Speedup> {
    let mut out = Vec::new();
    for base in runs {
        let Some(t0) = base.threads else { continue };
        let same = |r: &&PlanRun| {
            r.points == base.points && r.format == base.format && r.mode == base.mode
        };
        let fewest = runs.iter().filter(same).filter_map(|r| r.threads).min();
        if fewest != Some(t0) {
            continue;
        }
        for r in runs.iter().filter(same) {
            let Some(t) = r.threads.filter(|&t| t > t0) else {
                continue;
            };
            let stages = STAGES
                .iter()
                .filter_map(|st| {
                    let (a, b) = (*base.stages_ms.get(*st)?, *r.stages_ms.get(*st)?);
                    (a >= 1 && b >= 1).then(|| (st.to_string(), a as f64 / b as f64))
                })
                .collect();
            out.push(Speedup {
                points: r.points,
                format: r.format,
                mode: r.mode.clone(),
                base_threads: t0,
                threads: t,
                plan: base.plan_ms / r.plan_ms,
                stages,
            });
        }
    }
    out
}

fn mb(bytes: u64) -> f64 {
    bytes as f64 / 1e6
}

fn machine() -> String {
    let cpus = std::thread::available_parallelism().map_or(0, |n| n.get());
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    format!("{cpus} threads, {model}")
}

/// All CPUs' time since boot, from the first line of `/proc/stat`, in clock ticks.
#[derive(Debug, Clone, Copy, PartialEq)]
struct CpuTimes {
    /// Time the hypervisor ran something else while this machine's CPUs wanted to run.
    steal: u64,
    /// Every field: user, nice, system, idle, iowait, irq, softirq, steal.
    total: u64,
}

impl CpuTimes {
    /// Reads the `cpu` line of `/proc/stat`'s text; `None` when it has no steal field.
    fn parse(stat: &str) -> Option<CpuTimes> {
        let line = stat.lines().find(|l| l.starts_with("cpu "))?;
        // Guest time is counted in user time already: the first eight fields are the whole.
        let fields: Vec<u64> = line
            .split_whitespace()
            .skip(1)
            .take(8)
            .map(|f| f.parse().ok())
            .collect::<Option<_>>()?;
        (fields.len() == 8).then(|| CpuTimes {
            steal: fields[7],
            total: fields.iter().sum(),
        })
    }

    /// The steal's share of the time from `self` to `later`, in per cent.
    fn steal_percent_until(&self, later: &CpuTimes) -> Option<f64> {
        let total = later.total.checked_sub(self.total)?;
        let steal = later.steal.checked_sub(self.steal)?;
        (total > 0).then(|| 100.0 * steal as f64 / total as f64)
    }
}

fn cpu_times() -> Option<CpuTimes> {
    CpuTimes::parse(&std::fs::read_to_string("/proc/stat").ok()?)
}

/// The report as markdown tables.
fn markdown(r: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Machine: {}; load average at the end: {}",
        r.machine, r.load_average
    );
    // On a virtual machine whose host is busy, every time below is longer than the machine's
    // own: say so beside the figures.
    match r.steal_percent {
        Some(p) if p >= 1.0 => {
            let _ = writeln!(
                s,
                "The host took {p:.1} % of the CPUs' time while the bench ran (steal): the times \
                 are that much slower than an idle host gives."
            );
        }
        Some(p) => {
            let _ = writeln!(s, "Time taken by the host (steal): {p:.1} %.");
        }
        None => {}
    }
    let _ = writeln!(s);
    if !r.plan_runs.is_empty() {
        let _ = writeln!(
            s,
            "| points | format | mode | threads | file MB | cat ms | info ms | plan ms | plan/info | plan CPU ms | {} | Mpts/s | peak MB | peak/compact |",
            STAGES
                .iter()
                .map(|st| format!("{st} ms"))
                .collect::<Vec<_>>()
                .join(" | ")
        );
        let _ = writeln!(s, "|{}", "---|".repeat(14 + STAGES.len()));
        for p in &r.plan_runs {
            let stages: Vec<String> = STAGES
                .iter()
                .map(|st| p.stages_ms.get(*st).map_or("-".into(), |v| v.to_string()))
                .collect();
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {:.0} | {:.0} | {:.0} | {:.0} | {:.2} | {:.0} | {} | {:.1} | {:.0} | {:.2} |",
                count(p.points),
                p.format.name(),
                p.mode,
                p.threads.map_or("default".into(), |t| t.to_string()),
                mb(p.file_bytes),
                p.cat_ms,
                p.info_ms,
                p.plan_ms,
                p.plan_ms / p.info_ms,
                p.plan_cpu_ms,
                stages.join(" | "),
                p.points_per_second / 1e6,
                mb(p.peak_rss_bytes),
                p.peak_rss_bytes as f64 / p.compact_bytes as f64,
            );
        }
        let _ = writeln!(
            s,
            "\nplan ms: wall time of `asbuilt plan` (process start to exit); stage times are the plan's own. \
             compact = 14 B/point (f32 x, y, z + u16 scan slot). info peak MB: {}\n",
            r.plan_runs
                .iter()
                .map(|p| format!("{}/{} {:.0}", count(p.points), p.format.name(), mb(p.info_peak_rss_bytes)))
                .collect::<std::collections::BTreeSet<_>>()
                .into_iter()
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    if !r.exponents.is_empty() {
        let _ = writeln!(
            s,
            "| format | mode | threads | points | time exponent |\n|---|---|---|---|---|"
        );
        for e in &r.exponents {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} .. {} | {:.3} |",
                e.format.name(),
                e.mode,
                e.threads.map_or("default".into(), |t| t.to_string()),
                count(e.from_points),
                count(e.to_points),
                e.exponent
            );
        }
        s.push('\n');
    }
    if !r.speedups.is_empty() {
        let _ = writeln!(
            s,
            "| points | format | mode | threads | plan | {} |\n|{}",
            STAGES.join(" | "),
            "---|".repeat(5 + STAGES.len())
        );
        for x in &r.speedups {
            let stages: Vec<String> = STAGES
                .iter()
                .map(|st| x.stages.get(*st).map_or("-".into(), |v| format!("{v:.2}×")))
                .collect();
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} → {} | {:.2}× | {} |",
                count(x.points),
                x.format.name(),
                x.mode,
                x.base_threads,
                x.threads,
                x.plan,
                stages.join(" | ")
            );
        }
        let _ = writeln!(
            s,
            "\nspeedup: time with the fewer threads over time with the more (RAYON_NUM_THREADS).\n"
        );
    }
    if !r.read_runs.is_empty() {
        let _ = writeln!(
            s,
            "| format | points | threads | file MB | cat ms | cat MB/s | info ms | info CPU ms | read Mpts/s | read MB/s | peak MB | peak/compact |\n|---|---|---|---|---|---|---|---|---|---|---|---|"
        );
        for x in &r.read_runs {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.1} | {:.0} | {:.0} | {:.2} |",
                x.format.name(),
                count(x.points),
                x.threads.map_or("default".to_string(), |t| t.to_string()),
                mb(x.file_bytes),
                x.cat_ms,
                x.cat_mb_per_second,
                x.info_ms,
                x.info_cpu_ms,
                x.mpts_per_second,
                mb(x.file_bytes) / (x.info_ms / 1e3),
                mb(x.peak_rss_bytes),
                x.peak_rss_bytes as f64 / x.compact_bytes as f64,
            );
        }
    }
    if !r.fit_runs.is_empty() {
        let _ = writeln!(
            s,
            "\n| building | points | poses | threads | plan ms | total ms | fit ms | fit share | largest stage |\n|---|---|---|---|---|---|---|---|---|"
        );
        for x in &r.fit_runs {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {:.0} | {} | {} | {:.1} % | {} ({} ms) |",
                x.building,
                count(x.points),
                if x.poses { "yes" } else { "no" },
                x.threads.map_or("default".to_string(), |t| t.to_string()),
                x.plan_ms,
                x.total_ms,
                x.fit_ms,
                100.0 * x.fit_share,
                x.largest_stage,
                x.largest_ms,
            );
        }
    }
    if !r.upload_runs.is_empty() {
        let _ = writeln!(
            s,
            "\n| format | points | read early | file MB | rate MB/s | upload ms | last byte → succeeded ms | job's read ms | job's plan ms |\n|---|---|---|---|---|---|---|---|---|"
        );
        for x in &r.upload_runs {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.0} | {} | {:.0} | {:.0} | {} | {} |",
                x.format,
                count(x.points),
                if x.early { "yes" } else { "no" },
                mb(x.file_bytes),
                if x.rate_mb_s > 0.0 {
                    format!("{}", x.rate_mb_s)
                } else {
                    "max".into()
                },
                x.upload_ms,
                x.last_byte_to_done_ms,
                x.read_ms,
                x.plan_ms,
            );
        }
    }
    s
}

/// 17400000 → `17.4M`.
fn count(n: u64) -> String {
    if n >= 1_000_000 {
        format!("{}M", (n as f64 / 1e6 * 10.0).round() / 10.0)
    } else if n >= 1000 {
        format!("{}k", (n as f64 / 1e3).round())
    } else {
        n.to_string()
    }
}

/// Writes this process's peak resident memory in bytes (Linux: `VmHWM`) and its CPU time in
/// milliseconds (user + system, all threads) to `path`, as `BYTES MS`.
pub fn write_peak_rss(path: &Path) {
    let kb = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse::<u64>().ok())
        });
    // Fields 14 and 15 of /proc/self/stat, after the parenthesised name; in ticks of 1/100 s.
    let cpu_ms = std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            let rest = s.rsplit_once(')')?.1;
            let f: Vec<&str> = rest.split_whitespace().collect();
            let ticks = f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?;
            Some(ticks * 10)
        })
        .unwrap_or(0);
    if let Some(kb) = kb {
        let _ = std::fs::write(path, format!("{} {cpu_ms}", kb * 1024));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_host_s_share_is_the_steal_over_all_the_time_between_two_readings() {
        let before = "cpu  100 5 50 800 10 0 5 30 7 0\ncpu0 50 2 25 400 5 0 2 15 3 0\n";
        let after = "cpu  200 5 90 1500 10 0 5 190 9 0\ncpu0 1 1 1 1 1 1 1 1 1 1\n";
        let (a, b) = (
            CpuTimes::parse(before).unwrap(),
            CpuTimes::parse(after).unwrap(),
        );
        // Guest time (the ninth field) is in user time already and is not added again.
        assert_eq!(
            a,
            CpuTimes {
                steal: 30,
                total: 1000
            }
        );
        // 160 ticks stolen of 1,000 between the two.
        let p = a.steal_percent_until(&b).unwrap();
        assert!((p - 16.0).abs() < 1e-12, "{p}");
        assert_eq!(b.steal_percent_until(&a), None);
        assert_eq!(a.steal_percent_until(&a), None);
        // An old kernel's line without a steal field, and no cpu line at all.
        assert_eq!(CpuTimes::parse("cpu  1 2 3 4 5 6 7\n"), None);
        assert_eq!(CpuTimes::parse("intr 5\n"), None);
    }

    #[test]
    fn counts_parse_with_suffixes() {
        assert_eq!(parse_count("17.4M").unwrap(), 17_400_000);
        assert_eq!(parse_count("200k").unwrap(), 200_000);
        assert_eq!(parse_count("1234").unwrap(), 1234);
        assert!(parse_count("lots").is_err());
        assert!(parse_count("0").is_err());
        assert_eq!(count(17_400_000), "17.4M");
        assert_eq!(count(4_000_000), "4M");
    }

    fn run(points: u64, plan_ms: f64) -> PlanRun {
        PlanRun {
            points,
            format: BenchFormat::Ply,
            mode: "memory".into(),
            threads: None,
            file_bytes: 0,
            cat_ms: 0.0,
            info_ms: 1.0,
            info_cpu_ms: 1.0,
            info_peak_rss_bytes: 0,
            plan_ms,
            plan_cpu_ms: 1.0,
            stages_ms: BTreeMap::new(),
            points_per_second: 0.0,
            peak_rss_bytes: 0,
            compact_bytes: 1,
        }
    }

    #[test]
    fn exponent_of_linear_cost_is_one() {
        let e = exponents(&[
            run(1_000_000, 100.0),
            run(4_000_000, 400.0),
            run(70_000_000, 7000.0),
        ]);
        assert_eq!(e.len(), 1);
        assert!((e[0].exponent - 1.0).abs() < 1e-9, "{}", e[0].exponent);
        assert_eq!((e[0].from_points, e[0].to_points), (1_000_000, 70_000_000));
    }

    #[test]
    fn a_fit_row_takes_the_share_and_the_largest_stage_from_the_plan_s_own_times() {
        let out = ChildRun {
            wall_ms: 420.0,
            cpu_ms: 700.0,
            peak_rss: 0,
            stages: BTreeMap::from([
                ("samples".to_string(), 110),
                ("label".to_string(), 150),
                ("fit".to_string(), 40),
                ("total".to_string(), 320),
            ]),
        };
        let row = FitRun::of("dense_office", 1_140_000, true, Some(2), &out);
        assert_eq!((row.fit_ms, row.total_ms), (40, 320));
        assert!((row.fit_share - 0.125).abs() < 1e-12);
        assert_eq!((row.largest_stage.as_str(), row.largest_ms), ("label", 150));
        let text = markdown(&Report {
            machine: String::new(),
            load_average: String::new(),
            steal_percent: Some(12.5),
            plan_runs: Vec::new(),
            exponents: Vec::new(),
            speedups: Vec::new(),
            read_runs: Vec::new(),
            upload_runs: Vec::new(),
            fit_runs: vec![row],
        });
        assert!(
            text.contains(
                "| dense_office | 1.1M | yes | 2 | 420 | 320 | 40 | 12.5 % | label (150 ms) |"
            ),
            "{text}"
        );
        assert!(
            text.contains("The host took 12.5 % of the CPUs' time while the bench ran"),
            "{text}"
        );
    }

    #[test]
    fn speedups_compare_each_stage_with_the_fewest_threads() {
        let with = |threads: usize, plan_ms: f64, samples: u64| {
            let mut r = run(1_000_000, plan_ms);
            r.threads = Some(threads);
            r.stages_ms = BTreeMap::from([
                ("samples".to_string(), samples),
                ("label".to_string(), 50),
                ("write".to_string(), 0),
            ]);
            r
        };
        let mut other_size = with(1, 10.0, 1);
        other_size.points = 4_000_000;
        let s = speedups(&[with(1, 1000.0, 600), with(2, 800.0, 300), other_size]);
        assert_eq!(s.len(), 1, "{s:?}");
        assert_eq!((s[0].base_threads, s[0].threads), (1, 2));
        assert!((s[0].plan - 1.25).abs() < 1e-12);
        assert!((s[0].stages["samples"] - 2.0).abs() < 1e-12);
        assert!((s[0].stages["label"] - 1.0).abs() < 1e-12);
        // A stage that took no measurable time has no ratio.
        assert!(!s[0].stages.contains_key("write"));
    }
}
