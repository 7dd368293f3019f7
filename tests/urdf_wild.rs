//! URDFs as the wild writes them load leniently with typed warnings naming the element and line,
//! and the strict options refuse them with the same words: ANYmal B (example-robot-data) whose base
//! inertia violates the triangle inequality, PyBullet's biped (an XML declaration after blank lines,
//! `lower="-1.57."`, `<contact_coefficients>`), its cube_no_rotation (inverted limits: no limit),
//! husky (`rpy` on `<axis>`, a roslaunch `$(optenv …)` left in an origin), racecar (`xacro:`
//! namespace, `<sensor>` in `<gazebo>`) and humanoid (a NUL byte after `</robot>`). What leaves no
//! model (not XML, a cycle, a missing link, NaN, an unknown joint type) stays an error. Balancing
//! replaces an inconsistent inertia by the mean of its moments. PyBullet's humanoid, with spherical
//! joints, falls as a ragdoll; a fixed model without joints steps.

use gelenk::io::urdf::{
    load_file_with_warnings, load_str, load_str_with_warnings, UrdfError, UrdfOptions, WarningKind,
};
use gelenk::math::Mat3;
use gelenk::model::{InertiaIssue, Joint, RigidInertia, Shape};
use gelenk::prelude::*;
use gelenk::world::{World, WorldOptions};
use std::path::{Path, PathBuf};

fn wild(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/urdf_wild").join(name)
}

fn pybullet(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("models/pybullet").join(name)
}

