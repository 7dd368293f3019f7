//! Composite rigid-body algorithm (Featherstone, RBDA §6.2): the joint-space mass matrix
//! `M(q)`, with `M_ij = S_iᵀ Iᶜ_i S_j` for j an ancestor of i, where `Iᶜ_i` is the composite
//! inertia of the subtree at i. Inertias and joint columns are taken to world coordinates once,
//! so that composites add without transforms and each entry is one 6-D dot product
//! `M_jk = J_jᵀ (⁰Iᶜ_i J_k)` (Pinocchio's world-frame variant). "World" here means world axes
//! about a reference point at the first body's origin rather than the world origin: M does not
//! depend on that point, and far from the origin (1e6 m) the world-origin variant cancels terms
//! of size m·|p|² and loses every digit of M (the 6 % Delassus error found by the far-origin
//! hard case).

use super::check::check_q;
#[cfg(doc)]
use super::jacobian::compute_joint_jacobians;
use super::jacobian::parent_pose;
use super::kinematics::joint_step;
use crate::data::Data;
use crate::error::DynamicsError;
use crate::math::{Mat3, Motion, SpatialInertia, Vec3};
use crate::model::{Joint, Model};
use nalgebra::{DMatrix, DVector};

/// Computes the full symmetric mass matrix `M(q)` (kg, kg·m, kg·m²) into `data.mass_matrix` and
/// returns it. Also leaves body poses in `data.x_wb` and joint Jacobian columns in `data.j_world`
/// (as [`compute_joint_jacobians`] does).
pub fn crba<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &DVector<f64>,
) -> Result<&'d DMatrix<f64>, DynamicsError> {
    check_q(model, q)?;
    kinematics_and_world_terms(model, data, q);
    data.sized_mass_matrix(model);
    let nv = model.nv();
    composite_rigid_body_entries(model, data, |data, k, _, m, value| {
        // Column-major: (m, k) then (k, m).
        let entries = data.mass_matrix.as_mut_slice();
        entries[k * nv + m] = value;
        entries[m * nv + k] = value;
    });
    finite_mass_matrix(model, data)
}

/// `data.mass_matrix` if every entry is finite, else the error naming the joint of the first
/// column with a non-finite entry.
pub(super) fn finite_mass_matrix<'d>(
    model: &Model,
    data: &'d Data,
) -> Result<&'d DMatrix<f64>, DynamicsError> {
    let m = &data.mass_matrix;
    if !all_finite(m.as_slice()) {
        let k = m.iter().position(|e| !e.is_finite()).unwrap_or(0);
        let column = k / m.nrows().max(1);
        return Err(DynamicsError::NonFiniteResult {
            what: "mass matrix",
            at: format!("joint `{}`", model.joint_name(model.dof_joint(column))),
        });
    }
    Ok(m)
}

/// True when every entry is finite. A value is not finite when its exponent bits are all set,
/// so that adding one to the exponent field carries into the sign bit: OR-ed over the values,
/// an integer reduction that the compiler vectorizes (the element-wise test with early exit
/// does not vectorize, and a float sum waits on the adder at every step).
pub(super) fn all_finite(values: &[f64]) -> bool {
    const EXPONENT: u64 = 0x7ff0_0000_0000_0000;
    const EXPONENT_ONE: u64 = 0x0010_0000_0000_0000;
    let carries = values.iter().fold(0, |any, x| any | ((x.to_bits() & EXPONENT) + EXPONENT_ONE));
    carries & (1 << 63) == 0
}

/// CRBA after [`compute_joint_jacobians`] at the same q (the joint transforms, body poses and
/// world Jacobian columns in `data` are current; the world's step computes them in its
/// kinematics phase), straight into the factorization's packed rows (`data.factor_packed`, see
/// [`super::factor_mass_matrix`]): per dof k, M's entries on k's ancestors root first, then
/// M_kk; the entries off the tree (zero) are not written, and `data.mass_matrix` is left as it
/// is. The world's step factors these rows in place
/// ([`super::factor_packed_mass_matrix`]): neither the dense matrix's two triangles
/// nor the factorization's gather of them are needed.
pub(crate) fn crba_packed_at_kinematics(model: &Model, data: &mut Data) {
    world_terms_at_kinematics(model, data);
    let path_start = &model.dof_path_start;
    composite_rigid_body_entries(model, data, |data, k, up, _, value| {
        // The walk from k to the root visits k's packed row from its diagonal backwards.
        data.factor_packed[path_start[k + 1] + k - up] = value;
    });
}

/// The world terms from the kinematics in `data` (poses `x_wb`, columns `j_world`): columns
/// about the reference point (the first body's origin) into `data.j_crba`, each body's inertia
/// in world axes about that point into `data.ycrb`. A world column about the reference point is
/// the column about the world origin plus one cross product (the axes are the world's already).
fn world_terms_at_kinematics(model: &Model, data: &mut Data) {
    if model.nbodies() < 2 {
        return;
    }
    let reference = data.x_wb[1].translation;
    for (column, world) in data.j_crba.iter_mut().zip(&data.j_world) {
        *column = Motion { linear: world.linear + world.angular.cross(&reference), angular: world.angular };
    }
    for ((composite, inertia), x_wb) in data.ycrb.iter_mut().zip(&model.inertias).zip(&data.x_wb).skip(1) {
        *composite = rotated_shifted(inertia, &x_wb.rotation, &(x_wb.translation - reference));
    }
}

