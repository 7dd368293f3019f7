//! Options of a [`super::World`]: time step, solver chain, friction model, joint-limit and
//! sleeping parameters.

use super::StepError;
use crate::collision::CollisionOptions;
use crate::constraints::{ContactParameters, FrictionModel, JointLimitParameters, Speculation};
use crate::integrators::IntegratorKind;
use crate::math::Vec3;
use crate::solvers::{
    ClarabelSolver, ConstraintSolver, LemkeOptions, LemkeSolver, NewtonSolver, PgsSolver, SolverChain,
};

/// Most Newton iterations of one solve in a world's chain ([`NewtonSolver::max_iterations`]):
/// enough for the islands of hard-contact heaps of ragdolls (`models/ragdoll_crowd.toml` on hard
/// rows, the MJCF piles of `benches/ragdoll_mjcf.py`), whose redundant hard rows take many
/// proximal rounds (docs/solvers.md). A solve that converges ends before it; it bounds the work
/// of one that does not.
pub const CHAIN_NEWTON_ITERATIONS: usize = 400;

/// A solver of the chain, by kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SolverKind {
    /// Lemke's method on the pyramid LCP (`facets` directions when friction is a cone).
    Lemke {
        /// Pyramid directions.
        facets: usize,
    },
    /// clarabel on the convex relaxation.
    Clarabel,
    /// Newton's method on the primal problem with a sparse Cholesky factorization.
    Newton,
    /// Newton's method, its answer certified by the exact (Coulomb) formulation's residual
    /// ([`NewtonSolver::certify_exact`]): accepted where no contact slides.
    NewtonExact,
    /// Projected Gauss–Seidel.
    Pgs {
        /// Maximum sweeps.
        iterations: usize,
        /// Over-relaxation factor.
        omega: f64,
    },
}

impl SolverKind {
    /// A boxed solver of this kind.
    pub fn build(&self) -> Box<dyn ConstraintSolver> {
        match *self {
            SolverKind::Lemke { facets } => Box::new(LemkeSolver { facets, ..LemkeSolver::default() }),
            SolverKind::Clarabel => Box::new(ClarabelSolver::default()),
            SolverKind::Newton | SolverKind::NewtonExact => {
                let mut newton = NewtonSolver::default();
                newton.max_iterations = CHAIN_NEWTON_ITERATIONS;
                newton.certify_exact = *self == SolverKind::NewtonExact;
                Box::new(newton)
            }
            SolverKind::Pgs { iterations, omega } => Box::new(PgsSolver::new(iterations, 1e-10, omega, true)),
        }
    }

    /// Parses `lemke`, `clarabel`, `newton`, `newton-exact`, `pgs` or `pgsN` (N ≥ 1 sweeps).
    pub fn parse(name: &str) -> Option<Self> {
        match name {
            "lemke" => Some(SolverKind::Lemke { facets: 8 }),
            "clarabel" => Some(SolverKind::Clarabel),
            "newton" => Some(SolverKind::Newton),
            "newton-exact" => Some(SolverKind::NewtonExact),
            "pgs" => Some(SolverKind::Pgs { iterations: 50, omega: 1.0 }),
            other => other
                .strip_prefix("pgs")
                .and_then(|n| n.parse().ok())
                .filter(|&iterations| iterations >= 1)
                .map(|iterations| SolverKind::Pgs { iterations, omega: 1.0 }),
        }
    }
}

/// Sleeping parameters (ODE's auto-disable): a multibody is idle when its speeds, averaged over
/// `average_samples` steps, stay below the thresholds; an island of touching bodies sleeps when
/// all its members have been idle for `idle_steps` steps and `idle_time` seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SleepOptions {
    /// Whether bodies may fall asleep.
    pub enabled: bool,
    /// Linear speed threshold (m/s): free-joint origin speed and slider rates of the averaged
    /// velocity.
    pub linear_threshold: f64,
    /// Angular speed threshold (rad/s): free-joint angular speed and joint rates of the averaged
    /// velocity.
    pub angular_threshold: f64,
    /// Steps over which the generalized velocity is averaged, as a vector (ODE's rule: jitter
    /// that changes sign from step to step averages out, a steady creep does not), before its
    /// speeds are compared with the thresholds.
    pub average_samples: usize,
    /// Idle steps before sleeping.
    pub idle_steps: usize,
    /// Idle time (s) before sleeping.
    pub idle_time: f64,
}

