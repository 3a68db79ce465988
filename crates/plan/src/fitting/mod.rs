//! Stage 6 (§3.5): RANSAC lines and circles fitted to the boundary samples, and the boundary
//! rebuilt from the models with sharp corners.
//!
//! The steps: [`ransac`] finds the models (scoring each candidate only on the samples its
//! inlier band crosses, through `index`), `grow` resets small components and grows models
//! along the boundary, `rebuild` replaces each ring's runs with edges on their models, and
//! `simple` finds where the result is not valid. Where rebuilt edges cross (a corner placed
//! past a neighbour, the two faces of a thin wall fitted leaning into each other), the crossing
//! becomes a corner and the region the walls enclose counter-clockwise is kept
//! ([`crate::validity::resolve`]); the repair is noted. The traced staircase is never put back.

pub(crate) mod circle;
pub(crate) mod grow;
pub(crate) mod index;
pub(crate) mod line;
pub(crate) mod model;
pub mod ransac;
pub(crate) mod rebuild;
pub(crate) mod simple;

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use crate::boundary::Boundary;
use crate::cancel::{Cancel, Cancelled};
use crate::geom::{self, P2};
use crate::labeling::LabeledMesh;
use crate::params::{within, ParamRange};
use crate::plan::{Polygon, Wall};
use crate::validity::{self, Grid};

/// Parameters of [`fit_walls`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FittingParams {
    /// Inlier distance threshold, metres (§3.5 leaves it open; about half d_s). Range 0.001..=1.
    pub inlier_distance: f64,
    /// Inlier normal angle threshold, radians (§3.5 leaves it open). Range 0.01..=π/2.
    pub inlier_angle: f64,
    /// Minimum inliers for a model (§3.5: "a specified minimum number of inliers").
    /// Range 3..=1000.
    pub min_inliers: usize,
    /// Connected components of a model with fewer samples are reset (§3.5: 15). Range 0..=1000.
    pub min_component: usize,
    /// A smaller component is kept when it has at least this many samples, none farther than
    /// six inlier distances from the next, and the boundary turns just past both its ends: the
    /// face of a short stub of wall between two corners, beside a closet door. Beyond the
    /// paper; 0 keeps none. Range 0..=1000.
    pub min_stub_component: usize,
    /// Unassigned samples within this many boundary hops join the nearest model (§3.5: 15).
    /// Range 0..=200.
    pub grow_hops: usize,
    /// RANSAC iterations per model search (an upper bound; the search stops early once the
    /// best model is found with 99% confidence). Range 1..=100000.
    pub iterations: usize,
    /// Fit circles as well as lines (§3.5).
    pub circles: bool,
    /// Circles larger than this are treated as lines, metres. Range 0.01..=1000.
    pub max_radius: f64,
    /// An arc that bows less than this from its chord over its inliers becomes a line, metres.
    /// Beyond the paper (which keeps whichever model has more inliers): on the real apartment,
    /// short straight walls came out as 5 m and 21 m arcs bowing 1 to 2 cm, within the inlier band.
    /// Range 0..=1.
    pub min_arc_sagitta: f64,
    /// Two neighbouring models meet at their intersection only when it lies within this
    /// distance of both runs' end samples, metres (§3.5 "sharp corners"; the limit is ours).
    /// Range 0..=10.
    pub max_corner_distance: f64,
    /// Beyond that distance, two runs still meet at their models' intersection when it lies
    /// within this many metres and no wall sample lies in the corner it adds or cuts, metres.
    /// Beyond the paper: a wall seen sparsely stops short of the corner, and the traced
    /// boundary crosses the room diagonally there. 0 turns it off. Range 0..=20.
    pub max_open_corner: f64,
    /// Arcs are densified so that chords stray at most this far from the circle, metres.
    /// Range 0.0001..=1.
    pub arc_chord_error: f64,
    /// Random seed, so that runs repeat exactly.
    pub seed: u64,
}

