//! Stage 3: the contacts of the step (broad phase, narrow phase and reduced manifolds in
//! [`CollisionWorld::detect`]), with the colliders that move further than the contact margin
//! in the step swept along their motion (continuous collision, docs/collision.md) and every
//! awake collider's motion given to the manifold reduction (which points the step closes); a sleeping
//! multibody touched by an awake one wakes, and its kinematics are brought up to date for the
//! rows.

use super::check::dynamics_error;
use crate::collision::{Attachment, CollisionWorld, Contact, SweepDiagnostic};
use crate::world::{sleep, Multibody, StepError};

/// Which colliders are swept: `continuous` (automatic sweeping of fast colliders) and the
/// bodies a sweep was asked for whatever their speed (multibody, body).
pub(crate) struct Sweeps<'a> {
    /// [`crate::world::WorldOptions::continuous_collision`].
    pub(crate) continuous: bool,
    /// [`crate::world::World::set_always_swept`]'s bodies.
    pub(crate) always: &'a [(usize, usize)],
}

/// Fills `contacts` with the step's contacts of a step of `h` (s) and wakes the sleepers they
/// touch.
pub(crate) fn run(
    bodies: &mut [Multibody],
    names: &[String],
    collision: &mut CollisionWorld,
    contacts: &mut Vec<Contact>,
    h: f64,
    sweeps: Sweeps<'_>,
) -> Result<(), StepError> {
    for (i, b) in bodies.iter_mut().enumerate() {
        let forced = |body: usize| sweeps.always.contains(&(i, body));
        if b.asleep {
            collision.set_multibody_motions(i, &[], h, false, |_| false);
            continue;
        }
        b.update_start_world_velocities();
        collision.set_multibody_motions(i, &b.world_velocities.start, h, sweeps.continuous, forced);
    }
    contacts.clear();
    contacts.extend_from_slice(collision.detect());
    for &(multibody, body) in sweeps.always {
        if !collision.body_has_collider(multibody, body) {
            collision.push_sweep_diagnostic(SweepDiagnostic::NoShape { multibody, body });
        }
    }
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
