//! The equations of motion are self-consistent on seeded random trees of every joint kind: ABA inverts RNEA, CRBA (world frame) and the body-frame mass matrix agree, CRBA is the symmetric positive definite derivative of RNEA in the acceleration, CRBA-based forward dynamics equals ABA, Jacobians are derivatives of forward kinematics, integrate and difference are inverse, and energy obeys dE/dt = vᵀτ.

use gelenk::math::{log3, Mat3};
use gelenk::model::FrameKind;
use gelenk::prelude::*;
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::f64::consts::PI;

/// Seeds of the random trees; each tree is checked at [`STATES`] random states.
const SEEDS: [u64; 6] = [1, 2, 3, 5, 8, 13];
const STATES: usize = 4;
/// Step of the finite differences along q ⊕ t v (s).
const FD_STEP: f64 = 1e-4;
/// Number of bodies (fixed ones included) of each random tree.
const BODIES: usize = 16;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Fixed,
    Hinge,
    Slider,
    Ball,
    Universal,
    Hinge2,
    Hinge2Suspension,
    Free,
    Planar,
}

const KINDS: [Kind; 9] = [
    Kind::Fixed,
    Kind::Hinge,
    Kind::Slider,
    Kind::Ball,
    Kind::Universal,
    Kind::Hinge2,
    Kind::Hinge2Suspension,
    Kind::Free,
    Kind::Planar,
];

fn r(rng: &mut StdRng, lo: f64, hi: f64) -> f64 {
    rng.random_range(lo..hi)
}

/// A random unit vector.
fn unit(rng: &mut StdRng) -> Vec3 {
    loop {
        let v = Vec3::new(r(rng, -1.0, 1.0), r(rng, -1.0, 1.0), r(rng, -1.0, 1.0));
        let n = v.norm();
        if n > 0.2 && n <= 1.0 {
            return v / n;
        }
    }
}

/// Two random unit vectors at least ~17° from parallel.
fn two_axes(rng: &mut StdRng) -> (Vec3, Vec3) {
    let a1 = unit(rng);
    loop {
        let a2 = unit(rng);
        if a1.cross(&a2).norm() > 0.3 {
            return (a1, a2);
        }
    }
}

fn random_joint(kind: Kind, rng: &mut StdRng) -> Joint {
    // Axes are scaled by a random factor: the builder must normalize them.
    let scale = r(rng, 0.5, 2.0);
    match kind {
        Kind::Fixed => Joint::Fixed,
        Kind::Hinge => Joint::hinge(unit(rng) * scale),
        Kind::Slider => Joint::slider(unit(rng) * scale),
        Kind::Ball => Joint::Ball,
        Kind::Universal => {
            let (axis1, axis2) = two_axes(rng);
            Joint::Universal { axis1: axis1 * scale, axis2 }
        }
        Kind::Hinge2 => {
            let (axis1, axis2) = two_axes(rng);
            Joint::Hinge2 { axis1, axis2: axis2 * scale, suspension: None }
        }
        Kind::Hinge2Suspension => {
            let (axis1, axis2) = two_axes(rng);
            Joint::Hinge2 { axis1, axis2, suspension: Some(Suspension { stiffness: 1000.0, damping: 0.0 }) }
        }
        Kind::Free => Joint::Free,
        Kind::Planar => Joint::Planar,
    }
}

fn random_rotation(rng: &mut StdRng) -> Mat3 {
    Transform::from_xyz_rpy([0.0; 3], [r(rng, -PI, PI), r(rng, -PI / 2.0, PI / 2.0), r(rng, -PI, PI)])
        .rotation
}

