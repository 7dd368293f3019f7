//! [`World`]: several multibodies and static geometry stepped together with contacts, joint
//! limits, motors, servos, joint friction and loop closures as one constraint problem per step.
//!
//! [`World::step`] is the table of contents (docs/architecture.md):
//! check state finite → kinematics → collision → free motion → constraint rows → solve →
//! velocity update (→ rows for the speculative contacts and limit stops that the solved velocity
//! closes, and solve again) → integrate q on the manifold (free origins on straight lines, see
//! [`crate::model::Joint::integrate_decoupled`]) → project loop closures onto their manifold
//! ([`LoopProjection`]) → sleeping and statistics.
//! Steps without any row skip the solver (and, without implicit springs or damping, use ABA
//! instead of CRBA); sleeping islands are skipped entirely. With an integrator other than the
//! default semi-implicit Euler ([`WorldOptions::integrator`]), steps without contacts, limits,
//! motors or joint friction replace free motion, rows, solve and integration by that integrator
//! (loop closures at the acceleration level): see [`smooth`].

mod contact_rows;
mod multibody;
mod options;
mod projection;
mod sleep;
pub mod smooth;

pub use multibody::{Motor, Multibody, PoseServo, Servo};
pub use options::{SleepOptions, SolverKind, WorldOptions};
pub use projection::LoopProjection;
pub use smooth::{integrator_name, parse_integrator, INTEGRATOR_NAMES};

use crate::collision::{Attachment, CollisionWorld, Contact, MeshOptions};
use crate::constraints::{
    add_contact_rows_with, add_joint_friction_rows, add_joint_limit_rows_speculative,
    add_loop_closure_rows_between, add_motor_row, BuiltRows, ConstraintProblem, ContactParameters,
    DroppedLimit, FrictionModel, LimitVelocities, LoopClosure, ProblemBuilder, RowOrigin, Speculation,
    TreeFactor,
};
use crate::error::CollisionError;
use crate::error::DynamicsError;
use crate::integrators::{IntegratorError, IntegratorKind};
use crate::math::{FastHasher, Transform, Vec3};
use crate::model::{Model, Shape};
use crate::solvers::{Fallback, SolverChain, SolverError};
use nalgebra::DVector;
use std::collections::HashMap;
use std::time::Instant;
use thiserror::Error;

/// Why a step failed. The state is left as it was before the step.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StepError {
    /// A NaN or infinity in a multibody's state (before or after the step).
    #[error("multibody `{multibody}`: {what} of joint `{joint}` is not finite")]
    NonFinite {
        /// Multibody name.
        multibody: String,
        /// Joint owning the coordinate.
        joint: String,
        /// "q", "v", "new q" or "new v".
        what: &'static str,
    },
    /// The dynamics refused the state (a singular mass matrix, ...).
    #[error("multibody `{multibody}`: {source}")]
    Dynamics {
        /// Multibody name.
        multibody: String,
        /// The error.
        source: DynamicsError,
    },
    /// Collision detection failed.
    #[error(transparent)]
    Collision(#[from] CollisionError),
    /// Every solver of the chain failed.
    #[error(transparent)]
    Solver(#[from] SolverError),
    /// The smooth integrator failed for another reason than the dynamics (an adaptive step
    /// size that underflowed).
    #[error("multibody `{multibody}`: {source}")]
    Integrator {
        /// Multibody name.
        multibody: String,
        /// The error.
        source: IntegratorError,
    },
    /// A multibody or body index out of range.
    #[error("index {index} is out of range ({count} {what})")]
    IndexOutOfRange {
        /// What was indexed.
        what: &'static str,
        /// Index given.
        index: usize,
        /// Number available.
        count: usize,
    },
}

/// What the last step did, cheaply gathered.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StepStats {
    /// Steps taken so far.
    pub step: u64,
    /// Simulated time after the step (s).
    pub time: f64,
    /// Contact points.
    pub contacts: usize,
    /// Constraint rows.
    pub rows: usize,
    /// Solver whose answer was used (empty when no rows).
    pub solver: &'static str,
    /// Its iterations or pivots.
    pub iterations: usize,
    /// Its certifying residual (m/s).
    pub residual: f64,
    /// Solvers that failed before it, and why.
    pub fallbacks: Vec<Fallback>,
    /// Deepest penetration among the contacts (m, ≥ 0).
    pub max_penetration: f64,
    /// Multibodies asleep after the step.
    pub asleep: usize,
    /// Total energy (J) after the step, if diagnostics are on.
    pub energy: Option<f64>,
    /// Total linear momentum (kg·m/s, world axes) after the step, if diagnostics are on.
    pub momentum: Option<Vec3>,
    /// Largest constraint violation after the step, if diagnostics are on: loop-closure
    /// translation error (m) or joint-limit overshoot (rad or m), whichever is larger.
    pub constraint_violation: Option<f64>,
    /// Nanoseconds per phase: kinematics, collision, free motion, rows + assembly, solve,
    /// integration + sleeping; zeros unless [`WorldOptions::time_phases`] is on.
    pub phase_ns: [u64; 6],
    /// The scheme of the step: `"semi-implicit-euler"` for the velocity-level step, else the
    /// name of [`WorldOptions::integrator`] (a smooth step, see [`smooth`]).
    pub integrator: &'static str,
}

/// A simulated world.
pub struct World {
    options: WorldOptions,
    bodies: Vec<Multibody>,
    names: Vec<String>,
    collision: CollisionWorld,
    materials: Vec<ContactParameters>,
    pair_parameters: HashMap<(u32, u32), ContactParameters, FastHasher>,
    /// Loop closures: (multibody of body A, multibody of body B, the closure).
    loops: Vec<(usize, usize, LoopClosure)>,
    /// Per multibody, the buffers of the position projection of its own loop closures (None
    /// without loops within it).
    projections: Vec<Option<projection::ProjectionBuffers>>,
    /// The integrators of smooth steps, built at the first smooth step.
    smooth: smooth::SmoothSteppers,
    chain: SolverChain,
    builder: ProblemBuilder,
    problem: ConstraintProblem,
    /// The rows `problem`'s W was built from, and per multibody the factor it was built on
    /// ([`Multibody::factor_identity`]): a step whose rows and factors are the same keeps W.
    built_rows: BuiltRows,
    built_factors: Vec<Option<u64>>,
    /// The generation of the kept contact rows W was built from (see `contact_rows`).
    built_contact_rows: Option<u64>,
    /// How many times a step built W from its rows ([`World::problem_builds`]).
    problem_builds: u64,
    lambda: DVector<f64>,
    /// Last step's row keys and impulses, in row order ([`World::warm_start`]).
    warm_keys: Vec<u64>,
    warm_values: Vec<f64>,
    /// The origins of last solve's rows and the generation of its kept contact rows (see
    /// `contact_rows`), and whether this step's rows are those rows ([`World::warm_start`]).
    warm_origins: Vec<RowOrigin>,
    warm_generation: Option<u64>,
    warm_same_rows: bool,
    /// Key → position in `warm_keys`, built only in steps whose rows came in another order.
    warm_index: HashMap<u64, usize, FastHasher>,
    /// This step's row keys (become `warm_keys` once solved).
    row_keys: Vec<u64>,
    /// Last step's contacts with rows, for those whose key changed ([`World::warm_start`]).
    warm_contacts: Vec<WarmContact>,
    /// Per entry of `warm_contacts`: matched by a contact of this step.
    warm_taken: Vec<bool>,
    /// This step's rows that matched a key (their positions in `warm_keys`) and that did not.
    warm_matched: Vec<usize>,
    warm_missed: Vec<usize>,
    contacts: Vec<Contact>,
    /// Per contact of this step: it gets rows (the speculation test, or forced).
    contact_has_rows: Vec<bool>,
    /// The contact rows the builder starts with, kept while they stay this step's rows.
    kept_contact_rows: contact_rows::KeptContactRows,
    /// This step's contacts that the speculation test left without rows.
    speculation_dropped: Vec<usize>,
    /// Per contact of this step: given rows after a solve whose velocities close it
    /// ([`World::close_dropped_rows`]).
    speculation_forced: Vec<bool>,
    /// Per multibody: its velocities after the solve are computed (`close_dropped_rows`).
    speculation_updated: Vec<bool>,
    /// This step's joint-limit stops that the speculation left without a row.
    limits_dropped: Vec<DroppedLimit>,
    v_all: DVector<f64>,
    v_free_all: DVector<f64>,
    /// Diagonal blocks of the stacked mass matrix (first column, width): one per root subtree
    /// of each multibody.
    blocks: Vec<(usize, usize)>,
    /// Per block, its multibody and the index of its first dof in that multibody.
    block_owner: Vec<(usize, usize)>,
    /// Wᵀλ while applying impulses (nv entries).
    impulse_scratch: Vec<f64>,
    nv_total: usize,
    time: f64,
    steps: u64,
    accumulator: f64,
    stats: StepStats,
    islands: sleep::Islands,
}

