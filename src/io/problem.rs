//! Constraint problems as files: for solver regression tests, and for running other solvers on
//! gelenk's problems.
//!
//! [`write_problem`] writes one [`ConstraintProblem`] into a directory:
//!
//! | file | content |
//! |---|---|
//! | `problem.json` | gelenk's own form, enough to rebuild the exact problem ([`read_problem`]): `A`, `b`, `R`, target velocities, row laws, contact blocks (normal row, μ, μ₂), friction model, row origins and, when known, `J` and `M⁻¹Jᵀ` |
//! | `cone.json` | the cone program of [`cone_program`] in the schema clarabel's `save_to_file` writes (`P`, `q`, `A`, `b`, `cones`, `settings`): `DefaultSolver::load_from_file` reads it |
//! | `lcp.npz` | the LCP of [`lcp_of`] that Lemke's method solves: `M`, `q`, and the map back to impulses `λ = C z + c0` |
//! | `qp.npz` | when the cone program has no second-order cone (frictionless or pyramid friction): the QP in qpsolvers' form `min ½xᵀPx + qᵀx, Gx ≤ h, Ax = b, lb ≤ x ≤ ub`, every matrix dense; rows that bound one variable go to `lb`/`ub`, zero-cone rows to `A`, the others (pyramid facets) to `G` |
//! | `meta.json` | [`ProblemMeta`]: scene, step, formulation, each solver's status, solution, objective and residuals (clarabel's is the reference), and the tolerances a re-solve must meet |
//!
//! `problem.json` stores matrices as arrays of rows and an unbounded box side as `null`
//! (`lo = −∞`, `hi = +∞`); numbers are written in the shortest form that reads back to the same
//! `f64`, so write → read gives the identical problem. The `.npy` entries of the `.npz` files are
//! format 1.0, `<f8`, C order; the archives are stored (uncompressed) zip files that
//! `numpy.load` reads.

use crate::constraints::{ConstraintProblem, ContactBlock, FrictionModel, RowLaw, RowOrigin};
use crate::solvers::{
    cone_program, lcp_of, residuals, ClarabelSolver, ConstraintSolver, LemkeSolver, PgsSolver, Residuals,
};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, SupportedConeT};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use thiserror::Error;

/// `format` field of `problem.json`.
pub const PROBLEM_FORMAT: &str = "gelenk-constraint-problem";
/// `format` field of `meta.json`.
pub const META_FORMAT: &str = "gelenk-problem-meta";
/// Version of both formats.
pub const FORMAT_VERSION: u32 = 1;
/// Name of gelenk's own problem file.
pub const PROBLEM_FILE: &str = "problem.json";
/// Name of the clarabel JSON file.
pub const CONE_FILE: &str = "cone.json";
/// Name of the LCP archive.
pub const LCP_FILE: &str = "lcp.npz";
/// Name of the QP archive (only for problems without second-order cones).
pub const QP_FILE: &str = "qp.npz";
/// Name of the metadata file.
pub const META_FILE: &str = "meta.json";

/// Certifying-residual tolerance (m/s) recorded for Lemke's method.
pub const LEMKE_TOLERANCE: f64 = 1e-8;
/// Certifying-residual tolerance (m/s) recorded for clarabel (it stops at a relative gap of
/// 1e-10, which is not a bound on the complementarity residual of an ill-conditioned problem).
pub const CLARABEL_TOLERANCE: f64 = 1e-6;
/// Certifying-residual tolerance (m/s) recorded for PGS: looser, as projected Gauss–Seidel
/// converges linearly and slowly on stacks and redundant rows.
pub const PGS_TOLERANCE: f64 = 1e-3;
/// PGS sweeps used by [`CorpusSolver::Pgs`].
pub const PGS_SWEEPS: usize = 20_000;
/// Tolerance (m/s) on the row velocities `w` of a solver whose `w` must equal the reference's.
pub const W_TOLERANCE: f64 = 1e-6;

