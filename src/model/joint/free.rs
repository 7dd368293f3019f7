//! Free (floating) joint: q = [p; quaternion (x, y, z, w)], v = `[v; ω]` in the child frame,
//! `S = 1₆`. Integration by the SE(3) exponential of the body twist: `X ← X exp(ξ dt)`.

use super::{read_quaternion, write_quaternion};
use crate::math::{exp3, log3, skew, Mat3, Motion, Transform, Vec3};
use nalgebra::UnitQuaternion;

pub(super) fn transform_and_subspace(q: &[f64], s: &mut [Motion]) -> Transform {
    for (k, col) in s.iter_mut().enumerate() {
        *col = if k < 3 {
            Motion::new(Vec3::ith(k, 1.0), Vec3::zeros())
        } else {
            Motion::new(Vec3::zeros(), Vec3::ith(k - 3, 1.0))
        };
    }
    Transform::new(read_quaternion(&q[3..7]).to_rotation_matrix().into_inner(), Vec3::new(q[0], q[1], q[2]))
}

/// The SE(3) exponential of a body twist `[v; ω]`: `(exp3(ω), V(ω) v)` with
/// `V = 1 + (1 − cos θ)/θ² [ω]× + (θ − sin θ)/θ³ [ω]×²`.
pub(crate) fn exp6(v: &Vec3, w: &Vec3) -> Transform {
    let t2 = w.norm_squared();
    let t = t2.sqrt();
    let (b, c) = if t < 1e-4 {
        (0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0)
    } else {
        ((1.0 - t.cos()) / t2, (t - t.sin()) / (t2 * t))
    };
    let k = skew(w);
    let vmat = Mat3::identity() + k * b + k * k * c;
    Transform::new(exp3(w), vmat * v)
}

/// The SE(3) logarithm: the body twist `[v; ω]` with `exp6(v, ω) = x`.
pub(crate) fn log6(x: &Transform) -> (Vec3, Vec3) {
    let w = log3(&x.rotation);
    let t2 = w.norm_squared();
    let t = t2.sqrt();
    let d =
        if t < 1e-4 { 1.0 / 12.0 + t2 / 720.0 } else { (1.0 - t * t.sin() / (2.0 * (1.0 - t.cos()))) / t2 };
    let k = skew(&w);
    let vinv = Mat3::identity() - k * 0.5 + k * k * d;
    (vinv * x.translation, w)
}

fn pose(q: &[f64]) -> (UnitQuaternion<f64>, Vec3) {
    (read_quaternion(&q[3..7]), Vec3::new(q[0], q[1], q[2]))
}

pub(super) fn integrate(q: &[f64], v: &[f64], dt: f64, q_out: &mut [f64]) {
    let (r, p) = pose(q);
    let step = exp6(&(Vec3::new(v[0], v[1], v[2]) * dt), &(Vec3::new(v[3], v[4], v[5]) * dt));
    let p_new = p + r * step.translation;
    let mut r_new = r * UnitQuaternion::from_matrix(&step.rotation);
    r_new.renormalize();
    q_out[0..3].copy_from_slice(p_new.as_slice());
    write_quaternion(&r_new, &mut q_out[3..7]);
}

/// The step of rigid-body engines (ODE, MuJoCo) on R³ × SO(3): the origin moves along the
/// straight line `p + R v dt` (R at the start, so `R v` is the origin's world velocity), the
/// orientation turns by `exp(ω dt)`. Unlike the SE(3) screw of [`integrate`], the origin does
/// not curve with the rotation, so a ball rolling without slip (contact point at rest) keeps its
/// centre on the plane; both agree to first order in dt.
pub(super) fn integrate_decoupled(q: &[f64], v: &[f64], dt: f64, q_out: &mut [f64]) {
    let (r, p) = pose(q);
    let p_new = p + r * (Vec3::new(v[0], v[1], v[2]) * dt);
    let mut r_new = r * UnitQuaternion::from_scaled_axis(Vec3::new(v[3], v[4], v[5]) * dt);
    r_new.renormalize();
    q_out[0..3].copy_from_slice(p_new.as_slice());
    write_quaternion(&r_new, &mut q_out[3..7]);
}

pub(super) fn difference(q0: &[f64], q1: &[f64], v_out: &mut [f64]) {
    let (r0, p0) = pose(q0);
    let (r1, p1) = pose(q1);
    let rel = Transform::new((r0.inverse() * r1).to_rotation_matrix().into_inner(), r0.inverse() * (p1 - p0));
    let (v, w) = log6(&rel);
    v_out[0..3].copy_from_slice(v.as_slice());
    v_out[3..6].copy_from_slice(w.as_slice());
}
