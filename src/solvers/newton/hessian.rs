//! The Newton solver's Hessian `H = I + Wᵀ G W` (nv × nv, symmetric positive definite) and its
//! Cholesky factor `H = L Lᵀ`, sparse by blocks.
//!
//! The blocks are stretches of consecutive velocity columns that the solver chooses (branches
//! of the multibodies' trees). A block's own entries are kept dense, and two blocks are coupled
//! where some group of rows touches both (two branches on one path to the root, or a contact
//! between two multibodies). The factor keeps that structure: the blocks are eliminated in an
//! approximate-minimum-degree order of the block graph (faer's AMD), and L is stored as one
//! dense panel per block, column-major: the block's diagonal block over the later blocks its
//! columns reach (coupled ones and fill). A panel updates the later blocks through one dense
//! product of its rows below (`U = L_below L_belowᵀ`), scattered block by block; the solves
//! gather and scatter a panel's rows below once per block. There is no permutation of H or of
//! the right-hand side (a panel's rows are blocks' own columns): this is a supernodal Cholesky
//! whose supernodes are the branches; a general sparse code (faer's simplicial or supernodal
//! LLᵀ) spends most of its time on the scalar pattern and the permutations on these small,
//! dense blocks.
//!
//! The order and the panels are kept while the set of coupled block pairs stays the same: a
//! resting pile factors with the analysis of an earlier step.

