//! Pins the constraint solvers quantitatively: Lemke recovers known solutions of random P-matrix
//! LCPs; Lemke, clarabel and PGS agree on what is unique in problems assembled from real collision
//! (a resting box, a two-box stack, a spinning box), hold a box on a 10° incline or let it slide
//! downhill (clarabel's cone relaxation "hovers" at μ‖u_t‖), handle redundant loop-closure rows,
//! joint limits with bounce and saturating motors; PGS converges to clarabel's answer; the solver
//! chain reports its fallbacks; bad input gives errors, never panics.

use gelenk::collision::{Attachment, CollisionOptions, CollisionWorld, Contact, MeshOptions};
use gelenk::constraints::{
    add_contact_rows, add_joint_limit_rows, add_loop_closure_rows, add_motor_row, assemble_single,
    loop_error, ConstraintProblem, ContactBlock, ContactParameters, FrictionModel, JointLimitParameters,
    LoopClosure, LoopKind, ProblemBuilder, RowLaw,
};
use gelenk::math::{axis_angle, Mat3};
use gelenk::model::{JointLimits, Shape};
use gelenk::prelude::*;
use gelenk::solvers::{
    lemke, residuals, ClarabelSolver, ConstraintSolver, LemkeOptions, LemkeSolver, PgsSolver, Residuals,
    SolveInfo, SolverChain, SolverError,
};
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::panic::{catch_unwind, AssertUnwindSafe};

const G: f64 = 9.81;

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

fn box_spec(name: &str, mass: f64, size: Vec3) -> BodySpec {
    BodySpec::new(name, "universe", Joint::Free, Transform::identity(), RigidInertia::solid_box(mass, size))
        .with_collision(Shape::Box { size }, Transform::identity())
}

/// Writes the pose (rotation `r`, position `t`) of free body `k` into q.
fn set_free_pose(q: &mut DVector<f64>, k: usize, r: &Mat3, t: Vec3) {
    let quat = nalgebra::UnitQuaternion::from_matrix(r);
    q.rows_mut(7 * k, 3).copy_from(&t);
    q[7 * k + 3] = quat.i;
    q[7 * k + 4] = quat.j;
    q[7 * k + 5] = quat.k;
    q[7 * k + 6] = quat.w;
}

/// A problem assembled from the contacts of `model` (free boxes) at (q, v) with a static
/// half-space of normal `ground` through the origin; gravity on, v_free = v + h·ABA(q, v, 0).
struct Assembled {
    problem: ConstraintProblem,
    contacts: Vec<Contact>,
    v_free: DVector<f64>,
}

fn assemble_contacts(
    model: &Model,
    q: &DVector<f64>,
    v: &DVector<f64>,
    h: f64,
    ground: Vec3,
    params: ContactParameters,
    friction: FrictionModel,
) -> Assembled {
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, q).unwrap();
    let mut world = CollisionWorld::new(CollisionOptions::default());
    let mb = world.add_model(model, &MeshOptions::default()).unwrap();
    world.set_self_collision(mb, true).unwrap();
    world
        .add_static(
            "ground",
            &Shape::HalfSpace { normal: ground },
            Transform::identity(),
            &MeshOptions::default(),
        )
        .unwrap();
    world.update_multibody(mb, &data).unwrap();
    let contacts = world.detect().to_vec();
    let tau = DVector::zeros(model.nv());
    let a = aba(model, &mut data, q, v, &tau).unwrap().clone();
    let v_free = v + a * h;
    compute_joint_jacobians(model, &mut data, q).unwrap();
    crba(model, &mut data, q).unwrap();
    factor_mass_matrix(model, &mut data).unwrap();
    let mut rows = ProblemBuilder::new(model.nv(), friction);
    add_contact_rows(&mut rows, &[(model, &data)], &[0], &contacts, 0, v, h, |_| params);
    let mut problem = ConstraintProblem::default();
    assemble_single(&rows, model, &data, &v_free, &mut problem);
    Assembled { problem, contacts, v_free }
}

fn frictionless() -> ContactParameters {
    ContactParameters { mu: 0.0, ..Default::default() }
}

fn solve_with(solver: &mut dyn ConstraintSolver, problem: &ConstraintProblem) -> (DVector<f64>, SolveInfo) {
    let mut lambda = DVector::zeros(problem.rows());
    let info = solver.solve(problem, &mut lambda).unwrap_or_else(|e| panic!("{}: {e}", solver.name()));
    (lambda, info)
}

fn row_velocities(problem: &ConstraintProblem, lambda: &DVector<f64>) -> DVector<f64> {
    let mut w = DVector::zeros(problem.rows());
    problem.velocities(lambda, &mut w);
    w
}

fn residuals_of(problem: &ConstraintProblem, lambda: &DVector<f64>) -> Residuals {
    let mut w = DVector::zeros(0);
    residuals(problem, lambda, &mut w)
}

fn max_diff(a: &DVector<f64>, b: &DVector<f64>) -> f64 {
    assert_eq!(a.len(), b.len());
    (a - b).amax()
}

fn sci(xs: &[f64]) -> String {
    xs.iter().map(|x| format!("{x:.3e}")).collect::<Vec<_>>().join(", ")
}

fn total_normal_impulse(problem: &ConstraintProblem, lambda: &DVector<f64>) -> f64 {
    problem.contacts.iter().map(|c| lambda[c.normal]).sum()
}

/// Post-step velocity v⁺ = v_free + M⁻¹ Jᵀ λ (unique even when λ is not).
fn post_velocity(problem: &ConstraintProblem, v_free: &DVector<f64>, lambda: &DVector<f64>) -> DVector<f64> {
    v_free + &problem.minv_jt * lambda
}

/// A box of 2 kg, 0.4 × 0.3 × 0.2 m, resting flat on the ground (0.2 mm into it: within the
/// surface layer, so the target normal velocity is 0).
fn resting_box() -> (Model, DVector<f64>, f64) {
    let mass = 2.0;
    let mut b = ModelBuilder::new();
    b.add_body(box_spec("box", mass, Vec3::new(0.4, 0.3, 0.2)));
    let model = b.build().unwrap();
    let mut q = model.neutral_configuration();
    set_free_pose(&mut q, 0, &Mat3::identity(), Vec3::new(0.0, 0.0, 0.1 - 2e-4));
    (model, q, mass)
}

