//! The builder's W and A against a dense solve with M, and the kept rows' tolerance.

use super::*;
use crate::algorithms::jacobian::last_dof_of;
use crate::algorithms::{crba, factor_mass_matrix};
use crate::constraints::ConstraintProblem;
use crate::data::Data;
use crate::io::urdf::{load_file, UrdfOptions};
use crate::model::{Model, NO_DOF};
use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};

/// Random entries on the path of `body` to the root (a Jacobian row of a point on it).
fn fill_path(model: &Model, body: usize, sign: f64, rng: &mut impl Rng, row: &mut RowMut<'_>) {
    let mut k = last_dof_of(model, body);
    while k != NO_DOF {
        row[k] += sign * rng.random_range(-1.0..1.0);
        k = model.dof_parent[k];
    }
}

/// The ragdoll at a random configuration (seeded), its mass matrix factored: the model, the
/// data holding the factor, M, and the generator for the rest of the test.
fn factored_ragdoll(seed: u64) -> (Model, Data, DMatrix<f64>, rand::rngs::StdRng) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/models/ragdoll.urdf");
    let model = load_file(path, &UrdfOptions::floating()).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let q = model.random_configuration(&mut rng);
    let mut data = Data::new(&model);
    crba(&model, &mut data, &q).unwrap();
    let m = data.mass_matrix.clone();
    factor_mass_matrix(&model, &mut data).unwrap();
    (model, data, m, rng)
}

/// Assembles `builder`'s rows at a random free velocity and checks against the dense solve
/// with M: A = J M⁻¹ Jᵀ, each ‖W_i‖² = A_ii, each contact's A_{t1 t2}, and the bias J v_free
/// (no targets). Returns the problem for further checks.
fn assemble_against_dense(
    builder: &ProblemBuilder,
    model: &Model,
    data: &Data,
    m: &DMatrix<f64>,
    rng: &mut rand::rngs::StdRng,
) -> ConstraintProblem {
    let mut problem = ConstraintProblem::default();
    let v_free = DVector::from_fn(model.nv(), |_, _| rng.random_range(-1.0..1.0));
    assemble_single(builder, model, data, &v_free, &mut problem);
    let j = problem.jacobian.clone();
    let expected = &j * m.clone().cholesky().unwrap().solve(&j.transpose());
    let scale = expected.abs().max();
    assert!((&problem.delassus - &expected).abs().max() < 1e-12 * scale);
    let velocity = &j * &v_free;
    for i in 0..builder.len() {
        assert!((problem.sparsity.row_norm2[i] - expected[(i, i)]).abs() < 1e-12 * scale, "row {i}");
        assert!((problem.bias[i] - velocity[i]).abs() < 1e-12 * velocity.amax(), "row {i}");
    }
    for c in 0..problem.contacts.len() {
        let (_, t1, t2) = problem.contacts[c].rows();
        let coupling = problem.friction_coupling(c);
        assert!((coupling - expected[(t1, t2)]).abs() < 1e-12 * scale, "contact {c}");
    }
    problem
}

/// Appends random point rates along the path of `body` to the root, as
/// [`crate::collision::point_rates`] does (last dof first), and returns their range; the
/// rate of dof `zero_at` (if on the path) is zero.
fn random_rates(
    builder: &mut ProblemBuilder,
    model: &Model,
    body: usize,
    zero_at: usize,
    rng: &mut impl Rng,
) -> (usize, usize) {
    let start = builder.rates_mut().len();
    let mut k = last_dof_of(model, body);
    while k != NO_DOF {
        let u = Vec3::from_fn(|_, _| rng.random_range(-1.0..1.0));
        builder.rates_mut().push((k, if k == zero_at { Vec3::zeros() } else { u }));
        k = model.dof_parent[k];
    }
    (start, builder.rates_mut().len())
}

