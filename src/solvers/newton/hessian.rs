//! The Newton solver's Hessian `H = I + Wᵀ G W` (nv × nv, symmetric positive definite) and its
//! Cholesky factor `H = L Lᵀ`, sparse by blocks.
//!
//! The velocity blocks are the multibodies. A block's own entries are dense (its rows' paths
//! overlap near the root, and a floating base couples them all), and two blocks are coupled
//! where some group of rows touches both (a contact between two multibodies). The factor keeps
//! that structure: the blocks are eliminated in an approximate-minimum-degree order of the
//! block graph (faer's AMD), and L is stored as one dense panel per block, column-major: the
//! block's diagonal block over the later blocks its columns reach (coupled ones and fill).
//! Every operation of the factorization and of the solves is then a short dense loop over
//! contiguous panel columns, with no permutation of H or of the right-hand side (a panel's rows
//! are blocks' own columns). This is a supernodal Cholesky whose supernodes are the multibodies;
//! a general sparse code (faer's simplicial or supernodal LLᵀ) spends most of its time on the
//! scalar pattern and the permutations on these small, dense blocks.
//!
//! The order and the panels are kept while the set of coupled block pairs stays the same: a
//! resting pile factors with the analysis of an earlier step.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::amd;
use faer::sparse::SymbolicSparseColMatRef;

