//! Analytic ray casting against a story's surfaces, for static and mobile scanners.

use rand::Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::buildings::{Patch, StoryModel, Surface};
use super::truth::{angle_in_sweep, TruthWall};

/// Rays start this far along before they can hit, so a surface never hits its own ray origin.
const EPS: f64 = 1.0e-9;
/// The lowest ray elevation: scanners do not see the floor right under their tripod.
const MIN_ELEVATION: f64 = -60.0 * std::f64::consts::PI / 180.0;

/// The distance along the unit direction `d` from `o` to the first surface, floor or ceiling.
pub fn cast(story: &StoryModel, o: [f64; 3], d: [f64; 3]) -> Option<f64> {
    let mut best = f64::INFINITY;
    if !story.slabs {
        // Floors and ceilings are patches.
    } else if d[2] < 0.0 {
        best = (story.floor_z - o[2]) / d[2];
    } else if d[2] > 0.0 {
        best = (story.ceiling_z - o[2]) / d[2];
    }
    for s in &story.surfaces {
        if let Some(t) = hit_surface(s, o, d, best) {
            best = t;
        }
    }
    for p in &story.patches {
        if let Some(t) = hit_patch(p, o, d, best) {
            best = t;
        }
    }
    // A ray that leaves through a window's outer plane measures nothing: there is no outside.
    for w in &story.truth.windows {
        let (a, b) = w.exit();
        let plane = Surface {
            curve: TruthWall::Line { a, b },
            z: [w.sill_z, w.head_z],
        };
        if hit_surface(&plane, o, d, best).is_some() {
            return None;
        }
    }
    (best.is_finite() && best > EPS).then_some(best)
}

fn hit_surface(s: &Surface, o: [f64; 3], d: [f64; 3], best: f64) -> Option<f64> {
    let in_z = |t: f64| {
        let z = o[2] + t * d[2];
        z >= s.z[0] && z <= s.z[1]
    };
    match s.curve {
        TruthWall::Line { a, b } => {
            let e = [b[0] - a[0], b[1] - a[1]];
            let denom = d[0] * e[1] - d[1] * e[0];
            if denom.abs() < 1e-15 {
                return None;
            }
            let w = [a[0] - o[0], a[1] - o[1]];
            let t = (w[0] * e[1] - w[1] * e[0]) / denom;
            let u = (w[0] * d[1] - w[1] * d[0]) / denom;
            (t > EPS && t < best && (0.0..=1.0).contains(&u) && in_z(t)).then_some(t)
        }
        TruthWall::Arc {
            center,
            radius,
            start,
            sweep,
        } => {
            let qa = d[0] * d[0] + d[1] * d[1];
            if qa < 1e-18 {
                return None;
            }
            let oc = [o[0] - center[0], o[1] - center[1]];
            let qb = 2.0 * (d[0] * oc[0] + d[1] * oc[1]);
            let qc = oc[0] * oc[0] + oc[1] * oc[1] - radius * radius;
            let disc = qb * qb - 4.0 * qa * qc;
            if disc < 0.0 {
                return None;
            }
            let root = disc.sqrt();
            [(-qb - root) / (2.0 * qa), (-qb + root) / (2.0 * qa)]
                .into_iter()
                .find(|&t| {
                    t > EPS && t < best && in_z(t) && {
                        let x = oc[0] + t * d[0];
                        let y = oc[1] + t * d[1];
                        angle_in_sweep(y.atan2(x), start, sweep)
                    }
                })
        }
    }
}

fn hit_patch(p: &Patch, o: [f64; 3], d: [f64; 3], best: f64) -> Option<f64> {
    let t = if p.slope == [0.0, 0.0] {
        if d[2] == 0.0 {
            return None;
        }
        (p.z - o[2]) / d[2]
    } else {
        // o_z + t d_z = z_at(o_xy + t d_xy), the patch's plane rising along its slope.
        let rise = d[2] - (p.slope[0] * d[0] + p.slope[1] * d[1]);
        if rise == 0.0 {
            return None;
        }
        (p.z_at([o[0], o[1]]) - o[2]) / rise
    };
    (t > EPS && t < best && p.contains([o[0] + t * d[0], o[1] + t * d[1]])).then_some(t)
}

/// A random direction, uniform over the sphere above `MIN_ELEVATION`.
pub fn direction(rng: &mut impl Rng) -> [f64; 3] {
    let z_min = MIN_ELEVATION.sin();
    let z: f64 = rng.random_range(z_min..1.0);
    let az: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    [r * az.cos(), r * az.sin(), z]
}

/// A deterministic random stream for one block of rays.
pub fn block_rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    rng
}

