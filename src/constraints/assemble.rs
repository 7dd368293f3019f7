//! Assembly: rows collected by a [`ProblemBuilder`] become a [`ConstraintProblem`] with the
//! Delassus matrix `A = J M⁻¹ Jᵀ` computed from the tree-sparse factor of M (never forming M⁻¹):
//! A = W Wᵀ with W = J L⁻¹ D^{-1/2}, whose rows keep the sparsity of J's rows.

use super::{ConstraintProblem, ContactBlock, FrictionModel, RowLaw, RowOrigin, RowSparsity};
use crate::data::Data;
use crate::model::{Model, NO_DOF};
use nalgebra::{DMatrix, DVector};

/// Collects constraint rows (Jacobian row, law, target velocity, softness) for one step.
/// Buffers are kept between steps.
#[derive(Clone, Debug)]
pub struct ProblemBuilder {
    nv: usize,
    rows: Vec<f64>,
    targets: Vec<f64>,
    softness: Vec<f64>,
    laws: Vec<RowLaw>,
    contacts: Vec<ContactBlock>,
    origins: Vec<RowOrigin>,
    /// Friction model of the contacts.
    pub friction: FrictionModel,
}

impl ProblemBuilder {
    /// An empty builder for a system of `nv` velocity coordinates.
    pub fn new(nv: usize, friction: FrictionModel) -> Self {
        Self {
            nv,
            rows: Vec::new(),
            targets: Vec::new(),
            softness: Vec::new(),
            laws: Vec::new(),
            contacts: Vec::new(),
            origins: Vec::new(),
            friction,
        }
    }

    /// Number of velocity coordinates.
    pub fn nv(&self) -> usize {
        self.nv
    }

    /// Number of rows so far.
    pub fn len(&self) -> usize {
        self.laws.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.laws.is_empty()
    }

    /// Removes every row (keeps the buffers).
    pub fn clear(&mut self) {
        self.rows.clear();
        self.targets.clear();
        self.softness.clear();
        self.laws.clear();
        self.contacts.clear();
        self.origins.clear();
    }

    /// Appends a row and returns its index and its Jacobian row (zeroed, nv entries) to fill.
    /// `target` is the row's target velocity u*, `softness` its regularisation R_ii.
    pub fn push_row(
        &mut self,
        law: RowLaw,
        target: f64,
        softness: f64,
        origin: RowOrigin,
    ) -> (usize, &mut [f64]) {
        let index = self.laws.len();
        self.laws.push(law);
        self.targets.push(target);
        self.softness.push(softness);
        self.origins.push(origin);
        let start = self.rows.len();
        self.rows.resize(start + self.nv, 0.0);
        (index, &mut self.rows[start..])
    }

    /// Registers a contact block whose normal row is `normal` (the two friction rows follow it).
    pub fn push_contact_block(&mut self, block: ContactBlock) -> usize {
        self.contacts.push(block);
        self.contacts.len() - 1
    }

    /// Number of contact blocks so far.
    pub fn contact_count(&self) -> usize {
        self.contacts.len()
    }

    /// Sets the target velocity of row `i`.
    pub fn set_target(&mut self, i: usize, target: f64) {
        self.targets[i] = target;
    }

    /// The target velocity u* of row `i`.
    pub fn target(&self, i: usize) -> f64 {
        self.targets[i]
    }

