//! The model: topology, joints, inertias and parameters of one kinematic tree; built once by
//! [`ModelBuilder`] and never changed while simulating.
//!
//! Body 0 is the universe (the world frame, named `universe`); bodies `1..nbodies` are the moving
//! bodies in depth-first order, each carried by exactly one non-fixed joint of the same index.
//! Fixed joints do not appear: the builder fuses a body attached by a fixed joint into its parent,
//! and its link and joint frames stay addressable as [`Frame`]s.

mod builder;
mod geometry;
pub mod joint;
pub mod ranges;
mod trees;

pub use builder::{BodySpec, InertiaIssue, JointDynamics, JointLimits, ModelBuilder, RigidInertia};
pub use geometry::{GeometryRole, GeometrySpec, Shape};
pub use joint::{swing_twist, BallLimits, Joint, Suspension, SwingTwist};

use crate::error::DynamicsError;
use crate::math::{SpatialInertia, Transform, Vec3};
use nalgebra::DVector;
use rand::Rng;

/// Marks "no parent degree of freedom" in [`Model::dof_parent`].
pub const NO_DOF: usize = usize::MAX;

/// Smallest norm of a ball or free joint's quaternion that [`Model::check_quaternions`] accepts.
pub const MIN_QUATERNION_NORM: f64 = 1e-9;

/// What a [`Frame`] was declared as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameKind {
    /// A body (URDF link) frame.
    Body,
    /// A joint frame (for a moving joint this is the child body's frame).
    Joint,
}

/// A named frame rigidly attached to a model body, such as a fused link or a fixed joint.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Name (link or joint name).
    pub name: String,
    /// What it was declared as.
    pub kind: FrameKind,
    /// Body it is attached to (0 = universe).
    pub body: usize,
    /// Pose of the frame in that body's frame.
    pub placement: Transform,
}

/// A kinematic tree of rigid bodies. Every per-body vector has [`Model::nbodies`] entries, index 0
/// being the universe.
#[derive(Clone, Debug)]
pub struct Model {
    pub(crate) name: String,
    pub(crate) nq: usize,
    pub(crate) nv: usize,
    pub(crate) body_names: Vec<String>,
    pub(crate) joint_names: Vec<String>,
    pub(crate) joints: Vec<Joint>,
    pub(crate) parents: Vec<usize>,
    pub(crate) children: Vec<Vec<usize>>,
    pub(crate) placements: Vec<Transform>,
    pub(crate) inertias: Vec<SpatialInertia>,
    pub(crate) idx_q: Vec<usize>,
    pub(crate) idx_v: Vec<usize>,
    pub(crate) dof_joint: Vec<usize>,
    pub(crate) dof_parent: Vec<usize>,
    /// Per dof k, the first dof s of the contiguous chain ending at k (the parent of each of
    /// s+1..=k is the dof before it): the ancestors of k are s..k and those of `dof_parent[s]`,
    /// so walks to the root run over contiguous stretches (a free joint's six dofs, a ball
    /// joint's three, a hinge chain numbered depth-first).
    pub(crate) dof_run_start: Vec<usize>,
    /// The ancestors of each dof, root first: dof k's are `dof_path[dof_path_start[k]..
    /// dof_path_start[k + 1]]`. An ancestor's path is a prefix of its descendants' (a path to the
    /// root is a chain), which the mass-matrix factorization's packed rows rely on.
    pub(crate) dof_path: Vec<usize>,
    /// Offsets into `dof_path`, one per dof plus one.
    pub(crate) dof_path_start: Vec<usize>,
    /// Per body i, one past the last dof of i's subtree: the subtree's dofs are
    /// `idx_v[i]..subtree_dof_end[i]` (bodies are numbered depth first, so they are contiguous).
    pub(crate) subtree_dof_end: Vec<usize>,
    pub(crate) lower_position_limit: DVector<f64>,
    pub(crate) upper_position_limit: DVector<f64>,
    pub(crate) velocity_limit: DVector<f64>,
    pub(crate) effort_limit: DVector<f64>,
    pub(crate) damping: DVector<f64>,
    pub(crate) friction: DVector<f64>,
    pub(crate) ball_limits: Vec<Option<BallLimits>>,
    pub(crate) frames: Vec<Frame>,
    pub(crate) geometries: Vec<GeometrySpec>,
    pub(crate) gravity: Vec3,
    pub(crate) source_dir: Option<std::path::PathBuf>,
}

