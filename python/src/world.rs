//! `gelenk.World`: a simulated world (from a scene file, an MJCF file, a model or a built-in
//! scene) with its state as numpy arrays, forces, motors, contacts and step statistics, and the
//! loaders `load_scene` and `load_mjcf`.

use crate::arrays::{to_py1, vec3, vector};
use crate::checks::{self, Allowed};
use crate::errors::{self, StepError};
use crate::model::PyModel;
use crate::sim::{Layout, Recipe, Sim};
use gelenk::world::{Motor, Servo, WorldOptions};
use numpy::PyArray1;
use pyo3::exceptions::{PyIndexError, PyKeyError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::{Arc, Mutex, MutexGuard};

/// A simulated world: multibodies, static geometry, contacts, limits, motors and loop closures
/// stepped together (`step`, `advance`). Its state is the flat vector `[qpos, qvel]` over its
/// multibodies in order (`get_state`, `set_state`, `state_labels`, `joint_index`); each
/// multibody's own q, v and joint forces τ are reachable by index or name.
///
/// `World(model, dt=None, gravity=None, ground=False, missing_meshes="error")`: a world holding
/// `model` as its only multibody, at the model's neutral configuration and at rest, with time
/// step `dt` (s; default 0.002), gravity `gravity` (m/s²; default (0, 0, −9.81)) and, if
/// `ground`, the ground plane z = 0. A collision mesh that cannot be found is an error, or with
/// `missing_meshes="skip"` left out (listed in `warnings`). Scene files, MJCF files and the
/// built-in scenes give worlds too: `load_scene`, `load_mjcf`, `World.builtin`.
#[pyclass(name = "World", module = "gelenk")]
pub struct PyWorld {
    /// Locked only to reach the world from `&self`; Python's borrow rules already serialize use.
    sim: Mutex<Sim>,
    layout: Layout,
    name: String,
}

impl PyWorld {
    /// Wraps a world.
    pub fn wrap(sim: Sim, name: String) -> Self {
        let layout = sim.layout();
        Self { sim: Mutex::new(sim), layout, name }
    }

    /// The world, locked.
    pub fn lock(&self) -> MutexGuard<'_, Sim> {
        self.sim.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// The flat layout of the state.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The index of a multibody given as an index or a name.
    fn multibody_index(&self, sim: &Sim, multibody: &Bound<'_, PyAny>) -> PyResult<usize> {
        let world = sim.world();
        let count = world.multibody_count();
        if let Ok(i) = multibody.extract::<usize>() {
            if i >= count {
                return Err(PyIndexError::new_err(format!(
                    "index {i} is out of range ({count} multibodies)"
                )));
            }
            return Ok(i);
        }
        let name: String = multibody
            .extract()
            .map_err(|_| PyTypeError::new_err("multibody: expected an index (int) or a name (str)"))?;
        (0..count)
            .find(|&i| world.multibody_name(i) == name)
            .ok_or_else(|| PyKeyError::new_err(format!("no multibody named `{name}`")))
    }

    /// The index of a body of multibody `mb` given as an index (≥ 1) or a name.
    fn body_index(sim: &Sim, mb: usize, body: &Bound<'_, PyAny>) -> PyResult<usize> {
        let model = sim.world().multibody(mb).model();
        if let Ok(i) = body.extract::<usize>() {
            return Ok(i);
        }
        let name: String = body
            .extract()
            .map_err(|_| PyTypeError::new_err("body: expected an index (int) or a name (str)"))?;
        model.body_id(&name).ok_or_else(|| PyKeyError::new_err(format!("no body named `{name}`")))
    }

    fn options(dt: Option<f64>, gravity: Option<[f64; 3]>) -> PyResult<WorldOptions> {
        let mut options = WorldOptions::default();
        if let Some(dt) = dt {
            options.dt = checks::number("dt", dt, Allowed::Positive)?;
        }
        if let Some(g) = gravity {
            checks::numbers("gravity", &g, Allowed::Finite)?;
            options.gravity = g.into();
        }
        Ok(options)
    }
}

/// The statistics of the last step as a dict.
pub fn stats_dict<'py>(py: Python<'py>, stats: &gelenk::world::StepStats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("step", stats.step)?;
    d.set_item("time", stats.time)?;
    d.set_item("contacts", stats.contacts)?;
    d.set_item("rows", stats.rows)?;
    d.set_item("solver", stats.solver)?;
    d.set_item("iterations", stats.iterations)?;
    d.set_item("residual", stats.residual)?;
    d.set_item("fallbacks", stats.fallbacks.len())?;
    d.set_item("max_penetration", stats.max_penetration)?;
    d.set_item("asleep", stats.asleep)?;
    d.set_item("energy", stats.energy)?;
    d.set_item("integrator", stats.integrator)?;
    Ok(d)
}

