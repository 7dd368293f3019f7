//! Stage 8, first: a lone free body's origin moves with the step's mean velocity along the
//! directions that no contact normal constrains.
//!
//! The world's step is semi-implicit Euler: `q⁺ = q ⊕ h v⁺`, the end velocity over the whole
//! step. Under a constant force that is first order: a box sliding to a stop under Coulomb
//! friction (deceleration μg) covers `v₀²/(2μg) − h v₀/2`, 4 % short of the exact distance for
//! v₀ = 2 m/s, μ = 0.5 at 1/60 s, and a thrown body's parabola is off by `h² g / 2` per step.
//! The trapezoid `q⁺ = q ⊕ h (v + v⁺)/2` is exact under a constant force, but it must not
//! replace the end velocity where a row holds the body: along a contact normal the solve chose
//! v⁺ so that `q ⊕ h v⁺` closes the gap (a speculative contact against a wall, a body resting
//! on another), and the mean velocity would carry it past that point. Nor where a force depends
//! on the configuration (a joint's spring, a servo, a loop closure): there the trapezoid with
//! an explicit velocity update gains energy every period.
//!
//! So only a **lone free body** (a multibody of one free joint, no motor, servo, limit or
//! loop closure) is shifted, and only its origin, along the directions orthogonal to the
//! normals of every contact it has in the step (the world's contacts, rows or not):
//! `s = −(h/2) P (v⁺ − v)`, P the projection onto the complement of the normals' span, v the
//! velocity at the step's start (impulses applied), in the body's axes at the step's start,
//! as the free joint's linear velocity is. Its orientation keeps the end rate (the implicit
//! gyroscopic step's own). A box sliding on a plane then covers the exact distance, a body in
//! flight follows the parabola exactly, and a body at rest does not move (v = v⁺).

use crate::collision::{Attachment, Contact};
use crate::constraints::LoopClosure;
use crate::math::Vec3;
use crate::model::Joint;
use crate::world::stages::rows::has_row_sources;
use crate::world::Multibody;
use nalgebra::DVector;

/// Normals whose component off the span of those before is shorter than this (relative) add
/// no direction to it.
const NEW_DIRECTION: f64 = 1e-9;

/// What the shifts are computed from.
pub(crate) struct MidpointInputs<'a> {
    /// The step's contacts.
    pub(crate) contacts: &'a [Contact],
    /// The loop closures (multibody, other multibody, closure).
    pub(crate) closures: &'a [(usize, usize, LoopClosure)],
    /// Stacked velocities at the step's start and after the impulses (rad/s or m/s per dof).
    pub(crate) v_start: &'a DVector<f64>,
    /// See `v_start`.
    pub(crate) v_end: &'a DVector<f64>,
    /// A joint within this distance of a limit has a row (m or rad).
    pub(crate) limit_margin: f64,
}

/// Sets every multibody's `midpoint_shift` for a step of `h` seconds: zero but for awake lone
/// free bodies (see the module documentation). `b.data` must hold the poses at the step's start.
/// One pass over the contacts: each adds its normal to the span of the lone bodies it touches.
pub(crate) fn run(bodies: &mut [Multibody], inputs: &MidpointInputs<'_>, h: f64) {
    for (i, b) in bodies.iter_mut().enumerate() {
        b.midpoint_shift = Vec3::zeros();
        b.midpoint_span.lone = lone_free_body(i, b, inputs);
        b.midpoint_span.rank = 0;
    }
    for c in inputs.contacts {
        let a = match c.body_a {
            Attachment::Body { multibody, .. } => Some(multibody),
            Attachment::World => None,
        };
        let other = match c.body_b {
            Attachment::Body { multibody, .. } if Some(multibody) != a => Some(multibody),
            _ => None,
        };
        for m in [a, other].into_iter().flatten() {
            let b = &mut bodies[m];
            if b.midpoint_span.lone {
                let rotation = b.data.x_wb[1].rotation;
                b.midpoint_span.add(rotation.transpose() * c.normal, c.normal.norm());
            }
        }
    }
    for b in bodies.iter_mut().filter(|b| b.midpoint_span.lone && b.midpoint_span.rank < 3) {
        let col = b.col;
        let change = Vec3::new(
            inputs.v_end[col] - inputs.v_start[col],
            inputs.v_end[col + 1] - inputs.v_start[col + 1],
            inputs.v_end[col + 2] - inputs.v_start[col + 2],
        );
        b.midpoint_shift = b.midpoint_span.off(change) * (-0.5 * h);
    }
}

/// The span of a lone free body's contact normals in a step, in its body axes at the step's
/// start: an orthonormal basis built by Gram–Schmidt in the contacts' order.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct NormalSpan {
    /// Whether the multibody is a lone free body this step (else the span is not kept).
    lone: bool,
    basis: [Vec3; 3],
    rank: usize,
}

impl NormalSpan {
    /// Adds `normal` (body axes; `length` its length) unless it lies in the span already.
    fn add(&mut self, normal: Vec3, length: f64) {
        if self.rank == 3 {
            return;
        }
        let mut e = normal;
        for d in &self.basis[..self.rank] {
            e -= *d * d.dot(&e);
        }
        let norm = e.norm();
        if norm > NEW_DIRECTION * length {
            self.basis[self.rank] = e / norm;
            self.rank += 1;
        }
    }

    /// `v` less its components along the span.
    fn off(&self, mut v: Vec3) -> Vec3 {
        for d in &self.basis[..self.rank] {
            v -= *d * d.dot(&v);
        }
        v
    }
}

/// Whether multibody `i` (`b`) is an awake, moving lone free body without rows of its own or
/// loop closures.
fn lone_free_body(i: usize, b: &Multibody, inputs: &MidpointInputs<'_>) -> bool {
    !b.asleep
        && !b.kinematic
        && b.model.nbodies() == 2
        && matches!(b.model.joint(1), Joint::Free)
        && !has_row_sources(b, inputs.limit_margin)
        && !inputs.closures.iter().any(|(a, c, _)| *a == i || *c == i)
}
