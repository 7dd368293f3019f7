//! The convex (Anitescu 2006) relaxation as a cone program solved by clarabel's interior-point
//! method:
//!
//! `minimise ½ λᵀ (A + R) λ + bᵀ λ  subject to  λ ∈ K`,
//!
//! whose optimality conditions are `w = (A + R) λ + b ∈ K*`, `λ ⟂ w`. K is a product of: the
//! free line for bilateral rows (no constraint: their optimality condition is `w_i = 0`); the
//! nonnegative half-line for unilateral rows and box rows (two rows each, `λ − lo ≥ 0`,
//! `hi − λ ≥ 0`); per contact the second-order cone `‖(λ₁/μ, λ₂/μ₂)‖ ≤ λ_n` (exact Coulomb
//! friction) or the pyramid's k linear facets, and a zero cone pinning λ_t = 0 when μ = 0.
//! Without friction it is a plain QP. In clarabel's form `min ½xᵀPx + qᵀx, Ax + s = b, s ∈ C`:
//! P is the upper triangle of A + R, and the rows are ordered zero cone, nonnegative cone, then
//! one 3-dimensional second-order cone per contact.
//!
//! The relaxation's price: a sliding contact's normal velocity comes out as `μ‖u_t‖` instead of
//! 0 (the bodies "hover" while sliding). The residuals show it; the documentation says it.

use super::residuals::{pyramid_facet, pyramid_offset_and_half, Residuals};
use super::{check_problem, ConstraintSolver, SolveInfo, SolverError};
use crate::constraints::{ConstraintProblem, FrictionModel, RowLaw};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::DVector;

/// A cone program in clarabel's form: `min ½xᵀPx + qᵀx  s.t.  Ax + s = b, s ∈ cones`.
#[derive(Clone, Debug)]
pub struct ConeProgram {
    /// P, upper triangle, CSC.
    pub p: CscMatrix<f64>,
    /// q.
    pub q: Vec<f64>,
    /// A, CSC.
    pub a: CscMatrix<f64>,
    /// b.
    pub b: Vec<f64>,
    /// Cones, in row order.
    pub cones: Vec<SupportedConeT<f64>>,
}

/// Builds the cone program of `problem` (see the module documentation): the variables are λ
/// alone and P is the upper triangle of A + R, dense when A is (the form the exported problems
/// carry).
pub fn cone_program(problem: &ConstraintProblem) -> ConeProgram {
    let n = problem.rows();
    let delassus = problem.delassus_dense();
    // P: upper triangle of A + R, column by column.
    let (mut colptr, mut rowval, mut nzval) = (vec![0usize], Vec::new(), Vec::new());
    for j in 0..n {
        for i in 0..=j {
            let x = delassus[(i, j)] + if i == j { problem.regularization[i] } else { 0.0 };
            if x != 0.0 || i == j {
                rowval.push(i);
                nzval.push(x);
            }
        }
        colptr.push(rowval.len());
    }
    let p = CscMatrix::new(n, n, colptr, rowval, nzval);
    let (a, b, cones) = constraint_rows(problem, n, Vec::new());
    ConeProgram { p, q: problem.bias.iter().copied().collect(), a, b, cones }
}

