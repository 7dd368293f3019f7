//! Running a scene: [`run`] steps a [`Scene`] for its duration, applying its vehicle commands
//! before each step, records a trajectory ([`Recording`], written as CSV or JSON) and sums the run
//! up ([`RunSummary`]: steps per second, real-time factor, energy drift, penetration, solvers).
//! Nothing here prints; the command line (`gelenk simulate`) shows what [`run`] returns.
//! With [`RunOptions::record_frames`] the recording also holds what a viewer draws ([`Frame`]s).

use crate::io::scene::{Scene, SceneError};
use crate::model::Joint;
use crate::world::SolverKind;
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

mod frames;
pub use frames::{BodyPose, ContactSample, Frame, FramedBody};

/// Options of [`run`]; `None` keeps the scene's value.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunOptions {
    /// Simulated time (s) instead of the scene's `duration`.
    pub duration: Option<f64>,
    /// Time step (s) instead of the scene's `dt`. Changing it rebuilds the world from the scene
    /// file, which is only allowed before the world has stepped.
    pub dt: Option<f64>,
    /// Solver chain instead of the scene's (see [`crate::io::scene::parse_solvers`]); rebuilds
    /// the world as `dt`.
    pub solvers: Option<Vec<SolverKind>>,
    /// Record one row every this many steps instead of `[record] every`; 0 records nothing.
    pub record_every: Option<usize>,
    /// Also record a [`Frame`] (body poses, contact points, energy) with every row, into
    /// [`Recording::frames`], for the glTF export and the player (`crate::viz`).
    pub record_frames: bool,
    /// Relative softness of the rows instead of `[world] softness`
    /// ([`crate::world::WorldOptions::softness`]).
    pub softness: Option<f64>,
    /// The softened rows' damper share instead of `[world] softness_damping`
    /// ([`crate::world::WorldOptions::softness_damping`]; a fraction in [0, 1]).
    pub softness_damping: Option<f64>,
    /// Threads the islands of each step are solved on instead of `[world] threads`
    /// ([`crate::world::World::set_threads`]; ≥ 1).
    pub threads: Option<usize>,
    /// The contacts' position correction after each step on or off instead of `[world]
    /// contact_projection` ([`crate::world::WorldOptions::contact_projection`]).
    pub contact_projection: Option<bool>,
}

/// Most steps one [`run`] takes: 10⁹ steps are hours of any scene; more is a typo in `duration` or
/// `dt` (1e300 s, 1e-300 s) that would only spin.
const MAX_RUN_STEPS: u64 = 1_000_000_000;

/// One recorded row.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RecordedStep {
    /// Step number (0: the initial state).
    pub step: u64,
    /// Simulated time (s).
    pub time: f64,
    /// q (and v) of the recorded multibodies, as named by [`Recording::columns`].
    pub values: Vec<f64>,
    /// Total energy (J), when recorded.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy: Option<f64>,
    /// Contact points of the step.
    pub contacts: usize,
    /// Constraint rows of the step.
    pub rows: usize,
    /// Solver whose answer was used (empty without rows).
    pub solver: String,
    /// Its iterations or pivots.
    pub iterations: usize,
    /// Its certifying residual (m/s).
    pub residual: f64,
    /// Deepest penetration (m).
    pub max_penetration: f64,
}

/// A recorded trajectory: one [`RecordedStep`] every `every` steps, the initial state and the
/// last step included.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Recording {
    /// Scene name.
    pub scene: String,
    /// Time step (s).
    pub dt: f64,
    /// Names of the entries of [`RecordedStep::values`]: `multibody.joint` for a scalar joint,
    /// `multibody.joint.component` otherwise (`x y z qx qy qz qw` for a free joint); velocities
    /// end in `.v` or name their component (`vx … wz`).
    pub columns: Vec<String>,
    /// Whether rows carry the energy.
    pub energy: bool,
    /// The rows.
    pub rows: Vec<RecordedStep>,
    /// The bodies whose poses [`Recording::frames`] hold (empty unless
    /// [`RunOptions::record_frames`]). Not written to CSV or JSON.
    #[serde(skip)]
    pub bodies: Vec<FramedBody>,
    /// One frame per row (empty unless [`RunOptions::record_frames`]). Not written to CSV or JSON.
    #[serde(skip)]
    pub frames: Vec<Frame>,
}

