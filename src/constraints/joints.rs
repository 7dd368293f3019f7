//! Joint rows: position limits (unilateral, with bounce and ODE's StopERP/StopCFM) — of scalar
//! coordinates and the swing cone, twist range and total angle of ball joints
//! ([`crate::model::BallLimits`]) —, velocity motors (a bounded row: target velocity, maximum
//! force — ODE's Vel/FMax) and Coulomb joint friction (a bounded row with target velocity 0).

use super::{ProblemBuilder, RowLaw, RowOrigin, Speculation};
use crate::math::Vec3;
use crate::model::{BallLimits, Joint, Model};
use nalgebra::DVector;

/// Parameters of joint-limit rows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointLimitParameters {
    /// Fraction of the limit violation removed per step (ODE's StopERP).
    pub erp: f64,
    /// Softness (ODE's StopCFM): the row gets `cfm/h` on the diagonal.
    pub cfm: f64,
    /// Restitution at the stop (ODE's Bounce), ε ∈ [0, 1].
    pub restitution: f64,
    /// Approach speed below which the stop does not bounce (rad/s or m/s).
    pub bounce_velocity: f64,
    /// A limit row is created when the coordinate is within this distance of the stop (rad or m).
    pub margin: f64,
    /// Distance from the stop (rad or m) up to which a stop within `margin` always gets its row
    /// in a world step; further away it gets one only if the step can close the gap (the
    /// world's [`Speculation`] speed factor, see [`add_joint_limit_rows_speculative`]).
    pub speculative_within: f64,
}

impl Default for JointLimitParameters {
    fn default() -> Self {
        Self {
            erp: 0.2,
            cfm: 0.0,
            restitution: 0.0,
            bounce_velocity: 0.1,
            margin: 0.02,
            speculative_within: 0.01,
        }
    }
}

fn has_scalar_coordinates(joint: &Joint) -> bool {
    !matches!(joint, Joint::Ball | Joint::Free | Joint::Fixed) && joint.nq() == joint.nv()
}

/// Appends a row for every active position limit of `model` at configuration `q` and velocity
/// `v` (joints whose coordinates are scalars: hinge, slider, universal, hinge2, planar; and ball
/// joints with [`crate::model::BallLimits`]). A lower limit row has J = e_k (its impulse pushes
/// the coordinate up), an upper one J = −e_k. A ball joint's swing row has J = −∂θ/∂ω (the unit
/// swing axis in the child frame, see [`crate::model::swing_twist`]: its impulse turns the child
/// back into the cone), its twist rows J = ±∂φ/∂ω, its total-angle row J = −∂θ/∂ω (the unit
/// rotation axis). `col` is the column offset of this model's velocities; `h` the step (s). A
/// row exists when its stop is within `p.margin`.
pub fn add_joint_limit_rows(
    builder: &mut ProblemBuilder,
    model: &Model,
    q: &DVector<f64>,
    v: &DVector<f64>,
    col: usize,
    h: f64,
    p: &JointLimitParameters,
) {
    let velocities = LimitVelocities { start: v, free: v, solved: None };
    add_joint_limit_rows_speculative(
        builder,
        model,
        q,
        velocities,
        col,
        h,
        p,
        Speculation::ALL,
        &mut Vec::new(),
    );
}

/// The velocities a speculative limit is judged by (each the model's nv entries): `start`, the
/// state's (which also sets the rows' approach speeds and targets); `free`, with the step's
/// gravity and forces in it; and, once the step has been solved, `solved`, the velocity after
/// its impulses (the world's check after the solve).
#[derive(Clone, Copy, Debug)]
pub struct LimitVelocities<'a> {
    /// Velocity at the start of the step.
    pub start: &'a DVector<f64>,
    /// Free velocity of the step.
    pub free: &'a DVector<f64>,
    /// Velocity after a solve of the step, if there was one.
    pub solved: Option<&'a DVector<f64>>,
}

/// A stop within the limit margin that the speculation left without a row
/// ([`add_joint_limit_rows_speculative`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DroppedLimit {
    /// Distance to the stop (rad or m, > 0).
    pub distance: f64,
    /// Column of the joint's first velocity coordinate in the problem.
    pub column: usize,
    /// The row it would have had over the joint's velocity coordinates from `column` on (1
    /// entry for a scalar coordinate, 3 for a ball joint's swing or twist): a positive rate
    /// moves away from the stop.
    pub direction: [f64; 3],
    /// Entries of `direction` in use (1 or 3).
    pub dofs: usize,
}

impl DroppedLimit {
    /// Speed (rad/s or m/s) at which the coordinate approaches its stop under `v`, the
    /// velocity of the whole problem (its columns).
    pub fn closing_speed(&self, v: &[f64]) -> f64 {
        let rate: f64 = (0..self.dofs).map(|k| self.direction[k] * v[self.column + k]).sum();
        -rate
    }
}

