//! URDFs from the wild dropped on a plane as PyBullet drops them: PyBullet's random objects write
//! the inertia diag(1, 1, 0), which it never reads (its default computes inertias from the
//! collision shapes): gelenk warns about the singular inertia naming the option, and with
//! `inertia_from_collision` the object falls and rests. Binary STL files whose header begins with
//! `solid` read as binary; a mesh without finite vertices is a typed error.

use gelenk::collision::mesh;
use gelenk::error::CollisionError;
use gelenk::io::urdf::{load_file_with_warnings, UrdfOptions, WarningKind};
use gelenk::math::Vec3;
use gelenk::run::{run, RunOptions};
use std::path::{Path, PathBuf};

fn wild(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/urdf_wild").join(name)
}

fn principal_moments(m: &gelenk::math::Mat3) -> [f64; 3] {
    let mut e: Vec<f64> = m.symmetric_eigenvalues().iter().copied().collect();
    e.sort_by(f64::total_cmp);
    [e[0], e[1], e[2]]
}

#[test]
fn a_singular_inertia_warns_and_names_the_option() {
    let loaded =
        load_file_with_warnings(wild("random_urdfs/009/009.urdf"), &UrdfOptions::floating()).unwrap();
    let warning = loaded
        .warnings
        .iter()
        .find(|w| matches!(w.kind, WarningKind::SingularInertia { has_collision: true, .. }))
        .unwrap_or_else(|| panic!("no singular-inertia warning in {:#?}", loaded.warnings));
    let text = warning.to_string();
    assert!(text.contains("inertia_from_collision") && text.contains("line 2"), "{text}");
    assert!(load_file_with_warnings(wild("random_urdfs/009/009.urdf"), &UrdfOptions::strict()).is_err());
}

#[test]
fn inertia_from_collision_keeps_the_mass_and_fits_the_shape() {
    let options = UrdfOptions { inertia_from_collision: true, ..UrdfOptions::floating() };
    let loaded = load_file_with_warnings(wild("random_urdfs/009/009.urdf"), &options).unwrap();
    assert!(loaded.warnings.is_empty(), "{:#?}", loaded.warnings);
    let inertia = loaded.model.inertia(1);
    assert_eq!(inertia.mass, 0.1);
    assert_eq!(inertia.com(), Vec3::zeros());
    let moments = principal_moments(&inertia.inertia_com());
    // PyBullet 3.2.7 gives (2.76e-4, 7.17e-5, 2.77e-4) kg·m²: the box of the collision shape's
    // bounding box (margin included), times the <inertia_scaling value="3"> of the file's
    // <contact>. gelenk integrates the convex hull and reads no scaling: the same size.
    let pybullet_unscaled = [7.17e-5 / 3.0, 2.76e-4 / 3.0, 2.77e-4 / 3.0];
    for (ours, theirs) in moments.iter().zip(pybullet_unscaled) {
        assert!(*ours > 0.3 * theirs && *ours < 1.5 * theirs, "{moments:?} against {pybullet_unscaled:?}");
    }
}

/// The drop of the benchmark (benches/urdf_collections.py): 5 cm above a plane, 2 s at 1/240 s.
fn drop(urdf: &Path, inertia_from_collision: bool) -> Result<f64, String> {
    let text = format!(
        "name = \"drop\"\n[world]\ndt = {}\nduration = 2.0\n[[ground]]\nkind = \"plane\"\n\
         [[urdf]]\npath = {:?}\nfloating = true\nposition = [0, 0, 0.1]\ninertia_from_collision = {}\n",
        1.0 / 240.0,
        urdf.display().to_string(),
        inertia_from_collision
    );
    let mut scene = gelenk::io::scene::load_str(&text, ".").map_err(|e| e.to_string())?;
    let summary = run(&mut scene, &RunOptions::default(), |_| {}).map_err(|e| e.to_string())?;
    let q = &scene.world.multibody(0).state.q;
    assert!(q.iter().all(|x| x.is_finite()), "{q}");
    assert!(q[2] > 0.0 && q[2] < 0.06, "not resting on the plane: z = {}", q[2]);
    Ok(summary.max_penetration)
}

