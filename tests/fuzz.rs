//! Mutation fuzzing of every reader on the corpus in `tests/fuzz_corpus/` (see `fuzz_support` and
//! `docs/reliability.md`): URDF, MJCF, scene TOML, states JSON, problem JSON, and the corpus's
//! CBF and QPS files (solved by clarabel when small, for CBF). Each input must
//! end in a typed error or in a result whose numbers are all finite: the model's dynamics at its
//! neutral configuration and a few world steps on a ground for URDF and MJCF, a short run for a
//! scene, the dynamics on each state for states, every corpus solver for a problem. A panic, a
//! case over its time budget or a non-finite number returned as `Ok` fails the test. The FCLIB
//! reader (HDF5, the `fclib` feature) has its own targets in `tests/fuzz_fclib.rs`.
//!
//! CI runs each target for `GELENK_FUZZ_SECONDS` (default 8 s); an hour per target:
//! `GELENK_FUZZ_SECONDS=3600 GELENK_FUZZ_SEED=random cargo test --profile ci --test fuzz -- --test-threads 1 --nocapture`
//! (`--nocapture` shows each target's summary: cases, seed, longest case).

mod fuzz_support;

use fuzz_support::{finite, fuzz, Verdict};
use gelenk::collision::MeshOptions;
use gelenk::io::problem::{
    parse_cbf, parse_qps, problem_from_json, run_solver, solve_cbf_with_clarabel, CorpusSolver,
};
use gelenk::io::scene::RunOptions;
use gelenk::math::Transform;
use gelenk::model::Shape;
use gelenk::prelude::*;
use gelenk::world::{World, WorldOptions};
use nalgebra::DVector;
use std::path::Path;
use std::sync::OnceLock;
use std::time::Duration;

/// Budget of one case: a reader and a few steps of a small model take milliseconds.
const CASE: Duration = Duration::from_secs(10);
/// Budget of one scene case: building up to `count = 100000` bodies takes seconds.
const SCENE_CASE: Duration = Duration::from_secs(30);
/// Most degrees of freedom of a model that a case steps in a world (larger ones are only read).
const STEPPED_DOFS: usize = 200;

const XML_TOKENS: &[&str] = &[
    "<link name=\"x\">",
    "</link>",
    "<joint name=\"j\" type=\"floating\"><parent link=\"x\"/><child link=\"y\"/></joint>",
    "<joint name=\"k\" type=\"revolute\">",
    "</joint>",
    "<inertial><mass value=\"1e308\"/><inertia ixx=\"1e308\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial>",
    "<origin xyz=\"1e300 0 0\" rpy=\"0 1e300 0\"/>",
    "<axis xyz=\"0 0 0\"/>",
    "<limit lower=\"1\" upper=\"-1\" effort=\"0\" velocity=\"0\"/>",
    "<collision><geometry><box size=\"0 0 0\"/></geometry></collision>",
    "<geometry><mesh filename=\"/dev/zero\"/></geometry>",
    "<geometry><sphere radius=\"-1\"/></geometry>",
    "<gelenk joint=\"j\" type=\"hinge2\" axis2=\"0 1 0\" suspension_stiffness=\"1e308\"/>",
    "<gelenk joint=\"j\" type=\"universal\" axis2=\"1 0 0\"/>",
    "<body name=\"b\" pos=\"0 0 1\"><freejoint/><geom type=\"box\" size=\"1 1 1\"/>",
    "</body>",
    "<joint type=\"ball\"/>",
    "<geom type=\"capsule\" fromto=\"0 0 0 0 0 0\" size=\"0.1\"/>",
    "<default class=\"c\"><geom size=\"1e308\"/></default>",
    "<!-- x -->",
    "<![CDATA[ ]]>",
    "&amp;",
    "\u{0}",
];

const TOML_TOKENS: &[&str] = &[
    "\n[[body]]\nname = \"b\"\nshape = \"box\"\nsize = [1, 1, 1]\nmass = 1\n",
    "\n[[ground]]\n",
    "count = 1000\n",
    "count = 100000\n",
    "mass = 1e308\n",
    "dt = 1e-300\n",
    "duration = 1e300\n",
    "spacing = [0, 0, 0]\n",
    "jitter = 1e300\n",
    "position = [0, 0, 1e300]\n",
    "velocity = [1e300, 0, 0]\n",
    "[world]\n",
    "solver = \"lemke\"\n",
    "friction = \"pyramid1000000\"\n",
    "[[",
    "]]",
    "{ a = [[[[1]]]] }",
    "\"\"\"",
    "#",
];

const JSON_TOKENS: &[&str] = &[
    "[",
    "]",
    "{",
    "}",
    ",",
    "\"q\": [1e308],",
    "\"x\": 1,",
    "\"rows\": 1000000,",
    "\"facets\": 1000000",
    "\"nv\": 4294967296,",
    "null",
    "1e400",
    "-0",
    "\"states\": []",
    "\"mu\": -1,",
    "\"normal\": 99,",
];

