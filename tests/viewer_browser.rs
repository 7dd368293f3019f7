//! The player in a real browser: headless Chromium opens the pages of the ragdoll pile and of
//! the buggy on terrain, seeks to three recorded instants and takes screenshots, in which a
//! ragdoll's head and the buggy's chassis are drawn where the recording has them (the body,
//! drawn alone in flat magenta, has its pixel centroid within a few pixels of its projected
//! centre), the contact overlay draws the recorded contacts, and the page, offline, fetches
//! nothing and reports no console error. Where Chromium is not installed (`.ci/run` installs Debian's package) the tests say so
//! and pass. With `GELENK_WRITE_DOCS=1` the last screenshots are written to docs/player_*.png.
#![cfg(unix)]

mod chromium;

use gelenk::collision::Attachment;
use gelenk::io::scene::{self, RunOptions, Scene};
use gelenk::math::{Transform, Vec3};
use gelenk::run::Recording;
use std::path::{Path, PathBuf};

const WIDTH: u32 = 1280;
const HEIGHT: u32 = 800;

/// A drawn pixel of a highlighted body (flat magenta, antialiased edges left out).
fn magenta(p: [u8; 4]) -> bool {
    p[0] > 200 && p[1] < 80 && p[2] > 200
}

/// The picture of a scene for docs/: its file name, the instant (0, 1, 2: early, middle, last),
/// the fraction of the view the bodies fill, and whether the contacts are shown.
struct DocPicture {
    file: &'static str,
    instant: usize,
    fill: f64,
    contacts: bool,
}

/// Runs `scene_file` (in models/) for `duration` s with frames and writes its player page as
/// `page.html` into a directory of its own for `test`; the scene, the recording, the directory.
fn player_page(scene_file: &str, duration: f64, test: &str) -> (Scene, Recording, PathBuf) {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut loaded = scene::load_file(repo.join("models").join(scene_file)).unwrap();
    let options = RunOptions { duration: Some(duration), record_frames: true, ..RunOptions::default() };
    let recording = scene::run(&mut loaded, &options, |_| {}).unwrap().recording;
    let html = gelenk::viz::player::player_html(&loaded.world, &recording).unwrap();
    let dir: PathBuf = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("player-{test}-{scene_file}"));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("page.html"), html).unwrap();
    (loaded, recording, dir)
}