    /// The Jacobian row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.rows[i * self.nv..(i + 1) * self.nv]
    }

    /// Builds the problem into `problem` for one multibody whose mass matrix is factored in
    /// `factor` (one velocity block), `v_free` its free velocity.
    pub fn build_into(&self, v_free: &DVector<f64>, factor: TreeFactor<'_>, problem: &mut ConstraintProblem) {
        let blocks = [(0, self.nv)];
        self.build_into_blocks(v_free, &blocks, |_| Some((factor, 0)), true, problem);
    }

    /// Builds the problem into `problem` for a block-diagonal M: `blocks[b]` = (first column,
    /// width) of block b (a multibody, or one root subtree of a multibody), and `factor_of(b)`
    /// gives the factor of the multibody holding block b with the index of the block's first
    /// dof in that multibody's numbering (None: the block cannot move, M⁻¹ = 0 there). Rows
    /// touch few blocks, so M⁻¹Jᵀ and A = J M⁻¹Jᵀ are computed block by block, and the block
    /// structure is kept in [`ConstraintProblem::sparsity`]. With `dense` false, the dense
    /// `jacobian` and `minv_jt` are left empty (the sparse segments hold them; use
    /// [`ConstraintProblem::apply_impulses`]) — the stepping path, which never needs them — and
    /// A itself is left unformed ([`ConstraintProblem::is_matrix_free`]) when its n² entries
    /// outnumber twice W's non-zero spans.
    ///
    /// With M = Lᵀ D L (RBDA §6.5), A = W Wᵀ for W = J L⁻¹ D^{-1/2}. A row of J acting on a body
    /// is non-zero only on the dofs of the body's path to the root, and L⁻ᵀ keeps that pattern
    /// (Featherstone, "Exploiting sparsity in operational-space dynamics", 2010): each row of W
    /// costs O(path · depth), each entry of A a dot product over the span its two rows share.
    pub fn build_into_blocks<'f>(
        &self,
        v_free: &DVector<f64>,
        blocks: &[(usize, usize)],
        factor_of: impl Fn(usize) -> Option<(TreeFactor<'f>, usize)>,
        dense: bool,
        problem: &mut ConstraintProblem,
    ) {
        let (n, nv) = (self.len(), self.nv);
        let (jn, jv) = if dense { (n, nv) } else { (n, 0) };
        if problem.jacobian.shape() != (jn, jv) {
            problem.jacobian = DMatrix::zeros(jn, jv);
            problem.minv_jt = DMatrix::zeros(jv, jn);
        }
        if problem.bias.len() != n {
            problem.regularization = DVector::zeros(n);
            problem.bias = DVector::zeros(n);
            problem.target = DVector::zeros(n);
        }
        // Which blocks each row touches, with the row's J, W and M⁻¹Jᵀ entries on each.
        let sp = &mut problem.sparsity;
        sp.nv = nv;
        sp.blocks.clear();
        sp.blocks.extend_from_slice(blocks);
        sp.row_start.clear();
        sp.blocks_of_row.clear();
        sp.segment_start.clear();
        sp.segment_span.clear();
        sp.w_values.clear();
        sp.row_start.push(0);
        for i in 0..n {
            let row = self.row(i);
            for (b, &(col, width)) in blocks.iter().enumerate() {
                let segment = &row[col..col + width];
                // A branch-free OR over the bits (±0 ignored) vectorizes; most blocks are zero.
                if segment.iter().fold(0u64, |acc, x| acc | (x.to_bits() << 1)) == 0 {
                    continue;
                }
                let Some(last) = segment.iter().rposition(|x| *x != 0.0) else { continue };
                sp.blocks_of_row.push(b);
                let start = sp.w_values.len();
                sp.segment_start.push(start);
                sp.w_values.extend_from_slice(segment);
                let span = match factor_of(b) {
                    Some((factor, first_dof)) => factor.scale_row(first_dof, last, &mut sp.w_values[start..]),
                    None => {
                        sp.w_values[start..].fill(0.0);
                        (0, 0)
                    }
                };
                sp.segment_span.push(span);
            }
            sp.row_start.push(sp.blocks_of_row.len());
        }
        // Rows of each block, by counting sort (rows stay in increasing order).
        sp.block_start.clear();
        sp.block_start.resize(blocks.len() + 1, 0);
        for &b in &sp.blocks_of_row {
            sp.block_start[b + 1] += 1;
        }
        for b in 0..blocks.len() {
            sp.block_start[b + 1] += sp.block_start[b];
        }
        sp.rows_of_block.clear();
        sp.rows_of_block.resize(sp.blocks_of_row.len(), 0);
        sp.segment_of_block_row.clear();
        sp.segment_of_block_row.resize(sp.blocks_of_row.len(), 0);
        sp.span_of_block_row.clear();
        sp.span_of_block_row.resize(sp.blocks_of_row.len(), (0, 0));
        for i in 0..n {
            for e in sp.row_start[i]..sp.row_start[i + 1] {
                let b = sp.blocks_of_row[e];
                // block_start[b] is used as the fill cursor, then restored below.
                sp.rows_of_block[sp.block_start[b]] = i;
                sp.segment_of_block_row[sp.block_start[b]] = sp.segment_start[e];
                sp.span_of_block_row[sp.block_start[b]] = sp.segment_span[e];
                sp.block_start[b] += 1;
            }
        }
        for b in (0..blocks.len()).rev() {
            sp.block_start[b + 1] = sp.block_start[b];
        }
        sp.block_start[0] = 0;
        // Dense J and M⁻¹Jᵀ (for export and inspection), if asked.
        if dense {
            problem.minv_jt.fill(0.0);
            for i in 0..n {
                problem.jacobian.row_mut(i).copy_from_slice(self.row(i));
                let sp = &problem.sparsity;
                for e in sp.row_start[i]..sp.row_start[i + 1] {
                    let (col, width) = sp.blocks[sp.blocks_of_row[e]];
                    let (start, (lo, hi)) = (sp.segment_start[e], sp.segment_span[e]);
                    // Column i of the column-major nv × n matrix, on the block's rows.
                    let x = &mut problem.minv_jt.as_mut_slice()[i * nv + col..i * nv + col + width];
                    x[lo..hi].copy_from_slice(&sp.w_values[start + lo..start + hi]);
                    if let Some((factor, first_dof)) = factor_of(sp.blocks_of_row[e]) {
                        factor.unscale_solve(first_dof, x);
                    }
                }
            }
        }
        // A = W Wᵀ, unless the stepping path is better off matrix-free: n² entries against the
        // spans of W (many rows on small bodies, where a sweep over W is cheaper than over A).
        let span_total: usize = problem.sparsity.segment_span.iter().map(|(lo, hi)| hi - lo).sum();
        if dense || 2 * span_total >= n * n {
            if problem.delassus.shape() != (n, n) {
                problem.delassus = DMatrix::zeros(n, n);
            }
            delassus_from_w(&problem.sparsity, &mut problem.delassus);
        } else if problem.delassus.nrows() != 0 {
            problem.delassus = DMatrix::zeros(0, 0);
        }
        for i in 0..n {
            let row = self.row(i);
            let mut b = 0.0;
            for &blk in problem.sparsity.row_blocks(i) {
                let (col, width) = blocks[blk];
                b += row[col..col + width]
                    .iter()
                    .zip(&v_free.as_slice()[col..col + width])
                    .map(|(p, q)| p * q)
                    .sum::<f64>();
            }
            problem.bias[i] = b - self.targets[i];
            problem.target[i] = self.targets[i];
            problem.regularization[i] = self.softness[i];
        }
        problem.laws.clone_from(&self.laws);
        problem.contacts.clone_from(&self.contacts);
        problem.origins.clone_from(&self.origins);
        problem.friction = self.friction;
    }
}

