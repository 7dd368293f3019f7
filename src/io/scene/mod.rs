//! Scene files (TOML): a [`World`] described in text — URDF models placed in the world, primitive
//! rigid bodies (single ones, stacks, grids and piles), ground planes, slopes and height fields,
//! contact materials, the solver chain and the time step. [`run`] (from [`crate::run`], also
//! reachable here) steps a scene for its duration, records a trajectory ([`Recording`], written
//! as CSV or JSON) and sums the run up ([`RunSummary`]: steps per second, real-time factor,
//! energy drift, penetration, solvers).
//!
//! Every key is checked: an unknown key, a value of the wrong type or out of range, a material
//! or joint that does not exist is a [`SceneError::Invalid`] naming the file, the line and
//! column, and the key path (`body[2].mass`). Paths in a scene (URDF files, package search
//! paths) are relative to the scene file's directory.
//!
//! Vehicle commands (`[[vehicle.command]]`) are applied by [`run`] (or [`Scene::apply_controls`])
//! before the first step that starts at or after their time `at`.
//!
//! ## Example
//!
//! ```
//! use gelenk::io::scene::{self, RunOptions};
//! let mut scene = scene::load_str(
//!     r#"
//!     name = "two boxes"
//!     [world]
//!     dt = 0.002
//!     duration = 0.02
//!     solver = ["pgs100", "clarabel"]
//!
//!     [contact]                 # material 0, the default of every collider
//!     mu = 0.8
//!
//!     [[material]]
//!     index = 1
//!     name = "rubber"
//!     restitution = 0.8
//!
//!     [[ground]]                # the plane z = 0
//!
//!     [[body]]
//!     name = "box"              # box0, box1
//!     shape = "box"
//!     size = [0.1, 0.1, 0.1]
//!     density = 500
//!     position = [0, 0, 0.05]
//!     count = 2
//!     spacing = [0, 0, 0.1]
//!
//!     [[body]]
//!     name = "ball"
//!     shape = "sphere"
//!     radius = 0.05
//!     mass = 0.2
//!     position = [0.5, 0, 1]
//!     velocity = [-1, 0, 0]
//!     material = "rubber"
//!     "#,
//!     ".",
//! )
//! .unwrap();
//! assert_eq!(scene.world.multibody_count(), 3);
//! let summary = scene::run(&mut scene, &RunOptions::default(), |_fraction| {}).unwrap();
//! assert_eq!(summary.steps, 10);
//! let mut csv = Vec::new();
//! summary.recording.write_csv(&mut csv).unwrap();
//! assert_eq!(String::from_utf8(csv).unwrap().lines().count(), 1 + 11); // header, steps 0..=10
//!
//! let error = scene::load_str("[[body]]\nshape = \"box\"\nsize = [1, 1, 1]\nmass = -1\n", ".")
//!     .err()
//!     .unwrap();
//! assert_eq!(error.to_string(), "<string>: line 4, column 8, `body[0].mass`: expected a positive number, got -1");
//! ```
//!
//! ## Schema
//!
//! Top level: `name` (default: the file's stem), `description` (free text).
//!
//! | table | key | meaning (default) |
//! |---|---|---|
//! | `[world]` | `dt` | time step, s (0.002) |
//! | | `duration` | simulated time of [`run`], s (1) |
//! | | `gravity` | `[x, y, z]`, m/s² (`[0, 0, -9.81]`) |
//! | | `solver` | solver chain, first choice first: a name or a list of `"lemke"`, `"clarabel"`, `"newton"`, `"newton-exact"`, `"pgs"`, `"pgsN"` (N sweeps) (`["newton-exact", "pgs100", "newton", "clarabel"]`) |
//! | | `threads` | threads the islands of each step's problem are solved on, ≥ 1; above 1 needs the `parallel` feature ([`World::set_threads`](crate::world::World::set_threads); 1) |
//! | | `tolerance` | residual (m/s) the chain accepts (1e-6) |
//! | | `softness` | relative compliance of contacts, limits, joint friction and motors, `R_ii = s A_ii` ([`WorldOptions::softness`](crate::world::WorldOptions::softness); 0: hard) |
//! | | `softness_damping` | share β ∈ [0, 1] of that compliance that is a damper beside the row's spring ([`WorldOptions::softness_damping`](crate::world::WorldOptions::softness_damping); 0) |
//! | | `accept_last` | take the last solver's answer above the tolerance rather than fail (true) |
//! | | `friction` | `"cone"`, `"pyramid"` (4 facets) or `"pyramidN"`, 3 ≤ N ≤ 64 (`"pyramid:N"` means the same) (`"cone"`) |
//! | | `margin` | contact margin, m (0.005) |
//! | | `speculative_within`, `speculative_factor` | contacts still apart get rows if their gap is at most `speculative_within` m or at most `speculative_factor` times the distance their points close in one step (`inf`: every contact within the margin) ([`crate::constraints::Speculation`]; 0.002, 2) |
//! | | `collide_joined_bodies` | also test bodies joined by a joint (false) |
//! | | `continuous_collision` | sweep colliders that move further than the margin in one step, so that fast bodies cannot pass through others ([`WorldOptions::continuous_collision`](crate::world::WorldOptions::continuous_collision); true) |
//! | | `contact_projection` | after each step, push contacts deeper than 0.5 mm out by a change of the configuration alone, not of the velocity ([`WorldOptions::contact_projection`](crate::world::WorldOptions::contact_projection); true) |
//! | | `mass_matrix_reuse` | reuse a multibody's factored mass matrix while no joint coordinate has moved further than this since it was factored, and the constraint problem's W built on it while the rows stay the same: `true`, `false` or a tolerance in rad or m ([`WorldOptions::mass_matrix_reuse`](crate::world::WorldOptions::mass_matrix_reuse); true: 1e-8) |
//! | | `contact_reuse` | keep a pair's contact points while it moves less than this, refreshing only their distances: `true`, `false` or `{ translation = m, rotation = rad }` ([`crate::collision::ManifoldReuse`]; true: 1e-8 m, 1e-7 rad) |
//! | | `sleep` | let resting bodies sleep (true) |
//! | | `integrator` | scheme of the steps without contacts, limits, motors or joint friction: `"semi-implicit-euler"` (the velocity-level step throughout), `"explicit-euler"`, `"velocity-verlet"`, `"rk4"`, `"dopri45"`, `"gbs"`/`"gbsN"` or `"implicit-euler"` ([`WorldOptions::integrator`](crate::world::WorldOptions::integrator); `"semi-implicit-euler"`) |
//! | `[contact]` | `mu`, `mu2`, `restitution`, `bounce_velocity`, `erp`, `cfm`, `surface_layer`, `max_correcting_velocity` | parameters of material 0 ([`ContactParameters`](crate::constraints::ContactParameters)) |
//! | `[limits]` | `erp`, `cfm`, `restitution`, `bounce_velocity`, `margin`, `speculative_within` | joint-limit parameters ([`JointLimitParameters`](crate::constraints::JointLimitParameters); a stop within `margin` but further than `speculative_within` gets a row only if the step can close the gap) |
//! | `[[material]]` | `index` (≥ 1, required), `name`, and the keys of `[contact]` | a material; unset parameters are `[contact]`'s |
//! | `[[pair]]` | `materials = [a, b]` (indices or names) and the keys of `[contact]` | parameters when materials a and b touch, instead of the combination rule |
//! | `[[ground]]` | `kind` | `"plane"` (default), `"slope"` or `"heightfield"` |
//! | | `name`, `material` | collider name (`ground{i}`), material index or name (0) |
//! | | `position`, `rpy` or `quaternion` | pose of the ground's frame (identity); rpy in rad, quaternion `[x, y, z, w]` |
//! | | `normal`, `offset` | plane: the surface `normal · p = offset` in the ground's frame (`[0, 0, 1]`, 0) |
//! | | `angle_deg`, `direction` | slope: a plane through the frame's origin rising at `angle_deg` (required, in (−90, 90)) along the horizontal `direction` (`[1, 0, 0]`); heightfield: a tilt added to the heights (0) |
//! | | `size` | heightfield: `[size_x, size_y]`, m (required), centred on the frame's origin |
//! | | `heights` | heightfield: rows of heights, m; `heights[i][j]` is at `x_i`, `y_j` (at least 2×2) |
//! | | `samples`, `bump_height`, `bump_wavelength` | generated heightfield (when `heights` is absent): `[nx, ny]` samples, at most 2²² in all (`[33, 33]`), bumps `h·sin(2πx/λ)·sin(2πy/λ)` (0 m, 1 m) |
//! | `[[urdf]]` | `path` | URDF file (required), relative to the scene file |
//! | | `name` | multibody name (the robot's name) |
//! | | `floating` | free joint at the root (false: the root link is fixed to the world) |
//! | | `position`, `rpy` or `quaternion` | pose of the root link in the world (identity) |
//! | | `velocity`, `angular_velocity` | floating base: initial velocity of the root link, world axes (0) |
//! | | `joints` | initial positions, `{ joint = value }` (a list for joints of several coordinates); within limits. Other joints start at their neutral position, or the nearest position within their limits where it is outside them |
//! | | `joint_velocities` | initial rates, `{ joint = value }` |
//! | | `limits` | position limits overriding the file's, `{ joint = [lower, upper] }` (hinge and slider joints) |
//! | | `servo` | `{ gain, max_velocity, max_force }`: hold every scalar joint at its initial position |
//! | | `pose_servo` | `{ gain, max_velocity, torque_per_kg }`: a powered ragdoll — every joint but the floating base (ball joints too) driven to its initial position by a [`PoseServo`](crate::world::PoseServo) whose torque bound is `torque_per_kg` × the mass the joint moves |
//! | | `count`, `spacing`, `jitter`, `seed` | copies of the model as for `[[body]]` (named `{name}{k}` or `{name}_{i}_{j}_{k}`) |
//! | | `random_rotation` | floating base: each copy turned by a uniformly random rotation (seeded by `seed`) (false) |
//! | | `spin` | floating base: an angular velocity of this magnitude (rad/s) about a random axis (seeded) added to `angular_velocity` (0) |
//! | | `self_collision` | collisions between the model's own bodies (false) |
//! | | `material` | material of every collider of the model (0) |
//! | | `missing_meshes` | `"error"` (default) or `"skip"` collision meshes that cannot be found or read |
//! | | `package_paths` | directories searched for `package://` URIs |
//! | | `strict` | every URDF loader warning is an error ([`UrdfOptions::strict`](crate::io::urdf::UrdfOptions::strict)) (false) |
//! | | `balance_inertia` | inconsistent link inertias balanced as MuJoCo's `balanceinertia` ([`UrdfOptions::balance_inertia`](crate::io::urdf::UrdfOptions::balance_inertia)) (false) |
//! | | `inertia_from_collision` | each link's rotational inertia computed from its collision shapes with the file's mass, as PyBullet does by default ([`UrdfOptions::inertia_from_collision`](crate::io::urdf::UrdfOptions::inertia_from_collision)) (false) |
//! | `[[body]]` | `shape` | `"box"` (`size = [x, y, z]`), `"sphere"` (`radius`), `"capsule"` or `"cylinder"` (`radius`, `length` along z) |
//! | | `mass` or `density` | kg, or kg/m³ (density 1000) |
//! | | `name` | multibody name (`body{i}`); with `count = n`, `{name}{k}`; with `count = [nx, ny, nz]`, `{name}_{i}_{j}_{k}` |
//! | | `position`, `rpy` or `quaternion` | pose of the (first) body (identity) |
//! | | `velocity`, `angular_velocity` | initial velocity, world axes (0) |
//! | | `count`, `spacing` | `n` copies at `position + k·spacing`, or a grid `[nx, ny, nz]` at `position + (i·sx, j·sy, k·sz)`; at most 100 000 copies |
//! | | `jitter`, `seed` | random offset of each copy, uniform in ±jitter m per axis (0), and its seed (0) |
//! | | `material` | material index or name (0) |
//! | | `fixed` | static geometry instead of a free body (false) |
//! | `[[vehicle]]` | `multibody` | name of a floating `[[urdf]]` multibody to drive with [`crate::vehicle::Vehicle`] (required) |
//! | | `front`, `rear` | wheel joints `[left, right]`: hinge2 joints, or hinges spinning the wheels (on the chassis or on steering hinges) (`["front_left", "front_right"]`, `["rear_left", "rear_right"]`) |
//! | | `driven` | `"rear"` (default), `"front"` or `"all"`: the wheels the throttle drives |
//! | | `wheel_radius`, `drive_torque`, `brake_torque`, `steering_gain`, `steering_rate`, `steering_torque`, `patch_contact` | [`crate::vehicle::VehicleConfig`] (its `buggy()` values) |
//! | `[[vehicle.command]]` | `at` | simulated time (s) from which the command holds (required) |
//! | | `speed` | throttle: target speed, m/s (releases the brakes) |
//! | | `coast` | `true`: no drive torque, brakes released |
//! | | `steering_deg` | bicycle-model steering angle, degrees, positive = left |
//! | | `brake` | brakes on (`true`) or off (`false`) |
//! | `[record]` | `every` | record one row every this many steps (1) |
//! | | `multibodies` | names of the multibodies recorded (all) |
//! | | `velocities`, `energy` | also record v, and the total energy (false) |
//!
//! Loading goes in stages, one private module each: `values` checks single values (a positive
//! number, a vector of three, a count), `schema` declares the tables a file may hold, `build`
//! turns the checked document into a [`World`], and `source` maps a byte offset back to its line,
//! column and key path for errors.

