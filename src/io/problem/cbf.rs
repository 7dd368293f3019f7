//! CBF, CBLIB's Conic Benchmark Format (version 3, text): the convex cone program of a problem
//! (the Anitescu relaxation that clarabel solves), for conic solvers.
//!
//! CBF has a linear objective and conic constraints `Ax + b ∈ K` only, so the quadratic
//! `½λᵀPλ` (P = A + R) becomes an epigraph variable t with the rotated cone
//! `(t, 1, Fᵀλ) ∈ QR` (`2 t ≥ ‖Fᵀλ‖²`), where `P = F Fᵀ` is the pivoted Cholesky factor of
//! [`super::factor`]; the file is then `min t + bᵀλ` subject to the cone program's constraints
//! `b_c − A_c λ ∈ K` of [`cone_program`] written as `−A_c λ + b_c ∈ K`. Variables: λ (n, in
//! row order), then t. Numbers are written in Rust's shortest round-trip form, so reading a
//! file gives back exactly the numbers written ([`CbfFile`] round-trips to the last bit).

use super::factor::{pivoted_cholesky, qp_matrix};
use super::ProblemFileError;
use crate::constraints::ConstraintProblem;
use crate::solvers::cone_program;
use clarabel::solver::SupportedConeT;
use std::fmt::Write as _;
use std::path::Path;

/// Rows above which [`cbf_of`] refuses a problem: the factor F is dense (n × rank entries).
pub const CBF_MAX_ROWS: usize = 1000;

/// A CBF domain (cone) of a block of variables or constraint rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CbfCone {
    /// `F`: free.
    Free,
    /// `L+`: nonnegative.
    Nonnegative,
    /// `L-`: nonpositive.
    Nonpositive,
    /// `L=`: zero.
    Zero,
    /// `Q`: second-order cone, `x₁ ≥ ‖x₂..‖`.
    Quadratic,
    /// `QR`: rotated second-order cone, `2 x₁ x₂ ≥ ‖x₃..‖²`, `x₁, x₂ ≥ 0`.
    RotatedQuadratic,
}

impl CbfCone {
    /// Its CBF name.
    pub fn name(self) -> &'static str {
        match self {
            CbfCone::Free => "F",
            CbfCone::Nonnegative => "L+",
            CbfCone::Nonpositive => "L-",
            CbfCone::Zero => "L=",
            CbfCone::Quadratic => "Q",
            CbfCone::RotatedQuadratic => "QR",
        }
    }

    fn parse(name: &str) -> Option<CbfCone> {
        [
            CbfCone::Free,
            CbfCone::Nonnegative,
            CbfCone::Nonpositive,
            CbfCone::Zero,
            CbfCone::Quadratic,
            CbfCone::RotatedQuadratic,
        ]
        .into_iter()
        .find(|c| c.name() == name)
    }
}

/// A CBF file's content (the subset without integer or semidefinite parts): minimize
/// `Σ objective·x + objective_constant` subject to `Σ_j a_ij x_j + b_i ∈ cones`, `x ∈ variables`.
#[derive(Clone, Debug, PartialEq)]
pub struct CbfFile {
    /// Whether the objective is minimized (`MIN`) rather than maximized (`MAX`).
    pub minimize: bool,
    /// Variable domains: (cone, length), in order; lengths add up to the variable count.
    pub variables: Vec<(CbfCone, usize)>,
    /// Constraint domains: (cone, length), in order.
    pub constraints: Vec<(CbfCone, usize)>,
    /// Objective coefficients `(j, c_j)` (`OBJACOORD`).
    pub objective: Vec<(usize, f64)>,
    /// Objective constant (`OBJBCOORD`; 0 when absent).
    pub objective_constant: f64,
    /// Constraint matrix entries `(i, j, a_ij)` (`ACOORD`).
    pub a: Vec<(usize, usize, f64)>,
    /// Constraint constants `(i, b_i)` (`BCOORD`).
    pub b: Vec<(usize, f64)>,
}

impl CbfFile {
    /// Variable count.
    pub fn variable_count(&self) -> usize {
        self.variables.iter().map(|v| v.1).sum()
    }

