//! `gelenk bench dynamics` (median time per call of the rigid-body algorithms on random states)
//! and `gelenk bench world` (whole-step time of a scene or MJCF file, per phase).

use gelenk::prelude::*;
use nalgebra::DVector;
use rand::SeedableRng;
use serde_json::json;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

// The benchmarks.
#[derive(clap::Subcommand)]
pub enum BenchCommand {
    /// Median ns per call of rnea, crba, mass_matrix (M alone), aba and nle over a pool of
    /// random states.
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
    /// benches/peers/humanoid_fall.xml): median and mean µs per step, time per phase.
    World {
        /// Scene file (.toml) or MJCF file (.xml).
        scene: PathBuf,
        /// Solver chain instead of the scene's, e.g. `pgs50`, `pgs100,clarabel`, `newton`.
        #[arg(long)]
        solver: Option<String>,
        /// Relative softness of the rows instead of the scene's (R_ii = s A_ii; 0: hard).
        #[arg(long)]
        softness: Option<f64>,
        /// Share of the softened rows' impulses carried by their dampers instead of the
        /// scene's (a fraction in [0, 1]).
        #[arg(long)]
        softness_damping: Option<f64>,
        /// The contacts' position correction after each step on or off instead of the scene's
        /// (on by default).
        #[arg(long, value_name = "on|off")]
        contact_projection: Option<crate::Switch>,
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

/// Runs `gelenk bench …`.
pub fn run(command: BenchCommand) -> Result<(), String> {
    match command {
        BenchCommand::Dynamics { model, floating, json, rounds } => {
            bench_dynamics(&model, floating, json, rounds)
        }
        BenchCommand::World {
            scene,
            solver,
            softness,
            softness_damping,
            contact_projection,
            steps,
            settle,
            sleep,
            controls,
            rounds,
            json,
        } => {
            let contact_projection = contact_projection.map(crate::Switch::on);
            bench_world(
                &scene,
                solver.as_deref(),
                steps,
                settle,
                BenchOptions { sleep, controls, softness, softness_damping, contact_projection },
                rounds,
                json,
            )
        }
    }
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
    let options = gelenk::io::urdf::UrdfOptions { floating_base: floating, ..Default::default() };
    let model = gelenk::io::urdf::load_file(path, &options).map_err(|e| e.to_string())?;
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
    let mass_matrix_ns = median_ns(rounds, POOL, |k| {
        black_box(mass_matrix(&model, &mut data, &qs[k]).ok());
    });
    let aba_ns = median_ns(rounds, POOL, |k| {
        black_box(aba(&model, &mut data, &qs[k], &vs[k], &accs[k]).ok());
    });
    let nle_ns = median_ns(rounds, POOL, |k| {
        black_box(nonlinear_effects(&model, &mut data, &qs[k], &vs[k]).ok());
    });
    if as_json {
        println!(
            "{}",
            json!({"rnea_ns": rnea_ns, "crba_ns": crba_ns, "mass_matrix_ns": mass_matrix_ns,
                   "aba_ns": aba_ns, "nle_ns": nle_ns})
        );
    } else {
        println!(
            "model `{}` (nq = {}, nv = {}), median of {rounds} rounds over {POOL} random states",
            model.name(),
            model.nq(),
            model.nv()
        );
        for (name, ns) in [
            ("rnea", rnea_ns),
            ("crba", crba_ns),
            ("mass_matrix", mass_matrix_ns),
            ("aba", aba_ns),
            ("nle", nle_ns),
        ] {
            println!("{name:<11} {ns:>10.0} ns/call");
        }
    }
    Ok(())
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
            let scene = gelenk::io::mjcf::load_file(path).map_err(|e| e.to_string())?;
            let options = scene.world_options();
            Ok(BenchTarget::Mjcf(Box::new(scene.into_world(options).map_err(|e| e.to_string())?)))
        } else {
            Ok(BenchTarget::Scene(Box::new(crate::progress::load_scene(path)?)))
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

/// Switches of `bench world`: sleeping kept on, vehicle commands applied, the rows' softness and
/// their dampers' share, the contact projection on or off.
struct BenchOptions {
    sleep: bool,
    controls: bool,
    softness: Option<f64>,
    softness_damping: Option<f64>,
    contact_projection: Option<bool>,
}

fn bench_world(
    path: &Path,
    solver: Option<&str>,
    steps: usize,
    settle: usize,
    BenchOptions { sleep, controls, softness, softness_damping, contact_projection }: BenchOptions,
    rounds: usize,
    as_json: bool,
) -> Result<(), String> {
    let solvers =
        solver.map(gelenk::io::scene::parse_solvers).transpose().map_err(|e| format!("--solver: {e}"))?;
    let (mut medians, mut means, mut phases) = (Vec::new(), Vec::new(), Vec::new());
    let (mut rows, mut fallbacks, mut iterations, mut solver_usage) =
        (0usize, 0usize, 0usize, std::collections::BTreeMap::new());
    let (mut builds, mut kept_rows) = (0, 0);
    let mut quality = RunQuality::default();
    let load = || -> Result<BenchTarget, String> {
        let mut target = BenchTarget::load(path)?;
        let world = target.world();
        if let Some(s) = &solvers {
            world.set_solvers(s.clone());
        }
        if let Some(s) = softness {
            if !(s.is_finite() && s >= 0.0) {
                return Err(format!("--softness must be finite and non-negative, got {s}"));
            }
            world.set_softness(s);
        }
        if let Some(beta) = softness_damping {
            if !(0.0..=1.0).contains(&beta) {
                return Err(format!("--softness-damping must be in [0, 1], got {beta}"));
            }
            world.set_softness_damping(beta);
        }
        if let Some(enabled) = contact_projection {
            let projection = world.options().contact_projection;
            world.set_contact_projection(gelenk::world::ContactProjection { enabled, ..projection });
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
        let mut phase = [0u64; 7];
        (rows, fallbacks, iterations) = (0, 0, 0);
        solver_usage.clear();
        quality = RunQuality::default();
        let tolerance = target.world().options().tolerance;
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
            quality.add(stats, tolerance);
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
    let phase: Vec<f64> = (0..7).map(|k| median(phases.iter().map(|p| p[k]).collect())).collect();
    let (median_us, mean_us) = (median(medians), median(means));
    const PHASES: [&str; 7] = gelenk::world::PHASE_NAMES;
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
                   "contact_row_reuses": kept_rows, "max_penetration": quality.max_penetration,
                   "steps_above_tolerance": quality.steps_above_tolerance,
                   "max_residual": quality.max_residual, "max_islands": quality.max_islands,
                   "largest_island": quality.largest_island})
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
        println!(
            "deepest penetration {:.2} mm; {} of {steps} steps above the tolerance (largest residual {:.1e} m/s); islands: up to {}, the largest {} rows",
            quality.max_penetration * 1e3,
            quality.steps_above_tolerance,
            quality.max_residual,
            quality.max_islands,
            quality.largest_island
        );
    }
    Ok(())
}

/// What the timed episode of `bench world` answered, as `gelenk simulate` reports it: the
/// deepest penetration (m), the steps whose accepted answer is above the chain's tolerance and
/// the largest residual (m/s), the most islands of one step and the most rows of one island.
#[derive(Default)]
struct RunQuality {
    max_penetration: f64,
    steps_above_tolerance: usize,
    max_residual: f64,
    max_islands: usize,
    largest_island: usize,
}

impl RunQuality {
    fn add(&mut self, stats: &gelenk::world::StepStats, tolerance: f64) {
        self.max_penetration = self.max_penetration.max(stats.max_penetration);
        if stats.rows > 0 {
            self.steps_above_tolerance += usize::from(stats.residual > tolerance);
            self.max_residual = self.max_residual.max(stats.residual);
            self.max_islands = self.max_islands.max(stats.islands);
            self.largest_island = self.largest_island.max(stats.largest_island);
        }
    }
}
