//! Smooth steps of the world (`WorldOptions::integrator`, src/world/smooth.rs): without
//! contacts, limits, motors or joint friction the chosen integrator advances the multibodies,
//! loop closures held at the acceleration level and projected onto their manifold; with them,
//! the velocity-level step. Checked: a body tied to a swinging rod by a ball, hinge or slider
//! loop closure moves as the same body on the joint of that kind (both with RK4); free fall is exact
//! with RK4 until the contact step takes over and back; applied forces; sleeping and waking;
//! which steps fall back; bit-identical runs.

use gelenk::collision::MeshOptions;
use gelenk::constraints::{ContactParameters, LoopClosure, LoopKind};
use gelenk::integrators::IntegratorKind;
use gelenk::math::{Mat3, Transform, Vec3};
use gelenk::model::{BodySpec, Joint, JointDynamics, ModelBuilder, RigidInertia, Shape};
use gelenk::report::stability;
use gelenk::world::{Motor, SolverKind, World, WorldOptions};
use nalgebra::{DVector, UnitQuaternion};

fn options(integrator: IntegratorKind) -> WorldOptions {
    let mut o = WorldOptions {
        dt: 1e-3,
        integrator,
        solvers: vec![SolverKind::Lemke { facets: 8 }, SolverKind::Clarabel],
        tolerance: 1e-9,
        ..Default::default()
    };
    o.sleep.enabled = false;
    o
}

/// The centre of mass of the test body in its frame (m).
const COM: Vec3 = Vec3::new(0.1, -0.05, -0.3);

/// A 2 kg body with an asymmetric inertia whose centre of mass is `COM + shift` in its frame.
fn inertia_shifted(shift: Vec3) -> RigidInertia {
    RigidInertia::new(2.0, COM + shift, Mat3::from_diagonal(&Vec3::new(0.03, 0.05, 0.02)))
}

fn inertia() -> RigidInertia {
    inertia_shifted(Vec3::zeros())
}

fn one_body(joint: Joint) -> gelenk::Model {
    one_body_shifted(joint, Vec3::zeros())
}

fn one_body_shifted(joint: Joint, shift: Vec3) -> gelenk::Model {
    let mut b = ModelBuilder::new();
    b.add_body(BodySpec::new("body", "universe", joint, Transform::identity(), inertia_shifted(shift)));
    b.build().unwrap()
}

fn rotation_of_free(q: &DVector<f64>) -> Mat3 {
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[6], q[3], q[4], q[5]))
        .to_rotation_matrix()
        .into_inner()
}

/// A rod of 1 kg and 0.5 m hanging from its origin along −z.
fn rod() -> RigidInertia {
    RigidInertia::new(1.0, Vec3::new(0.0, 0.0, -0.25), Mat3::from_diagonal(&Vec3::new(0.021, 0.021, 1e-3)))
}

/// The tip of the rod in its frame (m).
const TIP: Vec3 = Vec3::new(0.0, 0.0, -0.5);

