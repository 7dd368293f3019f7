//! Reduced contact sets: at most four points per colliding pair, chosen as the deepest point and
//! the points that span the largest area in the contact plane (the lecture's reduced contact set;
//! the same heuristic as Gregorius, "Robust contact creation for physics simulations", GDC 2015).
//! Four well-spread points hold a resting box as firmly as the whole contact polygon does, and the
//! constraint problem stays small.
//!
//! When at least three candidates touch (a gap within a tenth of the margin, now or at the end of
//! the step at the two colliders' velocities: `Candidate::predicted`), the points are chosen
//! among those alone. A convex hull of a lumpy mesh on the ground has dozens of vertices
//! within a 2 cm margin, several of them penetrating: chosen by spread among all of them, the
//! set holds the far rim 1–2 cm above the ground and drops the penetrating vertices between,
//! and the body rocks on its deepest vertex and sinks. A pair with fewer touching points (a
//! box landing on an edge) keeps its speculative points, which hold the rotation that closes
//! them. A body tipping onto a face touches along one edge while the far edge is still up; the
//! far edge closes within the step and counts as touching by its predicted gap, so the set spans
//! both edges (chosen by the present gaps alone, the near edge held and the far one went 12 mm
//! into a ragdoll's pelvis below in one 2 ms step).

use crate::math::Vec3;

/// A candidate contact point before reduction (world frame).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Candidate {
    pub point_a: Vec3,
    pub point_b: Vec3,
    pub normal: Vec3,
    pub distance: f64,
    /// The gap (m) expected at the end of the step from the two colliders' motions at its
    /// start (`distance` when they are not known).
    pub predicted: f64,
    pub feature: u64,
}

/// Maximum number of contact points kept per pair.
pub const MAX_POINTS_PER_PAIR: usize = 4;

/// Share of the contact margin within which a candidate counts as touching (module docs).
const TOUCHING_SHARE_OF_MARGIN: f64 = 0.1;

/// Reorders `points` so that its first `k ≤ 4` entries are the reduced set and returns `k`:
/// among the touching candidates when at least three touch (present or predicted gap at most a
/// tenth of `margin`, m; module docs), else among all, [`spread`]'s choice.
pub(crate) fn reduce(points: &mut [Candidate], margin: f64) -> usize {
    if points.len() <= MAX_POINTS_PER_PAIR {
        return points.len();
    }
    let touching_gap = TOUCHING_SHARE_OF_MARGIN * margin;
    let mut touching = 0;
    for i in 0..points.len() {
        if points[i].distance.min(points[i].predicted) <= touching_gap {
            points.swap(touching, i);
            touching += 1;
        }
    }
    let pool = if touching >= 3 { touching } else { points.len() };
    if pool <= MAX_POINTS_PER_PAIR {
        return pool;
    }
    spread(&mut points[..pool])
}

/// Reorders `points` (more than four) so that its first `k ≤ 4` entries are the most spread
/// set and returns `k`. Chooses: the deepest point; the point farthest from it; the point making
/// the largest triangle with those two; the point that adds the largest area outside that
/// triangle (if any does). Distances are measured in the plane orthogonal to the deepest point's
/// normal.
fn spread(points: &mut [Candidate]) -> usize {
    let deepest = argmax(points, 0, |c| -c.distance);
    points.swap(0, deepest);
    let n = points[0].normal;
    let project = |p: &Vec3| p - n * n.dot(p);
    let p0 = project(&points[0].point_a);
    let far = argmax(points, 1, |c| (project(&c.point_a) - p0).norm_squared());
    points.swap(1, far);
    let p1 = project(&points[1].point_a);
    let area = |a: &Vec3, b: &Vec3, c: &Vec3| n.dot(&(b - a).cross(&(c - a)));
    let third = argmax(points, 2, |c| area(&p0, &p1, &project(&c.point_a)).abs());
    points.swap(2, third);
    let p2 = project(&points[2].point_a);
    // Orient the triangle counter-clockwise about n so that points outside it have a negative
    // signed area against some edge.
    let (e0, e1) = if area(&p0, &p1, &p2) >= 0.0 { (p0, p1) } else { (p1, p0) };
    let outside = |c: &Candidate| {
        let p = project(&c.point_a);
        -(area(&e0, &e1, &p).min(area(&e1, &p2, &p)).min(area(&p2, &e0, &p)))
    };
    let fourth = argmax(points, 3, outside);
    if outside(&points[fourth]) > 0.0 {
        points.swap(3, fourth);
        4
    } else {
        3
    }
}

