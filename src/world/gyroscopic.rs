//! The gyroscopic couple `−ω × I ω` of the bodies of free joints, implicit in the
//! velocity-level step's free motion.
//!
//! Explicit in the step (inside `C(q, v) v`), the couple makes semi-implicit Euler add energy to
//! a spinning body at every step: a T-handle spinning at 10 rad/s about its intermediate axis
//! (the Dzhanibekov flip) gains a factor 8 of kinetic energy in 10 s at h = 1/60 s. The free
//! motion here replaces, for each such body spinning by more than [`SPIN_THRESHOLD`] rad per
//! step, the explicit couple by the midpoint couple `−ω_m × L̄` with `ω_m = (ω₀ + ω₁) / 2`
//! (start and end of the step, the end unknown) and `L̄ = I ω̄`, the body's angular momentum at
//! the explicit step's midpoint velocity `ω̄` (a predictor, as in Catto's "Numerical methods",
//! GDC 2015, and Bullet's `computeGyroscopicImpulseImplicit_Body`, which use the implicit Euler
//! form). Since `ω_m · (ω_m × L̄) = 0` for any `L̄`, the couple does no work over the step: a
//! lone spinning body keeps its kinetic energy to round-off at any step size, the norm of its
//! angular momentum to O(h²) and the flip period of the Dzhanibekov spin to 1 % at 1/60 s
//! (the implicit Euler form instead dissipates it: 65 % of the energy in 10 s at 1/60 s).
//! The world-frame direction of the angular momentum `R₁ I ω₁` is off by a bounded O(h) offset
//! (4.6 % at 1/60 s, 0.27 % at 1 ms; it does not grow): the step moves the rotation with the
//! velocity at the end of the step (`R₁ = R₀ exp(h ω₁)`), so ω₁ is the velocity over the step
//! and its momentum belongs to the orientation halfway through it, `R₁ exp(−h ω₁/2) I ω₁`,
//! which stays within 7.2e-3 at 1/60 s (the Dzhanibekov case of the stability report). A step
//! that conserved `R₁ I ω₁` exactly would have to dissipate energy (`I ω₁ = exp(−h ω₁) I ω₀`,
//! Bullet's implicit form solved exactly, loses 35 % of the energy in 10 s at 1/60 s and flips
//! at 1.06 s instead of 2.44 s).
//!
//! What stays explicit, and its measured effect: for a free body whose centre of mass is off
//! its origin, the turn of the body-axes linear momentum (`−ω × p` in the free joint's body
//! coordinates) is explicit; a 2 kg body 6 cm off-centre tumbling at 10 rad/s while drifting at
//! 0.37 m/s then gains up to 0.9 % of its energy in a step and its kinetic energy drifts by 4.6 %
//! over 10 s at 1/60 s (6.9 times its energy with the couple explicit too), `tests/gyroscopic.rs`.
//!
//! The couple is linear in the unknown `Δv = v₁ − v₀`: with `J_b` the body's angular Jacobian
//! (world axes, 3 × nv) and `S_b = [L̄_b]×`,
//! `(M̃ − h/2 Σ_b J_bᵀ S_b J_b) Δv = h (τ − C v − g) + h Σ_b J_bᵀ (−ω₀ × (L̄_b − I_b ω₀))`,
//! where the sum's matrix is skew-symmetric, so the system is never singular (its symmetric part
//! is M̃). It is solved with the factor of M̃ the free motion already holds, by the
//! Sherman–Morrison–Woodbury identity: 3 solves per spinning body and a dense 3k × 3k system for
//! k spinning bodies. The couple's reaction reaches every joint between the body and the root
//! through `J_b`, so a chain's momentum is exchanged as in the explicit step. The body's other
//! velocity-dependent terms (the centripetal force of its centre of mass about a ball joint,
//! the couplings with its parent's motion) stay explicit.
//!
//! The bodies of different subtrees of the root (the ragdolls of one MJCF file, say) do not
//! couple: M̃ is block-diagonal over the subtrees, and the Woodbury system is solved subtree
//! by subtree, each on its own dofs (a crowd's cost is linear in its size).
//!
//! Which bodies: those of free joints, with their inertia about the centre of mass (the couple
//! of the Newton–Euler equations). The bodies of ball joints keep the explicit couple: inside a
//! limb the couple about the joint is one part of the coupled chain's velocity product, and
//! treating it alone implicitly let a powered ragdoll's limits open by 1.15° on landing
//! (`tests/ragdoll.rs` bounds them by 1°).

