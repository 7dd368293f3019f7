//! The hard cases of the stability report, one function per case (the scene and its
//! measurement), and the scenes' helpers that tests use directly.

use super::meter::{step, CaseError};
use super::{options, Outcome, Setting};
use crate::collision::MeshOptions;
use crate::constraints::ContactParameters;
use crate::integrators::IntegratorKind;
use crate::math::{axis_angle, exp3, Mat3, Transform, Vec3};
use crate::model::{BodySpec, Joint, Model, ModelBuilder, RigidInertia, Shape, Suspension};
use crate::scenes::{four_bar_world, free_body};
use crate::world::{integrator_name, StepError, World, WorldOptions};
use nalgebra::{DVector, UnitQuaternion};

pub(super) fn steps(duration: f64, dt: f64) -> usize {
    (duration / dt).round() as usize
}

pub(super) fn cube(side: f64, mass: f64) -> Model {
    let size = Vec3::repeat(side);
    free_body("box", Shape::Box { size }, RigidInertia::solid_box(mass, size))
}

pub(super) fn ball(radius: f64, mass: f64) -> Model {
    free_body("ball", Shape::Sphere { radius }, RigidInertia::solid_sphere(mass, radius))
}

pub(super) fn add(w: &mut World, name: &str, model: Model) -> Result<usize, StepError> {
    w.add_multibody(name, model, &MeshOptions::default())
}

/// Writes position `p` and rotation `r` into a free multibody's q.
pub(super) fn place(w: &mut World, m: usize, p: Vec3, r: UnitQuaternion<f64>) {
    let q = &mut w.multibody_mut(m).state.q;
    q.rows_mut(0, 3).copy_from(&p);
    q.rows_mut(3, 4).copy_from_slice(&[r.i, r.j, r.k, r.w]);
}

pub(super) fn position(w: &World, m: usize) -> Vec3 {
    w.multibody(m).state.q.fixed_rows::<3>(0).into()
}

pub(super) fn rotation(q: &DVector<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[6], q[3], q[4], q[5]))
}

pub(super) fn ground(options: WorldOptions, normal: Vec3) -> Result<World, StepError> {
    let mut w = World::new(options);
    w.add_static("ground", &Shape::HalfSpace { normal }, Transform::identity(), 0)?;
    Ok(w)
}

/// What [`hold`] measured: the largest displacement of the watched body's origin from the start
/// (m), the deepest penetration seen (m), and the steps whose solver chain fell back (an
/// earlier solver's answer failed its check) out of the steps taken.
pub(super) struct Held {
    drift: f64,
    depth: f64,
    fallbacks: usize,
    steps: usize,
}

/// Steps a world whose `watched` multibody should stay put for `n` steps.
pub(super) fn hold(w: &mut World, watched: usize, n: usize) -> Result<Held, CaseError> {
    let start = position(w, watched);
    let mut held = Held { drift: 0.0, depth: 0.0, fallbacks: 0, steps: n };
    for _ in 0..n {
        let stats = step(w)?;
        held.depth = held.depth.max(stats.max_penetration);
        held.fallbacks += usize::from(!stats.fallbacks.is_empty());
        held.drift = held.drift.max((position(w, watched) - start).norm());
    }
    Ok(held)
}

/// The verdict on a held pile: drift below 1 % of `size`, penetration below `margin`, and with
/// the default chain at most 1 % of the steps falling back.
pub(super) fn held(setting: &Setting, held: &Held, margin: f64, size: f64) -> Outcome {
    let Held { drift, depth, fallbacks, steps } = *held;
    let fallback_share = fallbacks as f64 / steps.max(1) as f64;
    Outcome {
        figure: drift,
        pass: drift < 0.01 * size && depth < margin && (!setting.default_chain || fallback_share <= 0.01),
        detail: format!(
            "penetration {depth:.2e} m (margin {margin} m), fallbacks in {fallbacks} of {steps} steps"
        ),
    }
}

pub(super) fn stack(setting: &Setting, count: usize) -> Result<Outcome, CaseError> {
    let side = 0.1;
    let o = options(setting);
    let margin = o.collision.margin;
    let mut w = ground(o, Vec3::z())?;
    let mut top = 0;
    for k in 0..count {
        top = add(&mut w, &format!("box{k}"), cube(side, 1.0))?;
        place(&mut w, top, Vec3::new(0.0, 0.0, side / 2.0 + side * k as f64), UnitQuaternion::identity());
    }
    let pile = hold(&mut w, top, steps(10.0, setting.dt))?;
    Ok(held(setting, &pile, margin, side))
}

