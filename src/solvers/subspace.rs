//! Subspace minimisation for projected Gauss–Seidel (Silcowitz, Niebe and Erleben, "Projected
//! Gauss–Seidel subspace minimization method for interactive rigid body dynamics", 2010).
//!
//! PGS finds the active set of a problem (which contacts press, stick or slide, which limits and
//! motors are at a bound) in a few sweeps, but then converges on it only linearly, at a rate set
//! by A's conditioning: a redundant contact set (four corners of a foot on the floor) at the end
//! of a stiff chain makes that rate so close to 1 that thousands of sweeps are needed. With the
//! active set fixed the problem is a linear system, which one dense solve settles:
//!
//! - equality rows `w_i = 0` with `λ_i` free: bilateral rows, unilateral rows with `λ_i > 0`,
//!   bounded rows strictly inside their box, the normal of a pressing contact and the tangents of
//!   a sticking one (strictly inside its cone);
//! - a sliding contact (on the cone's boundary) has two unknowns, its normal impulse and its
//!   direction θ, with `λ_t = λ_n (μ₁ cos θ, μ₂ sin θ)`: the equations are `w_n = 0` and that
//!   the scaled slip `(μ₁ w₁, μ₂ w₂)` be parallel to the direction (maximum dissipation), the
//!   latter nonlinear in θ and linearised (a Newton step per round);
//! - with pyramid friction (the friction set a regular polygon in `s = (λ₁/μ₁, λ₂/μ₂)`, facet
//!   normals `n_j` at offset `cos(π/k)`) everything is linear: a contact on facet j has two
//!   unknowns, its normal impulse (the tangents following at `s·n_j = cos(π/k) λ_n`) and its
//!   position τ along the facet (`s = cos(π/k) λ_n n_j + τ e_j`, `e_j` the facet's direction),
//!   with the equations `w_n = 0` and `e_j·(μ₁ w₁, μ₂ w₂) = 0` (slip along −n_j: maximum
//!   dissipation); a contact at a vertex `v` has one, its normal impulse with `s = λ_n v`, and the
//!   equation `w_n = 0`. One solve per active set, no Newton rounds;
//! - every other row keeps its impulse (zero, or the bound it sits at).
//!
//! The reduced system (not symmetric when a contact slides) is solved by LU with partial
//! pivoting of `K + εI` — by Cholesky when every unknown is a free row and K is A + R over them
//! (a resting stack) — and one refinement step against K: a proximal-point iteration, so
//! that the singular K of a redundant contact set still yields a solution near PGS's iterate.
//! That solution is followed as far as the active set allows (see [`subspace_step`]), the
//! result is projected onto the feasible set and taken only if it lowers the exact residual
//! ([`super::Residuals::exact`], what a [`super::SolverChain`] certifies); PGS then sweeps on
//! from it, correcting the active set where the step left it wrong.

use super::friction::project_friction;
use super::residuals::{
    contact_of_normal, norm2, pyramid_facet, pyramid_offset_and_half, pyramid_vertex, residuals,
    residuals_at_velocities,
};
use crate::constraints::{ConstraintProblem, FrictionModel, RowLaw};
use nalgebra::DVector;

/// Largest problem (rows) a subspace step is tried on: the dense LU costs O(s³).
pub(crate) const MAX_SUBSPACE: usize = 128;

/// Proximal regularisation of the reduced solve, relative to K's largest diagonal entry.
const PROXIMAL: f64 = 1e-10;

/// Solves of the proximal iteration: the plain solve and one refinement. (Session 20: with a
/// second refinement, `models/box_stack10.toml` 1.947 G instructions against 1.779 G, the
/// humanoid 0.714 G against 0.707 G, ragdoll seeds 1–7 9.90 G against 9.77 G, with as many or
/// more steps above the tolerance; with none, the box stack 2.32 G and the humanoid 0.774 G.)
const REFINEMENTS: usize = 2;

/// A contact slides when its tangential impulse is this close (relatively) to the cone.
const ON_CONE: f64 = 1e-9;

/// In the first round, PGS's iterate puts a pyramid contact on its facet (or at its vertex)
/// when its tangential impulse is this close (relatively) to it. The sweeps leave a contact
/// that slides slightly inside its pyramid (its normal impulse still growing, the facet moving
/// out): guessed sticking, it cost a round to find its facet. A wrong guess costs a round
/// too (the release of [`release_pyramid_contacts`]); later rounds start from exact solves and
/// classify at [`ON_CONE`]. Ragdoll seeds 1–7 (`models/ragdoll_fall.toml`): 1e-9 → 1e-2 took
/// 8.6 % off the episodes' instructions, every seed lower; 1e-1 (in every round) only 3 %.
const GUESS_ON_PYRAMID: f64 = 1e-2;

/// One unknown of the reduced system.
#[derive(Clone, Copy, Debug)]
enum Unit {
    /// λ of this row is free; its equation is `w_row = 0`.
    Row(usize),
    /// The normal impulse of a sliding contact, its tangents following on the cone:
    /// `λ_t = λ_n (μ₁ cos θ, μ₂ sin θ)`; its equation is `w_n = 0`.
    Slide(Sliding),
    /// The direction θ of the same sliding contact (always right after its `Slide`); its
    /// equation is that the scaled slip `m = (μ₁ w₁, μ₂ w₂)` be parallel to (cos θ, sin θ):
    /// `g = −sin θ m₁ + cos θ m₂ = 0` (maximum dissipation when they are opposite).
    Angle(Sliding),
    /// The normal impulse of a contact on a facet of its friction pyramid, its tangents
    /// following on the facet: `s·n = cos(π/k) λ_n`; its equation is `w_n = 0`.
    Facet(OnFacet),
    /// The position τ along the same facet (always right after its `Facet`): `s += τ e`; its
    /// equation is that the scaled slip be normal to the facet: `e·(μ₁ w₁, μ₂ w₂) = 0`.
    Along(OnFacet),
    /// The normal impulse of a contact at a vertex `v` of its friction pyramid: `s = λ_n v`;
    /// its equation is `w_n = 0`.
    Corner(AtVertex),
}

/// A contact on a facet of its friction pyramid: rows, coefficients, the facet's outward normal
/// `n` and direction `e = (−n₂, n₁)` in the scaled plane, the facet offset cos(π/k) and half
/// the facet's length per unit normal impulse, sin(π/k).
#[derive(Clone, Copy, Debug)]
struct OnFacet {
    normal: usize,
    t1: usize,
    t2: usize,
    mu: [f64; 2],
    n: [f64; 2],
    offset: f64,
    half: f64,
}

impl OnFacet {
    /// The facet's direction e = (−n₂, n₁).
    fn e(&self) -> [f64; 2] {
        [-self.n[1], self.n[0]]
    }
}

/// A contact at vertex `index` of its friction pyramid, `v` in the scaled plane.
#[derive(Clone, Copy, Debug)]
struct AtVertex {
    normal: usize,
    t1: usize,
    t2: usize,
    mu: [f64; 2],
    index: usize,
    v: [f64; 2],
}

/// A sliding contact's rows, coefficients, normal impulse and direction (in λ_t/μ coordinates).
#[derive(Clone, Copy, Debug)]
struct Sliding {
    normal: usize,
    t1: usize,
    t2: usize,
    mu: [f64; 2],
    lambda_n: f64,
    cos: f64,
    sin: f64,
}

