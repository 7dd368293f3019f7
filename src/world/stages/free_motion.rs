//! Stage 4: each awake multibody's free velocity, the velocity after one step without
//! constraint impulses ([`Multibody::free_motion`]: `M v_free = M v + h (τ − C)`, semi-implicit
//! in springs and damping), stacked over the world with the velocities at the step's start.

use super::check::dynamics_error;
use crate::world::dofs::StackedDofs;
use crate::world::{Multibody, StepError};

/// Computes the free velocity of every awake multibody (zero for sleepers, and for all in a
/// smooth step, which integrates instead) and stacks it in `dofs`. `has_rows`: the step has
/// constraint rows (else a multibody without implicit terms may use ABA instead of CRBA);
/// `mass_matrix_reuse`: [`crate::world::WorldOptions::mass_matrix_reuse`].
pub(crate) fn run(
    bodies: &mut [Multibody],
    names: &[String],
    dofs: &mut StackedDofs,
    h: f64,
    has_rows: bool,
    smooth: bool,
    mass_matrix_reuse: Option<f64>,
) -> Result<(), StepError> {
    for (i, b) in bodies.iter_mut().enumerate() {
        if b.asleep || smooth {
            b.v_free.fill(0.0);
            continue;
        }
        b.free_motion(h, has_rows, mass_matrix_reuse).map_err(dynamics_error(&names[i]))?;
    }
    dofs.stack(bodies);
    Ok(())
}