pub(super) fn stack10(setting: &Setting) -> Result<Outcome, CaseError> {
    stack(setting, 10)
}

pub(super) fn stack20(setting: &Setting) -> Result<Outcome, CaseError> {
    stack(setting, 20)
}

pub(super) fn pyramid10(setting: &Setting) -> Result<Outcome, CaseError> {
    let (side, gap) = (0.1, 0.002);
    let o = options(setting);
    let margin = o.collision.margin;
    let mut w = ground(o, Vec3::z())?;
    let mut top = 0;
    for row in 0..10 {
        for k in 0..10 - row {
            let x = (k as f64 - (9 - row) as f64 / 2.0) * (side + gap);
            top = add(&mut w, &format!("box{row}_{k}"), cube(side, 1.0))?;
            place(&mut w, top, Vec3::new(x, 0.0, side / 2.0 + side * row as f64), UnitQuaternion::identity());
        }
    }
    let pile = hold(&mut w, top, steps(10.0, setting.dt))?;
    Ok(held(setting, &pile, margin, side))
}

pub(super) fn heavy_on_light(setting: &Setting) -> Result<Outcome, CaseError> {
    let side = 0.1;
    let o = options(setting);
    let margin = o.collision.margin;
    let mut w = ground(o, Vec3::z())?;
    let light = add(&mut w, "light", cube(side, 1.0))?;
    place(&mut w, light, Vec3::new(0.0, 0.0, side / 2.0), UnitQuaternion::identity());
    let heavy = add(&mut w, "heavy", cube(side, 1000.0))?;
    place(&mut w, heavy, Vec3::new(0.0, 0.0, 1.5 * side), UnitQuaternion::identity());
    let pile = hold(&mut w, heavy, steps(10.0, setting.dt))?;
    Ok(held(setting, &pile, margin, side))
}

pub(super) fn cradle(setting: &Setting) -> Result<Outcome, CaseError> {
    // Five balls in a row without gravity: four touching, the first 5 cm away at 1 m/s, so
    // that its impact meets the touching four at once (a simultaneous impact).
    let mut o = options(setting);
    o.gravity = Vec3::zeros();
    o.contact =
        ContactParameters { mu: 0.0, restitution: 1.0, bounce_velocity: 0.0, erp: 0.0, ..Default::default() };
    let tolerance = o.tolerance;
    let mut w = World::new(o);
    let (r, mass) = (0.05, 1.0);
    for k in 0..5 {
        let m = add(&mut w, &format!("ball{k}"), ball(r, mass))?;
        let x = if k == 0 { -0.05 } else { 2.0 * r * k as f64 };
        place(&mut w, m, Vec3::new(x, 0.0, 0.0), UnitQuaternion::identity());
    }
    w.multibody_mut(0).state.v[0] = 1.0;
    let (p0, e0) = (w.linear_momentum(), w.total_energy());
    let (mut dp, mut de, mut allowed) = (0.0f64, f64::NEG_INFINITY, CRADLE_ROUND_OFF);
    for _ in 0..steps(0.5, setting.dt) {
        step(&mut w)?;
        dp = dp.max((w.linear_momentum() - p0).norm());
        de = de.max((w.total_energy() - e0) / e0);
        // An answer accepted at residual τ (m/s) may leave each ball's velocity τ off, so
        // the energy may differ by up to τ Σ m‖v‖: "never grows" holds to that, and to
        // round-off.
        let momenta: f64 = (0..5).map(|k| mass * w.multibody(k).state.v.fixed_rows::<3>(0).norm()).sum();
        allowed = allowed.max(tolerance * momenta / e0);
    }
    let v: Vec<String> = (0..5).map(|k| format!("{:.3}", w.multibody(k).state.v[0])).collect();
    Ok(Outcome {
        figure: dp,
        pass: dp < 1e-12 && de <= allowed,
        detail: format!(
            "final v = [{}] m/s, max ΔE/E = {de:.1e} (the solve's tolerance allows {allowed:.1e})",
            v.join(", ")
        ),
    })
}

/// The relative energy growth in the cradle that counts as round-off.
pub(super) const CRADLE_ROUND_OFF: f64 = 1e-12;

