//! Progress bars on stderr (indicatif): building a scene and running it. They are drawn only
//! when stderr is a terminal (indicatif's stderr target hides itself otherwise), so a pipe, a
//! file or a test sees nothing of them.

use gelenk::io::scene::{self, Scene, SetUpProgress};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::path::Path;
use std::time::{Duration, Instant};

/// How long a scene's set-up runs before its bar appears: most scenes build in milliseconds
/// and show none.
const SET_UP_QUIET: Duration = Duration::from_millis(300);

/// A bar on stderr (hidden unless stderr is a terminal) of `len` units drawn as `template`, in
/// ASCII (`#` done, space to go), narrower than an 80-column terminal.
fn bar(len: u64, template: &str) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    let style = ProgressStyle::with_template(template).expect("a valid template").progress_chars("# ");
    bar.set_style(style);
    bar
}

/// Loads a scene file, with a bar of the bodies built on a terminal when its set-up takes more
/// than [`SET_UP_QUIET`] (a scene with `count = 30000` takes seconds).
pub fn load_scene(path: &Path) -> Result<Scene, String> {
    let start = Instant::now();
    let mut shown: Option<ProgressBar> = None;
    let loaded = scene::load_file_with_progress(path, |p: SetUpProgress| {
        if shown.is_none() && start.elapsed() >= SET_UP_QUIET && p.built < p.total {
            shown = Some(bar(p.total as u64, "building the scene [{bar:30}] {pos}/{len} bodies {elapsed}"));
        }
        if let Some(bar) = &shown {
            bar.set_position(p.built as u64);
        }
    });
    if let Some(bar) = shown {
        bar.finish_and_clear();
    }
    loaded.map_err(|e| e.to_string())
}

/// The run's bar, for [`scene::run`]: the fraction of the duration simulated, left on its own
/// line of the terminal when the run ends.
pub fn run_bar() -> impl FnMut(f64) {
    let bar = bar(100, "[{bar:50}] {percent:>3}%");
    move |fraction| {
        bar.set_position((fraction.clamp(0.0, 1.0) * 100.0).floor() as u64);
        if fraction >= 1.0 && !bar.is_finished() {
            bar.finish();
            if !bar.is_hidden() {
                eprintln!();
            }
        }
    }
}
