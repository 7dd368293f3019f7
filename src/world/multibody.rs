//! One multibody of a world: its model, data, state, applied forces, motors and the buffers of
//! its share of a step.

use super::gyroscopic::Gyroscopic;
use crate::algorithms::{
    aba, check_v, compute_joint_jacobians, crba_packed_at_kinematics, factor_mass_matrix,
    nonlinear_effects_at_kinematics, solve_mass_matrix_slice,
};
use crate::data::Data;
use crate::error::DynamicsError;
use crate::integrators::implicit::{implicit_velocity_from_dynamics, ImplicitTerms};
use crate::math::{Motion, Vec3};
use crate::model::{Joint, Model};
use crate::state::State;
use nalgebra::DVector;

/// A velocity motor on one dof: drive the rate to `target_velocity` with at most `max_force`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motor {
    /// Target rate (rad/s or m/s).
    pub target_velocity: f64,
    /// Force bound (N·m or N).
    pub max_force: f64,
}

/// A position servo on one dof: a motor whose target velocity is `gain · (target − q)`, clamped
/// to `max_velocity`, with the force bound `max_force`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Servo {
    /// Target position (rad or m).
    pub target_position: f64,
    /// Proportional gain (1/s).
    pub gain: f64,
    /// Largest commanded rate (rad/s or m/s).
    pub max_velocity: f64,
    /// Force bound (N·m or N).
    pub max_force: f64,
}

/// A pose servo ("powered ragdoll"): drives every joint except free ones towards the
/// configuration `target` with bounded force, as velocity motors whose target rate is
/// `gain · (target ⊖ q)` per dof (the manifold difference: for a ball joint the rotation vector
/// of `q⁻¹ q_target`, child frame), clamped to `max_velocity`.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseServo {
    /// Target configuration (length nq; free-joint entries are ignored).
    pub target: DVector<f64>,
    /// Proportional gain (1/s).
    pub gain: f64,
    /// Largest commanded rate per dof (rad/s or m/s).
    pub max_velocity: f64,
    /// Force bound of each dof (length nv; N·m or N).
    pub max_force: DVector<f64>,
}

impl PoseServo {
    /// A servo to `target` with the same force bound `max_force` on every dof.
    pub fn uniform(target: DVector<f64>, gain: f64, max_velocity: f64, max_force: f64, nv: usize) -> Self {
        Self { target, gain, max_velocity, max_force: DVector::from_element(nv, max_force) }
    }

    /// A servo to `target` whose force bound on each dof of joint j is `torque_per_kg` times the
    /// mass (kg) of the subtree the joint moves (N·m/kg → N·m): strong hips and spine, weak
    /// wrists, as muscles scale with the load they carry.
    pub fn scaled_by_subtree_mass(
        model: &Model,
        target: DVector<f64>,
        gain: f64,
        max_velocity: f64,
        torque_per_kg: f64,
    ) -> Self {
        let mut max_force = DVector::zeros(model.nv());
        for j in 1..model.nbodies() {
            let bound = torque_per_kg * model.subtree_mass(j);
            max_force.rows_mut(model.idx_v(j), model.joint(j).nv()).fill(bound);
        }
        Self { target, gain, max_velocity, max_force }
    }
}

