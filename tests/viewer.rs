//! The glTF export and the player page: the glb reads back (gltf crate) with a node, a mesh
//! primitive per collider and an animation channel pair per body that replay the recorded poses;
//! the Khronos glTF validator reports no issue in it, not even a hint (where node and npm are
//! there);
//! recording frames leaves the CSV and JSON outputs as they were; the page needs no network;
//! bad input from the command line is a one-line error that leaves no file behind.

use gelenk::io::scene::{self, RunOptions, Scene};
use gelenk::math::{Transform, Vec3};
use gelenk::model::Shape;
use gelenk::run::Recording;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Every kind of shape: plane and height-field ground, a static triangle mesh, boxes, a sphere, a
/// capsule, a cylinder, and a convex hull added to a box's body.
const SCENE: &str = r#"
name = "shapes"
[world]
dt = 0.002
duration = 0.3
[[ground]]
[[ground]]
name = "bumps"
kind = "heightfield"
size = [4.0, 3.0]
samples = [9, 7]
bump_height = 0.03
bump_wavelength = 1.0
position = [6, 0, 0]
[[body]]
name = "box"
shape = "box"
size = [0.2, 0.3, 0.1]
mass = 1
position = [0, 0, 0.3]
count = 2
spacing = [0.5, 0, 0]
angular_velocity = [1, 2, 0]
[[body]]
name = "ball"
shape = "sphere"
radius = 0.1
mass = 1
position = [0, 1, 0.5]
velocity = [1, 0, 0]
[[body]]
name = "pill"
shape = "capsule"
radius = 0.05
length = 0.3
mass = 1
position = [0, -1, 0.4]
[[body]]
name = "can"
shape = "cylinder"
radius = 0.1
length = 0.2
mass = 1
position = [1, -1, 0.4]
[record]
every = 10
"#;

fn shapes_scene() -> Scene {
    let mut loaded = scene::load_str(SCENE, ".").unwrap();
    let tetrahedron = Shape::ConvexHull {
        points: vec![
            Vec3::new(0.0, 0.0, 0.1),
            Vec3::new(0.1, 0.0, 0.1),
            Vec3::new(0.0, 0.1, 0.1),
            Vec3::new(0.0, 0.0, 0.2),
        ],
    };
    loaded
        .world
        .collision_mut()
        .add_body_collider(0, 1, "box0 hull", &tetrahedron, Transform::identity(), &Default::default())
        .unwrap();
    let wedge = Shape::TriMesh {
        vertices: vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 0.5),
        ],
        triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
    };
    loaded
        .world
        .add_static("wedge", &wedge, Transform::from_translation(Vec3::new(-3.0, 0.0, 0.0)), 0)
        .unwrap();
    loaded
}

