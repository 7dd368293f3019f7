//! Explicit Runge–Kutta schemes in the chart of each step (RKMK): classical RK4 and the
//! adaptive Dormand–Prince 5(4) pair.

use super::chart::Chart;
use super::{check_step, Integrator, IntegratorError};
use crate::data::Data;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::state::State;
use nalgebra::DVector;

/// `out = y0 + h Σⱼ aⱼ kⱼ` (a Runge–Kutta stage input or the step's result).
fn combine(y0: &DVector<f64>, h: f64, a: &[f64], k: &[DVector<f64>], out: &mut DVector<f64>) {
    out.copy_from(y0);
    for (aj, kj) in a.iter().zip(k) {
        if *aj != 0.0 {
            out.axpy(h * aj, kj, 1.0);
        }
    }
}

/// Buffers shared by the Runge–Kutta schemes: the chart, `y₀ = [0; v₀]`, stage derivatives,
/// a stage input and the result.
#[derive(Clone, Debug)]
struct Stages {
    chart: Chart,
    y0: DVector<f64>,
    k: Vec<DVector<f64>>,
    y: DVector<f64>,
    y1: DVector<f64>,
}

impl Stages {
    fn new(model: &Model, stages: usize) -> Self {
        let n = 2 * model.nv();
        Self {
            chart: Chart::new(model),
            y0: DVector::zeros(n),
            k: vec![DVector::zeros(n); stages],
            y: DVector::zeros(n),
            y1: DVector::zeros(n),
        }
    }

    /// Centres the chart at `state.q`; `k[0] = F(y₀)` unless `first_known` (FSAL).
    fn begin(
        &mut self,
        model: &Model,
        data: &mut Data,
        state: &State,
        tau: &DVector<f64>,
        first_known: bool,
    ) -> Result<(), DynamicsError> {
        self.chart.start(model, &state.q)?;
        if !first_known {
            self.chart.derivative_at_centre(model, data, tau, &state.v, &mut self.k[0])?;
        }
        let nv = model.nv();
        self.y0.rows_mut(0, nv).fill(0.0);
        self.y0.rows_mut(nv, nv).copy_from(&state.v);
        Ok(())
    }

    /// `k[i] = F(y₀ + h Σⱼ a[j] k[j])`.
    fn stage(
        &mut self,
        model: &Model,
        data: &mut Data,
        tau: &DVector<f64>,
        h: f64,
        a: &[f64],
        i: usize,
    ) -> Result<(), DynamicsError> {
        combine(&self.y0, h, a, &self.k[..i], &mut self.y);
        let (_, rest) = self.k.split_at_mut(i);
        self.chart.derivative(model, data, tau, &self.y, &mut rest[0])
    }
}

/// Classical fourth-order Runge–Kutta in the chart of each step. Order 4, 4 ABA per step.
#[derive(Clone, Debug)]
pub struct Rk4 {
    stages: Stages,
}

impl Rk4 {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        Self { stages: Stages::new(model, 4) }
    }
}

impl Integrator for Rk4 {
    fn name(&self) -> &'static str {
        "rk4"
    }
    fn order(&self) -> u32 {
        4
    }
    fn step(
        &mut self,
        model: &Model,
        data: &mut Data,
        state: &mut State,
        tau: &DVector<f64>,
        h: f64,
    ) -> Result<(), IntegratorError> {
        let s = &mut self.stages;
        check_step(model, s.chart.nq(), s.chart.nv(), h)?;
        s.begin(model, data, state, tau, false)?;
        s.stage(model, data, tau, h, &[0.5], 1)?;
        s.stage(model, data, tau, h, &[0.0, 0.5], 2)?;
        s.stage(model, data, tau, h, &[0.0, 0.0, 1.0], 3)?;
        combine(&s.y0, h, &[1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0], &s.k, &mut s.y1);
        s.chart.point(model, &s.y1, &mut state.q, &mut state.v);
        state.t += h;
        Ok(())
    }
    fn evaluations(&self) -> u64 {
        self.stages.chart.evaluations()
    }
}

