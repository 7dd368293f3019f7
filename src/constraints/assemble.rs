//! Assembly: rows collected by a [`ProblemBuilder`] become a [`ConstraintProblem`] with the
//! Delassus matrix `A = J M⁻¹ Jᵀ` computed from the factor of M (one tree-sparse solve per row,
//! never forming M⁻¹).

use super::{ConstraintProblem, ContactBlock, FrictionModel, RowLaw, RowOrigin};
use crate::algorithms::solve_mass_matrix_slice;
use crate::data::Data;
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// Collects constraint rows (Jacobian row, law, target velocity, softness) for one step.
/// Buffers are kept between steps.
#[derive(Clone, Debug)]
pub struct ProblemBuilder {
    nv: usize,
    rows: Vec<f64>,
    targets: Vec<f64>,
    softness: Vec<f64>,
    laws: Vec<RowLaw>,
    contacts: Vec<ContactBlock>,
    origins: Vec<RowOrigin>,
    /// Friction model of the contacts.
    pub friction: FrictionModel,
}

impl ProblemBuilder {
    /// An empty builder for a system of `nv` velocity coordinates.
    pub fn new(nv: usize, friction: FrictionModel) -> Self {
        Self {
            nv,
            rows: Vec::new(),
            targets: Vec::new(),
            softness: Vec::new(),
            laws: Vec::new(),
            contacts: Vec::new(),
            origins: Vec::new(),
            friction,
        }
    }

    /// Number of velocity coordinates.
    pub fn nv(&self) -> usize {
        self.nv
    }

    /// Number of rows so far.
    pub fn len(&self) -> usize {
        self.laws.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.laws.is_empty()
    }

    /// Removes every row (keeps the buffers).
    pub fn clear(&mut self) {
        self.rows.clear();
        self.targets.clear();
        self.softness.clear();
        self.laws.clear();
        self.contacts.clear();
        self.origins.clear();
    }

    /// Appends a row and returns its index and its Jacobian row (zeroed, nv entries) to fill.
    /// `target` is the row's target velocity u*, `softness` its regularisation R_ii.
    pub fn push_row(
        &mut self,
        law: RowLaw,
        target: f64,
        softness: f64,
        origin: RowOrigin,
    ) -> (usize, &mut [f64]) {
        let index = self.laws.len();
        self.laws.push(law);
        self.targets.push(target);
        self.softness.push(softness);
        self.origins.push(origin);
        let start = self.rows.len();
        self.rows.resize(start + self.nv, 0.0);
        (index, &mut self.rows[start..])
    }

    /// Registers a contact block whose normal row is `normal` (the two friction rows follow it).
    pub fn push_contact_block(&mut self, block: ContactBlock) -> usize {
        self.contacts.push(block);
        self.contacts.len() - 1
    }

    /// Number of contact blocks so far.
    pub fn contact_count(&self) -> usize {
        self.contacts.len()
    }

    /// Sets the target velocity of row `i`.
    pub fn set_target(&mut self, i: usize, target: f64) {
        self.targets[i] = target;
    }

    /// The Jacobian row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.rows[i * self.nv..(i + 1) * self.nv]
    }

    /// Builds the problem into `problem` with `minv` applying M⁻¹ in place to a vector of nv
    /// entries, and `v_free` the free velocity.
    pub fn build_into(
        &self,
        v_free: &DVector<f64>,
        mut minv: impl FnMut(&mut [f64]),
        problem: &mut ConstraintProblem,
    ) {
        let (n, nv) = (self.len(), self.nv);
        if problem.jacobian.shape() != (n, nv) {
            problem.jacobian = DMatrix::zeros(n, nv);
            problem.minv_jt = DMatrix::zeros(nv, n);
            problem.delassus = DMatrix::zeros(n, n);
            problem.regularization = DVector::zeros(n);
            problem.bias = DVector::zeros(n);
            problem.target = DVector::zeros(n);
        }
        for i in 0..n {
            let row = self.row(i);
            for (k, &x) in row.iter().enumerate() {
                problem.jacobian[(i, k)] = x;
                problem.minv_jt[(k, i)] = x;
            }
            minv(problem.minv_jt.column_mut(i).as_mut_slice());
        }
        // A = J (M⁻¹Jᵀ), symmetric: the lower triangle from contiguous rows of J and columns of
        // M⁻¹Jᵀ, mirrored (a hand loop: nalgebra's dynamic gemm allocates a packing buffer).
        for j in 0..n {
            let x = problem.minv_jt.column(j);
            let x = x.as_slice();
            for i in j..n {
                let a: f64 = self.row(i).iter().zip(x).map(|(a, b)| a * b).sum();
                problem.delassus[(i, j)] = a;
                problem.delassus[(j, i)] = a;
            }
        }
        problem.bias.gemv(1.0, &problem.jacobian, v_free, 0.0);
        for i in 0..n {
            problem.bias[i] -= self.targets[i];
            problem.target[i] = self.targets[i];
            problem.regularization[i] = self.softness[i];
        }
        problem.laws.clone_from(&self.laws);
        problem.contacts.clone_from(&self.contacts);
        problem.origins.clone_from(&self.origins);
        problem.friction = self.friction;
    }
}

/// Builds the problem of a single multibody: `data.mass_matrix_factor` must hold the factor of
/// M(q) ([`crate::algorithms::factor_mass_matrix`]).
pub fn assemble_single(
    builder: &ProblemBuilder,
    model: &Model,
    data: &Data,
    v_free: &DVector<f64>,
    problem: &mut ConstraintProblem,
) {
    builder.build_into(v_free, |x| solve_mass_matrix_slice(model, data, x), problem);
}