/// Casts one ray from `o` and returns the (noisy) point it measures, if it hits.
pub fn measure(
    story: &StoryModel,
    o: [f64; 3],
    rng: &mut ChaCha8Rng,
    noise: Option<&Normal<f64>>,
) -> Option<[f64; 3]> {
    let d = direction(rng);
    let t = cast(story, o, d)?;
    let r = match noise {
        Some(n) => (t + n.sample(rng)).max(0.0),
        None => t,
    };
    Some([o[0] + r * d[0], o[1] + r * d[1], o[2] + r * d[2]])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::buildings::BuildingKind;

    #[test]
    fn rays_hit_a_sloped_patch_on_its_plane() {
        let mut story = BuildingKind::SquareRoom.build().stories.remove(0);
        story.slabs = false;
        story.surfaces.clear();
        // A roof rising 0.5 m per metre in y from z = 3 at y = 0, over 10 m × 10 m.
        story.patches = vec![Patch {
            corners: [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]],
            z: 3.0,
            slope: [0.0, 0.5],
        }];
        let o = [5.0, 2.0, 1.0];
        // Straight up: the roof at y = 2 is at 4.
        assert!((cast(&story, o, [0.0, 0.0, 1.0]).unwrap() - 3.0).abs() < 1e-12);
        // Towards +y at 45°, s = t/√2 along each axis: 1 + s = 3 + 0.5 (2 + s), so s = 6.
        let k = std::f64::consts::FRAC_1_SQRT_2;
        let t = cast(&story, o, [0.0, k, k]).unwrap();
        assert!((t * k - 6.0).abs() < 1e-9, "{t}");
        // Down: no floor plane without slabs, and no patch below.
        assert_eq!(cast(&story, o, [0.0, 0.0, -1.0]), None);
    }

    #[test]
    fn rays_hit_walls_floor_and_ceiling_of_the_square_room() {
        let b = BuildingKind::SquareRoom.build();
        let s = &b.stories[0];
        let o = [2.0, 2.0, 1.5];
        assert!((cast(s, o, [1.0, 0.0, 0.0]).unwrap() - 4.0).abs() < 1e-12);
        assert!((cast(s, o, [-1.0, 0.0, 0.0]).unwrap() - 2.0).abs() < 1e-12);
        assert!((cast(s, o, [0.0, 0.0, -1.0]).unwrap() - 1.5).abs() < 1e-12);
        assert!((cast(s, o, [0.0, 0.0, 1.0]).unwrap() - 1.1).abs() < 1e-12);
        let k = std::f64::consts::FRAC_1_SQRT_2;
        // 45° down towards +x: the floor at 1.5 m horizontal distance, before the wall.
        assert!((cast(s, o, [k, 0.0, -k]).unwrap() - 1.5 * 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn rays_hit_the_lobby_arc_at_its_radius() {
        let b = BuildingKind::CurvedLobby.build();
        let s = &b.stories[0];
        let o = [0.0, 0.0, 1.5];
        let a = 1.0_f64;
        let d = [
            a.cos() * 0.999,
            a.sin() * 0.999,
            (1.0f64 - 0.999 * 0.999).sqrt(),
        ];
        let t = cast(s, o, d).unwrap();
        let p = [t * d[0], t * d[1]];
        let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
        assert!((r - 10.0).abs() < 1e-9, "{r}");
    }

    fn geom_unit(d: [f64; 3]) -> [f64; 3] {
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        d.map(|v| v / n)
    }

    #[test]
    fn doors_show_the_next_room_below_the_lintel_only() {
        let b = BuildingKind::RotatedL.build();
        let s = &b.stories[0];
        // In the canonical frame the door is at x 2-2.9 in the wall y 5-5.2; check before rotation
        // by undoing it.
        let undo = |p: [f64; 2]| {
            let q = [p[0] - 3.0, p[1] + 2.0];
            crate::simulate::truth::rotate(q, -super::super::buildings::ROTATED_L_ANGLE)
        };
        let fwd = |p: [f64; 2]| {
            let q = crate::simulate::truth::rotate(p, super::super::buildings::ROTATED_L_ANGLE);
            [q[0] + 3.0, q[1] - 2.0]
        };
        let from = fwd([2.45, 2.5]);
        let dir2 =
            crate::simulate::truth::rotate([0.0, 1.0], super::super::buildings::ROTATED_L_ANGLE);
        // Below the far wall's window sill (0.8 m).
        let low = cast(s, [from[0], from[1], 0.5], [dir2[0], dir2[1], 0.0]).unwrap();
        let hit = undo([from[0] + low * dir2[0], from[1] + low * dir2[1]]);
        assert!(
            (hit[1] - 10.0).abs() < 1e-9,
            "through the door to the far wall: {hit:?}"
        );
        // Between the sill and the head: through the door and out of the window (x 2-3 in
        // the wall y = 10), so nothing is measured.
        assert_eq!(
            cast(s, [from[0], from[1], 1.2], [dir2[0], dir2[1], 0.0]),
            None
        );
        // Up into the window: the underside of its head, 15 cm into the 30 cm reveal.
        let k = 0.3 / 7.65;
        let d = geom_unit([dir2[0], dir2[1], k]);
        let t = cast(s, [from[0], from[1], 1.7], d).unwrap();
        let p = [from[0] + t * d[0], from[1] + t * d[1]];
        let z = 1.7 + t * d[2];
        assert!((z - 2.0).abs() < 1e-9, "the head's underside: {z}");
        assert!((undo(p)[1] - 10.15).abs() < 1e-9, "{:?}", undo(p));
        let high = cast(s, [from[0], from[1], 2.5], [dir2[0], dir2[1], 0.0]).unwrap();
        let hit = undo([from[0] + high * dir2[0], from[1] + high * dir2[1]]);
        assert!((hit[1] - 5.0).abs() < 1e-9, "the lintel: {hit:?}");
    }
}
