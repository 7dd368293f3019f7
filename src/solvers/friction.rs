//! A contact's friction impulses against its friction set (the cone's ellipse, or the regular
//! polygon of a pyramid, in the coordinates (λ₁/μ₁, λ₂/μ₂)): the block Gauss–Seidel steps of
//! [`super::PgsSolver`] and the radial projection that PGS and the subspace step share.

use super::residuals::{norm2, pyramid_facet, pyramid_offset_and_half};
use crate::constraints::FrictionModel;

/// The unconstrained minimiser `o − ω G⁻¹ w` of a contact's two friction rows (G = [[g11, g12],
/// [g12, g22]]), or `None` if G is singular.
fn unconstrained_block_step(o: [f64; 2], w: [f64; 2], g: [f64; 3], omega: f64) -> Option<[f64; 2]> {
    let [g11, g12, g22] = g;
    let det = g11 * g22 - g12 * g12;
    if det.is_nan() || det <= 1e-14 * (g11 * g22).max(f64::MIN_POSITIVE) {
        return None;
    }
    Some([o[0] - omega * (g22 * w[0] - g12 * w[1]) / det, o[1] - omega * (g11 * w[1] - g12 * w[0]) / det])
}

/// One block Gauss–Seidel step on a contact's two friction rows with the cone as the friction
/// set: with `G` = [[g11, g12], [g12, g22]] the 2×2 block of A + R, `w` the rows' current
/// velocities and `o` their impulses, the local problem is `min ½ λᵀGλ + (w − G o)ᵀλ` over the
/// ellipse `(λ₁/μ₁)² + (λ₂/μ₂)² ≤ bound²`. The unconstrained minimiser `o − ω G⁻¹ w` is taken if
/// inside; otherwise the boundary minimiser, where `G λ + c = −γ ∇` (γ ≥ 0): the new tangential
/// velocity is opposite to the impulse in the scaled coordinates, i.e. maximum dissipation. A
/// scalar-rows-then-radial-scaling update instead has fixed points that violate maximum
/// dissipation when G is not isotropic (a wheel: light spin dof against a heavy chassis), which
/// keep PGS from converging on turning vehicles. γ is found by Newton's method on the secular
/// equation `1/‖s(γ)‖ = 1/bound` (Moré and Sorensen, 1983), started from `gamma_start` (the
/// last sweep's multiplier of this contact, near the root for a sliding contact; the iteration
/// is the same safeguarded Newton, γ ≥ 0, at most 30 steps) and leaving the new γ there.
/// `None` if G is singular.
#[allow(clippy::too_many_arguments)]
pub(super) fn friction_block_step(
    o: [f64; 2],
    w: [f64; 2],
    g: [f64; 3],
    bound: f64,
    mu: [f64; 2],
    omega: f64,
    gamma_start: &mut f64,
) -> Option<(f64, f64)> {
    let [g11, g12, g22] = g;
    let free = unconstrained_block_step(o, w, g, omega)?;
    let scaled = |l: [f64; 2]| {
        let s1 = if mu[0] > 0.0 { l[0] / mu[0] } else { 0.0 };
        let s2 = if mu[1] > 0.0 { l[1] / mu[1] } else { 0.0 };
        (s1, s2)
    };
    let (s1, s2) = scaled(free);
    if norm2(s1, s2) <= bound {
        return Some((mu[0] * s1, mu[1] * s2));
    }
    if bound <= 0.0 || mu[0] <= 0.0 || mu[1] <= 0.0 {
        return Some((0.0, 0.0));
    }
    // In s = λ/μ: min ½ sᵀHs + dᵀs, ‖s‖ ≤ bound, with H = D G D, d = D (w − G o).
    let (h11, h12, h22) = (mu[0] * mu[0] * g11, mu[0] * mu[1] * g12, mu[1] * mu[1] * g22);
    let c = [w[0] - g11 * o[0] - g12 * o[1], w[1] - g12 * o[0] - g22 * o[1]];
    let d = [mu[0] * c[0], mu[1] * c[1]];
    let solve = |gamma: f64| {
        let (a11, a22) = (h11 + gamma, h22 + gamma);
        let det = a11 * a22 - h12 * h12;
        let s = [-(a22 * d[0] - h12 * d[1]) / det, -(a11 * d[1] - h12 * d[0]) / det];
        // ds/dγ = −(H + γI)⁻¹ s.
        let ds = [-(a22 * s[0] - h12 * s[1]) / det, -(a11 * s[1] - h12 * s[0]) / det];
        (s, ds)
    };
    let mut gamma: f64 = gamma_start.max(0.0);
    for _ in 0..30 {
        let (s, ds) = solve(gamma);
        let norm = norm2(s[0], s[1]);
        if norm <= 0.0 {
            break;
        }
        let phi = 1.0 / norm - 1.0 / bound;
        if phi.abs() * bound < 1e-12 {
            break;
        }
        let dphi = -(s[0] * ds[0] + s[1] * ds[1]) / norm.powi(3);
        let next = gamma - phi / dphi;
        gamma = if next.is_finite() { next.max(0.0) } else { break };
    }
    *gamma_start = gamma;
    let (s, _) = solve(gamma);
    // Land exactly on the boundary.
    let norm = norm2(s[0], s[1]);
    let k = if norm > 0.0 { bound / norm } else { 0.0 };
    Some((mu[0] * s[0] * k, mu[1] * s[1] * k))
}