mod build;
mod schema;
mod source;
mod values;

/// Running a loaded scene lives in [`crate::run`]; these are reachable here too, beside
/// [`load_file`].
pub use crate::run::{run, RecordedStep, Recording, RunOptions, RunSummary};

use crate::constraints::FrictionModel;
use crate::error::ModelError;
use crate::io::urdf::UrdfError;
use crate::vehicle::Vehicle;
use crate::world::{SolverKind, StepError, World};
use build::Overrides;
use source::Source;
use std::fmt;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Names of the integrators a scene may ask for (`gbsN` too): the world's velocity-level
/// semi-implicit Euler step, or a scheme of [`crate::integrators`] for the steps without contact
/// ([`crate::world::smooth`]).
pub const INTEGRATORS: [&str; 9] = crate::world::INTEGRATOR_NAMES;

/// Where in a scene file something is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    /// The file (`<string>` for text).
    pub file: String,
    /// Line, from 1 (0 when unknown).
    pub line: usize,
    /// Column, from 1, in characters.
    pub column: usize,
    /// Path of the key (`body[2].mass`, `world.solver[1]`); empty when unknown.
    pub key: String,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if self.line > 0 {
            write!(f, ": line {}, column {}", self.line, self.column)?;
        }
        if !self.key.is_empty() {
            write!(f, "{} `{}`", if self.line > 0 { "," } else { ":" }, self.key)?;
        }
        Ok(())
    }
}

