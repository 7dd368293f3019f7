//! `gelenk corpus build`: steps the scenes of [`corpus_scenes`], keeps the problems of selected
//! steps, solves each for a reference certified by gelenk's residuals, and writes each problem
//! in every format that poses it, with an index (`index.json`, `index.csv`).
//!
//! A problem's directory `OUT/FAMILY/SCENE-sNNNN/` holds `problem.json` (gelenk's form, A
//! sparse), `reference.json` ([`Reference`]), `problem.cbf` (up to [`CBF_MAX_ROWS`] rows),
//! `problem.qps` (frictionless and pyramid problems) and, with the `fclib` feature,
//! `problem.hdf5` (problems of contact blocks alone with Coulomb cones).

use super::corpus_scenes::{corpus_scenes, corpus_world, CorpusScene};
use super::{
    formulation, problem_to_json_sparse, qp_of, run_solver, write_cbf, write_qps, CorpusSolver,
    ResidualRecord, SolveStatus, CBF_MAX_ROWS,
};
use super::{pivoted_cholesky, qp_matrix};
use crate::constraints::{ConstraintProblem, RowLaw};
use crate::solvers::{residuals, ConstraintSolver, NewtonSolver};
use nalgebra::DVector;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The certified-residual tolerance (m/s) a reference solution must meet.
pub const REFERENCE_TOLERANCE: f64 = 1e-6;
/// Rows up to which clarabel computes the reference (its KKT system is dense in A).
pub const CLARABEL_REFERENCE_ROWS: usize = 1000;
/// Rows up to which the index estimates the conditioning (a dense pivoted Cholesky of A + R).
pub const CONDITIONING_ROWS: usize = 1500;
/// `format` field of `reference.json`.
pub const REFERENCE_FORMAT: &str = "gelenk-reference-solution";
/// Name of the reference-solution file.
pub const REFERENCE_FILE: &str = "reference.json";
/// Name of the index files (`.json`, `.csv`).
pub const INDEX_FILE: &str = "index";

/// A problem's reference solution (`reference.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Reference {
    /// [`REFERENCE_FORMAT`].
    pub format: String,
    /// The solver that found it: `clarabel` or `newton`.
    pub solver: String,
    /// Its certified residual (m/s): the convex (Anitescu) problem's, which both solve.
    pub certified: f64,
    /// The exact complementarity residual (m/s) of the same impulses (small when no contact
    /// slides: then it also solves the exact Coulomb problem, FCLIB's).
    pub exact: f64,
    /// All residuals.
    pub residuals: ResidualRecord,
    /// Solver time (s).
    pub time: f64,
    /// Impulses λ (N·s).
    pub lambda: Vec<f64>,
    /// Row velocities w = (A + R)λ + b (m/s).
    pub w: Vec<f64>,
}

/// One problem of the corpus, as the index lists it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IndexEntry {
    /// Directory relative to the corpus root (`FAMILY/SCENE-sNNNN`).
    pub id: String,
    /// Family.
    pub family: String,
    /// Scene name.
    pub scene: String,
    /// Step index.
    pub step: usize,
    /// Time step (s).
    pub h: f64,
    /// Rows.
    pub rows: usize,
    /// Contact blocks.
    pub contacts: usize,
    /// `frictionless-qp`, `pyramid-qp` or `cone-socp`.
    pub formulation: String,
    /// Numerical rank of A + R (pivoted Cholesky; up to [`CONDITIONING_ROWS`] rows).
    pub rank: Option<usize>,
    /// Conditioning estimate of A + R on its range ([`super::PivotedCholesky::condition_estimate`]).
    pub conditioning: Option<f64>,
    /// Degeneracy: unilateral rows weakly active at the reference (λ and w both below 1e-9 m/s
    /// in velocity units, λ scaled by A_ii + R_ii).
    pub degenerate_rows: usize,
    /// The reference's solver.
    pub reference: String,
    /// The reference's certified residual (m/s).
    pub certified: f64,
    /// The reference's exact residual (m/s).
    pub exact: f64,
    /// Files written.
    pub files: Vec<String>,
}

/// What `corpus build` should do.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildOptions {
    /// Output directory.
    pub out: PathBuf,
    /// The models directory (scene files, URDFs).
    pub models: PathBuf,
    /// Scene names to build (empty: all).
    pub only: Vec<String>,
    /// Problems with fewer rows are skipped.
    pub min_rows: usize,
}

