//! The laws of the Newton solver's groups of rows, as projections in the metric of the
//! regularisation E: a row with bounds (bilateral, unilateral, box) or a contact's normal and
//! friction rows in the Coulomb cone. For each group the solver needs the impulse
//! `λ(y) = Π_C(−E⁻¹ y)` (the projection in the E-norm) and its derivative
//! `G = −∂λ/∂y = Π'_C(−E⁻¹ y) E⁻¹`, a symmetric positive semi-definite block of the Hessian.

/// A group of rows that share one law.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Group {
    /// One row with `lo ≤ λ ≤ hi` (N·s; bilateral rows: ±∞, unilateral rows: 0 and +∞).
    Row {
        /// The row.
        row: usize,
        /// Lower bound (N·s, may be −∞).
        lo: f64,
        /// Upper bound (N·s, may be +∞).
        hi: f64,
    },
    /// A contact whose normal is `normal` and friction rows `normal + 1`, `normal + 2`, with
    /// the cone `‖(λ₁/μ, λ₂/μ₂)‖ ≤ λ_n`. In the scaled impulses `λ'_k = √e_k λ_k` (e chosen
    /// so that `μ √e₁ = μ₂ √e₂`) it is the circular cone `‖λ'_t‖ ≤ slope · λ'_n`.
    Cone {
        /// Row of the normal.
        normal: usize,
        /// Slope of the circular cone in scaled impulses: `μ √(e₁ / e_n)`.
        slope: f64,
    },
}

impl Group {
    /// The first row and the number of rows (1 or 3).
    pub(super) fn rows(&self) -> (usize, usize) {
        match *self {
            Group::Row { row, .. } => (row, 1),
            Group::Cone { normal, .. } => (normal, 3),
        }
    }
}

/// The zone of a group at some y: which piece of the piecewise-smooth law applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Zone {
    /// λ = 0 or at a bound: no curvature.
    Free,
    /// Inside the set: G = E⁻¹ on every row of the group.
    Interior,
    /// On the boundary of the cone (a sliding contact): G is the cone's projection derivative.
    Boundary,
}

