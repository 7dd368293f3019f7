//! The Newton solver answers the convex (Anitescu) contact problem: on random problems with
//! every kind of row, hard and soft, its impulses satisfy the convex residuals to 1e-9 m/s and
//! give the same row velocities as clarabel's interior-point answer; in a world of colliding
//! boxes every step is certified without a fallback.

use gelenk::constraints::{ConstraintProblem, ContactBlock, FrictionModel, RowLaw};
use gelenk::solvers::{residuals, ClarabelSolver, ConstraintSolver, NewtonSolver};
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// A random problem: `contacts` contacts (some frictionless, some anisotropic), then a few
/// unilateral, bounded and bilateral rows; A = B Bᵀ of rank `rank` (rank-deficient: redundant
/// rows) plus R = `soft`·diag(A). b = B β + s with s in the dual of the rows' sets (0 on
/// bilateral and friction rows, ≥ 0 on unilateral ones), so that a solution exists.
fn random_problem(rng: &mut StdRng, contacts: usize, rank: usize, soft: f64) -> ConstraintProblem {
    let extra = rng.random_range(0..4);
    let n = 3 * contacts + 3 * extra;
    let b = DMatrix::from_fn(n, rank, |_, _| rng.random_range(-1.0..1.0));
    let a = &b * b.transpose();
    let beta = DVector::from_fn(rank, |_, _| rng.random_range(-1.0..1.0));
    let mut bias = &b * beta;
    let mut laws = Vec::new();
    let mut blocks = Vec::new();
    for c in 0..contacts {
        let mu = match c % 4 {
            0 => 0.0,
            _ => rng.random_range(0.2..1.2),
        };
        let mu2 = if c % 4 == 3 { rng.random_range(0.2..1.2) } else { mu };
        blocks.push(ContactBlock { normal: 3 * c, mu, mu2 });
        laws.push(RowLaw::Unilateral);
        laws.push(RowLaw::Friction { contact: c });
        laws.push(RowLaw::Friction { contact: c });
    }
    for _ in 0..extra {
        laws.push(RowLaw::Unilateral);
        let lo = rng.random_range(-1.0..0.0);
        laws.push(RowLaw::Bounded { lo, hi: lo + rng.random_range(0.1..1.0) });
        laws.push(RowLaw::Bilateral);
    }
    for (i, law) in laws.iter().enumerate() {
        bias[i] += match law {
            RowLaw::Unilateral => rng.random_range(-0.5..1.0f64).max(0.0),
            RowLaw::Bounded { .. } => rng.random_range(-1.0..1.0),
            _ => 0.0,
        };
    }
    let mut problem = ConstraintProblem::from_parts(a.clone(), bias, laws, blocks, FrictionModel::Cone);
    for i in 0..n {
        problem.regularization[i] = soft * a[(i, i)];
    }
    problem
}

fn velocities(problem: &ConstraintProblem, lambda: &DVector<f64>) -> DVector<f64> {
    let mut w = DVector::zeros(problem.rows());
    problem.velocities(lambda, &mut w);
    w
}

/// 60 random problems (seeds from `seed`, friction as `friction` gives for each case): Newton's
/// answer satisfies the convex residuals to 1e-9 m/s and gives clarabel's row velocities.
fn random_problems_agree_with_clarabel(seed: u64, friction: impl Fn(u64) -> FrictionModel, label: &str) {
    let mut worst = (0.0f64, 0.0f64);
    for case in 0..60u64 {
        let mut rng = StdRng::seed_from_u64(seed + case);
        let contacts = rng.random_range(1..8);
        let n_estimate = 3 * contacts + 9;
        let rank = if case % 3 == 0 { rng.random_range(2..=3 * contacts) } else { n_estimate + 4 };
        let soft = if case % 2 == 0 { 0.0 } else { 0.02 };
        let mut problem = random_problem(&mut rng, contacts, rank, soft);
        problem.friction = friction(case);
        let mut newton = NewtonSolver::default();
        let mut lambda = DVector::zeros(problem.rows());
        newton.solve(&problem, &mut lambda).unwrap_or_else(|e| panic!("case {case}: {e}"));
        let mut w = DVector::zeros(0);
        let r = residuals(&problem, &lambda, &mut w);
        assert!(
            r.convex() < 1e-9,
            "case {case} ({} rows, soft {soft}, {:?}): convex residual {:.3e}",
            problem.rows(),
            problem.friction,
            r.convex()
        );
        let mut clarabel = ClarabelSolver::default();
        let mut reference = DVector::zeros(problem.rows());
        clarabel.solve(&problem, &mut reference).unwrap_or_else(|e| panic!("case {case}: clarabel: {e}"));
        let dw = (velocities(&problem, &lambda) - velocities(&problem, &reference)).amax();
        assert!(dw < 1e-5, "case {case}: row velocities differ from clarabel's by {dw:.3e}");
        worst = (worst.0.max(r.convex()), worst.1.max(dw));
    }
    eprintln!("{label}: worst convex residual {:.2e}, worst |w − w_clarabel| {:.2e}", worst.0, worst.1);
}

