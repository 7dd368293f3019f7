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
//! - Joint damping and `frictionloss` become [`JointDynamics`]; hinge and slide ranges become
//!   [`JointLimits`] when limited (`limited="auto"` means "when a range is given"); angles are in
//!   degrees unless `<compiler angle="radian">`. Ball-joint ranges (a cone) are ignored.
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

use crate::constraints::FrictionModel;
use crate::error::{DynamicsError, MjcfError, ModelError};
use crate::math::{Mat3, Transform, Vec3};
use crate::model::{
    BodySpec, FrameKind, GeometryRole, GeometrySpec, Joint, JointDynamics, JointLimits, Model, ModelBuilder,
    RigidInertia, Shape,
};
use nalgebra::{DVector, Quaternion, UnitQuaternion};
use roxmltree::{Node, NodeId};
use std::collections::HashMap;
use std::f64::consts::PI;
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

/// What gelenk's [`GeometrySpec`] does not hold about a body geom.
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

/// Loads an MJCF file.
pub fn load_file(path: impl AsRef<Path>) -> Result<MjcfScene, MjcfError> {
    let path = path.as_ref();
    let file = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|source| MjcfError::Io { file: file.clone(), source })?;
    let mut scene = load_named(&text, &file)?;
    scene.model.set_source_dir(Some(path.parent().map(Path::to_path_buf).unwrap_or_default()));
    Ok(scene)
}

/// Loads an MJCF document from text.
pub fn load_str(text: &str) -> Result<MjcfScene, MjcfError> {
    load_named(text, "<string>")
}

/// Converts MuJoCo's `qpos` to gelenk's q for a model loaded from MJCF (same joint order):
/// quaternions go from (w, x, y, z) to (x, y, z, w).
pub fn q_from_mujoco(model: &Model, qpos: &[f64]) -> Result<DVector<f64>, DynamicsError> {
    check_len("qpos", model.nq(), qpos.len())?;
    let mut q = DVector::from_column_slice(qpos);
    for i in 1..model.nbodies() {
        let a = model.idx_q(i);
        match model.joint(i) {
            Joint::Free => q.as_mut_slice()[a + 3..a + 7].rotate_left(1),
            Joint::Ball => q.as_mut_slice()[a..a + 4].rotate_left(1),
            _ => {}
        }
    }
    Ok(q)
}

/// Converts gelenk's q to MuJoCo's `qpos` (the inverse of [`q_from_mujoco`]).
pub fn q_to_mujoco(model: &Model, q: &DVector<f64>) -> Result<DVector<f64>, DynamicsError> {
    check_len("q", model.nq(), q.len())?;
    let mut qpos = q.clone();
    for i in 1..model.nbodies() {
        let a = model.idx_q(i);
        match model.joint(i) {
            Joint::Free => qpos.as_mut_slice()[a + 3..a + 7].rotate_right(1),
            Joint::Ball => qpos.as_mut_slice()[a..a + 4].rotate_right(1),
            _ => {}
        }
    }
    Ok(qpos)
}

/// Converts MuJoCo's `qvel` to gelenk's v at configuration `q` (gelenk's): a free joint's linear
/// velocity is in world axes in MuJoCo and in body axes in gelenk (`v = Rᵀ v_mujoco`); angular
/// velocities are in body axes in both. Other joints are the same.
pub fn v_from_mujoco(model: &Model, q: &DVector<f64>, qvel: &[f64]) -> Result<DVector<f64>, DynamicsError> {
    check_len("q", model.nq(), q.len())?;
    check_len("qvel", model.nv(), qvel.len())?;
    let mut v = DVector::from_column_slice(qvel);
    for i in 1..model.nbodies() {
        if *model.joint(i) == Joint::Free {
            let (a, d) = (model.idx_q(i), model.idx_v(i));
            let lin = free_rotation(q, a).tr_mul(&Vec3::new(qvel[d], qvel[d + 1], qvel[d + 2]));
            v.as_mut_slice()[d..d + 3].copy_from_slice(lin.as_slice());
        }
    }
    Ok(v)
}

/// Converts gelenk's v to MuJoCo's `qvel` at configuration `q` (the inverse of
/// [`v_from_mujoco`]).
pub fn v_to_mujoco(model: &Model, q: &DVector<f64>, v: &DVector<f64>) -> Result<DVector<f64>, DynamicsError> {
    check_len("q", model.nq(), q.len())?;
    check_len("v", model.nv(), v.len())?;
    let mut qvel = v.clone();
    for i in 1..model.nbodies() {
        if *model.joint(i) == Joint::Free {
            let (a, d) = (model.idx_q(i), model.idx_v(i));
            let lin = free_rotation(q, a) * Vec3::new(v[d], v[d + 1], v[d + 2]);
            qvel.as_mut_slice()[d..d + 3].copy_from_slice(lin.as_slice());
        }
    }
    Ok(qvel)
}

fn check_len(what: &'static str, expected: usize, got: usize) -> Result<(), DynamicsError> {
    if expected != got {
        return Err(DynamicsError::DimensionMismatch { what, expected, got });
    }
    Ok(())
}

fn free_rotation(q: &DVector<f64>, a: usize) -> Mat3 {
    let quat = Quaternion::new(q[a + 6], q[a + 3], q[a + 4], q[a + 5]);
    UnitQuaternion::from_quaternion(quat).to_rotation_matrix().into_inner()
}

// ---------------------------------------------------------------------------------------------
// Loading

/// Which defaults an element takes.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Joint,
    Geom,
    /// Elements without defaults (body, frame, inertial, freejoint, …).
    None,
}

