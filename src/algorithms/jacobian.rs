//! Jacobians. The joint Jacobian column of dof k of body i is `J_k = ⁰X_i S_k` (world
//! coordinates, about the world origin); the Jacobian of a frame F attached to body b stacks the
//! columns of the dofs on b's path to the root, re-expressed as asked in [`JacobianFrame`], so
//! that `J(q) q̇` is F's spatial velocity.

use super::check::check_q;
use super::kinematics::joint_step;
use crate::data::Data;
use crate::error::DynamicsError;
use crate::math::Transform;
use crate::model::{Model, NO_DOF};
use nalgebra::{DMatrix, DVector};

/// The frame in which a Jacobian expresses a velocity `[v; ω]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JacobianFrame {
    /// The frame itself: velocity of its origin and angular velocity, in its own axes.
    Local,
    /// Velocity of the frame's origin and angular velocity, in world axes.
    LocalWorldAligned,
    /// Spatial velocity about the world origin, in world axes.
    World,
}

/// Computes body poses `data.x_wb` and every joint Jacobian column `data.j_world` at `q`.
pub fn compute_joint_jacobians(
    model: &Model,
    data: &mut Data,
    q: &DVector<f64>,
) -> Result<(), DynamicsError> {
    check_q(model, q)?;
    let mut previous = data.x_wb[0];
    for i in 1..model.nbodies() {
        let x_pb = joint_step(model, data, q, i);
        let (p, iv, nv) = (model.parents[i], model.idx_v[i], model.joints[i].nv());
        let x_wb = parent_pose(data, &previous, i, p) * x_pb;
        data.x_wb[i] = x_wb;
        for (column, s) in data.j_world[iv..iv + nv].iter_mut().zip(&data.s[iv..iv + nv]) {
            *column = x_wb.act_motion(s);
        }
        previous = x_wb;
    }
    Ok(())
}

/// The world pose of body `i`'s parent `p`: `previous` (body i − 1's, still in registers) when
/// p = i − 1, as along a chain, which spares reading back the pose just stored.
#[inline(always)]
pub(crate) fn parent_pose(data: &Data, previous: &Transform, i: usize, p: usize) -> Transform {
    if p + 1 == i {
        *previous
    } else {
        data.x_wb[p]
    }
}

/// The 6×nv Jacobian of frame `frame` (an index into [`Model::frames`]) from the columns of the
/// last [`compute_joint_jacobians`] call, written to `data.jacobian` (linear rows first) and
/// returned. Columns of dofs that do not move the frame are zero.
pub fn frame_jacobian<'d>(
    model: &Model,
    data: &'d mut Data,
    frame: usize,
    expressed_in: JacobianFrame,
) -> Result<&'d DMatrix<f64>, DynamicsError> {
    let f = model.frames.get(frame).ok_or(DynamicsError::IndexOutOfRange {
        what: "frames",
        index: frame,
        count: model.frames.len(),
    })?;
    let x_wf = data.x_wb[f.body] * f.placement;
    data.jacobian.fill(0.0);
    let mut k = last_dof_of(model, f.body);
    while k != NO_DOF {
        let col = data.j_world[k];
        let col = match expressed_in {
            JacobianFrame::World => col,
            JacobianFrame::Local => x_wf.act_inv_motion(&col),
            JacobianFrame::LocalWorldAligned => {
                let mut shifted = col;
                shifted.linear += col.angular.cross(&x_wf.translation);
                shifted
            }
        };
        for r in 0..3 {
            data.jacobian[(r, k)] = col.linear[r];
            data.jacobian[(r + 3, k)] = col.angular[r];
        }
        k = model.dof_parent[k];
    }
    Ok(&data.jacobian)
}

pub(crate) fn last_dof_of(model: &Model, body: usize) -> usize {
    let mut b = body;
    while b != 0 {
        let nv = model.joints[b].nv();
        if nv > 0 {
            return model.idx_v[b] + nv - 1;
        }
        b = model.parents[b];
    }
    NO_DOF
}
