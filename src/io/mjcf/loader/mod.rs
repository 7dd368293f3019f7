//! Reading an MJCF document: global settings (`<compiler>`, `<option>`, `<default>` classes,
//! `<contact>`), then `<worldbody>` depth-first. Attribute reading is in [`attributes`], the
//! conversion of bodies, joints and geoms into the model in [`convert`].

mod attributes;
mod convert;

use super::schema::{equals_default, schema, Treatment};
use super::{GeomInfo, MjcfScene, StaticGeometry};
use crate::constraints::FrictionModel;
use crate::error::MjcfError;
use crate::io::limits::ReadLimits;
use crate::math::{Transform, Vec3};
use crate::model::{BodySpec, ModelBuilder, Shape};
use roxmltree::{Node, NodeId};
use std::collections::HashMap;

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

pub(super) fn load_named(text: &str, file: &str, limits: &ReadLimits) -> Result<MjcfScene, MjcfError> {
    // roxmltree parses recursively: a deeply nested document (a long chain of bodies) is parsed
    // on a thread with a stack to match, and one nested beyond the limit is refused.
    limits.check_len(text).map_err(|message| MjcfError::Xml { file: file.to_string(), message })?;
    let max = limits.max_depth;
    crate::io::limits::with_xml_stack(
        text,
        max,
        |depth| {
            MjcfError::Xml {
            file: file.to_string(),
            message: format!("elements are nested {depth} deep; at most {max} levels are supported (ReadLimits::max_depth)"),
        }
        },
        |message| MjcfError::Xml { file: file.to_string(), message },
        || load_on_this_thread(text, file),
    )
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
        crate::io::describe_element(self.doc, node)
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
                    Some(Treatment::UnlessDefault(default))
                        if !equals_default(attribute.value(), default) =>
                    {
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
}
