//! The physically meaningful ranges of a model's quantities. Beyond them double precision loses
//! the dynamics (a 1e308 kg body overflows the first product; a 1e-12 kg link beside a 1 kg one
//! leaves a mass matrix whose condition number no solver survives), so the model builder refuses
//! values above the upper bounds ([`crate::error::ModelError::OutOfRange`]) and the URDF loader
//! warns about positive masses below [`MIN_POSITIVE_MASS`]. `docs/reliability.md` lists them.

/// Largest body mass accepted (kg): a loaded container ship is 2e8 kg.
pub const MAX_MASS: f64 = 1e9;
/// Smallest positive body mass without a warning (kg); a massless (0 kg) link is valid.
pub const MIN_POSITIVE_MASS: f64 = 1e-9;
/// Largest entry of a rotational inertia accepted (kg·m²).
pub const MAX_INERTIA: f64 = 1e12;
/// Largest length accepted (m): a joint placement's offset, a centre of mass's offset, a
/// shape's size.
pub const MAX_LENGTH: f64 = 1e6;
/// Time steps accepted by scene files (s): from 1e-7 s (10 MHz) to 1 s.
pub const TIME_STEP_RANGE: (f64, f64) = (1e-7, 1.0);

/// A quantity with an accepted range, as [`crate::error::ModelError::OutOfRange`] names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// A body's mass (kg), at most [`MAX_MASS`].
    Mass,
    /// The largest entry of a body's rotational inertia (kg·m²), at most [`MAX_INERTIA`].
    Inertia,
    /// The distance of a body's centre of mass from its frame (m), at most [`MAX_LENGTH`].
    ComOffset,
    /// The distance of a joint from its parent's frame (m), at most [`MAX_LENGTH`].
    PlacementOffset,
    /// A collision or visual shape's largest length ([`shape_extent`]) or its offset from the
    /// body frame (m), at most [`MAX_LENGTH`].
    ShapeSize,
}

impl Quantity {
    /// "body" or "joint".
    pub fn owner(self) -> &'static str {
        if self == Quantity::PlacementOffset {
            "joint"
        } else {
            "body"
        }
    }

    /// Its name in a message.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Mass => "mass",
            Quantity::Inertia => "inertia entry",
            Quantity::ComOffset => "centre of mass offset",
            Quantity::PlacementOffset => "placement offset",
            Quantity::ShapeSize => "shape size or offset",
        }
    }

    /// Its unit.
    pub fn unit(self) -> &'static str {
        match self {
            Quantity::Mass => "kg",
            Quantity::Inertia => "kg·m²",
            Quantity::ComOffset | Quantity::PlacementOffset | Quantity::ShapeSize => "m",
        }
    }

    /// The largest value accepted.
    pub fn limit(self) -> f64 {
        match self {
            Quantity::Mass => MAX_MASS,
            Quantity::Inertia => MAX_INERTIA,
            Quantity::ComOffset | Quantity::PlacementOffset | Quantity::ShapeSize => MAX_LENGTH,
        }
    }
}

/// The largest length of a primitive shape (a box side, a radius, a length, a scale, a hull
/// point's distance from its frame), or `None` for a half-space or a file not yet read.
pub fn shape_extent(shape: &crate::model::Shape) -> Option<f64> {
    use crate::model::Shape;
    let largest = |values: &mut dyn Iterator<Item = f64>| values.fold(0.0f64, |m, x| m.max(x.abs()));
    match shape {
        Shape::Box { size } => Some(size.amax()),
        Shape::Sphere { radius } => Some(radius.abs()),
        Shape::Capsule { radius, length } | Shape::Cylinder { radius, length } => {
            Some(radius.abs().max(length.abs()))
        }
        Shape::ConvexHull { points } => Some(largest(&mut points.iter().map(|p| p.norm()))),
        Shape::TriMesh { vertices, .. } => Some(largest(&mut vertices.iter().map(|p| p.norm()))),
        Shape::HeightField { heights, size_x, size_y } => {
            Some(heights.amax().max(size_x.abs()).max(size_y.abs()))
        }
        Shape::HalfSpace { .. } => None,
        Shape::Mesh { scale, .. } => Some(scale.amax()),
    }
}

/// A number for a message: as written for ordinary magnitudes, in scientific notation otherwise
/// (`1e308`, not 309 digits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Num(pub f64);

impl std::fmt::Display for Num {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let x = self.0;
        if x == 0.0 || !x.is_finite() || (1e-4..1e6).contains(&x.abs()) {
            write!(f, "{x}")
        } else {
            write!(f, "{x:e}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Num;

    #[test]
    fn numbers_in_messages_stay_short() {
        assert_eq!(Num(1e308).to_string(), "1e308");
        assert_eq!(Num(-2.5e-300).to_string(), "-2.5e-300");
        assert_eq!(Num(0.25).to_string(), "0.25");
        assert_eq!(Num(1e9).to_string(), "1e9");
        assert_eq!(Num(12345.5).to_string(), "12345.5");
        assert_eq!(Num(f64::INFINITY).to_string(), "inf");
    }
}
