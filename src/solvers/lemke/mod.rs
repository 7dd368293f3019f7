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
//!   are tried when a path fails, and seeded pseudo-random covering vectors when none of those
//!   leaves an answer.
//! - A pivot must exceed 1e-7 of its column: rounding of ill-conditioned bases passes for
//!   pivots below that, and a pivot on rounding makes the basis singular.
//! - The answer is verified on the original LCP; one that misses the tolerance is polished by a
//!   fresh factorization and iterative refinement of the final basis. If the basis itself is
//!   slightly infeasible (basic values some 1e-9 below zero after hundreds of degenerate
//!   pivots), a path is restarted from it with the covering vector B·1, which lifts every
//!   value with one z0 and ends where z0 leaves again ([`path::Path::restart`]).
//! - As a [`LemkeSolver`] in a solver chain, an answer whose LCP residual misses the tolerance
//!   (a basis of a highly degenerate vertex, values some 1e-9 below zero) is accepted when the
//!   problem's own residual, the one the chain certifies, is within the chain's tolerance;
//!   only otherwise are the other covering vectors tried, each a path from the identity again.
//! - An answer that neither check accepts (at the most degenerate vertices of a pyramid of
//!   touching boxes, thousands of w a few 1e-9 below zero that no pivot from the final basis
//!   resolves) is polished by block Gauss–Seidel sweeps, each contact's small LCP solved
//!   exactly with the rest of z fixed ([`polish`]), and judged by the same two checks before
//!   the next path is tried.
//! - A path that leaves along a secondary ray returns the ray with its check ([`RayCertificate`]):
//!   the ray's conditions recomputed from M and q, and whether its direction is a Farkas proof
//!   that the LCP has no feasible point (then no other covering vector is tried).
//!
//! [`lcp_of`] turns a [`ConstraintProblem`] into the LCP of the polyhedral-friction formulation.

mod basis;
mod columns;
mod delassus;
mod lazy;
mod lcp;
mod path;
mod polish;
mod ray;
mod scaling;
mod solver;

pub use lcp::{lcp_of, Lcp};
pub use ray::RayCertificate;
pub use solver::{LemkeMemory, LemkeSolver};

use super::SolverError;
use basis::NONE;
use columns::{Columns, Csc, Matrix};
use nalgebra::{DMatrix, DVector};
use path::{covering_of_basis, Path, PathEnd, PathOptions};
use scaling::Scaling;

/// Options of Lemke's method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LemkeOptions {
    /// Maximum number of pivots per covering vector (0: 10 × the LCP size + 100; a path from
    /// the identity takes a fraction of the size on contact LCPs, and one that goes on far
    /// longer is cycling through rounding, which the next covering vector escapes sooner).
    /// Paths from a given basis (a warm start, a restart) get half the size + 100.
    pub max_pivots: usize,
    /// Pivot tolerance relative to the largest entry of the entering column B⁻¹a (an entry
    /// must exceed it to pivot). On the zero-compliance LCPs of box pyramids (four coplanar
    /// corners under every box, eight friction facets spanning a plane) the bases grow
    /// ill-conditioned, and entries that are zero in exact arithmetic come out of B⁻¹a at
    /// 1e-9 to 1e-7 of the column's largest: a pivot on one makes the basis singular to working
    /// precision, its values jump at the next refactorization (by 0.1 and more on a q of 0.16)
    /// and the path ends on a false ray. 1e-7 leaves most such entries out; the paths that
    /// take one all the same end early, and the next covering vector is tried.
    pub pivot_tolerance: f64,
    /// Accepted complementarity residual max |min(z_i, w_i)| relative to max(1, ‖q‖∞).
    pub tolerance: f64,
    /// Column updates between refactorizations of the basis (0: chosen from the sizes).
    pub refactor_interval: usize,
    /// Harris's degeneracy tolerance δ of the ratio test, relative to max(1, ‖q‖∞) of the LCP a
    /// path runs on: basic values within δ of zero count as degenerate (the lexicographic rule
    /// chooses among their rows) and a pivot may leave a basic value at −δ. A quarter of the
    /// default `tolerance`: on the degenerate LCPs of box piles (a zero-compliance Delassus
    /// matrix of rank far below its size, four coplanar corners under every box, eight friction
    /// facets of a sticking contact with zero sliding speed) a δ near rounding (1e-11) lets
    /// rounding noise of ill-conditioned bases decide hundreds of ties, and paths wander (blocks
    /// of 600 and more variables) into singular bases and false rays; a δ near the tolerance
    /// keeps the blocks at the size of the answer's active set and the overshoots, cleaned by
    /// `Path::clean` and restarts, within the tolerance.
    pub degeneracy_tolerance: f64,
    /// Most floating-point operations of the bases' solves and factorizations over all paths
    /// of one solve (estimated from their sizes; 0: no limit but the pivots'). A pivot costs
    /// O(k²) and a refactorization O(k³) in the size k of the basis's factorized block, so that
    /// a pivot limit alone does not bound the time of a large LCP; beyond this budget the solve
    /// ends with [`SolverError::LemkeWorkLimit`].
    pub max_operations: f64,
    /// The paths after the first (other covering vectors, the unscaled LCP) may spend together
    /// at most this multiple of the first path's operations, or of 10⁹ if that is more (0: no
    /// such limit). The first path is the one that answers a contact LCP; the others rescue
    /// the degenerate ones whose first path ends on rounding, at the first path's cost or
    /// less. Without the limit an LCP no path solves (ten interpenetrating rovers: 6 000
    /// variables, every path ending on a ray) costs eight full paths, each pivot O(k²) in a
    /// dense basis.
    pub fallback_share: f64,
    /// Most entries the LCP's sparse matrices (A + R, then M) may store (0: no limit). M, its
    /// equilibrated copy and A + R take 16 bytes an entry, and M fills in where contacts share
    /// bodies: ten rovers built into one place give an LCP of 14 500 variables whose M is
    /// nearly dense (5.8 GB). Beyond the limit the solve ends with
    /// [`SolverError::LemkeMatrixTooLarge`] before allocating for the rest.
    pub max_matrix_entries: usize,
}

