//! Ball-joint anatomical limits (swing cone + twist range) are enforced as unilateral rows: a
//! pendulum on a ball joint thrown past its cone or twisted past its range stops within 1° of
//! the stop; the rows appear only near a stop; URDF's `<gelenk type="ball">` extension sets the
//! limits; a pose servo drives a ball joint to a target orientation with bounded torque.

use gelenk::collision::MeshOptions;
use gelenk::constraints::RowOrigin;
use gelenk::io::urdf::{load_str, UrdfOptions};
use gelenk::math::{Transform, Vec3};
use gelenk::model::{swing_twist, BallLimits, BodySpec, Joint, ModelBuilder, RigidInertia};
use gelenk::world::{PoseServo, SolverKind, World, WorldOptions};
use nalgebra::{DVector, UnitQuaternion};

const SWING: f64 = 0.5;
const TWIST: f64 = 0.4;
/// The acceptance bound: no limit exceeded by more than 1°.
const ONE_DEGREE: f64 = std::f64::consts::PI / 180.0;

/// A 1 kg rod of 0.5 m hanging from a ball joint at the origin, twist axis along the rod (−z).
fn ball_pendulum() -> gelenk::Model {
    let mut b = ModelBuilder::new();
    let rod = RigidInertia::new(
        1.0,
        Vec3::new(0.0, 0.0, -0.5),
        nalgebra::Matrix3::from_diagonal(&Vec3::new(0.02, 0.02, 0.002)),
    );
    let limits = BallLimits::cone_twist(Vec3::new(0.0, 0.0, -1.0), SWING, -TWIST, TWIST);
    b.add_body(
        BodySpec::new("rod", "universe", Joint::Ball, Transform::identity(), rod).with_ball_limits(limits),
    );
    b.build().unwrap()
}

fn world(model: gelenk::Model) -> World {
    let options = WorldOptions {
        solvers: vec![SolverKind::Pgs { iterations: 100, omega: 1.0 }, SolverKind::Clarabel],
        ..WorldOptions::default()
    };
    let mut w = World::new(options);
    w.add_multibody("pendulum", model, &MeshOptions::default()).unwrap();
    w
}

/// Runs `steps` steps and returns the largest swing and |twist| seen, and whether each kind of
/// limit row appeared.
fn run(w: &mut World, steps: usize) -> (f64, f64, bool, bool) {
    let a = Vec3::new(0.0, 0.0, -1.0);
    let (mut swing, mut twist, mut swing_row, mut twist_row) = (0.0f64, 0.0f64, false, false);
    for _ in 0..steps {
        w.step().unwrap();
        for o in &w.problem().origins {
            swing_row |= matches!(o, RowOrigin::SwingLimit(0));
            twist_row |= matches!(o, RowOrigin::TwistLowerLimit(0) | RowOrigin::TwistUpperLimit(0));
        }
        let st = swing_twist(w.multibody(0).state.q.as_slice(), &a);
        swing = swing.max(st.swing);
        twist = twist.max(st.twist.abs());
        assert!(w.constraint_violation() < ONE_DEGREE);
    }
    (swing, twist, swing_row, twist_row)
}

#[test]
fn a_ball_joint_thrown_past_its_swing_cone_stops_within_one_degree() {
    let mut w = world(ball_pendulum());
    // 6 rad/s about x: unconstrained it would swing up to about 1.2 rad (E = ½Iω², I ≈ 0.27).
    w.multibody_mut(0).state.v = DVector::from_vec(vec![6.0, 1.0, 0.0]);
    let (swing, twist, swing_row, _) = run(&mut w, 1000);
    assert!(swing_row, "no swing row was ever created");
    assert!(swing > SWING - 0.02, "never reached the cone: {swing}");
    assert!(swing < SWING + ONE_DEGREE, "swing {swing} exceeds the cone {SWING} by more than 1°");
    assert!(twist < TWIST + ONE_DEGREE);
}