fn run_with_frames(scene: &mut Scene) -> Recording {
    let options = RunOptions { record_frames: true, ..RunOptions::default() };
    scene::run(scene, &options, |_| {}).unwrap().recording
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("gelenk_viewer_{}_{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn the_glb_reads_back_with_every_body_shape_and_its_recorded_motion() {
    let mut loaded = shapes_scene();
    let recording = run_with_frames(&mut loaded);
    assert_eq!(recording.frames.len(), recording.rows.len());
    assert_eq!(recording.rows.len(), 16); // t = 0, 0.02, …, 0.3
    let names: Vec<&str> = recording.bodies.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, ["box0/box", "box1/box", "ball/ball", "pill/pill", "can/can"]);
    let bytes = gelenk::viz::gltf::glb_bytes(&loaded.world, &recording).unwrap();

    let gltf = gltf::Gltf::from_slice(&bytes).unwrap();
    let blob = gltf.blob.as_deref().unwrap();
    let document = &gltf.document;
    let scene = document.default_scene().unwrap();
    let roots: Vec<_> = scene.nodes().collect();
    assert_eq!(roots.len(), 1);
    assert_eq!(roots[0].name(), Some(gelenk::viz::gltf::ROOT_NODE));
    let children: Vec<_> = roots[0].children().collect();
    let child_names: Vec<&str> = children.iter().filter_map(|n| n.name()).collect();
    assert_eq!(
        child_names,
        ["ground0", "bumps", "wedge", "box0/box", "box1/box", "ball/ball", "pill/pill", "can/can"]
    );
    // A primitive per collider: box0 carries its box and the hull.
    let primitives = |name: &str| {
        children.iter().find(|n| n.name() == Some(name)).unwrap().mesh().unwrap().primitives().count()
    };
    assert_eq!(primitives("box0/box"), 2);
    assert_eq!(primitives("ball/ball"), 1);
    // The ball's vertices lie on its sphere (radius 0.1 m about the body origin).
    let ball = children.iter().find(|n| n.name() == Some("ball/ball")).unwrap();
    for primitive in ball.mesh().unwrap().primitives() {
        let reader = primitive.reader(|_| Some(blob));
        for p in reader.read_positions().unwrap() {
            let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            assert!((r - 0.1).abs() < 1e-6, "{r}");
        }
        assert!(reader.read_normals().is_some());
        assert!(reader.read_indices().unwrap().into_u32().count() > 0);
    }

    // The animation replays the recorded poses at the recorded times.
    let animation = document.animations().next().unwrap();
    assert_eq!(animation.name(), Some(gelenk::viz::gltf::ANIMATION));
    assert_eq!(animation.channels().count(), 2 * recording.bodies.len());
    for channel in animation.channels() {
        let name = channel.target().node().name().unwrap();
        let b = recording.bodies.iter().position(|b| b.name == name).unwrap();
        let reader = channel.reader(|_| Some(blob));
        let times: Vec<f32> = reader.read_inputs().unwrap().collect();
        assert_eq!(times.len(), recording.rows.len());
        for (t, row) in times.iter().zip(&recording.rows) {
            assert_eq!(*t, row.time as f32);
        }
        match reader.read_outputs().unwrap() {
            gltf::animation::util::ReadOutputs::Translations(values) => {
                for (v, frame) in values.zip(&recording.frames) {
                    let p = frame.poses[b].translation;
                    assert!((Vec3::new(v[0] as f64, v[1] as f64, v[2] as f64) - p).norm() < 1e-6);
                }
            }
            gltf::animation::util::ReadOutputs::Rotations(values) => {
                for (v, frame) in values.into_f32().zip(&recording.frames) {
                    let q = frame.poses[b].rotation;
                    // The same rotation: q or −q.
                    let dot: f64 = (0..4).map(|i| v[i] as f64 * q[i]).sum();
                    assert!((dot.abs() - 1.0).abs() < 1e-6, "{v:?} vs {q:?}");
                }
            }
            _ => panic!("unexpected channel"),
        }
    }
    // The bodies moved: the boxes spin, the ball rolls.
    let first = &recording.frames[0].poses;
    let last = &recording.frames.last().unwrap().poses;
    assert!((last[2].translation - first[2].translation).norm() > 0.1);
}

#[test]
fn recording_frames_leaves_the_csv_and_json_as_they_were() {
    let mut plain = shapes_scene();
    let without = scene::run(&mut plain, &RunOptions::default(), |_| {}).unwrap().recording;
    let mut framed = shapes_scene();
    let with = run_with_frames(&mut framed);
    assert!(without.frames.is_empty() && without.bodies.is_empty());
    let (mut a, mut b) = (Vec::new(), Vec::new());
    without.write_csv(&mut a).unwrap();
    with.write_csv(&mut b).unwrap();
    assert_eq!(String::from_utf8(a).unwrap(), String::from_utf8(b).unwrap());
    let (mut a, mut b) = (Vec::new(), Vec::new());
    without.write_json(&mut a).unwrap();
    with.write_json(&mut b).unwrap();
    assert_eq!(String::from_utf8(a).unwrap(), String::from_utf8(b).unwrap());
}

