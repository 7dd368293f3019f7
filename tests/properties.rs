//! Property-based tests (proptest) of the readers and of `World::step` on generated input: random
//! worlds (shapes, joints, masses from 1e-3 to 1e9 kg, dt from 1e-5 to 0.05 s), generated URDF
//! documents with extreme numbers, states files and scene files. Every input ends in a typed
//! error or in a result whose numbers are all finite. `PROPTEST_CASES` sets the number of cases.

use gelenk::collision::MeshOptions;
use gelenk::math::Transform;
use gelenk::model::{BodySpec, Joint, ModelBuilder, RigidInertia, Shape};
use gelenk::prelude::*;
use gelenk::world::{World, WorldOptions};
use proptest::prelude::*;

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig { cases, failure_persistence: None, ..ProptestConfig::default() }
}

/// A number drawn log-uniformly from [10^lo, 10^hi].
fn log_uniform(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (lo..hi).prop_map(|e: f64| 10f64.powf(e))
}

#[derive(Clone, Debug)]
struct BodyCase {
    shape: Shape,
    mass: f64,
    joint: u8,
    height: f64,
    speed: [f64; 3],
}

fn shape() -> impl Strategy<Value = Shape> {
    let size = || log_uniform(-2.0, 0.3);
    prop_oneof![
        (size(), size(), size()).prop_map(|(a, b, c)| Shape::Box { size: Vec3::new(a, b, c) }),
        size().prop_map(|radius| Shape::Sphere { radius }),
        (size(), size()).prop_map(|(radius, length)| Shape::Capsule { radius, length }),
        (size(), size()).prop_map(|(radius, length)| Shape::Cylinder { radius, length }),
    ]
}

fn body_case() -> impl Strategy<Value = BodyCase> {
    (shape(), log_uniform(-3.0, 9.0), 0u8..4, 0.0..3.0f64, prop::array::uniform3(-10.0..10.0f64))
        .prop_map(|(shape, mass, joint, height, speed)| BodyCase { shape, mass, joint, height, speed })
}

fn inertia_of(shape: &Shape, mass: f64) -> RigidInertia {
    match shape {
        Shape::Box { size } => RigidInertia::solid_box(mass, *size),
        Shape::Sphere { radius } => RigidInertia::solid_sphere(mass, *radius),
        Shape::Capsule { radius, length } | Shape::Cylinder { radius, length } => {
            RigidInertia::solid_cylinder(mass, *radius, *length)
        }
        _ => RigidInertia::solid_sphere(mass, 0.1),
    }
}

fn model_of(case: &BodyCase) -> Result<Model, ModelError> {
    let joint = match case.joint {
        0 => Joint::Free,
        1 => Joint::Hinge { axis: Vec3::y() },
        2 => Joint::Ball,
        _ => Joint::Slider { axis: Vec3::z() },
    };
    let placement = Transform::from_translation(Vec3::new(0.0, 0.0, case.height));
    let mut b = ModelBuilder::new();
    b.add_body(
        BodySpec::new("body", "universe", joint, placement, inertia_of(&case.shape, case.mass))
            .with_collision(case.shape.clone(), Transform::identity()),
    );
    b.build()
}

proptest! {
    #![proptest_config(config(48))]

    /// A world of random bodies on a ground: every step is `Ok` with a finite state and energy,
    /// or a typed error; never a panic.
    #[test]
    fn world_steps_stay_finite_or_fail_typed(
        bodies in prop::collection::vec(body_case(), 1..5),
        dt in log_uniform(-5.0, (0.05f64).log10()),
    ) {
        let mut world = World::new(WorldOptions { dt, ..WorldOptions::default() });
        world.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
        for (k, case) in bodies.iter().enumerate() {
            let model = model_of(case).unwrap();
            let i = world.add_multibody(&format!("body{k}"), model, &MeshOptions::default()).unwrap();
            let v = &mut world.multibody_mut(i).state.v;
            for (j, x) in v.iter_mut().enumerate() {
                *x = case.speed[j % 3];
            }
        }
        // A body jointed to the world may be held inside the ground (an infeasible contact
        // problem, a typed error); free bodies always have a step.
        let all_free = bodies.iter().all(|b| b.joint == 0);
        for _ in 0..5 {
            if let Err(e) = world.step() {
                prop_assert!(!all_free, "step of free bodies failed: {e}");
                break;
            }
            for i in 0..world.multibody_count() {
                let s = &world.multibody(i).state;
                prop_assert!(s.q.iter().chain(s.v.iter()).all(|x| x.is_finite()));
            }
            prop_assert!(world.total_energy().is_finite());
        }
    }
}

/// A number as a generated document writes it: ordinary, extreme or not a number.
fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => (-10.0..10.0f64).prop_map(|x| format!("{x}")),
        1 => prop::sample::select(vec!["1e308", "-1e308", "1e-320", "0", "-0", "nan", "inf", "1e9", "1e12", "1e-12"])
            .prop_map(str::to_string),
    ]
}

fn urdf_link(name: String, numbers: Vec<String>) -> String {
    let n = |i: usize| numbers[i % numbers.len()].as_str();
    format!(
        r#"<link name="{name}"><inertial><origin xyz="{} {} {}"/><mass value="{}"/><inertia ixx="{}" ixy="0" ixz="0" iyy="{}" iyz="0" izz="{}"/></inertial><collision><geometry><box size="{} {} {}"/></geometry></collision></link>"#,
        n(0),
        n(1),
        n(2),
        n(3),
        n(4),
        n(5),
        n(6),
        n(7),
        n(8),
        n(9)
    )
}

