//! Stages 5 (the problem) and 6 (the solve): the [`ConstraintProblem`] of the assembled rows
//! (W = J L⁻¹ D^{-1/2} over each multibody's mass-matrix factor, kept while the rows and
//! factors are those it was built from), its impulses by the solver chain warm-started from the
//! last step ([`WarmStart`]), and the velocity after them, `v⁺ = v_free + M⁻¹ Jᵀ λ`.
//!
//! The problem is solved island by island ([`IslandPartition`]): rows joined through the
//! multibodies they touch form an island, islands share no velocity, and each is solved by a
//! chain of its own (island k by chain k, whatever thread runs it, so that the answer does not
//! depend on the thread count; see `islands.rs`). Sleeping multibodies have no rows: their
//! islands cost nothing.

use crate::collision::Contact;
use crate::constraints::{BuiltRows, ConstraintProblem, FrictionModel, ProblemBuilder, RowsMark};
use crate::error::SolverError;
use crate::solvers::{ChainReport, SolverChain};
use crate::world::dofs::{block_factors, StackedDofs};
use crate::world::stages::islands::IslandSolves;
use crate::world::warm_start::WarmStart;
use crate::world::{Multibody, WorldOptions};
use nalgebra::DVector;

/// The softening of a step's rows: [`WorldOptions::softness`] and
/// [`WorldOptions::softness_damping`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Softening {
    /// Relative compliance s (0: hard rows).
    pub(crate) relative: f64,
    /// Share β of the compliance that is a damper.
    pub(crate) damping: f64,
}

/// The solver chain, the step's problem and impulses, and what lets W be kept between steps.
pub(crate) struct Solve {
    /// The solvers, tried in order (the chain whose settings every island's chain copies, and
    /// that certifies the step's report).
    pub(crate) chain: SolverChain,
    /// The islands of the problem, each with its chain, sub-problem and impulses.
    pub(crate) islands: IslandSolves,
    /// The constraint problem of the last step.
    pub(crate) problem: ConstraintProblem,
    /// Its impulses (N·s), one per row.
    pub(crate) lambda: DVector<f64>,
    /// The elastic part of each softened row's impulse (N·s) that the softening is centred on
    /// ([`ConstraintProblem::follow_elastic_impulses`]); unused while the rows are hard.
    centre: DVector<f64>,
    /// The rows `problem`'s W was built from, and per multibody the factor it was built on
    /// ([`Multibody::factor_identity`]): a step whose rows and factors are the same keeps W.
    built_rows: BuiltRows,
    built_factors: Vec<Option<u64>>,
    /// The generation of the kept contact rows W was built from (see `contact_rows`).
    built_contact_rows: Option<u64>,
    /// How many times a step built W from its rows ([`crate::world::World::problem_builds`]).
    pub(crate) builds: u64,
    /// Last step's impulses by row, for the warm start.
    pub(crate) warm: WarmStart,
}

impl Solve {
    /// No problem yet; the chain of `options` solves the problems to come.
    pub(crate) fn new(options: &WorldOptions) -> Self {
        Self {
            chain: options.chain(),
            islands: IslandSolves::new(options),
            problem: ConstraintProblem::default(),
            built_rows: BuiltRows::default(),
            built_factors: Vec::new(),
            built_contact_rows: None,
            builds: 0,
            lambda: DVector::zeros(0),
            centre: DVector::zeros(0),
            warm: WarmStart::default(),
        }
    }

    /// Replaces the solver chain by that of `options` (every island's too).
    pub(crate) fn set_chain(&mut self, options: &WorldOptions) {
        self.chain = options.chain();
        self.islands.set_chain(options);
    }

    /// The empty problem of a step without rows.
    pub(crate) fn clear(&mut self, friction: FrictionModel) {
        self.problem = ConstraintProblem { friction, ..ConstraintProblem::default() };
        self.built_rows.forget();
        self.lambda = DVector::zeros(0);
    }

    /// The constraint problem of the rows in `builder` (W over each multibody's factor). When
    /// every multibody kept the factor W was last built on and the rows are the same up to
    /// `mass_matrix_reuse`'s tolerance (a body at rest), W stands and only the bias is new
    /// ([`ProblemBuilder::refresh_bias`]). `kept`: the generation of the contact rows the
    /// builder starts with and where they end (rows of one generation are the same bits).
    pub(crate) fn build(
        &mut self,
        builder: &ProblemBuilder,
        kept: Option<(u64, RowsMark)>,
        bodies: &[Multibody],
        dofs: &StackedDofs,
        mass_matrix_reuse: Option<f64>,
    ) {
        if let Some(tolerance) = mass_matrix_reuse {
            let same_factors = self.built_factors.len() == bodies.len()
                && bodies.iter().zip(&self.built_factors).all(|(b, f)| b.factor_identity() == *f);
            // Contact rows kept since W was built are its rows bit for bit.
            let unchanged = kept
                .filter(|(generation, _)| Some(*generation) == self.built_contact_rows)
                .map(|(_, mark)| mark);
            if same_factors && self.built_rows.same_rows(builder, tolerance, unchanged) {
                builder.refresh_bias(&dofs.v_free, &mut self.problem);
                return;
            }
        }
        let factor_of = block_factors(bodies, &dofs.block_owner);
        builder.build_into_blocks(&dofs.v_free, factor_of, false, &mut self.problem);
        self.builds += 1;
        if mass_matrix_reuse.is_some() {
            self.built_rows.record(builder);
            self.built_contact_rows = kept.map(|(generation, _)| generation);
            self.built_factors.clear();
            self.built_factors.extend(bodies.iter().map(Multibody::factor_identity));
        } else {
            // A record of older rows must not outlive this W (the reuse may be switched on again).
            self.built_rows.forget();
        }
    }

    /// Solves the built problem island by island, warm-started from the last solve, keeps its impulses for the
    /// next, and applies them: `dofs.v_free` becomes the velocity after the impulses.
    /// `generation`: that of the contact rows the builder starts with. `softening`: that the
    /// problem was softened by, centred here on the elastic part of the last step's impulses
    /// ([`ConstraintProblem::center_softening`]), which the answer then moves
    /// ([`ConstraintProblem::follow_elastic_impulses`]).
    pub(crate) fn solve(
        &mut self,
        contacts: &[Contact],
        generation: Option<u64>,
        softening: Softening,
        bodies: &[Multibody],
        dofs: &mut StackedDofs,
    ) -> Result<ChainReport, SolverError> {
        let soft = softening.relative > 0.0;
        let centre = soft.then_some(&mut self.centre);
        self.warm.start(&self.problem, contacts, generation, &mut self.lambda, centre);
        if soft {
            self.problem.center_softening(softening.relative, &self.centre);
        }
        let report = self.islands.solve(&self.problem, &mut self.lambda, &self.chain)?;
        if soft {
            self.problem.follow_elastic_impulses(softening.damping, &self.lambda, &mut self.centre);
        }
        self.warm.remember(&self.problem, contacts, generation, &self.lambda, soft.then_some(&self.centre));
        dofs.apply_impulses(&self.problem, &self.lambda, bodies);
        Ok(report)
    }
}