/// Why a scene could not be loaded or run.
#[derive(Debug, Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// File path.
        file: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Not valid TOML, an unknown key, a value of the wrong type or out of range, a reference to
    /// something that does not exist.
    #[error("{at}: {message}")]
    Invalid {
        /// Where.
        at: Location,
        /// What is wrong.
        message: String,
    },
    /// A `[[urdf]]` model could not be loaded.
    #[error("{at}: {source}")]
    Urdf {
        /// The entry's `path`.
        at: Location,
        /// The URDF error.
        source: Box<UrdfError>,
    },
    /// A model built from a `[[body]]` is invalid.
    #[error("{at}: {source}")]
    Model {
        /// The entry.
        at: Location,
        /// The model error.
        source: Box<ModelError>,
    },
    /// The world refused a model or a piece of geometry (a mesh, a degenerate shape).
    #[error("{at}: {source}")]
    World {
        /// The entry.
        at: Location,
        /// The world's error.
        source: Box<StepError>,
    },
    /// Invalid [`RunOptions`].
    #[error("run options: {0}")]
    Options(String),
    /// A quantity of the run came out NaN or infinite (the state stayed finite, but a sum over
    /// it overflowed: masses, speeds or heights too large for double precision).
    #[error("{what} is not finite ({value}) after {step} steps")]
    NonFiniteResult {
        /// The quantity ("total energy", "penetration", "residual").
        what: &'static str,
        /// Steps done when it was found.
        step: u64,
        /// The value.
        value: f64,
    },
    /// A step failed.
    #[error("step {step} (t = {time} s): {source}")]
    Step {
        /// Number of the step that failed, from 1.
        step: u64,
        /// Simulated time before the step (s).
        time: f64,
        /// The error.
        source: Box<StepError>,
    },
}

