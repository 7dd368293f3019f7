//! `gelenk simulate` (run a scene file, print its summary, record its states, export it as
//! glTF) and `gelenk render` (a filmstrip of a scene as a PNG).

use gelenk::io::scene;
use std::path::PathBuf;

// Arguments of `gelenk simulate`.
#[derive(clap::Args)]
pub struct SimulateArgs {
    /// Scene file.
    scene: PathBuf,
    /// Simulated time (s) instead of the scene's.
    #[arg(long)]
    duration: Option<f64>,
    /// Time step (s) instead of the scene's.
    #[arg(long)]
    dt: Option<f64>,
    /// Solver chain instead of the scene's, e.g. `pgs50`, `lemke,clarabel`, `newton`.
    #[arg(long)]
    solver: Option<String>,
    /// Relative softness of contacts, limits, joint friction and motors instead of the
    /// scene's (R_ii = s A_ii; 0: hard).
    #[arg(long)]
    softness: Option<f64>,
    /// Share of the softened rows' impulses carried by a damper beside each row's spring,
    /// instead of the scene's (a fraction in [0, 1]; see `softness_damping` in docs/scenes.md).
    #[arg(long)]
    softness_damping: Option<f64>,
    /// Threads the islands of each step are solved on instead of the scene's (≥ 1; the
    /// trajectory is the same on any count).
    #[arg(long)]
    threads: Option<usize>,
    /// The contacts' position correction after each step on or off instead of the scene's
    /// (`[world] contact_projection`; on by default).
    #[arg(long, value_name = "on|off")]
    contact_projection: Option<crate::Switch>,
    /// Write the recorded states to FILE.csv or FILE.json.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write the run as binary glTF to FILE.glb: the bodies' collision shapes and their motion,
    /// at the scene's recording rate.
    #[arg(long, value_name = "FILE")]
    gltf: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

// Arguments of `gelenk render`.
#[derive(clap::Args)]
pub struct RenderArgs {
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
}

/// Runs `gelenk simulate`: a progress bar on a terminal's stderr, then the summary on stdout.
pub fn simulate(args: &SimulateArgs) -> Result<(), String> {
    let mut loaded = crate::progress::load_scene(&args.scene)?;
    let solvers =
        args.solver.as_deref().map(scene::parse_solvers).transpose().map_err(|e| format!("--solver: {e}"))?;
    // Created before the run: a path that cannot be written fails now, not after it.
    let glb = args
        .gltf
        .as_deref()
        .map(|path| gelenk::viz::OutputFile::create(path, "glb"))
        .transpose()
        .map_err(|e| e.to_string())?;
    let record_every = if args.out.is_some() || glb.is_some() { None } else { Some(0) };
    let options = scene::RunOptions {
        duration: args.duration,
        dt: args.dt,
        solvers,
        record_every,
        record_frames: glb.is_some(),
        softness: args.softness,
        softness_damping: args.softness_damping,
        threads: args.threads,
        contact_projection: args.contact_projection.map(crate::Switch::on),
    };
    let summary = scene::run(&mut loaded, &options, crate::progress::run_bar()).map_err(|e| e.to_string())?;
    for warning in &loaded.warnings {
        eprintln!("gelenk: warning: {warning}");
    }
    if let Some(out) = &args.out {
        summary.recording.save(out).map_err(|e| format!("{}: cannot write: {e}", out.display()))?;
    }
    if let Some(glb) = glb {
        let bytes =
            gelenk::viz::gltf::glb_bytes(&loaded.world, &summary.recording).map_err(|e| e.to_string())?;
        glb.commit(&bytes).map_err(|e| e.to_string())?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?);
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
            "solver: {} steps with rows ({}); {} fallbacks; {} steps above tolerance; max residual {:.2e} m/s; mean iterations {:.1}",
            summary.solved_steps,
            usage.join(", "),
            summary.fallbacks,
            summary.steps_above_tolerance,
            summary.max_residual,
            summary.mean_iterations
        );
        println!("islands: up to {} in a step, largest {} rows", summary.max_islands, summary.largest_island);
        match summary.asleep_from {
            Some(t) => println!("asleep from {t:.3} s to the end"),
            None => println!("awake at the end"),
        }
        let per_step = 1e6 / summary.steps.max(1) as f64;
        let phases: Vec<String> = gelenk::world::PHASE_NAMES
            .iter()
            .zip(&summary.phase_time)
            .map(|(name, seconds)| format!("{name} {:.1}", seconds * per_step))
            .collect();
        println!("mean µs per phase: {}", phases.join(", "));
    }
    Ok(())
}

/// Runs `gelenk render`.
pub fn render(args: &RenderArgs) -> Result<(), String> {
    let mut loaded = crate::progress::load_scene(&args.scene)?;
    let options =
        gelenk::render::RenderOptions { frames: args.frames, duration: args.duration, ..Default::default() };
    let summary =
        gelenk::render::render_scene(&mut loaded, &options, &args.out).map_err(|e| e.to_string())?;
    let times: Vec<String> = summary.frame_times.iter().map(|t| format!("{t:.3}")).collect();
    println!(
        "{}: {} steps, {} frames at t = {} s -> {} ({}×{} px)",
        loaded.name,
        summary.steps,
        times.len(),
        times.join(", "),
        args.out.display(),
        summary.size.0,
        summary.size.1
    );
    Ok(())
}
