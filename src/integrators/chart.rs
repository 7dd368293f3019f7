//! The chart of one step: `q = q₀ ⊕ Θ`, and the smooth dynamics written in it,
//! `ẏ = F(y)` for `y = [Θ; v]`: `Θ̇ = dexp⁻¹₋Θ(v)`, `v̇ = aba(q₀ ⊕ Θ, v, τ + τ_p(q, v))`.

use super::implicit::ImplicitTerms;
use crate::algorithms::aba;
use crate::data::Data;
use crate::error::DynamicsError;
use crate::model::{Joint, Model};
use nalgebra::DVector;

/// A chart at `q₀` with the buffers to evaluate the dynamics in it (allocated once).
#[derive(Clone, Debug)]
pub struct Chart {
    q0: DVector<f64>,
    q: DVector<f64>,
    theta: DVector<f64>,
    v: DVector<f64>,
    tau: DVector<f64>,
    terms: ImplicitTerms,
    /// Every joint's configuration space is a vector space (hinges, sliders, universal, hinge2):
    /// `q₀ ⊕ Θ = q₀ + Θ` and `Θ̇ = v` exactly, so the chart needs neither the per-joint
    /// exponential map nor dexp⁻¹.
    euclidean: bool,
    evaluations: u64,
}

impl Chart {
    /// Buffers for `model`; the chart starts at the neutral configuration.
    pub fn new(model: &Model) -> Self {
        let nv = model.nv();
        Self {
            q0: model.neutral_configuration(),
            q: model.neutral_configuration(),
            theta: DVector::zeros(nv),
            v: DVector::zeros(nv),
            tau: DVector::zeros(nv),
            terms: ImplicitTerms::new(model),
            euclidean: (1..model.nbodies())
                .all(|i| !matches!(model.joint(i), Joint::Ball | Joint::Free | Joint::Planar)),
            evaluations: 0,
        }
    }

    /// nq of the model the chart was built for.
    pub fn nq(&self) -> usize {
        self.q0.len()
    }

    /// nv of the model the chart was built for.
    pub fn nv(&self) -> usize {
        self.v.len()
    }

    /// Number of ABA calls made so far.
    pub fn evaluations(&self) -> u64 {
        self.evaluations
    }

    /// Centres the chart at `q0` (length nq, checked).
    pub fn start(&mut self, model: &Model, q0: &DVector<f64>) -> Result<(), DynamicsError> {
        if q0.len() != model.nq() {
            return Err(DynamicsError::DimensionMismatch { what: "q", expected: model.nq(), got: q0.len() });
        }
        self.q0.copy_from(q0);
        Ok(())
    }

    /// The generalized acceleration `aba(q, v, τ + τ_p(q, v))` (m/s², rad/s²) with the passive
    /// joint forces τ_p (damping, suspension springs), written to `data.ddq`.
    pub fn acceleration<'d>(
        &mut self,
        model: &Model,
        data: &'d mut Data,
        tau: &DVector<f64>,
        q: &DVector<f64>,
        v: &DVector<f64>,
    ) -> Result<&'d DVector<f64>, DynamicsError> {
        if tau.len() != model.nv() {
            return Err(DynamicsError::DimensionMismatch {
                what: "tau",
                expected: model.nv(),
                got: tau.len(),
            });
        }
        if q.len() != model.nq() {
            return Err(DynamicsError::DimensionMismatch { what: "q", expected: model.nq(), got: q.len() });
        }
        if v.len() != model.nv() {
            return Err(DynamicsError::DimensionMismatch { what: "v", expected: model.nv(), got: v.len() });
        }
        self.evaluations += 1;
        if self.terms.is_empty() {
            return aba(model, data, q, v, tau);
        }
        self.tau.copy_from(tau);
        self.terms.subtract_passive_forces(model, q, v, 0.0, &mut self.tau);
        aba(model, data, q, v, &self.tau)
    }

    /// `dy = F(y)` at `y = [Θ; v]` (length 2·nv) in this chart.
    pub fn derivative(
        &mut self,
        model: &Model,
        data: &mut Data,
        tau: &DVector<f64>,
        y: &DVector<f64>,
        dy: &mut DVector<f64>,
    ) -> Result<(), DynamicsError> {
        let nv = model.nv();
        self.v.copy_from(&y.rows(nv, nv));
        if self.euclidean && y.len() == 2 * self.q.len() {
            for ((q, q0), theta) in self.q.iter_mut().zip(&self.q0).zip(y.rows(0, nv).iter()) {
                *q = q0 + theta;
            }
            dy.rows_mut(0, nv).copy_from(&self.v);
        } else {
            self.theta.copy_from(&y.rows(0, nv));
            model.integrate(&self.q0, &self.theta, 1.0, &mut self.q);
            self.chart_rates(model, dy);
        }
        let (q, v) = (std::mem::take(&mut self.q), std::mem::take(&mut self.v));
        let result = self.acceleration(model, data, tau, &q, &v).map(|a| dy.rows_mut(nv, nv).copy_from(a));
        self.q = q;
        self.v = v;
        result
    }

    /// `dy[..nv] = dexp⁻¹₋Θ(v)` joint by joint, for Θ and v in `self.theta`, `self.v`.
    fn chart_rates(&self, model: &Model, dy: &mut DVector<f64>) {
        for i in 1..model.nbodies() {
            let joint = model.joint(i);
            let r = model.idx_v(i)..model.idx_v(i) + joint.nv();
            joint.chart_rate(
                &self.theta.as_slice()[r.clone()],
                &self.v.as_slice()[r.clone()],
                &mut dy.as_mut_slice()[r],
            );
        }
    }

    /// `dy = F([0; v₀])` at the chart's centre: `Θ̇ = v₀`, `v̇ = aba(q₀, v₀, τ)`.
    pub fn derivative_at_centre(
        &mut self,
        model: &Model,
        data: &mut Data,
        tau: &DVector<f64>,
        v0: &DVector<f64>,
        dy: &mut DVector<f64>,
    ) -> Result<(), DynamicsError> {
        let nv = model.nv();
        let q0 = std::mem::take(&mut self.q0);
        let result = self.acceleration(model, data, tau, &q0, v0).map(|a| dy.rows_mut(nv, nv).copy_from(a));
        self.q0 = q0;
        result?;
        dy.rows_mut(0, nv).copy_from(v0);
        Ok(())
    }

    /// Leaves the chart: `q_out = q₀ ⊕ Θ`, `v_out = v` for `y = [Θ; v]`.
    pub fn point(
        &mut self,
        model: &Model,
        y: &DVector<f64>,
        q_out: &mut DVector<f64>,
        v_out: &mut DVector<f64>,
    ) {
        let nv = model.nv();
        self.theta.copy_from(&y.rows(0, nv));
        model.integrate(&self.q0, &self.theta, 1.0, q_out);
        v_out.copy_from(&y.rows(nv, nv));
    }
}
