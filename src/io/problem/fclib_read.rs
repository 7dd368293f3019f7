//! The FCLIB reader ([`read_fclib`]): a local problem of a file written by fclib, Siconos or
//! gelenk, read from untrusted input. HDF5 is parsed in Rust by `hdf5-pure` (no C library), from
//! the file's bytes in memory; this module decides what the file's objects may be before anything
//! is read or allocated for them:
//!
//! - the file is a regular file (a named pipe would block its read) of at most
//!   [`FCLIB_MAX_FILE_BYTES`], whose superblock does not record a longer file (a truncated file);
//! - every object read is reached through hard links only, and every dataset keeps its data in
//!   the file: `hdf5-pure` follows no soft or external link (a dataset behind one is missing)
//!   and reads no external raw data or virtual dataset (each could name another file, a device
//!   or a pipe);
//! - a dataset's declared size is checked before it is read: at most [`FCLIB_MAX_ENTRIES`]
//!   entries (and chunks of at most as many), and exactly as many as W's size implies where it
//!   implies one; W, held dense, has at most [`FCLIB_MAX_ENTRIES`] entries; data stored in one
//!   block (compact, or contiguous and written) has exactly the entries' size; a read gives
//!   exactly the declared number of entries;
//! - integers (sizes, indices) are stored as integers (an unsigned one beyond `i64` is refused)
//!   and numbers as floating-point numbers;
//! - indices lie in range, compressed pointers start at 0 and never decrease, a compressed
//!   column or row holds each index once, W is finite,
//!   within ±1e100, symmetric and not negative on its diagonal, q likewise bounded, μ finite and
//!   ≥ 0, a solution (`/solution/u`, `/solution/r`) complete and finite.
//!
//! Each refusal is a [`ProblemFileError::Invalid`] naming the file and the dataset.

use super::fclib::FclibLocal;
use super::json::MAX_MAGNITUDE;
use super::{validate_problem, ProblemFileError};
use hdf5_pure::{DType, FormatError, Layout};
use nalgebra::{DMatrix, DVector};
use std::path::Path;

/// Most entries of any dataset the reader loads, and of W held dense (m² ≤ 5·10⁷: up to 7071
/// rows, 2357 contacts); a file declaring more is refused before anything is allocated for it.
pub const FCLIB_MAX_ENTRIES: usize = 50_000_000;

/// Largest FCLIB file read (bytes, 1 GiB): the whole file is read into memory before it is
/// parsed, so a larger one is refused first. W of [`FCLIB_MAX_ENTRIES`] entries, all stored as
/// compressed columns of 8-byte numbers and 4-byte indices, takes 600 MB.
pub const FCLIB_MAX_FILE_BYTES: u64 = 1 << 30;

/// Integers or floating-point numbers, the two kinds of FCLIB's datasets.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Int,
    Float,
}

/// An open FCLIB file and its path, for errors naming both the file and the dataset.
struct Source<'a> {
    file: hdf5_pure::File,
    path: &'a Path,
}

/// What a missing object is called: `hdf5-pure` reaches objects through hard links only.
const MISSING: &str = "missing (the reader follows only the file's own hard links, no soft or external link)";

fn not_found(e: &hdf5_pure::Error) -> bool {
    matches!(e, hdf5_pure::Error::Format(FormatError::PathNotFound(_)))
}

