//! Lemke's complementary pivoting method (Cottle, Pang & Stone, "The Linear Complementarity
//! Problem", §4.4) for `w = M z + q, z ≥ 0, w ≥ 0, zᵀw = 0`, with a covering vector of ones, the
//! lexicographic minimum-ratio test (no cycling on degenerate problems such as four coplanar box
//! corners), a pivot limit, tolerances scaled by the problem, and a verified answer.
//!
//! [`lcp_of`] turns a [`ConstraintProblem`] into the LCP of the polyhedral-friction formulation
//! (Stewart & Trinkle 1996): per contact the normal impulse, k friction-direction impulses β_j
//! and a slack γ (the sliding speed); bounded rows by the usual split into a shifted variable and
//! an upper-bound multiplier; bilateral rows as the difference of two nonnegative variables.

use super::{check_problem, ConstraintSolver, SolveInfo, SolverError};
use crate::constraints::{ConstraintProblem, FrictionModel, RowLaw};
use nalgebra::{DMatrix, DVector};

/// Options of Lemke's method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LemkeOptions {
    /// Maximum number of pivots (0: 50 × the LCP size + 100).
    pub max_pivots: usize,
    /// Pivot tolerance relative to the largest |M_ij| (a column entry must exceed it to pivot).
    pub pivot_tolerance: f64,
    /// Accepted complementarity residual relative to max(1, ‖q‖∞).
    pub tolerance: f64,
}

impl Default for LemkeOptions {
    fn default() -> Self {
        Self { max_pivots: 0, pivot_tolerance: 1e-13, tolerance: 1e-9 }
    }
}

/// An LCP `w = M z + q`, with the map back to impulses `λ = C z + c0`.
#[derive(Clone, Debug, PartialEq)]
pub struct Lcp {
    /// M (m × m).
    pub m: DMatrix<f64>,
    /// q (m).
    pub q: DVector<f64>,
    /// C (rows × m): impulses from LCP variables.
    pub c: DMatrix<f64>,
    /// c0 (rows).
    pub c0: DVector<f64>,
}

/// The LCP of `problem` with friction as a pyramid of `facets` directions (the problem's own
/// pyramid if it states one).
pub fn lcp_of(problem: &ConstraintProblem, facets: usize) -> Lcp {
    let n = problem.rows();
    let k = match problem.friction {
        FrictionModel::Pyramid { facets } => facets,
        FrictionModel::Cone => facets,
    };
    // Columns of C and extra couplings E, e; friction rows get their columns per contact.
    let mut columns: Vec<Vec<(usize, f64)>> = Vec::new();
    let mut extra: Vec<(usize, usize, f64)> = Vec::new();
    let mut e_entries: Vec<(usize, f64)> = Vec::new();
    let mut c0 = DVector::zeros(n);
    let mut normal_var = vec![usize::MAX; n];
    for i in 0..n {
        match problem.laws[i] {
            RowLaw::Unilateral => {
                normal_var[i] = columns.len();
                columns.push(vec![(i, 1.0)]);
            }
            RowLaw::Bilateral => {
                columns.push(vec![(i, 1.0)]);
                columns.push(vec![(i, -1.0)]);
            }
            RowLaw::Bounded { lo, hi } => match (lo.is_finite(), hi.is_finite()) {
                (true, true) => {
                    c0[i] = lo;
                    let x = columns.len();
                    columns.push(vec![(i, 1.0)]);
                    let sigma = columns.len();
                    columns.push(Vec::new());
                    extra.push((x, sigma, 1.0));
                    extra.push((sigma, x, -1.0));
                    e_entries.push((sigma, hi - lo));
                }
                (true, false) => {
                    c0[i] = lo;
                    columns.push(vec![(i, 1.0)]);
                }
                (false, true) => {
                    c0[i] = hi;
                    columns.push(vec![(i, -1.0)]);
                }
                (false, false) => {
                    columns.push(vec![(i, 1.0)]);
                    columns.push(vec![(i, -1.0)]);
                }
            },
            RowLaw::Friction { .. } => {}
        }
    }
    for block in &problem.contacts {
        let (nr, t1, t2) = block.rows();
        if block.mu == 0.0 && block.mu2 == 0.0 {
            continue;
        }
        let first_beta = columns.len();
        for j in 0..k {
            let t = 2.0 * std::f64::consts::PI * j as f64 / k as f64;
            columns.push(vec![(t1, block.mu * t.cos()), (t2, block.mu2 * t.sin())]);
        }
        let gamma = columns.len();
        columns.push(Vec::new());
        for beta in first_beta..gamma {
            extra.push((beta, gamma, 1.0));
            extra.push((gamma, beta, -1.0));
        }
        extra.push((gamma, normal_var[nr], 1.0));
    }
    let m = columns.len();
    let mut c = DMatrix::zeros(n, m);
    for (j, col) in columns.iter().enumerate() {
        for &(i, x) in col {
            c[(i, j)] += x;
        }
    }
    let mut a = problem.delassus_dense().into_owned();
    for i in 0..n {
        a[(i, i)] += problem.regularization[i];
    }
    let ac = &a * &c;
    let mut mm = c.transpose() * ac;
    let mut q = c.transpose() * (&a * &c0 + &problem.bias);
    for (i, j, x) in extra {
        mm[(i, j)] += x;
    }
    for (i, x) in e_entries {
        q[i] += x;
    }
    Lcp { m: mm, q, c, c0 }
}