impl Unit {
    /// λ moves by the unknown times Σ coefficient · e_row (a linearisation for `Angle`).
    fn column(&self) -> [(usize, f64); 3] {
        match *self {
            Unit::Row(i) => [(i, 1.0), (i, 0.0), (i, 0.0)],
            Unit::Slide(c) => [(c.normal, 1.0), (c.t1, c.mu[0] * c.cos), (c.t2, c.mu[1] * c.sin)],
            Unit::Angle(c) => {
                [(c.t1, -c.lambda_n * c.mu[0] * c.sin), (c.t2, c.lambda_n * c.mu[1] * c.cos), (c.t2, 0.0)]
            }
            Unit::Facet(f) => {
                [(f.normal, 1.0), (f.t1, f.mu[0] * f.offset * f.n[0]), (f.t2, f.mu[1] * f.offset * f.n[1])]
            }
            Unit::Along(f) => {
                let e = f.e();
                [(f.t1, f.mu[0] * e[0]), (f.t2, f.mu[1] * e[1]), (f.t2, 0.0)]
            }
            Unit::Corner(c) => [(c.normal, 1.0), (c.t1, c.mu[0] * c.v[0]), (c.t2, c.mu[1] * c.v[1])],
        }
    }
    /// The equation Σ coefficient · w_row (+ the explicit θ-derivative on the diagonal).
    fn equation(&self) -> [(usize, f64); 2] {
        match *self {
            Unit::Row(i) => [(i, 1.0), (i, 0.0)],
            Unit::Slide(c) => [(c.normal, 1.0), (c.normal, 0.0)],
            Unit::Angle(c) => [(c.t1, -c.sin * c.mu[0]), (c.t2, c.cos * c.mu[1])],
            Unit::Facet(OnFacet { normal, .. }) | Unit::Corner(AtVertex { normal, .. }) => {
                [(normal, 1.0), (normal, 0.0)]
            }
            Unit::Along(f) => {
                let e = f.e();
                [(f.t1, e[0] * f.mu[0]), (f.t2, e[1] * f.mu[1])]
            }
        }
    }
}

/// Scratch space of the subspace step (kept by the PGS workspace; allocation-free once sized).
#[derive(Clone, Debug, Default)]
pub(crate) struct SubspaceWorkspace {
    units: Vec<Unit>,
    /// The pyramid contact (by normal row) that the next classification puts on the given
    /// facet, or inside (`None`), though its impulses sit at a vertex or on a facet: see
    /// [`release_pyramid_contacts`].
    released: Option<(usize, Option<usize>)>,
    /// Contacts (normal rows) whose release the next round undid at once (a zero step): not
    /// released again in this step, so that a degenerate contact cannot make the rounds cycle
    /// between two active sets.
    release_refused: Vec<usize>,
    /// Per row: whether it belongs to a contact.
    contact_row: Vec<bool>,
    /// Per row: its index in `rows`, or `usize::MAX`.
    local: Vec<usize>,
    /// The rows the units touch (the only ones whose λ moves or whose w is read).
    rows: Vec<usize>,
    /// λ and w of those rows at the start.
    start: Vec<f64>,
    w_start: Vec<f64>,
    /// λ's change over those rows since the start, in a later round.
    delta: Vec<f64>,
    /// The column range [lo, hi) outside which each of those rows of W is zero, the groups of
    /// rows (first, count, lane offset) and their rows of W as lanes, when the Gram is formed
    /// from W here ([`fill_gram`]).
    w_range: Vec<(usize, usize)>,
    groups: Vec<(usize, usize, usize)>,
    w_lanes: Vec<[f64; GROUP]>,
    /// Per group, where its runs start in `group_runs` (one per group plus one), and the runs
    /// (first column, end) outside which its rows of W are zero.
    group_run_start: Vec<usize>,
    group_runs: Vec<(usize, usize)>,
    /// A + R over those rows (row-major).
    gram: Vec<f64>,
    /// (A + R) times each unit's column, over `rows` (units × rows).
    gc: Vec<f64>,
    /// K (row-major, units × units) and its LU factors.
    k: Vec<f64>,
    lu: Vec<f64>,
    pivots: Vec<usize>,
    rhs: Vec<f64>,
    x: Vec<f64>,
    correction: Vec<f64>,
    /// Row velocities of the current iterate.
    w: DVector<f64>,
    /// The projected result.
    pub(crate) candidate: DVector<f64>,
    /// Wᵀ `candidate` (length nv), formed with the candidate's residuals when `sum_valid`
    /// (matrix-free problems): PGS takes its kept Wᵀλ from here on acceptance.
    pub(crate) candidate_sum: Vec<f64>,
    pub(crate) sum_valid: bool,
    /// The residuals of `candidate`, once a step has computed them.
    pub(crate) residuals: Option<super::Residuals>,
    /// Reduced solves (rounds) of the last step.
    pub(crate) rounds: usize,
    /// The exact residual of the λ the last step started from (m/s; infinite if the step was
    /// not tried).
    pub(crate) start_residual: f64,
}

impl SubspaceWorkspace {
    /// Reserves room for a problem of `n` rows, so that the step allocates nothing later.
    pub(crate) fn reserve(&mut self, n: usize) {
        let s = n.min(MAX_SUBSPACE);
        for v in [&mut self.gram, &mut self.gc, &mut self.k, &mut self.lu] {
            v.reserve((s * s).saturating_sub(v.len()));
        }
        for v in [&mut self.rhs, &mut self.x, &mut self.correction] {
            v.reserve(n.saturating_sub(v.len()));
        }
        self.units.reserve(n.saturating_sub(self.units.len()));
        self.contact_row.reserve(n.saturating_sub(self.contact_row.len()));
        for v in [&mut self.start, &mut self.w_start, &mut self.delta] {
            v.reserve(n.saturating_sub(v.len()));
        }
        self.local.reserve(n.saturating_sub(self.local.len()));
        self.rows.reserve(n.saturating_sub(self.rows.len()));
        self.pivots.reserve(n.saturating_sub(self.pivots.len()));
        if self.w.len() != n {
            self.w = DVector::zeros(n);
            self.candidate = DVector::zeros(n);
        }
    }
}

/// What a subspace step did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum SubspaceOutcome {
    /// Not attempted, or no reduced solve succeeded: nothing free, too many free impulses, a
    /// pyramid contact with one friction coefficient zero, or a singular reduced system.
    Skipped,
    /// Not needed: λ itself is within `converged` (its exact residual), its residuals are in
    /// `workspace.residuals`.
    Converged(f64),
    /// The projected solve did not lower the exact residual (which it reports).
    Rejected(f64),
    /// `workspace.candidate` holds the better impulses, with this exact residual.
    Accepted(f64),
}