impl World {
    /// An empty world.
    pub fn new(options: WorldOptions) -> Self {
        Self {
            collision: CollisionWorld::new(options.collision),
            chain: options.chain(),
            builder: ProblemBuilder::new(0, options.friction),
            materials: vec![options.contact],
            options,
            bodies: Vec::new(),
            names: Vec::new(),
            pair_parameters: HashMap::default(),
            loops: Vec::new(),
            projections: Vec::new(),
            smooth: smooth::SmoothSteppers::default(),
            problem: ConstraintProblem::default(),
            built_rows: BuiltRows::default(),
            built_factors: Vec::new(),
            built_contact_rows: None,
            problem_builds: 0,
            lambda: DVector::zeros(0),
            warm_keys: Vec::new(),
            warm_origins: Vec::new(),
            warm_generation: None,
            warm_same_rows: false,
            warm_values: Vec::new(),
            warm_index: HashMap::default(),
            warm_contacts: Vec::new(),
            warm_taken: Vec::new(),
            warm_matched: Vec::new(),
            warm_missed: Vec::new(),
            row_keys: Vec::new(),
            contacts: Vec::new(),
            contact_has_rows: Vec::new(),
            kept_contact_rows: contact_rows::KeptContactRows::default(),
            speculation_dropped: Vec::new(),
            speculation_forced: Vec::new(),
            speculation_updated: Vec::new(),
            limits_dropped: Vec::new(),
            v_all: DVector::zeros(0),
            v_free_all: DVector::zeros(0),
            blocks: Vec::new(),
            block_owner: Vec::new(),
            impulse_scratch: Vec::new(),
            nv_total: 0,
            time: 0.0,
            steps: 0,
            accumulator: 0.0,
            stats: StepStats::default(),
            islands: sleep::Islands::default(),
        }
    }

    /// The options.
    pub fn options(&self) -> &WorldOptions {
        &self.options
    }

    /// Adds a multibody (its gravity is set to the world's) with its collision geometry and
    /// returns its index. Its state starts at the neutral configuration, at rest.
    pub fn add_multibody(
        &mut self,
        name: &str,
        mut model: Model,
        meshes: &MeshOptions,
    ) -> Result<usize, StepError> {
        model.set_gravity(self.options.gravity);
        let index = self.collision.add_model(&model, meshes)?;
        debug_assert_eq!(index, self.bodies.len());
        let mut body = Multibody::new(model);
        body.col = self.nv_total;
        for (first, width) in body.model.root_subtree_dofs() {
            self.blocks.push((body.col + first, width));
            self.block_owner.push((index, first));
        }
        self.nv_total += body.model.nv();
        self.bodies.push(body);
        self.projections.push(None);
        self.names.push(name.to_string());
        self.builder = ProblemBuilder::with_blocks(self.nv_total, &self.blocks, self.options.friction)
            .map_err(StepError::Solver)?;
        self.kept_contact_rows.invalidate();
        self.v_all = DVector::zeros(self.nv_total);
        self.v_free_all = DVector::zeros(self.nv_total);
        Ok(index)
    }

    /// Adds static geometry at `pose` (world frame) with material `material`; returns the collider.
    pub fn add_static(
        &mut self,
        name: &str,
        shape: &Shape,
        pose: Transform,
        material: u32,
    ) -> Result<usize, StepError> {
        let c = self.collision.add_static(name, shape, pose, &MeshOptions::default())?;
        self.collision.set_material(c, material);
        self.kept_contact_rows.invalidate();
        Ok(c)
    }

    /// Turns self-collision of a multibody on or off.
    pub fn set_self_collision(&mut self, multibody: usize, on: bool) -> Result<(), StepError> {
        Ok(self.collision.set_self_collision(multibody, on)?)
    }

    /// Defines material `index` (0 is the default material of every collider).
    pub fn set_material(&mut self, index: u32, parameters: ContactParameters) {
        let i = index as usize;
        if self.materials.len() <= i {
            self.materials.resize(i + 1, self.options.contact);
        }
        self.materials[i] = parameters;
        self.kept_contact_rows.invalidate();
    }

    /// Parameters used when materials `a` and `b` touch, overriding the combination rule.
    pub fn set_pair_parameters(&mut self, a: u32, b: u32, parameters: ContactParameters) {
        self.pair_parameters.insert((a.min(b), a.max(b)), parameters);
        self.kept_contact_rows.invalidate();
    }

    /// Replaces the solver chain (the first solver whose answer is certified is used); the
    /// warm-start memory is kept.
    pub fn set_solvers(&mut self, solvers: Vec<SolverKind>) {
        self.options.solvers = solvers;
        self.chain = self.options.chain();
    }

    /// Replaces the friction model of the contact rows ([`WorldOptions::friction`]) from the next
    /// step on.
    pub fn set_friction(&mut self, friction: FrictionModel) -> Result<(), StepError> {
        self.builder =
            ProblemBuilder::with_blocks(self.nv_total, &self.blocks, friction).map_err(StepError::Solver)?;
        self.kept_contact_rows.invalidate();
        self.options.friction = friction;
        self.chain = self.options.chain();
        Ok(())
    }

    /// Replaces the integrator of smooth steps ([`WorldOptions::integrator`]).
    pub fn set_integrator(&mut self, integrator: IntegratorKind) {
        self.options.integrator = integrator;
    }

    /// Replaces which contacts still apart get rows ([`WorldOptions::speculation`]).
    pub fn set_speculation(&mut self, speculation: Speculation) {
        self.options.speculation = speculation;
    }

    /// Sets [`WorldOptions::mass_matrix_reuse`] (None: every step factors the mass matrices).
    pub fn set_mass_matrix_reuse(&mut self, tolerance: Option<f64>) {
        self.options.mass_matrix_reuse = tolerance;
    }

    /// Turns the per-phase wall-clock timing of the step statistics on or off
    /// ([`WorldOptions::time_phases`]).
    pub fn set_phase_timing(&mut self, on: bool) {
        self.options.time_phases = on;
    }

    /// Replaces the sleeping parameters; disabling sleep wakes every multibody.
    pub fn set_sleep(&mut self, sleep: SleepOptions) {
        self.options.sleep = sleep;
        if !sleep.enabled {
            for i in 0..self.bodies.len() {
                self.wake(i);
            }
        }
    }

    /// Adds a loop closure between two bodies of multibody `multibody` (body 0 is the world).
    pub fn add_loop(&mut self, multibody: usize, closure: LoopClosure) -> Result<(), StepError> {
        self.add_loop_between(multibody, multibody, closure)
    }

    /// Adds a loop closure between body `closure.body_a` of multibody `multibody_a` and body
    /// `closure.body_b` of multibody `multibody_b` (body 0 of either is the world). The two
    /// multibodies then sleep and wake together. Closures within one multibody are also
    /// projected back onto their manifold after each step ([`WorldOptions::loop_projection`]);
    /// closures between two multibodies rely on their velocity rows and Baumgarte feedback
    /// (`erp`) alone.
    pub fn add_loop_between(
        &mut self,
        multibody_a: usize,
        multibody_b: usize,
        closure: LoopClosure,
    ) -> Result<(), StepError> {
        for (m, body) in [(multibody_a, closure.body_a), (multibody_b, closure.body_b)] {
            self.check_multibody(m)?;
            let count = self.bodies[m].model.nbodies();
            if body >= count {
                return Err(StepError::IndexOutOfRange { what: "bodies", index: body, count });
            }
        }
        if self.bodies[multibody_a].asleep != self.bodies[multibody_b].asleep {
            self.wake(multibody_a);
            self.wake(multibody_b);
        }
        self.loops.push((multibody_a, multibody_b, closure));
        if multibody_a == multibody_b {
            let m = multibody_a;
            let rows = projection::ProjectionBuffers::rows_for(self.own_loops(m));
            let model = &self.bodies[m].model;
            self.projections[m] = Some(projection::ProjectionBuffers::new(model.nv(), model.nq(), rows));
        }
        Ok(())
    }

    /// The loop closures between bodies of multibody `m` alone.
    fn own_loops(&self, m: usize) -> impl Iterator<Item = &LoopClosure> {
        self.loops.iter().filter(move |(a, b, _)| *a == m && *b == m).map(|(_, _, c)| c)
    }

    /// The collision world (colliders, materials, filters).
    pub fn collision(&self) -> &CollisionWorld {
        &self.collision
    }

