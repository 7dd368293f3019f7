//! The active set of PGS's iterate (pressing, sticking, sliding, on a pyramid's facet or at
//! its vertex), and the release of a pyramid contact whose slip says it is wrong.

use super::*;

/// Fills `ws.units` with PGS's active set at `lambda` (a sticking contact's normal is followed
/// by its tangents, a sliding one's by its direction, whose tangents it puts exactly on the
/// cone); false if nothing is free. A pyramid contact within `on_pyramid` (relative) of its
/// pyramid's boundary is put on it.
pub(super) fn active_units(
    problem: &ConstraintProblem,
    lambda: &mut DVector<f64>,
    ws: &mut SubspaceWorkspace,
    on_pyramid: f64,
) -> bool {
    let n = problem.rows();
    ws.units.clear();
    ws.contact_row.clear();
    ws.contact_row.resize(n, false);
    for c in &problem.contacts {
        let (nr, t1, t2) = c.rows();
        ws.contact_row[nr] = true;
        ws.contact_row[t1] = true;
        ws.contact_row[t2] = true;
        let normal = lambda[nr];
        if normal <= 0.0 {
            continue; // Separating: every impulse stays zero.
        }
        let scaled = |l: f64, mu: f64| if mu > 0.0 { l / mu } else { 0.0 };
        let (s1, s2) = (scaled(lambda[t1], c.mu), scaled(lambda[t2], c.mu2));
        if let FrictionModel::Pyramid { facets } = problem.friction {
            if (c.mu > 0.0) != (c.mu2 > 0.0) {
                return false; // A pyramid squeezed to a segment: not handled.
            }
            let release = ws.released.filter(|(row, _)| *row == nr).map(|(_, facet)| facet);
            let units = match release {
                Some(None) => None,
                Some(Some(j)) => {
                    let facet = on_facet(c, facets, j);
                    Some((Unit::Facet(facet), Some(Unit::Along(facet))))
                }
                None => pyramid_units(c, facets, normal, [s1, s2], on_pyramid),
            };
            if let Some((first, along)) = units {
                let (v1, v2) = match first {
                    Unit::Corner(v) => (normal * v.v[0], normal * v.v[1]),
                    Unit::Facet(f) => {
                        // Exactly onto the facet, keeping the position along it.
                        let (e, along) = (f.e(), f.e()[0] * s1 + f.e()[1] * s2);
                        let base = f.offset * normal;
                        (base * f.n[0] + along * e[0], base * f.n[1] + along * e[1])
                    }
                    _ => unreachable!("pyramid_units returns a Corner or a Facet first"),
                };
                lambda[t1] = c.mu * v1;
                lambda[t2] = c.mu2 * v2;
                ws.units.push(first);
                ws.units.extend(along);
                continue;
            }
        }
        let reach = norm2(s1, s2);
        if problem.friction == FrictionModel::Cone
            && c.mu.max(c.mu2) > 0.0
            && reach > 0.0
            && reach >= (1.0 - ON_CONE) * normal
        {
            let (cos, sin) = (s1 / reach, s2 / reach);
            lambda[t1] = normal * c.mu * cos;
            lambda[t2] = normal * c.mu2 * sin;
            let sliding = Sliding { normal: nr, t1, t2, mu: [c.mu, c.mu2], lambda_n: normal, cos, sin };
            ws.units.push(Unit::Slide(sliding));
            // With one coefficient zero the direction is only a sign.
            if c.mu > 0.0 && c.mu2 > 0.0 {
                ws.units.push(Unit::Angle(sliding));
            }
        } else {
            ws.units.push(Unit::Row(nr));
            for (t, mu) in [(t1, c.mu), (t2, c.mu2)] {
                if mu > 0.0 {
                    ws.units.push(Unit::Row(t));
                }
            }
        }
    }
    for i in 0..n {
        if ws.contact_row[i] {
            continue;
        }
        let free = match problem.laws[i] {
            RowLaw::Bilateral => true,
            RowLaw::Unilateral => lambda[i] > 0.0,
            RowLaw::Bounded { lo, hi } => lo < lambda[i] && lambda[i] < hi,
            RowLaw::Friction { .. } => false, // Owned by a contact (checked by `check_problem`).
        };
        if free {
            ws.units.push(Unit::Row(i));
        }
    }
    !ws.units.is_empty()
}

