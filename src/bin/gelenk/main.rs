//! The `gelenk` command-line tool: inspect a model, evaluate its dynamics on given states, run,
//! render, view and benchmark scenes, export and re-solve constraint problems, and write the reports.
//! It parses arguments and prints; the work is the library's. Each command lives in its own
//! module beside this file. Errors are printed as one line on stderr with a non-zero exit.

mod bench;
mod corpus;
mod dynamics;
mod inspect;
mod problems;
mod progress;
mod report;
mod simulate;
mod view;

use clap::{Parser, Subcommand};
use gelenk::prelude::*;
use std::path::Path;
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "gelenk", version, about = "Multibody dynamics in generalized coordinates")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the kinematic tree: bodies, joints, masses and index ranges.
    Inspect(inspect::InspectArgs),
    /// Evaluate M, nle, gravity, RNEA, ABA, energies and centre of mass on states from a file.
    Dynamics(dynamics::DynamicsArgs),
    /// Step a built-in scene, a scene file (models/*.toml) or an MJCF file and write each step's
    /// constraint problem (problem.json, cone.json, lcp.npz, qp.npz for QPs, meta.json) into
    /// OUT/step-NNNN/.
    ExportProblems(problems::ExportArgs),
    /// Solve one exported problem again (a problem.json or its directory); print status,
    /// residuals and time, and compare with meta.json when it is there. Exits non-zero when the
    /// solver fails, or when its status is worse than the one meta.json records (solved <
    /// inaccurate < failed): a corpus problem is a regression test.
    SolveProblem(problems::SolveArgs),
    /// The contact-problem corpus: `build` (step the corpus scenes, write every problem in
    /// gelenk's JSON, CBF, QPS and FCLIB with a certified reference) and `bench` (a
    /// qpbenchmark-style table of solvers over a corpus).
    Corpus {
        #[command(subcommand)]
        what: corpus::CorpusCommand,
    },
    /// Run a scene file (models/*.toml) and print a summary; optionally record the states.
    Simulate(simulate::SimulateArgs),
    /// Reports: `stability` (the hard-case table) and `speed-error` (error against cost of
    /// integrators and solver settings).
    Report {
        #[command(subcommand)]
        what: report::ReportCommand,
    },
    /// Run a scene and draw a filmstrip (side x–z and top x–y views of every collider, FRAMES
    /// instants from 0 to T) with plots of centre-of-mass height, speed and energy, as a PNG.
    Render(simulate::RenderArgs),
    /// Run a scene file and write a player: one self-contained HTML page (three.js and the run
    /// embedded; opens offline) with play/pause, time slider, speed, orbiting camera, contact
    /// overlay and energy and penetration plots.
    View(view::ViewArgs),
    /// Time algorithms in-process (median over rounds, after warm-up).
    Bench {
        #[command(subcommand)]
        what: bench::BenchCommand,
    },
}

/// An option that is on or off (`--contact-projection on|off`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Switch {
    /// On.
    On,
    /// Off.
    Off,
}

impl Switch {
    /// Whether it is on.
    fn on(self) -> bool {
        self == Switch::On
    }
}

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, so `gelenk simulate … | head` would make println! panic once the
    // reader closes the pipe; the default action ends the program quietly, as Unix tools do.
    #[cfg(unix)]
    // SAFETY: called before any other thread exists; SIG_DFL is a valid handler for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Inspect(args) => inspect::run(&args),
        Command::Dynamics(args) => dynamics::run(&args),
        Command::ExportProblems(args) => problems::export(&args),
        Command::SolveProblem(args) => problems::solve(&args),
        Command::Corpus { what } => corpus::run(&what),
        Command::Simulate(args) => simulate::simulate(&args),
        Command::Report { what } => report::run(what),
        Command::Render(args) => simulate::render(&args),
        Command::View(args) => view::run(&args),
        Command::Bench { what } => bench::run(what),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("gelenk: error: {message}");
            ExitCode::FAILURE
        }
    }
}

/// How `inspect` and `dynamics` read a URDF ([`UrdfOptions`]).
#[derive(clap::Args)]
pub struct UrdfArgs {
    /// Attach the root link by a free joint.
    #[arg(long)]
    floating: bool,
    /// Make every loader warning (unknown element or attribute, inconsistent inertia, ...) an error.
    #[arg(long)]
    strict: bool,
    /// Replace inconsistent link inertias by their balanced form (MuJoCo's balanceinertia).
    #[arg(long)]
    balance_inertia: bool,
    /// Compute each link's rotational inertia from its collision shapes, keeping the file's mass
    /// (PyBullet's default).
    #[arg(long)]
    inertia_from_collision: bool,
}

impl UrdfArgs {
    /// The loader options these arguments ask for.
    fn options(&self) -> UrdfOptions {
        UrdfOptions {
            floating_base: self.floating,
            strict: self.strict,
            balance_inertia: self.balance_inertia,
            inertia_from_collision: self.inertia_from_collision,
            ..Default::default()
        }
    }
}

/// Loads a URDF file with the loader's warnings.
fn load_urdf(path: &Path, urdf: &UrdfArgs) -> Result<gelenk::io::urdf::Loaded, String> {
    gelenk::io::urdf::load_file_with_warnings(path, &urdf.options()).map_err(|e| e.to_string())
}
