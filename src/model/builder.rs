//! [`ModelBuilder`]: validates a body description and turns it into a [`Model`], fusing bodies
//! attached by fixed joints into their parents.

use super::ranges;
use super::{BallLimits, Frame, FrameKind, GeometrySpec, Joint, Model, NO_DOF};
use crate::error::ModelError;
use crate::math::{Mat3, SpatialInertia, Transform, Vec3};
use nalgebra::DVector;
use std::collections::HashMap;

/// Mass properties of a rigid body in its own frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidInertia {
    /// Mass (kg), finite and non-negative.
    pub mass: f64,
    /// Centre of mass in the body frame (m).
    pub com: Vec3,
    /// Rotational inertia about the centre of mass in body-frame axes (kg·m²): symmetric,
    /// positive semi-definite, principal moments satisfying the triangle inequality.
    pub inertia_com: Mat3,
}

impl RigidInertia {
    /// No mass at all.
    pub fn massless() -> Self {
        Self { mass: 0.0, com: Vec3::zeros(), inertia_com: Mat3::zeros() }
    }

    /// A body of `mass` kg with centre of mass `com` and inertia about it `inertia_com`.
    pub fn new(mass: f64, com: Vec3, inertia_com: Mat3) -> Self {
        Self { mass, com, inertia_com }
    }

    /// A solid box of `mass` kg and full side lengths `size` (m), centred at the origin.
    pub fn solid_box(mass: f64, size: Vec3) -> Self {
        let (x2, y2, z2) = (size.x * size.x, size.y * size.y, size.z * size.z);
        let d = Vec3::new(y2 + z2, x2 + z2, x2 + y2) * (mass / 12.0);
        Self { mass, com: Vec3::zeros(), inertia_com: Mat3::from_diagonal(&d) }
    }

    /// A solid sphere of `mass` kg and `radius` m, centred at the origin.
    pub fn solid_sphere(mass: f64, radius: f64) -> Self {
        let i = 0.4 * mass * radius * radius;
        Self { mass, com: Vec3::zeros(), inertia_com: Mat3::from_diagonal_element(i) }
    }

    /// A solid cylinder of `mass` kg, `radius` and `length` (m) along z, centred at the origin.
    pub fn solid_cylinder(mass: f64, radius: f64, length: f64) -> Self {
        let axial = 0.5 * mass * radius * radius;
        let transverse = mass * (3.0 * radius * radius + length * length) / 12.0;
        Self {
            mass,
            com: Vec3::zeros(),
            inertia_com: Mat3::from_diagonal(&Vec3::new(transverse, transverse, axial)),
        }
    }

    /// A solid capsule of total `mass` kg (uniform density): a cylinder of `radius` and `length`
    /// (m) along z with hemispherical caps, centred at the origin.
    pub fn solid_capsule(mass: f64, radius: f64, length: f64) -> Self {
        let (r, l) = (radius, length);
        let (v_cyl, v_caps) =
            (std::f64::consts::PI * r * r * l, 4.0 / 3.0 * std::f64::consts::PI * r * r * r);
        let (m_cyl, m_caps) = (mass * v_cyl / (v_cyl + v_caps), mass * v_caps / (v_cyl + v_caps));
        let axial = 0.5 * m_cyl * r * r + 0.4 * m_caps * r * r;
        // Caps: a sphere's inertia about its centre, shifted by the hemisphere centroid offset
        // (l/2 + 3r/8) with the parallel-axis theorem applied through each half's own centroid.
        let cap_about_own = 0.4 * m_caps * r * r - m_caps * (3.0 * r / 8.0).powi(2);
        let transverse =
            m_cyl * (3.0 * r * r + l * l) / 12.0 + cap_about_own + m_caps * (l / 2.0 + 3.0 * r / 8.0).powi(2);
        Self {
            mass,
            com: Vec3::zeros(),
            inertia_com: Mat3::from_diagonal(&Vec3::new(transverse, transverse, axial)),
        }
    }

    fn spatial(&self) -> SpatialInertia {
        SpatialInertia::new(self.mass, self.com, self.inertia_com)
    }

