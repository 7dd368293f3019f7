//! `gelenk view`: run a scene file and write its player, one self-contained HTML page.

use gelenk::io::scene;
use std::path::PathBuf;

// Arguments of `gelenk view`.
#[derive(clap::Args)]
pub struct ViewArgs {
    /// Scene file.
    scene: PathBuf,
    /// Output page (.html); by default the scene file's name with `.html`, in the current
    /// directory.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Simulated time (s) instead of the scene's.
    #[arg(long)]
    duration: Option<f64>,
    /// Record a frame every N steps instead of the scene's `[record] every`.
    #[arg(long, value_name = "N")]
    every: Option<usize>,
}

/// Runs `gelenk view`.
pub fn run(args: &ViewArgs) -> Result<(), String> {
    if args.every == Some(0) {
        return Err("--every must be at least 1".to_string());
    }
    let mut loaded = crate::progress::load_scene(&args.scene)?;
    let out = match &args.out {
        Some(out) => out.clone(),
        None => {
            let stem =
                args.scene.file_stem().ok_or_else(|| format!("{}: not a file", args.scene.display()))?;
            PathBuf::from(stem).with_extension("html")
        }
    };
    // Created before the run: a path that cannot be written fails now, not after it.
    let page = gelenk::viz::OutputFile::create(&out, "html").map_err(|e| e.to_string())?;
    let options = scene::RunOptions {
        duration: args.duration,
        record_every: args.every,
        record_frames: true,
        ..scene::RunOptions::default()
    };
    let summary = scene::run(&mut loaded, &options, crate::progress::run_bar()).map_err(|e| e.to_string())?;
    for warning in &loaded.warnings {
        eprintln!("gelenk: warning: {warning}");
    }
    let html =
        gelenk::viz::player::player_html(&loaded.world, &summary.recording).map_err(|e| e.to_string())?;
    page.commit(html.as_bytes()).map_err(|e| e.to_string())?;
    println!(
        "{}: {} steps, {} frames of {} bodies -> {} ({:.1} MB); open it in a browser",
        summary.scene,
        summary.steps,
        summary.recording.frames.len(),
        summary.recording.bodies.len(),
        out.display(),
        html.len() as f64 / 1e6
    );
    Ok(())
}
