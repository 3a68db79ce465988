//! Helpers shared by the tests: a server in process or as a process, the engines, the OpenAPI
//! contract, and waiting for an outcome.

pub mod contract;
pub mod engines;
pub mod process;
pub mod server;
pub mod wait;

use std::path::{Path, PathBuf};

/// Every file under `dir` (the blob store's leftovers).
pub fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = vec![];
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            if e.path().is_dir() {
                stack.push(e.path());
            } else {
                out.push(e.path());
            }
        }
    }
    out
}
