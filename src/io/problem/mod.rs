//! Constraint problems as files: for solver regression tests, and for running other solvers on
//! gelenk's problems.
//!
//! [`write_problem`] writes one [`ConstraintProblem`] into a directory:
//!
//! | file | content |
//! |---|---|
//! | `problem.json` | gelenk's own form, enough to rebuild the exact problem ([`read_problem`]): `A`, `b`, `R`, target velocities, row laws, contact blocks (normal row, μ, μ₂), friction model, row origins and, when known, `J` and `M⁻¹Jᵀ` |
//! | `cone.json` | the cone program of [`cone_program`](crate::solvers::cone_program) in the schema clarabel's `save_to_file` writes (`P`, `q`, `A`, `b`, `cones`, `settings`): `DefaultSolver::load_from_file` reads it |
//! | `lcp.npz` | the LCP of [`lcp_of`](crate::solvers::lcp_of) that Lemke's method solves: `M`, `q`, and the map back to impulses `λ = C z + c0` |
//! | `qp.npz` | when the cone program has no second-order cone (frictionless or pyramid friction): the QP in qpsolvers' form `min ½xᵀPx + qᵀx, Gx ≤ h, Ax = b, lb ≤ x ≤ ub`, every matrix dense; rows that bound one variable go to `lb`/`ub`, zero-cone rows to `A`, the others (pyramid facets) to `G` |
//! | `meta.json` | [`ProblemMeta`]: scene, step, formulation, each solver's status, solution, objective and residuals (clarabel's is the reference), and the tolerances a re-solve must meet |
//!
//! `problem.json` stores matrices as arrays of rows and an unbounded box side as `null`
//! (`lo = −∞`, `hi = +∞`); numbers are written in the shortest form that reads back to the same
//! `f64`, so write → read gives the identical problem. The `.npy` entries of the `.npz` files are
//! format 1.0, `<f8`, C order; the archives are stored (uncompressed) zip files that
//! `numpy.load` reads.
//!
//! One private module per file kind: `json` (problem.json), `cone` (cone.json and the QP form),
//! `npz` (lcp.npz, qp.npz), `corpus` (re-solving and meta.json); `resolve` judges a re-solved
//! problem against its meta.json, and `export` writes the problems of a scene's steps.
//!
//! The standard formats of the corpus (`gelenk corpus build`, docs/corpus.md), each read back to
//! the last bit: `cbf` (CBLIB's Conic Benchmark Format: the cone program, its quadratic as a
//! rotated cone over the pivoted Cholesky factor of `factor`), `qps` (Maros–Meszaros QPS of the
//! QP form) and, with the `fclib` feature, `fclib` (FCLIB's local HDF5 problem W, q, μ).

mod cbf;
mod cone;
mod corpus;
mod corpus_bench;
mod corpus_build;
mod corpus_scenes;
mod export;
mod factor;
#[cfg(feature = "fclib")]
mod fclib;
#[cfg(feature = "fclib")]
mod fclib_read;
mod json;
mod npz;
mod qps;
mod resolve;

pub use cbf::{
    cbf_of, cbf_text, parse_cbf, read_cbf, solve_cbf_with_clarabel, write_cbf, CbfCone, CbfFile, CBF_MAX_ROWS,
};
pub use cone::{clarabel_settings, cone_json, qp_of, QpForm};
pub use corpus::{
    formulation, is_frictionless, objective, run_configured_solver, run_solver, CorpusSolver, ProblemMeta,
    ResidualRecord, SolveStatus, SolverRecord,
};
pub use corpus_bench::{
    bench_csv, bench_run, bench_table, bench_text, runs_csv, BenchOptions, BenchRow, BenchRun, BenchSolver,
    LEVELS, TIME_SHIFT,
};
pub use corpus_build::{
    build_corpus, degenerate_rows, index_csv, read_index, reference_solution, BuildOptions, BuildSummary,
    IndexEntry, Reference, CLARABEL_REFERENCE_ROWS, CONDITIONING_ROWS, INDEX_FILE, REFERENCE_FILE,
    REFERENCE_FORMAT, REFERENCE_TOLERANCE,
};
pub use corpus_scenes::{corpus_scenes, corpus_world, CorpusScene, CorpusWorld, SceneSource};
pub use export::{export_problems, ExportError, ExportKind, ExportOptions, ExportedProblem};
pub use factor::{pivoted_cholesky, qp_matrix, PivotedCholesky};
#[cfg(feature = "fclib")]
pub use fclib::{fclib_of, write_fclib, FclibLocal};
#[cfg(feature = "fclib")]
pub use fclib_read::{read_fclib, FCLIB_MAX_ENTRIES, FCLIB_MAX_FILE_BYTES};
pub use json::{problem_from_json, problem_to_json, problem_to_json_sparse, validate_problem};
pub use npz::{lcp_facets, lcp_npz, npy_bytes, npz_bytes, qp_npz, stored_zip};
pub use qps::{parse_qps, qps_text, read_qps, write_qps};
pub use resolve::{resolve_problem, Regression, Resolved};

use crate::constraints::ConstraintProblem;
use std::path::{Path, PathBuf};
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

/// The file `name` in `path` if `path` is a directory, else `path` itself.
fn resolve(path: &Path, name: &str) -> PathBuf {
    if path.is_dir() {
        path.join(name)
    } else {
        path.to_path_buf()
    }
}

fn read_text(path: &Path) -> Result<String, ProblemFileError> {
    crate::io::limits::ReadLimits::default()
        .read_text_io(path)
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
