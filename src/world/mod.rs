//! [`World`]: several multibodies and static geometry stepped together with contacts, joint
//! limits, motors, servos, joint friction and loop closures as one constraint problem per step.
//!
//! [`World::step`] is the table of contents (docs/architecture.md), one stage per file of
//! `src/world/stages/`: check state finite → kinematics → collision → free motion → constraint
//! rows and their problem → solve and velocity update (warm-started, `warm_start.rs`) → rows for
//! the speculative contacts and limit stops that the solved velocity closes, and solve again →
//! a lone free body's origin along the step's mean velocity where no contact normal constrains
//! it (`stages/midpoint.rs`) → the contacts' position correction from their predicted gaps ([`ContactProjection`],
//! `contact_projection.rs`) → integrate q on the manifold (free origins on straight lines, see
//! [`crate::model::Joint::integrate_decoupled`]), the correction included, and close the loop
//! closures at the new configuration (SHAKE, [`LoopProjection`]; a linkage whose only rows are
//! its own closures is stepped by RATTLE instead, `rattle.rs`) → the contacts detected again at
//! the new configuration when the step moved them, and corrected again → sleeping (`sleep.rs`)
//! and statistics ([`StepStats`]).
//! Steps without any row skip the solver (and, without implicit springs or damping, use ABA
//! instead of CRBA); sleeping islands are skipped entirely. With an integrator other than the
//! default semi-implicit Euler ([`WorldOptions::integrator`]), steps without contacts, limits,
//! motors or joint friction replace free motion, rows, solve and integration by that integrator
//! (loop closures at the acceleration level): see [`smooth`].
//!
//! A world's state is grouped by responsibility: the multibodies and their names, the stacked
//! dofs and velocities (`dofs`), the loop closures (`loops`), the collision world and the
//! contact materials (`materials`), the rows (`stages/rows.rs`), the speculation
//! (`stages/speculation.rs`), the problem and its solve (`stages/solve.rs`), sleeping islands,
//! and the statistics of the last step.

mod contact_projection;
mod contact_rows;
mod dofs;
pub mod gyroscopic;
mod loops;
mod materials;
mod multibody;
mod options;
mod projection;
mod rattle;
mod sleep;
pub mod smooth;
mod stages;
mod stats;
#[cfg(test)]
mod tests;
mod warm_start;

pub use contact_projection::{ContactProjection, ProjectionStats};
pub use multibody::{Motor, Multibody, PoseServo, Servo};
pub use options::{SleepOptions, SolverKind, WorldOptions, CHAIN_NEWTON_ITERATIONS};
pub use projection::LoopProjection;
pub use smooth::{integrator_name, parse_integrator, INTEGRATOR_NAMES};
pub use stats::{StepStats, PHASE_NAMES};
pub use warm_start::WARM_MATCH_DISTANCE;

