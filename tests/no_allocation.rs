//! After `Data::new`, the success paths of the dynamics algorithms (kinematics, RNEA, CRBA, ABA, CRBA forward dynamics, energies, centre of mass, Jacobians) perform zero heap allocations, on solo12 with a floating base and on a tree with every joint kind.

mod common;

use gelenk::io::urdf::{load_file, UrdfOptions};
use gelenk::prelude::*;
use nalgebra::DVector;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

#[path = "common/counting_allocator.rs"]
mod counting_allocator;
use counting_allocator::allocations_in;

/// A tree with every joint kind, fixed joints (fused) included.
fn all_joints_model() -> Model {
    let inertia = |m: f64| {
        let r = Transform::from_xyz_rpy([0.0; 3], [0.3 * m, -0.2, 0.7]).rotation;
        let b = RigidInertia::solid_box(m, Vec3::new(0.2, 0.3 * m, 0.15));
        RigidInertia::new(m, Vec3::new(0.05, -0.02, 0.1), r * b.inertia_com * r.transpose())
    };
    let at = |x: f64, y: f64, z: f64| Transform::from_xyz_rpy([x, y, z], [0.1, -0.3, 0.5]);
    let bodies = [
        ("trunk", "universe", Joint::Free),
        ("neck", "trunk", Joint::Ball),
        ("head", "neck", Joint::Fixed),
        ("shoulder", "trunk", Joint::Universal { axis1: Vec3::x(), axis2: Vec3::new(0.0, 1.0, 0.2) }),
        ("elbow", "shoulder", Joint::hinge(Vec3::new(0.0, 0.0, 1.0))),
        ("piston", "elbow", Joint::slider(Vec3::new(1.0, 1.0, 0.0))),
        ("wheel", "trunk", Joint::Hinge2 { axis1: Vec3::z(), axis2: Vec3::y(), suspension: None }),
        (
            "sprung_wheel",
            "trunk",
            Joint::Hinge2 {
                axis1: Vec3::z(),
                axis2: Vec3::x(),
                suspension: Some(Suspension { stiffness: 1e4, damping: 50.0 }),
            },
        ),
        ("sled", "universe", Joint::Planar),
        ("sensor", "sled", Joint::Fixed),
        ("flap", "sensor", Joint::hinge(Vec3::y())),
    ];
    let mut builder = ModelBuilder::new();
    for (k, (name, parent, joint)) in bodies.into_iter().enumerate() {
        let x = 0.1 * k as f64;
        builder.add_body(
            BodySpec::new(name, parent, joint, at(x, -x, 0.2), inertia(0.5 + 0.1 * k as f64))
                .with_joint_name(format!("{name}_joint")),
        );
    }
    builder.build().unwrap()
}

/// One state: q, v, a, tau.
type Inputs = (DVector<f64>, DVector<f64>, DVector<f64>, DVector<f64>);

/// Runs every algorithm once at (q, v, a, tau), `integrate`/`difference` writing into `out`;
/// returns a checksum so nothing is optimized away.
fn run_all(
    model: &Model,
    data: &mut Data,
    (q, v, a, tau): &Inputs,
    frames: &[usize],
    (q_out, v_out): (&mut DVector<f64>, &mut DVector<f64>),
) -> f64 {
    let mut sum = 0.0;
    forward_kinematics(model, data, q).unwrap();
    for &f in frames {
        sum += frame_placement(model, data, f).unwrap().translation.x;
    }
    sum += rnea(model, data, q, v, a).unwrap()[0];
    sum += nonlinear_effects(model, data, q, v).unwrap()[0];
    sum += generalized_gravity(model, data, q).unwrap()[0];
    sum += crba(model, data, q).unwrap()[(0, 0)];
    sum += mass_matrix(model, data, q).unwrap()[(0, 0)];
    sum += aba(model, data, q, v, tau).unwrap()[0];
    sum += forward_dynamics_crba(model, data, q, v, tau).unwrap()[0];
    sum += kinetic_energy(model, data, q, v).unwrap();
    sum += potential_energy(model, data, q).unwrap();
    sum += center_of_mass(model, data, q).unwrap().z;
    compute_joint_jacobians(model, data, q).unwrap();
    for &f in frames {
        for which in [JacobianFrame::Local, JacobianFrame::LocalWorldAligned, JacobianFrame::World] {
            sum += frame_jacobian(model, data, f, which).unwrap()[(5, 0)];
        }
    }
    model.integrate(q, v, 1e-3, q_out);
    model.difference(q, q_out, v_out);
    model.normalize(q_out);
    sum + v_out[0]
}

