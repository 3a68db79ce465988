//! The constrained generalized eigenproblem of 2D Eigencrust (design note §2.6, §3) and its
//! harmonic alternative, solved densely for small graphs and by shift-invert around one sparse
//! Cholesky factorization for large ones.
//!
//! With the signed Laplacian L (L_ij = −w_ij, L_ii = D_ii = Σ_j |w_ij|), the label vector
//! x ∈ {±1}ⁿ minimising the cut cost minimises xᵀLx / xᵀDx. Hard constraints fix x_i = s_i·t for
//! every constrained node i: substituting merges all of them into one node K, giving the
//! (free + 1)-sized pencil (L̃, D̃). The relaxed labels are the eigenvector of its smallest
//! eigenvalue; we work with the normalised N = D̃^{-1/2} L̃ D̃^{-1/2} (spectrum in [0, 2]).

use crate::cancel::Cancel;
use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, MatMut, Side};
use nalgebra::{DMatrix, SymmetricEigen};

/// Shift keeping N + σI positive definite when the signed graph is balanced (λ_min = 0).
const SIGMA: f64 = 1e-9;
/// Convergence: ‖Nz − λz‖ for unit z.
pub(crate) const TOLERANCE: f64 = 1e-9;
/// Lanczos vectors kept before an explicit restart.
const BASIS: usize = 24;
/// Linear solves allowed to the eigen-solver before it gives up.
const MAX_SOLVES: usize = 150;

/// The constrained system: free nodes `0..k`, the merged constrained node `k`.
#[derive(Debug, Clone)]
pub(crate) struct Reduced {
    /// Per graph node: its index in the reduced system (`k` for every constrained node).
    pub index: Vec<u32>,
    /// Per graph node: +1 forced inside, −1 forced outside, 0 free.
    pub sign: Vec<f64>,
    /// Index of the merged node K (= number of free nodes).
    pub k: usize,
    /// Diagonal of D̃.
    pub d: Vec<f64>,
    /// Lower triangle (row ≥ col) of L̃ as CSC, duplicates summed.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    val: Vec<f64>,
}

impl Reduced {
    /// Builds (L̃, D̃) from the weighted edges and the forced labels.
    pub(crate) fn new(n: usize, edges: &[(u32, u32, f64)], forced: &[Option<bool>]) -> Reduced {
        let sign: Vec<f64> = forced
            .iter()
            .map(|f| match f {
                Some(true) => 1.0,
                Some(false) => -1.0,
                None => 0.0,
            })
            .collect();
        let mut index = vec![0u32; n];
        let mut k = 0usize;
        for i in 0..n {
            if sign[i] == 0.0 {
                index[i] = k as u32;
                k += 1;
            }
        }
        for i in 0..n {
            if sign[i] != 0.0 {
                index[i] = k as u32;
            }
        }
        let mut degree = vec![0.0f64; n];
        for &(u, v, w) in edges {
            degree[u as usize] += w.abs();
            degree[v as usize] += w.abs();
        }
        let mut d = vec![0.0f64; k + 1];
        let mut beta = 0.0;
        let mut trip: Vec<(usize, usize, f64)> = Vec::with_capacity(edges.len() + k + 1);
        for i in 0..n {
            if sign[i] == 0.0 {
                d[index[i] as usize] = degree[i];
            } else {
                d[k] += degree[i];
                beta += degree[i];
            }
        }
        for &(u, v, w) in edges {
            let (u, v) = (u as usize, v as usize);
            let l = -w;
            match (sign[u] == 0.0, sign[v] == 0.0) {
                (true, true) => {
                    let (a, b) = (index[u] as usize, index[v] as usize);
                    trip.push((a.max(b), a.min(b), l));
                }
                (true, false) => trip.push((k, index[u] as usize, l * sign[v])),
                (false, true) => trip.push((k, index[v] as usize, l * sign[u])),
                (false, false) => beta += 2.0 * sign[u] * sign[v] * l,
            }
        }
        for (i, &di) in d.iter().enumerate().take(k) {
            trip.push((i, i, di));
        }
        trip.push((k, k, beta));
        // CSC of the lower triangle, duplicates summed.
        trip.sort_unstable_by_key(|&(r, c, _)| (c, r));
        let mut col_ptr = vec![0usize; k + 2];
        let mut row_idx = Vec::with_capacity(trip.len());
        let mut val: Vec<f64> = Vec::with_capacity(trip.len());
        let mut last = (usize::MAX, usize::MAX);
        for (r, c, x) in trip {
            if (r, c) == last {
                *val.last_mut().expect("a previous entry") += x;
            } else {
                row_idx.push(r);
                val.push(x);
                col_ptr[c + 1] += 1;
                last = (r, c);
            }
        }
        for c in 0..=k {
            col_ptr[c + 1] += col_ptr[c];
        }
        Reduced {
            index,
            sign,
            k,
            d,
            col_ptr,
            row_idx,
            val,
        }
    }

