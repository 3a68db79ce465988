//! Draws one story's stages as SVG, for looking at what the labeling did.
//!
//! Run with `cargo run --release -p asbuilt-plan --example render_stages -- BUILDING POINTS SEED
//! LEVEL OUT_DIR [--no-poses] [--mobile] [--view X0,Y0,X1,Y1]`, or on a scan file with
//! `-- --input FILE [--poses FILE] LEVEL OUT_DIR [--no-poses] [--view ...]` (no truth drawn; the
//! view is in the cloud's local frame). It writes `labels.svg` (after labeling), `cleaned.svg` (after
//! cleanup) and `fitted.svg` (the final polygons over the cleaned labels, truth in red).
//! Triangles: inside light blue, outside white, forced inside dark blue, forced outside grey.

use asbuilt_plan::boundary::trace_boundary;
use asbuilt_plan::cleanup::clean_labels;
use asbuilt_plan::cloud::Viewpoints;
use asbuilt_plan::fitting::fit_walls;
use asbuilt_plan::geom::P2;
use asbuilt_plan::io::{self, poses};
use asbuilt_plan::labeling::{label, LabeledMesh};
use asbuilt_plan::samples::sample_walls;
use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};
use asbuilt_plan::smoothing::smooth_samples;
use asbuilt_plan::stories::split_stories;
use asbuilt_plan::Cancel;
use asbuilt_plan::Params;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let (mut cloud, truth_stories) = match args.iter().position(|a| a == "--input") {
        Some(i) => {
            let path = std::path::PathBuf::from(args.remove(i + 1));
            args.remove(i);
            let mut cloud = io::read_cloud(&path).unwrap();
            if let Some(j) = args.iter().position(|a| a == "--poses") {
                poses::load_poses(&mut cloud, std::path::Path::new(&args.remove(j + 1))).unwrap();
                args.remove(j);
            }
            (cloud, None)
        }
        None => {
            let kind = BuildingKind::from_name(&args[0]).expect("a building name");
            let options = ScanOptions {
                points: args[1].parse().unwrap(),
                seed: args[2].parse().unwrap(),
                mobile: args.iter().any(|a| a == "--mobile"),
                ..Default::default()
            };
            let sim = simulate(kind, &options).unwrap();
            args.drain(..3);
            (sim.cloud, Some(sim.truth.stories))
        }
    };
    let level: usize = args[0].parse().unwrap();
    let out = std::path::PathBuf::from(&args[1]);
    std::fs::create_dir_all(&out).unwrap();
    if args.iter().any(|a| a == "--no-poses") {
        cloud.viewpoints = Viewpoints::None;
        cloud.scan.clear();
        cloud.scan_ids.clear();
    }
    let params = Params::default();
    let view: Option<[f64; 4]> = args.iter().position(|a| a == "--view").map(|i| {
        let v: Vec<f64> = args[i + 1].split(',').map(|x| x.parse().unwrap()).collect();
        [v[0], v[1], v[2], v[3]]
    });
    let z: Vec<f32> = cloud.xyz.iter().map(|p| p[2]).collect();
    let stories = split_stories(&z, &params.stories).unwrap();
    let story = &stories[level];
    let mut samples = sample_walls(&cloud, story, &params.samples, &Cancel::never()).unwrap();
    smooth_samples(
        &mut samples,
        params.samples.cell_size,
        &params.smoothing,
        &Cancel::never(),
    )
    .unwrap();
    let mut labeled = label(&samples, &params.labeling, &Cancel::never()).unwrap();
    let truth: Vec<Vec<P2>> = truth_stories.map_or(Vec::new(), |t| {
        t[level]
            .polygons
            .iter()
            .flat_map(|p| std::iter::once(p.exterior.clone()).chain(p.holes.clone()))
            .collect()
    });
    let poses = samples.viewpoints.clone();
    std::fs::write(
        out.join("labels.svg"),
        draw(&labeled, &[], &truth, &poses, view),
    )
    .unwrap();
    let report = clean_labels(&mut labeled, &params.cleanup);
    eprintln!("cleanup: {report:?}");
    std::fs::write(
        out.join("cleaned.svg"),
        draw(&labeled, &[], &truth, &poses, view),
    )
    .unwrap();
    let boundary = trace_boundary(&labeled).unwrap();
    let fitted = fit_walls(&labeled, &boundary, &params.fitting, &Cancel::never()).unwrap();
    let rings: Vec<Vec<P2>> = fitted
        .polygons
        .iter()
        .flat_map(|p| std::iter::once(p.exterior.clone()).chain(p.holes.clone()))
        .collect();
    std::fs::write(
        out.join("fitted.svg"),
        draw(&labeled, &rings, &truth, &poses, view),
    )
    .unwrap();
}

fn draw(
    l: &LabeledMesh,
    rings: &[Vec<P2>],
    truth: &[Vec<P2>],
    poses: &[P2],
    view: Option<[f64; 4]>,
) -> String {
    let m = &l.mesh;
    let pts = &m.vertices[..m.n_samples];
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for p in pts {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k] - 0.5);
            hi[k] = hi[k].max(p[k] + 0.5);
        }
    }
    if let Some(v) = view {
        (lo, hi) = ([v[0], v[1]], [v[2], v[3]]);
    }
    let s = 2400.0 / (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let tx = |p: P2| format!("{:.1},{:.1}", (p[0] - lo[0]) * s, (hi[1] - p[1]) * s);
    let mut o = format!(
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{:.0}" height="{:.0}" style="background:white">"##,
        (hi[0] - lo[0]) * s,
        (hi[1] - lo[1]) * s
    );
    for (t, tri) in m.triangles.iter().enumerate() {
        let fill = match (l.forced[t], l.inside[t]) {
            (Some(true), _) => "#36c",
            (Some(false), _) => "#bbb",
            (None, true) => "#adf",
            (None, false) => "#fff",
        };
        let d: Vec<String> = tri.iter().map(|&v| tx(m.vertices[v as usize])).collect();
        o += &format!(
            r##"<polygon points="{}" fill="{fill}" stroke="#999" stroke-width="0.3"/>"##,
            d.join(" ")
        );
    }
    for (i, p) in pts.iter().enumerate() {
        let n = m.normals[i];
        let q = [p[0] + 0.08 * n[0], p[1] + 0.08 * n[1]];
        o += &format!(
            r#"<line points="" x1="{}" y1="{}" x2="{}" y2="{}" stroke="green" stroke-width="0.8"/>"#,
            tx(*p).split(',').next().unwrap(),
            tx(*p).split(',').nth(1).unwrap(),
            tx(q).split(',').next().unwrap(),
            tx(q).split(',').nth(1).unwrap()
        );
    }
    for (ring, colour) in rings
        .iter()
        .map(|r| (r, "black"))
        .chain(truth.iter().map(|r| (r, "red")))
    {
        let d: Vec<String> = ring.iter().map(|p| tx(*p)).collect();
        o += &format!(
            r#"<polygon points="{}" fill="none" stroke="{colour}" stroke-width="1.5"/>"#,
            d.join(" ")
        );
    }
    for p in poses {
        let c = tx(*p);
        let (x, y) = c.split_once(',').unwrap();
        o += &format!(r#"<circle cx="{x}" cy="{y}" r="5" fill="orange"/>"#);
    }
    o + "</svg>"
}
