//! Pins Lemke's method with its factorized basis: it finds the unique solution of random LCPs
//! with a P-matrix; it solves degenerate LCPs (rank-deficient M, ties in the ratio test) and
//! gives the same answer whether the basis is refactorized after every pivot or after many; an
//! LCP without solution ends on a secondary ray whose certificate is checked here against M and
//! q independently of the solver; every problem of the committed corpus (`tests/problems/`), a
//! heavy box on a light one (mass ratio 1:1000), a 400-variable stack of ten boxes and every step
//! of the ten-box stack of the hard cases at each time step of the stability table are solved to
//! residuals certified by the shared `solvers::residuals`, and so is a twenty-box stack's LCP
//! whose paths end on slightly infeasible bases, every step of six seconds of the 55-box
//! pyramid at 1/60 s, mostly from the last step's basis, and every step of the same pyramid
//! with 1.5 mm gaps, whose bases turn ill-conditioned enough that rounding noise would pass
//! for pivots, and of the 36-box pyramid of touching boxes, whose paths end at degenerate
//! vertices a few 1e-9 outside the LCP (both within the world's 1e-8 m/s at every step, the
//! answers block Gauss–Seidel polished); the 2000-variable (softened) pile LCP of the benchmark
//! certifies far below the world's tolerance; a solve warm-started from the last basis or from
//! a basis read from impulses certifies like a cold one, supports the stack with the same
//! normal impulse and pivots less, and so does one on the same rows with the contacts in another
//! order (the last basis, in the wrong places, is passed over for the one read from the
//! impulses); a problem with the last M is solved from its last basis with q alone formed; told
//! its chain's tolerance, Lemke accepts an answer above its own LCP tolerance that the problem's
//! residual certifies instead of running more paths, and refines an answer within its LCP
//! tolerance whose residual on the problem misses the chain's (1e-9 m/s on a buggy's and a
//! humanoid pile's corpus problems) by a path from its basis; on frictionless contacts, whose
//! row velocities are unique, Lemke and clarabel agree.

use gelenk::collision::MeshOptions;
use gelenk::constraints::{ConstraintProblem, ContactBlock, FrictionModel, RowLaw};
use gelenk::io::problem::{read_problem, CorpusSolver, PROBLEM_FILE};
use gelenk::math::{Transform, Vec3};
use gelenk::model::{RigidInertia, Shape};
use gelenk::report::stability::{free_body, options, Setting, TIME_STEPS};
use gelenk::solvers::{
    lcp_of, lemke, lemke_with_report, residuals, ClarabelSolver, ConstraintSolver, LemkeMemory, LemkeOptions,
    LemkeSolver, SolverError,
};
use gelenk::world::{SolverKind, World, WorldOptions};
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// An exported problem of `tests/data/` (written by `io::problem::problem_to_json`).
fn exported_problem(name: &str) -> ConstraintProblem {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name);
    gelenk::io::problem::problem_from_json(&std::fs::read_to_string(&path).unwrap(), &path).unwrap()
}

/// max |min(z_i, w_i)| with w = M z + q, and min(z).
fn natural_residual(m: &DMatrix<f64>, q: &DVector<f64>, z: &DVector<f64>) -> (f64, f64) {
    let w = m * z + q;
    let r = z.iter().zip(w.iter()).fold(0.0f64, |r, (z, w)| r.max(z.min(*w).abs()));
    (r, z.min())
}

/// A random LCP with a known solution whose M = B Bᵀ has rank `rank` < n (redundant rows,
/// as four coplanar corners give) and whose solution is degenerate: about a third of the
/// pairs have z_i = w_i = 0.
fn degenerate_lcp(rng: &mut StdRng, n: usize, rank: usize) -> (DMatrix<f64>, DVector<f64>) {
    let b = DMatrix::from_fn(n, rank, |_, _| rng.random_range(-1.0..1.0));
    // Duplicate rows make ratio ties exact: rows 2i+1 copy rows 2i for the first few.
    let mut b = b;
    for i in 0..n / 6 {
        let row = b.row(2 * i).into_owned();
        b.row_mut(2 * i + 1).copy_from(&row);
    }
    let m = &b * b.transpose();
    let (mut z, mut w) = (DVector::zeros(n), DVector::zeros(n));
    for i in 0..n {
        match rng.random_range(0..3) {
            0 => z[i] = rng.random_range(0.1..1.0),
            1 => w[i] = rng.random_range(0.1..1.0),
            _ => {}
        }
    }
    let q = &w - &m * &z;
    (m, q)
}

