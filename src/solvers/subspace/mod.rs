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

mod active_set;
mod gram;
mod reduced;
mod step;
#[cfg(test)]
mod tests;

use active_set::{active_units, release_pyramid_contacts};
use gram::{fill_gram, GROUP};
use reduced::reduced_solve;
use step::{step_length, Blocking};

/// Largest problem (rows) a subspace step is tried on: the dense LU costs O(s³).
pub(crate) const MAX_SUBSPACE: usize = 128;

/// Proximal regularisation of the reduced solve, relative to K's largest diagonal entry.
const PROXIMAL: f64 = 1e-10;

/// Solves of the proximal iteration: the plain solve and one refinement. Without the
/// refinement the singular K of a redundant contact set leaves the solution too far from PGS's
/// iterate and the box stack and the humanoid need more rounds; a second refinement costs more
/// than it saves on the box stack, the humanoid and the ragdolls, with no fewer steps above the
/// tolerance.
const REFINEMENTS: usize = 2;

/// A contact slides when its tangential impulse is this close (relatively) to the cone.
const ON_CONE: f64 = 1e-9;

/// In the first round, PGS's iterate puts a pyramid contact on its facet (or at its vertex)
/// when its tangential impulse is this close (relatively) to it. The sweeps leave a contact
/// that slides slightly inside its pyramid (its normal impulse still growing, the facet moving
/// out): guessed sticking, it cost a round to find its facet. A wrong guess costs a round
/// too (the release of [`release_pyramid_contacts`]); later rounds start from exact solves and
/// classify at [`ON_CONE`]. On ragdoll episodes (`models/ragdoll_fall.toml`, seeds 1–7) 1e-2
/// costs less than a guess at [`ON_CONE`] on every seed, and less than 1e-1.
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
