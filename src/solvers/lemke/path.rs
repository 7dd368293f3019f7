//! One complementary pivoting path of Lemke's method (Cottle, Pang & Stone, "The Linear
//! Complementarity Problem", §4.4) on `I w − M z − d z0 = q` with a positive covering vector d:
//! z0 enters at the row of the most negative q_i / d_i, then each pivot brings in the complement
//! of the variable that just left, until z0 leaves (a solution), the entering column has no
//! positive entry (a secondary ray) or the pivot limit is reached.
//!
//! The minimum-ratio test is lexicographic (Cottle, Pang & Stone §4.9): among rows whose ratios
//! tie, the one whose row of `B⁻¹ / α_i` is lexicographically smallest, which is the exact
//! outcome of perturbing q by (ε, ε², …, εⁿ) and never cycles. Column j of B⁻¹ is read by a
//! solve with e_j — or for free when w_j is basic at position p, as then B⁻¹ e_j = e_p — and
//! only as many columns are read as the tie needs; a tie that needs more solves than it has rows
//! reads the tied rows of B⁻¹ instead (transposed solves).

use super::basis::{Basis, Singular, NONE};
use super::columns::Columns;

/// How a path ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum PathEnd {
    /// z0 left the basis: the basic values are a solution (of the problem the path solved).
    Solved,
    /// The entering variable's column (in `Path::alpha`) has no positive entry: the path leaves
    /// along a secondary ray.
    Ray {
        /// The variable that could not enter.
        entering: usize,
    },
    /// The pivot limit was reached.
    PivotLimit,
    /// The basis's operations reached [`PathOptions::max_operations`].
    WorkLimit,
    /// A basis came back (rounding defeated the anti-cycling rule): the path would cycle.
    Cycle,
    /// A refactorization found the basis singular.
    Singular(Singular),
}

/// Tolerances and limits of a path.
#[derive(Clone, Copy, Debug)]
pub(super) struct PathOptions {
    /// Pivots allowed.
    pub max_pivots: usize,
    /// Operations of the basis ([`Basis::operations`]) allowed.
    pub max_operations: f64,
    /// A column entry must exceed this fraction of the column's largest to be a pivot.
    pub pivot_tolerance: f64,
    /// Updates between refactorizations (0: chosen from the sizes).
    pub refactor_interval: usize,
    /// Harris's tolerance δ relative to max(1, ‖q‖∞) ([`super::LemkeOptions::degeneracy_tolerance`]).
    pub degeneracy_tolerance: f64,
}

/// A pivoting path: its basis, basic values and counters.
pub(super) struct Path<'a> {
    cols: &'a Columns<'a>,
    q: &'a [f64],
    options: PathOptions,
    /// The factorized basis.
    pub basis: Basis,
    /// Basic values, by position.
    pub x: Vec<f64>,
    /// The last entering column solved against the basis, by position.
    pub alpha: Vec<f64>,
    /// Pivots done.
    pub pivots: usize,
    /// Solves with unit vectors done by the lexicographic tie-break.
    pub lex_solves: usize,
    /// Harris's tolerance δ: basic values at most this large count as zero in the ratio test
    /// (degenerate rows), and a pivot may leave one at −δ.
    x_tol: f64,
    refactor_interval: usize,
    refactor_soon: bool,
    unit: Vec<f64>,
    column: Vec<f64>,
    ties: Vec<usize>,
    /// Rows of B⁻¹ of tied positions (`tie_positions`), for long tie-breaks.
    rows: Vec<f64>,
    tie_positions: Vec<usize>,
    row_of_tie: Vec<usize>,
    /// Zobrist hash of the set of basic variables, and the hashes seen on this path.
    basis_hash: u64,
    seen: std::collections::HashSet<u64>,
}

