//! Stage 2: forward kinematics and joint Jacobians of every awake multibody
//! ([`Multibody::kinematics`]); its colliders move to the new poses.

use super::check::dynamics_error;
use crate::collision::CollisionWorld;
use crate::world::{Multibody, StepError};

/// Updates the kinematics of every awake multibody and moves its colliders.
pub(crate) fn run(
    bodies: &mut [Multibody],
    names: &[String],
    collision: &mut CollisionWorld,
) -> Result<(), StepError> {
    for (i, b) in bodies.iter_mut().enumerate() {
        if !b.asleep {
            b.kinematics().map_err(dynamics_error(&names[i]))?;
            collision.update_multibody(i, &b.data)?;
        }
    }
    Ok(())
}