/// World pose (rotation, joint point) of the second body after 2 s, from two multibodies of
/// two bodies each: a rod on a hinge about y at the origin carrying the body on a joint of
/// `kind` at the rod's tip (a tree), and the same rod with the body on a free joint tied to the
/// rod's tip by a loop closure of `kind` at the point `r` of the body's frame (its frame, and
/// its inertia, shifted by `r` so that it is the same body). Same initial state, RK4 at 1 ms.
/// The closure point rides on the swinging rod, so the drift term J̇v of the closure
/// (centripetal and Coriolis accelerations of the rod's tip) matters.
fn tree_and_loop(kind: LoopKind) -> ((Mat3, Vec3), (Mat3, Vec3)) {
    let steps = 2000;
    let r = Vec3::new(0.2, -0.1, 0.15);
    let (joint, v_joint): (Joint, Vec<f64>) = match kind {
        LoopKind::Ball => (Joint::Ball, vec![0.4, -1.2, 3.0]),
        LoopKind::Hinge { axis } => (Joint::hinge(axis), vec![2.5]),
        LoopKind::Slider { axis } => (Joint::slider(axis), vec![0.7]),
        LoopKind::Weld => unreachable!(),
    };
    let mut tree = ModelBuilder::new();
    tree.add_body(BodySpec::new("rod", "universe", Joint::hinge(Vec3::y()), Transform::identity(), rod()));
    tree.add_body(BodySpec::new("body", "rod", joint, Transform::from_translation(TIP), inertia()));
    let tree = tree.build().unwrap();
    let mut state = gelenk::State::new(&tree);
    state.q[0] = 0.6;
    state.v[0] = 1.0;
    state.v.rows_mut(1, v_joint.len()).copy_from_slice(&v_joint);
    // The body's pose and body-frame velocity in the tree: the free joint's initial state.
    let mut data = gelenk::Data::new(&tree);
    gelenk::algorithms::rnea(&tree, &mut data, &state.q, &state.v, &DVector::zeros(tree.nv())).unwrap();
    gelenk::algorithms::forward_kinematics(&tree, &mut data, &state.q).unwrap();
    let (pose, velocity) = (data.x_wb[2], data.v[2]);
    let mut closed = ModelBuilder::new();
    closed.add_body(BodySpec::new("rod", "universe", Joint::hinge(Vec3::y()), Transform::identity(), rod()));
    closed.add_body(BodySpec::new(
        "body",
        "universe",
        Joint::Free,
        Transform::identity(),
        inertia_shifted(r),
    ));
    let closed = closed.build().unwrap();

    let mut w_tree = World::new(options(IntegratorKind::Rk4));
    let t = w_tree.add_multibody("tree", tree.clone(), &MeshOptions::default()).unwrap();
    w_tree.multibody_mut(t).state.q.copy_from(&state.q);
    w_tree.multibody_mut(t).state.v.copy_from(&state.v);
    let mut w_loop = World::new(options(IntegratorKind::Rk4));
    let c = w_loop.add_multibody("closed", closed, &MeshOptions::default()).unwrap();
    {
        let s = &mut w_loop.multibody_mut(c).state;
        s.q[0] = state.q[0];
        s.v[0] = state.v[0];
        // The free body's origin sits at −r in the tree body's frame.
        let origin = pose.translation - pose.rotation * r;
        let rotation = UnitQuaternion::from_matrix(&pose.rotation);
        s.q.rows_mut(1, 3).copy_from(&origin);
        s.q.rows_mut(4, 4).copy_from_slice(&[rotation.i, rotation.j, rotation.k, rotation.w]);
        s.v.rows_mut(1, 3).copy_from(&(velocity.linear - velocity.angular.cross(&r)));
        s.v.rows_mut(4, 3).copy_from(&velocity.angular);
    }
    w_loop
        .add_loop(
            c,
            LoopClosure {
                body_a: 2,
                frame_a: Transform::from_translation(r),
                body_b: 1,
                frame_b: Transform::from_translation(TIP),
                kind,
                erp: 0.2,
            },
        )
        .unwrap();
    for _ in 0..steps {
        w_tree.step().unwrap();
        w_loop.step().unwrap();
        assert_eq!(w_loop.stats().integrator, "rk4");
    }
    assert_eq!(w_tree.stats().integrator, "rk4");
    gelenk::algorithms::forward_kinematics(&tree, &mut data, &w_tree.multibody(t).state.q).unwrap();
    let q = &w_loop.multibody(c).state.q;
    let rotation = rotation_of_free(&q.rows(1, 7).into_owned());
    (
        (data.x_wb[2].rotation, data.x_wb[2].translation),
        (rotation, Vec3::new(q[1], q[2], q[3]) + rotation * r),
    )
}

