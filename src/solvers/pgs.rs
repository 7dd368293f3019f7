//! Projected Gauss–Seidel with successive over-relaxation (ODE's QuickStep family; Erleben,
//! "Velocity-based shock propagation", 2007): sweep the rows in order, solve each for its own
//! impulse with the others fixed, project onto the row's law; friction pairs are updated
//! together and projected onto the cone (or pyramid) of the current normal impulse. Warm-started
//! from the impulses passed in (the last step's, matched by the caller).

use super::friction::{friction_block_step, project_friction, pyramid_block_step};
use super::residuals::residuals_at_velocities;
use super::subspace::{subspace_step, SubspaceOutcome, SubspaceWorkspace, MAX_SUBSPACE};
use super::{check_problem, ConstraintSolver, SolveInfo, SolverError};
use crate::constraints::{ConstraintProblem, FrictionModel, RowLaw};
use nalgebra::DVector;

/// Default sweeps between subspace steps: long enough that problems PGS settles quickly never
/// pay for one.
const SUBSPACE_PERIOD: usize = 8;

/// The first subspace step comes once the sweeps have cost 1/this of its estimated cost.
const SUBSPACE_COST_SHARE: usize = 4;

/// Longest wait (solves) between exact solves of a λ already within the goal. A subspace step
/// that finds λ within the residual goal accepts it as it is, and the next solve's sweeps start
/// from that error: a resting box stack's sweeps would move λ by 1–3e-8 every step, over their
/// 1e-9 tolerance, and sustain a wobble of 3e-7 m/s (3.4 sweeps per step for ever). Solving
/// such a λ exactly ends the sweeps there (one per step from then on), but not where the
/// sweeps go on for another reason (a ragdoll lying still, its joint-friction rows at their
/// bounds): an exact solve is tried, tried again as soon as the next solve settles in one
/// sweep, and after each failure waited for twice as long, up to this, so that the exact solves
/// that fail cost little.
const EXACT_WAIT_MAX: usize = 64;

/// Sweeps before the first subspace step when the previous solve was settled by one: the
/// active set then usually carries over from the warm start, and the sweeps before the step
/// only correct it where it changed.
const SUBSPACE_EARLY: usize = 3;

/// Share of a chain's certified tolerance that PGS aims for ([`PgsSolver::residual_goal`]): a
/// sliding or creeping ragdoll's warm-started solves are within ~1e-7 m/s after a few sweeps,
/// well within the 1e-6 a chain certifies, and a subspace step on to 1e-10 and beyond (two
/// reduced factorizations of ~48 unknowns) costs more than the rest of the step. A tenth
/// leaves the next warm start good enough: at 0.3 the ragdoll of `models/ragdoll_fall.toml`
/// misses the tolerance ten times as often.
pub const CERTIFIED_SHARE: f64 = 0.1;

/// Projected Gauss–Seidel.
#[derive(Clone, Debug)]
pub struct PgsSolver {
    /// Maximum number of sweeps.
    pub iterations: usize,
    /// Stop when no impulse changes by more than this, in velocity units (m/s).
    pub tolerance: f64,
    /// Over-relaxation factor ω ∈ (0, 2); 1 = plain Gauss–Seidel.
    pub omega: f64,
    /// Start from the impulses passed in (else from zero).
    pub warm_start: bool,
    /// Accelerate the sweeps as nonsmooth nonlinear conjugate gradients (NNCG: Silcowitz,
    /// Niebe and Erleben, "A nonsmooth nonlinear conjugate gradient method for interactive
    /// contact force problems", 2010): the change of one sweep is taken as the negative
    /// gradient, and a Fletcher–Reeves multiple of the previous direction is added, with a
    /// restart when the change grows. Long chains, piles and high mass ratios, where plain
    /// sweeps stall, converge in a fraction of the sweeps; each sweep costs a little more.
    pub accelerate: bool,
    /// Subspace minimisation (Silcowitz, Niebe and Erleben, "Projected Gauss–Seidel subspace
    /// minimization method for interactive rigid body dynamics", 2010; `solvers/subspace.rs`):
    /// fix the active set the sweeps found (pressing, sticking and sliding contacts, rows at a
    /// bound), solve the remaining system — linear, plus a Newton step on each sliding
    /// direction — with a dense LU, and follow that solution as far as the active set allows;
    /// the projected result replaces the iterate only if it lowers the exact residual
    /// ([`super::Residuals::exact`]), and the sweeps go on from it. Redundant contact sets on
    /// stiff chains (a humanoid's foot), where sweeps crawl at a rate near 1, are then solved in
    /// a few sweeps. The first step comes after `subspace_period` sweeps, later if the sweeps
    /// are cheap next to it (big problems of light rows) — but after 3 when the solver's last
    /// solve was settled by a subspace step (a foot staying on the ground: the next step's active
    /// set is mostly the last one's) —, the next ones at doubling sweep counts,
    /// and one after the last sweep of an unconverged solve: problems the sweeps settle sooner
    /// never pay for it. Cone or pyramid friction, at most 128 rows.
    pub subspace: bool,
    /// Fewest sweeps before the first subspace step (≥ 1).
    pub subspace_period: usize,
    /// Exact residual (m/s) at which a subspace step ends the solve: λ as the sweeps left it if
    /// its residual is already within it, or the step's result if it gets there. `None`: the
    /// sweep tolerance `tolerance`. A [`super::SolverChain`] sets it to a tenth of the
    /// tolerance it certifies against (`CERTIFIED_SHARE`).
    pub residual_goal: Option<f64>,
    /// Scratch space reused between solves (leave it at its default).
    pub workspace: PgsWorkspace,
}