#[test]
fn a_random_object_drops_with_its_inertia_from_collision() {
    let urdf = wild("random_urdfs/009/009.urdf");
    let penetration = drop(&urdf, true).unwrap();
    assert!(penetration < 0.01, "penetration {penetration} m");
    // As written (diag(1, 1, 0)), the free body has no inertia about z: the step refuses it.
    let e = drop(&urdf, false).unwrap_err();
    assert!(e.contains("mass or inertia"), "{e}");
}

#[test]
fn a_mesh_without_finite_vertices_is_a_typed_error() {
    let path = wild("random_urdfs/168/168.obj");
    match mesh::load("random_obj_168", &path, &Vec3::repeat(0.015)) {
        Err(CollisionError::MeshUnreadable { message, .. }) => {
            assert!(message.contains("144 of its 144 vertices are not finite"), "{message}")
        }
        other => panic!("{other:?}"),
    }
    let options = UrdfOptions { inertia_from_collision: true, ..UrdfOptions::floating() };
    let e = load_file_with_warnings(wild("random_urdfs/168/168.urdf"), &options).unwrap_err();
    assert!(e.to_string().contains("not finite"), "{e}");
}

/// A binary STL of one tetrahedron whose 80-byte header begins with `header`.
fn binary_stl(header: &[u8]) -> Vec<u8> {
    let mut bytes = vec![b' '; 80];
    bytes[..header.len()].copy_from_slice(header);
    let v = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    bytes.extend_from_slice(&(faces.len() as u32).to_le_bytes());
    for f in faces {
        bytes.extend_from_slice(&[0u8; 12]); // normal
        for i in f {
            for c in v[i] {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
        bytes.extend_from_slice(&[0u8; 2]); // attribute byte count
    }
    bytes
}

#[test]
fn binary_stl_beginning_with_solid_reads_as_binary() {
    let dir = std::env::temp_dir().join(format!("gelenk_stl_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // CAD exporters write the part's name after `solid`; a newline in the header and the
    // triangle bytes after it then look like a broken ASCII file.
    let path = dir.join("part.STL");
    std::fs::write(&path, binary_stl(b"solid part\nfacet normal 0 0 0\n")).unwrap();
    let m = mesh::load("part", &path, &Vec3::repeat(2.0)).unwrap();
    assert_eq!((m.vertices.len(), m.triangles.len()), (12, 4));
    assert!(m.vertices.iter().all(|v| v.max() <= 2.0 && v.min() >= 0.0));
    assert!(m.vertices.contains(&Vec3::new(0.0, 0.0, 2.0)));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_scene_starts_joints_within_their_limits() {
    // Kinova's shoulder is limited to [0.82, 5.46] rad: at 0 the limit rows would swing the arm
    // back at erp/h rad/s in the first step.
    let dir = std::env::temp_dir().join(format!("gelenk_limits_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let urdf = r#"<robot name="arm">
      <link name="base"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <link name="upper"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <link name="lower"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="0 1 0"/>
        <limit lower="0.82" upper="5.46" effort="80" velocity="1"/></joint>
      <joint name="elbow" type="revolute"><parent link="upper"/><child link="lower"/><axis xyz="0 1 0"/>
        <origin xyz="0 0 0.5"/><limit lower="-1" upper="1" effort="80" velocity="1"/></joint>
    </robot>"#;
    std::fs::write(dir.join("arm.urdf"), urdf).unwrap();
    let scene = gelenk::io::scene::load_str("[[urdf]]\npath = \"arm.urdf\"\n", &dir).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    let q = &scene.world.multibody(0).state.q;
    assert_eq!(q.as_slice(), &[0.82, 0.0]);
}
