//! The basis of Lemke's method as a factorization, never an explicit inverse.
//!
//! The basis B holds m columns of `[I, −M, −d]` (w_i's column is e_i, z_j's is −M·j, the
//! artificial z0's is −d). At a refactorization, let N be the rows whose w is not basic (k of
//! them, as many as the basic columns that are not unit columns). Ordering the rows (N, rest) and
//! the columns (non-unit, unit), B = [[B_N, 0], [B_S, I]]: only the k × k block B_N is
//! factorized, by LU with partial pivoting (faer), and a solve costs the LU's two triangular
//! solves plus one pass over the non-unit columns' entries. Lemke's basis starts as I and its
//! k grows only with the variables that become active, so k is often far below m.
//!
//! Between refactorizations each column replacement appends an eta vector (the product form
//! B_t = B_0 E_1 ⋯ E_t, E_s the identity with column r_s replaced by B_{s−1}⁻¹ a_s; Dantzig &
//! Orchard-Hays 1954): a solve applies B_0⁻¹ and then each E_s⁻¹ at the cost of its non-zeros.
//! The caller refactorizes after a number of updates chosen to balance the LU's O(k³) against
//! the etas' growing cost, and whenever accuracy is in doubt.

use super::columns::Columns;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting::{factor, solve};
use faer::perm::PermRef;
use faer::{MatMut, MatRef, Par};

/// Marks "none" in the index maps.
pub(super) const NONE: usize = usize::MAX;

/// A factorized basis with its eta file.
pub(super) struct Basis {
    n: usize,
    /// The basic variable at each position (w_i = i, z_j = n + j, z0 = 2n).
    pub vars: Vec<usize>,
    /// The position of each variable, [`NONE`] when non-basic.
    pub position: Vec<usize>,
    // The basis B_0 of the last refactorization.
    /// Rows whose w was non-basic, in the LU's row order.
    rows_n: Vec<usize>,
    /// The slot of each row in `rows_n`, or [`NONE`].
    row_slot: Vec<usize>,
    /// Per LU column: its position in B_0 and the variable that held it.
    col_pos: Vec<usize>,
    col_var: Vec<usize>,
    /// The position of w_i in B_0 for the other rows, [`NONE`] for the rows of `rows_n`.
    w_pos: Vec<usize>,
    /// L and U of B_N (unit lower and upper triangle in one k × k column-major matrix, in the
    /// first k² entries; the buffer is kept across refactorizations) and its row permutation.
    lu: Vec<f64>,
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    stack: MemBuffer,
    /// Floating-point operations of the solves and factorizations so far (an estimate from the
    /// sizes: 2k² per triangular pair, ⅔k³ per LU, one per eta entry and per row), the measure
    /// of a path's work that [`super::LemkeOptions::max_operations`] bounds.
    pub operations: f64,
    /// Scratch of the LU factorization, grown as k grows.
    factor_stack: MemBuffer,
    factor_stack_k: usize,
    // The eta file: per update its position, pivot entry and off-pivot non-zeros.
    eta_pos: Vec<usize>,
    eta_pivot: Vec<f64>,
    eta_start: Vec<usize>,
    eta_index: Vec<usize>,
    eta_value: Vec<f64>,
    /// Scratch: a right-hand side by row, a right-hand side by position (transposed solves),
    /// and the k-vector of the LU solve.
    work: Vec<f64>,
    work_by_position: Vec<f64>,
    small: Vec<f64>,
    /// Refactorizations done.
    pub refactorizations: usize,
}

/// Why a refactorization failed: B_N's LU has a pivot this small relative to its largest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Singular {
    /// min |U_ii| / max |U_ii|.
    pub ratio: f64,
}

