//! Assembly: rows collected by a [`ProblemBuilder`] become a [`ConstraintProblem`] with the
//! Delassus matrix `A = J M⁻¹ Jᵀ` computed from the tree-sparse factor of M (never forming M⁻¹):
//! A = W Wᵀ with W = J L⁻¹ D^{-1/2}, whose rows keep the sparsity of J's rows.

use super::{ConstraintProblem, ContactBlock, FrictionModel, RowLaw, RowOrigin, RowSparsity};
use crate::data::Data;
use crate::error::SolverError;
use crate::math::{axpy, dot, Vec3};
use crate::model::{Model, NO_DOF};
use nalgebra::{DMatrix, DVector};
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

    /// Rows `i..i + 3`, a contact's normal and friction rows given by point rates
    /// ([`ProblemBuilder::push_point_contact`]), into `sp`: W for the three at once, as three
    /// lanes of one back substitution along each side's path ([`TreeFactor::scale_chain_lanes`];
    /// along the union of both paths when the two sides share a block,
    /// [`TreeFactor::scale_pattern_lanes`]). `jv` gets their J v_free.
    #[allow(clippy::too_many_arguments)]
    fn push_rate_contact<'f>(
        &self,
        i: usize,
        factor_of: &impl Fn(usize) -> Option<(TreeFactor<'f>, usize)>,
        v_free: &[f64],
        lanes: &mut Vec<[f64; 4]>,
        pattern: &mut Vec<usize>,
        stretches: &mut Vec<(usize, usize, usize)>,
        sp: &mut RowSparsity,
        jv: &mut [f64],
    ) {
        let row = |r: usize| match self.forms[i + r] {
            RowForm::Rates(row) => row,
            _ => unreachable!("a contact's rows are given by point rates"),
        };
        let sides = row(0).sides;
        let d = [row(0).direction, row(1).direction, row(2).direction];
        let lane = |u: &Vec3| [d[0].dot(u), d[1].dot(u), d[2].dot(u), 0.0];
        let (a, b) = (&self.rates[sides[0].0..sides[0].1], &self.rates[sides[1].0..sides[1].1]);
        let block_of = |rates: &[(usize, Vec3)]| rates.first().map(|&(c, _)| self.block_of_col[c] as usize);
        let none: &[(usize, Vec3)] = &[];
        // One group per block the contact touches, in block order (W's runs then increase):
        // one side's path, or both sides' paths when they share the block.
        let groups = match (block_of(a), block_of(b)) {
            (Some(x), Some(y)) if x == y => [Some((x, a, b)), None],
            (Some(x), Some(y)) if y < x => [Some((y, b, none)), Some((x, a, none))],
            (x, y) => [x.map(|x| (x, a, none)), y.map(|y| (y, b, none))],
        };
        lanes.clear();
        // J v_free of the three rows (and the unused lane), summed in path order.
        let mut velocity = [0.0; 4];
        let add_velocity = |velocity: [f64; 4], x: &[f64; 4], v: f64| {
            [velocity[0] + x[0] * v, velocity[1] + x[1] * v, velocity[2] + x[2] * v, velocity[3] + x[3] * v]
        };
        // Per group: its block and its stretches of consecutive columns (first column, first
        // lane, length) in `stretches`, from which W's runs are copied row by row.
        let mut shapes = [None, None];
        stretches.clear();
        let push_stretch =
            |stretches: &mut Vec<(usize, usize, usize)>, from: usize, c: usize, lane: usize| {
                let count = stretches.len();
                match stretches.last_mut() {
                    Some((col, _, len)) if count > from && *col + *len == c => *len += 1,
                    _ => stretches.push((c, lane, 1)),
                }
            };
        for (shape, &(block, first, second)) in shapes.iter_mut().zip(groups.iter().flatten()) {
            let (block_col, width) = self.blocks[block];
            // A block that cannot move (no factor) has W = 0 there: no runs.
            let factor = factor_of(block);
            // `add_contact_rows_with` fills the rates with whole paths (the builder's contract).
            if let (true, Some((factor, first_dof))) = (cfg!(debug_assertions), factor) {
                for path in [first, second] {
                    assert!(
                        factor.is_path_to_root(path.iter().map(|&(c, _)| first_dof + c - block_col)),
                        "the point rates of contact row {i} are not one body's path to the root"
                    );
                }
            }
            let (offset, from) = (lanes.len(), stretches.len());
            if second.is_empty() {
                // The path's rates run from its last dof up: reversed, the chain root first.
                lanes.extend(first.iter().rev().map(|(_, u)| lane(u)));
                for ((c, _), x) in first.iter().rev().zip(&lanes[offset..]) {
                    velocity = add_velocity(velocity, x, v_free[*c]);
                }
                if let Some((factor, first_dof)) = factor {
                    factor.scale_chain_lanes(first_dof + first[0].0 - block_col, &mut lanes[offset..]);
                    for (p, (c, _)) in first.iter().rev().enumerate() {
                        push_stretch(stretches, from, *c, offset + p);
                    }
                    *shape = Some((block, from..stretches.len()));
                }
            } else {
                // Lanes at the block's dofs: a stretch of consecutive columns is one of lanes.
                lanes.resize(offset + width, [0.0; 4]);
                let u = &mut lanes[offset..];
                pattern.clear();
                merge_paths(first, second, block_col, pattern);
                for &(c, ref r) in first.iter().chain(second) {
                    let x = lane(r);
                    for (u, x) in u[c - block_col].iter_mut().zip(x) {
                        *u += x;
                    }
                }
                for &k in pattern.iter() {
                    velocity = add_velocity(velocity, &u[k], v_free[block_col + k]);
                }
                if let Some((factor, first_dof)) = factor {
                    factor.scale_pattern_lanes(first_dof, pattern, u);
                    for &k in pattern.iter().rev() {
                        push_stretch(stretches, from, block_col + k, offset + k);
                    }
                    *shape = Some((block, from..stretches.len()));
                }
            }
        }
        jv[i..i + 3].copy_from_slice(&velocity[..3]);
        // A_{t1 t2}, which PGS's two-row friction step needs, while the lanes are at hand.
        let mut coupling = 0.0;
        for (_, range) in shapes.iter().flatten() {
            for &(_, lane, len) in &stretches[range.clone()] {
                coupling += lanes[lane..lane + len].iter().map(|x| x[1] * x[2]).sum::<f64>();
            }
        }
        sp.friction_coupling.push(coupling);
        for r in 0..3 {
            let mut norm2 = 0.0;
            for (block, range) in shapes.iter().flatten() {
                let (start, runs) = (sp.w_values.len(), sp.runs.len());
                for &(col, lane, len) in &stretches[range.clone()] {
                    sp.runs.push((col, sp.w_values.len(), len));
                    sp.w_values.extend(lanes[lane..lane + len].iter().map(|x| x[r]));
                }
                let w = &sp.w_values[start..];
                norm2 += dot(w, w);
                close_entry(sp, *block, runs);
            }
            finish_row(sp, norm2);
        }
    }

    /// W of a row on one joint's dofs ([`ProblemBuilder::push_joint_row`]: `coefficients` at
    /// the columns from `first`) into `sp`, as the runs of the chain of the joint's last dof
    /// ([`TreeFactor::scale_chain`]); returns ‖W_i‖². `u` is scratch.
    fn push_joint_row_w<'f>(
        &self,
        first: usize,
        coefficients: &[f64],
        factor_of: &impl Fn(usize) -> Option<(TreeFactor<'f>, usize)>,
        u: &mut Vec<f64>,
        sp: &mut RowSparsity,
    ) -> f64 {
        let last = first + coefficients.len() - 1;
        let block = self.block_of_col[last] as usize;
        let Some((factor, first_dof)) = factor_of(block) else { return 0.0 };
        let block_col = self.blocks[block].0;
        let tail = first_dof + last - block_col;
        let dof = |c: usize| first_dof + c - block_col;
        if (first + 1..=last).any(|c| factor.dof_parent[dof(c)] != dof(c - 1)) {
            // Not one joint's chained dofs: the row as stored entries, scaled by the walk.
            let width = self.blocks[block].1;
            u.clear();
            u.resize(width, 0.0);
            u[first - block_col..=last - block_col].copy_from_slice(coefficients);
            let Some(last_entry) = last_nonzero(u) else { return 0.0 };
            let span = factor.scale_row(first_dof, last_entry, u);
            let runs = sp.runs.len();
            let norm2 = push_dense_runs(sp, block_col, u, span);
            close_entry(sp, block, runs);
            return norm2;
        }
        // The joint's dofs are the chain's last entries.
        let path = factor.chain(tail);
        u.clear();
        u.resize(path.len() + 1 - coefficients.len(), 0.0);
        u.extend_from_slice(coefficients);
        factor.scale_chain(tail, u);
        let col = |p: usize| block_col + path.get(p).copied().unwrap_or(tail) - first_dof;
        let (start, runs) = (sp.w_values.len(), sp.runs.len());
        // Runs of consecutive columns from the first non-zero entry (ancestors the joint is
        // not coupled to stay zero).
        let mut p = u.iter().position(|x| *x != 0.0).unwrap_or(u.len());
        while p < u.len() {
            let from = p;
            p += 1;
            while p < u.len() && col(p) == col(p - 1) + 1 {
                p += 1;
            }
            sp.runs.push((col(from), sp.w_values.len(), p - from));
            sp.w_values.extend_from_slice(&u[from..p]);
        }
        close_entry(sp, block, runs);
        let w = &sp.w_values[start..];
        dot(w, w)
    }

    /// How many rows from `i` (1 to 4) are rows on the dofs of one joint that
    /// [`Self::push_joint_rows_w_lanes`] scales as lanes of one pass: consecutive joint rows
    /// whose columns all lie in one run of at most three chained dofs (a joint's friction rows,
    /// one per dof; a ball joint's swing and twist rows, each on its three dofs).
    fn joint_lanes<'f>(
        &self,
        i: usize,
        factor_of: &impl Fn(usize) -> Option<(TreeFactor<'f>, usize)>,
    ) -> usize {
        let RowForm::Joint { first, len, .. } = self.forms[i] else { return 1 };
        let (mut lo, mut hi) = (first, first + len - 1);
        let mut count = 1;
        while count < 4 && i + count < self.forms.len() {
            let RowForm::Joint { first, len, .. } = self.forms[i + count] else { break };
            let (l, h) = (lo.min(first), hi.max(first + len - 1));
            if h - l > 2 {
                break;
            }
            (lo, hi) = (l, h);
            count += 1;
        }
        if count == 1 {
            return 1;
        }
        let block = self.block_of_col[hi] as usize;
        if self.block_of_col[lo] as usize != block {
            return 1;
        }
        let Some((factor, first_dof)) = factor_of(block) else { return 1 };
        let dof = |c: usize| first_dof + c - self.blocks[block].0;
        if (lo + 1..=hi).any(|c| factor.dof_parent[dof(c)] != dof(c - 1)) {
            return 1;
        }
        count
    }

    /// W of `count` rows from `i` on one joint's chained dofs ([`Self::joint_lanes`]), as lanes of
    /// one back substitution along the chain of their last dof ([`TreeFactor::scale_chain_lanes`]),
    /// each row's runs then taken up to its own last dof: the same entries, bit for bit, as
    /// [`Self::push_joint_row_w`] row by row, for the cost of one row.
    fn push_joint_rows_w_lanes<'f>(
        &self,
        i: usize,
        count: usize,
        factor_of: &impl Fn(usize) -> Option<(TreeFactor<'f>, usize)>,
        lanes: &mut Vec<[f64; 4]>,
        sp: &mut RowSparsity,
    ) {
        let row = |j: usize| match self.forms[j] {
            RowForm::Joint { first, coefficients, len } => (first, coefficients, len),
            _ => unreachable!("joint_lanes groups joint rows only"),
        };
        let last = (i..i + count).map(|j| row(j).0 + row(j).2 - 1).max().unwrap_or(0);
        let block = self.block_of_col[last] as usize;
        let Some((factor, first_dof)) = factor_of(block) else {
            unreachable!("joint_lanes checked the factor")
        };
        let block_col = self.blocks[block].0;
        let tail = first_dof + last - block_col;
        let path = factor.chain(tail);
        // The chain's position of column c, one of the joint's dofs (the chain's last entries).
        let position = |c: usize| path.len() - (last - c);
        lanes.clear();
        lanes.resize(path.len() + 1, [0.0; 4]);
        for (lane, j) in (i..i + count).enumerate() {
            let (first, coefficients, len) = row(j);
            for (k, x) in coefficients[..len].iter().enumerate() {
                lanes[position(first + k)][lane] = *x;
            }
        }
        factor.scale_chain_lanes(tail, lanes);
        let col = |p: usize| block_col + path.get(p).copied().unwrap_or(tail) - first_dof;
        for (lane, j) in (i..i + count).enumerate() {
            let (first, _, len) = row(j);
            let end = position(first + len - 1) + 1;
            let (start, runs) = (sp.w_values.len(), sp.runs.len());
            let mut p = lanes[..end].iter().position(|x| x[lane] != 0.0).unwrap_or(end);
            while p < end {
                let from = p;
                p += 1;
                while p < end && col(p) == col(p - 1) + 1 {
                    p += 1;
                }
                sp.runs.push((col(from), sp.w_values.len(), p - from));
                sp.w_values.extend(lanes[from..p].iter().map(|x| x[lane]));
            }
            close_entry(sp, block, runs);
            let w = &sp.w_values[start..];
            finish_row(sp, dot(w, w));
        }
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

    /// Renews what `problem` holds besides W: the bias `b = J v_free − u*`, the targets, the
    /// regularisation, the laws, contact blocks and origins, for rows that are those `problem`
    /// was built from up to [`BuiltRows::same_rows`]'s tolerance, on the same factors — W, A
    /// and the solvers' kept Wᵀλ stand. O(entries of J) instead of O(path · depth) per row.
    pub(crate) fn refresh_bias(&self, v_free: &DVector<f64>, problem: &mut ConstraintProblem) {
        let v_free = v_free.as_slice();
        // A contact's three rows share their point rates: the relative velocity of its points
        // once, then one dot product per direction.
        let mut point_velocity: Option<([(usize, usize); 2], Vec3)> = None;
        for i in 0..self.len() {
            let velocity = match self.forms[i] {
                RowForm::Rates(RateRow { sides, direction }) => {
                    let relative = match point_velocity {
                        Some((kept, relative)) if kept == sides => relative,
                        _ => {
                            let mut sum = [0.0; 3];
                            for &(start, end) in &sides {
                                for (c, u) in &self.rates[start..end] {
                                    let x = v_free[*c];
                                    sum = [sum[0] + u.x * x, sum[1] + u.y * x, sum[2] + u.z * x];
                                }
                            }
                            let relative = Vec3::new(sum[0], sum[1], sum[2]);
                            point_velocity = Some((sides, relative));
                            relative
                        }
                    };
                    direction.dot(&relative)
                }
                _ => self.row_dot(i, v_free),
            };
            problem.bias[i] = velocity;
        }
        self.finish_problem(problem);
    }

    /// The rest of `problem` once its bias holds J v_free: b = J v_free − u*, the targets u*,
    /// the regularisation, laws, contact blocks, origins and friction model of the rows.
    fn finish_problem(&self, problem: &mut ConstraintProblem) {
        for i in 0..self.len() {
            problem.bias[i] -= self.targets[i];
            problem.target[i] = self.targets[i];
            problem.regularization[i] = self.softness[i];
        }
        problem.laws.clone_from(&self.laws);
        problem.contacts.clone_from(&self.contacts);
        problem.origins.clone_from(&self.origins);
        problem.friction = self.friction;
    }

    /// Builds the problem into `problem` for one multibody whose mass matrix is factored in
    /// `factor`, `v_free` its free velocity.
    pub fn build_into(&self, v_free: &DVector<f64>, factor: TreeFactor<'_>, problem: &mut ConstraintProblem) {
        let blocks = &self.blocks;
        self.build_into_blocks(v_free, |b| Some((factor, blocks[b].0)), true, problem);
    }

    /// Builds the problem into `problem` for a block-diagonal M over the builder's blocks
    /// ([`ProblemBuilder::with_blocks`]: a multibody, or one root subtree of one): `factor_of(b)`
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
        factor_of: impl Fn(usize) -> Option<(TreeFactor<'f>, usize)>,
        dense: bool,
        problem: &mut ConstraintProblem,
    ) {
        let (n, nv, blocks) = (self.len(), self.nv, &self.blocks[..]);
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
        // Which blocks each row touches, with the row's W on each, as runs.
        let sp = &mut problem.sparsity;
        sp.nv = nv;
        sp.blocks.clear();
        sp.blocks.extend_from_slice(blocks);
        sp.row_start.clear();
        sp.blocks_of_row.clear();
        sp.entry_run_start.clear();
        sp.w_values.clear();
        sp.row_norm2.clear();
        sp.friction_coupling.clear();
        sp.runs.clear();
        sp.run_start.clear();
        sp.run_start.push(0);
        sp.row_start.push(0);
        sp.entry_run_start.push(0);
        // W changes: a solver's kept Wᵀλ of the last problem is void.
        problem.kept_lambda.0.get_mut().clear();
        let mut lanes = std::mem::take(problem.lanes.0.get_mut());
        let mut pattern = std::mem::take(problem.pattern.0.get_mut());
        let mut stretches = std::mem::take(problem.stretches.0.get_mut());
        let mut scaled = std::mem::take(problem.scratch.0.get_mut());
        let sp = &mut problem.sparsity;
        // J v_free per row, formed with the rows (the bias below).
        let jv = problem.bias.as_mut_slice();
        let v_free = v_free.as_slice();
        let (mut i, mut next_contact) = (0, 0);
        while i < n {
            while next_contact < self.contacts.len() && self.contacts[next_contact].normal < i {
                next_contact += 1;
            }
            if matches!(self.forms[i], RowForm::Joint { .. }) {
                let count = self.joint_lanes(i, &factor_of);
                if count > 1 {
                    self.push_joint_rows_w_lanes(i, count, &factor_of, &mut lanes, sp);
                }
                for (form, jv) in self.forms[i..i + count].iter().zip(&mut jv[i..i + count]) {
                    let RowForm::Joint { first, coefficients, len } = *form else { unreachable!() };
                    *jv = (0..len).map(|c| coefficients[c] * v_free[first + c]).sum();
                    if count == 1 {
                        let norm2 =
                            self.push_joint_row_w(first, &coefficients[..len], &factor_of, &mut scaled, sp);
                        finish_row(sp, norm2);
                    }
                }
                i += count;
                continue;
            }
            if matches!(self.forms[i], RowForm::Rates(_)) {
                debug_assert_eq!(self.contacts.get(next_contact).map(|c| c.normal), Some(i));
                self.push_rate_contact(
                    i,
                    &factor_of,
                    v_free,
                    &mut lanes,
                    &mut pattern,
                    &mut stretches,
                    sp,
                    jv,
                );
                i += 3;
                continue;
            }
            let (mut norm2, mut velocity) = (0.0, 0.0);
            for (b, col, segment) in self.segments(i) {
                let Some(last) = last_nonzero(segment) else { continue };
                velocity += dot(segment, &v_free[col..col + segment.len()]);
                let Some((factor, first_dof)) = factor_of(b) else { continue };
                scaled.clear();
                scaled.extend_from_slice(segment);
                let span = factor.scale_row(first_dof, last, &mut scaled);
                let runs = sp.runs.len();
                norm2 += push_dense_runs(sp, col, &scaled, span);
                close_entry(sp, b, runs);
            }
            finish_row(sp, norm2);
            jv[i] = velocity;
            i += 1;
        }
        if problem.sparsity.friction_coupling.len() != self.contacts.len() {
            // Some contact's rows were stored entries: A_{t1 t2} from W when asked.
            problem.sparsity.friction_coupling.clear();
        }
        *problem.lanes.0.get_mut() = lanes;
        *problem.pattern.0.get_mut() = pattern;
        *problem.stretches.0.get_mut() = stretches;
        *problem.scratch.0.get_mut() = scaled;
        // Dense J and M⁻¹Jᵀ (for export and inspection), if asked.
        if dense {
            problem.jacobian.fill(0.0);
            problem.minv_jt.fill(0.0);
            for i in 0..n {
                for (_, first, values) in self.segments(i) {
                    for (k, v) in values.iter().enumerate() {
                        problem.jacobian[(i, first + k)] += *v;
                    }
                }
                for (c, x) in self.compact_entries(i) {
                    problem.jacobian[(i, c)] += x;
                }
                let sp = &problem.sparsity;
                for e in sp.row_start[i]..sp.row_start[i + 1] {
                    let (col, width) = sp.blocks[sp.blocks_of_row[e]];
                    // Column i of the column-major nv × n matrix, on the block's rows.
                    let x = &mut problem.minv_jt.as_mut_slice()[i * nv + col..i * nv + col + width];
                    for &(c, start, len) in sp.entry_runs(e) {
                        x[c - col..c - col + len].copy_from_slice(&sp.w_values[start..start + len]);
                    }
                    if let Some((factor, first_dof)) = factor_of(sp.blocks_of_row[e]) {
                        factor.unscale_solve(first_dof, x);
                    }
                }
            }
        }
        // A = W Wᵀ, unless the stepping path is better off matrix-free: n² entries against the
        // spans of W (many rows on small bodies, where a sweep over W is cheaper than over A).
        let span_total: usize = problem.sparsity.runs.iter().map(|run| run.2).sum();
        if dense || 2 * span_total >= n * n {
            if problem.delassus.shape() != (n, n) {
                problem.delassus = DMatrix::zeros(n, n);
            }
            index_rows_by_block(&mut problem.sparsity);
            delassus_from_w(&problem.sparsity, &mut problem.delassus);
        } else {
            // Matrix-free: the per-block index is only needed to form A, which is left unformed.
            problem.sparsity.block_start.clear();
            if problem.delassus.nrows() != 0 {
                problem.delassus = DMatrix::zeros(0, 0);
            }
        }
        self.finish_problem(problem);
    }
}

