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
use super::delassus::delassus_plus_r;
use super::lazy::ColumnCache;
use crate::constraints::{ConstraintProblem, FrictionModel, RowLaw};
use crate::solvers::SolverError;
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

/// The LCP with M by sparse columns and C by its columns (row, coefficient). M is formed in
/// full only when a path from the identity needs it ([`Self::form_m`]); a path from a warm
/// start reads the few columns it touches, each formed once ([`super::lazy`]).
#[derive(Clone, Debug)]
pub(super) struct SparseLcp {
    /// M, once formed.
    pub m: Option<Csc>,
    /// q.
    pub q: DVector<f64>,
    /// Column j of C: the impulse rows variable j feeds, with their coefficients.
    pub c: Vec<Vec<(usize, f64)>>,
    /// c0.
    pub c0: DVector<f64>,
    /// A + R.
    pub(super) a: Csc,
    /// e: (LCP row, entry).
    e_entries: Vec<(usize, f64)>,
    /// Cᵀ by columns: the LCP variables each impulse row feeds.
    pub(super) vars_of_row: Vec<Vec<(usize, f64)>>,
    /// E by columns.
    pub(super) extra_of_column: Vec<Vec<(usize, f64)>>,
    /// M's columns formed one at a time.
    pub(super) cache: std::cell::RefCell<ColumnCache>,
}

