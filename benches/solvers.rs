//! Criterion benchmarks of the constraint solvers on contact problems of 4, 40 and 400 contacts
//! (one box on the ground; a stack of 10 boxes; ten such stacks), assembled from real collision
//! and dynamics at rest under gravity with dt = 2 ms and μ = 0.8. Before timing, each solver's
//! certifying residual (m/s) is printed, so the table of time against residual can be read off.
//!
//! Run: `cargo bench --bench solvers`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use gelenk::collision::{CollisionOptions, CollisionWorld, MeshOptions};
use gelenk::constraints::{
    add_contact_rows, assemble_single, ConstraintProblem, ContactParameters, FrictionModel, ProblemBuilder,
};
use gelenk::model::Shape;
use gelenk::prelude::*;
use gelenk::solvers::{residuals, ClarabelSolver, ConstraintSolver, LemkeSolver, PgsSolver};
use nalgebra::DVector;
use std::hint::black_box;
use std::time::{Duration, Instant};

const H: f64 = 0.002;

/// `stacks` stacks of `height` 0.1 m boxes (1 mm gaps) on a half-space, as one constraint problem.
fn stack_problem(stacks: usize, height: usize, friction: FrictionModel) -> ConstraintProblem {
    let side = Vec3::repeat(0.1);
    let mut builder = ModelBuilder::new();
    for s in 0..stacks {
        for k in 0..height {
            builder.add_body(
                BodySpec::new(
                    format!("b{s}_{k}"),
                    "universe",
                    Joint::Free,
                    Transform::identity(),
                    RigidInertia::solid_box(0.5, side),
                )
                .with_collision(Shape::Box { size: side }, Transform::identity()),
            );
        }
    }
    let model = builder.build().unwrap();
    let mut data = Data::new(&model);
    let mut q = model.neutral_configuration();
    for s in 0..stacks {
        for k in 0..height {
            let i = 7 * (s * height + k);
            q[i] = 0.5 * s as f64;
            q[i + 2] = 0.0499 + 0.1005 * k as f64;
        }
    }
    let v = DVector::zeros(model.nv());
    let tau = DVector::zeros(model.nv());
    let mut world = CollisionWorld::new(CollisionOptions::default());
    let mb = world.add_model(&model, &MeshOptions::default()).unwrap();
    world.set_self_collision(mb, true).unwrap();
    world
        .add_static(
            "ground",
            &Shape::HalfSpace { normal: Vec3::z() },
            Transform::identity(),
            &MeshOptions::default(),
        )
        .unwrap();
    compute_joint_jacobians(&model, &mut data, &q).unwrap();
    world.update_multibody(mb, &data).unwrap();
    let contacts = world.detect().to_vec();
    let v_free = &v + aba(&model, &mut data, &q, &v, &tau).unwrap() * H;
    crba(&model, &mut data, &q).unwrap();
    factor_mass_matrix(&model, &mut data).unwrap();
    let mut rows = ProblemBuilder::new(model.nv(), friction);
    let params = ContactParameters { mu: 0.8, ..Default::default() };
    add_contact_rows(&mut rows, &[(&model, &data)], &[0], &contacts, 0, &v, H, |_| params);
    let mut problem = ConstraintProblem::default();
    assemble_single(&rows, &model, &data, &v_free, &mut problem);
    problem
}

fn solvers() -> Vec<(String, Box<dyn ConstraintSolver>, FrictionModel)> {
    let pyramid = FrictionModel::Pyramid { facets: 4 };
    vec![
        ("lemke (pyramid 4)".into(), Box::new(LemkeSolver::default()), pyramid),
        ("clarabel (cone)".into(), Box::new(ClarabelSolver::default()), FrictionModel::Cone),
        (
            "pgs 10 (cone)".into(),
            Box::new(PgsSolver { tolerance: 0.0, ..PgsSolver::with_iterations(10) }),
            FrictionModel::Cone,
        ),
        (
            "pgs 50 (cone)".into(),
            Box::new(PgsSolver { tolerance: 0.0, ..PgsSolver::with_iterations(50) }),
            FrictionModel::Cone,
        ),
    ]
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("solvers");
    group.warm_up_time(Duration::from_millis(300)).measurement_time(Duration::from_secs(2)).sample_size(10);
    for (stacks, height) in [(1, 1), (1, 10), (10, 10)] {
        for (name, mut solver, friction) in solvers() {
            let problem = stack_problem(stacks, height, friction);
            let contacts = problem.contacts.len();
            if name.starts_with("lemke") && contacts > 40 {
                continue; // a dense 2400-variable tableau: seconds per solve, see README.
            }
            let mut lambda = DVector::zeros(problem.rows());
            let start = Instant::now();
            let outcome = solver.solve(&problem, &mut lambda);
            let once = start.elapsed();
            let residual = match outcome {
                Ok(_) => solver.certify(&residuals(&problem, &lambda, &mut DVector::zeros(0))),
                Err(e) => {
                    eprintln!("{name} on {contacts} contacts: {e}");
                    continue;
                }
            };
            eprintln!("| {name} | {contacts} | residual {residual:.1e} m/s | first solve {once:?} |");
            group.bench_function(BenchmarkId::new(name.clone(), contacts), |b| {
                b.iter(|| {
                    lambda.fill(0.0);
                    black_box(solver.solve(&problem, &mut lambda).is_ok())
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
