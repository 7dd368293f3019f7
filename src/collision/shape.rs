//! Our [`Shape`] descriptions turned into parry shapes, in one place. Parry's cylinders and
//! heightfields are y-up while gelenk's (and URDF's) are z-up: such shapes carry a fixed offset
//! rotation from the parry frame to the geometry frame.

use super::convert::to_vector;
use super::mesh::{self, MeshData, MeshOptions};
use crate::error::CollisionError;
use crate::math::{axis_angle, Transform, Vec3};
use crate::model::Shape;
use parry3d_f64::math::Vector;
use parry3d_f64::shape::{HeightFieldFlags, SharedShape, TriMeshFlags};
use parry3d_f64::utils::Array2;
use std::path::Path;

/// The kind of a collider's shape, as the narrow phase dispatches on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ShapeKind {
    /// Sphere.
    Sphere,
    /// Box.
    Box,
    /// Capsule.
    Capsule,
    /// Cylinder.
    Cylinder,
    /// Convex hull (also meshes on moving bodies, by default).
    ConvexHull,
    /// Triangle mesh.
    TriMesh,
    /// Heightfield terrain.
    HeightField,
    /// Half-space (ground plane).
    HalfSpace,
}

impl ShapeKind {
    /// Whether the shape is convex (a support-mapped solid).
    pub fn is_convex(self) -> bool {
        !matches!(self, ShapeKind::TriMesh | ShapeKind::HeightField | ShapeKind::HalfSpace)
    }
    /// Lower-case name, as `gelenk inspect` prints it.
    pub fn name(self) -> &'static str {
        match self {
            ShapeKind::Sphere => "sphere",
            ShapeKind::Box => "box",
            ShapeKind::Capsule => "capsule",
            ShapeKind::Cylinder => "cylinder",
            ShapeKind::ConvexHull => "convex_hull",
            ShapeKind::TriMesh => "trimesh",
            ShapeKind::HeightField => "heightfield",
            ShapeKind::HalfSpace => "halfspace",
        }
    }
}

/// A parry shape with its kind and the pose of parry's shape frame in the geometry frame.
#[derive(Clone)]
pub(crate) struct ParryShape {
    pub shape: SharedShape,
    pub kind: ShapeKind,
    pub offset: Option<Transform>,
}

/// Where a geometry comes from, for error messages and mesh resolution.
pub(crate) struct ShapeSource<'a> {
    pub link: &'a str,
    pub model_dir: Option<&'a Path>,
    pub on_body: bool,
}

fn y_up_to_z_up() -> Transform {
    Transform::new(axis_angle(&Vec3::x(), std::f64::consts::FRAC_PI_2), Vec3::zeros())
}

/// Builds the parry shape of `shape`. Meshes are read here; `Ok(None)` never happens for
/// primitives and means "mesh skipped" only when the caller handles missing meshes by skipping
/// (the error is returned and the caller decides).
pub(crate) fn build(
    shape: &Shape,
    src: &ShapeSource,
    meshes: &MeshOptions,
) -> Result<ParryShape, CollisionError> {
    let invalid = |what: String| CollisionError::InvalidShape { link: src.link.to_string(), what };
    let positive = |name: &str, x: f64| {
        if x.is_finite() && x > 0.0 {
            Ok(x)
        } else {
            Err(invalid(format!("{name} must be positive and finite, got {x}")))
        }
    };
    let plain = |shape: SharedShape, kind| Ok(ParryShape { shape, kind, offset: None });
    match shape {
        Shape::Sphere { radius } => plain(SharedShape::ball(positive("radius", *radius)?), ShapeKind::Sphere),
        Shape::Box { size } => {
            let h = [positive("size x", size.x)?, positive("size y", size.y)?, positive("size z", size.z)?];
            plain(SharedShape::cuboid(h[0] / 2.0, h[1] / 2.0, h[2] / 2.0), ShapeKind::Box)
        }
        Shape::Capsule { radius, length } => {
            let (r, half) = (positive("radius", *radius)?, positive("length", *length)? / 2.0);
            plain(SharedShape::capsule_z(half, r), ShapeKind::Capsule)
        }
        Shape::Cylinder { radius, length } => {
            let (r, half) = (positive("radius", *radius)?, positive("length", *length)? / 2.0);
            Ok(ParryShape {
                shape: SharedShape::cylinder(half, r),
                kind: ShapeKind::Cylinder,
                offset: Some(y_up_to_z_up()),
            })
        }
        Shape::ConvexHull { points } => convex_hull(points, src.link),
        Shape::TriMesh { vertices, triangles } => trimesh(vertices, triangles, src.link),
        Shape::HeightField { heights, size_x, size_y } => {
            let (sx, sy) = (positive("size_x", *size_x)?, positive("size_y", *size_y)?);
            let (nx, ny) = heights.shape();
            if nx < 2 || ny < 2 {
                return Err(invalid(format!("a heightfield needs at least 2×2 samples, got {nx}×{ny}")));
            }
            if heights.iter().any(|h| !h.is_finite()) {
                return Err(invalid("a heightfield sample is not finite".into()));
            }
            // Parry: row r along its z (= our −y), column c along its x (= our x), height along its y.
            let mut data = Vec::with_capacity(nx * ny);
            for c in 0..nx {
                for r in 0..ny {
                    data.push(heights[(c, ny - 1 - r)]);
                }
            }
            let field = Array2::new(ny, nx, data);
            Ok(ParryShape {
                shape: SharedShape::heightfield_with_flags(
                    field,
                    Vector::new(sx, 1.0, sy),
                    HeightFieldFlags::FIX_INTERNAL_EDGES,
                ),
                kind: ShapeKind::HeightField,
                offset: Some(y_up_to_z_up()),
            })
        }
        Shape::HalfSpace { normal } => {
            if src.on_body {
                return Err(invalid("a half-space can only be static geometry".into()));
            }
            let n = normal.try_normalize(1e-12).filter(|n| n.iter().all(|c| c.is_finite()));
            let n =
                n.ok_or_else(|| invalid(format!("half-space normal {normal:?} is zero or not finite")))?;
            plain(SharedShape::halfspace(to_vector(&n)), ShapeKind::HalfSpace)
        }
        Shape::Mesh { uri, scale } => {
            if !scale.iter().all(|s| s.is_finite() && *s != 0.0) {
                return Err(invalid(format!("mesh scale {scale:?} must be finite and non-zero")));
            }
            let path = mesh::resolve(src.link, uri, src.model_dir, &meshes.search_paths)?;
            let MeshData { vertices, triangles } = mesh::load(src.link, &path, scale)?;
            if src.on_body && !meshes.exact_meshes_on_bodies {
                convex_hull(&vertices, src.link)
            } else {
                trimesh(&vertices, &triangles, src.link)
            }
        }
    }
}

