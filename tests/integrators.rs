//! The integrators of `gelenk::integrators` converge at the order they name (error at dt, dt/2,
//! dt/4 against a Gragg–Bulirsch–Stoer reference on a 3-link pendulum with ball joints, so the
//! manifold matters), explicit Euler gains energy while semi-implicit Euler's stays bounded,
//! the implicit scheme is stable on a stiff suspension spring where the explicit ones blow up,
//! the adaptive scheme meets its tolerance and lands on the requested time, and bad input is a
//! typed error that leaves the state untouched.

use gelenk::integrators::{
    DormandPrince45, ExplicitEuler, GraggBulirschStoer, ImplicitEuler, Integrator, IntegratorError,
    IntegratorKind, Rk4, SemiImplicitEuler,
};
use gelenk::math::{Transform, Vec3};
use gelenk::model::{BodySpec, Joint, JointDynamics, ModelBuilder, RigidInertia, Suspension};
use gelenk::prelude::*;
use nalgebra::{DVector, Matrix3};

/// Three rods of 0.3 m hanging from the origin: ball, hinge (about y), ball. `damping` on the
/// hinge exercises the passive forces in every scheme.
fn ball_pendulum(damping: f64) -> Model {
    let rod = RigidInertia::new(
        1.0,
        Vec3::new(0.0, 0.0, -0.15),
        Matrix3::from_diagonal(&Vec3::new(0.01, 0.012, 0.002)),
    );
    let down = Transform::new(Matrix3::identity(), Vec3::new(0.0, 0.0, -0.3));
    let mut b = ModelBuilder::new();
    b.add_body(BodySpec::new("l1", "universe", Joint::Ball, Transform::identity(), rod));
    let mut l2 = BodySpec::new("l2", "l1", Joint::hinge(Vec3::y()), down, rod);
    l2.dynamics = JointDynamics { damping, friction: 0.0 };
    b.add_body(l2);
    b.add_body(BodySpec::new("l3", "l2", Joint::Ball, down, rod));
    b.build().unwrap()
}

/// A state with every joint moving and the ball joints tilted.
fn initial_state(model: &Model) -> State {
    let mut s = State::new(model);
    let mut v = DVector::zeros(model.nv());
    v.copy_from_slice(&[0.8, -0.5, 1.5, 2.0, -1.0, 0.7, 3.0]);
    let q0 = s.q.clone();
    model.integrate(&q0, &v, 0.4, &mut s.q);
    s.v.copy_from(&v);
    s
}

/// Runs `integrator` to `t_end` in steps of `h`.
fn run(model: &Model, integrator: &mut dyn Integrator, h: f64, t_end: f64) -> State {
    let mut data = Data::new(model);
    let mut state = initial_state(model);
    let tau = DVector::zeros(model.nv());
    let steps = (t_end / h).round() as usize;
    for _ in 0..steps {
        integrator.step(model, &mut data, &mut state, &tau, h).unwrap();
    }
    state
}

/// Distance between two states: configuration difference on the manifold plus velocity.
fn distance(model: &Model, a: &State, b: &State) -> f64 {
    let mut dq = DVector::zeros(model.nv());
    model.difference(&a.q, &b.q, &mut dq);
    dq.norm() + (&a.v - &b.v).norm()
}

fn reference(model: &Model, t_end: f64) -> State {
    run(model, &mut GraggBulirschStoer::new(model, 8), 1e-3, t_end)
}

/// Measured orders log₂(e(h)/e(h/2)) and log₂(e(h/2)/e(h/4)).
fn measured_orders(
    model: &Model,
    kind: IntegratorKind,
    h: f64,
    t_end: f64,
    reference: &State,
) -> (f64, f64, [f64; 3]) {
    let errors = [h, h / 2.0, h / 4.0]
        .map(|dt| distance(model, &run(model, kind.build(model).as_mut(), dt, t_end), reference));
    ((errors[0] / errors[1]).log2(), (errors[1] / errors[2]).log2(), errors)
}

#[test]
fn reference_is_converged() {
    // GBS (8 columns, order 16) at 1 ms against RK4 at 0.1 ms (error ~ (1e-4)⁴·C ≈ 1e-12).
    let model = ball_pendulum(0.05);
    let t_end = 0.5;
    let gbs = reference(&model, t_end);
    let rk4 = run(&model, &mut Rk4::new(&model), 1e-4, t_end);
    let d = distance(&model, &gbs, &rk4);
    assert!(d < 1e-10, "GBS and fine RK4 differ by {d}");
}

