//! The certificate of a Lemke path that ends on a secondary ray, checked against the original
//! LCP `w = M z + q` (not the equilibrated one the path ran on).
//!
//! When the entering column has no positive entry, the path's point (z*, z0* > 0) moves along
//! (dz, dz0) forever: z(t) = z* + t dz ≥ 0, z0(t) = z0* + t dz0 > 0 and
//! w(t) = M z(t) + q + d z0(t) ≥ 0 stay complementary for every t ≥ 0, so z0 never reaches 0 and
//! no solution is reachable from the covering vector d. The certificate recomputes w* and
//! dw = M dz + d dz0 from M, q and d and reports how far these conditions fail.
//!
//! If moreover y = dz ≥ 0 has `Mᵀy ≤ 0` and `qᵀy < 0`, y is a Farkas certificate that the LCP
//! has no feasible point at all: for any z ≥ 0, yᵀ(M z + q) = (Mᵀy)ᵀz + qᵀy < 0, so some
//! component of M z + q is negative (Cottle, Pang & Stone, Theorem 4.4.13, gives this outcome
//! for copositive-plus M; the check here needs no assumption on M).

use super::columns::Csc;
use nalgebra::DVector;

/// A secondary ray of Lemke's method with the numbers that check it.
#[derive(Clone, Debug, PartialEq)]
pub struct RayCertificate {
    /// The covering vector the path started from (`ones`, `golden`, `diagonal`).
    pub covering: &'static str,
    /// Whether the path ran on the equilibrated LCP (the numbers below are in the original's units).
    pub equilibrated: bool,
    /// z* at the ray's start.
    pub start: Vec<f64>,
    /// The artificial variable z0* > 0 at the ray's start.
    pub start_z0: f64,
    /// The ray's direction dz, scaled so that max(‖dz‖∞, |dz0|) = 1.
    pub direction: Vec<f64>,
    /// The rate dz0 of the artificial variable along the ray (same scale).
    pub direction_z0: f64,
    /// The largest violation of the ray's conditions (dz, dz0, dw ≥ 0 and the complementarity
    /// of z(t) and w(t)), each relative to the scale of its terms: rounding-level (≤ 1e-8)
    /// when the path really leaves along a ray.
    pub ray_error: f64,
    /// qᵀy for y = max(dz, 0).
    pub q_dot_y: f64,
    /// max_j (Mᵀy)_j⁺ for the same y.
    pub mty_excess: f64,
    /// No z ≥ 0 with ‖z‖₁ below this radius has M z + q ≥ 0 (−qᵀy / max(Mᵀy)⁺; infinite when
    /// Mᵀy ≤ 0 holds exactly, 0 when qᵀy ≥ 0).
    pub infeasible_radius: f64,
    /// y proves the LCP infeasible: qᵀy < 0 and Mᵀy ≤ 0 up to rounding (1e-12 of ‖M‖·‖y‖₁).
    pub infeasible: bool,
}

/// The largest |entry| of a slice.
fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, &x| m.max(x.abs()))
}

impl RayCertificate {
    /// The certificate of the ray from (z*, z0*) along (dz, dz0) for `w = M z + q + d z0`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn check(
        m: &Csc,
        q: &DVector<f64>,
        d: &[f64],
        start: Vec<f64>,
        start_z0: f64,
        mut direction: Vec<f64>,
        mut direction_z0: f64,
        covering: &'static str,
        equilibrated: bool,
    ) -> Self {
        let n = q.len();
        let norm = max_abs(&direction).max(direction_z0.abs());
        if norm > 0.0 {
            direction.iter_mut().for_each(|x| *x /= norm);
            direction_z0 /= norm;
        }
        let z = DVector::from_column_slice(&start);
        let dz = DVector::from_column_slice(&direction);
        let mut w: DVector<f64> = q + DVector::from_fn(n, |i, _| d[i] * start_z0);
        m.mul_add(z.as_slice(), w.as_mut_slice());
        let mut dw = DVector::from_fn(n, |i, _| d[i] * direction_z0);
        m.mul_add(dz.as_slice(), dw.as_mut_slice());
        let m_abs = m.max_abs();
        let m_scale = m_abs.max(max_abs(d)).max(f64::MIN_POSITIVE);
        let w_scale = w.amax().max(q.amax()).max(f64::MIN_POSITIVE);
        let z_scale = z.amax().max(f64::MIN_POSITIVE);
        let mut error = (-direction_z0).max(0.0);
        for i in 0..n {
            error = error
                .max(-dz[i])
                .max(-dw[i] / m_scale)
                .max((dz[i] * w[i]).abs() / w_scale)
                .max((z[i] * dw[i]).abs() / (z_scale * m_scale))
                .max((dz[i] * dw[i]).abs() / m_scale);
        }
        let y = dz.map(|x| x.max(0.0));
        let q_dot_y = q.dot(&y);
        let mut mty = vec![0.0; n];
        m.tr_mul(y.as_slice(), &mut mty);
        let mty_excess = mty.iter().fold(0.0f64, |a, &x| a.max(x));
        let infeasible_radius = if q_dot_y >= 0.0 {
            0.0
        } else if mty_excess == 0.0 {
            f64::INFINITY
        } else {
            -q_dot_y / mty_excess
        };
        let y_norm = y.sum();
        let infeasible =
            y_norm > 0.0 && q_dot_y < -1e-12 * q.amax() * y_norm && mty_excess <= 1e-12 * m_abs * y_norm;
        Self {
            covering,
            equilibrated,
            start,
            start_z0,
            direction,
            direction_z0,
            ray_error: if error.is_nan() { f64::INFINITY } else { error },
            q_dot_y,
            mty_excess,
            infeasible_radius,
            infeasible,
        }
    }
}

impl std::fmt::Display for RayCertificate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "covering vector {}{}: z0 = {:.3e} at the ray's start, rate {:.3e} along it; the ray meets \
             M and q to {:.1e}; ",
            self.covering,
            if self.equilibrated { " (equilibrated)" } else { "" },
            self.start_z0,
            self.direction_z0,
            self.ray_error
        )?;
        if self.infeasible {
            write!(
                f,
                "its direction y proves the LCP infeasible (qᵀy = {:.3e} < 0, max(Mᵀy)⁺ = {:.1e})",
                self.q_dot_y, self.mty_excess
            )
        } else {
            write!(
                f,
                "no Farkas proof of infeasibility (qᵀy = {:.3e}, max(Mᵀy)⁺ = {:.1e})",
                self.q_dot_y, self.mty_excess
            )
        }
    }
}
