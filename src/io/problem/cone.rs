//! `cone.json` (the cone program in clarabel's `save_to_file` schema) and the QP form of a
//! problem without second-order cones (qpsolvers' `min ½xᵀPx + qᵀx, Gx ≤ h, Ax = b, lb ≤ x ≤ ub`).

use crate::constraints::ConstraintProblem;
use crate::solvers::{cone_program, ClarabelSolver};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, SupportedConeT};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// The settings [`ClarabelSolver`] hands to clarabel (as its `solve` builds them), with
/// clarabel's `save_to_file` sanitising: an infinite time limit is written as `f64::MAX`.
pub fn clarabel_settings(solver: &ClarabelSolver) -> DefaultSettings<f64> {
    DefaultSettings {
        verbose: false,
        max_iter: solver.max_iterations,
        tol_gap_abs: solver.tolerance,
        tol_gap_rel: solver.tolerance,
        tol_feas: solver.tolerance,
        tol_ktratio: 1e-8,
        time_limit: f64::MAX,
        ..DefaultSettings::default()
    }
}

#[derive(Serialize)]
struct ConeFile<'a> {
    #[serde(rename = "P")]
    p: &'a CscMatrix<f64>,
    q: &'a [f64],
    #[serde(rename = "A")]
    a: &'a CscMatrix<f64>,
    b: &'a [f64],
    cones: &'a [SupportedConeT<f64>],
    settings: DefaultSettings<f64>,
}

/// `cone.json`'s text: the cone program of `problem` in the JSON schema of clarabel's
/// `save_to_file` (readable by `DefaultSolver::load_from_file`), with [`clarabel_settings`].
pub fn cone_json(problem: &ConstraintProblem) -> Result<String, String> {
    let program = cone_program(problem);
    let file = ConeFile {
        p: &program.p,
        q: &program.q,
        a: &program.a,
        b: &program.b,
        cones: &program.cones,
        settings: clarabel_settings(&ClarabelSolver::default()),
    };
    serde_json::to_string(&file).map_err(|e| e.to_string())
}

/// A QP in qpsolvers' form: `min ½xᵀPx + qᵀx  s.t.  Gx ≤ h, Ax = b, lb ≤ x ≤ ub`, x = λ.
#[derive(Clone, Debug, PartialEq)]
pub struct QpForm {
    /// P = A + R (full, symmetric).
    pub p: DMatrix<f64>,
    /// q = b of the problem.
    pub q: DVector<f64>,
    /// Inequality rows (pyramid facets, one-sided friction boxes); may have 0 rows.
    pub g: DMatrix<f64>,
    /// Their right-hand side.
    pub h: DVector<f64>,
    /// Equality rows (λ_t = 0 of frictionless tangents); may have 0 rows.
    pub a: DMatrix<f64>,
    /// Their right-hand side.
    pub b: DVector<f64>,
    /// Lower bounds (−∞ where none).
    pub lb: DVector<f64>,
    /// Upper bounds (+∞ where none).
    pub ub: DVector<f64>,
}

/// The QP of `problem`'s cone program when it has no second-order cone (frictionless or pyramid
/// friction), else `None`. Rows with one entry become bounds, zero-cone rows equalities.
pub fn qp_of(problem: &ConstraintProblem) -> Option<QpForm> {
    let program = cone_program(problem);
    let n = problem.rows();
    let m = program.b.len();
    let mut dense = DMatrix::zeros(m, n);
    for j in 0..n {
        for k in program.a.colptr[j]..program.a.colptr[j + 1] {
            dense[(program.a.rowval[k], j)] += program.a.nzval[k];
        }
    }
    let (mut lb, mut ub) =
        (DVector::from_element(n, f64::NEG_INFINITY), DVector::from_element(n, f64::INFINITY));
    let (mut g_rows, mut a_rows): (Vec<usize>, Vec<usize>) = (Vec::new(), Vec::new());
    let mut row = 0;
    for cone in &program.cones {
        match *cone {
            SupportedConeT::ZeroConeT(d) => {
                a_rows.extend(row..row + d);
                row += d;
            }
            SupportedConeT::NonnegativeConeT(d) => {
                for r in row..row + d {
                    let entries: Vec<usize> = (0..n).filter(|&j| dense[(r, j)] != 0.0).collect();
                    // c x_j ≤ b_r is a bound b_r / c (+ 0.0 turns −0 into 0).
                    match entries[..] {
                        [j] if dense[(r, j)] > 0.0 => ub[j] = ub[j].min(program.b[r] / dense[(r, j)] + 0.0),
                        [j] => lb[j] = lb[j].max(program.b[r] / dense[(r, j)] + 0.0),
                        _ => g_rows.push(r),
                    }
                }
                row += d;
            }
            _ => return None,
        }
    }
    let select = |rows: &[usize]| {
        (
            DMatrix::from_fn(rows.len(), n, |i, j| dense[(rows[i], j)]),
            DVector::from_fn(rows.len(), |i, _| program.b[rows[i]]),
        )
    };
    let (g, h) = select(&g_rows);
    let (a, b) = select(&a_rows);
    let p = problem.delassus_dense().into_owned() + DMatrix::from_diagonal(&problem.regularization);
    Some(QpForm { p, q: problem.bias.clone(), g, h, a, b, lb, ub })
}
