//! `gelenk.Model`, `gelenk.Data`, `gelenk.ModelBuilder` and `gelenk.load_urdf`.

use crate::arrays::{to_py1, vector};
use crate::checks::{self, Allowed};
use crate::errors;
use gelenk::io::urdf::UrdfOptions;
use gelenk::math::{Mat3, Transform, Vec3};
use gelenk::model::{BodySpec, FrameKind, Joint, ModelBuilder, RigidInertia, Suspension};
use gelenk::{Data, Model};
use nalgebra::DVector;
use numpy::PyArray1;
use pyo3::exceptions::{PyIndexError, PyKeyError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rand::SeedableRng;

/// A kinematic tree of rigid bodies (Pinocchio's `Model`): topology, joints, inertias, limits.
/// Immutable. Body 0 is the universe; body i ≥ 1 is carried by joint i; joints are numbered
/// depth-first. Units SI, z up, quaternions (x, y, z, w).
#[pyclass(name = "Model", module = "gelenk", frozen)]
pub struct PyModel {
    pub model: Model,
}

/// The short name of a joint's kind.
pub fn joint_kind(joint: &Joint) -> &'static str {
    match joint {
        Joint::Fixed => "fixed",
        Joint::Hinge { .. } => "hinge",
        Joint::Slider { .. } => "slider",
        Joint::Ball => "ball",
        Joint::Universal { .. } => "universal",
        Joint::Hinge2 { .. } => "hinge2",
        Joint::Free => "free",
        Joint::Planar => "planar",
    }
}

impl PyModel {
    /// The index of a frame given as an index or a name.
    pub fn frame_index(&self, frame: &Bound<'_, PyAny>) -> PyResult<usize> {
        let count = self.model.frames().len();
        if let Ok(index) = frame.extract::<usize>() {
            if index >= count {
                return Err(PyIndexError::new_err(format!("frame {index} is out of range ({count} frames)")));
            }
            return Ok(index);
        }
        match frame.extract::<String>() {
            Ok(name) => self
                .model
                .frame_id(&name)
                .ok_or_else(|| PyKeyError::new_err(format!("no frame named `{name}`"))),
            Err(_) => Err(PyTypeError::new_err("frame: expected an index (int) or a name (str)")),
        }
    }
}

