//! Re-solving problem files: the solvers as the corpus configures them, the status and residuals
//! each reaches, and `meta.json` ([`ProblemMeta`]), which records them for a later re-solve to meet.

use super::{
    lcp_facets, qp_of, CLARABEL_TOLERANCE, CONE_FILE, FORMAT_VERSION, LCP_FILE, LEMKE_TOLERANCE, META_FILE,
    META_FORMAT, PGS_SWEEPS, PGS_TOLERANCE, PROBLEM_FILE, QP_FILE, W_TOLERANCE,
};
use crate::constraints::{ConstraintProblem, FrictionModel};
use crate::solvers::{
    cone_program, residuals, ClarabelSolver, ConstraintSolver, LemkeSolver, PgsSolver, Residuals,
};
use clarabel::solver::SupportedConeT;
use nalgebra::DVector;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// The solvers a problem file is re-solved with, configured as the corpus expects (not the
/// World's [`crate::world::SolverKind`], whose PGS is warm-started and stops earlier).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CorpusSolver {
    /// [`LemkeSolver`] with default options (a cone is approximated by 8 facets).
    Lemke,
    /// [`ClarabelSolver`] with default options: the reference.
    Clarabel,
    /// [`PgsSolver`] with [`PGS_SWEEPS`] sweeps from zero (no warm start).
    Pgs,
}

impl CorpusSolver {
    /// Every solver, in the order files record them.
    pub const ALL: [CorpusSolver; 3] = [CorpusSolver::Lemke, CorpusSolver::Clarabel, CorpusSolver::Pgs];

    /// Its name (`lemke`, `clarabel`, `pgs`).
    pub fn name(self) -> &'static str {
        match self {
            CorpusSolver::Lemke => "lemke",
            CorpusSolver::Clarabel => "clarabel",
            CorpusSolver::Pgs => "pgs",
        }
    }

    /// A solver configured as the corpus expects.
    pub fn solver(self) -> Box<dyn ConstraintSolver> {
        match self {
            CorpusSolver::Lemke => Box::new(LemkeSolver::default()),
            CorpusSolver::Clarabel => Box::new(ClarabelSolver::default()),
            CorpusSolver::Pgs => Box::new(PgsSolver::new(PGS_SWEEPS, 1e-13, 1.0, false)),
        }
    }

    /// The tolerance recorded for this solver's certifying residual (m/s).
    pub fn tolerance(self) -> f64 {
        match self {
            CorpusSolver::Lemke => LEMKE_TOLERANCE,
            CorpusSolver::Clarabel => CLARABEL_TOLERANCE,
            CorpusSolver::Pgs => PGS_TOLERANCE,
        }
    }

    /// The problem this solver's answer is certified against: the problem itself, except for
    /// Lemke's method on a friction cone, which solves (exactly) the inscribed pyramid of
    /// [`LemkeSolver::facets`] directions; its residuals are measured on that pyramid.
    pub fn certifying_problem(self, problem: &ConstraintProblem) -> Cow<'_, ConstraintProblem> {
        match (self, problem.friction) {
            (CorpusSolver::Lemke, FrictionModel::Cone) => {
                let mut pyramid = problem.clone();
                pyramid.friction = FrictionModel::Pyramid { facets: LemkeSolver::default().facets };
                Cow::Owned(pyramid)
            }
            _ => Cow::Borrowed(problem),
        }
    }
}

impl std::str::FromStr for CorpusSolver {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        CorpusSolver::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("unknown solver `{s}` (lemke, clarabel, pgs)"))
    }
}

/// Outcome of a solve, ordered from best to worst (`Solved < Inaccurate < Failed`): a status
/// greater than the one a problem's meta.json records is a regression.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SolveStatus {
    /// Impulses returned, certifying residual within the solver's tolerance.
    Solved,
    /// Impulses returned, certifying residual above the solver's tolerance.
    Inaccurate,
    /// The solver returned an error.
    Failed,
}

impl SolveStatus {
    /// Its name as files and the command line write it: `solved`, `inaccurate`, `failed`.
    pub fn name(self) -> &'static str {
        match self {
            SolveStatus::Solved => "solved",
            SolveStatus::Inaccurate => "inaccurate",
            SolveStatus::Failed => "failed",
        }
    }
}