    /// What makes the rotational inertia one no rigid body can have, if anything: a principal
    /// moment below zero, or moments violating the triangle inequality I₁ + I₂ ≥ I₃ (each up to
    /// a tolerance relative to the largest entry, as CAD exports round: 1e-9 for the sign, 1e-6
    /// for the triangle). A point mass (zero inertia) is consistent. Assumes a finite symmetric
    /// tensor.
    pub fn issue(&self) -> Option<InertiaIssue> {
        let i = &self.inertia_com;
        let scale = i.amax();
        let moments = principal_moments(i);
        let tol = 1e-9 * scale;
        if moments[0] < -tol {
            Some(InertiaIssue::NotPositive { moments })
        } else if moments[0] + moments[1] < moments[2] - (1e-6 * scale).max(tol) {
            Some(InertiaIssue::TriangleInequality { moments })
        } else {
            None
        }
    }

    /// The inertia with MuJoCo's `balanceinertia` repair: when [`RigidInertia::issue`] finds one,
    /// the three principal moments are set to their mean (negative ones counted as 0), which
    /// makes the tensor that mean times the identity; otherwise unchanged. Mass and centre of
    /// mass are kept.
    pub fn balanced(&self) -> RigidInertia {
        if self.issue().is_none() {
            return *self;
        }
        let moments = principal_moments(&self.inertia_com);
        let mean = moments.iter().map(|m| m.max(0.0)).sum::<f64>() / 3.0;
        RigidInertia { inertia_com: Mat3::from_diagonal_element(mean), ..*self }
    }
}

/// Why a rotational inertia is one no rigid body can have ([`RigidInertia::issue`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InertiaIssue {
    /// A principal moment is negative: some rotation would have negative kinetic energy.
    NotPositive {
        /// Principal moments, ascending (kg·m²).
        moments: [f64; 3],
    },
    /// The principal moments violate I₁ + I₂ ≥ I₃: no mass distribution has them.
    TriangleInequality {
        /// Principal moments, ascending (kg·m²).
        moments: [f64; 3],
    },
}

impl std::fmt::Display for InertiaIssue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            InertiaIssue::NotPositive { moments } => {
                write!(
                    f,
                    "inertia tensor is not positive semi-definite (principal moments {moments:?} kg·m²)"
                )
            }
            InertiaIssue::TriangleInequality { moments } => {
                write!(f, "principal moments {moments:?} kg·m² violate the triangle inequality I1 + I2 >= I3")
            }
        }
    }
}

/// Eigenvalues of a symmetric 3×3 tensor, ascending.
fn principal_moments(i: &Mat3) -> [f64; 3] {
    let mut m = i.symmetric_eigenvalues();
    m.as_mut_slice().sort_by(|a, b| a.total_cmp(b));
    [m[0], m[1], m[2]]
}

/// Joint limits. Empty vectors mean "none"; otherwise `lower`/`upper` have the joint's nq
/// entries and `velocity`/`effort` its nv entries (±∞ allowed).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JointLimits {
    /// Lower position limits (rad or m).
    pub lower: Vec<f64>,
    /// Upper position limits (rad or m).
    pub upper: Vec<f64>,
    /// Velocity limits (rad/s or m/s), non-negative.
    pub velocity: Vec<f64>,
    /// Effort limits (N·m or N), non-negative.
    pub effort: Vec<f64>,
}

/// Passive joint dynamics (URDF `<dynamics>`), the same for every degree of freedom of the joint.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JointDynamics {
    /// Viscous damping (N·m·s/rad or N·s/m).
    pub damping: f64,
    /// Coulomb friction level (N·m or N).
    pub friction: f64,
}

/// One body and the joint that attaches it to its parent.
#[derive(Clone, Debug, PartialEq)]
pub struct BodySpec {
    /// Body (link) name, unique.
    pub name: String,
    /// Parent body name; `universe` for the world.
    pub parent: String,
    /// Joint name, unique among joints.
    pub joint_name: String,
    /// The joint.
    pub joint: Joint,
    /// Pose of the joint frame in the parent body's frame. The body frame coincides with the
    /// joint frame when the joint is at its neutral configuration.
    pub placement: Transform,
    /// Mass properties in the body frame.
    pub inertia: RigidInertia,
    /// Joint limits.
    pub limits: JointLimits,
    /// Joint damping and friction.
    pub dynamics: JointDynamics,
    /// Swing-cone and twist limits; only for a [`Joint::Ball`].
    pub ball_limits: Option<BallLimits>,
    /// Collision and visual shapes, placed in this body's frame.
    pub geometries: Vec<GeometrySpec>,
}