use crate::algorithms::{solve_mass_matrix_dofs, solve_mass_matrix_slice};
use crate::data::Data;
use crate::math::{Mat3, Vec3};
use crate::model::{Joint, Model};
use nalgebra::{DMatrix, DVector};
use std::ops::Range;

/// A body spins fast enough for its gyroscopic couple to be treated implicitly when it turns
/// by more than this angle in one step (rad). Below it the explicit couple changes the kinetic
/// energy by a relative O(angle²) ≤ 1e-8 per step, and the free motion costs nothing more.
pub const SPIN_THRESHOLD: f64 = 1e-4;

/// The buffers of the implicit gyroscopic couple of one multibody, sized once.
#[derive(Clone, Debug)]
pub(crate) struct Gyroscopic {
    /// Bodies of free joints, with their rotational inertia about the centre of mass in body
    /// axes and the dofs of their subtree of the root; in body order, so that the bodies of
    /// one subtree are consecutive.
    candidates: Vec<(usize, Mat3, Range<usize>)>,
    /// This step's spinning bodies: body, `ω₀` and `L̄` (world axes), the dofs of its subtree.
    spinning: Vec<(usize, Vec3, Vec3, Range<usize>)>,
    /// `M̃⁻¹ J_bᵀ`, three columns per spinning body.
    w: DMatrix<f64>,
    /// `1 + h G C` of the Woodbury identity (3k × 3k), overwritten by its elimination.
    system: DMatrix<f64>,
    /// The Woodbury unknown y (3k).
    y: DVector<f64>,
    /// Scratch of length nv.
    column: DVector<f64>,
}

/// The angular velocity (world axes) of body `body` under the generalized velocity `v`:
/// `Σ_k J_ω,k v_k` over the dofs between the body and the root.
fn angular_velocity(model: &Model, data: &Data, body: usize, v: &[f64]) -> Vec3 {
    let mut omega = Vec3::zeros();
    let mut b = body;
    while b != 0 {
        let dofs = model.idx_v(b)..model.idx_v(b) + model.joint(b).nv();
        for (column, vk) in data.j_world[dofs.clone()].iter().zip(&v[dofs]) {
            omega += column.angular * *vk;
        }
        b = model.parent(b);
    }
    omega
}

/// `out ← J_bᵀ t` (generalized forces of the couple `t`, world axes, on body `body`), added
/// to `out`'s entries on the body's path to the root.
fn add_couple(model: &Model, data: &Data, body: usize, t: &Vec3, out: &mut [f64]) {
    let mut b = body;
    while b != 0 {
        let dofs = model.idx_v(b)..model.idx_v(b) + model.joint(b).nv();
        for (column, out_k) in data.j_world[dofs.clone()].iter().zip(&mut out[dofs]) {
            *out_k += column.angular.dot(t);
        }
        b = model.parent(b);
    }
}