/// The units of a contact on the boundary of its friction pyramid (k facets) at scaled tangent
/// impulse `s` and normal impulse `normal` > 0, within `tolerance` (relative) of a facet or a
/// vertex: `(Corner, None)` at a vertex, `(Facet, Some(Along))` on a facet; `None` inside
/// (sticking) or frictionless.
pub(super) fn pyramid_units(
    c: &crate::constraints::ContactBlock,
    facets: usize,
    normal: f64,
    s: [f64; 2],
    tolerance: f64,
) -> Option<(Unit, Option<Unit>)> {
    if c.mu <= 0.0 {
        return None;
    }
    let offset = pyramid_offset_and_half(facets).0;
    let (mut best, mut reach) = (0, f64::NEG_INFINITY);
    for j in 0..facets {
        let (nx, ny) = pyramid_facet(facets, j);
        let r = nx * s[0] + ny * s[1];
        if r > reach {
            (best, reach) = (j, r);
        }
    }
    if reach < (1.0 - tolerance) * offset * normal {
        return None;
    }
    let facet = on_facet(c, facets, best);
    let e = facet.e();
    let tau = e[0] * s[0] + e[1] * s[1];
    // Facet j runs from vertex j (τ = −half λ_n) to vertex j + 1 (τ = +half λ_n).
    if tau.abs() >= (1.0 - tolerance) * facet.half * normal {
        let vertex = if tau > 0.0 { best + 1 } else { best };
        let index = vertex % facets;
        let (vx, vy) = pyramid_vertex(facets, index);
        let corner =
            AtVertex { normal: facet.normal, t1: facet.t1, t2: facet.t2, mu: facet.mu, index, v: [vx, vy] };
        return Some((Unit::Corner(corner), None));
    }
    Some((Unit::Facet(facet), Some(Unit::Along(facet))))
}

/// Contact `c` on facet `j` of its friction pyramid (k facets).
pub(super) fn on_facet(c: &crate::constraints::ContactBlock, facets: usize, j: usize) -> OnFacet {
    let (nx, ny) = pyramid_facet(facets, j % facets);
    let (normal, t1, t2) = c.rows();
    let (offset, half) = pyramid_offset_and_half(facets);
    OnFacet { normal, t1, t2, mu: [c.mu, c.mu2], n: [nx, ny], offset, half }
}

/// After a round that solved its active set exactly: the pyramid contact whose slip says the
/// active set is most wrong, put into `ws.released` for the next round, and whether there is one.
/// At a vertex, the slip `m = (μ₁ w₁, μ₂ w₂)` must not decrease `m·s` along either facet
/// leaving it (else maximum dissipation moves the impulse along that facet); on a facet, the
/// slip must oppose the facet's outward normal, `m = −γ n` with γ ≥ 0 (else the contact
/// sticks). Without this a
/// contact that passes a vertex on its way to the next facet stays at the vertex, and the
/// reduced solve is inconsistent for every later round.
pub(super) fn release_pyramid_contacts(
    problem: &ConstraintProblem,
    candidate: &DVector<f64>,
    ws: &mut SubspaceWorkspace,
    tolerance: f64,
) -> bool {
    let FrictionModel::Pyramid { facets } = problem.friction else { return false };
    let m = ws.rows.len();
    // Row velocities at the candidate: ws.w is that of the round's start.
    let velocity = |ws: &SubspaceWorkspace, row: usize| {
        let a = ws.local[row];
        let g = &ws.gram[a * m..(a + 1) * m];
        ws.w_start[a]
            + g.iter().zip(&ws.rows).zip(&ws.start).map(|((g, &r), l0)| g * (candidate[r] - l0)).sum::<f64>()
    };
    // The largest violation only (by its rate of change of dissipation, m/s): releasing every
    // violator at once moves contacts whose violation is only the others' doing.
    let mut worst = (0.0, 0, None);
    for k in 0..ws.units.len() {
        let (normal, t1, t2, mu) = match ws.units[k] {
            Unit::Facet(f) => (f.normal, f.t1, f.t2, f.mu),
            Unit::Corner(c) => (c.normal, c.t1, c.t2, c.mu),
            _ => continue,
        };
        if ws.release_refused.contains(&normal) {
            continue;
        }
        let slip = [mu[0] * velocity(ws, t1), mu[1] * velocity(ws, t2)];
        // A slip within the tolerance says nothing (a contact resting on its pyramid's edge).
        let scale = slip[0].abs().max(slip[1].abs());
        if scale <= tolerance {
            continue;
        }
        match ws.units[k] {
            Unit::Facet(f) => {
                let rate = slip[0] * f.n[0] + slip[1] * f.n[1];
                if rate > ON_CONE * scale && rate > worst.0 {
                    worst = (rate, normal, None);
                }
            }
            Unit::Corner(c) => {
                // Vertex i lies between facet i − 1 (its end, leaving along −e) and facet i
                // (its start, leaving along +e).
                let (before, after) = ((c.index + facets - 1) % facets, c.index);
                let rate = |j: usize, sign: f64| {
                    let (nx, ny) = pyramid_facet(facets, j);
                    sign * (-ny * slip[0] + nx * slip[1])
                };
                let (r_before, r_after) = (rate(before, -1.0), rate(after, 1.0));
                let best = if r_before < r_after { (before, r_before) } else { (after, r_after) };
                if best.1 < -ON_CONE * scale && -best.1 > worst.0 {
                    worst = (-best.1, normal, Some(best.0));
                }
            }
            _ => {}
        }
    }
    ws.released = (worst.0 > 0.0).then_some((worst.1, worst.2));
    ws.released.is_some()
}
