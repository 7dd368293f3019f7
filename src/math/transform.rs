//! Rigid transforms (poses) and the SO(3) exponential and logarithm.

use super::{Force, Mat3, Motion, Vec3};
use nalgebra::{Quaternion, UnitQuaternion};
use std::ops::Mul;

/// A rigid transform `x_ab`: the pose of frame B in frame A. It maps B coordinates to A
/// coordinates, `p_a = rotation · p_b + translation` (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Rotation `R_ab` (columns are B's axes in A).
    pub rotation: Mat3,
    /// Translation `t_ab`: B's origin in A coordinates (m).
    pub translation: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self::identity()
    }
}

/// The skew-symmetric matrix `[x]×` with `[x]× y = x × y`.
#[inline]
pub fn skew(x: &Vec3) -> Mat3 {
    Mat3::new(0.0, -x.z, x.y, x.z, 0.0, -x.x, -x.y, x.x, 0.0)
}

/// The SO(3) exponential (Rodrigues' formula): the rotation by `|w|` radians about `w/|w|`.
pub fn exp3(w: &Vec3) -> Mat3 {
    let t2 = w.norm_squared();
    let t = t2.sqrt();
    // Taylor expansions keep sin(t)/t and (1 - cos t)/t² accurate near zero.
    let (a, b) =
        if t < 1e-4 { (1.0 - t2 / 6.0, 0.5 - t2 / 24.0) } else { (t.sin() / t, (1.0 - t.cos()) / t2) };
    let k = skew(w);
    Mat3::identity() + k * a + k * k * b
}

/// Rotation by `angle` radians about the unit vector `axis` (Rodrigues' formula written out:
/// `R = cos θ 1 + sin θ [a]× + (1 − cos θ) a aᵀ`), cheaper than [`exp3`] when the axis is known.
#[inline]
pub fn axis_angle(axis: &Vec3, angle: f64) -> Mat3 {
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    let (x, y, z) = (axis.x, axis.y, axis.z);
    let (tx, ty, tz) = (t * x, t * y, t * z);
    Mat3::new(
        tx * x + c,
        tx * y - s * z,
        tx * z + s * y,
        tx * y + s * z,
        ty * y + c,
        ty * z - s * x,
        tx * z - s * y,
        ty * z + s * x,
        tz * z + c,
    )
}

/// The SO(3) logarithm: the rotation vector `w` with `exp3(w) = r` and `|w| ≤ π`.
pub fn log3(r: &Mat3) -> Vec3 {
    let q = UnitQuaternion::from_matrix(r);
    quat_log(&q)
}

/// Rotation vector of a unit quaternion, angle in [0, π].
pub(crate) fn quat_log(q: &UnitQuaternion<f64>) -> Vec3 {
    let (w, v) = if q.w < 0.0 { (-q.w, -q.imag()) } else { (q.w, q.imag()) };
    let s = v.norm();
    if s < 1e-8 {
        // angle = 2 atan2(s, w) ≈ 2 s / w
        v * (2.0 / w)
    } else {
        v * (2.0 * s.atan2(w) / s)
    }
}

/// Unit quaternion of the rotation vector `w` (the exponential map on S³).
pub(crate) fn quat_exp(w: &Vec3) -> UnitQuaternion<f64> {
    let t = w.norm();
    let half = 0.5 * t;
    let s = if t < 1e-6 { 0.5 - t * t / 48.0 } else { half.sin() / t };
    UnitQuaternion::new_unchecked(Quaternion::new(half.cos(), w.x * s, w.y * s, w.z * s))
}

impl Transform {
    /// The identity pose.
    #[inline]
    pub fn identity() -> Self {
        Self { rotation: Mat3::identity(), translation: Vec3::zeros() }
    }

    /// A pose from a rotation matrix and a translation (m).
    #[inline]
    pub fn new(rotation: Mat3, translation: Vec3) -> Self {
        Self { rotation, translation }
    }

    /// A pure translation (m).
    #[inline]
    pub fn from_translation(translation: Vec3) -> Self {
        Self { rotation: Mat3::identity(), translation }
    }

    /// A pose from a translation (m) and a quaternion given as `[x, y, z, w]`; the quaternion is
    /// normalized.
    pub fn from_translation_quaternion(translation: Vec3, xyzw: [f64; 4]) -> Self {
        let q = UnitQuaternion::from_quaternion(Quaternion::new(xyzw[3], xyzw[0], xyzw[1], xyzw[2]));
        Self { rotation: q.to_rotation_matrix().into_inner(), translation }
    }

