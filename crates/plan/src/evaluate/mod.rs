//! Scores a floor plan against ground truth: area IoU, boundary distance, completeness,
//! watertightness, arc radius error, and floor and ceiling heights.
//!
//! Plan and truth may have different local origins (a PLY reader picks its own); everything is
//! compared in the truth's local frame.

mod area;
mod distance;
pub mod rooms;
mod watertight;
pub mod windows;

use serde::Serialize;

use crate::geom::{self, P2};
use crate::plan::{FloorPlan, Polygon, StoryPlan, WallModel};
use crate::simulate::truth::{Truth, TruthStory, TruthWall};

pub use area::{area, iou};
pub use watertight::watertight;

use area::rings;
use distance::{boundary_distances, completeness, stats};

/// How finely to measure.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EvaluateParams {
    /// Scanline spacing for the area IoU, metres (x is exact along each scanline).
    pub scanline: f64,
    /// Spacing of the points sampled along boundaries and walls, metres.
    pub step: f64,
    /// A truth wall point is covered when the plan boundary passes within this, metres.
    pub completeness_tolerance: f64,
    /// Truth arcs at least this large must come back as arcs, metres.
    pub min_arc_radius: f64,
    /// A plan story matches a truth story when their floors are this close, metres.
    pub story_tolerance: f64,
}

impl Default for EvaluateParams {
    fn default() -> Self {
        EvaluateParams {
            scanline: 0.005,
            step: 0.01,
            completeness_tolerance: 0.05,
            min_arc_radius: 1.0,
            story_tolerance: 1.0,
        }
    }
}

/// How one truth arc came back.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArcScore {
    /// The truth arc's centre.
    pub center: P2,
    /// The truth arc's radius, metres.
    pub radius: f64,
    /// The closest plan arc's radius, `None` when the plan has no arc there.
    pub plan_radius: Option<f64>,
    /// |plan - truth| / truth radius.
    pub relative_error: Option<f64>,
}

/// The scores of one truth story.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StoryScore {
    /// The truth story's level.
    pub level: usize,
    /// The matched plan story's level, `None` when the plan has no story at this height.
    pub plan_level: Option<usize>,
    /// Floor height error against the truth, metres.
    pub floor_error: f64,
    /// Ceiling height error against the truth, metres.
    pub ceiling_error: f64,
    /// Intersection over union of the open floor areas.
    pub iou: f64,
    /// The truth's open floor area, m².
    pub truth_area: f64,
    /// The plan's open floor area, m².
    pub plan_area: f64,
    /// Distance from the plan's boundary to the truth's walls: mean and 95th percentile, metres.
    pub boundary_mean: f64,
    /// 95th percentile of that distance, metres.
    pub boundary_p95: f64,
    /// The largest such distance, metres.
    pub boundary_max: f64,
    /// Fraction of truth wall length with plan boundary within the tolerance.
    pub completeness: f64,
    /// `None` when every ring is closed and nothing intersects; else the first problem.
    pub watertight_problem: Option<String>,
    /// Arcs of radius at least `min_arc_radius`.
    pub arcs: Vec<ArcScore>,
    /// Rooms, doors and wall thickness; `None` when the truth gives no rooms.
    pub rooms: Option<rooms::RoomsScore>,
    /// Windows; `None` when neither the truth nor the plan has any.
    pub windows: Option<windows::WindowsScore>,
}

impl StoryScore {
    /// The largest arc radius error, infinite when an arc was not found.
    pub fn worst_arc_error(&self) -> f64 {
        self.arcs
            .iter()
            .map(|a| a.relative_error.unwrap_or(f64::INFINITY))
            .fold(0.0, f64::max)
    }
}

/// A whole plan's scores: one per truth story, and what the plan has beyond the truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Evaluation {
    /// One score per truth story, in level order.
    pub stories: Vec<StoryScore>,
    /// Plan stories that match no truth story.
    pub extra_stories: usize,
}