/// A multibody in a world.
#[derive(Clone, Debug)]
pub struct Multibody {
    pub(crate) model: Model,
    pub(crate) data: Data,
    /// Configuration, velocity and time.
    pub state: State,
    /// Joint torques or forces applied every step until changed (N·m or N).
    pub tau: DVector<f64>,
    /// Driven by the user: its velocity is kept as set, forces and contacts do not change it.
    pub kinematic: bool,
    pub(crate) motors: Vec<Option<Motor>>,
    pub(crate) servos: Vec<Option<Servo>>,
    pub(crate) pose_servo: Option<PoseServo>,
    /// Generalized forces of this step's external forces (cleared after each step).
    pub(crate) tau_external: DVector<f64>,
    pub(crate) pending_forces: Vec<(usize, Vec3, Vec3, Vec3)>,
    pub(crate) asleep: bool,
    pub(crate) idle_steps: usize,
    pub(crate) idle_time: f64,
    /// The last `average_samples` generalized velocities, flat (sample-major), for sleeping.
    pub(crate) velocity_history: Vec<f64>,
    /// Velocities recorded in `velocity_history` since the multibody last woke.
    pub(crate) history_len: usize,
    /// Scratch: the average of `velocity_history`.
    pub(crate) velocity_average: DVector<f64>,
    pub(crate) col: usize,
    pub(crate) v_free: DVector<f64>,
    pub(crate) v_next: DVector<f64>,
    pub(crate) q_next: DVector<f64>,
    pub(crate) rhs: DVector<f64>,
    pub(crate) factored: bool,
    /// Joint damping and suspension springs, treated implicitly.
    implicit_terms: ImplicitTerms,
    /// The gyroscopic couple of spinning bodies of free and ball joints, treated implicitly.
    gyroscopic: Gyroscopic,
    /// `data` holds the factor of a mass matrix that does not depend on q (free bodies on the
    /// root, no joint damping: see [`has_constant_mass_matrix`]): the free motion skips CRBA and
    /// the factorization. Other writers of the factor (smooth steps) write the same M, up to
    /// round-off.
    constant_mass_factored: bool,
    /// The last factor of M (+ h·D) the free motion computed, with its q and h, for
    /// [`super::WorldOptions::mass_matrix_reuse`]: copied back into `data` when reused, since
    /// other users of `data` (impulses, smooth steps) may factor there in between.
    kept_factor: KeptFactor,
    /// Mass-matrix factorizations by the free motion so far (see [`Multibody::factorizations`]).
    factorizations: u64,
    /// Per body, its spatial velocity in world axes about the world origin under `state.v`, under
    /// `v_free` ([`Multibody::update_world_velocities`]) and under the velocity after the
    /// step's solve ([`Multibody::update_solved_world_velocities`]).
    pub(crate) world_velocities: WorldVelocities,
    /// The velocity after the step's first solve, while the world solves again
    /// ([`super::World::step`]'s check after the solve).
    pub(crate) v_solved: DVector<f64>,
    /// The contact projection's displacement of this step (rad or m per dof, in the tangent
    /// space at the step's start, as `h · v_next` is), added to the step's displacement
    /// `h · v_next` when q is integrated ([`Multibody::integrate_step`]); meaningful only while
    /// `corrected` ([`super::contact_projection`]).
    pub(crate) position_correction: DVector<f64>,
    /// Whether this step's `position_correction` applies.
    pub(crate) corrected: bool,
    /// A lone free body's shift of its origin over the step (m, in its body axes at the step's
    /// start, as the free joint's linear velocity is): the step's mean velocity replaces its
    /// end velocity along the directions no contact normal constrains
    /// ([`super::stages::midpoint`]); zero for any other multibody.
    pub(crate) midpoint_shift: Vec3,
    /// Scratch of the shift: the span of this step's contact normals.
    pub(crate) midpoint_span: super::stages::midpoint::NormalSpan,
    /// Scratch: `v_next + (position_correction + midpoint_shift) / h`, the velocity q is
    /// integrated with.
    step_velocity: DVector<f64>,
    /// Scratch: a configuration (nq).
    q_scratch: DVector<f64>,
}

/// Per body of a multibody, its spatial velocity in world axes about the world origin under
/// three velocities of a step (see [`Multibody::update_world_velocities`]).
#[derive(Clone, Debug)]
pub(crate) struct WorldVelocities {
    /// Under the state's velocity at the start of the step.
    pub(crate) start: Vec<Motion>,
    /// Under the free velocity.
    pub(crate) free: Vec<Motion>,
    /// Under the velocity after the step's solve.
    pub(crate) solved: Vec<Motion>,
}

