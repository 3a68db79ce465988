//! Draws one story's stages as SVG, for looking at what the labeling did.
//!
//! Run with `cargo run --release -p asbuilt-plan --example render_stages -- BUILDING POINTS SEED
//! LEVEL OUT_DIR [--no-poses | --plain] [--mobile] [--view X0,Y0,X1,Y1]`, or on a scan file with
//! `-- --input FILE [--poses FILE] LEVEL OUT_DIR [--no-poses] [--view ...]` (no truth drawn; the
//! view is in the cloud's local frame). It writes `labels.svg` (after labeling), `cleaned.svg` (after
//! cleanup) and `fitted.svg` (the final polygons over the cleaned labels, truth in red). Scanners the
//! cloud does not give are estimated first, as the plan does (pseudo-viewpoints in open space too).
//! Triangles: inside light blue, outside white, forced inside dark blue, forced outside grey.
//!
//! It also writes `plan.png`: the plan the pipeline makes (`asbuilt_plan::plan`, derived
//! parameters and all) for that level, in black, over the story's points in a slice from 35 %
//! to 65 % of its height (grey), with its wall samples (blue), scanners (orange) and the truth
//! (red).
//!
//! And `rooms.png`: the plan's rooms for that level, each filled in its own colour and labelled
//! with its number and area (m²), over the same slice, with doors (green), openings (magenta),
//! windows (cyan) and wall centre lines (dark grey; exterior ones light grey), truth in red.

