//! Joints: a closed enum, one module per kind, and the one place that dispatches over kinds.
//!
//! Every kind offers the same small set of operations on its slice of the configuration `q`
//! (length [`Joint::nq`]) and velocity `v` (length [`Joint::nv`]):
//! - [`Joint::transform_and_subspace`]: the joint transform `x_jc` (pose of the child frame in the
//!   joint frame) and the motion subspace `S` (one [`Motion`] per degree of freedom, in the child
//!   frame), so that the child's velocity relative to the parent, in the child frame, is `vJ = S q̇`;
//! - [`Joint::bias`]: `cJ = S̊ q̇`, the apparent derivative of `S` in the child frame times `q̇`;
//! - [`Joint::integrate`], [`Joint::difference`]: motion on the configuration manifold
//!   (exponential map for ball, free and planar joints, renormalized quaternions);
//! - [`Joint::neutral`], [`Joint::random`]: configurations.

mod ball;
mod free;
mod hinge;
mod hinge2;
mod planar;
mod slider;
mod universal;

pub use ball::{swing_twist, BallLimits, SwingTwist};

use crate::math::{Motion, Transform, Vec3};
use rand::Rng;

/// Spring-damper of a hinge2 suspension, acting along the steering axis (ODE's hinge2
/// suspension, in generalized coordinates).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Suspension {
    /// Spring stiffness k (N/m); the spring is at rest at travel 0.
    pub stiffness: f64,
    /// Damping c (N·s/m).
    pub damping: f64,
}

/// The kind of a joint together with its axes. Axes are unit vectors (the model builder
/// normalizes them) in the joint frame unless said otherwise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Joint {
    /// No motion; the model builder fuses the child into its parent. nq = nv = 0.
    Fixed,
    /// Rotation θ (rad) about `axis`. nq = nv = 1.
    Hinge {
        /// Rotation axis, joint frame.
        axis: Vec3,
    },
    /// Translation (m) along `axis`. nq = nv = 1.
    Slider {
        /// Translation axis, joint frame.
        axis: Vec3,
    },
    /// Spherical joint: q a unit quaternion (x, y, z, w), v the angular velocity in the child frame.
    /// nq = 4, nv = 3.
    Ball,
    /// Two rotations: θ₁ about `axis1` (fixed in the parent), then θ₂ about `axis2` (fixed in the
    /// child): `R = exp(θ₁ a₁) exp(θ₂ a₂)`. nq = nv = 2.
    Universal {
        /// First axis, joint (parent-side) frame.
        axis1: Vec3,
        /// Second axis, child frame.
        axis2: Vec3,
    },
    /// ODE's hinge2 (steer + spin) in generalized coordinates: optional suspension travel `s` (m)
    /// along `axis1`, steering θ₁ about `axis1` (fixed in the parent), spin θ₂ about `axis2` (fixed
    /// in the child). q = (s,) θ₁, θ₂ (s only with a suspension); nq = nv = 2, or 3 with suspension.
    Hinge2 {
        /// Steering (and suspension) axis, joint frame.
        axis1: Vec3,
        /// Spin axis, child frame.
        axis2: Vec3,
        /// Suspension spring-damper; `None` for a rigid hinge2 without travel.
        suspension: Option<Suspension>,
    },
    /// Six degrees of freedom: q = position (m) of the child frame, then its quaternion
    /// (x, y, z, w); v = `[v; ω]` of the child frame in the child frame. nq = 7, nv = 6.
    Free,
    /// Motion in the joint frame's xy-plane: q = x, y (m), θ (rad, about z); v = `[vx, vy, ω]` of
    /// the child frame, expressed in the child frame. nq = nv = 3.
    Planar,
}

impl Joint {
    /// A hinge about `axis` (normalized by the model builder).
    pub fn hinge(axis: Vec3) -> Self {
        Joint::Hinge { axis }
    }

    /// A slider along `axis` (normalized by the model builder).
    pub fn slider(axis: Vec3) -> Self {
        Joint::Slider { axis }
    }

    /// Number of configuration coordinates.
    pub fn nq(&self) -> usize {
        match self {
            Joint::Fixed => 0,
            Joint::Hinge { .. } | Joint::Slider { .. } => 1,
            Joint::Ball => 4,
            Joint::Universal { .. } => 2,
            Joint::Hinge2 { suspension, .. } => 2 + usize::from(suspension.is_some()),
            Joint::Free => 7,
            Joint::Planar => 3,
        }
    }

    /// Number of velocity coordinates (degrees of freedom).
    pub fn nv(&self) -> usize {
        match self {
            Joint::Ball => 3,
            Joint::Free => 6,
            other => other.nq(),
        }
    }

