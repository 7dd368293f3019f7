//! In steady state (the same contacts from step to step), `World::step` performs zero heap
//! allocations (nor does collision detection): a stack of three boxes resting on the ground, solved by projected Gauss–Seidel,
//! three stacks solved as three islands,
//! a free pendulum without contacts (ABA path), and a resting ragdoll (joint damping: the
//! implicit free motion, with its mass-matrix factor kept and computed again; the dense mass
//! matrix is never formed).

use gelenk::collision::MeshOptions;
use gelenk::math::{Transform, Vec3};
use gelenk::model::{BodySpec, Joint, ModelBuilder, RigidInertia, Shape};
use gelenk::world::{SolverKind, World, WorldOptions};

#[path = "common/counting_allocator.rs"]
mod counting_allocator;
use counting_allocator::allocations_in;

/// Allocations made by this thread while running `f`.
fn allocations_during(f: impl FnOnce()) -> usize {
    allocations_in(f).0
}

/// A free body on the universe with one collider at its origin.
fn free_body(name: impl Into<String>, inertia: RigidInertia, shape: Shape) -> BodySpec {
    BodySpec::new(name, "universe", Joint::Free, Transform::identity(), inertia)
        .with_collision(shape, Transform::identity())
}

/// A free cube of 0.5 kg.
fn free_cube(name: impl Into<String>, side: f64) -> BodySpec {
    free_body(name, RigidInertia::solid_box(0.5, Vec3::repeat(side)), Shape::Box { size: Vec3::repeat(side) })
}

fn lone_box(side: f64) -> gelenk::Model {
    let mut b = ModelBuilder::new();
    b.add_body(free_cube("box", side));
    b.build().unwrap()
}

#[test]
fn resting_stack_steps_without_allocating() {
    let mut options = WorldOptions {
        solvers: vec![SolverKind::Pgs { iterations: 30, omega: 1.0 }],
        accept_last: true,
        ..Default::default()
    };
    options.sleep.enabled = false;
    let mut w = World::new(options);
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    for k in 0..3 {
        let b = w.add_multibody(&format!("box{k}"), lone_box(0.1), &MeshOptions::default()).unwrap();
        w.multibody_mut(b).state.q[2] = 0.05 + 0.1 * k as f64;
    }
    for _ in 0..300 {
        w.step().unwrap();
    }
    let contacts = w.stats().contacts;
    assert_eq!(contacts, 12, "{:?}", w.stats());
    let mut failures = 0;
    let count = allocations_during(|| {
        for _ in 0..50 {
            if w.step().is_err() {
                failures += 1;
            }
        }
    });
    assert_eq!(failures, 0);
    assert_eq!(w.stats().contacts, contacts);
    assert_eq!(count, 0, "World::step allocated {count} times in 50 steady steps");
}

/// Three stacks of two boxes side by side: three islands, each extracted into its own problem
/// and solved by its own chain, with every buffer kept from the last step (on this thread; the
/// counting allocator does not see rayon's threads).
#[test]
fn resting_stacks_solved_as_islands_step_without_allocating() {
    let mut options = WorldOptions {
        solvers: vec![SolverKind::Pgs { iterations: 30, omega: 1.0 }],
        accept_last: true,
        ..Default::default()
    };
    options.sleep.enabled = false;
    let mut w = World::new(options);
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    for stack in 0..3 {
        for k in 0..2 {
            let b =
                w.add_multibody(&format!("box{stack}_{k}"), lone_box(0.1), &MeshOptions::default()).unwrap();
            let q = &mut w.multibody_mut(b).state.q;
            q[0] = 0.5 * stack as f64;
            q[2] = 0.05 + 0.1 * k as f64;
        }
    }
    for _ in 0..300 {
        w.step().unwrap();
    }
    assert_eq!(w.stats().islands, 3, "{:?}", w.stats());
    assert_eq!(w.stats().contacts, 24, "{:?}", w.stats());
    let count = allocations_during(|| {
        for _ in 0..50 {
            w.step().unwrap();
        }
    });
    assert_eq!(w.stats().islands, 3);
    assert_eq!(count, 0, "World::step allocated {count} times in 50 steady steps of three islands");
}

/// The contact projection (docs/collision.md) in steady use: a box pressed 1 mm into the ground
/// before every step is pushed back out by the predicted gaps' correction, and a box sliding
/// on the frictionless ground at 1 m/s (2 mm per step, more than the slop) has its contacts
/// detected again at the end of every step; neither allocates once the buffers have grown.
#[test]
fn the_contact_projection_steps_without_allocating() {
    let mut options = WorldOptions::default();
    options.sleep.enabled = false;
    options.contact.mu = 0.0;
    let mut w = World::new(options);
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    let pressed = w.add_multibody("pressed", lone_box(0.1), &MeshOptions::default()).unwrap();
    let sliding = w.add_multibody("sliding", lone_box(0.1), &MeshOptions::default()).unwrap();
    w.multibody_mut(pressed).state.q[2] = 0.05;
    let q = &mut w.multibody_mut(sliding).state.q;
    (q[1], q[2]) = (1.0, 0.05);
    w.multibody_mut(sliding).state.v[0] = 1.0;
    let step = |w: &mut World| {
        w.multibody_mut(pressed).state.q[2] -= 1e-3;
        let stats = w.step().unwrap();
        (stats.projection.islands, stats.projection.end_check)
    };
    for _ in 0..100 {
        step(&mut w);
    }
    let (mut projected, mut checked) = (0, 0);
    let count = allocations_during(|| {
        for _ in 0..50 {
            let (islands, end_check) = step(&mut w);
            projected += usize::from(islands > 0);
            checked += usize::from(end_check);
        }
    });
    assert_eq!((projected, checked), (50, 50), "every step projects and checks");
    assert_eq!(
        count, 0,
        "World::step allocated {count} times in 50 steps with the contact projection at work"
    );
}

