//! A Newton method on the primal (velocity) form of the convex contact problem, with a sparse
//! Cholesky factorization: the solver for problems where projected Gauss–Seidel crawls (piles of
//! articulated bodies, where the rows of one multibody are strongly coupled).
//!
//! **Formulation.** With A = W Wᵀ, the convex (Anitescu) problem regularised by a diagonal
//! `E ≥ R` (`E = R` on rows already as soft as [`NewtonSolver::epsilon`] of their diagonal; the
//! others topped up by a proximal weight `P = E − R`) and shifted by a proximal centre λ̄,
//!
//! `min_{λ ∈ C} ½ λᵀ (A + E) λ + cᵀ λ`,  `c = b − P λ̄`,
//!
//! is the dual of the unconstrained, convex, once-differentiable problem in x (Todorov,
//! "Convex and analytically-invertible dynamics", 2014; MuJoCo's primal Newton solver):
//!
//! `min_x ½ ‖x‖² + Σ_g φ_g(W_g x + c_g)`,  `∇ = x − Wᵀ λ(x)`,  `∇² = I + Wᵀ G W`,
//!
//! where `λ_g(y) = Π_{C_g}(−E⁻¹ y)` is the projection in the E-metric onto each group's set
//! (a row's bounds, a contact's friction cone: `laws.rs`) and `G = −∂λ/∂y`. x is the velocity
//! change in the coordinates where M is the identity; at the optimum `x = Wᵀ λ`. Each Newton
//! step factors H (`hessian.rs`, sparse over the multibodies) and takes the exact minimum along
//! the direction (a root of the directional derivative, O(rows) per trial since `W d` is formed
//! once).
//!
//! **Outer rounds** (the proximal point method, Rockafellar 1976) make the answer exact on the
//! hard rows (`P > 0`): λ̄ is moved to the round's answer and the problem solved again, so
//! that `P (λ − λ̄) → 0`; the rounds are a fixed-point iteration, accelerated by Anderson's
//! method (`anderson.rs`); rounds that stall (redundant hard rows) lower the weight tenfold. A
//! problem whose rows are all soft (R ≥ ε A_ii, see
//! [`crate::world::WorldOptions::softness`]) is solved in one round.
//!
//! The answer is certified by the shared residuals of the convex relaxation
//! ([`Residuals::convex`], as clarabel's): a sliding contact satisfies it with the relaxation's
//! separating normal velocity `w_n = μ ‖w_t‖`. Friction in the Coulomb cone or in a k-facet
//! pyramid (MuJoCo's pyramidal cone is the 4-facet one): a pyramid contact's law projects onto
//! the polyhedral cone, facet by facet (`laws.rs`).

mod anderson;
mod hessian;
mod laws;
mod rows;

use super::residuals::{contact_of_normal, residuals_at_velocities};
use super::{check_problem, ConstraintSolver, Residuals, SolveInfo, SolverError};
use crate::constraints::{ConstraintProblem, FrictionModel, RowLaw, RowSparsity};
use hessian::Hessian;
use laws::{project, Group, Zone};
use nalgebra::DVector;

/// Share of a chain's certified tolerance the solver aims for, so that the next step's warm
/// start begins well within it.
const CERTIFIED_SHARE: f64 = 0.1;

/// Smallest proximal weight the rounds lower [`NewtonSolver::epsilon`] to when they stall.
const MIN_EPSILON: f64 = 1e-8;

/// How far above its target the bound on `‖W g‖∞` may be for the product itself to be formed
/// (see `converged`).
const CONVERGED_BOUND_SLACK: f64 = 100.0;

/// Rounds of history kept by the Anderson acceleration.
const ANDERSON_DEPTH: usize = 5;

/// The Newton solver and its settings.
pub struct NewtonSolver {
    /// Most Newton iterations in one solve (all rounds together).
    pub max_iterations: usize,
    /// Most outer (proximal) rounds.
    pub max_rounds: usize,
    /// Least regularisation of a row relative to its diagonal A_ii + R_ii: rows softer than this
    /// are solved as they are, harder ones through proximal rounds. Small values make the
    /// problem nearly nonsmooth (more Newton iterations); large ones need more rounds.
    pub epsilon: f64,
    /// Residual (m/s) at which a round's answer ends the solve; `None`: a tenth of the chain's
    /// tolerance, or 1e-9 outside a chain.
    pub residual_goal: Option<f64>,
    /// Start from the impulses passed in (else from zero).
    pub warm_start: bool,
    /// Certify answers by the exact complementarity formulation's residual
    /// ([`Residuals::exact`], as PGS's and Lemke's are) instead of the convex relaxation's. The
    /// relaxation agrees with Coulomb's law wherever contacts stick or separate (a resting
    /// stack: Newton's answer is then exact); a sliding contact's relaxed answer separates at
    /// μ‖w_t‖ and fails this certificate, so that a chain hands such a problem on to a solver of
    /// the exact problem. Named `newton-exact` when set.
    pub certify_exact: bool,
    /// W of a problem given by its dense A.
    own_w: RowSparsity,
    workspace: Workspace,
}

