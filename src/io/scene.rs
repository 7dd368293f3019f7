//! Scene files (TOML): a [`World`] described in text — URDF models placed in the world, primitive
//! rigid bodies (single ones, stacks, grids and piles), ground planes, slopes and height fields,
//! contact materials, the solver chain and the time step — and [`run`], which steps a scene for
//! its duration, records a trajectory ([`Recording`], written as CSV or JSON) and sums the run
//! up ([`RunSummary`]: steps per second, real-time factor, energy drift, penetration, solvers).
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
//! | | `solver` | solver chain, first choice first: a name or a list of `"lemke"`, `"clarabel"`, `"pgs"`, `"pgsN"` (N sweeps) (`["pgs100", "clarabel"]`) |
//! | | `tolerance` | residual (m/s) the chain accepts (1e-6) |
//! | | `accept_last` | take the last solver's answer above the tolerance rather than fail (true) |
//! | | `friction` | `"cone"`, `"pyramid"` (4 facets) or `"pyramidN"`, 3 ≤ N ≤ 64 (`"cone"`) |
//! | | `margin` | contact margin, m (0.005) |
//! | | `speculative_within`, `speculative_factor` | contacts still apart get rows if their gap is at most `speculative_within` m or at most `speculative_factor` times the distance their points close in one step (`inf`: every contact within the margin) ([`crate::constraints::Speculation`]; 0.002, 2) |
//! | | `collide_joined_bodies` | also test bodies joined by a joint (false) |
//! | | `mass_matrix_reuse` | reuse a multibody's factored mass matrix while no joint coordinate has moved further than this since it was factored, and the constraint problem's W built on it while the rows stay the same: `true`, `false` or a tolerance in rad or m ([`WorldOptions::mass_matrix_reuse`]; true: 1e-8) |
//! | | `contact_reuse` | keep a pair's contact points while it moves less than this, refreshing only their distances: `true`, `false` or `{ translation = m, rotation = rad }` ([`crate::collision::ManifoldReuse`]; true: 1e-8 m, 1e-7 rad) |
//! | | `sleep` | let resting bodies sleep (true) |
//! | | `integrator` | scheme of the steps without contacts, limits, motors or joint friction: `"semi-implicit-euler"` (the velocity-level step throughout), `"explicit-euler"`, `"velocity-verlet"`, `"rk4"`, `"dopri45"`, `"gbs"`/`"gbsN"` or `"implicit-euler"` ([`WorldOptions::integrator`]; `"semi-implicit-euler"`) |
//! | `[contact]` | `mu`, `mu2`, `restitution`, `bounce_velocity`, `erp`, `cfm`, `surface_layer`, `max_correcting_velocity` | parameters of material 0 ([`ContactParameters`]) |
//! | `[limits]` | `erp`, `cfm`, `restitution`, `bounce_velocity`, `margin`, `speculative_within` | joint-limit parameters ([`JointLimitParameters`]; a stop within `margin` but further than `speculative_within` gets a row only if the step can close the gap) |
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
//! | | `joints` | initial positions, `{ joint = value }` (a list for joints of several coordinates); within limits |
//! | | `joint_velocities` | initial rates, `{ joint = value }` |
//! | | `limits` | position limits overriding the file's, `{ joint = [lower, upper] }` (hinge and slider joints) |
//! | | `servo` | `{ gain, max_velocity, max_force }`: hold every scalar joint at its initial position |
//! | | `pose_servo` | `{ gain, max_velocity, torque_per_kg }`: a powered ragdoll — every joint but the floating base (ball joints too) driven to its initial position by a [`PoseServo`] whose torque bound is `torque_per_kg` × the mass the joint moves |
//! | | `count`, `spacing`, `jitter`, `seed` | copies of the model as for `[[body]]` (named `{name}{k}` or `{name}_{i}_{j}_{k}`) |
//! | | `random_rotation` | floating base: each copy turned by a uniformly random rotation (seeded by `seed`) (false) |
//! | | `spin` | floating base: an angular velocity of this magnitude (rad/s) about a random axis (seeded) added to `angular_velocity` (0) |
//! | | `self_collision` | collisions between the model's own bodies (false) |
//! | | `material` | material of every collider of the model (0) |
//! | | `missing_meshes` | `"error"` (default) or `"skip"` collision meshes that cannot be found or read |
//! | | `package_paths` | directories searched for `package://` URIs |
//! | | `strict` | every URDF loader warning is an error ([`UrdfOptions::strict`]) (false) |
//! | | `balance_inertia` | inconsistent link inertias balanced as MuJoCo's `balanceinertia` ([`UrdfOptions::balance_inertia`]) (false) |
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

use crate::collision::{ManifoldReuse, MeshOptions, MissingMeshPolicy};
use crate::constraints::{ContactParameters, FrictionModel, JointLimitParameters};
use crate::error::ModelError;
use crate::io::urdf::{self, UrdfError, UrdfOptions};
use crate::math::{Transform, Vec3};
use crate::model::{BodySpec, Joint, Model, ModelBuilder, RigidInertia, Shape};
use crate::vehicle::{Driven, Vehicle, VehicleConfig};
use crate::world::{PoseServo, Servo, SolverKind, StepError, World, WorldOptions};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt;
use std::io::Write;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Instant;
use thiserror::Error;
use toml::Spanned;

/// Names of the integrators a scene may ask for (`gbsN` too): the world's velocity-level
/// semi-implicit Euler step, or a scheme of [`crate::integrators`] for the steps without contact
/// ([`crate::world::smooth`]).
pub const INTEGRATORS: [&str; 9] = crate::world::INTEGRATOR_NAMES;

// ------------------------------------------------------------------------------------------------
// Public API
// ------------------------------------------------------------------------------------------------

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
        *self = build(self.source.clone(), &Overrides::default())?;
        Ok(())
    }
}

/// Loads a scene file.
pub fn load_file(path: impl AsRef<Path>) -> Result<Scene, SceneError> {
    let path = path.as_ref();
    let file = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|source| SceneError::Io { file: file.clone(), source })?;
    let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let source = Source { file, path: Some(path.to_path_buf()), stem, text, base_dir };
    build(source, &Overrides::default())
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
    build(source, &Overrides::default())
}

