//! Unit tests of the world's step that look inside it: kept factors, kept W, kept contact rows,
//! phase timing, the impulse sum, the warm start.

use super::dofs::block_factors;
use super::*;
use crate::constraints::{add_contact_rows_with, RowOrigin};
use crate::model::RigidInertia;
use crate::scenes::free_body;

/// A 0.2 m box resting on the ground for 100 steps: four contacts with impulses.
fn resting_box() -> World {
    let mut w = World::new(WorldOptions::default());
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    let size = Vec3::repeat(0.2);
    let model = free_body("box", Shape::Box { size }, RigidInertia::solid_box(2.0, size));
    let i = w.add_multibody("box", model, &MeshOptions::default()).unwrap();
    w.bodies[i].state.q[2] = 0.1;
    w.set_sleep(SleepOptions { enabled: false, ..w.options.sleep });
    for _ in 0..100 {
        w.step().unwrap();
    }
    w
}

/// The ragdoll scene, sleeping off, after 1500 steps: at rest on the ground.
fn resting_ragdoll() -> crate::io::scene::Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ragdoll_fall.toml");
    let mut s = crate::io::scene::load_file(path).unwrap();
    s.world.set_sleep(crate::world::SleepOptions { enabled: false, ..s.world.options().sleep });
    for _ in 0..1500 {
        s.world.step().unwrap();
    }
    s
}

/// The free motion with the factor kept from an earlier step (the joints moved by less than
/// the 1e-8 tolerance since) equals the one with a new factorization to 1e-8 m/s, a hundredth
/// of the solver's tolerance (measured: up to 1.3e-9 m/s; the free motion itself is ~0.02 m/s,
/// gravity over a step), on a resting ragdoll (joint damping: M + h·D).
#[test]
fn a_kept_mass_matrix_factor_gives_the_free_motion_of_a_new_one() {
    let mut s = resting_ragdoll();
    let h = s.world.options().dt;
    let mut compared = 0;
    for _ in 0..50 {
        s.world.step().unwrap();
        let b = &mut s.world.bodies[0];
        let factored = b.factorizations();
        b.free_motion(h, true, Some(1e-8)).unwrap();
        if b.factorizations() != factored {
            continue;
        }
        let kept = b.v_free.clone();
        b.free_motion(h, true, None).unwrap();
        let gap = (&kept - &b.v_free).amax();
        assert!(gap < 1e-8, "kept factor against a new one: {gap:e} m/s");
        assert!(b.v_free.amax() > 1e-3, "the free motion is not trivial: {}", b.v_free.amax());
        compared += 1;
    }
    assert!(compared >= 40, "{compared} of 50 steps kept the factor");
}

#[test]
fn a_kept_delassus_matrix_and_a_new_one_pose_the_same_problem() {
    let mut s = resting_ragdoll();
    let w = &mut s.world;
    let mut compared = 0;
    for _ in 0..50 {
        let builds = w.problem_builds();
        w.step().unwrap();
        if w.problem_builds() != builds {
            continue;
        }
        // The same rows built anew, on the factors and free velocity of this step.
        let mut v_free = w.dofs.v_free.clone();
        for b in &w.bodies {
            v_free.rows_mut(b.col, b.model.nv()).copy_from(&b.v_free);
        }
        let mut fresh = ConstraintProblem::default();
        let factor_of = block_factors(&w.bodies, &w.dofs.block_owner);
        w.rows.builder.build_into_blocks(&v_free, factor_of, false, &mut fresh);
        let (kept, new) = (w.solve.problem.delassus_dense(), fresh.delassus_dense());
        let scale = new.amax();
        let gap = (&*kept - &*new).amax();
        assert!(gap <= 1e-8 * scale, "kept A against a new one: {gap:e} of {scale:e}");
        let bias_gap = (&w.solve.problem.bias - &fresh.bias).amax();
        assert!(bias_gap <= 1e-12, "bias: {bias_gap:e} m/s");
        assert_eq!(w.solve.problem.laws, fresh.laws);
        assert_eq!(w.solve.problem.contacts, fresh.contacts);
        assert!(fresh.rows() > 20, "{} rows", fresh.rows());
        compared += 1;
    }
    assert!(compared >= 40, "{compared} of 50 resting steps kept W");
}

