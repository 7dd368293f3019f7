//! FCLIB-shaped HDF5 files built from a fuzzer's bytes, for the structure-aware target of
//! `tests/fuzz_fclib.rs`: what gelenk owns is what its reader does with well-formed HDF5 holding
//! hostile FCLIB content, so `hdf5-pure` writes every file and the bytes choose the content.
//!
//! A plan is read as: 8 bytes seeding the numbers (a symmetric positive definite W, q, μ and a
//! solution), one byte of options (compressed columns or triplets, a solution, an info group,
//! chunked and compressed datasets with checksums, the newest file format, a user block), one
//! byte for the number of contacts, then faults of three bytes each (kind, dataset, value):
//! datasets removed, set to extreme numbers, resized, stored with another type or shape, replaced
//! by a group; W made unsymmetric, negative on its diagonal, given duplicate or out-of-range
//! indices; mixed-problem datasets added, the group renamed, sizes of up to 2³⁰ contacts
//! declared. A missing byte reads as 0, so an empty plan is a valid problem of no contact.
//!
//! Each fault says what the reader must do with it alone: keep the problem (an option FCLIB
//! allows: unsorted columns, CSR of a symmetric W, extra datasets), refuse it (a missing dataset,
//! a non-finite number, an index out of range), or either. [`Expect`] combines them: the problem
//! written when every fault keeps it, a refusal when the plan's only fault refuses it.
//!
//! `hdf5-pure` writes no soft or external link, no dataset left unwritten and no raw data in
//! another file: the faults that would make them (kinds 7 to 10) remove the object instead,
//! which is what the reader sees of them (`hdf5-pure` follows only hard links and reads no
//! external raw data; a huge declared dataset is refused by its declared size alone). Files with
//! each of them, written by libhdf5, are kept in `tests/data/fclib/` and read by
//! `tests/fuzz_fclib.rs`.

use gelenk::io::problem::FclibLocal;
use hdf5_pure::{EnumTypeBuilder, FileBuilder, FinishedGroup, GroupBuilder, LibVer};
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::collections::BTreeMap;
use std::path::Path;

/// What reading the file must give.
#[derive(Debug)]
pub enum Expect {
    /// This problem, to the last bit.
    Local(FclibLocal),
    /// A typed error, for the reason given.
    Error(String),
    /// Either: a typed error or a consistent problem.
    Either,
}

/// The numbers of a dataset.
#[derive(Clone, Debug, PartialEq)]
enum Values {
    Int(Vec<i64>),
    Float(Vec<f64>),
    Text(String),
}

impl Values {
    fn len(&self) -> usize {
        match self {
            Values::Int(v) => v.len(),
            Values::Float(v) => v.len(),
            Values::Text(_) => 1,
        }
    }
}

/// The type a dataset's values are stored as (converted on writing as libhdf5 converts:
/// integers clamped to the type's range, numbers rounded, NaN as 0).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Stored {
    I8,
    I32,
    I64,
    U64,
    F32,
    F64,
    /// HDF5's boolean: an enumeration FALSE = 0, TRUE = 1 over a byte.
    Bool,
}

/// How a dataset's values are laid out in the file.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Shape {
    Vector,
    Column,
    Row,
    Scalar,
    Null,
}

/// One object of the file, by its path.
#[derive(Clone, Debug, PartialEq)]
enum Node {
    Data {
        values: Values,
        stored: Option<Stored>,
        shape: Shape,
    },
    Group,
    /// Declared with these dimensions and never written: left out of the file, which
    /// `hdf5-pure` cannot write (the plan's other datasets still declare the huge size).
    Huge(Vec<usize>),
}

fn ints(v: Vec<i64>) -> Node {
    Node::Data { values: Values::Int(v), stored: Some(Stored::I32), shape: Shape::Vector }
}

fn floats(v: &[f64]) -> Node {
    Node::Data { values: Values::Float(v.to_vec()), stored: None, shape: Shape::Vector }
}

