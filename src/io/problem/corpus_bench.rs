//! `gelenk corpus bench`: every problem of a corpus solved by each solver from zero impulses,
//! and a qpbenchmark-style table per family: success rates at certified residuals 1e-3, 1e-6
//! and 1e-9 m/s, the shifted geometric mean of solve time, and the worst residual.
//!
//! A solver's residual is the one that certifies its formulation ([`ConstraintSolver::certify`]):
//! the convex (Anitescu) problem's for clarabel and newton, the exact complementarity problem's
//! for PGS and Lemke (Lemke's on a cone measured on the pyramid it solves). The shifted
//! geometric mean `exp(mean(ln(t + s))) − s` uses the shift s = [`TIME_SHIFT`]; a run that does
//! not reach 1e-3 m/s (or fails, or is skipped) counts as the time limit, as qpbenchmark does.

use super::{run_configured_solver, CorpusSolver, SolveStatus};
use crate::constraints::ConstraintProblem;
use crate::solvers::{residuals, ConstraintSolver, NewtonSolver, PgsSolver};
use nalgebra::DVector;
use std::time::Instant;

/// Shift (s) of the shifted geometric mean of times.
pub const TIME_SHIFT: f64 = 1e-3;
/// The residual levels (m/s) of the success rates.
pub const LEVELS: [f64; 3] = [1e-3, 1e-6, 1e-9];

/// A solver of the bench.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BenchSolver {
    /// clarabel (as [`CorpusSolver::Clarabel`]).
    Clarabel,
    /// Projected Gauss–Seidel with [`BenchOptions::pgs_sweeps`] sweeps from zero.
    Pgs,
    /// [`NewtonSolver`] with default options, asked for 1e-9 m/s.
    Newton,
    /// Lemke's method (as [`CorpusSolver::Lemke`], told the certified tolerance 1e-9 m/s), on
    /// problems up to [`BenchOptions::lemke_max_rows`] rows.
    Lemke,
}

impl BenchSolver {
    /// Every solver.
    pub const ALL: [BenchSolver; 4] =
        [BenchSolver::Clarabel, BenchSolver::Pgs, BenchSolver::Newton, BenchSolver::Lemke];

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            BenchSolver::Clarabel => "clarabel",
            BenchSolver::Pgs => "pgs",
            BenchSolver::Newton => "newton",
            BenchSolver::Lemke => "lemke",
        }
    }
}

impl std::str::FromStr for BenchSolver {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        BenchSolver::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("unknown solver `{s}` (clarabel, pgs, newton, lemke)"))
    }
}

/// Bench settings.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchOptions {
    /// PGS sweeps.
    pub pgs_sweeps: usize,
    /// Lemke's method is skipped (counted as a failure) above this many rows.
    pub lemke_max_rows: usize,
    /// Time (s) a run that does not reach 1e-3 m/s counts as.
    pub time_limit: f64,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self { pgs_sweeps: 2000, lemke_max_rows: 2000, time_limit: 10.0 }
    }
}

/// One solver on one problem.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchRun {
    /// Problem id.
    pub id: String,
    /// Family.
    pub family: String,
    /// Rows.
    pub rows: usize,
    /// Solver.
    pub solver: BenchSolver,
    /// Certified residual (m/s); `None` when it failed or was skipped.
    pub residual: Option<f64>,
    /// Solve time (s).
    pub time: f64,
    /// Why there is no residual.
    pub note: Option<String>,
}