#[pymethods]
impl PyModel {
    /// The model's name (the URDF robot's name).
    #[getter]
    fn name(&self) -> &str {
        self.model.name()
    }
    /// Number of configuration coordinates.
    #[getter]
    fn nq(&self) -> usize {
        self.model.nq()
    }
    /// Number of velocity coordinates (degrees of freedom).
    #[getter]
    fn nv(&self) -> usize {
        self.model.nv()
    }
    /// Number of bodies, the universe (body 0) included.
    #[getter]
    fn nbodies(&self) -> usize {
        self.model.nbodies()
    }
    /// Names of the moving joints, in joint order (joint i carries body i; the universe's
    /// "joint" is left out, so entry k names joint k + 1).
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        (1..self.model.nbodies()).map(|i| self.model.joint_name(i).to_string()).collect()
    }
    /// Names of the bodies, the universe first.
    #[getter]
    fn body_names(&self) -> Vec<String> {
        (0..self.model.nbodies()).map(|i| self.model.body_name(i).to_string()).collect()
    }
    /// Names of the frames (links and joints, fused fixed links included), in frame order.
    #[getter]
    fn frame_names(&self) -> Vec<String> {
        self.model.frames().iter().map(|f| f.name.clone()).collect()
    }
    /// One dict per moving joint: `name`, `type`, `body` (its index), `parent` (parent body
    /// index), `idx_q`, `nq`, `idx_v`, `nv` — where its coordinates sit in q and v.
    #[getter]
    fn joints<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let m = &self.model;
        (1..m.nbodies())
            .map(|i| {
                let d = PyDict::new(py);
                d.set_item("name", m.joint_name(i))?;
                d.set_item("type", joint_kind(m.joint(i)))?;
                d.set_item("body", i)?;
                d.set_item("parent", m.parent(i))?;
                d.set_item("idx_q", m.idx_q(i))?;
                d.set_item("nq", m.joint(i).nq())?;
                d.set_item("idx_v", m.idx_v(i))?;
                d.set_item("nv", m.joint(i).nv())?;
                Ok(d)
            })
            .collect()
    }
    /// Lower position limits (nq entries; −inf where unlimited).
    #[getter]
    fn lower_position_limit<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.model.lower_position_limit().as_slice())
    }
    /// Upper position limits (nq entries; +inf where unlimited).
    #[getter]
    fn upper_position_limit<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.model.upper_position_limit().as_slice())
    }
    /// Velocity limits (nv entries, rad/s or m/s).
    #[getter]
    fn velocity_limit<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.model.velocity_limit().as_slice())
    }
    /// Effort limits (nv entries, N·m or N).
    #[getter]
    fn effort_limit<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.model.effort_limit().as_slice())
    }
    /// Viscous joint damping (nv entries, N·m·s/rad or N·s/m).
    #[getter]
    fn damping<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.model.damping().as_slice())
    }
    /// Coulomb joint friction (nv entries, N·m or N).
    #[getter]
    fn friction<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.model.friction().as_slice())
    }
    /// Gravity in the world frame (m/s²).
    #[getter]
    fn gravity<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.model.gravity().as_slice())
    }
    /// Total mass of the moving bodies (kg).
    #[getter]
    fn mass(&self) -> f64 {
        self.model.total_mass()
    }
    /// The neutral configuration: zero angles and offsets, identity quaternions.
    fn neutral<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.model.neutral_configuration().as_slice())
    }
    /// A random configuration within the position limits (uniform angles where unlimited,
    /// uniformly random unit quaternions), drawn from a generator seeded with `seed` (the same
    /// seed gives the same configuration), or seeded from the clock when `seed` is None.
    #[pyo3(signature = (seed=None))]
    fn random_configuration<'py>(&self, py: Python<'py>, seed: Option<u64>) -> Bound<'py, PyArray1<f64>> {
        let seed = seed.unwrap_or_else(clock_seed);
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        to_py1(py, self.model.random_configuration(&mut rng).as_slice())
    }
    /// Index of the frame called `name`: a body (link) frame before a joint frame of the same
    /// name, unless `kind` is "body" or "joint". KeyError when there is none.
    #[pyo3(signature = (name, kind=None))]
    fn frame_id(&self, name: &str, kind: Option<&str>) -> PyResult<usize> {
        let kind = match kind {
            None => None,
            Some("body") => Some(FrameKind::Body),
            Some("joint") => Some(FrameKind::Joint),
            Some(other) => {
                return Err(PyValueError::new_err(format!(
                    "kind: expected \"body\" or \"joint\", got \"{other}\""
                )))
            }
        };
        let found = match kind {
            None => self.model.frame_id(name),
            Some(kind) => self.model.frames().iter().position(|f| f.name == name && f.kind == kind),
        };
        found.ok_or_else(|| PyKeyError::new_err(format!("no frame named `{name}`")))
    }
    /// Index of the body called `name` (the universe is 0). KeyError when there is none.
    fn body_id(&self, name: &str) -> PyResult<usize> {
        self.model.body_id(name).ok_or_else(|| PyKeyError::new_err(format!("no body named `{name}`")))
    }
    /// Index of the moving joint called `name` (= the index of the body it carries). KeyError
    /// when there is none.
    fn joint_id(&self, name: &str) -> PyResult<usize> {
        self.model.joint_id(name).ok_or_else(|| PyKeyError::new_err(format!("no joint named `{name}`")))
    }
    /// A new `Data` for this model.
    fn create_data(&self) -> PyData {
        PyData::for_model(&self.model)
    }
    fn __repr__(&self) -> String {
        format!(
            "gelenk.Model(name={:?}, nq={}, nv={}, nbodies={})",
            self.model.name(),
            self.model.nq(),
            self.model.nv(),
            self.model.nbodies()
        )
    }
}