impl Recording {
    /// Writes the rows as CSV: a header line (`step,time,<columns>[,energy],contacts,rows,solver,
    /// iterations,residual,max_penetration`), then one line per row.
    pub fn write_csv(&self, mut out: impl Write) -> std::io::Result<()> {
        let mut header = vec!["step".to_string(), "time".to_string()];
        header.extend(self.columns.iter().map(|c| csv_field(c)));
        if self.energy {
            header.push("energy".to_string());
        }
        header.extend(
            ["contacts", "rows", "solver", "iterations", "residual", "max_penetration"].map(String::from),
        );
        writeln!(out, "{}", header.join(","))?;
        let mut line = String::new();
        for row in &self.rows {
            use std::fmt::Write as _;
            line.clear();
            let _ = write!(line, "{},{}", row.step, row.time);
            for v in &row.values {
                let _ = write!(line, ",{v}");
            }
            if self.energy {
                let _ = write!(line, ",{}", row.energy.unwrap_or(f64::NAN));
            }
            let _ = write!(
                line,
                ",{},{},{},{},{},{}",
                row.contacts,
                row.rows,
                csv_field(&row.solver),
                row.iterations,
                row.residual,
                row.max_penetration
            );
            writeln!(out, "{line}")?;
        }
        out.flush()
    }

    /// Writes the recording as one JSON object `{"scene", "dt", "columns", "energy", "rows": [{"step",
    /// "time", "values", "energy"?, "contacts", "rows", "solver", "iterations", "residual",
    /// "max_penetration"}]}` (non-finite numbers become `null`).
    pub fn write_json(&self, mut out: impl Write) -> std::io::Result<()> {
        serde_json::to_writer(&mut out, self)?;
        writeln!(out)?;
        out.flush()
    }

    /// Writes the recording to `path`, as JSON if it ends in `.json`, as CSV if it ends in
    /// `.csv`; any other extension is an [`std::io::ErrorKind::InvalidInput`] error.
    pub fn save(&self, path: impl AsRef<Path>) -> std::io::Result<()> {
        let path = path.as_ref();
        let extension = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        let kind = match extension.as_deref() {
            Some("csv") => true,
            Some("json") => false,
            _ => {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    "the output file must end in .csv or .json",
                ))
            }
        };
        let file = std::io::BufWriter::new(std::fs::File::create(path)?);
        if kind {
            self.write_csv(file)
        } else {
            self.write_json(file)
        }
    }
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// What a run did. It serializes (serde) to what `gelenk simulate --json` prints: every field but
/// the recording, which [`Recording::save`] writes.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RunSummary {
    /// Scene name.
    pub scene: String,
    /// Steps taken.
    pub steps: u64,
    /// Time step (s).
    pub dt: f64,
    /// Simulated time (s).
    pub simulated_time: f64,
    /// Wall-clock time of the run (s), recording included.
    pub wall_time: f64,
    /// Steps per wall-clock second.
    pub steps_per_second: f64,
    /// Simulated seconds per wall-clock second.
    pub real_time_factor: f64,
    /// Total energy before the first step (J).
    pub energy_start: f64,
    /// Total energy after the last step (J).
    pub energy_end: f64,
    /// `energy_end − energy_start` (J): losses to contacts, damping and friction show as
    /// negative drift, energy created by the integrator or the solver as positive.
    pub energy_drift: f64,
    /// Deepest penetration over the run (m).
    pub max_penetration: f64,
    /// Most contact points in one step.
    pub max_contacts: usize,
    /// Most constraint rows in one step.
    pub max_rows: usize,
    /// Steps that had constraint rows to solve.
    pub solved_steps: u64,
    /// Steps whose answer came from each solver.
    pub solver_usage: BTreeMap<String, u64>,
    /// Solver failures and residual misses, summed over the steps: answers that passed the step
    /// on to the next solver of the chain, and last answers accepted above the tolerance.
    pub fallbacks: u64,
    /// Largest certifying residual of an accepted answer (m/s).
    pub max_residual: f64,
    /// Steps whose accepted answer's certifying residual is above the chain's tolerance (the
    /// last solver's answer accepted, [`crate::world::WorldOptions::accept_last`]).
    pub steps_above_tolerance: u64,
    /// Simulated time (s) from which every multibody was asleep to the end of the run; `None`
    /// when one was awake after the last step (always so with sleeping off, or with a
    /// kinematic body, which never sleeps).
    pub asleep_from: Option<f64>,
    /// Most islands of one step's problem.
    pub max_islands: usize,
    /// Most rows of one island.
    pub largest_island: usize,
    /// Mean iterations (or pivots) per solved step.
    pub mean_iterations: f64,
    /// Wall-clock seconds per phase of the step, summed over the steps, in the order of
    /// [`crate::world::PHASE_NAMES`]: kinematics, collision, free motion, rows and assembly,
    /// solve, integration and sleeping, contact projection.
    pub phase_time: [f64; 7],
    /// The recorded trajectory.
    #[serde(skip)]
    pub recording: Recording,
}