/// Replaces the reduced set `points[..kept]` by one point per contact normal, at the centre of the
/// points sharing it (positions averaged) with the depth of the deepest of them, for a collider
/// whose contact stands for a patch (a tyre); returns the new count. Points of one pair share
/// their normal unless they come from several manifolds (the triangles of a height field under
/// a wheel), which stay separate contacts. The deepest depth, not the mean: a tilted wheel's lower
/// rim edge must not sink while the upper one is still above the surface (a speculative point).
pub(crate) fn merge_to_patch(points: &mut [Candidate], kept: usize) -> usize {
    // (sum of point_a, sum of point_b, deepest distance, count, normal, feature) per normal.
    let mut groups: [(Vec3, Vec3, f64, usize, Vec3, u64); MAX_POINTS_PER_PAIR] =
        [(Vec3::zeros(), Vec3::zeros(), f64::INFINITY, 0, Vec3::zeros(), 0); MAX_POINTS_PER_PAIR];
    let mut count = 0;
    for c in &points[..kept.min(MAX_POINTS_PER_PAIR)] {
        let g = match groups[..count].iter().position(|g| (g.4 - c.normal).norm() <= 1e-9) {
            Some(g) => g,
            None => {
                // One point per pair and normal: a constant feature per group keeps the warm start
                // matched when the rim point that reduction put first changes.
                groups[count] = (Vec3::zeros(), Vec3::zeros(), f64::INFINITY, 0, c.normal, count as u64);
                count += 1;
                count - 1
            }
        };
        let group = &mut groups[g];
        group.0 += c.point_a;
        group.1 += c.point_b;
        group.2 = group.2.min(c.distance);
        group.3 += 1;
    }
    for (slot, (a, b, distance, n, normal, feature)) in points.iter_mut().zip(&groups[..count]) {
        let scale = 1.0 / *n as f64;
        *slot = Candidate {
            point_a: a * scale,
            point_b: b * scale,
            normal: *normal,
            distance: *distance,
            predicted: *distance,
            feature: *feature,
        };
    }
    count
}