/// The Jacobian rows a problem's W was last built from, as the builder held them: when a
/// step's rows are the same up to a tolerance and the mass-matrix factors are the ones W was
/// built on, W = J L⁻¹ D^{-1/2} (and A = W Wᵀ, when formed) stand, and only the bias
/// J v_free − u* is new ([`ProblemBuilder::refresh_bias`]). The buffers are kept between steps.
#[derive(Clone, Debug, Default)]
pub(crate) struct BuiltRows {
    /// Whether the rows below are those of the problem's W.
    valid: bool,
    blocks: Vec<(usize, usize)>,
    forms: Vec<RowForm>,
    rates: Vec<(usize, Vec3)>,
    row_segments: Vec<usize>,
    segment_block: Vec<usize>,
    values: Vec<f64>,
    laws: Vec<RowLaw>,
}

impl BuiltRows {
    /// Records `builder`'s rows as those W was just built from (copies; no allocation once the
    /// buffers have grown to the rows' size).
    pub(crate) fn record(&mut self, builder: &ProblemBuilder) {
        self.valid = true;
        self.blocks.clone_from(&builder.blocks);
        self.forms.clone_from(&builder.forms);
        self.rates.clone_from(&builder.rates);
        self.row_segments.clone_from(&builder.row_segments);
        self.segment_block.clone_from(&builder.segment_block);
        self.values.clone_from(&builder.values);
        self.laws.clone_from(&builder.laws);
    }

