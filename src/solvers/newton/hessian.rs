//! The Newton solver's Hessian `H = I + Wᵀ G W` (nv × nv, symmetric positive definite) as a
//! sparse matrix and its Cholesky factor (faer's supernodal or simplicial LLᵀ with an AMD
//! ordering).
//!
//! Its pattern is block-structured: the velocity blocks are the multibodies, a block's own
//! entries are stored dense (its rows' paths overlap near the root), and two blocks are
//! coupled where some group of rows touches both (a contact between two multibodies). The
//! pattern, and with it the symbolic factorization, is kept while the set of coupled block
//! pairs stays the same: a resting pile factors with the symbolic analysis of an earlier step.
//!
//! H is assembled in its block order and copied into the fill-reducing (AMD) order once per
//! factorization through a map made with the pattern (one pass over the entries), and factored
//! there without a permutation of faer's own: its general permutation of a symmetric matrix,
//! done at every numeric factorization, cost more than the copy.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

/// The lower triangle of H in compressed columns, and its factor.
#[derive(Default)]
pub(super) struct Hessian {
    /// Velocity blocks (first column, width) the pattern was made for.
    blocks: Vec<(usize, usize)>,
    /// Coupled block pairs (lower block, upper block), sorted: the pattern's key.
    pairs: Vec<(usize, usize)>,
    /// Per block, where its coupled later blocks start in `links`.
    link_start: Vec<usize>,
    /// (later block, offset of its rows in each column of the block below the block's own
    /// rows), by block.
    links: Vec<(usize, usize)>,
    block_of_col: Vec<usize>,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
    /// Per column, its index in the AMD order; the lower triangle of H in that order (pattern
    /// and values), and where each entry of `values` goes in it.
    order: Vec<usize>,
    ordered: Option<SymbolicSparseColMat<usize>>,
    ordered_values: Vec<f64>,
    ordered_position: Vec<usize>,
    /// A right-hand side in the AMD order.
    ordered_rhs: Vec<f64>,
    /// Whether `ordered` holds the lower triangle (else the upper).
    lower: bool,
    symbolic: Option<SymbolicCholesky<usize>>,
    factor: Vec<f64>,
    memory: Option<MemBuffer>,
    memory_bytes: usize,
    /// Symbolic analyses done (patterns made).
    pub(super) analyses: usize,
}

/// Why the factorization failed.
#[derive(Debug)]
pub(super) struct NotPositiveDefinite;

