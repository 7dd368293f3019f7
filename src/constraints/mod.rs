//! Constraints as one velocity-level complementarity problem per step (Stewart–Trinkle,
//! Anitescu–Potra). With the free velocity `v_free = v + h M⁻¹(τ − C v − g)` and constraint rows
//! `J`, impulses `λ` give `v⁺ = v_free + M⁻¹ Jᵀ λ`, and the row velocities are
//!
//! `w = (A + R) λ + b`,  `A = J M⁻¹ Jᵀ` (the Delassus matrix),  `b = J v_free − u*`,
//!
//! where `u*` is each row's target velocity (restitution, position stabilisation, motor speed)
//! and `R` a diagonal regularisation (constraint softness, ODE's CFM). Each row obeys a
//! [`RowLaw`]; contacts tie one normal and two friction rows into a [`ContactBlock`] whose
//! friction is an exact cone or a pyramid ([`FrictionModel`]).
//!
//! The [`ConstraintProblem`] is plain data: every solver reads the same struct, the residuals
//! are computed from it by one function ([`crate::solvers::residuals()`]), and it can be written to
//! files for QP-solver regression tests.

mod builder;
mod contact;
mod islands;
mod joints;
mod loops;

pub use builder::{assemble_single, ProblemBuilder, RowMut, TreeFactor};
pub(crate) use builder::{BuiltRows, RowsMark};
pub use contact::{add_contact_rows, add_contact_rows_with, ContactParameters, Speculation};
pub use islands::IslandPartition;
pub use joints::{
    add_joint_friction_rows, add_joint_limit_rows, add_joint_limit_rows_speculative, add_motor_row,
    DroppedLimit, JointLimitParameters, LimitVelocities,
};
pub use loops::{
    add_loop_closure_rows, add_loop_closure_rows_between, loop_closure_drift_between, loop_error,
    loop_error_between, LoopClosure, LoopKind, LoopSide,
};

use nalgebra::{DMatrix, DVector};

/// The law a row's impulse `λ_i` and velocity `w_i` obey.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RowLaw {
    /// Equality (loop closures): `w_i = 0`, `λ_i` free.
    Bilateral,
    /// Signorini (contact normals, joint limits): `λ_i ≥ 0`, `w_i ≥ 0`, `λ_i w_i = 0`.
    Unilateral,
    /// Box (motors, joint friction): `lo ≤ λ_i ≤ hi`; `w_i = 0` strictly inside, `w_i ≥ 0` at
    /// `lo`, `w_i ≤ 0` at `hi` (N·s).
    Bounded {
        /// Lower bound (N·s, may be −∞).
        lo: f64,
        /// Upper bound (N·s, may be +∞).
        hi: f64,
    },
    /// A friction row of contact block `contact` (its bound depends on the normal impulse).
    Friction {
        /// Index into [`ConstraintProblem::contacts`].
        contact: usize,
    },
}

/// Most facets a friction pyramid may have ([`FrictionModel::Pyramid`]): each contact's LCP has
/// one variable per facet, and beyond a few dozen the cone itself is both exact and cheaper.
pub const MAX_PYRAMID_FACETS: usize = 64;

/// How friction bounds the tangential impulse of a contact.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrictionModel {
    /// The exact Coulomb cone `(λ₁/μ)² + (λ₂/μ₂)² ≤ λ_n²`.
    Cone,
    /// The inscribed pyramid: the convex hull of `λ_n (μ cos θ_j, μ₂ sin θ_j)`, `θ_j = 2πj/k`,
    /// `3 ≤ k = facets ≤` [`MAX_PYRAMID_FACETS`]. Lemke always solves this form.
    Pyramid {
        /// Number of facets (directions) k.
        facets: usize,
    },
}

