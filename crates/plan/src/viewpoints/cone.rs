//! Where a static scanner stood, from its own points: the blind cone under the tripod.
//!
//! A terrestrial scanner does not measure below some elevation (−45° to −70°), so each scan
//! leaves a round hole in its floor: the points of lowest elevation, one per azimuth sector,
//! all lie on one downward cone whose apex is the scanner. Seen from the apex, every sector's
//! lowest point has the same elevation; seen from anywhere else, they do not.
//!
//! 1. Candidates: the low points (the bottom quarter of the scan's heights) are rasterised;
//!    the maxima of the distance to the nearest low point are the centres of empty places.
//!    From each, rays in every direction stop at the first low point; a circle fits those stops
//!    well only around the blind spot (an empty place in a sparse far room or a shadow behind
//!    furniture has a ragged edge).
//! 2. The best few circles seed a robust Gauss-Newton fit of the cone
//!    `z = apex_z − slope · |xy − apex_xy|` to the lowest point of each sector (the apex height
//!    fixed half way up the scan), the sectors re-chosen around the new apex at every step. The apex with most sectors on its cone wins.

use nalgebra::{Matrix6, Vector6};

use super::raster::Raster;
use crate::geom::P2;

/// Parameters of the blind-cone search (the defaults suit tripod scanners indoors).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ConeParams {
    /// Azimuth sectors around a candidate apex.
    pub sectors: usize,
    /// Raster cell for the low points, metres.
    pub cell: f64,
    /// The blind spot's radius in the low points lies within this range, metres.
    pub radius: (f64, f64),
    /// Candidate circles whose cone is fitted.
    pub seeds: usize,
    /// A sector's lowest point is on the cone when this close to it (vertically), metres.
    pub tolerance: f64,
    /// Points farther than this from the apex are not looked at, metres.
    pub reach: f64,
}

impl Default for ConeParams {
    fn default() -> Self {
        ConeParams {
            sectors: 72,
            cell: 0.1,
            radius: (0.3, 4.0),
            seeds: 4,
            tolerance: 0.05,
            reach: 10.0,
        }
    }
}

/// A fitted blind cone.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Cone {
    /// The scanner: the cone's apex, local frame (for a moving scanner, at the window's
    /// reference time).
    pub apex: [f64; 3],
    /// A moving scanner's horizontal velocity, m per time unit; zero for a static scan.
    pub velocity: [f64; 2],
    /// tan of the lowest elevation's depression.
    pub slope: f64,
    /// Sectors whose lowest point lies on the cone, of `sectors`.
    pub support: usize,
    /// Root mean square horizontal distance of those points from the cone, metres.
    pub residual: f64,
}

/// The slope stays within these bounds: lowest elevations of −11° to −79°.
const SLOPE: (f64, f64) = (0.2, 5.0);
/// Below this many points a scan is not located.
pub(crate) const MIN_POINTS: usize = 200;
/// Fewer supporting sectors than this fraction is no blind cone.
const MIN_SUPPORT: f64 = 0.2;
/// A moving scanner's blind spot is sought among this share of a window's points, those
/// nearest its reference time.
const SEED_SHARE: usize = 8;
/// Rasters stay below this many cells.
const MAX_CELLS: usize = 1 << 21;

/// Locates the scanner of `points` (one static scan, local frame). `None` when the points show
/// no blind cone.
pub(crate) fn locate(points: &[[f32; 3]], params: &ConeParams) -> Option<Cone> {
    if points.len() < MIN_POINTS {
        return None;
    }
    let pts: Vec<[f64; 3]> = points.iter().map(|p| p.map(f64::from)).collect();
    let (zl, zh) = z_range(&pts)?;
    let span = zh - zl;
    let seeds = seed_circles(&pts, zl + 0.25 * span, params);
    let mut best: Option<Cone> = None;
    for (center, radius) in seeds {
        // Half way up: scanners stand about there, and any height within the story serves.
        let z0 = zl + 0.5 * span;
        let slope = ((z0 - zl) / radius).clamp(SLOPE.0, SLOPE.1);
        let height = (zl + 0.2 * span, zh - 0.05 * span);
        let start = Cone::at([center[0], center[1], z0], slope);
        for h in [None, Some(height)] {
            let fitted = fit_cone(
                &Obs {
                    pts: &pts,
                    dt: None,
                },
                start,
                h,
                params,
            );
            best = better(best, fitted);
        }
    }
    best.filter(|c| c.support as f64 >= MIN_SUPPORT * params.sectors as f64)
}

