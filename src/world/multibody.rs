//! One multibody of a world: its model, data, state, applied forces, motors and the buffers of
//! its share of a step.

use crate::algorithms::{aba, compute_joint_jacobians};
use crate::data::Data;
use crate::error::DynamicsError;
use crate::integrators::implicit::{implicit_free_velocity, ImplicitTerms};
use crate::math::Vec3;
use crate::model::Model;
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
    /// Generalized forces of this step's external forces (cleared after each step).
    pub(crate) tau_external: DVector<f64>,
    pub(crate) pending_forces: Vec<(usize, Vec3, Vec3, Vec3)>,
    pub(crate) asleep: bool,
    pub(crate) idle_steps: usize,
    pub(crate) idle_time: f64,
    pub(crate) speed_history: Vec<(f64, f64)>,
    pub(crate) col: usize,
    pub(crate) v_free: DVector<f64>,
    pub(crate) v_next: DVector<f64>,
    pub(crate) q_next: DVector<f64>,
    pub(crate) rhs: DVector<f64>,
    pub(crate) factored: bool,
    /// Joint damping and suspension springs, treated implicitly.
    implicit_terms: ImplicitTerms,
}

impl Multibody {
    pub(crate) fn new(model: Model) -> Self {
        let nv = model.nv();
        let data = Data::new(&model);
        let state = State::new(&model);
        let nb = model.nbodies();
        Self {
            implicit_terms: ImplicitTerms::new(&model),
            data,
            state,
            tau: DVector::zeros(nv),
            kinematic: false,
            motors: vec![None; nv],
            servos: vec![None; nv],
            tau_external: DVector::zeros(nv),
            pending_forces: Vec::with_capacity(nb),
            asleep: false,
            idle_steps: 0,
            idle_time: 0.0,
            speed_history: Vec::new(),
            col: 0,
            v_free: DVector::zeros(nv),
            v_next: DVector::zeros(nv),
            q_next: model.neutral_configuration(),
            rhs: DVector::zeros(nv),
            factored: false,
            model,
        }
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
    /// springs and strong damping stay stable). With `need_factor` false and no implicit terms,
    /// ABA gives it in O(n) without M.
    pub(crate) fn free_motion(&mut self, h: f64, need_factor: bool) -> Result<(), DynamicsError> {
        if self.kinematic {
            self.v_free.copy_from(&self.state.v);
            self.factored = false;
            return Ok(());
        }
        self.rhs.copy_from(&self.tau);
        self.rhs += &self.tau_external;
        if !need_factor && self.implicit_terms.is_empty() {
            let a = aba(&self.model, &mut self.data, &self.state.q, &self.state.v, &self.rhs)?;
            self.v_free.copy_from(&self.state.v);
            self.v_free.axpy(h, a, 1.0);
            self.factored = false;
            return Ok(());
        }
        implicit_free_velocity(
            &self.model,
            &mut self.data,
            &self.implicit_terms,
            &self.state.q,
            &self.state.v,
            h,
            &mut self.rhs,
            &mut self.v_free,
        )?;
        self.factored = true;
        Ok(())
    }
}