impl Default for NewtonSolver {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            max_rounds: 40,
            epsilon: 1e-2,
            residual_goal: None,
            warm_start: true,
            certify_exact: false,
            own_w: RowSparsity::default(),
            workspace: Workspace::default(),
        }
    }
}

impl std::fmt::Debug for NewtonSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NewtonSolver")
            .field("max_iterations", &self.max_iterations)
            .field("max_rounds", &self.max_rounds)
            .field("epsilon", &self.epsilon)
            .field("residual_goal", &self.residual_goal)
            .field("warm_start", &self.warm_start)
            .field("certify_exact", &self.certify_exact)
            .finish_non_exhaustive()
    }
}

/// Buffers reused between solves.
#[derive(Default)]
struct Workspace {
    groups: Vec<Group>,
    /// Per group: its columns (increasing) in `columns[column_start[g]..column_start[g + 1]]`
    /// and its rows of W on them, dense, row after row, from `local_start[g]`.
    column_start: Vec<usize>,
    columns: Vec<usize>,
    local_start: Vec<usize>,
    local_w: Vec<f64>,
    /// The Hessian's blocks (branches of the multibodies' trees, see [`hessian_blocks`]), each
    /// column's block, and the coupled block pairs (blocks some group's columns touch together).
    hessian_blocks: Vec<(usize, usize)>,
    block_of_col: Vec<usize>,
    cuts: Vec<bool>,
    touched: Vec<usize>,
    pairs: Vec<(usize, usize)>,
    /// Per group, its Hessian block (row-major, up to 3 × 3) and zone at the current x.
    curvature: Vec<[f64; 9]>,
    zones: Vec<Zone>,
    /// Per row: diagonal d = A_ii + R_ii, metric E, 1/√E, proximal weight P = E − R.
    diagonal: Vec<f64>,
    e: Vec<f64>,
    inv_sqrt_e: Vec<f64>,
    prox: Vec<f64>,
    /// Per row: the round's bias c, y = W x + c, y at the line search's start, W d, λ(x), the
    /// proximal centre, the best answer, and zeros (the bias of W d).
    c: Vec<f64>,
    y: Vec<f64>,
    y0: Vec<f64>,
    u: Vec<f64>,
    lambda: Vec<f64>,
    centre: Vec<f64>,
    best: Vec<f64>,
    zeros: Vec<f64>,
    /// Velocities w = (A + R) λ + b of a certified answer, and that answer as a vector.
    w: DVector<f64>,
    lambda_vec: DVector<f64>,
    /// Per column: x, the gradient, the direction, Wᵀλ.
    x: Vec<f64>,
    gradient: Vec<f64>,
    direction: Vec<f64>,
    sum: Vec<f64>,
    /// The dense local product G W_g.
    gw: Vec<f64>,
    hessian: Hessian,
    /// Per group, the Hessian block and zone its term in the assembled H was made with (zeros
    /// while its zone is free), and whether the assembled H belongs to this solve's groups.
    assembled_curvature: Vec<[f64; 9]>,
    assembled_zones: Vec<Zone>,
    assembled: bool,
    /// Whether the Hessian's factor is of an assembly of this solve.
    factored: bool,
    anderson: anderson::Anderson,
}

impl NewtonSolver {
    /// Symbolic analyses of the Hessian's pattern done so far (a new one each time the set of
    /// coupled multibodies changes).
    pub fn pattern_analyses(&self) -> usize {
        self.workspace.hessian.analyses
    }
}

