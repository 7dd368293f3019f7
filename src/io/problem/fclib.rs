//! FCLIB (Acary, Brémond, Koziara, Pérignon: a collection of discrete 3-D frictional contact
//! problems in HDF5, read by Siconos): the local formulation `u = W r + q`, `C*_μ ∋ û ⊥ r ∈ C_μ`
//! of a problem whose rows are all contact blocks, with the reference solution.
//!
//! The layout is the one fclib's `fclib_write_local` / `fclib_read_local` use:
//!
//! | dataset | content |
//! |---|---|
//! | `/fclib_local/spacedim` | int[1] = 3 |
//! | `/fclib_local/W/{m,n,nz,nzmax}` | int[1] each; `nz = −1`: compressed columns |
//! | `/fclib_local/W/{p,i,x}` | column pointers int[n+1], row indices int[nzmax], values double[nzmax] |
//! | `/fclib_local/vectors/q`, `/fclib_local/vectors/mu` | double[m], double[m/3] |
//! | `/solution/u`, `/solution/r` | (optional) the reference's local velocities and impulses |
//!
//! gelenk's problem maps as `W = A + R` (the softness R folded into W), `q = b`, `μ` of each
//! contact, the rows in the problem's order (contact k on rows 3k, 3k+1, 3k+2: normal first).
//! Only problems of contact blocks alone, with isotropic friction (μ = μ₂), have this form
//! ([`fclib_of`] says why not otherwise). [`read_fclib`] also reads triplet matrices (`nz ≥ 0`).
//! HDF5 is the system's C library: the `fclib` cargo feature, `apt-get install libhdf5-dev`.

use super::{validate_problem, ProblemFileError};
use crate::constraints::{ConstraintProblem, ContactBlock, FrictionModel, RowLaw, RowOrigin};
use nalgebra::{DMatrix, DVector};
use std::path::Path;

/// A local FCLIB problem and its optional solution.
#[derive(Clone, Debug, PartialEq)]
pub struct FclibLocal {
    /// W (m × m, m = 3 × contacts), dense here; written as compressed columns of its entries
    /// whose bits are not +0.0.
    pub w: DMatrix<f64>,
    /// q (m).
    pub q: DVector<f64>,
    /// μ of each contact.
    pub mu: DVector<f64>,
    /// The solution `(u, r)`: local velocities (m/s) and impulses (N·s), when known.
    pub solution: Option<(DVector<f64>, DVector<f64>)>,
}

/// The FCLIB form of `problem`, or why it has none (rows that are not contact blocks,
/// anisotropic friction, a friction pyramid).
pub fn fclib_of(problem: &ConstraintProblem) -> Result<FclibLocal, String> {
    validate_problem(problem)?;
    let n = problem.rows();
    if problem.friction != FrictionModel::Cone {
        return Err("FCLIB poses Coulomb cones; this problem has a friction pyramid".into());
    }
    if n != 3 * problem.contacts.len() || problem.contacts.iter().enumerate().any(|(k, c)| c.normal != 3 * k)
    {
        return Err("FCLIB's local form holds contact blocks only; this problem has other rows".into());
    }
    if let Some(k) = problem.contacts.iter().position(|c| c.mu != c.mu2) {
        return Err(format!("contact {k}: anisotropic friction (μ ≠ μ₂) has no FCLIB form"));
    }
    let mut w = problem.delassus_dense().into_owned();
    for i in 0..n {
        w[(i, i)] += problem.regularization[i];
    }
    Ok(FclibLocal {
        w,
        q: problem.bias.clone(),
        mu: DVector::from_iterator(problem.contacts.len(), problem.contacts.iter().map(|c| c.mu)),
        solution: None,
    })
}

impl FclibLocal {
    /// The gelenk problem it poses: A = W, R = 0, b = q, contact k on rows 3k.. with μ = μ₂.
    pub fn problem(&self) -> ConstraintProblem {
        let contacts: Vec<ContactBlock> =
            self.mu.iter().enumerate().map(|(k, &mu)| ContactBlock { normal: 3 * k, mu, mu2: mu }).collect();
        let laws = (0..self.q.len())
            .map(|i| if i % 3 == 0 { RowLaw::Unilateral } else { RowLaw::Friction { contact: i / 3 } })
            .collect();
        let mut problem = ConstraintProblem::from_parts(
            self.w.clone(),
            self.q.clone(),
            laws,
            contacts,
            FrictionModel::Cone,
        );
        problem.origins = (0..self.q.len()).map(|i| RowOrigin::Contact(i / 3)).collect();
        problem
    }
}