    /// Short lower-case name of the kind: fixed, hinge, slider, ball, universal, hinge2, free, planar.
    pub fn kind_name(&self) -> &'static str {
        match self {
            Joint::Fixed => "fixed",
            Joint::Hinge { .. } => "hinge",
            Joint::Slider { .. } => "slider",
            Joint::Ball => "ball",
            Joint::Universal { .. } => "universal",
            Joint::Hinge2 { .. } => "hinge2",
            Joint::Free => "free",
            Joint::Planar => "planar",
        }
    }

    /// Which configuration coordinates are angles (rad) rather than lengths (m) or quaternion
    /// components; used for default sampling ranges.
    fn coordinate_is_angle(&self, k: usize) -> bool {
        match self {
            Joint::Hinge { .. } | Joint::Universal { .. } => true,
            Joint::Hinge2 { suspension, .. } => !(suspension.is_some() && k == 0),
            Joint::Planar => k == 2,
            _ => false,
        }
    }

    /// The joint transform `x_jc` (child frame in joint frame) at configuration `q`, writing the
    /// motion subspace columns (child frame) into `s` (length nv).
    #[inline]
    pub fn transform_and_subspace(&self, q: &[f64], s: &mut [Motion]) -> Transform {
        debug_assert_eq!(q.len(), self.nq());
        debug_assert_eq!(s.len(), self.nv());
        match self {
            Joint::Fixed => Transform::identity(),
            Joint::Hinge { axis } => hinge::transform_and_subspace(axis, q, s),
            Joint::Slider { axis } => slider::transform_and_subspace(axis, q, s),
            Joint::Ball => ball::transform_and_subspace(q, s),
            Joint::Universal { axis1, axis2 } => universal::transform_and_subspace(axis1, axis2, q, s),
            Joint::Hinge2 { axis1, axis2, suspension } => {
                hinge2::transform_and_subspace(axis1, axis2, suspension.is_some(), q, s)
            }
            Joint::Free => free::transform_and_subspace(q, s),
            Joint::Planar => planar::transform_and_subspace(q, s),
        }
    }

    /// `placement · x_jc(q)`: the child body's pose in the parent body's frame for a joint frame
    /// at `placement`, writing the subspace into `s` as [`Joint::transform_and_subspace`] does.
    ///
    /// Inlined into the kinematic loops for the hinge (the common joint, whose transform is a
    /// few multiplications; a call returns the pose through memory, which the loop then waits
    /// to read back); the other kinds are one call.
    #[inline(always)]
    pub fn placed_transform(&self, placement: &Transform, q: &[f64], s: &mut [Motion]) -> Transform {
        match self {
            Joint::Hinge { axis } => hinge::placed_transform(placement, axis, q, s),
            _ => self.placed_transform_general(placement, q, s),
        }
    }

    /// [`Joint::placed_transform`] stored into `out` by each kind's own arm: a hinge's pose
    /// goes from registers to `out`, where a pose returned from the match passes through a
    /// stack slot (the other kinds' call fills it) that the caller then waits to read back.
    #[inline(always)]
    pub(crate) fn write_placed_transform(
        &self,
        placement: &Transform,
        q: &[f64],
        s: &mut [Motion],
        out: &mut Transform,
    ) {
        match self {
            Joint::Hinge { axis } => *out = hinge::placed_transform(placement, axis, q, s),
            _ => *out = self.placed_transform_general(placement, q, s),
        }
    }

    #[inline(never)]
    fn placed_transform_general(&self, placement: &Transform, q: &[f64], s: &mut [Motion]) -> Transform {
        placement * &self.transform_and_subspace(q, s)
    }

    /// The bias `cJ = S̊ q̇` (child frame) for subspace `s` computed at the same `q`, velocity `v`.
    /// Zero for every kind whose subspace is constant in the child frame.
    #[inline]
    pub fn bias(&self, s: &[Motion], v: &[f64]) -> Motion {
        match self {
            Joint::Universal { axis2, .. } => universal::bias(axis2, s, v),
            Joint::Hinge2 { axis2, suspension, .. } => hinge2::bias(axis2, suspension.is_some(), s, v),
            _ => Motion::zero(),
        }
    }

    /// True when the subspace `S` depends on `q` (so `cJ` may be non-zero).
    #[inline]
    pub fn has_bias(&self) -> bool {
        matches!(self, Joint::Universal { .. } | Joint::Hinge2 { .. })
    }

    /// `q_out = q ⊕ v·dt`: moves along the manifold with constant velocity `v` for `dt` seconds.
    pub fn integrate(&self, q: &[f64], v: &[f64], dt: f64, q_out: &mut [f64]) {
        match self {
            Joint::Ball => ball::integrate(q, v, dt, q_out),
            Joint::Free => free::integrate(q, v, dt, q_out),
            Joint::Planar => planar::integrate(q, v, dt, q_out),
            _ => {
                for k in 0..q.len() {
                    q_out[k] = q[k] + v[k] * dt;
                }
            }
        }
    }

    /// Like [`Joint::integrate`], except that free and planar joints move their origin along a
    /// straight line with its world velocity at the start and turn separately (R³ × SO(3), the
    /// step of rigid-body engines) instead of along the SE(3) screw of constant body velocity.
    /// Both are first-order accurate; the decoupled step keeps a ball rolling without slip on
    /// its plane, where the screw step sinks its centre by r(ω dt)²/2 per step.
    pub fn integrate_decoupled(&self, q: &[f64], v: &[f64], dt: f64, q_out: &mut [f64]) {
        match self {
            Joint::Free => free::integrate_decoupled(q, v, dt, q_out),
            Joint::Planar => planar::integrate_decoupled(q, v, dt, q_out),
            _ => self.integrate(q, v, dt, q_out),
        }
    }

    /// The rate `Θ̇` of the chart coordinate Θ (`q = q₀ ⊕ Θ`, see [`Joint::integrate`] with unit
    /// time) at which the joint moves with velocity `v` when it is at Θ:
    /// `Θ̇ = dexp⁻¹₋Θ(v) = v + ½[Θ, v] + Σₖ B₂ₖ/(2k)! ad_Θ²ᵏ v` (Munthe-Kaas; Bernoulli numbers
    /// B₂ₖ; the bracket of so(3), se(3) or se(2) for ball, free and planar joints). Joints whose
    /// coordinates are Euclidean give `Θ̇ = v`. This lets Runge–Kutta stages combine tangent
    /// vectors in one chart and leave the manifold only through [`Joint::integrate`].
    /// The series converges for rotations |Θ| < 2π; it is summed to double precision for
    /// |Θ| ≲ 1 rad, far above one time step's rotation.
    pub fn chart_rate(&self, theta: &[f64], v: &[f64], out: &mut [f64]) {
        let embed = |x: &[f64]| -> [f64; 6] {
            match self {
                Joint::Ball => [0.0, 0.0, 0.0, x[0], x[1], x[2]],
                Joint::Free => [x[0], x[1], x[2], x[3], x[4], x[5]],
                Joint::Planar => [x[0], x[1], 0.0, 0.0, 0.0, x[2]],
                _ => [0.0; 6],
            }
        };
        match self {
            Joint::Ball | Joint::Free | Joint::Planar => {
                let rate = se3_dexp_inv(&embed(theta), &embed(v));
                match self {
                    Joint::Ball => out.copy_from_slice(&rate[3..6]),
                    Joint::Free => out.copy_from_slice(&rate),
                    _ => {
                        out[0] = rate[0];
                        out[1] = rate[1];
                        out[2] = rate[5];
                    }
                }
            }
            _ => out.copy_from_slice(v),
        }
    }

    /// `v_out = q1 ⊖ q0`: the constant velocity that moves `q0` to `q1` in unit time. Angles of
    /// hinges are real coordinates (not wrapped), so the difference is their plain difference.
    pub fn difference(&self, q0: &[f64], q1: &[f64], v_out: &mut [f64]) {
        match self {
            Joint::Ball => ball::difference(q0, q1, v_out),
            Joint::Free => free::difference(q0, q1, v_out),
            Joint::Planar => planar::difference(q0, q1, v_out),
            _ => {
                for k in 0..q0.len() {
                    v_out[k] = q1[k] - q0[k];
                }
            }
        }
    }

    /// The neutral configuration: zero angles and offsets, identity quaternions.
    pub fn neutral(&self, q_out: &mut [f64]) {
        q_out.fill(0.0);
        match self {
            Joint::Ball => q_out[3] = 1.0,
            Joint::Free => q_out[6] = 1.0,
            _ => {}
        }
    }

    /// Where the quaternion `[x, y, z, w]` sits among the joint's coordinates (ball, free);
    /// `None` for other kinds.
    pub fn quaternion_range(&self) -> Option<std::ops::Range<usize>> {
        match self {
            Joint::Ball => Some(0..4),
            Joint::Free => Some(3..7),
            _ => None,
        }
    }

    /// Norm of the quaternion part of `q` (ball, free); `None` for other kinds.
    pub fn quaternion_norm(&self, q: &[f64]) -> Option<f64> {
        self.quaternion_range().map(|r| q[r].iter().map(|x| x * x).sum::<f64>().sqrt())
    }

    /// Renormalizes the quaternion part of `q` (ball, free); no-op for other kinds.
    pub fn normalize(&self, q: &mut [f64]) {
        if let Some(r) = self.quaternion_range() {
            let quat = &mut q[r];
            let n = quat.iter().map(|x| x * x).sum::<f64>().sqrt();
            quat.iter_mut().for_each(|x| *x /= n);
        }
    }

    /// A random configuration: each coordinate uniform within `[lower, upper]` where both are
    /// finite, otherwise uniform in [−π, π] for angles and [−1, 1] m for lengths; quaternions are
    /// uniform on the unit sphere (Shoemake).
    pub fn random<R: Rng + ?Sized>(&self, rng: &mut R, lower: &[f64], upper: &[f64], q_out: &mut [f64]) {
        let quat_range = self.quaternion_range().unwrap_or(0..0);
        for k in 0..q_out.len() {
            if quat_range.contains(&k) {
                continue;
            }
            let (lo, hi) = if lower[k].is_finite() && upper[k].is_finite() {
                (lower[k], upper[k])
            } else if self.coordinate_is_angle(k) {
                (-std::f64::consts::PI, std::f64::consts::PI)
            } else {
                (-1.0, 1.0)
            };
            q_out[k] = if hi > lo { rng.random_range(lo..=hi) } else { lo };
        }
        if !quat_range.is_empty() {
            q_out[quat_range].copy_from_slice(&uniform_quaternion(rng));
        }
    }
}

