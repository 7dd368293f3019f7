//! Integrators for the smooth dynamics of one multibody (no contact): `q̈ = aba(q, v, τ + τ_p)`
//! with the passive joint forces `τ_p` (joint damping, hinge2 suspension springs).
//!
//! Every scheme moves on the configuration manifold: a step starts a chart at `q₀` and works with
//! `y = [Θ; v]`, `q = q₀ ⊕ Θ` ([`Model::integrate`]), `Θ̇ = dexp⁻¹₋Θ(v)`
//! ([`crate::model::Joint::chart_rate`]), `v̇ = aba(q₀ ⊕ Θ, v, τ)` (Munthe-Kaas' RKMK). Stages
//! therefore combine tangent vectors, never raw quaternions, and a step ends with one
//! `q₁ = q₀ ⊕ Θ₁`, so quaternions stay unit and the classical orders hold.
//!
//! | integrator | order | dynamics evaluations per step | notes |
//! |---|---|---|---|
//! | [`ExplicitEuler`] | 1 | 1 ABA | the baseline: energy grows |
//! | [`SemiImplicitEuler`] | 1 | 1 ABA | symplectic for conservative forces; the world's scheme |
//! | [`VelocityVerlet`] | 2 | 1 ABA | leapfrog, kick–drift–kick |
//! | [`Rk4`] | 4 | 4 ABA | classical Runge–Kutta |
//! | [`Rk6`] | 6 | 7 ABA | Butcher's sixth-order method |
//! | [`Rk8`] | 8 | 12 ABA | DOP853's eighth-order solution, fixed step |
//! | [`DormandPrince45`] | 5 (4 embedded) | 6 ABA per accepted step | adaptive, step-to-time |
//! | [`GraggBulirschStoer`] | 2·columns | 1 + Σ nⱼ ABA | extrapolated midpoint, references |
//! | [`ImplicitEuler`] | 1 | CRBA + RNEA + factorization | implicit in v for damping and springs (MuJoCo's `implicitfast`) |
//!
//! Each integrator owns its buffers, sized for one model at construction; a step allocates
//! nothing.

mod chart;
mod euler;
mod extrapolation;
pub mod implicit;
mod runge_kutta;
mod verlet;

pub use chart::Chart;
pub use euler::{ExplicitEuler, SemiImplicitEuler};
pub use extrapolation::GraggBulirschStoer;
pub use implicit::{ImplicitEuler, ImplicitTerms};
pub use runge_kutta::{AdaptiveStats, DormandPrince45, Rk4, Rk6, Rk8};
pub use verlet::VelocityVerlet;

use crate::data::Data;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::state::State;
use nalgebra::DVector;
use thiserror::Error;

/// Why an integration step failed. The state is left as it was before the step.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum IntegratorError {
    /// The dynamics failed (bad state, NaN, singular mass matrix).
    #[error(transparent)]
    Dynamics(#[from] DynamicsError),
    /// The step is not a positive finite number of seconds.
    #[error("the time step must be positive and finite, got {0}")]
    BadStep(f64),
    /// The integrator's buffers were sized for another model.
    #[error("the integrator was built for a model with nq = {expected_nq}, nv = {expected_nv}, not nq = {nq}, nv = {nv}")]
    ModelMismatch {
        /// nq of the model the integrator was built for.
        expected_nq: usize,
        /// nv of that model.
        expected_nv: usize,
        /// nq of the model given.
        nq: usize,
        /// nv of the model given.
        nv: usize,
    },
    /// The adaptive step size fell below what double precision can resolve at time `t`.
    #[error("step size underflow at t = {t} s (h = {h} s): the tolerances cannot be met")]
    StepSizeUnderflow {
        /// Time reached (s).
        t: f64,
        /// Step size tried (s).
        h: f64,
    },
}