impl Evaluation {
    /// The smallest IoU of any story.
    pub fn min_iou(&self) -> f64 {
        self.stories.iter().map(|s| s.iou).fold(1.0, f64::min)
    }
    /// The largest 95th-percentile boundary distance of any story.
    pub fn max_boundary_p95(&self) -> f64 {
        self.stories
            .iter()
            .map(|s| s.boundary_p95)
            .fold(0.0, f64::max)
    }
    /// The smallest completeness of any story.
    pub fn min_completeness(&self) -> f64 {
        self.stories
            .iter()
            .map(|s| s.completeness)
            .fold(1.0, f64::min)
    }
    /// The largest floor or ceiling height error of any story.
    pub fn max_height_error(&self) -> f64 {
        self.stories
            .iter()
            .map(|s| s.floor_error.max(s.ceiling_error))
            .fold(0.0, f64::max)
    }
    /// True when every truth story has a plan story and none has a watertightness problem.
    pub fn all_watertight(&self) -> bool {
        self.stories
            .iter()
            .all(|s| s.plan_level.is_some() && s.watertight_problem.is_none())
    }
    /// The largest arc radius error of any story, infinite when an arc was not found.
    pub fn worst_arc_error(&self) -> f64 {
        self.stories
            .iter()
            .map(StoryScore::worst_arc_error)
            .fold(0.0, f64::max)
    }

    /// One line per story, for test failures and reports.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        for st in &self.stories {
            s.push_str(&format!(
                "level {}: IoU {:.4}, boundary mean {:.4} p95 {:.4} max {:.3} m, completeness {:.3}, floor err {:.3}, ceiling err {:.3}, area {:.2}/{:.2} m², watertight {}, worst arc err {:.4}\n",
                st.level,
                st.iou,
                st.boundary_mean,
                st.boundary_p95,
                st.boundary_max,
                st.completeness,
                st.floor_error,
                st.ceiling_error,
                st.plan_area,
                st.truth_area,
                st.watertight_problem.as_deref().unwrap_or("yes"),
                st.worst_arc_error(),
            ));
        }
        for st in &self.stories {
            if let Some(r) = &st.rooms {
                s.push_str(&format!("level {} {}\n", st.level, r.summary()));
            }
            if let Some(w) = &st.windows {
                s.push_str(&format!("level {} {}\n", st.level, w.summary()));
            }
        }
        s.push_str(&format!("extra plan stories: {}\n", self.extra_stories));
        s
    }
}

/// Scores `plan` against `truth`.
pub fn evaluate(plan: &FloorPlan, truth: &Truth, params: &EvaluateParams) -> Evaluation {
    let shift = [
        plan.origin[0] - truth.origin[0],
        plan.origin[1] - truth.origin[1],
        plan.origin[2] - truth.origin[2],
    ];
    let mut used = vec![false; plan.stories.len()];
    let stories = truth
        .stories
        .iter()
        .map(|t| {
            // By floor height; a plan story whose floor was not seen (and was assumed higher,
            // within the truth story) is matched by its ceiling.
            let within = |p: &StoryPlan| (t.floor_z..t.ceiling_z).contains(&(p.floor_z + shift[2]));
            let nearest = |by_ceiling: bool| {
                plan.stories
                    .iter()
                    .enumerate()
                    .filter(|(k, p)| !used[*k] && (!by_ceiling || within(p)))
                    .map(|(k, p)| {
                        let e = match by_ceiling {
                            false => p.floor_z + shift[2] - t.floor_z,
                            true => p.ceiling_z + shift[2] - t.ceiling_z,
                        };
                        (k, e.abs())
                    })
                    .filter(|&(_, e)| e <= params.story_tolerance)
                    .min_by(|a, b| a.1.total_cmp(&b.1))
            };
            let matched = nearest(false).or_else(|| nearest(true));
            match matched {
                Some((k, _)) => {
                    used[k] = true;
                    let local = moved(&plan.stories[k], shift);
                    score_story(&local, t, params)
                }
                None => missing_story(t, params),
            }
        })
        .collect();
    Evaluation {
        stories,
        extra_stories: used.iter().filter(|u| !**u).count(),
    }
}