    /// The collision world, mutably (filters, materials, self-collision).
    pub fn collision_mut(&mut self) -> &mut CollisionWorld {
        // Colliders' materials may change: the contact rows are formed anew.
        self.kept_contact_rows.invalidate();
        &mut self.collision
    }

    /// Multibody `i`.
    pub fn multibody(&self, i: usize) -> &Multibody {
        &self.bodies[i]
    }

    /// Multibody `i`, mutably (state, torques, motors); changing it wakes it.
    pub fn multibody_mut(&mut self, i: usize) -> &mut Multibody {
        self.wake(i);
        &mut self.bodies[i]
    }

    /// Number of multibodies.
    pub fn multibody_count(&self) -> usize {
        self.bodies.len()
    }

    /// Name of multibody `i`.
    pub fn multibody_name(&self, i: usize) -> &str {
        &self.names[i]
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Statistics of the last step.
    pub fn stats(&self) -> &StepStats {
        &self.stats
    }

    /// Contacts of the last step.
    pub fn contacts(&self) -> &[Contact] {
        &self.contacts
    }

    /// The constraint problem of the last step (for export and diagnostics).
    pub fn problem(&self) -> &ConstraintProblem {
        &self.problem
    }

    /// Impulses of the last step (N·s), one per row of [`World::problem`].
    pub fn impulses(&self) -> &DVector<f64> {
        &self.lambda
    }

    /// Wakes multibody `i` (and lets its island be evaluated again).
    pub fn wake(&mut self, i: usize) {
        if let Some(b) = self.bodies.get_mut(i) {
            b.asleep = false;
            b.idle_steps = 0;
            b.idle_time = 0.0;
            b.history_len = 0;
            self.collision.set_asleep(i, false);
        }
    }

    fn check_multibody(&self, i: usize) -> Result<(), StepError> {
        if i < self.bodies.len() {
            Ok(())
        } else {
            Err(StepError::IndexOutOfRange { what: "multibodies", index: i, count: self.bodies.len() })
        }
    }

    /// Applies a force `force` (N, world axes) at the world point `point` (m) and a torque
    /// `torque` (N·m, world axes) to body `body` of multibody `multibody` during the next step.
    pub fn apply_force(
        &mut self,
        multibody: usize,
        body: usize,
        force: Vec3,
        point: Vec3,
        torque: Vec3,
    ) -> Result<(), StepError> {
        self.check_multibody(multibody)?;
        let nb = self.bodies[multibody].model.nbodies();
        if body == 0 || body >= nb {
            return Err(StepError::IndexOutOfRange { what: "bodies", index: body, count: nb });
        }
        self.wake(multibody);
        self.bodies[multibody].pending_forces.push((body, force, point, torque));
        Ok(())
    }

    /// Applies an impulse `impulse` (N·s, world axes) at the world point `point` to body `body`:
    /// an instant velocity change `Δv = M⁻¹ J_pᵀ p`.
    pub fn apply_impulse(
        &mut self,
        multibody: usize,
        body: usize,
        impulse: Vec3,
        point: Vec3,
    ) -> Result<(), StepError> {
        self.check_multibody(multibody)?;
        let name = self.names[multibody].clone();
        let mb = &mut self.bodies[multibody];
        let nb = mb.model.nbodies();
        if body == 0 || body >= nb {
            return Err(StepError::IndexOutOfRange { what: "bodies", index: body, count: nb });
        }
        let dynamics = |source| StepError::Dynamics { multibody: name.clone(), source };
        crate::algorithms::compute_joint_jacobians(&mb.model, &mut mb.data, &mb.state.q).map_err(dynamics)?;
        crate::algorithms::crba(&mb.model, &mut mb.data, &mb.state.q).map_err(dynamics)?;
        crate::algorithms::factor_mass_matrix(&mb.model, &mut mb.data).map_err(dynamics)?;
        let mut dv = DVector::zeros(mb.model.nv());
        crate::collision::add_point_direction_row(
            &mb.model,
            &mb.data,
            body,
            &point,
            &impulse,
            1.0,
            dv.as_mut_slice(),
            0,
        );
        crate::algorithms::solve_mass_matrix(&mb.model, &mb.data, &mut dv);
        mb.state.v += dv;
        self.wake(multibody);
        Ok(())
    }

    /// Runs whole steps of `options.dt` for a frame of `frame_dt` seconds, at most
    /// `options.max_substeps` of them (the rest of the backlog is dropped, so a slow frame cannot
    /// cause ever more steps), and returns the interpolation factor α ∈ [0, 1) between the last
    /// two states for rendering.
    pub fn advance(&mut self, frame_dt: f64) -> Result<f64, StepError> {
        let dt = self.options.dt;
        self.accumulator += frame_dt.max(0.0);
        let mut substeps = 0;
        while self.accumulator >= dt && substeps < self.options.max_substeps {
            self.step()?;
            self.accumulator -= dt;
            substeps += 1;
        }
        if self.accumulator >= dt {
            self.accumulator %= dt;
        }
        Ok(self.accumulator / dt)
    }

    /// One step of `options.dt`. See the module documentation for the order of the phases.
    pub fn step(&mut self) -> Result<&StepStats, StepError> {
        let h = self.options.dt;
        let mut clock = self.options.time_phases.then(Instant::now);
        let mut phase = [0u64; 6];
        let mut lap = |k: usize, clock: &mut Option<Instant>| {
            if let Some(clock) = clock {
                let now = Instant::now();
                phase[k] = (now - *clock).as_nanos() as u64;
                *clock = now;
            }
        };
        // 1. Check the state.
        for (i, b) in self.bodies.iter().enumerate() {
            check_finite(&self.names[i], &b.model, &b.state.q, &b.state.v, false)?;
        }
        // 2. Kinematics.
        for i in 0..self.bodies.len() {
            if !self.bodies[i].asleep {
                let b = &mut self.bodies[i];
                b.kinematics()
                    .map_err(|source| StepError::Dynamics { multibody: self.names[i].clone(), source })?;
                self.collision.update_multibody(i, &b.data)?;
            }
        }
        lap(0, &mut clock);
        // 3. Collision, and waking of sleepers touched by awake bodies.
        self.contacts.clear();
        self.contacts.extend_from_slice(self.collision.detect());
        for k in 0..self.contacts.len() {
            let c = self.contacts[k];
            if let (Attachment::Body { multibody: a, .. }, Attachment::Body { multibody: b, .. }) =
                (c.body_a, c.body_b)
            {
                for (sleeper, other) in [(a, b), (b, a)] {
                    if self.bodies[sleeper].asleep && !self.bodies[other].asleep {
                        self.wake(sleeper);
                        let s = &mut self.bodies[sleeper];
                        s.kinematics().map_err(|source| StepError::Dynamics {
                            multibody: self.names[sleeper].clone(),
                            source,
                        })?;
                    }
                }
            }
        }
        lap(1, &mut clock);
        // Smooth step (no inequality rows, an integrator chosen): phases 4–6 are skipped and
        // phase 7 integrates with the chosen scheme (smooth.rs).
        let smooth = smooth::applies(self);
        if smooth {
            self.smooth.prepare(self.options.integrator, &self.bodies, &self.loops);
        }
        // 4. Free motion.
        let has_rows = !self.contacts.is_empty()
            || !self.loops.is_empty()
            || self.bodies.iter().any(|b| {
                b.motors.iter().any(Option::is_some)
                    || b.servos.iter().any(Option::is_some)
                    || b.pose_servo.is_some()
                    || b.model.friction().iter().any(|f| *f > 0.0)
                    || has_active_limit(b, self.options.limits.margin)
            });
        for i in 0..self.bodies.len() {
            let b = &mut self.bodies[i];
            if b.asleep || smooth {
                b.v_free.fill(0.0);
                continue;
            }
            b.free_motion(h, has_rows, self.options.mass_matrix_reuse)
                .map_err(|source| StepError::Dynamics { multibody: self.names[i].clone(), source })?;
        }
        for b in &self.bodies {
            let (col, nv) = (b.col, b.model.nv());
            self.v_all.rows_mut(col, nv).copy_from(&b.state.v);
            self.v_free_all.rows_mut(col, nv).copy_from(&b.v_free);
        }
        lap(2, &mut clock);
        // 5. Constraint rows (`add_rows` clears the builder, or keeps its contact rows).
        self.speculation_forced.clear();
        self.speculation_forced.resize(self.contacts.len(), false);
        self.speculation_dropped.clear();
        self.limits_dropped.clear();
        if has_rows && !smooth {
            self.add_rows(h, false);
        } else {
            self.builder.clear();
            self.kept_contact_rows.invalidate();
        }
        let mut rows = self.builder.len();
        // 6. Solve.
        let mut report = None;
        if rows > 0 {
            self.build_problem();
            lap(3, &mut clock);
            self.warm_start();
            report = Some(self.chain.solve(&self.problem, &mut self.lambda)?);
            self.remember_impulses();
        } else {
            self.problem =
                ConstraintProblem { friction: self.options.friction, ..ConstraintProblem::default() };
            self.built_rows.forget();
            self.lambda = DVector::zeros(0);
            lap(3, &mut clock);
        }
        // 7. Velocity update (v_free_all becomes the velocity after the impulses).
        if rows > 0 {
            self.apply_problem_impulses();
        }
        // A contact or limit stop the speculation test left out may be closed by the impulses of
        // the other rows (a resting hand flicked down by a body landing on its arm): then it gets
        // rows and the problem is solved again, warm-started from this solve.
        for _ in 0..SPECULATION_PASSES {
            if !self.close_dropped_rows(h) {
                break;
            }
            for b in &mut self.bodies {
                let nv = b.model.nv();
                b.v_solved.copy_from(&self.v_free_all.rows(b.col, nv));
                self.v_free_all.rows_mut(b.col, nv).copy_from(&b.v_free);
            }
            self.add_rows(h, true);
            rows = self.builder.len();
            self.build_problem();
            self.warm_start();
            let again = self.chain.solve(&self.problem, &mut self.lambda)?;
            self.remember_impulses();
            self.apply_problem_impulses();
            report = Some(match report {
                Some(mut first) => {
                    first.fallbacks.extend(again.fallbacks);
                    crate::solvers::ChainReport {
                        iterations: first.iterations + again.iterations,
                        fallbacks: first.fallbacks,
                        ..again
                    }
                }
                None => again,
            });
        }
        lap(4, &mut clock);
        // Integration on the manifold; commit only if all is finite.
        for i in 0..self.bodies.len() {
            let b = &mut self.bodies[i];
            let nv = b.model.nv();
            if b.asleep {
                b.v_next.fill(0.0);
                b.q_next.copy_from(&b.state.q);
                continue;
            }
            if smooth {
                let closures =
                    self.loops.iter().filter(move |(a, b, _)| *a == i && *b == i).map(|(_, _, c)| c);
                let name = &self.names[i];
                self.smooth
                    .advance(i, b, closures, self.projections[i].as_mut(), &self.options.loop_projection, h)
                    .map_err(|source| match source {
                        IntegratorError::Dynamics(source) => {
                            StepError::Dynamics { multibody: name.clone(), source }
                        }
                        source => StepError::Integrator { multibody: name.clone(), source },
                    })?;
                check_finite(name, &b.model, &b.q_next, &b.v_next, true)?;
                continue;
            }
            b.v_next.copy_from(&self.v_free_all.rows(b.col, nv));
            // Straight-line origins (R³ × SO(3)), not the SE(3) screw: see
            // `Joint::integrate_decoupled` (a rolling ball would otherwise sink into its plane).
            b.model.integrate_decoupled(&b.state.q, &b.v_next, h, &mut b.q_next);
            if !b.kinematic {
                b.transport_free_velocities(h);
            }
            if let Some(buffers) = self.projections[i].as_mut() {
                if !b.kinematic && b.factored {
                    let closures =
                        self.loops.iter().filter(move |(a, b, _)| *a == i && *b == i).map(|(_, _, c)| c);
                    buffers
                        .project(b, closures, &self.options.loop_projection)
                        .map_err(|source| StepError::Dynamics { multibody: self.names[i].clone(), source })?;
                }
            }
            check_finite(&self.names[i], &b.model, &b.q_next, &b.v_next, true)?;
        }
        for b in &mut self.bodies {
            std::mem::swap(&mut b.state.q, &mut b.q_next);
            std::mem::swap(&mut b.state.v, &mut b.v_next);
            b.state.t += h;
            b.pending_forces.clear();
        }
        self.time += h;
        self.steps += 1;
        // 8. Sleeping and statistics.
        if self.options.sleep.enabled {
            sleep::update(self);
        }
        let (energy, momentum, constraint_violation) = if self.options.diagnostics {
            (Some(self.total_energy()), Some(self.linear_momentum()), Some(self.constraint_violation()))
        } else {
            (None, None, None)
        };
        lap(5, &mut clock);
        let report = report.unwrap_or_else(|| crate::solvers::ChainReport {
            solver: "",
            iterations: 0,
            residuals: Default::default(),
            fallbacks: Vec::new(),
            note: None,
        });
        let certify = self.chain.certify(report.solver, &report.residuals);
        self.stats = StepStats {
            step: self.steps,
            time: self.time,
            contacts: self.contacts.len(),
            rows,
            solver: report.solver,
            iterations: report.iterations,
            residual: certify,
            fallbacks: report.fallbacks,
            max_penetration: self.contacts.iter().map(|c| -c.distance).fold(0.0, f64::max),
            asleep: self.bodies.iter().filter(|b| b.asleep).count(),
            energy,
            momentum,
            constraint_violation,
            phase_ns: phase,
            integrator: if smooth {
                smooth::integrator_name(&self.options.integrator)
            } else {
                "semi-implicit-euler"
            },
        };
        Ok(&self.stats)
    }

    /// Kinetic plus potential energy of every multibody (J), at the current states.
    pub fn total_energy(&mut self) -> f64 {
        let mut total = 0.0;
        for b in &mut self.bodies {
            let (q, v) = (&b.state.q, &b.state.v);
            total += crate::algorithms::kinetic_energy(&b.model, &mut b.data, q, v).unwrap_or(f64::NAN);
            total += crate::algorithms::potential_energy(&b.model, &mut b.data, q).unwrap_or(f64::NAN);
        }
        total
    }

    /// Moves every collider to the current states (poses, Jacobians), as a step's first phase
    /// does: for drawing or querying contacts before the first step or after editing states.
    pub fn refresh_collision(&mut self) -> Result<(), StepError> {
        for i in 0..self.bodies.len() {
            let b = &mut self.bodies[i];
            b.kinematics()
                .map_err(|source| StepError::Dynamics { multibody: self.names[i].clone(), source })?;
            self.collision.update_multibody(i, &b.data)?;
        }
        Ok(())
    }

    /// Kinetic energy of every multibody (J), at the current states.
    pub fn kinetic_energy(&mut self) -> f64 {
        let mut total = 0.0;
        for b in &mut self.bodies {
            let (q, v) = (&b.state.q, &b.state.v);
            total += crate::algorithms::kinetic_energy(&b.model, &mut b.data, q, v).unwrap_or(f64::NAN);
        }
        total
    }

    /// Total linear momentum Σ R_i (m_i v_i + ω_i × m_i c_i) of every body (kg·m/s, world axes)
    /// at the current states.
    pub fn linear_momentum(&mut self) -> Vec3 {
        let mut total = Vec3::zeros();
        for b in &mut self.bodies {
            let _ = crate::algorithms::forward_kinematics(&b.model, &mut b.data, &b.state.q);
            let _ = crate::algorithms::kinetic_energy(&b.model, &mut b.data, &b.state.q, &b.state.v);
            for i in 1..b.model.nbodies() {
                let (inertia, v) = (b.model.inertia(i), &b.data.v[i]);
                let local = v.linear * inertia.mass + v.angular.cross(&inertia.first_moment);
                total += b.data.x_wb[i].rotation * local;
            }
        }
        total
    }

    /// The largest loop-closure translation error (m) and joint-limit overshoot (rad or m, ball
    /// joints' swing cone and twist range included) at the current states.
    pub fn constraint_violation(&mut self) -> f64 {
        let mut worst: f64 = 0.0;
        for b in &self.bodies {
            let (lo, hi) = (b.model.lower_position_limit(), b.model.upper_position_limit());
            for i in 1..b.model.nbodies() {
                let joint = b.model.joint(i);
                if let Some(limits) = b.model.ball_limits(i) {
                    let iq = b.model.idx_q(i);
                    let (distances, _) = limits.distances(&b.state.q.as_slice()[iq..iq + 4]);
                    worst = distances.iter().fold(worst, |w, d| w.max(-d));
                }
                if matches!(joint, crate::model::Joint::Ball | crate::model::Joint::Free) {
                    continue;
                }
                for k in b.model.idx_q(i)..b.model.idx_q(i) + joint.nq() {
                    worst = worst.max(lo[k] - b.state.q[k]).max(b.state.q[k] - hi[k]);
                }
            }
        }
        for b in &mut self.bodies {
            if crate::algorithms::forward_kinematics(&b.model, &mut b.data, &b.state.q).is_err() {
                return f64::NAN;
            }
        }
        for (a, b, closure) in &self.loops {
            let (da, db) = (&self.bodies[*a].data, &self.bodies[*b].data);
            worst = worst.max(crate::constraints::loop_error_between(da, db, closure).0.norm());
        }
        worst
    }

    fn parameters_of(&self, c: &Contact) -> ContactParameters {
        let colliders = self.collision.colliders();
        let (ma, mb) = (colliders[c.collider_a].material, colliders[c.collider_b].material);
        if !self.pair_parameters.is_empty() {
            if let Some(p) = self.pair_parameters.get(&(ma.min(mb), ma.max(mb))) {
                return *p;
            }
        }
        let get = |m: u32| self.materials.get(m as usize).copied().unwrap_or(self.options.contact);
        let (a, b) = (get(ma), get(mb));
        if ma == mb {
            return a;
        }
        // Combination: geometric mean of friction, the livelier bounce, the softer contact.
        ContactParameters {
            mu: (a.mu * b.mu).sqrt(),
            mu2: match (a.mu2, b.mu2) {
                (None, None) => None,
                (x, y) => Some((x.unwrap_or(a.mu) * y.unwrap_or(b.mu)).sqrt()),
            },
            restitution: a.restitution.max(b.restitution),
            bounce_velocity: a.bounce_velocity.min(b.bounce_velocity),
            erp: a.erp.min(b.erp),
            cfm: a.cfm.max(b.cfm),
            surface_layer: a.surface_layer.max(b.surface_layer),
            max_correcting_velocity: a.max_correcting_velocity.min(b.max_correcting_velocity),
        }
    }

    /// The constraint problem of the rows in `self.builder` (W over each multibody's factor).
    /// When every multibody kept the factor W was last built on and the rows are the same up
    /// to [`WorldOptions::mass_matrix_reuse`]'s tolerance (a body at rest), W stands and only
    /// the bias is new ([`ProblemBuilder::refresh_bias`]).
    fn build_problem(&mut self) {
        if let Some(tolerance) = self.options.mass_matrix_reuse {
            let same_factors = self.built_factors.len() == self.bodies.len()
                && self.bodies.iter().zip(&self.built_factors).all(|(b, f)| b.factor_identity() == *f);
            // Contact rows kept since W was built are its rows bit for bit.
            let unchanged = self
                .kept_contact_rows
                .current()
                .filter(|(generation, _)| Some(*generation) == self.built_contact_rows)
                .map(|(_, mark)| mark);
            if same_factors && self.built_rows.same_rows(&self.builder, tolerance, unchanged) {
                self.builder.refresh_bias(&self.v_free_all, &mut self.problem);
                return;
            }
        }
        let factor_of = block_factors(&self.bodies, &self.block_owner);
        self.builder.build_into_blocks(&self.v_free_all, factor_of, false, &mut self.problem);
        self.problem_builds += 1;
        if self.options.mass_matrix_reuse.is_some() {
            self.built_rows.record(&self.builder);
            self.built_contact_rows = self.kept_contact_rows.current().map(|(generation, _)| generation);
            self.built_factors.clear();
            self.built_factors.extend(self.bodies.iter().map(Multibody::factor_identity));
        } else {
            // A record of older rows must not outlive this W (the reuse may be switched on again).
            self.built_rows.forget();
        }
    }

    /// How many times a step has built the constraint problem's W = J L⁻¹ D^{-1/2} (and
    /// A = W Wᵀ) from its rows; steps whose rows and mass-matrix factors are those of the last
    /// build keep it (see [`WorldOptions::mass_matrix_reuse`]).
    pub fn problem_builds(&self) -> u64 {
        self.problem_builds
    }

    /// How many steps kept their contact rows from an earlier step (a body at rest: see
    /// [`WorldOptions::mass_matrix_reuse`]) instead of forming them from the contacts.
    pub fn contact_row_reuses(&self) -> u64 {
        self.kept_contact_rows.reuses
    }

    /// `v_free_all += M⁻¹ Jᵀ λ`: the velocity after the solved impulses.
    fn apply_problem_impulses(&mut self) {
        let factor_of = block_factors(&self.bodies, &self.block_owner);
        self.problem.apply_impulses(&self.lambda, &mut self.v_free_all, &mut self.impulse_scratch, factor_of);
    }

    /// Marks in `speculation_forced` the contacts the speculation test left out that the
    /// velocity after the solve (`v_free_all`) would have kept: their two points approach fast
    /// enough to close the gap by the speculation's own measure. True if there is one, or if
    /// a joint-limit stop left without a row closes by the same measure (the next pass of
    /// [`World::add_rows`] judges those by the solved velocity itself).
    fn close_dropped_rows(&mut self, h: f64) -> bool {
        let limit_speculation =
            Speculation { always_within: self.options.limits.speculative_within, ..self.options.speculation };
        let v = self.v_free_all.as_slice();
        let limit_closes = self
            .limits_dropped
            .iter()
            .any(|d| limit_speculation.keeps(d.distance, d.closing_speed(v).max(0.0), h));
        if self.speculation_dropped.is_empty() {
            return limit_closes;
        }
        // The bodies' velocities after the solve, once per multibody that has a dropped contact.
        self.speculation_updated.clear();
        self.speculation_updated.resize(self.bodies.len(), false);
        for &k in &self.speculation_dropped {
            let c = &self.contacts[k];
            for side in [c.body_a, c.body_b] {
                if let Attachment::Body { multibody, .. } = side {
                    if !self.speculation_updated[multibody] {
                        self.speculation_updated[multibody] = true;
                        let b = &mut self.bodies[multibody];
                        let v = &self.v_free_all.as_slice()[b.col..b.col + b.model.nv()];
                        b.update_solved_world_velocities(v);
                    }
                }
            }
        }
        let mut found = false;
        for &k in &self.speculation_dropped {
            let c = &self.contacts[k];
            let velocity = |side, p: &Vec3| point_velocity(&self.bodies, side, p, |w| &w.solved);
            let separating = c.normal.dot(&(velocity(c.body_a, &c.point_a) - velocity(c.body_b, &c.point_b)));
            if self.options.speculation.keeps(c.distance, (-separating).max(0.0), h) {
                self.speculation_forced[k] = true;
                found = true;
            }
        }
        found || limit_closes
    }

    /// Appends this step's rows to `self.builder`. `after_solve`: the step was solved once, and
    /// limit stops are judged by the solved velocity (`Multibody::v_solved`) too.
    fn add_rows(&mut self, h: f64, after_solve: bool) {
        let mut builder = std::mem::replace(&mut self.builder, ProblemBuilder::new(0, self.options.friction));
        if self.options.speculation.speed_factor.is_finite() {
            for b in &mut self.bodies {
                b.update_world_velocities();
            }
        }
        let bodies = &self.bodies;
        let contacts = std::mem::take(&mut self.contacts);
        let (v, speculation) = (&self.v_all, self.options.speculation);
        let forced = &self.speculation_forced;
        let mut dropped = std::mem::take(&mut self.speculation_dropped);
        dropped.clear();
        // Which contacts get rows, decided before any row is formed.
        let mut has_rows = std::mem::take(&mut self.contact_has_rows);
        has_rows.clear();
        has_rows.extend(contacts.iter().enumerate().map(|(i, c)| {
            if forced[i] || speculation.keeps(c.distance, 0.0, h) {
                return true;
            }
            // The closing speed of the contact's two points under v and under v_free.
            let relative = |which: fn(&multibody::WorldVelocities) -> &[crate::math::Motion]| {
                point_velocity(bodies, c.body_a, &c.point_a, which)
                    - point_velocity(bodies, c.body_b, &c.point_b, which)
            };
            let speed = relative(|w| &w.start).norm().max(relative(|w| &w.free).norm());
            let keep = speculation.keeps(c.distance, speed, h);
            if !keep {
                dropped.push(i);
            }
            keep
        }));
        // The builder still starts with last step's contact rows: kept if they are this step's
        // rows (see `contact_rows`), with new targets; else formed anew.
        let kept =
            self.options.mass_matrix_reuse.filter(|_| !after_solve).and_then(|tolerance| {
                self.kept_contact_rows.hold(tolerance, h, bodies, &contacts, &has_rows)
            });
        if let Some(mark) = kept {
            builder.truncate(mark);
            let with_rows = contacts.iter().zip(&has_rows).filter(|(_, rows)| **rows).map(|(c, _)| c);
            // The approach speed from the bodies' world velocities when the speculation test
            // formed them (O(1) per contact; the same J v as the normal row's, up to the kept
            // rows' tolerance), else from the row.
            let world_velocities = speculation.speed_factor.is_finite();
            let velocity = |side, p: &Vec3| point_velocity(bodies, side, p, |w| &w.start);
            for (k, c) in with_rows.enumerate() {
                let normal = builder.contact_blocks()[k].normal;
                let approach = if world_velocities {
                    c.normal.dot(&(velocity(c.body_a, &c.point_a) - velocity(c.body_b, &c.point_b)))
                } else {
                    builder.row_dot(normal, v.as_slice())
                };
                builder.set_target(
                    normal,
                    self.parameters_of(c).target_normal_velocity(c.distance, approach, h),
                );
            }
            self.kept_contact_rows.reuses += 1;
        } else {
            builder.clear();
            add_contact_rows_with(
                &mut builder,
                |m| (&bodies[m].model, &bodies[m].data, bodies[m].col),
                &contacts,
                0,
                v,
                h,
                |c| self.parameters_of(c),
                |i, _| has_rows[i],
            );
            if self.options.mass_matrix_reuse.is_some() {
                self.kept_contact_rows.record(h, bodies, &contacts, &has_rows, builder.mark());
            } else {
                self.kept_contact_rows.invalidate();
            }
        }
        self.contacts = contacts;
        self.contact_has_rows = has_rows;
        self.speculation_dropped = dropped;
        let mut limits_dropped = std::mem::take(&mut self.limits_dropped);
        limits_dropped.clear();
        for b in bodies.iter().filter(|b| !b.asleep && !b.kinematic) {
            let solved = after_solve.then_some(&b.v_solved);
            add_joint_limit_rows_speculative(
                &mut builder,
                &b.model,
                &b.state.q,
                LimitVelocities { start: &b.state.v, free: &b.v_free, solved },
                b.col,
                h,
                &self.options.limits,
                Speculation { always_within: self.options.limits.speculative_within, ..speculation },
                &mut limits_dropped,
            );
            for (k, motor) in b.motors.iter().enumerate() {
                if let Some(m) = motor {
                    add_motor_row(&mut builder, k, b.col, m.target_velocity, m.max_force, h);
                }
            }
            for (k, servo) in b.servos.iter().enumerate() {
                if let Some(s) = servo {
                    let qk = position_of_dof(&b.model, &b.state.q, k);
                    let rate = (s.gain * (s.target_position - qk)).clamp(-s.max_velocity, s.max_velocity);
                    add_motor_row(&mut builder, k, b.col, rate, s.max_force, h);
                }
            }
            if let Some(servo) = &b.pose_servo {
                add_pose_servo_rows(&mut builder, b, servo, h);
            }
            add_joint_friction_rows(&mut builder, &b.model, b.col, h);
        }
        for (index, (a, b, closure)) in self.loops.iter().enumerate() {
            let (a, b) = (&bodies[*a], &bodies[*b]);
            if !a.asleep || !b.asleep {
                add_loop_closure_rows_between(
                    &mut builder,
                    (&a.model, &a.data, a.col),
                    (&b.model, &b.data, b.col),
                    closure,
                    index,
                    h,
                );
            }
        }
        self.limits_dropped = limits_dropped;
        self.builder = builder;
    }

    fn row_key(&self, i: usize, counter: &mut (usize, u64)) -> u64 {
        let origin = self.problem.origins[i];
        // Rows of one origin are numbered in order so that each gets its own key.
        let base = match origin {
            RowOrigin::Contact(k) => {
                let c = &self.contacts[k];
                (c.collider_a as u64) << 40 ^ (c.collider_b as u64) << 20 ^ c.feature.rotate_left(7)
            }
            RowOrigin::LowerLimit(k) => 1 << 62 | k as u64,
            RowOrigin::UpperLimit(k) => 2 << 61 | k as u64,
            RowOrigin::SwingLimit(k) => 9 << 57 | k as u64,
            RowOrigin::TwistLowerLimit(k) => 11 << 56 | k as u64,
            RowOrigin::TwistUpperLimit(k) => 13 << 55 | k as u64,
            RowOrigin::Motor(k) => 3 << 60 | k as u64,
            RowOrigin::JointFriction(k) => 5 << 59 | k as u64,
            RowOrigin::Loop(k) => 7 << 58 | k as u64,
            RowOrigin::Other => 0,
        };
        if counter.1 == base && i > 0 {
            counter.0 += 1;
        } else {
            *counter = (0, base);
        }
        base.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ counter.0 as u64
    }

    /// λ's warm start: each row's impulse of the last step, matched by its key. Rows mostly come
    /// in the same order as last step (collision pairs and their features are enumerated in a
    /// stable order), so keys are matched by a cursor over last step's rows; only a row that
    /// breaks the order is looked up in an index, built at most once per step. A contact whose
    /// key is new takes the impulses of last step's contact of the same collider pair nearest
    /// to it (within [`WARM_MATCH_DISTANCE`]) that no other contact took: parry's feature ids
    /// of one resting contact change from step to step (a capsule's segment against a box edge
    /// reports its features, then none), and in a pile of 20 ragdolls 5 % of the contacts
    /// with rows lost their impulses every step that way. When the rows are the last solve's
    /// (its kept contact rows, the same other rows in the same order: a body at rest), λ holds
    /// their impulses already and no key is formed.
    fn warm_start(&mut self) {
        let n = self.problem.rows();
        // The rows of the last solve, in its order (its kept contact rows, the same other rows):
        // λ holds their impulses already.
        let generation = self.kept_contact_rows.current().map(|(generation, _)| generation);
        self.warm_same_rows = generation.is_some()
            && generation == self.warm_generation
            && self.lambda.len() == n
            && self.warm_values.len() == n
            && self.problem.origins == self.warm_origins;
        if self.warm_same_rows {
            return;
        }
        if self.lambda.len() != n {
            self.lambda = DVector::zeros(n);
        }
        let mut counter = (0, u64::MAX);
        let mut keys = std::mem::take(&mut self.row_keys);
        keys.clear();
        keys.extend((0..n).map(|i| self.row_key(i, &mut counter)));
        let (mut cursor, mut indexed) = (0, false);
        self.warm_matched.clear();
        self.warm_missed.clear();
        for (i, key) in keys.iter().enumerate() {
            let found = if self.warm_keys.get(cursor) == Some(key) {
                Some(cursor)
            } else {
                if !indexed {
                    self.warm_index.clear();
                    self.warm_index.extend(self.warm_keys.iter().enumerate().map(|(p, k)| (*k, p)));
                    indexed = true;
                }
                self.warm_index.get(key).copied()
            };
            match found {
                Some(p) => {
                    self.lambda[i] = self.warm_values[p];
                    cursor = p + 1;
                    self.warm_matched.push(p);
                }
                None => {
                    self.lambda[i] = 0.0;
                    self.warm_missed.push(i);
                }
            }
        }
        self.row_keys = keys;
        if !self.warm_missed.is_empty() {
            self.match_moved_contacts();
        }
    }

    /// The second pass of [`World::warm_start`]: a contact none of whose rows matched a key
    /// takes the impulses of the nearest untaken contact of its pair with as many rows.
    fn match_moved_contacts(&mut self) {
        // Last step's contacts that a key matched (by their first row) are taken.
        self.warm_taken.clear();
        self.warm_taken.resize(self.warm_contacts.len(), false);
        for &p in &self.warm_matched {
            if let Ok(e) = self.warm_contacts.binary_search_by_key(&p, |c| c.first_row) {
                self.warm_taken[e] = true;
            }
        }
        let origins = &self.problem.origins;
        let mut m = 0;
        while m < self.warm_missed.len() {
            let i = self.warm_missed[m];
            let origin = origins[i];
            // A contact's first row, and all its rows missed (consecutive in `warm_missed`).
            let count = origin_run(origins, i);
            let whole = (i == 0 || origins[i - 1] != origin)
                && self.warm_missed.get(m + count - 1) == Some(&(i + count - 1));
            let (RowOrigin::Contact(k), true) = (origin, whole) else {
                m += 1;
                continue;
            };
            m += count;
            let c = &self.contacts[k];
            let mut best = (WARM_MATCH_DISTANCE * WARM_MATCH_DISTANCE, None);
            for (e, w) in self.warm_contacts.iter().enumerate() {
                if w.pair == (c.collider_a, c.collider_b) && w.rows == count && !self.warm_taken[e] {
                    let d2 = (w.point - c.point_a).norm_squared();
                    if d2 <= best.0 {
                        best = (d2, Some(e));
                    }
                }
            }
            if let (_, Some(e)) = best {
                self.warm_taken[e] = true;
                let first = self.warm_contacts[e].first_row;
                for r in 0..count {
                    self.lambda[i + r] = self.warm_values[first + r];
                }
            }
        }
    }

    /// Keeps this step's impulses with their row keys for the next step's warm start.
    fn remember_impulses(&mut self) {
        self.warm_values.clear();
        self.warm_values.extend_from_slice(self.lambda.as_slice());
        self.warm_generation = self.kept_contact_rows.current().map(|(generation, _)| generation);
        if self.warm_same_rows {
            // Keys and contacts describe these rows already (a contact's point has moved by less
            // than the kept rows' tolerance).
            return;
        }
        std::mem::swap(&mut self.warm_keys, &mut self.row_keys);
        self.warm_origins.clone_from(&self.problem.origins);
        self.warm_contacts.clear();
        let (n, origins) = (self.problem.rows(), &self.problem.origins);
        let mut i = 0;
        while i < n {
            let count = origin_run(origins, i);
            if let RowOrigin::Contact(k) = origins[i] {
                let c = &self.contacts[k];
                self.warm_contacts.push(WarmContact {
                    pair: (c.collider_a, c.collider_b),
                    point: c.point_a,
                    first_row: i,
                    rows: count,
                });
            }
            i += count;
        }
    }
}

/// The world velocity (m/s) of the point `p` (world) moving with `side`, from the spatial
/// velocities per body that `which` picks of its multibody's [`multibody::WorldVelocities`]
/// (under the start, free or solved velocity); zero for static geometry.
fn point_velocity(
    bodies: &[Multibody],
    side: Attachment,
    p: &Vec3,
    which: impl Fn(&multibody::WorldVelocities) -> &[crate::math::Motion],
) -> Vec3 {
    match side {
        Attachment::Body { multibody, body } => {
            let at = &which(&bodies[multibody].world_velocities)[body];
            at.linear + at.angular.cross(p)
        }
        Attachment::World => Vec3::zeros(),
    }
}

/// How far (m) a contact's point may have moved since the last step for it to take that
/// step's impulses of its collider pair when its feature key changed (the world's warm start).
/// Below the spacing of two contacts of one pair (a box's corners, a capsule's two ends), above
/// what a resting contact moves.
pub const WARM_MATCH_DISTANCE: f64 = 0.005;

/// Per block of the stacked mass matrix, the factor of its multibody and the block's first dof
/// in it; none for a block that cannot move (asleep, kinematic or unfactored).
fn block_factors<'a>(
    bodies: &'a [Multibody],
    owners: &'a [(usize, usize)],
) -> impl Fn(usize) -> Option<(TreeFactor<'a>, usize)> + 'a {
    move |block| {
        let (k, first_dof) = owners[block];
        let b = &bodies[k];
        let movable = !(b.asleep || b.kinematic || !b.factored);
        movable.then(|| (TreeFactor::new(&b.model, &b.data), first_dof))
    }
}

/// Solves per step after the first for contacts and limit stops that the speculation test left
/// out and the solved velocity closes ([`World::close_dropped_rows`]): each pass adds those it
/// finds.
const SPECULATION_PASSES: usize = 2;

/// The number of rows from row `i` on that share its origin (a contact's rows are consecutive).
fn origin_run(origins: &[RowOrigin], i: usize) -> usize {
    origins[i..].iter().take_while(|o| **o == origins[i]).count()
}

/// A contact of the last step with rows, for [`World::warm_start`]'s second pass.
#[derive(Clone, Copy, Debug)]
struct WarmContact {
    pair: (usize, usize),
    /// Its point on collider A (world, m).
    point: Vec3,
    /// Its first row and number of rows in last step's problem.
    first_row: usize,
    rows: usize,
}

fn check_finite(
    name: &str,
    model: &Model,
    q: &DVector<f64>,
    v: &DVector<f64>,
    after: bool,
) -> Result<(), StepError> {
    if crate::math::all_finite(q.as_slice()) && crate::math::all_finite(v.as_slice()) {
        return Ok(());
    }
    let joint_of_q = |k: usize| (1..model.nbodies()).rev().find(|&i| model.idx_q(i) <= k).unwrap_or(0);
    let joint_of_v = |k: usize| if k < model.nv() { model.dof_joint(k) } else { 0 };
    if let Some(k) = q.iter().position(|x| !x.is_finite()) {
        return Err(StepError::NonFinite {
            multibody: name.to_string(),
            joint: model.joint_name(joint_of_q(k)).to_string(),
            what: if after { "new q" } else { "q" },
        });
    }
    if let Some(k) = v.iter().position(|x| !x.is_finite()) {
        return Err(StepError::NonFinite {
            multibody: name.to_string(),
            joint: model.joint_name(joint_of_v(k)).to_string(),
            what: if after { "new v" } else { "v" },
        });
    }
    Ok(())
}

/// Whether some scalar joint coordinate, or some ball joint's swing or twist, of the multibody is
/// within `margin` of a limit.
fn has_active_limit(b: &Multibody, margin: f64) -> bool {
    let (lo, hi) = (b.model.lower_position_limit(), b.model.upper_position_limit());
    (1..b.model.nbodies()).any(|i| {
        let joint = b.model.joint(i);
        if let Some(limits) = b.model.ball_limits(i) {
            let iq = b.model.idx_q(i);
            let (distances, _) = limits.distances(&b.state.q.as_slice()[iq..iq + 4]);
            return distances.iter().any(|d| *d <= margin);
        }
        let scalar = !matches!(joint, crate::model::Joint::Ball | crate::model::Joint::Free);
        scalar
            && (b.model.idx_q(i)..b.model.idx_q(i) + joint.nq()).any(|k| {
                (lo[k].is_finite() && b.state.q[k] - lo[k] <= margin)
                    || (hi[k].is_finite() && hi[k] - b.state.q[k] <= margin)
            })
    })
}

/// Motor rows of a [`PoseServo`]: for every joint but free ones, the rate `gain · (q_target ⊖ q)`
/// (per dof, clamped to `max_velocity`; for a ball joint the rotation vector of `q⁻¹ q_target`
/// in the child frame), with each dof's force bound. Dofs with their own motor or servo are left
/// to it.
fn add_pose_servo_rows(builder: &mut ProblemBuilder, b: &Multibody, servo: &PoseServo, h: f64) {
    let model = &b.model;
    for j in 1..model.nbodies() {
        let joint = model.joint(j);
        if matches!(joint, crate::model::Joint::Free) {
            continue;
        }
        let (iq, iv, nq, nv) = (model.idx_q(j), model.idx_v(j), joint.nq(), joint.nv());
        let mut error = [0.0; 6];
        joint.difference(
            &b.state.q.as_slice()[iq..iq + nq],
            &servo.target.as_slice()[iq..iq + nq],
            &mut error[..nv],
        );
        for (k, e) in error[..nv].iter().enumerate() {
            let dof = iv + k;
            if b.motors[dof].is_some() || b.servos[dof].is_some() {
                continue;
            }
            let rate = (servo.gain * e).clamp(-servo.max_velocity, servo.max_velocity);
            add_motor_row(builder, dof, b.col, rate, servo.max_force[dof], h);
        }
    }
}

/// The position coordinate of velocity dof `k` for joints whose coordinates are scalars.
fn position_of_dof(model: &Model, q: &DVector<f64>, k: usize) -> f64 {
    let j = model.dof_joint(k);
    let joint = model.joint(j);
    if joint.nq() == joint.nv() {
        q[model.idx_q(j) + (k - model.idx_v(j))]
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::RigidInertia;
    use crate::report::stability::free_body;

    /// A 0.2 m box resting on the ground for 100 steps: four contacts with impulses.
    fn resting_box() -> World {
        let mut w = World::new(WorldOptions::default());
        w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
        let size = Vec3::repeat(0.2);
        let model = free_body("box", Shape::Box { size }, RigidInertia::solid_box(2.0, size));
        let i = w.add_multibody("box", model, &MeshOptions::default()).unwrap();
        w.bodies[i].state.q[2] = 0.1;
        w.set_sleep(SleepOptions { enabled: false, ..w.options.sleep });
        for _ in 0..100 {
            w.step().unwrap();
        }
        w
    }

    /// The ragdoll scene, sleeping off, after 1500 steps: at rest on the ground.
    fn resting_ragdoll() -> crate::io::scene::Scene {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ragdoll_fall.toml");
        let mut s = crate::io::scene::load_file(path).unwrap();
        s.world.set_sleep(crate::world::SleepOptions { enabled: false, ..s.world.options().sleep });
        for _ in 0..1500 {
            s.world.step().unwrap();
        }
        s
    }

    /// The free motion with the factor kept from an earlier step (the joints moved by less than
    /// the 1e-8 tolerance since) equals the one with a new factorization to 1e-8 m/s, a hundredth
    /// of the solver's tolerance (measured: up to 1.3e-9 m/s; the free motion itself is ~0.02 m/s,
    /// gravity over a step), on a resting ragdoll (joint damping: M + h·D).
    #[test]
    fn a_kept_mass_matrix_factor_gives_the_free_motion_of_a_new_one() {
        let mut s = resting_ragdoll();
        let h = s.world.options().dt;
        let mut compared = 0;
        for _ in 0..50 {
            s.world.step().unwrap();
            let b = &mut s.world.bodies[0];
            let factored = b.factorizations();
            b.free_motion(h, true, Some(1e-8)).unwrap();
            if b.factorizations() != factored {
                continue;
            }
            let kept = b.v_free.clone();
            b.free_motion(h, true, None).unwrap();
            let gap = (&kept - &b.v_free).amax();
            assert!(gap < 1e-8, "kept factor against a new one: {gap:e} m/s");
            assert!(b.v_free.amax() > 1e-3, "the free motion is not trivial: {}", b.v_free.amax());
            compared += 1;
        }
        assert!(compared >= 40, "{compared} of 50 steps kept the factor");
    }

    #[test]
    fn a_kept_delassus_matrix_and_a_new_one_pose_the_same_problem() {
        let mut s = resting_ragdoll();
        let w = &mut s.world;
        let mut compared = 0;
        for _ in 0..50 {
            let builds = w.problem_builds();
            w.step().unwrap();
            if w.problem_builds() != builds {
                continue;
            }
            // The same rows built anew, on the factors and free velocity of this step.
            let mut v_free = w.v_free_all.clone();
            for b in &w.bodies {
                v_free.rows_mut(b.col, b.model.nv()).copy_from(&b.v_free);
            }
            let mut fresh = ConstraintProblem::default();
            let factor_of = block_factors(&w.bodies, &w.block_owner);
            w.builder.build_into_blocks(&v_free, factor_of, false, &mut fresh);
            let (kept, new) = (w.problem.delassus_dense(), fresh.delassus_dense());
            let scale = new.amax();
            let gap = (&*kept - &*new).amax();
            assert!(gap <= 1e-8 * scale, "kept A against a new one: {gap:e} of {scale:e}");
            let bias_gap = (&w.problem.bias - &fresh.bias).amax();
            assert!(bias_gap <= 1e-12, "bias: {bias_gap:e} m/s");
            assert_eq!(w.problem.laws, fresh.laws);
            assert_eq!(w.problem.contacts, fresh.contacts);
            assert!(fresh.rows() > 20, "{} rows", fresh.rows());
            compared += 1;
        }
        assert!(compared >= 40, "{compared} of 50 resting steps kept W");
    }

    /// A resting ragdoll keeps its contact rows on most steps, and the kept rows are the rows
    /// formed anew from the step's contacts: Jacobian entries to 1e-7 (m/s per unit rate; the
    /// tolerance is 1e-8 in every coordinate and contact point), targets to 1e-9 m/s, the same
    /// laws and contact blocks. Moving the ragdoll by a micrometre forms them anew.
    #[test]
    fn kept_contact_rows_are_the_rows_formed_anew() {
        let mut s = resting_ragdoll();
        let w = &mut s.world;
        let mut compared = 0;
        for _ in 0..50 {
            let reuses = w.contact_row_reuses();
            w.step().unwrap();
            if w.contact_row_reuses() == reuses {
                continue;
            }
            let mut fresh = ProblemBuilder::with_blocks(w.nv_total, &w.blocks, w.options.friction).unwrap();
            let bodies = &w.bodies;
            let (has_rows, h) = (&w.contact_has_rows, w.options.dt);
            add_contact_rows_with(
                &mut fresh,
                |m| (&bodies[m].model, &bodies[m].data, bodies[m].col),
                &w.contacts,
                0,
                &w.v_all,
                h,
                |c| w.parameters_of(c),
                |i, _| has_rows[i],
            );
            assert!(fresh.contact_count() >= 5, "{} contacts with rows", fresh.contact_count());
            assert_eq!(fresh.contact_blocks(), &w.builder.contact_blocks()[..fresh.contact_count()]);
            for i in 0..fresh.len() {
                let gap = (DVector::from_vec(fresh.row(i)) - DVector::from_vec(w.builder.row(i))).amax();
                assert!(gap <= 1e-7, "row {i}: kept against new {gap:e}");
                let target_gap = (fresh.target(i) - w.builder.target(i)).abs();
                assert!(target_gap <= 1e-9, "row {i}: target {target_gap:e} m/s");
            }
            compared += 1;
        }
        assert!(compared >= 40, "{compared} of 50 resting steps kept the contact rows");
        // A micrometre is far beyond the tolerance: the next step forms its rows anew.
        w.multibody_mut(0).state.q[0] += 1e-6;
        let reuses = w.contact_row_reuses();
        w.step().unwrap();
        assert_eq!(w.contact_row_reuses(), reuses);
    }

    /// The step reads no clock unless asked to: zeros by default, the phases' times when on.
    #[test]
    fn a_step_times_its_phases_only_when_asked() {
        let mut w = resting_box();
        assert!(!w.options().time_phases);
        assert_eq!(w.step().unwrap().phase_ns, [0; 6]);
        w.set_phase_timing(true);
        let phases = w.step().unwrap().phase_ns;
        assert!(phases.iter().sum::<u64>() > 0, "{phases:?}");
    }

    /// Through the ragdoll's landing (subspace steps accepted, their Wᵀλ handed to PGS), the
    /// Wᵀλ that the solve leaves for the step's impulses (which `apply_impulses` turns into the
    /// velocity change) is Wᵀλ formed afresh, to 1e-9 of its size.
    #[test]
    fn the_impulse_sum_a_solve_keeps_is_that_of_its_impulses() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ragdoll_fall.toml");
        let mut s = crate::io::scene::load_file(path).unwrap();
        let w = &mut s.world;
        let mut compared = 0;
        for step in 0..700 {
            w.step().unwrap();
            let p = &w.problem;
            if step < 200 || !p.is_matrix_free() || p.rows() == 0 {
                continue;
            }
            let lambda = w.lambda.as_slice();
            let mut kept = vec![0.0; p.sparsity.nv];
            if !p.kept_impulse_sum(lambda, &mut kept) {
                continue;
            }
            let mut fresh = vec![0.0; p.sparsity.nv];
            for (i, &l) in lambda.iter().enumerate() {
                for (col, wi) in p.sparsity.row_spans(i) {
                    for (f, wi) in fresh[col..col + wi.len()].iter_mut().zip(wi) {
                        *f += l * wi;
                    }
                }
            }
            let scale = fresh.iter().fold(1e-6_f64, |m, x| m.max(x.abs()));
            let gap = kept.iter().zip(&fresh).fold(0.0_f64, |m, (k, f)| m.max((k - f).abs()));
            assert!(gap <= 1e-9 * scale, "step {step}: kept Wᵀλ off by {gap:e} of {scale:e}");
            compared += 1;
        }
        assert!(compared >= 300, "{compared} of 500 landing steps compared");
    }

    #[test]
    fn a_contact_whose_feature_id_changed_keeps_its_impulses_and_one_that_moved_does_not() {
        let mut w = resting_box();
        let before = w.lambda.clone();
        assert_eq!(w.contacts.len(), 4);
        assert!(before.iter().filter(|x| **x > 0.0).count() >= 4, "{before}");
        // The resting box's rows are the last solve's (kept contact rows): λ stands as it is,
        // and matching the rows by their keys gives the same λ.
        w.warm_start();
        assert!(w.warm_same_rows);
        assert_eq!(w.lambda, before);
        w.kept_contact_rows.invalidate();
        w.warm_start();
        assert!(!w.warm_same_rows);
        assert_eq!(w.lambda, before);
        // The same contacts with other feature ids (parry's ids of a resting contact flip), and
        // the last one moved by 1 cm (whose rows a step would form anew): its impulses are not
        // the old contact's.
        for c in &mut w.contacts {
            c.feature ^= 0xdead_beef;
        }
        w.contacts[3].point_a.x += 0.01;
        w.warm_start();
        let origins = w.problem.origins.clone();
        let rows_of = |k: usize| {
            (0..origins.len()).filter(|&r| origins[r] == RowOrigin::Contact(k)).collect::<Vec<_>>()
        };
        for k in 0..3 {
            for r in rows_of(k) {
                assert_eq!(w.lambda[r], before[r], "contact {k} row {r}");
            }
        }
        assert!(rows_of(3).iter().all(|&r| w.lambda[r] == 0.0), "{}", w.lambda);
    }
}