impl Hessian {
    /// Makes the pattern for `blocks` and the coupled `pairs` (sorted, lower block first) unless
    /// it is the one in use.
    pub(super) fn prepare(&mut self, blocks: &[(usize, usize)], pairs: &[(usize, usize)]) {
        if self.symbolic.is_some() && self.blocks == blocks && self.pairs == pairs {
            return;
        }
        self.analyses += 1;
        self.blocks.clear();
        self.blocks.extend_from_slice(blocks);
        self.pairs.clear();
        self.pairs.extend_from_slice(pairs);
        let nv = blocks.last().map_or(0, |&(col, width)| col + width);
        self.block_of_col.clear();
        self.block_of_col.resize(nv, usize::MAX);
        for (b, &(col, width)) in blocks.iter().enumerate() {
            self.block_of_col[col..col + width].fill(b);
        }
        self.link_start.clear();
        self.links.clear();
        let mut p = 0;
        for b in 0..blocks.len() {
            self.link_start.push(self.links.len());
            let mut offset = 0;
            while p < pairs.len() && pairs[p].0 == b {
                let later = pairs[p].1;
                self.links.push((later, offset));
                offset += blocks[later].1;
                p += 1;
            }
        }
        self.link_start.push(self.links.len());
        self.col_ptr.clear();
        self.row_idx.clear();
        self.col_ptr.push(0);
        for j in 0..nv {
            let b = self.block_of_col[j];
            let (col, width) = blocks[b];
            self.row_idx.extend(j..col + width);
            for &(later, _) in &self.links[self.link_start[b]..self.link_start[b + 1]] {
                let (c, w) = blocks[later];
                self.row_idx.extend(c..c + w);
            }
            self.col_ptr.push(self.row_idx.len());
        }
        self.values.clear();
        self.values.resize(self.row_idx.len(), 0.0);
        let pattern = SymbolicSparseColMatRef::new_checked(nv, nv, &self.col_ptr, None, &self.row_idx);
        let amd =
            factorize_symbolic_cholesky(pattern, Side::Lower, SymmetricOrdering::Amd, Default::default())
                .expect("symbolic Cholesky of a valid pattern");
        self.order.clear();
        match amd.perm() {
            Some(perm) => self.order.extend_from_slice(perm.arrays().1),
            None => self.order.extend(0..nv),
        }
        // One triangle of H in the new order, columns sorted, rows increasing in each: the
        // upper for the symbolic analysis (which, without an ordering of its own, reads the
        // upper triangle) and the simplicial factorization, the lower for the supernodal one
        // (the triangle each reads without a transposed copy).
        let mut entries: Vec<(usize, usize, usize)> = Vec::with_capacity(self.row_idx.len());
        let triangle = |entries: &mut Vec<(usize, usize, usize)>, upper: bool| {
            entries.clear();
            for j in 0..nv {
                for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                    let (a, b) = (self.order[self.row_idx[p]], self.order[j]);
                    let (row, col) = if upper { (a.min(b), a.max(b)) } else { (a.max(b), a.min(b)) };
                    entries.push((col, row, p));
                }
            }
            // By row, then stably by column: two counting sorts, O(entries + nv).
            let mut sorted = vec![(0, 0, 0); entries.len()];
            counting_sort_by(entries, &mut sorted, nv, |e| e.1);
            counting_sort_by(&sorted, entries, nv, |e| e.0);
            let mut col_ptr = vec![0usize; nv + 1];
            let mut row_idx = Vec::with_capacity(entries.len());
            for &(col, row, _) in entries.iter() {
                col_ptr[col + 1] += 1;
                row_idx.push(row);
            }
            for j in 0..nv {
                col_ptr[j + 1] += col_ptr[j];
            }
            SymbolicSparseColMat::new_checked(nv, nv, col_ptr, None, row_idx)
        };
        let mut ordered = triangle(&mut entries, true);
        let symbolic = factorize_symbolic_cholesky(
            ordered.as_ref(),
            Side::Upper,
            SymmetricOrdering::Identity,
            Default::default(),
        )
        .expect("symbolic Cholesky of a valid pattern");
        self.lower = false;
        if matches!(symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)) {
            ordered = triangle(&mut entries, false);
            self.lower = true;
        }
        self.ordered_position.clear();
        self.ordered_position.resize(entries.len(), 0);
        for (k, &(_, _, p)) in entries.iter().enumerate() {
            self.ordered_position[p] = k;
        }
        self.ordered = Some(ordered);
        self.ordered_values.clear();
        self.ordered_values.resize(entries.len(), 0.0);
        self.ordered_rhs.clear();
        self.ordered_rhs.resize(nv, 0.0);
        self.factor.clear();
        self.factor.resize(symbolic.len_val(), 0.0);
        let need = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ]);
        let bytes = need.unaligned_bytes_required();
        if self.memory.is_none() || self.memory_bytes < bytes {
            self.memory = Some(MemBuffer::new(need));
            self.memory_bytes = bytes;
        }
        self.symbolic = Some(symbolic);
    }

    /// Sets H to the identity (the pattern's other entries to 0).
    pub(super) fn reset(&mut self) {
        self.values.fill(0.0);
        for j in 0..self.block_of_col.len() {
            self.values[self.col_ptr[j]] = 1.0;
        }
    }

    /// Where H's entry (i, j), i ≥ j, lives in `values`.
    fn position(&self, i: usize, j: usize) -> usize {
        let b = self.block_of_col[j];
        let bi = self.block_of_col[i];
        let (col, width) = self.blocks[b];
        if bi == b {
            return self.col_ptr[j] + (i - j);
        }
        let links = &self.links[self.link_start[b]..self.link_start[b + 1]];
        let offset = links.iter().find(|&&(later, _)| later == bi).map(|&(_, offset)| offset);
        let offset = offset.expect("a coupled block of the pattern");
        self.col_ptr[j] + (col + width - j) + offset + (i - self.blocks[bi].0)
    }

    /// Adds the symmetric `local` (`columns.len()`² entries, column-major) at the rows and
    /// columns `columns` (increasing).
    pub(super) fn add(&mut self, columns: &[usize], local: &[f64]) {
        let m = columns.len();
        for b in 0..m {
            let j = columns[b];
            // Entries of one block in column j are consecutive: find the start once per run.
            let mut a = b;
            while a < m {
                let start = self.position(columns[a], j);
                let block = self.block_of_col[columns[a]];
                let first = columns[a];
                while a < m && self.block_of_col[columns[a]] == block {
                    self.values[start + (columns[a] - first)] += local[b * m + a];
                    a += 1;
                }
            }
        }
    }

    /// out = H x from the stored lower triangle.
    #[cfg(test)]
    pub(super) fn multiply(&self, x: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for j in 0..x.len() {
            for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                let i = self.row_idx[p];
                out[i] += self.values[p] * x[j];
                if i != j {
                    out[j] += self.values[p] * x[i];
                }
            }
        }
    }

    /// Factors H (its values as added since [`Self::reset`]).
    pub(super) fn factor(&mut self) -> Result<(), NotPositiveDefinite> {
        let symbolic = self.symbolic.as_ref().expect("a prepared pattern");
        let ordered = self.ordered.as_ref().expect("a prepared pattern");
        for (&k, &x) in self.ordered_position.iter().zip(&self.values) {
            self.ordered_values[k] = x;
        }
        let matrix = SparseColMatRef::new(ordered.as_ref(), &self.ordered_values);
        let memory = self.memory.as_mut().expect("a prepared pattern");
        let stack = MemStack::new(memory);
        symbolic
            .factorize_numeric_llt(
                &mut self.factor,
                matrix,
                if self.lower { Side::Lower } else { Side::Upper },
                LltRegularization::default(),
                Par::Seq,
                stack,
                Default::default(),
            )
            .map(|_| ())
            .map_err(|_| NotPositiveDefinite)
    }

    /// Solves H x = rhs in place with the last factor.
    pub(super) fn solve(&mut self, rhs: &mut [f64]) {
        let symbolic = self.symbolic.as_ref().expect("a prepared pattern");
        let memory = self.memory.as_mut().expect("a prepared pattern");
        let stack = MemStack::new(memory);
        for (&new, &x) in self.order.iter().zip(rhs.iter()) {
            self.ordered_rhs[new] = x;
        }
        let n = rhs.len();
        let ordered = MatMut::from_column_major_slice_mut(&mut self.ordered_rhs, n, 1);
        LltRef::<'_, usize, f64>::new(symbolic, &self.factor).solve_in_place_with_conj(
            Conj::No,
            ordered,
            Par::Seq,
            stack,
        );
        for (&new, x) in self.order.iter().zip(rhs.iter_mut()) {
            *x = self.ordered_rhs[new];
        }
    }
}

