//! Assembly: rows collected by a [`ProblemBuilder`] become a [`ConstraintProblem`] with the
//! Delassus matrix `A = J M⁻¹ Jᵀ` computed from the tree-sparse factor of M (never forming M⁻¹):
//! A = W Wᵀ with W = J L⁻¹ D^{-1/2}, whose rows keep the sparsity of J's rows.
//!
//! This file holds the builder and its rows (stored segments, or compactly as a contact's point
//! rates or one joint's coefficients); `delassus.rs` turns them into W, A and the bias,
//! `tree_factor.rs` holds the factor of M they are scaled by, and `reuse.rs` the record that lets
//! a step with the same rows keep W.

mod delassus;
mod reuse;
#[cfg(test)]
mod tests;
mod tree_factor;

pub use delassus::assemble_single;
pub(crate) use delassus::{delassus_from_w, index_rows_by_block, runs_dot};
pub(crate) use reuse::BuiltRows;
pub use tree_factor::TreeFactor;

use super::{ContactBlock, FrictionModel, RowLaw, RowOrigin};
use crate::error::SolverError;
use crate::math::{dot, Vec3};
use std::ops::{Index, IndexMut};

/// Collects constraint rows (Jacobian row, law, target velocity, softness) for one step.
/// Buffers are kept between steps.
///
/// The velocity columns are split into blocks (a multibody, or one root subtree of one; one
/// block of all columns by default, see [`ProblemBuilder::with_blocks`]), and a row stores one
/// dense segment per block it touches: a contact row of a world with thousands of velocity
/// coordinates costs the width of its one or two bodies' blocks, not the world's width.
#[derive(Clone, Debug)]
pub struct ProblemBuilder {
    nv: usize,
    /// (first column, width) of each block; they tile `0..nv`.
    blocks: Vec<(usize, usize)>,
    /// The block of each column.
    block_of_col: Vec<u32>,
    /// First segment of each row: row i's are `row_segments[i]..row_segments[i + 1]` (the last
    /// row's run to the end).
    row_segments: Vec<usize>,
    /// Block of each segment.
    segment_block: Vec<usize>,
    /// Start of each segment's values (its block's width of them) in `values`.
    segment_start: Vec<usize>,
    values: Vec<f64>,
    targets: Vec<f64>,
    softness: Vec<f64>,
    laws: Vec<RowLaw>,
    contacts: Vec<ContactBlock>,
    origins: Vec<RowOrigin>,
    /// Point rates of the contacts' rows ([`crate::collision::point_rates`]: velocity column,
    /// world velocity of the point per unit rate of that column's dof), each side of each
    /// contact one path to the root, last dof first.
    rates: Vec<(usize, Vec3)>,
    /// Per row, how its Jacobian row is given.
    forms: Vec<RowForm>,
    /// Friction model of the contacts.
    pub friction: FrictionModel,
}

/// A position in a [`ProblemBuilder`]'s rows (the lengths of its buffers), to truncate to.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct RowsMark {
    rows: usize,
    segments: usize,
    values: usize,
    contacts: usize,
    rates: usize,
}

/// How a row's Jacobian row is given: stored entries, or compactly (a contact's point rates,
/// the coefficients on one joint's dofs), so that such a row costs the length of its bodies'
/// paths to the root, not the width of their blocks.
#[derive(Clone, Copy, Debug)]
enum RowForm {
    /// Entries stored in segments ([`ProblemBuilder::push_row`]).
    Stored,
    /// A contact row ([`ProblemBuilder::push_point_contact`]).
    Rates(RateRow),
    /// `coefficients[..len]` at the consecutive columns `first..first + len`, the dofs of one
    /// joint, each the parent of the next ([`ProblemBuilder::push_joint_row`]).
    Joint { first: usize, coefficients: [f64; 3], len: usize },
}

/// A contact row given by its point rates: its Jacobian row is `J = Σ (dᵀ u) e_c` over the
/// rates `(c, u)` of both sides.
#[derive(Clone, Copy, Debug)]
struct RateRow {
    /// Ranges in [`ProblemBuilder::rates`] of the two sides' rates (empty: a static side).
    sides: [(usize, usize); 2],
    /// The row's world direction d (unit): the contact normal or a tangent.
    direction: Vec3,
}

/// The Jacobian row being written ([`ProblemBuilder::push_row`]), indexed by velocity column
/// like a dense row of `nv` entries; entries never written read as zero. Writing to a column
/// of a block the row does not touch yet adds a zeroed segment for that block.
#[derive(Debug)]
pub struct RowMut<'a> {
    builder: &'a mut ProblemBuilder,
}

impl RowMut<'_> {
    fn find(&self, col: usize) -> Option<usize> {
        let b = &*self.builder;
        let block = b.block_of_col[col] as usize;
        let first = *b.row_segments.last().expect("a row is open");
        (first..b.segment_block.len())
            .find(|&s| b.segment_block[s] == block)
            .map(|s| b.segment_start[s] + col - b.blocks[block].0)
    }
}

