//! Row and column equilibration of an LCP. For positive diagonal D and E, `w = M z + q` with
//! `0 ≤ z ⟂ w ≥ 0` holds exactly when `w' = (D M E) z' + D q` with `0 ≤ z' ⟂ w' ≥ 0` does, for
//! `z = E z'` and `w' = D w`: complementarity is kept by any positive scaling of the pairs. A
//! 1000:1 mass ratio gives M entries 1000 times apart; after Ruiz's equilibration (Ruiz 2001:
//! repeated division of each row and column by the square root of its largest entry) every row
//! and column of D M E has its largest magnitude near 1, so that one pivot tolerance fits all.
//! The factors are rounded to powers of two, which scale without rounding error.

use super::columns::Csc;

/// Row factors D and column factors E (powers of two).
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Scaling {
    /// D: w' = D w.
    pub row: Vec<f64>,
    /// E: z = E z'.
    pub col: Vec<f64>,
}

impl Scaling {
    /// No scaling.
    pub fn identity(n: usize) -> Self {
        Self { row: vec![1.0; n], col: vec![1.0; n] }
    }

    /// Ruiz's equilibration of M in `iterations` sweeps.
    pub fn equilibrate(m: &Csc, iterations: usize) -> Self {
        let n = m.n();
        let (mut row, mut col) = (vec![1.0; n], vec![1.0; n]);
        let (mut row_max, mut col_max) = (vec![0.0f64; n], vec![0.0f64; n]);
        for _ in 0..iterations {
            row_max.fill(0.0);
            col_max.fill(0.0);
            for j in 0..n {
                let (rows, values) = m.column(j);
                let (c, mut largest) = (col[j], 0.0f64);
                for (&i, &v) in rows.iter().zip(values) {
                    let a = (row[i] * v * c).abs();
                    row_max[i] = row_max[i].max(a);
                    largest = largest.max(a);
                }
                col_max[j] = largest;
            }
            let mut settled = true;
            for (f, &x) in row.iter_mut().zip(&row_max).chain(col.iter_mut().zip(&col_max)) {
                if x > 0.0 && x.is_finite() {
                    *f /= x.sqrt();
                    settled &= (x - 1.0).abs() < 0.1;
                }
            }
            if settled {
                break;
            }
        }
        let power_of_two = |x: f64| 2f64.powi(x.log2().round().clamp(-1000.0, 1000.0) as i32);
        Self {
            row: row.into_iter().map(power_of_two).collect(),
            col: col.into_iter().map(power_of_two).collect(),
        }
    }

    /// Whether every factor is 1.
    pub fn is_identity(&self) -> bool {
        self.row.iter().chain(&self.col).all(|&x| x == 1.0)
    }
}
