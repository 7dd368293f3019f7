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
use gelenk::io::scene::{self, RunOptions};
use gelenk::math::{Transform, Vec3};
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

/// Checks the player of `scene_file` run for `duration` s on `body`.
fn check_player(scene_file: &str, duration: f64, body: &str, doc: DocPicture) {
    let Some(browser) = chromium::find() else {
        println!(
            "skipped: Chromium is not installed (Debian: apt-get install chromium; .ci/run installs it)"
        );
        return;
    };
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut loaded = scene::load_file(repo.join("models").join(scene_file)).unwrap();
    let options = RunOptions { duration: Some(duration), record_frames: true, ..RunOptions::default() };
    let recording = scene::run(&mut loaded, &options, |_| {}).unwrap().recording;
    let html = gelenk::viz::player::player_html(&loaded.world, &recording).unwrap();
    let dir: PathBuf = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("player-{scene_file}"));
    std::fs::create_dir_all(&dir).unwrap();
    let page_file = dir.join("page.html");
    std::fs::write(&page_file, html).unwrap();

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