/// Scratch space of [`PgsSolver`]: the velocity change M⁻¹Jᵀλ of the velocity-space sweeps.
#[derive(Clone, Debug, Default)]
pub struct PgsWorkspace {
    dv: DVector<f64>,
    /// A_ii + R_ii per row.
    diagonal: Vec<f64>,
    /// A between the two friction rows of each contact.
    coupling: Vec<f64>,
    /// Per contact, whether its two friction rows of W have the same runs (as assembly lays
    /// them out): then their velocities and updates take one pass over Wᵀλ, not two.
    paired: Vec<bool>,
    /// NNCG: impulses before the sweep and the search direction.
    previous: Vec<f64>,
    /// Per contact, the multiplier γ of the last friction block step: the next sweep starts
    /// its Newton iteration there (a sliding contact's γ barely moves between sweeps).
    gamma: Vec<f64>,
    direction: Vec<f64>,
    subspace: SubspaceWorkspace,
    /// Whether the last solve ended on a subspace step within the tolerance: an accepted one,
    /// or one that found λ already converged.
    settled_by_subspace: bool,
    /// Row velocities at λ from the kept Wᵀλ: for a subspace step's start and the final
    /// residual certificate.
    velocities: Vec<f64>,
    /// Solves to wait before a subspace step may again solve a λ it finds within the goal
    /// exactly (see [`EXACT_WAIT_MAX`]), the wait after the next failure, and whether the last
    /// solve did so (its success is judged by the next solve).
    exact_wait: usize,
    exact_backoff: usize,
    exact_pending: bool,
}

impl Default for PgsSolver {
    fn default() -> Self {
        Self {
            iterations: 50,
            tolerance: 1e-9,
            omega: 1.0,
            warm_start: true,
            accelerate: true,
            subspace: true,
            subspace_period: SUBSPACE_PERIOD,
            residual_goal: None,
            workspace: PgsWorkspace::default(),
        }
    }
}

impl PgsSolver {
    /// PGS with `iterations` sweeps and default tolerance and relaxation.
    pub fn with_iterations(iterations: usize) -> Self {
        Self { iterations, ..Self::default() }
    }

    /// PGS with every setting given.
    pub fn new(iterations: usize, tolerance: f64, omega: f64, warm_start: bool) -> Self {
        Self {
            iterations,
            tolerance,
            omega,
            warm_start,
            accelerate: true,
            subspace: true,
            subspace_period: SUBSPACE_PERIOD,
            residual_goal: None,
            workspace: PgsWorkspace::default(),
        }
    }
}