/// What a build wrote and skipped.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildSummary {
    /// The index.
    pub entries: Vec<IndexEntry>,
    /// Problems kept but not written: no reference met [`REFERENCE_TOLERANCE`] (scene, step).
    pub uncertified: Vec<(String, usize)>,
    /// Wall-clock time (s).
    pub seconds: f64,
}

/// The reference solution of `problem`: clarabel up to [`CLARABEL_REFERENCE_ROWS`] rows when it
/// certifies, else the Newton solver; `None` when neither meets [`REFERENCE_TOLERANCE`].
pub fn reference_solution(problem: &ConstraintProblem) -> Option<Reference> {
    let record = |solver: &str, lambda: &DVector<f64>, seconds: f64| {
        let mut w = DVector::zeros(problem.rows());
        let r = residuals(problem, lambda, &mut w);
        Reference {
            format: REFERENCE_FORMAT.to_string(),
            solver: solver.to_string(),
            certified: r.convex(),
            exact: r.exact(),
            residuals: ResidualRecord::from(&r),
            time: seconds,
            lambda: lambda.iter().copied().collect(),
            w: w.iter().copied().collect(),
        }
    };
    if problem.rows() <= CLARABEL_REFERENCE_ROWS {
        let (answer, elapsed) = run_solver(CorpusSolver::Clarabel, problem);
        if answer.status == SolveStatus::Solved {
            let reference = record("clarabel", &DVector::from_vec(answer.lambda), elapsed.as_secs_f64());
            if reference.certified <= REFERENCE_TOLERANCE {
                return Some(reference);
            }
        }
    }
    let mut newton = NewtonSolver::default();
    newton.set_certified_tolerance(1e-3 * REFERENCE_TOLERANCE);
    let mut lambda = DVector::zeros(problem.rows());
    let start = Instant::now();
    newton.solve(problem, &mut lambda).ok()?;
    let reference = record("newton", &lambda, start.elapsed().as_secs_f64());
    (reference.certified <= REFERENCE_TOLERANCE).then_some(reference)
}

/// Unilateral rows where both λ (scaled by the row's diagonal) and w are below 1e-9 m/s.
pub fn degenerate_rows(problem: &ConstraintProblem, reference: &Reference) -> usize {
    let tau = 1e-9;
    (0..problem.rows())
        .filter(|&i| problem.laws[i] == RowLaw::Unilateral)
        .filter(|&i| {
            let diagonal = problem.delassus_entry(i, i) + problem.regularization[i];
            (reference.lambda[i] * diagonal).abs() <= tau && reference.w[i].abs() <= tau
        })
        .count()
}

fn write_err(path: &Path, e: impl std::fmt::Display) -> String {
    format!("{}: {e}", path.display())
}

/// Writes one problem's directory and returns its index entry.
fn write_entry(
    root: &Path,
    scene: &CorpusScene,
    step: usize,
    h: f64,
    problem: &ConstraintProblem,
    reference: &Reference,
) -> Result<IndexEntry, String> {
    let id = format!("{}/{}-s{step:04}", scene.family, scene.name);
    let dir = root.join(&id);
    std::fs::create_dir_all(&dir).map_err(|e| write_err(&dir, e))?;
    let mut files = Vec::new();
    let mut put = |name: &str, bytes: &[u8]| -> Result<(), String> {
        let path = dir.join(name);
        std::fs::write(&path, bytes).map_err(|e| write_err(&path, e))?;
        files.push(name.to_string());
        Ok(())
    };
    put(super::PROBLEM_FILE, problem_to_json_sparse(problem)?.as_bytes())?;
    put(REFERENCE_FILE, serde_json::to_string(reference).map_err(|e| e.to_string())?.as_bytes())?;
    if problem.rows() <= CBF_MAX_ROWS {
        write_cbf(&dir.join("problem.cbf"), problem).map_err(|e| e.to_string())?;
        files.push("problem.cbf".into());
    }
    let form = formulation(problem);
    if form != "cone-socp" {
        if let Some(qp) = qp_of(problem) {
            let name = format!("{}-s{step:04}", scene.name);
            write_qps(&dir.join("problem.qps"), &name, &qp).map_err(|e| e.to_string())?;
            files.push("problem.qps".into());
        }
    }
    #[cfg(feature = "fclib")]
    if let Ok(mut local) = super::fclib_of(problem) {
        if reference.exact <= REFERENCE_TOLERANCE {
            local.solution =
                Some((DVector::from_vec(reference.w.clone()), DVector::from_vec(reference.lambda.clone())));
        }
        super::write_fclib(&dir.join("problem.hdf5"), &local).map_err(|e| e.to_string())?;
        files.push("problem.hdf5".into());
    }
    let (rank, conditioning) = if problem.rows() <= CONDITIONING_ROWS {
        let f = pivoted_cholesky(&qp_matrix(problem));
        (Some(f.rank()), Some(f.condition_estimate()))
    } else {
        (None, None)
    };
    Ok(IndexEntry {
        id,
        family: scene.family.to_string(),
        scene: scene.name.to_string(),
        step,
        h,
        rows: problem.rows(),
        contacts: problem.contacts.len(),
        formulation: form.to_string(),
        rank,
        conditioning,
        degenerate_rows: degenerate_rows(problem, reference),
        reference: reference.solver.clone(),
        certified: reference.certified,
        exact: reference.exact,
        files,
    })
}

