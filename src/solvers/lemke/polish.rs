//! Block Gauss–Seidel polishing of an LCP answer that a pivoting path left slightly outside
//! the tolerance.
//!
//! At a highly degenerate vertex (a pyramid of boxes: four coplanar corners under every box,
//! eight friction facets per contact, a Delassus matrix of rank far below its size) the final
//! basis of a path, refined to the working precision, can leave w_i some 1e-9 below zero at
//! thousands of rows: contacts left sliding at a few nm/s without the friction that would stop
//! them, unloaded corners approaching at that speed. The values below Harris's tolerance are
//! ties the path could not resolve, and no principal pivot or restart from that basis resolves
//! thousands of them. Starting from the answer, block Gauss–Seidel resolves them one block at
//! a time: each block's small LCP, the rest of z held fixed, is solved exactly (a dense Lemke
//! tableau, its final active set re-solved by an LU with full pivoting), and w is updated by
//! the block's columns. The corrections are of the size of the violations, so the rounding of
//! the updates stays far below them.
//!
//! Blocks are read from M alone: a variable whose diagonal entry is zero (a contact's friction
//! slack γ, whose row couples it to the normal impulse and the facets, whose column to the
//! facets; a bound multiplier and its variable) is grouped with every variable its row and
//! column couple it to; every other variable is a block of its own, solved as
//! z_i = max(0, z_i − w_i / M_ii).

use super::columns::Columns;
use nalgebra::{DMatrix, DVector};

/// The largest block solved by the dense tableau; larger groups are left as they are.
const MAX_BLOCK: usize = 24;

/// Sweeps in a row without a smaller residual after which polishing stops.
const STALLED_SWEEPS: usize = 3;

/// Calls `f(i, M_ij)` for the non-zeros of column j of M (`cols` holds −M's columns).
#[inline]
fn column(cols: &Columns, j: usize, mut f: impl FnMut(usize, f64)) {
    cols.for_each(cols.n() + j, |i, v| f(i, -v));
}

/// w = M z + q.
fn w_of(cols: &Columns, q: &[f64], z: &[f64], w: &mut [f64]) {
    w.copy_from_slice(q);
    for (j, &zj) in z.iter().enumerate() {
        if zj != 0.0 {
            column(cols, j, |i, v| w[i] += v * zj);
        }
    }
}

/// The blocks of variables of M (see the module documentation), M read from `cols`.
pub(super) fn blocks_of(cols: &Columns) -> Vec<Vec<usize>> {
    let n = cols.n();
    let mut zero_diagonal = vec![true; n];
    for (j, zero) in zero_diagonal.iter_mut().enumerate() {
        column(cols, j, |i, v| *zero &= i != j || v == 0.0);
    }
    let mut pairs = Vec::new();
    for j in 0..n {
        column(cols, j, |i, _| {
            // Entry (i, j): column j of a zero-diagonal j, or row i of a zero-diagonal i.
            if i != j && (zero_diagonal[j] || zero_diagonal[i]) {
                pairs.push((i, j));
            }
        });
    }
    blocks_of_pairs(n, pairs)
}

