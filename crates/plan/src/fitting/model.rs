//! A wall model: a line or a circle, with the operations RANSAC and the rebuild need.

use crate::fitting::circle::Circle;
use crate::fitting::line::Line;
use crate::geom::{self, P2};
use crate::plan::WallModel;

/// A fitted wall model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Model {
    Line(Line),
    Circle(Circle),
}

impl Model {
    /// Unsigned distance from `p` to the model.
    pub fn distance(&self, p: P2) -> f64 {
        match self {
            Model::Line(l) => l.distance(p),
            Model::Circle(c) => c.distance(p),
        }
    }

    /// The model's unit normal near `p` (its sign is not meaningful).
    pub fn normal_at(&self, p: P2) -> P2 {
        match self {
            Model::Line(l) => l.normal(),
            Model::Circle(c) => c.normal_at(p),
        }
    }

    /// The nearest point of the model.
    pub fn project(&self, p: P2) -> P2 {
        match self {
            Model::Line(l) => l.project(p),
            Model::Circle(c) => c.project(p),
        }
    }

    /// True when `p` (with unit normal `n`, if known) is an inlier: within `max_dist` of the
    /// model and with a normal within `min_cos` (a cosine) of the model's (§3.5). `side` (±1)
    /// orients the model's normal. Beyond the paper: sample normals point into the open side
    /// of the boundary, so the two faces of a thin wall, which face opposite ways, never share
    /// a model, however close they are.
    pub fn accepts(&self, p: P2, n: Option<P2>, max_dist: f64, min_cos: f64, side: f64) -> bool {
        self.distance(p) <= max_dist
            && n.is_none_or(|n| side * geom::dot(n, self.normal_at(p)) >= min_cos)
    }

    /// The orientation (±1) of the model's normal that most of the oriented normals of
    /// `points` agree with; +1 when none has a normal.
    pub fn side_of(&self, points: impl IntoIterator<Item = (P2, Option<P2>)>) -> f64 {
        let sum: f64 = points
            .into_iter()
            .filter_map(|(p, n)| n.map(|n| geom::dot(n, self.normal_at(p))))
            .sum();
        if sum < 0.0 {
            -1.0
        } else {
            1.0
        }
    }

    /// Points where two models meet.
    pub fn intersections(&self, other: &Model) -> Vec<P2> {
        match (self, other) {
            (Model::Line(a), Model::Line(b)) => a.intersect(b).into_iter().collect(),
            (Model::Line(l), Model::Circle(c)) | (Model::Circle(c), Model::Line(l)) => {
                c.intersect_line(l)
            }
            (Model::Circle(a), Model::Circle(b)) => a.intersect_circle(b),
        }
    }

    /// The least-squares model of the same kind through `points`.
    pub fn refit(&self, points: &[P2]) -> Option<Model> {
        match self {
            Model::Line(_) => Line::fit(points).map(Model::Line),
            Model::Circle(_) => Circle::fit(points).map(Model::Circle),
        }
    }

    /// The model as reported in the plan.
    pub fn wall_model(&self) -> WallModel {
        match self {
            Model::Line(_) => WallModel::Line,
            Model::Circle(c) => WallModel::Arc {
                center: c.center,
                radius: c.radius,
            },
        }
    }
}