/// Builds the problem of a single multibody: `data.mass_matrix_factor` must hold the factor of
/// M(q) ([`crate::algorithms::factor_mass_matrix`]).
pub fn assemble_single(
    builder: &ProblemBuilder,
    model: &Model,
    data: &Data,
    v_free: &DVector<f64>,
    problem: &mut ConstraintProblem,
) {
    builder.build_into(v_free, TreeFactor::new(model, data), problem);
}

/// The tree-sparse factor M = Lᵀ D L of one multibody ([`crate::algorithms::factor_mass_matrix`]):
/// L's entries below the diagonal and D on the diagonal of `factor`, `dof_parent` the tree.
#[derive(Clone, Copy, Debug)]
pub struct TreeFactor<'a> {
    factor: &'a DMatrix<f64>,
    dof_parent: &'a [usize],
}

impl<'a> TreeFactor<'a> {
    /// The factor held in `data` (`data.mass_matrix_factor` must be current).
    pub fn new(model: &'a Model, data: &'a Data) -> Self {
        Self { factor: &data.mass_matrix_factor, dof_parent: &model.dof_parent }
    }

    /// For one row segment J (on the dofs `first_dof..first_dof + w.len()` of a block that is a
    /// union of whole root subtrees, `w` holding J on entry, `last` its last non-zero entry):
    /// writes w = D^{-1/2} L⁻ᵀ Jᵀ and returns the span [lo, hi) outside which w is zero.
    fn scale_row(&self, first_dof: usize, last: usize, w: &mut [f64]) -> (usize, usize) {
        let (h, parent) = (self.factor, self.dof_parent);
        // w ← L⁻ᵀ w, walking each non-zero entry's ancestors (they have lower indices).
        for k in (0..=last).rev() {
            let wk = w[k];
            if wk == 0.0 {
                continue;
            }
            let (mut j, row) = (parent[first_dof + k], first_dof + k);
            while j != NO_DOF {
                w[j - first_dof] -= h[(row, j)] * wk;
                j = parent[j];
            }
        }
        let Some(lo) = w[..=last].iter().position(|x| *x != 0.0) else { return (0, 0) };
        for k in lo..=last {
            w[k] /= h[(first_dof + k, first_dof + k)].sqrt();
        }
        (lo, last + 1)
    }

