//! Every integration test of the service and the binary, in one test binary: each binary links
//! the whole service, and linking one instead of eleven saves minutes on a small machine. No
//! test here changes process-wide state (environment, current directory, signal handlers), so
//! they share a process safely; the ones that need a process of their own start `asbuilt`.
//!
//! One topic per module; run one with `cargo test --test service MODULE::`.

mod support;

mod api;
mod backends;
mod browser;
mod cli;
mod deploy_manifests;
mod early_read;
mod hostile;
mod integrating;
mod job_api;
mod scale_out;
mod service_plan;
mod service_process;
mod simulate_cli;
mod streaming_cli;
