//! One frictionless contact between two free bodies: the impulse of every solver equals the
//! lecture's closed form f = −(1+ε)(N·v_rel) / (m_A⁻¹ + m_B⁻¹ + (r_A×N)ᵀ Ĵ_A⁻¹ (r_A×N) +
//! (r_B×N)ᵀ Ĵ_B⁻¹ (r_B×N)) (eq. 17 of C. Herta, "Game Physik — Simulating Physics", 2004), and the post-impact normal velocity is
//! −ε times the pre-impact one.

use gelenk::collision::{CollisionOptions, CollisionWorld, MeshOptions};
use gelenk::constraints::{
    add_contact_rows, assemble_single, ConstraintProblem, ContactParameters, FrictionModel, ProblemBuilder,
};
use gelenk::math::{axis_angle, Mat3};
use gelenk::model::Shape;
use gelenk::prelude::*;
use gelenk::solvers::{ClarabelSolver, ConstraintSolver, LemkeSolver, PgsSolver};
use nalgebra::{DVector, Vector6};

fn body(name: &str, mass: f64, size: Vec3) -> BodySpec {
    BodySpec::new(name, "universe", Joint::Free, Transform::identity(), RigidInertia::solid_box(mass, size))
        .with_collision(Shape::Box { size }, Transform::identity())
}

