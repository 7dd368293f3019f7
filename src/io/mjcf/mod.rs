//! MuJoCo MJCF scenes: the subset of MJCF that gelenk's comparisons with MuJoCo use, loaded into a
//! [`Model`] plus the static world geometry and the simulation options ([`MjcfScene`]).
//!
//! ## What is read
//! - `<compiler angle eulerseq inertiafromgeom autolimits settotalmass>`;
//! - `<option timestep gravity cone>` and its `<flag gravity contact>`;
//! - `<default>` classes, nested, with their `<joint>` and `<geom>` defaults; `class` on joints
//!   and geoms, `childclass` on bodies and frames;
//! - `<worldbody>` with nested `<body name pos quat|axisangle|euler|xyaxes|zaxis>`, `<frame>`,
//!   `<inertial pos quat… mass diaginertia|fullinertia>`,
//!   `<joint type=hinge|slide|ball|free name pos axis range limited damping frictionloss armature>`,
//!   `<freejoint>` and `<geom type=plane|sphere|capsule|cylinder|box name size fromto pos quat…
//!   density mass friction contype conaffinity>`;
//! - `<contact><exclude body1 body2/>`, recorded in [`MjcfScene::contact_excludes`].
//!
//! Every attribute of those elements is checked against MuJoCo 4.0's schema: one MuJoCo does not
//! know (a misspelling) is an [`MjcfError::InvalidAttribute`]; names, looks, MuJoCo's solver
//! settings and constraint softness (`solref`, `solimp`, `margin` of joints) are read past; one
//! that changes the dynamics in a way gelenk cannot represent (`condim` other than 3, geom
//! `margin`, `gap`, `priority`, `adhesion`, `surfacevel`, `shellinertia`, joint `springdamper`,
//! fluid `density` and `viscosity`, the flags `constraint`, `limit`, `frictionloss`, `damper`,
//! `filterparent` disabled or `override` enabled, …) is [`MjcfError::Unsupported`] unless it has
//! MuJoCo's default value.
//!
//! `<actuator>`, `<sensor>`, `<visual>`, `<asset>`, `<keyframe>`, `<statistic>`, `<size>`,
//! `<custom>`, sites, cameras and lights are ignored. What would change the dynamics or contacts
//! and cannot be represented is an [`MjcfError::Unsupported`] naming the element: mesh, height
//! field, ellipsoid and SDF geoms, tendons, equality constraints, contact pairs, flexes, joint
//! springs (`stiffness`) and reference positions (`ref`), mocap bodies, gravity compensation,
//! `<include>`.
//!
//! ## Mapping
//! - Bodies and joints keep MuJoCo's order (depth-first in document order, joints in body order),
//!   which is also gelenk's, so q and v index the same joints as MuJoCo's qpos and qvel (up to
//!   the quaternion and free-joint velocity conventions, see [`q_from_mujoco`] and
//!   [`v_from_mujoco`]).
//! - A body with one joint becomes a model body named like it. A body with several joints
//!   becomes a chain: each joint but the last carries a massless body named `body__joint`, the
//!   last carries the body itself, all in MJCF order. A joint's `pos` places its frame (the axis
//!   passes through it); the body frame stays where MJCF puts it, so when the last joint has a
//!   `pos` the model body's frame is the joint's and [`MjcfBody::placement`] gives the MJCF body
//!   frame in it.
//! - A body without joints is welded to its parent (fused by the model builder). Geoms of the
//!   world body and of bodies welded to it are [`StaticGeometry`]; planes become half-spaces.
//! - A free joint (allowed in bodies whose parent is the world or welded to it) is a child of the
//!   universe whose joint frame is the world frame: q is the body's world pose, as MuJoCo's qpos.
//! - Mass properties come from the geoms exactly as MuJoCo computes them (density 1000 kg/m³
//!   unless `density` or `mass` says otherwise), or from `<inertial>` (`inertiafromgeom`).
//! - Joint damping and `frictionloss` become [`JointDynamics`](crate::model::JointDynamics); hinge and slide ranges become
//!   [`JointLimits`](crate::model::JointLimits) when limited (`limited="auto"` means "when a range is given"); angles are in
//!   degrees unless `<compiler angle="radian">`. A limited ball joint's range (`0 θ`, MuJoCo's
//!   bound on the total rotation angle) becomes [`BallLimits::total_angle`](crate::model::BallLimits::total_angle).
//!   Armature is not modelled by gelenk: it is recorded in [`MjcfScene::joint_armature`].
//! - Unnamed elements get names: `body{id}` (id as MuJoCo counts bodies, world = 0),
//!   `{body}_joint` (or `{body}_joint{k}` when the body has several), `{body}_geom{k}`, and
//!   `world_geom{k}` for world geoms.
//!
//! ```
//! let scene = gelenk::io::mjcf::load_str(
//!     r#"<mujoco><worldbody>
//!          <geom type="plane" size="1 1 0.1"/>
//!          <body name="ball" pos="0 0 1"><freejoint/><geom type="sphere" size="0.1"/></body>
//!        </worldbody></mujoco>"#,
//! ).unwrap();
//! assert_eq!((scene.model.nq(), scene.model.nv()), (7, 6));
//! assert_eq!(scene.statics.len(), 1);
//! let mass = 1000.0 * 4.0 / 3.0 * std::f64::consts::PI * 0.1f64.powi(3);
//! assert!((scene.model.total_mass() - mass).abs() < 1e-12);
//! assert_eq!(scene.q0[2], 1.0); // MuJoCo's qpos0: the body's pose
//! ```
//!
//! Private modules: `loader` reads the document (sections, defaults, attribute values) and
//! converts its elements into model bodies (`loader::convert`), checking every attribute against
//! MuJoCo's schema (`schema`); `coordinates` converts states between MuJoCo's conventions and
//! gelenk's ([`q_from_mujoco`] and its kin); `world` puts a loaded scene into a
//! [`crate::world::World`] ([`MjcfScene::into_world`]).