#[derive(Default)]
struct Class {
    parent: Option<String>,
    joint: HashMap<String, String>,
    geom: HashMap<String, String>,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum InertiaFromGeom {
    Auto,
    Always,
    Never,
}

struct Compiler {
    radian: bool,
    eulerseq: [u8; 3],
    inertia_from_geom: InertiaFromGeom,
    autolimits: bool,
    settotalmass: f64,
}

/// The frame children of an MJCF body attach to, and where that frame is.
#[derive(Clone)]
struct Parent {
    /// Body spec whose frame the MJCF parent body's frame is fixed in (`universe` for the world).
    spec: String,
    /// Pose of the MJCF parent body frame in that spec's frame.
    offset: Transform,
    /// Pose of the MJCF parent body frame in the world, when it is welded to the world.
    world: Option<Transform>,
    /// The parent's name, for generated names.
    name: String,
}

/// A geom read from the document, in its body's frame.
struct Geom {
    name: String,
    shape: Shape,
    pose: Transform,
    /// Mass and principal moments about the geom frame's origin, in geom axes (kg, kg·m²).
    mass: f64,
    moments: Vec3,
    friction: [f64; 3],
    collides: bool,
    node: NodeId,
}

/// A body's children, with `<frame>`s flattened.
struct Children<'a, 'i> {
    joints: Vec<Node<'a, 'i>>,
    geoms: Vec<(Node<'a, 'i>, Transform, String)>,
    bodies: Vec<(Node<'a, 'i>, Transform, String)>,
    inertial: Option<Node<'a, 'i>>,
}

struct Loader<'a, 'i> {
    file: &'a str,
    doc: &'a roxmltree::Document<'i>,
    compiler: Compiler,
    classes: HashMap<String, Class>,
    builder: ModelBuilder,
    specs: Vec<BodySpec>,
    statics: Vec<StaticGeometry>,
    geoms: Vec<GeomInfo>,
    bodies: Vec<(String, String, Transform)>,
    free_bodies: Vec<(String, Transform)>,
    joint_damping: Vec<(String, f64)>,
    joint_armature: Vec<(String, f64)>,
    /// The elements behind spec (body) names and joint names, to report model errors.
    body_elements: HashMap<String, NodeId>,
    joint_elements: HashMap<String, NodeId>,
    body_count: usize,
}

/// Element nesting that the XML parser (recursive) handles on any thread's stack.
const SHALLOW: usize = 100;
/// Deepest element nesting accepted.
const MAX_DEPTH: usize = 10_000;
/// Stack reserved per nesting level when parsing a deep document on its own thread.
const STACK_PER_LEVEL: usize = 32 * 1024;

fn load_named(text: &str, file: &str) -> Result<MjcfScene, MjcfError> {
    // roxmltree parses recursively: a deeply nested document (a long chain of bodies) would
    // overflow a small stack, so such documents are parsed on a thread with a stack to match.
    let depth = nesting_depth(text);
    if depth <= SHALLOW {
        return load_on_this_thread(text, file);
    }
    if depth > MAX_DEPTH {
        return Err(MjcfError::Xml {
            file: file.to_string(),
            message: format!("elements are nested {depth} deep; at most {MAX_DEPTH} levels are supported"),
        });
    }
    std::thread::scope(|scope| {
        std::thread::Builder::new()
            .name("gelenk-mjcf".to_string())
            .stack_size((depth + 64) * STACK_PER_LEVEL)
            .spawn_scoped(scope, || load_on_this_thread(text, file))
            .map_err(|e| MjcfError::Xml {
                file: file.to_string(),
                message: format!("no thread to parse a document nested {depth} deep: {e}"),
            })?
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
    })
}

/// An upper bound of the element nesting depth (comments, CDATA, processing instructions,
/// declarations and quoted attribute values skipped), without parsing.
fn nesting_depth(text: &str) -> usize {
    let b = text.as_bytes();
    let find = |from: usize, pat: &[u8]| {
        b[from.min(b.len())..]
            .windows(pat.len())
            .position(|w| w == pat)
            .map_or(b.len(), |p| from + p + pat.len())
    };
    let (mut i, mut depth, mut max) = (0, 0usize, 0);
    while i < b.len() {
        if b[i] != b'<' {
            i += 1;
        } else if b[i..].starts_with(b"<!--") {
            i = find(i + 4, b"-->");
        } else if b[i..].starts_with(b"<![CDATA[") {
            i = find(i + 9, b"]]>");
        } else if b[i..].starts_with(b"<?") {
            i = find(i + 2, b"?>");
        } else if b[i..].starts_with(b"<!") {
            i = find(i + 2, b">");
        } else if b[i..].starts_with(b"</") {
            depth = depth.saturating_sub(1);
            i = find(i + 2, b">");
        } else {
            // A start tag: up to the `>` outside quotes; `/>` closes it at once.
            let mut quote = None;
            let mut j = i + 1;
            while j < b.len() {
                match (quote, b[j]) {
                    (None, b'"' | b'\'') => quote = Some(b[j]),
                    (Some(q), c) if c == q => quote = None,
                    (None, b'>') => break,
                    _ => {}
                }
                j += 1;
            }
            if j >= b.len() || b[j - 1] != b'/' {
                depth += 1;
                max = max.max(depth);
            }
            i = j + 1;
        }
    }
    max
}

/// How gelenk treats one of MuJoCo's attributes of an element.
#[derive(Clone, Copy)]
enum Treatment {
    /// Read (or checked where it is read).
    Read,
    /// Without effect on what gelenk simulates: names, looks, MuJoCo's solver settings and the
    /// softness of its constraints (gelenk's contacts and limits are hard), actuator limits.
    Ignored,
    /// Changes the dynamics or the contacts in a way gelenk cannot represent, unless it has the
    /// value given here (MuJoCo's default; numbers compared as numbers).
    UnlessDefault(&'static str),
}

use Treatment::{Ignored, Read, UnlessDefault};

const ORIENTATION: [(&str, Treatment); 5] =
    [("quat", Read), ("axisangle", Read), ("euler", Read), ("xyaxes", Read), ("zaxis", Read)];

/// MuJoCo 4.0's attributes of the elements gelenk reads (its schema, as `mj_loadXML` checks it),
/// with how gelenk treats each; `None` for elements gelenk does not read. A joint or geom inside
/// `<default>` has the attributes of one in a body less `name` and `class`.
fn schema(element: &str) -> Option<Vec<(&'static str, Treatment)>> {
    let list: Vec<(&'static str, Treatment)> = match element {
        "compiler" => vec![
            ("angle", Read),
            ("eulerseq", Read),
            ("inertiafromgeom", Read),
            ("autolimits", Read),
            ("settotalmass", Read),
            ("coordinate", Read),
            ("boundmass", Read),
            ("boundinertia", Read),
            ("discardvisual", Read),
            ("balanceinertia", UnlessDefault("false")),
            ("alignfree", UnlessDefault("false")),
            ("inertiagrouprange", UnlessDefault("0 5")),
            ("meshdir", Ignored),
            ("texturedir", Ignored),
            ("assetdir", Ignored),
            ("strippath", Ignored),
            ("fitaabb", Ignored),
            ("fusestatic", Ignored),
            ("saveinertial", Ignored),
            ("usethread", Ignored),
            ("savecanonical", Ignored),
            ("savecompiled", Ignored),
            ("passthrough", Ignored),
            ("conflict", Ignored),
        ],
        "option" => vec![
            ("timestep", Read),
            ("gravity", Read),
            ("cone", Read),
            ("density", UnlessDefault("0")),
            ("viscosity", UnlessDefault("0")),
            ("wind", Ignored), // acts only through density and viscosity
            ("magnetic", Ignored),
            ("integrator", Ignored),
            ("impratio", Ignored),
            ("tolerance", Ignored),
            ("ls_tolerance", Ignored),
            ("noslip_tolerance", Ignored),
            ("ccd_tolerance", Ignored),
            ("iterations", Ignored),
            ("ls_iterations", Ignored),
            ("noslip_iterations", Ignored),
            ("ccd_iterations", Ignored),
            ("sdf_iterations", Ignored),
            ("sdf_initpoints", Ignored),
            ("jacobian", Ignored),
            ("solver", Ignored),
            ("actuatorgroupdisable", Ignored),
            ("sleep_tolerance", Ignored),
            ("o_margin", Ignored), // the o_* apply only with the override flag, refused below
            ("o_solref", Ignored),
            ("o_solimp", Ignored),
            ("o_friction", Ignored),
        ],
        "flag" => vec![
            ("gravity", Read),
            ("contact", Read),
            ("constraint", UnlessDefault("enable")),
            ("limit", UnlessDefault("enable")),
            ("frictionloss", UnlessDefault("enable")),
            ("damper", UnlessDefault("enable")),
            ("filterparent", UnlessDefault("enable")),
            ("override", UnlessDefault("disable")),
            ("equality", Ignored), // equality constraints are refused where they appear
            ("spring", Ignored),   // joint springs are refused where they appear
            ("actuation", Ignored),
            ("clampctrl", Ignored),
            ("warmstart", Ignored),
            ("refsafe", Ignored),
            ("sensor", Ignored),
            ("midphase", Ignored),
            ("eulerdamp", Ignored),
            ("autoreset", Ignored),
            ("nativeccd", Ignored),
            ("diagexact", Ignored),
            ("speculative", Ignored),
            ("ipc", Ignored),
            ("energy", Ignored),
            ("fwdinv", Ignored),
            ("invdiscrete", Ignored),
            ("multiccd", Ignored),
            ("island", Ignored),
            ("sleep", Ignored),
        ],
        "body" => vec![
            ("name", Read),
            ("childclass", Read),
            ("pos", Read),
            ("mocap", Read),
            ("gravcomp", Read),
            ("user", Ignored),
            ("fuse", Ignored),
            ("simple", Ignored),
            ("sleep", Ignored),
        ],
        "frame" => vec![("name", Ignored), ("childclass", Read), ("pos", Read)],
        "inertial" => vec![("pos", Read), ("mass", Read), ("diaginertia", Read), ("fullinertia", Read)],
        "freejoint" => vec![("name", Read), ("group", Ignored), ("align", UnlessDefault("false"))],
        "joint" => vec![
            ("name", Read),
            ("class", Read),
            ("type", Read),
            ("pos", Read),
            ("axis", Read),
            ("limited", Read),
            ("range", Read),
            ("damping", Read),
            ("frictionloss", Read),
            ("armature", Read),
            ("stiffness", Read),
            ("ref", Read),
            ("springdamper", UnlessDefault("0 0")),
            ("springref", Ignored), // acts only through stiffness, refused unless zero
            ("springyield", Ignored),
            ("margin", Ignored),
            ("solreflimit", Ignored),
            ("solimplimit", Ignored),
            ("solreffriction", Ignored),
            ("solimpfriction", Ignored),
            ("actuatorfrclimited", Ignored),
            ("actuatorfrcrange", Ignored),
            ("actuatorgravcomp", Ignored),
            ("group", Ignored),
            ("user", Ignored),
        ],
        "geom" => vec![
            ("name", Read),
            ("class", Read),
            ("type", Read),
            ("size", Read),
            ("fromto", Read),
            ("pos", Read),
            ("density", Read),
            ("mass", Read),
            ("friction", Read),
            ("contype", Read),
            ("conaffinity", Read),
            ("condim", UnlessDefault("3")),
            ("margin", UnlessDefault("0")),
            ("gap", UnlessDefault("0")),
            ("priority", UnlessDefault("0")),
            ("shellinertia", UnlessDefault("false")),
            ("adhesion", UnlessDefault("0")),
            ("surfacevel", UnlessDefault("0 0 0")),
            ("fluidshape", Ignored), // acts only through option density and viscosity
            ("fluidcoef", Ignored),
            ("solref", Ignored),
            ("solimp", Ignored),
            ("solmix", Ignored),
            ("mesh", Ignored), // mesh and height-field geoms are refused by type
            ("hfield", Ignored),
            ("fitscale", Ignored),
            ("material", Ignored),
            ("rgba", Ignored),
            ("group", Ignored),
            ("castshadow", Ignored),
            ("user", Ignored),
        ],
        "exclude" => vec![("name", Ignored), ("body1", Read), ("body2", Read)],
        "default" => vec![("class", Read)],
        _ => return None,
    };
    let oriented = matches!(element, "body" | "frame" | "inertial" | "geom");
    Some(list.into_iter().chain(ORIENTATION.into_iter().filter(|_| oriented)).collect())
}

/// Whether an attribute's value equals `default`: as numbers when both parse as numbers.
fn equals_default(value: &str, default: &str) -> bool {
    let numbers = |t: &str| t.split_whitespace().map(str::parse::<f64>).collect::<Result<Vec<_>, _>>();
    match (numbers(value), numbers(default)) {
        (Ok(a), Ok(b)) if !a.is_empty() => a == b,
        _ => value.trim() == default,
    }
}

fn load_on_this_thread(text: &str, file: &str) -> Result<MjcfScene, MjcfError> {
    let doc = roxmltree::Document::parse(text)
        .map_err(|e| MjcfError::Xml { file: file.to_string(), message: e.to_string() })?;
    let root = doc.root_element();
    let mut loader = Loader {
        file,
        doc: &doc,
        compiler: Compiler {
            radian: false,
            eulerseq: *b"xyz",
            inertia_from_geom: InertiaFromGeom::Auto,
            autolimits: true,
            settotalmass: -1.0,
        },
        classes: HashMap::new(),
        builder: ModelBuilder::new(),
        specs: Vec::new(),
        statics: Vec::new(),
        geoms: Vec::new(),
        bodies: Vec::new(),
        free_bodies: Vec::new(),
        joint_damping: Vec::new(),
        joint_armature: Vec::new(),
        body_elements: HashMap::new(),
        joint_elements: HashMap::new(),
        body_count: 1,
    };
    if root.tag_name().name() != "mujoco" {
        return Err(loader.invalid(root, "the root element must be <mujoco>"));
    }
    loader.check_attributes(root)?;
    loader.builder.name(root.attribute("model").unwrap_or("MuJoCo Model"));

    // Global settings first: they apply to the whole document wherever they appear.
    let sections: Vec<Node> = root.children().filter(Node::is_element).collect();
    for &s in &sections {
        if s.tag_name().name() == "compiler" {
            loader.read_compiler(s)?;
        }
    }
    let mut timestep = 0.002;
    let mut gravity = Vec3::new(0.0, 0.0, -9.81);
    let (mut gravity_on, mut contact_enabled) = (true, true);
    let mut friction = FrictionModel::Pyramid { facets: 4 };
    let mut excludes = Vec::new();
    for &s in &sections {
        match s.tag_name().name() {
            "compiler" => {}
            "option" => {
                if let Some(t) = loader.scalar(s, Kind::None, "timestep")? {
                    if t <= 0.0 {
                        return Err(loader.bad_attr(s, "timestep", &t.to_string(), "must be positive"));
                    }
                    timestep = t;
                }
                if let Some(g) = loader.vector::<3>(s, Kind::None, "gravity")? {
                    gravity = Vec3::from(g);
                }
                friction = match s.attribute("cone") {
                    None | Some("pyramidal") => FrictionModel::Pyramid { facets: 4 },
                    Some("elliptic") => FrictionModel::Cone,
                    Some(t) => {
                        return Err(loader.bad_attr(s, "cone", t, "expected `pyramidal` or `elliptic`"))
                    }
                };
                for flag in s.children().filter(Node::is_element) {
                    if flag.tag_name().name() == "flag" {
                        gravity_on &= loader.enabled(flag, "gravity")?;
                        contact_enabled &= loader.enabled(flag, "contact")?;
                    }
                }
            }
            "default" => loader.read_default(s)?,
            "worldbody" | "asset" | "visual" | "statistic" | "size" | "actuator" | "sensor" | "keyframe"
            | "custom" => {}
            "contact" => {
                for c in s.children().filter(Node::is_element) {
                    match c.tag_name().name() {
                        "exclude" => {
                            let body = |a: &str| {
                                c.attribute(a).map(str::to_string).ok_or_else(|| loader.missing(c, a))
                            };
                            excludes.push((body("body1")?, body("body2")?, loader.describe(c)));
                        }
                        other => {
                            return Err(loader.unsupported(c, &format!("contact <{other}> (only <exclude>)")))
                        }
                    }
                }
            }
            "equality" | "tendon" | "deformable" => {
                if let Some(c) = s.children().find(Node::is_element) {
                    let what = format!("<{}> in <{}>", c.tag_name().name(), s.tag_name().name());
                    return Err(loader.unsupported(c, &what));
                }
            }
            other => return Err(loader.unsupported(s, &format!("section <{other}>"))),
        }
    }
    if !gravity_on {
        gravity = Vec3::zeros();
    }
    loader.builder.gravity(gravity);

    let world = Parent {
        spec: "universe".to_string(),
        offset: Transform::identity(),
        world: Some(Transform::identity()),
        name: "world".to_string(),
    };
    let mut world_geom_count = 0;
    for wb in sections.iter().filter(|s| s.tag_name().name() == "worldbody") {
        let children = loader.children(*wb, "main", Transform::identity())?;
        if let Some(j) = children.joints.first() {
            return Err(loader.invalid(*j, "the world body cannot have joints"));
        }
        if let Some(i) = children.inertial {
            return Err(loader.invalid(i, "the world body cannot have an <inertial>"));
        }
        for (node, pose, class) in &children.geoms {
            let g = loader.geom(*node, class, *pose, &format!("world_geom{world_geom_count}"))?;
            world_geom_count += 1;
            loader.statics.push(StaticGeometry {
                name: g.name,
                shape: g.shape,
                pose: g.pose,
                friction: g.friction,
                collides: g.collides,
            });
        }
        // Depth-first in document order, with an explicit stack: nesting depth is unbounded.
        let mut stack: Vec<_> = children
            .bodies
            .into_iter()
            .rev()
            .map(|(node, pose, class)| (node, world.clone(), pose, class))
            .collect();
        while let Some((node, parent, pose, class)) = stack.pop() {
            let (me, bodies) = loader.body(node, &parent, pose, &class)?;
            stack.extend(bodies.into_iter().rev().map(|(node, pose, class)| (node, me.clone(), pose, class)));
        }
    }
    loader.finish(timestep, gravity, contact_enabled, friction, excludes)
}

impl<'a, 'i> Loader<'a, 'i> {
    // ----- errors -----------------------------------------------------------------------------