/// The same program lifted to sparse form, for a matrix-free problem (A = W Wᵀ, W sparse): the
/// variables are (λ, y) with y = Wᵀλ ∈ ℝ^nv pinned by nv zero-cone rows, and the objective
/// `½ yᵀy + ½ λᵀRλ + bᵀλ` equals the λ-form's. Its KKT system has the sparsity of W instead
/// of A's n² entries, so clarabel's factorisation costs about the rows times the square of a
/// row's width rather than n³: a heap of a thousand contacts is solved in a fraction of a
/// second instead of minutes. `None` when the problem carries no W (A is formed).
pub fn lifted_cone_program(problem: &ConstraintProblem) -> Option<ConeProgram> {
    if !problem.is_matrix_free() {
        return None;
    }
    let n = problem.rows();
    let nv = problem.sparsity.nv;
    // P = diag(R, I): one entry per column.
    let diagonal: Vec<f64> =
        problem.regularization.iter().copied().chain(std::iter::repeat_n(1.0, nv)).collect();
    let p = CscMatrix::new(n + nv, n + nv, (0..=n + nv).collect(), (0..n + nv).collect(), diagonal);
    // y − Wᵀλ = 0: row k of the lifting holds −W_ik for every row i that touches column k.
    let mut lifting: Vec<Row> = (0..nv).map(|k| (vec![(n + k, 1.0)], 0.0)).collect();
    for i in 0..n {
        for (col, values) in problem.sparsity.row_spans(i) {
            for (k, &w) in values.iter().enumerate() {
                if w != 0.0 {
                    lifting[col + k].0.push((i, -w));
                }
            }
        }
    }
    let (a, b, cones) = constraint_rows(problem, n + nv, lifting);
    let q = problem.bias.iter().copied().chain(std::iter::repeat_n(0.0, nv)).collect();
    Some(ConeProgram { p, q, a, b, cones })
}

/// One constraint row of a cone program: its (column, coefficient) entries and its b.
type Row = (Vec<(usize, f64)>, f64);

/// The rows `A x + s = b, s ∈ cones` of the program over `columns` variables (λ first): the
/// given zero-cone rows `extra_zero` first, then each row law's and contact's cone rows (see the
/// module documentation).
fn constraint_rows(
    problem: &ConstraintProblem,
    columns: usize,
    extra_zero: Vec<Row>,
) -> (CscMatrix<f64>, Vec<f64>, Vec<SupportedConeT<f64>>) {
    let n = problem.rows();
    let (mut zero, mut nonneg, mut soc): (Vec<Row>, Vec<Row>, Vec<[Row; 3]>) =
        (extra_zero, Vec::new(), Vec::new());
    // A contact's normal row under the exact cone is constrained by its cone, not on its own.
    let mut cone_normal = vec![false; n];
    if matches!(problem.friction, FrictionModel::Cone) {
        for c in problem.contacts.iter().filter(|c| c.mu > 0.0 && c.mu2 > 0.0) {
            cone_normal[c.normal] = true;
        }
    }
    for (i, &under_cone) in cone_normal.iter().enumerate() {
        match problem.laws[i] {
            RowLaw::Unilateral => {
                if !under_cone {
                    nonneg.push((vec![(i, -1.0)], 0.0));
                }
            }
            RowLaw::Bounded { lo, hi } => {
                if lo.is_finite() {
                    nonneg.push((vec![(i, -1.0)], -lo));
                }
                if hi.is_finite() {
                    nonneg.push((vec![(i, 1.0)], hi));
                }
            }
            RowLaw::Bilateral | RowLaw::Friction { .. } => {}
        }
    }
    for c in &problem.contacts {
        let (nr, t1, t2) = c.rows();
        if c.mu == 0.0 || c.mu2 == 0.0 {
            // No friction along a zero-μ tangent; the other (if any) as a box |λ| ≤ μ λ_n.
            for (t, mu) in [(t1, c.mu), (t2, c.mu2)] {
                if mu == 0.0 {
                    zero.push((vec![(t, 1.0)], 0.0));
                } else {
                    nonneg.push((vec![(t, 1.0), (nr, -mu)], 0.0));
                    nonneg.push((vec![(t, -1.0), (nr, -mu)], 0.0));
                }
            }
            continue;
        }
        match problem.friction {
            FrictionModel::Cone => {
                soc.push([
                    (vec![(nr, -1.0)], 0.0),
                    (vec![(t1, -1.0 / c.mu)], 0.0),
                    (vec![(t2, -1.0 / c.mu2)], 0.0),
                ]);
            }
            FrictionModel::Pyramid { facets } => {
                let offset = pyramid_offset_and_half(facets).0;
                for j in 0..facets {
                    let (nx, ny) = pyramid_facet(facets, j);
                    nonneg.push((vec![(t1, nx / c.mu), (t2, ny / c.mu2), (nr, -offset)], 0.0));
                }
            }
        }
    }
    let mut rows: Vec<Row> = Vec::new();
    let mut cones = Vec::new();
    if !zero.is_empty() {
        cones.push(SupportedConeT::ZeroConeT(zero.len()));
        rows.extend(zero);
    }
    if !nonneg.is_empty() {
        cones.push(SupportedConeT::NonnegativeConeT(nonneg.len()));
        rows.extend(nonneg);
    }
    for block in soc {
        cones.push(SupportedConeT::SecondOrderConeT(3));
        rows.extend(block);
    }
    let m = rows.len();
    let mut triplets: Vec<(usize, usize, f64)> = Vec::new();
    for (r, (entries, _)) in rows.iter().enumerate() {
        for &(col, x) in entries {
            triplets.push((col, r, x));
        }
    }
    triplets.sort_by_key(|t| (t.0, t.1));
    let (mut colptr, mut rowval, mut nzval) = (vec![0usize; columns + 1], Vec::new(), Vec::new());
    for &(col, r, x) in &triplets {
        colptr[col + 1] += 1;
        rowval.push(r);
        nzval.push(x);
    }
    for j in 0..columns {
        colptr[j + 1] += colptr[j];
    }
    let a = CscMatrix::new(m, columns, colptr, rowval, nzval);
    let b = rows.iter().map(|(_, b)| *b).collect();
    (a, b, cones)
}

