//! Reading a URDF document into plain descriptions, as ROS's urdfdom reads it: the first of a
//! repeated element counts, an element or attribute URDF does not define is read past, a missing
//! optional value takes URDF's default. Each of these is a [`UrdfWarning`] (an error with
//! [`super::UrdfOptions::strict`]); what makes the document unusable (a number that is not one, a
//! joint without a parent link, an unknown joint type) is an error in both modes.

use super::{UrdfError, UrdfWarning, WarningKind};
use crate::math::{Transform, Vec3};
use crate::model::{GeometryRole, Shape};

/// A `<link>`.
pub(super) struct LinkDesc {
    pub name: String,
    /// Line of the `<link>` element (1-based).
    pub line: usize,
    /// Mass (kg); 0 without `<inertial>`.
    pub mass: f64,
    /// Pose of the inertial frame in the link frame.
    pub inertial_origin: Transform,
    /// `ixx, ixy, ixz, iyy, iyz, izz` in the inertial frame (kg·m²).
    pub inertia: [f64; 6],
    /// Collision and visual shapes with their pose in the link frame.
    pub geometries: Vec<(GeometryRole, Transform, Shape)>,
}

/// URDF's joint types.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum JointType {
    Revolute,
    Continuous,
    Prismatic,
    Fixed,
    Floating,
    Planar,
    Spherical,
}

/// A `<limit>`; a missing attribute is 0 (as a missing `<limit>`).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct LimitDesc {
    pub lower: f64,
    pub upper: f64,
    pub effort: f64,
    pub velocity: f64,
}

/// A `<joint>`.
pub(super) struct JointDesc {
    pub name: String,
    /// Line of the `<joint>` element (1-based).
    pub line: usize,
    pub kind: JointType,
    /// Pose of the joint frame in the parent link frame.
    pub origin: Transform,
    pub parent: String,
    pub child: String,
    /// Axis in the joint frame (x when not given), not normalized.
    pub axis: Vec3,
    pub limit: LimitDesc,
    /// `(damping, friction)` of `<dynamics>`.
    pub dynamics: Option<(f64, f64)>,
}

/// The links and joints of a `<robot>`, in document order.
pub(super) struct RobotDesc {
    pub name: String,
    pub links: Vec<LinkDesc>,
    pub joints: Vec<JointDesc>,
}