    fn describe(&self, node: Node) -> String {
        super::describe_element(self.doc, node)
    }

    /// Describes an element known by id (descriptions are made only for errors: finding the line
    /// number scans the text).
    fn describe_id(&self, id: NodeId) -> String {
        self.doc.get_node(id).map_or_else(|| "<worldbody>".to_string(), |n| self.describe(n))
    }

    fn invalid(&self, node: Node, what: &str) -> MjcfError {
        MjcfError::Invalid {
            file: self.file.to_string(),
            element: self.describe(node),
            what: what.to_string(),
        }
    }

    fn unsupported(&self, node: Node, what: &str) -> MjcfError {
        MjcfError::Unsupported {
            file: self.file.to_string(),
            element: self.describe(node),
            what: what.to_string(),
        }
    }

    fn missing(&self, node: Node, attribute: &str) -> MjcfError {
        MjcfError::MissingAttribute {
            file: self.file.to_string(),
            element: self.describe(node),
            attribute: attribute.to_string(),
        }
    }

    fn bad_attr(&self, node: Node, attribute: &str, value: &str, what: &str) -> MjcfError {
        MjcfError::InvalidAttribute {
            file: self.file.to_string(),
            element: self.describe(node),
            attribute: attribute.to_string(),
            value: value.to_string(),
            what: what.to_string(),
        }
    }

