//! Sleeping (ODE's auto-disable): per multibody, speeds averaged over the last steps; islands of
//! multibodies joined by contacts fall asleep together when every member has been idle long
//! enough; a sleeping island costs nothing until something touches or pushes it.

use super::World;
use crate::collision::Attachment;
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

/// Updates idle counters and puts idle islands to sleep.
pub(crate) fn update(world: &mut World) {
    let options = world.options.sleep;
    let h = world.options.dt;
    let samples = options.average_samples.max(1);
    let step = world.steps as usize;
    for b in world.bodies.iter_mut().filter(|b| !b.asleep) {
        let speed = speeds(&b.model, &b.state.v);
        if b.speed_history.len() < samples {
            b.speed_history.push(speed);
        } else {
            b.speed_history[step % samples] = speed;
        }
        let n = b.speed_history.len() as f64;
        let (sum_l, sum_a) = b.speed_history.iter().fold((0.0, 0.0), |(l, a), (x, y)| (l + x, a + y));
        let idle = b.speed_history.len() >= samples
            && sum_l / n < options.linear_threshold
            && sum_a / n < options.angular_threshold;
        if idle && !b.kinematic {
            b.idle_steps += 1;
            b.idle_time += h;
        } else {
            b.idle_steps = 0;
            b.idle_time = 0.0;
        }
    }
    let n = world.bodies.len();
    let mut islands = std::mem::take(&mut world.islands);
    islands.reset(n);
    for c in &world.contacts {
        if let (Attachment::Body { multibody: a, body: ba }, Attachment::Body { multibody: b, body: bb }) =
            (c.body_a, c.body_b)
        {
            if a != b && ba != 0 && bb != 0 {
                islands.union(a, b);
            }
        }
    }
    for (a, b, _) in &world.loops {
        islands.union(*a, *b);
    }
    for i in 0..n {
        let b = &world.bodies[i];
        let ready = b.asleep || (b.idle_steps >= options.idle_steps && b.idle_time >= options.idle_time);
        let root = islands.find(i);
        islands.all_idle[root] &= ready && !b.kinematic;
    }
    for i in 0..n {
        let root = islands.find(i);
        if islands.all_idle[root] && !world.bodies[i].asleep {
            let b = &mut world.bodies[i];
            b.asleep = true;
            b.state.v.fill(0.0);
            world.collision.set_asleep(i, true);
        }
    }
    world.islands = islands;
}