impl BodySpec {
    /// A body `name` attached to `parent` by `joint` (named like the body) at `placement`.
    pub fn new(
        name: impl Into<String>,
        parent: impl Into<String>,
        joint: Joint,
        placement: Transform,
        inertia: RigidInertia,
    ) -> Self {
        let name = name.into();
        Self {
            joint_name: name.clone(),
            name,
            parent: parent.into(),
            joint,
            placement,
            inertia,
            limits: JointLimits::default(),
            dynamics: JointDynamics::default(),
            ball_limits: None,
            geometries: Vec::new(),
        }
    }

    /// Renames the joint.
    pub fn with_joint_name(mut self, joint_name: impl Into<String>) -> Self {
        self.joint_name = joint_name.into();
        self
    }

    /// Adds a collision shape at `placement` in this body's frame.
    pub fn with_collision(mut self, shape: super::Shape, placement: Transform) -> Self {
        self.geometries.push(GeometrySpec {
            link: self.name.clone(),
            role: super::GeometryRole::Collision,
            shape,
            placement,
            body: 0,
        });
        self
    }

    /// Sets the limits.
    pub fn with_limits(mut self, limits: JointLimits) -> Self {
        self.limits = limits;
        self
    }

    /// Sets swing-cone, twist and total-angle limits (ball joints only; checked by the builder).
    pub fn with_ball_limits(mut self, limits: BallLimits) -> Self {
        self.ball_limits = Some(limits);
        self
    }
}

/// Collects [`BodySpec`]s in any order (parents may be added after their children) and builds a
/// validated [`Model`]. Joints are numbered depth-first from the universe, children in the order
/// they were added (Pinocchio's URDF order).
#[derive(Clone, Debug)]
pub struct ModelBuilder {
    name: String,
    bodies: Vec<BodySpec>,
    gravity: Vec3,
    accept_inconsistent_inertia: bool,
}

impl Default for ModelBuilder {
    fn default() -> Self {
        Self::new()
    }
}

/// Name of body 0, the world.
pub const UNIVERSE: &str = "universe";

impl ModelBuilder {
    /// An empty model with gravity (0, 0, −9.81) m/s².
    pub fn new() -> Self {
        Self {
            name: String::new(),
            bodies: Vec::new(),
            gravity: Vec3::new(0.0, 0.0, -9.81),
            accept_inconsistent_inertia: false,
        }
    }

    /// Accepts rotational inertias that no rigid body can have ([`RigidInertia::issue`]: a
    /// negative principal moment, the triangle inequality violated) instead of refusing them
    /// (the default). The URDF loader sets it in its lenient mode, where such an inertia is a
    /// warning. Non-finite or asymmetric inertias and negative masses stay errors.
    pub fn accept_inconsistent_inertia(&mut self, accept: bool) -> &mut Self {
        self.accept_inconsistent_inertia = accept;
        self
    }

    /// Sets the model's name.
    pub fn name(&mut self, name: impl Into<String>) -> &mut Self {
        self.name = name.into();
        self
    }

    /// Sets gravity in the world frame (m/s²).
    pub fn gravity(&mut self, g: Vec3) -> &mut Self {
        self.gravity = g;
        self
    }

    /// Adds a body; nothing is checked until [`ModelBuilder::build`].
    pub fn add_body(&mut self, body: BodySpec) -> &mut Self {
        self.bodies.push(body);
        self
    }

