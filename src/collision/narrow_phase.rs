//! Narrow phase: contact manifolds of one pair of colliders through parry, with the per-pair
//! state (manifolds and workspaces) that persists between steps.
//!
//! [`dispatch`] is the one place that decides which algorithm handles which pair of shapes.

use super::shape::ShapeKind;
use parry3d_f64::math::{Pose, Real};
use parry3d_f64::query::details::{
    contact_manifold_ball_ball_shapes, contact_manifold_capsule_capsule_shapes,
    contact_manifold_convex_ball_shapes, contact_manifold_cuboid_cuboid_shapes,
    contact_manifold_pfm_pfm_shapes, contact_manifolds_trimesh_shape_shapes, NormalConstraints,
    NormalConstraintsPair,
};
use parry3d_f64::query::{
    ContactManifold, ContactManifoldsWorkspace, DefaultQueryDispatcher, PersistentQueryDispatcher,
    Unsupported,
};
use parry3d_f64::query::{PointQuery, TrackedContact};
use parry3d_f64::shape::{
    HalfSpace, PackedFeatureId, PolygonalFeature, PolygonalFeatureMap, Shape as ParryShape, Triangle,
};
use std::collections::HashMap;
mod axis_ends;

/// Manifolds of one pair, as parry writes them.
pub(crate) type Manifold = ContactManifold<(), ()>;

