//! Contacts at the ends of two capsules' axes, beside parry's closest pair (see
//! [`add_axis_ends`]).

use super::Manifold;
use parry3d_f64::math::{Pose, Real, Vector};
use parry3d_f64::query::TrackedContact;
use parry3d_f64::shape::{PackedFeatureId, Shape as ParryShape};

/// Capsule A against capsule B, after parry's manifold (the closest points of the two axes, or
/// two clipped points when the axes are nearly parallel): a contact for each end of either axis
/// within `prediction` of the other capsule, along the line from that end to its closest point
/// on the other axis, each in a manifold of its own (its own normal; `subshape1` tells them
/// apart for the feature ids). Two fat capsules lying across each other at an angle touch near
/// one end of an axis and rock onto the other end: with the closest point alone, the contact
/// jumps from one end to the other between steps and the end that was not a contact sinks into
/// the other capsule (a ragdoll's abdomen on another's, 5 mm in one 2 ms step). Ends within half
/// the smaller radius of a point already found are not added again, nor is an end whose normal
/// opposes parry's (capsules so deep in each other that their axes overlap: the two ends of one
/// axis then see the other axis on opposite sides, and rows demanding separation both ways have
/// no solution). Leaves `manifolds[0]`.
pub(super) fn add_axis_ends(
    pos_ab: &Pose,
    shape_a: &dyn ParryShape,
    shape_b: &dyn ParryShape,
    prediction: Real,
    manifolds: &mut Vec<Manifold>,
) {
    let (Some(a), Some(b)) = (shape_a.as_capsule(), shape_b.as_capsule()) else {
        manifolds.truncate(1);
        return;
    };
    let pos_ba = pos_ab.inverse();
    let (a0, a1) = (a.segment.a, a.segment.b);
    let (b0, b1) = (*pos_ab * b.segment.a, *pos_ab * b.segment.b);
    let near = 0.5 * a.radius.min(b.radius);
    let mut used = 1;
    let primary = manifolds.first().filter(|m| !m.points.is_empty()).map(|m| m.local_n1);
    let ends = [(a0, b0, b1, true), (a1, b0, b1, true), (b0, a0, a1, false), (b1, a0, a1, false)];
    for (k, (end, s0, s1, of_a)) in ends.into_iter().enumerate() {
        let on_axis = closest_on_segment(end, s0, s1);
        let axis_gap = (on_axis - end).length();
        let distance = axis_gap - a.radius - b.radius;
        if axis_gap <= 1e-12 || distance > prediction {
            continue;
        }
        let (on_a, on_b) = if of_a { (end, on_axis) } else { (on_axis, end) };
        let n1 = (on_b - on_a) / axis_gap;
        if primary.is_some_and(|primary| n1.dot(primary) <= 0.0) {
            continue;
        }
        let p1 = on_a + n1 * a.radius;
        if manifolds[..used].iter().any(|m| m.points.iter().any(|c| (c.local_p1 - p1).length() <= near)) {
            continue;
        }
        if manifolds.len() <= used {
            manifolds.push(Manifold::new());
        }
        let m = &mut manifolds[used];
        m.points.clear();
        m.local_n1 = n1;
        m.local_n2 = pos_ba.rotation * -n1;
        m.subshape1 = 1 + k as u32;
        let end_feature = PackedFeatureId::vertex(k as u32 % 2);
        let (fid1, fid2) = if of_a {
            (end_feature, PackedFeatureId::face(0))
        } else {
            (PackedFeatureId::face(0), end_feature)
        };
        m.points.push(TrackedContact::new(p1, pos_ba * (on_b - n1 * b.radius), fid1, fid2, distance));
        used += 1;
    }
    manifolds.truncate(used);
}