/// What [`run`] records, from the scene's `[record]` table.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordOptions {
    /// One row every this many steps (0: nothing is recorded).
    pub every: usize,
    /// Record generalized velocities too.
    pub velocities: bool,
    /// Record the total energy (J).
    pub energy: bool,
}

impl Default for RecordOptions {
    fn default() -> Self {
        Self { every: 1, velocities: false, energy: false }
    }
}

/// A loaded scene: the world at its initial state and how to run it.
pub struct Scene {
    /// Name (`name` key, else the file's stem).
    pub name: String,
    /// Free text (`description` key).
    pub description: String,
    /// The scene file, if loaded from one.
    pub file: Option<PathBuf>,
    /// The world, at the initial state.
    pub world: World,
    /// Simulated time of a run (s).
    pub duration: f64,
    /// Integrator name (one of [`INTEGRATORS`]).
    pub integrator: String,
    /// Multibodies recorded, by index.
    pub recorded: Vec<usize>,
    /// What is recorded.
    pub record: RecordOptions,
    /// Things left out while loading (skipped meshes).
    pub warnings: Vec<String>,
    /// Vehicles of `[[vehicle]]` entries with their timed commands.
    pub vehicles: Vec<ScriptedVehicle>,
    source: Source,
}

/// One command of a `[[vehicle.command]]` entry: what changes at time `at`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TimedCommand {
    /// Simulated time (s) from which the command holds.
    pub at: f64,
    /// New target speed (m/s), releasing the brakes.
    pub speed: Option<f64>,
    /// Coast: no drive torque, brakes released.
    pub coast: bool,
    /// New steering angle (rad, positive = left).
    pub steering: Option<f64>,
    /// Brakes on or off.
    pub brake: Option<bool>,
}

