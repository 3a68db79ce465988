//! Converts a cloud between formats, for read benchmarks: the output's extension chooses the
//! writer (`.e57` with its poses, `.las`, `.laz`, `.ply`, `.ascii.ply`, `.xyz` with the scan
//! index as a fourth column).
//!
//! ```sh
//! cargo run --release -p asbuilt-plan --example convert -- IN [--poses POSES.json] OUT...
//! ```

use std::path::{Path, PathBuf};

use asbuilt_plan::io::{self, export, ply, poses};

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let sidecar = args.iter().position(|a| a == "--poses").map(|i| {
        let p = PathBuf::from(args.get(i + 1).cloned().unwrap_or_else(|| usage()));
        args.drain(i..i + 2);
        p
    });
    if args.len() < 2 {
        usage();
    }
    let input = Path::new(&args[0]);
    let mut cloud = io::read_cloud(input).unwrap_or_else(|e| fail(e));
    if let Some(p) = &sidecar {
        poses::load_poses(&mut cloud, p).unwrap_or_else(|e| fail(e));
    }
    eprintln!("read {} points from {}", cloud.len(), input.display());
    for out in &args[1..] {
        let path = Path::new(out);
        let name = out.to_ascii_lowercase();
        let result = if name.ends_with(".e57") {
            export::write_e57(path, &cloud).map_err(|e| e.to_string())
        } else if name.ends_with(".laz") {
            export::write_las(path, &cloud, true).map_err(|e| e.to_string())
        } else if name.ends_with(".las") {
            export::write_las(path, &cloud, false).map_err(|e| e.to_string())
        } else if name.ends_with(".ascii.ply") {
            ply::write_ply(path, &cloud, ply::Encoding::Ascii).map_err(|e| e.to_string())
        } else if name.ends_with(".ply") {
            ply::write_ply(path, &cloud, ply::Encoding::BinaryLittleEndian)
                .map_err(|e| e.to_string())
        } else if name.ends_with(".xyz") {
            export::write_xyz(path, &cloud).map_err(|e| e.to_string())
        } else {
            Err(format!("{out}: unknown output format"))
        };
        result.unwrap_or_else(|e| fail(e));
        eprintln!("wrote {out}");
    }
}

fn usage() -> ! {
    eprintln!("usage: convert IN [--poses POSES.json] OUT...");
    std::process::exit(2)
}

fn fail(e: impl std::fmt::Display) -> ! {
    eprintln!("{e}");
    std::process::exit(1)
}
