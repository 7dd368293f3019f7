//! Hinge (revolute) joint: rotation about a fixed unit axis, `x_jc = (exp(θ a), 0)`, `S = [0; a]`.

use crate::math::{axis_angle, Motion, Transform, Vec3};

pub(super) fn transform_and_subspace(axis: &Vec3, q: &[f64], s: &mut [Motion]) -> Transform {
    s[0] = Motion::new(Vec3::zeros(), *axis);
    Transform::new(axis_angle(axis, q[0]), Vec3::zeros())
}

/// `placement · x_jc(θ)`. The joint moves no origin, so the translation is the placement's; for a
/// coordinate axis the rotation only mixes two columns of the placement's rotation (the
/// specialization Pinocchio gets from its RevoluteX/Y/Z joint types).
#[inline]
pub(super) fn placed_transform(placement: &Transform, axis: &Vec3, q: &[f64], s: &mut [Motion]) -> Transform {
    s[0] = Motion::new(Vec3::zeros(), *axis);
    let aligned = |k: usize| axis[k] == 1.0 && axis[(k + 1) % 3] == 0.0 && axis[(k + 2) % 3] == 0.0;
    let r = &placement.rotation;
    let rotation = match (0..3).find(|&k| aligned(k)) {
        Some(k) => {
            // Rotation about e_k: columns (k+1, k+2) turn by θ.
            let (sn, cs) = q[0].sin_cos();
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            let (ci, cj) = (r.column(i).into_owned(), r.column(j).into_owned());
            let mut out = *r;
            out.set_column(i, &(ci * cs + cj * sn));
            out.set_column(j, &(cj * cs - ci * sn));
            out
        }
        None => r * axis_angle(axis, q[0]),
    };
    Transform::new(rotation, placement.translation)
}
