//! Continuous collision: a body that moves further than the contact margin in one step is swept
//! along its motion and stopped by what lies in its path — a 1 cm sphere at up to
//! v·dt/(thickness + 2r) = 1000 against a 2 cm wall, a fast box against a 1 mm plate, two fast
//! spheres head-on — while slow bodies are never swept, and what a sweep cannot do is a typed
//! diagnostic in the step statistics.

use gelenk::collision::{MeshOptions, SweepDiagnostic};
use gelenk::constraints::ContactParameters;
use gelenk::math::{Transform, Vec3};
use gelenk::model::{BodySpec, Joint, Model, ModelBuilder, RigidInertia, Shape};
use gelenk::report::stability::{self, Setting};
use gelenk::world::{World, WorldOptions};

fn free(name: &str, shape: Option<Shape>, inertia: RigidInertia) -> Model {
    let mut spec = BodySpec::new(name, "universe", Joint::Free, Transform::identity(), inertia);
    if let Some(shape) = shape {
        spec = spec.with_collision(shape, Transform::identity());
    }
    let mut b = ModelBuilder::new();
    b.add_body(spec);
    b.build().unwrap()
}

/// A world without gravity or friction, sleeping off, with the default solver chain.
fn world(dt: f64) -> World {
    let mut o = WorldOptions { dt, gravity: Vec3::zeros(), ..Default::default() };
    o.contact = ContactParameters { mu: 0.0, ..Default::default() };
    o.sleep.enabled = false;
    World::new(o)
}

fn x(w: &World, m: usize) -> f64 {
    w.multibody(m).state.q[0]
}

#[test]
fn a_small_fast_sphere_never_passes_a_thin_wall() {
    // The fast_sphere case (1 cm sphere, 2 cm wall 1 m ahead) at v·dt/(thickness + 2r) from 0.5
    // to 1000 and the three time steps of the report; with the default chain.
    let (r, thickness) = (0.01, 0.02);
    for dt in stability::TIME_STEPS {
        for ratio in [0.5, 2.0, 10.0, 100.0, 1000.0] {
            let speed = ratio * (thickness + 2.0 * r) / dt;
            let setting = Setting::new(gelenk::world::SolverKind::Pgs { iterations: 100, omega: 1.0 }, dt);
            let through = stability::tunnels(&setting, speed, r, thickness).unwrap();
            assert!(!through, "dt {dt}, ratio {ratio} ({speed} m/s): tunnels");
        }
    }
}

#[test]
fn the_sphere_ends_against_the_wall_and_tunnels_without_the_sweep() {
    // 1/60 s, 100 m/s: the first step ends with the sphere touching the wall's face (x = 1 − r),
    // not short of it and not beyond it; with continuous collision off it passes through.
    for continuous in [true, false] {
        let mut w = world(1.0 / 60.0);
        w.set_continuous_collision(continuous);
        w.add_static(
            "wall",
            &Shape::Box { size: Vec3::new(0.02, 1.0, 1.0) },
            Transform::from_translation(Vec3::new(1.01, 0.0, 0.0)),
            0,
        )
        .unwrap();
        let m = w
            .add_multibody(
                "ball",
                free("ball", Some(Shape::Sphere { radius: 0.01 }), RigidInertia::solid_sphere(0.01, 0.01)),
                &MeshOptions::default(),
            )
            .unwrap();
        w.multibody_mut(m).state.v[0] = 100.0;
        let stats = w.step().unwrap().clone();
        if continuous {
            assert_eq!(stats.sweeps.hits, 1, "{stats:?}");
            // Against the face to the solver's tolerance (1e-6 m/s over the step).
            assert!((x(&w, m) - 0.99).abs() < 1e-5, "x = {}", x(&w, m));
            for _ in 0..10 {
                w.step().unwrap();
            }
            assert!(x(&w, m) < 0.99 + 1e-6 && x(&w, m) > 0.98, "x = {}", x(&w, m));
        } else {
            assert_eq!(stats.sweeps.swept_colliders, 0);
            w.step().unwrap();
            assert!(x(&w, m) > 1.02, "without the sweep it passes: x = {}", x(&w, m));
        }
    }
}

#[test]
fn a_fast_box_stops_at_a_one_millimetre_plate() {
    // A 10 cm cube at 50 m/s (8 cm per step at 1/60 s... 83 cm) against a 1 mm plate.
    let mut w = world(1.0 / 60.0);
    w.add_static(
        "plate",
        &Shape::Box { size: Vec3::new(0.001, 2.0, 2.0) },
        Transform::from_translation(Vec3::new(1.0, 0.0, 0.0)),
        0,
    )
    .unwrap();
    let side = 0.1;
    let m = w
        .add_multibody(
            "box",
            free(
                "box",
                Some(Shape::Box { size: Vec3::repeat(side) }),
                RigidInertia::solid_box(1.0, Vec3::repeat(side)),
            ),
            &MeshOptions::default(),
        )
        .unwrap();
    w.multibody_mut(m).state.v[0] = 50.0;
    for _ in 0..60 {
        w.step().unwrap();
        assert!(x(&w, m) < 1.0 - side / 2.0 + 1e-3, "box passes the plate: x = {}", x(&w, m));
    }
}

