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
    let h = &mut data.mass_matrix_factor;
    let lambda = &model.dof_parent;
    // Only the entries (k, j) with j an ancestor of k (or k itself) are read and written: the
    // rest of a tree's M is zero and of no use (ten free boxes: 210 of 3600 entries).
    for k in 0..model.nv() {
        let mut j = k;
        while j != NO_DOF {
            h[(k, j)] = data.mass_matrix[(k, j)];
            j = lambda[j];
        }
    }
    for k in (0..model.nv()).rev() {
        let pivot = h[(k, k)];
        if pivot.is_nan() || pivot <= 0.0 || pivot <= PIVOT_TOLERANCE * data.mass_matrix[(k, k)] {
            return Err(DynamicsError::SingularMassMatrix {
                joint: model.joint_name(model.dof_joint(k)).to_string(),
            });
        }
        let mut i = lambda[k];
        while i != NO_DOF {
            let a = h[(k, i)] / pivot;
            let mut j = i;
            while j != NO_DOF {
                h[(i, j)] -= a * h[(k, j)];
                j = lambda[j];
            }
            h[(k, i)] = a;
            i = lambda[i];
        }
    }
    for k in 0..model.nv() {
        data.factor_inv_sqrt_d[k] = 1.0 / data.mass_matrix_factor[(k, k)].sqrt();
        // L's row k mirrored into column k above the diagonal (contiguous in memory), for the
        // row scaling of the constraint assembly, which walks ancestors in stretches.
        let mut j = lambda[k];
        let mut coupled = false;
        while j != NO_DOF {
            let l = data.mass_matrix_factor[(k, j)];
            data.mass_matrix_factor[(j, k)] = l;
            coupled |= l != 0.0;
            j = lambda[j];
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
