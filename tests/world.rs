//! The world's step against closed forms: a bouncing ball rebounds to ε²h, a resting box stays
//! still, a sliding box stops after v₀²/(2μg), a box on an incline sticks iff μ ≥ tan θ, a
//! pendulum stops at its joint limit, a motor reaches its target, two runs are bit-identical,
//! the accumulator caps substeps, a sleeping stack sleeps and wakes when hit, a ball rolls down
//! an incline at (5/7) g sin θ (or slides at g (sin θ − μ cos θ)), a four-bar linkage stays
//! closed to 1e-8 m, a spinning free body keeps its straight-line velocity, a speculative
//! contact gets rows only when the step can close its gap.

use gelenk::collision::MeshOptions;
use gelenk::constraints::ContactParameters;
use gelenk::math::{axis_angle, Transform, Vec3};
use gelenk::model::{BodySpec, Joint, JointLimits, ModelBuilder, RigidInertia, Shape};
use gelenk::world::{Motor, SolverKind, World, WorldOptions};

fn lone_body(name: &str, shape: Shape, inertia: RigidInertia) -> gelenk::Model {
    let mut b = ModelBuilder::new();
    b.add_body(
        BodySpec::new(name, "universe", Joint::Free, Transform::identity(), inertia)
            .with_collision(shape, Transform::identity()),
    );
    b.build().unwrap()
}

/// Adds a free 1 kg solid ball of radius `r` named "ball"; returns its multibody index.
fn add_ball(w: &mut World, r: f64) -> usize {
    w.add_multibody(
        "ball",
        lone_body("ball", Shape::Sphere { radius: r }, RigidInertia::solid_sphere(1.0, r)),
        &MeshOptions::default(),
    )
    .unwrap()
}

fn world_with_ground(options: WorldOptions, normal: Vec3) -> World {
    let mut w = World::new(options);
    w.add_static("ground", &Shape::HalfSpace { normal }, Transform::identity(), 0).unwrap();
    w
}

fn exact_options() -> WorldOptions {
    WorldOptions {
        solvers: vec![SolverKind::Lemke { facets: 8 }, SolverKind::Clarabel],
        tolerance: 1e-8,
        ..Default::default()
    }
}

#[test]
fn ball_rebounds_to_epsilon_squared_height() {
    let mut options = exact_options();
    options.dt = 1e-4;
    options.contact =
        ContactParameters { restitution: 0.8, bounce_velocity: 0.01, mu: 0.0, ..Default::default() };
    options.collision.margin = 0.02;
    options.sleep.enabled = false;
    let mut w = world_with_ground(options, Vec3::z());
    let r = 0.05;
    let ball = add_ball(&mut w, r);
    let h0 = 1.0;
    w.multibody_mut(ball).state.q[2] = r + h0;
    let mut apex: f64 = 0.0;
    let mut bounced = false;
    let mut last_z = r + h0;
    for _ in 0..20000 {
        w.step().unwrap();
        let z = w.multibody(ball).state.q[2];
        let vz = w.multibody(ball).state.v[2];
        if vz > 0.0 {
            bounced = true;
        }
        if bounced && vz <= 0.0 && z < last_z {
            apex = last_z - r;
            break;
        }
        last_z = z;
    }
    let expected = 0.8f64.powi(2) * h0;
    assert!((apex - expected).abs() < 0.01 * expected, "apex {apex} vs {expected}");
}

#[test]
fn resting_box_stays_still() {
    let mut options = exact_options();
    options.sleep.enabled = false;
    let mut w = world_with_ground(options, Vec3::z());
    let side = 0.2;
    let b = w
        .add_multibody(
            "box",
            lone_body(
                "box",
                Shape::Box { size: Vec3::repeat(side) },
                RigidInertia::solid_box(1.0, Vec3::repeat(side)),
            ),
            &MeshOptions::default(),
        )
        .unwrap();
    w.multibody_mut(b).state.q[2] = side / 2.0;
    for _ in 0..500 {
        w.step().unwrap();
    }
    let x1 = w.multibody(b).state.q.clone();
    for _ in 0..4500 {
        w.step().unwrap();
        assert!(w.multibody(b).state.v.norm() < 1e-6, "v = {}", w.multibody(b).state.v.norm());
    }
    let drift = (w.multibody(b).state.q.clone() - x1).norm();
    assert!(drift < 1e-6, "drift {drift}");
}

