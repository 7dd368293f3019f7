//! Forward kinematics: every body's pose, `x_wb(i) = x_wb(λ(i)) · placement(i) · x_jc(q_i)`.

use super::check::check_q;
use crate::data::Data;
use crate::error::DynamicsError;
use crate::math::Transform;
use crate::model::Model;
use nalgebra::DVector;

/// Computes `data.x_pb` (pose in the parent body), `data.x_wb` (pose in the world) for every body
/// and the motion subspace columns `data.s` at configuration `q`.
pub fn forward_kinematics(model: &Model, data: &mut Data, q: &DVector<f64>) -> Result<(), DynamicsError> {
    check_q(model, q)?;
    for i in 1..model.nbodies() {
        joint_step(model, data, q, i);
        let p = model.parents[i];
        data.x_wb[i] = data.x_wb[p] * data.x_pb[i];
    }
    Ok(())
}

/// Joint `i`'s transform and subspace at `q`: sets `data.x_pb[i]` and `data.s` of its dofs, and
/// returns `x_pb[i]` (the caller's copy in registers, not read back from memory).
#[inline(always)]
pub(crate) fn joint_step(model: &Model, data: &mut Data, q: &DVector<f64>, i: usize) -> Transform {
    let joint = &model.joints[i];
    let (iq, iv) = (model.idx_q[i], model.idx_v[i]);
    let x_pb = joint.placed_transform(
        &model.placements[i],
        &q.as_slice()[iq..iq + joint.nq()],
        &mut data.s[iv..iv + joint.nv()],
    );
    data.x_pb[i] = x_pb;
    x_pb
}

/// Pose in the world of frame `frame` (see [`Model::frames`]) from the body poses of the last
/// [`forward_kinematics`] call.
pub fn frame_placement(model: &Model, data: &Data, frame: usize) -> Result<Transform, DynamicsError> {
    let f = model.frames.get(frame).ok_or(DynamicsError::IndexOutOfRange {
        what: "frames",
        index: frame,
        count: model.frames.len(),
    })?;
    Ok(data.x_wb[f.body] * f.placement)
}