impl ConstraintSolver for PgsSolver {
    fn name(&self) -> &'static str {
        "pgs"
    }

    fn set_certified_tolerance(&mut self, tolerance: f64) {
        self.residual_goal = Some(CERTIFIED_SHARE * tolerance);
    }

    fn solve(
        &mut self,
        problem: &ConstraintProblem,
        lambda: &mut DVector<f64>,
    ) -> Result<SolveInfo, SolverError> {
        check_problem(problem)?;
        let goal = self.residual_goal.map_or(self.tolerance, |g| g.max(self.tolerance));
        let n = problem.rows();
        if lambda.len() != n || !self.warm_start || !crate::math::all_finite(lambda.as_slice()) {
            *lambda = DVector::zeros(n);
        }
        let a = &problem.delassus;
        self.workspace.diagonal.clear();
        match problem.kept_diagonal() {
            Some(a) => self
                .workspace
                .diagonal
                .extend(a.iter().zip(problem.regularization.iter()).map(|(a, r)| a + r)),
            None => self
                .workspace
                .diagonal
                .extend((0..n).map(|i| problem.delassus_entry(i, i) + problem.regularization[i])),
        }
        self.workspace.coupling.clear();
        self.workspace.coupling.extend((0..problem.contacts.len()).map(|c| problem.friction_coupling(c)));
        self.workspace.paired.clear();
        let sp = &problem.sparsity;
        if sp.run_start.len() == n + 1 {
            let runs = |i: usize| sp.runs[sp.run_start[i]..sp.run_start[i + 1]].iter().map(|r| (r.0, r.2));
            self.workspace.paired.extend(problem.contacts.iter().map(|c| {
                let (_, t1, t2) = c.rows();
                runs(t1).eq(runs(t2))
            }));
        }
        let paired = &self.workspace.paired;
        let mut gamma = std::mem::take(&mut self.workspace.gamma);
        gamma.clear();
        gamma.resize(problem.contacts.len(), 0.0);
        let (diagonal, coupling) = (&self.workspace.diagonal, &self.workspace.coupling);
        let diag = |i: usize| diagonal[i];
        // With the block structure, sweep in the factored space (ODE's QuickStep in the metric
        // of M = Lᵀ D L): keep s = Wᵀλ with W = J L⁻¹ D^{-1/2}, so that
        // w_i = W_i · s + b_i + R_i λ_i costs a dot and an axpy over the span of row i of W
        // (the path of its bodies to the root); otherwise, or when the dense row of A is
        // shorter, use the dense row of A.
        let span_total: usize = problem.sparsity.runs.iter().map(|run| run.2).sum();
        let sparse = problem.is_matrix_free()
            || (!problem.sparsity.is_empty()
                && problem.sparsity.row_start.len() == n + 1
                && 2 * span_total < n * n);
        let nv = problem.sparsity.nv;
        if sparse {
            if self.workspace.dv.len() != nv {
                self.workspace.dv = DVector::zeros(nv);
            }
            if !problem.kept_impulse_sum(lambda.as_slice(), self.workspace.dv.as_mut_slice()) {
                self.workspace.dv.fill(0.0);
                for i in 0..n {
                    if lambda[i] != 0.0 {
                        axpy_blocks(problem, i, lambda[i], &mut self.workspace.dv);
                    }
                }
            }
        }
        // MuJoCo's warm-start guard: λ₀ only if it beats λ = 0 on the objective
        // f(λ) = ½ λᵀ(A + R)λ + bᵀλ (f(0) = 0). After an impact the last step's impulses can be
        // a hundred times the answer, and the sweeps then take their time to shed them (a
        // ragdoll's separating hand: λ_n 25 → 0 at 3 % per sweep). Only where a subspace step
        // can make up for a cold start: without one (over 128 rows) the sweeps live on their
        // warm start (with the guard there too the 20-ragdoll pile never slept within 10 s).
        if self.subspace && n <= MAX_SUBSPACE && lambda.iter().any(|x| *x != 0.0) {
            let quadratic: f64 = if sparse {
                self.workspace.dv.iter().map(|x| x * x).sum()
            } else {
                // Symmetric A: the strict upper triangle twice, and only where λ_i ≠ 0.
                (0..n)
                    .filter(|&i| lambda[i] != 0.0)
                    .map(|i| {
                        let column = a.column(i);
                        let upper = crate::math::dot(&column.as_slice()[..i], &lambda.as_slice()[..i]);
                        lambda[i] * (2.0 * upper + column[i] * lambda[i])
                    })
                    .sum()
            };
            let soft: f64 = (0..n).map(|i| problem.regularization[i] * lambda[i] * lambda[i]).sum();
            let linear = problem.bias.dot(lambda);
            // (Scaling λ₀ by its best factor instead, or whenever that factor is below 1, costs
            // more on the ragdolls, and the latter falls back on models/box_stack10.toml.)
            if 0.5 * (quadratic + soft) + linear > 0.0 {
                lambda.fill(0.0);
                self.workspace.dv.fill(0.0);
            }
        }
        // Wᵀλ, passed to the closures below (a RefCell around it cost a borrow flag's update
        // per row velocity and per update).
        let mut dv = std::mem::take(&mut self.workspace.dv);
        let w = |i: usize, lambda: &DVector<f64>, dv: &DVector<f64>| {
            if sparse {
                let dv = dv.as_slice();
                let mut jdv = 0.0;
                for (col, w) in problem.sparsity.row_spans(i) {
                    jdv += crate::math::dot(w, &dv[col..col + w.len()]);
                }
                jdv + problem.regularization[i] * lambda[i] + problem.bias[i]
            } else {
                a.column(i).dot(lambda) + problem.regularization[i] * lambda[i] + problem.bias[i]
            }
        };
        // All rows' velocities at λ from the kept s = Wᵀλ (sparse sweeps only): one pass over
        // W's spans, where forming them afresh (`ConstraintProblem::velocities`) takes two.
        let velocities_at = |lambda: &DVector<f64>, dv: &DVector<f64>, out: &mut Vec<f64>| {
            out.clear();
            out.extend((0..n).map(|i| w(i, lambda, dv)));
        };
        let moved = |i: usize, delta: f64, dv: &mut DVector<f64>| {
            if sparse && delta != 0.0 {
                axpy_blocks(problem, i, delta, dv);
            }
        };
        // A contact's two friction rows: `w` and `moved` of both in one pass over their runs
        // when these are the same (the same bits as one row after the other).
        let pair_runs = |t1: usize, t2: usize| {
            let sp = &problem.sparsity;
            let (first, second) = (sp.run_start[t1], sp.run_start[t2]);
            let count = sp.run_start[t1 + 1] - first;
            sp.runs[first..first + count]
                .iter()
                .zip(&sp.runs[second..second + count])
                .map(|(&(col, a, len), &(_, b, _))| (col, &sp.w_values[a..a + len], &sp.w_values[b..b + len]))
        };
        let w_pair = |contact: usize, t1: usize, t2: usize, lambda: &DVector<f64>, dv: &DVector<f64>| {
            if !(sparse && paired.get(contact).copied().unwrap_or(false)) {
                return (w(t1, lambda, dv), w(t2, lambda, dv));
            }
            let dv = dv.as_slice();
            let (mut j1, mut j2) = (0.0, 0.0);
            for (col, a, b) in pair_runs(t1, t2) {
                let (d1, d2) = crate::math::dot2(a, b, &dv[col..col + a.len()]);
                j1 += d1;
                j2 += d2;
            }
            let r = &problem.regularization;
            (j1 + r[t1] * lambda[t1] + problem.bias[t1], j2 + r[t2] * lambda[t2] + problem.bias[t2])
        };
        let moved_pair = |contact: usize, t1: usize, d1: f64, t2: usize, d2: f64, dv: &mut DVector<f64>| {
            if sparse && d1 != 0.0 && d2 != 0.0 && paired.get(contact).copied().unwrap_or(false) {
                let dv = dv.as_mut_slice();
                for (col, a, b) in pair_runs(t1, t2) {
                    crate::math::axpy2(&mut dv[col..col + a.len()], d1, a, d2, b);
                }
            } else {
                moved(t1, d1, dv);
                moved(t2, d2, dv);
            }
        };
        let (mut previous, mut direction) =
            (std::mem::take(&mut self.workspace.previous), std::mem::take(&mut self.workspace.direction));
        if self.accelerate {
            previous.clear();
            previous.resize(n, 0.0);
            direction.clear();
            direction.resize(n, 0.0);
        }
        let mut last_gradient2 = 0.0;
        let mut sweeps = 0;
        // A sweep costs two passes over W's non-zeros (or A's rows); a subspace step up to a
        // dense LU of n unknowns per round plus A over the rows. The first step waits until
        // the sweeps have cost a fraction of that (problems that converge sooner never pay for
        // it), the next ones come at doubling sweep counts, and one always comes after the last
        // sweep of an unconverged solve.
        let sweep_cost = if sparse { 2 * span_total } else { n * n }.max(1);
        let subspace_cost = n * n * n / 3 + if sparse { n * span_total } else { n * n };
        let first_subspace =
            self.subspace_period.max(1).max(subspace_cost.div_ceil(SUBSPACE_COST_SHARE * sweep_cost));
        // An early step is a one-off: if it does not settle the solve, the schedule goes on as
        // without it (a hard problem, where the active set keeps changing, would otherwise pay
        // for a dense solve and an NNCG restart at every doubling from the first sweep on).
        let mut next_subspace = if self.workspace.settled_by_subspace {
            SUBSPACE_EARLY.min(first_subspace)
        } else {
            first_subspace
        };
        let mut settled_by_subspace = false;
        self.workspace.exact_wait = self.workspace.exact_wait.saturating_sub(1);
        let exact_due = self.workspace.exact_wait == 0;
        let mut exact_done = false;
        // The residuals of the final λ, when a subspace step computed them (they are handed to
        // the chain, which would compute them again).
        let mut certified = None;
        for _ in 0..self.iterations {
            sweeps += 1;
            if self.accelerate {
                previous.copy_from_slice(lambda.as_slice());
            }
            let mut change: f64 = 0.0;
            for i in 0..n {
                let d = diag(i);
                if d <= 0.0 {
                    continue;
                }
                let old = lambda[i];
                let new = match problem.laws[i] {
                    RowLaw::Unilateral => (old - self.omega * w(i, lambda, &dv) / d).max(0.0),
                    RowLaw::Bilateral => old - self.omega * w(i, lambda, &dv) / d,
                    RowLaw::Bounded { lo, hi } => (old - self.omega * w(i, lambda, &dv) / d).clamp(lo, hi),
                    RowLaw::Friction { contact } => {
                        let block = problem.contacts[contact];
                        let (nr, t1, t2) = block.rows();
                        if i != t1 {
                            continue; // t2 is updated with t1.
                        }
                        let (o1, o2) = (lambda[t1], lambda[t2]);
                        {
                            // Both tangents at once, exactly on the friction disc or polygon
                            // (see `friction_block_step`): a fixed point then opposes slip.
                            let (w1, w2) = w_pair(contact, t1, t2, lambda, &dv);
                            let g = [diag(t1), coupling[contact], diag(t2)];
                            let (bound, mu) = (lambda[nr].max(0.0), [block.mu, block.mu2]);
                            let step = match problem.friction {
                                FrictionModel::Cone => friction_block_step(
                                    [o1, o2],
                                    [w1, w2],
                                    g,
                                    bound,
                                    mu,
                                    self.omega,
                                    &mut gamma[contact],
                                ),
                                FrictionModel::Pyramid { facets } => {
                                    pyramid_block_step([o1, o2], [w1, w2], g, bound, mu, self.omega, facets)
                                }
                            };
                            if let Some((p1, p2)) = step {
                                lambda[t1] = p1;
                                lambda[t2] = p2;
                                moved_pair(contact, t1, p1 - o1, t2, p2 - o2, &mut dv);
                                change = change.max(g[0] * (p1 - o1).abs()).max(g[2] * (p2 - o2).abs());
                                continue;
                            }
                        }
                        lambda[t1] = o1 - self.omega * w(t1, lambda, &dv) / d;
                        moved(t1, lambda[t1] - o1, &mut dv);
                        let d2 = diag(t2);
                        let before = lambda[t2];
                        if d2 > 0.0 {
                            lambda[t2] = o2 - self.omega * w(t2, lambda, &dv) / d2;
                        }
                        moved(t2, lambda[t2] - before, &mut dv);
                        let (u1, u2) = (lambda[t1], lambda[t2]);
                        let (p1, p2) = project_friction(
                            lambda[t1],
                            lambda[t2],
                            lambda[nr],
                            block.mu,
                            block.mu2,
                            problem.friction,
                        );
                        lambda[t1] = p1;
                        lambda[t2] = p2;
                        moved(t1, p1 - u1, &mut dv);
                        moved(t2, p2 - u2, &mut dv);
                        change = change.max(d * (p1 - o1).abs()).max(d2 * (p2 - o2).abs());
                        continue;
                    }
                };
                lambda[i] = new;
                moved(i, new - old, &mut dv);
                change = change.max(d * (new - old).abs());
            }
            if change <= self.tolerance {
                break;
            }
            if self.accelerate && sweeps < self.iterations {
                // NNCG: −∇f = λ_{k+1} − λ_k; β = ‖∇f_{k+1}‖² / ‖∇f_k‖² (restart if > 1);
                // λ_{k+1} += β p_k; p_{k+1} = β p_k − ∇f_{k+1}.
                let gradient2: f64 = lambda.iter().zip(&previous).map(|(l, p)| (l - p) * (l - p)).sum();
                let beta = if last_gradient2 > 0.0 { gradient2 / last_gradient2 } else { f64::INFINITY };
                last_gradient2 = gradient2;
                // With x̃ the swept impulses, p_{k+1} = β p_k + x̃ − λ_k = λ_{k+1} − λ_k in
                // both cases (β = 0 on a restart).
                for i in 0..n {
                    if beta <= 1.0 {
                        let step = beta * direction[i];
                        lambda[i] += step;
                        moved(i, step, &mut dv);
                    }
                    direction[i] = lambda[i] - previous[i];
                }
            }
            if self.subspace && (sweeps >= next_subspace || sweeps == self.iterations) {
                next_subspace = if sweeps < first_subspace { first_subspace } else { 2 * sweeps };
                let velocities = sparse.then(|| {
                    velocities_at(lambda, &dv, &mut self.workspace.velocities);
                    &self.workspace.velocities[..]
                });
                let ws = &mut self.workspace.subspace;
                // When due, a λ already within the goal is solved exactly (`converged` 0).
                let converged = if exact_due { 0.0 } else { goal };
                let mut outcome = subspace_step(problem, lambda, velocities, ws, self.tolerance, converged);
                if exact_due && ws.start_residual <= goal {
                    exact_done = true;
                    if !matches!(outcome, SubspaceOutcome::Accepted(_)) {
                        // Not improved on: λ as it is, with its residuals.
                        outcome = subspace_step(problem, lambda, velocities, ws, self.tolerance, goal);
                    }
                }
                if let SubspaceOutcome::Converged(_) = outcome {
                    // The sweeps' change is above the tolerance but λ already meets it (a
                    // redundant contact set: the sweeps move λ along its internal forces). The
                    // next solve checks early again: waiting for the regular schedule there
                    // costs the sweeps up to it (a box stack with 12 subspace rounds would
                    // alternate 1 and 69 sweeps).
                    certified = ws.residuals.take();
                    settled_by_subspace = true;
                    break;
                }
                if let SubspaceOutcome::Accepted(reached) = outcome {
                    lambda.copy_from(&ws.candidate);
                    if sparse && ws.sum_valid {
                        // Wᵀλ as the candidate's residuals formed it (the same sums, same order).
                        dv.as_mut_slice().copy_from_slice(&ws.candidate_sum);
                    } else if sparse {
                        dv.fill(0.0);
                        for i in 0..n {
                            if lambda[i] != 0.0 {
                                axpy_blocks(problem, i, lambda[i], &mut dv);
                            }
                        }
                    }
                    // The iterate jumped: restart NNCG's directions.
                    last_gradient2 = 0.0;
                    if reached <= goal {
                        settled_by_subspace = true;
                        certified = ws.residuals.take();
                        break;
                    }
                }
            }
        }
        if certified.is_none() && sparse {
            velocities_at(lambda, &dv, &mut self.workspace.velocities);
            certified = Some(residuals_at_velocities(problem, lambda, &self.workspace.velocities));
        }
        if sparse {
            problem.keep_impulse_sum(lambda.as_slice(), dv.as_slice());
        }
        self.workspace.settled_by_subspace = settled_by_subspace;
        // Judge the last solve's exact solve by this one: settled in one sweep, or not.
        if self.workspace.exact_pending {
            if sweeps <= 1 {
                self.workspace.exact_backoff = 1;
            } else {
                self.workspace.exact_wait = self.workspace.exact_backoff.max(1);
                self.workspace.exact_backoff = (2 * self.workspace.exact_backoff).clamp(1, EXACT_WAIT_MAX);
            }
        }
        self.workspace.exact_pending = exact_done;
        self.workspace.previous = previous;
        self.workspace.gamma = gamma;
        self.workspace.direction = direction;
        self.workspace.dv = dv;
        // A degenerate row (a subnormal diagonal entry) can blow the sweeps up: no answer then.
        if !crate::math::all_finite(lambda.as_slice()) {
            lambda.fill(0.0);
            return Err(SolverError::NonFinite { solver: "pgs" });
        }
        Ok(SolveInfo { iterations: sweeps, note: None, residuals: certified })
    }
}

/// s[span of row i] += δ · W_iᵀ.
fn axpy_blocks(problem: &ConstraintProblem, i: usize, delta: f64, s: &mut DVector<f64>) {
    let s = s.as_mut_slice();
    for (col, w) in problem.sparsity.row_spans(i) {
        crate::math::axpy(&mut s[col..col + w.len()], delta, w);
    }
}
