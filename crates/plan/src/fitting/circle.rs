//! Curved wall models: circle through three points, Kåsa's algebraic fit refined by
//! Gauss-Newton on the geometric distance, and intersections.

use nalgebra::{Matrix3, Vector3};

use crate::fitting::line::Line;
use crate::geom::{self, P2};

/// A circle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Circle {
    pub center: P2,
    pub radius: f64,
}

impl Circle {
    /// The circle through three points, or `None` when they are (nearly) collinear.
    pub fn through(a: P2, b: P2, c: P2) -> Option<Circle> {
        let (ab, ac) = (geom::sub(b, a), geom::sub(c, a));
        let d = 2.0 * geom::cross(ab, ac);
        let scale = geom::dot(ab, ab).max(geom::dot(ac, ac));
        if d.abs() <= 1e-12 * scale || scale == 0.0 {
            return None;
        }
        let (b2, c2) = (geom::dot(ab, ab), geom::dot(ac, ac));
        let u = [(ac[1] * b2 - ab[1] * c2) / d, (ab[0] * c2 - ac[0] * b2) / d];
        let circle = Circle {
            center: geom::add(a, u),
            radius: geom::norm(u),
        };
        circle.is_finite().then_some(circle)
    }

    /// Least-squares circle: Kåsa's algebraic fit, then Gauss-Newton on the geometric residuals
    /// |p − c| − r. `None` for fewer than three points or collinear ones.
    pub fn fit(points: &[P2]) -> Option<Circle> {
        let start = Self::kasa(points)?;
        Some(Self::refine(points, start).unwrap_or(start))
    }

    /// Kåsa's fit: minimises Σ (x² + y² + Dx + Ey + F)², a linear problem, in coordinates
    /// centred on the centroid for conditioning.
    pub fn kasa(points: &[P2]) -> Option<Circle> {
        if points.len() < 3 {
            return None;
        }
        let n = points.len() as f64;
        let c = points.iter().fold([0.0, 0.0], |acc, &p| {
            geom::add(acc, geom::scale(p, 1.0 / n))
        });
        let mut ata = Matrix3::<f64>::zeros();
        let mut atb = Vector3::<f64>::zeros();
        for p in points {
            let [x, y] = geom::sub(*p, c);
            let row = Vector3::new(x, y, 1.0);
            ata += row * row.transpose();
            atb -= row * (x * x + y * y);
        }
        let sol = ata.lu().solve(&atb)?;
        let u = [-sol[0] / 2.0, -sol[1] / 2.0];
        let r2 = u[0] * u[0] + u[1] * u[1] - sol[2];
        let circle = Circle {
            center: geom::add(c, u),
            radius: r2.max(0.0).sqrt(),
        };
        // Collinear points drive the radius to infinity through rounding: no circle.
        (r2 > 0.0 && circle.is_finite() && circle.radius < 1e6).then_some(circle)
    }

    /// Gauss-Newton on the geometric distance, from `start`. `None` if it breaks down.
    pub fn refine(points: &[P2], start: Circle) -> Option<Circle> {
        let mut c = start;
        for _ in 0..50 {
            let mut jtj = Matrix3::<f64>::zeros();
            let mut jtr = Vector3::<f64>::zeros();
            for p in points {
                let d = geom::sub(*p, c.center);
                let len = geom::norm(d);
                if len == 0.0 {
                    continue;
                }
                let j = Vector3::new(-d[0] / len, -d[1] / len, -1.0);
                jtj += j * j.transpose();
                jtr += j * (len - c.radius);
            }
            let step = jtj.lu().solve(&(-jtr))?;
            c = Circle {
                center: [c.center[0] + step[0], c.center[1] + step[1]],
                radius: c.radius + step[2],
            };
            if !c.is_finite() || c.radius <= 0.0 {
                return None;
            }
            if step.norm() <= 1e-13 * c.radius.max(1.0) {
                break;
            }
        }
        Some(c)
    }

    fn is_finite(&self) -> bool {
        self.center[0].is_finite() && self.center[1].is_finite() && self.radius.is_finite()
    }

    /// Unsigned distance from `p` to the circle.
    pub fn distance(&self, p: P2) -> f64 {
        (geom::dist(p, self.center) - self.radius).abs()
    }

    /// The outward radial direction at `p` (the circle's normal there).
    pub fn normal_at(&self, p: P2) -> P2 {
        geom::normalize(geom::sub(p, self.center)).unwrap_or([1.0, 0.0])
    }

    /// The nearest point on the circle.
    pub fn project(&self, p: P2) -> P2 {
        geom::add(self.center, geom::scale(self.normal_at(p), self.radius))
    }

    /// Angle of `p` around the centre.
    pub fn angle(&self, p: P2) -> f64 {
        (p[1] - self.center[1]).atan2(p[0] - self.center[0])
    }

    /// How far the arc covering `points` (the circle less the widest angular gap between them)
    /// bows away from its chord: R (1 − cos(θ / 2)) for a covered angle θ. Over half a turn it
    /// is the radius or more.
    pub fn sagitta(&self, points: &[P2]) -> f64 {
        let mut angles: Vec<f64> = points.iter().map(|&p| self.angle(p)).collect();
        if angles.len() < 2 {
            return 0.0;
        }
        angles.sort_by(f64::total_cmp);
        let wrap = angles[0] + std::f64::consts::TAU - angles[angles.len() - 1];
        let gap = angles.windows(2).map(|w| w[1] - w[0]).fold(wrap, f64::max);
        let covered = std::f64::consts::TAU - gap;
        self.radius * (1.0 - (covered / 2.0).cos())
    }

