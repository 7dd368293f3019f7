//! A pivoted Cholesky factor `P ≈ F Fᵀ` of the QP matrix `P = A + R` of a problem: the
//! quadratic objective of the CBF file (CBF has conic constraints only), and the corpus index's
//! rank and conditioning estimate.

use crate::constraints::ConstraintProblem;
use nalgebra::DMatrix;

/// `P = F Fᵀ` up to rounding, `F` n × rank.
#[derive(Clone, Debug, PartialEq)]
pub struct PivotedCholesky {
    /// The factor, n × rank (column k has zeros in the rows pivoted before k).
    pub factor: DMatrix<f64>,
    /// The pivots `d_k` (the Schur-complement diagonal chosen at step k), largest first.
    pub pivots: Vec<f64>,
}

impl PivotedCholesky {
    /// The numerical rank: columns kept.
    pub fn rank(&self) -> usize {
        self.pivots.len()
    }

    /// `d_1 / d_rank`: a cheap estimate (from below, usually within a small factor) of the
    /// condition number of P restricted to its range; 1 for rank ≤ 1, +∞ for rank 0.
    pub fn condition_estimate(&self) -> f64 {
        match (self.pivots.first(), self.pivots.last()) {
            (Some(&first), Some(&last)) if last > 0.0 => first / last,
            _ => f64::INFINITY,
        }
    }
}

/// The QP matrix `P = A + R` of `problem` (dense, symmetric positive semidefinite).
pub fn qp_matrix(problem: &ConstraintProblem) -> DMatrix<f64> {
    let mut p = problem.delassus_dense().into_owned();
    for i in 0..p.nrows() {
        p[(i, i)] += problem.regularization[i];
    }
    p
}

/// The pivoted (diagonal-pivoting, outer-product) Cholesky factor of the symmetric positive
/// semidefinite `p`, stopped when the largest remaining diagonal is at most `n ε` times the
/// largest diagonal of `p`: O(n rank²) operations.
pub fn pivoted_cholesky(p: &DMatrix<f64>) -> PivotedCholesky {
    let n = p.nrows();
    let mut d: Vec<f64> = (0..n).map(|i| p[(i, i)]).collect();
    let scale = d.iter().copied().fold(0.0, f64::max);
    let stop = n as f64 * f64::EPSILON * scale;
    let mut used = vec![false; n];
    let mut columns: Vec<Vec<f64>> = Vec::new();
    let mut pivots = Vec::new();
    loop {
        let best = (0..n).filter(|&i| !used[i]).max_by(|&a, &b| d[a].total_cmp(&d[b]));
        let Some(k) = best.filter(|&k| d[k] > stop && d[k] > 0.0) else { break };
        used[k] = true;
        let root = d[k].sqrt();
        let mut column = vec![0.0; n];
        for i in (0..n).filter(|&i| !used[i] || i == k) {
            let mut x = p[(i, k)];
            for c in &columns {
                x -= c[i] * c[k];
            }
            column[i] = x / root;
        }
        column[k] = root;
        for i in (0..n).filter(|&i| !used[i]) {
            d[i] -= column[i] * column[i];
        }
        pivots.push(d[k]);
        columns.push(column);
    }
    let rank = columns.len();
    let factor = DMatrix::from_fn(n, rank, |i, j| columns[j][i]);
    PivotedCholesky { factor, pivots }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_factor_reproduces_a_semidefinite_matrix_and_finds_its_rank() {
        // P = B Bᵀ with B 5 × 3: rank 3.
        let b = DMatrix::from_fn(5, 3, |i, j| ((i * 7 + j * 3) % 5) as f64 - 1.5 + 0.1 * j as f64);
        let p = &b * b.transpose();
        let f = pivoted_cholesky(&p);
        assert_eq!(f.rank(), 3);
        let error = (&f.factor * f.factor.transpose() - &p).abs().max();
        assert!(error < 1e-12 * p.abs().max(), "{error}");
        assert!(f.condition_estimate() >= 1.0 && f.condition_estimate().is_finite());
        assert_eq!(pivoted_cholesky(&DMatrix::zeros(2, 2)).rank(), 0);
    }
}