/// Numbers that a fault writes into a floating-point dataset.
const EXTREME_FLOATS: &[f64] = &[
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    1e308,
    -1e308,
    1.01e100,
    -1.01e100,
    f64::MAX,
    5e-324,
    -0.0,
    0.0,
    -1.0,
    0.5,
    1e9,
    -1e-300,
    2.0,
];

/// Datasets and groups a fault can aim at; the first ones are the datasets a reader needs.
const TARGETS: &[&str] = &[
    "fclib_local/W/x",
    "fclib_local/W/i",
    "fclib_local/W/p",
    "fclib_local/vectors/q",
    "fclib_local/vectors/mu",
    "fclib_local/W/nz",
    "fclib_local/W/m",
    "fclib_local/W/n",
    "fclib_local/spacedim",
    "fclib_local/W/nzmax",
    "solution/u",
    "solution/r",
    "fclib_local",
    "fclib_local/W",
    "fclib_local/vectors",
    "solution",
];
/// The first `REQUIRED` of [`TARGETS`] must be present.
const REQUIRED: usize = 9;

/// Most faults read from a plan: more mostly repeat the first refusal.
const MAX_FAULTS: usize = 6;

/// Bytes of a plan, 0 past its end.
struct Plan<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Plan<'_> {
    fn byte(&mut self) -> u8 {
        let b = self.bytes.get(self.at).copied().unwrap_or(0);
        self.at += 1;
        b
    }
    fn done(&self) -> bool {
        self.at >= self.bytes.len()
    }
}

/// What a fault alone asks of the reader.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Verdict {
    Keep,
    Refuse(&'static str),
    Either,
}

/// The file's objects and the problem they pose before any fault.
struct Layout {
    nodes: BTreeMap<String, Node>,
    local: FclibLocal,
    triplets: bool,
    chunked: bool,
}

/// Writes the FCLIB file that `plan` describes at `path` (replacing it) and says what reading
/// it must give.
pub fn write_case(plan: &[u8], path: &Path) -> Expect {
    let mut plan = Plan { bytes: plan, at: 0 };
    let mut seed = [0u8; 8];
    seed.iter_mut().for_each(|b| *b = plan.byte());
    let mut rng = StdRng::seed_from_u64(u64::from_le_bytes(seed));
    let options = plan.byte();
    let contacts = match plan.byte() {
        b @ 0..=249 => usize::from(b % 5),
        b => 10 + 6 * usize::from(b - 250),
    };
    let mut layout = baseline(&mut rng, contacts, options);
    let mut verdicts = Vec::new();
    let mut faults = 0;
    while !plan.done() && faults < MAX_FAULTS {
        let (kind, target, value) = (plan.byte(), plan.byte(), plan.byte());
        verdicts.push(apply(&mut layout, &mut rng, kind, usize::from(target), value));
        faults += 1;
    }
    match write(&layout, path, options) {
        Err(e) => panic!("{}: hdf5-pure wrote no file: {e}", path.display()),
        // Objects under a dataset (or under a link) are left out: the file is not the layout.
        Ok(false) => return Expect::Either,
        Ok(true) => {}
    }
    let refusals: Vec<&str> = verdicts
        .iter()
        .filter_map(|v| match v {
            Verdict::Refuse(why) => Some(*why),
            _ => None,
        })
        .collect();
    let others = verdicts.iter().filter(|v| !matches!(v, Verdict::Keep)).count();
    // A later fault may undo an earlier one (a NaN in a solution then removed), so a refusal is
    // expected of a plan of one fault only.
    match (verdicts.len(), others, refusals.as_slice()) {
        (_, 0, _) => Expect::Local(layout.local),
        (1, 1, [why]) => Expect::Error(why.to_string()),
        _ => Expect::Either,
    }
}

