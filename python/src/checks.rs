//! The one check of float arguments given from Python: every number a function or setter takes
//! (a gain, a time step, a force bound, a mass, the entries of a vector) passes through
//! [`number`] or [`numbers`], so that NaN, ±∞ and values out of range are a `ValueError` naming
//! the argument (and the entry), always worded the same way, before anything is changed.

use pyo3::exceptions::PyValueError;
use pyo3::PyResult;

/// The values a float argument may take.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Allowed {
    /// Any finite number.
    Finite,
    /// A finite number ≥ 0.
    NonNegative,
    /// A finite number > 0.
    Positive,
    /// A number ≥ 0 or +∞ (a bound: +∞ means none).
    Bound,
}

impl Allowed {
    fn admits(self, x: f64) -> bool {
        match self {
            Allowed::Finite => x.is_finite(),
            Allowed::NonNegative => x.is_finite() && x >= 0.0,
            Allowed::Positive => x.is_finite() && x > 0.0,
            Allowed::Bound => x >= 0.0, // false for NaN; +∞ passes
        }
    }

    /// Why `x` (not admitted) is refused, after the argument's name.
    fn refusal(self, x: f64) -> String {
        match self {
            Allowed::NonNegative if x.is_finite() => format!("must be ≥ 0, got {x}"),
            Allowed::Positive if x.is_finite() => format!("must be > 0, got {x}"),
            Allowed::Finite | Allowed::NonNegative | Allowed::Positive => format!("is not finite ({x})"),
            Allowed::Bound if x.is_nan() => "is not a number (NaN)".to_string(),
            Allowed::Bound => format!("must be ≥ 0 (or inf: no bound), got {x}"),
        }
    }
}

/// `value` of the argument `name` if it is `allowed`, else a `ValueError` naming it:
/// `gain is not finite (NaN)`, `dt must be > 0, got -0.1`, `max_force is not a number (NaN)`.
pub fn number(name: &str, value: f64, allowed: Allowed) -> PyResult<f64> {
    if allowed.admits(value) {
        Ok(value)
    } else {
        Err(PyValueError::new_err(format!("{name} {}", allowed.refusal(value))))
    }
}

/// Checks that every entry of the argument `name` is `allowed`, naming the first that is not:
/// `force[1] is not finite (inf)`.
pub fn numbers(name: &str, values: &[f64], allowed: Allowed) -> PyResult<()> {
    match values.iter().position(|&x| !allowed.admits(x)) {
        None => Ok(()),
        Some(i) => number(&format!("{name}[{i}]"), values[i], allowed).map(|_| ()),
    }
}
