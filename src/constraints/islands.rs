//! Islands of a constraint problem: rows joined through the velocity blocks they touch (W's
//! rows share a block when their bodies touch through contacts, joint rows or loop closures)
//! form an island, and islands share no velocity coordinate. A and W are block diagonal over
//! the islands, so the problem is as many independent problems (Box2D's and ODE's islands,
//! MuJoCo's `mj_island`): each is solved on its own, with the cost of its own size, and islands
//! may be solved on different threads.
//!
//! [`IslandPartition::split`] finds the islands of a problem (union–find over blocks and rows,
//! O(rows + W's block entries)); [`IslandPartition::extract`] writes one island as a problem of
//! its own, with its blocks' columns numbered from 0, its rows, laws, contact blocks, W's runs,
//! the diagonal and friction couplings kept by assembly, and A's sub-matrix when A is formed.

use super::builder::index_rows_by_block;
use super::{ConstraintProblem, ContactBlock, RowLaw};
use nalgebra::DMatrix;

/// Marks a node, block or contact that belongs to no island.
const NONE: usize = usize::MAX;

/// The islands of a problem (see the module documentation); buffers are kept between splits.
#[derive(Clone, Debug, Default)]
pub struct IslandPartition {
    /// Union–find parents over the nodes: block b is node b, row i is node `blocks + i`.
    parent: Vec<usize>,
    /// Per root node, its island (NONE for a component without rows).
    island_of_node: Vec<usize>,
    /// Per row, its island, then its index within the island.
    island_of_row: Vec<usize>,
    local_row: Vec<usize>,
    /// Per block, its index within its island (NONE: touched by no row).
    local_block: Vec<usize>,
    /// Per row, the contact whose normal it is (NONE otherwise); per contact, its index among
    /// its island's contacts.
    contact_of_normal: Vec<usize>,
    local_contact: Vec<usize>,
    /// The islands' rows (increasing within each) and blocks (increasing), island after island:
    /// island k's are `rows[row_start[k]..row_start[k + 1]]` and likewise for blocks.
    rows: Vec<usize>,
    row_start: Vec<usize>,
    blocks: Vec<usize>,
    block_start: Vec<usize>,
}

impl IslandPartition {
    /// Finds the islands of `problem`, numbered in the order of their first rows; returns how
    /// many there are. A problem without W's block structure (given by its matrix alone) is one
    /// island.
    pub fn split(&mut self, problem: &ConstraintProblem) -> usize {
        let n = problem.rows();
        let sp = &problem.sparsity;
        let nb = if sp.is_empty() { 0 } else { sp.blocks.len() };
        self.parent.clear();
        self.parent.extend(0..nb + n);
        if sp.is_empty() {
            // No block structure: every row is joined to the first.
            for i in 1..n {
                self.union(nb, nb + i);
            }
        } else {
            for i in 0..n {
                for &b in sp.row_blocks(i) {
                    self.union(b, nb + i);
                }
            }
        }
        self.contact_of_normal.clear();
        self.contact_of_normal.resize(n, NONE);
        for (k, c) in problem.contacts.iter().enumerate() {
            // A contact's three rows stay together, whatever they touch.
            self.union(nb + c.normal, nb + c.normal + 1);
            self.union(nb + c.normal, nb + c.normal + 2);
            self.contact_of_normal[c.normal] = k;
        }
        self.island_of_node.clear();
        self.island_of_node.resize(nb + n, NONE);
        self.island_of_row.clear();
        let mut count = 0;
        for i in 0..n {
            let root = self.find(nb + i);
            if self.island_of_node[root] == NONE {
                self.island_of_node[root] = count;
                count += 1;
            }
            self.island_of_row.push(self.island_of_node[root]);
        }
        // Rows and blocks by island (counting sort: increasing within each island).
        counting_sort(&self.island_of_row, count, &mut self.row_start, &mut self.rows, &mut self.local_row);
        self.local_block.clear();
        self.local_block.resize(nb, NONE);
        let mut island_of_block = std::mem::take(&mut self.island_of_node);
        for b in 0..nb {
            let root = self.find(b);
            island_of_block[b] = island_of_block[root];
        }
        island_of_block.truncate(nb);
        let mut block_local = std::mem::take(&mut self.local_block);
        counting_sort(&island_of_block, count, &mut self.block_start, &mut self.blocks, &mut block_local);
        self.local_block = block_local;
        self.island_of_node = island_of_block;
        self.local_contact.clear();
        self.local_contact.resize(problem.contacts.len(), NONE);
        let mut contacts_in = std::mem::take(&mut self.parent);
        contacts_in.clear();
        contacts_in.resize(count, 0);
        for &i in &self.rows {
            let k = self.contact_of_normal[i];
            if k != NONE {
                let island = self.island_of_row[i];
                self.local_contact[k] = contacts_in[island];
                contacts_in[island] += 1;
            }
        }
        self.parent = contacts_in;
        count
    }