/// λ of a group at row values `y` (its 1 or 3 entries), in the metric `e` (its rows' E), with
/// `inv_sqrt_e` = 1/√e: writes λ into `lambda` and, when `hessian` is given, G (row-major
/// k × k) into it; returns the zone.
pub(super) fn project(
    group: &Group,
    y: &[f64],
    e: &[f64],
    inv_sqrt_e: &[f64],
    lambda: &mut [f64],
    hessian: Option<&mut [f64]>,
) -> Zone {
    match *group {
        Group::Row { lo, hi, .. } => {
            let z = -y[0] / e[0];
            let (l, zone) = if z <= lo {
                (lo, Zone::Free)
            } else if z >= hi {
                (hi, Zone::Free)
            } else {
                (z, Zone::Interior)
            };
            lambda[0] = l;
            if let Some(h) = hessian {
                h[0] = if zone == Zone::Interior { 1.0 / e[0] } else { 0.0 };
            }
            zone
        }
        Group::Cone { slope, .. } => {
            // Scaled z' = −E^{-1/2} y and its Euclidean projection onto the circular cone.
            let zn = -y[0] * inv_sqrt_e[0];
            let z1 = -y[1] * inv_sqrt_e[1];
            let z2 = -y[2] * inv_sqrt_e[2];
            let r = (z1 * z1 + z2 * z2).sqrt();
            if r <= slope * zn {
                lambda[0] = zn * inv_sqrt_e[0];
                lambda[1] = z1 * inv_sqrt_e[1];
                lambda[2] = z2 * inv_sqrt_e[2];
                if let Some(h) = hessian {
                    h.fill(0.0);
                    for k in 0..3 {
                        h[4 * k] = 1.0 / e[k];
                    }
                }
                return Zone::Interior;
            }
            if slope * r <= -zn {
                lambda[..3].fill(0.0);
                if let Some(h) = hessian {
                    h.fill(0.0);
                }
                return Zone::Free;
            }
            // The boundary: t (1, slope t̂) with t = (z_n + slope r) / (1 + slope²).
            let inv = 1.0 / (1.0 + slope * slope);
            let t = (zn + slope * r) * inv;
            let (c, s) = (z1 / r, z2 / r);
            lambda[0] = t * inv_sqrt_e[0];
            lambda[1] = slope * t * c * inv_sqrt_e[1];
            lambda[2] = slope * t * s * inv_sqrt_e[2];
            if let Some(h) = hessian {
                // Π' = v vᵀ/(1 + slope²) + slope t / r (I − t̂ t̂ᵀ) on the tangent plane, with
                // v = (1, slope t̂); then G = E^{-1/2} Π' E^{-1/2}.
                let v = [1.0, slope * c, slope * s];
                let curl = slope * t / r;
                let tangent = [[0.0, 0.0, 0.0], [0.0, 1.0 - c * c, -c * s], [0.0, -c * s, 1.0 - s * s]];
                for a in 0..3 {
                    for b in 0..3 {
                        let p = v[a] * v[b] * inv + curl * tangent[a][b];
                        h[3 * a + b] = inv_sqrt_e[a] * p * inv_sqrt_e[b];
                    }
                }
            }
            Zone::Boundary
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// λ(y) of the cone is the E-metric projection: it lies in the cone, and its derivative
    /// G matches finite differences of −λ in every zone.
    #[test]
    fn cone_projection_and_its_derivative() {
        let e = [0.3, 0.7, 0.7];
        let inv_sqrt_e = e.map(|x: f64| 1.0 / x.sqrt());
        let mu = 0.6;
        let slope = mu * (e[1] / e[0]).sqrt();
        let group = Group::Cone { normal: 0, slope };
        let points = [[-1.0, 0.1, -0.2], [-1.0, 2.0, 0.5], [1.0, 0.1, 0.2], [-0.2, 0.9, -0.4]];
        let mut zones = Vec::new();
        for y in points {
            let mut l = [0.0; 3];
            let mut g = [0.0; 9];
            zones.push(project(&group, &y, &e, &inv_sqrt_e, &mut l, Some(&mut g)));
            assert!((l[1] * l[1] + l[2] * l[2]).sqrt() <= mu * l[0] + 1e-12, "{l:?} outside the cone");
            for k in 0..3 {
                let step = 1e-7;
                let (mut yp, mut ym) = (y, y);
                yp[k] += step;
                ym[k] -= step;
                let (mut lp, mut lm) = ([0.0; 3], [0.0; 3]);
                project(&group, &yp, &e, &inv_sqrt_e, &mut lp, None);
                project(&group, &ym, &e, &inv_sqrt_e, &mut lm, None);
                for a in 0..3 {
                    let fd = -(lp[a] - lm[a]) / (2.0 * step);
                    assert!(
                        (fd - g[3 * a + k]).abs() < 1e-6,
                        "zone {:?}: G[{a}][{k}] {} vs {fd}",
                        zones.last(),
                        g[3 * a + k]
                    );
                }
            }
        }
        assert!(
            zones.contains(&Zone::Interior) && zones.contains(&Zone::Free) && zones.contains(&Zone::Boundary)
        );
    }

    /// The projection in the E-metric minimises ½ (λ − z)ᵀ E (λ − z) over the cone: no point
    /// of a fine sample of the cone does better.
    #[test]
    fn cone_projection_is_the_nearest_point_in_the_metric() {
        let e = [0.5, 2.0, 2.0];
        let inv_sqrt_e = e.map(|x: f64| 1.0 / x.sqrt());
        let mu = 0.8;
        let group = Group::Cone { normal: 0, slope: mu * (e[1] / e[0]).sqrt() };
        let y = [-0.4, 1.3, 0.2];
        let mut l = [0.0; 3];
        project(&group, &y, &e, &inv_sqrt_e, &mut l, None);
        let z = [-y[0] / e[0], -y[1] / e[1], -y[2] / e[2]];
        let cost = |p: [f64; 3]| (0..3).map(|k| e[k] * (p[k] - z[k]).powi(2)).sum::<f64>();
        let best = cost(l);
        for i in 0..=60 {
            let n = 2.0 * i as f64 / 60.0;
            for j in 0..=60 {
                let radius = mu * n * j as f64 / 60.0;
                for k in 0..72 {
                    let angle = std::f64::consts::TAU * k as f64 / 72.0;
                    let p = [n, radius * angle.cos(), radius * angle.sin()];
                    assert!(cost(p) >= best - 1e-12, "{p:?} is nearer than {l:?}");
                }
            }
        }
    }
}
