//! Sleeping (ODE's auto-disable): per multibody, speeds averaged over the last steps; islands of
//! multibodies joined by contacts fall asleep together when every member has been idle long
//! enough; a sleeping island costs nothing until something touches or pushes it.

use super::{Multibody, SleepOptions};
use crate::collision::{Attachment, CollisionWorld, Contact};
use crate::constraints::LoopClosure;
use crate::model::Joint;

/// Union–find over multibodies (buffers reused between steps).
#[derive(Clone, Debug, Default)]
pub(crate) struct Islands {
    parent: Vec<usize>,
    all_idle: Vec<bool>,
}

impl Islands {
    fn reset(&mut self, n: usize) {
        self.parent.clear();
        self.parent.extend(0..n);
        self.all_idle.clear();
        self.all_idle.resize(n, true);
    }

    fn find(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.parent[ra.max(rb)] = ra.min(rb);
        }
    }
}

/// Largest linear (m/s) and angular (rad/s) generalized speed of a multibody.
fn speeds(model: &crate::model::Model, v: &nalgebra::DVector<f64>) -> (f64, f64) {
    let (mut linear, mut angular): (f64, f64) = (0.0, 0.0);
    for i in 1..model.nbodies() {
        let start = model.idx_v(i);
        let joint = model.joint(i);
        let dofs = &v.as_slice()[start..start + joint.nv()];
        match joint {
            Joint::Free => {
                linear = linear.max(nalgebra::Vector3::from_column_slice(&dofs[..3]).norm());
                angular = angular.max(nalgebra::Vector3::from_column_slice(&dofs[3..]).norm());
            }
            Joint::Slider { .. } => linear = linear.max(dofs[0].abs()),
            Joint::Planar => {
                linear = linear.max(dofs[0].hypot(dofs[1]));
                angular = angular.max(dofs[2].abs());
            }
            Joint::Hinge2 { suspension: Some(_), .. } => {
                linear = linear.max(dofs[0].abs());
                angular = angular.max(dofs[1..].iter().fold(0.0, |m, x| m.max(x.abs())));
            }
            _ => angular = angular.max(dofs.iter().fold(0.0, |m, x| m.max(x.abs()))),
        }
    }
    (linear, angular)
}

/// Updates idle counters (a step of `h` seconds) and puts idle islands to sleep: multibodies
/// joined by `contacts` or `closures` sleep together.
pub(crate) fn update(
    options: &SleepOptions,
    h: f64,
    bodies: &mut [Multibody],
    contacts: &[Contact],
    closures: &[(usize, usize, LoopClosure)],
    collision: &mut CollisionWorld,
    islands: &mut Islands,
) {
    let samples = options.average_samples.max(1);
    for b in bodies.iter_mut().filter(|b| !b.asleep) {
        // ODE's rule (dInternalHandleAutoDisabling): the velocities of the last `samples`
        // steps are averaged as vectors and the average's speeds compared with the thresholds,
        // so that solver jitter (a light hand's velocity flipping sign from step to step)
        // averages out while a slow steady creep does not.
        let nv = b.model.nv();
        if b.velocity_history.len() != samples * nv {
            b.velocity_history.clear();
            b.velocity_history.resize(samples * nv, 0.0);
            b.history_len = 0;
        }
        let slot = b.history_len % samples;
        b.velocity_history[slot * nv..(slot + 1) * nv].copy_from_slice(b.state.v.as_slice());
        b.history_len += 1;
        let idle = b.history_len >= samples && {
            if b.velocity_average.len() != nv {
                b.velocity_average = nalgebra::DVector::zeros(nv);
            }
            b.velocity_average.fill(0.0);
            // nv = 0 (a fixed base without joints): the history is empty and the multibody idle.
            for sample in b.velocity_history.chunks_exact(nv.max(1)) {
                for (a, x) in b.velocity_average.iter_mut().zip(sample) {
                    *a += x;
                }
            }
            b.velocity_average /= samples as f64;
            let (linear, angular) = speeds(&b.model, &b.velocity_average);
            linear < options.linear_threshold && angular < options.angular_threshold
        };
        if idle && !b.kinematic {
            b.idle_steps += 1;
            b.idle_time += h;
        } else {
            b.idle_steps = 0;
            b.idle_time = 0.0;
        }
    }
    let n = bodies.len();
    islands.reset(n);
    for c in contacts {
        if let (Attachment::Body { multibody: a, body: ba }, Attachment::Body { multibody: b, body: bb }) =
            (c.body_a, c.body_b)
        {
            if a != b && ba != 0 && bb != 0 {
                islands.union(a, b);
            }
        }
    }
    for (a, b, _) in closures {
        islands.union(*a, *b);
    }
    for (i, b) in bodies.iter().enumerate() {
        let ready = b.asleep || (b.idle_steps >= options.idle_steps && b.idle_time >= options.idle_time);
        let root = islands.find(i);
        islands.all_idle[root] &= ready && !b.kinematic;
    }
    for (i, b) in bodies.iter_mut().enumerate() {
        let root = islands.find(i);
        if islands.all_idle[root] && !b.asleep {
            b.asleep = true;
            b.state.v.fill(0.0);
            collision.set_asleep(i, true);
        }
    }
}

/// Wakes multibody `i` (if there is one) and lets its island be evaluated again.
pub(crate) fn wake(bodies: &mut [Multibody], collision: &mut CollisionWorld, i: usize) {
    if let Some(b) = bodies.get_mut(i) {
        b.asleep = false;
        b.idle_steps = 0;
        b.idle_time = 0.0;
        b.history_len = 0;
        collision.set_asleep(i, false);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::MeshOptions;
    use crate::math::Vec3;
    use crate::model::{RigidInertia, Shape};
    use crate::scenes::free_body;
    use crate::world::{World, WorldOptions};

    #[test]
    fn velocities_are_averaged_as_vectors_so_jitter_sleeps_and_a_slow_creep_does_not() {
        // Two cubes apart (two islands). The velocities are written as a jittering solver and a
        // steady creep would leave them, without the wake-up that user velocity changes bring.
        let mut w = World::new(WorldOptions { gravity: Vec3::zeros(), ..Default::default() });
        let cube = || {
            let size = Vec3::repeat(0.1);
            free_body("b", Shape::Box { size }, RigidInertia::solid_box(1.0, size))
        };
        let (jitter, creep) = (
            w.add_multibody("jitter", cube(), &MeshOptions::default()).unwrap(),
            w.add_multibody("creep", cube(), &MeshOptions::default()).unwrap(),
        );
        assert_eq!(w.options.sleep.angular_threshold, 0.01);
        let steps = w.options.sleep.average_samples + w.options.sleep.idle_steps + 5;
        for k in 0..steps {
            // ±0.05 rad/s from step to step: each speed is 5× the threshold, the average is 0.
            w.bodies[jitter].state.v[5] = if k % 2 == 0 { 0.05 } else { -0.05 };
            // A steady 0.02 rad/s: twice the threshold.
            w.bodies[creep].state.v[5] = 0.02;
            let (options, h) = (w.options.sleep, w.options.dt);
            let (contacts, closures) = (&w.contacts, &w.loops.closures);
            update(&options, h, &mut w.bodies, contacts, closures, &mut w.collision, &mut w.islands);
        }
        assert!(w.bodies[jitter].asleep, "jitter averages out: asleep");
        assert!(!w.bodies[creep].asleep, "a steady creep above the threshold stays awake");
    }
}
