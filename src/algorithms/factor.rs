//! Tree-sparse factorization of the mass matrix (Featherstone, RBDA §6.5, "LTDL"):
//! `M = Lᵀ D L` with L unit lower triangular and non-zero only where the column's dof is an
//! ancestor of the row's dof. Costs O(n d²) for tree depth d and fills in nothing.

use super::check::{check_q, check_result_v, check_v};
use super::{crba, nonlinear_effects};
use crate::data::Data;
use crate::error::DynamicsError;
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// Relative size below which a pivot of the factorization counts as zero.
const PIVOT_TOLERANCE: f64 = 1e-12;

/// Factors `data.mass_matrix` (from [`crba`]) into M = Lᵀ D L, kept in `data` as packed rows
/// (see [`mass_matrix_factor`] for the dense view). A joint whose subtree cannot move gives
/// [`DynamicsError::SingularMassMatrix`].
pub fn factor_mass_matrix(model: &Model, data: &mut Data) -> Result<(), DynamicsError> {
    pack_mass_matrix(model, data);
    factor_packed_mass_matrix(model, data)
}

/// Gathers `data.mass_matrix`'s tree entries into the factorization's packed rows
/// (`data.factor_packed`): row k holds M_kj for the ancestors j of k, root first, then M_kk; the
/// rest of a tree's M is zero and of no use (ten free boxes: 210 of 3600 entries).
pub(crate) fn pack_mass_matrix(model: &Model, data: &mut Data) {
    let n = model.nv();
    let (paths, path_start) = (&model.dof_path, &model.dof_path_start);
    data.sized_mass_matrix(model);
    let m = data.mass_matrix.as_slice();
    for k in 0..n {
        let path = &paths[path_start[k]..path_start[k + 1]];
        let row = &mut data.factor_packed[path_start[k] + k..path_start[k + 1] + k + 1];
        for (x, &j) in row.iter_mut().zip(path) {
            *x = m[k * n + j];
        }
        row[path.len()] = m[k * n + k];
    }
}

/// [`factor_mass_matrix`] on M's packed rows, already in `data.factor_packed` (from
/// [`super::crba::crba_packed_at_kinematics`], or gathered from the dense M).
pub(crate) fn factor_packed_mass_matrix(model: &Model, data: &mut Data) -> Result<(), DynamicsError> {
    let n = model.nv();
    let (paths, path_start) = (&model.dof_path, &model.dof_path_start);
    // RBDA §6.5's LTDL on packed rows (MuJoCo's sparse factorization does the same): row k holds
    // H_kj for the ancestors j of k, root first, then H_kk. The ancestors of an ancestor i of k
    // are a prefix of k's (a path to the root is a chain), so the update of row i by row k is
    // one axpy over that prefix, with no index lookups. Only the entries (k, j) with j an
    // ancestor of k (or k) are read and written.
    let packed = &mut data.factor_packed;
    let row_start = |k: usize| path_start[k] + k;
    // M's diagonal, the scale of each pivot's zero test (the rows are overwritten by L and D);
    // kept where 1/√D goes at the end.
    let reference = &mut data.factor_inv_sqrt_d;
    for k in 0..n {
        reference[k] = packed[path_start[k + 1] + k];
    }
    for k in (0..n).rev() {
        let (start, depth) = (row_start(k), path_start[k + 1] - path_start[k]);
        let pivot = packed[start + depth];
        if pivot.is_nan() || pivot <= 0.0 || pivot <= PIVOT_TOLERANCE * reference[k] {
            return Err(DynamicsError::SingularMassMatrix {
                joint: model.joint_name(model.dof_joint(k)).to_string(),
            });
        }
        // For each ancestor i of k, nearest first (at depth p, so that its row has p + 1
        // entries): H_ij −= (H_ki / D_k) H_kj over the ancestors-or-self j of i, then
        // L_ki = H_ki / D_k. Row k's entries above i are still undivided when i is done, and
        // entry p is last read by its own update. One division per dof, not one per entry (a
        // ragdoll's 39 rows hold 381 entries; a division's throughput is that of several
        // multiply-adds).
        let inverse_pivot = 1.0 / pivot;
        let (before, row_k) = packed.split_at_mut(start);
        for p in (0..depth).rev() {
            let a = row_k[p] * inverse_pivot;
            if a != 0.0 {
                let i = paths[path_start[k] + p];
                crate::math::axpy(&mut before[row_start(i)..row_start(i) + p + 1], -a, &row_k[..=p]);
            }
            row_k[p] = a;
        }
    }
    for k in 0..n {
        let (start, depth) = (row_start(k), path_start[k + 1] - path_start[k]);
        data.factor_inv_sqrt_d[k] = 1.0 / packed[start + depth].sqrt();
        data.factor_row_coupled[k] = packed[start..start + depth].iter().any(|l| *l != 0.0);
    }
    Ok(())
}

