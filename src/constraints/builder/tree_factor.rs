//! The tree-sparse factor M = Lᵀ D L of one multibody and the back substitutions along a
//! dof's path to the root that turn a Jacobian row into a row of W = J L⁻¹ D^{-1/2}.

use crate::data::Data;
use crate::math::{axpy, dot};
use crate::model::{Model, NO_DOF};

/// The tree-sparse factor M = Lᵀ D L of one multibody ([`crate::algorithms::factor_mass_matrix`]):
/// L's entries below the diagonal and D on the diagonal of `factor`, `dof_parent` the tree.
#[derive(Clone, Copy, Debug)]
pub struct TreeFactor<'a> {
    /// L's rows packed along each dof's path ([`crate::algorithms::factor_mass_matrix`]): dof
    /// k's ancestors' entries, root first, then D_k, from `dof_path_start[k] + k`.
    packed: &'a [f64],
    dof_path: &'a [usize],
    dof_path_start: &'a [usize],
    inv_sqrt_d: &'a [f64],
    coupled: &'a [bool],
    pub(super) dof_parent: &'a [usize],
    run_start: &'a [usize],
}

impl<'a> TreeFactor<'a> {
    /// The factor held in `data` ([`crate::algorithms::factor_mass_matrix`] must have factored
    /// the current M).
    pub fn new(model: &'a Model, data: &'a Data) -> Self {
        Self {
            packed: &data.factor_packed,
            dof_path: &model.dof_path,
            dof_path_start: &model.dof_path_start,
            inv_sqrt_d: data.factor_inv_sqrt_d.as_slice(),
            coupled: &data.factor_row_coupled,
            dof_parent: &model.dof_parent,
            run_start: &model.dof_run_start,
        }
    }

