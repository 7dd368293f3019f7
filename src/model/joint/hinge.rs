//! Hinge (revolute) joint: rotation about a fixed unit axis, `x_jc = (exp(θ a), 0)`, `S = [0; a]`.

use crate::math::{axis_angle, Mat3, Motion, Transform, Vec3};

pub(super) fn transform_and_subspace(axis: &Vec3, q: &[f64], s: &mut [Motion]) -> Transform {
    s[0] = Motion::new(Vec3::zeros(), *axis);
    Transform::new(axis_angle(axis, q[0]), Vec3::zeros())
}

/// `placement · x_jc(θ)`. The joint moves no origin, so the translation is the placement's; for a
/// coordinate axis the rotation only mixes two columns of the placement's rotation (the
/// specialization Pinocchio gets from its RevoluteX/Y/Z joint types). Always inlined: as a
/// call, the pose returns through memory and the caller's first read of it stalls on the
/// store.
#[inline(always)]
pub(super) fn placed_transform(placement: &Transform, axis: &Vec3, q: &[f64], s: &mut [Motion]) -> Transform {
    // Component by component: a whole `Motion` built first goes through a stack copy whose
    // wide reload waits on its narrow stores.
    s[0].linear.fill(0.0);
    s[0].angular.copy_from(axis);
    let aligned = |k: usize| axis[k] == 1.0 && axis[(k + 1) % 3] == 0.0 && axis[(k + 2) % 3] == 0.0;
    let r = &placement.rotation;
    let rotation = match (0..3).find(|&k| aligned(k)) {
        Some(k) => {
            // Rotation about e_k: columns (k+1, k+2) turn by θ. Each k with its own constant
            // columns: a column picked by a run-time index would send the matrix through memory.
            // The `libm` crate's sine and cosine in one Rust call (musl's algorithm, within an
            // ulp): a third cheaper than the platform's `sincos` through the dynamic linker.
            let (sn, cs) = libm::sincos(q[0]);
            let c = [r.column(0).into_owned(), r.column(1).into_owned(), r.column(2).into_owned()];
            let turn = |ci: &Vec3, cj: &Vec3| (ci * cs + cj * sn, cj * cs - ci * sn);
            match k {
                0 => {
                    let (c1, c2) = turn(&c[1], &c[2]);
                    Mat3::from_columns(&[c[0], c1, c2])
                }
                1 => {
                    let (c2, c0) = turn(&c[2], &c[0]);
                    Mat3::from_columns(&[c0, c[1], c2])
                }
                _ => {
                    let (c0, c1) = turn(&c[0], &c[1]);
                    Mat3::from_columns(&[c0, c1, c[2]])
                }
            }
        }
        None => r * axis_angle(axis, q[0]),
    };
    Transform::new(rotation, placement.translation)
}
