//! The Gram matrix, the dense solves and the pyramid guess of the subspace step.

use super::active_set::pyramid_units;
use super::reduced::{cholesky_factor, cholesky_solve, lu_factor, lu_solve};
use super::*;

/// The Gram over a landing ragdoll's rows and over a subset of them in another order
/// (matrix-free, W on paths through a branched tree; groups of rows with equal column
/// ranges as lanes) equals A's entries W_i · W_j over W's runs, plus R on the diagonal.
#[test]
fn the_gram_from_lanes_is_a_over_the_rows() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/models/ragdoll_fall.toml");
    let mut scene = crate::io::scene::load_file(path).unwrap();
    for _ in 0..450 {
        scene.world.step().unwrap();
    }
    let problem = scene.world.problem();
    let n = problem.rows();
    assert!(problem.is_matrix_free() && n > 30, "{n} rows");
    for rows in [(0..n).collect::<Vec<_>>(), (0..n).rev().step_by(3).collect()] {
        let mut ws = SubspaceWorkspace { rows, ..Default::default() };
        fill_gram(problem, &mut ws);
        let m = ws.rows.len();
        let scale = (0..m).map(|a| ws.gram[a * m + a]).fold(0.0, f64::max);
        for (a, &i) in ws.rows.iter().enumerate() {
            for (b, &j) in ws.rows.iter().enumerate() {
                let expected =
                    problem.delassus_entry(i, j) + if i == j { problem.regularization[i] } else { 0.0 };
                let got = ws.gram[a * m + b];
                assert!((got - expected).abs() <= 1e-12 * scale, "rows {i}, {j}: {got} against {expected}");
            }
        }
    }
}

/// Cholesky and LU agree on a symmetric positive definite system (a Gram matrix plus a
/// small diagonal), and Cholesky refuses an indefinite one.
#[test]
fn cholesky_solves_what_lu_solves_and_refuses_an_indefinite_matrix() {
    let s = 9;
    let b: Vec<f64> = (0..s * 12).map(|k| ((k * 37 % 23) as f64 - 11.0) / 7.0).collect();
    let mut a = vec![0.0; s * s];
    for i in 0..s {
        for j in 0..s {
            a[i * s + j] = crate::math::dot(&b[i * 12..(i + 1) * 12], &b[j * 12..(j + 1) * 12]);
        }
        a[i * s + i] += 1e-3;
    }
    let rhs: Vec<f64> = (0..s).map(|i| (i as f64 * 0.9).cos()).collect();
    let (mut l, mut lu, mut pivots) = (a.clone(), a.clone(), Vec::new());
    assert!(cholesky_factor(&mut l, s));
    assert!(lu_factor(&mut lu, &mut pivots, s));
    let (mut x, mut y) = (rhs.clone(), rhs.clone());
    cholesky_solve(&l, s, &mut x);
    lu_solve(&lu, &pivots, s, &mut y);
    for i in 0..s {
        let residual = crate::math::dot(&a[i * s..(i + 1) * s], &x) - rhs[i];
        assert!(residual.abs() < 1e-9, "row {i}: residual {residual}");
        assert!((x[i] - y[i]).abs() < 1e-8 * y[i].abs().max(1.0), "{} against {}", x[i], y[i]);
    }
    a[4 * s + 4] = -1.0;
    assert!(!cholesky_factor(&mut a, s));
}

/// PGS's iterate leaves a contact that slides just inside its friction pyramid (its normal
/// impulse still growing over the sweeps): the step guesses it on its facet, where it
/// ends, and solves the step in one round. Humanoid step 898 (nine contacts, several
/// sliding) with a 4-facet pyramid: its exact answer (Lemke) with each sliding contact's
/// tangential impulse moved 0.5 % inward.
#[test]
fn a_contact_just_inside_its_facet_is_guessed_on_it() {
    use crate::solvers::{ConstraintSolver, LemkeSolver};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/humanoid_fall_step0898_problem.json");
    let mut problem = crate::io::problem::read_problem(&path).unwrap();
    let facets = 4;
    problem.friction = FrictionModel::Pyramid { facets };
    let mut exact = DVector::zeros(problem.rows());
    LemkeSolver::default().solve(&problem, &mut exact).unwrap();
    let mut lambda = exact.clone();
    let mut moved = 0;
    for c in &problem.contacts {
        let (nr, t1, t2) = c.rows();
        let s = [exact[t1] / c.mu, exact[t2] / c.mu2];
        if let Some((Unit::Facet(_), _)) = pyramid_units(c, facets, exact[nr], s, ON_CONE) {
            lambda[t1] *= 0.995;
            lambda[t2] *= 0.995;
            moved += 1;
        }
    }
    assert!(moved >= 2, "{moved} contacts slide on a facet at the answer");
    let mut ws = SubspaceWorkspace::default();
    let outcome = subspace_step(&problem, &lambda, None, &mut ws, 1e-10, 1e-9);
    assert!(matches!(outcome, SubspaceOutcome::Accepted(r) if r <= 1e-9), "{outcome:?}");
    assert_eq!(ws.rounds, 1, "reduced solves");
}
