//! Every buffer the algorithms write, sized once for a model.

use crate::math::{Force, Mat6, Motion, SpatialInertia, Transform, Vec3, Vec6};
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// Work space and results of the algorithms for one [`Model`]. [`Data::new`] allocates every
/// buffer; no algorithm allocates afterwards. Per-body vectors have `nbodies` entries (index 0 the
/// universe), per-dof vectors `nv`.
#[derive(Clone, Debug)]
pub struct Data {
    /// Pose of each body in its parent body's frame, `x_pb = placement · x_jc(q)`.
    pub x_pb: Vec<Transform>,
    /// Pose of each body in the world, `x_wb`.
    pub x_wb: Vec<Transform>,
    /// Spatial velocity of each body, in its own frame.
    pub v: Vec<Motion>,
    /// Spatial acceleration of each body, in its own frame (RNEA: including the fictitious
    /// upward acceleration −g that accounts for gravity).
    pub a: Vec<Motion>,
    /// Spatial force transmitted by each body's joint, in the body frame (RNEA).
    pub f: Vec<Force>,
    /// Bias acceleration `c = v × vJ + cJ` of each body (ABA), in world axes about the body's
    /// origin.
    pub c_j: Vec<Motion>,
    /// Motion subspace column of each dof, in its body's frame.
    pub s: Vec<Motion>,
    /// Column of each dof in world coordinates (about the world origin): the joint Jacobian.
    pub j_world: Vec<Motion>,
    /// Composite rigid-body inertia of each subtree, in world axes about the CRBA reference point
    /// (the first body's origin; see [`crate::algorithms::crba`]).
    pub ycrb: Vec<SpatialInertia>,
    /// Composite rigid-body inertia of each subtree, in the body's own frame (about its origin,
    /// in its axes), from [`crate::algorithms::mass_matrix`].
    pub ycrb_body: Vec<SpatialInertia>,
    /// [`crate::algorithms::mass_matrix`]'s forces `Iᶜ S_k`, one per dof k, as six rows of nv
    /// (force x, y, z then moment x, y, z): during its pass, the forces of a subtree's dofs in
    /// the frame of the body being visited.
    pub(crate) subtree_forces: Vec<f64>,
    /// Joint motion-subspace columns in world axes about the CRBA reference point (the first
    /// body's origin), one per velocity dof: [`crate::algorithms::crba`]'s working copy of
    /// `j_world`, kept near the bodies so that M does not lose digits far from the origin.
    /// [`crate::algorithms::aba`] uses it for the columns in world axes about each body's own
    /// origin.
    pub j_crba: Vec<Motion>,
    /// Articulated-body inertia, in world axes about the body's origin (ABA).
    pub ia: Vec<Mat6>,
    /// Articulated bias force, in world axes about the body's origin (ABA).
    pub pa: Vec<Force>,
    /// Spatial velocity of each body, in world axes about the body's origin (ABA).
    pub aba_v: Vec<Motion>,
    /// Spatial acceleration of each body including the fictitious upward −g, in world axes
    /// about the body's origin (ABA).
    pub aba_a: Vec<Motion>,
    /// `U = Iᴬ S` per dof, world axes about the body's origin (ABA).
    pub u: Vec<Vec6>,
    /// `D⁻¹ = (Sᵀ Iᴬ S)⁻¹` per body, top-left nv×nv block used (ABA).
    pub d_inv: Vec<Mat6>,
    /// `u = τ − Sᵀ pᴬ` per dof (ABA).
    pub u_bias: DVector<f64>,
    /// Joint forces from [`crate::algorithms::rnea`] (N·m or N).
    pub tau: DVector<f64>,
    /// Nonlinear effects `C(q, v) v + g(q)` from [`crate::algorithms::nonlinear_effects`].
    pub nle: DVector<f64>,
    /// Generalized gravity `g(q)` from [`crate::algorithms::generalized_gravity`].
    pub gravity_torque: DVector<f64>,
    /// Generalized acceleration from [`crate::algorithms::aba`] or
    /// [`crate::algorithms::forward_dynamics_crba`].
    pub ddq: DVector<f64>,
    /// Joint-space mass matrix `M(q)` (full, symmetric, nv × nv) from
    /// [`crate::algorithms::crba`] or [`crate::algorithms::mass_matrix`]. A world's multibodies
    /// start with it empty (0 × 0, [`Data::without_dense_mass_matrix`]): their steps factor M
    /// from its packed rows and never form it, and a 2500-dof crowd read from one MJCF file
    /// would otherwise carry 50 MB of zeros; the first call that writes it sizes it.
    pub mass_matrix: DMatrix<f64>,
    /// `1/√D_kk` per dof, from [`crate::algorithms::factor_mass_matrix`] with the factor (the
    /// row scaling of the constraint assembly needs it for every row).
    pub factor_inv_sqrt_d: DVector<f64>,
    /// Per dof k, whether L_kj ≠ 0 for some ancestor j of k (from
    /// [`crate::algorithms::factor_mass_matrix`]): rows of L that are zero off the diagonal (a
    /// free body whose origin is its centre of mass, on principal axes) are skipped by the
    /// constraint assembly's row scaling.
    pub factor_row_coupled: Vec<bool>,
    /// The factorization's working rows: per dof k, M's entries (then L's and D's) on k's
    /// ancestors, root first, and on k itself, packed one row after the other (see
    /// [`crate::algorithms::factor_mass_matrix`]).
    pub(crate) factor_packed: Vec<f64>,
    /// A 6×nv frame Jacobian, output of [`crate::algorithms::frame_jacobian`].
    pub jacobian: DMatrix<f64>,
    /// Centre of mass in the world (m).
    pub com: Vec3,
    /// Kinetic energy (J).
    pub kinetic_energy: f64,
    /// Potential energy in gravity, zero at the world origin (J).
    pub potential_energy: f64,
}