/// A random tree holding every joint kind at least once, and the total mass of its moving bodies
/// (bodies welded to the universe through fixed joints excluded).
fn random_tree(seed: u64) -> (Model, f64) {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut kinds: Vec<Kind> = KINDS.to_vec();
    while kinds.len() < BODIES {
        kinds.push(KINDS[rng.random_range(0..KINDS.len())]);
    }
    for i in (1..kinds.len()).rev() {
        let j = rng.random_range(0..=i);
        kinds.swap(i, j);
    }
    let mut names = vec!["universe".to_string()];
    let mut welded_to_world = vec![true];
    let mut moving_mass = 0.0;
    let mut builder = ModelBuilder::new();
    builder.name(format!("random_{seed}"));
    for (k, &kind) in kinds.iter().enumerate() {
        let p = rng.random_range(0..names.len());
        let name = format!("body{k}");
        let xyz = [r(&mut rng, -0.5, 0.5), r(&mut rng, -0.5, 0.5), r(&mut rng, -0.5, 0.5)];
        let rpy = [r(&mut rng, -PI, PI), r(&mut rng, -1.5, 1.5), r(&mut rng, -PI, PI)];
        let placement = Transform::from_xyz_rpy(xyz, rpy);
        let mass = r(&mut rng, 0.5, 2.0);
        let size = Vec3::new(r(&mut rng, 0.05, 0.5), r(&mut rng, 0.05, 0.5), r(&mut rng, 0.05, 0.5));
        let rot = random_rotation(&mut rng);
        let com = Vec3::new(r(&mut rng, -0.2, 0.2), r(&mut rng, -0.2, 0.2), r(&mut rng, -0.2, 0.2));
        let inertia = RigidInertia::new(
            mass,
            com,
            rot * RigidInertia::solid_box(mass, size).inertia_com * rot.transpose(),
        );
        let joint = random_joint(kind, &mut rng);
        let welded = kind == Kind::Fixed && welded_to_world[p];
        if !welded {
            moving_mass += mass;
        }
        welded_to_world.push(welded);
        builder.add_body(
            BodySpec::new(name.clone(), names[p].clone(), joint, placement, inertia)
                .with_joint_name(format!("joint{k}")),
        );
        names.push(name);
    }
    let model = builder.build().expect("a random tree of valid bodies builds");
    (model, moving_mass)
}

fn uniform(rng: &mut StdRng, n: usize) -> DVector<f64> {
    DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0))
}

/// One random state: q, v, a, tau.
type Inputs = (DVector<f64>, DVector<f64>, DVector<f64>, DVector<f64>);

/// Every (seed, model, random state) to check: q random, v, a, tau uniform in [-1, 1].
struct Case {
    seed: u64,
    model: Model,
    moving_mass: f64,
    states: Vec<Inputs>,
}

fn cases() -> Vec<Case> {
    SEEDS
        .iter()
        .map(|&seed| {
            let (model, moving_mass) = random_tree(seed);
            let mut rng = StdRng::seed_from_u64(seed ^ 0x5eed);
            let states = (0..STATES)
                .map(|_| {
                    let q = model.random_configuration(&mut rng);
                    let v = uniform(&mut rng, model.nv());
                    let a = uniform(&mut rng, model.nv());
                    let tau = uniform(&mut rng, model.nv());
                    (q, v, a, tau)
                })
                .collect();
            Case { seed, model, moving_mass, states }
        })
        .collect()
}

fn max_abs(x: &DVector<f64>) -> f64 {
    x.amax()
}