/// A valid problem of `contacts` contacts: W = B Bᵀ/m + I with B's entries in [−1, 1] (exactly
/// symmetric: the upper triangle is mirrored), q in [−1, 1], μ in [0, 1], as compressed columns
/// or triplets (options bit 0) with an optional solution (bit 1) and info group (bit 2).
fn baseline(rng: &mut StdRng, contacts: usize, options: u8) -> Layout {
    let m = 3 * contacts;
    let b =
        DMatrix::from_fn(m, m, |_, _| if rng.random_bool(0.6) { 0.0 } else { rng.random_range(-1.0..1.0) });
    let mut w = &b * b.transpose() / (m.max(1) as f64) + DMatrix::identity(m, m);
    for i in 0..m {
        for j in 0..i {
            w[(i, j)] = w[(j, i)];
        }
    }
    let q = DVector::from_fn(m, |_, _| rng.random_range(-1.0..1.0));
    let mu = DVector::from_fn(contacts, |_, _| rng.random_range(0.0..1.0));
    let solution = (options & 2 != 0).then(|| {
        (
            DVector::from_fn(m, |_, _| rng.random_range(-1.0..1.0)),
            DVector::from_fn(m, |_, _| rng.random_range(0.0..1.0)),
        )
    });
    let local = FclibLocal { w, q, mu, solution };
    let mut layout =
        Layout { nodes: BTreeMap::new(), local, triplets: options & 1 != 0, chunked: options & 8 != 0 };
    encode(&mut layout);
    if options & 4 != 0 {
        for (name, text) in
            [("title", "fuzz"), ("description", "a generated problem"), ("math_info", "W SPD")]
        {
            let node = Node::Data { values: Values::Text(text.into()), stored: None, shape: Shape::Scalar };
            layout.nodes.insert(format!("fclib_local/info/{name}"), node);
        }
    }
    layout
}

/// The datasets of `layout.local` (W's entries whose bits are not +0.0, by columns).
fn encode(layout: &mut Layout) {
    let local = &layout.local;
    let m = local.q.len();
    let (mut p, mut cols, mut rows, mut x) = (vec![0i64], Vec::new(), Vec::new(), Vec::new());
    for j in 0..m {
        for i in 0..m {
            if local.w[(i, j)].to_bits() != 0 {
                cols.push(j as i64);
                rows.push(i as i64);
                x.push(local.w[(i, j)]);
            }
        }
        p.push(rows.len() as i64);
    }
    let nnz = x.len() as i64;
    let nodes = &mut layout.nodes;
    nodes.insert("fclib_local/spacedim".into(), ints(vec![3]));
    nodes.insert("fclib_local/W/m".into(), ints(vec![m as i64]));
    nodes.insert("fclib_local/W/n".into(), ints(vec![m as i64]));
    nodes.insert("fclib_local/W/nzmax".into(), ints(vec![nnz]));
    if layout.triplets {
        nodes.insert("fclib_local/W/nz".into(), ints(vec![nnz]));
        nodes.insert("fclib_local/W/p".into(), ints(cols));
    } else {
        nodes.insert("fclib_local/W/nz".into(), ints(vec![-1]));
        nodes.insert("fclib_local/W/p".into(), ints(p));
    }
    nodes.insert("fclib_local/W/i".into(), ints(rows));
    nodes.insert("fclib_local/W/x".into(), floats(&x));
    nodes.insert("fclib_local/vectors/q".into(), floats(local.q.as_slice()));
    nodes.insert("fclib_local/vectors/mu".into(), floats(local.mu.as_slice()));
    match &local.solution {
        Some((u, r)) => {
            nodes.insert("solution/u".into(), floats(u.as_slice()));
            nodes.insert("solution/r".into(), floats(r.as_slice()));
        }
        None => {
            nodes.remove("solution/u");
            nodes.remove("solution/r");
        }
    }
}

fn scalar_of(nodes: &BTreeMap<String, Node>, name: &str) -> Option<i64> {
    match nodes.get(name) {
        Some(Node::Data { values: Values::Int(v), .. }) if v.len() == 1 => Some(v[0]),
        _ => None,
    }
}

