//! Sparse columns: the LCP of a contact problem couples only contacts that share a body, so
//! most of M is zero, and Lemke's work per pivot follows M's non-zeros, not its n².

use super::lcp::SparseLcp;
use nalgebra::DMatrix;

/// An n × n matrix by compressed sparse columns (exact zeros dropped; rows within a column in
/// no particular order).
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Csc {
    n: usize,
    start: Vec<usize>,
    rows: Vec<usize>,
    values: Vec<f64>,
}

impl Csc {
    /// The non-zeros of a dense square matrix.
    pub fn from_dense(m: &DMatrix<f64>) -> Self {
        let n = m.nrows();
        let mut out = Self::with_capacity(n, 0);
        for j in 0..n {
            for (i, &v) in m.column(j).iter().enumerate() {
                if v != 0.0 {
                    out.rows.push(i);
                    out.values.push(v);
                }
            }
            out.start.push(out.rows.len());
        }
        out
    }

    /// An empty n × n matrix to be filled column by column with [`Self::push`] and
    /// [`Self::end_column`].
    pub fn with_capacity(n: usize, nonzeros: usize) -> Self {
        let mut start = Vec::with_capacity(n + 1);
        start.push(0);
        Self { n, start, rows: Vec::with_capacity(nonzeros), values: Vec::with_capacity(nonzeros) }
    }

    /// Number of stored entries.
    pub fn nonzeros(&self) -> usize {
        self.values.len()
    }

    /// Appends entry (i, v) to the column being filled.
    #[inline]
    pub fn push(&mut self, i: usize, v: f64) {
        self.rows.push(i);
        self.values.push(v);
    }

    /// Closes the column being filled.
    pub fn end_column(&mut self) {
        self.start.push(self.rows.len());
    }

    /// `diag(row_scale) · self · diag(col_scale)`.
    pub fn scaled(&self, row_scale: &[f64], col_scale: &[f64]) -> Self {
        let mut out = Self::default();
        self.scaled_into(row_scale, col_scale, &mut out);
        out
    }

    /// [`Self::scaled`] into `out` (its buffers reused).
    pub fn scaled_into(&self, row_scale: &[f64], col_scale: &[f64], out: &mut Self) {
        out.n = self.n;
        out.start.clone_from(&self.start);
        out.rows.clone_from(&self.rows);
        out.values.clear();
        out.values.reserve(self.values.len());
        for (j, &c) in col_scale.iter().enumerate().take(self.n) {
            let range = self.start[j]..self.start[j + 1];
            out.values.extend(
                self.rows[range.clone()].iter().zip(&self.values[range]).map(|(&i, &v)| v * row_scale[i] * c),
            );
        }
    }

    /// Size n.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The non-zeros of column j.
    #[inline]
    pub fn column(&self, j: usize) -> (&[usize], &[f64]) {
        let range = self.start[j]..self.start[j + 1];
        (&self.rows[range.clone()], &self.values[range])
    }

    /// Entry (j, j).
    pub fn diagonal(&self, j: usize) -> f64 {
        let (rows, values) = self.column(j);
        rows.iter().zip(values).filter(|(&i, _)| i == j).map(|(_, &v)| v).sum()
    }

    /// The largest |entry|.
    pub fn max_abs(&self) -> f64 {
        self.values.iter().fold(0.0f64, |m, &v| m.max(v.abs()))
    }

    /// out += self · z.
    pub fn mul_add(&self, z: &[f64], out: &mut [f64]) {
        for (j, &zj) in z.iter().enumerate() {
            if zj != 0.0 {
                let (rows, values) = self.column(j);
                for (&i, &v) in rows.iter().zip(values) {
                    out[i] += v * zj;
                }
            }
        }
    }

    /// out = selfᵀ · y.
    pub fn tr_mul(&self, y: &[f64], out: &mut [f64]) {
        for (j, o) in out.iter_mut().enumerate() {
            let (rows, values) = self.column(j);
            *o = rows.iter().zip(values).map(|(&i, &v)| v * y[i]).sum();
        }
    }
}

/// M as a path reads it: formed by sparse columns, or a contact LCP's columns formed as read.
#[derive(Clone, Copy)]
pub(super) enum Matrix<'m> {
    /// M by sparse columns.
    Formed(&'m Csc),
    /// A contact problem's LCP, its columns formed on first use.
    Lazy(&'m SparseLcp),
}

/// The columns of Lemke's system `I w − M z − d z0 = q`: M (as the path sees it, possibly
/// equilibrated) and the covering vector d.
pub(super) struct Columns<'m> {
    /// M.
    pub m: Matrix<'m>,
    /// The covering vector d (all entries positive).
    pub d: Vec<f64>,
}

impl Columns<'_> {
    /// Number of rows (and of z variables).
    pub fn n(&self) -> usize {
        match self.m {
            Matrix::Formed(m) => m.n(),
            Matrix::Lazy(lcp) => lcp.q.len(),
        }
    }

    /// Calls `f(row, value)` for the non-zeros of the column of variable `var` in
    /// `[I, −M, −d]` (w_i = i, z_j = n + j, z0 = 2n).
    #[inline]
    pub fn for_each(&self, var: usize, mut f: impl FnMut(usize, f64)) {
        let n = self.n();
        if var < n {
            f(var, 1.0);
        } else if var < 2 * n {
            match self.m {
                Matrix::Formed(m) => {
                    let (rows, values) = m.column(var - n);
                    for (&i, &v) in rows.iter().zip(values) {
                        f(i, -v);
                    }
                }
                Matrix::Lazy(lcp) => lcp.for_each_in_column(var - n, |i, v| f(i, -v)),
            }
        } else {
            for (i, &v) in self.d.iter().enumerate() {
                f(i, -v);
            }
        }
    }
}