#[test]
fn p_matrix_lcps_have_their_unique_solution_found() {
    // M = B Bᵀ + S + δ I with S skew-symmetric is positive definite, hence a P-matrix: the LCP
    // has exactly one solution, the z the test built q from.
    for case in 0..40u64 {
        let mut rng = StdRng::seed_from_u64(0x9a7e_0000 + case);
        let n = rng.random_range(1..=120);
        let b = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
        let s = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
        let m = &b * b.transpose() + (&s - s.transpose()) + DMatrix::identity(n, n) * 0.1;
        let (mut z, mut w) = (DVector::zeros(n), DVector::zeros(n));
        for i in 0..n {
            if rng.random_bool(0.5) {
                z[i] = rng.random_range(0.1..2.0);
            } else {
                w[i] = rng.random_range(0.1..2.0);
            }
        }
        let q = &w - &m * &z;
        let (found, _) =
            lemke(&m, &q, &LemkeOptions::default()).unwrap_or_else(|e| panic!("case {case}: {e}"));
        let (r, z_min) = natural_residual(&m, &q, &found);
        let scale = q.amax().max(1.0);
        assert!(r <= 1e-9 * scale && z_min >= 0.0, "case {case} (n = {n}): residual {r:e}, min z {z_min:e}");
        let error = (&found - &z).amax();
        assert!(error <= 1e-6 * z.amax().max(1.0), "case {case} (n = {n}): |z − z*| = {error:e}");
    }
}

#[test]
fn degenerate_lcps_are_solved_and_refactorization_does_not_change_the_answer() {
    let mut most_pivots = 0;
    for case in 0..40u64 {
        let mut rng = StdRng::seed_from_u64(0xde9e_0000 + case);
        let n = rng.random_range(4..=80);
        let rank = (n / 2).max(1);
        let (m, q) = degenerate_lcp(&mut rng, n, rank);
        let (z, report) = lemke_with_report(&m, &q, &LemkeOptions::default())
            .unwrap_or_else(|e| panic!("case {case} (n = {n}, rank {rank}): {e}"));
        let (r, z_min) = natural_residual(&m, &q, &z);
        let scale = q.amax().max(1.0);
        assert!(r <= 1e-9 * scale && z_min >= 0.0, "case {case}: residual {r:e}, min z {z_min:e}");
        assert!((report.residual - r).abs() <= 1e-12 * scale, "case {case}: the report states the residual");
        most_pivots = most_pivots.max(report.pivots);
        // Refactorizing after every pivot (no eta file) solves it too, to the same w: w = M z + q
        // is unique for positive semi-definite M, z need not be.
        let every = LemkeOptions { refactor_interval: 1, ..Default::default() };
        let (z1, report1) = lemke_with_report(&m, &q, &every).unwrap_or_else(|e| panic!("case {case}: {e}"));
        assert!(report1.refactorizations >= report1.pivots.saturating_sub(1), "case {case}: {report1:?}");
        let dw = (&m * (&z1 - &z)).amax();
        assert!(dw <= 1e-8 * scale, "case {case}: w differs by {dw:e} between refactorization intervals");
    }
    eprintln!("degenerate LCPs: most pivots {most_pivots}");
}

#[test]
fn an_lcp_without_solution_ends_on_a_ray_whose_certificate_checks() {
    // Infeasible LCPs with copositive-plus M, for which a ray proves infeasibility (Cottle, Pang
    // & Stone, Theorem 4.4.13): 1 × 1 and 2 × 2 examples, and M = B Bᵀ (60 × 60) whose B has
    // rows in pairs b, −b, so that y = 1 has Mᵀy = 0, with Σ q_i < 0.
    let mut rng = StdRng::seed_from_u64(7);
    let n = 60;
    let mut b = DMatrix::from_fn(n, 20, |_, _| rng.random_range(-1.0..1.0));
    for i in 0..n / 2 {
        let row = -b.row(2 * i).into_owned();
        b.row_mut(2 * i + 1).copy_from(&row);
    }
    let big_q = DVector::from_fn(n, |_, _| rng.random_range(-1.0..0.5));
    assert!(big_q.sum() < 0.0);
    let cases = [
        // 0 · z − 1 ≥ 0 is impossible.
        (DMatrix::from_element(1, 1, 0.0), DVector::from_element(1, -1.0)),
        // w1 = z1 − z2 − 1, w2 = −z1 + z2 − 1: w1 + w2 = −2 < 0 for every z.
        (DMatrix::from_row_slice(2, 2, &[1.0, -1.0, -1.0, 1.0]), DVector::from_row_slice(&[-1.0, -1.0])),
        (&b * b.transpose(), big_q),
    ];
    for (label, (m, q)) in cases.iter().enumerate() {
        let certificate = match lemke(m, q, &LemkeOptions::default()) {
            Err(SolverError::LemkeRay { certificate, .. }) => certificate,
            other => panic!("case {label}: expected a ray, got {other:?}"),
        };
        eprintln!("case {label}: {certificate}");
        // The solver's own check of the ray…
        assert!(certificate.ray_error <= 1e-9, "case {label}: ray error {:e}", certificate.ray_error);
        assert!(certificate.start_z0 > 0.0 && certificate.direction_z0 >= 0.0, "case {label}");
        assert!(certificate.infeasible, "case {label}: {certificate}");
        // …and an independent one: y = dz ≥ 0, Mᵀy ≤ 0, qᵀy < 0 (Farkas).
        let y = DVector::from_column_slice(&certificate.direction);
        assert!(y.min() >= 0.0 && y.max() > 0.0, "case {label}: y = {y}");
        let mty = m.transpose() * &y;
        assert!(mty.max() <= 1e-12 * m.amax() * y.sum(), "case {label}: Mᵀy = {mty}");
        assert!(q.dot(&y) < 0.0, "case {label}: qᵀy = {}", q.dot(&y));
        assert_eq!(certificate.q_dot_y, q.dot(&y), "case {label}");
        // Along the ray, z(t) = z* + t dz stays ≥ 0 and M z(t) + q + d z0(t) ≥ 0 for every t ≥ 0
        // with d the covering vector, which the certificate does not store: at least the
        // z-part is nonnegative at t = 0 and t = 1e6.
        let start = DVector::from_column_slice(&certificate.start);
        assert!(start.min() >= 0.0 && (&start + &y * 1e6).min() >= 0.0, "case {label}");
    }
    // The message says what the ray proves.
    let (m, q) = &cases[0];
    let message = lemke(m, q, &LemkeOptions::default()).unwrap_err().to_string();
    assert!(
        message.contains("ray termination") && message.contains("proves the LCP infeasible"),
        "{message}"
    );

    // M ≤ 0 (not copositive) with some q_i < 0 has no feasible point either (w_i < 0), but a
    // ray need not prove it: the ray itself still checks, and the certificate claims
    // infeasibility only with a valid proof.
    let m = DMatrix::from_fn(50, 50, |_, _| -rng.random_range(0.0..1.0));
    let q = DVector::from_fn(50, |i, _| if i % 7 == 3 { -1.0 } else { rng.random_range(0.1..1.0) });
    match lemke(&m, &q, &LemkeOptions::default()) {
        Err(SolverError::LemkeRay { certificate, .. }) => {
            eprintln!("M ≤ 0: {certificate}");
            assert!(certificate.ray_error <= 1e-9, "{certificate}");
            let y = DVector::from_column_slice(&certificate.direction).map(|x| x.max(0.0));
            let proves = (m.transpose() * &y).max() <= 1e-12 * m.amax() * y.sum() && q.dot(&y) < 0.0;
            assert_eq!(certificate.infeasible, proves, "{certificate}");
        }
        other => panic!("M ≤ 0: expected a ray, got {other:?}"),
    }
}

