//! The MJCF loader against MuJoCo: tests/data/mjcf_reference.json (made offline by
//! tests/data/gen_mjcf_reference.py; CI needs no MuJoCo) holds, for the three peer scenes of
//! benches/peers and two scenes exercising the rest of the supported subset, MuJoCo's layout,
//! masses, options, initial configuration and, at random states, body poses, mass matrix, bias
//! forces and gravity, already converted to gelenk's conventions. Every quantity must match to
//! 1e-9 relative to the largest entry of the reference. Bad documents must give typed errors
//! naming the element, never a panic.

use gelenk::constraints::FrictionModel;
use gelenk::error::MjcfError;
use gelenk::io::mjcf::{self, MjcfScene};
use gelenk::math::{Mat3, Vec3};
use gelenk::model::{GeometryRole, Joint, Shape};
use gelenk::prelude::*;
use nalgebra::{DMatrix, DVector};
use serde_json::Value;
use std::path::PathBuf;

const TOL: f64 = 1e-9;

fn reference() -> Value {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mjcf_reference.json");
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn cases() -> Vec<Value> {
    reference()["cases"].as_array().unwrap().clone()
}

fn case_named(name: &str) -> (Value, MjcfScene) {
    let case = cases().into_iter().find(|c| c["name"] == name).unwrap();
    let scene = mjcf::load_str(case["xml"].as_str().unwrap()).unwrap();
    (case, scene)
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

fn dvec(v: &Value) -> DVector<f64> {
    DVector::from_vec(floats(v))
}

fn dmat(v: &Value) -> DMatrix<f64> {
    let rows: Vec<Vec<f64>> = v.as_array().unwrap().iter().map(floats).collect();
    DMatrix::from_fn(rows.len(), rows.first().map_or(0, Vec::len), |i, j| rows[i][j])
}

/// max |got − want| / max |want| (normwise relative error; absolute when the reference is 0).
fn rel_err(got: &[f64], want: &[f64]) -> f64 {
    assert_eq!(got.len(), want.len(), "length mismatch");
    let scale = want.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = got.iter().zip(want).map(|(g, w)| (g - w).abs()).fold(0.0, f64::max);
    if scale > 0.0 {
        diff / scale
    } else {
        diff
    }
}

fn check(case: &str, what: &str, got: &[f64], want: &[f64]) -> f64 {
    let err = rel_err(got, want);
    assert!(err <= TOL, "{case}: {what} differs by {err:e} (relative)\n got  {got:?}\n want {want:?}");
    err
}

/// gelenk's name of a joint in the reference: MuJoCo's name, or the loader's generated one.
fn joint_name(case: &Value, j: &Value) -> String {
    match j["name"].as_str() {
        Some(n) => n.to_string(),
        None => {
            let body = j["body"].as_str().unwrap();
            let n = case["joints"].as_array().unwrap().iter().filter(|k| k["body"] == j["body"]).count();
            assert_eq!(n, 1, "the reference scenes only leave single joints unnamed");
            format!("{body}_joint")
        }
    }
}

fn body_name(case: &Value, k: usize) -> String {
    case["bodies"][k]["name"].as_str().map_or_else(|| format!("body{}", k + 1), str::to_string)
}

#[test]
fn peer_scenes_have_mujocos_dimensions() {
    for (name, nq, nv) in [("pendulum5", 5, 5), ("humanoid_fall", 28, 27), ("box_stack10", 70, 60)] {
        let (case, scene) = case_named(name);
        assert_eq!((scene.model.nq(), scene.model.nv()), (nq, nv), "{name}");
        assert_eq!(case["nq"].as_u64().unwrap() as usize, nq);
        assert_eq!(case["nv"].as_u64().unwrap() as usize, nv);
    }
}

#[test]
fn peer_files_load_and_match_the_reference_text() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("benches/peers");
    for name in ["pendulum5", "humanoid_fall", "box_stack10"] {
        let path = dir.join(format!("{name}.xml"));
        let scene = mjcf::load_file(&path).unwrap();
        let (case, from_text) = case_named(name);
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            case["xml"].as_str().unwrap(),
            "{name}: the peer file changed; rerun tests/data/gen_mjcf_reference.py"
        );
        assert_eq!(scene.model.nv(), from_text.model.nv());
        assert_eq!(scene.model.source_dir(), Some(dir.as_path()));
    }
}