    /// Constraint row count.
    pub fn constraint_count(&self) -> usize {
        self.constraints.iter().map(|c| c.1).sum()
    }
}

fn cone_of(cone: &SupportedConeT<f64>) -> Result<(CbfCone, usize), String> {
    match *cone {
        SupportedConeT::ZeroConeT(d) => Ok((CbfCone::Zero, d)),
        SupportedConeT::NonnegativeConeT(d) => Ok((CbfCone::Nonnegative, d)),
        SupportedConeT::SecondOrderConeT(d) => Ok((CbfCone::Quadratic, d)),
        ref other => Err(format!("cone {other:?} has no CBF form here")),
    }
}

/// The CBF content of `problem`'s cone program (see the module documentation). Refuses problems
/// of more than [`CBF_MAX_ROWS`] rows.
pub fn cbf_of(problem: &ConstraintProblem) -> Result<CbfFile, String> {
    super::validate_problem(problem)?;
    let n = problem.rows();
    if n > CBF_MAX_ROWS {
        return Err(format!("{n} rows: CBF is written for at most {CBF_MAX_ROWS} rows (dense factor)"));
    }
    let program = cone_program(problem);
    let factor = pivoted_cholesky(&qp_matrix(problem)).factor;
    let t = n;
    let mut constraints = Vec::new();
    let mut a = Vec::new();
    let mut b = Vec::new();
    // The cone program's rows: −A_c λ + b_c ∈ K.
    for j in 0..n {
        for k in program.a.colptr[j]..program.a.colptr[j + 1] {
            let x = program.a.nzval[k];
            if x.to_bits() != 0 {
                a.push((program.a.rowval[k], j, -x));
            }
        }
    }
    a.sort_by_key(|&(i, j, _)| (i, j));
    for (i, &x) in program.b.iter().enumerate() {
        if x.to_bits() != 0 {
            b.push((i, x));
        }
    }
    for cone in &program.cones {
        constraints.push(cone_of(cone)?);
    }
    // The epigraph: (t, 1, Fᵀλ) ∈ QR.
    let m = program.b.len();
    constraints.push((CbfCone::RotatedQuadratic, 2 + factor.ncols()));
    a.push((m, t, 1.0));
    b.push((m + 1, 1.0));
    for c in 0..factor.ncols() {
        for j in 0..n {
            let x = factor[(j, c)];
            if x.to_bits() != 0 {
                a.push((m + 2 + c, j, x));
            }
        }
    }
    let mut objective: Vec<(usize, f64)> =
        problem.bias.iter().enumerate().filter(|(_, x)| x.to_bits() != 0).map(|(j, &x)| (j, x)).collect();
    objective.push((t, 1.0));
    Ok(CbfFile {
        minimize: true,
        variables: vec![(CbfCone::Free, n + 1)],
        constraints,
        objective,
        objective_constant: 0.0,
        a,
        b,
    })
}

/// The text of `file` in CBF version 3.
pub fn cbf_text(file: &CbfFile) -> String {
    let mut s = String::new();
    let domains = |s: &mut String, total: usize, list: &[(CbfCone, usize)]| {
        let _ = writeln!(s, "{total} {}", list.len());
        for (cone, len) in list {
            let _ = writeln!(s, "{} {len}", cone.name());
        }
        s.push('\n');
    };
    s.push_str("# gelenk constraint problem: the convex cone program (CBF, CBLIB)\nVER\n3\n\n");
    s.push_str(if file.minimize { "OBJSENSE\nMIN\n\n" } else { "OBJSENSE\nMAX\n\n" });
    s.push_str("VAR\n");
    domains(&mut s, file.variable_count(), &file.variables);
    s.push_str("CON\n");
    domains(&mut s, file.constraint_count(), &file.constraints);
    if !file.objective.is_empty() {
        let _ = writeln!(s, "OBJACOORD\n{}", file.objective.len());
        for (j, x) in &file.objective {
            let _ = writeln!(s, "{j} {x:e}");
        }
        s.push('\n');
    }
    if file.objective_constant.to_bits() != 0 {
        let _ = writeln!(s, "OBJBCOORD\n{:e}\n", file.objective_constant);
    }
    if !file.a.is_empty() {
        let _ = writeln!(s, "ACOORD\n{}", file.a.len());
        for (i, j, x) in &file.a {
            let _ = writeln!(s, "{i} {j} {x:e}");
        }
        s.push('\n');
    }
    if !file.b.is_empty() {
        let _ = writeln!(s, "BCOORD\n{}", file.b.len());
        for (i, x) in &file.b {
            let _ = writeln!(s, "{i} {x:e}");
        }
        s.push('\n');
    }
    s
}

