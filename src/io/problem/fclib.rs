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
//! ([`fclib_of`] says why not otherwise). [`read_fclib`](super::read_fclib) (in `fclib_read`) also
//! reads W as compressed rows (`nz = −2`, as fclib's own sample file) and triplets (`nz ≥ 0`).
//! HDF5 is read and written in Rust by `hdf5-pure` (no C library); files are written in the
//! format of HDF5 1.8 (version 2 superblock), which libhdf5 1.8 and later, h5py and fclib read.

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
    let (m32, nnz) = (int(m, "W/m")?, int(values.len(), "W/nzmax")?);
    let mut file = hdf5_pure::FileBuilder::new();
    // HDF5 1.8's format (version 2 superblock): what libhdf5 1.8 and later read.
    file.with_libver_bounds(hdf5_pure::LibVer::Earliest, hdf5_pure::LibVer::V18);
    let mut root = file.create_group("fclib_local");
    root.create_dataset("spacedim").with_i32_data(&[3]);
    let mut w = root.create_group("W");
    w.create_dataset("nzmax").with_i32_data(&[nnz]);
    w.create_dataset("m").with_i32_data(&[m32]);
    w.create_dataset("n").with_i32_data(&[m32]);
    w.create_dataset("nz").with_i32_data(&[-1]);
    w.create_dataset("p").with_i32_data(&p);
    w.create_dataset("i").with_i32_data(&rows);
    w.create_dataset("x").with_f64_data(&values);
    root.add_group(w.finish());
    let mut vectors = root.create_group("vectors");
    vectors.create_dataset("q").with_f64_data(local.q.as_slice());
    vectors.create_dataset("mu").with_f64_data(local.mu.as_slice());
    root.add_group(vectors.finish());
    file.add_group(root.finish());
    if let Some((u, r)) = &local.solution {
        let mut solution = file.create_group("solution");
        solution.create_dataset("u").with_f64_data(u.as_slice());
        solution.create_dataset("r").with_f64_data(r.as_slice());
        file.add_group(solution.finish());
    }
    file.write(path).map_err(|e| invalid(path, format!("file: {e}")))
}

#[cfg(test)]
mod tests {
    use super::super::read_fclib;
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

    /// fclib's own sample (`src/tests/data/local_problem_test.hdf5` of the fclib repository,
    /// Apache-2.0): 48 contacts, W as compressed rows, with a solution (r = 0) and guesses.
    #[test]
    fn the_fclib_projects_sample_reads() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/problems/formats");
        let sample = read_fclib(&root.join("fclib-local_problem_test.hdf5")).unwrap();
        assert_eq!((sample.w.shape(), sample.mu.len()), ((144, 144), 48));
        assert!(sample.mu.iter().all(|&mu| mu == 0.7));
        let (u, r) = sample.solution.as_ref().unwrap();
        assert_eq!((u.len(), r.len()), (144, 144));
        // Stored as rows of a W symmetric to rounding (its largest entry is 696).
        assert!((&sample.w - sample.w.transpose()).amax() < 1e-12, "W is not symmetric");
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
            let file = hdf5_pure::File::open_rw(&path).unwrap();
            file.root().delete("fclib_local/vectors/mu").unwrap();
            file.group("fclib_local/vectors")
                .unwrap()
                .create_dataset("mu", |b| {
                    b.with_f64_data(&[0.1, 0.2, 0.3]);
                })
                .unwrap();
            file.commit().unwrap();
        }
        let text = read_fclib(&path).unwrap_err().to_string();
        assert!(text.contains("fclib_local/vectors/mu: 3 entries, expected 2"), "{text}");
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
