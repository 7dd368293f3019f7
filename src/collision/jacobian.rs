//! Contact frames and contact Jacobians: for a contact between A and B, the 3×nv matrix `J_c`
//! such that `J_c v = Rᵀ (v_A(p_A) − v_B(p_B))`, the velocity of A's contact point relative to
//! B's, in the contact frame whose axes are the normal (B → A) and two tangents. Positive normal
//! velocity separates. This is the input of the constraint rows.

use super::world::{Attachment, Contact};
use crate::algorithms::jacobian::last_dof_of;
use crate::data::Data;
use crate::error::CollisionError;
use crate::math::{Mat3, Vec3};
use crate::model::{Model, NO_DOF};
use nalgebra::DMatrix;

/// A Jacobian row being written: hands out the dense run of entries that holds a column, so
/// that a walk along a body's path to the root writes without a lookup per entry. A dense row
/// (`[f64]` of nv entries) is one run; a [`crate::constraints::RowMut`] has one per block.
pub trait JacobianRow {
    /// The run of entries holding column `col` (created zeroed if the row has none yet) and the
    /// column of its first entry.
    fn segment_mut(&mut self, col: usize) -> (&mut [f64], usize);
}

impl JacobianRow for [f64] {
    fn segment_mut(&mut self, _col: usize) -> (&mut [f64], usize) {
        (self, 0)
    }
}

/// `row[col + k] += value(k)` for every dof k on the path from `last` to the root.
fn add_along_path(
    model: &Model,
    last: usize,
    row: &mut (impl JacobianRow + ?Sized),
    col: usize,
    mut value: impl FnMut(usize) -> f64,
) {
    let mut k = last;
    if k == NO_DOF {
        return;
    }
    let (mut segment, mut first) = row.segment_mut(col + k);
    while k != NO_DOF {
        if col + k < first || col + k - first >= segment.len() {
            (segment, first) = row.segment_mut(col + k);
        }
        segment[col + k - first] += value(k);
        k = model.dof_parent[k];
    }
}

/// Two unit tangents completing the unit normal `n` to a right-handed orthonormal frame
/// (n, t1, t2), continuous except where n_z changes sign (Duff et al., "Building an orthonormal
/// basis, revisited", JCGT 2017).
pub fn tangents(n: &Vec3) -> (Vec3, Vec3) {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t1 = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let t2 = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    (t1, t2)
}

/// The contact frame of normal `n`: a rotation whose columns are (n, t1, t2) in world axes.
pub fn contact_frame(n: &Vec3) -> Mat3 {
    let (t1, t2) = tangents(n);
    Mat3::from_columns(&[*n, t1, t2])
}

/// Adds `sign · Rᵀ J_p` to the 3 rows starting at `row` and the nv columns starting at `col` of
/// `out`, where `J_p` is the 3×nv Jacobian of the world velocity of the point `point` (world, m)
/// fixed on body `body`, and `R` the contact frame. Needs `data.j_world` and `data.x_wb` from
/// [`crate::algorithms::compute_joint_jacobians`].
#[allow(clippy::too_many_arguments)]
pub fn add_point_jacobian(
    model: &Model,
    data: &Data,
    body: usize,
    point: &Vec3,
    frame: &Mat3,
    sign: f64,
    out: &mut DMatrix<f64>,
    row: usize,
    col: usize,
) {
    let mut k = last_dof_of(model, body);
    while k != NO_DOF {
        let column = &data.j_world[k];
        // Velocity of the body-fixed point at `point` from the spatial velocity about the origin.
        let v = column.linear + column.angular.cross(point);
        let local = frame.tr_mul(&v);
        for r in 0..3 {
            out[(row + r, col + k)] += sign * local[r];
        }
        k = model.dof_parent[k];
    }
}

/// Adds `sign · dᵀ J_p` to `row[col..col + nv]`: the rate of the velocity of the point `point`
/// (world, m) fixed on body `body` along the world direction `direction`. Needs `data.j_world`.
#[allow(clippy::too_many_arguments)]
pub fn add_point_direction_row(
    model: &Model,
    data: &Data,
    body: usize,
    point: &Vec3,
    direction: &Vec3,
    sign: f64,
    row: &mut (impl JacobianRow + ?Sized),
    col: usize,
) {
    add_along_path(model, last_dof_of(model, body), row, col, |k| {
        let column = &data.j_world[k];
        sign * direction.dot(&(column.linear + column.angular.cross(point)))
    });
}

