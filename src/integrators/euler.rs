//! First-order schemes: explicit Euler (the baseline that gains energy) and semi-implicit
//! (symplectic) Euler, the world's scheme.

use super::chart::Chart;
use super::{check_step, Integrator, IntegratorError};
use crate::data::Data;
use crate::model::Model;
use crate::state::State;
use nalgebra::DVector;

/// Explicit (forward) Euler: `q₁ = q₀ ⊕ h v₀`, `v₁ = v₀ + h a(q₀, v₀)`. Order 1. Its energy
/// grows every step (for an oscillator by a factor 1 + (ωh)²), shown by a test; it is here as
/// the baseline to compare against.
#[derive(Clone, Debug)]
pub struct ExplicitEuler {
    chart: Chart,
    q_next: DVector<f64>,
}

impl ExplicitEuler {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        Self { chart: Chart::new(model), q_next: model.neutral_configuration() }
    }
}

impl Integrator for ExplicitEuler {
    fn name(&self) -> &'static str {
        "explicit-euler"
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
        check_step(model, self.chart.nq(), self.chart.nv(), h)?;
        let a = self.chart.acceleration(model, data, tau, &state.q, &state.v)?;
        model.integrate(&state.q, &state.v, h, &mut self.q_next);
        state.v.axpy(h, a, 1.0);
        state.q.copy_from(&self.q_next);
        state.t += h;
        Ok(())
    }
    fn evaluations(&self) -> u64 {
        self.chart.evaluations()
    }
}

/// Semi-implicit (symplectic) Euler: `v₁ = v₀ + h a(q₀, v₀)`, `q₁ = q₀ ⊕ h v₁`. Order 1.
/// Symplectic when the mass matrix is constant and the forces depend on q only (a spring: the
/// energy error stays bounded, O(h)); with a configuration-dependent mass matrix, as in any
/// pendulum chain, the energy still drifts, but far slower than with explicit Euler. The world's
/// time stepping is this scheme plus impulses.
#[derive(Clone, Debug)]
pub struct SemiImplicitEuler {
    chart: Chart,
    q_next: DVector<f64>,
}

impl SemiImplicitEuler {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        Self { chart: Chart::new(model), q_next: model.neutral_configuration() }
    }
}

impl Integrator for SemiImplicitEuler {
    fn name(&self) -> &'static str {
        "semi-implicit-euler"
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
        check_step(model, self.chart.nq(), self.chart.nv(), h)?;
        let a = self.chart.acceleration(model, data, tau, &state.q, &state.v)?;
        state.v.axpy(h, a, 1.0);
        model.integrate(&state.q, &state.v, h, &mut self.q_next);
        state.q.copy_from(&self.q_next);
        state.t += h;
        Ok(())
    }
    fn evaluations(&self) -> u64 {
        self.chart.evaluations()
    }
}
