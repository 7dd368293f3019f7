//! A + R over the rows of the active set: the Gram matrix of W's rows, from lanes of up to
//! four rows at a time when A is matrix-free.

use super::*;

/// Most entries of the lane copy of W's rows that [`fill_gram`] makes (rows × velocity
/// columns): beyond it (hundreds of multibodies in one world) the Gram is formed entry by entry.
pub(super) const MAX_DENSE_W: usize = 1 << 16;

/// Rows of W packed side by side as the lanes of one group in [`fill_gram`].
pub(super) const GROUP: usize = 4;

/// A + R over `ws.rows` into `ws.gram`. When A is matrix-free: W's rows grouped, up to
/// [`GROUP`] consecutive rows with the same column range (a contact's normal and tangent rows
/// act on the same bodies), each group copied as lanes (`w_lanes[col]` holds its rows' entries
/// in that column), and each block of the Gram between two groups one pass over the overlap of
/// their runs per row of the first group ([`gram_block`]), each column adding that row's entry
/// times the other group's four — up to sixteen products per column pair of lanes, where one dot
/// product per pair of rows would load them once per pair (hundreds of short dots per subspace
/// step of a humanoid). Else (A formed, or a world too wide for the copy) entry by entry.
pub(super) fn fill_gram(problem: &ConstraintProblem, ws: &mut SubspaceWorkspace) {
    let m = ws.rows.len();
    // Every entry is written below (a block of two groups that share no column as zeros): no
    // clearing of the m² entries first.
    ws.gram.resize(m * m, 0.0);
    let sp = &problem.sparsity;
    let nv = sp.nv;
    if problem.is_matrix_free() && m * nv <= MAX_DENSE_W {
        // Each row's column range [lo, hi) (empty: lo = hi).
        ws.w_range.clear();
        for &r in &ws.rows {
            let (mut lo, mut hi) = (nv, 0);
            for (col, w) in sp.row_spans(r) {
                lo = lo.min(col);
                hi = hi.max(col + w.len());
            }
            ws.w_range.push(if lo < hi { (lo, hi) } else { (0, 0) });
        }
        // Groups: (first row, rows, offset of its lanes in `w_lanes`), and each group's runs:
        // those of its rows when they all have the same (a contact's three rows do), else its
        // whole range.
        ws.groups.clear();
        ws.w_lanes.clear();
        ws.group_runs.clear();
        ws.group_run_start.clear();
        let runs_of = |r: usize| sp.row_spans(r).map(|(col, w)| (col, col + w.len()));
        let mut a = 0;
        while a < m {
            let range = ws.w_range[a];
            let mut count = 1;
            while count < GROUP && a + count < m && ws.w_range[a + count] == range {
                count += 1;
            }
            let offset = ws.w_lanes.len();
            ws.w_lanes.resize(offset + range.1 - range.0, [0.0; GROUP]);
            for lane in 0..count {
                for (col, w) in sp.row_spans(ws.rows[a + lane]) {
                    let at = offset + col - range.0;
                    for (x, v) in ws.w_lanes[at..at + w.len()].iter_mut().zip(w) {
                        x[lane] = *v;
                    }
                }
            }
            ws.group_run_start.push(ws.group_runs.len());
            let first = ws.rows[a];
            if (1..count).all(|lane| runs_of(ws.rows[a + lane]).eq(runs_of(first))) {
                let at = ws.group_runs.len();
                ws.group_runs.extend(runs_of(first));
                // Increasing within each multibody's block; a row on two multibodies lists its
                // blocks in the contact's order.
                ws.group_runs[at..].sort_unstable();
            } else if range.0 < range.1 {
                ws.group_runs.push(range);
            }
            ws.groups.push((a, count, offset));
            a += count;
        }
        ws.group_run_start.push(ws.group_runs.len());
        for (g, &(a, count_a, offset_a)) in ws.groups.iter().enumerate() {
            let lo_a = ws.w_range[a].0;
            let runs_a = &ws.group_runs[ws.group_run_start[g]..ws.group_run_start[g + 1]];
            for (h, &(b, count_b, offset_b)) in ws.groups.iter().enumerate().skip(g) {
                let lo_b = ws.w_range[b].0;
                let runs_b = &ws.group_runs[ws.group_run_start[h]..ws.group_run_start[h + 1]];
                let mut block = [[0.0; GROUP]; GROUP];
                // Only where both groups' runs overlap: elsewhere one side is zero (a left
                // foot's rows and a right foot's share the root's columns, not the legs'), and
                // the products skipped are exact zeros, so the sums are those over the whole
                // range, to the bit.
                let (mut i, mut j) = (0, 0);
                while i < runs_a.len() && j < runs_b.len() {
                    let (from, to) = (runs_a[i].0.max(runs_b[j].0), runs_a[i].1.min(runs_b[j].1));
                    if from < to {
                        let ua = &ws.w_lanes[offset_a + from - lo_a..offset_a + to - lo_a];
                        let ub = &ws.w_lanes[offset_b + from - lo_b..offset_b + to - lo_b];
                        gram_block(ua, ub, count_a, &mut block);
                    }
                    if runs_a[i].1 <= runs_b[j].1 {
                        i += 1;
                    } else {
                        j += 1;
                    }
                }
                for (i, row) in block.iter().enumerate().take(count_a) {
                    for (j, &value) in row.iter().enumerate().take(count_b) {
                        ws.gram[(a + i) * m + b + j] = value;
                        ws.gram[(b + j) * m + a + i] = value;
                    }
                }
            }
        }
    } else {
        for a in 0..m {
            for b in a..m {
                let g = problem.delassus_entry(ws.rows[a], ws.rows[b]);
                ws.gram[a * m + b] = g;
                ws.gram[b * m + a] = g;
            }
        }
    }
    for (a, &r) in ws.rows.iter().enumerate() {
        ws.gram[a * m + a] += problem.regularization[r];
    }
}

/// Adds to `block[i][j]` the products of lane i of `ua` (group a's rows, `count_a` of them)
/// and lane j of `ub` over the columns both cover, column by column. One pass per two rows of
/// group a (a contact's group has three): each pass keeps each row's four sums in one vector
/// register, where the 4 × 4 block updated per column made the compiler shuffle x and y into
/// 8-wide vectors (and three rows per pass cost more instructions than two).
pub(super) fn gram_block(
    ua: &[[f64; GROUP]],
    ub: &[[f64; GROUP]],
    count_a: usize,
    block: &mut [[f64; GROUP]; GROUP],
) {
    let mut i = 0;
    while i + 1 < count_a {
        // Two rows of group a per pass: each y loaded once for both.
        let (first, second) = block.split_at_mut(i + 1);
        let (row0, row1) = (&mut first[i], &mut second[0]);
        for (x, y) in ua.iter().zip(ub) {
            let (x0, x1) = (x[i], x[i + 1]);
            for ((acc0, acc1), &yj) in row0.iter_mut().zip(row1.iter_mut()).zip(y) {
                *acc0 += x0 * yj;
                *acc1 += x1 * yj;
            }
        }
        i += 2;
    }
    if i < count_a {
        let row = &mut block[i];
        for (x, y) in ua.iter().zip(ub) {
            let xi = x[i];
            for (acc, &yj) in row.iter_mut().zip(y) {
                *acc += xi * yj;
            }
        }
    }
}