impl Source<'_> {
    fn invalid(&self, field: &str, reason: impl std::fmt::Display) -> ProblemFileError {
        ProblemFileError::Invalid { path: self.path.to_path_buf(), reason: format!("{field}: {reason}") }
    }

    /// Whether object `name` (a path from the root: a group or a dataset) exists, reached through
    /// hard links only; `Err` when the file's structure on the way cannot be read.
    fn exists(&self, name: &str) -> Result<bool, ProblemFileError> {
        match self.file.group(name) {
            Ok(_) => return Ok(true),
            Err(e) if not_found(&e) => return Ok(false),
            Err(_) => {}
        }
        match self.file.dataset(name) {
            Ok(_) => Ok(true),
            Err(e) if not_found(&e) => Ok(false),
            Err(e) => Err(self.invalid(name, e)),
        }
    }

    /// Dataset `name`, its data stored in the file, and its number of entries (checked against
    /// [`FCLIB_MAX_ENTRIES`] from its declared dimensions, before any read).
    fn dataset(&self, name: &str, kind: Kind) -> Result<(hdf5_pure::Dataset, usize), ProblemFileError> {
        let dataset = self.file.dataset(name).map_err(|e| {
            if not_found(&e) {
                self.invalid(name, MISSING)
            } else {
                self.invalid(name, e)
            }
        })?;
        let dims = dataset.shape().map_err(|e| self.invalid(name, e))?;
        // A scalar has no dimensions and one entry (a null dataspace too: its read gives none,
        // which `read` refuses).
        let declared = dims.iter().try_fold(1u64, |n, &d| n.checked_mul(d));
        let len = declared
            .and_then(|n| usize::try_from(n).ok())
            .filter(|&n| n <= FCLIB_MAX_ENTRIES)
            .ok_or_else(|| {
                self.invalid(
                    name,
                    format!("declared with dimensions {dims:?}: over {FCLIB_MAX_ENTRIES} entries"),
                )
            })?;
        let size = dataset.element_size().map_err(|e| self.invalid(name, e))?;
        let bytes = (len as u64).saturating_mul(size);
        // Data in one block fills exactly its entries. A compact block (in the object header) is
        // always there; a contiguous one may be unallocated, when never written (the dataset then
        // reads as its fill value, as fclib's own sample's solution/r).
        let layout = dataset.layout().map_err(|e| self.invalid(name, e))?;
        let stored = match layout {
            Layout::Compact { size } => Some(size),
            Layout::Contiguous { address: Some(_), size } => Some(size),
            Layout::Contiguous { address: None, .. } => None,
            Layout::Chunked { ref chunk_shape, .. } => {
                let chunk = chunk_shape.iter().try_fold(1u64, |n, &d| n.checked_mul(d));
                if chunk.is_none_or(|n| n > FCLIB_MAX_ENTRIES as u64) {
                    return Err(self.invalid(
                        name,
                        format!("chunks of dimensions {chunk_shape:?}: over {FCLIB_MAX_ENTRIES} entries"),
                    ));
                }
                None
            }
            _ => {
                return Err(self.invalid(name, "its data lies outside the file (external or virtual storage)"))
            }
        };
        if let Some(stored) = stored.filter(|&stored| stored != bytes) {
            return Err(self.invalid(name, format!("{len} entries of {size} bytes stored in {stored} bytes")));
        }
        let stored = dataset.dtype().map_err(|e| self.invalid(name, e))?;
        let fits = match kind {
            Kind::Int => matches!(
                stored,
                DType::I8
                    | DType::I16
                    | DType::I32
                    | DType::I64
                    | DType::U8
                    | DType::U16
                    | DType::U32
                    | DType::U64
            ),
            Kind::Float => matches!(stored, DType::F32 | DType::F64),
        };
        if !fits {
            let expected = if kind == Kind::Int { "integers" } else { "floating-point numbers" };
            return Err(self.invalid(name, format!("stored as {stored}, expected {expected}")));
        }
        Ok((dataset, len))
    }

    /// The number of entries of dataset `name`, without reading it.
    fn len(&self, name: &str, kind: Kind) -> Result<usize, ProblemFileError> {
        self.dataset(name, kind).map(|(_, len)| len)
    }

    /// `values`, read from dataset `name` of `len` declared entries, when they are as many.
    fn read<T>(
        &self,
        name: &str,
        len: usize,
        values: Result<Vec<T>, hdf5_pure::Error>,
    ) -> Result<Vec<T>, ProblemFileError> {
        let values = values.map_err(|e| self.invalid(name, e))?;
        if values.len() != len {
            return Err(self.invalid(name, format!("{} entries read of {len} declared", values.len())));
        }
        Ok(values)
    }

    /// The integers of dataset `name`; exactly `want` of them when given.
    fn ints(&self, name: &str, want: Option<usize>) -> Result<Vec<i64>, ProblemFileError> {
        let (dataset, len) = self.dataset(name, Kind::Int)?;
        self.expect(name, len, want)?;
        if matches!(dataset.dtype(), Ok(DType::U64)) {
            let values = self.read(name, len, dataset.read_u64())?;
            return values
                .iter()
                .enumerate()
                .map(|(k, &v)| {
                    i64::try_from(v)
                        .map_err(|_| self.invalid(name, format!("entry {k} is {v}, beyond 64-bit integers")))
                })
                .collect();
        }
        self.read(name, len, dataset.read_i64())
    }

    /// The numbers of dataset `name`; exactly `want` of them when given.
    fn doubles(&self, name: &str, want: Option<usize>) -> Result<Vec<f64>, ProblemFileError> {
        let (dataset, len) = self.dataset(name, Kind::Float)?;
        self.expect(name, len, want)?;
        self.read(name, len, dataset.read_f64())
    }

    fn expect(&self, name: &str, len: usize, want: Option<usize>) -> Result<(), ProblemFileError> {
        match want {
            Some(want) if want != len => Err(self.invalid(name, format!("{len} entries, expected {want}"))),
            _ => Ok(()),
        }
    }

    fn scalar(&self, name: &str) -> Result<i64, ProblemFileError> {
        Ok(self.ints(name, Some(1))?[0])
    }
}