#[test]
fn random_trees_contain_every_joint_kind_and_fuse_fixed_ones() {
    for c in cases() {
        let m = &c.model;
        let kinds: Vec<&str> = (1..m.nbodies()).map(|i| m.joint(i).kind_name()).collect();
        for k in ["hinge", "slider", "ball", "universal", "hinge2", "free", "planar"] {
            assert!(kinds.contains(&k), "seed {}: no {k} joint in {kinds:?}", c.seed);
        }
        assert!(!kinds.contains(&"fixed"), "seed {}: a fixed joint was not fused", c.seed);
        let with_suspension =
            (1..m.nbodies()).any(|i| matches!(m.joint(i), Joint::Hinge2 { suspension: Some(_), .. }));
        assert!(with_suspension, "seed {}: no hinge2 with suspension", c.seed);
        // Every body and joint stays addressable as a frame, fused or not.
        for k in 0..BODIES {
            assert!(m.frame_id(&format!("body{k}")).is_some(), "seed {}: body{k} has no frame", c.seed);
            assert!(m.frame_id(&format!("joint{k}")).is_some(), "seed {}: joint{k} has no frame", c.seed);
        }
        let nq: usize = (1..m.nbodies()).map(|i| m.joint(i).nq()).sum();
        let nv: usize = (1..m.nbodies()).map(|i| m.joint(i).nv()).sum();
        assert_eq!((m.nq(), m.nv()), (nq, nv), "seed {}", c.seed);
        assert!(m.nbodies() - 1 < BODIES, "seed {}: at least one fixed body must have been fused", c.seed);
    }
}

#[test]
fn aba_inverts_rnea() {
    for c in cases() {
        let mut data = Data::new(&c.model);
        for (k, (q, v, a, _)) in c.states.iter().enumerate() {
            let tau = rnea(&c.model, &mut data, q, v, a).unwrap().clone();
            let a2 = aba(&c.model, &mut data, q, v, &tau).unwrap().clone();
            let err = max_abs(&(&a2 - a)) / (1.0 + max_abs(a));
            assert!(err < 1e-8, "seed {} state {k}: aba(rnea(a)) differs from a by {err:e}", c.seed);
            // and the other way round
            let a3 = aba(&c.model, &mut data, q, v, &c.states[k].3).unwrap().clone();
            let tau3 = rnea(&c.model, &mut data, q, v, &a3).unwrap().clone();
            let err = max_abs(&(&tau3 - &c.states[k].3)) / (1.0 + max_abs(&c.states[k].3));
            assert!(err < 1e-8, "seed {} state {k}: rnea(aba(tau)) differs from tau by {err:e}", c.seed);
        }
    }
}

#[test]
fn mass_matrix_is_symmetric_positive_definite() {
    for c in cases() {
        let mut data = Data::new(&c.model);
        for (k, (q, ..)) in c.states.iter().enumerate() {
            let m = crba(&c.model, &mut data, q).unwrap().clone();
            assert_eq!(m.shape(), (c.model.nv(), c.model.nv()));
            let asym = (&m - m.transpose()).amax();
            assert!(asym <= 1e-12 * m.amax(), "seed {} state {k}: M not symmetric ({asym:e})", c.seed);
            assert!(m.clone().cholesky().is_some(), "seed {} state {k}: Cholesky of M fails", c.seed);
            let eig = m.clone().symmetric_eigenvalues();
            let (lo, hi) = (eig.min(), eig.max());
            assert!(
                lo > 1e-10 * hi,
                "seed {} state {k}: smallest eigenvalue {lo:e} (largest {hi:e})",
                c.seed
            );
        }
    }
}

/// The body-frame mass matrix equals the world-frame CRBA's on many more random trees (every
/// joint kind in each), symmetric to the bit, whatever the workspace held before.
#[test]
fn mass_matrix_in_body_frames_equals_crba() {
    for seed in 100..160 {
        let (model, _) = random_tree(seed);
        let mut rng = StdRng::seed_from_u64(seed);
        let (mut data, mut reused) = (Data::new(&model), Data::new(&model));
        for k in 0..4 {
            let q = model.random_configuration(&mut rng);
            let world = crba(&model, &mut data, &q).unwrap().clone();
            let local = mass_matrix(&model, &mut reused, &q).unwrap();
            let err = (local - &world).amax();
            assert!(err <= 1e-12 * world.amax(), "seed {seed} state {k}: differs from crba by {err:e}");
            assert_eq!(local, &local.transpose(), "seed {seed} state {k}: not symmetric to the bit");
        }
    }
}

