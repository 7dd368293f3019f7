//! The mass matrix alone, in body frames (Featherstone, RBDA Table 6.2): composite inertias
//! accumulate from the leaves in through the joint transforms, `Iᶜ_λ += ^λX*_i Iᶜ_i ⁱX_λ`, and
//! each dof's force `f = Iᶜ_i S_k` travels up its path, `f ← ^λX*_j f`, giving `M_km = S_mᵀ f`
//! for the dofs m of each ancestor. Nothing is taken to the world: no world poses, no Jacobian
//! columns, so M costs the joint transforms, one inertia transform per body and one force
//! transform per (dof, ancestor body) pair. [`super::crba`] computes the same M together with
//! the world poses and Jacobian columns that contacts need.

use super::check::check_q;
use super::crba::finite_mass_matrix;
use crate::data::Data;
use crate::error::DynamicsError;
use crate::math::{fma, Force, Mat3, Motion, SpatialInertia, Transform, Vec3};
use crate::model::{Joint, Model};
use nalgebra::{DMatrix, DVector};
use std::ops::Range;

/// Computes the full symmetric mass matrix `M(q)` (kg, kg·m, kg·m²) into `data.mass_matrix`
/// and returns it, as [`super::crba`] does, without the world poses and Jacobian columns:
/// leaves the joint transforms in `data.x_pb`, the motion subspaces in `data.s` and the
/// composite inertias in body frames in `data.ycrb_body`. Entries between dofs on different
/// branches (zero) are never written, so they stay zero.
///
/// A `q` of the wrong length or with a non-finite entry or a zero quaternion is refused as by
/// [`super::crba`]; a non-finite M is [`DynamicsError::NonFiniteResult`] naming the first
/// column's joint.
pub fn mass_matrix<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &DVector<f64>,
) -> Result<&'d DMatrix<f64>, DynamicsError> {
    check_q(model, q)?;
    for i in 1..model.nbodies() {
        let (joint, iq, iv) = (&model.joints[i], model.idx_q[i], model.idx_v[i]);
        joint.write_placed_transform(
            &model.placements[i],
            &q.as_slice()[iq..iq + joint.nq()],
            &mut data.s[iv..iv + joint.nv()],
            &mut data.x_pb[i],
        );
        data.ycrb_body[i] = model.inertias[i];
    }
    composite_pass(model, data);
    finite_mass_matrix(model, data)
}

/// The forces of [`Data::subtree_forces`] as six rows of nv (force x, y, z, moment x, y, z).
struct ForceRows<'a>([&'a mut [f64]; 6]);

impl<'a> ForceRows<'a> {
    fn new(storage: &'a mut [f64], nv: usize) -> Self {
        let (fx, rest) = storage.split_at_mut(nv);
        let (fy, rest) = rest.split_at_mut(nv);
        let (fz, rest) = rest.split_at_mut(nv);
        let (mx, rest) = rest.split_at_mut(nv);
        let (my, mz) = rest.split_at_mut(nv);
        Self([fx, fy, fz, mx, my, mz])
    }

    #[inline(always)]
    fn set(&mut self, k: usize, f: &[f64; 6]) {
        for (row, value) in self.0.iter_mut().zip(f) {
            row[k] = *value;
        }
    }

    /// Re-expresses the forces of dofs `range` by `x` (`aX*b f`, for forces given in B), and
    /// hands each one, as it is formed, to `visit(k, f)`.
    #[inline(always)]
    fn transform(&mut self, x: &Transform, range: Range<usize>, mut visit: impl FnMut(usize, &[f64; 6])) {
        let (first, n) = (range.start, range.len());
        let [fx, fy, fz, mx, my, mz] = &mut self.0;
        let (fx, fy, fz) = (&mut fx[range.clone()], &mut fy[range.clone()], &mut fz[range.clone()]);
        let (mx, my, mz) = (&mut mx[range.clone()], &mut my[range.clone()], &mut mz[range]);
        let (fx, fy, fz, mx, my, mz) =
            (&mut fx[..n], &mut fy[..n], &mut fz[..n], &mut mx[..n], &mut my[..n], &mut mz[..n]);
        let r = &x.rotation;
        let (t0, t1, t2) = (x.translation.x, x.translation.y, x.translation.z);
        let row = |i: usize, a: f64, b: f64, c: f64| fma(r[(i, 0)], a, fma(r[(i, 1)], b, r[(i, 2)] * c));
        for k in 0..n {
            let (a, b, c) = (fx[k], fy[k], fz[k]);
            let (l0, l1, l2) = (row(0, a, b, c), row(1, a, b, c), row(2, a, b, c));
            let (a, b, c) = (mx[k], my[k], mz[k]);
            let f = [
                l0,
                l1,
                l2,
                row(0, a, b, c) + fma(t1, l2, -t2 * l1),
                row(1, a, b, c) + fma(t2, l0, -t0 * l2),
                row(2, a, b, c) + fma(t0, l1, -t1 * l0),
            ];
            (fx[k], fy[k], fz[k], mx[k], my[k], mz[k]) = (f[0], f[1], f[2], f[3], f[4], f[5]);
            visit(first + k, &f);
        }
    }
}