impl std::fmt::Display for SolveStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// [`Residuals`] as written to files (m/s; `qp_*` only for frictionless problems).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ResidualRecord {
    /// Signorini natural-map residual.
    pub signorini: f64,
    /// Max |λ_i w_i| over unilateral rows.
    pub complementarity: f64,
    /// Max |w_i| over bilateral rows.
    pub bilateral: f64,
    /// Bounded-row natural-map residual.
    pub bounded: f64,
    /// Friction-set violation.
    pub friction_feasibility: f64,
    /// Dissipation gap.
    pub dissipation: f64,
    /// KKT residual of the convex relaxation.
    pub conic_kkt: f64,
    /// [`Residuals::exact`].
    pub exact: f64,
    /// [`Residuals::convex`].
    pub convex: f64,
    /// qpsolvers' primal residual.
    pub qp_primal: Option<f64>,
    /// qpsolvers' dual residual.
    pub qp_dual: Option<f64>,
    /// qpsolvers' duality gap.
    pub qp_gap: Option<f64>,
}

impl From<&Residuals> for ResidualRecord {
    fn from(r: &Residuals) -> Self {
        Self {
            signorini: r.signorini,
            complementarity: r.complementarity,
            bilateral: r.bilateral,
            bounded: r.bounded,
            friction_feasibility: r.friction_feasibility,
            dissipation: r.dissipation,
            conic_kkt: r.conic_kkt,
            exact: r.exact(),
            convex: r.convex(),
            qp_primal: r.qp.map(|q| q.primal),
            qp_dual: r.qp.map(|q| q.dual),
            qp_gap: r.qp.map(|q| q.gap),
        }
    }
}

/// One solver's answer to a problem.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolverRecord {
    /// Solved, inaccurate or failed.
    pub status: SolveStatus,
    /// The error (failed) or the solver's remark.
    pub message: Option<String>,
    /// Iterations, sweeps or pivots.
    pub iterations: usize,
    /// Certifying residual (m/s) on [`CorpusSolver::certifying_problem`].
    pub certified: Option<f64>,
    /// `½λᵀ(A + R)λ + bᵀλ` (J·s… in impulse × velocity units).
    pub objective: Option<f64>,
    /// Residuals on the certifying problem.
    pub residuals: Option<ResidualRecord>,
    /// Impulses λ (N·s); empty when failed.
    pub lambda: Vec<f64>,
    /// Row velocities `w = (A + R)λ + b` (m/s); empty when failed.
    pub w: Vec<f64>,
}

/// `½λᵀ(A + R)λ + bᵀλ`.
pub fn objective(problem: &ConstraintProblem, lambda: &DVector<f64>) -> f64 {
    let mut w = DVector::zeros(problem.rows());
    problem.velocities(lambda, &mut w);
    // w = (A + R)λ + b, so ½λᵀ(A + R)λ + bᵀλ = ½λᵀ(w + b).
    0.5 * lambda.dot(&(w + &problem.bias))
}

/// Solves `problem` with `kind` (from zero impulses) and records the outcome; also returns the
/// solver's wall-clock time.
pub fn run_solver(kind: CorpusSolver, problem: &ConstraintProblem) -> (SolverRecord, Duration) {
    run_configured_solver(kind, kind.solver(), problem)
}

/// [`run_solver`] with `solver`, a solver of `kind` configured by the caller (the corpus bench's
/// Lemke, told the tolerance it is certified against).
pub fn run_configured_solver(
    kind: CorpusSolver,
    mut solver: Box<dyn ConstraintSolver>,
    problem: &ConstraintProblem,
) -> (SolverRecord, Duration) {
    let mut lambda = DVector::zeros(problem.rows());
    let start = Instant::now();
    let result = solver.solve(problem, &mut lambda);
    let elapsed = start.elapsed();
    let record = match result {
        Err(e) => SolverRecord {
            status: SolveStatus::Failed,
            message: Some(e.to_string()),
            iterations: 0,
            certified: None,
            objective: None,
            residuals: None,
            lambda: Vec::new(),
            w: Vec::new(),
        },
        Ok(info) => {
            let mut w = DVector::zeros(problem.rows());
            let r = residuals(&kind.certifying_problem(problem), &lambda, &mut w);
            let certified = solver.certify(&r);
            SolverRecord {
                status: if certified <= kind.tolerance() {
                    SolveStatus::Solved
                } else {
                    SolveStatus::Inaccurate
                },
                message: info.note,
                iterations: info.iterations,
                certified: Some(certified),
                objective: Some(objective(problem, &lambda)),
                residuals: Some(ResidualRecord::from(&r)),
                lambda: lambda.iter().copied().collect(),
                w: w.iter().copied().collect(),
            }
        }
    };
    (record, elapsed)
}

