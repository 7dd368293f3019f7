//! Exporting the constraint problems of a scene's steps ([`export_problems`], `gelenk
//! export-problems`): a built-in scene of [`crate::scenes`], a scene file or an MJCF file is
//! stepped, and the problem of each selected step that has rows is written into
//! `OUT/step-NNNN/` with its [`ProblemMeta`].

use super::{write_problem, ProblemFileError, ProblemMeta};
use crate::constraints::FrictionModel;
use crate::error::MjcfError;
use crate::io::{mjcf, scene};
use crate::scenes;
use crate::world::{StepError, World};
use std::path::Path;
use thiserror::Error;

/// What to export.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportOptions {
    /// Steps to simulate.
    pub steps: usize,
    /// Friction model of the contact rows (a scene file's or MJCF file's world takes it before
    /// its first step).
    pub friction: FrictionModel,
    /// Steps whose problems are written (indices from 0); empty: every step that has rows.
    pub only: Vec<usize>,
}

impl ExportOptions {
    /// Whether step `step`'s problem is written (when it has rows).
    pub fn selects(&self, step: usize) -> bool {
        self.only.is_empty() || self.only.contains(&step)
    }
}

/// Where exported problems come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportKind {
    /// A built-in scene ([`crate::scenes::scene_world`]: a world solved by clarabel alone, the
    /// reference solution).
    BuiltIn,
    /// A scene file (`.toml`), stepped by its world with its own solver chain; its vehicle
    /// commands are applied before each step.
    SceneFile,
    /// An MJCF file (`.xml`), stepped by the world of [`crate::io::mjcf::MjcfScene::into_world`]
    /// with its own solver chain.
    Mjcf,
}

impl ExportKind {
    /// The kind of `scene`: a scene file or MJCF file by its extension (`.toml`, `.xml`), else
    /// the name of a built-in scene.
    pub fn of(scene: &str) -> ExportKind {
        match Path::new(scene).extension().map(|e| e.to_ascii_lowercase()) {
            Some(e) if e == "toml" => ExportKind::SceneFile,
            Some(e) if e == "xml" => ExportKind::Mjcf,
            _ => ExportKind::BuiltIn,
        }
    }
}

/// One problem written.
#[derive(Clone, Copy, Debug)]
pub struct ExportedProblem<'a> {
    /// Its directory (`OUT/step-NNNN`).
    pub dir: &'a Path,
    /// Its metadata, as written to `meta.json`.
    pub meta: &'a ProblemMeta,
    /// Where it came from.
    pub kind: ExportKind,
}