#[test]
fn crba_columns_are_rnea_differences() {
    for c in cases() {
        let model = &c.model;
        let nv = model.nv();
        let mut data = Data::new(model);
        let zero = DVector::zeros(nv);
        for (k, (q, ..)) in c.states.iter().enumerate() {
            let m = crba(model, &mut data, q).unwrap().clone();
            let g = rnea(model, &mut data, q, &zero, &zero).unwrap().clone();
            for col in 0..nv {
                let mut e = DVector::zeros(nv);
                e[col] = 1.0;
                let t = rnea(model, &mut data, q, &zero, &e).unwrap().clone();
                let diff = &t - &g;
                let err = max_abs(&(&diff - m.column(col)));
                assert!(
                    err <= 1e-10 * (1.0 + m.amax()),
                    "seed {} state {k}: column {col} of M differs from rnea(q, 0, e) - rnea(q, 0, 0) by {err:e}",
                    c.seed
                );
            }
        }
    }
}

#[test]
fn forward_dynamics_crba_equals_aba() {
    for c in cases() {
        let mut data = Data::new(&c.model);
        for (k, (q, v, _, tau)) in c.states.iter().enumerate() {
            let a1 = aba(&c.model, &mut data, q, v, tau).unwrap().clone();
            let a2 = forward_dynamics_crba(&c.model, &mut data, q, v, tau).unwrap().clone();
            let err = max_abs(&(&a1 - &a2)) / (1.0 + max_abs(&a1));
            assert!(err < 1e-9, "seed {} state {k}: ABA and CRBA forward dynamics differ by {err:e}", c.seed);
            // M a + nle = tau
            let m = data.mass_matrix.clone();
            let nle = nonlinear_effects(&c.model, &mut data, q, v).unwrap().clone();
            let err = max_abs(&(&m * &a1 + &nle - tau)) / (1.0 + max_abs(tau));
            assert!(err < 1e-9, "seed {} state {k}: M a + nle - tau = {err:e}", c.seed);
        }
    }
}

#[test]
fn nonlinear_effects_and_gravity_are_rnea_with_zero_inputs() {
    for c in cases() {
        let model = &c.model;
        let mut data = Data::new(model);
        let zero = DVector::zeros(model.nv());
        for (k, (q, v, ..)) in c.states.iter().enumerate() {
            let nle = nonlinear_effects(model, &mut data, q, v).unwrap().clone();
            let want = rnea(model, &mut data, q, v, &zero).unwrap().clone();
            assert!(
                max_abs(&(&nle - &want)) <= 1e-12 * (1.0 + max_abs(&want)),
                "seed {} state {k}: nle",
                c.seed
            );
            let g = generalized_gravity(model, &mut data, q).unwrap().clone();
            let want = rnea(model, &mut data, q, &zero, &zero).unwrap().clone();
            assert!(
                max_abs(&(&g - &want)) <= 1e-12 * (1.0 + max_abs(&want)),
                "seed {} state {k}: gravity",
                c.seed
            );
            assert!(max_abs(&g) > 1e-3, "seed {} state {k}: gravity unexpectedly zero", c.seed);
            // Without gravity, g(q) vanishes and nle is purely velocity dependent (quadratic in v).
            let mut weightless = model.clone();
            weightless.set_gravity(Vec3::zeros());
            let mut d2 = Data::new(&weightless);
            assert!(max_abs(generalized_gravity(&weightless, &mut d2, q).unwrap()) < 1e-14);
            let c1 = nonlinear_effects(&weightless, &mut d2, q, v).unwrap().clone();
            let v2 = v * 2.0;
            let c2 = nonlinear_effects(&weightless, &mut d2, q, &v2).unwrap().clone();
            let err = max_abs(&(&c2 - &c1 * 4.0));
            assert!(
                err <= 1e-10 * (1.0 + max_abs(&c2)),
                "seed {} state {k}: C(q, 2v) 2v != 4 C(q, v) v",
                c.seed
            );
        }
    }
}

