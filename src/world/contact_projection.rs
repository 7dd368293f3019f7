//! Contacts held apart at the position level after each velocity-level step: post-stabilization
//! (Cline & Pai 2003, "Post-stabilization for rigid body simulation with contact and
//! constraints"; Bullet's split impulse and Box2D v3's relax pass answer the same need).
//!
//! The velocity-level step makes each contact's normal velocity close at most the gap the
//! contact has, but the positions it reaches are only as good as a first-order answer: soft
//! rows ([`WorldOptions::softness`], centred on their springs' impulses) yield while their load changes,
//! the step's straight-line motion of a turning limb carries its end into the ground, a pair
//! whose closest features change within the step meets where its manifold has no point, and
//! Baumgarte feedback (the contacts' `erp`) removes a penetration only a fraction per step,
//! adding velocity as it does. This stage moves the configuration alone, in two parts.
//!
//! **1. Predicted gaps** (after the solve, before q is integrated):
//!
//! - Each contact's gap at the end of the step from its two witness points carried with their
//!   bodies to the poses the step reaches, `q⁺ = q ⊕ h v⁺` (`v⁺` the velocity after the
//!   impulses): `g⁺ = n⁺·(p_A⁺ − p_B⁺)` (m), the normal turned with body B. This is the bodies'
//!   whole motion over the step, not its first-order part `g + h Jₙ v⁺`: a limb turning at
//!   20 rad/s at 1/60 s swings its end 1.7 cm past the straight line the rows see. No
//!   collision pass: the step's contacts, rows and W are reused.
//! - With `c = g⁺ + slop`, find `λ ≥ 0` (kg·m) with `w = Jₙ Δ + c ≥ 0`, `λ w = 0`,
//!   `Δ = M⁻¹ Jₙᵀ λ` (rad or m per dof): the least correction in the mass metric that leaves no
//!   contact deeper than the slop. Only the normal rows take part (the correction is
//!   frictionless), with the joint-limit rows of the multibodies they touch (a stop's gap at
//!   `q⁺`, 0 if already past it: the correction may not carry a joint past a stop, nor deeper,
//!   where the stop's Baumgarte feedback would give it velocity), and only on the islands of
//!   the step's problem that hold a contact predicted deeper than the trigger (above the
//!   slop, so that a resting heap's micrometre creep is not corrected step after step): a step
//!   without one does no more than the prediction.
//! - Projected Gauss–Seidel in W space (`W = J L⁻¹ D^{-1/2}`, the step's own, A_nn its kept
//!   diagonal), forward and backward in turn: `s = Wᵀλ`, each row
//!   `λ ← max(0, λ − (W_n·s + c_n)/A_nn)`, until no row's update moves it by more than the
//!   tolerance (m) or after `sweeps` sweeps; then `Δ = L⁻¹ D^{-1/2} s` block by block on the
//!   multibodies' factors.
//! - The rows' Jₙ is that of the step's start, and the bodies' motion is not linear: the gaps
//!   are predicted again at the corrected poses and, while a contact is still deeper than the
//!   slop by more than the tolerance, the problem is solved again from the last λ with the new
//!   gaps (`c − A λ` as the constant term: a chord method, Jₙ and A kept), at most `rounds`
//!   times.
//! - Δ is applied in the integrator's chart, `q⁺ = q ⊕ (h v⁺ + Δ)`
//!   ([`Multibody::integrate_step`]): it lives where the rows and `h v⁺` do, in the tangent
//!   space at the step's start (free and ball joints' quaternions turned by the same
//!   exponential map). The velocity is not changed, so no kinetic energy is added; a free
//!   body's velocity is carried to its new axes with the turn it actually made.
//!
//! **2. The check at the end of the step** ([`World::check_end_contacts`], after q is
//! integrated): when a collider touched by the step's contacts moved further than the slop in
//! the step, the contacts are detected again at the poses the step reached, which sees what
//! the step's manifolds could not predict (pairs whose closest features changed, contacts born
//! within the step). If one is deeper than the trigger, those contacts get rows at the end poses
//! (the step's mass-matrix factors as the metric) and one more projection, solved by the same
//! sweeps and, when they do not converge (a heap, whose corrections travel through tens of
//! bodies), by Newton's method ([`NewtonSolver`]) from their answer; it is applied at `q⁺` in
//! its own chart ([`Multibody::apply_end_correction`]); while a correction leaves a contact
//! deeper than the trigger, the contacts are detected and corrected again (`rounds` at most).
//! A heap at rest moves less than the
//! slop per step: the check costs it nothing.
//!
//! Loop closures within a multibody are closed after part 1 at the corrected configuration
//! (SHAKE, [`super::LoopProjection`]). No allocation once the buffers have grown to the
//! largest step.

