//! The point spacing of a cloud (beyond the paper): the median distance from a point to its
//! nearest neighbour, measured on the points of a sample of the cloud's volume. The grid's cell
//! size follows from it ([`super::derive`]), so that clouds of voxel centres or downsampled
//! clouds (8 cm, 10 cm) are planned at a scale that suits them.
//!
//! The sample is every point in the 1 m cubes whose hashed coordinates fall below a threshold;
//! the threshold halves until at most [`MAX_PROBE`] points remain. Which cubes are kept depends
//! only on where the points are, so the result does not depend on the order the points come in
//! (whole, in parallel parts, or chunk by chunk from a file).

use rayon::prelude::*;

/// The edge of the cubes the sample is made of, metres.
const CUBE: f64 = 1.0;
/// Each cube is cut into this many bins a side to find neighbours (3.1 cm bins).
const BINS: usize = 32;
/// Neighbours are looked for up to this many bins away (25 cm); farther points are isolated.
const MAX_SHELL: usize = 8;
/// The most points the sample keeps.
pub(crate) const MAX_PROBE: usize = 1 << 16;
/// Fewer nearest-neighbour distances than this say nothing: no spacing is measured.
const MIN_MEASURED: usize = 200;

/// A growing sample of a cloud's points for [`SpacingProbe::spacing`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SpacingProbe {
    /// Cubes are kept when their hash's top `level` bits are zero.
    level: u32,
    /// Kept points, with their cube's key.
    points: Vec<(u64, [f32; 3])>,
}

/// A cube's key: its coordinates, 21 bits each (wrapping far outside ±1000 km).
fn cube_key(p: &[f32; 3]) -> u64 {
    let c = |v: f32| (floor_i64(v as f64 / CUBE) as u64) & 0x1f_ffff;
    (c(p[0]) << 42) | (c(p[1]) << 21) | c(p[2])
}

/// `x.floor() as i64`, without the libm call the baseline x86-64 target makes for `floor`
/// (three per point here): the truncation, one less when it rounded up.
#[inline]
fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    // Past the ends of i64 the cast saturates, as `floor() as i64` does.
    t.saturating_sub(i64::from(t as f64 > x))
}

/// Points whose cube keys are found together, a coordinate at a time in 32-bit lanes.
const LANES: usize = 8;

/// Coordinates below this in magnitude take the lanes' path: 2^22, where adding
/// [`ROUNDER`] leaves a float whose units are whole numbers.
const LANE_RANGE: f32 = 4_194_304.0;

/// 1.5 × 2^23: adding it to a float under 2^22 in magnitude rounds it to a whole number,
/// which the sum's low bits then hold.
const ROUNDER: f32 = 12_582_912.0;

/// [`cube_key`] of each of `LANES` points, when every coordinate is within ±2^22 m (so
/// finite); `None` otherwise. Each coordinate is rounded to the nearest whole number by adding
/// [`ROUNDER`] and reading the sum's bits, and its floor is that, one less when it rounded up:
/// the same as `cube_key`'s, in steps the compiler can do several lanes at a time (a float's
/// cast to an integer is not one: it checks for overflow).
fn lane_keys(pts: &[[f32; 3]]) -> Option<[u64; LANES]> {
    let mut c = [[0f32; LANES]; 3];
    let mut small = true;
    for (k, p) in pts.iter().enumerate() {
        for a in 0..3 {
            c[a][k] = p[a];
            small &= p[a].abs() < LANE_RANGE;
        }
    }
    if !small {
        return None;
    }
    let floor = |v: &[f32; LANES]| -> [u64; LANES] {
        let mut out = [0u64; LANES];
        for (o, &v) in out.iter_mut().zip(v) {
            let n = (v + ROUNDER).to_bits() as i32 - ROUNDER.to_bits() as i32;
            *o = ((n - i32::from(n as f32 > v)) as u32 & 0x1f_ffff) as u64;
        }
        out
    };
    let (x, y, z) = (floor(&c[0]), floor(&c[1]), floor(&c[2]));
    Some(std::array::from_fn(|k| (x[k] << 42) | (y[k] << 21) | z[k]))
}

/// SplitMix64's finaliser: spreads the cube keys evenly over the hash range.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

fn kept(key: u64, level: u32) -> bool {
    level == 0 || mix(key) >> (64 - level) == 0
}

impl SpacingProbe {
    /// Adds points; non-finite ones are skipped.
    pub fn add(&mut self, xyz: &[[f32; 3]]) {
        let mut chunks = xyz.chunks_exact(LANES);
        for chunk in chunks.by_ref() {
            match lane_keys(chunk) {
                Some(keys) => {
                    for (&key, p) in keys.iter().zip(chunk) {
                        self.offer(key, p);
                    }
                }
                None => self.add_one_by_one(chunk),
            }
        }
        self.add_one_by_one(chunks.remainder());
    }