    /// A pose from a translation (m) and roll-pitch-yaw angles (rad), as URDF's `origin`:
    /// `R = Rz(yaw) Ry(pitch) Rx(roll)`.
    pub fn from_xyz_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> Self {
        let r = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]);
        Self { rotation: r.to_rotation_matrix().into_inner(), translation: Vec3::new(xyz[0], xyz[1], xyz[2]) }
    }

    /// The rotation as a unit quaternion, `[x, y, z, w]` with `w ≥ 0`.
    pub fn quaternion_xyzw(&self) -> [f64; 4] {
        let q = UnitQuaternion::from_matrix(&self.rotation);
        let c = if q.w < 0.0 { -q.coords } else { q.coords };
        [c.x, c.y, c.z, c.w]
    }

    /// The inverse pose `x_ba`.
    #[inline]
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self { rotation: rt, translation: -(rt * self.translation) }
    }

    /// Maps a point from B to A coordinates.
    #[inline]
    pub fn act_point(&self, p_b: &Vec3) -> Vec3 {
        self.rotation * p_b + self.translation
    }

    /// Maps a point from A to B coordinates.
    #[inline]
    pub fn act_inv_point(&self, p_a: &Vec3) -> Vec3 {
        self.rotation.tr_mul(&(p_a - self.translation))
    }

    /// Re-expresses a motion given in B into A (Featherstone's `aXb m`).
    #[inline]
    pub fn act_motion(&self, m_b: &Motion) -> Motion {
        let angular = self.rotation * m_b.angular;
        Motion { linear: self.rotation * m_b.linear + self.translation.cross(&angular), angular }
    }

    /// Re-expresses a motion given in A into B (`bXa m`).
    #[inline]
    pub fn act_inv_motion(&self, m_a: &Motion) -> Motion {
        Motion {
            linear: self.rotation.tr_mul(&(m_a.linear - self.translation.cross(&m_a.angular))),
            angular: self.rotation.tr_mul(&m_a.angular),
        }
    }

    /// Re-expresses a force given in B into A (`aXb* f`).
    #[inline]
    pub fn act_force(&self, f_b: &Force) -> Force {
        let linear = self.rotation * f_b.linear;
        Force { linear, angular: self.rotation * f_b.angular + self.translation.cross(&linear) }
    }

    /// Re-expresses a force given in A into B (`bXa* f`).
    #[inline]
    pub fn act_inv_force(&self, f_a: &Force) -> Force {
        Force {
            linear: self.rotation.tr_mul(&f_a.linear),
            angular: self.rotation.tr_mul(&(f_a.angular - self.translation.cross(&f_a.linear))),
        }
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.rotation.iter().chain(self.translation.iter()).all(|x| x.is_finite())
    }
}

impl Mul for Transform {
    type Output = Transform;
    /// Composition `x_ac = x_ab * x_bc`.
    #[inline]
    fn mul(self, o: Transform) -> Transform {
        Transform {
            rotation: self.rotation * o.rotation,
            translation: self.rotation * o.translation + self.translation,
        }
    }
}

impl Mul<&Transform> for &Transform {
    type Output = Transform;
    #[inline]
    fn mul(self, o: &Transform) -> Transform {
        Transform {
            rotation: self.rotation * o.rotation,
            translation: self.rotation * o.translation + self.translation,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn exp_log_round_trip() {
        for w in [Vec3::new(0.3, -1.2, 2.0), Vec3::new(1e-9, 0.0, 2e-9), Vec3::new(0.0, 3.1, 0.0)] {
            let r = exp3(&w);
            assert_relative_eq!(r.transpose() * r, Mat3::identity(), epsilon = 1e-14);
            assert_relative_eq!(log3(&r), w, epsilon = 1e-12);
            let q = quat_exp(&w);
            assert_relative_eq!(q.to_rotation_matrix().into_inner(), r, epsilon = 1e-14);
            let n = w.norm();
            assert_relative_eq!(axis_angle(&(w / n), n), r, epsilon = 1e-14);
        }
    }

    #[test]
    fn motion_and_force_actions_preserve_power() {
        let x = Transform::from_xyz_rpy([0.1, -0.4, 0.7], [0.3, -0.2, 1.1]);
        let m = Motion::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(-0.5, 0.2, 0.9));
        let f = Force::new(Vec3::new(0.3, -2.0, 1.0), Vec3::new(0.1, 0.4, -0.7));
        assert_relative_eq!(x.act_motion(&m).dot(&x.act_force(&f)), m.dot(&f), epsilon = 1e-12);
        let back = x.act_inv_motion(&x.act_motion(&m));
        assert_relative_eq!(back.to_vector(), m.to_vector(), epsilon = 1e-12);
        let back = x.act_inv_force(&x.act_force(&f));
        assert_relative_eq!(back.to_vector(), f.to_vector(), epsilon = 1e-12);
        let id = x * x.inverse();
        assert_relative_eq!(id.rotation, Mat3::identity(), epsilon = 1e-12);
        assert_relative_eq!(id.translation, Vec3::zeros(), epsilon = 1e-12);
    }
}
