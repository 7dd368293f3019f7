//! RATTLE: the velocity-level step of a multibody whose only constraints in a step are its own
//! loop closures (a linkage swinging free: no contact, limit, motor, servo or joint friction
//! on it, no closure to another multibody).
//!
//! The first-order step ([`super::stages::integrate`] with SHAKE) integrates
//! `M(q₀)(v₁ − v₀) = h (τ − C(q₀, v₀)v₀ − g(q₀)) + Jᵀλ` and reports v₁, the velocity over the
//! step. Its Coriolis and centrifugal term is explicit on an inertia that depends on q, so it
//! is no symplectic map and its energy drifts by O(h) per unit time; and the velocity it
//! reports is the mean over the step, not the velocity at q₁, an O(h) error of the kinetic
//! energy at any step. On the four-bar of [`crate::scenes::four_bar_world`], 10 s lose 44 %,
//! 15 % and 3.9 % of the largest kinetic energy at 1/60, 1/240 and 1/1000 s, whether the
//! closure is held by SHAKE or by Baumgarte feedback alone, and the same rods released
//! without the loop lose as much: the loop closure is not what dissipates.
//!
//! RATTLE (Andersen 1983; Hairer–Lubich–Wanner, *Geometric Numerical Integration*, VII.1.4,
//! the generalized Störmer–Verlet method for `H = ½ pᵀM(q)⁻¹p + U(q)` with holonomic
//! constraints) keeps the position and the momentum `p = M(q) v` at the step's ends:
//!
//! ```text
//! p½ = p₀ + h/2 (∂L/∂q(q₀, M₀⁻¹p½) + τ) + J₀ᵀλ          (implicit in p½)
//! q₁ = q₀ + h/2 (M₀⁻¹ + M₁⁻¹) p½,   e(q₁) = 0          (implicit in q₁ and λ)
//! p₁ = p½ + h/2 (∂L/∂q(q₁, M₁⁻¹p½) + τ) + J₁ᵀμ,   J₁ M₁⁻¹ p₁ = 0
//! ```
//!
//! with `∂L/∂q = ∂T/∂q − g` ([`crate::algorithms`]'s momentum pass), `J₀ = J(q₀)`,
//! `J₁ = J(q₁)`. It is symmetric, second order and symplectic on the constraint manifold:
//! the energy error stays bounded and shrinks like h² (the four-bar: 0.7 %, 0.04 % and
//! 0.003 % of its largest kinetic energy over 10 s at 1/60, 1/240 and 1/1000 s), the
//! closure holds to the projection's tolerance, and the reported v₁ lies in the tangent
//! space at q₁. The implicit equations are solved by fixed-point sweeps, each one M₁'s
//! factorization at the current q₁ and one quasi-Newton step on λ along M₀⁻¹J₀ᵀ (as SHAKE),
//! until the closure error and the change of q₁ are below [`LoopProjection::tolerance`]; the
//! sweeps contract by about h‖v‖/L each. Sweeps that do not converge within their limit (a
//! step far too long for the linkage's speed) leave the step to the first-order step and
//! SHAKE. τ (joint torques and this step's external forces)
//! is held constant over the step.
//!
//! It applies to multibodies of hinges, sliders and fixed joints without springs or damping
//! (a vector space of coordinates; [`RattleBuffers::applies_to`]); others keep the
//! first-order step and SHAKE. A step of the multibody with any other row (a contact
//! appears) is the first-order step: its velocity is then the mean over the step again.

use super::multibody::Multibody;
use super::projection::{cholesky_solve, LoopProjection, ProjectionBuffers};
use crate::algorithms::{
    compute_joint_jacobians, crba_packed_at_kinematics, factor_packed_mass_matrix, has_screw_joints_only,
    momentum_and_lagrangian_force, solve_mass_matrix_slice,
};
use crate::constraints::LoopClosure;
use crate::data::Data;
use crate::error::DynamicsError;
use crate::integrators::ImplicitTerms;
use crate::math::Force;
use crate::model::Model;
use nalgebra::DVector;

/// The fewest fixed-point sweeps a step may take before it stops unconverged, whatever
/// [`LoopProjection::iterations`] asks: the sweeps contract by about h‖v‖/L, so a tight
/// tolerance takes more of them than SHAKE's Newton steps (the four-bar: 9–15 sweeps at
/// 1/60 s, 5–7 at 1/1000 s, to 1e-12).
const SWEEP_LIMIT_FLOOR: usize = 40;