#[test]
fn free_pendulum_steps_without_allocating() {
    let mut b = ModelBuilder::new();
    let rod = RigidInertia::new(1.0, Vec3::new(0.0, 0.0, -0.5), nalgebra::Matrix3::identity() * 1e-2);
    b.add_body(BodySpec::new("l1", "universe", Joint::hinge(Vec3::y()), Transform::identity(), rod));
    b.add_body(BodySpec::new(
        "l2",
        "l1",
        Joint::hinge(Vec3::y()),
        Transform::from_translation(Vec3::new(0.0, 0.0, -1.0)),
        rod,
    ));
    let mut w = World::new(WorldOptions::default());
    let p = w.add_multibody("pendulum", b.build().unwrap(), &MeshOptions::default()).unwrap();
    w.multibody_mut(p).state.q[0] = 1.0;
    for _ in 0..10 {
        w.step().unwrap();
    }
    let count = allocations_during(|| {
        for _ in 0..100 {
            w.step().unwrap();
        }
    });
    assert_eq!(count, 0, "World::step allocated {count} times");
}

#[test]
fn collision_detection_allocates_nothing_in_steady_state() {
    use gelenk::collision::{CollisionOptions, CollisionWorld};
    let mut b = ModelBuilder::new();
    for k in 0..3 {
        b.add_body(free_cube(format!("box{k}"), 0.1));
    }
    let model = b.build().unwrap();
    let mut data = gelenk::Data::new(&model);
    let mut q = model.neutral_configuration();
    for k in 0..3 {
        q[7 * k + 2] = 0.05 + 0.1 * k as f64;
    }
    let mut cw = CollisionWorld::new(CollisionOptions::default());
    let mb = cw.add_model(&model, &MeshOptions::default()).unwrap();
    cw.set_self_collision(mb, true).unwrap();
    cw.add_static(
        "g",
        &Shape::HalfSpace { normal: Vec3::z() },
        Transform::identity(),
        &MeshOptions::default(),
    )
    .unwrap();
    gelenk::algorithms::forward_kinematics(&model, &mut data, &q).unwrap();
    cw.update_multibody(mb, &data).unwrap();
    for _ in 0..5 {
        cw.detect();
    }
    let count = allocations_during(|| {
        for _ in 0..10 {
            cw.detect();
        }
    });
    assert_eq!(count, 0, "CollisionWorld::detect allocated {count} times in 10 calls");
}

/// A wheel (cylinder on its rim) and a box resting on a bumpy height field: each triangle under
/// them keeps its manifold from call to call (parry's own loop rebuilt its list at every call).
#[test]
fn collision_with_a_height_field_allocates_nothing_in_steady_state() {
    use gelenk::collision::{CollisionOptions, CollisionWorld};
    use nalgebra::DMatrix;
    let mut b = ModelBuilder::new();
    // Only the geometry matters here (detection alone, no stepping).
    let inertia = RigidInertia::solid_box(1.0, Vec3::repeat(0.1));
    b.add_body(free_body("wheel", inertia, Shape::Cylinder { radius: 0.3, length: 0.2 }));
    b.add_body(free_body("box", inertia, Shape::Box { size: Vec3::new(0.3, 0.2, 0.1) }));
    let model = b.build().unwrap();
    let mut data = gelenk::Data::new(&model);
    // ±5 cm bumps over 2 m on 25 cm cells, as in models/buggy_terrain.toml.
    let (n, size) = (33, 8.0);
    let height = |x: f64, y: f64| 0.05 * (std::f64::consts::PI * x).sin() * (std::f64::consts::PI * y).cos();
    let at = |i: usize| -size / 2.0 + i as f64 * size / (n - 1) as f64;
    let terrain = Shape::HeightField {
        heights: DMatrix::from_fn(n, n, |i, j| height(at(i), at(j))),
        size_x: size,
        size_y: size,
    };
    let mut cw = CollisionWorld::new(CollisionOptions::default());
    let mb = cw.add_model(&model, &MeshOptions::default()).unwrap();
    cw.add_static("terrain", &terrain, Transform::identity(), &MeshOptions::default()).unwrap();
    let mut q = model.neutral_configuration();
    // The cylinder's axis is its z: turned onto y, it stands on its rim (a wheel) at (0.3, 0.2).
    let axle = nalgebra::UnitQuaternion::from_axis_angle(&Vec3::x_axis(), std::f64::consts::FRAC_PI_2);
    let (x, y) = (0.3, 0.2);
    q.fixed_rows_mut::<3>(0).copy_from(&Vec3::new(x, y, height(x, y) + 0.3 - 1e-4));
    q.fixed_rows_mut::<4>(3).copy_from(&axle.coords);
    let (x, y) = (-0.6, 0.9);
    q.fixed_rows_mut::<3>(7).copy_from(&Vec3::new(x, y, height(x, y) + 0.05 - 1e-4));
    gelenk::algorithms::forward_kinematics(&model, &mut data, &q).unwrap();
    cw.update_multibody(mb, &data).unwrap();
    for _ in 0..5 {
        cw.detect();
    }
    assert!(cw.detect().len() >= 2, "the wheel and the box touch the terrain");
    let count = allocations_during(|| {
        for _ in 0..10 {
            cw.detect();
        }
    });
    assert_eq!(count, 0, "CollisionWorld::detect allocated {count} times in 10 calls");
}