/// A ball 15 mm above the ground with a 50 mm contact margin: the contact is reported either
/// way, but gets rows only when the step can close its gap (`Speculation`): not at rest, yes
/// at 5 m/s downwards (10 mm per step, doubled), and yes at rest when every contact within the
/// margin is asked for. A ball at 10 m/s 8 mm up (20 mm per step) is stopped by its speculative
/// row without sinking into the ground.
#[test]
fn speculative_contacts_get_rows_only_when_the_step_can_close_them() {
    use gelenk::constraints::Speculation;
    let r = 0.05;
    let ball_above = |gap: f64, vz: f64, speculation: Speculation| {
        let mut options = exact_options();
        options.collision.margin = 0.05;
        options.speculation = speculation;
        options.sleep.enabled = false;
        let mut w = world_with_ground(options, Vec3::z());
        let ball = add_ball(&mut w, r);
        w.multibody_mut(ball).state.q[2] = r + gap;
        w.multibody_mut(ball).state.v[2] = vz;
        let stats = w.step().unwrap().clone();
        (stats.contacts, stats.rows, w.multibody(ball).state.q[2] - r)
    };
    let default = Speculation::default();
    assert_eq!(default, Speculation { always_within: 0.002, speed_factor: 2.0 });
    let (contacts, rows, _) = ball_above(0.015, 0.0, default);
    assert_eq!((contacts, rows), (1, 0), "at rest, 15 mm up");
    let (contacts, rows, _) = ball_above(0.015, -5.0, default);
    assert_eq!((contacts, rows), (1, 3), "at 5 m/s, 15 mm up");
    let (contacts, rows, _) = ball_above(0.015, 0.0, Speculation::ALL);
    assert_eq!((contacts, rows), (1, 3), "every contact within the margin");
    let (contacts, rows, _) = ball_above(0.0015, 0.0, default);
    assert_eq!((contacts, rows), (1, 3), "within always_within");
    let (_, rows, height) = ball_above(0.008, -10.0, default);
    assert_eq!(rows, 3);
    assert!(height.abs() < 1e-9, "the fast ball stops on the ground: height {height}");
}

/// A contact that the speculation test leaves out (3 mm apart, nothing moving before the step)
/// gets rows when the solve of the step's other rows closes it: a seesaw's end (a ball 0.5 m
/// from its hinge) is swung down at 2.5 m/s (5 mm per step) by the hinge's motor, a row the
/// speculation cannot see coming. It stops on the ground; without the check after the solve it
/// went 2 mm into it in the first step.
#[test]
fn a_contact_left_out_by_the_speculation_gets_rows_when_the_solve_closes_it() {
    let (r, arm, gap) = (0.05, 0.5, 0.003);
    let mut options = exact_options();
    options.collision.margin = 0.02;
    options.sleep.enabled = false;
    let mut w = world_with_ground(options, Vec3::z());
    // The bar's mass at the hinge: gravity gives the free motion no turn.
    let bar = RigidInertia::new(1.0, Vec3::zeros(), nalgebra::Matrix3::identity() * 0.1);
    let mut b = ModelBuilder::new();
    b.add_body(
        BodySpec::new(
            "bar",
            "universe",
            Joint::hinge(Vec3::y()),
            Transform::from_translation(Vec3::new(0.0, 0.0, r + gap)),
            bar,
        )
        .with_collision(Shape::Sphere { radius: r }, Transform::from_translation(Vec3::new(-arm, 0.0, 0.0))),
    );
    let seesaw = w.add_multibody("seesaw", b.build().unwrap(), &MeshOptions::default()).unwrap();
    // A positive turn about y lifts the end at −x.
    w.multibody_mut(seesaw).set_motor(0, Some(Motor { target_velocity: -5.0, max_force: 100.0 }));
    let bottom = |w: &World| r + gap + arm * w.multibody(seesaw).state.q[0].sin() - r;
    let stats = w.step().unwrap().clone();
    assert_eq!((stats.contacts, stats.rows), (1, 4), "the motor's row and the contact's three");
    assert!(bottom(&w) > -1e-9, "the end stops on the ground: {}", bottom(&w));
    for _ in 0..50 {
        w.step().unwrap();
        assert!(bottom(&w) > -1e-6, "the end stays on the ground: {}", bottom(&w));
    }
}