/// A resting ragdoll keeps its contact rows on most steps, and the kept rows are the rows
/// formed anew from the step's contacts: Jacobian entries to 1e-7 (m/s per unit rate; the
/// tolerance is 1e-8 in every coordinate and contact point), targets to 1e-9 m/s, the same
/// laws and contact blocks. Moving the ragdoll by a micrometre forms them anew.
#[test]
fn kept_contact_rows_are_the_rows_formed_anew() {
    let mut s = resting_ragdoll();
    let w = &mut s.world;
    let mut compared = 0;
    for _ in 0..50 {
        let reuses = w.contact_row_reuses();
        w.step().unwrap();
        if w.contact_row_reuses() == reuses {
            continue;
        }
        let mut fresh = ProblemBuilder::with_blocks(w.dofs.nv, &w.dofs.blocks, w.options.friction).unwrap();
        let bodies = &w.bodies;
        let (has_rows, h) = (&w.rows.contact_has_rows, w.options.dt);
        add_contact_rows_with(
            &mut fresh,
            |m| (&bodies[m].model, &bodies[m].data, bodies[m].col),
            &w.contacts,
            0,
            &w.dofs.v_start,
            h,
            |c| w.materials.parameters_of(w.collision.colliders(), c),
            |i, _| has_rows[i],
        );
        assert!(fresh.contact_count() >= 5, "{} contacts with rows", fresh.contact_count());
        assert_eq!(fresh.contact_blocks(), &w.rows.builder.contact_blocks()[..fresh.contact_count()]);
        for i in 0..fresh.len() {
            let gap = (DVector::from_vec(fresh.row(i)) - DVector::from_vec(w.rows.builder.row(i))).amax();
            assert!(gap <= 1e-7, "row {i}: kept against new {gap:e}");
            let target_gap = (fresh.target(i) - w.rows.builder.target(i)).abs();
            assert!(target_gap <= 1e-9, "row {i}: target {target_gap:e} m/s");
        }
        compared += 1;
    }
    assert!(compared >= 40, "{compared} of 50 resting steps kept the contact rows");
    // A micrometre is far beyond the tolerance: the next step forms its rows anew.
    w.multibody_mut(0).state.q[0] += 1e-6;
    let reuses = w.contact_row_reuses();
    w.step().unwrap();
    assert_eq!(w.contact_row_reuses(), reuses);
}

/// The step reads no clock unless asked to: zeros by default, the phases' times when on.
#[test]
fn a_step_times_its_phases_only_when_asked() {
    let mut w = resting_box();
    assert!(!w.options().time_phases);
    assert_eq!(w.step().unwrap().phase_ns, [0; 7]);
    w.set_phase_timing(true);
    let phases = w.step().unwrap().phase_ns;
    assert!(phases.iter().sum::<u64>() > 0, "{phases:?}");
}

/// Through the ragdoll's landing (subspace steps accepted, their Wᵀλ handed to PGS), the
/// Wᵀλ that the solve leaves for the step's impulses (which `apply_impulses` turns into the
/// velocity change) is Wᵀλ formed afresh, to 1e-9 of its size.
#[test]
fn the_impulse_sum_a_solve_keeps_is_that_of_its_impulses() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ragdoll_fall.toml");
    let mut s = crate::io::scene::load_file(path).unwrap();
    let w = &mut s.world;
    let mut compared = 0;
    for step in 0..700 {
        w.step().unwrap();
        let p = &w.solve.problem;
        if step < 200 || !p.is_matrix_free() || p.rows() == 0 {
            continue;
        }
        let lambda = w.solve.lambda.as_slice();
        let mut kept = vec![0.0; p.sparsity.nv];
        if !p.kept_impulse_sum(lambda, &mut kept) {
            continue;
        }
        let mut fresh = vec![0.0; p.sparsity.nv];
        for (i, &l) in lambda.iter().enumerate() {
            for (col, wi) in p.sparsity.row_spans(i) {
                for (f, wi) in fresh[col..col + wi.len()].iter_mut().zip(wi) {
                    *f += l * wi;
                }
            }
        }
        let scale = fresh.iter().fold(1e-6_f64, |m, x| m.max(x.abs()));
        let gap = kept.iter().zip(&fresh).fold(0.0_f64, |m, (k, f)| m.max((k - f).abs()));
        assert!(gap <= 1e-9 * scale, "step {step}: kept Wᵀλ off by {gap:e} of {scale:e}");
        compared += 1;
    }
    assert!(compared >= 300, "{compared} of 500 landing steps compared");
}

