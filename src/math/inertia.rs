//! Rigid-body spatial inertia.

use super::{skew, Force, Mat3, Mat6, Motion, Transform, Vec3};

/// Spatial inertia of a rigid body about its frame's origin, in the frame's axes.
///
/// Stored as mass `m` (kg), first moment `h = m c` (kg·m, `c` the centre of mass) and rotational
/// inertia about the origin `I_o = I_c − m [c]×²` (kg·m²), the form in which `I v` costs least.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpatialInertia {
    /// Mass (kg).
    pub mass: f64,
    /// First moment of mass `m c` about the origin (kg·m).
    pub first_moment: Vec3,
    /// Rotational inertia about the frame origin (kg·m²), symmetric.
    pub inertia_origin: Mat3,
}

impl Default for SpatialInertia {
    fn default() -> Self {
        Self::zero()
    }
}

impl SpatialInertia {
    /// The inertia of nothing (massless).
    pub fn zero() -> Self {
        Self { mass: 0.0, first_moment: Vec3::zeros(), inertia_origin: Mat3::zeros() }
    }

    /// From mass (kg), centre of mass `com` (m, frame coordinates) and rotational inertia about the
    /// centre of mass `inertia_com` (kg·m², frame axes).
    pub fn new(mass: f64, com: Vec3, inertia_com: Mat3) -> Self {
        let k = skew(&com);
        Self { mass, first_moment: com * mass, inertia_origin: inertia_com - k * k * mass }
    }

    /// Centre of mass in frame coordinates (m); the origin for a massless body.
    pub fn com(&self) -> Vec3 {
        if self.mass > 0.0 {
            self.first_moment / self.mass
        } else {
            Vec3::zeros()
        }
    }

    /// Rotational inertia about the centre of mass (kg·m², frame axes).
    pub fn inertia_com(&self) -> Mat3 {
        if self.mass > 0.0 {
            let k = skew(&self.first_moment);
            self.inertia_origin + k * k / self.mass
        } else {
            self.inertia_origin
        }
    }

    /// Momentum `I v` of the body moving with spatial velocity `v` (same frame).
    #[inline]
    pub fn mul_motion(&self, v: &Motion) -> Force {
        let h = &self.first_moment;
        Force {
            linear: v.linear * self.mass - h.cross(&v.angular),
            angular: self.inertia_origin * v.angular + h.cross(&v.linear),
        }
    }

    /// The 6×6 matrix `[[m 1, −[h]×], [[h]×, I_o]]`.
    #[inline]
    pub fn to_matrix(&self) -> Mat6 {
        let mut out = Mat6::zeros();
        self.write_matrix(&mut out);
        out
    }

    /// Writes [`SpatialInertia::to_matrix`] into `out` (every entry).
    #[inline]
    pub fn write_matrix(&self, out: &mut Mat6) {
        let (m, h, i) = (self.mass, &self.first_moment, &self.inertia_origin);
        // Column-major, column by column: [m e_c; [h]× e_c] then [−[h]× e_c; I_o e_c].
        let data = out.as_mut_slice();
        data[..18].copy_from_slice(&[
            m, 0.0, 0.0, 0.0, h.z, -h.y, //
            0.0, m, 0.0, -h.z, 0.0, h.x, //
            0.0, 0.0, m, h.y, -h.x, 0.0,
        ]);
        data[18..].copy_from_slice(&[
            0.0,
            -h.z,
            h.y,
            i[(0, 0)],
            i[(1, 0)],
            i[(2, 0)], //
            h.z,
            0.0,
            -h.x,
            i[(0, 1)],
            i[(1, 1)],
            i[(2, 1)], //
            -h.y,
            h.x,
            0.0,
            i[(0, 2)],
            i[(1, 2)],
            i[(2, 2)],
        ]);
    }

