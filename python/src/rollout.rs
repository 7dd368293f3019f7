//! `gelenk.rollout`: B worlds of one scene stepped T times each, one world per task on a rayon
//! pool with the GIL released (MuJoCo's `mujoco.rollout`). Each world is stepped by one thread
//! from start to end and shares nothing with the others, so the result does not depend on the
//! number of threads: it is bit for bit what stepping each world alone gives.

use crate::arrays::{array2, array3};
use crate::checks::{self, Allowed};
use crate::errors::{self, StepError};
use crate::model::PyModel;
use crate::sim::{skip_meshes, Layout, Recipe, Sim};
use crate::world::PyWorld;
use numpy::{PyArray1, PyArray3, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use std::borrow::Cow;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

/// Per world, the statistics of each step.
#[derive(Default)]
struct StepRecord {
    contacts: Vec<i64>,
    rows: Vec<i64>,
    iterations: Vec<i64>,
    residual: Vec<f64>,
    max_penetration: Vec<f64>,
}

/// A rayon pool of `threads` threads, built once per size.
fn pool(threads: usize) -> PyResult<Arc<rayon::ThreadPool>> {
    static POOLS: OnceLock<Mutex<HashMap<usize, Arc<rayon::ThreadPool>>>> = OnceLock::new();
    let mut pools = POOLS.get_or_init(Default::default).lock().unwrap_or_else(|p| p.into_inner());
    if let Some(p) = pools.get(&threads) {
        return Ok(Arc::clone(p));
    }
    let built = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("gelenk-rollout-{i}"))
        .build()
        .map_err(|e| PyValueError::new_err(format!("threads: cannot start {threads} threads: {e}")))?;
    let built = Arc::new(built);
    pools.insert(threads, Arc::clone(&built));
    Ok(built)
}

/// The world a rollout's worlds are built from: a `World`'s at its initial state, or a `Model`
/// alone in a default world.
fn template(scene: &Bound<'_, PyAny>) -> PyResult<(Sim, Layout)> {
    if let Ok(world) = scene.cast::<PyWorld>() {
        let world = world.borrow();
        let sim = world.lock();
        let fresh = errors::guard(|| sim.fresh().map_err(PyValueError::new_err))?;
        return Ok((fresh, world.layout().clone()));
    }
    if let Ok(model) = scene.cast::<PyModel>() {
        let model = model.get().model.clone();
        let recipe = Arc::new(Recipe::Model {
            model,
            options: Default::default(),
            ground: false,
            meshes: skip_meshes(),
        });
        let world = recipe.build().map_err(PyValueError::new_err)?;
        let sim = Sim::World { world: Box::new(world), recipe };
        let layout = sim.layout();
        return Ok((sim, layout));
    }
    Err(PyTypeError::new_err("scene: expected a gelenk.World or a gelenk.Model"))
}

/// Why one world of a rollout stopped.
enum Failure {
    /// Its world could not be built again from the scene (the message says why).
    Build(String),
    /// Its initial state was refused (the message says why).
    InitialState(String),
    /// A step failed (the message names the step).
    Step(String),
}

/// Steps one world from `initial` for `steps` steps, with joint forces `controls[t]` (if any)
/// before step t, writing the state after each step into `out` (steps × nstate).
fn run_one(
    sim: &mut Sim,
    layout: &Layout,
    initial: &[f64],
    controls: Option<&[f64]>,
    out: &mut [f64],
    record: &mut StepRecord,
    want_stats: bool,
) -> Result<(), Failure> {
    let (nstate, nv) = (layout.nstate(), layout.nv());
    sim.write_state(layout, initial).map_err(Failure::InitialState)?;
    for (t, row) in out.chunks_mut(nstate).enumerate() {
        if let Some(u) = controls {
            sim.write_tau(layout, &u[t * nv..(t + 1) * nv]);
        }
        sim.step().map_err(Failure::Step)?;
        sim.read_state(layout, row);
        if want_stats {
            let s = sim.world().stats();
            record.contacts.push(s.contacts as i64);
            record.rows.push(s.rows as i64);
            record.iterations.push(s.iterations as i64);
            record.residual.push(s.residual);
            record.max_penetration.push(s.max_penetration);
        }
    }
    Ok(())
}

