//! W = J L⁻¹ D^{-1/2} row by row over the tree-sparse factor of M (never forming M⁻¹), its
//! sparsity (runs of non-zero entries per block), and the Delassus matrix `A = J M⁻¹ Jᵀ = W Wᵀ`
//! of a [`ProblemBuilder`]'s rows; the bias `b = J v_free − u*`.

use super::{ProblemBuilder, RateRow, RowForm, TreeFactor};
use crate::constraints::{ConstraintProblem, RowSparsity};
use crate::data::Data;
use crate::math::{dot, Vec3};
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

impl ProblemBuilder {
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
