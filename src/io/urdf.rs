//! URDF models through `urdf-rs`, with gelenk's extension for universal and hinge2 joints.
//!
//! Mapping: `revolute`/`continuous` → hinge, `prismatic` → slider, `fixed` → fused into the
//! parent, `floating` → free, `planar` → planar (the URDF axis is the plane normal), `spherical`
//! → ball. Axes are normalized. The inertial origin's rotation is applied to the inertia tensor.
//! Joints are numbered depth-first in the order the file lists them (Pinocchio's order). Position
//! limits of `continuous` joints are ignored; a `<limit>` of zero velocity or zero effort, and a
//! zero-width position range, mean "not given". Collision and visual shapes are kept in the model
//! ([`crate::model::GeometrySpec`]); no mesh file is opened. `<mimic>` is not modelled: the
//! joint moves on its own.
//!
//! A misspelt child of `<joint>`, `<link>` or `<inertial>`, or a misspelt attribute of `<origin>`,
//! `<axis>`, `<parent>`, `<child>`, `<mass>` or `<inertia>`, is an error ([`UrdfError::Parse`],
//! naming the element and its line), where urdf-rs alone would read the default (an `<axiss>`
//! leaves the axis at x, an `<inertail>` leaves the link massless). Vendors' extra attributes on
//! `<limit>`, `<dynamics>` and the like, PyBullet's `<contact>` in a link and elements in an XML
//! namespace (Drake's `drake:…`) load.
//!
//! ## Extension: universal and hinge2 joints
//! URDF has neither. gelenk reads an extra element, a direct child of `<robot>`, that standard
//! parsers ignore (as they ignore `<gazebo>`), and declares the joint itself as a standard
//! `revolute` or `continuous` joint about the first axis, so other tools still load the model
//! (with one rotation instead of two):
//!
//! ```xml
//! <joint name="hip" type="continuous"> <!-- axis 1, fixed in the parent -->
//!   <parent link="pelvis"/> <child link="thigh"/> <axis xyz="1 0 0"/>
//! </joint>
//! <gelenk joint="hip" type="universal" axis2="0 1 0" lower2="-1" upper2="1"/>
//!
//! <joint name="front_left" type="continuous"> <!-- steering axis -->
//!   <parent link="chassis"/> <child link="wheel_fl"/> <axis xyz="0 0 1"/>
//!   <limit lower="-0.6" upper="0.6" effort="50" velocity="5"/>
//! </joint>
//! <gelenk joint="front_left" type="hinge2" axis2="0 1 0"
//!         suspension_stiffness="20000" suspension_damping="800"
//!         suspension_lower="-0.1" suspension_upper="0.1"/>
//! ```
//! `axis2` is in the child frame. For hinge2, giving `suspension_stiffness` (N/m) adds the
//! suspension travel coordinate along axis 1 (q = [s, θ₁, θ₂]); `suspension_damping` (N·s/m)
//! defaults to 0. The `<limit>` of the joint applies to axis 1 (steering); `lower2`/`upper2`
//! to axis 2.
//!
//! ## Extension: ball-joint limits
//! A `spherical` joint takes anatomical limits ([`crate::model::BallLimits`]): a swing cone of
//! half-angle `swing` (rad) about `twist_axis` (joint frame, default `0 0 1`) and a twist range
//! `[twist_lower, twist_upper]` (rad, default ±π) about it:
//!
//! ```xml
//! <joint name="neck" type="spherical"><parent link="chest"/><child link="head"/></joint>
//! <gelenk joint="neck" type="ball" twist_axis="0 0 1" swing="0.7" twist_lower="-0.6" twist_upper="0.6"/>
//! ```

use crate::error::ModelError;
use crate::math::{Mat3, Transform, Vec3};
use crate::model::{
    BallLimits, BodySpec, GeometryRole, GeometrySpec, Joint, JointDynamics, JointLimits, Model, ModelBuilder,
    RigidInertia, Shape, Suspension,
};
use std::collections::HashMap;
use std::path::Path;
use thiserror::Error;

