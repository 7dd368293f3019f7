//! Residuals of a candidate solution λ of a [`ConstraintProblem`], computed the same way for
//! every solver. All are in velocity units (m/s or rad/s): impulses are scaled by the row's
//! diagonal `A_ii + R_ii`, so "1e-9" means the same for every row.

use crate::constraints::{ConstraintProblem, FrictionModel, RowLaw};
use nalgebra::DVector;

/// How far λ is from solving the problem, per law (all ≥ 0; 0 = exact).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Residuals {
    /// Signorini: max over unilateral rows of |min(d_i λ_i, w_i)| (the natural-map residual; 0 iff
    /// `0 ≤ λ ⟂ w ≥ 0`).
    pub signorini: f64,
    /// Signorini residual restricted to unilateral rows that are not contact normals (joint
    /// limits): these obey Signorini in the convex relaxation too.
    pub signorini_limits: f64,
    /// Max |λ_i w_i| over unilateral rows (N·s · m/s): the LCP complementarity product.
    pub complementarity: f64,
    /// Max |w_i| over bilateral rows.
    pub bilateral: f64,
    /// Max natural-map residual |d_i λ_i − d_i clamp(λ_i − w_i/d_i, lo, hi)| over bounded rows.
    pub bounded: f64,
    /// Max violation of the friction set (cone or pyramid, as the problem states) by λ_t.
    pub friction_feasibility: f64,
    /// Max dissipation gap: how much more power a friction impulse in the friction set could
    /// dissipate than λ_t does, per unit of the friction bound (0 iff friction opposes slip).
    pub dissipation: f64,
    /// KKT residual of the convex (Anitescu) relaxation: per contact, the violation of
    /// `w ∈ K*` (dual cone: `w_n ≥ ‖(μ w₁, μ₂ w₂)‖`) and the natural-map residual of
    /// `0 ≤ λ_n ⟂ w_n − ‖(μ w₁, μ₂ w₂)‖ ≥ 0`. Sliding contacts satisfy this with `w_n > 0`: the
    /// relaxation's known "hovering".
    pub conic_kkt: f64,
    /// QP residuals (qpsolvers' definitions) of the frictionless problem, with duals recovered
    /// from w; `None` when some contact has friction.
    pub qp: Option<QpResiduals>,
}

/// Primal, dual and duality-gap residuals of a QP, as qpsolvers defines them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct QpResiduals {
    /// Max constraint violation.
    pub primal: f64,
    /// ‖P x + q + Gᵀ z + Aᵀ y‖∞.
    pub dual: f64,
    /// |xᵀ P x + qᵀ x + hᵀ z + bᵀ y|.
    pub gap: f64,
}

impl Residuals {
    /// The residual that certifies the exact complementarity formulation (Lemke, PGS).
    pub fn exact(&self) -> f64 {
        self.signorini
            .max(self.bilateral)
            .max(self.bounded)
            .max(self.friction_feasibility)
            .max(self.dissipation)
    }
    /// The residual that certifies the convex relaxation (clarabel).
    pub fn convex(&self) -> f64 {
        self.conic_kkt
            .max(self.signorini_limits)
            .max(self.bilateral)
            .max(self.bounded)
            .max(self.friction_feasibility)
            .max(self.dissipation)
    }
}

/// (cos, sin) of the angle `π m / k`: exact constants for the 4-facet pyramid (MuJoCo's, and
/// the one residuals of every pyramid contact evaluate several times per solve), trigonometry
/// otherwise.
fn pyramid_angle(m: usize, k: usize) -> (f64, f64) {
    use std::f64::consts::FRAC_1_SQRT_2 as H;
    if k == 4 {
        const EIGHTHS: [(f64, f64); 8] =
            [(1.0, 0.0), (H, H), (0.0, 1.0), (-H, H), (-1.0, 0.0), (-H, -H), (0.0, -1.0), (H, -H)];
        return EIGHTHS[m % 8];
    }
    let angle = std::f64::consts::PI * m as f64 / k as f64;
    (angle.cos(), angle.sin())
}

/// Outward normal of facet j of the k-facet friction pyramid in the (λ₁/μ, λ₂/μ₂) plane, at
/// angle π(2j + 1)/k; the facet lies at offset [`pyramid_offset_and_half`] times the normal impulse.
pub(crate) fn pyramid_facet(k: usize, j: usize) -> (f64, f64) {
    pyramid_angle(2 * j + 1, k)
}

/// Vertex j of the k-facet friction pyramid per unit normal impulse, at angle 2πj/k (facet j
/// runs from vertex j to vertex j + 1).
pub(crate) fn pyramid_vertex(k: usize, j: usize) -> (f64, f64) {
    pyramid_angle(2 * j, k)
}

