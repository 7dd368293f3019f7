//! Stage 5: the constraint rows of a step in one [`ProblemBuilder`], over the stacked dofs:
//! contacts that the speculation test keeps ([`super::speculation`]; rows kept from an earlier
//! step while nothing they are made of has moved, see [`crate::world::contact_rows`]), joint
//! limits (speculative stops), motors, servos, pose servos, joint friction and loop closures.

use super::speculation::{point_velocity, SpeculationState};
use crate::collision::{Collider, Contact};
use crate::constraints::{
    add_contact_rows_with, add_joint_friction_rows, add_joint_limit_rows_speculative,
    add_loop_closure_rows_between, add_motor_row, LimitVelocities, LoopClosure, ProblemBuilder, RowsMark,
    Speculation,
};
use crate::math::Vec3;
use crate::model::{Joint, Model};
use crate::world::contact_rows::KeptContactRows;
use crate::world::materials::Materials;
use crate::world::{Multibody, PoseServo, WorldOptions};
use nalgebra::DVector;

/// A step's rows as they are assembled, and what lets the contact rows be kept between steps.
pub(crate) struct RowAssembly {
    /// The rows, over the stacked dofs; it starts with last step's contact rows.
    pub(crate) builder: ProblemBuilder,
    /// What the contact rows at the start of `builder` were formed from.
    pub(crate) kept: KeptContactRows,
    /// Per contact of the step: it gets rows (the speculation test, or forced).
    pub(crate) contact_has_rows: Vec<bool>,
}

/// What a step's rows are formed from.
pub(crate) struct RowSources<'a> {
    /// The multibodies (their world velocities are brought up to date for the speculation).
    pub(crate) bodies: &'a mut [Multibody],
    /// The step's contacts.
    pub(crate) contacts: &'a [Contact],
    /// The world's loop closures (multibody of body A, multibody of body B, the closure).
    pub(crate) closures: &'a [(usize, usize, LoopClosure)],
    /// The stacked velocity at the step's start.
    pub(crate) v_start: &'a DVector<f64>,
    /// The contact materials, and the colliders whose materials they are.
    pub(crate) materials: &'a Materials,
    pub(crate) colliders: &'a [Collider],
}

impl RowAssembly {
    /// An empty builder over `builder`'s dofs.
    pub(crate) fn new(builder: ProblemBuilder) -> Self {
        Self { builder, kept: KeptContactRows::default(), contact_has_rows: Vec::new() }
    }

    /// A step without rows: the builder is emptied.
    pub(crate) fn clear(&mut self) {
        self.builder.clear();
        self.kept.invalidate();
    }

    /// Where the contact rows kept at the start of the builder end, and their generation.
    pub(crate) fn kept_contact_rows(&self) -> Option<(u64, RowsMark)> {
        self.kept.current()
    }

    /// Forms this step's rows. `after_solve`: the step was solved once, and limit stops are
    /// judged by the solved velocity (`Multibody::v_solved`) too.
    pub(crate) fn assemble(
        &mut self,
        sources: RowSources<'_>,
        options: &WorldOptions,
        speculation: &mut SpeculationState,
        h: f64,
        after_solve: bool,
    ) {
        let RowSources { bodies, contacts, closures, v_start: v, materials, colliders } = sources;
        if options.speculation.speed_factor.is_finite() {
            for b in bodies.iter_mut() {
                b.update_world_velocities();
            }
        }
        let bodies: &[Multibody] = bodies;
        let parameters_of = |c: &Contact| materials.parameters_of(colliders, c);
        let speculation_options = options.speculation;
        // Which contacts get rows, decided before any row is formed.
        speculation.select_contacts(bodies, contacts, speculation_options, h, &mut self.contact_has_rows);
        let has_rows = &self.contact_has_rows;
        let builder = &mut self.builder;
        // The builder still starts with last step's contact rows: kept if they are this step's
        // rows (see `contact_rows`), with new targets; else formed anew.
        let kept = options
            .mass_matrix_reuse
            .filter(|_| !after_solve)
            .and_then(|tolerance| self.kept.hold(tolerance, h, bodies, contacts, has_rows));
        if let Some(mark) = kept {
            builder.truncate(mark);
            let with_rows = contacts.iter().zip(has_rows).filter(|(_, rows)| **rows).map(|(c, _)| c);
            // The approach speed from the bodies' world velocities when the speculation test
            // formed them (O(1) per contact; the same J v as the normal row's, up to the kept
            // rows' tolerance), else from the row.
            let world_velocities = speculation_options.speed_factor.is_finite();
            let velocity = |side, p: &Vec3| point_velocity(bodies, side, p, |w| &w.start);
            for (k, c) in with_rows.enumerate() {
                let normal = builder.contact_blocks()[k].normal;
                let approach = if world_velocities {
                    c.normal.dot(&(velocity(c.body_a, &c.point_a) - velocity(c.body_b, &c.point_b)))
                } else {
                    builder.row_dot(normal, v.as_slice())
                };
                builder.set_target(normal, parameters_of(c).target_normal_velocity(c.distance, approach, h));
            }
            self.kept.reuses += 1;
        } else {
            builder.clear();
            add_contact_rows_with(
                builder,
                |m| (&bodies[m].model, &bodies[m].data, bodies[m].col),
                contacts,
                0,
                v,
                h,
                parameters_of,
                |i, _| has_rows[i],
            );
            if options.mass_matrix_reuse.is_some() {
                self.kept.record(h, bodies, contacts, has_rows, builder.mark());
            } else {
                self.kept.invalidate();
            }
        }
        let limits_dropped = &mut speculation.limits_dropped;
        limits_dropped.clear();
        for b in bodies.iter().filter(|b| !b.asleep && !b.kinematic) {
            let solved = after_solve.then_some(&b.v_solved);
            add_joint_limit_rows_speculative(
                builder,
                &b.model,
                &b.state.q,
                LimitVelocities { start: &b.state.v, free: &b.v_free, solved },
                b.col,
                h,
                &options.limits,
                Speculation { always_within: options.limits.speculative_within, ..speculation_options },
                limits_dropped,
            );
            for (k, motor) in b.motors.iter().enumerate() {
                if let Some(m) = motor {
                    add_motor_row(builder, k, b.col, m.target_velocity, m.max_force, h);
                }
            }
            for (k, servo) in b.servos.iter().enumerate() {
                if let Some(s) = servo {
                    let qk = position_of_dof(&b.model, &b.state.q, k);
                    let rate = (s.gain * (s.target_position - qk)).clamp(-s.max_velocity, s.max_velocity);
                    add_motor_row(builder, k, b.col, rate, s.max_force, h);
                }
            }
            if let Some(servo) = &b.pose_servo {
                add_pose_servo_rows(builder, b, servo, h);
            }
            add_joint_friction_rows(builder, &b.model, b.col, h);
        }
        for (index, (a, b, closure)) in closures.iter().enumerate() {
            let (a, b) = (&bodies[*a], &bodies[*b]);
            if !a.asleep || !b.asleep {
                add_loop_closure_rows_between(
                    builder,
                    (&a.model, &a.data, a.col),
                    (&b.model, &b.data, b.col),
                    closure,
                    index,
                    h,
                );
            }
        }
    }
}