/// Checks the player of `scene_file` run for `duration` s on `body`.
fn check_player(scene_file: &str, duration: f64, body: &str, doc: DocPicture) {
    let Some(browser) = chromium::find() else {
        println!(
            "skipped: Chromium is not installed (Debian: apt-get install chromium; .ci/run installs it)"
        );
        return;
    };
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (loaded, recording, dir) = player_page(scene_file, duration, "drawn");
    let page_file = dir.join("page.html");

    // The body's first collider's centre, in the body frame.
    let b = recording.bodies.iter().position(|x| x.name == body).unwrap();
    let attachment =
        Attachment::Body { multibody: recording.bodies[b].multibody, body: recording.bodies[b].body };
    let collider =
        loaded.world.collision().colliders().iter().find(|c| c.attachment() == attachment).unwrap();
    let centre_in_body = collider.placement().translation;

    let mut page = chromium::Page::open(&browser, &dir.join("profile"), WIDTH, HEIGHT);
    // Offline, as a page opened from a mail or a report may be; every request is recorded.
    page.call("Network.enable", serde_json::json!({}));
    let offline = serde_json::json!({ "offline": true, "latency": 0, "downloadThroughput": -1, "uploadThroughput": -1 });
    page.call("Network.emulateNetworkConditions", offline);
    page.navigate(&format!("file://{}", page_file.display()));
    assert_eq!(page.eval("gelenkPlayer.ready.then(() => { gelenkPlayer.pause(); return true; })"), true);
    let n = recording.frames.len();
    for (i, k) in [n / 8, n / 2, n - 1].into_iter().enumerate() {
        let t = recording.rows[k].time;
        page.eval(&format!("gelenkPlayer.seek({t}); gelenkPlayer.fit(); true"));

        // The page draws the body at its recorded pose (single precision).
        let pose = &recording.frames[k].poses[b];
        let drawn = page.eval(&format!("gelenkPlayer.bodyPosition('{body}')"));
        let drawn: Vec<f64> = drawn.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        let error = (Vec3::new(drawn[0], drawn[1], drawn[2]) - pose.translation).norm();
        assert!(error < 1e-4, "{body} at t = {t}: drawn at {drawn:?}, recorded at {:?}", pose.translation);

        // And the screenshot shows it there.
        let centre = Transform::from_translation_quaternion(pose.translation, pose.rotation)
            .act_point(&centre_in_body);
        let projected = page.eval(&format!("gelenkPlayer.project({}, {}, {})", centre.x, centre.y, centre.z));
        let (px, py) = (projected["x"].as_f64().unwrap(), projected["y"].as_f64().unwrap());
        assert_eq!(page.eval(&format!("gelenkPlayer.highlight('{body}')")), true);
        let (image, _) = page.screenshot();
        assert_eq!((image.width, image.height), (WIDTH, HEIGHT));
        let region = image.region(magenta).unwrap_or_else(|| panic!("{body} is not drawn at t = {t}"));
        let size =
            0.5 * ((region.bounds.2 - region.bounds.0) as f64 + (region.bounds.3 - region.bounds.1) as f64);
        let tolerance = 3.0 + 0.1 * size;
        let (cx, cy) = region.centroid;
        assert!(
            region.pixels >= 30 && (cx - px).abs() < tolerance && (cy - py).abs() < tolerance,
            "{body} at t = {t}: {region:?}, its centre projects to ({px:.1}, {py:.1}) ± {tolerance:.1}"
        );
        page.eval("gelenkPlayer.highlight(null)");

        // The picture is not empty; the contact overlay draws the recorded contacts.
        let (image, png) = page.screenshot();
        assert!(image.region(magenta).is_none(), "the highlight stayed");
        let background = image.pixel(WIDTH / 2, 2);
        let drawn = image.region(|p| p.iter().zip(&background).any(|(a, b)| a.abs_diff(*b) > 12)).unwrap();
        assert!(drawn.pixels > (WIDTH * HEIGHT / 20) as u64, "t = {t}: only {} pixels drawn", drawn.pixels);
        let drawn_contacts = page.eval("gelenkPlayer.showContacts(true); gelenkPlayer.overlayCount()");
        assert_eq!(drawn_contacts, recording.frames[k].contacts.len(), "t = {t}");
        page.eval("gelenkPlayer.showContacts(false); true");
        std::fs::write(dir.join(format!("t{i}.png")), &png).unwrap();
        if i == doc.instant {
            page.eval(&format!(
                "gelenkPlayer.fit({}); gelenkPlayer.showContacts({}); true",
                doc.fill, doc.contacts
            ));
            let (_, picture) = page.screenshot();
            page.eval("gelenkPlayer.showContacts(false); true");
            std::fs::write(dir.join(doc.file), &picture).unwrap();
            if std::env::var_os("GELENK_WRITE_DOCS").is_some() {
                std::fs::write(repo.join("docs").join(doc.file), &picture).unwrap();
            }
        }
    }
    let errors = page.errors();
    assert!(errors.is_empty(), "console errors: {errors:#?}");
    let requests: Vec<&str> = page
        .events
        .iter()
        .filter(|e| e["method"] == "Network.requestWillBeSent")
        .filter_map(|e| e["params"]["request"]["url"].as_str())
        .collect();
    assert!(requests.iter().any(|url| url.starts_with("file:")), "the page's own request was not seen");
    let fetched: Vec<&&str> =
        requests.iter().filter(|url| !url.starts_with("file:") && !url.starts_with("data:")).collect();
    assert!(fetched.is_empty(), "the page fetched {fetched:?}");
    println!("{scene_file}: screenshots in {}", dir.display());
}

#[test]
fn the_ragdoll_pile_is_drawn_where_it_was_recorded() {
    let doc = DocPicture { file: "player_ragdoll_pile.png", instant: 2, fill: 0.9, contacts: false };
    check_player("ragdoll_pile.toml", 3.0, "ragdoll19/head", doc);
}

