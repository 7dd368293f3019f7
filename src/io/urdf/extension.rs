//! gelenk's `<gelenk>` extension elements: universal, hinge2 and ball-limit data for joints the
//! file declares as standard URDF joints (see the module documentation of [`super`]).

use super::UrdfError;
use crate::math::Vec3;
use crate::model::{BallLimits, Suspension};
use std::collections::HashMap;

/// One `<gelenk joint="…">` element.
pub(super) struct Extension {
    pub kind: String,
    pub axis2: Vec3,
    pub lower2: f64,
    pub upper2: f64,
    pub suspension: Option<Suspension>,
    pub suspension_range: (f64, f64),
    pub ball: Option<BallLimits>,
}

/// The `<gelenk>` children of `<robot>`, by joint name.
pub(super) fn read_extensions(
    doc: &roxmltree::Document,
    file: &str,
) -> Result<HashMap<String, Extension>, UrdfError> {
    let mut out = HashMap::new();
    for node in doc.root_element().children().filter(|n| n.has_tag_name("gelenk")) {
        let joint = node.attribute("joint").unwrap_or_default().to_string();
        let err = |what: String| UrdfError::Joint { file: file.into(), joint: joint.clone(), what };
        if joint.is_empty() {
            return Err(err("a <gelenk> extension element needs a `joint` attribute".into()));
        }
        let number = |name: &str, default: f64| -> Result<f64, UrdfError> {
            match node.attribute(name) {
                None => Ok(default),
                Some(t) => t
                    .trim()
                    .parse::<f64>()
                    .map_err(|_| err(format!("attribute {name}=\"{t}\" is not a number"))),
            }
        };
        let kind = node.attribute("type").unwrap_or_default().to_string();
        if kind != "universal" && kind != "hinge2" && kind != "ball" {
            return Err(err(format!("<gelenk> type \"{kind}\" is not `universal`, `hinge2` or `ball`")));
        }
        let vector = |name: &str, text: &str| -> Result<Vec3, UrdfError> {
            let parts: Vec<f64> = text
                .split_whitespace()
                .map(str::parse)
                .collect::<Result<_, _>>()
                .map_err(|_| err(format!("{name}=\"{text}\" is not three numbers")))?;
            if parts.len() != 3 {
                return Err(err(format!("{name}=\"{text}\" is not three numbers")));
            }
            Ok(Vec3::new(parts[0], parts[1], parts[2]))
        };
        if kind == "ball" {
            let pi = std::f64::consts::PI;
            let ball = BallLimits {
                twist_axis: vector("twist_axis", node.attribute("twist_axis").unwrap_or("0 0 1"))?,
                swing: number("swing", pi)?,
                twist_lower: number("twist_lower", -pi)?,
                twist_upper: number("twist_upper", pi)?,
                angle: number("angle", pi)?,
            };
            let ext = Extension {
                kind,
                axis2: Vec3::zeros(),
                lower2: f64::NEG_INFINITY,
                upper2: f64::INFINITY,
                suspension: None,
                suspension_range: (f64::NEG_INFINITY, f64::INFINITY),
                ball: Some(ball),
            };
            if out.insert(joint.clone(), ext).is_some() {
                return Err(err("two <gelenk> extension elements name this joint".into()));
            }
            continue;
        }
        let axis_text =
            node.attribute("axis2").ok_or_else(|| err("<gelenk> needs an `axis2` attribute".into()))?;
        let axis2 = vector("axis2", axis_text)?;
        let suspension = match node.attribute("suspension_stiffness") {
            Some(_) if kind == "hinge2" => Some(Suspension {
                stiffness: number("suspension_stiffness", 0.0)?,
                damping: number("suspension_damping", 0.0)?,
            }),
            Some(_) => return Err(err("suspension attributes apply to hinge2 joints only".into())),
            None => None,
        };
        let ext = Extension {
            kind,
            axis2,
            lower2: number("lower2", f64::NEG_INFINITY)?,
            upper2: number("upper2", f64::INFINITY)?,
            suspension,
            suspension_range: (
                number("suspension_lower", f64::NEG_INFINITY)?,
                number("suspension_upper", f64::INFINITY)?,
            ),
            ball: None,
        };
        if out.insert(joint.clone(), ext).is_some() {
            return Err(err("two <gelenk> extension elements name this joint".into()));
        }
    }
    Ok(out)
}