/// A vehicle of a scene and its commands, sorted by time.
#[derive(Clone, Debug, PartialEq)]
pub struct ScriptedVehicle {
    /// The controller.
    pub vehicle: Vehicle,
    /// Commands, by increasing `at`.
    pub commands: Vec<TimedCommand>,
    /// Commands applied so far.
    pub applied: usize,
}

impl fmt::Debug for Scene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Scene")
            .field("name", &self.name)
            .field("file", &self.file)
            .field("multibodies", &self.world.multibody_count())
            .field("dt", &self.world.options().dt)
            .field("duration", &self.duration)
            .field("integrator", &self.integrator)
            .field("recorded", &self.recorded)
            .field("record", &self.record)
            .field("vehicles", &self.vehicles.len())
            .finish_non_exhaustive()
    }
}

impl Scene {
    /// Index of the multibody called `name`.
    pub fn multibody(&self, name: &str) -> Option<usize> {
        (0..self.world.multibody_count()).find(|&i| self.world.multibody_name(i) == name)
    }

    /// Applies every vehicle command whose time has come (`at` ≤ the world's time plus half a
    /// step), in order; [`run`] calls it before each step.
    pub fn apply_controls(&mut self) -> Result<(), SceneError> {
        let now = self.world.time() + 0.5 * self.world.options().dt;
        for v in &mut self.vehicles {
            while let Some(c) = v.commands.get(v.applied).copied().filter(|c| c.at <= now) {
                let failed = |e: crate::vehicle::VehicleError| SceneError::Options(e.to_string());
                if let Some(angle) = c.steering {
                    v.vehicle.set_steering(&mut self.world, angle).map_err(failed)?;
                }
                if let Some(speed) = c.speed {
                    v.vehicle.set_speed(&mut self.world, speed).map_err(failed)?;
                }
                if c.coast {
                    v.vehicle.coast(&mut self.world);
                }
                if let Some(on) = c.brake {
                    v.vehicle.set_brake(&mut self.world, on);
                }
                v.applied += 1;
            }
        }
        Ok(())
    }

    /// Builds the scene again from its text: the world back at its initial state.
    pub fn reset(&mut self) -> Result<(), SceneError> {
        *self = build::build(self.source.clone(), &Overrides::default(), &mut |_| {})?;
        Ok(())
    }

    /// A new copy of the scene built from its text: its world at the initial state, this one
    /// left as it is (batched rollouts build one world per rollout this way).
    pub fn rebuilt(&self) -> Result<Scene, SceneError> {
        build::build(self.source.clone(), &Overrides::default(), &mut |_| {})
    }

    /// Builds the scene again from its text with `dt` and the solver chain replaced where given
    /// (the world back at its initial state); [`run`] uses it for its options.
    pub(crate) fn rebuild_with(
        &mut self,
        dt: Option<f64>,
        solvers: Option<Vec<SolverKind>>,
    ) -> Result<(), SceneError> {
        *self = build::build(self.source.clone(), &Overrides { dt, solvers }, &mut |_| {})?;
        Ok(())
    }
}

/// How far the building of a scene has come: `built` of its `total` bodies and models, each
/// copy of a `count` counted once (grounds and vehicles are not counted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SetUpProgress {
    /// Bodies and models built so far.
    pub built: usize,
    /// Bodies and models the scene has.
    pub total: usize,
}

/// Loads a scene file, at most [`crate::io::limits::ReadLimits::max_bytes`] of it (the default
/// limits; the text's tables and arrays nest at most `max_data_depth` deep).
pub fn load_file(path: impl AsRef<Path>) -> Result<Scene, SceneError> {
    load_file_with_progress(path, |_| {})
}