/// Principal inertia (kg·m², about the centre of mass) of the T-shaped body: a 0.4 m bar along
/// x and a 0.3 m stem along −z, 5 cm square sections, 1 kg each, centre of mass at the origin.
/// x is the intermediate axis (Ixx = 0.0234, Iyy = 0.0366, Izz = 0.0140).
pub fn t_body_inertia() -> Mat3 {
    let offset: f64 = 0.0875; // each part's centre is 8.75 cm from the joint centre of mass
    let bar = Vec3::new(
        0.05f64.powi(2) + 0.05f64.powi(2),
        0.4f64.powi(2) + 0.05f64.powi(2),
        0.4f64.powi(2) + 0.05f64.powi(2),
    ) / 12.0;
    let stem = Vec3::new(
        0.05f64.powi(2) + 0.3f64.powi(2),
        0.05f64.powi(2) + 0.3f64.powi(2),
        0.05f64.powi(2) + 0.05f64.powi(2),
    ) / 12.0;
    let shift = Vec3::new(2.0 * offset * offset, 2.0 * offset * offset, 0.0);
    Mat3::from_diagonal(&(bar + stem + shift))
}

/// Half the time between sign changes of ω_x, i.e. the flip period (s), from Euler's equations
/// `I ω̇ = I ω × ω` integrated by RK4 at 1e-5 s (the reference of the Dzhanibekov case).
pub fn dzhanibekov_reference_period(inertia: &Mat3, omega: Vec3, duration: f64) -> Option<f64> {
    let inverse = inertia.try_inverse()?;
    let f = |w: &Vec3| inverse * (inertia * w).cross(w);
    let h = 1e-5;
    let mut w = omega;
    let mut crossings = Vec::new();
    for k in 0..(duration / h) as usize {
        let k1 = f(&w);
        let k2 = f(&(w + k1 * (h / 2.0)));
        let k3 = f(&(w + k2 * (h / 2.0)));
        let k4 = f(&(w + k3 * h));
        let next = w + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
        if next.x.signum() != w.x.signum() {
            crossings.push((k as f64 + w.x / (w.x - next.x)) * h);
        }
        w = next;
    }
    flip_period(&crossings)
}

/// The flip period from the times ω_x changes sign: twice the mean interval.
/// Records the scheme a step used ([`crate::world::StepStats::integrator`]) once: a smooth case
/// names in its detail which steps it took (a scheme without a closed-loop form leaves a
/// linkage to the velocity-level step).
pub(super) fn note_scheme(schemes: &mut Vec<&'static str>, scheme: &'static str) {
    if !schemes.contains(&scheme) {
        schemes.push(scheme);
    }
}

