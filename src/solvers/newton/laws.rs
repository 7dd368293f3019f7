//! The laws of the Newton solver's groups of rows, as projections in the metric of the
//! regularisation E: a row with bounds (bilateral, unilateral, box) or a contact's normal and
//! friction rows in the Coulomb cone or in a k-facet friction pyramid. For each group the solver needs the impulse
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
    /// A contact whose normal is `normal` and friction rows `normal + 1`, `normal + 2`, with the
    /// k-facet pyramid of [`crate::constraints::FrictionModel::Pyramid`]: the cone spanned by
    /// the edges `(1, μ cos θ_j, μ₂ sin θ_j)`, `θ_j = 2πj/k` (the convex hull of the vertices
    /// `λ_n (μ cos θ_j, μ₂ sin θ_j)`).
    Pyramid {
        /// Row of the normal.
        normal: usize,
        /// Number of facets k (3 ≤ k ≤ [`crate::constraints::MAX_PYRAMID_FACETS`]).
        facets: usize,
        /// Friction coefficients along the first and the second tangent (> 0).
        mu: f64,
        mu2: f64,
    },
}

impl Group {
    /// The first row and the number of rows (1 or 3).
    pub(super) fn rows(&self) -> (usize, usize) {
        match *self {
            Group::Row { row, .. } => (row, 1),
            Group::Cone { normal, .. } | Group::Pyramid { normal, .. } => (normal, 3),
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
    /// On facet j of a pyramid (a sliding contact): G projects onto the facet's plane.
    Facet(usize),
    /// On edge j of a pyramid (a contact sliding against a vertex direction): G projects onto
    /// the edge's line.
    Edge(usize),
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
        Group::Pyramid { facets, mu, mu2, .. } => {
            project_on_pyramid(facets, mu, mu2, y, inv_sqrt_e, lambda, hessian)
        }
    }
}

/// The pyramid's [`project`]: in scaled impulses `λ' = E^{1/2} λ` the pyramid is a polyhedral
/// cone with facet normals `a'_j = E^{-1/2} a_j`, `a_j = (−cos(π/k), n_j₁/μ, n_j₂/μ₂)` (n_j the
/// facet's unit normal in the friction plane, `a_j · λ ≤ 0` inside) and edges `v'_j = E^{1/2}
/// (1, μ cos θ_j, μ₂ sin θ_j)`; the Euclidean projection of `z' = −E^{-1/2} y` onto it is the
/// nearest of the candidates that lie in it: z' itself, z' projected on a facet's plane where
/// that falls between the facet's two edges, z' projected on an edge's ray, and the apex.
fn project_on_pyramid(
    facets: usize,
    mu: f64,
    mu2: f64,
    y: &[f64],
    inv_sqrt_e: &[f64],
    lambda: &mut [f64],
    hessian: Option<&mut [f64]>,
) -> Zone {
    use crate::solvers::residuals::{pyramid_facet, pyramid_offset_and_half, pyramid_vertex};
    let k = facets;
    let z = [-y[0] * inv_sqrt_e[0], -y[1] * inv_sqrt_e[1], -y[2] * inv_sqrt_e[2]];
    let offset = pyramid_offset_and_half(k).0;
    let normal_of = |j: usize| -> [f64; 3] {
        let (nx, ny) = pyramid_facet(k, j % k);
        [-offset * inv_sqrt_e[0], nx / mu * inv_sqrt_e[1], ny / mu2 * inv_sqrt_e[2]]
    };
    let edge_of = |j: usize| -> [f64; 3] {
        let (c, s) = pyramid_vertex(k, j % k);
        [1.0 / inv_sqrt_e[0], mu * c / inv_sqrt_e[1], mu2 * s / inv_sqrt_e[2]]
    };
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    // Facet terms a'_j · z' (z' is inside when none is positive).
    let mut outside = false;
    for j in 0..k {
        outside |= dot(&normal_of(j), &z) > 0.0;
    }
    let mut best = ([0.0; 3], f64::INFINITY, Zone::Free);
    let consider = |p: [f64; 3], zone: Zone, best: &mut ([f64; 3], f64, Zone)| {
        let d = (0..3).map(|a| (z[a] - p[a]).powi(2)).sum::<f64>();
        if d < best.1 {
            *best = (p, d, zone);
        }
    };
    if !outside {
        best = (z, 0.0, Zone::Interior);
    } else {
        consider([0.0; 3], Zone::Free, &mut best);
        for j in 0..k {
            let a = normal_of(j);
            let t = dot(&a, &z);
            if t > 0.0 {
                let scale = t / dot(&a, &a);
                let p = [z[0] - scale * a[0], z[1] - scale * a[1], z[2] - scale * a[2]];
                // Between the facet's edges j and j + 1: inside the neighbouring facets.
                if dot(&normal_of(j + k - 1), &p) <= 0.0 && dot(&normal_of(j + 1), &p) <= 0.0 {
                    consider(p, Zone::Facet(j), &mut best);
                }
            }
            let v = edge_of(j);
            let t = dot(&v, &z);
            if t > 0.0 {
                let scale = t / dot(&v, &v);
                consider([scale * v[0], scale * v[1], scale * v[2]], Zone::Edge(j), &mut best);
            }
        }
    }
    let (p, _, zone) = best;
    for a in 0..3 {
        lambda[a] = p[a] * inv_sqrt_e[a];
    }
    if let Some(h) = hessian {
        // Π' of the zone, then G = E^{-1/2} Π' E^{-1/2}.
        let projector = |a: usize, b: usize| -> f64 {
            let identity = if a == b { 1.0 } else { 0.0 };
            match zone {
                Zone::Interior => identity,
                Zone::Facet(j) => {
                    let n = normal_of(j);
                    identity - n[a] * n[b] / dot(&n, &n)
                }
                Zone::Edge(j) => {
                    let v = edge_of(j);
                    v[a] * v[b] / dot(&v, &v)
                }
                _ => 0.0,
            }
        };
        for a in 0..3 {
            for b in 0..3 {
                h[3 * a + b] = inv_sqrt_e[a] * projector(a, b) * inv_sqrt_e[b];
            }
        }
    }
    zone
}

#[cfg(test)]
mod tests {
    use super::*;