/// A seed from the clock, for random draws the caller did not seed.
fn clock_seed() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

/// Every buffer the algorithms write for one model (Pinocchio's `Data`), allocated once. The
/// algorithms take it as their second argument and leave their results in it as well as
/// returning them.
///
/// `Data(model)` (or `model.create_data()`): the buffers for `model`; a Data serves only models
/// of the same sizes (ValueError otherwise).
#[pyclass(name = "Data", module = "gelenk")]
pub struct PyData {
    pub data: Data,
    /// Scratch copies of the inputs q, v and a (or tau), sized once.
    pub q: DVector<f64>,
    pub v: DVector<f64>,
    pub x: DVector<f64>,
    sizes: (usize, usize, usize),
}

impl PyData {
    /// Data for `model`.
    pub fn for_model(model: &Model) -> Self {
        Self {
            data: Data::new(model),
            q: DVector::zeros(model.nq()),
            v: DVector::zeros(model.nv()),
            x: DVector::zeros(model.nv()),
            sizes: (model.nq(), model.nv(), model.nbodies()),
        }
    }

    /// Checks that this data was made for a model of `model`'s sizes.
    pub fn check(&self, model: &Model) -> PyResult<()> {
        let sizes = (model.nq(), model.nv(), model.nbodies());
        if sizes != self.sizes {
            return Err(PyValueError::new_err(format!(
                "data was made for a model with (nq, nv, nbodies) = {:?}, this one has {sizes:?}",
                self.sizes
            )));
        }
        Ok(())
    }
}

#[pymethods]
impl PyData {
    /// The constructor, documented on the class (where `help()` shows it).
    #[new]
    fn new(model: &Bound<'_, PyModel>) -> Self {
        Self::for_model(&model.get().model)
    }
    /// The mass matrix M(q) of the last `crba` or `mass_matrix` (nv × nv, symmetric).
    #[getter]
    fn mass_matrix<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<f64>> {
        crate::arrays::to_py2(py, &self.data.mass_matrix)
    }
    /// The accelerations of the last `aba` (nv).
    #[getter]
    fn ddq<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.data.ddq.as_slice())
    }
    /// The joint forces of the last `rnea` (nv).
    #[getter]
    fn tau<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.data.tau.as_slice())
    }
    /// The nonlinear effects of the last `nonlinear_effects` (nv).
    #[getter]
    fn nle<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.data.nle.as_slice())
    }
    /// The centre of mass of the last `center_of_mass` (m, world).
    #[getter]
    fn com<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_py1(py, self.data.com.as_slice())
    }
    fn __repr__(&self) -> String {
        let (nq, nv, nbodies) = self.sizes;
        format!("gelenk.Data(nq={nq}, nv={nv}, nbodies={nbodies})")
    }
}

/// Loads a URDF file. `floating`: attach the root link by a free joint (7 coordinates, 6
/// dofs) instead of fixing it to the world. `strict`: every loader warning is an error;
/// otherwise warnings (unknown elements, inconsistent inertias, ...) are issued as Python
/// `UserWarning`s. `balance_inertia`: replace inconsistent link inertias by their balanced
/// form (MuJoCo's balanceinertia). Raises FileNotFoundError, ValueError.
#[pyfunction]
#[pyo3(signature = (path, floating=false, strict=false, balance_inertia=false))]
pub fn load_urdf(
    py: Python<'_>,
    path: std::path::PathBuf,
    floating: bool,
    strict: bool,
    balance_inertia: bool,
) -> PyResult<PyModel> {
    let options = UrdfOptions { floating_base: floating, strict, balance_inertia, ..Default::default() };
    let loaded =
        errors::guard(|| gelenk::io::urdf::load_file_with_warnings(&path, &options).map_err(errors::urdf))?;
    for w in &loaded.warnings {
        let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
        let message = std::ffi::CString::new(w.to_string().replace('\0', " ")).expect("no NUL");
        PyErr::warn(py, &category, &message, 1)?;
    }
    Ok(PyModel { model: loaded.model })
}

