//! Single checked values of a scene file: each type's `Deserialize` refuses what the key does
//! not accept (a negative mass, a non-finite coordinate, an unknown solver) with a message that
//! [`super::SceneError::Invalid`] places at the value.

use super::{parse_friction, parse_solvers, INTEGRATORS};
use crate::collision::ManifoldReuse;
use crate::constraints::FrictionModel;
use crate::math::Vec3;
use crate::world::{SolverKind, WorldOptions};
use serde::de::Error as _;
use serde::{Deserialize, Deserializer};

macro_rules! checked_number {
    ($(#[$doc:meta])* $name:ident, $expected:literal, $ok:expr) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub(super) struct $name(pub(super) f64);

        impl<'de> Deserialize<'de> for $name {
            fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let x = f64::deserialize(d)?;
                let ok: fn(f64) -> bool = $ok;
                if ok(x) {
                    Ok(Self(x))
                } else {
                    Err(D::Error::custom(format!(concat!("expected ", $expected, ", got {}"), x)))
                }
            }
        }
    };
}

checked_number!(
    /// A finite number.
    Finite,
    "a finite number",
    |x| x.is_finite()
);
checked_number!(
    /// A finite number > 0.
    Positive,
    "a positive number",
    |x| x.is_finite() && x > 0.0
);
checked_number!(
    /// A finite number ≥ 0.
    NonNegative,
    "a non-negative number",
    |x| x.is_finite() && x >= 0.0
);
checked_number!(
    /// A number > 0, infinity allowed.
    PositiveOrInfinite,
    "a positive number or inf",
    |x| x > 0.0
);
checked_number!(
    /// A number in [0, 1].
    Fraction,
    "a number between 0 and 1",
    |x| (0.0..=1.0).contains(&x)
);

/// A vector of three finite numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct V3(pub(super) Vec3);

impl<'de> Deserialize<'de> for V3 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let [x, y, z] = <[Finite; 3]>::deserialize(d)?;
        Ok(V3(Vec3::new(x.0, y.0, z.0)))
    }
}

/// An integer ≥ 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Count1(pub(super) usize);

impl<'de> Deserialize<'de> for Count1 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let n = i64::deserialize(d)?;
        if n >= 1 {
            Ok(Count1(n as usize))
        } else {
            Err(D::Error::custom(format!("expected a positive integer, got {n}")))
        }
    }
}

/// `count`: `n` (a row of n copies along `spacing`) or `[nx, ny, nz]` (a grid).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Count {
    Row(usize),
    Grid([usize; 3]),
}

/// Most copies one `count` makes: a scene file describes a scene to step, and a count beyond
/// this (a typo, a wrapped product) would only exhaust memory while building it.
const MAX_COPIES: usize = 100_000;

impl<'de> Deserialize<'de> for Count {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let expected = "expected a positive integer or a list [nx, ny, nz] of positive integers";
        let positive = |v: &toml::Value| v.as_integer().filter(|n| *n >= 1).map(|n| n as usize);
        let count = match toml::Value::deserialize(d)? {
            v @ toml::Value::Integer(_) => {
                positive(&v).map(Count::Row).ok_or_else(|| D::Error::custom(expected))?
            }
            toml::Value::Array(a) if a.len() == 3 => {
                let dims: Option<Vec<usize>> = a.iter().map(positive).collect();
                dims.map(|d| Count::Grid([d[0], d[1], d[2]])).ok_or_else(|| D::Error::custom(expected))?
            }
            _ => return Err(D::Error::custom(expected)),
        };
        let total = match count {
            Count::Row(n) => Some(n),
            Count::Grid([x, y, z]) => x.checked_mul(y).and_then(|xy| xy.checked_mul(z)),
        };
        match total {
            Some(n) if n <= MAX_COPIES => Ok(count),
            _ => Err(D::Error::custom(match count {
                Count::Row(n) => format!("at most {MAX_COPIES} copies, got {n}"),
                Count::Grid([x, y, z]) => format!("at most {MAX_COPIES} copies, got [{x}, {y}, {z}]"),
            })),
        }
    }
}

/// A material, by index or by name.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum MaterialRef {
    Index(u32),
    Name(String),
}

impl Default for MaterialRef {
    fn default() -> Self {
        MaterialRef::Index(0)
    }
}

