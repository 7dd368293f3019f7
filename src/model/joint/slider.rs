//! Slider (prismatic) joint: translation along a fixed unit axis, `x_jc = (1, d a)`, `S = [a; 0]`.

use crate::math::{Motion, Transform, Vec3};

pub(super) fn transform_and_subspace(axis: &Vec3, q: &[f64], s: &mut [Motion]) -> Transform {
    s[0] = Motion::new(*axis, Vec3::zeros());
    Transform::from_translation(axis * q[0])
}