/// Locates a moving scanner over one short time window: the points with their `times`, the
/// scanner taken to move in a straight line at a steady speed. The result's apex is where it
/// was at `t_ref`. `seed` (say, the last window's answer moved on to `t_ref`) is tried first;
/// the empty places of [`locate`] are tried when it fails.
pub(crate) fn locate_moving(
    points: &[[f32; 3]],
    times: &[f64],
    t_ref: f64,
    seed: Option<Cone>,
    params: &ConeParams,
) -> Option<Cone> {
    if points.len() < MIN_POINTS || points.len() != times.len() {
        return None;
    }
    let pts: Vec<[f64; 3]> = points.iter().map(|p| p.map(f64::from)).collect();
    let dt: Vec<f64> = times.iter().map(|t| t - t_ref).collect();
    let obs = Obs {
        pts: &pts,
        dt: Some(&dt),
    };
    let enough = |c: &Cone| c.support as f64 >= MIN_SUPPORT * params.sectors as f64;
    if let Some(s) = seed {
        let fitted = fit_cone(&obs, s, None, params).filter(enough);
        if fitted.is_some() {
            return fitted;
        }
    }
    let (zl, zh) = z_range(&pts)?;
    let span = zh - zl;
    let z0 = seed.map_or(zl + 0.5 * span, |s| s.apex[2]);
    let mut best = None;
    // Over the whole window the moving scanner saw the floor under most of its path; only the
    // points of a short time around `t_ref` leave its blind spot empty. Their empty places
    // seed the fit.
    let mut near: Vec<usize> = (0..pts.len()).collect();
    near.sort_by(|&a, &b| dt[a].abs().total_cmp(&dt[b].abs()));
    near.truncate((pts.len() / SEED_SHARE).max(MIN_POINTS));
    let middle: Vec<[f64; 3]> = near.iter().map(|&i| pts[i]).collect();
    let seeds = seed_circles(&middle, zl + 0.25 * span, params);
    for (center, radius) in seeds {
        let slope = ((z0 - zl) / radius).clamp(SLOPE.0, SLOPE.1);
        best = better(
            best,
            fit_cone(
                &obs,
                Cone::at([center[0], center[1], z0], slope),
                None,
                params,
            ),
        );
    }
    best.filter(enough)
}

/// The better of two fits: more sectors on the cone, then the smaller residual.
fn better(best: Option<Cone>, new: Option<Cone>) -> Option<Cone> {
    match (best, new) {
        (Some(b), Some(n)) => {
            let wins = n.support > b.support || (n.support == b.support && n.residual < b.residual);
            Some(if wins { n } else { b })
        }
        (b, n) => b.or(n),
    }
}

impl Cone {
    /// A starting guess: a static apex and a slope.
    fn at(apex: [f64; 3], slope: f64) -> Cone {
        Cone {
            apex,
            velocity: [0.0; 2],
            slope,
            support: 0,
            residual: 0.0,
        }
    }

    /// Where the scanner was `dt` after the reference time.
    pub fn position(&self, dt: f64) -> [f64; 3] {
        [
            self.apex[0] + self.velocity[0] * dt,
            self.apex[1] + self.velocity[1] * dt,
            self.apex[2],
        ]
    }
}

/// The points a cone is fitted to, with their times after the reference time when the scanner
/// moves.
struct Obs<'a> {
    pts: &'a [[f64; 3]],
    dt: Option<&'a [f64]>,
}

impl Obs<'_> {
    fn dt(&self, i: usize) -> f64 {
        self.dt.map_or(0.0, |d| d[i])
    }
}

/// The 1st and 99th percentiles of the heights.
fn z_range(pts: &[[f64; 3]]) -> Option<(f64, f64)> {
    let mut z: Vec<f64> = pts.iter().map(|p| p[2]).collect();
    let n = z.len();
    let lo = *z.select_nth_unstable_by(n / 100, f64::total_cmp).1;
    let hi = *z.select_nth_unstable_by(n - 1 - n / 100, f64::total_cmp).1;
    (hi > lo).then_some((lo, hi))
}

/// Empty places among the points below `z_low`, as circles `(centre, radius)` fitted to where
/// rays from each place stop, best first.
fn seed_circles(pts: &[[f64; 3]], z_low: f64, params: &ConeParams) -> Vec<(P2, f64)> {
    let low = pts.iter().filter(|p| p[2] < z_low).map(|p| [p[0], p[1]]);
    let Some(raster) = Raster::of_points(low, params.cell, params.radius.1, MAX_CELLS) else {
        return Vec::new();
    };
    let dist = raster.distance();
    let (r_min, r_max) = params.radius;
    let mut found: Vec<(usize, f64, P2, f64)> = Vec::new();
    for j in 1..raster.ny.saturating_sub(1) {
        for i in 1..raster.nx.saturating_sub(1) {
            let d = dist[j * raster.nx + i];
            if !(d >= r_min && d <= r_max) {
                continue;
            }
            // A local maximum of the distance: the centre of an empty place.
            let peak = (0..9).all(|k| {
                let (a, b) = (i + k % 3 - 1, j + k / 3 - 1);
                dist[b * raster.nx + a] <= d
            });
            if !peak {
                continue;
            }
            if let Some((c, r, n)) = ray_circle(&raster, raster.center(i, j), params) {
                found.push((n, -r, c, r));
            }
        }
    }
    // Most rays on the circle first; several peaks of one hole give the same circle.
    found.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.total_cmp(&b.1)));
    let mut out: Vec<(P2, f64)> = Vec::new();
    for (_, _, c, r) in found {
        if out
            .iter()
            .all(|(o, _)| crate::geom::dist(*o, c) > 2.0 * params.cell)
        {
            out.push((c, r));
            if out.len() == params.seeds {
                break;
            }
        }
    }
    out
}