/// Boxes stacked flat on the ground, each 0.2 m high and a little smaller than the one below,
/// every contact 0.2 mm deep. Returns the model, q and the masses.
fn box_stack(count: usize) -> (Model, DVector<f64>, Vec<f64>) {
    let mut b = ModelBuilder::new();
    let masses: Vec<f64> = (0..count).map(|k| if k == 0 { 2.0 } else { 1.0 + 0.1 * k as f64 }).collect();
    let sizes: Vec<Vec3> = (0..count)
        .map(|k| {
            if count == 2 && k == 1 {
                Vec3::new(0.3, 0.2, 0.2)
            } else {
                Vec3::new(0.4 - 0.02 * k as f64, 0.3 - 0.015 * k as f64, 0.2)
            }
        })
        .collect();
    for k in 0..count {
        b.add_body(box_spec(&format!("box{k}"), masses[k], sizes[k]));
    }
    let model = b.build().unwrap();
    let mut q = model.neutral_configuration();
    let pen = 2e-4;
    for k in 0..count {
        let z = 0.2 * k as f64 + 0.1 - (k as f64 + 1.0) * pen;
        set_free_pose(&mut q, k, &Mat3::identity(), Vec3::new(0.0, 0.0, z));
    }
    (model, q, masses)
}

// ---------------------------------------------------------------------------------------------
// 1. Random P-matrix LCPs with known solutions
// ---------------------------------------------------------------------------------------------

#[test]
fn lemke_recovers_known_solutions_of_random_p_matrix_lcps() {
    let (mut worst, mut most_pivots) = (0.0f64, 0usize);
    for case in 0..50u64 {
        let mut rng = StdRng::seed_from_u64(0x5eed_0000 + case);
        let n = match case {
            0 => 1,
            1 => 60,
            _ => rng.random_range(1..=60),
        };
        let b = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
        let mut m = &b * b.transpose() + DMatrix::identity(n, n);
        if case % 2 == 1 {
            // SPD + skew-symmetric: still positive definite (xᵀ M x = xᵀ S x > 0), a P-matrix.
            let c = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
            m += &c - c.transpose();
        }
        let z_star =
            DVector::from_fn(n, |_, _| if rng.random_bool(0.5) { rng.random_range(0.1..2.0) } else { 0.0 });
        let w_star =
            DVector::from_fn(n, |i, _| if z_star[i] > 0.0 { 0.0 } else { rng.random_range(0.1..2.0) });
        let q = &w_star - &m * &z_star;
        let (z, pivots) =
            lemke(&m, &q, &LemkeOptions::default()).unwrap_or_else(|e| panic!("case {case} (n = {n}): {e}"));
        let error = (&z - &z_star).amax() / z_star.amax().max(1.0);
        assert!(error < 1e-9, "case {case} (n = {n}): relative error {error:.3e}");
        let w = &m * &z + &q;
        assert!((&w - &w_star).amax() < 1e-9 * q.amax().max(1.0), "case {case}: w differs");
        assert!(z.iter().all(|&x| x >= 0.0));
        worst = worst.max(error);
        most_pivots = most_pivots.max(pivots);
    }
    eprintln!("random LCPs: worst relative error {worst:.3e}, most pivots {most_pivots}");
}

// ---------------------------------------------------------------------------------------------
// 2. Frictionless multi-contact problems from collision
// ---------------------------------------------------------------------------------------------

/// Lemke and clarabel on `problem`: what is unique agrees, both certify.
fn compare_lemke_clarabel(label: &str, problem: &ConstraintProblem) -> (DVector<f64>, DVector<f64>) {
    let (l_lemke, _) = solve_with(&mut LemkeSolver::default(), problem);
    let (l_clar, _) = solve_with(&mut ClarabelSolver::default(), problem);
    let (r_lemke, r_clar) = (residuals_of(problem, &l_lemke), residuals_of(problem, &l_clar));
    assert!(r_lemke.exact() < 1e-8, "{label}: lemke residuals {r_lemke:?}");
    assert!(r_clar.convex() < 1e-8, "{label}: clarabel residuals {r_clar:?}");
    // Frictionless: the QP residuals are available and small for both.
    for (name, r) in [("lemke", r_lemke), ("clarabel", r_clar)] {
        let qp = r.qp.unwrap_or_else(|| panic!("{label}: {name}: frictionless problem has QP residuals"));
        assert!(qp.primal < 1e-8 && qp.dual < 1e-8, "{label}: {name}: {qp:?}");
    }
    let (w_lemke, w_clar) = (row_velocities(problem, &l_lemke), row_velocities(problem, &l_clar));
    let dw = max_diff(&w_lemke, &w_clar);
    assert!(dw < 1e-8, "{label}: w differs by {dw:.3e}");
    let (t_lemke, t_clar) = (total_normal_impulse(problem, &l_lemke), total_normal_impulse(problem, &l_clar));
    assert!((t_lemke - t_clar).abs() < 1e-8, "{label}: total normal impulse {t_lemke} vs {t_clar}");
    // Generalized impulse Jᵀλ (forces and moments on every body) is unique.
    let (g_lemke, g_clar) = (problem.jacobian.transpose() * &l_lemke, problem.jacobian.transpose() * &l_clar);
    let dg = max_diff(&g_lemke, &g_clar);
    assert!(dg < 1e-8, "{label}: Jᵀλ differs by {dg:.3e}");
    eprintln!(
        "{label}: {} rows, |Δw| {dw:.2e}, |Δ total| {:.2e}, |Δ Jᵀλ| {dg:.2e}, residuals lemke {:.2e} clarabel {:.2e}",
        problem.rows(),
        (t_lemke - t_clar).abs(),
        r_lemke.exact(),
        r_clar.convex()
    );
    (l_lemke, l_clar)
}

