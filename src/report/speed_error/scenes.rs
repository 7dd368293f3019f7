//! The scenes of the speed–error report: smooth multibodies stepped by an [`Integrator`] and
//! contact scenes stepped by the [`World`], each with its error measures.

use super::types::ReportError;
use crate::algorithms::{kinetic_energy, potential_energy};
use crate::collision::MeshOptions;
use crate::constraints::ContactParameters;
use crate::data::Data;
use crate::integrators::{DormandPrince45, IntegratorKind};
use crate::math::{Mat3, Transform, Vec3};
use crate::model::{BodySpec, Joint, Model, ModelBuilder, RigidInertia, Shape};
use crate::scenes::{four_bar_world, free_body};
use crate::state::State;
use crate::world::{SolverKind, World, WorldOptions};
use nalgebra::{DVector, UnitQuaternion};
use std::path::Path;
use std::time::Instant;

/// Output interval of the smooth scenes (s): errors are sampled here when the step divides it;
/// a longer step is sampled at every step instead (see [`sample_interval`]).
pub(crate) const SAMPLE_INTERVAL: f64 = 0.04;

/// The sample interval of a run with step `dt` over `duration` seconds: [`SAMPLE_INTERVAL`]
/// when `dt` divides it, otherwise `dt` itself when it divides the duration (steps longer than
/// 40 ms, e.g. 50 ms, are compared with a reference sampled on their own grid); None when
/// neither holds.
pub(crate) fn sample_interval(dt: f64, duration: f64) -> Option<f64> {
    let divides = |interval: f64| {
        let n = (interval / dt).round();
        n >= 1.0 && (n * dt - interval).abs() <= 1e-9 * interval
    };
    if divides(SAMPLE_INTERVAL) {
        Some(SAMPLE_INTERVAL)
    } else if divides(duration) {
        Some(dt)
    } else {
        None
    }
}

/// A smooth scene: a model, its initial state and duration.
pub(crate) struct SmoothScene {
    pub name: &'static str,
    pub model: Model,
    pub initial: State,
    pub duration: f64,
    /// Step of the Gragg–Bulirsch–Stoer reference (8 columns).
    pub reference_dt: f64,
}

/// The 5-link pendulum of `peers/pendulum5.xml` through the MJCF reader, every hinge at 0.3 rad.
pub(crate) fn pendulum5(peers_dir: &Path) -> Result<SmoothScene, ReportError> {
    let scene = crate::io::mjcf::load_file(peers_dir.join("pendulum5.xml"))?;
    let model = scene.model;
    let mut initial = State::new(&model);
    initial.q.fill(0.3);
    Ok(SmoothScene { name: "pendulum5", model, initial, duration: 5.0, reference_dt: 2e-3 })
}

/// A free box spinning at 5 rad/s about its intermediate principal axis (inertia 0.01, 0.02,
/// 0.03 kg·m²), perturbed by 0.01 rad/s about the others, without gravity: it flips every few
/// seconds (Dzhanibekov).
pub(crate) fn dzhanibekov() -> Result<SmoothScene, ReportError> {
    let mut b = ModelBuilder::new();
    b.gravity(Vec3::zeros());
    let inertia = RigidInertia::new(1.0, Vec3::zeros(), Mat3::from_diagonal(&Vec3::new(0.01, 0.02, 0.03)));
    b.add_body(BodySpec::new("body", "universe", Joint::Free, Transform::identity(), inertia));
    let model = b.build()?;
    let mut initial = State::new(&model);
    initial.v.copy_from_slice(&[0.0, 0.0, 0.0, 0.01, 5.0, 0.01]);
    Ok(SmoothScene { name: "dzhanibekov", model, initial, duration: 20.0, reference_dt: 2e-3 })
}