    /// Size of the reduced system.
    pub(crate) fn n(&self) -> usize {
        self.k + 1
    }

    /// Entries (row ≥ col) of N + shift·I.
    fn normalized_lower(&self, shift: f64) -> Vec<(usize, usize, f64)> {
        let s: Vec<f64> = self.d.iter().map(|&x| 1.0 / x.max(1e-300).sqrt()).collect();
        let mut out = Vec::with_capacity(self.val.len());
        for c in 0..self.n() {
            for p in self.col_ptr[c]..self.col_ptr[c + 1] {
                let r = self.row_idx[p];
                let v = self.val[p] * s[r] * s[c] + if r == c { shift } else { 0.0 };
                out.push((r, c, v));
            }
        }
        out
    }

    /// L̃·y (unnormalised), from the stored lower triangle.
    pub(crate) fn apply_l(&self, y: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.n()];
        for c in 0..self.n() {
            for p in self.col_ptr[c]..self.col_ptr[c + 1] {
                let (r, v) = (self.row_idx[p], self.val[p]);
                out[r] += v * y[c];
                if r != c {
                    out[c] += v * y[r];
                }
            }
        }
        out
    }

    /// N·z.
    fn apply_n(&self, z: &[f64]) -> Vec<f64> {
        let y: Vec<f64> = z.iter().zip(&self.d).map(|(z, d)| z / d.sqrt()).collect();
        let ly = self.apply_l(&y);
        ly.iter().zip(&self.d).map(|(l, d)| l / d.sqrt()).collect()
    }

    /// y = D̃^{-1/2} z: back from the normalised space.
    #[cfg(test)]
    pub(crate) fn unnormalize(&self, z: &[f64]) -> Vec<f64> {
        z.iter().zip(&self.d).map(|(z, d)| z / d.sqrt()).collect()
    }

    /// The dense N + shift·I.
    fn dense(&self, shift: f64) -> Mat<f64> {
        let n = self.n();
        let mut m = Mat::<f64>::zeros(n, n);
        for (r, c, v) in self.normalized_lower(shift) {
            m[(r, c)] = v;
            m[(c, r)] = v;
        }
        m
    }
}

/// What a solve produced, in the normalised space (signs equal those of the labels).
#[derive(Debug, Clone)]
pub(crate) struct Solution {
    /// The eigenvector of the smallest eigenvalue, z_K ≥ 0; `None` when not asked for or failed.
    pub eigen: Option<Vec<f64>>,
    /// Its eigenvalue λ of L̃y = λD̃y.
    pub lambda: Option<f64>,
    /// ‖Nz − λz‖ for unit z.
    pub residual: Option<f64>,
    /// Linear solves (sparse) or 1 (dense) spent on the eigenvector.
    pub iterations: usize,
    /// Whether the eigen-solver met [`TOLERANCE`].
    pub converged: bool,
    /// The harmonic solution: L_FF x_F = −L_FC s_C, with x_K = 1 (normalised space).
    pub harmonic: Vec<f64>,
    /// True when the dense path was taken.
    pub dense: bool,
    /// Why the eigen-solver result was not usable, when it was not.
    pub note: Option<String>,
}

/// Solves the reduced system: always the harmonic solution, and the eigenvector when `eigen`.
/// Once `cancel` says so the Lanczos iterations stop and the solution is not converged; the
/// caller checks `cancel` afterwards.
pub(crate) fn solve(
    r: &Reduced,
    eigen: bool,
    dense_below: usize,
    cancel: &Cancel,
) -> Result<Solution, String> {
    if r.n() < dense_below.max(2) {
        solve_dense(r, eigen)
    } else {
        solve_sparse(r, eigen, cancel)
    }
}

fn unit_k(r: &Reduced) -> Vec<f64> {
    let mut e = vec![0.0; r.n()];
    e[r.k] = 1.0;
    e
}