/// Applies one fault and says what it asks of the reader.
fn apply(layout: &mut Layout, rng: &mut StdRng, kind: u8, target: usize, value: u8) -> Verdict {
    let name = TARGETS[target % TARGETS.len()];
    let required =
        TARGETS[..REQUIRED].contains(&name) || (name.starts_with("fclib_local") && !name.ends_with("nzmax"));
    let has_solution = layout.local.solution.is_some();
    let in_solution = name.starts_with("solution");
    let m = layout.local.q.len();
    let entries = match layout.nodes.get("fclib_local/W/x") {
        Some(Node::Data { values, .. }) => values.len() as i64,
        _ => 0,
    };
    let nodes = &mut layout.nodes;
    let value = usize::from(value);
    let outside =
        |why| if required || (in_solution && has_solution) { Verdict::Refuse(why) } else { Verdict::Either };
    match kind % 16 {
        // Removed (with everything beneath). Also what the reader sees of the objects
        // `hdf5-pure` does not write (see the module's notes): a soft or external link (7, 8), a
        // huge dataset declared and never written (9), raw data in another file (10).
        2 | 7..=10 => {
            if !nodes.keys().any(|k| k == name || k.starts_with(&format!("{name}/"))) {
                return Verdict::Keep;
            }
            remove_tree(nodes, name);
            if name == "solution" {
                layout.local.solution = None;
                Verdict::Keep
            } else if required || in_solution {
                Verdict::Refuse("a dataset FCLIB requires is missing (or u or r of a solution)")
            } else {
                Verdict::Either
            }
        }
        // One entry set to an extreme number.
        0 | 1 => {
            let Some(Node::Data { values, .. }) = nodes.get_mut(name) else { return Verdict::Either };
            match values {
                Values::Float(v) if !v.is_empty() => {
                    let k = rng.random_range(0..v.len());
                    let x = EXTREME_FLOATS[value % EXTREME_FLOATS.len()];
                    if v[k].to_bits() == x.to_bits() {
                        return Verdict::Keep;
                    }
                    v[k] = x;
                    let bad = if name.ends_with("mu") {
                        !(x >= 0.0 && x.is_finite())
                    } else if in_solution {
                        !x.is_finite()
                    } else {
                        !x.is_finite() || x.abs() > 1e100
                    };
                    if bad {
                        outside("a number that is not finite, too large, or a negative μ")
                    } else {
                        Verdict::Either
                    }
                }
                Values::Int(v) if !v.is_empty() => {
                    let k = rng.random_range(0..v.len());
                    let (mi, old) = (m as i64, v[k]);
                    let x = [
                        -1,
                        -2,
                        0,
                        1,
                        2,
                        3,
                        mi - 1,
                        mi,
                        mi + 1,
                        entries,
                        entries + 1,
                        i64::from(i32::MAX),
                        i64::from(i32::MIN),
                        1 << 40,
                        -(1 << 40),
                        6,
                    ][value % 16];
                    if x == old {
                        return Verdict::Keep;
                    }
                    v[k] = x;
                    int_verdict(name, layout.triplets, k, x, mi, entries)
                }
                _ => Verdict::Either,
            }
        }
        // Resized: one entry fewer or more, emptied, doubled.
        3 => {
            let Some(Node::Data { values, .. }) = nodes.get_mut(name) else { return Verdict::Either };
            let before = values.clone();
            match values {
                Values::Int(v) => resize(v, value, 7),
                Values::Float(v) => resize(v, value, 0.25),
                Values::Text(_) => return Verdict::Either,
            }
            if *values == before {
                Verdict::Keep
            } else if name.ends_with("nzmax")
                || (layout.triplets && name.ends_with("W/x") && values.len() > before.len())
            {
                Verdict::Either
            } else {
                outside("a dataset of the wrong length")
            }
        }
        // Stored with another type (converted on writing).
        4 => {
            let Some(Node::Data { stored, values, .. }) = nodes.get_mut(name) else { return Verdict::Either };
            let types = [
                Some(Stored::I8),
                Some(Stored::I64),
                Some(Stored::U64),
                Some(Stored::F32),
                Some(Stored::F64),
                Some(Stored::Bool),
                None,
            ];
            if value % 8 == 7 {
                *values = Values::Text("3".into());
                return outside("text where numbers belong");
            }
            *stored = types[value % 8 % types.len()];
            Verdict::Either
        }
        // Stored with another shape.
        5 => {
            let Some(Node::Data { shape, .. }) = nodes.get_mut(name) else { return Verdict::Either };
            *shape = [Shape::Column, Shape::Row, Shape::Scalar, Shape::Null][value % 4];
            Verdict::Either
        }
        // A group in place of a dataset, a dataset in place of a group.
        6 => {
            let was_group = matches!(nodes.get(name), Some(Node::Group))
                || nodes.keys().any(|k| k.starts_with(&format!("{name}/")));
            nodes.retain(|k, _| !k.starts_with(&format!("{name}/")));
            nodes.insert(name.into(), if was_group { ints(vec![3]) } else { Node::Group });
            outside("a group where a dataset belongs, or the reverse")
        }
        // W changed before it is written: unsymmetric, negative diagonal, duplicate or
        // out-of-range indices, unsorted columns, CSR of the same arrays.
        11 | 12 => matrix_fault(layout, rng, value),
        // Extra objects: mixed-problem datasets, a global problem beside, unknown datasets.
        13 => {
            let (path, verdict) = match value % 5 {
                0 => ("fclib_local/V/m", Verdict::Refuse("a mixed problem (V, R)")),
                1 => ("fclib_local/R/m", Verdict::Refuse("a mixed problem (V, R)")),
                2 => ("fclib_global/M/m", Verdict::Keep),
                3 => ("fclib_local/W/comment", Verdict::Keep),
                _ => ("guesses/number_of_guesses", Verdict::Keep),
            };
            if nodes.contains_key(path) {
                return Verdict::Keep;
            }
            if !nodes.contains_key("fclib_local/W/m") && verdict != Verdict::Keep {
                return Verdict::Either;
            }
            nodes.insert(path.into(), ints(vec![1]));
            verdict
        }
        // The problem renamed as a global one.
        14 => {
            let moved: Vec<(String, Node)> = std::mem::take(nodes)
                .into_iter()
                .map(|(k, v)| (k.replacen("fclib_local", "fclib_global", 1), v))
                .collect();
            nodes.extend(moved);
            Verdict::Refuse("no fclib_local group")
        }
        // A large declared problem: W empty (zero), q and μ zero.
        _ => {
            let contacts = [1000, 2000, 2400, 3000, 1 << 20, 1 << 30][value % 6];
            let m = 3 * contacts;
            remove_tree(nodes, "fclib_local");
            remove_tree(nodes, "solution");
            layout.local.solution = None;
            nodes.insert("fclib_local/spacedim".into(), ints(vec![3]));
            for name in ["m", "n"] {
                nodes.insert(format!("fclib_local/W/{name}"), ints(vec![m]));
            }
            nodes.insert("fclib_local/W/nz".into(), ints(vec![-1]));
            nodes.insert("fclib_local/W/i".into(), ints(vec![]));
            nodes.insert("fclib_local/W/x".into(), floats(&[]));
            if contacts > 3000 {
                // Declared, not stored: the reader must refuse before allocating.
                nodes.insert("fclib_local/W/p".into(), Node::Huge(vec![m as usize + 1]));
                nodes.insert("fclib_local/vectors/q".into(), Node::Huge(vec![m as usize]));
                nodes.insert("fclib_local/vectors/mu".into(), Node::Huge(vec![contacts as usize]));
                return Verdict::Refuse("W too large to hold");
            }
            nodes.insert("fclib_local/W/p".into(), ints(vec![0; m as usize + 1]));
            nodes.insert("fclib_local/vectors/q".into(), floats(&vec![0.0; m as usize]));
            nodes.insert("fclib_local/vectors/mu".into(), floats(&vec![0.0; contacts as usize]));
            Verdict::Either
        }
    }
}