/// 30 hinge links of 0.1 m and 0.1 kg hanging from the origin, the last one 1000× heavier
/// (100 kg), started bent (q_i = 0.1 sin i rad): light links under a heavy load make the
/// system stiff (fastest mode ≈ 300 rad/s).
pub(crate) fn chain30() -> Result<SmoothScene, ReportError> {
    let n = 30;
    let mut b = ModelBuilder::new();
    for i in 0..n {
        let mass = if i == n - 1 { 100.0 } else { 0.1 };
        let i_rod = mass * 0.01 / 12.0;
        let inertia = RigidInertia::new(
            mass,
            Vec3::new(0.0, 0.0, -0.05),
            Mat3::from_diagonal(&Vec3::new(i_rod, i_rod, 1e-6 * mass)),
        );
        let parent = if i == 0 { "universe".to_string() } else { format!("link{}", i - 1) };
        let placement = if i == 0 {
            Transform::identity()
        } else {
            Transform::from_translation(Vec3::new(0.0, 0.0, -0.1))
        };
        b.add_body(BodySpec::new(format!("link{i}"), parent, Joint::hinge(Vec3::y()), placement, inertia));
    }
    let model = b.build()?;
    let mut initial = State::new(&model);
    for i in 0..n {
        initial.q[i] = 0.1 * (i as f64 + 1.0).sin();
    }
    Ok(SmoothScene { name: "chain30", model, initial, duration: 1.0, reference_dt: 2e-4 })
}

/// A run of a smooth scene: q and v at every sample time (flattened), and the cost.
pub(crate) struct Trajectory {
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    /// Time between samples (s).
    pub interval: f64,
    /// Median wall time per simulated second (µs).
    pub cost_us_per_s: f64,
    /// Mean step size (s): dt for fixed steps, the mean accepted step for the adaptive scheme.
    pub mean_step: f64,
}

impl Trajectory {
    pub fn samples(&self, nq: usize) -> usize {
        self.q.len() / nq
    }
}

/// Dynamics evaluations after which a smooth run is abandoned as too expensive for the report
/// (the adaptive scheme at tight tolerances on the stiff chain).
pub(crate) const MAX_EVALUATIONS: u64 = 1_000_000;

/// A run that takes longer than this (s) is not repeated: its noise averages out over its steps.
pub(crate) const LONG_RUN: f64 = 0.5;

/// Short runs are repeated (beyond the requested repeats) until this much wall time (s) has
/// been timed, up to [`MAX_REPEATS`] runs: a millisecond run timed three times on a shared
/// machine reports whatever preemption hit it, the median of many does not.
pub(crate) const MIN_TIMED: f64 = 0.1;

/// Most timed runs of one configuration.
pub(crate) const MAX_REPEATS: usize = 50;

/// Steps `scene` with `kind` at `dt` (the output interval for the adaptive scheme) `repeats`
/// times (more for short runs, see [`MIN_TIMED`]; once for a run over [`LONG_RUN`]), sampling
/// every `interval` seconds; None if `dt` does not divide `interval` or the run needs more than
/// `budget` dynamics evaluations.
pub(crate) fn run_smooth(
    scene: &SmoothScene,
    kind: IntegratorKind,
    dt: f64,
    interval: f64,
    repeats: usize,
    budget: u64,
) -> Result<Option<Trajectory>, ReportError> {
    let model = &scene.model;
    let per_sample = (interval / dt).round() as usize;
    if per_sample == 0 || (per_sample as f64 * dt - interval).abs() > 1e-9 * interval {
        return Ok(None);
    }
    let samples = (scene.duration / interval).round() as usize;
    let tau = DVector::zeros(model.nv());
    let mut data = Data::new(model);
    let mut times = Vec::with_capacity(repeats);
    let mut q = Vec::with_capacity((samples + 1) * model.nq());
    let mut v = Vec::with_capacity((samples + 1) * model.nv());
    let mut steps = 0u64;
    let mut timed = 0.0;
    while times.len() < repeats.max(1) || (timed < MIN_TIMED && times.len() < MAX_REPEATS) {
        let adaptive = matches!(kind, IntegratorKind::DormandPrince45 { .. });
        let mut dopri = match kind {
            IntegratorKind::DormandPrince45 { rtol, atol } => Some(DormandPrince45::new(model, rtol, atol)),
            _ => None,
        };
        let mut fixed = kind.build(model);
        let mut state = scene.initial.clone();
        q.clear();
        v.clear();
        q.extend_from_slice(state.q.as_slice());
        v.extend_from_slice(state.v.as_slice());
        let start = Instant::now();
        for k in 1..=samples {
            let evaluations = if let Some(dopri) = dopri.as_mut() {
                dopri.advance_to(model, &mut data, &mut state, &tau, k as f64 * interval)?;
                crate::integrators::Integrator::evaluations(dopri)
            } else {
                for _ in 0..per_sample {
                    fixed.step(model, &mut data, &mut state, &tau, dt)?;
                }
                fixed.evaluations()
            };
            if evaluations > budget {
                return Ok(None);
            }
            q.extend_from_slice(state.q.as_slice());
            v.extend_from_slice(state.v.as_slice());
        }
        let elapsed = start.elapsed().as_secs_f64();
        times.push(elapsed);
        timed += elapsed;
        let long = elapsed > LONG_RUN;
        steps = match (&dopri, adaptive) {
            (Some(d), true) => d.stats().accepted,
            _ => (samples * per_sample) as u64,
        };
        if long {
            break;
        }
    }
    let duration = samples as f64 * interval;
    Ok(Some(Trajectory {
        q,
        v,
        interval,
        cost_us_per_s: median(&mut times) * 1e6 / duration,
        mean_step: duration / steps.max(1) as f64,
    }))
}

