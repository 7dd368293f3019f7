//! Solvers of a [`ConstraintProblem`] behind one trait: our own Lemke pivoting method on the LCP
//! of the pyramid-friction formulation, clarabel's interior-point method on the convex
//! (Anitescu) cone program, and projected Gauss–Seidel (fast, approximate). Residuals are
//! computed outside the solvers by [`residuals()`], and a [`SolverChain`] falls back to the next
//! solver when one fails or misses its tolerance, recording why.

mod chain;
mod conic;
mod friction;
mod lemke;
mod newton;
mod pgs;
pub mod residuals;
mod subspace;

/// Why a solver returned no solution (defined with the other error enums in [`crate::error`]).
pub use crate::error::SolverError;
pub use chain::{ChainReport, Fallback, SolverChain};
pub use conic::{cone_program, lifted_cone_program, ClarabelSolver, ConeProgram};
pub use lemke::{
    lcp_of, lemke, lemke_with_report, Lcp, LemkeMemory, LemkeOptions, LemkeReport, LemkeSolver,
    RayCertificate,
};
pub use newton::NewtonSolver;
pub use pgs::{PgsSolver, PgsWorkspace};
pub use residuals::{residuals, QpResiduals, Residuals};

use crate::constraints::{ConstraintProblem, RowLaw};
use crate::math::all_finite;
use nalgebra::DVector;

/// Facts about one solve.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SolveInfo {
    /// Iterations (PGS sweeps, clarabel iterations) or pivots (Lemke).
    pub iterations: usize,
    /// Remarks (clarabel's AlmostSolved, Lemke's pyramid approximation of a cone, ...).
    pub note: Option<String>,
    /// The residuals of the returned impulses, when the solver computed them on its way (PGS:
    /// from its subspace step, or from the Wᵀλ its sweeps keep — equal to a fresh evaluation up
    /// to the rounding of that sum): a [`SolverChain`] then certifies with them instead of
    /// computing them again.
    pub residuals: Option<Residuals>,
}

/// A solver of constraint problems. `Send`, so that a [`crate::world::World`] holding a chain of
/// them can be moved to and stepped on another thread (batched rollouts step one world per thread).
pub trait ConstraintSolver: Send {
    /// Short name (`lemke`, `clarabel`, `pgs`).
    fn name(&self) -> &'static str;
    /// Solves `problem`, writing impulses (N·s) into `lambda`, which holds a warm start on entry
    /// (resized and zeroed by the solver if its length is wrong).
    fn solve(
        &mut self,
        problem: &ConstraintProblem,
        lambda: &mut DVector<f64>,
    ) -> Result<SolveInfo, SolverError>;
    /// The residual measure (m/s) that certifies this solver's formulation.
    fn certify(&self, residuals: &Residuals) -> f64 {
        residuals.exact()
    }
    /// Tells the solver the tolerance (m/s) its answer is certified against
    /// ([`SolverChain::tolerance`], before each solve): a solver that measures its own
    /// residual on the way may stop once it is well within it. Ignored by default.
    fn set_certified_tolerance(&mut self, _tolerance: f64) {}
    /// Whether the solver solves a problem other than the one it is certified on, so that its
    /// answers miss the certificate by design on some problems (`newton-exact`: the convex
    /// relaxation, certified on the exact formulation, misses wherever a contact slides). A
    /// chain passes over such a first solver for a while after it missed
    /// ([`SolverChain::skip_after_miss`]). False by default.
    fn certifies_part(&self) -> bool {
        false
    }
}

/// Checks the problem's sizes and finiteness once, for every solver.
pub(crate) fn check_problem(problem: &ConstraintProblem) -> Result<(), SolverError> {
    let n = problem.rows();
    let bad = |what: String| Err(SolverError::InvalidProblem(what));
    let shape_ok = problem.delassus.shape() == (n, n) || problem.is_matrix_free();
    if !shape_ok || problem.bias.len() != n || problem.regularization.len() != n {
        return bad(format!(
            "{n} rows but A is {:?} and b has {}",
            problem.delassus.shape(),
            problem.bias.len()
        ));
    }
    // With the sparse segments at hand, A is finite if they are (A is made of their products),
    // which is cheaper to check than n² entries; and a row's segments are finite if their
    // squared norm (summed by the assembly over the spans the solvers read) is — one value per
    // row instead of the nv-wide segments (a square overflowing to infinity flags a row of
    // W above 1e154, of no use either).
    let sp = &problem.sparsity;
    let finite_w = if sp.row_norm2.len() == n { all_finite(&sp.row_norm2) } else { all_finite(&sp.w_values) };
    let finite_a = if sp.is_empty() {
        all_finite(problem.delassus.as_slice())
    } else {
        finite_w && (problem.is_matrix_free() || (0..n).all(|i| problem.delassus[(i, i)].is_finite()))
    };
    if !finite_a || !all_finite(problem.bias.as_slice()) || !all_finite(problem.regularization.as_slice()) {
        return bad("A, b or R holds NaN or infinity".into());
    }
    for (k, c) in problem.contacts.iter().enumerate() {
        if c.normal + 2 >= n {
            return bad(format!("contact block at row {} exceeds {n} rows", c.normal));
        }
        if !(c.mu >= 0.0 && c.mu2 >= 0.0 && c.mu.is_finite() && c.mu2.is_finite()) {
            return bad(format!("contact at row {}: friction coefficients must be finite and ≥ 0", c.normal));
        }
        let friction = RowLaw::Friction { contact: k };
        if problem.laws[c.normal] != RowLaw::Unilateral
            || problem.laws[c.normal + 1] != friction
            || problem.laws[c.normal + 2] != friction
        {
            return bad(format!(
                "contact {k}: rows {}..{} must be a unilateral normal and two friction rows naming it",
                c.normal,
                c.normal + 2
            ));
        }
    }
    for (i, law) in problem.laws.iter().enumerate() {
        if let RowLaw::Friction { contact } = *law {
            let ok = problem.contacts.get(contact).is_some_and(|c| i == c.normal + 1 || i == c.normal + 2);
            if !ok {
                return bad(format!("row {i}: friction row names contact {contact}, which does not own it"));
            }
        }
        if let RowLaw::Bounded { lo, hi } = *law {
            if lo.is_nan() || hi.is_nan() || lo > hi {
                return bad(format!("row {i}: bounds [{lo}, {hi}] are not an interval"));
            }
        }
    }
    if let crate::constraints::FrictionModel::Pyramid { facets } = problem.friction {
        if facets < 3 {
            return bad(format!("a friction pyramid needs at least 3 facets, got {facets}"));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::math::all_finite;

    #[test]
    fn all_finite_finds_any_nan_or_infinity_in_every_position() {
        for len in 0..11 {
            let clean: Vec<f64> = (0..len).map(|i| i as f64 * -1.5e300).collect();
            assert!(all_finite(&clean));
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                for k in 0..len {
                    let mut x = clean.clone();
                    x[k] = bad;
                    assert!(!all_finite(&x), "{bad} at {k} of {len}");
                }
            }
        }
    }
}
