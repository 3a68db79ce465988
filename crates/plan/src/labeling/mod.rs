//! Stage 4 (§3.3): Delaunay triangulation of the wall samples and 2D Eigencrust inside/outside
//! labeling. See `shared/design/eigencrust-2d.md` for the derivation.
//!
//! - `mesh`: spade Delaunay of the samples plus four box corners.
//! - `gaps`: vertices filled into short holes of straight rows of samples (beyond the paper).
//! - `backs`: vertices behind faces whose wall shows no other face (beyond the paper).
//! - `faces`: wall faces in the mesh, and lines of sight crossing them from behind (beyond the
//!   paper).
//! - `weights`: poles and the signed edge weights (eq. (1) for adjacent poles).
//! - `walk`: exact straight-line walks (point location, lines of sight, the mobile path).
//! - `constraints`: forced inside/outside triangles.
//! - `spectral`: the constrained pencil, its smallest eigenvector (dense, or shift-invert
//!   Lanczos on one sparse Cholesky factor) and the harmonic solution from the same factor.

mod backs;
mod constraints;
mod faces;
mod gaps;
pub(crate) mod mesh;
mod spectral;
mod walk;
mod weights;

use serde::{Deserialize, Serialize};

pub use mesh::{Mesh, MeshError, NONE};

use crate::cancel::{Cancel, Cancelled};
use crate::params::{within, ParamRange};
use crate::samples::WallSamples;

/// Parameters of [`label`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LabelingParams {
    /// Lines of sight needed to force a triangle inside (§3.3: 10). Range 1..=10000.
    pub min_rays: u32,
    /// The central fraction of each pose→sample segment that counts as a line of sight (§3.3: 50%).
    /// Range 0.01..=1.
    pub ray_fraction: f64,
    /// Beyond the paper: also count the part of each line of sight between the scanner and the
    /// central fraction. That part is open air, and without it the thin triangles radiating
    /// from a scanner are crossed by few counted rays and come out as slits of "outside".
    pub rays_from_scanner: bool,
    /// Beyond the paper: when set, each line of sight runs on to this many metres short of its
    /// sample instead of stopping at the central fraction's far end. A quarter of a 7 m ray is
    /// 1.75 m of floor that no ray would vouch for, which lets sparse far corners fall outside;
    /// a fixed margin of a few cells still keeps rays clear of the wall they end on.
    /// `None` is the paper's central fraction. Range 0..=10.
    pub ray_end_margin: Option<f64>,
    /// Beyond the paper: behind each face whose wall shows no other face, a vertex one typical
    /// wall thickness back (see `backs`), so a room that saw the wall poorly cannot be joined
    /// through it to the room that saw it well. Used only for samples of a mobile scan (its
    /// path known, or `WallSamples::moving`).
    pub wall_backs: bool,
    /// Use only pole pairs that share an edge as negative edges (reading (b) of the design note).
    pub adjacent_poles_only: bool,
    /// Beyond the paper (§3.3 trusts every line of sight): a line of sight that crosses a wall
    /// face from behind, where a scanner in front of that face saw it straight, forces nothing.
    /// An opaque wall hides what lies beyond it, so the points the scanner recorded there were
    /// a mirror's image or seen through glass; their lines of sight cut the wall away (the real
    /// apartment's bathroom mirror carved the wall between bathroom and kitchen). Such a face
    /// gets backs (see `backs`) where its wall shows no other face.
    pub rays_stop_at_faces: bool,
    /// Node count below which the eigenproblem is solved densely (design note §3 suggests ~3000).
    /// Measured (release, 2 cores): sparse shift-invert takes under 1 ms at 560 triangles where
    /// dense takes 34 ms, and 6 ms at 4.7k where dense takes 7.4 s; so dense only for tiny graphs.
    /// Range 0..=2000: the dense solve cannot be interrupted, and at 2000 it takes about a second.
    pub dense_below: usize,
    /// Use the harmonic labels when they disagree with the eigenvector's on more than this
    /// fraction of the inside area (design note §3: 2%). Range 0..=1.
    pub max_disagreement: f64,
    /// Solver: `eigen` (the paper's spectral partition) or `harmonic` (the linear-system variant).
    pub solver: Solver,
}