/// Buffers of one multibody's RATTLE step (sized once, when its first loop is added).
#[derive(Clone, Debug)]
pub(crate) struct RattleBuffers {
    /// Kinematics and the mass-matrix factor at the step's end configuration q₁.
    end: Data,
    /// Subtree weights of the momentum pass (one per body).
    weights: Vec<Force>,
    /// p₀ = M₀ v₀, then p₁.
    p0: DVector<f64>,
    /// p½.
    p_half: DVector<f64>,
    /// ∂L/∂q at the current velocity.
    force: DVector<f64>,
    /// Applied generalized forces τ (joint torques and external forces).
    tau: DVector<f64>,
    /// M₀⁻¹p½ (the velocity at which ∂L/∂q(q₀, ·) is taken).
    w: DVector<f64>,
    /// ½(M₀⁻¹ + M₁⁻¹) p½, the mean velocity over the step.
    mean: DVector<f64>,
    /// M₁⁻¹p½ and scratch.
    scratch: DVector<f64>,
    /// The next estimate of q₁.
    q_trial: DVector<f64>,
    /// The first-order step's q₁ and v₁, restored when the sweeps do not converge.
    q_first: DVector<f64>,
    v_first: DVector<f64>,
    /// J₀, row-major (rows × nv).
    j0: Vec<f64>,
    /// The closure impulses λ (rows).
    lambda: Vec<f64>,
}

impl RattleBuffers {
    /// Whether RATTLE can step `model`: every joint a hinge, a slider or fixed (coordinates in
    /// a vector space, the momentum pass's ∂T/∂q), and no spring or damping (which the
    /// first-order step treats implicitly).
    pub(crate) fn applies_to(model: &Model) -> bool {
        model.nv() > 0 && has_screw_joints_only(model) && ImplicitTerms::new(model).is_empty()
    }

    /// Buffers for `model` with `rows` loop rows.
    pub(crate) fn new(model: &Model, rows: usize) -> Self {
        let (nv, nq) = (model.nv(), model.nq());
        Self {
            end: Data::new(model),
            weights: vec![Force::zero(); model.nbodies()],
            p0: DVector::zeros(nv),
            p_half: DVector::zeros(nv),
            force: DVector::zeros(nv),
            tau: DVector::zeros(nv),
            w: DVector::zeros(nv),
            mean: DVector::zeros(nv),
            scratch: DVector::zeros(nv),
            q_trial: DVector::zeros(nq),
            q_first: DVector::zeros(nq),
            v_first: DVector::zeros(nv),
            j0: vec![0.0; rows * nv],
            lambda: vec![0.0; rows],
        }
    }

    /// The factor of M into `self.end`, at the configuration of its kinematics.
    fn factor_end(&mut self, model: &Model) -> Result<(), DynamicsError> {
        crba_packed_at_kinematics(model, &mut self.end);
        factor_packed_mass_matrix(model, &mut self.end)
    }

