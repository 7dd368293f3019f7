//! A recorded run as one self-contained HTML page ([`player_html`], [`write_player`]) that plays
//! it in a browser, offline (from `file://` too): the binary glTF of [`super::gltf`] and the
//! run's data are embedded in the page, and so is three.js (its minified module build with
//! GLTFLoader and OrbitControls, from `assets/three/`, MIT licence in `assets/three/LICENSE`), as
//! an import map of `data:` URLs.
//!
//! The page has play/pause (space bar), a time slider, the speed, a camera that orbits (drag),
//! zooms (wheel) and follows the bodies, the contact points and normals as an overlay, and plots
//! of the total energy and the deepest penetration over time. It exposes `window.gelenkPlayer`
//! for scripts and tests: `ready` (a promise), `bodies`, `times`, `duration`, `seek(t)`,
//! `play()`, `pause()`, `setSpeed(s)`, `showContacts(on)`, `follow(on)`, `fit(fill)` (the
//! camera on the bodies as they are, their box filling that fraction of the view, 0.8 by
//! default), `project(x, y, z)` (a world point, z up, to `{x, y}` pixels of the page),
//! `bodyPosition(name)` (the drawn body's origin, world frame), `highlight(name)` (draws one body
//! flat magenta on top of everything; `null` restores), `overlayCount()` (contact points drawn)
//! and `state()` (time, playing, speed, following, contacts shown, the camera's position and
//! target in the world frame, and the clock's and the panel's texts).

use super::gltf::glb_bytes;
use super::{check_frames, focus, OutputFile, VizError};
use crate::run::Recording;
use crate::world::World;
use base64::Engine as _;
use serde::Serialize;
use std::path::Path;

const TEMPLATE: &str = include_str!("../../assets/player/player.html");
const PLAYER_JS: &str = include_str!("../../assets/player/player.js");

/// three.js's module build imports its core by a relative path, which a `data:` URL cannot
/// resolve; the page maps this bare name instead.
const THREE_CORE: &str = "three/core";

/// The vendored modules as (import-map name, source, (relative import, bare name) rewrites).
#[allow(clippy::type_complexity)]
const MODULES: [(&str, &str, &[(&str, &str)]); 6] = [
    (
        "three",
        include_str!("../../assets/three/three.module.min.js"),
        &[("\"./three.core.min.js\"", "\"three/core\"")],
    ),
    (THREE_CORE, include_str!("../../assets/three/three.core.min.js"), &[]),
    (
        "three/addons/loaders/GLTFLoader.js",
        include_str!("../../assets/three/GLTFLoader.js"),
        &[
            ("'../utils/BufferGeometryUtils.js'", "'three/addons/utils/BufferGeometryUtils.js'"),
            ("'../utils/SkeletonUtils.js'", "'three/addons/utils/SkeletonUtils.js'"),
        ],
    ),
    (
        "three/addons/utils/BufferGeometryUtils.js",
        include_str!("../../assets/three/BufferGeometryUtils.js"),
        &[],
    ),
    ("three/addons/utils/SkeletonUtils.js", include_str!("../../assets/three/SkeletonUtils.js"), &[]),
    ("three/addons/controls/OrbitControls.js", include_str!("../../assets/three/OrbitControls.js"), &[]),
];

/// What the page's script reads (the element `gelenk-data`).
#[derive(Serialize)]
struct PlayerData<'a> {
    scene: &'a str,
    dt: f64,
    /// Recorded instants (s).
    times: Vec<f64>,
    /// Total energy at each instant (J).
    energy: Vec<f64>,
    /// Deepest penetration at each instant (m).
    penetration: Vec<f64>,
    /// Body node names, in the order of the recording.
    bodies: Vec<&'a str>,
    /// The centre of the bodies' travel (world, m).
    centre: [f64; 3],
    /// Contacts: those of instant k are `offsets[k]..offsets[k + 1]`; three numbers each in
    /// `points` and `normals` (world), one in `distances` (m).
    contacts: Contacts,
}

#[derive(Serialize, Default)]
struct Contacts {
    offsets: Vec<usize>,
    points: Vec<f64>,
    normals: Vec<f64>,
    distances: Vec<f64>,
}

/// Numbers of the page's data to 0.1 µm / 1e-7: the page stays small and the drawing exact.
fn round(x: f64) -> f64 {
    if x.is_finite() {
        (x * 1e7).round() / 1e7
    } else {
        0.0
    }
}

