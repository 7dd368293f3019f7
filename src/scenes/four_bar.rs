//! The four-bar linkage: crank a = 0.15 m hinged at the origin, coupler b = 0.35 m, rocker
//! c = 0.30 m, a chain of three y-hinges of 1 kg rods ([`super::rod`]), whose rocker tip is
//! closed by a hinge loop joint to the world point (d, 0, 0), d = 0.40 m. It starts at rest in
//! the closed configuration with crank angle 1 rad and swings under gravity; the hinge closure
//! gives five rows of which three are redundant (the mechanism is planar).

use super::rod;
use crate::collision::MeshOptions;
use crate::constraints::{LoopClosure, LoopKind};
use crate::error::ModelError;
use crate::math::{Transform, Vec3};
use crate::model::{Model, ModelBuilder};
use crate::world::{StepError, World, WorldOptions};

/// Crank, coupler, rocker and ground lengths (m).
pub const FOUR_BAR_LENGTHS: (f64, f64, f64, f64) = (0.15, 0.35, 0.30, 0.40);

/// The crank angle (rad) of the initial configuration.
pub const FOUR_BAR_CRANK_ANGLE: f64 = 1.0;

/// The open chain of the linkage: crank, coupler and rocker (bodies 1, 2, 3).
pub fn four_bar_model() -> Result<Model, ModelError> {
    let (a, b, c, _) = FOUR_BAR_LENGTHS;
    let at = |x: f64| Transform::from_translation(Vec3::new(x, 0.0, 0.0));
    let mut builder = ModelBuilder::new();
    builder.add_body(rod("crank", "universe", at(0.0), a));
    builder.add_body(rod("coupler", "crank", at(a), b));
    builder.add_body(rod("rocker", "coupler", at(b), c));
    builder.build()
}

/// The hinge loop joint that closes the chain: the rocker's tip to the world point (d, 0, 0).
pub fn four_bar_closure() -> LoopClosure {
    let (_, _, c, d) = FOUR_BAR_LENGTHS;
    LoopClosure {
        body_a: 3,
        frame_a: Transform::from_translation(Vec3::new(c, 0.0, 0.0)),
        body_b: 0,
        frame_b: Transform::from_translation(Vec3::new(d, 0.0, 0.0)),
        kind: LoopKind::Hinge { axis: Vec3::y() },
        erp: 0.2,
    }
}

/// The joint angles (rad) of the closed configuration with crank angle `phi1`: the coupler's
/// tip where the circles about the crank's tip (radius b) and the ground point (radius c) meet,
/// computed in 2-D coordinates (x, −z), where a body turned by φ points along (cos φ, sin φ).
pub fn four_bar_closed_angles(phi1: f64) -> [f64; 3] {
    let (a, b, c, d) = FOUR_BAR_LENGTHS;
    let p = nalgebra::Vector2::new(a * phi1.cos(), a * phi1.sin());
    let o2 = nalgebra::Vector2::new(d, 0.0);
    let dist = (o2 - p).norm();
    let u = (o2 - p) / dist;
    let l = (b * b - c * c + dist * dist) / (2.0 * dist);
    let tip = p + u * l - nalgebra::Vector2::new(-u.y, u.x) * (b * b - l * l).sqrt();
    let phi2 = (tip.y - p.y).atan2(tip.x - p.x);
    let phi3 = (o2.y - tip.y).atan2(o2.x - tip.x);
    [phi1, phi2 - phi1, phi3 - phi2]
}

/// A world with `options` holding the linkage (multibody `four-bar`, its loop closure added)
/// at its initial configuration; returns it with the multibody's index.
pub fn four_bar_world(options: WorldOptions) -> Result<(World, usize), StepError> {
    let model = four_bar_model().expect("the four-bar is a valid model");
    let mut w = World::new(options);
    let m = w.add_multibody("four-bar", model, &MeshOptions::default())?;
    w.add_loop(m, four_bar_closure())?;
    w.multibody_mut(m).state.q.copy_from_slice(&four_bar_closed_angles(FOUR_BAR_CRANK_ANGLE));
    Ok((w, m))
}