    /// Every attribute of the elements gelenk reads is one of MuJoCo's ([`schema`]): a misspelt
    /// attribute is an error, as in MuJoCo, not a silently ignored setting; one that would change
    /// the dynamics in a way gelenk cannot represent is [`MjcfError::Unsupported`] unless it has
    /// MuJoCo's default value. Elements are those of `<compiler>`, `<option>` and its `<flag>`,
    /// `<default>` classes with their `<joint>` and `<geom>`, the bodies, frames, inertials,
    /// joints and geoms of `<worldbody>`, and `<contact><exclude>`.
    fn check_attributes(&self, root: Node) -> Result<(), MjcfError> {
        for node in root.descendants().filter(Node::is_element) {
            let tag = node.tag_name().name();
            let parent = node.parent_element().map(|p| p.tag_name().name()).unwrap_or("");
            let (element, in_default) = match (parent, tag) {
                ("mujoco", "compiler" | "option") | ("option", "flag") | ("contact", "exclude") => {
                    (tag, false)
                }
                ("mujoco" | "default", "default") => (tag, false),
                ("default", "joint" | "geom") => (tag, true),
                (_, "body" | "frame" | "inertial" | "joint" | "freejoint" | "geom")
                    if node.ancestors().any(|a| a.has_tag_name("worldbody")) =>
                {
                    (tag, false)
                }
                _ => continue,
            };
            let Some(known) = schema(element) else { continue };
            for attribute in node.attributes() {
                let name = attribute.name();
                let treatment = known
                    .iter()
                    .find(|(n, _)| *n == name && !(in_default && matches!(*n, "name" | "class")))
                    .map(|(_, t)| *t);
                match treatment {
                    None => {
                        let place =
                            if in_default { format!("<{tag}> in <default>") } else { format!("<{tag}>") };
                        return Err(self.bad_attr(
                            node,
                            name,
                            attribute.value(),
                            &format!("MuJoCo has no such attribute of {place}"),
                        ));
                    }
                    Some(UnlessDefault(default)) if !equals_default(attribute.value(), default) => {
                        return Err(self.unsupported(
                            node,
                            &format!(
                                "{name}=\"{}\" (only MuJoCo's default, \"{default}\")",
                                attribute.value()
                            ),
                        ));
                    }
                    Some(_) => {}
                }
            }
        }
        Ok(())
    }

    // ----- attributes -------------------------------------------------------------------------

    /// The attribute as written on the element, else from its default class chain.
    fn get(&self, node: Node, kind: Kind, class: &str, name: &str) -> Option<String> {
        if let Some(v) = node.attribute(name) {
            return Some(v.to_string());
        }
        if kind == Kind::None {
            return None;
        }
        let mut c = Some(class);
        while let Some(name_c) = c {
            let class = self.classes.get(name_c)?;
            let map = if kind == Kind::Joint { &class.joint } else { &class.geom };
            if let Some(v) = map.get(name) {
                return Some(v.clone());
            }
            c = class.parent.as_deref();
        }
        None
    }

    /// The class an element takes its defaults from: its own `class`, else the inherited
    /// `childclass`.
    fn class_of(&self, node: Node, inherited: &str) -> Result<String, MjcfError> {
        match node.attribute("class") {
            Some(c) if self.classes.contains_key(c) => Ok(c.to_string()),
            Some(c) => Err(self.bad_attr(node, "class", c, "no <default> class has this name")),
            None => Ok(inherited.to_string()),
        }
    }

    fn numbers_of(&self, node: Node, name: &str, text: &str) -> Result<Vec<f64>, MjcfError> {
        text.split_whitespace()
            .map(|t| match t.parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(x),
                _ => Err(self.bad_attr(node, name, text, &format!("`{t}` is not a finite number"))),
            })
            .collect()
    }

    /// Between `min` and `max` numbers, if the attribute is present.
    fn numbers(
        &self,
        node: Node,
        kind: Kind,
        class: &str,
        name: &str,
        min: usize,
        max: usize,
    ) -> Result<Option<Vec<f64>>, MjcfError> {
        let Some(text) = self.get(node, kind, class, name) else { return Ok(None) };
        let v = self.numbers_of(node, name, &text)?;
        if v.len() < min || v.len() > max {
            let count = if min == max { format!("{min}") } else { format!("{min} to {max}") };
            return Err(self.bad_attr(
                node,
                name,
                &text,
                &format!("expected {count} numbers, found {}", v.len()),
            ));
        }
        Ok(Some(v))
    }

    fn vector_c<const N: usize>(
        &self,
        node: Node,
        kind: Kind,
        class: &str,
        name: &str,
    ) -> Result<Option<[f64; N]>, MjcfError> {
        Ok(self.numbers(node, kind, class, name, N, N)?.map(|v| {
            let mut a = [0.0; N];
            a.copy_from_slice(&v);
            a
        }))
    }

    fn vector<const N: usize>(
        &self,
        node: Node,
        kind: Kind,
        name: &str,
    ) -> Result<Option<[f64; N]>, MjcfError> {
        self.vector_c::<N>(node, kind, "main", name)
    }

    fn scalar_c(&self, node: Node, kind: Kind, class: &str, name: &str) -> Result<Option<f64>, MjcfError> {
        Ok(self.vector_c::<1>(node, kind, class, name)?.map(|a| a[0]))
    }

    fn scalar(&self, node: Node, kind: Kind, name: &str) -> Result<Option<f64>, MjcfError> {
        self.scalar_c(node, kind, "main", name)
    }

    /// A non-negative scalar.
    fn non_negative(
        &self,
        node: Node,
        kind: Kind,
        class: &str,
        name: &str,
    ) -> Result<Option<f64>, MjcfError> {
        match self.scalar_c(node, kind, class, name)? {
            Some(x) if x < 0.0 => Err(self.bad_attr(node, name, &x.to_string(), "must not be negative")),
            x => Ok(x),
        }
    }

    fn boolean(&self, node: Node, name: &str, text: &str) -> Result<bool, MjcfError> {
        match text {
            "true" => Ok(true),
            "false" => Ok(false),
            _ => Err(self.bad_attr(node, name, text, "expected `true` or `false`")),
        }
    }

    fn enabled(&self, node: Node, name: &str) -> Result<bool, MjcfError> {
        match node.attribute(name) {
            None | Some("enable") => Ok(true),
            Some("disable") => Ok(false),
            Some(t) => Err(self.bad_attr(node, name, t, "expected `enable` or `disable`")),
        }
    }

    fn angle(&self, x: f64) -> f64 {
        if self.compiler.radian {
            x
        } else {
            x.to_radians()
        }
    }

