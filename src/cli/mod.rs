//! The command-line front ends of the pipeline. Each subcommand is a file with `Args` and `run`.

#[cfg(feature = "bench")]
pub mod bench;
#[cfg(feature = "bench")]
mod bench_upload;
pub mod healthcheck;
pub mod info;
pub mod plan;
mod progress;
pub mod serve;
pub mod simulate;