/// Configurations equal joint by joint, quaternions up to sign.
fn assert_same_configuration(model: &Model, got: &DVector<f64>, want: &DVector<f64>, tol: f64, what: &str) {
    for i in 1..model.nbodies() {
        let j = model.joint(i);
        let (iq, nq) = (model.idx_q(i), j.nq());
        let quat = match j {
            Joint::Ball => Some(iq..iq + 4),
            Joint::Free => Some(iq + 3..iq + 7),
            _ => None,
        };
        let mut g = got.rows(iq, nq).clone_owned();
        let w = want.rows(iq, nq);
        if let Some(range) = quat {
            let (a, b) = (range.start - iq, range.end - iq);
            let dot: f64 = (a..b).map(|k| g[k] * w[k]).sum();
            if dot < 0.0 {
                for k in a..b {
                    g[k] = -g[k];
                }
            }
        }
        let err = (&g - w).amax();
        assert!(
            err <= tol,
            "{what}: joint {} ({}) differs by {err:e}: {g:?} vs {w:?}",
            model.joint_name(i),
            j.kind_name()
        );
    }
}

#[test]
fn integrate_and_difference_are_inverse() {
    for c in cases() {
        let model = &c.model;
        let mut rng = StdRng::seed_from_u64(c.seed + 100);
        let (nq, nv) = (model.nq(), model.nv());
        let mut q1 = DVector::zeros(nq);
        let mut q2 = DVector::zeros(nq);
        let mut d = DVector::zeros(nv);
        for (k, (q0, v, ..)) in c.states.iter().enumerate() {
            let dt = r(&mut rng, 0.05, 1.0);
            model.integrate(q0, v, dt, &mut q1);
            model.difference(q0, &q1, &mut d);
            let err = max_abs(&(&d - v * dt));
            assert!(err < 1e-10, "seed {} state {k}: difference(q0, q0 + v dt) - v dt = {err:e}", c.seed);

            model.difference(q0, q0, &mut d);
            assert!(max_abs(&d) < 1e-12, "seed {} state {k}: difference(q, q) != 0", c.seed);

            let target = model.random_configuration(&mut rng);
            model.difference(q0, &target, &mut d);
            model.integrate(q0, &d, 1.0, &mut q2);
            assert_same_configuration(model, &q2, &target, 1e-9, &format!("seed {} state {k}", c.seed));

            // integrating in two halves equals integrating at once (constant velocity)
            model.integrate(q0, v, 0.5 * dt, &mut q2);
            let half = q2.clone();
            model.integrate(&half, v, 0.5 * dt, &mut q2);
            assert_same_configuration(model, &q2, &q1, 1e-12, &format!("seed {} state {k} halves", c.seed));
        }
    }
}

/// Central-difference velocity of a frame along `q ⊕ t v` at t = 0, as a Local motion `[v; ω]`.
fn frame_velocity_fd(
    model: &Model,
    data: &mut Data,
    q: &DVector<f64>,
    v: &DVector<f64>,
    frame: usize,
) -> (Vec3, Vec3) {
    forward_kinematics(model, data, q).unwrap();
    let x0 = frame_placement(model, data, frame).unwrap();
    let mut central = |h: f64| {
        let mut qp = q.clone();
        let mut qm = q.clone();
        model.integrate(q, v, h, &mut qp);
        model.integrate(q, v, -h, &mut qm);
        forward_kinematics(model, data, &qp).unwrap();
        let xp = frame_placement(model, data, frame).unwrap();
        forward_kinematics(model, data, &qm).unwrap();
        let xm = frame_placement(model, data, frame).unwrap();
        let lin_world = (xp.translation - xm.translation) / (2.0 * h);
        let ang_local = (log3(&(x0.rotation.transpose() * xp.rotation))
            - log3(&(x0.rotation.transpose() * xm.rotation)))
            / (2.0 * h);
        (x0.rotation.transpose() * lin_world, ang_local)
    };
    // Richardson extrapolation of two central differences: error O(h⁴).
    let (h, small) = (central(FD_STEP), central(FD_STEP / 2.0));
    ((small.0 * 4.0 - h.0) / 3.0, (small.1 * 4.0 - h.1) / 3.0)
}

