//! Smooth steps: the integrator choice of [`super::WorldOptions::integrator`] for the steps
//! without inequality rows.
//!
//! The world's contact step is velocity-level semi-implicit Euler; the integrator choice applies
//! to the smooth part and to scenes without contact. A step is *smooth* when
//! it has no contact (not even a speculative one within the contact margin), no joint limit
//! within its margin, no motor, servo, pose servo or joint friction on any multibody, and no
//! loop closure between two different multibodies; every awake multibody is then advanced by
//! the chosen integrator of [`crate::integrators`] on the configuration manifold, with its
//! joint torques and this step's external forces held constant over the step. As soon as a
//! contact or another inequality row appears, the step falls back to the velocity-level path,
//! and back again when it is gone; [`super::StepStats::integrator`] says which scheme a step
//! used. [`IntegratorKind::SemiImplicitEuler`] (the default) keeps the velocity-level step
//! throughout.
//!
//! Multibodies without loop closures are stepped by the integrator itself
//! ([`IntegratorKind::build`], the public [`Integrator`] API). A multibody with loop closures
//! of its own is a differential-algebraic system; it is stepped by the same Runge–Kutta
//! tableau (explicit Euler or RK4; other kinds fall back to the velocity-level step for such
//! scenes) applied in the chart of the step (RKMK, as [`crate::integrators`]) to the index-1
//! form of the closures: each stage solves the KKT system
//!
//! `[M Jᵀ; J 0] [q̈; −λ] = [τ − C v − g + τ_p; −J̇ v]`
//!
//! by the range-space method, `q̈ = q̈_free + M⁻¹Jᵀ (J M⁻¹Jᵀ + εI)⁻¹ (−J̇ v − J q̈_free)`
//! (ε = 1e-12 of the mean diagonal keeps redundant rows harmless; J̇ v from
//! [`crate::constraints::loop_closure_drift_between`]). After the step, q and v are projected
//! back onto the closure manifold and its tangent space in the mass metric at the new q
//! (the [`super::LoopProjection`] of the velocity-level path), which removes the O(hᵖ⁺¹) drift
//! of the index-1 form without Baumgarte terms; the velocity projection only removes kinetic
//! energy, of the order of the squared drift.

use super::multibody::Multibody;
use super::projection::{cholesky_solve, factor_gram, LoopProjection, ProjectionBuffers};
use super::stages::rows::has_row_sources;
use super::WorldOptions;
use crate::algorithms::{compute_joint_jacobians, crba, factor_mass_matrix, rnea, solve_mass_matrix};
use crate::collision::Contact;
use crate::constraints::{
    add_loop_closure_rows, loop_closure_drift_between, FrictionModel, LoopClosure, ProblemBuilder, RowLaw,
    RowOrigin,
};
use crate::data::Data;
use crate::error::DynamicsError;
use crate::integrators::{ImplicitTerms, Integrator, IntegratorError, IntegratorKind};
use crate::model::Model;
use crate::state::State;
use nalgebra::DVector;

/// Names of the integrators a world (or a scene's `[world] integrator`) accepts, as
/// [`parse_integrator`] reads them.
pub const INTEGRATOR_NAMES: [&str; 9] = [
    "semi-implicit-euler",
    "explicit-euler",
    "velocity-verlet",
    "rk4",
    "rk6",
    "rk8",
    "dopri45",
    "gbs",
    "implicit-euler",
];

/// The integrator called `name` (one of [`INTEGRATOR_NAMES`]; `dopri45` with rtol = 1e-9 and
/// atol = 1e-12, `gbs` with 4 columns, or `gbsN` with N columns).
pub fn parse_integrator(name: &str) -> Option<IntegratorKind> {
    Some(match name {
        "semi-implicit-euler" => IntegratorKind::SemiImplicitEuler,
        "explicit-euler" => IntegratorKind::ExplicitEuler,
        "velocity-verlet" => IntegratorKind::VelocityVerlet,
        "rk4" => IntegratorKind::Rk4,
        "rk6" => IntegratorKind::Rk6,
        "rk8" => IntegratorKind::Rk8,
        "dopri45" => IntegratorKind::DormandPrince45 { rtol: 1e-9, atol: 1e-12 },
        "gbs" => IntegratorKind::GraggBulirschStoer { columns: 4 },
        "implicit-euler" => IntegratorKind::ImplicitEuler,
        other => {
            let columns: usize = other.strip_prefix("gbs")?.parse().ok()?;
            if columns == 0 {
                return None;
            }
            IntegratorKind::GraggBulirschStoer { columns }
        }
    })
}