/// `V_b = V_parent + Σ_k J_k v_k` over the columns of body b's joint (world axes, about the world
/// origin; `data.j_world` current): every body's spatial velocity under `v` into `out` (one per
/// body; the root's entry stays zero).
fn propagate_world_velocities(model: &Model, data: &Data, v: &[f64], out: &mut [Motion]) {
    for i in 1..model.nbodies() {
        let mut at = out[model.parent(i)];
        let dofs = model.idx_v(i)..model.idx_v(i) + model.joint(i).nv();
        for (column, vk) in data.j_world[dofs.clone()].iter().zip(&v[dofs]) {
            at.linear += column.linear * *vk;
            at.angular += column.angular * *vk;
        }
        out[i] = at;
    }
}

impl Multibody {
    pub(crate) fn new(model: Model) -> Self {
        let nv = model.nv();
        let data = Data::without_dense_mass_matrix(&model);
        let kept_factor = KeptFactor::new(&model, &data);
        let state = State::new(&model);
        let nb = model.nbodies();
        Self {
            implicit_terms: ImplicitTerms::new(&model),
            gyroscopic: Gyroscopic::new(&model),
            data,
            state,
            tau: DVector::zeros(nv),
            kinematic: false,
            motors: vec![None; nv],
            servos: vec![None; nv],
            pose_servo: None,
            tau_external: DVector::zeros(nv),
            pending_forces: Vec::with_capacity(nb),
            asleep: false,
            idle_steps: 0,
            idle_time: 0.0,
            velocity_history: Vec::new(),
            history_len: 0,
            velocity_average: DVector::zeros(0),
            col: 0,
            v_free: DVector::zeros(nv),
            v_next: DVector::zeros(nv),
            q_next: model.neutral_configuration(),
            rhs: DVector::zeros(nv),
            factored: false,
            constant_mass_factored: false,
            kept_factor,
            factorizations: 0,
            world_velocities: WorldVelocities {
                start: vec![Motion::zero(); nb],
                free: vec![Motion::zero(); nb],
                solved: vec![Motion::zero(); nb],
            },
            v_solved: DVector::zeros(nv),
            position_correction: DVector::zeros(nv),
            corrected: false,
            midpoint_shift: Vec3::zeros(),
            midpoint_span: Default::default(),
            step_velocity: DVector::zeros(nv),
            q_scratch: DVector::zeros(model.nq()),
            model,
        }
    }

    /// Fills `world_velocities.start` and `.free`: the spatial velocity of every body in world
    /// axes about the world origin (a point p of the body moves at `linear + angular × p`) under
    /// the state's velocity and under the free velocity (`data.j_world` must be current). O(nv):
    /// the world's speculative-contact test reads a contact's closing speed from it instead of
    /// forming the contact's Jacobian.
    pub(crate) fn update_world_velocities(&mut self) {
        let (model, data, out) = (&self.model, &self.data, &mut self.world_velocities);
        propagate_world_velocities(model, data, self.state.v.as_slice(), &mut out.start);
        propagate_world_velocities(model, data, self.v_free.as_slice(), &mut out.free);
    }

    /// Fills `world_velocities.start` alone (the collision stage's sweeps read it before the
    /// free motion).
    pub(crate) fn update_start_world_velocities(&mut self) {
        let (model, data, out) = (&self.model, &self.data, &mut self.world_velocities);
        propagate_world_velocities(model, data, self.state.v.as_slice(), &mut out.start);
    }