impl Basis {
    /// The starting basis: every w basic at its own position (B = I).
    pub fn identity(n: usize) -> Self {
        let mut position = vec![NONE; 2 * n + 1];
        for (i, p) in position.iter_mut().enumerate().take(n) {
            *p = i;
        }
        Self {
            n,
            vars: (0..n).collect(),
            position,
            rows_n: Vec::new(),
            row_slot: vec![NONE; n],
            col_pos: Vec::new(),
            col_var: Vec::new(),
            w_pos: (0..n).collect(),
            lu: Vec::new(),
            perm: Vec::new(),
            perm_inv: Vec::new(),
            stack: MemBuffer::new(
                solve::solve_in_place_scratch::<usize, f64>(n.max(1), 1, Par::Seq)
                    .or(solve::solve_transpose_in_place_scratch::<usize, f64>(n.max(1), 1, Par::Seq)),
            ),
            factor_stack: MemBuffer::new(faer::dyn_stack::StackReq::EMPTY),
            factor_stack_k: 0,
            eta_pos: Vec::new(),
            eta_pivot: Vec::new(),
            eta_start: vec![0],
            eta_index: Vec::new(),
            eta_value: Vec::new(),
            work: vec![0.0; n],
            work_by_position: vec![0.0; n],
            small: vec![0.0; n],
            refactorizations: 0,
            operations: 0.0,
        }
    }

    /// Number of eta updates since the last refactorization.
    pub fn updates(&self) -> usize {
        self.eta_pos.len()
    }

    /// Size k of the factorized block at the last refactorization.
    pub fn factorized_size(&self) -> usize {
        self.rows_n.len()
    }

    /// Solves B x = a: `a` by row, `x` by position (FTRAN).
    pub fn solve(&mut self, cols: &Columns, a: &[f64], x: &mut [f64]) {
        debug_assert!(a.len() == self.n && x.len() == self.n);
        self.work.copy_from_slice(a);
        self.solve_b0_from_work(cols, x);
        self.apply_etas(x);
    }

    /// Solves B x = col(var) for a column of `[I, −M, −d]`.
    pub fn solve_column(&mut self, cols: &Columns, var: usize, x: &mut [f64]) {
        self.work.fill(0.0);
        cols.for_each(var, |i, v| self.work[i] = v);
        self.solve_b0_from_work(cols, x);
        self.apply_etas(x);
    }

    /// x = B_0⁻¹ work (work by row, destroyed).
    fn solve_b0_from_work(&mut self, cols: &Columns, x: &mut [f64]) {
        let k = self.rows_n.len();
        self.operations += (2 * k * k + self.n) as f64;
        if k > 0 {
            let y = &mut self.small[..k];
            let mut any = false;
            for (slot, &i) in self.rows_n.iter().enumerate() {
                y[slot] = self.work[i];
                any |= y[slot] != 0.0;
            }
            if any {
                let lu = MatRef::from_column_major_slice(&self.lu[..k * k], k, k);
                let perm = PermRef::new_checked(&self.perm, &self.perm_inv, k);
                solve::solve_in_place(
                    lu,
                    lu,
                    perm,
                    MatMut::from_column_major_slice_mut(y, k, 1),
                    Par::Seq,
                    MemStack::new(&mut self.stack),
                );
            }
            for c in 0..k {
                let yc = y[c];
                x[self.col_pos[c]] = yc;
                if yc != 0.0 {
                    let work = &mut self.work;
                    cols.for_each(self.col_var[c], |i, v| work[i] -= v * yc);
                }
            }
        }
        for (i, &p) in self.w_pos.iter().enumerate() {
            if p != NONE {
                x[p] = self.work[i];
            }
        }
    }