    fn add_one_by_one(&mut self, xyz: &[[f32; 3]]) {
        for p in xyz {
            if p.iter().all(|c| c.is_finite()) {
                self.offer(cube_key(p), p);
            }
        }
    }

    /// Keeps `p`, in the cube `key`, when the cube is kept.
    #[inline]
    fn offer(&mut self, key: u64, p: &[f32; 3]) {
        if kept(key, self.level) {
            self.points.push((key, *p));
            if self.points.len() > MAX_PROBE {
                self.thin();
            }
        }
    }

    /// Adds the points kept by `other`, a probe of other points.
    pub fn merge(&mut self, other: SpacingProbe) {
        self.level = self.level.max(other.level);
        let level = self.level;
        self.points.retain(|(k, _)| kept(*k, level));
        self.points
            .extend(other.points.into_iter().filter(|(k, _)| kept(*k, level)));
        while self.points.len() > MAX_PROBE {
            self.thin();
        }
    }

    /// Halves the share of cubes kept.
    fn thin(&mut self) {
        while self.points.len() > MAX_PROBE && self.level < 64 {
            self.level += 1;
            let level = self.level;
            self.points.retain(|(k, _)| kept(*k, level));
        }
    }

    /// The probe of a whole cloud, in parallel. Each thread keeps one probe across its
    /// chunks: once its share is thinned, most points are dropped on their hash alone.
    pub fn of(xyz: &[[f32; 3]]) -> SpacingProbe {
        xyz.par_chunks(1 << 16)
            .fold(SpacingProbe::default, |mut p, chunk| {
                p.add(chunk);
                p
            })
            .reduce(SpacingProbe::default, |mut a, b| {
                a.merge(b);
                a
            })
    }

    /// The median nearest-neighbour distance among the kept points, metres; `None` when too
    /// few points have a neighbour within 25 cm inside their cube. A point whose neighbour
    /// could lie in the next cube (closer to the cube's face than to any neighbour found) is
    /// left out.
    pub fn spacing(&self) -> Option<f64> {
        let mut points = self.points.clone();
        points.sort_unstable_by(|a, b| {
            a.0.cmp(&b.0)
                .then_with(|| a.1.map(f32::to_bits).cmp(&b.1.map(f32::to_bits)))
        });
        let mut d: Vec<f64> = Vec::new();
        let mut start = 0;
        while start < points.len() {
            let key = points[start].0;
            let end = start + points[start..].partition_point(|p| p.0 == key);
            nearest_in_cube(&points[start..end], &mut d);
            start = end;
        }
        if d.len() < MIN_MEASURED {
            return None;
        }
        let mid = d.len() / 2;
        Some(*d.select_nth_unstable_by(mid, f64::total_cmp).1)
    }
}

/// Appends the nearest-neighbour distance of each point of one cube (whose neighbour surely
/// lies in the cube) to `out`.
fn nearest_in_cube(pts: &[(u64, [f32; 3])], out: &mut Vec<f64>) {
    if pts.len() < 2 {
        return;
    }
    let origin = pts[0].1.map(|c| (c as f64 / CUBE).floor() * CUBE);
    let g = CUBE / BINS as f64;
    let bin = |p: &[f32; 3]| {
        std::array::from_fn::<usize, 3, _>(|k| {
            (((p[k] as f64 - origin[k]) / g) as usize).min(BINS - 1)
        })
    };
    let id = |b: [usize; 3]| (b[2] * BINS + b[1]) * BINS + b[0];
    // Counting sort of the points by bin.
    let mut start = vec![0u32; BINS * BINS * BINS + 1];
    for (_, p) in pts {
        start[id(bin(p)) + 1] += 1;
    }
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    let mut fill = start.clone();
    let mut sorted = vec![[0f32; 3]; pts.len()];
    for (_, p) in pts {
        let i = id(bin(p));
        sorted[fill[i] as usize] = *p;
        fill[i] += 1;
    }
    for (_, p) in pts {
        let b = bin(p);
        let mut best = f64::INFINITY;
        for r in 0..=MAX_SHELL {
            // Every point within r bins' width lies in the shells searched so far.
            if best <= r as f64 * g {
                break;
            }
            for_shell(b, r, |c| {
                let i = id(c);
                for q in &sorted[start[i] as usize..start[i + 1] as usize] {
                    let d2: f64 = (0..3).map(|k| (q[k] as f64 - p[k] as f64).powi(2)).sum();
                    if d2 > 0.0 && d2 < best * best {
                        best = d2.sqrt();
                    }
                }
            });
        }
        // Farther from the cube's faces than from the neighbour found: none outside is nearer.
        let face = (0..3)
            .map(|k| {
                let v = p[k] as f64 - origin[k];
                v.min(CUBE - v)
            })
            .fold(f64::INFINITY, f64::min);
        if best.is_finite() && best <= face {
            out.push(best);
        }
    }
}