    /// Forgets the recorded rows (the problem was replaced).
    pub(crate) fn forget(&mut self) {
        self.valid = false;
    }

    /// Whether `builder`'s rows are the recorded ones: the same rows, laws, blocks and columns,
    /// and every Jacobian entry (a contact's direction and point rates, a joint row's
    /// coefficients, stored entries) within `tolerance` of the recorded one, relative to the
    /// larger of 1 and its size (directions are unit, point rates m per rad or 1). The rows
    /// before `unchanged` (if given) are known to be the recorded ones bit for bit (kept from
    /// the step W was built in): their entries are not compared.
    pub(crate) fn same_rows(
        &self,
        builder: &ProblemBuilder,
        tolerance: f64,
        unchanged: Option<RowsMark>,
    ) -> bool {
        let from = unchanged.unwrap_or_default();
        // Branch-free (`&`, not `&&`) over the many point rates: one compare per entry.
        let close = |a: f64, b: f64| (a - b).abs() <= tolerance * b.abs().max(1.0);
        let close3 = |a: &Vec3, b: &Vec3| close(a.x, b.x) & close(a.y, b.y) & close(a.z, b.z);
        let same_form = |a: &RowForm, b: &RowForm| match (a, b) {
            (RowForm::Stored, RowForm::Stored) => true,
            (RowForm::Rates(a), RowForm::Rates(b)) => {
                a.sides == b.sides && close3(&a.direction, &b.direction)
            }
            (
                RowForm::Joint { first, coefficients, len },
                RowForm::Joint { first: first_b, coefficients: coefficients_b, len: len_b },
            ) => {
                first == first_b
                    && len == len_b
                    && coefficients[..*len].iter().zip(coefficients_b).all(|(a, b)| close(*a, *b))
            }
            _ => false,
        };
        self.valid
            && self.blocks == builder.blocks
            && self.laws == builder.laws
            && self.row_segments == builder.row_segments
            && self.segment_block == builder.segment_block
            && self.rates.len() == builder.rates.len()
            && self.values.len() == builder.values.len()
            && self.forms.len() == builder.forms.len()
            && builder.forms[from.rows..].iter().zip(&self.forms[from.rows..]).all(|(a, b)| same_form(a, b))
            && builder.rates[from.rates..]
                .iter()
                .zip(&self.rates[from.rates..])
                .fold(true, |same, (a, b)| same & (a.0 == b.0) & close3(&a.1, &b.1))
            && builder.values[from.values..]
                .iter()
                .zip(&self.values[from.values..])
                .fold(true, |same, (a, b)| same & close(*a, *b))
    }
}