/// Solves `problem` with `solver` and records the run.
pub fn bench_run(
    id: &str,
    family: &str,
    problem: &ConstraintProblem,
    solver: BenchSolver,
    options: &BenchOptions,
) -> BenchRun {
    let mut run = BenchRun {
        id: id.to_string(),
        family: family.to_string(),
        rows: problem.rows(),
        solver,
        residual: None,
        time: 0.0,
        note: None,
    };
    let corpus = match solver {
        BenchSolver::Clarabel => Some(CorpusSolver::Clarabel),
        BenchSolver::Lemke if problem.rows() > options.lemke_max_rows => {
            run.note = Some(format!("skipped: more than {} rows", options.lemke_max_rows));
            return run;
        }
        BenchSolver::Lemke => Some(CorpusSolver::Lemke),
        BenchSolver::Pgs | BenchSolver::Newton => None,
    };
    if let Some(kind) = corpus {
        let mut configured = kind.solver();
        if kind == CorpusSolver::Lemke {
            // Told the finest level of the table, as the Newton solver is: an answer within
            // Lemke's LCP tolerance whose residual misses it is polished.
            configured.set_certified_tolerance(LEVELS[2]);
        }
        let (record, elapsed) = run_configured_solver(kind, configured, problem);
        run.time = elapsed.as_secs_f64();
        match record.status {
            SolveStatus::Failed => run.note = record.message,
            _ => run.residual = record.certified,
        }
        return run;
    }
    let mut chosen: Box<dyn ConstraintSolver> = match solver {
        BenchSolver::Pgs => Box::new(PgsSolver::new(options.pgs_sweeps, 1e-13, 1.0, false)),
        _ => {
            let mut newton = NewtonSolver::default();
            newton.set_certified_tolerance(1e-9);
            Box::new(newton)
        }
    };
    let mut lambda = DVector::zeros(problem.rows());
    let start = Instant::now();
    let result = chosen.solve(problem, &mut lambda);
    run.time = start.elapsed().as_secs_f64();
    match result {
        Ok(_) => {
            let mut w = DVector::zeros(problem.rows());
            run.residual = Some(chosen.certify(&residuals(problem, &lambda, &mut w)));
        }
        Err(e) => run.note = Some(e.to_string()),
    }
    run
}

/// One line of the table: a solver on a family (or on `all`).
#[derive(Clone, Debug, PartialEq)]
pub struct BenchRow {
    /// Family, or `all`.
    pub family: String,
    /// Solver.
    pub solver: BenchSolver,
    /// Problems.
    pub problems: usize,
    /// Fraction of problems solved at each of [`LEVELS`].
    pub success: [f64; 3],
    /// Shifted geometric mean of time (s).
    pub time_sgm: f64,
    /// Worst certified residual over the runs that returned one (m/s); `None` if none did.
    pub worst: Option<f64>,
    /// Runs without a residual (failed or skipped).
    pub failed: usize,
}

/// The table of `runs`: per family then `all`, per solver in the order given.
pub fn bench_table(runs: &[BenchRun], solvers: &[BenchSolver], time_limit: f64) -> Vec<BenchRow> {
    let mut families: Vec<&str> = Vec::new();
    for r in runs {
        if !families.contains(&r.family.as_str()) {
            families.push(&r.family);
        }
    }
    families.push("all");
    let mut rows = Vec::new();
    for family in families {
        for &solver in solvers {
            let mine: Vec<&BenchRun> = runs
                .iter()
                .filter(|r| r.solver == solver && (family == "all" || r.family == family))
                .collect();
            if mine.is_empty() {
                continue;
            }
            let count = mine.len() as f64;
            let success = LEVELS.map(|level| {
                mine.iter().filter(|r| r.residual.is_some_and(|x| x <= level)).count() as f64 / count
            });
            let log_sum: f64 = mine
                .iter()
                .map(|r| {
                    let t = if r.residual.is_some_and(|x| x <= LEVELS[0]) { r.time } else { time_limit };
                    (t + TIME_SHIFT).ln()
                })
                .sum();
            rows.push(BenchRow {
                family: family.to_string(),
                solver,
                problems: mine.len(),
                success,
                time_sgm: (log_sum / count).exp() - TIME_SHIFT,
                worst: mine.iter().filter_map(|r| r.residual).reduce(f64::max),
                failed: mine.iter().filter(|r| r.residual.is_none()).count(),
            });
        }
    }
    rows
}