fn convex_hull(points: &[Vec3], link: &str) -> Result<ParryShape, CollisionError> {
    let invalid = |what: String| CollisionError::InvalidShape { link: link.to_string(), what };
    if points.len() < 4 {
        return Err(invalid(format!("a convex hull needs at least 4 points, got {}", points.len())));
    }
    if points.iter().any(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(invalid("a convex-hull point is not finite".into()));
    }
    if !spans_volume(points) {
        return Err(invalid("the convex-hull points are coplanar (the hull has no volume)".into()));
    }
    let pts: Vec<Vector> = points.iter().map(to_vector).collect();
    let shape =
        SharedShape::convex_hull(&pts).ok_or_else(|| invalid("the convex hull could not be built".into()))?;
    Ok(ParryShape { shape, kind: ShapeKind::ConvexHull, offset: None })
}

fn trimesh(vertices: &[Vec3], triangles: &[[u32; 3]], link: &str) -> Result<ParryShape, CollisionError> {
    let invalid = |what: String| CollisionError::InvalidShape { link: link.to_string(), what };
    if triangles.is_empty() {
        return Err(invalid("a triangle mesh needs at least one triangle".into()));
    }
    if vertices.iter().any(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(invalid("a mesh vertex is not finite".into()));
    }
    if let Some(t) = triangles.iter().find(|t| t.iter().any(|&i| i as usize >= vertices.len())) {
        return Err(invalid(format!("triangle {t:?} refers to a vertex beyond the {}", vertices.len())));
    }
    let shape = SharedShape::trimesh_with_flags(
        vertices.iter().map(to_vector).collect(),
        triangles.to_vec(),
        TriMeshFlags::FIX_INTERNAL_EDGES,
    )
    .map_err(|e| invalid(format!("triangle mesh rejected: {e}")))?;
    Ok(ParryShape { shape, kind: ShapeKind::TriMesh, offset: None })
}

/// Whether the points span a volume: some point lies off the plane of the widest triangle by more
/// than 1e-9 of the cloud's extent.
fn spans_volume(points: &[Vec3]) -> bool {
    let a = points[0];
    let b =
        *points.iter().max_by(|p, q| (*p - a).norm_squared().total_cmp(&(*q - a).norm_squared())).unwrap();
    let extent = (b - a).norm();
    if extent == 0.0 {
        return false;
    }
    let ab = b - a;
    let c = *points
        .iter()
        .max_by(|p, q| ab.cross(&(*p - a)).norm().total_cmp(&ab.cross(&(*q - a)).norm()))
        .unwrap();
    let n = ab.cross(&(c - a));
    let n_norm = n.norm();
    if n_norm <= 1e-18 * extent * extent {
        return false;
    }
    let n = n / n_norm;
    points.iter().any(|p| n.dot(&(p - a)).abs() > 1e-9 * extent)
}