/// The dynamics of `model` at `q` and a velocity and force made from it, each `Ok` finite; then,
/// for a small model, three steps of a world with a ground, each `Ok` step leaving a finite state.
fn exercise(model: &Model, q: &DVector<f64>) -> Verdict {
    let mut data = Data::new(model);
    let nv = model.nv();
    let v = DVector::from_fn(nv, |i, _| (i as f64 * 0.7).sin());
    let tau = DVector::from_fn(nv, |i, _| (i as f64 * 1.3).cos());
    if let Ok(m) = crba(model, &mut data, q) {
        finite("mass matrix", m.as_slice())?;
    }
    if let Ok(x) = rnea(model, &mut data, q, &v, &tau) {
        finite("rnea", x.as_slice())?;
    }
    if let Ok(x) = aba(model, &mut data, q, &v, &tau) {
        finite("aba", x.as_slice())?;
    }
    if let Ok(e) = kinetic_energy(model, &mut data, q, &v) {
        finite("kinetic energy", &[e])?;
    }
    if nv > STEPPED_DOFS {
        return Ok(());
    }
    let mut world = World::new(WorldOptions::default());
    if world.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).is_err()
    {
        return Ok(());
    }
    let Ok(i) = world.add_multibody("model", model.clone(), &MeshOptions::default()) else { return Ok(()) };
    if world.multibody(i).state.q.len() == q.len() {
        world.multibody_mut(i).state.q.copy_from(q);
    }
    for _ in 0..3 {
        if world.step().is_err() {
            break;
        }
        let state = &world.multibody(i).state;
        finite("q after a step", state.q.as_slice())?;
        finite("v after a step", state.v.as_slice())?;
    }
    Ok(())
}

fn urdf(input: &[u8]) -> Verdict {
    let text = String::from_utf8_lossy(input);
    for options in [UrdfOptions::default(), UrdfOptions::floating()] {
        if let Ok(loaded) = gelenk::io::urdf::load_str_with_warnings(&text, &options) {
            let q = loaded.model.neutral_configuration();
            exercise(&loaded.model, &q)?;
        }
    }
    Ok(())
}

fn mjcf(input: &[u8]) -> Verdict {
    let text = String::from_utf8_lossy(input);
    if let Ok(scene) = gelenk::io::mjcf::load_str(&text) {
        exercise(&scene.model, &scene.q0)?;
    }
    Ok(())
}

fn scene(input: &[u8]) -> Verdict {
    let text = String::from_utf8_lossy(input);
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let Ok(mut scene) = gelenk::io::scene::load_str(&text, &models) else { return Ok(()) };
    let dofs: usize = (0..scene.world.multibody_count()).map(|i| scene.world.multibody(i).model().nv()).sum();
    if dofs > STEPPED_DOFS {
        return Ok(());
    }
    let dt = scene.world.options().dt;
    let options = RunOptions { duration: Some(3.0 * dt), ..RunOptions::default() };
    if let Ok(summary) = gelenk::io::scene::run(&mut scene, &options, |_| {}) {
        finite(
            "run summary (energy start, end, drift, penetration)",
            &[summary.energy_start, summary.energy_end, summary.energy_drift, summary.max_penetration],
        )?;
        for row in &summary.recording.rows {
            finite("recorded values", &row.values)?;
        }
    }
    Ok(())
}

/// A two-joint and a six-joint model for the states files.
fn states_models() -> &'static [Model; 2] {
    static MODELS: OnceLock<[Model; 2]> = OnceLock::new();
    MODELS.get_or_init(|| {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
        let load = |name: &str| gelenk::io::urdf::load_file(dir.join(name), &UrdfOptions::default()).unwrap();
        [load("double_pendulum_simple.urdf"), load("ur5_robot.urdf")]
    })
}

fn states(input: &[u8]) -> Verdict {
    let text = String::from_utf8_lossy(input);
    for model in states_models() {
        let Ok(states) = gelenk::io::states::parse(&text, model.nq(), model.nv()) else { continue };
        let mut data = Data::new(model);
        for s in &states {
            if let Ok(x) = rnea(model, &mut data, &s.q, &s.v, &s.a) {
                finite("rnea", x.as_slice())?;
            }
            if let Ok(x) = aba(model, &mut data, &s.q, &s.v, &s.tau) {
                finite("aba", x.as_slice())?;
            }
            if let Ok(x) = generalized_gravity(model, &mut data, &s.q) {
                finite("gravity", x.as_slice())?;
            }
            if let Ok(e) = potential_energy(model, &mut data, &s.q) {
                finite("potential energy", &[e])?;
            }
        }
    }
    Ok(())
}

fn problem(input: &[u8]) -> Verdict {
    let text = String::from_utf8_lossy(input);
    let Ok(problem) = problem_from_json(&text, Path::new("problem.json")) else { return Ok(()) };
    if problem.rows() > 500 {
        return Ok(());
    }
    for kind in CorpusSolver::ALL {
        let (record, _) = run_solver(kind, &problem);
        finite(&format!("{} impulses", kind.name()), &record.lambda)?;
        finite(&format!("{} velocities", kind.name()), &record.w)?;
    }
    Ok(())
}