impl Data {
    /// Allocates every buffer for `model`.
    pub fn new(model: &Model) -> Self {
        Self::allocate(model, true)
    }

    /// Every buffer for `model` but the dense mass matrix, left empty (0 × 0) until an algorithm
    /// that writes it is called (a world's multibodies: their steps never form it).
    pub fn without_dense_mass_matrix(model: &Model) -> Self {
        Self::allocate(model, false)
    }

    fn allocate(model: &Model, dense_mass_matrix: bool) -> Self {
        let (n, nv) = (model.nbodies(), model.nv());
        let m_size = if dense_mass_matrix { nv } else { 0 };
        Self {
            x_pb: vec![Transform::identity(); n],
            x_wb: vec![Transform::identity(); n],
            v: vec![Motion::zero(); n],
            a: vec![Motion::zero(); n],
            f: vec![Force::zero(); n],
            c_j: vec![Motion::zero(); n],
            s: vec![Motion::zero(); nv],
            j_world: vec![Motion::zero(); nv],
            ycrb: vec![SpatialInertia::zero(); n],
            ycrb_body: vec![SpatialInertia::zero(); n],
            subtree_forces: vec![0.0; 6 * nv],
            j_crba: vec![Motion::zero(); nv],
            ia: vec![Mat6::zeros(); n],
            pa: vec![Force::zero(); n],
            aba_v: vec![Motion::zero(); n],
            aba_a: vec![Motion::zero(); n],
            u: vec![Vec6::zeros(); nv],
            d_inv: vec![Mat6::zeros(); n],
            u_bias: DVector::zeros(nv),
            tau: DVector::zeros(nv),
            nle: DVector::zeros(nv),
            gravity_torque: DVector::zeros(nv),
            ddq: DVector::zeros(nv),
            mass_matrix: DMatrix::zeros(m_size, m_size),
            factor_inv_sqrt_d: DVector::zeros(nv),
            factor_row_coupled: vec![true; nv],
            factor_packed: vec![0.0; model.dof_path.len() + nv],
            jacobian: DMatrix::zeros(6, nv),
            com: Vec3::zeros(),
            kinetic_energy: 0.0,
            potential_energy: 0.0,
        }
    }

    /// `mass_matrix` sized nv × nv for `model` (zeros when it was not yet), for the algorithms
    /// that write or read the dense M.
    pub(crate) fn sized_mass_matrix(&mut self, model: &Model) -> &mut DMatrix<f64> {
        let nv = model.nv();
        if self.mass_matrix.shape() != (nv, nv) {
            self.mass_matrix = DMatrix::zeros(nv, nv);
        }
        &mut self.mass_matrix
    }
}