#[test]
fn random_problems_are_solved_and_agree_with_clarabel() {
    random_problems_agree_with_clarabel(0x4e57_0000, |_| FrictionModel::Cone, "random problems");
}

/// A warm start at the answer is recognised as one: no iteration.
#[test]
fn a_warm_start_at_the_answer_takes_no_iteration() {
    let mut rng = StdRng::seed_from_u64(11);
    let problem = random_problem(&mut rng, 5, 30, 0.0);
    let mut newton = NewtonSolver::default();
    let mut lambda = DVector::zeros(problem.rows());
    let first = newton.solve(&problem, &mut lambda).unwrap();
    assert!(first.iterations > 0);
    let again = newton.solve(&problem, &mut lambda).unwrap();
    assert_eq!(again.iterations, 0);
}

/// Friction pyramids (3, 4 and 8 facets, isotropic and anisotropic, hard and soft): the answer
/// satisfies the convex residuals of the pyramid problem to 1e-9 m/s and gives clarabel's row
/// velocities.
#[test]
fn random_pyramid_problems_are_solved_and_agree_with_clarabel() {
    let facets = |case: u64| FrictionModel::Pyramid { facets: [4, 3, 8][case as usize % 3] };
    random_problems_agree_with_clarabel(0x5059_0000, facets, "random pyramid problems");
}

/// Boxes dropped on each other and on the ground (many multibodies, the sparse Hessian):
/// every step's answer is certified by the convex residual without a fallback.
#[test]
fn a_pile_of_boxes_is_certified_every_step() {
    let scene = r#"
name = "newton_boxes"
[world]
dt = 0.016666666666666666
duration = 1.5
solver = "newton"
[contact]
mu = 0.6
[[ground]]
kind = "plane"
[[body]]
name = "box"
shape = "box"
size = [0.1, 0.15, 0.05]
density = 500
position = [-0.1, -0.1, 0.1]
count = [2, 2, 4]
spacing = [0.18, 0.22, 0.13]
jitter = 0.03
seed = 4
"#;
    let mut scene = gelenk::io::scene::load_str(scene, ".").unwrap();
    let tolerance = scene.world.options().tolerance;
    let mut worst = 0.0f64;
    let mut rows = 0;
    for step in 0..90 {
        let stats = scene.world.step().unwrap_or_else(|e| panic!("step {step}: {e}"));
        assert!(stats.fallbacks.is_empty(), "step {step}: {:?}", stats.fallbacks);
        assert!(stats.residual <= tolerance, "step {step}: residual {:.3e}", stats.residual);
        worst = worst.max(stats.residual);
        rows = rows.max(stats.rows);
    }
    assert!(rows >= 60, "the boxes pile up ({rows} rows at most)");
    eprintln!("box pile: up to {rows} rows, worst residual {worst:.2e}");
}

/// `soften` adds `s · A_ii` to unilateral and bounded rows, the normal's `s · A_nn` to a
/// contact's friction rows, and nothing to bilateral rows.
#[test]
fn softness_is_relative_to_each_rows_effective_mass() {
    let a = DMatrix::from_diagonal(&DVector::from_vec(vec![2.0, 3.0, 5.0, 7.0, 11.0, 13.0]));
    let laws = vec![
        RowLaw::Unilateral,
        RowLaw::Friction { contact: 0 },
        RowLaw::Friction { contact: 0 },
        RowLaw::Bounded { lo: -1.0, hi: 1.0 },
        RowLaw::Bilateral,
        RowLaw::Unilateral,
    ];
    let contacts = vec![ContactBlock { normal: 0, mu: 0.5, mu2: 0.5 }];
    let mut problem =
        ConstraintProblem::from_parts(a, DVector::zeros(6), laws, contacts, FrictionModel::Cone);
    problem.regularization[5] = 1.0;
    problem.soften(0.1);
    let expected = [0.2, 0.2, 0.2, 0.7, 0.0, 1.0 + 1.3];
    for (i, e) in expected.iter().enumerate() {
        assert!(
            (problem.regularization[i] - e).abs() < 1e-15,
            "row {i}: {} vs {e}",
            problem.regularization[i]
        );
    }
}