/// The same for a joint-limit stop: a pendulum hanging still 15 mrad above its lower stop (inside
/// the 20 mrad margin, beyond the 10 mrad `speculative_within`) has no limit row, until its
/// hinge motor swings it toward the stop at 10 rad/s (20 mrad per step): the check after the
/// solve gives the stop its row, and the pendulum ends the step on it instead of 5 mrad past.
#[test]
fn a_limit_left_out_by_the_speculation_gets_its_row_when_the_solve_closes_it() {
    let lower = -0.015;
    let mut options = exact_options();
    options.dt = 2e-3;
    options.sleep.enabled = false;
    let mut w = World::new(options);
    let p = w.add_multibody("pendulum", pendulum(lower), &MeshOptions::default()).unwrap();
    w.multibody_mut(p).set_motor(0, Some(Motor { target_velocity: -10.0, max_force: 5000.0 }));
    let stats = w.step().unwrap().clone();
    assert_eq!(stats.rows, 2, "the motor's row and the stop's");
    let q = w.multibody(p).state.q[0];
    assert!(q >= lower - 1e-9, "ends the step on the stop: q = {q}");
    for _ in 0..50 {
        w.step().unwrap();
        let q = w.multibody(p).state.q[0];
        assert!(q >= lower - 1e-6, "stays on the stop: q = {q}");
    }
}

/// A 0.2 m, 1 kg box resting on the ground with μ = 0.5 at dt = 1 ms, pushed at 2 m/s along
/// `direction` (unit, horizontal): its displacement (x, y) after 3 s and the fallbacks on the way
/// (but `newton-exact`'s).
fn slide_box(mut options: WorldOptions, direction: [f64; 2]) -> ((f64, f64), usize) {
    options.dt = 1e-3;
    options.contact = ContactParameters { mu: 0.5, ..Default::default() };
    options.sleep.enabled = false;
    let mut w = world_with_ground(options, Vec3::z());
    let side = 0.2;
    let b = w
        .add_multibody(
            "box",
            lone_body(
                "box",
                Shape::Box { size: Vec3::repeat(side) },
                RigidInertia::solid_box(1.0, Vec3::repeat(side)),
            ),
            &MeshOptions::default(),
        )
        .unwrap();
    w.multibody_mut(b).state.q[2] = side / 2.0;
    for _ in 0..50 {
        w.step().unwrap();
    }
    let (x0, y0) = (w.multibody(b).state.q[0], w.multibody(b).state.q[1]);
    let v0 = 2.0;
    w.multibody_mut(b).state.v[0] = v0 * direction[0];
    w.multibody_mut(b).state.v[1] = v0 * direction[1];
    // The default chain starts with `newton-exact`, whose relaxed answer for a sliding contact
    // fails the exact certificate by design and is passed on: those are not counted.
    let mut fallbacks = 0;
    for _ in 0..3000 {
        fallbacks += w.step().unwrap().fallbacks.iter().filter(|f| f.solver != "newton-exact").count();
    }
    let q = &w.multibody(b).state.q;
    ((q[0] - x0, q[1] - y0), fallbacks)
}

#[test]
fn sliding_box_stops_after_v0_squared_over_two_mu_g() {
    let ((distance, _), _) = slide_box(exact_options(), [1.0, 0.0]);
    let expected = 2.0 * 2.0 / (2.0 * 0.5 * 9.81);
    assert!((distance - expected).abs() < 0.02 * expected, "distance {distance} vs {expected}");
}

/// MuJoCo's pyramidal friction (`FrictionModel::Pyramid { facets: 4 }`: `|λ₁| + |λ₂| ≤ μ λ_n`)
/// with the default chain (PGS with its linear subspace steps answering each sliding step,
/// certified at 1e-6 m/s): a box
/// sliding along a tangent axis (a vertex of the pyramid) stops after v₀²/(2μg) like with the
/// cone; sliding along the diagonal (a facet: the friction along the motion is μ/√2 per unit
/// normal force) it goes √2 times as far and stays on the diagonal.
#[test]
fn pyramid_friction_stops_a_box_after_the_distance_its_facets_give() {
    use gelenk::constraints::FrictionModel;
    let slide = |direction: [f64; 2]| {
        let options = WorldOptions { friction: FrictionModel::Pyramid { facets: 4 }, ..Default::default() };
        let (displacement, fallbacks) = slide_box(options, direction);
        assert_eq!(fallbacks, 0, "every sliding step certified by PGS");
        displacement
    };
    let axis = 4.0 / (2.0 * 0.5 * 9.81);
    let (dx, dy) = slide([1.0, 0.0]);
    assert!((dx - axis).abs() < 0.02 * axis && dy.abs() < 1e-6, "along x: ({dx}, {dy}) vs {axis}");
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let (dx, dy) = slide([h, h]);
    let (along, across) = ((dx + dy) * h, (dx - dy) * h);
    let expected = std::f64::consts::SQRT_2 * axis;
    println!("diagonal: {along:.5} m along (expected {expected:.5}), {across:.2e} m across");
    assert!((along - expected).abs() < 0.02 * expected, "along the diagonal: {along} vs {expected}");
    assert!(across.abs() < 1e-3 * expected, "off the diagonal by {across}");
}

