//! Loop closures held on their position manifold after a step.
//!
//! The velocity rows of a loop closure make `J(q₀) v⁺ = −erp·e/h`, but integrating q with the
//! constant v⁺ over a step leaves a second-order error `e = O(h²‖v‖²/L)` that Baumgarte
//! feedback only damps. Two corrections close it, one per kind of step:
//!
//! - **The velocity-level step: SHAKE** (Ryckaert, Ciccotti & Berendsen 1977; Hairer–Lubich–Wanner,
//!   *Geometric Numerical Integration*, VII.1, eq. 1.22). The closure impulse keeps its
//!   direction at the step's start, M⁻¹J(q₀)ᵀ, and its size is corrected until the
//!   configuration the step reaches is closed, `e(q₀ ⊕ h v⁺) = 0`, by quasi-Newton steps
//!   `v⁺ ← v⁺ − M⁻¹J₀ᵀ (J₀ M⁻¹ J₀ᵀ + εI)⁻¹ e(q₁)/h`, `q₁ = q₀ ⊕ h v⁺`. Position and velocity move
//!   together (q₁ − q₀ = h v⁺ stays exact), so the closure removes no kinetic energy of its
//!   own. A projection of q₁ alone followed by a projection of v⁺ onto the tangent space at q₁
//!   would instead remove `½ (J₁v⁺)ᵀ(J₁M⁻¹J₁ᵀ)⁻¹(J₁v⁺)` of kinetic energy per step with
//!   `J₁v⁺ = O(h‖v‖²/L)`: a loss of order h over a fixed time (on the four-bar, a quarter of
//!   its energy in 10 s at h = 1 ms). The first-order step itself is no symplectic map on an
//!   inertia that depends on q (its centrifugal term is explicit) and reports the mean
//!   velocity over the step: the four-bar still loses 3.9 % in 10 s at 1 ms with SHAKE, as
//!   much as with Baumgarte feedback alone. A linkage of hinges and sliders whose only rows
//!   are its own closures is therefore stepped by RATTLE ([`super::rattle`], second order and
//!   symplectic, these buffers' rows and Gram factor); SHAKE closes the loops of every other
//!   multibody in a velocity-level step. Drake's and MuJoCo's velocity-level steps keep loop
//!   constraints by Baumgarte-like feedback alone (they do not project).
//! - **Smooth steps** ([`crate::world::smooth`]): Gauss–Newton steps in the mass metric on q,
//!   `q ← q ⊕ Δ`, `Δ = −M⁻¹Jᵀ (J M⁻¹ Jᵀ + εI)⁻¹ e(q)`, then v onto the tangent space,
//!   `v ← v − M⁻¹Jᵀ (J M⁻¹ Jᵀ + εI)⁻¹ J v`: a high-order step's drift is O(hᵖ⁺¹) and the
//!   projection's loss with it (Hairer–Lubich–Wanner, IV.4).
//!
//! M is the factor of the step (at the start-of-step q): any fixed positive-definite metric
//! gives the same fixed point, and this one makes the correction the least-action one. The
//! small ε keeps redundant rows (a planar four-bar's hinge closure has 5 rows of rank 2)
//! harmless.

use super::multibody::Multibody;
use super::rattle::RattleBuffers;
use crate::algorithms::{compute_joint_jacobians, solve_mass_matrix_slice};
use crate::constraints::{add_loop_closure_rows, FrictionModel, LoopClosure, LoopKind, ProblemBuilder};
use crate::data::Data;
use crate::error::DynamicsError;
use crate::model::Model;
use nalgebra::DVector;

/// Options of the loop closures' position correction (SHAKE or RATTLE's sweeps in a
/// velocity-level step, the mass-metric projection after a smooth step).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoopProjection {
    /// Largest number of (quasi-)Newton steps per step (0 turns the correction off, RATTLE
    /// with it, and leaves only the Baumgarte feedback of each closure's `erp`). RATTLE allows
    /// itself the larger of this and 40 fixed-point sweeps (the world's RATTLE step).
    pub iterations: usize,
    /// Stop when every closure error component is below this (m or rad).
    pub tolerance: f64,
}

impl Default for LoopProjection {
    fn default() -> Self {
        Self { iterations: 8, tolerance: 1e-12 }
    }
}

/// Buffers of the projection of one multibody's loop closures, sized when a loop is added.
#[derive(Clone, Debug)]
pub(crate) struct ProjectionBuffers {
    pub(super) builder: ProblemBuilder,
    /// M⁻¹Jᵀ, column-major (nv × rows).
    pub(super) minv_jt: Vec<f64>,
    /// J M⁻¹ Jᵀ + εI and then its Cholesky factor (rows × rows, row-major).
    pub(super) gram: Vec<f64>,
    /// Right-hand side and multipliers (rows).
    pub(super) mu: Vec<f64>,
    /// Correction (nv).
    pub(super) delta: DVector<f64>,
    /// The configuration before a correction.
    q_before: DVector<f64>,
    /// The buffers of the RATTLE step, for a multibody it applies to (hinges, sliders and
    /// fixed joints, no springs or damping: [`RattleBuffers::applies_to`]).
    pub(super) rattle: Option<Box<RattleBuffers>>,
}

