//! Hinge2 joint (ODE's steer + spin wheel joint) in generalized coordinates.
//!
//! q = [s,] θ₁, θ₂: optional suspension travel s along a₁, steering θ₁ about a₁ (fixed in the
//! parent), spin θ₂ about a₂ (fixed in the child). `x_jc = (exp(θ₁ a₁) exp(θ₂ a₂), s a₁)`.
//! With `b = R₂ᵀ a₁` (a₁ in the child frame) the subspace is `S = [[b, 0, 0], [0, b, a₂]]` and
//! `ḃ = θ̇₂ b × a₂`, so `cJ = [ṡ θ̇₂ b × a₂; θ̇₁ θ̇₂ b × a₂]`. Without suspension the joint is
//! kinematically a universal joint.

use super::universal::two_axis_rotation;
use crate::math::{Motion, Transform, Vec3};

pub(super) fn transform_and_subspace(
    axis1: &Vec3,
    axis2: &Vec3,
    suspension: bool,
    q: &[f64],
    s: &mut [Motion],
) -> Transform {
    let off = usize::from(suspension);
    let (r, b) = two_axis_rotation(axis1, axis2, q[off], q[off + 1]);
    if suspension {
        s[0] = Motion::new(b, Vec3::zeros());
    }
    s[off] = Motion::new(Vec3::zeros(), b);
    s[off + 1] = Motion::new(Vec3::zeros(), *axis2);
    let travel = if suspension { axis1 * q[0] } else { Vec3::zeros() };
    Transform::new(r, travel)
}

pub(super) fn bias(axis2: &Vec3, suspension: bool, s: &[Motion], v: &[f64]) -> Motion {
    let off = usize::from(suspension);
    let b_dot = s[off].angular.cross(axis2) * v[off + 1];
    let linear = if suspension { b_dot * v[0] } else { Vec3::zeros() };
    Motion::new(linear, b_dot * v[off])
}