/// One contact's rows: normal at `normal`, tangents at `normal + 1` and `normal + 2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactBlock {
    /// Row index of the normal.
    pub normal: usize,
    /// Friction coefficient along the first tangent.
    pub mu: f64,
    /// Friction coefficient along the second tangent (= `mu` when isotropic).
    pub mu2: f64,
}

impl ContactBlock {
    /// Row indices (normal, tangent 1, tangent 2).
    pub fn rows(&self) -> (usize, usize, usize) {
        (self.normal, self.normal + 1, self.normal + 2)
    }
}

/// What created a row, for diagnostics and for matching rows across steps (warm starts). A dof
/// is named by its column in the problem's velocities: its index in its multibody's v plus the
/// multibody's column offset (the same in a one-multibody problem), so that two multibodies'
/// rows never share an origin.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RowOrigin {
    /// Normal or friction row of a contact (index into the collision contacts).
    Contact(usize),
    /// Lower position limit of the dof of this column.
    LowerLimit(usize),
    /// Upper position limit of the dof of this column.
    UpperLimit(usize),
    /// Swing-cone limit of the ball joint whose first dof has this column.
    SwingLimit(usize),
    /// Lower twist limit of the ball joint whose first dof has this column.
    TwistLowerLimit(usize),
    /// Upper twist limit of the ball joint whose first dof has this column.
    TwistUpperLimit(usize),
    /// Total-angle limit of the ball joint whose first dof has this column.
    AngleLimit(usize),
    /// Velocity motor of the dof of this column.
    Motor(usize),
    /// Coulomb friction of the dof of this column.
    JointFriction(usize),
    /// Loop-closure joint (index given by the caller).
    Loop(usize),
    /// Anything else.
    Other,
}

/// A velocity-level constraint problem: `w = (A + R) λ + b` with the laws of each row.
#[derive(Clone, Debug, PartialEq)]
pub struct ConstraintProblem {
    /// Constraint Jacobian J (rows × nv).
    pub jacobian: DMatrix<f64>,
    /// M⁻¹ Jᵀ (nv × rows): the velocity change per unit impulse of each row.
    pub minv_jt: DMatrix<f64>,
    /// Delassus matrix A = J M⁻¹ Jᵀ (rows × rows, symmetric positive semi-definite), or empty
    /// (0 × 0) when the problem is matrix-free ([`Self::is_matrix_free`]): then `sparsity` holds
    /// W with A = W Wᵀ, and [`Self::delassus_entry`], [`Self::delassus_dense`] and
    /// [`Self::velocities`] work from it. The stepping path leaves A unformed when its n²
    /// entries would cost more than W's (many rows on small bodies: stacks, piles).
    pub delassus: DMatrix<f64>,
    /// Diagonal regularisation R (m/s per N·s), from constraint softness.
    pub regularization: DVector<f64>,
    /// b = J v_free − u* (m/s or rad/s).
    pub bias: DVector<f64>,
    /// Target velocities u* of each row (kept for diagnostics and export).
    pub target: DVector<f64>,
    /// Law of each row.
    pub laws: Vec<RowLaw>,
    /// Contact blocks.
    pub contacts: Vec<ContactBlock>,
    /// Friction model of every contact block.
    pub friction: FrictionModel,
    /// Origin of each row.
    pub origins: Vec<RowOrigin>,
    /// Wᵀλ of the matrix-free product in [`Self::velocities`] (nv entries, reused).
    pub(crate) scratch: Scratch,
    /// A contact's three Jacobian rows as lanes during assembly (reused).
    pub(crate) lanes: Scratch<[f64; 4]>,
    /// The dofs of a contact's two paths during assembly (reused).
    pub(crate) pattern: Scratch<usize>,
    /// A contact's runs of consecutive columns during assembly (reused).
    pub(crate) stretches: Scratch<(usize, usize, usize)>,
    /// Impulses λ a solver left with the Wᵀλ it kept for them ([`Self::keep_impulse_sum`]):
    /// [`Self::apply_impulses`] with the same λ starts from that sum.
    pub(crate) kept_lambda: Scratch,
    pub(crate) kept_sum: Scratch,
    /// Which velocity blocks (multibodies or their root subtrees) each row touches, when the problem was assembled from
    /// blocks: lets iterative solvers work in velocity space with sparse rows. Empty otherwise.
    pub sparsity: RowSparsity,
}

