//! The `asbuilt` command: the floor-plan pipeline from the command line, and the service.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cli;

/// Watertight as-built floor plans from laser scans.
#[derive(Parser)]
#[command(name = "asbuilt", version, about)]
struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Make a floor plan from a point cloud.
    Plan(cli::plan::PlanArgs),
    /// Describe a point cloud: points, bounds, scans, poses, format.
    Info(cli::info::InfoArgs),
    /// Generate a synthetic building, scan it, and write the cloud, poses and ground truth.
    Simulate(cli::simulate::SimulateArgs),
    /// Run the HTTP API and its workers (SQLite and a local data directory by default).
    Serve(cli::serve::ServeArgs),
    /// Create or upgrade the job database, then exit.
    Migrate(cli::serve::ServeArgs),
    /// Run pipeline workers only, sharing a PostgreSQL database and S3 storage with the API.
    Worker(cli::serve::WorkerArgs),
    /// Ask a running server or worker for /healthz; exit 0 when healthy (for container health checks).
    Healthcheck(cli::healthcheck::HealthcheckArgs),
    /// Time the pipeline per stage on generated buildings of 1 M to 70 M points (see benches/README.md).
    #[cfg(feature = "bench")]
    Bench(cli::bench::BenchArgs),
}

fn main() -> ExitCode {
    asbuilt_plan::io::keep_freed_memory();
    let args = Args::parse();
    let result = match args.command {
        Command::Plan(a) => cli::plan::run(a),
        Command::Info(a) => cli::info::run(a),
        Command::Simulate(a) => cli::simulate::run(a),
        Command::Serve(a) => cli::serve::run(a),
        Command::Migrate(a) => cli::serve::migrate(a),
        Command::Worker(a) => cli::serve::worker(a),
        Command::Healthcheck(a) => cli::healthcheck::run(a),
        #[cfg(feature = "bench")]
        Command::Bench(a) => cli::bench::run(a),
    };
    // `asbuilt bench` measures each child's peak memory this way.
    #[cfg(feature = "bench")]
    if let Some(path) = std::env::var_os(cli::bench::PEAK_RSS_ENV) {
        cli::bench::write_peak_rss(std::path::Path::new(&path));
    }
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("asbuilt: {}", cli::describe(&e));
            ExitCode::FAILURE
        }
    }
}