#[test]
fn resting_box_frictionless_lemke_and_clarabel_hold_it_against_gravity() {
    let (model, q, mass) = resting_box();
    let h = 1e-3;
    let v = DVector::zeros(model.nv());
    let s = assemble_contacts(&model, &q, &v, h, Vec3::z(), frictionless(), FrictionModel::Cone);
    assert_eq!(s.contacts.len(), 4, "four coplanar corners: {:?}", s.contacts);
    assert_eq!(s.problem.rows(), 12);
    let (l_lemke, l_clar) = compare_lemke_clarabel("resting box", &s.problem);
    let expected = mass * G * h;
    // clarabel's default tolerance (1e-10) is on velocities: its total impulse is m g h to
    // ~1.4e-10 m/s × m (1.4e-8 relative, measured); at tolerance 1e-12 it meets 1e-9 relative.
    let total = total_normal_impulse(&s.problem, &l_clar);
    assert!(
        (total - expected).abs() / mass < 1e-9,
        "clarabel (default): total {total} vs m g h = {expected}"
    );
    let (l_tight, _) = solve_with(&mut ClarabelSolver { tolerance: 1e-12, ..Default::default() }, &s.problem);
    for (name, lambda) in
        [("lemke", &l_lemke), ("clarabel", &l_clar), ("clarabel (tolerance 1e-12)", &l_tight)]
    {
        let total = total_normal_impulse(&s.problem, lambda);
        if name != "clarabel" {
            assert!(
                (total - expected).abs() < 1e-9 * expected,
                "{name}: total {total} vs m g h = {expected}"
            );
        }
        // Held: the box does not move after the step.
        let v_plus = post_velocity(&s.problem, &s.v_free, lambda);
        assert!(v_plus.amax() < 1e-9, "{name}: v⁺ = {v_plus}");
        // Moments about the centre vanish: the impulse acts through the centre of mass.
        let (mut mx, mut my) = (0.0, 0.0);
        for (c, block) in s.contacts.iter().zip(&s.problem.contacts) {
            mx += c.point_a.y * lambda[block.normal];
            my -= c.point_a.x * lambda[block.normal];
        }
        assert!(mx.abs() < 1e-10 && my.abs() < 1e-10, "{name}: moments {mx} {my} (N·m·s)");
    }
    // PGS too (it reaches the same velocities).
    let (l_pgs, _) =
        solve_with(&mut PgsSolver { iterations: 500, tolerance: 0.0, ..Default::default() }, &s.problem);
    let total = total_normal_impulse(&s.problem, &l_pgs);
    assert!((total - expected).abs() < 1e-9 * expected, "pgs: total {total} vs {expected}");
}

#[test]
fn two_box_stack_frictionless_lemke_and_clarabel_agree() {
    let (model, q, masses) = box_stack(2);
    let h = 1.0 / 60.0;
    let v = DVector::zeros(model.nv());
    let s = assemble_contacts(&model, &q, &v, h, Vec3::z(), frictionless(), FrictionModel::Cone);
    assert_eq!(s.contacts.len(), 8, "{:?}", s.contacts);
    let (l_lemke, l_clar) = compare_lemke_clarabel("2-box stack", &s.problem);
    for (name, lambda) in [("lemke", &l_lemke), ("clarabel", &l_clar)] {
        let (mut ground, mut between) = (0.0, 0.0);
        for (c, block) in s.contacts.iter().zip(&s.problem.contacts) {
            if c.body_b == Attachment::World {
                ground += lambda[block.normal];
            } else {
                between += lambda[block.normal];
            }
        }
        let (eg, eb) = ((masses[0] + masses[1]) * G * h, masses[1] * G * h);
        assert!((ground - eg).abs() < 1e-9 * eg, "{name}: ground {ground} vs {eg}");
        assert!((between - eb).abs() < 1e-9 * eb, "{name}: between {between} vs {eb}");
        let v_plus = post_velocity(&s.problem, &s.v_free, lambda);
        assert!(v_plus.amax() < 1e-9, "{name}: v⁺ = {v_plus}");
    }
}

#[test]
fn spinning_box_frictionless_lemke_and_clarabel_agree() {
    let (model, _, _) = resting_box();
    let h = 1e-3;
    for seed in 0..5u64 {
        let mut rng = StdRng::seed_from_u64(77 + seed);
        let yaw = rng.random_range(-3.0..3.0);
        let mut q = model.neutral_configuration();
        set_free_pose(&mut q, 0, &axis_angle(&Vec3::z(), yaw), Vec3::new(0.0, 0.0, 0.1 - 2e-4));
        let v = DVector::from_fn(6, |i, _| {
            if i < 3 {
                rng.random_range(-0.1..0.1)
            } else {
                rng.random_range(-1.0..1.0)
            }
        });
        let s = assemble_contacts(&model, &q, &v, h, Vec3::z(), frictionless(), FrictionModel::Cone);
        assert_eq!(s.contacts.len(), 4);
        let (l_lemke, l_clar) = compare_lemke_clarabel(&format!("spinning box {seed}"), &s.problem);
        let dv = max_diff(
            &post_velocity(&s.problem, &s.v_free, &l_lemke),
            &post_velocity(&s.problem, &s.v_free, &l_clar),
        );
        // Angular velocities amplify impulse differences by 1/I (I_zz ≈ 0.04 kg·m²).
        assert!(dv < 1e-7, "seed {seed}: v⁺ differs by {dv:.3e}");
    }
}

// ---------------------------------------------------------------------------------------------
// 3. Friction on a 10° incline
// ---------------------------------------------------------------------------------------------

const INCLINE_DEG: f64 = 10.0;

/// A box at rest on a half-space tilted by 10° about x; returns the problem (friction model
/// `friction`) and the downhill unit vector.
fn incline(mu: f64, friction: FrictionModel) -> (Assembled, Vec3) {
    let (model, _, _) = resting_box();
    let theta = INCLINE_DEG.to_radians();
    let r = axis_angle(&Vec3::x(), theta);
    let normal = r * Vec3::z();
    let mut q = model.neutral_configuration();
    set_free_pose(&mut q, 0, &r, r * Vec3::new(0.0, 0.0, 0.1 - 2e-4));
    let v = DVector::zeros(6);
    let h = 1.0 / 60.0;
    let s = assemble_contacts(
        &model,
        &q,
        &v,
        h,
        normal,
        ContactParameters { mu, ..Default::default() },
        friction,
    );
    assert_eq!(s.contacts.len(), 4);
    let g = Vec3::new(0.0, 0.0, -1.0);
    let downhill = (g - normal * normal.dot(&g)).normalize();
    (s, downhill)
}

fn friction_solvers() -> Vec<(FrictionModel, Box<dyn ConstraintSolver>)> {
    let pgs = || Box::new(PgsSolver { iterations: 20_000, tolerance: 1e-15, ..Default::default() });
    vec![
        (FrictionModel::Cone, Box::new(ClarabelSolver::default())),
        (FrictionModel::Pyramid { facets: 4 }, Box::new(LemkeSolver::default())),
        (FrictionModel::Pyramid { facets: 8 }, Box::new(LemkeSolver::default())),
        (FrictionModel::Pyramid { facets: 4 }, pgs()),
        (FrictionModel::Pyramid { facets: 8 }, pgs()),
    ]
}