/// One subspace-minimisation step from `lambda` (see the module docs): on acceptance the
/// candidate is left in `ws.candidate` for the caller to take. `velocities`, when the caller
/// has them, are the row velocities `(A + R) λ + b` at `lambda` (PGS forms them from the
/// Wᵀλ its sweeps keep); else the step forms them. λ needs no step if its exact residual is
/// within `converged` (≥ `good_enough`, PGS's residual goal); the step's Newton rounds aim at
/// `good_enough`.
///
/// The reduced solve is a direction, followed as far as the active set allows (a primal
/// active-set step): when a free impulse would leave its set on the way — a pressing normal
/// reaching zero, a sticking contact reaching its cone, a row reaching its bound — the step stops
/// there, that impulse joins its bound (the contact now slides in the direction it arrived
/// with), and the system is solved again, at most `MAX_ROUNDS` times. A wrong guess of PGS
/// (all four corners of a foot sticking where two must slip) makes the system inconsistent and
/// its solution huge along the contact set's internal-force directions, which are exactly where
/// PGS creeps; the first blocking impulse then ends that step at the right active set.
pub(crate) fn subspace_step(
    problem: &ConstraintProblem,
    lambda: &DVector<f64>,
    velocities: Option<&[f64]>,
    ws: &mut SubspaceWorkspace,
    good_enough: f64,
    converged: f64,
) -> SubspaceOutcome {
    let n = problem.rows();
    ws.start_residual = f64::INFINITY;
    if n > MAX_SUBSPACE {
        return SubspaceOutcome::Skipped;
    }
    ws.reserve(n);
    let current = match velocities {
        Some(w) => {
            ws.w.as_mut_slice().copy_from_slice(w);
            residuals_at_velocities(problem, lambda, w)
        }
        None => residuals(problem, lambda, &mut ws.w),
    };
    ws.residuals = None;
    ws.sum_valid = false;
    ws.rounds = 0;
    ws.start_residual = current.exact();
    ws.released = None;
    ws.release_refused.clear();
    if current.exact() <= converged {
        let exact = current.exact();
        ws.residuals = Some(current);
        return SubspaceOutcome::Converged(exact);
    }
    let current = current.exact();
    let mut candidate = std::mem::replace(&mut ws.candidate, DVector::zeros(0));
    candidate.copy_from(lambda);
    // NNCG's extrapolation may have left the feasible set.
    project(problem, &mut candidate);
    if !active_units(problem, &mut candidate, ws, GUESS_ON_PYRAMID) {
        ws.candidate = candidate;
        return SubspaceOutcome::Skipped;
    }
    // Only the rows the units touch move or are read: A + R over them, w kept up to date
    // from their changes (the other rows' λ stay as they are).
    ws.local.clear();
    ws.local.resize(n, usize::MAX);
    ws.rows.clear();
    for unit in &ws.units {
        for r in unit.column().map(|(r, _)| r).into_iter().chain(unit.equation().map(|(r, _)| r)) {
            if ws.local[r] == usize::MAX {
                ws.local[r] = ws.rows.len();
                ws.rows.push(r);
            }
        }
    }
    fill_gram(problem, ws);
    let m = ws.rows.len();
    // ws.w holds the velocities at λ: still those of the candidate unless the projection or
    // the placement of contacts on their cone or pyramid moved it. From here on only w over
    // the rows is read (the residuals at the end form all of it afresh): when every moved
    // impulse is one of the rows, (A + R) over them gives the change, where forming w again
    // takes two passes over W (ragdoll landings: after 553 of 807 placements).
    if candidate != *lambda {
        let among_rows = (0..n).all(|i| candidate[i] == lambda[i] || ws.local[i] != usize::MAX);
        if among_rows {
            ws.delta.clear();
            ws.delta.extend(ws.rows.iter().map(|&r| candidate[r] - lambda[r]));
            for a in 0..m {
                let change = crate::math::dot(&ws.gram[a * m..(a + 1) * m], &ws.delta);
                ws.w[ws.rows[a]] += change;
            }
        } else {
            problem.velocities(&candidate, &mut ws.w);
        }
    }
    ws.start.clear();
    ws.start.extend(ws.rows.iter().map(|&r| candidate[r]));
    ws.w_start.clear();
    ws.w_start.extend(ws.rows.iter().map(|&r| ws.w[r]));
    let mut solved = false;
    let mut reached = None;
    let max_rounds = match problem.friction {
        FrictionModel::Cone => MAX_ROUNDS,
        FrictionModel::Pyramid { .. } => MAX_PYRAMID_ROUNDS,
    };
    for round in 0..max_rounds {
        // The units only lose rows between rounds (an impulse reaching its bound leaves them),
        // so the first round's rows cover every later one.
        if round > 0 {
            ws.delta.clear();
            ws.delta.extend(ws.rows.iter().zip(&ws.start).map(|(&r, l0)| candidate[r] - l0));
            for a in 0..m {
                let g = &ws.gram[a * m..(a + 1) * m];
                let change: f64 = g.iter().zip(&ws.delta).map(|(g, d)| g * d).sum();
                ws.w[ws.rows[a]] = ws.w_start[a] + change;
            }
            if !active_units(problem, &mut candidate, ws, ON_CONE) {
                break;
            }
        }
        ws.rounds += 1;
        if !reduced_solve(ws) {
            break;
        }
        solved = true;
        let (alpha, blocking) = step_length(problem, &candidate, ws);
        if alpha <= ZERO_STEP {
            if let Some((row, _)) = ws.released {
                ws.release_refused.push(row);
            }
        }
        ws.released = None;
        let mut turn: f64 = 0.0;
        for (k, (unit, x)) in ws.units.iter().zip(&ws.x).enumerate() {
            match *unit {
                Unit::Row(i) => candidate[i] += alpha * x,
                Unit::Slide(c) => {
                    let normal = (c.lambda_n + alpha * x).max(0.0);
                    let angle = match ws.units.get(k + 1) {
                        Some(Unit::Angle(_)) => alpha * ws.x[k + 1],
                        _ => 0.0,
                    };
                    turn = turn.max(angle.abs());
                    let (sin_d, cos_d) = angle.sin_cos();
                    let (cos, sin) = (c.cos * cos_d - c.sin * sin_d, c.sin * cos_d + c.cos * sin_d);
                    candidate[c.normal] = normal;
                    candidate[c.t1] = normal * c.mu[0] * cos;
                    candidate[c.t2] = normal * c.mu[1] * sin;
                }
                Unit::Angle(_) => {}
                // Linear in their unknowns: λ moves along the column.
                Unit::Facet(_) | Unit::Along(_) | Unit::Corner(_) => {
                    for (row, coefficient) in unit.column() {
                        candidate[row] += alpha * x * coefficient;
                    }
                }
            }
        }
        match blocking {
            // Exact on this active set (up to the direction's Newton step).
            Blocking::None if turn <= NEWTON_TURN => {
                if !release_pyramid_contacts(problem, &candidate, ws, good_enough) {
                    break;
                }
            }
            Blocking::None | Blocking::Turn => {}
            // Exactly onto the bound, so that the next round classifies it there.
            Blocking::Zero(row) => {
                candidate[row] = 0.0;
                if let Some(c) = contact_of_normal(problem, row) {
                    let (_, t1, t2) = problem.contacts[c].rows();
                    candidate[t1] = 0.0;
                    candidate[t2] = 0.0;
                }
            }
            Blocking::Bound(row, value) => candidate[row] = value,
            Blocking::Cone | Blocking::Vertex => {}
        }
        project(problem, &mut candidate);
        if blocking == Blocking::None {
            // Another Newton round on the sliding directions would follow: stop once the iterate
            // is good enough (a residual costs a product with A, a round a reduced factorisation;
            // the humanoid's sliding feet needed a third round only to shrink the turn to 1e-10).
            let r = candidate_residuals(problem, &candidate, ws);
            if r.exact() <= NEWTON_STOP * good_enough {
                reached = Some(r);
                break;
            }
        }
    }
    // (A candidate whose residuals were just computed was projected right before.)
    if reached.is_none() {
        project(problem, &mut candidate);
    }
    ws.candidate = candidate;
    if !solved {
        return SubspaceOutcome::Skipped;
    }
    let reached = match reached {
        Some(r) => r,
        None => {
            let candidate = std::mem::replace(&mut ws.candidate, DVector::zeros(0));
            let r = candidate_residuals(problem, &candidate, ws);
            ws.candidate = candidate;
            r
        }
    };
    let exact = reached.exact();
    ws.residuals = Some(reached);
    if exact < current {
        SubspaceOutcome::Accepted(exact)
    } else {
        SubspaceOutcome::Rejected(exact)
    }
}

/// The residuals of `candidate` (velocities into `ws.w`), keeping Wᵀ `candidate` in
/// `ws.candidate_sum`.
fn candidate_residuals(
    problem: &ConstraintProblem,
    candidate: &DVector<f64>,
    ws: &mut SubspaceWorkspace,
) -> super::Residuals {
    ws.sum_valid = problem.velocities_with_sum(candidate, &mut ws.w, &mut ws.candidate_sum);
    residuals_at_velocities(problem, candidate, ws.w.as_slice())
}

/// Most entries of the lane copy of W's rows that [`fill_gram`] makes (rows × velocity
/// columns): beyond it (hundreds of multibodies in one world) the Gram is formed entry by entry.
const MAX_DENSE_W: usize = 1 << 16;

/// Rows of W packed side by side as the lanes of one group in [`fill_gram`].
const GROUP: usize = 4;

