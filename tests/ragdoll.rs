//! The ragdoll of models/ragdoll.urdf (de Leva 1996 segments, ball/hinge/universal joints with
//! anatomical limits) meets its acceptance bounds: dropped from 1 m with a random spin it comes to
//! rest within 3 s of landing, no joint opens, no limit is exceeded by more than 1°, nothing
//! penetrates more than 5 mm and the energy never grows; a pile of ragdolls stays finite, above
//! the ground and falls asleep; a pose servo (powered ragdoll) holds the pose with bounded torque.

use gelenk::collision::Attachment;
use gelenk::constraints::RowOrigin;
use gelenk::io::scene::{self, Scene};
use gelenk::model::Joint;
use std::path::{Path, PathBuf};

fn models() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("models")
}

fn scene_text(name: &str) -> String {
    std::fs::read_to_string(models().join(name)).unwrap()
}

/// The acceptance bounds.
const ONE_DEGREE: f64 = std::f64::consts::PI / 180.0;
const MAX_PENETRATION: f64 = 0.005;
const MAX_JOINT_GAP: f64 = 0.001;

/// Largest distance (m) between a joint's anchor on the parent (parent pose · joint placement)
/// and on the child (the child frame's origin) over every joint of every multibody. Joints are
/// generalized coordinates, so this is rounding-small by construction; the test pins that no
/// stabilisation or integration shortcut ever breaks it.
fn largest_joint_gap(s: &Scene) -> f64 {
    let mut worst: f64 = 0.0;
    for m in 0..s.world.multibody_count() {
        let mb = s.world.multibody(m);
        let (model, data) = (mb.model(), mb.data());
        for i in 1..model.nbodies() {
            if matches!(model.joint(i), Joint::Free) {
                continue;
            }
            let anchor = data.x_wb[model.parent(i)] * *model.placement(i);
            worst = worst.max((anchor.translation - data.x_wb[i].translation).norm());
        }
    }
    worst
}

struct Fall {
    landing: f64,
    rest: Option<f64>,
    max_penetration: f64,
    max_violation: f64,
    max_gap: f64,
    max_energy_gain: f64,
    drop_energy: f64,
}

fn fall(text: &str, seconds: f64) -> (Scene, Fall) {
    let mut s = scene::load_str(text, models()).unwrap();
    let mass: f64 = (0..s.world.multibody_count()).map(|i| s.world.multibody(i).model().total_mass()).sum();
    let drop_energy = mass * 9.81 * 1.0;
    let e0 = s.world.total_energy();
    let mut f = Fall {
        landing: f64::NAN,
        rest: None,
        max_penetration: 0.0,
        max_violation: 0.0,
        max_gap: 0.0,
        max_energy_gain: f64::NEG_INFINITY,
        drop_energy,
    };
    let steps = (seconds / s.world.options().dt).round() as usize;
    for _ in 0..steps {
        let stats = s.world.step().unwrap();
        let (t, pen) = (stats.time, stats.max_penetration);
        f.max_penetration = f.max_penetration.max(pen);
        if f.landing.is_nan() && s.world.contacts().iter().any(|c| c.body_b == Attachment::World) {
            f.landing = t;
        }
        f.max_violation = f.max_violation.max(s.world.constraint_violation());
        f.max_gap = f.max_gap.max(largest_joint_gap(&s));
        f.max_energy_gain = f.max_energy_gain.max(s.world.total_energy() - e0);
        // At rest from the last time the kinetic energy was at or above 1 % of the drop energy.
        let resting = s.world.kinetic_energy() < 0.01 * drop_energy;
        match (resting, f.rest) {
            (true, None) => f.rest = Some(t),
            (false, Some(_)) => f.rest = None,
            _ => {}
        }
    }
    (s, f)
}