#[test]
fn smooth_steps_allocate_nothing() {
    // RK4 steps of the four-bar (constrained stages and the projection), and Dormand–Prince
    // steps of a free body, after the first step has built the integrators.
    use gelenk::integrators::IntegratorKind;
    let mut options = WorldOptions { dt: 1e-3, integrator: IntegratorKind::Rk4, ..Default::default() };
    options.sleep.enabled = false;
    let (mut four_bar, _) = gelenk::report::stability::four_bar_world(options.clone()).unwrap();
    options.integrator = IntegratorKind::DormandPrince45 { rtol: 1e-9, atol: 1e-12 };
    let mut free = World::new(options);
    let b = free.add_multibody("box", lone_box(0.1), &MeshOptions::default()).unwrap();
    free.multibody_mut(b).state.v[4] = 3.0;
    for _ in 0..10 {
        four_bar.step().unwrap();
        free.step().unwrap();
    }
    assert_eq!((four_bar.stats().integrator, free.stats().integrator), ("rk4", "dopri45"));
    let count = allocations_during(|| {
        for _ in 0..100 {
            four_bar.step().unwrap();
            free.step().unwrap();
        }
    });
    assert_eq!(count, 0, "smooth steps allocated {count} times");
}

/// A ragdoll at rest (joint damping: the implicit free motion, its factor kept between steps
/// and factored again when a joint moves) steps without allocating.
#[test]
fn a_resting_ragdoll_steps_without_allocating() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ragdoll_fall.toml");
    let mut s = gelenk::io::scene::load_file(path).unwrap();
    s.world.set_sleep(gelenk::world::SleepOptions { enabled: false, ..s.world.options().sleep });
    for _ in 0..1500 {
        s.world.step().unwrap();
    }
    let elbow = s.world.multibody(0).model().joint_id("elbow_l").unwrap();
    let iq = s.world.multibody(0).model().idx_q(elbow);
    let before = s.world.multibody(0).factorizations();
    let count = allocations_during(|| {
        for k in 0..100 {
            if k == 50 {
                // A joint turned by 1e-6 rad: the factor is computed and kept again.
                s.world.multibody_mut(0).state.q[iq] += 1e-6;
            }
            s.world.step().unwrap();
        }
    });
    assert!(s.world.multibody(0).factorizations() > before, "no factorization in the counted steps");
    assert_eq!(count, 0, "World::step allocated {count} times in 100 resting steps");
    // The step factors M from its packed rows: the dense nv × nv M (50 MB for a 2500-dof crowd
    // read from one MJCF file) is never formed, until an algorithm that returns it is called.
    let model = s.world.multibody(0).model().clone();
    let q = s.world.multibody(0).state.q.clone();
    let mut data = s.world.multibody(0).data().clone();
    assert_eq!(data.mass_matrix.shape(), (0, 0), "the world's step formed the dense mass matrix");
    let m = gelenk::algorithms::crba(&model, &mut data, &q).unwrap();
    assert_eq!(m.shape(), (model.nv(), model.nv()));
}

#[test]
fn rattle_steps_of_a_linkage_allocate_nothing() {
    // The default step of the free four-bar is RATTLE (its only rows its own closure): the
    // fixed-point sweeps, the factorizations at the step's end and the velocity projection run
    // in buffers sized when the loop was added.
    let mut options = WorldOptions { dt: 1.0 / 60.0, ..Default::default() };
    options.sleep.enabled = false;
    let (mut four_bar, _) = gelenk::report::stability::four_bar_world(options).unwrap();
    for _ in 0..10 {
        four_bar.step().unwrap();
    }
    assert_eq!(four_bar.stats().integrator, "rattle");
    let count = allocations_during(|| {
        for _ in 0..100 {
            four_bar.step().unwrap();
        }
    });
    assert_eq!(count, 0, "RATTLE steps allocated {count} times");
}