/// The short name of an integrator kind (as in [`INTEGRATOR_NAMES`]).
pub fn integrator_name(kind: &IntegratorKind) -> &'static str {
    match kind {
        IntegratorKind::ExplicitEuler => "explicit-euler",
        IntegratorKind::SemiImplicitEuler => "semi-implicit-euler",
        IntegratorKind::VelocityVerlet => "velocity-verlet",
        IntegratorKind::Rk4 => "rk4",
        IntegratorKind::Rk6 => "rk6",
        IntegratorKind::Rk8 => "rk8",
        IntegratorKind::DormandPrince45 { .. } => "dopri45",
        IntegratorKind::GraggBulirschStoer { .. } => "gbs",
        IntegratorKind::ImplicitEuler => "implicit-euler",
    }
}

/// The explicit Runge–Kutta tableau (stage coefficients, weights) used for multibodies with
/// loop closures, if the kind has one here.
fn closed_loop_tableau(kind: &IntegratorKind) -> Option<(&'static [&'static [f64]], &'static [f64])> {
    const RK4_A: [&[f64]; 3] = [&[0.5], &[0.0, 0.5], &[0.0, 0.0, 1.0]];
    const RK4_B: [f64; 4] = [1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0];
    match kind {
        IntegratorKind::ExplicitEuler => Some((&[], &[1.0])),
        IntegratorKind::Rk4 => Some((&RK4_A, &RK4_B)),
        _ => None,
    }
}

/// Whether this step is smooth (see the module documentation): the integrator is not the
/// velocity-level default, there is no contact, no loop closure between two multibodies (and,
/// with loop closures, the integrator has a closed-loop tableau), and no multibody has a motor,
/// servo, pose servo, joint friction or a joint limit within its margin.
pub(super) fn applies(
    options: &WorldOptions,
    bodies: &[Multibody],
    contacts: &[Contact],
    closures: &[(usize, usize, LoopClosure)],
) -> bool {
    let kind = &options.integrator;
    if matches!(kind, IntegratorKind::SemiImplicitEuler) || !contacts.is_empty() {
        return false;
    }
    if closures.iter().any(|(a, b, _)| a != b) {
        return false;
    }
    if !closures.is_empty() && closed_loop_tableau(kind).is_none() {
        return false;
    }
    !bodies.iter().any(|b| has_row_sources(b, options.limits.margin))
}

/// How one multibody is stepped smoothly.
enum Stepper {
    /// A tree: the integrator itself, on a scratch copy of the state.
    Tree { integrator: Box<dyn Integrator>, state: State },
    /// A tree with loop closures of its own: the constrained Runge–Kutta step.
    Closed(Box<ClosedLoopRk>),
}

/// The smooth steppers of every multibody, built for one integrator kind, multibody count and
/// loop count (rebuilt, allocating, only when one of them changes).
#[derive(Default)]
pub(crate) struct SmoothSteppers {
    built_for: Option<(IntegratorKind, usize, usize)>,
    steppers: Vec<Stepper>,
}

