//! QPS (the Maros–Meszaros QP format: free MPS with a `QUADOBJ` section) of a problem's QP form
//! ([`QpForm`]: frictionless or pyramid-friction problems), for QP solvers.
//!
//! Variables `x0 … x{n−1}` are the impulses in row order; rows `g0 …` are `G x ≤ h` (`L`),
//! rows `e0 …` are `A x = b` (`E`); the objective row is `obj`; `BOUNDS` gives `FR` (free),
//! `MI`/`LO`/`UP`/`FX`, since MPS's default bound is `[0, +∞)`; `QUADOBJ` lists the lower
//! triangle of P (the objective is `½xᵀPx + qᵀx`). Entries whose bits are +0.0 are not written,
//! and numbers are written in Rust's shortest round-trip form: [`parse_qps`] of [`qps_text`]
//! gives back the same [`QpForm`] to the last bit (−0.0 included).

use super::{ProblemFileError, QpForm};
use nalgebra::{DMatrix, DVector};
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

/// The QPS text of `qp`, named `name` (no whitespace).
pub fn qps_text(name: &str, qp: &QpForm) -> String {
    let n = qp.p.nrows();
    let mut s = String::new();
    let _ = writeln!(s, "NAME {name}\nROWS\n N obj");
    for i in 0..qp.g.nrows() {
        let _ = writeln!(s, " L g{i}");
    }
    for i in 0..qp.a.nrows() {
        let _ = writeln!(s, " E e{i}");
    }
    s.push_str("COLUMNS\n");
    for j in 0..n {
        let mut entries = Vec::new();
        if qp.q[j].to_bits() != 0 {
            entries.push(("obj".to_string(), qp.q[j]));
        }
        entries.extend(
            (0..qp.g.nrows())
                .filter(|&i| qp.g[(i, j)].to_bits() != 0)
                .map(|i| (format!("g{i}"), qp.g[(i, j)])),
        );
        entries.extend(
            (0..qp.a.nrows())
                .filter(|&i| qp.a[(i, j)].to_bits() != 0)
                .map(|i| (format!("e{i}"), qp.a[(i, j)])),
        );
        if entries.is_empty() {
            // A column must appear to exist: an explicit zero objective entry.
            entries.push(("obj".to_string(), 0.0));
        }
        for (row, x) in entries {
            let _ = writeln!(s, " x{j} {row} {x:e}");
        }
    }
    s.push_str("RHS\n");
    for (prefix, rhs) in [("g", &qp.h), ("e", &qp.b)] {
        for (i, x) in rhs.iter().enumerate() {
            if x.to_bits() != 0 {
                let _ = writeln!(s, " rhs {prefix}{i} {x:e}");
            }
        }
    }
    s.push_str("BOUNDS\n");
    for j in 0..n {
        let (lo, hi) = (qp.lb[j], qp.ub[j]);
        if lo == f64::NEG_INFINITY && hi == f64::INFINITY {
            let _ = writeln!(s, " FR bnd x{j}");
        } else if lo.to_bits() == hi.to_bits() {
            let _ = writeln!(s, " FX bnd x{j} {lo:e}");
        } else {
            if lo == f64::NEG_INFINITY {
                let _ = writeln!(s, " MI bnd x{j}");
            } else {
                let _ = writeln!(s, " LO bnd x{j} {lo:e}");
            }
            if hi < f64::INFINITY {
                let _ = writeln!(s, " UP bnd x{j} {hi:e}");
            }
        }
    }
    s.push_str("QUADOBJ\n");
    for j in 0..n {
        for i in j..n {
            if qp.p[(i, j)].to_bits() != 0 {
                let _ = writeln!(s, " x{i} x{j} {:e}", qp.p[(i, j)]);
            }
        }
    }
    s.push_str("ENDATA\n");
    s
}

#[derive(Clone, Copy, PartialEq)]
enum Section {
    None,
    Rows,
    Columns,
    Rhs,
    Bounds,
    Quad,
}

#[derive(Clone, Copy)]
enum RowKind {
    Objective,
    Less(usize),
    Greater(usize),
    Equal(usize),
}