/// A world with a ground plane, friction μ = 0.5 and `solver`.
fn world(dt: f64, solver: SolverKind) -> World {
    let mut options = WorldOptions { dt, solvers: vec![solver], accept_last: true, ..Default::default() };
    options.sleep.enabled = false;
    options.contact.mu = 0.5;
    let mut w = World::new(options);
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    w
}

/// Adds a free 0.1 m box of `mass` kg resting at height `z` (its centre).
fn add_box(w: &mut World, name: &str, mass: f64, z: f64, yaw: f64) {
    let size = Vec3::repeat(0.1);
    let model = free_body(name, Shape::Box { size }, RigidInertia::solid_box(mass, size));
    let m = w.add_multibody(name, model, &MeshOptions::default()).unwrap();
    let q = &mut w.multibody_mut(m).state.q;
    q[2] = z;
    let half = 0.5 * yaw;
    q[5] = half.sin();
    q[6] = half.cos();
}

/// The problem of the world's last step (its rows as posed before the solve).
fn last_problem(w: &mut World, steps: usize) -> ConstraintProblem {
    for _ in 0..steps {
        w.step().unwrap();
    }
    w.problem().clone()
}

/// Lemke on `problem` (friction cone as an 8-facet pyramid): the impulses and the certifying
/// residual of the shared residuals on the pyramid Lemke solves.
fn lemke_certified(problem: &ConstraintProblem) -> (DVector<f64>, f64, usize) {
    let mut solver = LemkeSolver::default();
    let mut lambda = DVector::zeros(problem.rows());
    let info = solver.solve(problem, &mut lambda).unwrap_or_else(|e| panic!("lemke: {e}"));
    let mut pyramid = problem.clone();
    pyramid.friction = FrictionModel::Pyramid { facets: solver.facets };
    let r = solver.certify(&residuals(&pyramid, &lambda, &mut DVector::zeros(0)));
    (lambda, r, info.iterations)
}

#[test]
fn a_heavy_box_on_a_light_one_is_solved_at_every_time_step() {
    // Mass ratio 1:1000: M's entries for the two boxes differ by three orders of magnitude.
    for dt in [1.0 / 60.0, 1.0 / 240.0, 1.0 / 1000.0] {
        let mut w = world(dt, SolverKind::Clarabel);
        add_box(&mut w, "light", 1.0, 0.05, 0.0);
        add_box(&mut w, "heavy", 1000.0, 0.15, 0.0);
        let problem = last_problem(&mut w, 5);
        assert_eq!(problem.contacts.len(), 8, "dt {dt}: four corners under each box");
        let (lambda, r, pivots) = lemke_certified(&problem);
        assert!(r <= 1e-8, "dt {dt}: certified residual {r:e} m/s");
        // The ground carries both boxes: Σ λ_n = (1000 + 1) kg · g · dt, to the step's
        // settling (a few µm of penetration recovered per step at most).
        let ground: f64 = problem.contacts.iter().map(|c| lambda[c.normal]).sum();
        eprintln!("heavy on light, dt {dt}: residual {r:.1e} m/s, {pivots} pivots, Σλ_n {ground:.4} N·s");
    }
}