/// Builds a model body by body (parents may come after their children), as the URDF loader
/// does; `build()` validates it and numbers the joints depth-first.
///
/// `ModelBuilder(name="", gravity=(0, 0, -9.81))`: an empty model called `name` with gravity
/// `gravity` (m/s², world frame).
#[pyclass(name = "ModelBuilder", module = "gelenk")]
pub struct PyModelBuilder {
    builder: ModelBuilder,
}

/// The joint of a `ModelBuilder.add_body` call.
fn joint_of(
    kind: &str,
    axis: Option<[f64; 3]>,
    axis1: Option<[f64; 3]>,
    axis2: Option<[f64; 3]>,
    suspension: Option<(f64, f64)>,
) -> PyResult<Joint> {
    let need = |a: Option<[f64; 3]>, name: &str| {
        a.map(Vec3::from).ok_or_else(|| PyValueError::new_err(format!("a {kind} joint needs `{name}`")))
    };
    Ok(match kind {
        "hinge" | "revolute" | "continuous" => Joint::Hinge { axis: need(axis, "axis")? },
        "slider" | "prismatic" => Joint::Slider { axis: need(axis, "axis")? },
        "ball" | "spherical" => Joint::Ball,
        "free" | "floating" => Joint::Free,
        "planar" => Joint::Planar,
        "fixed" => Joint::Fixed,
        "universal" => Joint::Universal { axis1: need(axis1, "axis1")?, axis2: need(axis2, "axis2")? },
        "hinge2" => Joint::Hinge2 {
            axis1: need(axis1, "axis1")?,
            axis2: need(axis2, "axis2")?,
            suspension: suspension.map(|(stiffness, damping)| Suspension { stiffness, damping }),
        },
        other => {
            return Err(PyValueError::new_err(format!(
                "unknown joint type `{other}` (known: hinge, slider, ball, universal, hinge2, free, planar, fixed)"
            )))
        }
    })
}

#[pymethods]
impl PyModelBuilder {
    /// The constructor, documented on the class (where `help()` shows it).
    #[new]
    #[pyo3(signature = (name="", gravity=[0.0, 0.0, -9.81]))]
    fn new(name: &str, gravity: [f64; 3]) -> PyResult<Self> {
        checks::numbers("gravity", &gravity, Allowed::Finite)?;
        let mut builder = ModelBuilder::new();
        builder.name(name).gravity(Vec3::from(gravity));
        Ok(Self { builder })
    }