impl Default for SleepOptions {
    fn default() -> Self {
        Self {
            enabled: true,
            linear_threshold: 0.01,
            angular_threshold: 0.01,
            average_samples: 10,
            idle_steps: 10,
            idle_time: 0.0,
        }
    }
}

/// Everything a world is configured with.
#[derive(Clone, Debug, PartialEq)]
pub struct WorldOptions {
    /// Fixed time step h (s).
    pub dt: f64,
    /// At most this many steps per [`super::World::advance`] call.
    pub max_substeps: usize,
    /// Gravity (m/s²), applied to every multibody added.
    pub gravity: Vec3,
    /// Collision options (contact margin, joined bodies).
    pub collision: CollisionOptions,
    /// Which contacts within the margin but still apart get rows: those the step can close
    /// ([`Speculation`]; [`Speculation::ALL`]: every one).
    pub speculation: Speculation,
    /// Continuous collision: a collider that moves further than the contact margin in one step
    /// (at the step's starting velocity) is swept along its motion, and a pair it would meet
    /// within the step gets a speculative contact at the time of impact, so that a fast body
    /// cannot pass through another (docs/collision.md). Slower colliders cost nothing more.
    /// [`super::World::set_always_swept`] sweeps chosen bodies at any speed.
    pub continuous_collision: bool,
    /// Friction cone or pyramid.
    pub friction: FrictionModel,
    /// Solver chain, first choice first, run on each island of the step's problem
    /// ([`super::World::set_threads`]). The default, `newton-exact` → PGS (100 sweeps) →
    /// Newton → clarabel: `newton-exact` answers sticking and separating contacts of the exact
    /// Coulomb problem in a few iterations, PGS solves it where contacts slide (a box slides on
    /// its plane), Newton's method and clarabel its convex relaxation (a sliding contact
    /// separates at μ‖v_t‖). Piles of articulated bodies are answered by Newton's method on
    /// softened rows (`newton`, `clarabel` with [`Self::softness`] 0.02:
    /// models/ragdoll_crowd.toml).
    pub solvers: Vec<SolverKind>,
    /// Steps for which an island's chain passes over its first solver after that solver
    /// missed ([`SolverChain::skip_after_miss`]; 0: always tried). With the default chain, a
    /// scene whose contacts slide skips `newton-exact`, which cannot certify them, for this
    /// many steps at a time.
    pub skip_first_after_miss: usize,
    /// Work budget of Lemke's method in one step ([`LemkeOptions::max_operations`]:
    /// floating-point operations of its bases, 0: none). A step is not an offline solve: an
    /// LCP beyond it (ten rovers built into each other, 18 000 variables) ends the step with
    /// [`crate::error::SolverError::LemkeWorkLimit`] (or hands it to the chain's next solver)
    /// rather than after tens of seconds. The default, 10¹⁰, is several seconds of one core and
    /// ten times what the largest hard case's LCP takes (the 55-box pyramid at 1/60 s).
    pub lemke_operations: f64,
    /// Most entries Lemke's sparse matrices may store in one step
    /// ([`LemkeOptions::max_matrix_entries`], 16 bytes each; 0: none). The default, 2·10⁷
    /// (320 MB for M, as much for its equilibrated copy), is five times what the largest
    /// problem of the corpus needs (a heap of ragdolls: 6 500 variables, 4.4·10⁶ entries); ten
    /// rovers at one place (14 500 variables, M nearly dense: 2·10⁸ entries, 5.8 GB) end the
    /// step with [`crate::error::SolverError::LemkeMatrixTooLarge`] (or hand it to the chain's
    /// next solver) before M is formed.
    pub lemke_matrix_entries: usize,
    /// Residual (m/s) a solver's answer must meet before the chain accepts it.
    pub tolerance: f64,
    /// Relative softness s of the inequality and box rows (contacts, joint limits, joint
    /// friction, motors; loop closures stay hard): each gets the regularisation
    /// `R_ii += s · A_ii` ([`crate::constraints::ConstraintProblem::soften`]), a compliance
    /// scaled to the row's effective mass, as MuJoCo's impedance and Drake SAP's near-rigid
    /// regularisation are, centred on the impulse of the row's spring (the elastic part of last
    /// step's impulses, [`crate::constraints::ConstraintProblem::center_softening`] and
    /// [`Self::softness_damping`]): the compliance acts on the change of a row's impulse, so a
    /// contact that carries the same load step after step holds it as a hard one would instead
    /// of sinking under it (a ragdoll under a heap of twenty would sink by centimetres). 0 (the
    /// default): hard rows. A row whose impulse changes keeps a fraction `s / (1 + s)` of the
    /// velocity it would otherwise cancel in that step. This is what lets [`SolverKind::Newton`] converge in a few
    /// iterations on piles of articulated bodies (the whole problem is then smooth). Every
    /// solver of the chain solves, and is certified on, the softened problem.
    pub softness: f64,
    /// Share β ∈ [0, 1] of the softened rows' compliance that is a damper: each softened row is
    /// a spring and a damper side by side (Kelvin–Voigt), the softening centred on the spring's
    /// impulse, which follows the row's impulses as `λ̄ ← (1 − β) λ + β λ̄`
    /// ([`crate::constraints::ConstraintProblem::follow_elastic_impulses`]). 0 (the default):
    /// undamped springs; 1: dampers alone (a loaded row sinks). MuJoCo's humanoid lying on rows
    /// of s = 0.11 keeps rocking on their slowest modes with 0 and comes to rest with 0.5; the
    /// 64 ragdolls of models/ragdoll_crowd.toml (s = 0.02) at 1/60 s are asleep in 7.4 s with 0
    /// and not within 10 s with 0.5 (docs/solvers.md). Unused while [`Self::softness`] is 0.
    pub softness_damping: f64,
    /// Accept the last solver's answer even above the tolerance (recorded) instead of failing.
    pub accept_last: bool,
    /// Contact parameters of material 0 (the default material).
    pub contact: ContactParameters,
    /// Joint-limit parameters.
    pub limits: JointLimitParameters,
    /// Sleeping.
    pub sleep: SleepOptions,
    /// Compute energy and momentum in the step statistics (costs one extra pass).
    pub diagnostics: bool,
    /// Measure each phase's wall time into [`super::StepStats::phase_ns`] (zeros when off):
    /// seven clock reads per step, about 1 % of a 20 µs ragdoll step, so off unless asked for
    /// (`gelenk simulate` and `gelenk bench world` turn it on where they report phases).
    pub time_phases: bool,
    /// The position correction of loop closures within a multibody after each step (SHAKE
    /// after a velocity-level step, or RATTLE's sweeps for a linkage whose only rows are its
    /// own closures; a mass-metric projection after a smooth step).
    pub loop_projection: super::LoopProjection,
    /// The position correction of contacts after each velocity-level step
    /// ([`super::ContactProjection`], on by default): each contact predicted deeper than the
    /// slop at the end of the step is pushed out by a change of q alone (along M⁻¹Jₙᵀ, the
    /// least change in the mass metric), reusing the step's normal rows; v is not changed.
    pub contact_projection: super::ContactProjection,
    /// Integrator of the steps without contacts, limits, motors or joint friction (see
    /// [`super::smooth`]); the default, semi-implicit Euler, keeps the velocity-level step for
    /// every step.
    pub integrator: IntegratorKind,
    /// Reuse of a multibody's factored mass matrix while its joints have hardly moved: when no
    /// coordinate (rad or m; a floating root's pose excepted, which M does not depend on) is
    /// further than this from where M was last factored, at the same step, the step solves with
    /// that factor instead of running CRBA and the factorization again (None: every step
    /// factors). M's entries then lag by a first-order change of at most this much in a
    /// coordinate (relative 1e-8 of M's entries at the default); a resting ragdoll's joints move
    /// by less than a nanoradian per step, so it factors once every few hundred steps.
    /// The constraint problem's W = J L⁻¹ D^{-1/2} (and A = W Wᵀ) is kept with the factor it was
    /// built on while the step's rows are the same rows with every Jacobian entry within this
    /// tolerance (relative to the larger of 1 and the entry) of those W was built from: only the
    /// bias J v_free − u* is formed anew ([`super::World::problem_builds`] counts the builds).
    /// The contact rows themselves (point rates along the normal and tangents) are kept from an
    /// earlier step while every coordinate (rad or m, the root's pose included) and every contact
    /// point and normal component (m) is within this tolerance of where they were formed and the
    /// same contacts get rows; only their targets are new ([`super::World::contact_row_reuses`]
    /// counts those steps).
    pub mass_matrix_reuse: Option<f64>,
}