/// Calls `f` with every bin at Chebyshev distance `r` from `b` within the cube.
fn for_shell(b: [usize; 3], r: usize, mut f: impl FnMut([usize; 3])) {
    let r = r as isize;
    let range = |c: usize| (c as isize - r).max(0)..=(c as isize + r).min(BINS as isize - 1);
    for z in range(b[2]) {
        for y in range(b[1]) {
            for x in range(b[0]) {
                let on_shell = (x - b[0] as isize).abs() == r
                    || (y - b[1] as isize).abs() == r
                    || (z - b[2] as isize).abs() == r;
                if on_shell {
                    f([x as usize, y as usize, z as usize]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on a lattice of `step` over a wall and a floor, 6 m × 3 m each, both halfway
    /// through their cubes.
    fn lattice(step: f32) -> Vec<[f32; 3]> {
        let n = (3.0 / step) as usize;
        let mut v = Vec::new();
        for i in 0..2 * n {
            for j in 0..n {
                let (a, b) = ((i as f32 + 0.5) * step, (j as f32 + 0.5) * step);
                v.push([a, 0.5, b + 1.0]);
                v.push([a, b + 1.0, 0.5]);
            }
        }
        v
    }

    #[test]
    fn a_lattice_has_its_step_for_spacing() {
        for step in [0.02f32, 0.08, 0.1] {
            let s = SpacingProbe::of(&lattice(step)).spacing().unwrap();
            assert!((s - step as f64).abs() < 1e-4, "{step}: {s}");
        }
    }

    #[test]
    fn the_probe_does_not_depend_on_order_or_parts() {
        // More points than the probe keeps: the cubes are thinned.
        let mut pts = lattice(0.01);
        assert!(pts.len() > 2 * MAX_PROBE);
        let whole = SpacingProbe::of(&pts);
        assert!(whole.level > 0 && whole.points.len() <= MAX_PROBE);
        pts.reverse();
        let mut parts = SpacingProbe::default();
        for chunk in pts.chunks(10_007) {
            let mut p = SpacingProbe::default();
            p.add(chunk);
            parts.merge(p);
        }
        assert_eq!(parts.level, whole.level);
        assert_eq!(parts.spacing(), whole.spacing());
        assert!((whole.spacing().unwrap() - 0.01).abs() < 1e-4);
    }

    #[test]
    fn the_floor_is_the_libm_floor() {
        let mut xs = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1.5,
            2.0f64.powi(52) + 0.5,
            -(2.0f64.powi(53)) - 2.0,
            9.3e18,
            -9.3e18,
            -(2.0f64.powi(63)),
            f32::MAX as f64,
            f32::MIN as f64,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        xs.extend((-3000..3000).map(|k| k as f64 * 0.0137));
        xs.extend((-100..100).map(|k| k as f32 * 0.1).map(|v| v as f64));
        // Halves (rounding ties go to even), whole numbers and their neighbours, and the
        // lanes' range.
        for v in [
            0.5f32,
            1.5,
            2.5,
            3.5,
            7.0,
            4_194_303.5,
            4_194_303.0,
            4_194_304.0,
        ] {
            for w in [
                v,
                -v,
                f32::from_bits(v.to_bits() + 1),
                f32::from_bits(v.to_bits() - 1),
            ] {
                xs.extend([w as f64, -w as f64]);
            }
        }
        for &x in &xs {
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        }
        // The lanes give the same keys, and leave alone what they cannot take.
        let vs: Vec<f32> = xs.iter().map(|&x| x as f32).collect();
        for (k, w) in vs.windows(3).enumerate() {
            let pts: Vec<[f32; 3]> = (0..LANES).map(|j| [w[0], w[1], w[2] + j as f32]).collect();
            match lane_keys(&pts) {
                Some(keys) => {
                    for (key, p) in keys.iter().zip(&pts) {
                        assert_eq!(*key, cube_key(p), "{k}: {p:?}");
                    }
                }
                None => assert!(
                    pts.iter()
                        .flatten()
                        .any(|v| v.is_nan() || v.abs() >= LANE_RANGE),
                    "{k}"
                ),
            }
        }
    }

    #[test]
    fn too_few_points_measure_nothing() {
        let few: Vec<[f32; 3]> = (0..50).map(|i| [i as f32 * 0.01, 0.0, 0.0]).collect();
        assert_eq!(SpacingProbe::of(&few).spacing(), None);
        // Isolated points (1 m apart) have no neighbour within reach.
        let far: Vec<[f32; 3]> = (0..5000).map(|i| [i as f32, 0.5, 0.5]).collect();
        assert_eq!(SpacingProbe::of(&far).spacing(), None);
        assert_eq!(SpacingProbe::of(&[[f32::NAN; 3]]).spacing(), None);
    }
}
