//! The stages of [`super::World::step`], in order, one file each: each is a function of the parts
//! of the world it reads and writes (the multibodies, the collision world, the stacked
//! velocities, the rows, the problem), so that a stage can be run on any set of multibodies.
//!
//! 1. [`check`]: every state finite.
//! 2. [`kinematics`]: poses, velocities and Jacobians of the awake multibodies; colliders follow.
//! 3. [`collision`]: contacts; sleepers touched by awake bodies wake.
//! 4. [`free_motion`]: the velocity without constraint impulses, stacked over the world.
//! 5. [`rows`]: the constraint rows (contacts the speculation keeps, limits, motors, servos,
//!    joint friction, loop closures); [`solve`] poses their problem.
//! 6. [`solve`]: warm start, the solver chain on each island ([`islands`]), the velocity after
//!    the impulses.
//! 7. [`speculation`]: rows for the contacts and limit stops the solved velocity closes, and
//!    the problem solved again.
//! 8. [`integrate`]: q on the manifold, loop closures projected, the new state committed; a
//!    lone free body's origin moves with the step's mean velocity where no contact normal
//!    constrains it ([`midpoint`]), and the contacts' position correction
//!    (`super::contact_projection`) is added to the step's displacement before, and checked at
//!    the new configuration after.
//!
//! Sleeping ([`super::sleep`]) and the statistics ([`super::stats`]) close the step.

pub(super) mod check;
pub(super) mod collision;
pub(super) mod free_motion;
pub(super) mod integrate;
pub(super) mod islands;
pub(super) mod kinematics;
pub(super) mod midpoint;
pub(super) mod rows;
pub(super) mod solve;
pub(super) mod speculation;