#[pymethods]
impl PyWorld {
    /// The constructor, documented on the class (where `help()` shows it).
    #[new]
    #[pyo3(signature = (model, dt=None, gravity=None, ground=false, missing_meshes="error"))]
    fn new(
        model: &Bound<'_, PyModel>,
        dt: Option<f64>,
        gravity: Option<[f64; 3]>,
        ground: bool,
        missing_meshes: &str,
    ) -> PyResult<Self> {
        let model = model.get().model.clone();
        let options = Self::options(dt, gravity)?;
        let meshes = match missing_meshes {
            "error" => gelenk::collision::MeshOptions::default(),
            "skip" => crate::sim::skip_meshes(),
            other => {
                return Err(PyValueError::new_err(format!(
                    "missing_meshes: expected \"error\" or \"skip\", got \"{other}\""
                )))
            }
        };
        let name = model.name().to_string();
        let recipe = Arc::new(Recipe::Model { model, options: Box::new(options), ground, meshes });
        let world = recipe.build().map_err(PyValueError::new_err)?;
        Ok(Self::wrap(Sim::World { world: Box::new(world), recipe }, name))
    }

    /// A built-in scene ("box-drop", "box-flat", "stack2", "stack10", "sphere-incline",
    /// "four-bar", "limit-pendulum") as a world.
    #[staticmethod]
    fn builtin(name: &str) -> PyResult<Self> {
        let recipe = Arc::new(Recipe::BuiltIn(name.to_string()));
        let world = recipe.build().map_err(PyValueError::new_err)?;
        Ok(Self::wrap(Sim::World { world: Box::new(world), recipe }, name.to_string()))
    }