/// Rays from `from` in every sector direction; the circle through their first hits, with the
/// number of hits on it. `None` when too few rays hit or the circle does not contain `from`.
fn ray_circle(raster: &Raster, from: P2, params: &ConeParams) -> Option<(P2, f64, usize)> {
    let n = params.sectors;
    let hits: Vec<P2> = (0..n)
        .filter_map(|k| {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            let dir = [a.cos(), a.sin()];
            let t = raster.first_hit(from, dir, 2.0 * params.radius.1)?;
            Some([from[0] + t * dir[0], from[1] + t * dir[1]])
        })
        .collect();
    if (hits.len() as f64) < MIN_SUPPORT * n as f64 {
        return None;
    }
    let tol = 1.5 * raster.cell;
    let (mut c, mut r) = fit_circle(&hits)?;
    for _ in 0..3 {
        let near: Vec<P2> = hits
            .iter()
            .copied()
            .filter(|p| (crate::geom::dist(*p, c) - r).abs() <= tol)
            .collect();
        if near.len() < 3 {
            return None;
        }
        (c, r) = fit_circle(&near)?;
    }
    let on = hits
        .iter()
        .filter(|p| (crate::geom::dist(**p, c) - r).abs() <= tol)
        .count();
    let inside = crate::geom::dist(from, c) < r;
    (inside && r >= params.radius.0 && r <= params.radius.1).then_some((c, r, on))
}