/// A uniformly distributed unit quaternion `[x, y, z, w]` (Shoemake, Graphics Gems III).
pub(crate) fn uniform_quaternion<R: Rng + ?Sized>(rng: &mut R) -> [f64; 4] {
    let u1: f64 = rng.random();
    let u2: f64 = rng.random::<f64>() * std::f64::consts::TAU;
    let u3: f64 = rng.random::<f64>() * std::f64::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    [a * u2.sin(), a * u2.cos(), b * u3.sin(), b * u3.cos()]
}

/// Reads a quaternion stored `[x, y, z, w]` as a unit quaternion (normalizing it).
pub(crate) fn read_quaternion(q: &[f64]) -> nalgebra::UnitQuaternion<f64> {
    nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[3], q[0], q[1], q[2]))
}

/// Writes a unit quaternion as `[x, y, z, w]`.
pub(crate) fn write_quaternion(r: &nalgebra::UnitQuaternion<f64>, out: &mut [f64]) {
    out.copy_from_slice(&[r.i, r.j, r.k, r.w]);
}

/// Bernoulli numbers over factorials, `B₂ₖ/(2k)!` for k = 1…10.
const DEXP_INV_COEFFICIENTS: [f64; 10] = [
    1.0 / 12.0,
    -1.0 / 720.0,
    1.0 / 30240.0,
    -1.0 / 1209600.0,
    1.0 / 47900160.0,
    -691.0 / 1307674368000.0,
    1.0 / 74724249600.0,
    -3617.0 / 10670622842880000.0,
    43867.0 / 5109094217170944000.0,
    -174611.0 / 802857662698291200000.0,
];