/// Velocity blocks (one per multibody: first column and width) and, per row, the blocks its
/// Jacobian row touches (`blocks_of_row[row_start[i]..row_start[i + 1]]`). M⁻¹ is block
/// diagonal, so row i's column of M⁻¹Jᵀ is non-zero only on those blocks too.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RowSparsity {
    /// Number of velocity coordinates (all blocks).
    pub nv: usize,
    /// (first column, width) of each block.
    pub blocks: Vec<(usize, usize)>,
    /// Offsets into `blocks_of_row`, one per row plus one.
    pub row_start: Vec<usize>,
    /// Block indices touched by each row, concatenated.
    pub blocks_of_row: Vec<usize>,
    /// For each (row, touched block) entry of `blocks_of_row`, where its runs start in `runs`
    /// (one per entry plus one: entry e's runs are `runs[entry_run_start[e]..entry_run_start[e + 1]]`).
    pub entry_run_start: Vec<usize>,
    /// W = J L⁻¹ D^{-1/2}'s entries (M = Lᵀ D L, A = W Wᵀ), run after run (see `runs`).
    pub w_values: Vec<f64>,
    /// Rows touching each block: `rows_of_block[block_start[b]..block_start[b + 1]]`. This
    /// per-block index (with the two fields after it) is filled only when A is formed; a
    /// matrix-free problem leaves `block_start` empty.
    pub rows_of_block: Vec<usize>,
    /// Offsets into `rows_of_block`, one per block plus one.
    pub block_start: Vec<usize>,
    /// For each entry of `rows_of_block`, that row's entry (index into `blocks_of_row`) on
    /// that block.
    pub entry_of_block_row: Vec<usize>,
    /// ‖W_i‖² = A_ii per row (1/kg or 1/(kg·m²)), the diagonal every solver and the residuals
    /// need; empty when the problem was not built from segments.
    pub row_norm2: Vec<f64>,
    /// A_{t1 t2} per contact, in contact order: the coupling of its two friction rows
    /// (1/kg or 1/(kg·m²)), formed with their rows of W when every contact was given by point
    /// rates; empty otherwise (then [`ConstraintProblem::friction_coupling`] forms it from W).
    pub friction_coupling: Vec<f64>,
    /// Runs of W's rows, outside which W is zero (a run may hold a few zeros): (first column in
    /// the stacked velocities, offset in `w_values`, length), in increasing columns within each
    /// (row, block) entry. A row of W is
    /// non-zero only on its bodies' paths to the root, which in a branched tree (a ragdoll's
    /// foot: pelvis, hip, knee, ankle) is a few runs of a much wider span; only the runs'
    /// entries are stored. Row i's runs are `runs[run_start[i]..run_start[i + 1]]`.
    pub runs: Vec<(usize, usize, usize)>,
    /// Offsets into `runs`, one per row plus one.
    pub run_start: Vec<usize>,
}

