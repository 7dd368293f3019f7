//! A world's contacts and constraint problems as dicts of numpy arrays, and problem files read
//! back (`gelenk._gelenk.read_problem`, used by `gelenk.problems`).

use crate::arrays::{rows_to_py2, to_py1, to_py2};
use crate::errors;
use gelenk::collision::Attachment;
use gelenk::constraints::{ConstraintProblem, FrictionModel, RowLaw, RowOrigin};
use gelenk::world::World;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// (multibody, body) of a collider's attachment; (−1, −1) for static world geometry.
fn attachment(a: Attachment) -> (i64, i64) {
    match a {
        Attachment::World => (-1, -1),
        Attachment::Body { multibody, body } => (multibody as i64, body as i64),
    }
}

/// The contacts of the world's last step (see `World.contacts`).
pub fn contacts_dict<'py>(py: Python<'py>, world: &World) -> PyResult<Bound<'py, PyDict>> {
    let contacts = world.contacts();
    let (problem, lambda) = (world.problem(), world.impulses());
    let k = contacts.len();
    // Each contact's three impulses, from the rows whose origin it is.
    let mut impulse = vec![0.0; 3 * k];
    if lambda.len() == problem.rows() {
        for block in &problem.contacts {
            if let RowOrigin::Contact(c) = problem.origins[block.normal] {
                if c < k {
                    for r in 0..3 {
                        impulse[3 * c + r] = lambda[block.normal + r];
                    }
                }
            }
        }
    }
    let colliders = world.collision().colliders();
    let flat = |f: &dyn Fn(&gelenk::collision::Contact) -> [f64; 3]| {
        rows_to_py2(py, contacts.iter().flat_map(f).collect(), 3)
    };
    let d = PyDict::new(py);
    d.set_item("point_a", flat(&|c| c.point_a.into()))?;
    d.set_item("point_b", flat(&|c| c.point_b.into()))?;
    d.set_item("normal", flat(&|c| c.normal.into()))?;
    let distance: Vec<f64> = contacts.iter().map(|c| c.distance).collect();
    let depth: Vec<f64> = distance.iter().map(|x| (-x).max(0.0)).collect();
    d.set_item("distance", PyArray1::from_vec(py, distance))?;
    d.set_item("depth", PyArray1::from_vec(py, depth))?;
    d.set_item("impulse", rows_to_py2(py, impulse, 3))?;
    let a: Vec<(i64, i64)> = contacts.iter().map(|c| attachment(c.body_a)).collect();
    let b: Vec<(i64, i64)> = contacts.iter().map(|c| attachment(c.body_b)).collect();
    d.set_item("multibody_a", PyArray1::from_vec(py, a.iter().map(|x| x.0).collect()))?;
    d.set_item("body_a", PyArray1::from_vec(py, a.iter().map(|x| x.1).collect()))?;
    d.set_item("multibody_b", PyArray1::from_vec(py, b.iter().map(|x| x.0).collect()))?;
    d.set_item("body_b", PyArray1::from_vec(py, b.iter().map(|x| x.1).collect()))?;
    let name = |i: usize| colliders.get(i).map(|c| c.name().to_string()).unwrap_or_default();
    d.set_item("collider_a", contacts.iter().map(|c| name(c.collider_a)).collect::<Vec<_>>())?;
    d.set_item("collider_b", contacts.iter().map(|c| name(c.collider_b)).collect::<Vec<_>>())?;
    Ok(d)
}

/// The name of a friction model as the command line spells it.
fn friction_name(friction: FrictionModel) -> String {
    match friction {
        FrictionModel::Cone => "cone".to_string(),
        FrictionModel::Pyramid { facets } => format!("pyramid{facets}"),
    }
}

/// A constraint problem `w = (A + R) λ + b` as a dict (see `World.problem`).
pub fn problem_dict<'py>(py: Python<'py>, problem: &ConstraintProblem) -> PyResult<Bound<'py, PyDict>> {
    let n = problem.rows();
    let d = PyDict::new(py);
    d.set_item("A", to_py2(py, &problem.delassus_dense()))?;
    d.set_item("R", to_py1(py, problem.regularization.as_slice()))?;
    d.set_item("b", to_py1(py, problem.bias.as_slice()))?;
    d.set_item("target", to_py1(py, problem.target.as_slice()))?;
    if problem.jacobian.nrows() == n && n > 0 {
        d.set_item("J", to_py2(py, &problem.jacobian))?;
    }
    let (mut lo, mut hi) = (vec![f64::NEG_INFINITY; n], vec![f64::INFINITY; n]);
    let mut laws = Vec::with_capacity(n);
    for (i, law) in problem.laws.iter().enumerate() {
        laws.push(match law {
            RowLaw::Bilateral => "bilateral",
            RowLaw::Unilateral => {
                lo[i] = 0.0;
                "unilateral"
            }
            RowLaw::Bounded { lo: l, hi: h } => {
                (lo[i], hi[i]) = (*l, *h);
                "bounded"
            }
            RowLaw::Friction { .. } => "friction",
        });
    }
    d.set_item("laws", laws)?;
    d.set_item("lo", PyArray1::from_vec(py, lo))?;
    d.set_item("hi", PyArray1::from_vec(py, hi))?;
    let contacts = &problem.contacts;
    d.set_item("normal_rows", PyArray1::from_vec(py, contacts.iter().map(|c| c.normal as i64).collect()))?;
    d.set_item("mu", PyArray1::from_vec(py, contacts.iter().map(|c| c.mu).collect()))?;
    d.set_item("mu2", PyArray1::from_vec(py, contacts.iter().map(|c| c.mu2).collect()))?;
    d.set_item("friction", friction_name(problem.friction))?;
    Ok(d)
}

/// Reads `problem.json` (a file, or a directory holding one) into the dict of `World.problem`
/// (`A`, `R`, `b`, `target`, `J`, `laws`, `lo`, `hi`, `normal_rows`, `mu`, `mu2`,
/// `friction`). Raises FileNotFoundError, ValueError (naming the file).
#[pyfunction]
pub fn read_problem<'py>(py: Python<'py>, path: std::path::PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let problem = errors::guard(|| gelenk::io::problem::read_problem(&path).map_err(errors::problem_file))?;
    problem_dict(py, &problem)
}

/// Steps a scene and writes the constraint problem of each step that has rows into
/// `out/step-NNNN/` (problem.json, cone.json, lcp.npz, qp.npz for QPs, meta.json), as `gelenk
/// export-problems` does. `scene`: a built-in scene's name, a scene file (.toml) or an MJCF file
/// (.xml); `friction`: "cone", "pyramid" or "pyramidN"; `only`: the steps to write (default:
/// every step with rows). Returns the number of problems written.
#[pyfunction]
#[pyo3(signature = (scene, out, steps, friction="cone", only=None))]
pub fn export_problems(
    py: Python<'_>,
    scene: &str,
    out: std::path::PathBuf,
    steps: usize,
    friction: &str,
    only: Option<Vec<usize>>,
) -> PyResult<usize> {
    let friction = gelenk::io::scene::parse_friction(friction)
        .map_err(|e| pyo3::exceptions::PyValueError::new_err(format!("friction: {e}")))?;
    let options = gelenk::io::problem::ExportOptions { steps, friction, only: only.unwrap_or_default() };
    py.detach(|| {
        errors::guard(|| {
            gelenk::io::problem::export_problems(scene, &out, &options, |_| {}).map_err(errors::export)
        })
    })
}
