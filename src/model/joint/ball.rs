//! Ball (spherical) joint: q a unit quaternion (x, y, z, w), `S = [0; 1]` (angular velocity in the
//! child frame); integration `q ← q ⊗ exp(ω dt)`.

use super::{read_quaternion, write_quaternion};
use crate::math::{quat_exp, quat_log, Motion, Transform, Vec3};

pub(super) fn transform_and_subspace(q: &[f64], s: &mut [Motion]) -> Transform {
    for (k, col) in s.iter_mut().enumerate() {
        *col = Motion::new(Vec3::zeros(), Vec3::ith(k, 1.0));
    }
    Transform::new(read_quaternion(q).to_rotation_matrix().into_inner(), Vec3::zeros())
}

pub(super) fn integrate(q: &[f64], v: &[f64], dt: f64, q_out: &mut [f64]) {
    let w = Vec3::new(v[0], v[1], v[2]) * dt;
    let mut r = read_quaternion(q) * quat_exp(&w);
    r.renormalize();
    write_quaternion(&r, q_out);
}

pub(super) fn difference(q0: &[f64], q1: &[f64], v_out: &mut [f64]) {
    let d = read_quaternion(q0).inverse() * read_quaternion(q1);
    v_out.copy_from_slice(quat_log(&d).as_slice());
}

/// Limits of a ball joint: a swing cone about the twist axis plus a twist range about it (the
/// "cone–twist" limit of ragdolls), and a bound on the total rotation angle (MuJoCo's ball-joint
/// `range`). The twist axis is given in the joint frame; at the neutral configuration it is also
/// the child's axis. The ball's rotation `R` is split as `R = R_swing R_twist` (see
/// [`swing_twist`]): the swing is the smallest rotation taking the twist axis `a` to `R a`, the
/// twist a rotation about `a` in the child frame. A stop at the end of its angle's range (a
/// swing or total angle of π, a twist bound of ±π) is no stop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BallLimits {
    /// Twist axis `a` (unit after model building), joint frame.
    pub twist_axis: Vec3,
    /// Half-angle of the swing cone (rad), in (0, π].
    pub swing: f64,
    /// Lower twist limit (rad), in [−π, twist_upper].
    pub twist_lower: f64,
    /// Upper twist limit (rad), in [twist_lower, π].
    pub twist_upper: f64,
    /// Largest total rotation angle `2 acos|w|` of the ball from its neutral configuration
    /// (rad), in (0, π].
    pub angle: f64,
}

/// Marks a stop that is no stop in [`BallLimits::distances`].
const NO_STOP: f64 = f64::INFINITY;

impl BallLimits {
    /// A swing cone of half-angle `swing` about `twist_axis` and the twist range
    /// `[twist_lower, twist_upper]` (rad), the total angle unbounded.
    pub fn cone_twist(twist_axis: Vec3, swing: f64, twist_lower: f64, twist_upper: f64) -> Self {
        Self { twist_axis, swing, twist_lower, twist_upper, angle: std::f64::consts::PI }
    }

    /// The total rotation angle bounded by `angle` (rad), as MuJoCo's ball-joint `range` bounds
    /// it; no cone and no twist range.
    pub fn total_angle(angle: f64) -> Self {
        let pi = std::f64::consts::PI;
        Self { twist_axis: Vec3::z(), swing: pi, twist_lower: -pi, twist_upper: pi, angle }
    }

    /// Distances to the four stops at ball configuration `q` (quaternion `[x, y, z, w]`):
    /// `[swing − θ_swing, φ_twist − twist_lower, twist_upper − φ_twist, angle − θ]` (rad), +∞
    /// for a stop that is no stop; negative means the stop is exceeded by that much. Returns
    /// the decomposition too.
    pub fn distances(&self, q: &[f64]) -> ([f64; 4], SwingTwist) {
        let st = swing_twist(q, &self.twist_axis);
        let pi = std::f64::consts::PI;
        let stop = |active: bool, distance: f64| if active { distance } else { NO_STOP };
        let distances = [
            stop(self.swing < pi, self.swing - st.swing),
            stop(self.twist_lower > -pi, st.twist - self.twist_lower),
            stop(self.twist_upper < pi, self.twist_upper - st.twist),
            stop(self.angle < pi, self.angle - st.angle),
        ];
        (distances, st)
    }