#[test]
fn a_recording_without_frames_is_refused() {
    let mut loaded = shapes_scene();
    let recording = scene::run(&mut loaded, &RunOptions::default(), |_| {}).unwrap().recording;
    let error = gelenk::viz::gltf::glb_bytes(&loaded.world, &recording).unwrap_err();
    assert!(matches!(error, gelenk::viz::VizError::NoFrames), "{error}");
    let mut loaded = shapes_scene();
    let mut broken = run_with_frames(&mut loaded);
    broken.frames[3].poses[1].translation.x = f64::NAN;
    let error = gelenk::viz::player::player_html(&loaded.world, &broken).unwrap_err();
    assert_eq!(error.to_string(), "the pose of box1/box at t = 0.0600 s is not finite in single precision");
    // Finite, but beyond single precision.
    broken.frames[3].poses[1].translation.x = 1e39;
    assert!(gelenk::viz::gltf::glb_bytes(&loaded.world, &broken).is_err());
}

#[test]
fn the_player_page_needs_no_network() {
    let mut loaded = shapes_scene();
    let recording = run_with_frames(&mut loaded);
    let html = gelenk::viz::player::player_html(&loaded.world, &recording).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>"));
    // Nothing is fetched: no element refers to another file, every module is a data: URL.
    for reference in ["src=", "href=", "<link", "@import", "url("] {
        assert!(!html.contains(reference), "the page contains {reference}");
    }
    let map_start = html.find("<script type=\"importmap\">").unwrap();
    let map_end = map_start + html[map_start..].find("</script>").unwrap();
    let map: serde_json::Value =
        serde_json::from_str(&html[map_start + "<script type=\"importmap\">".len()..map_end]).unwrap();
    let imports = map["imports"].as_object().unwrap();
    assert_eq!(imports.len(), 6);
    assert!(imports.values().all(|url| url.as_str().unwrap().starts_with("data:text/javascript;base64,")));
    // The data the page plays: one entry per frame.
    let data_start = html.find("<script type=\"application/json\" id=\"gelenk-data\">").unwrap();
    let data_text = &html[data_start..];
    let data_text = &data_text[data_text.find('>').unwrap() + 1..data_text.find("</script>").unwrap()];
    let data: serde_json::Value = serde_json::from_str(data_text).unwrap();
    assert_eq!(data["times"].as_array().unwrap().len(), recording.frames.len());
    assert_eq!(data["contacts"]["offsets"].as_array().unwrap().len(), recording.frames.len() + 1);
    let contacts: usize = recording.frames.iter().map(|f| f.contacts.len()).sum();
    assert!(contacts > 0);
    assert_eq!(data["contacts"]["distances"].as_array().unwrap().len(), contacts);
}