use asbuilt_plan::boundary::trace_boundary;
use asbuilt_plan::cleanup::clean_labels;
use asbuilt_plan::cloud::Viewpoints;
use asbuilt_plan::fitting::fit_walls;
use asbuilt_plan::geom::P2;
use asbuilt_plan::io::{self, poses};
use asbuilt_plan::labeling::{label, LabeledMesh};
use asbuilt_plan::samples::{sample_walls, SpacingProbe};
use asbuilt_plan::simulate::{random, scan, BuildingKind, ScanOptions};
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
            let building = random::from_name(&args[0])
                .or_else(|| BuildingKind::from_name(&args[0]).map(BuildingKind::build))
                .expect("a building name (or random_SEED, random30_SEED)");
            let options = ScanOptions {
                points: args[1].parse().unwrap(),
                seed: args[2].parse().unwrap(),
                mobile: args.iter().any(|a| a == "--mobile"),
                voxel: BuildingKind::from_name(&args[0]).and_then(BuildingKind::voxel),
                ..Default::default()
            };
            let sim = scan(&building, &options).unwrap();
            args.drain(..3);
            (sim.cloud, Some(sim.truth.stories))
        }
    };
    let level: usize = args[0].parse().unwrap();
    let out = std::path::PathBuf::from(&args[1]);
    std::fs::create_dir_all(&out).unwrap();
    let plain = args.iter().any(|a| a == "--plain");
    if plain || args.iter().any(|a| a == "--no-poses") {
        cloud.viewpoints = Viewpoints::None;
        cloud.scan.clear();
        cloud.scan_ids.clear();
    }
    // Plain x, y, z: no times either, so no path can be estimated.
    if plain {
        cloud.time.clear();
    }
    let mut params = Params::default();
    while let Some(i) = args.iter().position(|a| a == "--param") {
        params.set(&args[i + 1]).expect("a parameter");
        args.drain(i..i + 2);
    }
    let plan = asbuilt_plan::plan(&cloud, &params, &mut asbuilt_plan::progress::NoProgress);
    match &plan {
        Ok(plan) => {
            eprintln!("notes: {:?}", plan.notes);
            eprintln!("parameters: {}", plan.parameters["samples"]);
        }
        Err(e) => eprintln!("plan failed: {e}"),
    }
    let view: Option<[f64; 4]> = args.iter().position(|a| a == "--view").map(|i| {
        let v: Vec<f64> = args[i + 1].split(',').map(|x| x.parse().unwrap()).collect();
        [v[0], v[1], v[2], v[3]]
    });
    let z: Vec<f32> = cloud.xyz.iter().map(|p| p[2]).collect();
    let stories = split_stories(&z, &params.stories).unwrap();
    let story = &stories[level];
    let truth: Vec<Vec<P2>> = truth_stories.as_ref().map_or(Vec::new(), |t| {
        t[level]
            .polygons
            .iter()
            .flat_map(|p| std::iter::once(p.exterior.clone()).chain(p.holes.clone()))
            .collect()
    });
    let mut png = Raster::new(&cloud, story, view);
    let (lo, hi): (f64, f64) = (
        story.floor_z + 0.35 * (story.top_z - story.floor_z),
        story.floor_z + 0.65 * (story.top_z - story.floor_z),
    );
    for p in &cloud.xyz {
        if (lo..hi).contains(&(p[2] as f64)) {
            png.dot([p[0] as f64, p[1] as f64], 1, [120, 120, 120]);
        }
    }
    if let Ok(plan) = &plan {
        if let Some(s) = plan.stories.iter().find(|s| s.level == level) {
            for p in &s.samples {
                png.dot(*p, 2, [40, 90, 220]);
            }
            for poly in &s.polygons {
                for ring in std::iter::once(&poly.exterior).chain(&poly.holes) {
                    png.ring(ring, [0, 0, 0]);
                }
            }
        }
    }
    for ring in &truth {
        png.ring(ring, [220, 30, 30]);
    }
    if let Viewpoints::Static(poses) = &cloud.viewpoints {
        for p in poses
            .iter()
            .filter(|p| story.holds_viewpoint(p.position[2]))
        {
            png.dot([p.position[0], p.position[1]], 4, [255, 140, 0]);
        }
    }
    std::fs::write(out.join("plan.png"), png.encode()).unwrap();
    if let Ok(plan) = &plan {
        if let Some(s) = plan.stories.iter().find(|s| s.level == level) {
            let mut r = Raster::new(&cloud, story, view);
            draw_rooms(&mut r, &cloud, s, (lo, hi), &truth);
            std::fs::write(out.join("rooms.png"), r.encode()).unwrap();
            for room in &s.spaces.rooms {
                eprintln!(
                    "{} area {:.2} m² perimeter {:.2} m scanners {:?} neighbours {:?}",
                    room.id, room.area, room.perimeter, room.scanners, room.neighbours
                );
            }
            for d in &s.spaces.doors {
                eprintln!(
                    "{} {:?} width {:.3} depth {:.3} head {:?} rooms {:?} at [{:.2}, {:.2}] -> [{:.2}, {:.2}]",
                    d.id, d.kind, d.width, d.depth, d.head_z, d.rooms, d.a[0], d.a[1], d.b[0], d.b[1]
                );
            }
            for w in s.spaces.walls.iter().filter(|w| !w.exterior) {
                eprintln!(
                    "{} thickness {:.3} {:?} -> {:?} rooms {:?}",
                    w.id, w.thickness, w.a, w.b, w.rooms
                );
            }
            for w in &s.spaces.windows {
                eprintln!(
                    "{} width {:.2} sill {:.2} head {:.2} room {:?}",
                    w.id, w.width, w.sill_z, w.head_z, w.room
                );
            }
        }
    }
    // The stages below run with the parameters the plan derived from the point spacing.
    let (params, _) = params.derive(SpacingProbe::of(&cloud.xyz).spacing());
    // Scanners the cloud does not give are estimated as the plan does: from scan ids or times,
    // else pseudo-viewpoints in the open space the samples enclose.
    // (An estimated mobile path is set aside for pseudo-viewpoints, as the plan does.)
    let estimated = asbuilt_plan::viewpoints::estimate(&cloud, &params.viewpoints).viewpoints;
    match &estimated {
        Some(Viewpoints::Trajectory(_)) if params.viewpoints.open_space => {}
        Some(v) => cloud.viewpoints = v.clone(),
        None => {}
    }
    let mut samples = sample_walls(&cloud, story, &params.samples, &Cancel::never()).unwrap();
    if matches!(cloud.viewpoints, Viewpoints::None) && params.viewpoints.open_space {
        asbuilt_plan::viewpoints::place_open_space(
            &cloud,
            story,
            &mut samples,
            &params.viewpoints,
            params.samples.max_range,
        );
    }
    smooth_samples(
        &mut samples,
        params.samples.cell_size,
        &params.smoothing,
        &Cancel::never(),
    )
    .unwrap();
    let mut labeled = label(&samples, &params.labeling, &Cancel::never()).unwrap();
    let poses = samples.viewpoints.clone();
    std::fs::write(
        out.join("labels.svg"),
        draw(&labeled, &[], &truth, &poses, view),
    )
    .unwrap();
    let mut raster = Raster::new(&cloud, story, view);
    raster.labels(&labeled, &truth);
    std::fs::write(out.join("labels.png"), raster.encode()).unwrap();
    let report = clean_labels(&mut labeled, &params.cleanup);
    let mut raster = Raster::new(&cloud, story, view);
    raster.labels(&labeled, &truth);
    std::fs::write(out.join("cleaned.png"), raster.encode()).unwrap();
    eprintln!("cleanup: {report:?}");
    std::fs::write(
        out.join("cleaned.svg"),
        draw(&labeled, &[], &truth, &poses, view),
    )
    .unwrap();
    let boundary = trace_boundary(&labeled).unwrap();
    let fitted = fit_walls(&labeled, &boundary, &params.fitting, &Cancel::never()).unwrap();
    if let Some(v) = view {
        let within = |p: &P2| p[0] >= v[0] && p[0] <= v[2] && p[1] >= v[1] && p[1] <= v[3];
        for w in fitted.walls.iter().filter(|w| w.points.iter().any(within)) {
            eprintln!("wall {:?} support {} {:?}", w.model, w.support, w.points);
        }
        eprintln!("fitting notes: {:?}", fitted.notes);
    }
    let rings: Vec<Vec<P2>> = fitted
        .polygons
        .iter()
        .flat_map(|p| std::iter::once(p.exterior.clone()).chain(p.holes.clone()))
        .collect();
    // The traced boundary in orange and the fitted rings in black, over the cleaned labels.
    for poly in &boundary.polygons {
        for ring in std::iter::once(&poly.exterior).chain(&poly.holes) {
            let pts: Vec<P2> = ring
                .vertices
                .iter()
                .map(|&v| labeled.mesh.vertices[v as usize])
                .collect();
            raster.ring(&pts, [255, 140, 0]);
        }
    }
    for ring in &rings {
        raster.ring(ring, [0, 0, 0]);
    }
    std::fs::write(out.join("fitted.png"), raster.encode()).unwrap();
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