/// Appends block-local dofs of the union of two paths to the root to `pattern`, decreasing and
/// each once: the columns of `first` and `second` (point rates, each path from its last dof
/// up, so decreasing) less `block_col`.
fn merge_paths(
    first: &[(usize, Vec3)],
    second: &[(usize, Vec3)],
    block_col: usize,
    pattern: &mut Vec<usize>,
) {
    let (mut x, mut y) = (first.iter().map(|r| r.0).peekable(), second.iter().map(|r| r.0).peekable());
    loop {
        let next = match (x.peek(), y.peek()) {
            (Some(&a), Some(&b)) => {
                if a >= b {
                    x.next();
                }
                if b >= a {
                    y.next();
                }
                a.max(b)
            }
            (Some(&a), None) => {
                x.next();
                a
            }
            (None, Some(&b)) => {
                y.next();
                b
            }
            (None, None) => return,
        };
        pattern.push(next - block_col);
    }
}

/// Ends the row's entry on block `block` whose runs were appended since `runs_before`: recorded
/// only if it has any (W is zero on the block otherwise).
fn close_entry(sp: &mut RowSparsity, block: usize, runs_before: usize) {
    if sp.runs.len() > runs_before {
        sp.blocks_of_row.push(block);
        sp.entry_run_start.push(sp.runs.len());
    }
}

/// Ends the row being written: its ‖W_i‖² and where its runs and blocks end.
fn finish_row(sp: &mut RowSparsity, norm2: f64) {
    sp.row_norm2.push(norm2);
    sp.run_start.push(sp.runs.len());
    sp.row_start.push(sp.blocks_of_row.len());
}

/// The index of the last non-zero entry of a row segment (None: all zero). A branch-free OR
/// over the bits (±0 ignored) first, which vectorizes: many segments are all zero.
fn last_nonzero(segment: &[f64]) -> Option<usize> {
    if segment.iter().fold(0u64, |acc, x| acc | (x.to_bits() << 1)) == 0 {
        return None;
    }
    segment.iter().rposition(|x| *x != 0.0)
}