/// Line-by-line reader that names the line of every error.
struct Lines<'a> {
    lines: std::iter::Peekable<std::iter::Enumerate<std::str::Lines<'a>>>,
    line: usize,
}

impl<'a> Lines<'a> {
    /// The next line that is neither blank nor a comment.
    fn next(&mut self) -> Option<&'a str> {
        for (k, line) in self.lines.by_ref() {
            let t = line.trim();
            if !t.is_empty() && !t.starts_with('#') {
                self.line = k + 1;
                return Some(t);
            }
        }
        None
    }

    fn need(&mut self, what: &str) -> Result<&'a str, String> {
        self.next().ok_or_else(|| format!("the file ends inside {what}"))
    }

    fn fields<const N: usize>(&mut self, what: &str) -> Result<[&'a str; N], String> {
        let line = self.need(what)?;
        let fields: Vec<&str> = line.split_whitespace().collect();
        <[&str; N]>::try_from(fields.as_slice())
            .map_err(|_| format!("line {}: {what} needs {N} fields, got \"{line}\"", self.line))
    }

    fn int(&self, x: &str, what: &str) -> Result<usize, String> {
        x.parse().map_err(|_| format!("line {}: {what}: \"{x}\" is not a count or index", self.line))
    }

    fn real(&self, x: &str, what: &str) -> Result<f64, String> {
        match x.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(format!("line {}: {what}: \"{x}\" is not a finite number", self.line)),
        }
    }
}

/// A `VAR` or `CON` section: total, cone count, then one `NAME LENGTH` line per cone. Entries
/// are read one by one, so a corrupt count reserves no memory.
fn domains(lines: &mut Lines<'_>, what: &str) -> Result<Vec<(CbfCone, usize)>, String> {
    let [total, count] = lines.fields::<2>(what)?;
    let (total, count) = (lines.int(total, what)?, lines.int(count, what)?);
    let mut list = Vec::new();
    for _ in 0..count {
        let [name, len] = lines.fields::<2>(what)?;
        let cone = CbfCone::parse(name)
            .ok_or_else(|| format!("line {}: {what}: unknown cone \"{name}\"", lines.line))?;
        list.push((cone, lines.int(len, what)?));
    }
    let sum: usize = list.iter().map(|c| c.1).sum();
    if sum != total {
        return Err(format!("{what}: the cones hold {sum} entries, the header says {total}"));
    }
    Ok(list)
}