impl Gyroscopic {
    /// Buffers for `model`: every body of a free joint may spin.
    pub(crate) fn new(model: &Model) -> Self {
        // Each body's subtree of the root (its ancestor whose parent is the root), and the dofs
        // of each such subtree (contiguous: bodies are numbered depth-first).
        let mut top = vec![0usize; model.nbodies()];
        // (first dof, end) per subtree, grown body by body from nothing.
        let mut dofs = vec![(usize::MAX, 0); model.nbodies()];
        for i in 1..model.nbodies() {
            top[i] = if model.parent(i) == 0 { i } else { top[model.parent(i)] };
            let (start, end) = (model.idx_v(i), model.idx_v(i) + model.joint(i).nv());
            let range = &mut dofs[top[i]];
            *range = (range.0.min(start), range.1.max(end));
        }
        let candidates: Vec<(usize, Mat3, Range<usize>)> = (1..model.nbodies())
            .filter_map(|i| match model.joint(i) {
                Joint::Free => Some((i, model.inertia(i).inertia_com(), dofs[top[i]].0..dofs[top[i]].1)),
                _ => None,
            })
            .collect();
        let (nv, k) = (model.nv(), 3 * candidates.len());
        Self {
            spinning: Vec::with_capacity(candidates.len()),
            candidates,
            w: DMatrix::zeros(nv, k),
            system: DMatrix::zeros(k, k),
            y: DVector::zeros(k),
            column: DVector::zeros(nv),
        }
    }

    /// Whether some body turns by more than [`SPIN_THRESHOLD`] in a step of `h` at velocity `v`
    /// (`data.j_world` current): then the free motion needs the factor of M̃.
    pub(crate) fn any_spinning(&self, model: &Model, data: &Data, v: &[f64], h: f64) -> bool {
        self.candidates
            .iter()
            .any(|&(b, _, _)| h * angular_velocity(model, data, b, v).norm() > SPIN_THRESHOLD)
    }

    /// Replaces the explicit gyroscopic couple of every spinning body in `v_free` (the explicit
    /// free velocity from `v` over `h`) by the implicit midpoint couple (module documentation).
    /// `data` holds the factor of M̃ the free motion solved with, and the step's `j_world`.
    pub(crate) fn apply(
        &mut self,
        model: &Model,
        data: &Data,
        v: &DVector<f64>,
        v_free: &mut DVector<f64>,
        h: f64,
    ) {
        // ω₀, the predictor ω̄ (the explicit step's midpoint) and L̄ of each spinning body; the
        // correction of the explicit couple −ω₀ × I ω₀ to −ω₀ × L̄ as generalized forces.
        self.spinning.clear();
        self.column.fill(0.0);
        for (b, inertia_body, dofs) in &self.candidates {
            let b = *b;
            let omega0 = angular_velocity(model, data, b, v.as_slice());
            if h * omega0.norm() <= SPIN_THRESHOLD {
                continue;
            }
            let omega_free = angular_velocity(model, data, b, v_free.as_slice());
            let r = &data.x_wb[b].rotation;
            let inertia = r * inertia_body * r.transpose();
            let momentum = inertia * ((omega0 + omega_free) * 0.5);
            let correction = -omega0.cross(&(momentum - inertia * omega0));
            add_couple(model, data, b, &correction, self.column.as_mut_slice());
            self.spinning.push((b, omega0, momentum, dofs.clone()));
        }
        if self.spinning.is_empty() {
            return;
        }
        // z = Δv of the explicit step with the corrected couple: v_free − v + h M̃⁻¹ Σ J_bᵀ t_b.
        solve_mass_matrix_slice(model, data, self.column.as_mut_slice());
        v_free.axpy(h, &self.column, 1.0);
        // The spinning bodies of one subtree of the root at a time (consecutive in the list).
        let mut first = 0;
        while first < self.spinning.len() {
            let dofs = self.spinning[first].3.clone();
            let mut end = first + 1;
            while end < self.spinning.len() && self.spinning[end].3 == dofs {
                end += 1;
            }
            self.apply_subtree(model, data, v, v_free, h, first..end, dofs);
            first = end;
        }
    }