fn solve_dense(r: &Reduced, eigen: bool) -> Result<Solution, String> {
    let n = r.n();
    let mut harmonic = unit_k(r);
    let mut shift = SIGMA;
    loop {
        let m = r.dense(shift);
        if let Ok(llt) = m.llt(Side::Lower) {
            llt.solve_in_place(MatMut::from_column_major_slice_mut(&mut harmonic, n, 1));
            break;
        }
        shift *= 1e3;
        if shift > 1e-3 {
            return Err("the dense constrained system is not positive definite".into());
        }
    }
    let mut sol = Solution {
        eigen: None,
        lambda: None,
        residual: None,
        iterations: 0,
        converged: false,
        harmonic,
        dense: true,
        note: None,
    };
    if eigen {
        match r.dense(0.0).self_adjoint_eigen(Side::Lower) {
            Ok(evd) => {
                let lambda = evd.S().column_vector()[0];
                let z: Vec<f64> = (0..n).map(|i| evd.U()[(i, 0)]).collect();
                finish_eigen(r, &mut sol, z, lambda, 1, true);
            }
            Err(e) => sol.note = Some(format!("dense eigen-decomposition failed: {e:?}")),
        }
    }
    Ok(sol)
}

/// Stores an eigenpair after fixing its sign (z_K > 0) and measuring its residual.
fn finish_eigen(
    r: &Reduced,
    sol: &mut Solution,
    mut z: Vec<f64>,
    lambda: f64,
    iterations: usize,
    converged: bool,
) {
    let norm = z.iter().map(|x| x * x).sum::<f64>().sqrt();
    z.iter_mut().for_each(|x| *x /= norm);
    let nz = r.apply_n(&z);
    let residual = nz
        .iter()
        .zip(&z)
        .map(|(a, b)| (a - lambda * b).powi(2))
        .sum::<f64>()
        .sqrt();
    let max = z.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    sol.iterations = iterations;
    sol.lambda = Some(lambda);
    sol.residual = Some(residual);
    sol.converged = converged && residual <= TOLERANCE.max(1e-12 * lambda.abs());
    if z[r.k].abs() <= 1e-9 * max {
        // The constrained node barely moves: the sign of the whole vector is arbitrary.
        sol.note = Some("eigenvector vanishes on the constrained triangles".into());
        return;
    }
    if z[r.k] < 0.0 {
        z.iter_mut().for_each(|x| *x = -*x);
    }
    sol.eigen = Some(z);
}