/// Parses a solver chain written as in `[world] solver` or on a command line: names separated
/// by commas (`"pgs100,clarabel"`), each `lemke`, `clarabel`, `pgs` or `pgsN`.
pub fn parse_solvers(text: &str) -> Result<Vec<SolverKind>, String> {
    let chain = text
        .split(',')
        .map(str::trim)
        .map(|name| {
            SolverKind::parse(name).ok_or_else(|| {
                format!("unknown solver `{name}` (known: lemke, clarabel, pgs, pgsN with N >= 1 sweeps)")
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    if chain.is_empty() {
        return Err("the solver chain is empty".to_string());
    }
    Ok(chain)
}

/// Parses a friction model: `cone`, `pyramid` (4 facets) or `pyramidN` (3 ≤ N ≤
/// [`crate::constraints::MAX_PYRAMID_FACETS`] facets).
pub fn parse_friction(text: &str) -> Result<FrictionModel, String> {
    let bad = || {
        format!(
            "unknown friction model `{text}` (known: cone, pyramid, pyramidN with 3 <= N <= {})",
            crate::constraints::MAX_PYRAMID_FACETS
        )
    };
    match text {
        "cone" => Ok(FrictionModel::Cone),
        "pyramid" => Ok(FrictionModel::Pyramid { facets: 4 }),
        other => {
            let facets: usize = other.strip_prefix("pyramid").and_then(|n| n.parse().ok()).ok_or_else(bad)?;
            if !(3..=crate::constraints::MAX_PYRAMID_FACETS).contains(&facets) {
                return Err(bad());
            }
            Ok(FrictionModel::Pyramid { facets })
        }
    }
}

/// Options of [`run`]; `None` keeps the scene's value.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunOptions {
    /// Simulated time (s) instead of the scene's `duration`.
    pub duration: Option<f64>,
    /// Time step (s) instead of the scene's `dt`. Changing it rebuilds the world from the scene
    /// file, which is only allowed before the world has stepped.
    pub dt: Option<f64>,
    /// Solver chain instead of the scene's (see [`parse_solvers`]); rebuilds the world as `dt`.
    pub solvers: Option<Vec<SolverKind>>,
    /// Record one row every this many steps instead of `[record] every`; 0 records nothing.
    pub record_every: Option<usize>,
}

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
                    format!("{}: the output file must end in .csv or .json", path.display()),
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

/// What a run did.
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
    /// Mean iterations (or pivots) per solved step.
    pub mean_iterations: f64,
    /// Wall-clock seconds per phase of the step, summed: kinematics, collision, free motion, rows
    /// and assembly, solve, integration and sleeping.
    pub phase_time: [f64; 6],
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
    let overrides = Overrides { dt: options.dt, solvers: options.solvers.clone() };
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
        *scene = build(scene.source.clone(), &overrides)?;
    }
    let duration = options.duration.unwrap_or(scene.duration);
    if !(duration.is_finite() && duration >= 0.0) {
        return Err(SceneError::Options(format!("duration must be non-negative, got {duration}")));
    }
    let dt = scene.world.options().dt;
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
        rows: Vec::new(),
    };
    let mut summary = RunSummary { scene: scene.name.clone(), dt, ..RunSummary::default() };
    // The summary reports where the time went.
    scene.world.set_phase_timing(true);
    summary.energy_start = scene.world.total_energy();
    let mut iterations = 0u64;
    let start = Instant::now();
    if every > 0 {
        record_row(scene, 0, &mut recording);
    }
    let mut reported = 0u64;
    for step in 1..=steps {
        let time = scene.world.time();
        scene.apply_controls()?;
        let stats =
            scene.world.step().map_err(|source| SceneError::Step { step, time, source: Box::new(source) })?;
        summary.max_penetration = summary.max_penetration.max(stats.max_penetration);
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
            iterations += stats.iterations as u64;
        }
        if every > 0 && (step % every == 0 || step == steps) {
            record_row(scene, step, &mut recording);
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
    summary.energy_end = scene.world.total_energy();
    summary.energy_drift = summary.energy_end - summary.energy_start;
    summary.mean_iterations =
        if summary.solved_steps > 0 { iterations as f64 / summary.solved_steps as f64 } else { 0.0 };
    summary.recording = recording;
    Ok(summary)
}

fn record_row(scene: &mut Scene, step: u64, recording: &mut Recording) {
    let energy = if scene.record.energy { Some(scene.world.total_energy()) } else { None };
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

/// Names of the q and v components of a joint, in order.
fn coordinate_labels(joint: &Joint) -> (Vec<&'static str>, Vec<&'static str>) {
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

// ------------------------------------------------------------------------------------------------
// The document: checked values
// ------------------------------------------------------------------------------------------------

macro_rules! checked_number {
    ($(#[$doc:meta])* $name:ident, $expected:literal, $ok:expr) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq)]
        struct $name(f64);

        impl<'de> Deserialize<'de> for $name {
            fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let x = f64::deserialize(d)?;
                let ok: fn(f64) -> bool = $ok;
                if ok(x) {
                    Ok(Self(x))
                } else {
                    Err(D::Error::custom(format!(concat!("expected ", $expected, ", got {}"), x)))
                }
            }
        }
    };
}

checked_number!(
    /// A finite number.
    Finite,
    "a finite number",
    |x| x.is_finite()
);
checked_number!(
    /// A finite number > 0.
    Positive,
    "a positive number",
    |x| x.is_finite() && x > 0.0
);
checked_number!(
    /// A finite number ≥ 0.
    NonNegative,
    "a non-negative number",
    |x| x.is_finite() && x >= 0.0
);
checked_number!(
    /// A number > 0, infinity allowed.
    PositiveOrInfinite,
    "a positive number or inf",
    |x| x > 0.0
);
checked_number!(
    /// A number in [0, 1].
    Fraction,
    "a number between 0 and 1",
    |x| (0.0..=1.0).contains(&x)
);

/// A vector of three finite numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
struct V3(Vec3);

impl<'de> Deserialize<'de> for V3 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let [x, y, z] = <[Finite; 3]>::deserialize(d)?;
        Ok(V3(Vec3::new(x.0, y.0, z.0)))
    }
}

/// An integer ≥ 1.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Count1(usize);

impl<'de> Deserialize<'de> for Count1 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let n = i64::deserialize(d)?;
        if n >= 1 {
            Ok(Count1(n as usize))
        } else {
            Err(D::Error::custom(format!("expected a positive integer, got {n}")))
        }
    }
}

/// `count`: `n` (a row of n copies along `spacing`) or `[nx, ny, nz]` (a grid).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Count {
    Row(usize),
    Grid([usize; 3]),
}

/// Whether copies placed by `count` (`dims`, a grid or a row) at `spacing` land on each other:
/// a row of several with no spacing, or a grid of several along an axis without spacing along
/// it, and no jitter to move them apart (identical bodies on each other have no contact normal).
fn copies_coincide(dims: [usize; 3], grid: bool, spacing: &Vec3, jitter: f64) -> bool {
    if jitter > 0.0 {
        return false;
    }
    if grid {
        (0..3).any(|a| dims[a] > 1 && spacing[a] == 0.0)
    } else {
        dims[0] > 1 && *spacing == Vec3::zeros()
    }
}

/// Most steps one [`run`] takes: 10⁹ steps are hours of any scene; more is a typo in `duration` or
/// `dt` (1e300 s, 1e-300 s) that would only spin.
const MAX_RUN_STEPS: u64 = 1_000_000_000;

/// Most copies one `count` makes: a scene file describes a scene to step, and a count beyond
/// this (a typo, a wrapped product) would only exhaust memory while building it.
const MAX_COPIES: usize = 100_000;

/// Most samples a generated heightfield has (`samples = [nx, ny]`), 32 MiB of heights.
const MAX_HEIGHTFIELD_SAMPLES: usize = 1 << 22;

impl<'de> Deserialize<'de> for Count {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let expected = "expected a positive integer or a list [nx, ny, nz] of positive integers";
        let positive = |v: &toml::Value| v.as_integer().filter(|n| *n >= 1).map(|n| n as usize);
        let count = match toml::Value::deserialize(d)? {
            v @ toml::Value::Integer(_) => {
                positive(&v).map(Count::Row).ok_or_else(|| D::Error::custom(expected))?
            }
            toml::Value::Array(a) if a.len() == 3 => {
                let dims: Option<Vec<usize>> = a.iter().map(positive).collect();
                dims.map(|d| Count::Grid([d[0], d[1], d[2]])).ok_or_else(|| D::Error::custom(expected))?
            }
            _ => return Err(D::Error::custom(expected)),
        };
        let total = match count {
            Count::Row(n) => Some(n),
            Count::Grid([x, y, z]) => x.checked_mul(y).and_then(|xy| xy.checked_mul(z)),
        };
        match total {
            Some(n) if n <= MAX_COPIES => Ok(count),
            _ => Err(D::Error::custom(match count {
                Count::Row(n) => format!("at most {MAX_COPIES} copies, got {n}"),
                Count::Grid([x, y, z]) => format!("at most {MAX_COPIES} copies, got [{x}, {y}, {z}]"),
            })),
        }
    }
}

/// A material, by index or by name.
#[derive(Clone, Debug, PartialEq)]
enum MaterialRef {
    Index(u32),
    Name(String),
}

impl Default for MaterialRef {
    fn default() -> Self {
        MaterialRef::Index(0)
    }
}

impl<'de> Deserialize<'de> for MaterialRef {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        match toml::Value::deserialize(d)? {
            toml::Value::Integer(n) if (0..=u32::MAX as i64).contains(&n) => Ok(MaterialRef::Index(n as u32)),
            toml::Value::String(s) => Ok(MaterialRef::Name(s)),
            other => Err(D::Error::custom(format!(
                "expected a material index (a non-negative integer) or name, got {other}"
            ))),
        }
    }
}

