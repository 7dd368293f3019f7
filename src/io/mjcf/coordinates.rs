//! MuJoCo's `qpos` and `qvel` and gelenk's q and v for a model loaded from MJCF: the same joint
//! order, different quaternion and free-joint velocity conventions.

use crate::error::DynamicsError;
use crate::math::{Mat3, Vec3};
use crate::model::{Joint, Model};
use nalgebra::{DVector, Quaternion, UnitQuaternion};

/// Converts MuJoCo's `qpos` to gelenk's q for a model loaded from MJCF (same joint order):
/// quaternions go from (w, x, y, z) to (x, y, z, w).
pub fn q_from_mujoco(model: &Model, qpos: &[f64]) -> Result<DVector<f64>, DynamicsError> {
    check_len("qpos", model.nq(), qpos.len())?;
    let mut q = DVector::from_column_slice(qpos);
    for i in 1..model.nbodies() {
        let a = model.idx_q(i);
        match model.joint(i) {
            Joint::Free => q.as_mut_slice()[a + 3..a + 7].rotate_left(1),
            Joint::Ball => q.as_mut_slice()[a..a + 4].rotate_left(1),
            _ => {}
        }
    }
    Ok(q)
}

/// Converts gelenk's q to MuJoCo's `qpos` (the inverse of [`q_from_mujoco`]).
pub fn q_to_mujoco(model: &Model, q: &DVector<f64>) -> Result<DVector<f64>, DynamicsError> {
    check_len("q", model.nq(), q.len())?;
    let mut qpos = q.clone();
    for i in 1..model.nbodies() {
        let a = model.idx_q(i);
        match model.joint(i) {
            Joint::Free => qpos.as_mut_slice()[a + 3..a + 7].rotate_right(1),
            Joint::Ball => qpos.as_mut_slice()[a..a + 4].rotate_right(1),
            _ => {}
        }
    }
    Ok(qpos)
}

/// Converts MuJoCo's `qvel` to gelenk's v at configuration `q` (gelenk's): a free joint's linear
/// velocity is in world axes in MuJoCo and in body axes in gelenk (`v = Rᵀ v_mujoco`); angular
/// velocities are in body axes in both. Other joints are the same.
pub fn v_from_mujoco(model: &Model, q: &DVector<f64>, qvel: &[f64]) -> Result<DVector<f64>, DynamicsError> {
    check_len("q", model.nq(), q.len())?;
    check_len("qvel", model.nv(), qvel.len())?;
    let mut v = DVector::from_column_slice(qvel);
    for i in 1..model.nbodies() {
        if *model.joint(i) == Joint::Free {
            let (a, d) = (model.idx_q(i), model.idx_v(i));
            let lin = free_rotation(q, a).tr_mul(&Vec3::new(qvel[d], qvel[d + 1], qvel[d + 2]));
            v.as_mut_slice()[d..d + 3].copy_from_slice(lin.as_slice());
        }
    }
    Ok(v)
}

/// Converts gelenk's v to MuJoCo's `qvel` at configuration `q` (the inverse of
/// [`v_from_mujoco`]).
pub fn v_to_mujoco(model: &Model, q: &DVector<f64>, v: &DVector<f64>) -> Result<DVector<f64>, DynamicsError> {
    check_len("q", model.nq(), q.len())?;
    check_len("v", model.nv(), v.len())?;
    let mut qvel = v.clone();
    for i in 1..model.nbodies() {
        if *model.joint(i) == Joint::Free {
            let (a, d) = (model.idx_q(i), model.idx_v(i));
            let lin = free_rotation(q, a) * Vec3::new(v[d], v[d + 1], v[d + 2]);
            qvel.as_mut_slice()[d..d + 3].copy_from_slice(lin.as_slice());
        }
    }
    Ok(qvel)
}

fn check_len(what: &'static str, expected: usize, got: usize) -> Result<(), DynamicsError> {
    if expected != got {
        return Err(DynamicsError::DimensionMismatch { what, expected, got });
    }
    Ok(())
}

fn free_rotation(q: &DVector<f64>, a: usize) -> Mat3 {
    let quat = Quaternion::new(q[a + 6], q[a + 3], q[a + 4], q[a + 5]);
    UnitQuaternion::from_quaternion(quat).to_rotation_matrix().into_inner()
}