#[test]
fn algorithms_do_not_allocate_after_data_new() {
    // The counter sees this thread's allocations: check that it works at all.
    let (n, vec) = allocations_in(|| vec![1.0f64; 16]);
    assert!(n >= 1, "the counting allocator missed an allocation");
    drop(vec);
    let (n, ()) = allocations_in(|| ());
    assert_eq!(n, 0);

    let solo = load_file(common::models_dir().join("solo12.urdf"), &UrdfOptions::floating()).unwrap();
    assert_eq!((solo.nq(), solo.nv()), (19, 18));
    let tree = all_joints_model();
    for i in 1..tree.nbodies() {
        assert_ne!(tree.joint(i).kind_name(), "fixed");
    }
    for kind in ["free", "ball", "universal", "hinge", "slider", "hinge2", "planar"] {
        assert!((1..tree.nbodies()).any(|i| tree.joint(i).kind_name() == kind), "no {kind} joint");
    }

    for (label, model) in [("solo12 floating", &solo), ("all joint kinds", &tree)] {
        let mut rng = StdRng::seed_from_u64(7);
        let frames: Vec<usize> = (0..model.frames().len()).collect();
        let mut data = Data::new(model);
        let mut q_out = DVector::zeros(model.nq());
        let mut v_out = DVector::zeros(model.nv());
        let states: Vec<Inputs> = (0..5)
            .map(|_| {
                let q = model.random_configuration(&mut rng);
                let mut u = || DVector::from_fn(model.nv(), |_, _| rng.random_range(-1.0..1.0));
                (q, u(), u(), u())
            })
            .collect();
        let mut checksum = 0.0;
        for (k, state) in states.iter().enumerate() {
            let (n, s) =
                allocations_in(|| run_all(model, &mut data, state, &frames, (&mut q_out, &mut v_out)));
            assert_eq!(n, 0, "{label}, state {k}: the algorithms made {n} heap allocations after Data::new");
            assert!(s.is_finite(), "{label}: non-finite results");
            checksum += s;
        }
        assert!(checksum.is_finite());
        // one algorithm at a time, so that a failure names the culprit
        let (q, v, a, tau) = &states[0];
        let check = |what: &str, n: usize| assert_eq!(n, 0, "{label}: {what} allocated {n} times");
        check("forward_kinematics", allocations_in(|| forward_kinematics(model, &mut data, q).is_ok()).0);
        check("rnea", allocations_in(|| rnea(model, &mut data, q, v, a).is_ok()).0);
        check("nonlinear_effects", allocations_in(|| nonlinear_effects(model, &mut data, q, v).is_ok()).0);
        check("generalized_gravity", allocations_in(|| generalized_gravity(model, &mut data, q).is_ok()).0);
        check("crba", allocations_in(|| crba(model, &mut data, q).is_ok()).0);
        check("mass_matrix", allocations_in(|| mass_matrix(model, &mut data, q).is_ok()).0);
        check("aba", allocations_in(|| aba(model, &mut data, q, v, tau).is_ok()).0);
        check(
            "forward_dynamics_crba",
            allocations_in(|| forward_dynamics_crba(model, &mut data, q, v, tau).is_ok()).0,
        );
        check("kinetic_energy", allocations_in(|| kinetic_energy(model, &mut data, q, v).is_ok()).0);
        check("potential_energy", allocations_in(|| potential_energy(model, &mut data, q).is_ok()).0);
        check("center_of_mass", allocations_in(|| center_of_mass(model, &mut data, q).is_ok()).0);
        check(
            "compute_joint_jacobians",
            allocations_in(|| compute_joint_jacobians(model, &mut data, q).is_ok()).0,
        );
        let f = frames.len() - 1;
        check(
            "frame_jacobian",
            allocations_in(|| frame_jacobian(model, &mut data, f, JacobianFrame::Local).is_ok()).0,
        );
    }
}
