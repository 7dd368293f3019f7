//! What a Python `World` holds: a gelenk world and the recipe that builds it again from scratch
//! (a scene file's text, an MJCF scene, a model, a built-in scene), the flat state layout over
//! its multibodies, and a step that applies a scene's vehicle commands as `gelenk simulate`
//! does. No Python objects here: a `Sim` is `Send`, so rollouts step one per thread.

use gelenk::collision::MeshOptions;
use gelenk::io::mjcf::MjcfScene;
use gelenk::io::scene::{Scene, SceneError};
use gelenk::math::Vec3;
use gelenk::model::Shape;
use gelenk::world::{World, WorldOptions};
use gelenk::Model;
use std::sync::Arc;

/// How to build a world again at its initial state.
pub enum Recipe {
    /// An MJCF scene, as [`MjcfScene::into_world`] with its own options.
    Mjcf(MjcfScene),
    /// One model as the world's only multibody, at its neutral configuration, optionally on the
    /// ground plane z = 0; `meshes` says where collision meshes are and what a missing one does
    /// (the options boxed: they are most of the variant's size).
    Model { model: Model, options: Box<WorldOptions>, ground: bool, meshes: MeshOptions },
    /// A built-in scene of [`gelenk::scenes::scene_world`].
    BuiltIn(String),
}

impl Recipe {
    /// A world at the recipe's initial state.
    pub fn build(&self) -> Result<World, String> {
        match self {
            Recipe::Mjcf(scene) => {
                let options = scene.world_options();
                scene.clone().into_world(options).map_err(|e| e.to_string())
            }
            Recipe::Model { model, options, ground, meshes } => {
                let mut world = World::new(options.as_ref().clone());
                if *ground {
                    let plane = Shape::HalfSpace { normal: Vec3::z() };
                    world
                        .add_static("ground", &plane, gelenk::math::Transform::identity(), 0)
                        .map_err(|e| e.to_string())?;
                }
                let name = if model.name().is_empty() { "model" } else { model.name() };
                world.add_multibody(name, model.clone(), meshes).map_err(|e| e.to_string())?;
                Ok(world)
            }
            Recipe::BuiltIn(name) => gelenk::scenes::scene_world(name).map_err(|e| e.to_string()),
        }
    }
}

/// A world and how to build it again.
pub enum Sim {
    /// A scene file: its world, vehicles and commands.
    Scene(Box<Scene>),
    /// Any other world.
    World { world: Box<World>, recipe: Arc<Recipe> },
}

/// Where each multibody's coordinates sit in the flat vectors: q of multibody i at
/// `q_start[i]..q_start[i + 1]` of qpos, v at `v_start[i]..v_start[i + 1]` of qvel; the state
/// vector is `[qpos, qvel]` (nq + nv entries).
#[derive(Clone, Debug, PartialEq)]
pub struct Layout {
    pub q_start: Vec<usize>,
    pub v_start: Vec<usize>,
}

impl Layout {
    /// Total configuration coordinates.
    pub fn nq(&self) -> usize {
        *self.q_start.last().unwrap_or(&0)
    }
    /// Total velocity coordinates.
    pub fn nv(&self) -> usize {
        *self.v_start.last().unwrap_or(&0)
    }
    /// Length of the state vector.
    pub fn nstate(&self) -> usize {
        self.nq() + self.nv()
    }
}

impl Sim {
    /// The world.
    pub fn world(&self) -> &World {
        match self {
            Sim::Scene(scene) => &scene.world,
            Sim::World { world, .. } => world,
        }
    }

    /// The world, to change.
    pub fn world_mut(&mut self) -> &mut World {
        match self {
            Sim::Scene(scene) => &mut scene.world,
            Sim::World { world, .. } => world,
        }
    }

    /// What was left out while loading (meshes skipped).
    pub fn warnings(&self) -> Vec<String> {
        match self {
            Sim::Scene(scene) => scene.warnings.clone(),
            Sim::World { world, .. } => world.collision().warnings().to_vec(),
        }
    }

    /// A new world of the same recipe at its initial state.
    pub fn fresh(&self) -> Result<Sim, String> {
        match self {
            Sim::Scene(scene) => scene.rebuilt().map(|s| Sim::Scene(Box::new(s))).map_err(|e| e.to_string()),
            Sim::World { recipe, .. } => {
                Ok(Sim::World { world: Box::new(recipe.build()?), recipe: Arc::clone(recipe) })
            }
        }
    }