#[test]
fn a_400_variable_stack_lcp_is_solved_and_certified() {
    // Ten boxes, each turned by 0.1 rad against the one below, at dt = 1/60 s: 40 contacts,
    // whose cone Lemke approximates by 8 facets — 10 LCP variables per contact.
    let mut w = world(1.0 / 60.0, SolverKind::Clarabel);
    for k in 0..10 {
        add_box(&mut w, &format!("box{k}"), 1.0, 0.05 + 0.1 * k as f64 - 1e-4, 0.1 * k as f64);
    }
    let problem = last_problem(&mut w, 30);
    assert_eq!(problem.contacts.len(), 40);
    assert_eq!(lcp_of(&problem, 8).q.len(), 400);
    let (lambda, r, pivots) = lemke_certified(&problem);
    assert!(r <= 1e-8, "certified residual {r:e} m/s after {pivots} pivots");
    // The stack rests: the ground carries ten boxes, Σ λ_n (ground) = 10 kg · g · dt within the
    // settling of one step.
    let total: f64 = problem.contacts.iter().map(|c| lambda[c.normal]).sum();
    eprintln!("stack of 10: residual {r:.1e} m/s, {pivots} pivots, Σλ_n {total:.4} N·s");
}

#[test]
fn every_corpus_problem_is_solved_and_certified() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/problems");
    let mut solved = 0;
    for entry in std::fs::read_dir(&root).unwrap() {
        let dir = entry.unwrap().path();
        if !dir.join(PROBLEM_FILE).is_file() {
            continue;
        }
        let problem = read_problem(&dir).unwrap();
        let mut solver = LemkeSolver::default();
        let mut lambda = DVector::zeros(problem.rows());
        solver.solve(&problem, &mut lambda).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        let certifying = CorpusSolver::Lemke.certifying_problem(&problem);
        let r = solver.certify(&residuals(&certifying, &lambda, &mut DVector::zeros(0)));
        assert!(r <= 1e-8, "{}: certified residual {r:e} m/s", dir.display());
        solved += 1;
    }
    assert!(solved >= 18, "{solved} problems in {}", root.display());
}

#[test]
fn every_step_of_the_ten_box_stack_is_solved_at_every_time_step() {
    // The hard case `stack10` (ten 0.1 m boxes stacked on the ground) with Lemke alone and no
    // answer accepted above the world's tolerance (1e-8 m/s): a step whose LCP Lemke does not
    // solve is an error. One simulated second at each time step of the stability table.
    for dt in TIME_STEPS {
        let mut o = options(&Setting::new(SolverKind::Lemke { facets: 8 }, dt));
        o.accept_last = false;
        let mut w = World::new(o);
        w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
        for k in 0..10 {
            add_box(&mut w, &format!("box{k}"), 1.0, 0.05 + 0.1 * k as f64, 0.0);
        }
        let steps = (1.0 / dt).round() as usize;
        let mut most_contacts = 0;
        for step in 0..steps {
            let stats = w.step().unwrap_or_else(|e| panic!("dt {dt}, step {step}: {e}"));
            assert!(stats.fallbacks.is_empty(), "dt {dt}, step {step}: {:?}", stats.fallbacks);
            assert!(
                stats.contacts == 0 || stats.residual <= 1e-8,
                "dt {dt}, step {step}: {}",
                stats.residual
            );
            most_contacts = most_contacts.max(stats.contacts);
        }
        assert!(most_contacts >= 40, "dt {dt}: {most_contacts} contacts at most");
    }
}

/// A pyramid of 0.1 m cubes of 1 kg on a plane, `base` boxes in the bottom row and `gap` (m)
/// between the boxes of a row, stepped at `dt` by Lemke alone as the stability report sets it;
/// returns the world and the top box.
fn box_pyramid(base: usize, gap: f64, dt: f64) -> (World, usize) {
    let mut w = World::new(options(&Setting::new(SolverKind::Lemke { facets: 8 }, dt)));
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    let side = 0.1;
    let mut top = 0;
    for row in 0..base {
        for k in 0..base - row {
            let name = format!("box{row}_{k}");
            let size = Vec3::repeat(side);
            let model = free_body(&name, Shape::Box { size }, RigidInertia::solid_box(1.0, size));
            top = w.add_multibody(&name, model, &MeshOptions::default()).unwrap();
            let q = &mut w.multibody_mut(top).state.q;
            q[0] = (k as f64 - (base - 1 - row) as f64 / 2.0) * (side + gap);
            q[2] = side / 2.0 + side * row as f64;
        }
    }
    (w, top)
}