use crate::math::fma;
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
    /// The rank of each entry of `below`, for searching a panel's later blocks.
    below_rank: Vec<usize>,
    /// Scratch of [`Hessian::factor`]: per block, where it starts in the panel being updated;
    /// and the update a panel makes to the later blocks (also the gathered rows of
    /// [`Hessian::solve`]).
    scatter: Vec<usize>,
    update: Vec<f64>,
    /// Scratch of [`Hessian::factor`]: a panel's rows below its diagonal block, copied with
    /// their column height padded to whole register tiles (see [`lower_gram`]).
    packed: Vec<f64>,
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
        self.below_rank.clear();
        self.height.clear();
        for b in 0..nb {
            self.below_start.push(self.below.len());
            let mut row = self.blocks[b].1;
            for &r in &lists[list_start[b]..list_start[b] + list_len[b]] {
                self.below.push((r, row));
                self.below_rank.push(self.rank[r]);
                row += self.blocks[r].1;
            }
            self.height.push(row);
        }
        self.below_start.push(self.below.len());
        self.scatter.clear();
        self.scatter.resize(nb, 0);
    }

    /// The panel row where block `r`'s rows start in block `b`'s panel (`r` later than `b`).
    fn offset(&self, b: usize, r: usize) -> usize {
        let range = self.below_start[b]..self.below_start[b + 1];
        let at = self.below_rank[range.clone()]
            .binary_search(&self.rank[r])
            .expect("a later block of the pattern");
        self.below[range][at].1
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
    /// consecutive columns of one block; the entries of a pair of segments form a rectangle of
    /// one panel (its columns one panel height apart, its rows consecutive, or the other way
    /// round when the later segment's block is eliminated first), located once per pair.
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
        for sb in 0..segments.len() - 1 {
            let (b0, b1) = (segments[sb], segments[sb + 1]);
            for sa in sb..segments.len() - 1 {
                let (a0, a1) = (segments[sa], segments[sa + 1]);
                let start = self.position(columns[a0], columns[b0]);
                let block_a = self.block_of_col[columns[a0]];
                let block_b = self.block_of_col[columns[b0]];
                // Steps in `assembled` from one row (a) and one column (b) of the rectangle
                // to the next: rows of a panel are consecutive, its columns `height` apart.
                let (step_a, step_b) = if block_a != block_b && self.rank[block_a] < self.rank[block_b] {
                    (self.height[block_a], 1)
                } else {
                    (1, self.height[block_b])
                };
                for b in b0..b1 {
                    let from = if sa == sb { b } else { a0 };
                    let at = start + (b - b0) * step_b + (from - a0) * step_a;
                    let weights = [
                        right[b],
                        if count > 1 { right[m + b] } else { 0.0 },
                        if count > 2 { right[2 * m + b] } else { 0.0 },
                    ];
                    if count <= 3 && step_a == 1 {
                        let target = &mut self.assembled[at..at + (a1 - from)];
                        add_rows(target, left, m, from, count, &weights);
                    } else {
                        for a in from..a1 {
                            let sum: f64 = (0..count).map(|r| left[r * m + a] * right[r * m + b]).sum();
                            self.assembled[at + (a - from) * step_a] += sum;
                        }
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
        let Self {
            order,
            blocks,
            below,
            below_start,
            panel_start,
            height,
            values,
            scatter,
            update,
            packed,
            ..
        } = self;
        for &b in order.iter() {
            let width = blocks[b].1;
            let (start, h) = (panel_start[b], height[b]);
            // Panels are laid out in elimination order: this one's source, later ones after it.
            let (done, later) = values.split_at_mut(start + h * width);
            let panel = &mut done[start..];
            factor_panel(panel, h, width)?;
            let entries = &below[below_start[b]..below_start[b + 1]];
            let below_rows = h - width;
            if below_rows == 0 {
                continue;
            }
            // U = L_{below,b} L_{below,b}ᵀ, the update of every later block this one reaches
            // (lower triangle, column-major, `ld` rows per column).
            let ld = below_rows.next_multiple_of(TILE_ROWS);
            packed.clear();
            packed.resize(width * ld, 0.0);
            for k in 0..width {
                packed[k * ld..k * ld + below_rows].copy_from_slice(&panel[k * h + width..(k + 1) * h]);
            }
            if update.len() < ld * ld {
                update.resize(ld * ld, 0.0);
            }
            lower_gram(packed, ld, width, below_rows, &mut update[..ld * ld]);
            let base = start + h * width;
            for (p, &(r1, o1)) in entries.iter().enumerate() {
                let w1 = blocks[r1].1;
                let (s1, h1) = (panel_start[r1] - base, height[r1]);
                // The later blocks of b's panel are r1's later blocks too (the fill analysis
                // makes them so): where each starts in r1's panel, by block.
                for &(r, row) in &below[below_start[r1]..below_start[r1 + 1]] {
                    scatter[r] = row;
                }
                for &(r2, o2) in &entries[p..] {
                    let w2 = blocks[r2].1;
                    let (dest, diagonal) = if r2 == r1 { (0, true) } else { (scatter[r2], false) };
                    // Block (r2, r1) of H −= its block of U (the lower triangle on the diagonal).
                    for j in 0..w1 {
                        let from = if diagonal { j } else { 0 };
                        let column = s1 + j * h1 + dest;
                        let target = &mut later[column + from..column + w2];
                        let u = (o1 - width + j) * ld + o2 - width;
                        for (t, s) in target.iter_mut().zip(&update[u + from..u + w2]) {
                            *t -= s;
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// Solves H x = rhs in place with the last factor.
    pub(super) fn solve(&mut self, rhs: &mut [f64]) {
        let Self { order, blocks, below, below_start, panel_start, height, values, update: gathered, .. } =
            self;
        // L y = rhs, blocks in elimination order: the block's own triangle, then its panel's
        // rows below times y into the later blocks (accumulated contiguously, scattered once).
        for &b in order.iter() {
            let (c, width) = blocks[b];
            let (start, h) = (panel_start[b], height[b]);
            let below_rows = h - width;
            gathered.clear();
            gathered.resize(below_rows, 0.0);
            for j in 0..width {
                let column = &values[start + j * h..start + (j + 1) * h];
                let y = rhs[c + j] / column[j];
                rhs[c + j] = y;
                for (x, l) in rhs[c + j + 1..c + width].iter_mut().zip(&column[j + 1..width]) {
                    *x -= l * y;
                }
                for (g, l) in gathered.iter_mut().zip(&column[width..]) {
                    *g += l * y;
                }
            }
            for &(r, row) in &below[below_start[b]..below_start[b + 1]] {
                let (cr, wr) = blocks[r];
                for (x, g) in rhs[cr..cr + wr].iter_mut().zip(&gathered[row - width..row - width + wr]) {
                    *x -= g;
                }
            }
        }
        // Lᵀ x = y, in reverse: the later blocks' x gathered once per block.
        for &b in order.iter().rev() {
            let (c, width) = blocks[b];
            let (start, h) = (panel_start[b], height[b]);
            gathered.clear();
            for &(r, _) in &below[below_start[b]..below_start[b + 1]] {
                let (cr, wr) = blocks[r];
                gathered.extend_from_slice(&rhs[cr..cr + wr]);
            }
            for j in (0..width).rev() {
                let column = &values[start + j * h..start + (j + 1) * h];
                let mut s = rhs[c + j] - crate::math::dot(&column[width..], gathered);
                for (x, l) in rhs[c + j + 1..c + width].iter().zip(&column[j + 1..width]) {
                    s -= l * x;
                }
                rhs[c + j] = s / column[j];
            }
        }
    }
}

/// Rows of a tile of [`lower_gram`]: a multiple of the SIMD width, so that a tile's column is
/// whole vectors.
const TILE_ROWS: usize = 8;
/// Columns of a tile of [`lower_gram`]: with [`TILE_ROWS`], 32 accumulators, which the
/// registers hold.
const TILE_COLS: usize = 4;

/// `update` (`ld` × `ld`, column-major) ← the lower triangle of B Bᵀ in its first `rows`
/// columns, B = `packed` (`ld` rows, a multiple of [`TILE_ROWS`] and at least `rows`, and
/// `width` columns, column-major, zero below its first `rows` rows). Tiles of [`TILE_ROWS`] ×
/// [`TILE_COLS`] entries accumulate over all `width` columns in registers and are stored once
/// (a rank-one pass per column would load and store the whole triangle `width` times); the
/// tiles on the diagonal and at the ends also write a few entries above the diagonal or in the
/// padding, which nothing reads.
fn lower_gram(packed: &[f64], ld: usize, width: usize, rows: usize, update: &mut [f64]) {
    // Tiles start below `rows` at multiples of their size, which divides `ld`: each lies
    // within `ld`.
    for j in (0..rows).step_by(TILE_COLS) {
        for i in (j - j % TILE_ROWS..rows).step_by(TILE_ROWS) {
            let mut acc = [[0.0; TILE_ROWS]; TILE_COLS];
            for column in packed.chunks_exact(ld).take(width) {
                let a: &[f64; TILE_ROWS] = column[i..i + TILE_ROWS].try_into().expect("a whole tile");
                let f: &[f64; TILE_COLS] = column[j..j + TILE_COLS].try_into().expect("whole columns");
                for (acc, f) in acc.iter_mut().zip(f) {
                    for (t, a) in acc.iter_mut().zip(a) {
                        *t = fma(*a, *f, *t);
                    }
                }
            }
            for (c, acc) in acc.iter().enumerate() {
                let at = (j + c) * ld + i;
                update[at..at + TILE_ROWS].copy_from_slice(acc);
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

    /// Blocks of the given widths side by side from column 0, and the columns they cover.
    fn consecutive_blocks(widths: &[usize]) -> (Vec<(usize, usize)>, usize) {
        let mut blocks = Vec::new();
        let mut col = 0;
        for &w in widths {
            blocks.push((col, w));
            col += w;
        }
        (blocks, col)
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
        let (blocks, nv) = consecutive_blocks(&[3, 1, 4, 2, 6, 3]);
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

    /// Wide blocks all coupled to each other: the first blocks eliminated have panels tens of
    /// rows high, not multiples of a tile, so their updates take several register tiles and
    /// padded ones, and the factor still solves the dense matrix.
    #[test]
    fn tall_panels_factor_through_whole_and_padded_tiles() {
        let (blocks, nv) = consecutive_blocks(&[9, 13, 6, 11, 7]);
        let pairs: Vec<(usize, usize)> = (0..5).flat_map(|a| (a + 1..5).map(move |b| (a, b))).collect();
        let mut h = Hessian::default();
        h.prepare(&blocks, &pairs);
        assert!(h.height.iter().any(|&height| height >= 30), "heights {:?}", h.height);
        h.reset();
        let mut dense = nalgebra::DMatrix::<f64>::identity(nv, nv);
        for g in 0..12 {
            // Three rows over every third column from an offset: every block pair coupled.
            let columns: Vec<usize> = (g % 3..nv).step_by(3).collect();
            add_rank(&mut h, &mut dense, &columns, 0.17 + 0.09 * g as f64, 3);
        }
        check_against_dense(&mut h, &dense);
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