/// Why a problem file could not be read or written. Every variant names the file.
#[derive(Debug, Error)]
pub enum ProblemFileError {
    /// The file could not be read.
    #[error("{}: cannot read: {source}", .path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file or directory could not be written.
    #[error("{}: cannot write: {source}", .path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Not JSON of the expected shape (serde's message gives line and column).
    #[error("{}: not a valid {what}: {source}", .path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// What the file should hold.
        what: &'static str,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// Well-formed, but not a consistent problem (sizes, laws, contact blocks, numbers).
    #[error("{}: {reason}", .path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is inconsistent.
        reason: String,
    },
}

// ---------------------------------------------------------------------------------------------
// problem.json

#[derive(Serialize, Deserialize)]
#[serde(tag = "law", rename_all = "snake_case")]
enum LawFile {
    Bilateral,
    Unilateral,
    Bounded { lo: Option<f64>, hi: Option<f64> },
    Friction { contact: usize },
}

#[derive(Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case")]
enum FrictionFile {
    Cone,
    Pyramid { facets: usize },
}

#[derive(Serialize, Deserialize)]
#[serde(tag = "kind", content = "index", rename_all = "snake_case")]
enum OriginFile {
    Contact(usize),
    LowerLimit(usize),
    UpperLimit(usize),
    SwingLimit(usize),
    TwistLowerLimit(usize),
    TwistUpperLimit(usize),
    Motor(usize),
    JointFriction(usize),
    Loop(usize),
    Other,
}

#[derive(Serialize, Deserialize)]
struct ContactFile {
    normal: usize,
    mu: f64,
    mu2: f64,
}

#[derive(Serialize, Deserialize)]
struct ProblemFile {
    format: String,
    version: u32,
    rows: usize,
    nv: usize,
    friction: FrictionFile,
    laws: Vec<LawFile>,
    contacts: Vec<ContactFile>,
    #[serde(default)]
    origins: Option<Vec<OriginFile>>,
    bias: Vec<f64>,
    regularization: Vec<f64>,
    #[serde(default)]
    target: Option<Vec<f64>>,
    delassus: Vec<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    jacobian: Option<Vec<Vec<f64>>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    minv_jt: Option<Vec<Vec<f64>>>,
}

fn matrix_rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}

fn matrix_from_rows(
    rows: &[Vec<f64>],
    nrows: usize,
    ncols: usize,
    name: &str,
) -> Result<DMatrix<f64>, String> {
    if rows.len() != nrows || rows.iter().any(|r| r.len() != ncols) {
        return Err(format!("\"{name}\" must be {nrows} rows of {ncols} numbers"));
    }
    Ok(DMatrix::from_fn(nrows, ncols, |i, j| rows[i][j]))
}

fn vector(x: &[f64], n: usize, name: &str) -> Result<DVector<f64>, String> {
    if x.len() != n {
        return Err(format!("\"{name}\" has {} entries, the problem has {n} rows", x.len()));
    }
    Ok(DVector::from_column_slice(x))
}