#[test]
fn box_on_incline_sticks_iff_mu_at_least_tan_theta() {
    let theta: f64 = 20f64.to_radians();
    for (mu, sticks) in [(0.30, false), (0.42, true)] {
        let mut options = exact_options();
        options.dt = 1e-3;
        options.contact = ContactParameters { mu, ..Default::default() };
        options.sleep.enabled = false;
        let normal = axis_angle(&Vec3::y(), theta) * Vec3::z();
        let mut w = world_with_ground(options, normal);
        let side = 0.2;
        let b = w
            .add_multibody(
                "box",
                lone_body(
                    "box",
                    Shape::Box { size: Vec3::repeat(side) },
                    RigidInertia::solid_box(1.0, Vec3::repeat(side)),
                ),
                &MeshOptions::default(),
            )
            .unwrap();
        let rot = nalgebra::UnitQuaternion::from_axis_angle(&Vec3::y_axis(), theta);
        let centre = normal * (side / 2.0);
        let q = &mut w.multibody_mut(b).state.q;
        q.rows_mut(0, 3).copy_from(&centre);
        q[3] = rot.i;
        q[4] = rot.j;
        q[5] = rot.k;
        q[6] = rot.w;
        for _ in 0..1000 {
            w.step().unwrap();
        }
        let moved = (w.multibody(b).state.q.rows(0, 3) - centre).norm();
        if sticks {
            assert!(moved < 1e-3, "μ = {mu}: moved {moved}");
        } else {
            // a = g (sin θ − μ cos θ): 1 s of sliding.
            let expected = 0.5 * 9.81 * (theta.sin() - mu * theta.cos());
            assert!(
                (moved - expected).abs() < 0.05 * expected,
                "μ = {mu}: moved {moved}, expected {expected}"
            );
        }
    }
}

fn pendulum(lower: f64) -> gelenk::Model {
    let mut b = ModelBuilder::new();
    let rod = RigidInertia::new(1.0, Vec3::new(0.0, 0.0, -0.5), nalgebra::Matrix3::identity() * 1e-3);
    b.add_body(
        BodySpec::new("arm", "universe", Joint::hinge(Vec3::y()), Transform::identity(), rod)
            .with_limits(JointLimits { lower: vec![lower], upper: vec![3.0], ..Default::default() }),
    );
    b.build().unwrap()
}

#[test]
fn pendulum_stops_at_its_limit_and_a_motor_reaches_its_target() {
    let mut options = exact_options();
    options.sleep.enabled = false;
    let mut w = World::new(options);
    // The hanging position q = 0 lies beyond the lower limit 0.3: the pendulum falls onto the
    // stop and stays there.
    let p = w.add_multibody("pendulum", pendulum(0.3), &MeshOptions::default()).unwrap();
    w.multibody_mut(p).state.q[0] = 1.0;
    for _ in 0..2000 {
        w.step().unwrap();
        assert!(w.multibody(p).state.q[0] > 0.3 - 0.01, "q = {}", w.multibody(p).state.q[0]);
    }
    let q = w.multibody(p).state.q[0];
    assert!((q - 0.3).abs() < 0.002, "rests at the limit: {q}");

    let mut w = World::new(exact_options());
    let p = w.add_multibody("pendulum", pendulum(-3.0), &MeshOptions::default()).unwrap();
    w.multibody_mut(p).set_motor(0, Some(Motor { target_velocity: 1.0, max_force: 50.0 }));
    for _ in 0..200 {
        w.step().unwrap();
    }
    assert!((w.multibody(p).state.v[0] - 1.0).abs() < 1e-9, "v = {}", w.multibody(p).state.v[0]);
}

