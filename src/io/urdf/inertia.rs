//! A link's inertia: as the file writes it, checked (an inconsistent one is a warning, balanced on
//! request; a singular one is a warning that names [`UrdfOptions::inertia_from_collision`]), or
//! computed from the link's collision shapes with the file's mass and centre of mass.

use super::read::LinkDesc;
use super::{UrdfError, UrdfOptions, UrdfWarning, WarningKind};
use crate::collision::{MissingMeshPolicy, SolidVolume};
use crate::error::CollisionError;
use crate::math::Mat3;
use crate::model::{GeometryRole, RigidInertia};
use std::path::Path;

/// A principal moment at most this fraction of the largest one makes the inertia singular.
const SINGULAR_RATIO: f64 = 1e-9;

/// The inertia of `link` under `options`; warnings are added to `warnings`.
pub(super) fn link_inertia(
    link: &LinkDesc,
    file: &str,
    model_dir: Option<&Path>,
    options: &UrdfOptions,
    warnings: &mut Vec<UrdfWarning>,
) -> Result<RigidInertia, UrdfError> {
    let frame = link.inertial_origin;
    let element = || format!("<link name=\"{}\">", link.name);
    if options.inertia_from_collision && link.mass > 0.0 {
        if let Some(solid) = collision_solid(link, file, model_dir, options)? {
            let inertia = solid.inertia * (link.mass / solid.volume);
            return Ok(RigidInertia::new(link.mass, frame.translation, inertia));
        }
    }
    let [ixx, ixy, ixz, iyy, iyz, izz] = link.inertia;
    let local = Mat3::new(ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz);
    let mut inertia =
        RigidInertia::new(link.mass, frame.translation, frame.rotation * local * frame.rotation.transpose());
    if let Some(issue) = inertia.issue() {
        if options.balance_inertia {
            inertia = inertia.balanced();
        }
        warnings.push(UrdfWarning {
            element: element(),
            line: link.line,
            kind: WarningKind::InconsistentInertia { issue, balanced: options.balance_inertia },
        });
    } else if let Some(moments) = singular_moments(&inertia) {
        let warning = UrdfWarning {
            element: element(),
            line: link.line,
            kind: WarningKind::SingularInertia {
                moments,
                has_collision: link.geometries.iter().any(|g| g.0 == GeometryRole::Collision),
            },
        };
        if options.strict {
            return Err(UrdfError::Parse { file: file.to_string(), message: warning.to_string() });
        }
        warnings.push(warning);
    }
    Ok(inertia)
}

/// The principal moments (ascending, kg·m²) of a link with mass whose rotational inertia is
/// singular: its smallest moment is at most [`SINGULAR_RATIO`] of its largest (a point mass, a
/// rod). `None` for a massless link or a regular inertia.
fn singular_moments(inertia: &RigidInertia) -> Option<[f64; 3]> {
    if inertia.mass <= 0.0 {
        return None;
    }
    let mut moments: Vec<f64> = inertia.inertia_com.symmetric_eigenvalues().iter().copied().collect();
    moments.sort_by(f64::total_cmp);
    (moments[0] <= SINGULAR_RATIO * moments[2]).then_some([moments[0], moments[1], moments[2]])
}

/// The solid of the link's collision shapes, or `None` when it has none with a volume (or, with
/// [`MissingMeshPolicy::Skip`], none that could be read).
fn collision_solid(
    link: &LinkDesc,
    file: &str,
    model_dir: Option<&Path>,
    options: &UrdfOptions,
) -> Result<Option<SolidVolume>, UrdfError> {
    let mut parts = Vec::new();
    for (role, placement, shape) in &link.geometries {
        if *role != GeometryRole::Collision {
            continue;
        }
        match SolidVolume::of_shape(shape, placement, &link.name, model_dir, &options.meshes) {
            Ok(solid) => parts.push(solid),
            Err(CollisionError::MeshNotFound { .. } | CollisionError::MeshUnreadable { .. })
                if options.meshes.missing == MissingMeshPolicy::Skip => {}
            Err(source) => return Err(UrdfError::Collision { file: file.to_string(), source }),
        }
    }
    Ok(SolidVolume::combine(&parts))
}