/// Whether every contact of `problem` is frictionless (the problem is then a pure QP).
pub fn is_frictionless(problem: &ConstraintProblem) -> bool {
    problem.contacts.iter().all(|c| c.mu == 0.0 && c.mu2 == 0.0)
}

/// Formulation name: `frictionless-qp`, `pyramid-qp` (linear friction facets) or `cone-socp`.
pub fn formulation(problem: &ConstraintProblem) -> &'static str {
    if is_frictionless(problem) {
        "frictionless-qp"
    } else if cone_program(problem).cones.iter().any(|c| matches!(c, SupportedConeT::SecondOrderConeT(_))) {
        "cone-socp"
    } else {
        "pyramid-qp"
    }
}

/// Metadata of a problem file: where it came from, how each solver did, what a re-solve must
/// meet.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProblemMeta {
    /// [`META_FORMAT`].
    pub format: String,
    /// [`FORMAT_VERSION`].
    pub version: u32,
    /// Scene name.
    pub scene: String,
    /// Step index within the scene.
    pub step: usize,
    /// Time step (s).
    pub h: f64,
    /// [`formulation`].
    pub formulation: String,
    /// Friction model: `cone` or `pyramid:K` (K facets), as [`crate::io::scene::parse_friction`]
    /// reads it.
    pub friction: String,
    /// Rows.
    pub rows: usize,
    /// Contact blocks.
    pub contacts: usize,
    /// Velocity coordinates (0 if J is not stored).
    pub nv: usize,
    /// Friction directions of `lcp.npz`.
    pub lcp_facets: usize,
    /// Files of the problem directory.
    pub files: Vec<String>,
    /// The solver whose answer is the reference (`clarabel`).
    pub reference: String,
    /// Each solver's answer, by name.
    pub solutions: BTreeMap<String, SolverRecord>,
    /// Each solver's certifying-residual tolerance (m/s), by name.
    pub tolerances: BTreeMap<String, f64>,
    /// Tolerance (m/s) on `w` for the solvers of `w_unique_for`.
    pub w_tolerance: f64,
    /// Solvers whose `w` must equal the reference's: `w` is unique for the convex program that
    /// clarabel solves (its Hessian-times-solution is), so always `clarabel`; for frictionless
    /// problems the LCP is that program's optimality system, so also `lemke` and `pgs`.
    pub w_unique_for: Vec<String>,
    /// Remarks for people.
    pub notes: Vec<String>,
}

impl ProblemMeta {
    /// Solves `problem` with every [`CorpusSolver`] and records the outcomes (clarabel's is the
    /// reference) for scene `scene`, step `step`, time step `h`.
    pub fn compute(scene: &str, step: usize, h: f64, problem: &ConstraintProblem) -> Self {
        let solutions: BTreeMap<String, SolverRecord> =
            CorpusSolver::ALL.iter().map(|&k| (k.name().to_string(), run_solver(k, problem).0)).collect();
        let tolerances = CorpusSolver::ALL.iter().map(|&k| (k.name().to_string(), k.tolerance())).collect();
        let frictionless = is_frictionless(problem);
        let w_unique_for = if frictionless {
            CorpusSolver::ALL.iter().map(|k| k.name().to_string()).collect()
        } else {
            vec!["clarabel".to_string()]
        };
        let mut files = vec![PROBLEM_FILE, CONE_FILE, LCP_FILE];
        if qp_of(problem).is_some() {
            files.push(QP_FILE);
        }
        files.push(META_FILE);
        let mut notes = vec![
            "residuals in m/s (impulses scaled by the row's diagonal); lemke's on a friction cone are measured on the pyramid it solves"
                .to_string(),
        ];
        if !frictionless {
            notes.push(
                "clarabel solves the convex (Anitescu) relaxation, lemke and pgs the exact complementarity problem: their w differ where contacts slide"
                    .to_string(),
            );
        }
        Self {
            format: META_FORMAT.to_string(),
            version: FORMAT_VERSION,
            scene: scene.to_string(),
            step,
            h,
            formulation: formulation(problem).to_string(),
            friction: match problem.friction {
                FrictionModel::Cone => "cone".to_string(),
                FrictionModel::Pyramid { facets } => format!("pyramid:{facets}"),
            },
            rows: problem.rows(),
            contacts: problem.contacts.len(),
            nv: problem.jacobian.ncols(),
            lcp_facets: lcp_facets(problem),
            files: files.into_iter().map(String::from).collect(),
            reference: CorpusSolver::Clarabel.name().to_string(),
            solutions,
            tolerances,
            w_tolerance: W_TOLERANCE,
            w_unique_for,
            notes,
        }
    }
}