/// Which partition to compute.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Solver {
    /// The paper's spectral partition (the pencil's smallest eigenvector).
    Eigen,
    /// The harmonic solution of the linear system, the variant.
    Harmonic,
}

/// The accepted values of [`LabelingParams`] (see [`crate::params::ParamRange`]).
pub const RANGES: &[ParamRange] = &[
    ParamRange::new("min_rays", 1.0, 10_000.0, ""),
    ParamRange::new("ray_fraction", 0.01, 1.0, ""),
    ParamRange::new("ray_end_margin", 0.0, 10.0, "m"),
    ParamRange::new("dense_below", 0.0, 2000.0, ""),
    ParamRange::new("max_disagreement", 0.0, 1.0, ""),
];

impl Default for LabelingParams {
    fn default() -> Self {
        LabelingParams {
            min_rays: 10,
            ray_fraction: 0.5,
            rays_from_scanner: true,
            ray_end_margin: Some(0.15),
            wall_backs: true,
            adjacent_poles_only: false,
            rays_stop_at_faces: true,
            dense_below: 200,
            max_disagreement: 0.02,
            solver: Solver::Eigen,
        }
    }
}

/// A triangulation with an inside/outside label per triangle.
#[derive(Debug, Clone, PartialEq)]
pub struct LabeledMesh {
    /// The Delaunay triangulation of the samples.
    pub mesh: Mesh,
    /// Per triangle: true when inside (open floor).
    pub inside: Vec<bool>,
    /// Per triangle: the hard constraint, if any (`Some(true)` forced inside).
    pub forced: Vec<Option<bool>>,
}

/// Why labeling failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LabelingError {
    /// The triangulation failed.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// Fewer than 3 distinct samples.
    #[error("too few wall samples to label: {0} (need at least 3 distinct)")]
    TooFewSamples(usize),
    /// The samples are collinear: they enclose no area.
    #[error("the {0} wall samples are collinear: they enclose no area")]
    Collinear(usize),
    /// A parameter is outside its range.
    #[error("invalid labeling parameter `{name}`: {why}")]
    BadParam {
        /// The parameter's name.
        name: &'static str,
        /// What is wrong.
        why: String,
    },
    /// The eigen-solver failed.
    #[error("the eigen-solver failed: {0}")]
    Solver(String),
    /// The run was stopped from outside.
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
}

/// Which computation produced the labels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Dense eigen-decomposition of the constrained pencil.
    DenseEigen,
    /// Shift-invert Lanczos around a sparse Cholesky factorization.
    SparseEigen,
    /// The harmonic (linear-system) solution: asked for, or the eigen-solver's fallback.
    Harmonic,
}