mod coordinates;
mod loader;
mod schema;
mod world;

pub use coordinates::{q_from_mujoco, q_to_mujoco, v_from_mujoco, v_to_mujoco};

use crate::constraints::FrictionModel;
use crate::error::MjcfError;
use crate::io::limits::ReadLimits;
use crate::math::{Transform, Vec3};
use crate::model::{Model, Shape};
use nalgebra::DVector;
use std::path::Path;

/// Geometry fixed in the world: geoms of `<worldbody>` and of bodies welded to it.
#[derive(Clone, Debug, PartialEq)]
pub struct StaticGeometry {
    /// The geom's name (or the generated one).
    pub name: String,
    /// The shape; an MJCF plane is [`Shape::HalfSpace`] with normal +z of the geom frame.
    pub shape: Shape,
    /// Pose of the shape frame in the world.
    pub pose: Transform,
    /// MuJoCo friction coefficients: sliding, torsional, rolling.
    pub friction: [f64; 3],
    /// False when `contype` and `conaffinity` are both 0 (the geom never collides in MuJoCo).
    pub collides: bool,
}

/// What gelenk's [`crate::model::GeometrySpec`] does not hold about a body geom.
#[derive(Clone, Debug, PartialEq)]
pub struct GeomInfo {
    /// The geom's name (or the generated one).
    pub name: String,
    /// MuJoCo friction coefficients: sliding, torsional, rolling.
    pub friction: [f64; 3],
}

/// Where an MJCF body ended up in the model.
#[derive(Clone, Debug, PartialEq)]
pub struct MjcfBody {
    /// The MJCF body's name (or the generated one).
    pub name: String,
    /// The model body it moves with (0 = universe, for bodies welded to the world).
    pub body: usize,
    /// Pose of the MJCF body frame in that model body's frame (identity unless the body is welded
    /// to another one or its last joint has a `pos`).
    pub placement: Transform,
}

/// An MJCF scene: the multibody model, the static world, and MuJoCo's options.
#[derive(Clone, Debug)]
pub struct MjcfScene {
    /// The bodies and joints (name from `<mujoco model>`, gravity from `<option>`). Body
    /// geoms are attached as collision shapes, or as visual shapes when `contype` and
    /// `conaffinity` are both 0.
    pub model: Model,
    /// Geoms fixed in the world.
    pub statics: Vec<StaticGeometry>,
    /// `<option timestep>` (s), default 0.002.
    pub timestep: f64,
    /// `<option gravity>` (m/s², world frame), default (0, 0, −9.81); zero when
    /// `<flag gravity="disable">`. Also set on [`MjcfScene::model`].
    pub gravity: Vec3,
    /// False when `<flag contact="disable">`.
    pub contact_enabled: bool,
    /// `<option cone>`: MuJoCo's default `pyramidal` is gelenk's 4-facet pyramid (the same set:
    /// `|λ₁| + |λ₂| ≤ μ λ_n`), `elliptic` the Coulomb cone.
    pub friction: FrictionModel,
    /// Damping of every joint (N·m·s/rad or N·s/m), in model joint order.
    pub joint_damping: Vec<(String, f64)>,
    /// Armature of every joint (kg·m² or kg), in model joint order. gelenk does not model armature
    /// (rotor inertia added to the mass matrix diagonal); it is kept here for reference.
    pub joint_armature: Vec<(String, f64)>,
    /// Name and friction of every body geom, parallel to `model.geometries()`.
    pub geoms: Vec<GeomInfo>,
    /// Every MJCF body, in document order.
    pub bodies: Vec<MjcfBody>,
    /// Pairs of bodies excluded from contact by `<contact><exclude>`.
    pub contact_excludes: Vec<(String, String)>,
    /// MuJoCo's initial configuration `qpos0` in gelenk's conventions: free joints at their
    /// body's pose, everything else neutral.
    pub q0: DVector<f64>,
}

/// Loads an MJCF file within the default [`ReadLimits`].
pub fn load_file(path: impl AsRef<Path>) -> Result<MjcfScene, MjcfError> {
    load_file_with_limits(path, &ReadLimits::default())
}

/// Loads an MJCF file, refusing one larger or more deeply nested than `limits`.
pub fn load_file_with_limits(path: impl AsRef<Path>, limits: &ReadLimits) -> Result<MjcfScene, MjcfError> {
    let path = path.as_ref();
    let file = path.display().to_string();
    let text = limits.read_text_io(path).map_err(|source| MjcfError::Io { file: file.clone(), source })?;
    let mut scene = loader::load_named(&text, &file, limits)?;
    scene.model.set_source_dir(Some(path.parent().map(Path::to_path_buf).unwrap_or_default()));
    Ok(scene)
}

/// Loads an MJCF document from text within the default [`ReadLimits`].
pub fn load_str(text: &str) -> Result<MjcfScene, MjcfError> {
    loader::load_named(text, "<string>", &ReadLimits::default())
}