/// The import map of the vendored modules, each a base64 `data:` URL.
fn import_map() -> String {
    let engine = base64::engine::general_purpose::STANDARD;
    let mut imports = serde_json::Map::new();
    for (name, source, rewrites) in MODULES {
        let mut source = source.to_string();
        for (from, to) in rewrites {
            source = source.replace(from, to);
        }
        let url = format!("data:text/javascript;base64,{}", engine.encode(source));
        imports.insert(name.to_string(), serde_json::Value::String(url));
    }
    serde_json::json!({ "imports": imports }).to_string()
}

/// JSON that can stand inside a `<script>` element: `</` is written `<\/`.
fn script_json(value: &impl Serialize) -> Result<String, VizError> {
    let text = serde_json::to_string(value).map_err(|e| VizError::Encode(e.to_string()))?;
    Ok(text.replace("</", "<\\/"))
}

fn escape_html(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The player page of the run (see the module's description). The recording must hold frames
/// ([`crate::run::RunOptions::record_frames`]) recorded from `world`.
pub fn player_html(world: &World, recording: &Recording) -> Result<String, VizError> {
    check_frames(recording)?;
    let glb = glb_bytes(world, recording)?;
    let bounds = focus(recording);
    let mut contacts = Contacts { offsets: vec![0], ..Contacts::default() };
    for frame in &recording.frames {
        for c in &frame.contacts {
            contacts.points.extend(c.point.iter().map(|x| round(*x)));
            contacts.normals.extend(c.normal.iter().map(|x| round(*x)));
            contacts.distances.push(round(c.distance));
        }
        contacts.offsets.push(contacts.distances.len());
    }
    let centre = (bounds.min + bounds.max) * 0.5;
    let data = PlayerData {
        scene: &recording.scene,
        dt: recording.dt,
        times: recording.rows.iter().map(|r| r.time).collect(),
        energy: recording.frames.iter().map(|f| f.energy).collect(),
        penetration: recording.rows.iter().map(|r| r.max_penetration).collect(),
        bodies: recording.bodies.iter().map(|b| b.name.as_str()).collect(),
        centre: [centre.x, centre.y, centre.z],
        contacts,
    };
    let glb = base64::engine::general_purpose::STANDARD.encode(glb);
    // The pieces are put in last: none of them is searched for placeholders.
    let mut page = String::with_capacity(TEMPLATE.len() + glb.len() + 2_000_000);
    let mut rest = TEMPLATE;
    while let Some(start) = rest.find("{{") {
        let end = rest[start..].find("}}").map(|e| start + e + 2).unwrap_or(rest.len());
        page.push_str(&rest[..start]);
        match &rest[start..end] {
            "{{TITLE}}" => page.push_str(&escape_html(&recording.scene)),
            "{{IMPORT_MAP}}" => page.push_str(&import_map()),
            "{{DATA}}" => page.push_str(&script_json(&data)?),
            "{{GLB}}" => page.push_str(&glb),
            "{{PLAYER_JS}}" => page.push_str(PLAYER_JS),
            other => page.push_str(other),
        }
        rest = &rest[end..];
    }
    page.push_str(rest);
    Ok(page)
}

/// Writes [`player_html`] to `path` (which must end in `.html`), whole or not at all.
pub fn write_player(world: &World, recording: &Recording, path: &Path) -> Result<(), VizError> {
    let out = OutputFile::create(path, "html")?;
    out.commit(player_html(world, recording)?.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_module_rewrite_applies_and_no_relative_import_is_left() {
        for (name, source, rewrites) in MODULES {
            let mut source = source.to_string();
            for (from, to) in rewrites {
                assert!(source.contains(from), "{name}: {from} not found");
                source = source.replace(from, to);
            }
            for quote in ['"', '\''] {
                for relative in ["./", "../"] {
                    let import = format!("from{quote}{relative}");
                    let spaced = format!("from {quote}{relative}");
                    assert!(
                        !source.contains(&import) && !source.contains(&spaced),
                        "{name} imports {relative}"
                    );
                }
            }
        }
        assert!(!PLAYER_JS.contains("</script"));
        for placeholder in ["{{TITLE}}", "{{IMPORT_MAP}}", "{{DATA}}", "{{GLB}}", "{{PLAYER_JS}}"] {
            assert_eq!(TEMPLATE.matches(placeholder).count(), 1, "{placeholder}");
        }
    }

    #[test]
    fn script_json_cannot_close_the_script() {
        let text = script_json(&serde_json::json!({ "name": "</script><b>" })).unwrap();
        assert!(!text.contains("</"));
        let back: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(back["name"], "</script><b>");
    }
}
