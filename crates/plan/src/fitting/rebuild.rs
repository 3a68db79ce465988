//! Rebuilding a traced ring from its models (§3.5): runs of samples on one model become edges
//! exactly on the model, neighbouring runs meet at sharp corners (line-line, line-circle or
//! circle-circle intersections), and arcs are densified to a chord error.

use std::f64::consts::{PI, TAU};

use crate::fitting::model::Model;
use crate::fitting::FittingParams;
use crate::geom::{self, P2};
use crate::plan::Wall;

/// A stretch of a ring: consecutive ring positions on one model, or one traced vertex.
#[derive(Debug, Clone, PartialEq)]
pub struct Piece {
    pub model: Option<usize>,
    pub positions: Vec<usize>,
}

/// A rebuilt ring with the provenance the validity repair needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Rebuilt {
    pub points: Vec<P2>,
    /// For each point, the piece that emitted it.
    pub piece_of_point: Vec<usize>,
    pub pieces: Vec<Piece>,
    pub walls: Vec<Wall>,
}

/// Largest angular step for an arc of radius `r` whose chords stray at most `chord_error`.
fn arc_step(r: f64, chord_error: f64) -> f64 {
    if chord_error >= r {
        return PI / 4.0;
    }
    (2.0 * (1.0 - chord_error / r).acos()).clamp(1e-4, PI / 4.0)
}

/// Wraps an angle difference into (−π, π].
fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(TAU);
    if w > PI {
        w - TAU
    } else {
        w
    }
}

/// Points of an arc from `start` to `end` that passes through `via` (in order), both ends
/// included.
fn arc_points(
    c: &crate::fitting::circle::Circle,
    start: P2,
    via: &[P2],
    end: P2,
    chord: f64,
) -> Vec<P2> {
    let mut sweep = 0.0;
    let mut prev = c.angle(start);
    for p in via.iter().chain(std::iter::once(&end)) {
        let a = c.angle(*p);
        sweep += wrap(a - prev);
        prev = a;
    }
    let a0 = c.angle(start);
    let steps = (sweep.abs() / arc_step(c.radius, chord)).ceil().max(1.0) as usize;
    let mut pts: Vec<P2> = (0..=steps)
        .map(|k| c.at(a0 + sweep * k as f64 / steps as f64))
        .collect();
    pts[0] = start;
    pts[steps] = end;
    pts
}

/// Whether the region between two runs and their models' meeting point holds no wall sample:
/// `empty(u, c, v)` for the triangle from the end `u` of one run through the corner `c` to the
/// start `v` of the next.
pub type EmptyCorner<'a> = &'a dyn Fn(P2, P2, P2) -> bool;

/// The way a run travels, from its first sample to its last (zero for a single sample).
fn run_direction(pos: &[P2], piece: &Piece) -> P2 {
    let (first, last) = (piece.positions[0], *piece.positions.last().unwrap_or(&0));
    geom::sub(pos[last], pos[first])
}