/// The least first-path work [`LemkeOptions::fallback_share`] is a multiple of (operations).
const FALLBACK_FLOOR: f64 = 1e9;

impl Default for LemkeOptions {
    fn default() -> Self {
        Self {
            max_pivots: 0,
            pivot_tolerance: 1e-7,
            tolerance: 1e-9,
            refactor_interval: 0,
            degeneracy_tolerance: 2.5e-10,
            max_operations: 0.0,
            fallback_share: 4.0,
            max_matrix_entries: 0,
        }
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
    /// Floating-point operations of the bases' solves and factorizations over all attempts
    /// (estimated from their sizes, [`LemkeOptions::max_operations`]).
    pub operations: f64,
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
    /// Principal pivots that repaired final bases with slightly negative values.
    pub swaps: usize,
    /// Whether the answer was polished by block Gauss–Seidel sweeps from a path's answer
    /// above the tolerance.
    pub polished_blocks: bool,
    /// Whether the solve started from a given complementary basis (the last solve's).
    pub warm_started: bool,
    /// Whether the answer is the point where a path ended on a ray, the pivot limit, a cycle
    /// or a singular basis with z0 so near zero that, z0 dropped, it meets the tolerance.
    pub near_solution: bool,
    /// Whether the answer is that of a path from the first answer's basis with a finer LCP
    /// tolerance, run because the first answer's residual on the problem missed the tolerance
    /// the caller certifies against ([`LemkeSolver::certified_tolerance`]).
    pub refined_to_level: bool,
}

impl LemkeReport {
    /// Adds the counts of `other` (work done on the way to this report's answer).
    fn add_work(&mut self, other: &LemkeReport) {
        self.pivots += other.pivots;
        self.attempts += other.attempts;
        self.refactorizations += other.refactorizations;
        self.operations += other.operations;
        self.lex_solves += other.lex_solves;
        self.restarts += other.restarts;
        self.swaps += other.swaps;
    }