/// Reads an FCLIB local problem (and its `/solution` when present) from `path`: W as compressed
/// columns (`nz = −1`), compressed rows (`nz = −2`) or `nz` triplets (duplicates summed, as
/// CSparse does). Errors name the file and the dataset: a file that is not HDF5 or is damaged, a
/// missing, mistyped or oversized dataset, sizes that disagree, indices out of range or
/// repeated, a W that is not symmetric or negative on its diagonal, numbers that are not finite
/// or beyond ±1e100, a negative μ; the module documentation lists every rule.
pub fn read_fclib(path: &Path) -> Result<FclibLocal, ProblemFileError> {
    let meta = std::fs::metadata(path)
        .map_err(|source| ProblemFileError::Read { path: path.to_path_buf(), source })?;
    let refuse = |reason: String| ProblemFileError::Invalid { path: path.to_path_buf(), reason };
    if !meta.is_file() {
        return Err(refuse("not a regular file (an FCLIB file is read from disk)".into()));
    }
    if meta.len() > FCLIB_MAX_FILE_BYTES {
        return Err(refuse(format!("file: {} bytes, over the {FCLIB_MAX_FILE_BYTES} read", meta.len())));
    }
    let bytes =
        std::fs::read(path).map_err(|source| ProblemFileError::Read { path: path.to_path_buf(), source })?;
    let length = bytes.len() as u64;
    let file = hdf5_pure::File::from_bytes(bytes)
        .map_err(|e| refuse(format!("file (not an HDF5 file, or damaged): {e}")))?;
    // The end the superblock records (`hdf5-pure` gives it from the file's start, past any user
    // block): a shorter file was cut short.
    let end = file.superblock().eof_address;
    if end > length {
        return Err(refuse(format!("file (truncated): {length} bytes, its superblock records {end}")));
    }
    let source = Source { file, path };
    if !source.exists("fclib_local")? {
        let global = source.exists("fclib_global")? || source.exists("fclib_global_rolling")?;
        return Err(source.invalid(
            "/fclib_local",
            if global {
                "the file holds a global FCLIB problem; only the local form is read"
            } else {
                "no local FCLIB problem in the file"
            },
        ));
    }
    let spacedim = source.scalar("fclib_local/spacedim")?;
    if spacedim != 3 {
        return Err(
            source.invalid("fclib_local/spacedim", format!("{spacedim}: only 3-D contact problems are read"))
        );
    }
    if source.exists("fclib_local/V")? || source.exists("fclib_local/R")? {
        return Err(source.invalid("fclib_local/V, R", "mixed problems (equality rows) are not read"));
    }
    let m = matrix_size(&source)?;
    // The vectors' sizes before W's data: a file whose sizes disagree allocates nothing.
    let contacts = m / 3;
    for (name, want) in [("fclib_local/vectors/q", m), ("fclib_local/vectors/mu", contacts)] {
        source.expect(name, source.len(name, Kind::Float)?, Some(want))?;
    }
    let w = matrix(&source, m)?;
    let q = source.doubles("fclib_local/vectors/q", Some(m))?;
    if let Some(k) = q.iter().position(|&v| !bounded(v)) {
        return Err(source.invalid(
            "fclib_local/vectors/q",
            format!("entry {k} is {}, not a finite number within ±{MAX_MAGNITUDE:e}", q[k]),
        ));
    }
    let mu = source.doubles("fclib_local/vectors/mu", Some(contacts))?;
    if let Some(k) = mu.iter().position(|&v| !(v >= 0.0 && v.is_finite())) {
        return Err(source.invalid("fclib_local/vectors/mu", format!("contact {k} has μ = {}", mu[k])));
    }
    let solution = if source.exists("solution")? {
        let u = source.doubles("solution/u", Some(m))?;
        let r = source.doubles("solution/r", Some(m))?;
        for (name, x) in [("solution/u", &u), ("solution/r", &r)] {
            if let Some(k) = x.iter().position(|v| !v.is_finite()) {
                return Err(source.invalid(name, format!("entry {k} is {}", x[k])));
            }
        }
        Some((DVector::from_vec(u), DVector::from_vec(r)))
    } else {
        None
    };
    let local = FclibLocal { w, q: DVector::from_vec(q), mu: DVector::from_vec(mu), solution };
    // What is left to check is W's symmetry and diagonal (gelenk's A is W, its b is q).
    validate_problem(&local.problem())
        .map_err(|reason| source.invalid("fclib_local/W (gelenk's A)", reason))?;
    Ok(local)
}