#[test]
fn single_contact_impulse_equals_the_closed_form() {
    let (size_a, size_b) = (Vec3::new(0.4, 0.3, 0.2), Vec3::new(1.0, 0.8, 0.5));
    let (mass_a, mass_b) = (2.0, 7.0);
    let mut builder = ModelBuilder::new();
    builder.gravity(Vec3::zeros());
    builder.add_body(body("a", mass_a, size_a)).add_body(body("b", mass_b, size_b));
    let model = builder.build().unwrap();
    let mut data = Data::new(&model);

    // B tilted, A resting on B's top face, touching at a corner-free face contact: place A so
    // that one of its corners penetrates B's top face (a single contact point).
    let rot_b = axis_angle(&Vec3::new(0.2, -0.1, 1.0).normalize(), 0.3);
    let rot_a = axis_angle(&Vec3::new(1.0, 1.0, 0.3).normalize(), 0.7);
    let mut q = model.neutral_configuration();
    let set_pose = |q: &mut DVector<f64>, k: usize, r: &Mat3, t: Vec3| {
        let quat = nalgebra::UnitQuaternion::from_matrix(r);
        q.rows_mut(7 * k, 3).copy_from(&t);
        q[7 * k + 3] = quat.i;
        q[7 * k + 4] = quat.j;
        q[7 * k + 5] = quat.k;
        q[7 * k + 6] = quat.w;
    };
    set_pose(&mut q, 1, &rot_b, Vec3::new(0.1, -0.2, 0.0));
    // Lowest corner of A (along B's up axis) placed 1 mm below B's top face.
    let up = rot_b * Vec3::z();
    let top_centre = Vec3::new(0.1, -0.2, 0.0) + up * size_b.z / 2.0;
    let corners: Vec<Vec3> = (0..8)
        .map(|i| {
            let s = Vec3::new(
                if i & 1 == 0 { -0.5 } else { 0.5 },
                if i & 2 == 0 { -0.5 } else { 0.5 },
                if i & 4 == 0 { -0.5 } else { 0.5 },
            );
            rot_a * size_a.component_mul(&s)
        })
        .collect();
    let lowest = corners.iter().min_by(|a, b| a.dot(&up).total_cmp(&b.dot(&up))).unwrap();
    let centre_a = top_centre + Vec3::new(0.05, 0.02, 0.0) - lowest - up * 0.001;
    set_pose(&mut q, 0, &rot_a, centre_a);

    forward_kinematics(&model, &mut data, &q).unwrap();
    let mut world = CollisionWorld::new(CollisionOptions::default());
    let mb = world.add_model(&model, &MeshOptions::default()).unwrap();
    world.set_self_collision(mb, true).unwrap();
    world.update_multibody(mb, &data).unwrap();
    let contacts = world.detect().to_vec();
    assert_eq!(contacts.len(), 1, "{contacts:?}");
    let c = contacts[0];

    // Velocities: A and B moving towards each other and spinning.
    let v = DVector::from_vec(vec![0.3, -0.2, -1.1, 0.5, -0.7, 0.2, -0.1, 0.4, 0.6, 0.3, 0.1, -0.4]);
    let epsilon = 0.5;
    let params = ContactParameters {
        mu: 0.0,
        restitution: epsilon,
        bounce_velocity: 0.0,
        erp: 0.0,
        ..Default::default()
    };
    let h = 1e-3;

    compute_joint_jacobians(&model, &mut data, &q).unwrap();
    crba(&model, &mut data, &q).unwrap();
    factor_mass_matrix(&model, &mut data).unwrap();
    let mut rows = ProblemBuilder::new(model.nv(), FrictionModel::Cone);
    add_contact_rows(&mut rows, &[(&model, &data)], &[0], &contacts, 0, &v, h, |_| params);
    let mut problem = ConstraintProblem::default();
    // No gravity, no velocity-dependent forces along the normal in one step: v_free = v + h M⁻¹(−C v).
    // Use v_free = v so that the closed form applies exactly to the impulse of this step.
    assemble_single(&rows, &model, &data, &v, &mut problem);

    // Closed form from world-frame quantities.
    let world_velocity = |k: usize| {
        let x = &data.x_wb[k + 1];
        let local = Vector6::from_column_slice(&v.as_slice()[6 * k..6 * k + 6]);
        let (lin, ang) = (x.rotation * local.fixed_rows::<3>(0), x.rotation * local.fixed_rows::<3>(3));
        (lin, ang, x.translation, x.rotation)
    };
    let (va, wa, pa, ra) = world_velocity(0);
    let (vb, wb, pb, rb) = world_velocity(1);
    let n = c.normal;
    let (r_a, r_b) = (c.point_a - pa, c.point_b - pb);
    let v_rel = (va + wa.cross(&r_a)) - (vb + wb.cross(&r_b));
    let inertia_world = |mass: f64, size: Vec3, r: &Mat3| {
        let i = RigidInertia::solid_box(mass, size).inertia_com;
        r * i * r.transpose()
    };
    let (ja, jb) = (inertia_world(mass_a, size_a, &ra), inertia_world(mass_b, size_b, &rb));
    let (ra_n, rb_n) = (r_a.cross(&n), r_b.cross(&n));
    let denominator = 1.0 / mass_a
        + 1.0 / mass_b
        + ra_n.dot(&(ja.try_inverse().unwrap() * ra_n))
        + rb_n.dot(&(jb.try_inverse().unwrap() * rb_n));
    let closed_form = -(1.0 + epsilon) * n.dot(&v_rel) / denominator;
    assert!(n.dot(&v_rel) < 0.0, "bodies approach");

    let mut solvers: Vec<Box<dyn ConstraintSolver>> = vec![
        Box::new(LemkeSolver::default()),
        Box::new(ClarabelSolver::default()),
        Box::new(PgsSolver::default()),
    ];
    for solver in &mut solvers {
        let mut lambda = DVector::zeros(problem.rows());
        solver.solve(&problem, &mut lambda).unwrap();
        let error = (lambda[0] - closed_form).abs() / closed_form.abs();
        assert!(
            error < 1e-12 || (solver.name() == "clarabel" && error < 1e-9),
            "{}: {} vs {closed_form}",
            solver.name(),
            lambda[0]
        );
        let v_after = &v + &problem.minv_jt * &lambda;
        let u_before = problem.jacobian.row(0).dot(&v.transpose());
        let u_after = problem.jacobian.row(0).dot(&v_after.transpose());
        assert!(
            (u_after + epsilon * u_before).abs() < 1e-9,
            "{}: {u_after} vs {}",
            solver.name(),
            -epsilon * u_before
        );
    }
}