#[test]
fn the_buggy_on_terrain_is_drawn_where_it_was_recorded() {
    let doc = DocPicture { file: "player_buggy_terrain.png", instant: 1, fill: 0.3, contacts: true };
    check_player("buggy_terrain.toml", 10.0, "buggy/chassis", doc);
}

fn vec3(value: &serde_json::Value) -> Vec3 {
    let x: Vec<f64> = value.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    Vec3::new(x[0], x[1], x[2])
}

/// The number at the start of a text such as "12.345 J".
fn leading_number(text: &serde_json::Value) -> f64 {
    let text = text.as_str().unwrap();
    text.split_whitespace().next().and_then(|x| x.parse().ok()).unwrap_or_else(|| panic!("{text:?}"))
}

/// How far the run advances at the page's speed in `milliseconds` of the page's time, against
/// that time (s, s); the run starts again from 0 and is paused after.
fn advance(page: &mut chromium::Page, milliseconds: u32) -> (f64, f64) {
    let measured = page.eval(&format!(
        "(async () => {{ gelenkPlayer.seek(0); gelenkPlayer.play(); const t0 = gelenkPlayer.state().time; \
         const w0 = performance.now(); await new Promise((done) => setTimeout(done, {milliseconds})); \
         const t1 = gelenkPlayer.state().time; const w1 = performance.now(); gelenkPlayer.pause(); \
         return [t1 - t0, (w1 - w0) / 1000]; }})()"
    ));
    (measured[0].as_f64().unwrap(), measured[1].as_f64().unwrap())
}