#[test]
fn frame_jacobians_are_derivatives_of_kinematics() {
    for c in cases() {
        let model = &c.model;
        let mut data = Data::new(model);
        for (k, (q, v, ..)) in c.states.iter().enumerate().take(2) {
            for f in 0..model.frames().len() {
                let (lin, ang) = frame_velocity_fd(model, &mut data, q, v, f);
                forward_kinematics(model, &mut data, q).unwrap();
                let x = frame_placement(model, &data, f).unwrap();
                compute_joint_jacobians(model, &mut data, q).unwrap();
                let local = frame_jacobian(model, &mut data, f, JacobianFrame::Local).unwrap() * v;
                let aligned =
                    frame_jacobian(model, &mut data, f, JacobianFrame::LocalWorldAligned).unwrap() * v;
                let world = frame_jacobian(model, &mut data, f, JacobianFrame::World).unwrap() * v;
                let scale = 1.0 + lin.norm() + ang.norm();
                let name = &model.frames()[f].name;
                let ctx = format!("seed {} state {k} frame {f} `{name}`", c.seed);

                let fd = DVector::from_iterator(6, lin.iter().chain(ang.iter()).copied());
                let err = max_abs(&(&local - &fd));
                assert!(err < 1e-7 * scale, "{ctx}: Local J v differs from finite differences by {err:e}\n J v = {local:?}\n fd  = {fd:?}");

                // LocalWorldAligned: the same vectors in world axes.
                let (lw, aw) = (x.rotation * lin, x.rotation * ang);
                let want = DVector::from_iterator(6, lw.iter().chain(aw.iter()).copied());
                let err = max_abs(&(&aligned - &want));
                assert!(err < 1e-7 * scale, "{ctx}: LocalWorldAligned J v inconsistent ({err:e})");

                // World: spatial velocity about the world origin, v_O = v_p + p × ω.
                let vo = lw + x.translation.cross(&aw);
                let want = DVector::from_iterator(6, vo.iter().chain(aw.iter()).copied());
                let err = max_abs(&(&world - &want));
                assert!(
                    err < 1e-7 * (scale + x.translation.norm() * ang.norm()),
                    "{ctx}: World J v inconsistent ({err:e})"
                );

                // Columns of dofs that do not move the frame are zero, and exactly so.
                if model.frames()[f].body == 0 {
                    assert_eq!(data.jacobian.amax(), 0.0, "{ctx}: a frame fixed to the world has a Jacobian");
                }
            }
        }
    }
}

#[test]
fn jacobian_of_a_body_frame_equals_its_spatial_velocity() {
    // J_local(body i) v is the body's spatial velocity that RNEA/ABA propagate in data.v.
    for c in cases() {
        let model = &c.model;
        let mut data = Data::new(model);
        let (q, v, ..) = &c.states[0];
        compute_joint_jacobians(model, &mut data, q).unwrap();
        let mut jv = Vec::new();
        for i in 1..model.nbodies() {
            let f = model
                .frames()
                .iter()
                .position(|fr| fr.body == i && fr.kind == FrameKind::Joint && fr.name == model.joint_name(i))
                .unwrap();
            jv.push(frame_jacobian(model, &mut data, f, JacobianFrame::Local).unwrap() * v);
        }
        let _ = kinetic_energy(model, &mut data, q, v).unwrap();
        for i in 1..model.nbodies() {
            let want = data.v[i].to_vector();
            let got = &jv[i - 1];
            let err = (0..6).map(|r| (got[r] - want[r]).abs()).fold(0.0, f64::max);
            assert!(
                err < 1e-12 * (1.0 + want.amax()),
                "seed {} body {i}: J v != body velocity ({err:e})",
                c.seed
            );
        }
    }
}