/// Builds the problem of a single multibody whose M(q) [`crate::algorithms::factor_mass_matrix`]
/// has factored in `data`.
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
    /// L's rows packed along each dof's path ([`crate::algorithms::factor_mass_matrix`]): dof
    /// k's ancestors' entries, root first, then D_k, from `dof_path_start[k] + k`.
    packed: &'a [f64],
    dof_path: &'a [usize],
    dof_path_start: &'a [usize],
    inv_sqrt_d: &'a [f64],
    coupled: &'a [bool],
    dof_parent: &'a [usize],
    run_start: &'a [usize],
}

impl<'a> TreeFactor<'a> {
    /// The factor held in `data` ([`crate::algorithms::factor_mass_matrix`] must have factored
    /// the current M).
    pub fn new(model: &'a Model, data: &'a Data) -> Self {
        Self {
            packed: &data.factor_packed,
            dof_path: &model.dof_path,
            dof_path_start: &model.dof_path_start,
            inv_sqrt_d: data.factor_inv_sqrt_d.as_slice(),
            coupled: &data.factor_row_coupled,
            dof_parent: &model.dof_parent,
            run_start: &model.dof_run_start,
        }
    }

    /// L_kj for the ancestors j of dof k in `start..end` (a stretch of consecutive ancestors):
    /// k's packed row holds its ancestors root first, so the stretch is contiguous there, from
    /// the position of `start` on k's path (its depth).
    fn stretch(&self, k: usize, start: usize, end: usize) -> &'a [f64] {
        let depth_of_start = self.dof_path_start[start + 1] - self.dof_path_start[start];
        let from = self.dof_path_start[k] + k + depth_of_start;
        &self.packed[from..from + (end - start)]
    }

    /// Whether `dofs` (a side's point rates' dofs, [`crate::collision::point_rates`]) run from
    /// a dof up its path to the root, each the parent of the one before, ending at a root dof
    /// (or are empty).
    fn is_path_to_root(&self, mut dofs: impl Iterator<Item = usize>) -> bool {
        let Some(mut k) = dofs.next() else { return true };
        for parent in dofs {
            if self.dof_parent.get(k) != Some(&parent) {
                return false;
            }
            k = parent;
        }
        self.dof_parent.get(k) == Some(&NO_DOF)
    }

    /// The ancestors of dof `tail`, root first.
    fn chain(&self, tail: usize) -> &'a [usize] {
        &self.dof_path[self.dof_path_start[tail]..self.dof_path_start[tail + 1]]
    }

    /// [`Self::scale_chain_lanes`] for one row: `u[p]` its entry at the chain's p-th dof.
    fn scale_chain(&self, tail: usize, u: &mut [f64]) {
        let path = self.chain(tail);
        debug_assert_eq!(u.len(), path.len() + 1);
        let dof_at = |p: usize| path.get(p).copied().unwrap_or(tail);
        for p in (1..u.len()).rev() {
            let (dof, up) = (dof_at(p), u[p]);
            if up == 0.0 || !self.coupled[dof] {
                continue;
            }
            axpy(&mut u[..p], -up, &self.packed[self.dof_path_start[dof] + dof..][..p]);
        }
        for (p, x) in u.iter_mut().enumerate() {
            *x *= self.inv_sqrt_d[dof_at(p)];
        }
    }

    /// [`Self::scale_row`] for up to four rows (lanes) non-zero only on the chain of dof `tail` and its
    /// ancestors: `u[p]` holds the lanes at the chain's p-th dof (root first, `tail` last). The
    /// ancestors of the chain's p-th dof are its first p dofs, and that dof's packed row of L
    /// holds their entries in the same order, so the back substitution is a dense triangular
    /// one over the chain: no walk of ancestor stretches, no scan of the block's other dofs.
    fn scale_chain_lanes(&self, tail: usize, u: &mut [[f64; 4]]) {
        let path = self.chain(tail);
        debug_assert_eq!(u.len(), path.len() + 1);
        let dof_at = |p: usize| path.get(p).copied().unwrap_or(tail);
        // Right-looking: the latest entry p first, u_p subtracted from every earlier entry q
        // with L_pq, read from p's packed row, which holds its ancestors' entries in the
        // chain's order (the same operations in the same order per entry as collecting each
        // q from the later p, which looked each L_pq up by its own index). A dof whose row of L
        // is zero off the diagonal (a body whose origin is its centre of mass, on principal
        // axes) has nothing to subtract.
        for p in (1..u.len()).rev() {
            let dof = dof_at(p);
            if !self.coupled[dof] {
                continue;
            }
            let row = &self.packed[self.dof_path_start[dof] + dof..][..p];
            let (earlier, rest) = u.split_at_mut(p);
            let up = rest[0];
            for (uq, &l) in earlier.iter_mut().zip(row) {
                for a in 0..4 {
                    uq[a] -= l * up[a];
                }
            }
        }
        for (p, w) in u.iter_mut().enumerate() {
            let s = self.inv_sqrt_d[dof_at(p)];
            for x in w.iter_mut() {
                *x *= s;
            }
        }
    }

    /// For one row segment J (on the dofs `first_dof..first_dof + w.len()` of a block that is a
    /// union of whole root subtrees, `w` holding J on entry, `last` its last non-zero entry):
    /// writes w = D^{-1/2} L⁻ᵀ Jᵀ and returns the span [lo, hi) outside which w is zero.
    fn scale_row(&self, first_dof: usize, last: usize, w: &mut [f64]) -> (usize, usize) {
        // w ← L⁻ᵀ w, walking each non-zero entry's ancestors (they have lower indices) in
        // contiguous stretches, L_kj read from k's packed row.
        for k in (0..=last).rev() {
            let wk = w[k];
            let row = first_dof + k;
            if wk == 0.0 || !self.coupled[row] {
                continue;
            }
            let (mut start, mut end) = (self.run_start[row], row);
            loop {
                axpy(&mut w[start - first_dof..end - first_dof], -wk, self.stretch(row, start, end));
                let next = self.dof_parent[start];
                if next == NO_DOF {
                    break;
                }
                (start, end) = (self.run_start[next], next + 1);
            }
        }
        let Some(lo) = w[..=last].iter().position(|x| *x != 0.0) else { return (0, 0) };
        for (w, s) in w[lo..=last].iter_mut().zip(&self.inv_sqrt_d[first_dof + lo..]) {
            *w *= s;
        }
        (lo, last + 1)
    }

    /// [`Self::scale_chain_lanes`] for rows non-zero on a union of paths to the root (a contact
    /// between two bodies of one block): `u` holds the lanes at the block's dofs (dof
    /// `first_dof + k` at `u[k]`), zero outside `pattern`, the union's block-local dofs in
    /// decreasing order (every dof's ancestors are in it). Right-looking as there: a dof's
    /// lanes are final once its descendants, which come before it, have been subtracted.
    fn scale_pattern_lanes(&self, first_dof: usize, pattern: &[usize], u: &mut [[f64; 4]]) {
        for &k in pattern {
            let dof = first_dof + k;
            if !self.coupled[dof] {
                continue;
            }
            let uk = u[k];
            let path = self.chain(dof);
            let row = &self.packed[self.dof_path_start[dof] + dof..][..path.len()];
            for (&j, &l) in path.iter().zip(row) {
                let w = &mut u[j - first_dof];
                for a in 0..4 {
                    w[a] -= l * uk[a];
                }
            }
        }
        for &k in pattern {
            let s = self.inv_sqrt_d[first_dof + k];
            for x in u[k].iter_mut() {
                *x *= s;
            }
        }
    }

    /// x ← L⁻¹ D^{-1/2} x on a block's slice (the inverse map of the row scaling W = J L⁻¹ D^{-1/2}, so
    /// that M⁻¹Jᵀλ = L⁻¹ D^{-1/2} Wᵀλ).
    pub fn unscale_solve(&self, first_dof: usize, x: &mut [f64]) {
        let Some(lo) = x.iter().position(|x| *x != 0.0) else { return };
        // Entries below lo stay zero: no dof there has an ancestor at or above lo.
        for k in lo..x.len() {
            let row = first_dof + k;
            let mut xk = x[k] * self.inv_sqrt_d[row];
            if !self.coupled[row] {
                x[k] = xk;
                continue;
            }
            let (mut start, mut end) = (self.run_start[row], row);
            loop {
                xk -= dot(self.stretch(row, start, end), &x[start - first_dof..end - first_dof]);
                let next = self.dof_parent[start];
                if next == NO_DOF {
                    break;
                }
                (start, end) = (self.run_start[next], next + 1);
            }
            x[k] = xk;
        }
    }
}