/// Rows a closure of this kind contributes.
fn rows_of(kind: &LoopKind) -> usize {
    match kind {
        LoopKind::Ball => 3,
        LoopKind::Hinge { .. } | LoopKind::Slider { .. } => 5,
        LoopKind::Weld => 6,
    }
}

impl ProjectionBuffers {
    /// Buffers for a multibody of `model` with `rows` loop rows.
    pub(crate) fn new(model: &Model, rows: usize) -> Self {
        let (nv, nq) = (model.nv(), model.nq());
        let mut builder = ProblemBuilder::new(nv, FrictionModel::Cone);
        for _ in 0..rows {
            builder.push_row(
                crate::constraints::RowLaw::Bilateral,
                0.0,
                0.0,
                crate::constraints::RowOrigin::Other,
            );
        }
        builder.clear();
        Self {
            builder,
            minv_jt: vec![0.0; nv * rows],
            gram: vec![0.0; rows * rows],
            mu: vec![0.0; rows],
            delta: DVector::zeros(nv),
            q_before: DVector::zeros(nq),
            rattle: RattleBuffers::applies_to(model).then(|| Box::new(RattleBuffers::new(model, rows))),
        }
    }

    /// Row count for a set of closures.
    pub(crate) fn rows_for<'a>(closures: impl Iterator<Item = &'a LoopClosure>) -> usize {
        closures.map(|c| rows_of(&c.kind)).sum()
    }

    /// Fills the rows at the multibody's current `data` (poses and Jacobians at `b.q_next`) with
    /// targets −e, M⁻¹Jᵀ and the factored Gram matrix; returns ‖e‖∞.
    pub(super) fn linearize<'a>(
        &mut self,
        model: &Model,
        data: &Data,
        closures: impl Iterator<Item = &'a LoopClosure>,
    ) -> f64 {
        let error = self.errors(model, data, closures);
        factor_gram(&self.builder, model, data, &mut self.minv_jt, &mut self.gram);
        error
    }

    /// Solves the Gram system for the right-hand side in `mu` and writes −M⁻¹Jᵀμ into `delta`.
    pub(super) fn correction(&mut self, nv: usize) {
        let n = self.builder.len();
        cholesky_solve(&self.gram[..n * n], n, &mut self.mu[..n]);
        self.delta.fill(0.0);
        for i in 0..n {
            let x = &self.minv_jt[i * nv..(i + 1) * nv];
            for (d, xk) in self.delta.iter_mut().zip(x) {
                *d -= self.mu[i] * xk;
            }
        }
    }

    /// Projects `b.q_next` onto the closures' manifold and `b.v_next` onto its tangent space
    /// (after a smooth step; a velocity-level step uses [`Self::shake`]).
    /// `b.data` must hold the mass-matrix factor of this step; on return it holds poses and
    /// Jacobians at the projected q.
    pub(crate) fn project<'a>(
        &mut self,
        b: &mut Multibody,
        closures: impl Iterator<Item = &'a LoopClosure> + Clone,
        options: &LoopProjection,
    ) -> Result<(), DynamicsError> {
        let nv = b.model.nv();
        for _ in 0..options.iterations {
            compute_joint_jacobians(&b.model, &mut b.data, &b.q_next)?;
            let error = self.linearize(&b.model, &b.data, closures.clone());
            if error <= options.tolerance {
                break;
            }
            // J Δ = −e: the rows' targets are −e already.
            for i in 0..self.builder.len() {
                self.mu[i] = -self.builder.target(i);
            }
            self.correction(nv);
            self.q_before.copy_from(&b.q_next);
            b.model.integrate(&self.q_before, &self.delta, 1.0, &mut b.q_next);
        }
        if options.iterations == 0 {
            return Ok(());
        }
        compute_joint_jacobians(&b.model, &mut b.data, &b.q_next)?;
        self.linearize(&b.model, &b.data, closures);
        // Tangent projection of the velocity: μ = (J M⁻¹ Jᵀ)⁻¹ J v, v ← v − M⁻¹Jᵀμ.
        for i in 0..self.builder.len() {
            self.mu[i] = self.builder.row_dot(i, b.v_next.as_slice());
        }
        self.correction(nv);
        b.v_next += &self.delta;
        Ok(())
    }

    /// SHAKE after a velocity-level step (see the module documentation): corrects the size of
    /// the closure impulse along M⁻¹J(q₀)ᵀ until `q₀ ⊕ h v⁺` closes every loop, moving `b.v_next`
    /// (the velocity over the step, in the start-of-step axes) and `b.q_next = q₀ ⊕ h v⁺`
    /// together. `b.data` must hold the mass-matrix factor of this step and the Jacobians at
    /// the step's start `b.state.q`; on return it holds poses and Jacobians at `b.q_next`.
    pub(crate) fn shake<'a>(
        &mut self,
        b: &mut Multibody,
        closures: impl Iterator<Item = &'a LoopClosure> + Clone,
        options: &LoopProjection,
        h: f64,
    ) -> Result<(), DynamicsError> {
        if options.iterations == 0 {
            return Ok(());
        }
        // M⁻¹J₀ᵀ and the factor of J₀ M⁻¹ J₀ᵀ + εI, at the step's start.
        self.linearize(&b.model, &b.data, closures.clone());
        let nv = b.model.nv();
        for iteration in 0..=options.iterations {
            compute_joint_jacobians(&b.model, &mut b.data, &b.q_next)?;
            let error = self.errors(&b.model, &b.data, closures.clone());
            if error <= options.tolerance || iteration == options.iterations {
                break;
            }
            // h J δv = −e: the rows' targets are −e, so μ = e/h = −target/h.
            for i in 0..self.builder.len() {
                self.mu[i] = -self.builder.target(i) / h;
            }
            self.correction(nv);
            b.v_next += &self.delta;
            b.integrate_step(h);
        }
        Ok(())
    }

    /// The rows of the closures at the multibody's current `data` (poses at `b.q_next`) with
    /// targets −e, leaving M⁻¹Jᵀ and the Gram factor as they are; returns ‖e‖∞.
    pub(super) fn errors<'a>(
        &mut self,
        model: &Model,
        data: &Data,
        closures: impl Iterator<Item = &'a LoopClosure>,
    ) -> f64 {
        self.builder.clear();
        for c in closures {
            // erp = 1 and h = 1: the target is exactly −e for each row.
            let unit = LoopClosure { erp: 1.0, ..*c };
            add_loop_closure_rows(&mut self.builder, model, data, 0, &unit, 0, 1.0);
        }
        (0..self.builder.len()).map(|i| self.builder.target(i).abs()).fold(0.0, f64::max)
    }
}