#[test]
fn every_integrator_converges_at_its_order() {
    let model = ball_pendulum(0.05);
    let t_end = 0.5;
    let reference = reference(&model, t_end);
    // Step sizes in each scheme's asymptotic range, with errors far above the reference's
    // (~1e-12) and rounding. The adaptive scheme with infinite tolerances takes exactly one
    // Dormand–Prince step per call, so its fixed-step order shows.
    let cases: [(IntegratorKind, f64); 9] = [
        (IntegratorKind::ExplicitEuler, 2e-3),
        (IntegratorKind::SemiImplicitEuler, 2e-3),
        (IntegratorKind::ImplicitEuler, 2e-3),
        (IntegratorKind::VelocityVerlet, 1e-2),
        (IntegratorKind::Rk4, 2e-2),
        (IntegratorKind::Rk6, 2.5e-2),
        (IntegratorKind::DormandPrince45 { rtol: f64::INFINITY, atol: f64::INFINITY }, 1.25e-2),
        (IntegratorKind::GraggBulirschStoer { columns: 2 }, 5e-2),
        (IntegratorKind::GraggBulirschStoer { columns: 3 }, 2.5e-2),
    ];
    for (kind, h) in cases {
        let order = kind.build(&model).order() as f64;
        let (p1, p2, errors) = measured_orders(&model, kind, h, t_end, &reference);
        println!("{:<22} order {order}: measured {p1:.3}, {p2:.3}; errors {errors:?}", kind.label());
        // Within 0.3 of the nominal order: the leading error term dominates at these steps,
        // the next term shifts the ratio by O(h) (the first pair is the coarser one).
        assert!(
            (p2 - order).abs() < 0.3,
            "{}: order {order}, measured {p1:.3} then {p2:.3} ({errors:?})",
            kind.label()
        );
        assert!(
            (p1 - order).abs() < 0.5,
            "{}: order {order}, measured {p1:.3} then {p2:.3} ({errors:?})",
            kind.label()
        );
    }
}

#[test]
fn rk8_converges_at_order_8() {
    // Eighth order leaves the pre-asymptotic range only where its error nears the reference's
    // (~1e-12 at 0.5 s); over 2 s the errors at 50, 25 and 12.5 ms (9e-4, 4e-7, 1e-9) stay
    // far above it.
    let model = ball_pendulum(0.05);
    let t_end = 2.0;
    let reference = reference(&model, t_end);
    let (p1, p2, errors) = measured_orders(&model, IntegratorKind::Rk8, 5e-2, t_end, &reference);
    println!("RK8 order 8: measured {p1:.3}, {p2:.3}; errors {errors:?}");
    assert!(errors[2] > 1e-3 * errors[1] && errors[2] > 1e-10, "errors {errors:?} near the reference's");
    // The finer pair within 0.3 of 8, as for the other schemes; the coarser pair (50 → 25 ms)
    // is still pre-asymptotic, where the error falls faster than h⁸: at least 8 − 0.5.
    assert!((p2 - 8.0).abs() < 0.3, "RK8: measured {p1:.3} then {p2:.3} ({errors:?})");
    assert!(p1 > 7.5, "RK8: measured {p1:.3} then {p2:.3} ({errors:?})");
}

#[test]
fn quaternions_stay_unit() {
    let model = ball_pendulum(0.0);
    for kind in [
        IntegratorKind::ExplicitEuler,
        IntegratorKind::Rk4,
        IntegratorKind::Rk8,
        IntegratorKind::DormandPrince45 { rtol: 1e-6, atol: 1e-9 },
        IntegratorKind::GraggBulirschStoer { columns: 4 },
    ] {
        let s = run(&model, kind.build(&model).as_mut(), 1e-2, 2.0);
        for range in [0..4, 5..9] {
            let norm = s.q.rows(range.start, 4).norm();
            assert!((norm - 1.0).abs() < 1e-14, "{}: |quaternion| = {norm}", kind.label());
        }
    }
}

