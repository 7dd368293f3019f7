//! Attribute values of MJCF elements: numbers, vectors, booleans and poses, taken from the
//! element or its default class chain, each checked where it is read.

use super::{Kind, Loader};
use crate::error::MjcfError;
use crate::math::{Mat3, Transform, Vec3};
use nalgebra::{Quaternion, UnitQuaternion};
use roxmltree::Node;

impl Loader<'_, '_> {
    /// The attribute as written on the element, else from its default class chain.
    pub(super) fn get(&self, node: Node, kind: Kind, class: &str, name: &str) -> Option<String> {
        if let Some(v) = node.attribute(name) {
            return Some(v.to_string());
        }
        if kind == Kind::None {
            return None;
        }
        let mut c = Some(class);
        while let Some(name_c) = c {
            let class = self.classes.get(name_c)?;
            let map = if kind == Kind::Joint { &class.joint } else { &class.geom };
            if let Some(v) = map.get(name) {
                return Some(v.clone());
            }
            c = class.parent.as_deref();
        }
        None
    }

    /// The class an element takes its defaults from: its own `class`, else the inherited
    /// `childclass`.
    pub(super) fn class_of(&self, node: Node, inherited: &str) -> Result<String, MjcfError> {
        match node.attribute("class") {
            Some(c) if self.classes.contains_key(c) => Ok(c.to_string()),
            Some(c) => Err(self.bad_attr(node, "class", c, "no <default> class has this name")),
            None => Ok(inherited.to_string()),
        }
    }