/// The table as aligned text.
pub fn bench_text(rows: &[BenchRow]) -> String {
    let mut s = format!(
        "{:<14} {:<9} {:>8} {:>8} {:>8} {:>8} {:>12} {:>10} {:>7}\n",
        "family", "solver", "problems", "≤1e-3", "≤1e-6", "≤1e-9", "time sgm", "worst", "failed"
    );
    for r in rows {
        s.push_str(&format!(
            "{:<14} {:<9} {:>8} {:>7.1}% {:>7.1}% {:>7.1}% {:>10.3} ms {:>10} {:>7}\n",
            r.family,
            r.solver.name(),
            r.problems,
            100.0 * r.success[0],
            100.0 * r.success[1],
            100.0 * r.success[2],
            1e3 * r.time_sgm,
            r.worst.map_or("-".to_string(), |w| format!("{w:.1e}")),
            r.failed
        ));
    }
    s
}

/// The table as CSV (times in seconds, rates as fractions).
pub fn bench_csv(rows: &[BenchRow]) -> String {
    let mut s = String::from(
        "family,solver,problems,success_1e-3,success_1e-6,success_1e-9,time_sgm_s,worst_residual,failed\n",
    );
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{},{},{},{:e},{},{}\n",
            r.family,
            r.solver.name(),
            r.problems,
            r.success[0],
            r.success[1],
            r.success[2],
            r.time_sgm,
            r.worst.map_or(String::new(), |w| format!("{w:e}")),
            r.failed
        ));
    }
    s
}

/// One line per run as CSV: id, family, rows, solver, certified residual (m/s, empty when
/// the run failed or was skipped), time (s), note (why there is no residual; quoted).
pub fn runs_csv(runs: &[BenchRun]) -> String {
    let mut s = String::from("id,family,rows,solver,residual,time_s,note\n");
    for r in runs {
        s.push_str(&format!(
            "{},{},{},{},{},{:e},\"{}\"\n",
            r.id,
            r.family,
            r.rows,
            r.solver.name(),
            r.residual.map_or(String::new(), |x| format!("{x:e}")),
            r.time,
            r.note.as_deref().unwrap_or("").replace('"', "\"\"")
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(family: &str, solver: BenchSolver, residual: Option<f64>, time: f64) -> BenchRun {
        BenchRun { id: "p".into(), family: family.into(), rows: 3, solver, residual, time, note: None }
    }

    #[test]
    fn the_table_counts_levels_and_charges_failures_the_time_limit() {
        let runs = vec![
            run("a", BenchSolver::Pgs, Some(1e-4), 0.001),
            run("a", BenchSolver::Pgs, Some(1e-7), 0.001),
            run("b", BenchSolver::Pgs, None, 0.5),
            run("b", BenchSolver::Pgs, Some(1e-2), 0.001),
        ];
        let table = bench_table(&runs, &[BenchSolver::Pgs], 1.0);
        assert_eq!(table.iter().map(|r| r.family.as_str()).collect::<Vec<_>>(), ["a", "b", "all"]);
        assert_eq!(table[0].success, [1.0, 0.5, 0.0]);
        assert_eq!(table[1].success, [0.0, 0.0, 0.0]);
        assert_eq!(table[1].failed, 1);
        assert_eq!(table[1].worst, Some(1e-2));
        // Family b: both runs count 1 s: the mean is 1 s.
        assert!((table[1].time_sgm - 1.0).abs() < 1e-12);
        assert!((table[0].time_sgm - 0.001).abs() < 1e-12);
        assert_eq!(table[2].problems, 4);
        assert!(bench_csv(&table).lines().count() == 4 && bench_text(&table).contains("all"));
        let lines: Vec<String> = runs_csv(&runs).lines().map(String::from).collect();
        assert_eq!(lines.len(), 5);
        assert_eq!(lines[1], "p,a,3,pgs,1e-4,1e-3,\"\"");
        assert_eq!(lines[3], "p,b,3,pgs,,5e-1,\"\"");
    }
}