    /// Validates every body and joint, orders the tree depth-first, fuses fixed joints and
    /// returns the model.
    pub fn build(&self) -> Result<Model, ModelError> {
        let specs = self.validated_specs()?;
        let index: HashMap<&str, usize> =
            specs.iter().enumerate().map(|(i, s)| (s.name.as_str(), i)).collect();
        // children[k + 1] lists the specs whose parent is spec k; children[0] the roots.
        let mut children = vec![Vec::new(); specs.len() + 1];
        for (i, s) in specs.iter().enumerate() {
            let slot = if s.parent == UNIVERSE {
                0
            } else {
                match index.get(s.parent.as_str()) {
                    Some(&p) => p + 1,
                    None => {
                        return Err(ModelError::UnknownParent {
                            body: s.name.clone(),
                            parent: s.parent.clone(),
                        })
                    }
                }
            };
            children[slot].push(i);
        }

        let mut model = Model {
            name: self.name.clone(),
            nq: 0,
            nv: 0,
            body_names: vec![UNIVERSE.to_string()],
            joint_names: vec![UNIVERSE.to_string()],
            joints: vec![Joint::Fixed],
            parents: vec![0],
            children: vec![Vec::new()],
            placements: vec![Transform::identity()],
            inertias: vec![SpatialInertia::zero()],
            idx_q: vec![0],
            idx_v: vec![0],
            dof_joint: Vec::new(),
            dof_parent: Vec::new(),
            dof_run_start: Vec::new(),
            dof_path: Vec::new(),
            dof_path_start: Vec::new(),
            subtree_dof_end: Vec::new(),
            lower_position_limit: DVector::zeros(0),
            upper_position_limit: DVector::zeros(0),
            velocity_limit: DVector::zeros(0),
            effort_limit: DVector::zeros(0),
            damping: DVector::zeros(0),
            friction: DVector::zeros(0),
            ball_limits: vec![None],
            frames: vec![Frame {
                name: UNIVERSE.to_string(),
                kind: FrameKind::Body,
                body: 0,
                placement: Transform::identity(),
            }],
            geometries: Vec::new(),
            gravity: self.gravity,
            source_dir: None,
        };
        let mut limits: Vec<(usize, &BodySpec)> = Vec::new();
        let mut visited = vec![false; specs.len()];
        // Depth-first: (spec, moving ancestor body, pose of the spec's parent link in that body).
        let mut stack: Vec<(usize, usize, Transform)> =
            children[0].iter().rev().map(|&c| (c, 0, Transform::identity())).collect();
        while let Some((k, ancestor, x_ap)) = stack.pop() {
            visited[k] = true;
            let s = &specs[k];
            let x_aj = x_ap * s.placement;
            let (body, x_bc) = if s.joint == Joint::Fixed {
                model.inertias[ancestor] += s.inertia.spatial().transformed(&x_aj);
                (ancestor, x_aj)
            } else {
                let b = model.joints.len();
                model.body_names.push(s.name.clone());
                model.joint_names.push(s.joint_name.clone());
                model.joints.push(s.joint);
                model.parents.push(ancestor);
                model.children.push(Vec::new());
                model.children[ancestor].push(b);
                model.placements.push(x_aj);
                model.inertias.push(s.inertia.spatial());
                model.ball_limits.push(s.ball_limits);
                model.idx_q.push(model.nq);
                model.idx_v.push(model.nv);
                let parent_last_dof = last_dof(&model, ancestor);
                for d in 0..s.joint.nv() {
                    model.dof_joint.push(b);
                    model.dof_parent.push(if d == 0 { parent_last_dof } else { model.nv + d - 1 });
                }
                model.nq += s.joint.nq();
                model.nv += s.joint.nv();
                limits.push((b, s));
                (b, Transform::identity())
            };
            for g in &s.geometries {
                model.geometries.push(GeometrySpec { body, placement: x_bc * g.placement, ..g.clone() });
            }
            for (name, kind) in [(&s.name, FrameKind::Body), (&s.joint_name, FrameKind::Joint)] {
                model.frames.push(Frame { name: name.clone(), kind, body, placement: x_bc });
            }
            for &c in children[k + 1].iter().rev() {
                stack.push((c, body, x_bc));
            }
        }
        if let Some(k) = visited.iter().position(|v| !v) {
            return Err(ModelError::Cycle { body: specs[k].name.clone() });
        }
        fill_limits(&mut model, &limits);
        for k in 0..model.nv {
            let start = if k > 0 && model.dof_parent[k] == k - 1 { model.dof_run_start[k - 1] } else { k };
            model.dof_run_start.push(start);
        }
        model.dof_path_start.push(0);
        for k in 0..model.nv {
            let first = model.dof_path.len();
            let mut j = model.dof_parent[k];
            while j != NO_DOF {
                model.dof_path.push(j);
                j = model.dof_parent[j];
            }
            model.dof_path[first..].reverse();
            model.dof_path_start.push(model.dof_path.len());
        }
        // Depth-first numbering: a subtree's bodies, and so its dofs, follow its root's.
        let nbodies = model.joints.len();
        model.subtree_dof_end = (0..nbodies).map(|i| model.idx_v[i] + model.joints[i].nv()).collect();
        for i in (1..nbodies).rev() {
            let p = model.parents[i];
            model.subtree_dof_end[p] = model.subtree_dof_end[p].max(model.subtree_dof_end[i]);
        }
        Ok(model)
    }