/// Options for loading a URDF model.
#[derive(Clone, Debug, PartialEq)]
pub struct UrdfOptions {
    /// Attach the root link to the world by a free joint (floating base) instead of fixing it.
    pub floating_base: bool,
    /// Name of the joint that attaches the root link to the world.
    pub root_joint_name: String,
}

impl Default for UrdfOptions {
    fn default() -> Self {
        Self { floating_base: false, root_joint_name: "root_joint".to_string() }
    }
}

impl UrdfOptions {
    /// Default options with a free joint at the root.
    pub fn floating() -> Self {
        Self { floating_base: true, ..Self::default() }
    }
}

/// A URDF file that cannot become a model. Every variant names the file (`<string>` for text).
#[derive(Debug, Error)]
pub enum UrdfError {
    /// The file could not be read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// File path.
        file: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Not well-formed XML or not a URDF robot; the parser's own text is kept.
    #[error("{file}: not a valid URDF document: {message}")]
    Parse {
        /// File path.
        file: String,
        /// urdf-rs's (or the XML parser's) message.
        message: String,
    },
    /// A joint element is inconsistent (unknown link, second parent, bad extension, …).
    #[error("{file}: joint `{joint}`: {what}")]
    Joint {
        /// File path.
        file: String,
        /// Joint name.
        joint: String,
        /// What is wrong.
        what: String,
    },
    /// The links do not form one tree.
    #[error("{file}: {what}")]
    Tree {
        /// File path.
        file: String,
        /// What is wrong.
        what: String,
    },
    /// The description is well-formed but the model is invalid (mass, inertia, axis, …).
    #[error("{file}: {source}")]
    Model {
        /// File path.
        file: String,
        /// The model error, naming the link or joint.
        source: ModelError,
    },
}

/// Loads a URDF file.
pub fn load_file(path: impl AsRef<Path>, options: &UrdfOptions) -> Result<Model, UrdfError> {
    let path = path.as_ref();
    let file = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|source| UrdfError::Io { file: file.clone(), source })?;
    let mut model = load_named(&text, &file, options)?;
    model.source_dir = Some(path.parent().map(Path::to_path_buf).unwrap_or_default());
    Ok(model)
}

/// Loads a URDF document from text.
pub fn load_str(text: &str, options: &UrdfOptions) -> Result<Model, UrdfError> {
    load_named(text, "<string>", options)
}

struct Extension {
    kind: String,
    axis2: Vec3,
    lower2: f64,
    upper2: f64,
    suspension: Option<Suspension>,
    suspension_range: (f64, f64),
    ball: Option<BallLimits>,
}