/// Checks that `problem` is consistent: sizes, finite numbers, laws and contact blocks agreeing
/// (what every solver and [`residuals()`] rely on).
pub fn validate_problem(problem: &ConstraintProblem) -> Result<(), String> {
    let n = problem.rows();
    let nv = problem.jacobian.ncols();
    let sized = |name: &str, len: usize| {
        if len == n {
            Ok(())
        } else {
            Err(format!("{name} has {len} entries, the problem has {n} rows"))
        }
    };
    sized("b", problem.bias.len())?;
    sized("R", problem.regularization.len())?;
    sized("the target velocities", problem.target.len())?;
    sized("the row origins", problem.origins.len())?;
    let delassus = problem.delassus_dense();
    if delassus.shape() != (n, n) {
        return Err(format!("A is {:?}, the problem has {n} rows", delassus.shape()));
    }
    if problem.jacobian.nrows() != n || problem.minv_jt.shape() != (nv, n) {
        return Err(format!(
            "J is {:?} and M⁻¹Jᵀ {:?}; with {n} rows they must be n×nv and nv×n",
            problem.jacobian.shape(),
            problem.minv_jt.shape()
        ));
    }
    let all_finite = |x: &[f64]| x.iter().all(|v| v.is_finite());
    for (name, x) in [
        ("A", delassus.as_slice()),
        ("b", problem.bias.as_slice()),
        ("R", problem.regularization.as_slice()),
        ("the target velocities", problem.target.as_slice()),
        ("J", problem.jacobian.as_slice()),
        ("M⁻¹Jᵀ", problem.minv_jt.as_slice()),
    ] {
        if !all_finite(x) {
            return Err(format!("{name} holds NaN or infinity"));
        }
    }
    if let Some(i) = problem.regularization.iter().position(|&r| r < 0.0) {
        return Err(format!("row {i}: regularization R = {} is negative", problem.regularization[i]));
    }
    // A = J M⁻¹ Jᵀ is symmetric positive semidefinite; a solver given anything else answers
    // another question (PGS and Lemke read one triangle only where they read it at all). The
    // full test of definiteness is a factorization; its diagonal and symmetry are cheap.
    let scale = (0..n).map(|i| delassus[(i, i)].abs()).fold(0.0, f64::max);
    if let Some(i) = (0..n).find(|&i| delassus[(i, i)] < -1e-12 * scale) {
        return Err(format!(
            "A[{i}][{i}] = {} is negative: A must be positive semidefinite",
            delassus[(i, i)]
        ));
    }
    for i in 0..n {
        if let Some(j) = (i + 1..n).find(|&j| (delassus[(i, j)] - delassus[(j, i)]).abs() > 1e-9 * scale) {
            return Err(format!(
                "A is not symmetric: A[{i}][{j}] = {} but A[{j}][{i}] = {}",
                delassus[(i, j)],
                delassus[(j, i)]
            ));
        }
    }
    if let FrictionModel::Pyramid { facets } = problem.friction {
        if !(3..=crate::constraints::MAX_PYRAMID_FACETS).contains(&facets) {
            return Err(format!(
                "a friction pyramid needs 3 to {} facets, got {facets}",
                crate::constraints::MAX_PYRAMID_FACETS
            ));
        }
    }
    for (k, c) in problem.contacts.iter().enumerate() {
        if c.normal.checked_add(2).is_none_or(|last| last >= n) {
            return Err(format!(
                "contact {k}: rows {}..{} exceed the {n} rows",
                c.normal,
                c.normal.saturating_add(2)
            ));
        }
        if problem.laws[c.normal] != RowLaw::Unilateral {
            return Err(format!("contact {k}: its normal row {} is not unilateral", c.normal));
        }
        for t in [c.normal + 1, c.normal + 2] {
            if problem.laws[t] != (RowLaw::Friction { contact: k }) {
                return Err(format!("contact {k}: row {t} is not a friction row of contact {k}"));
            }
        }
        if !(c.mu >= 0.0 && c.mu2 >= 0.0 && c.mu.is_finite() && c.mu2.is_finite()) {
            return Err(format!(
                "contact {k}: friction coefficients {} and {} must be finite and ≥ 0",
                c.mu, c.mu2
            ));
        }
    }
    for (i, law) in problem.laws.iter().enumerate() {
        match *law {
            RowLaw::Friction { contact } => {
                let owner = problem.contacts.get(contact).map(|c| c.normal);
                if !owner.is_some_and(|normal| i == normal + 1 || i == normal + 2) {
                    return Err(format!("row {i}: friction row of contact {contact}, which has no such row"));
                }
            }
            RowLaw::Bounded { lo, hi } => {
                if lo.is_nan() || hi.is_nan() || lo > hi || lo == f64::INFINITY || hi == f64::NEG_INFINITY {
                    return Err(format!("row {i}: bounds [{lo}, {hi}] are not an interval"));
                }
            }
            RowLaw::Bilateral | RowLaw::Unilateral => {}
        }
    }
    Ok(())
}

