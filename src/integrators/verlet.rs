//! Leapfrog / velocity Verlet (kick–drift–kick) on the manifold.

use super::chart::Chart;
use super::{check_step, Integrator, IntegratorError};
use crate::data::Data;
use crate::model::Model;
use crate::state::State;
use nalgebra::DVector;

/// Velocity Verlet (Störmer–Verlet, kick–drift–kick): `v½ = v₀ + ½h a(q₀, v₀)`,
/// `q₁ = q₀ ⊕ h v½`, `v₁ = v½ + ½h a(q₁, v₁)`. Order 2. Multibody accelerations depend on the
/// velocity (Coriolis, gyroscopic terms), so the closing kick is implicit in v₁; it is evaluated
/// at the explicit predictor `ṽ₁ = v½ + ½h (2a₀ − a₋₁)` (the opening accelerations of this and
/// the previous step extrapolated; `v½ + ½h a₀` on a first step), within O(h³) of v₁, so order 2
/// holds. For forces that depend on q only this is exactly velocity Verlet. The closing
/// acceleration is reused for the next opening kick while the state is the one this scheme left,
/// so a step costs 1 ABA.
#[derive(Clone, Debug)]
pub struct VelocityVerlet {
    chart: Chart,
    a0: DVector<f64>,
    /// The previous step's opening acceleration, and that step's size.
    a_prev: DVector<f64>,
    h_prev: f64,
    prev_valid: bool,
    v_half: DVector<f64>,
    v_pred: DVector<f64>,
    q_next: DVector<f64>,
    /// The state and forces the cached closing acceleration `a0` was computed for.
    cached_q: DVector<f64>,
    cached_v: DVector<f64>,
    cached_tau: DVector<f64>,
    cache_valid: bool,
}

impl VelocityVerlet {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        let nv = model.nv();
        Self {
            chart: Chart::new(model),
            a0: DVector::zeros(nv),
            a_prev: DVector::zeros(nv),
            h_prev: 0.0,
            prev_valid: false,
            v_half: DVector::zeros(nv),
            v_pred: DVector::zeros(nv),
            q_next: model.neutral_configuration(),
            cached_q: model.neutral_configuration(),
            cached_v: DVector::zeros(nv),
            cached_tau: DVector::zeros(nv),
            cache_valid: false,
        }
    }
}

impl Integrator for VelocityVerlet {
    fn name(&self) -> &'static str {
        "velocity-verlet"
    }
    fn order(&self) -> u32 {
        2
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
        let cached = self.cache_valid
            && state.q == self.cached_q
            && state.v == self.cached_v
            && *tau == self.cached_tau;
        self.cache_valid = false;
        if !cached {
            let a = self.chart.acceleration(model, data, tau, &state.q, &state.v)?;
            self.a0.copy_from(a);
        }
        self.v_half.copy_from(&state.v);
        self.v_half.axpy(0.5 * h, &self.a0, 1.0);
        model.integrate(&state.q, &self.v_half, h, &mut self.q_next);
        self.v_pred.copy_from(&self.v_half);
        if cached && self.prev_valid && self.h_prev == h {
            // a(t₁) ≈ 2 a₀ − a₋₁ to O(h²): the predictor is then within O(h³) of v₁.
            self.v_pred.axpy(h, &self.a0, 1.0);
            self.v_pred.axpy(-0.5 * h, &self.a_prev, 1.0);
        } else {
            self.v_pred.axpy(0.5 * h, &self.a0, 1.0);
        }
        self.a_prev.copy_from(&self.a0);
        self.prev_valid = true;
        self.h_prev = h;
        let a = self.chart.acceleration(model, data, tau, &self.q_next, &self.v_pred)?;
        self.a0.copy_from(a);
        state.v.copy_from(&self.v_half);
        state.v.axpy(0.5 * h, &self.a0, 1.0);
        state.q.copy_from(&self.q_next);
        state.t += h;
        self.cached_q.copy_from(&state.q);
        self.cached_v.copy_from(&state.v);
        self.cached_tau.copy_from(tau);
        self.cache_valid = true;
        Ok(())
    }
    fn evaluations(&self) -> u64 {
        self.chart.evaluations()
    }
}