impl<'de> Deserialize<'de> for MaterialRef {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        match toml::Value::deserialize(d)? {
            toml::Value::Integer(n) if (0..=u32::MAX as i64).contains(&n) => Ok(MaterialRef::Index(n as u32)),
            toml::Value::String(s) => Ok(MaterialRef::Name(s)),
            other => Err(D::Error::custom(format!(
                "expected a material index (a non-negative integer) or name, got {other}"
            ))),
        }
    }
}

/// A joint value: one number, or a list for joints of several coordinates.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct JointValue(pub(super) Vec<f64>);

impl<'de> Deserialize<'de> for JointValue {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let expected = "expected a finite number or a list of finite numbers";
        let number = |v: &toml::Value| match v {
            toml::Value::Integer(n) => Some(*n as f64),
            toml::Value::Float(x) if x.is_finite() => Some(*x),
            _ => None,
        };
        match toml::Value::deserialize(d)? {
            toml::Value::Array(a) => a
                .iter()
                .map(number)
                .collect::<Option<Vec<_>>>()
                .map(JointValue)
                .ok_or(D::Error::custom(expected)),
            v => number(&v).map(|x| JointValue(vec![x])).ok_or_else(|| D::Error::custom(expected)),
        }
    }
}

/// `solver`: a name or a list of names.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct SolverList(pub(super) Vec<SolverKind>);

impl<'de> Deserialize<'de> for SolverList {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let names = match toml::Value::deserialize(d)? {
            toml::Value::String(s) => vec![s],
            toml::Value::Array(a) => a
                .into_iter()
                .map(|v| match v {
                    toml::Value::String(s) => Ok(s),
                    other => Err(D::Error::custom(format!("expected a solver name, got {other}"))),
                })
                .collect::<Result<Vec<_>, _>>()?,
            other => {
                return Err(D::Error::custom(format!(
                    "expected a solver name or a list of them, got {other}"
                )))
            }
        };
        parse_solvers(&names.join(",")).map(SolverList).map_err(D::Error::custom)
    }
}

/// `contact_reuse`: `true` (the default tolerances), `false`, or `{ translation, rotation }`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ReuseSetting(pub(super) Option<ManifoldReuse>);

impl<'de> Deserialize<'de> for ReuseSetting {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Tolerances {
            translation: Option<Positive>,
            rotation: Option<Positive>,
        }
        match toml::Value::deserialize(d)? {
            toml::Value::Boolean(on) => Ok(Self(on.then(ManifoldReuse::default))),
            table @ toml::Value::Table(_) => {
                let t: Tolerances = table.try_into().map_err(D::Error::custom)?;
                let defaults = ManifoldReuse::default();
                Ok(Self(Some(ManifoldReuse {
                    translation: t.translation.map_or(defaults.translation, |x| x.0),
                    rotation: t.rotation.map_or(defaults.rotation, |x| x.0),
                })))
            }
            other => Err(D::Error::custom(format!(
                "expected true, false or {{ translation = m, rotation = rad }}, got {other}"
            ))),
        }
    }
}

/// `mass_matrix_reuse`: `true` (the default tolerance), `false`, or a tolerance (rad or m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct MassReuseSetting(pub(super) Option<f64>);

impl<'de> Deserialize<'de> for MassReuseSetting {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        match toml::Value::deserialize(d)? {
            toml::Value::Boolean(on) => {
                Ok(Self(if on { WorldOptions::default().mass_matrix_reuse } else { None }))
            }
            toml::Value::Float(x) if x.is_finite() && x > 0.0 => Ok(Self(Some(x))),
            other => {
                Err(D::Error::custom(format!("expected true, false or a positive tolerance, got {other}")))
            }
        }
    }
}

/// `friction`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct FrictionName(pub(super) FrictionModel);

impl<'de> Deserialize<'de> for FrictionName {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        parse_friction(&String::deserialize(d)?).map(FrictionName).map_err(D::Error::custom)
    }
}

/// `integrator`.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct IntegratorName(pub(super) String);

impl<'de> Deserialize<'de> for IntegratorName {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        if crate::world::parse_integrator(&name).is_some() {
            Ok(IntegratorName(name))
        } else {
            Err(D::Error::custom(format!("unknown integrator `{name}` (known: {})", INTEGRATORS.join(", "))))
        }
    }
}