fn remove_tree(nodes: &mut BTreeMap<String, Node>, name: &str) {
    nodes.retain(|k, _| k != name && !k.starts_with(&format!("{name}/")));
}

fn resize<T: Clone>(v: &mut Vec<T>, how: usize, fill: T) {
    match how % 4 {
        0 => {
            v.pop();
        }
        1 => v.push(fill),
        2 => v.clear(),
        _ => {
            let copy = v.clone();
            v.extend(copy);
        }
    }
}

/// What an integer `x` written as entry `k` of dataset `name` asks of the reader (`m` rows, `nnz`
/// entries).
fn int_verdict(name: &str, triplets: bool, k: usize, x: i64, m: i64, nnz: i64) -> Verdict {
    let refuse = Verdict::Refuse;
    match name.rsplit('/').next().unwrap_or("") {
        "spacedim" => refuse("spacedim is not 3"),
        "m" | "n" => refuse("W's declared size disagrees with its data"),
        "nz" if triplets => {
            if !(-2..0).contains(&x) {
                refuse("nz disagrees with the triplets")
            } else {
                Verdict::Either
            }
        }
        "nz" => match x {
            -2 => Verdict::Keep,
            x if x < -2 => refuse("an unknown matrix form"),
            _ => Verdict::Either,
        },
        "p" if !triplets && (k == 0 || !(0..=nnz).contains(&x)) => refuse("a column pointer out of range"),
        "p" | "i" if triplets && !(0..m).contains(&x) => refuse("a triplet index out of range"),
        "i" if !(0..m).contains(&x) => refuse("a row index out of range"),
        _ => Verdict::Either,
    }
}