impl ConstraintSolver for NewtonSolver {
    fn name(&self) -> &'static str {
        if self.certify_exact {
            "newton-exact"
        } else {
            "newton"
        }
    }

    fn solve(
        &mut self,
        problem: &ConstraintProblem,
        lambda: &mut DVector<f64>,
    ) -> Result<SolveInfo, SolverError> {
        check_problem(problem)?;
        let n = problem.rows();
        if lambda.len() != n || !self.warm_start {
            *lambda = DVector::zeros(n);
        }
        if n == 0 {
            return Ok(SolveInfo::default());
        }
        let goal = self.residual_goal.unwrap_or(1e-9);
        let own_rows = !rows::has_rows(problem);
        let nv = if own_rows { n } else { problem.sparsity.nv };
        let ws = &mut self.workspace;
        for v in [&mut ws.x, &mut ws.gradient, &mut ws.direction, &mut ws.sum] {
            v.clear();
            v.resize(nv, 0.0);
        }
        if ws.w.len() != n {
            ws.w = DVector::zeros(n);
            ws.lambda_vec = DVector::zeros(n);
        }
        // A warm start already within the goal is the answer (checked before any set-up: a
        // resting pile's steps end here).
        let (residual, report) =
            certify(problem, &problem.sparsity, own_rows, ws, lambda.as_slice(), Sum::Compute);
        if residual <= goal {
            return Ok(SolveInfo { iterations: 0, note: None, residuals: Some(report) });
        }
        if own_rows {
            rows::dense_factor(problem, &mut self.own_w)?;
        }
        let w_rows: &RowSparsity = if own_rows { &self.own_w } else { &problem.sparsity };
        setup_groups(problem, w_rows, own_rows, ws)?;
        set_metric(problem, ws, self.epsilon);
        ws.hessian.prepare(&ws.hessian_blocks, &ws.pairs);
        ws.assembled = false;
        for v in [
            &mut ws.c,
            &mut ws.y,
            &mut ws.y0,
            &mut ws.u,
            &mut ws.lambda,
            &mut ws.centre,
            &mut ws.best,
            &mut ws.zeros,
        ] {
            v.clear();
            v.resize(n, 0.0);
        }
        ws.centre.copy_from_slice(lambda.as_slice());
        rows::transpose_product(w_rows, &ws.centre, &mut ws.x);
        let hard = ws.prox.iter().any(|&p| p > 0.0);
        ws.anderson.reset(n, ANDERSON_DEPTH);
        let mut best = (f64::INFINITY, Residuals::default());
        let mut best_is_last = false;
        let mut iterations = 0;
        let mut epsilon = self.epsilon;
        let mut previous = f64::INFINITY;
        for _ in 0..self.max_rounds {
            for i in 0..n {
                ws.c[i] = problem.bias[i] - ws.prox[i] * ws.centre[i];
            }
            iterations += newton(w_rows, ws, goal, self.max_iterations.saturating_sub(iterations))?;
            let answer = std::mem::take(&mut ws.lambda);
            let (residual, report) = certify(problem, w_rows, own_rows, ws, &answer, Sum::Known);
            ws.lambda = answer;
            best_is_last = residual < best.0;
            if best_is_last {
                best = (residual, report);
                ws.best.copy_from_slice(&ws.lambda);
            }
            if residual <= goal || !hard || iterations >= self.max_iterations {
                break;
            }
            if residual > 0.5 * previous && epsilon > MIN_EPSILON {
                // Slow rounds (redundant hard rows, whose proximal error shrinks at a rate
                // near 1): a smaller weight, and a history for the new map.
                epsilon = (0.1 * epsilon).max(MIN_EPSILON);
                set_metric(problem, ws, epsilon);
                ws.anderson.reset(n, ANDERSON_DEPTH);
            }
            previous = residual;
            ws.anderson.next_centre(&mut ws.centre, &ws.lambda);
        }
        if !best_is_last {
            // The problem keeps the Wᵀλ of the last answer certified: make it the best one's.
            let answer = std::mem::take(&mut ws.best);
            certify(problem, w_rows, own_rows, ws, &answer, Sum::Compute);
            ws.best = answer;
        }
        lambda.as_mut_slice().copy_from_slice(&ws.best);
        Ok(SolveInfo { iterations, note: None, residuals: Some(best.1) })
    }

    fn certify(&self, residuals: &Residuals) -> f64 {
        if self.certify_exact {
            residuals.exact()
        } else {
            residuals.convex()
        }
    }

    fn certifies_part(&self) -> bool {
        self.certify_exact
    }

    fn set_certified_tolerance(&mut self, tolerance: f64) {
        self.residual_goal = Some(CERTIFIED_SHARE * tolerance);
    }
}

