//! The velocity-level step's position update for lone free bodies (src/world/stages/midpoint.rs):
//! a lone free body's origin moves with the step's mean velocity along the directions no
//! contact normal constrains, so that a thrown ball follows its parabola exactly and a ball
//! rolling on a slope covers the distance of its constant acceleration; along a contact normal
//! and for a body on a joint the step keeps the end-of-step velocity.

use gelenk::collision::MeshOptions;
use gelenk::math::{Transform, Vec3};
use gelenk::model::{BodySpec, Joint, ModelBuilder, RigidInertia, Shape};
use gelenk::world::{World, WorldOptions};

const H: f64 = 1.0 / 60.0;
const G: f64 = 9.81;

fn options() -> WorldOptions {
    let mut o = WorldOptions { dt: H, ..Default::default() };
    o.sleep.enabled = false;
    o
}

/// A 1 kg ball of radius 5 cm on a free joint; with `tail`, a second ball hinged to it.
fn ball(tail: bool) -> gelenk::Model {
    let mut b = ModelBuilder::new();
    let inertia = RigidInertia::solid_sphere(1.0, 0.05);
    b.add_body(
        BodySpec::new("ball", "universe", Joint::Free, Transform::identity(), inertia)
            .with_collision(Shape::Sphere { radius: 0.05 }, Transform::identity()),
    );
    if tail {
        let placement = Transform::from_translation(Vec3::new(0.0, 0.0, -0.2));
        b.add_body(BodySpec::new("tail", "ball", Joint::hinge(Vec3::y()), placement, inertia));
    }
    b.build().unwrap()
}

#[test]
fn a_thrown_ball_follows_its_parabola_exactly() {
    let mut w = World::new(options());
    let m = w.add_multibody("ball", ball(false), &MeshOptions::default()).unwrap();
    let (p0, v0) = (Vec3::new(0.0, 0.0, 10.0), Vec3::new(3.0, -1.0, 4.0));
    w.multibody_mut(m).state.q[2] = p0.z;
    w.multibody_mut(m).state.v.rows_mut(0, 3).copy_from(&v0);
    let mut worst: f64 = 0.0;
    for k in 1..=60 {
        w.step().unwrap();
        let t = k as f64 * H;
        let exact = p0 + v0 * t - Vec3::z() * (G * t * t / 2.0);
        let q = &w.multibody(m).state.q;
        worst = worst.max((Vec3::new(q[0], q[1], q[2]) - exact).norm());
    }
    // Rounding only; the end-of-step velocity alone would be g h t / 2 = 8 cm low after 1 s.
    assert!(worst < 1e-12, "off the parabola by {worst:e} m");
}

#[test]
fn a_body_on_a_joint_keeps_the_end_of_step_velocity() {
    let mut w = World::new(options());
    let m = w.add_multibody("ball", ball(true), &MeshOptions::default()).unwrap();
    w.multibody_mut(m).state.q[2] = 10.0;
    let steps = 60;
    for _ in 0..steps {
        w.step().unwrap();
    }
    // Semi-implicit Euler in free fall: z = z₀ − g h² n (n + 1) / 2.
    let n = steps as f64;
    let first_order = 10.0 - G * H * H * n * (n + 1.0) / 2.0;
    let z = w.multibody(m).state.q[2];
    assert!((z - first_order).abs() < 1e-9, "z {z} m, first-order step {first_order} m");
}

#[test]
fn a_ball_rolling_down_a_slope_covers_its_constant_acceleration_and_stays_on_it() {
    // A 20° slope through the origin; the ball rolls without slipping at a = (5/7) g sin θ.
    let theta: f64 = 20f64.to_radians();
    let normal = Vec3::new(-theta.sin(), 0.0, theta.cos());
    let down = Vec3::new(theta.cos(), 0.0, theta.sin()) * -1.0;
    let mut o = options();
    o.contact.mu = 0.8;
    let mut w = World::new(o);
    w.add_static("slope", &Shape::HalfSpace { normal }, Transform::identity(), 0).unwrap();
    let m = w.add_multibody("ball", ball(false), &MeshOptions::default()).unwrap();
    let start = normal * 0.05 - down * 5.0;
    w.multibody_mut(m).state.q.rows_mut(0, 3).copy_from(&start);
    let steps = 60;
    for _ in 0..steps {
        w.step().unwrap();
    }
    let q = &w.multibody(m).state.q;
    let p = Vec3::new(q[0], q[1], q[2]);
    let t = steps as f64 * H;
    let exact = 5.0 / 7.0 * G * theta.sin() * t * t / 2.0;
    let along = (p - start).dot(&down);
    let off_plane = (p - start).dot(&normal);
    // Exact but for the first step, where the contact's rows meet the ball at rest.
    assert!((along - exact).abs() < 2e-3 * exact, "rolled {along} m, exact {exact} m");
    assert!(off_plane.abs() < 1e-6, "left the slope by {off_plane} m");
}