/// The facets' offset cos(π/k) and half length sin(π/k), per unit normal impulse.
pub(crate) fn pyramid_offset_and_half(k: usize) -> (f64, f64) {
    pyramid_angle(1, k)
}

/// How far the scaled tangent impulse `s` lies outside the k-facet pyramid of normal impulse
/// `normal` (its largest facet term, at least 0). For MuJoCo's four facets (normals
/// (±½√2, ±½√2), offset ½√2) the largest term is the one whose signs match s: the same
/// products and sums as the loop over the facets, without it.
fn pyramid_violation(k: usize, s1: f64, s2: f64, normal: f64) -> f64 {
    if k == 4 {
        use std::f64::consts::FRAC_1_SQRT_2 as H;
        return ((H * s1).abs() + (H * s2).abs() - H * normal.max(0.0)).max(0.0);
    }
    (0..k)
        .map(|j| {
            let (nx, ny) = pyramid_facet(k, j);
            nx * s1 + ny * s2 - pyramid_offset_and_half(k).0 * normal.max(0.0)
        })
        .fold(0.0, f64::max)
}

/// The support of the k-facet pyramid's unit section in −m: its largest vertex term
/// max_j −(m₁ c_j + m₂ s_j); for four facets (vertices (±1, 0), (0, ±1)) max(|m₁|, |m₂|).
fn pyramid_support(k: usize, m1: f64, m2: f64) -> f64 {
    if k == 4 {
        return m1.abs().max(m2.abs());
    }
    (0..k)
        .map(|j| {
            let (c, s) = pyramid_vertex(k, j);
            -(m1 * c + m2 * s)
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

/// The contact whose normal is row `i`, if any: contact rows are laid out (n, t1, t2), so the
/// next row is a friction row naming the contact (O(1), unlike a search over the contacts).
pub(super) fn contact_of_normal(problem: &ConstraintProblem, i: usize) -> Option<usize> {
    match problem.laws.get(i + 1) {
        Some(RowLaw::Friction { contact }) => {
            problem.contacts.get(*contact).is_some_and(|c| c.normal == i).then_some(*contact)
        }
        _ => None,
    }
}

/// √(a² + b²) without `hypot`'s overflow care, which costs a libm call in the hot loops; the
/// arguments are impulses and velocities, far from overflow.
#[inline]
pub(crate) fn norm2(a: f64, b: f64) -> f64 {
    (a * a + b * b).sqrt()
}

/// Computes every residual of λ for `problem`. `w` is scratch space (resized if needed).
pub fn residuals(problem: &ConstraintProblem, lambda: &DVector<f64>, w: &mut DVector<f64>) -> Residuals {
    let n = problem.rows();
    if w.len() != n {
        *w = DVector::zeros(n);
    }
    problem.velocities(lambda, w);
    residuals_at_velocities(problem, lambda, w.as_slice())
}

/// [`residuals`] with the row velocities `w = (A + R) λ + b` at λ already computed (a solver
/// that keeps Wᵀλ gets them with one product with W instead of two).
pub(crate) fn residuals_at_velocities(
    problem: &ConstraintProblem,
    lambda: &DVector<f64>,
    w: &[f64],
) -> Residuals {
    residuals_with_friction(problem, problem.friction, lambda, w)
}

/// [`residuals_at_velocities`] with the contacts' friction sets given by `friction` instead of
/// `problem.friction` (Lemke's answer to a cone problem measured on the pyramid it solves,
/// without a copy of the problem).
pub(crate) fn residuals_with_friction(
    problem: &ConstraintProblem,
    friction: FrictionModel,
    lambda: &DVector<f64>,
    w: &[f64],
) -> Residuals {
    let n = problem.rows();
    let kept = problem.kept_diagonal();
    let d = |i: usize| {
        let a = match kept {
            Some(a) => a[i],
            None => problem.delassus_entry(i, i),
        };
        (a + problem.regularization[i]).max(f64::MIN_POSITIVE)
    };
    let mut r = Residuals::default();
    let frictionless = problem.contacts.iter().all(|c| c.mu == 0.0 && c.mu2 == 0.0);
    let mut qp = QpResiduals::default();
    let mut gap = 0.0;
    for i in 0..n {
        let (li, wi, di) = (lambda[i], w[i], d(i));
        match problem.laws[i] {
            RowLaw::Unilateral => {
                let natural = (di * li).min(wi).abs();
                r.signorini = r.signorini.max(natural);
                if contact_of_normal(problem, i).is_none() {
                    r.signorini_limits = r.signorini_limits.max(natural);
                }
                r.complementarity = r.complementarity.max((li * wi).abs());
                qp.primal = qp.primal.max(-li);
                qp.dual = qp.dual.max(-wi);
                gap += li * wi;
            }
            RowLaw::Bilateral => {
                r.bilateral = r.bilateral.max(wi.abs());
                qp.dual = qp.dual.max(wi.abs());
            }
            RowLaw::Bounded { lo, hi } => {
                let projected = (li - wi / di).clamp(lo, hi);
                r.bounded = r.bounded.max(di * (li - projected).abs());
                qp.primal = qp.primal.max(lo - li).max(li - hi);
                let dual = if li <= lo {
                    (-wi).max(0.0)
                } else if li >= hi {
                    wi.max(0.0)
                } else {
                    wi.abs()
                };
                qp.dual = qp.dual.max(dual);
                gap += if li <= lo || li >= hi { li * wi } else { 0.0 };
            }
            RowLaw::Friction { .. } => {}
        }
    }
    for c in &problem.contacts {
        let (n_row, t1, t2) = c.rows();
        let (ln, l1, l2) = (lambda[n_row], lambda[t1], lambda[t2]);
        let (wn, w1, w2) = (w[n_row], w[t1], w[t2]);
        let scale = d(n_row);
        // Friction set in scaled coordinates s = (λ₁/μ, λ₂/μ₂).
        let scaled = |x: f64, mu: f64| if mu > 0.0 { x / mu } else { 0.0 };
        let (s1, s2) = (scaled(l1, c.mu), scaled(l2, c.mu2));
        let zero_mu_excess =
            (if c.mu > 0.0 { 0.0 } else { l1.abs() }).max(if c.mu2 > 0.0 { 0.0 } else { l2.abs() });
        let violation = match friction {
            FrictionModel::Cone => (norm2(s1, s2) - ln.max(0.0)).max(0.0),
            FrictionModel::Pyramid { facets } => pyramid_violation(facets, s1, s2, ln),
        };
        let violation = (violation * c.mu.max(c.mu2)).max(zero_mu_excess) * scale;
        r.friction_feasibility = r.friction_feasibility.max(violation);
        // The support of the friction set's unit section in −w_t: max over it of −f·w_t (the
        // ellipse's ‖(μ w₁, μ₂ w₂)‖, or the pyramid's largest vertex term).
        let (m1, m2) = (c.mu * w1, c.mu2 * w2);
        let support = match friction {
            FrictionModel::Cone => norm2(m1, m2),
            FrictionModel::Pyramid { facets } => pyramid_support(facets, m1, m2),
        };
        // Dissipation gap: max over the friction set of −w_t·f, minus −w_t·λ_t, per unit bound.
        let best = ln.max(0.0) * support;
        // Per unit of the friction bound, floored at the impulse that changes a velocity by
        // 1 µm/s, so that the direction of a negligible impulse does not count.
        let bound = c.mu.max(c.mu2) * ln.max(0.0);
        if bound > 0.0 {
            let floor = 1e-6 / scale;
            r.dissipation = r.dissipation.max(((best + w1 * l1 + w2 * l2) / bound.max(floor)).abs());
        }
        // Convex relaxation (Anitescu): w ∈ K* (w_n ≥ ‖(μ w₁, μ₂ w₂)‖) and, per block,
        // λ_n (w_n − ‖(μ w₁, μ₂ w₂)‖) = 0 (friction opposing slip is the dissipation term).
        // The dual of the friction set: w_n ≥ the support above.
        let surplus = wn - support;
        r.conic_kkt = r.conic_kkt.max((-surplus).max(0.0)).max((scale * ln).min(surplus).abs());
        if frictionless {
            qp.primal = qp.primal.max(l1.abs()).max(l2.abs());
        }
    }
    if frictionless {
        qp.gap = gap.abs();
        r.qp = Some(qp);
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The four-facet shortcuts give the loops' values (as f64 equality: a zero's sign aside).
    #[test]
    fn the_four_facet_pyramid_terms_equal_the_loops_over_facets_and_vertices() {
        let values = [0.0, -0.0, 1e-300, -2.5, 0.3, 7.0, -1e-9, 1.0 / 3.0];
        for &s1 in &values {
            for &s2 in &values {
                for &normal in &values {
                    let looped = (0..4)
                        .map(|j| {
                            let (nx, ny) = pyramid_facet(4, j);
                            nx * s1 + ny * s2 - pyramid_offset_and_half(4).0 * normal.max(0.0)
                        })
                        .fold(0.0, f64::max);
                    assert_eq!(pyramid_violation(4, s1, s2, normal), looped, "{s1} {s2} {normal}");
                }
                let looped = (0..4)
                    .map(|j| {
                        let (c, s) = pyramid_vertex(4, j);
                        -(s1 * c + s2 * s)
                    })
                    .fold(f64::NEG_INFINITY, f64::max);
                assert_eq!(pyramid_support(4, s1, s2), looped, "{s1} {s2}");
            }
        }
    }
}
