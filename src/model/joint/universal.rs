//! Universal joint: `R = exp(θ₁ a₁) exp(θ₂ a₂)`, a₁ fixed in the parent, a₂ fixed in the child.
//!
//! Child angular velocity in the child frame: `ω = R₂ᵀ a₁ θ̇₁ + a₂ θ̇₂`, so
//! `S = [[0, 0], [R₂ᵀ a₁, a₂]]`; its apparent derivative gives
//! `cJ = [0; θ̇₁ θ̇₂ (R₂ᵀ a₁) × a₂]`.

use crate::math::{axis_angle, Mat3, Motion, Transform, Vec3};

/// Rotation of the two-axis joint and `R₂ᵀ a₁` (the first axis seen from the child frame).
#[inline]
pub(super) fn two_axis_rotation(axis1: &Vec3, axis2: &Vec3, theta1: f64, theta2: f64) -> (Mat3, Vec3) {
    let r1 = axis_angle(axis1, theta1);
    let r2 = axis_angle(axis2, theta2);
    (r1 * r2, r2.tr_mul(axis1))
}

pub(super) fn transform_and_subspace(axis1: &Vec3, axis2: &Vec3, q: &[f64], s: &mut [Motion]) -> Transform {
    let (r, a1_child) = two_axis_rotation(axis1, axis2, q[0], q[1]);
    s[0] = Motion::new(Vec3::zeros(), a1_child);
    s[1] = Motion::new(Vec3::zeros(), *axis2);
    Transform::new(r, Vec3::zeros())
}

pub(super) fn bias(axis2: &Vec3, s: &[Motion], v: &[f64]) -> Motion {
    Motion::new(Vec3::zeros(), s[0].angular.cross(axis2) * (v[0] * v[1]))
}