fn to_file(problem: &ConstraintProblem) -> ProblemFile {
    let bound = |x: f64| x.is_finite().then_some(x);
    let has_jacobian = problem.jacobian.ncols() > 0;
    ProblemFile {
        format: PROBLEM_FORMAT.to_string(),
        version: FORMAT_VERSION,
        rows: problem.rows(),
        nv: problem.jacobian.ncols(),
        friction: match problem.friction {
            FrictionModel::Cone => FrictionFile::Cone,
            FrictionModel::Pyramid { facets } => FrictionFile::Pyramid { facets },
        },
        laws: problem
            .laws
            .iter()
            .map(|law| match *law {
                RowLaw::Bilateral => LawFile::Bilateral,
                RowLaw::Unilateral => LawFile::Unilateral,
                RowLaw::Bounded { lo, hi } => LawFile::Bounded { lo: bound(lo), hi: bound(hi) },
                RowLaw::Friction { contact } => LawFile::Friction { contact },
            })
            .collect(),
        contacts: problem
            .contacts
            .iter()
            .map(|c| ContactFile { normal: c.normal, mu: c.mu, mu2: c.mu2 })
            .collect(),
        origins: Some(
            problem
                .origins
                .iter()
                .map(|o| match *o {
                    RowOrigin::Contact(i) => OriginFile::Contact(i),
                    RowOrigin::LowerLimit(i) => OriginFile::LowerLimit(i),
                    RowOrigin::UpperLimit(i) => OriginFile::UpperLimit(i),
                    RowOrigin::SwingLimit(i) => OriginFile::SwingLimit(i),
                    RowOrigin::TwistLowerLimit(i) => OriginFile::TwistLowerLimit(i),
                    RowOrigin::TwistUpperLimit(i) => OriginFile::TwistUpperLimit(i),
                    RowOrigin::Motor(i) => OriginFile::Motor(i),
                    RowOrigin::JointFriction(i) => OriginFile::JointFriction(i),
                    RowOrigin::Loop(i) => OriginFile::Loop(i),
                    RowOrigin::Other => OriginFile::Other,
                })
                .collect(),
        ),
        bias: problem.bias.iter().copied().collect(),
        regularization: problem.regularization.iter().copied().collect(),
        target: Some(problem.target.iter().copied().collect()),
        delassus: matrix_rows(&problem.delassus_dense()),
        jacobian: has_jacobian.then(|| matrix_rows(&problem.jacobian)),
        minv_jt: has_jacobian.then(|| matrix_rows(&problem.minv_jt)),
    }
}

fn from_file(file: ProblemFile) -> Result<ConstraintProblem, String> {
    if file.format != PROBLEM_FORMAT {
        return Err(format!("format is \"{}\", expected \"{PROBLEM_FORMAT}\"", file.format));
    }
    if file.version == 0 || file.version > FORMAT_VERSION {
        return Err(format!(
            "format version {} is not supported (this gelenk reads {FORMAT_VERSION})",
            file.version
        ));
    }
    let n = file.rows;
    if file.laws.len() != n {
        return Err(format!("\"laws\" has {} entries, the problem has {n} rows", file.laws.len()));
    }
    let (jacobian, minv_jt) = match (&file.jacobian, &file.minv_jt) {
        (Some(j), Some(m)) => {
            (matrix_from_rows(j, n, file.nv, "jacobian")?, matrix_from_rows(m, file.nv, n, "minv_jt")?)
        }
        (None, None) => (DMatrix::zeros(n, 0), DMatrix::zeros(0, n)),
        _ => return Err("\"jacobian\" and \"minv_jt\" must be given together".into()),
    };
    let problem = ConstraintProblem {
        sparsity: Default::default(),
        scratch: Default::default(),
        lanes: Default::default(),
        pattern: Default::default(),
        stretches: Default::default(),
        kept_lambda: Default::default(),
        kept_sum: Default::default(),
        jacobian,
        minv_jt,
        delassus: matrix_from_rows(&file.delassus, n, n, "delassus")?,
        regularization: vector(&file.regularization, n, "regularization")?,
        bias: vector(&file.bias, n, "bias")?,
        target: match &file.target {
            Some(t) => vector(t, n, "target")?,
            None => DVector::zeros(n),
        },
        laws: file
            .laws
            .iter()
            .map(|law| match *law {
                LawFile::Bilateral => RowLaw::Bilateral,
                LawFile::Unilateral => RowLaw::Unilateral,
                LawFile::Bounded { lo, hi } => {
                    RowLaw::Bounded { lo: lo.unwrap_or(f64::NEG_INFINITY), hi: hi.unwrap_or(f64::INFINITY) }
                }
                LawFile::Friction { contact } => RowLaw::Friction { contact },
            })
            .collect(),
        contacts: file
            .contacts
            .iter()
            .map(|c| ContactBlock { normal: c.normal, mu: c.mu, mu2: c.mu2 })
            .collect(),
        friction: match file.friction {
            FrictionFile::Cone => FrictionModel::Cone,
            FrictionFile::Pyramid { facets } => FrictionModel::Pyramid { facets },
        },
        origins: match &file.origins {
            None => vec![RowOrigin::Other; n],
            Some(origins) => origins
                .iter()
                .map(|o| match *o {
                    OriginFile::Contact(i) => RowOrigin::Contact(i),
                    OriginFile::LowerLimit(i) => RowOrigin::LowerLimit(i),
                    OriginFile::UpperLimit(i) => RowOrigin::UpperLimit(i),
                    OriginFile::SwingLimit(i) => RowOrigin::SwingLimit(i),
                    OriginFile::TwistLowerLimit(i) => RowOrigin::TwistLowerLimit(i),
                    OriginFile::TwistUpperLimit(i) => RowOrigin::TwistUpperLimit(i),
                    OriginFile::Motor(i) => RowOrigin::Motor(i),
                    OriginFile::JointFriction(i) => RowOrigin::JointFriction(i),
                    OriginFile::Loop(i) => RowOrigin::Loop(i),
                    OriginFile::Other => RowOrigin::Other,
                })
                .collect(),
        },
    };
    validate_problem(&problem)?;
    Ok(problem)
}