/// Whether the step may have rows: a contact, a loop closure, or a multibody with a source of
/// rows of its own ([`has_row_sources`]).
pub(crate) fn needed(
    bodies: &[Multibody],
    contacts: &[Contact],
    closures: &[(usize, usize, LoopClosure)],
    limit_margin: f64,
) -> bool {
    !contacts.is_empty() || !closures.is_empty() || bodies.iter().any(|b| has_row_sources(b, limit_margin))
}

/// Whether multibody `b` has a motor, servo, pose servo, joint friction or a joint within
/// `limit_margin` of a limit.
pub(crate) fn has_row_sources(b: &Multibody, limit_margin: f64) -> bool {
    b.motors.iter().any(Option::is_some)
        || b.servos.iter().any(Option::is_some)
        || b.pose_servo.is_some()
        || b.model.friction().iter().any(|f| *f > 0.0)
        || has_active_limit(b, limit_margin)
}

/// Whether some scalar joint coordinate, or some ball joint's swing or twist, of the multibody is
/// within `margin` of a limit.
fn has_active_limit(b: &Multibody, margin: f64) -> bool {
    let (lo, hi) = (b.model.lower_position_limit(), b.model.upper_position_limit());
    (1..b.model.nbodies()).any(|i| {
        let joint = b.model.joint(i);
        if let Some(limits) = b.model.ball_limits(i) {
            let iq = b.model.idx_q(i);
            let (distances, _) = limits.distances(&b.state.q.as_slice()[iq..iq + 4]);
            return distances.iter().any(|d| *d <= margin);
        }
        let scalar = !matches!(joint, Joint::Ball | Joint::Free);
        scalar
            && (b.model.idx_q(i)..b.model.idx_q(i) + joint.nq()).any(|k| {
                (lo[k].is_finite() && b.state.q[k] - lo[k] <= margin)
                    || (hi[k].is_finite() && hi[k] - b.state.q[k] <= margin)
            })
    })
}

/// Motor rows of a [`PoseServo`]: for every joint but free ones, the rate `gain · (q_target ⊖ q)`
/// (per dof, clamped to `max_velocity`; for a ball joint the rotation vector of `q⁻¹ q_target`
/// in the child frame), with each dof's force bound. Dofs with their own motor or servo are left
/// to it.
fn add_pose_servo_rows(builder: &mut ProblemBuilder, b: &Multibody, servo: &PoseServo, h: f64) {
    let model = &b.model;
    for j in 1..model.nbodies() {
        let joint = model.joint(j);
        if matches!(joint, Joint::Free) {
            continue;
        }
        let (iq, iv, nq, nv) = (model.idx_q(j), model.idx_v(j), joint.nq(), joint.nv());
        let mut error = [0.0; 6];
        joint.difference(
            &b.state.q.as_slice()[iq..iq + nq],
            &servo.target.as_slice()[iq..iq + nq],
            &mut error[..nv],
        );
        for (k, e) in error[..nv].iter().enumerate() {
            let dof = iv + k;
            if b.motors[dof].is_some() || b.servos[dof].is_some() {
                continue;
            }
            let rate = (servo.gain * e).clamp(-servo.max_velocity, servo.max_velocity);
            add_motor_row(builder, dof, b.col, rate, servo.max_force[dof], h);
        }
    }
}

/// The position coordinate of velocity dof `k` for joints whose coordinates are scalars.
fn position_of_dof(model: &Model, q: &DVector<f64>, k: usize) -> f64 {
    let j = model.dof_joint(k);
    let joint = model.joint(j);
    if joint.nq() == joint.nv() {
        q[model.idx_q(j) + (k - model.idx_v(j))]
    } else {
        0.0
    }
}