/// [`compute_joint_jacobians`] and [`world_terms_at_kinematics`] in one pass over the bodies,
/// each body's world terms formed while its pose is at hand, with the same arithmetic (the
/// world's step, which takes the two apart, gets M to the last bit).
fn kinematics_and_world_terms(model: &Model, data: &mut Data, q: &DVector<f64>) {
    let mut previous = data.x_wb[0];
    let mut reference = Vec3::zeros();
    for i in 1..model.nbodies() {
        let x_pb = joint_step(model, data, q, i);
        let (p, iv, nv) = (model.parents[i], model.idx_v[i], model.joints[i].nv());
        let x_wb = parent_pose(data, &previous, i, p) * x_pb;
        if i == 1 {
            reference = x_wb.translation;
        }
        data.x_wb[i] = x_wb;
        let t = &x_wb.translation;
        let (world, about_reference) = (&mut data.j_world[iv..iv + nv], &mut data.j_crba[iv..iv + nv]);
        match &model.joints[i] {
            // S = [0; axis] (hinge.rs): one rotation, and the linear part is a moment (the
            // products with S's zeros that `act_motion` forms add exact zeros).
            Joint::Hinge { .. } => {
                let angular = x_wb.rotation * data.s[iv].angular;
                world[0] = Motion { linear: t.cross(&angular), angular };
            }
            // S = 1₆ (free.rs): the columns are the rotation's.
            Joint::Free => {
                for c in 0..3 {
                    let axis = x_wb.rotation.column(c).into_owned();
                    world[c] = Motion { linear: axis, angular: Vec3::zeros() };
                    world[c + 3] = Motion { linear: t.cross(&axis), angular: axis };
                }
            }
            _ => {
                for (world, s) in world.iter_mut().zip(&data.s[iv..iv + nv]) {
                    *world = x_wb.act_motion(s);
                }
            }
        }
        for (column, world) in about_reference.iter_mut().zip(world.iter()) {
            *column =
                Motion { linear: world.linear + world.angular.cross(&reference), angular: world.angular };
        }
        data.ycrb[i] = rotated_shifted(&model.inertias[i], &x_wb.rotation, &(x_wb.translation - reference));
        previous = x_wb;
    }
}

/// RBDA §6.2's second pass over the world terms in `data.j_crba` and `data.ycrb`: composites
/// from the leaves in, with `store(data, k, up, m, M_mk)` called for each dof k and each of k's
/// ancestors-or-self m, `up` steps up the path from k (0 for m = k).
fn composite_rigid_body_entries(
    model: &Model,
    data: &mut Data,
    mut store: impl FnMut(&mut Data, usize, usize, usize, f64),
) {
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

/// `inertia` (about its body's origin, in its axes) about the point `t` in axes rotated by `r`:
/// [`SpatialInertia::transformed`] by the pose `(r, t)`, forming each of the symmetric
/// rotational inertia's six distinct entries once. With `h = r h_b` and `g = h + m t / 2`:
/// `I_o' = r I_o rᵀ − (t gᵀ + g tᵀ) + 2 (g·t) 1`, `h' = h + m t`.
#[inline(always)]
fn rotated_shifted(inertia: &SpatialInertia, r: &Mat3, t: &Vec3) -> SpatialInertia {
    let m = inertia.mass;
    let h = r * inertia.first_moment;
    let ri = r * inertia.inertia_origin;
    let g = h + t * (0.5 * m);
    let diagonal = 2.0 * g.dot(t);
    let mut out = Mat3::zeros();
    for c in 0..3 {
        for k in c..3 {
            let rotated = ri[(k, 0)] * r[(c, 0)] + ri[(k, 1)] * r[(c, 1)] + ri[(k, 2)] * r[(c, 2)];
            let value = rotated - (t[k] * g[c] + g[k] * t[c]);
            out[(k, c)] = value;
            out[(c, k)] = value;
        }
        out[(c, c)] += diagonal;
    }
    SpatialInertia { mass: m, first_moment: h + t * m, inertia_origin: out }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Transform;

    #[test]
    fn rotated_shifted_is_the_inertia_transformed_by_the_pose() {
        let inertia = SpatialInertia::new(
            3.5,
            Vec3::new(0.2, -0.1, 0.4),
            Mat3::new(0.3, 0.02, -0.01, 0.02, 0.5, 0.03, -0.01, 0.03, 0.4),
        );
        let pose = Transform::from_xyz_rpy([1.5, -0.7, 2.1], [0.4, -1.1, 2.5]);
        let expected = inertia.transformed(&pose);
        let got = rotated_shifted(&inertia, &pose.rotation, &pose.translation);
        assert_eq!(got.mass, expected.mass);
        assert!((got.first_moment - expected.first_moment).norm() < 1e-12);
        assert!((got.inertia_origin - expected.inertia_origin).norm() < 1e-12);
        assert_eq!(got.inertia_origin, got.inertia_origin.transpose(), "symmetric to the bit");
    }

    #[test]
    fn all_finite_sees_a_nan_or_an_infinity_anywhere() {
        let finite: Vec<f64> = (0..11).map(|k| k as f64 * 1e300 - 3.0).collect();
        assert!(all_finite(&finite));
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            for k in 0..finite.len() {
                let mut values = finite.clone();
                values[k] = bad;
                assert!(!all_finite(&values), "{bad} at {k}");
            }
        }
    }
}