#[test]
fn layout_options_and_masses_match_mujoco() {
    for case in cases() {
        let name = case["name"].as_str().unwrap();
        let scene = mjcf::load_str(case["xml"].as_str().unwrap()).unwrap();
        let model = &scene.model;
        assert_eq!(model.nq(), case["nq"].as_u64().unwrap() as usize, "{name}: nq");
        assert_eq!(model.nv(), case["nv"].as_u64().unwrap() as usize, "{name}: nv");
        assert_eq!(scene.timestep, case["timestep"].as_f64().unwrap(), "{name}: timestep");
        check(name, "gravity", scene.gravity.as_slice(), &floats(&case["gravity"]));
        check(name, "model gravity", model.gravity().as_slice(), &floats(&case["gravity"]));
        check(name, "total mass", &[model.total_mass()], &[case["moving_mass"].as_f64().unwrap()]);
        check(name, "qpos0", scene.q0.as_slice(), &floats(&case["qpos0"]));

        // Joints: same order, kind, dofs, damping, friction loss, armature and limits as MuJoCo.
        let joints = case["joints"].as_array().unwrap();
        assert_eq!(scene.joint_damping.len(), joints.len(), "{name}: joint count");
        let moving: Vec<usize> = (1..model.nbodies()).filter(|&b| model.joint(b).nv() > 0).collect();
        assert_eq!(moving.len(), joints.len(), "{name}: moving joints");
        for (k, j) in joints.iter().enumerate() {
            let jn = joint_name(&case, j);
            let b = model.joint_id(&jn).unwrap_or_else(|| panic!("{name}: joint {jn} missing"));
            assert_eq!(b, moving[k], "{name}: {jn} is not MuJoCo's joint {k}");
            assert_eq!(model.idx_q(b), j["idx_q"].as_u64().unwrap() as usize, "{name}: idx_q of {jn}");
            assert_eq!(model.idx_v(b), j["idx_v"].as_u64().unwrap() as usize, "{name}: idx_v of {jn}");
            let kind = match model.joint(b) {
                Joint::Free => "free",
                Joint::Ball => "ball",
                Joint::Slider { .. } => "slide",
                Joint::Hinge { .. } => "hinge",
                other => panic!("{name}: unexpected joint {other:?}"),
            };
            assert_eq!(kind, j["type"].as_str().unwrap(), "{name}: type of {jn}");
            let iv = model.idx_v(b);
            let damping = j["damping"].as_f64().unwrap();
            assert_eq!(scene.joint_damping[k], (jn.clone(), damping), "{name}: damping of {jn}");
            assert_eq!(scene.joint_armature[k], (jn.clone(), j["armature"].as_f64().unwrap()));
            for d in iv..iv + model.joint(b).nv() {
                assert_eq!(model.damping()[d], damping, "{name}: damping of {jn}");
                assert_eq!(model.friction()[d], j["frictionloss"].as_f64().unwrap(), "{name}: {jn}");
            }
            let iq = model.idx_q(b);
            let (lo, hi) = (model.lower_position_limit()[iq], model.upper_position_limit()[iq]);
            if j["limited"].as_bool().unwrap() && matches!(kind, "hinge" | "slide") {
                check(name, &format!("range of {jn}"), &[lo, hi], &floats(&j["range"]));
            } else {
                assert_eq!((lo, hi), (f64::NEG_INFINITY, f64::INFINITY), "{name}: {jn} must be unlimited");
            }
        }

        // Subtree masses of every body that is a model body.
        for (k, b) in case["bodies"].as_array().unwrap().iter().enumerate() {
            if let Some(id) = model.body_id(&body_name(&case, k)) {
                let want = b["subtree_mass"].as_f64().unwrap();
                check(
                    name,
                    &format!("subtree mass of {}", body_name(&case, k)),
                    &[model.subtree_mass(id)],
                    &[want],
                );
            }
        }
        assert_eq!(scene.bodies.len(), case["bodies"].as_array().unwrap().len(), "{name}: MJCF bodies");
        assert_eq!(scene.geoms.len(), model.geometries().len(), "{name}: geom info");
    }
}

