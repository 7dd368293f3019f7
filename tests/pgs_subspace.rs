//! PGS with subspace minimisation (`PgsSolver::subspace`) on problems where plain PGS stalls:
//! two steps of `benches/peers/humanoid_fall.xml` (written by `World::problem` and
//! `gelenk::io::problem::problem_to_json` at steps 80 and 898 of the episode that
//! `gelenk bench world benches/peers/humanoid_fall.xml` runs), where the chain `pgs100,clarabel`
//! fell back to clarabel. Step 80: the four corner contacts of a foot (12 rows, a redundant set on
//! a stiff chain), where two corners must slip by 4.5e-5 m/s; plain sweeps creep along the
//! contacts' internal-force direction and stay above 1e-6 m/s for thousands of sweeps. Step 898:
//! 36 rows, nine contacts, several sliding. Solved cold (from λ = 0), as the probe that found them.

use gelenk::constraints::ConstraintProblem;
use gelenk::solvers::{residuals, ConstraintSolver, PgsSolver};
use nalgebra::DVector;
use std::path::Path;

fn load(name: &str) -> ConstraintProblem {
    gelenk::io::problem::read_problem(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name))
        .unwrap()
}

/// (exact residual in m/s, sweeps) of a cold PGS solve.
fn solve(problem: &ConstraintProblem, sweeps: usize, subspace: bool) -> (f64, usize) {
    let mut pgs = PgsSolver { subspace, tolerance: 1e-12, ..PgsSolver::with_iterations(sweeps) };
    let mut lambda = DVector::zeros(problem.rows());
    let info = pgs.solve(problem, &mut lambda).unwrap();
    let mut w = DVector::zeros(0);
    (residuals(problem, &lambda, &mut w).exact(), info.iterations)
}

#[test]
fn subspace_steps_solve_a_redundant_foot_contact_where_plain_pgs_stalls() {
    let problem = load("humanoid_fall_step0080_problem.json");
    assert_eq!((problem.rows(), problem.contacts.len()), (12, 4));
    let (with, sweeps) = solve(&problem, 100, true);
    // 1e-9 m/s: three orders below the chain's certifying tolerance (1e-6 m/s); the subspace
    // step lands at rounding level (measured 3.5e-16 after 8 sweeps).
    assert!(with <= 1e-9, "PGS-SM residual {with:.3e} after {sweeps} sweeps");
    assert!(sweeps <= 40, "PGS-SM took {sweeps} sweeps");
    // Plain PGS (same sweeps, and ten times as many): still above the chain's 1e-6 m/s.
    for budget in [100, 1000] {
        let (plain, _) = solve(&problem, budget, false);
        assert!(plain > 1e-6, "plain PGS reached {plain:.3e} in {budget} sweeps: the case no longer stalls");
    }
}

#[test]
fn subspace_steps_find_sliding_directions_on_a_nine_contact_step() {
    let problem = load("humanoid_fall_step0898_problem.json");
    assert_eq!(problem.rows(), 36);
    let (with, sweeps) = solve(&problem, 100, true);
    // Measured 2.6e-16 after 40 sweeps; 1e-9 m/s as above.
    assert!(with <= 1e-9, "PGS-SM residual {with:.3e} after {sweeps} sweeps");
    let (plain, _) = solve(&problem, 100, false);
    assert!(plain > 1e-6, "plain PGS reached {plain:.3e}");
}

#[test]
fn subspace_steps_leave_quickly_converging_solves_alone() {
    // Plain PGS and PGS-SM give the same impulses when the sweeps converge before the first
    // subspace step is due (8 sweeps at the earliest): the foot problem warm-started at the
    // answer a first solve found.
    let problem = load("humanoid_fall_step0080_problem.json");
    let mut first = PgsSolver { subspace: true, tolerance: 1e-12, ..PgsSolver::with_iterations(200) };
    let mut lambda = DVector::zeros(problem.rows());
    first.solve(&problem, &mut lambda).unwrap();
    let (mut a, mut b) = (lambda.clone(), lambda.clone());
    let info_a = PgsSolver { subspace: true, tolerance: 1e-10, ..PgsSolver::with_iterations(100) }
        .solve(&problem, &mut a)
        .unwrap();
    let info_b = PgsSolver { subspace: false, tolerance: 1e-10, ..PgsSolver::with_iterations(100) }
        .solve(&problem, &mut b)
        .unwrap();
    assert_eq!(info_a.iterations, info_b.iterations);
    assert!(info_a.iterations < 8, "warm start at the answer took {} sweeps", info_a.iterations);
    assert_eq!(a, b);
}