use super::dofs::block_factors;
use super::multibody::Multibody;
use super::stages::check::{dynamics_error, finite};
use super::{StepError, World, WorldOptions};
use crate::collision::{Attachment, CollisionWorld, Contact};
use crate::constraints::RowLaw;
use crate::constraints::{
    add_contact_rows_with, ConstraintProblem, IslandPartition, ProblemBuilder, RowOrigin,
};
use crate::math::{Motion, Transform, Vec3};
use crate::solvers::{ConstraintSolver, NewtonSolver};
use nalgebra::{DMatrix, DVector};

/// Compliance of the rows given to Newton's method, relative to their diagonal (as
/// [`WorldOptions::softness`]): at Newton's own threshold, so that it solves them in one round;
/// the rows then keep this fraction of a gap, which the next round's prediction takes up.
const NEWTON_SOFTNESS: f64 = 0.0101;

/// Options of the contacts' position correction after each step ([`WorldOptions::contact_projection`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactProjection {
    /// Whether contacts are projected (true by default; scene key `[world] contact_projection`,
    /// `gelenk simulate --contact-projection on|off`).
    pub enabled: bool,
    /// Penetration left uncorrected (m, ≥ 0): a contact is pushed out only to this depth, so that
    /// resting contacts stay in contact and their rows stay the same from step to step. Below
    /// the contacts' `surface_layer` (1 mm by default), within which Baumgarte feedback does
    /// nothing.
    pub slop: f64,
    /// Penetration that starts a correction (m, ≥ `slop`): an island is corrected when one of
    /// its contacts is deeper than this, and then every contact of it deeper than the slop is
    /// pushed out to the slop. The gap between the two keeps a resting heap, whose soft rows
    /// let a contact creep by micrometres as loads shift, from being corrected step after step
    /// (each correction shifts its loads again, and the heap does not come to rest).
    pub trigger: f64,
    /// Most times the gaps are predicted and the correction solved in a step (≥ 1), and most
    /// detections and corrections at the end of the step.
    pub rounds: usize,
    /// Most Gauss–Seidel sweeps per island and round.
    pub sweeps: usize,
    /// Tolerance (m): an island's sweeps stop once no row's update moved it by more than this,
    /// and the rounds once no contact is predicted deeper than the slop by more than this.
    pub tolerance: f64,
}

impl Default for ContactProjection {
    fn default() -> Self {
        Self { enabled: true, slop: 5e-4, trigger: 7.5e-4, rounds: 3, sweeps: 20, tolerance: 1e-5 }
    }
}

/// What the contact projection did in a step ([`super::StepStats::projection`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProjectionStats {
    /// Contacts predicted deeper than the slop at the end of the step, before the correction.
    pub contacts: usize,
    /// Deepest predicted penetration at the end of the step before the correction (m, ≥ 0; 0
    /// when no contact was predicted to penetrate or the projection is off).
    pub depth: f64,
    /// Deepest predicted penetration at the end of the step after the correction (m, ≥ 0).
    pub residual: f64,
    /// Islands corrected.
    pub islands: usize,
    /// Rounds (predictions followed by a solve).
    pub rounds: usize,
    /// Most Gauss–Seidel sweeps of an island in a round.
    pub sweeps: usize,
    /// Whether the sweeps of the end-of-step check did not converge and Newton's method solved
    /// its problem.
    pub newton: bool,
    /// The furthest a point of a collider touched by the step's contacts moves in the step
    /// (m; an upper bound from each collider's bounding ball).
    pub motion: f64,
    /// Whether the contacts were detected again at the end of the step (some collider moved
    /// further than the slop).
    pub end_check: bool,
    /// The deepest penetration among the contacts found at the end of the step, before their
    /// correction (m, ≥ 0; 0 without that check).
    pub end_depth: f64,
    /// Detections at the end of the step (0 without the check; another follows each correction
    /// that left a contact deeper than the trigger, `rounds` at most).
    pub end_rounds: usize,
    /// The deepest penetration found by the last of them (m, ≥ 0): what its correction, if it
    /// made one, started from.
    pub end_residual: f64,
}

/// No multibody: the side of a contact on static geometry.
const WORLD: usize = usize::MAX;

/// A contact's two witness points fixed in their bodies, and its normal fixed in body B.
#[derive(Clone, Copy, Debug)]
struct Witness {
    /// Normal row.
    row: usize,
    /// Multibody and body of each side (`WORLD` for static geometry).
    a: (usize, usize),
    b: (usize, usize),
    /// The points in their bodies' frames (world for static geometry), m.
    point_a: Vec3,
    point_b: Vec3,
    /// The normal (B to A) in B's frame (world for static geometry).
    normal: Vec3,
    /// The contact's distance minus `n·(p_A − p_B)` at the step's start (m; zero up to rounding).
    offset: f64,
}