/// Dormand–Prince 5(4) coefficients (Hairer, Nørsett & Wanner, Table II.5.2).
const DP_A: [&[f64]; 6] = [
    &[1.0 / 5.0],
    &[3.0 / 40.0, 9.0 / 40.0],
    &[44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0],
    &[19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0],
    &[9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0],
    &[35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0],
];
/// Fifth-order weights minus the embedded fourth-order ones: the local error estimate.
const DP_E: [f64; 7] =
    [71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0, 22.0 / 525.0, -1.0 / 40.0];

/// Counters of an adaptive integrator.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AdaptiveStats {
    /// Steps accepted.
    pub accepted: u64,
    /// Steps rejected (error above tolerance) and retried smaller.
    pub rejected: u64,
}

/// Adaptive Dormand–Prince 5(4) with error control: a step is accepted when
/// `‖e / (atol + rtol·max(|y₀|, |y₁|))‖_rms ≤ 1` on `y = [Θ; v]` of the step's chart (Θ starts
/// at 0, so the relative part of a coordinate's scale is the step's own displacement), else
/// rejected and retried with `h·max(0.2, 0.9·err^(−1/5))`; accepted steps grow by at most 5×.
/// Seven stages, the last one reused as the next step's first (FSAL): 6 ABA per accepted step.
/// [`Integrator::step`] advances to `t + h` exactly ([`DormandPrince45::advance_to`]), so `h`
/// is an output interval, not the internal step. Propagates the 5th-order solution (order 5).
#[derive(Clone, Debug)]
pub struct DormandPrince45 {
    stages: Stages,
    /// Relative tolerance.
    pub rtol: f64,
    /// Absolute tolerance (rad, m, rad/s, m/s).
    pub atol: f64,
    /// Next internal step to try (s); starts at 1 ms.
    pub h: f64,
    stats: AdaptiveStats,
    saved_q: DVector<f64>,
    saved_v: DVector<f64>,
    cached_q: DVector<f64>,
    cached_v: DVector<f64>,
    cached_tau: DVector<f64>,
    cache_valid: bool,
}

impl DormandPrince45 {
    /// Buffers for `model`, tolerances `rtol` and `atol`.
    pub fn new(model: &Model, rtol: f64, atol: f64) -> Self {
        let nv = model.nv();
        Self {
            stages: Stages::new(model, 7),
            rtol,
            atol,
            h: 1e-3,
            stats: AdaptiveStats::default(),
            saved_q: model.neutral_configuration(),
            saved_v: DVector::zeros(nv),
            cached_q: model.neutral_configuration(),
            cached_v: DVector::zeros(nv),
            cached_tau: DVector::zeros(nv),
            cache_valid: false,
        }
    }

    /// Accepted and rejected steps so far.
    pub fn stats(&self) -> AdaptiveStats {
        self.stats
    }

    /// Advances `state` to time `t_end` (s) with as many internal steps as the tolerances
    /// need, the last one shortened to land on `t_end`. On error the state is unchanged.
    pub fn advance_to(
        &mut self,
        model: &Model,
        data: &mut Data,
        state: &mut State,
        tau: &DVector<f64>,
        t_end: f64,
    ) -> Result<(), IntegratorError> {
        check_step(model, self.stages.chart.nq(), self.stages.chart.nv(), t_end - state.t)?;
        if state.q.len() != model.nq() || state.v.len() != model.nv() {
            let (what, expected, got) = if state.q.len() != model.nq() {
                ("q", model.nq(), state.q.len())
            } else {
                ("v", model.nv(), state.v.len())
            };
            return Err(DynamicsError::DimensionMismatch { what, expected, got }.into());
        }
        self.saved_q.copy_from(&state.q);
        self.saved_v.copy_from(&state.v);
        let t_start = state.t;
        let result = self.advance_inner(model, data, state, tau, t_end);
        if result.is_err() {
            state.q.copy_from(&self.saved_q);
            state.v.copy_from(&self.saved_v);
            state.t = t_start;
            self.cache_valid = false;
        }
        result
    }