#[test]
fn a_solve_settled_by_a_subspace_step_makes_the_next_one_try_it_early() {
    // The next step's problem of a foot that stays on the ground: the same rows with the free
    // velocity a little changed (1e-4 m/s on every row), warm-started at the last answer. The
    // solver that settled the last solve by a subspace step tries one after 3 sweeps; a fresh
    // solver waits for 8.
    let problem = load("humanoid_fall_step0080_problem.json");
    let mut solver = PgsSolver { subspace: true, ..PgsSolver::with_iterations(100) };
    let mut lambda = DVector::zeros(problem.rows());
    let first = solver.solve(&problem, &mut lambda).unwrap();
    let mut next = problem.clone();
    for (i, b) in next.bias.iter_mut().enumerate() {
        *b += 1e-4 * if i % 2 == 0 { 1.0 } else { -0.5 };
    }
    let mut w = DVector::zeros(0);
    let (mut early, mut fresh) = (lambda.clone(), lambda.clone());
    let early_info = solver.solve(&next, &mut early).unwrap();
    let fresh_info =
        PgsSolver { subspace: true, ..PgsSolver::with_iterations(100) }.solve(&next, &mut fresh).unwrap();
    let (r_early, r_fresh) =
        (residuals(&next, &early, &mut w).exact(), residuals(&next, &fresh, &mut w).exact());
    println!(
        "first {} sweeps; next: early {} sweeps ({r_early:.2e} m/s), fresh {} sweeps ({r_fresh:.2e} m/s)",
        first.iterations, early_info.iterations, fresh_info.iterations
    );
    assert!(r_early <= 1e-9 && r_fresh <= 1e-9);
    assert!(early_info.iterations <= 3, "early: {} sweeps", early_info.iterations);
    assert!(fresh_info.iterations >= 8, "fresh: {} sweeps", fresh_info.iterations);
}

#[test]
fn residuals_handed_to_the_chain_are_those_of_the_returned_impulses() {
    // A solve that ends on a subspace step hands over the residuals it computed (the chain
    // certifies with them): they must be exactly what the impulses it returns give.
    for name in ["humanoid_fall_step0080_problem.json", "humanoid_fall_step0898_problem.json"] {
        let problem = load(name);
        let mut pgs = PgsSolver::with_iterations(100);
        let mut lambda = DVector::zeros(problem.rows());
        let info = pgs.solve(&problem, &mut lambda).unwrap();
        let handed = info.residuals.unwrap_or_else(|| panic!("{name}: no residuals handed over"));
        let mut w = DVector::zeros(0);
        assert_eq!(handed, residuals(&problem, &lambda, &mut w), "{name}");
        assert!(handed.exact() <= 1e-9, "{name}: {:.3e}", handed.exact());
    }
}

#[test]
fn residuals_from_the_sum_the_sweeps_keep_match_a_fresh_evaluation() {
    // On a matrix-free problem PGS keeps s = Wᵀλ through its sweeps and hands over the
    // residuals of its answer from it (the chain certifies with them): a ragdoll lying on the
    // ground (models/ragdoll_fall.toml after 1 s), plain sweeps (no subspace step), cold.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ragdoll_fall.toml");
    let mut scene = gelenk::io::scene::load_file(&path).unwrap();
    for _ in 0..500 {
        scene.world.step().unwrap();
    }
    let problem = scene.world.problem().clone();
    assert!(problem.rows() > 30 && problem.is_matrix_free(), "{} rows", problem.rows());
    for sweeps in [5, 200] {
        let mut pgs = PgsSolver { subspace: false, tolerance: 1e-9, ..PgsSolver::with_iterations(sweeps) };
        let mut lambda = DVector::zeros(problem.rows());
        let info = pgs.solve(&problem, &mut lambda).unwrap();
        let handed = info.residuals.expect("residuals from the kept sum");
        let fresh = residuals(&problem, &lambda, &mut DVector::zeros(0));
        // Equal up to the rounding of the kept sum.
        let (a, b) = (handed.exact(), fresh.exact());
        assert!((a - b).abs() <= 1e-12 + 1e-9 * b, "{sweeps} sweeps: handed {a:.6e}, fresh {b:.6e}");
    }
}

