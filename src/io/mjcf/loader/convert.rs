//! MJCF elements into model bodies: geoms with MuJoCo's mass properties, bodies with their joints
//! (a chain of bodies for several joints), inertials, and the finished [`MjcfScene`].

use super::attributes::z_to;
use super::{Geom, InertiaFromGeom, Kind, Loader, Parent};
use crate::constraints::FrictionModel;
use crate::error::{MjcfError, ModelError};
use crate::io::mjcf::{GeomInfo, MjcfBody, MjcfScene, StaticGeometry};
use crate::math::{Mat3, Transform, Vec3};
use crate::model::ranges::Quantity;
use crate::model::{
    BallLimits, BodySpec, FrameKind, GeometryRole, GeometrySpec, Joint, JointDynamics, JointLimits,
    RigidInertia, Shape,
};
use roxmltree::{Node, NodeId};
use std::collections::HashMap;
use std::f64::consts::PI;

impl<'a, 'i> Loader<'a, 'i> {
    // ----- geoms ------------------------------------------------------------------------------

    /// Reads a geom; `frame` is the pose of its enclosing frame in the body frame.
    pub(super) fn geom(
        &self,
        node: Node,
        class: &str,
        frame: Transform,
        default_name: &str,
    ) -> Result<Geom, MjcfError> {
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
    pub(super) fn body(
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
                spec.ball_limits = j.ball_limits;
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
                ball_limits: None,
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
        let mut ball_limits = None;
        if limited && joint == Joint::Ball {
            // MuJoCo bounds the total rotation angle by range[1]; range[0] must be 0.
            let Some([lo, hi]) = range else { return Err(self.missing(node, "range")) };
            if lo != 0.0 || hi <= 0.0 {
                let text = self.get(node, k, c, "range").unwrap_or_default();
                return Err(self.bad_attr(
                    node,
                    "range",
                    &text,
                    "a ball joint's range is 0 and a positive angle",
                ));
            }
            // An angle of π or more bounds nothing: every rotation is within π.
            ball_limits = Some(BallLimits::total_angle(self.angle(hi).min(PI)));
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
            ball_limits,
            dynamics,
            armature: self.non_negative(node, k, c, "armature")?.unwrap_or(0.0),
        })
    }

    // ----- model ------------------------------------------------------------------------------

    pub(super) fn finish(
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
                | ModelError::OutOfRange { quantity: Quantity::PlacementOffset, name: joint, .. }
                | ModelError::DuplicateName { what: "joint", name: joint } => Some(joint),
                _ => None,
            };
            let body = match &source {
                ModelError::DuplicateName { what: "body", name: body }
                | ModelError::InvalidMass { body, .. }
                | ModelError::OutOfRange { name: body, .. }
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
    /// MuJoCo's ball-joint range: a bound on the total rotation angle.
    ball_limits: Option<BallLimits>,
    dynamics: JointDynamics,
    armature: f64,
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