    /// Number of islands of the last split.
    pub fn len(&self) -> usize {
        self.row_start.len().saturating_sub(1)
    }

    /// Whether the last split found no island (no rows).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The rows of island `k`, increasing.
    pub fn rows(&self, k: usize) -> &[usize] {
        &self.rows[self.row_start[k]..self.row_start[k + 1]]
    }

    /// The velocity blocks of island `k`, increasing.
    pub fn blocks(&self, k: usize) -> &[usize] {
        &self.blocks[self.block_start[k]..self.block_start[k + 1]]
    }

    /// Writes island `k` of `problem` (the problem last split) into `out` as a problem of its
    /// own: its rows in increasing order, its blocks' columns numbered from 0 in increasing block
    /// order. Buffers of `out` are reused; its vectors are reallocated only when their size
    /// changes.
    pub fn extract(&self, problem: &ConstraintProblem, k: usize, out: &mut ConstraintProblem) {
        let rows = self.rows(k);
        let n = rows.len();
        out.reset_rows(n);
        out.friction = problem.friction;
        out.kept_lambda.0.get_mut().clear();
        for (l, &i) in rows.iter().enumerate() {
            out.bias[l] = problem.bias[i];
            out.regularization[l] = problem.regularization[i];
            out.target[l] = problem.target[i];
            out.origins.push(problem.origins[i]);
            out.laws.push(match problem.laws[i] {
                RowLaw::Friction { contact } => RowLaw::Friction { contact: self.local_contact[contact] },
                law => law,
            });
            let c = self.contact_of_normal[i];
            if c != NONE {
                out.contacts.push(ContactBlock { normal: l, ..problem.contacts[c] });
            }
        }
        self.extract_sparsity(problem, k, out);
        if problem.is_matrix_free() {
            if out.delassus.nrows() != 0 {
                out.delassus = DMatrix::zeros(0, 0);
            }
            out.sparsity.block_start.clear();
        } else {
            if out.delassus.shape() != (n, n) {
                out.delassus = DMatrix::zeros(n, n);
            }
            for (b, &j) in rows.iter().enumerate() {
                for (a, &i) in rows.iter().enumerate() {
                    out.delassus[(a, b)] = problem.delassus[(i, j)];
                }
            }
            if !out.sparsity.is_empty() {
                index_rows_by_block(&mut out.sparsity);
            }
        }
    }

