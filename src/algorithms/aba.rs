//! Articulated-body algorithm (Featherstone, RBDA §7.3): forward dynamics
//! `q̈ = M(q)⁻¹ (τ − C(q, v) v − g(q))` in O(n). Each body's quantities are expressed in world
//! axes about the body's own origin: joint columns, inertias and velocities are turned to world
//! axes once in the first pass, so that passing an articulated inertia or force to the parent is
//! a pure shift by the lever arm between the two origins, without the rotations of the
//! body-frame algorithm's `^λX*_i Iᵃ ⁱX_λ`; about the body's own origin (not one reference point
//! for the whole tree, Pinocchio's world-frame variant) no quantity carries m·|p|² terms of
//! distant bodies, so long chains keep the body-frame algorithm's digits.
//!
//! Pass 1: poses, columns `S_i = R_i S_i^body`, velocities `v_i = shift(v_λ) + S_i q̇_i`, bias
//! accelerations `c_i = v_i × S_i q̇_i + R_i cJ_i`, `Iᴬ_i = I_i` in world axes,
//! `pᴬ_i = v_i ×* I_i v_i`. Pass 2 (leaves to root): `U = Iᴬ S`, `D = Sᵀ U`, `u = τ − Sᵀ pᴬ`,
//! `Iᴬ_λ += shift(Iᴬ − U D⁻¹ Uᵀ)`, `pᴬ_λ += shift(pᴬ + Iᴬ c + U D⁻¹ (u − Uᵀ c))`. Pass 3 (root to
//! leaves): `a' = shift(a_λ) + c_i`, `q̈_i = D⁻¹ (u − Uᵀ a')`, `a_i = a' + S q̈_i`, with
//! `a_0 = −g`.

use super::check::{check_q, check_result_v, check_v};
use super::kinematics::joint_step;
use crate::data::Data;
use crate::error::DynamicsError;
use crate::math::{Force, Mat3, Mat6, Motion, Transform, Vec3, Vec6};
use crate::model::Model;
use nalgebra::DVector;

/// Relative size below which a joint-space articulated inertia pivot counts as zero.
const PIVOT_TOLERANCE: f64 = 1e-12;

/// Forward dynamics by the articulated-body algorithm: generalized accelerations for joint forces
/// `tau` (N·m / N) at state (q, v), written to `data.ddq` and returned. A joint whose moving
/// subtree has no inertia along its motion gives [`DynamicsError::SingularMassMatrix`]. Also
/// leaves the body poses in `data.x_wb`.
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
    data.aba_v[0] = Motion::zero();
    for i in 1..n {
        joint_step(model, data, q, i);
        let (p, iv, joint) = (model.parents[i], model.idx_v[i], &model.joints[i]);
        let nv = joint.nv();
        data.x_wb[i] = data.x_wb[p] * data.x_pb[i];
        // The body's frame turned to world axes, and its origin seen from the parent's.
        let x = Transform { rotation: data.x_wb[i].rotation, translation: Vec3::zeros() };
        let r = data.x_wb[i].translation - data.x_wb[p].translation;
        let vq = &v.as_slice()[iv..iv + nv];
        let mut v_j = Motion::zero();
        for (k, vk) in vq.iter().enumerate() {
            let column = x.act_motion(&data.s[iv + k]);
            data.j_crba[iv + k] = column;
            v_j += column * *vk;
        }
        let v_i = shift_motion(&data.aba_v[p], &r) + v_j;
        let mut c = v_i.cross(&v_j);
        if joint.has_bias() {
            c += x.act_motion(&joint.bias(&data.s[iv..iv + nv], vq));
        }
        let inertia = model.inertias[i].transformed(&x);
        data.aba_v[i] = v_i;
        data.c_j[i] = c;
        inertia.write_matrix(&mut data.ia[i]);
        data.pa[i] = v_i.cross_force(&inertia.mul_motion(&v_i));
    }

    for i in (1..n).rev() {
        let (p, iv, nv) = (model.parents[i], model.idx_v[i], model.joints[i].nv());
        let (done, rest) = data.ia.split_at_mut(i);
        let ia = &rest[0];
        let pa = data.pa[i].to_vector();
        let c = data.c_j[i].to_vector();
        let scale = (0..6).map(|k| ia[(k, k)].abs()).fold(0.0, f64::max);
        let singular = || DynamicsError::SingularMassMatrix { joint: model.joint_name(i).to_string() };
        if nv == 1 {
            // One dof (hinges, sliders: every joint of a chain like the pendulum's): D is a
            // scalar and `U D⁻¹ Uᵀ` a rank-one update.
            let s = data.j_crba[iv].to_vector();
            let u = ia * s;
            let d = s.dot(&u);
            if d.is_nan() || d <= PIVOT_TOLERANCE * scale {
                return Err(singular());
            }
            let d_inv = 1.0 / d;
            let u_bias = tau[iv] - s.dot(&pa);
            data.u[iv] = u;
            data.u_bias[iv] = u_bias;
            data.d_inv[i][(0, 0)] = d_inv;
            if p == 0 {
                continue;
            }
            // pᴬ_λ += pᴬ + Iᴬ c + U D⁻¹ (u − Uᵀ c), Iᴬ_λ += Iᴬ − U D⁻¹ Uᵀ.
            let pa_a = pa + ia * c + u * (d_inv * (u_bias - u.dot(&c)));
            let mut ia_a = *ia;
            ia_a.ger(-d_inv, &u, &u, 1.0);
            let r = data.x_wb[i].translation - data.x_wb[p].translation;
            add_shifted_inertia(&ia_a, &r, &mut done[p]);
            add_shifted_force(&pa_a, &r, &mut data.pa[p]);
        } else {
            let mut d = Mat6::identity();
            for a in 0..nv {
                let s_a = data.j_crba[iv + a].to_vector();
                let u = ia * s_a;
                data.u[iv + a] = u;
                data.u_bias[iv + a] = tau[iv + a] - s_a.dot(&pa);
                for b in 0..=a {
                    let dab = data.j_crba[iv + b].to_vector().dot(&u);
                    d[(a, b)] = dab;
                    d[(b, a)] = dab;
                }
            }
            data.d_inv[i] = invert_spd_block(&d, nv, PIVOT_TOLERANCE * scale).ok_or_else(singular)?;
            if p == 0 {
                continue;
            }
            let d_inv = &data.d_inv[i];
            let mut ia_a = *ia;
            let mut pa_a = pa;
            for b in 0..nv {
                let mut w = Vec6::zeros();
                for a in 0..nv {
                    w += data.u[iv + a] * d_inv[(a, b)];
                }
                ia_a -= w * data.u[iv + b].transpose();
                pa_a += w * data.u_bias[iv + b];
            }
            pa_a += ia_a * c;
            let r = data.x_wb[i].translation - data.x_wb[p].translation;
            add_shifted_inertia(&ia_a, &r, &mut done[p]);
            add_shifted_force(&pa_a, &r, &mut data.pa[p]);
        }
    }

    data.aba_a[0] = Motion::new(-model.gravity, Vec3::zeros());
    for i in 1..n {
        let (p, iv, nv) = (model.parents[i], model.idx_v[i], model.joints[i].nv());
        let r = data.x_wb[i].translation - data.x_wb[p].translation;
        let a_prime = shift_motion(&data.aba_a[p], &r) + data.c_j[i];
        let a_vec = a_prime.to_vector();
        let mut a_i = a_prime;
        if nv == 1 {
            let qdd = data.d_inv[i][(0, 0)] * (data.u_bias[iv] - data.u[iv].dot(&a_vec));
            data.ddq[iv] = qdd;
            a_i += data.j_crba[iv] * qdd;
        } else {
            let mut r = [0.0; 6];
            for (b, rb) in r.iter_mut().enumerate().take(nv) {
                *rb = data.u_bias[iv + b] - data.u[iv + b].dot(&a_vec);
            }
            for a in 0..nv {
                let qdd: f64 = (0..nv).map(|b| data.d_inv[i][(a, b)] * r[b]).sum();
                data.ddq[iv + a] = qdd;
                a_i += data.j_crba[iv + a] * qdd;
            }
        }
        data.aba_a[i] = a_i;
    }
    check_result_v(model, &data.ddq, "aba")?;
    Ok(&data.ddq)
}