/// In-place Cholesky factor `G = L Lᵀ` of a symmetric positive-definite `n × n` row-major
/// matrix (L in the lower triangle).
/// For the rows of `builder` (one multibody, `data` holding the factor of M): writes the columns
/// of M⁻¹Jᵀ into `minv_jt` (nv entries each) and the Cholesky factor of G = J M⁻¹ Jᵀ + εI into
/// `gram` (row-major, rows × rows), ε = 1e-12 × the mean of G's diagonal so that redundant rows
/// get a negligible multiplier instead of a failed factorization.
pub(super) fn factor_gram(
    builder: &ProblemBuilder,
    model: &crate::model::Model,
    data: &crate::data::Data,
    minv_jt: &mut [f64],
    gram: &mut [f64],
) {
    let (n, nv) = (builder.len(), model.nv());
    for i in 0..n {
        let column = &mut minv_jt[i * nv..(i + 1) * nv];
        builder.row_into(i, column);
        solve_mass_matrix_slice(model, data, column);
    }
    let mut trace = 0.0;
    for i in 0..n {
        for j in 0..=i {
            let value = builder.row_dot(i, &minv_jt[j * nv..(j + 1) * nv]);
            gram[i * n + j] = value;
            gram[j * n + i] = value;
        }
        trace += gram[i * n + i];
    }
    let epsilon = 1e-12 * trace.max(f64::MIN_POSITIVE) / n.max(1) as f64;
    for i in 0..n {
        gram[i * n + i] += epsilon;
    }
    cholesky_in_place(&mut gram[..n * n], n);
}

pub(super) fn cholesky_in_place(g: &mut [f64], n: usize) {
    for j in 0..n {
        let mut d = g[j * n + j];
        for k in 0..j {
            d -= g[j * n + k] * g[j * n + k];
        }
        let d = d.max(f64::MIN_POSITIVE).sqrt();
        g[j * n + j] = d;
        for i in j + 1..n {
            let mut s = g[i * n + j];
            for k in 0..j {
                s -= g[i * n + k] * g[j * n + k];
            }
            g[i * n + j] = s / d;
        }
    }
}

/// Solves `L Lᵀ x = b` in place with the factor of [`cholesky_in_place`].
pub(super) fn cholesky_solve(l: &[f64], n: usize, x: &mut [f64]) {
    for i in 0..n {
        let mut s = x[i];
        for k in 0..i {
            s -= l[i * n + k] * x[k];
        }
        x[i] = s / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = x[i];
        for k in i + 1..n {
            s -= l[k * n + i] * x[k];
        }
        x[i] = s / l[i * n + i];
    }
}
