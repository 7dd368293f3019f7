//! M's columns one at a time, for a path from a warm start: column j is
//! `Cᵀ (A + R) C e_j + E e_j`, formed the first time the path reads it and kept. A path that
//! starts at the last step's basis touches its basic columns and the few that enter — a few
//! hundred of a pile's thousands — so forming M in full (most of a cold solve's assembly) is
//! left to the paths from the identity ([`SparseLcp::form_m`]).

use super::basis::NONE;
use super::lcp::SparseLcp;

/// The columns of M formed so far, packed.
#[derive(Clone, Debug, Default)]
pub(super) struct ColumnCache {
    /// Per column: where its entries start in `rows` / `values`, or [`NONE`]; and how many.
    start: Vec<usize>,
    count: Vec<usize>,
    rows: Vec<usize>,
    values: Vec<f64>,
    /// Scratch: the two impulse rows' products by LCP row, and the rows they touch.
    g: [Vec<f64>; 2],
    seen: Vec<bool>,
    touched: Vec<usize>,
}

impl SparseLcp {
    /// Calls `f(i, M_ij)` for the non-zeros of column j of M (of the formed M when there is
    /// one, else of the cache, forming the column on first use).
    #[inline]
    pub fn for_each_in_column(&self, j: usize, mut f: impl FnMut(usize, f64)) {
        if let Some(m) = &self.m {
            let (rows, values) = m.column(j);
            for (&i, &v) in rows.iter().zip(values) {
                f(i, v);
            }
            return;
        }
        if self.cache.borrow().start.get(j).is_none_or(|&s| s == NONE) {
            self.form_column(j);
        }
        let cache = self.cache.borrow();
        let range = cache.start[j]..cache.start[j] + cache.count[j];
        for (&i, &v) in cache.rows[range.clone()].iter().zip(&cache.values[range]) {
            f(i, v);
        }
    }

    /// out += M z, by the columns of z's non-zeros.
    pub fn mul_add(&self, z: &[f64], out: &mut [f64]) {
        for (j, &zj) in z.iter().enumerate() {
            if zj != 0.0 {
                self.for_each_in_column(j, |i, v| out[i] += v * zj);
            }
        }
    }

    /// Forms column j into the cache, with the arithmetic of the full assembly (each impulse
    /// row's products g_r = Cᵀ (A + R) e_r summed first, then C_rj g_r).
    fn form_column(&self, j: usize) {
        let m = self.q.len();
        let mut cache = self.cache.borrow_mut();
        let cache = &mut *cache;
        if cache.start.len() != m {
            cache.start = vec![NONE; m];
            cache.count = vec![0; m];
            cache.g = [vec![0.0; m], vec![0.0; m]];
            cache.seen = vec![false; m];
        }
        let column = &self.c[j];
        for (slot, &(r, _)) in column.iter().enumerate() {
            let (rows, values) = self.a.column(r);
            for (&s, &v) in rows.iter().zip(values) {
                for &(i, x) in &self.vars_of_row[s] {
                    if !cache.seen[i] {
                        cache.seen[i] = true;
                        cache.touched.push(i);
                    }
                    cache.g[slot][i] += x * v;
                }
            }
        }
        let start = cache.rows.len();
        let value = |cache: &ColumnCache, i: usize| match column.len() {
            0 => 0.0,
            1 => column[0].1 * cache.g[0][i],
            _ => column[0].1 * cache.g[0][i] + column[1].1 * cache.g[1][i],
        };
        // E's entries (at most one per row) added where they fall.
        let mut extra_done = vec![false; self.extra_of_column[j].len()];
        for t in 0..cache.touched.len() {
            let i = cache.touched[t];
            let mut v = value(cache, i);
            for (e, &(row, x)) in self.extra_of_column[j].iter().enumerate() {
                if row == i {
                    v += x;
                    extra_done[e] = true;
                }
            }
            if v != 0.0 {
                cache.rows.push(i);
                cache.values.push(v);
            }
        }
        for (e, &(row, x)) in self.extra_of_column[j].iter().enumerate() {
            if !extra_done[e] && x != 0.0 {
                cache.rows.push(row);
                cache.values.push(x);
            }
        }
        for t in 0..cache.touched.len() {
            let i = cache.touched[t];
            cache.g[0][i] = 0.0;
            cache.g[1][i] = 0.0;
            cache.seen[i] = false;
        }
        cache.touched.clear();
        cache.start[j] = start;
        cache.count[j] = cache.rows.len() - start;
    }
}