fn gelenk(args: &[&str], dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_gelenk")).args(args).current_dir(dir).output().unwrap()
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn the_cli_writes_the_glb_and_the_page() {
    let dir = temp_dir("cli");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ball_bounce.toml");
    let scene = scene.to_str().unwrap();
    let out = gelenk(&["simulate", scene, "--duration", "0.2", "--gltf", "run.glb"], &dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let glb = std::fs::read(dir.join("run.glb")).unwrap();
    let gltf = gltf::Gltf::from_slice(&glb).unwrap();
    assert_eq!(gltf.document.animations().count(), 1);
    let out = gelenk(&["view", scene, "--duration", "0.2"], &dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("-> ball_bounce.html"), "{stdout}");
    assert_eq!(files_in(&dir), ["ball_bounce.html", "run.glb"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A one-line error on stderr, a failure status, and nothing left in `dir` but `keep`.
fn assert_refused(out: &std::process::Output, dir: &Path, keep: &[&str], expected: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "succeeded: {}", String::from_utf8_lossy(&out.stdout));
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("gelenk: error: ") && stderr.contains(expected), "{stderr}");
    assert_eq!(files_in(dir), keep, "{stderr}");
}

#[test]
fn bad_input_is_a_one_line_error_and_leaves_no_file() {
    let dir = temp_dir("bad");
    std::fs::write(dir.join("broken.toml"), "name = \"broken\"\n[world]\ndt = \"fast\"\n").unwrap();
    let scene_ok = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ball_bounce.toml");
    let scene_ok = scene_ok.to_str().unwrap();
    // A ball thrown at 1e308 m/s: its position overflows to infinity in the second step.
    std::fs::write(
        dir.join("overflow.toml"),
        "name = \"overflow\"\n[world]\ndt = 1\nduration = 10\n[[body]]\nname = \"ball\"\nshape = \"sphere\"\n\
         radius = 0.1\nmass = 1\nvelocity = [1e308, 0, 0]\n[record]\nevery = 1\n",
    )
    .unwrap();
    let keep = ["broken.toml", "overflow.toml"];

    let out = gelenk(&["view", "broken.toml", "--out", "broken.html"], &dir);
    assert_refused(&out, &dir, &keep, "broken.toml");
    let out = gelenk(&["simulate", "broken.toml", "--gltf", "broken.glb"], &dir);
    assert_refused(&out, &dir, &keep, "broken.toml");
    let out = gelenk(&["view", "missing.toml"], &dir);
    assert_refused(&out, &dir, &keep, "missing.toml");

    let out = gelenk(&["view", scene_ok, "--out", "no/such/dir/run.html"], &dir);
    assert_refused(&out, &dir, &keep, "no/such/dir/run.html: cannot write");
    let out = gelenk(&["simulate", scene_ok, "--gltf", "run.gltf"], &dir);
    assert_refused(&out, &dir, &keep, "must end in .glb");
    std::fs::create_dir(dir.join("taken.html")).unwrap();
    let out = gelenk(&["view", scene_ok, "--out", "taken.html"], &dir);
    assert_refused(&out, &dir, &["broken.toml", "overflow.toml", "taken.html"], "is a directory");
    std::fs::remove_dir(dir.join("taken.html")).unwrap();

    let out = gelenk(&["view", "overflow.toml", "--out", "overflow.html"], &dir);
    assert_refused(&out, &dir, &keep, "not finite");
    let out = gelenk(&["simulate", "overflow.toml", "--gltf", "overflow.glb"], &dir);
    assert_refused(&out, &dir, &keep, "not finite");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The Khronos glTF validator's package directory (npm package `gltf-validator`), installed into
/// the target directory on first use; the reason where node, npm or the package cannot be had.
fn khronos_validator() -> Result<PathBuf, String> {
    let have = |tool: &str| Command::new(tool).arg("--version").output().is_ok_and(|o| o.status.success());
    if !have("node") || !have("npm") {
        return Err("node or npm is not installed".to_string());
    }
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gltf-validator");
    let package = dir.join("node_modules/gltf-validator");
    if !package.join("package.json").exists() {
        std::fs::create_dir_all(&dir).unwrap();
        let out = Command::new("npm")
            .args(["install", "--no-save", "--no-audit", "--no-fund", "--prefix"])
            .arg(&dir)
            .arg("gltf-validator@2.0.0-dev.3.10")
            .output()
            .map_err(|e| format!("npm: {e}"))?;
        if !out.status.success() {
            return Err(format!(
                "npm install gltf-validator failed: {}",
                String::from_utf8_lossy(&out.stderr).trim()
            ));
        }
    }
    Ok(package)
}

#[test]
fn the_khronos_validator_reports_no_issue() {
    let package = match khronos_validator() {
        Ok(p) => p,
        Err(reason) => {
            println!("skipped: the Khronos glTF validator is not available ({reason})");
            return;
        }
    };
    let mut loaded = shapes_scene();
    let recording = run_with_frames(&mut loaded);
    let dir = temp_dir("validator");
    let glb = dir.join("shapes.glb");
    gelenk::viz::gltf::write_glb(&loaded.world, &recording, &glb).unwrap();
    let script = r#"
const validator = require(process.argv[1]);
const bytes = new Uint8Array(require('fs').readFileSync(process.argv[2]));
validator.validateBytes(bytes, { maxIssues: 100 }).then(
  (report) => console.log(JSON.stringify(report)),
  (error) => { console.error(String(error)); process.exit(2); });
"#;
    let out = Command::new("node").arg("-e").arg(script).arg(&package).arg(&glb).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let issues = &report["issues"];
    for count in ["numErrors", "numWarnings", "numInfos", "numHints"] {
        assert_eq!(issues[count], 0, "{issues:#}");
    }
    assert_eq!(report["info"]["animationCount"], 1, "{:#}", report["info"]);
    std::fs::remove_dir_all(&dir).unwrap();
}