/// `inertia` (about body i's origin, in its axes) about the parent's origin in the parent's
/// axes, for `x` the pose of body i in its parent: with `h = R h_i` and `g = h + m t / 2`,
/// `I_o = R I_o,i Rᵀ − (t gᵀ + g tᵀ) + 2 (g·t) 1` (six distinct entries), `h' = h + m t`.
#[inline(always)]
fn in_parent(inertia: &SpatialInertia, x: &Transform) -> SpatialInertia {
    let (r, t, m) = (&x.rotation, &x.translation, inertia.mass);
    let rotate = |v: &Vec3| {
        let row = |i: usize| fma(r[(i, 0)], v.x, fma(r[(i, 1)], v.y, r[(i, 2)] * v.z));
        Vec3::new(row(0), row(1), row(2))
    };
    let io = &inertia.inertia_origin;
    // R I_o, column by column.
    let ri = [
        rotate(&io.column(0).into_owned()),
        rotate(&io.column(1).into_owned()),
        rotate(&io.column(2).into_owned()),
    ];
    let h = rotate(&inertia.first_moment);
    let half_m = 0.5 * m;
    let g = Vec3::new(fma(half_m, t.x, h.x), fma(half_m, t.y, h.y), fma(half_m, t.z, h.z));
    let diagonal = 2.0 * fma(g.x, t.x, fma(g.y, t.y, g.z * t.z));
    let mut out = Mat3::zeros();
    for c in 0..3 {
        for k in c..3 {
            // (R I_o Rᵀ)_kc = Σ_j (R I_o)_kj R_cj.
            let rotated = fma(ri[0][k], r[(c, 0)], fma(ri[1][k], r[(c, 1)], ri[2][k] * r[(c, 2)]));
            let value = fma(-t[k], g[c], fma(-g[k], t[c], rotated));
            out[(k, c)] = value;
            out[(c, k)] = value;
        }
        out[(c, c)] += diagonal;
    }
    SpatialInertia {
        mass: m,
        first_moment: Vec3::new(fma(m, t.x, h.x), fma(m, t.y, h.y), fma(m, t.z, h.z)),
        inertia_origin: out,
    }
}

/// The leaves-in pass over the joint transforms and subspaces in `data`, with the bodies' own
/// inertias in `data.ycrb_body`. At body i, the forces of i's subtree's dofs are in i's frame;
/// i's own forces `Iᶜ_i S` and its own block of M are formed, then all of the subtree's forces
/// move to the parent's frame at once (independent transforms, where walking each dof's force
/// up its path would wait for the previous transform at every step), each giving its entries
/// against the parent's dofs while it is in registers.
fn composite_pass(model: &Model, data: &mut Data) {
    let nv = model.nv();
    if nv == 0 {
        return;
    }
    data.sized_mass_matrix(model);
    let Data { x_pb, s, ycrb_body, subtree_forces, mass_matrix, .. } = data;
    let entries = mass_matrix.as_mut_slice();
    let mut forces = ForceRows::new(subtree_forces, nv);
    for i in (1..model.nbodies()).rev() {
        let composite = ycrb_body[i];
        let (iv, n) = (model.idx_v[i], model.joints[i].nv());
        let columns = &s[iv..iv + n];
        for (k, column) in (iv..).zip(columns) {
            let f = match &model.joints[i] {
                Joint::Hinge { axis } => hinge_force(&composite, axis),
                _ => force_array(&composite.mul_motion(column)),
            };
            forces.set(k, &f);
            // The block of i's own dofs: M_mk for m ≤ k.
            for (m, column) in (iv..=k).zip(columns) {
                store(entries, nv, k, m, entry(&model.joints[i], column, m - iv, &f));
            }
        }
        let p = model.parents[i];
        if p == 0 {
            continue;
        }
        let (pv, pn) = (model.idx_v[p], model.joints[p].nv());
        let range = iv..model.subtree_dof_end[i];
        match &model.joints[p] {
            Joint::Hinge { axis } => forces.transform(&x_pb[i], range, |k, f| {
                store(entries, nv, k, pv, fma(axis.x, f[3], fma(axis.y, f[4], axis.z * f[5])));
            }),
            Joint::Free => forces.transform(&x_pb[i], range, |k, f| {
                for (c, value) in f.iter().enumerate() {
                    store(entries, nv, k, pv + c, *value);
                }
            }),
            joint => forces.transform(&x_pb[i], range, |k, f| {
                for (c, column) in s[pv..pv + pn].iter().enumerate() {
                    store(entries, nv, k, pv + c, entry(joint, column, c, f));
                }
            }),
        }
        ycrb_body[p] += in_parent(&composite, &x_pb[i]);
    }
}