/// The point of the segment from `s0` to `s1` nearest to `p`.
fn closest_on_segment(p: Vector, s0: Vector, s1: Vector) -> Vector {
    let axis = s1 - s0;
    let length_squared = axis.length_squared();
    if length_squared <= 0.0 {
        return s0;
    }
    s0 + axis * ((p - s0).dot(axis) / length_squared).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::super::{dispatch, PairState};
    use crate::collision::shape::ShapeKind;
    use parry3d_f64::math::{Pose, Rotation, Vector};

    /// Two fat capsules crossing at 30°, B 2 mm above A: parry's closest pair is the crossing
    /// point; the ends of B's axis are 4.2 mm from A within the 1 cm margin and are contacts too,
    /// each with the normal of its own closest pair, and A's ends (near B's) are not repeated.
    #[test]
    fn capsules_lying_across_each_other_touch_at_the_ends_of_the_axis() {
        use parry3d_f64::shape::Capsule;
        let (half, r) = (0.06, 0.1);
        let capsule = Capsule::new_x(half, r);
        let rotation = Rotation::from_scaled_axis(Vector::new(0.0, 0.0, std::f64::consts::FRAC_PI_6));
        let pos_ab = Pose::from_parts(Vector::new(0.0, 0.0, 2.0 * r + 0.002), rotation);
        let mut state = PairState::default();
        dispatch(ShapeKind::Capsule, &capsule, ShapeKind::Capsule, &capsule, &pos_ab, 0.01, &mut state)
            .unwrap();
        let points: Vec<_> =
            state.manifolds.iter().flat_map(|m| m.points.iter().map(move |p| (m.local_n1, p))).collect();
        assert_eq!(points.len(), 3, "{points:?}");
        let (end_x, end_y) = (half * 30f64.to_radians().cos(), half * 30f64.to_radians().sin());
        let expected = ((end_y * end_y + (2.0 * r + 0.002).powi(2)).sqrt() - 2.0 * r, 0.002);
        for (n1, p) in &points {
            let on_a = p.local_p1;
            let on_b = pos_ab * p.local_p2;
            assert!(((on_b - on_a).dot(*n1) - p.dist).abs() < 1e-12, "{p:?}");
            let at_end = (on_a.x.abs() - end_x).abs() < 1e-3;
            let want = if at_end { expected.0 } else { expected.1 };
            assert!((p.dist - want).abs() < 1e-9, "distance {} at {on_a:?}, want {want}", p.dist);
        }
        assert_eq!(points.iter().filter(|(_, p)| p.local_p1.x.abs() > 0.04).count(), 2);
        // Lifted out of the margin, the ends go and the extra manifolds with them.
        let far = Pose::from_parts(Vector::new(0.0, 0.0, 2.0 * r + 0.008), rotation);
        dispatch(ShapeKind::Capsule, &capsule, ShapeKind::Capsule, &capsule, &far, 0.01, &mut state).unwrap();
        assert_eq!(state.manifolds.iter().map(|m| m.points.len()).sum::<usize>(), 1);
    }
    /// Two upright capsules so deep in each other that B's short axis lies within A's: the two
    /// ends of A's axis see B's axis below and above. No end contact opposes parry's normal (a
    /// pair of rows demanding separation both ways has no solution: every solver failed on it).
    #[test]
    fn capsules_whose_axes_overlap_get_no_opposed_normals() {
        use parry3d_f64::shape::Capsule;
        let (a, b) = (Capsule::new_z(0.5, 1.0), Capsule::new_z(0.016, 1.0));
        let pos_ab = Pose::from_parts(Vector::new(0.0, 0.0, -0.427), Rotation::IDENTITY);
        let mut state = PairState::default();
        dispatch(ShapeKind::Capsule, &a, ShapeKind::Capsule, &b, &pos_ab, 0.01, &mut state).unwrap();
        let primary = state.manifolds[0].local_n1;
        assert!(!state.manifolds[0].points.is_empty());
        for m in &state.manifolds {
            assert!(m.local_n1.dot(primary) > 0.0, "normal {:?} against {primary:?}", m.local_n1);
        }
    }
}
