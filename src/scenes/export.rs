//! The scenes of `gelenk export-problems` (and of the committed problem corpus,
//! `tests/problems`): one multibody each on a [`World`] whose chain is clarabel alone, sleeping
//! off and the Delassus matrix formed anew every step, so that each step poses its own problem
//! and is solved to the reference accuracy; the problem of each step is [`World::problem`].
//!
//! | scene | what | rows |
//! |---|---|---|
//! | `box-drop` | a tilted box thrown onto the ground, μ = 0.5 | 1–4 contacts, sliding, cone |
//! | `box-flat` | a box sliding flat on the ground, μ = 0 | 4 coplanar contacts (degenerate), pure QP |
//! | `stack2` | two boxes stacked on the ground, μ = 0.6 | 8 contacts, cone |
//! | `stack10` | ten boxes stacked, μ = 0.6 | 40 contacts, cone |
//! | `sphere-incline` | a sphere sliding down a 20° incline, μ = 0.3 | 1 contact, sliding then rolling |
//! | `four-bar` | the four-bar linkage of [`super::four_bar_world`] under gravity | 5 bilateral rows, 3 of them redundant |
//! | `limit-pendulum` | a hinge pendulum falling onto its upper limit (bounce 0.3) | 1 unilateral row |

use super::four_bar::{four_bar_closed_angles, four_bar_closure, FOUR_BAR_CRANK_ANGLE, FOUR_BAR_LENGTHS};
use super::rod;
use crate::collision::MeshOptions;
use crate::constraints::{ContactParameters, FrictionModel, JointLimitParameters};
use crate::error::ModelError;
use crate::math::{axis_angle, Mat3, Transform, Vec3};
use crate::model::{BodySpec, Joint, JointLimits, ModelBuilder, RigidInertia, Shape};
use crate::world::{SolverKind, StepError, World, WorldOptions};
use nalgebra::{DVector, UnitQuaternion};
use thiserror::Error;

/// Names of the built-in scenes.
pub const SCENE_NAMES: [&str; 7] =
    ["box-drop", "box-flat", "stack2", "stack10", "sphere-incline", "four-bar", "limit-pendulum"];