fn solve_sparse(r: &Reduced, eigen: bool, cancel: &Cancel) -> Result<Solution, String> {
    let n = r.n();
    let mut shift = SIGMA;
    let llt = loop {
        let trip: Vec<Triplet<usize, usize, f64>> = r
            .normalized_lower(shift)
            .into_iter()
            .map(|(row, col, v)| Triplet::new(row, col, v))
            .collect();
        let m = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &trip)
            .map_err(|e| format!("sparse matrix: {e:?}"))?;
        match m.sp_cholesky(Side::Lower) {
            Ok(llt) => break llt,
            Err(e) => {
                shift *= 1e3;
                if shift > 1e-3 {
                    return Err(format!("sparse Cholesky failed: {e:?}"));
                }
            }
        }
    };
    let solve = |x: &mut Vec<f64>| {
        llt.solve_in_place(MatMut::from_column_major_slice_mut(x, n, 1));
    };
    let mut harmonic = unit_k(r);
    solve(&mut harmonic);
    let mut sol = Solution {
        eigen: None,
        lambda: None,
        residual: None,
        iterations: 0,
        converged: false,
        harmonic: harmonic.clone(),
        dense: false,
        note: None,
    };
    if eigen {
        let (z, lambda, solves, converged) = lanczos(r, shift, harmonic, solve, cancel);
        finish_eigen(r, &mut sol, z, lambda, solves, converged);
        if !sol.converged && sol.note.is_none() {
            sol.note = Some(format!(
                "eigen-solver did not converge in {solves} solves (residual {:.2e})",
                sol.residual.unwrap_or(f64::NAN)
            ));
        }
    }
    Ok(sol)
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Shift-invert Lanczos with full reorthogonalisation and explicit restarts: the largest
/// eigenpair of (N + σI)⁻¹ is the smallest of N. Returns (z, λ, solves, converged).
fn lanczos(
    r: &Reduced,
    shift: f64,
    start: Vec<f64>,
    mut solve: impl FnMut(&mut Vec<f64>),
    cancel: &Cancel,
) -> (Vec<f64>, f64, usize, bool) {
    let mut v = start;
    let mut solves = 1; // the harmonic solve that made the start vector
    loop {
        let nv = dot(&v, &v).sqrt();
        v.iter_mut().for_each(|x| *x /= nv);
        let mut q: Vec<Vec<f64>> = vec![v.clone()];
        let (mut alpha, mut beta) = (Vec::new(), Vec::new());
        let mut best: Option<(f64, Vec<f64>)> = None;
        let mut converged = false;
        for j in 0..BASIS {
            let mut w = q[j].clone();
            solve(&mut w);
            solves += 1;
            let a = dot(&q[j], &w);
            alpha.push(a);
            // Two passes of classical Gram-Schmidt against the whole basis.
            for _ in 0..2 {
                for qi in &q {
                    let c = dot(qi, &w);
                    w.iter_mut().zip(qi).for_each(|(x, y)| *x -= c * y);
                }
            }
            let b = dot(&w, &w).sqrt();
            // One sparse solve per step, tens of milliseconds at the largest.
            let last = j + 1 == BASIS || solves >= MAX_SOLVES || cancel.is_stopped();
            if (j + 1) % 3 == 0 || last || b < 1e-14 {
                let (theta, s) = ritz(&alpha, &beta);
                // ‖M⁻¹z − θz‖ = b·|s_m|, so ‖Nz − λz‖ ≤ ‖M‖·b·|s_m|/θ with ‖M‖ ≤ 2 + σ.
                let estimate = 2.0 * b * s[j].abs() / theta;
                best = Some((theta, s));
                if estimate <= 0.5 * TOLERANCE || b < 1e-14 {
                    converged = true;
                    break;
                }
            }
            if last {
                break;
            }
            w.iter_mut().for_each(|x| *x /= b);
            beta.push(b);
            q.push(w);
        }
        let (theta, s) = best.expect("at least one Ritz check per cycle");
        let mut z = vec![0.0; r.n()];
        for (qi, si) in q.iter().zip(&s) {
            z.iter_mut().zip(qi).for_each(|(x, y)| *x += si * y);
        }
        let lambda = 1.0 / theta - shift;
        if converged || solves >= MAX_SOLVES || cancel.is_stopped() {
            return (z, lambda, solves, converged);
        }
        v = z;
    }
}