impl RowSparsity {
    /// Whether the structure is present.
    pub fn is_empty(&self) -> bool {
        self.row_start.is_empty()
    }
    /// Blocks touched by row `i`.
    pub fn row_blocks(&self, i: usize) -> &[usize] {
        &self.blocks_of_row[self.row_start[i]..self.row_start[i + 1]]
    }
    /// The runs of (row, block) entry `e` of `blocks_of_row`.
    pub fn entry_runs(&self, e: usize) -> &[(usize, usize, usize)] {
        &self.runs[self.entry_run_start[e]..self.entry_run_start[e + 1]]
    }
    /// Appends row `i` of `source` as this structure's next row: its (row, block) entries with
    /// the blocks renumbered by `local_block` (a block of `source` → its block here) and its
    /// runs' columns moved from the source block's first column to that block's. The blocks
    /// must be in place; the row's `row_norm2` is the caller's to push.
    pub fn push_row_from(&mut self, source: &RowSparsity, i: usize, local_block: &[usize]) {
        for e in source.row_start[i]..source.row_start[i + 1] {
            let b = source.blocks_of_row[e];
            let lb = local_block[b];
            let (from, to) = (source.blocks[b].0, self.blocks[lb].0);
            self.blocks_of_row.push(lb);
            for &(col, start, len) in source.entry_runs(e) {
                self.runs.push((col - from + to, self.w_values.len(), len));
                self.w_values.extend_from_slice(&source.w_values[start..start + len]);
            }
            self.entry_run_start.push(self.runs.len());
        }
        self.row_start.push(self.blocks_of_row.len());
        self.run_start.push(self.runs.len());
    }
    /// The non-zero runs of row `i` of W: (first column in the stacked velocities, W's entries
    /// from there). Outside them row i of W is zero, so (A λ)_i = Σ W_i · (Wᵀλ) over them.
    pub fn row_spans(&self, i: usize) -> impl Iterator<Item = (usize, &[f64])> + '_ {
        self.runs[self.run_start[i]..self.run_start[i + 1]]
            .iter()
            .map(move |&(col, start, len)| (col, &self.w_values[start..start + len]))
    }
}

impl Default for ConstraintProblem {
    fn default() -> Self {
        Self {
            jacobian: DMatrix::zeros(0, 0),
            minv_jt: DMatrix::zeros(0, 0),
            delassus: DMatrix::zeros(0, 0),
            regularization: DVector::zeros(0),
            bias: DVector::zeros(0),
            target: DVector::zeros(0),
            laws: Vec::new(),
            contacts: Vec::new(),
            friction: FrictionModel::Cone,
            origins: Vec::new(),
            sparsity: RowSparsity::default(),
            scratch: Scratch::default(),
            kept_lambda: Scratch::default(),
            kept_sum: Scratch::default(),
            lanes: Scratch::default(),
            pattern: Scratch::default(),
            stretches: Scratch::default(),
        }
    }
}

/// Reused scratch space inside a [`ConstraintProblem`]: not part of the problem's value (equal
/// to every other, cloned empty).
#[derive(Debug)]
pub(crate) struct Scratch<T = f64>(std::cell::RefCell<Vec<T>>);

impl<T> Default for Scratch<T> {
    fn default() -> Self {
        Self(std::cell::RefCell::new(Vec::new()))
    }
}

impl<T> Clone for Scratch<T> {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl<T> PartialEq for Scratch<T> {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl ConstraintProblem {
    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.laws.len()
    }

    /// Makes this problem one of `n` rows to be filled in place (a sub-problem gathered from
    /// another): bias, regularization and target sized n, J and M⁻¹Jᵀ sized for no columns,
    /// laws, origins and contacts emptied; buffers of the right size are kept, so that a
    /// sub-problem rebuilt each step does not allocate.
    pub(crate) fn reset_rows(&mut self, n: usize) {
        if self.bias.len() != n {
            self.bias = DVector::zeros(n);
            self.regularization = DVector::zeros(n);
            self.target = DVector::zeros(n);
        }
        if self.jacobian.shape() != (n, 0) {
            self.jacobian = DMatrix::zeros(n, 0);
            self.minv_jt = DMatrix::zeros(0, n);
        }
        self.laws.clear();
        self.origins.clear();
        self.contacts.clear();
    }

    /// Whether A is left unformed (see [`Self::delassus`]).
    pub fn is_matrix_free(&self) -> bool {
        self.delassus.nrows() != self.rows() && !self.sparsity.is_empty()
    }