    /// Position and orientation of a body, frame, geom or inertial in its parent frame.
    fn pose(&self, node: Node, kind: Kind, class: &str) -> Result<Transform, MjcfError> {
        let pos = self.vector_c::<3>(node, kind, class, "pos")?.map(Vec3::from).unwrap_or_else(Vec3::zeros);
        Ok(Transform::new(self.orientation(node, kind, class)?, pos))
    }

    fn orientation(&self, node: Node, kind: Kind, class: &str) -> Result<Mat3, MjcfError> {
        let given: Vec<&str> = ["quat", "axisangle", "euler", "xyaxes", "zaxis"]
            .into_iter()
            .filter(|a| node.attribute(*a).is_some())
            .collect();
        if given.len() > 1 {
            return Err(self.invalid(node, &format!("several orientations given ({})", given.join(", "))));
        }
        // An orientation written on the element replaces any in its defaults.
        let which = match given.first() {
            Some(a) => *a,
            None => match ["quat", "axisangle", "euler", "xyaxes", "zaxis"]
                .into_iter()
                .find(|a| self.get(node, kind, class, a).is_some())
            {
                Some(a) => a,
                None => return Ok(Mat3::identity()),
            },
        };
        let zero = |what: &str| {
            let text = self.get(node, kind, class, which).unwrap_or_default();
            self.bad_attr(node, which, &text, &format!("{what} is zero"))
        };
        let r = match which {
            "quat" => {
                let q = self.vector_c::<4>(node, kind, class, "quat")?.unwrap_or([1.0, 0.0, 0.0, 0.0]);
                let q = Quaternion::new(q[0], q[1], q[2], q[3]);
                if q.norm() < 1e-12 {
                    return Err(zero("the quaternion"));
                }
                UnitQuaternion::from_quaternion(q).to_rotation_matrix().into_inner()
            }
            "axisangle" => {
                let a = self.vector_c::<4>(node, kind, class, "axisangle")?.unwrap_or_default();
                let axis = Vec3::new(a[0], a[1], a[2]);
                let axis = axis.try_normalize(1e-12).ok_or_else(|| zero("the axis"))?;
                crate::math::axis_angle(&axis, self.angle(a[3]))
            }
            "euler" => {
                let e = self.vector_c::<3>(node, kind, class, "euler")?.unwrap_or_default();
                let mut q = UnitQuaternion::identity();
                for (k, c) in self.compiler.eulerseq.iter().enumerate() {
                    let axis = match c.to_ascii_lowercase() {
                        b'x' => Vec3::x_axis(),
                        b'y' => Vec3::y_axis(),
                        _ => Vec3::z_axis(),
                    };
                    let r = UnitQuaternion::from_axis_angle(&axis, self.angle(e[k]));
                    q = if c.is_ascii_lowercase() { q * r } else { r * q };
                }
                q.to_rotation_matrix().into_inner()
            }
            "xyaxes" => {
                let a = self.vector_c::<6>(node, kind, class, "xyaxes")?.unwrap_or_default();
                let x = Vec3::new(a[0], a[1], a[2]).try_normalize(1e-12).ok_or_else(|| zero("the x axis"))?;
                let y = Vec3::new(a[3], a[4], a[5]);
                let y = (y - x * x.dot(&y))
                    .try_normalize(1e-12)
                    .ok_or_else(|| zero("the y axis (made orthogonal to x)"))?;
                Mat3::from_columns(&[x, y, x.cross(&y)])
            }
            _ => {
                let z = self.vector_c::<3>(node, kind, class, "zaxis")?.unwrap_or_default();
                let z = Vec3::from(z).try_normalize(1e-12).ok_or_else(|| zero("the z axis"))?;
                z_to(&z)
            }
        };
        Ok(r)
    }

    // ----- sections ---------------------------------------------------------------------------

    fn read_compiler(&mut self, node: Node) -> Result<(), MjcfError> {
        if let Some(a) = node.attribute("angle") {
            self.compiler.radian = match a {
                "radian" => true,
                "degree" => false,
                _ => return Err(self.bad_attr(node, "angle", a, "expected `degree` or `radian`")),
            };
        }
        if let Some(s) = node.attribute("eulerseq") {
            let b = s.as_bytes();
            if b.len() != 3 || !b.iter().all(|c| b"xyzXYZ".contains(c)) {
                return Err(self.bad_attr(node, "eulerseq", s, "expected three characters from xyzXYZ"));
            }
            self.compiler.eulerseq = [b[0], b[1], b[2]];
        }
        if let Some(s) = node.attribute("inertiafromgeom") {
            self.compiler.inertia_from_geom = match s {
                "auto" => InertiaFromGeom::Auto,
                "true" => InertiaFromGeom::Always,
                "false" => InertiaFromGeom::Never,
                _ => {
                    return Err(self.bad_attr(
                        node,
                        "inertiafromgeom",
                        s,
                        "expected `true`, `false` or `auto`",
                    ))
                }
            };
        }
        if let Some(s) = node.attribute("autolimits") {
            self.compiler.autolimits = self.boolean(node, "autolimits", s)?;
        }
        if let Some(m) = self.scalar(node, Kind::None, "settotalmass")? {
            self.compiler.settotalmass = m;
        }
        if node.attribute("coordinate").is_some_and(|c| c != "local") {
            return Err(self.unsupported(node, "coordinate=\"global\""));
        }
        for a in ["boundmass", "boundinertia"] {
            if self.scalar(node, Kind::None, a)?.is_some_and(|x| x != 0.0) {
                return Err(self.unsupported(node, a));
            }
        }
        if let Some(s) = node.attribute("discardvisual") {
            if self.boolean(node, "discardvisual", s)? {
                return Err(self.unsupported(node, "discardvisual=\"true\""));
            }
        }
        Ok(())
    }

    fn read_default(&mut self, top: Node) -> Result<(), MjcfError> {
        let mut stack: Vec<(Node, Option<String>)> = vec![(top, None)];
        while let Some((node, parent)) = stack.pop() {
            let name = match (node.attribute("class"), &parent) {
                (Some(c), _) => c.to_string(),
                (None, None) => "main".to_string(),
                (None, Some(_)) => return Err(self.missing(node, "class")),
            };
            if self.classes.contains_key(&name) {
                return Err(self.invalid(node, &format!("default class `{name}` is defined twice")));
            }
            let mut class = Class { parent, ..Class::default() };
            for c in node.children().filter(Node::is_element) {
                let attrs = || c.attributes().map(|a| (a.name().to_string(), a.value().to_string()));
                match c.tag_name().name() {
                    "default" => stack.push((c, Some(name.clone()))),
                    "joint" => class.joint.extend(attrs()),
                    "geom" => class.geom.extend(attrs()),
                    _ => {} // site, camera, actuator, … defaults: nothing gelenk reads
                }
            }
            self.classes.insert(name, class);
        }
        Ok(())
    }

    /// The children of a body (or of the world body), looking through `<frame>`s: `prefix` is the
    /// pose of the frame being read in the body frame, `childclass` its class.
    fn children(
        &self,
        node: Node<'a, 'i>,
        childclass: &str,
        prefix: Transform,
    ) -> Result<Children<'a, 'i>, MjcfError> {
        let mut out = Children { joints: Vec::new(), geoms: Vec::new(), bodies: Vec::new(), inertial: None };
        self.collect(node, childclass, prefix, &mut out, true)?;
        Ok(out)
    }

