//! The built-in scenes, one definition each, shared by the tests, the reports
//! ([`crate::report`]), the benches and `gelenk export-problems`.
//!
//! - [`four_bar_world`]: the four-bar linkage on a [`crate::world::World`] (the stability
//!   report, the speed-error report, the world's tests);
//! - [`scene_world`]: the scenes whose constraint problems `gelenk export-problems` writes
//!   ([`SCENE_NAMES`], `export.rs`);
//! - [`free_body`] and [`rod`]: the bodies scenes are made of.

mod bodies;
mod export;
mod four_bar;

pub use bodies::{free_body, rod};
pub use export::{scene_world, SceneError, SCENE_NAMES};
pub use four_bar::{
    four_bar_closed_angles, four_bar_closure, four_bar_model, four_bar_world, FOUR_BAR_CRANK_ANGLE,
    FOUR_BAR_LENGTHS,
};