/// The rooms filled and labelled over the point slice `band`, with doors, windows and walls.
fn draw_rooms(
    r: &mut Raster,
    cloud: &asbuilt_plan::cloud::PointCloud,
    s: &asbuilt_plan::plan::StoryPlan,
    band: (f64, f64),
    truth: &[Vec<P2>],
) {
    let palette = [
        [255, 224, 178],
        [200, 230, 201],
        [187, 222, 251],
        [248, 187, 208],
        [225, 190, 231],
        [255, 245, 157],
        [178, 235, 242],
        [215, 204, 200],
    ];
    for (k, room) in s.spaces.rooms.iter().enumerate() {
        let mut rings = vec![room.polygon.exterior.clone()];
        rings.extend(room.polygon.holes.iter().cloned());
        r.fill(&rings, palette[k % palette.len()]);
    }
    for p in &cloud.xyz {
        if (band.0..band.1).contains(&(p[2] as f64)) {
            r.dot([p[0] as f64, p[1] as f64], 0, [90, 90, 90]);
        }
    }
    for w in &s.spaces.walls {
        let c = if w.exterior {
            [170, 170, 170]
        } else {
            [60, 60, 60]
        };
        r.segment(w.a, w.b, 1, c);
    }
    for room in &s.spaces.rooms {
        for ring in std::iter::once(&room.polygon.exterior).chain(&room.polygon.holes) {
            r.ring(ring, [0, 0, 0]);
        }
    }
    for ring in truth {
        r.ring(ring, [220, 30, 30]);
    }
    for d in &s.spaces.doors {
        let c = match d.kind {
            asbuilt_plan::plan::DoorKind::Door => [0, 170, 0],
            asbuilt_plan::plan::DoorKind::Opening => [220, 0, 220],
        };
        r.segment(d.a, d.b, 4, c);
    }
    for w in &s.spaces.windows {
        r.segment(w.a, w.b, 4, [0, 190, 220]);
    }
    for room in &s.spaces.rooms {
        let ring = &room.polygon.exterior;
        // The label at the room's widest inner point along its middle scanline.
        let n = ring.len() as f64;
        let c = [
            ring.iter().map(|p| p[0]).sum::<f64>() / n,
            ring.iter().map(|p| p[1]).sum::<f64>() / n,
        ];
        let number = room.id.rsplit('R').next().unwrap_or("");
        r.text(c, &format!("R{number} {:.1}", room.area), [0, 0, 0]);
    }
}

/// An RGB picture of a story from above, 2400 pixels on its longer side.
struct Raster {
    lo: P2,
    hi: P2,
    scale: f64,
    w: usize,
    h: usize,
    rgb: Vec<u8>,
}