/// A + R over `ws.rows` into `ws.gram`. When A is matrix-free: W's rows grouped, up to
/// [`GROUP`] consecutive rows with the same column range (a contact's normal and tangent rows
/// act on the same bodies), each group copied as lanes (`w_lanes[col]` holds its rows' entries
/// in that column), and each block of the Gram between two groups one pass over the overlap of
/// their runs per row of the first group ([`gram_block`]), each column adding that row's entry
/// times the other group's four — up to sixteen products per column pair of lanes, where one dot
/// product per pair of rows loaded them once per pair (a humanoid episode's subspace steps
/// formed 666 short dots per step). Else (A formed, or a world too wide for the copy) entry by
/// entry.
fn fill_gram(problem: &ConstraintProblem, ws: &mut SubspaceWorkspace) {
    let m = ws.rows.len();
    // Every entry is written below (a block of two groups that share no column as zeros): no
    // clearing of the m² entries first.
    ws.gram.resize(m * m, 0.0);
    let sp = &problem.sparsity;
    let nv = sp.nv;
    if problem.is_matrix_free() && m * nv <= MAX_DENSE_W {
        // Each row's column range [lo, hi) (empty: lo = hi).
        ws.w_range.clear();
        for &r in &ws.rows {
            let (mut lo, mut hi) = (nv, 0);
            for (col, w) in sp.row_spans(r) {
                lo = lo.min(col);
                hi = hi.max(col + w.len());
            }
            ws.w_range.push(if lo < hi { (lo, hi) } else { (0, 0) });
        }
        // Groups: (first row, rows, offset of its lanes in `w_lanes`), and each group's runs:
        // those of its rows when they all have the same (a contact's three rows do), else its
        // whole range.
        ws.groups.clear();
        ws.w_lanes.clear();
        ws.group_runs.clear();
        ws.group_run_start.clear();
        let runs_of = |r: usize| sp.row_spans(r).map(|(col, w)| (col, col + w.len()));
        let mut a = 0;
        while a < m {
            let range = ws.w_range[a];
            let mut count = 1;
            while count < GROUP && a + count < m && ws.w_range[a + count] == range {
                count += 1;
            }
            let offset = ws.w_lanes.len();
            ws.w_lanes.resize(offset + range.1 - range.0, [0.0; GROUP]);
            for lane in 0..count {
                for (col, w) in sp.row_spans(ws.rows[a + lane]) {
                    let at = offset + col - range.0;
                    for (x, v) in ws.w_lanes[at..at + w.len()].iter_mut().zip(w) {
                        x[lane] = *v;
                    }
                }
            }
            ws.group_run_start.push(ws.group_runs.len());
            let first = ws.rows[a];
            if (1..count).all(|lane| runs_of(ws.rows[a + lane]).eq(runs_of(first))) {
                let at = ws.group_runs.len();
                ws.group_runs.extend(runs_of(first));
                // Increasing within each multibody's block; a row on two multibodies lists its
                // blocks in the contact's order.
                ws.group_runs[at..].sort_unstable();
            } else if range.0 < range.1 {
                ws.group_runs.push(range);
            }
            ws.groups.push((a, count, offset));
            a += count;
        }
        ws.group_run_start.push(ws.group_runs.len());
        for (g, &(a, count_a, offset_a)) in ws.groups.iter().enumerate() {
            let lo_a = ws.w_range[a].0;
            let runs_a = &ws.group_runs[ws.group_run_start[g]..ws.group_run_start[g + 1]];
            for (h, &(b, count_b, offset_b)) in ws.groups.iter().enumerate().skip(g) {
                let lo_b = ws.w_range[b].0;
                let runs_b = &ws.group_runs[ws.group_run_start[h]..ws.group_run_start[h + 1]];
                let mut block = [[0.0; GROUP]; GROUP];
                // Only where both groups' runs overlap: elsewhere one side is zero (a left
                // foot's rows and a right foot's share the root's columns, not the legs'), and
                // the products skipped are exact zeros, so the sums are those over the whole
                // range, to the bit.
                let (mut i, mut j) = (0, 0);
                while i < runs_a.len() && j < runs_b.len() {
                    let (from, to) = (runs_a[i].0.max(runs_b[j].0), runs_a[i].1.min(runs_b[j].1));
                    if from < to {
                        let ua = &ws.w_lanes[offset_a + from - lo_a..offset_a + to - lo_a];
                        let ub = &ws.w_lanes[offset_b + from - lo_b..offset_b + to - lo_b];
                        gram_block(ua, ub, count_a, &mut block);
                    }
                    if runs_a[i].1 <= runs_b[j].1 {
                        i += 1;
                    } else {
                        j += 1;
                    }
                }
                for (i, row) in block.iter().enumerate().take(count_a) {
                    for (j, &value) in row.iter().enumerate().take(count_b) {
                        ws.gram[(a + i) * m + b + j] = value;
                        ws.gram[(b + j) * m + a + i] = value;
                    }
                }
            }
        }
    } else {
        for a in 0..m {
            for b in a..m {
                let g = problem.delassus_entry(ws.rows[a], ws.rows[b]);
                ws.gram[a * m + b] = g;
                ws.gram[b * m + a] = g;
            }
        }
    }
    for (a, &r) in ws.rows.iter().enumerate() {
        ws.gram[a * m + a] += problem.regularization[r];
    }
}

/// Adds to `block[i][j]` the products of lane i of `ua` (group a's rows, `count_a` of them)
/// and lane j of `ub` over the columns both cover, column by column. One pass per two rows of
/// group a (a contact's group has three): each pass keeps each row's four sums in one vector
/// register, where the 4 × 4 block updated per column made the compiler shuffle x and y into
/// 8-wide vectors (and three rows per pass cost more instructions than two).
fn gram_block(ua: &[[f64; GROUP]], ub: &[[f64; GROUP]], count_a: usize, block: &mut [[f64; GROUP]; GROUP]) {
    let mut i = 0;
    while i + 1 < count_a {
        // Two rows of group a per pass: each y loaded once for both.
        let (first, second) = block.split_at_mut(i + 1);
        let (row0, row1) = (&mut first[i], &mut second[0]);
        for (x, y) in ua.iter().zip(ub) {
            let (x0, x1) = (x[i], x[i + 1]);
            for ((acc0, acc1), &yj) in row0.iter_mut().zip(row1.iter_mut()).zip(y) {
                *acc0 += x0 * yj;
                *acc1 += x1 * yj;
            }
        }
        i += 2;
    }
    if i < count_a {
        let row = &mut block[i];
        for (x, y) in ua.iter().zip(ub) {
            let xi = x[i];
            for (acc, &yj) in row.iter_mut().zip(y) {
                *acc += xi * yj;
            }
        }
    }
}

/// Rounds of solve-and-block (and Newton steps on sliding directions) per subspace step.
const MAX_ROUNDS: usize = 8;

/// The same with pyramid friction: a round only moves one contact across a vertex or off a
/// facet ([`release_pyramid_contacts`]), and its solve is exact (no Newton step to repeat), so
/// more rounds are worth their reduced solves (a cold nine-contact humanoid step: 64 sweeps with
/// 8 rounds, 16 with 16).
const MAX_PYRAMID_ROUNDS: usize = 16;

/// A step this short undid the release that preceded it: rounding leaves α ≈ 1e-18 where a
/// degenerate contact set blocks at zero, and a release refused only at exactly zero cycled
/// through all rounds (the ragdoll's 16 unconverged steps in a row: 16 rounds each, not 6).
const ZERO_STEP: f64 = 1e-12;

/// Largest turn of a sliding direction per round (rad): Newton's step on θ is cut there.
const MAX_TURN: f64 = 0.5;

/// A Newton round whose iterate's residual is below this share of the tolerance ends the step
/// (far enough below that the next step's warm start is as good as an exact one).
const NEWTON_STOP: f64 = 1e-3;

/// A round whose full step turns no direction more than this (rad) ends the step.
const NEWTON_TURN: f64 = 1e-10;