#[test]
fn a_ragdoll_dropped_from_one_metre_lands_and_comes_to_rest_within_the_bounds() {
    let (s, f) = fall(&scene_text("ragdoll_fall.toml"), 5.0);
    println!(
        "landing {:.3} s, rest {:?} s, penetration {:.2} mm, limit overshoot {:.3}°, joint gap {:.1e} m, energy gain {:.3e} J",
        f.landing,
        f.rest,
        f.max_penetration * 1e3,
        f.max_violation.to_degrees(),
        f.max_gap,
        f.max_energy_gain
    );
    // Soles 1 m up: free fall takes √(2 h / g) = 0.45 s (the spin tilts the lowest point).
    assert!(f.landing > 0.3 && f.landing < 0.6, "landing at {}", f.landing);
    let rest = f.rest.expect("never came to rest");
    assert!(rest - f.landing < 3.0, "at rest {:.2} s after landing", rest - f.landing);
    assert!(f.max_gap < MAX_JOINT_GAP, "a joint opened by {} m", f.max_gap);
    assert!(f.max_violation < ONE_DEGREE, "a limit was exceeded by {}°", f.max_violation.to_degrees());
    assert!(f.max_penetration < MAX_PENETRATION, "penetration {} m", f.max_penetration);
    // Gravity's work is in the potential energy, so the total may only fall. Allowance: 0.1 % of
    // the drop energy for the integrator (semi-implicit Euler's O(h) energy error on the
    // tumbling bodies before landing).
    assert!(f.max_energy_gain < 1e-3 * f.drop_energy, "energy grew by {} J", f.max_energy_gain);
    // It ended lying on the ground: every body within a body's thickness of it.
    let lowest_origin = (1..s.world.multibody(0).model().nbodies())
        .map(|i| s.world.multibody(0).data().x_wb[i].translation.z)
        .fold(f64::INFINITY, f64::min);
    assert!(lowest_origin > 0.0 && lowest_origin < 0.2, "lowest body origin at {lowest_origin} m");
}

#[test]
fn the_ragdoll_fall_is_deterministic() {
    let run = || {
        let mut s = scene::load_str(&scene_text("ragdoll_fall.toml"), models()).unwrap();
        for _ in 0..300 {
            s.world.step().unwrap();
        }
        s.world.multibody(0).state.q.clone()
    };
    // The random spin comes from the scene's seed: two loads give bit-identical runs.
    assert_eq!(run(), run());
}

/// The pile scene with `count` ragdolls instead of 20.
fn pile_text(count: usize) -> String {
    let text = scene_text("ragdoll_pile.toml");
    assert!(text.contains("count = 20"));
    text.replace("count = 20", &format!("count = {count}"))
}

/// Steps a pile for 10 s (or until `sleep_within`, if later): finite, above the ground, and
/// with `sleep_within`, all asleep by then.
fn check_pile(text: &str, count: usize, sleep_within: Option<f64>) {
    let mut s = scene::load_str(text, models()).unwrap();
    assert_eq!(s.world.multibody_count(), count);
    let seconds = sleep_within.unwrap_or(10.0).max(10.0);
    let steps = (seconds / s.world.options().dt).round() as usize;
    let mut asleep_at = None;
    for k in 0..steps {
        // A NaN is a step error naming the joint (and the state is kept), so unwrap is the check.
        let stats = s.world.step().unwrap();
        if stats.asleep == count && asleep_at.is_none() {
            asleep_at = Some(stats.time);
        }
        if k % 25 == 0 || k + 1 == steps {
            // No body below the ground: every collider's box above z = −5 mm (the penetration bound).
            for c in s.world.collision().colliders() {
                if let Attachment::Body { .. } = c.attachment() {
                    assert!(c.aabb().0[2] > -MAX_PENETRATION, "{} at z = {}", c.name(), c.aabb().0[2]);
                }
            }
        }
    }
    for i in 0..count {
        let st = &s.world.multibody(i).state;
        assert!(st.q.iter().chain(st.v.iter()).all(|x| x.is_finite()));
    }
    if let Some(limit) = sleep_within {
        assert_eq!(
            s.world.stats().asleep,
            count,
            "not all asleep after {limit} s (first all asleep: {asleep_at:?})"
        );
        let at = asleep_at.expect("asleep at the end");
        assert!(at <= limit, "all asleep only at {at} s");
    }
    println!("{count} ragdolls: all asleep at {asleep_at:?} s");
}

/// Warm starts match rows by origin: a limit of one ragdoll must never carry another's name.
#[test]
fn the_limit_rows_of_two_ragdolls_never_share_an_origin() {
    let mut s = scene::load_str(&pile_text(2), models()).unwrap();
    let mut limit_rows = 0;
    for _ in 0..600 {
        s.world.step().unwrap();
        let mut seen = std::collections::HashSet::new();
        for origin in &s.world.problem().origins {
            if !matches!(origin, RowOrigin::Contact(_)) {
                limit_rows += 1;
                assert!(seen.insert(*origin), "{origin:?} twice");
            }
        }
    }
    assert!(limit_rows > 1000, "{limit_rows} limit rows: the test needs them");
}