/// How labeling went: sizes, constraints, the solver used and its accuracy.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LabelingReport {
    /// Triangles (graph nodes), including the box-corner ones.
    pub triangles: usize,
    /// Distinct samples triangulated, the filled vertices among them.
    pub samples: usize,
    /// Vertices filled into short holes of straight rows of samples (see `gaps`).
    pub filled: usize,
    /// Vertices placed behind faces whose wall shows no other face (see `backs`).
    pub backed: usize,
    /// Positive (same-side) edges.
    pub positive_edges: usize,
    /// Negative edges between poles sharing an edge (eq. (1)).
    pub negative_adjacent: usize,
    /// Negative edges between poles not sharing an edge.
    pub negative_apart: usize,
    /// Triangles forced outside (box corners).
    pub forced_outside: usize,
    /// Triangles forced inside (any reason, after conflicts).
    pub forced_inside: usize,
    /// Triangles crossed by at least `min_rays` lines of sight.
    pub inside_by_rays: usize,
    /// Triangles containing a viewpoint.
    pub inside_by_poses: usize,
    /// Triangles crossed by the mobile path.
    pub inside_by_path: usize,
    /// Triangles that evidence put inside but that touch a box corner (they stay outside).
    pub conflicts: usize,
    /// Lines of sight walked, and skipped (viewpoint outside the triangulation, or degenerate).
    pub rays: usize,
    /// Lines of sight skipped.
    pub rays_skipped: usize,
    /// Lines of sight dropped because they crossed a face seen straight from its other side.
    pub rays_blocked: usize,
    /// Free nodes of the constrained system (its size is this + 1).
    pub free_nodes: usize,
    /// The computation whose labels were used.
    pub method: Method,
    /// The smallest eigenvalue of L̃y = λD̃y, when the eigen-solver ran.
    pub eigenvalue: Option<f64>,
    /// ‖Nz − λz‖ for the unit eigenvector of the normalised pencil.
    pub residual: Option<f64>,
    /// Linear solves (sparse) spent on the eigenvector; 1 for the dense path.
    pub iterations: usize,
    /// Fraction of the inside area where eigenvector and harmonic labels differ.
    pub disagreement: Option<f64>,
    /// Free triangles whose value was too close to zero to sign; labeled from their neighbours.
    pub ties: usize,
    /// Why the harmonic labels were used instead of the eigenvector, when they were.
    pub fallback: Option<String>,
    /// Wall time of each phase.
    pub timings: LabelingTimings,
}

/// Wall time of each labeling phase, in milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct LabelingTimings {
    /// Delaunay triangulation.
    pub mesh_ms: f64,
    /// Poles and edge weights.
    pub graph_ms: f64,
    /// Hard constraints (segment walks).
    pub constraints_ms: f64,
    /// Assembly, factorization, eigen and harmonic solves.
    pub solve_ms: f64,
}

/// Triangulates the samples and labels every triangle inside or outside. Stops with
/// `Cancelled` once `cancel` says so.
pub fn label(
    samples: &WallSamples,
    params: &LabelingParams,
    cancel: &Cancel,
) -> Result<LabeledMesh, LabelingError> {
    label_with_report(samples, params, cancel).map(|(m, _)| m)
}