    /// A's diagonal A_ii = ‖W_i‖² as assembly kept it (matrix-free problems), else `None`
    /// (then [`Self::delassus_entry`] per row).
    pub(crate) fn kept_diagonal(&self) -> Option<&[f64]> {
        let norms = &self.sparsity.row_norm2;
        (self.is_matrix_free() && norms.len() == self.rows()).then_some(&norms[..])
    }

    /// A_ij, from the dense A or, matrix-free, as W_i · W_j over the blocks both rows touch.
    pub fn delassus_entry(&self, i: usize, j: usize) -> f64 {
        if !self.is_matrix_free() {
            return self.delassus[(i, j)];
        }
        let sp = &self.sparsity;
        if i == j && sp.row_norm2.len() == self.rows() {
            return sp.row_norm2[i];
        }
        let mut a = 0.0;
        for ei in sp.row_start[i]..sp.row_start[i + 1] {
            for ej in sp.row_start[j]..sp.row_start[j + 1] {
                if sp.blocks_of_row[ei] == sp.blocks_of_row[ej] {
                    a += builder::runs_dot(sp, sp.entry_runs(ei), sp.entry_runs(ej));
                }
            }
        }
        a
    }

    /// A_{t1 t2} of contact `contact`'s two friction rows: kept from assembly, or
    /// [`ConstraintProblem::delassus_entry`].
    pub fn friction_coupling(&self, contact: usize) -> f64 {
        match self.sparsity.friction_coupling.get(contact) {
            Some(&a) if self.sparsity.friction_coupling.len() == self.contacts.len() => a,
            _ => {
                let (_, t1, t2) = self.contacts[contact].rows();
                self.delassus_entry(t1, t2)
            }
        }
    }

    /// The dense A: borrowed, or formed from W when the problem is matrix-free (for the
    /// pivoting and interior-point solvers, which need every entry).
    pub fn delassus_dense(&self) -> std::borrow::Cow<'_, DMatrix<f64>> {
        if !self.is_matrix_free() {
            return std::borrow::Cow::Borrowed(&self.delassus);
        }
        let mut a = DMatrix::zeros(self.rows(), self.rows());
        // The stepping path leaves the per-block index out when A is not formed.
        let mut sparsity = self.sparsity.clone();
        builder::index_rows_by_block(&mut sparsity);
        builder::delassus_from_w(&sparsity, &mut a);
        std::borrow::Cow::Owned(a)
    }

    /// Row velocities `w = (A + R) λ + b` written into `w` (matrix-free: W (Wᵀλ) + R λ + b).
    pub fn velocities(&self, lambda: &DVector<f64>, w: &mut DVector<f64>) {
        self.velocities_with_sum(lambda, w, &mut self.scratch.0.borrow_mut());
    }

    /// [`Self::velocities`], leaving Wᵀλ (length nv) in `s` when the problem is matrix-free
    /// (true then; false, `s` untouched, when A is formed): a solver that keeps Wᵀλ takes it
    /// from there instead of forming it again.
    pub(crate) fn velocities_with_sum(
        &self,
        lambda: &DVector<f64>,
        w: &mut DVector<f64>,
        s: &mut Vec<f64>,
    ) -> bool {
        w.copy_from(&self.bias);
        let matrix_free = self.is_matrix_free();
        if matrix_free {
            let sp = &self.sparsity;
            s.clear();
            s.resize(sp.nv, 0.0);
            for (i, &l) in lambda.iter().enumerate() {
                if l != 0.0 {
                    for (col, wi) in sp.row_spans(i) {
                        for (s, wi) in s[col..col + wi.len()].iter_mut().zip(wi) {
                            *s += l * wi;
                        }
                    }
                }
            }
            for i in 0..w.len() {
                w[i] += sp
                    .row_spans(i)
                    .map(|(col, wi)| crate::math::dot(wi, &s[col..col + wi.len()]))
                    .sum::<f64>();
            }
        } else {
            w.gemv(1.0, &self.delassus, lambda, 1.0);
        }
        for i in 0..w.len() {
            w[i] += self.regularization[i] * lambda[i];
        }
        matrix_free
    }

