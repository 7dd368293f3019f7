//! Narrow phase: contact manifolds of one pair of colliders through parry, with the per-pair
//! state (manifolds and workspaces) that persists between steps.
//!
//! [`dispatch`] is the one place that decides which algorithm handles which pair of shapes.

use super::shape::ShapeKind;
use parry3d_f64::math::{Pose, Real};
use parry3d_f64::query::details::{
    contact_manifold_ball_ball_shapes, contact_manifold_capsule_capsule_shapes,
    contact_manifold_convex_ball_shapes, contact_manifold_cuboid_cuboid_shapes,
    contact_manifold_pfm_pfm_shapes,
};
use parry3d_f64::query::TrackedContact;
use parry3d_f64::query::{
    ContactManifold, ContactManifoldsWorkspace, DefaultQueryDispatcher, PersistentQueryDispatcher,
    Unsupported,
};
use parry3d_f64::shape::{HalfSpace, PackedFeatureId, PolygonalFeature, Shape as ParryShape};
use std::collections::HashMap;

/// Manifolds of one pair, as parry writes them.
pub(crate) type Manifold = ContactManifold<(), ()>;

/// What persists for one pair of colliders between steps.
#[derive(Default)]
pub(crate) struct PairState {
    pub manifolds: Vec<Manifold>,
    pub workspace: Option<ContactManifoldsWorkspace>,
    pub last_step: u64,
}

/// Per-pair state keyed by (collider A, collider B).
#[derive(Default)]
pub(crate) struct PairCache {
    pub pairs: HashMap<(u32, u32), PairState, crate::math::FastHasher>,
}

impl PairCache {
    /// Drops the state of pairs that were not near each other in step `step`.
    pub fn forget_older_than(&mut self, step: u64) {
        self.pairs.retain(|_, s| s.last_step >= step);
    }
}

/// Computes the contact manifolds of shape A (kind `kind_a`) against shape B, with `pos_ab` the
/// pose of B's frame in A's frame and `prediction` the contact margin (m). Points come out in the
/// frames of A and B (or of their sub-shapes, see `ContactManifold::subshape_pos*`); each
/// manifold's `local_n1` is the outward normal of A (pointing from A to B).
///
/// | A \ B | sphere | box | capsule | cylinder, hull | half-space | trimesh, heightfield |
/// |---|---|---|---|---|---|---|
/// | sphere | ball–ball | convex–ball | convex–ball | convex–ball | sphere–plane (ours) | per triangle |
/// | box | convex–ball | box–box (SAT + clipping) | polygonal features | polygonal features | half-space–features (ours) | per triangle |
/// | capsule | convex–ball | polygonal features | capsule–capsule | polygonal features | half-space–features (ours) | per triangle |
/// | cylinder, hull | convex–ball | polygonal features | polygonal features | polygonal features | half-space–features (ours) | per triangle |
///
/// "Polygonal features" is GJK/EPA for the normal followed by clipping of the two support
/// features; "per triangle" runs the convex rules against each triangle near the other shape.
/// Static–static pairs never reach this function.
pub(crate) fn dispatch(
    kind_a: ShapeKind,
    shape_a: &dyn ParryShape,
    kind_b: ShapeKind,
    shape_b: &dyn ParryShape,
    pos_ab: &Pose,
    prediction: Real,
    state: &mut PairState,
) -> Result<(), Unsupported> {
    use ShapeKind::*;
    let convex = |k: ShapeKind| k.is_convex();
    if convex(kind_a) && (convex(kind_b) || kind_b == HalfSpace) {
        if state.manifolds.is_empty() {
            state.manifolds.push(Manifold::new());
        }
        let m = &mut state.manifolds[0];
        // Parry copies the previous points to match contacts across steps; we match by feature
        // ids ourselves, so clearing first keeps that copy from allocating every step.
        m.points.clear();
        match (kind_a, kind_b) {
            (Sphere, Sphere) => contact_manifold_ball_ball_shapes(pos_ab, shape_a, shape_b, prediction, m),
            (Box, Box) => {
                contact_manifold_cuboid_cuboid_shapes(pos_ab, shape_a, shape_b, prediction, m);
                add_hull_vertices(pos_ab, shape_a, shape_b, prediction, m);
            }
            (Capsule, Capsule) => {
                contact_manifold_capsule_capsule_shapes(pos_ab, shape_a, shape_b, prediction, m)
            }
            (_, HalfSpace) => {
                let half_space = shape_b.as_halfspace().ok_or(Unsupported)?;
                convex_against_half_space(pos_ab, shape_a, half_space, prediction, m)?;
            }
            (Sphere, _) | (_, Sphere) => {
                contact_manifold_convex_ball_shapes(pos_ab, shape_a, shape_b, None, None, prediction, m)
            }
            _ => {
                contact_manifold_pfm_pfm_shapes(pos_ab, shape_a, shape_b, None, None, prediction, m);
                if kind_a == ConvexHull || kind_b == ConvexHull {
                    add_hull_vertices(pos_ab, shape_a, shape_b, prediction, m);
                }
            }
        }
        drop_duplicate_points(m);
        Ok(())
    } else {
        DefaultQueryDispatcher.contact_manifolds(
            pos_ab,
            shape_a,
            shape_b,
            prediction,
            &mut state.manifolds,
            &mut state.workspace,
        )?;
        state.manifolds.iter_mut().for_each(drop_duplicate_points);
        Ok(())
    }
}

