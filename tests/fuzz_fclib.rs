//! Fuzzing of the FCLIB reader (`gelenk::io::problem::read_fclib`, the `fclib` feature; see
//! `docs/reliability.md`), two targets on the harness of `fuzz_support`:
//!
//! - `fuzz_fclib_content`: structure-aware. Each input is a plan (`fuzz_support::fclib`) from
//!   which `hdf5-pure` writes a well-formed HDF5 file with hostile FCLIB content (sizes that
//!   disagree, W unsymmetric or with indices out of range, non-finite numbers, missing, extra,
//!   mistyped datasets). Reading it must give what the plan implies: the problem
//!   to the last bit when every fault is one FCLIB allows, a typed error when one fault alone
//!   makes the file invalid, and otherwise either a typed error or a consistent problem.
//! - `fuzz_fclib_bytes`: truncated and corrupted copies of valid files
//!   (`tests/fuzz_corpus/fclib/`): the damage must be a typed error.
//!
//! HDF5 is parsed by `hdf5-pure`, in Rust and in this process: a panic in it fails the target
//! like one in gelenk. The files of `tests/data/fclib/` (libhdf5's own crash and hang inputs,
//! and objects `hdf5-pure` does not write: soft and external links, external raw data, a huge
//! unwritten dataset) are read by `tests_data_files_are_typed_errors`.
//!
//! Every error must name the file; every problem read must be finite, of consistent sizes, and,
//! when small, solved by every corpus solver to finite numbers. The file under test is
//! `<target tmp>/fuzz-fclib/{content,bytes}-<process id>.hdf5`, removed when the target ends
//! well: after a case that kills the process, it holds that case's input.
//!
//! `cargo test --profile ci --features fclib --test fuzz_fclib`; an hour per target:
//! `GELENK_FUZZ_SECONDS=3600 GELENK_FUZZ_SEED=random cargo test --profile ci --features fclib --test fuzz_fclib -- --test-threads 1`.

#![cfg(feature = "fclib")]

mod fuzz_support;

use fuzz_support::fclib::{write_case, Expect};
use fuzz_support::{finite, fuzz, Verdict};
use gelenk::io::problem::{read_fclib, run_solver, CorpusSolver, FclibLocal, ProblemFileError};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;

/// Budget of one case: writing and reading a file of a few kB takes milliseconds; a declared
/// problem of 6000 rows, validated as dense, well under a second.
const CASE: Duration = Duration::from_secs(10);
/// Largest problem (rows) that a case solves with every corpus solver.
const SOLVED_ROWS: usize = 120;

/// Kinds of faults of a plan, as tokens the mutator inserts (kind, dataset, value).
const PLAN_TOKENS: &[&str] = &[
    "\u{0}\u{0}\u{0}",
    "\u{1}\u{3}\u{1}",
    "\u{1}\u{1}\u{8}",
    "\u{2}\u{3}\u{0}",
    "\u{3}\u{2}\u{1}",
    "\u{4}\u{4}\u{7}",
    "\u{5}\u{3}\u{2}",
    "\u{6}\u{d}\u{0}",
    "\u{7}\u{6}\u{0}",
    "\u{8}\u{0}\u{2}",
    "\u{9}\u{2}\u{1}",
    "\u{a}\u{3}\u{1}",
    "\u{b}\u{0}\u{0}",
    "\u{c}\u{0}\u{2}",
    "\u{d}\u{0}\u{0}",
    "\u{e}\u{0}\u{0}",
    "\u{f}\u{0}\u{2}",
];

/// Byte patterns of HDF5 files: the signature, undefined addresses, huge and negative sizes.
const HDF5_TOKENS: &[&str] = &[
    "HDF\r\n\u{1a}\n",
    "\u{7f}\u{7f}\u{7f}\u{7f}\u{7f}\u{7f}\u{7f}\u{7f}",
    "\u{0}\u{0}\u{0}\u{0}\u{0}\u{0}\u{0}\u{0}",
    "\u{1}\u{0}\u{0}\u{0}",
    "TREE",
    "HEAP",
    "SNOD",
    "OHDR",
    "FRHP",
    "BTHD",
    "\u{3}\u{0}\u{0}\u{0}",
];

/// The directory of the files under test.
fn workdir() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-fclib");
        std::fs::create_dir_all(&dir).unwrap();
        dir
    })
}

/// The file a target writes its cases to, one per process (runs may share the target directory).
fn case_file(target: &str, dir: &Path) -> PathBuf {
    dir.join(format!("{target}-{}.hdf5", std::process::id()))
}

/// A problem read: sizes that agree, finite numbers, and finite answers of every corpus solver
/// when it has at most [`SOLVED_ROWS`] rows.
fn check_problem(local: &FclibLocal) -> Verdict {
    let m = local.q.len();
    if local.w.shape() != (m, m) || 3 * local.mu.len() != m {
        return Err(format!("W {:?}, q {m}, μ {} read as Ok", local.w.shape(), local.mu.len()));
    }
    finite("W", local.w.as_slice())?;
    finite("q", local.q.as_slice())?;
    finite("μ", local.mu.as_slice())?;
    if let Some((u, r)) = &local.solution {
        if u.len() != m || r.len() != m {
            return Err(format!("a solution of {} and {} entries for {m} rows read as Ok", u.len(), r.len()));
        }
        finite("solution u", u.as_slice())?;
        finite("solution r", r.as_slice())?;
    }
    if m <= SOLVED_ROWS {
        let problem = local.problem();
        for kind in CorpusSolver::ALL {
            let (record, _) = run_solver(kind, &problem);
            finite(&format!("{} impulses", kind.name()), &record.lambda)?;
            finite(&format!("{} velocities", kind.name()), &record.w)?;
        }
    }
    Ok(())
}

