//! Straight wall models: total-least-squares fit and intersections.

use crate::geom::{self, P2};

/// An infinite line through `point` along the unit vector `dir`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    pub point: P2,
    pub dir: P2,
}

impl Line {
    /// The total-least-squares line of `points` (the principal axis of their scatter), or `None`
    /// when the points do not span a direction (fewer than two distinct points).
    pub fn fit(points: &[P2]) -> Option<Line> {
        if points.len() < 2 {
            return None;
        }
        let n = points.len() as f64;
        let c = points.iter().fold([0.0, 0.0], |acc, &p| {
            geom::add(acc, geom::scale(p, 1.0 / n))
        });
        let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
        for p in points {
            let d = geom::sub(*p, c);
            sxx += d[0] * d[0];
            sxy += d[0] * d[1];
            syy += d[1] * d[1];
        }
        if sxx + syy <= 0.0 || !(sxx + syy).is_finite() {
            return None;
        }
        // Direction of the largest eigenvector of the 2 × 2 scatter matrix, in closed form.
        let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
        Some(Line {
            point: c,
            dir: [angle.cos(), angle.sin()],
        })
    }

    /// Unit normal (the direction turned left).
    pub fn normal(&self) -> P2 {
        [-self.dir[1], self.dir[0]]
    }

    /// Unsigned distance from `p` to the line.
    pub fn distance(&self, p: P2) -> f64 {
        geom::dot(geom::sub(p, self.point), self.normal()).abs()
    }

    /// The foot of the perpendicular from `p`.
    pub fn project(&self, p: P2) -> P2 {
        let t = geom::dot(geom::sub(p, self.point), self.dir);
        geom::add(self.point, geom::scale(self.dir, t))
    }

    /// The crossing point of two lines, or `None` when they are (nearly) parallel.
    pub fn intersect(&self, other: &Line) -> Option<P2> {
        let denom = geom::cross(self.dir, other.dir);
        // Below about 0.06°, the corner would sit kilometres away; treat as parallel.
        if denom.abs() < 1e-3 {
            return None;
        }
        let t = geom::cross(geom::sub(other.point, self.point), other.dir) / denom;
        Some(geom::add(self.point, geom::scale(self.dir, t)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_recovers_a_diagonal_line_and_rejects_a_point() {
        let pts: Vec<P2> = (0..10).map(|i| [i as f64, 2.0 * i as f64 + 1.0]).collect();
        let l = Line::fit(&pts).unwrap();
        for p in &pts {
            assert!(l.distance(*p) < 1e-12);
        }
        assert!(geom::cross(l.dir, [1.0, 2.0]).abs() < 1e-12);
        assert!(Line::fit(&[[1.0, 1.0], [1.0, 1.0], [1.0, 1.0]]).is_none());
        assert!(Line::fit(&[[1.0, 1.0]]).is_none());
    }

    #[test]
    fn perpendicular_lines_meet_at_the_corner() {
        let a = Line {
            point: [0.0, 0.0],
            dir: [1.0, 0.0],
        };
        let b = Line {
            point: [4.0, 7.0],
            dir: [0.0, -1.0],
        };
        assert_eq!(a.intersect(&b), Some([4.0, 0.0]));
        assert!(a
            .intersect(&Line {
                point: [0.0, 1.0],
                dir: [-1.0, 0.0]
            })
            .is_none());
        assert_eq!(a.project([2.0, 5.0]), [2.0, 0.0]);
    }
}
