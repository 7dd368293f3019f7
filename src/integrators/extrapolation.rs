//! Gragg–Bulirsch–Stoer extrapolation: Gragg's modified midpoint rule at n = 2, 4, 6, …
//! substeps, extrapolated to zero substep size in h² (Aitken–Neville), in the chart of each step.

use super::chart::Chart;
use super::{check_step, Integrator, IntegratorError};
use crate::data::Data;
use crate::model::Model;
use crate::state::State;
use nalgebra::DVector;

/// Gragg–Bulirsch–Stoer with a fixed number of columns K (substep sequence nⱼ = 2j,
/// Deuflhard's): order 2K, `1 + K(K+1)` ABA per step. With K = 6–8 and a millisecond step it
/// reaches rounding error on smooth multibodies: the reference of the speed–error report.
#[derive(Clone, Debug)]
pub struct GraggBulirschStoer {
    chart: Chart,
    columns: usize,
    y0: DVector<f64>,
    f0: DVector<f64>,
    f: DVector<f64>,
    z_prev: DVector<f64>,
    z: DVector<f64>,
    z_next: DVector<f64>,
    row_old: Vec<DVector<f64>>,
    row_new: Vec<DVector<f64>>,
}

impl GraggBulirschStoer {
    /// Buffers for `model`, `columns` extrapolation columns (at least 1; 1 is Gragg's rule alone,
    /// order 2).
    pub fn new(model: &Model, columns: usize) -> Self {
        let n = 2 * model.nv();
        let columns = columns.max(1);
        Self {
            chart: Chart::new(model),
            columns,
            y0: DVector::zeros(n),
            f0: DVector::zeros(n),
            f: DVector::zeros(n),
            z_prev: DVector::zeros(n),
            z: DVector::zeros(n),
            z_next: DVector::zeros(n),
            row_old: vec![DVector::zeros(n); columns],
            row_new: vec![DVector::zeros(n); columns],
        }
    }

    /// Number of extrapolation columns K.
    pub fn columns(&self) -> usize {
        self.columns
    }
}

impl Integrator for GraggBulirschStoer {
    fn name(&self) -> &'static str {
        "gbs"
    }
    fn order(&self) -> u32 {
        2 * self.columns as u32
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
        let nv = model.nv();
        self.chart.start(model, &state.q)?;
        self.chart.derivative_at_centre(model, data, tau, &state.v, &mut self.f0)?;
        self.y0.rows_mut(0, nv).fill(0.0);
        self.y0.rows_mut(nv, nv).copy_from(&state.v);
        for j in 0..self.columns {
            let n = 2 * (j + 1);
            let hs = h / n as f64;
            // Gragg: z₁ = z₀ + hs f(z₀), z_{m+1} = z_{m−1} + 2 hs f(z_m), then the smoothing step.
            self.z_prev.copy_from(&self.y0);
            self.z.copy_from(&self.y0);
            self.z.axpy(hs, &self.f0, 1.0);
            for _ in 1..n {
                self.chart.derivative(model, data, tau, &self.z, &mut self.f)?;
                self.z_next.copy_from(&self.z_prev);
                self.z_next.axpy(2.0 * hs, &self.f, 1.0);
                std::mem::swap(&mut self.z_prev, &mut self.z);
                std::mem::swap(&mut self.z, &mut self.z_next);
            }
            self.chart.derivative(model, data, tau, &self.z, &mut self.f)?;
            let t0 = &mut self.row_new[0];
            t0.copy_from(&self.z);
            *t0 += &self.z_prev;
            t0.axpy(hs, &self.f, 1.0);
            *t0 *= 0.5;
            // Aitken–Neville in h²: T_{j,l} = T_{j,l−1} + (T_{j,l−1} − T_{j−1,l−1}) / ((nⱼ/n_{j−l})² − 1).
            for l in 1..=j {
                let ratio = (n as f64 / (2 * (j + 1 - l)) as f64).powi(2);
                let (done, rest) = self.row_new.split_at_mut(l);
                let prev = &done[l - 1];
                rest[0].copy_from(prev);
                rest[0].axpy(1.0 / (ratio - 1.0), prev, 1.0);
                rest[0].axpy(-1.0 / (ratio - 1.0), &self.row_old[l - 1], 1.0);
            }
            std::mem::swap(&mut self.row_old, &mut self.row_new);
        }
        let last = &self.row_old[self.columns - 1];
        self.chart.point(model, last, &mut state.q, &mut state.v);
        state.t += h;
        Ok(())
    }
    fn evaluations(&self) -> u64 {
        self.chart.evaluations()
    }
}