#[test]
fn contact_rows_from_point_rates_give_the_delassus_matrix_and_bias_of_a_dense_solve() {
    let (model, data, m, mut rng) = factored_ragdoll(3);
    let nv = model.nv();
    let mut builder = ProblemBuilder::new(nv, FrictionModel::Cone);
    // A self-contact between two limbs (two paths in one block, scaled along their union),
    // a contact with the world (one path, scaled along its chain) whose rates are zero at a
    // dof in the middle of the path, and between them a row of stored entries and a contact
    // of stored rows (scaled row by row).
    let last = model.nbodies() - 1;
    let middle = model.dof_path[model.dof_path_start[last_dof_of(&model, last / 3)] + 4];
    for (a, b) in [(last, Some(last / 2)), (last / 3, None)] {
        let side_a = random_rates(&mut builder, &model, a, middle, &mut rng);
        let side_b = match b {
            Some(b) => random_rates(&mut builder, &model, b, NO_DOF, &mut rng),
            None => (side_a.1, side_a.1),
        };
        let directions = [0; 3].map(|_| Vec3::from_fn(|_, _| rng.random_range(-1.0..1.0)));
        let normal =
            builder.push_point_contact([side_a, side_b], directions, 0.0, RowOrigin::Other, 0.5, 0.5);
        assert_eq!(builder.contacts[builder.contact_count() - 1].normal, normal);
        let (_, mut row) = builder.push_row(RowLaw::Unilateral, 0.0, 0.0, RowOrigin::Other);
        fill_path(&model, last / 2, 1.0, &mut rng, &mut row);
    }
    // Contacts given by point rates only: assembly keeps their A_{t1 t2}; with a contact of
    // stored rows among them (below) it is formed from W when asked.
    let rates_only = assemble_against_dense(&builder, &model, &data, &m, &mut rng);
    assert_eq!(rates_only.sparsity.friction_coupling.len(), 2);
    let normal = builder.len();
    for r in 0..3 {
        let law =
            if r == 0 { RowLaw::Unilateral } else { RowLaw::Friction { contact: builder.contact_count() } };
        let (_, mut row) = builder.push_row(law, 0.0, 0.0, RowOrigin::Other);
        fill_path(&model, last, 1.0, &mut rng, &mut row);
    }
    builder.push_contact_block(ContactBlock { normal, mu: 0.5, mu2: 0.5 });
    let problem = assemble_against_dense(&builder, &model, &data, &m, &mut rng);
    assert!(problem.sparsity.friction_coupling.is_empty());
    // The rows' entries are the point rates' along each direction (both sides summed).
    for i in [0, 1, 2, 4, 5, 6] {
        let mut expected = vec![0.0; nv];
        let RowForm::Rates(RateRow { sides, direction }) = builder.forms[i] else { unreachable!() };
        for (start, end) in sides {
            for (c, u) in &builder.rates[start..end] {
                expected[*c] += direction.dot(u);
            }
        }
        for (k, expected) in expected.iter().enumerate() {
            assert_eq!(problem.jacobian[(i, k)], *expected, "row {i}, dof {k}");
        }
    }
    // The rows given by rates store only their paths' (or the union's) entries of W.
    let stored: usize =
        (0..3).map(|i| problem.sparsity.row_spans(i).map(|(_, w)| w.len()).sum::<usize>()).sum();
    let union = (0..nv).filter(|&k| problem.jacobian.row(0)[k] != 0.0).count();
    assert!(stored <= 3 * union, "{stored} entries stored for 3 rows on {union} dofs");
}