/// A fault of W, re-encoded: unsymmetric, negative diagonal, a duplicate or out-of-range index in
/// compressed columns, unsorted columns, or the arrays declared CSR (W is symmetric: the same W).
fn matrix_fault(layout: &mut Layout, rng: &mut StdRng, value: usize) -> Verdict {
    let m = layout.local.q.len();
    if m < 2 || !layout.nodes.contains_key("fclib_local/W/x") {
        return Verdict::Either;
    }
    let (i, j) = (rng.random_range(0..m), rng.random_range(0..m));
    // Earlier faults may have left p, i and x disagreeing; the index faults need them whole.
    let len = |name: &str| match layout.nodes.get(name) {
        Some(Node::Data { values, .. }) => Some(values.len()),
        _ => None,
    };
    let (entries, rows) = (len("fclib_local/W/x"), len("fclib_local/W/i"));
    let whole = match layout.nodes.get("fclib_local/W/p") {
        Some(Node::Data { values: Values::Int(p), .. }) if entries == rows => {
            let n = entries.unwrap_or(0) as i64;
            if layout.triplets {
                p.len() as i64 == n
            } else {
                p.len() == m + 1 && p.windows(2).all(|w| 0 <= w[0] && w[0] <= w[1] && w[1] <= n)
            }
        }
        _ => false,
    };
    if !whole && matches!(value % 5, 2 | 3) {
        return Verdict::Either;
    }
    match value % 5 {
        0 if i != j => {
            layout.local.w[(i, j)] += 1.0;
            encode(layout);
            Verdict::Refuse("W is not symmetric")
        }
        1 => {
            layout.local.w[(i, i)] = -1.0;
            encode(layout);
            Verdict::Refuse("W has a negative diagonal entry")
        }
        2 if !layout.triplets => {
            // Column j's first entry repeated with another value.
            let p = match layout.nodes.get("fclib_local/W/p") {
                Some(Node::Data { values: Values::Int(p), .. }) if p.len() == m + 1 => p.clone(),
                _ => return Verdict::Either,
            };
            let start = p[j] as usize;
            if p[j + 1] as usize == start {
                return Verdict::Either;
            }
            for (name, node) in layout.nodes.iter_mut() {
                match (name.as_str(), node) {
                    ("fclib_local/W/p", Node::Data { values: Values::Int(v), .. }) => {
                        v[j + 1..].iter_mut().for_each(|x| *x += 1)
                    }
                    ("fclib_local/W/i", Node::Data { values: Values::Int(v), .. }) => {
                        v.insert(start, v[start])
                    }
                    ("fclib_local/W/x", Node::Data { values: Values::Float(v), .. }) => {
                        v.insert(start, v[start] + 1.0)
                    }
                    ("fclib_local/W/nzmax", Node::Data { values: Values::Int(v), .. }) => v[0] += 1,
                    _ => {}
                }
            }
            Verdict::Refuse("a duplicate entry in a compressed column")
        }
        3 => {
            // Every column's (or the triplets') entries in reverse order.
            let p = match layout.nodes.get("fclib_local/W/p") {
                Some(Node::Data { values: Values::Int(p), .. }) => p.clone(),
                _ => return Verdict::Either,
            };
            let spans: Vec<(usize, usize)> = if layout.triplets {
                vec![(0, p.len())]
            } else {
                p.windows(2).map(|w| (w[0] as usize, w[1] as usize)).collect()
            };
            for (name, node) in layout.nodes.iter_mut() {
                let reverse = |v: &mut [i64]| spans.iter().for_each(|&(a, b)| v[a..b].reverse());
                match (name.as_str(), node) {
                    ("fclib_local/W/i", Node::Data { values: Values::Int(v), .. }) => reverse(v),
                    ("fclib_local/W/p", Node::Data { values: Values::Int(v), .. }) if layout.triplets => {
                        reverse(v)
                    }
                    ("fclib_local/W/x", Node::Data { values: Values::Float(v), .. }) => {
                        spans.iter().for_each(|&(a, b)| v[a..b].reverse())
                    }
                    _ => {}
                }
            }
            Verdict::Keep
        }
        _ if !layout.triplets => {
            layout.nodes.insert("fclib_local/W/nz".into(), ints(vec![-2]));
            Verdict::Keep
        }
        _ => Verdict::Either,
    }
}