#[test]
fn the_box_pyramid_stands_on_lemke_alone_for_six_seconds() {
    // The hard case `pyramid10` (55 boxes of 0.1 m, base 10, 2 mm apart; some 490 contacts,
    // 4900 LCP variables of which every box's four coplanar corners and every sticking
    // contact's eight friction facets are degenerate) at 1/60 s with Lemke alone, as the
    // stability report runs it: every step solved, the top box still, and the steps answered
    // from the last step's basis (a path from the identity costs hundreds of pivots here).
    let (mut w, top) = box_pyramid(10, 0.002, 1.0 / 60.0);
    let start = w.multibody(top).state.q.fixed_rows::<3>(0).into_owned();
    let (mut pivots, mut most_contacts) = (0, 0);
    let steps = 360;
    for step in 0..steps {
        let stats = w.step().unwrap_or_else(|e| panic!("step {step}: {e}"));
        pivots += stats.iterations;
        most_contacts = most_contacts.max(stats.contacts);
    }
    let drift = (w.multibody(top).state.q.fixed_rows::<3>(0) - start).norm();
    assert!(most_contacts >= 400, "{most_contacts} contacts at most");
    assert!(drift < 1e-3, "the top box moved {drift} m");
    assert!(pivots < 10 * steps, "{pivots} pivots in {steps} steps");
}

#[test]
fn a_pyramid_whose_bases_meet_rounding_noise_is_answered_at_every_step() {
    // The 55-box pyramid with 1.5 mm between the boxes of a row at 1/60 s, Lemke alone. By
    // step 262 its LCP's bases are so ill-conditioned that entries of B⁻¹a which are zero in
    // exact arithmetic come out at 1e-9 to 1e-7 of the column: a pivot on one makes the basis
    // singular to working precision (its values jump from ≥ −5e-10 to −0.13 at the next
    // refactorization) and the path ends on a ray that no infeasibility explains (it meets M
    // and q only to 3e-4). The pivot tolerance (1e-7 of the column) keeps the paths off such
    // entries: every step is answered, the top box still, and every answer certified within
    // the world's 1e-8 m/s (the answers at the pyramid's most degenerate vertices polished by
    // block Gauss–Seidel).
    let (mut w, top) = box_pyramid(10, 0.0015, 1.0 / 60.0);
    let tolerance = w.options().tolerance;
    let start = w.multibody(top).state.q.fixed_rows::<3>(0).into_owned();
    let (mut above, mut worst) = (0, 0.0f64);
    let steps = 280;
    for step in 0..steps {
        let stats = w.step().unwrap_or_else(|e| panic!("step {step}: {e}"));
        above += usize::from(stats.residual > tolerance);
        worst = worst.max(stats.residual);
    }
    let drift = (w.multibody(top).state.q.fixed_rows::<3>(0) - start).norm();
    assert!(drift < 1e-6, "the top box moved {drift} m");
    assert_eq!(above, 0, "{above} of {steps} steps above {tolerance:e} m/s (largest {worst:e})");
}

#[test]
fn a_pyramid_of_touching_boxes_certifies_at_every_step() {
    // The 36-box pyramid whose boxes of a row touch (no gap) at 1/60 s, Lemke alone, six
    // seconds: at its most degenerate vertices every path's final basis, refined, leaves some
    // 1200 of its 3680 w a few 1e-9 below zero (boxes left sliding at a few nm/s without the
    // friction that stops them, unloaded corners approaching at that speed), and neither
    // principal pivots nor restarts from that basis resolve them. Block Gauss–Seidel from the
    // path's answer does: every step certified within the world's 1e-8 m/s.
    let (mut w, top) = box_pyramid(8, 0.0, 1.0 / 60.0);
    let tolerance = w.options().tolerance;
    let start = w.multibody(top).state.q.fixed_rows::<3>(0).into_owned();
    let (mut above, mut worst) = (0, 0.0f64);
    for step in 0..360 {
        let stats = w.step().unwrap_or_else(|e| panic!("step {step}: {e}"));
        above += usize::from(stats.residual > tolerance);
        worst = worst.max(stats.residual);
    }
    let drift = (w.multibody(top).state.q.fixed_rows::<3>(0) - start).norm();
    assert!(drift < 1e-6, "the top box moved {drift} m");
    assert_eq!(above, 0, "{above} steps above {tolerance:e} m/s (largest {worst:e})");
}

#[test]
fn a_twenty_box_stack_lcp_whose_paths_end_on_infeasible_bases_is_solved() {
    // A step of the hard case `stack20` at 1/60 s (80 contacts, 800 LCP variables, written by
    // `World::problem` with `io::problem::problem_to_json`): the paths from the covering
    // vectors end on complementary bases whose values are some 1e-9 below zero after hundreds
    // of degenerate pivots, which polishing cannot repair; a path restarted from such a basis
    // lifts them and ends on a solution.
    let problem = exported_problem("lemke_stack20_dt60_problem.json");
    assert_eq!(problem.contacts.len(), 80);
    let (_, r, pivots) = lemke_certified(&problem);
    assert!(r <= 1e-8, "certified residual {r:e} m/s after {pivots} pivots");
}

