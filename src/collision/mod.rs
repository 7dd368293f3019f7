//! Collision detection over parry3d-f64: shapes on bodies and in the static world, a sweep-and-
//! prune broad phase, parry's contact manifolds as the narrow phase, reduced contact sets of at
//! most four points per pair, and contact Jacobians.
//!
//! Conventions, said once: a [`Contact`]'s normal is a unit vector in world axes pointing **from
//! B to A**; its distance is signed (negative = penetration); contacts are reported up to the
//! margin of [`CollisionOptions`]. When one side is static geometry, it is B, so ground normals
//! point up into the body. Parry's types never leave this module (conversions live in `convert`).
//!
//! ```
//! use gelenk::collision::{CollisionOptions, CollisionWorld, MeshOptions};
//! use gelenk::math::{Transform, Vec3};
//! use gelenk::model::{BodySpec, Joint, ModelBuilder, RigidInertia, Shape};
//!
//! let body = BodySpec::new("ball", "universe", Joint::Free, Transform::identity(),
//!     RigidInertia::solid_sphere(1.0, 0.1))
//!     .with_collision(Shape::Sphere { radius: 0.1 }, Transform::identity());
//! let model = ModelBuilder::new().add_body(body).build().unwrap();
//! let mut data = gelenk::Data::new(&model);
//!
//! let mut world = CollisionWorld::new(CollisionOptions::default());
//! let ball = world.add_model(&model, &MeshOptions::default()).unwrap();
//! world.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(),
//!     &MeshOptions::default()).unwrap();
//!
//! let mut q = model.neutral_configuration();
//! q[2] = 0.099; // 1 mm into the ground
//! gelenk::algorithms::forward_kinematics(&model, &mut data, &q).unwrap();
//! world.update_multibody(ball, &data).unwrap();
//! let contacts = world.detect();
//! assert_eq!(contacts.len(), 1);
//! assert!((contacts[0].distance + 0.001).abs() < 1e-12);
//! assert!((contacts[0].normal - Vec3::z()).norm() < 1e-12);
//! ```

mod broad_phase;
mod convert;
mod inertia;
pub mod jacobian;
pub mod mesh;
mod narrow_phase;
pub mod reduce;
mod shape;
mod world;

pub use inertia::SolidVolume;
pub use jacobian::{
    add_angular_direction_row, add_point_direction_row, add_point_jacobian, add_point_rates_row,
    contact_frame, contact_jacobian, point_rates, tangents, JacobianRow,
};
pub use mesh::{MeshData, MeshOptions, MissingMeshPolicy};
pub use reduce::MAX_POINTS_PER_PAIR;
pub use shape::ShapeKind;
pub use world::{
    Attachment, Collider, CollisionFilter, CollisionOptions, CollisionStats, CollisionWorld, Contact,
    ManifoldReuse, SweepDiagnostic, SweepStats, SweptMotion,
};
