//! The LCP of a [`ConstraintProblem`] in the polyhedral-friction formulation (Stewart & Trinkle
//! 1996): per contact the normal impulse, k friction-direction impulses β_j and a slack γ (the
//! sliding speed); bounded rows by the usual split into a shifted variable and an upper-bound
//! multiplier; bilateral rows as the difference of two nonnegative variables.
//!
//! With `λ = C z + c0` the LCP is `w = Cᵀ(A + R)C z + Cᵀ((A + R) c0 + b) + E z + e`, where E and e
//! couple the friction slacks and the bound multipliers. [`lcp_of`] forms M by dense products
//! (what `gelenk export-problems` writes); the solver forms it by sparse columns
//! (`sparse_lcp_of`): C has at most two entries per column and A is zero between rows that share
//! no body, so the cost follows M's non-zeros rather than the m² · rows of dense products.

use super::columns::Csc;
use crate::constraints::{ConstraintProblem, FrictionModel, RowLaw};
use nalgebra::{DMatrix, DVector};

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

/// The LCP with M by sparse columns and C by its columns (row, coefficient).
pub(super) struct SparseLcp {
    /// M.
    pub m: Csc,
    /// q.
    pub q: DVector<f64>,
    /// Column j of C: the impulse rows variable j feeds, with their coefficients.
    pub c: Vec<Vec<(usize, f64)>>,
    /// c0.
    pub c0: DVector<f64>,
}

impl SparseLcp {
    /// λ = C z + c0.
    pub fn impulses(&self, z: &DVector<f64>) -> DVector<f64> {
        let mut lambda = self.c0.clone();
        for (col, &zj) in self.c.iter().zip(z.iter()) {
            for &(i, x) in col {
                lambda[i] += x * zj;
            }
        }
        lambda
    }
}

/// The LCP of `problem` with friction as a pyramid of `facets` directions (the problem's own
/// pyramid if it states one), by dense products (the arithmetic of `gelenk export-problems`'
/// lcp.npz; [`LemkeSolver`](super::LemkeSolver) forms the same M by sparse columns, equal up to
/// the rounding of the sums).
pub fn lcp_of(problem: &ConstraintProblem, facets: usize) -> Lcp {
    let Variables { columns, extra, e_entries, c0 } = variables(problem, facets);
    let (n, m) = (problem.rows(), columns.len());
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

/// The LCP's variables: the columns of C, the couplings E (i, j, E_ij) and e (i, e_i), and c0.
struct Variables {
    columns: Vec<Vec<(usize, f64)>>,
    extra: Vec<(usize, usize, f64)>,
    e_entries: Vec<(usize, f64)>,
    c0: DVector<f64>,
}

/// The variables of `problem`'s LCP with a pyramid of `facets` directions.
fn variables(problem: &ConstraintProblem, facets: usize) -> Variables {
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
    Variables { columns, extra, e_entries, c0 }
}

/// [`lcp_of`] with M by sparse columns.
///
/// Consecutive variables whose columns of C draw on the same impulse rows form a group (a
/// contact's k facet impulses share its two friction rows; a bilateral row's two variables its
/// one row). For each group the products g_r = Cᵀ (A + R) e_r of its rows r are formed once,
/// in dense scratch over the rows they touch, and each of its columns of M is the combination
/// Σ_r C_rj g_r plus its couplings E_j: a contact's facets cost one pass over their shared
/// pattern each instead of a product with A each.
pub(super) fn sparse_lcp_of(problem: &ConstraintProblem, facets: usize) -> SparseLcp {
    let Variables { columns, extra, e_entries, c0 } = variables(problem, facets);
    let n = problem.rows();
    let m = columns.len();
    let mut a = problem.delassus_dense().into_owned();
    for i in 0..n {
        a[(i, i)] += problem.regularization[i];
    }
    let shifted = &a * &c0 + &problem.bias;
    let mut q = DVector::from_fn(m, |i, _| columns[i].iter().map(|&(r, x)| x * shifted[r]).sum());
    for &(i, x) in &e_entries {
        q[i] += x;
    }
    // A + R by columns (symmetric: column r is row r), and the LCP variables each impulse row
    // feeds (Cᵀ by columns).
    let a = Csc::from_dense(&a);
    let mut vars_of_row: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    for (j, col) in columns.iter().enumerate() {
        for &(i, x) in col {
            vars_of_row[i].push((j, x));
        }
    }
    let mut extra_of_column: Vec<Vec<(usize, f64)>> = vec![Vec::new(); m];
    for &(i, j, x) in &extra {
        extra_of_column[j].push((i, x));
    }
    let same_rows = |i: usize, j: usize| {
        columns[i].len() == columns[j].len() && columns[i].iter().zip(&columns[j]).all(|(a, b)| a.0 == b.0)
    };
    // g_r for the (at most two, C having at most two entries per column) rows of a group, by
    // LCP variable over the union of their patterns; then one column at a time.
    let mut g = [vec![0.0; m], vec![0.0; m]];
    let mut touched = Vec::new();
    let mut seen = vec![false; m];
    let (mut col, mut col_rows) = (vec![0.0; m], Vec::new());
    let mut mm = Csc::with_capacity(m, a.nonzeros() * 8);
    let mut j = 0;
    while j < m {
        let mut end = j + 1;
        while end < m && same_rows(j, end) {
            end += 1;
        }
        debug_assert!(columns[j].len() <= 2, "C has at most two entries per column");
        for (slot, &(r, _)) in columns[j].iter().enumerate() {
            let (rows, values) = a.column(r);
            for (&s, &v) in rows.iter().zip(values) {
                for &(i, x) in &vars_of_row[s] {
                    if !seen[i] {
                        seen[i] = true;
                        touched.push(i);
                    }
                    g[slot][i] += x * v;
                }
            }
        }
        for jj in j..end {
            let c = &columns[jj];
            match c.len() {
                0 => {}
                1 => {
                    let x = c[0].1;
                    for &i in &touched {
                        col[i] = x * g[0][i];
                    }
                }
                _ => {
                    let (x0, x1) = (c[0].1, c[1].1);
                    for &i in &touched {
                        col[i] = x0 * g[0][i] + x1 * g[1][i];
                    }
                }
            }
            if !c.is_empty() {
                col_rows.extend_from_slice(&touched);
            }
            // A coupling in a row outside the group's pattern adds that row (E has at most one
            // entry per row and column).
            for &(i, x) in &extra_of_column[jj] {
                if !seen[i] {
                    col_rows.push(i);
                }
                col[i] += x;
            }
            for &i in &col_rows {
                if col[i] != 0.0 {
                    mm.push(i, col[i]);
                }
                col[i] = 0.0;
            }
            mm.end_column();
            col_rows.clear();
        }
        for &i in &touched {
            g[0][i] = 0.0;
            g[1][i] = 0.0;
            seen[i] = false;
        }
        touched.clear();
        j = end;
    }
    SparseLcp { m: mm, q, c: columns, c0 }
}