    /// The point at angle `a`.
    pub fn at(&self, a: f64) -> P2 {
        [
            self.center[0] + self.radius * a.cos(),
            self.center[1] + self.radius * a.sin(),
        ]
    }

    /// Where the circle meets a line (0, 1 or 2 points; a near-tangent gives the touch point).
    pub fn intersect_line(&self, line: &Line) -> Vec<P2> {
        let foot = line.project(self.center);
        let h = geom::dist(foot, self.center);
        if h > self.radius * (1.0 + 1e-9) {
            return Vec::new();
        }
        let half = (self.radius * self.radius - h * h).max(0.0).sqrt();
        vec![
            geom::add(foot, geom::scale(line.dir, half)),
            geom::sub(foot, geom::scale(line.dir, half)),
        ]
    }

    /// Where two circles meet (0 or 2 points).
    pub fn intersect_circle(&self, other: &Circle) -> Vec<P2> {
        let d = geom::dist(self.center, other.center);
        if d == 0.0 || d > self.radius + other.radius || d < (self.radius - other.radius).abs() {
            return Vec::new();
        }
        let a = (self.radius * self.radius - other.radius * other.radius + d * d) / (2.0 * d);
        let h = (self.radius * self.radius - a * a).max(0.0).sqrt();
        let u = geom::scale(geom::sub(other.center, self.center), 1.0 / d);
        let mid = geom::add(self.center, geom::scale(u, a));
        let perp = [-u[1], u[0]];
        vec![
            geom::add(mid, geom::scale(perp, h)),
            geom::sub(mid, geom::scale(perp, h)),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_points_give_their_circumcircle_and_collinear_gives_none() {
        let c = Circle::through([1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]).unwrap();
        assert!(geom::norm(c.center) < 1e-15 && (c.radius - 1.0).abs() < 1e-15);
        assert!(Circle::through([0.0, 0.0], [1.0, 1.0], [2.0, 2.0]).is_none());
        assert!(Circle::through([0.0, 0.0], [0.0, 0.0], [2.0, 2.0]).is_none());
    }

    #[test]
    fn least_squares_fit_of_a_noisy_quarter_arc() {
        // A 90° arc of radius 5 about (3, -2) with alternating ±5 mm radial offsets: Kåsa is
        // biased on partial arcs, Gauss-Newton removes the bias.
        let truth = Circle {
            center: [3.0, -2.0],
            radius: 5.0,
        };
        let pts: Vec<P2> = (0..80)
            .map(|i| {
                let a = 0.3 + i as f64 * (std::f64::consts::FRAC_PI_2 / 79.0);
                let r = 5.0 + if i % 2 == 0 { 0.005 } else { -0.005 };
                [3.0 + r * a.cos(), -2.0 + r * a.sin()]
            })
            .collect();
        let c = Circle::fit(&pts).unwrap();
        assert!(
            (c.radius - truth.radius).abs() < 1e-3,
            "radius {}",
            c.radius
        );
        assert!(geom::dist(c.center, truth.center) < 2e-3);
        // The gradient of the geometric cost vanishes at the optimum: Σ residuals = 0.
        let sum: f64 = pts
            .iter()
            .map(|&p| geom::dist(p, c.center) - c.radius)
            .sum();
        assert!(sum.abs() < 1e-9, "{sum}");
        assert!(Circle::fit(&[[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]).is_none());
    }

    #[test]
    fn intersections_lie_on_both_curves() {
        let c = Circle {
            center: [1.0, 1.0],
            radius: 2.0,
        };
        let l = Line {
            point: [0.0, 0.5],
            dir: [1.0, 0.0],
        };
        let hits = c.intersect_line(&l);
        assert_eq!(hits.len(), 2);
        for h in hits {
            assert!(c.distance(h) < 1e-12 && l.distance(h) < 1e-12);
        }
        let d = Circle {
            center: [2.5, 1.0],
            radius: 1.0,
        };
        for h in c.intersect_circle(&d) {
            assert!(c.distance(h) < 1e-12 && d.distance(h) < 1e-12);
        }
        assert!(c
            .intersect_line(&Line {
                point: [0.0, 5.0],
                dir: [1.0, 0.0]
            })
            .is_empty());
    }

    #[test]
    fn sagitta_is_the_bow_of_the_covered_arc() {
        let c = Circle {
            center: [0.0, 0.0],
            radius: 20.0,
        };
        // 1.2 m of a 20 m circle, straddling angle 0: bows 9 mm.
        let half = 0.6 / 20.0;
        let pts: Vec<P2> = (0..=10)
            .map(|k| c.at(-half + 2.0 * half * f64::from(k) / 10.0))
            .collect();
        let expect = 20.0 * (1.0 - half.cos());
        assert!((c.sagitta(&pts) - expect).abs() < 1e-12);
        assert!((expect - 0.009).abs() < 1e-4);
        // Three quarters of a turn: the widest gap is the missing quarter.
        let d = Circle {
            center: [1.0, 2.0],
            radius: 0.5,
        };
        let pts: Vec<P2> = (0..=30)
            .map(|k| d.at(std::f64::consts::PI * 1.5 * f64::from(k) / 30.0))
            .collect();
        let expect = 0.5 * (1.0 - (std::f64::consts::PI * 0.75).cos());
        assert!((d.sagitta(&pts) - expect).abs() < 1e-9);
    }
}