    /// The counts of this report and `later`'s summed (the facts of two solves in a row).
    fn merged(self, later: LemkeReport) -> LemkeReport {
        LemkeReport {
            pivots: self.pivots + later.pivots,
            attempts: self.attempts + later.attempts,
            refactorizations: self.refactorizations + later.refactorizations,
            operations: self.operations + later.operations,
            lex_solves: self.lex_solves + later.lex_solves,
            restarts: self.restarts + later.restarts,
            swaps: self.swaps + later.swaps,
            ..later
        }
    }
}

/// Paths restarted from the final basis of a path whose answer misses the tolerance.
const RESTARTS: usize = 2;

/// Sweeps of block Gauss–Seidel at most on an answer above the tolerance ([`polish`]).
const POLISH_SWEEPS: usize = 30;

/// Principal pivots tried on a final basis with slightly negative values ([`Path::clean`]).
const SWAPS: usize = 16;

/// The paths tried in order: (equilibrated, covering vector). The covering vectors are in the
/// units of the LCP the path runs on. The pseudo-random ones (seeded: the same problem always
/// takes the same paths) come last, tried only when no earlier path left an answer (within the
/// tolerance or not), for the LCPs whose fixed paths all end on rounding: on
/// the degenerate LCPs of box pyramids each path reaches a solution or not depending on
/// which ties rounding decides, and a path with other ties, not a repeat of the same one, is
/// what succeeds (as PATH restarts from a perturbed point; Dirkse & Ferris 1995).
const ATTEMPTS: [(bool, Covering); 8] = [
    (true, Covering::Ones),
    (true, Covering::Golden),
    (false, Covering::Ones),
    (false, Covering::Golden),
    (true, Covering::Diagonal),
    (true, Covering::Random(1)),
    (true, Covering::Random(2)),
    (true, Covering::Random(3)),
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
    /// d_i in [1, 2), pseudo-random from the seed (SplitMix64).
    Random(u64),
}

impl Covering {
    fn name(self) -> &'static str {
        match self {
            Covering::Ones => "ones",
            Covering::Golden => "golden",
            Covering::Diagonal => "diagonal",
            Covering::Random(_) => "random",
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
            Covering::Random(seed) => {
                let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15);
                (0..n)
                    .map(|_| {
                        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
                        let mut z = state;
                        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
                        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
                        z ^= z >> 31;
                        1.0 + (z >> 11) as f64 / (1u64 << 53) as f64
                    })
                    .collect()
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
    let m = Csc::from_dense(m);
    let solution = solve_sparse(&m, q, options, &mut None, LemkeReport::default(), &mut |_| false)?;
    if !solution.within_tolerance {
        let tolerance = options.tolerance * q.amax().max(1.0);
        return Err(SolverError::Inaccurate {
            solver: "lemke".into(),
            residual: solution.report.residual,
            tolerance,
        });
    }
    Ok((solution.z, solution.report))
}

/// M equilibrated (Ruiz's scaling, [`scaling`]) and its scaled copy, formed once per M.
#[derive(Clone, Debug)]
struct Equilibrated {
    scaling: Scaling,
    m: Csc,
}

impl Equilibrated {
    /// The equilibration of `m`.
    pub fn of(m: &Csc) -> Self {
        let scaling = Scaling::equilibrate(m, 20);
        Self { m: m.scaled(&scaling.row, &scaling.col), scaling }
    }
}

/// An answer of [`solve_sparse`].
struct Solution {
    /// z.
    pub z: DVector<f64>,
    /// The facts of the solve.
    pub report: LemkeReport,
    /// Whether z's natural residual is within the tolerance; the best answer of paths that all
    /// missed it otherwise (for a caller that certifies the answer by other residuals).
    pub within_tolerance: bool,
    /// The complementary basis z is the solution of (w_i = i, z_j = n + j, by position), when
    /// it is one (not for a path's end point accepted with z0 dropped).
    pub basis: Option<Vec<usize>>,
    /// Whether z, above the LCP tolerance, was accepted by the caller's own certificate.
    pub certified: bool,
}

impl Solution {
    /// z = 0 for a q ≥ 0: every w basic, no pivot.
    fn trivial(n: usize, report: LemkeReport) -> Self {
        Self {
            z: DVector::zeros(n),
            report,
            within_tolerance: true,
            basis: Some((0..n).collect()),
            certified: false,
        }
    }
}

/// The caller's certificate of an answer z that misses the LCP tolerance (a [`LemkeSolver`]'s:
/// the problem's residual within the tolerance its chain certifies against): `true` accepts z
/// and ends the solve.
pub(super) type Certify<'a> = dyn FnMut(&DVector<f64>) -> bool + 'a;

/// Whether `vars` is a complementary basis of an LCP of size n: one of w_i, z_i for every i.
fn is_complementary(vars: &[usize], n: usize) -> bool {
    let mut covered = vec![false; n];
    vars.len() == n
        && vars.iter().all(|&var| {
            let i = if var < n { var } else { var.wrapping_sub(n) };
            i < n && !std::mem::replace(&mut covered[i], true)
        })
}

/// The operations a solve may spend ([`LemkeOptions::max_operations`]).
fn budget_of(options: &LemkeOptions) -> f64 {
    if options.max_operations > 0.0 {
        options.max_operations
    } else {
        f64::INFINITY
    }
}

/// The options of a path for an LCP of size n, and the accepted natural residual.
fn path_options(options: &LemkeOptions, q: &DVector<f64>) -> (PathOptions, f64) {
    let n = q.len();
    let path_options = PathOptions {
        max_pivots: if options.max_pivots == 0 { 10 * n + 100 } else { options.max_pivots },
        max_operations: budget_of(options),
        pivot_tolerance: options.pivot_tolerance,
        refactor_interval: options.refactor_interval,
        degeneracy_tolerance: options.degeneracy_tolerance,
    };
    (path_options, options.tolerance * q.amax().max(1.0))
}

/// The natural residual of z with w = M z + q, M from `cols` (whose z-columns are −M's).
fn residual_of_columns(cols: &Columns, q: &DVector<f64>, z: &[f64]) -> f64 {
    let n = q.len();
    let mut w = q.as_slice().to_vec();
    for (j, &zj) in z.iter().enumerate() {
        if zj != 0.0 {
            cols.for_each(n + j, |i, v| w[i] -= v * zj);
        }
    }
    let residual = z.iter().zip(&w).fold(0.0f64, |r, (z, w)| r.max(z.min(*w).abs()));
    if residual.is_nan() {
        f64::INFINITY
    } else {
        residual
    }
}

/// A path of the unscaled LCP (M by `cols`, whose covering vector is replaced) from the
/// complementary basis `start` (the last solve's, or one read from a warm start): a start
/// whose values are feasible for this q is the answer without a pivot; one slightly
/// infeasible is lifted by z0 along the covering vector B·1 and its path followed until z0
/// leaves ([`Path::restart`]). Unscaled, as M's equilibration (twenty sweeps over its entries)
/// would cost more than the few pivots from a basis near the answer. An answer above the
/// tolerance is accepted when `certify` accepts it; with `certify_repairs`, `certify` also ends
/// the repair of the path's final basis ([`repair_final_basis`]) once it accepts a point.
/// `Err` with the work done when the path ends otherwise or its answer is not accepted.
fn solve_from_basis(
    cols: &mut Columns,
    q: &DVector<f64>,
    options: &LemkeOptions,
    start: &[usize],
    certify: &mut Certify<'_>,
    certify_repairs: bool,
) -> Result<Solution, LemkeReport> {
    let n = q.len();
    let mut report = LemkeReport { warm_started: true, ..Default::default() };
    if q.iter().all(|&x| x >= 0.0) {
        return Ok(Solution::trivial(n, report));
    }
    if !is_complementary(start, n) {
        return Err(report);
    }
    let (mut path_options, tolerance) = path_options(options, q);
    // A path from near the answer ends within a few pivots; one that has gone on for more
    // pivots than the start has active variables (plus 100) is wandering, and the path from the
    // identity (each active variable enters it once, plus the degenerate exchanges) is the
    // surer way on.
    let active = start.iter().filter(|&&var| var >= n).count();
    path_options.max_pivots = path_options.max_pivots.min(n / 2 + 100).min(active + 100);
    cols.d = covering_of_basis(cols, start);
    let mut path = Path::new(cols, q.as_slice(), path_options);
    let end = path.restart(start);
    report.attempts += 1;
    report.pivots += path.pivots;
    report.operations += path.basis.operations;
    report.lex_solves += path.lex_solves;
    report.refactorizations += path.basis.refactorizations;
    report.factorized_size = path.basis.factorized_size();
    if end == PathEnd::Solved {
        let z_of = |path: &Path| -> Vec<f64> { (0..n).map(|j| path.value(n + j).max(0.0)).collect() };
        let residual_of = |z: &[f64]| residual_of_columns(cols, q, z);
        let mut enough = |z: &[f64]| certify_repairs && certify(&DVector::from_column_slice(z));
        let repaired = repair_final_basis(
            &mut path,
            q.as_slice(),
            path_options,
            tolerance,
            &mut report,
            &z_of,
            &residual_of,
            &mut enough,
        );
        let (mut z, mut residual) = (DVector::from_vec(repaired.z), repaired.residual);
        let mut within_tolerance = residual <= tolerance;
        let mut accepted = within_tolerance || certify(&z);
        if !accepted {
            // Neither within the tolerance nor certified: polished from this answer.
            let blocks = match cols.m {
                Matrix::Lazy(lcp) => lcp.blocks(),
                Matrix::Formed(_) => polish::blocks_of(cols),
            };
            if let Some((polished, polished_residual)) =
                polish::polish(cols, q.as_slice(), &blocks, z.as_slice(), tolerance, POLISH_SWEEPS)
            {
                report.polished_blocks = true;
                (z, residual) = (DVector::from_vec(polished), polished_residual);
                within_tolerance = residual <= tolerance;
                accepted = within_tolerance || certify(&z);
            }
        }
        if accepted {
            report.residual = residual;
            return Ok(Solution {
                z,
                report,
                within_tolerance,
                basis: repaired.basis,
                certified: !within_tolerance,
            });
        }
    }
    Err(report)
}

/// [`lemke_with_report`] on M by sparse columns (sizes and finiteness checked by the caller),
/// with M's equilibration (formed here if `None`) and the report of work already done. A
/// path's answer above the tolerance that `certify` accepts ends the solve (the other covering
/// vectors are tried only for answers neither meets).
fn solve_sparse(
    m: &Csc,
    q: &DVector<f64>,
    options: &LemkeOptions,
    equilibrated: &mut Option<Equilibrated>,
    mut report: LemkeReport,
    certify: &mut Certify<'_>,
) -> Result<Solution, SolverError> {
    let n = q.len();
    if q.iter().all(|&x| x >= 0.0) {
        return Ok(Solution::trivial(n, report));
    }
    let (path_options, tolerance) = path_options(options, q);
    let scaled_q =
        |scaling: &Scaling| -> Vec<f64> { q.iter().zip(&scaling.row).map(|(q, r)| q * r).collect() };
    let equilibrated = equilibrated.get_or_insert_with(|| Equilibrated::of(m));
    let identity = Scaling::identity(n);
    let mut best: Option<(DVector<f64>, f64, Option<Vec<usize>>)> = None;
    let mut failure: Option<SolverError> = None;
    let mut blocks = None;
    // Operations done before the first path (a warm start's), and after it.
    let before = report.operations;
    let mut first_path: Option<f64> = None;
    for (scaled, covering) in ATTEMPTS {
        if !scaled && equilibrated.scaling.is_identity() {
            continue; // the same path as the equilibrated one
        }
        if matches!(covering, Covering::Random(_)) && best.is_some() {
            break; // an answer to hand on (above the tolerance): the random paths are for none
        }
        let mut remaining = path_options.max_operations - report.operations;
        let mut limit = path_options.max_operations;
        if let Some(first) = first_path {
            // The paths after the first share a budget in proportion to the first's work.
            let share = options.fallback_share;
            if share > 0.0 {
                let fallbacks = share * (first - before).max(FALLBACK_FLOOR);
                remaining = remaining.min(fallbacks - (report.operations - first));
                limit = limit.min(fallbacks);
            }
        }
        if remaining <= 0.0 {
            failure = Some(SolverError::LemkeWorkLimit { pivots: report.pivots, budget: limit });
            break;
        }
        let path_options = PathOptions { max_operations: remaining, ..path_options };
        let scaling = if scaled { &equilibrated.scaling } else { &identity };
        let cols = Columns {
            m: Matrix::Formed(if scaled { &equilibrated.m } else { m }),
            d: covering.vector(m, scaling),
        };
        let q_scaled = scaled_q(scaling);
        let outcome =
            attempt(m, q, &cols, &q_scaled, scaling, covering, scaled, path_options, tolerance, &mut report);
        first_path.get_or_insert(report.operations);
        match outcome {
            Attempt::Solved(solution) => return Ok(solution),
            Attempt::Inaccurate(mut z, mut residual, basis) => {
                if certify(&z) {
                    report.residual = residual;
                    return Ok(Solution { z, report, within_tolerance: false, basis, certified: true });
                }
                // Neither within the tolerance nor certified: polished from this answer.
                let original = Columns { m: Matrix::Formed(m), d: Vec::new() };
                let blocks = blocks.get_or_insert_with(|| polish::blocks_of(&original));
                if let Some((polished, polished_residual)) =
                    polish::polish(&original, q.as_slice(), blocks, z.as_slice(), tolerance, POLISH_SWEEPS)
                {
                    report.polished_blocks = true;
                    (z, residual) = (DVector::from_vec(polished), polished_residual);
                    let within_tolerance = residual <= tolerance;
                    if within_tolerance || certify(&z) {
                        report.residual = residual;
                        return Ok(Solution {
                            z,
                            report,
                            within_tolerance,
                            basis,
                            certified: !within_tolerance,
                        });
                    }
                }
                if best.as_ref().is_none_or(|(_, r, _)| residual < *r) {
                    best = Some((z, residual, basis));
                }
            }
            Attempt::Failed(error, last) => {
                failure = Some(match error {
                    SolverError::LemkeWorkLimit { pivots, .. } => {
                        SolverError::LemkeWorkLimit { pivots, budget: limit }
                    }
                    error => error,
                });
                if last {
                    break;
                }
            }
        }
    }
    match (best, failure) {
        (Some((z, residual, basis)), _) => {
            report.residual = residual;
            Ok(Solution { z, report, within_tolerance: false, basis, certified: false })
        }
        (None, Some(SolverError::LemkeRay { certificate, .. })) => {
            Err(SolverError::LemkeRay { pivots: report.pivots, certificate })
        }
        (None, Some(SolverError::LemkeWorkLimit { budget, .. })) => {
            Err(SolverError::LemkeWorkLimit { pivots: report.pivots, budget })
        }
        (None, Some(e)) => Err(e),
        (None, None) => Err(SolverError::PivotLimit { pivots: report.pivots }),
    }
}

/// How one path from the identity (and its restarts) ended.
enum Attempt {
    /// An answer within the tolerance.
    Solved(Solution),
    /// The path's best answer, above the tolerance, with its residual and basis.
    Inaccurate(DVector<f64>, f64, Option<Vec<usize>>),
    /// The path failed; whether no further path is to be tried (its ray proves the LCP
    /// infeasible, or the solve's work budget is spent).
    Failed(SolverError, bool),
}

/// One path of [`solve_sparse`] on `cols` (M scaled by `scaling` with a covering vector), its
/// answer polished and, if slightly infeasible, restarted from its final basis.
#[allow(clippy::too_many_arguments)]
fn attempt(
    m: &Csc,
    q: &DVector<f64>,
    cols: &Columns,
    q_scaled: &[f64],
    scaling: &Scaling,
    covering: Covering,
    scaled: bool,
    path_options: PathOptions,
    tolerance: f64,
    report: &mut LemkeReport,
) -> Attempt {
    let n = q.len();
    let mut path = Path::new(cols, q_scaled, path_options);
    let end = path.run();
    report.attempts += 1;
    report.pivots += path.pivots;
    report.operations += path.basis.operations;
    report.lex_solves += path.lex_solves;
    report.refactorizations += path.basis.refactorizations;
    report.factorized_size = path.basis.factorized_size();
    let z_of =
        |path: &Path| -> Vec<f64> { (0..n).map(|j| (scaling.col[j] * path.value(n + j)).max(0.0)).collect() };
    // The path's point, z0 dropped: a solution when the path ended there (made as accurate as
    // its final basis allows), and possibly one within the tolerance when it ended otherwise
    // with z0 already near zero.
    let residual_of = |z: &[f64]| natural_residual(m, q, z);
    let (z, residual, basis) = if end == PathEnd::Solved {
        let repaired = repair_final_basis(
            &mut path,
            q_scaled,
            path_options,
            tolerance,
            report,
            &z_of,
            &residual_of,
            &mut |_| false,
        );
        (repaired.z, repaired.residual, repaired.basis)
    } else {
        let z = z_of(&path);
        let residual = residual_of(&z);
        (z, residual, None)
    };
    if residual <= tolerance {
        report.residual = residual;
        report.near_solution = end != PathEnd::Solved;
        return Attempt::Solved(Solution {
            z: DVector::from_vec(z),
            report: report.clone(),
            within_tolerance: true,
            basis,
            certified: false,
        });
    }
    match end {
        PathEnd::Solved => Attempt::Inaccurate(DVector::from_vec(z), residual, basis),
        PathEnd::Ray { entering } => {
            let certificate = ray_certificate(m, q, &path, entering, scaling, &cols.d, covering, scaled);
            let infeasible = certificate.infeasible;
            Attempt::Failed(
                SolverError::LemkeRay { pivots: report.pivots, certificate: Box::new(certificate) },
                infeasible,
            )
        }
        PathEnd::PivotLimit => {
            Attempt::Failed(SolverError::PivotLimit { pivots: path_options.max_pivots }, false)
        }
        // The budget is the solve's: no further path.
        PathEnd::WorkLimit => {
            Attempt::Failed(SolverError::LemkeWorkLimit { pivots: report.pivots, budget: f64::NAN }, true)
        }
        PathEnd::Cycle => Attempt::Failed(SolverError::LemkeCycle { pivots: report.pivots }, false),
        PathEnd::Singular(singular) => Attempt::Failed(
            SolverError::LemkeSingularBasis { pivots: report.pivots, ratio: singular.ratio },
            false,
        ),
    }
}

/// A path's answer after [`repair_final_basis`]: z (original units), its natural residual on
/// the original LCP and its complementary basis.
struct Repaired {
    z: Vec<f64>,
    residual: f64,
    basis: Option<Vec<usize>>,
}

/// The answer of a path that ended with z0 leaving (`Solved`), made as accurate as its final
/// basis allows: the values polished (fresh factorization and refinement); a basis whose values
/// are slightly negative repaired by principal pivots ([`Path::clean`]); and a basis still
/// slightly infeasible taken as the start of a path with the covering vector B·1
/// ([`Path::restart`]), twice at most, each held to as many pivots as that basis has active
/// variables plus 100. `z_of` reads z (in the original units) from a path, `residual_of` its
/// natural residual on the original LCP; the repairs end once the best point is within the
/// tolerance or `enough` accepts it; the best answer is returned.
#[allow(clippy::too_many_arguments)]
fn repair_final_basis(
    path: &mut Path,
    q_path: &[f64],
    path_options: PathOptions,
    tolerance: f64,
    report: &mut LemkeReport,
    z_of: &dyn Fn(&Path) -> Vec<f64>,
    residual_of: &dyn Fn(&[f64]) -> f64,
    enough: &mut dyn FnMut(&[f64]) -> bool,
) -> Repaired {
    let n = q_path.len();
    let mut z = z_of(path);
    let mut residual = residual_of(&z);
    let mut basis = Some(path.basis.vars.clone());
    let refactorizations = path.basis.refactorizations;
    if path.polish(2).is_ok() {
        report.polished = true;
        report.refactorizations += path.basis.refactorizations - refactorizations;
        let polished = z_of(path);
        let polished_residual = residual_of(&polished);
        if polished_residual <= residual {
            (z, residual) = (polished, polished_residual);
        }
        // Slightly negative values of the final basis: principal pivots to a clean one.
        if residual > tolerance && !enough(&z) {
            let vars = path.basis.vars.clone();
            if let Ok(swaps) = path.clean(SWAPS) {
                report.swaps += swaps;
                let cleaned = z_of(path);
                let cleaned_residual = residual_of(&cleaned);
                if cleaned_residual < residual {
                    (z, residual) = (cleaned, cleaned_residual);
                    basis = Some(path.basis.vars.clone());
                } else {
                    basis = Some(vars);
                }
            }
        }
    }
    // The final basis itself is slightly infeasible: a path restarted from it (and once more
    // from that one's end), the best point kept.
    let mut vars = path.basis.vars.clone();
    for _ in 0..RESTARTS {
        if residual <= tolerance || enough(&z) {
            break;
        }
        let restart_cols = Columns { m: path.columns().m, d: covering_of_basis(path.columns(), &vars) };
        let active = vars.iter().filter(|&&var| var >= n).count();
        let restart_options = PathOptions {
            max_pivots: path_options.max_pivots.min(n / 2 + 100).min(active + 100),
            ..path_options
        };
        let mut restart = Path::new(&restart_cols, q_path, restart_options);
        let restart_end = restart.restart(&vars);
        report.restarts += 1;
        report.pivots += restart.pivots;
        report.operations += restart.basis.operations;
        report.lex_solves += restart.lex_solves;
        report.refactorizations += restart.basis.refactorizations;
        if restart_end != PathEnd::Solved {
            break;
        }
        let _ = restart.polish(2);
        let restarted = z_of(&restart);
        let restarted_residual = residual_of(&restarted);
        if restarted_residual < residual {
            (z, residual) = (restarted, restarted_residual);
            basis = Some(restart.basis.vars.clone());
        }
        vars.copy_from_slice(&restart.basis.vars);
    }
    Repaired { z, residual, basis }
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