/// clarabel on the convex relaxation.
#[derive(Clone, Debug)]
pub struct ClarabelSolver {
    /// Absolute and relative gap and feasibility tolerance handed to clarabel.
    pub tolerance: f64,
    /// Iteration limit.
    pub max_iterations: u32,
    /// Accept clarabel's `AlmostSolved` (reduced accuracy); the residual check still applies.
    pub accept_almost_solved: bool,
}

impl Default for ClarabelSolver {
    fn default() -> Self {
        Self { tolerance: 1e-10, max_iterations: 200, accept_almost_solved: true }
    }
}

impl ConstraintSolver for ClarabelSolver {
    fn name(&self) -> &'static str {
        "clarabel"
    }

    fn solve(
        &mut self,
        problem: &ConstraintProblem,
        lambda: &mut DVector<f64>,
    ) -> Result<SolveInfo, SolverError> {
        check_problem(problem)?;
        let n = problem.rows();
        if n == 0 {
            *lambda = DVector::zeros(0);
            return Ok(SolveInfo::default());
        }
        let program = lifted_cone_program(problem).unwrap_or_else(|| cone_program(problem));
        let settings = DefaultSettings {
            verbose: false,
            max_iter: self.max_iterations,
            tol_gap_abs: self.tolerance,
            tol_gap_rel: self.tolerance,
            tol_feas: self.tolerance,
            tol_ktratio: 1e-8,
            ..DefaultSettings::default()
        };
        let mut solver =
            DefaultSolver::new(&program.p, &program.q, &program.a, &program.b, &program.cones, settings)
                .map_err(|e| SolverError::Clarabel { status: format!("setup failed: {e:?}") })?;
        solver.solve();
        let status = solver.solution.status;
        let note = match status {
            SolverStatus::Solved => None,
            SolverStatus::AlmostSolved if self.accept_almost_solved => {
                Some("clarabel: almost solved".to_string())
            }
            other => return Err(SolverError::Clarabel { status: format!("{other:?}") }),
        };
        *lambda = DVector::from_column_slice(&solver.solution.x[..n]);
        Ok(SolveInfo { iterations: solver.solution.iterations as usize, note, residuals: None })
    }

    fn certify(&self, residuals: &Residuals) -> f64 {
        residuals.convex()
    }
}