pub(super) fn flip_period(crossings: &[f64]) -> Option<f64> {
    (crossings.len() >= 2)
        .then(|| 2.0 * (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64)
}

pub(super) fn dzhanibekov(setting: &Setting) -> Result<Outcome, CaseError> {
    let inertia = t_body_inertia();
    let omega0 = Vec3::new(10.0, 1.0, 0.0);
    let duration = 10.0;
    let mut o = options(setting);
    o.gravity = Vec3::zeros();
    let mut w = World::new(o);
    let m = add(
        &mut w,
        "T",
        free_body("T", Shape::Sphere { radius: 0.01 }, RigidInertia::new(2.0, Vec3::zeros(), inertia)),
    )?;
    w.multibody_mut(m).state.v.rows_mut(3, 3).copy_from(&omega0);
    // Angular momentum (world axes) at the end of the step and at the step's midpoint
    // orientation, the energy and ω_x. The velocity-level step moves the rotation with the
    // velocity at the end of the step (q₁ = q₀ ⊕ h v₁), so v₁ is the velocity over the step
    // and its momentum belongs to the orientation halfway through it, R₁ exp(−h ω₁/2); a
    // smooth step's velocity and orientation are at the same instant.
    let angular = |w: &World| -> (Vec3, Vec3, f64, f64) {
        let s = &w.multibody(m).state;
        let omega: Vec3 = s.v.fixed_rows::<3>(3).into();
        let (r, momentum) = (rotation(&s.q), inertia * omega);
        let midpoint = r * (exp3(&(omega * (-0.5 * setting.dt))) * momentum);
        (r * momentum, midpoint, 0.5 * omega.dot(&momentum), omega.x)
    };
    let (l0, _, e0, _) = angular(&w);
    let (mut dl, mut dl_end, mut de, mut rise, mut previous) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, e0);
    let mut crossings = Vec::new();
    let mut last = omega0.x;
    let mut schemes: Vec<&'static str> = Vec::new();
    for k in 0..steps(duration, setting.dt) {
        step(&mut w)?;
        let scheme = w.stats().integrator;
        note_scheme(&mut schemes, scheme);
        let (l_end, l_mid, e, wx) = angular(&w);
        let l = if scheme == integrator_name(&IntegratorKind::SemiImplicitEuler) { l_mid } else { l_end };
        dl = dl.max((l - l0).norm() / l0.norm());
        dl_end = dl_end.max((l_end - l0).norm() / l0.norm());
        de = de.max((e - e0).abs() / e0);
        rise = rise.max((e - previous) / e0);
        previous = e;
        if wx.signum() != last.signum() {
            crossings.push((k as f64 + last / (last - wx)) * setting.dt);
        }
        last = wx;
    }
    let reference = dzhanibekov_reference_period(&inertia, omega0, duration);
    let period = flip_period(&crossings);
    let period_error = match (period, reference) {
        (Some(p), Some(r)) => (p - r).abs() / r,
        _ => f64::INFINITY,
    };
    let figure = dl.max(de);
    let pass = if setting.integrator == IntegratorKind::SemiImplicitEuler {
        // The velocity-level step: the energy never grows (beyond round-off), the momentum stays
        // within 1e-2 and the flip keeps its period within 5 %.
        rise <= DZHANIBEKOV_ROUND_OFF && dl <= 1e-2 && period_error <= 0.05
    } else {
        figure < 1e-6 && period_error < 0.01
    };
    Ok(Outcome {
        figure,
        pass,
        detail: format!(
            "|ΔL|/L {dl:.1e} (at the end of the step {dl_end:.1e}), |ΔE|/E {de:.1e}, largest rise of E in a step {rise:.1e} of E₀, flip period {} s vs {} s (error {period_error:.1e}); steps: {}",
            period.map_or("none".into(), |p| format!("{p:.4}")),
            reference.map_or("none".into(), |p| format!("{p:.4}")),
            schemes.join(", "),
        ),
    })
}

/// The largest rise of the kinetic energy in one step (relative to the initial energy) that
/// the Dzhanibekov case counts as round-off rather than a gain.
pub(super) const DZHANIBEKOV_ROUND_OFF: f64 = 1e-12;

pub(super) fn four_bar(setting: &Setting) -> Result<Outcome, CaseError> {
    let (mut w, m) = four_bar_world(options(setting))?;
    let e0 = w.total_energy();
    let (mut closure, mut de, mut kinetic) = (0.0f64, 0.0f64, 0.0f64);
    let mut schemes: Vec<&'static str> = Vec::new();
    let mut scratch = crate::data::Data::new(w.multibody(m).model());
    for _ in 0..steps(10.0, setting.dt) {
        step(&mut w)?;
        note_scheme(&mut schemes, w.stats().integrator);
        closure = closure.max(w.constraint_violation());
        let e = w.total_energy();
        de = de.max((e - e0).abs());
        let b = w.multibody(m);
        let energy = crate::algorithms::kinetic_energy(b.model(), &mut scratch, &b.state.q, &b.state.v)
            .map_err(|source| StepError::Dynamics { multibody: "four-bar".into(), source })?;
        kinetic = kinetic.max(energy);
    }
    let relative = de / kinetic.max(f64::MIN_POSITIVE);
    // The velocity-level step (RATTLE for the free linkage, second order) is held to 2 %; a
    // smooth step of a higher-order integrator to 1e-4.
    let bound = if setting.integrator == IntegratorKind::SemiImplicitEuler { 0.02 } else { 1e-4 };
    Ok(Outcome {
        figure: closure,
        pass: closure < 1e-8 && relative < bound,
        detail: format!(
            "|ΔE| = {relative:.1e} of the largest kinetic energy ({kinetic:.3} J); steps: {}",
            schemes.join(", ")
        ),
    })
}