fn argmax(points: &[Candidate], from: usize, key: impl Fn(&Candidate) -> f64) -> usize {
    let mut best = from;
    let mut best_key = f64::NEG_INFINITY;
    for (i, c) in points.iter().enumerate().skip(from) {
        let k = key(c);
        if k > best_key {
            best_key = k;
            best = i;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(x: f64, y: f64, d: f64) -> Candidate {
        let p = Vec3::new(x, y, 0.0);
        Candidate { point_a: p, point_b: p, normal: Vec3::z(), distance: d, predicted: d, feature: 0 }
    }

    /// A box tipping onto a face: four points touch along one edge, the far edge is 15 mm up
    /// and closes by 20 mm in the step. Chosen among the touching points alone, the set would
    /// hold only the near edge and the far edge would sink through; predicted to touch, the far
    /// points join the pool and the spread set spans both edges.
    #[test]
    fn points_the_step_closes_count_as_touching() {
        let mut near_edge_only = Vec::new();
        let mut both = Vec::new();
        for (pts, closing) in [(&mut near_edge_only, 0.0), (&mut both, 0.02)] {
            for y in [-0.1, -0.05, 0.05, 0.1] {
                pts.push(at(0.0, y, 0.0005));
            }
            for y in [-0.1, 0.1] {
                let mut far = at(0.2, y, 0.015);
                far.predicted = far.distance - closing;
                pts.push(far);
            }
        }
        let k = reduce(&mut near_edge_only, 0.02);
        assert!(near_edge_only[..k].iter().all(|c| c.point_a.x == 0.0), "{:?}", &near_edge_only[..k]);
        let k = reduce(&mut both, 0.02);
        assert_eq!(k, 4);
        assert!(both[..k].iter().any(|c| c.point_a.x == 0.2), "{:?}", &both[..k]);
        assert!(both[..k].iter().any(|c| c.point_a.x == 0.0), "{:?}", &both[..k]);
    }

    #[test]
    fn keeps_the_deepest_and_the_corners_of_a_square() {
        // 3×3 grid of points on a square, the centre one deepest.
        let mut pts = Vec::new();
        for i in -1..=1 {
            for j in -1..=1 {
                let d = if i == 0 && j == 0 { -0.02 } else { -0.01 };
                pts.push(at(i as f64, j as f64, d));
            }
        }
        let k = reduce(&mut pts, 0.005);
        assert_eq!(k, 4);
        assert_eq!(pts[0].distance, -0.02);
        // The kept points reach every side of the square.
        let kept = &pts[..k];
        let (xs, ys): (Vec<f64>, Vec<f64>) = kept.iter().map(|c| (c.point_a.x, c.point_a.y)).unzip();
        assert_eq!(xs.iter().cloned().fold(f64::INFINITY, f64::min), -1.0);
        assert_eq!(xs.iter().cloned().fold(f64::NEG_INFINITY, f64::max), 1.0);
        assert_eq!(ys.iter().cloned().fold(f64::INFINITY, f64::min), -1.0);
        assert_eq!(ys.iter().cloned().fold(f64::NEG_INFINITY, f64::max), 1.0);
    }

    /// A lumpy hull on the ground: five penetrating vertices within 3 cm of the deepest, and a
    /// rim 6 cm out, 1 to 1.7 cm above the ground (within a 2 cm margin). The set is chosen among
    /// the touching vertices; with fewer than three touching, the rim is kept (speculative points).
    #[test]
    fn touching_points_are_chosen_before_a_far_rim_above_the_ground() {
        let mut pts = vec![
            at(0.0, 0.0, -0.0025),
            at(0.03, 0.0, -0.002),
            at(-0.03, 0.01, -0.0018),
            at(0.0, 0.03, -0.0021),
            at(0.01, -0.03, -0.0016),
            at(0.06, 0.06, 0.012),
            at(-0.06, -0.06, 0.017),
            at(-0.06, 0.06, 0.010),
        ];
        let k = reduce(&mut pts, 0.02);
        assert_eq!(k, 4);
        assert!(pts[..k].iter().all(|c| c.distance < 0.0), "{:?}", &pts[..k]);
        assert_eq!(pts[0].distance, -0.0025);
        // Only two touching: the spread set over all, rim included.
        let mut few = vec![at(0.0, 0.0, -0.0025), at(0.03, 0.0, -0.002), at(0.06, 0.06, 0.012)];
        few.extend([at(-0.06, -0.06, 0.017), at(-0.06, 0.06, 0.010), at(0.06, -0.06, 0.015)]);
        let k = reduce(&mut few, 0.02);
        assert!(few[..k].iter().any(|c| c.distance > 0.002));
    }

    #[test]
    fn small_sets_are_kept_whole() {
        let mut pts = vec![at(0.0, 0.0, 0.0), at(1.0, 0.0, 0.0)];
        assert_eq!(reduce(&mut pts, 0.005), 2);
    }

    /// A wheel's two rim points on flat ground become one point midway, at the deeper depth;
    /// points with another normal (a height field's other triangle) stay a contact of their own.
    #[test]
    fn patch_contact_is_the_centre_of_the_points_sharing_a_normal() {
        let mut points = [at(0.0, -0.1, -0.002), at(0.0, 0.1, 0.001)];
        assert_eq!(merge_to_patch(&mut points, 2), 1);
        assert!((points[0].point_a - Vec3::new(0.0, 0.0, 0.0)).norm() < 1e-15);
        assert_eq!(points[0].distance, -0.002);
        let mut straddling = [at(0.0, -0.1, -0.001), at(0.3, 0.1, -0.003), at(0.0, 0.1, -0.002)];
        straddling[1].normal = Vec3::new(0.0, 0.1, 1.0).normalize();
        assert_eq!(merge_to_patch(&mut straddling, 3), 2);
        assert!((straddling[0].point_a - Vec3::new(0.0, 0.0, 0.0)).norm() < 1e-15);
        assert_eq!((straddling[0].distance, straddling[1].distance), (-0.002, -0.003));
        assert_eq!(straddling[1].point_a, Vec3::new(0.3, 0.1, 0.0));
    }
}