/// What ends a step early.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Blocking {
    /// Nothing: the full step is feasible.
    None,
    /// The impulse of this row (a normal: with its tangents) reaches zero.
    Zero(usize),
    /// This row reaches this bound.
    Bound(usize, f64),
    /// A sticking contact reaches its cone or pyramid (the projection puts it exactly there).
    Cone,
    /// A contact on a facet of its pyramid reaches a vertex.
    Vertex,
    /// A sliding direction would turn more than `MAX_TURN`.
    Turn,
}

/// K and −g over `ws.units` from the Gram matrix over `ws.rows` and `ws.w`, solved into `ws.x`; false
/// if the factorisation fails.
fn reduced_solve(ws: &mut SubspaceWorkspace) -> bool {
    let s = ws.units.len();
    let m = ws.rows.len();
    if s > MAX_SUBSPACE || m == 0 {
        return false;
    }
    // (A + R) times each unit's column over the rows (m per unit), then K[u][v] as the unit
    // u's equation applied to it.
    // (Both are written in full below: no clearing first.)
    ws.gc.resize(s * m, 0.0);
    for v in 0..s {
        let out = &mut ws.gc[v * m..(v + 1) * m];
        // Zero coefficients may name rows outside `rows` (a tangent with μ = 0).
        let mut terms = ws.units[v].column().into_iter().filter(|(_, b)| *b != 0.0);
        // Gram is symmetric: its row c is its column c.
        let gram_row = |c: usize| &ws.gram[ws.local[c] * m..(ws.local[c] + 1) * m];
        match terms.next() {
            Some((c, b)) => {
                for (o, g) in out.iter_mut().zip(gram_row(c)) {
                    *o = b * g;
                }
            }
            None => out.fill(0.0),
        }
        for (c, b) in terms {
            for (o, g) in out.iter_mut().zip(gram_row(c)) {
                *o += b * g;
            }
        }
    }
    ws.k.resize(s * s, 0.0);
    ws.rhs.clear();
    let mut largest: f64 = 0.0;
    for u in 0..s {
        let equation = ws.units[u].equation();
        // The equation's terms with a non-zero coefficient, by local row (a zero coefficient
        // may name a row outside `rows`); K's row u is then one or two strided reads of gc
        // per entry, with no lookup of the rows inside the loop over v.
        let mut terms = [(0usize, 0.0f64); 2];
        let mut count = 0;
        for &(r, a) in equation.iter().filter(|(_, a)| *a != 0.0) {
            terms[count] = (ws.local[r], a);
            count += 1;
        }
        let k_row = &mut ws.k[u * s..(u + 1) * s];
        let gc = ws.gc.chunks_exact(m);
        match count {
            1 => {
                let (l, a) = terms[0];
                for (k, gc) in k_row.iter_mut().zip(gc) {
                    *k = a * gc[l];
                }
            }
            2 => {
                let ((l0, a0), (l1, a1)) = (terms[0], terms[1]);
                for (k, gc) in k_row.iter_mut().zip(gc) {
                    *k = a0 * gc[l0] + a1 * gc[l1];
                }
            }
            _ => k_row.fill(0.0),
        }
        let g: f64 = equation.iter().map(|&(r, a)| a * ws.w[r]).sum();
        if let Unit::Angle(c) = ws.units[u] {
            // ∂g/∂θ at fixed w: −(cos θ m₁ + sin θ m₂) (= ‖m‖ when friction opposes slip).
            ws.k[u * s + u] -= c.cos * c.mu[0] * ws.w[c.t1] + c.sin * c.mu[1] * ws.w[c.t2];
        }
        largest = largest.max(ws.k[u * s + u].abs());
        ws.rhs.push(-g);
    }
    if largest <= 0.0 || !largest.is_finite() {
        return false;
    }
    let epsilon = PROXIMAL * largest;
    let shifted_k = |lu: &mut Vec<f64>| {
        lu.clear();
        lu.extend_from_slice(&ws.k);
        for u in 0..s {
            lu[u * s + u] += epsilon;
        }
    };
    shifted_k(&mut ws.lu);
    // Only free rows (no contact on its cone, facet or vertex): K is A + R over them,
    // symmetric and positive semi-definite, and K + εI is factored by Cholesky at half the
    // LU's cost; if rounding makes a pivot non-positive, by LU after all.
    let symmetric = ws.units.iter().all(|unit| matches!(unit, Unit::Row(_)));
    let cholesky = symmetric && cholesky_factor(&mut ws.lu, s);
    if !cholesky {
        if symmetric {
            shifted_k(&mut ws.lu);
        }
        if !lu_factor(&mut ws.lu, &mut ws.pivots, s) {
            return false;
        }
    }
    let solve = |lu: &[f64], pivots: &[usize], x: &mut [f64]| {
        if cholesky {
            cholesky_solve(lu, s, x);
        } else {
            lu_solve(lu, pivots, s, x);
        }
    };
    // Proximal iteration x ← x + (K + εI)⁻¹ (r − K x), from x = 0: its first step is the
    // plain solve.
    ws.x.clear();
    ws.x.extend_from_slice(&ws.rhs);
    solve(&ws.lu, &ws.pivots, &mut ws.x);
    for _ in 1..REFINEMENTS {
        ws.correction.clear();
        for u in 0..s {
            let kx: f64 = crate::math::dot(&ws.k[u * s..(u + 1) * s], &ws.x);
            ws.correction.push(ws.rhs[u] - kx);
        }
        solve(&ws.lu, &ws.pivots, &mut ws.correction);
        for (x, d) in ws.x.iter_mut().zip(&ws.correction) {
            *x += d;
        }
    }
    ws.x.iter().all(|x| x.is_finite())
}

/// The longest step α ≤ 1 along `ws.x` that keeps every free impulse in its set, and what
/// blocks it.
fn step_length(
    problem: &ConstraintProblem,
    lambda: &DVector<f64>,
    ws: &SubspaceWorkspace,
) -> (f64, Blocking) {
    let (mut alpha, mut blocking) = (1.0, Blocking::None);
    let mut limit = |a: f64, b: Blocking| {
        if a < alpha {
            alpha = a.max(0.0);
            blocking = b;
        }
    };
    for (k, (unit, &x)) in ws.units.iter().zip(&ws.x).enumerate() {
        match *unit {
            Unit::Slide(c) => {
                if x < 0.0 {
                    limit(c.lambda_n / -x, Blocking::Zero(c.normal));
                }
            }
            Unit::Angle(_) => {
                if x.abs() > MAX_TURN {
                    limit(MAX_TURN / x.abs(), Blocking::Turn);
                }
            }
            Unit::Facet(OnFacet { normal, .. }) | Unit::Corner(AtVertex { normal, .. }) => {
                if x < 0.0 {
                    limit(lambda[normal] / -x, Blocking::Zero(normal));
                }
            }
            Unit::Along(f) => {
                // |τ + α x| = half (λ_n + α x_n), with x_n the facet's normal unit (right before).
                let x_n = ws.x[k - 1];
                let e = f.e();
                let scaled = [lambda[f.t1] / f.mu[0], lambda[f.t2] / f.mu[1]];
                let tau = e[0] * scaled[0] + e[1] * scaled[1];
                let reach = f.half * lambda[f.normal];
                for sign in [1.0, -1.0] {
                    // sign (τ + α x) = half (λ_n + α x_n): α (sign x − half x_n) = reach − sign τ.
                    let rate = sign * x - f.half * x_n;
                    if rate > 0.0 {
                        limit((reach - sign * tau) / rate, Blocking::Vertex);
                    }
                }
            }
            Unit::Row(row) => {
                let l = lambda[row];
                match problem.laws[row] {
                    RowLaw::Unilateral => {
                        if x < 0.0 {
                            limit(l / -x, Blocking::Zero(row));
                        }
                        // A sticking contact: its tangents are the next units (see `active_units`).
                        if let Some(c) = contact_of_normal(problem, row).map(|c| &problem.contacts[c]) {
                            let (_, t1, t2) = c.rows();
                            let mut d = [0.0; 2];
                            for (unit, &dx) in ws.units[k + 1..].iter().zip(&ws.x[k + 1..]).take(2) {
                                match *unit {
                                    Unit::Row(t) if t == t1 => d[0] = dx,
                                    Unit::Row(t) if t == t2 => d[1] = dx,
                                    _ => {}
                                }
                            }
                            let scaled = |v: f64, mu: f64| if mu > 0.0 { v / mu } else { 0.0 };
                            let s0 = [scaled(lambda[t1], c.mu), scaled(lambda[t2], c.mu2)];
                            let ds = [scaled(d[0], c.mu), scaled(d[1], c.mu2)];
                            match problem.friction {
                                FrictionModel::Cone => {
                                    // ‖s0 + α ds‖² = (l + α x)²: the first positive root.
                                    let qa = ds[0] * ds[0] + ds[1] * ds[1] - x * x;
                                    let qb = 2.0 * (s0[0] * ds[0] + s0[1] * ds[1] - l * x);
                                    let qc = s0[0] * s0[0] + s0[1] * s0[1] - l * l;
                                    if let Some(root) = first_positive_root(qa, qb, qc) {
                                        limit(root, Blocking::Cone);
                                    }
                                }
                                FrictionModel::Pyramid { facets } => {
                                    // n_j·(s0 + α ds) = offset (l + α x) on the first facet met.
                                    let offset = pyramid_offset_and_half(facets).0;
                                    for j in 0..facets {
                                        let (nx, ny) = pyramid_facet(facets, j);
                                        let rate = nx * ds[0] + ny * ds[1] - offset * x;
                                        if rate > 0.0 {
                                            let room = offset * l - (nx * s0[0] + ny * s0[1]);
                                            limit(room / rate, Blocking::Cone);
                                        }
                                    }
                                }
                            }
                        }
                    }
                    RowLaw::Bounded { lo, hi } => {
                        if x < 0.0 && lo.is_finite() {
                            limit((l - lo) / -x, Blocking::Bound(row, lo));
                        } else if x > 0.0 && hi.is_finite() {
                            limit((hi - l) / x, Blocking::Bound(row, hi));
                        }
                    }
                    RowLaw::Bilateral | RowLaw::Friction { .. } => {}
                }
            }
        }
    }
    (alpha, blocking)
}