    /// G (row-major 3 × 3) of `group` at `y` equals central finite differences of −λ(y).
    fn assert_derivative(
        group: &Group,
        y: [f64; 3],
        e: &[f64],
        inv_sqrt_e: &[f64],
        g: &[f64; 9],
        label: &str,
    ) {
        for k in 0..3 {
            let step = 1e-7;
            let (mut yp, mut ym) = (y, y);
            yp[k] += step;
            ym[k] -= step;
            let (mut lp, mut lm) = ([0.0; 3], [0.0; 3]);
            project(group, &yp, e, inv_sqrt_e, &mut lp, None);
            project(group, &ym, e, inv_sqrt_e, &mut lm, None);
            for a in 0..3 {
                let fd = -(lp[a] - lm[a]) / (2.0 * step);
                assert!((fd - g[3 * a + k]).abs() < 1e-6, "{label}: G[{a}][{k}] {} vs {fd}", g[3 * a + k]);
            }
        }
    }

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
            assert_derivative(&group, y, &e, &inv_sqrt_e, &g, &format!("zone {:?}", zones.last()));
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
    /// A k-facet pyramid (k = 3, 4, 8; anisotropic friction) in a metric of unequal rows: λ(y)
    /// lies in the pyramid, no point of a fine sample of the pyramid is nearer in the E-metric,
    /// and G matches finite differences of −λ in every zone the points reach (inside, on
    /// facets, on edges, at the apex).
    #[test]
    fn pyramid_projection_is_the_nearest_point_and_its_derivative() {
        use crate::solvers::residuals::pyramid_vertex;
        let e = [0.4, 1.3, 0.6];
        let inv_sqrt_e = e.map(|x: f64| 1.0 / x.sqrt());
        let (mu, mu2) = (0.7, 0.4);
        let mut zones = Vec::new();
        for facets in [3, 4, 8] {
            let group = Group::Pyramid { normal: 0, facets, mu, mu2 };
            let points = [
                [-1.0, 0.05, -0.02],
                [-1.0, 2.0, 0.5],
                [-1.0, 1.5, 1.4],
                [1.0, 0.1, 0.2],
                [-0.2, 0.9, -0.4],
                [-0.3, -0.1, 0.9],
                [0.1, -2.0, -0.3],
            ];
            for y in points {
                let mut l = [0.0; 3];
                let mut g = [0.0; 9];
                let zone = project(&group, &y, &e, &inv_sqrt_e, &mut l, Some(&mut g));
                zones.push(zone);
                let z = [-y[0] / e[0], -y[1] / e[1], -y[2] / e[2]];
                let cost = |p: [f64; 3]| (0..3).map(|k| e[k] * (p[k] - z[k]).powi(2)).sum::<f64>();
                let best = cost(l);
                // The pyramid sampled as combinations of two neighbouring edges.
                for j in 0..facets {
                    let (c0, s0) = pyramid_vertex(facets, j);
                    let (c1, s1) = pyramid_vertex(facets, (j + 1) % facets);
                    for a in 0..=40 {
                        for b in 0..=40 {
                            let (a, b) = (3.0 * a as f64 / 40.0, 3.0 * b as f64 / 40.0);
                            let p = [a + b, mu * (a * c0 + b * c1), mu2 * (a * s0 + b * s1)];
                            assert!(cost(p) >= best - 1e-12, "k {facets}: {p:?} is nearer than {l:?}");
                        }
                    }
                }
                assert_derivative(&group, y, &e, &inv_sqrt_e, &g, &format!("k {facets} zone {zone:?}"));
            }
        }
        for wanted in [Zone::Interior, Zone::Free] {
            assert!(zones.contains(&wanted), "{wanted:?} not reached: {zones:?}");
        }
        assert!(zones.iter().any(|z| matches!(z, Zone::Facet(_))), "no facet: {zones:?}");
        assert!(zones.iter().any(|z| matches!(z, Zone::Edge(_))), "no edge: {zones:?}");
    }
}
