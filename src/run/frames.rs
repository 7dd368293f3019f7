//! What a viewer needs from a run ([`crate::run::RunOptions::record_frames`]): the world pose of
//! every body that carries a collider and the contact points, at the recorded instants.

use crate::collision::Attachment;
use crate::math::{Transform, Vec3};
use crate::world::World;
use crate::Data;

/// A moving body whose pose the frames record: a body (not the fixed universe) of a multibody
/// that carries at least one collider.
#[derive(Clone, Debug, PartialEq)]
pub struct FramedBody {
    /// Index of the multibody in the world.
    pub multibody: usize,
    /// Body index in that multibody's model.
    pub body: usize,
    /// `multibody/body`, e.g. `ragdoll19/head`.
    pub name: String,
}

/// Pose of a body in the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyPose {
    /// The body origin in world coordinates (m).
    pub translation: Vec3,
    /// The body's orientation `R_wb` as a unit quaternion (x, y, z, w).
    pub rotation: [f64; 4],
}

/// One contact point of a frame, in the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactSample {
    /// Midpoint of the two surface points (m).
    pub point: Vec3,
    /// Unit normal pointing from collider B to collider A.
    pub normal: Vec3,
    /// Signed distance along the normal (m): negative = penetration, positive = gap within the
    /// contact margin.
    pub distance: f64,
}

/// The world at one recorded instant, parallel to a [`crate::run::RecordedStep`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Frame {
    /// Pose of each [`FramedBody`] of [`crate::run::Recording::bodies`], in that order, from the
    /// recorded state q.
    pub poses: Vec<BodyPose>,
    /// Contact points of the step that ended at this instant (detected at the step's start,
    /// where the solver saw them); none at step 0.
    pub contacts: Vec<ContactSample>,
    /// Total energy (J).
    pub energy: f64,
}

/// Computes frames: forward kinematics of the recorded state in buffers of its own, so that the
/// world's buffers (which hold the kinematics of the step's start) stay as they are.
pub(crate) struct FrameRecorder {
    datas: Vec<Data>,
}

impl FrameRecorder {
    /// A recorder for `world` and the bodies whose poses it records.
    pub(crate) fn new(world: &World) -> (Self, Vec<FramedBody>) {
        let mut carries = std::collections::BTreeSet::new();
        for c in world.collision().colliders() {
            if let Attachment::Body { multibody, body } = c.attachment() {
                if body != 0 {
                    carries.insert((multibody, body));
                }
            }
        }
        let bodies = carries
            .into_iter()
            .map(|(multibody, body)| FramedBody {
                multibody,
                body,
                name: format!(
                    "{}/{}",
                    world.multibody_name(multibody),
                    world.multibody(multibody).model().body_name(body)
                ),
            })
            .collect();
        let datas = (0..world.multibody_count()).map(|i| Data::new(world.multibody(i).model())).collect();
        (Self { datas }, bodies)
    }

    /// The frame of the world's current state. A state that kinematics refuses (not finite) gives
    /// non-finite poses, which the viewers report.
    pub(crate) fn capture(&mut self, world: &World, bodies: &[FramedBody], energy: f64) -> Frame {
        let mut done = vec![false; self.datas.len()];
        let mut poses = Vec::with_capacity(bodies.len());
        for b in bodies {
            let data = &mut self.datas[b.multibody];
            if !done[b.multibody] {
                let mb = world.multibody(b.multibody);
                if crate::algorithms::forward_kinematics(mb.model(), data, &mb.state.q).is_err() {
                    data.x_wb.iter_mut().for_each(|x| x.translation = Vec3::repeat(f64::NAN));
                }
                done[b.multibody] = true;
            }
            poses.push(body_pose(&data.x_wb[b.body]));
        }
        let contacts = world
            .contacts()
            .iter()
            .map(|c| ContactSample {
                point: (c.point_a + c.point_b) * 0.5,
                normal: c.normal,
                distance: c.distance,
            })
            .collect();
        Frame { poses, contacts, energy }
    }
}

fn body_pose(x: &Transform) -> BodyPose {
    // A non-finite rotation matrix is never handed to the quaternion extraction (an iteration).
    let rotation = if x.rotation.iter().all(|r| r.is_finite()) { x.quaternion_xyzw() } else { [f64::NAN; 4] };
    BodyPose { translation: x.translation, rotation }
}