#[test]
fn incline_with_mu_half_every_solver_sticks() {
    for (friction, mut solver) in friction_solvers() {
        let (s, _) = incline(0.5, friction);
        let (lambda, info) = solve_with(solver.as_mut(), &s.problem);
        let label = format!("{} on {friction:?}", solver.name());
        let v_plus = post_velocity(&s.problem, &s.v_free, &lambda);
        let r = residuals_of(&s.problem, &lambda);
        let certified = solver.certify(&r);
        eprintln!(
            "incline μ = 0.5, {label}: |v⁺| {:.2e}, residual {certified:.2e}, iterations {}",
            v_plus.amax(),
            info.iterations
        );
        assert!(v_plus.amax() < 1e-9, "{label}: sticking, but v⁺ = {v_plus}");
        assert!(certified < 1e-8, "{label}: residuals {r:?}");
        // The normal impulses carry the normal weight m g h cos θ.
        let theta = INCLINE_DEG.to_radians();
        let normal_total = total_normal_impulse(&s.problem, &lambda);
        let expected = 2.0 * G * (1.0 / 60.0) * theta.cos();
        assert!(
            (normal_total - expected).abs() < 1e-8 * expected,
            "{label}: normal {normal_total} vs {expected}"
        );
    }
}

#[test]
fn incline_with_mu_tenth_slides_downhill() {
    let mu = 0.1;
    let theta = INCLINE_DEG.to_radians();
    let h = 1.0 / 60.0;
    let expected_speed = h * G * (theta.sin() - mu * theta.cos());
    for facets in [4, 8] {
        let friction = FrictionModel::Pyramid { facets };
        let (s, downhill) = incline(mu, friction);
        let (lambda, _) = solve_with(&mut LemkeSolver::default(), &s.problem);
        let r = residuals_of(&s.problem, &lambda);
        assert!(r.exact() < 1e-8, "lemke, {facets} facets: {r:?}");
        let u = &s.problem.jacobian * post_velocity(&s.problem, &s.v_free, &lambda);
        for (c, block) in s.contacts.iter().zip(&s.problem.contacts) {
            let (n, t1, t2) = block.rows();
            let (e1, e2) = gelenk::collision::tangents(&c.normal);
            let slip = e1 * u[t1] + e2 * u[t2];
            let cos = slip.dot(&downhill) / slip.norm();
            assert!(cos > 1.0 - 1e-9, "lemke, {facets} facets: slip {slip:?} is not downhill {downhill:?}");
            // The pyramid has a vertex along the downhill direction: exact Coulomb sliding.
            assert!(
                (slip.norm() - expected_speed).abs() < 1e-9 * expected_speed,
                "lemke, {facets} facets: slip speed {} vs h g (sin θ − μ cos θ) = {expected_speed}",
                slip.norm()
            );
            assert!(u[n].abs() < 1e-9, "lemke: no normal velocity, got {}", u[n]);
        }
    }
}

#[test]
fn incline_with_mu_tenth_clarabel_cone_hovers_at_mu_times_slip() {
    // The convex (Anitescu) relaxation replaces `w_n ⟂ λ_n` by `w_n − μ‖w_t‖ ⟂ λ_n`: a sliding
    // contact separates at the normal speed μ‖u_t‖ instead of staying on the surface. This is the
    // documented price of the relaxation (src/solvers/conic.rs), pinned here.
    let mu = 0.1;
    let (s, downhill) = incline(mu, FrictionModel::Cone);
    let (lambda, _) = solve_with(&mut ClarabelSolver::default(), &s.problem);
    let r = residuals_of(&s.problem, &lambda);
    assert!(r.convex() < 1e-8, "clarabel: {r:?}");
    let w = row_velocities(&s.problem, &lambda);
    let mut worst: f64 = 0.0;
    for (c, block) in s.contacts.iter().zip(&s.problem.contacts) {
        let (n, t1, t2) = block.rows();
        assert!(lambda[n] > 0.0, "every corner carries load");
        let slip = w[t1].hypot(w[t2]);
        let (e1, e2) = gelenk::collision::tangents(&c.normal);
        let direction = (e1 * w[t1] + e2 * w[t2]) / slip;
        assert!(direction.dot(&downhill) > 1.0 - 1e-6, "clarabel slides downhill");
        assert!(w[n] > 1e-4, "hovering: normal velocity {} should be > 0", w[n]);
        assert!((w[n] - mu * slip).abs() < 1e-6, "hover {} vs μ‖u_t‖ = {}", w[n], mu * slip);
        worst = worst.max((w[n] - mu * slip).abs());
    }
    eprintln!(
        "clarabel cone hover: w_n ≈ {:.4e}, |w_n − μ‖u_t‖| ≤ {worst:.2e}",
        w[s.problem.contacts[0].normal]
    );
}

// ---------------------------------------------------------------------------------------------
// 4. PGS approaches clarabel
// ---------------------------------------------------------------------------------------------

fn pgs_errors(problem: &ConstraintProblem, sweeps: &[usize]) -> Vec<f64> {
    let (l_ref, _) = solve_with(&mut ClarabelSolver::default(), problem);
    let w_ref = row_velocities(problem, &l_ref);
    sweeps
        .iter()
        .map(|&k| {
            let mut pgs = PgsSolver {
                iterations: k,
                tolerance: 0.0,
                omega: 1.0,
                warm_start: false,
                ..Default::default()
            };
            let (l, info) = solve_with(&mut pgs, problem);
            // With tolerance 0, PGS stops early only at an exact fixed point (no impulse changed).
            assert!(info.iterations <= k);
            max_diff(&row_velocities(problem, &l), &w_ref)
        })
        .collect()
}