/// The connected components of the variables 0..n linked by `pairs`, each in increasing order.
pub(super) fn blocks_of_pairs(n: usize, pairs: impl IntoIterator<Item = (usize, usize)>) -> Vec<Vec<usize>> {
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for (i, j) in pairs {
        let (a, b) = (find(&mut parent, i), find(&mut parent, j));
        if a != b {
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut index = vec![usize::MAX; n];
    let mut blocks: Vec<Vec<usize>> = Vec::new();
    for i in 0..n {
        let root = find(&mut parent, i);
        if index[root] == usize::MAX {
            index[root] = blocks.len();
            blocks.push(Vec::new());
        }
        blocks[index[root]].push(i);
    }
    blocks
}

/// The natural residual max |min(z_i, w_i)|.
fn natural(z: &[f64], w: &[f64]) -> f64 {
    let r = z.iter().zip(w).fold(0.0f64, |r, (z, w)| r.max(z.min(*w).abs()));
    if r.is_nan() {
        f64::INFINITY
    } else {
        r
    }
}

/// Polishes z (an answer of `w = M z + q ⟂ z ≥ 0`) by at most `sweeps` sweeps of block
/// Gauss–Seidel over `blocks`, each sweep visiting the blocks whose residual exceeds a tenth
/// of `tolerance`, until the natural residual is within half the tolerance or
/// [`STALLED_SWEEPS`] sweeps in a row leave it above the best so far. Returns the best z and
/// its natural residual (w recomputed from M and q after each sweep); `None` when no sweep
/// improved on z.
pub(super) fn polish(
    cols: &Columns,
    q: &[f64],
    blocks: &[Vec<usize>],
    z: &[f64],
    tolerance: f64,
    sweeps: usize,
) -> Option<(Vec<f64>, f64)> {
    let n = q.len();
    let mut z = z.to_vec();
    let mut w = q.to_vec();
    w_of(cols, q, &z, &mut w);
    let start = natural(&z, &w);
    let mut best = (z.clone(), start);
    let mut local = DMatrix::zeros(0, 0);
    let mut position = vec![usize::MAX; n];
    let mut stalled = 0;
    for _ in 0..sweeps {
        if best.1 <= 0.5 * tolerance || stalled == STALLED_SWEEPS {
            break;
        }
        for block in blocks {
            let violation = block.iter().fold(0.0f64, |r, &i| r.max(z[i].min(w[i]).abs()));
            if violation <= 0.1 * tolerance || block.len() > MAX_BLOCK {
                continue;
            }
            let b = block.len();
            // The block's LCP: w_B = M_BB z_B + (w_B − M_BB z_B).
            local.resize_mut(b, b, 0.0);
            local.fill(0.0);
            for (k, &i) in block.iter().enumerate() {
                position[i] = k;
            }
            for (c, &j) in block.iter().enumerate() {
                column(cols, j, |i, v| {
                    if position[i] != usize::MAX {
                        local[(position[i], c)] += v;
                    }
                });
            }
            for &i in block {
                position[i] = usize::MAX;
            }
            let mut q_local = DVector::from_iterator(b, block.iter().map(|&i| w[i]));
            for c in 0..b {
                let zc = z[block[c]];
                if zc != 0.0 {
                    for r in 0..b {
                        q_local[r] -= local[(r, c)] * zc;
                    }
                }
            }
            let Some(solution) = small_lcp(&local, &q_local) else { continue };
            for (c, &j) in block.iter().enumerate() {
                let delta = solution[c] - z[j];
                if delta != 0.0 {
                    z[j] = solution[c];
                    column(cols, j, |i, v| w[i] += v * delta);
                }
            }
        }
        // w afresh from M and q (the updates' rounding does not accumulate over sweeps).
        w_of(cols, q, &z, &mut w);
        let swept = natural(&z, &w);
        if swept < best.1 {
            best.0.copy_from_slice(&z);
            best.1 = swept;
            stalled = 0;
        } else {
            stalled += 1;
        }
    }
    (best.1 < start).then_some(best)
}

/// The solution of a small dense LCP `w = M z + q ⟂ z ≥ 0` by Lemke's method on an explicit
/// tableau (covering vector of ones, the smallest index among tied rows, z0's row first), its
/// final active set J re-solved as M_JJ z_J = −q_J by an LU with full pivoting; `None` when
/// the path ends on a ray or the pivot limit, or the re-solved point is not a solution.
pub(super) fn small_lcp(m: &DMatrix<f64>, q: &DVector<f64>) -> Option<DVector<f64>> {
    let n = q.len();
    if q.iter().all(|&x| x >= 0.0) {
        return Some(DVector::zeros(n));
    }
    let scale = q.amax().max(m.amax()).max(f64::MIN_POSITIVE);
    // Columns: w (0..n), z (n..2n), z0 (2n), right-hand side (2n + 1).
    let width = 2 * n + 2;
    let mut t = DMatrix::zeros(n, width);
    for i in 0..n {
        t[(i, i)] = 1.0;
        for j in 0..n {
            t[(i, n + j)] = -m[(i, j)];
        }
        t[(i, 2 * n)] = -1.0;
        t[(i, 2 * n + 1)] = q[i];
    }
    let mut basic: Vec<usize> = (0..n).collect();
    let pivot = |t: &mut DMatrix<f64>, r: usize, c: usize| {
        let p = t[(r, c)];
        for k in 0..width {
            t[(r, k)] /= p;
        }
        for i in 0..n {
            if i != r {
                let f = t[(i, c)];
                if f != 0.0 {
                    for k in 0..width {
                        let v = t[(r, k)];
                        t[(i, k)] -= f * v;
                    }
                }
            }
        }
    };
    let first = (0..n).min_by(|&a, &b| q[a].total_cmp(&q[b]))?;
    pivot(&mut t, first, 2 * n);
    let mut leaving = basic[first];
    basic[first] = 2 * n;
    let eps = 1e-12;
    for _ in 0..(10 * n + 20) {
        let entering = if leaving < n { leaving + n } else { leaving - n };
        let column_max = (0..n).fold(0.0f64, |a, i| a.max(t[(i, entering)].abs()));
        let mut best: Option<(usize, f64)> = None;
        for i in 0..n {
            let a = t[(i, entering)];
            if a > eps * column_max.max(1.0) {
                let ratio = t[(i, 2 * n + 1)].max(0.0) / a;
                let better = match best {
                    None => true,
                    Some((b, r)) => {
                        ratio < r - 1e-14 * scale
                            || (ratio <= r + 1e-14 * scale && (basic[i] == 2 * n && basic[b] != 2 * n))
                    }
                };
                if better {
                    best = Some((i, ratio));
                }
            }
        }
        let (row, _) = best?;
        pivot(&mut t, row, entering);
        leaving = basic[row];
        basic[row] = entering;
        if leaving == 2 * n {
            // The active set, re-solved by a full-pivoting LU.
            let active: Vec<usize> = basic.iter().filter(|&&v| v >= n).map(|&v| v - n).collect();
            let k = active.len();
            let mut z = DVector::zeros(n);
            if k > 0 {
                let mjj = DMatrix::from_fn(k, k, |a, b| m[(active[a], active[b])]);
                let rhs = DVector::from_iterator(k, active.iter().map(|&i| -q[i]));
                let zj = mjj.full_piv_lu().solve(&rhs)?;
                for (a, &i) in active.iter().enumerate() {
                    z[i] = zj[a].max(0.0);
                }
            }
            let w = m * &z + q;
            let r = z.iter().zip(w.iter()).fold(0.0f64, |r, (z, w)| r.max(z.min(*w).abs()));
            return (r <= 1e-12 * scale).then_some(z);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solvers::lemke::columns::{Csc, Matrix};

    /// A one-contact pyramid LCP with four facets (normal, four facet impulses, slack γ), μ = 0.5,
    /// A = I, and a tangential bias `b_t` pushing the contact sideways.
    fn one_contact(b_n: f64, b_t: [f64; 2]) -> (DMatrix<f64>, DVector<f64>) {
        let mu = 0.5;
        let d: Vec<[f64; 2]> = (0..4)
            .map(|j| {
                let t = std::f64::consts::FRAC_PI_2 * j as f64;
                [mu * t.cos(), mu * t.sin()]
            })
            .collect();
        let mut m = DMatrix::zeros(6, 6);
        m[(0, 0)] = 1.0;
        for a in 0..4 {
            for b in 0..4 {
                m[(1 + a, 1 + b)] = d[a][0] * d[b][0] + d[a][1] * d[b][1];
            }
            m[(1 + a, 5)] = 1.0;
            m[(5, 1 + a)] = -1.0;
        }
        m[(5, 0)] = mu;
        let mut q = DVector::zeros(6);
        q[0] = b_n;
        for a in 0..4 {
            q[1 + a] = d[a][0] * b_t[0] + d[a][1] * b_t[1];
        }
        (m, q)
    }

    fn natural_of(m: &DMatrix<f64>, q: &DVector<f64>, z: &DVector<f64>) -> f64 {
        let w = m * z + q;
        natural(z.as_slice(), w.as_slice())
    }

    #[test]
    fn small_lcps_of_a_contact_are_solved_sticking_and_sliding() {
        // Pressed down, pushed sideways a little (sticking) and a lot (sliding).
        for b_t in [[0.01, 0.0], [0.3, -0.4], [0.0, 0.0]] {
            let (m, q) = one_contact(-1.0, b_t);
            let z = small_lcp(&m, &q).expect("solved");
            assert!(z.iter().all(|&x| x >= 0.0));
            assert!(natural_of(&m, &q, &z) <= 1e-14, "residual {:e}", natural_of(&m, &q, &z));
            assert!((z[0] - 1.0).abs() < 1e-12, "normal impulse {}", z[0]);
        }
        // Separating while sliding: no impulse, the slack at the sliding speed (μ-scaled).
        let (m, q) = one_contact(1.0, [0.2, 0.0]);
        let z = small_lcp(&m, &q).expect("solved");
        assert!(z.rows(0, 5).iter().all(|&x| x == 0.0), "impulses {z}");
        assert!((z[5] - 0.1).abs() < 1e-15, "slack {}", z[5]);
    }

    #[test]
    fn blocks_group_a_zero_diagonal_variable_with_its_couplings() {
        // Two contacts side by side: their blocks are {0, 1..=4, 5} and {6, 7..=10, 11}, however
        // the contacts couple through A.
        let (m1, _) = one_contact(-1.0, [0.0, 0.0]);
        let mut m = DMatrix::zeros(12, 12);
        m.view_mut((0, 0), (6, 6)).copy_from(&m1);
        m.view_mut((6, 6), (6, 6)).copy_from(&m1);
        m[(0, 6)] = 0.3;
        m[(6, 0)] = 0.3;
        let csc = Csc::from_dense(&m);
        let cols = Columns { m: Matrix::Formed(&csc), d: Vec::new() };
        assert_eq!(blocks_of(&cols), vec![(0..6).collect::<Vec<_>>(), (6..12).collect()]);
    }

    #[test]
    fn polishing_resolves_an_answer_a_few_rounding_units_outside_the_lcp() {
        // Two coupled contacts pressed down: the exact answer perturbed by 1e-9 in the normal
        // impulses and with a sliding speed left out is polished to within 1e-12.
        let (m1, q1) = one_contact(-1.0, [0.001, 0.002]);
        let mut m = DMatrix::zeros(12, 12);
        m.view_mut((0, 0), (6, 6)).copy_from(&m1);
        m.view_mut((6, 6), (6, 6)).copy_from(&m1);
        m[(0, 6)] = 0.3;
        m[(6, 0)] = 0.3;
        let mut q = DVector::zeros(12);
        q.rows_mut(0, 6).copy_from(&q1);
        q.rows_mut(6, 6).copy_from(&q1);
        let exact = crate::solvers::lemke(&m, &q, &Default::default()).expect("solved").0;
        let mut z = exact.clone();
        z[0] += 1e-9;
        z[6] -= 2e-9;
        let csc = Csc::from_dense(&m);
        let cols = Columns { m: Matrix::Formed(&csc), d: Vec::new() };
        let start = natural_of(&m, &q, &z);
        assert!(start > 1e-10, "the perturbed answer is off by {start:e}");
        let (polished, residual) =
            polish(&cols, q.as_slice(), &blocks_of(&cols), z.as_slice(), 1e-12, 30).expect("an improvement");
        assert!(residual <= 1e-12, "polished to {residual:e}");
        assert!((natural_of(&m, &q, &DVector::from_vec(polished)) - residual).abs() <= 1e-15);
    }
}
