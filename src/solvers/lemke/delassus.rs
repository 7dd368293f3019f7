//! A + R by sparse columns for the LCP's assembly, and the key of the inputs M depends on.
//!
//! A matrix-free problem (stacks, piles) stores W with A = W Wᵀ; A's column j is
//! Σ_c W_jc W_·c over the velocity columns c of row j's runs, formed from W's transpose (the rows
//! touching each velocity column): the cost follows the pairs of rows that share a body, not
//! the n² entries of the dense A. A problem with A formed gives its non-zeros.

use super::columns::Csc;
use crate::constraints::{ConstraintProblem, FrictionModel, RowLaw};

/// A + R (the problem's regularization on the diagonal) by sparse columns; `Err(limit)` as soon
/// as it would store more than `limit` entries (0: no limit), before allocating for them.
pub(super) fn delassus_plus_r(problem: &ConstraintProblem, limit: usize) -> Result<Csc, usize> {
    let n = problem.rows();
    let limit = if limit == 0 { usize::MAX } else { limit };
    if !problem.is_matrix_free() {
        // The dense A is in memory already; its sparse copy is checked once formed.
        let mut a = problem.delassus.clone();
        for i in 0..n {
            a[(i, i)] += problem.regularization[i];
        }
        let a = Csc::from_dense(&a);
        return if a.nonzeros() > limit { Err(limit) } else { Ok(a) };
    }
    let sp = &problem.sparsity;
    // Wᵀ: for each velocity column, the rows whose runs cover it and their entries.
    let mut start = vec![0usize; sp.nv + 1];
    for i in 0..n {
        for (col, values) in sp.row_spans(i) {
            for c in col..col + values.len() {
                start[c + 1] += 1;
            }
        }
    }
    for c in 0..sp.nv {
        start[c + 1] += start[c];
    }
    let mut cursor = start.clone();
    let mut rows_of = vec![0usize; start[sp.nv]];
    let mut values_of = vec![0.0; start[sp.nv]];
    for i in 0..n {
        for (col, values) in sp.row_spans(i) {
            for (c, &v) in (col..).zip(values) {
                rows_of[cursor[c]] = i;
                values_of[cursor[c]] = v;
                cursor[c] += 1;
            }
        }
    }
    let mut a = Csc::with_capacity(n, 0);
    let (mut column, mut seen, mut touched) = (vec![0.0; n], vec![false; n], Vec::new());
    for j in 0..n {
        for (col, values) in sp.row_spans(j) {
            for (c, &v) in (col..).zip(values) {
                if v == 0.0 {
                    continue;
                }
                for e in start[c]..start[c + 1] {
                    let i = rows_of[e];
                    if !seen[i] {
                        seen[i] = true;
                        touched.push(i);
                    }
                    column[i] += v * values_of[e];
                }
            }
        }
        if !seen[j] {
            seen[j] = true;
            touched.push(j);
        }
        column[j] += problem.regularization[j];
        for &i in &touched {
            if column[i] != 0.0 {
                a.push(i, column[i]);
            }
            column[i] = 0.0;
            seen[i] = false;
        }
        a.end_column();
        touched.clear();
        if a.nonzeros() > limit {
            return Err(limit);
        }
    }
    Ok(a)
}

/// Everything the LCP's M is formed from (the rows' laws, the contacts, the friction model and
/// facets, R, and A or W), kept to tell whether a new problem poses the same M: then the last
/// M and the factorization of the last basis serve again, only q being new.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct MatrixKey {
    laws: Vec<RowLaw>,
    contacts: Vec<(usize, u64, u64)>,
    facets: usize,
    regularization: Vec<u64>,
    delassus: Vec<u64>,
    runs: Vec<(usize, usize, usize)>,
    run_start: Vec<usize>,
    w_values: Vec<u64>,
}

impl MatrixKey {
    /// Whether `problem` (with `facets`) has this key, bit for bit.
    pub fn matches(&self, problem: &ConstraintProblem, facets: usize) -> bool {
        let bits = |x: &f64| x.to_bits();
        let sp = &problem.sparsity;
        self.facets == pyramid_facets(problem, facets)
            && self.laws == problem.laws
            && self.contacts.len() == problem.contacts.len()
            && self
                .contacts
                .iter()
                .zip(&problem.contacts)
                .all(|(k, c)| *k == (c.normal, c.mu.to_bits(), c.mu2.to_bits()))
            && self.regularization.iter().copied().eq(problem.regularization.iter().map(bits))
            && if problem.is_matrix_free() {
                self.delassus.is_empty()
                    && self.runs == sp.runs
                    && self.run_start == sp.run_start
                    && self.w_values.iter().copied().eq(sp.w_values.iter().map(bits))
            } else {
                self.runs.is_empty() && self.delassus.iter().copied().eq(problem.delassus.iter().map(bits))
            }
    }

    /// Makes this the key of `problem` (its buffers reused).
    pub fn fill(&mut self, problem: &ConstraintProblem, facets: usize) {
        let bits = |x: &f64| x.to_bits();
        self.facets = pyramid_facets(problem, facets);
        self.laws.clone_from(&problem.laws);
        self.contacts.clear();
        self.contacts.extend(problem.contacts.iter().map(|c| (c.normal, c.mu.to_bits(), c.mu2.to_bits())));
        self.regularization.clear();
        self.regularization.extend(problem.regularization.iter().map(bits));
        self.delassus.clear();
        self.runs.clear();
        self.run_start.clear();
        self.w_values.clear();
        if problem.is_matrix_free() {
            let sp = &problem.sparsity;
            self.runs.extend_from_slice(&sp.runs);
            self.run_start.extend_from_slice(&sp.run_start);
            self.w_values.extend(sp.w_values.iter().map(bits));
        } else {
            self.delassus.extend(problem.delassus.iter().map(bits));
        }
    }
}

/// The facets of the pyramid the LCP uses: the problem's own, or `facets` for a cone.
fn pyramid_facets(problem: &ConstraintProblem, facets: usize) -> usize {
    match problem.friction {
        FrictionModel::Pyramid { facets } => facets,
        FrictionModel::Cone => facets,
    }
}
