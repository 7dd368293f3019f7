//! Stage 1: a NaN or infinity in a state is an error, named by its multibody and joint, before
//! the step and after it.

use crate::model::Model;
use crate::world::{Multibody, StepError};
use nalgebra::DVector;

/// Every multibody's q and v are finite.
pub(crate) fn states(bodies: &[Multibody], names: &[String]) -> Result<(), StepError> {
    for (i, b) in bodies.iter().enumerate() {
        finite(&names[i], &b.model, &b.state.q, &b.state.v, false)?;
    }
    Ok(())
}

/// `q` and `v` of multibody `name` are finite; `after`: they are the step's new state.
pub(crate) fn finite(
    name: &str,
    model: &Model,
    q: &DVector<f64>,
    v: &DVector<f64>,
    after: bool,
) -> Result<(), StepError> {
    if crate::math::all_finite(q.as_slice()) && crate::math::all_finite(v.as_slice()) {
        return Ok(());
    }
    let joint_of_q = |k: usize| (1..model.nbodies()).rev().find(|&i| model.idx_q(i) <= k).unwrap_or(0);
    let joint_of_v = |k: usize| if k < model.nv() { model.dof_joint(k) } else { 0 };
    if let Some(k) = q.iter().position(|x| !x.is_finite()) {
        return Err(StepError::NonFinite {
            multibody: name.to_string(),
            joint: model.joint_name(joint_of_q(k)).to_string(),
            what: if after { "new q" } else { "q" },
        });
    }
    if let Some(k) = v.iter().position(|x| !x.is_finite()) {
        return Err(StepError::NonFinite {
            multibody: name.to_string(),
            joint: model.joint_name(joint_of_v(k)).to_string(),
            what: if after { "new v" } else { "v" },
        });
    }
    Ok(())
}

/// The error of multibody `name`'s dynamics.
pub(crate) fn dynamics_error(name: &str) -> impl Fn(crate::error::DynamicsError) -> StepError + '_ {
    move |source| StepError::Dynamics { multibody: name.to_string(), source }
}