/// W's size m (`m = n`, a multiple of 3, m² within [`FCLIB_MAX_ENTRIES`]).
fn matrix_size(source: &Source) -> Result<usize, ProblemFileError> {
    let (m, n) = (source.scalar("fclib_local/W/m")?, source.scalar("fclib_local/W/n")?);
    if m != n || m < 0 || m % 3 != 0 {
        return Err(
            source.invalid("fclib_local/W", format!("{m} × {n}, expected square with 3 rows per contact"))
        );
    }
    usize::try_from(m)
        .ok()
        .filter(|&m| m.checked_mul(m).is_some_and(|entries| entries <= FCLIB_MAX_ENTRIES))
        .ok_or_else(|| {
            source.invalid("fclib_local/W", format!("{m} × {m}: over {FCLIB_MAX_ENTRIES} entries held dense"))
        })
}

/// W (m × m) from its compressed columns, compressed rows or triplets.
fn matrix(source: &Source, m: usize) -> Result<DMatrix<f64>, ProblemFileError> {
    let nz = source.scalar("fclib_local/W/nz")?;
    let index = |v: i64, field: &str| {
        usize::try_from(v).ok().filter(|&v| v < m).ok_or_else(|| {
            source.invalid(&format!("fclib_local/W/{field}"), format!("index {v} outside 0..{m}"))
        })
    };
    let mut w = DMatrix::zeros(m, m);
    match nz {
        -1 | -2 => {
            // Compressed columns (p: column pointers, i: row indices) or rows (the roles swapped).
            let (lines, across) = if nz == -1 { ("column", "row") } else { ("row", "column") };
            let p = source.ints("fclib_local/W/p", Some(m + 1))?;
            let i = source.ints("fclib_local/W/i", None)?;
            let x = source.doubles("fclib_local/W/x", Some(i.len()))?;
            if p[0] != 0 {
                return Err(source.invalid("fclib_local/W/p", format!("starts at {}, not 0", p[0])));
            }
            // The last line that set each entry of a line, to find an index repeated in one line.
            let mut seen = vec![usize::MAX; m];
            for line in 0..m {
                let (start, end) = (p[line], p[line + 1]);
                if start < 0 || end < start || end as u64 > x.len() as u64 {
                    return Err(source.invalid(
                        "fclib_local/W/p",
                        format!("{lines} {line} spans {start}..{end} of {} entries", x.len()),
                    ));
                }
                for k in start as usize..end as usize {
                    let other = index(i[k], "i")?;
                    if seen[other] == line {
                        return Err(source.invalid(
                            "fclib_local/W/i",
                            format!("{across} {other} appears twice in {lines} {line}"),
                        ));
                    }
                    seen[other] = line;
                    let (r, c) = if nz == -1 { (other, line) } else { (line, other) };
                    w[(r, c)] = finite_entry(source, x[k], k)?;
                }
            }
        }
        nz if nz >= 0 => {
            let count = usize::try_from(nz).unwrap_or(usize::MAX);
            let p = source.ints("fclib_local/W/p", Some(count))?;
            let i = source.ints("fclib_local/W/i", Some(count))?;
            let (dataset, len) = source.dataset("fclib_local/W/x", Kind::Float)?;
            if len < count {
                return Err(
                    source.invalid("fclib_local/W/x", format!("{len} entries for nz = {nz} triplets"))
                );
            }
            let x = source.read("fclib_local/W/x", len, dataset.read_f64())?;
            for k in 0..count {
                w[(index(i[k], "i")?, index(p[k], "p")?)] += finite_entry(source, x[k], k)?;
            }
            if let Some(k) = w.iter().position(|&v| !bounded(v)) {
                return Err(source.invalid(
                    "fclib_local/W",
                    format!("the triplets sum to {} at ({}, {})", w[k], k % m, k / m),
                ));
            }
        }
        _ => {
            return Err(source.invalid("fclib_local/W/nz", format!("{nz}: not a matrix form (−1, −2 or ≥ 0)")))
        }
    }
    Ok(w)
}

/// `x`, entry `k` of W/x, when finite and within ±1e100.
fn finite_entry(source: &Source, x: f64, k: usize) -> Result<f64, ProblemFileError> {
    if bounded(x) {
        Ok(x)
    } else {
        Err(source.invalid(
            "fclib_local/W/x",
            format!("entry {k} is {x}, not a finite number within ±{MAX_MAGNITUDE:e}"),
        ))
    }
}

/// Whether `x` is a finite number within ±1e100 (what gelenk's problems hold).
fn bounded(x: f64) -> bool {
    x.is_finite() && x.abs() <= MAX_MAGNITUDE
}