#[test]
fn dynamics_match_mujoco() {
    let mut states = 0;
    for case in cases() {
        let name = case["name"].as_str().unwrap();
        let scene = mjcf::load_str(case["xml"].as_str().unwrap()).unwrap();
        let model = &scene.model;
        let mut data = Data::new(model);
        for (k, s) in case["states"].as_array().unwrap().iter().enumerate() {
            let what = |w: &str| format!("state {k}: {w}");
            let (q, v) = (dvec(&s["q"]), dvec(&s["v"]));
            // The conversions from MuJoCo's qpos and qvel agree with the generator's.
            let raw = &s["mujoco"];
            let q_conv = mjcf::q_from_mujoco(model, &floats(&raw["qpos"])).unwrap();
            check(name, &what("q from qpos"), q_conv.as_slice(), q.as_slice());
            let v_conv = mjcf::v_from_mujoco(model, &q, &floats(&raw["qvel"])).unwrap();
            check(name, &what("v from qvel"), v_conv.as_slice(), v.as_slice());
            check(
                name,
                &what("qpos"),
                mjcf::q_to_mujoco(model, &q).unwrap().as_slice(),
                &floats(&raw["qpos"]),
            );
            check(
                name,
                &what("qvel"),
                mjcf::v_to_mujoco(model, &q, &v).unwrap().as_slice(),
                &floats(&raw["qvel"]),
            );

            // Body poses (MJCF body frames, welded bodies and joint offsets included).
            forward_kinematics(model, &mut data, &q).unwrap();
            for (i, body) in scene.bodies.iter().enumerate() {
                assert_eq!(body.name, body_name(&case, i), "{name}: body order");
                let pose = data.x_wb[body.body] * body.placement;
                let p = &s["body_poses"][i];
                check(
                    name,
                    &what(&format!("position of {}", body.name)),
                    pose.translation.as_slice(),
                    &floats(&p["xpos"]),
                );
                let xmat = floats(&p["xmat"]);
                let r = Mat3::from_row_slice(&xmat);
                check(
                    name,
                    &what(&format!("rotation of {}", body.name)),
                    pose.rotation.as_slice(),
                    r.as_slice(),
                );
            }

            let m = crba(model, &mut data, &q).unwrap().clone();
            let mut worst =
                check(name, &what("mass matrix"), m.as_slice(), dmat(&s["mass_matrix"]).as_slice());
            let nle = nonlinear_effects(model, &mut data, &q, &v).unwrap().clone();
            worst = worst.max(check(name, &what("nle"), nle.as_slice(), &floats(&s["nle"])));
            let g = generalized_gravity(model, &mut data, &q).unwrap().clone();
            worst = worst.max(check(name, &what("gravity"), g.as_slice(), &floats(&s["gravity"])));
            eprintln!("{name} state {k}: largest relative error of M, nle, gravity {worst:.1e}");
            states += 1;
        }
    }
    assert_eq!(states, 15);
}