/// A joint-limit row of the step's problem: which multibody and which stop, to read its gap at
/// the end of the step from that multibody's `q_next`.
#[derive(Clone, Copy, Debug)]
struct LimitStop {
    /// The row.
    row: usize,
    /// Its multibody.
    multibody: usize,
    /// The stop.
    kind: StopKind,
}

/// A stop of [`LimitStop`].
#[derive(Clone, Copy, Debug)]
enum StopKind {
    /// A scalar coordinate's lower (`upper` false) or upper stop: q index and bound.
    Scalar { qi: usize, bound: f64, upper: bool },
    /// A ball joint's swing cone (0), lower (1) or upper (2) twist stop, or total-angle stop
    /// (3): its joint and which.
    Ball { joint: usize, which: usize },
}

/// The projection's buffers, grown to the largest step and kept.
#[derive(Default)]
pub(crate) struct ContactProjector {
    /// The contacts with rows, by contact block of the problem.
    witnesses: Vec<Witness>,
    /// The joint-limit rows of the multibodies the contacts touch.
    stops: Vec<LimitStop>,
    /// Per row of the step's problem: `c = g⁺ + slop` (m) for a contact's normal row, the gap at
    /// the end of the step (rad or m, 0 if already past the stop) for a joint-limit row of a
    /// multibody the contacts touch, +∞ for any other row; during a round's solve, the constant
    /// term `c − (A λ)`.
    gap: Vec<f64>,
    /// Per row: the projection's multiplier (kg·m).
    lambda: Vec<f64>,
    /// Wᵀλ over the stacked dofs, and a block of it being turned into a correction.
    sum: Vec<f64>,
    scratch: Vec<f64>,
    /// The islands being corrected: their contacts' normal rows and their limit rows, one
    /// island after the other, and per island its range there and its index.
    normals: Vec<usize>,
    islands: Vec<(usize, usize, usize)>,
    /// Per multibody: its poses at the end of the step (per body), and whether a contact with
    /// rows touches it (then they are current).
    poses: Vec<Vec<Transform>>,
    touched: Vec<bool>,
    /// A joint's motion subspace (written by the joint transforms, not read).
    subspace: [Motion; 6],
    /// The selected rows as a problem of their own (their islands' blocks renumbered from 0),
    /// for Newton's method when Gauss–Seidel's sweeps do not converge: its multipliers, and
    /// per block of the step's problem its index there.
    sub: ConstraintProblem,
    sub_lambda: DVector<f64>,
    local_block: Vec<usize>,
    newton: NewtonSolver,
    /// The last step's statistics.
    pub(crate) stats: ProjectionStats,
}

/// What the projection reads of a step.
pub(crate) struct ProjectionInputs<'a> {
    /// The step's problem (W, its diagonal, the rows' origins).
    pub(crate) problem: &'a ConstraintProblem,
    /// Its islands (the last split, of `problem`).
    pub(crate) partition: &'a IslandPartition,
    /// The step's contacts, indexed by the rows' [`RowOrigin::Contact`].
    pub(crate) contacts: &'a [Contact],
    /// The stacked velocity after the impulses.
    pub(crate) velocity: &'a DVector<f64>,
    /// Per block of the stacked dofs, its multibody and first dof there.
    pub(crate) block_owner: &'a [(usize, usize)],
    /// The colliders (their bodies and bounding balls), at the poses of the step's start.
    pub(crate) collision: &'a CollisionWorld,
}

