//! What a step did ([`StepStats`]): counts, the solver's report, the time per phase when asked
//! ([`PhaseTimer`]), and the diagnostics (energy, momentum, constraint violation) computed from
//! the state.

use super::{Multibody, World};
use crate::collision::{Contact, SweepDiagnostic, SweepStats};
use crate::math::Vec3;
use crate::solvers::{ChainReport, Fallback, SolverChain};
use std::time::Instant;

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
    /// Islands the step's constraint problem was solved as (independent groups of rows joined
    /// through the multibodies they touch; 0 without rows).
    pub islands: usize,
    /// Rows of the largest island.
    pub largest_island: usize,
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
    /// integration + sleeping, contact projection (both of its parts:
    /// [`super::WorldOptions::contact_projection`]); zeros unless
    /// [`super::WorldOptions::time_phases`] is on.
    pub phase_ns: [u64; 7],
    /// The scheme of the step: `"semi-implicit-euler"` for the velocity-level step,
    /// `"rattle"` when every moving multibody was a linkage stepped by RATTLE (its only rows
    /// its own loop closures), `"semi-implicit-euler+rattle"` when some
    /// were, else the name of [`super::WorldOptions::integrator`] (a smooth step, see
    /// [`super::smooth`]).
    pub integrator: &'static str,
    /// Colliders swept by continuous collision, time-of-impact queries and the speculative
    /// contacts they added ([`super::WorldOptions::continuous_collision`]).
    pub sweeps: SweepStats,
    /// What the sweeps could not do: a sweep asked of a body without a collider, a
    /// time-of-impact query that did not converge or is not supported for a pair.
    pub sweep_diagnostics: Vec<SweepDiagnostic>,
    /// What the contacts' position correction did ([`super::WorldOptions::contact_projection`]).
    pub projection: super::ProjectionStats,
}

/// The names of the timed phases of a step, in the order of [`StepStats::phase_ns`]:
/// kinematics, collision detection, free motion, rows and the problem's assembly, the solve,
/// integration with sleeping, and the contact projection.
pub const PHASE_NAMES: [&str; 7] =
    ["kinematics", "collision", "free_motion", "assembly", "solve", "integrate", "projection"];

/// The phases of a step timed by [`PhaseTimer`], in the order of [`StepStats::phase_ns`].
#[derive(Clone, Copy, Debug)]
pub(crate) enum Phase {
    /// Kinematics.
    Kinematics = 0,
    /// Collision detection.
    Collision = 1,
    /// Free motion.
    FreeMotion = 2,
    /// Rows and the problem's assembly.
    Rows = 3,
    /// The solve and the speculation passes.
    Solve = 4,
    /// Integration, sleeping and diagnostics.
    Integrate = 5,
    /// The contact projection: predicted gaps and their correction, and the check at the end
    /// of the step.
    Projection = 6,
}

/// Wall-clock time per phase of a step, read only when [`super::WorldOptions::time_phases`] is
/// on (reading the clock costs tens of nanoseconds).
pub(crate) struct PhaseTimer {
    clock: Option<Instant>,
    ns: [u64; 7],
}

impl PhaseTimer {
    /// Starts the clock if `on`.
    pub(crate) fn start(on: bool) -> Self {
        Self { clock: on.then(Instant::now), ns: [0; 7] }
    }

    /// Ends a part of `phase` now: the time since the last lap is added to it (a phase may be
    /// timed in several parts).
    pub(crate) fn lap(&mut self, phase: Phase) {
        if let Some(clock) = &mut self.clock {
            let now = Instant::now();
            self.ns[phase as usize] += (now - *clock).as_nanos() as u64;
            *clock = now;
        }
    }
}

/// The diagnostics of [`StepStats`], computed when [`super::WorldOptions::diagnostics`] is on.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Diagnostics {
    energy: Option<f64>,
    momentum: Option<Vec3>,
    constraint_violation: Option<f64>,
}

impl StepStats {
    /// The statistics of step `step` ending at `time` (s): `report` of the solves (none without
    /// rows) certified by `chain`, `rows` rows, the step's contacts and the multibodies after it,
    /// the islands of the last solve and the rows of the largest.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn gather(
        (step, time): (u64, f64),
        contacts: &[Contact],
        rows: usize,
        report: Option<ChainReport>,
        chain: &SolverChain,
        bodies: &[Multibody],
        diagnostics: Diagnostics,
        timer: PhaseTimer,
        integrator: &'static str,
        (sweeps, sweep_diagnostics): (SweepStats, &[SweepDiagnostic]),
        (islands, largest_island): (usize, usize),
        projection: super::ProjectionStats,
    ) -> Self {
        let (islands, largest_island) = if report.is_some() { (islands, largest_island) } else { (0, 0) };
        let report = report.unwrap_or_else(|| ChainReport {
            solver: "",
            iterations: 0,
            residuals: Default::default(),
            fallbacks: Vec::new(),
            skipped_first: false,
            note: None,
        });
        let certify = chain.certify(report.solver, &report.residuals);
        StepStats {
            step,
            time,
            contacts: contacts.len(),
            rows,
            solver: report.solver,
            iterations: report.iterations,
            residual: certify,
            fallbacks: report.fallbacks,
            islands,
            largest_island,
            max_penetration: contacts.iter().map(|c| -c.distance).fold(0.0, f64::max),
            asleep: bodies.iter().filter(|b| b.asleep).count(),
            energy: diagnostics.energy,
            momentum: diagnostics.momentum,
            constraint_violation: diagnostics.constraint_violation,
            phase_ns: timer.ns,
            integrator,
            sweeps,
            sweep_diagnostics: sweep_diagnostics.to_vec(),
            projection,
        }
    }
}

impl World {
    /// The step's diagnostics at the current states, if [`super::WorldOptions::diagnostics`]
    /// is on: energy, linear momentum, constraint violation.
    pub(crate) fn diagnostics(&mut self) -> Diagnostics {
        if !self.options.diagnostics {
            return Diagnostics::default();
        }
        Diagnostics {
            energy: Some(self.total_energy()),
            momentum: Some(self.linear_momentum()),
            constraint_violation: Some(self.constraint_violation()),
        }
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
    /// joints' swing cone, twist range and total angle included) at the current states.
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
        for (a, b, closure) in &self.loops.closures {
            let (da, db) = (&self.bodies[*a].data, &self.bodies[*b].data);
            worst = worst.max(crate::constraints::loop_error_between(da, db, closure).0.norm());
        }
        worst
    }
}