    /// Whether all four stops are surely further than `margin` (rad) from configuration `q`,
    /// by bounds that need no inverse trigonometry: with `s = cos(θ_swing/2)` and `w, p` as in
    /// [`swing_twist`], `θ_swing ≤ π sin(θ_swing/2)`, for `w > 0` `|φ| ≤ π |p| / s`, and
    /// `θ ≤ π sin(θ/2) = π |(x, y, z)|` (all from `x ≤ (π/2) sin x` on [0, π/2]). False says
    /// nothing: [`Self::distances`] decides. A ragdoll's ball joints are mostly far from their
    /// stops, and the acos and atan2 of the exact distances were ~1 % of its step.
    pub fn surely_beyond(&self, q: &[f64], margin: f64) -> bool {
        let norm2 = q.iter().map(|x| x * x).sum::<f64>();
        // (Also false for a NaN norm.)
        if norm2.is_nan() || norm2 <= 0.0 {
            return false;
        }
        let inverse = 1.0 / norm2.sqrt();
        let (u, w) = (Vec3::new(q[0], q[1], q[2]) * inverse, q[3] * inverse);
        let p = u.dot(&self.twist_axis);
        let s2 = w * w + p * p;
        if w.is_nan() || w <= 0.0 || s2.is_nan() || s2 <= 0.0 {
            return false;
        }
        // Relative slack far above the rounding of either side.
        const SLACK: f64 = 1e-9;
        let pi = std::f64::consts::PI;
        let swing_bound = pi * (1.0 - s2).max(0.0).sqrt() * (1.0 + SLACK) + SLACK;
        let twist_bound = pi * p.abs() / s2.sqrt() * (1.0 + SLACK) + SLACK;
        let angle_bound = pi * u.norm() * (1.0 + SLACK) + SLACK;
        (self.swing >= pi || swing_bound < self.swing - margin)
            && (self.twist_lower <= -pi || self.twist_lower + margin < -twist_bound)
            && (self.twist_upper >= pi || twist_bound < self.twist_upper - margin)
            && (self.angle >= pi || angle_bound < self.angle - margin)
    }
}

/// The swing–twist decomposition of a ball joint's rotation and the rates of both angles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwingTwist {
    /// Swing angle θ ∈ [0, π] (rad): the angle between the twist axis `a` and `R a`.
    pub swing: f64,
    /// Twist angle φ ∈ (−π, π] (rad) about `a`.
    pub twist: f64,
    /// `θ̇ = swing_rate · ω` for the child angular velocity ω (child frame, the ball's v): the unit
    /// swing axis, perpendicular to `a` and to `Rᵀ a`, seen in the child frame. Zero at θ = 0,
    /// where the swing direction is undefined.
    pub swing_rate: Vec3,
    /// `φ̇ = twist_rate · ω` (child frame); equal to `a` at the neutral configuration.
    pub twist_rate: Vec3,
    /// Total rotation angle θ = 2 atan2(|(x, y, z)|, |w|) ∈ [0, π] (rad).
    pub angle: f64,
    /// `θ̇ = angle_rate · ω` (child frame): the unit rotation axis, sign(w) (x, y, z)/|(x, y, z)|
    /// (the same in the parent frame: the rotation leaves its axis fixed). Zero at θ = 0.
    pub angle_rate: Vec3,
}