/// [`friction_block_step`] for the friction pyramid: the local problem
/// `min ½ sᵀHs + dᵀs` (in `s = (λ₁/μ₁, λ₂/μ₂)`) over the regular polygon of `facets` facets at
/// offset `cos(π/k)·bound`. The unconstrained minimiser if inside; else the best of each facet's
/// own minimiser clamped to the facet (a convex problem whose free minimum lies outside has its
/// minimum on the boundary). A radial scaling instead has fixed points where the slip does not
/// oppose the friction impulse (a contact stuck at a vertex it should slide away from).
/// `None` if G is singular or a coefficient is zero (the caller's scalar rows handle those).
pub(super) fn pyramid_block_step(
    o: [f64; 2],
    w: [f64; 2],
    g: [f64; 3],
    bound: f64,
    mu: [f64; 2],
    omega: f64,
    facets: usize,
) -> Option<(f64, f64)> {
    let [g11, g12, g22] = g;
    if mu[0] <= 0.0 || mu[1] <= 0.0 {
        return None;
    }
    let free = unconstrained_block_step(o, w, g, omega)?;
    if bound <= 0.0 {
        return Some((0.0, 0.0));
    }
    let s_free = [free[0] / mu[0], free[1] / mu[1]];
    let (offset, half) = pyramid_offset_and_half(facets);
    let half = half * bound;
    let inside = (0..facets).all(|j| {
        let (nx, ny) = pyramid_facet(facets, j);
        nx * s_free[0] + ny * s_free[1] <= offset * bound
    });
    if inside {
        return Some((free[0], free[1]));
    }
    // H = D G D and d = D (w − G o)/ω in s (ω scales the step: H/ω's free minimiser is s_free).
    let h = [mu[0] * mu[0] * g11 / omega, mu[0] * mu[1] * g12 / omega, mu[1] * mu[1] * g22 / omega];
    let hs = |s: [f64; 2]| [h[0] * s[0] + h[1] * s[1], h[1] * s[0] + h[2] * s[1]];
    // ½ sᵀHs + dᵀs = ½ (s − s_free)ᵀ H (s − s_free) + const.
    let cost = |s: [f64; 2]| {
        let r = [s[0] - s_free[0], s[1] - s_free[1]];
        let hr = hs(r);
        0.5 * (r[0] * hr[0] + r[1] * hr[1])
    };
    let mut best = (f64::INFINITY, [0.0, 0.0]);
    for j in 0..facets {
        let (nx, ny) = pyramid_facet(facets, j);
        let (p, e) = ([offset * bound * nx, offset * bound * ny], [-ny, nx]);
        // Minimise over τ: eᵀH(p + τe − s_free) = 0.
        let he = hs(e);
        let ehe = e[0] * he[0] + e[1] * he[1];
        let r = [p[0] - s_free[0], p[1] - s_free[1]];
        let tau = if ehe > 0.0 { (-(r[0] * he[0] + r[1] * he[1]) / ehe).clamp(-half, half) } else { 0.0 };
        let s = [p[0] + tau * e[0], p[1] + tau * e[1]];
        let c = cost(s);
        if c < best.0 {
            best = (c, s);
        }
    }
    Some((mu[0] * best.1[0], mu[1] * best.1[1]))
}