use crate::collision::{CollisionWorld, Contact, MeshOptions};
use crate::constraints::{
    ConstraintProblem, ContactParameters, FrictionModel, LoopClosure, ProblemBuilder, Speculation,
};
use crate::error::CollisionError;
use crate::error::DynamicsError;
use crate::integrators::{IntegratorError, IntegratorKind};
use crate::math::{Transform, Vec3};
use crate::model::{Model, Shape};
use crate::solvers::{ChainReport, SolverError};
use dofs::StackedDofs;
use loops::Loops;
use materials::Materials;
use nalgebra::DVector;
use stages::rows::{RowAssembly, RowSources};
use stages::solve::{Softening, Solve};
use stages::speculation::SpeculationState;
use stats::{Phase, PhaseTimer};
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
    /// A thread count of 0, or above 1 without the `parallel` feature
    /// ([`World::set_threads`]).
    #[error("threads: {0}")]
    Threads(String),
    /// A setting of [`WorldOptions`] the step cannot use ([`WorldOptions::check`]).
    #[error("world option `{name}` = {value}: expected {expected}")]
    InvalidOption {
        /// The option's field name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        expected: &'static str,
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

/// A simulated world.
pub struct World {
    options: WorldOptions,
    /// The multibodies, in the order they were added, and their names.
    bodies: Vec<Multibody>,
    names: Vec<String>,
    /// Their dofs stacked into one vector, and the stacked velocities of the step.
    dofs: StackedDofs,
    /// Loop closures within and between multibodies.
    loops: Loops,
    collision: CollisionWorld,
    materials: Materials,
    /// The contacts of the last step.
    contacts: Vec<Contact>,
    /// The step's constraint rows.
    rows: RowAssembly,
    /// The contacts and limit stops the speculation test left without rows.
    speculation: SpeculationState,
    /// The solver chain, the step's problem and its impulses, the warm start.
    solve: Solve,
    /// The contacts' position correction after the solve ([`WorldOptions::contact_projection`]).
    projector: contact_projection::ContactProjector,
    /// The contacts at the end of a step, their rows and problem (the projection's check).
    end_contacts: contact_projection::EndContacts,
    /// The sweeps' statistics and diagnostics of the step's detection.
    sweep_record: (crate::collision::SweepStats, Vec<crate::collision::SweepDiagnostic>),
    /// The integrators of smooth steps, built at the first smooth step.
    smooth: smooth::SmoothSteppers,
    islands: sleep::Islands,
    time: f64,
    steps: u64,
    /// Simulated time owed to [`World::advance`] (s).
    accumulator: f64,
    stats: StepStats,
    /// Bodies swept by continuous collision at any speed ([`World::set_always_swept`]).
    always_swept: Vec<(usize, usize)>,
    /// Multibodies the last step advanced by RATTLE ([`rattle`]).
    rattled: usize,
}

/// A world is `Send`: it can be built on one thread and stepped on another (batched rollouts
/// step one world per thread). Checked at compile time.
const _: fn() = || {
    fn send<T: Send>() {}
    send::<World>();
    send::<crate::io::scene::Scene>();
};

impl World {
    /// An empty world.
    pub fn new(options: WorldOptions) -> Self {
        Self {
            collision: CollisionWorld::new(options.collision),
            solve: Solve::new(&options),
            projector: contact_projection::ContactProjector::default(),
            end_contacts: contact_projection::EndContacts::new(),
            sweep_record: Default::default(),
            rows: RowAssembly::new(ProblemBuilder::new(0, options.friction)),
            materials: Materials::new(options.contact),
            options,
            bodies: Vec::new(),
            names: Vec::new(),
            dofs: StackedDofs::new(),
            loops: Loops::default(),
            contacts: Vec::new(),
            speculation: SpeculationState::default(),
            smooth: smooth::SmoothSteppers::default(),
            islands: sleep::Islands::default(),
            time: 0.0,
            steps: 0,
            accumulator: 0.0,
            stats: StepStats::default(),
            always_swept: Vec::new(),
            rattled: 0,
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
        let blocks_before = self.dofs.blocks.len();
        self.dofs.add(index, &mut body);
        self.bodies.push(body);
        self.loops.projections.push(None);
        self.names.push(name.to_string());
        self.rows
            .builder
            .append_blocks(self.dofs.nv, &self.dofs.blocks[blocks_before..])
            .map_err(StepError::Solver)?;
        self.rows.kept.invalidate();
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
        self.rows.kept.invalidate();
        Ok(c)
    }

    /// Turns self-collision of a multibody on or off.
    pub fn set_self_collision(&mut self, multibody: usize, on: bool) -> Result<(), StepError> {
        Ok(self.collision.set_self_collision(multibody, on)?)
    }

    /// Defines material `index` (0 is the default material of every collider).
    pub fn set_material(&mut self, index: u32, parameters: ContactParameters) {
        self.materials.set(index, parameters);
        self.rows.kept.invalidate();
    }

    /// Parameters used when materials `a` and `b` touch, overriding the combination rule.
    pub fn set_pair_parameters(&mut self, a: u32, b: u32, parameters: ContactParameters) {
        self.materials.set_pair(a, b, parameters);
        self.rows.kept.invalidate();
    }

    /// Replaces the solver chain (the first solver whose answer is certified is used); the
    /// warm-start memory is kept.
    pub fn set_solvers(&mut self, solvers: Vec<SolverKind>) {
        self.options.solvers = solvers;
        self.solve.set_chain(&self.options);
    }

    /// Solves the islands of each step's constraint problem on `threads` threads (1: on the
    /// calling thread, the default). The trajectory is the same bit for bit for any count
    /// (island k is always solved by the same solver chain, see `stages/islands.rs`). Above 1
    /// needs the `parallel` feature; 0 is refused.
    pub fn set_threads(&mut self, threads: usize) -> Result<(), StepError> {
        self.solve.islands.set_threads(threads).map_err(StepError::Threads)
    }

    /// Threads the islands of a step are solved on ([`World::set_threads`]).
    pub fn threads(&self) -> usize {
        self.solve.islands.threads()
    }

    /// Replaces the friction model of the contact rows ([`WorldOptions::friction`]) from the next
    /// step on.
    pub fn set_friction(&mut self, friction: FrictionModel) -> Result<(), StepError> {
        self.rows.builder = ProblemBuilder::with_blocks(self.dofs.nv, &self.dofs.blocks, friction)
            .map_err(StepError::Solver)?;
        self.rows.kept.invalidate();
        self.options.friction = friction;
        self.solve.set_chain(&self.options);
        Ok(())
    }

    /// Sets the relative softness of the rows ([`WorldOptions::softness`]) from the next step
    /// on; a negative or non-finite value makes that step fail with
    /// [`StepError::InvalidOption`].
    pub fn set_softness(&mut self, relative: f64) {
        self.options.softness = relative;
    }

    /// Sets the share β of the softened rows' impulses carried by their dampers
    /// ([`WorldOptions::softness_damping`]) from the next step on; a value outside [0, 1] makes
    /// that step fail with [`StepError::InvalidOption`].
    pub fn set_softness_damping(&mut self, beta: f64) {
        self.options.softness_damping = beta;
    }

    /// Replaces the integrator of smooth steps ([`WorldOptions::integrator`]).
    pub fn set_integrator(&mut self, integrator: IntegratorKind) {
        self.options.integrator = integrator;
    }

    /// Replaces the contacts' position correction after each step
    /// ([`WorldOptions::contact_projection`]) from the next step on.
    pub fn set_contact_projection(&mut self, projection: ContactProjection) {
        self.options.contact_projection = projection;
    }

    /// Turns the automatic sweeping of fast colliders on or off
    /// ([`WorldOptions::continuous_collision`]).
    pub fn set_continuous_collision(&mut self, on: bool) {
        self.options.continuous_collision = on;
    }

    /// Sweeps body `body` of multibody `multibody` along its motion at every step, whatever its
    /// speed (`on`), or only when it moves fast and [`WorldOptions::continuous_collision`] is on
    /// (`!on`). A body without a collider is accepted and reported in each step's
    /// [`StepStats::sweep_diagnostics`] ([`crate::collision::SweepDiagnostic::NoShape`]).
    pub fn set_always_swept(&mut self, multibody: usize, body: usize, on: bool) -> Result<(), StepError> {
        self.check_multibody(multibody)?;
        let count = self.bodies[multibody].model.nbodies();
        if body == 0 || body >= count {
            return Err(StepError::IndexOutOfRange { what: "bodies", index: body, count });
        }
        self.always_swept.retain(|&x| x != (multibody, body));
        if on {
            self.always_swept.push((multibody, body));
        }
        Ok(())
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
    /// multibodies then sleep and wake together. Closures within one multibody are also closed
    /// at each step's new configuration ([`WorldOptions::loop_projection`]);
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
        self.loops.closures.push((multibody_a, multibody_b, closure));
        if multibody_a == multibody_b {
            let m = multibody_a;
            let rows = projection::ProjectionBuffers::rows_for(loops::own(&self.loops.closures, m));
            let model = &self.bodies[m].model;
            self.loops.projections[m] = Some(projection::ProjectionBuffers::new(model, rows));
        }
        Ok(())
    }

    /// The collision world (colliders, materials, filters).
    pub fn collision(&self) -> &CollisionWorld {
        &self.collision
    }

    /// The collision world, mutably (filters, materials, self-collision).
    pub fn collision_mut(&mut self) -> &mut CollisionWorld {
        // Colliders' materials may change: the contact rows are formed anew.
        self.rows.kept.invalidate();
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
        &self.solve.problem
    }

    /// Impulses of the last step (N·s), one per row of [`World::problem`].
    pub fn impulses(&self) -> &DVector<f64> {
        &self.solve.lambda
    }

    /// Wakes multibody `i` (and lets its island be evaluated again).
    pub fn wake(&mut self, i: usize) {
        sleep::wake(&mut self.bodies, &mut self.collision, i);
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
        let mut timer = PhaseTimer::start(self.options.time_phases);
        self.options.check()?;
        stages::check::states(&self.bodies, &self.names)?;
        stages::kinematics::run(&mut self.bodies, &self.names, &mut self.collision)?;
        timer.lap(Phase::Kinematics);
        let sweeps = stages::collision::Sweeps {
            continuous: self.options.continuous_collision,
            always: &self.always_swept,
        };
        stages::collision::run(
            &mut self.bodies,
            &self.names,
            &mut self.collision,
            &mut self.contacts,
            h,
            sweeps,
        )?;
        self.sweep_record.0 = self.collision.sweep_stats();
        self.sweep_record.1.clear();
        self.sweep_record.1.extend_from_slice(self.collision.sweep_diagnostics());
        timer.lap(Phase::Collision);
        let smooth = self.prepare_smooth_step();
        let has_rows = self.free_motion(h, smooth)?;
        timer.lap(Phase::FreeMotion);
        let solve = self.rows_and_problem(h, has_rows && !smooth);
        timer.lap(Phase::Rows);
        let report = if solve { Some(self.solve_problem()?) } else { None };
        let report = self.speculation_passes(h, report)?;
        timer.lap(Phase::Solve);
        self.midpoint_shifts(h, smooth);
        self.project_contacts(h, report.is_some());
        timer.lap(Phase::Projection);
        self.integrate(h, smooth)?;
        timer.lap(Phase::Integrate);
        if !smooth {
            self.check_end_contacts(h)?;
        }
        timer.lap(Phase::Projection);
        stages::integrate::commit(&mut self.bodies, h);
        self.time += h;
        self.steps += 1;
        self.sleep(h);
        let diagnostics = self.diagnostics();
        timer.lap(Phase::Integrate);
        self.record_stats(report, diagnostics, timer, smooth);
        Ok(&self.stats)
    }

    /// Whether this step is smooth (no inequality rows, an integrator chosen: see [`smooth`]);
    /// if so, its steppers are ready.
    fn prepare_smooth_step(&mut self) -> bool {
        let smooth = smooth::applies(&self.options, &self.bodies, &self.contacts, &self.loops.closures);
        if smooth {
            self.smooth.prepare(self.options.integrator, &self.bodies, &self.loops.closures);
        }
        smooth
    }

    /// Stage 4: the free motion (see [`stages::free_motion`]); returns whether the step may have
    /// rows.
    fn free_motion(&mut self, h: f64, smooth: bool) -> Result<bool, StepError> {
        let margin = self.options.limits.margin;
        let has_rows = stages::rows::needed(&self.bodies, &self.contacts, &self.loops.closures, margin);
        let reuse = self.options.mass_matrix_reuse;
        stages::free_motion::run(&mut self.bodies, &self.names, &mut self.dofs, h, has_rows, smooth, reuse)?;
        Ok(has_rows)
    }

    /// Stage 5: the step's rows (none unless `rows`) and their problem; returns whether there is
    /// a problem to solve.
    fn rows_and_problem(&mut self, h: f64, rows: bool) -> bool {
        self.speculation.reset(self.contacts.len());
        if rows {
            self.assemble_rows(h, false);
        } else {
            self.rows.clear();
        }
        let solve = !self.rows.builder.is_empty();
        if solve {
            self.build_problem();
        } else {
            self.solve.clear(self.options.friction);
        }
        solve
    }

    /// Stage 8, first: lone free bodies' origins along the step's mean velocity where no contact
    /// normal constrains them (see [`stages::midpoint`]); none in a smooth step.
    fn midpoint_shifts(&mut self, h: f64, smooth: bool) {
        let inputs = stages::midpoint::MidpointInputs {
            contacts: &self.contacts,
            closures: &self.loops.closures,
            v_start: &self.dofs.v_start,
            v_end: &self.dofs.v_free,
            limit_margin: self.options.limits.margin,
        };
        if smooth {
            self.bodies.iter_mut().for_each(|b| b.midpoint_shift = Vec3::zeros());
        } else {
            stages::midpoint::run(&mut self.bodies, &inputs, h);
        }
    }

    /// Stage 8, second: the contacts' position correction of the step from their predicted gaps
    /// (see [`contact_projection`]), into the multibodies' `position_correction`; `solved`: the
    /// step's problem was solved and its impulses applied.
    fn project_contacts(&mut self, h: f64, solved: bool) {
        let inputs = contact_projection::ProjectionInputs {
            problem: &self.solve.problem,
            partition: self.solve.islands.partition(),
            contacts: &self.contacts,
            velocity: &self.dofs.v_free,
            block_owner: &self.dofs.block_owner,
            collision: &self.collision,
        };
        self.projector.run(inputs, &mut self.bodies, &self.options, h, solved);
    }

    /// Stage 8: every multibody's new state (see [`stages::integrate`]), not yet committed.
    fn integrate(&mut self, h: f64, smooth: bool) -> Result<(), StepError> {
        let steppers = smooth.then_some(&mut self.smooth);
        let (v, projection) = (&self.dofs.v_free, &self.options.loop_projection);
        let sources = stages::integrate::RowSources {
            contacts: &self.contacts,
            limit_margin: self.options.limits.margin,
        };
        self.rattled = stages::integrate::run(
            &mut self.bodies,
            &self.names,
            v,
            &mut self.loops,
            steppers,
            projection,
            &sources,
            h,
        )?;
        Ok(())
    }

    /// Puts idle islands to sleep, if sleeping is on (see [`sleep`]).
    fn sleep(&mut self, h: f64) {
        if self.options.sleep.enabled {
            let (contacts, closures) = (&self.contacts, &self.loops.closures);
            let (bodies, collision) = (&mut self.bodies, &mut self.collision);
            sleep::update(&self.options.sleep, h, bodies, contacts, closures, collision, &mut self.islands);
        }
    }

    /// The statistics of the step just taken.
    fn record_stats(
        &mut self,
        report: Option<ChainReport>,
        diagnostics: stats::Diagnostics,
        timer: PhaseTimer,
        smooth: bool,
    ) {
        let moving = self.bodies.iter().filter(|b| !b.asleep && !b.kinematic).count();
        let integrator = if smooth {
            smooth::integrator_name(&self.options.integrator)
        } else if self.rattled == 0 {
            "semi-implicit-euler"
        } else if self.rattled == moving {
            "rattle"
        } else {
            "semi-implicit-euler+rattle"
        };
        self.stats = StepStats::gather(
            (self.steps, self.time),
            &self.contacts,
            self.rows.builder.len(),
            report,
            &self.solve.chain,
            &self.bodies,
            diagnostics,
            timer,
            integrator,
            (self.sweep_record.0, &self.sweep_record.1),
            (self.solve.islands.count, self.solve.islands.largest),
            self.projector.stats,
        );
    }

    /// Stage 5: this step's rows into the builder (see [`stages::rows`]). `after_solve`: a
    /// speculation pass, whose limit stops are judged by the solved velocity too.
    fn assemble_rows(&mut self, h: f64, after_solve: bool) {
        let sources = RowSources {
            bodies: &mut self.bodies,
            contacts: &self.contacts,
            closures: &self.loops.closures,
            v_start: &self.dofs.v_start,
            materials: &self.materials,
            colliders: self.collision.colliders(),
        };
        self.rows.assemble(sources, &self.options, &mut self.speculation, h, after_solve);
    }

    /// Stage 5: the constraint problem of the assembled rows (see [`Solve::build`]).
    fn build_problem(&mut self) {
        let kept = self.rows.kept_contact_rows();
        let reuse = self.options.mass_matrix_reuse;
        self.solve.build(&self.rows.builder, kept, &self.bodies, &self.dofs, reuse);
        if self.options.softness > 0.0 {
            self.solve.problem.soften(self.options.softness);
        }
    }

    /// Stage 6: the impulses of the built problem and the velocity after them (see
    /// [`Solve::solve`]).
    fn solve_problem(&mut self) -> Result<ChainReport, StepError> {
        let generation = self.rows.kept_contact_rows().map(|(generation, _)| generation);
        let softening = Softening { relative: self.options.softness, damping: self.options.softness_damping };
        Ok(self.solve.solve(&self.contacts, generation, softening, &self.bodies, &mut self.dofs)?)
    }

    /// Moves every collider to the current states (poses, Jacobians), as a step's first phase
    /// does: for drawing or querying contacts before the first step or after editing states.
    pub fn refresh_collision(&mut self) -> Result<(), StepError> {
        for (i, b) in self.bodies.iter_mut().enumerate() {
            b.kinematics().map_err(stages::check::dynamics_error(&self.names[i]))?;
            self.collision.update_multibody(i, &b.data)?;
        }
        Ok(())
    }

    /// How many times a step has built the constraint problem's W = J L⁻¹ D^{-1/2} (and
    /// A = W Wᵀ) from its rows; steps whose rows and mass-matrix factors are those of the last
    /// build keep it (see [`WorldOptions::mass_matrix_reuse`]).
    pub fn problem_builds(&self) -> u64 {
        self.solve.builds
    }

    /// How many steps kept their contact rows from an earlier step (a body at rest: see
    /// [`WorldOptions::mass_matrix_reuse`]) instead of forming them from the contacts.
    pub fn contact_row_reuses(&self) -> u64 {
        self.rows.kept.reuses
    }
}
