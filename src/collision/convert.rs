//! The one place where gelenk's nalgebra types meet parry's glam types.

use crate::math::{Mat3, Transform, Vec3};
use parry3d_f64::math::{Mat3 as PMat3, Pose, Rotation, Vector};

/// A gelenk vector as a parry vector.
#[inline]
pub(crate) fn to_vector(v: &Vec3) -> Vector {
    Vector::new(v.x, v.y, v.z)
}

/// A parry vector as a gelenk vector.
#[inline]
pub(crate) fn from_vector(v: Vector) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

/// A gelenk rigid transform as a parry pose (rotation as a unit quaternion).
#[inline]
pub(crate) fn to_pose(x: &Transform) -> Pose {
    let r = &x.rotation;
    let m = PMat3::from_cols(
        Vector::new(r[(0, 0)], r[(1, 0)], r[(2, 0)]),
        Vector::new(r[(0, 1)], r[(1, 1)], r[(2, 1)]),
        Vector::new(r[(0, 2)], r[(1, 2)], r[(2, 2)]),
    );
    Pose::from_parts(to_vector(&x.translation), Rotation::from_mat3(&m).normalize())
}

/// A parry pose as a gelenk rigid transform.
#[inline]
pub(crate) fn from_pose(p: &Pose) -> Transform {
    let m = PMat3::from_quat(p.rotation);
    let rotation = Mat3::from_columns(&[from_vector(m.x_axis), from_vector(m.y_axis), from_vector(m.z_axis)]);
    Transform::new(rotation, from_vector(p.translation))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::axis_angle;

    #[test]
    fn pose_round_trip() {
        let x = Transform::new(
            axis_angle(&Vec3::new(0.3, -0.5, 0.8).normalize(), 2.1),
            Vec3::new(1.0, -2.0, 3.0),
        );
        let back = from_pose(&to_pose(&x));
        assert!((back.rotation - x.rotation).abs().max() < 1e-14);
        assert!((back.translation - x.translation).abs().max() < 1e-15);
        let p = Vec3::new(0.2, 0.4, -0.7);
        let via_parry = from_vector(to_pose(&x).transform_point(to_vector(&p)));
        assert!((via_parry - x.act_point(&p)).abs().max() < 1e-14);
    }
}
