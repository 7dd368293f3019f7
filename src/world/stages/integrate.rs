//! Stage 8: the new state. The velocity after the impulses is integrated on the manifold (free
//! origins on straight lines, see [`crate::model::Joint::integrate_decoupled`]) and the loop
//! closures within a multibody are closed at the new configuration by correcting their
//! impulse, position and velocity together (SHAKE, [`LoopProjection`]); a
//! smooth step integrates with its scheme instead ([`crate::world::smooth`]). The new state is
//! committed only once every multibody's is finite.

use super::check::{dynamics_error, finite};
use crate::integrators::IntegratorError;
use crate::world::loops::{own, Loops};
use crate::world::smooth::SmoothSteppers;
use crate::world::{LoopProjection, Multibody, StepError};
use nalgebra::DVector;

/// Writes every multibody's next state (`q_next`, `v_next`): sleepers stay where they are;
/// `smooth`: the steppers of a smooth step; else from the stacked velocity after the impulses
/// `v`. An error leaves the states as they were.
pub(crate) fn run(
    bodies: &mut [Multibody],
    names: &[String],
    v: &DVector<f64>,
    loops: &mut Loops,
    mut smooth: Option<&mut SmoothSteppers>,
    projection: &LoopProjection,
    h: f64,
) -> Result<(), StepError> {
    for (i, b) in bodies.iter_mut().enumerate() {
        let nv = b.model.nv();
        if b.asleep {
            b.v_next.fill(0.0);
            b.q_next.copy_from(&b.state.q);
            continue;
        }
        if let Some(steppers) = smooth.as_deref_mut() {
            let name = &names[i];
            steppers
                .advance(i, b, own(&loops.closures, i), loops.projections[i].as_mut(), projection, h)
                .map_err(|source| match source {
                    IntegratorError::Dynamics(source) => {
                        StepError::Dynamics { multibody: name.clone(), source }
                    }
                    source => StepError::Integrator { multibody: name.clone(), source },
                })?;
            finite(name, &b.model, &b.q_next, &b.v_next, true)?;
            continue;
        }
        b.v_next.copy_from(&v.rows(b.col, nv));
        // Straight-line origins (R³ × SO(3)), not the SE(3) screw: see
        // `Joint::integrate_decoupled` (a rolling ball would otherwise sink into its plane).
        b.model.integrate_decoupled(&b.state.q, &b.v_next, h, &mut b.q_next);
        if let Some(buffers) = loops.projections[i].as_mut() {
            if !b.kinematic && b.factored {
                buffers
                    .shake(b, own(&loops.closures, i), projection, h)
                    .map_err(dynamics_error(&names[i]))?;
            }
        }
        if !b.kinematic {
            b.transport_free_velocities(h);
        }
        finite(&names[i], &b.model, &b.q_next, &b.v_next, true)?;
    }
    Ok(())
}

/// Makes every multibody's next state its state, `h` seconds later; this step's applied forces
/// are spent.
pub(crate) fn commit(bodies: &mut [Multibody], h: f64) {
    for b in bodies {
        std::mem::swap(&mut b.state.q, &mut b.q_next);
        std::mem::swap(&mut b.state.v, &mut b.v_next);
        b.state.t += h;
        b.pending_forces.clear();
    }
}
