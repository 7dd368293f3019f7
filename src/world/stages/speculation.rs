//! Stage 7 and the speculation test of stage 5: a contact still apart gets rows when its points
//! approach fast enough to close the gap within the step ([`Speculation::keeps`]); one that the
//! test left out may yet be closed by the impulses of the other rows (a resting hand flicked
//! down by a body landing on its arm): then it gets rows and the problem is solved again,
//! warm-started from this solve. Joint-limit stops are judged the same way.

use crate::collision::{Attachment, Contact};
use crate::constraints::{DroppedLimit, Speculation};
use crate::math::{Motion, Vec3};
use crate::solvers::ChainReport;
use crate::world::multibody::WorldVelocities;
use crate::world::{Multibody, StepError, World, WorldOptions};
use nalgebra::DVector;

/// Solves per step after the first for contacts and limit stops that the speculation test left
/// out and the solved velocity closes ([`SpeculationState::close_dropped`]): each pass adds
/// those it finds.
const SPECULATION_PASSES: usize = 2;

/// The contacts and limit stops of a step that the speculation test left without rows, and
/// those a solve found closing.
#[derive(Default)]
pub(crate) struct SpeculationState {
    /// This step's contacts that the speculation test left without rows.
    dropped: Vec<usize>,
    /// Per contact of this step: given rows after a solve whose velocities close it.
    forced: Vec<bool>,
    /// Per multibody: its velocities after the solve are computed (`close_dropped`).
    updated: Vec<bool>,
    /// This step's joint-limit stops that the speculation left without a row.
    pub(crate) limits_dropped: Vec<DroppedLimit>,
}

impl SpeculationState {
    /// A new step with `contacts` contacts: none forced, none dropped.
    pub(crate) fn reset(&mut self, contacts: usize) {
        self.forced.clear();
        self.forced.resize(contacts, false);
        self.dropped.clear();
        self.limits_dropped.clear();
    }

    /// Sets `has_rows[i]` for each contact: forced, or kept by `speculation` at the closing
    /// speed of its two points under the start or the free velocity (the bodies' world
    /// velocities); records the others as dropped.
    pub(crate) fn select_contacts(
        &mut self,
        bodies: &[Multibody],
        contacts: &[Contact],
        speculation: Speculation,
        h: f64,
        has_rows: &mut Vec<bool>,
    ) {
        let (forced, dropped) = (&self.forced, &mut self.dropped);
        dropped.clear();
        has_rows.clear();
        has_rows.extend(contacts.iter().enumerate().map(|(i, c)| {
            if forced[i] || speculation.keeps(c.distance, 0.0, h) {
                return true;
            }
            // The closing speed of the contact's two points under v and under v_free.
            let relative = |which: fn(&WorldVelocities) -> &[Motion]| {
                point_velocity(bodies, c.body_a, &c.point_a, which)
                    - point_velocity(bodies, c.body_b, &c.point_b, which)
            };
            let speed = relative(|w| &w.start).norm().max(relative(|w| &w.free).norm());
            let keep = speculation.keeps(c.distance, speed, h);
            if !keep {
                dropped.push(i);
            }
            keep
        }));
    }

    /// Marks as forced the contacts the speculation test left out that the velocity after the
    /// solve `v` (stacked) would have kept: their two points approach fast enough to close the
    /// gap by the speculation's own measure. True if there is one, or if a joint-limit stop left
    /// without a row closes by the same measure (the next assembly judges those by the solved
    /// velocity itself).
    pub(crate) fn close_dropped(
        &mut self,
        bodies: &mut [Multibody],
        contacts: &[Contact],
        v: &DVector<f64>,
        options: &WorldOptions,
        h: f64,
    ) -> bool {
        let limit_speculation =
            Speculation { always_within: options.limits.speculative_within, ..options.speculation };
        let v = v.as_slice();
        let limit_closes = self
            .limits_dropped
            .iter()
            .any(|d| limit_speculation.keeps(d.distance, d.closing_speed(v).max(0.0), h));
        if self.dropped.is_empty() {
            return limit_closes;
        }
        // The bodies' velocities after the solve, once per multibody that has a dropped contact.
        self.updated.clear();
        self.updated.resize(bodies.len(), false);
        for &k in &self.dropped {
            let c = &contacts[k];
            for side in [c.body_a, c.body_b] {
                if let Attachment::Body { multibody, .. } = side {
                    if !self.updated[multibody] {
                        self.updated[multibody] = true;
                        let b = &mut bodies[multibody];
                        let v = &v[b.col..b.col + b.model.nv()];
                        b.update_solved_world_velocities(v);
                    }
                }
            }
        }
        let mut found = false;
        for &k in &self.dropped {
            let c = &contacts[k];
            let velocity = |side, p: &Vec3| point_velocity(bodies, side, p, |w| &w.solved);
            let separating = c.normal.dot(&(velocity(c.body_a, &c.point_a) - velocity(c.body_b, &c.point_b)));
            if options.speculation.keeps(c.distance, (-separating).max(0.0), h) {
                self.forced[k] = true;
                found = true;
            }
        }
        found || limit_closes
    }
}

impl World {
    /// Stage 7: while the solved velocity closes a contact or limit stop left without rows (at
    /// most [`SPECULATION_PASSES`] times), the rows are formed again with it and the problem
    /// solved again; `report` gathers the iterations and fallbacks of every solve.
    pub(crate) fn speculation_passes(
        &mut self,
        h: f64,
        mut report: Option<ChainReport>,
    ) -> Result<Option<ChainReport>, StepError> {
        for _ in 0..SPECULATION_PASSES {
            if !self.speculation.close_dropped(
                &mut self.bodies,
                &self.contacts,
                &self.dofs.v_free,
                &self.options,
                h,
            ) {
                break;
            }
            let v = &mut self.dofs.v_free;
            for b in &mut self.bodies {
                let nv = b.model.nv();
                b.v_solved.copy_from(&v.rows(b.col, nv));
                v.rows_mut(b.col, nv).copy_from(&b.v_free);
            }
            self.assemble_rows(h, true);
            self.build_problem();
            let again = self.solve_problem()?;
            report = Some(match report {
                Some(mut first) => {
                    first.fallbacks.extend(again.fallbacks);
                    ChainReport {
                        iterations: first.iterations + again.iterations,
                        fallbacks: first.fallbacks,
                        ..again
                    }
                }
                None => again,
            });
        }
        Ok(report)
    }
}

/// The world velocity (m/s) of the point `p` (world) moving with `side`, from the spatial
/// velocities per body that `which` picks of its multibody's [`WorldVelocities`] (under the
/// start, free or solved velocity); zero for static geometry.
pub(crate) fn point_velocity(
    bodies: &[Multibody],
    side: Attachment,
    p: &Vec3,
    which: impl Fn(&WorldVelocities) -> &[Motion],
) -> Vec3 {
    match side {
        Attachment::Body { multibody, body } => {
            let at = &which(&bodies[multibody].world_velocities)[body];
            at.linear + at.angular.cross(p)
        }
        Attachment::World => Vec3::zeros(),
    }
}