impl Model {
    /// The model's name (URDF robot name).
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Directory of the file the model was loaded from (relative mesh URIs resolve against it).
    pub fn source_dir(&self) -> Option<&std::path::Path> {
        self.source_dir.as_deref()
    }
    /// Sets the directory that relative mesh URIs resolve against.
    pub fn set_source_dir(&mut self, dir: Option<std::path::PathBuf>) {
        self.source_dir = dir;
    }
    /// Number of configuration coordinates.
    pub fn nq(&self) -> usize {
        self.nq
    }
    /// Number of degrees of freedom.
    pub fn nv(&self) -> usize {
        self.nv
    }
    /// Number of bodies including the universe (so moving joints are `1..nbodies`).
    pub fn nbodies(&self) -> usize {
        self.joints.len()
    }
    /// Name of body `i` (0: `universe`).
    pub fn body_name(&self, i: usize) -> &str {
        &self.body_names[i]
    }
    /// Name of the joint carrying body `i`.
    pub fn joint_name(&self, i: usize) -> &str {
        &self.joint_names[i]
    }
    /// The joint carrying body `i` (`Joint::Fixed` for the universe).
    pub fn joint(&self, i: usize) -> &Joint {
        &self.joints[i]
    }
    /// Parent body of body `i` (the universe is its own parent).
    pub fn parent(&self, i: usize) -> usize {
        self.parents[i]
    }
    /// Child bodies of body `i`, in joint order.
    pub fn children(&self, i: usize) -> &[usize] {
        &self.children[i]
    }
    /// Pose of joint `i`'s frame in the parent body's frame.
    pub fn placement(&self, i: usize) -> &Transform {
        &self.placements[i]
    }
    /// Spatial inertia of body `i` in its own frame, fused fixed children included.
    pub fn inertia(&self, i: usize) -> &SpatialInertia {
        &self.inertias[i]
    }
    /// First index of joint `i` in q.
    pub fn idx_q(&self, i: usize) -> usize {
        self.idx_q[i]
    }
    /// First index of joint `i` in v.
    pub fn idx_v(&self, i: usize) -> usize {
        self.idx_v[i]
    }
    /// The body whose joint owns degree of freedom `k`.
    pub fn dof_joint(&self, k: usize) -> usize {
        self.dof_joint[k]
    }
    /// The previous degree of freedom on the path to the root ([`NO_DOF`] at the root): the
    /// sparsity pattern of the mass matrix (Featherstone's λ over dofs).
    pub fn dof_parent(&self, k: usize) -> usize {
        self.dof_parent[k]
    }
    /// Lower position limits (length nq; −∞ where none).
    pub fn lower_position_limit(&self) -> &DVector<f64> {
        &self.lower_position_limit
    }
    /// Upper position limits (length nq; +∞ where none).
    pub fn upper_position_limit(&self) -> &DVector<f64> {
        &self.upper_position_limit
    }
    /// Velocity limits (length nv; +∞ where none).
    pub fn velocity_limit(&self) -> &DVector<f64> {
        &self.velocity_limit
    }
    /// Effort limits, N or N·m (length nv; +∞ where none).
    pub fn effort_limit(&self) -> &DVector<f64> {
        &self.effort_limit
    }
    /// Viscous damping coefficients (length nv), URDF `<dynamics damping>`.
    pub fn damping(&self) -> &DVector<f64> {
        &self.damping
    }
    /// Coulomb friction levels (length nv), URDF `<dynamics friction>`.
    pub fn friction(&self) -> &DVector<f64> {
        &self.friction
    }
    /// Swing-cone and twist limits of the ball joint carrying body `i` (`None`: unlimited, or
    /// not a ball joint).
    pub fn ball_limits(&self, i: usize) -> Option<&BallLimits> {
        self.ball_limits.get(i).and_then(Option::as_ref)
    }
    /// Whether some ball joint has swing/twist limits.
    pub fn has_ball_limits(&self) -> bool {
        self.ball_limits.iter().any(Option::is_some)
    }
    /// Every named frame: links and joints, fused ones included.
    pub fn frames(&self) -> &[Frame] {
        &self.frames
    }
    /// Collision and visual geometry, attached to model bodies with placements in their frames.
    pub fn geometries(&self) -> &[GeometrySpec] {
        &self.geometries
    }
    /// Gravity in the world frame (m/s²).
    pub fn gravity(&self) -> Vec3 {
        self.gravity
    }
    /// Sets gravity in the world frame (m/s²).
    pub fn set_gravity(&mut self, g: Vec3) {
        self.gravity = g;
    }
    /// Body index of a body by name (`universe` is 0).
    pub fn body_id(&self, name: &str) -> Option<usize> {
        self.body_names.iter().position(|n| n == name)
    }
    /// Body index of the body carried by the named (moving) joint.
    pub fn joint_id(&self, name: &str) -> Option<usize> {
        self.joint_names.iter().skip(1).position(|n| n == name).map(|i| i + 1)
    }
    /// Index of a frame by name, bodies looked up before joints.
    pub fn frame_id(&self, name: &str) -> Option<usize> {
        self.frames
            .iter()
            .position(|f| f.name == name && f.kind == FrameKind::Body)
            .or_else(|| self.frames.iter().position(|f| f.name == name))
    }
    /// Total mass (kg).
    pub fn total_mass(&self) -> f64 {
        self.inertias.iter().skip(1).map(|i| i.mass).sum()
    }
    /// Mass of body `i` and all its descendants (kg).
    pub fn subtree_mass(&self, i: usize) -> f64 {
        self.inertias[i].mass + self.children[i].iter().map(|&c| self.subtree_mass(c)).sum::<f64>()
    }
    /// Velocity ranges (first dof, number of dofs) of the subtrees hanging from the root, in
    /// order: M(q) is block diagonal over them, so each can be solved on its own (ten boxes
    /// on free joints in one model are ten 6×6 blocks, not one 60×60). One range covering
    /// every dof if the numbering does not keep each subtree contiguous.
    pub fn root_subtree_dofs(&self) -> Vec<(usize, usize)> {
        let mut ranges: Vec<(usize, usize)> = Vec::new();
        for k in 0..self.nv {
            let parent = self.dof_parent[k];
            if parent == NO_DOF {
                ranges.push((k, 1));
            } else if let Some(last) = ranges.last_mut().filter(|r| parent >= r.0) {
                last.1 += 1;
            } else {
                return vec![(0, self.nv)];
            }
        }
        ranges
    }
    /// Joints whose moving subtree has neither mass nor rotational inertia: the mass matrix is
    /// singular in their coordinates, and forward dynamics reports
    /// [`crate::DynamicsError::SingularMassMatrix`] for them.
    pub fn massless_subtrees(&self) -> Vec<usize> {
        (1..self.nbodies())
            .filter(|&i| {
                let mut stack = vec![i];
                while let Some(b) = stack.pop() {
                    let inertia = &self.inertias[b];
                    if inertia.mass > 0.0 || inertia.inertia_origin.iter().any(|x| *x != 0.0) {
                        return false;
                    }
                    stack.extend_from_slice(&self.children[b]);
                }
                true
            })
            .collect()
    }
    /// The neutral configuration: zero angles and offsets, identity quaternions.
    pub fn neutral_configuration(&self) -> DVector<f64> {
        let mut q = DVector::zeros(self.nq);
        for i in 1..self.nbodies() {
            let j = &self.joints[i];
            j.neutral(&mut q.as_mut_slice()[self.idx_q[i]..self.idx_q[i] + j.nq()]);
        }
        q
    }
    /// A random configuration within the position limits (see [`Joint::random`]).
    pub fn random_configuration<R: Rng + ?Sized>(&self, rng: &mut R) -> DVector<f64> {
        let mut q = DVector::zeros(self.nq);
        for i in 1..self.nbodies() {
            let j = &self.joints[i];
            let r = self.idx_q[i]..self.idx_q[i] + j.nq();
            j.random(
                rng,
                &self.lower_position_limit.as_slice()[r.clone()],
                &self.upper_position_limit.as_slice()[r.clone()],
                &mut q.as_mut_slice()[r],
            );
        }
        q
    }
    /// `q_out = q ⊕ v·dt` joint by joint on the configuration manifold.
    pub fn integrate(&self, q: &DVector<f64>, v: &DVector<f64>, dt: f64, q_out: &mut DVector<f64>) {
        for i in 1..self.nbodies() {
            let j = &self.joints[i];
            let (rq, rv) = (self.idx_q[i]..self.idx_q[i] + j.nq(), self.idx_v[i]..self.idx_v[i] + j.nv());
            j.integrate(&q.as_slice()[rq.clone()], &v.as_slice()[rv], dt, &mut q_out.as_mut_slice()[rq]);
        }
    }
    /// `q_out = q ⊕ v·dt` with [`Joint::integrate_decoupled`] for every joint: free and planar
    /// origins move along straight lines (the world's time step uses this).
    pub fn integrate_decoupled(&self, q: &DVector<f64>, v: &DVector<f64>, dt: f64, q_out: &mut DVector<f64>) {
        for i in 1..self.nbodies() {
            let j = &self.joints[i];
            let (rq, rv) = (self.idx_q[i]..self.idx_q[i] + j.nq(), self.idx_v[i]..self.idx_v[i] + j.nv());
            j.integrate_decoupled(
                &q.as_slice()[rq.clone()],
                &v.as_slice()[rv],
                dt,
                &mut q_out.as_mut_slice()[rq],
            );
        }
    }
    /// `v_out = q1 ⊖ q0`: the velocity that [`Model::integrate`] turns `q0` into `q1` with in unit time.
    pub fn difference(&self, q0: &DVector<f64>, q1: &DVector<f64>, v_out: &mut DVector<f64>) {
        for i in 1..self.nbodies() {
            let j = &self.joints[i];
            let (rq, rv) = (self.idx_q[i]..self.idx_q[i] + j.nq(), self.idx_v[i]..self.idx_v[i] + j.nv());
            j.difference(&q0.as_slice()[rq.clone()], &q1.as_slice()[rq], &mut v_out.as_mut_slice()[rv]);
        }
    }
    /// Renormalizes every quaternion in `q`.
    pub fn normalize(&self, q: &mut DVector<f64>) {
        for i in 1..self.nbodies() {
            let j = &self.joints[i];
            j.normalize(&mut q.as_mut_slice()[self.idx_q[i]..self.idx_q[i] + j.nq()]);
        }
    }
    /// Checks that every quaternion in `q` (nq entries) can be normalized: a norm of at least
    /// [`MIN_QUATERNION_NORM`]. The algorithms normalize the others as they read them.
    pub fn check_quaternions(&self, q: &[f64]) -> Result<(), DynamicsError> {
        // Squared norms: no square root per joint on the step's path (kinematics checks q).
        for i in 1..self.nbodies() {
            let Some(r) = self.joints[i].quaternion_range() else { continue };
            let squared: f64 = q[self.idx_q[i] + r.start..self.idx_q[i] + r.end].iter().map(|x| x * x).sum();
            // Written so that a NaN passes here and is reported as not finite.
            if squared < MIN_QUATERNION_NORM * MIN_QUATERNION_NORM {
                return Err(DynamicsError::DegenerateQuaternion {
                    joint: self.joint_name(i).to_string(),
                    norm: squared.sqrt(),
                });
            }
        }
        Ok(())
    }
    /// The joint owning configuration index `k`.
    pub fn joint_of_q(&self, k: usize) -> usize {
        (1..self.nbodies()).rev().find(|&i| self.idx_q[i] <= k).unwrap_or(0)
    }
}
