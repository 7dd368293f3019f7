//! Energies and centre of mass: `T = ½ Σ v_iᵀ I_i v_i`, `V = −Σ m_i gᵀ c_i` (zero at the world
//! origin), `c = Σ m_i c_i / Σ m_i`.

use super::check::{check_q, check_result, check_v};
use super::kinematics::{forward_kinematics, joint_step};
use crate::data::Data;
use crate::error::DynamicsError;
use crate::math::{Motion, Vec3};
use crate::model::Model;
use nalgebra::DVector;

/// Kinetic energy (J) at (q, v), also stored in `data.kinetic_energy`.
pub fn kinetic_energy(
    model: &Model,
    data: &mut Data,
    q: &DVector<f64>,
    v: &DVector<f64>,
) -> Result<f64, DynamicsError> {
    check_q(model, q)?;
    check_v(model, v, "v")?;
    let mut total = 0.0;
    data.v[0] = Motion::zero();
    for i in 1..model.nbodies() {
        joint_step(model, data, q, i);
        let (p, iv, nv) = (model.parents[i], model.idx_v[i], model.joints[i].nv());
        let mut v_i = data.x_pb[i].act_inv_motion(&data.v[p]);
        for k in iv..iv + nv {
            v_i += data.s[k] * v[k];
        }
        data.v[i] = v_i;
        total += model.inertias[i].kinetic_energy(&v_i);
    }
    data.kinetic_energy = total;
    check_result(&[total], "kinetic energy")?;
    Ok(total)
}

/// Potential energy in gravity (J), zero when every centre of mass is at the world origin's
/// height; also stored in `data.potential_energy`. Leaves body poses in `data.x_wb`.
pub fn potential_energy(model: &Model, data: &mut Data, q: &DVector<f64>) -> Result<f64, DynamicsError> {
    forward_kinematics(model, data, q)?;
    let g = model.gravity;
    let total: f64 = (1..model.nbodies())
        .map(|i| {
            let inertia = &model.inertias[i];
            -inertia.mass * g.dot(&data.x_wb[i].act_point(&inertia.com()))
        })
        .sum();
    data.potential_energy = total;
    check_result(&[total], "potential energy")?;
    Ok(total)
}

/// Centre of mass of all moving bodies in the world (m), also stored in `data.com`; the world
/// origin for a massless model. Leaves body poses in `data.x_wb`.
pub fn center_of_mass(model: &Model, data: &mut Data, q: &DVector<f64>) -> Result<Vec3, DynamicsError> {
    forward_kinematics(model, data, q)?;
    let mut first_moment = Vec3::zeros();
    let mut mass = 0.0;
    for i in 1..model.nbodies() {
        let inertia = &model.inertias[i];
        first_moment += data.x_wb[i].act_point(&inertia.com()) * inertia.mass;
        mass += inertia.mass;
    }
    data.com = if mass > 0.0 { first_moment / mass } else { Vec3::zeros() };
    check_result(data.com.as_slice(), "centre of mass")?;
    Ok(data.com)
}