impl Index<usize> for RowMut<'_> {
    type Output = f64;

    fn index(&self, col: usize) -> &f64 {
        assert!(col < self.builder.nv, "column {col} out of range ({} columns)", self.builder.nv);
        match self.find(col) {
            Some(k) => &self.builder.values[k],
            None => &0.0,
        }
    }
}

impl IndexMut<usize> for RowMut<'_> {
    fn index_mut(&mut self, col: usize) -> &mut f64 {
        assert!(col < self.builder.nv, "column {col} out of range ({} columns)", self.builder.nv);
        let (segment, first) = crate::collision::JacobianRow::segment_mut(self, col);
        &mut segment[col - first]
    }
}

impl crate::collision::JacobianRow for RowMut<'_> {
    fn segment_mut(&mut self, col: usize) -> (&mut [f64], usize) {
        let b = &mut *self.builder;
        let block = b.block_of_col[col] as usize;
        let (first, width) = b.blocks[block];
        let open = *b.row_segments.last().expect("a row is open");
        let start = match (open..b.segment_block.len()).find(|&s| b.segment_block[s] == block) {
            Some(s) => b.segment_start[s],
            None => {
                let start = b.values.len();
                b.segment_block.push(block);
                b.segment_start.push(start);
                b.values.resize(start + width, 0.0);
                start
            }
        };
        (&mut b.values[start..start + width], first)
    }
}

impl ProblemBuilder {
    /// An empty builder for a system of `nv` velocity coordinates, all in one block.
    pub fn new(nv: usize, friction: FrictionModel) -> Self {
        let blocks = if nv > 0 { vec![(0, nv)] } else { Vec::new() };
        Self {
            nv,
            blocks,
            block_of_col: vec![0; nv],
            row_segments: Vec::new(),
            segment_block: Vec::new(),
            segment_start: Vec::new(),
            values: Vec::new(),
            targets: Vec::new(),
            softness: Vec::new(),
            laws: Vec::new(),
            contacts: Vec::new(),
            origins: Vec::new(),
            rates: Vec::new(),
            forms: Vec::new(),
            friction,
        }
    }

    /// An empty builder whose columns are split into `blocks` ((first column, width) each, in
    /// order, tiling `0..nv` with no gap or overlap) such that M is block-diagonal over them:
    /// rows store one segment per block they touch, and [`ProblemBuilder::build_into_blocks`]
    /// factors per block.
    pub fn with_blocks(
        nv: usize,
        blocks: &[(usize, usize)],
        friction: FrictionModel,
    ) -> Result<Self, SolverError> {
        let mut next = 0;
        let mut block_of_col = Vec::with_capacity(nv);
        for (b, &(first, width)) in blocks.iter().enumerate() {
            if first != next || width == 0 {
                return Err(SolverError::InvalidProblem(format!(
                    "velocity blocks {blocks:?} do not tile the {nv} velocity columns (block {b})"
                )));
            }
            block_of_col.resize(first + width, b as u32);
            next = first + width;
        }
        if next != nv {
            return Err(SolverError::InvalidProblem(format!(
                "velocity blocks {blocks:?} cover {next} of the {nv} velocity columns"
            )));
        }
        let mut builder = Self::new(0, friction);
        builder.nv = nv;
        builder.blocks = blocks.to_vec();
        builder.block_of_col = block_of_col;
        Ok(builder)
    }

    /// Appends the velocity columns `self.nv()..nv`, split into `blocks` ((first column, width)
    /// each, in order, tiling them with no gap or overlap), and drops the rows: the builder is as
    /// [`ProblemBuilder::with_blocks`] would make it for all the blocks, in time proportional to
    /// the columns added (a world adds its multibodies one at a time).
    pub fn append_blocks(&mut self, nv: usize, blocks: &[(usize, usize)]) -> Result<(), SolverError> {
        let mut next = self.nv;
        for (b, &(first, width)) in blocks.iter().enumerate() {
            if first != next || width == 0 {
                return Err(SolverError::InvalidProblem(format!(
                    "velocity block {b} ({first}, {width}) does not continue the tiling at column {next}"
                )));
            }
            next = first + width;
        }
        if next != nv {
            return Err(SolverError::InvalidProblem(format!(
                "appended velocity blocks end at column {next}, not at {nv}"
            )));
        }
        for &(first, width) in blocks {
            self.block_of_col.resize(first + width, self.blocks.len() as u32);
            self.blocks.push((first, width));
        }
        self.nv = nv;
        self.clear();
        Ok(())
    }

    /// Number of velocity coordinates.
    pub fn nv(&self) -> usize {
        self.nv
    }

