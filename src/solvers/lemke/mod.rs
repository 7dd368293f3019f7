//! Lemke's complementary pivoting method (Cottle, Pang & Stone, "The Linear Complementarity
//! Problem", §4.4) for `w = M z + q, z ≥ 0, w ≥ 0, zᵀw = 0`.
//!
//! - The basis is an LU factorization with product-form column updates and periodic
//!   refactorization ([`basis`]), never an explicit inverse; a solve costs O(k² + nnz) for the
//!   k variables that became active, which keeps a 400-variable contact LCP in milliseconds.
//! - The ratio test is lexicographic (no cycling on degenerate problems such as four coplanar
//!   box corners), with B⁻¹'s columns read by solves against the factorization ([`path`]).
//! - Tolerances are scaled: pivots relative to the entering column, degeneracy relative to q.
//! - The LCP is equilibrated (powers of two, [`scaling`]) so that a 1000:1 mass ratio leaves
//!   every row and column of M near unit size; the unscaled problem and other covering vectors
//!   are tried when a path fails.
//! - The answer is verified on the original LCP; one that misses the tolerance is polished by a
//!   fresh factorization and iterative refinement of the final basis. If the basis itself is
//!   slightly infeasible (basic values some 1e-9 below zero after hundreds of degenerate
//!   pivots), a path is restarted from it with the covering vector B·1, which lifts every
//!   value with one z0 and ends where z0 leaves again ([`path::Path::restart`]).
//! - A path that leaves along a secondary ray returns the ray with its check ([`RayCertificate`]):
//!   the ray's conditions recomputed from M and q, and whether its direction is a Farkas proof
//!   that the LCP has no feasible point (then no other covering vector is tried).
//!
//! [`lcp_of`] turns a [`ConstraintProblem`] into the LCP of the polyhedral-friction formulation.

mod basis;
mod columns;
mod lcp;
mod path;
mod ray;
mod scaling;

pub use lcp::{lcp_of, Lcp};
pub use ray::RayCertificate;

use super::{check_problem, ConstraintSolver, SolveInfo, SolverError};
use crate::constraints::{ConstraintProblem, FrictionModel};
use basis::NONE;
use columns::{Columns, Csc};
use lcp::sparse_lcp_of;
use nalgebra::{DMatrix, DVector};
use path::{covering_of_basis, Path, PathEnd, PathOptions};
use scaling::Scaling;

/// Options of Lemke's method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LemkeOptions {
    /// Maximum number of pivots per covering vector (0: 50 × the LCP size + 100).
    pub max_pivots: usize,
    /// Pivot tolerance relative to the largest entry of the entering column B⁻¹a (an entry
    /// must exceed it to pivot).
    pub pivot_tolerance: f64,
    /// Accepted complementarity residual max |min(z_i, w_i)| relative to max(1, ‖q‖∞).
    pub tolerance: f64,
    /// Column updates between refactorizations of the basis (0: chosen from the sizes).
    pub refactor_interval: usize,
}

impl Default for LemkeOptions {
    fn default() -> Self {
        Self { max_pivots: 0, pivot_tolerance: 1e-9, tolerance: 1e-9, refactor_interval: 0 }
    }
}

/// Facts about one call of [`lemke_with_report`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LemkeReport {
    /// Pivots over all attempts.
    pub pivots: usize,
    /// Paths run (covering vectors and scalings tried).
    pub attempts: usize,
    /// Refactorizations of the basis over all attempts.
    pub refactorizations: usize,
    /// Solves with unit vectors for lexicographic tie-breaks.
    pub lex_solves: usize,
    /// Size k of the last factorized block.
    pub factorized_size: usize,
    /// The natural residual max |min(z_i, w_i)| of the answer on the original LCP.
    pub residual: f64,
    /// Whether the answer was polished (fresh factorization and iterative refinement).
    pub polished: bool,
    /// Paths restarted from a final basis that polishing left outside the tolerance.
    pub restarts: usize,
    /// Whether the answer is the point where a path ended on a ray, the pivot limit, a cycle
    /// or a singular basis with z0 so near zero that, z0 dropped, it meets the tolerance.
    pub near_solution: bool,
}