impl ContactProjector {
    /// Clears every multibody's correction; then, if `solved` (the step of `h` seconds has a
    /// problem whose impulses were applied) and the projection is on, predicts the contacts'
    /// gaps at the end of the step and writes the correction of every island holding one deeper
    /// than the slop into its multibodies' `position_correction` (see the module
    /// documentation). `b.data` must hold each multibody's poses at the step's start and the
    /// factor of its mass matrix; `b.v_next` and `b.q_next` are overwritten.
    pub(crate) fn run(
        &mut self,
        inputs: ProjectionInputs<'_>,
        bodies: &mut [Multibody],
        options: &WorldOptions,
        h: f64,
        solved: bool,
    ) {
        self.stats = ProjectionStats::default();
        for b in bodies.iter_mut() {
            b.corrected = false;
        }
        let settings = options.contact_projection;
        let problem = inputs.problem;
        if !(settings.enabled && solved) || problem.contacts.is_empty() || problem.sparsity.is_empty() {
            return;
        }
        self.witnesses_of(&inputs, bodies);
        for (m, b) in bodies.iter_mut().enumerate() {
            if self.touched[m] {
                end_poses(b, &inputs, h, &mut self.poses[m], &mut self.subspace);
            }
        }
        self.stats.motion = self.largest_motion(inputs.collision, bodies);
        self.gap.clear();
        self.gap.resize(problem.rows(), f64::INFINITY);
        let (count, deepest) = self.predict(bodies, false, settings.slop);
        self.stats.contacts = count;
        self.stats.depth = deepest;
        self.stats.residual = deepest;
        if deepest <= settings.trigger {
            return;
        }
        self.select_islands(inputs.partition, settings.trigger - settings.slop);
        let sp = &problem.sparsity;
        self.sum.clear();
        self.sum.resize(sp.nv, 0.0);
        self.lambda.clear();
        self.lambda.resize(problem.rows(), 0.0);
        for round in 0..settings.rounds.max(1) {
            self.stats.rounds = round + 1;
            if round > 0 {
                // The constant term of the linear model at the last λ: c − W·(Wᵀλ).
                for &i in &self.normals {
                    self.gap[i] -= row_times(problem, i, &self.sum);
                }
            }
            let sweeps = self.solve(problem, inputs.partition, &settings, false);
            self.stats.sweeps = self.stats.sweeps.max(sweeps);
            self.apply(problem, inputs.partition, inputs.block_owner, bodies);
            for &(_, _, island) in &self.islands {
                for &block in inputs.partition.blocks(island) {
                    let m = inputs.block_owner[block].0;
                    if self.touched[m] {
                        end_poses(&mut bodies[m], &inputs, h, &mut self.poses[m], &mut self.subspace);
                    }
                }
            }
            let (_, residual) = self.predict(bodies, true, settings.slop);
            self.stats.residual = residual;
            if residual <= settings.slop + settings.tolerance {
                break;
            }
        }
    }

    /// The witness of every contact with rows, and which multibodies they touch.
    fn witnesses_of(&mut self, inputs: &ProjectionInputs<'_>, bodies: &[Multibody]) {
        self.touched.clear();
        self.touched.resize(bodies.len(), false);
        if self.poses.len() < bodies.len() {
            self.poses.resize_with(bodies.len(), Vec::new);
        }
        self.witnesses.clear();
        let problem = inputs.problem;
        for block in &problem.contacts {
            let row = block.normal;
            let RowOrigin::Contact(k) = problem.origins[row] else { continue };
            let c = &inputs.contacts[k];
            let mut side = |attachment: Attachment, point: &Vec3| match attachment {
                Attachment::Body { multibody, body } => {
                    self.touched[multibody] = true;
                    let pose = &bodies[multibody].data.x_wb[body];
                    ((multibody, body), pose.act_inv_point(point))
                }
                Attachment::World => ((WORLD, 0), *point),
            };
            let (a, point_a) = side(c.body_a, &c.point_a);
            let (b, point_b) = side(c.body_b, &c.point_b);
            let normal =
                if b.0 == WORLD { c.normal } else { bodies[b.0].data.x_wb[b.1].rotation.tr_mul(&c.normal) };
            let offset = c.distance - c.normal.dot(&(c.point_a - c.point_b));
            self.witnesses.push(Witness { row, a, b, point_a, point_b, normal, offset });
        }
        for (m, b) in bodies.iter().enumerate() {
            if self.touched[m] && self.poses[m].len() != b.model.nbodies() {
                self.poses[m].resize(b.model.nbodies(), Transform::identity());
            }
        }
        self.stops.clear();
        for row in 0..problem.rows() {
            let column = match problem.origins[row] {
                RowOrigin::LowerLimit(c)
                | RowOrigin::UpperLimit(c)
                | RowOrigin::SwingLimit(c)
                | RowOrigin::TwistLowerLimit(c)
                | RowOrigin::TwistUpperLimit(c)
                | RowOrigin::AngleLimit(c) => c,
                _ => continue,
            };
            let Some(&block) = problem.sparsity.row_blocks(row).first() else { continue };
            let multibody = inputs.block_owner[block].0;
            if !self.touched[multibody] {
                continue;
            }
            let model = &bodies[multibody].model;
            let dof = column - bodies[multibody].col;
            let joint = model.dof_joint(dof);
            let qi = model.idx_q(joint) + (dof - model.idx_v(joint));
            let kind = match problem.origins[row] {
                RowOrigin::LowerLimit(_) => {
                    StopKind::Scalar { qi, bound: model.lower_position_limit()[qi], upper: false }
                }
                RowOrigin::UpperLimit(_) => {
                    StopKind::Scalar { qi, bound: model.upper_position_limit()[qi], upper: true }
                }
                RowOrigin::SwingLimit(_) => StopKind::Ball { joint, which: 0 },
                RowOrigin::TwistLowerLimit(_) => StopKind::Ball { joint, which: 1 },
                RowOrigin::TwistUpperLimit(_) => StopKind::Ball { joint, which: 2 },
                _ => StopKind::Ball { joint, which: 3 },
            };
            self.stops.push(LimitStop { row, multibody, kind });
        }
    }