pub(super) fn suspension(setting: &Setting) -> Result<Outcome, CaseError> {
    let mass = 10.0;
    let mut worst = 0.0f64;
    let mut details = Vec::new();
    for ratio in [1e-2, 1.0, 1e2, 1e4] {
        let k = ratio * mass / (setting.dt * setting.dt);
        let joint = Joint::Hinge2 {
            axis1: Vec3::z(),
            axis2: Vec3::y(),
            suspension: Some(Suspension { stiffness: k, damping: 0.0 }),
        };
        let mut b = ModelBuilder::new();
        b.add_body(BodySpec::new(
            "wheel",
            "universe",
            joint,
            Transform::identity(),
            RigidInertia::solid_sphere(mass, 0.3),
        ));
        let mut w = World::new(options(setting));
        let m = add(&mut w, "wheel", b.build().expect("a hinge2 wheel is a valid model"))?;
        let rest = -mass * 9.81 / k;
        let mut amplitude = 0.0f64;
        for _ in 0..steps(2.0, setting.dt) {
            step(&mut w)?;
            amplitude = amplitude.max((w.multibody(m).state.q[0] - rest).abs());
        }
        let growth = amplitude / rest.abs();
        details.push(format!("{ratio:.0e}: {growth:.3}"));
        worst = worst.max(growth);
    }
    Ok(Outcome {
        figure: worst,
        // Released at s = 0, the undamped spring oscillates about s₀ with amplitude |s₀|; an
        // implicit step may damp it but must never amplify it.
        pass: worst <= 1.0 + 1e-9,
        detail: format!("per k·dt²/m: {}", details.join(", ")),
    })
}

pub(super) fn ramp5(setting: &Setting) -> Result<Outcome, CaseError> {
    let theta: f64 = 20f64.to_radians();
    let side = 0.1;
    let mus = [0.25, 0.33, 0.35, 0.40, 0.50];
    let normal = axis_angle(&Vec3::y(), theta) * Vec3::z();
    let down = Vec3::new(theta.cos(), 0.0, -theta.sin());
    let mut w = ground(options(setting), normal)?;
    let tilt = UnitQuaternion::from_axis_angle(&Vec3::y_axis(), theta);
    let mut starts = Vec::new();
    for (k, mu) in mus.iter().enumerate() {
        let m = add(&mut w, &format!("box{k}"), cube(side, 1.0))?;
        let material = k as u32 + 1;
        for &c in w.collision().colliders_of(m).to_vec().iter() {
            w.collision_mut().set_material(c, material);
        }
        w.set_pair_parameters(material, 0, ContactParameters { mu: *mu, ..Default::default() });
        let p = normal * (side / 2.0) + Vec3::y() * (0.3 * k as f64);
        place(&mut w, m, p, tilt);
        starts.push(p);
    }
    let duration = 1.0;
    for _ in 0..steps(duration, setting.dt) {
        step(&mut w)?;
    }
    let mut right = 0;
    let mut moved = Vec::new();
    for (k, mu) in mus.iter().enumerate() {
        let d = (position(&w, k) - starts[k]).dot(&down);
        let expected = if *mu >= theta.tan() {
            0.0
        } else {
            0.5 * 9.81 * (theta.sin() - mu * theta.cos()) * duration * duration
        };
        let ok = if expected == 0.0 { d.abs() < 1e-3 } else { (d - expected).abs() < 0.05 * expected };
        right += usize::from(ok);
        moved.push(format!("μ {mu}: {d:.4} m (expected {expected:.4})"));
    }
    Ok(Outcome { figure: right as f64, pass: right == mus.len(), detail: moved.join("; ") })
}

/// A ball of radius 0.1 m released on a 20° incline with friction μ: the acceleration of its
/// centre along the slope (m/s², least-squares fit of s(t) over 1 s) and the largest slip speed.
pub fn ball_on_incline(setting: &Setting, mu: f64) -> Result<(f64, f64), CaseError> {
    let theta: f64 = 20f64.to_radians();
    let mut o = options(setting);
    o.contact = ContactParameters { mu, ..Default::default() };
    let normal = axis_angle(&Vec3::y(), theta) * Vec3::z();
    let down = Vec3::new(theta.cos(), 0.0, -theta.sin());
    let mut w = ground(o, normal)?;
    let r = 0.1;
    let m = add(&mut w, "ball", ball(r, 1.0))?;
    place(&mut w, m, normal * r, UnitQuaternion::identity());
    let x0 = position(&w, m);
    let (mut normal_matrix, mut rhs, mut slip) = (Mat3::zeros(), Vec3::zeros(), 0.0f64);
    for k in 1..=steps(1.0, setting.dt) {
        step(&mut w)?;
        let t = k as f64 * setting.dt;
        let s = (position(&w, m) - x0).dot(&down);
        let basis = Vec3::new(1.0, t, 0.5 * t * t);
        normal_matrix += basis * basis.transpose();
        rhs += basis * s;
        let st = &w.multibody(m).state;
        let (v, omega): (Vec3, Vec3) = (st.v.fixed_rows::<3>(0).into(), st.v.fixed_rows::<3>(3).into());
        let n_local = rotation(&st.q).inverse() * normal;
        slip = slip.max((v + omega.cross(&(-n_local * r))).norm());
    }
    let a = normal_matrix.cholesky().map_or(f64::NAN, |c| c.solve(&rhs)[2]);
    Ok((a, slip))
}