fn load_named(text: &str, file: &str, options: &UrdfOptions) -> Result<Model, UrdfError> {
    let parse_err = |message: String| UrdfError::Parse { file: file.to_string(), message };
    // roxmltree first: it reports malformed XML with a position, and it reads our extension.
    let doc = roxmltree::Document::parse(text).map_err(|e| parse_err(e.to_string()))?;
    if doc.root_element().tag_name().name() != "robot" {
        return Err(parse_err(format!(
            "root element is <{}>, expected <robot>",
            doc.root_element().tag_name().name()
        )));
    }
    check_physics_elements(&doc, file)?;
    let extensions = read_extensions(&doc, file)?;
    let robot = urdf_rs::read_from_string(text).map_err(|e| parse_err(e.to_string()))?;

    let tree_err = |what: String| UrdfError::Tree { file: file.to_string(), what };
    let links: HashMap<&str, &urdf_rs::Link> = robot.links.iter().map(|l| (l.name.as_str(), l)).collect();
    if links.len() != robot.links.len() {
        return Err(tree_err("two links share a name".to_string()));
    }
    let mut parent_joint: HashMap<&str, &str> = HashMap::new();
    for j in &robot.joints {
        for link in [&j.parent.link, &j.child.link] {
            if !links.contains_key(link.as_str()) {
                return Err(UrdfError::Joint {
                    file: file.into(),
                    joint: j.name.clone(),
                    what: format!("unknown link `{link}`"),
                });
            }
        }
        if let Some(other) = parent_joint.insert(j.child.link.as_str(), j.name.as_str()) {
            return Err(UrdfError::Joint {
                file: file.into(),
                joint: j.name.clone(),
                what: format!("link `{}` already has parent joint `{other}`", j.child.link),
            });
        }
    }
    for name in extensions.keys() {
        if !robot.joints.iter().any(|j| &j.name == name) {
            return Err(UrdfError::Joint {
                file: file.into(),
                joint: name.clone(),
                what: "a <gelenk> extension names a joint that does not exist".into(),
            });
        }
    }
    let roots: Vec<&urdf_rs::Link> =
        robot.links.iter().filter(|l| !parent_joint.contains_key(l.name.as_str())).collect();
    let root = match roots.as_slice() {
        [root] => *root,
        [] if robot.links.is_empty() => return Err(tree_err("the robot has no link".into())),
        [] => return Err(tree_err("every link has a parent joint: the joints form a cycle".into())),
        many => {
            let names: Vec<&str> = many.iter().map(|l| l.name.as_str()).collect();
            return Err(tree_err(format!(
                "several root links ({}): the links do not form one tree",
                names.join(", ")
            )));
        }
    };

    let mut builder = ModelBuilder::new();
    builder.name(robot.name.clone());
    let root_joint = if options.floating_base { Joint::Free } else { Joint::Fixed };
    builder.add_body(
        link_body(root, "universe", root_joint, Transform::identity())
            .with_joint_name(options.root_joint_name.clone()),
    );
    for j in &robot.joints {
        let child = links[j.child.link.as_str()];
        let placement = pose(&j.origin);
        let axis = Vec3::from(j.axis.xyz.0);
        let mut body =
            link_body(child, &j.parent.link, Joint::Fixed, placement).with_joint_name(j.name.clone());
        let joint_err = |what: String| UrdfError::Joint { file: file.into(), joint: j.name.clone(), what };
        let lim = &j.limit;
        let given = |x: f64| if x > 0.0 && x.is_finite() { x } else { f64::INFINITY };
        // Equal bounds (urdf-rs reads a missing one as 0) mean no limit; inverted or NaN bounds
        // are an error where the joint has a range (revolute and prismatic).
        let range = || {
            if lim.lower.is_nan() || lim.upper.is_nan() || lim.lower > lim.upper {
                Err(joint_err(format!(
                    "<limit lower=\"{}\" upper=\"{}\">: lower must not exceed upper (equal bounds: no limit)",
                    lim.lower, lim.upper
                )))
            } else if lim.lower < lim.upper {
                Ok((lim.lower, lim.upper))
            } else {
                Ok((f64::NEG_INFINITY, f64::INFINITY))
            }
        };
        let (velocity, effort) = (given(lim.velocity), given(lim.effort));
        let dynamics = j
            .dynamics
            .as_ref()
            .map(|d| JointDynamics { damping: d.damping, friction: d.friction })
            .unwrap_or_default();
        body.dynamics = dynamics;
        use urdf_rs::JointType as T;
        match &j.joint_type {
            T::Revolute | T::Continuous => {
                let range =
                    if j.joint_type == T::Continuous { (f64::NEG_INFINITY, f64::INFINITY) } else { range()? };
                match extensions.get(&j.name) {
                    None => {
                        body.joint = Joint::Hinge { axis };
                        body.limits = limits(&[range], velocity, effort, 1);
                    }
                    Some(ext) if ext.kind == "ball" => {
                        return Err(joint_err(format!(
                            "a <gelenk> ball extension needs a spherical joint, not {:?}",
                            j.joint_type
                        )))
                    }
                    Some(ext) if ext.kind == "universal" => {
                        body.joint = Joint::Universal { axis1: axis, axis2: ext.axis2 };
                        body.limits = limits(&[range, (ext.lower2, ext.upper2)], velocity, effort, 2);
                    }
                    Some(ext) => {
                        body.joint = Joint::Hinge2 { axis1: axis, axis2: ext.axis2, suspension: ext.suspension };
                        let spin = (ext.lower2, ext.upper2);
                        body.limits = if ext.suspension.is_some() {
                            limits(&[ext.suspension_range, range, spin], velocity, effort, 3)
                        } else {
                            limits(&[range, spin], velocity, effort, 2)
                        };
                    }
                }
            }
            T::Spherical => {
                body.joint = Joint::Ball;
                match extensions.get(&j.name) {
                    Some(ext) if ext.kind == "ball" => body.ball_limits = ext.ball,
                    Some(ext) => {
                        return Err(joint_err(format!(
                            "a <gelenk> {} extension needs a revolute or continuous joint, not spherical",
                            ext.kind
                        )))
                    }
                    None => {}
                }
            }
            other if extensions.get(&j.name).is_some_and(|e| e.kind == "ball") => {
                return Err(joint_err(format!("a <gelenk> ball extension needs a spherical joint, not {other:?}")))
            }
            other if extensions.contains_key(&j.name) => {
                return Err(joint_err(format!(
                    "a <gelenk> universal or hinge2 extension needs a revolute or continuous joint, not {other:?}"
                )))
            }
            T::Prismatic => {
                body.joint = Joint::Slider { axis };
                body.limits = limits(&[range()?], velocity, effort, 1);
            }
            T::Fixed => {}
            T::Floating => body.joint = Joint::Free,
            T::Planar => {
                let n = axis.try_normalize(1e-12).ok_or_else(|| joint_err("planar joint with a zero normal axis".into()))?;
                let align = nalgebra::Rotation3::rotation_between(&Vec3::z(), &n)
                    .unwrap_or_else(|| nalgebra::Rotation3::from_axis_angle(&Vec3::x_axis(), std::f64::consts::PI))
                    .into_inner();
                if (align - Mat3::identity()).amax() < 1e-15 {
                    body.joint = Joint::Planar;
                } else {
                    // The planar joint moves in its frame's xy-plane: turn that frame so that z is the
                    // URDF normal, and attach the link back through a fixed rotation.
                    let carrier = format!("{}__planar", child.name);
                    let mut carrier_body = BodySpec::new(
                        carrier.clone(),
                        j.parent.link.clone(),
                        Joint::Planar,
                        placement * Transform::new(align, Vec3::zeros()),
                        RigidInertia::massless(),
                    )
                    .with_joint_name(j.name.clone());
                    carrier_body.dynamics = dynamics;
                    builder.add_body(carrier_body);
                    body.dynamics = JointDynamics::default();
                    body.parent = carrier;
                    body.placement = Transform::new(align.transpose(), Vec3::zeros());
                    body.joint_name = format!("{}__planar_fixed", j.name);
                }
            }
        }
        builder.add_body(body);
    }
    builder.build().map_err(|source| UrdfError::Model { file: file.to_string(), source })
}