    /// W's block structure and runs of island `k`, its columns renumbered.
    fn extract_sparsity(&self, problem: &ConstraintProblem, k: usize, out: &mut ConstraintProblem) {
        let (sp, local) = (&problem.sparsity, &mut out.sparsity);
        local.blocks.clear();
        local.row_start.clear();
        local.blocks_of_row.clear();
        local.entry_run_start.clear();
        local.w_values.clear();
        local.row_norm2.clear();
        local.friction_coupling.clear();
        local.runs.clear();
        local.run_start.clear();
        local.rows_of_block.clear();
        local.entry_of_block_row.clear();
        local.block_start.clear();
        local.nv = 0;
        if sp.is_empty() {
            return;
        }
        for &b in self.blocks(k) {
            let width = sp.blocks[b].1;
            local.blocks.push((local.nv, width));
            local.nv += width;
        }
        local.row_start.push(0);
        local.entry_run_start.push(0);
        local.run_start.push(0);
        let rows = self.rows(k);
        for &i in rows {
            local.push_row_from(sp, i, &self.local_block);
        }
        if sp.row_norm2.len() == problem.rows() {
            local.row_norm2.extend(rows.iter().map(|&i| sp.row_norm2[i]));
        }
        if !sp.friction_coupling.is_empty() && sp.friction_coupling.len() == problem.contacts.len() {
            local.friction_coupling.extend(rows.iter().filter_map(|&i| {
                let c = self.contact_of_normal[i];
                (c != NONE).then(|| sp.friction_coupling[c])
            }));
        }
    }

    fn find(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.parent[ra.max(rb)] = ra.min(rb);
        }
    }
}