pub(super) fn rolling_ball(setting: &Setting) -> Result<Outcome, CaseError> {
    let (a, slip) = ball_on_incline(setting, 0.3)?;
    let expected = 5.0 / 7.0 * 9.81 * 20f64.to_radians().sin();
    let error = (a - expected).abs() / expected;
    Ok(Outcome {
        figure: error,
        pass: error < 0.01,
        detail: format!("a = {a:.4} m/s² (expected {expected:.4}), slip ≤ {slip:.1e} m/s"),
    })
}

/// Distance (m) a 0.2 m box launched at `v0` m/s slides on the ground with μ = 0.5, and its
/// largest height above its resting height while sliding (m: the convex relaxation's "hover").
pub fn sliding_distance(setting: &Setting, v0: f64) -> Result<(f64, f64), CaseError> {
    let mut o = options(setting);
    o.contact = ContactParameters { mu: 0.5, ..Default::default() };
    let mut w = ground(o, Vec3::z())?;
    let side = 0.2;
    let m = add(&mut w, "box", cube(side, 1.0))?;
    place(&mut w, m, Vec3::new(0.0, 0.0, side / 2.0), UnitQuaternion::identity());
    for _ in 0..steps(0.05, setting.dt) {
        step(&mut w)?;
    }
    let start = position(&w, m);
    w.multibody_mut(m).state.v[0] = v0;
    let mut hover = 0.0f64;
    for _ in 0..steps(3.0, setting.dt) {
        step(&mut w)?;
        hover = hover.max(position(&w, m).z - start.z);
    }
    Ok((position(&w, m).x - start.x, hover))
}

pub(super) fn sliding_box(setting: &Setting) -> Result<Outcome, CaseError> {
    let v0 = 2.0;
    let (d, hover) = sliding_distance(setting, v0)?;
    let expected = v0 * v0 / (2.0 * 0.5 * 9.81);
    let error = (d - expected).abs() / expected;
    Ok(Outcome {
        figure: error,
        pass: error < 0.02,
        detail: format!("distance {d:.4} m (expected {expected:.4}), rose {hover:.1e} m while sliding"),
    })
}

pub(super) fn resting(setting: &Setting) -> Result<Outcome, CaseError> {
    let mut w = ground(options(setting), Vec3::z())?;
    let side = 0.2;
    let m = add(&mut w, "box", cube(side, 1.0))?;
    place(&mut w, m, Vec3::new(0.0, 0.0, side / 2.0), UnitQuaternion::identity());
    let mut speed = 0.0f64;
    for _ in 0..steps(10.0, setting.dt) {
        step(&mut w)?;
        speed = speed.max(w.multibody(m).state.v.norm());
    }
    Ok(Outcome { figure: speed, pass: speed < 1e-6, detail: String::new() })
}

/// A sphere of radius `r` (m) at `speed` m/s against a static wall `thickness` m thick (its
/// near face 1 m ahead); whether it ends beyond the wall.
pub fn tunnels(setting: &Setting, speed: f64, r: f64, thickness: f64) -> Result<bool, CaseError> {
    let mut o = options(setting);
    o.gravity = Vec3::zeros();
    o.contact = ContactParameters { mu: 0.0, ..Default::default() };
    let mut w = World::new(o);
    w.add_static(
        "wall",
        &Shape::Box { size: Vec3::new(thickness, 1.0, 1.0) },
        Transform::from_translation(Vec3::new(1.0 + thickness / 2.0, 0.0, 0.0)),
        0,
    )?;
    let m = add(&mut w, "ball", ball(r, 0.01))?;
    w.multibody_mut(m).state.v[0] = speed;
    for _ in 0..steps(0.05, setting.dt).max(2) {
        step(&mut w)?;
    }
    Ok(position(&w, m).x > 1.0 + thickness / 2.0)
}