/// The plan story in the truth's frame.
fn moved(s: &StoryPlan, shift: [f64; 3]) -> StoryPlan {
    let m = |p: &P2| [p[0] + shift[0], p[1] + shift[1]];
    let ring = |r: &Vec<P2>| r.iter().map(m).collect::<Vec<_>>();
    StoryPlan {
        level: s.level,
        floor_z: s.floor_z + shift[2],
        ceiling_z: s.ceiling_z + shift[2],
        polygons: s
            .polygons
            .iter()
            .map(|p| Polygon {
                exterior: ring(&p.exterior),
                holes: p.holes.iter().map(ring).collect(),
            })
            .collect(),
        walls: s
            .walls
            .iter()
            .map(|w| crate::plan::Wall {
                model: match w.model {
                    WallModel::Arc { center, radius } => WallModel::Arc {
                        center: m(&center),
                        radius,
                    },
                    WallModel::Line => WallModel::Line,
                },
                points: ring(&w.points),
                support: w.support,
            })
            .collect(),
        samples: Vec::new(),
        spaces: moved_spaces(&s.spaces, m),
        underlay: None,
    }
}

/// The spaces moved by `m`.
fn moved_spaces(s: &crate::plan::Spaces, m: impl Fn(&P2) -> P2) -> crate::plan::Spaces {
    let mut out = s.clone();
    let ring = |r: &mut Vec<P2>| r.iter_mut().for_each(|p| *p = m(p));
    for r in &mut out.rooms {
        ring(&mut r.polygon.exterior);
        r.polygon.holes.iter_mut().for_each(ring);
    }
    for d in &mut out.doors {
        (d.a, d.b) = (m(&d.a), m(&d.b));
    }
    for w in &mut out.windows {
        (w.a, w.b) = (m(&w.a), m(&w.b));
    }
    for w in &mut out.walls {
        (w.a, w.b) = (m(&w.a), m(&w.b));
    }
    out
}

fn missing_story(t: &TruthStory, params: &EvaluateParams) -> StoryScore {
    StoryScore {
        level: t.level,
        plan_level: None,
        floor_error: f64::INFINITY,
        ceiling_error: f64::INFINITY,
        iou: 0.0,
        truth_area: area(&t.polygons),
        plan_area: 0.0,
        boundary_mean: f64::INFINITY,
        boundary_p95: f64::INFINITY,
        boundary_max: f64::INFINITY,
        completeness: 0.0,
        watertight_problem: Some("no plan story at this height".into()),
        arcs: truth_arcs(t, params)
            .map(|(center, radius)| ArcScore {
                center,
                radius,
                plan_radius: None,
                relative_error: None,
            })
            .collect(),
        rooms: None,
        windows: None,
    }
}

fn score_story(p: &StoryPlan, t: &TruthStory, params: &EvaluateParams) -> StoryScore {
    let plan_rings = rings(&p.polygons);
    let distances = boundary_distances(&plan_rings, &t.walls, params.step);
    let (mean, p95, max) = stats(distances);
    StoryScore {
        level: t.level,
        plan_level: Some(p.level),
        floor_error: (p.floor_z - t.floor_z).abs(),
        ceiling_error: (p.ceiling_z - t.ceiling_z).abs(),
        iou: iou(&p.polygons, &t.polygons, params.scanline),
        truth_area: area(&t.polygons),
        plan_area: area(&p.polygons),
        boundary_mean: mean,
        boundary_p95: p95,
        boundary_max: max,
        completeness: completeness(&plan_rings, &t.walls, params),
        watertight_problem: watertight(&p.polygons).err(),
        arcs: truth_arcs(t, params)
            .map(|(center, radius)| arc_score(p, center, radius))
            .collect(),
        rooms: rooms::score_rooms(p, t, params.scanline),
        windows: windows::score_windows(p, t),
    }
}