/// Four ragdolls dropped into a pile at a game's time step with the pile scene's chain (Newton,
/// softness 0.02): the Newton solver answers every step within the chain's tolerance, without
/// a fallback.
#[test]
fn a_soft_ragdoll_pile_is_certified_every_step() {
    let models = concat!(env!("CARGO_MANIFEST_DIR"), "/models");
    let text = std::fs::read_to_string(format!("{models}/ragdoll_pile.toml")).unwrap();
    let text = text.replace("count = 20", "count = 4").replace("dt = 0.002", "dt = 0.016666666666666666");
    assert!(text.contains("count = 4") && text.contains("softness = 0.02") && text.contains("\"newton\""));
    let mut scene = gelenk::io::scene::load_str(&text, models).unwrap();
    let tolerance = scene.world.options().tolerance;
    let mut most_rows = 0;
    for step in 0..90 {
        let stats = scene.world.step().unwrap_or_else(|e| panic!("step {step}: {e}"));
        assert!(stats.fallbacks.is_empty(), "step {step}: {:?}", stats.fallbacks);
        assert!(stats.residual <= tolerance, "step {step}: residual {:.3e}", stats.residual);
        most_rows = most_rows.max(stats.rows);
    }
    assert!(most_rows >= 100, "the ragdolls land on each other ({most_rows} rows at most)");
}

/// The softness is centred on last step's impulses: a stack of ten 0.5 kg boxes at 2 ms with
/// softness 0.5 stands and carries its weight as a hard stack does. Uncentred, a bottom contact
/// point (A_nn ≈ 6 /kg, a quarter of the stack's weight) would sink beyond the 1 mm surface
/// layer by `0.5 A_nn λ h / erp` ≈ 0.7 mm; centred it settles within the layer. (At 1/60 s the
/// position correction, ERP 0.2, makes so soft a stack bob by centimetres: not asserted.)
#[test]
fn a_soft_stack_carries_its_load_without_sinking() {
    let models = concat!(env!("CARGO_MANIFEST_DIR"), "/models");
    let text = std::fs::read_to_string(format!("{models}/box_stack10.toml")).unwrap();
    let text = text
        .replace("\ndt = 0.002\n", "\ndt = 0.002\nsoftness = 0.5\n")
        .replace("solver = [\"pgs100\", \"clarabel\"]", "solver = [\"newton\", \"clarabel\"]");
    assert!(text.contains("softness = 0.5") && text.contains("[\"newton\", \"clarabel\"]"));
    let mut scene = gelenk::io::scene::load_str(&text, models).unwrap();
    let top = scene.world.multibody_count() - 1;
    let top_start = scene.world.multibody(top).state.q[2];
    let (mut deepest_late, mut top_lowest, mut top_highest) = (0.0f64, top_start, top_start);
    for step in 0..1000 {
        let stats = scene.world.step().unwrap_or_else(|e| panic!("step {step}: {e}"));
        if step >= 750 {
            deepest_late = deepest_late.max(stats.max_penetration);
        }
        let z = scene.world.multibody(top).state.q[2];
        (top_lowest, top_highest) = (top_lowest.min(z), top_highest.max(z));
    }
    println!("top box from {top_start:.4} m within [{top_lowest:.4}, {top_highest:.4}] m; late depth {deepest_late:.2e} m");
    // The stack stands: its top box neither falls nor is thrown up.
    assert!(top_start - top_lowest < 0.02 && top_highest - top_start < 0.02, "the stack does not stand");
    assert!(deepest_late < 1e-3, "the stack sinks under its load: {deepest_late:.2e} m deep");
}

/// `follow_elastic_impulses` moves each softened row's centre to `(1 − β) λ + β λ̄`, and to 0
/// for a unilateral row at 0 and for the friction rows of a contact whose normal is at 0.
#[test]
fn the_centre_of_the_softening_follows_the_elastic_impulses() {
    let a = DMatrix::from_diagonal(&DVector::from_vec(vec![1.0; 8]));
    let laws = vec![
        RowLaw::Unilateral,
        RowLaw::Friction { contact: 0 },
        RowLaw::Friction { contact: 0 },
        RowLaw::Unilateral,
        RowLaw::Friction { contact: 1 },
        RowLaw::Friction { contact: 1 },
        RowLaw::Bounded { lo: -1.0, hi: 1.0 },
        RowLaw::Unilateral,
    ];
    let contacts =
        vec![ContactBlock { normal: 0, mu: 0.5, mu2: 0.5 }, ContactBlock { normal: 3, mu: 0.5, mu2: 0.5 }];
    let problem = ConstraintProblem::from_parts(a, DVector::zeros(8), laws, contacts, FrictionModel::Cone);
    let lambda = DVector::from_vec(vec![2.0, 0.4, -0.2, 0.0, 0.0, 0.0, -0.5, 0.0]);
    let mut centre = DVector::from_vec(vec![1.0, 0.2, 0.2, 3.0, 0.5, -0.5, 0.5, 1.0]);
    problem.follow_elastic_impulses(0.25, &lambda, &mut centre);
    let expected = [1.75, 0.35, -0.1, 0.0, 0.0, 0.0, -0.25, 0.0];
    for (i, e) in expected.iter().enumerate() {
        assert!((centre[i] - e).abs() < 1e-15, "row {i}: {} vs {e}", centre[i]);
    }
    // β = 0: the centre is the impulse (undamped springs); β = 1: it stays (dampers alone).
    let mut undamped = centre.clone();
    problem.follow_elastic_impulses(0.0, &lambda, &mut undamped);
    assert_eq!(undamped, lambda);
    let mut dampers = DVector::from_vec(vec![0.0; 8]);
    problem.follow_elastic_impulses(1.0, &lambda, &mut dampers);
    assert_eq!(dampers, DVector::from_vec(vec![0.0; 8]));
}