pub(super) fn fast_sphere(setting: &Setting) -> Result<Outcome, CaseError> {
    let (speed, r, thickness) = (100.0, 0.01, 0.02);
    let through = tunnels(setting, speed, r, thickness)?;
    let ratio = speed * setting.dt / (thickness + 2.0 * r);
    Ok(Outcome {
        figure: ratio,
        pass: !through,
        detail: if through { "tunnels".into() } else { "stopped".into() },
    })
}

/// The far-from-origin scene at `offset`: a ball thrown along the ground with back-spin (it
/// slides, then rolls; one contact, so the answer is unique — a box's four coplanar corners
/// share friction non-uniquely, and 1e-10 m rounding at 1e6 m then picks another share). Its
/// trajectory relative to the offset (position and quaternion per step).
pub(super) fn far_run(setting: &Setting, offset: Vec3) -> Result<Vec<[f64; 7]>, CaseError> {
    let mut w = World::new(options(setting));
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::from_translation(offset), 0)?;
    let r = 0.1;
    let m = add(&mut w, "ball", ball(r, 1.0))?;
    place(&mut w, m, offset + Vec3::new(0.0, 0.0, r), UnitQuaternion::identity());
    {
        let v = &mut w.multibody_mut(m).state.v;
        v[0] = 1.0;
        v[1] = 0.5;
        v[4] = -5.0;
        v[5] = 3.0;
    }
    let mut out = Vec::new();
    for _ in 0..steps(1.0, setting.dt) {
        step(&mut w)?;
        let q = &w.multibody(m).state.q;
        let p = Vec3::new(q[0], q[1], q[2]) - offset;
        out.push([p.x, p.y, p.z, q[3], q[4], q[5], q[6]]);
    }
    Ok(out)
}

pub(super) fn far_origin(setting: &Setting) -> Result<Outcome, CaseError> {
    let near = far_run(setting, Vec3::zeros())?;
    let far = far_run(setting, Vec3::repeat(1e6))?;
    let travel = near.iter().map(|s| Vec3::new(s[0], s[1], s[2] - near[0][2]).norm()).fold(0.0, f64::max);
    let mut worst = 0.0f64;
    for (a, b) in near.iter().zip(&far) {
        let dp = Vec3::new(a[0] - b[0], a[1] - b[1], a[2] - b[2]).norm() / travel;
        let dq = (0..4).map(|k| (a[3 + k] - b[3 + k]).powi(2)).sum::<f64>().sqrt();
        worst = worst.max(dp).max(dq);
    }
    Ok(Outcome { figure: worst, pass: worst < 1e-6, detail: format!("travel {travel:.3} m") })
}

/// FNV-1a hash of every multibody's q and v bits.
pub fn state_hash(w: &World) -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for m in 0..w.multibody_count() {
        let s = &w.multibody(m).state;
        for x in s.q.iter().chain(s.v.iter()) {
            for byte in x.to_bits().to_le_bytes() {
                hash ^= u64::from(byte);
                hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
    }
    hash
}

/// Five boxes dropped tumbling onto the ground and onto each other: the state hash after 1000
/// steps.
pub fn tumbling_hash(setting: &Setting) -> Result<u64, CaseError> {
    let mut w = ground(options(setting), Vec3::z())?;
    for k in 0..5 {
        let m = add(&mut w, &format!("box{k}"), cube(0.1, 0.5))?;
        let r = UnitQuaternion::from_scaled_axis(Vec3::new(0.3, 0.2 * k as f64, 0.1));
        place(&mut w, m, Vec3::new(0.03 * k as f64, -0.02 * k as f64, 0.08 + 0.12 * k as f64), r);
    }
    for _ in 0..1000 {
        step(&mut w)?;
    }
    Ok(state_hash(&w))
}

pub(super) fn determinism(setting: &Setting) -> Result<Outcome, CaseError> {
    let (a, b) = (tumbling_hash(setting)?, tumbling_hash(setting)?);
    Ok(Outcome { figure: f64::from(u8::from(a != b)), pass: a == b, detail: format!("hash {a:016x}") })
}