/// The accepted values of [`FittingParams`] (see [`crate::params::ParamRange`]). The counts
/// bound RANSAC's and growing's work per model and per sample; cancellation bounds the rest.
pub const RANGES: &[ParamRange] = &[
    ParamRange::new("inlier_distance", 0.001, 1.0, "m"),
    ParamRange::new("inlier_angle", 0.01, std::f64::consts::FRAC_PI_2, "rad"),
    ParamRange::new("min_inliers", 3.0, 1000.0, ""),
    ParamRange::new("min_component", 0.0, 1000.0, ""),
    ParamRange::new("min_stub_component", 0.0, 1000.0, ""),
    ParamRange::new("grow_hops", 0.0, 200.0, ""),
    ParamRange::new("iterations", 1.0, 100_000.0, ""),
    ParamRange::new("max_radius", 0.01, 1000.0, "m"),
    ParamRange::new("min_arc_sagitta", 0.0, 1.0, "m"),
    ParamRange::new("max_corner_distance", 0.0, 10.0, "m"),
    ParamRange::new("max_open_corner", 0.0, 20.0, "m"),
    ParamRange::new("arc_chord_error", 0.0001, 1.0, "m"),
];

impl Default for FittingParams {
    fn default() -> Self {
        FittingParams {
            inlier_distance: 0.03,
            inlier_angle: 0.35,
            min_inliers: 15,
            min_component: 15,
            min_stub_component: 3,
            grow_hops: 15,
            iterations: 500,
            circles: true,
            max_radius: 30.0,
            min_arc_sagitta: 0.03,
            max_corner_distance: 0.5,
            max_open_corner: 3.0,
            arc_chord_error: 0.01,
            seed: 1,
        }
    }
}

/// The fitted story: watertight polygons (local coordinates) and the walls on their boundary.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FittedStory {
    /// The story's polygons, watertight, local coordinates.
    pub polygons: Vec<Polygon>,
    /// The walls on the polygons' boundary.
    pub walls: Vec<Wall>,
    /// Repairs worth telling the user about (crossings of rebuilt walls resolved).
    pub notes: Vec<String>,
}

/// Why fitting failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FittingError {
    /// A parameter is outside its range.
    #[error("invalid fitting parameter `{name}`: {why}")]
    BadParam {
        /// The parameter's name.
        name: &'static str,
        /// What is wrong.
        why: String,
    },
    /// The run was stopped from outside.
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
}

/// The boundary vertices RANSAC works on, with the boundary edges between them.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundarySamples {
    /// The boundary vertices' positions, local coordinates.
    pub pos: Vec<P2>,
    /// Unit normal, when the sample has one.
    pub normal: Vec<Option<P2>>,
    /// Neighbours along the boundary rings.
    pub adj: Vec<Vec<u32>>,
    /// Whether the normal has been turned towards the open side yet.
    pub oriented: Vec<bool>,
}

impl FittingParams {
    /// Checks every value; the error names the parameter.
    pub fn check(&self) -> Result<(), FittingError> {
        check_params(self)
    }
}

fn check_params(p: &FittingParams) -> Result<(), FittingError> {
    let check = |name, v: f64| {
        within(RANGES, name, v).map_err(|(name, why)| FittingError::BadParam { name, why })
    };
    check("inlier_distance", p.inlier_distance)?;
    check("inlier_angle", p.inlier_angle)?;
    check("min_inliers", p.min_inliers as f64)?;
    check("min_component", p.min_component as f64)?;
    check("min_stub_component", p.min_stub_component as f64)?;
    check("grow_hops", p.grow_hops as f64)?;
    check("iterations", p.iterations as f64)?;
    check("max_radius", p.max_radius)?;
    check("min_arc_sagitta", p.min_arc_sagitta)?;
    check("max_corner_distance", p.max_corner_distance)?;
    check("max_open_corner", p.max_open_corner)?;
    check("arc_chord_error", p.arc_chord_error)
}

/// Random starts tried in all when the fitted walls cross: each search from another seed.
const STARTS: u64 = 4;

/// Fits lines and circles to the boundary and rebuilds it on the models. Where the rebuilt
/// walls cross, RANSAC starts again from the next seed (up to [`STARTS`] in all) while each
/// start crosses fewer times than the last, and the fit with the fewest crossings is kept: a
/// crossing is models disagreeing with the traced boundary, and its repair can join rooms
/// through a sliver (the real apartment's bathroom and bedroom, with one seed in two). Stops
/// with `Cancelled` once `cancel` says so.
pub fn fit_walls(
    labeled: &LabeledMesh,
    boundary: &Boundary,
    params: &FittingParams,
    cancel: &Cancel,
) -> Result<FittedStory, FittingError> {
    check_params(params)?;
    let (samples, rings, exterior_of) = collect_samples(labeled, boundary);
    let first = fit_once(labeled, &samples, &rings, &exterior_of, params, cancel)?;
    let crossings = first.1;
    let mut best = first;
    for k in 1..STARTS {
        if best.1 == 0 {
            break;
        }
        let other = FittingParams {
            seed: params.seed.wrapping_add(k),
            ..params.clone()
        };
        let next = fit_once(labeled, &samples, &rings, &exterior_of, &other, cancel)?;
        // Crossings that another draw does not reduce are in the boundary itself (the faces
        // of a thin partition leaning into each other): more starts only cost time.
        if next.1 >= best.1 {
            break;
        }
        best = next;
    }
    let (mut fitted, left) = best;
    if left < crossings {
        fitted.notes.insert(
            0,
            format!(
                "fitting: the first fit's walls crossed {crossings} time(s); another random start crossed {left}"
            ),
        );
    }
    Ok(fitted)
}