/// The groups of rows, their columns and local rows of W, the coupled block pairs, and each
/// row's diagonal.
fn setup_groups(
    problem: &ConstraintProblem,
    w: &RowSparsity,
    own_rows: bool,
    ws: &mut Workspace,
) -> Result<(), SolverError> {
    let n = problem.rows();
    ws.groups.clear();
    for i in 0..n {
        match problem.laws[i] {
            RowLaw::Bilateral => {
                ws.groups.push(Group::Row { row: i, lo: f64::NEG_INFINITY, hi: f64::INFINITY })
            }
            RowLaw::Bounded { lo, hi } => ws.groups.push(Group::Row { row: i, lo, hi }),
            RowLaw::Friction { .. } => {}
            RowLaw::Unilateral => match contact_of_normal(problem, i) {
                None => ws.groups.push(Group::Row { row: i, lo: 0.0, hi: f64::INFINITY }),
                Some(c) => {
                    let contact = &problem.contacts[c];
                    if contact.mu > 0.0 && contact.mu2 > 0.0 {
                        ws.groups.push(match problem.friction {
                            FrictionModel::Cone => Group::Cone { normal: i, slope: 0.0 },
                            FrictionModel::Pyramid { facets } => {
                                Group::Pyramid { normal: i, facets, mu: contact.mu, mu2: contact.mu2 }
                            }
                        });
                    } else if contact.mu == 0.0 && contact.mu2 == 0.0 {
                        ws.groups.push(Group::Row { row: i, lo: 0.0, hi: f64::INFINITY });
                        ws.groups.push(Group::Row { row: i + 1, lo: 0.0, hi: 0.0 });
                        ws.groups.push(Group::Row { row: i + 2, lo: 0.0, hi: 0.0 });
                    } else {
                        return Err(SolverError::InvalidProblem(format!(
                            "newton: the cone of contact {c} needs friction along both tangents or neither (μ {}, μ₂ {})",
                            contact.mu, contact.mu2
                        )));
                    }
                }
            },
        }
    }
    let covered: usize = ws.groups.iter().map(|g| g.rows().1).sum();
    if covered != n {
        return Err(SolverError::InvalidProblem(format!(
            "newton: {covered} of {n} rows belong to a law (friction rows outside a contact block)"
        )));
    }
    ws.diagonal.clear();
    let kept = problem.kept_diagonal();
    for i in 0..n {
        let a = match kept {
            Some(a) => a[i],
            None if w.row_norm2.len() == n => w.row_norm2[i],
            None => problem.delassus_entry(i, i),
        };
        ws.diagonal.push(a + problem.regularization[i]);
    }
    hessian_blocks(w, ws, own_rows);
    ws.column_start.clear();
    ws.columns.clear();
    ws.local_start.clear();
    ws.local_w.clear();
    ws.pairs.clear();
    ws.column_start.push(0);
    for g in 0..ws.groups.len() {
        let (first, count) = ws.groups[g].rows();
        let start = ws.columns.len();
        // The rows of a contact usually share their runs (disjoint, most often increasing):
        // then the first row's columns are the group's, sorted already.
        let runs = |i: usize| w.row_spans(i).map(|(col, wi)| (col, wi.len()));
        let shared = (first + 1..first + count).all(|i| runs(i).eq(runs(first)));
        for i in first..first + count {
            if i == first || !shared {
                for (col, wi) in w.row_spans(i) {
                    ws.columns.extend(col..col + wi.len());
                }
            }
        }
        if !shared || ws.columns[start..].windows(2).any(|p| p[0] >= p[1]) {
            ws.columns[start..].sort_unstable();
            let mut write = start;
            for read in start..ws.columns.len() {
                if write == start || ws.columns[read] != ws.columns[write - 1] {
                    ws.columns[write] = ws.columns[read];
                    write += 1;
                }
            }
            ws.columns.truncate(write);
        }
        let write = ws.columns.len();
        ws.touched.clear();
        for &col in &ws.columns[start..write] {
            let block = ws.block_of_col[col];
            if ws.touched.last() != Some(&block) {
                ws.touched.push(block);
            }
        }
        for (k, &a) in ws.touched.iter().enumerate() {
            for &b in &ws.touched[k + 1..] {
                ws.pairs.push((a, b));
            }
        }
        ws.column_start.push(write);
        let cols = write - start;
        ws.local_start.push(ws.local_w.len());
        let base = ws.local_w.len();
        ws.local_w.resize(base + count * cols, 0.0);
        for (r, i) in (first..first + count).enumerate() {
            for (col, wi) in w.row_spans(i) {
                // The run's columns are consecutive, so they are too among the group's.
                let at = ws.columns[start..write].binary_search(&col).expect("a column of the group");
                ws.local_w[base + r * cols + at..base + r * cols + at + wi.len()].copy_from_slice(wi);
            }
        }
    }
    ws.local_start.push(ws.local_w.len());
    ws.pairs.sort_unstable();
    ws.pairs.dedup();
    ws.curvature.clear();
    ws.curvature.resize(ws.groups.len(), [0.0; 9]);
    ws.zones.clear();
    ws.zones.resize(ws.groups.len(), Zone::Free);
    Ok(())
}