#[test]
fn pgs_converges_to_clarabel_on_a_two_box_stack() {
    let (model, q, _) = box_stack(2);
    let v = DVector::zeros(model.nv());
    let s = assemble_contacts(&model, &q, &v, 1.0 / 60.0, Vec3::z(), frictionless(), FrictionModel::Cone);
    let sweeps = [5, 20, 100, 500];
    let errors = pgs_errors(&s.problem, &sweeps);
    eprintln!("PGS vs clarabel, 2-box stack, |Δw|∞ at {sweeps:?} sweeps: {}", sci(&errors));
    // Decreasing until it reaches clarabel's own accuracy (~5e-12 here; its tolerance is 1e-10).
    for k in 1..errors.len() {
        assert!(errors[k] < errors[k - 1] || errors[k] < 1e-10, "error does not decrease: {errors:?}");
    }
    assert!(errors[3] < 1e-6, "{errors:?}");
}

#[test]
fn pgs_error_decreases_on_a_ten_box_stack() {
    let (model, q, _) = box_stack(10);
    let v = DVector::zeros(model.nv());
    let s = assemble_contacts(&model, &q, &v, 1.0 / 60.0, Vec3::z(), frictionless(), FrictionModel::Cone);
    assert_eq!(s.contacts.len(), 40);
    let sweeps = [5, 20, 100, 500, 2000];
    let errors = pgs_errors(&s.problem, &sweeps);
    eprintln!("PGS vs clarabel, 10-box stack, |Δw|∞ at {sweeps:?} sweeps: {}", sci(&errors));
    for k in 1..errors.len() {
        assert!(errors[k] < errors[k - 1] || errors[k] < 1e-10, "error does not decrease: {errors:?}");
    }
    // Slow on a tall stack (measured 3.9e-5 at 500 sweeps), converged at 2000.
    assert!(errors[4] < 1e-8, "{errors:?}");
}

// ---------------------------------------------------------------------------------------------
// 5. Redundant loop-closure rows
// ---------------------------------------------------------------------------------------------

#[test]
fn four_bar_with_redundant_closure_rows() {
    // Planar four-bar in the x-z plane, all hinges about y: O → A → B → P, P on the ground.
    let (o, a, b, p) =
        (Vec3::zeros(), Vec3::new(0.1, 0.0, 0.4), Vec3::new(0.9, 0.0, 0.5), Vec3::new(1.0, 0.0, 0.0));
    let link = |name: &str, parent: &str, at: Vec3, to: Vec3| {
        let inertia = RigidInertia::new(1.0, to / 2.0, Mat3::from_diagonal(&Vec3::new(0.02, 0.02, 0.005)));
        BodySpec::new(
            name,
            parent,
            Joint::Hinge { axis: Vec3::y() },
            Transform::from_translation(at),
            inertia,
        )
    };
    let mut mb = ModelBuilder::new();
    mb.add_body(link("l1", "universe", o, a - o)).add_body(link("l2", "l1", a - o, b - a)).add_body(link(
        "l3",
        "l2",
        b - a,
        p - b,
    ));
    let model = mb.build().unwrap();
    let l3 = model.body_id("l3").unwrap();
    let closure = |kind| LoopClosure {
        body_a: l3,
        frame_a: Transform::from_translation(p - b),
        body_b: 0,
        frame_b: Transform::from_translation(p),
        kind,
        erp: 0.2,
    };
    let closures = [closure(LoopKind::Hinge { axis: Vec3::y() }), closure(LoopKind::Ball)];
    let q = model.neutral_configuration();
    let v = DVector::from_vec(vec![0.7, -1.3, 0.4]);
    let h = 1e-3;
    let mut data = Data::new(&model);
    let tau = DVector::zeros(3);
    let v_free = &v + aba(&model, &mut data, &q, &v, &tau).unwrap() * h;
    compute_joint_jacobians(&model, &mut data, &q).unwrap();
    crba(&model, &mut data, &q).unwrap();
    factor_mass_matrix(&model, &mut data).unwrap();
    let mut rows = ProblemBuilder::new(model.nv(), FrictionModel::Cone);
    for (i, c) in closures.iter().enumerate() {
        let (dp, dr) = loop_error(&data, c);
        assert!(dp.norm() < 1e-12 && dr.norm() < 1e-12, "closed at q = 0");
        add_loop_closure_rows(&mut rows, &model, &data, 0, c, i, h);
    }
    let mut problem = ConstraintProblem::default();
    assemble_single(&rows, &model, &data, &v_free, &mut problem);
    assert_eq!(problem.rows(), 8, "5 hinge rows + 3 ball rows");
    let rank = problem.jacobian.clone().svd(false, false).rank(1e-10);
    assert_eq!(rank, 2, "a planar closure removes 2 dofs; 6 of the 8 rows are redundant");

    let mut answers = Vec::new();
    for mut solver in
        [Box::new(LemkeSolver::default()) as Box<dyn ConstraintSolver>, Box::new(ClarabelSolver::default())]
    {
        let (lambda, info) = solve_with(solver.as_mut(), &problem);
        let v_plus = post_velocity(&problem, &v_free, &lambda);
        let jv = (&problem.jacobian * &v_plus).amax();
        let r = residuals_of(&problem, &lambda);
        eprintln!(
            "four-bar, {}: |J v⁺| {jv:.2e}, bilateral {:.2e}, iterations {}",
            solver.name(),
            r.bilateral,
            info.iterations
        );
        assert!(jv < 1e-8, "{}: J v⁺ = {jv:.3e}", solver.name());
        assert!(r.bilateral < 1e-8, "{}: {r:?}", solver.name());
        answers.push(v_plus);
    }
    assert!(max_diff(&answers[0], &answers[1]) < 1e-8, "lemke and clarabel give the same v⁺");
    let (lambda, _) =
        solve_with(&mut PgsSolver { iterations: 5000, tolerance: 1e-14, ..Default::default() }, &problem);
    let v_pgs = post_velocity(&problem, &v_free, &lambda);
    let d = max_diff(&v_pgs, &answers[0]);
    eprintln!("four-bar, pgs: |v⁺ − v⁺_lemke| {d:.2e}");
    assert!(d < 1e-6, "pgs v⁺ {v_pgs} vs {}", answers[0]);
}

// ---------------------------------------------------------------------------------------------
// 6. Joint limits and motors
// ---------------------------------------------------------------------------------------------

fn pendulum() -> Model {
    let inertia =
        RigidInertia::new(1.0, Vec3::new(0.0, 0.0, -0.5), Mat3::from_diagonal(&Vec3::new(0.01, 0.01, 0.002)));
    let limits = JointLimits { lower: vec![-0.5], upper: vec![0.5], ..Default::default() };
    let arm =
        BodySpec::new("arm", "universe", Joint::Hinge { axis: Vec3::y() }, Transform::identity(), inertia)
            .with_limits(limits);
    ModelBuilder::new().add_body(arm).build().unwrap()
}

