//! Diagnostic for one wall segment A-B of a scan file: the points near it by scan and height,
//! the points each scan recorded beyond it, the samples along it with their viewers, the lines
//! of sight that cross it, and the labels of the triangles touching it.
//! `wall_diag --input FILE [--poses F] [--drop-slot N] LEVEL AX,AY,BX,BY` (`DUMP=FILE` writes
//! the points around as x y z slot).
use asbuilt_plan::cloud::Viewpoints;
use asbuilt_plan::geom::{cross, sub, P2};
use asbuilt_plan::io::{self, poses};
use asbuilt_plan::labeling::label_with_report;
use asbuilt_plan::samples::{sample_walls, SpacingProbe};
use asbuilt_plan::smoothing::smooth_samples;
use asbuilt_plan::stories::split_stories;
use asbuilt_plan::Cancel;
use asbuilt_plan::Params;

fn seg_hit(p: P2, q: P2, a: P2, b: P2) -> Option<(f64, f64)> {
    let r = sub(q, p);
    let s = sub(b, a);
    let d = cross(r, s);
    if d.abs() < 1e-12 {
        return None;
    }
    let t = cross(sub(a, p), s) / d;
    let u = cross(sub(a, p), r) / d;
    ((0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u)).then_some((t, u))
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let i = args.iter().position(|a| a == "--input").unwrap();
    let path = std::path::PathBuf::from(args.remove(i + 1));
    args.remove(i);
    let mut cloud = io::read_cloud(&path).unwrap();
    if let Some(j) = args.iter().position(|a| a == "--poses") {
        poses::load_poses(&mut cloud, std::path::Path::new(&args.remove(j + 1))).unwrap();
        args.remove(j);
    }
    if let Some(j) = args.iter().position(|a| a == "--drop-slot") {
        let slot: u16 = args.remove(j + 1).parse().unwrap();
        args.remove(j);
        let keep: Vec<bool> = cloud.scan.iter().map(|&s| s != slot).collect();
        let mut k = 0;
        cloud.xyz.retain(|_| {
            k += 1;
            keep[k - 1]
        });
        cloud.scan.retain(|&s| s != slot);
        eprintln!("dropped slot {slot}: {} points left", cloud.xyz.len());
    }
    let mut params = Params::default();
    while let Some(i) = args.iter().position(|a| a == "--param") {
        params.set(&args[i + 1]).expect("a parameter");
        args.drain(i..i + 2);
    }
    let level: usize = args[0].parse().unwrap();
    let v: Vec<f64> = args[1].split(',').map(|x| x.parse().unwrap()).collect();
    let (a, b) = ([v[0], v[1]], [v[2], v[3]]);
    let (params, _) = params.derive(SpacingProbe::of(&cloud.xyz).spacing());
    let estimated = asbuilt_plan::viewpoints::estimate(&cloud, &params.viewpoints).viewpoints;
    match &estimated {
        Some(Viewpoints::Trajectory(_)) if params.viewpoints.open_space => {}
        Some(v) => cloud.viewpoints = v.clone(),
        None => {}
    }
    let z: Vec<f32> = cloud.xyz.iter().map(|p| p[2]).collect();
    let stories = split_stories(&z, &params.stories).unwrap();
    let story = &stories[level];
    eprintln!(
        "story floor {:.2} top {:.2} z {:.2}..{:.2}",
        story.floor_z, story.top_z, story.z_min, story.z_max
    );
    if let Viewpoints::Static(p) = &cloud.viewpoints {
        for (k, p) in p.iter().enumerate() {
            eprintln!("pose slot {k}: {:?}", p.position);
        }
    }
    let len = asbuilt_plan::geom::dist(a, b);
    let dir = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
    let nrm = [-dir[1], dir[0]];
    // Raw points near the line: height histogram per scan slot, each side.
    let mut hist: std::collections::BTreeMap<(u16, i32), [u32; 14]> = Default::default();
    for (k, p) in cloud.xyz.iter().enumerate() {
        let d = sub([p[0] as f64, p[1] as f64], a);
        let t = d[0] * dir[0] + d[1] * dir[1];
        let o = d[0] * nrm[0] + d[1] * nrm[1];
        if t < 0.0 || t > len || o.abs() > 0.15 {
            continue;
        }
        let side = (o / 0.05).floor() as i32;
        let zb = (((p[2] as f64 - story.floor_z) / 0.25).floor() as i32).clamp(0, 13) as usize;
        let slot = cloud.scan.get(k).copied().unwrap_or(u16::MAX);
        hist.entry((slot, side)).or_insert([0; 14])[zb] += 1;
    }
    for ((slot, side), h) in &hist {
        eprintln!("pts slot {slot} off {:+.2}: {:?}", *side as f64 * 0.05, h);
    }

    if let Viewpoints::Static(ps) = &cloud.viewpoints {
        for (slot, p) in ps.iter().enumerate() {
            through(&cloud, slot as u16, p.position, a, b, story.floor_z);
        }
    }
    if let Ok(path) = std::env::var("DUMP") {
        use std::io::Write;
        let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
        for (k, p) in cloud.xyz.iter().enumerate() {
            if p[0] > -14.5 && p[0] < -8.0 && p[1] > -5.5 && p[1] < 0.5 {
                writeln!(
                    f,
                    "{} {} {} {}",
                    p[0],
                    p[1],
                    p[2],
                    cloud.scan.get(k).copied().unwrap_or(0)
                )
                .unwrap();
            }
        }
    }
    let mut samples = sample_walls(&cloud, story, &params.samples, &Cancel::never()).unwrap();
    smooth_samples(
        &mut samples,
        params.samples.cell_size,
        &params.smoothing,
        &Cancel::never(),
    )
    .unwrap();
    eprintln!("viewpoints listed: {:?}", samples.viewpoints);
    for s in &samples.samples {
        let d = sub(s.pos, a);
        let t = d[0] * dir[0] + d[1] * dir[1];
        let o = d[0] * nrm[0] + d[1] * nrm[1];
        if t > -0.3 && t < len + 0.3 && o.abs() < 0.3 {
            eprintln!(
                "sample t {t:.2} off {o:+.3} pos [{:.2},{:.2}] n [{:.2},{:.2}] conf {:.2} seen {:?}",
                s.pos[0], s.pos[1], s.normal[0], s.normal[1], s.confidence, s.seen_from
            );
        }
    }
    // Rays crossing the segment.
    let lp = &params.labeling;
    let f = lp.ray_fraction;
    let lo = if lp.rays_from_scanner {
        0.0
    } else {
        (1.0 - f) / 2.0
    };
    // The walked part of the line of sight from `vp` to `pos`, as the labeling walks it.
    let ray = |vp: P2, pos: P2| {
        let dd = asbuilt_plan::geom::dist(vp, pos);
        let hi = match lp.ray_end_margin {
            Some(m) => ((1.0 + f) / 2.0).max(1.0 - m / dd.max(1e-9)),
            None => (1.0 + f) / 2.0,
        };
        let at = |k: f64| [vp[0] + k * (pos[0] - vp[0]), vp[1] + k * (pos[1] - vp[1])];
        (at(lo), at(hi))
    };
    let mut per_vp: std::collections::BTreeMap<u32, Vec<(P2, f64)>> = Default::default();
    for s in &samples.samples {
        for &vi in &s.seen_from {
            let (p, q) = ray(samples.viewpoints[vi as usize], s.pos);
            if let Some((_, u)) = seg_hit(p, q, a, b) {
                per_vp.entry(vi).or_default().push((s.pos, u));
            }
        }
    }
    for (vi, v) in &per_vp {
        eprintln!(
            "viewpoint {vi} {:?}: {} rays cross the segment, e.g. to {:?}",
            samples.viewpoints[*vi as usize],
            v.len(),
            &v[..v.len().min(8)]
        );
    }
    let (labeled, report) =
        label_with_report(&samples, &params.labeling, &Cancel::never()).unwrap();
    let m = &labeled.mesh;
    let mut n_forced = 0;
    for (t, tri) in m.triangles.iter().enumerate() {
        let p = tri.map(|k| m.vertices[k as usize]);
        let hits = (0..3).any(|e| seg_hit(p[e], p[(e + 1) % 3], a, b).is_some());
        if hits {
            if labeled.forced[t] == Some(true) {
                n_forced += 1;
            }
            eprintln!(
                "tri {t} {:?} inside {} forced {:?}",
                p.map(|q| [
                    (q[0] * 100.0).round() / 100.0,
                    (q[1] * 100.0).round() / 100.0
                ]),
                labeled.inside[t],
                labeled.forced[t]
            );
        }
    }
    eprintln!("forced-inside triangles crossing the segment: {n_forced}");
    // Triangles on the + side touching the face: which rays cross them.
    let on_face = |q: P2| {
        let d = sub(q, a);
        let t = d[0] * dir[0] + d[1] * dir[1];
        let o = d[0] * nrm[0] + d[1] * nrm[1];
        t > 0.1 * len && t < 0.9 * len && o.abs() < 0.03
    };
    let inside_tri = |p: [P2; 3], q: P2| {
        let s0 = cross(sub(p[1], p[0]), sub(q, p[0]));
        let s1 = cross(sub(p[2], p[1]), sub(q, p[1]));
        let s2 = cross(sub(p[0], p[2]), sub(q, p[2]));
        (s0 >= 0.0 && s1 >= 0.0 && s2 >= 0.0) || (s0 <= 0.0 && s1 <= 0.0 && s2 <= 0.0)
    };
    for (t, tri) in m.triangles.iter().enumerate() {
        let p = tri.map(|k| m.vertices[k as usize]);
        let c = [
            (p[0][0] + p[1][0] + p[2][0]) / 3.0,
            (p[0][1] + p[1][1] + p[2][1]) / 3.0,
        ];
        let dc = sub(c, a);
        if !(p.iter().any(|&q| on_face(q)) && dc[0] * nrm[0] + dc[1] * nrm[1] > 0.005) {
            continue;
        }
        let mut by: std::collections::BTreeMap<u32, usize> = Default::default();
        for s in &samples.samples {
            for &vi in &s.seen_from {
                let (p0, q0) = ray(samples.viewpoints[vi as usize], s.pos);
                let hit = (0..3).any(|e| seg_hit(p0, q0, p[e], p[(e + 1) % 3]).is_some())
                    || inside_tri(p, p0)
                    || inside_tri(p, q0);
                if hit {
                    *by.entry(vi).or_default() += 1;
                }
            }
        }
        eprintln!(
            "plus-side tri {t} {:?} inside {} forced {:?} rays by viewpoint {:?}",
            p.map(|q| [
                (q[0] * 100.0).round() / 100.0,
                (q[1] * 100.0).round() / 100.0
            ]),
            labeled.inside[t],
            labeled.forced[t],
            by
        );
    }
    eprintln!("report: {report:?}");
}