/// Writes `layout` with `hdf5-pure`: options bit 3 chunks and compresses every dataset (deflate,
/// shuffle, Fletcher-32 checksums), bit 4 asks for the newest file format, bit 5 a user block.
/// `Ok(false)` when objects had to be left out (under a dataset or a link; links, unwritten
/// datasets and external raw data themselves are left out silently: see the module's notes).
fn write(layout: &Layout, path: &Path, options: u8) -> Result<bool, hdf5_pure::Error> {
    let mut file = FileBuilder::new();
    if options & 16 != 0 {
        file.with_libver_bounds(LibVer::LATEST, LibVer::LATEST);
    }
    if options & 32 != 0 {
        file.with_userblock(512);
    }
    let whole = fill(&mut file, "", &layout.nodes, layout.chunked);
    file.write(path)?;
    Ok(whole)
}

/// A group being built: the file's root or a group under it.
trait Parent {
    fn dataset(&mut self, name: &str) -> &mut hdf5_pure::DatasetBuilder;
    fn group(&mut self, name: &str) -> GroupBuilder;
    fn add(&mut self, group: FinishedGroup);
}

impl Parent for FileBuilder {
    fn dataset(&mut self, name: &str) -> &mut hdf5_pure::DatasetBuilder {
        self.create_dataset(name)
    }
    fn group(&mut self, name: &str) -> GroupBuilder {
        self.create_group(name)
    }
    fn add(&mut self, group: FinishedGroup) {
        self.add_group(group)
    }
}

impl Parent for GroupBuilder {
    fn dataset(&mut self, name: &str) -> &mut hdf5_pure::DatasetBuilder {
        self.create_dataset(name)
    }
    fn group(&mut self, name: &str) -> GroupBuilder {
        self.create_group(name)
    }
    fn add(&mut self, group: FinishedGroup) {
        self.add_group(group)
    }
}

/// Adds the objects of `nodes` under `prefix` (`""`: the root, else ending in `/`) to `parent`,
/// groups implied by deeper paths included; whether nothing had to be left out.
fn fill(parent: &mut dyn Parent, prefix: &str, nodes: &BTreeMap<String, Node>, chunked: bool) -> bool {
    let children: std::collections::BTreeSet<&str> = nodes
        .keys()
        .filter_map(|k| k.strip_prefix(prefix))
        .map(|rest| rest.split('/').next().unwrap_or(rest))
        .collect();
    let mut whole = true;
    for child in children {
        let path = format!("{prefix}{child}");
        let below = format!("{path}/");
        let deeper = nodes.keys().any(|k| k.starts_with(&below));
        match nodes.get(&path) {
            None | Some(Node::Group) => {
                let mut group = parent.group(child);
                whole &= fill(&mut group, &below, nodes, chunked);
                parent.add(group.finish());
            }
            Some(Node::Data { values, stored, shape }) => {
                data(parent, child, values, *stored, *shape, chunked);
                whole &= !deeper;
            }
            Some(_) => whole &= !deeper,
        }
    }
    whole
}