fn energy(model: &Model, data: &mut Data, q: &DVector<f64>, v: &DVector<f64>) -> (f64, f64) {
    (kinetic_energy(model, data, q, v).unwrap(), potential_energy(model, data, q).unwrap())
}

/// d/dt of kinetic and potential energy along the state curve with tangent (v, a), by central
/// differences.
fn energy_rates(
    model: &Model,
    data: &mut Data,
    q: &DVector<f64>,
    v: &DVector<f64>,
    a: &DVector<f64>,
) -> (f64, f64) {
    let mut central = |h: f64| {
        let mut qp = q.clone();
        let mut qm = q.clone();
        model.integrate(q, v, h, &mut qp);
        model.integrate(q, v, -h, &mut qm);
        let (kp, pp) = energy(model, data, &qp, &(v + a * h));
        let (km, pm) = energy(model, data, &qm, &(v - a * h));
        ((kp - km) / (2.0 * h), (pp - pm) / (2.0 * h))
    };
    // Richardson extrapolation of two central differences: error O(h⁴).
    let (h, small) = (central(FD_STEP), central(FD_STEP / 2.0));
    ((small.0 * 4.0 - h.0) / 3.0, (small.1 * 4.0 - h.1) / 3.0)
}

#[test]
fn power_balance_holds_along_the_motion() {
    for c in cases() {
        let model = &c.model;
        let mut data = Data::new(model);
        let zero = DVector::zeros(model.nv());
        for (k, (q, v, _, tau)) in c.states.iter().enumerate() {
            for (label, t) in [("tau = 0", &zero), ("random tau", tau)] {
                let a = aba(model, &mut data, q, v, t).unwrap().clone();
                let (dk, dp) = energy_rates(model, &mut data, q, v, &a);
                let power = v.dot(t);
                let err = (dk + dp - power).abs();
                let scale = 1.0 + dk.abs() + dp.abs();
                assert!(
                    err < 1e-6 * scale,
                    "seed {} state {k} ({label}): dKE/dt = {dk}, dPE/dt = {dp}, v·tau = {power}, error {err:e}",
                    c.seed
                );
                assert!(
                    dk.abs() + dp.abs() > 1e-3,
                    "seed {} state {k}: the energy does not change at all",
                    c.seed
                );
            }
        }
    }
}

#[test]
fn generalized_gravity_is_the_gradient_of_potential_energy() {
    for c in cases() {
        let model = &c.model;
        let mut data = Data::new(model);
        let zero = DVector::zeros(model.nv());
        for (k, (q, v, ..)) in c.states.iter().enumerate() {
            let g = generalized_gravity(model, &mut data, q).unwrap().clone();
            let (_, dp) = energy_rates(model, &mut data, q, v, &zero);
            let want = g.dot(v);
            assert!(
                (dp - want).abs() < 1e-6 * (1.0 + want.abs()),
                "seed {} state {k}: dPE/dt {dp} vs g·v {want}",
                c.seed
            );
        }
    }
}

#[test]
fn kinetic_energy_is_half_v_m_v() {
    for c in cases() {
        let model = &c.model;
        let mut data = Data::new(model);
        for (k, (q, v, ..)) in c.states.iter().enumerate() {
            let m = crba(model, &mut data, q).unwrap().clone();
            let want = 0.5 * v.dot(&(&m * v));
            let ke = kinetic_energy(model, &mut data, q, v).unwrap();
            assert!(
                (ke - want).abs() <= 1e-12 * (1.0 + want.abs()),
                "seed {} state {k}: KE {ke} vs ½vᵀMv {want}",
                c.seed
            );
            assert!(ke > 0.0);
            assert_eq!(data.kinetic_energy, ke);
            // quadratic in v
            let ke3 = kinetic_energy(model, &mut data, q, &(v * 3.0)).unwrap();
            assert!((ke3 - 9.0 * ke).abs() <= 1e-12 * ke3, "seed {} state {k}: KE not quadratic", c.seed);
        }
    }
}