/// The smallest positive root of `a t² + b t + c` with `c < 0` (the path starts inside), if any.
fn first_positive_root(a: f64, b: f64, c: f64) -> Option<f64> {
    if c >= 0.0 {
        return Some(0.0);
    }
    if a.abs() <= 1e-300 {
        return (b > 0.0).then(|| -c / b);
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    // Stable roots: q = −(b + sign(b) √disc)/2, t = q/a and c/q.
    let q = -0.5 * (b + b.signum() * sq);
    let roots = [if q != 0.0 { c / q } else { f64::INFINITY }, q / a];
    roots
        .into_iter()
        .filter(|t| *t > 0.0 && t.is_finite())
        .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.min(t))))
}

/// Fills `ws.units` with PGS's active set at `lambda` (a sticking contact's normal is followed
/// by its tangents, a sliding one's by its direction, whose tangents it puts exactly on the
/// cone); false if nothing is free. A pyramid contact within `on_pyramid` (relative) of its
/// pyramid's boundary is put on it.
fn active_units(
    problem: &ConstraintProblem,
    lambda: &mut DVector<f64>,
    ws: &mut SubspaceWorkspace,
    on_pyramid: f64,
) -> bool {
    let n = problem.rows();
    ws.units.clear();
    ws.contact_row.clear();
    ws.contact_row.resize(n, false);
    for c in &problem.contacts {
        let (nr, t1, t2) = c.rows();
        ws.contact_row[nr] = true;
        ws.contact_row[t1] = true;
        ws.contact_row[t2] = true;
        let normal = lambda[nr];
        if normal <= 0.0 {
            continue; // Separating: every impulse stays zero.
        }
        let scaled = |l: f64, mu: f64| if mu > 0.0 { l / mu } else { 0.0 };
        let (s1, s2) = (scaled(lambda[t1], c.mu), scaled(lambda[t2], c.mu2));
        if let FrictionModel::Pyramid { facets } = problem.friction {
            if (c.mu > 0.0) != (c.mu2 > 0.0) {
                return false; // A pyramid squeezed to a segment: not handled.
            }
            let release = ws.released.filter(|(row, _)| *row == nr).map(|(_, facet)| facet);
            let units = match release {
                Some(None) => None,
                Some(Some(j)) => {
                    let facet = on_facet(c, facets, j);
                    Some((Unit::Facet(facet), Some(Unit::Along(facet))))
                }
                None => pyramid_units(c, facets, normal, [s1, s2], on_pyramid),
            };
            if let Some((first, along)) = units {
                let (v1, v2) = match first {
                    Unit::Corner(v) => (normal * v.v[0], normal * v.v[1]),
                    Unit::Facet(f) => {
                        // Exactly onto the facet, keeping the position along it.
                        let (e, along) = (f.e(), f.e()[0] * s1 + f.e()[1] * s2);
                        let base = f.offset * normal;
                        (base * f.n[0] + along * e[0], base * f.n[1] + along * e[1])
                    }
                    _ => unreachable!("pyramid_units returns a Corner or a Facet first"),
                };
                lambda[t1] = c.mu * v1;
                lambda[t2] = c.mu2 * v2;
                ws.units.push(first);
                ws.units.extend(along);
                continue;
            }
        }
        let reach = norm2(s1, s2);
        if problem.friction == FrictionModel::Cone
            && c.mu.max(c.mu2) > 0.0
            && reach > 0.0
            && reach >= (1.0 - ON_CONE) * normal
        {
            let (cos, sin) = (s1 / reach, s2 / reach);
            lambda[t1] = normal * c.mu * cos;
            lambda[t2] = normal * c.mu2 * sin;
            let sliding = Sliding { normal: nr, t1, t2, mu: [c.mu, c.mu2], lambda_n: normal, cos, sin };
            ws.units.push(Unit::Slide(sliding));
            // With one coefficient zero the direction is only a sign.
            if c.mu > 0.0 && c.mu2 > 0.0 {
                ws.units.push(Unit::Angle(sliding));
            }
        } else {
            ws.units.push(Unit::Row(nr));
            for (t, mu) in [(t1, c.mu), (t2, c.mu2)] {
                if mu > 0.0 {
                    ws.units.push(Unit::Row(t));
                }
            }
        }
    }
    for i in 0..n {
        if ws.contact_row[i] {
            continue;
        }
        let free = match problem.laws[i] {
            RowLaw::Bilateral => true,
            RowLaw::Unilateral => lambda[i] > 0.0,
            RowLaw::Bounded { lo, hi } => lo < lambda[i] && lambda[i] < hi,
            RowLaw::Friction { .. } => false, // Owned by a contact (checked by `check_problem`).
        };
        if free {
            ws.units.push(Unit::Row(i));
        }
    }
    !ws.units.is_empty()
}

/// The units of a contact on the boundary of its friction pyramid (k facets) at scaled tangent
/// impulse `s` and normal impulse `normal` > 0, within `tolerance` (relative) of a facet or a
/// vertex: `(Corner, None)` at a vertex, `(Facet, Some(Along))` on a facet; `None` inside
/// (sticking) or frictionless.
fn pyramid_units(
    c: &crate::constraints::ContactBlock,
    facets: usize,
    normal: f64,
    s: [f64; 2],
    tolerance: f64,
) -> Option<(Unit, Option<Unit>)> {
    if c.mu <= 0.0 {
        return None;
    }
    let offset = pyramid_offset_and_half(facets).0;
    let (mut best, mut reach) = (0, f64::NEG_INFINITY);
    for j in 0..facets {
        let (nx, ny) = pyramid_facet(facets, j);
        let r = nx * s[0] + ny * s[1];
        if r > reach {
            (best, reach) = (j, r);
        }
    }
    if reach < (1.0 - tolerance) * offset * normal {
        return None;
    }
    let facet = on_facet(c, facets, best);
    let e = facet.e();
    let tau = e[0] * s[0] + e[1] * s[1];
    // Facet j runs from vertex j (τ = −half λ_n) to vertex j + 1 (τ = +half λ_n).
    if tau.abs() >= (1.0 - tolerance) * facet.half * normal {
        let vertex = if tau > 0.0 { best + 1 } else { best };
        let index = vertex % facets;
        let (vx, vy) = pyramid_vertex(facets, index);
        let corner =
            AtVertex { normal: facet.normal, t1: facet.t1, t2: facet.t2, mu: facet.mu, index, v: [vx, vy] };
        return Some((Unit::Corner(corner), None));
    }
    Some((Unit::Facet(facet), Some(Unit::Along(facet))))
}

