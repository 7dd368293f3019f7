//! W, the factor of the Delassus matrix `A = W Wᵀ` that the Newton solver works with: the
//! problem's own sparse rows when assembly kept them (W = J L⁻¹ D^{-1/2}, one block per
//! multibody), else the Cholesky factor of its dense A (one block), and the two products the
//! solver needs, `W x` and `Wᵀ λ`.

use super::super::SolverError;
use crate::constraints::{ConstraintProblem, RowSparsity};

/// Whether the problem carries W's rows (it was assembled from multibody blocks).
pub(super) fn has_rows(problem: &ConstraintProblem) -> bool {
    let sp = &problem.sparsity;
    !sp.is_empty() && sp.run_start.len() == problem.rows() + 1 && sp.row_start.len() == problem.rows() + 1
}

/// Fills `own` with W = L, A + δI = L Lᵀ (lower triangular, one run per row over columns
/// 0..=i), δ a relative 1e-13 of A's largest diagonal entry so that a singular A (redundant
/// rows) factors; the certificate is computed with A itself.
pub(super) fn dense_factor(problem: &ConstraintProblem, own: &mut RowSparsity) -> Result<(), SolverError> {
    let n = problem.rows();
    let mut a = problem.delassus_dense().into_owned();
    let largest = (0..n).map(|i| a[(i, i)]).fold(0.0, f64::max);
    let shift = 1e-13 * largest.max(f64::MIN_POSITIVE);
    for i in 0..n {
        a[(i, i)] += shift;
    }
    let l = nalgebra::Cholesky::new(a)
        .ok_or_else(|| SolverError::InvalidProblem("newton: A is not positive semi-definite".into()))?
        .unpack();
    *own = RowSparsity { nv: n, blocks: vec![(0, n)], ..RowSparsity::default() };
    own.row_start.push(0);
    own.entry_run_start.push(0);
    own.run_start.push(0);
    for i in 0..n {
        own.blocks_of_row.push(0);
        own.row_start.push(own.blocks_of_row.len());
        own.runs.push((0, own.w_values.len(), i + 1));
        own.w_values.extend((0..=i).map(|j| l[(i, j)]));
        own.run_start.push(own.runs.len());
        own.entry_run_start.push(own.runs.len());
        own.row_norm2.push((0..=i).map(|j| l[(i, j)] * l[(i, j)]).sum());
    }
    Ok(())
}

/// `out_i = W_i · x + c_i` for every row.
pub(super) fn product(w: &RowSparsity, x: &[f64], c: &[f64], out: &mut [f64]) {
    for (i, out) in out.iter_mut().enumerate() {
        *out =
            c[i] + w.row_spans(i).map(|(col, wi)| crate::math::dot(wi, &x[col..col + wi.len()])).sum::<f64>();
    }
}

/// `out = Wᵀ λ`.
pub(super) fn transpose_product(w: &RowSparsity, lambda: &[f64], out: &mut [f64]) {
    out.fill(0.0);
    for (i, &l) in lambda.iter().enumerate() {
        if l != 0.0 {
            for (col, wi) in w.row_spans(i) {
                for (o, wi) in out[col..col + wi.len()].iter_mut().zip(wi) {
                    *o += l * wi;
                }
            }
        }
    }
}
