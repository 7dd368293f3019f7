//! Stage 6 island by island: the step's problem split into its islands
//! ([`IslandPartition`]: rows joined through the multibodies they touch), each island written as
//! a problem of its own and solved by its own solver chain, the impulses gathered back.
//!
//! Island k (islands numbered in the order of their first rows) is always solved by chain k:
//! a solver's memory of its last solve (PGS's subspace timing, Newton's symbolic analysis) is
//! that of island k's last solve whichever thread ran it, so the step's result is the same bit
//! for bit on any number of threads. With the `parallel` feature, [`IslandSolves::set_threads`]
//! above 1 solves the islands on a rayon pool of that many threads when the step has more than
//! one island and at least [`PARALLEL_MIN_ROWS`] rows (smaller steps are cheaper on one thread
//! than the hand-over).

use crate::constraints::{ConstraintProblem, IslandPartition};
use crate::solvers::{ChainReport, QpResiduals, Residuals, SolverChain, SolverError};
use crate::world::WorldOptions;
use nalgebra::DVector;

/// Fewest rows in a step (all islands together) for its islands to be solved on several
/// threads.
#[cfg_attr(not(feature = "parallel"), allow(dead_code))]
pub const PARALLEL_MIN_ROWS: usize = 64;

/// One island's chain, problem and impulses (kept between steps).
struct Slot {
    chain: SolverChain,
    problem: ConstraintProblem,
    lambda: DVector<f64>,
    outcome: Option<Result<ChainReport, SolverError>>,
}

impl Slot {
    fn solve(&mut self) {
        self.outcome = Some(self.chain.solve(&self.problem, &mut self.lambda));
    }
}

/// The islands of the step's problem and their solves.
pub(crate) struct IslandSolves {
    partition: IslandPartition,
    slots: Vec<Slot>,
    /// The options the chains are built from.
    options: WorldOptions,
    threads: usize,
    #[cfg(feature = "parallel")]
    pool: Option<rayon::ThreadPool>,
    /// Islands of the last solve, and the rows of the largest.
    pub(crate) count: usize,
    pub(crate) largest: usize,
}

impl IslandSolves {
    /// No island yet; chains are built from `options` as islands appear.
    pub(crate) fn new(options: &WorldOptions) -> Self {
        Self {
            partition: IslandPartition::default(),
            slots: Vec::new(),
            options: options.clone(),
            threads: 1,
            #[cfg(feature = "parallel")]
            pool: None,
            count: 0,
            largest: 0,
        }
    }

    /// Every island's chain becomes that of `options`.
    pub(crate) fn set_chain(&mut self, options: &WorldOptions) {
        self.options = options.clone();
        for slot in &mut self.slots {
            slot.chain = options.chain();
        }
    }

    /// Threads the islands are solved on (≥ 1; above 1 only with the `parallel` feature).
    pub(crate) fn set_threads(&mut self, threads: usize) -> Result<(), String> {
        if threads == 0 {
            return Err("a thread count must be at least 1".into());
        }
        #[cfg(feature = "parallel")]
        {
            self.pool = if threads > 1 {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
                Some(pool.map_err(|e| format!("cannot start {threads} threads: {e}"))?)
            } else {
                None
            };
        }
        #[cfg(not(feature = "parallel"))]
        if threads > 1 {
            return Err(format!("{threads} threads need gelenk built with the `parallel` feature"));
        }
        self.threads = threads;
        Ok(())
    }

    /// The islands of the last solve's problem.
    pub(crate) fn partition(&self) -> &IslandPartition {
        &self.partition
    }

    /// Threads the islands are solved on.
    pub(crate) fn threads(&self) -> usize {
        self.threads
    }

    /// Solves `problem` island by island; `lambda` holds the warm start on entry and the
    /// impulses on return. The report is that of the island whose certified residual is the
    /// largest (solver, residuals), with the most iterations of any island and every island's
    /// fallbacks; the first island (in order) whose chain failed fails the solve.
    pub(crate) fn solve(
        &mut self,
        problem: &ConstraintProblem,
        lambda: &mut DVector<f64>,
        template: &SolverChain,
    ) -> Result<ChainReport, SolverError> {
        let count = self.partition.split(problem);
        self.count = count;
        self.largest = (0..count).map(|k| self.partition.rows(k).len()).max().unwrap_or(0);
        while self.slots.len() < count.max(1) {
            self.slots.push(Slot {
                chain: self.options.chain(),
                problem: ConstraintProblem::default(),
                lambda: DVector::zeros(0),
                outcome: None,
            });
        }
        if count <= 1 {
            // One island is the whole problem.
            return self.slots[0].chain.solve(problem, lambda);
        }
        for (k, slot) in self.slots[..count].iter_mut().enumerate() {
            let rows = self.partition.rows(k);
            if slot.lambda.len() != rows.len() {
                slot.lambda = DVector::zeros(rows.len());
            }
            for (l, &i) in slot.lambda.iter_mut().zip(rows) {
                *l = lambda[i];
            }
            self.partition.extract(problem, k, &mut slot.problem);
        }
        self.run(count, problem.rows());
        let mut merged: Option<(f64, ChainReport)> = None;
        for (k, slot) in self.slots[..count].iter_mut().enumerate() {
            let report = slot.outcome.take().expect("every island was solved")?;
            for (&l, &i) in slot.lambda.iter().zip(self.partition.rows(k)) {
                lambda[i] = l;
            }
            let certified = template.certify(report.solver, &report.residuals);
            merged = Some(match merged {
                None => (certified, report),
                Some((worst, mut m)) => {
                    m.iterations = m.iterations.max(report.iterations);
                    m.fallbacks.extend(report.fallbacks);
                    m.note = m.note.or(report.note);
                    if certified > worst {
                        m.solver = report.solver;
                        m.residuals = worst_of(report.residuals, m.residuals);
                        (certified, m)
                    } else {
                        m.residuals = worst_of(m.residuals, report.residuals);
                        (worst, m)
                    }
                }
            });
        }
        Ok(merged.expect("two islands or more").1)
    }

    /// Solves the first `count` slots' problems: on the pool when there is one and the step is
    /// big enough, else in order on this thread.
    fn run(&mut self, count: usize, rows: usize) {
        let slots = &mut self.slots[..count];
        #[cfg(feature = "parallel")]
        if let Some(pool) = self.pool.as_ref().filter(|_| rows >= PARALLEL_MIN_ROWS) {
            use rayon::prelude::*;
            pool.install(|| slots.par_iter_mut().for_each(Slot::solve));
            return;
        }
        let _ = rows;
        slots.iter_mut().for_each(Slot::solve);
    }
}

/// `kept` with the informational residuals of `other` (complementarity products, QP
/// residuals) folded in where larger; the certifying ones are `kept`'s, the worst island's.
fn worst_of(kept: Residuals, other: Residuals) -> Residuals {
    let qp = match (kept.qp, other.qp) {
        (Some(a), Some(b)) => Some(QpResiduals {
            primal: a.primal.max(b.primal),
            dual: a.dual.max(b.dual),
            gap: a.gap.max(b.gap),
        }),
        _ => None,
    };
    Residuals { complementarity: kept.complementarity.max(other.complementarity), qp, ..kept }
}