/// `x` as an integer of `lo..=hi`, as libhdf5 converts (clamped, NaN as 0).
fn clamp_int(x: f64, lo: i64, hi: i64) -> i64 {
    if x.is_nan() {
        0
    } else {
        (x as i64).clamp(lo, hi)
    }
}

fn data(
    parent: &mut dyn Parent,
    leaf: &str,
    values: &Values,
    stored: Option<Stored>,
    shape: Shape,
    chunked: bool,
) {
    let builder = parent.dataset(leaf);
    let mut numbers: Vec<f64> = match values {
        Values::Text(t) => {
            builder.with_vlen_strings(&[t.as_str()]).with_shape(&[]);
            return;
        }
        Values::Int(v) => v.iter().map(|&x| x as f64).collect(),
        Values::Float(v) => v.clone(),
    };
    let mut integers: Vec<i64> = match values {
        Values::Int(v) => v.clone(),
        _ => numbers.iter().map(|&x| clamp_int(x, i64::MIN, i64::MAX)).collect(),
    };
    if shape == Shape::Null {
        // hdf5-pure writes no null dataspace: no entries at all, as close as it gets.
        (numbers, integers) = (Vec::new(), Vec::new());
    }
    let native = if matches!(values, Values::Int(_)) { Stored::I64 } else { Stored::F64 };
    let clamped = |lo: i64, hi: i64| integers.iter().map(move |&x| x.clamp(lo, hi));
    match stored.unwrap_or(native) {
        Stored::I8 => builder
            .with_i8_data(&clamped(i8::MIN.into(), i8::MAX.into()).map(|x| x as i8).collect::<Vec<_>>()),
        Stored::I32 => builder
            .with_i32_data(&clamped(i32::MIN.into(), i32::MAX.into()).map(|x| x as i32).collect::<Vec<_>>()),
        Stored::I64 => builder.with_i64_data(&integers),
        Stored::U64 => builder.with_u64_data(&clamped(0, i64::MAX).map(|x| x as u64).collect::<Vec<_>>()),
        Stored::F32 => builder.with_f32_data(&numbers.iter().map(|&x| x as f32).collect::<Vec<_>>()),
        Stored::F64 => builder.with_f64_data(&numbers),
        Stored::Bool => {
            let boolean = EnumTypeBuilder::u8_based().u8_value("FALSE", 0).u8_value("TRUE", 1).build();
            let bytes: Vec<u8> = integers.iter().map(|&x| u8::from(x != 0)).collect();
            match boolean {
                Ok(boolean) => builder.with_enum_u8_data(boolean, &bytes),
                Err(_) => builder.with_u8_data(&bytes),
            }
        }
    };
    let n = numbers.len() as u64;
    match shape {
        Shape::Vector => {}
        Shape::Column => {
            builder.with_shape(&[n, 1]);
        }
        Shape::Row => {
            builder.with_shape(&[1, n]);
        }
        Shape::Scalar if n == 1 => {
            builder.with_shape(&[]);
        }
        Shape::Scalar => {}
        Shape::Null => {}
    }
    if chunked && n > 0 && shape != Shape::Null && !(shape == Shape::Scalar && n == 1) {
        let chunk: Vec<u64> = match shape {
            Shape::Column => vec![n.clamp(1, 64), 1],
            Shape::Row => vec![1, n.clamp(1, 64)],
            _ => vec![n.clamp(1, 64)],
        };
        builder.with_chunks(&chunk).with_deflate(4).with_shuffle().with_fletcher32();
    }
}