#[test]
fn subspace_steps_solve_pyramid_friction_exactly_in_linear_rounds() {
    // The same two humanoid steps with the friction set a 4- and an 8-facet pyramid: contacts on
    // a facet or at a vertex make the reduced system linear (no Newton rounds on a direction).
    // Lemke pivots the same pyramid to an exact answer: PGS-SM must reach rounding level too,
    // where plain PGS stalls, and both answers must give the same row velocities (the impulses
    // of a redundant contact set are not unique; the motion is).
    use gelenk::constraints::FrictionModel;
    use gelenk::solvers::LemkeSolver;
    for name in ["humanoid_fall_step0080_problem.json", "humanoid_fall_step0898_problem.json"] {
        for facets in [4, 8] {
            let mut problem = load(name);
            problem.friction = FrictionModel::Pyramid { facets };
            let (with, sweeps) = solve(&problem, 100, true);
            let (plain, _) = solve(&problem, 100, false);
            println!(
                "{name} pyramid{facets}: PGS-SM {with:.2e} m/s after {sweeps} sweeps, plain {plain:.2e}"
            );
            assert!(with <= 1e-9, "{name} pyramid{facets}: PGS-SM residual {with:.3e} after {sweeps} sweeps");
            assert!(sweeps <= 60, "{name} pyramid{facets}: PGS-SM took {sweeps} sweeps");
            assert!(plain > 1e-6, "{name} pyramid{facets}: plain PGS reached {plain:.3e}: no longer a stall");
            let mut pgs = PgsSolver { tolerance: 1e-12, ..PgsSolver::with_iterations(100) };
            let mut lambda = DVector::zeros(problem.rows());
            pgs.solve(&problem, &mut lambda).unwrap();
            let mut lemke_lambda = DVector::zeros(problem.rows());
            LemkeSolver::default().solve(&problem, &mut lemke_lambda).unwrap();
            let (mut w, mut w_lemke) = (DVector::zeros(0), DVector::zeros(0));
            let lemke = residuals(&problem, &lemke_lambda, &mut w_lemke).exact();
            residuals(&problem, &lambda, &mut w);
            let gap = (&w - &w_lemke).amax();
            assert!(lemke <= 1e-9, "{name} pyramid{facets}: Lemke {lemke:.3e}");
            assert!(
                gap <= 1e-8,
                "{name} pyramid{facets}: row velocities differ from Lemke's by {gap:.3e} m/s"
            );
        }
    }
}

#[test]
fn a_warm_start_worse_than_zero_is_dropped() {
    // MuJoCo's guard: a warm start λ₀ with f(λ₀) = ½ λ₀ᵀ(A + R)λ₀ + bᵀλ₀ > f(0) = 0 is replaced by
    // zero. Fifty times the foot's answer (an impact's impulses carried into a resting step):
    // the solve then takes exactly the sweeps of a cold one, to the same answer; a tenth more
    // than the answer beats zero and converges from where it is.
    let problem = load("humanoid_fall_step0080_problem.json");
    let settle = |lambda: &mut DVector<f64>| {
        let mut pgs = PgsSolver { tolerance: 1e-12, ..PgsSolver::with_iterations(100) };
        let info = pgs.solve(&problem, lambda).unwrap();
        (info.iterations, residuals(&problem, lambda, &mut DVector::zeros(0)).exact())
    };
    let mut cold = DVector::zeros(problem.rows());
    let (cold_sweeps, cold_residual) = settle(&mut cold);
    let mut inflated = &cold * 50.0;
    let (sweeps, residual) = settle(&mut inflated);
    assert_eq!((sweeps, residual), (cold_sweeps, cold_residual));
    assert_eq!(inflated, cold);
    let mut near = &cold * 1.1;
    let (near_sweeps, near_residual) = settle(&mut near);
    assert!(near_residual <= 1e-9, "{near_residual:.3e} after {near_sweeps} sweeps");
    assert!(near_sweeps <= cold_sweeps, "kept warm start: {near_sweeps} sweeps, cold {cold_sweeps}");
}
