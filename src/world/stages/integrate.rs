//! Stage 8: the new state. The velocity after the impulses is integrated on the manifold (free
//! origins on straight lines, see [`crate::model::Joint::integrate_decoupled`]) and the loop
//! closures within a multibody are closed at the new configuration by correcting their
//! impulse, position and velocity together (SHAKE, [`LoopProjection`]). A multibody whose
//! only rows in the step are its own loop closures, of hinges and sliders, is stepped by
//! RATTLE instead ([`crate::world::rattle`]: second order and symplectic, the velocity at the
//! step's end); a smooth step integrates with its scheme ([`crate::world::smooth`]). The new
//! state is committed only once every multibody's is finite.

use super::check::{dynamics_error, finite};
use super::rows::has_row_sources;
use crate::collision::{Attachment, Contact};
use crate::constraints::LoopClosure;
use crate::integrators::IntegratorError;
use crate::world::loops::{own, Loops};
use crate::world::smooth::SmoothSteppers;
use crate::world::{LoopProjection, Multibody, StepError};
use nalgebra::DVector;

/// What else than loop closures gives the multibodies rows in a step, for the choice of
/// RATTLE: the contacts and the margin of joint limits' rows.
pub(crate) struct RowSources<'a> {
    /// The step's contacts.
    pub(crate) contacts: &'a [Contact],
    /// A joint within this distance of a limit has a row.
    pub(crate) limit_margin: f64,
}

impl RowSources<'_> {
    /// Whether multibody `i` (`b`) has no row in the step but its own loop closures' (among
    /// `closures`): no contact, no limit, motor, servo or joint friction, no closure to another
    /// multibody.
    fn only_own_loops(&self, i: usize, b: &Multibody, closures: &[(usize, usize, LoopClosure)]) -> bool {
        let touches =
            |side: &Attachment| matches!(side, Attachment::Body { multibody, .. } if *multibody == i);
        !has_row_sources(b, self.limit_margin)
            && !closures.iter().any(|(a, c, _)| a != c && (*a == i || *c == i))
            && !self.contacts.iter().any(|c| touches(&c.body_a) || touches(&c.body_b))
    }
}

/// Writes every multibody's next state (`q_next`, `v_next`): sleepers stay where they are;
/// `smooth`: the steppers of a smooth step; else from the stacked velocity after the impulses
/// `v`, by RATTLE for a multibody it applies to. Returns how many multibodies RATTLE stepped.
/// An error leaves the states as they were.
#[allow(clippy::too_many_arguments)]
pub(crate) fn run(
    bodies: &mut [Multibody],
    names: &[String],
    v: &DVector<f64>,
    loops: &mut Loops,
    mut smooth: Option<&mut SmoothSteppers>,
    projection: &LoopProjection,
    sources: &RowSources<'_>,
    h: f64,
) -> Result<usize, StepError> {
    let mut rattled = 0;
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
        // With this step's contact projection, if any (`Multibody::integrate_step`).
        b.integrate_step(h);
        if let Some(buffers) = loops.projections[i].as_mut() {
            if !b.kinematic && b.factored {
                let only_own_loops = sources.only_own_loops(i, b, &loops.closures);
                let closures = own(&loops.closures, i);
                let mut rattle = buffers.rattle.take();
                let stepped = match rattle.as_mut() {
                    Some(rattle) if projection.iterations > 0 && only_own_loops => rattle
                        .step(b, closures.clone(), buffers, projection, h)
                        .map_err(dynamics_error(&names[i])),
                    _ => Ok(false),
                };
                buffers.rattle = rattle;
                if stepped? {
                    rattled += 1;
                } else {
                    buffers.shake(b, closures, projection, h).map_err(dynamics_error(&names[i]))?;
                }
            }
        }
        if !b.kinematic {
            b.transport_free_velocities(h);
        }
        finite(&names[i], &b.model, &b.q_next, &b.v_next, true)?;
    }
    Ok(rattled)
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
