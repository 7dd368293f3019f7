//! Lemke's method as a [`ConstraintSolver`], with what one solve leaves for the next.

use super::columns::{Columns, Matrix};
use super::delassus::MatrixKey;
use super::lcp::{sparse_lcp_of, SparseLcp};
use super::{path_options, residual_of_columns, solve_from_basis, solve_sparse, Solution};
use super::{Equilibrated, LemkeOptions, LemkeReport};
use crate::constraints::{ConstraintProblem, FrictionModel};
use crate::solvers::residuals::residuals_with_friction;
use crate::solvers::{check_problem, residuals, ConstraintSolver, SolveInfo, SolverError};
use nalgebra::DVector;

/// Lemke's method as a [`ConstraintSolver`] (friction as a pyramid; a cone is approximated by
/// `facets` directions).
#[derive(Clone, Debug)]
pub struct LemkeSolver {
    /// Pivoting options.
    pub options: LemkeOptions,
    /// Pyramid directions used when the problem states a cone.
    pub facets: usize,
    /// What the last solve leaves for the next (its LCP and final basis).
    pub memory: LemkeMemory,
    /// The tolerance (m/s) of the problem's residual that certifies an answer
    /// ([`ConstraintSolver::set_certified_tolerance`], from a solver chain or a benchmark): an
    /// answer whose LCP residual misses `options.tolerance` is accepted when its problem
    /// residual is within this, instead of trying the other covering vectors; an answer within
    /// the LCP tolerance whose residual on the problem the LCP poses (a cone's pyramid) misses
    /// this is refined by a path from its basis with a finer LCP tolerance, kept when it is
    /// better ([`LemkeReport::refined_to_level`]). `None`: only the LCP tolerance.
    pub certified_tolerance: Option<f64>,
}

impl Default for LemkeSolver {
    fn default() -> Self {
        Self {
            options: LemkeOptions::default(),
            facets: 8,
            memory: LemkeMemory::default(),
            certified_tolerance: None,
        }
    }
}

/// What a [`LemkeSolver`] keeps from its last solve for the next: the LCP (M by sparse
/// columns, its equilibration, and the key of the problem data M was formed from) and the
/// complementary basis of the answer.
///
/// - A problem with the same key (the same rows and laws, the same R and the same A or W bit
///   for bit, as a world poses while its bodies rest and it keeps W) poses the same M: only q
///   is formed anew.
/// - The last basis is the start of the next solve when the LCP has the same variables (the
///   same rows, laws and contacts) in the same order, which the warm start shows by being the
///   last answer's impulses bit for bit (a world that matched its rows to the last step's found
///   each in its place): a resting stack's basis stays feasible as q changes a little, and is
///   then the answer without a pivot; a slightly infeasible one is repaired by a few pivots
///   from it (`Path::restart`).
/// - Otherwise, or when that start fails, a basis is read from the warm-start impulses
///   (`SparseLcp::basis_of_impulses`): a world matches them to the new rows by their contacts'
///   identity, so contacts that came, went or changed places keep their impulses.
/// - A path from a start is held to as many pivots as the start has active variables plus 100;
///   a start that fails is dropped for the paths from the identity, so the answer is the one a
///   cold solve certifies.
#[derive(Clone, Debug)]
pub struct LemkeMemory {
    /// Whether solves start from the last basis and reuse the last M (on by default).
    pub enabled: bool,
    key: MatrixKey,
    lcp: Option<SparseLcp>,
    /// M's equilibration, once a solve needed it.
    equilibrated: Option<Equilibrated>,
    /// The last answer's complementary basis and the laws and contact rows of its problem.
    basis: Option<Vec<usize>>,
    shape: (Vec<crate::constraints::RowLaw>, Vec<usize>, usize),
    /// The last answer's impulses λ.
    impulses: DVector<f64>,
    /// Facts of the last solve.
    pub last: LemkeReport,
    /// Solves whose M was the last solve's (only q formed).
    pub reused_matrices: usize,
}

impl Default for LemkeMemory {
    fn default() -> Self {
        Self {
            enabled: true,
            key: MatrixKey::default(),
            lcp: None,
            equilibrated: None,
            basis: None,
            shape: (Vec::new(), Vec::new(), 0),
            impulses: DVector::zeros(0),
            last: LemkeReport::default(),
            reused_matrices: 0,
        }
    }
}

impl LemkeMemory {
    /// A memory that is never used: every solve starts from the identity basis.
    pub fn off() -> Self {
        Self { enabled: false, ..Self::default() }
    }