/// Steps `scene` for its duration (or `options.duration`), recording as its `[record]` table
/// (or `options.record_every`) says, and calls `progress` with the fraction done (0 to 1) about
/// every percent and at the end. Nothing is printed.
pub fn run(
    scene: &mut Scene,
    options: &RunOptions,
    mut progress: impl FnMut(f64),
) -> Result<RunSummary, SceneError> {
    if let Some(dt) = options.dt {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(SceneError::Options(format!("dt must be positive, got {dt}")));
        }
    }
    if options.solvers.as_ref().is_some_and(Vec::is_empty) {
        return Err(SceneError::Options("the solver chain is empty".to_string()));
    }
    let current = scene.world.options();
    let changes = options.dt.is_some_and(|dt| dt != current.dt)
        || options.solvers.as_ref().is_some_and(|s| *s != current.solvers);
    if changes {
        if scene.world.time() > 0.0 {
            return Err(SceneError::Options(
                "dt and the solver can only be changed before the world has stepped".to_string(),
            ));
        }
        scene.rebuild_with(options.dt, options.solvers.clone())?;
    }
    if let Some(softness) = options.softness {
        if !(softness.is_finite() && softness >= 0.0) {
            return Err(SceneError::Options(format!(
                "softness must be finite and non-negative, got {softness}"
            )));
        }
        scene.world.set_softness(softness);
    }
    if let Some(beta) = options.softness_damping {
        if !(0.0..=1.0).contains(&beta) {
            return Err(SceneError::Options(format!("softness_damping must be in [0, 1], got {beta}")));
        }
        scene.world.set_softness_damping(beta);
    }
    if let Some(threads) = options.threads {
        scene.world.set_threads(threads).map_err(|e| SceneError::Options(e.to_string()))?;
    }
    if let Some(enabled) = options.contact_projection {
        let projection = scene.world.options().contact_projection;
        scene.world.set_contact_projection(crate::world::ContactProjection { enabled, ..projection });
    }
    let duration = options.duration.unwrap_or(scene.duration);
    if !(duration.is_finite() && duration >= 0.0) {
        return Err(SceneError::Options(format!("duration must be non-negative, got {duration}")));
    }
    let dt = scene.world.options().dt;
    let (dt_min, dt_max) = crate::model::ranges::TIME_STEP_RANGE;
    if !(dt_min..=dt_max).contains(&dt) {
        return Err(SceneError::Options(format!(
            "dt = {} s is outside [{dt_min:e}, {dt_max}] s, the time steps gelenk accepts",
            crate::model::ranges::Num(dt)
        )));
    }
    let steps = (duration / dt - 1e-9).ceil().max(0.0);
    if steps > MAX_RUN_STEPS as f64 {
        return Err(SceneError::Options(format!(
            "{duration} s at dt = {dt} s is {steps:e} steps, more than {MAX_RUN_STEPS:e} (shorten the duration or lengthen dt)"
        )));
    }
    let steps = steps as u64;
    let every = options.record_every.unwrap_or(scene.record.every) as u64;

    let mut recording = Recording {
        scene: scene.name.clone(),
        dt,
        columns: record_columns(scene),
        energy: scene.record.energy,
        ..Recording::default()
    };
    let mut frames = if options.record_frames {
        let (recorder, bodies) = frames::FrameRecorder::new(&scene.world);
        recording.bodies = bodies;
        Some(recorder)
    } else {
        None
    };
    let mut summary = RunSummary { scene: scene.name.clone(), dt, ..RunSummary::default() };
    // The summary reports where the time went.
    scene.world.set_phase_timing(true);
    summary.energy_start = finite("total energy", 0, scene.world.total_energy())?;
    let mut iterations = 0u64;
    let tolerance = scene.world.options().tolerance;
    let start = Instant::now();
    if every > 0 {
        record_row(scene, 0, &mut recording, frames.as_mut())?;
    }
    let mut reported = 0u64;
    for step in 1..=steps {
        let time = scene.world.time();
        scene.apply_controls()?;
        let stats =
            scene.world.step().map_err(|source| SceneError::Step { step, time, source: Box::new(source) })?;
        summary.max_penetration =
            summary.max_penetration.max(finite("penetration", step, stats.max_penetration)?);
        summary.max_contacts = summary.max_contacts.max(stats.contacts);
        summary.max_rows = summary.max_rows.max(stats.rows);
        summary.fallbacks += stats.fallbacks.len() as u64;
        for (total, ns) in summary.phase_time.iter_mut().zip(stats.phase_ns) {
            *total += ns as f64 * 1e-9;
        }
        if stats.rows > 0 {
            summary.solved_steps += 1;
            *summary.solver_usage.entry(stats.solver.to_string()).or_default() += 1;
            summary.max_residual = summary.max_residual.max(stats.residual);
            summary.steps_above_tolerance += u64::from(stats.residual > tolerance);
            summary.max_islands = summary.max_islands.max(stats.islands);
            summary.largest_island = summary.largest_island.max(stats.largest_island);
            if stats.residual.is_nan() {
                return Err(SceneError::NonFiniteResult {
                    what: "solver residual",
                    step,
                    value: stats.residual,
                });
            }
            iterations += stats.iterations as u64;
        }
        summary.asleep_from = if stats.asleep == scene.world.multibody_count() {
            summary.asleep_from.or(Some(scene.world.time()))
        } else {
            None
        };
        if every > 0 && (step % every == 0 || step == steps) {
            record_row(scene, step, &mut recording, frames.as_mut())?;
        }
        let percent = step * 100 / steps;
        if percent > reported {
            reported = percent;
            progress(step as f64 / steps as f64);
        }
    }
    let wall = start.elapsed().as_secs_f64();
    if reported < 100 {
        progress(1.0);
    }
    summary.steps = steps;
    summary.simulated_time = steps as f64 * dt;
    summary.wall_time = wall;
    summary.steps_per_second = if wall > 0.0 { steps as f64 / wall } else { 0.0 };
    summary.real_time_factor = if wall > 0.0 { summary.simulated_time / wall } else { 0.0 };
    summary.energy_end = finite("total energy", steps, scene.world.total_energy())?;
    summary.energy_drift = summary.energy_end - summary.energy_start;
    summary.mean_iterations =
        if summary.solved_steps > 0 { iterations as f64 / summary.solved_steps as f64 } else { 0.0 };
    summary.recording = recording;
    Ok(summary)
}

