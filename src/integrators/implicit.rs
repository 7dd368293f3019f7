//! Joint damping and hinge2 suspension springs, and the scheme that treats them implicitly in
//! the velocity (MuJoCo's `implicitfast`): `(M + h D + h² K) Δv = h (τ − C v − g − D v − K s)`.
//! The world's free-motion phase uses the same function.

use super::{check_step, Integrator, IntegratorError};
use crate::algorithms::{
    crba, factor_packed_mass_matrix, nonlinear_effects, pack_mass_matrix, solve_mass_matrix_slice,
};
use crate::data::Data;
use crate::error::DynamicsError;
use crate::model::{Joint, Model};
use crate::state::State;
use nalgebra::DVector;

/// The passive joint forces of a model: joint damping `D = diag(model.damping())` and the
/// hinge2 suspensions (travel s, stiffness k, damping c).
#[derive(Clone, Debug, PartialEq)]
pub struct ImplicitTerms {
    /// Suspension dofs: (q index, v index, stiffness k in N/m, damping c in N·s/m).
    suspensions: Vec<(usize, usize, f64, f64)>,
    has_damping: bool,
}

impl ImplicitTerms {
    /// The terms of `model`.
    pub fn new(model: &Model) -> Self {
        let suspensions = (1..model.nbodies())
            .filter_map(|i| match model.joint(i) {
                Joint::Hinge2 { suspension: Some(s), .. } => {
                    Some((model.idx_q(i), model.idx_v(i), s.stiffness, s.damping))
                }
                _ => None,
            })
            .collect();
        Self { suspensions, has_damping: model.damping().iter().any(|d| *d > 0.0) }
    }

    /// True when the model has neither joint damping nor suspension springs.
    pub fn is_empty(&self) -> bool {
        self.suspensions.is_empty() && !self.has_damping
    }

    /// `out −= K (s + h v) + c ṡ + D v`: the passive forces, with the spring evaluated `h`
    /// seconds ahead (h = 0 for the explicit forces; the step for the implicit scheme, whose
    /// h² K part then moves to the left side).
    pub fn subtract_passive_forces(
        &self,
        model: &Model,
        q: &DVector<f64>,
        v: &DVector<f64>,
        h: f64,
        out: &mut DVector<f64>,
    ) {
        for &(iq, iv, k, c) in &self.suspensions {
            out[iv] -= k * (q[iq] + h * v[iv]) + c * v[iv];
        }
        if self.has_damping {
            for (k, d) in model.damping().iter().enumerate() {
                out[k] -= d * v[k];
            }
        }
    }
}

/// The velocity after one step implicit in damping and springs:
/// `v_out = v + h M̃⁻¹ (τ − C v − g − D v − K (s + h v) − c ṡ)`, `M̃ = M + h D + h (c + h k)` on the
/// suspension dofs. On entry `rhs` holds the applied joint forces τ (N·m or N); on exit it holds
/// the acceleration `(v_out − v)/h`. Leaves M in `data.mass_matrix` and the factor of `M̃` in
/// `data` (for the world's constraint rows).
#[allow(clippy::too_many_arguments)]
pub fn implicit_free_velocity(
    model: &Model,
    data: &mut Data,
    terms: &ImplicitTerms,
    q: &DVector<f64>,
    v: &DVector<f64>,
    h: f64,
    rhs: &mut DVector<f64>,
    v_out: &mut DVector<f64>,
) -> Result<(), DynamicsError> {
    // Dynamics first: they check the lengths and finiteness of q and v.
    crba(model, data, q)?;
    pack_mass_matrix(model, data);
    nonlinear_effects(model, data, q, v)?;
    implicit_velocity_from_dynamics(model, data, terms, q, v, h, rhs, v_out, true)
}

/// The rest of [`implicit_free_velocity`] once `data` holds M's packed rows
/// (`data.factor_packed`) and the bias forces (`data.nle`) at (q, v): the world's step computes
/// those from its kinematics phase ([`crate::algorithms::crba_packed_at_kinematics`]) and calls
/// this directly. With `factor` false, `data` already holds the factor of M + h·D (the world's
/// reuse of a resting multibody's factor) and only the solve runs.
#[allow(clippy::too_many_arguments)]
pub(crate) fn implicit_velocity_from_dynamics(
    model: &Model,
    data: &mut Data,
    terms: &ImplicitTerms,
    q: &DVector<f64>,
    v: &DVector<f64>,
    h: f64,
    rhs: &mut DVector<f64>,
    v_out: &mut DVector<f64>,
    factor: bool,
) -> Result<(), DynamicsError> {
    if rhs.len() != model.nv() {
        return Err(DynamicsError::DimensionMismatch { what: "tau", expected: model.nv(), got: rhs.len() });
    }
    terms.subtract_passive_forces(model, q, v, h, rhs);
    *rhs -= &data.nle;
    if factor {
        // M_kk is the last entry of dof k's packed row.
        let diagonal = |k: usize| model.dof_path_start[k + 1] + k;
        for (k, d) in model.damping().iter().enumerate() {
            data.factor_packed[diagonal(k)] += h * d;
        }
        for &(_, iv, k, c) in &terms.suspensions {
            data.factor_packed[diagonal(iv)] += h * c + h * h * k;
        }
        factor_packed_mass_matrix(model, data)?;
    }
    solve_mass_matrix_slice(model, data, rhs.as_mut_slice());
    v_out.copy_from(v);
    v_out.axpy(h, rhs, 1.0);
    Ok(())
}

/// Euler implicit in the velocity for damping and springs, explicit in the other forces
/// (MuJoCo's `implicitfast`): `v₁` from [`implicit_free_velocity`], then `q₁ = q₀ ⊕ h v₁`.
/// Order 1; stable for stiff suspension springs and strong damping at any step.
#[derive(Clone, Debug)]
pub struct ImplicitEuler {
    terms: ImplicitTerms,
    rhs: DVector<f64>,
    v_next: DVector<f64>,
    q_next: DVector<f64>,
    evaluations: u64,
}

impl ImplicitEuler {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        Self {
            terms: ImplicitTerms::new(model),
            rhs: DVector::zeros(model.nv()),
            v_next: DVector::zeros(model.nv()),
            q_next: model.neutral_configuration(),
            evaluations: 0,
        }
    }
}

impl Integrator for ImplicitEuler {
    fn name(&self) -> &'static str {
        "implicit-euler"
    }

    fn order(&self) -> u32 {
        1
    }

    fn step(
        &mut self,
        model: &Model,
        data: &mut Data,
        state: &mut State,
        tau: &DVector<f64>,
        h: f64,
    ) -> Result<(), IntegratorError> {
        check_step(model, self.q_next.len(), self.v_next.len(), h)?;
        if tau.len() != model.nv() {
            return Err(DynamicsError::DimensionMismatch {
                what: "tau",
                expected: model.nv(),
                got: tau.len(),
            }
            .into());
        }
        self.rhs.copy_from(tau);
        self.evaluations += 1;
        implicit_free_velocity(
            model,
            data,
            &self.terms,
            &state.q,
            &state.v,
            h,
            &mut self.rhs,
            &mut self.v_next,
        )?;
        model.integrate(&state.q, &self.v_next, h, &mut self.q_next);
        state.q.copy_from(&self.q_next);
        state.v.copy_from(&self.v_next);
        state.t += h;
        Ok(())
    }

    fn evaluations(&self) -> u64 {
        self.evaluations
    }
}
