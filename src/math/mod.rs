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

/// `x ← x + a y`, four entries at a time: the loops that call it are short (a dof's ancestors,
/// a row's span, ~10 entries), shorter than the compiler's own vector loop (the vector width
/// times four), which leaves them to its epilogue. Each entry gets the same operations as a
/// plain loop, so results are bit for bit the same.
#[inline]
pub(crate) fn axpy(x: &mut [f64], a: f64, y: &[f64]) {
    debug_assert_eq!(x.len(), y.len());
    let mut cx = x.chunks_exact_mut(4);
    let mut cy = y.chunks_exact(4);
    for (p, q) in (&mut cx).zip(&mut cy) {
        p[0] += a * q[0];
        p[1] += a * q[1];
        p[2] += a * q[2];
        p[3] += a * q[3];
    }
    // At most three entries, written out: as a loop, the compiler makes them one masked
    // vector load and store, and a masked load of entries stored just before (the factor's
    // rows, updated by one dof after another) waits for the store to retire.
    match (cx.into_remainder(), cy.remainder()) {
        ([p0], [q0]) => *p0 += a * q0,
        ([p0, p1], [q0, q1]) => {
            *p0 += a * q0;
            *p1 += a * q1;
        }
        ([p0, p1, p2], [q0, q1, q2]) => {
            *p0 += a * q0;
            *p1 += a * q1;
            *p2 += a * q2;
        }
        _ => {}
    }
}

/// `x += a y + b z`, bit for bit [`axpy`] with `y` then with `z`, in one pass over `x` (a
/// contact's two friction rows of W moving the same velocities).
pub(crate) fn axpy2(x: &mut [f64], a: f64, y: &[f64], b: f64, z: &[f64]) {
    for ((x, y), z) in x.iter_mut().zip(y).zip(z) {
        *x = (*x + a * y) + b * z;
    }
}

/// (a · x, b · x), bit for bit two [`dot`] calls, in one pass over `x`.
pub(crate) fn dot2(a: &[f64], b: &[f64], x: &[f64]) -> (f64, f64) {
    let (mut s, mut t) = ([0.0; 4], [0.0; 4]);
    let (ca, cb, cx) = (a.chunks_exact(4), b.chunks_exact(4), x.chunks_exact(4));
    let (ra, rb, rx) = (ca.remainder(), cb.remainder(), cx.remainder());
    for ((p, q), y) in ca.zip(cb).zip(cx) {
        for k in 0..4 {
            s[k] += p[k] * y[k];
            t[k] += q[k] * y[k];
        }
    }
    for ((p, q), y) in ra.iter().zip(rb).zip(rx) {
        s[0] += p * y;
        t[0] += q * y;
    }
    ((s[0] + s[1]) + (s[2] + s[3]), (t[0] + t[1]) + (t[2] + t[3]))
}

/// `a b + c`: fused (one rounding) where the target has FMA instructions, as the C++ peers'
/// `-O3 -march=native` builds contract it; the plain form elsewhere, where `mul_add` would be a
/// library call.
#[inline(always)]
pub(crate) fn fma(a: f64, b: f64, c: f64) -> f64 {
    #[cfg(target_feature = "fma")]
    {
        a.mul_add(b, c)
    }
    #[cfg(not(target_feature = "fma"))]
    {
        a * b + c
    }
}

/// Σ a_k b_k with four partial sums, so that the additions pipeline (a single running sum is
/// bound by the latency of one addition per entry).
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let (mut s0, mut s1, mut s2, mut s3) = (0.0, 0.0, 0.0, 0.0);
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (p, q) in ca.zip(cb) {
        s0 += p[0] * q[0];
        s1 += p[1] * q[1];
        s2 += p[2] * q[2];
        s3 += p[3] * q[3];
    }
    for (p, q) in ra.iter().zip(rb) {
        s0 += p * q;
    }
    (s0 + s1) + (s2 + s3)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every length, every remainder: the same bits as the plain loop.
    #[test]
    fn axpy_equals_the_plain_loop_bit_for_bit() {
        for len in 0..13 {
            let y: Vec<f64> = (0..len).map(|k| (k as f64 * 0.37).sin() * 1e3).collect();
            let x0: Vec<f64> = (0..len).map(|k| (k as f64 * 1.9).cos() / 7.0).collect();
            let a = -0.123_456_789;
            let mut x = x0.clone();
            axpy(&mut x, a, &y);
            let plain: Vec<f64> = x0.iter().zip(&y).map(|(x, y)| x + a * y).collect();
            assert_eq!(x, plain, "length {len}");
        }
    }

    /// The fused pair kernels give the bits of the single ones, every length and remainder.
    #[test]
    fn the_pair_kernels_equal_two_single_ones_bit_for_bit() {
        for len in 0..13 {
            let y: Vec<f64> = (0..len).map(|k| (k as f64 * 0.37).sin() * 1e3).collect();
            let z: Vec<f64> = (0..len).map(|k| (k as f64 * 2.3).cos() * 0.1).collect();
            let x0: Vec<f64> = (0..len).map(|k| (k as f64 * 1.9).cos() / 7.0).collect();
            let (a, b) = (-0.123_456_789, 3.3e-4);
            let mut single = x0.clone();
            axpy(&mut single, a, &y);
            axpy(&mut single, b, &z);
            let mut pair = x0.clone();
            axpy2(&mut pair, a, &y, b, &z);
            assert_eq!(single, pair, "length {len}");
            let (d1, d2) = dot2(&y, &z, &x0);
            assert_eq!(
                (d1.to_bits(), d2.to_bits()),
                (dot(&y, &x0).to_bits(), dot(&z, &x0).to_bits()),
                "length {len}"
            );
        }
    }
}