    /// Checks names, masses, inertias, axes, placements and limits; returns the specs with
    /// normalized axes.
    fn validated_specs(&self) -> Result<Vec<BodySpec>, ModelError> {
        let mut body_names = HashMap::new();
        let mut joint_names = HashMap::new();
        let mut out = Vec::with_capacity(self.bodies.len());
        for s in &self.bodies {
            if s.name == UNIVERSE || body_names.insert(s.name.as_str(), ()).is_some() {
                return Err(ModelError::DuplicateName { what: "body", name: s.name.clone() });
            }
            if joint_names.insert(s.joint_name.as_str(), ()).is_some() {
                return Err(ModelError::DuplicateName { what: "joint", name: s.joint_name.clone() });
            }
            validate_inertia(&s.name, &s.inertia, self.accept_inconsistent_inertia)?;
            if !s.placement.is_finite() {
                return Err(ModelError::NonFinitePlacement { joint: s.joint_name.clone() });
            }
            let offset = s.placement.translation.norm();
            if offset > ranges::MAX_LENGTH {
                let (name, quantity) = (s.joint_name.clone(), ranges::Quantity::PlacementOffset);
                return Err(ModelError::OutOfRange { name, quantity, value: offset });
            }
            for g in &s.geometries {
                let extent =
                    ranges::shape_extent(&g.shape).unwrap_or(0.0).max(g.placement.translation.norm());
                // (A non-finite or degenerate shape is the collision world's to refuse.)
                if extent.is_finite() && extent > ranges::MAX_LENGTH {
                    let (name, quantity) = (s.name.clone(), ranges::Quantity::ShapeSize);
                    return Err(ModelError::OutOfRange { name, quantity, value: extent });
                }
            }
            let mut s = s.clone();
            s.joint = normalized_joint(&s.joint_name, &s.joint)?;
            if let Some(b) = &mut s.ball_limits {
                b.twist_axis = unit_axis(&s.joint_name, &b.twist_axis)?;
            }
            validate_limits(&s)?;
            out.push(s);
        }
        Ok(out)
    }
}

fn last_dof(model: &Model, body: usize) -> usize {
    let mut b = body;
    while b != 0 {
        let nv = model.joints[b].nv();
        if nv > 0 {
            return model.idx_v[b] + nv - 1;
        }
        b = model.parents[b];
    }
    NO_DOF
}

fn unit_axis(joint: &str, axis: &Vec3) -> Result<Vec3, ModelError> {
    let n = axis.norm();
    if !n.is_finite() || n < 1e-12 {
        return Err(ModelError::InvalidAxis { joint: joint.to_string(), axis: [axis.x, axis.y, axis.z] });
    }
    Ok(axis / n)
}

fn normalized_joint(name: &str, joint: &Joint) -> Result<Joint, ModelError> {
    let two_axes = |a1: &Vec3, a2: &Vec3| -> Result<(Vec3, Vec3), ModelError> {
        let (a1, a2) = (unit_axis(name, a1)?, unit_axis(name, a2)?);
        if a1.cross(&a2).norm() < 1e-6 {
            return Err(ModelError::ParallelAxes { joint: name.to_string() });
        }
        Ok((a1, a2))
    };
    Ok(match joint {
        Joint::Hinge { axis } => Joint::Hinge { axis: unit_axis(name, axis)? },
        Joint::Slider { axis } => Joint::Slider { axis: unit_axis(name, axis)? },
        Joint::Universal { axis1, axis2 } => {
            let (axis1, axis2) = two_axes(axis1, axis2)?;
            Joint::Universal { axis1, axis2 }
        }
        Joint::Hinge2 { axis1, axis2, suspension } => {
            let (axis1, axis2) = two_axes(axis1, axis2)?;
            if let Some(s) = suspension {
                let ok = |x: f64| x.is_finite() && x >= 0.0;
                if !ok(s.stiffness) || !ok(s.damping) {
                    return Err(ModelError::InvalidSuspension { joint: name.to_string() });
                }
            }
            Joint::Hinge2 { axis1, axis2, suspension: *suspension }
        }
        other => *other,
    })
}