/// The se(3) bracket `[x, y]` of twists `[v; ω]`: `(ω₁ × v₂ − ω₂ × v₁, ω₁ × ω₂)`.
fn se3_bracket(x: &[f64; 6], y: &[f64; 6]) -> [f64; 6] {
    let (v1, w1) = (Vec3::new(x[0], x[1], x[2]), Vec3::new(x[3], x[4], x[5]));
    let (v2, w2) = (Vec3::new(y[0], y[1], y[2]), Vec3::new(y[3], y[4], y[5]));
    let lin = w1.cross(&v2) - w2.cross(&v1);
    let ang = w1.cross(&w2);
    [lin.x, lin.y, lin.z, ang.x, ang.y, ang.z]
}

/// `dexp⁻¹₋Θ(v) = v + ½[Θ, v] + Σₖ B₂ₖ/(2k)! ad_Θ²ᵏ v` on se(3), summed until the terms vanish
/// in double precision (at most 20 powers).
fn se3_dexp_inv(theta: &[f64; 6], v: &[f64; 6]) -> [f64; 6] {
    let norm = |x: &[f64; 6]| x.iter().map(|e| e * e).sum::<f64>().sqrt();
    let mut out = *v;
    let mut power = se3_bracket(theta, v);
    for (o, p) in out.iter_mut().zip(&power) {
        *o += 0.5 * p;
    }
    let floor = 1e-18 * norm(v);
    for c in DEXP_INV_COEFFICIENTS {
        let even = se3_bracket(theta, &power);
        let term_norm = c.abs() * norm(&even);
        for (o, p) in out.iter_mut().zip(&even) {
            *o += c * p;
        }
        if term_norm <= floor {
            break;
        }
        power = se3_bracket(theta, &even);
    }
    out
}