/// Appends W's row segment on one block (`w`, the block's first column `col`, zero outside
/// `span`) as runs of its non-zero entries, and returns Σ w². Gaps of fewer than four zeros are
/// kept inside a run: skipping them would cost more in loop overhead than the products.
fn push_dense_runs(sp: &mut RowSparsity, col: usize, w: &[f64], span: (usize, usize)) -> f64 {
    const MIN_GAP: usize = 4;
    let mut k = span.0;
    let mut norm2 = 0.0;
    while k < span.1 {
        if w[k] == 0.0 {
            k += 1;
            continue;
        }
        let (first, mut end, mut zeros) = (k, k + 1, 0);
        k += 1;
        while k < span.1 && zeros < MIN_GAP {
            if w[k] == 0.0 {
                zeros += 1;
            } else {
                zeros = 0;
                end = k + 1;
            }
            k += 1;
        }
        let values = &w[first..end];
        sp.runs.push((col + first, sp.w_values.len(), values.len()));
        sp.w_values.extend_from_slice(values);
        norm2 += dot(values, values);
    }
    norm2
}

/// The rows touching each block (`rows_of_block`, `block_start`) with their segments and spans,
/// by counting sort over the rows' blocks (rows stay in increasing order): the index
/// [`delassus_from_w`] walks.
pub(crate) fn index_rows_by_block(sp: &mut RowSparsity) {
    sp.block_start.clear();
    sp.block_start.resize(sp.blocks.len() + 1, 0);
    for &b in &sp.blocks_of_row {
        sp.block_start[b + 1] += 1;
    }
    for b in 0..sp.blocks.len() {
        sp.block_start[b + 1] += sp.block_start[b];
    }
    sp.rows_of_block.clear();
    sp.rows_of_block.resize(sp.blocks_of_row.len(), 0);
    sp.entry_of_block_row.clear();
    sp.entry_of_block_row.resize(sp.blocks_of_row.len(), 0);
    for i in 0..sp.row_start.len().saturating_sub(1) {
        for e in sp.row_start[i]..sp.row_start[i + 1] {
            let b = sp.blocks_of_row[e];
            // block_start[b] is used as the fill cursor, then restored below.
            sp.rows_of_block[sp.block_start[b]] = i;
            sp.entry_of_block_row[sp.block_start[b]] = e;
            sp.block_start[b] += 1;
        }
    }
    for b in (0..sp.blocks.len()).rev() {
        sp.block_start[b + 1] = sp.block_start[b];
    }
    sp.block_start[0] = 0;
}

/// A = W Wᵀ into `a` (n × n): per block, over the pairs of rows touching it (other blocks give
/// zero), each dot product over the columns where both rows' runs overlap.
pub(crate) fn delassus_from_w(sp: &RowSparsity, a: &mut DMatrix<f64>) {
    a.fill(0.0);
    for b in 0..sp.blocks.len() {
        let range = sp.block_start[b]..sp.block_start[b + 1];
        let rows = &sp.rows_of_block[range.clone()];
        let entries = &sp.entry_of_block_row[range];
        for (p, (&i, &ei)) in rows.iter().zip(entries).enumerate() {
            for (&j, &ej) in rows[..=p].iter().zip(entries) {
                let x = runs_dot(sp, sp.entry_runs(ei), sp.entry_runs(ej));
                a[(i, j)] += x;
                if i != j {
                    a[(j, i)] += x;
                }
            }
        }
    }
}

