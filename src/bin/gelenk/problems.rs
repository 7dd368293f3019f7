//! `gelenk export-problems` (write the constraint problems of a scene's steps) and `gelenk
//! solve-problem` (solve one again, compare with its meta.json).

use gelenk::io::problem::{self, CorpusSolver, ExportKind, ExportOptions, ExportedProblem};
use serde_json::json;
use std::path::PathBuf;

// Arguments of `gelenk export-problems`.
#[derive(clap::Args)]
pub struct ExportArgs {
    /// Built-in scene (box-drop, box-flat, stack2, stack10, sphere-incline, four-bar,
    /// limit-pendulum), or a scene file (.toml) or MJCF file (.xml), stepped by the world with
    /// its own solver chain.
    scene: String,
    /// Number of steps to simulate.
    #[arg(long)]
    steps: usize,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// Friction model of the contact rows: `cone`, `pyramid` (4 facets) or `pyramidN` (3 ≤ N ≤ 64
    /// facets; `pyramid:N` is the same).
    #[arg(long, default_value = "cone")]
    friction: String,
    /// Write only these steps (comma-separated); default: every step that has rows.
    #[arg(long, value_delimiter = ',')]
    only: Vec<usize>,
}

// Arguments of `gelenk solve-problem`.
#[derive(clap::Args)]
pub struct SolveArgs {
    /// problem.json, or a directory holding one.
    file: PathBuf,
    /// Solver.
    #[arg(long, value_parser = ["lemke", "clarabel", "pgs"])]
    solver: String,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// Runs `gelenk export-problems`: one line per problem written, then a total.
pub fn export(args: &ExportArgs) -> Result<(), String> {
    let friction =
        gelenk::io::scene::parse_friction(&args.friction).map_err(|e| format!("--friction: {e}"))?;
    let options = ExportOptions { steps: args.steps, friction, only: args.only.clone() };
    let written = problem::export_problems(&args.scene, &args.out, &options, print_exported)
        .map_err(|e| e.to_string())?;
    if args.steps == 0 {
        println!("no problem written: --steps 0 takes no step");
    } else if written == 0 {
        println!("no problem written: none of the {} steps had constraint rows", args.steps);
    } else {
        println!("wrote {written} problems of {} steps to {}", args.steps, args.out.display());
    }
    Ok(())
}

/// One line per problem; a built-in scene's also gives each corpus solver's outcome.
fn print_exported(exported: &ExportedProblem<'_>) {
    let meta = exported.meta;
    let head = format!(
        "{}: {} rows, {} contacts, {}",
        exported.dir.display(),
        meta.rows,
        meta.contacts,
        meta.formulation
    );
    if exported.kind != ExportKind::BuiltIn {
        println!("{head}");
        return;
    }
    let outcome = |name: &str| {
        let r = &meta.solutions[name];
        match r.certified {
            Some(c) => format!("{name} {} {c:.1e}", r.status),
            None => format!("{name} failed"),
        }
    };
    println!("{head}; {}, {}, {}", outcome("clarabel"), outcome("lemke"), outcome("pgs"));
}

/// Runs `gelenk solve-problem`: the answer as text or JSON, then the verdict against meta.json
/// (an error when the solver fails or does worse than meta.json records).
pub fn solve(args: &SolveArgs) -> Result<(), String> {
    let path = &args.file;
    let kind: CorpusSolver = args.solver.parse()?;
    let resolved = problem::resolve_problem(path, kind).map_err(|e| e.to_string())?;
    let (problem, record, tolerance) = (&resolved.problem, &resolved.record, resolved.tolerance);
    let time_us = resolved.elapsed.as_secs_f64() * 1e6;
    if args.json {
        let out = json!({
            "file": path.display().to_string(), "solver": kind.name(), "rows": problem.rows(),
            "contacts": problem.contacts.len(), "formulation": problem::formulation(problem),
            "status": record.status, "message": record.message, "iterations": record.iterations,
            "certified": record.certified, "tolerance": tolerance, "objective": record.objective,
            "residuals": record.residuals, "time_us": time_us, "expected_status": resolved.expected,
            "w_error": resolved.w_error, "lambda": record.lambda, "w": record.w,
        });
        println!("{}", serde_json::to_string_pretty(&out).map_err(|e| e.to_string())?);
    } else {
        println!(
            "{}: {} rows, {} contacts, {}; solver {}",
            path.display(),
            problem.rows(),
            problem.contacts.len(),
            problem::formulation(problem),
            kind.name()
        );
        println!(
            "status      {} ({} iterations){}",
            record.status,
            record.iterations,
            match &record.message {
                Some(m) => format!(": {m}"),
                None => String::new(),
            }
        );
        if let Some(expected) = resolved.expected {
            println!("meta.json   {expected}");
        }
        if let (Some(c), Some(r)) = (record.certified, &record.residuals) {
            println!("certified   {c:.3e} m/s (tolerance {tolerance:.0e})");
            println!(
                "residuals   signorini {:.2e}, bilateral {:.2e}, bounded {:.2e}, friction {:.2e}, dissipation {:.2e}, conic KKT {:.2e}",
                r.signorini, r.bilateral, r.bounded, r.friction_feasibility, r.dissipation, r.conic_kkt
            );
            if let (Some(p), Some(d), Some(g)) = (r.qp_primal, r.qp_dual, r.qp_gap) {
                println!("qp          primal {p:.2e}, dual {d:.2e}, gap {g:.2e}");
            }
        }
        if let Some(o) = record.objective {
            println!("objective   {o:.12e}");
        }
        if let Some(e) = resolved.w_error {
            println!("|w − w_ref| {e:.3e} m/s");
        }
        println!("time        {time_us:.1} µs");
    }
    resolved.verdict().map_err(|e| format!("{}: {e}", path.display()))
}
