//! Continuous collision: colliders that move further in one step than the contact margin are
//! swept along their motion, and a pair that the swept box brings together but that is still
//! apart beyond the margin gets one speculative contact at its time of impact (parry's
//! `cast_shapes`), so that a fast body meets what it would otherwise pass through.
//!
//! The contact is the pair's first point of contact along the motion: its points are the two
//! witnesses of the impact, moved back to where the bodies are now, and its distance the gap
//! along the impact normal. The world gives it a speculative row like any contact still apart
//! (target normal velocity `−distance/h`, [`crate::constraints::ContactParameters`]): the
//! step may close the gap but not cross it. Motion is linear over the step (the collider's
//! origin velocity); the rotation's sweep (at most `|ω| h r` for a shape within radius r of its
//! origin) is covered by asking the cast for that distance instead of touching.

use super::{Attachment, CollisionWorld, Contact};
use crate::collision::convert::{from_vector, to_vector};
use crate::math::{Motion, Vec3};
use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::query::{cast_shapes, ShapeCastOptions, ShapeCastStatus};

/// A collider's motion over the next step, for the sweep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweptMotion {
    /// Velocity of the collider's shape origin (m/s, world axes).
    pub linear: Vec3,
    /// Angular velocity (rad/s, world axes).
    pub angular: Vec3,
    /// Duration of the step (s).
    pub h: f64,
}

impl SweptMotion {
    /// Velocity (m/s, world axes) of the world point `point` carried by a collider whose shape
    /// origin is at `origin` (m, world).
    pub fn point_velocity(&self, origin: &Vec3, point: &Vec3) -> Vec3 {
        self.linear + self.angular.cross(&(point - origin))
    }
}

/// Why a sweep could not do what was asked, reported in the step's statistics
/// ([`crate::world::StepStats::sweep_diagnostics`]); the step goes on with the contacts found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SweepDiagnostic {
    /// A sweep was asked for a body that has no collider: there is nothing to sweep.
    NoShape {
        /// Multibody index.
        multibody: usize,
        /// Body index in the multibody.
        body: usize,
    },
    /// The time-of-impact query of a pair stopped before converging; its conservative estimate
    /// (an impact no later than the true one) was used.
    NotConverged {
        /// Collider A (the moving one).
        collider_a: usize,
        /// Collider B.
        collider_b: usize,
    },
    /// parry has no time-of-impact query for the pair's shapes: the pair keeps only its
    /// contacts within the margin, as without sweeping.
    Unsupported {
        /// Collider A.
        collider_a: usize,
        /// Collider B.
        collider_b: usize,
    },
}

/// Counters of the sweeps of the last detection.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SweepStats {
    /// Colliders swept.
    pub swept_colliders: usize,
    /// Time-of-impact queries run.
    pub casts: usize,
    /// Speculative contacts added from an impact within the step.
    pub hits: usize,
}

/// The largest distance (m) a point of a shape within `radius` of the origin moving with
/// `motion` travels in the step.
fn travel(motion: &SweptMotion, radius: f64) -> f64 {
    (motion.linear.norm() + turn(motion, radius)) * motion.h
}

/// The speed (m/s) of the points within `radius` of the origin as the collider turns: zero
/// when it does not turn, whatever the radius (an unbounded shape's is infinite).
fn turn(motion: &SweptMotion, radius: f64) -> f64 {
    let w = motion.angular.norm();
    if w == 0.0 {
        0.0
    } else {
        w * radius
    }
}

impl CollisionWorld {
    /// Sets the motion of collider `collider` over the next step (None: not swept). Static
    /// colliders are never swept.
    pub fn set_motion(&mut self, collider: usize, motion: Option<SweptMotion>) {
        if collider >= self.colliders.len() || self.colliders[collider].attachment.is_static() {
            return;
        }
        if self.motions.len() < self.colliders.len() {
            self.motions.resize(self.colliders.len(), None);
        }
        self.motions[collider] = motion;
    }