/// Paths restarted from the final basis of a path whose answer misses the tolerance.
const RESTARTS: usize = 2;

/// The paths tried in order: (equilibrated, covering vector). The covering vectors are in the
/// units of the LCP the path runs on.
const ATTEMPTS: [(bool, Covering); 5] = [
    (true, Covering::Ones),
    (true, Covering::Golden),
    (false, Covering::Ones),
    (false, Covering::Golden),
    (true, Covering::Diagonal),
];

/// A covering vector d > 0.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Covering {
    /// d = 1.
    Ones,
    /// d_i = 1 + frac((i + 1) φ⁻¹): distinct entries, breaking symmetric ties.
    Golden,
    /// d_i = |M_ii|, at least 1e-3 max |M|.
    Diagonal,
}

impl Covering {
    fn name(self) -> &'static str {
        match self {
            Covering::Ones => "ones",
            Covering::Golden => "golden",
            Covering::Diagonal => "diagonal",
        }
    }

    fn vector(self, m: &Csc, scaling: &Scaling) -> Vec<f64> {
        let n = m.n();
        let golden = |i: usize| ((i as f64 + 1.0) * 0.618_033_988_749_895).fract();
        match self {
            Covering::Ones => vec![1.0; n],
            Covering::Golden => (0..n).map(|i| 1.0 + golden(i)).collect(),
            Covering::Diagonal => {
                let diagonal: Vec<f64> =
                    (0..n).map(|i| (scaling.row[i] * m.diagonal(i) * scaling.col[i]).abs()).collect();
                let floor = 1e-3 * diagonal.iter().fold(0.0f64, |a, &x| a.max(x));
                diagonal.into_iter().map(|x| x.max(floor).max(f64::MIN_POSITIVE)).collect()
            }
        }
    }
}

/// The natural residual max |min(z_i, w_i)| with w = M z + q.
fn natural_residual(m: &Csc, q: &DVector<f64>, z: &[f64]) -> f64 {
    let mut w = q.as_slice().to_vec();
    m.mul_add(z, &mut w);
    let residual = z.iter().zip(&w).fold(0.0f64, |r, (z, w)| r.max(z.min(*w).abs()));
    if residual.is_nan() {
        f64::INFINITY
    } else {
        residual
    }
}

/// Solves the LCP `w = M z + q ⟂ z ≥ 0` by Lemke's method; returns z and the number of pivots
/// (over all attempts). The answer is verified: its natural residual on (M, q) is within
/// `options.tolerance · max(1, ‖q‖∞)`. The equilibrated LCP with the covering vector of ones
/// comes first; if that path ends on a ray, at the pivot limit or on a singular basis, other
/// covering vectors (a different path to the same solution set, Cottle, Pang & Stone §4.4) and
/// the unscaled LCP are tried, unless the ray proves the LCP infeasible.
pub fn lemke(
    m: &DMatrix<f64>,
    q: &DVector<f64>,
    options: &LemkeOptions,
) -> Result<(DVector<f64>, usize), SolverError> {
    lemke_with_report(m, q, options).map(|(z, report)| (z, report.pivots))
}

/// [`lemke`] with the facts of the solve.
pub fn lemke_with_report(
    m: &DMatrix<f64>,
    q: &DVector<f64>,
    options: &LemkeOptions,
) -> Result<(DVector<f64>, LemkeReport), SolverError> {
    let n = q.len();
    if m.shape() != (n, n) {
        return Err(SolverError::InvalidProblem(format!("M is {:?}, q has {n} entries", m.shape())));
    }
    if !m.iter().chain(q.iter()).all(|x| x.is_finite()) {
        return Err(SolverError::InvalidProblem("M or q holds NaN or infinity".into()));
    }
    solve_sparse(&Csc::from_dense(m), q, options)
}