/// Solves the LCP `w = M z + q ⟂ z ≥ 0` by Lemke's method; returns z and the number of pivots
/// (over all attempts). The covering vector of ones comes first; if that path ends on a ray or
/// at the pivot limit, which rounding can cause on degenerate problems (a box's four coplanar
/// corners make its normal rows dependent), the method restarts with two other positive
/// covering vectors: a different path to the same solution set (Cottle, Pang & Stone §4.4).
pub fn lemke(
    m: &DMatrix<f64>,
    q: &DVector<f64>,
    options: &LemkeOptions,
) -> Result<(DVector<f64>, usize), SolverError> {
    let n = q.len();
    if m.shape() != (n, n) {
        return Err(SolverError::InvalidProblem(format!("M is {:?}, q has {n} entries", m.shape())));
    }
    let golden = |i: usize| ((i as f64 + 1.0) * 0.618_033_988_749_895).fract();
    let coverings = [
        DVector::from_element(n, 1.0),
        DVector::from_fn(n, |i, _| 1.0 + golden(i)),
        DVector::from_fn(n, |i, _| m[(i, i)].abs().max(1e-3 * m.amax()).max(f64::MIN_POSITIVE)),
    ];
    let mut total = 0;
    let mut last_error = None;
    for d in &coverings {
        match lemke_with_covering(m, q, d, options) {
            Ok((z, pivots)) => return Ok((z, total + pivots)),
            Err(e @ (SolverError::LemkeRay { .. } | SolverError::PivotLimit { .. })) => {
                total += match e {
                    SolverError::LemkeRay { pivots } | SolverError::PivotLimit { pivots } => pivots,
                    _ => 0,
                };
                last_error = Some(e);
            }
            Err(e) => return Err(e),
        }
    }
    Err(last_error.unwrap_or(SolverError::PivotLimit { pivots: total }))
}

/// Lemke's method with the covering vector `d` (all entries positive).
fn lemke_with_covering(
    m: &DMatrix<f64>,
    q: &DVector<f64>,
    d: &DVector<f64>,
    options: &LemkeOptions,
) -> Result<(DVector<f64>, usize), SolverError> {
    let n = q.len();
    if m.shape() != (n, n) {
        return Err(SolverError::InvalidProblem(format!("M is {:?}, q has {n} entries", m.shape())));
    }
    if q.iter().all(|&x| x >= 0.0) {
        return Ok((DVector::zeros(n), 0));
    }
    let scale = m.amax().max(1.0);
    let pivot_eps = options.pivot_tolerance * scale;
    let max_pivots = if options.max_pivots == 0 { 50 * n + 100 } else { options.max_pivots };
    // Variables: w_i = i, z_j = n + j, z0 = 2n. Columns of [I, −M, −d].
    let z0 = 2 * n;
    let mut basis: Vec<usize> = (0..n).collect();
    let mut b_inv = DMatrix::<f64>::identity(n, n);
    let mut x = q.clone();
    let mut column = DVector::zeros(n);
    let load_column = |var: usize, b_inv: &DMatrix<f64>, out: &mut DVector<f64>| {
        if var < n {
            out.copy_from(&b_inv.column(var));
        } else if var < 2 * n {
            out.gemv(-1.0, b_inv, &m.column(var - n), 0.0);
        } else {
            out.gemv(-1.0, b_inv, d, 0.0);
        }
    };
    // First pivot: z0 enters, the row of the most negative q_i / d_i leaves (ties: lowest index).
    let mut row = (0..n).min_by(|&a, &b| (q[a] / d[a]).total_cmp(&(q[b] / d[b]))).unwrap_or(0);
    let mut entering = z0;
    for pivots in 0..=max_pivots {
        if pivots > 0 {
            load_column(entering, &b_inv, &mut column);
            row = match ratio_test(&x, &column, &b_inv, &basis, z0, pivot_eps) {
                Some(r) => r,
                None => return Err(SolverError::LemkeRay { pivots }),
            };
        } else {
            load_column(entering, &b_inv, &mut column);
        }
        pivot(&mut b_inv, &mut x, &column, row);
        let leaving = std::mem::replace(&mut basis[row], entering);
        if leaving == z0 {
            let mut z = DVector::zeros(n);
            for (i, &var) in basis.iter().enumerate() {
                if (n..2 * n).contains(&var) {
                    z[var - n] = x[i].max(0.0);
                }
            }
            return Ok((z, pivots + 1));
        }
        entering = if leaving < n { leaving + n } else { leaving - n };
    }
    Err(SolverError::PivotLimit { pivots: max_pivots })
}