/// `from` into `to` (same length) sorted stably by `key` (< `keys`).
fn counting_sort_by<T: Copy>(from: &[T], to: &mut [T], keys: usize, key: impl Fn(&T) -> usize) {
    let mut start = vec![0usize; keys + 1];
    for x in from {
        start[key(x) + 1] += 1;
    }
    for k in 0..keys {
        start[k + 1] += start[k];
    }
    for x in from {
        let k = key(x);
        to[start[k]] = *x;
        start[k] += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three blocks, the first and last coupled: entries added through the block pattern give
    /// the dense matrix, and the factor solves it.
    #[test]
    fn block_pattern_assembles_and_solves_the_dense_matrix() {
        let blocks = [(0, 2), (2, 3), (5, 2)];
        let mut h = Hessian::default();
        h.prepare(&blocks, &[(0, 2)]);
        h.reset();
        let mut dense = nalgebra::DMatrix::<f64>::identity(7, 7);
        // A symmetric local block on columns {1, 5, 6} (blocks 0 and 2) and one on {2, 3, 4}.
        for (columns, seed) in [(&[1usize, 5, 6][..], 0.3), (&[2usize, 3, 4][..], -0.2)] {
            let m = columns.len();
            let v: Vec<f64> = (0..m).map(|k| seed + 0.5 * k as f64).collect();
            let local: Vec<f64> = (0..m * m).map(|e| v[e / m] * v[e % m]).collect();
            h.add(columns, &local);
            for a in 0..m {
                for b in 0..m {
                    dense[(columns[a], columns[b])] += local[b * m + a];
                }
            }
        }
        let x: Vec<f64> = (0..7).map(|k| 1.0 - 0.3 * k as f64).collect();
        let mut hx = vec![0.0; 7];
        h.multiply(&x, &mut hx);
        let expected = &dense * nalgebra::DVector::from_column_slice(&x);
        for k in 0..7 {
            assert!((hx[k] - expected[k]).abs() < 1e-14, "row {k}: {} vs {}", hx[k], expected[k]);
        }
        h.factor().unwrap();
        let mut solved = expected.as_slice().to_vec();
        h.solve(&mut solved);
        for k in 0..7 {
            assert!((solved[k] - x[k]).abs() < 1e-12, "x[{k}]: {} vs {}", solved[k], x[k]);
        }
    }
}