    /// One RATTLE step of `b` from its state (see the module documentation), writing
    /// `b.q_next` and `b.v_next`. `b.data` must hold the kinematics and the mass-matrix factor
    /// at the step's start, and `b.q_next`, `b.v_next` a first guess of the step (the
    /// first-order step's); on return `b.data` holds poses and Jacobians at `b.q_next`.
    /// Returns whether the sweeps converged within their limit (the closure error and the
    /// change of q₁ below the tolerance): if not (a step far too long for the linkage's speed,
    /// h‖v‖/L of order one), `b.q_next`, `b.v_next` and the kinematics and factor in `b.data`
    /// are left as they came, for the first-order step to be finished by SHAKE.
    pub(crate) fn step<'a>(
        &mut self,
        b: &mut Multibody,
        closures: impl Iterator<Item = &'a LoopClosure> + Clone,
        projection: &mut ProjectionBuffers,
        options: &LoopProjection,
        h: f64,
    ) -> Result<bool, DynamicsError> {
        let model = &b.model;
        self.q_first.copy_from(&b.q_next);
        self.v_first.copy_from(&b.v_next);
        let nv = model.nv();
        self.tau.copy_from(&b.tau);
        self.tau += &b.tau_external;
        // At q₀: J₀, M₀⁻¹J₀ᵀ and the Gram factor; p₀ = M₀ v₀.
        projection.linearize(model, &b.data, closures.clone());
        let rows = projection.builder.len();
        for i in 0..rows {
            projection.builder.row_into(i, &mut self.j0[i * nv..(i + 1) * nv]);
        }
        let (p0, force) = (self.p0.as_mut_slice(), self.force.as_mut_slice());
        momentum_and_lagrangian_force(model, &mut b.data, b.state.v.as_slice(), &mut self.weights, p0, force);
        // First guesses: the first-order step's velocity and configuration, no impulse.
        self.w.copy_from(&b.v_next);
        self.lambda[..rows].fill(0.0);
        let sweeps = options.iterations.max(SWEEP_LIMIT_FLOOR);
        compute_joint_jacobians(model, &mut self.end, &b.q_next)?;
        let mut converged = false;
        for _ in 0..sweeps {
            // p½ = p₀ + h/2 (∂L/∂q(q₀, w) + τ) + J₀ᵀλ, w = M₀⁻¹p½ of the previous sweep.
            let force = self.force.as_mut_slice();
            let scratch = self.scratch.as_mut_slice();
            momentum_and_lagrangian_force(
                model,
                &mut b.data,
                self.w.as_slice(),
                &mut self.weights,
                scratch,
                force,
            );
            self.p_half.copy_from(&self.p0);
            self.p_half.axpy(0.5 * h, &self.force, 1.0);
            self.p_half.axpy(0.5 * h, &self.tau, 1.0);
            for (i, lambda) in self.lambda[..rows].iter().enumerate() {
                for (p, j) in self.p_half.iter_mut().zip(&self.j0[i * nv..(i + 1) * nv]) {
                    *p += lambda * j;
                }
            }
            // The mean velocity ½(M₀⁻¹ + M₁⁻¹)p½ at the current q₁, and q₁ anew.
            self.w.copy_from(&self.p_half);
            solve_mass_matrix_slice(model, &b.data, self.w.as_mut_slice());
            self.factor_end(model)?;
            self.scratch.copy_from(&self.p_half);
            solve_mass_matrix_slice(model, &self.end, self.scratch.as_mut_slice());
            self.mean.copy_from(&self.w);
            self.mean += &self.scratch;
            self.mean *= 0.5;
            model.integrate(&b.state.q, &self.mean, h, &mut self.q_trial);
            let change =
                self.q_trial.iter().zip(b.q_next.iter()).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            if !self.q_trial.iter().all(|x| x.is_finite()) {
                break;
            }
            b.q_next.copy_from(&self.q_trial);
            // The closure error at the new q₁, and λ's quasi-Newton step h J₀M₀⁻¹J₀ᵀ δλ = −e.
            compute_joint_jacobians(model, &mut self.end, &b.q_next)?;
            let error = projection.errors(model, &self.end, closures.clone());
            if !error.is_finite() {
                break;
            }
            if error <= options.tolerance && change <= options.tolerance {
                converged = true;
                break;
            }
            for i in 0..rows {
                projection.mu[i] = -projection.builder.target(i) / h;
            }
            cholesky_solve(&projection.gram[..rows * rows], rows, &mut projection.mu[..rows]);
            for (lambda, mu) in self.lambda[..rows].iter_mut().zip(&projection.mu[..rows]) {
                *lambda -= mu;
            }
        }
        if !converged {
            b.q_next.copy_from(&self.q_first);
            b.v_next.copy_from(&self.v_first);
            return Ok(false);
        }
        // At q₁: p₁ = p½ + h/2 (∂L/∂q(q₁, M₁⁻¹p½) + τ), then v₁ = M₁⁻¹p₁ onto the tangent space
        // (J₁ M₁⁻¹ J₁ᵀ μ = J₁ v₁, v₁ ← v₁ − M₁⁻¹J₁ᵀμ).
        self.factor_end(model)?;
        self.scratch.copy_from(&self.p_half);
        solve_mass_matrix_slice(model, &self.end, self.scratch.as_mut_slice());
        let (p1, force) = (self.p0.as_mut_slice(), self.force.as_mut_slice());
        momentum_and_lagrangian_force(
            model,
            &mut self.end,
            self.scratch.as_slice(),
            &mut self.weights,
            p1,
            force,
        );
        self.p0.copy_from(&self.p_half);
        self.p0.axpy(0.5 * h, &self.force, 1.0);
        self.p0.axpy(0.5 * h, &self.tau, 1.0);
        b.v_next.copy_from(&self.p0);
        solve_mass_matrix_slice(model, &self.end, b.v_next.as_mut_slice());
        projection.linearize(model, &self.end, closures);
        for i in 0..projection.builder.len() {
            projection.mu[i] = projection.builder.row_dot(i, b.v_next.as_slice());
        }
        projection.correction(nv);
        b.v_next += &projection.delta;
        compute_joint_jacobians(model, &mut b.data, &b.q_next)?;
        Ok(true)
    }
}
