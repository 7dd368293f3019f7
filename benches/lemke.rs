//! Criterion benchmark of Lemke's method on the contact LCPs of two scenes, each problem the
//! one a world posed at a fixed step:
//! - `stack10`, step 29: the built-in scene of `gelenk export-problems stack10 --steps 30 --only
//!   29` (ten boxes, 40 contacts, an 8-facet pyramid: a 400-variable LCP);
//! - `pile`, step 300: `models/pile.toml` (100 boxes and balls dropped onto a plane, stepped by
//!   its own chain, Newton's method then clarabel; about 200 contacts at that step, a
//!   2000-variable LCP). The scene's rows are softened (R = 0.02 A_ii), which makes M positive
//!   definite on the normal rows but leaves the pyramid's friction rows and their
//!   complementarity as they are: the path takes as many pivots as the same pile's
//!   zero-compliance LCP (some 600 to 700), and the pyramid below is the degenerate,
//!   zero-compliance case;
//! - `pyramid10`, step 100: the corpus scene `pyramid10-dt60` (the stability report's pyramid of
//!   55 boxes at 1/60 s, stepped by Newton's method and clarabel; some 470 contacts, a
//!   4700-variable LCP whose degenerate vertices, four coplanar corners under every box, tie
//!   hundreds of rows).
//!
//! Before timing, the LCP size, the pivots, the LCP's natural residual and the residual that
//! certifies the impulses (on the pyramid Lemke solves) are printed; a solve that fails aborts
//! the benchmark. Each problem is timed cold (`LemkeMemory::off()`: the LCP formed and solved
//! from the identity basis) and warm (the solver's memory of the same problem: M kept, only q
//! formed, the last basis the start, as for a resting world that keeps W).
//!
//! Run: `cargo bench --bench lemke`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use gelenk::constraints::{ConstraintProblem, FrictionModel};
use gelenk::io::problem::{corpus_world, CorpusWorld, SceneSource};
use gelenk::solvers::{lcp_of, lemke_with_report, residuals, ConstraintSolver, LemkeMemory, LemkeSolver};
use gelenk::world::World;
use nalgebra::DVector;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

/// The problem `world` poses at step `step` (counted from 0).
fn problem_at(mut world: World, step: usize) -> ConstraintProblem {
    for _ in 0..=step {
        world.step().expect("the scene steps");
    }
    world.problem().clone()
}

fn bench(c: &mut Criterion) {
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let pile = models.join("pile.toml");
    let pyramid = match corpus_world(&SceneSource::Pyramid { dt: 1.0 / 60.0 }, &models).expect("corpus scene")
    {
        CorpusWorld::World(world) => *world,
        CorpusWorld::Scene(scene) => scene.world,
    };
    let problems = [
        ("stack10", problem_at(gelenk::scenes::scene_world("stack10").expect("built-in scene"), 29)),
        ("pile", problem_at(gelenk::io::scene::load_file(&pile).expect("models/pile.toml").world, 300)),
        ("pyramid10", problem_at(pyramid, 100)),
    ];
    let mut group = c.benchmark_group("lemke");
    group.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3)).sample_size(10);
    for (name, problem) in &problems {
        let mut solver = LemkeSolver { memory: LemkeMemory::off(), ..Default::default() };
        let size = lcp_of(problem, solver.facets).q.len();
        let mut lambda = DVector::zeros(problem.rows());
        let info = solver.solve(problem, &mut lambda).unwrap_or_else(|e| panic!("{name}: {e}"));
        let mut pyramid = problem.clone();
        if matches!(pyramid.friction, FrictionModel::Cone) {
            pyramid.friction = FrictionModel::Pyramid { facets: solver.facets };
        }
        let certified = solver.certify(&residuals(&pyramid, &lambda, &mut DVector::zeros(0)));
        let lcp = lcp_of(problem, solver.facets);
        let (_, report) =
            lemke_with_report(&lcp.m, &lcp.q, &solver.options).unwrap_or_else(|e| panic!("{name}: {e}"));
        eprintln!(
            "| {name} | {} contacts | {size} LCP variables | {} pivots | {} refactorizations | LCP residual {:.1e} | certified {certified:.1e} m/s |",
            problem.contacts.len(),
            info.iterations,
            report.refactorizations,
            report.residual
        );
        group.bench_function(BenchmarkId::new(format!("{name}-cold"), size), |b| {
            b.iter(|| {
                lambda.fill(0.0);
                black_box(solver.solve(problem, &mut lambda).is_ok())
            })
        });
        let mut warm = LemkeSolver::default();
        warm.solve(problem, &mut lambda).unwrap_or_else(|e| panic!("{name}: {e}"));
        group.bench_function(BenchmarkId::new(format!("{name}-warm"), size), |b| {
            b.iter(|| black_box(warm.solve(problem, &mut lambda).is_ok()))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
