//! Articulated-body algorithm (Featherstone, RBDA §7.3): forward dynamics
//! `q̈ = M(q)⁻¹ (τ − C(q, v) v − g(q))` in O(n), in body frames.
//!
//! Pass 1: velocities `v_i`, bias accelerations `c_i = cJ_i + v_i × vJ_i`, `Iᴬ_i = I_i`,
//! `pᴬ_i = v_i ×* I_i v_i`. Pass 2 (leaves to root): `U = Iᴬ S`, `D = Sᵀ U`, `u = τ − Sᵀ pᴬ`,
//! `Iᵃ = Iᴬ − U D⁻¹ Uᵀ`, `pᵃ = pᴬ + Iᵃ c + U D⁻¹ u`, added into the parent through `^λX*_i`.
//! Pass 3 (root to leaves): `a' = ⁱX_λ a_λ + c_i`, `q̈_i = D⁻¹ (u − Uᵀ a')`, `a_i = a' + S q̈_i`,
//! with `a_0 = −g`.

use super::check::{check_q, check_v};
use super::kinematics::joint_step;
use crate::data::Data;
use crate::error::DynamicsError;
use crate::math::{rotate_symmetric, Force, Mat3, Mat6, Motion, Transform, Vec3, Vec6};
use crate::model::Model;
use nalgebra::DVector;

/// Relative size below which a joint-space articulated inertia pivot counts as zero.
const PIVOT_TOLERANCE: f64 = 1e-12;

/// Forward dynamics by the articulated-body algorithm: generalized accelerations for joint forces
/// `tau` (N·m / N) at state (q, v), written to `data.ddq` and returned. A joint whose moving
/// subtree has no inertia along its motion gives [`DynamicsError::SingularMassMatrix`].
pub fn aba<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &DVector<f64>,
    v: &DVector<f64>,
    tau: &DVector<f64>,
) -> Result<&'d DVector<f64>, DynamicsError> {
    check_q(model, q)?;
    check_v(model, v, "v")?;
    check_v(model, tau, "tau")?;
    let n = model.nbodies();
    data.v[0] = Motion::zero();
    for i in 1..n {
        joint_step(model, data, q, i);
        let (p, iv, joint) = (model.parents[i], model.idx_v[i], &model.joints[i]);
        let nv = joint.nv();
        let s = &data.s[iv..iv + nv];
        let vq = &v.as_slice()[iv..iv + nv];
        let mut v_j = Motion::zero();
        for (col, vk) in s.iter().zip(vq) {
            v_j += *col * *vk;
        }
        let v_i = data.x_pb[i].act_inv_motion(&data.v[p]) + v_j;
        let mut c = v_i.cross(&v_j);
        if joint.has_bias() {
            c += joint.bias(s, vq);
        }
        let inertia = &model.inertias[i];
        data.v[i] = v_i;
        data.c_j[i] = c;
        data.ia[i] = inertia.to_matrix();
        data.pa[i] = v_i.cross_force(&inertia.mul_motion(&v_i));
    }

    for i in (1..n).rev() {
        let (p, iv, nv) = (model.parents[i], model.idx_v[i], model.joints[i].nv());
        let ia = data.ia[i];
        let pa = data.pa[i].to_vector();
        let scale = (0..6).map(|k| ia[(k, k)].abs()).fold(0.0, f64::max);
        let singular = || DynamicsError::SingularMassMatrix { joint: model.joint_name(i).to_string() };
        let (ia_a, pa_a) = if nv == 1 {
            // One dof (hinges, sliders: every joint of a chain like the pendulum's): D is a
            // scalar and `U D⁻¹ Uᵀ` a rank-one update.
            let s = data.s[iv];
            let u = mul_subspace(&ia, &s);
            let d = s.to_vector().dot(&u);
            // `!(d > tol)` also catches NaN.
            if !(d > PIVOT_TOLERANCE * scale) {
                return Err(singular());
            }
            let d_inv = 1.0 / d;
            let u_bias = tau[iv] - s.to_vector().dot(&pa);
            data.u[iv] = u;
            data.u_bias[iv] = u_bias;
            data.d_inv[i][(0, 0)] = d_inv;
            if p == 0 {
                continue;
            }
            let ud = u * d_inv;
            let ia_a = ia - ud * u.transpose();
            let pa_a = pa + ia_a * data.c_j[i].to_vector() + ud * u_bias;
            (ia_a, pa_a)
        } else {
            let mut d = Mat6::identity();
            for a in 0..nv {
                let u = ia * data.s[iv + a].to_vector();
                data.u[iv + a] = u;
                data.u_bias[iv + a] = tau[iv + a] - data.s[iv + a].to_vector().dot(&pa);
                for b in 0..=a {
                    let dab = data.s[iv + b].to_vector().dot(&u);
                    d[(a, b)] = dab;
                    d[(b, a)] = dab;
                }
            }
            data.d_inv[i] = invert_spd_block(&d, nv, PIVOT_TOLERANCE * scale).ok_or_else(singular)?;
            if p == 0 {
                continue;
            }
            let d_inv = &data.d_inv[i];
            let mut ia_a = ia;
            let mut pa_a = pa;
            for b in 0..nv {
                let mut w = Vec6::zeros();
                for a in 0..nv {
                    w += data.u[iv + a] * d_inv[(a, b)];
                }
                ia_a -= w * data.u[iv + b].transpose();
                pa_a += w * data.u_bias[iv + b];
            }
            pa_a += ia_a * data.c_j[i].to_vector();
            (ia_a, pa_a)
        };
        let x = data.x_pb[i];
        add_articulated_to_parent(&ia_a, &x, &mut data.ia[p]);
        data.pa[p] += x.act_force(&Force::from_vector(&pa_a));
    }

    let a0 = Motion::new(-model.gravity, Vec3::zeros());
    for i in 1..n {
        let (p, iv, nv) = (model.parents[i], model.idx_v[i], model.joints[i].nv());
        let a_parent = if p == 0 { a0 } else { data.a[p] };
        let a_prime = data.x_pb[i].act_inv_motion(&a_parent) + data.c_j[i];
        let a_vec = a_prime.to_vector();
        let mut r = [0.0; 6];
        for (b, rb) in r.iter_mut().enumerate().take(nv) {
            *rb = data.u_bias[iv + b] - data.u[iv + b].dot(&a_vec);
        }
        let mut a_i = a_prime;
        if nv == 1 {
            let qdd = data.d_inv[i][(0, 0)] * r[0];
            data.ddq[iv] = qdd;
            a_i += data.s[iv] * qdd;
        } else {
            for a in 0..nv {
                let qdd: f64 = (0..nv).map(|b| data.d_inv[i][(a, b)] * r[b]).sum();
                data.ddq[iv + a] = qdd;
                a_i += data.s[iv + a] * qdd;
            }
        }
        data.a[i] = a_i;
    }
    Ok(&data.ddq)
}

