//! `gelenk report stability` (the hard-case table) and `gelenk report speed-error` (error
//! against cost of integrators and solver settings): the reports run in the library; this parses
//! their options and prints their progress and results.

use std::path::{Path, PathBuf};

// The reports.
#[derive(clap::Subcommand)]
pub enum ReportCommand {
    /// The hard-case suite (tests/hard_cases.rs) for the default solver chain, every solver
    /// and time step: a pass/fail table with the measured figure and the cost of a step in each
    /// cell, as stability.md and stability.csv in DIR, rewritten as each cell finishes
    /// (markdown on stdout at the end without --out). Progress goes to stderr.
    Stability {
        /// Output directory.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Only these cases (comma-separated names; default: all).
        #[arg(long, value_delimiter = ',')]
        cases: Vec<String>,
        /// Only these columns: default (the world's default chain), lemke, clarabel, newton,
        /// pgsN (default: default, lemke, clarabel, pgs10, pgs50).
        #[arg(long, value_delimiter = ',')]
        solvers: Vec<String>,
        /// Wall-clock budget of one cell in s: a cell still running then is recorded as
        /// "timeout" (default 120; 10 with --quick).
        #[arg(long)]
        budget: Option<f64>,
        /// The default chain alone at dt = 1/60 s, 10 s per cell at most: the whole suite in
        /// under a minute (--solvers, --dt and --budget still apply).
        #[arg(long)]
        quick: bool,
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
        #[arg(long, default_value = "benches/peers")]
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

/// Runs `gelenk report …`.
pub fn run(command: ReportCommand) -> Result<(), String> {
    match command {
        ReportCommand::Stability { out, cases, solvers, dt, integrators, budget, quick } => {
            let options = StabilityOptions { cases, solvers, dts: dt, integrators, budget, quick };
            report_stability(out.as_deref(), &options)
        }
        ReportCommand::SpeedError { out, quick, peers, repeats, scenes } => {
            report_speed_error(&out, quick, &peers, repeats, scenes)
        }
    }
}

/// The selection of `gelenk report stability`.
struct StabilityOptions {
    cases: Vec<String>,
    solvers: Vec<String>,
    dts: Vec<f64>,
    integrators: Vec<String>,
    budget: Option<f64>,
    quick: bool,
}

fn report_stability(out: Option<&Path>, options: &StabilityOptions) -> Result<(), String> {
    use gelenk::report::stability;
    let StabilityOptions { cases, solvers, dts, integrators, budget, quick } = options;
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
    let columns: Vec<stability::Column> = if !solvers.is_empty() {
        solvers
            .iter()
            .map(|name| stability::Column::parse(name).ok_or_else(|| format!("unknown solver `{name}`")))
            .collect::<Result<_, _>>()?
    } else if *quick {
        vec![stability::Column::Default]
    } else {
        stability::COLUMNS.to_vec()
    };
    let dts: Vec<f64> = if !dts.is_empty() {
        dts.to_vec()
    } else if *quick {
        stability::TIME_STEPS[..1].to_vec()
    } else {
        stability::TIME_STEPS.to_vec()
    };
    let budget = budget.unwrap_or(if *quick { 10.0 } else { 120.0 });
    if !(budget > 0.0 && budget <= 1e6) {
        return Err(format!("budget {budget} s is outside (0, 1e6] s"));
    }
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
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    // Each finished cell rewrites the files, so that an interrupted run leaves its results.
    let mut finished: Vec<stability::Cell> = Vec::new();
    let mut write_error: Option<String> = None;
    let budget = Some(std::time::Duration::from_secs_f64(budget));
    let cells = stability::run(&selected, &columns, &dts, &integrator_kinds, budget, |cell| {
        let status = match &cell.outcome {
            stability::CellOutcome::Error(e) => format!("error: {e}"),
            _ => stability::cell_text(cell),
        };
        eprintln!(
            "{:<15} {:<9} dt {:<9.6} {:<19} {status} ({:.1} s)",
            cell.case, cell.solver, cell.dt, cell.integrator, cell.seconds
        );
        finished.push(cell.clone());
        if let (Some(dir), None) = (out, &write_error) {
            write_error = write_stability(dir, &finished, &selected).err();
        }
    });
    if let Some(e) = write_error {
        return Err(e);
    }
    match out {
        None => print!("{}", stability::markdown(&cells, &selected)),
        Some(dir) => write_stability(dir, &cells, &selected)?,
    }
    Ok(())
}

/// Writes stability.md and stability.csv of `cells` into `dir`.
fn write_stability(
    dir: &Path,
    cells: &[gelenk::report::stability::Cell],
    cases: &[gelenk::report::stability::Case],
) -> Result<(), String> {
    use gelenk::report::stability;
    for (name, text) in
        [("stability.md", stability::markdown(cells, cases)), ("stability.csv", stability::csv(cells))]
    {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
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