    /// Solves Bᵀ y = c: `c` by position, `y` by row (BTRAN). Row p of B⁻¹ is yᵀ for c = e_p.
    ///
    /// With B = B_0 E_1 ⋯ E_t, Bᵀ = E_tᵀ ⋯ E_1ᵀ B_0ᵀ: c is passed through E_t⁻ᵀ, …, E_1⁻ᵀ (E_sᵀ is
    /// the identity with row r_s replaced by the eta, so only entry r_s changes, by a dot
    /// product), then B_0ᵀ y = v is solved: a row whose w is basic in B_0 (a unit column at
    /// position p) has y_i = v_p; the rows of B_N follow from B_Nᵀ y_N = v_J − B_Sᵀ y_S over the
    /// non-unit columns J, by the transposed LU solve.
    pub fn solve_transpose(&mut self, cols: &Columns, c: &[f64], y: &mut [f64]) {
        debug_assert!(c.len() == self.n && y.len() == self.n);
        let k = self.rows_n.len();
        self.operations += (2 * k * k + self.n + self.eta_index.len()) as f64;
        let v = &mut self.work_by_position;
        v.copy_from_slice(c);
        for t in (0..self.eta_pos.len()).rev() {
            let r = self.eta_pos[t];
            let range = self.eta_start[t]..self.eta_start[t + 1];
            let dot: f64 = self.eta_index[range.clone()]
                .iter()
                .zip(&self.eta_value[range])
                .map(|(&i, &e)| e * v[i])
                .sum();
            v[r] = (v[r] - dot) / self.eta_pivot[t];
        }
        for (i, &p) in self.w_pos.iter().enumerate() {
            y[i] = if p != NONE { v[p] } else { 0.0 };
        }
        if k == 0 {
            return;
        }
        let rhs = &mut self.small[..k];
        let row_slot = &self.row_slot;
        for c in 0..k {
            let mut sum = v[self.col_pos[c]];
            cols.for_each(self.col_var[c], |i, value| {
                if row_slot[i] == NONE {
                    sum -= value * y[i];
                }
            });
            rhs[c] = sum;
        }
        let lu = MatRef::from_column_major_slice(&self.lu[..k * k], k, k);
        let perm = PermRef::new_checked(&self.perm, &self.perm_inv, k);
        solve::solve_transpose_in_place(
            lu,
            lu,
            perm,
            MatMut::from_column_major_slice_mut(rhs, k, 1),
            Par::Seq,
            MemStack::new(&mut self.stack),
        );
        for (slot, &i) in self.rows_n.iter().enumerate() {
            y[i] = rhs[slot];
        }
    }

    /// x ← E_t⁻¹ ⋯ E_1⁻¹ x.
    fn apply_etas(&mut self, x: &mut [f64]) {
        self.operations += self.eta_index.len() as f64;
        for t in 0..self.eta_pos.len() {
            let r = self.eta_pos[t];
            let xr = x[r] / self.eta_pivot[t];
            x[r] = xr;
            if xr != 0.0 {
                let range = self.eta_start[t]..self.eta_start[t + 1];
                for (&i, &v) in self.eta_index[range.clone()].iter().zip(&self.eta_value[range]) {
                    x[i] -= v * xr;
                }
            }
        }
    }

    /// Replaces the variable at position `r` by `entering`, whose column solved against the
    /// current basis is `alpha` (by position); returns the variable that left.
    pub fn replace(&mut self, r: usize, entering: usize, alpha: &[f64]) -> usize {
        self.eta_pos.push(r);
        self.eta_pivot.push(alpha[r]);
        for (i, &v) in alpha.iter().enumerate() {
            if i != r && v != 0.0 {
                self.eta_index.push(i);
                self.eta_value.push(v);
            }
        }
        self.eta_start.push(self.eta_index.len());
        let leaving = std::mem::replace(&mut self.vars[r], entering);
        self.position[leaving] = NONE;
        self.position[entering] = r;
        leaving
    }