/// Inverse of the symmetric positive definite top-left `n×n` block of `d` by Cholesky; `None`
/// when a pivot is not above `tolerance`.
fn invert_spd_block(d: &Mat6, n: usize, tolerance: f64) -> Option<Mat6> {
    if n == 1 {
        let mut out = Mat6::zeros();
        if d[(0, 0)].is_nan() || d[(0, 0)] <= tolerance {
            return None;
        }
        out[(0, 0)] = 1.0 / d[(0, 0)];
        return Some(out);
    }
    let mut l = Mat6::zeros();
    for j in 0..n {
        let mut s = d[(j, j)];
        for k in 0..j {
            s -= l[(j, k)] * l[(j, k)];
        }
        if s.is_nan() || s <= tolerance {
            return None;
        }
        l[(j, j)] = s.sqrt();
        for i in j + 1..n {
            let mut s = d[(i, j)];
            for k in 0..j {
                s -= l[(i, k)] * l[(j, k)];
            }
            l[(i, j)] = s / l[(j, j)];
        }
    }
    let mut inv = Mat6::zeros();
    for c in 0..n {
        // solve L y = e_c, then Lᵀ x = y
        let mut y = [0.0; 6];
        for i in 0..n {
            let mut s = if i == c { 1.0 } else { 0.0 };
            for k in 0..i {
                s -= l[(i, k)] * y[k];
            }
            y[i] = s / l[(i, i)];
        }
        for i in (0..n).rev() {
            let mut s = y[i];
            for k in i + 1..n {
                s -= l[(k, i)] * inv[(k, c)];
            }
            inv[(i, c)] = s / l[(i, i)];
        }
    }
    Some(inv)
}

/// `ia · s` for a motion-subspace column `s`; a purely angular column (every hinge) touches
/// only the angular columns of `ia`.
#[inline]
fn mul_subspace(ia: &Mat6, s: &Motion) -> Vec6 {
    if s.linear == Vec3::zeros() {
        ia.fixed_columns::<3>(3) * s.angular
    } else {
        ia * s.to_vector()
    }
}

/// `out += ^λX*_i Iᵃ ⁱX_λ`: an articulated inertia (blocks `[[A, B], [Bᵀ, C]]`, body frame, A and
/// C symmetric) expressed in the parent frame, for `x` the body's pose in the parent. With
/// `T = [t]×` and rotated blocks `A' = R A Rᵀ` etc.: `A_p = A'`, `B_p = B' − A' T`,
/// `C_p = C' + T B' + (T B')ᵀ − T A' T`. Products with T are cross products with t
/// (`A' T = −(T A')ᵀ` as A' is symmetric).
fn add_articulated_to_parent(ia: &Mat6, x: &Transform, out: &mut Mat6) {
    let r = &x.rotation;
    let t = &x.translation;
    let a: Mat3 = rotate_symmetric(r, &ia.fixed_view::<3, 3>(0, 0).into_owned());
    let b: Mat3 = r * ia.fixed_view::<3, 3>(0, 3) * r.transpose();
    let c: Mat3 = rotate_symmetric(r, &ia.fixed_view::<3, 3>(3, 3).into_owned());
    let cross_columns =
        |m: &Mat3| Mat3::from_columns(&[t.cross(&m.column(0)), t.cross(&m.column(1)), t.cross(&m.column(2))]);
    let ta = cross_columns(&a); // T A'
    let at = -ta.transpose(); // A' T
    let b_p = b - at;
    let tb = cross_columns(&b);
    let tat = cross_columns(&at); // T A' T
    let c_p = c + tb + tb.transpose() - tat;
    let mut block = |row: usize, col: usize, m: &Mat3| {
        let mut view = out.fixed_view_mut::<3, 3>(row, col);
        view += m;
    };
    block(0, 0, &a);
    block(0, 3, &b_p);
    block(3, 0, &b_p.transpose());
    block(3, 3, &c_p);
}