#[test]
fn center_of_mass_and_potential_energy_agree_with_total_mass() {
    for c in cases() {
        let model = &c.model;
        let mut data = Data::new(model);
        let total = model.total_mass();
        assert!(
            (total - c.moving_mass).abs() < 1e-12 * c.moving_mass,
            "seed {}: total mass {total} but the moving bodies weigh {}",
            c.seed,
            c.moving_mass
        );
        let welded = model.inertia(0).mass;
        assert!(
            (model.subtree_mass(0) - total - welded).abs() < 1e-12 * total,
            "seed {}: subtree mass",
            c.seed
        );
        for (k, (q, ..)) in c.states.iter().enumerate() {
            let com = center_of_mass(model, &mut data, q).unwrap();
            let pe = potential_energy(model, &mut data, q).unwrap();
            let want = -total * model.gravity().dot(&com);
            assert!(
                (pe - want).abs() < 1e-10 * (1.0 + want.abs()),
                "seed {} state {k}: PE {pe} vs -m g·com {want}",
                c.seed
            );
            // The centre of mass is the mass-weighted mean of the bodies' centres of mass.
            forward_kinematics(model, &mut data, q).unwrap();
            let mut first = Vec3::zeros();
            for i in 1..model.nbodies() {
                let inertia = model.inertia(i);
                first += data.x_wb[i].act_point(&inertia.com()) * inertia.mass;
            }
            let err = (com - first / total).norm();
            assert!(err < 1e-12 * (1.0 + com.norm()), "seed {} state {k}: com off by {err:e}", c.seed);
            // Under uniform gravity along x, g(q) for the whole model is still -∂PE: checked above;
            // here: with gravity scaled by 2, the gravity torques double.
            let g1 = generalized_gravity(model, &mut data, q).unwrap().clone();
            let mut heavy = model.clone();
            heavy.set_gravity(model.gravity() * 2.0);
            let mut d2 = Data::new(&heavy);
            let g2 = generalized_gravity(&heavy, &mut d2, q).unwrap().clone();
            assert!(max_abs(&(&g2 - &g1 * 2.0)) < 1e-12 * (1.0 + max_abs(&g2)));
        }
    }
}

#[test]
fn mass_matrix_equals_sum_of_body_jacobian_quadratic_forms() {
    // M = Σ_i J_iᵀ I_i J_i with J_i the Local Jacobian of body i.
    for c in cases().into_iter().take(3) {
        let model = &c.model;
        let mut data = Data::new(model);
        let (q, ..) = &c.states[1];
        compute_joint_jacobians(model, &mut data, q).unwrap();
        let mut sum = DMatrix::zeros(model.nv(), model.nv());
        for i in 1..model.nbodies() {
            let f = model
                .frames()
                .iter()
                .position(|fr| fr.body == i && fr.kind == FrameKind::Joint && fr.name == model.joint_name(i))
                .unwrap();
            let j = frame_jacobian(model, &mut data, f, JacobianFrame::Local).unwrap().clone();
            let inertia = DMatrix::from_column_slice(6, 6, model.inertia(i).to_matrix().as_slice());
            sum += j.transpose() * inertia * &j;
        }
        let m = crba(model, &mut data, q).unwrap();
        let err = (&sum - m).amax();
        assert!(err < 1e-10 * (1.0 + m.amax()), "seed {}: M differs from Σ JᵀIJ by {err:e}", c.seed);
    }
}
