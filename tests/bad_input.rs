//! Invalid models, malformed URDF and bad dynamics inputs are refused with typed errors that name the body, joint or problem — never a panic and never NaN results; a massless moving subtree is reported as a singular mass matrix.

use gelenk::io::urdf::load_str;
use gelenk::math::Mat3;
use gelenk::model::JointLimits;
use gelenk::prelude::*;
use nalgebra::DVector;

fn box_inertia() -> RigidInertia {
    RigidInertia::solid_box(1.0, Vec3::new(0.1, 0.2, 0.3))
}

/// A valid hinge body `name` whose joint is called `<name>_joint`.
fn body(name: &str, parent: &str) -> BodySpec {
    BodySpec::new(
        name,
        parent,
        Joint::hinge(Vec3::z()),
        Transform::from_xyz_rpy([0.0, 0.0, 0.3], [0.0; 3]),
        box_inertia(),
    )
    .with_joint_name(format!("{name}_joint"))
}

fn build(bodies: Vec<BodySpec>) -> Result<Model, ModelError> {
    let mut b = ModelBuilder::new();
    for s in bodies {
        b.add_body(s);
    }
    b.build()
}

/// Builds `base` (valid) plus `bad`, expecting an error; returns it.
fn err_with(bad: BodySpec) -> ModelError {
    match build(vec![body("base", "universe"), bad]) {
        Ok(_) => panic!("an invalid model was accepted"),
        Err(e) => e,
    }
}

fn assert_names(err: &ModelError, name: &str) {
    let text = err.to_string();
    assert!(text.contains(&format!("`{name}`")), "message `{text}` does not name `{name}`");
}

fn with_inertia(mass: f64, com: Vec3, inertia_com: Mat3) -> BodySpec {
    let mut b = body("arm", "base");
    b.inertia = RigidInertia::new(mass, com, inertia_com);
    b
}

#[test]
fn sanity_valid_model_builds() {
    let m = build(vec![body("base", "universe"), body("arm", "base")]).unwrap();
    assert_eq!(m.nv(), 2);
    // A point mass and a massless link are valid bodies.
    let mut point = body("point", "arm");
    point.inertia = RigidInertia::new(2.0, Vec3::new(0.1, 0.0, 0.0), Mat3::zeros());
    let mut ghost = body("ghost", "point");
    ghost.inertia = RigidInertia::massless();
    ghost.joint = Joint::Fixed;
    build(vec![body("base", "universe"), body("arm", "base"), point, ghost]).unwrap();
    // CAD rounding: a tiny asymmetry or a tiny triangle-inequality violation is tolerated.
    let i = Mat3::new(1.0, 1e-13, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 2.0 + 1e-9);
    err_free(with_inertia(1.0, Vec3::zeros(), i));
}

fn err_free(b: BodySpec) {
    if let Err(e) = build(vec![body("base", "universe"), b]) {
        panic!("a valid body was refused: {e}");
    }
}

#[test]
fn negative_mass() {
    let e = err_with(with_inertia(-1.0, Vec3::zeros(), Mat3::identity()));
    assert!(matches!(&e, ModelError::InvalidMass { body, mass } if body == "arm" && *mass == -1.0), "{e:?}");
    assert_names(&e, "arm");
}

#[test]
fn nan_mass() {
    let e = err_with(with_inertia(f64::NAN, Vec3::zeros(), Mat3::identity()));
    assert!(matches!(&e, ModelError::InvalidMass { body, mass } if body == "arm" && mass.is_nan()), "{e:?}");
    assert_names(&e, "arm");
}

#[test]
fn infinite_mass() {
    let e = err_with(with_inertia(f64::INFINITY, Vec3::zeros(), Mat3::identity()));
    assert!(matches!(&e, ModelError::InvalidMass { body, .. } if body == "arm"), "{e:?}");
}

#[test]
fn non_finite_com() {
    let e = err_with(with_inertia(1.0, Vec3::new(0.0, f64::NAN, 0.0), Mat3::identity()));
    assert!(matches!(&e, ModelError::NonFiniteInertia { body } if body == "arm"), "{e:?}");
    assert_names(&e, "arm");
}

#[test]
fn non_finite_inertia_tensor() {
    let mut i = Mat3::identity();
    i[(2, 2)] = f64::INFINITY;
    let e = err_with(with_inertia(1.0, Vec3::zeros(), i));
    assert!(matches!(&e, ModelError::NonFiniteInertia { body } if body == "arm"), "{e:?}");
    assert_names(&e, "arm");
}

#[test]
fn inertia_not_symmetric() {
    let i = Mat3::new(1.0, 0.1, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    let e = err_with(with_inertia(1.0, Vec3::zeros(), i));
    assert!(matches!(&e, ModelError::InertiaNotSymmetric { body } if body == "arm"), "{e:?}");
    assert_names(&e, "arm");
}

#[test]
fn inertia_not_positive() {
    let i = Mat3::from_diagonal(&Vec3::new(-0.1, 1.0, 1.0));
    let e = err_with(with_inertia(1.0, Vec3::zeros(), i));
    assert!(
        matches!(&e, ModelError::InertiaNotPositive { body, moments } if body == "arm" && moments[0] < 0.0),
        "{e:?}"
    );
    assert_names(&e, "arm");
    // Not positive in a rotated frame too (off-diagonal terms): eigenvalues 1 ± 2.
    let i = Mat3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 3.0);
    let e = err_with(with_inertia(1.0, Vec3::zeros(), i));
    assert!(matches!(&e, ModelError::InertiaNotPositive { body, .. } if body == "arm"), "{e:?}");
}

