//! Whole-step benchmarks of the scenes of benches/peers rebuilt in gelenk, at dt = 2 ms:
//! box_stack10.xml (ten 0.1 m cubes of density 500 resting in a stack on a plane) with each
//! solver chain, let settle for 0.5 s first; and humanoid_fall.xml (loaded by gelenk's MJCF
//! reader: a capsule humanoid, free base + 21 hinges, joint damping 1) dropped on the plane for
//! a 5 s episode, timed per step over the whole episode as MuJoCo's figure is. Sleeping is off
//! so that every step does the full work.
//!
//! Run: `cargo bench --bench world`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use gelenk::collision::MeshOptions;
use gelenk::constraints::ContactParameters;
use gelenk::math::{Transform, Vec3};
use gelenk::model::{BodySpec, Joint, ModelBuilder, RigidInertia, Shape};
use gelenk::world::{SolverKind, World, WorldOptions};
use std::time::Duration;

fn box_stack(solvers: Vec<SolverKind>) -> World {
    let mut options = WorldOptions { dt: 0.002, solvers, ..Default::default() };
    options.sleep.enabled = false;
    options.contact = ContactParameters { mu: 0.8, ..Default::default() };
    let mut w = World::new(options);
    w.add_static("floor", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    let side = 0.1;
    let mass = 500.0 * side * side * side;
    for k in 0..10 {
        let mut b = ModelBuilder::new();
        b.add_body(
            BodySpec::new(
                "box",
                "universe",
                Joint::Free,
                Transform::identity(),
                RigidInertia::solid_box(mass, Vec3::repeat(side)),
            )
            .with_collision(Shape::Box { size: Vec3::repeat(side) }, Transform::identity()),
        );
        let i = w.add_multibody(&format!("box{k}"), b.build().unwrap(), &MeshOptions::default()).unwrap();
        w.multibody_mut(i).state.q[2] = 0.05 + 0.101 * k as f64;
    }
    for _ in 0..250 {
        w.step().unwrap();
    }
    w
}

fn humanoid(solvers: Vec<SolverKind>) -> World {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/peers/humanoid_fall.xml");
    let scene = gelenk::io::mjcf::load_file(path).expect("humanoid_fall.xml loads");
    let mut options =
        WorldOptions { dt: scene.timestep, solvers, friction: scene.friction, ..Default::default() };
    options.sleep.enabled = false;
    options.contact = ContactParameters { mu: 0.7, ..Default::default() };
    let mut w = World::new(options);
    for s in scene.statics.iter().filter(|s| s.collides) {
        w.add_static(&s.name, &s.shape, s.pose, 0).unwrap();
    }
    let i = w.add_multibody("humanoid", scene.model, &MeshOptions::default()).unwrap();
    w.multibody_mut(i).state.q.copy_from(&scene.q0);
    w
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("world_step");
    group.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3)).sample_size(10);
    let chains: [(&str, Vec<SolverKind>); 3] = [
        ("pgs50", vec![SolverKind::Pgs { iterations: 50, omega: 1.0 }]),
        ("pgs100+clarabel", WorldOptions::default().solvers),
        ("lemke+clarabel", vec![SolverKind::Lemke { facets: 4 }, SolverKind::Clarabel]),
    ];
    for (name, solvers) in chains {
        let mut w = box_stack(solvers);
        w.set_phase_timing(true);
        let s = w.step().unwrap().clone();
        w.set_phase_timing(false);
        eprintln!(
            "box_stack10 [{name}]: {} contacts, {} rows, solver {} ({} it), residual {:.1e}, phases ns {:?}",
            s.contacts, s.rows, s.solver, s.iterations, s.residual, s.phase_ns
        );
        group.bench_function(BenchmarkId::new("box_stack10", name), |b| b.iter(|| w.step().unwrap().rows));
    }
    for (name, solvers) in [
        ("pgs50", vec![SolverKind::Pgs { iterations: 50, omega: 1.0 }]),
        ("pgs100+clarabel", WorldOptions::default().solvers),
    ] {
        group.bench_function(BenchmarkId::new("humanoid_fall_5s_per_step", name), |b| {
            b.iter_custom(|episodes| {
                let mut total = Duration::ZERO;
                for _ in 0..episodes {
                    let mut w = humanoid(solvers.clone());
                    let start = std::time::Instant::now();
                    for _ in 0..2500 {
                        w.step().unwrap();
                    }
                    total += start.elapsed() / 2500;
                }
                total
            })
        });
        let mut w = humanoid(solvers.clone());
        let (mut contacts, mut fallbacks) = (0, 0);
        for _ in 0..2500 {
            let s = w.step().unwrap();
            contacts += s.contacts;
            fallbacks += s.fallbacks.len();
        }
        eprintln!(
            "humanoid [{name}]: mean contacts {:.1}, fallbacks {fallbacks} in 2500 steps",
            contacts as f64 / 2500.0
        );
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
