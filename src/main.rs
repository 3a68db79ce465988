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
    /// Ask a running server or worker for /healthz; exit 0 when healthy (for container health checks).
    Healthcheck(cli::healthcheck::HealthcheckArgs),
}

fn main() -> ExitCode {
    let args = Args::parse();
    let result = match args.command {
        Command::Plan(a) => cli::plan::run(a),
        Command::Info(a) => cli::info::run(a),
        Command::Simulate(a) => cli::simulate::run(a),
        Command::Healthcheck(a) => cli::healthcheck::run(a),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("asbuilt: {e:#}");
            ExitCode::FAILURE
        }
    }
}
