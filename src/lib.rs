//! # gelenk — constraint-based Lagrangian multibody dynamics
//!
//! Articulated bodies in generalized coordinates (Featherstone): a kinematic tree of bodies joined
//! by fixed, hinge, slider, ball, universal, hinge2 (steer + spin, optional suspension), free and
//! planar joints, with RNEA, CRBA, ABA, kinematics and Jacobians, loaded from URDF or built in code.
//!
//! The design separates what never changes while simulating ([`Model`]), what the user owns
//! ([`State`]: q, v, t) and every buffer the algorithms write ([`Data`], allocated once by
//! [`Data::new`]). Algorithms are free functions over `(&Model, &mut Data, …)` in
//! [`algorithms`]; none allocates.
//!
//! Conventions are Pinocchio's (see [`math`]): SI units, z up, gravity (0, 0, −9.81) m/s²,
//! spatial vectors linear part first, quaternions (x, y, z, w), joints numbered depth-first.
//!
//! ```
//! use gelenk::prelude::*;
//! let model = gelenk::io::urdf::load_str(
//!     r#"<robot name="pendulum">
//!          <link name="base"/>
//!          <link name="arm"><inertial><mass value="1"/><origin xyz="0 0 -0.5"/>
//!            <inertia ixx="0.01" iyy="0.01" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>
//!          <joint name="shoulder" type="continuous"><parent link="base"/><child link="arm"/>
//!            <axis xyz="0 1 0"/></joint>
//!        </robot>"#,
//!     &UrdfOptions::default(),
//! ).unwrap();
//! let mut data = Data::new(&model);
//! let q = model.neutral_configuration();
//! let v = nalgebra::DVector::zeros(model.nv());
//! let tau = nalgebra::DVector::zeros(model.nv());
//! let a = aba(&model, &mut data, &q, &v, &tau).unwrap();
//! assert!(a[0].abs() < 1e-12); // hanging straight down: at rest
//! ```
//!
//! ## Cargo features
//!
//! All on by default; with `default-features = false` the library is the models, algorithms,
//! collision, constraints, solvers, [`world`], the built-in [`scenes`], [`run`] and the file
//! formats of [`io`], and each feature adds one optional part:
//!
//! | feature | adds |
//! |---|---|
//! | `plot` | `plot`: plotters with DejaVu Sans embedded |
//! | `render` | `render`: filmstrips of scenes as PNG images (needs `plot`) |
//! | `report` | `report`: the stability and speed-error reports (needs `plot`) |
//! | `cli` | the `gelenk` command-line tool (clap; needs `render` and `report`) |
#![warn(missing_docs)]

pub mod algorithms;
pub mod collision;
pub mod constraints;
pub mod data;
pub mod error;
pub mod integrators;
pub mod io;
pub mod math;
pub mod model;
#[cfg(feature = "plot")]
pub mod plot;
#[cfg(feature = "render")]
pub mod render;
#[cfg(feature = "report")]
pub mod report;
pub mod run;
pub mod scenes;
pub mod solvers;
pub mod state;
pub mod vehicle;
pub mod world;

/// The README's examples are compiled and run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

pub use data::Data;
pub use error::{CollisionError, DynamicsError, ModelError};
pub use model::{Model, ModelBuilder};
pub use state::State;

/// The items most programs need.
pub mod prelude {
    pub use crate::algorithms::*;
    pub use crate::data::Data;
    pub use crate::error::{DynamicsError, ModelError};
    pub use crate::io::urdf::UrdfOptions;
    pub use crate::math::{Force, Motion, SpatialInertia, Transform, Vec3};
    pub use crate::model::{BodySpec, Joint, Model, ModelBuilder, RigidInertia, Suspension};
    pub use crate::state::State;
}