    /// Whether the basis kept is a start for `problem`'s LCP with `facets`: the same rows, laws
    /// and contact rows, hence the same LCP variables.
    fn shape_matches(&self, problem: &ConstraintProblem, facets: usize) -> bool {
        self.shape.2 == facets
            && self.shape.0 == problem.laws
            && self.shape.1.len() == problem.contacts.len()
            && self.shape.1.iter().zip(&problem.contacts).all(|(&n, c)| n == c.normal)
    }
}

impl ConstraintSolver for LemkeSolver {
    fn name(&self) -> &'static str {
        "lemke"
    }

    fn set_certified_tolerance(&mut self, tolerance: f64) {
        self.certified_tolerance = Some(tolerance);
    }

    fn solve(
        &mut self,
        problem: &ConstraintProblem,
        lambda: &mut DVector<f64>,
    ) -> Result<SolveInfo, SolverError> {
        check_problem(problem)?;
        if matches!(problem.friction, FrictionModel::Cone) && self.facets < 3 {
            return Err(SolverError::InvalidProblem(format!(
                "a friction cone needs a pyramid of at least 3 facets, Lemke was given {}",
                self.facets
            )));
        }
        let memory = &mut self.memory;
        let facets = self.facets;
        let same_matrix = memory.enabled && memory.lcp.is_some() && memory.key.matches(problem, facets);
        if same_matrix {
            memory.reused_matrices += 1;
            memory.lcp.as_mut().expect("kept with its key").update_q(problem);
        } else {
            let lcp = sparse_lcp_of(problem, facets, self.options.max_matrix_entries)?;
            memory.equilibrated = None;
            memory.lcp = Some(lcp);
            if memory.enabled {
                memory.key.fill(problem, facets);
            }
        }
        // The starts tried in order: the last basis, when the LCP has the same variables in the
        // same order (λ is then the last answer's impulses: the rows came as they were), and the
        // basis read from the warm start λ (the caller's impulses matched to the rows by their
        // contacts' identity), unless it is the same basis.
        let enabled = memory.enabled;
        let kept = memory.basis.take().filter(|_| {
            memory.enabled && memory.shape_matches(problem, facets) && memory.impulses == *lambda
        });
        let lcp = memory.lcp.as_mut().expect("formed above");
        // An answer above the LCP tolerance is accepted when the problem's residual (the one
        // the chain certifies) is within the chain's tolerance.
        let mut scratch = DVector::zeros(0);
        let tolerance = self.certified_tolerance;
        let mut certify = |lcp: &SparseLcp, z: &DVector<f64>| {
            tolerance.is_some_and(|tolerance| {
                let r = residuals(problem, &lcp.impulses(z), &mut scratch);
                r.exact() <= tolerance
            })
        };
        let mut warm = Err(LemkeReport::default());
        if let Some(start) = &kept {
            warm = solve_from_basis(
                &mut Columns { m: Matrix::Lazy(lcp), d: Vec::new() },
                &lcp.q,
                &self.options,
                start,
                &mut |z| certify(lcp, z),
                false,
            );
        }
        if let Err(done) = &warm {
            let read = (enabled && lambda.iter().any(|&l| l != 0.0))
                .then(|| lcp.basis_of_impulses(problem, facets, lambda))
                .flatten()
                .filter(|read| kept.as_ref() != Some(read));
            if let Some(start) = read {
                let done = done.clone();
                warm = solve_from_basis(
                    &mut Columns { m: Matrix::Lazy(lcp), d: Vec::new() },
                    &lcp.q,
                    &self.options,
                    &start,
                    &mut |z| certify(lcp, z),
                    false,
                )
                .map(|mut solution| {
                    solution.report = done.clone().merged(solution.report);
                    solution
                })
                .map_err(|report| done.merged(report));
            }
        }
        let outcome = match warm {
            Ok(solution) => Ok(solution),
            Err(report) => {
                let formed = lcp.form_m(self.options.max_matrix_entries).map(|_| ());
                let lcp = &*lcp;
                formed.and_then(|()| {
                    let m = lcp.m.as_ref().expect("formed above");
                    solve_sparse(m, &lcp.q, &self.options, &mut memory.equilibrated, report, &mut |z| {
                        certify(lcp, z)
                    })
                })
            }
        };
        let mut solution = match outcome {
            Ok(solution) => solution,
            Err(e) => {
                memory.basis = None;
                return Err(e);
            }
        };
        let lcp = memory.lcp.as_ref().expect("formed above");
        if let Some(level) = self.certified_tolerance {
            refine_to_level(problem, facets, lcp, &self.options, level, &mut solution);
        }
        *lambda = lcp.impulses(&solution.z);
        memory.impulses.clone_from(lambda);
        memory.last = solution.report.clone();
        if memory.enabled {
            memory.basis = solution.basis;
            memory.shape.0.clone_from(&problem.laws);
            memory.shape.1.clear();
            memory.shape.1.extend(problem.contacts.iter().map(|c| c.normal));
            memory.shape.2 = facets;
        } else {
            memory.lcp = None;
        }
        let mut notes = Vec::new();
        if matches!(problem.friction, FrictionModel::Cone) {
            notes.push(format!("friction cone approximated by a {}-facet pyramid", self.facets));
        }
        if solution.certified {
            notes.push(format!(
                "LCP residual {:.2e} above Lemke's {:.0e} relative to ‖q‖, accepted on the problem's residual",
                solution.report.residual, self.options.tolerance
            ));
        } else if !solution.within_tolerance {
            // Every path ended on a basis whose values are some 1e-10 below zero (a highly
            // degenerate vertex, as of a pile of boxes on redundant corners): the best answer is
            // handed on for the caller to certify by the problem's residuals.
            notes.push(format!(
                "LCP residual {:.2e} above Lemke's {:.0e} relative to ‖q‖",
                solution.report.residual, self.options.tolerance
            ));
        }
        let note = (!notes.is_empty()).then(|| notes.join("; "));
        Ok(SolveInfo { iterations: solution.report.pivots, note, residuals: None })
    }
}