    /// Adds the velocity change of impulses λ, `M⁻¹Jᵀλ`, to `v` (length nv): from the dense
    /// `minv_jt` when the problem has it, else as L⁻¹ D^{-1/2} (Wᵀλ) block by block with the
    /// factors `factor_of` gives (as for [`ProblemBuilder::build_into_blocks`]); `scratch` is
    /// resized to nv. Blocks without a factor do not move.
    pub fn apply_impulses<'f>(
        &self,
        lambda: &DVector<f64>,
        v: &mut DVector<f64>,
        scratch: &mut Vec<f64>,
        factor_of: impl Fn(usize) -> Option<(TreeFactor<'f>, usize)>,
    ) {
        if self.sparsity.is_empty() || self.minv_jt.shape() == (v.len(), lambda.len()) {
            v.gemv(1.0, &self.minv_jt, lambda, 1.0);
            return;
        }
        let sp = &self.sparsity;
        scratch.clear();
        let kept = self.kept_sum.0.borrow();
        if kept.len() == sp.nv && *self.kept_lambda.0.borrow() == lambda.as_slice() {
            scratch.extend_from_slice(&kept);
        } else {
            scratch.resize(sp.nv, 0.0);
            for (i, &l) in lambda.iter().enumerate() {
                if l != 0.0 {
                    for (col, w) in sp.row_spans(i) {
                        for (s, w) in scratch[col..col + w.len()].iter_mut().zip(w) {
                            *s += l * w;
                        }
                    }
                }
            }
        }
        for (b, &(col, width)) in sp.blocks.iter().enumerate() {
            if let Some((factor, first_dof)) = factor_of(b) {
                let s = &mut scratch[col..col + width];
                factor.unscale_solve(first_dof, s);
                for (v, s) in v.as_mut_slice()[col..col + width].iter_mut().zip(s.iter()) {
                    *v += s;
                }
            }
        }
    }

    /// Writes into `sum` (nv entries) the Wᵀλ kept for exactly these impulses `lambda`
    /// ([`Self::keep_impulse_sum`]), if one is kept; false otherwise. A step whose W stands
    /// (see [`crate::world::WorldOptions::mass_matrix_reuse`]) and whose warm start is the last
    /// solve's λ starts its sweeps from it.
    pub(crate) fn kept_impulse_sum(&self, lambda: &[f64], sum: &mut [f64]) -> bool {
        let kept = self.kept_sum.0.borrow();
        let found = kept.len() == sum.len() && *self.kept_lambda.0.borrow() == lambda;
        if found {
            sum.copy_from_slice(&kept);
        }
        found
    }

    /// Records `sum` = Wᵀλ (nv entries) as kept by a solver for its impulses λ, so that
    /// [`Self::apply_impulses`] of the same λ skips forming it.
    pub(crate) fn keep_impulse_sum(&self, lambda: &[f64], sum: &[f64]) {
        let (mut l, mut s) = (self.kept_lambda.0.borrow_mut(), self.kept_sum.0.borrow_mut());
        l.clear();
        l.extend_from_slice(lambda);
        s.clear();
        s.extend_from_slice(sum);
    }

    /// Adds a compliance relative to each row's effective mass: `R_ii += relative · A_ii` for
    /// unilateral and bounded rows, and for a contact's two friction rows the normal's
    /// `relative · A_nn` (so that a contact's three rows are equally soft); bilateral rows
    /// (loop closures) stay as they are. See [`crate::world::WorldOptions::softness`].
    pub fn soften(&mut self, relative: f64) {
        for i in 0..self.rows() {
            self.regularization[i] += self.softening(i, relative);
        }
    }