impl SmoothSteppers {
    /// Builds the steppers unless they fit `kind`, `bodies` and `loops` already.
    pub(super) fn prepare(
        &mut self,
        kind: IntegratorKind,
        bodies: &[Multibody],
        loops: &[(usize, usize, LoopClosure)],
    ) {
        let key = (kind, bodies.len(), loops.len());
        if self.built_for == Some(key) {
            return;
        }
        self.steppers = bodies
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let own = loops.iter().filter(|(x, y, _)| *x == i && *y == i).map(|(_, _, c)| c);
                let rows = ProjectionBuffers::rows_for(own);
                match closed_loop_tableau(&kind) {
                    Some((a, weights)) if rows > 0 => {
                        Stepper::Closed(Box::new(ClosedLoopRk::new(&b.model, a, weights, rows)))
                    }
                    _ => Stepper::Tree { integrator: kind.build(&b.model), state: b.state.clone() },
                }
            })
            .collect();
        self.built_for = Some(key);
    }

    /// Advances awake multibody `i` (`b`) by `h` into `b.q_next`, `b.v_next` under its joint
    /// torques and this step's external forces; `closures` are its own loop closures and
    /// `projection` their projection buffers.
    pub(super) fn advance<'a>(
        &mut self,
        i: usize,
        b: &mut Multibody,
        closures: impl Iterator<Item = &'a LoopClosure> + Clone,
        projection: Option<&mut ProjectionBuffers>,
        options: &LoopProjection,
        h: f64,
    ) -> Result<(), IntegratorError> {
        if b.kinematic {
            // Driven by the user: its velocity is kept, as in the velocity-level step.
            b.v_next.copy_from(&b.state.v);
            b.model.integrate_decoupled(&b.state.q, &b.v_next, h, &mut b.q_next);
            return Ok(());
        }
        b.rhs.copy_from(&b.tau);
        b.rhs += &b.tau_external;
        b.factored = false;
        match &mut self.steppers[i] {
            Stepper::Tree { integrator, state } => {
                state.q.copy_from(&b.state.q);
                state.v.copy_from(&b.state.v);
                state.t = b.state.t;
                integrator.step(&b.model, &mut b.data, state, &b.rhs, h)?;
                b.q_next.copy_from(&state.q);
                b.v_next.copy_from(&state.v);
            }
            Stepper::Closed(rk) => {
                rk.step(
                    &b.model,
                    &mut b.data,
                    &b.state,
                    &b.rhs,
                    closures.clone(),
                    h,
                    &mut b.q_next,
                    &mut b.v_next,
                )?;
                if let Some(buffers) = projection {
                    // The projection's mass metric: M at the new configuration.
                    crba(&b.model, &mut b.data, &b.q_next)?;
                    factor_mass_matrix(&b.model, &mut b.data)?;
                    buffers.project(b, closures, options)?;
                }
            }
        }
        Ok(())
    }
}

/// An explicit Runge–Kutta step, in the chart of the step, of a multibody whose loop closures
/// hold at the acceleration level (see the module documentation). Buffers allocated once.
struct ClosedLoopRk {
    /// Stage coefficients a[s − 1][j] (stage s from the derivatives of stages j < s).
    a: &'static [&'static [f64]],
    /// Weights of the stages.
    weights: &'static [f64],
    work: StageWork,
    y0: DVector<f64>,
    y: DVector<f64>,
    k: Vec<DVector<f64>>,
}

/// What one evaluation of the constrained dynamics needs.
struct StageWork {
    q0: DVector<f64>,
    q: DVector<f64>,
    theta: DVector<f64>,
    v: DVector<f64>,
    /// Joint forces, then the free acceleration.
    force: DVector<f64>,
    zero: DVector<f64>,
    terms: ImplicitTerms,
    builder: ProblemBuilder,
    /// J̇ v per row, then the right-hand side and the multipliers λ.
    drift: Vec<f64>,
    lambda: Vec<f64>,
    /// M⁻¹Jᵀ, column-major (nv × rows).
    minv_jt: Vec<f64>,
    /// J M⁻¹ Jᵀ + εI and its Cholesky factor (rows × rows).
    gram: Vec<f64>,
}

impl ClosedLoopRk {
    fn new(model: &Model, a: &'static [&'static [f64]], weights: &'static [f64], rows: usize) -> Self {
        let (nv, nq) = (model.nv(), model.nq());
        let mut builder = ProblemBuilder::new(nv, FrictionModel::Cone);
        for _ in 0..rows {
            builder.push_row(RowLaw::Bilateral, 0.0, 0.0, RowOrigin::Other);
        }
        builder.clear();
        Self {
            a,
            weights,
            work: StageWork {
                q0: DVector::zeros(nq),
                q: DVector::zeros(nq),
                theta: DVector::zeros(nv),
                v: DVector::zeros(nv),
                force: DVector::zeros(nv),
                zero: DVector::zeros(nv),
                terms: ImplicitTerms::new(model),
                builder,
                drift: vec![0.0; rows],
                lambda: vec![0.0; rows],
                minv_jt: vec![0.0; nv * rows],
                gram: vec![0.0; rows * rows],
            },
            y0: DVector::zeros(2 * nv),
            y: DVector::zeros(2 * nv),
            k: vec![DVector::zeros(2 * nv); weights.len()],
        }
    }

    /// `q_out = q₀ ⊕ Θ₁`, `v_out = v₁` after one step of the tableau from `state`.
    #[allow(clippy::too_many_arguments)]
    fn step<'a>(
        &mut self,
        model: &Model,
        data: &mut Data,
        state: &State,
        tau: &DVector<f64>,
        closures: impl Iterator<Item = &'a LoopClosure> + Clone,
        h: f64,
        q_out: &mut DVector<f64>,
        v_out: &mut DVector<f64>,
    ) -> Result<(), DynamicsError> {
        let nv = model.nv();
        self.work.q0.copy_from(&state.q);
        self.y0.rows_mut(0, nv).fill(0.0);
        self.y0.rows_mut(nv, nv).copy_from(&state.v);
        for s in 0..self.weights.len() {
            self.y.copy_from(&self.y0);
            if s > 0 {
                for (j, aj) in self.a[s - 1].iter().enumerate() {
                    if *aj != 0.0 {
                        self.y.axpy(h * aj, &self.k[j], 1.0);
                    }
                }
            }
            self.work.derivative(model, data, tau, closures.clone(), &self.y, &mut self.k[s])?;
        }
        self.y.copy_from(&self.y0);
        for (bj, kj) in self.weights.iter().zip(&self.k) {
            self.y.axpy(h * bj, kj, 1.0);
        }
        self.work.theta.copy_from(&self.y.rows(0, nv));
        model.integrate(&self.work.q0, &self.work.theta, 1.0, q_out);
        v_out.copy_from(&self.y.rows(nv, nv));
        Ok(())
    }
}

