//! What a phone or tablet records when it is held up to capture a room's ceiling, as the
//! consumer-LiDAR rooms in the real data were: no floor, walls seen from the ceiling down to a
//! height that changes along them, and the ceiling itself only near where the phone went.

use std::f64::consts::TAU;

/// The walls' lowest recorded height rises and falls over this distance, metres: a phone
/// swept by hand dips lower in some places than in others.
const SWING_PERIOD: f64 = 5.0;
/// The direction, radians, along which that height changes.
const SWING_DIRECTION: f64 = 1.0;
/// Points within this of the ceiling belong to it, metres.
const CEILING_BAND: f64 = 0.05;

/// A ceiling-aimed capture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capture {
    /// Nothing below this height is recorded.
    pub above: f64,
    /// Where the phone was held higher, the lowest recorded height is up to this much more.
    pub swing: f64,
    /// The ceiling is recorded only this far, horizontally, from the scanner, metres.
    pub ceiling_reach: f64,
}

impl Capture {
    /// The lowest height recorded over `xy`.
    pub fn lowest(&self, xy: [f64; 2]) -> f64 {
        let along = xy[0] * SWING_DIRECTION.cos() + xy[1] * SWING_DIRECTION.sin();
        self.above + self.swing * 0.5 * (1.0 + (TAU * along / SWING_PERIOD).sin())
    }

    /// Whether the point `p`, measured from `scanner` in a story whose ceiling is at
    /// `ceiling_z`, is recorded.
    pub fn keeps(&self, p: [f64; 3], scanner: [f64; 3], ceiling_z: f64) -> bool {
        if p[2] < self.lowest([p[0], p[1]]) {
            return false;
        }
        p[2] < ceiling_z - CEILING_BAND
            || (p[0] - scanner[0]).hypot(p[1] - scanner[1]) <= self.ceiling_reach
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lowest_height_swings_between_its_bounds_and_the_ceiling_ends_at_its_reach() {
        let c = Capture {
            above: 1.5,
            swing: 1.8,
            ceiling_reach: 3.0,
        };
        let lows: Vec<f64> = (0..200).map(|k| c.lowest([k as f64 * 0.05, 0.0])).collect();
        let (lo, hi) = lows
            .iter()
            .fold((f64::MAX, f64::MIN), |a, &v| (a.0.min(v), a.1.max(v)));
        assert!(
            (1.5..1.52).contains(&lo) && hi <= 3.3 && hi > 3.28,
            "{lo} {hi}"
        );
        let at = [0.0, 0.0, 1.5];
        assert!(c.keeps([2.9, 0.0, 4.0], at, 4.0));
        assert!(!c.keeps([3.1, 0.0, 4.0], at, 4.0));
        // A wall point far away is kept when it is high enough.
        assert!(c.keeps([6.0, 0.0, 3.5], at, 4.0));
        assert!(!c.keeps([6.0, 0.0, 1.4], at, 4.0));
    }
}