/// [`lemke_with_report`] on M by sparse columns (sizes and finiteness checked by the caller).
fn solve_sparse(
    m: &Csc,
    q: &DVector<f64>,
    options: &LemkeOptions,
) -> Result<(DVector<f64>, LemkeReport), SolverError> {
    let n = q.len();
    let mut report = LemkeReport::default();
    if q.iter().all(|&x| x >= 0.0) {
        return Ok((DVector::zeros(n), report));
    }
    let tolerance = options.tolerance * q.amax().max(1.0);
    let path_options = PathOptions {
        max_pivots: if options.max_pivots == 0 { 50 * n + 100 } else { options.max_pivots },
        pivot_tolerance: options.pivot_tolerance,
        refactor_interval: options.refactor_interval,
    };
    let equilibrated = Scaling::equilibrate(m, 20);
    let identity = Scaling::identity(n);
    let mut best: Option<(DVector<f64>, f64)> = None;
    let mut failure: Option<SolverError> = None;
    for (scaled, covering) in ATTEMPTS {
        if !scaled && equilibrated.is_identity() {
            continue; // the same path as the equilibrated one
        }
        let scaling = if scaled { &equilibrated } else { &identity };
        let cols = Columns { m: m.scaled(&scaling.row, &scaling.col), d: covering.vector(m, scaling) };
        let q_scaled: Vec<f64> = q.iter().zip(&scaling.row).map(|(q, r)| q * r).collect();
        let mut path = Path::new(&cols, &q_scaled, path_options);
        let end = path.run();
        report.attempts += 1;
        report.pivots += path.pivots;
        report.lex_solves += path.lex_solves;
        report.refactorizations += path.basis.refactorizations;
        report.factorized_size = path.basis.factorized_size();
        let z_of = |path: &Path| -> Vec<f64> {
            (0..n).map(|j| (scaling.col[j] * path.value(n + j)).max(0.0)).collect()
        };
        // The path's point, z0 dropped: a solution when the path ended there, and possibly one
        // within the tolerance when it ended otherwise with z0 already near zero.
        let mut z = z_of(&path);
        let mut residual = natural_residual(m, q, &z);
        if end == PathEnd::Solved && residual > tolerance && path.polish(2).is_ok() {
            report.polished = true;
            report.refactorizations += 1;
            let polished = z_of(&path);
            let polished_residual = natural_residual(m, q, &polished);
            if polished_residual < residual {
                (z, residual) = (polished, polished_residual);
            }
            // The final basis itself is slightly infeasible: a path restarted from it (and once
            // more from that one's end), the best point kept.
            let mut vars = path.basis.vars.clone();
            for _ in 0..RESTARTS {
                if residual <= tolerance {
                    break;
                }
                let restart_cols = Columns { m: cols.m.clone(), d: covering_of_basis(&cols, &vars) };
                let mut restart = Path::new(&restart_cols, &q_scaled, path_options);
                let restart_end = restart.restart(&vars);
                report.restarts += 1;
                report.pivots += restart.pivots;
                report.lex_solves += restart.lex_solves;
                report.refactorizations += restart.basis.refactorizations;
                if restart_end != PathEnd::Solved {
                    break;
                }
                let restarted = z_of(&restart);
                let restarted_residual = natural_residual(m, q, &restarted);
                if restarted_residual < residual {
                    (z, residual) = (restarted, restarted_residual);
                }
                vars.copy_from_slice(&restart.basis.vars);
            }
        }
        if residual <= tolerance {
            report.residual = residual;
            report.near_solution = end != PathEnd::Solved;
            return Ok((DVector::from_vec(z), report));
        }
        match end {
            PathEnd::Solved => {
                if best.as_ref().is_none_or(|(_, r)| residual < *r) {
                    best = Some((DVector::from_vec(z), residual));
                }
            }
            PathEnd::Ray { entering } => {
                let certificate = ray_certificate(m, q, &path, entering, scaling, &cols.d, covering, scaled);
                let infeasible = certificate.infeasible;
                failure =
                    Some(SolverError::LemkeRay { pivots: report.pivots, certificate: Box::new(certificate) });
                if infeasible {
                    break;
                }
            }
            PathEnd::PivotLimit => {
                failure = Some(SolverError::PivotLimit { pivots: path_options.max_pivots });
            }
            PathEnd::Cycle => {
                failure = Some(SolverError::LemkeCycle { pivots: report.pivots });
            }
            PathEnd::Singular(singular) => {
                failure =
                    Some(SolverError::LemkeSingularBasis { pivots: report.pivots, ratio: singular.ratio });
            }
        }
    }
    match (best, failure) {
        (Some((_, residual)), _) => {
            Err(SolverError::Inaccurate { solver: "lemke".into(), residual, tolerance })
        }
        (None, Some(SolverError::LemkeRay { certificate, .. })) => {
            Err(SolverError::LemkeRay { pivots: report.pivots, certificate })
        }
        (None, Some(e)) => Err(e),
        (None, None) => Err(SolverError::PivotLimit { pivots: report.pivots }),
    }
}