    /// The furthest any point of a collider of the multibodies touched by the step's contacts
    /// moves over the step (m): from the poses at the step's start (`data`) to `poses`, bounded
    /// by its shape frame's travel plus its turn times its bounding radius.
    fn largest_motion(&self, collision: &CollisionWorld, bodies: &[Multibody]) -> f64 {
        let mut largest: f64 = 0.0;
        for (m, b) in bodies.iter().enumerate() {
            if !self.touched[m] || b.asleep {
                continue;
            }
            for &c in collision.colliders_of(m) {
                let collider = &collision.colliders()[c];
                let Attachment::Body { body, .. } = collider.attachment() else { continue };
                let (local, radius) = collider.bounding_ball();
                let (start, end) = (&b.data.x_wb[body], &self.poses[m][body]);
                let origin = |x: &Transform| x.act_point(&local.translation);
                let turn = turn_angle(start, end);
                let travel =
                    (origin(end) - origin(start)).norm() + if turn > 0.0 { turn * radius } else { 0.0 };
                largest = largest.max(travel);
            }
        }
        largest
    }

    /// `c = g⁺ + slop` of the contacts' normal rows at the poses in `poses`: every contact, or
    /// only those of the islands being corrected (`selected`). Returns how many are negative and
    /// the deepest predicted penetration (m, ≥ 0).
    fn predict(&mut self, bodies: &[Multibody], selected: bool, slop: f64) -> (usize, f64) {
        let mut deepest: f64 = 0.0;
        let mut count = 0;
        let poses = &self.poses;
        let at =
            |(m, body): (usize, usize), p: &Vec3| if m == WORLD { *p } else { poses[m][body].act_point(p) };
        for w in &self.witnesses {
            if selected && !self.gap[w.row].is_finite() {
                continue;
            }
            let normal = if w.b.0 == WORLD { w.normal } else { poses[w.b.0][w.b.1].rotation * w.normal };
            let predicted = normal.dot(&(at(w.a, &w.point_a) - at(w.b, &w.point_b))) + w.offset;
            let c = predicted + slop;
            self.gap[w.row] = c;
            if c < 0.0 {
                count += 1;
                deepest = deepest.max(-predicted);
            }
        }
        // The joint stops: the correction may not carry a joint past its stop, nor deeper.
        for stop in &self.stops {
            if selected && !self.gap[stop.row].is_finite() {
                continue;
            }
            let b = &bodies[stop.multibody];
            let q = b.q_next.as_slice();
            let gap = match stop.kind {
                StopKind::Scalar { qi, bound, upper: false } => q[qi] - bound,
                StopKind::Scalar { qi, bound, upper: true } => bound - q[qi],
                StopKind::Ball { joint, which } => {
                    let iq = b.model.idx_q(joint);
                    b.model.ball_limits(joint).map_or(f64::INFINITY, |l| l.distances(&q[iq..iq + 4]).0[which])
                }
            };
            self.gap[stop.row] = gap.max(0.0);
        }
        (count, deepest)
    }

    /// The islands holding a contact deeper than the slop by more than `excess` (m), with their
    /// contacts' normal rows and limit rows; the other rows leave the problem (their gap
    /// becomes +∞).
    fn select_islands(&mut self, partition: &IslandPartition, excess: f64) {
        self.normals.clear();
        self.islands.clear();
        for k in 0..partition.len() {
            let rows = partition.rows(k);
            if !rows.iter().any(|&i| self.gap[i] < -excess) {
                for &i in rows {
                    self.gap[i] = f64::INFINITY;
                }
                continue;
            }
            let start = self.normals.len();
            self.normals.extend(rows.iter().copied().filter(|&i| self.gap[i].is_finite()));
            self.islands.push((start, self.normals.len(), k));
        }
        self.stats.islands = self.islands.len();
    }

    /// The selected rows' multipliers from the current λ (`sum` = Wᵀλ) with constant terms
    /// `gap`: projected Gauss–Seidel and, with `newton`, Newton's method from its answer when
    /// an island's sweeps do not converge (a heap, whose corrections travel through tens of
    /// bodies). Returns the most sweeps an island took.
    fn solve(
        &mut self,
        problem: &ConstraintProblem,
        partition: &IslandPartition,
        settings: &ContactProjection,
        newton: bool,
    ) -> usize {
        let (sweeps, converged) = self.sweep(problem, settings);
        if newton && !converged && self.newton_solve(problem, partition, settings.tolerance) {
            self.stats.newton = true;
        }
        sweeps
    }