/// Two points of one manifold closer than this (m) on shape A are one contact.
const DUPLICATE_DISTANCE: Real = 1e-5;

/// Removes points that repeat an earlier point of the manifold. Parry's polygonal-feature rule
/// appends GJK's closest pair (with unknown feature ids) to the clipped points in 3D even when
/// clipping already produced it — a capsule's end on a box face comes out twice. Two rows with
/// one Jacobian make the Delassus matrix exactly singular, and on such degenerate problems
/// projected Gauss–Seidel stalls (a pile of ragdolls, hands on torsos, never settled).
fn drop_duplicate_points(m: &mut Manifold) {
    let mut k = 1;
    while k < m.points.len() {
        let p = m.points[k].local_p1;
        if m.points[..k].iter().any(|q| (q.local_p1 - p).length() <= DUPLICATE_DISTANCE) {
            m.points.remove(k);
        } else {
            k += 1;
        }
    }
}

/// A convex shape A against the half-space B (the most common pair: everything on the ground):
/// the vertices of A's support feature toward the plane within `prediction`, or the sphere's
/// lowest point. Written here rather than taken from parry because parry's version allocates on
/// every call; the result is the same manifold.
fn convex_against_half_space(
    pos_ab: &Pose,
    shape_a: &dyn ParryShape,
    half_space: &HalfSpace,
    prediction: Real,
    m: &mut Manifold,
) -> Result<(), Unsupported> {
    // The plane in A's frame: normal n (pointing out of the half-space, toward A), through o.
    let n = pos_ab.rotation * half_space.normal;
    let o = pos_ab.translation;
    let pos_ba = pos_ab.inverse();
    let mut emit = |point_a: parry3d_f64::math::Vector, border: Real, fid: PackedFeatureId| {
        let distance = (point_a - o).dot(n) - border;
        if distance <= prediction {
            let on_a = point_a - n * border;
            let on_plane = on_a - n * distance;
            m.points.push(TrackedContact::new(
                on_a,
                pos_ba * on_plane,
                fid,
                PackedFeatureId::face(0),
                distance,
            ));
        }
    };
    if let Some(ball) = shape_a.as_ball() {
        emit(parry3d_f64::math::Vector::ZERO, ball.radius, PackedFeatureId::face(0));
    } else if let Some(hull) = shape_a.as_convex_polyhedron() {
        // Parry's support feature of a hull stops at 4 vertices of a face; every vertex within
        // the margin is a candidate, and the reduction keeps the 4 that span the most area.
        for (i, p) in hull.points().iter().enumerate() {
            emit(*p, 0.0, PackedFeatureId::vertex(i as u32));
        }
    } else {
        let (features, border) = shape_a.as_polygonal_feature_map().ok_or(Unsupported)?;
        let mut feature = PolygonalFeature::default();
        features.local_support_feature(-n, &mut feature);
        for i in 0..feature.num_vertices {
            emit(feature.vertices[i], border, feature.vids[i]);
        }
    }
    m.local_n1 = -n;
    m.local_n2 = half_space.normal;
    m.subshape1 = 0;
    m.subshape2 = 0;
    Ok(())
}