    /// This inertia (given in frame B) expressed in frame A, for `x_ab` the pose of B in A:
    /// `I_a = aX*b I_b bXa`.
    #[inline]
    pub fn transformed(&self, x_ab: &Transform) -> SpatialInertia {
        let r = &x_ab.rotation;
        let t = &x_ab.translation;
        let h_r = r * self.first_moment;
        // I_o' = R I_o Rᵀ − ([Rh]×[t]× + [t]×[Rh]× + m [t]×²), with [a]×[b]× = b aᵀ − (a·b) 1:
        //      = R I_o Rᵀ − (t hᵀ + h tᵀ + m t tᵀ) + (2 h·t + m t·t) 1   (h = R h_b)
        let mut inertia_origin = rotate_symmetric(r, &self.inertia_origin);
        let diag = 2.0 * h_r.dot(t) + self.mass * t.norm_squared();
        let mt = t * self.mass;
        for c in 0..3 {
            for k in 0..3 {
                inertia_origin[(k, c)] -= t[k] * h_r[c] + h_r[k] * t[c] + mt[k] * t[c];
            }
            inertia_origin[(c, c)] += diag;
        }
        SpatialInertia { mass: self.mass, first_moment: h_r + t * self.mass, inertia_origin }
    }

    /// Kinetic energy `½ vᵀ I v` (J) of the body moving with `v`.
    #[inline]
    pub fn kinetic_energy(&self, v: &Motion) -> f64 {
        0.5 * v.dot(&self.mul_motion(v))
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.mass.is_finite()
            && self.first_moment.iter().all(|x| x.is_finite())
            && self.inertia_origin.iter().all(|x| x.is_finite())
    }
}

/// `R S Rᵀ` for a symmetric `S`, forming only the six distinct entries.
#[inline]
pub(crate) fn rotate_symmetric(r: &Mat3, s: &Mat3) -> Mat3 {
    let rs = r * s;
    let mut out = Mat3::zeros();
    for i in 0..3 {
        for j in i..3 {
            let x = rs[(i, 0)] * r[(j, 0)] + rs[(i, 1)] * r[(j, 1)] + rs[(i, 2)] * r[(j, 2)];
            out[(i, j)] = x;
            out[(j, i)] = x;
        }
    }
    out
}

impl std::ops::Add for SpatialInertia {
    type Output = SpatialInertia;
    fn add(self, o: SpatialInertia) -> SpatialInertia {
        SpatialInertia {
            mass: self.mass + o.mass,
            first_moment: self.first_moment + o.first_moment,
            inertia_origin: self.inertia_origin + o.inertia_origin,
        }
    }
}

impl std::ops::AddAssign for SpatialInertia {
    fn add_assign(&mut self, o: SpatialInertia) {
        self.mass += o.mass;
        self.first_moment += o.first_moment;
        self.inertia_origin += o.inertia_origin;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn matrix_form_and_transform_agree() {
        let i = SpatialInertia::new(
            2.5,
            Vec3::new(0.1, -0.2, 0.3),
            Mat3::new(0.2, 0.01, 0.0, 0.01, 0.3, 0.02, 0.0, 0.02, 0.25),
        );
        let v = Motion::new(Vec3::new(0.4, 1.0, -2.0), Vec3::new(0.3, -0.7, 0.5));
        assert_relative_eq!(i.mul_motion(&v).to_vector(), i.to_matrix() * v.to_vector(), epsilon = 1e-12);
        let x = Transform::from_xyz_rpy([0.5, 0.1, -0.3], [0.2, 0.9, -1.3]);
        let ia = i.transformed(&x);
        // momentum transforms as a force: I_a (aXb v) = aX*b (I_b v)
        let lhs = ia.mul_motion(&x.act_motion(&v));
        let rhs = x.act_force(&i.mul_motion(&v));
        assert_relative_eq!(lhs.to_vector(), rhs.to_vector(), epsilon = 1e-12);
        assert_relative_eq!(ia.com(), x.act_point(&i.com()), epsilon = 1e-12);
        assert_relative_eq!(
            i.inertia_com(),
            Mat3::new(0.2, 0.01, 0.0, 0.01, 0.3, 0.02, 0.0, 0.02, 0.25),
            epsilon = 1e-12
        );
    }
}
