//! Spatial algebra: typed 6-D motions, forces, rigid-body inertias and rigid transforms.
//!
//! Conventions (Pinocchio's, see `conventions.md`):
//! - spatial vectors put the **linear part first**, the angular part second;
//! - a [`Motion`] `[v; ω]` "of B expressed in B" is the velocity of the point of B at B's origin
//!   and B's angular velocity, both in B's axes;
//! - a [`Transform`] `x_ab` is the pose of frame B in frame A and maps B coordinates to A:
//!   `p_a = R_ab p_b + t_ab`;
//! - a [`SpatialInertia`] is about the body frame's origin, in body axes;
//! - quaternions are stored `(x, y, z, w)`.
//!
//! Names carry frames (Drake's monogram notation): `x_wb` is the pose of body B in the world W,
//! `v_b` a velocity expressed in B, `x_lp` a pose in the parent body's frame.

mod force;
mod hash;
mod inertia;
mod motion;
mod transform;

pub use force::Force;
pub(crate) use hash::FastHasher;
pub use inertia::SpatialInertia;
pub use motion::Motion;
pub use transform::{axis_angle, exp3, log3, skew, Transform};
pub(crate) use transform::{quat_exp, quat_log};

/// 3-vector of `f64` (metres, radians, newtons … by context).
pub type Vec3 = nalgebra::Vector3<f64>;
/// 3×3 matrix of `f64`.
pub type Mat3 = nalgebra::Matrix3<f64>;
/// 6-vector of `f64`, linear part first.
pub type Vec6 = nalgebra::Vector6<f64>;
/// 6×6 matrix of `f64`, blocks ordered (linear, angular).
pub type Mat6 = nalgebra::Matrix6<f64>;

/// Whether every entry is finite: x·0 is 0 for a finite x and NaN otherwise, summed in four
/// lanes without a branch per entry (a short-circuiting `all` neither vectorizes nor pipelines;
/// W's values are checked on every solve, q and v on every step).
pub(crate) fn all_finite(x: &[f64]) -> bool {
    let mut lanes = [0.0f64; 4];
    let chunks = x.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for (lane, v) in lanes.iter_mut().zip(c) {
            *lane += v * 0.0;
        }
    }
    let tail: f64 = rest.iter().map(|v| v * 0.0).sum();
    (lanes[0] + lanes[1] + lanes[2] + lanes[3] + tail) == 0.0
}
