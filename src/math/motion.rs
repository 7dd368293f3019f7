//! Spatial motion vectors (twists, spatial accelerations).

use super::{Force, Vec3, Vec6};
use std::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};

/// A spatial motion vector `[v; ω]`: linear velocity (m/s) of the point at the frame origin and
/// angular velocity (rad/s), both in the axes of the frame it is expressed in. Spatial
/// accelerations use the same type (m/s², rad/s²).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Motion {
    /// Linear part `v`.
    pub linear: Vec3,
    /// Angular part `ω`.
    pub angular: Vec3,
}

impl Motion {
    /// The zero motion.
    #[inline]
    pub fn zero() -> Self {
        Self { linear: Vec3::zeros(), angular: Vec3::zeros() }
    }

    /// A motion from its linear and angular parts.
    #[inline]
    pub fn new(linear: Vec3, angular: Vec3) -> Self {
        Self { linear, angular }
    }

    /// A motion from a 6-vector `[v; ω]`.
    #[inline]
    pub fn from_vector(x: &Vec6) -> Self {
        Self { linear: Vec3::new(x[0], x[1], x[2]), angular: Vec3::new(x[3], x[4], x[5]) }
    }

    /// The 6-vector `[v; ω]`.
    #[inline]
    pub fn to_vector(&self) -> Vec6 {
        Vec6::new(self.linear.x, self.linear.y, self.linear.z, self.angular.x, self.angular.y, self.angular.z)
    }

    /// Spatial cross product of motions `self × m` (Featherstone's `crm`):
    /// `[ω × v_m + v × ω_m; ω × ω_m]`.
    #[inline]
    pub fn cross(&self, m: &Motion) -> Motion {
        Motion {
            linear: self.angular.cross(&m.linear) + self.linear.cross(&m.angular),
            angular: self.angular.cross(&m.angular),
        }
    }

    /// Spatial cross product with a force `self ×* f` (Featherstone's `crf`):
    /// `[ω × f; ω × τ + v × f]`.
    #[inline]
    pub fn cross_force(&self, f: &Force) -> Force {
        Force {
            linear: self.angular.cross(&f.linear),
            angular: self.angular.cross(&f.angular) + self.linear.cross(&f.linear),
        }
    }

    /// Power pairing `m · f = v · f + ω · τ` (watts for a velocity and a wrench).
    #[inline]
    pub fn dot(&self, f: &Force) -> f64 {
        self.linear.dot(&f.linear) + self.angular.dot(&f.angular)
    }

    /// True when every component is finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.linear.iter().chain(self.angular.iter()).all(|x| x.is_finite())
    }
}

impl Add for Motion {
    type Output = Motion;
    #[inline]
    fn add(self, o: Motion) -> Motion {
        Motion { linear: self.linear + o.linear, angular: self.angular + o.angular }
    }
}

impl AddAssign for Motion {
    #[inline]
    fn add_assign(&mut self, o: Motion) {
        self.linear += o.linear;
        self.angular += o.angular;
    }
}

impl Sub for Motion {
    type Output = Motion;
    #[inline]
    fn sub(self, o: Motion) -> Motion {
        Motion { linear: self.linear - o.linear, angular: self.angular - o.angular }
    }
}

impl SubAssign for Motion {
    #[inline]
    fn sub_assign(&mut self, o: Motion) {
        self.linear -= o.linear;
        self.angular -= o.angular;
    }
}

impl Neg for Motion {
    type Output = Motion;
    #[inline]
    fn neg(self) -> Motion {
        Motion { linear: -self.linear, angular: -self.angular }
    }
}

impl Mul<f64> for Motion {
    type Output = Motion;
    #[inline]
    fn mul(self, s: f64) -> Motion {
        Motion { linear: self.linear * s, angular: self.angular * s }
    }
}
