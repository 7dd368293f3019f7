//! Loop closures between two multibodies: a double pendulum made of two separate multibodies
//! (a hinged link, and a free link whose top is tied to the first link's tip by a ball loop
//! closure) must move like the same double pendulum built as one tree (hinge + ball joint).

use gelenk::collision::MeshOptions;
use gelenk::constraints::{LoopClosure, LoopKind};
use gelenk::math::{Mat3, Transform, Vec3};
use gelenk::model::{BodySpec, Joint, ModelBuilder, RigidInertia};
use gelenk::world::{SolverKind, World, WorldOptions};

const LENGTH: f64 = 0.5;
const MASS: f64 = 1.0;

/// A slender rod of `LENGTH` hanging from its frame origin along −z.
fn rod() -> RigidInertia {
    let i = MASS * LENGTH * LENGTH / 12.0;
    RigidInertia::new(MASS, Vec3::new(0.0, 0.0, -LENGTH / 2.0), Mat3::from_diagonal(&Vec3::new(i, i, 1e-4)))
}

fn options() -> WorldOptions {
    let mut options = WorldOptions {
        dt: 1e-3,
        solvers: vec![SolverKind::Lemke { facets: 8 }, SolverKind::Clarabel],
        tolerance: 1e-9,
        ..Default::default()
    };
    options.sleep.enabled = false;
    options
}

/// The first link's hinge angle and the second link's tip position after `steps` steps, for the
/// tree and for the two multibodies tied by a loop closure.
fn run(steps: usize) -> ((f64, Vec3), (f64, Vec3), f64) {
    let theta0 = 0.6;
    // One tree: hinge about y at the origin, ball at the first link's tip.
    let mut tree = ModelBuilder::new();
    tree.add_body(BodySpec::new("upper", "universe", Joint::hinge(Vec3::y()), Transform::identity(), rod()));
    tree.add_body(BodySpec::new(
        "lower",
        "upper",
        Joint::Ball,
        Transform::from_translation(Vec3::new(0.0, 0.0, -LENGTH)),
        rod(),
    ));
    let mut w_tree = World::new(options());
    let t = w_tree.add_multibody("tree", tree.build().unwrap(), &MeshOptions::default()).unwrap();
    w_tree.multibody_mut(t).state.q[0] = theta0;
    // Give the ball joint an initial spin (ω in the link frame: 0.7 about x, 1.5 about the
    // link's own axis z) so that the motion is three-dimensional.
    w_tree.multibody_mut(t).state.v[1] = 0.7;
    w_tree.multibody_mut(t).state.v[3] = 1.5;

    // Two multibodies: the hinged link, and a free link placed where the tree puts its lower link.
    let mut upper = ModelBuilder::new();
    upper.add_body(BodySpec::new("upper", "universe", Joint::hinge(Vec3::y()), Transform::identity(), rod()));
    let mut lower = ModelBuilder::new();
    lower.add_body(BodySpec::new("lower", "universe", Joint::Free, Transform::identity(), rod()));
    let mut w_loop = World::new(options());
    let a = w_loop.add_multibody("upper", upper.build().unwrap(), &MeshOptions::default()).unwrap();
    let b = w_loop.add_multibody("lower", lower.build().unwrap(), &MeshOptions::default()).unwrap();
    w_loop.multibody_mut(a).state.q[0] = theta0;
    {
        // The free link's pose and velocity equal the tree's lower link (ball at identity).
        let (s, c) = theta0.sin_cos();
        let tip = Vec3::new(-LENGTH * s, 0.0, -LENGTH * c);
        let lower = &mut w_loop.multibody_mut(b).state;
        lower.q[0] = tip.x;
        lower.q[2] = tip.z;
        let half = theta0 / 2.0;
        lower.q[3] = 0.0;
        lower.q[4] = half.sin();
        lower.q[5] = 0.0;
        lower.q[6] = half.cos();
        // Tip velocity of the upper link (world: θ̇ × r = 0 at rest) plus the link's own spin.
        // Free-joint velocities are in the link frame: angular = ball angular velocity + hinge rate
        // expressed in the link frame (the hinge starts at rest).
        lower.v[3] = 0.7;
        lower.v[5] = 1.5;
        // The link's origin sits at the ball centre, which is at rest: linear velocity zero.
    }
    let closure = LoopClosure {
        body_a: 1,
        frame_a: Transform::from_translation(Vec3::new(0.0, 0.0, -LENGTH)),
        body_b: 1,
        frame_b: Transform::identity(),
        kind: LoopKind::Ball,
        erp: 0.2,
    };
    w_loop.add_loop_between(a, b, closure).unwrap();
    let mut worst: f64 = 0.0;
    for _ in 0..steps {
        w_tree.step().unwrap();
        w_loop.step().unwrap();
        worst = worst.max(w_loop.constraint_violation());
    }
    let tip_of = |w: &mut World, m: usize, body: usize| {
        let mb = w.multibody(m);
        let mut data = gelenk::Data::new(mb.model());
        gelenk::algorithms::forward_kinematics(mb.model(), &mut data, &mb.state.q).unwrap();
        data.x_wb[body].act_point(&Vec3::new(0.0, 0.0, -LENGTH))
    };
    let tree_result = (w_tree.multibody(t).state.q[0], tip_of(&mut w_tree, t, 2));
    let loop_result = (w_loop.multibody(a).state.q[0], tip_of(&mut w_loop, b, 1));
    (tree_result, loop_result, worst)
}

#[test]
fn two_multibodies_tied_by_a_ball_closure_move_as_the_tree() {
    let ((theta_tree, tip_tree), (theta_loop, tip_loop), worst) = run(1000);
    eprintln!("closure {worst:e} m, hinge {theta_tree} vs {theta_loop}, tip {tip_tree:?} vs {tip_loop:?}");
    // The closure's drift is removed by ERP every step; at dt = 1 ms it stays below 10 µm.
    assert!(worst < 1e-5, "closure error {worst:e} m");
    // Both are semi-implicit Euler at the same dt on the same dynamics; the loop version is
    // velocity-level exact, so the trajectories agree to the closure's position drift scale.
    assert!((theta_tree - theta_loop).abs() < 1e-3, "hinge {theta_tree} vs {theta_loop}");
    assert!((tip_tree - tip_loop).norm() < 1e-3, "tip {tip_tree:?} vs {tip_loop:?}");
    // And the motion was not trivial.
    assert!((theta_tree - 0.6).abs() > 0.1, "the pendulum moved: {theta_tree}");
}

#[test]
fn a_loop_between_multibodies_checks_its_indices() {
    let mut w = World::new(options());
    let mut m = ModelBuilder::new();
    m.add_body(BodySpec::new("link", "universe", Joint::hinge(Vec3::y()), Transform::identity(), rod()));
    let a = w.add_multibody("a", m.build().unwrap(), &MeshOptions::default()).unwrap();
    let closure = |body_b| LoopClosure {
        body_a: 1,
        frame_a: Transform::identity(),
        body_b,
        frame_b: Transform::identity(),
        kind: LoopKind::Ball,
        erp: 0.2,
    };
    assert!(w.add_loop_between(a, 5, closure(0)).is_err());
    assert!(w.add_loop_between(a, a, closure(7)).is_err());
    assert!(w.add_loop_between(a, a, closure(0)).is_ok());
}
