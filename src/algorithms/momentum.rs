//! The generalized momentum `p = M(q) w` and the Lagrangian force `∂L/∂q = ∂T/∂q(q, w) − g(q)`
//! of a velocity w, in one pass down and one up the tree: what a variational integrator's
//! discrete Euler–Lagrange equations need ([`crate::world`]'s RATTLE step).
//!
//! With `h_i = I_i v_i` the momentum of body i and `H_i` the momentum of the subtree rooted at
//! i (both spatial forces), a joint dof k of body i with motion subspace column `s_k` gives
//! `p_k = s_k · H_i` (`∂T/∂w_k`), and, for joints whose transform is `exp(s_k q_k)` (hinges and
//! sliders: turning q_k moves the whole subtree by the screw s_k), `∂T/∂q_k = (u_i × s_k) · H_i`
//! with `u_i` the velocity of body i's parent: differentiating `T = ½ Σ V_jᵀ I_j V_j` (world
//! axes) moves the subtree's inertias by `s_k ×` and its joint columns below k by
//! `s_k × s_m`, which sum to `−H_i · (s_k × u_i)`. Gravity's part is RNEA's `g(q)` with the
//! subtree's weights `G_i = Σ I_j a_g` (`a_g` the body's acceleration −gravity).

use crate::data::Data;
use crate::math::{Force, Motion};
use crate::model::{Joint, Model};

/// Whether every joint of `model` is a hinge, a slider or fixed: the joints for which
/// [`momentum_and_lagrangian_force`]'s `∂T/∂q` holds and whose configuration is a vector space
/// (`q ⊕ h v = q + h v`).
pub(crate) fn has_screw_joints_only(model: &Model) -> bool {
    (1..model.nbodies())
        .all(|i| matches!(model.joint(i), Joint::Fixed | Joint::Hinge { .. } | Joint::Slider { .. }))
}

/// Writes `p = M(q) w` (N·s or N·m·s) and `∂T/∂q(q, w) − g(q)` (N or N·m) of a model whose
/// joints are hinges, sliders or fixed ([`has_screw_joints_only`]). `data` must hold the joint
/// transforms, motion subspaces and world poses at q ([`crate::algorithms::compute_joint_jacobians`]);
/// `data.v`, `data.a` and `data.f` are overwritten (body velocities, parent velocities, subtree
/// momenta), and `weights` (one per body) with the subtrees' weights.
pub(crate) fn momentum_and_lagrangian_force(
    model: &Model,
    data: &mut Data,
    w: &[f64],
    weights: &mut [Force],
    p: &mut [f64],
    force: &mut [f64],
) {
    data.v[0] = Motion::zero();
    for (i, weight) in weights.iter_mut().enumerate().take(model.nbodies()).skip(1) {
        let (parent, iv, nv) = (model.parents[i], model.idx_v[i], model.joints[i].nv());
        let u = data.x_pb[i].act_inv_motion(&data.v[parent]);
        let mut v = u;
        for (s, wk) in data.s[iv..iv + nv].iter().zip(&w[iv..iv + nv]) {
            v += *s * *wk;
        }
        data.a[i] = u;
        data.v[i] = v;
        let inertia = &model.inertias[i];
        data.f[i] = inertia.mul_motion(&v);
        let fall = data.x_wb[i].rotation.tr_mul(&-model.gravity);
        *weight = inertia.mul_motion(&Motion::new(fall, crate::math::Vec3::zeros()));
    }
    for i in (1..model.nbodies()).rev() {
        let (parent, iv, nv) = (model.parents[i], model.idx_v[i], model.joints[i].nv());
        let (momentum, weight, u) = (data.f[i], weights[i], data.a[i]);
        for k in iv..iv + nv {
            let s = data.s[k];
            p[k] = s.dot(&momentum);
            force[k] = u.cross(&s).dot(&momentum) - s.dot(&weight);
        }
        if parent != 0 {
            let x = data.x_pb[i];
            data.f[parent] += x.act_force(&momentum);
            weights[parent] += x.act_force(&weight);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algorithms::{compute_joint_jacobians, crba, generalized_gravity, kinetic_energy};
    use crate::math::{Mat3, Transform, Vec3};
    use crate::model::{BodySpec, ModelBuilder, RigidInertia};
    use nalgebra::DVector;

    /// A branched tree of hinges and sliders about skew axes, with offset centres of mass.
    fn tree() -> Model {
        let inertia = |m: f64| {
            RigidInertia::new(
                m,
                Vec3::new(0.1, -0.05, 0.03),
                Mat3::from_diagonal(&Vec3::new(0.02, 0.03, 0.01)),
            )
        };
        let at = |x: f64, z: f64| Transform::from_translation(Vec3::new(x, 0.02, z));
        let axis = |x: f64, y: f64, z: f64| Vec3::new(x, y, z).normalize();
        let mut b = ModelBuilder::new();
        b.add_body(BodySpec::new(
            "a",
            "universe",
            Joint::hinge(axis(0.1, 1.0, 0.2)),
            at(0.0, 0.0),
            inertia(1.0),
        ));
        b.add_body(BodySpec::new("b", "a", Joint::slider(axis(1.0, 0.3, -0.2)), at(0.3, 0.1), inertia(0.7)));
        b.add_body(BodySpec::new("c", "b", Joint::hinge(axis(-0.4, 0.2, 1.0)), at(0.2, -0.1), inertia(0.5)));
        b.add_body(BodySpec::new("d", "a", Joint::hinge(axis(0.0, 1.0, 0.0)), at(-0.2, 0.2), inertia(1.2)));
        b.build().unwrap()
    }

    #[test]
    fn momentum_and_force_match_the_mass_matrix_and_the_derivatives_of_the_energy() {
        let model = tree();
        assert!(has_screw_joints_only(&model));
        let mut data = Data::new(&model);
        let n = model.nv();
        let q = DVector::from_vec(vec![0.4, 0.15, -0.7, 1.1]);
        let w = DVector::from_vec(vec![1.3, -0.8, 2.1, -1.7]);
        let mut weights = vec![Force::zero(); model.nbodies()];
        let (mut p, mut force) = (vec![0.0; n], vec![0.0; n]);
        compute_joint_jacobians(&model, &mut data, &q).unwrap();
        momentum_and_lagrangian_force(&model, &mut data, w.as_slice(), &mut weights, &mut p, &mut force);
        let mass = crba(&model, &mut data, &q).unwrap().clone();
        let expected_p = &mass * &w;
        let gravity = generalized_gravity(&model, &mut data, &q).unwrap().clone();
        for k in 0..n {
            assert!((p[k] - expected_p[k]).abs() < 1e-12, "p[{k}] {} vs {}", p[k], expected_p[k]);
            // ∂T/∂q_k by central differences (error ~ε² ≈ 1e-12).
            let epsilon = 1e-6;
            let (mut plus, mut minus) = (q.clone(), q.clone());
            plus[k] += epsilon;
            minus[k] -= epsilon;
            let dt = (kinetic_energy(&model, &mut data, &plus, &w).unwrap()
                - kinetic_energy(&model, &mut data, &minus, &w).unwrap())
                / (2.0 * epsilon);
            let expected = dt - gravity[k];
            assert!((force[k] - expected).abs() < 1e-8, "force[{k}] {} vs {expected}", force[k]);
        }
    }
}