/// A joint value: one number, or a list for joints of several coordinates.
#[derive(Clone, Debug, PartialEq)]
struct JointValue(Vec<f64>);

impl<'de> Deserialize<'de> for JointValue {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let expected = "expected a finite number or a list of finite numbers";
        let number = |v: &toml::Value| match v {
            toml::Value::Integer(n) => Some(*n as f64),
            toml::Value::Float(x) if x.is_finite() => Some(*x),
            _ => None,
        };
        match toml::Value::deserialize(d)? {
            toml::Value::Array(a) => a
                .iter()
                .map(number)
                .collect::<Option<Vec<_>>>()
                .map(JointValue)
                .ok_or(D::Error::custom(expected)),
            v => number(&v).map(|x| JointValue(vec![x])).ok_or_else(|| D::Error::custom(expected)),
        }
    }
}

/// `solver`: a name or a list of names.
#[derive(Clone, Debug, PartialEq)]
struct SolverList(Vec<SolverKind>);

impl<'de> Deserialize<'de> for SolverList {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let names = match toml::Value::deserialize(d)? {
            toml::Value::String(s) => vec![s],
            toml::Value::Array(a) => a
                .into_iter()
                .map(|v| match v {
                    toml::Value::String(s) => Ok(s),
                    other => Err(D::Error::custom(format!("expected a solver name, got {other}"))),
                })
                .collect::<Result<Vec<_>, _>>()?,
            other => {
                return Err(D::Error::custom(format!(
                    "expected a solver name or a list of them, got {other}"
                )))
            }
        };
        parse_solvers(&names.join(",")).map(SolverList).map_err(D::Error::custom)
    }
}

/// `contact_reuse`: `true` (the default tolerances), `false`, or `{ translation, rotation }`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct ReuseSetting(Option<ManifoldReuse>);

impl<'de> Deserialize<'de> for ReuseSetting {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Tolerances {
            translation: Option<Positive>,
            rotation: Option<Positive>,
        }
        match toml::Value::deserialize(d)? {
            toml::Value::Boolean(on) => Ok(Self(on.then(ManifoldReuse::default))),
            table @ toml::Value::Table(_) => {
                let t: Tolerances = table.try_into().map_err(D::Error::custom)?;
                let defaults = ManifoldReuse::default();
                Ok(Self(Some(ManifoldReuse {
                    translation: t.translation.map_or(defaults.translation, |x| x.0),
                    rotation: t.rotation.map_or(defaults.rotation, |x| x.0),
                })))
            }
            other => Err(D::Error::custom(format!(
                "expected true, false or {{ translation = m, rotation = rad }}, got {other}"
            ))),
        }
    }
}

/// `mass_matrix_reuse`: `true` (the default tolerance), `false`, or a tolerance (rad or m).
#[derive(Clone, Copy, Debug, PartialEq)]
struct MassReuseSetting(Option<f64>);

impl<'de> Deserialize<'de> for MassReuseSetting {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        match toml::Value::deserialize(d)? {
            toml::Value::Boolean(on) => {
                Ok(Self(if on { WorldOptions::default().mass_matrix_reuse } else { None }))
            }
            toml::Value::Float(x) if x.is_finite() && x > 0.0 => Ok(Self(Some(x))),
            other => {
                Err(D::Error::custom(format!("expected true, false or a positive tolerance, got {other}")))
            }
        }
    }
}

/// `friction`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FrictionName(FrictionModel);

impl<'de> Deserialize<'de> for FrictionName {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        parse_friction(&String::deserialize(d)?).map(FrictionName).map_err(D::Error::custom)
    }
}

/// `integrator`.
#[derive(Clone, Debug, PartialEq)]
struct IntegratorName(String);

impl<'de> Deserialize<'de> for IntegratorName {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        if crate::world::parse_integrator(&name).is_some() {
            Ok(IntegratorName(name))
        } else {
            Err(D::Error::custom(format!("unknown integrator `{name}` (known: {})", INTEGRATORS.join(", "))))
        }
    }
}