/// `value`, or the error naming it when it is NaN or infinite.
fn finite(what: &'static str, step: u64, value: f64) -> Result<f64, SceneError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(SceneError::NonFiniteResult { what, step, value })
    }
}

fn record_row(
    scene: &mut Scene,
    step: u64,
    recording: &mut Recording,
    frames: Option<&mut frames::FrameRecorder>,
) -> Result<(), SceneError> {
    let total = if scene.record.energy || frames.is_some() {
        Some(finite("total energy", step, scene.world.total_energy())?)
    } else {
        None
    };
    if let (Some(recorder), Some(total)) = (frames, total) {
        let frame = recorder.capture(&scene.world, &recording.bodies, total);
        recording.frames.push(frame);
    }
    let energy = if scene.record.energy { total } else { None };
    let mut values = Vec::with_capacity(recording.columns.len());
    for &i in &scene.recorded {
        let state = &scene.world.multibody(i).state;
        values.extend(state.q.iter());
        if scene.record.velocities {
            values.extend(state.v.iter());
        }
    }
    let stats = scene.world.stats();
    recording.rows.push(RecordedStep {
        step,
        time: scene.world.time(),
        values,
        energy,
        contacts: stats.contacts,
        rows: stats.rows,
        solver: stats.solver.to_string(),
        iterations: stats.iterations,
        residual: stats.residual,
        max_penetration: stats.max_penetration,
    });
    Ok(())
}