    /// One step: a scene's vehicle commands whose time has come, then the world's step. The
    /// error reads as `gelenk simulate` prints it: `step N (t = T s): why`.
    pub fn step(&mut self) -> Result<(), String> {
        let world = self.world();
        let (step, time) = (world.stats().step + 1, world.time());
        let failed = |source| SceneError::Step { step, time, source: Box::new(source) }.to_string();
        if let Sim::Scene(scene) = self {
            scene.apply_controls().map_err(|e| e.to_string())?;
        }
        self.world_mut().step().map(|_| ()).map_err(failed)
    }

    /// The flat layout of the world's multibodies.
    pub fn layout(&self) -> Layout {
        let world = self.world();
        let (mut q_start, mut v_start) = (vec![0], vec![0]);
        for i in 0..world.multibody_count() {
            let model = world.multibody(i).model();
            q_start.push(q_start[i] + model.nq());
            v_start.push(v_start[i] + model.nv());
        }
        Layout { q_start, v_start }
    }

    /// Writes `[qpos, qvel]` of every multibody into `out` (`layout.nstate()` entries).
    pub fn read_state(&self, layout: &Layout, out: &mut [f64]) {
        let world = self.world();
        let nq = layout.nq();
        for i in 0..world.multibody_count() {
            let state = &world.multibody(i).state;
            out[layout.q_start[i]..layout.q_start[i + 1]].copy_from_slice(state.q.as_slice());
            out[nq + layout.v_start[i]..nq + layout.v_start[i + 1]].copy_from_slice(state.v.as_slice());
        }
    }

    /// Sets every multibody's q and v from `[qpos, qvel]` (checked: finite, quaternions that can
    /// be normalized; nothing is changed on an error) and wakes them.
    pub fn write_state(&mut self, layout: &Layout, state: &[f64]) -> Result<(), String> {
        let nq = layout.nq();
        let world = self.world_mut();
        for i in 0..world.multibody_count() {
            let (q, v) = (
                &state[layout.q_start[i]..layout.q_start[i + 1]],
                &state[nq + layout.v_start[i]..nq + layout.v_start[i + 1]],
            );
            check_coordinates(world.multibody(i).model(), world.multibody_name(i), q, v)?;
        }
        for i in 0..world.multibody_count() {
            let mb = world.multibody_mut(i);
            mb.state.q.as_mut_slice().copy_from_slice(&state[layout.q_start[i]..layout.q_start[i + 1]]);
            mb.state
                .v
                .as_mut_slice()
                .copy_from_slice(&state[nq + layout.v_start[i]..nq + layout.v_start[i + 1]]);
            world.wake(i);
        }
        Ok(())
    }

    /// Sets every multibody's joint forces τ from the flat `tau` (`layout.nv()` entries, N·m or
    /// N), waking those whose forces changed. The caller checks that they are finite.
    pub fn write_tau(&mut self, layout: &Layout, tau: &[f64]) {
        let world = self.world_mut();
        for i in 0..world.multibody_count() {
            let new = &tau[layout.v_start[i]..layout.v_start[i + 1]];
            let mb = world.multibody_mut(i);
            if mb.tau.as_slice() != new {
                mb.tau.as_mut_slice().copy_from_slice(new);
                world.wake(i);
            }
        }
    }
}

/// Checks a multibody's q and v before they are set: finite, quaternions of usable norm.
pub fn check_coordinates(model: &Model, name: &str, q: &[f64], v: &[f64]) -> Result<(), String> {
    for (what, values, owner) in [("q", q, 0), ("v", v, 1)] {
        if let Some(k) = values.iter().position(|x| !x.is_finite()) {
            let joint = if owner == 0 { model.joint_of_q(k) } else { model.dof_joint(k) };
            return Err(format!(
                "multibody `{name}`: {what} of joint `{}` is not finite ({})",
                model.joint_name(joint),
                values[k]
            ));
        }
    }
    model.check_quaternions(q).map_err(|e| format!("multibody `{name}`: {e}"))
}

/// Mesh options that leave out collision meshes that cannot be found (with a warning).
pub fn skip_meshes() -> MeshOptions {
    MeshOptions { missing: gelenk::collision::MissingMeshPolicy::Skip, ..MeshOptions::default() }
}