    pub(super) fn numbers_of(&self, node: Node, name: &str, text: &str) -> Result<Vec<f64>, MjcfError> {
        text.split_whitespace()
            .map(|t| match t.parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(x),
                _ => Err(self.bad_attr(node, name, text, &format!("`{t}` is not a finite number"))),
            })
            .collect()
    }

    /// Between `min` and `max` numbers, if the attribute is present.
    pub(super) fn numbers(
        &self,
        node: Node,
        kind: Kind,
        class: &str,
        name: &str,
        min: usize,
        max: usize,
    ) -> Result<Option<Vec<f64>>, MjcfError> {
        let Some(text) = self.get(node, kind, class, name) else { return Ok(None) };
        let v = self.numbers_of(node, name, &text)?;
        if v.len() < min || v.len() > max {
            let count = if min == max { format!("{min}") } else { format!("{min} to {max}") };
            return Err(self.bad_attr(
                node,
                name,
                &text,
                &format!("expected {count} numbers, found {}", v.len()),
            ));
        }
        Ok(Some(v))
    }

    pub(super) fn vector_c<const N: usize>(
        &self,
        node: Node,
        kind: Kind,
        class: &str,
        name: &str,
    ) -> Result<Option<[f64; N]>, MjcfError> {
        Ok(self.numbers(node, kind, class, name, N, N)?.map(|v| {
            let mut a = [0.0; N];
            a.copy_from_slice(&v);
            a
        }))
    }

    pub(super) fn vector<const N: usize>(
        &self,
        node: Node,
        kind: Kind,
        name: &str,
    ) -> Result<Option<[f64; N]>, MjcfError> {
        self.vector_c::<N>(node, kind, "main", name)
    }

    pub(super) fn scalar_c(
        &self,
        node: Node,
        kind: Kind,
        class: &str,
        name: &str,
    ) -> Result<Option<f64>, MjcfError> {
        Ok(self.vector_c::<1>(node, kind, class, name)?.map(|a| a[0]))
    }

    pub(super) fn scalar(&self, node: Node, kind: Kind, name: &str) -> Result<Option<f64>, MjcfError> {
        self.scalar_c(node, kind, "main", name)
    }

    /// A non-negative scalar.
    pub(super) fn non_negative(
        &self,
        node: Node,
        kind: Kind,
        class: &str,
        name: &str,
    ) -> Result<Option<f64>, MjcfError> {
        match self.scalar_c(node, kind, class, name)? {
            Some(x) if x < 0.0 => Err(self.bad_attr(node, name, &x.to_string(), "must not be negative")),
            x => Ok(x),
        }
    }

    pub(super) fn boolean(&self, node: Node, name: &str, text: &str) -> Result<bool, MjcfError> {
        match text {
            "true" => Ok(true),
            "false" => Ok(false),
            _ => Err(self.bad_attr(node, name, text, "expected `true` or `false`")),
        }
    }

    pub(super) fn enabled(&self, node: Node, name: &str) -> Result<bool, MjcfError> {
        match node.attribute(name) {
            None | Some("enable") => Ok(true),
            Some("disable") => Ok(false),
            Some(t) => Err(self.bad_attr(node, name, t, "expected `enable` or `disable`")),
        }
    }

    pub(super) fn angle(&self, x: f64) -> f64 {
        if self.compiler.radian {
            x
        } else {
            x.to_radians()
        }
    }

    /// Position and orientation of a body, frame, geom or inertial in its parent frame.
    pub(super) fn pose(&self, node: Node, kind: Kind, class: &str) -> Result<Transform, MjcfError> {
        let pos = self.vector_c::<3>(node, kind, class, "pos")?.map(Vec3::from).unwrap_or_else(Vec3::zeros);
        Ok(Transform::new(self.orientation(node, kind, class)?, pos))
    }

    pub(super) fn orientation(&self, node: Node, kind: Kind, class: &str) -> Result<Mat3, MjcfError> {
        let given: Vec<&str> = ["quat", "axisangle", "euler", "xyaxes", "zaxis"]
            .into_iter()
            .filter(|a| node.attribute(*a).is_some())
            .collect();
        if given.len() > 1 {
            return Err(self.invalid(node, &format!("several orientations given ({})", given.join(", "))));
        }
        // An orientation written on the element replaces any in its defaults.
        let which = match given.first() {
            Some(a) => *a,
            None => match ["quat", "axisangle", "euler", "xyaxes", "zaxis"]
                .into_iter()
                .find(|a| self.get(node, kind, class, a).is_some())
            {
                Some(a) => a,
                None => return Ok(Mat3::identity()),
            },
        };
        let zero = |what: &str| {
            let text = self.get(node, kind, class, which).unwrap_or_default();
            self.bad_attr(node, which, &text, &format!("{what} is zero"))
        };
        let r = match which {
            "quat" => {
                let q = self.vector_c::<4>(node, kind, class, "quat")?.unwrap_or([1.0, 0.0, 0.0, 0.0]);
                let q = Quaternion::new(q[0], q[1], q[2], q[3]);
                if q.norm() < 1e-12 {
                    return Err(zero("the quaternion"));
                }
                UnitQuaternion::from_quaternion(q).to_rotation_matrix().into_inner()
            }
            "axisangle" => {
                let a = self.vector_c::<4>(node, kind, class, "axisangle")?.unwrap_or_default();
                let axis = Vec3::new(a[0], a[1], a[2]);
                let axis = axis.try_normalize(1e-12).ok_or_else(|| zero("the axis"))?;
                crate::math::axis_angle(&axis, self.angle(a[3]))
            }
            "euler" => {
                let e = self.vector_c::<3>(node, kind, class, "euler")?.unwrap_or_default();
                let mut q = UnitQuaternion::identity();
                for (k, c) in self.compiler.eulerseq.iter().enumerate() {
                    let axis = match c.to_ascii_lowercase() {
                        b'x' => Vec3::x_axis(),
                        b'y' => Vec3::y_axis(),
                        _ => Vec3::z_axis(),
                    };
                    let r = UnitQuaternion::from_axis_angle(&axis, self.angle(e[k]));
                    q = if c.is_ascii_lowercase() { q * r } else { r * q };
                }
                q.to_rotation_matrix().into_inner()
            }
            "xyaxes" => {
                let a = self.vector_c::<6>(node, kind, class, "xyaxes")?.unwrap_or_default();
                let x = Vec3::new(a[0], a[1], a[2]).try_normalize(1e-12).ok_or_else(|| zero("the x axis"))?;
                let y = Vec3::new(a[3], a[4], a[5]);
                let y = (y - x * x.dot(&y))
                    .try_normalize(1e-12)
                    .ok_or_else(|| zero("the y axis (made orthogonal to x)"))?;
                Mat3::from_columns(&[x, y, x.cross(&y)])
            }
            _ => {
                let z = self.vector_c::<3>(node, kind, class, "zaxis")?.unwrap_or_default();
                let z = Vec3::from(z).try_normalize(1e-12).ok_or_else(|| zero("the z axis"))?;
                z_to(&z)
            }
        };
        Ok(r)
    }
}

/// MuJoCo's `mjuu_z2quat`: the smallest rotation taking +z to the unit vector `z` (a half turn
/// about x when `z` is −z).
pub(super) fn z_to(z: &Vec3) -> Mat3 {
    let cross = Vec3::z().cross(z);
    let s = cross.norm();
    let axis = if s < 1e-10 { Vec3::x() } else { cross / s };
    crate::math::axis_angle(&axis, s.atan2(z.z))
}
