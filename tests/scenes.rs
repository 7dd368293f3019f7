//! Scene files (`models/*.toml`) and `gelenk::io::scene`: every shipped scene loads and runs; bad
//! scenes give errors with the line and the key; counts and spacing place bodies; runs record
//! and summarise.

use gelenk::io::scene::{self, RunOptions, SceneError};
use gelenk::world::SolverKind;
use std::path::{Path, PathBuf};

fn models_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("models")
}

fn scene_files() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(models_dir())
        .expect("models/ exists")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    files
}

/// The error of loading `text`, as a message.
fn load_error(text: &str) -> String {
    match scene::load_str(text, models_dir()) {
        Ok(s) => panic!("loaded a bad scene: {s:?}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn every_scene_file_loads_and_runs_for_0_2_s() {
    let files = scene_files();
    for name in ["box_stack10", "ball_bounce", "pendulum_limit", "panda_drop", "pile"] {
        assert!(
            files.iter().any(|f| f.file_stem().unwrap() == name),
            "models/{name}.toml is missing: {files:?}"
        );
    }
    for file in files {
        let mut s = scene::load_file(&file).unwrap_or_else(|e| panic!("{e}"));
        assert!(s.world.multibody_count() > 0, "{}", file.display());
        let options = RunOptions { duration: Some(0.2), ..RunOptions::default() };
        let summary =
            scene::run(&mut s, &options, |_| {}).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let dt = s.world.options().dt;
        assert_eq!(summary.steps, (0.2 / dt).round() as u64, "{}", file.display());
        assert!((s.world.time() - 0.2).abs() < 1e-9);
        assert!(summary.energy_start.is_finite() && summary.energy_end.is_finite(), "{}", file.display());
        for i in 0..s.world.multibody_count() {
            let state = &s.world.multibody(i).state;
            assert!(state.q.iter().chain(state.v.iter()).all(|x| x.is_finite()), "{}", file.display());
        }
    }
}

#[test]
fn scene_paths_resolve_against_the_scene_file() {
    let s = scene::load_file(models_dir().join("panda_drop.toml")).unwrap();
    assert_eq!(s.name, "panda_drop");
    let panda = s.multibody("panda").unwrap();
    let model = s.world.multibody(panda).model();
    assert_eq!(model.nq(), 9);
    let q = &s.world.multibody(panda).state.q;
    let j4 = model.joint_id("panda_joint4").unwrap();
    assert_eq!(q[model.idx_q(j4)], -2.356);
    // Its collision meshes are not in the repository: skipped, with a warning each.
    assert!(!s.warnings.is_empty());
    assert!(s.warnings.iter().all(|w| w.contains("skipped")), "{:?}", s.warnings);
}

#[test]
fn an_unknown_key_is_an_error_naming_the_key_and_its_line() {
    let message =
        load_error("[world]\ndt = 0.001\n\n[[body]]\nshape = \"box\"\nsize = [1, 1, 1]\ncolour = \"red\"\n");
    assert!(message.contains("line 7"), "{message}");
    assert!(message.contains("colour"), "{message}");
    assert!(message.contains("body[0].colour"), "{message}");

    let message = load_error("[world]\ndt = 0.001\ntimestep = 0.002\n");
    assert!(message.contains("line 3") && message.contains("world.timestep"), "{message}");

    let message = load_error("name = \"x\"\n[wrold]\ndt = 0.001\n");
    assert!(message.contains("line 2") && message.contains("wrold"), "{message}");

    // In an inline table.
    let message = load_error(
        "[[urdf]]\npath = \"panda.urdf\"\nmissing_meshes = \"skip\"\nservo = { gain = 1, max_velocity = 1, max_force = 1, kp = 3 }\n",
    );
    assert!(message.contains("line 4") && message.contains("urdf[0].servo.kp"), "{message}");
}

#[test]
fn bad_values_are_errors_with_their_line() {
    // Negative mass.
    let message = load_error("[[ground]]\n\n[[body]]\nshape = \"sphere\"\nradius = 0.1\nmass = -2\n");
    assert!(message.contains("line 6") && message.contains("body[0].mass"), "{message}");
    assert!(message.contains("positive"), "{message}");
    // Unknown solver name, second in the list.
    let message = load_error("[world]\ndt = 0.001\nsolver = [\"pgs\", \"simplex\"]\n");
    assert!(message.contains("line 3") && message.contains("world.solver"), "{message}");
    assert!(message.contains("simplex"), "{message}");
    // Unknown shape, friction and integrator.
    let message = load_error("[[body]]\nshape = \"cone\"\n");
    assert!(message.contains("line 2") && message.contains("cone"), "{message}");
    let message = load_error("[world]\nfriction = \"pyramid2\"\n");
    assert!(message.contains("line 2") && message.contains("pyramid2"), "{message}");
    let message = load_error("[world]\n\nintegrator = \"rk5\"\n");
    assert!(message.contains("line 3") && message.contains("rk5"), "{message}");
    // Wrong type, out of range, negative dt.
    let message = load_error("[contact]\nmu = \"high\"\n");
    assert!(message.contains("line 2") && message.contains("contact.mu"), "{message}");
    let message = load_error("[contact]\nmu = 0.5\nrestitution = 1.5\n");
    assert!(message.contains("line 3") && message.contains("contact.restitution"), "{message}");
    let message = load_error("[world]\ndt = -0.001\n");
    assert!(message.contains("line 2") && message.contains("world.dt"), "{message}");
    // A count of zero, a vector of two.
    let message = load_error("[[body]]\nshape = \"box\"\nsize = [1, 1, 1]\ncount = 0\n");
    assert!(message.contains("line 4") && message.contains("body[0].count"), "{message}");
    let message = load_error("[[body]]\nshape = \"box\"\nsize = [1, 1, 1]\nposition = [1, 2]\n");
    assert!(message.contains("line 4") && message.contains("body[0].position"), "{message}");
    // Counts that would exhaust memory (or wrap) while building, a PGS of no sweeps, a pyramid
    // of a million facets.
    let message =
        load_error("[[body]]\nshape = \"box\"\nsize = [1, 1, 1]\ncount = [4294967296, 4294967296, 1]\n");
    assert!(message.contains("line 4") && message.contains("at most 100000 copies"), "{message}");
    // Copies within the per-entry cap whose bodies exceed the scene's: 100 000 ragdolls of 16
    // bodies, and three entries of 70 000 boxes.
    let message = load_error(
        "[[urdf]]\npath = \"ragdoll.urdf\"\nfloating = true\ncount = 100000\nspacing = [0, 0, 1]\n",
    );
    assert!(
        message.contains("line 1") && message.contains("1600000 moving bodies; at most 200000"),
        "{message}"
    );
    let boxes = "[[body]]\nshape = \"box\"\nsize = [1, 1, 1]\ncount = 70000\nspacing = [2, 0, 0]\n";
    let message = load_error(&boxes.repeat(3));
    assert!(message.contains("line 11") && message.contains("210000 moving bodies"), "{message}");
    let message =
        load_error("[[ground]]\nkind = \"heightfield\"\nsize = [1, 1]\nsamples = [4294967296, 4294967296]\n");
    assert!(message.contains("more than 4194304 heights"), "{message}");
    let message = load_error("[world]\nsolver = \"pgs0\"\n");
    assert!(message.contains("line 2") && message.contains("pgs0"), "{message}");
    let message = load_error("[world]\nfriction = \"pyramid1000000\"\n");
    assert!(message.contains("line 2") && message.contains("N <= 64"), "{message}");
    // Copies that would lie on each other (a row without spacing, a grid flat along an axis).
    let message = load_error("[[body]]\nshape = \"box\"\nsize = [1, 1, 1]\ncount = 3\nspacing = [0, 0, 0]\n");
    assert!(message.contains("would lie on each other"), "{message}");
    let message =
        load_error("[[body]]\nshape = \"box\"\nsize = [1, 1, 1]\ncount = [2, 2, 1]\nspacing = [2, 0, 0]\n");
    assert!(message.contains("would lie on each other"), "{message}");
    scene::load_str(
        "[[body]]\nshape = \"box\"\nsize = [1, 1, 1]\ncount = [2, 2, 1]\nspacing = [2, 2, 0]\n",
        models_dir(),
    )
    .unwrap();
    // A URDF given as a scene.
    let message = load_error("<?xml version=\"1.0\"?>\n<robot name=\"r\"/>\n");
    assert!(message.contains("not a scene"), "{message}");
    // A zero quaternion for a ball joint.
    let message =
        load_error("[[urdf]]\npath = \"ragdoll.urdf\"\nfloating = true\njoints = { neck = [0, 0, 0, 0] }\n");
    assert!(message.contains("line 4") && message.contains("quaternion"), "{message}");
    // Not TOML at all.
    let message = load_error("[world\ndt = 1\n");
    assert!(message.contains("line 1"), "{message}");
}

#[test]
fn inconsistent_entries_are_errors_at_their_entry() {
    // A box without its size: the entry's header line.
    let message = load_error("[world]\ndt = 0.001\n\n[[body]]\nshape = \"box\"\nradius = 1\n");
    assert!(message.contains("line 4") && message.contains("body[0]"), "{message}");
    // Copies without spacing.
    let message = load_error("[[body]]\nshape = \"sphere\"\nradius = 0.1\ncount = 3\n");
    assert!(message.contains("line 1") && message.contains("spacing"), "{message}");
    // Two bodies of the same name.
    let message =
        load_error("[[body]]\nshape = \"sphere\"\nradius = 0.1\n\n[[body]]\nshape = \"sphere\"\nradius = 0.1\nname = \"body0\"\n");
    assert!(message.contains("line 5") && message.contains("body0"), "{message}");
    // An unknown material.
    let message = load_error("[[body]]\nshape = \"sphere\"\nradius = 0.1\nmaterial = \"ice\"\n");
    assert!(
        message.contains("line 4") && message.contains("body[0].material") && message.contains("ice"),
        "{message}"
    );
    // A plane with heightfield keys.
    let message = load_error("[[ground]]\nkind = \"plane\"\nheights = [[0, 0], [0, 0]]\n");
    assert!(message.contains("line 1") && message.contains("heights"), "{message}");
    // A URDF that is not there: the line of its path.
    let message = load_error("[[urdf]]\nname = \"r\"\npath = \"no/such.urdf\"\n");
    assert!(message.contains("line 3") && message.contains("urdf[0].path"), "{message}");
    // A joint the model does not have, and an initial position outside the limits.
    let panda = "[[urdf]]\npath = \"panda.urdf\"\nmissing_meshes = \"skip\"\n";
    let message = load_error(&format!("{panda}joints = {{ elbow = 1.0 }}\n"));
    assert!(message.contains("line 4") && message.contains("urdf[0].joints.elbow"), "{message}");
    let message = load_error(&format!("{panda}joints = {{ panda_joint4 = 0.5 }}\n"));
    assert!(message.contains("line 4") && message.contains("outside its limits"), "{message}");
    // Meshes missing without `missing_meshes = "skip"`.
    let message = load_error("[[urdf]]\npath = \"panda.urdf\"\n");
    assert!(message.contains("line 2") && message.contains("not found"), "{message}");
}

#[test]
fn errors_are_typed() {
    let e = scene::load_str("[world]\ndt = 0\n", ".").unwrap_err();
    match e {
        SceneError::Invalid { at, .. } => {
            assert_eq!((at.line, at.column, at.key.as_str()), (2, 6, "world.dt"));
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(scene::load_file("models/none.toml"), Err(SceneError::Io { .. })));
}

#[test]
fn count_and_spacing_make_rows_and_grids() {
    let s = scene::load_str(
        r#"
        [world]
        sleep = false
        [[body]]
        name = "row"
        shape = "sphere"
        radius = 0.05
        position = [1, 2, 3]
        count = 4
        spacing = [0.5, 0, 0.1]

        [[body]]
        name = "grid"
        shape = "box"
        size = [0.1, 0.2, 0.3]
        mass = 2
        position = [0, 0, 1]
        rpy = [0, 0, 1.5707963267948966]
        count = [3, 2, 2]
        spacing = [0.2, 0.3, 0.4]
        velocity = [1, 0, 0]

        [[body]]
        shape = "capsule"
        radius = 0.1
        length = 0.2
        "#,
        ".",
    )
    .unwrap();
    assert_eq!(s.world.multibody_count(), 4 + 12 + 1);
    for k in 0..4 {
        let i = s.multibody(&format!("row{k}")).unwrap();
        let q = &s.world.multibody(i).state.q;
        let expected = [1.0 + 0.5 * k as f64, 2.0, 3.0 + 0.1 * k as f64];
        for (a, e) in expected.iter().enumerate() {
            assert!((q[a] - e).abs() < 1e-12, "row{k}: {q}");
        }
    }
    for (i, j, k) in [(0, 0, 0), (2, 1, 1), (1, 0, 1)] {
        let index = s.multibody(&format!("grid_{i}_{j}_{k}")).unwrap();
        let mb = s.world.multibody(index);
        let q = &mb.state.q;
        let expected = [0.2 * i as f64, 0.3 * j as f64, 1.0 + 0.4 * k as f64];
        for (a, e) in expected.iter().enumerate() {
            assert!((q[a] - e).abs() < 1e-12, "grid_{i}_{j}_{k}: {q}");
        }
        // Yawed 90°: quaternion (0, 0, sin 45°, cos 45°); the world velocity +x is −y in the body.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!((q[5] - h).abs() < 1e-9 && (q[6] - h).abs() < 1e-9, "{q}");
        let v = &mb.state.v;
        assert!((v[0]).abs() < 1e-9 && (v[1] + 1.0).abs() < 1e-9, "{v}");
        assert!((mb.model().total_mass() - 2.0).abs() < 1e-12);
    }
    assert!(s.multibody("grid_3_0_0").is_none());
    let capsule = s.multibody("body2").unwrap();
    let volume = std::f64::consts::PI * (0.01 * 0.2 + 4.0 / 3.0 * 0.001);
    assert!((s.world.multibody(capsule).model().total_mass() - 1000.0 * volume).abs() < 1e-9);
}

#[test]
fn fixed_bodies_grounds_and_materials_become_colliders() {
    let s = scene::load_str(
        r#"
        [[material]]
        index = 2
        name = "ice"
        mu = 0.05

        [[pair]]
        materials = [0, "ice"]
        mu = 0.1

        [[ground]]
        material = "ice"
        [[ground]]
        kind = "slope"
        angle_deg = 20
        position = [5, 0, 0]
        [[ground]]
        kind = "heightfield"
        size = [2, 2]
        heights = [[0, 0.1, 0], [0, 0.2, 0]]
        position = [-5, 0, 0]

        [[body]]
        shape = "box"
        size = [1, 1, 1]
        fixed = true
        count = 3
        spacing = [0, 2, 0]
        [[body]]
        shape = "sphere"
        radius = 0.1
        material = 2
        "#,
        ".",
    )
    .unwrap();
    let colliders = s.world.collision().colliders();
    assert_eq!(colliders.len(), 3 + 3 + 1);
    assert_eq!(s.world.multibody_count(), 1);
    assert_eq!(colliders[0].material, 2);
    let ball = s.world.collision().colliders_of(0)[0];
    assert_eq!(colliders[ball].material, 2);
}

#[test]
fn urdf_entries_take_pose_joints_limits_and_floating_base() {
    let s = scene::load_str(
        r#"
        [[urdf]]
        path = "double_pendulum_simple.urdf"
        name = "fixed"
        position = [1, 2, 3]
        rpy = [0, 0, 1.5707963267948966]
        joints = { joint1 = 0.3 }
        limits = { joint1 = [-0.5, 0.5] }

        [[urdf]]
        path = "double_pendulum_simple.urdf"
        name = "floating"
        floating = true
        position = [0, 0, 2]
        velocity = [0, 0, 1]
        joint_velocities = { joint2 = -1 }
        "#,
        models_dir(),
    )
    .unwrap();
    let fixed = s.world.multibody(s.multibody("fixed").unwrap());
    let m = fixed.model();
    assert_eq!(m.nq(), 2);
    assert_eq!(fixed.state.q[0], 0.3);
    assert_eq!((m.lower_position_limit()[0], m.upper_position_limit()[0]), (-0.5, 0.5));
    // joint1 sits at (0.025, 0, 0) in the base link, which is yawed 90° at (1, 2, 3).
    let j1 = m.placement(m.joint_id("joint1").unwrap());
    assert!((j1.translation - nalgebra::Vector3::new(1.0, 2.025, 3.0)).norm() < 1e-12, "{j1:?}");
    let floating = s.world.multibody(s.multibody("floating").unwrap());
    assert_eq!(floating.model().nq(), 9);
    assert_eq!(floating.state.q.as_slice()[..7], [0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 1.0]);
    assert_eq!(floating.state.v[2], 1.0);
    assert_eq!(floating.state.v[7], -1.0);
}

#[test]
fn the_box_stack_stays_standing_for_2_s() {
    let mut s = scene::load_file(models_dir().join("box_stack10.toml")).unwrap();
    assert_eq!(s.world.multibody_count(), 10);
    let top = s.multibody("box9").unwrap();
    let start = s.world.multibody(top).state.q.clone();
    assert!((start[2] - 0.959).abs() < 1e-12);
    let summary = scene::run(&mut s, &RunOptions::default(), |_| {}).unwrap();
    assert_eq!(summary.steps, 1000);
    assert!(summary.max_penetration < 2e-3, "max penetration {}", summary.max_penetration);
    // The boxes start 1 mm apart (as in the MuJoCo file): the top one settles 9 mm lower within
    // 0.1 s, onto a stack of ten 0.1 m boxes, then stays there, upright, for the rest of the 2 s.
    let columns = &summary.recording.columns;
    let x = columns.iter().position(|c| c == "box9.free.x").unwrap();
    let settled = summary.recording.rows.iter().find(|r| r.time >= 0.1 - 1e-9).unwrap();
    let end = summary.recording.rows.last().unwrap();
    assert!((end.time - 2.0).abs() < 1e-9);
    let moved = (0..3).map(|a| (end.values[x + a] - settled.values[x + a]).powi(2)).sum::<f64>().sqrt();
    assert!(moved < 1e-3, "the top box moved {moved} m between t = 0.1 s and 2 s");
    for row in &summary.recording.rows {
        let drift = row.values[x].hypot(row.values[x + 1]);
        assert!(drift < 1e-3, "the top box drifted {drift} m sideways at t = {}", row.time);
        assert!(row.values[x + 6] > 0.99999, "the top box tilted at t = {}", row.time);
    }
    let height = end.values[x + 2];
    assert!((height - 0.95).abs() < 1e-3, "the top box rests at {height} m");
}

#[test]
fn the_resting_box_stack_is_still_and_its_solves_take_few_sweeps() {
    // A λ that PGS's subspace step finds within the residual goal but leaves unsolved sustains a
    // wobble of the redundant stack (~4e-7 m/s, 3 sweeps per step for ever: each step's sweeps
    // start from the accepted error); PgsSolver solves such a λ exactly where that ends the
    // sweeps, and the stack is still.
    let mut s = scene::load_file(models_dir().join("box_stack10.toml")).unwrap();
    s.world.set_sleep(gelenk::world::SleepOptions { enabled: false, ..s.world.options().sleep });
    let fastest = |world: &gelenk::world::World| {
        (0..world.multibody_count()).map(|i| world.multibody(i).state.v.amax()).fold(0.0, f64::max)
    };
    for _ in 0..1500 {
        s.world.step().unwrap();
    }
    let (mut sweeps, mut fastest_seen, mut pairs, mut refreshed) = (0, 0.0f64, 0, 0);
    for _ in 0..200 {
        let stats = s.world.step().unwrap();
        assert!(stats.fallbacks.is_empty(), "step {}: fell back to {:?}", stats.step, stats.fallbacks);
        sweeps += stats.iterations;
        fastest_seen = fastest_seen.max(fastest(&s.world));
        let collision = s.world.collision().stats();
        (pairs, refreshed) = (pairs + collision.broad_pairs, refreshed + collision.refreshed_pairs);
    }
    assert!(fastest_seen < 1e-8, "a box moves at {fastest_seen:e} m/s or rad/s at rest");
    assert!(sweeps <= 400, "{sweeps} sweeps over 200 resting steps");
    // A still pair keeps its manifolds (CollisionOptions::reuse): parry's box–box clipping runs
    // only where a pair moved by 1e-8 m or 1e-7 rad since.
    assert!(refreshed * 10 >= pairs * 9, "{refreshed} of {pairs} pairs refreshed at rest");
}

#[test]
fn runs_record_every_k_steps_as_csv_and_json() {
    let mut s = scene::load_file(models_dir().join("ball_bounce.toml")).unwrap();
    let options = RunOptions { duration: Some(0.1), record_every: Some(7), ..RunOptions::default() };
    let mut fractions = Vec::new();
    let summary = scene::run(&mut s, &options, |f| fractions.push(f)).unwrap();
    assert_eq!(summary.steps, 100);
    // Steps 0, 7, …, 98 and the last one, 100.
    let rows = &summary.recording.rows;
    assert_eq!(rows.len(), 1 + 14 + 1);
    assert_eq!(rows.iter().map(|r| r.step).collect::<Vec<_>>()[..3], [0, 7, 14]);
    assert_eq!(rows.last().unwrap().step, 100);
    assert!(fractions.windows(2).all(|w| w[0] < w[1]) && *fractions.last().unwrap() == 1.0);
    let mut csv = Vec::new();
    summary.recording.write_csv(&mut csv).unwrap();
    let csv = String::from_utf8(csv).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 1 + rows.len());
    assert_eq!(
        lines[0],
        "step,time,ball.free.x,ball.free.y,ball.free.z,ball.free.qx,ball.free.qy,ball.free.qz,ball.free.qw,\
         energy,contacts,rows,solver,iterations,residual,max_penetration"
    );
    assert!(lines.iter().all(|l| l.split(',').count() == 16));
    assert!(lines[1].starts_with("0,0,0,0,1,0,0,0,1,"), "{}", lines[1]);
    // Falling freely for 0.1 s.
    let z: f64 = lines.last().unwrap().split(',').nth(4).unwrap().parse().unwrap();
    assert!((z - (1.0 - 0.5 * 9.81 * 0.1 * 0.1)).abs() < 2e-3, "{z}");
    let mut json = Vec::new();
    summary.recording.write_json(&mut json).unwrap();
    let value: serde_json::Value = serde_json::from_slice(&json).unwrap();
    assert_eq!(value["rows"].as_array().unwrap().len(), rows.len());
    assert_eq!(value["columns"].as_array().unwrap().len(), 7);
    // Free fall conserves energy.
    assert!(summary.energy_drift.abs() < 1e-2 * summary.energy_start.abs(), "{summary:?}");

    // The scene's own `[record] every = 5`, and nothing with 0.
    let mut s = scene::load_file(models_dir().join("ball_bounce.toml")).unwrap();
    let options = RunOptions { duration: Some(0.1), ..RunOptions::default() };
    assert_eq!(scene::run(&mut s, &options, |_| {}).unwrap().recording.rows.len(), 21);
    let options = RunOptions { record_every: Some(0), ..options };
    assert!(scene::run(&mut s, &options, |_| {}).unwrap().recording.rows.is_empty());
}

/// The summary says from when the whole scene slept: the ragdoll falls, lands and sleeps well
/// within 5 s, and no step after that has rows; half a second in, it is still falling.
#[test]
fn a_run_reports_when_the_scene_fell_asleep() {
    let mut s = scene::load_file(models_dir().join("ragdoll_fall.toml")).unwrap();
    let options = RunOptions { duration: Some(0.5), record_every: Some(0), ..RunOptions::default() };
    assert_eq!(scene::run(&mut s, &options, |_| {}).unwrap().asleep_from, None);
    let options = RunOptions { duration: Some(5.0), ..options };
    let summary = scene::run(&mut s, &options, |_| {}).unwrap();
    let end = s.world.time();
    let asleep = summary.asleep_from.expect("asleep at the end");
    assert!(asleep > 0.5 && asleep < end - 1.0, "asleep from {asleep} s of {end} s");
    let quiet_steps = ((end - asleep) / summary.dt).round() as u64;
    assert!(summary.solved_steps + quiet_steps <= summary.steps, "{summary:?}");
}

#[test]
fn run_options_override_dt_and_solver_before_the_first_step() {
    let mut s = scene::load_file(models_dir().join("ball_bounce.toml")).unwrap();
    let options = RunOptions {
        duration: Some(0.6),
        dt: Some(0.002),
        solvers: Some(scene::parse_solvers("lemke").unwrap()),
        record_every: Some(0),
        ..RunOptions::default()
    };
    let summary = scene::run(&mut s, &options, |_| {}).unwrap();
    assert_eq!(summary.steps, 300);
    assert_eq!(s.world.options().dt, 0.002);
    assert_eq!(s.world.options().solvers, vec![SolverKind::Lemke { facets: 8 }]);
    assert_eq!(summary.solver_usage.keys().collect::<Vec<_>>(), ["lemke"], "{summary:?}");
    assert!(summary.solved_steps > 0 && summary.max_contacts >= 1);
    // Changing dt after stepping is refused; resetting allows it again.
    let options = RunOptions { dt: Some(0.001), ..options };
    assert!(matches!(scene::run(&mut s, &options, |_| {}), Err(SceneError::Options(_))));
    s.reset().unwrap();
    assert_eq!(s.world.time(), 0.0);
    assert!(scene::run(&mut s, &options, |_| {}).is_ok());
    assert!(scene::parse_solvers("pgs20, clarabel").unwrap().len() == 2);
    assert!(scene::parse_solvers("simplex").is_err());
    assert_eq!(scene::parse_solvers("newton").unwrap(), vec![SolverKind::Newton]);
    // A duration of 1e300 s would step for ever: refused with the number of steps.
    let options = RunOptions { duration: Some(1e300), ..RunOptions::default() };
    match scene::run(&mut s, &options, |_| {}) {
        Err(SceneError::Options(message)) => assert!(message.contains("steps, more than"), "{message}"),
        other => panic!("expected an options error, got {other:?}"),
    }
}

#[test]
fn the_ball_bounces_back_up() {
    let mut s = scene::load_file(models_dir().join("ball_bounce.toml")).unwrap();
    let options = RunOptions { duration: Some(1.0), ..RunOptions::default() };
    let summary = scene::run(&mut s, &options, |_| {}).unwrap();
    // It hits the ground at t ≈ 0.404 s at 3.96 m/s and leaves at about 0.8 of that: it must
    // rise well above half its drop height.
    let z: Vec<f64> = summary.recording.rows.iter().map(|r| r.values[2]).collect();
    let lowest = (0..z.len()).min_by(|&a, &b| z[a].total_cmp(&z[b])).unwrap();
    assert!(z[lowest] < 0.12, "lowest at {} m", z[lowest]);
    let rebound = z[lowest..].iter().cloned().fold(f64::MIN, f64::max);
    assert!(rebound > 0.5, "rebound to {rebound} m");
}

#[test]
fn vehicle_commands_drive_the_buggy_at_their_times() {
    let mut s = scene::load_file(models_dir().join("buggy_drive.toml")).unwrap();
    assert_eq!(s.vehicles.len(), 1);
    let commands = &s.vehicles[0].commands;
    assert_eq!(commands.len(), 4);
    assert_eq!((commands[0].at, commands[0].speed), (0.5, Some(5.0)));
    assert!((commands[1].steering.unwrap() - 20f64.to_radians()).abs() < 1e-15);
    assert_eq!(commands[3].brake, Some(true));
    // At rest before 0.5 s; after 3 s, 2.5 s of throttle: at the commanded 5 m/s (±5 %, the
    // vehicle criterion).
    let options = RunOptions { duration: Some(0.4), ..RunOptions::default() };
    scene::run(&mut s, &options, |_| {}).unwrap();
    let vehicle = s.vehicles[0].vehicle.clone();
    assert!(vehicle.speed(&s.world).abs() < 1e-3);
    assert_eq!(s.vehicles[0].applied, 0);
    let options = RunOptions { duration: Some(2.6), ..RunOptions::default() };
    scene::run(&mut s, &options, |_| {}).unwrap();
    assert_eq!(s.vehicles[0].applied, 1);
    let v = vehicle.speed(&s.world);
    assert!((v - 5.0).abs() < 0.25, "{v} m/s");
}

#[test]
fn bad_vehicle_entries_are_errors_with_their_line() {
    let buggy = "[[urdf]]\npath = \"buggy.urdf\"\nname = \"car\"\nfloating = true\n";
    // An unknown key in a command: its line and path.
    let message = load_error(&format!(
        "{buggy}[[vehicle]]\nmultibody = \"car\"\n[[vehicle.command]]\nat = 1\nthrottle = 3\n"
    ));
    assert!(message.contains("line 9") && message.contains("vehicle[0].command[0].throttle"), "{message}");
    // A multibody that does not exist.
    let message = load_error(&format!("{buggy}[[vehicle]]\nmultibody = \"truck\"\n"));
    assert!(message.contains("line 6") && message.contains("truck"), "{message}");
    // A negative time, an empty command, speed with coast, a steering angle out of range.
    let message = load_error(&format!(
        "{buggy}[[vehicle]]\nmultibody = \"car\"\n[[vehicle.command]]\nat = -1\nspeed = 1\n"
    ));
    assert!(message.contains("line 8") && message.contains("command[0].at"), "{message}");
    let message =
        load_error(&format!("{buggy}[[vehicle]]\nmultibody = \"car\"\n[[vehicle.command]]\nat = 1\n"));
    assert!(message.contains("line 7") && message.contains("at least one"), "{message}");
    let message = load_error(&format!(
        "{buggy}[[vehicle]]\nmultibody = \"car\"\n[[vehicle.command]]\nat = 1\nspeed = 2\ncoast = true\n"
    ));
    assert!(message.contains("not both"), "{message}");
    let message = load_error(&format!(
        "{buggy}[[vehicle]]\nmultibody = \"car\"\n[[vehicle.command]]\nat = 1\nsteering_deg = 95\n"
    ));
    assert!(message.contains("steering_deg"), "{message}");
    // A wheel joint that is not there, and a chassis fixed to the world.
    let message =
        load_error(&format!("{buggy}[[vehicle]]\nmultibody = \"car\"\nfront = [\"fl\", \"front_right\"]\n"));
    assert!(message.contains("line 5") && message.contains("no joint `fl`"), "{message}");
    let fixed = buggy.replace("floating = true", "floating = false");
    let message = load_error(&format!("{fixed}[[vehicle]]\nmultibody = \"car\"\n"));
    assert!(message.contains("free joint"), "{message}");
    // A bad parameter.
    let message = load_error(&format!("{buggy}[[vehicle]]\nmultibody = \"car\"\nwheel_radius = 0\n"));
    assert!(message.contains("line 7") && message.contains("vehicle[0].wheel_radius"), "{message}");
}

#[test]
fn the_integrator_key_sets_the_world_integrator() {
    use gelenk::integrators::IntegratorKind;
    for (name, kind) in [
        ("rk4", IntegratorKind::Rk4),
        ("semi-implicit-euler", IntegratorKind::SemiImplicitEuler),
        ("gbs6", IntegratorKind::GraggBulirschStoer { columns: 6 }),
    ] {
        let text =
            format!("[world]\nintegrator = \"{name}\"\n\n[[body]]\nshape = \"sphere\"\nradius = 0.1\n");
        let scene = scene::load_str(&text, models_dir()).unwrap();
        assert_eq!(scene.world.options().integrator, kind, "{name}");
        assert_eq!(scene.integrator, name);
    }
    // Without the key: the velocity-level step.
    let scene = scene::load_str("[[body]]\nshape = \"sphere\"\nradius = 0.1\n", models_dir()).unwrap();
    assert_eq!(scene.world.options().integrator, IntegratorKind::SemiImplicitEuler);
}

#[test]
fn the_contact_reuse_key_sets_the_collision_option() {
    use gelenk::collision::ManifoldReuse;
    let reuse_of = |value: &str| {
        let text =
            format!("[world]\ncontact_reuse = {value}\n\n[[body]]\nshape = \"sphere\"\nradius = 0.1\n");
        scene::load_str(&text, models_dir()).unwrap().world.options().collision.reuse
    };
    assert_eq!(reuse_of("false"), None);
    assert_eq!(reuse_of("true"), Some(ManifoldReuse::default()));
    assert_eq!(
        reuse_of("{ translation = 1e-6, rotation = 2e-5 }"),
        Some(ManifoldReuse { translation: 1e-6, rotation: 2e-5 })
    );
    assert_eq!(
        reuse_of("{ rotation = 2e-5 }"),
        Some(ManifoldReuse { rotation: 2e-5, ..ManifoldReuse::default() })
    );
    // Without the key: on, with the default bounds.
    let scene = scene::load_str("[[body]]\nshape = \"sphere\"\nradius = 0.1\n", models_dir()).unwrap();
    assert_eq!(scene.world.options().collision.reuse, Some(ManifoldReuse::default()));
    for bad in ["0.5", "{ translation = -1e-6 }", "{ angle = 1e-5 }"] {
        let message = load_error(&format!("[world]\ncontact_reuse = {bad}\n"));
        assert!(message.contains("line 2") && message.contains("world.contact_reuse"), "{bad}: {message}");
    }
}

#[test]
fn the_mass_matrix_reuse_key_sets_the_world_option() {
    let reuse_of = |value: &str| {
        let text =
            format!("[world]\nmass_matrix_reuse = {value}\n\n[[body]]\nshape = \"sphere\"\nradius = 0.1\n");
        scene::load_str(&text, models_dir()).unwrap().world.options().mass_matrix_reuse
    };
    assert_eq!(reuse_of("false"), None);
    assert_eq!(reuse_of("true"), Some(1e-8));
    assert_eq!(reuse_of("1e-6"), Some(1e-6));
    for bad in ["0.0", "-1e-6", "\"on\""] {
        let message = load_error(&format!("[world]\nmass_matrix_reuse = {bad}\n"));
        assert!(
            message.contains("line 2") && message.contains("world.mass_matrix_reuse"),
            "{bad}: {message}"
        );
    }
}

/// `RunOptions::softness` sets the world's relative softness; a negative or non-finite one is a
/// typed error before any step.
#[test]
fn run_options_set_the_softness() {
    let mut s = scene::load_file(models_dir().join("ball_bounce.toml")).unwrap();
    let options = RunOptions { duration: Some(0.1), softness: Some(0.01), ..RunOptions::default() };
    scene::run(&mut s, &options, |_| {}).unwrap();
    assert_eq!(s.world.options().softness, 0.01);
    for bad in [-0.1, f64::NAN, f64::INFINITY] {
        let mut s = scene::load_file(models_dir().join("ball_bounce.toml")).unwrap();
        let options = RunOptions { softness: Some(bad), ..RunOptions::default() };
        let error = scene::run(&mut s, &options, |_| {}).unwrap_err().to_string();
        assert!(error.contains("softness"), "{error}");
        assert_eq!(s.world.time(), 0.0);
    }
}

/// `[world] softness_damping` sets `WorldOptions::softness_damping`; outside [0, 1] it is an
/// error at its line.
#[test]
fn the_softness_damping_key_is_a_fraction() {
    let s = scene::load_str("[world]\nsoftness = 0.1\nsoftness_damping = 0.5\n[[ground]]\n", ".").unwrap();
    assert_eq!((s.world.options().softness, s.world.options().softness_damping), (0.1, 0.5));
    let message = load_error("[world]\nsoftness_damping = 1.5\n");
    assert!(message.contains("line 2") && message.contains("between 0 and 1"), "{message}");
}