/// The median of `x` (sorted in place).
pub(crate) fn median(x: &mut [f64]) -> f64 {
    x.sort_by(f64::total_cmp);
    let n = x.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        x[n / 2]
    } else {
        0.5 * (x[n / 2 - 1] + x[n / 2])
    }
}

/// Errors of one smooth run against the reference: (primary, energy, secondary). Both must
/// be sampled at the same interval (NaN otherwise: the samples would not be at the same times).
pub(crate) fn smooth_errors(
    scene: &SmoothScene,
    run: &Trajectory,
    reference: &Trajectory,
) -> (f64, f64, f64) {
    if (run.interval - reference.interval).abs() > 1e-9 * reference.interval {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    let model = &scene.model;
    let (nq, nv) = (model.nq(), model.nv());
    let n = run.samples(nq).min(reference.samples(nq));
    let last = |t: &Trajectory| {
        let s = t.samples(nq) - 1;
        (
            DVector::from_column_slice(&t.q[s * nq..(s + 1) * nq]),
            DVector::from_column_slice(&t.v[s * nv..(s + 1) * nv]),
        )
    };
    let (q_end, v_end) = last(run);
    let (q_ref, _) = last(reference);
    let mut data = Data::new(model);
    let energy = |data: &mut Data, q: &DVector<f64>, v: &DVector<f64>| {
        kinetic_energy(model, data, q, v).unwrap_or(f64::NAN)
            + potential_energy(model, data, q).unwrap_or(f64::NAN)
    };
    let e0 = energy(&mut data, &scene.initial.q, &scene.initial.v);
    match scene.name {
        "dzhanibekov" => {
            let ke0 =
                kinetic_energy(model, &mut data, &scene.initial.q, &scene.initial.v).unwrap_or(f64::NAN);
            let ke = kinetic_energy(model, &mut data, &q_end, &v_end).unwrap_or(f64::NAN);
            let l0 = angular_momentum(model, &scene.initial.q, &scene.initial.v);
            let l = angular_momentum(model, &q_end, &v_end);
            let period = flip_period(&run.v, nv, run.interval);
            let period_ref = flip_period(&reference.v, nv, reference.interval);
            let period_error = match (period, period_ref) {
                (Some(p), Some(r)) => (p - r).abs() / r,
                _ => 1.0, // no flip where the reference flips: a 100 % error
            };
            (period_error, (ke - ke0) / ke0, (l - l0).norm() / l0.norm())
        }
        _ => {
            // Hinge chains: every coordinate is an angle.
            let mut worst: f64 = 0.0;
            for k in 0..n * nq {
                worst = worst.max((run.q[k] - reference.q[k]).abs());
            }
            let rest = potential_energy(model, &mut data, &model.neutral_configuration()).unwrap_or(f64::NAN);
            let e = energy(&mut data, &q_end, &v_end);
            // MuJoCo's measure (benches/peers): the largest joint-angle error at T.
            let final_error = (&q_end - &q_ref).amax();
            (final_error, (e - e0) / (e0 - rest), worst)
        }
    }
}

/// World-frame angular momentum `R I ω` (kg·m²/s) of the free body of the Dzhanibekov scene.
fn angular_momentum(model: &Model, q: &DVector<f64>, v: &DVector<f64>) -> Vec3 {
    let r = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[6], q[3], q[4], q[5]));
    let omega = Vec3::new(v[3], v[4], v[5]);
    r * (model.inertia(1).inertia_com() * omega)
}