/// MuJoCo's humanoid (benches/peers/humanoid_fall.xml) dropped at 2 ms on rows as soft as
/// MuJoCo's default impedance ((1 − d)/d with d = 0.9): with the rows' dampers
/// (`softness_damping` 0.5) it comes to rest and falls asleep within 5 s, its
/// deepest penetration under 1 mm. Undamped (β = 0), its slowest modes on the soft rows keep it
/// rocking: it is still awake after 5 s.
#[test]
fn a_humanoid_on_soft_rows_comes_to_rest() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/peers/humanoid_fall.xml");
    let run = |damping: f64| {
        let scene = gelenk::io::mjcf::load_file(std::path::Path::new(path)).unwrap();
        let mut options = scene.world_options();
        options.softness = 0.11;
        options.softness_damping = damping;
        let mut world = scene.into_world(options).unwrap();
        let (mut asleep_at, mut deepest) = (None, 0.0f64);
        let count = world.multibody_count();
        for step in 0..2500 {
            let stats = world.step().unwrap_or_else(|e| panic!("step {step}: {e}"));
            deepest = deepest.max(stats.max_penetration);
            if stats.asleep == count && asleep_at.is_none() {
                asleep_at = Some(stats.time);
            }
        }
        (asleep_at, deepest)
    };
    let (damped, deepest) = run(0.5);
    let (undamped, _) = run(0.0);
    println!("asleep at {damped:?} s (damped), {undamped:?} s (undamped); deepest {deepest:.2e} m");
    assert!(damped.is_some_and(|t| t < 3.0), "the damped humanoid is still awake: {damped:?}");
    assert!(deepest < 1e-3, "{deepest:.2e} m deep");
    assert_eq!(undamped, None, "the undamped humanoid came to rest");
}

/// Sixteen ragdolls (models/ragdoll_crowd.toml's 2 × 2 columns, four high) dropped into a heap
/// at 1/60 s on hard rows with the world's default chain: every step is answered within the
/// chain's tolerance. The heap's hard problems, whose redundant rows take Newton's method many
/// proximal rounds, need up to `CHAIN_NEWTON_ITERATIONS` iterations in one solve.
#[test]
fn a_hard_heap_of_ragdolls_is_certified_every_step_by_the_default_chain() {
    let models = concat!(env!("CARGO_MANIFEST_DIR"), "/models");
    let text = std::fs::read_to_string(format!("{models}/ragdoll_crowd.toml")).unwrap();
    let text: String = text
        .lines()
        .filter(|l| !l.starts_with("solver =") && !l.starts_with("softness ="))
        .map(|l| match l {
            _ if l.starts_with("count = [2, 2, 16]") => "count = [2, 2, 4]",
            _ if l.starts_with("dt = 0.002") => "dt = 0.016666666666666666",
            _ => l,
        })
        .collect::<Vec<_>>()
        .join("\n");
    assert!(
        text.contains("count = [2, 2, 4]") && text.contains("dt = 0.0166") && !text.contains("softness =")
    );
    let mut scene = gelenk::io::scene::load_str(&text, models).unwrap();
    let options = scene.world.options();
    assert_eq!(options.solvers, gelenk::world::WorldOptions::default().solvers);
    let tolerance = options.tolerance;
    let mut most_rows = 0;
    for step in 0..90 {
        let stats = scene.world.step().unwrap_or_else(|e| panic!("step {step}: {e}"));
        assert!(
            stats.residual <= tolerance,
            "step {step}: residual {:.3e} ({})",
            stats.residual,
            stats.solver
        );
        most_rows = most_rows.max(stats.rows);
    }
    assert!(most_rows >= 250, "the ragdolls land on each other ({most_rows} rows at most)");
}