    /// The velocity blocks ((first column, width) each).
    pub fn blocks(&self) -> &[(usize, usize)] {
        &self.blocks
    }

    /// Number of rows so far.
    pub fn len(&self) -> usize {
        self.laws.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.laws.is_empty()
    }

    /// The point rates of the contact rows: append a contact's sides to it with
    /// [`crate::collision::point_rates`] (columns of this builder's velocities), then give their
    /// ranges to [`ProblemBuilder::push_point_contact`].
    pub(crate) fn rates_mut(&mut self) -> &mut Vec<(usize, Vec3)> {
        &mut self.rates
    }

    /// Where the rows end now: [`ProblemBuilder::truncate`] returns to it.
    pub(crate) fn mark(&self) -> RowsMark {
        RowsMark {
            rows: self.len(),
            segments: self.segment_block.len(),
            values: self.values.len(),
            contacts: self.contacts.len(),
            rates: self.rates.len(),
        }
    }

    /// Removes the rows after `mark` (from [`ProblemBuilder::mark`], with no row removed since),
    /// keeping those before it as they are.
    pub(crate) fn truncate(&mut self, mark: RowsMark) {
        debug_assert!(mark.rows <= self.len() && mark.rates <= self.rates.len());
        self.row_segments.truncate(mark.rows);
        self.segment_block.truncate(mark.segments);
        self.segment_start.truncate(mark.segments);
        self.values.truncate(mark.values);
        self.targets.truncate(mark.rows);
        self.softness.truncate(mark.rows);
        self.laws.truncate(mark.rows);
        self.contacts.truncate(mark.contacts);
        self.origins.truncate(mark.rows);
        self.rates.truncate(mark.rates);
        self.forms.truncate(mark.rows);
    }

    /// The contact blocks so far (normal row and friction coefficients of each contact).
    pub(crate) fn contact_blocks(&self) -> &[ContactBlock] {
        &self.contacts
    }

    /// Removes every row (keeps the buffers).
    pub fn clear(&mut self) {
        self.row_segments.clear();
        self.segment_block.clear();
        self.segment_start.clear();
        self.values.clear();
        self.targets.clear();
        self.softness.clear();
        self.laws.clear();
        self.contacts.clear();
        self.origins.clear();
        self.rates.clear();
        self.forms.clear();
    }

    /// Appends a row and returns its index and its Jacobian row (all zero) to fill, indexed by
    /// velocity column. `target` is the row's target velocity u*, `softness` its
    /// regularisation R_ii.
    pub fn push_row(
        &mut self,
        law: RowLaw,
        target: f64,
        softness: f64,
        origin: RowOrigin,
    ) -> (usize, RowMut<'_>) {
        let index = self.laws.len();
        self.laws.push(law);
        self.targets.push(target);
        self.softness.push(softness);
        self.origins.push(origin);
        self.forms.push(RowForm::Stored);
        self.row_segments.push(self.segment_block.len());
        (index, RowMut { builder: self })
    }

    /// Appends a contact's normal row and its two friction rows, along the world directions
    /// `directions` (normal first, then the tangents), with the [`ContactBlock`] tying them;
    /// returns the normal row's index. Their Jacobian rows are given by point rates: `sides`
    /// are the ranges in [`ProblemBuilder::rates_mut`] of the two sides' rates, each one body's
    /// path to the root as [`crate::collision::point_rates`] appends it (side b's with the sign
    /// −1), empty for a static side. The normal row gets the regularisation `softness`, the
    /// targets are zero ([`ProblemBuilder::set_target`]).
    ///
    /// Assembly works on the paths: a contact costs the length of its bodies' paths to the
    /// root, not the width of their blocks. Panics if a range is out of bounds (and, in debug
    /// builds, at assembly if a side's rates are not a path to the root). The public way in
    /// is [`crate::constraints::add_contact_rows`], which forms the rates itself.
    pub(crate) fn push_point_contact(
        &mut self,
        sides: [(usize, usize); 2],
        directions: [Vec3; 3],
        softness: f64,
        origin: RowOrigin,
        mu: f64,
        mu2: f64,
    ) -> usize {
        for &(start, end) in &sides {
            assert!(start <= end && end <= self.rates.len(), "point rates {start}..{end} out of range");
        }
        let (normal, contact) = (self.len(), self.contacts.len());
        for (r, direction) in directions.into_iter().enumerate() {
            let law = if r == 0 { RowLaw::Unilateral } else { RowLaw::Friction { contact } };
            self.laws.push(law);
            self.targets.push(0.0);
            self.softness.push(if r == 0 { softness } else { 0.0 });
            self.origins.push(origin);
            self.forms.push(RowForm::Rates(RateRow { sides, direction }));
            self.row_segments.push(self.segment_block.len());
        }
        self.contacts.push(ContactBlock { normal, mu, mu2 });
        normal
    }

