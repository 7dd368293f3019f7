//! A problem file solved again and judged against the `meta.json` beside it ([`resolve_problem`],
//! `gelenk solve-problem`): a corpus problem is a regression test, and an answer worse than the
//! status meta.json records is a [`Regression`].

use super::META_FILE;
use super::{read_meta, read_problem, run_solver, CorpusSolver, ProblemFileError, SolveStatus, SolverRecord};
use crate::constraints::ConstraintProblem;
use std::path::Path;
use std::time::Duration;
use thiserror::Error;

/// One solver's answer to a problem file, with what its `meta.json` (when there is one) says
/// the answer must meet.
#[derive(Clone, Debug)]
pub struct Resolved {
    /// The problem read.
    pub problem: ConstraintProblem,
    /// The solver.
    pub solver: CorpusSolver,
    /// Its answer.
    pub record: SolverRecord,
    /// The solver's wall-clock time.
    pub elapsed: Duration,
    /// The certifying-residual tolerance (m/s): meta.json's for this solver, else
    /// [`CorpusSolver::tolerance`].
    pub tolerance: f64,
    /// The status meta.json records for this solver.
    pub expected: Option<SolveStatus>,
    /// Largest `|w − w_ref|` (m/s) when meta.json says this solver's row velocities must equal
    /// the reference solver's (`w_unique_for`).
    pub w_error: Option<f64>,
}

/// Why a re-solved problem fails its regression test.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum Regression {
    /// The solver returned no impulses.
    #[error("{solver} failed: {message}")]
    Failed {
        /// The solver's name.
        solver: &'static str,
        /// Its error.
        message: String,
    },
    /// The solver's status is worse than meta.json records.
    #[error(
        "{solver} is {status} where meta.json records {expected} (certified {certified:.3e} m/s, tolerance {tolerance:.0e})"
    )]
    Worse {
        /// The solver's name.
        solver: &'static str,
        /// Its status now.
        status: SolveStatus,
        /// The status meta.json records.
        expected: SolveStatus,
        /// Its certifying residual (m/s; NaN if none).
        certified: f64,
        /// The tolerance it was held to (m/s).
        tolerance: f64,
    },
}

/// Reads the problem at `path` (a `problem.json` or its directory) and the `meta.json` beside it
/// when there is one, and solves the problem with `solver` from zero impulses.
pub fn resolve_problem(path: &Path, solver: CorpusSolver) -> Result<Resolved, ProblemFileError> {
    let problem = read_problem(path)?;
    let meta_path = if path.is_dir() { path.join(META_FILE) } else { path.with_file_name(META_FILE) };
    let meta = if meta_path.exists() { Some(read_meta(&meta_path)?) } else { None };
    let (record, elapsed) = run_solver(solver, &problem);
    let tolerance =
        meta.as_ref().and_then(|m| m.tolerances.get(solver.name()).copied()).unwrap_or(solver.tolerance());
    let w_error = meta.as_ref().and_then(|m| {
        let reference = &m.solutions.get(&m.reference)?.w;
        let unique = m.w_unique_for.iter().any(|s| s == solver.name());
        (unique && reference.len() == record.w.len())
            .then(|| record.w.iter().zip(reference).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max))
    });
    let expected = meta.as_ref().and_then(|m| m.solutions.get(solver.name())).map(|r| r.status);
    Ok(Resolved { problem, solver, record, elapsed, tolerance, expected, w_error })
}

impl Resolved {
    /// The regression test: the solver must return impulses, with a status no worse than the one
    /// meta.json records (solved < inaccurate < failed). The row-velocity error is reported, not
    /// judged here.
    pub fn verdict(&self) -> Result<(), Regression> {
        let solver = self.solver.name();
        if self.record.status == SolveStatus::Failed {
            return Err(Regression::Failed {
                solver,
                message: self.record.message.clone().unwrap_or_else(|| "no solution".to_string()),
            });
        }
        match self.expected {
            Some(expected) if self.record.status > expected => Err(Regression::Worse {
                solver,
                status: self.record.status,
                expected,
                certified: self.record.certified.unwrap_or(f64::NAN),
                tolerance: self.tolerance,
            }),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn resolved(status: SolveStatus, expected: Option<SolveStatus>) -> Resolved {
        Resolved {
            problem: ConstraintProblem::default(),
            solver: CorpusSolver::Clarabel,
            record: SolverRecord {
                status,
                message: (status == SolveStatus::Failed).then(|| "no convergence".to_string()),
                iterations: 3,
                certified: (status != SolveStatus::Failed).then_some(2e-6),
                objective: None,
                residuals: None,
                lambda: Vec::new(),
                w: Vec::new(),
            },
            elapsed: Duration::ZERO,
            tolerance: 1e-6,
            expected,
            w_error: None,
        }
    }

    #[test]
    fn a_status_worse_than_meta_json_records_is_a_regression() {
        use SolveStatus::{Failed, Inaccurate, Solved};
        assert_eq!(resolved(Solved, Some(Solved)).verdict(), Ok(()));
        assert_eq!(resolved(Solved, Some(Inaccurate)).verdict(), Ok(()));
        assert_eq!(resolved(Inaccurate, Some(Inaccurate)).verdict(), Ok(()));
        assert_eq!(resolved(Inaccurate, None).verdict(), Ok(()));
        let worse = resolved(Inaccurate, Some(Solved)).verdict().unwrap_err();
        assert_eq!(
            worse.to_string(),
            "clarabel is inaccurate where meta.json records solved (certified 2.000e-6 m/s, tolerance 1e-6)"
        );
        // A failure is a regression whatever meta.json says.
        for expected in [None, Some(Failed)] {
            let failed = resolved(Failed, expected).verdict().unwrap_err();
            assert_eq!(failed.to_string(), "clarabel failed: no convergence");
        }
    }
}