/// The factor of [`factor_mass_matrix`] as a dense nv × nv matrix, for inspection (allocates):
/// D on the diagonal, L_kj at (k, j) and mirrored at (j, k) for each ancestor j of dof k, zero
/// elsewhere. The factorization itself keeps only the packed rows.
pub fn mass_matrix_factor(model: &Model, data: &Data) -> DMatrix<f64> {
    let n = model.nv();
    let mut h = DMatrix::zeros(n, n);
    for k in 0..n {
        let path = &model.dof_path[model.dof_path_start[k]..model.dof_path_start[k + 1]];
        let row = &data.factor_packed[model.dof_path_start[k] + k..][..=path.len()];
        h[(k, k)] = row[path.len()];
        for (&l, &j) in row.iter().zip(path) {
            h[(k, j)] = l;
            h[(j, k)] = l;
        }
    }
    h
}

/// Solves `M x = b` in place (`x` holds b on entry) with the factor of [`factor_mass_matrix`].
pub fn solve_mass_matrix(model: &Model, data: &Data, x: &mut DVector<f64>) {
    solve_mass_matrix_slice(model, data, x.as_mut_slice());
}

/// [`solve_mass_matrix`] on a slice of length nv (a column of a column-major matrix, say).
pub fn solve_mass_matrix_slice(model: &Model, data: &Data, x: &mut [f64]) {
    debug_assert_eq!(x.len(), model.nv());
    solve_mass_matrix_dofs(model, data, x, 0..model.nv());
}

