//! Progress while a scene is built: the library reports every body and model it builds
//! (`load_file_with_progress`), and `gelenk` turns a long set-up into a bar on stderr when stderr
//! is a terminal, and prints nothing of it otherwise.

use gelenk::io::scene::{load_file_with_progress, SetUpProgress};
use std::path::PathBuf;
use std::process::Command;

/// Writes `text` as a scene file in the tests' scratch folder; model paths resolve against the
/// repository's `models/`.
fn scene_file(name: &str, text: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("progress");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let path = dir.join(name);
    let models = concat!(env!("CARGO_MANIFEST_DIR"), "/models");
    std::fs::write(&path, text.replace("MODELS", models)).expect("scene written");
    path
}

/// `layers` × 10 000 boxes on the ground, run for one step: a set-up of about 0.15 s per layer
/// (this machine kind), a moment of running. Each test writes its own copy (`name`), as the
/// tests run at the same time.
fn many_boxes(name: &str, layers: usize) -> PathBuf {
    scene_file(
        name,
        &format!(
            "[world]\nduration = 0.002\n\n[[ground]]\n\n[[body]]\nname = \"box\"\nshape = \"box\"\n\
             size = [0.1, 0.1, 0.1]\nmass = 1\nposition = [0, 0, 1]\ncount = [100, 100, {layers}]\n\
             spacing = [0.3, 0.3, 0.3]\n"
        ),
    )
}

#[test]
fn set_up_progress_counts_every_copy_once_in_order() {
    let path = scene_file(
        "copies.toml",
        "[[ground]]\n\n[[urdf]]\npath = \"MODELS/double_pendulum_simple.urdf\"\ncount = 2\nspacing = [1, 0, 0]\n\n\
         [[body]]\nshape = \"sphere\"\nradius = 0.1\nmass = 1\nposition = [0, 0, 1]\ncount = [3, 2, 1]\n\
         spacing = [0.5, 0.5, 0]\n\n[[body]]\nshape = \"box\"\nsize = [1, 1, 1]\nfixed = true\n",
    );
    let mut seen = Vec::new();
    let scene = load_file_with_progress(&path, |p| seen.push(p)).expect("the scene loads");
    let expected: Vec<SetUpProgress> = (1..=9).map(|built| SetUpProgress { built, total: 9 }).collect();
    assert_eq!(seen, expected, "2 pendulums, 6 spheres and 1 fixed box, each reported once");
    assert_eq!(scene.world.multibody_count(), 8);
}

#[test]
fn a_long_set_up_prints_nothing_when_stderr_is_not_a_terminal() {
    let out = Command::new(env!("CARGO_BIN_EXE_gelenk"))
        .args(["simulate", many_boxes("boxes30000.toml", 3).to_str().expect("a UTF-8 path")])
        .output()
        .expect("gelenk runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(String::from_utf8_lossy(&out.stderr), "", "no bar and no escape codes in a pipe");
    assert!(String::from_utf8_lossy(&out.stdout).starts_with("boxes30000: 1 steps"));
}

#[test]
fn a_long_set_up_shows_its_bar_on_a_terminal() {
    // `script` (util-linux) runs the command on a pseudo-terminal and copies what it printed.
    // 100 000 boxes: the bodies take over a second to build, well past the bar's 0.3 s of quiet
    // (30 000 are built within it on an idle machine).
    let scene = many_boxes("boxes100000_terminal.toml", 10);
    let command = format!("{} simulate {}", env!("CARGO_BIN_EXE_gelenk"), scene.display());
    let Ok(out) = Command::new("script").args(["-qec", &command, "/dev/null"]).output() else {
        eprintln!("skipped: no `script` command (util-linux) to give gelenk a terminal");
        return;
    };
    let shown = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{shown}");
    assert!(shown.contains("building the scene ["), "the set-up bar was drawn:\n{shown}");
    assert!(shown.contains("/100000 bodies"), "it counts the bodies:\n{shown}");
    assert!(shown.contains("100%"), "then the run's bar:\n{shown}");
    assert!(shown.contains("boxes100000_terminal: 1 steps"), "and the summary:\n{shown}");
}
