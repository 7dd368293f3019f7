//! `gelenk corpus build` (step the corpus scenes, write every problem in every format with a
//! certified reference and an index) and `gelenk corpus bench` (solve a corpus with several
//! solvers, print and write a qpbenchmark-style table).

use gelenk::io::problem::{self, BenchOptions, BenchSolver, BuildOptions, IndexEntry};
use std::path::PathBuf;

#[derive(clap::Subcommand)]
pub enum CorpusCommand {
    /// Step the fixed list of corpus scenes and write their problems (problem.json, problem.cbf,
    /// problem.qps for QPs, problem.hdf5 with the `fclib` feature), each with a reference
    /// solution certified by gelenk's residuals, and index.json / index.csv.
    Build(BuildArgs),
    /// Solve every problem of a corpus (its index.json) with each solver and print a table per
    /// family: success rate at residuals 1e-3 / 1e-6 / 1e-9 m/s, shifted geometric mean of
    /// time, worst residual; also written as CSV.
    Bench(BenchArgs),
    /// Write one problem (a problem.json or its directory) in a standard format chosen by the
    /// output's extension: .cbf (CBF), .qps (QPS; frictionless and pyramid problems), .hdf5
    /// (FCLIB; with the `fclib` feature, contact-only problems with cones).
    Convert(ConvertArgs),
}

// Arguments of `gelenk corpus convert`.
#[derive(clap::Args)]
pub struct ConvertArgs {
    /// problem.json, or a directory holding one.
    problem: PathBuf,
    /// Output file: .cbf, .qps or .hdf5.
    #[arg(long)]
    out: PathBuf,
}

// Arguments of `gelenk corpus build`.
#[derive(clap::Args)]
pub struct BuildArgs {
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// The models directory (scene files and URDFs).
    #[arg(long, default_value = "models")]
    models: PathBuf,
    /// Build only these scenes (comma-separated names, as docs/corpus.md lists them).
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Skip problems with fewer rows.
    #[arg(long, default_value_t = 10)]
    min_rows: usize,
}

// Arguments of `gelenk corpus bench`.
#[derive(clap::Args)]
pub struct BenchArgs {
    /// The corpus directory (with index.json).
    dir: PathBuf,
    /// Solvers (comma-separated): clarabel, pgs, newton, lemke.
    #[arg(long, value_delimiter = ',', default_value = "clarabel,pgs,newton,lemke")]
    solvers: Vec<String>,
    /// Only problems with at most this many rows.
    #[arg(long)]
    max_rows: Option<usize>,
    /// Only these families (comma-separated).
    #[arg(long, value_delimiter = ',')]
    families: Vec<String>,
    /// Only every N-th problem of the index (a subset for a quick run).
    #[arg(long, default_value_t = 1)]
    every: usize,
    /// PGS sweeps.
    #[arg(long, default_value_t = BenchOptions::default().pgs_sweeps)]
    pgs_sweeps: usize,
    /// Lemke's method is skipped (counted as failed) above this many rows.
    #[arg(long, default_value_t = BenchOptions::default().lemke_max_rows)]
    lemke_max_rows: usize,
    /// Time (s) charged to a run that does not reach 1e-3 m/s.
    #[arg(long, default_value_t = BenchOptions::default().time_limit)]
    time_limit: f64,
    /// CSV output (default: DIR/bench.csv).
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Per-run CSV output (one line per problem and solver: residual, time, note).
    #[arg(long)]
    runs_csv: Option<PathBuf>,
}

/// Runs a `gelenk corpus` command.
pub fn run(command: &CorpusCommand) -> Result<(), String> {
    match command {
        CorpusCommand::Build(args) => build(args),
        CorpusCommand::Bench(args) => bench(args),
        CorpusCommand::Convert(args) => convert(args),
    }
}