/// `ws.hessian_blocks` and `ws.block_of_col`: the multibodies' blocks cut where a run of W's rows
/// starts. A row's runs are its bodies' paths to the root; in the depth-first numbering of a
/// tree a run starts at a root or at a child that does not follow its parent, so the blocks
/// are branches: a joint with its chain of first children (a ragdoll's pelvis and first leg,
/// the other leg, the spine and head, each arm). H's pattern over them keeps the tree's
/// sparsity, where two branches are coupled only by rows that touch both, with few blocks
/// (joint-sized ones cost more in bookkeeping than their zeros save).
fn hessian_blocks(w: &RowSparsity, ws: &mut Workspace, own_rows: bool) {
    let nv = w.nv;
    ws.cuts.clear();
    ws.cuts.resize(nv + 1, false);
    ws.cuts[nv] = true;
    for &(first, _) in &w.blocks {
        ws.cuts[first] = true;
    }
    // The solver's own W (a Cholesky factor of a dense A) is dense: its block stays whole.
    if !own_rows {
        for &(col, _, _) in &w.runs {
            ws.cuts[col] = true;
        }
    }
    ws.hessian_blocks.clear();
    ws.block_of_col.clear();
    let mut first = 0;
    for col in 1..=nv {
        if ws.cuts[col] {
            ws.block_of_col.extend(std::iter::repeat_n(ws.hessian_blocks.len(), col - first));
            ws.hessian_blocks.push((first, col - first));
            first = col;
        }
    }
}

/// E = max(R, ε d) per row (a floor keeps E > 0 on rows without inertia), the friction rows of a
/// cone contact raised to satisfy μ √e₁ = μ₂ √e₂ (its cone is then circular in scaled impulses),
/// each cone's slope in scaled impulses, and the proximal weights P = E − R.
fn set_metric(problem: &ConstraintProblem, ws: &mut Workspace, epsilon: f64) {
    let n = problem.rows();
    let floor = 1e-12 * ws.diagonal.iter().copied().fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    ws.e.clear();
    ws.e.extend((0..n).map(|i| problem.regularization[i].max(epsilon * ws.diagonal[i].max(floor))));
    for g in 0..ws.groups.len() {
        let (normal, cone) = match ws.groups[g] {
            Group::Cone { normal, .. } => (normal, true),
            Group::Pyramid { normal, .. } => (normal, false),
            Group::Row { .. } => continue,
        };
        {
            let c = &problem.contacts[contact_of_normal(problem, normal).expect("a contact normal")];
            let (t1, t2) = (normal + 1, normal + 2);
            // A friction row softened relative to its contact's normal (as the world's softness
            // does) is soft enough by that measure: its own diagonal, which may be far larger
            // (a tangent that spins a slender limb), would make it hard and cost proximal rounds.
            let soft_floor = epsilon * ws.diagonal[normal].max(floor);
            for t in [t1, t2] {
                if problem.regularization[t] >= soft_floor {
                    ws.e[t] = problem.regularization[t];
                }
            }
            if !cone {
                // A pyramid's facets need no particular metric: any E leaves it a polyhedral cone.
                continue;
            }
            // Only the smaller side is raised (a round trip through μ² would leave the other
            // a rounding error above its R, and a row above its R is a hard one).
            let (k1, k2) = (c.mu * c.mu * ws.e[t1], c.mu2 * c.mu2 * ws.e[t2]);
            let kappa2 = k1.max(k2);
            if k1 < k2 {
                ws.e[t1] = kappa2 / (c.mu * c.mu);
            } else if k2 < k1 {
                ws.e[t2] = kappa2 / (c.mu2 * c.mu2);
            }
            ws.groups[g] = Group::Cone { normal, slope: kappa2.sqrt() / ws.e[normal].sqrt() };
        }
    }
    ws.inv_sqrt_e.clear();
    ws.inv_sqrt_e.extend(ws.e.iter().map(|e| 1.0 / e.sqrt()));
    ws.prox.clear();
    ws.prox.extend((0..n).map(|i| ws.e[i] - problem.regularization[i]));
}

/// Whether `ws.sum` already holds Wᵀλ of the answer being certified.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Sum {
    Compute,
    Known,
}

/// Row velocities w = (A + R) λ + b of `lambda` into `ws.w`, and the convex residual and the
/// report. With the problem's own W, Wᵀλ is kept with the problem for the velocity update.
fn certify(
    problem: &ConstraintProblem,
    w_rows: &RowSparsity,
    own_rows: bool,
    ws: &mut Workspace,
    lambda: &[f64],
    sum: Sum,
) -> (f64, Residuals) {
    ws.lambda_vec.as_mut_slice().copy_from_slice(lambda);
    if own_rows {
        problem.velocities(&ws.lambda_vec, &mut ws.w);
    } else {
        if sum == Sum::Compute {
            rows::transpose_product(w_rows, lambda, &mut ws.sum);
        }
        rows::product(w_rows, &ws.sum, problem.bias.as_slice(), ws.w.as_mut_slice());
        for ((w, r), l) in ws.w.iter_mut().zip(problem.regularization.iter()).zip(lambda) {
            *w += r * l;
        }
        problem.keep_impulse_sum(lambda, &ws.sum);
    }
    let report = residuals_at_velocities(problem, &ws.lambda_vec, ws.w.as_slice());
    (report.convex(), report)
}