/// The certificate of the ray a path ended on, in the original LCP's units: z = E z', the
/// covering vector D⁻¹ d' (w' = D w).
#[allow(clippy::too_many_arguments)]
fn ray_certificate(
    m: &Csc,
    q: &DVector<f64>,
    path: &Path,
    entering: usize,
    scaling: &Scaling,
    d_scaled: &[f64],
    covering: Covering,
    scaled: bool,
) -> RayCertificate {
    let n = q.len();
    // Along the ray the entering variable grows at rate 1 and the basic ones at −α.
    let mut rate = vec![0.0; 2 * n + 1];
    rate[entering] = 1.0;
    for (p, &var) in path.basis.vars.iter().enumerate() {
        rate[var] = -path.alpha[p];
    }
    let start = (0..n).map(|j| scaling.col[j] * path.value(n + j).max(0.0)).collect();
    let direction = (0..n).map(|j| scaling.col[j] * rate[n + j]).collect();
    let d: Vec<f64> = d_scaled.iter().zip(&scaling.row).map(|(d, r)| d / r).collect();
    debug_assert_ne!(path.basis.position[2 * n], NONE, "z0 is basic on a secondary ray");
    RayCertificate::check(m, q, &d, start, path.value(2 * n), direction, rate[2 * n], covering.name(), scaled)
}

/// Lemke's method as a [`ConstraintSolver`] (friction as a pyramid; a cone is approximated by
/// `facets` directions).
#[derive(Clone, Debug)]
pub struct LemkeSolver {
    /// Pivoting options.
    pub options: LemkeOptions,
    /// Pyramid directions used when the problem states a cone.
    pub facets: usize,
}

impl Default for LemkeSolver {
    fn default() -> Self {
        Self { options: LemkeOptions::default(), facets: 8 }
    }
}

impl ConstraintSolver for LemkeSolver {
    fn name(&self) -> &'static str {
        "lemke"
    }

    fn solve(
        &mut self,
        problem: &ConstraintProblem,
        lambda: &mut DVector<f64>,
    ) -> Result<SolveInfo, SolverError> {
        check_problem(problem)?;
        if matches!(problem.friction, FrictionModel::Cone) && self.facets < 3 {
            return Err(SolverError::InvalidProblem(format!(
                "a friction cone needs a pyramid of at least 3 facets, Lemke was given {}",
                self.facets
            )));
        }
        let lcp = sparse_lcp_of(problem, self.facets);
        let (z, report) = solve_sparse(&lcp.m, &lcp.q, &self.options)?;
        *lambda = lcp.impulses(&z);
        let pivots = report.pivots;
        let note = matches!(problem.friction, FrictionModel::Cone)
            .then(|| format!("friction cone approximated by a {}-facet pyramid", self.facets));
        Ok(SolveInfo { iterations: pivots, note, residuals: None })
    }
}