/// Tokens of CBF and QPS files: section keywords, huge counts and indices, cones, non-finite
/// and overflowing numbers.
const FORMAT_TOKENS: &[&str] = &[
    "\nVAR\n4294967296 1\nF 4294967296\n",
    "\nCON\n3 1\nQ 3\n",
    "\nACOORD\n1\n0 0 nan\n",
    "\nBCOORD\n1\n99999999 1\n",
    "\nOBJACOORD\n2\n0 inf\n",
    "L+ 1000000\n",
    "QR 1\n",
    "\nOBJSENSE\nMAX\n",
    "\nROWS\n N obj\n E e0\n",
    "\nCOLUMNS\n x0 obj 1e400\n",
    "\nBOUNDS\n UP bnd x0 -1\n MI bnd x0\n",
    "\nQUADOBJ\n x0 x1 -1e308\n",
    "\nRHS\n rhs e0 NaN\n",
    " x4294967296 ",
    "\nENDATA\n",
    "-0",
    "1e-320",
    "\u{0}",
];

/// A CBF file read, and, if it has at most 200 variables, solved by clarabel: a typed error or
/// finite numbers.
fn cbf(input: &[u8]) -> Verdict {
    let text = String::from_utf8_lossy(input);
    let Ok(file) = parse_cbf(&text, Path::new("problem.cbf")) else { return Ok(()) };
    finite("objective", &file.objective.iter().map(|c| c.1).collect::<Vec<_>>())?;
    finite("constraint matrix", &file.a.iter().map(|c| c.2).collect::<Vec<_>>())?;
    finite("constraint constants", &file.b.iter().map(|c| c.1).collect::<Vec<_>>())?;
    if file.variable_count() > 200 || file.constraint_count() > 400 {
        return Ok(());
    }
    if let Ok((objective, x)) = solve_cbf_with_clarabel(&file) {
        finite("clarabel's objective", &[objective])?;
        finite("clarabel's x", &x)?;
    }
    Ok(())
}

/// A QPS file read: a typed error or a QP whose matrices and right-hand sides are finite (bounds
/// may be infinite: no bound).
fn qps(input: &[u8]) -> Verdict {
    let text = String::from_utf8_lossy(input);
    let Ok((_, qp)) = parse_qps(&text, Path::new("problem.qps")) else { return Ok(()) };
    for (what, values) in [("P", qp.p.as_slice()), ("q", qp.q.as_slice()), ("G", qp.g.as_slice())] {
        finite(what, values)?;
    }
    for (what, values) in [("h", qp.h.as_slice()), ("A", qp.a.as_slice()), ("b", qp.b.as_slice())] {
        finite(what, values)?;
    }
    if qp.lb.iter().chain(qp.ub.iter()).any(|x| x.is_nan()) {
        return Err("a NaN bound read as Ok".into());
    }
    Ok(())
}

#[test]
fn fuzz_urdf() {
    assert!(fuzz("urdf", XML_TOKENS, CASE, urdf) > 0);
}

#[test]
fn fuzz_mjcf() {
    assert!(fuzz("mjcf", XML_TOKENS, CASE, mjcf) > 0);
}

#[test]
fn fuzz_scene() {
    assert!(fuzz("scene", TOML_TOKENS, SCENE_CASE, scene) > 0);
}

#[test]
fn fuzz_states() {
    assert!(fuzz("states", JSON_TOKENS, CASE, states) > 0);
}

#[test]
fn fuzz_problem() {
    assert!(fuzz("problem", JSON_TOKENS, CASE, problem) > 0);
}

#[test]
fn fuzz_cbf() {
    assert!(fuzz("cbf", FORMAT_TOKENS, CASE, cbf) > 0);
}

#[test]
fn fuzz_qps() {
    assert!(fuzz("qps", FORMAT_TOKENS, CASE, qps) > 0);
}

/// The harness itself finds what it is meant to find: a panicking target fails the test.
#[test]
#[should_panic(expected = "panic: planted")]
fn the_fuzzer_reports_a_panic() {
    fn planted(input: &[u8]) -> Verdict {
        if input.len() > 1 {
            panic!("planted");
        }
        Ok(())
    }
    fuzz("states", JSON_TOKENS, CASE, planted);
}

/// … and a non-finite result returned as `Ok`.
#[test]
#[should_panic(expected = "wrong result: planted[0] = NaN")]
fn the_fuzzer_reports_a_non_finite_result() {
    fuzz("states", JSON_TOKENS, CASE, |_| finite("planted", &[f64::NAN]));
}

/// … and a case that runs past its budget (a hang).
#[test]
#[should_panic(expected = "(a hang)")]
fn the_fuzzer_reports_a_hang() {
    fn spin(input: &[u8]) -> Verdict {
        let start = std::time::Instant::now();
        let mut x = input.len() as f64;
        while input.len() > 1 && start.elapsed() < Duration::from_secs(2) {
            x = std::hint::black_box(x.sqrt() + 1.0);
        }
        finite("spin", &[x])
    }
    fuzz("states", JSON_TOKENS, Duration::from_millis(200), spin);
}