#[test]
fn lemke_and_clarabel_agree_on_frictionless_contacts() {
    // Without friction the LCP is the optimality condition of a convex QP, whose row velocities
    // w = (A + R) λ + b are unique: Lemke's and clarabel's must agree.
    let mut w = world(1.0 / 240.0, SolverKind::Clarabel);
    for k in 0..4 {
        add_box(
            &mut w,
            &format!("box{k}"),
            [1.0, 1000.0, 3.0, 0.5][k],
            0.05 + 0.1 * k as f64 - 1e-4,
            0.3 * k as f64,
        );
    }
    let mut problem = last_problem(&mut w, 10);
    for block in &mut problem.contacts {
        block.mu = 0.0;
        block.mu2 = 0.0;
    }
    assert!(problem.contacts.len() >= 16);
    let velocities = |lambda: &DVector<f64>| {
        let mut a = problem.delassus_dense().into_owned();
        for i in 0..problem.rows() {
            a[(i, i)] += problem.regularization[i];
        }
        a * lambda + &problem.bias
    };
    let mut lambda_lemke = DVector::zeros(problem.rows());
    LemkeSolver::default().solve(&problem, &mut lambda_lemke).unwrap();
    let mut lambda_clarabel = DVector::zeros(problem.rows());
    ClarabelSolver::default().solve(&problem, &mut lambda_clarabel).unwrap();
    let (wl, wc) = (velocities(&lambda_lemke), velocities(&lambda_clarabel));
    let scale = problem.bias.amax().max(1e-3);
    let difference = (&wl - &wc).amax();
    assert!(difference <= 1e-6 * scale, "w differs by {difference:e} (scale {scale:e})");
}

#[test]
fn the_pile_lcp_answer_certifies_at_the_world_tolerance() {
    // models/pile.toml at step 300 (the benchmark's 2000-variable LCP, about 200 contacts, its
    // rows softened by the scene's `softness`, R = 0.02 A_ii): the answer's basic values are
    // refined with residuals in double-double arithmetic, so the impulses certify far below the
    // world's 1e-8 m/s, where the dissipation gap of contacts with the smallest normal impulses
    // (per unit of their friction bound) amplifies any inaccuracy of the basic values.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/pile.toml");
    let mut world = gelenk::io::scene::load_file(&path).unwrap().world;
    for _ in 0..=300 {
        world.step().unwrap();
    }
    let problem = world.problem().clone();
    assert!(lcp_of(&problem, 8).q.len() >= 1500, "a pile LCP of {} variables", lcp_of(&problem, 8).q.len());
    assert!(problem.regularization.iter().all(|&r| r > 0.0), "every row of the pile is softened");
    let (_, r, pivots) = lemke_certified(&problem);
    assert!(r <= 1e-9, "certified residual {r:e} m/s after {pivots} pivots");
}

/// The problem of each of `steps` steps of a ten-box stack at `dt` with Lemke alone.
fn stack_problems(dt: f64, steps: usize) -> Vec<ConstraintProblem> {
    let mut w = World::new(options(&Setting::new(SolverKind::Lemke { facets: 8 }, dt)));
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    for k in 0..10 {
        add_box(&mut w, &format!("box{k}"), 1.0, 0.05 + 0.1 * k as f64, 0.1 * k as f64);
    }
    (0..steps)
        .map(|_| {
            w.step().unwrap();
            w.problem().clone()
        })
        .collect()
}

/// Lemke's answer to `problem` by `solver` from the warm start `lambda`: the impulses, the
/// certified residual, the pivots and whether the solve started from a given basis.
fn solve_with(
    solver: &mut LemkeSolver,
    problem: &ConstraintProblem,
    mut lambda: DVector<f64>,
) -> (DVector<f64>, f64, usize, bool) {
    let info = solver.solve(problem, &mut lambda).unwrap_or_else(|e| panic!("lemke: {e}"));
    let mut pyramid = problem.clone();
    pyramid.friction = FrictionModel::Pyramid { facets: solver.facets };
    let r = solver.certify(&residuals(&pyramid, &lambda, &mut DVector::zeros(0)));
    (lambda, r, info.iterations, solver.memory.last.warm_started)
}

/// Σ λ_n over the contacts: the support the stack gets, unique where the impulses need not be.
fn normal_sum(problem: &ConstraintProblem, lambda: &DVector<f64>) -> f64 {
    problem.contacts.iter().map(|c| lambda[c.normal]).sum()
}

#[test]
fn a_warm_started_solve_equals_a_cold_one_with_fewer_pivots() {
    // Consecutive steps of a resting ten-box stack: the solver that solved step 40 starts step
    // 41 from its final basis (the same contact rows) and the one given step 41's answer as its
    // warm start reads its basis from those impulses; both certify like a cold solve, support
    // the stack with the same normal impulse and pivot less.
    let problems = stack_problems(1.0 / 60.0, 42);
    let (before, now) = (&problems[40], &problems[41]);
    assert_eq!(before.laws, now.laws, "the same rows at both steps");
    let zeros = DVector::zeros(now.rows());
    let (cold, r_cold, pivots_cold, warm_cold) =
        solve_with(&mut LemkeSolver { memory: LemkeMemory::off(), ..Default::default() }, now, zeros.clone());
    assert!(!warm_cold && r_cold <= 1e-8 && pivots_cold > 10, "cold: {r_cold:e} m/s, {pivots_cold} pivots");
    let mut solver = LemkeSolver::default();
    let (last, _, _, _) = solve_with(&mut solver, before, zeros.clone());
    let (kept, r_kept, pivots_kept, warm_kept) = solve_with(&mut solver, now, last);
    let (read, r_read, pivots_read, warm_read) = solve_with(&mut LemkeSolver::default(), now, cold.clone());
    let total = normal_sum(now, &cold);
    for (name, lambda, r, pivots, warm) in [
        ("kept basis", &kept, r_kept, pivots_kept, warm_kept),
        ("basis read from λ", &read, r_read, pivots_read, warm_read),
    ] {
        assert!(warm, "{name}: started from a basis");
        assert!(r <= 1e-8, "{name}: certified residual {r:e} m/s");
        assert!(pivots < pivots_cold, "{name}: {pivots} pivots, cold {pivots_cold}");
        let sum = normal_sum(now, lambda);
        // Two answers within Lemke's LCP tolerance (1e-9 ‖q‖∞; Harris's tolerance lets basic
        // values end up to 2.5e-10 ‖q‖∞ below zero before they are cleaned) agree to 1e-8.
        assert!((sum - total).abs() <= 1e-8 * total, "{name}: Σλ_n {sum} against {total}");
    }
}