fn parse(text: &str) -> Result<(String, QpForm), String> {
    let mut name = String::new();
    let mut section = Section::None;
    let mut rows: HashMap<String, RowKind> = HashMap::new();
    let (mut inequalities, mut equalities) = (0usize, 0usize);
    let mut columns: HashMap<String, usize> = HashMap::new();
    let mut column_entries: Vec<Vec<(RowKind, f64)>> = Vec::new();
    let mut rhs: Vec<(RowKind, f64)> = Vec::new();
    let mut bounds: Vec<(String, usize, &str, Option<f64>)> = Vec::new();
    let mut quad: Vec<(usize, usize, f64)> = Vec::new();
    let mut ended = false;
    // Bounds may be infinite (no bound); matrix entries and right-hand sides must be finite.
    let number = |x: &str, line: usize| -> Result<f64, String> {
        x.parse::<f64>()
            .ok()
            .filter(|v| !v.is_nan())
            .ok_or_else(|| format!("line {line}: \"{x}\" is not a number"))
    };
    let finite = |x: &str, line: usize| -> Result<f64, String> {
        let value = number(x, line)?;
        match value.is_finite() {
            true => Ok(value),
            false => Err(format!("line {line}: \"{x}\" is not a finite number")),
        }
    };
    for (k, raw) in text.lines().enumerate() {
        let line = k + 1;
        if raw.trim().is_empty() || raw.starts_with('*') {
            continue;
        }
        if ended {
            return Err(format!("line {line}: text after ENDATA"));
        }
        let f: Vec<&str> = raw.split_whitespace().collect();
        if !raw.starts_with(' ') && !raw.starts_with('\t') {
            section = match f[0] {
                "NAME" => {
                    name = f.get(1).unwrap_or(&"").to_string();
                    Section::None
                }
                "ROWS" => Section::Rows,
                "COLUMNS" => Section::Columns,
                "RHS" => Section::Rhs,
                "BOUNDS" => Section::Bounds,
                "QUADOBJ" => Section::Quad,
                "ENDATA" => {
                    ended = true;
                    Section::None
                }
                "RANGES" | "QMATRIX" | "QSECTION" | "OBJSENSE" => {
                    return Err(format!("line {line}: section {} is not supported", f[0]))
                }
                other => return Err(format!("line {line}: unknown section \"{other}\"")),
            };
            continue;
        }
        let column = |name: &str| {
            columns.get(name).copied().ok_or_else(|| format!("line {line}: unknown column \"{name}\""))
        };
        let row = |name: &str| {
            rows.get(name).copied().ok_or_else(|| format!("line {line}: unknown row \"{name}\""))
        };
        match section {
            Section::Rows => {
                let [kind, row] = f[..] else {
                    return Err(format!("line {line}: ROWS needs a type and a name"));
                };
                let kind = match kind {
                    "N" if !rows.values().any(|r| matches!(r, RowKind::Objective)) => RowKind::Objective,
                    "N" => return Err(format!("line {line}: a second objective row")),
                    "L" => RowKind::Less(post_inc(&mut inequalities)),
                    "G" => RowKind::Greater(post_inc(&mut inequalities)),
                    "E" => RowKind::Equal(post_inc(&mut equalities)),
                    other => return Err(format!("line {line}: row type \"{other}\" is not N, L, G or E")),
                };
                if rows.insert(row.to_string(), kind).is_some() {
                    return Err(format!("line {line}: row \"{row}\" given twice"));
                }
            }
            Section::Columns => {
                if f.len() != 3 && f.len() != 5 {
                    return Err(format!(
                        "line {line}: COLUMNS needs a column and one or two (row, value) pairs"
                    ));
                }
                let next = columns.len();
                let j = *columns.entry(f[0].to_string()).or_insert(next);
                if j == column_entries.len() {
                    column_entries.push(Vec::new());
                }
                for pair in f[1..].chunks(2) {
                    column_entries[j].push((row(pair[0])?, finite(pair[1], line)?));
                }
            }
            Section::Rhs => {
                if f.len() != 3 && f.len() != 5 {
                    return Err(format!(
                        "line {line}: RHS needs a set name and one or two (row, value) pairs"
                    ));
                }
                for pair in f[1..].chunks(2) {
                    rhs.push((row(pair[0])?, finite(pair[1], line)?));
                }
            }
            Section::Bounds => {
                let (kind, j, value) = match f[..] {
                    [kind @ ("FR" | "MI" | "PL"), _, col] => (kind, column(col)?, None),
                    [kind @ ("LO" | "UP" | "FX"), _, col, x] => (kind, column(col)?, Some(number(x, line)?)),
                    _ => {
                        return Err(format!(
                            "line {line}: bound \"{}\" is not FR, MI, PL, LO, UP or FX with its fields",
                            raw.trim()
                        ))
                    }
                };
                bounds.push((f[0].to_string(), j, kind, value));
            }
            Section::Quad => {
                let [a, b, x] = f[..] else {
                    return Err(format!("line {line}: QUADOBJ needs two columns and a value"));
                };
                quad.push((column(a)?, column(b)?, finite(x, line)?));
            }
            Section::None => return Err(format!("line {line}: data outside a section")),
        }
    }
    if !ended {
        return Err("no ENDATA: the file is truncated".into());
    }
    let n = columns.len();
    // The QP is dense (qpsolvers' form): refuse before allocating what a short file of many
    // names would ask for.
    let entries = (n as u128) * (n as u128 + inequalities as u128 + equalities as u128);
    if entries > QPS_MAX_DENSE_ENTRIES as u128 {
        return Err(format!(
            "{n} columns and {} rows make dense matrices of {entries} entries, over the reader's {QPS_MAX_DENSE_ENTRIES}",
            inequalities + equalities
        ));
    }
    let mut qp = QpForm {
        p: DMatrix::zeros(n, n),
        q: DVector::zeros(n),
        g: DMatrix::zeros(inequalities, n),
        h: DVector::zeros(inequalities),
        a: DMatrix::zeros(equalities, n),
        b: DVector::zeros(equalities),
        lb: DVector::zeros(n),
        ub: DVector::from_element(n, f64::INFINITY),
    };
    for (j, entries) in column_entries.iter().enumerate() {
        for &(row, x) in entries {
            match row {
                RowKind::Objective => qp.q[j] = x,
                RowKind::Less(i) => qp.g[(i, j)] = x,
                RowKind::Greater(i) => qp.g[(i, j)] = -x,
                RowKind::Equal(i) => qp.a[(i, j)] = x,
            }
        }
    }
    for (row, x) in rhs {
        match row {
            RowKind::Objective => return Err("an objective constant in RHS is not supported".into()),
            RowKind::Less(i) => qp.h[i] = x,
            RowKind::Greater(i) => qp.h[i] = -x,
            RowKind::Equal(i) => qp.b[i] = x,
        }
    }
    for (_, j, kind, value) in bounds {
        match (kind, value) {
            ("FR", _) => (qp.lb[j], qp.ub[j]) = (f64::NEG_INFINITY, f64::INFINITY),
            ("MI", _) => qp.lb[j] = f64::NEG_INFINITY,
            ("PL", _) => qp.ub[j] = f64::INFINITY,
            ("LO", Some(x)) => qp.lb[j] = x,
            ("UP", Some(x)) => qp.ub[j] = x,
            ("FX", Some(x)) => (qp.lb[j], qp.ub[j]) = (x, x),
            _ => unreachable!("bounds are checked when read"),
        }
    }
    for (i, j, x) in quad {
        qp.p[(i, j)] = x;
        qp.p[(j, i)] = x;
    }
    if let Some(j) = (0..n).find(|&j| qp.lb[j] > qp.ub[j]) {
        return Err(format!("variable {j}: bounds [{}, {}] are not an interval", qp.lb[j], qp.ub[j]));
    }
    Ok((name, qp))
}

fn post_inc(x: &mut usize) -> usize {
    *x += 1;
    *x - 1
}

/// Most entries (P, G and A together, dense) a QPS file may ask for: 5·10⁷ (400 MB), far above
/// the corpus's QPs (up to 1000 rows) and below what would exhaust memory.
pub const QPS_MAX_DENSE_ENTRIES: usize = 50_000_000;

/// Parses QPS text into its name and QP; `path` only names the source in errors. `G` rows are
/// negated into `G x ≤ h`.
pub fn parse_qps(text: &str, path: &Path) -> Result<(String, QpForm), ProblemFileError> {
    parse(text).map_err(|reason| ProblemFileError::Invalid { path: path.to_path_buf(), reason })
}

/// Reads a QPS file.
pub fn read_qps(path: &Path) -> Result<(String, QpForm), ProblemFileError> {
    parse_qps(&super::read_text(path)?, path)
}

/// Writes `qp` as a QPS file at `path`, named `name`.
pub fn write_qps(path: &Path, name: &str, qp: &QpForm) -> Result<(), ProblemFileError> {
    std::fs::write(path, qps_text(name, qp))
        .map_err(|source| ProblemFileError::Write { path: path.to_path_buf(), source })
}
