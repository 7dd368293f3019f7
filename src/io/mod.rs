//! Reading and writing models: URDF (with gelenk's extension for universal and hinge2 joints).

pub mod mjcf;
pub mod problem;
pub mod scene;
pub mod urdf;
