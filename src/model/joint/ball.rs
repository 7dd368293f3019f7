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