/// Rebuilds one ring. `pos[i]` is the traced position of ring vertex `i` and `assigned[i]` its
/// model. A ring whose samples all lie on one line is left as traced. Two runs whose models meet
/// farther than `max_corner_distance` from their ends still meet there when the meeting point
/// is within `max_open_corner` and `empty` says no sample lies in the corner they would add or
/// cut: a sparsely seen wall whose last samples stop short of the corner.
pub fn rebuild_ring(
    pos: &[P2],
    assigned: &[Option<usize>],
    models: &[Model],
    params: &FittingParams,
    empty: EmptyCorner<'_>,
) -> Rebuilt {
    let m = pos.len();
    let traced = || Rebuilt {
        points: pos.to_vec(),
        piece_of_point: (0..m).collect(),
        pieces: (0..m)
            .map(|i| Piece {
                model: None,
                positions: vec![i],
            })
            .collect(),
        walls: Vec::new(),
    };
    let first = assigned.first().copied().flatten();
    if m == 0 || assigned.iter().all(|a| a.is_none()) {
        return traced();
    }
    if assigned.iter().all(|a| *a == first) {
        let k = first.unwrap_or(0);
        let Model::Circle(c) = models[k] else {
            return traced();
        };
        // A whole ring on one circle: a round column or room, traced in the ring's direction.
        let sweep = TAU * geom::ring_signed_area(pos).signum();
        let steps = (TAU / arc_step(c.radius, params.arc_chord_error))
            .ceil()
            .max(8.0) as usize;
        let a0 = c.angle(pos[0]);
        let mut points: Vec<P2> = (0..=steps)
            .map(|i| c.at(a0 + sweep * i as f64 / steps as f64))
            .collect();
        let wall = Wall {
            model: models[k].wall_model(),
            points: points.clone(),
            support: m,
        };
        points.pop();
        return Rebuilt {
            piece_of_point: vec![0; points.len()],
            points,
            pieces: vec![Piece {
                model: first,
                positions: (0..m).collect(),
            }],
            walls: vec![wall],
        };
    }
    // Start at a break so that no run wraps around the end of the list.
    let start = (0..m)
        .find(|&i| assigned[i].is_none() || assigned[i] != assigned[(i + m - 1) % m])
        .unwrap_or(0);
    let mut pieces: Vec<Piece> = Vec::new();
    for k in 0..m {
        let i = (start + k) % m;
        match pieces.last_mut() {
            Some(p) if p.model.is_some() && p.model == assigned[i] => p.positions.push(i),
            _ => pieces.push(Piece {
                model: assigned[i],
                positions: vec![i],
            }),
        }
    }
    let np = pieces.len();
    // corner[j]: where piece j meets piece j + 1, when both are runs whose models meet nearby.
    let corner: Vec<Option<P2>> = (0..np)
        .map(|j| {
            let (p, q) = (&pieces[j], &pieces[(j + 1) % np]);
            let (Some(a), Some(b)) = (p.model, q.model) else {
                return None;
            };
            if a == b {
                return None;
            }
            let (u, v) = (pos[*p.positions.last()?], pos[q.positions[0]]);
            let mid = geom::scale(geom::add(u, v), 0.5);
            let meets = models[a].intersections(&models[b]);
            let nearest = |limit: f64, ok: &dyn Fn(P2) -> bool| {
                meets
                    .iter()
                    .copied()
                    .filter(|&c| geom::dist(c, u) <= limit && geom::dist(c, v) <= limit && ok(c))
                    .min_by(|x, y| geom::dist(*x, mid).total_cmp(&geom::dist(*y, mid)))
            };
            let lines = matches!(models[a], Model::Line(_)) && matches!(models[b], Model::Line(_));
            nearest(params.max_corner_distance, &|_| true).or_else(|| {
                // An open corner: the runs must run on into it (no run turns back), and it
                // must add or cut only empty floor. Only two straight walls run on into one:
                // an arc carried that far leaves its samples behind (a door swing's chord
                // crossing a room).
                let (pu, qv) = (run_direction(pos, p), run_direction(pos, q));
                if !lines {
                    return None;
                }
                nearest(params.max_open_corner, &|c| {
                    geom::dot(geom::sub(c, u), pu) > 0.0
                        && geom::dot(geom::sub(v, c), qv) > 0.0
                        && empty(u, c, v)
                })
            })
        })
        .collect();
    let mut points: Vec<P2> = Vec::new();
    let mut piece_of_point = Vec::new();
    let mut walls = Vec::new();
    for (j, piece) in pieces.iter().enumerate() {
        let line: Vec<P2> = match piece.model {
            None => vec![pos[piece.positions[0]]],
            Some(k) => {
                let model = &models[k];
                let first = pos[piece.positions[0]];
                let last = pos[*piece.positions.last().unwrap_or(&0)];
                let s = corner[(j + np - 1) % np].unwrap_or_else(|| model.project(first));
                let e = corner[j].unwrap_or_else(|| model.project(last));
                let line = match model {
                    Model::Line(_) => vec![s, e],
                    Model::Circle(c) => {
                        let via: Vec<P2> = piece.positions.iter().map(|&i| pos[i]).collect();
                        arc_points(c, s, &via, e, params.arc_chord_error)
                    }
                };
                // A run that shrank to a point (one sample, no corners) is no wall.
                if line.windows(2).any(|w| w[0] != w[1]) {
                    walls.push(Wall {
                        model: model.wall_model(),
                        points: line.clone(),
                        support: piece.positions.len(),
                    });
                }
                line
            }
        };
        for p in line {
            if points.last() != Some(&p) {
                points.push(p);
                piece_of_point.push(j);
            }
        }
    }
    while points.len() > 1 && points.last() == points.first() {
        points.pop();
        piece_of_point.pop();
    }
    Rebuilt {
        points,
        piece_of_point,
        pieces,
        walls,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fitting::circle::Circle;
    use crate::fitting::line::Line;

    #[test]
    fn cut_corner_becomes_sharp() {
        // Samples along y = 0 then x = 1, the corner itself unsampled.
        let pos = vec![
            [0.0, 0.0],
            [0.5, 0.0],
            [0.9, 0.0],
            [1.0, 0.1],
            [1.0, 0.5],
            [1.0, 1.0],
        ];
        let a = Model::Line(Line {
            point: [0.0, 0.0],
            dir: [1.0, 0.0],
        });
        let b = Model::Line(Line {
            point: [1.0, 0.0],
            dir: [0.0, 1.0],
        });
        let assigned = [Some(0), Some(0), Some(0), Some(1), Some(1), None];
        let r = rebuild_ring(
            &pos,
            &assigned,
            &[a, b],
            &FittingParams::default(),
            &|_, _, _| true,
        );
        assert_eq!(
            r.points,
            vec![[0.0, 0.0], [1.0, 0.0], [1.0, 0.5], [1.0, 1.0]]
        );
        assert_eq!(r.walls.len(), 2);
        assert_eq!(r.walls[0].points, vec![[0.0, 0.0], [1.0, 0.0]]);
        assert_eq!(r.walls[1].points, vec![[1.0, 0.0], [1.0, 0.5]]);
        assert_eq!(r.walls[0].support, 3);
    }

    #[test]
    fn arc_is_densified_within_the_chord_error() {
        let c = Circle {
            center: [0.0, 0.0],
            radius: 5.0,
        };
        let pts = arc_points(&c, [5.0, 0.0], &[[0.0, 5.0]], [-5.0, 0.0], 0.01);
        for w in pts.windows(2) {
            let mid = geom::scale(geom::add(w[0], w[1]), 0.5);
            assert!(c.radius - geom::norm(mid) <= 0.01 + 1e-12);
            assert!(w[0][1] >= -1e-12, "the arc goes the wrong way round");
        }
        assert!(pts.len() > 10);
        assert_eq!(*pts.last().unwrap(), [-5.0, 0.0]);
    }
}