/// One fit from `params.seed`, with the number of crossings and folds its rebuilt rings had.
fn fit_once(
    labeled: &LabeledMesh,
    samples: &BoundarySamples,
    rings: &[Vec<usize>],
    exterior_of: &[Option<usize>],
    params: &FittingParams,
    cancel: &Cancel,
) -> Result<(FittedStory, usize), FittingError> {
    let consensus = ransac::find_models(samples, params, cancel)?;
    let models = consensus.models;
    let mut assigned = consensus.assigned;
    grow::reset_small_components(
        samples,
        &models,
        &mut assigned,
        params.min_component,
        params.min_stub_component,
        params.inlier_distance,
    );
    // A face more than half the inlier band behind a model is another wall face.
    let behind = params.inlier_distance / 2.0;
    grow::grow(
        samples,
        &models,
        &mut assigned,
        params.grow_hops,
        behind,
        cancel,
    )?;

    let ring_pos: Vec<Vec<P2>> = rings
        .iter()
        .map(|r| r.iter().map(|&s| samples.pos[s]).collect())
        .collect();
    let ring_assign: Vec<Vec<Option<usize>>> = rings
        .iter()
        .map(|r| r.iter().map(|&s| assigned[s]).collect())
        .collect();
    let mesh = &labeled.mesh;
    let wall_samples = &mesh.vertices[..mesh.n_samples.min(mesh.vertices.len())];
    let grid = index::SampleGrid::new(wall_samples, 4.0 * params.inlier_distance);
    let margin = params.inlier_distance;
    let empty = |u: P2, c: P2, v: P2| corner_is_empty(&grid, wall_samples, [u, c, v], margin);
    let rebuilt: Vec<rebuild::Rebuilt> = ring_pos
        .iter()
        .zip(&ring_assign)
        .map(|(pos, a)| rebuild::rebuild_ring(pos, a, &models, params, &empty))
        .collect();
    let points: Vec<Vec<P2>> = rebuilt.iter().map(|r| r.points.clone()).collect();
    let problems = simple::problems(&points, exterior_of);
    let mut polygons: Vec<Polygon> = Vec::new();
    for (r, ext) in exterior_of.iter().enumerate() {
        let points = points[r].clone();
        match (ext, polygons.last_mut()) {
            (Some(_), Some(p)) => p.holes.push(points),
            _ => polygons.push(Polygon {
                exterior: points,
                holes: Vec::new(),
            }),
        }
    }
    let mut notes = Vec::new();
    if !problems.is_empty() {
        // Where rebuilt walls cross (or a ring folds over), the crossing points become corners
        // and what the walls enclose counter-clockwise stays inside.
        let at = problem_places(&problems, &points);
        match validity::resolve(&polygons, &Grid::local()) {
            Ok(resolved) => {
                polygons = resolved;
                notes.push(format!(
                    "fitting: {} crossing(s) or fold(s) of fitted walls resolved where they cross, near local {at}",
                    problems.len()
                ));
            }
            Err(why) => notes.push(format!(
                "fitting: {} crossing(s) of fitted walls near local {at} could not be resolved ({why})",
                problems.len()
            )),
        }
    }
    let walls = rebuilt.into_iter().flat_map(|r| r.walls).collect();
    Ok((
        FittedStory {
            polygons,
            walls,
            notes,
        },
        problems.len(),
    ))
}