/// [`load_file`], telling `progress` after each body or model is built (a scene of many
/// copies takes seconds to build: `gelenk` shows a progress bar on a terminal with it).
pub fn load_file_with_progress(
    path: impl AsRef<Path>,
    mut progress: impl FnMut(SetUpProgress),
) -> Result<Scene, SceneError> {
    let path = path.as_ref();
    let file = path.display().to_string();
    let text = crate::io::limits::ReadLimits::default()
        .read_text_io(path)
        .map_err(|source| SceneError::Io { file: file.clone(), source })?;
    let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let source = Source { file, path: Some(path.to_path_buf()), stem, text, base_dir };
    build::build(source, &Overrides::default(), &mut progress)
}

/// Loads a scene from text; relative paths in it resolve against `base_dir`.
pub fn load_str(text: &str, base_dir: impl AsRef<Path>) -> Result<Scene, SceneError> {
    let source = Source {
        file: "<string>".to_string(),
        path: None,
        stem: "scene".to_string(),
        text: text.to_string(),
        base_dir: base_dir.as_ref().to_path_buf(),
    };
    build::build(source, &Overrides::default(), &mut |_| {})
}

/// Parses a solver chain written as in `[world] solver` or on a command line: names separated
/// by commas (`"pgs100,clarabel"`), each `lemke`, `clarabel`, `pgs` or `pgsN`.
pub fn parse_solvers(text: &str) -> Result<Vec<SolverKind>, String> {
    let chain = text
        .split(',')
        .map(str::trim)
        .map(|name| {
            SolverKind::parse(name).ok_or_else(|| {
                format!(
                    "unknown solver `{name}` (known: lemke, clarabel, newton, newton-exact, pgs, pgsN with N >= 1 sweeps)"
                )
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    if chain.is_empty() {
        return Err("the solver chain is empty".to_string());
    }
    Ok(chain)
}

/// Parses a friction model: `cone`, `pyramid` (4 facets) or `pyramidN` (N facets, 3 ≤ N ≤
/// [`crate::constraints::MAX_PYRAMID_FACETS`]), as in `[world] friction` and on the command line.
///
/// `pyramidN` follows the solver chain's `pgsN` and the integrators' `gbsN`; `pyramid:N` is read
/// with the same meaning, as it is the form `meta.json` files record
/// ([`crate::io::problem::ProblemMeta::friction`]).
pub fn parse_friction(text: &str) -> Result<FrictionModel, String> {
    let max = crate::constraints::MAX_PYRAMID_FACETS;
    if text == "cone" {
        return Ok(FrictionModel::Cone);
    }
    if text == "pyramid" {
        return Ok(FrictionModel::Pyramid { facets: 4 });
    }
    let count = text.strip_prefix("pyramid").map(|n| n.strip_prefix(':').unwrap_or(n));
    match count.map(str::parse::<usize>) {
        Some(Ok(facets)) if (3..=max).contains(&facets) => Ok(FrictionModel::Pyramid { facets }),
        Some(Ok(_)) => Err(format!("friction model `{text}`: a pyramid needs 3 <= N <= {max} facets")),
        _ => Err(format!(
            "unknown friction model `{text}` (known: cone, pyramid (4 facets), pyramidN with 3 <= N <= {max} facets; pyramid:N is pyramidN)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn friction_models_parse_in_both_spellings_with_the_same_meaning() {
        assert_eq!(parse_friction("cone"), Ok(FrictionModel::Cone));
        assert_eq!(parse_friction("pyramid"), Ok(FrictionModel::Pyramid { facets: 4 }));
        for facets in [3, 6, crate::constraints::MAX_PYRAMID_FACETS] {
            let model = Ok(FrictionModel::Pyramid { facets });
            assert_eq!(parse_friction(&format!("pyramid{facets}")), model);
            assert_eq!(parse_friction(&format!("pyramid:{facets}")), model);
        }
        for out_of_range in ["pyramid2", "pyramid:2", "pyramid65", "pyramid:0"] {
            let message = parse_friction(out_of_range).unwrap_err();
            assert!(message.contains(out_of_range) && message.contains("3 <= N <= 64 facets"), "{message}");
        }
        for unknown in ["", "Cone", "pyramid:", "pyramid:x", "pyramids", "pyramid::4", "cone:4"] {
            let message = parse_friction(unknown).unwrap_err();
            assert!(message.starts_with("unknown friction model"), "{unknown}: {message}");
        }
    }
}
