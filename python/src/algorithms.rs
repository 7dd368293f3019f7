//! The dynamics algorithms as Pinocchio-style functions `f(model, data, q, ...)`: the inputs are
//! read in place from float64 arrays into `data`'s scratch vectors (no allocation), the result
//! is returned as a new array and also left in `data`.

use crate::arrays::{homogeneous, pose7, read_into, to_py1, to_py2};
use crate::errors;
use crate::model::{PyData, PyModel};
use gelenk::algorithms::{self as alg, JacobianFrame};
use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// Reads q (and v, and the third vector x) of `model` into `data`'s scratch vectors.
fn inputs(
    model: &gelenk::Model,
    data: &mut PyData,
    q: &Bound<'_, PyAny>,
    v: Option<(&Bound<'_, PyAny>, &str)>,
    x: Option<(&Bound<'_, PyAny>, &str)>,
) -> PyResult<()> {
    data.check(model)?;
    read_into(q, "q", model.nq(), &mut data.q)?;
    if let Some((v, name)) = v {
        read_into(v, name, model.nv(), &mut data.v)?;
    }
    if let Some((x, name)) = x {
        read_into(x, name, model.nv(), &mut data.x)?;
    }
    Ok(())
}

/// Inverse dynamics (RNEA): the joint forces τ = M(q) a + C(q, v) v + g(q) (N·m or N) that give
/// accelerations `a`.
#[pyfunction]
pub fn rnea<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyModel>,
    mut data: PyRefMut<'py, PyData>,
    q: &Bound<'py, PyAny>,
    v: &Bound<'py, PyAny>,
    a: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let m = &model.get().model;
    let d = &mut *data;
    inputs(m, d, q, Some((v, "v")), Some((a, "a")))?;
    errors::guard(|| {
        let tau = alg::rnea(m, &mut d.data, &d.q, &d.v, &d.x).map_err(errors::dynamics)?;
        Ok(to_py1(py, tau.as_slice()))
    })
}

/// Forward dynamics (articulated-body algorithm): the accelerations q̈ = M(q)⁻¹ (τ − C(q, v) v −
/// g(q)) under joint forces `tau`. ValueError for a singular mass matrix (a massless subtree).
#[pyfunction]
pub fn aba<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyModel>,
    mut data: PyRefMut<'py, PyData>,
    q: &Bound<'py, PyAny>,
    v: &Bound<'py, PyAny>,
    tau: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let m = &model.get().model;
    let d = &mut *data;
    inputs(m, d, q, Some((v, "v")), Some((tau, "tau")))?;
    errors::guard(|| {
        let ddq = alg::aba(m, &mut d.data, &d.q, &d.v, &d.x).map_err(errors::dynamics)?;
        Ok(to_py1(py, ddq.as_slice()))
    })
}

/// The joint-space mass matrix M(q) (composite rigid-body algorithm), nv × nv, symmetric.
#[pyfunction]
pub fn crba<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyModel>,
    mut data: PyRefMut<'py, PyData>,
    q: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let m = &model.get().model;
    let d = &mut *data;
    inputs(m, d, q, None, None)?;
    errors::guard(|| {
        let mass = alg::crba(m, &mut d.data, &d.q).map_err(errors::dynamics)?;
        Ok(to_py2(py, mass))
    })
}

/// The joint-space mass matrix M(q) alone, nv × nv, symmetric: the same M as `crba`, computed
/// in body frames without the world poses and Jacobian columns that `crba` also leaves in `data`.
#[pyfunction]
pub fn mass_matrix<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyModel>,
    mut data: PyRefMut<'py, PyData>,
    q: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let m = &model.get().model;
    let d = &mut *data;
    inputs(m, d, q, None, None)?;
    errors::guard(|| {
        let mass = alg::mass_matrix(m, &mut d.data, &d.q).map_err(errors::dynamics)?;
        Ok(to_py2(py, mass))
    })
}

/// The nonlinear effects C(q, v) v + g(q) = rnea(q, v, 0).
#[pyfunction]
pub fn nonlinear_effects<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyModel>,
    mut data: PyRefMut<'py, PyData>,
    q: &Bound<'py, PyAny>,
    v: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let m = &model.get().model;
    let d = &mut *data;
    inputs(m, d, q, Some((v, "v")), None)?;
    errors::guard(|| {
        let nle = alg::nonlinear_effects(m, &mut d.data, &d.q, &d.v).map_err(errors::dynamics)?;
        Ok(to_py1(py, nle.as_slice()))
    })
}

/// The generalized gravity g(q) = rnea(q, 0, 0).
#[pyfunction]
pub fn generalized_gravity<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyModel>,
    mut data: PyRefMut<'py, PyData>,
    q: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let m = &model.get().model;
    let d = &mut *data;
    inputs(m, d, q, None, None)?;
    errors::guard(|| {
        let g = alg::generalized_gravity(m, &mut d.data, &d.q).map_err(errors::dynamics)?;
        Ok(to_py1(py, g.as_slice()))
    })
}

/// Forward kinematics: every body's pose in the world at `q`, kept in `data` for
/// `frame_placement` and `frame_pose`.
#[pyfunction]
pub fn forward_kinematics<'py>(
    model: &Bound<'py, PyModel>,
    mut data: PyRefMut<'py, PyData>,
    q: &Bound<'py, PyAny>,
) -> PyResult<()> {
    let m = &model.get().model;
    let d = &mut *data;
    inputs(m, d, q, None, None)?;
    errors::guard(|| alg::forward_kinematics(m, &mut d.data, &d.q).map_err(errors::dynamics))
}