    /// L_kj for the ancestors j of dof k in `start..end` (a stretch of consecutive ancestors):
    /// k's packed row holds its ancestors root first, so the stretch is contiguous there, from
    /// the position of `start` on k's path (its depth).
    pub(super) fn stretch(&self, k: usize, start: usize, end: usize) -> &'a [f64] {
        let depth_of_start = self.dof_path_start[start + 1] - self.dof_path_start[start];
        let from = self.dof_path_start[k] + k + depth_of_start;
        &self.packed[from..from + (end - start)]
    }

    /// Whether `dofs` (a side's point rates' dofs, [`crate::collision::point_rates`]) run from
    /// a dof up its path to the root, each the parent of the one before, ending at a root dof
    /// (or are empty).
    pub(super) fn is_path_to_root(&self, mut dofs: impl Iterator<Item = usize>) -> bool {
        let Some(mut k) = dofs.next() else { return true };
        for parent in dofs {
            if self.dof_parent.get(k) != Some(&parent) {
                return false;
            }
            k = parent;
        }
        self.dof_parent.get(k) == Some(&NO_DOF)
    }

    /// The ancestors of dof `tail`, root first.
    pub(super) fn chain(&self, tail: usize) -> &'a [usize] {
        &self.dof_path[self.dof_path_start[tail]..self.dof_path_start[tail + 1]]
    }

    /// [`Self::scale_chain_lanes`] for one row: `u[p]` its entry at the chain's p-th dof.
    pub(super) fn scale_chain(&self, tail: usize, u: &mut [f64]) {
        let path = self.chain(tail);
        debug_assert_eq!(u.len(), path.len() + 1);
        let dof_at = |p: usize| path.get(p).copied().unwrap_or(tail);
        for p in (1..u.len()).rev() {
            let (dof, up) = (dof_at(p), u[p]);
            if up == 0.0 || !self.coupled[dof] {
                continue;
            }
            axpy(&mut u[..p], -up, &self.packed[self.dof_path_start[dof] + dof..][..p]);
        }
        for (p, x) in u.iter_mut().enumerate() {
            *x *= self.inv_sqrt_d[dof_at(p)];
        }
    }

    /// [`Self::scale_row`] for up to four rows (lanes) non-zero only on the chain of dof `tail` and its
    /// ancestors: `u[p]` holds the lanes at the chain's p-th dof (root first, `tail` last). The
    /// ancestors of the chain's p-th dof are its first p dofs, and that dof's packed row of L
    /// holds their entries in the same order, so the back substitution is a dense triangular
    /// one over the chain: no walk of ancestor stretches, no scan of the block's other dofs.
    pub(super) fn scale_chain_lanes(&self, tail: usize, u: &mut [[f64; 4]]) {
        let path = self.chain(tail);
        debug_assert_eq!(u.len(), path.len() + 1);
        let dof_at = |p: usize| path.get(p).copied().unwrap_or(tail);
        // Right-looking: the latest entry p first, u_p subtracted from every earlier entry q
        // with L_pq, read from p's packed row, which holds its ancestors' entries in the
        // chain's order (the same operations in the same order per entry as collecting each
        // q from the later p, which looked each L_pq up by its own index). A dof whose row of L
        // is zero off the diagonal (a body whose origin is its centre of mass, on principal
        // axes) has nothing to subtract.
        for p in (1..u.len()).rev() {
            let dof = dof_at(p);
            if !self.coupled[dof] {
                continue;
            }
            let row = &self.packed[self.dof_path_start[dof] + dof..][..p];
            let (earlier, rest) = u.split_at_mut(p);
            let up = rest[0];
            for (uq, &l) in earlier.iter_mut().zip(row) {
                for a in 0..4 {
                    uq[a] -= l * up[a];
                }
            }
        }
        for (p, w) in u.iter_mut().enumerate() {
            let s = self.inv_sqrt_d[dof_at(p)];
            for x in w.iter_mut() {
                *x *= s;
            }
        }
    }

    /// For one row segment J (on the dofs `first_dof..first_dof + w.len()` of a block that is a
    /// union of whole root subtrees, `w` holding J on entry, `last` its last non-zero entry):
    /// writes w = D^{-1/2} L⁻ᵀ Jᵀ and returns the span [lo, hi) outside which w is zero.
    pub(super) fn scale_row(&self, first_dof: usize, last: usize, w: &mut [f64]) -> (usize, usize) {
        // w ← L⁻ᵀ w, walking each non-zero entry's ancestors (they have lower indices) in
        // contiguous stretches, L_kj read from k's packed row.
        for k in (0..=last).rev() {
            let wk = w[k];
            let row = first_dof + k;
            if wk == 0.0 || !self.coupled[row] {
                continue;
            }
            let (mut start, mut end) = (self.run_start[row], row);
            loop {
                axpy(&mut w[start - first_dof..end - first_dof], -wk, self.stretch(row, start, end));
                let next = self.dof_parent[start];
                if next == NO_DOF {
                    break;
                }
                (start, end) = (self.run_start[next], next + 1);
            }
        }
        let Some(lo) = w[..=last].iter().position(|x| *x != 0.0) else { return (0, 0) };
        for (w, s) in w[lo..=last].iter_mut().zip(&self.inv_sqrt_d[first_dof + lo..]) {
            *w *= s;
        }
        (lo, last + 1)
    }

    /// [`Self::scale_chain_lanes`] for rows non-zero on a union of paths to the root (a contact
    /// between two bodies of one block): `u` holds the lanes at the block's dofs (dof
    /// `first_dof + k` at `u[k]`), zero outside `pattern`, the union's block-local dofs in
    /// decreasing order (every dof's ancestors are in it). Right-looking as there: a dof's
    /// lanes are final once its descendants, which come before it, have been subtracted.
    pub(super) fn scale_pattern_lanes(&self, first_dof: usize, pattern: &[usize], u: &mut [[f64; 4]]) {
        for &k in pattern {
            let dof = first_dof + k;
            if !self.coupled[dof] {
                continue;
            }
            let uk = u[k];
            let path = self.chain(dof);
            let row = &self.packed[self.dof_path_start[dof] + dof..][..path.len()];
            for (&j, &l) in path.iter().zip(row) {
                let w = &mut u[j - first_dof];
                for a in 0..4 {
                    w[a] -= l * uk[a];
                }
            }
        }
        for &k in pattern {
            let s = self.inv_sqrt_d[first_dof + k];
            for x in u[k].iter_mut() {
                *x *= s;
            }
        }
    }

    /// x ← L⁻¹ D^{-1/2} x on a block's slice (the inverse map of the row scaling W = J L⁻¹ D^{-1/2}, so
    /// that M⁻¹Jᵀλ = L⁻¹ D^{-1/2} Wᵀλ).
    pub fn unscale_solve(&self, first_dof: usize, x: &mut [f64]) {
        let Some(lo) = x.iter().position(|x| *x != 0.0) else { return };
        // Entries below lo stay zero: no dof there has an ancestor at or above lo.
        for k in lo..x.len() {
            let row = first_dof + k;
            let mut xk = x[k] * self.inv_sqrt_d[row];
            if !self.coupled[row] {
                x[k] = xk;
                continue;
            }
            let (mut start, mut end) = (self.run_start[row], row);
            loop {
                xk -= dot(self.stretch(row, start, end), &x[start - first_dof..end - first_dof]);
                let next = self.dof_parent[start];
                if next == NO_DOF {
                    break;
                }
                (start, end) = (self.run_start[next], next + 1);
            }
            x[k] = xk;
        }
    }
}
