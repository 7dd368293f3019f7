//! Recursive Newton–Euler algorithm (Featherstone, RBDA §5.3): inverse dynamics
//! `τ = M(q) a + C(q, v) v + g(q)`, in body frames.
//!
//! Forward pass: `v_i = ⁱX_λ v_λ + S_i q̇_i`, `a_i = ⁱX_λ a_λ + S_i q̈_i + cJ_i + v_i × S_i q̇_i`
//! with `a_0 = −g`; `f_i = I_i a_i + v_i ×* I_i v_i`. Backward pass: `τ_i = S_iᵀ f_i`,
//! `f_λ += ^λX*_i f_i`.

use super::check::{check_q, check_result_v, check_v};
use super::kinematics::joint_step;
use crate::data::Data;
use crate::error::DynamicsError;
use crate::math::{Motion, Vec3};
use crate::model::Model;
use nalgebra::DVector;

/// Inverse dynamics: joint forces `τ = M(q) a + C(q, v) v + g(q)` (N·m / N), written to
/// `data.tau` and returned.
pub fn rnea<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &DVector<f64>,
    v: &DVector<f64>,
    a: &DVector<f64>,
) -> Result<&'d DVector<f64>, DynamicsError> {
    check_q(model, q)?;
    check_v(model, v, "v")?;
    check_v(model, a, "a")?;
    rnea_passes(model, data, Some(q), Some(v), Some(a));
    check_result_v(model, &data.tau, "rnea")?;
    Ok(&data.tau)
}

/// Nonlinear effects `C(q, v) v + g(q)` = `rnea(q, v, 0)`, written to `data.nle` and returned.
pub fn nonlinear_effects<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &DVector<f64>,
    v: &DVector<f64>,
) -> Result<&'d DVector<f64>, DynamicsError> {
    check_q(model, q)?;
    check_v(model, v, "v")?;
    rnea_passes(model, data, Some(q), Some(v), None);
    data.nle.copy_from(&data.tau);
    check_result_v(model, &data.nle, "nonlinear effects")?;
    Ok(&data.nle)
}

/// [`nonlinear_effects`] with the joint transforms and motion subspaces already in `data` from
/// [`crate::algorithms::compute_joint_jacobians`] at the same q (the world's step computes them
/// in its kinematics phase): `v` must have nv entries (not checked again).
pub(crate) fn nonlinear_effects_at_kinematics<'d>(
    model: &Model,
    data: &'d mut Data,
    v: &DVector<f64>,
) -> &'d DVector<f64> {
    rnea_passes(model, data, None, Some(v), None);
    data.nle.copy_from(&data.tau);
    &data.nle
}

/// Generalized gravity `g(q)` = `rnea(q, 0, 0)`, written to `data.gravity_torque` and returned.
pub fn generalized_gravity<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &DVector<f64>,
) -> Result<&'d DVector<f64>, DynamicsError> {
    check_q(model, q)?;
    rnea_passes(model, data, Some(q), None, None);
    data.gravity_torque.copy_from(&data.tau);
    check_result_v(model, &data.gravity_torque, "generalized gravity")?;
    Ok(&data.gravity_torque)
}

/// Both passes of RNEA into `data.tau`; `None` stands for a zero vector of v or a. With `q`
/// `None` the joint transforms and motion subspaces in `data` are taken as current (from
/// [`crate::algorithms::compute_joint_jacobians`] at the same q).
pub(crate) fn rnea_passes(
    model: &Model,
    data: &mut Data,
    q: Option<&DVector<f64>>,
    v: Option<&DVector<f64>>,
    a: Option<&DVector<f64>>,
) {
    data.v[0] = Motion::zero();
    data.a[0] = Motion::new(-model.gravity, Vec3::zeros());
    for i in 1..model.nbodies() {
        if let Some(q) = q {
            joint_step(model, data, q, i);
        }
        let (p, iv, joint) = (model.parents[i], model.idx_v[i], &model.joints[i]);
        let nv = joint.nv();
        let x = data.x_pb[i];
        let s = &data.s[iv..iv + nv];
        let mut a_i = x.act_inv_motion(&data.a[p]);
        if let Some(a) = a {
            for (col, ak) in s.iter().zip(&a.as_slice()[iv..iv + nv]) {
                a_i += *col * *ak;
            }
        }
        let v_i = if let Some(v) = v {
            let vq = &v.as_slice()[iv..iv + nv];
            let mut v_j = Motion::zero();
            for (col, vk) in s.iter().zip(vq) {
                v_j += *col * *vk;
            }
            let v_i = x.act_inv_motion(&data.v[p]) + v_j;
            if joint.has_bias() {
                a_i += joint.bias(s, vq);
            }
            a_i += v_i.cross(&v_j);
            v_i
        } else {
            Motion::zero()
        };
        let inertia = &model.inertias[i];
        data.v[i] = v_i;
        data.a[i] = a_i;
        data.f[i] = inertia.mul_motion(&a_i) + v_i.cross_force(&inertia.mul_motion(&v_i));
    }
    for i in (1..model.nbodies()).rev() {
        let (p, iv, nv) = (model.parents[i], model.idx_v[i], model.joints[i].nv());
        let f = data.f[i];
        for k in iv..iv + nv {
            data.tau[k] = data.s[k].dot(&f);
        }
        if p != 0 {
            let f_p = data.x_pb[i].act_force(&f);
            data.f[p] += f_p;
        }
    }
}