    fn advance_inner(
        &mut self,
        model: &Model,
        data: &mut Data,
        state: &mut State,
        tau: &DVector<f64>,
        t_end: f64,
    ) -> Result<(), IntegratorError> {
        let nv = model.nv();
        while state.t < t_end {
            let remaining = t_end - state.t;
            let last = self.h >= remaining;
            let h = if last { remaining } else { self.h };
            if h.is_nan() || h <= 1e-14 * state.t.abs().max(1.0) {
                return Err(IntegratorError::StepSizeUnderflow { t: state.t, h });
            }
            let first_known = self.cache_valid
                && state.q == self.cached_q
                && state.v == self.cached_v
                && *tau == self.cached_tau;
            let s = &mut self.stages;
            s.begin(model, data, state, tau, first_known)?;
            // A trial step so large that a stage leaves the dynamics' domain (a non-finite state)
            // is rejected like any other; the first stage, at the accepted state, is not a trial.
            let mut failed = false;
            for (i, a) in DP_A.iter().enumerate() {
                if let Err(e) = s.stage(model, data, tau, h, a, i + 1) {
                    match e {
                        DynamicsError::NonFinite { .. } => {
                            failed = true;
                            break;
                        }
                        other => return Err(other.into()),
                    }
                }
            }
            if failed {
                self.stats.rejected += 1;
                self.h = 0.2 * h;
                continue;
            }
            // The 7th stage was evaluated at y₁ = y₀ + h Σ a₇ⱼ kⱼ (the 5th-order solution).
            combine(&s.y0, h, DP_A[5], &s.k, &mut s.y1);
            let mut err_sq = 0.0;
            for i in 0..2 * nv {
                let e: f64 = h * DP_E.iter().zip(&s.k).map(|(ej, kj)| ej * kj[i]).sum::<f64>();
                let scale = self.atol + self.rtol * s.y0[i].abs().max(s.y1[i].abs());
                err_sq += (e / scale).powi(2);
            }
            let mut err = (err_sq / (2 * nv).max(1) as f64).sqrt();
            if !err.is_finite() {
                err = 1e10;
            }
            let factor = (0.9 * err.powf(-0.2)).clamp(0.2, 5.0);
            if err <= 1.0 {
                s.chart.point(model, &s.y1, &mut state.q, &mut state.v);
                state.t = if last { t_end } else { state.t + h };
                // FSAL: k₇'s acceleration is a(q₁, v₁); its Θ̇ part is recomputed as v₁.
                let (first, rest) = s.k.split_at_mut(1);
                first[0].rows_mut(nv, nv).copy_from(&rest[5].rows(nv, nv));
                s.k[0].rows_mut(0, nv).copy_from(&state.v);
                self.cached_q.copy_from(&state.q);
                self.cached_v.copy_from(&state.v);
                self.cached_tau.copy_from(tau);
                self.cache_valid = true;
                self.stats.accepted += 1;
                // A step shortened to land on t_end says nothing about the natural step size.
                self.h = if last { self.h.max(h * factor) } else { h * factor };
            } else {
                self.stats.rejected += 1;
                self.h = h * factor.min(1.0);
            }
        }
        Ok(())
    }
}

impl Integrator for DormandPrince45 {
    fn name(&self) -> &'static str {
        "dopri45"
    }
    fn order(&self) -> u32 {
        5
    }
    fn step(
        &mut self,
        model: &Model,
        data: &mut Data,
        state: &mut State,
        tau: &DVector<f64>,
        h: f64,
    ) -> Result<(), IntegratorError> {
        let t_end = state.t + h;
        self.advance_to(model, data, state, tau, t_end)
    }
    fn evaluations(&self) -> u64 {
        self.stages.chart.evaluations()
    }
}