impl SparseLcp {
    /// q = Cᵀ((A + R) c0 + b) + e for `problem`, whose M is this LCP's (the same
    /// [`super::delassus::MatrixKey`]): only the bias b is new.
    pub fn update_q(&mut self, problem: &ConstraintProblem) {
        self.q = q_of(&self.a, &self.c, &self.c0, &self.e_entries, problem);
    }

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

/// z for impulses λ of `problem` (the inverse of λ = C z + c0 where it is one): a normal
/// impulse, the parts of a bilateral or free row, the offset of a bounded one from its bound,
/// and a contact's friction impulse as the two pyramid edges that span it (clamped into the
/// pyramid's angle sector); the friction slacks and bound multipliers are left at zero. The
/// guess a warm start's basis is read from. Also returns the friction slacks' indices (each
/// after its contact's k edge variables).
fn z_of_impulses(
    problem: &ConstraintProblem,
    facets: usize,
    lambda: &DVector<f64>,
) -> (Vec<f64>, Vec<usize>, usize) {
    let k = match problem.friction {
        FrictionModel::Pyramid { facets } => facets,
        FrictionModel::Cone => facets,
    };
    let mut z = Vec::new();
    for (i, law) in problem.laws.iter().enumerate() {
        let l = lambda[i];
        match *law {
            RowLaw::Unilateral => z.push(l.max(0.0)),
            RowLaw::Bilateral => z.extend([l.max(0.0), (-l).max(0.0)]),
            RowLaw::Bounded { lo, hi } => match (lo.is_finite(), hi.is_finite()) {
                (true, true) => z.extend([(l - lo).max(0.0), 0.0]),
                (true, false) => z.push((l - lo).max(0.0)),
                (false, true) => z.push((hi - l).max(0.0)),
                (false, false) => z.extend([l.max(0.0), (-l).max(0.0)]),
            },
            RowLaw::Friction { .. } => {}
        }
    }
    let sector = 2.0 * std::f64::consts::PI / k as f64;
    let mut slacks = Vec::new();
    for block in &problem.contacts {
        if block.mu == 0.0 && block.mu2 == 0.0 {
            continue;
        }
        let (_, t1, t2) = block.rows();
        let scaled = |x: f64, mu: f64| if mu > 0.0 { x / mu } else { 0.0 };
        let (s1, s2) = (scaled(lambda[t1], block.mu), scaled(lambda[t2], block.mu2));
        let first = z.len();
        z.resize(first + k + 1, 0.0);
        slacks.push(first + k);
        if s1 != 0.0 || s2 != 0.0 {
            let angle = s2.atan2(s1).rem_euclid(2.0 * std::f64::consts::PI);
            let j = ((angle / sector) as usize).min(k - 1);
            let (a, b) = (sector * j as f64, sector * (j + 1) as f64);
            let det = (b - a).sin();
            z[first + j] = ((s1 * b.sin() - s2 * b.cos()) / det).max(0.0);
            z[first + (j + 1) % k] = ((s2 * a.cos() - s1 * a.sin()) / det).max(0.0);
        }
    }
    (z, slacks, k)
}

impl SparseLcp {
    /// A complementary basis read from impulses λ of `problem` (a warm start): z from λ
    /// ([`z_of_impulses`]), w = M z + q, the friction slack γ of a contact with a friction
    /// impulse the sliding speed max(0, −min_j w_βj) its edges' rows ask for, then per index z_i basic where
    /// z_i > max(w_i, 0) in the equilibrated units (`col`: z = E z', `row`: w' = D w) by more
    /// than rounding, else w_i.
    /// `None` when λ does not fit the problem.
    pub fn basis_of_impulses(
        &self,
        problem: &ConstraintProblem,
        facets: usize,
        lambda: &DVector<f64>,
    ) -> Option<Vec<usize>> {
        let n = self.q.len();
        if lambda.len() != problem.rows() || !lambda.iter().all(|l| l.is_finite()) {
            return None;
        }
        let (mut z, slacks, k) = z_of_impulses(problem, facets, lambda);
        if z.len() != n {
            return None;
        }
        let mut w = self.q.as_slice().to_vec();
        self.mul_add(&z, &mut w);
        for &g in &slacks {
            let edges = g - k..g;
            // Without friction impulse the slack is degenerate (w_γ = μλ_n − Σβ = 0 whatever
            // γ), and a basic γ without a basic edge would make the basis singular.
            if z[edges.clone()].iter().all(|&beta| beta == 0.0) {
                continue;
            }
            let gamma = w[edges.clone()].iter().fold(0.0f64, |m, &x| m.max(-x));
            z[g] = gamma;
            for wj in &mut w[edges] {
                *wj += gamma;
            }
        }
        // Values within rounding of zero count as zero (a tiny edge impulse or sliding speed
        // would bring a column the solution does not need into the basis).
        let zero = 1e-10 * self.q.amax().max(1.0);
        let mut basis: Vec<usize> =
            (0..n).map(|i| if z[i] > w[i].max(0.0) + zero { n + i } else { i }).collect();
        // A basic γ whose edges are all non-basic has a zero column in the basis (its only
        // entries are in the edges' rows): w_γ stays basic instead.
        for &g in &slacks {
            if basis[g] == n + g && basis[g - k..g].iter().zip(g - k..g).all(|(&var, i)| var == i) {
                basis[g] = g;
            }
        }
        Some(basis)
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
///
/// Fails with [`SolverError::LemkeMatrixTooLarge`] when A + R would store more than
/// `max_entries` entries (0: no limit).
pub(super) fn sparse_lcp_of(
    problem: &ConstraintProblem,
    facets: usize,
    max_entries: usize,
) -> Result<SparseLcp, SolverError> {
    let Variables { columns, extra, e_entries, c0 } = variables(problem, facets);
    let n = problem.rows();
    let m = columns.len();
    // A + R by columns (symmetric: column r is row r), and the LCP variables each impulse row
    // feeds (Cᵀ by columns).
    let a =
        delassus_plus_r(problem, max_entries).map_err(|limit| SolverError::LemkeMatrixTooLarge { limit })?;
    let q = q_of(&a, &columns, &c0, &e_entries, problem);
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
    Ok(SparseLcp {
        m: None,
        q,
        c: columns,
        c0,
        a,
        e_entries,
        vars_of_row,
        extra_of_column,
        cache: Default::default(),
    })
}

impl SparseLcp {
    /// The blocks of variables polishing solves together ([`super::polish`]): the variables
    /// coupled by E (a contact's friction slack with its normal impulse and facets, a bound
    /// multiplier with its variable), which are the ones a zero diagonal of M couples; every
    /// other variable alone.
    pub fn blocks(&self) -> Vec<Vec<usize>> {
        let pairs = self
            .extra_of_column
            .iter()
            .enumerate()
            .flat_map(|(j, col)| col.iter().map(move |&(i, _)| (i, j)));
        super::polish::blocks_of_pairs(self.q.len(), pairs)
    }

    /// M in full, formed on the first call; [`SolverError::LemkeMatrixTooLarge`] as soon as it
    /// would store more than `max_entries` entries (0: no limit).
    pub fn form_m(&mut self, max_entries: usize) -> Result<&Csc, SolverError> {
        if self.m.is_none() {
            let limit = if max_entries == 0 { usize::MAX } else { max_entries };
            let m = self.assemble_m(limit).ok_or(SolverError::LemkeMatrixTooLarge { limit: max_entries })?;
            self.m = Some(m);
        }
        Ok(self.m.as_ref().expect("formed above"))
    }

    /// M by groups of columns sharing their impulse rows (see [`sparse_lcp_of`]); None once it
    /// holds more than `limit` entries.
    fn assemble_m(&self, limit: usize) -> Option<Csc> {
        let (columns, a, vars_of_row, extra_of_column) =
            (&self.c, &self.a, &self.vars_of_row, &self.extra_of_column);
        let m = columns.len();
        let same_rows = |i: usize, j: usize| {
            columns[i].len() == columns[j].len()
                && columns[i].iter().zip(&columns[j]).all(|(a, b)| a.0 == b.0)
        };
        // g_r for the (at most two, C having at most two entries per column) rows of a group, by
        // LCP variable over the union of their patterns; then one column at a time.
        let mut g = [vec![0.0; m], vec![0.0; m]];
        let mut touched = Vec::new();
        let mut seen = vec![false; m];
        let (mut col, mut col_rows) = (vec![0.0; m], Vec::new());
        let mut mm = Csc::with_capacity(m, (a.nonzeros() * 8).min(limit));
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
            if mm.nonzeros() > limit {
                return None;
            }
            for &i in &touched {
                g[0][i] = 0.0;
                g[1][i] = 0.0;
                seen[i] = false;
            }
            touched.clear();
            j = end;
        }
        Some(mm)
    }
}

/// q = Cᵀ((A + R) c0 + b) + e.
fn q_of(
    a: &Csc,
    columns: &[Vec<(usize, f64)>],
    c0: &DVector<f64>,
    e_entries: &[(usize, f64)],
    problem: &ConstraintProblem,
) -> DVector<f64> {
    let mut shifted = problem.bias.as_slice().to_vec();
    a.mul_add(c0.as_slice(), &mut shifted);
    let mut q = DVector::from_fn(columns.len(), |i, _| columns[i].iter().map(|&(r, x)| x * shifted[r]).sum());
    for &(i, x) in e_entries {
        q[i] += x;
    }
    q
}