#[test]
fn a_ball_joint_spun_about_its_twist_axis_stops_within_one_degree() {
    let mut w = world(ball_pendulum());
    w.multibody_mut(0).state.v = DVector::from_vec(vec![0.0, 0.0, 20.0]);
    let (swing, twist, _, twist_row) = run(&mut w, 500);
    assert!(twist_row, "no twist row was ever created");
    assert!(twist > TWIST - 0.02, "never reached the twist stop: {twist}");
    assert!(twist < TWIST + ONE_DEGREE, "twist {twist} exceeds {TWIST} by more than 1°");
    assert!(swing < 1e-6, "a pure twist swung the rod: {swing}");
}

#[test]
fn no_limit_rows_away_from_the_stops() {
    let mut w = world(ball_pendulum());
    w.multibody_mut(0).state.v = DVector::from_vec(vec![1.0, 0.0, 1.0]);
    for _ in 0..20 {
        w.step().unwrap();
        assert_eq!(w.stats().rows, 0, "rows far from the stops");
    }
}

#[test]
fn urdf_ball_extension_sets_the_limits_and_bad_ones_are_errors() {
    let robot = |ext: &str, kind: &str| {
        format!(
            r#"<robot name="r"><link name="a"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
<link name="b"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="neck" type="{kind}"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/></joint>{ext}</robot>"#
        )
    };
    let m = load_str(
        &robot(r#"<gelenk joint="neck" type="ball" twist_axis="0 0 2" swing="0.7" twist_lower="-0.6" twist_upper="0.5"/>"#, "spherical"),
        &UrdfOptions::default(),
    )
    .unwrap();
    let neck = m.joint_id("neck").unwrap();
    assert_eq!(*m.joint(neck), Joint::Ball);
    assert_eq!(m.ball_limits(neck), Some(&BallLimits::cone_twist(Vec3::z(), 0.7, -0.6, 0.5)));
    let bounded = load_str(
        &robot(r#"<gelenk joint="neck" type="ball" angle="0.9"/>"#, "spherical"),
        &UrdfOptions::default(),
    )
    .unwrap();
    assert_eq!(bounded.ball_limits(1), Some(&BallLimits::total_angle(0.9)));
    let plain = load_str(&robot("", "spherical"), &UrdfOptions::default()).unwrap();
    assert!(plain.ball_limits(1).is_none() && !plain.has_ball_limits());
    for (ext, kind, needle) in [
        (r#"<gelenk joint="neck" type="ball" swing="0.7"/>"#, "revolute", "spherical"),
        (r#"<gelenk joint="neck" type="ball" swing="-1"/>"#, "spherical", "swing cone"),
        (
            r#"<gelenk joint="neck" type="ball" swing="1" twist_lower="1" twist_upper="0"/>"#,
            "spherical",
            "twist range",
        ),
        (r#"<gelenk joint="neck" type="ball" angle="4"/>"#, "spherical", "total rotation angle"),
        (r#"<gelenk joint="neck" type="ball" twist_axis="0 0"/>"#, "spherical", "three numbers"),
        (r#"<gelenk joint="neck" type="ball" twist_axis="0 0 0"/>"#, "spherical", "axis"),
        (r#"<gelenk joint="neck" type="universal" axis2="0 1 0"/>"#, "spherical", "revolute or continuous"),
    ] {
        let e = load_str(&robot(ext, kind), &UrdfOptions::default()).unwrap_err().to_string();
        assert!(e.contains(needle), "{ext} on {kind}: {e}");
    }
}

#[test]
fn a_pose_servo_turns_a_ball_joint_to_its_target_with_bounded_torque() {
    let mut b = ModelBuilder::new();
    let rod = RigidInertia::new(
        1.0,
        Vec3::new(0.0, 0.0, -0.5),
        nalgebra::Matrix3::from_diagonal(&Vec3::new(0.02, 0.02, 0.002)),
    );
    b.add_body(BodySpec::new("rod", "universe", Joint::Ball, Transform::identity(), rod));
    let model = b.build().unwrap();
    let mut w = world(model);
    let target = UnitQuaternion::from_scaled_axis(Vec3::new(0.3, -0.2, 0.8));
    let t = DVector::from_vec(vec![target.i, target.j, target.k, target.w]);
    // Holding the rod 0.36 rad off vertical takes m g l sin θ ≈ 1.7 N·m; 10 N·m suffice.
    let max_torque = 10.0;
    let servo = PoseServo::uniform(t, 10.0, 5.0, max_torque, 3);
    w.multibody_mut(0).set_pose_servo(Some(servo)).unwrap();
    let h = w.options().dt;
    for _ in 0..1500 {
        w.step().unwrap();
        for (i, o) in w.problem().origins.iter().enumerate() {
            if matches!(o, RowOrigin::Motor(_)) {
                // Impulse bound of a motor row: max_force · h (plus rounding).
                assert!(w.impulses()[i].abs() <= max_torque * h * (1.0 + 1e-9));
            }
        }
    }
    let q = &w.multibody(0).state.q;
    let reached = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[3], q[0], q[1], q[2]));
    // The servo is a velocity motor with rate gain·error: against gravity it settles where the
    // bounded impulse balances, within a small steady-state error (gain 10/s, dt 2 ms).
    let error = reached.angle_to(&target);
    assert!(error < ONE_DEGREE, "servo ended {error} rad from the target");
    // Too weak a servo cannot hold the pose against gravity.
    let mut weak = w.multibody(0).pose_servo().unwrap().clone();
    weak.max_force.fill(0.5);
    w.multibody_mut(0).set_pose_servo(Some(weak)).unwrap();
    let mut worst: f64 = 0.0;
    for _ in 0..1500 {
        w.step().unwrap();
        let q = &w.multibody(0).state.q;
        let now = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[3], q[0], q[1], q[2]));
        worst = worst.max(now.angle_to(&target));
    }
    // It swings down (the servo only brakes it): 0.5 N·m balances gravity 0.1 rad off vertical.
    assert!(worst > 0.2, "a 0.5 N·m servo held a pose that needs ~1.7 N·m: worst error {worst} rad");
    assert!(w
        .multibody_mut(0)
        .set_pose_servo(Some(PoseServo::uniform(DVector::zeros(3), 1.0, 1.0, 1.0, 3)))
        .is_err());
}

/// MuJoCo's ball-joint `range` (a bound on the total rotation angle) read from MJCF: a capsule
/// on a ball joint of range 40°, thrown about a tilted axis, stops within 1° of 40° (MuJoCo's
/// row for it: distance 40° − θ, Jacobian minus the rotation axis); a range that does not
/// start at 0 is refused, as MuJoCo refuses it.
#[test]
fn an_mjcf_ball_range_bounds_the_total_rotation_angle() {
    let xml = |range: &str| {
        format!(
            r#"<mujoco><option gravity="0 0 0"/><worldbody><body name="rod" pos="0 0 1">
                 <joint name="ball" type="ball" range="{range}"/>
                 <geom type="capsule" size="0.05" fromto="0 0 0 0 0 -0.5" contype="0" conaffinity="0"/>
               </body></worldbody></mujoco>"#
        )
    };
    let scene = gelenk::io::mjcf::load_str(&xml("0 40")).unwrap();
    let bound = 40f64.to_radians();
    assert_eq!(scene.model.ball_limits(1), Some(&BallLimits::total_angle(bound)));
    let options = scene.world_options();
    let mut w = scene.into_world(options).unwrap();
    w.multibody_mut(0).state.v = DVector::from_vec(vec![3.0, 2.0, 4.0]);
    let (mut largest, mut angle_row) = (0.0f64, false);
    for _ in 0..1000 {
        w.step().unwrap();
        angle_row |= w.problem().origins.iter().any(|o| matches!(o, RowOrigin::AngleLimit(0)));
        let st = swing_twist(w.multibody(0).state.q.as_slice(), &Vec3::z());
        largest = largest.max(st.angle);
        assert!(w.constraint_violation() < ONE_DEGREE);
    }
    assert!(angle_row, "no total-angle row was ever created");
    assert!(largest > bound - 0.02, "never reached the stop: {largest}");
    assert!(largest < bound + ONE_DEGREE, "angle {largest} exceeds {bound} by more than 1°");
    for bad in ["-10 40", "10 40", "0 0"] {
        let e = gelenk::io::mjcf::load_str(&xml(bad)).unwrap_err().to_string();
        assert!(e.contains("range") && e.contains("ball joint"), "{bad}: {e}");
    }
}