/// [`label`], also returning how it went.
pub fn label_with_report(
    samples: &WallSamples,
    params: &LabelingParams,
    cancel: &Cancel,
) -> Result<(LabeledMesh, LabelingReport), LabelingError> {
    check_params(params)?;
    let clock = std::time::Instant::now();
    let mut lap = {
        let mut last = clock.elapsed();
        move || {
            let now = clock.elapsed();
            let ms = (now - last).as_secs_f64() * 1e3;
            last = now;
            ms
        }
    };
    let mut timings = LabelingTimings::default();
    let mut points: Vec<_> = samples.samples.iter().map(|s| s.pos).collect();
    let mut normals: Vec<_> = samples.samples.iter().map(|s| s.normal).collect();
    let mut mesh = match Mesh::build(&points, &normals) {
        Err(MeshError::TooFewSamples(n)) => return Err(LabelingError::TooFewSamples(n)),
        other => other?,
    };
    if collinear(&mesh.vertices[..mesh.n_samples]) {
        return Err(LabelingError::Collinear(mesh.n_samples));
    }
    let (added, added_normals) = gaps::fill(&mesh);
    let filled = added.len();
    if filled > 0 {
        // The filled vertices lie on segments between samples: the mesh only gains vertices.
        points.extend(added);
        normals.extend(added_normals);
        mesh = Mesh::build(&points, &normals)?;
    }
    timings.mesh_ms = lap();
    cancel.check()?;
    // Walls carved by lines of sight from a room that saw them poorly, or by a scanner seeing
    // through a face from behind (a mirror), get their backs, and the constraints are found
    // again on the mesh that holds them.
    // Carved walls only for a mobile scan (along its trajectory, or from pseudo-viewpoints when
    // its path is unknown): the walker steps into rooms and sees their
    // faces of the corridor walls poorly, where a static station stands in each room. On static
    // scans backs gained little (office 0.9996 -> 0.9999) and notched the real apartment's
    // corridor wall (longest line 8.6 -> 4.8 m); from pseudo-viewpoints they cut holes behind
    // clutter.
    let along_path = samples
        .path
        .iter()
        .any(|p| p[0].is_finite() && p[1].is_finite());
    let carving = params.wall_backs && (along_path || samples.moving);
    // The spacing pass only where it is used.
    let spacing = (carving || params.rays_stop_at_faces)
        .then(|| gaps::spacing(&mesh))
        .flatten();
    let candidates = match spacing {
        Some(h) if carving => backs::place(&samples.samples, h),
        _ => Vec::new(),
    };
    let probes: Vec<crate::geom::P2> = candidates.iter().map(|b| b.probes[1]).collect();
    let mut cons = constraints::hard_constraints(
        &mesh,
        samples,
        &[],
        constraints::Probes {
            points: &probes,
            radius: backs::SEEN_WITHIN * spacing.unwrap_or(0.0),
        },
        spacing,
        params,
        cancel,
    )?;
    // Samples of the faces that blocked a line of sight from behind.
    let mut blocking = vec![false; samples.samples.len()];
    for &v in &cons.blocking {
        if let Some(&k) = mesh.sample_of.get(v as usize) {
            if let Some(b) = blocking.get_mut(k as usize) {
                *b = true;
            }
        }
    }
    let mirrored = match spacing {
        Some(h) if !carving && !cons.blocking.is_empty() => backs::place(&samples.samples, h),
        _ => Vec::new(),
    };
    let mut hint = 0u32;
    let mut k = 0;
    let candidates = if carving { &candidates } else { &mirrored };
    let chosen = backs::select(candidates, spacing.unwrap_or(0.0), |b| {
        let seen = cons.probes_seen.get(k).copied().unwrap_or(true);
        k += 1;
        if blocking[b.sample] {
            return true;
        }
        // Forced inside by lines of sight that all passed it by at a distance: a triangle
        // reaching from the face across the wall, not open floor behind clutter.
        carving
            && !seen
            && match walk::locate(&mesh, b.probes[1], hint) {
                Some(t) => {
                    hint = t;
                    cons.forced[t as usize] == Some(true)
                }
                None => false,
            }
    });
    let backed = chosen.points.len();
    if backed > 0 {
        points.extend(&chosen.points);
        normals.extend(&chosen.normals);
        mesh = Mesh::build(&points, &normals)?;
        cancel.check()?;
        cons = constraints::hard_constraints(
            &mesh,
            samples,
            &chosen.solid,
            constraints::Probes::default(),
            spacing,
            params,
            cancel,
        )?;
    }
    timings.constraints_ms = lap();
    cancel.check()?;
    let graph = weights::build_graph(&mesh, params.adjacent_poles_only);
    timings.graph_ms = lap();
    let nt = mesh.triangles.len();
    let reduced = spectral::Reduced::new(nt, &graph.edges, &cons.forced);
    let want_eigen = params.solver == Solver::Eigen;
    let sol = spectral::solve(&reduced, want_eigen, params.dense_below, cancel);
    // A solve stopped early is not a solver failure.
    cancel.check()?;
    let sol = sol.map_err(LabelingError::Solver)?;
    timings.solve_ms = lap();

    let harmonic = signs(&reduced, &graph, &sol.harmonic);
    let mut report = LabelingReport {
        triangles: nt,
        samples: mesh.n_samples,
        filled,
        backed,
        positive_edges: graph.edges.iter().filter(|e| e.2 > 0.0).count(),
        negative_adjacent: graph.negative_adjacent,
        negative_apart: graph.negative_apart,
        forced_outside: cons.outside,
        forced_inside: cons.forced.iter().filter(|f| **f == Some(true)).count(),
        inside_by_rays: cons.inside_rays,
        inside_by_poses: cons.inside_poses,
        inside_by_path: cons.inside_path,
        conflicts: cons.conflicts,
        rays: cons.rays,
        rays_skipped: cons.rays_skipped,
        rays_blocked: cons.rays_blocked,
        free_nodes: reduced.k,
        method: Method::Harmonic,
        eigenvalue: sol.lambda,
        residual: sol.residual,
        iterations: sol.iterations,
        disagreement: None,
        ties: harmonic.1,
        fallback: None,
        timings,
    };
    let mut inside = harmonic.0.clone();
    if want_eigen {
        match (&sol.eigen, sol.converged) {
            (Some(z), true) => {
                let eigen = signs(&reduced, &graph, z);
                let differ = (0..nt)
                    .filter(|&t| eigen.0[t] != harmonic.0[t])
                    .map(|t| mesh.area(t))
                    .sum::<f64>();
                let union = (0..nt)
                    .filter(|&t| eigen.0[t] || harmonic.0[t])
                    .map(|t| mesh.area(t))
                    .sum::<f64>();
                let disagreement = if union > 0.0 {
                    differ / union + 0.0
                } else {
                    0.0
                };
                report.disagreement = Some(disagreement);
                if disagreement > params.max_disagreement {
                    report.fallback = Some(format!(
                        "eigenvector and harmonic labels differ on {:.1}% of the inside area",
                        100.0 * disagreement
                    ));
                } else {
                    report.method = if sol.dense {
                        Method::DenseEigen
                    } else {
                        Method::SparseEigen
                    };
                    report.ties = eigen.1;
                    inside = eigen.0;
                }
            }
            _ => {
                report.fallback = Some(
                    sol.note
                        .clone()
                        .unwrap_or_else(|| "the eigen-solver did not converge".into()),
                );
            }
        }
    }
    Ok((
        LabeledMesh {
            mesh,
            inside,
            forced: cons.forced,
        },
        report,
    ))
}