#[test]
fn an_unchanged_matrix_is_reused_and_a_new_q_solved_from_the_last_basis() {
    // The same problem with its bias scaled by 1.001 (as a resting world poses it when it keeps
    // W and forms only b): M is the last one, q alone is formed, and the last basis, whose
    // values scale with q, answers it.
    let problems = stack_problems(1.0 / 240.0, 60);
    let problem = &problems[59];
    let mut solver = LemkeSolver::default();
    let (first, _, _, _) = solve_with(&mut solver, problem, DVector::zeros(problem.rows()));
    let mut nudged = problem.clone();
    nudged.bias *= 1.001;
    let (lambda, r, pivots, warm) = solve_with(&mut solver, &nudged, first);
    assert_eq!(solver.memory.reused_matrices, 1, "M kept");
    // The basic values scale with q: z0 in and out again where a value is below zero by
    // rounding, with a degenerate exchange between on some steps (this one).
    assert!(warm && r <= 1e-8 && pivots <= 3, "{r:e} m/s after {pivots} pivots");
    let (cold, r_cold, _, _) = solve_with(
        &mut LemkeSolver { memory: LemkeMemory::off(), ..Default::default() },
        &nudged,
        DVector::zeros(problem.rows()),
    );
    assert!(r_cold <= 1e-8);
    let (sum, total) = (normal_sum(&nudged, &lambda), normal_sum(&nudged, &cold));
    assert!((sum - total).abs() <= 1e-9 * total, "Σλ_n {sum} against {total}");
}

/// `problem` (contact rows only) with its contact blocks in the order `order` (block `order[c]`
/// of `problem` becomes block c), by its dense A: the rows a world poses when its contacts
/// come in another order.
fn reordered(problem: &ConstraintProblem, order: &[usize]) -> ConstraintProblem {
    assert_eq!(problem.rows(), 3 * problem.contacts.len(), "contact rows only");
    let row = |i: usize| 3 * order[i / 3] + i % 3;
    let n = problem.rows();
    let a = problem.delassus_dense();
    let mut out = ConstraintProblem::from_parts(
        DMatrix::from_fn(n, n, |i, j| a[(row(i), row(j))]),
        DVector::from_fn(n, |i, _| problem.bias[row(i)]),
        (0..n)
            .map(|i| match problem.laws[row(i)] {
                RowLaw::Friction { .. } => RowLaw::Friction { contact: i / 3 },
                law => law,
            })
            .collect(),
        (0..order.len()).map(|c| ContactBlock { normal: 3 * c, ..problem.contacts[order[c]] }).collect(),
        problem.friction,
    );
    out.regularization = DVector::from_fn(n, |i, _| problem.regularization[row(i)]);
    out
}

#[test]
fn a_warm_start_on_reordered_contacts_reads_its_basis_from_the_impulses() {
    // Step 41 of the resting ten-box stack with its contacts in reverse order, after the solver
    // answered step 40 in the original order: the same rows and laws, so the last basis has the
    // right shape but every contact in another place. The warm start (step 40's impulses,
    // reordered with the contacts as a world matches them) is not the last answer, so the
    // basis is read from it: it certifies like a cold solve, supports the stack with the same
    // normal impulse and pivots less.
    let problems = stack_problems(1.0 / 60.0, 42);
    let (before, now) = (&problems[40], &problems[41]);
    assert_eq!(before.laws, now.laws, "the same rows at both steps");
    let order: Vec<usize> = (0..now.contacts.len()).rev().collect();
    let now = reordered(now, &order);
    let zeros = DVector::zeros(now.rows());
    let (cold, r_cold, pivots_cold, _) = solve_with(
        &mut LemkeSolver { memory: LemkeMemory::off(), ..Default::default() },
        &now,
        zeros.clone(),
    );
    assert!(r_cold <= 1e-8 && pivots_cold > 10, "cold: {r_cold:e} m/s, {pivots_cold} pivots");
    let mut solver = LemkeSolver::default();
    let (last, _, _, _) = solve_with(&mut solver, before, zeros);
    let start = DVector::from_fn(now.rows(), |i, _| last[3 * order[i / 3] + i % 3]);
    let (lambda, r, pivots, warm) = solve_with(&mut solver, &now, start);
    assert!(warm && r <= 1e-8, "certified residual {r:e} m/s");
    assert!(pivots < pivots_cold / 2, "{pivots} pivots, cold {pivots_cold}");
    let (sum, total) = (normal_sum(&now, &lambda), normal_sum(&now, &cold));
    // Both within Lemke's LCP tolerance: the same support to 1e-8.
    assert!((sum - total).abs() <= 1e-8 * total, "Σλ_n {sum} against {total}");
}