/// Parry's polygonal features stop at 4 vertices of a face, so a hull resting on a face with
/// more vertices would be held on one side only; and two equal boxes stacked face on face
/// have their corners exactly on the clipping boundary, where rounding keeps 2, 3 or 4 of
/// them from step to step (a stack then rocks and settles by millimetres). Every vertex of a
/// hull or box within the margin of the contact plane (through the manifold's first point,
/// along its normal) whose foot on that plane lies on the other shape's surface is added; the
/// reduction then keeps the 4 that span the most area. When the clipping kept no point at all
/// (the same corners exactly on the boundary), the plane goes through the other shape's
/// support point along the manifold's normal: otherwise the pair would lose every contact for
/// a step and the boxes above it fall by g·h².
fn add_hull_vertices(
    pos_ab: &Pose,
    shape_a: &dyn ParryShape,
    shape_b: &dyn ParryShape,
    prediction: Real,
    m: &mut Manifold,
) {
    let pos_ba = pos_ab.inverse();
    // The two surfaces' planes: through the manifold's first point, or, when parry's clipping
    // kept no point at all (two equal boxes face on face, offset by rounding: every corner lies
    // on the other face's boundary), through each shape's support point along its normal.
    let (plane_b_in_a, plane_a_in_b) = match m.points.first() {
        Some(first) => (*pos_ab * first.local_p2, pos_ba * first.local_p1),
        None => {
            let unit = |n: parry3d_f64::math::Vector| (n.length() - 1.0).abs() <= 1e-6;
            let (Some(support_a), Some(support_b)) = (shape_a.as_support_map(), shape_b.as_support_map())
            else {
                return;
            };
            if !unit(m.local_n1) || !unit(m.local_n2) {
                return;
            }
            (
                *pos_ab * support_b.local_support_point(m.local_n2),
                pos_ba * support_a.local_support_point(m.local_n1),
            )
        }
    };
    let on_surface = |foot: parry3d_f64::math::Vector, shape: &dyn ParryShape| {
        let proj = shape.project_local_point(foot, false);
        ((proj.point - foot).length() <= 1e-9 * (1.0 + foot.length())).then_some(proj.point)
    };
    {
        // Plane of B's surface in A's frame; n1 points from A to B.
        let (plane, n1) = (plane_b_in_a, m.local_n1);
        for (i, v) in vertices(shape_a).enumerate() {
            let v = &v;
            let distance = (plane - *v).dot(n1);
            let known = m.points.iter().any(|c| (c.local_p1 - *v).length() <= 1e-9);
            if distance <= prediction && !known {
                if let Some(on_b) = on_surface(pos_ba * (*v + n1 * distance), shape_b) {
                    m.points.push(TrackedContact::new(
                        *v,
                        on_b,
                        PackedFeatureId::vertex(i as u32),
                        PackedFeatureId::face(0),
                        distance,
                    ));
                }
            }
        }
    }
    {
        let (plane, n2) = (plane_a_in_b, m.local_n2);
        for (i, v) in vertices(shape_b).enumerate() {
            let v = &v;
            let distance = (plane - *v).dot(n2);
            let known = m.points.iter().any(|c| (c.local_p2 - *v).length() <= 1e-9);
            if distance <= prediction && !known {
                if let Some(on_a) = on_surface(*pos_ab * (*v + n2 * distance), shape_a) {
                    m.points.push(TrackedContact::new(
                        on_a,
                        *v,
                        PackedFeatureId::face(0),
                        PackedFeatureId::vertex(i as u32),
                        distance,
                    ));
                }
            }
        }
    }
}