/// Builds a one-dof pendulum problem with `rows` filled by `add`; returns it with v_free.
fn pendulum_problem(
    model: &Model,
    q: f64,
    v: f64,
    h: f64,
    add: impl FnOnce(&mut ProblemBuilder, &DVector<f64>, &DVector<f64>),
) -> (ConstraintProblem, DVector<f64>) {
    let (q, v) = (DVector::from_element(1, q), DVector::from_element(1, v));
    let mut data = Data::new(model);
    let v_free = &v + aba(model, &mut data, &q, &v, &DVector::zeros(1)).unwrap() * h;
    compute_joint_jacobians(model, &mut data, &q).unwrap();
    crba(model, &mut data, &q).unwrap();
    factor_mass_matrix(model, &mut data).unwrap();
    let mut rows = ProblemBuilder::new(1, FrictionModel::Cone);
    add(&mut rows, &q, &v);
    let mut problem = ConstraintProblem::default();
    assemble_single(&rows, model, &data, &v_free, &mut problem);
    (problem, v_free)
}

fn all_solvers() -> Vec<Box<dyn ConstraintSolver>> {
    vec![
        Box::new(LemkeSolver::default()),
        Box::new(ClarabelSolver::default()),
        Box::new(PgsSolver { iterations: 100, tolerance: 0.0, ..Default::default() }),
    ]
}

#[test]
fn joint_limit_stops_and_bounces() {
    let model = pendulum();
    let h = 1e-3;
    let lower = -0.5;
    // (q, v, restitution, expected v⁺): at the stop, no bounce → 0; bounce 0.5 from −2 → +1 (also
    // from 1 mm above the stop: the gap closes within the step); a slow approach (below
    // bounce_velocity) does not bounce; 5 mm above the stop at −10 rad/s, the speculative target
    // −distance/h lets the joint reach the stop exactly at the end of the step.
    let cases = [
        (lower, -2.0, 0.0, Some(0.0)),
        (lower, -2.0, 0.5, Some(1.0)),
        (lower + 0.001, -2.0, 0.5, Some(1.0)),
        (lower, -0.05, 0.5, Some(0.0)),
        (lower + 0.005, -10.0, 0.0, Some(-5.0)),
        // 5 mm above the stop at −2 rad/s: within the margin, but it does not reach the stop.
        (lower + 0.005, -2.0, 0.0, None),
    ];
    for (q, v, restitution, expected) in cases {
        let p = JointLimitParameters { restitution, bounce_velocity: 0.1, ..Default::default() };
        let (problem, v_free) = pendulum_problem(&model, q, v, h, |rows, q, v| {
            add_joint_limit_rows(rows, &model, q, v, 0, h, &p);
        });
        assert_eq!(problem.rows(), 1, "the lower-limit row is active within the margin");
        for mut solver in all_solvers() {
            let (lambda, _) = solve_with(solver.as_mut(), &problem);
            let v_plus = post_velocity(&problem, &v_free, &lambda)[0];
            let label = format!("{} at q = {q}, v = {v}, ε = {restitution}", solver.name());
            let r = residuals_of(&problem, &lambda);
            // clarabel is an interior-point method: 1.9e-9 rad/s off the stop was measured at its
            // default tolerance; the exact methods hit the target to rounding.
            let tolerance = if solver.name() == "clarabel" { 1e-8 } else { 1e-9 };
            assert!(r.signorini < tolerance, "{label}: {r:?}");
            match expected {
                Some(e) => {
                    assert!((v_plus - e).abs() < tolerance, "{label}: v⁺ = {v_plus}, expected {e}");
                    assert!(q + h * v_plus >= lower - 1e-12, "{label}: passes the stop");
                }
                None => {
                    assert!(lambda[0].abs() < 1e-3 * tolerance, "{label}: inactive row, λ = {}", lambda[0]);
                    assert!((v_plus - v_free[0]).abs() < tolerance);
                }
            }
        }
    }
}

#[test]
fn motor_reaches_its_target_or_saturates() {
    let model = pendulum();
    let h = 1e-3;
    let target = 1.5;
    // Inertia about the pivot: I_yy + m l² = 0.01 + 0.25.
    let inertia = 0.26;
    for mut solver in all_solvers() {
        let (problem, v_free) =
            pendulum_problem(&model, 0.0, 0.0, h, |rows, _, _| add_motor_row(rows, 0, 0, target, 1e4, h));
        let (lambda, _) = solve_with(solver.as_mut(), &problem);
        let v_plus = post_velocity(&problem, &v_free, &lambda)[0];
        assert!((v_plus - target).abs() < 1e-9, "{}: strong motor v⁺ = {v_plus}", solver.name());
        assert!((lambda[0] - inertia * target).abs() < 1e-9, "{}: λ = {}", solver.name(), lambda[0]);

        let max_force = 0.2;
        let (problem, v_free) = pendulum_problem(&model, 0.0, 0.0, h, |rows, _, _| {
            add_motor_row(rows, 0, 0, target, max_force, h)
        });
        let (lambda, _) = solve_with(solver.as_mut(), &problem);
        let v_plus = post_velocity(&problem, &v_free, &lambda)[0];
        // Exact methods land on the bound; clarabel's interior point stays inside it by ~1.4e-11 N·s
        // (7e-8 relative: 5e-11 rad/s, within its velocity tolerance).
        let tolerance = if solver.name() == "clarabel" { 1e-10 * inertia } else { 1e-15 };
        assert!(
            (lambda[0] - max_force * h).abs() < tolerance,
            "{}: saturated λ = {}",
            solver.name(),
            lambda[0]
        );
        assert!(
            (v_plus - max_force * h / inertia).abs() < tolerance / inertia + 1e-15,
            "{}: weak motor v⁺ = {v_plus}",
            solver.name()
        );
        assert!(v_plus < target);
        let r = residuals_of(&problem, &lambda);
        assert!(r.bounded < 1e-9, "{}: {r:?}", solver.name());
    }
}

// ---------------------------------------------------------------------------------------------
// 7. Solver chain
// ---------------------------------------------------------------------------------------------

fn stack_problem() -> ConstraintProblem {
    let (model, q, _) = box_stack(2);
    let v = DVector::zeros(model.nv());
    assemble_contacts(&model, &q, &v, 1.0 / 60.0, Vec3::z(), frictionless(), FrictionModel::Cone).problem
}