#[test]
fn an_answer_the_chain_certifies_ends_the_solve() {
    // A stack20 step, with Lemke's own LCP tolerance (1e-11) below what its first path reaches
    // (4e-10): alone, Lemke tries further covering vectors; told the tolerance its chain
    // certifies against (1e-8 m/s), it accepts the first path's answer, whose problem residual
    // is within it, and says so.
    let problem = exported_problem("lemke_stack20_dt60_problem.json");
    let options = LemkeOptions { tolerance: 1e-11, ..Default::default() };
    let mut alone = LemkeSolver { options, ..Default::default() };
    alone.solve(&problem, &mut DVector::zeros(problem.rows())).unwrap();
    assert!(alone.memory.last.attempts >= 2, "alone: {:?}", alone.memory.last);
    let mut chained = LemkeSolver { options, ..Default::default() };
    chained.set_certified_tolerance(1e-8);
    let mut lambda = DVector::zeros(problem.rows());
    let info = chained.solve(&problem, &mut lambda).unwrap();
    let report = &chained.memory.last;
    assert_eq!(report.attempts, 1, "{report:?}");
    assert!(
        report.residual > chained.options.tolerance,
        "the LCP residual {:e} misses Lemke's",
        report.residual
    );
    let r = chained.certify(&residuals(&problem, &lambda, &mut DVector::zeros(0)));
    assert!(r <= 1e-8, "problem residual {r:e} m/s");
    assert!(info.note.is_some_and(|n| n.contains("accepted on the problem's residual")));
    assert!(
        report.pivots < alone.memory.last.pivots,
        "{} pivots, alone {}",
        report.pivots,
        alone.memory.last.pivots
    );
}

#[test]
fn an_answer_within_the_lcp_tolerance_is_refined_to_the_level_it_is_certified_against() {
    // Two corpus problems (a buggy on terrain, cone friction as 8 facets; a humanoid of the
    // pile, joint limits and 4-facet pyramids) whose first answer meets Lemke's LCP tolerance
    // (1e-9 relative to max(1, ‖q‖∞)) but not 1e-9 m/s on the problem: its final basis leaves
    // friction facets a few 1e-9 below zero, which the dissipation gap counts per unit of a
    // small friction bound. Told 1e-9 m/s, Lemke refines the answer by a path from its basis.
    for name in ["lemke_buggy_terrain_s0089_problem.json", "lemke_humanoid_pile_s0399_problem.json"] {
        let problem = exported_problem(name);
        let certifying = CorpusSolver::Lemke.certifying_problem(&problem);
        let q = lcp_of(&problem, 8).q;
        let lcp_tolerance = LemkeOptions::default().tolerance * q.amax().max(1.0);
        let mut alone = LemkeSolver::default();
        let mut lambda = DVector::zeros(problem.rows());
        alone.solve(&problem, &mut lambda).unwrap();
        let r = alone.certify(&residuals(&certifying, &lambda, &mut DVector::zeros(0)));
        assert!(r > 1e-9 && alone.memory.last.residual <= lcp_tolerance, "{name}: alone {r:e} m/s");
        let mut told = LemkeSolver::default();
        told.set_certified_tolerance(1e-9);
        let mut lambda = DVector::zeros(problem.rows());
        told.solve(&problem, &mut lambda).unwrap();
        let report = &told.memory.last;
        let r = told.certify(&residuals(&certifying, &lambda, &mut DVector::zeros(0)));
        assert!(r <= 1e-9, "{name}: told 1e-9 m/s, {r:e} m/s ({report:?})");
        assert!(report.refined_to_level && report.residual <= lcp_tolerance, "{name}: {report:?}");
        eprintln!("{name}: {r:.1e} m/s, {} pivots", report.pivots);
    }
}

/// `LemkeOptions::max_matrix_entries` bounds what a solve stores: an exported stack20 step (its
/// A given dense, as a problem file gives it) is refused with the typed error at a limit below
/// its A + R's entries, and solved at the default (no limit) and at a limit it fits in.
#[test]
fn the_matrix_limit_refuses_a_problem_before_forming_its_lcp() {
    let problem = exported_problem("lemke_stack20_dt60_problem.json");
    assert!(!problem.is_matrix_free(), "the file gives A");
    let solve = |max_matrix_entries: usize| {
        let options = LemkeOptions { max_matrix_entries, ..Default::default() };
        LemkeSolver { options, ..Default::default() }.solve(&problem, &mut DVector::zeros(problem.rows()))
    };
    match solve(problem.rows()) {
        Err(SolverError::LemkeMatrixTooLarge { limit }) => assert_eq!(limit, problem.rows()),
        other => panic!("expected the matrix limit, got {other:?}"),
    }
    solve(0).unwrap();
    solve(100 * problem.rows() * problem.rows()).unwrap();
}