/// Lexicographic minimum-ratio test: among rows with a positive column entry, the one whose
/// (x_i, B⁻¹_i·) / col_i is lexicographically smallest; z0's row wins a tie on the ratio.
fn ratio_test(
    x: &DVector<f64>,
    column: &DVector<f64>,
    b_inv: &DMatrix<f64>,
    basis: &[usize],
    z0: usize,
    eps: f64,
) -> Option<usize> {
    let mut best: Option<usize> = None;
    let n = x.len();
    for i in 0..n {
        if column[i] <= eps {
            continue;
        }
        best = Some(match best {
            None => i,
            Some(b) => {
                // Basic values are ≥ 0 in exact arithmetic; a rounding-negative one would win the
                // test with a negative step and leave the basis infeasible.
                let (ri, rb) = (x[i].max(0.0) / column[i], x[b].max(0.0) / column[b]);
                // Ties within rounding of the explicitly updated B⁻¹ (a few hundred ulps after
                // tens of pivots) go to the lexicographic rule: a strict 1e-12 let a symmetric
                // four-corner contact pick a wrong row on rounding and end on a ray.
                let tie = (ri - rb).abs() <= 1e-9 * ri.abs().max(rb.abs()).max(1e-300);
                if !tie {
                    if ri < rb {
                        i
                    } else {
                        b
                    }
                } else if basis[i] == z0 {
                    i
                } else if basis[b] == z0 {
                    b
                } else {
                    // Compare rows of B⁻¹ scaled by the pivot entries.
                    let mut choice = b;
                    for j in 0..n {
                        let (ci, cb) = (b_inv[(i, j)] / column[i], b_inv[(b, j)] / column[b]);
                        if (ci - cb).abs() > 1e-14 * ci.abs().max(cb.abs()) {
                            choice = if ci < cb { i } else { b };
                            break;
                        }
                    }
                    choice
                }
            }
        });
    }
    best
}

/// The product-form update of B⁻¹ and x for `column` entering at `row` (Gauss–Jordan step).
fn pivot(b_inv: &mut DMatrix<f64>, x: &mut DVector<f64>, column: &DVector<f64>, row: usize) {
    let n = x.len();
    let p = column[row];
    for j in 0..n {
        b_inv[(row, j)] /= p;
    }
    x[row] /= p;
    // Column by column: B⁻¹ is column-major, and each entry gets the same single update
    // B⁻¹_ij −= col_i · B⁻¹_rj as row by row would give it (row-wise loops strode by n).
    for j in 0..n {
        let v = b_inv[(row, j)];
        if v == 0.0 {
            continue;
        }
        for (i, (b, &f)) in b_inv.column_mut(j).iter_mut().zip(column.iter()).enumerate() {
            if i != row && f != 0.0 {
                *b -= f * v;
            }
        }
    }
    let xr = x[row];
    for i in 0..n {
        if i != row && column[i] != 0.0 {
            x[i] -= column[i] * xr;
        }
    }
}

/// Lemke's method as a [`ConstraintSolver`] (friction as a pyramid; a cone is approximated by
/// `facets` directions).
#[derive(Clone, Debug)]
pub struct LemkeSolver {
    /// Pivoting options.
    pub options: LemkeOptions,
    /// Pyramid directions used when the problem states a cone.
    pub facets: usize,
}

impl Default for LemkeSolver {
    fn default() -> Self {
        Self { options: LemkeOptions::default(), facets: 8 }
    }
}

impl ConstraintSolver for LemkeSolver {
    fn name(&self) -> &'static str {
        "lemke"
    }

    fn solve(
        &mut self,
        problem: &ConstraintProblem,
        lambda: &mut DVector<f64>,
    ) -> Result<SolveInfo, SolverError> {
        check_problem(problem)?;
        if matches!(problem.friction, FrictionModel::Cone) && self.facets < 3 {
            return Err(SolverError::InvalidProblem(format!(
                "a friction cone needs a pyramid of at least 3 facets, Lemke was given {}",
                self.facets
            )));
        }
        let lcp = lcp_of(problem, self.facets);
        let (z, pivots) = lemke(&lcp.m, &lcp.q, &self.options)?;
        // Verify before returning: the LCP's own natural residual, relative to the data.
        let w = &lcp.m * &z + &lcp.q;
        let residual = z.iter().zip(w.iter()).map(|(z, w)| z.min(*w).abs()).fold(0.0, f64::max);
        let scale = lcp.q.amax().max(1.0);
        if residual.is_nan() || residual > self.options.tolerance * scale {
            return Err(SolverError::Inaccurate {
                solver: "lemke".into(),
                residual,
                tolerance: self.options.tolerance * scale,
            });
        }
        *lambda = &lcp.c * &z + &lcp.c0;
        let note = matches!(problem.friction, FrictionModel::Cone)
            .then(|| format!("friction cone approximated by a {}-facet pyramid", self.facets));
        Ok(SolveInfo { iterations: pivots, note, residuals: None })
    }
}
