//! Collision shapes as triangle meshes for drawing: parry's tessellations of the primitives and
//! hulls, the triangles of meshes and height fields, and a half-space as a large square.
//! Triangles are counter-clockwise seen from outside (glTF's front faces).

use crate::math::{Transform, Vec3};
use parry3d_f64::math::Vector;
use parry3d_f64::shape::SharedShape;

/// Segments around a sphere, capsule or cylinder.
const AROUND: u32 = 24;
/// Rings from pole to pole of a sphere or capsule.
const RINGS: u32 = 12;

/// A triangle mesh in some frame (m).
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct TriangleMesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals of a smooth surface (sphere, capsule, height field); `None` for a
    /// faceted one, which glTF viewers shade flat.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Triangles, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

fn vec3(v: Vector) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

fn f32x3(v: &Vec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// How a vertex normal follows from a vertex in parry's shape frame.
enum Normals {
    Flat,
    /// Away from this segment (a sphere's centre is a segment of length 0).
    AwayFrom(Vec3, Vec3),
    /// The mean of the normals of the triangles that share the vertex.
    Averaged,
}

/// The mesh of a collider's shape, with `pose` (parry's shape frame in the mesh's frame) applied;
/// `None` for a half-space (see [`plane_square`]) and shapes that have no surface to draw.
pub(crate) fn shape_mesh(shape: &SharedShape, pose: &Transform) -> Option<TriangleMesh> {
    let (vertices, triangles, normals) = if let Some(ball) = shape.as_ball() {
        let (v, t) = ball.to_trimesh(AROUND, RINGS);
        (v, t, Normals::AwayFrom(Vec3::zeros(), Vec3::zeros()))
    } else if let Some(cuboid) = shape.as_cuboid() {
        let (v, t) = cuboid.to_trimesh();
        (v, t, Normals::Flat)
    } else if let Some(capsule) = shape.as_capsule() {
        let (v, t) = capsule.to_trimesh(AROUND, RINGS);
        (v, t, Normals::AwayFrom(vec3(capsule.segment.a), vec3(capsule.segment.b)))
    } else if let Some(cylinder) = shape.as_cylinder() {
        let (v, t) = cylinder.to_trimesh(AROUND);
        (v, t, Normals::Flat)
    } else if let Some(hull) = shape.as_convex_polyhedron() {
        let (v, t) = hull.to_trimesh();
        (v, t, Normals::Flat)
    } else if let Some(mesh) = shape.as_trimesh() {
        (mesh.vertices().to_vec(), mesh.indices().to_vec(), Normals::Flat)
    } else if let Some(field) = shape.as_heightfield() {
        let (v, t) = field.to_trimesh();
        (v, t, Normals::Averaged)
    } else {
        return None;
    };
    if triangles.is_empty() {
        return None;
    }
    let local: Vec<Vec3> = vertices.into_iter().map(vec3).collect();
    let normals = match normals {
        Normals::Flat => None,
        Normals::AwayFrom(a, b) => Some(
            local
                .iter()
                .map(|p| {
                    let ab = b - a;
                    let s = if ab.norm_squared() > 0.0 {
                        ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    (p - (a + ab * s)).try_normalize(0.0).unwrap_or_else(Vec3::z)
                })
                .collect::<Vec<_>>(),
        ),
        Normals::Averaged => {
            let mut sum = vec![Vec3::zeros(); local.len()];
            for t in &triangles {
                let [a, b, c] = t.map(|i| local[i as usize]);
                let n = (b - a).cross(&(c - a));
                for &i in t {
                    sum[i as usize] += n;
                }
            }
            Some(sum.into_iter().map(|n| n.try_normalize(0.0).unwrap_or_else(Vec3::y)).collect())
        }
    };
    Some(TriangleMesh {
        positions: local.iter().map(|p| f32x3(&pose.act_point(p))).collect(),
        normals: normals.map(|n| n.iter().map(|n| f32x3(&(pose.rotation * n).normalize())).collect()),
        triangles,
    })
}

/// A square of side `2 · half_size` on the plane through `point` with unit normal `normal`,
/// centred on the plane's point nearest to `centre`, facing along the normal.
pub(crate) fn plane_square(point: &Vec3, normal: &Vec3, centre: &Vec3, half_size: f64) -> TriangleMesh {
    let middle = centre - normal * (centre - point).dot(normal);
    // Two unit vectors u, w across the plane with u × w = n.
    let helper = if normal.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() };
    let u = normal.cross(&helper).normalize();
    let w = normal.cross(&u);
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    TriangleMesh {
        positions: corners.iter().map(|(a, b)| f32x3(&(middle + (u * *a + w * *b) * half_size))).collect(),
        normals: Some(vec![f32x3(normal); 4]),
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// The half-space of a collider: a point of its boundary plane and its outward unit normal, in
/// the frame `pose` maps parry's shape frame into; `None` if the shape is not a half-space.
pub(crate) fn half_space(shape: &SharedShape, pose: &Transform) -> Option<(Vec3, Vec3)> {
    let half = shape.as_halfspace()?;
    Some((pose.translation, (pose.rotation * vec3(half.normal)).normalize()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::axis_angle;

    /// Six times the signed volume: positive when the triangles face outwards.
    fn signed_volume(mesh: &TriangleMesh) -> f64 {
        let p = |i: u32| {
            let v = mesh.positions[i as usize];
            Vec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
        };
        mesh.triangles.iter().map(|t| p(t[0]).dot(&p(t[1]).cross(&p(t[2])))).sum()
    }

    #[test]
    fn closed_shapes_face_outwards_and_have_their_volume() {
        let pose = Transform::new(axis_angle(&Vec3::new(1.0, 2.0, 3.0).normalize(), 0.7), Vec3::zeros());
        let pi = std::f64::consts::PI;
        let hull = SharedShape::convex_hull(&[
            Vector::new(0.0, 0.0, 0.0),
            Vector::new(1.0, 0.0, 0.0),
            Vector::new(0.0, 1.0, 0.0),
            Vector::new(0.0, 0.0, 1.0),
        ])
        .unwrap();
        let cases = [
            (SharedShape::ball(0.5), 4.0 / 3.0 * pi * 0.125, 0.05),
            (SharedShape::cuboid(0.5, 1.0, 1.5), 6.0, 1e-6),
            (SharedShape::capsule_z(0.5, 0.2), pi * 0.04 + 4.0 / 3.0 * pi * 0.008, 0.05),
            (SharedShape::cylinder(0.5, 0.3), pi * 0.09, 0.05),
            (hull, 1.0 / 6.0, 1e-6),
        ];
        for (shape, volume, tolerance) in cases {
            let mesh = shape_mesh(&shape, &pose).unwrap();
            let v = signed_volume(&mesh) / 6.0;
            assert!((v - volume).abs() < tolerance * volume, "{:?}: {v} vs {volume}", shape.shape_type());
        }
    }

    #[test]
    fn smooth_normals_point_outwards() {
        let pose = Transform::from_translation(Vec3::new(1.0, 2.0, 3.0));
        let mesh = shape_mesh(&SharedShape::capsule_z(0.5, 0.2), &pose).unwrap();
        let normals = mesh.normals.unwrap();
        for (p, n) in mesh.positions.iter().zip(&normals) {
            let radial = Vec3::new(p[0] as f64 - 1.0, p[1] as f64 - 2.0, 0.0);
            let n = Vec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
            assert!((n.norm() - 1.0).abs() < 1e-6);
            assert!(n.dot(&radial) >= -1e-6);
        }
    }

    #[test]
    fn height_field_faces_up() {
        // parry's height fields are y-up: the triangles face +y in its frame.
        let heights = parry3d_f64::utils::Array2::new(3, 4, vec![0.1; 12]);
        let field = SharedShape::heightfield(heights, Vector::new(2.0, 1.0, 3.0));
        let mesh = shape_mesh(&field, &Transform::identity()).unwrap();
        let p = |i: u32| {
            let v = mesh.positions[i as usize];
            Vec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
        };
        assert_eq!(mesh.triangles.len(), 2 * 2 * 3);
        for t in &mesh.triangles {
            let n = (p(t[1]) - p(t[0])).cross(&(p(t[2]) - p(t[0])));
            assert!(n.y > 0.0 && n.x.abs() + n.z.abs() < 1e-9 * n.y, "{n:?}");
        }
        assert!(mesh.normals.unwrap().iter().all(|n| (n[1] - 1.0).abs() < 1e-6));
    }

    #[test]
    fn plane_square_lies_on_the_plane_around_the_centre() {
        let normal = Vec3::new(-0.34, 0.0, 0.94).normalize();
        let point = Vec3::new(8.0, 0.0, 0.0);
        let square = plane_square(&point, &normal, &Vec3::new(0.0, 1.0, 0.0), 10.0);
        let corner = |i: usize| {
            let c = square.positions[i];
            Vec3::new(c[0] as f64, c[1] as f64, c[2] as f64)
        };
        let centre = (corner(0) + corner(2)) * 0.5;
        for i in 0..4 {
            assert!((corner(i) - point).dot(&normal).abs() < 1e-4);
        }
        assert!((centre.y - 1.0).abs() < 1e-5);
        let face = (corner(1) - corner(0)).cross(&(corner(2) - corner(0)));
        assert!(face.dot(&normal) > 0.0);
    }
}
