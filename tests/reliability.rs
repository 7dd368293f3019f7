//! Hostile input ends in a typed error, quickly: endless files and deep nesting are refused by
//! every reader, masses beyond the accepted range are refused at load, results that overflow are
//! errors (never NaN or infinity returned as a value), a degenerate problem is not "solved" with
//! NaN impulses, and an empty scene is an error. See docs/reliability.md.

use gelenk::error::{DynamicsError, ModelError, SolverError};
use gelenk::io::limits::ReadLimits;
use gelenk::io::problem::{problem_from_json, run_solver, CorpusSolver, SolveStatus};
use gelenk::io::scene::{self, RunOptions, SceneError};
use gelenk::io::urdf::{self, UrdfError, WarningKind};
use gelenk::model::ranges::Quantity;
use gelenk::prelude::*;
use nalgebra::DVector;
use std::path::Path;
use std::time::{Duration, Instant};

fn manifest(path: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// Runs `f`, which must return an error within a second.
fn fails_fast<T, E: std::fmt::Display>(what: &str, f: impl FnOnce() -> Result<T, E>) -> String {
    let start = Instant::now();
    let message = match f() {
        Ok(_) => panic!("{what}: accepted"),
        Err(e) => e.to_string(),
    };
    assert!(start.elapsed() < Duration::from_secs(1), "{what}: {:?}", start.elapsed());
    message
}

#[test]
fn dev_zero_is_refused_by_every_reader_within_a_second() {
    let zero = Path::new("/dev/zero");
    if !zero.exists() {
        return;
    }
    let limit = "larger than the limit of 67108864 bytes";
    for message in [
        fails_fast("urdf", || urdf::load_file(zero, &UrdfOptions::default())),
        fails_fast("mjcf", || gelenk::io::mjcf::load_file(zero)),
        fails_fast("scene", || scene::load_file(zero)),
        fails_fast("states", || gelenk::io::states::read_file(zero, 1, 1, &ReadLimits::default())),
        fails_fast("problem", || gelenk::io::problem::read_problem(zero)),
    ] {
        assert!(message.contains(limit), "{message}");
    }
}

#[test]
fn the_size_limit_is_configurable() {
    let small = ReadLimits { max_bytes: 100, ..ReadLimits::default() };
    let options = UrdfOptions { limits: small, ..UrdfOptions::default() };
    let e = urdf::load_file(manifest("models/double_pendulum_simple.urdf"), &options).unwrap_err();
    assert!(
        matches!(&e, UrdfError::Io { source, .. } if source.kind() == std::io::ErrorKind::FileTooLarge),
        "{e}"
    );
    urdf::load_file(manifest("models/double_pendulum_simple.urdf"), &UrdfOptions::default()).unwrap();
}

fn nested(depth: usize) -> String {
    format!("<robot name=\"r\"><link name=\"a\"/>{}{}</robot>", "<x>".repeat(depth), "</x>".repeat(depth))
}

#[test]
fn deep_urdf_nesting_is_refused_and_deep_but_allowed_nesting_loads() {
    let e = fails_fast("deep urdf", || urdf::load_str(&nested(20_000), &UrdfOptions::default()));
    assert!(e.contains("nested 20001 deep; at most 10000"), "{e}");
    let loaded = urdf::load_str_with_warnings(&nested(5_000), &UrdfOptions::default()).unwrap();
    assert!(matches!(&loaded.warnings[0].kind, WarningKind::UnknownElement { tag, .. } if tag == "x"));
}

fn one_link(mass: &str) -> String {
    format!(
        r#"<robot name="r"><link name="base"/><link name="arm"><inertial><origin xyz="0.5 0 0"/><mass value="{mass}"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
        <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/><origin xyz="0 0 0.5"/></joint></robot>"#
    )
}

#[test]
fn masses_beyond_the_range_are_refused_and_tiny_ones_warned() {
    let e = urdf::load_str(&one_link("1e308"), &UrdfOptions::default()).unwrap_err();
    match &e {
        UrdfError::Model { source: ModelError::OutOfRange { name, quantity, .. }, .. } => {
            assert_eq!((name.as_str(), *quantity), ("arm", Quantity::Mass));
        }
        other => panic!("{other}"),
    }
    assert!(e.to_string().contains("mass 1e308 kg is beyond 1e9 kg"), "{e}");
    let loaded = urdf::load_str_with_warnings(&one_link("1e-12"), &UrdfOptions::default()).unwrap();
    assert!(loaded.warnings.iter().any(|w| matches!(w.kind, WarningKind::TinyMass { .. })));
    assert!(urdf::load_str(&one_link("1e-12"), &UrdfOptions::strict()).is_err());
    urdf::load_str(&one_link("1e9"), &UrdfOptions::default()).unwrap();
}

#[test]
fn overflowing_dynamics_are_errors_naming_the_result_and_joint() {
    let model = urdf::load_str(&one_link("1e9"), &UrdfOptions::default()).unwrap();
    let mut data = Data::new(&model);
    let q = DVector::from_element(1, 0.3);
    let v = DVector::from_element(1, 1e160);
    let e = rnea(&model, &mut data, &q, &v, &v).unwrap_err();
    assert_eq!(e, DynamicsError::NonFiniteResult { what: "rnea", at: "joint `j`".to_string() });
    assert!(matches!(kinetic_energy(&model, &mut data, &q, &v), Err(DynamicsError::NonFiniteResult { .. })));
    assert!(matches!(
        aba(&model, &mut data, &q, &v, &v),
        Err(DynamicsError::NonFiniteResult { what: "aba", .. })
    ));
    // Ordinary values stay fine.
    let small = DVector::from_element(1, 1.0);
    assert!(rnea(&model, &mut data, &q, &small, &small).unwrap().iter().all(|x| x.is_finite()));
}

#[test]
fn a_run_whose_energy_overflows_is_an_error() {
    let text = "[[ground]]\nkind = \"plane\"\n[[body]]\nshape = \"sphere\"\nradius = 0.1\nmass = 1\nposition = [0, 0, 1]\nvelocity = [1e200, 0, 0]\n";
    let mut s = scene::load_str(text, ".").unwrap();
    let e = scene::run(&mut s, &RunOptions { duration: Some(0.01), ..RunOptions::default() }, |_| {})
        .unwrap_err();
    assert!(matches!(e, SceneError::NonFiniteResult { what: "total energy", step: 0, .. }), "{e}");
}

#[test]
fn an_empty_scene_and_a_time_step_out_of_range_are_errors() {
    for text in ["", "# nothing\n[world]\ndt = 0.01\n"] {
        let e = scene::load_str(text, ".").unwrap_err().to_string();
        assert!(e.contains("the scene is empty"), "{e}");
    }
    let e =
        scene::load_str("[world]\ndt = 1e-9\n[[ground]]\nkind = \"plane\"\n", ".").unwrap_err().to_string();
    assert!(e.contains("dt = 1e-9 s is outside [1e-7, 1] s"), "{e}");
    let deep = format!("x = {}{}\n", "[".repeat(10_000), "]".repeat(10_000));
    let e = fails_fast("deep toml", || scene::load_str(&deep, "."));
    assert!(e.contains("nested more than 128 deep"), "{e}");
}

#[test]
fn a_misspelt_joint_element_is_named_in_the_tree_error() {
    let text = r#"<robot name="r"><link name="a"/><link name="b"/>
        <jiont name="j" type="revolute"><parent link="a"/><child link="b"/></jiont></robot>"#;
    let e = urdf::load_str(text, &UrdfOptions::default()).unwrap_err().to_string();
    assert!(e.contains("several root links (a, b)"), "{e}");
    assert!(e.contains("unknown elements read past: <jiont> at line 2"), "{e}");
}

#[test]
fn pgs_refuses_to_return_nan_impulses_on_a_subnormal_diagonal() {
    let path = manifest("tests/fuzz_corpus/problem/found-subnormal-diagonal.json");
    let problem = problem_from_json(&std::fs::read_to_string(&path).unwrap(), &path).unwrap();
    let (record, _) = run_solver(CorpusSolver::Pgs, &problem);
    assert_eq!(record.status, SolveStatus::Failed, "{record:?}");
    let mut solver = CorpusSolver::Pgs.solver();
    let mut lambda = DVector::zeros(problem.rows());
    assert_eq!(solver.solve(&problem, &mut lambda).unwrap_err(), SolverError::NonFinite { solver: "pgs" });
}

/// Ten floating rovers stacked through each other on Lemke alone (a finding of the scene
/// fuzzer, `tests/fuzz_corpus/scene/found-overlapping-huskies-lemke.toml`): an LCP of about
/// 6 000 variables whose every path ends on a ray and whose M is nearly dense. A world's step
/// refuses to form that M (`lemke_matrix_entries`, 2·10⁷ by default); with no such limit, the
/// paths after the first stop at their share of the work (`LemkeOptions::fallback_share`). Each
/// ends the step with the typed error that says so.
#[test]
fn lemke_on_an_lcp_no_path_solves_stops_at_its_bounds() {
    let path = manifest("tests/fuzz_corpus/scene/found-overlapping-huskies-lemke.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let mut scene = scene::load_str(&text, manifest("models")).unwrap();
    let error = scene.world.step().expect_err("M is larger than the world's limit").to_string();
    assert!(error.contains("more than 20000000 entries"), "{error}");
    let unbounded = text.replace("[world]\n", "[world]\nlemke_matrix_entries = 0\n");
    assert_ne!(unbounded, text);
    let mut scene = scene::load_str(&unbounded, manifest("models")).unwrap();
    let error = scene.world.step().expect_err("no path solves this LCP").to_string();
    assert!(error.contains("work budget of 4.0e9 operations"), "{error}");
}

/// `LemkeOptions::max_operations` bounds a solve's work: a positive definite LCP that Lemke
/// solves by default ends with the typed error at a budget too small for its first pivot.
#[test]
fn lemke_respects_its_operations_budget() {
    use gelenk::solvers::{lemke_with_report, LemkeOptions};
    let n = 40;
    let m = nalgebra::DMatrix::from_fn(n, n, |i, j| if i == j { 4.0 } else { 1.0 / (1.0 + (i + j) as f64) });
    let q = DVector::from_fn(n, |i, _| if i % 2 == 0 { -1.0 } else { 0.5 });
    let (_, report) = lemke_with_report(&m, &q, &LemkeOptions::default()).unwrap();
    assert!(report.operations > 0.0);
    let tight = LemkeOptions { max_operations: 0.5 * report.operations, ..LemkeOptions::default() };
    match lemke_with_report(&m, &q, &tight) {
        Err(SolverError::LemkeWorkLimit { budget, .. }) => assert_eq!(budget, tight.max_operations),
        other => panic!("expected the work limit, got {other:?}"),
    }
}

/// A box on the ground for five steps, Lemke alone solving its contacts with `options`.
fn box_on_ground_with_lemke(options: gelenk::world::WorldOptions) -> Result<(), String> {
    use gelenk::model::Shape;
    use gelenk::world::{SolverKind, World, WorldOptions};
    let options = WorldOptions { solvers: vec![SolverKind::Lemke { facets: 4 }], ..options };
    let mut w = World::new(options);
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    let size = Vec3::repeat(0.1);
    let model = gelenk::scenes::free_body("box", Shape::Box { size }, RigidInertia::solid_box(1.0, size));
    let m = w.add_multibody("box", model, &gelenk::collision::MeshOptions::default()).unwrap();
    w.multibody_mut(m).state.q[2] = 0.05;
    for _ in 0..5 {
        w.step().map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// A world's Lemke solves are held to `WorldOptions::lemke_operations`: a box on the ground
/// with a budget too small for one pivot ends its first step with contact rows in the typed
/// error naming that budget; the default budget answers the same step.
#[test]
fn a_world_holds_lemke_to_its_step_budget() {
    use gelenk::world::WorldOptions;
    assert_eq!(WorldOptions::default().lemke_operations, 1e10);
    box_on_ground_with_lemke(WorldOptions::default()).unwrap();
    let tight = WorldOptions { lemke_operations: 10.0, ..Default::default() };
    let error =
        box_on_ground_with_lemke(tight).expect_err("a budget of 10 operations is too small for a pivot");
    assert!(error.contains("work budget of 1.0e1 operations"), "{error}");
}

/// A world's Lemke solves are held to `WorldOptions::lemke_matrix_entries`: the box's four
/// contacts on a 4-facet pyramid make an LCP of 24 variables whose M stores more than 40
/// entries, so a limit of 40 ends the first contact step with the typed error naming it (M is
/// not formed); the default limit answers the same steps.
#[test]
fn a_world_holds_lemke_to_its_matrix_limit() {
    use gelenk::world::WorldOptions;
    assert_eq!(WorldOptions::default().lemke_matrix_entries, 20_000_000);
    box_on_ground_with_lemke(WorldOptions::default()).unwrap();
    let tight = WorldOptions { lemke_matrix_entries: 40, ..Default::default() };
    let error =
        box_on_ground_with_lemke(tight).expect_err("M of a box's contacts stores more than 40 entries");
    assert!(error.contains("more than 40 entries"), "{error}");
}