#[test]
fn two_fast_spheres_head_on_do_not_pass_each_other() {
    let mut w = world(1.0 / 60.0);
    let ball = || free("ball", Some(Shape::Sphere { radius: 0.02 }), RigidInertia::solid_sphere(0.1, 0.02));
    let a = w.add_multibody("a", ball(), &MeshOptions::default()).unwrap();
    let b = w.add_multibody("b", ball(), &MeshOptions::default()).unwrap();
    w.multibody_mut(a).state.q[0] = -0.5;
    w.multibody_mut(b).state.q[0] = 0.5;
    w.multibody_mut(a).state.v[0] = 60.0;
    w.multibody_mut(b).state.v[0] = -60.0;
    for _ in 0..20 {
        w.step().unwrap();
        assert!(x(&w, a) < x(&w, b), "a at {}, b at {}", x(&w, a), x(&w, b));
    }
}

#[test]
fn slow_bodies_are_not_swept() {
    // A box resting on the ground and one falling slowly: no collider moves further than the
    // 5 mm margin per step, so nothing is swept and no time of impact is asked.
    let mut o = WorldOptions { dt: 1.0 / 60.0, ..Default::default() };
    o.sleep.enabled = false;
    let mut w = World::new(o);
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    let m = w
        .add_multibody(
            "box",
            free(
                "box",
                Some(Shape::Box { size: Vec3::repeat(0.1) }),
                RigidInertia::solid_box(1.0, Vec3::repeat(0.1)),
            ),
            &MeshOptions::default(),
        )
        .unwrap();
    w.multibody_mut(m).state.q[2] = 0.05;
    for _ in 0..120 {
        let s = w.step().unwrap();
        assert_eq!((s.sweeps.swept_colliders, s.sweeps.casts), (0, 0), "{s:?}");
    }
}

#[test]
fn a_sweep_asked_of_a_body_without_a_shape_is_a_diagnostic() {
    let mut w = world(1.0 / 60.0);
    let m = w
        .add_multibody(
            "ghost",
            free("ghost", None, RigidInertia::solid_sphere(1.0, 0.1)),
            &MeshOptions::default(),
        )
        .unwrap();
    w.set_always_swept(m, 1, true).unwrap();
    w.multibody_mut(m).state.v[0] = 100.0;
    let s = w.step().unwrap();
    assert_eq!(s.sweep_diagnostics, vec![SweepDiagnostic::NoShape { multibody: m, body: 1 }]);
    assert!(w.set_always_swept(m, 2, true).is_err(), "body 2 does not exist");
    assert!(w.set_always_swept(7, 1, true).is_err(), "multibody 7 does not exist");
}

/// The deepest penetration (m) over 1 s of a 40 × 10 × 10 cm box (a limb) dropped tilted at
/// 35° and turning at 4 rad/s from `height` (m) onto the ground at 1/60 s, with a 2 cm
/// contact margin and the default chain.
fn tilted_limb_penetration(continuous: bool, height: f64) -> f64 {
    let mut o = WorldOptions { dt: 1.0 / 60.0, ..Default::default() };
    o.collision.margin = 0.02;
    o.sleep.enabled = false;
    let mut w = World::new(o);
    w.set_continuous_collision(continuous);
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    let size = Vec3::new(0.4, 0.1, 0.1);
    let m = w
        .add_multibody(
            "limb",
            free("limb", Some(Shape::Box { size }), RigidInertia::solid_box(3.0, size)),
            &MeshOptions::default(),
        )
        .unwrap();
    let half = 35f64.to_radians() / 2.0;
    let state = &mut w.multibody_mut(m).state;
    state.q[2] = height;
    (state.q[4], state.q[6]) = (half.sin(), half.cos()); // about y: one end first
    state.v[4] = 4.0;
    let mut deepest = 0.0f64;
    for _ in 0..60 {
        deepest = deepest.max(w.step().unwrap().max_penetration);
    }
    deepest
}

#[test]
fn a_tilted_limb_landing_at_a_games_rate_stays_out_of_the_ground() {
    // It lands at ~4.5–5.4 m/s, 8 cm per step, so where the step before the landing leaves
    // it depends on the height: its lower end is stopped by a speculative point, and the
    // pair's margin, grown by how far the box travels, holds its other points too while it
    // turns onto its face.
    let heights = (0..12).map(|k| 1.0 + 0.05 * f64::from(k));
    let deepest =
        |continuous| heights.clone().map(|z| tilted_limb_penetration(continuous, z)).fold(0.0, f64::max);
    let with = deepest(true);
    assert!(with < 5e-3, "deepest penetration {with} m");
    // The margin alone (no sweep, no growth) lets it sink deeper than 1 cm from some height.
    let without = deepest(false);
    assert!(without > 1e-2, "without continuous collision: {without} m");
}
