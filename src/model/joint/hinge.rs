//! Hinge (revolute) joint: rotation about a fixed unit axis, `x_jc = (exp(θ a), 0)`, `S = [0; a]`.

use crate::math::{exp3, Motion, Transform, Vec3};

pub(super) fn transform_and_subspace(axis: &Vec3, q: &[f64], s: &mut [Motion]) -> Transform {
    s[0] = Motion::new(Vec3::zeros(), *axis);
    Transform::new(exp3(&(axis * q[0])), Vec3::zeros())
}