#[test]
fn a_contact_whose_feature_id_changed_keeps_its_impulses_and_one_that_moved_does_not() {
    let mut w = resting_box();
    let before = w.solve.lambda.clone();
    assert_eq!(w.contacts.len(), 4);
    assert!(before.iter().filter(|x| **x > 0.0).count() >= 4, "{before}");
    // The resting box's rows are the last solve's (kept contact rows): λ stands as it is,
    // and matching the rows by their keys gives the same λ.
    warm_start(&mut w);
    assert!(w.solve.warm.same_rows);
    assert_eq!(w.solve.lambda, before);
    w.rows.kept.invalidate();
    warm_start(&mut w);
    assert!(!w.solve.warm.same_rows);
    assert_eq!(w.solve.lambda, before);
    // The same contacts with other feature ids (parry's ids of a resting contact flip), and
    // the last one moved by 1 cm (whose rows a step would form anew): its impulses are not
    // the old contact's.
    for c in &mut w.contacts {
        c.feature ^= 0xdead_beef;
    }
    w.contacts[3].point_a.x += 0.01;
    warm_start(&mut w);
    let origins = w.solve.problem.origins.clone();
    let rows_of =
        |k: usize| (0..origins.len()).filter(|&r| origins[r] == RowOrigin::Contact(k)).collect::<Vec<_>>();
    for k in 0..3 {
        for r in rows_of(k) {
            assert_eq!(w.solve.lambda[r], before[r], "contact {k} row {r}");
        }
    }
    assert!(rows_of(3).iter().all(|&r| w.solve.lambda[r] == 0.0), "{}", w.solve.lambda);
}

/// The world's warm start of its last problem's rows, as a step does it before the solve.
fn warm_start(w: &mut World) {
    let generation = w.rows.kept_contact_rows().map(|(generation, _)| generation);
    let solve = &mut w.solve;
    solve.warm.start(&solve.problem, &w.contacts, generation, &mut solve.lambda, None);
}

/// Options out of range stop the step before anything changes, naming the option: a softness
/// set below 0 through the API, a NaN time step, a damping fraction above 1; back in range,
/// the world steps again.
#[test]
fn options_out_of_range_stop_the_step_with_the_option_named() {
    let mut w = resting_box();
    let before = w.bodies[0].state.clone();
    w.set_softness(-0.1);
    let e = w.step().unwrap_err();
    assert!(matches!(e, StepError::InvalidOption { name: "softness", .. }), "{e}");
    assert_eq!(w.bodies[0].state, before, "the state changed");
    w.set_softness(0.0);
    w.step().unwrap();
    for (options, name) in [
        (WorldOptions { dt: f64::NAN, ..WorldOptions::default() }, "dt"),
        (WorldOptions { dt: 0.0, ..WorldOptions::default() }, "dt"),
        (WorldOptions { tolerance: -1.0, ..WorldOptions::default() }, "tolerance"),
        (WorldOptions { softness_damping: 1.5, ..WorldOptions::default() }, "softness_damping"),
    ] {
        let mut w = World::new(options);
        let e = w.step().unwrap_err();
        assert!(matches!(e, StepError::InvalidOption { name: n, .. } if n == name), "{name}: {e}");
        assert!(e.to_string().contains(name), "{e}");
    }
}