#[test]
fn recorded_rows_are_the_same_within_the_tolerance_only_and_keep_w_with_a_new_bias() {
    let (model, data, _, mut rng) = factored_ragdoll(5);
    let nv = model.nv();
    let last = model.nbodies() - 1;
    let mut base = ProblemBuilder::new(nv, FrictionModel::Cone);
    let side = random_rates(&mut base, &model, last, NO_DOF, &mut rng);
    let directions = [Vec3::z(), Vec3::x(), Vec3::y()];
    base.push_point_contact([side, (side.1, side.1)], directions, 1e-6, RowOrigin::Other, 0.5, 0.5);
    let first = last_dof_of(&model, last / 2);
    base.push_joint_row(RowLaw::Unilateral, 0.1, 0.0, RowOrigin::Other, first, &[1.0]);
    let mut recorded = BuiltRows::default();
    assert!(!recorded.same_rows(&base, 1e-8, None), "nothing recorded yet");
    recorded.record(&base);
    assert!(recorded.same_rows(&base, 1e-8, None));
    // A point rate moved by half the tolerance is the same row; by twice it, not.
    let mut moved = base.clone();
    let scale = moved.rates[0].1.x.abs().max(1.0);
    moved.rates[0].1.x += 0.5e-8 * scale;
    assert!(recorded.same_rows(&moved, 1e-8, None));
    moved.rates[0].1.x += 2e-8 * scale;
    assert!(!recorded.same_rows(&moved, 1e-8, None));
    // A turned direction, another joint coefficient, another law: not the same rows.
    let mut turned = base.clone();
    let RowForm::Rates(row) = &mut turned.forms[1] else { unreachable!() };
    row.direction.y += 1e-6;
    assert!(!recorded.same_rows(&turned, 1e-8, None));
    let mut scaled = base.clone();
    let RowForm::Joint { coefficients, .. } = &mut scaled.forms[3] else { unreachable!() };
    coefficients[0] = 1.0 + 1e-6;
    assert!(!recorded.same_rows(&scaled, 1e-8, None));
    let mut other_law = base.clone();
    other_law.laws[3] = RowLaw::Bilateral;
    assert!(!recorded.same_rows(&other_law, 1e-8, None));
    recorded.forget();
    assert!(!recorded.same_rows(&base, 1e-8, None));
    // The kept problem with a new free velocity and target: the bias of a new build.
    let factor = TreeFactor::new(&model, &data);
    let v_free = DVector::from_fn(nv, |_, _| rng.random_range(-1.0..1.0));
    let mut kept = ConstraintProblem::default();
    base.build_into(&DVector::zeros(nv), factor, &mut kept);
    base.set_target(3, -0.25);
    base.refresh_bias(&v_free, &mut kept);
    let mut fresh = ConstraintProblem::default();
    base.build_into(&v_free, factor, &mut fresh);
    for i in 0..base.len() {
        let (a, b) = (kept.bias[i], fresh.bias[i]);
        assert!((a - b).abs() <= 1e-14, "row {i}: {a} against {b}");
    }
    assert_eq!(kept.target, fresh.target);
    assert_eq!(kept.regularization, fresh.regularization);
    assert_eq!(kept.delassus, fresh.delassus);
}

#[test]
#[cfg(debug_assertions)]
#[should_panic(expected = "not one body's path to the root")]
fn point_rates_that_skip_a_dof_of_the_path_are_refused() {
    let (model, data, _, mut rng) = factored_ragdoll(4);
    let mut builder = ProblemBuilder::new(model.nv(), FrictionModel::Cone);
    let side = random_rates(&mut builder, &model, model.nbodies() - 1, NO_DOF, &mut rng);
    builder.rates_mut().remove(side.0 + 1);
    let side = (side.0, side.1 - 1);
    builder.push_point_contact([side, (side.1, side.1)], [Vec3::z(); 3], 0.0, RowOrigin::Other, 0.5, 0.5);
    let v_free = DVector::zeros(model.nv());
    assemble_single(&builder, &model, &data, &v_free, &mut ConstraintProblem::default());
}