fn convert(args: &ConvertArgs) -> Result<(), String> {
    let problem = problem::read_problem(&args.problem).map_err(|e| e.to_string())?;
    let out = &args.out;
    let extension = out.extension().and_then(|e| e.to_str()).unwrap_or("");
    match extension {
        "cbf" => problem::write_cbf(out, &problem).map_err(|e| e.to_string())?,
        "qps" => {
            let qp = problem::qp_of(&problem).ok_or_else(|| {
                format!("{}: the problem has friction cones: no QP form", args.problem.display())
            })?;
            let name = out
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("problem")
                .replace(char::is_whitespace, "_");
            problem::write_qps(out, &name, &qp).map_err(|e| e.to_string())?;
        }
        #[cfg(feature = "fclib")]
        "hdf5" | "h5" => {
            let local =
                problem::fclib_of(&problem).map_err(|e| format!("{}: {e}", args.problem.display()))?;
            problem::write_fclib(out, &local).map_err(|e| e.to_string())?;
        }
        #[cfg(not(feature = "fclib"))]
        "hdf5" | "h5" => return Err("FCLIB files need gelenk built with the `fclib` feature".into()),
        other => return Err(format!("{}: unknown extension \"{other}\" (cbf, qps, hdf5)", out.display())),
    }
    println!("{}: {} rows written to {}", args.problem.display(), problem.rows(), out.display());
    Ok(())
}

fn build(args: &BuildArgs) -> Result<(), String> {
    let options = BuildOptions {
        out: args.out.clone(),
        models: args.models.clone(),
        only: args.only.clone(),
        min_rows: args.min_rows,
    };
    let summary = problem::build_corpus(&options, |e: &IndexEntry| {
        println!(
            "{}: {} rows, {}, reference {} {:.1e} m/s",
            e.id, e.rows, e.formulation, e.reference, e.certified
        );
    })?;
    let rows = summary.entries.iter().map(|e| e.rows);
    println!(
        "wrote {} problems ({} to {} rows) to {} in {:.0} s; {} kept steps had no certified reference",
        summary.entries.len(),
        rows.clone().min().unwrap_or(0),
        rows.max().unwrap_or(0),
        args.out.display(),
        summary.seconds,
        summary.uncertified.len()
    );
    for (scene, step) in &summary.uncertified {
        println!("  uncertified: {scene} step {step}");
    }
    Ok(())
}

fn bench(args: &BenchArgs) -> Result<(), String> {
    let solvers: Vec<BenchSolver> = args.solvers.iter().map(|s| s.parse()).collect::<Result<_, _>>()?;
    let options = BenchOptions {
        pgs_sweeps: args.pgs_sweeps,
        lemke_max_rows: args.lemke_max_rows,
        time_limit: args.time_limit,
    };
    let index = problem::read_index(&args.dir).map_err(|e| e.to_string())?;
    let chosen: Vec<&IndexEntry> = index
        .iter()
        .filter(|e| args.max_rows.is_none_or(|m| e.rows <= m))
        .filter(|e| args.families.is_empty() || args.families.contains(&e.family))
        .step_by(args.every.max(1))
        .collect();
    let mut runs = Vec::new();
    for entry in &chosen {
        let problem = problem::read_problem(&args.dir.join(&entry.id)).map_err(|e| e.to_string())?;
        for &solver in &solvers {
            let run = problem::bench_run(&entry.id, &entry.family, &problem, solver, &options);
            eprintln!(
                "{} {}: {} in {:.3} ms",
                entry.id,
                solver.name(),
                run.residual.map_or_else(|| run.note.clone().unwrap_or_default(), |r| format!("{r:.1e} m/s")),
                1e3 * run.time
            );
            runs.push(run);
        }
    }
    let table = problem::bench_table(&runs, &solvers, args.time_limit);
    print!("{}", problem::bench_text(&table));
    let csv = args.csv.clone().unwrap_or_else(|| args.dir.join("bench.csv"));
    std::fs::write(&csv, problem::bench_csv(&table)).map_err(|e| format!("{}: {e}", csv.display()))?;
    if let Some(path) = &args.runs_csv {
        std::fs::write(path, problem::runs_csv(&runs)).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    println!("{} problems, table written to {}", chosen.len(), csv.display());
    Ok(())
}