/// Items `0..of.len()` grouped by `of[item]` (`groups` groups; NONE: in none): `start` gets
/// the groups' offsets into `items` (increasing within each group), `local[item]` the item's
/// index within its group (NONE for items in none).
fn counting_sort(
    of: &[usize],
    groups: usize,
    start: &mut Vec<usize>,
    items: &mut Vec<usize>,
    local: &mut Vec<usize>,
) {
    start.clear();
    start.resize(groups + 1, 0);
    for &g in of.iter().filter(|&&g| g != NONE) {
        start[g + 1] += 1;
    }
    for g in 0..groups {
        start[g + 1] += start[g];
    }
    items.clear();
    items.resize(start[groups], 0);
    local.clear();
    local.resize(of.len(), NONE);
    // start[g] serves as group g's fill cursor, then is restored.
    for (item, &g) in of.iter().enumerate() {
        if g != NONE {
            items[start[g]] = item;
            local[item] = start[g];
            start[g] += 1;
        }
    }
    for g in (0..groups).rev() {
        start[g + 1] = start[g];
    }
    start[0] = 0;
    for (item, &g) in of.iter().enumerate() {
        if g != NONE {
            local[item] -= start[g];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solvers::{residuals, ConstraintSolver, PgsSolver};
    use nalgebra::DVector;

    /// A matrix-free problem of three multibodies (one block each): rows 0–2 a contact on
    /// block 0 and block 2, row 3 a limit on block 1, rows 4–6 a contact on block 2 alone, so
    /// islands {0, 1, 2, 4, 5, 6} and {3}.
    fn three_bodies() -> ConstraintProblem {
        use crate::constraints::{FrictionModel, RowOrigin, RowSparsity};
        let blocks = vec![(0, 2), (2, 1), (3, 2)];
        // Per row: (block, first column, values).
        let rows: Vec<Vec<(usize, usize, Vec<f64>)>> = vec![
            vec![(0, 0, vec![1.0, 0.5]), (2, 3, vec![-0.7, 0.2])],
            vec![(0, 0, vec![0.1, 0.9]), (2, 3, vec![0.3, 0.4])],
            vec![(0, 1, vec![0.8]), (2, 4, vec![-0.6])],
            vec![(1, 2, vec![1.3])],
            vec![(2, 3, vec![0.9, 0.1])],
            vec![(2, 3, vec![0.2, 1.1])],
            vec![(2, 4, vec![0.5])],
        ];
        let mut sp = RowSparsity { nv: 5, blocks, ..Default::default() };
        sp.row_start.push(0);
        sp.entry_run_start.push(0);
        sp.run_start.push(0);
        for row in &rows {
            let mut norm2 = 0.0;
            for (b, col, values) in row {
                sp.blocks_of_row.push(*b);
                sp.runs.push((*col, sp.w_values.len(), values.len()));
                sp.w_values.extend_from_slice(values);
                sp.entry_run_start.push(sp.runs.len());
                norm2 += values.iter().map(|x| x * x).sum::<f64>();
            }
            sp.row_start.push(sp.blocks_of_row.len());
            sp.run_start.push(sp.runs.len());
            sp.row_norm2.push(norm2);
        }
        let laws = vec![
            RowLaw::Unilateral,
            RowLaw::Friction { contact: 0 },
            RowLaw::Friction { contact: 0 },
            RowLaw::Unilateral,
            RowLaw::Unilateral,
            RowLaw::Friction { contact: 1 },
            RowLaw::Friction { contact: 1 },
        ];
        let contacts = vec![
            ContactBlock { normal: 0, mu: 0.5, mu2: 0.5 },
            ContactBlock { normal: 4, mu: 0.8, mu2: 0.8 },
        ];
        let bias = DVector::from_vec(vec![-1.0, 0.3, -0.2, -0.5, -2.0, 0.1, 0.4]);
        let mut p =
            ConstraintProblem::from_parts(DMatrix::zeros(0, 0), bias, laws, contacts, FrictionModel::Cone);
        p.origins = vec![RowOrigin::Other; 7];
        p.sparsity = sp;
        assert!(p.is_matrix_free());
        p
    }

    #[test]
    fn rows_joined_through_blocks_form_islands_and_each_island_solves_like_the_whole() {
        let p = three_bodies();
        let mut islands = IslandPartition::default();
        assert_eq!(islands.split(&p), 2);
        assert_eq!(islands.rows(0), &[0, 1, 2, 4, 5, 6]);
        assert_eq!(islands.blocks(0), &[0, 2]);
        assert_eq!(islands.rows(1), &[3]);
        assert_eq!(islands.blocks(1), &[1]);
        // The whole problem and its islands solved alike give the same impulses.
        let solve = |q: &ConstraintProblem| {
            let mut lambda = DVector::zeros(q.rows());
            PgsSolver::new(2000, 1e-14, 1.0, true).solve(q, &mut lambda).unwrap();
            lambda
        };
        let whole = solve(&p);
        let mut sub = ConstraintProblem::default();
        for k in 0..2 {
            islands.extract(&p, k, &mut sub);
            assert_eq!(sub.rows(), islands.rows(k).len());
            // The island's A is the whole A's sub-matrix.
            for (a, &i) in islands.rows(k).iter().enumerate() {
                for (b, &j) in islands.rows(k).iter().enumerate() {
                    assert!((sub.delassus_entry(a, b) - p.delassus_entry(i, j)).abs() < 1e-15);
                }
            }
            let part = solve(&sub);
            let mut w = DVector::zeros(0);
            assert!(residuals(&sub, &part, &mut w).exact() < 1e-9);
            for (a, &i) in islands.rows(k).iter().enumerate() {
                assert!((part[a] - whole[i]).abs() < 1e-9, "row {i}: {} vs {}", part[a], whole[i]);
            }
        }
        // The second contact is the island's second contact, its friction rows name it.
        islands.extract(&p, 0, &mut sub);
        assert_eq!(sub.contacts[1].normal, 3);
        assert_eq!(sub.laws[4], RowLaw::Friction { contact: 1 });
        assert_eq!(sub.sparsity.nv, 4);
    }

    #[test]
    fn a_problem_given_by_its_matrix_alone_is_one_island() {
        let mut p = three_bodies();
        let a = p.delassus_dense().into_owned();
        p.delassus = a;
        p.sparsity = Default::default();
        let mut islands = IslandPartition::default();
        assert_eq!(islands.split(&p), 1);
        let mut sub = ConstraintProblem::default();
        islands.extract(&p, 0, &mut sub);
        assert_eq!(sub.delassus, p.delassus);
        assert_eq!(sub.laws, p.laws);
    }
}
