//! From the links and joints read ([`super::read`]) to a [`Model`]: the tree, the joint mapping,
//! the limits; each link's inertia comes from [`super::inertia`].

use super::extension::Extension;
use super::read::{JointDesc, JointType, LinkDesc, RobotDesc};
use super::{UrdfError, UrdfOptions, UrdfWarning, WarningKind};
use crate::math::{Mat3, Transform, Vec3};
use crate::model::{
    ranges, BodySpec, GeometrySpec, Joint, JointDynamics, JointLimits, Model, ModelBuilder, RigidInertia,
};
use std::collections::HashMap;
use std::path::Path;

/// Builds the model of `robot`; inertia warnings (and, leniently, inverted limits) are added to
/// `warnings`.
pub(super) fn model(
    robot: &RobotDesc,
    extensions: &HashMap<String, Extension>,
    file: &str,
    dir: Option<&Path>,
    options: &UrdfOptions,
    warnings: &mut Vec<UrdfWarning>,
) -> Result<Model, UrdfError> {
    let tree_err = |what: String| UrdfError::Tree { file: file.to_string(), what };
    let links: HashMap<&str, &LinkDesc> = robot.links.iter().map(|l| (l.name.as_str(), l)).collect();
    if links.len() != robot.links.len() {
        return Err(tree_err("two links share a name".to_string()));
    }
    let mut parent_joint: HashMap<&str, &str> = HashMap::new();
    for j in &robot.joints {
        for link in [&j.parent, &j.child] {
            if !links.contains_key(link.as_str()) {
                return Err(UrdfError::Joint {
                    file: file.into(),
                    joint: j.name.clone(),
                    what: format!("unknown link `{link}`"),
                });
            }
        }
        if let Some(other) = parent_joint.insert(j.child.as_str(), j.name.as_str()) {
            return Err(UrdfError::Joint {
                file: file.into(),
                joint: j.name.clone(),
                what: format!("link `{}` already has parent joint `{other}`", j.child),
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
    let roots: Vec<&LinkDesc> =
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

    for link in &robot.links {
        if link.mass > 0.0 && link.mass < ranges::MIN_POSITIVE_MASS {
            let warning = UrdfWarning {
                element: format!("<link name=\"{}\">", link.name),
                line: link.line,
                kind: WarningKind::TinyMass { mass: link.mass },
            };
            if options.strict {
                return Err(UrdfError::Parse { file: file.to_string(), message: warning.to_string() });
            }
            warnings.push(warning);
        }
    }
    let mut builder = ModelBuilder::new();
    builder.name(robot.name.clone());
    builder.accept_inconsistent_inertia(!options.strict);
    let inertia = |link: &LinkDesc, warnings: &mut Vec<UrdfWarning>| {
        super::inertia::link_inertia(link, file, dir, options, warnings)
    };
    let mut root_body = link_body(root, "universe", Transform::identity(), inertia(root, warnings)?)
        .with_joint_name(options.root_joint_name.clone());
    root_body.joint = if options.floating_base { Joint::Free } else { Joint::Fixed };
    builder.add_body(root_body);
    for j in &robot.joints {
        let child = links[j.child.as_str()];
        let body =
            link_body(child, &j.parent, j.origin, inertia(child, warnings)?).with_joint_name(j.name.clone());
        for b in joint_bodies(j, body, extensions.get(&j.name), file, options.strict, warnings)? {
            builder.add_body(b);
        }
    }
    builder.build().map_err(|source| UrdfError::Model { file: file.to_string(), source })
}

/// The body of a link (fixed joint) with its inertia and geometry.
fn link_body(link: &LinkDesc, parent: &str, placement: Transform, inertia: RigidInertia) -> BodySpec {
    let mut body = BodySpec::new(link.name.clone(), parent, Joint::Fixed, placement, inertia);
    for (role, placement, shape) in &link.geometries {
        body.geometries.push(GeometrySpec {
            link: link.name.clone(),
            role: *role,
            shape: shape.clone(),
            placement: *placement,
            body: 0,
        });
    }
    body
}

/// The body (or, for a planar joint about a non-z normal, the two bodies) of joint `j` whose
/// child link is `body`.
fn joint_bodies(
    j: &JointDesc,
    mut body: BodySpec,
    extension: Option<&Extension>,
    file: &str,
    strict: bool,
    warnings: &mut Vec<UrdfWarning>,
) -> Result<Vec<BodySpec>, UrdfError> {
    let joint_err = |what: String| UrdfError::Joint { file: file.into(), joint: j.name.clone(), what };
    let lim = &j.limit;
    let given = |x: f64| if x > 0.0 && x.is_finite() { x } else { f64::INFINITY };
    // Equal bounds (a missing one reads as 0) mean no limit. NaN bounds are an error where the
    // joint has a range (revolute and prismatic); inverted ones too in strict mode, and otherwise
    // no limit with a warning (Bullet's convention for a free axis, as in PyBullet's
    // cube_no_rotation.urdf).
    let mut range = || -> Result<(f64, f64), UrdfError> {
        let text = format!("<limit lower=\"{}\" upper=\"{}\">", lim.lower, lim.upper);
        if lim.lower.is_nan() || lim.upper.is_nan() || (strict && lim.lower > lim.upper) {
            Err(joint_err(format!("{text}: lower must not exceed upper (equal bounds: no limit)")))
        } else if lim.lower < lim.upper {
            Ok((lim.lower, lim.upper))
        } else {
            if lim.lower > lim.upper {
                warnings.push(UrdfWarning {
                    element: format!("<joint name=\"{}\">", j.name),
                    line: j.line,
                    kind: WarningKind::InvertedLimits { lower: lim.lower, upper: lim.upper },
                });
            }
            Ok((f64::NEG_INFINITY, f64::INFINITY))
        }
    };
    let (velocity, effort) = (given(lim.velocity), given(lim.effort));
    let dynamics =
        j.dynamics.map(|(damping, friction)| JointDynamics { damping, friction }).unwrap_or_default();
    body.dynamics = dynamics;
    let axis = j.axis;
    let kind_name = format!("{:?}", j.kind).to_lowercase();
    match (j.kind, extension) {
        (JointType::Revolute | JointType::Continuous, ext) => {
            let range =
                if j.kind == JointType::Continuous { (f64::NEG_INFINITY, f64::INFINITY) } else { range()? };
            match ext {
                None => {
                    body.joint = Joint::Hinge { axis };
                    body.limits = limits(&[range], velocity, effort, 1);
                }
                Some(ext) if ext.kind == "ball" => {
                    return Err(joint_err(format!(
                        "a <gelenk> ball extension needs a spherical joint, not {kind_name}"
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
        (JointType::Spherical, ext) => {
            body.joint = Joint::Ball;
            match ext {
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
        (_, Some(ext)) if ext.kind == "ball" => {
            return Err(joint_err(format!(
                "a <gelenk> ball extension needs a spherical joint, not {kind_name}"
            )))
        }
        (_, Some(_)) => {
            return Err(joint_err(format!(
            "a <gelenk> universal or hinge2 extension needs a revolute or continuous joint, not {kind_name}"
        )))
        }
        (JointType::Prismatic, None) => {
            body.joint = Joint::Slider { axis };
            body.limits = limits(&[range()?], velocity, effort, 1);
        }
        (JointType::Fixed, None) => {}
        (JointType::Floating, None) => body.joint = Joint::Free,
        (JointType::Planar, None) => {
            let n = axis
                .try_normalize(1e-12)
                .ok_or_else(|| joint_err("planar joint with a zero normal axis".into()))?;
            let align = nalgebra::Rotation3::rotation_between(&Vec3::z(), &n)
                .unwrap_or_else(|| {
                    nalgebra::Rotation3::from_axis_angle(&Vec3::x_axis(), std::f64::consts::PI)
                })
                .into_inner();
            if (align - Mat3::identity()).amax() < 1e-15 {
                body.joint = Joint::Planar;
            } else {
                // The planar joint moves in its frame's xy-plane: turn that frame so that z is the
                // URDF normal, and attach the link back through a fixed rotation.
                let carrier = format!("{}__planar", j.child);
                let mut carrier_body = BodySpec::new(
                    carrier.clone(),
                    j.parent.clone(),
                    Joint::Planar,
                    j.origin * Transform::new(align, Vec3::zeros()),
                    RigidInertia::massless(),
                )
                .with_joint_name(j.name.clone());
                carrier_body.dynamics = dynamics;
                body.dynamics = JointDynamics::default();
                body.parent = carrier;
                body.placement = Transform::new(align.transpose(), Vec3::zeros());
                body.joint_name = format!("{}__planar_fixed", j.name);
                return Ok(vec![carrier_body, body]);
            }
        }
    }
    Ok(vec![body])
}

fn limits(ranges: &[(f64, f64)], velocity: f64, effort: f64, nv: usize) -> JointLimits {
    JointLimits {
        lower: ranges.iter().map(|r| r.0).collect(),
        upper: ranges.iter().map(|r| r.1).collect(),
        velocity: vec![velocity; nv],
        effort: vec![effort; nv],
    }
}
