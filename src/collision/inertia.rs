//! Volume, centroid and rotational inertia of collision shapes as uniform solids: what a link's
//! inertia is when it is computed from its collision geometry (PyBullet's default for URDF,
//! `gelenk::io::urdf::UrdfOptions::inertia_from_collision`).
//!
//! Each shape is the solid the collision detection sees on a moving body: a primitive as it is, a
//! mesh as the convex hull of its vertices. Parry integrates each one; the parts are combined with
//! the parallel-axis theorem (overlapping shapes count twice, as in a compound of their volumes).

use super::convert::from_vector;
use super::mesh::MeshOptions;
use super::shape::{self, ShapeSource};
use crate::error::CollisionError;
use crate::math::{Mat3, Transform, Vec3};
use crate::model::Shape;
use std::path::Path;

/// A solid of unit density (1 kg/m³): its volume, centroid and rotational inertia about the
/// centroid, in the frame its shapes are placed in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolidVolume {
    /// Volume (m³); numerically the mass at unit density.
    pub volume: f64,
    /// Centroid (m).
    pub centroid: Vec3,
    /// Rotational inertia about the centroid at unit density (kg·m² per kg/m³, i.e. m⁵).
    pub inertia: Mat3,
}

impl SolidVolume {
    /// The solid of `shape` placed at `placement`. A mesh is resolved and read as the collision
    /// world does (`meshes`' search paths, the model's directory) and taken as its convex hull.
    /// Half-spaces and heightfields have no finite volume: an error, as on a moving body.
    pub fn of_shape(
        shape: &Shape,
        placement: &Transform,
        link: &str,
        model_dir: Option<&Path>,
        meshes: &MeshOptions,
    ) -> Result<SolidVolume, CollisionError> {
        let hulls = MeshOptions { exact_meshes_on_bodies: false, ..meshes.clone() };
        let src = ShapeSource { link, model_dir, on_body: true };
        let built = shape::build(shape, &src, &hulls)?;
        if matches!(built.kind, shape::ShapeKind::HeightField | shape::ShapeKind::HalfSpace) {
            return Err(CollisionError::InvalidShape {
                link: link.to_string(),
                what: format!("a {} has no finite volume", built.kind.name()),
            });
        }
        let props = built.shape.mass_properties(1.0);
        let pose = built.offset.map_or(*placement, |offset| placement * &offset);
        let local = props.reconstruct_inertia_matrix();
        let local = Mat3::from_fn(|r, c| local.col(c)[r]);
        Ok(SolidVolume {
            volume: props.mass(),
            centroid: pose.act_point(&from_vector(props.local_com)),
            inertia: pose.rotation * local * pose.rotation.transpose(),
        })
    }

    /// The union of `parts` as one solid (volumes add; inertias move to the common centroid by
    /// the parallel-axis theorem); `None` when their volume is not positive.
    pub fn combine(parts: &[SolidVolume]) -> Option<SolidVolume> {
        let volume: f64 = parts.iter().map(|p| p.volume).sum();
        if !(volume > 0.0 && volume.is_finite()) {
            return None;
        }
        let centroid = parts.iter().map(|p| p.centroid * p.volume).sum::<Vec3>() / volume;
        let inertia = parts
            .iter()
            .map(|p| {
                let d = p.centroid - centroid;
                p.inertia + (Mat3::identity() * d.norm_squared() - d * d.transpose()) * p.volume
            })
            .sum();
        Some(SolidVolume { volume, centroid, inertia })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::axis_angle;
    use crate::model::RigidInertia;

    fn solid(shape: Shape, placement: Transform) -> SolidVolume {
        SolidVolume::of_shape(&shape, &placement, "l", None, &MeshOptions::default()).unwrap()
    }

    #[test]
    fn primitives_match_their_closed_forms() {
        let size = Vec3::new(0.2, 0.4, 0.6);
        let turn = axis_angle(&Vec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
        let b = solid(Shape::Box { size }, Transform::new(turn, Vec3::new(1.0, 0.0, 0.0)));
        let v = size.x * size.y * size.z;
        assert!((b.volume - v).abs() < 1e-15);
        assert!((b.centroid - Vec3::new(1.0, 0.0, 0.0)).norm() < 1e-15);
        let expected = turn * RigidInertia::solid_box(v, size).inertia_com * turn.transpose();
        assert!((b.inertia - expected).amax() < 1e-15, "{} vs {expected}", b.inertia);
        // A cylinder is z-up in gelenk and y-up in parry: its axial moment must be about z.
        let c = solid(Shape::Cylinder { radius: 0.1, length: 1.0 }, Transform::identity());
        let expected = RigidInertia::solid_cylinder(c.volume, 0.1, 1.0).inertia_com;
        assert!((c.inertia - expected).amax() < 1e-12 * expected.amax(), "{}", c.inertia);
    }

    #[test]
    fn two_boxes_combine_as_one() {
        let size = Vec3::new(0.5, 0.2, 0.2);
        let left = solid(Shape::Box { size }, Transform::from_translation(Vec3::new(-0.25, 0.0, 0.0)));
        let right = solid(Shape::Box { size }, Transform::from_translation(Vec3::new(0.25, 0.0, 0.0)));
        let both = SolidVolume::combine(&[left, right]).unwrap();
        let whole = solid(Shape::Box { size: Vec3::new(1.0, 0.2, 0.2) }, Transform::identity());
        assert!((both.volume - whole.volume).abs() < 1e-15);
        assert!(both.centroid.norm() < 1e-15);
        assert!((both.inertia - whole.inertia).amax() < 1e-15);
        assert_eq!(SolidVolume::combine(&[]), None);
    }
}