/// The Hessian's panels (H's lower triangle by blocks until [`Hessian::factor`], then L's).
#[derive(Default)]
pub(super) struct Hessian {
    /// Whether a pattern has been made.
    prepared: bool,
    /// Velocity blocks (first column, width) the pattern was made for.
    blocks: Vec<(usize, usize)>,
    /// Coupled block pairs (lower block, upper block), sorted: the pattern's key.
    pairs: Vec<(usize, usize)>,
    /// Blocks in elimination order, and each block's place in that order.
    order: Vec<usize>,
    rank: Vec<usize>,
    /// Per block, its panel's later blocks (increasing in elimination order) with the panel row
    /// where each starts: `below[below_start[b]..below_start[b + 1]]`.
    below_start: Vec<usize>,
    below: Vec<(usize, usize)>,
    /// Per block, where its panel starts in `values` (panels are laid out in elimination order)
    /// and the panel's height (its own width plus the widths of the blocks below).
    panel_start: Vec<usize>,
    height: Vec<usize>,
    block_of_col: Vec<usize>,
    /// H's lower triangle as assembled, by panels; kept across factorizations, so that a
    /// Newton iteration adds only what changed since the last.
    assembled: Vec<f64>,
    /// The panels being factored: a copy of `assembled`, then L.
    values: Vec<f64>,
    /// Scratch of [`Hessian::add_gram`]: where a group's segments start among its columns.
    segments: Vec<usize>,
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
        if self.prepared && self.blocks == blocks && self.pairs == pairs {
            return;
        }
        self.prepared = true;
        self.analyses += 1;
        self.blocks.clear();
        self.blocks.extend_from_slice(blocks);
        self.pairs.clear();
        self.pairs.extend_from_slice(pairs);
        let nb = blocks.len();
        let nv = blocks.last().map_or(0, |&(col, width)| col + width);
        self.block_of_col.clear();
        self.block_of_col.resize(nv, usize::MAX);
        for (b, &(col, width)) in blocks.iter().enumerate() {
            self.block_of_col[col..col + width].fill(b);
        }
        self.order_blocks();
        self.analyse_fill();
        let mut start = 0;
        self.panel_start.clear();
        self.panel_start.resize(nb, 0);
        for &b in &self.order {
            self.panel_start[b] = start;
            start += self.height[b] * blocks[b].1;
        }
        self.assembled.clear();
        self.assembled.resize(start, 0.0);
        self.values.clear();
        self.values.resize(start, 0.0);
    }

    /// `order` and `rank`: an approximate minimum degree order of the block graph (blocks
    /// coupled by a pair are neighbours).
    fn order_blocks(&mut self) {
        let nb = self.blocks.len();
        self.order.clear();
        self.order.extend(0..nb);
        // The upper triangle of the block graph's pattern, column by column, rows increasing
        // (pairs are sorted by lower block, so a counting pass by upper block keeps them so).
        let mut col_ptr = vec![0usize; nb + 1];
        for &(a, b) in &self.pairs {
            if a != b {
                col_ptr[b + 1] += 1;
            }
        }
        for k in 0..nb {
            col_ptr[k + 1] += col_ptr[k] + 1;
        }
        let mut row_idx = vec![0usize; col_ptr[nb]];
        let mut fill = col_ptr.clone();
        for &(a, b) in &self.pairs {
            if a != b {
                row_idx[fill[b]] = a;
                fill[b] += 1;
            }
        }
        for k in 0..nb {
            row_idx[fill[k]] = k;
        }
        if nb > 1 {
            let pattern = SymbolicSparseColMatRef::new_checked(nb, nb, &col_ptr, None, &row_idx);
            let mut perm = vec![0usize; nb];
            let mut perm_inv = vec![0usize; nb];
            let mut memory = MemBuffer::new(amd::order_scratch::<usize>(nb, row_idx.len()));
            let stack = MemStack::new(&mut memory);
            // AMD fails only on index overflow; the identity order is then still a valid one.
            if amd::order(&mut perm, &mut perm_inv, pattern, amd::Control::default(), stack).is_ok() {
                self.order.copy_from_slice(&perm);
            }
        }
        self.rank.clear();
        self.rank.resize(nb, 0);
        for (k, &b) in self.order.iter().enumerate() {
            self.rank[b] = k;
        }
    }

    /// `below`, `below_start` and `height`: each block's later neighbours and the fill its
    /// elimination creates (the union of its children's, in the block elimination tree).
    fn analyse_fill(&mut self) {
        let nb = self.blocks.len();
        // Each block's later neighbours in the elimination order, as lists.
        let mut later_start = vec![0usize; nb + 1];
        for &(a, b) in &self.pairs {
            if a != b {
                later_start[if self.rank[a] < self.rank[b] { a } else { b } + 1] += 1;
            }
        }
        for k in 0..nb {
            later_start[k + 1] += later_start[k];
        }
        let mut later = vec![0usize; later_start[nb]];
        let mut fill = later_start.clone();
        for &(a, b) in &self.pairs {
            if a != b {
                let (first, second) = if self.rank[a] < self.rank[b] { (a, b) } else { (b, a) };
                later[fill[first]] = second;
                fill[first] += 1;
            }
        }
        // Children in the elimination tree, as linked lists.
        let mut first_child = vec![usize::MAX; nb];
        let mut next_sibling = vec![usize::MAX; nb];
        let mut mark = vec![usize::MAX; nb];
        let mut pattern: Vec<usize> = Vec::new();
        // Patterns are made in elimination order; block b's lives in `lists[list_start[b]..]`.
        let mut list_start = vec![0usize; nb];
        let mut list_len = vec![0usize; nb];
        let mut lists: Vec<usize> = Vec::new();
        for k in 0..nb {
            let b = self.order[k];
            pattern.clear();
            mark[b] = k;
            for &r in &later[later_start[b]..later_start[b + 1]] {
                if mark[r] != k {
                    mark[r] = k;
                    pattern.push(r);
                }
            }
            let mut child = first_child[b];
            while child != usize::MAX {
                for &r in &lists[list_start[child]..list_start[child] + list_len[child]] {
                    if mark[r] != k {
                        mark[r] = k;
                        pattern.push(r);
                    }
                }
                child = next_sibling[child];
            }
            let rank = &self.rank;
            pattern.sort_unstable_by_key(|&r| rank[r]);
            if let Some(&parent) = pattern.first() {
                next_sibling[b] = first_child[parent];
                first_child[parent] = b;
            }
            list_start[b] = lists.len();
            list_len[b] = pattern.len();
            lists.extend_from_slice(&pattern);
        }
        self.below_start.clear();
        self.below.clear();
        self.height.clear();
        for b in 0..nb {
            self.below_start.push(self.below.len());
            let mut row = self.blocks[b].1;
            for &r in &lists[list_start[b]..list_start[b] + list_len[b]] {
                self.below.push((r, row));
                row += self.blocks[r].1;
            }
            self.height.push(row);
        }
        self.below_start.push(self.below.len());
    }

    /// The panel row where block `r`'s rows start in block `b`'s panel (`r` later than `b`).
    fn offset(&self, b: usize, r: usize) -> usize {
        offset_in(&self.below[self.below_start[b]..self.below_start[b + 1]], &self.rank, r)
    }

    /// Where H's entry (i, j) lives in `values` (i's block not before j's in block index).
    fn position(&self, i: usize, j: usize) -> usize {
        let (bi, bj) = (self.block_of_col[i], self.block_of_col[j]);
        let (ci, cj) = (self.blocks[bi].0, self.blocks[bj].0);
        if bi == bj {
            let (hi, lo) = (i.max(j), i.min(j));
            return self.panel_start[bj] + (lo - cj) * self.height[bj] + (hi - cj);
        }
        let (col_block, col, row_block, row) =
            if self.rank[bj] < self.rank[bi] { (bj, j - cj, bi, i - ci) } else { (bi, i - ci, bj, j - cj) };
        self.panel_start[col_block] + col * self.height[col_block] + self.offset(col_block, row_block) + row
    }

    /// Sets H to the identity (the pattern's other entries to 0).
    pub(super) fn reset(&mut self) {
        self.assembled.fill(0.0);
        for (b, &(_, width)) in self.blocks.iter().enumerate() {
            let (start, h) = (self.panel_start[b], self.height[b]);
            for j in 0..width {
                self.assembled[start + j * h + j] = 1.0;
            }
        }
    }

    /// Adds the lower triangle of the symmetric `leftᵀ right` (both `count` × `columns.len()`,
    /// row-major) at the rows and columns `columns` (increasing): a group's `W_gᵀ (G W_g)`,
    /// into the panels without forming it. The group's columns fall into segments of
    /// consecutive columns of one block, whose entries in a column of H are consecutive in a
    /// panel (or one panel row apart, when the segment's block is eliminated first): each
    /// segment is added by one short loop over contiguous rows of `left`.
    pub(super) fn add_gram(&mut self, columns: &[usize], left: &[f64], right: &[f64], count: usize) {
        let m = columns.len();
        let mut segments = std::mem::take(&mut self.segments);
        segments.clear();
        for a in 0..m {
            let joins = a > 0
                && columns[a] == columns[a - 1] + 1
                && self.block_of_col[columns[a]] == self.block_of_col[columns[a - 1]];
            if !joins {
                segments.push(a);
            }
        }
        segments.push(m);
        let mut first_segment = 0;
        for b in 0..m {
            let j = columns[b];
            let block_of_j = self.block_of_col[j];
            while segments[first_segment + 1] <= b {
                first_segment += 1;
            }
            let weights = [
                right[b],
                if count > 1 { right[m + b] } else { 0.0 },
                if count > 2 { right[2 * m + b] } else { 0.0 },
            ];
            for s in first_segment..segments.len() - 1 {
                let (from, to) = (segments[s].max(b), segments[s + 1]);
                let block = self.block_of_col[columns[from]];
                let start = self.position(columns[from], j);
                let transposed = block != block_of_j && self.rank[block] < self.rank[block_of_j];
                let len = to - from;
                if count <= 3 && !transposed {
                    let target = &mut self.assembled[start..start + len];
                    add_rows(target, left, m, from, count, &weights);
                } else {
                    let stride = if transposed { self.height[block] } else { 1 };
                    for a in from..to {
                        let sum: f64 = (0..count).map(|r| left[r * m + a] * right[r * m + b]).sum();
                        self.assembled[start + (a - from) * stride] += sum;
                    }
                }
            }
        }
        self.segments = segments;
    }

    /// out = H x from the assembled lower triangle.
    #[cfg(test)]
    pub(super) fn multiply(&self, x: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for (b, &(c, width)) in self.blocks.iter().enumerate() {
            let (start, h) = (self.panel_start[b], self.height[b]);
            for j in 0..width {
                let column = &self.assembled[start + j * h..start + (j + 1) * h];
                for i in j..width {
                    out[c + i] += column[i] * x[c + j];
                    if i != j {
                        out[c + j] += column[i] * x[c + i];
                    }
                }
                for &(r, row) in &self.below[self.below_start[b]..self.below_start[b + 1]] {
                    let (cr, wr) = self.blocks[r];
                    for i in 0..wr {
                        out[cr + i] += column[row + i] * x[c + j];
                        out[c + j] += column[row + i] * x[cr + i];
                    }
                }
            }
        }
    }

    /// Factors H = L Lᵀ (its values as added since [`Self::reset`], which stay assembled).
    pub(super) fn factor(&mut self) -> Result<(), NotPositiveDefinite> {
        self.values.copy_from_slice(&self.assembled);
        let Self { order, blocks, below, below_start, panel_start, height, rank, values, .. } = self;
        for &b in order.iter() {
            let width = blocks[b].1;
            let (start, h) = (panel_start[b], height[b]);
            // Panels are laid out in elimination order: this one's source, later ones after it.
            let (done, later) = values.split_at_mut(start + h * width);
            let panel = &mut done[start..];
            factor_panel(panel, h, width)?;
            let entries = &below[below_start[b]..below_start[b + 1]];
            let base = start + h * width;
            for (p, &(r1, o1)) in entries.iter().enumerate() {
                let w1 = blocks[r1].1;
                let (s1, h1) = (panel_start[r1] - base, height[r1]);
                let later_of_r1 = &below[below_start[r1]..below_start[r1 + 1]];
                for &(r2, o2) in &entries[p..] {
                    let w2 = blocks[r2].1;
                    let (dest, diagonal) =
                        if r2 == r1 { (0, true) } else { (offset_in(later_of_r1, rank, r2), false) };
                    // Block (r2, r1) of H −= L_{r2,b} L_{r1,b}ᵀ (its lower triangle on the diagonal).
                    for j in 0..w1 {
                        let target = &mut later[s1 + j * h1 + dest..s1 + j * h1 + dest + w2];
                        let from = if diagonal { j } else { 0 };
                        for kk in 0..width {
                            let column = &panel[kk * h..(kk + 1) * h];
                            let f = column[o1 + j];
                            if f != 0.0 {
                                let source = &column[o2 + from..o2 + w2];
                                for (t, s) in target[from..].iter_mut().zip(source) {
                                    *t -= f * s;
                                }
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// Solves H x = rhs in place with the last factor.
    pub(super) fn solve(&self, rhs: &mut [f64]) {
        // L y = rhs, blocks in elimination order.
        for &b in &self.order {
            let (c, width) = self.blocks[b];
            let (start, h) = (self.panel_start[b], self.height[b]);
            let entries = &self.below[self.below_start[b]..self.below_start[b + 1]];
            for j in 0..width {
                let column = &self.values[start + j * h..start + (j + 1) * h];
                let y = rhs[c + j] / column[j];
                rhs[c + j] = y;
                for (x, l) in rhs[c + j + 1..c + width].iter_mut().zip(&column[j + 1..width]) {
                    *x -= l * y;
                }
                for &(r, row) in entries {
                    let (cr, wr) = self.blocks[r];
                    for (x, l) in rhs[cr..cr + wr].iter_mut().zip(&column[row..row + wr]) {
                        *x -= l * y;
                    }
                }
            }
        }
        // Lᵀ x = y, in reverse.
        for &b in self.order.iter().rev() {
            let (c, width) = self.blocks[b];
            let (start, h) = (self.panel_start[b], self.height[b]);
            let entries = &self.below[self.below_start[b]..self.below_start[b + 1]];
            for j in (0..width).rev() {
                let column = &self.values[start + j * h..start + (j + 1) * h];
                let mut s = rhs[c + j];
                for (x, l) in rhs[c + j + 1..c + width].iter().zip(&column[j + 1..width]) {
                    s -= l * x;
                }
                for &(r, row) in entries {
                    let (cr, wr) = self.blocks[r];
                    for (x, l) in rhs[cr..cr + wr].iter().zip(&column[row..row + wr]) {
                        s -= l * x;
                    }
                }
                rhs[c + j] = s / column[j];
            }
        }
    }
}

/// `target[k] += Σ_r weights[r] · left[r · m + from + k]` over the first `count` (≤ 3) rows.
fn add_rows(target: &mut [f64], left: &[f64], m: usize, from: usize, count: usize, weights: &[f64; 3]) {
    let len = target.len();
    let row = |r: usize| &left[r * m + from..r * m + from + len];
    match count {
        1 => {
            for (t, l0) in target.iter_mut().zip(row(0)) {
                *t += weights[0] * l0;
            }
        }
        2 => {
            for ((t, l0), l1) in target.iter_mut().zip(row(0)).zip(row(1)) {
                *t += weights[0] * l0 + weights[1] * l1;
            }
        }
        _ => {
            for (((t, l0), l1), l2) in target.iter_mut().zip(row(0)).zip(row(1)).zip(row(2)) {
                *t += weights[0] * l0 + weights[1] * l1 + weights[2] * l2;
            }
        }
    }
}

/// The panel row where block `r`'s rows start, among a panel's later blocks `entries`.
fn offset_in(entries: &[(usize, usize)], rank: &[usize], r: usize) -> usize {
    let at = entries
        .binary_search_by_key(&rank[r], |&(block, _)| rank[block])
        .expect("a later block of the pattern");
    entries[at].1
}

/// Cholesky of a panel (`h` rows, `width` columns, column-major): its top `width` × `width`
/// block becomes L_bb (lower triangle) and the rows below L_rb = H_rb L_bb⁻ᵀ. Left-looking,
/// column by column, the earlier columns applied four at a time (one pass over the target per
/// four of them).
fn factor_panel(panel: &mut [f64], h: usize, width: usize) -> Result<(), NotPositiveDefinite> {
    for c in 0..width {
        let (done, rest) = panel.split_at_mut(c * h);
        let target = &mut rest[c..h];
        let mut k = 0;
        while k + 4 <= c {
            let (a0, a1) = (&done[k * h + c..(k + 1) * h], &done[(k + 1) * h + c..(k + 2) * h]);
            let (a2, a3) = (&done[(k + 2) * h + c..(k + 3) * h], &done[(k + 3) * h + c..(k + 4) * h]);
            let (f0, f1, f2, f3) = (a0[0], a1[0], a2[0], a3[0]);
            for i in 0..target.len() {
                target[i] -= (f0 * a0[i] + f1 * a1[i]) + (f2 * a2[i] + f3 * a3[i]);
            }
            k += 4;
        }
        for k in k..c {
            let a = &done[k * h + c..(k + 1) * h];
            let f = a[0];
            if f != 0.0 {
                for (t, s) in target.iter_mut().zip(a) {
                    *t -= f * s;
                }
            }
        }
        let d = target[0];
        // Also refuses NaN: a pivot that is not a positive finite number.
        if !(d > 0.0 && d.is_finite()) {
            return Err(NotPositiveDefinite);
        }
        let l = d.sqrt();
        target[0] = l;
        let inverse = 1.0 / l;
        for x in &mut target[1..] {
            *x *= inverse;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Adds a symmetric positive semi-definite local block on `columns` to `h` and to `dense`.
    fn add_both(h: &mut Hessian, dense: &mut nalgebra::DMatrix<f64>, columns: &[usize], seed: f64) {
        add_rank(h, dense, columns, seed, 2);
    }

    /// Adds `Σ_r v_rᵀ v_r` over `count` rows v_r on `columns` to `h` and to `dense`, as a group
    /// of `count` rows.
    fn add_rank(
        h: &mut Hessian,
        dense: &mut nalgebra::DMatrix<f64>,
        columns: &[usize],
        seed: f64,
        count: usize,
    ) {
        let m = columns.len();
        let v: Vec<f64> = (0..count * m)
            .map(|i| {
                let (r, k) = ((i / m) as f64, (i % m) as f64);
                (seed * (k + 1.0) + 0.7 * r).cos() + 0.5 * k * (r - 1.0)
            })
            .collect();
        h.add_gram(columns, &v, &v, count);
        for a in 0..m {
            for b in 0..m {
                dense[(columns[a], columns[b])] +=
                    (0..count).map(|r| v[r * m + a] * v[r * m + b]).sum::<f64>();
            }
        }
    }

    /// Checks that `h` (assembled like `dense`) multiplies and solves as the dense matrix.
    fn check_against_dense(h: &mut Hessian, dense: &nalgebra::DMatrix<f64>) {
        let n = dense.nrows();
        let x: Vec<f64> = (0..n).map(|k| 1.0 - 0.3 * k as f64).collect();
        let mut hx = vec![0.0; n];
        h.multiply(&x, &mut hx);
        let expected = dense * nalgebra::DVector::from_column_slice(&x);
        for k in 0..n {
            assert!((hx[k] - expected[k]).abs() < 1e-13, "row {k}: {} vs {}", hx[k], expected[k]);
        }
        h.factor().unwrap();
        let mut solved = expected.as_slice().to_vec();
        h.solve(&mut solved);
        for k in 0..n {
            assert!((solved[k] - x[k]).abs() < 1e-11, "x[{k}]: {} vs {}", solved[k], x[k]);
        }
    }

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
        add_both(&mut h, &mut dense, &[1, 5, 6], 0.3);
        add_both(&mut h, &mut dense, &[2, 3, 4], -0.2);
        check_against_dense(&mut h, &dense);
    }

    /// A ring of six blocks of different widths, each coupled to its neighbours and to one
    /// across: eliminating any block fills in between its neighbours, so the factor needs the
    /// fill analysis to be right; it is refactored after new values (the same pattern).
    #[test]
    fn a_ring_of_coupled_blocks_with_fill_solves_the_dense_matrix() {
        let widths = [3, 1, 4, 2, 6, 3];
        let mut blocks = Vec::new();
        let mut col = 0;
        for w in widths {
            blocks.push((col, w));
            col += w;
        }
        let nv = col;
        let mut pairs: Vec<(usize, usize)> =
            (0..6).map(|b| (b.min((b + 1) % 6), b.max((b + 1) % 6))).collect();
        pairs.push((0, 3));
        pairs.sort_unstable();
        let mut h = Hessian::default();
        h.prepare(&blocks, &pairs);
        for round in 0..2 {
            h.prepare(&blocks, &pairs);
            h.reset();
            let mut dense = nalgebra::DMatrix::<f64>::identity(nv, nv);
            for (p, &(a, b)) in pairs.iter().enumerate() {
                // Two columns of each block of the pair (or its one).
                let mut columns: Vec<usize> = Vec::new();
                for block in [a, b] {
                    let (c, w) = blocks[block];
                    columns.extend(c..c + w.min(2));
                }
                let seed = 0.2 + 0.1 * p as f64 - 0.35 * round as f64;
                add_both(&mut h, &mut dense, &columns, seed);
            }
            // Whole diagonal blocks, too.
            for (b, &(c, w)) in blocks.iter().enumerate() {
                let columns: Vec<usize> = (c..c + w).collect();
                add_both(&mut h, &mut dense, &columns, -0.4 + 0.15 * b as f64);
            }
            check_against_dense(&mut h, &dense);
        }
        assert_eq!(h.analyses, 1, "the pattern is made once");
    }

    /// Groups of one to four rows over columns with gaps and across blocks, added in turns
    /// with factorizations between them: the assembled matrix survives each factorization, so
    /// later additions (a Newton iteration's changes) land on it, and every factor solves the
    /// dense sum so far.
    #[test]
    fn additions_after_a_factorization_accumulate_on_the_assembled_matrix() {
        let blocks = [(0, 4), (4, 6), (10, 3)];
        let pairs = [(0, 1), (1, 2)];
        let mut h = Hessian::default();
        h.prepare(&blocks, &pairs);
        h.reset();
        let mut dense = nalgebra::DMatrix::<f64>::identity(13, 13);
        let groups: [&[usize]; 4] = [&[0, 1, 3, 5, 6, 7, 9], &[2, 3, 4, 8, 9], &[6, 10, 11, 12], &[0, 2]];
        for (turn, count) in [1, 3, 2, 4].into_iter().enumerate() {
            for (g, columns) in groups.iter().enumerate() {
                add_rank(&mut h, &mut dense, columns, 0.3 + 0.2 * g as f64 - 0.1 * turn as f64, count);
            }
            check_against_dense(&mut h, &dense);
        }
    }

    /// A matrix that is not positive definite (a NaN on the diagonal) is refused.
    #[test]
    fn a_nan_pivot_is_refused() {
        let mut h = Hessian::default();
        h.prepare(&[(0, 2)], &[]);
        h.reset();
        h.add_gram(&[1], &[f64::NAN], &[1.0], 1);
        assert!(h.factor().is_err());
    }
}