    fn collect(
        &self,
        node: Node<'a, 'i>,
        childclass: &str,
        prefix: Transform,
        out: &mut Children<'a, 'i>,
        is_body: bool,
    ) -> Result<(), MjcfError> {
        // Children in document order, entering `<frame>`s in place (explicit stack, no recursion).
        let element_children = |n: Node<'a, 'i>| n.children().filter(Node::is_element).collect::<Vec<_>>();
        let mut stack: Vec<(Node<'a, 'i>, String, Transform, bool)> = element_children(node)
            .into_iter()
            .rev()
            .map(|c| (c, childclass.to_string(), prefix, is_body))
            .collect();
        while let Some((c, childclass, prefix, is_body)) = stack.pop() {
            let inherited_class = |c: Node| match c.attribute("childclass") {
                Some(cc) if !self.classes.contains_key(cc) => {
                    Err(self.bad_attr(c, "childclass", cc, "no <default> class has this name"))
                }
                Some(cc) => Ok(cc.to_string()),
                None => Ok(childclass.clone()),
            };
            match c.tag_name().name() {
                "joint" | "freejoint" if is_body => out.joints.push(c),
                "inertial" if is_body => {
                    if out.inertial.replace(c).is_some() {
                        return Err(self.invalid(c, "a body has at most one <inertial>"));
                    }
                }
                "geom" => out.geoms.push((c, prefix, self.class_of(c, &childclass)?)),
                "body" => out.bodies.push((c, prefix, inherited_class(c)?)),
                "frame" => {
                    let class = inherited_class(c)?;
                    let pose = prefix * self.pose(c, Kind::None, "main")?;
                    stack.extend(
                        element_children(c).into_iter().rev().map(|g| (g, class.clone(), pose, false)),
                    );
                }
                "site" | "camera" | "light" => {}
                other @ ("joint" | "freejoint" | "inertial") => {
                    return Err(self.invalid(c, &format!("<{other}> cannot be inside a <frame>")))
                }
                other => return Err(self.unsupported(c, &format!("<{other}> in a body"))),
            }
        }
        Ok(())
    }

    // ----- geoms ------------------------------------------------------------------------------

    /// Reads a geom; `frame` is the pose of its enclosing frame in the body frame.
    fn geom(&self, node: Node, class: &str, frame: Transform, default_name: &str) -> Result<Geom, MjcfError> {
        let k = Kind::Geom;
        let name = node.attribute("name").map(str::to_string).unwrap_or_else(|| default_name.to_string());
        let kind = self.get(node, k, class, "type").unwrap_or_else(|| "sphere".to_string());
        match kind.as_str() {
            "plane" | "sphere" | "capsule" | "cylinder" | "box" => {}
            "ellipsoid" | "mesh" | "hfield" | "sdf" => {
                return Err(self.unsupported(node, &format!("geom type `{kind}`")))
            }
            _ => {
                return Err(self.bad_attr(
                    node,
                    "type",
                    &kind,
                    "unknown geom type (expected plane, sphere, capsule, cylinder, box, ellipsoid, mesh, hfield or sdf)",
                ))
            }
        }
        let mut size = [0.0; 3];
        if let Some(s) = self.numbers(node, k, class, "size", 1, 3)? {
            if let Some(x) = s.iter().find(|x| **x < 0.0) {
                let text = self.get(node, k, class, "size").unwrap_or_default();
                return Err(self.bad_attr(node, "size", &text, &format!("size {x} is negative")));
            }
            size[..s.len()].copy_from_slice(&s);
        }
        let mut pose = self.pose(node, k, class)?;
        if let Some(ft) = self.vector_c::<6>(node, k, class, "fromto")? {
            if !matches!(kind.as_str(), "capsule" | "cylinder" | "box") {
                return Err(
                    self.invalid(node, &format!("fromto needs a capsule, cylinder or box, not a {kind}"))
                );
            }
            let (from, to) = (Vec3::new(ft[0], ft[1], ft[2]), Vec3::new(ft[3], ft[4], ft[5]));
            let d = from - to; // MuJoCo's geom z axis points from `to` to `from`
            if d.norm() < 1e-12 {
                let text = self.get(node, k, class, "fromto").unwrap_or_default();
                return Err(self.bad_attr(node, "fromto", &text, "the two points coincide"));
            }
            pose = Transform::new(z_to(&(d / d.norm())), (from + to) * 0.5);
            if kind == "box" {
                size = [size[0], size[0], 0.5 * d.norm()];
            } else {
                size[1] = 0.5 * d.norm();
            }
        }
        let needed = match kind.as_str() {
            "plane" => 0,
            "sphere" => 1,
            "capsule" | "cylinder" => 2,
            _ => 3,
        };
        if size[..needed].iter().any(|x| *x <= 0.0) {
            let text = self.get(node, k, class, "size").unwrap_or_else(|| "0 0 0".to_string());
            return Err(self.bad_attr(
                node,
                "size",
                &text,
                &format!("a {kind} needs {needed} positive size{}", if needed > 1 { "s" } else { "" }),
            ));
        }
        let (r, h) = (size[0], 2.0 * size[1]);
        let (shape, volume, unit_moments) = match kind.as_str() {
            "plane" => (Shape::HalfSpace { normal: Vec3::z() }, 0.0, Vec3::zeros()),
            "sphere" => {
                let i = 0.4 * r * r;
                (Shape::Sphere { radius: r }, 4.0 / 3.0 * PI * r * r * r, Vec3::new(i, i, i))
            }
            "cylinder" => {
                let t = (3.0 * r * r + h * h) / 12.0;
                (Shape::Cylinder { radius: r, length: h }, PI * r * r * h, Vec3::new(t, t, 0.5 * r * r))
            }
            "capsule" => {
                // MuJoCo's mjCGeom::SetInertia: the cylinder, plus the two hemispheres (a sphere's
                // mass) with the parallel-axis shift of each hemisphere.
                let volume = PI * r * r * (h + 4.0 / 3.0 * r);
                let sphere = 4.0 * r / (4.0 * r + 3.0 * h); // fraction of the mass in the caps
                let cyl = 1.0 - sphere;
                let t = cyl * (3.0 * r * r + h * h) / 12.0
                    + sphere * (0.4 * r * r + h * (3.0 * r + 2.0 * h) / 8.0);
                let a = cyl * r * r / 2.0 + sphere * 0.4 * r * r;
                (Shape::Capsule { radius: r, length: h }, volume, Vec3::new(t, t, a))
            }
            _ => {
                let [a, b, c] = size;
                let m = Vec3::new(b * b + c * c, a * a + c * c, a * a + b * b) / 3.0;
                (Shape::Box { size: Vec3::new(2.0 * a, 2.0 * b, 2.0 * c) }, 8.0 * a * b * c, m)
            }
        };
        let mass = match self.non_negative(node, k, class, "mass")? {
            Some(m) => m,
            None => self.non_negative(node, k, class, "density")?.unwrap_or(1000.0) * volume,
        };
        let mut friction = [1.0, 0.005, 0.0001];
        if let Some(f) = self.numbers(node, k, class, "friction", 1, 3)? {
            if f.iter().any(|x| *x < 0.0) {
                let text = self.get(node, k, class, "friction").unwrap_or_default();
                return Err(self.bad_attr(node, "friction", &text, "must not be negative"));
            }
            friction[..f.len()].copy_from_slice(&f);
        }
        let int = |a: &str| -> Result<i64, MjcfError> {
            match self.get(node, k, class, a) {
                None => Ok(1),
                Some(t) => t.trim().parse().map_err(|_| self.bad_attr(node, a, &t, "not an integer")),
            }
        };
        let collides = int("contype")? != 0 || int("conaffinity")? != 0;
        Ok(Geom {
            name,
            shape,
            pose: frame * pose,
            mass,
            moments: unit_moments * mass,
            friction,
            collides,
            node: node.id(),
        })
    }

    // ----- bodies -----------------------------------------------------------------------------