    /// Factorizes the current basis anew (and empties the eta file).
    pub fn refactor(&mut self, cols: &Columns) -> Result<(), Singular> {
        let n = self.n;
        self.refactorizations += 1;
        self.rows_n.clear();
        self.row_slot.fill(NONE);
        for i in 0..n {
            if self.position[i] == NONE {
                self.row_slot[i] = self.rows_n.len();
                self.rows_n.push(i);
            }
        }
        self.col_pos.clear();
        self.col_var.clear();
        for (p, &var) in self.vars.iter().enumerate() {
            if var >= n {
                self.col_pos.push(p);
                self.col_var.push(var);
            }
        }
        for i in 0..n {
            self.w_pos[i] = self.position[i];
        }
        self.eta_pos.clear();
        self.eta_pivot.clear();
        self.eta_start.truncate(1);
        self.eta_index.clear();
        self.eta_value.clear();
        let k = self.rows_n.len();
        self.operations += 2.0 * (k as f64).powi(3) / 3.0 + n as f64;
        debug_assert_eq!(k, self.col_pos.len(), "as many non-unit columns as rows without a basic w");
        self.lu.clear();
        self.lu.resize(k * k, 0.0);
        self.perm.resize(k, 0);
        self.perm_inv.resize(k, 0);
        if k == 0 {
            return Ok(());
        }
        for c in 0..k {
            let (lu, slot) = (&mut self.lu, &self.row_slot);
            cols.for_each(self.col_var[c], |i, v| {
                if slot[i] != NONE {
                    lu[c * k + slot[i]] = v;
                }
            });
        }
        if k > self.factor_stack_k {
            // Room for twice this k: the block grows along the path.
            let room = (2 * k).min(n);
            self.factor_stack = MemBuffer::new(factor::lu_in_place_scratch::<usize, f64>(
                room,
                room,
                Par::Seq,
                Default::default(),
            ));
            self.factor_stack_k = room;
        }
        factor::lu_in_place(
            MatMut::from_column_major_slice_mut(&mut self.lu[..k * k], k, k),
            &mut self.perm,
            &mut self.perm_inv,
            Par::Seq,
            MemStack::new(&mut self.factor_stack),
            Default::default(),
        );
        let (mut smallest, mut largest) = (f64::INFINITY, 0.0f64);
        for c in 0..k {
            let u = self.lu[c * k + c].abs();
            smallest = smallest.min(u);
            largest = largest.max(u);
        }
        let ratio = if largest > 0.0 { smallest / largest } else { 0.0 };
        // NaN fails this test too.
        if ratio > 1e-15 {
            Ok(())
        } else {
            Err(Singular { ratio })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solvers::lemke::columns::{Csc, Matrix};
    use nalgebra::DMatrix;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// The dense basis B (columns of `[I, −M, −d]` at their positions).
    fn dense_basis(basis: &Basis, cols: &Columns) -> DMatrix<f64> {
        let n = cols.n();
        let mut b = DMatrix::zeros(n, n);
        for (p, &var) in basis.vars.iter().enumerate() {
            cols.for_each(var, |i, v| b[(i, p)] += v);
        }
        b
    }

    #[test]
    fn solves_and_transposed_solves_match_the_basis_through_updates_and_refactorizations() {
        let mut rng = StdRng::seed_from_u64(0xb7a5);
        let n = 12;
        let m = DMatrix::from_fn(
            n,
            n,
            |_, _| if rng.random_bool(0.4) { rng.random_range(-2.0..2.0) } else { 0.0 },
        );
        let m = m + DMatrix::identity(n, n) * 3.0;
        let m = Csc::from_dense(&m);
        let cols = Columns { m: Matrix::Formed(&m), d: (0..n).map(|i| 1.0 + 0.1 * i as f64).collect() };
        let mut basis = Basis::identity(n);
        let (mut x, mut y, mut alpha) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        // Bring in z0 and z_j's at random positions, refactorizing now and then: each basis
        // stays non-singular (M is diagonally dominant, d generic).
        let mut entering: Vec<usize> = (n..2 * n + 1).collect();
        for step in 0..10 {
            let var = entering.remove(rng.random_range(0..entering.len()));
            basis.solve_column(&cols, var, &mut alpha);
            let r = (0..n)
                .filter(|&p| basis.vars[p] < n)
                .max_by(|&a, &b| alpha[a].abs().total_cmp(&alpha[b].abs()));
            let Some(r) = r else { break };
            basis.replace(r, var, &alpha);
            if step % 4 == 3 {
                basis.refactor(&cols).unwrap();
            }
            let b = dense_basis(&basis, &cols);
            let c: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
            basis.solve(&cols, &c, &mut x);
            basis.solve_transpose(&cols, &c, &mut y);
            let bx = &b * DMatrix::from_column_slice(n, 1, &x);
            let bty = b.transpose() * DMatrix::from_column_slice(n, 1, &y);
            for i in 0..n {
                assert!((bx[i] - c[i]).abs() < 1e-10, "step {step}: (B x − c)_{i} = {:e}", bx[i] - c[i]);
                assert!((bty[i] - c[i]).abs() < 1e-10, "step {step}: (Bᵀ y − c)_{i} = {:e}", bty[i] - c[i]);
            }
        }
        assert!(
            basis.updates() > 0 && basis.factorized_size() > 0,
            "both the etas and the LU were exercised"
        );
    }
}