    /// Projected Gauss–Seidel on the selected islands' rows from the current λ (`sum` = Wᵀλ),
    /// with constant terms `gap`; returns the most sweeps an island took and whether every
    /// island converged.
    fn sweep(&mut self, problem: &ConstraintProblem, settings: &ContactProjection) -> (usize, bool) {
        let sp = &problem.sparsity;
        let diagonal = problem.kept_diagonal();
        let (mut most_sweeps, mut converged) = (0, true);
        for &(start, end, _) in &self.islands {
            let rows = &self.normals[start..end];
            let mut sweeps = 0;
            while sweeps < settings.sweeps {
                sweeps += 1;
                let mut largest: f64 = 0.0;
                // Forward and backward in turn (symmetric Gauss–Seidel): a correction travels the
                // whole of a stack in one sweep whichever way its rows are ordered.
                let backward = sweeps % 2 == 0;
                for k in 0..rows.len() {
                    let i = if backward { rows[rows.len() - 1 - k] } else { rows[k] };
                    let a = diagonal.map_or_else(|| problem.delassus_entry(i, i), |d| d[i]);
                    if a <= 0.0 {
                        continue;
                    }
                    let w = row_times(problem, i, &self.sum) + self.gap[i];
                    let next = (self.lambda[i] - w / a).max(0.0);
                    let change = next - self.lambda[i];
                    if change != 0.0 {
                        self.lambda[i] = next;
                        for (col, wi) in sp.row_spans(i) {
                            for (s, wi) in self.sum[col..col + wi.len()].iter_mut().zip(wi) {
                                *s += change * wi;
                            }
                        }
                        largest = largest.max(change.abs() * a);
                    }
                }
                if largest <= settings.tolerance {
                    break;
                }
                if sweeps == settings.sweeps {
                    converged = false;
                }
            }
            most_sweeps = most_sweeps.max(sweeps);
        }
        (most_sweeps, converged)
    }

    /// Newton's method ([`NewtonSolver`]) on the selected rows as one problem, from the current
    /// λ, the rows softened by [`NEWTON_SOFTNESS`]; `sum` becomes Wᵀλ of its answer. False
    /// (λ and `sum` kept) if it fails.
    fn newton_solve(
        &mut self,
        problem: &ConstraintProblem,
        partition: &IslandPartition,
        tolerance: f64,
    ) -> bool {
        self.gather(problem, partition);
        let n = self.normals.len();
        if self.sub_lambda.len() != n {
            self.sub_lambda = DVector::zeros(n);
        }
        for (l, &i) in self.sub_lambda.iter_mut().zip(&self.normals) {
            *l = self.lambda[i];
        }
        self.newton.residual_goal = Some(tolerance);
        if self.newton.solve(&self.sub, &mut self.sub_lambda).is_err()
            || !crate::math::all_finite(self.sub_lambda.as_slice())
        {
            return false;
        }
        let sp = &problem.sparsity;
        for &(_, _, island) in &self.islands {
            for &block in partition.blocks(island) {
                let (col, width) = sp.blocks[block];
                self.sum[col..col + width].fill(0.0);
            }
        }
        for (&l, &i) in self.sub_lambda.iter().zip(&self.normals) {
            self.lambda[i] = l;
            if l != 0.0 {
                for (col, wi) in sp.row_spans(i) {
                    for (s, wi) in self.sum[col..col + wi.len()].iter_mut().zip(wi) {
                        *s += l * wi;
                    }
                }
            }
        }
        true
    }

    /// `sub` = the selected rows of `problem` (unilateral, bias the constant terms `gap`,
    /// compliance [`NEWTON_SOFTNESS`] of their diagonal), over their islands' blocks numbered
    /// from 0: matrix-free, W's runs copied.
    fn gather(&mut self, problem: &ConstraintProblem, partition: &IslandPartition) {
        let (sp, sub) = (&problem.sparsity, &mut self.sub);
        sub.reset_rows(self.normals.len());
        if sub.delassus.nrows() != 0 {
            sub.delassus = DMatrix::zeros(0, 0);
        }
        let local = &mut sub.sparsity;
        local.blocks.clear();
        local.nv = 0;
        self.local_block.clear();
        self.local_block.resize(sp.blocks.len(), usize::MAX);
        for &(_, _, island) in &self.islands {
            for &b in partition.blocks(island) {
                self.local_block[b] = local.blocks.len();
                local.blocks.push((local.nv, sp.blocks[b].1));
                local.nv += sp.blocks[b].1;
            }
        }
        for v in [&mut local.row_start, &mut local.entry_run_start, &mut local.run_start] {
            v.clear();
            v.push(0);
        }
        local.blocks_of_row.clear();
        local.w_values.clear();
        local.row_norm2.clear();
        local.friction_coupling.clear();
        local.runs.clear();
        local.rows_of_block.clear();
        local.entry_of_block_row.clear();
        local.block_start.clear();
        let diagonal = problem.kept_diagonal();
        for (l, &i) in self.normals.iter().enumerate() {
            local.push_row_from(sp, i, &self.local_block);
            let a = diagonal.map_or_else(|| problem.delassus_entry(i, i), |d| d[i]);
            local.row_norm2.push(a);
            sub.bias[l] = self.gap[i];
            sub.regularization[l] = NEWTON_SOFTNESS * a;
            sub.target[l] = 0.0;
            sub.laws.push(RowLaw::Unilateral);
            sub.origins.push(problem.origins[i]);
        }
    }

