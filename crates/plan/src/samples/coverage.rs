//! How much of a story's outline its wall samples cover, for stories whose floor was not seen.
//!
//! Without a floor nothing but the walls says where a room ends. When the walls were seen along
//! only a small share of the outline they enclose, the plan's edges would be guessed chords,
//! so such a story fails with what was seen instead of planning silently wrong.

use geo::{ConvexHull, Coord, MultiPoint, Point};

use super::WallSample;

/// A floorless story needs its walls seen along at least this share of the perimeter of their
/// convex hull. Below it most of the outline would be a guess.
pub(super) const MIN_SEEN_SHARE: f64 = 0.25;

/// The length of wall the samples stand for (one sample a cell along a wall), and the
/// perimeter of their convex hull, metres.
pub(super) fn seen_and_around(samples: &[WallSample], cell: f64) -> (f64, f64) {
    let points: MultiPoint = samples
        .iter()
        .map(|s| {
            Point(Coord {
                x: s.pos[0],
                y: s.pos[1],
            })
        })
        .collect();
    let hull = points.convex_hull();
    let around = hull
        .exterior()
        .lines()
        .map(|l| (l.end.x - l.start.x).hypot(l.end.y - l.start.y))
        .sum();
    (samples.len() as f64 * cell, around)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(x: f64, y: f64) -> WallSample {
        WallSample {
            pos: [x, y],
            normal: [1.0, 0.0],
            confidence: 1.0,
            seen_from: Vec::new(),
        }
    }

    /// A 4 m square's sides sampled every 5 cm where `keep` holds for the place along the side.
    fn square(keep: impl Fn(f64) -> bool) -> Vec<WallSample> {
        (0..80)
            .map(|k| k as f64 * 0.05)
            .filter(|&t| keep(t))
            .flat_map(|t| {
                [
                    sample(t, 0.0),
                    sample(4.0, t),
                    sample(4.0 - t, 4.0),
                    sample(0.0, 4.0 - t),
                ]
            })
            .collect()
    }

    #[test]
    fn a_closed_square_is_seen_all_round_and_its_corners_alone_are_not() {
        let (seen, around) = seen_and_around(&square(|_| true), 0.05);
        assert!((seen - 16.0).abs() < 1e-9, "{seen}");
        assert!((around - 16.0).abs() < 0.1, "{around}");
        // A quarter metre of wall each side of each corner: an eighth of the outline.
        let corners = square(|t| !(0.25..3.75).contains(&t));
        let (seen, around) = seen_and_around(&corners, 0.05);
        assert!((seen - 2.0).abs() < 1e-9 && (around - 16.0).abs() < 0.1);
        assert!(seen / around < MIN_SEEN_SHARE);
        assert_eq!(seen_and_around(&[], 0.05), (0.0, 0.0));
    }
}