    /// Sets the motion of every collider of multibody `multibody` over a step of `h` (s) from
    /// its bodies' spatial velocities `velocities` (one per body, world axes, about the world
    /// origin; bodies beyond the slice do not move): with `automatic`, a collider is swept
    /// when one of its points travels further than the contact margin in the step, and then
    /// its pairs' margin grows by how far its points travel (up to its radius: beyond, the
    /// sweep finds the impact); whatever its speed it is swept when `always(body)`. Every
    /// collider's motion is kept for the manifold reduction, swept or not (which points the step
    /// closes, [`crate::collision::reduce`]). Returns false if the index is out of range.
    pub fn set_multibody_motions(
        &mut self,
        multibody: usize,
        velocities: &[Motion],
        h: f64,
        automatic: bool,
        always: impl Fn(usize) -> bool,
    ) -> bool {
        if multibody >= self.multibodies.len() {
            return false;
        }
        if self.motions.len() < self.colliders.len() {
            self.motions.resize(self.colliders.len(), None);
        }
        if self.reach.len() < self.colliders.len() {
            self.reach.resize(self.colliders.len(), 0.0);
        }
        if self.drift.len() < self.colliders.len() {
            self.drift.resize(self.colliders.len(), None);
        }
        let margin = self.options.margin;
        for &c in &self.multibodies[multibody].colliders {
            let collider = &self.colliders[c];
            let body = match collider.attachment {
                Attachment::Body { body, .. } if body != 0 => body,
                _ => continue,
            };
            let Some(v) = velocities.get(body) else {
                self.motions[c] = None;
                self.reach[c] = 0.0;
                self.drift[c] = None;
                continue;
            };
            let origin = from_vector(collider.world_pose.translation);
            let motion = SweptMotion { linear: v.linear + v.angular.cross(&origin), angular: v.angular, h };
            let distance = travel(&motion, collider.radius);
            let swept = always(body) || (automatic && distance > margin);
            self.motions[c] = swept.then_some(motion);
            self.drift[c] = Some(motion);
            // A collider that stays within the margin keeps the margin (and its pairs their
            // reused manifolds): resting bodies are not touched.
            let fast = automatic && distance > margin && distance.is_finite();
            self.reach[c] = if fast { distance.min(collider.radius) } else { 0.0 };
        }
        true
    }

    /// Whether body `body` of multibody `multibody` has a collider.
    pub fn body_has_collider(&self, multibody: usize, body: usize) -> bool {
        self.multibodies.get(multibody).is_some_and(|m| {
            m.colliders.iter().any(|&c| self.colliders[c].attachment == Attachment::Body { multibody, body })
        })
    }

    /// Clears every collider's motion (nothing is swept until set again).
    pub fn clear_motions(&mut self) {
        self.motions.iter_mut().for_each(|m| *m = None);
        self.reach.iter_mut().for_each(|r| *r = 0.0);
        self.drift.iter_mut().for_each(|d| *d = None);
    }

    /// Collider `c`'s motion over the next step as last set, swept or not (None when its
    /// multibody's velocities were not given).
    pub(super) fn drift_of(&self, c: usize) -> Option<SweptMotion> {
        self.drift.get(c).copied().flatten()
    }

    /// How far (m) collider `c`'s points may travel in the next step, as far as its pairs'
    /// margin is concerned (0 unless set by [`CollisionWorld::set_multibody_motions`]).
    pub(super) fn reach_of(&self, c: usize) -> f64 {
        self.reach.get(c).copied().unwrap_or(0.0)
    }

    /// The diagnostics of the last detection's sweeps.
    pub fn sweep_diagnostics(&self) -> &[SweepDiagnostic] {
        &self.sweep_diagnostics
    }

    /// Counters of the last detection's sweeps.
    pub fn sweep_stats(&self) -> SweepStats {
        self.sweep_stats
    }

    /// Records a diagnostic for the step's statistics (cleared by the next detection).
    pub(crate) fn push_sweep_diagnostic(&mut self, diagnostic: SweepDiagnostic) {
        self.sweep_diagnostics.push(diagnostic);
    }