    /// The scene's or model's name.
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }
    /// Time step (s).
    #[getter]
    fn dt(&self) -> f64 {
        self.lock().world().options().dt
    }
    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.lock().world().time()
    }
    /// Total configuration coordinates (length of qpos).
    #[getter]
    fn nq(&self) -> usize {
        self.layout.nq()
    }
    /// Total velocity coordinates (length of qvel, and of the joint forces τ).
    #[getter]
    fn nv(&self) -> usize {
        self.layout.nv()
    }
    /// Length of the state vector `[qpos, qvel]`.
    #[getter]
    fn nstate(&self) -> usize {
        self.layout.nstate()
    }
    /// What was left out while loading (collision meshes skipped), one sentence each.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.lock().warnings()
    }
    /// Names of the multibodies, in order.
    #[getter]
    fn multibody_names(&self) -> Vec<String> {
        let sim = self.lock();
        let world = sim.world();
        (0..world.multibody_count()).map(|i| world.multibody_name(i).to_string()).collect()
    }
    /// One dict per joint of every multibody: `multibody`, `joint`, `type`, `qpos` (first index in
    /// qpos and in the state), `nq`, `qvel` (first index in qvel; in the state add `nq`), `nv`.
    fn joint_index<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let sim = self.lock();
        let world = sim.world();
        let mut out = Vec::new();
        for i in 0..world.multibody_count() {
            let model = world.multibody(i).model();
            for j in 1..model.nbodies() {
                let d = PyDict::new(py);
                d.set_item("multibody", world.multibody_name(i))?;
                d.set_item("joint", model.joint_name(j))?;
                d.set_item("type", crate::model::joint_kind(model.joint(j)))?;
                d.set_item("qpos", self.layout.q_start[i] + model.idx_q(j))?;
                d.set_item("nq", model.joint(j).nq())?;
                d.set_item("qvel", self.layout.v_start[i] + model.idx_v(j))?;
                d.set_item("nv", model.joint(j).nv())?;
                out.push(d);
            }
        }
        Ok(out)
    }
    /// A name for every entry of the state `[qpos, qvel]`: `multibody.joint` for a scalar
    /// joint's coordinate, `multibody.joint.component` otherwise (`x y z qx qy qz qw` of a free
    /// joint), velocities ending in `.v` or naming their component (`vx … wz`) — the columns of
    /// `gelenk simulate --out`.
    fn state_labels(&self) -> Vec<String> {
        let sim = self.lock();
        let world = sim.world();
        let (mut positions, mut velocities) = (Vec::new(), Vec::new());
        for i in 0..world.multibody_count() {
            let model = world.multibody(i).model();
            for j in 1..model.nbodies() {
                let (q_labels, v_labels) = gelenk::run::coordinate_labels(model.joint(j));
                let base = format!("{}.{}", world.multibody_name(i), model.joint_name(j));
                positions.extend(q_labels.iter().map(|l| {
                    if l.is_empty() {
                        base.clone()
                    } else {
                        format!("{base}.{l}")
                    }
                }));
                velocities.extend(v_labels.iter().map(|l| format!("{base}.{l}")));
            }
        }
        positions.extend(velocities);
        positions
    }

    /// The state `[qpos, qvel]` (a new array of `nstate` entries).
    fn get_state<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let mut out = vec![0.0; self.layout.nstate()];
        self.lock().read_state(&self.layout, &mut out);
        PyArray1::from_vec(py, out)
    }
    /// Sets the state `[qpos, qvel]` (ValueError for the wrong length, a non-finite entry or a
    /// quaternion that cannot be normalized; nothing changes then) and wakes every multibody.
    fn set_state(&self, state: &Bound<'_, PyAny>) -> PyResult<()> {
        let x = vector(state, "state", self.layout.nstate())?;
        self.lock().write_state(&self.layout, x.as_slice()).map_err(PyValueError::new_err)
    }
    /// Configuration of every multibody, laid end to end (nq entries; a new array).
    #[getter]
    fn qpos<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let mut out = vec![0.0; self.layout.nstate()];
        self.lock().read_state(&self.layout, &mut out);
        out.truncate(self.layout.nq());
        PyArray1::from_vec(py, out)
    }
    #[setter]
    fn set_qpos(&self, qpos: &Bound<'_, PyAny>) -> PyResult<()> {
        let q = vector(qpos, "qpos", self.layout.nq())?;
        let mut sim = self.lock();
        let mut x = vec![0.0; self.layout.nstate()];
        sim.read_state(&self.layout, &mut x);
        x[..self.layout.nq()].copy_from_slice(q.as_slice());
        sim.write_state(&self.layout, &x).map_err(PyValueError::new_err)
    }
    /// Velocity of every multibody, laid end to end (nv entries; a new array).
    #[getter]
    fn qvel<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let mut out = vec![0.0; self.layout.nstate()];
        self.lock().read_state(&self.layout, &mut out);
        PyArray1::from_vec(py, out.split_off(self.layout.nq()))
    }
    #[setter]
    fn set_qvel(&self, qvel: &Bound<'_, PyAny>) -> PyResult<()> {
        let v = vector(qvel, "qvel", self.layout.nv())?;
        let mut sim = self.lock();
        let mut x = vec![0.0; self.layout.nstate()];
        sim.read_state(&self.layout, &mut x);
        x[self.layout.nq()..].copy_from_slice(v.as_slice());
        sim.write_state(&self.layout, &x).map_err(PyValueError::new_err)
    }
    /// Joint forces τ of every multibody, laid end to end (nv entries, N·m or N), applied at
    /// every step until changed.
    #[getter]
    fn tau<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let sim = self.lock();
        let world = sim.world();
        let mut out = Vec::with_capacity(self.layout.nv());
        for i in 0..world.multibody_count() {
            out.extend(world.multibody(i).tau.iter());
        }
        PyArray1::from_vec(py, out)
    }
    #[setter]
    fn set_tau(&self, tau: &Bound<'_, PyAny>) -> PyResult<()> {
        let tau = vector(tau, "tau", self.layout.nv())?;
        checks::numbers("tau", tau.as_slice(), Allowed::Finite)?;
        self.lock().write_tau(&self.layout, tau.as_slice());
        Ok(())
    }
    /// Configuration q of one multibody (an index or a name).
    fn q<'py>(&self, py: Python<'py>, multibody: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let sim = self.lock();
        let i = self.multibody_index(&sim, multibody)?;
        Ok(to_py1(py, sim.world().multibody(i).state.q.as_slice()))
    }
    /// Velocity v of one multibody (an index or a name).
    fn v<'py>(&self, py: Python<'py>, multibody: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let sim = self.lock();
        let i = self.multibody_index(&sim, multibody)?;
        Ok(to_py1(py, sim.world().multibody(i).state.v.as_slice()))
    }
    /// Sets the configuration q (and, if given, the velocity v) of one multibody and wakes it.
    #[pyo3(signature = (multibody, q, v=None))]
    fn set_multibody_state(
        &self,
        multibody: &Bound<'_, PyAny>,
        q: &Bound<'_, PyAny>,
        v: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let mut sim = self.lock();
        let i = self.multibody_index(&sim, multibody)?;
        let mut x = vec![0.0; self.layout.nstate()];
        sim.read_state(&self.layout, &mut x);
        let (q0, q1) = (self.layout.q_start[i], self.layout.q_start[i + 1]);
        x[q0..q1].copy_from_slice(vector(q, "q", q1 - q0)?.as_slice());
        if let Some(v) = v {
            let nq = self.layout.nq();
            let (v0, v1) = (nq + self.layout.v_start[i], nq + self.layout.v_start[i + 1]);
            x[v0..v1].copy_from_slice(vector(v, "v", v1 - v0)?.as_slice());
        }
        sim.write_state(&self.layout, &x).map_err(PyValueError::new_err)
    }
    /// The model of one multibody (an index or a name), for the dynamics functions.
    fn model(&self, multibody: &Bound<'_, PyAny>) -> PyResult<PyModel> {
        let sim = self.lock();
        let i = self.multibody_index(&sim, multibody)?;
        Ok(PyModel { model: sim.world().multibody(i).model().clone() })
    }

    /// Takes `n` steps of `dt` (the GIL is released meanwhile). A scene file's vehicle commands
    /// are applied before each step whose time has come, as `gelenk simulate` does. Raises
    /// `gelenk.StepError` when a step fails, with the message `gelenk simulate` prints; the
    /// state is then the one before the failed step.
    #[pyo3(signature = (n=1))]
    fn step(&self, py: Python<'_>, n: usize) -> PyResult<()> {
        let mut sim = self.lock();
        let sim = &mut *sim;
        py.detach(|| {
            errors::guard(|| {
                for _ in 0..n {
                    sim.step().map_err(StepError::new_err)?;
                }
                Ok(())
            })
        })
    }
    /// Runs whole steps of `dt` for a frame of `frame_dt` seconds (at most `max_substeps` of
    /// them; the rest of the backlog is dropped) and returns the interpolation factor
    /// α ∈ [0, 1) between the last two states, for rendering.
    fn advance(&self, frame_dt: f64) -> PyResult<f64> {
        checks::number("frame_dt", frame_dt, Allowed::Finite)?;
        let mut sim = self.lock();
        errors::guard(|| sim.world_mut().advance(frame_dt).map_err(errors::step))
    }
    /// The world again at its initial state (the scene or model as loaded).
    fn reset(&self) -> PyResult<()> {
        let mut sim = self.lock();
        let fresh = errors::guard(|| sim.fresh().map_err(PyValueError::new_err))?;
        *sim = fresh;
        Ok(())
    }

    /// Statistics of the last step: `step`, `time` (s), `contacts`, `rows`, `solver`,
    /// `iterations`, `residual` (m/s), `fallbacks`, `max_penetration` (m), `asleep`, `energy`
    /// (J, or None unless diagnostics are on), `integrator`.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        stats_dict(py, self.lock().world().stats())
    }
    /// Kinetic plus potential energy of every multibody at the current state (J).
    fn energy(&self) -> f64 {
        self.lock().world_mut().total_energy()
    }
    /// Kinetic energy of every multibody at the current state (J).
    fn kinetic_energy(&self) -> f64 {
        self.lock().world_mut().kinetic_energy()
    }

    /// The contacts of the last step as a dict of arrays, one row per contact point:
    /// `point_a`, `point_b` (k × 3, m, world: the nearest points of the two surfaces),
    /// `normal` (k × 3, unit, from B to A), `distance` (k, m: negative = penetration),
    /// `depth` (k, m: penetration depth, max(−distance, 0)), `impulse` (k × 3, N·s: normal
    /// then the two friction impulses; zero for a contact without rows), `multibody_a`,
    /// `body_a`, `multibody_b`, `body_b` (k; −1 for static geometry), `collider_a`,
    /// `collider_b` (names).
    fn contacts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        crate::contacts::contacts_dict(py, self.lock().world())
    }
    /// Impulses of the last step's constraint rows (N·s), one per row of `problem()`.
    fn impulses<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.lock().world().impulses().as_slice())
    }
    /// The last step's constraint problem `w = (A + R) λ + b`: `A` (rows × rows Delassus
    /// matrix), `R` (regularization), `b` (bias), `target`, `normal_rows` (row of each
    /// contact's normal), `mu`, `friction` ("cone" or "pyramidN").
    fn problem<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        crate::contacts::problem_dict(py, self.lock().world().problem())
    }

    /// Applies the force `force` (N, world axes) at the world point `point` (m), and the
    /// torque `torque` (N·m, world axes), to body `body` (an index ≥ 1 or a name) of
    /// `multibody` during the next step.
    #[pyo3(signature = (multibody, body, force, point, torque=None))]
    fn apply_force(
        &self,
        multibody: &Bound<'_, PyAny>,
        body: &Bound<'_, PyAny>,
        force: &Bound<'_, PyAny>,
        point: &Bound<'_, PyAny>,
        torque: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let (force, point) = (vec3(force, "force")?, vec3(point, "point")?);
        let torque = torque.map(|t| vec3(t, "torque")).transpose()?.unwrap_or_default();
        for (v, name) in [(&force, "force"), (&point, "point"), (&torque, "torque")] {
            checks::numbers(name, v.as_slice(), Allowed::Finite)?;
        }
        let mut sim = self.lock();
        let i = self.multibody_index(&sim, multibody)?;
        let b = Self::body_index(&sim, i, body)?;
        sim.world_mut().apply_force(i, b, force, point, torque).map_err(errors::step)
    }
    /// Applies the impulse `impulse` (N·s, world axes) at the world point `point` (m) to body
    /// `body` of `multibody`: an instant velocity change.
    fn apply_impulse(
        &self,
        multibody: &Bound<'_, PyAny>,
        body: &Bound<'_, PyAny>,
        impulse: &Bound<'_, PyAny>,
        point: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let (impulse, point) = (vec3(impulse, "impulse")?, vec3(point, "point")?);
        checks::numbers("impulse", impulse.as_slice(), Allowed::Finite)?;
        checks::numbers("point", point.as_slice(), Allowed::Finite)?;
        let mut sim = self.lock();
        let i = self.multibody_index(&sim, multibody)?;
        let b = Self::body_index(&sim, i, body)?;
        errors::guard(|| sim.world_mut().apply_impulse(i, b, impulse, point).map_err(errors::step))
    }
    /// Puts a velocity motor on dof `dof` of `multibody`: drive its rate to `target_velocity`
    /// (rad/s or m/s) with at most `max_force` (N·m or N); `target_velocity=None` removes it.
    #[pyo3(signature = (multibody, dof, target_velocity, max_force=f64::INFINITY))]
    fn set_motor(
        &self,
        multibody: &Bound<'_, PyAny>,
        dof: usize,
        target_velocity: Option<f64>,
        max_force: f64,
    ) -> PyResult<()> {
        if let Some(target_velocity) = target_velocity {
            checks::number("target_velocity", target_velocity, Allowed::Finite)?;
        }
        checks::number("max_force", max_force, Allowed::Bound)?;
        let mut sim = self.lock();
        let i = self.multibody_index(&sim, multibody)?;
        check_dof(sim.world().multibody(i).model().nv(), dof)?;
        let motor = target_velocity.map(|target_velocity| Motor { target_velocity, max_force });
        sim.world_mut().wake(i);
        sim.world_mut().multibody_mut(i).set_motor(dof, motor);
        Ok(())
    }
    /// Puts a position servo on dof `dof` of `multibody`: a motor whose target rate is
    /// `gain · (target_position − q)` (gain in 1/s), clamped to `max_velocity`, with force bound
    /// `max_force`; `target_position=None` removes it.
    #[pyo3(signature = (multibody, dof, target_position, gain=10.0, max_velocity=f64::INFINITY, max_force=f64::INFINITY))]
    fn set_servo(
        &self,
        multibody: &Bound<'_, PyAny>,
        dof: usize,
        target_position: Option<f64>,
        gain: f64,
        max_velocity: f64,
        max_force: f64,
    ) -> PyResult<()> {
        if let Some(target_position) = target_position {
            checks::number("target_position", target_position, Allowed::Finite)?;
        }
        checks::number("gain", gain, Allowed::NonNegative)?;
        checks::number("max_velocity", max_velocity, Allowed::Bound)?;
        checks::number("max_force", max_force, Allowed::Bound)?;
        let mut sim = self.lock();
        let i = self.multibody_index(&sim, multibody)?;
        check_dof(sim.world().multibody(i).model().nv(), dof)?;
        let servo =
            target_position.map(|target_position| Servo { target_position, gain, max_velocity, max_force });
        sim.world_mut().wake(i);
        sim.world_mut().multibody_mut(i).set_servo(dof, servo);
        Ok(())
    }

    fn __repr__(&self) -> String {
        let sim = self.lock();
        format!(
            "gelenk.World(name={:?}, multibodies={}, nq={}, nv={}, dt={}, time={})",
            self.name,
            sim.world().multibody_count(),
            self.layout.nq(),
            self.layout.nv(),
            sim.world().options().dt,
            sim.world().time()
        )
    }
}