    /// The Woodbury correction of the spinning bodies `group` (indices into `spinning`), which
    /// share the subtree of the root whose dofs are `dofs`: `v_free[dofs]` moves by −W y.
    #[allow(clippy::too_many_arguments)]
    fn apply_subtree(
        &mut self,
        model: &Model,
        data: &Data,
        v: &DVector<f64>,
        v_free: &mut DVector<f64>,
        h: f64,
        group: Range<usize>,
        dofs: Range<usize>,
    ) {
        let spinning = &self.spinning[group];
        // W = M̃⁻¹ U with U = [J_bᵀ …], three columns per spinning body, zero off `dofs`.
        let k = 3 * spinning.len();
        for (p, &(b, _, _, _)) in spinning.iter().enumerate() {
            for axis in 0..3 {
                let mut column = self.w.column_mut(3 * p + axis);
                column.rows_range_mut(dofs.clone()).fill(0.0);
                let t = Vec3::ith(axis, 1.0);
                add_couple(model, data, b, &t, column.as_mut_slice());
                solve_mass_matrix_dofs(model, data, column.as_mut_slice(), dofs.clone());
            }
        }
        // (M̃ + h U G Uᵀ) Δv = b with G = blockdiag(−½ [L̄_b]×): Δv = z − W y, where
        // (1 + h G Uᵀ W) y = h G Uᵀ z.
        for (p, &(b, _, momentum, _)) in spinning.iter().enumerate() {
            let g = crate::math::skew(&momentum) * (-0.5 * h);
            // Uᵀ z: Δω of body b under z = v_free − v.
            let z_omega = angular_velocity(model, data, b, v_free.as_slice())
                - angular_velocity(model, data, b, v.as_slice());
            let rhs = g * z_omega;
            for a in 0..3 {
                self.y[3 * p + a] = rhs[a];
            }
            for q in 0..spinning.len() {
                for col in 0..3 {
                    let wq = self.w.column(3 * q + col);
                    let c = angular_velocity(model, data, b, wq.as_slice());
                    let gc = g * c;
                    for a in 0..3 {
                        let identity = if p == q && a == col { 1.0 } else { 0.0 };
                        self.system[(3 * p + a, 3 * q + col)] = identity + gc[a];
                    }
                }
            }
        }
        solve_dense_in_place(&mut self.system, k, &mut self.y);
        for (j, yj) in self.y.iter().take(k).enumerate() {
            let column = self.w.column(j);
            v_free.rows_range_mut(dofs.clone()).axpy(-yj, &column.rows_range(dofs.clone()), 1.0);
        }
    }
}

/// Solves the leading `n × n` block of `a` against the first `n` entries of `b` in place
/// (Gaussian elimination with partial pivoting; `a` is overwritten by its factors). The system
/// here is `1 + h G C`, regular since `M̃ + h U G Uᵀ` is (its symmetric part is M̃); a zero
/// pivot, which only round-off could make, leaves that entry zero rather than divide by zero.
fn solve_dense_in_place(a: &mut DMatrix<f64>, n: usize, b: &mut DVector<f64>) {
    for col in 0..n {
        let mut best = col;
        for row in col + 1..n {
            if a[(row, col)].abs() > a[(best, col)].abs() {
                best = row;
            }
        }
        if best != col {
            for j in 0..n {
                a.swap((col, j), (best, j));
            }
            b.swap_rows(col, best);
        }
        let pivot = a[(col, col)];
        if pivot == 0.0 {
            continue;
        }
        for row in col + 1..n {
            let factor = a[(row, col)] / pivot;
            if factor != 0.0 {
                for j in col..n {
                    a[(row, j)] -= factor * a[(col, j)];
                }
                b[row] -= factor * b[col];
            }
        }
    }
    for col in (0..n).rev() {
        let pivot = a[(col, col)];
        if pivot == 0.0 {
            b[col] = 0.0;
            continue;
        }
        let mut x = b[col];
        for j in col + 1..n {
            x -= a[(col, j)] * b[j];
        }
        b[col] = x / pivot;
    }
}