#[test]
fn inertia_triangle_inequality() {
    let i = Mat3::from_diagonal(&Vec3::new(1.0, 1.0, 3.0));
    let e = err_with(with_inertia(1.0, Vec3::zeros(), i));
    assert!(
        matches!(&e, ModelError::InertiaTriangleInequality { body, moments } if body == "arm" && moments[2] > 2.9),
        "{e:?}"
    );
    assert_names(&e, "arm");
}

fn with_joint(joint: Joint) -> BodySpec {
    let mut b = body("arm", "base");
    b.joint = joint;
    b
}

#[test]
fn zero_hinge_axis() {
    let e = err_with(with_joint(Joint::hinge(Vec3::zeros())));
    assert!(matches!(&e, ModelError::InvalidAxis { joint, .. } if joint == "arm_joint"), "{e:?}");
    assert_names(&e, "arm_joint");
}

#[test]
fn zero_slider_axis() {
    let e = err_with(with_joint(Joint::slider(Vec3::zeros())));
    assert!(matches!(&e, ModelError::InvalidAxis { joint, .. } if joint == "arm_joint"), "{e:?}");
}

#[test]
fn non_finite_axis() {
    let e = err_with(with_joint(Joint::hinge(Vec3::new(f64::NAN, 0.0, 1.0))));
    assert!(matches!(&e, ModelError::InvalidAxis { joint, .. } if joint == "arm_joint"), "{e:?}");
    let e = err_with(with_joint(Joint::Universal {
        axis1: Vec3::x(),
        axis2: Vec3::new(0.0, f64::INFINITY, 0.0),
    }));
    assert!(matches!(&e, ModelError::InvalidAxis { joint, .. } if joint == "arm_joint"), "{e:?}");
    let e = err_with(with_joint(Joint::Hinge2 { axis1: Vec3::zeros(), axis2: Vec3::y(), suspension: None }));
    assert!(matches!(&e, ModelError::InvalidAxis { joint, .. } if joint == "arm_joint"), "{e:?}");
}

#[test]
fn parallel_axes_universal() {
    let e = err_with(with_joint(Joint::Universal { axis1: Vec3::x(), axis2: Vec3::new(2.0, 0.0, 0.0) }));
    assert!(matches!(&e, ModelError::ParallelAxes { joint } if joint == "arm_joint"), "{e:?}");
    assert_names(&e, "arm_joint");
    // anti-parallel is parallel too
    let e = err_with(with_joint(Joint::Universal { axis1: Vec3::y(), axis2: -Vec3::y() }));
    assert!(matches!(&e, ModelError::ParallelAxes { joint } if joint == "arm_joint"), "{e:?}");
}

#[test]
fn parallel_axes_hinge2() {
    for suspension in [None, Some(Suspension { stiffness: 100.0, damping: 1.0 })] {
        let e = err_with(with_joint(Joint::Hinge2 {
            axis1: Vec3::z(),
            axis2: Vec3::new(0.0, 0.0, -3.0),
            suspension,
        }));
        assert!(matches!(&e, ModelError::ParallelAxes { joint } if joint == "arm_joint"), "{e:?}");
        assert_names(&e, "arm_joint");
    }
}

#[test]
fn unknown_parent() {
    let e = err_with(body("arm", "nowhere"));
    assert!(
        matches!(&e, ModelError::UnknownParent { body, parent } if body == "arm" && parent == "nowhere"),
        "{e:?}"
    );
    assert_names(&e, "arm");
    assert_names(&e, "nowhere");
}

#[test]
fn duplicate_body_name() {
    let e = err_with(body("base", "universe").with_joint_name("other_joint"));
    assert!(matches!(&e, ModelError::DuplicateName { what: "body", name } if name == "base"), "{e:?}");
    assert_names(&e, "base");
}

#[test]
fn duplicate_joint_name() {
    let e = err_with(body("arm", "base").with_joint_name("base_joint"));
    assert!(matches!(&e, ModelError::DuplicateName { what: "joint", name } if name == "base_joint"), "{e:?}");
    assert_names(&e, "base_joint");
}

#[test]
fn body_named_universe() {
    let e = err_with(body("universe", "base"));
    assert!(matches!(&e, ModelError::DuplicateName { what: "body", name } if name == "universe"), "{e:?}");
    assert_names(&e, "universe");
}

#[test]
fn cycle_of_parents() {
    let e = build(vec![body("base", "universe"), body("a", "b"), body("b", "a")]).unwrap_err();
    assert!(matches!(&e, ModelError::Cycle { body } if body == "a" || body == "b"), "{e:?}");
    assert!(e.to_string().contains("`a`") || e.to_string().contains("`b`"), "{e}");
    // a body that is its own parent
    let e = build(vec![body("base", "universe"), body("self", "self")]).unwrap_err();
    assert!(matches!(&e, ModelError::Cycle { body } if body == "self"), "{e:?}");
}