    /// `Δ = L⁻¹ D^{-1/2} Wᵀλ` on the blocks of the corrected islands, into their multibodies'
    /// `position_correction`.
    fn apply(
        &mut self,
        problem: &ConstraintProblem,
        partition: &IslandPartition,
        block_owner: &[(usize, usize)],
        bodies: &mut [Multibody],
    ) {
        let sp = &problem.sparsity;
        for &(_, _, island) in &self.islands {
            for &block in partition.blocks(island) {
                let (col, width) = sp.blocks[block];
                self.scratch.clear();
                self.scratch.extend_from_slice(&self.sum[col..col + width]);
                let first_dof = {
                    let factor_of = block_factors(bodies, block_owner);
                    let Some((factor, first_dof)) = factor_of(block) else { continue };
                    factor.unscale_solve(first_dof, &mut self.scratch);
                    first_dof
                };
                let (owner, _) = block_owner[block];
                let b = &mut bodies[owner];
                if !b.corrected {
                    b.position_correction.fill(0.0);
                    b.corrected = true;
                }
                b.position_correction.rows_mut(first_dof, width).copy_from_slice(&self.scratch);
            }
        }
    }
}

/// The buffers of the check at the end of the step: the contacts found at the poses the step
/// reached, their rows and problem.
pub(crate) struct EndContacts {
    pub(crate) builder: ProblemBuilder,
    pub(crate) problem: ConstraintProblem,
    pub(crate) partition: IslandPartition,
    pub(crate) contacts: Vec<Contact>,
    /// The stacked dofs (count, blocks) `builder` was made for.
    pub(crate) sized_for: (usize, usize),
}

impl EndContacts {
    /// Empty buffers over no dofs.
    pub(crate) fn new() -> Self {
        Self {
            builder: ProblemBuilder::new(0, crate::constraints::FrictionModel::Cone),
            problem: ConstraintProblem::default(),
            partition: IslandPartition::default(),
            contacts: Vec::new(),
            sized_for: (0, 0),
        }
    }
}

impl ContactProjector {
    /// The correction of the contacts found at the end of the step, whose rows (at the end
    /// poses) and problem `end` holds: every island with a contact deeper than the slop is
    /// solved once, and its correction written into its multibodies' `position_correction`
    /// (`corrected` set), to be applied at `q_next` in the chart there. Returns whether any was.
    pub(crate) fn correct_end_contacts(
        &mut self,
        end: &EndContacts,
        block_owner: &[(usize, usize)],
        bodies: &mut [Multibody],
        settings: &ContactProjection,
    ) -> bool {
        for b in bodies.iter_mut() {
            b.corrected = false;
        }
        let problem = &end.problem;
        self.gap.clear();
        self.gap.resize(problem.rows(), f64::INFINITY);
        let mut deepest: f64 = 0.0;
        for block in &problem.contacts {
            let RowOrigin::Contact(k) = problem.origins[block.normal] else { continue };
            let distance = end.contacts[k].distance;
            self.gap[block.normal] = distance + settings.slop;
            deepest = deepest.max(-distance);
        }
        if deepest <= settings.trigger {
            return false;
        }
        self.select_islands(&end.partition, settings.trigger - settings.slop);
        self.sum.clear();
        self.sum.resize(problem.sparsity.nv, 0.0);
        self.lambda.clear();
        self.lambda.resize(problem.rows(), 0.0);
        self.solve(problem, &end.partition, settings, true);
        self.apply(problem, &end.partition, block_owner, bodies);
        true
    }
}

/// The angle (rad) of the rotation from `start`'s axes to `end`'s, accurate near zero (from the
/// skew part of `R_startᵀ R_end` as well as its trace).
fn turn_angle(start: &Transform, end: &Transform) -> f64 {
    let r = start.rotation.tr_mul(&end.rotation);
    let sin = 0.5 * Vec3::new(r[(2, 1)] - r[(1, 2)], r[(0, 2)] - r[(2, 0)], r[(1, 0)] - r[(0, 1)]).norm();
    sin.atan2(0.5 * (r.trace() - 1.0))
}

impl World {
    /// Stage 8, after the integration, when some collider touched by the step's contacts moved
    /// further than the slop ([`ProjectionStats::motion`]): the contacts at the poses the step
    /// reached (kinematics and detection at every awake multibody's `q_next`) and, if one is
    /// deeper than the slop, their correction (rows at the end poses, the step's factors as the
    /// metric), applied to `q_next` in its own chart.
    /// A correction that leaves a contact deeper than the trigger (a thin limb turning, whose
    /// rows at the end poses are linear in its turn) is followed by another detection and
    /// correction, `rounds` of them at most.
    pub(super) fn check_end_contacts(&mut self, h: f64) -> Result<(), StepError> {
        let settings = self.options.contact_projection;
        if !settings.enabled || self.projector.stats.motion <= settings.slop {
            return Ok(());
        }
        for _ in 0..settings.rounds.max(1) {
            if !self.end_round(h)? {
                break;
            }
        }
        Ok(())
    }

