//! A chain of solvers with a fallback policy: each runs in turn until one returns impulses whose
//! certifying residual is within the chain's tolerance; every failure and its reason is kept.

use super::{residuals, ConstraintSolver, Residuals, SolverError};
use crate::constraints::ConstraintProblem;
use crate::math::all_finite;
use nalgebra::DVector;

/// A solver that was tried and did not deliver, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Fallback {
    /// Solver name.
    pub solver: String,
    /// The error or the residual miss.
    pub reason: String,
}

/// The outcome of a chain solve.
#[derive(Clone, Debug, PartialEq)]
pub struct ChainReport {
    /// The solver whose answer was taken.
    pub solver: &'static str,
    /// Its iterations or pivots.
    pub iterations: usize,
    /// Residuals of the answer.
    pub residuals: Residuals,
    /// Solvers tried before it.
    pub fallbacks: Vec<Fallback>,
    /// Whether the chain passed over its first solver without trying it
    /// ([`SolverChain::skip_after_miss`]).
    pub skipped_first: bool,
    /// The solver's remark, if any.
    pub note: Option<String>,
}

/// Solvers tried in order, with the residual tolerance (m/s) an answer must meet.
pub struct SolverChain {
    /// The solvers, first choice first.
    pub solvers: Vec<Box<dyn ConstraintSolver>>,
    /// Accepted certifying residual (m/s).
    pub tolerance: f64,
    /// Take the last solver's answer even above the tolerance (recorded as a fallback reason)
    /// rather than failing the step.
    pub accept_last: bool,
    /// A solver after one whose answer missed the tolerance starts from that answer instead of
    /// the warm start; a solver that failed hands on nothing. Off by default: on, clarabel's
    /// answers after a PGS miss change, and with them later warm starts (docs/solvers.md).
    pub hand_on: bool,
    /// Calls for which the first solver of a chain of several is passed over after it missed,
    /// when it is one that certifies only part of the problems it is given
    /// ([`ConstraintSolver::certifies_part`]: `newton-exact` answers resting contacts, not
    /// sliding ones), 0: always tried. Its misses come in runs (a box slides for many steps);
    /// passing over it saves its cost on each. After this many calls it is tried again.
    pub skip_after_miss: usize,
    /// Calls left for which the first solver is passed over.
    skipping: usize,
    w: DVector<f64>,
    candidate: DVector<f64>,
}

impl SolverChain {
    /// A chain of `solvers` with residual tolerance `tolerance` (m/s).
    pub fn new(solvers: Vec<Box<dyn ConstraintSolver>>, tolerance: f64) -> Self {
        Self {
            solvers,
            tolerance,
            accept_last: false,
            hand_on: false,
            skip_after_miss: 0,
            skipping: 0,
            w: DVector::zeros(0),
            candidate: DVector::zeros(0),
        }
    }

    /// The certifying residual of `residuals` for the solver named `solver` (the exact
    /// formulation's if no solver has that name).
    pub fn certify(&self, solver: &str, residuals: &Residuals) -> f64 {
        self.solvers.iter().find(|s| s.name() == solver).map_or(residuals.exact(), |s| s.certify(residuals))
    }

    /// Solves `problem`; `lambda` holds the warm start on entry and the answer on success.
    pub fn solve(
        &mut self,
        problem: &ConstraintProblem,
        lambda: &mut DVector<f64>,
    ) -> Result<ChainReport, SolverError> {
        let mut fallbacks = Vec::new();
        let count = self.solvers.len();
        if self.candidate.len() == lambda.len() {
            self.candidate.copy_from(lambda);
        } else {
            self.candidate.clone_from(lambda);
        }
        let mut hand = false;
        let skip_first = self.skipping > 0 && count > 1;
        self.skipping = self.skipping.saturating_sub(1);
        for (k, solver) in self.solvers.iter_mut().enumerate().skip(usize::from(skip_first)) {
            if hand && all_finite(self.candidate.as_slice()) {
                // The last solver's answer missed the tolerance: the next starts from it.
            } else if self.candidate.len() == lambda.len() {
                self.candidate.copy_from(lambda);
            } else {
                self.candidate.clone_from(lambda);
            }
            solver.set_certified_tolerance(self.tolerance);
            match solver.solve(problem, &mut self.candidate) {
                Ok(mut info) => {
                    let r = match info.residuals.take() {
                        Some(r) => r,
                        None => residuals(problem, &self.candidate, &mut self.w),
                    };
                    let certified = solver.certify(&r);
                    let last = k + 1 == count;
                    if certified <= self.tolerance || (last && self.accept_last) {
                        if certified > self.tolerance {
                            fallbacks.push(Fallback {
                                solver: solver.name().to_string(),
                                reason: format!("accepted above tolerance: residual {certified:.3e}"),
                            });
                        }
                        if lambda.len() == self.candidate.len() {
                            lambda.copy_from(&self.candidate);
                        } else {
                            lambda.clone_from(&self.candidate);
                        }
                        return Ok(ChainReport {
                            solver: solver.name(),
                            iterations: info.iterations,
                            residuals: r,
                            fallbacks,
                            skipped_first: skip_first,
                            note: info.note,
                        });
                    }
                    fallbacks.push(Fallback {
                        solver: solver.name().to_string(),
                        reason: format!("residual {certified:.3e} above tolerance {:.1e}", self.tolerance),
                    });
                    hand = self.hand_on;
                    if k == 0 && solver.certifies_part() {
                        self.skipping = self.skip_after_miss;
                    }
                }
                Err(e) => {
                    fallbacks.push(Fallback { solver: solver.name().to_string(), reason: e.to_string() });
                    hand = false;
                    if k == 0 && solver.certifies_part() {
                        self.skipping = self.skip_after_miss;
                    }
                }
            }
        }
        Err(SolverError::AllFailed(
            fallbacks.iter().map(|f| format!("{}: {}", f.solver, f.reason)).collect::<Vec<_>>().join("; "),
        ))
    }
}