/// `problem.json`'s text for `problem` (compact JSON), after [`validate_problem`].
pub fn problem_to_json(problem: &ConstraintProblem) -> Result<String, String> {
    validate_problem(problem)?;
    serde_json::to_string(&to_file(problem)).map_err(|e| e.to_string())
}

/// The problem in `problem.json`'s text `text`; `path` only names the source in errors.
pub fn problem_from_json(text: &str, path: &Path) -> Result<ConstraintProblem, ProblemFileError> {
    let file: ProblemFile = serde_json::from_str(text).map_err(|source| ProblemFileError::Parse {
        path: path.to_path_buf(),
        what: "problem file",
        source,
    })?;
    from_file(file).map_err(|reason| ProblemFileError::Invalid { path: path.to_path_buf(), reason })
}

/// The file `name` in `path` if `path` is a directory, else `path` itself.
fn resolve(path: &Path, name: &str) -> PathBuf {
    if path.is_dir() {
        path.join(name)
    } else {
        path.to_path_buf()
    }
}

fn read_text(path: &Path) -> Result<String, ProblemFileError> {
    std::fs::read_to_string(path)
        .map_err(|source| ProblemFileError::Read { path: path.to_path_buf(), source })
}

/// Reads a problem from `path`: a `problem.json` file or a directory holding one.
pub fn read_problem(path: &Path) -> Result<ConstraintProblem, ProblemFileError> {
    let file = resolve(path, PROBLEM_FILE);
    problem_from_json(&read_text(&file)?, &file)
}

/// Reads the metadata beside a problem: `path` is a problem directory, its `problem.json` or
/// the `meta.json` itself.
pub fn read_meta(path: &Path) -> Result<ProblemMeta, ProblemFileError> {
    let file = if path.is_dir() {
        path.join(META_FILE)
    } else if path.file_name().is_some_and(|n| n == META_FILE) {
        path.to_path_buf()
    } else {
        path.with_file_name(META_FILE)
    };
    let meta: ProblemMeta = serde_json::from_str(&read_text(&file)?).map_err(|source| {
        ProblemFileError::Parse { path: file.clone(), what: "problem metadata file", source }
    })?;
    if meta.format != META_FORMAT || meta.version == 0 || meta.version > FORMAT_VERSION {
        return Err(ProblemFileError::Invalid {
            path: file,
            reason: format!(
                "format \"{}\" version {} is not {META_FORMAT} {FORMAT_VERSION}",
                meta.format, meta.version
            ),
        });
    }
    Ok(meta)
}

// ---------------------------------------------------------------------------------------------
// cone.json (clarabel's schema)