fn parse(text: &str) -> Result<CbfFile, String> {
    let mut lines = Lines { lines: text.lines().enumerate().peekable(), line: 0 };
    let mut file = CbfFile {
        minimize: true,
        variables: Vec::new(),
        constraints: Vec::new(),
        objective: Vec::new(),
        objective_constant: 0.0,
        a: Vec::new(),
        b: Vec::new(),
    };
    let (mut version, mut seen_var, mut seen_con) = (None, false, false);
    // Each section at most once (CBF's rule): a second CON after ACOORD would leave entries
    // outside the rows they were checked against.
    let mut seen: Vec<&str> = Vec::new();
    while let Some(keyword) = lines.next() {
        if seen.contains(&keyword) {
            return Err(format!("line {}: a second {keyword} section", lines.line));
        }
        seen.push(keyword);
        match keyword {
            "VER" => {
                let v = lines.need("VER")?;
                version = Some(lines.int(v, "VER")?);
                if !matches!(version, Some(1..=3)) {
                    return Err(format!("line {}: CBF version {v} is not 1, 2 or 3", lines.line));
                }
            }
            "OBJSENSE" => {
                file.minimize = match lines.need("OBJSENSE")? {
                    "MIN" => true,
                    "MAX" => false,
                    other => return Err(format!("line {}: OBJSENSE \"{other}\" is not MIN or MAX", lines.line)),
                }
            }
            "VAR" => {
                file.variables = domains(&mut lines, "VAR")?;
                seen_var = true;
            }
            "CON" => {
                file.constraints = domains(&mut lines, "CON")?;
                seen_con = true;
            }
            "OBJACOORD" | "OBJBCOORD" | "ACOORD" | "BCOORD" if !(seen_var && seen_con) => {
                return Err(format!("line {}: {keyword} before VAR and CON", lines.line));
            }
            "OBJACOORD" => {
                let count = lines.need("OBJACOORD").and_then(|c| lines.int(c, "OBJACOORD"))?;
                let n = file.variable_count();
                for _ in 0..count {
                    let [j, x] = lines.fields::<2>("OBJACOORD")?;
                    let j = lines.int(j, "OBJACOORD")?;
                    if j >= n {
                        return Err(format!("line {}: OBJACOORD: variable {j} of {n}", lines.line));
                    }
                    file.objective.push((j, lines.real(x, "OBJACOORD")?));
                }
            }
            "OBJBCOORD" => {
                let x = lines.need("OBJBCOORD")?;
                file.objective_constant = lines.real(x, "OBJBCOORD")?;
            }
            "ACOORD" => {
                let count = lines.need("ACOORD").and_then(|c| lines.int(c, "ACOORD"))?;
                let (m, n) = (file.constraint_count(), file.variable_count());
                for _ in 0..count {
                    let [i, j, x] = lines.fields::<3>("ACOORD")?;
                    let (i, j) = (lines.int(i, "ACOORD")?, lines.int(j, "ACOORD")?);
                    if i >= m || j >= n {
                        return Err(format!("line {}: ACOORD: entry ({i}, {j}) outside {m} × {n}", lines.line));
                    }
                    file.a.push((i, j, lines.real(x, "ACOORD")?));
                }
            }
            "BCOORD" => {
                let count = lines.need("BCOORD").and_then(|c| lines.int(c, "BCOORD"))?;
                let m = file.constraint_count();
                for _ in 0..count {
                    let [i, x] = lines.fields::<2>("BCOORD")?;
                    let i = lines.int(i, "BCOORD")?;
                    if i >= m {
                        return Err(format!("line {}: BCOORD: row {i} of {m}", lines.line));
                    }
                    file.b.push((i, lines.real(x, "BCOORD")?));
                }
            }
            other => {
                return Err(format!(
                    "line {}: keyword \"{other}\" is not read here (integer and semidefinite parts are not supported)",
                    lines.line
                ))
            }
        }
    }
    if version.is_none() {
        return Err("no VER section: not a CBF file".into());
    }
    if !seen_var {
        return Err("no VAR section".into());
    }
    Ok(file)
}

/// Parses CBF text; `path` only names the source in errors.
pub fn parse_cbf(text: &str, path: &Path) -> Result<CbfFile, ProblemFileError> {
    parse(text).map_err(|reason| ProblemFileError::Invalid { path: path.to_path_buf(), reason })
}

/// Reads a CBF file.
pub fn read_cbf(path: &Path) -> Result<CbfFile, ProblemFileError> {
    parse_cbf(&super::read_text(path)?, path)
}

/// Writes `problem`'s CBF file at `path`.
pub fn write_cbf(path: &Path, problem: &ConstraintProblem) -> Result<(), ProblemFileError> {
    let file =
        cbf_of(problem).map_err(|reason| ProblemFileError::Invalid { path: path.to_path_buf(), reason })?;
    std::fs::write(path, cbf_text(&file))
        .map_err(|source| ProblemFileError::Write { path: path.to_path_buf(), source })
}