/// Points of scan slot `slot` whose 2D line from `vp` crosses segment a-b, beyond it: the height
/// (above `floor`) where the 3D line crosses the segment, and the point's own height.
#[allow(dead_code)]
pub fn through(
    cloud: &asbuilt_plan::PointCloud,
    slot: u16,
    vp: [f64; 3],
    a: P2,
    b: P2,
    floor: f64,
) {
    let mut hist = [0u32; 14];
    let mut own = [0u32; 14];
    let mut uh = [0u32; 20];
    let mut n = 0;
    let mut ex = Vec::new();
    let key = |p: &[f32; 3]| {
        (
            (p[0] / 0.1).floor() as i64,
            (p[1] / 0.1).floor() as i64,
            (p[2] / 0.1).floor() as i64,
        )
    };
    let mut others = std::collections::HashSet::new();
    for (k, p) in cloud.xyz.iter().enumerate() {
        if cloud.scan.get(k) != Some(&slot) {
            others.insert(key(p));
        }
    }
    let mut near_other = 0;
    for (k, p) in cloud.xyz.iter().enumerate() {
        if cloud.scan.get(k) != Some(&slot) {
            continue;
        }
        let q = [p[0] as f64, p[1] as f64];
        if let Some((t, u)) = seg_hit([vp[0], vp[1]], q, a, b) {
            if t > 0.97 || !(0.05..=0.95).contains(&u) {
                continue; // on the wall itself
            }
            let zc = vp[2] + t * (p[2] as f64 - vp[2]) - floor;
            hist[((zc / 0.25).floor() as i32).clamp(0, 13) as usize] += 1;
            uh[((u * 20.0) as usize).min(19)] += 1;
            own[(((p[2] as f64 - floor) / 0.25).floor() as i32).clamp(0, 13) as usize] += 1;
            n += 1;
            let (x, y, z) = key(p);
            if (-1..=1).any(|i| {
                (-1..=1).any(|j| (-1..=1).any(|l| others.contains(&(x + i, y + j, z + l))))
            }) {
                near_other += 1;
            }
            if ex.len() < 10 && n % 7 == 0 {
                ex.push((q, u, p[2] as f64 - floor, zc));
            }
        }
    }
    eprintln!("slot {slot}: {n} points seen through the segment ({near_other} within 10-20 cm of another scan's); crossing height hist {hist:?}; own height hist {own:?}; u hist {uh:?}; e.g. {ex:?}");
}
