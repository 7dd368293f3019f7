//! Explicit Runge–Kutta schemes in the chart of each step (RKMK): classical RK4, Butcher's RK6,
//! the eighth-order Dormand–Prince method with a fixed step, and the adaptive Dormand–Prince 5(4)
//! pair.

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

/// An explicit Runge–Kutta method: the rows of its Butcher matrix below the diagonal (row i
/// gives stage i + 1 from stages 0…i) and its weights.
struct Tableau {
    a: &'static [&'static [f64]],
    b: &'static [f64],
}

/// One step of an explicit tableau in the chart of `state.q` (RKMK).
fn tableau_step(
    s: &mut Stages,
    tableau: &Tableau,
    model: &Model,
    data: &mut Data,
    state: &mut State,
    tau: &DVector<f64>,
    h: f64,
) -> Result<(), IntegratorError> {
    check_step(model, s.chart.nq(), s.chart.nv(), h)?;
    s.begin(model, data, state, tau, false)?;
    for (i, a) in tableau.a.iter().enumerate() {
        s.stage(model, data, tau, h, a, i + 1)?;
    }
    combine(&s.y0, h, tableau.b, &s.k, &mut s.y1);
    s.chart.point(model, &s.y1, &mut state.q, &mut state.v);
    state.t += h;
    Ok(())
}

/// Classical fourth-order Runge–Kutta.
const RK4: Tableau =
    Tableau { a: &[&[0.5], &[0.0, 0.5], &[0.0, 0.0, 1.0]], b: &[1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0] };

/// Butcher's sixth-order method with seven stages (Butcher 1964; Butcher, *Numerical Methods
/// for Ordinary Differential Equations*, 2016, §324), nodes 0, ⅓, ⅔, ⅓, ½, ½, 1.
const RK6: Tableau = Tableau {
    a: &[
        &[1.0 / 3.0],
        &[0.0, 2.0 / 3.0],
        &[1.0 / 12.0, 1.0 / 3.0, -1.0 / 12.0],
        &[-1.0 / 16.0, 9.0 / 8.0, -3.0 / 16.0, -3.0 / 8.0],
        &[0.0, 9.0 / 8.0, -3.0 / 8.0, -3.0 / 4.0, 1.0 / 2.0],
        &[9.0 / 44.0, -9.0 / 11.0, 63.0 / 44.0, 18.0 / 11.0, 0.0, -16.0 / 11.0],
    ],
    b: &[11.0 / 120.0, 0.0, 27.0 / 40.0, 27.0 / 40.0, -4.0 / 15.0, -4.0 / 15.0, 11.0 / 120.0],
};