/// The pose of frame `frame` (an index or a name) in the world, from the last
/// `forward_kinematics`, as a 4×4 homogeneous matrix `[R t; 0 1]`.
#[pyfunction]
pub fn frame_placement<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyModel>,
    data: PyRef<'py, PyData>,
    frame: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let pm = model.get();
    data.check(&pm.model)?;
    let f = pm.frame_index(frame)?;
    let x = alg::frame_placement(&pm.model, &data.data, f).map_err(errors::dynamics)?;
    Ok(homogeneous(py, &x))
}

/// The pose of frame `frame` (an index or a name) in the world, from the last
/// `forward_kinematics`, as 7 numbers: position (m), then the unit quaternion (x, y, z, w) —
/// the layout of a free joint's q.
#[pyfunction]
pub fn frame_pose<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyModel>,
    data: PyRef<'py, PyData>,
    frame: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let pm = model.get();
    data.check(&pm.model)?;
    let f = pm.frame_index(frame)?;
    let x = alg::frame_placement(&pm.model, &data.data, f).map_err(errors::dynamics)?;
    Ok(to_py1(py, &pose7(&x)))
}

/// The 6 × nv Jacobian of frame `frame` (an index or a name) at `q`, linear rows first, so that
/// `J @ v` is the frame's velocity `[v; ω]` expressed as `reference` says: "local" (the frame's
/// own axes, its origin's velocity), "local_world_aligned" (world axes, its origin's velocity)
/// or "world" (world axes, about the world origin) — Pinocchio's LOCAL, LOCAL_WORLD_ALIGNED and
/// WORLD.
#[pyfunction]
#[pyo3(signature = (model, data, q, frame, reference="local"))]
pub fn frame_jacobian<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyModel>,
    mut data: PyRefMut<'py, PyData>,
    q: &Bound<'py, PyAny>,
    frame: &Bound<'py, PyAny>,
    reference: &str,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let pm = model.get();
    let m = &pm.model;
    let expressed_in = match reference {
        "local" => JacobianFrame::Local,
        "local_world_aligned" => JacobianFrame::LocalWorldAligned,
        "world" => JacobianFrame::World,
        other => {
            return Err(PyValueError::new_err(format!(
                "reference: expected \"local\", \"local_world_aligned\" or \"world\", got \"{other}\""
            )))
        }
    };
    let f = pm.frame_index(frame)?;
    let d = &mut *data;
    inputs(m, d, q, None, None)?;
    errors::guard(|| {
        alg::compute_joint_jacobians(m, &mut d.data, &d.q).map_err(errors::dynamics)?;
        let j = alg::frame_jacobian(m, &mut d.data, f, expressed_in).map_err(errors::dynamics)?;
        Ok(to_py2(py, j))
    })
}

/// Kinetic energy at (q, v) (J).
#[pyfunction]
pub fn kinetic_energy<'py>(
    model: &Bound<'py, PyModel>,
    mut data: PyRefMut<'py, PyData>,
    q: &Bound<'py, PyAny>,
    v: &Bound<'py, PyAny>,
) -> PyResult<f64> {
    let m = &model.get().model;
    let d = &mut *data;
    inputs(m, d, q, Some((v, "v")), None)?;
    errors::guard(|| alg::kinetic_energy(m, &mut d.data, &d.q, &d.v).map_err(errors::dynamics))
}

/// Potential energy in gravity at q (J), zero when every centre of mass is at the world
/// origin's height.
#[pyfunction]
pub fn potential_energy<'py>(
    model: &Bound<'py, PyModel>,
    mut data: PyRefMut<'py, PyData>,
    q: &Bound<'py, PyAny>,
) -> PyResult<f64> {
    let m = &model.get().model;
    let d = &mut *data;
    inputs(m, d, q, None, None)?;
    errors::guard(|| alg::potential_energy(m, &mut d.data, &d.q).map_err(errors::dynamics))
}

/// Centre of mass of the moving bodies at q (m, world frame).
#[pyfunction]
pub fn center_of_mass<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyModel>,
    mut data: PyRefMut<'py, PyData>,
    q: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let m = &model.get().model;
    let d = &mut *data;
    inputs(m, d, q, None, None)?;
    errors::guard(|| {
        let c = alg::center_of_mass(m, &mut d.data, &d.q).map_err(errors::dynamics)?;
        Ok(to_py1(py, c.as_slice()))
    })
}

/// Benchmark helper (not part of the API): `calls` Rust calls of `aba(model, data, q, v, tau)`
/// in a loop on the same inputs, so that a benchmark can time the Rust call with the clock it
/// times `gelenk.aba` with, in the same process (python/benches/bench.py).
#[pyfunction]
pub fn _aba_loop<'py>(
    model: &Bound<'py, PyModel>,
    mut data: PyRefMut<'py, PyData>,
    q: &Bound<'py, PyAny>,
    v: &Bound<'py, PyAny>,
    tau: &Bound<'py, PyAny>,
    calls: usize,
) -> PyResult<()> {
    let m = &model.get().model;
    let d = &mut *data;
    inputs(m, d, q, Some((v, "v")), Some((tau, "tau")))?;
    errors::guard(|| {
        for _ in 0..calls {
            std::hint::black_box(alg::aba(m, &mut d.data, &d.q, &d.v, &d.x).map_err(errors::dynamics)?);
        }
        Ok(())
    })
}