/// Joint limits are speculative like contacts: the pendulum held by gravity toward its stop
/// 15 mrad away (inside the 20 mrad limit margin, beyond the 10 mrad `speculative_within`)
/// gets no limit row at rest, where the step cannot close the gap, but gets one when it swings
/// at 5 rad/s (10 mrad per step, doubled), and at rest when every stop within the margin is
/// asked for.
#[test]
fn limit_rows_are_speculative_like_contacts() {
    use gelenk::constraints::Speculation;
    let rows_at = |q: f64, v: f64, speculation: Speculation| {
        let mut options = exact_options();
        options.dt = 2e-3;
        options.speculation = speculation;
        options.sleep.enabled = false;
        let mut w = World::new(options);
        let p = w.add_multibody("pendulum", pendulum(0.3), &MeshOptions::default()).unwrap();
        w.multibody_mut(p).state.q[0] = q;
        w.multibody_mut(p).state.v[0] = v;
        w.step().unwrap().rows
    };
    let default = Speculation::default();
    assert_eq!(gelenk::constraints::JointLimitParameters::default().speculative_within, 0.01);
    assert_eq!(rows_at(0.315, 0.0, default), 0, "at rest, 15 mrad from the stop");
    assert_eq!(rows_at(0.315, -5.0, default), 1, "at 5 rad/s toward the stop");
    assert_eq!(rows_at(0.315, 5.0, default), 1, "at 5 rad/s away (the speed, not its sign, counts)");
    assert_eq!(rows_at(0.315, 0.0, Speculation::ALL), 1, "every stop within the margin");
    assert_eq!(rows_at(0.305, 0.0, default), 1, "within speculative_within");
    assert_eq!(rows_at(0.35, -5.0, default), 0, "outside the margin");
}