fn record_columns(scene: &Scene) -> Vec<String> {
    let mut columns = Vec::new();
    for &i in &scene.recorded {
        let name = scene.world.multibody_name(i);
        let model = scene.world.multibody(i).model();
        let mut velocities = Vec::new();
        for j in 1..model.nbodies() {
            let joint = model.joint(j);
            let (q_labels, v_labels) = coordinate_labels(joint);
            let base = format!("{name}.{}", model.joint_name(j));
            for label in q_labels {
                columns.push(if label.is_empty() { base.clone() } else { format!("{base}.{label}") });
            }
            for label in v_labels {
                velocities.push(format!("{base}.{label}"));
            }
        }
        if scene.record.velocities {
            columns.extend(velocities);
        }
    }
    columns
}

/// Names of the q and v components of a joint, in order, as [`Recording::columns`] uses them:
/// a scalar joint's q component is unnamed (`""`: the column is the joint's name) and its v
/// component is `v`; a free joint's are `x y z qx qy qz qw` and `vx vy vz wx wy wz`.
pub fn coordinate_labels(joint: &Joint) -> (Vec<&'static str>, Vec<&'static str>) {
    match joint {
        Joint::Fixed => (vec![], vec![]),
        Joint::Hinge { .. } | Joint::Slider { .. } => (vec![""], vec!["v"]),
        Joint::Ball => (vec!["qx", "qy", "qz", "qw"], vec!["wx", "wy", "wz"]),
        Joint::Universal { .. } => (vec!["q1", "q2"], vec!["v1", "v2"]),
        Joint::Hinge2 { suspension: Some(_), .. } => {
            (vec!["travel", "steer", "spin"], vec!["vtravel", "vsteer", "vspin"])
        }
        Joint::Hinge2 { suspension: None, .. } => (vec!["steer", "spin"], vec!["vsteer", "vspin"]),
        Joint::Free => {
            (vec!["x", "y", "z", "qx", "qy", "qz", "qw"], vec!["vx", "vy", "vz", "wx", "wy", "wz"])
        }
        Joint::Planar => (vec!["x", "y", "theta"], vec!["vx", "vy", "w"]),
    }
}