/// The page's controls answer the mouse and the keyboard as a person uses them: the button and
/// the space bar play and pause, the speed list (keyboard) changes the rate, a click on the time
/// slider seeks and the panel shows the recorded energy and penetration there, the contacts box
/// shows the recorded contacts, and dragging orbits, the wheel zooms, a right-drag pans.
#[test]
fn the_controls_answer_the_mouse_and_the_keyboard() {
    let Some(browser) = chromium::find() else {
        println!(
            "skipped: Chromium is not installed (Debian: apt-get install chromium; .ci/run installs it)"
        );
        return;
    };
    let (_loaded, recording, dir) = player_page("buggy_terrain.toml", 3.0, "controls");
    let (width, height) = (960.0, 600.0);
    let mut page = chromium::Page::open(&browser, &dir.join("profile"), width as u32, height as u32);
    page.navigate(&format!("file://{}", dir.join("page.html").display()));
    assert_eq!(page.eval("gelenkPlayer.ready.then(() => true)"), true);
    let duration = recording.rows.last().unwrap().time;
    let centre = |r: (f64, f64, f64, f64)| (r.0 + 0.5 * r.2, r.1 + 0.5 * r.3);

    // It plays from the start; the button pauses it and time stands still.
    page.wait(300);
    let state = page.eval("gelenkPlayer.state()");
    assert!(state["playing"] == true && state["time"].as_f64().unwrap() > 0.0, "{state}");
    let play = page.rect("#play");
    page.click(centre(play));
    let paused = page.eval("gelenkPlayer.state()");
    assert_eq!(paused["playing"], false, "{paused}");
    assert_eq!(page.eval("document.getElementById('play').textContent"), "play");
    page.wait(300);
    assert_eq!(page.eval("gelenkPlayer.state().time"), paused["time"]);
    // The space bar, the button still focused, plays and pauses: one toggle per press.
    page.key(" ", "Space", 32);
    page.wait(300);
    let state = page.eval("gelenkPlayer.state()");
    assert!(state["playing"] == true && state["time"].as_f64() > paused["time"].as_f64(), "{state}");
    page.key(" ", "Space", 32);
    assert_eq!(page.eval("gelenkPlayer.state().playing"), false);

    // The speed list from the keyboard: 1× down to 4×, then up to 0.25×; the run advances 16
    // times faster at the one than at the other (frames capped at 0.1 s of the page's time each
    // scale both alike).
    page.eval("document.getElementById('speed').focus(); true");
    for _ in 0..2 {
        page.key("ArrowDown", "ArrowDown", 40);
    }
    assert_eq!(page.eval("gelenkPlayer.state().speed"), 4.0);
    let fast = advance(&mut page, 600);
    for _ in 0..4 {
        page.key("ArrowUp", "ArrowUp", 38);
    }
    assert_eq!(page.eval("gelenkPlayer.state().speed"), 0.25);
    let slow = advance(&mut page, 600);
    let (fast_rate, slow_rate) = (fast.0 / fast.1, slow.0 / slow.1);
    assert!(fast_rate <= 4.0 * 1.05 && slow_rate <= 0.25 * 1.05, "{fast:?} {slow:?}");
    assert!(fast_rate > 4.0 * slow_rate, "4×: {fast:?}, 0.25×: {slow:?} (advance, wall time)");

    // A click on the slider seeks there and pauses; the clock and the panel show that instant.
    let slider = page.rect("#time");
    for fraction in [0.25, 0.75] {
        page.eval("gelenkPlayer.play(); true");
        page.click((slider.0 + fraction * slider.2, slider.1 + 0.5 * slider.3));
        let state = page.eval("gelenkPlayer.state()");
        let t = state["time"].as_f64().unwrap();
        assert_eq!(state["playing"], false, "{state}");
        assert!((t - fraction * duration).abs() < 0.05 * duration, "clicked at {fraction}: {state}");
        assert_eq!(state["clock"], format!("{t:.3} s"));
        let k = recording.rows.iter().rposition(|r| r.time <= t + 1e-9).unwrap();
        let energy = recording.frames[k].energy;
        assert!((leading_number(&state["energy"]) - energy).abs() <= 1e-3 * (1.0 + energy.abs()), "{state}");
        let penetration = 1000.0 * recording.rows[k].max_penetration;
        assert!((leading_number(&state["penetration"]) - penetration).abs() <= 1e-3, "{state}");
    }

    // The contacts box shows the contacts of the instant, and hides them.
    let t = page.eval("gelenkPlayer.state().time").as_f64().unwrap();
    let k = recording.rows.iter().rposition(|r| r.time <= t + 1e-9).unwrap();
    let contacts = recording.frames[k].contacts.len();
    assert!(contacts > 0, "the buggy touches nothing at t = {}", recording.rows[k].time);
    let (without, _) = page.screenshot();
    let checkbox = page.rect("#contacts");
    page.click(centre(checkbox));
    assert_eq!(page.eval("gelenkPlayer.state().contacts"), true);
    assert_eq!(page.eval("gelenkPlayer.overlayCount()"), contacts);
    let (with, _) = page.screenshot();
    assert!(with.rgba != without.rgba, "the overlay draws nothing");
    page.click(centre(checkbox));
    assert_eq!(page.eval("gelenkPlayer.overlayCount()"), 0);

    // Orbit (drag): the camera turns about its target at the same distance. Zoom (wheel): it
    // comes closer. Pan (right-drag): the target moves. Follow is off, so only the mouse moves it.
    let follow = page.rect("#follow");
    page.click(centre(follow));
    assert_eq!(page.eval("gelenkPlayer.state().following"), false);
    let view = |page: &mut chromium::Page| {
        let s = page.eval("gelenkPlayer.state()");
        (vec3(&s["camera"]), vec3(&s["target"]))
    };
    let middle = (0.5 * width, 0.5 * height);
    let (camera0, target0) = view(&mut page);
    let distance0 = (camera0 - target0).norm();
    page.drag(middle, (middle.0 + 150.0, middle.1 + 40.0), "left");
    let (camera1, target1) = view(&mut page);
    let distance1 = (camera1 - target1).norm();
    assert!((target1 - target0).norm() < 1e-9 * (1.0 + distance0), "{target0} {target1}");
    assert!((distance1 - distance0).abs() < 1e-3 * distance0, "{distance0} {distance1}");
    assert!((camera1 - camera0).norm() > 0.2 * distance0, "{camera0} {camera1}");
    page.wheel(middle, -500.0);
    let (camera2, target2) = view(&mut page);
    assert!((camera2 - target2).norm() < 0.9 * distance1, "{camera2} {target2}");
    page.drag(middle, (middle.0 - 100.0, middle.1), "right");
    let (_, target3) = view(&mut page);
    assert!((target3 - target2).norm() > 1e-3 * distance1, "{target2} {target3}");

    let errors = page.errors();
    assert!(errors.is_empty(), "console errors: {errors:#?}");
}