#[test]
fn explicit_euler_gains_energy_on_a_pendulum_chain() {
    let model = ball_pendulum(0.0);
    let mut data = Data::new(&model);
    let energy = |data: &mut Data, s: &State| {
        kinetic_energy(&model, data, &s.q, &s.v).unwrap() + potential_energy(&model, data, &s.q).unwrap()
    };
    let s0 = initial_state(&model);
    let e0 = energy(&mut data, &s0);
    let tau = DVector::zeros(model.nv());
    let mut gains = Vec::new();
    for h in [1e-3, 5e-4] {
        let mut explicit = ExplicitEuler::new(&model);
        let mut rk4 = Rk4::new(&model);
        let (mut a, mut b) = (s0.clone(), s0.clone());
        let mut drift = Vec::new();
        for _second in 0..4 {
            for _ in 0..(1.0 / h) as usize {
                explicit.step(&model, &mut data, &mut a, &tau, h).unwrap();
                rk4.step(&model, &mut data, &mut b, &tau, h).unwrap();
            }
            drift.push(energy(&mut data, &a) - e0);
        }
        let rk4_drift = energy(&mut data, &b) - e0;
        println!("h = {h}: explicit Euler ΔE per second {drift:.4?} J, RK4 ΔE after 4 s {rk4_drift:.2e} J");
        // Explicit Euler pumps energy in every second, while RK4 at the same step keeps it
        // below 1e-8 J (order h⁴).
        assert!(drift[0] > 0.0);
        for w in drift.windows(2) {
            assert!(w[1] > w[0] + 0.2 * drift[0], "explicit Euler's energy gain stalls: {drift:?}");
        }
        assert!(rk4_drift.abs() < 1e-8);
        gains.push(drift[3]);
    }
    // A larger step gains more: at least 1.5× for twice the step (the motion is chaotic, so the
    // first-order factor 2 shows only roughly).
    assert!(gains[0] > 1.5 * gains[1], "gains {gains:?}");
}

#[test]
fn explicit_euler_spirals_out_where_semi_implicit_euler_stays_bounded() {
    // A 1 kg mass on a 100 N/m spring (ω = 10 rad/s), h = 10 ms: explicit Euler multiplies the
    // energy by 1 + (ωh)² = 1.01 every step; semi-implicit Euler is symplectic here (constant
    // mass matrix), its energy error stays within O(ωh) = 10 % of E₀ forever.
    let model = suspension(100.0, 0.0);
    let tau = DVector::zeros(model.nv());
    let mut data = Data::new(&model);
    let energy = |s: &State| 0.5 * s.v[0] * s.v[0] + 0.5 * 100.0 * s.q[0] * s.q[0];
    let mut s0 = State::new(&model);
    s0.q[0] = 0.01;
    let e0 = energy(&s0);
    let h = 1e-2;
    let (mut a, mut b) = (s0.clone(), s0.clone());
    let (mut explicit, mut semi) = (ExplicitEuler::new(&model), SemiImplicitEuler::new(&model));
    let mut semi_worst: f64 = 0.0;
    for _ in 0..1000 {
        explicit.step(&model, &mut data, &mut a, &tau, h).unwrap();
        semi.step(&model, &mut data, &mut b, &tau, h).unwrap();
        semi_worst = semi_worst.max((energy(&b) / e0 - 1.0).abs());
    }
    let growth = energy(&a) / e0;
    let expected = 1.01f64.powi(1000);
    assert!(
        (growth / expected - 1.0).abs() < 1e-6,
        "explicit Euler's energy grew {growth}×, expected {expected}×"
    );
    assert!(semi_worst < 0.1, "semi-implicit Euler's energy error reached {semi_worst} of E₀");
}

/// A 1 kg body on a hinge2 suspension of stiffness k and damping c, no gravity, displaced 1 cm.
fn suspension(k: f64, c: f64) -> Model {
    let mut b = ModelBuilder::new();
    b.gravity(Vec3::zeros());
    let joint = Joint::Hinge2 {
        axis1: Vec3::z(),
        axis2: Vec3::y(),
        suspension: Some(Suspension { stiffness: k, damping: c }),
    };
    b.add_body(BodySpec::new(
        "wheel",
        "universe",
        joint,
        Transform::identity(),
        RigidInertia::solid_sphere(1.0, 0.1),
    ));
    b.build().unwrap()
}