/// The exact residual (m/s) of the impulses of LCP answer z on the problem the LCP poses:
/// `problem` itself, a friction cone replaced by the pyramid of `facets` directions.
fn pyramid_residual(problem: &ConstraintProblem, facets: usize, lcp: &SparseLcp, z: &DVector<f64>) -> f64 {
    let lambda = lcp.impulses(z);
    let mut w = DVector::zeros(problem.rows());
    problem.velocities(&lambda, &mut w);
    let friction = match problem.friction {
        FrictionModel::Cone => FrictionModel::Pyramid { facets },
        pyramid => pyramid,
    };
    let r = residuals_with_friction(problem, friction, &lambda, w.as_slice()).exact();
    if r.is_nan() {
        f64::INFINITY
    } else {
        r
    }
}

/// An answer whose exact residual on the problem the LCP poses misses `level` (m/s), the
/// tolerance the caller certifies against, though its LCP residual is within Lemke's
/// tolerance relative to max(1, ‖q‖∞): the final basis of a degenerate vertex leaves some
/// basic w a few 1e-9 below zero (friction facets of a contact whose slip the basis does not
/// quite match), within the LCP tolerance but counted, in the dissipation gap, per unit of a
/// small friction bound. A path from the answer's basis ([`solve_from_basis`]: z0 lifts the
/// slightly negative values along the covering vector B·1 and the path ends where it leaves
/// again, within a few pivots) is run with the LCP tolerance a thousand times finer, so that its
/// final basis is repaired (principal pivots, restarts) until its natural residual is within
/// that finer tolerance or its residual on the problem within `level`. Its answer replaces the
/// first only when its natural residual is within Lemke's tolerance and its residual on the
/// problem is lower.
fn refine_to_level(
    problem: &ConstraintProblem,
    facets: usize,
    lcp: &SparseLcp,
    options: &LemkeOptions,
    level: f64,
    solution: &mut Solution,
) {
    let Some(start) = solution.basis.clone() else { return };
    let before = pyramid_residual(problem, facets, lcp, &solution.z);
    if before <= level {
        return;
    }
    let (_, tolerance) = path_options(options, &lcp.q);
    let columns = || match &lcp.m {
        Some(m) => Columns { m: Matrix::Formed(m), d: Vec::new() },
        None => Columns { m: Matrix::Lazy(lcp), d: Vec::new() },
    };
    // The refinement spends what is left of the solve's budget of operations.
    let max_operations = match options.max_operations {
        budget if budget > 0.0 => budget - solution.report.operations,
        _ => 0.0,
    };
    if options.max_operations > 0.0 && max_operations <= 0.0 {
        return;
    }
    let finer = LemkeOptions { tolerance: 1e-3 * options.tolerance, max_operations, ..*options };
    let mut certify = |z: &DVector<f64>| {
        residual_of_columns(&columns(), &lcp.q, z.as_slice()) <= tolerance
            && pyramid_residual(problem, facets, lcp, z) <= level
    };
    match solve_from_basis(&mut columns(), &lcp.q, &finer, &start, &mut certify, true) {
        Ok(candidate) => {
            let after = pyramid_residual(problem, facets, lcp, &candidate.z);
            if candidate.report.residual <= tolerance && after < before {
                let report = LemkeReport {
                    refined_to_level: true,
                    ..solution.report.clone().merged(candidate.report)
                };
                *solution = Solution { report, within_tolerance: true, certified: false, ..candidate };
            } else {
                solution.report.add_work(&candidate.report);
            }
        }
        Err(done) => solution.report.add_work(&done),
    }
}