/// Flip period (s) of the Dzhanibekov body: twice the mean time between sign changes of the
/// intermediate-axis rate ω_y (linear interpolation between samples `interval` s apart).
fn flip_period(v: &[f64], nv: usize, interval: f64) -> Option<f64> {
    let mut crossings = Vec::new();
    let n = v.len() / nv;
    for s in 1..n {
        let (a, b) = (v[(s - 1) * nv + 4], v[s * nv + 4]);
        if (a > 0.0) != (b > 0.0) {
            crossings.push(interval * ((s - 1) as f64 + a / (a - b)));
        }
    }
    if crossings.len() < 2 {
        return None;
    }
    Some(2.0 * (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64)
}

/// A contact scene of the report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum ContactScene {
    /// A ball dropped from 1 m, restitution 0.8: apex after n bounces against ε²ⁿh.
    BouncingBall,
    /// A box pushed at 2 m/s on μ = 0.5: stopping distance against v₀²/(2μg).
    SlidingBox,
    /// Ten 0.1 m cubes stacked: drift and penetration.
    Stack10,
    /// A four-bar linkage under gravity closed by a loop joint: closure error.
    FourBar,
}

impl ContactScene {
    pub fn name(self) -> &'static str {
        match self {
            ContactScene::BouncingBall => "bouncing_ball",
            ContactScene::SlidingBox => "sliding_box",
            ContactScene::Stack10 => "stack10",
            ContactScene::FourBar => "four_bar",
        }
    }

    fn duration(self, quick: bool) -> f64 {
        match (self, quick) {
            (ContactScene::BouncingBall, false) => 3.0,
            (ContactScene::SlidingBox, _) => 0.7,
            (ContactScene::Stack10, false) | (ContactScene::FourBar, false) => 2.0,
            (ContactScene::BouncingBall, true) => 2.5,
            _ => 0.5,
        }
    }
}

/// Result of a contact run: (primary error, energy or second measure, secondary), cost.
pub(crate) struct ContactRun {
    pub error: f64,
    pub energy: f64,
    pub secondary: f64,
    pub cost_us_per_s: f64,
}

/// Builds the world of `scene` with step `dt` and solver chain `solvers`; returns it with the
/// index of the body the measures follow.
fn build_world(scene: ContactScene, dt: f64, solvers: &[SolverKind]) -> Result<World, ReportError> {
    let mut options = WorldOptions { dt, solvers: solvers.to_vec(), max_substeps: 1, ..Default::default() };
    options.sleep.enabled = false;
    let mut world;
    let meshes = MeshOptions::default();
    match scene {
        ContactScene::BouncingBall => {
            options.contact =
                ContactParameters { restitution: 0.8, bounce_velocity: 0.01, mu: 0.0, ..Default::default() };
            options.collision.margin = 0.02;
            world = World::new(options);
            world.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0)?;
            let r = 0.05;
            let ball = world.add_multibody(
                "ball",
                free_body("ball", Shape::Sphere { radius: r }, RigidInertia::solid_sphere(1.0, r)),
                &meshes,
            )?;
            world.multibody_mut(ball).state.q[2] = r + 1.0;
        }
        ContactScene::SlidingBox => {
            options.contact = ContactParameters { mu: 0.5, ..Default::default() };
            world = World::new(options);
            world.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0)?;
            let side = Vec3::repeat(0.2);
            let b = world.add_multibody(
                "box",
                free_body("box", Shape::Box { size: side }, RigidInertia::solid_box(1.0, side)),
                &meshes,
            )?;
            let state = &mut world.multibody_mut(b).state;
            state.q[2] = 0.1;
            state.v[0] = 2.0;
        }
        ContactScene::Stack10 => {
            options.contact = ContactParameters { mu: 0.8, ..Default::default() };
            world = World::new(options);
            world.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0)?;
            let side = Vec3::repeat(0.1);
            for k in 0..10 {
                let name = format!("box{k}");
                let b = world.add_multibody(
                    &name,
                    free_body(&name, Shape::Box { size: side }, RigidInertia::solid_box(0.5, side)),
                    &meshes,
                )?;
                world.multibody_mut(b).state.q[2] = 0.05 + 0.1 * k as f64;
            }
        }
        ContactScene::FourBar => {
            world = four_bar_world(options)?.0;
        }
    }
    Ok(world)
}

