//! The `gelenk` command-line tool: inspect a model, evaluate its dynamics on given states, and
//! time the rigid-body algorithms. Errors are printed as one line on stderr with a non-zero exit.

use clap::{Parser, Subcommand};
use gelenk::prelude::*;
use nalgebra::DVector;
use rand::SeedableRng;
use serde_json::{json, Value};
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Parser)]
#[command(name = "gelenk", version, about = "Multibody dynamics in generalized coordinates")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the kinematic tree: bodies, joints, masses and index ranges.
    Inspect {
        /// URDF file.
        model: PathBuf,
        #[command(flatten)]
        urdf: UrdfArgs,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Evaluate M, nle, gravity, RNEA, ABA, energies and centre of mass on states from a file.
    Dynamics {
        /// URDF file.
        model: PathBuf,
        #[command(flatten)]
        urdf: UrdfArgs,
        /// JSON file `{"states":[{"q":[…],"v":[…],"a":[…],"tau":[…]}]}` (v, a, tau default to 0).
        #[arg(long)]
        states: PathBuf,
    },
    /// Step a built-in scene, a scene file (models/*.toml) or an MJCF file and write each step's
    /// constraint problem (problem.json, cone.json, lcp.npz, qp.npz for QPs, meta.json) into
    /// OUT/step-NNNN/.
    ExportProblems {
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
        /// Friction model of the contact rows: `cone` or `pyramid:K` (K ≥ 3 facets).
        #[arg(long, default_value = "cone")]
        friction: String,
        /// Write only these steps (comma-separated); default: every step that has rows.
        #[arg(long, value_delimiter = ',')]
        only: Vec<usize>,
    },
    /// Solve one exported problem again (a problem.json or its directory); print status,
    /// residuals and time, and compare with meta.json when it is there. Exits non-zero when the
    /// solver fails, or when its status is worse than the one meta.json records (solved <
    /// inaccurate < failed): a corpus problem is a regression test.
    SolveProblem {
        /// problem.json, or a directory holding one.
        file: PathBuf,
        /// Solver.
        #[arg(long, value_parser = ["lemke", "clarabel", "pgs"])]
        solver: String,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Run a scene file (models/*.toml) and print a summary; optionally record the states.
    Simulate {
        /// Scene file.
        scene: PathBuf,
        /// Simulated time (s) instead of the scene's.
        #[arg(long)]
        duration: Option<f64>,
        /// Time step (s) instead of the scene's.
        #[arg(long)]
        dt: Option<f64>,
        /// Solver chain instead of the scene's, e.g. `pgs50`, `lemke,clarabel`.
        #[arg(long)]
        solver: Option<String>,
        /// Write the recorded states to FILE.csv or FILE.json.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Print the summary as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Reports: `stability` (the hard-case table) and `speed-error` (error against cost of
    /// integrators and solver settings).
    Report {
        #[command(subcommand)]
        what: ReportCommand,
    },
    /// Run a scene and draw a filmstrip (side x–z and top x–y views of every collider, FRAMES
    /// instants from 0 to T) with plots of centre-of-mass height, speed and energy, as a PNG.
    Render {
        /// Scene file.
        scene: PathBuf,
        /// Output image (.png).
        #[arg(long)]
        out: PathBuf,
        /// Number of frames, from t = 0 to t = T.
        #[arg(long, default_value_t = 8)]
        frames: usize,
        /// Simulated time T (s) instead of the scene's duration.
        #[arg(long)]
        duration: Option<f64>,
    },
    /// Time algorithms in-process (median over rounds, after warm-up).
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
}

/// How `inspect` and `dynamics` read a URDF (gelenk::io::urdf::UrdfOptions).
#[derive(clap::Args)]
struct UrdfArgs {
    /// Attach the root link by a free joint.
    #[arg(long)]
    floating: bool,
    /// Make every loader warning (unknown element or attribute, inconsistent inertia, ...) an error.
    #[arg(long)]
    strict: bool,
    /// Replace inconsistent link inertias by their balanced form (MuJoCo's balanceinertia).
    #[arg(long)]
    balance_inertia: bool,
}

impl UrdfArgs {
    fn options(&self) -> UrdfOptions {
        UrdfOptions {
            floating_base: self.floating,
            strict: self.strict,
            balance_inertia: self.balance_inertia,
            ..Default::default()
        }
    }
}

#[derive(Subcommand)]
enum ReportCommand {
    /// The hard-case suite (tests/hard_cases.rs) for every solver and time step: a pass/fail
    /// table with the measured figure in each cell, as stability.md and stability.csv in DIR
    /// (markdown on stdout without --out). Progress goes to stderr.
    Stability {
        /// Output directory.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Only these cases (comma-separated names; default: all).
        #[arg(long, value_delimiter = ',')]
        cases: Vec<String>,
        /// Only these solvers (lemke, clarabel, pgsN; default: lemke, clarabel, pgs10, pgs50).
        #[arg(long, value_delimiter = ',')]
        solvers: Vec<String>,
        /// Only these time steps in s, each in [1e-6, 0.05] (default: 1/60, 1/240, 1/1000).
        #[arg(long, value_delimiter = ',')]
        dt: Vec<f64>,
        /// World integrators (semi-implicit-euler, rk4, dopri45, ...; default:
        /// semi-implicit-euler, and rk4 too on the cases without contact). The first one runs
        /// every case; the others only the cases without contact (dzhanibekov, four_bar).
        #[arg(long, value_delimiter = ',')]
        integrators: Vec<String>,
    },
    /// Scenes × integrators × time steps (× solver settings for contact scenes): writes
    /// speed_error.csv, speed_error.md, speed_error.png and speed_error.svg into OUT.
    SpeedError {
        /// Output directory.
        #[arg(long, default_value = "speed-error-report")]
        out: PathBuf,
        /// A subset that runs in seconds.
        #[arg(long)]
        quick: bool,
        /// Directory with pendulum5.xml and MuJoCo's figures (README.md).
        #[arg(long, default_value = "../shared/peers")]
        peers: PathBuf,
        /// Timed repeats per configuration (median reported); default 3, 1 with --quick.
        #[arg(long)]
        repeats: Option<usize>,
        /// Only these scenes (pendulum5, dzhanibekov, chain30, bouncing_ball, sliding_box,
        /// stack10, four_bar); default all.
        #[arg(long, value_delimiter = ',')]
        scenes: Vec<String>,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Median ns per call of rnea, crba, aba and nle over a pool of random states.
    Dynamics {
        /// URDF file.
        model: PathBuf,
        /// Attach the root link by a free joint.
        #[arg(long)]
        floating: bool,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
        /// Timed rounds (at least 1); the median is reported.
        #[arg(long, default_value_t = 51, value_parser = at_least_one)]
        rounds: usize,
    },
    /// Whole-step time of a scene (models/*.toml, or an MJCF .xml such as
    /// ../shared/peers/humanoid_fall.xml): median and mean µs per step, time per phase.
    World {
        /// Scene file (.toml) or MJCF file (.xml).
        scene: PathBuf,
        /// Solver chain instead of the scene's, e.g. `pgs50`, `pgs100,clarabel`.
        #[arg(long)]
        solver: Option<String>,
        /// Steps timed (at least 1; one episode from the initial state, after `--settle`).
        #[arg(long, default_value_t = 2500, value_parser = at_least_one)]
        steps: usize,
        /// Steps run untimed first (e.g. to let a stack settle).
        #[arg(long, default_value_t = 0)]
        settle: usize,
        /// Keep sleeping on (off by default so that every step does the full work).
        #[arg(long)]
        sleep: bool,
        /// Apply a scene file's vehicle commands before each step, as `simulate` does (off by
        /// default: the world alone is stepped, a buggy stands where it starts).
        #[arg(long)]
        controls: bool,
        /// Episodes timed (at least 1); the reported figures are medians over episodes.
        #[arg(long, default_value_t = 5, value_parser = at_least_one)]
        rounds: usize,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
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
        Command::Inspect { model, urdf, json } => inspect(&model, &urdf.options(), json),
        Command::Dynamics { model, urdf, states } => dynamics(&model, &urdf.options(), &states),
        Command::ExportProblems { scene, steps, out, friction, only } => {
            export_problems(&scene, steps, &out, &friction, &only)
        }
        Command::SolveProblem { file, solver, json } => solve_problem(&file, &solver, json),
        Command::Simulate { scene, duration, dt, solver, out, json } => {
            simulate(&scene, duration, dt, solver.as_deref(), out.as_deref(), json)
        }
        Command::Report { what: ReportCommand::Stability { out, cases, solvers, dt, integrators } } => {
            report_stability(out.as_deref(), &cases, &solvers, &dt, &integrators)
        }
        Command::Render { scene, out, frames, duration } => render(&scene, &out, frames, duration),
        Command::Report { what: ReportCommand::SpeedError { out, quick, peers, repeats, scenes } } => {
            report_speed_error(&out, quick, &peers, repeats, scenes)
        }
        Command::Bench { what: BenchCommand::Dynamics { model, floating, json, rounds } } => {
            bench_dynamics(&model, floating, json, rounds)
        }
        Command::Bench {
            what: BenchCommand::World { scene, solver, steps, settle, sleep, controls, rounds, json },
        } => bench_world(
            &scene,
            solver.as_deref(),
            steps,
            settle,
            BenchOptions { sleep, controls },
            rounds,
            json,
        ),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("gelenk: error: {message}");
            ExitCode::FAILURE
        }
    }
}

fn load(path: &Path, floating: bool) -> Result<Model, String> {
    let options = UrdfOptions { floating_base: floating, ..Default::default() };
    gelenk::io::urdf::load_file(path, &options).map_err(|e| e.to_string())
}

/// The model and the loader's warnings.
fn load_with_warnings(path: &Path, options: &UrdfOptions) -> Result<gelenk::io::urdf::Loaded, String> {
    gelenk::io::urdf::load_file_with_warnings(path, options).map_err(|e| e.to_string())
}

fn joints_json(model: &Model) -> Vec<Value> {
    (1..model.nbodies())
        .map(|i| {
            json!({
                "name": model.joint_name(i),
                "type": model.joint(i).kind_name(),
                "parent": model.joint_name(model.parent(i)),
                "idx_q": model.idx_q(i),
                "nq": model.joint(i).nq(),
                "idx_v": model.idx_v(i),
                "nv": model.joint(i).nv(),
            })
        })
        .collect()
}

fn inspect(path: &Path, options: &UrdfOptions, as_json: bool) -> Result<(), String> {
    let gelenk::io::urdf::Loaded { model, warnings } = load_with_warnings(path, options)?;
    let massless = model.massless_subtrees();
    if as_json {
        let collision: Vec<Value> = collision_geometry(&model)
            .map(|(g, resolved)| {
                json!({"body": model.body_name(g.body), "link": g.link, "shape": g.shape.kind_name(),
                       "parameters": g.shape.summary(), "xyz": g.placement.translation.as_slice(),
                       "mesh_file": resolved})
            })
            .collect();
        let warnings: Vec<Value> = warnings
            .iter()
            .map(|w| json!({"element": w.element, "line": w.line, "message": w.to_string()}))
            .collect();
        let out = json!({"nq": model.nq(), "nv": model.nv(), "mass": model.total_mass(),
                         "joints": joints_json(&model), "collision": collision, "warnings": warnings});
        println!("{}", serde_json::to_string_pretty(&out).map_err(|e| e.to_string())?);
    } else {
        println!(
            "model `{}`: {} moving bodies, nq = {}, nv = {}",
            model.name(),
            model.nbodies() - 1,
            model.nq(),
            model.nv()
        );
        println!(
            "{:<24} {:<24} {:<9} {:<24} {:>10} {:>7} {:>7}",
            "body", "joint", "kind", "parent", "mass [kg]", "q", "v"
        );
        for i in 1..model.nbodies() {
            let j = model.joint(i);
            let range = |start: usize, n: usize| format!("{}..{}", start, start + n);
            println!(
                "{:<24} {:<24} {:<9} {:<24} {:>10} {:>7} {:>7}",
                model.body_name(i),
                model.joint_name(i),
                j.kind_name(),
                model.body_name(model.parent(i)),
                mass_text(model.inertia(i).mass, 4),
                range(model.idx_q(i), j.nq()),
                range(model.idx_v(i), j.nv()),
            );
        }
        println!(
            "total mass: {} kg; {} named frames",
            mass_text(model.total_mass(), 6),
            model.frames().len()
        );
        let mut geometry = collision_geometry(&model).peekable();
        if geometry.peek().is_none() {
            println!("collision geometry: none");
        } else {
            println!("collision geometry:");
            println!("{:<24} {:<24} {:<11} parameters", "body", "link", "shape");
        }
        for (g, resolved) in geometry {
            let file = match (&g.shape, resolved) {
                (gelenk::model::Shape::Mesh { .. }, Some(path)) => format!(" -> {path}"),
                (gelenk::model::Shape::Mesh { .. }, None) => " -> NOT FOUND".to_string(),
                _ => String::new(),
            };
            println!(
                "{:<24} {:<24} {:<11} {}{}",
                model.body_name(g.body),
                g.link,
                g.shape.kind_name(),
                g.shape.summary(),
                file
            );
        }
    }
    if !as_json {
        for w in &warnings {
            println!("warning: {w}");
        }
    }
    for i in massless {
        eprintln!(
            "gelenk: warning: joint `{}` moves a subtree without mass or inertia: the mass matrix is singular and forward dynamics will refuse it",
            model.joint_name(i)
        );
    }
    Ok(())
}

fn render(path: &Path, out: &Path, frames: usize, duration: Option<f64>) -> Result<(), String> {
    let mut loaded = gelenk::io::scene::load_file(path).map_err(|e| e.to_string())?;
    let options = gelenk::render::RenderOptions { frames, duration, ..Default::default() };
    let summary = gelenk::render::render_scene(&mut loaded, &options, out).map_err(|e| e.to_string())?;
    let times: Vec<String> = summary.frame_times.iter().map(|t| format!("{t:.3}")).collect();
    println!(
        "{}: {} steps, {} frames at t = {} s -> {} ({}×{} px)",
        loaded.name,
        summary.steps,
        times.len(),
        times.join(", "),
        out.display(),
        summary.size.0,
        summary.size.1
    );
    Ok(())
}

fn simulate(
    path: &Path,
    duration: Option<f64>,
    dt: Option<f64>,
    solver: Option<&str>,
    out: Option<&Path>,
    as_json: bool,
) -> Result<(), String> {
    use gelenk::io::scene;
    use std::io::{IsTerminal, Write};
    let mut loaded = scene::load_file(path).map_err(|e| e.to_string())?;
    let solvers = solver.map(scene::parse_solvers).transpose().map_err(|e| format!("--solver: {e}"))?;
    let options =
        scene::RunOptions { duration, dt, solvers, record_every: if out.is_some() { None } else { Some(0) } };
    let terminal = std::io::stderr().is_terminal();
    let mut shown = -1i64;
    let summary = scene::run(&mut loaded, &options, |fraction| {
        let percent = (fraction * 100.0).floor() as i64;
        if terminal && percent != shown {
            shown = percent;
            let filled = (percent / 2) as usize;
            eprint!("\r[{}{}] {percent:3}%", "#".repeat(filled), " ".repeat(50 - filled.min(50)));
            let _ = std::io::stderr().flush();
        }
    })
    .map_err(|e| e.to_string())?;
    if terminal {
        eprintln!();
    }
    for warning in &loaded.warnings {
        eprintln!("gelenk: warning: {warning}");
    }
    if let Some(out) = out {
        summary.recording.save(out).map_err(|e| format!("{}: cannot write: {e}", out.display()))?;
    }
    if as_json {
        let value = json!({
            "scene": summary.scene, "steps": summary.steps, "dt": summary.dt,
            "simulated_time": summary.simulated_time, "wall_time": summary.wall_time,
            "steps_per_second": summary.steps_per_second, "real_time_factor": summary.real_time_factor,
            "energy_start": summary.energy_start, "energy_end": summary.energy_end,
            "energy_drift": summary.energy_drift, "max_penetration": summary.max_penetration,
            "max_contacts": summary.max_contacts, "max_rows": summary.max_rows,
            "solver_usage": summary.solver_usage, "fallbacks": summary.fallbacks,
            "max_residual": summary.max_residual, "mean_iterations": summary.mean_iterations,
        });
        println!("{}", serde_json::to_string_pretty(&value).map_err(|e| e.to_string())?);
    } else {
        println!(
            "{}: {} steps of {} s ({} s simulated) in {:.3} s: {:.0} steps/s, {:.1}× real time",
            summary.scene,
            summary.steps,
            summary.dt,
            summary.simulated_time,
            summary.wall_time,
            summary.steps_per_second,
            summary.real_time_factor
        );
        println!(
            "energy {:.6} J -> {:.6} J (drift {:+.3e}); max penetration {:.2e} m; up to {} contacts, {} rows",
            summary.energy_start,
            summary.energy_end,
            summary.energy_drift,
            summary.max_penetration,
            summary.max_contacts,
            summary.max_rows
        );
        let usage: Vec<String> = summary.solver_usage.iter().map(|(k, v)| format!("{k} {v}")).collect();
        println!(
            "solver: {} steps with rows ({}); {} fallbacks; max residual {:.2e} m/s; mean iterations {:.1}",
            summary.solved_steps,
            usage.join(", "),
            summary.fallbacks,
            summary.max_residual,
            summary.mean_iterations
        );
    }
    Ok(())
}

/// Collision geometry of the model with, for meshes, the file the URI resolves to (if any).
fn collision_geometry(
    model: &gelenk::Model,
) -> impl Iterator<Item = (&gelenk::model::GeometrySpec, Option<String>)> + '_ {
    model.geometries().iter().filter(|g| g.role == gelenk::model::GeometryRole::Collision).map(|g| {
        let resolved = match &g.shape {
            gelenk::model::Shape::Mesh { uri, .. } => {
                gelenk::collision::mesh::resolve(&g.link, uri, model.source_dir(), &[])
                    .ok()
                    .map(|p| p.display().to_string())
            }
            _ => None,
        };
        (g, resolved)
    })
}

fn vector(
    state: &Value,
    key: &str,
    len: usize,
    index: usize,
    required: bool,
) -> Result<DVector<f64>, String> {
    match state.get(key) {
        None if !required => Ok(DVector::zeros(len)),
        None => Err(format!("state {index}: missing \"{key}\"")),
        Some(v) => {
            let items = v.as_array().ok_or_else(|| format!("state {index}: \"{key}\" is not an array"))?;
            if items.len() != len {
                return Err(format!(
                    "state {index}: \"{key}\" has {} entries, the model needs {len}",
                    items.len()
                ));
            }
            items
                .iter()
                .map(|x| x.as_f64().ok_or_else(|| format!("state {index}: \"{key}\" holds a non-number")))
                .collect::<Result<Vec<f64>, String>>()
                .map(DVector::from_vec)
        }
    }
}

fn dynamics(path: &Path, options: &UrdfOptions, states_path: &Path) -> Result<(), String> {
    let gelenk::io::urdf::Loaded { model, warnings } = load_with_warnings(path, options)?;
    for w in &warnings {
        eprintln!("gelenk: warning: {w}");
    }
    let text = std::fs::read_to_string(states_path)
        .map_err(|e| format!("{}: cannot read: {e}", states_path.display()))?;
    let doc: Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: not valid JSON: {e}", states_path.display()))?;
    let states = doc
        .get("states")
        .and_then(Value::as_array)
        .ok_or_else(|| format!("{}: expected {{\"states\": [...]}}", states_path.display()))?;
    let mut data = Data::new(&model);
    let (nq, nv) = (model.nq(), model.nv());
    let mut results = Vec::with_capacity(states.len());
    for (k, s) in states.iter().enumerate() {
        let q = vector(s, "q", nq, k, true)?;
        let v = vector(s, "v", nv, k, false)?;
        let a = vector(s, "a", nv, k, false)?;
        let tau = vector(s, "tau", nv, k, false)?;
        let fail = |e: DynamicsError| format!("state {k}: {e}");
        let m = crba(&model, &mut data, &q).map_err(fail)?;
        let rows: Vec<Vec<f64>> = m.row_iter().map(|r| r.iter().copied().collect()).collect();
        let nle = nonlinear_effects(&model, &mut data, &q, &v).map_err(fail)?.as_slice().to_vec();
        let gravity = generalized_gravity(&model, &mut data, &q).map_err(fail)?.as_slice().to_vec();
        let tau_id = rnea(&model, &mut data, &q, &v, &a).map_err(fail)?.as_slice().to_vec();
        // A singular mass matrix (a massless moving subtree) leaves ABA undefined: null, with the reason.
        let (ddq, aba_error) = match aba(&model, &mut data, &q, &v, &tau) {
            Ok(a) => (Some(a.as_slice().to_vec()), None),
            Err(e) => (None, Some(e.to_string())),
        };
        let ke = kinetic_energy(&model, &mut data, &q, &v).map_err(fail)?;
        let pe = potential_energy(&model, &mut data, &q).map_err(fail)?;
        let com = center_of_mass(&model, &mut data, &q).map_err(fail)?;
        results.push(json!({
            "mass_matrix": rows, "nle": nle, "gravity": gravity, "rnea": tau_id, "aba": ddq, "aba_error": aba_error,
            "kinetic_energy": ke, "potential_energy": pe, "com": [com.x, com.y, com.z],
            "mass": model.total_mass(),
        }));
    }
    let out = json!({"nq": nq, "nv": nv, "joints": joints_json(&model), "results": results});
    println!("{}", serde_json::to_string(&out).map_err(|e| e.to_string())?);
    Ok(())
}

/// A count of at least one, for options where zero would time or report nothing.
fn at_least_one(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!("expected an integer of at least 1, got `{text}`")),
    }
}

/// Median nanoseconds per call of `f` over `rounds` rounds of one pass through a pool of states.
fn median_ns(rounds: usize, pool: usize, mut f: impl FnMut(usize)) -> f64 {
    let warm = Instant::now();
    while warm.elapsed().as_millis() < 200 {
        (0..pool).for_each(&mut f);
    }
    let mut per_call: Vec<f64> = (0..rounds)
        .map(|_| {
            let start = Instant::now();
            (0..pool).for_each(&mut f);
            start.elapsed().as_nanos() as f64 / pool as f64
        })
        .collect();
    per_call.sort_by(f64::total_cmp);
    per_call[per_call.len() / 2]
}

fn bench_dynamics(path: &Path, floating: bool, as_json: bool, rounds: usize) -> Result<(), String> {
    let model = load(path, floating)?;
    let mut data = Data::new(&model);
    let mut rng = rand::rngs::StdRng::seed_from_u64(42);
    const POOL: usize = 1000;
    let mut random_vector =
        |n: usize| DVector::from_fn(n, |_, _| rand::Rng::random_range(&mut rng, -1.0..1.0));
    let vs: Vec<DVector<f64>> = (0..POOL).map(|_| random_vector(model.nv())).collect();
    let accs: Vec<DVector<f64>> = (0..POOL).map(|_| random_vector(model.nv())).collect();
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let qs: Vec<DVector<f64>> = (0..POOL).map(|_| model.random_configuration(&mut rng)).collect();
    // Surface a model that forward dynamics refuses before timing it.
    aba(&model, &mut data, &qs[0], &vs[0], &accs[0]).map_err(|e| e.to_string())?;
    let rnea_ns = median_ns(rounds, POOL, |k| {
        black_box(rnea(&model, &mut data, &qs[k], &vs[k], &accs[k]).ok());
    });
    let crba_ns = median_ns(rounds, POOL, |k| {
        black_box(crba(&model, &mut data, &qs[k]).ok());
    });
    let aba_ns = median_ns(rounds, POOL, |k| {
        black_box(aba(&model, &mut data, &qs[k], &vs[k], &accs[k]).ok());
    });
    let nle_ns = median_ns(rounds, POOL, |k| {
        black_box(nonlinear_effects(&model, &mut data, &qs[k], &vs[k]).ok());
    });
    if as_json {
        println!("{}", json!({"rnea_ns": rnea_ns, "crba_ns": crba_ns, "aba_ns": aba_ns, "nle_ns": nle_ns}));
    } else {
        println!(
            "model `{}` (nq = {}, nv = {}), median of {rounds} rounds over {POOL} random states",
            model.name(),
            model.nq(),
            model.nv()
        );
        for (name, ns) in [("rnea", rnea_ns), ("crba", crba_ns), ("aba", aba_ns), ("nle", nle_ns)] {
            println!("{name:<6} {ns:>10.0} ns/call");
        }
    }
    Ok(())
}

/// A world to time: a TOML scene, or an MJCF file as one multibody on its static geometry.
fn load_world(path: &Path) -> Result<gelenk::world::World, String> {
    use gelenk::collision::MeshOptions;
    use gelenk::world::{World, WorldOptions};
    if is_mjcf(path) {
        let scene = gelenk::io::mjcf::load_file(path).map_err(|e| e.to_string())?;
        // MuJoCo's friction model (`<option cone>`) and its pair rule (the larger of the two
        // geoms' sliding friction; one world coefficient, the largest, when geoms differ).
        let mu = scene.geoms.iter().map(|g| g.friction[0]).chain(scene.statics.iter().map(|s| s.friction[0]));
        let mut options =
            WorldOptions { dt: scene.timestep, friction: scene.friction, ..WorldOptions::default() };
        options.contact.mu = mu.fold(0.0, f64::max);
        let mut world = World::new(options);
        for s in scene.statics.iter().filter(|s| s.collides) {
            world.add_static(&s.name, &s.shape, s.pose, 0).map_err(|e| e.to_string())?;
        }
        let name = scene.model.name().to_string();
        let i =
            world.add_multibody(&name, scene.model, &MeshOptions::default()).map_err(|e| e.to_string())?;
        // Self-collision stays off, as in benches/world.rs (the peers' scenes rest on the plane).
        world.multibody_mut(i).state.q.copy_from(&scene.q0);
        Ok(world)
    } else {
        Ok(gelenk::io::scene::load_file(path).map_err(|e| e.to_string())?.world)
    }
}

/// What `bench world` steps: a scene file's scene (whose vehicle commands it may apply), or an
/// MJCF file's world.
enum BenchTarget {
    Scene(Box<gelenk::io::scene::Scene>),
    Mjcf(Box<gelenk::world::World>),
}

impl BenchTarget {
    fn load(path: &Path) -> Result<Self, String> {
        if is_mjcf(path) {
            Ok(BenchTarget::Mjcf(Box::new(load_world(path)?)))
        } else {
            Ok(BenchTarget::Scene(Box::new(gelenk::io::scene::load_file(path).map_err(|e| e.to_string())?)))
        }
    }

    fn world(&mut self) -> &mut gelenk::world::World {
        match self {
            BenchTarget::Scene(scene) => &mut scene.world,
            BenchTarget::Mjcf(world) => world,
        }
    }

    /// One step, after the scene's due vehicle commands when `controls` is set.
    fn step(&mut self, controls: bool) -> Result<&gelenk::world::StepStats, String> {
        if let (BenchTarget::Scene(scene), true) = (&mut *self, controls) {
            scene.apply_controls().map_err(|e| e.to_string())?;
        }
        self.world().step().map_err(|e| e.to_string())
    }
}

/// `path` names an MJCF file (by its extension), not a scene file.
fn is_mjcf(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("xml"))
}

/// Switches of `bench world`: sleeping kept on, vehicle commands applied.
struct BenchOptions {
    sleep: bool,
    controls: bool,
}

fn bench_world(
    path: &Path,
    solver: Option<&str>,
    steps: usize,
    settle: usize,
    BenchOptions { sleep, controls }: BenchOptions,
    rounds: usize,
    as_json: bool,
) -> Result<(), String> {
    use std::time::Instant;
    let solvers =
        solver.map(gelenk::io::scene::parse_solvers).transpose().map_err(|e| format!("--solver: {e}"))?;
    let (mut medians, mut means, mut phases) = (Vec::new(), Vec::new(), Vec::new());
    let (mut rows, mut fallbacks, mut iterations, mut solver_usage) =
        (0usize, 0usize, 0usize, std::collections::BTreeMap::new());
    let (mut builds, mut kept_rows) = (0, 0);
    let load = || -> Result<BenchTarget, String> {
        let mut target = BenchTarget::load(path)?;
        let world = target.world();
        if let Some(s) = &solvers {
            world.set_solvers(s.clone());
        }
        if !sleep {
            world.set_sleep(gelenk::world::SleepOptions { enabled: false, ..world.options().sleep });
        }
        for _ in 0..settle {
            target.step(controls)?;
        }
        Ok(target)
    };
    for _ in 0..rounds {
        // The episode mean as MuJoCo's is measured (benches/mujoco_peers.py): one clock around
        // the steps, no timing inside them; the per-step times and phases from a second run of
        // the same (deterministic) episode with clocks around and inside each step.
        let mut target = load()?;
        let start = Instant::now();
        for _ in 0..steps {
            target.step(controls)?;
        }
        means.push(start.elapsed().as_secs_f64() * 1e6 / steps.max(1) as f64);
        let mut target = load()?;
        target.world().set_phase_timing(true);
        let mut times = Vec::with_capacity(steps);
        let mut phase = [0u64; 6];
        (rows, fallbacks, iterations) = (0, 0, 0);
        solver_usage.clear();
        let builds_before = target.world().problem_builds();
        let kept_before = target.world().contact_row_reuses();
        for _ in 0..steps {
            let start = Instant::now();
            let stats = target.step(controls)?;
            times.push(start.elapsed().as_secs_f64() * 1e6);
            for (total, ns) in phase.iter_mut().zip(stats.phase_ns) {
                *total += ns;
            }
            rows = rows.max(stats.rows);
            fallbacks += stats.fallbacks.len();
            iterations += stats.iterations;
            if stats.rows > 0 {
                *solver_usage.entry(stats.solver).or_insert(0usize) += 1;
            }
        }
        builds = target.world().problem_builds() - builds_before;
        kept_rows = target.world().contact_row_reuses() - kept_before;
        times.sort_by(f64::total_cmp);
        medians.push(times.get(times.len() / 2).copied().unwrap_or(0.0));
        phases.push(phase.map(|ns| ns as f64 * 1e-3 / steps.max(1) as f64));
    }
    let median = |mut x: Vec<f64>| {
        x.sort_by(f64::total_cmp);
        x[x.len() / 2]
    };
    let phase: Vec<f64> = (0..6).map(|k| median(phases.iter().map(|p| p[k]).collect())).collect();
    let (median_us, mean_us) = (median(medians), median(means));
    const PHASES: [&str; 6] = ["kinematics", "collision", "free_motion", "assembly", "solve", "integrate"];
    if as_json {
        let phase_json: serde_json::Map<String, serde_json::Value> =
            PHASES.iter().zip(&phase).map(|(n, us)| (n.to_string(), json!(us))).collect();
        println!(
            "{}",
            json!({"scene": path.display().to_string(), "steps": steps, "rounds": rounds,
                   "median_us_per_step": median_us, "mean_us_per_step": mean_us,
                   "phase_mean_us": phase_json, "max_rows": rows, "fallbacks": fallbacks,
                   "mean_iterations": iterations as f64 / steps.max(1) as f64,
                   "solver_usage": solver_usage, "problem_builds": builds,
                   "contact_row_reuses": kept_rows})
        );
    } else {
        println!(
            "{}: {steps} steps after {settle}, median over {rounds} episodes: {median_us:.1} µs/step (per-step median), {mean_us:.1} µs/step (episode mean)",
            path.display()
        );
        let parts: Vec<String> = PHASES.iter().zip(&phase).map(|(n, us)| format!("{n} {us:.1}")).collect();
        println!("mean µs per phase: {}", parts.join(", "));
        println!(
            "up to {rows} rows; solver use {solver_usage:?}; {fallbacks} fallbacks, {:.1} iterations per step, W built {builds} times (World::problem_builds) and contact rows kept on {kept_rows} steps (World::contact_row_reuses) in the last episode",
            iterations as f64 / steps.max(1) as f64
        );
    }
    Ok(())
}

fn parse_friction(text: &str) -> Result<gelenk::constraints::FrictionModel, String> {
    use gelenk::constraints::{FrictionModel, MAX_PYRAMID_FACETS};
    match text.split_once(':') {
        None if text == "cone" => Ok(FrictionModel::Cone),
        Some(("pyramid", k)) => match k.parse::<usize>() {
            Ok(facets) if (3..=MAX_PYRAMID_FACETS).contains(&facets) => Ok(FrictionModel::Pyramid { facets }),
            _ => Err(format!("--friction {text}: a pyramid needs 3 to {MAX_PYRAMID_FACETS} facets")),
        },
        _ => Err(format!("--friction {text}: expected `cone` or `pyramid:K`")),
    }
}

fn export_problems(
    scene: &str,
    steps: usize,
    out: &Path,
    friction: &str,
    only: &[usize],
) -> Result<(), String> {
    use gelenk::io::problem::{write_problem, ProblemMeta};
    use gelenk::solvers::{ClarabelSolver, ConstraintSolver};
    let path = Path::new(scene);
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml") || e.eq_ignore_ascii_case("xml")) {
        return export_world_problems(path, steps, out, friction, only);
    }
    let mut scene = gelenk::scenes::Scene::new(scene).map_err(|e| e.to_string())?;
    scene.friction = parse_friction(friction)?;
    let mut problem = gelenk::constraints::ConstraintProblem::default();
    let mut lambda = DVector::zeros(0);
    let mut written = 0;
    for step in 0..steps {
        scene.problem(&mut problem).map_err(|e| e.to_string())?;
        if problem.rows() > 0 && (only.is_empty() || only.contains(&step)) {
            let meta = ProblemMeta::compute(&scene.name, step, scene.h, &problem);
            let dir = out.join(format!("step-{step:04}"));
            write_problem(&dir, &problem, &meta).map_err(|e| e.to_string())?;
            let outcome = |name: &str| {
                let r = &meta.solutions[name];
                match r.certified {
                    Some(c) => format!("{name} {:?} {c:.1e}", r.status).to_lowercase(),
                    None => format!("{name} failed"),
                }
            };
            println!(
                "{}: {} rows, {} contacts, {}; {}, {}, {}",
                dir.display(),
                meta.rows,
                meta.contacts,
                meta.formulation,
                outcome("clarabel"),
                outcome("lemke"),
                outcome("pgs")
            );
            written += 1;
        }
        // The scene goes on with clarabel's impulses (the reference solution).
        ClarabelSolver::default()
            .solve(&problem, &mut lambda)
            .map_err(|e| format!("{} step {step}: {e}", scene.name))?;
        scene.advance(&problem, &lambda);
    }
    println!("wrote {written} problems of {steps} steps to {}", out.display());
    Ok(())
}

/// `export-problems` for a scene or MJCF file: the world steps with its own solver chain, and
/// the problem of each selected step is written as it was posed (before the solve).
fn export_world_problems(
    path: &Path,
    steps: usize,
    out: &Path,
    friction: &str,
    only: &[usize],
) -> Result<(), String> {
    use gelenk::io::problem::{write_problem, ProblemMeta};
    enum Source {
        /// A TOML scene: its controls (vehicle commands, servos) are applied before each step.
        Scene(Box<gelenk::io::scene::Scene>),
        Mjcf(Box<gelenk::world::World>),
    }
    let mut source = if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml")) {
        Source::Scene(Box::new(gelenk::io::scene::load_file(path).map_err(|e| e.to_string())?))
    } else {
        Source::Mjcf(Box::new(load_world(path)?))
    };
    let friction = parse_friction(friction)?;
    let name = path.file_stem().map_or_else(|| "scene".to_string(), |s| s.to_string_lossy().into_owned());
    let mut written = 0;
    for step in 0..steps {
        let world = match &mut source {
            Source::Scene(scene) => {
                scene.apply_controls().map_err(|e| format!("{name} step {step}: {e}"))?;
                &mut scene.world
            }
            Source::Mjcf(world) => world,
        };
        if step == 0 {
            world.set_friction(friction).map_err(|e| e.to_string())?;
        }
        let h = world.options().dt;
        world.step().map_err(|e| format!("{name} step {step}: {e}"))?;
        let problem = world.problem();
        if problem.rows() > 0 && (only.is_empty() || only.contains(&step)) {
            let meta = ProblemMeta::compute(&name, step, h, problem);
            let dir = out.join(format!("step-{step:04}"));
            write_problem(&dir, problem, &meta).map_err(|e| e.to_string())?;
            println!(
                "{}: {} rows, {} contacts, {}",
                dir.display(),
                meta.rows,
                meta.contacts,
                meta.formulation
            );
            written += 1;
        }
    }
    println!("wrote {written} problems of {steps} steps to {}", out.display());
    Ok(())
}

/// A mass (kg) with `decimals` places, in exponent form outside 1e-3 … 1e6 kg (a mass of 1e300 kg
/// is 301 digits in fixed form).
fn mass_text(mass: f64, decimals: usize) -> String {
    if mass == 0.0 || (1e-3..1e6).contains(&mass.abs()) {
        format!("{mass:.decimals$}")
    } else {
        format!("{mass:.decimals$e}")
    }
}

fn solve_problem(path: &Path, solver: &str, as_json: bool) -> Result<(), String> {
    use gelenk::io::problem::{read_meta, read_problem, run_solver, CorpusSolver, SolveStatus, META_FILE};
    let kind: CorpusSolver = solver.parse()?;
    let problem = read_problem(path).map_err(|e| e.to_string())?;
    let meta_path = if path.is_dir() { path.join(META_FILE) } else { path.with_file_name(META_FILE) };
    let meta =
        if meta_path.exists() { Some(read_meta(&meta_path).map_err(|e| e.to_string())?) } else { None };
    let (record, elapsed) = run_solver(kind, &problem);
    let tolerance =
        meta.as_ref().and_then(|m| m.tolerances.get(kind.name()).copied()).unwrap_or(kind.tolerance());
    // Largest |w − w_ref| when this solver's w must equal the reference's.
    let w_error = meta.as_ref().and_then(|m| {
        let reference = &m.solutions.get(&m.reference)?.w;
        let unique = m.w_unique_for.iter().any(|s| s == kind.name());
        (unique && reference.len() == record.w.len())
            .then(|| record.w.iter().zip(reference).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max))
    });
    let expected = meta.as_ref().and_then(|m| m.solutions.get(kind.name())).map(|r| r.status);
    let time_us = elapsed.as_secs_f64() * 1e6;
    if as_json {
        let out = json!({
            "file": path.display().to_string(), "solver": kind.name(), "rows": problem.rows(),
            "contacts": problem.contacts.len(), "formulation": gelenk::io::problem::formulation(&problem),
            "status": record.status, "message": record.message, "iterations": record.iterations,
            "certified": record.certified, "tolerance": tolerance, "objective": record.objective,
            "residuals": record.residuals, "time_us": time_us, "expected_status": expected,
            "w_error": w_error, "lambda": record.lambda, "w": record.w,
        });
        println!("{}", serde_json::to_string_pretty(&out).map_err(|e| e.to_string())?);
    } else {
        println!(
            "{}: {} rows, {} contacts, {}; solver {}",
            path.display(),
            problem.rows(),
            problem.contacts.len(),
            gelenk::io::problem::formulation(&problem),
            kind.name()
        );
        let status = format!("{:?}", record.status).to_lowercase();
        println!(
            "status      {status} ({} iterations){}",
            record.iterations,
            match &record.message {
                Some(m) => format!(": {m}"),
                None => String::new(),
            }
        );
        if let Some(expected) = expected {
            println!("meta.json   {}", format!("{expected:?}").to_lowercase());
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
        if let Some(e) = w_error {
            println!("|w − w_ref| {e:.3e} m/s");
        }
        println!("time        {time_us:.1} µs");
    }
    if record.status == SolveStatus::Failed {
        return Err(format!(
            "{}: {} failed: {}",
            path.display(),
            kind.name(),
            record.message.as_deref().unwrap_or("no solution")
        ));
    }
    // A corpus problem is a regression test: worse than meta.json records is a failure.
    if let Some(expected) = expected.filter(|e| record.status > *e) {
        let lower = |s: SolveStatus| format!("{s:?}").to_lowercase();
        return Err(format!(
            "{}: {} is {} where meta.json records {} (certified {:.3e} m/s, tolerance {tolerance:.0e})",
            path.display(),
            kind.name(),
            lower(record.status),
            lower(expected),
            record.certified.unwrap_or(f64::NAN)
        ));
    }
    Ok(())
}

fn report_stability(
    out: Option<&Path>,
    cases: &[String],
    solvers: &[String],
    dts: &[f64],
    integrators: &[String],
) -> Result<(), String> {
    use gelenk::report::stability;
    let selected: Vec<stability::Case> = if cases.is_empty() {
        stability::CASES.to_vec()
    } else {
        cases
            .iter()
            .map(|name| {
                stability::case(name).copied().ok_or_else(|| {
                    let known: Vec<&str> = stability::CASES.iter().map(|c| c.name).collect();
                    format!("unknown case `{name}` (known: {})", known.join(", "))
                })
            })
            .collect::<Result<_, _>>()?
    };
    let solver_kinds: Vec<gelenk::world::SolverKind> = if solvers.is_empty() {
        stability::SOLVERS.to_vec()
    } else {
        solvers
            .iter()
            .map(|name| {
                gelenk::world::SolverKind::parse(name).ok_or_else(|| format!("unknown solver `{name}`"))
            })
            .collect::<Result<_, _>>()?
    };
    let dts: Vec<f64> = if dts.is_empty() { stability::TIME_STEPS.to_vec() } else { dts.to_vec() };
    // The shortest phase of a case lasts 0.05 s, the longest case 10 s: a step outside
    // [1e-6, 0.05] s would time nothing or run for ever.
    if let Some(bad) = dts.iter().find(|h| !(1e-6..=0.05).contains(*h)) {
        return Err(format!("time step {bad} s is outside [1e-6, 0.05] s"));
    }
    let integrator_kinds: Vec<gelenk::integrators::IntegratorKind> = if integrators.is_empty() {
        std::iter::once(gelenk::integrators::IntegratorKind::SemiImplicitEuler)
            .chain(stability::SMOOTH_INTEGRATORS)
            .collect()
    } else {
        integrators
            .iter()
            .map(|name| {
                gelenk::world::parse_integrator(name).ok_or_else(|| {
                    format!(
                        "unknown integrator `{name}` (known: {})",
                        gelenk::world::INTEGRATOR_NAMES.join(", ")
                    )
                })
            })
            .collect::<Result<_, _>>()?
    };
    let cells = stability::run(&selected, &solver_kinds, &dts, &integrator_kinds, |cell| {
        let status = match &cell.outcome {
            None => "skipped".to_string(),
            Some(Ok(o)) => format!("{} {:.2e}", if o.pass { "pass" } else { "FAIL" }, o.figure),
            Some(Err(e)) => format!("error: {e}"),
        };
        eprintln!(
            "{:<15} {:<9} dt {:<9.6} {:<19} {status} ({:.1} s)",
            cell.case, cell.solver, cell.dt, cell.integrator, cell.seconds
        );
    });
    let markdown = stability::markdown(&cells, &selected);
    match out {
        None => print!("{markdown}"),
        Some(dir) => {
            std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
            for (name, text) in [("stability.md", markdown), ("stability.csv", stability::csv(&cells))] {
                let path = dir.join(name);
                std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
            }
        }
    }
    Ok(())
}

fn report_speed_error(
    out: &Path,
    quick: bool,
    peers: &Path,
    repeats: Option<usize>,
    scenes: Vec<String>,
) -> Result<(), String> {
    use gelenk::report::speed_error;
    use std::io::{IsTerminal, Write};
    let options = speed_error::SpeedErrorOptions {
        quick,
        peers_dir: peers.to_path_buf(),
        repeats: repeats.unwrap_or(if quick { 1 } else { 3 }),
        scenes,
    };
    let tty = std::io::stderr().is_terminal();
    let report = speed_error::run(&options, |what, fraction| {
        if tty {
            let filled = (fraction * 30.0).round() as usize;
            eprint!(
                "\r[{}{}] {:3.0}% {:<60}",
                "#".repeat(filled),
                ".".repeat(30 - filled.min(30)),
                fraction * 100.0,
                what
            );
            let _ = std::io::stderr().flush();
        }
    })
    .map_err(|e| e.to_string())?;
    if tty {
        eprintln!();
    }
    speed_error::write(&report, out).map_err(|e| e.to_string())?;
    println!(
        "{} measurements ({} failed) written to {}",
        report.rows.len(),
        report.failed.len(),
        out.display()
    );
    for g in &report.goal {
        let ours = g.gelenk.as_ref().map_or("none reaches it".to_string(), |m| {
            format!("{} dt={:.0e}: {:.0} µs at {:.1e} rad", m.configuration, m.dt, m.cost_us, m.error)
        });
        println!(
            "MuJoCo {} dt={:.0e}: {:.0} µs per simulated s at {:.1e} rad | gelenk {ours} | ratio {:.2}",
            g.mujoco.integrator,
            g.mujoco.dt,
            g.mujoco.cost_us,
            g.mujoco.error,
            g.ratio()
        );
    }
    if !report.goal.is_empty() {
        println!(
            "goal (gelenk's best at most half of MuJoCo's best at every error level, pendulum): {}",
            if report.goal_met() { "holds" } else { "does not hold" }
        );
    }
    Ok(())
}
