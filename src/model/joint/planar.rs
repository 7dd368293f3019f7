//! Planar joint: q = [x, y, θ] in the joint frame's xy-plane, v = `[vx, vy, ω]` of the child frame
//! in the child frame; `S = [e_x; 0], [e_y; 0], [0; e_z]`. Integration by the SE(2) exponential.

use crate::math::{Mat3, Motion, Transform, Vec3};

pub(super) fn transform_and_subspace(q: &[f64], s: &mut [Motion]) -> Transform {
    s[0] = Motion::new(Vec3::x(), Vec3::zeros());
    s[1] = Motion::new(Vec3::y(), Vec3::zeros());
    s[2] = Motion::new(Vec3::zeros(), Vec3::z());
    let (sn, cs) = q[2].sin_cos();
    let r = Mat3::new(cs, -sn, 0.0, sn, cs, 0.0, 0.0, 0.0, 1.0);
    Transform::new(r, Vec3::new(q[0], q[1], 0.0))
}

/// `sin φ / φ` and `(1 − cos φ)/φ`, accurate near zero.
fn se2_coefficients(phi: f64) -> (f64, f64) {
    if phi.abs() < 1e-4 {
        (1.0 - phi * phi / 6.0, phi / 2.0 - phi * phi * phi / 24.0)
    } else {
        (phi.sin() / phi, (1.0 - phi.cos()) / phi)
    }
}

pub(super) fn integrate(q: &[f64], v: &[f64], dt: f64, q_out: &mut [f64]) {
    let phi = v[2] * dt;
    let (a, b) = se2_coefficients(phi);
    // displacement in the start pose's frame: V(φ) v dt
    let dx = (a * v[0] - b * v[1]) * dt;
    let dy = (b * v[0] + a * v[1]) * dt;
    let (sn, cs) = q[2].sin_cos();
    q_out[0] = q[0] + cs * dx - sn * dy;
    q_out[1] = q[1] + sn * dx + cs * dy;
    q_out[2] = q[2] + phi;
}

/// The decoupled step on R² × SO(2): the origin moves along the straight line `R(θ) (vx, vy) dt`,
/// the angle by `ω dt` (see `free::integrate_decoupled`).
pub(super) fn integrate_decoupled(q: &[f64], v: &[f64], dt: f64, q_out: &mut [f64]) {
    let (sn, cs) = q[2].sin_cos();
    q_out[0] = q[0] + (cs * v[0] - sn * v[1]) * dt;
    q_out[1] = q[1] + (sn * v[0] + cs * v[1]) * dt;
    q_out[2] = q[2] + v[2] * dt;
}

pub(super) fn difference(q0: &[f64], q1: &[f64], v_out: &mut [f64]) {
    let phi = q1[2] - q0[2];
    let (sn, cs) = q0[2].sin_cos();
    let (ex, ey) = (q1[0] - q0[0], q1[1] - q0[1]);
    let (lx, ly) = (cs * ex + sn * ey, -sn * ex + cs * ey);
    let (a, b) = se2_coefficients(phi);
    // invert V(φ) = [[a, −b], [b, a]]
    let det = a * a + b * b;
    v_out[0] = (a * lx + b * ly) / det;
    v_out[1] = (-b * lx + a * ly) / det;
    v_out[2] = phi;
}