fn limits(ranges: &[(f64, f64)], velocity: f64, effort: f64, nv: usize) -> JointLimits {
    JointLimits {
        lower: ranges.iter().map(|r| r.0).collect(),
        upper: ranges.iter().map(|r| r.1).collect(),
        velocity: vec![velocity; nv],
        effort: vec![effort; nv],
    }
}

fn pose(p: &urdf_rs::Pose) -> Transform {
    Transform::from_xyz_rpy(p.xyz.0, p.rpy.0)
}

fn link_body(link: &urdf_rs::Link, parent: &str, joint: Joint, placement: Transform) -> BodySpec {
    let inertial = &link.inertial;
    let frame = pose(&inertial.origin);
    let i = &inertial.inertia;
    let local = Mat3::new(i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz);
    let inertia = RigidInertia::new(
        inertial.mass.value,
        frame.translation,
        frame.rotation * local * frame.rotation.transpose(),
    );
    let mut body = BodySpec::new(link.name.clone(), parent, joint, placement, inertia);
    let shapes = link
        .collision
        .iter()
        .map(|c| (GeometryRole::Collision, &c.origin, &c.geometry))
        .chain(link.visual.iter().map(|v| (GeometryRole::Visual, &v.origin, &v.geometry)));
    for (role, origin, geometry) in shapes {
        let shape = match geometry {
            urdf_rs::Geometry::Box { size } => Shape::Box { size: Vec3::from(size.0) },
            urdf_rs::Geometry::Cylinder { radius, length } => {
                Shape::Cylinder { radius: *radius, length: *length }
            }
            urdf_rs::Geometry::Capsule { radius, length } => {
                Shape::Capsule { radius: *radius, length: *length }
            }
            urdf_rs::Geometry::Sphere { radius } => Shape::Sphere { radius: *radius },
            urdf_rs::Geometry::Mesh { filename, scale } => Shape::Mesh {
                uri: filename.clone(),
                scale: scale.map(|s| Vec3::from(s.0)).unwrap_or_else(|| Vec3::repeat(1.0)),
            },
        };
        body.geometries.push(GeometrySpec {
            link: link.name.clone(),
            role,
            shape,
            placement: pose(origin),
            body: 0,
        });
    }
    body
}

