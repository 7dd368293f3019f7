//! The Python extension module `gelenk._gelenk` (re-exported by the package `gelenk`): models
//! and the dynamics algorithms on numpy arrays, worlds and their stepping, batched rollouts on
//! every core, and the constraint-problem files. Each file binds one part of the library:
//!
//! | file | binds |
//! |---|---|
//! | `model.rs` | `Model`, `Data`, `ModelBuilder`, `load_urdf`, `integrate`, `difference` |
//! | `algorithms.rs` | `rnea`, `aba`, `crba`, `mass_matrix`, `nonlinear_effects`, `generalized_gravity`, kinematics, frames, Jacobians, energies |
//! | `world.rs` (with `sim.rs`) | `World`, `load_scene`, `load_mjcf` |
//! | `contacts.rs` | contacts and constraint problems as arrays, `export_problems`, `read_problem` |
//! | `rollout.rs` | `rollout` |
//! | `errors.rs`, `arrays.rs`, `checks.rs` | exceptions, numpy conversions, the check of float arguments |

mod algorithms;
mod arrays;
mod checks;
mod contacts;
mod errors;
mod model;
mod rollout;
mod sim;
mod world;

use pyo3::prelude::*;

/// gelenk: constraint-based Lagrangian multibody dynamics in generalized coordinates.
/// The module needs the GIL (`gil_used = true`): the dynamics functions read their input arrays
/// in place while holding it (see `arrays::read_into`).
#[pymodule(gil_used = true)]
fn _gelenk(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("StepError", py.get_type::<errors::StepError>())?;
    m.add_class::<model::PyModel>()?;
    m.add_class::<model::PyData>()?;
    m.add_class::<model::PyModelBuilder>()?;
    m.add_class::<world::PyWorld>()?;
    m.add_function(wrap_pyfunction!(model::load_urdf, m)?)?;
    m.add_function(wrap_pyfunction!(model::integrate, m)?)?;
    m.add_function(wrap_pyfunction!(model::difference, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::rnea, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::aba, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::crba, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::mass_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::nonlinear_effects, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::generalized_gravity, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::forward_kinematics, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::frame_placement, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::frame_pose, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::frame_jacobian, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::kinetic_energy, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::potential_energy, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::center_of_mass, m)?)?;
    m.add_function(wrap_pyfunction!(algorithms::_aba_loop, m)?)?;
    m.add_function(wrap_pyfunction!(world::load_scene, m)?)?;
    m.add_function(wrap_pyfunction!(world::load_mjcf, m)?)?;
    m.add_function(wrap_pyfunction!(contacts::export_problems, m)?)?;
    m.add_function(wrap_pyfunction!(contacts::read_problem, m)?)?;
    m.add_function(wrap_pyfunction!(rollout::rollout, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
