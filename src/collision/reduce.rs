//! Reduced contact sets: at most four points per colliding pair, chosen as the deepest point and
//! the points that span the largest area in the contact plane (the lecture's reduced contact set;
//! the same heuristic as Gregorius, "Robust contact creation for physics simulations", GDC 2015).
//! Four well-spread points hold a resting box as firmly as the whole contact polygon does, and the
//! constraint problem stays small.

use crate::math::Vec3;

/// A candidate contact point before reduction (world frame).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Candidate {
    pub point_a: Vec3,
    pub point_b: Vec3,
    pub normal: Vec3,
    pub distance: f64,
    pub feature: u64,
}

/// Maximum number of contact points kept per pair.
pub const MAX_POINTS_PER_PAIR: usize = 4;

/// Reorders `points` so that its first `k ≤ 4` entries are the reduced set and returns `k`.
/// Chooses: the deepest point; the point farthest from it; the point making the largest triangle
/// with those two; the point that adds the largest area outside that triangle (if any does).
/// Distances are measured in the plane orthogonal to the deepest point's normal.
pub(crate) fn reduce(points: &mut [Candidate]) -> usize {
    if points.len() <= MAX_POINTS_PER_PAIR {
        return points.len();
    }
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
        Candidate { point_a: p, point_b: p, normal: Vec3::z(), distance: d, feature: 0 }
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
        let k = reduce(&mut pts);
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

    #[test]
    fn small_sets_are_kept_whole() {
        let mut pts = vec![at(0.0, 0.0, 0.0), at(1.0, 0.0, 0.0)];
        assert_eq!(reduce(&mut pts), 2);
    }
}