/// Scales (λ₁, λ₂) radially into the friction set of normal impulse `normal` (in the coordinates
/// (λ₁/μ, λ₂/μ₂), where the set is a disc or a regular polygon).
pub(super) fn project_friction(
    l1: f64,
    l2: f64,
    normal: f64,
    mu: f64,
    mu2: f64,
    model: FrictionModel,
) -> (f64, f64) {
    let bound = normal.max(0.0);
    let s1 = if mu > 0.0 { l1 / mu } else { 0.0 };
    let s2 = if mu2 > 0.0 { l2 / mu2 } else { 0.0 };
    let reach = match model {
        FrictionModel::Cone => norm2(s1, s2),
        FrictionModel::Pyramid { facets } => {
            let offset = pyramid_offset_and_half(facets).0;
            (0..facets)
                .map(|j| {
                    let (nx, ny) = pyramid_facet(facets, j);
                    (nx * s1 + ny * s2) / offset
                })
                .fold(0.0, f64::max)
        }
    };
    let scale = if reach > bound {
        if reach > 0.0 {
            bound / reach
        } else {
            0.0
        }
    } else {
        1.0
    };
    (mu * s1 * scale, mu2 * s2 * scale)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn pyramid_block_step_minimises_the_local_problem_over_the_polygon() {
        // Against the best of 20 000 points sampled in the polygon (the step's cost must not be
        // beaten by any), for anisotropic blocks G and both pyramids MuJoCo and Lemke use.
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        for facets in [4, 8] {
            let (offset, _) = pyramid_offset_and_half(facets);
            for _ in 0..50 {
                let (g11, g22) = (rng.random_range(0.1..10.0), rng.random_range(0.1..10.0));
                let g12 = rng.random_range(-0.9..0.9) * f64::sqrt(g11 * g22);
                let (o, w) = (
                    [rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)],
                    [rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0)],
                );
                let (bound, mu) =
                    (rng.random_range(0.1..2.0), [rng.random_range(0.2..1.5), rng.random_range(0.2..1.5)]);
                let (p1, p2) = pyramid_block_step(o, w, [g11, g12, g22], bound, mu, 1.0, facets).unwrap();
                // min ½ λᵀGλ + (w − G o)ᵀλ
                let cost = |l: [f64; 2]| {
                    let c = [w[0] - g11 * o[0] - g12 * o[1], w[1] - g12 * o[0] - g22 * o[1]];
                    0.5 * (g11 * l[0] * l[0] + 2.0 * g12 * l[0] * l[1] + g22 * l[1] * l[1])
                        + c[0] * l[0]
                        + c[1] * l[1]
                };
                let inside = |s: [f64; 2]| {
                    (0..facets).all(|j| {
                        let (nx, ny) = pyramid_facet(facets, j);
                        nx * s[0] + ny * s[1] <= offset * bound * (1.0 + 1e-12)
                    })
                };
                assert!(inside([p1 / mu[0], p2 / mu[1]]), "step left the polygon");
                let best = cost([p1, p2]);
                for _ in 0..20_000 {
                    let s = [rng.random_range(-bound..bound), rng.random_range(-bound..bound)];
                    if inside(s) {
                        let c = cost([mu[0] * s[0], mu[1] * s[1]]);
                        assert!(
                            best <= c + 1e-12 * (1.0 + c.abs()),
                            "sample {s:?} beats the step: {c} < {best}"
                        );
                    }
                }
            }
        }
    }
}