/// Loads leniently, expects a warning whose text contains each of `needles` (the same one), and
/// that the strict options refuse the file with a message containing them too.
fn warns_and_strict_refuses(path: &Path, needles: &[&str]) {
    let loaded = load_file_with_warnings(path, &UrdfOptions::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let texts: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    assert!(
        texts.iter().any(|t| needles.iter().all(|n| t.contains(n))),
        "{}: no warning with {needles:?} in {texts:#?}",
        path.display()
    );
    let strict = load_file_with_warnings(path, &UrdfOptions::strict()).map(|l| l.model.nv());
    let message = match strict {
        Ok(nv) => panic!("{}: strict options loaded it (nv = {nv})", path.display()),
        Err(e) => e.to_string(),
    };
    // Strict stops at the first warning (naming its element and line) or at today's model error.
    assert!(
        [" at line ", "joint `", "body `"].iter().any(|n| message.contains(n)),
        "{}: {message}",
        path.display()
    );
}

#[test]
fn files_from_the_wild_load_with_warnings_and_strict_refuses_them() {
    warns_and_strict_refuses(
        &wild("anymal_b.urdf"),
        &["<link name=\"base\"> at line 42", "triangle inequality", "kept as written"],
    );
    warns_and_strict_refuses(&wild("biped2d_pybullet.urdf"), &["document at line 4", "XML declaration"]);
    warns_and_strict_refuses(
        &wild("biped2d_pybullet.urdf"),
        &["<limit> at line 115", "`lower`", "\"-1.57\""],
    );
    warns_and_strict_refuses(
        &wild("biped2d_pybullet.urdf"),
        &["at line 79", "unknown element <contact_coefficients>"],
    );
    warns_and_strict_refuses(&wild("cube_no_rotation.urdf"), &["lower above upper", "no position limit"]);
    warns_and_strict_refuses(
        &pybullet("husky/husky.urdf"),
        &["<axis> at line 144", "unknown attribute `rpy`"],
    );
    warns_and_strict_refuses(&pybullet("husky/husky.urdf"), &["<origin> at line 97", "\"0.19 0 0.149\""]);
    warns_and_strict_refuses(&pybullet("humanoid/humanoid.urdf"), &["NUL bytes after the root element"]);
    // racecar.urdf: the `xacro:` namespace, transmissions and gazebo sensors are read past
    // silently; a <material> inside a <geometry> is not.
    warns_and_strict_refuses(
        &pybullet("racecar/racecar.urdf"),
        &["<geometry> at line 284", "unknown element <material>"],
    );
    let racecar = load_file_with_warnings(pybullet("racecar/racecar.urdf"), &UrdfOptions::default()).unwrap();
    assert_eq!(racecar.model.nv(), 6);
    assert_eq!(racecar.warnings.len(), 1, "{:?}", racecar.warnings);
}

#[test]
fn inverted_limits_mean_no_limit_and_the_axis_rpy_is_ignored() {
    let cube = load_file_with_warnings(wild("cube_no_rotation.urdf"), &UrdfOptions::default()).unwrap();
    let m = &cube.model;
    assert_eq!(m.nv(), 4, "three sliders and a hinge");
    assert!(m.lower_position_limit().iter().all(|x| *x == f64::NEG_INFINITY));
    let inverted =
        cube.warnings.iter().filter(|w| matches!(w.kind, WarningKind::InvertedLimits { .. })).count();
    assert_eq!(inverted, 3, "the continuous joint's limits are not read");
    // husky's wheels turn about y whatever the `rpy` written on their axes.
    let husky = load_file_with_warnings(pybullet("husky/husky.urdf"), &UrdfOptions::default()).unwrap();
    let j = husky.model.joint_id("front_left_wheel").unwrap();
    assert_eq!(*husky.model.joint(j), Joint::Hinge { axis: Vec3::y() });
}

#[test]
fn inconsistent_inertia_is_kept_or_balanced() {
    let text = |izz: &str| {
        format!(
            r#"<robot name="r"><link name="a"/><link name="b"><inertial><mass value="2"/><inertia ixx="1" iyy="1" izz="{izz}" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="j" type="continuous"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint></robot>"#
        )
    };
    // izz = 3 > ixx + iyy: kept as written (so the dynamics agree with Pinocchio's), with a warning.
    let kept = load_str_with_warnings(&text("3"), &UrdfOptions::default()).unwrap();
    assert_eq!(kept.warnings.len(), 1, "{:?}", kept.warnings);
    let WarningKind::InconsistentInertia {
        issue: InertiaIssue::TriangleInequality { moments },
        balanced: false,
    } = kept.warnings[0].kind
    else {
        panic!("{:?}", kept.warnings[0])
    };
    assert_eq!(moments, [1.0, 1.0, 3.0]);
    assert_eq!(kept.warnings[0].line, 1);
    let m = &kept.model;
    assert!((m.inertia(1).inertia_com()[(2, 2)] - 3.0).abs() < 1e-12);
    // balanced: all moments the mean 5/3 (MuJoCo's balanceinertia).
    let options = UrdfOptions { balance_inertia: true, ..Default::default() };
    let balanced = load_str_with_warnings(&text("3"), &options).unwrap();
    assert!(matches!(balanced.warnings[0].kind, WarningKind::InconsistentInertia { balanced: true, .. }));
    let i = balanced.model.inertia(1).inertia_com();
    for k in 0..3 {
        assert!((i[(k, k)] - 5.0 / 3.0).abs() < 1e-12, "{i}");
    }
    // A negative moment (tiago's wheels have -3.5e-8 of 9.1e-8): kept, or balanced to the mean of
    // the non-negative ones.
    let negative = RigidInertia::new(1.0, Vec3::zeros(), Mat3::from_diagonal(&Vec3::new(-1.0, 2.0, 2.5)));
    assert!(matches!(negative.issue(), Some(InertiaIssue::NotPositive { .. })));
    assert_eq!(negative.balanced().inertia_com, Mat3::from_diagonal_element(1.5));
    assert!(negative.balanced().issue().is_none());
    // strict: today's model errors.
    let e = load_str(&text("3"), &UrdfOptions::strict()).unwrap_err();
    assert!(matches!(e, UrdfError::Model { .. }) && e.to_string().contains("triangle"), "{e}");
    // consistent inertias give no warning
    assert!(load_str_with_warnings(&text("1.5"), &UrdfOptions::default()).unwrap().warnings.is_empty());
}

#[test]
fn unusable_files_stay_errors_in_the_lenient_mode() {
    let link = |n: &str| format!(r#"<link name="{n}"/>"#);
    let joint = |n: &str, kind: &str, p: &str, c: &str, extra: &str| {
        format!(r#"<joint name="{n}" type="{kind}"><parent link="{p}"/><child link="{c}"/>{extra}</joint>"#)
    };
    let robot = |body: String| format!(r#"<robot name="r">{body}</robot>"#);
    let lenient = UrdfOptions::default();
    for (text, needle) in [
        ("not XML".to_string(), "not a valid URDF"),
        (
            robot(format!(
                "{}{}{}{}",
                link("a"),
                link("b"),
                joint("j", "revolute", "a", "b", ""),
                joint("k", "revolute", "b", "a", "")
            )),
            "cycle",
        ),
        (robot(format!("{}{}", link("a"), joint("j", "revolute", "a", "ghost", ""))), "ghost"),
        (
            robot(format!("{}{}{}", link("a"), link("b"), joint("j", "telescopic", "a", "b", ""))),
            "telescopic",
        ),
        (
            robot(format!(
                "{}{}{}",
                link("a"),
                link("b"),
                joint("j", "revolute", "a", "b", r#"<limit lower="nan" upper="1"/>"#)
            )),
            "lower must not exceed upper",
        ),
        (
            robot(format!(
                "{}{}{}",
                link("a"),
                link("b"),
                joint("j", "revolute", "a", "b", r#"<origin xyz="${x} 0 0"/>"#)
            )),
            "is not 3 numbers",
        ),
        (
            robot(format!(
                r#"{}<link name="b"><inertial><mass value="-1"/></inertial></link>{}"#,
                link("a"),
                joint("j", "revolute", "a", "b", "")
            )),
            "mass",
        ),
    ] {
        let e = load_str(&text, &lenient).map(|m| m.nv()).unwrap_err().to_string();
        assert!(e.contains(needle), "{needle}: {e}");
    }
}

fn ground_world() -> World {
    let mut world = World::new(WorldOptions::default());
    world.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    world
}

#[test]
fn pybullet_humanoid_with_spherical_joints_falls_as_a_ragdoll() {
    let model =
        gelenk::io::urdf::load_file(pybullet("humanoid/humanoid.urdf"), &UrdfOptions::floating()).unwrap();
    let balls = (1..model.nbodies()).filter(|&j| *model.joint(j) == Joint::Ball).count();
    assert_eq!(balls, 8, "chest, neck, hips, ankles, shoulders: spherical");
    let mut world = ground_world();
    let index = world.add_multibody("humanoid", model, &Default::default()).unwrap();
    // PyBullet's humanoid is y-up: turn it z-up and stand it with its feet above the ground.
    let q = &mut world.multibody_mut(index).state.q;
    let up = Transform::from_xyz_rpy([0.0, 0.0, 3.7], [std::f64::consts::FRAC_PI_2, 0.0, 0.0]);
    q.rows_mut(0, 3).copy_from(&up.translation);
    q.rows_mut(3, 4).copy_from_slice(&up.quaternion_xyzw());
    let height = |world: &mut World| {
        let mb = world.multibody(index);
        let (model, q) = (mb.model().clone(), mb.state.q.clone());
        let mut data = Data::new(&model);
        gelenk::algorithms::center_of_mass(&model, &mut data, &q).unwrap().z
    };
    let start = height(&mut world);
    let mut deepest: f64 = 0.0;
    for _ in 0..(3.0 / world.options().dt) as usize {
        world.step().unwrap();
        deepest = world.contacts().iter().fold(deepest, |d, c| d.max(-c.distance));
    }
    let end = height(&mut world);
    println!("centre of mass {start} m -> {end} m; deepest penetration {deepest} m");
    assert!(end < 0.5 * start, "the ragdoll did not fall: {start} m -> {end} m");
    assert!(end > 0.0 && deepest < 0.01, "through the ground: {end} m, penetration {deepest} m");
}

#[test]
fn a_fixed_model_without_joints_steps() {
    let text = r#"<robot name="table"><link name="top"><collision><geometry><box size="1 1 0.1"/></geometry></collision></link></robot>"#;
    let model = load_str(text, &UrdfOptions::default()).unwrap();
    assert_eq!(model.nv(), 0);
    let mut world = ground_world();
    world.add_multibody("table", model, &Default::default()).unwrap();
    for _ in 0..100 {
        world.step().unwrap();
    }
}