#[test]
fn implicit_euler_is_stable_on_a_stiff_spring() {
    // k = 1e6 N/m on 1 kg: ω = 1000 rad/s; h = 10 ms gives ωh = 10, far beyond the explicit
    // schemes' stability limits (ωh < 2 for semi-implicit Euler, 2.8 for RK4).
    let model = suspension(1e6, 10.0);
    let tau = DVector::zeros(model.nv());
    let h = 1e-2;
    let s0 = {
        let mut s = State::new(&model);
        s.q[0] = 0.01;
        s
    };
    let mut data = Data::new(&model);
    let mut implicit = ImplicitEuler::new(&model);
    let mut s = s0.clone();
    for _ in 0..100 {
        implicit.step(&model, &mut data, &mut s, &tau, h).unwrap();
        assert!(s.q[0].abs() <= 0.01, "implicit Euler grew the travel to {}", s.q[0]);
    }
    // Implicit Euler damps the spring numerically: after 1 s the travel is gone.
    assert!(s.q[0].abs() < 1e-6, "travel {}", s.q[0]);
    for mut explicit in
        [Box::new(SemiImplicitEuler::new(&model)) as Box<dyn Integrator>, Box::new(Rk4::new(&model))]
    {
        let mut s = s0.clone();
        for _ in 0..20 {
            if explicit.step(&model, &mut data, &mut s, &tau, h).is_err() {
                break;
            }
        }
        assert!(
            s.q[0].is_nan() || s.q[0].abs() >= 1.0,
            "{} stayed bounded at ωh = 10: {}",
            explicit.name(),
            s.q[0]
        );
    }
}

#[test]
fn implicit_euler_matches_the_spring_at_small_steps() {
    // Damped oscillator s̈ = −k s − c ṡ (m = 1 kg): closed form at t = 0.2 s; error O(h).
    let (k, c) = (400.0, 4.0);
    let model = suspension(k, c);
    let tau = DVector::zeros(model.nv());
    let mut data = Data::new(&model);
    let (wd, zeta_w) = ((k - c * c / 4.0).sqrt(), c / 2.0);
    let exact = |t: f64| 0.01 * (-zeta_w * t).exp() * ((wd * t).cos() + zeta_w / wd * (wd * t).sin());
    let mut errors = Vec::new();
    for h in [1e-3f64, 5e-4] {
        let mut s = State::new(&model);
        s.q[0] = 0.01;
        let mut implicit = ImplicitEuler::new(&model);
        for _ in 0..(0.2 / h).round() as usize {
            implicit.step(&model, &mut data, &mut s, &tau, h).unwrap();
        }
        errors.push((s.q[0] - exact(0.2)).abs());
    }
    let order = (errors[0] / errors[1]).log2();
    assert!((order - 1.0).abs() < 0.1, "order {order}, errors {errors:?}");
    assert!(errors[0] < 2e-4, "error {errors:?} (travel 1e-2 m)");
}

#[test]
fn dormand_prince_meets_its_tolerance_and_lands_on_time() {
    let model = ball_pendulum(0.05);
    let t_end = 0.5;
    let reference = reference(&model, t_end);
    let mut last_error = f64::INFINITY;
    for rtol in [1e-4, 1e-7, 1e-10] {
        let mut dopri = DormandPrince45::new(&model, rtol, rtol);
        dopri.h = 1.0; // far too large: the first attempts must be rejected
        let mut data = Data::new(&model);
        let mut state = initial_state(&model);
        let tau = DVector::zeros(model.nv());
        dopri.advance_to(&model, &mut data, &mut state, &tau, t_end).unwrap();
        assert_eq!(state.t, t_end);
        let error = distance(&model, &state, &reference);
        let stats = dopri.stats();
        println!("rtol {rtol:e}: error {error:.3e}, {stats:?}");
        assert!(stats.rejected >= 1);
        // The global error is within two orders of the local tolerance for this short, smooth
        // run, and shrinks with it.
        assert!(error < 100.0 * rtol, "rtol {rtol}: error {error}");
        assert!(error < last_error);
        last_error = error;
    }
}