#[test]
fn statics_and_geometry() {
    let (_, scene) = case_named("humanoid_fall");
    assert_eq!(scene.statics.len(), 1);
    let floor = &scene.statics[0];
    assert_eq!(floor.name, "floor");
    assert_eq!(floor.shape, Shape::HalfSpace { normal: Vec3::z() });
    assert_eq!(floor.pose.translation, Vec3::zeros());
    assert_eq!(floor.friction, [0.7, 0.005, 0.0001]);
    assert!(floor.collides && scene.contact_enabled);
    // Body geoms: 14 capsules and a sphere, colliding, capsules along the fromto segment.
    let geoms = scene.model.geometries();
    assert_eq!(geoms.len(), 15);
    assert!(geoms.iter().all(|g| g.role == GeometryRole::Collision));
    assert!(scene.geoms.iter().all(|g| g.friction[0] == 0.7));
    let k = scene.geoms.iter().position(|g| g.name == "thigh_r").unwrap();
    let thigh = &geoms[k];
    assert_eq!(scene.model.body_name(thigh.body), "thigh_r");
    let Shape::Capsule { radius, length } = thigh.shape else { panic!("thigh is a capsule") };
    let seg = Vec3::new(0.0, 0.01, -0.34);
    assert!((radius - 0.06).abs() < 1e-15 && (length - seg.norm()).abs() < 1e-15);
    assert!((thigh.placement.translation - seg / 2.0).norm() < 1e-15);
    assert!((thigh.placement.rotation * Vec3::z() + seg.normalize()).norm() < 1e-15);
    let head = &geoms[scene.geoms.iter().position(|g| g.name == "head").unwrap()];
    assert_eq!(head.shape, Shape::Sphere { radius: 0.09 });

    // Pendulum: contact disabled, geoms visual only (contype = conaffinity = 0), no statics.
    let (_, scene) = case_named("pendulum5");
    assert!(!scene.contact_enabled && scene.statics.is_empty());
    assert!(scene.model.geometries().iter().all(|g| g.role == GeometryRole::Visual));

    // Box stack: ten 0.1 m cubes, friction 0.8, on a half-space.
    let (_, scene) = case_named("box_stack10");
    assert_eq!(scene.statics[0].friction[0], 0.8);
    assert_eq!(scene.model.geometries().len(), 10);
    for g in scene.model.geometries() {
        assert_eq!(g.shape, Shape::Box { size: Vec3::repeat(0.1) });
    }
    assert_eq!(scene.model.joint_name(1), "box0_joint");

    // Features: a tilted plane, a wall, and the geom of a body welded to the world.
    let (_, scene) = case_named("features_degree");
    let names: Vec<&str> = scene.statics.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["floor", "wall", "stand_geom0"]);
    let n = scene.statics[0].pose.rotation * Vec3::z();
    let t = 5f64.to_radians();
    assert!((n - Vec3::new(0.0, -t.sin(), t.cos())).norm() < 1e-15);
    assert_eq!(scene.statics[1].shape, Shape::Box { size: Vec3::new(2.0, 0.2, 2.0) });
    assert_eq!(scene.statics[2].shape, Shape::Cylinder { radius: 0.05, length: 0.4 });
    assert!((scene.statics[2].pose.translation - Vec3::new(0.0, 0.0, 0.5)).norm() < 1e-15);
    // A geom with contype = conaffinity = 0 is visual; the others collide.
    let hand = scene.geoms.iter().position(|g| g.name == "hand_geom0").unwrap();
    assert_eq!(scene.model.geometries()[hand].role, GeometryRole::Visual);
    assert_eq!(scene.model.geometries().iter().filter(|g| g.role == GeometryRole::Collision).count(), 8);
    // Chains: intermediate massless bodies named body__joint carry all but the last joint.
    assert_eq!(scene.model.body_name(scene.model.joint_id("slide1").unwrap()), "base__slide1");
    assert_eq!(scene.model.body_name(scene.model.joint_id("hinge1").unwrap()), "base");
}

fn err(xml: &str) -> MjcfError {
    match mjcf::load_str(xml) {
        Ok(_) => panic!("accepted:\n{xml}"),
        Err(e) => e,
    }
}

fn scene(body: &str) -> String {
    format!("<mujoco><worldbody>{body}</worldbody></mujoco>")
}