impl LabelingParams {
    /// Checks every value; the error names the parameter.
    pub fn check(&self) -> Result<(), LabelingError> {
        check_params(self)
    }
}

fn check_params(p: &LabelingParams) -> Result<(), LabelingError> {
    let check = |name, v: f64| {
        within(RANGES, name, v).map_err(|(name, why)| LabelingError::BadParam { name, why })
    };
    check("min_rays", p.min_rays as f64)?;
    check("ray_fraction", p.ray_fraction)?;
    if let Some(m) = p.ray_end_margin {
        check("ray_end_margin", m)?;
    }
    check("dense_below", p.dense_below as f64)?;
    check("max_disagreement", p.max_disagreement)
}

/// True when every point lies on one line (exact test).
fn collinear(points: &[crate::geom::P2]) -> bool {
    let Some(&a) = points.first() else {
        return true;
    };
    let Some(&b) = points.iter().find(|&&p| p != a) else {
        return true;
    };
    let c = |p: crate::geom::P2| robust::Coord { x: p[0], y: p[1] };
    points
        .iter()
        .all(|&p| robust::orient2d(c(a), c(b), c(p)) == 0.0)
}

/// Labels from a solution vector (normalised space): forced triangles keep their label, free
/// ones are inside when positive. Values too close to zero take the side their weighted
/// neighbours favour. Returns the labels and the number of ties.
fn signs(r: &spectral::Reduced, g: &weights::Graph, z: &[f64]) -> (Vec<bool>, usize) {
    let n = r.index.len();
    let max = z.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let value = |t: usize| {
        if r.sign[t] == 0.0 {
            z[r.index[t] as usize]
        } else {
            r.sign[t] * max
        }
    };
    let tie = |t: usize| r.sign[t] == 0.0 && value(t).abs() <= 1e-12 * max;
    let mut inside: Vec<bool> = (0..n).map(|t| value(t) > 0.0).collect();
    let tied: Vec<usize> = (0..n).filter(|&t| tie(t)).collect();
    if !tied.is_empty() {
        let mut vote = vec![0.0f64; n];
        for &(u, v, w) in &g.edges {
            let (u, v) = (u as usize, v as usize);
            // A positive edge pulls toward the neighbour's side, a negative one away from it.
            vote[u] += w * value(v).signum();
            vote[v] += w * value(u).signum();
        }
        for &t in &tied {
            inside[t] = vote[t] > 0.0;
        }
    }
    (inside, tied.len())
}

#[cfg(test)]
mod tests;