#[test]
fn chain_falls_back_from_pgs_to_lemke() {
    let problem = stack_problem();
    // One plain sweep falls short; a subspace step after it would solve this small problem.
    let pgs = PgsSolver { iterations: 1, tolerance: 1e-10, subspace: false, ..Default::default() };
    let mut chain = SolverChain::new(vec![Box::new(pgs), Box::new(LemkeSolver::default())], 1e-10);
    let mut lambda = DVector::zeros(problem.rows());
    let report = chain.solve(&problem, &mut lambda).unwrap();
    assert_eq!(report.solver, "lemke");
    assert_eq!(report.fallbacks.len(), 1, "{:?}", report.fallbacks);
    assert_eq!(report.fallbacks[0].solver, "pgs");
    assert!(report.fallbacks[0].reason.contains("above tolerance"), "{}", report.fallbacks[0].reason);
    assert!(report.residuals.exact() <= 1e-10);
    let (direct, _) = solve_with(&mut LemkeSolver::default(), &problem);
    assert_eq!(lambda, direct, "the chain returns Lemke's impulses");
    eprintln!("chain: {:?}", report.fallbacks);
}

#[test]
fn chain_reports_every_failure() {
    let problem = stack_problem();
    // One plain sweep falls short; a subspace step after it would solve this small problem.
    let pgs = PgsSolver { iterations: 1, tolerance: 1e-10, subspace: false, ..Default::default() };
    let lemke =
        LemkeSolver { options: LemkeOptions { max_pivots: 1, ..Default::default() }, ..Default::default() };
    let mut chain = SolverChain::new(vec![Box::new(pgs), Box::new(lemke)], 1e-10);
    let mut lambda = DVector::zeros(problem.rows());
    match chain.solve(&problem, &mut lambda) {
        Err(SolverError::AllFailed(msg)) => {
            assert!(msg.contains("pgs: residual"), "{msg}");
            assert!(msg.contains("lemke: Lemke: pivot limit 1"), "{msg}");
        }
        other => panic!("expected AllFailed, got {other:?}"),
    }

    // An LCP without solution: w = −λ − 1 ≥ 0 is impossible for λ ≥ 0.
    let infeasible = ConstraintProblem::from_parts(
        DMatrix::from_element(1, 1, -1.0),
        DVector::from_element(1, -1.0),
        vec![RowLaw::Unilateral],
        vec![],
        FrictionModel::Cone,
    );
    let mut chain = SolverChain::new(all_solvers(), 1e-8);
    let mut lambda = DVector::zeros(1);
    let result = catch_unwind(AssertUnwindSafe(|| chain.solve(&infeasible, &mut lambda)));
    match result {
        Ok(Err(SolverError::AllFailed(msg))) => {
            eprintln!("infeasible chain: {msg}");
            for name in ["lemke: ", "clarabel: ", "pgs: "] {
                assert!(msg.contains(name), "{name} missing in {msg}");
            }
            assert!(msg.contains("ray termination"), "{msg}");
        }
        Ok(other) => panic!("expected AllFailed, got {other:?}"),
        Err(_) => panic!("the chain panicked on an infeasible LCP"),
    }
}

// ---------------------------------------------------------------------------------------------
// 8. Bad input
// ---------------------------------------------------------------------------------------------

fn one_contact(delassus: DMatrix<f64>, mu: f64, friction: FrictionModel) -> ConstraintProblem {
    ConstraintProblem::from_parts(
        delassus,
        DVector::from_vec(vec![-1.0, 0.2, -0.1]),
        vec![RowLaw::Unilateral, RowLaw::Friction { contact: 0 }, RowLaw::Friction { contact: 0 }],
        vec![ContactBlock { normal: 0, mu, mu2: mu }],
        friction,
    )
}

fn spd3() -> DMatrix<f64> {
    DMatrix::from_row_slice(3, 3, &[2.0, 0.3, -0.2, 0.3, 1.5, 0.1, -0.2, 0.1, 1.0])
}

/// Runs every solver on `problem` and asserts an InvalidProblem error and no panic (all solvers
/// are tried before failing, so that the message lists every offender).
fn assert_invalid(label: &str, problem: &ConstraintProblem) {
    let mut failures = Vec::new();
    for mut solver in all_solvers() {
        let name = solver.name().to_string();
        let mut lambda = DVector::zeros(problem.rows());
        let result = catch_unwind(AssertUnwindSafe(|| solver.solve(problem, &mut lambda)));
        match result {
            Ok(Err(SolverError::InvalidProblem(msg))) => eprintln!("{label}, {name}: invalid problem: {msg}"),
            Ok(other) => {
                failures.push(format!("{name}: expected InvalidProblem, got {other:?} (λ = {lambda:?})"))
            }
            Err(_) => failures.push(format!("{name}: panicked")),
        }
    }
    assert!(failures.is_empty(), "{label}:\n  {}", failures.join("\n  "));
}

#[test]
fn bad_input_is_an_invalid_problem() {
    let mut nan = spd3();
    nan[(1, 2)] = f64::NAN;
    assert_invalid("NaN in A", &one_contact(nan, 0.5, FrictionModel::Cone));
    let mut bias_inf = one_contact(spd3(), 0.5, FrictionModel::Cone);
    bias_inf.bias[0] = f64::INFINITY;
    assert_invalid("∞ in b", &bias_inf);
    let mismatched = ConstraintProblem::from_parts(
        DMatrix::identity(2, 2),
        DVector::from_element(3, -1.0),
        vec![RowLaw::Unilateral; 3],
        vec![],
        FrictionModel::Cone,
    );
    assert_invalid("2×2 A with 3 rows", &mismatched);
    assert_invalid("negative μ", &one_contact(spd3(), -0.1, FrictionModel::Cone));
    assert_invalid("NaN μ", &one_contact(spd3(), f64::NAN, FrictionModel::Cone));
    assert_invalid("2-facet pyramid", &one_contact(spd3(), 0.5, FrictionModel::Pyramid { facets: 2 }));
    // A contact block whose rows run past the end of the problem.
    let mut past = one_contact(spd3(), 0.5, FrictionModel::Cone);
    past.contacts[0].normal = 1;
    assert_invalid("contact block past the last row", &past);

    // Lemke's function itself.
    let r = lemke(&DMatrix::identity(2, 2), &DVector::from_element(3, -1.0), &LemkeOptions::default());
    assert!(matches!(r, Err(SolverError::InvalidProblem(_))), "{r:?}");
}

