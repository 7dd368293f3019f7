//! The fixed list of scenes `gelenk corpus build` steps ([`corpus_scenes`]), grouped in
//! families, and the worlds they start from.

use crate::collision::MeshOptions;
use crate::constraints::FrictionModel;
use crate::io::scene;
use crate::math::Vec3;
use crate::model::{RigidInertia, Shape};
use crate::scenes::{free_body, scene_world};
use crate::world::{SolverKind, StepError, World, WorldOptions};
use nalgebra::UnitQuaternion;
use std::path::{Path, PathBuf};

/// Where a corpus scene's world comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum SceneSource {
    /// A built-in scene of [`crate::scenes::scene_world`], with this friction model.
    BuiltIn(&'static str, FrictionModel),
    /// A scene file under the models directory (its own time step, solver and controls).
    File(&'static str),
    /// Scene-file text (TOML) read with the models directory as its base (a variant of the
    /// committed scenes: the box grid).
    Text(&'static str),
    /// An MJCF file, relative to the models directory, stepped by the world of
    /// [`crate::io::mjcf::MjcfScene::into_world`].
    Mjcf(&'static str),
    /// `count` copies of an MJCF file's model (relative to the models directory, one free
    /// root) dropped onto its static geometry one above the other, 1.8 m apart (more than the
    /// humanoid is tall) and each turned
    /// by 60° about the vertical, so that they land on each other.
    MjcfPile {
        /// The MJCF file.
        file: &'static str,
        /// Copies.
        count: usize,
    },
    /// `count` 0.1 m, 1 kg cubes stacked on a plane (the stability report's stacks).
    Stack {
        /// Cubes.
        count: usize,
        /// Time step (s).
        dt: f64,
    },
    /// A 10-row pyramid of 0.1 m cubes, 2 mm apart (the stability report's pyramid).
    Pyramid {
        /// Time step (s).
        dt: f64,
    },
    /// A 1000 kg cube on a 1 kg cube (the stability report's 1:1000 mass ratio).
    HeavyOnLight {
        /// Time step (s).
        dt: f64,
    },
}

/// One scene of the corpus: its family, its name, its world and which steps become problems.
#[derive(Clone, Debug, PartialEq)]
pub struct CorpusScene {
    /// Family (the corpus index and the bench table group by it).
    pub family: &'static str,
    /// Scene name, unique in the list (directory names start with it).
    pub name: &'static str,
    /// Its world.
    pub source: SceneSource,
    /// Steps simulated.
    pub steps: usize,
    /// Every how many steps a problem is kept (step indices `every − 1, 2 every − 1, …`).
    pub every: usize,
}

/// A scene file: a grid of 12 × 12 × 3 boxes resting on a plane and on each other (5184
/// contact rows from the first step): the corpus's largest problems.
const BOX_GRID: &str = r#"
name = "box_grid"
[world]
dt = 0.002
duration = 1.0
solver = "newton"
accept_last = true
[contact]
mu = 0.6
[[ground]]
kind = "plane"
[[body]]
name = "box"
shape = "box"
size = [0.08, 0.08, 0.08]
density = 600
position = [-0.55, -0.55, 0.0399]
count = [12, 12, 3]
spacing = [0.1, 0.1, 0.0799]
"#;

/// MuJoCo's passive humanoid (MJCF, relative to the models directory).
const HUMANOID: &str = "../benches/peers/humanoid_fall.xml";

/// The corpus's scenes: free stacks and pyramids, the stability report's hard cases at 1/60 s
/// and 1/1000 s, piles of boxes and balls, a ragdoll, a ragdoll pile, MuJoCo's humanoid falling
/// (MJCF) and a pile of four of them, the buggy on terrain, and a grid of 432 resting boxes.
pub fn corpus_scenes() -> Vec<CorpusScene> {
    let pyramid4 = FrictionModel::Pyramid { facets: 4 };
    let s = |family, name, source, steps, every| CorpusScene { family, name, source, steps, every };
    let (slow, fast) = (1.0 / 60.0, 1.0 / 1000.0);
    vec![
        s("box", "box-flat", SceneSource::BuiltIn("box-flat", FrictionModel::Cone), 60, 3),
        s("box", "box-drop", SceneSource::BuiltIn("box-drop", FrictionModel::Cone), 150, 2),
        s("stack", "stack2-cone", SceneSource::BuiltIn("stack2", FrictionModel::Cone), 60, 1),
        s("stack", "stack2-pyramid4", SceneSource::BuiltIn("stack2", pyramid4), 60, 1),
        s("stack", "stack10-cone", SceneSource::BuiltIn("stack10", FrictionModel::Cone), 60, 3),
        s("stack", "stack10-pyramid4", SceneSource::BuiltIn("stack10", pyramid4), 60, 3),
        s("hard", "stack10-dt60", SceneSource::Stack { count: 10, dt: slow }, 60, 3),
        s("hard", "stack10-dt1000", SceneSource::Stack { count: 10, dt: fast }, 200, 10),
        s("hard", "stack20-dt60", SceneSource::Stack { count: 20, dt: slow }, 60, 3),
        s("hard", "stack20-dt1000", SceneSource::Stack { count: 20, dt: fast }, 200, 10),
        s("hard", "pyramid10-dt60", SceneSource::Pyramid { dt: slow }, 60, 3),
        s("hard", "pyramid10-dt1000", SceneSource::Pyramid { dt: fast }, 200, 10),
        s("hard", "heavy-on-light-dt60", SceneSource::HeavyOnLight { dt: slow }, 60, 3),
        s("hard", "heavy-on-light-dt1000", SceneSource::HeavyOnLight { dt: fast }, 200, 10),
        s("pile", "pile", SceneSource::File("pile.toml"), 600, 10),
        s("ragdoll", "ragdoll-fall", SceneSource::File("ragdoll_fall.toml"), 1000, 15),
        s("ragdoll-crowd", "ragdoll-pile", SceneSource::File("ragdoll_pile.toml"), 2000, 50),
        s("humanoid", "humanoid-fall", SceneSource::Mjcf(HUMANOID), 1500, 40),
        s("humanoid-crowd", "humanoid-pile", SceneSource::MjcfPile { file: HUMANOID, count: 4 }, 1500, 40),
        s("vehicle", "buggy-terrain", SceneSource::File("buggy_terrain.toml"), 1000, 15),
        s("grid", "box-grid", SceneSource::Text(BOX_GRID), 10, 1),
    ]
}

/// A world and, for a scene file, the scene (its controls are applied before each step).
pub enum CorpusWorld {
    /// A world stepped as it is.
    World(Box<World>),
    /// A scene file's scene.
    Scene(Box<scene::Scene>),
}

impl CorpusWorld {
    /// Applies the scene's controls (if any) and returns the world to step.
    pub fn prepare(&mut self) -> Result<&mut World, String> {
        match self {
            CorpusWorld::World(w) => Ok(w),
            CorpusWorld::Scene(s) => {
                s.apply_controls().map_err(|e| e.to_string())?;
                Ok(&mut s.world)
            }
        }
    }
}

fn hard_world(dt: f64) -> Result<World, StepError> {
    let mut options = WorldOptions {
        dt,
        solvers: vec![SolverKind::Newton, SolverKind::Clarabel],
        tolerance: 1e-8,
        accept_last: true,
        ..Default::default()
    };
    options.sleep.enabled = false;
    let mut w = World::new(options);
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, crate::math::Transform::identity(), 0)?;
    Ok(w)
}

fn add_cube(w: &mut World, name: &str, side: f64, mass: f64, at: Vec3) -> Result<(), StepError> {
    let size = Vec3::repeat(side);
    let model = free_body(name, Shape::Box { size }, RigidInertia::solid_box(mass, size));
    let m = w.add_multibody(name, model, &MeshOptions::default())?;
    let q = &mut w.multibody_mut(m).state.q;
    let r = UnitQuaternion::<f64>::identity();
    q.rows_mut(0, 3).copy_from(&at);
    q.rows_mut(3, 4).copy_from_slice(&[r.i, r.j, r.k, r.w]);
    Ok(())
}

/// Builds the world of `source`; scene files are read from `models`.
pub fn corpus_world(source: &SceneSource, models: &Path) -> Result<CorpusWorld, String> {
    let side = 0.1;
    let world = match *source {
        SceneSource::BuiltIn(name, friction) => {
            let mut w = scene_world(name).map_err(|e| e.to_string())?;
            w.set_friction(friction).map_err(|e| e.to_string())?;
            w
        }
        SceneSource::File(file) => {
            let path: PathBuf = models.join(file);
            return Ok(CorpusWorld::Scene(Box::new(scene::load_file(&path).map_err(|e| e.to_string())?)));
        }
        SceneSource::Text(text) => {
            return Ok(CorpusWorld::Scene(Box::new(
                scene::load_str(text, models).map_err(|e| e.to_string())?,
            )));
        }
        SceneSource::Mjcf(file) => {
            let loaded = crate::io::mjcf::load_file(models.join(file)).map_err(|e| e.to_string())?;
            let options = loaded.world_options();
            loaded.into_world(options).map_err(|e| e.to_string())?
        }
        SceneSource::MjcfPile { file, count } => {
            let loaded = crate::io::mjcf::load_file(models.join(file)).map_err(|e| e.to_string())?;
            let free_root =
                loaded.model.nbodies() > 1 && matches!(loaded.model.joint(1), crate::model::Joint::Free);
            if !free_root {
                return Err(format!("{file}: a pile needs a model with a free root"));
            }
            let options = loaded.world_options();
            let (model, q0) = (loaded.model.clone(), loaded.q0.clone());
            let mut w = loaded.into_world(options).map_err(|e| e.to_string())?;
            for k in 1..count {
                let name = format!("{}{k}", model.name());
                let m = w
                    .add_multibody(&name, model.clone(), &MeshOptions::default())
                    .map_err(|e| e.to_string())?;
                let q = &mut w.multibody_mut(m).state.q;
                q.copy_from(&q0);
                // Free root: position, then the quaternion (i, j, k, w).
                q[2] += 1.8 * k as f64;
                let turn =
                    UnitQuaternion::from_axis_angle(&Vec3::z_axis(), std::f64::consts::FRAC_PI_3 * k as f64);
                let r =
                    turn * UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[6], q[3], q[4], q[5]));
                q.rows_mut(3, 4).copy_from_slice(&[r.i, r.j, r.k, r.w]);
            }
            w
        }
        SceneSource::Stack { count, dt } => {
            let mut w = hard_world(dt).map_err(|e| e.to_string())?;
            for k in 0..count {
                let at = Vec3::new(0.0, 0.0, side / 2.0 + side * k as f64);
                add_cube(&mut w, &format!("box{k}"), side, 1.0, at).map_err(|e| e.to_string())?;
            }
            w
        }
        SceneSource::Pyramid { dt } => {
            let gap = 0.002;
            let mut w = hard_world(dt).map_err(|e| e.to_string())?;
            for row in 0..10 {
                for k in 0..10 - row {
                    let x = (k as f64 - (9 - row) as f64 / 2.0) * (side + gap);
                    let at = Vec3::new(x, 0.0, side / 2.0 + side * row as f64);
                    add_cube(&mut w, &format!("box{row}_{k}"), side, 1.0, at).map_err(|e| e.to_string())?;
                }
            }
            w
        }
        SceneSource::HeavyOnLight { dt } => {
            let mut w = hard_world(dt).map_err(|e| e.to_string())?;
            add_cube(&mut w, "light", side, 1.0, Vec3::new(0.0, 0.0, side / 2.0))
                .map_err(|e| e.to_string())?;
            add_cube(&mut w, "heavy", side, 1000.0, Vec3::new(0.0, 0.0, 1.5 * side))
                .map_err(|e| e.to_string())?;
            w
        }
    };
    Ok(CorpusWorld::World(Box::new(world)))
}