/// Contact `c` on facet `j` of its friction pyramid (k facets).
fn on_facet(c: &crate::constraints::ContactBlock, facets: usize, j: usize) -> OnFacet {
    let (nx, ny) = pyramid_facet(facets, j % facets);
    let (normal, t1, t2) = c.rows();
    let (offset, half) = pyramid_offset_and_half(facets);
    OnFacet { normal, t1, t2, mu: [c.mu, c.mu2], n: [nx, ny], offset, half }
}

/// After a round that solved its active set exactly: the pyramid contact whose slip says the
/// active set is most wrong, put into `ws.released` for the next round, and whether there is one.
/// At a vertex, the slip `m = (μ₁ w₁, μ₂ w₂)` must not decrease `m·s` along either facet
/// leaving it (else maximum dissipation moves the impulse along that facet); on a facet, the
/// slip must oppose the facet's outward normal, `m = −γ n` with γ ≥ 0 (else the contact
/// sticks). Without this a
/// contact that passes a vertex on its way to the next facet stays at the vertex, and the
/// reduced solve is inconsistent for every later round.
fn release_pyramid_contacts(
    problem: &ConstraintProblem,
    candidate: &DVector<f64>,
    ws: &mut SubspaceWorkspace,
    tolerance: f64,
) -> bool {
    let FrictionModel::Pyramid { facets } = problem.friction else { return false };
    let m = ws.rows.len();
    // Row velocities at the candidate: ws.w is that of the round's start.
    let velocity = |ws: &SubspaceWorkspace, row: usize| {
        let a = ws.local[row];
        let g = &ws.gram[a * m..(a + 1) * m];
        ws.w_start[a]
            + g.iter().zip(&ws.rows).zip(&ws.start).map(|((g, &r), l0)| g * (candidate[r] - l0)).sum::<f64>()
    };
    // The largest violation only (by its rate of change of dissipation, m/s): releasing every
    // violator at once moves contacts whose violation is only the others' doing.
    let mut worst = (0.0, 0, None);
    for k in 0..ws.units.len() {
        let (normal, t1, t2, mu) = match ws.units[k] {
            Unit::Facet(f) => (f.normal, f.t1, f.t2, f.mu),
            Unit::Corner(c) => (c.normal, c.t1, c.t2, c.mu),
            _ => continue,
        };
        if ws.release_refused.contains(&normal) {
            continue;
        }
        let slip = [mu[0] * velocity(ws, t1), mu[1] * velocity(ws, t2)];
        // A slip within the tolerance says nothing (a contact resting on its pyramid's edge).
        let scale = slip[0].abs().max(slip[1].abs());
        if scale <= tolerance {
            continue;
        }
        match ws.units[k] {
            Unit::Facet(f) => {
                let rate = slip[0] * f.n[0] + slip[1] * f.n[1];
                if rate > ON_CONE * scale && rate > worst.0 {
                    worst = (rate, normal, None);
                }
            }
            Unit::Corner(c) => {
                // Vertex i lies between facet i − 1 (its end, leaving along −e) and facet i
                // (its start, leaving along +e).
                let (before, after) = ((c.index + facets - 1) % facets, c.index);
                let rate = |j: usize, sign: f64| {
                    let (nx, ny) = pyramid_facet(facets, j);
                    sign * (-ny * slip[0] + nx * slip[1])
                };
                let (r_before, r_after) = (rate(before, -1.0), rate(after, 1.0));
                let best = if r_before < r_after { (before, r_before) } else { (after, r_after) };
                if best.1 < -ON_CONE * scale && -best.1 > worst.0 {
                    worst = (-best.1, normal, Some(best.0));
                }
            }
            _ => {}
        }
    }
    ws.released = (worst.0 > 0.0).then_some((worst.1, worst.2));
    ws.released.is_some()
}

/// Projects λ onto the feasible set: λ ≥ 0 on unilateral rows, into the box on bounded rows,
/// into the cone of the (projected) normal impulse on contacts.
fn project(problem: &ConstraintProblem, lambda: &mut DVector<f64>) {
    for i in 0..problem.rows() {
        match problem.laws[i] {
            RowLaw::Unilateral => lambda[i] = lambda[i].max(0.0),
            RowLaw::Bounded { lo, hi } => lambda[i] = lambda[i].clamp(lo, hi),
            RowLaw::Bilateral | RowLaw::Friction { .. } => {}
        }
    }
    for c in &problem.contacts {
        let (nr, t1, t2) = c.rows();
        (lambda[t1], lambda[t2]) =
            project_friction(lambda[t1], lambda[t2], lambda[nr], c.mu, c.mu2, problem.friction);
    }
}

/// In-place LU factorisation with partial pivoting of the row-major s × s matrix `a`; false if
/// a pivot vanishes. Two columns per pass over the trailing rows: column `col`'s multipliers
/// update only column `col + 1` first (enough to choose its pivot and finish its pivot row),
/// then each row below takes both rank-1 updates in one pass, `x − f₁ u₁ − f₂ u₂` in the
/// order of two single passes — the same factors to the bit, with half the passes (the
/// reduced systems are small: ~40 unknowns, rows too short for the per-row work to vanish).
fn lu_factor(a: &mut [f64], pivots: &mut Vec<usize>, s: usize) -> bool {
    pivots.clear();
    // Picks the pivot of column `col` among rows col.. and swaps it into row col; its inverse.
    let pivot = |a: &mut [f64], pivots: &mut Vec<usize>, col: usize| {
        let (mut best, mut best_abs) = (col, a[col * s + col].abs());
        for r in col + 1..s {
            let v = a[r * s + col].abs();
            if v > best_abs {
                (best, best_abs) = (r, v);
            }
        }
        if best_abs <= 0.0 || !best_abs.is_finite() {
            return None;
        }
        pivots.push(best);
        if best != col {
            let (upper, lower) = a.split_at_mut(best * s);
            upper[col * s..(col + 1) * s].swap_with_slice(&mut lower[..s]);
        }
        // One division per column, not one per entry below the pivot: a division's throughput
        // is that of several vector multiply-adds.
        Some(1.0 / a[col * s + col])
    };
    let mut col = 0;
    while col < s {
        let Some(inverse_first) = pivot(a, pivots, col) else { return false };
        if col + 1 == s {
            break;
        }
        // Multipliers of column col, applied to column col + 1 only.
        let next = col + 1;
        let upper_right = a[col * s + next];
        for row in a[next * s..].chunks_exact_mut(s) {
            let factor = row[col] * inverse_first;
            row[col] = factor;
            if factor != 0.0 {
                row[next] -= factor * upper_right;
            }
        }
        let Some(inverse_second) = pivot(a, pivots, next) else { return false };
        let (top, bottom) = a.split_at_mut((next + 1) * s);
        let (first_row, second_row) = top[col * s..].split_at_mut(s);
        // The second pivot row's rest takes column col's update now (it is U's row next).
        let factor = second_row[col];
        if factor != 0.0 {
            for (x, p) in second_row[next + 1..].iter_mut().zip(&first_row[next + 1..]) {
                *x -= factor * p;
            }
        }
        let (u1, u2) = (&first_row[next + 1..], &second_row[next + 1..]);
        for row in bottom.chunks_exact_mut(s) {
            let (f1, f2) = (row[col], row[next] * inverse_second);
            row[next] = f2;
            let rest = &mut row[next + 1..];
            match (f1 != 0.0, f2 != 0.0) {
                (true, true) => {
                    for ((x, p), q) in rest.iter_mut().zip(u1).zip(u2) {
                        *x = *x - f1 * p - f2 * q;
                    }
                }
                (true, false) => {
                    for (x, p) in rest.iter_mut().zip(u1) {
                        *x -= f1 * p;
                    }
                }
                (false, true) => {
                    for (x, q) in rest.iter_mut().zip(u2) {
                        *x -= f2 * q;
                    }
                }
                (false, false) => {}
            }
        }
        col += 2;
    }
    true
}