/// The boundary's vertices as samples, each ring as a list of sample indices, and for each
/// ring the index of its exterior ring (`None` for exteriors). Rings are listed polygon by
/// polygon, exterior first.
fn collect_samples(
    labeled: &LabeledMesh,
    boundary: &Boundary,
) -> (BoundarySamples, Vec<Vec<usize>>, Vec<Option<usize>>) {
    let mesh = &labeled.mesh;
    let mut index: HashMap<u32, usize> = HashMap::new();
    let mut samples = BoundarySamples {
        pos: Vec::new(),
        normal: Vec::new(),
        adj: Vec::new(),
        oriented: Vec::new(),
    };
    let mut rings: Vec<Vec<usize>> = Vec::new();
    let mut exterior_of: Vec<Option<usize>> = Vec::new();
    for poly in &boundary.polygons {
        let ext = rings.len();
        for (j, ring) in std::iter::once(&poly.exterior)
            .chain(&poly.holes)
            .enumerate()
        {
            let ids: Vec<usize> = ring
                .vertices
                .iter()
                .map(|&v| {
                    *index.entry(v).or_insert_with(|| {
                        let p = mesh.vertices.get(v as usize).copied().unwrap_or([0.0; 2]);
                        // Box corners carry no normal.
                        let is_sample = (v as usize) < mesh.n_samples;
                        let n = mesh.normals.get(v as usize).copied();
                        samples.pos.push(p);
                        samples
                            .normal
                            .push(n.filter(|_| is_sample).and_then(geom::normalize));
                        samples.adj.push(Vec::new());
                        samples.oriented.push(false);
                        samples.pos.len() - 1
                    })
                })
                .collect();
            for w in 0..ids.len() {
                let (a, b) = (ids[w], ids[(w + 1) % ids.len()]);
                if a != b && !samples.adj[a].contains(&(b as u32)) {
                    samples.adj[a].push(b as u32);
                    samples.adj[b].push(a as u32);
                }
            }
            orient_normals(&mut samples, &ids);
            rings.push(ids);
            exterior_of.push((j > 0).then_some(ext));
        }
    }
    (samples, rings, exterior_of)
}

/// Turns the normals of a ring's samples towards the open side: traced rings keep the inside
/// on their left, so the left normal of the boundary around each sample points into the room.
/// A sample already oriented by an earlier ring (a pinch vertex) keeps its sign.
fn orient_normals(samples: &mut BoundarySamples, ring: &[usize]) {
    let n = ring.len();
    for k in 0..n {
        let (prev, here, next) = (ring[(k + n - 1) % n], ring[k], ring[(k + 1) % n]);
        if samples.oriented[here] {
            continue;
        }
        let d = geom::sub(samples.pos[next], samples.pos[prev]);
        let left = [-d[1], d[0]];
        if let Some(normal) = samples.normal[here].as_mut() {
            if geom::dot(*normal, left) < 0.0 {
                *normal = geom::scale(*normal, -1.0);
            }
        }
        samples.oriented[here] = true;
    }
}

/// True when no wall sample lies inside triangle `t` farther than `margin` from its sides: the
/// corner a completed wall pair would add or cut holds nothing a scanner saw.
fn corner_is_empty(grid: &index::SampleGrid, samples: &[P2], t: [P2; 3], margin: f64) -> bool {
    let area2 = geom::cross(geom::sub(t[1], t[0]), geom::sub(t[2], t[0]));
    if !area2.is_finite() || area2 == 0.0 {
        return true;
    }
    let sign = area2.signum();
    let mut empty = true;
    grid.in_box(t, |i| {
        let p = samples[i];
        // Signed distances to the three sides, positive inside.
        let inside = (0..3).all(|k| {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let len = geom::dist(a, b).max(1e-12);
            sign * geom::cross(geom::sub(b, a), geom::sub(p, a)) / len > margin
        });
        if inside {
            empty = false;
        }
    });
    empty
}

/// Where the first few problems are, for a note: "(x, y), (x, y), …".
fn problem_places(problems: &[simple::Problem], rings: &[Vec<P2>]) -> String {
    let at: Vec<String> = problems
        .iter()
        .take(5)
        .map(|p| {
            let (r, i) = match *p {
                simple::Problem::Crossing(s, _) => s,
                simple::Problem::BadRing(r) => (r, 0),
                simple::Problem::HoleOutside { hole, .. } => (hole, 0),
            };
            let q = rings[r].get(i).copied().unwrap_or([0.0, 0.0]);
            format!("({:.2}, {:.2})", q[0], q[1])
        })
        .collect();
    format!(
        "{}{}",
        at.join(", "),
        if problems.len() > 5 { ", …" } else { "" }
    )
}

#[cfg(test)]
mod tests;