/// Appends, for every dof k on the path of body `body` to the root, `(col + k, sign · J_p,k)`:
/// the column and the world velocity of the point `point` (world, m) fixed on the body per unit
/// rate of dof k. Several rows at the same point (a contact's normal and tangents) then cost a
/// dot product per entry ([`add_point_rates_row`]) instead of a cross product each. Needs
/// `data.j_world`.
pub fn point_rates(
    model: &Model,
    data: &Data,
    body: usize,
    point: &Vec3,
    sign: f64,
    col: usize,
    out: &mut Vec<(usize, Vec3)>,
) {
    let mut k = last_dof_of(model, body);
    while k != NO_DOF {
        let column = &data.j_world[k];
        out.push((col + k, (column.linear + column.angular.cross(point)) * sign));
        k = model.dof_parent[k];
    }
}

/// Adds `dᵀ u` to `row[c]` for every `(c, u)` of `rates` (from [`point_rates`]): a row along the
/// world direction `direction`.
pub fn add_point_rates_row(rates: &[(usize, Vec3)], direction: &Vec3, row: &mut (impl JacobianRow + ?Sized)) {
    let Some(&(c0, _)) = rates.first() else { return };
    let (mut segment, mut first) = row.segment_mut(c0);
    for (c, u) in rates {
        if *c < first || c - first >= segment.len() {
            (segment, first) = row.segment_mut(*c);
        }
        segment[c - first] += direction.dot(u);
    }
}

/// Adds `sign · dᵀ J_ω` to `row[col..col + nv]`: the rate of body `body`'s angular velocity about
/// the world direction `direction`. Needs `data.j_world`.
pub fn add_angular_direction_row(
    model: &Model,
    data: &Data,
    body: usize,
    direction: &Vec3,
    sign: f64,
    row: &mut (impl JacobianRow + ?Sized),
    col: usize,
) {
    add_along_path(model, last_dof_of(model, body), row, col, |k| {
        sign * direction.dot(&data.j_world[k].angular)
    });
}

/// Writes the 3×nv contact Jacobian of `contact` (rows: normal, tangent 1, tangent 2; see
/// [`tangents`]) into `out`, for a contact whose non-static sides belong to multibody
/// `multibody`, the one described by `model` and `data` (after
/// [`crate::algorithms::compute_joint_jacobians`]). Static sides contribute nothing.
pub fn contact_jacobian(
    model: &Model,
    data: &Data,
    multibody: usize,
    contact: &Contact,
    out: &mut DMatrix<f64>,
) -> Result<(), CollisionError> {
    if out.nrows() != 3 || out.ncols() != model.nv() {
        return Err(CollisionError::IndexOutOfRange {
            what: "Jacobian columns",
            index: out.ncols(),
            count: model.nv(),
        });
    }
    out.fill(0.0);
    let frame = contact_frame(&contact.normal);
    for (side, point, sign) in
        [(contact.body_a, contact.point_a, 1.0), (contact.body_b, contact.point_b, -1.0)]
    {
        match side {
            Attachment::World => {}
            Attachment::Body { multibody: m, body } => {
                if m != multibody {
                    return Err(CollisionError::IndexOutOfRange {
                        what: "multibodies",
                        index: m,
                        count: multibody + 1,
                    });
                }
                if body >= model.nbodies() {
                    return Err(CollisionError::IndexOutOfRange {
                        what: "bodies",
                        index: body,
                        count: model.nbodies(),
                    });
                }
                add_point_jacobian(model, data, body, &point, &frame, sign, out, 0, 0);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tangents_are_orthonormal_and_right_handed() {
        for n in [
            Vec3::z(),
            -Vec3::z(),
            Vec3::x(),
            Vec3::new(0.3, -0.4, 0.5).normalize(),
            Vec3::new(1e-9, 0.0, -1.0),
        ] {
            let n = n.normalize();
            let r = contact_frame(&n);
            assert!((r.transpose() * r - Mat3::identity()).abs().max() < 1e-14);
            assert!((r.determinant() - 1.0).abs() < 1e-14);
        }
    }
}