    /// Adds body `name` attached to body `parent` ("universe" for the world) by a joint of type
    /// `joint` ("hinge", "slider", "ball", "universal", "hinge2", "free", "planar", "fixed";
    /// hinge and slider take `axis`, universal and hinge2 `axis1`, `axis2`, hinge2 an optional
    /// `suspension` (stiffness N/m, damping N·s/m)). The joint frame sits at `translation` (m)
    /// and `quaternion` (x, y, z, w) in the parent's frame; the body has mass `mass` (kg),
    /// centre of mass `com` (m, body frame) and rotational inertia `inertia` (3×3 about the
    /// centre of mass, body axes, kg·m²). A number that is not finite is a ValueError naming
    /// the argument; everything else is checked by `build()`.
    #[pyo3(signature = (name, parent, joint, *, axis=None, axis1=None, axis2=None, suspension=None,
        translation=[0.0; 3], quaternion=[0.0, 0.0, 0.0, 1.0], mass=0.0, com=[0.0; 3],
        inertia=[[0.0; 3]; 3], joint_name=None))]
    #[allow(clippy::too_many_arguments)]
    fn add_body(
        &mut self,
        name: &str,
        parent: &str,
        joint: &str,
        axis: Option<[f64; 3]>,
        axis1: Option<[f64; 3]>,
        axis2: Option<[f64; 3]>,
        suspension: Option<(f64, f64)>,
        translation: [f64; 3],
        quaternion: [f64; 4],
        mass: f64,
        com: [f64; 3],
        inertia: [[f64; 3]; 3],
        joint_name: Option<&str>,
    ) -> PyResult<()> {
        for (what, values) in [("axis", axis), ("axis1", axis1), ("axis2", axis2)] {
            checks::numbers(what, &values.unwrap_or_default(), Allowed::Finite)?;
        }
        if let Some((stiffness, damping)) = suspension {
            checks::numbers("suspension", &[stiffness, damping], Allowed::NonNegative)?;
        }
        checks::numbers("translation", &translation, Allowed::Finite)?;
        checks::numbers("quaternion", &quaternion, Allowed::Finite)?;
        checks::number("mass", mass, Allowed::Finite)?;
        checks::numbers("com", &com, Allowed::Finite)?;
        for (r, row) in inertia.iter().enumerate() {
            checks::numbers(&format!("inertia[{r}]"), row, Allowed::Finite)?;
        }
        let joint = joint_of(joint, axis, axis1, axis2, suspension)?;
        let norm = quaternion.iter().map(|x| x * x).sum::<f64>().sqrt();
        if !(norm.is_finite() && norm > 1e-9) {
            return Err(PyValueError::new_err(format!("quaternion of `{name}` has norm {norm}")));
        }
        let placement = Transform::from_translation_quaternion(Vec3::from(translation), quaternion);
        let inertia = RigidInertia::new(mass, Vec3::from(com), Mat3::from_fn(|r, c| inertia[r][c]));
        let mut spec = BodySpec::new(name, parent, joint, placement, inertia);
        if let Some(j) = joint_name {
            spec = spec.with_joint_name(j);
        }
        self.builder.add_body(spec);
        Ok(())
    }

    /// Validates every body and joint and returns the model (ValueError naming the body or
    /// joint at fault).
    fn build(&self) -> PyResult<PyModel> {
        errors::guard(|| self.builder.build().map(|model| PyModel { model }).map_err(errors::model))
    }
}

/// `q ⊕ v·dt`: the configuration reached from `q` moving at `v` for `dt` seconds, joint by
/// joint on the configuration manifold (quaternions stay unit).
#[pyfunction]
#[pyo3(signature = (model, q, v, dt=1.0))]
pub fn integrate<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyModel>,
    q: &Bound<'py, PyAny>,
    v: &Bound<'py, PyAny>,
    dt: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let m = &model.get().model;
    checks::number("dt", dt, Allowed::Finite)?;
    let (q, v) = (vector(q, "q", m.nq())?, vector(v, "v", m.nv())?);
    checks::numbers("q", q.as_slice(), Allowed::Finite)?;
    checks::numbers("v", v.as_slice(), Allowed::Finite)?;
    m.check_quaternions(q.as_slice()).map_err(errors::dynamics)?;
    let mut out = q.clone();
    errors::guard(|| {
        m.integrate(&q, &v, dt, &mut out);
        Ok(())
    })?;
    Ok(to_py1(py, out.as_slice()))
}

/// `q1 ⊖ q0`: the velocity that `integrate` turns `q0` into `q1` with in unit time.
#[pyfunction]
pub fn difference<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyModel>,
    q0: &Bound<'py, PyAny>,
    q1: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let m = &model.get().model;
    let (q0, q1) = (vector(q0, "q0", m.nq())?, vector(q1, "q1", m.nq())?);
    checks::numbers("q0", q0.as_slice(), Allowed::Finite)?;
    checks::numbers("q1", q1.as_slice(), Allowed::Finite)?;
    m.check_quaternions(q0.as_slice()).map_err(errors::dynamics)?;
    m.check_quaternions(q1.as_slice()).map_err(errors::dynamics)?;
    let mut out = DVector::zeros(m.nv());
    errors::guard(|| {
        m.difference(&q0, &q1, &mut out);
        Ok(())
    })?;
    Ok(to_py1(py, out.as_slice()))
}