/// A motion (velocity or spatial acceleration) about a point moved by `r` (same axes):
/// `[v + ω × r; ω]`.
#[inline]
fn shift_motion(m: &Motion, r: &Vec3) -> Motion {
    Motion { linear: m.linear + m.angular.cross(r), angular: m.angular }
}

/// `out += f` taken from a point `r` away to the parent's point (same axes): `[f; n + r × f]`.
#[inline]
fn add_shifted_force(f: &Vec6, r: &Vec3, out: &mut Force) {
    let linear = Vec3::new(f[0], f[1], f[2]);
    out.linear += linear;
    out.angular += Vec3::new(f[3], f[4], f[5]) + r.cross(&linear);
}

/// `out += ^λX*_i Iᵃ ⁱX_λ` for a pure translation (both frames in world axes, the body's origin
/// `r` from the parent's): for `Iᵃ = [[A, B], [Bᵀ, C]]` (A, C symmetric) and `T = [r]×`,
/// `A_p = A`, `B_p = B − A T`, `C_p = C + T B + (T B)ᵀ − T A T`. Products with T are cross
/// products with r (`A T = −(T A)ᵀ` as A is symmetric).
fn add_shifted_inertia(ia: &Mat6, r: &Vec3, out: &mut Mat6) {
    let a: Mat3 = ia.fixed_view::<3, 3>(0, 0).into_owned();
    let b: Mat3 = ia.fixed_view::<3, 3>(0, 3).into_owned();
    let c: Mat3 = ia.fixed_view::<3, 3>(3, 3).into_owned();
    let cross_columns =
        |m: &Mat3| Mat3::from_columns(&[r.cross(&m.column(0)), r.cross(&m.column(1)), r.cross(&m.column(2))]);
    let at = -cross_columns(&a).transpose(); // A T
    let b_p = b - at;
    let tb = cross_columns(&b);
    let c_p = c + tb + tb.transpose() - cross_columns(&at);
    let mut add = |row: usize, col: usize, m: &Mat3| {
        let mut view = out.fixed_view_mut::<3, 3>(row, col);
        view += m;
    };
    add(0, 0, &a);
    add(0, 3, &b_p);
    add(3, 0, &b_p.transpose());
    add(3, 3, &c_p);
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
