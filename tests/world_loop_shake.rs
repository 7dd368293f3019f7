//! Loop closures within a multibody in the velocity-level step. A linkage of hinges and sliders
//! whose only rows are its own closures is stepped by RATTLE: it stays closed, reports the
//! velocity at the end of the step (on the closure's tangent space), and keeps its energy to
//! the second-order step's bounded error. Any other row (here a motor) gives the first-order
//! step, whose closure is held by SHAKE: the closure impulse is resized until the configuration
//! the step reaches is closed, so the configuration moves with exactly the velocity the step
//! reports (q₁ = q₀ + h v₁ on hinges).

use gelenk::scenes::FOUR_BAR_LENGTHS;
use gelenk::world::{Motor, WorldOptions};
use nalgebra::DVector;

fn options(dt: f64) -> WorldOptions {
    let mut o = WorldOptions { dt, ..Default::default() };
    o.sleep.enabled = false;
    o
}

/// The velocity of the rocker's tip (m/s) in the plane (x, −z), where a rod turned by φ about
/// y points along (cos φ, sin φ): J(q) v of the closure's two independent rows.
fn tip_velocity(q: &DVector<f64>, v: &DVector<f64>) -> [f64; 2] {
    let (a, b, c, _) = FOUR_BAR_LENGTHS;
    let (mut angle, mut rate, mut tip) = (0.0, 0.0, [0.0, 0.0]);
    for (k, length) in [a, b, c].into_iter().enumerate() {
        angle += q[k];
        rate += v[k];
        tip[0] -= length * angle.sin() * rate;
        tip[1] += length * angle.cos() * rate;
    }
    tip
}

#[test]
fn the_free_four_bar_is_stepped_by_rattle_and_reports_a_velocity_on_the_tangent_space() {
    // The first-order step's v₁ is the mean velocity over the step and leaves the tangent space
    // at q₁ by O(h‖v‖²/L) (up to 0.07 m/s of tip velocity here at 1/60 s).
    let h = 1.0 / 60.0;
    let (mut w, m) = gelenk::scenes::four_bar_world(options(h)).unwrap();
    let (mut worst_tip, mut worst_closure, mut largest_rate) = (0.0f64, 0.0f64, 0.0f64);
    for _ in 0..600 {
        w.step().unwrap();
        assert_eq!(w.stats().integrator, "rattle");
        let s = &w.multibody(m).state;
        let [x, z] = tip_velocity(&s.q, &s.v);
        worst_tip = worst_tip.max(x.abs()).max(z.abs());
        largest_rate = largest_rate.max(s.v.amax());
        worst_closure = worst_closure.max(w.constraint_violation());
    }
    println!(
        "four-bar at 1/60 s: tip velocity ≤ {worst_tip:e} m/s (joint rates up to {largest_rate:.2} rad/s), closure ≤ {worst_closure:e} m"
    );
    assert!(largest_rate > 1.0, "the linkage swings: {largest_rate} rad/s");
    assert!(worst_tip < 1e-10, "tip velocity {worst_tip:e} m/s");
    assert!(worst_closure < 1e-11, "closure error {worst_closure:e} m");
}

#[test]
fn a_driven_four_bar_takes_the_first_order_step_and_moves_with_the_velocity_it_reports() {
    // A motor on the crank gives the linkage a row of its own: the first-order step with SHAKE.
    // A projection of q alone after the step (then of v onto the tangent space) would move q by
    // O(h²‖v‖²/L) ≈ 1e-4 rad per step here that v does not show.
    let h = 1.0 / 60.0;
    let (mut w, m) = gelenk::scenes::four_bar_world(options(h)).unwrap();
    w.multibody_mut(m).set_motor(0, Some(Motor { target_velocity: 2.0, max_force: 5.0 }));
    let (mut worst_gap, mut worst_closure) = (0.0f64, 0.0f64);
    for _ in 0..600 {
        let q0 = w.multibody(m).state.q.clone();
        w.step().unwrap();
        assert_eq!(w.stats().integrator, "semi-implicit-euler");
        let s = &w.multibody(m).state;
        worst_gap = worst_gap.max((&s.q - &q0 - &s.v * h).amax());
        worst_closure = worst_closure.max(w.constraint_violation());
    }
    println!(
        "driven four-bar at 1/60 s: |q₁ − q₀ − h v₁| ≤ {worst_gap:e} rad, closure ≤ {worst_closure:e} m"
    );
    assert!(worst_gap < 1e-13, "q moved by {worst_gap:e} rad more than h v");
    assert!(worst_closure < 1e-11, "closure error {worst_closure:e} m");
}

/// max |E − E₀| over 10 s at step `h`, relative to the largest kinetic energy.
fn energy_error(h: f64) -> f64 {
    let (mut w, _) = gelenk::scenes::four_bar_world(options(h)).unwrap();
    let e0 = w.total_energy();
    let (mut de, mut kinetic) = (0.0f64, 0.0f64);
    for _ in 0..(10.0 / h).round() as usize {
        w.step().unwrap();
        de = de.max((w.total_energy() - e0).abs());
        kinetic = kinetic.max(w.kinetic_energy());
    }
    de / kinetic
}