/// The settings [`ClarabelSolver`] hands to clarabel (as its `solve` builds them), with
/// clarabel's `save_to_file` sanitising: an infinite time limit is written as `f64::MAX`.
pub fn clarabel_settings(solver: &ClarabelSolver) -> DefaultSettings<f64> {
    DefaultSettings {
        verbose: false,
        max_iter: solver.max_iterations,
        tol_gap_abs: solver.tolerance,
        tol_gap_rel: solver.tolerance,
        tol_feas: solver.tolerance,
        tol_ktratio: 1e-8,
        time_limit: f64::MAX,
        ..DefaultSettings::default()
    }
}

#[derive(Serialize)]
struct ConeFile<'a> {
    #[serde(rename = "P")]
    p: &'a CscMatrix<f64>,
    q: &'a [f64],
    #[serde(rename = "A")]
    a: &'a CscMatrix<f64>,
    b: &'a [f64],
    cones: &'a [SupportedConeT<f64>],
    settings: DefaultSettings<f64>,
}

/// `cone.json`'s text: the cone program of `problem` in the JSON schema of clarabel's
/// `save_to_file` (readable by `DefaultSolver::load_from_file`), with [`clarabel_settings`].
pub fn cone_json(problem: &ConstraintProblem) -> Result<String, String> {
    let program = cone_program(problem);
    let file = ConeFile {
        p: &program.p,
        q: &program.q,
        a: &program.a,
        b: &program.b,
        cones: &program.cones,
        settings: clarabel_settings(&ClarabelSolver::default()),
    };
    serde_json::to_string(&file).map_err(|e| e.to_string())
}

// ---------------------------------------------------------------------------------------------
// QP form

/// A QP in qpsolvers' form: `min ½xᵀPx + qᵀx  s.t.  Gx ≤ h, Ax = b, lb ≤ x ≤ ub`, x = λ.
#[derive(Clone, Debug, PartialEq)]
pub struct QpForm {
    /// P = A + R (full, symmetric).
    pub p: DMatrix<f64>,
    /// q = b of the problem.
    pub q: DVector<f64>,
    /// Inequality rows (pyramid facets, one-sided friction boxes); may have 0 rows.
    pub g: DMatrix<f64>,
    /// Their right-hand side.
    pub h: DVector<f64>,
    /// Equality rows (λ_t = 0 of frictionless tangents); may have 0 rows.
    pub a: DMatrix<f64>,
    /// Their right-hand side.
    pub b: DVector<f64>,
    /// Lower bounds (−∞ where none).
    pub lb: DVector<f64>,
    /// Upper bounds (+∞ where none).
    pub ub: DVector<f64>,
}

/// The QP of `problem`'s cone program when it has no second-order cone (frictionless or pyramid
/// friction), else `None`. Rows with one entry become bounds, zero-cone rows equalities.
pub fn qp_of(problem: &ConstraintProblem) -> Option<QpForm> {
    let program = cone_program(problem);
    let n = problem.rows();
    let m = program.b.len();
    let mut dense = DMatrix::zeros(m, n);
    for j in 0..n {
        for k in program.a.colptr[j]..program.a.colptr[j + 1] {
            dense[(program.a.rowval[k], j)] += program.a.nzval[k];
        }
    }
    let (mut lb, mut ub) =
        (DVector::from_element(n, f64::NEG_INFINITY), DVector::from_element(n, f64::INFINITY));
    let (mut g_rows, mut a_rows): (Vec<usize>, Vec<usize>) = (Vec::new(), Vec::new());
    let mut row = 0;
    for cone in &program.cones {
        match *cone {
            SupportedConeT::ZeroConeT(d) => {
                a_rows.extend(row..row + d);
                row += d;
            }
            SupportedConeT::NonnegativeConeT(d) => {
                for r in row..row + d {
                    let entries: Vec<usize> = (0..n).filter(|&j| dense[(r, j)] != 0.0).collect();
                    // c x_j ≤ b_r is a bound b_r / c (+ 0.0 turns −0 into 0).
                    match entries[..] {
                        [j] if dense[(r, j)] > 0.0 => ub[j] = ub[j].min(program.b[r] / dense[(r, j)] + 0.0),
                        [j] => lb[j] = lb[j].max(program.b[r] / dense[(r, j)] + 0.0),
                        _ => g_rows.push(r),
                    }
                }
                row += d;
            }
            _ => return None,
        }
    }
    let select = |rows: &[usize]| {
        (
            DMatrix::from_fn(rows.len(), n, |i, j| dense[(rows[i], j)]),
            DVector::from_fn(rows.len(), |i, _| program.b[rows[i]]),
        )
    };
    let (g, h) = select(&g_rows);
    let (a, b) = select(&a_rows);
    let p = problem.delassus_dense().into_owned() + DMatrix::from_diagonal(&problem.regularization);
    Some(QpForm { p, q: problem.bias.clone(), g, h, a, b, lb, ub })
}

