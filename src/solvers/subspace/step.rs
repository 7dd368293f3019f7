//! How far the reduced solve's direction can be followed: the longest step that keeps every
//! free impulse in its set, and what blocks it.

use super::*;

/// What ends a step early.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Blocking {
    /// Nothing: the full step is feasible.
    None,
    /// The impulse of this row (a normal: with its tangents) reaches zero.
    Zero(usize),
    /// This row reaches this bound.
    Bound(usize, f64),
    /// A sticking contact reaches its cone or pyramid (the projection puts it exactly there).
    Cone,
    /// A contact on a facet of its pyramid reaches a vertex.
    Vertex,
    /// A sliding direction would turn more than `MAX_TURN`.
    Turn,
}

/// The longest step α ≤ 1 along `ws.x` that keeps every free impulse in its set, and what
/// blocks it.
pub(super) fn step_length(
    problem: &ConstraintProblem,
    lambda: &DVector<f64>,
    ws: &SubspaceWorkspace,
) -> (f64, Blocking) {
    let (mut alpha, mut blocking) = (1.0, Blocking::None);
    let mut limit = |a: f64, b: Blocking| {
        if a < alpha {
            alpha = a.max(0.0);
            blocking = b;
        }
    };
    for (k, (unit, &x)) in ws.units.iter().zip(&ws.x).enumerate() {
        match *unit {
            Unit::Slide(c) => {
                if x < 0.0 {
                    limit(c.lambda_n / -x, Blocking::Zero(c.normal));
                }
            }
            Unit::Angle(_) => {
                if x.abs() > MAX_TURN {
                    limit(MAX_TURN / x.abs(), Blocking::Turn);
                }
            }
            Unit::Facet(OnFacet { normal, .. }) | Unit::Corner(AtVertex { normal, .. }) => {
                if x < 0.0 {
                    limit(lambda[normal] / -x, Blocking::Zero(normal));
                }
            }
            Unit::Along(f) => {
                // |τ + α x| = half (λ_n + α x_n), with x_n the facet's normal unit (right before).
                let x_n = ws.x[k - 1];
                let e = f.e();
                let scaled = [lambda[f.t1] / f.mu[0], lambda[f.t2] / f.mu[1]];
                let tau = e[0] * scaled[0] + e[1] * scaled[1];
                let reach = f.half * lambda[f.normal];
                for sign in [1.0, -1.0] {
                    // sign (τ + α x) = half (λ_n + α x_n): α (sign x − half x_n) = reach − sign τ.
                    let rate = sign * x - f.half * x_n;
                    if rate > 0.0 {
                        limit((reach - sign * tau) / rate, Blocking::Vertex);
                    }
                }
            }
            Unit::Row(row) => {
                let l = lambda[row];
                match problem.laws[row] {
                    RowLaw::Unilateral => {
                        if x < 0.0 {
                            limit(l / -x, Blocking::Zero(row));
                        }
                        // A sticking contact: its tangents are the next units (see `active_units`).
                        if let Some(c) = contact_of_normal(problem, row).map(|c| &problem.contacts[c]) {
                            let (_, t1, t2) = c.rows();
                            let mut d = [0.0; 2];
                            for (unit, &dx) in ws.units[k + 1..].iter().zip(&ws.x[k + 1..]).take(2) {
                                match *unit {
                                    Unit::Row(t) if t == t1 => d[0] = dx,
                                    Unit::Row(t) if t == t2 => d[1] = dx,
                                    _ => {}
                                }
                            }
                            let scaled = |v: f64, mu: f64| if mu > 0.0 { v / mu } else { 0.0 };
                            let s0 = [scaled(lambda[t1], c.mu), scaled(lambda[t2], c.mu2)];
                            let ds = [scaled(d[0], c.mu), scaled(d[1], c.mu2)];
                            match problem.friction {
                                FrictionModel::Cone => {
                                    // ‖s0 + α ds‖² = (l + α x)²: the first positive root.
                                    let qa = ds[0] * ds[0] + ds[1] * ds[1] - x * x;
                                    let qb = 2.0 * (s0[0] * ds[0] + s0[1] * ds[1] - l * x);
                                    let qc = s0[0] * s0[0] + s0[1] * s0[1] - l * l;
                                    if let Some(root) = first_positive_root(qa, qb, qc) {
                                        limit(root, Blocking::Cone);
                                    }
                                }
                                FrictionModel::Pyramid { facets } => {
                                    // n_j·(s0 + α ds) = offset (l + α x) on the first facet met.
                                    let offset = pyramid_offset_and_half(facets).0;
                                    for j in 0..facets {
                                        let (nx, ny) = pyramid_facet(facets, j);
                                        let rate = nx * ds[0] + ny * ds[1] - offset * x;
                                        if rate > 0.0 {
                                            let room = offset * l - (nx * s0[0] + ny * s0[1]);
                                            limit(room / rate, Blocking::Cone);
                                        }
                                    }
                                }
                            }
                        }
                    }
                    RowLaw::Bounded { lo, hi } => {
                        if x < 0.0 && lo.is_finite() {
                            limit((l - lo) / -x, Blocking::Bound(row, lo));
                        } else if x > 0.0 && hi.is_finite() {
                            limit((hi - l) / x, Blocking::Bound(row, hi));
                        }
                    }
                    RowLaw::Bilateral | RowLaw::Friction { .. } => {}
                }
            }
        }
    }
    (alpha, blocking)
}

/// The smallest positive root of `a t² + b t + c` with `c < 0` (the path starts inside), if any.
pub(super) fn first_positive_root(a: f64, b: f64, c: f64) -> Option<f64> {
    if c >= 0.0 {
        return Some(0.0);
    }
    if a.abs() <= 1e-300 {
        return (b > 0.0).then(|| -c / b);
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    // Stable roots: q = −(b + sign(b) √disc)/2, t = q/a and c/q.
    let q = -0.5 * (b + b.signum() * sq);
    let roots = [if q != 0.0 { c / q } else { f64::INFINITY }, q / a];
    roots
        .into_iter()
        .filter(|t| *t > 0.0 && t.is_finite())
        .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.min(t))))
}
