//! The reduced system over the active set's unknowns, and its dense solves: LU with partial
//! pivoting, Cholesky when the system is symmetric positive definite.

use super::*;

/// K and −g over `ws.units` from the Gram matrix over `ws.rows` and `ws.w`, solved into `ws.x`; false
/// if the factorisation fails.
pub(super) fn reduced_solve(ws: &mut SubspaceWorkspace) -> bool {
    let s = ws.units.len();
    let m = ws.rows.len();
    if s > MAX_SUBSPACE || m == 0 {
        return false;
    }
    // (A + R) times each unit's column over the rows (m per unit), then K[u][v] as the unit
    // u's equation applied to it.
    // (Both are written in full below: no clearing first.)
    ws.gc.resize(s * m, 0.0);
    for v in 0..s {
        let out = &mut ws.gc[v * m..(v + 1) * m];
        // Zero coefficients may name rows outside `rows` (a tangent with μ = 0).
        let mut terms = ws.units[v].column().into_iter().filter(|(_, b)| *b != 0.0);
        // Gram is symmetric: its row c is its column c.
        let gram_row = |c: usize| &ws.gram[ws.local[c] * m..(ws.local[c] + 1) * m];
        match terms.next() {
            Some((c, b)) => {
                for (o, g) in out.iter_mut().zip(gram_row(c)) {
                    *o = b * g;
                }
            }
            None => out.fill(0.0),
        }
        for (c, b) in terms {
            for (o, g) in out.iter_mut().zip(gram_row(c)) {
                *o += b * g;
            }
        }
    }
    ws.k.resize(s * s, 0.0);
    ws.rhs.clear();
    let mut largest: f64 = 0.0;
    for u in 0..s {
        let equation = ws.units[u].equation();
        // The equation's terms with a non-zero coefficient, by local row (a zero coefficient
        // may name a row outside `rows`); K's row u is then one or two strided reads of gc
        // per entry, with no lookup of the rows inside the loop over v.
        let mut terms = [(0usize, 0.0f64); 2];
        let mut count = 0;
        for &(r, a) in equation.iter().filter(|(_, a)| *a != 0.0) {
            terms[count] = (ws.local[r], a);
            count += 1;
        }
        let k_row = &mut ws.k[u * s..(u + 1) * s];
        let gc = ws.gc.chunks_exact(m);
        match count {
            1 => {
                let (l, a) = terms[0];
                for (k, gc) in k_row.iter_mut().zip(gc) {
                    *k = a * gc[l];
                }
            }
            2 => {
                let ((l0, a0), (l1, a1)) = (terms[0], terms[1]);
                for (k, gc) in k_row.iter_mut().zip(gc) {
                    *k = a0 * gc[l0] + a1 * gc[l1];
                }
            }
            _ => k_row.fill(0.0),
        }
        let g: f64 = equation.iter().map(|&(r, a)| a * ws.w[r]).sum();
        if let Unit::Angle(c) = ws.units[u] {
            // ∂g/∂θ at fixed w: −(cos θ m₁ + sin θ m₂) (= ‖m‖ when friction opposes slip).
            ws.k[u * s + u] -= c.cos * c.mu[0] * ws.w[c.t1] + c.sin * c.mu[1] * ws.w[c.t2];
        }
        largest = largest.max(ws.k[u * s + u].abs());
        ws.rhs.push(-g);
    }
    if largest <= 0.0 || !largest.is_finite() {
        return false;
    }
    let epsilon = PROXIMAL * largest;
    let shifted_k = |lu: &mut Vec<f64>| {
        lu.clear();
        lu.extend_from_slice(&ws.k);
        for u in 0..s {
            lu[u * s + u] += epsilon;
        }
    };
    shifted_k(&mut ws.lu);
    // Only free rows (no contact on its cone, facet or vertex): K is A + R over them,
    // symmetric and positive semi-definite, and K + εI is factored by Cholesky at half the
    // LU's cost; if rounding makes a pivot non-positive, by LU after all.
    let symmetric = ws.units.iter().all(|unit| matches!(unit, Unit::Row(_)));
    let cholesky = symmetric && cholesky_factor(&mut ws.lu, s);
    if !cholesky {
        if symmetric {
            shifted_k(&mut ws.lu);
        }
        if !lu_factor(&mut ws.lu, &mut ws.pivots, s) {
            return false;
        }
    }
    let solve = |lu: &[f64], pivots: &[usize], x: &mut [f64]| {
        if cholesky {
            cholesky_solve(lu, s, x);
        } else {
            lu_solve(lu, pivots, s, x);
        }
    };
    // Proximal iteration x ← x + (K + εI)⁻¹ (r − K x), from x = 0: its first step is the
    // plain solve.
    ws.x.clear();
    ws.x.extend_from_slice(&ws.rhs);
    solve(&ws.lu, &ws.pivots, &mut ws.x);
    for _ in 1..REFINEMENTS {
        ws.correction.clear();
        for u in 0..s {
            let kx: f64 = crate::math::dot(&ws.k[u * s..(u + 1) * s], &ws.x);
            ws.correction.push(ws.rhs[u] - kx);
        }
        solve(&ws.lu, &ws.pivots, &mut ws.correction);
        for (x, d) in ws.x.iter_mut().zip(&ws.correction) {
            *x += d;
        }
    }
    ws.x.iter().all(|x| x.is_finite())
}