/// The index as CSV (one header line, one line per problem).
pub fn index_csv(entries: &[IndexEntry]) -> String {
    let mut s = String::from(
        "id,family,scene,step,h,rows,contacts,formulation,rank,conditioning,degenerate_rows,reference,certified,exact,files\n",
    );
    let opt = |x: Option<String>| x.unwrap_or_default();
    for e in entries {
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{:e},{:e},{}\n",
            e.id,
            e.family,
            e.scene,
            e.step,
            e.h,
            e.rows,
            e.contacts,
            e.formulation,
            opt(e.rank.map(|r| r.to_string())),
            opt(e.conditioning.map(|c| format!("{c:e}"))),
            e.degenerate_rows,
            e.reference,
            e.certified,
            e.exact,
            e.files.join(" ")
        ));
    }
    s
}

/// Reads a corpus's `index.json`.
pub fn read_index(root: &Path) -> Result<Vec<IndexEntry>, super::ProblemFileError> {
    let path = root.join(format!("{INDEX_FILE}.json"));
    let text = super::read_text(&path)?;
    serde_json::from_str(&text).map_err(|source| super::ProblemFileError::Parse {
        path,
        what: "corpus index",
        source,
    })
}

/// Builds the corpus (see the module documentation); `progress` is called after each problem
/// written. Stops at the first scene that cannot be loaded or stepped, or file that cannot be
/// written.
pub fn build_corpus(
    options: &BuildOptions,
    mut progress: impl FnMut(&IndexEntry),
) -> Result<BuildSummary, String> {
    let start = Instant::now();
    let mut summary = BuildSummary::default();
    let scenes: Vec<CorpusScene> = corpus_scenes()
        .into_iter()
        .filter(|s| options.only.is_empty() || options.only.iter().any(|o| o == s.name))
        .collect();
    if scenes.is_empty() {
        return Err(format!("no corpus scene is named {}", options.only.join(", ")));
    }
    for scene in &scenes {
        let mut world =
            corpus_world(&scene.source, &options.models).map_err(|e| format!("{}: {e}", scene.name))?;
        for step in 0..scene.steps {
            let w = world.prepare().map_err(|e| format!("{} step {step}: {e}", scene.name))?;
            let h = w.options().dt;
            w.step().map_err(|e| format!("{} step {step}: {e}", scene.name))?;
            if (step + 1) % scene.every != 0 {
                continue;
            }
            let problem = w.problem();
            if problem.rows() < options.min_rows {
                continue;
            }
            match reference_solution(problem) {
                Some(reference) => {
                    let entry = write_entry(&options.out, scene, step, h, problem, &reference)?;
                    progress(&entry);
                    summary.entries.push(entry);
                }
                None => summary.uncertified.push((scene.name.to_string(), step)),
            }
        }
    }
    let json = serde_json::to_string_pretty(&summary.entries).map_err(|e| e.to_string())?;
    for (ext, text) in [("json", json), ("csv", index_csv(&summary.entries))] {
        let path = options.out.join(format!("{INDEX_FILE}.{ext}"));
        std::fs::write(&path, text).map_err(|e| write_err(&path, e))?;
    }
    summary.seconds = start.elapsed().as_secs_f64();
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scene_names_are_unique_and_every_family_is_there() {
        let scenes = corpus_scenes();
        let mut names: Vec<&str> = scenes.iter().map(|s| s.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), scenes.len());
        for family in ["stack", "hard", "pile", "ragdoll", "ragdoll-crowd", "humanoid", "vehicle", "grid"] {
            assert!(scenes.iter().any(|s| s.family == family), "{family}");
        }
    }
}
