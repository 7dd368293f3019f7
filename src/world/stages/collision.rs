//! Stage 3: the contacts of the step (broad phase, narrow phase and reduced manifolds in
//! [`CollisionWorld::detect`]); a sleeping multibody touched by an awake one wakes, and its
//! kinematics are brought up to date for the rows.

use super::check::dynamics_error;
use crate::collision::{Attachment, CollisionWorld, Contact};
use crate::world::{sleep, Multibody, StepError};

/// Fills `contacts` with the step's contacts and wakes the sleepers they touch.
pub(crate) fn run(
    bodies: &mut [Multibody],
    names: &[String],
    collision: &mut CollisionWorld,
    contacts: &mut Vec<Contact>,
) -> Result<(), StepError> {
    contacts.clear();
    contacts.extend_from_slice(collision.detect());
    for c in contacts.iter() {
        if let (Attachment::Body { multibody: a, .. }, Attachment::Body { multibody: b, .. }) =
            (c.body_a, c.body_b)
        {
            for (sleeper, other) in [(a, b), (b, a)] {
                if bodies[sleeper].asleep && !bodies[other].asleep {
                    sleep::wake(bodies, collision, sleeper);
                    bodies[sleeper].kinematics().map_err(dynamics_error(&names[sleeper]))?;
                }
            }
        }
    }
    Ok(())
}