/// Why an export stopped.
#[derive(Debug, Error)]
pub enum ExportError {
    /// The built-in scene does not exist.
    #[error(transparent)]
    BuiltIn(#[from] scenes::SceneError),
    /// The scene file could not be loaded.
    #[error(transparent)]
    Scene(#[from] scene::SceneError),
    /// The MJCF file could not be loaded.
    #[error(transparent)]
    Mjcf(#[from] MjcfError),
    /// The world refused the MJCF scene's geometry or the friction model.
    #[error(transparent)]
    World(#[from] StepError),
    /// A step failed: the world's step or its controls.
    #[error("{scene} step {step}: {source}")]
    Step {
        /// Scene name (a file's stem).
        scene: String,
        /// Step index, from 0.
        step: usize,
        /// What failed.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A problem could not be written.
    #[error(transparent)]
    Write(#[from] ProblemFileError),
}

/// Steps `scene` (a built-in scene's name, a scene file or an MJCF file; see [`ExportKind::of`])
/// for `options.steps` steps, writes the problem of every selected step that has rows into
/// `out/step-NNNN/` ([`write_problem`]), calls `written` after each, and returns how many were
/// written. Each world steps with its own solver chain (a built-in scene's: clarabel), and its
/// problems are written as posed (before the solve).
pub fn export_problems(
    scene: &str,
    out: &Path,
    options: &ExportOptions,
    written: impl FnMut(&ExportedProblem<'_>),
) -> Result<usize, ExportError> {
    export_world(scene, ExportKind::of(scene), out, options, written)
}

fn export_world(
    scene: &str,
    kind: ExportKind,
    out: &Path,
    options: &ExportOptions,
    mut written: impl FnMut(&ExportedProblem<'_>),
) -> Result<usize, ExportError> {
    enum Source {
        /// A scene file: its controls (vehicle commands, servos) are applied before each step.
        Scene(Box<scene::Scene>),
        /// A world stepped as it is (an MJCF file, a built-in scene).
        World(Box<World>),
    }
    let path = Path::new(scene);
    let mut source = match kind {
        ExportKind::SceneFile => Source::Scene(Box::new(scene::load_file(path)?)),
        ExportKind::Mjcf => {
            let loaded = mjcf::load_file(path)?;
            let world_options = loaded.world_options();
            Source::World(Box::new(loaded.into_world(world_options)?))
        }
        ExportKind::BuiltIn => Source::World(Box::new(scenes::scene_world(scene)?)),
    };
    let name = match kind {
        ExportKind::BuiltIn => scene.to_string(),
        _ => path.file_stem().map_or_else(|| "scene".to_string(), |s| s.to_string_lossy().into_owned()),
    };
    let failed = |step: usize, source: Box<dyn std::error::Error + Send + Sync>| ExportError::Step {
        scene: name.clone(),
        step,
        source,
    };
    let mut count = 0;
    for step in 0..options.steps {
        let world = match &mut source {
            Source::Scene(scene) => {
                scene.apply_controls().map_err(|e| failed(step, Box::new(e)))?;
                &mut scene.world
            }
            Source::World(world) => world,
        };
        if step == 0 {
            world.set_friction(options.friction)?;
        }
        let h = world.options().dt;
        world.step().map_err(|e| failed(step, Box::new(e)))?;
        let problem = world.problem();
        if problem.rows() > 0 && options.selects(step) {
            let meta = ProblemMeta::compute(&name, step, h, problem);
            let dir = out.join(format!("step-{step:04}"));
            write_problem(&dir, problem, &meta)?;
            written(&ExportedProblem { dir: &dir, meta: &meta, kind });
            count += 1;
        }
    }
    Ok(count)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kind_follows_the_extension() {
        assert_eq!(ExportKind::of("box-drop"), ExportKind::BuiltIn);
        assert_eq!(ExportKind::of("models/ragdoll_fall.toml"), ExportKind::SceneFile);
        assert_eq!(ExportKind::of("peers/HUMANOID.XML"), ExportKind::Mjcf);
        assert_eq!(ExportKind::of("notes.txt"), ExportKind::BuiltIn);
    }

    #[test]
    fn a_built_in_scene_writes_the_selected_steps_that_have_rows() {
        let out = std::env::temp_dir().join(format!("gelenk_export_{}", std::process::id()));
        let options =
            ExportOptions { steps: 30, friction: FrictionModel::Pyramid { facets: 6 }, only: vec![0, 29] };
        let mut seen = Vec::new();
        let written = export_problems("box-flat", &out, &options, |p| {
            assert_eq!(p.kind, ExportKind::BuiltIn);
            assert_eq!(p.meta.friction, "pyramid:6");
            assert!(p.dir.join(super::super::META_FILE).is_file());
            seen.push(p.meta.step);
        })
        .unwrap();
        std::fs::remove_dir_all(&out).ok();
        // The box rests on the ground from the start: both selected steps have rows.
        assert_eq!((written, seen), (2, vec![0, 29]));
        let error = export_problems("no-such-scene", &out, &options, |_| {}).unwrap_err();
        assert!(matches!(error, ExportError::BuiltIn(_)), "{error}");
        let error = export_problems("no/such/scene.toml", &out, &options, |_| {}).unwrap_err();
        assert!(matches!(error, ExportError::Scene(_)), "{error}");
    }
}