/// Solves the cone program of a CBF file with clarabel (the variables must be free; `Q` and `QR`
/// constraint rows become clarabel second-order cones, `QR` through
/// `((x₁+x₂)/√2, (x₁−x₂)/√2, x₃..)`): the optimal objective (with the file's sense) and x.
/// The check that a CBF file poses the problem it came from.
pub fn solve_cbf_with_clarabel(file: &CbfFile) -> Result<(f64, Vec<f64>), String> {
    use clarabel::algebra::CscMatrix;
    use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus};
    if file.variables.iter().any(|v| v.0 != CbfCone::Free) {
        return Err("only free variables are supported".into());
    }
    let (n, m) = (file.variable_count(), file.constraint_count());
    let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); m];
    for &(i, j, x) in &file.a {
        rows[i].push((j, x));
    }
    let mut constant = vec![0.0; m];
    for &(i, x) in &file.b {
        constant[i] += x;
    }
    // clarabel: A_c x + s = b_c, s ∈ K, with s = a x + b: A_c = −a, b_c = b.
    let (mut triplets, mut b_c, mut cones) = (Vec::new(), Vec::new(), Vec::new());
    let mut push_row = |entries: &[(usize, f64)], c: f64, triplets: &mut Vec<(usize, usize, f64)>| {
        let r = b_c.len();
        for &(j, x) in entries {
            triplets.push((r, j, -x));
        }
        b_c.push(c);
    };
    let mut start = 0;
    for &(cone, len) in &file.constraints {
        let block = start..start + len;
        match cone {
            CbfCone::Free => {}
            CbfCone::Zero => {
                block.clone().for_each(|i| push_row(&rows[i], constant[i], &mut triplets));
                cones.push(SupportedConeT::ZeroConeT(len));
            }
            CbfCone::Nonnegative | CbfCone::Nonpositive => {
                let sign = if cone == CbfCone::Nonnegative { 1.0 } else { -1.0 };
                for i in block.clone() {
                    let entries: Vec<(usize, f64)> = rows[i].iter().map(|&(j, x)| (j, sign * x)).collect();
                    push_row(&entries, sign * constant[i], &mut triplets);
                }
                cones.push(SupportedConeT::NonnegativeConeT(len));
            }
            CbfCone::Quadratic => {
                block.clone().for_each(|i| push_row(&rows[i], constant[i], &mut triplets));
                cones.push(SupportedConeT::SecondOrderConeT(len));
            }
            CbfCone::RotatedQuadratic => {
                if len < 2 {
                    return Err("a QR cone needs at least 2 entries".into());
                }
                let (i1, i2) = (start, start + 1);
                let h = std::f64::consts::FRAC_1_SQRT_2;
                let combine = |s: f64| {
                    let mut e: Vec<(usize, f64)> = rows[i1].iter().map(|&(j, x)| (j, h * x)).collect();
                    e.extend(rows[i2].iter().map(|&(j, x)| (j, s * h * x)));
                    (e, h * constant[i1] + s * h * constant[i2])
                };
                let (plus, c_plus) = combine(1.0);
                let (minus, c_minus) = combine(-1.0);
                push_row(&plus, c_plus, &mut triplets);
                push_row(&minus, c_minus, &mut triplets);
                (start + 2..start + len).for_each(|i| push_row(&rows[i], constant[i], &mut triplets));
                cones.push(SupportedConeT::SecondOrderConeT(len));
            }
        }
        start += len;
    }
    let rows_c = b_c.len();
    let mut by_column: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    for (r, j, x) in triplets {
        by_column[j].push((r, x));
    }
    let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
    for column in &mut by_column {
        column.sort_by_key(|e| e.0);
        let mut last: Option<usize> = None;
        for &(r, x) in column.iter() {
            if last == Some(r) {
                *nzval.last_mut().expect("an entry was pushed") += x;
            } else {
                rowval.push(r);
                nzval.push(x);
            }
            last = Some(r);
        }
        colptr.push(rowval.len());
    }
    let a = CscMatrix::new(rows_c, n, colptr, rowval, nzval);
    let p = CscMatrix::zeros((n, n));
    let sign = if file.minimize { 1.0 } else { -1.0 };
    let mut q = vec![0.0; n];
    for &(j, x) in &file.objective {
        q[j] += sign * x;
    }
    let settings = DefaultSettings { verbose: false, ..DefaultSettings::default() };
    let mut solver = DefaultSolver::new(&p, &q, &a, &b_c, &cones, settings).map_err(|e| format!("{e:?}"))?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {
            let x = solver.solution.x.clone();
            let value = q.iter().zip(&x).map(|(c, x)| c * x).sum::<f64>() * sign + file.objective_constant;
            Ok((value, x))
        }
        status => Err(format!("clarabel: {status:?}")),
    }
}