/// Newton iterations on the round's problem (`ws.c`, `ws.e`) from `ws.x`, until the row
/// velocities of x and of Wᵀλ(x) differ by at most a tenth of `goal` (`‖W g‖∞`, the gradient
/// g = x − Wᵀλ seen by the rows: what separates the answer's velocities from those its impulses
/// were projected at), no step moves x, or `budget` iterations are done; `ws.lambda` is left at
/// λ(x) and `ws.sum` at Wᵀλ. Returns the iterations done.
fn newton(w: &RowSparsity, ws: &mut Workspace, goal: f64, budget: usize) -> Result<usize, SolverError> {
    let largest_row = ws.diagonal.iter().copied().fold(0.0, f64::max).sqrt();
    let mut done = 0;
    let mut previous_norm = f64::INFINITY;
    rows::product(w, &ws.x, &ws.c, &mut ws.y);
    evaluate(ws);
    loop {
        // y and λ(y) are at x: from the line above, or from the line search's last trial.
        rows::transpose_product(w, &ws.lambda, &mut ws.sum);
        let mut norm = 0.0;
        for k in 0..ws.x.len() {
            ws.gradient[k] = ws.x[k] - ws.sum[k];
            norm += ws.gradient[k] * ws.gradient[k];
        }
        if converged(w, ws, largest_row * norm.sqrt(), 0.1 * goal) || done >= budget {
            return Ok(done);
        }
        // Near the answer (the last step shrank the gradient tenfold or more) with the same
        // zones as at the last factorization, only sliding contacts' G moved a little: the
        // last factor still gives a descent direction that converges fast (the line search
        // keeps it safe), and refactoring the Hessian is most of an iteration's cost.
        let pending = pending_changes(ws);
        let converging = norm <= 0.1 * previous_norm;
        let reuse = ws.factored && (!pending.changed || (converging && !pending.zones_changed));
        if !reuse {
            assemble(ws);
            ws.hessian.factor().map_err(|_| {
                SolverError::InvalidProblem("newton: the Hessian is not positive definite".into())
            })?;
            ws.factored = true;
        }
        previous_norm = norm;
        for k in 0..ws.x.len() {
            ws.direction[k] = -ws.gradient[k];
        }
        ws.hessian.solve(&mut ws.direction);
        rows::product(w, &ws.direction, &ws.zeros, &mut ws.u);
        let alpha = line_search(ws);
        let mut moved = 0.0f64;
        for k in 0..ws.x.len() {
            let step = alpha * ws.direction[k];
            moved = moved.max(step.abs() / (1.0 + ws.x[k].abs()));
            ws.x[k] += step;
        }
        done += 1;
        if moved <= 1e-15 {
            // No progress left at this precision: the answer stands.
            rows::product(w, &ws.x, &ws.c, &mut ws.y);
            evaluate(ws);
            rows::transpose_product(w, &ws.lambda, &mut ws.sum);
            return Ok(done);
        }
    }
}

/// Whether `‖W g‖∞ ≤ target` for the gradient in `ws.gradient`. `bound` = max_i ‖W_i‖ ‖g‖
/// bounds it: W g (one product, into `ws.u`, free until the direction's) is formed only once
/// the bound is within [`CONVERGED_BOUND_SLACK`] of the target, as it is 20 to 50 times the
/// product on piles of ragdolls.
fn converged(w: &RowSparsity, ws: &mut Workspace, bound: f64, target: f64) -> bool {
    if bound <= target {
        return true;
    }
    if bound > CONVERGED_BOUND_SLACK * target {
        return false;
    }
    rows::product(w, &ws.gradient, &ws.zeros, &mut ws.u);
    ws.u.iter().all(|v| v.abs() <= target)
}

/// λ(y) of every group at `ws.y`, with the Hessian blocks and zones.
fn evaluate(ws: &mut Workspace) {
    for (g, group) in ws.groups.iter().enumerate() {
        let (first, count) = group.rows();
        let rows = first..first + count;
        ws.zones[g] = project(
            group,
            &ws.y[rows.clone()],
            &ws.e[rows.clone()],
            &ws.inv_sqrt_e[rows.clone()],
            &mut ws.lambda[rows],
            Some(&mut ws.curvature[g][..count * count]),
        );
    }
}