/// Rolls out B copies of `scene` (a `World`, rebuilt at its initial state as loaded, or a
/// `Model` alone in a world without ground, its collision meshes that cannot be found left
/// out) from `initial_states` (B × nstate, each a state
/// `[qpos, qvel]` as `World.get_state` gives) for `steps` steps, applying the joint forces
/// `controls[b, t]` (B × T × nv, N·m or N; None: the scene's own forces) before step t, on
/// `threads` threads (None: one per core) with the GIL released. Returns the states after each
/// step, B × T × nstate, and with `stats=True` also a dict of B × T arrays: `contacts`, `rows`,
/// `iterations`, `residual` (m/s), `max_penetration` (m). The result is the same, bit for bit,
/// for any number of threads, and equals stepping each world alone. Raises ValueError for bad
/// shapes or a non-finite or degenerate initial state, `gelenk.StepError` when a step fails
/// (naming the rollout and the step).
#[pyfunction]
#[pyo3(signature = (scene, initial_states, controls=None, steps=None, threads=None, stats=false))]
pub fn rollout<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
    initial_states: &Bound<'py, PyAny>,
    controls: Option<&Bound<'py, PyAny>>,
    steps: Option<usize>,
    threads: Option<usize>,
    stats: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let (template, layout) = template(scene)?;
    let (nstate, nv) = (layout.nstate(), layout.nv());
    let initial = array2(initial_states, "initial_states")?;
    let [batch, width] = [initial.shape()[0], initial.shape()[1]];
    if width != nstate {
        return Err(PyValueError::new_err(format!(
            "initial_states: expected shape (B, {nstate}) (nstate = nq + nv = {} + {}), got {:?}",
            layout.nq(),
            nv,
            initial.shape()
        )));
    }
    let controls = controls.map(|c| array3(c, "controls")).transpose()?;
    let steps = match (&controls, steps) {
        (Some(c), s) => {
            let shape = c.shape();
            if shape[0] != batch || shape[2] != nv || s.is_some_and(|s| s != shape[1]) {
                return Err(PyValueError::new_err(format!(
                    "controls: expected shape ({batch}, {}, {nv}) (B, steps, nv), got {shape:?}",
                    s.map_or_else(|| "T".to_string(), |s| s.to_string())
                )));
            }
            shape[1]
        }
        (None, Some(s)) => s,
        (None, None) => return Err(PyValueError::new_err("steps: required when controls is None")),
    };
    if threads == Some(0) {
        return Err(PyValueError::new_err("threads: at least 1"));
    }
    // Read in place where the arrays are contiguous (the usual case), else copied once.
    let initial: Cow<'_, [f64]> = match initial.as_slice() {
        Ok(slice) => Cow::Borrowed(slice),
        Err(_) => Cow::Owned(initial.as_array().iter().copied().collect()),
    };
    let controls: Option<Cow<'_, [f64]>> = controls.as_ref().map(|c| match c.as_slice() {
        Ok(slice) => Cow::Borrowed(slice),
        Err(_) => Cow::Owned(c.as_array().iter().copied().collect()),
    });
    if let Some(c) = controls.as_deref() {
        if let Some(k) = c.iter().position(|x| !x.is_finite()) {
            let (b, t, i) = (k / (steps * nv), k / nv % steps, k % nv);
            checks::number(&format!("controls[{b}, {t}, {i}]"), c[k], Allowed::Finite)?;
        }
    }

    let states = PyArray3::<f64>::zeros(py, [batch, steps, nstate], false);
    let mut out = states.readwrite();
    let out = out.as_slice_mut().expect("a new array is contiguous");
    let mut records: Vec<StepRecord> = (0..batch).map(|_| StepRecord::default()).collect();
    let pool = threads.map(pool).transpose()?;

    let failure = py.detach(|| {
        errors::guard(|| {
            // Each task builds its world from the template (on the thread that steps it, while
            // the other threads step theirs) and drops it when done: only as many worlds as
            // threads exist at once. A world cannot be shared between threads (it keeps scratch
            // buffers in cells), so the template is reached through a lock, held while building.
            let template = Mutex::new(template);
            let fresh = || template.lock().unwrap_or_else(|p| p.into_inner()).fresh();
            let block = steps * nstate;
            let mut work = || {
                out.par_chunks_mut(block.max(1))
                    .zip(records.par_iter_mut())
                    .enumerate()
                    .map(|(b, (out, record))| {
                        let mut sim = fresh().map_err(|e| (b, Failure::Build(e)))?;
                        let x0 = &initial[b * nstate..(b + 1) * nstate];
                        let u = controls.as_deref().map(|c| &c[b * steps * nv..(b + 1) * steps * nv]);
                        run_one(&mut sim, &layout, x0, u, out, record, stats).map_err(|e| (b, e))
                    })
                    .collect::<Vec<_>>()
            };
            let results = match &pool {
                Some(pool) => pool.install(work),
                None => work(),
            };
            Ok(results.into_iter().find_map(Result::err))
        })
    })?;
    match failure {
        Some((b, Failure::Step(message))) => {
            return Err(StepError::new_err(format!("rollout {b}, {message}")))
        }
        Some((b, Failure::Build(message))) => {
            return Err(PyValueError::new_err(format!("rollout {b}: {message}")))
        }
        Some((b, Failure::InitialState(message))) => {
            return Err(PyValueError::new_err(format!("initial_states[{b}]: {message}")))
        }
        None => {}
    }
    if !stats {
        return Ok(states.into_any());
    }
    let d = PyDict::new(py);
    let shape = [batch, steps];
    let ints = |f: &dyn Fn(&StepRecord) -> &Vec<i64>| {
        PyArray1::from_vec(py, records.iter().flat_map(|r| f(r).iter().copied()).collect()).reshape(shape)
    };
    let floats = |f: &dyn Fn(&StepRecord) -> &Vec<f64>| {
        PyArray1::from_vec(py, records.iter().flat_map(|r| f(r).iter().copied()).collect()).reshape(shape)
    };
    d.set_item("contacts", ints(&|r| &r.contacts)?)?;
    d.set_item("rows", ints(&|r| &r.rows)?)?;
    d.set_item("iterations", ints(&|r| &r.iterations)?)?;
    d.set_item("residual", floats(&|r| &r.residual)?)?;
    d.set_item("max_penetration", floats(&|r| &r.max_penetration)?)?;
    Ok((states, d).into_pyobject(py)?.into_any())
}