/// Swing–twist decomposition of the unit quaternion `q = [x, y, z, w]` about the unit axis `a`:
/// with `p = (x, y, z)·a`, the twist is `q_t = (w, p a)/√(w² + p²)` and the swing
/// `q_s = q q_t⁻¹`, so `cos(θ/2) = √(w² + p²)` and `φ = 2 atan2(p, w)` (wrapped to (−π, π]).
/// Their rates follow from `q̇ = ½ q ⊗ (0, ω)` (ω in the child frame):
/// `φ̇ = ω·(w² a + w (a × u) + p u)/(w² + p²)` and
/// `θ̇ = ω·(w u − p w a − p (a × u))/(√(w² + p²) sin(θ/2))` with `u = (x, y, z)`; the latter
/// vector has unit length. Undefined (rates zero) only at θ = π exactly. The total angle
/// `2 atan2(|u|, |w|)` changes at the rate of ω along the rotation axis `sign(w) u/|u|`.
pub fn swing_twist(q: &[f64], a: &Vec3) -> SwingTwist {
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    let (u, w) = (Vec3::new(q[0], q[1], q[2]) / norm, q[3] / norm);
    let p = u.dot(a);
    let s2 = w * w + p * p;
    let s = s2.sqrt().min(1.0);
    let swing = 2.0 * s.acos();
    let mut twist = 2.0 * p.atan2(w);
    if twist > std::f64::consts::PI {
        twist -= std::f64::consts::TAU;
    } else if twist <= -std::f64::consts::PI {
        twist += std::f64::consts::TAU;
    }
    let a_cross_u = a.cross(&u);
    let half_sin = (1.0 - s2).max(0.0).sqrt();
    let swing_rate = if half_sin > 1e-12 && s > 1e-12 {
        (u * w - a * (p * w) - a_cross_u * p) / (s * half_sin)
    } else {
        Vec3::zeros()
    };
    let twist_rate = if s2 > 1e-24 { (a * (w * w) + a_cross_u * w + u * p) / s2 } else { Vec3::zeros() };
    let sine = u.norm();
    let angle = 2.0 * sine.atan2(w.abs());
    let angle_rate = if sine > 1e-12 { u * (w.signum() / sine) } else { Vec3::zeros() };
    SwingTwist { swing, twist, swing_rate, twist_rate, angle, angle_rate }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::UnitQuaternion;
    use rand::{Rng, SeedableRng};

    /// Wherever the bounds say "beyond the margin", the exact distances agree; and they say it
    /// for most rotations well inside the limits (the point of the bounds).
    #[test]
    fn surely_beyond_never_hides_a_stop_within_the_margin() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let limits = BallLimits {
            twist_axis: Vec3::new(0.0, 0.6, 0.8),
            swing: 1.2,
            twist_lower: -0.7,
            twist_upper: 0.5,
            angle: 1.1,
        };
        let margin = 0.1;
        let (mut beyond, mut inside) = (0, 0);
        for _ in 0..20_000 {
            let axis = random_unit(&mut rng);
            let angle = rng.random_range(0.0..std::f64::consts::PI);
            let r = UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle);
            let scale = rng.random_range(0.5..2.0) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let q = [r.i * scale, r.j * scale, r.k * scale, r.w * scale];
            let (d, _) = limits.distances(&q);
            let exact = d.iter().all(|d| *d > margin);
            if limits.surely_beyond(&q, margin) {
                assert!(exact, "bounds said beyond, distances {d:?}");
                beyond += 1;
            }
            if exact && d.iter().all(|d| *d > 2.0 * margin) && angle < 0.3 {
                inside += 1;
            }
        }
        assert!(beyond > 0 && beyond >= inside / 2, "{beyond} beyond, {inside} well inside");
    }

    fn random_unit(rng: &mut rand::rngs::StdRng) -> Vec3 {
        loop {
            let v = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if v.norm() > 0.1 && v.norm() < 1.0 {
                return v.normalize();
            }
        }
    }

    fn xyzw(r: &UnitQuaternion<f64>) -> [f64; 4] {
        [r.i, r.j, r.k, r.w]
    }

    #[test]
    fn decomposition_recovers_known_swing_and_twist() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for _ in 0..200 {
            let a = random_unit(&mut rng);
            // A swing axis perpendicular to a, a swing angle in [0, π) and a twist in (−π, π).
            let s_axis = a.cross(&random_unit(&mut rng)).normalize();
            let (theta, phi) = (rng.random_range(0.0..3.0), rng.random_range(-3.1..3.1));
            let r =
                UnitQuaternion::from_scaled_axis(s_axis * theta) * UnitQuaternion::from_scaled_axis(a * phi);
            for sign in [1.0, -1.0] {
                let q = xyzw(&r).map(|x| x * sign); // q and −q are the same rotation
                let st = swing_twist(&q, &a);
                assert!((st.swing - theta).abs() < 1e-9, "swing {} vs {theta}", st.swing);
                assert!((st.twist - phi).abs() < 1e-9, "twist {} vs {phi}", st.twist);
                // The swing angle is the angle between a and R a.
                assert!((a.dot(&(r * a)).clamp(-1.0, 1.0).acos() - theta).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn rates_equal_finite_differences_and_swing_axis_is_perpendicular() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let eps = 1e-7;
        for _ in 0..200 {
            let a = random_unit(&mut rng);
            let r = UnitQuaternion::from_scaled_axis(random_unit(&mut rng) * rng.random_range(0.05..2.9));
            let omega = random_unit(&mut rng);
            let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 }; // q and −q: one rotation
            let q = xyzw(&r).map(|x| x * sign);
            let st = swing_twist(&q, &a);
            let ahead = swing_twist(&xyzw(&(r * UnitQuaternion::from_scaled_axis(omega * eps))), &a);
            let behind = swing_twist(&xyzw(&(r * UnitQuaternion::from_scaled_axis(-omega * eps))), &a);
            let fd_swing = (ahead.swing - behind.swing) / (2.0 * eps);
            let fd_twist = (ahead.twist - behind.twist) / (2.0 * eps);
            let fd_angle = (ahead.angle - behind.angle) / (2.0 * eps);
            assert!((st.angle - r.angle()).abs() < 1e-9, "angle {} vs {}", st.angle, r.angle());
            assert!(
                (st.angle_rate.dot(&omega) - fd_angle).abs() < 1e-6,
                "{} vs {fd_angle}",
                st.angle_rate.dot(&omega)
            );
            assert!((st.angle_rate.norm() - 1.0).abs() < 1e-9);
            // Central differences of smooth functions: error O(eps²) plus rounding ~1e-16/eps.
            assert!(
                (st.swing_rate.dot(&omega) - fd_swing).abs() < 1e-6,
                "{} vs {fd_swing}",
                st.swing_rate.dot(&omega)
            );
            assert!(
                (st.twist_rate.dot(&omega) - fd_twist).abs() < 1e-6,
                "{} vs {fd_twist}",
                st.twist_rate.dot(&omega)
            );
            assert!((st.swing_rate.norm() - 1.0).abs() < 1e-9);
            // Perpendicular to the child's twist axis a and to the parent's seen from the child.
            assert!(st.swing_rate.dot(&a).abs() < 1e-9);
            assert!(st.swing_rate.dot(&(r.inverse() * a)).abs() < 1e-9);
        }
    }
}