    /// Adds the specs of one body; returns the frame its children attach to, and the children.
    #[allow(clippy::type_complexity)]
    fn body(
        &mut self,
        node: Node<'a, 'i>,
        parent: &Parent,
        frame: Transform,
        class: &str,
    ) -> Result<(Parent, Vec<(Node<'a, 'i>, Transform, String)>), MjcfError> {
        let id = self.body_count;
        self.body_count += 1;
        let name = node.attribute("name").map(str::to_string).unwrap_or_else(|| format!("body{id}"));
        let element = node.id();
        if let Some(m) = node.attribute("mocap") {
            if self.boolean(node, "mocap", m)? {
                return Err(self.unsupported(node, "mocap bodies"));
            }
        }
        if self.scalar(node, Kind::None, "gravcomp")?.is_some_and(|g| g != 0.0) {
            return Err(self.unsupported(node, "gravity compensation (gravcomp)"));
        }
        let pose = frame * self.pose(node, Kind::None, "main")?;
        let children = self.children(node, class, Transform::identity())?;

        // Geoms and mass properties, in the MJCF body frame.
        let mut geoms = Vec::with_capacity(children.geoms.len());
        for (k, (g, prefix, gclass)) in children.geoms.iter().enumerate() {
            geoms.push(self.geom(*g, gclass, *prefix, &format!("{name}_geom{k}"))?);
        }
        let from_geoms = match (self.compiler.inertia_from_geom, children.inertial) {
            (InertiaFromGeom::Always, _) | (InertiaFromGeom::Auto, None) => true,
            (InertiaFromGeom::Never, _) | (InertiaFromGeom::Auto, Some(_)) => false,
        };
        let inertia = match (from_geoms, children.inertial) {
            (true, _) => combine(&geoms),
            (false, Some(i)) => self.inertial(i)?,
            (false, None) => RigidInertia::massless(),
        };

        // Joints.
        let n = children.joints.len();
        let mut joints = Vec::with_capacity(n);
        for (k, j) in children.joints.iter().enumerate() {
            let default_name = if n == 1 { format!("{name}_joint") } else { format!("{name}_joint{k}") };
            joints.push(self.joint(*j, class, default_name)?);
        }
        if !joints.is_empty() || parent.world.is_none() {
            if let Some(g) = geoms.iter().find(|g| matches!(g.shape, Shape::HalfSpace { .. })) {
                return Err(MjcfError::Invalid {
                    file: self.file.to_string(),
                    element: self.describe_id(g.node),
                    what: format!("a plane must be fixed in the world, but body `{name}` moves"),
                });
            }
        }
        let placement = parent.offset * pose;
        let (spec_name, offset, world) = if joints.is_empty() {
            // Welded to the parent: a fixed joint, fused by the builder.
            let world = parent.world.map(|w| w * pose);
            let mut spec = BodySpec::new(name.clone(), parent.spec.clone(), Joint::Fixed, placement, inertia)
                .with_joint_name(format!("{name}_weld"));
            match world {
                Some(w) => self.add_statics(geoms, &w),
                None => self.attach(&mut spec, geoms, Transform::identity()),
            }
            self.body_elements.insert(name.clone(), element);
            self.specs.push(spec);
            (name.clone(), Transform::identity(), world)
        } else if joints.iter().any(|j| j.joint == Joint::Free) {
            let j = &joints[0];
            if n > 1 {
                return Err(self.invalid(j.node, "a free joint must be the only joint of its body"));
            }
            let Some(parent_world) = parent.world else {
                return Err(self.invalid(
                    j.node,
                    &format!("a free joint needs a body attached to the world, but `{}` moves", parent.name),
                ));
            };
            if j.pos != Vec3::zeros() {
                return Err(self.unsupported(j.node, "a free joint with a `pos`"));
            }
            // The joint frame is the world frame, so that q is the body's world pose (MuJoCo's qpos).
            let mut spec = BodySpec::new(
                name.clone(),
                parent.spec.clone(),
                Joint::Free,
                (parent_world * parent.offset.inverse()).inverse(),
                inertia,
            )
            .with_joint_name(j.name.clone());
            spec.dynamics = j.dynamics;
            self.attach(&mut spec, geoms, Transform::identity());
            self.free_bodies.push((name.clone(), parent_world * pose));
            self.record_joint(j, &name, element);
            self.specs.push(spec);
            (name.clone(), Transform::identity(), None)
        } else {
            let mut prev_spec = parent.spec.clone();
            let mut prev_pos = Vec3::zeros();
            for (k, j) in joints.iter().enumerate() {
                let last = k + 1 == n;
                let spec_name = if last { name.clone() } else { format!("{name}__{}", j.name) };
                let placement = if k == 0 {
                    placement * Transform::from_translation(j.pos)
                } else {
                    Transform::from_translation(j.pos - prev_pos)
                };
                let mut spec = BodySpec::new(
                    spec_name.clone(),
                    prev_spec.clone(),
                    j.joint,
                    placement,
                    if last { shifted(&inertia, &j.pos) } else { RigidInertia::massless() },
                )
                .with_joint_name(j.name.clone())
                .with_limits(j.limits.clone());
                spec.dynamics = j.dynamics;
                if last {
                    self.attach(&mut spec, std::mem::take(&mut geoms), Transform::from_translation(-j.pos));
                }
                self.record_joint(j, &spec_name, element);
                self.specs.push(spec);
                prev_spec = spec_name;
                prev_pos = j.pos;
            }
            (name.clone(), Transform::from_translation(-prev_pos), None)
        };
        self.bodies.push((name.clone(), spec_name.clone(), offset));
        Ok((Parent { spec: spec_name, offset, world, name }, children.bodies))
    }

    fn record_joint(&mut self, j: &JointRead, spec: &str, body_element: NodeId) {
        self.joint_damping.push((j.name.clone(), j.dynamics.damping));
        self.joint_armature.push((j.name.clone(), j.armature));
        self.joint_elements.insert(j.name.clone(), j.node.id());
        self.body_elements.insert(spec.to_string(), body_element);
    }

    /// Puts body geoms on a spec, `offset` being the pose of the MJCF body frame in the spec frame.
    fn attach(&mut self, spec: &mut BodySpec, geoms: Vec<Geom>, offset: Transform) {
        for g in geoms {
            let role = if g.collides { GeometryRole::Collision } else { GeometryRole::Visual };
            spec.geometries.push(GeometrySpec {
                link: spec.name.clone(),
                role,
                shape: g.shape,
                placement: offset * g.pose,
                body: 0,
            });
            self.geoms.push(GeomInfo { name: g.name, friction: g.friction });
        }
    }

    fn add_statics(&mut self, geoms: Vec<Geom>, world: &Transform) {
        for g in geoms {
            self.statics.push(StaticGeometry {
                name: g.name,
                shape: g.shape,
                pose: world * &g.pose,
                friction: g.friction,
                collides: g.collides,
            });
        }
    }

    fn inertial(&self, node: Node) -> Result<RigidInertia, MjcfError> {
        let k = Kind::None;
        let pose = self.pose(node, k, "main")?;
        if node.attribute("pos").is_none() {
            return Err(self.missing(node, "pos"));
        }
        let mass = self.non_negative(node, k, "main", "mass")?.ok_or_else(|| self.missing(node, "mass"))?;
        let local =
            match (self.vector::<3>(node, k, "diaginertia")?, self.vector::<6>(node, k, "fullinertia")?) {
                (Some(d), None) => Mat3::from_diagonal(&Vec3::from(d)),
                (None, Some(f)) => Mat3::new(f[0], f[3], f[4], f[3], f[1], f[5], f[4], f[5], f[2]),
                (None, None) => return Err(self.missing(node, "diaginertia")),
                (Some(_), Some(_)) => {
                    return Err(self.invalid(node, "both diaginertia and fullinertia are given"))
                }
            };
        Ok(RigidInertia::new(mass, pose.translation, pose.rotation * local * pose.rotation.transpose()))
    }