#[test]
fn a_pile_of_four_ragdolls_stays_finite_and_above_ground() {
    check_pile(&pile_text(4), 4, None);
}

#[test]
fn a_pile_of_four_ragdolls_sleeps_within_ten_seconds() {
    check_pile(&pile_text(4), 4, Some(10.0));
}

/// The whole scene as shipped (the slowest test of the suite: the awake pile's steps solve ~2000
/// rows each). The shoulders' 0.5 N·m of joint friction is what lets it sleep: with joint
/// damping alone an upper arm lying on another ragdoll twists on at ~0.2 rad/s under its
/// forearm's weight (`cargo run --release --example pile_sleep -- 3 12` prints when it sleeps).
#[test]
fn a_pile_of_twenty_ragdolls_stays_finite_above_ground_and_sleeps_within_ten_seconds() {
    check_pile(&scene_text("ragdoll_pile.toml"), 20, Some(10.0));
}

/// Two other drops of the same pile, so that the criteria are not one seed's luck. Where a pile
/// comes to rest is chaotic: a change of rounding alone gives another pile, and its last creep
/// (a head or a hand turning under its joint's damping near a neutral balance, the same with
/// 1000 sweeps as with 100: the model, not the solver) sets when it sleeps. The shipped drop is
/// held to 10 s above; these two to 15 s. Seed 1 sleeps at 6.4 s; in seed 2 one head rests
/// balanced on its frictionless neck and topples as an inverted pendulum (its speed grows from
/// 0.025 rad/s at 6.5 s to 1.3 rad/s at 13.5 s) until it lies on the neck's limit, and the pile
/// sleeps at 13.8 s; seeds 3 to 5 at 6.4–8.1 s (`cargo run --release --example pile_sleep --
/// SEED 16`).
#[test]
fn the_pile_of_twenty_sleeps_within_fifteen_seconds_for_other_drops_too() {
    let text = scene_text("ragdoll_pile.toml");
    assert!(text.contains("seed = 3"));
    for seed in [1, 2] {
        check_pile(&text.replace("seed = 3", &format!("seed = {seed}")), 20, Some(15.0));
    }
}

#[test]
fn a_powered_ragdoll_holds_its_pose_with_bounded_torque() {
    let passive = scene_text("ragdoll_fall.toml");
    let powered = passive.replace(
        "self_collision = true",
        "self_collision = true\npose_servo = { gain = 10.0, max_velocity = 5.0, torque_per_kg = 6.0 }",
    );
    // Mean joint-space distance (rad) from the T-pose over the non-free joints.
    let deviation = |s: &Scene| {
        let mb = s.world.multibody(0);
        let model = mb.model();
        let target = model.neutral_configuration();
        let mut d = nalgebra::DVector::zeros(model.nv());
        model.difference(&mb.state.q, &target, &mut d);
        d.rows(6, model.nv() - 6).norm() / ((model.nv() - 6) as f64).sqrt()
    };
    // Where a ragdoll lands and how it lies is chaotic (the passive one ends 0.23–0.54 rad RMS
    // from the T-pose over five seeds): the two are compared by their means over the seeds
    // (the shipped one among them), every powered one is held to an absolute bound.
    let seeds = [1, 2, 3, 4, 7];
    let (mut limp_dev, mut strong_dev) = (0.0, 0.0);
    for seed in seeds {
        let with_seed = |text: &str| text.replace("seed = 7", &format!("seed = {seed}"));
        let limp = deviation(&fall(&with_seed(&passive), 3.0).0);
        let strong = deviation(&fall(&with_seed(&powered), 3.0).0);
        println!("seed {seed}: RMS joint deviation from the T-pose: passive {limp:.3} rad, powered {strong:.3} rad");
        // Lying on the ground the T-pose cannot always be held (the ground pushes the toes and
        // hands), and the bounded servos yield at impact.
        assert!(strong < 0.3, "seed {seed}: the powered ragdoll lost its pose: {strong} rad RMS");
        limp_dev += limp / seeds.len() as f64;
        strong_dev += strong / seeds.len() as f64;
    }
    // Measured: passive 0.395 rad, powered 0.115 rad on average (below 0.001 on seeds 2 and 3,
    // which end lying flat in the T-pose); a servo that does nothing has a ratio near 1.
    assert!(strong_dev < 0.6 * limp_dev, "powered {strong_dev} vs passive {limp_dev} (means)");
    let (mut strong, f) = fall(&powered, 3.0);
    assert!(f.max_violation < ONE_DEGREE);
    // Every motor impulse is within its dof's torque bound times the step.
    let servo = strong.world.multibody(0).pose_servo().unwrap().clone();
    let h = strong.world.options().dt;
    for _ in 0..50 {
        strong.world.step().unwrap();
        let problem = strong.world.problem();
        for (i, origin) in problem.origins.iter().enumerate() {
            if let RowOrigin::Motor(k) = origin {
                assert!(strong.world.impulses()[i].abs() <= servo.max_force[*k] * h * (1.0 + 1e-9));
            }
        }
    }
    // The bound scales with the mass a joint moves: the hips are far stronger than the wrists.
    let model = strong.world.multibody(0).model();
    let hip = model.idx_v(model.joint_id("hip_l").unwrap());
    let wrist = model.idx_v(model.joint_id("wrist_l").unwrap());
    assert!((servo.max_force[hip] - 6.0 * (10.62 + 3.2475 + 1.0275)).abs() < 1e-9);
    assert!((servo.max_force[wrist] - 6.0 * 0.4575).abs() < 1e-9);
}