    /// Fills `world_velocities.solved` the same way under `v`, the velocity after a solve (this
    /// multibody's nv entries): for the contacts the world checks after the solve.
    pub(crate) fn update_solved_world_velocities(&mut self, v: &[f64]) {
        propagate_world_velocities(&self.model, &self.data, v, &mut self.world_velocities.solved);
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The data of the last step (body poses `x_wb`, Jacobians, mass matrix, ...).
    pub fn data(&self) -> &Data {
        &self.data
    }

    /// Whether the multibody sleeps.
    pub fn is_asleep(&self) -> bool {
        self.asleep
    }

    /// Sets a velocity motor on dof `k` (`None` removes it).
    pub fn set_motor(&mut self, k: usize, motor: Option<Motor>) {
        self.motors[k] = motor;
    }

    /// Sets a position servo on dof `k` (`None` removes it).
    pub fn set_servo(&mut self, k: usize, servo: Option<Servo>) {
        self.servos[k] = servo;
    }

    /// Sets a pose servo driving every non-free joint to a target configuration (`None` removes
    /// it). Errors when the target or force vector has the wrong length or is not finite, or a
    /// gain, rate or force bound is negative.
    pub fn set_pose_servo(&mut self, servo: Option<PoseServo>) -> Result<(), crate::error::ModelError> {
        if let Some(s) = &servo {
            let bad = |reason: String| crate::error::ModelError::InvalidLimits {
                joint: "pose servo".into(),
                reason,
            };
            if s.target.len() != self.model.nq() || s.max_force.len() != self.model.nv() {
                return Err(bad(format!(
                    "target has {} entries (nq = {}), max_force {} (nv = {})",
                    s.target.len(),
                    self.model.nq(),
                    s.max_force.len(),
                    self.model.nv()
                )));
            }
            if !(s.target.iter().all(|x| x.is_finite()) && s.gain >= 0.0 && s.max_velocity >= 0.0)
                || s.max_force.iter().any(|f| f.is_nan() || *f < 0.0)
            {
                return Err(bad("target must be finite; gain, max_velocity, max_force non-negative".into()));
            }
        }
        self.pose_servo = servo;
        Ok(())
    }

    /// The pose servo, if any.
    pub fn pose_servo(&self) -> Option<&PoseServo> {
        self.pose_servo.as_ref()
    }

    /// Poses and Jacobian columns at the current q, and the generalized forces of the pending
    /// external forces (`J_pᵀ f + J_ωᵀ τ` for a force `f` at world point `p` and torque `τ`).
    pub(crate) fn kinematics(&mut self) -> Result<(), DynamicsError> {
        compute_joint_jacobians(&self.model, &mut self.data, &self.state.q)?;
        self.tau_external.fill(0.0);
        for &(body, force, point, torque) in &self.pending_forces {
            let mut b = body;
            // Walk the dofs that move `body`, from the body to the root.
            while b != 0 {
                let joint = self.model.joint(b);
                for k in self.model.idx_v(b)..self.model.idx_v(b) + joint.nv() {
                    let col = &self.data.j_world[k];
                    self.tau_external[k] +=
                        force.dot(&(col.linear + col.angular.cross(&point))) + torque.dot(&col.angular);
                }
                b = self.model.parent(b);
            }
        }
        Ok(())
    }

    /// The free velocity `v_free = v + h M̃⁻¹ (τ + τ_ext − C v − g − D v − K (s + h v))` with
    /// `M̃ = M + h D + h² K` (damping D and suspension stiffness K treated implicitly, so that stiff
    /// springs and strong damping stay stable), and the gyroscopic couple of spinning bodies of
    /// free and ball joints taken out of `C v` and treated implicitly (see
    /// [`super::gyroscopic`]). With `need_factor` false, no implicit terms and nothing spinning,
    /// ABA gives it in O(n) without M.
    pub(crate) fn free_motion(
        &mut self,
        h: f64,
        need_factor: bool,
        reuse: Option<f64>,
    ) -> Result<(), DynamicsError> {
        if self.kinematic {
            self.v_free.copy_from(&self.state.v);
            self.factored = false;
            return Ok(());
        }
        self.rhs.copy_from(&self.tau);
        self.rhs += &self.tau_external;
        let spinning = self.gyroscopic.any_spinning(&self.model, &self.data, self.state.v.as_slice(), h);
        if !need_factor && !spinning && self.implicit_terms.is_empty() {
            let a = aba(&self.model, &mut self.data, &self.state.q, &self.state.v, &self.rhs)?;
            self.v_free.copy_from(&self.state.v);
            self.v_free.axpy(h, a, 1.0);
            self.factored = false;
            self.add_frame_rotation_terms(h);
            return Ok(());
        }
        if self.implicit_terms.is_empty() && has_constant_mass_matrix(&self.model) {
            if !self.constant_mass_factored {
                constant_mass_matrix(&self.model, &mut self.data);
                factor_mass_matrix(&self.model, &mut self.data)?;
                self.constant_mass_factored = true;
            }
            // Only the bias forces are new (RNEA, on the kinematics phase's joint transforms).
            check_v(&self.model, &self.state.v, "v")?;
            nonlinear_effects_at_kinematics(&self.model, &mut self.data, &self.state.v);
            self.rhs -= &self.data.nle;
            solve_mass_matrix_slice(&self.model, &self.data, self.rhs.as_mut_slice());
            self.v_free.copy_from(&self.state.v);
            self.v_free.axpy(h, &self.rhs, 1.0);
            self.factored = true;
            if spinning {
                self.gyroscopic.apply(&self.model, &self.data, &self.state.v, &mut self.v_free, h);
            }
            self.add_frame_rotation_terms(h);
            return Ok(());
        }
        // The step's kinematics phase computed the joint transforms at this q: CRBA and RNEA
        // skip them.
        check_v(&self.model, &self.state.v, "v")?;
        let reuse =
            reuse.is_some_and(|tolerance| self.kept_factor.holds(&self.model, &self.state.q, h, tolerance));
        if reuse {
            self.kept_factor.restore(&mut self.data);
        } else {
            crba_packed_at_kinematics(&self.model, &mut self.data);
        }
        nonlinear_effects_at_kinematics(&self.model, &mut self.data, &self.state.v);
        implicit_velocity_from_dynamics(
            &self.model,
            &mut self.data,
            &self.implicit_terms,
            &self.state.q,
            &self.state.v,
            h,
            &mut self.rhs,
            &mut self.v_free,
            !reuse,
        )?;
        if !reuse {
            self.factorizations += 1;
            self.kept_factor.keep(&self.data, &self.state.q, h);
        }
        self.factored = true;
        if spinning {
            self.gyroscopic.apply(&self.model, &self.data, &self.state.v, &mut self.v_free, h);
        }
        self.add_frame_rotation_terms(h);
        Ok(())
    }

    /// How many times the free motion has factored this multibody's mass matrix (CRBA and
    /// the LTDL factorization); steps that reuse the last factor
    /// ([`super::WorldOptions::mass_matrix_reuse`]) or need none (no rows, no damping: ABA) do not
    /// count.
    pub fn factorizations(&self) -> u64 {
        self.factorizations
    }

    /// Which factor of M `data` holds for the constraint rows: None when the multibody cannot
    /// take impulses this step (asleep, kinematic, or not factored), else the count of
    /// factorizations, which changes whenever the factor does (a reused factor, or the constant
    /// M of free bodies, keeps it).
    pub(crate) fn factor_identity(&self) -> Option<u64> {
        (!(self.asleep || self.kinematic) && self.factored).then_some(self.factorizations)
    }

    /// Free joints: turns the body-frame rate `v̇` of the origin's velocity into its classical
    /// acceleration `v̇ + ω × v`, so that `v_free`'s linear part is the origin's velocity at the end
    /// of the step expressed in the axes of the start of the step (where the constraint rows
    /// are). [`Multibody::transport_free_velocities`] then re-expresses it in the new axes, exactly.
    ///
    /// Why: body-frame velocities carry the term `−ω × v` of the rotating axes. Integrated
    /// explicitly it multiplies |v| by √(1 + (ω h)²) every step — a body spinning at 24 rad/s
    /// gains a third of its speed per second at h = 1 ms, and a rolling ball accelerates at
    /// 0.74 g sin θ instead of 5/7 g sin θ.
    fn add_frame_rotation_terms(&mut self, h: f64) {
        for i in 1..self.model.nbodies() {
            if matches!(self.model.joint(i), Joint::Free) {
                let k = self.model.idx_v(i);
                let v = Vec3::new(self.state.v[k], self.state.v[k + 1], self.state.v[k + 2]);
                let w = Vec3::new(self.state.v[k + 3], self.state.v[k + 4], self.state.v[k + 5]);
                let correction = w.cross(&v) * h;
                for a in 0..3 {
                    self.v_free[k + a] += correction[a];
                }
            }
        }
    }

    /// `q_next = q ⊕ (h · v_next + Δ + s)` on the manifold, free origins on straight lines
    /// ([`Model::integrate_decoupled`]), with Δ this step's contact projection
    /// (`position_correction`, when `corrected`; else Δ = 0) and s a lone free body's
    /// `midpoint_shift`: both are taken in the same chart, at the step's start, as the step's
    /// own displacement and the constraint rows.
    pub(crate) fn integrate_step(&mut self, h: f64) {
        let shifted = self.midpoint_shift != Vec3::zeros();
        if self.corrected || shifted {
            self.step_velocity.copy_from(&self.v_next);
            if self.corrected {
                self.step_velocity.axpy(1.0 / h, &self.position_correction, 1.0);
            }
            if shifted {
                // Only a lone free body is shifted: its linear dofs are its first three.
                for a in 0..3 {
                    self.step_velocity[a] += self.midpoint_shift[a] / h;
                }
            }
            self.model.integrate_decoupled(&self.state.q, &self.step_velocity, h, &mut self.q_next);
        } else {
            self.model.integrate_decoupled(&self.state.q, &self.v_next, h, &mut self.q_next);
        }
    }

    /// `q_next ← q_next ⊕ Δ` with Δ = `position_correction` taken in the tangent space at
    /// `q_next` (the end contacts' rows are at `q_next`); a free joint's velocity, in its
    /// body's axes, follows the turn `exp(Δω)` so that its world velocity stays as it was.
    pub(crate) fn apply_end_correction(&mut self) {
        std::mem::swap(&mut self.q_next, &mut self.q_scratch);
        self.model.integrate_decoupled(&self.q_scratch, &self.position_correction, 1.0, &mut self.q_next);
        for i in 1..self.model.nbodies() {
            if matches!(self.model.joint(i), Joint::Free) {
                let k = self.model.idx_v(i);
                let v = Vec3::new(self.v_next[k], self.v_next[k + 1], self.v_next[k + 2]);
                let c = &self.position_correction;
                let turn = Vec3::new(c[k + 3], c[k + 4], c[k + 5]);
                let turned = nalgebra::UnitQuaternion::from_scaled_axis(turn).inverse() * v;
                for a in 0..3 {
                    self.v_next[k + a] = turned[a];
                }
            }
        }
    }

    /// Free joints: `v_next`'s linear part, expressed in the axes of the start of the step, in
    /// the axes after the step turned them by `exp(ω h)` (ω the rate q was integrated with,
    /// the contact projection's turn included): `v ← exp(ω h)ᵀ v`, so that the origin's velocity
    /// in world axes is the one the step solved for. The angular part is invariant under its
    /// own rotation.
    pub(crate) fn transport_free_velocities(&mut self, h: f64) {
        for i in 1..self.model.nbodies() {
            if matches!(self.model.joint(i), Joint::Free) {
                let k = self.model.idx_v(i);
                let v = Vec3::new(self.v_next[k], self.v_next[k + 1], self.v_next[k + 2]);
                let mut w = Vec3::new(self.v_next[k + 3], self.v_next[k + 4], self.v_next[k + 5]);
                if self.corrected {
                    let c = &self.position_correction;
                    w += Vec3::new(c[k + 3], c[k + 4], c[k + 5]) / h;
                }
                let turned = nalgebra::UnitQuaternion::from_scaled_axis(w * h).inverse() * v;
                for a in 0..3 {
                    self.v_next[k + a] = turned[a];
                }
            }
        }
    }
}

/// Whether M(q) is the same for every q: free bodies attached to the root (their fused fixed
/// children included), whose body-frame mass matrix is block diagonal with each body's spatial
/// inertia about its origin.
fn has_constant_mass_matrix(model: &Model) -> bool {
    (1..model.nbodies()).all(|i| matches!(model.joint(i), Joint::Free) && model.parent(i) == 0)
}

/// M of a model of free bodies on the root ([`has_constant_mass_matrix`]) into
/// `data.mass_matrix`: block diagonal, each block the body's spatial inertia about its origin in
/// its own axes, `[[m 1, −m [c]×], [m [c]×, I_o]]`. Written from the inertias, not by CRBA (which
/// rotates them to world axes and back), so that structurally zero entries are exactly zero and
/// the assembly skips them ([`Data::factor_row_coupled`]).
fn constant_mass_matrix(model: &Model, data: &mut Data) {
    data.sized_mass_matrix(model).fill(0.0);
    for i in 1..model.nbodies() {
        let k = model.idx_v(i);
        let block = model.inertia(i).to_matrix();
        data.mass_matrix.view_mut((k, k), (6, 6)).copy_from(&block);
    }
}

/// A factor of M (+ h·D) kept with the configuration and step it belongs to; its buffers have
/// the sizes of the multibody's `Data` from the start, so keeping one copies and never allocates.
#[derive(Clone, Debug)]
struct KeptFactor {
    valid: bool,
    h: f64,
    q: DVector<f64>,
    packed: Vec<f64>,
    inv_sqrt_d: DVector<f64>,
    row_coupled: Vec<bool>,
}

impl KeptFactor {
    fn new(model: &Model, data: &Data) -> Self {
        Self {
            valid: false,
            h: 0.0,
            q: DVector::zeros(model.nq()),
            packed: vec![0.0; data.factor_packed.len()],
            inv_sqrt_d: DVector::zeros(data.factor_inv_sqrt_d.len()),
            row_coupled: vec![false; data.factor_row_coupled.len()],
        }
    }