fn urdf_document() -> impl Strategy<Value = String> {
    let link_numbers = prop::collection::vec(number(), 10);
    let joint = (
        0usize..6,
        prop::sample::select(vec![
            "revolute",
            "continuous",
            "prismatic",
            "fixed",
            "floating",
            "planar",
            "spherical",
        ]),
        prop::collection::vec(number(), 5),
    );
    (prop::collection::vec(link_numbers, 1..6), prop::collection::vec(joint, 0..6)).prop_map(|(links, joints)| {
        let mut text = String::from("<robot name=\"generated\">");
        for (i, numbers) in links.iter().enumerate() {
            text += &urdf_link(format!("l{i}"), numbers.clone());
        }
        for (i, (parent, kind, n)) in joints.iter().enumerate() {
            // Child i + 1 hangs from an earlier link (a tree), or from a random one (maybe not).
            let child = i + 1;
            let parent = if *parent < child { *parent } else { parent % links.len().max(1) };
            text += &format!(
                r#"<joint name="j{i}" type="{kind}"><parent link="l{parent}"/><child link="l{child}"/><origin xyz="{} {} 0"/><axis xyz="{} 0 1"/><limit lower="{}" upper="1" effort="1" velocity="1"/></joint>"#,
                n[0], n[1], n[2], n[3]
            );
        }
        text + "</robot>"
    })
}

proptest! {
    #![proptest_config(config(256))]

    /// A generated URDF loads into a model whose dynamics at the neutral configuration are
    /// finite, or is a typed error.
    #[test]
    fn generated_urdf_loads_finite_or_fails_typed(text in urdf_document(), floating: bool) {
        let options = UrdfOptions { floating_base: floating, ..UrdfOptions::default() };
        if let Ok(model) = gelenk::io::urdf::load_str(&text, &options) {
            let mut data = Data::new(&model);
            let q = model.neutral_configuration();
            let v = DVector::from_element(model.nv(), 1.0);
            if let Ok(tau) = rnea(&model, &mut data, &q, &v, &v) {
                prop_assert!(tau.iter().all(|x| x.is_finite()));
            }
            if let Ok(a) = aba(&model, &mut data, &q, &v, &v) {
                prop_assert!(a.iter().all(|x| x.is_finite()));
            }
            prop_assert!(model.total_mass().is_finite());
        }
    }

    /// A states document parses into vectors of the model's sizes holding finite numbers, or is
    /// a typed error (an unknown key included).
    #[test]
    fn states_parse_to_finite_vectors_or_fail_typed(
        entries in prop::collection::vec(
            (prop::sample::select(vec!["q", "v", "a", "tau", "x"]), prop::collection::vec(number(), 0..4)),
            0..5,
        ),
    ) {
        let body: Vec<String> = entries
            .iter()
            .map(|(k, xs)| format!("\"{k}\": [{}]", xs.join(", ")))
            .collect();
        let text = format!("{{\"states\": [{{{}}}]}}", body.join(", "));
        match gelenk::io::states::parse(&text, 2, 3) {
            Ok(states) => {
                prop_assert!(!entries.iter().any(|(k, _)| *k == "x"));
                for s in states {
                    prop_assert_eq!(s.q.len(), 2);
                    prop_assert_eq!((s.v.len(), s.a.len(), s.tau.len()), (3, 3, 3));
                    prop_assert!(s.q.iter().chain(&s.v).chain(&s.a).chain(&s.tau).all(|x| x.is_finite()));
                }
            }
            Err(e) => prop_assert!(!e.to_string().is_empty()),
        }
    }

    /// A scene of generated bodies loads and runs a few steps with a finite summary, or is a
    /// typed error.
    #[test]
    fn generated_scenes_run_finite_or_fail_typed(
        count in 1usize..20,
        mass in log_uniform(-3.0, 9.0),
        size in log_uniform(-2.0, 0.5),
        dt in log_uniform(-5.0, (0.05f64).log10()),
        shape in prop::sample::select(vec!["box", "sphere", "capsule", "cylinder"]),
        height in number(),
    ) {
        let dims = match shape {
            "box" => format!("size = [{size}, {size}, {size}]"),
            "sphere" => format!("radius = {size}"),
            _ => format!("radius = {size}\nlength = {size}"),
        };
        let text = format!(
            "[world]\ndt = {dt}\n[[ground]]\nkind = \"plane\"\n[[body]]\nname = \"b\"\nshape = \"{shape}\"\n{dims}\nmass = {mass}\nposition = [0, 0, {height}]\ncount = {count}\nspacing = [0, 0, {}]\n",
            2.5 * size
        );
        if let Ok(mut scene) = gelenk::io::scene::load_str(&text, ".") {
            let options = gelenk::io::scene::RunOptions { duration: Some(3.0 * dt), ..Default::default() };
            if let Ok(summary) = gelenk::io::scene::run(&mut scene, &options, |_| {}) {
                prop_assert!(summary.energy_start.is_finite() && summary.energy_end.is_finite());
            }
        }
    }
}

use nalgebra::DVector;