/// What changed since the Hessian was last assembled (all of it before the solve's first
/// assembly): some group's G, some group's zone.
fn pending_changes(ws: &Workspace) -> PendingChanges {
    if !ws.assembled {
        return PendingChanges { changed: true, zones_changed: true };
    }
    let mut pending = PendingChanges { changed: false, zones_changed: false };
    for (g, group) in ws.groups.iter().enumerate() {
        pending.zones_changed |= ws.zones[g] != ws.assembled_zones[g];
        let entries = group.rows().1.pow(2);
        let now = if ws.zones[g] == Zone::Free { &[0.0; 9] } else { &ws.curvature[g] };
        pending.changed |= now[..entries] != ws.assembled_curvature[g][..entries];
    }
    pending
}

/// H = I + Σ_g W_gᵀ G_g W_g over the groups with curvature. Within a solve only the groups
/// whose G changed since the last assembly add their change: a sticking contact's G is
/// constant, a separated one's zero, so most of a settled pile's terms stay as they are.
/// Iterations that keep the last factor leave their changes to the next assembly.
fn assemble(ws: &mut Workspace) {
    if !ws.assembled {
        ws.hessian.reset();
        ws.assembled_curvature.clear();
        ws.assembled_curvature.resize(ws.groups.len(), [0.0; 9]);
        ws.assembled_zones.clear();
        ws.assembled_zones.resize(ws.groups.len(), Zone::Free);
        ws.assembled = true;
        ws.factored = false;
    }
    for g in 0..ws.groups.len() {
        let (_, count) = ws.groups[g].rows();
        let entries = count * count;
        let now = if ws.zones[g] == Zone::Free { [0.0; 9] } else { ws.curvature[g] };
        let before = ws.assembled_curvature[g];
        ws.assembled_zones[g] = ws.zones[g];
        if now[..entries] == before[..entries] {
            continue;
        }
        let columns = &ws.columns[ws.column_start[g]..ws.column_start[g + 1]];
        let m = columns.len();
        let local = &ws.local_w[ws.local_start[g]..ws.local_start[g] + count * m];
        // ΔG W_g (count × m, row-major), then H += W_gᵀ (ΔG W_g) on the group's columns.
        ws.gw.clear();
        ws.gw.resize(count * m, 0.0);
        for a in 0..count {
            for b in 0..count {
                let gab = now[a * count + b] - before[a * count + b];
                if gab != 0.0 {
                    for (gw, w) in ws.gw[a * m..(a + 1) * m].iter_mut().zip(&local[b * m..(b + 1) * m]) {
                        *gw += gab * w;
                    }
                }
            }
        }
        ws.hessian.add_gram(columns, local, &ws.gw, count);
        ws.assembled_curvature[g] = now;
    }
}

/// What changed in the Hessian's terms since its last assembly.
struct PendingChanges {
    /// Some group's G (H would be new).
    changed: bool,
    /// Some group's zone (the active set).
    zones_changed: bool,
}