#[test]
fn two_runs_are_bit_identical_and_substeps_are_capped() {
    let run = || {
        let mut w = world_with_ground(WorldOptions::default(), Vec3::z());
        for k in 0..3 {
            let b = w
                .add_multibody(
                    &format!("b{k}"),
                    lone_body(
                        "b",
                        Shape::Box { size: Vec3::repeat(0.1) },
                        RigidInertia::solid_box(0.5, Vec3::repeat(0.1)),
                    ),
                    &MeshOptions::default(),
                )
                .unwrap();
            let q = &mut w.multibody_mut(b).state.q;
            q[0] = 0.02 * k as f64;
            q[2] = 0.06 + 0.12 * k as f64;
            q[3] = 0.1;
            q[6] = (1.0f64 - 0.01).sqrt();
        }
        for _ in 0..300 {
            w.step().unwrap();
        }
        (0..3)
            .flat_map(|k| w.multibody(k).state.q.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
            .collect::<Vec<_>>()
    };
    assert_eq!(run(), run());

    let mut w = World::new(WorldOptions { max_substeps: 4, ..Default::default() });
    w.add_multibody("p", pendulum(-3.0), &MeshOptions::default()).unwrap();
    let alpha = w.advance(1.0).unwrap();
    assert_eq!(w.stats().step, 4);
    assert!((0.0..1.0).contains(&alpha));
}

#[test]
fn a_sleeping_stack_sleeps_and_wakes_when_hit() {
    let mut w = world_with_ground(WorldOptions::default(), Vec3::z());
    let side = 0.1;
    let make = || {
        lone_body(
            "b",
            Shape::Box { size: Vec3::repeat(side) },
            RigidInertia::solid_box(0.5, Vec3::repeat(side)),
        )
    };
    for k in 0..3 {
        let b = w.add_multibody(&format!("b{k}"), make(), &MeshOptions::default()).unwrap();
        w.multibody_mut(b).state.q[2] = side / 2.0 + side * k as f64;
    }
    for _ in 0..1000 {
        w.step().unwrap();
    }
    assert_eq!(w.stats().asleep, 3, "all asleep: {:?}", w.stats());
    let top = w.multibody(2).state.q.clone();
    for _ in 0..100 {
        w.step().unwrap();
    }
    assert_eq!(w.multibody(2).state.q, top, "asleep bodies do not move");
    // A ball thrown at the top box wakes it.
    let ball = add_ball(&mut w, 0.05);
    {
        let s = &mut w.multibody_mut(ball).state;
        s.q[0] = -0.3;
        s.q[2] = 0.25;
        s.v[0] = 5.0;
    }
    for _ in 0..200 {
        w.step().unwrap();
    }
    assert!((w.multibody(2).state.q.clone() - top).norm() > 1e-3, "the top box was hit and moved");
}

#[test]
fn head_on_elastic_impact_conserves_momentum_and_energy() {
    let mut options = exact_options();
    options.gravity = Vec3::zeros();
    options.diagnostics = true;
    options.sleep.enabled = false;
    options.contact =
        ContactParameters { mu: 0.0, restitution: 1.0, bounce_velocity: 0.0, erp: 0.0, ..Default::default() };
    let mut w = World::new(options);
    let r = 0.1;
    let sphere = |m: f64| lone_body("s", Shape::Sphere { radius: r }, RigidInertia::solid_sphere(m, r));
    let a = w.add_multibody("a", sphere(1.0), &MeshOptions::default()).unwrap();
    let b = w.add_multibody("b", sphere(3.0), &MeshOptions::default()).unwrap();
    w.multibody_mut(a).state.q[0] = -0.3;
    w.multibody_mut(a).state.v[0] = 2.0;
    w.multibody_mut(b).state.q[0] = 0.3;
    w.multibody_mut(b).state.v[0] = -1.0;
    let p0 = w.linear_momentum();
    let e0 = w.total_energy();
    let mut touched = false;
    for _ in 0..400 {
        let s = w.step().unwrap();
        touched |= s.contacts > 0;
        let p = s.momentum.unwrap();
        assert!((p - p0).norm() < 1e-12, "momentum {p:?} vs {p0:?}");
        assert!(s.energy.unwrap() <= e0 * (1.0 + 1e-12), "energy grew: {} > {e0}", s.energy.unwrap());
    }
    assert!(touched);
    // Elastic 1-D impact: v_a' = ((m_a − m_b) v_a + 2 m_b v_b)/(m_a + m_b) = −2.5, v_b' = 0.5.
    let (va, vb) = (w.multibody(a).state.v[0], w.multibody(b).state.v[0]);
    assert!((va + 2.5).abs() < 1e-9 && (vb - 0.5).abs() < 1e-9, "after: {va}, {vb}");
}

/// Least-squares fit of s(t) = s₀ + v₀ t + ½ a t² to samples (t, s); returns a (m/s²).
fn fitted_acceleration(samples: &[(f64, f64)]) -> f64 {
    let mut normal = nalgebra::Matrix3::<f64>::zeros();
    let mut rhs = Vec3::zeros();
    for &(t, s) in samples {
        let basis = Vec3::new(1.0, t, 0.5 * t * t);
        normal += basis * basis.transpose();
        rhs += basis * s;
    }
    normal.cholesky().expect("enough samples").solve(&rhs)[2]
}

/// A ball (sphere on a free joint) released at rest on a 20° incline. The incline is a static
/// half-space whose normal is turned by θ about y (gravity stays −z): the World supports rotated
/// static half-spaces, so the scene needs no special frame. Returns the acceleration of the
/// centre along the slope fitted over 1 s, and the largest slip speed |v_contact point| seen.
fn ball_on_incline(mu: f64, theta: f64) -> (f64, f64) {
    let mut options = exact_options();
    options.dt = 1e-3;
    options.contact = ContactParameters { mu, ..Default::default() };
    options.sleep.enabled = false;
    let normal = axis_angle(&Vec3::y(), theta) * Vec3::z();
    let down_slope = Vec3::new(theta.cos(), 0.0, -theta.sin());
    let mut w = world_with_ground(options, normal);
    let r = 0.1;
    let ball = add_ball(&mut w, r);
    w.multibody_mut(ball).state.q.rows_mut(0, 3).copy_from(&(normal * r));
    let x0: Vec3 = w.multibody(ball).state.q.fixed_rows::<3>(0).into();
    let (mut samples, mut slip) = (Vec::new(), 0.0f64);
    for k in 1..=1000 {
        w.step().unwrap();
        let s = &w.multibody(ball).state;
        let x: Vec3 = s.q.fixed_rows::<3>(0).into();
        samples.push((k as f64 * 1e-3, (x - x0).dot(&down_slope)));
        // Contact point velocity v + ω × (−r n), in body axes (the free joint's v is local).
        let rotation = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            s.q[6], s.q[3], s.q[4], s.q[5],
        ));
        let (v, omega): (Vec3, Vec3) = (s.v.fixed_rows::<3>(0).into(), s.v.fixed_rows::<3>(3).into());
        let n_local = rotation.inverse() * normal;
        slip = slip.max((v + omega.cross(&(-n_local * r))).norm());
    }
    (fitted_acceleration(&samples), slip)
}