/// Known children of an element: (tag, `Some(attributes)` when URDF closes them).
type Known<'k> = &'k [(&'k str, Option<&'k [&'k str]>)];

const ORIGIN: (&str, Option<&[&str]>) = ("origin", Some(&["xyz", "rpy"]));
/// `<robot>`'s children; `transmission`, `gazebo`, `material` and `sensor` are ROS's, read past
/// here; `gelenk` is ours ([`super::extension`]).
const ROBOT: Known = &[
    ("link", None),
    ("joint", None),
    ("material", None),
    ("transmission", None),
    ("gazebo", None),
    ("sensor", None),
    ("gelenk", None),
];
const LINK: Known = &[("inertial", None), ("visual", None), ("collision", None), ("contact", None)];
const INERTIAL: Known =
    &[ORIGIN, ("mass", Some(&["value"])), ("inertia", Some(&["ixx", "ixy", "ixz", "iyy", "iyz", "izz"]))];
const VISUAL: Known = &[ORIGIN, ("geometry", None), ("material", None)];
const COLLISION: Known = &[ORIGIN, ("geometry", None)];
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
/// Elements that may appear once; a repeat is read past (urdfdom reads the first).
const SINGLE: &[&str] =
    &["inertial", "origin", "mass", "inertia", "geometry", "parent", "child", "axis", "limit", "dynamics"];

pub(super) struct Reader<'a, 'input> {
    doc: &'a roxmltree::Document<'input>,
    file: &'a str,
    strict: bool,
    /// Byte offsets of the document's line breaks, for [`Reader::line`].
    breaks: Vec<usize>,
    pub warnings: Vec<UrdfWarning>,
}

type Node<'a, 'input> = roxmltree::Node<'a, 'input>;

impl<'a, 'input> Reader<'a, 'input> {
    pub fn new(doc: &'a roxmltree::Document<'input>, file: &'a str, strict: bool) -> Self {
        let breaks = doc.input_text().match_indices('\n').map(|(i, _)| i).collect();
        Self { doc, file, strict, breaks, warnings: Vec::new() }
    }

    /// Line (1-based) of an element, by binary search (thousands of warnings stay fast).
    pub fn line(&self, node: Node) -> usize {
        self.breaks.partition_point(|&b| b < node.range().start) + 1
    }

    /// A parse error naming `node` and its line.
    pub fn error(&self, node: Node, what: impl std::fmt::Display) -> UrdfError {
        UrdfError::Parse {
            file: self.file.to_string(),
            message: format!("{}: {what}", crate::io::describe_element(self.doc, node)),
        }
    }

    /// Records a warning about `node`, or fails with it in strict mode.
    pub fn warn(&mut self, node: Node, kind: WarningKind) -> Result<(), UrdfError> {
        self.warn_in(node, node, kind)
    }

    /// Records a warning about `node` that concerns its child `at` (whose line it names), or
    /// fails with it in strict mode.
    fn warn_in(&mut self, node: Node, at: Node, kind: WarningKind) -> Result<(), UrdfError> {
        let warning = UrdfWarning { element: element_name(node), line: self.line(at), kind };
        if self.strict {
            return Err(UrdfError::Parse { file: self.file.to_string(), message: warning.to_string() });
        }
        self.warnings.push(warning);
        Ok(())
    }

    /// The children of `node` that URDF defines here, each tag once where it may appear once;
    /// warns about the others. Elements in an XML namespace (`xacro:`, `drake:`) are a tool's and
    /// are read past silently.
    fn children(&mut self, node: Node<'a, 'input>, known: Known) -> Result<Vec<Node<'a, 'input>>, UrdfError> {
        let mut out: Vec<Node> = Vec::new();
        let parent = node.tag_name().name().to_string();
        for child in node.children().filter(|c| c.is_element() && c.tag_name().namespace().is_none()) {
            let tag = child.tag_name().name();
            let Some((_, attributes)) = known.iter().find(|(t, _)| *t == tag) else {
                let names: Vec<&str> = known.iter().map(|(t, _)| *t).collect();
                let known = names.join(", ");
                let kind =
                    WarningKind::UnknownElement { tag: tag.to_string(), parent: parent.clone(), known };
                self.warn_in(node, child, kind)?;
                continue;
            };
            if SINGLE.contains(&tag) && out.iter().any(|c| c.has_tag_name(tag)) {
                self.warn_in(node, child, WarningKind::RepeatedElement { tag: tag.to_string() })?;
                continue;
            }
            if let Some(attributes) = attributes {
                for a in child.attributes().filter(|a| a.namespace().is_none()) {
                    if !attributes.contains(&a.name()) {
                        let attribute = a.name().to_string();
                        let known = attributes.join(", ");
                        self.warn(child, WarningKind::UnknownAttribute { attribute, known })?;
                    }
                }
            }
            out.push(child);
        }
        Ok(out)
    }

    /// A number attribute; `None` when absent. Text after a number (`-1.57.`, `0.07,`) is read
    /// past with a warning, as PyBullet's parser reads it; text that does not begin with a number
    /// is an error.
    fn number(&mut self, node: Node, name: &str) -> Result<Option<f64>, UrdfError> {
        let Some(text) = node.attribute(name) else { return Ok(None) };
        match lenient_number(text) {
            Some((x, true)) => Ok(Some(x)),
            Some((x, false)) => {
                self.warn(node, WarningKind::ExtraText { attribute: name.to_string(), read: x.to_string() })?;
                Ok(Some(x))
            }
            None => Err(self.error(node, format!("{name}=\"{text}\" is not a number"))),
        }
    }

    /// A number attribute URDF requires; a missing one is `default` with a warning.
    fn required_number(&mut self, node: Node, name: &str, default: f64) -> Result<f64, UrdfError> {
        match self.number(node, name)? {
            Some(x) => Ok(x),
            None => {
                self.warn(
                    node,
                    WarningKind::MissingValue { what: name.to_string(), default: default.to_string() },
                )?;
                Ok(default)
            }
        }
    }

    /// A shape's size attribute; a missing one is a warning and `None` (the shape is left out).
    fn size(&mut self, node: Node, name: &str) -> Result<Option<f64>, UrdfError> {
        let x = self.number(node, name)?;
        if x.is_none() {
            self.warn(
                node,
                WarningKind::MissingValue { what: name.to_string(), default: "no shape".into() },
            )?;
        }
        Ok(x)
    }

    /// A vector attribute of `N` numbers; `None` when absent. As PyBullet reads it, words that are
    /// not numbers (a roslaunch `$(optenv NAME` left in) and numbers after the first `N` are read
    /// past, text after a number too, each with a warning; fewer than `N` numbers is an error.
    fn vector<const N: usize>(&mut self, node: Node, name: &str) -> Result<Option<[f64; N]>, UrdfError> {
        let Some(text) = node.attribute(name) else { return Ok(None) };
        let mut clean = true;
        let mut parts = Vec::new();
        for word in text.split_whitespace() {
            match lenient_number(word) {
                Some((x, exact)) => {
                    clean &= exact;
                    parts.push(x);
                }
                None => clean = false,
            }
        }
        if parts.len() < N {
            return Err(self.error(node, format!("{name}=\"{text}\" is not {N} numbers")));
        }
        clean &= parts.len() == N;
        parts.truncate(N);
        if !clean {
            let read: Vec<String> = parts.iter().map(f64::to_string).collect();
            self.warn(node, WarningKind::ExtraText { attribute: name.to_string(), read: read.join(" ") })?;
        }
        Ok(Some(std::array::from_fn(|k| parts[k])))
    }

    /// The pose of an `<origin>` (identity when absent).
    fn origin(&mut self, origin: Option<Node>) -> Result<Transform, UrdfError> {
        let Some(o) = origin else { return Ok(Transform::identity()) };
        let xyz = self.vector::<3>(o, "xyz")?.unwrap_or_default();
        let rpy = self.vector::<3>(o, "rpy")?.unwrap_or_default();
        Ok(Transform::from_xyz_rpy(xyz, rpy))
    }

    /// A required attribute; a missing one is an error.
    fn name(&self, node: Node<'a, 'input>, attribute: &str) -> Result<&'a str, UrdfError> {
        node.attribute(attribute)
            .ok_or_else(|| self.error(node, format!("the `{attribute}` attribute is required")))
    }

    /// Reads the document.
    pub fn robot(&mut self) -> Result<RobotDesc, UrdfError> {
        let root = self.doc.root_element();
        if root.tag_name().name() != "robot" {
            return Err(UrdfError::Parse {
                file: self.file.to_string(),
                message: format!("root element is <{}>, expected <robot>", root.tag_name().name()),
            });
        }
        let name = root.attribute("name").unwrap_or_default().to_string();
        let (mut links, mut joints) = (Vec::new(), Vec::new());
        // `children` reads a repeated <link> or <joint> (not in SINGLE) as one more.
        for node in self.children(root, ROBOT)? {
            match node.tag_name().name() {
                "link" => links.push(self.link(node)?),
                "joint" => joints.push(self.joint(node)?),
                _ => {}
            }
        }
        Ok(RobotDesc { name, links, joints })
    }

    fn link(&mut self, node: Node<'a, 'input>) -> Result<LinkDesc, UrdfError> {
        let name = self.name(node, "name")?.to_string();
        let mut link = LinkDesc {
            name,
            line: self.line(node),
            mass: 0.0,
            inertial_origin: Transform::identity(),
            inertia: [0.0; 6],
            geometries: Vec::new(),
        };
        for child in self.children(node, LINK)? {
            match child.tag_name().name() {
                "inertial" => self.inertial(child, &mut link)?,
                "visual" => {
                    let c = self.children(child, VISUAL)?;
                    self.shape(child, &c, GeometryRole::Visual, &mut link)?;
                }
                "collision" => {
                    let c = self.children(child, COLLISION)?;
                    self.shape(child, &c, GeometryRole::Collision, &mut link)?;
                }
                _ => {}
            }
        }
        Ok(link)
    }

    fn inertial(&mut self, node: Node<'a, 'input>, link: &mut LinkDesc) -> Result<(), UrdfError> {
        let children = self.children(node, INERTIAL)?;
        let find = |tag: &str| children.iter().copied().find(|c| c.has_tag_name(tag));
        link.inertial_origin = self.origin(find("origin"))?;
        match find("mass") {
            Some(m) => link.mass = self.required_number(m, "value", 0.0)?,
            None => {
                self.warn(node, WarningKind::MissingValue { what: "<mass>".into(), default: "0".into() })?
            }
        }
        match find("inertia") {
            Some(i) => {
                for (k, name) in ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"].iter().enumerate() {
                    link.inertia[k] = self.required_number(i, name, 0.0)?;
                }
            }
            None => {
                self.warn(node, WarningKind::MissingValue { what: "<inertia>".into(), default: "0".into() })?
            }
        }
        Ok(())
    }

    /// A `<visual>` or `<collision>`: its shape, or a warning and nothing when the geometry is
    /// missing or of a kind URDF does not define.
    fn shape(
        &mut self,
        node: Node<'a, 'input>,
        children: &[Node<'a, 'input>],
        role: GeometryRole,
        link: &mut LinkDesc,
    ) -> Result<(), UrdfError> {
        let find = |tag: &str| children.iter().copied().find(|c| c.has_tag_name(tag));
        let placement = self.origin(find("origin"))?;
        let Some(geometry) = find("geometry") else {
            let what = "<geometry>".to_string();
            return self.warn(node, WarningKind::MissingValue { what, default: "no shape".into() });
        };
        let kinds: &[&str] = &["box", "cylinder", "capsule", "sphere", "mesh"];
        // The first shape counts; a second one, and elements that are no shape, are read past.
        let mut shape_node = None;
        for c in geometry.children().filter(|c| c.is_element() && c.tag_name().namespace().is_none()) {
            let tag = c.tag_name().name().to_string();
            if !kinds.contains(&tag.as_str()) {
                let kind =
                    WarningKind::UnknownElement { tag, parent: "geometry".into(), known: kinds.join(", ") };
                self.warn_in(geometry, c, kind)?;
            } else if shape_node.is_some() {
                self.warn_in(geometry, c, WarningKind::RepeatedElement { tag })?;
            } else {
                shape_node = Some(c);
            }
        }
        let Some(s) = shape_node else {
            let what = "a shape in <geometry>".to_string();
            return self.warn(geometry, WarningKind::MissingValue { what, default: "no shape".into() });
        };
        let tag = s.tag_name().name();
        // A shape without its size is left out (urdfdom refuses the link).
        let shape = match tag {
            "box" => match self.vector::<3>(s, "size")? {
                Some(size) => Some(Shape::Box { size: Vec3::from(size) }),
                None => {
                    let what = "size".to_string();
                    self.warn(s, WarningKind::MissingValue { what, default: "no shape".into() })?;
                    None
                }
            },
            "sphere" => self.size(s, "radius")?.map(|radius| Shape::Sphere { radius }),
            "cylinder" | "capsule" => match (self.size(s, "radius")?, self.size(s, "length")?) {
                (Some(radius), Some(length)) if tag == "cylinder" => Some(Shape::Cylinder { radius, length }),
                (Some(radius), Some(length)) => Some(Shape::Capsule { radius, length }),
                _ => None,
            },
            _ => match s.attribute("filename") {
                Some(uri) => {
                    let scale = self.vector::<3>(s, "scale")?.map_or(Vec3::repeat(1.0), Vec3::from);
                    Some(Shape::Mesh { uri: uri.to_string(), scale })
                }
                None => {
                    let what = "filename".to_string();
                    self.warn(s, WarningKind::MissingValue { what, default: "no shape".into() })?;
                    None
                }
            },
        };
        if let Some(shape) = shape {
            link.geometries.push((role, placement, shape));
        }
        Ok(())
    }

    fn joint(&mut self, node: Node<'a, 'input>) -> Result<JointDesc, UrdfError> {
        let name = self.name(node, "name")?.to_string();
        let type_text = self.name(node, "type")?;
        let kind = match type_text {
            "revolute" => JointType::Revolute,
            "continuous" => JointType::Continuous,
            "prismatic" => JointType::Prismatic,
            "fixed" => JointType::Fixed,
            "floating" => JointType::Floating,
            "planar" => JointType::Planar,
            "spherical" => JointType::Spherical,
            other => {
                return Err(UrdfError::Joint {
                    file: self.file.to_string(),
                    joint: name,
                    what: format!(
                        "unknown joint type \"{other}\" (URDF's are revolute, continuous, prismatic, fixed, floating, planar; spherical is read too)"
                    ),
                })
            }
        };
        let children = self.children(node, JOINT)?;
        let find = |tag: &str| children.iter().copied().find(|c| c.has_tag_name(tag));
        let link_of = |tag: &str| -> Result<String, UrdfError> {
            let e = find(tag).ok_or_else(|| self.error(node, format!("a joint needs a <{tag}> element")))?;
            Ok(self.name(e, "link")?.to_string())
        };
        let (parent, child) = (link_of("parent")?, link_of("child")?);
        let line = self.line(node);
        let origin = self.origin(find("origin"))?;
        let axis = match find("axis") {
            Some(a) => match self.vector::<3>(a, "xyz")? {
                Some(v) => Vec3::from(v),
                None => {
                    let what = "xyz".to_string();
                    self.warn(a, WarningKind::MissingValue { what, default: "1 0 0".into() })?;
                    Vec3::x()
                }
            },
            None => Vec3::x(),
        };
        let limit = match find("limit") {
            Some(l) => LimitDesc {
                lower: self.number(l, "lower")?.unwrap_or(0.0),
                upper: self.number(l, "upper")?.unwrap_or(0.0),
                effort: self.number(l, "effort")?.unwrap_or(0.0),
                velocity: self.number(l, "velocity")?.unwrap_or(0.0),
            },
            None => LimitDesc::default(),
        };
        let dynamics = match find("dynamics") {
            Some(d) => {
                Some((self.number(d, "damping")?.unwrap_or(0.0), self.number(d, "friction")?.unwrap_or(0.0)))
            }
            None => None,
        };
        Ok(JointDesc { name, line, kind, origin, parent, child, axis, limit, dynamics })
    }
}

/// `<tag name="…">` or `<tag>`.
fn element_name(node: Node) -> String {
    match node.attribute("name") {
        Some(n) => format!("<{} name=\"{n}\">", node.tag_name().name()),
        None => format!("<{}>", node.tag_name().name()),
    }
}

/// The number `text` begins with, and whether it is all of `text` (trimmed): `-1.57.` and
/// `0.149)` read as -1.57 and 0.149 (C's `strtod`, as PyBullet reads them); `None` when it does not
/// begin with a number.
fn lenient_number(text: &str) -> Option<(f64, bool)> {
    let t = text.trim();
    if let Ok(x) = t.parse::<f64>() {
        return Some((x, true));
    }
    // The longest prefix that parses; char boundaries only.
    let ends = t.char_indices().map(|(i, _)| i).skip(1).collect::<Vec<_>>();
    ends.into_iter().rev().find_map(|end| t[..end].parse::<f64>().ok()).map(|x| (x, false))
}