/// `M_km = M_mk = value`.
#[inline(always)]
fn store(entries: &mut [f64], nv: usize, k: usize, m: usize, value: f64) {
    entries[m * nv + k] = value;
    entries[k * nv + m] = value;
}

/// `S_cᵀ f` for column c of `joint`'s subspace, `column`: the moment's component along a
/// hinge's axis, the force's c-th component for a free joint (`S = 1₆`), the 6-D product
/// otherwise.
#[inline(always)]
fn entry(joint: &Joint, column: &Motion, c: usize, f: &[f64; 6]) -> f64 {
    match joint {
        Joint::Hinge { axis } => fma(axis.x, f[3], fma(axis.y, f[4], axis.z * f[5])),
        Joint::Free => f[c],
        _ => {
            let (l, a) = (&column.linear, &column.angular);
            let linear = fma(l.x, f[0], fma(l.y, f[1], l.z * f[2]));
            fma(a.x, f[3], fma(a.y, f[4], fma(a.z, f[5], linear)))
        }
    }
}

/// A force as `[f; τ]`.
#[inline(always)]
fn force_array(f: &Force) -> [f64; 6] {
    [f.linear.x, f.linear.y, f.linear.z, f.angular.x, f.angular.y, f.angular.z]
}

/// `Iᶜ S` for a hinge's column `S = [0; a]`: `[a × h; I_o a]`.
#[inline(always)]
fn hinge_force(composite: &SpatialInertia, a: &Vec3) -> [f64; 6] {
    let (h, io) = (&composite.first_moment, &composite.inertia_origin);
    let row = |i: usize| fma(io[(i, 0)], a.x, fma(io[(i, 1)], a.y, io[(i, 2)] * a.z));
    [fma(a.y, h.z, -a.z * h.y), fma(a.z, h.x, -a.x * h.z), fma(a.x, h.y, -a.y * h.x), row(0), row(1), row(2)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Mat3, Vec3};
    use crate::model::{BodySpec, Joint, ModelBuilder, RigidInertia};

    /// A free base carrying a ball joint carrying a hinge: every column count but 2 on one path.
    fn free_ball_hinge() -> Model {
        let inertia = |m: f64| {
            RigidInertia::new(m, Vec3::new(0.1, -0.05, 0.2), Mat3::from_diagonal(&Vec3::new(0.3, 0.2, 0.1)))
        };
        let mut builder = ModelBuilder::new();
        builder.add_body(BodySpec::new("base", "universe", Joint::Free, Transform::identity(), inertia(3.0)));
        builder.add_body(BodySpec::new(
            "shoulder",
            "base",
            Joint::Ball,
            Transform::from_xyz_rpy([0.2, 0.1, -0.3], [0.3, 0.1, -0.2]),
            inertia(1.5),
        ));
        builder.add_body(BodySpec::new(
            "forearm",
            "shoulder",
            Joint::hinge(Vec3::new(0.3, 1.0, 0.2)),
            Transform::from_xyz_rpy([0.0, 0.0, -0.4], [0.0, 0.5, 0.0]),
            inertia(0.7),
        ));
        builder.build().expect("model builds")
    }

    #[test]
    fn equals_the_world_frame_crba() {
        let model = free_ball_hinge();
        let mut data = Data::new(&model);
        let mut rng = <rand::rngs::StdRng as rand::SeedableRng>::seed_from_u64(3);
        for _ in 0..5 {
            let q = model.random_configuration(&mut rng);
            let world = super::super::crba(&model, &mut data, &q).unwrap().clone();
            let mut fresh = Data::new(&model);
            let local = mass_matrix(&model, &mut fresh, &q).unwrap();
            let scale = world.amax();
            assert!((local - &world).amax() <= 1e-12 * scale, "{local} vs {world}");
            assert_eq!(local, &local.transpose(), "symmetric to the bit");
        }
    }
}