#[test]
fn joint_rows_give_the_delassus_matrix_and_bias_of_a_dense_solve() {
    let (model, data, m, mut rng) = factored_ragdoll(5);
    let nv = model.nv();
    let mut builder = ProblemBuilder::new(nv, FrictionModel::Cone);
    // Rows on the dofs of one joint given compactly (a ball joint's three friction rows,
    // limits on combinations of its dofs, a root dof's row) and the same as stored rows,
    // a row on two limbs' dofs, unit rows on one chain and a unit row on a root dof; J v_free
    // is formed with the rows (the bias).
    let deepest = last_dof_of(&model, model.nbodies() - 1);
    let other_limb = last_dof_of(&model, model.nbodies() / 2);
    let unit = |builder: &mut ProblemBuilder, entries: &[(usize, f64)]| {
        let (_, mut row) =
            builder.push_row(RowLaw::Bounded { lo: -1.0, hi: 1.0 }, 0.0, 0.0, RowOrigin::Other);
        for &(k, value) in entries {
            row[k] = value;
        }
    };
    let joint = deepest - 2;
    let law = RowLaw::Bounded { lo: -1.0, hi: 1.0 };
    for k in joint..=deepest {
        builder.push_joint_row(law, 0.0, 0.0, RowOrigin::Other, k, &[1.0]);
    }
    builder.push_joint_row(law, 0.0, 0.0, RowOrigin::Other, joint, &[0.6, -0.8]);
    builder.push_joint_row(law, 0.0, 0.0, RowOrigin::Other, joint, &[0.6, 0.0, -0.8]);
    builder.push_joint_row(law, 0.0, 0.0, RowOrigin::Other, 0, &[1.0]);
    // Two consecutive columns that are not parent and child (another limb's first dof).
    let unchained = (1..nv).find(|&k| model.dof_parent[k] != k - 1).unwrap();
    builder.push_joint_row(law, 0.0, 0.0, RowOrigin::Other, unchained - 1, &[0.5, 1.0]);
    unit(&mut builder, &[(joint, 0.6), (joint + 1, -0.8)]);
    unit(&mut builder, &[(deepest, 1.0), (other_limb, 0.5)]);
    let chain: Vec<usize> =
        model.dof_path[model.dof_path_start[deepest]..model.dof_path_start[deepest + 1]].to_vec();
    for &k in chain.iter().rev().take(5) {
        unit(&mut builder, &[(k, rng.random_range(-1.0..1.0))]);
    }
    unit(&mut builder, &[(0, 1.0)]);
    let problem = assemble_against_dense(&builder, &model, &data, &m, &mut rng);
    // The compact joint rows' Jacobian rows are their coefficients at their columns.
    let expected: [&[(usize, f64)]; 7] = [
        &[(joint, 1.0)],
        &[(joint + 1, 1.0)],
        &[(joint + 2, 1.0)],
        &[(joint, 0.6), (joint + 1, -0.8)],
        &[(joint, 0.6), (joint + 2, -0.8)],
        &[(0, 1.0)],
        &[(unchained - 1, 0.5), (unchained, 1.0)],
    ];
    for (i, entries) in expected.iter().enumerate() {
        let mut row = vec![0.0; nv];
        for &(k, x) in entries.iter() {
            row[k] = x;
        }
        assert_eq!(problem.jacobian.row(i).iter().copied().collect::<Vec<_>>(), row, "row {i}");
        assert_eq!(builder.row(i), row, "row {i}");
    }
    for i in 0..builder.len() {
        // W's rows are the dense solve's M⁻¹Jᵀ mapped back (their spans too).
        let dense = problem.minv_jt.column(i);
        let mut row = vec![0.0; nv];
        for (col, w) in problem.sparsity.row_spans(i) {
            row[col..col + w.len()].copy_from_slice(w);
        }
        let factor = TreeFactor::new(&model, &data);
        factor.unscale_solve(0, &mut row);
        for k in 0..nv {
            assert!((row[k] - dense[k]).abs() < 1e-12 * dense.amax().max(1.0), "row {i}, dof {k}");
        }
    }
}