    /// Appends a row on the dofs of one joint: `coefficients` (at most 3) at the consecutive
    /// velocity columns from `first`, each dof the parent of the next (a joint's own dofs, as
    /// [`crate::model::Model`] numbers them); returns its index. `target` is the row's target
    /// velocity u*, `softness` its regularisation R_ii. Assembly scales it along the chain of
    /// the joint's last dof only (columns that are not one joint's chained dofs are scaled as
    /// stored entries). Panics with more than 3 coefficients, or columns out of range or in
    /// two velocity blocks.
    pub fn push_joint_row(
        &mut self,
        law: RowLaw,
        target: f64,
        softness: f64,
        origin: RowOrigin,
        first: usize,
        coefficients: &[f64],
    ) -> usize {
        let len = coefficients.len();
        assert!(
            (1..=3).contains(&len)
                && first + len <= self.nv
                && self.block_of_col[first] == self.block_of_col[first + len - 1],
            "joint row on columns {first}..{} (at most 3, in one velocity block)",
            first + len
        );
        let mut stored = [0.0; 3];
        stored[..len].copy_from_slice(coefficients);
        self.laws.push(law);
        self.targets.push(target);
        self.softness.push(softness);
        self.origins.push(origin);
        self.forms.push(RowForm::Joint { first, coefficients: stored, len });
        self.row_segments.push(self.segment_block.len());
        self.len() - 1
    }

    /// The entries of row `i` given compactly: (column, value), a column once per contact side
    /// whose path holds it (none for a row of stored entries).
    fn compact_entries(&self, i: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let (sides, direction, joint) = match self.forms[i] {
            RowForm::Rates(RateRow { sides, direction }) => (sides, direction, None),
            RowForm::Joint { first, coefficients, len } => {
                ([(0, 0); 2], Vec3::zeros(), Some((first, coefficients, len)))
            }
            RowForm::Stored => ([(0, 0); 2], Vec3::zeros(), None),
        };
        let rates = sides.into_iter().flat_map(move |(start, end)| {
            self.rates[start..end].iter().map(move |(c, u)| (*c, direction.dot(u)))
        });
        let joint = joint.into_iter().flat_map(|(first, coefficients, len)| {
            coefficients.into_iter().take(len).enumerate().map(move |(k, x)| (first + k, x))
        });
        rates.chain(joint)
    }

    /// The segments of row `i`: (block, first column, values over the block's width).
    fn segments(&self, i: usize) -> impl Iterator<Item = (usize, usize, &[f64])> + '_ {
        let end = self.row_segments.get(i + 1).copied().unwrap_or(self.segment_block.len());
        (self.row_segments[i]..end).map(move |s| {
            let block = self.segment_block[s];
            let (first, width) = self.blocks[block];
            let start = self.segment_start[s];
            (block, first, &self.values[start..start + width])
        })
    }

    /// Registers a contact block whose normal row is `normal` (the two friction rows follow it),
    /// for rows pushed with [`ProblemBuilder::push_row`].
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

    /// J_i · v for row `i` and a velocity `v` of `nv` entries (e.g. m/s for a contact normal).
    pub fn row_dot(&self, i: usize, v: &[f64]) -> f64 {
        let stored: f64 =
            self.segments(i).map(|(_, first, values)| dot(values, &v[first..first + values.len()])).sum();
        if let RowForm::Rates(RateRow { sides, direction }) = self.forms[i] {
            // A contact row (every step, for each contact's approach speed): plain loops over
            // the point rates, which the chained iterators of `compact_entries` do not become.
            let mut compact = -0.0;
            for (start, end) in sides {
                for (c, u) in &self.rates[start..end] {
                    compact += direction.dot(u) * v[*c];
                }
            }
            return stored + compact;
        }
        if let RowForm::Joint { first, coefficients, len } = self.forms[i] {
            // A joint row (every resting step's bias, for each limit and friction row).
            return stored
                + coefficients[..len].iter().zip(&v[first..first + len]).map(|(x, v)| x * v).sum::<f64>();
        }
        stored + self.compact_entries(i).map(|(c, x)| x * v[c]).sum::<f64>()
    }

    /// Writes the dense Jacobian row `i` (`nv` entries) into `out`.
    pub fn row_into(&self, i: usize, out: &mut [f64]) {
        out[..self.nv].fill(0.0);
        for (_, first, values) in self.segments(i) {
            for (o, v) in out[first..first + values.len()].iter_mut().zip(values) {
                *o += v;
            }
        }
        for (c, x) in self.compact_entries(i) {
            out[c] += x;
        }
    }

    /// The dense Jacobian row `i` (`nv` entries; allocates, for inspection and tests).
    pub fn row(&self, i: usize) -> Vec<f64> {
        let mut out = vec![0.0; self.nv];
        self.row_into(i, &mut out);
        out
    }
}