    fn joint(
        &self,
        node: Node<'a, 'i>,
        body_class: &str,
        default_name: String,
    ) -> Result<JointRead<'a, 'i>, MjcfError> {
        let name = node.attribute("name").map(str::to_string).unwrap_or(default_name);
        if node.tag_name().name() == "freejoint" {
            // <freejoint> takes no defaults.
            return Ok(JointRead {
                node,
                name,
                joint: Joint::Free,
                pos: Vec3::zeros(),
                limits: JointLimits::default(),
                dynamics: JointDynamics::default(),
                armature: 0.0,
            });
        }
        let k = Kind::Joint;
        let class = self.class_of(node, body_class)?;
        let c = class.as_str();
        let kind = self.get(node, k, c, "type").unwrap_or_else(|| "hinge".to_string());
        let axis = Vec3::from(self.vector_c::<3>(node, k, c, "axis")?.unwrap_or([0.0, 0.0, 1.0]));
        if matches!(kind.as_str(), "hinge" | "slide") && axis.norm() < 1e-12 {
            let text = self.get(node, k, c, "axis").unwrap_or_default();
            return Err(self.bad_attr(node, "axis", &text, "the axis is zero"));
        }
        let joint = match kind.as_str() {
            "hinge" => Joint::Hinge { axis },
            "slide" => Joint::Slider { axis },
            "ball" => Joint::Ball,
            "free" => Joint::Free,
            _ => return Err(self.bad_attr(node, "type", &kind, "expected hinge, slide, ball or free")),
        };
        for a in ["stiffness", "ref"] {
            if self.scalar_c(node, k, c, a)?.is_some_and(|x| x != 0.0) {
                return Err(
                    self.unsupported(node, &format!("joint `{a}` (gelenk has no joint springs or offsets)"))
                );
            }
        }
        let range = self.vector_c::<2>(node, k, c, "range")?;
        let limited = match self.get(node, k, c, "limited").as_deref() {
            None | Some("auto") => self.compiler.autolimits && range.is_some(),
            Some(t) => self.boolean(node, "limited", t)?,
        };
        let mut limits = JointLimits::default();
        if limited && matches!(joint, Joint::Hinge { .. } | Joint::Slider { .. }) {
            let Some([lo, hi]) = range else { return Err(self.missing(node, "range")) };
            if lo > hi {
                let text = self.get(node, k, c, "range").unwrap_or_default();
                return Err(self.bad_attr(node, "range", &text, "lower bound above upper bound"));
            }
            let (lo, hi) = if matches!(joint, Joint::Hinge { .. }) {
                (self.angle(lo), self.angle(hi))
            } else {
                (lo, hi)
            };
            limits.lower = vec![lo];
            limits.upper = vec![hi];
        }
        let dynamics = JointDynamics {
            damping: self.non_negative(node, k, c, "damping")?.unwrap_or(0.0),
            friction: self.non_negative(node, k, c, "frictionloss")?.unwrap_or(0.0),
        };
        Ok(JointRead {
            node,
            name,
            joint,
            pos: Vec3::from(self.vector_c::<3>(node, k, c, "pos")?.unwrap_or_default()),
            limits,
            dynamics,
            armature: self.non_negative(node, k, c, "armature")?.unwrap_or(0.0),
        })
    }

    // ----- model ------------------------------------------------------------------------------

    fn finish(
        mut self,
        timestep: f64,
        gravity: Vec3,
        contact_enabled: bool,
        friction: FrictionModel,
        excludes: Vec<(String, String, String)>,
    ) -> Result<MjcfScene, MjcfError> {
        // An exclude naming no body is a typo that would silently let the pair collide.
        for (a, b, element) in &excludes {
            if let Some(name) =
                [a, b].into_iter().find(|n| *n != "world" && !self.specs.iter().any(|s| s.name == **n))
            {
                return Err(MjcfError::Invalid {
                    file: self.file.to_string(),
                    element: element.clone(),
                    what: format!("`{name}` is not a body of the model"),
                });
            }
        }
        let contact_excludes: Vec<(String, String)> = excludes.into_iter().map(|(a, b, _)| (a, b)).collect();
        if self.compiler.settotalmass > 0.0 {
            let total: f64 = self.specs.iter().map(|s| s.inertia.mass).sum();
            if total > 0.0 {
                let f = self.compiler.settotalmass / total;
                for s in &mut self.specs {
                    s.inertia.mass *= f;
                    s.inertia.inertia_com *= f;
                }
            }
        }
        for s in std::mem::take(&mut self.specs) {
            self.builder.add_body(s);
        }
        let model = self.builder.build().map_err(|source| {
            let joint = match &source {
                ModelError::InvalidAxis { joint, .. }
                | ModelError::ParallelAxes { joint }
                | ModelError::NonFinitePlacement { joint }
                | ModelError::InvalidLimits { joint, .. }
                | ModelError::InvalidSuspension { joint }
                | ModelError::DuplicateName { what: "joint", name: joint } => Some(joint),
                _ => None,
            };
            let body = match &source {
                ModelError::DuplicateName { what: "body", name: body }
                | ModelError::InvalidMass { body, .. }
                | ModelError::NonFiniteInertia { body }
                | ModelError::InertiaNotSymmetric { body }
                | ModelError::InertiaNotPositive { body, .. }
                | ModelError::InertiaTriangleInequality { body, .. }
                | ModelError::UnknownParent { body, .. }
                | ModelError::Cycle { body } => Some(body),
                _ => None,
            };
            let element = joint
                .and_then(|j| self.joint_elements.get(j))
                .or_else(|| body.and_then(|b| self.body_elements.get(b)))
                .map_or_else(|| "<worldbody>".to_string(), |id| self.describe_id(*id));
            MjcfError::Model { file: self.file.to_string(), element, source }
        })?;
        debug_assert_eq!(model.geometries().len(), self.geoms.len());

        let mut q0 = model.neutral_configuration();
        for (name, pose) in &self.free_bodies {
            if let Some(b) = model.body_id(name) {
                let a = model.idx_q(b);
                q0.as_mut_slice()[a..a + 3].copy_from_slice(pose.translation.as_slice());
                q0.as_mut_slice()[a + 3..a + 7].copy_from_slice(&pose.quaternion_xyzw());
            }
        }
        let body_frames: HashMap<&str, &crate::model::Frame> = model
            .frames()
            .iter()
            .filter(|f| f.kind == FrameKind::Body)
            .map(|f| (f.name.as_str(), f))
            .collect();
        let bodies = self
            .bodies
            .iter()
            .map(|(name, spec, offset)| {
                let frame = body_frames.get(spec.as_str());
                let (body, placement) =
                    frame.map(|f| (f.body, f.placement * *offset)).unwrap_or((0, *offset));
                MjcfBody { name: name.clone(), body, placement }
            })
            .collect();
        Ok(MjcfScene {
            model,
            statics: self.statics,
            timestep,
            gravity,
            contact_enabled,
            friction,
            joint_damping: self.joint_damping,
            joint_armature: self.joint_armature,
            geoms: self.geoms,
            bodies,
            contact_excludes,
            q0,
        })
    }
}

/// A joint element, read.
struct JointRead<'a, 'i> {
    node: Node<'a, 'i>,
    name: String,
    joint: Joint,
    pos: Vec3,
    limits: JointLimits,
    dynamics: JointDynamics,
    armature: f64,
}

/// MuJoCo's `mjuu_z2quat`: the smallest rotation taking +z to the unit vector `z` (a half turn
/// about x when `z` is −z).
fn z_to(z: &Vec3) -> Mat3 {
    let cross = Vec3::z().cross(z);
    let s = cross.norm();
    let axis = if s < 1e-10 { Vec3::x() } else { cross / s };
    crate::math::axis_angle(&axis, s.atan2(z.z))
}

/// The mass properties of a set of geoms, in the body frame (MuJoCo's sum with the parallel-axis
/// theorem).
fn combine(geoms: &[Geom]) -> RigidInertia {
    let mass: f64 = geoms.iter().map(|g| g.mass).sum();
    if mass <= 0.0 {
        return RigidInertia::massless();
    }
    let com = geoms.iter().map(|g| g.pose.translation * g.mass).sum::<Vec3>() / mass;
    let mut inertia = Mat3::zeros();
    for g in geoms {
        let r = &g.pose.rotation;
        let d = g.pose.translation - com;
        inertia += r * Mat3::from_diagonal(&g.moments) * r.transpose()
            + (Mat3::identity() * d.norm_squared() - d * d.transpose()) * g.mass;
    }
    RigidInertia::new(mass, com, (inertia + inertia.transpose()) * 0.5)
}

/// The same mass properties in a frame translated by `p` (the joint frame at `p`).
fn shifted(inertia: &RigidInertia, p: &Vec3) -> RigidInertia {
    RigidInertia { com: inertia.com - p, ..*inertia }
}
