//! `gelenk render` and `gelenk::render`: every scene of models/ becomes a PNG filmstrip of the
//! promised size (side and top rows of N frames plus the plots); bad options are one-line errors.

use gelenk::io::scene;
use gelenk::render::{render_scene, RenderOptions};
use std::path::{Path, PathBuf};
use std::process::Command;

fn models() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("models")
}

/// Width and height from a PNG's IHDR chunk, after checking the signature.
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{} is not a PNG", path.display());
    assert_eq!(&bytes[12..16], b"IHDR");
    let word = |k: usize| u32::from_be_bytes([bytes[k], bytes[k + 1], bytes[k + 2], bytes[k + 3]]);
    (word(16), word(20))
}

fn temp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("gelenk_render_{}_{name}", std::process::id()))
}

#[test]
fn the_cli_renders_a_short_ragdoll_fall() {
    let out = temp("fall.png");
    let status = Command::new(env!("CARGO_BIN_EXE_gelenk"))
        .args(["render", "models/ragdoll_fall.toml", "--frames", "3", "--duration", "0.1", "--out"])
        .arg(&out)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let stdout = String::from_utf8_lossy(&status.stdout);
    assert!(stdout.contains("50 steps, 3 frames at t = 0.000, 0.050, 0.100 s"), "{stdout}");
    // 70 px label column + 3 frames of 220 px; title 34 + two rows of 220 + plots 260.
    assert_eq!(png_size(&out), (70 + 3 * 220, 34 + 2 * 220 + 260));
    std::fs::remove_file(&out).ok();
}

#[test]
fn bad_render_options_are_one_line_errors() {
    for (args, needle) in [
        (vec!["--frames", "1", "--out", "x.png"], "frames must be within 2..=64"),
        (vec!["--out", "x.jpg"], "must end in .png"),
        (vec!["--duration=-1", "--out", "x.png"], "duration must be positive"),
    ] {
        let output = Command::new(env!("CARGO_BIN_EXE_gelenk"))
            .args(["render", "models/ball_bounce.toml"])
            .args(&args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success());
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
        assert!(!Path::new(env!("CARGO_MANIFEST_DIR")).join(args[args.len() - 1]).exists());
    }
}

#[test]
fn every_scene_renders() {
    let mut files: Vec<PathBuf> = std::fs::read_dir(models())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 8);
    for file in files {
        let mut s = scene::load_file(&file).unwrap();
        let out = temp(&format!("{}.png", s.name));
        let options = RenderOptions { frames: 2, duration: Some(0.02), frame_size: 120 };
        let summary =
            render_scene(&mut s, &options, &out).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        assert_eq!(summary.frame_times.len(), 2);
        assert!((summary.frame_times[1] - 0.02).abs() < 1e-9, "{}", file.display());
        assert_eq!(png_size(&out), (70 + 2 * 120, 34 + 2 * 120 + 260), "{}", file.display());
        std::fs::remove_file(&out).ok();
    }
}