#[test]
fn a_body_on_a_loop_closure_moves_as_on_the_joint_of_that_kind() {
    // Both are RK4 at 1 ms for 2 s of a swinging, precessing body: their global errors bound
    // the difference (measured 4e-10 rad and 5e-11 m at most); 1e-8 leaves a margin, while
    // leaving out J̇v (the rod tip's centripetal and Coriolis accelerations) moves them by 1e-3.
    let tilted = Vec3::new(0.3, 1.0, 0.4).normalize();
    for kind in [LoopKind::Ball, LoopKind::Hinge { axis: tilted }, LoopKind::Slider { axis: tilted }] {
        let ((r_tree, p_tree), (r_loop, p_loop)) = tree_and_loop(kind);
        let (dr, dp) = ((r_tree - r_loop).norm(), (p_tree - p_loop).norm());
        println!("{kind:?}: rotation {dr:e}, joint point {dp:e} m");
        assert!(dr < 1e-8 && dp < 1e-8, "{kind:?}: rotation differs by {dr:e}, joint point by {dp:e} m");
        assert!(r_tree.norm() > 0.0);
    }
}

fn ball() -> gelenk::Model {
    let mut b = ModelBuilder::new();
    b.add_body(
        BodySpec::new(
            "ball",
            "universe",
            Joint::Free,
            Transform::identity(),
            RigidInertia::solid_sphere(1.0, 0.05),
        )
        .with_collision(Shape::Sphere { radius: 0.05 }, Transform::identity()),
    );
    b.build().unwrap()
}

#[test]
fn free_fall_is_exact_with_rk4_and_contacts_switch_to_the_velocity_level_step() {
    let mut o = options(IntegratorKind::Rk4);
    o.contact = ContactParameters { restitution: 0.5, bounce_velocity: 0.01, ..Default::default() };
    let mut w = World::new(o);
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    let m = w.add_multibody("ball", ball(), &MeshOptions::default()).unwrap();
    let z0 = 0.5;
    w.multibody_mut(m).state.q[2] = z0;
    let g = 9.81;
    let (mut smooth, mut contact, mut smooth_after_contact) = (0, 0, 0);
    let mut worst_fall: f64 = 0.0;
    for k in 1..=1500 {
        w.step().unwrap();
        match w.stats().integrator {
            "rk4" if contact == 0 => {
                smooth += 1;
                // RK4 integrates the quadratic z(t) exactly; semi-implicit Euler is off by g h t / 2.
                let t = k as f64 * 1e-3;
                worst_fall = worst_fall.max((w.multibody(m).state.q[2] - (z0 - 0.5 * g * t * t)).abs());
            }
            "rk4" => smooth_after_contact += 1,
            "semi-implicit-euler" => {
                assert!(w.stats().contacts > 0, "a velocity-level step without contact");
                contact += 1;
            }
            other => panic!("unexpected integrator {other}"),
        }
    }
    println!("free fall: {smooth} RK4 steps, error {worst_fall:e} m; {contact} contact steps; {smooth_after_contact} RK4 steps after");
    assert!(smooth > 250 && contact > 0 && smooth_after_contact > 0);
    // Rounding only (z ≈ 0.5 m, 300 steps).
    assert!(worst_fall < 1e-12, "free fall off by {worst_fall:e} m");
}

#[test]
fn applied_forces_act_in_smooth_steps() {
    // A constant force on a free body without gravity: x = F t² / (2 m), exact for RK4.
    let mut o = options(IntegratorKind::Rk4);
    o.gravity = Vec3::zeros();
    let mut w = World::new(o);
    let m = w.add_multibody("ball", ball(), &MeshOptions::default()).unwrap();
    let force = Vec3::new(2.0, -1.0, 0.5);
    let steps = 500;
    for _ in 0..steps {
        w.apply_force(m, 1, force, Vec3::zeros(), Vec3::zeros()).unwrap();
        w.step().unwrap();
        assert_eq!(w.stats().integrator, "rk4");
    }
    let t = steps as f64 * 1e-3;
    let q = &w.multibody(m).state.q;
    let error = (Vec3::new(q[0], q[1], q[2]) - force * (t * t / 2.0)).norm();
    assert!(error < 1e-12, "position off by {error:e} m");
}