/// A pseudo-random 64-bit key of variable `var` (SplitMix64), for the basis hash.
fn key(var: usize) -> u64 {
    let mut z = (var as u64).wrapping_add(1).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl<'a> Path<'a> {
    /// A path for `q` with the columns `cols` (which hold the covering vector).
    pub fn new(cols: &'a Columns<'a>, q: &'a [f64], options: PathOptions) -> Self {
        let n = cols.n();
        let q_max = q.iter().fold(0.0f64, |a, &v| a.max(v.abs()));
        Self {
            cols,
            q,
            options,
            basis: Basis::identity(n),
            x: q.to_vec(),
            alpha: vec![0.0; n],
            pivots: 0,
            lex_solves: 0,
            x_tol: options.degeneracy_tolerance * q_max.max(1.0),
            refactor_interval: if options.refactor_interval > 0 { options.refactor_interval } else { 16 },
            refactor_soon: false,
            unit: vec![0.0; n],
            column: vec![0.0; n],
            ties: Vec::new(),
            rows: Vec::new(),
            tie_positions: Vec::new(),
            row_of_tie: vec![NONE; n],
            basis_hash: (0..n).fold(0, |h, var| h ^ key(var)),
            seen: std::collections::HashSet::new(),
        }
    }

    /// The columns the path pivots on.
    pub fn columns(&self) -> &'a Columns<'a> {
        self.cols
    }

    /// Runs the path to its end.
    pub fn run(&mut self) -> PathEnd {
        let n = self.cols.n();
        let z0 = 2 * n;
        if self.q.iter().all(|&v| v >= 0.0) {
            return PathEnd::Solved;
        }
        self.basis.solve_column(self.cols, z0, &mut self.alpha);
        let row = self.first_row();
        let leaving = self.pivot(row, z0, true);
        self.follow(leaving)
    }

    /// A path that starts from the complementary basis `vars` (z0 not among them) of an earlier
    /// path whose final values are slightly negative (its degenerate pivots' rounding), with
    /// this path's covering vector d = B·1 (`cols.d`, from [`covering_of_basis`]): then
    /// B⁻¹(−d) = −1, z0 enters at the most negative value, lifting every value to zero or more,
    /// and the path goes on from there until z0 leaves again — usually after a few pivots, as
    /// z0 starts at the size of the rounding.
    pub fn restart(&mut self, vars: &[usize]) -> PathEnd {
        let n = self.cols.n();
        let z0 = 2 * n;
        for var in 0..n {
            self.basis.position[var] = NONE;
        }
        for (p, &var) in vars.iter().enumerate() {
            self.basis.vars[p] = var;
            self.basis.position[var] = p;
        }
        self.basis_hash = vars.iter().fold(0, |h, &var| h ^ key(var));
        if let Err(singular) = self.refactor() {
            return PathEnd::Singular(singular);
        }
        self.basis.solve_column(self.cols, z0, &mut self.alpha);
        // z0's level t lifts x − t α ≥ 0: the row with the largest −x_p / |α_p| leaves.
        let (x, alpha) = (&self.x, &self.alpha);
        let row = (0..n)
            .filter(|&p| alpha[p] < 0.0)
            .min_by(|&a, &b| (x[a] / -alpha[a]).total_cmp(&(x[b] / -alpha[b])));
        match row {
            Some(row) if x[row] < 0.0 => {
                let leaving = self.pivot(row, z0, true);
                self.follow(leaving)
            }
            _ => PathEnd::Solved,
        }
    }

    /// Follows the path on from the pivot that took `leaving` out of the basis.
    fn follow(&mut self, mut leaving: usize) -> PathEnd {
        let n = self.cols.n();
        let z0 = 2 * n;
        loop {
            if leaving == z0 {
                return PathEnd::Solved;
            }
            if self.pivots >= self.options.max_pivots {
                return PathEnd::PivotLimit;
            }
            if self.basis.operations >= self.options.max_operations {
                return PathEnd::WorkLimit;
            }
            if !self.seen.insert(self.basis_hash) {
                return PathEnd::Cycle;
            }
            if self.refactor_soon || self.basis.updates() >= self.refactor_interval {
                if let Err(singular) = self.refactor() {
                    return PathEnd::Singular(singular);
                }
            }
            let entering = if leaving < n { leaving + n } else { leaving - n };
            self.basis.solve_column(self.cols, entering, &mut self.alpha);
            match self.ratio_test() {
                Some(row) => leaving = self.pivot(row, entering, false),
                None => return PathEnd::Ray { entering },
            }
        }
    }

    /// Factorizes the basis anew, recomputes the basic values from q and picks the next
    /// refactorization interval: about √(⅔k³ / n) updates balance the LU's ⅔k³ flops against
    /// the etas' O(n) per solve (two solves per pivot), within [16, 128].
    pub fn refactor(&mut self) -> Result<(), Singular> {
        self.basis.refactor(self.cols)?;
        self.basis.solve(self.cols, self.q, &mut self.x);
        self.refactor_soon = false;
        self.refactor_interval = if self.options.refactor_interval > 0 {
            self.options.refactor_interval
        } else {
            let k = self.basis.factorized_size() as f64;
            let n = self.cols.n().max(1) as f64;
            ((2.0 / 3.0 * k * k * k / n).sqrt() as usize).clamp(16, 128)
        };
        Ok(())
    }

    /// The first pivot's row: the lexicographic minimum of (q_i, e_iᵀ) / d_i, that is the most
    /// negative q_i / d_i and, among ties, the largest index (ε^i is smallest there).
    fn first_row(&self) -> usize {
        let d = &self.cols.d;
        let ratio = |i: usize| self.q[i] / d[i];
        let best = (0..self.q.len()).map(ratio).fold(f64::INFINITY, f64::min);
        let tie = 1e-12 * best.abs();
        (0..self.q.len()).rev().find(|&i| ratio(i) <= best + tie).unwrap_or(0)
    }

    /// Pivots `entering` (its column in `alpha`) in at position `row`; returns the variable
    /// that left. The first pivot (z0 in, α_r = −d_r < 0, q_r < 0) takes x_r / α_r as it is;
    /// later pivots clamp a rounding-negative x_r to a zero step.
    fn pivot(&mut self, row: usize, entering: usize, first: bool) -> usize {
        let a_r = self.alpha[row];
        let theta = if first { self.x[row] / a_r } else { self.x[row].max(0.0) / a_r };
        for (x, &a) in self.x.iter_mut().zip(&self.alpha) {
            *x -= theta * a;
        }
        self.x[row] = theta;
        let a_max = self.alpha.iter().fold(0.0f64, |m, &v| m.max(v.abs()));
        // A small pivot makes the eta ill-conditioned: start over from a fresh factorization.
        self.refactor_soon |= a_r.abs() < 1e-6 * a_max;
        self.pivots += 1;
        let leaving = self.basis.replace(row, entering, &self.alpha);
        self.basis_hash ^= key(leaving) ^ key(entering);
        leaving
    }

    /// The ratio test on `alpha`; `None` if no entry is a pivot.
    ///
    /// Harris's two passes (Harris 1973) with the lexicographic rule for degenerate rows: the
    /// bound θ_max = min (x_i + δ) / α_i over pivot entries admits every row whose ratio is
    /// within it (a basic value may then overshoot zero by at most δ, counted from zero: a
    /// value already below zero has less left); among them only pivots
    /// within a factor of 10 of the largest are taken, so that a column entry that is zero up
    /// to rounding never becomes a pivot because its row's ratio happens to be smallest. Among
    /// the admitted rows, the degenerate ones (x_i ≤ δ) go to the lexicographic rule; without
    /// any, the largest pivot is taken. z0's row wins whenever it is admitted.
    fn ratio_test(&mut self) -> Option<usize> {
        let a_max = self.alpha.iter().fold(0.0f64, |m, &v| m.max(v.abs()));
        if a_max == 0.0 {
            return None;
        }
        let eps = self.options.pivot_tolerance * a_max;
        let delta = self.x_tol;
        let value = |x: f64| if x > delta { x } else { 0.0 };
        // A row already below zero keeps only what is left of its allowance δ, so that
        // overshoots do not add up over degenerate pivots into a basis that is infeasible by
        // many δ (which no refinement of the final values repairs).
        let mut theta_max = f64::INFINITY;
        for (&x, &a) in self.x.iter().zip(&self.alpha) {
            if a > eps {
                theta_max = theta_max.min((value(x) + delta + x.min(0.0)) / a);
            }
        }
        if theta_max == f64::INFINITY {
            return None;
        }
        let theta_max = theta_max.max(0.0);
        let admitted = |x: f64, a: f64| a > eps && value(x) / a <= theta_max;
        let z0_at = self.basis.position[2 * self.cols.n()];
        if z0_at != NONE && admitted(self.x[z0_at], self.alpha[z0_at]) {
            return Some(z0_at);
        }
        let mut a_big = 0.0f64;
        for (&x, &a) in self.x.iter().zip(&self.alpha) {
            if admitted(x, a) {
                a_big = a_big.max(a);
            }
        }
        let floor = 0.1 * a_big;
        self.ties.clear();
        let mut largest = None;
        for (i, (&x, &a)) in self.x.iter().zip(&self.alpha).enumerate() {
            if a >= floor && admitted(x, a) {
                if value(x) == 0.0 {
                    self.ties.push(i);
                }
                if largest.is_none_or(|(_, b)| a > b) {
                    largest = Some((i, a));
                }
            }
        }
        match self.ties.len() {
            0 => largest.map(|(i, _)| i),
            1 => Some(self.ties[0]),
            _ => Some(self.lexicographic_tie_break()),
        }
    }

    /// Narrows `ties` column by column of B⁻¹ (scaled by 1/α_i) to the lexicographic minimum.
    ///
    /// Columns are read by solves with e_j while that is cheap: after as many solves as there
    /// were ties, the rows of B⁻¹ of the ties left are read instead, one transposed solve each,
    /// and the remaining columns compared from them: a tie that needs many columns (a degenerate
    /// vertex of a pyramid of boxes can take hundreds) costs at most twice its size in solves.
    fn lexicographic_tie_break(&mut self) -> usize {
        let n = self.cols.n();
        let column_budget = self.ties.len();
        let mut column_solves = 0;
        let mut j = 0;
        while j < n && self.ties.len() > 1 {
            if self.drop_unit_column_tie(j) {
                j += 1;
                continue;
            }
            if column_solves == column_budget {
                break;
            }
            self.unit.fill(0.0);
            self.unit[j] = 1.0;
            self.basis.solve(self.cols, &self.unit, &mut self.column);
            self.lex_solves += 1;
            column_solves += 1;
            let column = &self.column;
            narrow(&mut self.ties, &self.alpha, |i| column[i]);
            j += 1;
        }
        if j < n && self.ties.len() > 1 {
            // Rows of B⁻¹ of the ties left: position p's in rows[t n..(t + 1) n] for
            // t = row_of_tie[p].
            let count = self.ties.len();
            self.rows.resize(count * n, 0.0);
            self.tie_positions.clear();
            self.tie_positions.extend_from_slice(&self.ties);
            for (t, &p) in self.tie_positions.iter().enumerate() {
                self.row_of_tie[p] = t;
                self.unit.fill(0.0);
                self.unit[p] = 1.0;
                self.basis.solve_transpose(self.cols, &self.unit, &mut self.rows[t * n..(t + 1) * n]);
                self.lex_solves += 1;
            }
            while j < n && self.ties.len() > 1 {
                if !self.drop_unit_column_tie(j) {
                    let (rows, row_of_tie, alpha) = (&self.rows, &self.row_of_tie, &self.alpha);
                    narrow(&mut self.ties, alpha, |p| rows[row_of_tie[p] * n + j]);
                }
                j += 1;
            }
            for &p in &self.tie_positions {
                self.row_of_tie[p] = NONE;
            }
        }
        // Ties left over all n columns are rounding (B⁻¹ has independent rows): take the
        // largest pivot entry.
        let alpha = &self.alpha;
        self.ties.iter().copied().max_by(|&a, &b| alpha[a].total_cmp(&alpha[b])).unwrap_or(0)
    }

    /// If w_j is basic (at position p), column j of B⁻¹ is e_p: row p has 1/α_p > 0 there and
    /// every other tied row 0, so p leaves the ties; returns whether w_j is basic.
    fn drop_unit_column_tie(&mut self, j: usize) -> bool {
        let p = self.basis.position[j];
        if p == NONE {
            return false;
        }
        if let Some(at) = self.ties.iter().position(|&i| i == p) {
            self.ties.swap_remove(at);
        }
        true
    }

    /// The value of variable `var` (0 when non-basic).
    pub fn value(&self, var: usize) -> f64 {
        match self.basis.position[var] {
            NONE => 0.0,
            p => self.x[p],
        }
    }

    /// Repairs a final complementary basis whose refined values are slightly negative (basic
    /// variables that should be zero, pushed below it by the rounding of hundreds of degenerate
    /// pivots through ill-conditioned bases): the most negative basic variable is swapped for
    /// its complement (a principal pivot, as in Murty's principal pivoting method) and the
    /// values refined again, at most `swaps` times and never twice for one pair; returns the
    /// swaps made. Near a solution such a swap moves the values by the size of the negative
    /// one, so a few swaps leave a basis feasible to the working precision.
    pub fn clean(&mut self, swaps: usize) -> Result<usize, Singular> {
        let n = self.cols.n();
        let zero = 1e-15 * self.q.iter().fold(1.0f64, |m, &v| m.max(v.abs()));
        let mut swapped = Vec::new();
        for _ in 0..swaps {
            self.polish(2)?;
            let negative = (0..n)
                .filter(|&p| self.x[p] < -zero && !swapped.contains(&(self.basis.vars[p] % n)))
                .min_by(|&a, &b| self.x[a].total_cmp(&self.x[b]));
            let Some(p) = negative else { break };
            let var = self.basis.vars[p];
            if var == 2 * n {
                break;
            }
            let complement = if var < n { var + n } else { var - n };
            self.basis.solve_column(self.cols, complement, &mut self.alpha);
            let a_max = self.alpha.iter().fold(0.0f64, |m, &v| m.max(v.abs()));
            if self.alpha[p].abs() <= 1e-9 * a_max {
                break;
            }
            let theta = self.x[p] / self.alpha[p];
            for (x, &a) in self.x.iter_mut().zip(&self.alpha) {
                *x -= theta * a;
            }
            self.x[p] = theta;
            self.basis.replace(p, complement, &self.alpha);
            swapped.push(var % n);
        }
        self.polish(2)?;
        Ok(swapped.len())
    }

    /// Refines the basic values by `steps` rounds of iterative refinement x ← x + B⁻¹(q − B x),
    /// the residual q − B x accumulated in double-double arithmetic (each product split exactly
    /// by a fused multiply-add, each sum by TwoSum; Ogita, Rump & Oishi 2005) so that the
    /// refined x is accurate to the working precision rather than to κ(B) times it (Wilkinson's
    /// refinement with an extended residual). The basis is refactorized first when it carries
    /// eta updates (a fresh factorization is the better corrector after many pivots).
    pub fn polish(&mut self, steps: usize) -> Result<(), Singular> {
        if self.basis.updates() > 0 {
            self.refactor()?;
        }
        self.refine(steps);
        Ok(())
    }

    /// `steps` rounds of the refinement of [`Self::polish`] on the current factorization.
    fn refine(&mut self, steps: usize) {
        let n = self.cols.n();
        let (mut high, mut low) = (vec![0.0; n], vec![0.0; n]);
        let mut correction = vec![0.0; n];
        for _ in 0..steps {
            high.copy_from_slice(self.q);
            low.fill(0.0);
            for (p, &var) in self.basis.vars.iter().enumerate() {
                let xp = self.x[p];
                if xp != 0.0 {
                    self.cols.for_each(var, |i, v| {
                        // −v x_p = product + error exactly; high + product = sum + rounding.
                        let product = -v * xp;
                        let error = (-v).mul_add(xp, -product);
                        let sum = high[i] + product;
                        let virtual_product = sum - high[i];
                        let rounding = (high[i] - (sum - virtual_product)) + (product - virtual_product);
                        high[i] = sum;
                        low[i] += rounding + error;
                    });
                }
            }
            for (h, l) in high.iter_mut().zip(&low) {
                *h += l;
            }
            if high.iter().all(|&r| r == 0.0) {
                break;
            }
            self.basis.solve(self.cols, &high, &mut correction);
            for (x, c) in self.x.iter_mut().zip(&correction) {
                *x += c;
            }
        }
    }
}

/// Keeps the ties whose `value(i) / α_i` is the smallest, within 1e-9 of the largest magnitude
/// (a column of zeros at every tie keeps them all).
fn narrow(ties: &mut Vec<usize>, alpha: &[f64], value: impl Fn(usize) -> f64) {
    let scaled = |i: usize| value(i) / alpha[i];
    let largest = ties.iter().fold(0.0f64, |m, &i| m.max(scaled(i).abs()));
    if largest == 0.0 {
        return;
    }
    let smallest = ties.iter().map(|&i| scaled(i)).fold(f64::INFINITY, f64::min);
    let limit = smallest + 1e-9 * largest;
    ties.retain(|&i| scaled(i) <= limit);
}

/// The covering vector d = B·1 of a path restarted from the basis `vars`: the sum of the basic
/// columns of `[I, −M, −d]` (by row).
pub(super) fn covering_of_basis(cols: &Columns, vars: &[usize]) -> Vec<f64> {
    let mut d = vec![0.0; cols.n()];
    for &var in vars {
        cols.for_each(var, |i, v| d[i] += v);
    }
    d
}