fn truth_arcs<'a>(
    t: &'a TruthStory,
    params: &'a EvaluateParams,
) -> impl Iterator<Item = (P2, f64)> + 'a {
    t.walls.iter().filter_map(move |w| match *w {
        TruthWall::Arc { center, radius, .. } if radius >= params.min_arc_radius => {
            Some((center, radius))
        }
        _ => None,
    })
}

fn arc_score(p: &StoryPlan, center: P2, radius: f64) -> ArcScore {
    let best = p
        .walls
        .iter()
        .filter_map(|w| match w.model {
            WallModel::Arc {
                center: c,
                radius: r,
            } if geom::dist(c, center) <= 0.25 * radius => Some(r),
            _ => None,
        })
        .min_by(|a, b| (a - radius).abs().total_cmp(&(b - radius).abs()));
    ArcScore {
        center,
        radius,
        plan_radius: best,
        relative_error: best.map(|r| (r - radius).abs() / radius),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x: f64, y: f64, s: f64) -> Polygon {
        Polygon {
            exterior: vec![[x, y], [x + s, y], [x + s, y + s], [x, y + s]],
            holes: Vec::new(),
        }
    }

    fn walls_of(p: &Polygon) -> Vec<TruthWall> {
        let r = &p.exterior;
        (0..r.len())
            .map(|k| TruthWall::Line {
                a: r[k],
                b: r[(k + 1) % r.len()],
            })
            .collect()
    }

    fn plan_of(p: Polygon, origin: [f64; 3]) -> FloorPlan {
        FloorPlan {
            origin,
            crs: None,
            georeference: None,
            input: Default::default(),
            parameters: serde_json::Value::Null,
            timings_ms: Vec::new(),
            stories: vec![StoryPlan {
                level: 0,
                floor_z: 0.0,
                ceiling_z: 2.5,
                polygons: vec![p],
                walls: Vec::new(),
                samples: Vec::new(),
                spaces: Default::default(),
                underlay: None,
            }],
            notes: Vec::new(),
        }
    }

    fn truth_of(p: Polygon) -> Truth {
        Truth {
            building: "test".into(),
            origin: [0.0; 3],
            stories: vec![TruthStory {
                level: 0,
                floor_z: 0.0,
                ceiling_z: 2.5,
                walls: walls_of(&p),
                polygons: vec![p],
                rooms: Vec::new(),
                doors: Vec::new(),
                windows: Vec::new(),
            }],
        }
    }

    #[test]
    fn identical_polygons_score_perfectly() {
        let sq = square(0.0, 0.0, 4.0);
        let e = evaluate(
            &plan_of(sq.clone(), [0.0; 3]),
            &truth_of(sq),
            &EvaluateParams::default(),
        );
        let s = &e.stories[0];
        assert!((s.iou - 1.0).abs() < 1e-12, "{}", e.summary());
        assert!(s.boundary_p95 < 1e-12);
        assert_eq!(s.completeness, 1.0);
        assert!(e.all_watertight());
        assert_eq!(s.floor_error, 0.0);
    }

    #[test]
    fn a_square_shifted_by_10_cm() {
        // 4 × 4 vs the same moved 0.1 in x: intersection 3.9 × 4, union 4.1 × 4.
        let truth = truth_of(square(0.0, 0.0, 4.0));
        let plan = plan_of(square(0.1, 0.0, 4.0), [0.0; 3]);
        let e = evaluate(&plan, &truth, &EvaluateParams::default());
        let s = &e.stories[0];
        assert!((s.iou - 3.9 / 4.1).abs() < 1e-9, "{}", s.iou);
        // The shifted left and right sides are 0.1 away; top and bottom lie on the truth's.
        assert!((s.boundary_p95 - 0.1).abs() < 1e-9, "{}", s.boundary_p95);
        assert!((s.boundary_max - 0.1).abs() < 1e-9);
        // Covered truth: the bottom and top walls except their first 5 cm (3.95 m each), and
        // the right wall's last 5 cm at each end, where the plan's top and bottom pass by.
        assert!(
            (s.completeness - 8.0 / 16.0).abs() < 0.002,
            "{}",
            s.completeness
        );
    }

    #[test]
    fn origins_are_reconciled() {
        let truth = truth_of(square(0.0, 0.0, 4.0));
        let plan = plan_of(square(-1000.0, -2000.0, 4.0), [1000.0, 2000.0, 0.0]);
        let e = evaluate(&plan, &truth, &EvaluateParams::default());
        assert!((e.stories[0].iou - 1.0).abs() < 1e-12);
    }

    #[test]
    fn holes_reduce_area_and_iou() {
        let mut p = square(0.0, 0.0, 4.0);
        p.holes
            .push(vec![[1.0, 1.0], [1.0, 3.0], [3.0, 3.0], [3.0, 1.0]]);
        let truth = truth_of(square(0.0, 0.0, 4.0));
        let e = evaluate(&plan_of(p, [0.0; 3]), &truth, &EvaluateParams::default());
        assert!((e.stories[0].iou - 12.0 / 16.0).abs() < 1e-9);
        assert!((e.stories[0].plan_area - 12.0).abs() < 1e-12);
        assert!(e.all_watertight());
    }

    #[test]
    fn self_intersections_and_degenerate_rings_are_found() {
        let bow = Polygon {
            exterior: vec![[0.0, 0.0], [2.0, 2.0], [2.0, 0.0], [0.0, 2.0]],
            holes: Vec::new(),
        };
        assert!(watertight(&[bow]).is_err());
        let line = Polygon {
            exterior: vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]],
            holes: Vec::new(),
        };
        assert!(watertight(&[line]).is_err());
        let mut outside_hole = square(0.0, 0.0, 1.0);
        outside_hole
            .holes
            .push(vec![[5.0, 5.0], [5.0, 6.0], [6.0, 6.0]]);
        assert!(watertight(&[outside_hole]).is_err());
        // A hole touching its exterior at one point, first there, is inside (OGC valid).
        let mut touching = square(0.0, 0.0, 4.0);
        touching
            .holes
            .push(vec![[2.0, 0.0], [3.0, 1.0], [1.0, 1.0]]);
        assert_eq!(watertight(&[touching]), Ok(()));
        // Two squares sharing one corner are fine; a closed repeated vertex is tolerated.
        let mut closed = square(0.0, 0.0, 1.0);
        closed.exterior.push([0.0, 0.0]);
        assert_eq!(watertight(&[closed, square(1.0, 1.0, 1.0)]), Ok(()));
        // Overlapping polygons are not.
        assert!(watertight(&[square(0.0, 0.0, 2.0), square(1.0, 1.0, 2.0)]).is_err());
    }

    #[test]
    fn arc_radius_error_and_missing_story() {
        let arc = TruthWall::Arc {
            center: [0.0, 0.0],
            radius: 10.0,
            start: 0.0,
            sweep: 1.0,
        };
        let mut truth = truth_of(square(0.0, 0.0, 4.0));
        truth.stories[0].walls.push(arc);
        let mut plan = plan_of(square(0.0, 0.0, 4.0), [0.0; 3]);
        plan.stories[0].walls.push(crate::plan::Wall {
            model: WallModel::Arc {
                center: [0.05, 0.0],
                radius: 10.1,
            },
            points: vec![],
            support: 10,
        });
        let e = evaluate(&plan, &truth, &EvaluateParams::default());
        assert!((e.worst_arc_error() - 0.01).abs() < 1e-12);
        plan.stories[0].floor_z = 3.0;
        let e = evaluate(&plan, &truth, &EvaluateParams::default());
        assert_eq!(e.stories[0].plan_level, None);
        assert_eq!(e.extra_stories, 1);
        assert!(!e.all_watertight());
        assert_eq!(e.worst_arc_error(), f64::INFINITY);
    }
}