// ------------------------------------------------------------------------------------------------
// The document: tables
// ------------------------------------------------------------------------------------------------

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct Document {
    name: Option<String>,
    description: Option<String>,
    #[serde(default)]
    world: WorldSection,
    #[serde(default)]
    contact: ContactSection,
    #[serde(default)]
    limits: LimitsSection,
    #[serde(default)]
    material: Vec<Spanned<MaterialSection>>,
    #[serde(default)]
    pair: Vec<Spanned<PairSection>>,
    #[serde(default)]
    ground: Vec<Spanned<GroundSection>>,
    #[serde(default)]
    urdf: Vec<Spanned<UrdfSection>>,
    #[serde(default)]
    body: Vec<Spanned<BodySection>>,
    #[serde(default)]
    vehicle: Vec<Spanned<VehicleSection>>,
    record: Option<Spanned<RecordSection>>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct VehicleSection {
    multibody: Spanned<String>,
    front: Option<[String; 2]>,
    rear: Option<[String; 2]>,
    driven: Option<DrivenName>,
    wheel_radius: Option<Positive>,
    drive_torque: Option<Positive>,
    brake_torque: Option<Positive>,
    steering_gain: Option<Positive>,
    steering_rate: Option<Positive>,
    steering_torque: Option<Positive>,
    patch_contact: Option<bool>,
    #[serde(default)]
    command: Vec<Spanned<CommandSection>>,
}

/// `driven` of a `[[vehicle]]`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "lowercase")]
enum DrivenName {
    Rear,
    Front,
    All,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CommandSection {
    at: NonNegative,
    speed: Option<Finite>,
    coast: Option<bool>,
    steering_deg: Option<Finite>,
    brake: Option<bool>,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct WorldSection {
    dt: Option<Positive>,
    duration: Option<NonNegative>,
    gravity: Option<V3>,
    solver: Option<SolverList>,
    tolerance: Option<Positive>,
    accept_last: Option<bool>,
    friction: Option<FrictionName>,
    margin: Option<NonNegative>,
    speculative_within: Option<NonNegative>,
    speculative_factor: Option<PositiveOrInfinite>,
    collide_joined_bodies: Option<bool>,
    contact_reuse: Option<ReuseSetting>,
    mass_matrix_reuse: Option<MassReuseSetting>,
    sleep: Option<bool>,
    integrator: Option<IntegratorName>,
}

/// Tables holding contact parameters: `[contact]`, `[[material]]`, `[[pair]]`.
macro_rules! contact_section {
    ($name:ident { $($extra:ident : $ty:ty),* $(,)? }) => {
        #[derive(Clone, Debug, Default, Deserialize)]
        #[serde(deny_unknown_fields)]
        struct $name {
            $($extra: $ty,)*
            mu: Option<NonNegative>,
            mu2: Option<NonNegative>,
            restitution: Option<Fraction>,
            bounce_velocity: Option<NonNegative>,
            erp: Option<Fraction>,
            cfm: Option<NonNegative>,
            surface_layer: Option<NonNegative>,
            max_correcting_velocity: Option<PositiveOrInfinite>,
        }

        impl $name {
            /// `base` with the parameters this table sets.
            fn apply(&self, base: ContactParameters) -> ContactParameters {
                ContactParameters {
                    mu: self.mu.map_or(base.mu, |x| x.0),
                    mu2: self.mu2.map(|x| x.0).or(base.mu2),
                    restitution: self.restitution.map_or(base.restitution, |x| x.0),
                    bounce_velocity: self.bounce_velocity.map_or(base.bounce_velocity, |x| x.0),
                    erp: self.erp.map_or(base.erp, |x| x.0),
                    cfm: self.cfm.map_or(base.cfm, |x| x.0),
                    surface_layer: self.surface_layer.map_or(base.surface_layer, |x| x.0),
                    max_correcting_velocity: self
                        .max_correcting_velocity
                        .map_or(base.max_correcting_velocity, |x| x.0),
                }
            }
        }
    };
}

contact_section!(ContactSection {});
contact_section!(MaterialSection { index: u32, name: Option<String>, });
contact_section!(PairSection { materials: [MaterialRef; 2] });

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct LimitsSection {
    erp: Option<Fraction>,
    cfm: Option<NonNegative>,
    restitution: Option<Fraction>,
    bounce_velocity: Option<NonNegative>,
    margin: Option<NonNegative>,
    speculative_within: Option<NonNegative>,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum GroundKind {
    #[default]
    Plane,
    Slope,
    Heightfield,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct GroundSection {
    #[serde(default)]
    kind: GroundKind,
    name: Option<String>,
    material: Option<Spanned<MaterialRef>>,
    position: Option<V3>,
    rpy: Option<V3>,
    quaternion: Option<[Finite; 4]>,
    normal: Option<V3>,
    offset: Option<Finite>,
    angle_deg: Option<Finite>,
    direction: Option<V3>,
    size: Option<[Positive; 2]>,
    heights: Option<Vec<Vec<Finite>>>,
    samples: Option<[Count1; 2]>,
    bump_height: Option<Finite>,
    bump_wavelength: Option<Positive>,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum MissingMeshes {
    #[default]
    Error,
    Skip,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ServoSection {
    gain: Positive,
    max_velocity: PositiveOrInfinite,
    max_force: PositiveOrInfinite,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PoseServoSection {
    gain: Positive,
    max_velocity: PositiveOrInfinite,
    torque_per_kg: Positive,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct UrdfSection {
    pose_servo: Option<PoseServoSection>,
    count: Option<Count>,
    spacing: Option<V3>,
    jitter: Option<NonNegative>,
    seed: Option<u64>,
    #[serde(default)]
    random_rotation: bool,
    spin: Option<NonNegative>,
    path: Spanned<String>,
    name: Option<String>,
    #[serde(default)]
    floating: bool,
    position: Option<V3>,
    rpy: Option<V3>,
    quaternion: Option<[Finite; 4]>,
    velocity: Option<V3>,
    angular_velocity: Option<V3>,
    #[serde(default)]
    joints: BTreeMap<String, Spanned<JointValue>>,
    #[serde(default)]
    joint_velocities: BTreeMap<String, Spanned<JointValue>>,
    #[serde(default)]
    limits: BTreeMap<String, Spanned<[Finite; 2]>>,
    servo: Option<ServoSection>,
    #[serde(default)]
    self_collision: bool,
    material: Option<Spanned<MaterialRef>>,
    #[serde(default)]
    missing_meshes: MissingMeshes,
    #[serde(default)]
    package_paths: Vec<String>,
    #[serde(default)]
    strict: bool,
    #[serde(default)]
    balance_inertia: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum ShapeName {
    Box,
    Sphere,
    Capsule,
    Cylinder,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BodySection {
    name: Option<String>,
    shape: ShapeName,
    size: Option<[Positive; 3]>,
    radius: Option<Positive>,
    length: Option<Positive>,
    mass: Option<Positive>,
    density: Option<Positive>,
    position: Option<V3>,
    rpy: Option<V3>,
    quaternion: Option<[Finite; 4]>,
    velocity: Option<V3>,
    angular_velocity: Option<V3>,
    count: Option<Count>,
    spacing: Option<V3>,
    jitter: Option<NonNegative>,
    seed: Option<u64>,
    material: Option<Spanned<MaterialRef>>,
    #[serde(default)]
    fixed: bool,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RecordSection {
    every: Option<Count1>,
    multibodies: Option<Vec<Spanned<String>>>,
    #[serde(default)]
    velocities: bool,
    #[serde(default)]
    energy: bool,
}

// ------------------------------------------------------------------------------------------------
// Building
// ------------------------------------------------------------------------------------------------

/// The text of a scene and where it came from (kept to rebuild the world).
#[derive(Clone, Debug)]
struct Source {
    file: String,
    path: Option<PathBuf>,
    stem: String,
    text: String,
    base_dir: PathBuf,
}

impl Source {
    fn location(&self, span: Range<usize>) -> Location {
        let offset = span.start.min(self.text.len());
        let before = &self.text[..offset];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |k| k + 1);
        let column = before[line_start..].chars().count() + 1;
        Location { file: self.file.clone(), line, column, key: key_path(&self.text, offset) }
    }

    fn invalid(&self, span: Range<usize>, message: impl Into<String>) -> SceneError {
        SceneError::Invalid { at: self.location(span), message: message.into() }
    }

    fn resolve(&self, path: &str) -> PathBuf {
        let p = Path::new(path);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.base_dir.join(p)
        }
    }
}

/// The path of the innermost key or value of `text` containing byte `offset`.
fn key_path(text: &str, offset: usize) -> String {
    use toml::de::{DeTable, DeValue};
    enum Segment {
        Key(String),
        Index(usize),
    }
    fn in_table(t: &DeTable<'_>, offset: usize, path: &mut Vec<Segment>) -> bool {
        for (k, v) in t.iter() {
            path.push(Segment::Key(k.get_ref().to_string()));
            if k.span().contains(&offset) || in_value(v, offset, path) {
                return true;
            }
            path.pop();
        }
        false
    }
    fn in_value(v: &Spanned<DeValue<'_>>, offset: usize, path: &mut Vec<Segment>) -> bool {
        match v.get_ref() {
            DeValue::Table(t) if in_table(t, offset, path) => return true,
            DeValue::Array(a) => {
                for (i, e) in a.iter().enumerate() {
                    path.push(Segment::Index(i));
                    if in_value(e, offset, path) {
                        return true;
                    }
                    path.pop();
                }
            }
            _ => {}
        }
        v.span().contains(&offset)
    }
    let (root, _) = DeTable::parse_recoverable(text);
    let mut path = Vec::new();
    in_table(root.get_ref(), offset, &mut path);
    let mut out = String::new();
    for segment in path {
        match segment {
            Segment::Key(k) => {
                if !out.is_empty() {
                    out.push('.');
                }
                if !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
                    out.push_str(&k);
                } else {
                    out.push_str(&format!("{k:?}"));
                }
            }
            Segment::Index(i) => out.push_str(&format!("[{i}]")),
        }
    }
    out
}

/// Run-time replacements of scene values.
#[derive(Clone, Debug, Default)]
struct Overrides {
    dt: Option<f64>,
    solvers: Option<Vec<SolverKind>>,
}

fn build(source: Source, overrides: &Overrides) -> Result<Scene, SceneError> {
    if source.text.trim_start().starts_with('<') {
        let message =
            "this is XML (a URDF or MJCF file?), not a scene: scene files are TOML (see models/*.toml)";
        return Err(source.invalid(0..0, message.to_string()));
    }
    let doc: Document = toml::from_str(&source.text).map_err(|e| {
        let span = e.span().unwrap_or(0..0);
        let message = e.message().trim_end().to_string();
        if e.span().is_some() {
            source.invalid(span, message)
        } else {
            SceneError::Invalid {
                at: Location { file: source.file.clone(), line: 0, column: 0, key: String::new() },
                message,
            }
        }
    })?;
    let mut b = Builder { src: &source, materials: HashMap::new(), names: HashSet::new() };

    // World options.
    let w = &doc.world;
    let defaults = WorldOptions::default();
    let mut options = WorldOptions {
        dt: w.dt.map_or(defaults.dt, |x| x.0),
        gravity: w.gravity.map_or(defaults.gravity, |g| g.0),
        friction: w.friction.map_or(defaults.friction, |f| f.0),
        solvers: w.solver.clone().map_or(defaults.solvers.clone(), |s| s.0),
        tolerance: w.tolerance.map_or(defaults.tolerance, |x| x.0),
        accept_last: w.accept_last.unwrap_or(defaults.accept_last),
        contact: doc.contact.apply(ContactParameters::default()),
        ..defaults
    };
    options.collision.margin = w.margin.map_or(options.collision.margin, |x| x.0);
    options.speculation.always_within =
        w.speculative_within.map_or(options.speculation.always_within, |x| x.0);
    options.speculation.speed_factor = w.speculative_factor.map_or(options.speculation.speed_factor, |x| x.0);
    options.collision.collide_joined_bodies =
        w.collide_joined_bodies.unwrap_or(options.collision.collide_joined_bodies);
    options.collision.reuse = w.contact_reuse.map_or(options.collision.reuse, |r| r.0);
    options.mass_matrix_reuse = w.mass_matrix_reuse.map_or(options.mass_matrix_reuse, |r| r.0);
    options.sleep.enabled = w.sleep.unwrap_or(options.sleep.enabled);
    if let Some(name) = &w.integrator {
        options.integrator = crate::world::parse_integrator(&name.0).unwrap_or(options.integrator);
    }
    let l = &doc.limits;
    let lim = JointLimitParameters::default();
    options.limits = JointLimitParameters {
        erp: l.erp.map_or(lim.erp, |x| x.0),
        cfm: l.cfm.map_or(lim.cfm, |x| x.0),
        restitution: l.restitution.map_or(lim.restitution, |x| x.0),
        bounce_velocity: l.bounce_velocity.map_or(lim.bounce_velocity, |x| x.0),
        margin: l.margin.map_or(lim.margin, |x| x.0),
        speculative_within: l.speculative_within.map_or(lim.speculative_within, |x| x.0),
    };
    if let Some(dt) = overrides.dt {
        options.dt = dt;
    }
    if let Some(solvers) = &overrides.solvers {
        options.solvers = solvers.clone();
    }
    let mut world = World::new(options.clone());

    // Materials and pairs.
    for m in &doc.material {
        let span = m.span();
        let m = m.get_ref();
        if m.index == 0 {
            return Err(b.src.invalid(span, "material 0 is the default material: set it in [contact]"));
        }
        if b.materials.values().any(|&i| i == m.index) {
            return Err(b.src.invalid(span, format!("material {} is defined twice", m.index)));
        }
        let name = m.name.clone().unwrap_or_else(|| format!("#{}", m.index));
        if b.materials.insert(name.clone(), m.index).is_some() {
            return Err(b.src.invalid(span, format!("two materials are named `{name}`")));
        }
        world.set_material(m.index, m.apply(options.contact));
    }
    for p in &doc.pair {
        let span = p.span();
        let p = p.get_ref();
        let a = b.material(&p.materials[0], span.clone())?;
        let c = b.material(&p.materials[1], span)?;
        world.set_pair_parameters(a, c, p.apply(options.contact));
    }

    for (i, g) in doc.ground.iter().enumerate() {
        b.ground(&mut world, i, g)?;
    }
    let mut warnings = Vec::new();
    for u in &doc.urdf {
        warnings.extend(b.urdf(&mut world, u)?);
    }
    warnings.extend(world.collision().warnings().iter().cloned());
    for (i, body) in doc.body.iter().enumerate() {
        b.body(&mut world, i, body)?;
    }
    let mut vehicles = Vec::new();
    for v in &doc.vehicle {
        vehicles.push(b.vehicle(&mut world, v)?);
    }

    // Recording.
    let mut record = RecordOptions::default();
    let mut recorded: Vec<usize> = (0..world.multibody_count()).collect();
    if let Some(r) = &doc.record {
        let section = r.get_ref();
        record.every = section.every.map_or(record.every, |x| x.0);
        record.velocities = section.velocities;
        record.energy = section.energy;
        if let Some(names) = &section.multibodies {
            recorded.clear();
            for name in names {
                let index = (0..world.multibody_count())
                    .find(|&i| world.multibody_name(i) == name.get_ref())
                    .ok_or_else(|| {
                        b.src.invalid(name.span(), format!("no multibody `{}`", name.get_ref()))
                    })?;
                recorded.push(index);
            }
        }
    }

    Ok(Scene {
        name: doc.name.clone().unwrap_or_else(|| source.stem.clone()),
        description: doc.description.clone().unwrap_or_default(),
        file: source.path.clone(),
        world,
        duration: doc.world.duration.map_or(1.0, |x| x.0),
        integrator: doc.world.integrator.clone().map_or(INTEGRATORS[0].to_string(), |x| x.0),
        recorded,
        record,
        warnings,
        vehicles,
        source,
    })
}

struct Builder<'a> {
    src: &'a Source,
    materials: HashMap<String, u32>,
    names: HashSet<String>,
}

impl Builder<'_> {
    fn material(&self, m: &MaterialRef, span: Range<usize>) -> Result<u32, SceneError> {
        match m {
            MaterialRef::Index(0) => Ok(0),
            MaterialRef::Index(i) if self.materials.values().any(|k| k == i) => Ok(*i),
            MaterialRef::Index(i) => {
                Err(self.src.invalid(span, format!("no material {i} (define it in [[material]])")))
            }
            MaterialRef::Name(name) => self.materials.get(name).copied().ok_or_else(|| {
                self.src.invalid(span, format!("no material named `{name}` (define it in [[material]])"))
            }),
        }
    }

    fn material_of(&self, m: &Option<Spanned<MaterialRef>>) -> Result<u32, SceneError> {
        m.as_ref().map_or(Ok(0), |m| self.material(m.get_ref(), m.span()))
    }

    fn claim_name(&mut self, name: &str, span: Range<usize>) -> Result<(), SceneError> {
        if self.names.insert(name.to_string()) {
            Ok(())
        } else {
            Err(self
                .src
                .invalid(span, format!("two multibodies are named `{name}`: give each entry its own `name`")))
        }
    }

    fn world_error(&self, span: Range<usize>) -> impl Fn(StepError) -> SceneError + '_ {
        move |source| SceneError::World { at: self.src.location(span.clone()), source: Box::new(source) }
    }

    fn ground(
        &mut self,
        world: &mut World,
        index: usize,
        g: &Spanned<GroundSection>,
    ) -> Result<(), SceneError> {
        let span = g.span();
        let g = g.get_ref();
        let err = |message: String| self.src.invalid(span.clone(), message);
        let frame = pose(g.position, g.rpy, g.quaternion).map_err(err)?;
        let material = self.material_of(&g.material)?;
        let name = g.name.clone().unwrap_or_else(|| format!("ground{index}"));
        let given = [
            ("normal", g.normal.is_some()),
            ("offset", g.offset.is_some()),
            ("angle_deg", g.angle_deg.is_some()),
            ("direction", g.direction.is_some()),
            ("size", g.size.is_some()),
            ("heights", g.heights.is_some()),
            ("samples", g.samples.is_some()),
            ("bump_height", g.bump_height.is_some()),
            ("bump_wavelength", g.bump_wavelength.is_some()),
        ];
        let (kind_name, allowed): (&str, &[&str]) = match g.kind {
            GroundKind::Plane => ("plane", &["normal", "offset"]),
            GroundKind::Slope => ("slope", &["angle_deg", "direction"]),
            GroundKind::Heightfield => (
                "heightfield",
                &["angle_deg", "direction", "size", "heights", "samples", "bump_height", "bump_wavelength"],
            ),
        };
        if let Some((key, _)) = given.iter().find(|(k, set)| *set && !allowed.contains(k)) {
            return Err(err(format!("`{key}` does not apply to kind = \"{kind_name}\"")));
        }
        let unit = |v: Vec3, what: &str| {
            let n = v.norm();
            if n > 1e-12 {
                Ok(v / n)
            } else {
                Err(err(format!("`{what}` must not be zero")))
            }
        };
        // The ascent direction of a slope or tilted height field, horizontal.
        let direction = || {
            let d = g.direction.map_or(Vec3::x(), |d| d.0);
            unit(Vec3::new(d.x, d.y, 0.0), "direction (horizontal part)")
        };
        let (shape, local) = match g.kind {
            GroundKind::Plane => {
                let n = unit(g.normal.map_or(Vec3::z(), |n| n.0), "normal")?;
                let offset = g.offset.map_or(0.0, |x| x.0);
                (Shape::HalfSpace { normal: n }, Transform::from_translation(n * offset))
            }
            GroundKind::Slope => {
                let angle = g.angle_deg.ok_or_else(|| err("a slope needs `angle_deg`".to_string()))?.0;
                if angle.abs() >= 90.0 {
                    return Err(err(format!("`angle_deg` must be between -90 and 90, got {angle}")));
                }
                let a = angle.to_radians();
                let n = -a.sin() * direction()? + a.cos() * Vec3::z();
                (Shape::HalfSpace { normal: n }, Transform::identity())
            }
            GroundKind::Heightfield => {
                let [sx, sy] =
                    g.size.ok_or_else(|| err("a heightfield needs `size = [x, y]`".to_string()))?;
                let (sx, sy) = (sx.0, sy.0);
                let tilt = g.angle_deg.map_or(0.0, |x| x.0);
                if tilt.abs() >= 90.0 {
                    return Err(err(format!("`angle_deg` must be between -90 and 90, got {tilt}")));
                }
                let slope = tilt.to_radians().tan() * direction()?;
                let heights = if let Some(rows) = &g.heights {
                    if let Some((key, _)) = given[6..].iter().find(|(_, set)| *set) {
                        return Err(err(format!(
                            "`{key}` generates heights: give it or `heights`, not both"
                        )));
                    }
                    let nx = rows.len();
                    let ny = rows.first().map_or(0, Vec::len);
                    if nx < 2 || ny < 2 || rows.iter().any(|r| r.len() != ny) {
                        return Err(err(
                            "`heights` must be at least 2 rows of at least 2 values, all rows of the same length"
                                .to_string(),
                        ));
                    }
                    DMatrix::from_fn(nx, ny, |i, j| rows[i][j].0)
                } else {
                    let [nx, ny] = g.samples.map_or([33, 33], |s| [s[0].0, s[1].0]);
                    if nx < 2 || ny < 2 {
                        return Err(err("`samples` must be at least [2, 2]".to_string()));
                    }
                    if nx.checked_mul(ny).is_none_or(|n| n > MAX_HEIGHTFIELD_SAMPLES) {
                        return Err(err(format!(
                            "`samples` = [{nx}, {ny}] is more than {MAX_HEIGHTFIELD_SAMPLES} heights"
                        )));
                    }
                    let amplitude = g.bump_height.map_or(0.0, |x| x.0);
                    let k = 2.0 * std::f64::consts::PI / g.bump_wavelength.map_or(1.0, |x| x.0);
                    DMatrix::from_fn(nx, ny, |i, j| {
                        let x = -sx / 2.0 + sx * i as f64 / (nx - 1) as f64;
                        let y = -sy / 2.0 + sy * j as f64 / (ny - 1) as f64;
                        amplitude * (k * x).sin() * (k * y).sin()
                    })
                };
                let (nx, ny) = heights.shape();
                let heights = DMatrix::from_fn(nx, ny, |i, j| {
                    let x = -sx / 2.0 + sx * i as f64 / (nx - 1) as f64;
                    let y = -sy / 2.0 + sy * j as f64 / (ny - 1) as f64;
                    heights[(i, j)] + slope.x * x + slope.y * y
                });
                (Shape::HeightField { heights, size_x: sx, size_y: sy }, Transform::identity())
            }
        };
        world.add_static(&name, &shape, frame * local, material).map_err(self.world_error(span.clone()))?;
        Ok(())
    }

    /// Adds the model(s) of a `[[urdf]]` entry; returns the URDF loader's warnings.
    fn urdf(&mut self, world: &mut World, u: &Spanned<UrdfSection>) -> Result<Vec<String>, SceneError> {
        let span = u.span();
        let u = u.get_ref();
        let err = |message: String| self.src.invalid(span.clone(), message);
        let placement = pose(u.position, u.rpy, u.quaternion).map_err(err)?;
        let material = self.material_of(&u.material)?;
        let path = self.src.resolve(u.path.get_ref());
        let options = UrdfOptions {
            floating_base: u.floating,
            strict: u.strict,
            balance_inertia: u.balance_inertia,
            ..UrdfOptions::default()
        };
        let loaded = urdf::load_file_with_warnings(&path, &options).map_err(|source| SceneError::Urdf {
            at: self.src.location(u.path.span()),
            source: Box::new(source),
        })?;
        let mut model = loaded.model;
        let file_name = u.path.get_ref();
        let warnings: Vec<String> = loaded.warnings.iter().map(|w| format!("{file_name}: {w}")).collect();
        if !u.floating && (u.velocity.is_some() || u.angular_velocity.is_some()) {
            return Err(err("`velocity` and `angular_velocity` need `floating = true`".to_string()));
        }
        let file = u.path.get_ref();
        let joint_of = |model: &Model, name: &str, span: Range<usize>| {
            model
                .joint_id(name)
                .filter(|&j| j > 0)
                .ok_or_else(|| self.src.invalid(span, format!("no moving joint `{name}` in {file}")))
        };
        // Limits first, so that initial positions are checked against them.
        for (name, value) in &u.limits {
            let j = joint_of(&model, name, value.span())?;
            if !matches!(model.joint(j), Joint::Hinge { .. } | Joint::Slider { .. }) {
                return Err(self.src.invalid(
                    value.span(),
                    format!(
                        "limits can be set on hinge and slider joints; `{name}` is {}",
                        model.joint(j).kind_name()
                    ),
                ));
            }
            let [lower, upper] = value.get_ref();
            if lower.0 > upper.0 {
                return Err(self
                    .src
                    .invalid(value.span(), format!("lower {} is above upper {}", lower.0, upper.0)));
            }
            let k = model.idx_q(j);
            model.lower_position_limit[k] = lower.0;
            model.upper_position_limit[k] = upper.0;
        }
        if !u.floating && (u.random_rotation || u.spin.is_some()) {
            return Err(err("`random_rotation` and `spin` need `floating = true`".to_string()));
        }
        let base_name = u.name.clone().unwrap_or_else(|| model.name().to_string());
        let base_name = if base_name.is_empty() { "robot".to_string() } else { base_name };

        let mut q = model.neutral_configuration();
        let mut v = nalgebra::DVector::zeros(model.nv());
        let root = model.children(0).first().copied().filter(|&j| *model.joint(j) == Joint::Free);
        if u.floating && root.is_none() {
            return Err(err("the floating base has no free joint".to_string()));
        }
        for (name, value) in &u.joints {
            let j = joint_of(&model, name, value.span())?;
            let (iq, nq) = (model.idx_q(j), model.joint(j).nq());
            let x = &value.get_ref().0;
            if x.len() != nq {
                return Err(self.src.invalid(
                    value.span(),
                    format!("joint `{name}` has {nq} coordinate(s), {} given", x.len()),
                ));
            }
            for (k, &xk) in x.iter().enumerate() {
                let (lo, hi) = (model.lower_position_limit()[iq + k], model.upper_position_limit()[iq + k]);
                if xk < lo || xk > hi {
                    return Err(self.src.invalid(
                        value.span(),
                        format!("joint `{name}`: {xk} is outside its limits [{lo}, {hi}]"),
                    ));
                }
                q[iq + k] = xk;
            }
            if model.joint(j).quaternion_norm(x).is_some_and(|n| n < crate::model::MIN_QUATERNION_NORM) {
                return Err(self.src.invalid(
                    value.span(),
                    format!("joint `{name}`: a quaternion of norm (nearly) zero is no rotation"),
                ));
            }
            model.joint(j).normalize(&mut q.as_mut_slice()[iq..iq + nq]);
        }
        for (name, value) in &u.joint_velocities {
            let j = joint_of(&model, name, value.span())?;
            let (iv, nv) = (model.idx_v(j), model.joint(j).nv());
            let x = &value.get_ref().0;
            if x.len() != nv {
                return Err(self.src.invalid(
                    value.span(),
                    format!("joint `{name}` has {nv} velocity coordinate(s), {} given", x.len()),
                ));
            }
            v.rows_mut(iv, nv).copy_from_slice(x);
        }
        let servo_dofs: Vec<(usize, f64)> = (1..model.nbodies())
            .filter(|&j| {
                let joint = model.joint(j);
                joint.nq() == joint.nv() && !matches!(joint, Joint::Free | Joint::Ball)
            })
            .flat_map(|j| (0..model.joint(j).nv()).map(move |k| (j, k)))
            .map(|(j, k)| (model.idx_v(j) + k, q[model.idx_q(j) + k]))
            .collect();

        let meshes = MeshOptions {
            search_paths: u.package_paths.iter().map(|p| self.src.resolve(p)).collect(),
            missing: match u.missing_meshes {
                MissingMeshes::Error => MissingMeshPolicy::Error,
                MissingMeshes::Skip => MissingMeshPolicy::Skip,
            },
            ..MeshOptions::default()
        };

        // Copies, placed as `[[body]]` copies are.
        let (dims, grid) = match u.count {
            None => ([1, 1, 1], false),
            Some(Count::Row(n)) => ([n, 1, 1], false),
            Some(Count::Grid(d)) => (d, true),
        };
        let total = dims[0] * dims[1] * dims[2];
        let spacing = match (u.spacing, total) {
            (Some(s), _) => s.0,
            (None, 1) => Vec3::zeros(),
            (None, _) => return Err(err(format!("{total} copies need `spacing`"))),
        };
        let jitter = u.jitter.map_or(0.0, |x| x.0);
        if copies_coincide(dims, grid, &spacing, jitter) {
            return Err(err(format!(
                "{total} copies with `spacing` {:?} and no `jitter` would lie on each other",
                spacing.as_slice()
            )));
        }
        let mut rng = rand::rngs::StdRng::seed_from_u64(u.seed.unwrap_or(0));
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let name = if total == 1 {
                        base_name.clone()
                    } else if grid {
                        format!("{base_name}_{i}_{j}_{k}")
                    } else {
                        format!("{base_name}{i}")
                    };
                    self.claim_name(&name, span.clone())?;
                    let offset = if grid {
                        Vec3::new(i as f64 * spacing.x, j as f64 * spacing.y, k as f64 * spacing.z)
                    } else {
                        i as f64 * spacing
                    };
                    let mut x = placement;
                    if jitter > 0.0 {
                        x.translation += Vec3::from_fn(|_, _| rng.random_range(-jitter..=jitter));
                    }
                    x.translation += offset;
                    if u.random_rotation {
                        let turn = crate::model::joint::uniform_quaternion(&mut rng);
                        let r = Transform::from_translation_quaternion(Vec3::zeros(), turn);
                        x.rotation = r.rotation * x.rotation;
                    }
                    let mut angular = u.angular_velocity.map_or(Vec3::zeros(), |w| w.0);
                    if let Some(spin) = u.spin {
                        let axis = loop {
                            let a = Vec3::from_fn(|_, _| rng.random_range(-1.0..=1.0));
                            if a.norm() > 0.1 && a.norm() <= 1.0 {
                                break a.normalize();
                            }
                        };
                        angular += axis * spin.0;
                    }
                    let mut model = model.clone();
                    let (mut q, mut v) = (q.clone(), v.clone());
                    if let Some(root) = root.filter(|_| u.floating) {
                        set_free_joint(&model, root, &x, u.velocity, Some(V3(angular)), &mut q, &mut v);
                    } else {
                        place_fixed_base(&mut model, &x);
                    }
                    let pose_servo = u.pose_servo.as_ref().map(|s| {
                        PoseServo::scaled_by_subtree_mass(
                            &model,
                            q.clone(),
                            s.gain.0,
                            s.max_velocity.0,
                            s.torque_per_kg.0,
                        )
                    });
                    let index = world
                        .add_multibody(&name, model, &meshes)
                        .map_err(self.world_error(u.path.span()))?;
                    world
                        .set_self_collision(index, u.self_collision)
                        .map_err(self.world_error(span.clone()))?;
                    for c in world.collision().colliders_of(index).to_vec() {
                        world.collision_mut().set_material(c, material);
                    }
                    let mb = world.multibody_mut(index);
                    mb.state.q = q;
                    mb.state.v = v;
                    if let Some(s) = &u.servo {
                        for &(k, target) in &servo_dofs {
                            mb.set_servo(
                                k,
                                Some(Servo {
                                    target_position: target,
                                    gain: s.gain.0,
                                    max_velocity: s.max_velocity.0,
                                    max_force: s.max_force.0,
                                }),
                            );
                        }
                    }
                    if let Some(servo) = pose_servo {
                        mb.set_pose_servo(Some(servo)).map_err(|source| SceneError::Model {
                            at: self.src.location(span.clone()),
                            source: Box::new(source),
                        })?;
                    }
                }
            }
        }
        Ok(warnings)
    }

    fn vehicle(&self, world: &mut World, v: &Spanned<VehicleSection>) -> Result<ScriptedVehicle, SceneError> {
        let span = v.span();
        let v = v.get_ref();
        let name = v.multibody.get_ref();
        let index = (0..world.multibody_count())
            .find(|&i| world.multibody_name(i) == name)
            .ok_or_else(|| self.src.invalid(v.multibody.span(), format!("no multibody `{name}`")))?;
        let defaults = VehicleConfig::buggy();
        let config = VehicleConfig {
            front: v.front.clone().unwrap_or(defaults.front),
            rear: v.rear.clone().unwrap_or(defaults.rear),
            driven: match v.driven {
                None => defaults.driven,
                Some(DrivenName::Rear) => Driven::Rear,
                Some(DrivenName::Front) => Driven::Front,
                Some(DrivenName::All) => Driven::All,
            },
            wheel_radius: v.wheel_radius.map_or(defaults.wheel_radius, |x| x.0),
            drive_torque: v.drive_torque.map_or(defaults.drive_torque, |x| x.0),
            brake_torque: v.brake_torque.map_or(defaults.brake_torque, |x| x.0),
            steering_gain: v.steering_gain.map_or(defaults.steering_gain, |x| x.0),
            steering_rate: v.steering_rate.map_or(defaults.steering_rate, |x| x.0),
            steering_torque: v.steering_torque.map_or(defaults.steering_torque, |x| x.0),
            patch_contact: v.patch_contact.unwrap_or(defaults.patch_contact),
        };
        let vehicle = Vehicle::attach(world, index, config)
            .map_err(|e| self.src.invalid(span.clone(), e.to_string()))?;
        let mut commands = Vec::with_capacity(v.command.len());
        for c in &v.command {
            let cspan = c.span();
            let c = c.get_ref();
            if c.speed.is_none() && c.coast.is_none() && c.steering_deg.is_none() && c.brake.is_none() {
                return Err(self.src.invalid(
                    cspan,
                    "a command sets at least one of `speed`, `coast`, `steering_deg`, `brake`",
                ));
            }
            if c.speed.is_some() && c.coast == Some(true) {
                return Err(self.src.invalid(cspan, "give `speed` or `coast = true`, not both"));
            }
            if let Some(deg) = c.steering_deg {
                if deg.0.abs() >= 90.0 {
                    return Err(self.src.invalid(
                        cspan,
                        format!("`steering_deg` must be between -90 and 90, got {}", deg.0),
                    ));
                }
            }
            commands.push(TimedCommand {
                at: c.at.0,
                speed: c.speed.map(|x| x.0),
                coast: c.coast.unwrap_or(false),
                steering: c.steering_deg.map(|x| x.0.to_radians()),
                brake: c.brake,
            });
        }
        // Stable: commands given for the same time apply in the order written.
        commands.sort_by(|a, b| a.at.total_cmp(&b.at));
        Ok(ScriptedVehicle { vehicle, commands, applied: 0 })
    }

    fn body(
        &mut self,
        world: &mut World,
        index: usize,
        body: &Spanned<BodySection>,
    ) -> Result<(), SceneError> {
        let span = body.span();
        let b = body.get_ref();
        let err = |message: String| self.src.invalid(span.clone(), message);
        let orientation = pose(b.position, b.rpy, b.quaternion).map_err(err)?;
        let material = self.material_of(&b.material)?;
        let need = |value: Option<Positive>, key: &str, shape: &str| {
            value.map(|x| x.0).ok_or_else(|| err(format!("a {shape} needs `{key}`")))
        };
        let refuse = |set: bool, key: &str, shape: &str| {
            if set {
                Err(err(format!("`{key}` does not apply to a {shape}")))
            } else {
                Ok(())
            }
        };
        let pi = std::f64::consts::PI;
        let (shape, volume) = match b.shape {
            ShapeName::Box => {
                refuse(b.radius.is_some(), "radius", "box")?;
                refuse(b.length.is_some(), "length", "box")?;
                let [x, y, z] = b.size.ok_or_else(|| err("a box needs `size = [x, y, z]`".to_string()))?;
                let size = Vec3::new(x.0, y.0, z.0);
                (Shape::Box { size }, size.x * size.y * size.z)
            }
            ShapeName::Sphere => {
                refuse(b.size.is_some(), "size", "sphere")?;
                refuse(b.length.is_some(), "length", "sphere")?;
                let r = need(b.radius, "radius", "sphere")?;
                (Shape::Sphere { radius: r }, 4.0 / 3.0 * pi * r.powi(3))
            }
            ShapeName::Capsule | ShapeName::Cylinder => {
                let what = if b.shape == ShapeName::Capsule { "capsule" } else { "cylinder" };
                refuse(b.size.is_some(), "size", what)?;
                let r = need(b.radius, "radius", what)?;
                let l = need(b.length, "length", what)?;
                if b.shape == ShapeName::Capsule {
                    (Shape::Capsule { radius: r, length: l }, pi * r * r * l + 4.0 / 3.0 * pi * r.powi(3))
                } else {
                    (Shape::Cylinder { radius: r, length: l }, pi * r * r * l)
                }
            }
        };
        let mass = match (b.mass, b.density) {
            (Some(_), Some(_)) => return Err(err("give `mass` or `density`, not both".to_string())),
            (Some(m), None) => m.0,
            (None, d) => d.map_or(1000.0, |d| d.0) * volume,
        };
        let inertia = match &shape {
            Shape::Box { size } => RigidInertia::solid_box(mass, *size),
            Shape::Sphere { radius } => RigidInertia::solid_sphere(mass, *radius),
            Shape::Capsule { radius, length } => RigidInertia::solid_capsule(mass, *radius, *length),
            Shape::Cylinder { radius, length } => RigidInertia::solid_cylinder(mass, *radius, *length),
            _ => unreachable!("primitive shapes only"),
        };
        if b.fixed && (b.velocity.is_some() || b.angular_velocity.is_some()) {
            return Err(err("a fixed body has no `velocity` or `angular_velocity`".to_string()));
        }

        // Copies.
        let (dims, grid) = match b.count {
            None => ([1, 1, 1], false),
            Some(Count::Row(n)) => ([n, 1, 1], false),
            Some(Count::Grid(d)) => (d, true),
        };
        let total = dims[0] * dims[1] * dims[2];
        let spacing = match (b.spacing, total) {
            (Some(s), _) => s.0,
            (None, 1) => Vec3::zeros(),
            (None, _) => return Err(err(format!("{total} copies need `spacing`"))),
        };
        let jitter = b.jitter.map_or(0.0, |x| x.0);
        if copies_coincide(dims, grid, &spacing, jitter) {
            return Err(err(format!(
                "{total} copies with `spacing` {:?} and no `jitter` would lie on each other",
                spacing.as_slice()
            )));
        }
        let mut rng = rand::rngs::StdRng::seed_from_u64(b.seed.unwrap_or(0));
        let base = b.name.clone().unwrap_or_else(|| format!("body{index}"));

        let model = if b.fixed {
            None
        } else {
            let spec = BodySpec::new(base.clone(), "universe", Joint::Free, Transform::identity(), inertia)
                .with_joint_name("free")
                .with_collision(shape.clone(), Transform::identity());
            let mut builder = ModelBuilder::new();
            builder.name(base.clone()).add_body(spec);
            Some(builder.build().map_err(|source| SceneError::Model {
                at: self.src.location(span.clone()),
                source: Box::new(source),
            })?)
        };
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let name = if total == 1 {
                        base.clone()
                    } else if grid {
                        format!("{base}_{i}_{j}_{k}")
                    } else {
                        format!("{base}{i}")
                    };
                    self.claim_name(&name, span.clone())?;
                    let offset = if grid {
                        Vec3::new(i as f64 * spacing.x, j as f64 * spacing.y, k as f64 * spacing.z)
                    } else {
                        i as f64 * spacing
                    };
                    let mut noise = Vec3::zeros();
                    if jitter > 0.0 {
                        noise = Vec3::from_fn(|_, _| rng.random_range(-jitter..=jitter));
                    }
                    let mut x = orientation;
                    x.translation += offset + noise;
                    match &model {
                        None => {
                            world
                                .add_static(&name, &shape, x, material)
                                .map_err(self.world_error(span.clone()))?;
                        }
                        Some(model) => {
                            let mut model = model.clone();
                            model.name = name.clone();
                            let index = world
                                .add_multibody(&name, model, &MeshOptions::default())
                                .map_err(self.world_error(span.clone()))?;
                            for c in world.collision().colliders_of(index).to_vec() {
                                world.collision_mut().set_material(c, material);
                            }
                            let mb = world.multibody_mut(index);
                            let (mut q, mut v) = (mb.state.q.clone(), mb.state.v.clone());
                            set_free_joint(mb.model(), 1, &x, b.velocity, b.angular_velocity, &mut q, &mut v);
                            mb.state.q = q;
                            mb.state.v = v;
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

/// A pose from `position` and either `rpy` (rad) or `quaternion` (`[x, y, z, w]`).
fn pose(position: Option<V3>, rpy: Option<V3>, quaternion: Option<[Finite; 4]>) -> Result<Transform, String> {
    let p = position.map_or(Vec3::zeros(), |p| p.0);
    match (rpy, quaternion) {
        (Some(_), Some(_)) => Err("give `rpy` or `quaternion`, not both".to_string()),
        (None, Some(q)) => {
            let xyzw = q.map(|x| x.0);
            if xyzw.iter().map(|x| x * x).sum::<f64>().sqrt() < 1e-9 {
                return Err("`quaternion` must not be zero".to_string());
            }
            Ok(Transform::from_translation_quaternion(p, xyzw))
        }
        (r, None) => {
            let r = r.map_or(Vec3::zeros(), |r| r.0);
            Ok(Transform::from_xyz_rpy([p.x, p.y, p.z], [r.x, r.y, r.z]))
        }
    }
}

/// Sets the free joint `j` (a child of the universe) so that its body is at world pose `x`, moving
/// with world-axes `velocity` (of the body origin) and `angular_velocity`.
fn set_free_joint(
    model: &Model,
    j: usize,
    x: &Transform,
    velocity: Option<V3>,
    angular_velocity: Option<V3>,
    q: &mut nalgebra::DVector<f64>,
    v: &mut nalgebra::DVector<f64>,
) {
    let local = model.placement(j).inverse() * *x;
    let (iq, iv) = (model.idx_q(j), model.idx_v(j));
    q.rows_mut(iq, 3).copy_from(&local.translation);
    q.rows_mut(iq + 3, 4).copy_from_slice(&local.quaternion_xyzw());
    let rt = x.rotation.transpose();
    v.rows_mut(iv, 3).copy_from(&(rt * velocity.map_or(Vec3::zeros(), |w| w.0)));
    v.rows_mut(iv + 3, 3).copy_from(&(rt * angular_velocity.map_or(Vec3::zeros(), |w| w.0)));
}

/// Moves a fixed-base model so that its root link (fused into the universe) sits at world pose `x`:
/// the joints attached to the universe, the universe's geometry and its frames are moved.
fn place_fixed_base(model: &mut Model, x: &Transform) {
    for i in 1..model.nbodies() {
        if model.parents[i] == 0 {
            model.placements[i] = x * &model.placements[i];
        }
    }
    for g in model.geometries.iter_mut().filter(|g| g.body == 0) {
        g.placement = x * &g.placement;
    }
    for f in model.frames.iter_mut().skip(1).filter(|f| f.body == 0) {
        f.placement = x * &f.placement;
    }
}