/// Why a scene could not be built or stepped.
#[derive(Debug, Error)]
pub enum SceneError {
    /// No built-in scene has this name.
    #[error("unknown scene `{0}` (known: box-drop, box-flat, stack2, stack10, sphere-incline, four-bar, limit-pendulum)")]
    Unknown(String),
    /// The scene's model is invalid (a bug in the scene).
    #[error("scene model: {0}")]
    Model(#[from] ModelError),
    /// The world refused the scene (a bug in the scene).
    #[error("scene world: {0}")]
    World(#[from] StepError),
}

fn boxed(name: &str, mass: f64, size: Vec3) -> BodySpec {
    BodySpec::new(name, "universe", Joint::Free, Transform::identity(), RigidInertia::solid_box(mass, size))
        .with_collision(Shape::Box { size }, Transform::identity())
}

/// Writes the pose of free body `k` (position, rotation) and its world velocity (linear, angular)
/// into q and v (the free joint's velocity is in body axes).
fn set_free(
    q: &mut DVector<f64>,
    v: &mut DVector<f64>,
    k: usize,
    pose: (Vec3, Mat3),
    velocity: (Vec3, Vec3),
) {
    let (p, r) = pose;
    let quat = UnitQuaternion::from_matrix(&r);
    q.rows_mut(7 * k, 3).copy_from(&p);
    q.rows_mut(7 * k + 3, 4).copy_from_slice(&[quat.i, quat.j, quat.k, quat.w]);
    v.rows_mut(6 * k, 3).copy_from(&(r.transpose() * velocity.0));
    v.rows_mut(6 * k + 3, 3).copy_from(&(r.transpose() * velocity.1));
}

/// The built-in scene `name` at its initial state, as a world (multibody 0 the scene's
/// multibody, named `name`).
pub fn scene_world(name: &str) -> Result<World, SceneError> {
    let mut builder = ModelBuilder::new();
    builder.name(name);
    let mut ground = Some(Vec3::z());
    let mut contact = ContactParameters::default();
    let mut limits = JointLimitParameters::default();
    let mut loops = Vec::new();
    let (mut h, mut poses, mut velocities) = (0.005, Vec::new(), Vec::new());
    let mut hinge_q: Vec<f64> = Vec::new();
    let identity = Mat3::identity();
    match name {
        "box-drop" => {
            builder.add_body(boxed("box", 2.0, Vec3::new(0.4, 0.3, 0.2)));
            let r = axis_angle(&Vec3::new(1.0, 0.5, 0.0).normalize(), 0.5);
            poses.push((Vec3::new(0.0, 0.0, 0.3), r));
            velocities.push((Vec3::new(1.0, 0.2, -1.0), Vec3::new(0.0, 0.0, 2.0)));
            contact.restitution = 0.2;
        }
        "box-flat" => {
            builder.add_body(boxed("box", 2.0, Vec3::new(0.4, 0.3, 0.2)));
            poses.push((Vec3::new(0.0, 0.0, 0.0995), identity));
            velocities.push((Vec3::new(0.5, 0.2, 0.0), Vec3::zeros()));
            contact.mu = 0.0;
        }
        "stack2" | "stack10" => {
            let count = if name == "stack2" { 2 } else { 10 };
            let size = Vec3::new(0.3, 0.3, 0.1);
            for k in 0..count {
                builder.add_body(boxed(&format!("box{k}"), 1.0, size));
                let r = axis_angle(&Vec3::z(), 0.1 * k as f64);
                let offset = Vec3::new(0.01 * (k % 3) as f64, -0.01 * (k % 2) as f64, 0.0);
                poses.push((offset + Vec3::z() * (0.05 + 0.1 * k as f64 - 0.0005 * (k + 1) as f64), r));
                velocities.push((Vec3::zeros(), Vec3::zeros()));
            }
            contact.mu = 0.6;
        }
        "sphere-incline" => {
            let radius = 0.1;
            builder.add_body(
                BodySpec::new(
                    "ball",
                    "universe",
                    Joint::Free,
                    Transform::identity(),
                    RigidInertia::solid_sphere(1.0, radius),
                )
                .with_collision(Shape::Sphere { radius }, Transform::identity()),
            );
            let slope = 20f64.to_radians();
            let normal = Vec3::new(slope.sin(), 0.0, slope.cos());
            ground = Some(normal);
            let down = Vec3::new(-slope.cos(), 0.0, slope.sin());
            poses.push((normal * (radius - 0.0005), identity));
            velocities.push((down * 0.5, Vec3::zeros()));
            contact.mu = 0.3;
        }
        "four-bar" => {
            // The linkage of `four_bar.rs`: its chain, its closure, its closed configuration.
            let (a, b, c, _) = FOUR_BAR_LENGTHS;
            let at = |x: f64| Transform::from_translation(Vec3::new(x, 0.0, 0.0));
            builder.add_body(rod("crank", "universe", at(0.0), a));
            builder.add_body(rod("coupler", "crank", at(a), b));
            builder.add_body(rod("rocker", "coupler", at(b), c));
            hinge_q = four_bar_closed_angles(FOUR_BAR_CRANK_ANGLE).to_vec();
            loops.push(four_bar_closure());
            ground = None;
            h = 0.01;
        }
        "limit-pendulum" => {
            let limits_spec =
                JointLimits { lower: vec![-0.5], upper: vec![0.3], velocity: vec![], effort: vec![] };
            builder.add_body(rod("arm", "universe", Transform::identity(), 1.0).with_limits(limits_spec));
            hinge_q = vec![0.0];
            limits.restitution = 0.3;
            ground = None;
            h = 0.01;
        }
        other => return Err(SceneError::Unknown(other.to_string())),
    }
    let model = builder.build()?;
    let mut q = model.neutral_configuration();
    let mut v = DVector::zeros(model.nv());
    for (k, (pose, velocity)) in poses.into_iter().zip(velocities).enumerate() {
        set_free(&mut q, &mut v, k, pose, velocity);
    }
    for (k, x) in hinge_q.into_iter().enumerate() {
        q[k] = x;
    }
    let mut options = WorldOptions {
        dt: h,
        solvers: vec![SolverKind::Clarabel],
        friction: FrictionModel::Cone,
        contact,
        limits,
        mass_matrix_reuse: None,
        ..WorldOptions::default()
    };
    options.sleep.enabled = false;
    let mut world = World::new(options);
    let m = world.add_multibody(name, model, &MeshOptions::default())?;
    world.set_self_collision(m, true)?;
    if let Some(normal) = ground {
        world.add_static("ground", &Shape::HalfSpace { normal }, Transform::identity(), 0)?;
    }
    for closure in loops {
        world.add_loop(m, closure)?;
    }
    let state = &mut world.multibody_mut(m).state;
    state.q.copy_from(&q);
    state.v.copy_from(&v);
    Ok(world)
}