    /// Whether the kept factor is for step `h` and every coordinate of `q` but a floating
    /// root's is within `tolerance` of the kept q. In the body-frame velocities of a free root
    /// (Pinocchio's), M does not depend on the root's pose.
    fn holds(&self, model: &Model, q: &DVector<f64>, h: f64, tolerance: f64) -> bool {
        if !self.valid || self.h != h {
            return false;
        }
        let from = if model.nbodies() > 1 && model.parent(1) == 0 && matches!(model.joint(1), Joint::Free) {
            model.idx_q(1) + 7
        } else {
            0
        };
        self.q.as_slice()[from..].iter().zip(&q.as_slice()[from..]).all(|(a, b)| (a - b).abs() <= tolerance)
    }

    fn keep(&mut self, data: &Data, q: &DVector<f64>, h: f64) {
        self.valid = true;
        self.h = h;
        self.q.copy_from(q);
        self.packed.copy_from_slice(&data.factor_packed);
        self.inv_sqrt_d.copy_from(&data.factor_inv_sqrt_d);
        self.row_coupled.copy_from_slice(&data.factor_row_coupled);
    }

    fn restore(&self, data: &mut Data) {
        data.factor_packed.copy_from_slice(&self.packed);
        data.factor_inv_sqrt_d.copy_from(&self.inv_sqrt_d);
        data.factor_row_coupled.copy_from_slice(&self.row_coupled);
    }
}