#[test]
fn non_finite_placement() {
    let mut b = body("arm", "base");
    b.placement.translation.y = f64::NAN;
    let e = err_with(b);
    assert!(matches!(&e, ModelError::NonFinitePlacement { joint } if joint == "arm_joint"), "{e:?}");
    assert_names(&e, "arm_joint");
    let mut b = body("arm", "base");
    b.placement.rotation[(1, 2)] = f64::INFINITY;
    let e = err_with(b);
    assert!(matches!(&e, ModelError::NonFinitePlacement { joint } if joint == "arm_joint"), "{e:?}");
}

fn limits(lower: Vec<f64>, upper: Vec<f64>) -> JointLimits {
    JointLimits { lower, upper, ..Default::default() }
}

#[test]
fn limits_lower_above_upper() {
    let e = err_with(body("arm", "base").with_limits(limits(vec![1.0], vec![-1.0])));
    assert!(matches!(&e, ModelError::InvalidLimits { joint, .. } if joint == "arm_joint"), "{e:?}");
    assert_names(&e, "arm_joint");
    // for the second coordinate of a universal joint
    let b = with_joint(Joint::Universal { axis1: Vec3::x(), axis2: Vec3::y() })
        .with_limits(limits(vec![-1.0, 0.5], vec![1.0, 0.2]));
    let e = err_with(b);
    assert!(matches!(&e, ModelError::InvalidLimits { joint, .. } if joint == "arm_joint"), "{e:?}");
}

#[test]
fn limits_of_wrong_length() {
    let e = err_with(body("arm", "base").with_limits(limits(vec![-1.0, -1.0], vec![1.0, 1.0])));
    assert!(matches!(&e, ModelError::InvalidLimits { joint, .. } if joint == "arm_joint"), "{e:?}");
    assert_names(&e, "arm_joint");
    // velocity limits have nv entries: a ball joint has 3, not 4
    let mut b = with_joint(Joint::Ball);
    b.limits = JointLimits { velocity: vec![1.0; 4], ..Default::default() };
    let e = err_with(b);
    assert!(matches!(&e, ModelError::InvalidLimits { joint, .. } if joint == "arm_joint"), "{e:?}");
}

#[test]
fn limits_nan_or_negative() {
    let e = err_with(body("arm", "base").with_limits(limits(vec![f64::NAN], vec![1.0])));
    assert!(matches!(&e, ModelError::InvalidLimits { joint, .. } if joint == "arm_joint"), "{e:?}");
    let mut b = body("arm", "base");
    b.limits = JointLimits { effort: vec![-5.0], ..Default::default() };
    let e = err_with(b);
    assert!(matches!(&e, ModelError::InvalidLimits { joint, .. } if joint == "arm_joint"), "{e:?}");
    let mut b = body("arm", "base");
    b.dynamics.damping = -0.1;
    let e = err_with(b);
    assert!(matches!(&e, ModelError::InvalidLimits { joint, .. } if joint == "arm_joint"), "{e:?}");
}

#[test]
fn invalid_suspension() {
    for (stiffness, damping) in [(-1.0, 0.0), (100.0, f64::NAN), (f64::INFINITY, 1.0), (100.0, -2.0)] {
        let suspension = Some(Suspension { stiffness, damping });
        let e = err_with(with_joint(Joint::Hinge2 { axis1: Vec3::z(), axis2: Vec3::y(), suspension }));
        assert!(matches!(&e, ModelError::InvalidSuspension { joint } if joint == "arm_joint"), "{e:?}");
        assert_names(&e, "arm_joint");
    }
}

// ---------------------------------------------------------------- malformed URDF

const LINK: &str = r#"<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>"#;