#[test]
fn ball_on_incline_rolls_at_five_sevenths_g_sin_theta_or_slides() {
    let (g, theta) = (9.81, 20f64.to_radians());
    let rolling_threshold = 2.0 / 7.0 * theta.tan(); // 0.104
                                                     // Rolls without slipping: μ = 0.3 ≥ (2/7) tan θ. The solver is exact (Lemke, 1e-8), so the
                                                     // only errors are the O(h) of the integrator (h/T = 1e-3) and the fit: 1 % is ample.
    let (a, slip) = ball_on_incline(0.3, theta);
    println!("rolling: a = {a} m/s², slip {slip} m/s");
    let rolling = 5.0 / 7.0 * g * theta.sin();
    assert!(0.3 >= rolling_threshold);
    assert!((a - rolling).abs() < 0.01 * rolling, "rolling: a = {a}, expected {rolling}, slip {slip}");
    assert!(slip < 1e-6, "rolling without slip, slip speed {slip}");
    // Slides: μ = 0.03, well below (2/7) tan θ; a = g (sin θ − μ cos θ).
    let (a, slip) = ball_on_incline(0.03, theta);
    println!("sliding: a = {a} m/s², slip {slip} m/s");
    let sliding = g * (theta.sin() - 0.03 * theta.cos());
    assert!((a - sliding).abs() < 0.01 * sliding, "sliding: a = {a}, expected {sliding}");
    assert!(slip > 0.1, "the contact point slips: {slip}");
}

#[test]
fn four_bar_linkage_keeps_its_closure_below_1e_8_m() {
    // The four-bar linkage of `gelenk::scenes`: a chain of three hinges (crank, coupler,
    // rocker) whose rocker tip is closed by a hinge loop joint to a world point.
    let mut options = exact_options();
    options.dt = 1e-3;
    options.diagnostics = true;
    options.sleep.enabled = false;
    let (mut w, m) = gelenk::scenes::four_bar_world(options).unwrap();
    let phi1 = gelenk::scenes::FOUR_BAR_CRANK_ANGLE;
    let start = w.constraint_violation();
    assert!(start < 1e-12, "the initial configuration is closed: {start}");
    let mut worst: f64 = 0.0;
    let mut swing: f64 = 0.0;
    for _ in 0..10_000 {
        let s = w.step().unwrap();
        worst = worst.max(s.constraint_violation.unwrap());
        swing = swing.max((w.multibody(m).state.q[0] - phi1).abs());
    }
    println!("four-bar: closure error ≤ {worst} m, crank swing {swing} rad");
    assert!(swing > 0.5, "the linkage moves under gravity: crank swing {swing} rad");
    assert!(worst < 1e-8, "closure error {worst} m");
}

#[test]
fn a_spinning_free_body_keeps_its_straight_line_velocity() {
    // Without gravity or contact the centre of a box spinning at 20 rad/s must move on a
    // straight line at constant speed. The world advances the origin on a straight line and
    // carries v into the new axes exactly, so only rounding remains (1e-12 over 1000 steps);
    // body-frame velocities integrated with an explicit −ω × v term would grow by
    // √(1 + (ωh)²) per step (+22 % over 1 s here).
    let mut options = exact_options();
    options.gravity = Vec3::zeros();
    options.dt = 1e-3;
    options.sleep.enabled = false;
    let mut w = World::new(options);
    let side = Vec3::new(0.3, 0.2, 0.1);
    let b = w
        .add_multibody(
            "box",
            lone_body("box", Shape::Box { size: side }, RigidInertia::solid_box(1.0, side)),
            &MeshOptions::default(),
        )
        .unwrap();
    {
        let s = &mut w.multibody_mut(b).state;
        s.v[0] = 1.0;
        s.v[5] = 20.0;
    }
    for k in 1..=1000 {
        w.step().unwrap();
        let s = &w.multibody(b).state;
        let x = Vec3::new(s.q[0], s.q[1], s.q[2]);
        let expected = Vec3::new(k as f64 * 1e-3, 0.0, 0.0);
        assert!((x - expected).norm() < 1e-12, "step {k}: centre {x:?}, expected {expected:?}");
        let speed = Vec3::new(s.v[0], s.v[1], s.v[2]).norm();
        assert!((speed - 1.0).abs() < 1e-12, "step {k}: speed {speed}");
    }
}

