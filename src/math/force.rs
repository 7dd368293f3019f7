//! Spatial force vectors (wrenches, momenta).

use super::{Vec3, Vec6};
use std::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};

/// A spatial force `[f; τ]`: force (N) and moment about the frame origin (N·m), in the axes of the
/// frame it is expressed in. Momenta use the same type (kg·m/s, kg·m²/s).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Force {
    /// Linear part `f`.
    pub linear: Vec3,
    /// Angular part `τ` (moment about the origin).
    pub angular: Vec3,
}

impl Force {
    /// The zero force.
    #[inline]
    pub fn zero() -> Self {
        Self { linear: Vec3::zeros(), angular: Vec3::zeros() }
    }

    /// A force from its linear and angular parts.
    #[inline]
    pub fn new(linear: Vec3, angular: Vec3) -> Self {
        Self { linear, angular }
    }

    /// A force from a 6-vector `[f; τ]`.
    #[inline]
    pub fn from_vector(x: &Vec6) -> Self {
        Self { linear: Vec3::new(x[0], x[1], x[2]), angular: Vec3::new(x[3], x[4], x[5]) }
    }

    /// The 6-vector `[f; τ]`.
    #[inline]
    pub fn to_vector(&self) -> Vec6 {
        Vec6::new(self.linear.x, self.linear.y, self.linear.z, self.angular.x, self.angular.y, self.angular.z)
    }

    /// True when every component is finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.linear.iter().chain(self.angular.iter()).all(|x| x.is_finite())
    }
}

impl Add for Force {
    type Output = Force;
    #[inline]
    fn add(self, o: Force) -> Force {
        Force { linear: self.linear + o.linear, angular: self.angular + o.angular }
    }
}

impl AddAssign for Force {
    #[inline]
    fn add_assign(&mut self, o: Force) {
        self.linear += o.linear;
        self.angular += o.angular;
    }
}

impl Sub for Force {
    type Output = Force;
    #[inline]
    fn sub(self, o: Force) -> Force {
        Force { linear: self.linear - o.linear, angular: self.angular - o.angular }
    }
}

impl SubAssign for Force {
    #[inline]
    fn sub_assign(&mut self, o: Force) {
        self.linear -= o.linear;
        self.angular -= o.angular;
    }
}

impl Neg for Force {
    type Output = Force;
    #[inline]
    fn neg(self) -> Force {
        Force { linear: -self.linear, angular: -self.angular }
    }
}

impl Mul<f64> for Force {
    type Output = Force;
    #[inline]
    fn mul(self, s: f64) -> Force {
        Force { linear: self.linear * s, angular: self.angular * s }
    }
}