#[test]
fn bad_documents_give_typed_errors() {
    assert!(matches!(err("<mujoco><worldbody></mujoco>"), MjcfError::Xml { .. }));
    // A contact exclude naming a body the model does not have (a typo that would let the pair
    // collide); one naming real bodies loads.
    let bodies = r#"<worldbody><body name="a"><joint/><geom size="0.1"/><body name="b"><joint/><geom size="0.1"/></body></body></worldbody>"#;
    let e = err(&format!(r#"<mujoco>{bodies}<contact><exclude body1="a" body2="zzz"/></contact></mujoco>"#));
    assert!(matches!(&e, MjcfError::Invalid { what, .. } if what.contains("`zzz`")), "{e}");
    let ok = mjcf::load_str(&format!(
        r#"<mujoco>{bodies}<contact><exclude body1="a" body2="b"/></contact></mujoco>"#
    ));
    assert_eq!(ok.unwrap().contact_excludes, vec![("a".to_string(), "b".to_string())]);
    assert!(matches!(err("<robot/>"), MjcfError::Invalid { .. }));

    let e = err(&scene(r#"<body name="b"><joint/><geom name="g" type="cone" size="1"/></body>"#));
    let MjcfError::InvalidAttribute { ref element, ref attribute, ref value, .. } = e else {
        panic!("{e:?}")
    };
    assert_eq!((attribute.as_str(), value.as_str()), ("type", "cone"));
    assert!(element.contains("<geom name=\"g\">") && element.contains("line 1"), "{element}");
    let text = e.to_string();
    assert!(text.starts_with("<string>: <geom name=\"g\">"), "{text}");

    let e = err(&scene(r#"<body><joint/><geom type="box" size="0.1 -0.2 0.1"/></body>"#));
    assert!(matches!(&e, MjcfError::InvalidAttribute { attribute, .. } if attribute == "size"), "{e}");
    let e = err(&scene(r#"<body><joint/><geom type="sphere"/></body>"#));
    assert!(matches!(&e, MjcfError::InvalidAttribute { attribute, .. } if attribute == "size"), "{e}");
    let e = err(&scene(r#"<body><joint/><geom type="capsule" size="0.1 x"/></body>"#));
    assert!(matches!(&e, MjcfError::InvalidAttribute { attribute, .. } if attribute == "size"), "{e}");
    let e = err(&scene(r#"<body pos="1 2"><joint/><geom size="0.1"/></body>"#));
    assert!(matches!(&e, MjcfError::InvalidAttribute { attribute, .. } if attribute == "pos"), "{e}");
    let e = err(&scene(r#"<body><joint axis="0 0 0"/><geom size="0.1"/></body>"#));
    assert!(matches!(&e, MjcfError::InvalidAttribute { attribute, .. } if attribute == "axis"), "{e}");
    let e = err(&scene(r#"<body><joint type="screw"/><geom size="0.1"/></body>"#));
    assert!(matches!(&e, MjcfError::InvalidAttribute { attribute, .. } if attribute == "type"), "{e}");
    let e = err(&scene(r#"<body><joint range="1 -1"/><geom size="0.1"/></body>"#));
    assert!(matches!(&e, MjcfError::InvalidAttribute { attribute, .. } if attribute == "range"), "{e}");
    let e = err(&scene(r#"<body><joint/><geom size="0.1" density="-1"/></body>"#));
    assert!(matches!(&e, MjcfError::InvalidAttribute { attribute, .. } if attribute == "density"), "{e}");
    let e = err(&scene(r#"<body><joint/><geom size="0.1" class="nope"/></body>"#));
    assert!(matches!(&e, MjcfError::InvalidAttribute { attribute, .. } if attribute == "class"), "{e}");
    let e = err(&scene(r#"<body><joint/><geom type="sphere" size="0.1" fromto="0 0 0 1 0 0"/></body>"#));
    assert!(matches!(e, MjcfError::Invalid { .. }), "{e}");

    for (xml, what) in [
        (scene(r#"<body><joint/><geom type="mesh" mesh="m"/></body>"#), "geom type `mesh`"),
        (scene(r#"<body><joint stiffness="10"/><geom size="0.1"/></body>"#), "stiffness"),
        (scene(r#"<body mocap="true"><geom size="0.1"/></body>"#), "mocap"),
        (scene(r#"<body><joint/><composite type="grid" count="2 2 1"/></body>"#), "composite"),
        ("<mujoco><tendon><fixed name=\"t\"/></tendon></mujoco>".to_string(), "tendon"),
        ("<mujoco><equality><weld body1=\"a\"/></equality></mujoco>".to_string(), "equality"),
        ("<mujoco><include file=\"x.xml\"/></mujoco>".to_string(), "include"),
    ] {
        let e = err(&xml);
        assert!(matches!(e, MjcfError::Unsupported { .. }), "{xml}: {e:?}");
        assert!(e.to_string().contains(what), "{e}");
    }

    // Structure: a free joint below a moving body, a plane on a moving body, duplicate names.
    let e = err(&scene(
        r#"<body name="a"><joint/><geom size="0.1"/><body name="b"><freejoint/><geom size="0.1"/></body></body>"#,
    ));
    assert!(matches!(e, MjcfError::Invalid { .. }) && e.to_string().contains("free joint"), "{e}");
    let e = err(&scene(r#"<body name="a"><joint/><geom name="p" type="plane" size="1 1 1"/></body>"#));
    assert!(matches!(&e, MjcfError::Invalid { element, .. } if element.contains("\"p\"")), "{e}");
    let e = err(&scene(
        r#"<body name="a"><joint/><geom size="0.1"/></body><body name="a"><joint/><geom size="0.1"/></body>"#,
    ));
    assert!(
        matches!(&e, MjcfError::Model { element, source: ModelError::DuplicateName { .. }, .. } if element.contains("\"a\"")),
        "{e}"
    );

    let e = mjcf::load_file("/nonexistent/scene.xml").unwrap_err();
    assert!(matches!(&e, MjcfError::Io { file, .. } if file == "/nonexistent/scene.xml"), "{e}");
}

/// MuJoCo's schema decides which attributes exist: a misspelt one is an error (MuJoCo refuses it
/// too), not a silently ignored setting; one whose effect gelenk cannot represent is refused
/// unless it has MuJoCo's default value; names, looks and MuJoCo's solver settings load.
#[test]
fn misspelt_and_unmodelled_attributes_are_errors() {
    let body = |joint: &str, geom: &str| {
        scene(&format!(r#"<body name="b"><joint name="j" {joint}/><geom size="0.1" {geom}/></body>"#))
    };
    for (xml, attribute, element) in [
        (body(r#"dampng="1""#, ""), "dampng", "<joint name=\"j\">"),
        (body("", r#"frction="1""#), "frction", "<geom>"),
        (
            scene(r#"<body name="b" poss="0 0 1"><joint/><geom size="0.1"/></body>"#),
            "poss",
            "<body name=\"b\">",
        ),
        ("<mujoco><option timestpe=\"0.01\"/></mujoco>".to_string(), "timestpe", "<option>"),
        ("<mujoco><option><flag gravty=\"disable\"/></option></mujoco>".to_string(), "gravty", "<flag>"),
        ("<mujoco><compiler angel=\"radian\"/></mujoco>".to_string(), "angel", "<compiler>"),
        // A default joint has no name (MuJoCo's schema): its attributes are checked too.
        ("<mujoco><default><joint name=\"x\"/></default></mujoco>".to_string(), "name", "<joint name=\"x\">"),
        ("<mujoco><default><geom densty=\"5\"/></default></mujoco>".to_string(), "densty", "<geom>"),
    ] {
        let e = err(&xml);
        let MjcfError::InvalidAttribute { attribute: ref a, element: ref el, ref what, .. } = e else {
            panic!("{xml}: {e:?}")
        };
        assert_eq!(a, attribute, "{xml}");
        assert!(el.contains(element) && what.contains("MuJoCo has no such attribute"), "{e}");
    }
    for (xml, what) in [
        (body("", r#"condim="4""#), "condim=\"4\""),
        (body("", r#"margin="0.01""#), "margin"),
        (body("", r#"priority="1""#), "priority"),
        (body(r#"springdamper="0.1 1""#, ""), "springdamper"),
        ("<mujoco><default><geom condim=\"1\"/></default></mujoco>".to_string(), "condim"),
        ("<mujoco><option density=\"1.2\"/></mujoco>".to_string(), "density"),
        ("<mujoco><option><flag filterparent=\"disable\"/></option></mujoco>".to_string(), "filterparent"),
        ("<mujoco><option><flag limit=\"disable\"/></option></mujoco>".to_string(), "limit"),
        ("<mujoco><option><flag override=\"enable\"/></option></mujoco>".to_string(), "override"),
        ("<mujoco><compiler balanceinertia=\"true\"/></mujoco>".to_string(), "balanceinertia"),
    ] {
        let e = err(&xml);
        assert!(matches!(e, MjcfError::Unsupported { .. }), "{xml}: {e:?}");
        assert!(e.to_string().contains(what), "{e}");
    }
    // MuJoCo's defaults written out (numbers compared as numbers), looks and solver settings.
    let ok = format!(
        r#"<mujoco><compiler meshdir="m" balanceinertia="false"/>
             <option integrator="implicitfast" iterations="50" solver="Newton" density="0.0">
               <flag warmstart="disable" filterparent="enable"/></option>
             <default><joint group="1" solreflimit="0.02 1"/><geom rgba="1 0 0 1" condim="3"/></default>
             {}</mujoco>"#,
        scene(r#"<body name="b" user="1"><joint name="j" margin="0.01" armature="0.1"/><geom size="0.1" margin="0.0" gap="0" solref="0.01 1" priority="0"/></body>"#)
            .trim_start_matches("<mujoco>")
            .trim_end_matches("</mujoco>")
    );
    let scene = mjcf::load_str(&ok).unwrap_or_else(|e| panic!("{e}\n{ok}"));
    assert_eq!(scene.model.nv(), 1);
}

#[test]
fn truncated_and_mutated_documents_never_panic() {
    let (case, _) = case_named("humanoid_fall");
    let xml = case["xml"].as_str().unwrap();
    let mut errors = 0;
    for end in (0..xml.len()).step_by(23).filter(|&e| xml.is_char_boundary(e)) {
        errors += mjcf::load_str(&xml[..end]).is_err() as usize;
    }
    assert!(errors > 0);
    for (from, to) in [
        ("size=\".07\"", "size=\"-.07\""),
        ("fromto=\"0 -.07 0 0 .07 0\"", "fromto=\"0 0 0 0 0 0\""),
        ("axis=\"0 0 1\"", "axis=\"nan 0 1\""),
        ("range=\"-45 45\"", "range=\"-45\""),
        ("type=\"capsule\"", "type=\"\""),
        ("<freejoint name=\"root\"/>", "<freejoint/><joint/>"),
        ("timestep=\"0.002\"", "timestep=\"-1\""),
        ("damping=\"1\"", "damping=\"-1\""),
    ] {
        assert!(xml.contains(from), "{from}");
        let bad = xml.replacen(from, to, 1);
        assert!(mjcf::load_str(&bad).is_err(), "accepted {to}");
    }
}

#[test]
fn options_radians_and_defaults() {
    let xml = r#"<mujoco model="m">
      <compiler angle="radian" settotalmass="3"/>
      <option timestep="0.01" gravity="0 0 -1"><flag gravity="disable" contact="disable"/></option>
      <default><joint damping="0.5" armature="0.1"/>
        <default class="c"><joint damping="0.7"/></default></default>
      <worldbody>
        <body name="a" childclass="c"><joint name="h" range="-1 2"/><geom size="0.1"/>
          <body name="b" pos="0 0 -1"><joint name="g" class="main" type="slide" limited="false" range="0 1"/>
            <geom type="box" size="0.1 0.2 0.3" mass="2"/></body></body>
      </worldbody>
      <contact><exclude body1="a" body2="b"/></contact>
    </mujoco>"#;
    let s = mjcf::load_str(xml).unwrap();
    assert_eq!(s.model.name(), "m");
    assert_eq!(s.timestep, 0.01);
    assert_eq!(s.gravity, Vec3::zeros());
    assert!(!s.contact_enabled);
    assert!((s.model.total_mass() - 3.0).abs() < 1e-12);
    assert_eq!(s.joint_damping, [("h".to_string(), 0.7), ("g".to_string(), 0.5)]);
    assert_eq!(s.joint_armature, [("h".to_string(), 0.1), ("g".to_string(), 0.1)]);
    assert_eq!(s.model.lower_position_limit().as_slice(), [-1.0, f64::NEG_INFINITY]);
    assert_eq!(s.model.upper_position_limit().as_slice(), [2.0, f64::INFINITY]);
    assert_eq!(s.contact_excludes, [("a".to_string(), "b".to_string())]);
    // MuJoCo's default friction cone is the pyramid |λ₁| + |λ₂| ≤ μ λ_n: 4 facets.
    assert_eq!(s.friction, FrictionModel::Pyramid { facets: 4 });
}

#[test]
fn option_cone_picks_the_friction_model() {
    let scene = |cone: &str| mjcf::load_str(&format!(r#"<mujoco><option {cone}/><worldbody/></mujoco>"#));
    assert_eq!(scene("cone=\"pyramidal\"").unwrap().friction, FrictionModel::Pyramid { facets: 4 });
    assert_eq!(scene("cone=\"elliptic\"").unwrap().friction, FrictionModel::Cone);
    let e = scene("cone=\"round\"").unwrap_err();
    assert!(matches!(&e, MjcfError::InvalidAttribute { attribute, .. } if attribute == "cone"), "{e}");
}

#[test]
fn deep_chains_load_and_absurd_nesting_is_an_error() {
    // Deeper than the XML parser's recursion fits in a test thread's stack.
    let chain = |n: usize| {
        let mut xml = String::from("<mujoco><worldbody>");
        for i in 0..n {
            xml += &format!("<body name=\"b{i}\" pos=\"0 0 -0.1\"><joint/><geom size=\"0.01\"/>");
        }
        xml + &"</body>".repeat(n) + "</worldbody></mujoco>"
    };
    let scene = mjcf::load_str(&chain(3000)).unwrap();
    assert_eq!(scene.model.nv(), 3000);
    assert_eq!(scene.model.parent(3000), 2999);
    let e = err(&chain(20_000));
    assert!(matches!(e, MjcfError::Xml { .. }) && e.to_string().contains("nested"), "{e}");
}

#[test]
fn free_body_under_a_static_body_has_world_coordinates() {
    // MuJoCo's free-joint qpos is the world pose, whatever static bodies lie above the body.
    let s = mjcf::load_str(&scene(
        r#"<body name="shelf" pos="1 2 3" euler="0 0 90">
             <body name="cup" pos="0.5 0 0.1" euler="90 0 0"><freejoint/><geom size="0.05"/></body>
           </body>"#,
    ))
    .unwrap();
    let model = &s.model;
    assert_eq!(model.nq(), 7);
    // World pose: translation (1, 2, 3) + Rz(90°)(0.5, 0, 0.1) = (1, 2.5, 3.1).
    assert!((Vec3::new(s.q0[0], s.q0[1], s.q0[2]) - Vec3::new(1.0, 2.5, 3.1)).norm() < 1e-12);
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, &s.q0).unwrap();
    let cup = s.bodies.iter().find(|b| b.name == "cup").unwrap();
    let pose = data.x_wb[cup.body] * cup.placement;
    assert!((pose.translation - Vec3::new(1.0, 2.5, 3.1)).norm() < 1e-12);
    let want = gelenk::math::axis_angle(&Vec3::z(), std::f64::consts::FRAC_PI_2)
        * gelenk::math::axis_angle(&Vec3::x(), std::f64::consts::FRAC_PI_2);
    assert!((pose.rotation - want).norm() < 1e-12);
    let shelf = s.bodies.iter().find(|b| b.name == "shelf").unwrap();
    assert_eq!(shelf.body, 0);
    assert!((shelf.placement.translation - Vec3::new(1.0, 2.0, 3.0)).norm() < 1e-12);
}
