//! Times stage 4 (labeling) on a synthetic floor of rooms and scores it against the truth.
//!
//! `cargo run --release -p asbuilt-plan --example labeling_bench -- [cols rows] [--no-poses]
//! [--solver eigen|harmonic] [--dense-below N] [--noise metres]`
//!
//! Rooms are 4 m × 3 m behind 0.2 m walls, with a 0.9 m door in every wall between horizontal
//! neighbours; samples every 5 cm along every wall face, normals into the room. With poses,
//! each room has a scanner at its centre that sees its own walls (jambs from both sides).

use asbuilt_plan::Cancel;
use std::time::Instant;

use asbuilt_plan::geom::P2;
use asbuilt_plan::labeling::{label_with_report, LabelingParams, Solver};
use asbuilt_plan::samples::{WallSample, WallSamples};

const W: f64 = 4.0;
const H: f64 = 3.0;
const T: f64 = 0.2;
const DOOR: (f64, f64) = (1.0, 1.9);
const STEP: f64 = 0.05;

struct Floor {
    cols: usize,
    rows: usize,
}

impl Floor {
    fn room(&self, i: usize, j: usize) -> [f64; 4] {
        let x = i as f64 * (W + T);
        let y = j as f64 * (H + T);
        [x, y, x + W, y + H]
    }

    fn inside(&self, p: P2) -> bool {
        let (fi, fj) = (p[0] / (W + T), p[1] / (H + T));
        if fi < 0.0 || fj < 0.0 {
            return false;
        }
        let (i, j) = (fi as usize, fj as usize);
        if i >= self.cols || j >= self.rows {
            return false;
        }
        let [x0, y0, x1, y1] = self.room(i, j);
        let in_room = p[0] > x0 && p[0] < x1 && p[1] > y0 && p[1] < y1;
        // The door to the right neighbour.
        let in_door = i + 1 < self.cols && p[0] >= x1 && p[1] > y0 + DOOR.0 && p[1] < y0 + DOOR.1;
        in_room || in_door
    }
}

/// Deterministic jitter in [-1, 1].
fn jitter(k: u64) -> f64 {
    let mut x = k.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03;
    x ^= x >> 29;
    x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^= x >> 32;
    (x as f64 / u64::MAX as f64) * 2.0 - 1.0
}

fn push_segment(out: &mut Vec<WallSample>, a: P2, b: P2, normal: P2, seen: Vec<u32>, noise: f64) {
    let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
    let n = (len / STEP).round().max(1.0) as usize;
    for k in 0..n {
        let t = k as f64 / n as f64;
        let id = out.len() as u64;
        out.push(WallSample {
            pos: [
                a[0] + t * (b[0] - a[0]) + noise * jitter(2 * id),
                a[1] + t * (b[1] - a[1]) + noise * jitter(2 * id + 1),
            ],
            normal,
            confidence: 1.0,
            seen_from: seen.clone(),
        });
    }
}