impl Raster {
    /// Spans the story's points (or `view`), with a margin.
    fn new(
        cloud: &asbuilt_plan::cloud::PointCloud,
        story: &asbuilt_plan::stories::Story,
        view: Option<[f64; 4]>,
    ) -> Raster {
        let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
        for p in &cloud.xyz {
            if (story.z_min..story.z_max).contains(&(p[2] as f64)) {
                for k in 0..2 {
                    lo[k] = lo[k].min(p[k] as f64 - 0.5);
                    hi[k] = hi[k].max(p[k] as f64 + 0.5);
                }
            }
        }
        if let Some(v) = view {
            (lo, hi) = ([v[0], v[1]], [v[2], v[3]]);
        }
        let scale = 2400.0 / (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let (w, h) = (
            ((hi[0] - lo[0]) * scale).ceil() as usize,
            ((hi[1] - lo[1]) * scale).ceil() as usize,
        );
        Raster {
            lo,
            hi,
            scale,
            w,
            h,
            rgb: vec![255; w * h * 3],
        }
    }

    fn pixel(&self, p: P2) -> (f64, f64) {
        (
            (p[0] - self.lo[0]) * self.scale,
            (self.hi[1] - p[1]) * self.scale,
        )
    }

    fn set(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.w && (y as usize) < self.h {
            let i = (y as usize * self.w + x as usize) * 3;
            self.rgb[i..i + 3].copy_from_slice(&c);
        }
    }

    /// A square dot of half-width `r` pixels.
    fn dot(&mut self, p: P2, r: i64, c: [u8; 3]) {
        let (x, y) = self.pixel(p);
        for dy in -r..=r {
            for dx in -r..=r {
                self.set(x as i64 + dx, y as i64 + dy, c);
            }
        }
    }

    /// A filled triangle.
    fn triangle(&mut self, t: [P2; 3], c: [u8; 3]) {
        let q = t.map(|p| self.pixel(p));
        let (x0, x1) = (
            q.iter().map(|p| p.0).fold(f64::MAX, f64::min),
            q.iter().map(|p| p.0).fold(f64::MIN, f64::max),
        );
        let (y0, y1) = (
            q.iter().map(|p| p.1).fold(f64::MAX, f64::min),
            q.iter().map(|p| p.1).fold(f64::MIN, f64::max),
        );
        let (x0, x1) = (x0.max(0.0) as i64, x1.min(self.w as f64) as i64);
        let (y0, y1) = (y0.max(0.0) as i64, y1.min(self.h as f64) as i64);
        let side = |a: (f64, f64), b: (f64, f64), p: (f64, f64)| {
            (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)
        };
        for y in y0..=y1 {
            for x in x0..=x1 {
                let p = (x as f64 + 0.5, y as f64 + 0.5);
                let s = [
                    side(q[0], q[1], p),
                    side(q[1], q[2], p),
                    side(q[2], q[0], p),
                ];
                if s.iter().all(|&v| v >= 0.0) || s.iter().all(|&v| v <= 0.0) {
                    self.set(x, y, c);
                }
            }
        }
    }

    /// The labeled mesh: inside light blue, forced inside dark blue, forced outside grey, with
    /// the samples in green and the truth in red.
    fn labels(&mut self, l: &LabeledMesh, truth: &[Vec<P2>]) {
        let m = &l.mesh;
        for (t, tri) in m.triangles.iter().enumerate() {
            let c = match (l.forced[t], l.inside[t]) {
                (Some(true), _) => [50, 100, 200],
                (Some(false), _) => [190, 190, 190],
                (None, true) => [170, 220, 255],
                (None, false) => [255, 255, 255],
            };
            self.triangle(tri.map(|v| m.vertices[v as usize]), c);
        }
        for ring in truth {
            self.ring(ring, [220, 30, 30]);
        }
        for p in &m.vertices[..m.n_samples] {
            self.dot(*p, 1, [0, 150, 0]);
        }
    }

    /// A segment, `w` pixels either side.
    fn segment(&mut self, a: P2, b: P2, w: i64, c: [u8; 3]) {
        let (a, b) = (self.pixel(a), self.pixel(b));
        let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
        for i in 0..=n {
            let f = i as f64 / n as f64;
            let (x, y) = (a.0 + f * (b.0 - a.0), a.1 + f * (b.1 - a.1));
            for dy in -w..=w {
                for dx in -w..=w {
                    self.set(x as i64 + dx, y as i64 + dy, c);
                }
            }
        }
    }

    /// Fills the region of `rings` (even-odd), pixel row by pixel row.
    fn fill(&mut self, rings: &[Vec<P2>], c: [u8; 3]) {
        let px: Vec<Vec<(f64, f64)>> = rings
            .iter()
            .map(|r| r.iter().map(|&p| self.pixel(p)).collect())
            .collect();
        for y in 0..self.h {
            let yc = y as f64 + 0.5;
            let mut xs = Vec::new();
            for r in &px {
                for k in 0..r.len() {
                    let (a, b) = (r[k], r[(k + 1) % r.len()]);
                    if (a.1 > yc) != (b.1 > yc) {
                        xs.push(a.0 + (yc - a.1) / (b.1 - a.1) * (b.0 - a.0));
                    }
                }
            }
            xs.sort_by(f64::total_cmp);
            for s in xs.chunks_exact(2) {
                for x in (s[0].max(0.0) as i64)..(s[1].min(self.w as f64) as i64) {
                    self.set(x, y as i64, c);
                }
            }
        }
    }

    /// Text in a 3 × 5 pixel font scaled 4 times, starting at `p`: digits, `R`, `.` and space.
    fn text(&mut self, p: P2, s: &str, c: [u8; 3]) {
        const GLYPHS: [(char, [u8; 5]); 13] = [
            ('0', [7, 5, 5, 5, 7]),
            ('1', [2, 6, 2, 2, 7]),
            ('2', [7, 1, 7, 4, 7]),
            ('3', [7, 1, 7, 1, 7]),
            ('4', [5, 5, 7, 1, 1]),
            ('5', [7, 4, 7, 1, 7]),
            ('6', [7, 4, 7, 5, 7]),
            ('7', [7, 1, 1, 1, 1]),
            ('8', [7, 5, 7, 5, 7]),
            ('9', [7, 5, 7, 1, 7]),
            ('R', [6, 5, 6, 5, 5]),
            ('.', [0, 0, 0, 0, 2]),
            (' ', [0, 0, 0, 0, 0]),
        ];
        let (x0, y0) = self.pixel(p);
        let k = 4i64;
        let width = s.chars().count() as i64 * 4 * k;
        let (x0, y0) = (x0 as i64 - width / 2, y0 as i64 - 5 * k / 2);
        for (i, ch) in s.chars().enumerate() {
            let Some((_, rows)) = GLYPHS.iter().find(|(g, _)| *g == ch) else {
                continue;
            };
            for (row, bits) in rows.iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        for dy in 0..k {
                            for dx in 0..k {
                                let x = x0 + (i as i64 * 4 + col) * k + dx;
                                self.set(x, y0 + row as i64 * k + dy, c);
                            }
                        }
                    }
                }
            }
        }
    }

    /// A closed ring, 3 pixels wide.
    fn ring(&mut self, ring: &[P2], c: [u8; 3]) {
        for k in 0..ring.len() {
            let (a, b) = (self.pixel(ring[k]), self.pixel(ring[(k + 1) % ring.len()]));
            let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
            for i in 0..=n {
                let f = i as f64 / n as f64;
                let (x, y) = (a.0 + f * (b.0 - a.0), a.1 + f * (b.1 - a.1));
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (-1, 0), (0, -1)] {
                    self.set(x as i64 + dx, y as i64 + dy, c);
                }
            }
        }
    }

    /// The picture as a PNG file: stored (uncompressed) deflate blocks, so that the example
    /// needs no image crate.
    fn encode(&self) -> Vec<u8> {
        let mut raw = Vec::with_capacity(self.h * (self.w * 3 + 1));
        for row in self.rgb.chunks(self.w * 3) {
            raw.push(0);
            raw.extend_from_slice(row);
        }
        let mut z = vec![0x78, 0x01];
        let mut blocks = raw.chunks(65_535).peekable();
        while let Some(b) = blocks.next() {
            z.push(u8::from(blocks.peek().is_none()));
            let len = b.len() as u16;
            z.extend_from_slice(&len.to_le_bytes());
            z.extend_from_slice(&(!len).to_le_bytes());
            z.extend_from_slice(b);
        }
        let (mut a, mut b) = (1u32, 0u32);
        for &x in &raw {
            a = (a + x as u32) % 65_521;
            b = (b + a) % 65_521;
        }
        z.extend_from_slice(&((b << 16) | a).to_be_bytes());
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        let mut ihdr = Vec::new();
        ihdr.extend_from_slice(&(self.w as u32).to_be_bytes());
        ihdr.extend_from_slice(&(self.h as u32).to_be_bytes());
        ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
        for (kind, data) in [(b"IHDR", ihdr), (b"IDAT", z), (b"IEND", Vec::new())] {
            png.extend_from_slice(&(data.len() as u32).to_be_bytes());
            let mut body = kind.to_vec();
            body.extend_from_slice(&data);
            png.extend_from_slice(&body);
            png.extend_from_slice(&crc32(&body).to_be_bytes());
        }
        png
    }
}

fn crc32(data: &[u8]) -> u32 {
    let mut crc = 0xffff_ffffu32;
    for &byte in data {
        crc ^= byte as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                0xedb8_8320 ^ (crc >> 1)
            } else {
                crc >> 1
            };
        }
    }
    !crc
}
