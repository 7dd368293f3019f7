//! Composite rigid-body algorithm (Featherstone, RBDA §6.2): the joint-space mass matrix
//! `M(q)`, with `M_ij = S_iᵀ Iᶜ_i S_j` for j an ancestor of i, where `Iᶜ_i` is the composite
//! inertia of the subtree at i. Inertias and joint columns are taken to world coordinates once,
//! so that composites add without transforms and each entry is one 6-D dot product
//! `M_jk = J_jᵀ (⁰Iᶜ_i J_k)` (Pinocchio's world-frame variant). "World" here means world axes
//! about a reference point at the first body's origin rather than the world origin: M does not
//! depend on that point, and far from the origin (1e6 m) the world-origin variant cancels terms
//! of size m·|p|² and loses every digit of M (the 6 % Delassus error found by the far-origin
//! hard case).

use super::jacobian::compute_joint_jacobians;
use crate::data::Data;
use crate::error::DynamicsError;
use crate::math::Transform;
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// Computes the full symmetric mass matrix `M(q)` (kg, kg·m, kg·m²) into `data.mass_matrix` and
/// returns it. Also leaves body poses in `data.x_wb` and joint Jacobian columns in `data.j_world`.
pub fn crba<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &DVector<f64>,
) -> Result<&'d DMatrix<f64>, DynamicsError> {
    compute_joint_jacobians(model, data, q)?;
    let m = crba_at_kinematics(model, data);
    if let Some(k) = m.iter().position(|e| !e.is_finite()) {
        let column = k / m.nrows().max(1);
        return Err(DynamicsError::NonFiniteResult {
            what: "mass matrix",
            at: format!("joint `{}`", model.joint_name(model.dof_joint(column))),
        });
    }
    Ok(m)
}

/// CRBA's passes after [`compute_joint_jacobians`] at the same q (the joint transforms, body
/// poses and world Jacobian columns in `data` are current; the world's step computes them in its
/// kinematics phase): M into `data.mass_matrix`.
fn crba_at_kinematics<'d>(model: &Model, data: &'d mut Data) -> &'d DMatrix<f64> {
    composite_rigid_body_entries(model, data, |data, k, _, m, value| {
        data.mass_matrix[(m, k)] = value;
        data.mass_matrix[(k, m)] = value;
    });
    &data.mass_matrix
}

/// [`crba_at_kinematics`] straight into the factorization's packed rows (`data.factor_packed`,
/// see [`super::factor_mass_matrix`]): per dof k, M's entries on k's ancestors root first, then
/// M_kk; the entries off the tree (zero) are not written, and `data.mass_matrix` is left as it
/// is. The world's step factors these rows in place
/// ([`super::factor_packed_mass_matrix`]): neither the dense matrix's two triangles
/// nor the factorization's gather of them are needed.
pub(crate) fn crba_packed_at_kinematics(model: &Model, data: &mut Data) {
    let path_start = &model.dof_path_start;
    composite_rigid_body_entries(model, data, |data, k, up, _, value| {
        // The walk from k to the root visits k's packed row from its diagonal backwards.
        data.factor_packed[path_start[k + 1] + k - up] = value;
    });
}

/// RBDA §6.2's two passes: world-axes inertias and joint columns (about the first body's
/// origin, into `data.j_crba` and `data.ycrb`), then composites from the leaves in, with
/// `store(data, k, up, m, M_mk)` called for each dof k and each of k's ancestors-or-self m, `up`
/// steps up the path from k (0 for m = k).
fn composite_rigid_body_entries(
    model: &Model,
    data: &mut Data,
    mut store: impl FnMut(&mut Data, usize, usize, usize, f64),
) {
    let mut to_reference = Transform::identity();
    for i in 1..model.nbodies() {
        let (iv, nv) = (model.idx_v[i], model.joints[i].nv());
        if i == 1 {
            to_reference = Transform::from_translation(-data.x_wb[1].translation);
        }
        let x_rb = to_reference * data.x_wb[i];
        for k in iv..iv + nv {
            data.j_crba[k] = x_rb.act_motion(&data.s[k]);
        }
        data.ycrb[i] = model.inertias[i].transformed(&x_rb);
    }
    for i in (1..model.nbodies()).rev() {
        let (p, iv, nv) = (model.parents[i], model.idx_v[i], model.joints[i].nv());
        let composite = data.ycrb[i];
        for k in iv..iv + nv {
            let f_reference = composite.mul_motion(&data.j_crba[k]);
            let value = data.j_crba[k].dot(&f_reference);
            store(data, k, 0, k, value);
            // k's ancestors nearest first: the path's list, not a walk of parent links (each
            // step of which waits for the last load).
            let path = &model.dof_path[model.dof_path_start[k]..model.dof_path_start[k + 1]];
            for (up, &m) in path.iter().rev().enumerate() {
                let value = data.j_crba[m].dot(&f_reference);
                store(data, k, up + 1, m, value);
            }
        }
        if p != 0 {
            data.ycrb[p] += composite;
        }
    }
}