#[test]
fn the_four_bar_keeps_its_energy_to_the_second_order_steps_error() {
    // RATTLE's energy error stays bounded and shrinks like h²: 0.7 % of the largest kinetic
    // energy over 10 s at 1/60 s, 0.04 % at 1/240 s. The first-order step lost 44 % and 15 %
    // (its centrifugal term explicit on an inertia that depends on q, its velocity the mean
    // over the step), with the closure held by SHAKE or by Baumgarte feedback alone.
    let (coarse, fine) = (energy_error(1.0 / 60.0), energy_error(1.0 / 240.0));
    println!("four-bar: |ΔE| / max kinetic energy {coarse:.3e} at 1/60 s, {fine:.3e} at 1/240 s");
    assert!(coarse < 0.02, "{coarse:e} of the largest kinetic energy at 1/60 s");
    let order = (coarse / fine).ln() / 4f64.ln();
    assert!(order > 1.7, "the error shrinks like h²: order {order:.2}");
}

#[test]
fn a_tumbling_floating_triangle_stays_closed() {
    // A free-floating base bar (0.4 m) and two hinged 0.3 m rods whose tip is tied back to the
    // base's origin by a ball closure, spinning without gravity: the closure is corrected with
    // the free joint's velocity in the axes of the step's start (then carried into the new
    // axes), so it holds to round-off while the triangle tumbles.
    use gelenk::constraints::{LoopClosure, LoopKind};
    use gelenk::math::{Mat3, Transform, Vec3};
    use gelenk::model::{BodySpec, Joint, ModelBuilder, RigidInertia};
    let at = |x: f64| Transform::from_translation(Vec3::new(x, 0.0, 0.0));
    let mut b = ModelBuilder::new();
    let bar = RigidInertia::new(
        1.0,
        Vec3::new(0.2, 0.0, 0.0),
        Mat3::from_diagonal(&Vec3::new(1e-4, 0.0133, 0.0133)),
    );
    b.add_body(BodySpec::new("base", "universe", Joint::Free, Transform::identity(), bar));
    b.add_body(gelenk::scenes::rod("first", "base", at(0.4), 0.3));
    b.add_body(gelenk::scenes::rod("second", "first", at(0.3), 0.3));
    let model = b.build().unwrap();
    let mut o = options(1e-3);
    o.gravity = Vec3::zeros();
    let mut w = gelenk::world::World::new(o);
    let m = w.add_multibody("triangle", model, &gelenk::collision::MeshOptions::default()).unwrap();
    w.add_loop(
        m,
        LoopClosure {
            body_a: 3,
            frame_a: at(0.3),
            body_b: 1,
            frame_b: Transform::identity(),
            kind: LoopKind::Ball,
            erp: 0.2,
        },
    )
    .unwrap();
    // The isosceles triangle in the plane (x, −z), where a rod turned by φ about y points along
    // (cos φ, sin φ): apex at (0.2, √(0.3² − 0.2²)).
    let apex = (0.2f64, (0.09f64 - 0.04).sqrt());
    let first = apex.1.atan2(apex.0 - 0.4);
    let second = (-apex.1).atan2(-apex.0);
    {
        let s = &mut w.multibody_mut(m).state;
        s.q.copy_from_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, first, second - first]);
        s.v.copy_from_slice(&[0.3, -0.2, 0.1, 1.0, 3.0, -2.0, 0.0, 0.0]);
    }
    assert!(w.constraint_violation() < 1e-12, "closed at the start: {}", w.constraint_violation());
    w.step().unwrap();
    let e1 = w.total_energy();
    let (mut closure, mut de, mut gap) = (0.0f64, 0.0f64, 0.0f64);
    let h = 1e-3;
    for _ in 0..2000 {
        let q0 = w.multibody(m).state.q.clone();
        w.step().unwrap();
        closure = closure.max(w.constraint_violation());
        de = de.max((w.total_energy() - e1).abs() / e1);
        // The base's origin moved by h times its reported velocity, in world axes (v is in
        // the base's axes at the end of the step), and the hinges by h times their rates.
        let s = &w.multibody(m).state;
        let r = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            s.q[6], s.q[3], s.q[4], s.q[5],
        ));
        let moved = Vec3::new(s.q[0] - q0[0], s.q[1] - q0[1], s.q[2] - q0[2]);
        gap = gap.max((moved - r * Vec3::new(s.v[0], s.v[1], s.v[2]) * h).norm());
        gap = gap.max((s.q[7] - q0[7] - h * s.v[6]).abs()).max((s.q[8] - q0[8] - h * s.v[7]).abs());
    }
    println!("floating triangle, 2 s at 1 ms: closure ≤ {closure:e} m, |ΔE|/E {de:e}, gap {gap:e}");
    assert!(closure < 1e-11, "closure error {closure:e} m");
    assert!(gap < 1e-13, "q moved by {gap:e} more than h v");
    assert!(de < 0.05, "|ΔE|/E {de:e}");
}

#[test]
fn a_four_bar_spun_too_fast_for_the_step_falls_back_to_the_first_order_step() {
    // RATTLE's sweeps contract by about h‖v‖/L: with the crank at 300 rad/s a 1/60 s step turns
    // it by 5 rad and they diverge; the step is then the first-order one with SHAKE, finite.
    // At 3 rad/s RATTLE converges.
    for (rate, expected) in [(300.0, "semi-implicit-euler"), (3.0, "rattle")] {
        let (mut w, m) = gelenk::scenes::four_bar_world(options(1.0 / 60.0)).unwrap();
        w.multibody_mut(m).state.v[0] = rate;
        w.step().unwrap();
        let closure = w.constraint_violation();
        let s = &w.multibody(m).state;
        println!(
            "crank at {rate} rad/s: {}, closure {:e} m, v {:?}",
            w.stats().integrator,
            closure,
            s.v.as_slice()
        );
        assert_eq!(w.stats().integrator, expected, "crank at {rate} rad/s");
        assert!(s.q.iter().chain(s.v.iter()).all(|x| x.is_finite()));
    }
}