/// A time-stepping scheme for `q̈ = aba(q, v, τ + τ_p)`. `Send`, as [`crate::solvers::ConstraintSolver`]:
/// a world holding integrators can be stepped on another thread.
pub trait Integrator: Send {
    /// Short name, e.g. `"rk4"`.
    fn name(&self) -> &'static str;
    /// Order of convergence p: the global error at a fixed time shrinks as hᵖ.
    fn order(&self) -> u32;
    /// Advances `state` by `h` seconds (q, v and t) under the joint forces `tau` (N·m or N,
    /// length nv), held constant over the step. Adaptive schemes take as many internal steps as
    /// their tolerances need and stop exactly at `t + h`. On error the state is unchanged.
    fn step(
        &mut self,
        model: &Model,
        data: &mut Data,
        state: &mut State,
        tau: &DVector<f64>,
        h: f64,
    ) -> Result<(), IntegratorError>;
    /// Number of dynamics evaluations (ABA calls, or CRBA factorizations for the implicit
    /// scheme) since construction: the cost model behind the measured times.
    fn evaluations(&self) -> u64;
}

/// The integrators by name, for command lines and reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum IntegratorKind {
    /// [`ExplicitEuler`].
    ExplicitEuler,
    /// [`SemiImplicitEuler`].
    SemiImplicitEuler,
    /// [`VelocityVerlet`].
    VelocityVerlet,
    /// [`Rk4`].
    Rk4,
    /// [`Rk6`].
    Rk6,
    /// [`Rk8`].
    Rk8,
    /// [`DormandPrince45`] with relative tolerance `rtol` and absolute tolerance `atol`.
    DormandPrince45 {
        /// Relative tolerance.
        rtol: f64,
        /// Absolute tolerance (rad, m, rad/s, m/s).
        atol: f64,
    },
    /// [`GraggBulirschStoer`] with this many extrapolation columns.
    GraggBulirschStoer {
        /// Columns (order 2·columns).
        columns: usize,
    },
    /// [`ImplicitEuler`].
    ImplicitEuler,
}

impl IntegratorKind {
    /// Builds the integrator with buffers for `model`.
    pub fn build(&self, model: &Model) -> Box<dyn Integrator> {
        match *self {
            IntegratorKind::ExplicitEuler => Box::new(ExplicitEuler::new(model)),
            IntegratorKind::SemiImplicitEuler => Box::new(SemiImplicitEuler::new(model)),
            IntegratorKind::VelocityVerlet => Box::new(VelocityVerlet::new(model)),
            IntegratorKind::Rk4 => Box::new(Rk4::new(model)),
            IntegratorKind::Rk6 => Box::new(Rk6::new(model)),
            IntegratorKind::Rk8 => Box::new(Rk8::new(model)),
            IntegratorKind::DormandPrince45 { rtol, atol } => {
                Box::new(DormandPrince45::new(model, rtol, atol))
            }
            IntegratorKind::GraggBulirschStoer { columns } => {
                Box::new(GraggBulirschStoer::new(model, columns))
            }
            IntegratorKind::ImplicitEuler => Box::new(ImplicitEuler::new(model)),
        }
    }

    /// Display label, with the tolerance or columns where they matter.
    pub fn label(&self) -> String {
        match *self {
            IntegratorKind::ExplicitEuler => "explicit Euler".to_string(),
            IntegratorKind::SemiImplicitEuler => "semi-implicit Euler".to_string(),
            IntegratorKind::VelocityVerlet => "velocity Verlet".to_string(),
            IntegratorKind::Rk4 => "RK4".to_string(),
            IntegratorKind::Rk6 => "RK6".to_string(),
            IntegratorKind::Rk8 => "RK8".to_string(),
            IntegratorKind::DormandPrince45 { rtol, .. } => format!("DOPRI45 rtol={rtol:.0e}"),
            IntegratorKind::GraggBulirschStoer { columns } => format!("GBS {columns} columns"),
            IntegratorKind::ImplicitEuler => "implicit Euler".to_string(),
        }
    }
}

/// Checks the step and that the buffers of an integrator built for (nq, nv) fit `model`.
pub(crate) fn check_step(model: &Model, nq: usize, nv: usize, h: f64) -> Result<(), IntegratorError> {
    if model.nq() != nq || model.nv() != nv {
        return Err(IntegratorError::ModelMismatch {
            expected_nq: nq,
            expected_nv: nv,
            nq: model.nq(),
            nv: model.nv(),
        });
    }
    if !(h.is_finite() && h > 0.0) {
        return Err(IntegratorError::BadStep(h));
    }
    Ok(())
}