/// [`add_joint_limit_rows`] with limits treated like speculative contacts: a stop within
/// `p.margin` gets a row only if `speculation` keeps it ([`Speculation::keeps`], the distance in
/// rad or m) at the largest of the coordinate's rates under `velocities.start` and
/// `velocities.free` and its closing speed under `velocities.solved`. A limb resting 0.05 rad
/// from its stop adds no row whose impulse could only be zero. The stops left without a row are
/// appended to `dropped` (the world checks them against the solved velocity). The world passes its contact
/// speculation with `always_within` = `p.speculative_within`: a floor of 0.01 rad, not the
/// contacts' 2 mm, because with 2 or 5 mrad the 20-ragdoll pile never fell asleep (stops
/// resting a few mrad off flickered in and out of the problem).
#[allow(clippy::too_many_arguments)]
pub fn add_joint_limit_rows_speculative(
    builder: &mut ProblemBuilder,
    model: &Model,
    q: &DVector<f64>,
    velocities: LimitVelocities,
    col: usize,
    h: f64,
    p: &JointLimitParameters,
    speculation: Speculation,
    dropped: &mut Vec<DroppedLimit>,
) {
    let (v, v_free) = (velocities.start, velocities.free);
    for i in 1..model.nbodies() {
        let joint = model.joint(i);
        if let Some(limits) = model.ball_limits(i) {
            let (iq, iv) = (model.idx_q(i), model.idx_v(i));
            add_ball_limit_rows(builder, limits, q, velocities, iq, iv, col, h, p, speculation, dropped);
            continue;
        }
        if !has_scalar_coordinates(joint) {
            continue;
        }
        for k in 0..joint.nv() {
            let (qi, vi) = (model.idx_q(i) + k, model.idx_v(i) + k);
            let (lo, hi) = (model.lower_position_limit()[qi], model.upper_position_limit()[qi]);
            for (distance, sign, origin) in [
                (q[qi] - lo, 1.0, RowOrigin::LowerLimit(col + vi)),
                (hi - q[qi], -1.0, RowOrigin::UpperLimit(col + vi)),
            ] {
                if !distance.is_finite() || distance > p.margin {
                    continue;
                }
                let closing = velocities.solved.map_or(0.0, |solved| -sign * solved[vi]);
                if !speculation.keeps(distance, v[vi].abs().max(v_free[vi].abs()).max(closing), h) {
                    dropped.push(DroppedLimit {
                        distance,
                        column: col + vi,
                        direction: [sign, 0.0, 0.0],
                        dofs: 1,
                    });
                    continue;
                }
                let approach = sign * v[vi];
                let target = limit_target(distance, approach, h, p);
                builder.push_joint_row(RowLaw::Unilateral, target, p.cfm / h, origin, col + vi, &[sign]);
            }
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn add_ball_limit_rows(
    builder: &mut ProblemBuilder,
    limits: &BallLimits,
    q: &DVector<f64>,
    velocities: LimitVelocities,
    iq: usize,
    iv: usize,
    col: usize,
    h: f64,
    p: &JointLimitParameters,
    speculation: Speculation,
    dropped: &mut Vec<DroppedLimit>,
) {
    if limits.surely_beyond(&q.as_slice()[iq..iq + 4], p.margin) {
        return; // No stop within the margin: no row, nothing dropped.
    }
    let (distances, st) = limits.distances(&q.as_slice()[iq..iq + 4]);
    let omega_of = |v: &DVector<f64>| Vec3::new(v[iv], v[iv + 1], v[iv + 2]);
    let (omega, omega_free) = (omega_of(velocities.start), omega_of(velocities.free));
    let omega_solved = velocities.solved.map(omega_of);
    let rows = [
        (distances[0], -st.swing_rate, RowOrigin::SwingLimit(col + iv)),
        (distances[1], st.twist_rate, RowOrigin::TwistLowerLimit(col + iv)),
        (distances[2], -st.twist_rate, RowOrigin::TwistUpperLimit(col + iv)),
        (distances[3], -st.angle_rate, RowOrigin::AngleLimit(col + iv)),
    ];
    for (distance, direction, origin) in rows {
        // A zero direction (a swing or total angle of exactly 0) is at no stop wider than the margin.
        if distance > p.margin || direction == Vec3::zeros() {
            continue;
        }
        let approach = direction.dot(&omega);
        let closing = omega_solved.map_or(0.0, |w| -direction.dot(&w));
        if !speculation.keeps(distance, approach.abs().max(direction.dot(&omega_free).abs()).max(closing), h)
        {
            let direction = [direction[0], direction[1], direction[2]];
            dropped.push(DroppedLimit { distance, column: col + iv, direction, dofs: 3 });
            continue;
        }
        let target = limit_target(distance, approach, h, p);
        let coefficients = [direction[0], direction[1], direction[2]];
        builder.push_joint_row(RowLaw::Unilateral, target, p.cfm / h, origin, col + iv, &coefficients);
    }
}

fn limit_target(distance: f64, approach: f64, h: f64, p: &JointLimitParameters) -> f64 {
    if approach < -p.bounce_velocity && distance <= -approach * h && p.restitution > 0.0 {
        (-p.restitution * approach).max(p.erp * (-distance).max(0.0) / h)
    } else if distance > 0.0 {
        -distance / h
    } else {
        p.erp * -distance / h
    }
}

/// Appends a velocity motor on velocity coordinate `dof` (index into v, plus `col`): drives the
/// coordinate's rate to `target_velocity` with at most `max_force` (N·m or N) over the step `h`.
pub fn add_motor_row(
    builder: &mut ProblemBuilder,
    dof: usize,
    col: usize,
    target_velocity: f64,
    max_force: f64,
    h: f64,
) {
    let bound = max_force.abs() * h;
    builder.push_joint_row(
        RowLaw::Bounded { lo: -bound, hi: bound },
        target_velocity,
        0.0,
        RowOrigin::Motor(col + dof),
        col + dof,
        &[1.0],
    );
}

/// Appends a Coulomb friction row for every dof of `model` with positive friction
/// ([`Model::friction`], N·m or N): the impulse opposing the dof's motion is at most friction·h.
pub fn add_joint_friction_rows(builder: &mut ProblemBuilder, model: &Model, col: usize, h: f64) {
    for (k, &f) in model.friction().iter().enumerate() {
        if f > 0.0 {
            let bound = f * h;
            builder.push_joint_row(
                RowLaw::Bounded { lo: -bound, hi: bound },
                0.0,
                0.0,
                RowOrigin::JointFriction(col + k),
                col + k,
                &[1.0],
            );
        }
    }
}
