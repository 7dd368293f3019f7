//! URDF files become the models they describe: the right dimensions, fixed joints fused with their frames still addressable at the right poses, inertias rotated by the inertial origin, limits and joint dynamics carried over, and gelenk's extension giving universal and hinge2 joints with the documented q layout.

mod common;

use gelenk::io::urdf::{load_file, load_str, UrdfOptions};
use gelenk::math::{exp3, Mat3};
use gelenk::model::FrameKind;
use gelenk::prelude::*;
use nalgebra::DVector;
use rand::rngs::StdRng;
use rand::SeedableRng;
use std::f64::consts::PI;

fn model_path(name: &str) -> std::path::PathBuf {
    common::models_dir().join(name)
}

fn load(name: &str, floating: bool) -> Model {
    let options = if floating { UrdfOptions::floating() } else { UrdfOptions::default() };
    load_file(model_path(name), &options).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn assert_pose_eq(got: &Transform, want: &Transform, tol: f64, what: &str) {
    let e = (got.rotation - want.rotation).amax().max((got.translation - want.translation).amax());
    assert!(e <= tol, "{what}: poses differ by {e:e}\n got  {got:?}\n want {want:?}");
}

fn xyz_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> Transform {
    Transform::from_xyz_rpy(xyz, rpy)
}

/// Sum of the link masses written in a URDF file, read with the standard parser, and the mass of
/// the links welded to the root by fixed joints (root included).
fn urdf_masses(name: &str) -> (f64, f64) {
    let robot = urdf_rs::read_file(model_path(name)).unwrap();
    let total = robot.links.iter().map(|l| l.inertial.mass.value).sum();
    let children: Vec<&str> = robot.joints.iter().map(|j| j.child.link.as_str()).collect();
    let root = robot.links.iter().find(|l| !children.contains(&l.name.as_str())).unwrap();
    let mut welded = vec![root.name.as_str()];
    let mut k = 0;
    while k < welded.len() {
        for j in &robot.joints {
            if j.parent.link == welded[k] && j.joint_type == urdf_rs::JointType::Fixed {
                welded.push(j.child.link.as_str());
            }
        }
        k += 1;
    }
    let welded_mass =
        robot.links.iter().filter(|l| welded.contains(&l.name.as_str())).map(|l| l.inertial.mass.value).sum();
    (total, welded_mass)
}

#[test]
fn robot_models_load_with_their_dimensions() {
    for (file, floating, nq, nv, nbodies) in [
        ("panda.urdf", false, 9, 9, 10),
        ("ur5_robot.urdf", false, 6, 6, 7),
        ("solo12.urdf", true, 19, 18, 14),
        ("solo12.urdf", false, 12, 12, 13),
        ("double_pendulum_simple.urdf", false, 2, 2, 3),
    ] {
        let m = load(file, floating);
        assert_eq!((m.nq(), m.nv(), m.nbodies()), (nq, nv, nbodies), "{file} floating={floating}");
        // no fixed joint survives
        assert!((1..m.nbodies()).all(|i| m.joint(i).kind_name() != "fixed"), "{file}");
        // the totals: a floating base keeps every link; a fixed base welds the root link to the world
        let (total, welded) = urdf_masses(file);
        let want = if floating { total } else { total - welded };
        // the welded links' mass is fused into the universe, not lost
        let universe = if floating { 0.0 } else { welded };
        assert!((m.inertia(0).mass - universe).abs() < 1e-12, "{file}: universe mass {}", m.inertia(0).mass);
        assert!((m.total_mass() - want).abs() < 1e-9 * total, "{file}: mass {} vs {want}", m.total_mass());
    }
}

#[test]
fn floating_base_layout_and_joint_order() {
    let m = load("solo12.urdf", true);
    let root = m.joint_id("root_joint").unwrap();
    assert_eq!(root, 1);
    assert_eq!(*m.joint(root), Joint::Free);
    assert_eq!((m.idx_q(root), m.idx_v(root)), (0, 0));
    // depth-first in file order: FL, FR, HL, HR legs, each HAA, HFE, KFE
    let mut k = 0;
    for leg in ["FL", "FR", "HL", "HR"] {
        for j in ["HAA", "HFE", "KFE"] {
            let id = m.joint_id(&format!("{leg}_{j}")).unwrap();
            assert_eq!((m.idx_q(id), m.idx_v(id)), (7 + k, 6 + k), "{leg}_{j}");
            k += 1;
        }
    }
    // the name of the root joint is an option
    let options =
        UrdfOptions { floating_base: true, root_joint_name: "base_free".into(), ..Default::default() };
    let m = load_file(model_path("solo12.urdf"), &options).unwrap();
    assert_eq!(m.joint_id("base_free"), Some(1));
    assert_eq!(m.joint_id("root_joint"), None);
    // the neutral configuration of the free joint is the identity quaternion (x, y, z, w)
    let q = m.neutral_configuration();
    assert_eq!(q.rows(0, 7).as_slice(), &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
}

#[test]
fn panda_fixed_frames_are_addressable_at_the_composed_pose() {
    let m = load("panda.urdf", false);
    let mut data = Data::new(&m);
    let j7 = m.joint_id("panda_joint7").unwrap();
    let mut rng = StdRng::seed_from_u64(3);
    for _ in 0..3 {
        let q = m.random_configuration(&mut rng);
        forward_kinematics(&m, &mut data, &q).unwrap();
        let x7 = data.x_wb[j7];
        let link8 = x7 * xyz_rpy([0.0, 0.0, 0.107], [0.0; 3]);
        let hand = link8 * xyz_rpy([0.0; 3], [0.0, 0.0, -PI / 4.0]);
        let tcp = hand * xyz_rpy([0.0, 0.0, 0.1034], [0.0; 3]);
        for (name, want) in [
            ("panda_link8", link8),
            ("panda_joint8", link8),
            ("panda_hand", hand),
            ("panda_hand_joint", hand),
            ("panda_hand_tcp", tcp),
            ("panda_hand_tcp_joint", tcp),
        ] {
            let f = m.frame_id(name).unwrap_or_else(|| panic!("no frame {name}"));
            assert_eq!(m.frames()[f].body, j7, "{name} is attached to panda_link7");
            let got = frame_placement(&m, &data, f).unwrap();
            assert_pose_eq(&got, &want, 1e-12, name);
        }
        // a link frame is found before a joint frame of the same pose, and kinds are recorded
        assert_eq!(m.frames()[m.frame_id("panda_hand").unwrap()].kind, FrameKind::Body);
        assert_eq!(m.frames()[m.frame_id("panda_hand_joint").unwrap()].kind, FrameKind::Joint);
        // the fingers hang from the fused hand: their joint placement composes the fixed chain
        let finger = m.joint_id("panda_finger_joint1").unwrap();
        assert_eq!(m.parent(finger), j7);
        let want = xyz_rpy([0.0, 0.0, 0.107], [0.0; 3])
            * xyz_rpy([0.0; 3], [0.0, 0.0, -PI / 4.0])
            * xyz_rpy([0.0, 0.0, 0.0584], [0.0; 3]);
        assert_pose_eq(m.placement(finger), &want, 1e-12, "finger placement");
    }
    // the root link is welded to the world
    let f = m.frame_id("panda_link0").unwrap();
    assert_eq!(m.frames()[f].body, 0);
}

#[test]
fn ur5_and_solo12_fixed_frames() {
    let m = load("ur5_robot.urdf", false);
    let mut data = Data::new(&m);
    let q = DVector::from_vec(vec![0.3, -1.1, 0.7, 2.0, -0.4, 1.3]);
    forward_kinematics(&m, &mut data, &q).unwrap();
    let w3 = data.x_wb[m.joint_id("wrist_3_joint").unwrap()];
    let tool0 = frame_placement(&m, &data, m.frame_id("tool0").unwrap()).unwrap();
    assert_pose_eq(&tool0, &(w3 * xyz_rpy([0.0, 0.0823, 0.0], [-PI / 2.0, 0.0, 0.0])), 1e-10, "tool0");
    let ee = frame_placement(&m, &data, m.frame_id("ee_link").unwrap()).unwrap();
    assert_pose_eq(&ee, &(w3 * xyz_rpy([0.0, 0.0823, 0.0], [0.0, 0.0, PI / 2.0])), 1e-10, "ee_link");
    for name in ["world", "base_link", "base", "world_joint"] {
        let f = m.frame_id(name).unwrap_or_else(|| panic!("no frame {name}"));
        assert_eq!(m.frames()[f].body, 0, "{name} is welded to the universe");
    }

    let m = load("solo12.urdf", true);
    let mut data = Data::new(&m);
    let mut rng = StdRng::seed_from_u64(11);
    let q = m.random_configuration(&mut rng);
    forward_kinematics(&m, &mut data, &q).unwrap();
    for (leg, y) in [("FL", 0.008), ("FR", -0.008), ("HL", 0.008), ("HR", -0.008)] {
        let kfe = m.joint_id(&format!("{leg}_KFE")).unwrap();
        let want = data.x_wb[kfe] * xyz_rpy([0.0, y, -0.16], [0.0; 3]);
        for name in [format!("{leg}_FOOT"), format!("{leg}_ANKLE")] {
            let f = m.frame_id(&name).unwrap();
            assert_eq!(m.frames()[f].body, kfe);
            assert_pose_eq(&frame_placement(&m, &data, f).unwrap(), &want, 1e-12, &name);
        }
    }
}

#[test]
fn robot_model_limits_and_joint_dynamics() {
    let m = load("panda.urdf", false);
    let j4 = m.joint_id("panda_joint4").unwrap();
    let (iq, iv) = (m.idx_q(j4), m.idx_v(j4));
    assert_eq!(m.lower_position_limit()[iq], -3.0718);
    assert_eq!(m.upper_position_limit()[iq], -0.0698);
    assert_eq!(m.velocity_limit()[iv], 2.175);
    assert_eq!(m.effort_limit()[iv], 87.0);
    assert_eq!(m.damping()[iv], 0.003);
    assert_eq!(m.friction()[iv], 0.0);
    let f1 = m.joint_id("panda_finger_joint1").unwrap();
    assert_eq!(*m.joint(f1), Joint::Slider { axis: Vec3::y() });
    assert_eq!((m.lower_position_limit()[m.idx_q(f1)], m.upper_position_limit()[m.idx_q(f1)]), (0.0, 0.04));
    assert_eq!(m.damping()[m.idx_v(f1)], 0.3);
    let f2 = m.joint_id("panda_finger_joint2").unwrap();
    assert_eq!(*m.joint(f2), Joint::Slider { axis: -Vec3::y() });
    // random configurations respect the limits
    let mut rng = StdRng::seed_from_u64(5);
    for _ in 0..20 {
        let q = m.random_configuration(&mut rng);
        for k in 0..m.nq() {
            assert!(
                q[k] >= m.lower_position_limit()[k] && q[k] <= m.upper_position_limit()[k],
                "q[{k}] = {}",
                q[k]
            );
        }
    }

    // double pendulum: lower = upper = 0 and velocity = effort = 0 mean "not given"
    let m = load("double_pendulum_simple.urdf", false);
    for k in 0..2 {
        assert_eq!(m.lower_position_limit()[k], f64::NEG_INFINITY);
        assert_eq!(m.upper_position_limit()[k], f64::INFINITY);
        assert_eq!(m.velocity_limit()[k], f64::INFINITY);
        assert_eq!(m.effort_limit()[k], f64::INFINITY);
        assert_eq!(m.damping()[k], 0.05);
    }
    // the massless end-effector link is fused and addressable
    let f = m.frame_id("link3").unwrap();
    assert_eq!(m.frames()[f].body, m.joint_id("joint2").unwrap());
}

const INERTIAL: &str = r#"<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.02" izz="0.025" ixy="0" ixz="0" iyz="0"/></inertial>"#;

fn robot(body: &str) -> String {
    format!(r#"<?xml version="1.0"?><robot name="test">{body}</robot>"#)
}

fn load_text(text: &str) -> Model {
    load_str(text, &UrdfOptions::default()).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

#[test]
fn links_without_inertial_massless_intermediates_and_tiny_inertias_load() {
    let text = robot(&format!(
        r#"<link name="base"/>
        <link name="mid"/>
        <link name="tip">{INERTIAL}</link>
        <link name="speck"><inertial><mass value="1e-9"/><inertia ixx="1e-15" iyy="2e-15" izz="2.5e-15" ixy="0" ixz="0" iyz="0"/></inertial></link>
        <joint name="j1" type="continuous"><parent link="base"/><child link="mid"/><axis xyz="0 0 1"/></joint>
        <joint name="j2" type="continuous"><parent link="mid"/><child link="tip"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/></joint>
        <joint name="j3" type="revolute"><parent link="tip"/><child link="speck"/><origin xyz="0 0 0.2"/><axis xyz="1 0 0"/>
          <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"#
    ));
    let m = load_text(&text);
    assert_eq!(m.nv(), 3);
    assert_eq!(m.inertia(m.joint_id("j1").unwrap()).mass, 0.0);
    assert!(m.massless_subtrees().is_empty(), "{:?}", m.massless_subtrees());
    let mut data = Data::new(&m);
    let q = DVector::from_vec(vec![0.4, -0.2, 0.3]);
    let v = DVector::from_vec(vec![1.0, -0.5, 2.0]);
    let tau = DVector::from_vec(vec![0.1, 0.0, 0.0]);
    let a = aba(&m, &mut data, &q, &v, &tau).unwrap().clone();
    assert!(a.iter().all(|x| x.is_finite()), "{a}");
    let mass = crba(&m, &mut data, &q).unwrap().clone();
    assert!(mass.cholesky().is_some());
}

#[test]
fn unnormalized_axes_are_normalized() {
    let make = |axis: &str| {
        robot(&format!(
            r#"<link name="a">{INERTIAL}</link><link name="b">{INERTIAL}</link><link name="c">{INERTIAL}</link>
            <joint name="h" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 0 0.5" rpy="0.1 0.2 0.3"/><axis xyz="{axis}"/>
              <limit lower="-2" upper="2" effort="5" velocity="3"/></joint>
            <joint name="s" type="prismatic"><parent link="b"/><child link="c"/><origin xyz="0.2 0 0"/><axis xyz="{axis}"/>
              <limit lower="-0.1" upper="0.1" effort="5" velocity="3"/></joint>"#
        ))
    };
    let unit = load_text(&make("0.6 0 0.8"));
    let long = load_text(&make("3 0 4"));
    let axis = Vec3::new(0.6, 0.0, 0.8);
    for (name, want) in [("h", Joint::Hinge { axis }), ("s", Joint::Slider { axis })] {
        let j = *long.joint(long.joint_id(name).unwrap());
        match (j, want) {
            (Joint::Hinge { axis: a }, Joint::Hinge { axis: b })
            | (Joint::Slider { axis: a }, Joint::Slider { axis: b }) => {
                assert!((a - b).norm() < 1e-15, "{name}: axis {a:?}")
            }
            _ => panic!("{name}: {j:?}"),
        }
    }
    let q = DVector::from_vec(vec![0.7, 0.05]);
    let mut d1 = Data::new(&unit);
    let mut d2 = Data::new(&long);
    let m1 = crba(&unit, &mut d1, &q).unwrap().clone();
    let m2 = crba(&long, &mut d2, &q).unwrap().clone();
    assert!((m1 - m2).amax() < 1e-14);
}

/// `{:e}` text of a number with every digit.
fn num(x: f64) -> String {
    format!("{x:.17e}")
}

#[test]
fn inertial_origin_rotation_applies_to_the_inertia() {
    let (rpy, xyz) = ([0.3, -0.5, 1.1], [0.1, -0.2, 0.3]);
    let diag = Vec3::new(0.1, 0.2, 0.25);
    let r = Transform::from_xyz_rpy([0.0; 3], rpy).rotation;
    let full = r * Mat3::from_diagonal(&diag) * r.transpose();
    let link = |inertial: String| {
        robot(&format!(
            r#"<link name="base"/><link name="arm">{inertial}</link>
            <joint name="j" type="continuous"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/></joint>"#
        ))
    };
    let rotated = link(format!(
        r#"<inertial><origin xyz="{} {} {}" rpy="{} {} {}"/><mass value="2"/>
           <inertia ixx="{}" iyy="{}" izz="{}" ixy="0" ixz="0" iyz="0"/></inertial>"#,
        xyz[0], xyz[1], xyz[2], rpy[0], rpy[1], rpy[2], diag.x, diag.y, diag.z
    ));
    let given = link(format!(
        r#"<inertial><origin xyz="{} {} {}"/><mass value="2"/>
           <inertia ixx="{}" iyy="{}" izz="{}" ixy="{}" ixz="{}" iyz="{}"/></inertial>"#,
        xyz[0],
        xyz[1],
        xyz[2],
        num(full[(0, 0)]),
        num(full[(1, 1)]),
        num(full[(2, 2)]),
        num(full[(0, 1)]),
        num(full[(0, 2)]),
        num(full[(1, 2)])
    ));
    let unrotated = link(format!(
        r#"<inertial><origin xyz="{} {} {}"/><mass value="2"/>
           <inertia ixx="{}" iyy="{}" izz="{}" ixy="0" ixz="0" iyz="0"/></inertial>"#,
        xyz[0], xyz[1], xyz[2], diag.x, diag.y, diag.z
    ));
    let (a, b, c) = (load_text(&rotated), load_text(&given), load_text(&unrotated));
    let (ia, ib, ic) = (a.inertia(1), b.inertia(1), c.inertia(1));
    assert_eq!(ia.mass, 2.0);
    assert!((ia.com() - Vec3::new(0.1, -0.2, 0.3)).norm() < 1e-15);
    assert!((ia.inertia_com() - full).amax() < 1e-12, "{:?} vs {full:?}", ia.inertia_com());
    assert!((ia.inertia_origin - ib.inertia_origin).amax() < 1e-12);
    assert!((ia.first_moment - ib.first_moment).amax() < 1e-15);
    assert!((ia.inertia_origin - ic.inertia_origin).amax() > 1e-3, "the rotation was ignored");
}

#[test]
fn limits_damping_friction_and_continuous_joints() {
    let text = robot(&format!(
        r#"<link name="a">{INERTIAL}</link><link name="b">{INERTIAL}</link><link name="c">{INERTIAL}</link><link name="d">{INERTIAL}</link>
        <joint name="rev" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
          <limit lower="-1.5" upper="2.5" effort="10" velocity="3"/><dynamics damping="0.5" friction="0.2"/></joint>
        <joint name="pri" type="prismatic"><parent link="b"/><child link="c"/><axis xyz="1 0 0"/>
          <limit lower="-0.1" upper="0.3" effort="100" velocity="0.5"/><dynamics damping="7"/></joint>
        <joint name="cont" type="continuous"><parent link="c"/><child link="d"/><axis xyz="0 1 0"/>
          <limit lower="-1" upper="1" effort="4" velocity="6"/><dynamics friction="0.9"/></joint>"#
    ));
    let m = load_text(&text);
    let expect = [
        ("rev", -1.5, 2.5, 3.0, 10.0, 0.5, 0.2),
        ("pri", -0.1, 0.3, 0.5, 100.0, 7.0, 0.0),
        ("cont", f64::NEG_INFINITY, f64::INFINITY, 6.0, 4.0, 0.0, 0.9),
    ];
    for (name, lo, hi, vel, eff, damp, fric) in expect {
        let id = m.joint_id(name).unwrap();
        let (iq, iv) = (m.idx_q(id), m.idx_v(id));
        assert_eq!(m.joint(id).nq(), 1, "{name}: a continuous joint is stored as one angle");
        assert_eq!(m.lower_position_limit()[iq], lo, "{name} lower");
        assert_eq!(m.upper_position_limit()[iq], hi, "{name} upper");
        assert_eq!(m.velocity_limit()[iv], vel, "{name} velocity");
        assert_eq!(m.effort_limit()[iv], eff, "{name} effort");
        assert_eq!(m.damping()[iv], damp, "{name} damping");
        assert_eq!(m.friction()[iv], fric, "{name} friction");
    }
    assert_eq!(m.joint(m.joint_id("cont").unwrap()).kind_name(), "hinge");
}

const EXTENSION_ROBOT: &str = r#"<?xml version="1.0"?>
<robot name="vehicle">
  <link name="chassis"><inertial><mass value="10"/><inertia ixx="1" iyy="2" izz="2.5" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="thigh"><inertial><origin xyz="0 0 -0.2"/><mass value="2"/><inertia ixx="0.05" iyy="0.05" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="wheel_fl"><inertial><mass value="1"/><inertia ixx="0.02" iyy="0.04" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="wheel_fr"><inertial><mass value="1"/><inertia ixx="0.02" iyy="0.04" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="hip" type="continuous">
    <parent link="chassis"/> <child link="thigh"/> <origin xyz="0 0 -0.1" rpy="0 0 0.3"/> <axis xyz="1 0 0"/>
  </joint>
  <joint name="front_left" type="revolute">
    <parent link="chassis"/> <child link="wheel_fl"/> <origin xyz="0.5 0.4 0" rpy="0.1 0 0"/> <axis xyz="0 0 1"/>
    <limit lower="-0.6" upper="0.6" effort="50" velocity="5"/>
  </joint>
  <joint name="front_right" type="revolute">
    <parent link="chassis"/> <child link="wheel_fr"/> <origin xyz="0.5 -0.4 0"/> <axis xyz="0 0 2"/>
    <limit lower="-0.5" upper="0.5" effort="50" velocity="5"/>
  </joint>
  <gelenk joint="hip" type="universal" axis2="0 1 0" lower2="-1" upper2="1"/>
  <gelenk joint="front_left" type="hinge2" axis2="0 1 0"
          suspension_stiffness="20000" suspension_damping="800"
          suspension_lower="-0.1" suspension_upper="0.1"/>
  <gelenk joint="front_right" type="hinge2" axis2="0 3 0" lower2="-10" upper2="10"/>
</robot>"#;

#[test]
fn gelenk_extension_gives_universal_and_hinge2_joints() {
    let m = load_text(EXTENSION_ROBOT);
    assert_eq!((m.nq(), m.nv()), (2 + 3 + 2, 7));
    let hip = m.joint_id("hip").unwrap();
    let fl = m.joint_id("front_left").unwrap();
    let fr = m.joint_id("front_right").unwrap();
    assert_eq!(*m.joint(hip), Joint::Universal { axis1: Vec3::x(), axis2: Vec3::y() });
    assert_eq!(
        *m.joint(fl),
        Joint::Hinge2 {
            axis1: Vec3::z(),
            axis2: Vec3::y(),
            suspension: Some(Suspension { stiffness: 20000.0, damping: 800.0 })
        }
    );
    assert_eq!(*m.joint(fr), Joint::Hinge2 { axis1: Vec3::z(), axis2: Vec3::y(), suspension: None });
    // layout in file order: hip [θ1, θ2], front_left [s, θ1, θ2], front_right [θ1, θ2]
    assert_eq!((m.idx_q(hip), m.idx_q(fl), m.idx_q(fr)), (0, 2, 5));
    let lo = m.lower_position_limit().as_slice().to_vec();
    let hi = m.upper_position_limit().as_slice().to_vec();
    let inf = f64::INFINITY;
    assert_eq!(lo, vec![-inf, -1.0, -0.1, -0.6, -inf, -0.5, -10.0]);
    assert_eq!(hi, vec![inf, 1.0, 0.1, 0.6, inf, 0.5, 10.0]);
    for k in 2..7 {
        assert_eq!((m.velocity_limit()[k], m.effort_limit()[k]), (5.0, 50.0), "dof {k}");
    }

    // kinematics follow the documented q layout: R = exp(θ1 a1) exp(θ2 a2), travel s a1
    let mut data = Data::new(&m);
    let q = DVector::from_vec(vec![0.4, -0.7, 0.05, 0.3, 1.9, -0.2, 2.5]);
    forward_kinematics(&m, &mut data, &q).unwrap();
    let pose = |xyz: [f64; 3], rpy: [f64; 3], a1: Vec3, a2: Vec3, s: f64, t1: f64, t2: f64| {
        xyz_rpy(xyz, rpy) * Transform::new(exp3(&(a1 * t1)) * exp3(&(a2 * t2)), a1 * s)
    };
    let (x, y, z) = (Vec3::x(), Vec3::y(), Vec3::z());
    assert_pose_eq(
        &data.x_wb[hip],
        &pose([0.0, 0.0, -0.1], [0.0, 0.0, 0.3], x, y, 0.0, 0.4, -0.7),
        1e-12,
        "hip",
    );
    assert_pose_eq(
        &data.x_wb[fl],
        &pose([0.5, 0.4, 0.0], [0.1, 0.0, 0.0], z, y, 0.05, 0.3, 1.9),
        1e-12,
        "front_left",
    );
    assert_pose_eq(
        &data.x_wb[fr],
        &pose([0.5, -0.4, 0.0], [0.0; 3], z, y, 0.0, -0.2, 2.5),
        1e-12,
        "front_right",
    );

    // suspension damping defaults to 0
    let text = EXTENSION_ROBOT.replace(r#" suspension_damping="800""#, "");
    let m2 = load_text(&text);
    assert_eq!(
        *m2.joint(m2.joint_id("front_left").unwrap()),
        Joint::Hinge2 {
            axis1: Vec3::z(),
            axis2: Vec3::y(),
            suspension: Some(Suspension { stiffness: 20000.0, damping: 0.0 })
        }
    );
}

#[test]
fn extension_file_is_still_a_standard_urdf() {
    let robot =
        urdf_rs::read_from_string(EXTENSION_ROBOT).expect("the standard parser accepts the extension");
    assert_eq!(robot.joints.len(), 3);
    assert_eq!(robot.links.len(), 4);
    // Without the extension elements the joints are plain hinges about the first axis.
    let plain: String = EXTENSION_ROBOT
        .lines()
        .filter(|l| !l.contains("<gelenk") && !l.trim_start().starts_with("suspension_"))
        .collect::<Vec<_>>()
        .join("\n");
    assert!(!plain.contains("gelenk"), "{plain}");
    let m = load_text(&plain);
    assert_eq!((m.nq(), m.nv()), (3, 3));
    for name in ["hip", "front_left", "front_right"] {
        assert_eq!(m.joint(m.joint_id(name).unwrap()).kind_name(), "hinge", "{name}");
    }
}

fn planar_robot(normal: &str) -> String {
    robot(&format!(
        r#"<link name="ground"/>
        <link name="puck"><inertial><origin xyz="0.05 0.02 -0.03" rpy="0.2 0.1 0"/><mass value="3"/>
          <inertia ixx="0.04" iyy="0.05" izz="0.06" ixy="0" ixz="0" iyz="0"/></inertial></link>
        <joint name="slide" type="planar"><parent link="ground"/><child link="puck"/>
          <origin xyz="0.1 0.2 0.3" rpy="0.3 -0.2 0.5"/><axis xyz="{normal}"/></joint>"#
    ))
}

/// Kinetic energy of the link `name` from its Local frame velocity `[v_o; ω]` and its URDF mass
/// properties (mass `m`, centre of mass `c` and inertia about it `ic`, link axes).
fn link_kinetic_energy(
    m: &Model,
    data: &mut Data,
    q: &DVector<f64>,
    v: &DVector<f64>,
    name: &str,
    (mass, c, ic): (f64, Vec3, Mat3),
) -> f64 {
    compute_joint_jacobians(m, data, q).unwrap();
    let f = m.frame_id(name).unwrap();
    let tw = frame_jacobian(m, data, f, JacobianFrame::Local).unwrap() * v;
    let (vo, w) = (Vec3::new(tw[0], tw[1], tw[2]), Vec3::new(tw[3], tw[4], tw[5]));
    let vc = vo + w.cross(&c);
    0.5 * mass * vc.norm_squared() + 0.5 * w.dot(&(ic * w))
}

#[test]
fn planar_joint_with_a_non_z_normal() {
    let origin = xyz_rpy([0.1, 0.2, 0.3], [0.3, -0.2, 0.5]);
    let puck_r = Transform::from_xyz_rpy([0.0; 3], [0.2, 0.1, 0.0]).rotation;
    let ic = puck_r * Mat3::from_diagonal(&Vec3::new(0.04, 0.05, 0.06)) * puck_r.transpose();
    let c = Vec3::new(0.05, 0.02, -0.03);
    for normal in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, -2.0, 0.0), Vec3::new(1.0, 2.0, -0.5), Vec3::z()]
    {
        let text = planar_robot(&format!("{} {} {}", normal.x, normal.y, normal.z));
        let m = load_text(&text);
        assert_eq!((m.nq(), m.nv()), (3, 3), "normal {normal:?}");
        let id = m.joint_id("slide").unwrap();
        assert_eq!(*m.joint(id), Joint::Planar);
        assert!((m.total_mass() - 3.0).abs() < 1e-15);
        let n = origin.rotation * normal.normalize(); // the normal in the world (the parent is the world)
        let mut data = Data::new(&m);
        let f = m.frame_id("puck").unwrap();
        forward_kinematics(&m, &mut data, &m.neutral_configuration()).unwrap();
        assert_pose_eq(&frame_placement(&m, &data, f).unwrap(), &origin, 1e-12, "puck at q = 0");
        let mut rng = StdRng::seed_from_u64(17);
        for _ in 0..4 {
            let q = m.random_configuration(&mut rng);
            forward_kinematics(&m, &mut data, &q).unwrap();
            let x = frame_placement(&m, &data, f).unwrap();
            // the puck stays in the plane through the joint origin orthogonal to the normal …
            let offset = x.translation - origin.translation;
            assert!(offset.dot(&n).abs() < 1e-12, "normal {normal:?}: left the plane by {}", offset.dot(&n));
            assert!((offset.norm() - (q[0] * q[0] + q[1] * q[1]).sqrt()).abs() < 1e-12);
            // … and turns by θ about the normal
            let rel = x.rotation * origin.rotation.transpose();
            let w = gelenk::math::log3(&rel);
            assert!(
                (w - n * q[2]).norm() < 1e-9 || (q[2].abs() > 3.1),
                "normal {normal:?}: rotation {w:?} vs θ n = {:?}",
                n * q[2]
            );
            // kinetic energy of the puck from the URDF's mass properties
            let v = DVector::from_vec(vec![0.7, -0.4, 1.3]);
            let want = link_kinetic_energy(&m, &mut data, &q, &v, "puck", (3.0, c, ic));
            let ke = kinetic_energy(&m, &mut data, &q, &v).unwrap();
            assert!((ke - want).abs() < 1e-12 * want, "normal {normal:?}: KE {ke} vs {want}");
        }
    }
}

#[test]
fn kinetic_energy_of_loaded_links_matches_their_urdf_mass_properties() {
    // solo12 floating: every link's mass properties as the standard parser reads them.
    let robot = urdf_rs::read_file(model_path("solo12.urdf")).unwrap();
    let m = load("solo12.urdf", true);
    let mut data = Data::new(&m);
    let mut rng = StdRng::seed_from_u64(23);
    let q = m.random_configuration(&mut rng);
    let v = DVector::from_fn(m.nv(), |i, _| ((i * 7 % 11) as f64 - 5.0) / 5.0);
    let mut sum = 0.0;
    for link in &robot.links {
        let i = &link.inertial;
        let frame = xyz_rpy(i.origin.xyz.0, i.origin.rpy.0);
        let t = &i.inertia;
        let local = Mat3::new(t.ixx, t.ixy, t.ixz, t.ixy, t.iyy, t.iyz, t.ixz, t.iyz, t.izz);
        let ic = frame.rotation * local * frame.rotation.transpose();
        sum += link_kinetic_energy(&m, &mut data, &q, &v, &link.name, (i.mass.value, frame.translation, ic));
    }
    let ke = kinetic_energy(&m, &mut data, &q, &v).unwrap();
    assert!((ke - sum).abs() < 1e-12 * sum, "KE {ke} vs Σ links {sum}");
}

/// A planar joint whose normal is not z is carried by an extra massless body; its `<dynamics>`
/// must land on that planar joint, not on the fused fixed joint behind it.
#[test]
fn planar_joint_dynamics_are_kept_whatever_the_normal() {
    for normal in ["0 0 1", "1 0 0", "0 1 1"] {
        let text = planar_robot(normal)
            .replace(r#"<axis xyz="#, r#"<dynamics damping="0.5" friction="0.25"/><axis xyz="#);
        let m = load_text(&text);
        assert_eq!(m.nv(), 3);
        assert_eq!(m.damping().as_slice(), &[0.5; 3], "normal {normal}: damping");
        assert_eq!(m.friction().as_slice(), &[0.25; 3], "normal {normal}: friction");
    }
}

#[test]
fn spherical_and_floating_urdf_joints() {
    let text = robot(&format!(
        r#"<link name="a">{INERTIAL}</link><link name="b">{INERTIAL}</link><link name="c">{INERTIAL}</link>
        <joint name="ball" type="spherical"><parent link="a"/><child link="b"/><origin xyz="0 0 -0.3"/><dynamics damping="0.2"/></joint>
        <joint name="free" type="floating"><parent link="b"/><child link="c"/><origin xyz="0.1 0 0"/></joint>"#
    ));
    let m = load_text(&text);
    assert_eq!((m.nq(), m.nv()), (4 + 7, 3 + 6));
    assert_eq!(*m.joint(m.joint_id("ball").unwrap()), Joint::Ball);
    assert_eq!(*m.joint(m.joint_id("free").unwrap()), Joint::Free);
    assert_eq!(&m.damping().as_slice()[0..3], &[0.2; 3]);
    let q = m.neutral_configuration();
    assert_eq!(q.as_slice(), &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
}