/// The largest eigenvalue of the Lanczos tridiagonal matrix and its eigenvector.
fn ritz(alpha: &[f64], beta: &[f64]) -> (f64, Vec<f64>) {
    let m = alpha.len();
    let t = DMatrix::from_fn(m, m, |i, j| {
        if i == j {
            alpha[i]
        } else if i + 1 == j {
            beta[i]
        } else if j + 1 == i {
            beta[j]
        } else {
            0.0
        }
    });
    let e = SymmetricEigen::new(t);
    let (imax, theta) =
        e.eigenvalues
            .iter()
            .enumerate()
            .fold(
                (0, f64::NEG_INFINITY),
                |b, (i, &x)| if x > b.1 { (i, x) } else { b },
            );
    (theta, e.eigenvectors.column(imax).iter().copied().collect())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A small signed graph: a path 0-1-2-3-4-5 with one frustrating negative edge, node 0
    /// forced outside and node 5 forced inside.
    type Edges = Vec<(u32, u32, f64)>;

    fn toy() -> (Edges, Vec<Option<bool>>) {
        let edges = vec![
            (0, 1, 5.0),
            (1, 2, 3.0),
            (2, 3, 0.5),
            (3, 4, 4.0),
            (4, 5, 6.0),
            (1, 4, -2.0),
            (0, 5, -1.0),
            (2, 4, 1.5),
        ];
        let mut forced = vec![None; 6];
        forced[0] = Some(false);
        forced[5] = Some(true);
        (edges, forced)
    }

    /// Expands a reduced vector to every graph node (x_i = s_i·y_K on constrained nodes).
    pub(crate) fn expand(r: &Reduced, y: &[f64]) -> Vec<f64> {
        (0..r.index.len())
            .map(|i| {
                if r.sign[i] == 0.0 {
                    y[r.index[i] as usize]
                } else {
                    r.sign[i] * y[r.k]
                }
            })
            .collect()
    }

    /// xᵀLx and xᵀDx on the full graph.
    pub(crate) fn full_quadratic_forms(edges: &[(u32, u32, f64)], x: &[f64]) -> (f64, f64) {
        let (mut l, mut d) = (0.0, 0.0);
        for &(u, v, w) in edges {
            let (a, b) = (x[u as usize], x[v as usize]);
            // Σ_{w>0} w (a − b)² + Σ_{w<0} |w| (a + b)², and D = Σ|w| per node.
            l += if w > 0.0 {
                w * (a - b).powi(2)
            } else {
                -w * (a + b).powi(2)
            };
            d += w.abs() * (a * a + b * b);
        }
        (l, d)
    }

    #[test]
    fn dense_and_sparse_eigenpairs_agree_and_satisfy_the_pencil() {
        let (edges, forced) = toy();
        let r = Reduced::new(6, &edges, &forced);
        assert_eq!(r.n(), 5);
        let dense = solve(&r, true, 1000, &Cancel::never()).unwrap();
        let sparse = solve(&r, true, 0, &Cancel::never()).unwrap();
        assert!(dense.dense && !sparse.dense);
        for s in [&dense, &sparse] {
            let z = s.eigen.as_ref().unwrap();
            let lambda = s.lambda.unwrap();
            assert!(s.converged, "{:?}", s.note);
            // ‖L̃y − λD̃y‖ relative to ‖D̃y‖.
            let y = r.unnormalize(z);
            let ly = r.apply_l(&y);
            let res: f64 = ly
                .iter()
                .zip(&y)
                .zip(&r.d)
                .map(|((l, y), d)| (l - lambda * d * y).powi(2))
                .sum::<f64>()
                .sqrt();
            let dy: f64 = y
                .iter()
                .zip(&r.d)
                .map(|(y, d)| (d * y).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(res <= 1e-8 * dy, "residual {res}");
            // The Rayleigh quotient on the full graph equals λ: the merge is exact.
            let x = expand(&r, &y);
            let (l, d) = full_quadratic_forms(&edges, &x);
            assert!((l / d - lambda).abs() < 1e-9, "{} vs {lambda}", l / d);
            // Constrained nodes keep their forced signs.
            assert!(x[0] < 0.0 && x[5] > 0.0);
        }
        assert!((dense.lambda.unwrap() - sparse.lambda.unwrap()).abs() < 1e-10);
        let (a, b) = (dense.eigen.unwrap(), sparse.eigen.unwrap());
        assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-7));
    }

    #[test]
    fn smallest_eigenvector_is_d_orthogonal_to_the_next_and_lambda_is_lowest() {
        let (edges, forced) = toy();
        let r = Reduced::new(6, &edges, &forced);
        let evd = r.dense(0.0).self_adjoint_eigen(Side::Lower).unwrap();
        let s = evd.S().column_vector();
        assert!(s[0] >= -1e-12 && s[0] <= s[1]);
        // z-orthogonality in the normalised space is D̃-orthogonality of y = D̃^{-1/2} z.
        let y0 = r.unnormalize(&(0..r.n()).map(|i| evd.U()[(i, 0)]).collect::<Vec<_>>());
        let y1 = r.unnormalize(&(0..r.n()).map(|i| evd.U()[(i, 1)]).collect::<Vec<_>>());
        let d_inner: f64 = (0..r.n()).map(|i| y0[i] * r.d[i] * y1[i]).sum();
        assert!(d_inner.abs() < 1e-12);
        // All eigenvalues of the normalised pencil lie in [0, 2].
        assert!((0..r.n()).all(|i| s[i] > -1e-12 && s[i] < 2.0 + 1e-12));
    }

    #[test]
    fn harmonic_solution_zeroes_the_free_rows() {
        let (edges, forced) = toy();
        let r = Reduced::new(6, &edges, &forced);
        for dense_below in [1000, 0] {
            let s = solve(&r, false, dense_below, &Cancel::never()).unwrap();
            assert!(s.eigen.is_none());
            let y = r.unnormalize(&s.harmonic);
            assert!(y[r.k] > 0.0);
            // L_FF y_F + b y_K = −σ D_FF y_F ≈ 0 on every free row.
            let ly = r.apply_l(&y);
            for (i, (l, d)) in ly.iter().zip(&r.d).take(r.k).enumerate() {
                assert!(l.abs() < 1e-6 * d * y[r.k], "row {i}: {l}");
            }
        }
    }
}