impl WorldOptions {
    /// Checks the settings every step reads, which the fields' types do not bound: a finite
    /// positive [`Self::dt`] and [`Self::tolerance`], a finite non-negative [`Self::softness`]
    /// and a [`Self::softness_damping`] in [0, 1]. [`super::World::step`] calls it first, so a
    /// world whose options were set out of range (`World::set_softness(-1.0)`, a NaN step)
    /// stops with [`StepError::InvalidOption`] and its state unchanged.
    pub fn check(&self) -> Result<(), StepError> {
        let bad = |name, value, expected| Err(StepError::InvalidOption { name, value, expected });
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return bad("dt", self.dt, "a finite time step above 0 s");
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return bad("tolerance", self.tolerance, "a finite residual above 0 m/s");
        }
        if !(self.softness.is_finite() && self.softness >= 0.0) {
            return bad("softness", self.softness, "a finite number of at least 0");
        }
        if !(0.0..=1.0).contains(&self.softness_damping) {
            return bad("softness_damping", self.softness_damping, "a fraction in [0, 1]");
        }
        Ok(())
    }
}

impl Default for WorldOptions {
    fn default() -> Self {
        Self {
            dt: 0.002,
            max_substeps: 8,
            gravity: Vec3::new(0.0, 0.0, -9.81),
            collision: CollisionOptions::default(),
            speculation: Speculation::default(),
            continuous_collision: true,
            friction: FrictionModel::Cone,
            solvers: vec![
                SolverKind::NewtonExact,
                SolverKind::Pgs { iterations: 100, omega: 1.0 },
                SolverKind::Newton,
                SolverKind::Clarabel,
            ],
            skip_first_after_miss: 30,
            lemke_operations: 1e10,
            lemke_matrix_entries: 20_000_000,
            tolerance: 1e-6,
            softness: 0.0,
            softness_damping: 0.0,
            accept_last: true,
            contact: ContactParameters::default(),
            limits: JointLimitParameters::default(),
            sleep: SleepOptions::default(),
            diagnostics: false,
            time_phases: false,
            loop_projection: super::LoopProjection::default(),
            contact_projection: super::ContactProjection::default(),
            integrator: IntegratorKind::SemiImplicitEuler,
            mass_matrix_reuse: Some(1e-8),
        }
    }
}

impl WorldOptions {
    /// The solver chain these options describe.
    pub fn chain(&self) -> SolverChain {
        let solvers = self.solvers.iter().map(|kind| match *kind {
            SolverKind::Lemke { facets } => {
                let options = LemkeOptions {
                    max_operations: self.lemke_operations,
                    max_matrix_entries: self.lemke_matrix_entries,
                    ..LemkeOptions::default()
                };
                Box::new(LemkeSolver { facets, options, ..LemkeSolver::default() })
                    as Box<dyn ConstraintSolver>
            }
            _ => kind.build(),
        });
        let mut chain = SolverChain::new(solvers.collect(), self.tolerance);
        chain.accept_last = self.accept_last;
        chain.skip_after_miss = self.skip_first_after_miss;
        chain
    }
}
