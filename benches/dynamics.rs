//! Criterion benchmarks of RNEA, CRBA, the mass matrix alone (`mass_matrix`) and ABA: the robots
//! of models (ur5, panda, solo12 with a free base), a 30-link chain, and chains of 10, 100 and
//! 1000 links for the cost per dof.
//! Each model is loaded once; every iteration takes the next state of a pool of random states.
//!
//! Run: `cargo bench --bench dynamics` (add `-- crba` to filter).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use gelenk::prelude::*;
use nalgebra::{DVector, Matrix3};
use rand::{Rng, SeedableRng};
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

const POOL: usize = 256;

struct Fixture {
    model: Model,
    data: Data,
    qs: Vec<DVector<f64>>,
    vs: Vec<DVector<f64>>,
    taus: Vec<DVector<f64>>,
}

impl Fixture {
    fn new(model: Model) -> Self {
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let nv = model.nv();
        let random = |rng: &mut rand::rngs::StdRng| DVector::from_fn(nv, |_, _| rng.random_range(-1.0..1.0));
        let vs = (0..POOL).map(|_| random(&mut rng)).collect();
        let taus = (0..POOL).map(|_| random(&mut rng)).collect();
        let qs = (0..POOL).map(|_| model.random_configuration(&mut rng)).collect();
        Self { data: Data::new(&model), model, qs, vs, taus }
    }
}

fn urdf(name: &str, floating: bool) -> Model {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("models").join(name);
    let options = UrdfOptions { floating_base: floating, ..Default::default() };
    gelenk::io::urdf::load_file(path, &options).expect("model loads")
}

/// A serial chain of `n` hinge links (0.25 m capsule-like rods), alternating y and x axes.
pub fn chain(n: usize) -> Model {
    let mut builder = ModelBuilder::new();
    let inertia = RigidInertia::new(
        1.0,
        Vec3::new(0.0, 0.0, -0.125),
        Matrix3::from_diagonal(&Vec3::new(5e-3, 5e-3, 2e-4)),
    );
    for k in 0..n {
        let parent = if k == 0 { "universe".to_string() } else { format!("link{}", k - 1) };
        let axis = if k % 2 == 0 { Vec3::y() } else { Vec3::x() };
        let placement = if k == 0 {
            Transform::identity()
        } else {
            Transform::from_translation(Vec3::new(0.0, 0.0, -0.25))
        };
        builder.add_body(BodySpec::new(format!("link{k}"), parent, Joint::hinge(axis), placement, inertia));
    }
    builder.build().expect("chain builds")
}

fn run(c: &mut Criterion, group_name: &str, models: Vec<(String, Model)>, per_dof: bool) {
    let mut group = c.benchmark_group(group_name);
    group.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(2)).sample_size(30);
    for (name, model) in models {
        let mut f = Fixture::new(model);
        if per_dof {
            group.throughput(Throughput::Elements(f.model.nv() as u64));
        }
        let mut k = 0;
        group.bench_function(BenchmarkId::new("rnea", &name), |b| {
            b.iter(|| {
                k = (k + 1) % POOL;
                black_box(rnea(&f.model, &mut f.data, &f.qs[k], &f.vs[k], &f.taus[k]).ok());
            })
        });
        group.bench_function(BenchmarkId::new("crba", &name), |b| {
            b.iter(|| {
                k = (k + 1) % POOL;
                black_box(crba(&f.model, &mut f.data, &f.qs[k]).ok());
            })
        });
        group.bench_function(BenchmarkId::new("mass_matrix", &name), |b| {
            b.iter(|| {
                k = (k + 1) % POOL;
                black_box(mass_matrix(&f.model, &mut f.data, &f.qs[k]).ok());
            })
        });
        group.bench_function(BenchmarkId::new("aba", &name), |b| {
            b.iter(|| {
                k = (k + 1) % POOL;
                black_box(aba(&f.model, &mut f.data, &f.qs[k], &f.vs[k], &f.taus[k]).ok());
            })
        });
    }
    group.finish();
}

fn robots(c: &mut Criterion) {
    let models = vec![
        ("ur5".to_string(), urdf("ur5_robot.urdf", false)),
        ("panda".to_string(), urdf("panda.urdf", false)),
        ("solo12_floating".to_string(), urdf("solo12.urdf", true)),
        ("chain30".to_string(), chain(30)),
    ];
    run(c, "robots", models, false);
}

fn chains(c: &mut Criterion) {
    let models = [10, 100, 1000].iter().map(|&n| (format!("chain{n}"), chain(n))).collect();
    run(c, "chains_per_dof", models, true);
}

criterion_group!(benches, robots, chains);
criterion_main!(benches);
