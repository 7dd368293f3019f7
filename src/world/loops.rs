//! A world's loop closures: between bodies of one multibody or of two, and per multibody the
//! buffers that project its own closures back onto their manifold after a step.

use super::projection::ProjectionBuffers;
use crate::constraints::LoopClosure;

/// The loop closures of a world.
#[derive(Default)]
pub(super) struct Loops {
    /// (multibody of body A, multibody of body B, the closure).
    pub(super) closures: Vec<(usize, usize, LoopClosure)>,
    /// Per multibody, the buffers of the position projection of its own loop closures (None
    /// without loops within it).
    pub(super) projections: Vec<Option<ProjectionBuffers>>,
}

/// The closures of `closures` between bodies of multibody `m` alone.
pub(super) fn own(
    closures: &[(usize, usize, LoopClosure)],
    m: usize,
) -> impl Iterator<Item = &LoopClosure> + Clone {
    closures.iter().filter(move |(a, b, _)| *a == m && *b == m).map(|(_, _, c)| c)
}