/// What persists for one pair of colliders between steps.
#[derive(Default)]
pub(crate) struct PairState {
    pub manifolds: Vec<Manifold>,
    pub workspace: Option<ContactManifoldsWorkspace>,
    pub last_step: u64,
    /// Pose of B in A's frame when the manifolds were last computed (None: never, or the last
    /// call failed), for [`refresh_distances`].
    pub computed_at: Option<Pose>,
    /// The pair's margin (m) when the manifolds were last computed: they hold every point
    /// within it.
    pub computed_margin: f64,
    /// Per manifold, whether this call's height-field loop reached its triangle
    /// ([`convex_against_height_field`]).
    visited: Vec<bool>,
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

/// Whether the pose of B in A's frame, `pos_ab`, is within `translation` (m) and `rotation`
/// (rad) of `before`.
pub(crate) fn pose_within(before: &Pose, pos_ab: &Pose, translation: Real, rotation: Real) -> bool {
    if (pos_ab.translation - before.translation).length_squared() > translation * translation {
        return false;
    }
    // The vector part of q₀⁻¹q has length sin(θ/2) for the angle θ between the two rotations
    // (whichever sign either quaternion has); near zero it is resolved to rounding, where
    // 1 − |q₀·q| = θ²/8 is lost below θ ≈ 4e-8 rad.
    let (q0, q) = (before.rotation, pos_ab.rotation);
    let (v0, v) = (q0.xyz(), q.xyz());
    let half_sine = v * q0.w - v0 * q.w - v0.cross(v);
    let bound = (0.5 * rotation.min(std::f64::consts::PI)).sin();
    half_sine.length_squared() <= bound * bound
}

/// Recomputes each point's signed distance for B at `pos_ab`, keeping A's point where it is on
/// A and the normal where it is in A's frame (Bullet's refresh of a persistent manifold): the
/// distance is `(p₂ − p₁)·n₁` with B's point p₂ carried along with B, and p₂ is then put at
/// `p₁ + dist · n₁`, so that the two points stay apart along the normal only. Exact to first
/// order in the motion since the manifolds were computed, off by what the motion changes of
/// which points are closest (second order: δ²/2r for a sphere of radius r moved sideways by δ).
pub(crate) fn refresh_distances(manifolds: &mut [Manifold], pos_ab: &Pose) {
    for m in manifolds {
        let sub1 = m.subshape_pos1().copied().unwrap_or(Pose::IDENTITY);
        let sub2 = pos_ab * m.subshape_pos2().copied().unwrap_or(Pose::IDENTITY);
        let n1 = sub1.rotation * m.local_n1;
        for p in &mut m.points {
            let p1 = sub1 * p.local_p1;
            p.dist = (sub2 * p.local_p2 - p1).dot(n1);
            p.local_p2 = sub2.inverse_transform_point(p1 + n1 * p.dist);
        }
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
/// features; "per triangle" runs the convex rules against each triangle near the other shape,
/// through [`TriangleFaces`]: a convex shape over a triangle's face (a wheel on a height field)
/// takes the face's normal without GJK/EPA, other triangles parry's polygonal-feature rule.
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
        if matches!((kind_a, kind_b), (Capsule, Capsule)) {
            axis_ends::add_axis_ends(pos_ab, shape_a, shape_b, prediction, &mut state.manifolds);
        }
        Ok(())
    } else if convex(kind_a) && kind_b == HeightField || convex(kind_b) && kind_a == HeightField {
        convex_against_height_field(pos_ab, shape_a, shape_b, prediction, state)?;
        state.manifolds.iter_mut().for_each(drop_duplicate_points);
        Ok(())
    } else if convex(kind_a) && kind_b == TriMesh || convex(kind_b) && kind_a == TriMesh {
        TriangleFaces.contact_manifolds(
            pos_ab,
            shape_a,
            shape_b,
            prediction,
            &mut state.manifolds,
            &mut state.workspace,
        )?;
        state.manifolds.iter_mut().for_each(drop_duplicate_points);
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

/// Parry's per-triangle loop over a triangle mesh (a height field's is
/// [`convex_against_height_field`]), with each triangle against
/// the convex shape by [`TriangleFace::contacts`] where the triangle's face decides the contact,
/// and by parry's own rule (GJK, then EPA when they overlap) elsewhere. EPA allocates on every
/// call and a wheel resting on a height field overlaps a triangle or two at every step: the
/// buggy on its terrain spent 40 µs of its 74 µs step in this collision, most of it in GJK/EPA.
struct TriangleFaces;

/// Parry's composite loops need the plain queries too; they are parry's.
impl parry3d_f64::query::QueryDispatcher for TriangleFaces {
    fn intersection_test(
        &self,
        pos12: &Pose,
        g1: &dyn ParryShape,
        g2: &dyn ParryShape,
    ) -> Result<parry3d_f64::query::ShapeIntersection, Unsupported> {
        DefaultQueryDispatcher.intersection_test(pos12, g1, g2)
    }

    fn distance(
        &self,
        pos12: &Pose,
        g1: &dyn ParryShape,
        g2: &dyn ParryShape,
    ) -> Result<parry3d_f64::query::ShapeDistance, Unsupported> {
        DefaultQueryDispatcher.distance(pos12, g1, g2)
    }

    fn contact(
        &self,
        pos12: &Pose,
        g1: &dyn ParryShape,
        g2: &dyn ParryShape,
        prediction: Real,
    ) -> Result<Option<parry3d_f64::query::Contact>, Unsupported> {
        DefaultQueryDispatcher.contact(pos12, g1, g2, prediction)
    }

    fn closest_points(
        &self,
        pos12: &Pose,
        g1: &dyn ParryShape,
        g2: &dyn ParryShape,
        max_dist: Real,
    ) -> Result<parry3d_f64::query::ClosestPoints, Unsupported> {
        DefaultQueryDispatcher.closest_points(pos12, g1, g2, max_dist)
    }

    fn cast_shapes(
        &self,
        pos12: &Pose,
        local_vel12: parry3d_f64::math::Vector,
        g1: &dyn ParryShape,
        g2: &dyn ParryShape,
        options: parry3d_f64::query::ShapeCastOptions,
    ) -> Result<Option<parry3d_f64::query::ShapeCastHit>, Unsupported> {
        DefaultQueryDispatcher.cast_shapes(pos12, local_vel12, g1, g2, options)
    }

    fn cast_shapes_nonlinear(
        &self,
        motion1: &parry3d_f64::query::NonlinearRigidMotion,
        g1: &dyn ParryShape,
        motion2: &parry3d_f64::query::NonlinearRigidMotion,
        g2: &dyn ParryShape,
        start_time: Real,
        end_time: Real,
        stop_at_penetration: bool,
    ) -> Result<Option<parry3d_f64::query::ShapeCastHit>, Unsupported> {
        DefaultQueryDispatcher.cast_shapes_nonlinear(
            motion1,
            g1,
            motion2,
            g2,
            start_time,
            end_time,
            stop_at_penetration,
        )
    }
}

impl PersistentQueryDispatcher<(), ()> for TriangleFaces {
    fn contact_manifolds(
        &self,
        pos12: &Pose,
        g1: &dyn ParryShape,
        g2: &dyn ParryShape,
        prediction: Real,
        manifolds: &mut Vec<Manifold>,
        workspace: &mut Option<ContactManifoldsWorkspace>,
    ) -> Result<(), Unsupported> {
        if g1.as_trimesh().is_some() || g2.as_trimesh().is_some() {
            contact_manifolds_trimesh_shape_shapes(self, pos12, g1, g2, prediction, manifolds, workspace);
            Ok(())
        } else {
            DefaultQueryDispatcher.contact_manifolds(pos12, g1, g2, prediction, manifolds, workspace)
        }
    }

    fn contact_manifold_convex_convex(
        &self,
        pos12: &Pose,
        g1: &dyn ParryShape,
        g2: &dyn ParryShape,
        normal_constraints1: Option<&dyn NormalConstraints>,
        normal_constraints2: Option<&dyn NormalConstraints>,
        prediction: Real,
        manifold: &mut Manifold,
    ) -> Result<(), Unsupported> {
        let decided = match (g1.as_triangle(), g2.as_triangle()) {
            (Some(triangle), None) => g2.as_polygonal_feature_map().is_some_and(|(convex, border)| {
                let faces = TriangleFace { triangle, constraints: normal_constraints1 };
                faces.contacts(pos12, convex, border, normal_constraints2, prediction, manifold, false)
            }),
            (None, Some(triangle)) => g1.as_polygonal_feature_map().is_some_and(|(convex, border)| {
                let faces = TriangleFace { triangle, constraints: normal_constraints2 };
                let pos21 = pos12.inverse();
                faces.contacts(&pos21, convex, border, normal_constraints1, prediction, manifold, true)
            }),
            _ => false,
        };
        if decided {
            return Ok(());
        }
        // Parry's polygonal-feature rule first keeps the last points while the pair has moved
        // less than 1 mm and 1° (a parked wheel skips GJK), then copies them to match the new
        // ones against (allocating at every call); we match contacts by feature ids ourselves.
        let polygonal = g1.as_polygonal_feature_map().is_some() && g2.as_polygonal_feature_map().is_some();
        if polygonal && manifold.try_update_contacts_eps(pos12, PARRY_COS_1_DEGREE, 1.0e-6) {
            return Ok(());
        }
        manifold.points.clear();
        DefaultQueryDispatcher.contact_manifold_convex_convex(
            pos12,
            g1,
            g2,
            normal_constraints1,
            normal_constraints2,
            prediction,
            manifold,
        )
    }
}

/// Marks a manifold of [`convex_against_height_field`] that no triangle holds.
const FREE_TRIANGLE: u32 = u32::MAX;

/// A convex shape against a height field (either of A and B), triangle by triangle as
/// [`TriangleFaces`] handles them, each triangle with its own manifold (the triangle's index as
/// the height field's sub-shape id, as parry numbers them) and parry's pseudo-normals. Parry's own
/// loop rebuilds its list of manifolds at every call (a dozen allocations per wheel and step);
/// here the manifolds of triangles left behind are emptied and handed to the next new ones.
fn convex_against_height_field(
    pos_ab: &Pose,
    shape_a: &dyn ParryShape,
    shape_b: &dyn ParryShape,
    prediction: Real,
    state: &mut PairState,
) -> Result<(), Unsupported> {
    use parry3d_f64::bounding_volume::BoundingVolume;
    let (field, convex, field_is_a) = match (shape_a.as_heightfield(), shape_b.as_heightfield()) {
        (Some(field), None) => (field, shape_b, true),
        (None, Some(field)) => (field, shape_a, false),
        _ => return Err(Unsupported),
    };
    let id = |m: &Manifold| if field_is_a { m.subshape1 } else { m.subshape2 };
    let pos_field_convex = if field_is_a { *pos_ab } else { pos_ab.inverse() };
    let aabb = convex.compute_aabb(&pos_field_convex).loosened(prediction);
    let (manifolds, visited) = (&mut state.manifolds, &mut state.visited);
    visited.clear();
    visited.resize(manifolds.len(), false);
    field.map_elements_in_local_aabb(&aabb, &mut |i, triangle| {
        let k = match manifolds.iter().position(|m| id(m) == i) {
            Some(k) => k,
            None => {
                let (subshape1, subshape2) = if field_is_a { (i, 0) } else { (0, i) };
                match manifolds.iter().position(|m| id(m) == FREE_TRIANGLE) {
                    Some(k) => {
                        (manifolds[k].subshape1, manifolds[k].subshape2) = (subshape1, subshape2);
                        k
                    }
                    None => {
                        manifolds.push(Manifold::with_data(subshape1, subshape2, ()));
                        visited.push(false);
                        manifolds.len() - 1
                    }
                }
            }
        };
        visited[k] = true;
        let pseudo_normals = field.triangle_normal_constraints(i);
        let constraints = pseudo_normals.as_ref().map(|n| n as &dyn NormalConstraints);
        let m = &mut manifolds[k];
        // Unsupported shapes are refused when colliders are made; the loop goes on regardless.
        let _ = if field_is_a {
            TriangleFaces.contact_manifold_convex_convex(
                pos_ab,
                triangle,
                convex,
                constraints,
                None,
                prediction,
                m,
            )
        } else {
            TriangleFaces.contact_manifold_convex_convex(
                pos_ab,
                convex,
                triangle,
                None,
                constraints,
                prediction,
                m,
            )
        };
    });
    for (m, _) in manifolds.iter_mut().zip(visited.iter()).filter(|(_, seen)| !**seen) {
        m.points.clear();
        (m.subshape1, m.subshape2) = (FREE_TRIANGLE, FREE_TRIANGLE);
    }
    Ok(())
}

/// cos 1° as parry's polygonal-feature rule rounds it (its `utils::COS_1_DEGREES` is private).
const PARRY_COS_1_DEGREE: Real = 0.99984769515;

/// One triangle of a height field or mesh, with the normals its neighbours allow (parry's
/// pseudo-normals, which keep contacts from catching on interior edges).
struct TriangleFace<'a> {
    triangle: &'a Triangle,
    constraints: Option<&'a dyn NormalConstraints>,
}

impl TriangleFace<'_> {
    /// The contacts of a convex shape (`convex` with its `border` radius, its frame at `pos_tc`
    /// in the triangle's frame) with this triangle when the triangle's face decides them;
    /// `false` (and the manifold untouched) when an edge or vertex of the triangle may.
    ///
    /// With n the face normal on the convex's side and s the convex's lowest point along −n at
    /// signed distance d above the face's plane: for d > `prediction` the plane separates them
    /// (no contact, exactly); for s's foot on the plane inside the triangle by at least max(0, −d)
    /// (the depth of an overlap), n is the contact normal — the closest pair, exactly, when they
    /// are apart, and the face's own normal (which the pseudo-normals would project an EPA
    /// direction onto) when they overlap by less than the way out over an edge. The points are
    /// then parry's clipping of the two support features along n, as in its polygonal-feature
    /// rule. `flipped`: the manifold's shape 1 is the convex.
    #[allow(clippy::too_many_arguments)]
    fn contacts(
        &self,
        pos_tc: &Pose,
        convex: &dyn PolygonalFeatureMap,
        border: Real,
        convex_constraints: Option<&dyn NormalConstraints>,
        prediction: Real,
        manifold: &mut Manifold,
        flipped: bool,
    ) -> bool {
        let Triangle { a, b, c } = *self.triangle;
        let Some(mut normal) = self.triangle.normal() else {
            return false;
        };
        if (pos_tc.translation - a).dot(normal) < 0.0 {
            normal = -normal;
        }
        let normal_c = pos_tc.rotation.inverse() * -normal;
        let support_c = convex.local_support_point(normal_c);
        let support = *pos_tc * support_c;
        let height = (support - a).dot(normal);
        let distance = height - border;
        if distance > prediction {
            manifold.points.clear();
            return true;
        }
        let foot = support - normal * height;
        // The foot's distance inside each edge (the edges run counter-clockwise about n).
        let ccw = (b - a).cross(c - a).dot(normal) > 0.0;
        let inside = |p: parry3d_f64::math::Vector, q: parry3d_f64::math::Vector| {
            let edge = if ccw { q - p } else { p - q };
            normal.cross(edge).dot(foot - p) / edge.length()
        };
        let margin = inside(a, b).min(inside(b, c)).min(inside(c, a));
        if margin.is_nan() || margin < (-distance).max(0.0) {
            // Before GJK: along the axis from the triangle's point nearest the convex's origin
            // (the triangle's support point along it) to that origin, the gap is a lower bound
            // on their distance, and beyond the margin it separates them exactly. It does for
            // most triangles beside the one a wheel stands on: their planes pass near its
            // lowest point, the wheel itself is centimetres above them.
            let origin = pos_tc.translation;
            let nearest = self.triangle.project_local_point(origin, true).point;
            if let Some(axis) = (origin - nearest).try_normalize() {
                let lowest = *pos_tc * convex.local_support_point(pos_tc.rotation.inverse() * -axis);
                if (lowest - nearest).dot(axis) - border > prediction {
                    manifold.points.clear();
                    return true;
                }
            }
            return false;
        }
        let (mut n_t, mut n_c) = (normal, normal_c);
        let constraints = (self.constraints, convex_constraints);
        if !constraints.project_local_normals(pos_tc, &mut n_t, &mut n_c) || n_t.dot(normal) < 1.0 - 1e-12 {
            return false;
        }
        let mut feature = PolygonalFeature::default();
        convex.local_support_feature_toward(normal_c, support_c, &mut feature);
        let face = PolygonalFeature::from(*self.triangle);
        manifold.points.clear();
        PolygonalFeature::contacts(
            pos_tc,
            &pos_tc.inverse(),
            normal,
            normal_c,
            &face,
            &feature,
            manifold,
            flipped,
        );
        if manifold.points.is_empty() {
            // Clipping at the features' boundaries can keep nothing: the closest pair then.
            let contact = TrackedContact::flipped(
                foot,
                support_c,
                PackedFeatureId::face(0),
                feature.fid,
                height,
                flipped,
            );
            manifold.points.push(contact);
        }
        for point in &mut manifold.points {
            let on_convex = if flipped { &mut point.local_p1 } else { &mut point.local_p2 };
            *on_convex += normal_c * border;
            point.dist -= border;
        }
        (manifold.local_n1, manifold.local_n2) =
            if flipped { (normal_c, normal) } else { (normal, normal_c) };
        true
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

    /// Convex shapes over one triangle, at random poses near its face: where the face decides
    /// (`TriangleFace::contacts` returns true), its manifold is parry's GJK/EPA one — the same
    /// normal, the same distances, each point one of parry's (parry adds GJK's closest pair as
    /// an extra point) — in both orders of the pair; and the plane's early out is never wrong.
    #[test]
    fn a_convex_over_a_triangle_face_gets_parrys_manifold_without_gjk() {
        use parry3d_f64::shape::{Capsule, Cylinder};
        use rand::{Rng, SeedableRng};
        let triangle = Triangle::new(
            Vector::new(-0.4, -0.3, 0.02),
            Vector::new(0.5, -0.2, -0.03),
            Vector::new(0.0, 0.45, 0.05),
        );
        // (name, shape, polygonal: its support features do not depend on the hint). A cylinder's
        // cap is a square turned toward the hint — parry's is GJK's closest point, ours the
        // support point —, so its corners away from the closest point differ.
        let shapes: [(&str, Box<dyn ParryShape>, bool); 3] = [
            ("wheel", Box::new(Cylinder::new(0.05, 0.3)), false),
            ("box", Box::new(Cuboid::new(Vector::new(0.1, 0.06, 0.04))), true),
            ("capsule", Box::new(Capsule::new_x(0.1, 0.03)), true),
        ];
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let (mut decided, mut compared, mut apart) = (0, 0, 0);
        for (name, shape, polygonal) in &shapes {
            for _ in 0..400 {
                let rotation = Rotation::from_scaled_axis(Vector::new(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                ));
                // Its lowest point toward the triangle at a height of −2 mm … +3 cm.
                let mut pos_tc = Pose::from_parts(
                    Vector::new(rng.random_range(-0.3..0.3), rng.random_range(-0.25..0.3), 0.0),
                    rotation,
                );
                let normal = triangle.normal().unwrap();
                let (features, border) = shape.as_polygonal_feature_map().unwrap();
                let lowest = pos_tc * features.local_support_point(pos_tc.rotation.inverse() * -normal);
                let height = (lowest - triangle.a).dot(normal) - border;
                pos_tc.translation += normal * (rng.random_range(-0.002..0.03) - height);
                let prediction = 0.01;
                for flipped in [false, true] {
                    let face = TriangleFace { triangle: &triangle, constraints: None };
                    let mut ours = Manifold::new();
                    if !face.contacts(&pos_tc, features, border, None, prediction, &mut ours, flipped) {
                        continue;
                    }
                    decided += 1;
                    let mut parry = Manifold::new();
                    if flipped {
                        let pos_ct = pos_tc.inverse();
                        DefaultQueryDispatcher
                            .contact_manifold_convex_convex(
                                &pos_ct, &**shape, &triangle, None, None, prediction, &mut parry,
                            )
                            .unwrap();
                    } else {
                        DefaultQueryDispatcher
                            .contact_manifold_convex_convex(
                                &pos_tc, &triangle, &**shape, None, None, prediction, &mut parry,
                            )
                            .unwrap();
                    }
                    if ours.points.is_empty() {
                        // The plane separates them by more than the margin.
                        assert!(parry.points.is_empty(), "{name}: parry found {:?}", parry.points);
                        apart += 1;
                        continue;
                    }
                    compared += 1;
                    assert!(
                        ours.local_n1.dot(parry.local_n1) > 1.0 - 1e-9,
                        "{name}: {:?} {:?}",
                        ours.local_n1,
                        parry.local_n1
                    );
                    assert!(
                        ours.local_n2.dot(parry.local_n2) > 1.0 - 1e-9,
                        "{name}: {:?} {:?}",
                        ours.local_n2,
                        parry.local_n2
                    );
                    // Ours exactly: each pair of points lies along the face normal at its
                    // distance, the one on the triangle's plane, the other on the shape.
                    let sides = |c: &TrackedContact<()>| {
                        if flipped {
                            (c.local_p2, c.local_p1)
                        } else {
                            (c.local_p1, c.local_p2)
                        }
                    };
                    for c in &ours.points {
                        let (on_triangle, on_convex) = sides(c);
                        let on_convex_t = pos_tc * on_convex;
                        assert!((on_triangle - triangle.a).dot(normal).abs() < 1e-12, "{name}: {c:?}");
                        assert!(
                            (on_convex_t - on_triangle - normal * c.dist).length() < 1e-12,
                            "{name}: {c:?}"
                        );
                        // (A rounded shape's far points are its core's plus the border along the
                        // normal, as in parry: inside it, not on its surface.)
                        let solid = shape.project_local_point(on_convex, true).point;
                        assert!((solid - on_convex).length() < 1e-9, "{name}: {c:?} outside the shape");
                    }
                    // The closest distance is parry's (GJK's).
                    let closest =
                        |m: &Manifold| m.points.iter().map(|c| c.dist).fold(f64::INFINITY, f64::min);
                    assert!((closest(&ours) - closest(&parry)).abs() < 1e-6, "{name}: {ours:?} {parry:?}");
                    if !polygonal {
                        continue;
                    }
                    // Parry's within GJK's tolerance (a normal off by up to ~1e-5 rad moves points
                    // 0.3 m away by a few 1e-6 m; a curved cap's square turns with the hint).
                    for p in &ours.points {
                        let twin = parry.points.iter().find(|q| {
                            (q.local_p1 - p.local_p1).length() < 1e-5
                                && (q.local_p2 - p.local_p2).length() < 1e-5
                        });
                        let twin =
                            twin.unwrap_or_else(|| panic!("{name}: {p:?} is not in {:?}", parry.points));
                        assert!(
                            (twin.dist - p.dist).abs() < 1e-5,
                            "{name}: {} against {}",
                            p.dist,
                            twin.dist
                        );
                        assert_eq!((twin.fid1, twin.fid2), (p.fid1, p.fid2), "{name}");
                    }
                    let extra = parry.points.len() - ours.points.len();
                    assert!(extra <= 1, "{name}: parry {:?} ours {:?}", parry.points, ours.points);
                }
            }
        }
        assert!(
            decided > 600 && compared > 300 && apart > 50,
            "{decided} decided, {compared} compared, {apart} apart"
        );
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

#[cfg(test)]
mod refresh_tests {
    use super::*;
    use parry3d_f64::math::{Rotation, Vector};
    use parry3d_f64::shape::{Capsule, Cuboid};

    /// A pair of shapes (kinds and shapes of A and B) at a pose of B in A's frame.
    type Case<'a> = (&'a str, ShapeKind, &'a dyn ParryShape, ShapeKind, &'a dyn ParryShape, Pose);

    fn closest(state: &PairState) -> f64 {
        state.manifolds.iter().flat_map(|m| m.points.iter().map(|p| p.dist)).fold(f64::INFINITY, f64::min)
    }

    /// Refreshing a manifold at the pose it was computed at gives parry's distances back; after
    /// a small motion the refreshed closest distance is parry's new one to second order in the
    /// motion, and the two points of each contact stay apart along the normal only.
    #[test]
    fn refreshed_distances_match_a_fresh_manifold() {
        let capsule = Capsule::new_z(0.15, 0.05);
        let cube = Cuboid::new(Vector::new(0.1, 0.06, 0.04));
        let ground = HalfSpace::new(Vector::Z);
        let tilt = Rotation::from_scaled_axis(Vector::new(0.3, -0.2, 0.1));
        let at = |x: f64, y: f64, z: f64, r: Rotation| Pose::from_parts(Vector::new(x, y, z), r);
        let cases: [Case; 4] = [
            (
                "capsule/ground",
                ShapeKind::Capsule,
                &capsule,
                ShapeKind::HalfSpace,
                &ground,
                at(0.0, 0.0, -0.045, Rotation::IDENTITY),
            ),
            (
                "box/ground",
                ShapeKind::Box,
                &cube,
                ShapeKind::HalfSpace,
                &ground,
                at(0.01, 0.0, -0.039, Rotation::from_scaled_axis(Vector::new(0.002, 0.001, 0.0))),
            ),
            (
                "capsule/capsule",
                ShapeKind::Capsule,
                &capsule,
                ShapeKind::Capsule,
                &capsule,
                at(0.098, 0.01, 0.02, tilt),
            ),
            (
                "box/capsule",
                ShapeKind::Box,
                &cube,
                ShapeKind::Capsule,
                &capsule,
                at(0.0, 0.0, 0.089, Rotation::from_scaled_axis(Vector::new(1.5, 0.0, 0.0))),
            ),
        ];
        for (name, kind_a, a, kind_b, b, pose) in cases {
            let mut state = PairState::default();
            dispatch(kind_a, a, kind_b, b, &pose, 0.02, &mut state).unwrap();
            let fresh: Vec<f64> =
                state.manifolds.iter().flat_map(|m| m.points.iter().map(|p| p.dist)).collect();
            assert!(!fresh.is_empty(), "{name}: no points");
            refresh_distances(&mut state.manifolds, &pose);
            for (p, d) in state.manifolds.iter().flat_map(|m| m.points.iter()).zip(&fresh) {
                assert!((p.dist - d).abs() < 1e-14, "{name}: refreshed {} against {d}", p.dist);
            }
            // 1e-5 m and 3e-5 rad: far beyond the default reuse bounds, to see the second order.
            let motion = at(3e-6, -2e-6, 4e-6, Rotation::from_scaled_axis(Vector::new(2e-5, 1e-5, -3e-5)));
            let moved = pose * motion;
            refresh_distances(&mut state.manifolds, &moved);
            let mut again = PairState::default();
            dispatch(kind_a, a, kind_b, b, &moved, 0.02, &mut again).unwrap();
            let (refreshed, recomputed) = (closest(&state), closest(&again));
            assert!(
                (refreshed - recomputed).abs() < 1e-9,
                "{name}: refreshed {refreshed} against {recomputed}"
            );
            assert!(
                (refreshed - closest_of(&fresh)).abs() > 1e-7,
                "{name}: the motion must change the distance"
            );
            for m in &state.manifolds {
                let sub1 = m.subshape_pos1().copied().unwrap_or(Pose::IDENTITY);
                let sub2 = moved * m.subshape_pos2().copied().unwrap_or(Pose::IDENTITY);
                let n1 = sub1.rotation * m.local_n1;
                for p in &m.points {
                    let apart = sub2 * p.local_p2 - sub1 * p.local_p1;
                    assert!((apart - n1 * p.dist).length() < 1e-15, "{name}: points apart by {apart:?}");
                }
            }
        }
    }

    fn closest_of(distances: &[f64]) -> f64 {
        distances.iter().copied().fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn pose_within_bounds_translation_and_rotation() {
        let pose = Pose::from_parts(
            Vector::new(0.3, -0.1, 0.2),
            Rotation::from_scaled_axis(Vector::new(0.4, 0.1, -0.2)),
        );
        let shifted = |dx: f64, angle: f64| {
            pose * Pose::from_parts(
                Vector::new(dx, 0.0, 0.0),
                Rotation::from_scaled_axis(Vector::new(0.0, 0.0, angle)),
            )
        };
        assert!(pose_within(&pose, &pose, 1e-8, 1e-7));
        assert!(pose_within(&pose, &shifted(0.9e-8, 0.0), 1e-8, 1e-7));
        assert!(!pose_within(&pose, &shifted(1.1e-8, 0.0), 1e-8, 1e-7));
        assert!(pose_within(&pose, &shifted(0.0, 0.9e-4), 1e-8, 1e-4));
        assert!(!pose_within(&pose, &shifted(0.0, 1.1e-4), 1e-8, 1e-4));
        // Resolved at the default bound too, where the cosine of half the angle is 1 − 1.25e-15.
        assert!(pose_within(&pose, &shifted(0.0, 0.9e-7), 1e-8, 1e-7));
        assert!(!pose_within(&pose, &shifted(0.0, 1.1e-7), 1e-8, 1e-7));
        // q and −q are the same rotation.
        let flipped = Pose::from_parts(pose.translation, -pose.rotation);
        assert!(pose_within(&pose, &flipped, 1e-8, 1e-7));
    }
}