/// The step α > 0 along `ws.direction` (with `ws.u` = W d) where the directional derivative
/// `ψ'(α) = dᵀ(x + α d) − uᵀ λ(y + α u)` vanishes: safeguarded Newton on ψ', whose slope
/// `ψ'' = ‖d‖² + uᵀ G u` comes with each trial. Leaves `ws.y` and `ws.lambda` at the step.
fn line_search(ws: &mut Workspace) -> f64 {
    let dd: f64 = ws.direction.iter().map(|d| d * d).sum();
    let xd: f64 = ws.x.iter().zip(&ws.direction).map(|(x, d)| x * d).sum();
    ws.y0.copy_from_slice(&ws.y);
    let derivative = |alpha: f64, ws: &mut Workspace| -> (f64, f64) {
        for i in 0..ws.y.len() {
            ws.y[i] = ws.y0[i] + alpha * ws.u[i];
        }
        evaluate(ws);
        let mut slope = xd + alpha * dd;
        let mut curvature = dd;
        for (g, group) in ws.groups.iter().enumerate() {
            let (first, count) = group.rows();
            for a in 0..count {
                slope -= ws.u[first + a] * ws.lambda[first + a];
                if ws.zones[g] != Zone::Free {
                    for b in 0..count {
                        curvature += ws.u[first + a] * ws.curvature[g][a * count + b] * ws.u[first + b];
                    }
                }
            }
        }
        (slope, curvature)
    };
    let (start, _) = derivative(0.0, ws);
    let (mut lo, mut hi) = (0.0, f64::INFINITY);
    let mut alpha = 1.0;
    let mut best = (0.0, start.abs());
    for _ in 0..40 {
        let (slope, curvature) = derivative(alpha, ws);
        if slope.abs() < best.1 {
            best = (alpha, slope.abs());
        }
        if slope.abs() <= 1e-10 * start.abs() {
            break;
        }
        if slope < 0.0 {
            lo = alpha;
        } else {
            hi = alpha;
        }
        let mut next = alpha - slope / curvature.max(f64::MIN_POSITIVE);
        if !(next > lo && next < hi) {
            next = if hi.is_finite() { 0.5 * (lo + hi) } else { 2.0 * alpha };
        }
        if (next - alpha).abs() <= 1e-14 * alpha {
            break;
        }
        alpha = next;
    }
    if best.0 != alpha {
        alpha = best.0;
        derivative(alpha, ws);
    }
    alpha
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constraints::ContactBlock;
    use nalgebra::DMatrix;

    /// A tree numbered depth first (a floating base of 6 columns, its first child's chain of
    /// 3 and a second child of 3): rows on the base, down the first chain and down the second
    /// branch cut the columns into the two branches, which a Newton Hessian then keeps
    /// uncoupled; the solver's own dense W stays one block.
    #[test]
    fn the_hessian_blocks_are_the_branches_of_a_tree() {
        let mut w = RowSparsity { nv: 12, blocks: vec![(0, 12)], ..RowSparsity::default() };
        w.run_start.push(0);
        for runs in [&[(0, 6)][..], &[(0, 9)], &[(0, 6), (9, 3)], &[(0, 7)]] {
            for &(col, len) in runs {
                w.runs.push((col, w.w_values.len(), len));
                w.w_values.extend(std::iter::repeat_n(1.0, len));
            }
            w.run_start.push(w.runs.len());
        }
        let mut ws = Workspace::default();
        hessian_blocks(&w, &mut ws, false);
        assert_eq!(ws.hessian_blocks, vec![(0, 9), (9, 3)]);
        assert_eq!(ws.block_of_col, [vec![0; 9], vec![1; 3]].concat());
        hessian_blocks(&w, &mut ws, true);
        assert_eq!(ws.hessian_blocks, vec![(0, 12)]);
    }

    /// The stop judges the gradient by the row velocities it leaves: a gradient mostly along a
    /// column no row sees stops the iterations although its norm times the largest row is far
    /// above the target; the same gradient turned onto a row does not.
    #[test]
    fn convergence_is_judged_by_the_row_velocities() {
        let mut w = RowSparsity { nv: 3, blocks: vec![(0, 3)], ..RowSparsity::default() };
        w.run_start.push(0);
        for (col, value) in [(0, 2.0), (1, 1.0)] {
            w.runs.push((col, w.w_values.len(), 1));
            w.w_values.push(value);
            w.run_start.push(w.runs.len());
        }
        let mut ws = Workspace { zeros: vec![0.0; 2], u: vec![0.0; 2], ..Workspace::default() };
        let (largest_row, target) = (2.0, 1e-8);
        for (gradient, expected) in [([1e-10, 0.0, 1e-7], true), ([1e-7, 0.0, 1e-10], false)] {
            ws.gradient = gradient.to_vec();
            let norm = gradient.iter().map(|g| g * g).sum::<f64>().sqrt();
            assert!(largest_row * norm > target);
            assert_eq!(converged(&w, &mut ws, largest_row * norm, target), expected, "{gradient:?}");
        }
        // Far above the target the product is not even formed.
        ws.gradient = vec![0.0, 0.0, 1.0];
        assert!(!converged(&w, &mut ws, 2.0, target));
    }

    /// A contact whose tangents are thirty times stiffer than its normal (a tangent that spins
    /// a slender limb), softened as the world's softness does (R = 0.1 A_nn on all three rows):
    /// every row counts as soft, so the problem is solved in one round without proximal terms.
    #[test]
    fn friction_softened_like_its_normal_makes_no_hard_row() {
        let a = DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 30.0, 30.0]));
        let laws = vec![RowLaw::Unilateral, RowLaw::Friction { contact: 0 }, RowLaw::Friction { contact: 0 }];
        let contact = ContactBlock { normal: 0, mu: 0.5, mu2: 0.5 };
        let bias = DVector::from_vec(vec![-1.0, 0.2, -0.1]);
        let mut problem = ConstraintProblem::from_parts(a, bias, laws, vec![contact], FrictionModel::Cone);
        problem.regularization.fill(0.1);
        let mut solver = NewtonSolver::default();
        let mut lambda = DVector::zeros(3);
        let info = solver.solve(&problem, &mut lambda).unwrap();
        assert!(info.residuals.unwrap().convex() <= 1e-9);
        assert_eq!(solver.workspace.prox, vec![0.0; 3], "metric {:?}", solver.workspace.e);
    }
}