fn invalid(path: &Path, reason: String) -> ProblemFileError {
    ProblemFileError::Invalid { path: path.to_path_buf(), reason }
}

fn h5(path: &Path, field: &str, e: hdf5::Error) -> ProblemFileError {
    invalid(path, format!("{field}: {e}"))
}

/// Writes `local` as an FCLIB file at `path` (replacing it).
pub fn write_fclib(path: &Path, local: &FclibLocal) -> Result<(), ProblemFileError> {
    let m = local.q.len();
    if local.w.shape() != (m, m) || 3 * local.mu.len() != m {
        return Err(invalid(
            path,
            format!("W is {:?}, q has {m} entries and μ {}", local.w.shape(), local.mu.len()),
        ));
    }
    let int = |x: usize, field: &str| {
        i32::try_from(x).map_err(|_| invalid(path, format!("{field} = {x} does not fit FCLIB's int")))
    };
    let (mut p, mut rows, mut values) = (vec![0i32], Vec::new(), Vec::new());
    for j in 0..m {
        for i in 0..m {
            if local.w[(i, j)].to_bits() != 0 {
                rows.push(int(i, "W/i")?);
                values.push(local.w[(i, j)]);
            }
        }
        p.push(int(rows.len(), "W/nzmax")?);
    }
    let write = || -> Result<(), (&'static str, hdf5::Error)> {
        let file = hdf5::File::create(path).map_err(|e| ("file", e))?;
        let root = file.create_group("fclib_local").map_err(|e| ("/fclib_local", e))?;
        let ints = |g: &hdf5::Group, name: &'static str, x: &[i32]| {
            g.new_dataset_builder().with_data(x).create(name).map(|_| ()).map_err(|e| (name, e))
        };
        let doubles = |g: &hdf5::Group, name: &'static str, x: &[f64]| {
            g.new_dataset_builder().with_data(x).create(name).map(|_| ()).map_err(|e| (name, e))
        };
        ints(&root, "spacedim", &[3])?;
        let w = root.create_group("W").map_err(|e| ("W", e))?;
        let (m32, nnz) = (m as i32, values.len() as i32);
        ints(&w, "nzmax", &[nnz])?;
        ints(&w, "m", &[m32])?;
        ints(&w, "n", &[m32])?;
        ints(&w, "nz", &[-1])?;
        ints(&w, "p", &p)?;
        ints(&w, "i", &rows)?;
        doubles(&w, "x", &values)?;
        let vectors = root.create_group("vectors").map_err(|e| ("vectors", e))?;
        doubles(&vectors, "q", local.q.as_slice())?;
        doubles(&vectors, "mu", local.mu.as_slice())?;
        if let Some((u, r)) = &local.solution {
            let solution = file.create_group("solution").map_err(|e| ("/solution", e))?;
            doubles(&solution, "u", u.as_slice())?;
            doubles(&solution, "r", r.as_slice())?;
        }
        Ok(())
    };
    write().map_err(|(field, e)| h5(path, field, e))
}