/// W_i · W_j over two rows' runs on one block (each in increasing columns): a dot product over
/// each overlap of a run of one with a run of the other.
pub(crate) fn runs_dot(sp: &RowSparsity, a: &[(usize, usize, usize)], b: &[(usize, usize, usize)]) -> f64 {
    let (mut p, mut q, mut total) = (0, 0, 0.0);
    while p < a.len() && q < b.len() {
        let ((ca, sa, la), (cb, sb, lb)) = (a[p], b[q]);
        let (lo, hi) = (ca.max(cb), (ca + la).min(cb + lb));
        if lo < hi {
            total += dot(&sp.w_values[sa + lo - ca..sa + hi - ca], &sp.w_values[sb + lo - cb..sb + hi - cb]);
        }
        if ca + la <= cb + lb {
            p += 1;
        } else {
            q += 1;
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algorithms::jacobian::last_dof_of;
    use crate::algorithms::{crba, factor_mass_matrix};
    use crate::io::urdf::{load_file, UrdfOptions};
    use rand::{Rng, SeedableRng};

    /// Random entries on the path of `body` to the root (a Jacobian row of a point on it).
    fn fill_path(model: &Model, body: usize, sign: f64, rng: &mut impl Rng, row: &mut RowMut<'_>) {
        let mut k = last_dof_of(model, body);
        while k != NO_DOF {
            row[k] += sign * rng.random_range(-1.0..1.0);
            k = model.dof_parent[k];
        }
    }

    /// The ragdoll at a random configuration (seeded), its mass matrix factored: the model, the
    /// data holding the factor, M, and the generator for the rest of the test.
    fn factored_ragdoll(seed: u64) -> (Model, Data, DMatrix<f64>, rand::rngs::StdRng) {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/models/ragdoll.urdf");
        let model = load_file(path, &UrdfOptions::floating()).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let q = model.random_configuration(&mut rng);
        let mut data = Data::new(&model);
        crba(&model, &mut data, &q).unwrap();
        let m = data.mass_matrix.clone();
        factor_mass_matrix(&model, &mut data).unwrap();
        (model, data, m, rng)
    }

    /// Assembles `builder`'s rows at a random free velocity and checks against the dense solve
    /// with M: A = J M⁻¹ Jᵀ, each ‖W_i‖² = A_ii, each contact's A_{t1 t2}, and the bias J v_free
    /// (no targets). Returns the problem for further checks.
    fn assemble_against_dense(
        builder: &ProblemBuilder,
        model: &Model,
        data: &Data,
        m: &DMatrix<f64>,
        rng: &mut rand::rngs::StdRng,
    ) -> ConstraintProblem {
        let mut problem = ConstraintProblem::default();
        let v_free = DVector::from_fn(model.nv(), |_, _| rng.random_range(-1.0..1.0));
        assemble_single(builder, model, data, &v_free, &mut problem);
        let j = problem.jacobian.clone();
        let expected = &j * m.clone().cholesky().unwrap().solve(&j.transpose());
        let scale = expected.abs().max();
        assert!((&problem.delassus - &expected).abs().max() < 1e-12 * scale);
        let velocity = &j * &v_free;
        for i in 0..builder.len() {
            assert!((problem.sparsity.row_norm2[i] - expected[(i, i)]).abs() < 1e-12 * scale, "row {i}");
            assert!((problem.bias[i] - velocity[i]).abs() < 1e-12 * velocity.amax(), "row {i}");
        }
        for c in 0..problem.contacts.len() {
            let (_, t1, t2) = problem.contacts[c].rows();
            let coupling = problem.friction_coupling(c);
            assert!((coupling - expected[(t1, t2)]).abs() < 1e-12 * scale, "contact {c}");
        }
        problem
    }

    /// Appends random point rates along the path of `body` to the root, as
    /// [`crate::collision::point_rates`] does (last dof first), and returns their range; the
    /// rate of dof `zero_at` (if on the path) is zero.
    fn random_rates(
        builder: &mut ProblemBuilder,
        model: &Model,
        body: usize,
        zero_at: usize,
        rng: &mut impl Rng,
    ) -> (usize, usize) {
        let start = builder.rates_mut().len();
        let mut k = last_dof_of(model, body);
        while k != NO_DOF {
            let u = Vec3::from_fn(|_, _| rng.random_range(-1.0..1.0));
            builder.rates_mut().push((k, if k == zero_at { Vec3::zeros() } else { u }));
            k = model.dof_parent[k];
        }
        (start, builder.rates_mut().len())
    }

    #[test]
    fn contact_rows_from_point_rates_give_the_delassus_matrix_and_bias_of_a_dense_solve() {
        let (model, data, m, mut rng) = factored_ragdoll(3);
        let nv = model.nv();
        let mut builder = ProblemBuilder::new(nv, FrictionModel::Cone);
        // A self-contact between two limbs (two paths in one block, scaled along their union),
        // a contact with the world (one path, scaled along its chain) whose rates are zero at a
        // dof in the middle of the path, and between them a row of stored entries and a contact
        // of stored rows (scaled row by row).
        let last = model.nbodies() - 1;
        let middle = model.dof_path[model.dof_path_start[last_dof_of(&model, last / 3)] + 4];
        for (a, b) in [(last, Some(last / 2)), (last / 3, None)] {
            let side_a = random_rates(&mut builder, &model, a, middle, &mut rng);
            let side_b = match b {
                Some(b) => random_rates(&mut builder, &model, b, NO_DOF, &mut rng),
                None => (side_a.1, side_a.1),
            };
            let directions = [0; 3].map(|_| Vec3::from_fn(|_, _| rng.random_range(-1.0..1.0)));
            let normal =
                builder.push_point_contact([side_a, side_b], directions, 0.0, RowOrigin::Other, 0.5, 0.5);
            assert_eq!(builder.contacts[builder.contact_count() - 1].normal, normal);
            let (_, mut row) = builder.push_row(RowLaw::Unilateral, 0.0, 0.0, RowOrigin::Other);
            fill_path(&model, last / 2, 1.0, &mut rng, &mut row);
        }
        // Contacts given by point rates only: assembly keeps their A_{t1 t2}; with a contact of
        // stored rows among them (below) it is formed from W when asked.
        let rates_only = assemble_against_dense(&builder, &model, &data, &m, &mut rng);
        assert_eq!(rates_only.sparsity.friction_coupling.len(), 2);
        let normal = builder.len();
        for r in 0..3 {
            let law = if r == 0 {
                RowLaw::Unilateral
            } else {
                RowLaw::Friction { contact: builder.contact_count() }
            };
            let (_, mut row) = builder.push_row(law, 0.0, 0.0, RowOrigin::Other);
            fill_path(&model, last, 1.0, &mut rng, &mut row);
        }
        builder.push_contact_block(ContactBlock { normal, mu: 0.5, mu2: 0.5 });
        let problem = assemble_against_dense(&builder, &model, &data, &m, &mut rng);
        assert!(problem.sparsity.friction_coupling.is_empty());
        // The rows' entries are the point rates' along each direction (both sides summed).
        for i in [0, 1, 2, 4, 5, 6] {
            let mut expected = vec![0.0; nv];
            let RowForm::Rates(RateRow { sides, direction }) = builder.forms[i] else { unreachable!() };
            for (start, end) in sides {
                for (c, u) in &builder.rates[start..end] {
                    expected[*c] += direction.dot(u);
                }
            }
            for (k, expected) in expected.iter().enumerate() {
                assert_eq!(problem.jacobian[(i, k)], *expected, "row {i}, dof {k}");
            }
        }
        // The rows given by rates store only their paths' (or the union's) entries of W.
        let stored: usize =
            (0..3).map(|i| problem.sparsity.row_spans(i).map(|(_, w)| w.len()).sum::<usize>()).sum();
        let union = (0..nv).filter(|&k| problem.jacobian.row(0)[k] != 0.0).count();
        assert!(stored <= 3 * union, "{stored} entries stored for 3 rows on {union} dofs");
    }

    #[test]
    fn recorded_rows_are_the_same_within_the_tolerance_only_and_keep_w_with_a_new_bias() {
        let (model, data, _, mut rng) = factored_ragdoll(5);
        let nv = model.nv();
        let last = model.nbodies() - 1;
        let mut base = ProblemBuilder::new(nv, FrictionModel::Cone);
        let side = random_rates(&mut base, &model, last, NO_DOF, &mut rng);
        let directions = [Vec3::z(), Vec3::x(), Vec3::y()];
        base.push_point_contact([side, (side.1, side.1)], directions, 1e-6, RowOrigin::Other, 0.5, 0.5);
        let first = last_dof_of(&model, last / 2);
        base.push_joint_row(RowLaw::Unilateral, 0.1, 0.0, RowOrigin::Other, first, &[1.0]);
        let mut recorded = BuiltRows::default();
        assert!(!recorded.same_rows(&base, 1e-8, None), "nothing recorded yet");
        recorded.record(&base);
        assert!(recorded.same_rows(&base, 1e-8, None));
        // A point rate moved by half the tolerance is the same row; by twice it, not.
        let mut moved = base.clone();
        let scale = moved.rates[0].1.x.abs().max(1.0);
        moved.rates[0].1.x += 0.5e-8 * scale;
        assert!(recorded.same_rows(&moved, 1e-8, None));
        moved.rates[0].1.x += 2e-8 * scale;
        assert!(!recorded.same_rows(&moved, 1e-8, None));
        // A turned direction, another joint coefficient, another law: not the same rows.
        let mut turned = base.clone();
        let RowForm::Rates(row) = &mut turned.forms[1] else { unreachable!() };
        row.direction.y += 1e-6;
        assert!(!recorded.same_rows(&turned, 1e-8, None));
        let mut scaled = base.clone();
        let RowForm::Joint { coefficients, .. } = &mut scaled.forms[3] else { unreachable!() };
        coefficients[0] = 1.0 + 1e-6;
        assert!(!recorded.same_rows(&scaled, 1e-8, None));
        let mut other_law = base.clone();
        other_law.laws[3] = RowLaw::Bilateral;
        assert!(!recorded.same_rows(&other_law, 1e-8, None));
        recorded.forget();
        assert!(!recorded.same_rows(&base, 1e-8, None));
        // The kept problem with a new free velocity and target: the bias of a new build.
        let factor = TreeFactor::new(&model, &data);
        let v_free = DVector::from_fn(nv, |_, _| rng.random_range(-1.0..1.0));
        let mut kept = ConstraintProblem::default();
        base.build_into(&DVector::zeros(nv), factor, &mut kept);
        base.set_target(3, -0.25);
        base.refresh_bias(&v_free, &mut kept);
        let mut fresh = ConstraintProblem::default();
        base.build_into(&v_free, factor, &mut fresh);
        for i in 0..base.len() {
            let (a, b) = (kept.bias[i], fresh.bias[i]);
            assert!((a - b).abs() <= 1e-14, "row {i}: {a} against {b}");
        }
        assert_eq!(kept.target, fresh.target);
        assert_eq!(kept.regularization, fresh.regularization);
        assert_eq!(kept.delassus, fresh.delassus);
    }

    #[test]
    #[cfg(debug_assertions)]
    #[should_panic(expected = "not one body's path to the root")]
    fn point_rates_that_skip_a_dof_of_the_path_are_refused() {
        let (model, data, _, mut rng) = factored_ragdoll(4);
        let mut builder = ProblemBuilder::new(model.nv(), FrictionModel::Cone);
        let side = random_rates(&mut builder, &model, model.nbodies() - 1, NO_DOF, &mut rng);
        builder.rates_mut().remove(side.0 + 1);
        let side = (side.0, side.1 - 1);
        builder.push_point_contact([side, (side.1, side.1)], [Vec3::z(); 3], 0.0, RowOrigin::Other, 0.5, 0.5);
        let v_free = DVector::zeros(model.nv());
        assemble_single(&builder, &model, &data, &v_free, &mut ConstraintProblem::default());
    }

    #[test]
    fn joint_rows_give_the_delassus_matrix_and_bias_of_a_dense_solve() {
        let (model, data, m, mut rng) = factored_ragdoll(5);
        let nv = model.nv();
        let mut builder = ProblemBuilder::new(nv, FrictionModel::Cone);
        // Rows on the dofs of one joint given compactly (a ball joint's three friction rows,
        // limits on combinations of its dofs, a root dof's row) and the same as stored rows,
        // a row on two limbs' dofs, unit rows on one chain and a unit row on a root dof; J v_free
        // is formed with the rows (the bias).
        let deepest = last_dof_of(&model, model.nbodies() - 1);
        let other_limb = last_dof_of(&model, model.nbodies() / 2);
        let unit = |builder: &mut ProblemBuilder, entries: &[(usize, f64)]| {
            let (_, mut row) =
                builder.push_row(RowLaw::Bounded { lo: -1.0, hi: 1.0 }, 0.0, 0.0, RowOrigin::Other);
            for &(k, value) in entries {
                row[k] = value;
            }
        };
        let joint = deepest - 2;
        let law = RowLaw::Bounded { lo: -1.0, hi: 1.0 };
        for k in joint..=deepest {
            builder.push_joint_row(law, 0.0, 0.0, RowOrigin::Other, k, &[1.0]);
        }
        builder.push_joint_row(law, 0.0, 0.0, RowOrigin::Other, joint, &[0.6, -0.8]);
        builder.push_joint_row(law, 0.0, 0.0, RowOrigin::Other, joint, &[0.6, 0.0, -0.8]);
        builder.push_joint_row(law, 0.0, 0.0, RowOrigin::Other, 0, &[1.0]);
        // Two consecutive columns that are not parent and child (another limb's first dof).
        let unchained = (1..nv).find(|&k| model.dof_parent[k] != k - 1).unwrap();
        builder.push_joint_row(law, 0.0, 0.0, RowOrigin::Other, unchained - 1, &[0.5, 1.0]);
        unit(&mut builder, &[(joint, 0.6), (joint + 1, -0.8)]);
        unit(&mut builder, &[(deepest, 1.0), (other_limb, 0.5)]);
        let chain: Vec<usize> =
            model.dof_path[model.dof_path_start[deepest]..model.dof_path_start[deepest + 1]].to_vec();
        for &k in chain.iter().rev().take(5) {
            unit(&mut builder, &[(k, rng.random_range(-1.0..1.0))]);
        }
        unit(&mut builder, &[(0, 1.0)]);
        let problem = assemble_against_dense(&builder, &model, &data, &m, &mut rng);
        // The compact joint rows' Jacobian rows are their coefficients at their columns.
        let expected: [&[(usize, f64)]; 7] = [
            &[(joint, 1.0)],
            &[(joint + 1, 1.0)],
            &[(joint + 2, 1.0)],
            &[(joint, 0.6), (joint + 1, -0.8)],
            &[(joint, 0.6), (joint + 2, -0.8)],
            &[(0, 1.0)],
            &[(unchained - 1, 0.5), (unchained, 1.0)],
        ];
        for (i, entries) in expected.iter().enumerate() {
            let mut row = vec![0.0; nv];
            for &(k, x) in entries.iter() {
                row[k] = x;
            }
            assert_eq!(problem.jacobian.row(i).iter().copied().collect::<Vec<_>>(), row, "row {i}");
            assert_eq!(builder.row(i), row, "row {i}");
        }
        for i in 0..builder.len() {
            // W's rows are the dense solve's M⁻¹Jᵀ mapped back (their spans too).
            let dense = problem.minv_jt.column(i);
            let mut row = vec![0.0; nv];
            for (col, w) in problem.sparsity.row_spans(i) {
                row[col..col + w.len()].copy_from_slice(w);
            }
            let factor = TreeFactor::new(&model, &data);
            factor.unscale_solve(0, &mut row);
            for k in 0..nv {
                assert!((row[k] - dense[k]).abs() < 1e-12 * dense.amax().max(1.0), "row {i}, dof {k}");
            }
        }
    }
}