fn link(name: &str) -> String {
    format!(r#"<link name="{name}">{LINK}</link>"#)
}

fn joint(name: &str, kind: &str, parent: &str, child: &str) -> String {
    format!(
        r#"<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"#
    )
}

fn robot(body: &str) -> String {
    format!(r#"<?xml version="1.0"?><robot name="r">{body}</robot>"#)
}

/// Loads `text` with the strict options (every loader warning an error), expecting an error
/// (not a panic); returns its message. tests/urdf_wild.rs checks which of these the default,
/// lenient options load.
fn urdf_err(text: &str) -> String {
    let result = std::panic::catch_unwind(|| load_str(text, &UrdfOptions::strict()).map(|m| m.nv()));
    match result {
        Err(_) => panic!("loading panicked on:\n{text}"),
        Ok(Ok(nv)) => panic!("a malformed URDF loaded (nv = {nv}):\n{text}"),
        Ok(Err(e)) => e.to_string(),
    }
}

/// Inverted or NaN bounds are an error (strict); equal bounds (a missing one reads as 0) mean
/// no limit, and a continuous joint ignores them.
#[test]
fn urdf_inverted_or_nan_limits_are_errors() {
    for (kind, lower, upper) in
        [("revolute", "1", "-1"), ("prismatic", "0.5", "0.2"), ("revolute", "nan", "1")]
    {
        let j = format!(
            r#"<joint name="j" type="{kind}"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/><limit lower="{lower}" upper="{upper}" effort="1" velocity="1"/></joint>"#
        );
        let msg = urdf_err(&robot(&format!("{}{}{j}", link("a"), link("b"))));
        assert!(
            msg.contains("joint `j`") && msg.contains("lower must not exceed upper"),
            "{kind} {lower} {upper}: {msg}"
        );
    }
    for (kind, lower, upper) in [("revolute", "0", "0"), ("continuous", "1", "-1")] {
        let j = format!(
            r#"<joint name="j" type="{kind}"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/><limit lower="{lower}" upper="{upper}" effort="1" velocity="1"/></joint>"#
        );
        let model =
            load_str(&robot(&format!("{}{}{j}", link("a"), link("b"))), &UrdfOptions::default()).unwrap();
        assert_eq!(model.lower_position_limit()[0], f64::NEG_INFINITY, "{kind} {lower} {upper}");
        assert_eq!(model.upper_position_limit()[0], f64::INFINITY, "{kind} {lower} {upper}");
    }
}

/// With the strict options, a misspelt element of a joint, link or inertial, or a misspelt
/// attribute of an origin, axis, mass or inertia, is an error naming it and its line, not a
/// silent default (the axis at x, a massless link); vendors' attributes on `<dynamics>` and
/// `<limit>`, `<mimic>`, `<safety_controller>` and PyBullet's `<contact>` load.
#[test]
fn urdf_misspelt_elements_and_attributes_are_errors() {
    let j = |inner: &str| {
        format!(
            r#"<joint name="j" type="revolute"><parent link="a"/><child link="b"/>{inner}<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"#
        )
    };
    for (body, needle) in [
        (format!("{}{}{}", link("a"), link("b"), j(r#"<axiss xyz="0 1 0"/>"#)), "unknown element <axiss>"),
        (format!("{}{}{}", link("a"), link("b"), j(r#"<axis xzy="0 1 0"/>"#)), "unknown attribute `xzy`"),
        (
            format!("{}{}{}", link("a"), link("b"), j(r#"<origin xyz="0 0 1" rpu="0 0 0"/>"#)),
            "unknown attribute `rpu`",
        ),
        (
            format!(r#"{}<link name="b"><inertail><mass value="1"/></inertail></link>{}"#, link("a"), j("")),
            "unknown element <inertail>",
        ),
        (
            format!(
                r#"{}<link name="b"><inertial><mass valeu="1" value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>{}"#,
                link("a"),
                j("")
            ),
            "unknown attribute `valeu`",
        ),
    ] {
        let msg = urdf_err(&robot(&body));
        assert!(msg.contains(needle) && msg.contains("at line 1"), "{needle}: {msg}");
    }
    let extras = j(
        r#"<axis xyz="0 1 0"/><dynamics damping="0.1" D="1" K="7000"/><mimic joint="k" multiplier="1"/><safety_controller k_velocity="1"/>"#,
    );
    let contact = r#"<link name="b"><contact><lateral_friction value="1"/></contact><drake:x xmlns:drake="http://drake.mit.edu"/><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>"#;
    let model = load_str(&robot(&format!("{}{contact}{extras}", link("a"))), &UrdfOptions::strict()).unwrap();
    assert_eq!(model.nv(), 1);
}

#[test]
fn urdf_valid_baseline_loads() {
    let text = robot(&format!("{}{}{}", link("a"), link("b"), joint("j", "revolute", "a", "b")));
    assert_eq!(load_str(&text, &UrdfOptions::default()).unwrap().nv(), 1);
}

#[test]
fn urdf_missing_file() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("no_such_dir/robot.urdf");
    let e = gelenk::io::urdf::load_file(&path, &UrdfOptions::default()).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("no_such_dir/robot.urdf") && msg.contains("cannot read"), "{msg}");
}

#[test]
fn urdf_not_xml() {
    let msg = urdf_err("this is not XML at all");
    assert!(msg.contains("<string>") && msg.contains("not a valid URDF"), "{msg}");
    let msg = urdf_err(r#"<robot name="r"><link name="a"></robot>"#);
    assert!(msg.contains("not a valid URDF"), "{msg}");
    let msg = urdf_err("");
    assert!(!msg.is_empty());
}

#[test]
fn urdf_xml_but_not_robot() {
    let msg = urdf_err(r#"<?xml version="1.0"?><sdf version="1.6"><model name="m"/></sdf>"#);
    assert!(msg.contains("sdf") && msg.contains("robot"), "{msg}");
}

#[test]
fn urdf_unknown_joint_type() {
    let msg = urdf_err(&robot(&format!("{}{}{}", link("a"), link("b"), joint("j", "telescopic", "a", "b"))));
    assert!(msg.contains("telescopic"), "message does not name the bad type: {msg}");
}

#[test]
fn urdf_joint_with_missing_link() {
    let msg = urdf_err(&robot(&format!("{}{}", link("a"), joint("j", "revolute", "a", "ghost"))));
    assert!(msg.contains("`j`") && msg.contains("ghost"), "{msg}");
    let msg = urdf_err(&robot(&format!("{}{}", link("b"), joint("j2", "revolute", "nobody", "b"))));
    assert!(msg.contains("`j2`") && msg.contains("nobody"), "{msg}");
}

#[test]
fn urdf_two_roots() {
    let msg = urdf_err(&robot(&format!("{}{}{}", link("a"), link("b"), link("c"))));
    assert!(msg.contains("root") && msg.contains("a, b, c"), "{msg}");
    let msg = urdf_err(&robot(&format!(
        "{}{}{}{}{}",
        link("a"),
        link("b"),
        link("c"),
        link("d"),
        joint("j", "revolute", "a", "b") + &joint("k", "revolute", "c", "d")
    )));
    assert!(msg.contains("root") && msg.contains("a, c"), "{msg}");
}

#[test]
fn urdf_link_with_two_parents() {
    let msg = urdf_err(&robot(&format!(
        "{}{}{}{}{}",
        link("a"),
        link("b"),
        link("c"),
        joint("j1", "revolute", "a", "c"),
        joint("j2", "revolute", "b", "c")
    )));
    assert!(msg.contains("`j2`") && msg.contains("`c`") && msg.contains("j1"), "{msg}");
}

#[test]
fn urdf_joint_cycle() {
    let msg = urdf_err(&robot(&format!(
        "{}{}{}{}",
        link("a"),
        link("b"),
        joint("j1", "revolute", "a", "b"),
        joint("j2", "revolute", "b", "a")
    )));
    assert!(msg.contains("cycle"), "{msg}");
}

#[test]
fn urdf_no_links() {
    let msg = urdf_err(r#"<robot name="empty"></robot>"#);
    assert!(msg.contains("link"), "{msg}");
}

#[test]
fn urdf_negative_mass() {
    let bad = r#"<link name="heavy"><inertial><mass value="-2"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>"#;
    let msg = urdf_err(&robot(&format!("{}{}{}", link("a"), bad, joint("j", "revolute", "a", "heavy"))));
    assert!(msg.contains("`heavy`") && msg.contains("mass"), "{msg}");
}

#[test]
fn urdf_bad_inertia_and_axis() {
    let bad = r#"<link name="odd"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="5" ixy="0" ixz="0" iyz="0"/></inertial></link>"#;
    let msg = urdf_err(&robot(&format!("{}{}{}", link("a"), bad, joint("j", "revolute", "a", "odd"))));
    assert!(msg.contains("`odd`") && msg.contains("triangle"), "{msg}");
    let j = r#"<joint name="spin" type="continuous"><parent link="a"/><child link="b"/><axis xyz="0 0 0"/></joint>"#;
    let msg = urdf_err(&robot(&format!("{}{}{}", link("a"), link("b"), j)));
    assert!(msg.contains("`spin`") && msg.contains("axis"), "{msg}");
}

fn with_extension(ext: &str, kind: &str) -> String {
    robot(&format!("{}{}{}{ext}", link("a"), link("b"), joint("j", kind, "a", "b")))
}

#[test]
fn urdf_bad_gelenk_extension() {
    let cases = [
        (r#"<gelenk joint="j" type="gimbal" axis2="0 1 0"/>"#, "revolute", "gimbal"),
        (r#"<gelenk joint="j" type="universal"/>"#, "revolute", "axis2"),
        (r#"<gelenk joint="j" type="universal" axis2="0 1"/>"#, "revolute", "axis2"),
        (r#"<gelenk joint="j" type="universal" axis2="0 x 1"/>"#, "revolute", "axis2"),
        (r#"<gelenk joint="j" type="universal" axis2="0 1 0" lower2="abc"/>"#, "revolute", "lower2"),
        (r#"<gelenk joint="missing" type="universal" axis2="0 1 0"/>"#, "revolute", "missing"),
        (r#"<gelenk type="universal" axis2="0 1 0"/>"#, "revolute", "joint"),
        (r#"<gelenk joint="j" type="universal" axis2="0 1 0"/>"#, "prismatic", "revolute"),
        (
            r#"<gelenk joint="j" type="universal" axis2="0 1 0" suspension_stiffness="10"/>"#,
            "revolute",
            "hinge2",
        ),
        (
            r#"<gelenk joint="j" type="universal" axis2="0 1 0"/><gelenk joint="j" type="hinge2" axis2="1 0 0"/>"#,
            "revolute",
            "two",
        ),
        (r#"<gelenk joint="j" type="universal" axis2="0 0 2"/>"#, "continuous", "parallel"),
        (
            r#"<gelenk joint="j" type="hinge2" axis2="0 1 0" suspension_stiffness="-5"/>"#,
            "continuous",
            "suspension",
        ),
        (
            r#"<gelenk joint="j" type="universal" axis2="0 1 0" lower2="1" upper2="-1"/>"#,
            "revolute",
            "limits",
        ),
    ];
    for (ext, kind, needle) in cases {
        let msg = urdf_err(&with_extension(ext, kind));
        assert!(msg.contains(needle), "extension {ext} on a {kind} joint: message `{msg}` lacks `{needle}`");
    }
}

// ---------------------------------------------------------------- dynamics inputs

/// base (hinge) → ball → slider: nq = 1 + 4 + 1 = 6, nv = 1 + 3 + 1 = 5.
fn small_model() -> Model {
    let mut ball = body("ball", "base");
    ball.joint = Joint::Ball;
    let mut slide = body("slide", "ball");
    slide.joint = Joint::slider(Vec3::x());
    build(vec![body("base", "universe"), ball, slide]).unwrap()
}

fn dim(e: DynamicsError, what: &str, expected: usize, got: usize) {
    match &e {
        DynamicsError::DimensionMismatch { what: w, expected: x, got: g }
            if *w == what && *x == expected && *g == got =>
        {
            let msg = e.to_string();
            assert!(
                msg.contains(what) && msg.contains(&expected.to_string()) && msg.contains(&got.to_string()),
                "{msg}"
            );
        }
        other => panic!("expected DimensionMismatch of {what} ({expected} vs {got}), got {other:?}"),
    }
}

#[test]
fn wrong_length_q_is_refused_by_every_algorithm() {
    let model = small_model();
    assert_eq!((model.nq(), model.nv()), (6, 5));
    let mut data = Data::new(&model);
    let q = DVector::zeros(5); // nv entries instead of nq
    let v = DVector::zeros(5);
    dim(forward_kinematics(&model, &mut data, &q).unwrap_err(), "q", 6, 5);
    dim(rnea(&model, &mut data, &q, &v, &v).unwrap_err(), "q", 6, 5);
    dim(nonlinear_effects(&model, &mut data, &q, &v).unwrap_err(), "q", 6, 5);
    dim(generalized_gravity(&model, &mut data, &q).unwrap_err(), "q", 6, 5);
    dim(crba(&model, &mut data, &q).unwrap_err(), "q", 6, 5);
    dim(mass_matrix(&model, &mut data, &q).unwrap_err(), "q", 6, 5);
    dim(aba(&model, &mut data, &q, &v, &v).unwrap_err(), "q", 6, 5);
    dim(forward_dynamics_crba(&model, &mut data, &q, &v, &v).unwrap_err(), "q", 6, 5);
    dim(kinetic_energy(&model, &mut data, &q, &v).unwrap_err(), "q", 6, 5);
    dim(potential_energy(&model, &mut data, &q).unwrap_err(), "q", 6, 5);
    dim(center_of_mass(&model, &mut data, &q).unwrap_err(), "q", 6, 5);
    dim(compute_joint_jacobians(&model, &mut data, &q).unwrap_err(), "q", 6, 5);
}

#[test]
fn wrong_length_v_a_tau() {
    let model = small_model();
    let mut data = Data::new(&model);
    let q = model.neutral_configuration();
    let ok = DVector::zeros(5);
    let long = DVector::zeros(6);
    dim(rnea(&model, &mut data, &q, &long, &ok).unwrap_err(), "v", 5, 6);
    dim(rnea(&model, &mut data, &q, &ok, &long).unwrap_err(), "a", 5, 6);
    dim(aba(&model, &mut data, &q, &ok, &long).unwrap_err(), "tau", 5, 6);
    dim(forward_dynamics_crba(&model, &mut data, &q, &ok, &long).unwrap_err(), "tau", 5, 6);
    dim(nonlinear_effects(&model, &mut data, &q, &DVector::zeros(0)).unwrap_err(), "v", 5, 0);
    dim(kinetic_energy(&model, &mut data, &q, &long).unwrap_err(), "v", 5, 6);
}

fn non_finite(e: DynamicsError, what: &str, index: usize, joint: &str) {
    match &e {
        DynamicsError::NonFinite { what: w, index: i, joint: j }
            if *w == what && *i == index && j == joint =>
        {
            let msg = e.to_string();
            assert!(msg.contains(&format!("`{joint}`")) && msg.contains(what), "{msg}");
        }
        other => panic!("expected NonFinite {what}[{index}] of `{joint}`, got {other:?}"),
    }
}

#[test]
fn non_finite_inputs_name_the_joint() {
    let model = small_model();
    let mut data = Data::new(&model);
    let q = model.neutral_configuration();
    let zero = DVector::zeros(5);
    // v: [base | ball ×3 | slide]
    let mut v = zero.clone();
    v[2] = f64::NAN;
    non_finite(aba(&model, &mut data, &q, &v, &zero).unwrap_err(), "v", 2, "ball_joint");
    non_finite(rnea(&model, &mut data, &q, &v, &zero).unwrap_err(), "v", 2, "ball_joint");
    non_finite(kinetic_energy(&model, &mut data, &q, &v).unwrap_err(), "v", 2, "ball_joint");
    non_finite(forward_dynamics_crba(&model, &mut data, &q, &v, &zero).unwrap_err(), "v", 2, "ball_joint");
    let mut v = zero.clone();
    v[4] = f64::NEG_INFINITY;
    non_finite(nonlinear_effects(&model, &mut data, &q, &v).unwrap_err(), "v", 4, "slide_joint");
    let mut tau = zero.clone();
    tau[0] = f64::INFINITY;
    non_finite(aba(&model, &mut data, &q, &zero, &tau).unwrap_err(), "tau", 0, "base_joint");
    non_finite(rnea(&model, &mut data, &q, &zero, &tau).unwrap_err(), "a", 0, "base_joint");
    // q: [base | ball quaternion ×4 | slide]
    let mut q_bad = q.clone();
    q_bad[4] = f64::NAN;
    non_finite(crba(&model, &mut data, &q_bad).unwrap_err(), "q", 4, "ball_joint");
    non_finite(mass_matrix(&model, &mut data, &q_bad).unwrap_err(), "q", 4, "ball_joint");
    non_finite(forward_kinematics(&model, &mut data, &q_bad).unwrap_err(), "q", 4, "ball_joint");
    let mut q_bad = q.clone();
    q_bad[5] = f64::NAN;
    non_finite(potential_energy(&model, &mut data, &q_bad).unwrap_err(), "q", 5, "slide_joint");
}

/// A finite q whose M overflows (a slider 1e200 m out on a ball joint: its inertia about the
/// ball's origin is m·t² = ∞) is a non-finite result naming the first column's joint, the same
/// error from the world-frame CRBA and the body-frame mass matrix.
#[test]
fn an_overflowing_mass_matrix_is_a_typed_error() {
    let model = small_model();
    let mut data = Data::new(&model);
    let mut q = model.neutral_configuration();
    q[5] = 1e200;
    let world = crba(&model, &mut data, &q).unwrap_err();
    let local = mass_matrix(&model, &mut Data::new(&model), &q).unwrap_err();
    assert!(
        matches!(&local, DynamicsError::NonFiniteResult { what: "mass matrix", at } if at.contains("joint `")),
        "{local:?}"
    );
    assert_eq!(local, world);
    q[5] = 1e3;
    assert!(mass_matrix(&model, &mut data, &q).unwrap().iter().all(|x| x.is_finite()));
}

/// A zero quaternion is no rotation: refused by the joint's name (normalizing it would divide by
/// zero and end as a singular mass matrix). A quaternion of any other length is normalized.
#[test]
fn a_zero_quaternion_is_refused_and_others_are_normalized() {
    let model = small_model();
    let mut data = Data::new(&model);
    let zero = DVector::zeros(5);
    // q: [base | ball quaternion ×4 | slide]
    let mut q = model.neutral_configuration();
    q.as_mut_slice()[1..5].copy_from_slice(&[0.0; 4]);
    for e in [
        aba(&model, &mut data, &q, &zero, &zero).unwrap_err(),
        crba(&model, &mut data, &q).unwrap_err(),
        mass_matrix(&model, &mut data, &q).unwrap_err(),
        forward_kinematics(&model, &mut data, &q).unwrap_err(),
    ] {
        assert!(
            matches!(&e, DynamicsError::DegenerateQuaternion { joint, norm } if joint == "ball_joint" && *norm == 0.0),
            "{e:?}"
        );
    }
    q.as_mut_slice()[1..5].copy_from_slice(&[0.2, -0.4, 0.4, 0.8]);
    let unit = aba(&model, &mut data, &q, &zero, &zero).unwrap().clone();
    q.as_mut_slice()[1..5].iter_mut().for_each(|x| *x *= 3.0);
    let scaled = aba(&model, &mut data, &q, &zero, &zero).unwrap().clone();
    assert!((unit - scaled).amax() < 1e-12);
}

#[test]
fn frame_index_out_of_range() {
    let model = small_model();
    let mut data = Data::new(&model);
    let n = model.frames().len();
    compute_joint_jacobians(&model, &mut data, &model.neutral_configuration()).unwrap();
    let e = frame_jacobian(&model, &mut data, n, JacobianFrame::Local).unwrap_err();
    assert!(
        matches!(e, DynamicsError::IndexOutOfRange { what: "frames", index, count } if index == n && count == n),
        "{e:?}"
    );
    let e = frame_placement(&model, &data, n + 7).unwrap_err();
    assert!(matches!(e, DynamicsError::IndexOutOfRange { what: "frames", .. }), "{e:?}");
}

// ---------------------------------------------------------------- singular mass matrices

fn massless(mut b: BodySpec) -> BodySpec {
    b.inertia = RigidInertia::massless();
    b
}

fn singular(e: DynamicsError, joint: &str) {
    match &e {
        DynamicsError::SingularMassMatrix { joint: j } if j == joint => {
            assert!(e.to_string().contains(&format!("`{joint}`")), "{e}");
        }
        other => panic!("expected SingularMassMatrix naming `{joint}`, got {other:?}"),
    }
}

#[test]
fn massless_leaf_is_a_singular_mass_matrix() {
    let mut tip = massless(body("tip", "arm"));
    tip.joint = Joint::hinge(Vec3::x());
    let model = build(vec![body("base", "universe"), body("arm", "base"), tip])
        .expect("a massless leaf still builds");
    let tip_id = model.joint_id("tip_joint").unwrap();
    assert_eq!(model.massless_subtrees(), vec![tip_id]);
    let mut data = Data::new(&model);
    let mut rng_q = model.neutral_configuration();
    rng_q[0] = 0.3;
    let v = DVector::from_element(model.nv(), 0.5);
    let tau = DVector::from_element(model.nv(), 1.0);
    singular(aba(&model, &mut data, &rng_q, &v, &tau).unwrap_err(), "tip_joint");
    singular(forward_dynamics_crba(&model, &mut data, &rng_q, &v, &tau).unwrap_err(), "tip_joint");
    // The inverse-dynamics side is fine: the massless joint needs no torque.
    let a = DVector::from_element(model.nv(), 1.0);
    let t = rnea(&model, &mut data, &rng_q, &v, &a).unwrap().clone();
    assert!(t.iter().all(|x| x.is_finite()));
    assert_eq!(t[model.idx_v(tip_id)], 0.0);
    let m = crba(&model, &mut data, &rng_q).unwrap();
    assert!(m.iter().all(|x| x.is_finite()));
    let local = mass_matrix(&model, &mut data, &rng_q).unwrap();
    assert!(local.iter().all(|x| x.is_finite()));
}

#[test]
fn massless_subtree_of_two_bodies_is_reported() {
    let mut tip = massless(body("tip", "mid"));
    tip.joint = Joint::slider(Vec3::y());
    let mid = massless(body("mid", "base"));
    let model = build(vec![body("base", "universe"), mid, tip]).unwrap();
    let listed = model.massless_subtrees();
    let (mid_id, tip_id) = (model.joint_id("mid_joint").unwrap(), model.joint_id("tip_joint").unwrap());
    assert!(listed.contains(&mid_id) && listed.contains(&tip_id) && listed.len() == 2, "{listed:?}");
    let mut data = Data::new(&model);
    let q = model.neutral_configuration();
    let z = DVector::zeros(model.nv());
    for e in [
        aba(&model, &mut data, &q, &z, &z).unwrap_err(),
        forward_dynamics_crba(&model, &mut data, &q, &z, &z).unwrap_err(),
    ] {
        match &e {
            DynamicsError::SingularMassMatrix { joint } => {
                assert!(joint == "mid_joint" || joint == "tip_joint", "{e}")
            }
            other => panic!("expected SingularMassMatrix, got {other:?}"),
        }
    }
}

#[test]
fn point_mass_on_its_own_hinge_axis_is_singular() {
    // Mass but no inertia about the axis: the subtree has no inertia along the joint's motion.
    let mut bead = body("bead", "base");
    bead.inertia = RigidInertia::new(1.0, Vec3::new(0.0, 0.0, 0.5), Mat3::zeros());
    let model = build(vec![body("base", "universe"), bead]).unwrap();
    let mut data = Data::new(&model);
    let q = model.neutral_configuration();
    let z = DVector::zeros(model.nv());
    singular(aba(&model, &mut data, &q, &z, &z).unwrap_err(), "bead_joint");
    singular(forward_dynamics_crba(&model, &mut data, &q, &z, &z).unwrap_err(), "bead_joint");
}

#[test]
fn massless_intermediate_link_with_massive_child_is_not_singular() {
    let mut mid = massless(body("mid", "base"));
    mid.joint = Joint::hinge(Vec3::x());
    let mut tip = body("tip", "mid");
    tip.joint = Joint::hinge(Vec3::y());
    tip.placement = Transform::from_xyz_rpy([0.2, 0.1, 0.4], [0.1, 0.2, 0.3]);
    let model = build(vec![body("base", "universe"), mid, tip]).unwrap();
    assert!(model.massless_subtrees().is_empty(), "{:?}", model.massless_subtrees());
    let mut data = Data::new(&model);
    let q = DVector::from_vec(vec![0.3, -0.4, 0.8]);
    let v = DVector::from_vec(vec![0.5, -1.0, 0.2]);
    let tau = DVector::from_vec(vec![0.1, 0.2, -0.3]);
    let a1 = aba(&model, &mut data, &q, &v, &tau).expect("not singular").clone();
    assert!(a1.iter().all(|x| x.is_finite()));
    let a2 = forward_dynamics_crba(&model, &mut data, &q, &v, &tau).expect("not singular").clone();
    assert!((&a1 - &a2).amax() < 1e-9 * (1.0 + a1.amax()), "{a1} vs {a2}");
    let t = rnea(&model, &mut data, &q, &v, &a1).unwrap();
    assert!((t - &tau).amax() < 1e-9);
}

#[test]
fn model_without_degrees_of_freedom() {
    let mut a = body("a", "universe");
    a.joint = Joint::Fixed;
    let mut b = body("b", "a");
    b.joint = Joint::Fixed;
    let model = build(vec![a, b]).unwrap();
    assert_eq!((model.nq(), model.nv(), model.nbodies()), (0, 0, 1));
    assert_eq!(model.total_mass(), 0.0);
    let mut data = Data::new(&model);
    let e = DVector::zeros(0);
    assert_eq!(aba(&model, &mut data, &e, &e, &e).unwrap().len(), 0);
    assert_eq!(forward_dynamics_crba(&model, &mut data, &e, &e, &e).unwrap().len(), 0);
    assert_eq!(rnea(&model, &mut data, &e, &e, &e).unwrap().len(), 0);
    assert_eq!(crba(&model, &mut data, &e).unwrap().shape(), (0, 0));
    assert_eq!(kinetic_energy(&model, &mut data, &e, &e).unwrap(), 0.0);
    assert_eq!(center_of_mass(&model, &mut data, &e).unwrap(), Vec3::zeros());
    dim(aba(&model, &mut data, &DVector::zeros(1), &e, &e).unwrap_err(), "q", 0, 1);
}

#[test]
fn mass_hidden_behind_a_ball_joint_on_the_axis_is_singular() {
    // `mid` (massless) turns about z; its child hangs from a ball joint on that axis and is a point
    // mass: turning `mid` moves nothing, so M is singular although no subtree is massless.
    let mid = massless(body("mid", "base"));
    let mut bob = body("bob", "mid");
    bob.joint = Joint::Ball;
    bob.placement = Transform::from_xyz_rpy([0.0, 0.0, 0.4], [0.0; 3]);
    bob.inertia = RigidInertia::new(1.0, Vec3::new(0.3, 0.0, 0.0), Mat3::zeros());
    let model = build(vec![body("base", "universe"), mid, bob]).unwrap();
    assert!(model.massless_subtrees().is_empty());
    let mut data = Data::new(&model);
    let q = model.neutral_configuration();
    let z = DVector::zeros(model.nv());
    for (what, r) in [
        ("aba", aba(&model, &mut data, &q, &z, &z).cloned()),
        ("forward_dynamics_crba", forward_dynamics_crba(&model, &mut data, &q, &z, &z).cloned()),
    ] {
        match r {
            Err(DynamicsError::SingularMassMatrix { .. }) => {}
            Err(e) => panic!("{what}: unexpected error {e}"),
            Ok(a) => panic!("{what}: returned {a} for a singular mass matrix"),
        }
    }
}
