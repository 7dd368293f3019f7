//! Input checks shared by the algorithms: lengths once, then finiteness, naming the joint.

use crate::error::DynamicsError;
use crate::model::Model;
use nalgebra::DVector;

/// Checks that `q` has nq finite entries.
pub(crate) fn check_q(model: &Model, q: &DVector<f64>) -> Result<(), DynamicsError> {
    check(model, q, "q", model.nq(), |m, k| m.joint_of_q(k))?;
    model.check_quaternions(q.as_slice())
}

/// Checks that a velocity-sized vector (`v`, `a`, `tau`) has nv finite entries.
pub(crate) fn check_v(model: &Model, x: &DVector<f64>, what: &'static str) -> Result<(), DynamicsError> {
    check(model, x, what, model.nv(), |m, k| m.dof_joint(k))
}

fn check(
    model: &Model,
    x: &DVector<f64>,
    what: &'static str,
    expected: usize,
    owner: impl Fn(&Model, usize) -> usize,
) -> Result<(), DynamicsError> {
    if x.len() != expected {
        return Err(DynamicsError::DimensionMismatch { what, expected, got: x.len() });
    }
    if crate::math::all_finite(x.as_slice()) {
        return Ok(());
    }
    match x.iter().position(|e| !e.is_finite()) {
        None => Ok(()),
        Some(index) => Err(DynamicsError::NonFinite {
            what,
            index,
            joint: model.joint_name(owner(model, index)).to_string(),
        }),
    }
}

/// Checks that a velocity-sized result (`tau`, `nle`, `ddq`, …) is finite, naming the joint of
/// its first non-finite entry.
pub(crate) fn check_result_v(
    model: &Model,
    x: &DVector<f64>,
    what: &'static str,
) -> Result<(), DynamicsError> {
    match x.iter().position(|e| !e.is_finite()) {
        None => Ok(()),
        Some(index) => Err(DynamicsError::NonFiniteResult {
            what,
            at: format!("joint `{}`", model.joint_name(model.dof_joint(index))),
        }),
    }
}

/// Checks that a scalar or a 3-vector result of the whole model is finite.
pub(crate) fn check_result(values: &[f64], what: &'static str) -> Result<(), DynamicsError> {
    if values.iter().all(|e| e.is_finite()) {
        Ok(())
    } else {
        Err(DynamicsError::NonFiniteResult { what, at: "the model".to_string() })
    }
}
