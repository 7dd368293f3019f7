//! Tree-sparse factorization of the mass matrix (Featherstone, RBDA §6.5, "LTDL"):
//! `M = Lᵀ D L` with L unit lower triangular and non-zero only where the column's dof is an
//! ancestor of the row's dof. Costs O(n d²) for tree depth d and fills in nothing.

use super::check::{check_q, check_v};
use super::{crba, nonlinear_effects};
use crate::data::Data;
use crate::error::DynamicsError;
use crate::model::{Model, NO_DOF};
use nalgebra::DVector;

/// Relative size below which a pivot of the factorization counts as zero.
const PIVOT_TOLERANCE: f64 = 1e-12;

/// Factors `data.mass_matrix` (from [`crba`]) into `data.mass_matrix_factor`. A joint whose
/// subtree cannot move gives [`DynamicsError::SingularMassMatrix`].
pub fn factor_mass_matrix(model: &Model, data: &mut Data) -> Result<(), DynamicsError> {
    let n = model.nv();
    let (parent, run_start) = (&model.dof_parent, &model.dof_run_start);
    let m = data.mass_matrix.as_slice();
    let h = data.mass_matrix_factor.as_mut_slice();
    // RBDA §6.5's LTDL on the upper triangle: column k of the column-major storage holds
    // H_jk = H_kj for the ancestors j of k, which are contiguous stretches (`dof_run_start`), so
    // each update is an axpy over a stretch instead of a walk of the parent links. Only the
    // entries (j, k) with j an ancestor of k (or k) are read and written: the rest of a tree's M
    // is zero and of no use (ten free boxes: 210 of 3600 entries).
    for k in 0..n {
        let column = k * n;
        let (mut start, mut end) = (run_start[k], k + 1);
        loop {
            h[column + start..column + end].copy_from_slice(&m[column + start..column + end]);
            let next = parent[start];
            if next == NO_DOF {
                break;
            }
            (start, end) = (run_start[next], next + 1);
        }
    }
    for k in (0..n).rev() {
        let pivot = h[k * n + k];
        if pivot.is_nan() || pivot <= 0.0 || pivot <= PIVOT_TOLERANCE * m[k * n + k] {
            return Err(DynamicsError::SingularMassMatrix {
                joint: model.joint_name(model.dof_joint(k)).to_string(),
            });
        }
        // For each ancestor i of k: H_ji −= (H_ki / D_k) H_jk over the ancestors-or-self j of i,
        // then L_ki = H_ki / D_k. Column k's entries above i are still undivided when i is done.
        let mut i = parent[k];
        while i != NO_DOF {
            let a = h[k * n + i] / pivot;
            if a != 0.0 {
                // i < k: column i lies before column k.
                let (before, from_k) = h.split_at_mut(k * n);
                let (column_i, column_k) = (&mut before[i * n..(i + 1) * n], &from_k[..n]);
                let (mut start, mut end) = (run_start[i], i + 1);
                loop {
                    for (x, y) in column_i[start..end].iter_mut().zip(&column_k[start..end]) {
                        *x -= a * y;
                    }
                    let next = parent[start];
                    if next == NO_DOF {
                        break;
                    }
                    (start, end) = (run_start[next], next + 1);
                }
            }
            i = parent[i];
        }
        let mut i = parent[k];
        while i != NO_DOF {
            h[k * n + i] /= pivot;
            i = parent[i];
        }
    }
    for k in 0..n {
        data.factor_inv_sqrt_d[k] = 1.0 / data.mass_matrix_factor[(k, k)].sqrt();
        // L's row k, held in column k above the diagonal, mirrored below it (the documented
        // layout, read by the solves).
        let mut j = parent[k];
        let mut coupled = false;
        while j != NO_DOF {
            let l = data.mass_matrix_factor[(j, k)];
            data.mass_matrix_factor[(k, j)] = l;
            coupled |= l != 0.0;
            j = parent[j];
        }
        data.factor_row_coupled[k] = coupled;
    }
    Ok(())
}

/// Solves `M x = b` in place (`x` holds b on entry) with the factor of [`factor_mass_matrix`].
pub fn solve_mass_matrix(model: &Model, data: &Data, x: &mut DVector<f64>) {
    solve_mass_matrix_slice(model, data, x.as_mut_slice());
}

/// [`solve_mass_matrix`] on a slice of length nv (a column of a column-major matrix, say).
pub fn solve_mass_matrix_slice(model: &Model, data: &Data, x: &mut [f64]) {
    debug_assert_eq!(x.len(), model.nv());
    let h = &data.mass_matrix_factor;
    let lambda = &model.dof_parent;
    let n = model.nv();
    for i in (0..n).rev() {
        let xi = x[i];
        // Rows of a contact or joint Jacobian are zero off the branch they act on.
        if xi == 0.0 {
            continue;
        }
        let mut j = lambda[i];
        while j != NO_DOF {
            x[j] -= h[(i, j)] * xi;
            j = lambda[j];
        }
    }
    for i in 0..n {
        x[i] /= h[(i, i)];
    }
    for i in 0..n {
        let mut j = lambda[i];
        let mut xi = x[i];
        while j != NO_DOF {
            xi -= h[(i, j)] * x[j];
            j = lambda[j];
        }
        x[i] = xi;
    }
}

/// Forward dynamics by CRBA and the tree-sparse factorization:
/// `q̈ = M(q)⁻¹ (τ − C(q, v) v − g(q))`, written to `data.ddq` and returned. Slower than
/// [`super::aba`] for long chains, but it leaves `M` and its factor in `data` for the
/// constraint solvers.
pub fn forward_dynamics_crba<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &DVector<f64>,
    v: &DVector<f64>,
    tau: &DVector<f64>,
) -> Result<&'d DVector<f64>, DynamicsError> {
    check_q(model, q)?;
    check_v(model, v, "v")?;
    check_v(model, tau, "tau")?;
    crba(model, data, q)?;
    factor_mass_matrix(model, data)?;
    nonlinear_effects(model, data, q, v)?;
    let mut ddq = std::mem::take(&mut data.ddq);
    ddq.copy_from(tau);
    ddq -= &data.nle;
    solve_mass_matrix(model, data, &mut ddq);
    data.ddq = ddq;
    Ok(&data.ddq)
}