/// In-place Cholesky factorisation `a = L Lᵀ` of the symmetric row-major s × s matrix `a`
/// (row by row, each entry of L one dot product of two row heads); L is left in the lower
/// triangle, the upper one is not read. False if a pivot is not positive.
fn cholesky_factor(a: &mut [f64], s: usize) -> bool {
    for i in 0..s {
        let (done, rest) = a.split_at_mut(i * s);
        let row_i = &mut rest[..s];
        for j in 0..i {
            let row_j = &done[j * s..j * s + j + 1];
            let sum = crate::math::dot(&row_i[..j], &row_j[..j]);
            row_i[j] = (row_i[j] - sum) / row_j[j];
        }
        let pivot = row_i[i] - crate::math::dot(&row_i[..i], &row_i[..i]);
        if pivot.is_nan() || pivot <= 0.0 {
            return false;
        }
        row_i[i] = pivot.sqrt();
    }
    true
}

/// Solves with the factor of [`cholesky_factor`], in place: `L y = b`, then `Lᵀ x = y` by
/// columns of Lᵀ (rows of L, contiguous).
fn cholesky_solve(l: &[f64], s: usize, x: &mut [f64]) {
    for r in 0..s {
        let sum = crate::math::dot(&l[r * s..r * s + r], &x[..r]);
        x[r] = (x[r] - sum) / l[r * s + r];
    }
    for r in (0..s).rev() {
        let xr = x[r] / l[r * s + r];
        x[r] = xr;
        for (x, l) in x[..r].iter_mut().zip(&l[r * s..r * s + r]) {
            *x -= l * xr;
        }
    }
}

/// Solves with the factors of [`lu_factor`], in place.
fn lu_solve(lu: &[f64], pivots: &[usize], s: usize, x: &mut [f64]) {
    for (col, &p) in pivots.iter().enumerate() {
        x.swap(col, p);
    }
    for r in 0..s {
        let sum: f64 = crate::math::dot(&lu[r * s..r * s + r], &x[..r]);
        x[r] -= sum;
    }
    for r in (0..s).rev() {
        let sum: f64 = crate::math::dot(&lu[r * s + r + 1..(r + 1) * s], &x[r + 1..]);
        x[r] = (x[r] - sum) / lu[r * s + r];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Gram over a landing ragdoll's rows and over a subset of them in another order
    /// (matrix-free, W on paths through a branched tree; groups of rows with equal column
    /// ranges as lanes) equals A's entries W_i · W_j over W's runs, plus R on the diagonal.
    #[test]
    fn the_gram_from_lanes_is_a_over_the_rows() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/models/ragdoll_fall.toml");
        let mut scene = crate::io::scene::load_file(path).unwrap();
        for _ in 0..450 {
            scene.world.step().unwrap();
        }
        let problem = scene.world.problem();
        let n = problem.rows();
        assert!(problem.is_matrix_free() && n > 30, "{n} rows");
        for rows in [(0..n).collect::<Vec<_>>(), (0..n).rev().step_by(3).collect()] {
            let mut ws = SubspaceWorkspace { rows, ..Default::default() };
            fill_gram(problem, &mut ws);
            let m = ws.rows.len();
            let scale = (0..m).map(|a| ws.gram[a * m + a]).fold(0.0, f64::max);
            for (a, &i) in ws.rows.iter().enumerate() {
                for (b, &j) in ws.rows.iter().enumerate() {
                    let expected =
                        problem.delassus_entry(i, j) + if i == j { problem.regularization[i] } else { 0.0 };
                    let got = ws.gram[a * m + b];
                    assert!(
                        (got - expected).abs() <= 1e-12 * scale,
                        "rows {i}, {j}: {got} against {expected}"
                    );
                }
            }
        }
    }

    /// Cholesky and LU agree on a symmetric positive definite system (a Gram matrix plus a
    /// small diagonal), and Cholesky refuses an indefinite one.
    #[test]
    fn cholesky_solves_what_lu_solves_and_refuses_an_indefinite_matrix() {
        let s = 9;
        let b: Vec<f64> = (0..s * 12).map(|k| ((k * 37 % 23) as f64 - 11.0) / 7.0).collect();
        let mut a = vec![0.0; s * s];
        for i in 0..s {
            for j in 0..s {
                a[i * s + j] = crate::math::dot(&b[i * 12..(i + 1) * 12], &b[j * 12..(j + 1) * 12]);
            }
            a[i * s + i] += 1e-3;
        }
        let rhs: Vec<f64> = (0..s).map(|i| (i as f64 * 0.9).cos()).collect();
        let (mut l, mut lu, mut pivots) = (a.clone(), a.clone(), Vec::new());
        assert!(cholesky_factor(&mut l, s));
        assert!(lu_factor(&mut lu, &mut pivots, s));
        let (mut x, mut y) = (rhs.clone(), rhs.clone());
        cholesky_solve(&l, s, &mut x);
        lu_solve(&lu, &pivots, s, &mut y);
        for i in 0..s {
            let residual = crate::math::dot(&a[i * s..(i + 1) * s], &x) - rhs[i];
            assert!(residual.abs() < 1e-9, "row {i}: residual {residual}");
            assert!((x[i] - y[i]).abs() < 1e-8 * y[i].abs().max(1.0), "{} against {}", x[i], y[i]);
        }
        a[4 * s + 4] = -1.0;
        assert!(!cholesky_factor(&mut a, s));
    }

    /// PGS's iterate leaves a contact that slides just inside its friction pyramid (its normal
    /// impulse still growing over the sweeps): the step guesses it on its facet, where it
    /// ends, and solves the step in one round. Humanoid step 898 (nine contacts, several
    /// sliding) with a 4-facet pyramid: its exact answer (Lemke) with each sliding contact's
    /// tangential impulse moved 0.5 % inward.
    #[test]
    fn a_contact_just_inside_its_facet_is_guessed_on_it() {
        use crate::solvers::{ConstraintSolver, LemkeSolver};
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/humanoid_fall_step0898_problem.json");
        let mut problem = crate::io::problem::read_problem(&path).unwrap();
        let facets = 4;
        problem.friction = FrictionModel::Pyramid { facets };
        let mut exact = DVector::zeros(problem.rows());
        LemkeSolver::default().solve(&problem, &mut exact).unwrap();
        let mut lambda = exact.clone();
        let mut moved = 0;
        for c in &problem.contacts {
            let (nr, t1, t2) = c.rows();
            let s = [exact[t1] / c.mu, exact[t2] / c.mu2];
            if let Some((Unit::Facet(_), _)) = pyramid_units(c, facets, exact[nr], s, ON_CONE) {
                lambda[t1] *= 0.995;
                lambda[t2] *= 0.995;
                moved += 1;
            }
        }
        assert!(moved >= 2, "{moved} contacts slide on a facet at the answer");
        let mut ws = SubspaceWorkspace::default();
        let outcome = subspace_step(&problem, &lambda, None, &mut ws, 1e-10, 1e-9);
        assert!(matches!(outcome, SubspaceOutcome::Accepted(r) if r <= 1e-9), "{outcome:?}");
        assert_eq!(ws.rounds, 1, "reduced solves");
    }
}