/// Equal boxes stacked face on face have their corners exactly on each other's face edges,
/// where the box–box clipping decides by rounding: without the corner completion of the narrow
/// phase a 20-stack's pairs had 2, 3 or 4 contacts from step to step (156…240 rows), and the
/// stack settled by 2.4 mm under clarabel. Every pair keeps its 4 corners while it rests.
#[test]
fn a_stack_of_equal_boxes_keeps_four_contacts_per_face() {
    let mut options = WorldOptions { solvers: vec![SolverKind::Clarabel], ..exact_options() };
    options.dt = 1.0 / 60.0;
    options.sleep.enabled = false;
    let mut w = world_with_ground(options, Vec3::z());
    let side = 0.1;
    let count = 20;
    let mut top = 0;
    for k in 0..count {
        let size = Vec3::repeat(side);
        top = w
            .add_multibody(
                &format!("box{k}"),
                lone_body("box", Shape::Box { size }, RigidInertia::solid_box(1.0, size)),
                &MeshOptions::default(),
            )
            .unwrap();
        w.multibody_mut(top).state.q[2] = side / 2.0 + side * k as f64;
    }
    let start = w.multibody(top).state.q[2];
    for step in 0..60 {
        let rows = w.step().unwrap().rows;
        assert_eq!(rows, 3 * 4 * count, "step {step}: {rows} rows, not 4 contacts per face");
    }
    let drift = (w.multibody(top).state.q[2] - start).abs();
    assert!(drift < 1e-6, "the top box moved {drift} m in 1 s");
}

/// The default chain starts with `newton-exact`: a resting stack is answered by Newton's method
/// certified on the exact formulation, a sliding box by PGS, the chain passing over
/// `newton-exact` for `skip_first_after_miss` steps after each miss.
#[test]
fn the_default_chain_answers_resting_contacts_by_newton_and_sliding_ones_by_pgs() {
    let mut options = WorldOptions { dt: 1.0 / 60.0, ..Default::default() };
    options.contact = ContactParameters { mu: 0.5, ..Default::default() };
    options.sleep.enabled = false;
    let skip = options.skip_first_after_miss;
    assert!(skip > 0);
    let cube = || {
        lone_body(
            "box",
            Shape::Box { size: Vec3::repeat(0.1) },
            RigidInertia::solid_box(1.0, Vec3::repeat(0.1)),
        )
    };
    // Five boxes stacked, resting: after they settle every step is Newton's.
    let mut w = world_with_ground(options.clone(), Vec3::z());
    for k in 0..5 {
        let b = w.add_multibody(&format!("box{k}"), cube(), &MeshOptions::default()).unwrap();
        w.multibody_mut(b).state.q[2] = 0.05 + 0.1 * k as f64;
    }
    for _ in 0..60 {
        w.step().unwrap();
    }
    for _ in 0..120 {
        let stats = w.step().unwrap();
        assert_eq!(stats.solver, "newton-exact", "fallbacks {:?}", stats.fallbacks);
    }
    // A box sliding at 2 m/s (μ 0.5 stops it in 0.41 s, 24 steps): PGS answers every sliding
    // step, and newton-exact is tried only on the first.
    let mut w = world_with_ground(options, Vec3::z());
    let b = w.add_multibody("box", cube(), &MeshOptions::default()).unwrap();
    w.multibody_mut(b).state.q[2] = 0.05;
    for _ in 0..30 {
        w.step().unwrap();
    }
    w.multibody_mut(b).state.v[0] = 2.0;
    let mut tried = 0;
    for _ in 0..20 {
        let stats = w.step().unwrap();
        assert!(stats.solver.starts_with("pgs"), "a sliding step answered by {}", stats.solver);
        tried += stats.fallbacks.iter().filter(|f| f.solver == "newton-exact").count();
    }
    assert_eq!(tried, 1, "newton-exact tried on {tried} of 20 sliding steps");
}
