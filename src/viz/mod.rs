//! Seeing a run: [`gltf`] writes a recorded run as one binary glTF 2.0 file (a node per moving
//! body with its collision shapes as meshes, an animation channel per body), and [`player`]
//! writes one self-contained HTML page that plays it in a browser (three.js embedded), with the
//! contact points and the energy and penetration over time. The filmstrip PNG is
//! [`crate::render`].
//!
//! Both read a [`Recording`] made with [`crate::run::RunOptions::record_frames`] and the
//! [`World`] it was recorded from (for the shapes, which do not change while running). Files are
//! written whole or not at all ([`OutputFile`]).
//!
//! ```no_run
//! use gelenk::io::scene::{self, RunOptions};
//! let mut loaded = scene::load_file("models/ragdoll_pile.toml")?;
//! let options = RunOptions { record_frames: true, ..RunOptions::default() };
//! let summary = scene::run(&mut loaded, &options, |_| {})?;
//! gelenk::viz::gltf::write_glb(&loaded.world, &summary.recording, "pile.glb".as_ref())?;
//! gelenk::viz::player::write_player(&loaded.world, &summary.recording, "pile.html".as_ref())?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod gltf;
mod mesh;
mod output;
pub mod player;

pub use output::OutputFile;

use crate::math::Vec3;
use crate::run::Recording;
#[cfg(doc)]
use crate::world::World;
use thiserror::Error;

/// Why a run could not be exported.
#[derive(Debug, Error)]
pub enum VizError {
    /// The recording holds no frames: it was made without
    /// [`crate::run::RunOptions::record_frames`] or with a record interval of 0.
    #[error("the recording has no frames to show (record frames, at a record interval above 0)")]
    NoFrames,
    /// A recorded pose is not finite, or too large for single precision (glTF's numbers).
    #[error("the pose of {body} at t = {time:.4} s is not finite in single precision")]
    NotFinite {
        /// The body, `multibody/body`.
        body: String,
        /// Simulated time (s).
        time: f64,
    },
    /// The output file could not be created or written.
    #[error("{file}: {message}")]
    Output {
        /// The output path.
        file: String,
        /// What went wrong.
        message: String,
    },
    /// The glTF document or the page's data could not be encoded.
    #[error("cannot encode the run: {0}")]
    Encode(String),
}

/// Where the moving bodies are over a recording (world frame, m): the bounding box of their
/// origins over all frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Focus {
    /// Lowest corner.
    pub min: Vec3,
    /// Highest corner.
    pub max: Vec3,
}

/// The focus of a recording whose poses are finite (see [`check_frames`]); a recording without
/// bodies is centred on the origin.
pub(crate) fn focus(recording: &Recording) -> Focus {
    let mut min = Vec3::repeat(f64::INFINITY);
    let mut max = Vec3::repeat(f64::NEG_INFINITY);
    for p in recording.frames.iter().flat_map(|f| &f.poses) {
        min = min.inf(&p.translation);
        max = max.sup(&p.translation);
    }
    if min.x.is_finite() {
        Focus { min, max }
    } else {
        Focus { min: Vec3::zeros(), max: Vec3::zeros() }
    }
}

/// Checks that the recording has frames, one per row, with poses finite in single precision.
pub(crate) fn check_frames(recording: &Recording) -> Result<(), VizError> {
    if recording.frames.is_empty() || recording.frames.len() != recording.rows.len() {
        return Err(VizError::NoFrames);
    }
    for (frame, row) in recording.frames.iter().zip(&recording.rows) {
        for (pose, body) in frame.poses.iter().zip(&recording.bodies) {
            let finite = pose.translation.iter().chain(&pose.rotation).all(|x| (*x as f32).is_finite());
            if !finite {
                return Err(VizError::NotFinite { body: body.name.clone(), time: row.time });
            }
        }
    }
    Ok(())
}