/// The eighth-order solution of Dormand and Prince's DOP853 (Hairer, Nørsett & Wanner,
/// *Solving ODEs I*, §II.10; the coefficients of Hairer's `dop853.f`): twelve stages.
#[allow(clippy::excessive_precision)]
const RK8: Tableau = Tableau {
    a: &[
        &[5.26001519587677318785587544488e-2],
        &[1.97250569845378994544595329183e-2, 5.91751709536136983633785987549e-2],
        &[2.95875854768068491816892993775e-2, 0.0, 8.87627564304205475450678981324e-2],
        &[
            2.41365134159266685502369798665e-1,
            0.0,
            -8.84549479328286085344864962717e-1,
            9.24834003261792003115737966543e-1,
        ],
        &[
            3.7037037037037037037037037037e-2,
            0.0,
            0.0,
            1.70828608729473871279604482173e-1,
            1.25467687566822425016691814123e-1,
        ],
        &[
            3.7109375e-2,
            0.0,
            0.0,
            1.70252211019544039314978060272e-1,
            6.02165389804559606850219397283e-2,
            -1.7578125e-2,
        ],
        &[
            3.70920001185047927108779319836e-2,
            0.0,
            0.0,
            1.70383925712239993810214054705e-1,
            1.07262030446373284651809199168e-1,
            -1.53194377486244017527936158236e-2,
            8.27378916381402288758473766002e-3,
        ],
        &[
            6.24110958716075717114429577812e-1,
            0.0,
            0.0,
            -3.36089262944694129406857109825e0,
            -8.68219346841726006818189891453e-1,
            2.75920996994467083049415600797e1,
            2.01540675504778934086186788979e1,
            -4.34898841810699588477366255144e1,
        ],
        &[
            4.77662536438264365890433908527e-1,
            0.0,
            0.0,
            -2.48811461997166764192642586468e0,
            -5.90290826836842996371446475743e-1,
            2.12300514481811942347288949897e1,
            1.52792336328824235832596922938e1,
            -3.32882109689848629194453265587e1,
            -2.03312017085086261358222928593e-2,
        ],
        &[
            -9.3714243008598732571704021658e-1,
            0.0,
            0.0,
            5.18637242884406370830023853209e0,
            1.09143734899672957818500254654e0,
            -8.14978701074692612513997267357e0,
            -1.85200656599969598641566180701e1,
            2.27394870993505042818970056734e1,
            2.49360555267965238987089396762e0,
            -3.0467644718982195003823669022e0,
        ],
        &[
            2.27331014751653820792359768449e0,
            0.0,
            0.0,
            -1.05344954667372501984066689879e1,
            -2.00087205822486249909675718444e0,
            -1.79589318631187989172765950534e1,
            2.79488845294199600508499808837e1,
            -2.85899827713502369474065508674e0,
            -8.87285693353062954433549289258e0,
            1.23605671757943030647266201528e1,
            6.43392746015763530355970484046e-1,
        ],
    ],
    b: &[
        5.42937341165687622380535766363e-2,
        0.0,
        0.0,
        0.0,
        0.0,
        4.45031289275240888144113950566e0,
        1.89151789931450038304281599044e0,
        -5.8012039600105847814672114227e0,
        3.1116436695781989440891606237e-1,
        -1.52160949662516078556178806805e-1,
        2.01365400804030348374776537501e-1,
        4.47106157277725905176885569043e-2,
    ],
};

/// A fixed-step explicit Runge–Kutta method given by its tableau: the type, its constructor and
/// its [`Integrator`] implementation (`tableau_step` does the work).
macro_rules! fixed_step_runge_kutta {
    ($(#[$doc:meta])* $name:ident, $label:literal, order $order:literal, $tableau:ident, stages $stages:literal) => {
        $(#[$doc])*
        #[derive(Clone, Debug)]
        pub struct $name {
            stages: Stages,
        }

        impl $name {
            /// Buffers for `model`.
            pub fn new(model: &Model) -> Self {
                Self { stages: Stages::new(model, $stages) }
            }
        }

        impl Integrator for $name {
            fn name(&self) -> &'static str {
                $label
            }
            fn order(&self) -> u32 {
                $order
            }
            fn step(
                &mut self,
                model: &Model,
                data: &mut Data,
                state: &mut State,
                tau: &DVector<f64>,
                h: f64,
            ) -> Result<(), IntegratorError> {
                tableau_step(&mut self.stages, &$tableau, model, data, state, tau, h)
            }
            fn evaluations(&self) -> u64 {
                self.stages.chart.evaluations()
            }
        }
    };
}

fixed_step_runge_kutta!(
    /// Classical fourth-order Runge–Kutta in the chart of each step. Order 4, 4 ABA per step.
    Rk4, "rk4", order 4, RK4, stages 4
);

fixed_step_runge_kutta!(
    /// Butcher's sixth-order Runge–Kutta (7 stages) in the chart of each step. Order 6, 7 ABA per
    /// step: at the same cost it reaches errors RK4 needs about twice the work for, once the step
    /// resolves the motion.
    Rk6, "rk6", order 6, RK6, stages 7
);

fixed_step_runge_kutta!(
    /// The eighth-order Dormand–Prince method (DOP853's propagated solution, 12 stages) with a
    /// fixed step, in the chart of each step. Order 8, 12 ABA per step.
    Rk8, "rk8", order 8, RK8, stages 12
);

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
                        DynamicsError::NonFinite { .. } | DynamicsError::NonFiniteResult { .. } => {
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