/// In-place LU factorisation with partial pivoting of the row-major s × s matrix `a`; false if
/// a pivot vanishes. Two columns per pass over the trailing rows: column `col`'s multipliers
/// update only column `col + 1` first (enough to choose its pivot and finish its pivot row),
/// then each row below takes both rank-1 updates in one pass, `x − f₁ u₁ − f₂ u₂` in the
/// order of two single passes — the same factors to the bit, with half the passes (the
/// reduced systems are small: ~40 unknowns, rows too short for the per-row work to vanish).
pub(super) fn lu_factor(a: &mut [f64], pivots: &mut Vec<usize>, s: usize) -> bool {
    pivots.clear();
    // Picks the pivot of column `col` among rows col.. and swaps it into row col; its inverse.
    let pivot = |a: &mut [f64], pivots: &mut Vec<usize>, col: usize| {
        let (mut best, mut best_abs) = (col, a[col * s + col].abs());
        for r in col + 1..s {
            let v = a[r * s + col].abs();
            if v > best_abs {
                (best, best_abs) = (r, v);
            }
        }
        if best_abs <= 0.0 || !best_abs.is_finite() {
            return None;
        }
        pivots.push(best);
        if best != col {
            let (upper, lower) = a.split_at_mut(best * s);
            upper[col * s..(col + 1) * s].swap_with_slice(&mut lower[..s]);
        }
        // One division per column, not one per entry below the pivot: a division's throughput
        // is that of several vector multiply-adds.
        Some(1.0 / a[col * s + col])
    };
    let mut col = 0;
    while col < s {
        let Some(inverse_first) = pivot(a, pivots, col) else { return false };
        if col + 1 == s {
            break;
        }
        // Multipliers of column col, applied to column col + 1 only.
        let next = col + 1;
        let upper_right = a[col * s + next];
        for row in a[next * s..].chunks_exact_mut(s) {
            let factor = row[col] * inverse_first;
            row[col] = factor;
            if factor != 0.0 {
                row[next] -= factor * upper_right;
            }
        }
        let Some(inverse_second) = pivot(a, pivots, next) else { return false };
        let (top, bottom) = a.split_at_mut((next + 1) * s);
        let (first_row, second_row) = top[col * s..].split_at_mut(s);
        // The second pivot row's rest takes column col's update now (it is U's row next).
        let factor = second_row[col];
        if factor != 0.0 {
            for (x, p) in second_row[next + 1..].iter_mut().zip(&first_row[next + 1..]) {
                *x -= factor * p;
            }
        }
        let (u1, u2) = (&first_row[next + 1..], &second_row[next + 1..]);
        for row in bottom.chunks_exact_mut(s) {
            let (f1, f2) = (row[col], row[next] * inverse_second);
            row[next] = f2;
            let rest = &mut row[next + 1..];
            match (f1 != 0.0, f2 != 0.0) {
                (true, true) => {
                    for ((x, p), q) in rest.iter_mut().zip(u1).zip(u2) {
                        *x = *x - f1 * p - f2 * q;
                    }
                }
                (true, false) => {
                    for (x, p) in rest.iter_mut().zip(u1) {
                        *x -= f1 * p;
                    }
                }
                (false, true) => {
                    for (x, q) in rest.iter_mut().zip(u2) {
                        *x -= f2 * q;
                    }
                }
                (false, false) => {}
            }
        }
        col += 2;
    }
    true
}

/// In-place Cholesky factorisation `a = L Lᵀ` of the symmetric row-major s × s matrix `a`
/// (row by row, each entry of L one dot product of two row heads); L is left in the lower
/// triangle, the upper one is not read. False if a pivot is not positive.
pub(super) fn cholesky_factor(a: &mut [f64], s: usize) -> bool {
    for i in 0..s {
        let (done, rest) = a.split_at_mut(i * s);
        let row_i = &mut rest[..s];
        for j in 0..i {
            let row_j = &done[j * s..j * s + j + 1];
            let sum = crate::math::dot(&row_i[..j], &row_j[..j]);
            row_i[j] = (row_i[j] - sum) / row_j[j];
        }
        let pivot = row_i[i] - crate::math::dot(&row_i[..i], &row_i[..i]);
        if pivot.is_nan() || pivot <= 0.0 {
            return false;
        }
        row_i[i] = pivot.sqrt();
    }
    true
}

/// Solves with the factor of [`cholesky_factor`], in place: `L y = b`, then `Lᵀ x = y` by
/// columns of Lᵀ (rows of L, contiguous).
pub(super) fn cholesky_solve(l: &[f64], s: usize, x: &mut [f64]) {
    for r in 0..s {
        let sum = crate::math::dot(&l[r * s..r * s + r], &x[..r]);
        x[r] = (x[r] - sum) / l[r * s + r];
    }
    for r in (0..s).rev() {
        let xr = x[r] / l[r * s + r];
        x[r] = xr;
        for (x, l) in x[..r].iter_mut().zip(&l[r * s..r * s + r]) {
            *x -= l * xr;
        }
    }
}

/// Solves with the factors of [`lu_factor`], in place.
pub(super) fn lu_solve(lu: &[f64], pivots: &[usize], s: usize, x: &mut [f64]) {
    for (col, &p) in pivots.iter().enumerate() {
        x.swap(col, p);
    }
    for r in 0..s {
        let sum: f64 = crate::math::dot(&lu[r * s..r * s + r], &x[..r]);
        x[r] -= sum;
    }
    for r in (0..s).rev() {
        let sum: f64 = crate::math::dot(&lu[r * s + r + 1..(r + 1) * s], &x[r + 1..]);
        x[r] = (x[r] - sum) / lu[r * s + r];
    }
}
