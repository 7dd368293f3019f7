//! Assembly: rows collected by a [`ProblemBuilder`] become a [`ConstraintProblem`] with the
//! Delassus matrix `A = J M⁻¹ Jᵀ` computed from the factor of M (one tree-sparse solve per row,
//! never forming M⁻¹).

use super::{ConstraintProblem, ContactBlock, FrictionModel, RowLaw, RowOrigin};
use crate::algorithms::solve_mass_matrix_slice;
use crate::data::Data;
use crate::model::Model;
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

    /// Builds the problem into `problem` with `minv` applying M⁻¹ in place to a vector of nv
    /// entries, and `v_free` the free velocity (one velocity block).
    pub fn build_into(
        &self,
        v_free: &DVector<f64>,
        mut minv: impl FnMut(&mut [f64]),
        problem: &mut ConstraintProblem,
    ) {
        let blocks = [(0, self.nv)];
        self.build_into_blocks(v_free, &blocks, |_, x| minv(x), true, problem);
    }

    /// Builds the problem into `problem` for a block-diagonal M: `blocks[b]` = (first column,
    /// width) of block b (a multibody), and `minv(b, x)` applies block b's M⁻¹ in place to its
    /// slice `x`. Rows touch few blocks, so M⁻¹Jᵀ and A = J M⁻¹Jᵀ are computed block by block,
    /// and the block structure is kept in [`ConstraintProblem::sparsity`]. With `dense` false,
    /// the dense `jacobian` and `minv_jt` are left empty (the sparse segments hold them; use
    /// [`ConstraintProblem::apply_impulses`]) — the stepping path, which never needs them.
    pub fn build_into_blocks(
        &self,
        v_free: &DVector<f64>,
        blocks: &[(usize, usize)],
        mut minv: impl FnMut(usize, &mut [f64]),
        dense: bool,
        problem: &mut ConstraintProblem,
    ) {
        let (n, nv) = (self.len(), self.nv);
        let (jn, jv) = if dense { (n, nv) } else { (n, 0) };
        if problem.jacobian.shape() != (jn, jv) {
            problem.jacobian = DMatrix::zeros(jn, jv);
            problem.minv_jt = DMatrix::zeros(jv, jn);
        }
        if problem.delassus.shape() != (n, n) {
            problem.delassus = DMatrix::zeros(n, n);
            problem.regularization = DVector::zeros(n);
            problem.bias = DVector::zeros(n);
            problem.target = DVector::zeros(n);
        }
        // Which blocks each row touches, with the row's J and M⁻¹Jᵀ entries on each.
        let sp = &mut problem.sparsity;
        sp.nv = nv;
        sp.blocks.clear();
        sp.blocks.extend_from_slice(blocks);
        sp.row_start.clear();
        sp.blocks_of_row.clear();
        sp.segment_start.clear();
        sp.j_values.clear();
        sp.x_values.clear();
        sp.row_start.push(0);
        for i in 0..n {
            let row = self.row(i);
            for (b, &(col, width)) in blocks.iter().enumerate() {
                let segment = &row[col..col + width];
                if segment.iter().any(|x| *x != 0.0) {
                    sp.blocks_of_row.push(b);
                    sp.segment_start.push(sp.j_values.len());
                    sp.j_values.extend_from_slice(segment);
                    let x_start = sp.x_values.len();
                    sp.x_values.extend_from_slice(segment);
                    minv(b, &mut sp.x_values[x_start..]);
                }
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
        for i in 0..n {
            for e in sp.row_start[i]..sp.row_start[i + 1] {
                let b = sp.blocks_of_row[e];
                // block_start[b] is used as the fill cursor, then restored below.
                sp.rows_of_block[sp.block_start[b]] = i;
                sp.segment_of_block_row[sp.block_start[b]] = sp.segment_start[e];
                sp.block_start[b] += 1;
            }
        }
        for b in (0..blocks.len()).rev() {
            sp.block_start[b + 1] = sp.block_start[b];
        }
        sp.block_start[0] = 0;
        // Dense J and M⁻¹Jᵀ (for export and inspection), if asked.
        problem.minv_jt.fill(0.0);
        for i in (0..n).filter(|_| dense) {
            let row = self.row(i);
            for (k, &x) in row.iter().enumerate() {
                problem.jacobian[(i, k)] = x;
            }
        }
        for i in (0..n).filter(|_| dense) {
            let sp = &problem.sparsity;
            for e in sp.row_start[i]..sp.row_start[i + 1] {
                let (col, width) = sp.blocks[sp.blocks_of_row[e]];
                let start = sp.segment_start[e];
                for k in 0..width {
                    problem.minv_jt[(col + k, i)] = sp.x_values[start + k];
                }
            }
        }
        // A = J (M⁻¹Jᵀ): per block, over the pairs of rows touching it (other blocks give zero).
        problem.delassus.fill(0.0);
        let sp = &problem.sparsity;
        for (b, &(_, width)) in blocks.iter().enumerate() {
            let range = sp.block_start[b]..sp.block_start[b + 1];
            let (rows, segments) = (&sp.rows_of_block[range.clone()], &sp.segment_of_block_row[range]);
            for (p, (&i, &si)) in rows.iter().zip(segments).enumerate() {
                let ji = &sp.j_values[si..si + width];
                for (&j, &sj) in rows[..=p].iter().zip(segments) {
                    let xj = &sp.x_values[sj..sj + width];
                    let a: f64 = ji.iter().zip(xj).map(|(p, q)| p * q).sum();
                    problem.delassus[(i, j)] += a;
                    if i != j {
                        problem.delassus[(j, i)] += a;
                    }
                }
            }
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
    builder.build_into(v_free, |x| solve_mass_matrix_slice(model, data, x), problem);
}