    /// Centres the softening of [`Self::soften`] on the impulses `centre` (one per row, N·s):
    /// `b_i −= s A_ii · centre_i`, so that the rows are `(A + R) λ + b − S λ̄` with `S` the
    /// added compliance: the compliance then acts on the change of the impulse from `centre`
    /// (the elastic part of last step's impulses, [`Self::follow_elastic_impulses`]) and not on
    /// the impulse itself, and a row that carries the same impulse step after step (a body
    /// resting under a heap) holds it as a hard row would, without sinking by `S λ h / erp`.
    /// Rows without a softening are unchanged.
    pub fn center_softening(&mut self, relative: f64, centre: &DVector<f64>) {
        for i in 0..self.rows() {
            let s = self.softening(i, relative);
            self.bias[i] -= s * centre[i];
        }
    }

    /// Moves the centres of the softening (see [`Self::center_softening`]) to the elastic part
    /// of the impulses `lambda` just solved for: `centre ← (1 − β) λ + β centre` with
    /// `β = damping`, and 0 for a contact whose normal impulse is 0 or a unilateral row at 0
    /// (a spring that has let go holds no load).
    ///
    /// Each softened row is then a spring and a damper side by side (Kelvin–Voigt) over the
    /// step: of its compliance `S`, the share `β` is the damper's (`S = 1/(h²K + hB)`,
    /// `β = hB·S`) and the rest the spring's, whose impulse is the centre. With `β = 0` the
    /// rows are undamped springs: a body lying on several soft rows, whose slowest modes the
    /// step's implicit solve barely damps, keeps rocking on them and never comes to rest. With
    /// `β = 1` they are dampers alone (the softening is not centred and a loaded row sinks).
    pub fn follow_elastic_impulses(&self, damping: f64, lambda: &DVector<f64>, centre: &mut DVector<f64>) {
        for i in 0..self.rows() {
            let released = match self.laws[i] {
                RowLaw::Unilateral => lambda[i] == 0.0,
                RowLaw::Friction { contact } => lambda[self.contacts[contact].normal] == 0.0,
                RowLaw::Bilateral | RowLaw::Bounded { .. } => false,
            };
            centre[i] = if released { 0.0 } else { (1.0 - damping) * lambda[i] + damping * centre[i] };
        }
    }

    /// The compliance [`Self::soften`] adds to row `i`.
    fn softening(&self, i: usize, relative: f64) -> f64 {
        match self.laws[i] {
            RowLaw::Bilateral => 0.0,
            RowLaw::Friction { contact } => relative * self.diagonal_of_row(self.contacts[contact].normal),
            RowLaw::Unilateral | RowLaw::Bounded { .. } => relative * self.diagonal_of_row(i),
        }
    }

    /// A_ii as kept by assembly, or from A or W.
    fn diagonal_of_row(&self, i: usize) -> f64 {
        match self.kept_diagonal() {
            Some(a) => a[i],
            None => self.delassus_entry(i, i),
        }
    }

    /// A problem given directly by its matrix and vectors (no Jacobian): for tests, imported
    /// problems and solver benchmarks. `jacobian` and `minv_jt` are left empty.
    pub fn from_parts(
        delassus: DMatrix<f64>,
        bias: DVector<f64>,
        laws: Vec<RowLaw>,
        contacts: Vec<ContactBlock>,
        friction: FrictionModel,
    ) -> Self {
        let n = bias.len();
        Self {
            jacobian: DMatrix::zeros(n, 0),
            minv_jt: DMatrix::zeros(0, n),
            delassus,
            regularization: DVector::zeros(n),
            target: DVector::zeros(n),
            bias,
            origins: vec![RowOrigin::Other; laws.len()],
            sparsity: RowSparsity::default(),
            scratch: Scratch::default(),
            kept_lambda: Scratch::default(),
            kept_sum: Scratch::default(),
            lanes: Scratch::default(),
            pattern: Scratch::default(),
            stretches: Scratch::default(),
            laws,
            contacts,
            friction,
        }
    }
}