impl StageWork {
    /// `dy = [Θ̇; q̈]` at `y = [Θ; v]`: `Θ̇ = dexp⁻¹₋Θ(v)` per joint and the constrained
    /// acceleration at `q = q₀ ⊕ Θ`.
    fn derivative<'a>(
        &mut self,
        model: &Model,
        data: &mut Data,
        tau: &DVector<f64>,
        closures: impl Iterator<Item = &'a LoopClosure>,
        y: &DVector<f64>,
        dy: &mut DVector<f64>,
    ) -> Result<(), DynamicsError> {
        let nv = model.nv();
        self.theta.copy_from(&y.rows(0, nv));
        self.v.copy_from(&y.rows(nv, nv));
        model.integrate(&self.q0, &self.theta, 1.0, &mut self.q);
        for i in 1..model.nbodies() {
            let joint = model.joint(i);
            let r = model.idx_v(i)..model.idx_v(i) + joint.nv();
            joint.chart_rate(
                &self.theta.as_slice()[r.clone()],
                &self.v.as_slice()[r.clone()],
                &mut dy.as_mut_slice()[r],
            );
        }
        // Kinematics and Jacobians, M and its factor, and C v + g with the bias accelerations
        // (data.v, data.a) that J̇ v needs, all at (q, v).
        compute_joint_jacobians(model, data, &self.q)?;
        crba(model, data, &self.q)?;
        factor_mass_matrix(model, data)?;
        rnea(model, data, &self.q, &self.v, &self.zero)?;
        // Free acceleration M⁻¹ (τ − C v − g + τ_p).
        self.force.copy_from(tau);
        self.force -= &data.tau;
        self.terms.subtract_passive_forces(model, &self.q, &self.v, 0.0, &mut self.force);
        solve_mass_matrix(model, data, &mut self.force);
        // The closures' rows J (erp irrelevant) and their drift J̇ v.
        self.builder.clear();
        let mut n = 0;
        for c in closures {
            add_loop_closure_rows(&mut self.builder, model, data, 0, c, 0, 1.0);
            n += loop_closure_drift_between((model, data), (model, data), c, &mut self.drift[n..]);
        }
        debug_assert_eq!(n, self.builder.len());
        // λ = (J M⁻¹ Jᵀ + εI)⁻¹ (−J̇ v − J q̈_free), q̈ = q̈_free + M⁻¹ Jᵀ λ.
        for i in 0..n {
            self.lambda[i] = -self.drift[i] - self.builder.row_dot(i, self.force.as_slice());
        }
        factor_gram(&self.builder, model, data, &mut self.minv_jt, &mut self.gram);
        cholesky_solve(&self.gram[..n * n], n, &mut self.lambda[..n]);
        for i in 0..n {
            let x = &self.minv_jt[i * nv..(i + 1) * nv];
            for (a, xk) in self.force.iter_mut().zip(x) {
                *a += self.lambda[i] * xk;
            }
        }
        dy.rows_mut(nv, nv).copy_from(&self.force);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_integrator_name_parses_and_names_itself() {
        for name in INTEGRATOR_NAMES {
            let kind = parse_integrator(name).unwrap();
            assert_eq!(integrator_name(&kind), name);
        }
        assert_eq!(parse_integrator("gbs6"), Some(IntegratorKind::GraggBulirschStoer { columns: 6 }));
        assert_eq!(parse_integrator("gbs0"), None);
        assert_eq!(parse_integrator("rk5"), None);
    }
}
