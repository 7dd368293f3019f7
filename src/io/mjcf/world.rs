//! A loaded MJCF scene put into a [`World`]: the model's trees as multibodies at MuJoCo's `qpos0`,
//! on the static geometry, with MuJoCo's time step, gravity and friction model.

use super::MjcfScene;
use crate::collision::MeshOptions;
use crate::world::{StepError, World, WorldOptions};

impl MjcfScene {
    /// World options that follow the scene: `<option timestep>`, its gravity, its friction model
    /// (`<option cone>`), and as the contact friction coefficient the largest sliding friction of
    /// any geom, colliding or not (MuJoCo combines two geoms' coefficients by their maximum; a
    /// world has one coefficient, so geoms of different friction all take the largest). Everything else is
    /// [`WorldOptions::default`].
    pub fn world_options(&self) -> WorldOptions {
        let mu = self.geoms.iter().map(|g| g.friction[0]).chain(self.statics.iter().map(|s| s.friction[0]));
        let mut options = WorldOptions {
            dt: self.timestep,
            gravity: self.gravity,
            friction: self.friction,
            ..WorldOptions::default()
        };
        options.contact.mu = mu.fold(0.0, f64::max);
        options
    }

    /// A world with `options` (usually [`MjcfScene::world_options`]) holding the colliding static
    /// geoms (material 0) and the model's trees at [`MjcfScene::q0`] and at rest, each tree a
    /// multibody of its own ([`Model::split_trees`](crate::model::Model::split_trees)): the
    /// file's top-level bodies (the humanoids of a pile) sleep, wake and form contact islands
    /// apart, as bodies of a MuJoCo model do. A model of one tree is one multibody named like
    /// the model; otherwise multibody k is the k-th tree in document order, named like its root
    /// body, and the multibodies' q (and v) concatenated in order are the model's;
    /// [`Model::tree_body`](crate::model::Model::tree_body) gives the multibody of an
    /// [`MjcfBody::body`](super::MjcfBody::body) and its index there. The trees collide with
    /// each other, as in MuJoCo; within one tree self-collision stays off (MuJoCo's humanoid
    /// overlaps its own capsules between non-adjacent bodies, which hard contacts cannot hold
    /// apart), and `<contact><exclude>`, `<flag contact>` and contype/conaffinity masks other
    /// than both 0 are not applied.
    pub fn into_world(self, options: WorldOptions) -> Result<World, StepError> {
        let mut world = World::new(options);
        for s in self.statics.iter().filter(|s| s.collides) {
            world.add_static(&s.name, &s.shape, s.pose, 0)?;
        }
        let trees = self.model.split_trees();
        let one = trees.len() == 1;
        let mut start = 0;
        for tree in trees {
            let name = if one { self.model.name() } else { tree.body_name(1) }.to_string();
            let nq = tree.nq();
            let index = world.add_multibody(&name, tree, &MeshOptions::default())?;
            world.multibody_mut(index).state.q.copy_from_slice(&self.q0.as_slice()[start..start + nq]);
            start += nq;
        }
        Ok(world)
    }
}

#[cfg(test)]
mod tests {
    use crate::constraints::FrictionModel;
    use crate::math::Vec3;

    #[test]
    fn a_loaded_scene_becomes_a_world_with_its_options_statics_and_initial_pose() {
        let scene = crate::io::mjcf::load_str(
            r#"<mujoco model="drop"><option timestep="0.004" cone="elliptic" gravity="0 0 -3"/>
                 <worldbody>
                   <geom type="plane" size="1 1 0.1" friction="0.4"/>
                   <geom type="box" size="0.1 0.1 0.1" pos="2 0 0" contype="0" conaffinity="0" friction="0.2"/>
                   <body name="ball" pos="0 0 1"><freejoint/>
                     <geom type="sphere" size="0.1" friction="0.9"/></body>
                 </worldbody></mujoco>"#,
        )
        .unwrap();
        let options = scene.world_options();
        assert_eq!(options.dt, 0.004);
        assert_eq!(options.gravity, Vec3::new(0.0, 0.0, -3.0));
        assert_eq!(options.friction, FrictionModel::Cone);
        assert_eq!(options.contact.mu, 0.9, "the largest sliding friction of any geom");
        let q0 = scene.q0.clone();
        let world = scene.into_world(options).unwrap();
        assert_eq!(world.multibody_count(), 1);
        assert_eq!(world.multibody_name(0), "drop");
        assert_eq!(world.multibody(0).state.q, q0);
        assert_eq!(world.multibody(0).state.q[2], 1.0);
        // The plane collides; the box that never collides in MuJoCo is left out.
        let statics: Vec<&str> = world
            .collision()
            .colliders()
            .iter()
            .filter(|c| c.attachment().is_static())
            .map(|c| c.name())
            .collect();
        assert_eq!(statics, ["world_geom0"]);
    }

    /// The world of an MJCF document with its own options, and the scene's initial q.
    fn world_of(xml: &str) -> (crate::world::World, nalgebra::DVector<f64>) {
        let scene = crate::io::mjcf::load_str(xml).unwrap();
        let q0 = scene.q0.clone();
        let options = scene.world_options();
        (scene.into_world(options).unwrap(), q0)
    }

    /// Two free boxes dropped one above the other in one file: the upper one lands on the lower
    /// (the file's bodies collide with each other, as in MuJoCo), it does not pass through it.
    #[test]
    fn the_bodies_of_one_file_collide_with_each_other() {
        let (mut world, _) = world_of(
            r#"<mujoco model="stack"><worldbody><geom type="plane" size="1 1 0.1"/>
                 <body name="low" pos="0 0 0.1"><freejoint/><geom type="box" size="0.1 0.1 0.1"/></body>
                 <body name="high" pos="0 0 0.35"><freejoint/><geom type="box" size="0.1 0.1 0.1"/></body>
               </worldbody></mujoco>"#,
        );
        for _ in 0..500 {
            world.step().unwrap();
        }
        assert_eq!((world.multibody_name(0), world.multibody_name(1)), ("low", "high"));
        let (low, high) = (world.multibody(0).state.q[2], world.multibody(1).state.q[2]);
        assert!((low - 0.1).abs() < 2e-3, "lower box at {low} m");
        assert!((high - 0.3).abs() < 2e-3, "upper box at {high} m: it must rest on the lower one");
    }

    /// Each tree of a file is a multibody of its own and sleeps on its own: a box resting on the
    /// plane falls asleep while another, dropped from 20 m, is still falling (one multibody
    /// holding both would stay awake until both rest).
    #[test]
    fn the_trees_of_one_file_sleep_apart() {
        let (mut world, q0) = world_of(
            r#"<mujoco model="two"><worldbody><geom type="plane" size="1 1 0.1"/>
                 <body name="resting" pos="0 0 0.1"><freejoint/><geom type="box" size="0.1 0.1 0.1"/></body>
                 <body name="falling" pos="3 0 20"><freejoint/><geom type="sphere" size="0.1"/></body>
               </worldbody></mujoco>"#,
        );
        assert_eq!(world.multibody_count(), 2);
        let q = [world.multibody(0).state.q.as_slice(), world.multibody(1).state.q.as_slice()].concat();
        assert_eq!(q, q0.as_slice(), "the trees' q concatenated are the model's");
        for _ in 0..500 {
            world.step().unwrap();
        }
        assert!(world.multibody(0).is_asleep(), "the resting box sleeps");
        assert!(!world.multibody(1).is_asleep(), "the sphere is still falling");
        assert!(world.multibody(1).state.v[2] < -9.0);
    }
}