    /// One detection at every awake multibody's `q_next` and, if a contact is deeper than the
    /// trigger, one correction applied to `q_next`; returns whether it corrected.
    fn end_round(&mut self, h: f64) -> Result<bool, StepError> {
        let settings = self.options.contact_projection;
        for (i, b) in self.bodies.iter_mut().enumerate() {
            if b.asleep {
                continue;
            }
            crate::algorithms::compute_joint_jacobians(&b.model, &mut b.data, &b.q_next)
                .map_err(dynamics_error(&self.names[i]))?;
            self.collision.update_multibody(i, &b.data)?;
            self.collision.set_multibody_motions(i, &[], h, false, |_| false);
        }
        let end = &mut self.end_contacts;
        end.contacts.clear();
        end.contacts.extend_from_slice(self.collision.detect());
        self.projector.stats.end_check = true;
        self.projector.stats.end_rounds += 1;
        // Only a contact that the correction can move counts (one side awake and factored).
        let bodies = &self.bodies;
        let movable = |side: Attachment| matches!(side, Attachment::Body { multibody, .. } if bodies[multibody].factor_identity().is_some());
        let deepest = end
            .contacts
            .iter()
            .filter(|c| movable(c.body_a) || movable(c.body_b))
            .map(|c| -c.distance)
            .fold(0.0, f64::max);
        if self.projector.stats.end_rounds == 1 {
            self.projector.stats.end_depth = deepest;
        }
        self.projector.stats.end_residual = deepest;
        if deepest <= settings.trigger {
            return Ok(false);
        }
        if end.sized_for != (self.dofs.nv, self.dofs.blocks.len()) {
            end.builder = ProblemBuilder::with_blocks(self.dofs.nv, &self.dofs.blocks, self.options.friction)
                .map_err(StepError::Solver)?;
            end.sized_for = (self.dofs.nv, self.dofs.blocks.len());
        }
        end.builder.clear();
        let bodies = &self.bodies;
        let (materials, colliders) = (&self.materials, self.collision.colliders());
        add_contact_rows_with(
            &mut end.builder,
            |m| (&bodies[m].model, &bodies[m].data, bodies[m].col),
            &end.contacts,
            0,
            &self.dofs.v_free,
            h,
            |c| materials.parameters_of(colliders, c),
            |_, _| true,
        );
        let factor_of = block_factors(bodies, &self.dofs.block_owner);
        end.builder.build_into_blocks(&self.dofs.v_free, factor_of, false, &mut end.problem);
        end.partition.split(&end.problem);
        if !self.projector.correct_end_contacts(end, &self.dofs.block_owner, &mut self.bodies, &settings) {
            return Ok(false);
        }
        for (i, b) in self.bodies.iter_mut().enumerate().filter(|(_, b)| b.corrected) {
            b.apply_end_correction();
            finite(&self.names[i], &b.model, &b.q_next, &b.v_next, true)?;
        }
        Ok(true)
    }
}

/// `W_i · s` over row i's runs.
fn row_times(problem: &ConstraintProblem, i: usize, s: &[f64]) -> f64 {
    problem.sparsity.row_spans(i).map(|(col, wi)| crate::math::dot(wi, &s[col..col + wi.len()])).sum()
}

/// Multibody `b`'s body poses at the end of the step into `poses`: at `q ⊕ (h v⁺ + Δ)` (its
/// velocity after the impulses, its correction if any), or where it is when it does not move
/// (asleep).
fn end_poses(
    b: &mut Multibody,
    inputs: &ProjectionInputs<'_>,
    h: f64,
    poses: &mut [Transform],
    subspace: &mut [Motion; 6],
) {
    if b.asleep {
        poses.copy_from_slice(&b.data.x_wb);
        return;
    }
    let nv = b.model.nv();
    b.v_next.copy_from(&inputs.velocity.rows(b.col, nv));
    b.integrate_step(h);
    let model = &b.model;
    poses[0] = b.data.x_wb[0];
    for i in 1..model.nbodies() {
        let joint = model.joint(i);
        let (iq, nq) = (model.idx_q(i), joint.nq());
        let x_pb = joint.placed_transform(
            model.placement(i),
            &b.q_next.as_slice()[iq..iq + nq],
            &mut subspace[..joint.nv()],
        );
        poses[i] = poses[model.parent(i)] * x_pb;
    }
}