fn samples(f: &Floor, poses: bool, noise: f64) -> WallSamples {
    let mut out = Vec::new();
    let mut viewpoints = Vec::new();
    for j in 0..f.rows {
        for i in 0..f.cols {
            let [x0, y0, x1, y1] = f.room(i, j);
            let me = (j * f.cols + i) as u32;
            let seen = |ids: &[u32]| if poses { ids.to_vec() } else { vec![] };
            viewpoints.push([(x0 + x1) / 2.0 + 0.3, (y0 + y1) / 2.0 - 0.2]);
            push_segment(&mut out, [x0, y0], [x1, y0], [0.0, 1.0], seen(&[me]), noise);
            push_segment(
                &mut out,
                [x1, y1],
                [x0, y1],
                [0.0, -1.0],
                seen(&[me]),
                noise,
            );
            // Left and right walls, with door gaps toward neighbours.
            let door = |has: bool, x: f64, n: P2, out: &mut Vec<WallSample>| {
                if has {
                    push_segment(out, [x, y0], [x, y0 + DOOR.0], n, seen(&[me]), noise);
                    push_segment(out, [x, y0 + DOOR.1], [x, y1], n, seen(&[me]), noise);
                } else {
                    push_segment(out, [x, y0], [x, y1], n, seen(&[me]), noise);
                }
            };
            door(i > 0, x0, [1.0, 0.0], &mut out);
            door(i + 1 < f.cols, x1, [-1.0, 0.0], &mut out);
            if i + 1 < f.cols {
                // Door jambs through the wall, seen from both rooms.
                let both = seen(&[me, me + 1]);
                let (ya, yb) = (y0 + DOOR.0, y0 + DOOR.1);
                push_segment(
                    &mut out,
                    [x1, ya],
                    [x1 + T, ya],
                    [0.0, 1.0],
                    both.clone(),
                    noise,
                );
                push_segment(&mut out, [x1, yb], [x1 + T, yb], [0.0, -1.0], both, noise);
            }
        }
    }
    WallSamples {
        samples: out,
        viewpoints: if poses { viewpoints } else { vec![] },
        ..Default::default()
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let nums: Vec<usize> = args.iter().filter_map(|a| a.parse().ok()).collect();
    let (cols, rows) = match nums[..] {
        [c, r, ..] => (c, r),
        _ => (19, 19),
    };
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
    };
    let poses = !args.iter().any(|a| a == "--no-poses");
    let mut params = LabelingParams::default();
    if let Some(s) = value("--solver") {
        params.solver = if s == "harmonic" {
            Solver::Harmonic
        } else {
            Solver::Eigen
        };
    }
    if let Some(n) = value("--dense-below").and_then(|s| s.parse().ok()) {
        params.dense_below = n;
    }
    let noise = value("--noise").and_then(|s| s.parse().ok()).unwrap_or(0.0);
    let floor = Floor { cols, rows };
    let ws = samples(&floor, poses, noise);
    let start = Instant::now();
    let (l, r) = match label_with_report(&ws, &params, &Cancel::never()) {
        Ok(x) => x,
        Err(e) => {
            eprintln!("labeling failed: {e}");
            std::process::exit(1);
        }
    };
    let secs = start.elapsed().as_secs_f64();
    // Score: area-weighted on a fine grid over the rooms' extent.
    let ext = floor.room(cols - 1, rows - 1);
    let (mut both, mut either, mut hint) = (0usize, 0usize, 0usize);
    let n = 1500;
    for a in 0..n {
        for b in 0..n {
            let p = [
                -0.5 + (ext[2] + 1.0) * (a as f64 + 0.5) / n as f64,
                -0.5 + (ext[3] + 1.0) * (b as f64 + 0.5) / n as f64,
            ];
            let Some(t) = l.mesh.locate(p, hint) else {
                continue;
            };
            hint = t;
            let (x, y) = (l.inside[t], floor.inside(p));
            both += (x && y) as usize;
            either += (x || y) as usize;
        }
    }
    // Wall triangles labeled inside: all three corners on wall faces and the centroid in a wall.
    let mut bridges = 0;
    let mut shown = Vec::new();
    for t in 0..l.inside.len() {
        let [a, b, c] = l.mesh.corners(t);
        let g = [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0];
        if l.inside[t] && !floor.inside(g) && !l.mesh.touches_corner(t) {
            bridges += 1;
            if shown.len() < 5 {
                shown.push(format!("({:.3}, {:.3})", g[0], g[1]));
            }
        }
    }
    println!(
        "rooms {cols}x{rows}, poses {poses}, noise {noise} m: {} samples, {} triangles",
        r.samples, r.triangles
    );
    println!(
        "labeling {secs:.3} s (mesh {:.0} ms, graph {:.0} ms, constraints {:.0} ms, solve {:.0} ms)",
        r.timings.mesh_ms, r.timings.graph_ms, r.timings.constraints_ms, r.timings.solve_ms
    );
    println!(
        "method {:?}, λ {:?}, residual {:?}, solves {}, disagreement {:?}, fallback {:?}",
        r.method, r.eigenvalue, r.residual, r.iterations, r.disagreement, r.fallback
    );
    println!(
        "forced inside {} (rays {}, poses {}), outside {}, conflicts {}, rays {} (+{} skipped), free {}",
        r.forced_inside,
        r.inside_by_rays,
        r.inside_by_poses,
        r.forced_outside,
        r.conflicts,
        r.rays,
        r.rays_skipped,
        r.free_nodes
    );
    println!(
        "IoU {:.4}; inside triangles with centroid outside the truth: {bridges}",
        both as f64 / either.max(1) as f64
    );
    if !shown.is_empty() {
        println!("first of them at {}", shown.join(" "));
    }
}