/// Checks a motor's or servo's dof index against the multibody's `nv` dofs.
fn check_dof(nv: usize, dof: usize) -> PyResult<()> {
    if dof >= nv {
        return Err(PyIndexError::new_err(format!("dof {dof} is out of range ({nv} dofs)")));
    }
    Ok(())
}

/// Loads a scene file (TOML, see docs/scenes.md): URDF models, bodies, grounds, materials,
/// solver and time step. Raises FileNotFoundError, ValueError (naming the file, line and key).
#[pyfunction]
pub fn load_scene(path: std::path::PathBuf) -> PyResult<PyWorld> {
    errors::guard(|| {
        let scene = gelenk::io::scene::load_file(&path).map_err(errors::scene)?;
        let name = scene.name.clone();
        Ok(PyWorld::wrap(Sim::Scene(Box::new(scene)), name))
    })
}

/// Loads an MJCF file (MuJoCo's format) as a world: each of the model's trees (a top-level body
/// and what hangs from it) a multibody at MuJoCo's `qpos0`, on its static geometry, with its
/// time step, gravity and friction model. Raises FileNotFoundError, ValueError.
#[pyfunction]
pub fn load_mjcf(path: std::path::PathBuf) -> PyResult<PyWorld> {
    errors::guard(|| {
        let scene = gelenk::io::mjcf::load_file(&path).map_err(errors::mjcf)?;
        let name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let recipe = Arc::new(Recipe::Mjcf(scene));
        let world = recipe.build().map_err(PyValueError::new_err)?;
        Ok(PyWorld::wrap(Sim::World { world: Box::new(world), recipe }, name))
    })
}
