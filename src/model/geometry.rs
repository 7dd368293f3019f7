//! Geometry descriptions attached to bodies (URDF `<collision>` and `<visual>`), kept for the
//! collision module; dynamics never reads them and never opens a mesh file.

use crate::math::{Transform, Vec3};
use nalgebra::DMatrix;

/// What a geometry is used for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GeometryRole {
    /// Collision geometry.
    Collision,
    /// Visual geometry.
    Visual,
}

/// A shape in its own frame, sizes in metres.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// A box of full side lengths `size`, centred.
    Box {
        /// Full side lengths (m).
        size: Vec3,
    },
    /// A cylinder along z, centred.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Length (m).
        length: f64,
    },
    /// A capsule along z, centred: a cylinder of `length` with hemispherical caps.
    Capsule {
        /// Radius (m).
        radius: f64,
        /// Length of the cylindrical part (m).
        length: f64,
    },
    /// A sphere, centred.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// The convex hull of a point cloud given in the shape frame (m).
    ConvexHull {
        /// Points whose hull is the shape (at least 4, not coplanar).
        points: Vec<Vec3>,
    },
    /// A triangle mesh in the shape frame: exact, hollow surface (m; counter-clockwise triangles
    /// seen from outside).
    TriMesh {
        /// Vertex positions (m).
        vertices: Vec<Vec3>,
        /// Vertex indices of each triangle.
        triangles: Vec<[u32; 3]>,
    },
    /// A terrain: `heights[(i, j)]` is the surface height (m, along z) at grid point
    /// `x = -size_x/2 + i·size_x/(rows-1)`, `y = -size_y/2 + j·size_y/(cols-1)`; the grid is centred on the
    /// shape frame's origin. At least 2×2 samples.
    HeightField {
        /// Heights (m), rows along x, columns along y.
        heights: DMatrix<f64>,
        /// Extent of the grid along x (m).
        size_x: f64,
        /// Extent of the grid along y (m).
        size_y: f64,
    },
    /// The half-space `n·p ≤ 0` of the shape frame (a ground plane through its origin); static only.
    HalfSpace {
        /// Outward normal (unit after normalisation; need not be given normalised).
        normal: Vec3,
    },
    /// A mesh file, by the URI written in the model (`package://`, relative or absolute path),
    /// not yet resolved or read.
    Mesh {
        /// URI as written.
        uri: String,
        /// Scale per axis.
        scale: Vec3,
    },
}

impl Shape {
    /// Lower-case kind name (`box`, `cylinder`, `capsule`, `sphere`, `convex_hull`, `trimesh`,
    /// `heightfield`, `halfspace`, `mesh`).
    pub fn kind_name(&self) -> &'static str {
        match self {
            Shape::Box { .. } => "box",
            Shape::Cylinder { .. } => "cylinder",
            Shape::Capsule { .. } => "capsule",
            Shape::Sphere { .. } => "sphere",
            Shape::ConvexHull { .. } => "convex_hull",
            Shape::TriMesh { .. } => "trimesh",
            Shape::HeightField { .. } => "heightfield",
            Shape::HalfSpace { .. } => "halfspace",
            Shape::Mesh { .. } => "mesh",
        }
    }

    /// The shape's parameters in one line, for people (sizes in m).
    pub fn summary(&self) -> String {
        match self {
            Shape::Box { size } => format!("size {:.4} × {:.4} × {:.4}", size.x, size.y, size.z),
            Shape::Cylinder { radius, length } | Shape::Capsule { radius, length } => {
                format!("radius {radius:.4}, length {length:.4}")
            }
            Shape::Sphere { radius } => format!("radius {radius:.4}"),
            Shape::ConvexHull { points } => format!("{} points", points.len()),
            Shape::TriMesh { vertices, triangles } => {
                format!("{} vertices, {} triangles", vertices.len(), triangles.len())
            }
            Shape::HeightField { heights, size_x, size_y } => {
                format!("{}×{} samples over {size_x:.3} × {size_y:.3}", heights.nrows(), heights.ncols())
            }
            Shape::HalfSpace { normal } => {
                format!("normal ({:.3}, {:.3}, {:.3})", normal.x, normal.y, normal.z)
            }
            Shape::Mesh { uri, scale } => {
                format!("{uri} (scale {:.4}, {:.4}, {:.4})", scale.x, scale.y, scale.z)
            }
        }
    }
}

/// A shape attached to a model body.
#[derive(Clone, Debug, PartialEq)]
pub struct GeometrySpec {
    /// Name of the link that declared it.
    pub link: String,
    /// Collision or visual.
    pub role: GeometryRole,
    /// The shape.
    pub shape: Shape,
    /// Pose of the shape in the declaring link's frame (in a [`super::BodySpec`]) or in the model
    /// body's frame (in a built [`super::Model`], after fusion).
    pub placement: Transform,
    /// Body the shape moves with (set by the builder; 0 = universe).
    pub body: usize,
}
