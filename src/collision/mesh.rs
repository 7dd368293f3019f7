//! Mesh files (STL, OBJ, COLLADA) through `mesh-loader`: URI resolution and loading into vertex
//! and triangle buffers in the geometry frame, scale applied.
//!
//! URIs resolve as ROS tools do: `package://PKG/REST` is looked up in each search path as
//! `DIR/PKG/REST` and `DIR/REST`, then in the model's directory and its ancestors (a directory named
//! `PKG` among them is the package root, and `DIR/PKG/REST` and `DIR/REST` are tried for each of
//! the model's directory and its two parents); `file://PATH` and
//! absolute paths are taken as they are; any other path is relative to the model's directory.

use crate::error::CollisionError;
use crate::math::Vec3;
use std::path::{Path, PathBuf};

/// What to do when a mesh file cannot be found or read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MissingMeshPolicy {
    /// Fail with [`CollisionError::MeshNotFound`] or [`CollisionError::MeshUnreadable`].
    #[default]
    Error,
    /// Leave the geometry out and record a warning (see [`crate::collision::CollisionWorld::warnings`]).
    Skip,
}

/// How mesh geometry becomes colliders.
#[derive(Clone, Debug, Default)]
pub struct MeshOptions {
    /// Directories searched for `package://` URIs (each may be a package's parent or the package itself).
    pub search_paths: Vec<PathBuf>,
    /// What happens when a mesh is missing or unreadable.
    pub missing: MissingMeshPolicy,
    /// Keep meshes on moving bodies as exact triangle meshes instead of their convex hulls.
    /// Triangle meshes are hollow and slower; static meshes are always exact.
    pub exact_meshes_on_bodies: bool,
}

/// A triangle soup read from a file, in the geometry frame (m).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshData {
    /// Vertex positions, scale applied (m).
    pub vertices: Vec<Vec3>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
}

/// The candidate file paths for `uri`, most specific first.
pub fn candidate_paths(uri: &str, model_dir: Option<&Path>, search_paths: &[PathBuf]) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Some(rest) = uri.strip_prefix("package://") {
        let (package, inner) = rest.split_once('/').unwrap_or((rest, ""));
        for dir in search_paths {
            out.push(dir.join(package).join(inner));
            out.push(dir.join(inner));
        }
        if let Some(dir) = model_dir {
            for ancestor in dir.ancestors() {
                if ancestor.file_name().is_some_and(|n| n == package) {
                    out.push(ancestor.join(inner));
                }
            }
            for ancestor in dir.ancestors().take(3) {
                // The package as a directory beside the model (PyBullet's xarm/xarm_description,
                // franka_panda/meshes), then the package's contents there.
                out.push(ancestor.join(package).join(inner));
                out.push(ancestor.join(inner));
            }
        }
    } else if let Some(path) = uri.strip_prefix("file://") {
        out.push(PathBuf::from(path));
    } else {
        let path = PathBuf::from(uri);
        match model_dir {
            Some(dir) if path.is_relative() => out.push(dir.join(path)),
            _ => out.push(path),
        }
    }
    out.dedup();
    out
}

/// Resolves `uri` to an existing file.
pub fn resolve(
    link: &str,
    uri: &str,
    model_dir: Option<&Path>,
    search_paths: &[PathBuf],
) -> Result<PathBuf, CollisionError> {
    let candidates = candidate_paths(uri, model_dir, search_paths);
    candidates.iter().find(|p| p.is_file()).cloned().ok_or_else(|| CollisionError::MeshNotFound {
        link: link.to_string(),
        uri: uri.to_string(),
        tried: candidates.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", "),
    })
}

/// Reads a mesh file (STL, OBJ or COLLADA by content and extension), merges its meshes and
/// applies `scale` per axis.
pub fn load(link: &str, path: &Path, scale: &Vec3) -> Result<MeshData, CollisionError> {
    let unreadable = |message: String| CollisionError::MeshUnreadable {
        link: link.to_string(),
        path: path.display().to_string(),
        message,
    };
    let scene = mesh_loader::Loader::default().load(path).map_err(|e| unreadable(e.to_string()))?;
    let mut mesh = MeshData::default();
    for part in &scene.meshes {
        let offset =
            u32::try_from(mesh.vertices.len()).map_err(|_| unreadable("too many vertices".into()))?;
        mesh.vertices.extend(part.vertices.iter().map(|v| {
            Vec3::new(f64::from(v[0]) * scale.x, f64::from(v[1]) * scale.y, f64::from(v[2]) * scale.z)
        }));
        for face in &part.faces {
            if face.iter().any(|&i| i as usize >= part.vertices.len()) {
                return Err(unreadable(format!(
                    "a face refers to a vertex beyond the {}",
                    part.vertices.len()
                )));
            }
            mesh.triangles.push([face[0] + offset, face[1] + offset, face[2] + offset]);
        }
    }
    if mesh.vertices.is_empty() {
        return Err(unreadable("the file holds no vertices".into()));
    }
    if mesh.vertices.iter().any(|v| !v.iter().all(|c| c.is_finite())) {
        return Err(unreadable("a vertex is not finite".into()));
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn package_uris_try_search_paths_then_the_model_tree() {
        let c = candidate_paths(
            "package://robot_description/meshes/a.stl",
            Some(Path::new("/x/robot_description/urdf")),
            &[PathBuf::from("/opt/share")],
        );
        assert_eq!(c[0], PathBuf::from("/opt/share/robot_description/meshes/a.stl"));
        assert_eq!(c[1], PathBuf::from("/opt/share/meshes/a.stl"));
        assert!(c.contains(&PathBuf::from("/x/robot_description/meshes/a.stl")));
        // The package as a directory beside the model (PyBullet's xarm/xarm_description).
        let c = candidate_paths("package://xarm_description/meshes/a.stl", Some(Path::new("/p/xarm")), &[]);
        assert!(c.contains(&PathBuf::from("/p/xarm/xarm_description/meshes/a.stl")), "{c:?}");
    }

    #[test]
    fn relative_and_file_uris() {
        assert_eq!(candidate_paths("m/a.obj", Some(Path::new("/d")), &[]), vec![PathBuf::from("/d/m/a.obj")]);
        assert_eq!(
            candidate_paths("file:///abs/a.dae", Some(Path::new("/d")), &[]),
            vec![PathBuf::from("/abs/a.dae")]
        );
    }
}
