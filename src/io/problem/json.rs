//! `problem.json`: gelenk's own form of a [`ConstraintProblem`], enough to rebuild the exact
//! problem, and the consistency check every problem read passes.

use super::{ProblemFileError, FORMAT_VERSION, PROBLEM_FORMAT};
use crate::constraints::{ConstraintProblem, ContactBlock, FrictionModel, RowLaw, RowOrigin};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::path::Path;

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
    AngleLimit(usize),
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
    /// A dense, as rows; absent when `delassus_entries` holds it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    delassus: Option<Vec<Vec<f64>>>,
    /// A sparse: `[i, j, A_ij]` for every entry that is not +0.0 (the corpus's large problems).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    delassus_entries: Option<Vec<(usize, usize, f64)>>,
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

/// Largest magnitude of a problem's numbers (A, b, R, targets, J, M⁻¹Jᵀ).
pub(crate) const MAX_MAGNITUDE: f64 = 1e100;

/// Checks that `problem` is consistent: sizes, finite numbers, laws and contact blocks agreeing
/// (what every solver and [`residuals()`](crate::solvers::residuals()) rely on).
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
        // Products of two such numbers overflow: the solvers' sums would be infinite.
        if x.iter().any(|v| v.abs() > MAX_MAGNITUDE) {
            return Err(format!("{name} holds a number beyond ±{MAX_MAGNITUDE:e}"));
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

fn to_file(problem: &ConstraintProblem, sparse: bool) -> ProblemFile {
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
                    RowOrigin::AngleLimit(i) => OriginFile::AngleLimit(i),
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
        delassus: (!sparse).then(|| matrix_rows(&problem.delassus_dense())),
        delassus_entries: sparse.then(|| {
            let a = problem.delassus_dense();
            let n = a.nrows();
            (0..n)
                .flat_map(|i| (0..n).map(move |j| (i, j)))
                .filter(|&(i, j)| a[(i, j)].to_bits() != 0)
                .map(|(i, j)| (i, j, a[(i, j)]))
                .collect()
        }),
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
        delassus: match (&file.delassus, &file.delassus_entries) {
            (Some(rows), None) => matrix_from_rows(rows, n, n, "delassus")?,
            (None, Some(entries)) => {
                let mut a = DMatrix::zeros(n, n);
                let mut seen = std::collections::HashSet::with_capacity(entries.len());
                for &(i, j, x) in entries {
                    if i >= n || j >= n {
                        return Err(format!("\"delassus_entries\": entry ({i}, {j}) outside {n}×{n}"));
                    }
                    if !seen.insert((i, j)) {
                        return Err(format!("\"delassus_entries\": entry ({i}, {j}) given twice"));
                    }
                    a[(i, j)] = x;
                }
                a
            }
            _ => return Err("exactly one of \"delassus\" and \"delassus_entries\" must be given".into()),
        },
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
                    OriginFile::AngleLimit(i) => RowOrigin::AngleLimit(i),
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
    serde_json::to_string(&to_file(problem, false)).map_err(|e| e.to_string())
}

/// `problem.json`'s text for `problem` with A stored sparse (`delassus_entries`: every entry
/// whose bits are not +0.0, so −0.0 survives), after [`validate_problem`]; [`problem_from_json`]
/// reads both forms.
pub fn problem_to_json_sparse(problem: &ConstraintProblem) -> Result<String, String> {
    validate_problem(problem)?;
    serde_json::to_string(&to_file(problem, true)).map_err(|e| e.to_string())
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
