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
//! are computed from it by one function ([`crate::solvers::residuals`]), and it can be written to
//! files for QP-solver regression tests.

mod assemble;
mod contact;
mod joints;
mod loops;

pub use assemble::{assemble_single, ProblemBuilder};
pub use contact::{add_contact_rows, add_contact_rows_with, ContactParameters};
pub use joints::{add_joint_friction_rows, add_joint_limit_rows, add_motor_row, JointLimitParameters};
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

/// How friction bounds the tangential impulse of a contact.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrictionModel {
    /// The exact Coulomb cone `(λ₁/μ)² + (λ₂/μ₂)² ≤ λ_n²`.
    Cone,
    /// The inscribed pyramid: the convex hull of `λ_n (μ cos θ_j, μ₂ sin θ_j)`, `θ_j = 2πj/k`,
    /// `k = facets ≥ 3`. Lemke always solves this form.
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

/// What created a row, for diagnostics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowOrigin {
    /// Normal or friction row of a contact (index into the collision contacts).
    Contact(usize),
    /// Lower position limit of a dof.
    LowerLimit(usize),
    /// Upper position limit of a dof.
    UpperLimit(usize),
    /// Swing-cone limit of the ball joint whose first dof is this.
    SwingLimit(usize),
    /// Lower twist limit of the ball joint whose first dof is this.
    TwistLowerLimit(usize),
    /// Upper twist limit of the ball joint whose first dof is this.
    TwistUpperLimit(usize),
    /// Velocity motor of a dof.
    Motor(usize),
    /// Coulomb friction of a dof.
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
    /// Delassus matrix A = J M⁻¹ Jᵀ (rows × rows, symmetric positive semi-definite).
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
    /// Which velocity blocks (multibodies) each row touches, when the problem was assembled from
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
    /// For each (row, touched block) entry of `blocks_of_row`, the offset of its segments in
    /// `j_values` and `x_values`.
    pub segment_start: Vec<usize>,
    /// J's entries of each (row, block) segment, contiguous.
    pub j_values: Vec<f64>,
    /// M⁻¹Jᵀ's entries of each (row, block) segment, contiguous.
    pub x_values: Vec<f64>,
    /// Rows touching each block: `rows_of_block[block_start[b]..block_start[b + 1]]`.
    pub rows_of_block: Vec<usize>,
    /// Offsets into `rows_of_block`, one per block plus one.
    pub block_start: Vec<usize>,
    /// For each entry of `rows_of_block`, the offset of that row's segment on that block.
    pub segment_of_block_row: Vec<usize>,
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
    /// The segments of row `i`: (first column, J entries, M⁻¹Jᵀ entries) per touched block.
    pub fn row_segments(&self, i: usize) -> impl Iterator<Item = (usize, &[f64], &[f64])> + '_ {
        (self.row_start[i]..self.row_start[i + 1]).map(move |e| {
            let (col, width) = self.blocks[self.blocks_of_row[e]];
            let start = self.segment_start[e];
            (col, &self.j_values[start..start + width], &self.x_values[start..start + width])
        })
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
        }
    }
}

impl ConstraintProblem {
    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.laws.len()
    }

    /// Row velocities `w = (A + R) λ + b` written into `w`.
    pub fn velocities(&self, lambda: &DVector<f64>, w: &mut DVector<f64>) {
        w.copy_from(&self.bias);
        w.gemv(1.0, &self.delassus, lambda, 1.0);
        for i in 0..w.len() {
            w[i] += self.regularization[i] * lambda[i];
        }
    }

    /// Adds the velocity change of impulses λ, `M⁻¹Jᵀλ`, to `v` (length nv): from the sparse
    /// segments when the problem has them, else from the dense `minv_jt`.
    pub fn apply_impulses(&self, lambda: &DVector<f64>, v: &mut DVector<f64>) {
        if self.sparsity.is_empty() {
            v.gemv(1.0, &self.minv_jt, lambda, 1.0);
            return;
        }
        let v = v.as_mut_slice();
        for (i, &l) in lambda.iter().enumerate() {
            if l != 0.0 {
                for (col, _, x) in self.sparsity.row_segments(i) {
                    for (vk, xk) in v[col..col + x.len()].iter_mut().zip(x) {
                        *vk += l * xk;
                    }
                }
            }
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
            laws,
            contacts,
            friction,
        }
    }
}