#[test]
fn lcp_without_solution_is_a_lemke_ray() {
    let (m, q) = (DMatrix::from_element(1, 1, -1.0), DVector::from_element(1, -1.0));
    let r = lemke(&m, &q, &LemkeOptions::default());
    assert!(matches!(r, Err(SolverError::LemkeRay { .. })), "{r:?}");
    let problem = ConstraintProblem::from_parts(
        m,
        q,
        vec![RowLaw::Unilateral],
        vec![],
        FrictionModel::Pyramid { facets: 4 },
    );
    let r = LemkeSolver::default().solve(&problem, &mut DVector::zeros(1));
    assert!(matches!(r, Err(SolverError::LemkeRay { .. })), "{r:?}");
    // A larger one: w₁ = z₁ − z₂ − 1, w₂ = −z₁ + z₂ − 1 cannot both be ≥ 0.
    let m = DMatrix::from_row_slice(2, 2, &[1.0, -1.0, -1.0, 1.0]);
    let r = lemke(&m, &DVector::from_element(2, -1.0), &LemkeOptions::default());
    assert!(matches!(r, Err(SolverError::LemkeRay { .. })), "{r:?}");
}

/// Inconsistent row laws and contact blocks (a friction row naming a contact that does not
/// exist; a contact whose normal row is not unilateral) must be rejected, not crash a solver.
#[test]
fn friction_rows_naming_a_missing_contact_are_rejected_without_panic() {
    let dangling = ConstraintProblem::from_parts(
        spd3(),
        DVector::from_vec(vec![-1.0, 0.2, -0.1]),
        vec![RowLaw::Unilateral, RowLaw::Friction { contact: 3 }, RowLaw::Friction { contact: 3 }],
        vec![],
        FrictionModel::Cone,
    );
    assert_invalid("friction rows naming a missing contact", &dangling);
}

/// See [`friction_rows_naming_a_missing_contact_are_rejected_without_panic`].
#[test]
fn contact_with_a_bilateral_normal_row_is_rejected_without_panic() {
    let bilateral_normal = ConstraintProblem::from_parts(
        spd3(),
        DVector::from_vec(vec![-1.0, 0.2, -0.1]),
        vec![RowLaw::Bilateral, RowLaw::Friction { contact: 0 }, RowLaw::Friction { contact: 0 }],
        vec![ContactBlock { normal: 0, mu: 0.5, mu2: 0.5 }],
        FrictionModel::Pyramid { facets: 4 },
    );
    assert_invalid("contact whose normal row is bilateral", &bilateral_normal);
}

/// A Lemke solver configured with fewer than 3 pyramid directions is the same degenerate
/// "pyramid" the problem check rejects; it must not silently drop friction.
#[test]
fn lemke_with_two_facets_on_a_cone_is_rejected() {
    let problem = one_contact(spd3(), 0.5, FrictionModel::Cone);
    let mut failures = Vec::new();
    for facets in [0, 1, 2] {
        let mut solver = LemkeSolver { facets, ..Default::default() };
        let mut lambda = DVector::zeros(3);
        let result = catch_unwind(AssertUnwindSafe(|| solver.solve(&problem, &mut lambda)));
        match result {
            Ok(Err(SolverError::InvalidProblem(_))) => {}
            Ok(other) => {
                failures.push(format!("{facets} facets: got {other:?}, λ = {:?}", lambda.as_slice()))
            }
            Err(_) => failures.push(format!("{facets} facets: panicked")),
        }
    }
    assert!(failures.is_empty(), "lemke with < 3 facets on a cone:\n  {}", failures.join("\n  "));
}

// ---------------------------------------------------------------------------------------------
// 9. Lemke approximates a cone by a pyramid and says so
// ---------------------------------------------------------------------------------------------

#[test]
fn lemke_on_a_cone_says_it_used_a_pyramid() {
    let (s, _) = incline(0.5, FrictionModel::Cone);
    for facets in [4, 8, 16] {
        let mut solver = LemkeSolver { facets, ..Default::default() };
        let (lambda, info) = solve_with(&mut solver, &s.problem);
        let note = info.note.unwrap_or_default();
        assert!(note.contains("pyramid") && note.contains(&format!("{facets}-facet")), "note: {note:?}");
        // The pyramid answer still sticks, and it lies inside the cone (inscribed pyramid).
        let v_plus = post_velocity(&s.problem, &s.v_free, &lambda);
        assert!(v_plus.amax() < 1e-9);
        let r = residuals_of(&s.problem, &lambda);
        assert!(r.friction_feasibility < 1e-12, "{r:?}");
    }
    let (s, _) = incline(0.5, FrictionModel::Pyramid { facets: 4 });
    let (_, info) = solve_with(&mut LemkeSolver::default(), &s.problem);
    assert_eq!(info.note, None, "no note when the problem states a pyramid");
}

/// The convex relaxation's certificate must still check the Signorini law of unilateral rows
/// that are not contact normals (joint limits): `conic_kkt` only covers contact blocks, and
/// `Residuals::convex` leaves out `signorini`, so a clarabel answer that violates a joint limit
/// would be certified as exact.
#[test]
fn convex_certificate_checks_joint_limit_rows() {
    let model = pendulum();
    let h = 1e-3;
    let p = JointLimitParameters::default();
    let (problem, _) = pendulum_problem(&model, -0.5, -2.0, h, |rows, q, v| {
        add_joint_limit_rows(rows, &model, q, v, 0, h, &p);
    });
    assert_eq!(problem.rows(), 1);
    // λ = 0 leaves the joint moving through its stop: w = b < 0.
    let lambda = DVector::zeros(1);
    let r = residuals_of(&problem, &lambda);
    let w = row_velocities(&problem, &lambda)[0];
    assert!(w < -1.0, "the stop is violated at {w} rad/s");
    assert!(r.exact() >= w.abs() * 0.999, "{r:?}");
    assert!(
        r.convex() >= w.abs() * 0.999,
        "convex() = {:.3e} certifies λ = 0 although the limit row is violated by {w:.3} rad/s ({r:?})",
        r.convex()
    );
    assert!(ClarabelSolver::default().certify(&r) > 1.0);
}