    /// x ← L⁻¹ D^{-1/2} x on a block's slice (the inverse map of the row scaling W = J L⁻¹ D^{-1/2}, so
    /// that M⁻¹Jᵀλ = L⁻¹ D^{-1/2} Wᵀλ).
    pub fn unscale_solve(&self, first_dof: usize, x: &mut [f64]) {
        let (h, parent) = (self.factor, self.dof_parent);
        let Some(lo) = x.iter().position(|x| *x != 0.0) else { return };
        // Entries below lo stay zero: no dof there has an ancestor at or above lo.
        for k in lo..x.len() {
            let row = first_dof + k;
            let mut xk = x[k] / h[(row, row)].sqrt();
            let mut j = parent[row];
            while j != NO_DOF {
                xk -= h[(row, j)] * x[j - first_dof];
                j = parent[j];
            }
            x[k] = xk;
        }
    }
}

/// A = W Wᵀ into `a` (n × n): per block, over the pairs of rows touching it (other blocks give
/// zero), each dot product over the span where both rows' W can be non-zero.
pub(crate) fn delassus_from_w(sp: &RowSparsity, a: &mut DMatrix<f64>) {
    a.fill(0.0);
    for b in 0..sp.blocks.len() {
        let range = sp.block_start[b]..sp.block_start[b + 1];
        let rows = &sp.rows_of_block[range.clone()];
        let segments = &sp.segment_of_block_row[range.clone()];
        let spans = &sp.span_of_block_row[range];
        for (p, ((&i, &si), &(lo_i, hi_i))) in rows.iter().zip(segments).zip(spans).enumerate() {
            for ((&j, &sj), &(lo_j, hi_j)) in rows[..=p].iter().zip(segments).zip(spans) {
                let (lo, hi) = (lo_i.max(lo_j), hi_i.min(hi_j));
                if lo >= hi {
                    continue;
                }
                let x = dot(&sp.w_values[si + lo..si + hi], &sp.w_values[sj + lo..sj + hi]);
                a[(i, j)] += x;
                if i != j {
                    a[(j, i)] += x;
                }
            }
        }
    }
}

/// Σ a_k b_k with four partial sums, so that the additions pipeline (a single running sum is
/// bound by the latency of one addition per entry).
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let (mut s0, mut s1, mut s2, mut s3) = (0.0, 0.0, 0.0, 0.0);
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (p, q) in ca.zip(cb) {
        s0 += p[0] * q[0];
        s1 += p[1] * q[1];
        s2 += p[2] * q[2];
        s3 += p[3] * q[3];
    }
    for (p, q) in ra.iter().zip(rb) {
        s0 += p * q;
    }
    (s0 + s1) + (s2 + s3)
}