#[test]
fn a_damped_pendulum_sleeps_and_wakes_in_smooth_steps() {
    let mut o = options(IntegratorKind::Rk4);
    o.sleep.enabled = true;
    let mut w = World::new(o);
    let mut spec =
        BodySpec::new("body", "universe", Joint::hinge(Vec3::y()), Transform::identity(), inertia());
    spec.dynamics = JointDynamics { damping: 2.0, friction: 0.0 };
    let mut b = ModelBuilder::new();
    b.add_body(spec);
    let m = w.add_multibody("pendulum", b.build().unwrap(), &MeshOptions::default()).unwrap();
    w.multibody_mut(m).state.q[0] = 0.5;
    let mut slept_at = None;
    for k in 0..20000 {
        w.step().unwrap();
        assert_eq!(w.stats().integrator, "rk4");
        if w.multibody(m).is_asleep() {
            slept_at = Some(k);
            break;
        }
    }
    assert!(slept_at.is_some(), "the damped pendulum never slept");
    let q = w.multibody(m).state.q[0];
    w.apply_force(m, 1, Vec3::new(5.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -0.3), Vec3::zeros()).unwrap();
    w.step().unwrap();
    assert!(!w.multibody(m).is_asleep());
    w.step().unwrap();
    assert!((w.multibody(m).state.q[0] - q).abs() > 1e-6, "the push did not move it");
}

#[test]
fn motors_loops_between_multibodies_and_unsupported_closed_loop_integrators_fall_back() {
    // A motor is an inequality row: velocity-level step.
    let mut w = World::new(options(IntegratorKind::Rk4));
    let m = w.add_multibody("pendulum", one_body(Joint::hinge(Vec3::y())), &MeshOptions::default()).unwrap();
    w.step().unwrap();
    assert_eq!(w.stats().integrator, "rk4");
    w.multibody_mut(m).set_motor(0, Some(Motor { target_velocity: 1.0, max_force: 10.0 }));
    w.step().unwrap();
    assert_eq!(w.stats().integrator, "semi-implicit-euler");
    // A loop closure between two multibodies.
    let mut w = World::new(options(IntegratorKind::Rk4));
    let a = w.add_multibody("a", one_body(Joint::hinge(Vec3::y())), &MeshOptions::default()).unwrap();
    let b = w.add_multibody("b", one_body(Joint::Free), &MeshOptions::default()).unwrap();
    let closure = LoopClosure {
        body_a: 1,
        frame_a: Transform::identity(),
        body_b: 1,
        frame_b: Transform::identity(),
        kind: LoopKind::Ball,
        erp: 0.2,
    };
    w.add_loop_between(a, b, closure).unwrap();
    w.step().unwrap();
    assert_eq!(w.stats().integrator, "semi-implicit-euler");
    // Dormand–Prince has no closed-loop tableau here: the four-bar keeps the velocity-level step
    // (RATTLE, for a linkage whose only rows are its own closure), while a tree is stepped by it.
    let (mut w, _) =
        stability::four_bar_world(options(IntegratorKind::DormandPrince45 { rtol: 1e-9, atol: 1e-12 }))
            .unwrap();
    w.step().unwrap();
    assert_eq!(w.stats().integrator, "rattle");
    let mut w = World::new(options(IntegratorKind::DormandPrince45 { rtol: 1e-9, atol: 1e-12 }));
    w.add_multibody("pendulum", one_body(Joint::hinge(Vec3::y())), &MeshOptions::default()).unwrap();
    w.step().unwrap();
    assert_eq!(w.stats().integrator, "dopri45");
}

#[test]
fn smooth_runs_are_bit_identical() {
    let hash = || {
        let (mut w, _) = stability::four_bar_world(options(IntegratorKind::Rk4)).unwrap();
        for _ in 0..1000 {
            w.step().unwrap();
        }
        stability::state_hash(&w)
    };
    assert_eq!(hash(), hash());
}