/// A resting ragdoll keeps its factored mass matrix (`WorldOptions::mass_matrix_reuse`): over
/// 200 resting steps it factors on at most a tenth of them, where with the reuse off every step
/// factors. (That a step with the kept factor moves as one with a new factor, to 1e-12, is
/// `world::tests::a_kept_mass_matrix_factor_gives_the_free_motion_of_a_new_one`.)
#[test]
fn a_resting_ragdoll_keeps_its_factored_mass_matrix() {
    let load = || {
        let mut s = scene::load_file(models().join("ragdoll_fall.toml")).unwrap();
        s.world.set_sleep(gelenk::world::SleepOptions { enabled: false, ..s.world.options().sleep });
        s
    };
    let mut s = load();
    assert_eq!(s.world.options().mass_matrix_reuse, Some(1e-8));
    for _ in 0..1500 {
        s.world.step().unwrap();
    }
    let (before, builds) = (s.world.multibody(0).factorizations(), s.world.problem_builds());
    let kept_rows = s.world.contact_row_reuses();
    for _ in 0..200 {
        s.world.step().unwrap();
    }
    // The contact rows themselves are kept too (formed anew when a coordinate or contact point
    // has moved by 1e-8): measured 199 of 200.
    let kept = s.world.contact_row_reuses() - kept_rows;
    assert!(kept >= 180, "contact rows kept on {kept} of 200 resting steps");
    let factored = s.world.multibody(0).factorizations() - before;
    assert!(factored <= 20, "{factored} factorizations in 200 resting steps");
    // The constraint rows' W is kept with the factor while the rows stay (a body at rest).
    let built = s.world.problem_builds() - builds;
    assert!(built <= 20, "W built {built} times in 200 resting steps");
    // Moving the floating root keeps the factor (M does not depend on the root's pose in its
    // body-frame velocities); turning a joint by 1e-6 rad does not.
    let count = |s: &Scene| s.world.multibody(0).factorizations();
    let (model, mut state) = (s.world.multibody(0).model().clone(), s.world.multibody(0).state.clone());
    state.q[2] += 1e-3;
    s.world.multibody_mut(0).state = state.clone();
    let at = count(&s);
    s.world.step().unwrap();
    assert_eq!(count(&s), at, "a root moved by 1 mm must keep the factor");
    let elbow = (1..model.nbodies()).find(|&j| model.joint_name(j) == "elbow_l").unwrap();
    let mut state = s.world.multibody(0).state.clone();
    state.q[model.idx_q(elbow)] += 1e-6;
    s.world.multibody_mut(0).state = state;
    s.world.step().unwrap();
    assert_eq!(count(&s), at + 1, "an elbow turned by 1e-6 rad must factor again");
    let (before, builds, kept_rows) = (count(&s), s.world.problem_builds(), s.world.contact_row_reuses());
    s.world.set_mass_matrix_reuse(None);
    for _ in 0..10 {
        s.world.step().unwrap();
    }
    assert!(s.world.problem_builds() - builds >= 10, "without the reuse every step builds W");
    assert_eq!(s.world.contact_row_reuses(), kept_rows, "without the reuse every step forms its rows");
    assert_eq!(s.world.multibody(0).factorizations() - before, 10, "without the reuse every step factors");
}
