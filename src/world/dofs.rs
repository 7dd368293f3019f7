//! The multibodies' dofs stacked into one vector: where each multibody's dofs start, the
//! diagonal blocks of the stacked mass matrix (one per root subtree), and the stacked
//! velocities that the rows and the solver work on.

use super::Multibody;
use crate::constraints::{ConstraintProblem, TreeFactor};
use nalgebra::DVector;

/// The stacked dofs of a world and its stacked velocities (rad/s or m/s per dof).
pub(super) struct StackedDofs {
    /// Dofs of every multibody together.
    pub(super) nv: usize,
    /// Diagonal blocks of the stacked mass matrix (first column, width): one per root subtree
    /// of each multibody.
    pub(super) blocks: Vec<(usize, usize)>,
    /// Per block, its multibody and the index of its first dof in that multibody.
    pub(super) block_owner: Vec<(usize, usize)>,
    /// Every multibody's velocity at the start of the step (sized to `nv` by `stack`).
    pub(super) v_start: DVector<f64>,
    /// The free velocity; after the solve, the velocity after the impulses.
    pub(super) v_free: DVector<f64>,
    /// Wᵀλ while applying impulses (`nv` entries).
    pub(super) impulse_scratch: Vec<f64>,
}

impl StackedDofs {
    /// No dofs.
    pub(super) fn new() -> Self {
        Self {
            nv: 0,
            blocks: Vec::new(),
            block_owner: Vec::new(),
            v_start: DVector::zeros(0),
            v_free: DVector::zeros(0),
            impulse_scratch: Vec::new(),
        }
    }

    /// Appends the dofs of `body`, multibody `index`, and sets its first column.
    pub(super) fn add(&mut self, index: usize, body: &mut Multibody) {
        body.col = self.nv;
        for (first, width) in body.model.root_subtree_dofs() {
            self.blocks.push((body.col + first, width));
            self.block_owner.push((index, first));
        }
        // The stacked vectors are sized by the next `stack`: a world built body by body stays
        // linear in its size.
        self.nv += body.model.nv();
    }

    /// Stacks every multibody's velocity at the step's start and its free velocity.
    pub(super) fn stack(&mut self, bodies: &[Multibody]) {
        if self.v_start.len() != self.nv {
            self.v_start = DVector::zeros(self.nv);
            self.v_free = DVector::zeros(self.nv);
        }
        for b in bodies {
            let (col, nv) = (b.col, b.model.nv());
            self.v_start.rows_mut(col, nv).copy_from(&b.state.v);
            self.v_free.rows_mut(col, nv).copy_from(&b.v_free);
        }
    }

    /// `v_free += M⁻¹ Jᵀ λ`: the velocity after the impulses `lambda` (N·s) of `problem`'s rows.
    pub(super) fn apply_impulses(
        &mut self,
        problem: &ConstraintProblem,
        lambda: &DVector<f64>,
        bodies: &[Multibody],
    ) {
        let factor_of = block_factors(bodies, &self.block_owner);
        problem.apply_impulses(lambda, &mut self.v_free, &mut self.impulse_scratch, factor_of);
    }
}

/// Per block of the stacked mass matrix, the factor of its multibody and the block's first dof
/// in it; none for a block that cannot move (asleep, kinematic or unfactored).
pub(super) fn block_factors<'a>(
    bodies: &'a [Multibody],
    owners: &'a [(usize, usize)],
) -> impl Fn(usize) -> Option<(TreeFactor<'a>, usize)> + 'a {
    move |block| {
        let (k, first_dof) = owners[block];
        let b = &bodies[k];
        let movable = !(b.asleep || b.kinematic || !b.factored);
        movable.then(|| (TreeFactor::new(&b.model, &b.data), first_dof))
    }
}