/// The vertices of a convex hull or a box (in its frame); none for other shapes.
fn vertices(shape: &dyn ParryShape) -> impl Iterator<Item = parry3d_f64::math::Vector> + '_ {
    let hull = shape.as_convex_polyhedron().map(|h| h.points()).unwrap_or(&[]);
    let half = shape.as_cuboid().map(|c| c.half_extents);
    let corners = (0..8 * usize::from(half.is_some())).map(move |k| {
        let h = half.unwrap_or_default();
        // Bit set = negative coordinate, as parry numbers a cuboid's vertex features.
        let sign = |bit: usize| if k & bit == 0 { 1.0 } else { -1.0 };
        parry3d_f64::math::Vector::new(sign(1) * h.x, sign(2) * h.y, sign(4) * h.z)
    });
    hull.iter().copied().chain(corners)
}

#[cfg(test)]
mod tests {
    use super::*;
    use parry3d_f64::math::{Rotation, Vector};
    use parry3d_f64::shape::Cuboid;

    /// The pose of one pair of a 20-box stack (equal 0.1 m cubes) at which parry's clipping kept
    /// no point: B 2.75e-15 m above A, turned by ~1e-16 rad. Every corner must still be found.
    #[test]
    fn equal_boxes_face_on_face_keep_four_contacts_when_clipping_keeps_none() {
        let cube = Cuboid::new(Vector::new(0.05, 0.05, 0.05));
        let rotation =
            Rotation::from_xyzw(-1.4062650245609794e-16, 2.13318836454674e-16, 4.4063919872127254e-17, 1.0);
        let translation = Vector::new(2.304988321515077e-17, 1.524036380320376e-17, 0.10000000000000275);
        let pos_ab = Pose::from_parts(translation, rotation);
        let mut state = PairState::default();
        dispatch(ShapeKind::Box, &cube, ShapeKind::Box, &cube, &pos_ab, 0.005, &mut state).unwrap();
        let points: Vec<_> = state.manifolds.iter().flat_map(|m| m.points.iter()).collect();
        assert!(points.len() >= 4, "{} contact points", points.len());
        for p in points {
            assert!(p.dist.abs() < 1e-12, "distance {}", p.dist);
        }
    }

    /// A capsule lying across a box face (a ragdoll's forearm on another's hand): parry's
    /// clipping gives the segment's two ends and GJK's closest pair repeats one of them; the
    /// manifold keeps each contact once (a repeated row makes the contact problem singular).
    #[test]
    fn capsule_on_a_box_face_has_no_repeated_contact_points() {
        use parry3d_f64::shape::Capsule;
        let plate = Cuboid::new(Vector::new(0.3, 0.3, 0.05));
        // Segment along x, 0.2 m long, radius 0.04, slightly tilted so that one end is deepest
        // (the closest pair GJK reports is then that end).
        let capsule = Capsule::new_x(0.1, 0.04);
        let rotation = Rotation::from_scaled_axis(Vector::new(0.0, 0.01, 0.0));
        let pos_ab = Pose::from_parts(Vector::new(0.05, 0.02, 0.05 + 0.04 - 1e-4), rotation);
        let mut state = PairState::default();
        dispatch(ShapeKind::Box, &plate, ShapeKind::Capsule, &capsule, &pos_ab, 0.02, &mut state).unwrap();
        let points: Vec<_> = state.manifolds.iter().flat_map(|m| m.points.iter()).collect();
        assert_eq!(points.len(), 2, "{points:?}");
        let gap = (points[0].local_p1 - points[1].local_p1).length();
        assert!(gap > 0.19, "the two ends are {gap} m apart");
    }
}