/// Runs a contact scene `repeats` times; errors from the last run, the median cost.
pub(crate) fn run_contact(
    scene: ContactScene,
    dt: f64,
    solvers: &[SolverKind],
    quick: bool,
    repeats: usize,
) -> Result<ContactRun, ReportError> {
    let duration = scene.duration(quick);
    let steps = (duration / dt).round() as usize;
    let mut times = Vec::new();
    let mut result = None;
    for _ in 0..repeats.max(1) {
        let mut world = build_world(scene, dt, solvers)?;
        let e0 = world.total_energy();
        let initial: Vec<DVector<f64>> =
            (0..world.multibody_count()).map(|i| world.multibody(i).state.q.clone()).collect();
        let (mut penetration, mut drift, mut closure): (f64, f64, f64) = (0.0, 0.0, 0.0);
        let mut apexes = Vec::new();
        let (mut rising, mut last_z) = (false, f64::NAN);
        let sample_every = ((0.01 / dt).round() as usize).max(1);
        let start = Instant::now();
        for step in 1..=steps {
            penetration = penetration.max(world.step()?.max_penetration);
            match scene {
                ContactScene::BouncingBall => {
                    let s = &world.multibody(0).state;
                    let (z, vz) = (s.q[2], s.v[2]);
                    if vz > 0.0 {
                        rising = true;
                    } else if rising {
                        apexes.push(last_z.max(z) - 0.05);
                        rising = false;
                    }
                    last_z = z;
                }
                ContactScene::Stack10 => {
                    for (i, q0) in initial.iter().enumerate() {
                        let q = &world.multibody(i).state.q;
                        drift = drift.max(
                            ((q[0] - q0[0]).powi(2) + (q[1] - q0[1]).powi(2) + (q[2] - q0[2]).powi(2)).sqrt(),
                        );
                    }
                }
                ContactScene::FourBar if step % sample_every == 0 => {
                    closure = closure.max(world.constraint_violation());
                }
                _ => {}
            }
        }
        times.push(start.elapsed().as_secs_f64());
        let long = times[times.len() - 1] > LONG_RUN;
        let energy = (world.total_energy() - e0) / e0.abs().max(1e-12);
        result = Some(match scene {
            ContactScene::BouncingBall => {
                // Apex after the n-th bounce against ε²ⁿ·h (h = 1 m), n = 1, 2, 3; a bounce
                // that did not happen counts as a 100 % error.
                let mut worst: f64 = 0.0;
                for n in 1..=3 {
                    let expected = 0.8f64.powi(2 * n as i32);
                    worst = worst.max(apexes.get(n - 1).map_or(1.0, |h| (h - expected).abs() / expected));
                }
                (worst, energy, penetration)
            }
            ContactScene::SlidingBox => {
                let expected = 2.0 * 2.0 / (2.0 * 0.5 * 9.81);
                let distance = world.multibody(0).state.q[0] - initial[0][0];
                ((distance - expected).abs() / expected, energy, penetration)
            }
            ContactScene::Stack10 => (drift, energy, penetration),
            ContactScene::FourBar => (closure.max(world.constraint_violation()), energy, 0.0),
        });
        if long {
            break;
        }
    }
    let (error, energy, secondary) = result.unwrap_or((f64::NAN, f64::NAN, f64::NAN));
    Ok(ContactRun { error, energy, secondary, cost_us_per_s: median(&mut times) * 1e6 / (steps as f64 * dt) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_are_sampled_every_40_ms_or_on_their_own_grid() {
        assert_eq!(sample_interval(1e-2, 5.0), Some(SAMPLE_INTERVAL));
        assert_eq!(sample_interval(0.04 / 3.0, 5.0), Some(SAMPLE_INTERVAL));
        assert_eq!(sample_interval(0.04, 1.0), Some(SAMPLE_INTERVAL));
        assert_eq!(sample_interval(0.05, 5.0), Some(0.05));
        assert_eq!(sample_interval(1.0 / 18.0, 1.0), Some(1.0 / 18.0));
        // 30 ms divides neither 40 ms nor 5 s; 1/18 s does not divide 0.2 s.
        assert_eq!(sample_interval(0.03, 5.0), None);
        assert_eq!(sample_interval(1.0 / 18.0, 0.2), None);
    }
}
