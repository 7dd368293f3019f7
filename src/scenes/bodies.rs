//! Bodies the built-in scenes are made of.

use crate::math::{Mat3, Transform, Vec3};
use crate::model::{BodySpec, Joint, Model, ModelBuilder, RigidInertia, Shape};

/// A model of one free body named `name` with collision shape `shape` at its origin.
pub fn free_body(name: &str, shape: Shape, inertia: RigidInertia) -> Model {
    let mut b = ModelBuilder::new();
    b.add_body(
        BodySpec::new(name, "universe", Joint::Free, Transform::identity(), inertia)
            .with_collision(shape, Transform::identity()),
    );
    b.build().expect("a lone free body is a valid model")
}

/// A rod of `length` m and 1 kg along the body's x axis (its centre of mass at the middle,
/// `length²/12` kg·m² about y and z, 1e-4 kg·m² about x), hinged about y at the body origin,
/// placed at `placement` in its parent `parent`.
pub fn rod(name: &str, parent: &str, placement: Transform, length: f64) -> BodySpec {
    let i = length * length / 12.0;
    let inertia = RigidInertia::new(
        1.0,
        Vec3::new(length / 2.0, 0.0, 0.0),
        Mat3::from_diagonal(&Vec3::new(1e-4, i, i)),
    );
    BodySpec::new(name, parent, Joint::hinge(Vec3::y()), placement, inertia)
}