/// The children of `<joint>`, `<link>` and `<inertial>`, and the attributes of the elements
/// whose attributes URDF closes (`origin`, `axis`, `parent`, `child`, `mass`, `inertia`), are
/// URDF's (its specification; `<contact>` in a link is PyBullet's, read past). A parser that
/// ignores the unknown turns a misspelling into a silent default (`<axiss>` or `<axis xzy=…>`
/// leaves the axis at x, `<inertail>` leaves the link massless): here it is an error.
/// `<limit>`, `<dynamics>` and the others keep vendors' extra attributes (Franka's panda.urdf
/// writes `D`, `K`, `mu_coulomb` on `<dynamics>`).
fn check_physics_elements(doc: &roxmltree::Document, file: &str) -> Result<(), UrdfError> {
    // (tag, its attributes if URDF closes them)
    type Known<'k> = &'k [(&'k str, Option<&'k [&'k str]>)];
    const ORIGIN: (&str, Option<&[&str]>) = ("origin", Some(&["xyz", "rpy"]));
    const JOINT: Known = &[
        ORIGIN,
        ("parent", Some(&["link"])),
        ("child", Some(&["link"])),
        ("axis", Some(&["xyz"])),
        ("calibration", None),
        ("dynamics", None),
        ("limit", None),
        ("mimic", None),
        ("safety_controller", None),
    ];
    const INERTIAL: Known =
        &[ORIGIN, ("mass", Some(&["value"])), ("inertia", Some(&["ixx", "ixy", "ixz", "iyy", "iyz", "izz"]))];
    const LINK: Known = &[("inertial", None), ("visual", None), ("collision", None), ("contact", None)];
    let error = |node: roxmltree::Node, what: String| UrdfError::Parse {
        file: file.to_string(),
        message: format!("{}: {what}", super::describe_element(doc, node)),
    };
    // The element's children are among `known` (tag, attributes), each with known attributes.
    let check = |node: roxmltree::Node, known: Known| -> Result<(), UrdfError> {
        // Elements in a namespace are some tool's extension (Drake's `drake:` ones): read past.
        for child in node.children().filter(|c| c.is_element() && c.tag_name().namespace().is_none()) {
            let tag = child.tag_name().name();
            let Some((_, attributes)) = known.iter().find(|(t, _)| *t == tag) else {
                let names: Vec<&str> = known.iter().map(|(t, _)| *t).collect();
                return Err(error(
                    node,
                    format!(
                        "unknown element <{tag}> (URDF's <{}> has {})",
                        node.tag_name().name(),
                        names.join(", ")
                    ),
                ));
            };
            let Some(attributes) = attributes else { continue };
            if let Some(a) = child.attributes().find(|a| !attributes.contains(&a.name())) {
                return Err(error(
                    child,
                    format!(
                        "unknown attribute `{}` (URDF's <{tag}> has {})",
                        a.name(),
                        attributes.join(", ")
                    ),
                ));
            }
        }
        Ok(())
    };
    for node in doc.root_element().children().filter(roxmltree::Node::is_element) {
        match node.tag_name().name() {
            "joint" => check(node, JOINT)?,
            "link" => {
                check(node, LINK)?;
                for inertial in node.children().filter(|c| c.has_tag_name("inertial")) {
                    check(inertial, INERTIAL)?;
                }
            }
            _ => {}
        }
    }
    Ok(())
}

fn read_extensions(doc: &roxmltree::Document, file: &str) -> Result<HashMap<String, Extension>, UrdfError> {
    let mut out = HashMap::new();
    for node in doc.root_element().children().filter(|n| n.has_tag_name("gelenk")) {
        let joint = node.attribute("joint").unwrap_or_default().to_string();
        let err = |what: String| UrdfError::Joint { file: file.into(), joint: joint.clone(), what };
        if joint.is_empty() {
            return Err(err("a <gelenk> extension element needs a `joint` attribute".into()));
        }
        let number = |name: &str, default: f64| -> Result<f64, UrdfError> {
            match node.attribute(name) {
                None => Ok(default),
                Some(t) => t
                    .trim()
                    .parse::<f64>()
                    .map_err(|_| err(format!("attribute {name}=\"{t}\" is not a number"))),
            }
        };
        let kind = node.attribute("type").unwrap_or_default().to_string();
        if kind != "universal" && kind != "hinge2" && kind != "ball" {
            return Err(err(format!("<gelenk> type \"{kind}\" is not `universal`, `hinge2` or `ball`")));
        }
        let vector = |name: &str, text: &str| -> Result<Vec3, UrdfError> {
            let parts: Vec<f64> = text
                .split_whitespace()
                .map(str::parse)
                .collect::<Result<_, _>>()
                .map_err(|_| err(format!("{name}=\"{text}\" is not three numbers")))?;
            if parts.len() != 3 {
                return Err(err(format!("{name}=\"{text}\" is not three numbers")));
            }
            Ok(Vec3::new(parts[0], parts[1], parts[2]))
        };
        if kind == "ball" {
            let pi = std::f64::consts::PI;
            let ball = BallLimits {
                twist_axis: vector("twist_axis", node.attribute("twist_axis").unwrap_or("0 0 1"))?,
                swing: number("swing", pi)?,
                twist_lower: number("twist_lower", -pi)?,
                twist_upper: number("twist_upper", pi)?,
            };
            let ext = Extension {
                kind,
                axis2: Vec3::zeros(),
                lower2: f64::NEG_INFINITY,
                upper2: f64::INFINITY,
                suspension: None,
                suspension_range: (f64::NEG_INFINITY, f64::INFINITY),
                ball: Some(ball),
            };
            if out.insert(joint.clone(), ext).is_some() {
                return Err(err("two <gelenk> extension elements name this joint".into()));
            }
            continue;
        }
        let axis_text =
            node.attribute("axis2").ok_or_else(|| err("<gelenk> needs an `axis2` attribute".into()))?;
        let axis2 = vector("axis2", axis_text)?;
        let suspension = match node.attribute("suspension_stiffness") {
            Some(_) if kind == "hinge2" => Some(Suspension {
                stiffness: number("suspension_stiffness", 0.0)?,
                damping: number("suspension_damping", 0.0)?,
            }),
            Some(_) => return Err(err("suspension attributes apply to hinge2 joints only".into())),
            None => None,
        };
        let ext = Extension {
            kind,
            axis2,
            lower2: number("lower2", f64::NEG_INFINITY)?,
            upper2: number("upper2", f64::INFINITY)?,
            suspension,
            suspension_range: (
                number("suspension_lower", f64::NEG_INFINITY)?,
                number("suspension_upper", f64::INFINITY)?,
            ),
            ball: None,
        };
        if out.insert(joint.clone(), ext).is_some() {
            return Err(err("two <gelenk> extension elements name this joint".into()));
        }
    }
    Ok(out)
}