/// Mass finite and non-negative; inertia finite and symmetric (up to 1e-9 of its largest entry),
/// and unless `accept_inconsistent` free of any [`RigidInertia::issue`]. A point mass (zero
/// inertia) and a massless link are valid.
fn validate_inertia(body: &str, inertia: &RigidInertia, accept_inconsistent: bool) -> Result<(), ModelError> {
    let body = body.to_string();
    if !inertia.mass.is_finite() || inertia.mass < 0.0 {
        return Err(ModelError::InvalidMass { body, mass: inertia.mass });
    }
    let i = &inertia.inertia_com;
    if !i.iter().chain(inertia.com.iter()).all(|x| x.is_finite()) {
        return Err(ModelError::NonFiniteInertia { body });
    }
    for (quantity, value) in [
        (ranges::Quantity::Mass, inertia.mass),
        (ranges::Quantity::Inertia, i.amax()),
        (ranges::Quantity::ComOffset, inertia.com.norm()),
    ] {
        if value > quantity.limit() {
            return Err(ModelError::OutOfRange { name: body, quantity, value });
        }
    }
    if (i - i.transpose()).amax() > 1e-9 * i.amax() {
        return Err(ModelError::InertiaNotSymmetric { body });
    }
    match inertia.issue() {
        Some(_) if accept_inconsistent => Ok(()),
        Some(InertiaIssue::NotPositive { moments }) => Err(ModelError::InertiaNotPositive { body, moments }),
        Some(InertiaIssue::TriangleInequality { moments }) => {
            Err(ModelError::InertiaTriangleInequality { body, moments })
        }
        None => Ok(()),
    }
}

fn validate_limits(s: &BodySpec) -> Result<(), ModelError> {
    let (nq, nv) = (s.joint.nq(), s.joint.nv());
    let err = |reason: String| ModelError::InvalidLimits { joint: s.joint_name.clone(), reason };
    let l = &s.limits;
    for (v, n, what) in [
        (&l.lower, nq, "lower"),
        (&l.upper, nq, "upper"),
        (&l.velocity, nv, "velocity"),
        (&l.effort, nv, "effort"),
    ] {
        if !v.is_empty() && v.len() != n {
            return Err(err(format!("{what} has {} entries, the joint has {n}", v.len())));
        }
        if v.iter().any(|x| x.is_nan()) {
            return Err(err(format!("{what} is NaN")));
        }
    }
    if !l.lower.is_empty() && !l.upper.is_empty() {
        if let Some(k) = (0..nq).find(|&k| l.lower[k] > l.upper[k]) {
            return Err(err(format!("lower {} is above upper {}", l.lower[k], l.upper[k])));
        }
    }
    if l.velocity.iter().chain(&l.effort).any(|x| *x < 0.0) {
        return Err(err("velocity and effort limits must be non-negative".to_string()));
    }
    if let Some(b) = &s.ball_limits {
        if s.joint != Joint::Ball {
            return Err(err(format!("ball limits need a ball joint, not {}", s.joint.kind_name())));
        }
        let pi = std::f64::consts::PI;
        if !(b.swing > 0.0 && b.swing <= pi) {
            return Err(err(format!("swing cone half-angle {} is not in (0, π]", b.swing)));
        }
        if !(-pi <= b.twist_lower && b.twist_lower <= b.twist_upper && b.twist_upper <= pi) {
            return Err(err(format!(
                "twist range [{}, {}] is not ordered within [−π, π]",
                b.twist_lower, b.twist_upper
            )));
        }
        if !(b.angle > 0.0 && b.angle <= pi) {
            return Err(err(format!("total rotation angle {} is not in (0, π]", b.angle)));
        }
    }
    let d = &s.dynamics;
    if !(d.damping.is_finite() && d.damping >= 0.0 && d.friction.is_finite() && d.friction >= 0.0) {
        return Err(err("damping and friction must be finite and non-negative".to_string()));
    }
    Ok(())
}

fn fill_limits(model: &mut Model, specs: &[(usize, &BodySpec)]) {
    let (nq, nv) = (model.nq, model.nv);
    model.lower_position_limit = DVector::from_element(nq, f64::NEG_INFINITY);
    model.upper_position_limit = DVector::from_element(nq, f64::INFINITY);
    model.velocity_limit = DVector::from_element(nv, f64::INFINITY);
    model.effort_limit = DVector::from_element(nv, f64::INFINITY);
    model.damping = DVector::zeros(nv);
    model.friction = DVector::zeros(nv);
    for &(b, s) in specs {
        let (iq, iv) = (model.idx_q[b], model.idx_v[b]);
        let l = &s.limits;
        for (src, dst, off) in [
            (&l.lower, &mut model.lower_position_limit, iq),
            (&l.upper, &mut model.upper_position_limit, iq),
            (&l.velocity, &mut model.velocity_limit, iv),
            (&l.effort, &mut model.effort_limit, iv),
        ] {
            for (k, x) in src.iter().enumerate() {
                dst[off + k] = *x;
            }
        }
        for k in 0..s.joint.nv() {
            model.damping[iv + k] = s.dynamics.damping;
            model.friction[iv + k] = s.dynamics.friction;
        }
    }
}