/// An error: it names the file.
fn check_error(error: &ProblemFileError, path: &Path) -> Verdict {
    let text = error.to_string();
    if text.contains(&path.display().to_string()) {
        Ok(())
    } else {
        Err(format!("an error that does not name the file: {text}"))
    }
}

fn bits(x: &[f64]) -> Vec<u64> {
    x.iter().map(|v| v.to_bits()).collect()
}

fn same(a: &FclibLocal, b: &FclibLocal) -> bool {
    let solution =
        |l: &FclibLocal| l.solution.as_ref().map(|(u, r)| (bits(u.as_slice()), bits(r.as_slice())));
    a.w.shape() == b.w.shape()
        && bits(a.w.as_slice()) == bits(b.w.as_slice())
        && bits(a.q.as_slice()) == bits(b.q.as_slice())
        && bits(a.mu.as_slice()) == bits(b.mu.as_slice())
        && solution(a) == solution(b)
}

fn content(plan: &[u8]) -> Verdict {
    let path = case_file("content", workdir());
    let expect = write_case(plan, &path);
    match (read_fclib(&path), expect) {
        (Ok(local), Expect::Local(want)) if !same(&local, &want) => {
            Err(format!("a valid file read as another problem: {local:?}, written {want:?}"))
        }
        (Ok(local), Expect::Local(_) | Expect::Either) => check_problem(&local),
        (Ok(_), Expect::Error(why)) => Err(format!("a file with {why} read as Ok")),
        (Err(e), Expect::Local(_)) => Err(format!("a valid file refused: {e}")),
        (Err(e), Expect::Error(_) | Expect::Either) => check_error(&e, &path),
    }
}

fn bytes(input: &[u8]) -> Verdict {
    let path = case_file("bytes", workdir());
    std::fs::write(&path, input).map_err(|e| format!("{}: {e}", path.display()))?;
    match read_fclib(&path) {
        Ok(local) => check_problem(&local),
        Err(e) => check_error(&e, &path),
    }
}

#[test]
fn fuzz_fclib_content() {
    assert!(fuzz("fclib-plan", PLAN_TOKENS, CASE, content) > 0);
    std::fs::remove_file(case_file("content", workdir())).ok();
}

#[test]
fn fuzz_fclib_bytes() {
    assert!(fuzz("fclib", HDF5_TOKENS, CASE, bytes) > 0);
    std::fs::remove_file(case_file("bytes", workdir())).ok();
}

/// Truncated copies of the corpus's valid files: the reader compares the file's length with the
/// end its superblock records, so each is refused, and the error names the file.
#[test]
fn truncated_files_are_typed_errors() {
    let path = case_file("truncated", workdir());
    for (name, bytes) in fuzz_support::corpus("fclib") {
        if read_fclib_bytes(&path, &bytes).is_err() {
            continue; // a found-* file, refused whole
        }
        let stride = (bytes.len() / 300).max(1);
        for len in (0..bytes.len()).step_by(stride).chain(bytes.len() - 8..bytes.len()) {
            match read_fclib_bytes(&path, &bytes[..len]) {
                Ok(_) => panic!("{}: its first {len} bytes read as a problem", name.display()),
                Err(e) => check_error(&e, &path).unwrap(),
            }
        }
    }
    std::fs::remove_file(&path).ok();
}

fn read_fclib_bytes(path: &Path, bytes: &[u8]) -> Result<FclibLocal, ProblemFileError> {
    std::fs::write(path, bytes).unwrap();
    read_fclib(path)
}

/// The files of `tests/data/fclib/`, each with the dataset its error must name: libhdf5's crash
/// and hang inputs (a damaged local heap), links the reader does not follow, raw data outside the
/// file, a dataset declared with 2⁴⁰ entries and never written.
#[test]
fn tests_data_files_are_typed_errors() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fclib");
    let cases = [
        ("libhdf5-1.10.8-crash-local-heap.hdf5", ""),
        ("libhdf5-1.10.8-hang-local-heap.hdf5", ""),
        // hdf5-pure 0.47 reads a soft link of a version 1 group as an undefined address.
        ("link-soft-mu-v1-groups.hdf5", "fclib_local/vectors/mu: "),
        ("link-soft-mu-v2-groups.hdf5", "fclib_local/vectors/mu: missing"),
        ("link-soft-vectors-v1-groups.hdf5", "fclib_local/vectors/"),
        ("link-soft-vectors-v2-groups.hdf5", "fclib_local/vectors/"),
        ("link-external-mu-v1-groups.hdf5", "fclib_local/vectors/mu: missing"),
        ("link-external-mu-v2-groups.hdf5", "fclib_local/vectors/mu: missing"),
        ("external-raw-mu.hdf5", "fclib_local/vectors/mu: "),
        ("unwritten-huge-q.hdf5", "fclib_local/vectors/q: declared with dimensions [1099511627776]"),
    ];
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.ends_with(".hdf5"))
        .collect();
    files.sort();
    let mut named: Vec<String> = cases.iter().map(|(name, _)| name.to_string()).collect();
    named.sort();
    assert_eq!(files, named, "every file of {} has a case here", dir.display());
    for (name, field) in cases {
        let path = dir.join(name);
        let error = read_fclib(&path).expect_err(name);
        check_error(&error, &path).unwrap();
        assert!(error.to_string().contains(field), "{name}: {error}");
    }
}