/// [`solve_mass_matrix_slice`] for an `x` (length nv) that is zero outside `dofs`, a range of
/// dofs that holds whole subtrees of the root (with every dof, its ancestors and descendants):
/// M is block-diagonal over those subtrees, so only `x[dofs]` is read and written, in
/// O(entries of the range's factor) rather than O(entries of the whole factor).
pub(crate) fn solve_mass_matrix_dofs(
    model: &Model,
    data: &Data,
    x: &mut [f64],
    dofs: std::ops::Range<usize>,
) {
    let (paths, path_start, packed) = (&model.dof_path, &model.dof_path_start, &data.factor_packed);
    // Row i of L is packed contiguously, its ancestors root first (see factor_mass_matrix).
    let row = |i: usize| {
        let (start, depth) = (path_start[i], path_start[i + 1] - path_start[i]);
        (&paths[start..start + depth], &packed[start + i..=start + i + depth])
    };
    for i in dofs.clone().rev() {
        let xi = x[i];
        // Rows of a contact or joint Jacobian are zero off the branch they act on.
        if xi == 0.0 {
            continue;
        }
        let (path, l) = row(i);
        for (&j, l) in path.iter().zip(l) {
            x[j] -= l * xi;
        }
    }
    for i in dofs.clone() {
        let (path, l) = row(i);
        x[i] /= l[path.len()];
    }
    for i in dofs {
        let (path, l) = row(i);
        let mut xi = x[i];
        // Nearest ancestor first.
        for (&j, l) in path.iter().zip(l).rev() {
            xi -= l * x[j];
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
    check_result_v(model, &data.ddq, "forward dynamics")?;
    Ok(&data.ddq)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algorithms::crba;
    use crate::io::urdf::{load_file, UrdfOptions};
    use crate::model::NO_DOF;
    use nalgebra::{DMatrix, DVector};
    use rand::SeedableRng;

    #[test]
    fn packed_factor_rebuilds_the_mass_matrix_and_solves_with_it() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/models/ragdoll.urdf");
        let model = load_file(path, &UrdfOptions::floating()).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let n = model.nv();
        for _ in 0..5 {
            let q = model.random_configuration(&mut rng);
            let mut data = Data::new(&model);
            crba(&model, &mut data, &q).unwrap();
            factor_mass_matrix(&model, &mut data).unwrap();
            // M = Lᵀ D L with L unit lower triangular, L_kj at (k, j) for the ancestors j of k.
            let f = &mass_matrix_factor(&model, &data);
            let mut l = DMatrix::<f64>::identity(n, n);
            let mut d = DMatrix::<f64>::zeros(n, n);
            for k in 0..n {
                d[(k, k)] = f[(k, k)];
                assert_eq!(data.factor_inv_sqrt_d[k], 1.0 / f[(k, k)].sqrt());
                let mut j = model.dof_parent[k];
                while j != NO_DOF {
                    l[(k, j)] = f[(k, j)];
                    assert_eq!(f[(k, j)], f[(j, k)], "mirror of L at ({k}, {j})");
                    j = model.dof_parent[j];
                }
            }
            let m = &data.mass_matrix;
            let rebuilt = l.transpose() * d * &l;
            assert!((&rebuilt - m).abs().max() < 1e-12 * m.abs().max());
            let b = DVector::from_fn(n, |i, _| (i as f64 * 0.7).sin());
            let mut x = b.clone();
            solve_mass_matrix(&model, &data, &mut x);
            let expected = m.clone().cholesky().unwrap().solve(&b);
            assert!((&x - &expected).abs().max() < 1e-10 * expected.abs().max());
        }
    }

    /// The world's path (CRBA straight into the packed rows, factored in place) against the
    /// public one (dense M, gathered): the same rows bit for bit, the same factor, and a tree
    /// entry of M is where the packed row puts it.
    #[test]
    fn packed_crba_gives_the_rows_of_the_dense_mass_matrix() {
        use crate::algorithms::{compute_joint_jacobians, crba_packed_at_kinematics};
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/models/ragdoll.urdf");
        let model = load_file(path, &UrdfOptions::floating()).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(4);
        for _ in 0..3 {
            let q = model.random_configuration(&mut rng);
            let mut dense = Data::new(&model);
            crba(&model, &mut dense, &q).unwrap();
            pack_mass_matrix(&model, &mut dense);
            let mut packed = Data::new(&model);
            compute_joint_jacobians(&model, &mut packed, &q).unwrap();
            crba_packed_at_kinematics(&model, &mut packed);
            assert_eq!(packed.factor_packed, dense.factor_packed);
            // Dof k's row: its ancestors root first, then the diagonal.
            let k = model.nv() - 1;
            let (start, depth) =
                (model.dof_path_start[k] + k, model.dof_path_start[k + 1] - model.dof_path_start[k]);
            let root = model.dof_path[model.dof_path_start[k]];
            assert_eq!(packed.factor_packed[start], dense.mass_matrix[(k, root)]);
            assert_eq!(packed.factor_packed[start + depth], dense.mass_matrix[(k, k)]);
            factor_packed_mass_matrix(&model, &mut packed).unwrap();
            factor_packed_mass_matrix(&model, &mut dense).unwrap();
            assert_eq!(packed.factor_packed, dense.factor_packed);
            assert_eq!(packed.factor_inv_sqrt_d, dense.factor_inv_sqrt_d);
        }
    }
}