// ---------------------------------------------------------------------------------------------
// .npy / .npz

/// One `.npy` file (format 1.0, little-endian f64, C order) of an array of `shape` whose
/// elements, in C (row-major) order, are `data`.
pub fn npy_bytes(shape: &[usize], data: &[f64]) -> Vec<u8> {
    let dims = match shape {
        [d] => format!("({d},)"),
        _ => format!("({})", shape.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    };
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {dims}, }}");
    // Magic (6) + version (2) + length (2) + header, padded with spaces and ended by '\n' to a
    // multiple of 64 bytes.
    let total = (10 + header.len() + 1).div_ceil(64) * 64;
    header.extend(std::iter::repeat_n(' ', total - 10 - header.len() - 1));
    header.push('\n');
    let mut out = Vec::with_capacity(total + 8 * data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for x in data {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out
}

/// CRC-32 (IEEE 802.3, as zip uses).
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in bytes {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

/// A zip archive of stored (uncompressed) files `(name, content)`, as `numpy.savez` writes
/// `.npz` files. Sizes and offsets must fit zip's 32-bit fields.
pub fn stored_zip(files: &[(String, Vec<u8>)]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    let mut central = Vec::new();
    let u32_of =
        |x: usize, what: &str| u32::try_from(x).map_err(|_| format!("{what} too large for a zip archive"));
    for (name, content) in files {
        let crc = crc32(content);
        let size = u32_of(content.len(), name)?;
        let offset = u32_of(out.len(), "archive")?;
        let name_len = u16::try_from(name.len()).map_err(|_| format!("entry name {name} too long"))?;
        // Fields shared by the local and the central header: version needed 2.0, no flags,
        // stored, time 00:00, date 1980-01-01, CRC, sizes, name length, no extra field.
        let mut common = Vec::new();
        for x in [20u16, 0, 0, 0, 0x21] {
            common.extend_from_slice(&x.to_le_bytes());
        }
        for x in [crc, size, size] {
            common.extend_from_slice(&x.to_le_bytes());
        }
        common.extend_from_slice(&name_len.to_le_bytes());
        common.extend_from_slice(&0u16.to_le_bytes());
        out.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
        out.extend_from_slice(&common);
        out.extend_from_slice(name.as_bytes());
        out.extend_from_slice(content);
        central.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
        central.extend_from_slice(&20u16.to_le_bytes()); // made by: 2.0
        central.extend_from_slice(&common);
        for x in [0u16, 0, 0] {
            central.extend_from_slice(&x.to_le_bytes()); // comment length, disk, internal attributes
        }
        central.extend_from_slice(&0u32.to_le_bytes()); // external attributes
        central.extend_from_slice(&offset.to_le_bytes());
        central.extend_from_slice(name.as_bytes());
    }
    let count = u16::try_from(files.len()).map_err(|_| "too many zip entries".to_string())?;
    let (central_offset, central_size) = (u32_of(out.len(), "archive")?, u32_of(central.len(), "directory")?);
    out.extend_from_slice(&central);
    out.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
    for x in [0u16, 0, count, count] {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out.extend_from_slice(&central_size.to_le_bytes());
    out.extend_from_slice(&central_offset.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    Ok(out)
}

/// An `.npz` archive of dense arrays `(name, shape, C-order data)` (entries `NAME.npy`).
pub fn npz_bytes(arrays: &[(&str, Vec<usize>, Vec<f64>)]) -> Result<Vec<u8>, String> {
    let files: Vec<(String, Vec<u8>)> =
        arrays.iter().map(|(name, shape, data)| (format!("{name}.npy"), npy_bytes(shape, data))).collect();
    stored_zip(&files)
}

fn matrix_entry<'a>(name: &'a str, m: &DMatrix<f64>) -> (&'a str, Vec<usize>, Vec<f64>) {
    (name, vec![m.nrows(), m.ncols()], m.transpose().as_slice().to_vec())
}

fn vector_entry<'a>(name: &'a str, v: &DVector<f64>) -> (&'a str, Vec<usize>, Vec<f64>) {
    (name, vec![v.len()], v.as_slice().to_vec())
}

/// Friction directions of the LCP written for `problem` (the problem's own pyramid, else
/// [`LemkeSolver`]'s default).
pub fn lcp_facets(problem: &ConstraintProblem) -> usize {
    match problem.friction {
        FrictionModel::Pyramid { facets } => facets,
        FrictionModel::Cone => LemkeSolver::default().facets,
    }
}

/// `lcp.npz`'s bytes: `M`, `q`, `C`, `c0` of [`lcp_of`] with [`lcp_facets`] directions.
pub fn lcp_npz(problem: &ConstraintProblem) -> Result<Vec<u8>, String> {
    let lcp = lcp_of(problem, lcp_facets(problem));
    npz_bytes(&[
        matrix_entry("M", &lcp.m),
        vector_entry("q", &lcp.q),
        matrix_entry("C", &lcp.c),
        vector_entry("c0", &lcp.c0),
    ])
}

/// `qp.npz`'s bytes (`P`, `q`, `G`, `h`, `A`, `b`, `lb`, `ub`), or `None` when the problem has a
/// second-order cone.
pub fn qp_npz(problem: &ConstraintProblem) -> Option<Result<Vec<u8>, String>> {
    let qp = qp_of(problem)?;
    Some(npz_bytes(&[
        matrix_entry("P", &qp.p),
        vector_entry("q", &qp.q),
        matrix_entry("G", &qp.g),
        vector_entry("h", &qp.h),
        matrix_entry("A", &qp.a),
        vector_entry("b", &qp.b),
        vector_entry("lb", &qp.lb),
        vector_entry("ub", &qp.ub),
    ]))
}

// ---------------------------------------------------------------------------------------------
// Solving and metadata

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
    let mut solver = kind.solver();
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
    /// Friction model (`cone` or `pyramid:K`).
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

/// Writes `problem` and `meta` into directory `dir` (created if needed): `problem.json`,
/// `cone.json`, `lcp.npz`, `qp.npz` (when the problem has no second-order cone; a stale one is
/// removed otherwise) and `meta.json`.
pub fn write_problem(
    dir: &Path,
    problem: &ConstraintProblem,
    meta: &ProblemMeta,
) -> Result<(), ProblemFileError> {
    let invalid = |name: &str, reason: String| ProblemFileError::Invalid { path: dir.join(name), reason };
    let problem_text = problem_to_json(problem).map_err(|r| invalid(PROBLEM_FILE, r))?;
    let cone_text = cone_json(problem).map_err(|r| invalid(CONE_FILE, r))?;
    let lcp = lcp_npz(problem).map_err(|r| invalid(LCP_FILE, r))?;
    let qp = qp_npz(problem).transpose().map_err(|r| invalid(QP_FILE, r))?;
    let meta_text = serde_json::to_string_pretty(meta).map_err(|e| invalid(META_FILE, e.to_string()))?;
    std::fs::create_dir_all(dir)
        .map_err(|source| ProblemFileError::Write { path: dir.to_path_buf(), source })?;
    let write = |name: &str, bytes: &[u8]| {
        let path = dir.join(name);
        std::fs::write(&path, bytes).map_err(|source| ProblemFileError::Write { path, source })
    };
    write(PROBLEM_FILE, problem_text.as_bytes())?;
    write(CONE_FILE, cone_text.as_bytes())?;
    write(LCP_FILE, &lcp)?;
    match qp {
        Some(bytes) => write(QP_FILE, &bytes)?,
        None => {
            let stale = dir.join(QP_FILE);
            if stale.exists() {
                std::fs::remove_file(&stale)
                    .map_err(|source| ProblemFileError::Write { path: stale, source })?;
            }
        }
    }
    write(META_FILE, format!("{meta_text}\n").as_bytes())
}