/// Reads an FCLIB local problem (and its `/solution` when present) from `path`. Errors name the
/// file and the dataset: a file that is not HDF5 or is truncated, a missing dataset, sizes that
/// disagree, indices out of range, a W that is not symmetric or not positive on its diagonal,
/// a negative or non-finite μ.
pub fn read_fclib(path: &Path) -> Result<FclibLocal, ProblemFileError> {
    if let Err(source) = std::fs::metadata(path) {
        return Err(ProblemFileError::Read { path: path.to_path_buf(), source });
    }
    let file = hdf5::File::open(path).map_err(|e| h5(path, "file (not an HDF5 file, or truncated)", e))?;
    if !file.link_exists("fclib_local") {
        let global = file.link_exists("fclib_global") || file.link_exists("fclib_global_rolling");
        return Err(invalid(
            path,
            if global {
                "/fclib_local: the file holds a global FCLIB problem; only the local form is read".into()
            } else {
                "/fclib_local: no local FCLIB problem in the file".into()
            },
        ));
    }
    let ints = |name: &str| -> Result<Vec<i64>, ProblemFileError> {
        file.dataset(name).and_then(|d| d.read_raw::<i64>()).map_err(|e| h5(path, name, e))
    };
    let doubles = |name: &str| -> Result<Vec<f64>, ProblemFileError> {
        file.dataset(name).and_then(|d| d.read_raw::<f64>()).map_err(|e| h5(path, name, e))
    };
    let scalar = |name: &str| -> Result<i64, ProblemFileError> {
        match ints(name)?[..] {
            [x] => Ok(x),
            ref other => Err(invalid(path, format!("{name}: {} entries, expected 1", other.len()))),
        }
    };
    let spacedim = scalar("fclib_local/spacedim")?;
    if spacedim != 3 {
        return Err(invalid(
            path,
            format!("fclib_local/spacedim = {spacedim}: only 3-D contact problems are read"),
        ));
    }
    if file.link_exists("fclib_local/V") || file.link_exists("fclib_local/R") {
        return Err(invalid(path, "fclib_local/V, R: mixed problems (equality rows) are not read".into()));
    }
    let (m, n, nz) = (scalar("fclib_local/W/m")?, scalar("fclib_local/W/n")?, scalar("fclib_local/W/nz")?);
    if m != n || m < 0 || m % 3 != 0 {
        return Err(invalid(
            path,
            format!("fclib_local/W: {m} × {n}, expected square with 3 rows per contact"),
        ));
    }
    let m = m as usize;
    let (p, i, x) = (ints("fclib_local/W/p")?, ints("fclib_local/W/i")?, doubles("fclib_local/W/x")?);
    let index = |v: i64, bound: usize, field: &str| {
        usize::try_from(v)
            .ok()
            .filter(|&v| v < bound)
            .ok_or_else(|| invalid(path, format!("fclib_local/W/{field}: index {v} outside 0..{bound}")))
    };
    let mut w = DMatrix::zeros(m, m);
    if nz == -1 {
        if p.len() != m + 1 || i.len() != x.len() {
            return Err(invalid(
                path,
                format!(
                    "fclib_local/W/p: {} pointers for {m} columns, i has {}, x has {}",
                    p.len(),
                    i.len(),
                    x.len()
                ),
            ));
        }
        for j in 0..m {
            let (start, end) = (p[j], p[j + 1]);
            if start < 0 || end < start || end as usize > x.len() {
                return Err(invalid(
                    path,
                    format!("fclib_local/W/p: column {j} spans {start}..{end} of {}", x.len()),
                ));
            }
            for k in start as usize..end as usize {
                w[(index(i[k], m, "i")?, j)] = x[k];
            }
        }
    } else if nz >= 0 {
        let count = nz as usize;
        if p.len() != count || i.len() != count || x.len() < count {
            return Err(invalid(
                path,
                format!(
                    "fclib_local/W: nz = {nz} triplets, but p has {}, i {}, x {}",
                    p.len(),
                    i.len(),
                    x.len()
                ),
            ));
        }
        for k in 0..count {
            w[(index(i[k], m, "i")?, index(p[k], m, "p")?)] += x[k];
        }
    } else {
        return Err(invalid(path, format!("fclib_local/W/nz = {nz}: compressed rows are not read")));
    }
    let q = doubles("fclib_local/vectors/q")?;
    let mu = doubles("fclib_local/vectors/mu")?;
    if q.len() != m || 3 * mu.len() != m {
        return Err(invalid(
            path,
            format!("fclib_local/vectors: q has {} entries and mu {}, W is {m} × {m}", q.len(), mu.len()),
        ));
    }
    if let Some(k) = mu.iter().position(|&v| !(v >= 0.0 && v.is_finite())) {
        return Err(invalid(path, format!("fclib_local/vectors/mu: contact {k} has μ = {}", mu[k])));
    }
    let solution = if file.link_exists("solution/u") && file.link_exists("solution/r") {
        let (u, r) = (doubles("solution/u")?, doubles("solution/r")?);
        if u.len() != m || r.len() != m {
            return Err(invalid(
                path,
                format!("solution: u has {} entries and r {}, expected {m}", u.len(), r.len()),
            ));
        }
        Some((DVector::from_vec(u), DVector::from_vec(r)))
    } else {
        None
    };
    let local = FclibLocal { w, q: DVector::from_vec(q), mu: DVector::from_vec(mu), solution };
    validate_problem(&local.problem()).map_err(|reason| invalid(path, format!("fclib_local: {reason}")))?;
    Ok(local)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("gelenk_fclib_{}_{name}.hdf5", std::process::id()))
    }

    /// Two contacts, W symmetric positive definite with a −0.0 entry.
    fn sample() -> FclibLocal {
        let w = DMatrix::from_fn(6, 6, |i, j| {
            if i == j {
                2.0 + i as f64 / 7.0
            } else if (i + j) % 4 == 1 {
                0.1 / (1 + i + j) as f64
            } else if i + j == 4 {
                -0.0
            } else {
                0.0
            }
        });
        FclibLocal {
            w,
            q: DVector::from_vec(vec![-0.3, 0.1, 1e-17, 0.2, -0.0, 0.7]),
            mu: DVector::from_vec(vec![0.6, 0.0]),
            solution: Some((DVector::from_element(6, 0.25), DVector::from_element(6, -1.5e-300))),
        }
    }

    fn bits(x: &[f64]) -> Vec<u64> {
        x.iter().map(|v| v.to_bits()).collect()
    }

    #[test]
    fn a_written_problem_reads_back_to_the_last_bit() {
        let path = temp("roundtrip");
        let local = sample();
        write_fclib(&path, &local).unwrap();
        let back = read_fclib(&path).unwrap();
        std::fs::remove_file(&path).ok();
        assert_eq!(bits(back.w.as_slice()), bits(local.w.as_slice()));
        assert_eq!(bits(back.q.as_slice()), bits(local.q.as_slice()));
        assert_eq!(bits(back.mu.as_slice()), bits(local.mu.as_slice()));
        assert_eq!(back.solution, local.solution);
        let problem = back.problem();
        assert_eq!(fclib_of(&problem).unwrap().w, local.w);
    }

    #[test]
    fn the_committed_sample_reads_as_the_committed_problem_writes() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/problems");
        let problem = super::super::read_problem(&root.join("stack2-cone-0000")).unwrap();
        let sample = read_fclib(&root.join("formats/stack2-cone-0000.hdf5")).unwrap();
        let written = fclib_of(&problem).unwrap();
        assert_eq!(bits(sample.w.as_slice()), bits(written.w.as_slice()));
        assert_eq!(bits(sample.q.as_slice()), bits(written.q.as_slice()));
        assert_eq!(sample.mu, written.mu);
    }

    #[test]
    fn bad_files_are_typed_errors_naming_the_file_and_the_dataset() {
        let path = temp("bad");
        let message = |local: &FclibLocal| {
            write_fclib(&path, local).unwrap();
            read_fclib(&path).unwrap_err().to_string()
        };
        let mut unsymmetric = sample();
        unsymmetric.w[(0, 1)] = 5.0;
        let text = message(&unsymmetric);
        assert!(text.contains(path.to_str().unwrap()) && text.contains("not symmetric"), "{text}");
        let mut negative = sample();
        negative.mu[1] = -0.1;
        assert!(message(&negative).contains("fclib_local/vectors/mu: contact 1"), "{}", message(&negative));
        // Mismatched dimensions: μ of a third contact, written by hand.
        write_fclib(&path, &sample()).unwrap();
        {
            let file = hdf5::File::open_rw(&path).unwrap();
            file.unlink("fclib_local/vectors/mu").unwrap();
            file.group("fclib_local/vectors")
                .unwrap()
                .new_dataset_builder()
                .with_data(&[0.1, 0.2, 0.3][..])
                .create("mu")
                .unwrap();
        }
        let text = read_fclib(&path).unwrap_err().to_string();
        assert!(text.contains("fclib_local/vectors: q has 6 entries and mu 3"), "{text}");
        // A truncated file and a file that is not HDF5.
        write_fclib(&path, &sample()).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        let text = read_fclib(&path).unwrap_err().to_string();
        assert!(text.contains(path.to_str().unwrap()), "{text}");
        std::fs::write(&path, b"not hdf5 at all").unwrap();
        assert!(read_fclib(&path).unwrap_err().to_string().contains("not an HDF5 file"));
        std::fs::remove_file(&path).ok();
        assert!(matches!(read_fclib(&path), Err(ProblemFileError::Read { .. })));
    }
}