#[test]
fn bad_input_is_a_typed_error_and_leaves_the_state() {
    let model = ball_pendulum(0.0);
    let other = suspension(1.0, 0.0);
    let mut data = Data::new(&model);
    let tau = DVector::zeros(model.nv());
    let kinds = [
        IntegratorKind::ExplicitEuler,
        IntegratorKind::SemiImplicitEuler,
        IntegratorKind::VelocityVerlet,
        IntegratorKind::Rk4,
        IntegratorKind::DormandPrince45 { rtol: 1e-6, atol: 1e-6 },
        IntegratorKind::GraggBulirschStoer { columns: 3 },
        IntegratorKind::ImplicitEuler,
    ];
    for kind in kinds {
        let mut integrator = kind.build(&model);
        let mut s = initial_state(&model);
        let before = s.clone();
        assert!(matches!(
            integrator.step(&model, &mut data, &mut s, &tau, 0.0),
            Err(IntegratorError::BadStep(_))
        ));
        assert!(matches!(
            integrator.step(&model, &mut data, &mut s, &tau, f64::NAN),
            Err(IntegratorError::BadStep(_))
        ));
        let mut other_data = Data::new(&other);
        let mut other_state = State::new(&other);
        let other_tau = DVector::zeros(other.nv());
        assert!(matches!(
            integrator.step(&other, &mut other_data, &mut other_state, &other_tau, 1e-3),
            Err(IntegratorError::ModelMismatch { .. })
        ));
        s.v[4] = f64::NAN;
        let nan_state = s.clone();
        assert!(
            matches!(
                integrator.step(&model, &mut data, &mut s, &tau, 1e-3),
                Err(IntegratorError::Dynamics(DynamicsError::NonFinite { .. }))
            ),
            "{}",
            kind.label()
        );
        assert_eq!(s.q, nan_state.q);
        assert_eq!(s.t, nan_state.t);
        let mut short = before.clone();
        short.q = DVector::zeros(3);
        assert!(matches!(
            integrator.step(&model, &mut data, &mut short, &tau, 1e-3),
            Err(IntegratorError::Dynamics(DynamicsError::DimensionMismatch { .. }))
        ));
        let short_tau = DVector::zeros(2);
        let mut s = before.clone();
        assert!(integrator.step(&model, &mut data, &mut s, &short_tau, 1e-3).is_err(), "{}", kind.label());
        assert_eq!(s, before);
    }
}

#[test]
fn chart_rate_is_the_derivative_of_the_chart() {
    // Θ̇ = dexp⁻¹₋Θ(v): moving along q(t) = (q₀ ⊕ Θ) ⊕ t v, the chart coordinate
    // Θ(t) = q(t) ⊖ q₀ changes at that rate (central difference, error ~ε² ≈ 1e-10).
    let mut b = ModelBuilder::new();
    let body = RigidInertia::solid_box(1.0, Vec3::new(0.1, 0.2, 0.3));
    b.add_body(BodySpec::new("free", "universe", Joint::Free, Transform::identity(), body));
    b.add_body(BodySpec::new("ball", "free", Joint::Ball, Transform::identity(), body));
    b.add_body(BodySpec::new("planar", "ball", Joint::Planar, Transform::identity(), body));
    let model = b.build().unwrap();
    let nv = model.nv();
    let q0 = model.random_configuration(&mut <rand::rngs::StdRng as rand::SeedableRng>::seed_from_u64(3));
    let theta = DVector::from_fn(nv, |i, _| 0.9 * ((i as f64) * 1.3).sin());
    let v = DVector::from_fn(nv, |i, _| ((i as f64) * 0.7 + 0.2).cos());
    let mut q = q0.clone();
    model.integrate(&q0, &theta, 1.0, &mut q);
    let eps = 1e-5;
    let (mut qp, mut qm) = (q.clone(), q.clone());
    model.integrate(&q, &v, eps, &mut qp);
    model.integrate(&q, &v, -eps, &mut qm);
    let (mut tp, mut tm) = (DVector::zeros(nv), DVector::zeros(nv));
    model.difference(&q0, &qp, &mut tp);
    model.difference(&q0, &qm, &mut tm);
    let numeric = (tp - tm) / (2.0 * eps);
    let mut analytic = DVector::zeros(nv);
    for i in 1..model.nbodies() {
        let j = model.joint(i);
        let r = model.idx_v(i)..model.idx_v(i) + j.nv();
        j.chart_rate(&theta.as_slice()[r.clone()], &v.as_slice()[r.clone()], &mut analytic.as_mut_slice()[r]);
    }
    let err = (&numeric - &analytic).norm();
    assert!(err < 1e-8, "chart rate off by {err}: numeric {numeric}, analytic {analytic}");
    // And it is not the identity (the correction matters at |Θ| ≈ 1).
    assert!((&analytic - &v).norm() > 0.1);
}