/// The least-squares (Kåsa) circle through `pts`: centre and radius.
pub(crate) fn fit_circle(pts: &[P2]) -> Option<(P2, f64)> {
    if pts.len() < 3 {
        return None;
    }
    // Centred on the mean for conditioning.
    let n = pts.len() as f64;
    let m = [
        pts.iter().map(|p| p[0]).sum::<f64>() / n,
        pts.iter().map(|p| p[1]).sum::<f64>() / n,
    ];
    let (mut sxx, mut sxy, mut syy, mut sxz, mut syz, mut sz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for p in pts {
        let (x, y) = (p[0] - m[0], p[1] - m[1]);
        let z = x * x + y * y;
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
        sxz += x * z;
        syz += y * z;
        sz += z;
    }
    // Solve [sxx sxy; sxy syy] [a; b] = [sxz; syz] / 2 for the centre offset (a, b).
    let det = sxx * syy - sxy * sxy;
    if det.is_nan() || det.abs() <= 1e-12 * (sxx * syy).max(1e-30) {
        return None;
    }
    let a = (sxz * syy - syz * sxy) / (2.0 * det);
    let b = (syz * sxx - sxz * sxy) / (2.0 * det);
    let r2 = a * a + b * b + sz / n;
    (r2 > 0.0 && r2.is_finite()).then(|| ([m[0] + a, m[1] + b], r2.sqrt()))
}

/// Points whose elevation and sector are worked out together before any sector is updated:
/// without the updates' branches in it, that loop runs on both lanes of the vector unit (the
/// square root and divisions are most of its time, and round the same either way).
const LANES: usize = 64;

/// A static scan's points in patches: sorted by a grid of [`PATCH`] cells, then cut into
/// chunks of [`LANES`], each with its horizontal box and lowest height. A fit looks for every
/// sector's lowest point some 40 times, and most chunks (floor beyond the blind spot, anything
/// above the scanner) hold none: from its box alone a chunk is seen to lie above the lowest
/// point found so far in every sector it may reach, and is passed over.
struct Patches {
    /// The points, sorted, and each one's index among the scan's.
    pts: Vec<[f64; 3]>,
    index: Vec<usize>,
    boxes: Vec<ChunkBox>,
}

/// The patches' grid cell, metres.
const PATCH: f64 = 0.25;

impl Patches {
    fn of(pts: &[[f64; 3]]) -> Patches {
        // Counting-sorted by cell, row by row; within a cell the points keep the scan's order.
        // The cells widen where the scan spans far more of them than it has points.
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in pts {
            lo = [lo[0].min(p[0]), lo[1].min(p[1])];
            hi = [hi[0].max(p[0]), hi[1].max(p[1])];
        }
        let mut cell = PATCH;
        let cells = |cell: f64| {
            let span = |k: usize| ((hi[k] - lo[k]) / cell).min(1e9) as usize + 1;
            (span(0), span(1))
        };
        while cells(cell).0.saturating_mul(cells(cell).1) > 4 * pts.len() + 16 {
            cell *= 2.0;
        }
        let (nx, ny) = cells(cell);
        let key = |p: &[f64; 3]| {
            let i = (((p[0] - lo[0]) / cell) as usize).min(nx - 1);
            let j = (((p[1] - lo[1]) / cell) as usize).min(ny - 1);
            j * nx + i
        };
        let keys: Vec<usize> = pts.iter().map(key).collect();
        let mut start = vec![0usize; nx * ny + 1];
        for &k in &keys {
            start[k + 1] += 1;
        }
        for k in 0..nx * ny {
            start[k + 1] += start[k];
        }
        let mut index = vec![0usize; pts.len()];
        for (i, &k) in keys.iter().enumerate() {
            index[start[k]] = i;
            start[k] += 1;
        }
        let pts: Vec<[f64; 3]> = index.iter().map(|&i| pts[i]).collect();
        let boxes = pts
            .chunks(LANES)
            .map(|chunk| {
                let mut b = ChunkBox {
                    lo: [f64::INFINITY; 2],
                    hi: [f64::NEG_INFINITY; 2],
                    zmin: f64::INFINITY,
                };
                for p in chunk {
                    b.lo = [b.lo[0].min(p[0]), b.lo[1].min(p[1])];
                    b.hi = [b.hi[0].max(p[0]), b.hi[1].max(p[1])];
                    b.zmin = b.zmin.min(p[2]);
                }
                b
            })
            .collect();
        Patches { pts, index, boxes }
    }
}

/// A chunk's horizontal box and lowest height.
#[derive(Debug, Clone, Copy)]
struct ChunkBox {
    lo: [f64; 2],
    hi: [f64; 2],
    zmin: f64,
}

/// Bounds are loosened by this much against rounding (relative).
const LOOSE: f64 = 1e-9;

impl ChunkBox {
    /// Whether no point of the chunk can be the lowest of its sector seen from `c`, given the
    /// lowest elevations found so far, `best` (which only fall): every point lies strictly
    /// above the lowest found in each sector the box may reach. Ties are never passed over.
    fn above(&self, c: [f64; 3], best: &[Option<(f64, usize)>], sectors: f64) -> bool {
        let dz = self.zmin - c[2];
        // Subtraction rounds monotonically: no point of the chunk is below the apex.
        if dz >= 0.0 {
            return true;
        }
        let gx = (self.lo[0] - c[0]).max(c[0] - self.hi[0]).max(0.0);
        let gy = (self.lo[1] - c[1]).max(c[1] - self.hi[1]).max(0.0);
        let gap = (gx * gx + gy * gy).sqrt() * (1.0 - LOOSE);
        // Near the apex (or around it) the box reaches every sector and bounds no elevation.
        if gap <= 0.05 {
            return false;
        }
        // The most negative elevation any point of the chunk can have.
        let lowest = dz / gap;
        // Seen from outside, a box spans less than half a turn, from one corner to another.
        let corners = [
            [self.lo[0], self.lo[1]],
            [self.hi[0], self.lo[1]],
            [self.lo[0], self.hi[1]],
            [self.hi[0], self.hi[1]],
        ]
        .map(|q| diamond_angle(q[0] - c[0], q[1] - c[1]));
        let (mut from, mut to) = (0.0f64, 0.0f64);
        for a in &corners[1..] {
            // The turn from the first corner, into (-2, 2].
            let mut t = a - corners[0];
            if t > 2.0 {
                t -= 4.0;
            } else if t <= -2.0 {
                t += 4.0;
            }
            from = from.min(t);
            to = to.max(t);
        }
        let n = best.len() as i64;
        let first = ((corners[0] + from) / 4.0 * sectors - LOOSE).floor() as i64;
        let last = ((corners[0] + to) / 4.0 * sectors + LOOSE).floor() as i64;
        (first..=last).all(|k| {
            best[k.rem_euclid(n) as usize].is_some_and(|(b, _)| lowest > b + LOOSE * b.abs())
        })
    }
}

/// For each sector around the scanner (where it was when each point was taken), the index of
/// the point below it with the lowest elevation; of several as low, the first. With `skip`
/// (`obs`'s points in patches; a static scan only), the points `seeds` (say, the last apex's
/// lowest) are looked at first, then the patches' chunks but those their boxes show to hold
/// no sector's lowest: the same points are found.
fn lowest_per_sector(
    obs: &Obs,
    cone: &Cone,
    params: &ConeParams,
    skip: Option<(&Patches, &[usize])>,
) -> Vec<usize> {
    let n = params.sectors;
    let mut best: Vec<Option<(f64, usize)>> = vec![None; n];
    let reach2 = params.reach * params.reach;
    let look = |p: &[f64; 3], c: [f64; 3]| -> (bool, f64, f64) {
        let (dx, dy, dz) = (p[0] - c[0], p[1] - c[1], p[2] - c[2]);
        let d2 = dx * dx + dy * dy;
        (
            !(dz >= 0.0 || d2 < 1e-4 || d2 > reach2),
            // tan of the elevation: the most negative is the lowest.
            dz / d2.sqrt(),
            diamond_angle(dx, dy) / 4.0 * n as f64,
        )
    };
    // Lower, or as low and earlier: the points may come out of order.
    let offer = |best: &mut [Option<(f64, usize)>], e: f64, sector: f64, i: usize| {
        let k = (sector as usize).min(n - 1);
        if best[k].is_none_or(|(b, j)| e < b || (e == b && i < j)) {
            best[k] = Some((e, i));
        }
    };
    // Where a static scanner stands, for every point.
    let apex = cone.position(0.0);
    if let Some((_, seeds)) = skip {
        for &i in seeds {
            if let (true, e, sector) = look(&obs.pts[i], apex) {
                offer(&mut best, e, sector, i);
            }
        }
    }
    let (mut elev, mut sector, mut seen) = ([0.0f64; LANES], [0.0f64; LANES], [false; LANES]);
    let (pts, index) = match skip {
        Some((patches, _)) => (&patches.pts[..], Some(&patches.index[..])),
        None => (obs.pts, None),
    };
    for (c, chunk) in pts.chunks(LANES).enumerate() {
        if let Some((patches, _)) = skip {
            if patches.boxes[c].above(apex, &best, n as f64) {
                continue;
            }
        }
        let first = c * LANES;
        let (elev, sector, seen) = (
            &mut elev[..chunk.len()],
            &mut sector[..chunk.len()],
            &mut seen[..chunk.len()],
        );
        let mut at = |j: usize, p: &[f64; 3], c: [f64; 3]| {
            (seen[j], elev[j], sector[j]) = look(p, c);
        };
        match obs.dt {
            // A static scanner stands in one place for every point.
            None => chunk.iter().enumerate().for_each(|(j, p)| at(j, p, apex)),
            // Indexed, not zipped: every point of the chunk gets its look.
            Some(dt) => chunk
                .iter()
                .enumerate()
                .for_each(|(j, p)| at(j, p, cone.position(dt[first + j]))),
        }
        for j in 0..chunk.len() {
            if seen[j] {
                let i = index.map_or(first + j, |index| index[first + j]);
                offer(&mut best, elev[j], sector[j], i);
            }
        }
    }
    best.into_iter().flatten().map(|(_, i)| i).collect()
}

/// A cheap stand-in for the angle of `(dx, dy)`: monotonic in it, from 0 to 4 for a full turn
/// (the sectors it makes are within a factor 1.5 of equal, which the fit does not mind).
/// Without branches, so that [`lowest_per_sector`]'s loop needs none.
fn diamond_angle(dx: f64, dy: f64) -> f64 {
    let s = dx.abs() + dy.abs();
    let (east, north) = (dx >= 0.0, dy >= 0.0);
    // The first and third quadrants measure dy, the others dx; the second and third count
    // down from their ends.
    let q = if east == north { dy } else { dx } / s;
    let base = match (east, north) {
        (true, true) => 0.0,
        (false, true) => 1.0,
        (false, false) => 2.0,
        (true, false) => 3.0,
    };
    let a = base + if east { q } else { -q };
    if s == 0.0 {
        0.0
    } else {
        a
    }
}

/// Fits the blind cone from `start`: damped Gauss-Newton on the sectors' lowest points,
/// outliers weighted out, for the apex's x, y and the slope; the velocity too when the points
/// carry times; and the apex height when `height` gives its bounds. With only the floor in
/// view, height and slope trade off (the blind spot's radius is height / slope) and a free
/// height drifts; with walls close by, only the right height puts their lowest points on the
/// cone.
fn fit_cone(
    obs: &Obs,
    start: Cone,
    height: Option<(f64, f64)>,
    params: &ConeParams,
) -> Option<Cone> {
    // Unknowns: x, y, slope, height, vx, vy.
    let free = [
        true,
        true,
        true,
        height.is_some(),
        obs.dt.is_some(),
        obs.dt.is_some(),
    ];
    // Only points below the apex can be a sector's lowest, and the apex never rises above
    // `height`'s top (or its start, when the height is fixed): the rest are dropped once
    // here rather than skipped on every iteration. The order is kept, so the fit is the same.
    let top = height.map_or(start.apex[2], |h| h.1.max(start.apex[2]));
    let keep: Vec<usize> = (0..obs.pts.len())
        .filter(|&i| obs.pts[i][2] < top)
        .collect();
    let kept_pts: Vec<[f64; 3]> = keep.iter().map(|&i| obs.pts[i]).collect();
    let kept_dt: Option<Vec<f64>> = obs.dt.map(|d| keep.iter().map(|&i| d[i]).collect());
    let obs = &Obs {
        pts: &kept_pts,
        dt: kept_dt.as_deref(),
    };
    let mut cone = start;
    // A static scan's points are looked at in patches, passed over where their boxes show no
    // lowest point, the last step's lowest points first; a moving scan's apex differs from
    // point to point.
    let patches = obs.dt.is_none().then(|| Patches::of(obs.pts));
    let mut last: Vec<usize> = Vec::new();
    let mut lowest = |cone: &Cone| -> Vec<usize> {
        let b = lowest_per_sector(obs, cone, params, patches.as_ref().map(|p| (p, &last[..])));
        last.clone_from(&b);
        b
    };
    let residuals = |cone: &Cone, b: &[usize]| -> Vec<(f64, Vector6<f64>)> {
        let t = cone.slope;
        b.iter()
            .map(|&i| {
                let (p, dt) = (obs.pts[i], obs.dt(i));
                let c = cone.position(dt);
                let (dx, dy) = (c[0] - p[0], c[1] - p[1]);
                let d = (dx * dx + dy * dy).sqrt().max(1e-9);
                let u = [dx / d, dy / d];
                let j = Vector6::new(t * u[0], t * u[1], d, -1.0, t * u[0] * dt, t * u[1] * dt);
                (p[2] - c[2] + t * d, j)
            })
            .collect()
    };
    for _ in 0..40 {
        let b = lowest(&cone);
        if b.len() < 8 {
            return None;
        }
        let r = residuals(&cone, &b);
        let mut abs: Vec<f64> = r.iter().map(|x| x.0.abs()).collect();
        let mid = abs.len() / 2;
        let mad = *abs.select_nth_unstable_by(mid, f64::total_cmp).1;
        let cut = (3.0 * 1.4826 * mad).max(params.tolerance / 2.0) + 0.01;
        let (mut a, mut g) = (Matrix6::<f64>::zeros(), Vector6::<f64>::zeros());
        for (res, j) in &r {
            if res.abs() <= cut {
                a += j * j.transpose();
                g += j * *res;
            }
        }
        for k in 0..6 {
            if free[k] {
                a[(k, k)] = a[(k, k)] * (1.0 + 1e-2) + 1e-9;
            } else {
                // A fixed unknown: its row and column say "no step".
                a.row_mut(k).fill(0.0);
                a.column_mut(k).fill(0.0);
                a[(k, k)] = 1.0;
                g[k] = 0.0;
            }
        }
        let step = a.lu().solve(&(-g))?;
        let (sx, sy) = (step[0].clamp(-0.3, 0.3), step[1].clamp(-0.3, 0.3));
        let z = match height {
            Some((lo, hi)) => (cone.apex[2] + step[3]).clamp(lo, hi),
            None => cone.apex[2],
        };
        cone.apex = [cone.apex[0] + sx, cone.apex[1] + sy, z];
        cone.slope = (cone.slope + step[2]).clamp(SLOPE.0, SLOPE.1);
        cone.velocity = [
            cone.velocity[0] + step[4].clamp(-0.5, 0.5),
            cone.velocity[1] + step[5].clamp(-0.5, 0.5),
        ];
        if !(cone
            .apex
            .iter()
            .chain(&cone.velocity)
            .all(|c| c.is_finite()))
        {
            return None;
        }
        if sx.abs().max(sy.abs()) < 1e-4 && step[4].abs().max(step[5].abs()) < 1e-3 {
            break;
        }
    }
    let b = lowest(&cone);
    let on: Vec<f64> = residuals(&cone, &b)
        .into_iter()
        .map(|x| x.0)
        .filter(|r| r.abs() <= params.tolerance)
        .collect();
    if on.is_empty() {
        return None;
    }
    let rms = (on.iter().map(|r| r * r).sum::<f64>() / on.len() as f64).sqrt();
    cone.support = on.len();
    cone.residual = rms / cone.slope;
    Some(cone)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A square room 8 × 6 m, 3 m high, scanned from `at` (height 1.5 m) with a blind cone
    /// below `min_elev` degrees: points on a regular grid of directions.
    pub(crate) fn scan_room(at: P2, min_elev: f64) -> Vec<[f32; 3]> {
        let (w, h, top) = (8.0, 6.0, 3.0);
        let o = [at[0], at[1], 1.5];
        let mut out = Vec::new();
        for ia in 0..360 {
            let az = (ia as f64 + 0.5).to_radians();
            for ie in 0..150 {
                let el = (min_elev + (89.0 - min_elev) * ie as f64 / 149.0).to_radians();
                let d = [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()];
                let mut t = f64::INFINITY;
                for (k, lo, hi) in [(0, 0.0, w), (1, 0.0, h), (2, 0.0, top)] {
                    if d[k] > 0.0 {
                        t = t.min((hi - o[k]) / d[k]);
                    } else if d[k] < 0.0 {
                        t = t.min((lo - o[k]) / d[k]);
                    }
                }
                out.push([0, 1, 2].map(|k| (o[k] + t * d[k]) as f32));
            }
        }
        out
    }

    /// The angle as first written, with a branch per quadrant.
    fn diamond_angle_branching(dx: f64, dy: f64) -> f64 {
        let s = dx.abs() + dy.abs();
        if s == 0.0 {
            return 0.0;
        }
        match (dx >= 0.0, dy >= 0.0) {
            (true, true) => dy / s,
            (false, true) => 1.0 - dx / s,
            (false, false) => 2.0 - dy / s,
            (true, false) => 3.0 + dx / s,
        }
    }

    /// The sectors' lowest points as first written: one point at a time, a branch each.
    fn lowest_one_by_one(obs: &Obs, cone: &Cone, params: &ConeParams) -> Vec<usize> {
        let n = params.sectors;
        let mut best: Vec<Option<(f64, usize)>> = vec![None; n];
        let reach2 = params.reach * params.reach;
        for (i, p) in obs.pts.iter().enumerate() {
            let c = cone.position(obs.dt(i));
            let (dx, dy, dz) = (p[0] - c[0], p[1] - c[1], p[2] - c[2]);
            let d2 = dx * dx + dy * dy;
            if dz >= 0.0 || d2 < 1e-4 || d2 > reach2 {
                continue;
            }
            let e = dz / d2.sqrt();
            let k = ((diamond_angle_branching(dx, dy) / 4.0 * n as f64) as usize).min(n - 1);
            if best[k].is_none_or(|(b, _)| e < b) {
                best[k] = Some((e, i));
            }
        }
        best.into_iter().flatten().map(|(_, i)| i).collect()
    }

    #[test]
    fn the_sectors_lowest_points_are_those_of_one_point_at_a_time() {
        // A pseudo-random cloud around the apex, with exact repeats (ties) and points above,
        // beside and beyond the reach; static and moving.
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut pts: Vec<[f64; 3]> = (0..5000)
            .map(|_| [next() * 24.0 - 12.0, next() * 24.0 - 12.0, next() * 3.0])
            .collect();
        pts.extend(pts[..300].to_vec());
        pts.push([0.0, 0.0, 0.0]);
        let dt: Vec<f64> = (0..pts.len()).map(|_| next() * 2.0 - 1.0).collect();
        let params = ConeParams::default();
        for (apex, velocity) in [
            ([0.0, 0.0, 1.5], [0.0, 0.0]),
            ([0.3, -2.0, 2.0], [0.0, 0.0]),
            ([0.3, -2.0, 2.0], [0.4, -0.2]),
        ] {
            let cone = Cone {
                velocity,
                ..Cone::at(apex, 1.0)
            };
            for dt in [None, Some(&dt[..])] {
                let obs = Obs { pts: &pts, dt };
                let got = lowest_per_sector(&obs, &cone, &params, None);
                assert!(got.len() > 60, "{}", got.len());
                assert_eq!(got, lowest_one_by_one(&obs, &cone, &params));
            }
        }
    }

    #[test]
    fn patches_passed_over_change_no_sector_s_lowest_point() {
        // A scan of a room with its blind spot, and the same points shuffled in with exact
        // repeats (ties) and a second floor below; apexes around the scanner and far off it,
        // with the seeds a step's lowest points would be, none, or arbitrary points.
        let mut pts: Vec<[f64; 3]> = scan_room([3.0, 2.5], -55.0)
            .iter()
            .map(|p| p.map(f64::from))
            .collect();
        let repeats: Vec<[f64; 3]> = pts.iter().step_by(37).copied().collect();
        pts.extend(repeats);
        pts.extend((0..400).map(|k| [(k % 20) as f64 * 0.4, (k / 20) as f64 * 0.3, -0.5]));
        let patches = Patches::of(&pts);
        let params = ConeParams::default();
        let obs = Obs {
            pts: &pts,
            dt: None,
        };
        let mut passed_over = 0;
        for apex in [
            [3.0, 2.5, 1.5],
            [3.04, 2.47, 1.5],
            [2.7, 2.9, 1.2],
            [0.4, 0.3, 2.9],
            [7.9, 5.9, 0.05],
        ] {
            let cone = Cone::at(apex, 1.0);
            let want = lowest_one_by_one(&obs, &cone, &params);
            assert!(want.len() >= 8, "{}", want.len());
            let near = lowest_one_by_one(&obs, &Cone::at([3.1, 2.4, 1.4], 1.0), &params);
            let arbitrary: Vec<usize> = (0..pts.len()).step_by(501).chain([7, 7, 0]).collect();
            for seeds in [&want[..], &near[..], &[][..], &arbitrary[..]] {
                let got = lowest_per_sector(&obs, &cone, &params, Some((&patches, seeds)));
                assert_eq!(got, want, "apex {apex:?}");
            }
            // The boxes do rule chunks out once every sector has its lowest point.
            let mut best = vec![None; params.sectors];
            for &i in &want {
                let p = pts[i];
                let (dx, dy, dz) = (p[0] - apex[0], p[1] - apex[1], p[2] - apex[2]);
                let k = ((diamond_angle(dx, dy) / 4.0 * params.sectors as f64) as usize)
                    .min(params.sectors - 1);
                best[k] = Some((dz / (dx * dx + dy * dy).sqrt(), i));
            }
            passed_over += patches
                .boxes
                .iter()
                .filter(|b| b.above(apex, &best, params.sectors as f64))
                .count();
        }
        assert!(passed_over > patches.boxes.len(), "{passed_over}");
    }

    #[test]
    fn a_box_is_passed_over_only_above_every_sector_it_reaches() {
        let sectors = 8.0;
        // Four sectors of 45°: the lowest elevation found so far in each.
        let mut best: Vec<Option<(f64, usize)>> = vec![Some((-1.0, 0)); 8];
        let apex = [0.0, 0.0, 1.5];
        // Floor 2-3 m east, a few centimetres either side of the axis: elevation -0.75 at
        // its nearest, above -1 in the two sectors it reaches (7 and 0).
        let far = ChunkBox {
            lo: [2.0, -0.1],
            hi: [3.0, 0.1],
            zmin: 0.0,
        };
        assert!(far.above(apex, &best, sectors));
        // One of those sectors has found nothing yet, or something higher: look.
        best[7] = None;
        assert!(!far.above(apex, &best, sectors));
        best[7] = Some((-0.5, 0));
        assert!(!far.above(apex, &best, sectors));
        best[7] = Some((-1.0, 0));
        // As low as the lowest found (a tie) is looked at: -1.5 / 1.5 = -1.
        let tie = ChunkBox {
            lo: [1.5, 0.0],
            hi: [3.0, 0.2],
            zmin: 0.0,
        };
        assert!(!tie.above(apex, &best, sectors));
        // Above the apex, wherever it is: never a lowest point.
        let high = ChunkBox {
            lo: [0.2, 0.2],
            hi: [0.5, 0.5],
            zmin: 1.5,
        };
        assert!(high.above(apex, &best, sectors));
        // Around the apex: no bound.
        let around = ChunkBox {
            lo: [-0.5, -0.5],
            hi: [0.5, 0.5],
            zmin: 1.0,
        };
        assert!(!around.above(apex, &best, sectors));
    }

    #[test]
    fn the_branchless_diamond_angle_is_the_branching_one() {
        let mut dirs: Vec<(f64, f64)> = (0..100_000)
            .map(|k| {
                let a = k as f64 * 0.000_062_831_853 + 1e-7;
                let r = 0.01 + (k % 97) as f64 * 0.1;
                (r * a.cos(), r * a.sin())
            })
            .collect();
        for v in [0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300, 3.5] {
            for w in [0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300, 2.25] {
                dirs.push((v, w));
            }
        }
        for (dx, dy) in dirs {
            let (a, b) = (diamond_angle(dx, dy), diamond_angle_branching(dx, dy));
            // Equal as numbers (a zero's sign may differ), so in the same sector.
            assert_eq!(a, b, "({dx}, {dy})");
            assert_eq!((a / 4.0 * 72.0) as usize, (b / 4.0 * 72.0) as usize);
        }
    }

    #[test]
    fn diamond_angle_runs_once_round() {
        let turn: Vec<f64> = (0..16)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 16.0;
                diamond_angle(a.cos(), a.sin())
            })
            .collect();
        assert!(turn.windows(2).all(|w| w[0] < w[1]), "{turn:?}");
        assert_eq!(diamond_angle(1.0, 0.0), 0.0);
        assert_eq!(diamond_angle(0.0, 1.0), 1.0);
        assert_eq!(diamond_angle(-1.0, 0.0), 2.0);
        assert_eq!(diamond_angle(0.0, -1.0), 3.0);
        assert!(diamond_angle(1.0, -1e-9) < 4.0);
    }

    #[test]
    fn circle_through_three_points() {
        let (c, r) = fit_circle(&[[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]]).unwrap();
        assert!(crate::geom::dist(c, [0.0, 0.0]) < 1e-12 && (r - 1.0).abs() < 1e-12);
        assert!(fit_circle(&[[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]).is_none());
    }

    #[test]
    fn one_scan_from_a_known_point() {
        for at in [[3.0, 2.5], [1.2, 4.6], [6.5, 1.0]] {
            let pts = scan_room(at, -60.0);
            let cone = locate(&pts, &ConeParams::default()).expect("a blind cone");
            let err = crate::geom::dist([cone.apex[0], cone.apex[1]], at);
            assert!(err < 0.02, "{at:?}: {err} m off ({cone:?})");
            // The blind spot's radius on the floor: 1.5 m / tan 60°.
            let radius = cone.apex[2] / cone.slope;
            assert!((radius - 1.5 / 3f64.sqrt()).abs() < 0.02, "{cone:?}");
            assert!(cone.apex[2] > 0.5 && cone.apex[2] < 2.9, "{cone:?}");
        }
    }

    #[test]
    fn no_blind_cone_no_estimate() {
        // Points spread evenly over the floor: no hole anywhere.
        let pts: Vec<[f32; 3]> = (0..4000)
            .map(|k| [(k % 80) as f32 * 0.1, (k / 80) as f32 * 0.1, 0.0])
            .chain((0..400).map(|k| [0.0, (k % 50) as f32 * 0.1, (k / 50) as f32 * 0.3]))
            .collect();
        assert_eq!(locate(&pts, &ConeParams::default()), None);
        assert_eq!(locate(&pts[..10], &ConeParams::default()), None);
    }
}