    /// Grows the broad-phase box of collider `c` (already loosened by the margin) by its
    /// sweep, if it has one.
    pub(super) fn swept_aabb(&self, c: usize, aabb: Aabb) -> Aabb {
        match self.motions.get(c).copied().flatten() {
            Some(m) => {
                let turn = turn(&m, self.colliders[c].radius) * m.h;
                let moved = Aabb::new(
                    aabb.mins + to_vector(&(m.linear * m.h)),
                    aabb.maxs + to_vector(&(m.linear * m.h)),
                );
                aabb.merged(&moved).loosened(turn)
            }
            None => aabb,
        }
    }

    /// The speculative contact of pair (a, b), still apart beyond the margin, if one of them is
    /// swept and they meet within the step.
    pub(super) fn sweep_pair(&mut self, a: usize, b: usize) {
        let motion = |c: usize| self.motions.get(c).copied().flatten();
        let (ma, mb) = (motion(a), motion(b));
        let Some(h) = ma.or(mb).map(|m| m.h) else { return };
        let (ca, cb) = (&self.colliders[a], &self.colliders[b]);
        let zero = SweptMotion { linear: Vec3::zeros(), angular: Vec3::zeros(), h };
        let (ma, mb) = (ma.unwrap_or(zero), mb.unwrap_or(zero));
        let turn = (turn(&ma, ca.radius) + turn(&mb, cb.radius)) * h;
        let options = ShapeCastOptions {
            max_time_of_impact: h,
            target_distance: turn,
            stop_at_penetration: true,
            compute_impact_geometry_on_penetration: true,
        };
        self.sweep_stats.casts += 1;
        let hit = cast_shapes(
            &ca.world_pose,
            to_vector(&ma.linear),
            &*ca.shape.0,
            &cb.world_pose,
            to_vector(&mb.linear),
            &*cb.shape.0,
            options,
        );
        let hit = match hit {
            Ok(Some(hit)) => hit,
            Ok(None) => return,
            Err(_) => {
                self.sweep_diagnostics.push(SweepDiagnostic::Unsupported { collider_a: a, collider_b: b });
                return;
            }
        };
        match hit.status {
            // Within the margin now: the narrow phase's own contacts stand for the pair.
            ShapeCastStatus::PenetratingOrWithinTargetDist => return,
            ShapeCastStatus::OutOfIterations | ShapeCastStatus::Failed => {
                self.sweep_diagnostics.push(SweepDiagnostic::NotConverged { collider_a: a, collider_b: b });
            }
            ShapeCastStatus::Converged => {}
        }
        // Witnesses and normal are in each shape's own frame; the shapes only translate, so the
        // witnesses at the current poses are the points that meet.
        let point_a = from_vector(ca.world_pose * hit.witness1);
        let point_b = from_vector(cb.world_pose * hit.witness2);
        let normal = -from_vector(ca.world_pose.rotation * hit.normal1);
        if !(normal.norm() > 0.5 && point_a.iter().chain(point_b.iter()).all(|x| x.is_finite())) {
            self.sweep_diagnostics.push(SweepDiagnostic::NotConverged { collider_a: a, collider_b: b });
            return;
        }
        let normal = normal.normalize();
        let distance = normal.dot(&(point_a - point_b)).max(0.0);
        self.sweep_stats.hits += 1;
        self.contacts.push(Contact {
            collider_a: a,
            collider_b: b,
            body_a: ca.attachment,
            body_b: cb.attachment,
            point_a,
            point_b,
            normal,
            distance,
            // Its own feature: a swept contact is never warm-started from a surface contact.
            feature: SWEPT_FEATURE ^ ((a as u64) << 24) ^ (b as u64),
        });
    }

    /// Whether collider `c` is swept this step.
    pub(super) fn is_swept(&self, c: usize) -> bool {
        self.motions.get(c).is_some_and(Option::is_some)
    }
}

/// The feature bits of a swept contact (see [`Contact::feature`]).
const SWEPT_FEATURE: u64 = 0x5357_4550_0000_0000;
