//! A model's root trees as models of their own: the subtrees hanging from the universe share no
//! degree of freedom (M(q) is block diagonal over them), so each can be a multibody of its own,
//! which sleeps, wakes and forms contact islands apart from the others (a pile of humanoids read
//! from one MJCF file).

use super::{Frame, Model, NO_DOF};
use nalgebra::DVector;

impl Model {
    /// The bodies attached to the universe, in body order: the roots of the model's trees.
    pub fn root_bodies(&self) -> &[usize] {
        &self.children[0]
    }

    /// Each root tree as a model of its own, in body order: tree k holds the bodies
    /// `root..end` (depth-first numbering keeps a subtree contiguous) with the same joints,
    /// placements (in the same universe frame), inertias, limits, dynamics, frames and
    /// geometries, and its configuration is the stretch `idx_q(root)..` of the whole model's q
    /// (likewise v): the trees' q concatenated in order are the model's q. Frames, geometries
    /// and the fused inertia of bodies welded to the universe go to the first tree. A model of
    /// one tree (or none) is returned whole. Each tree keeps the model's name, gravity and
    /// source directory.
    pub fn split_trees(&self) -> Vec<Model> {
        let roots = self.root_bodies();
        if roots.len() <= 1 {
            return vec![self.clone()];
        }
        let nbodies = self.nbodies();
        roots
            .iter()
            .enumerate()
            .map(|(k, &root)| {
                let end = roots.get(k + 1).copied().unwrap_or(nbodies);
                self.tree(root, end, k == 0)
            })
            .collect()
    }

    /// Where body `body` of this model is in [`Model::split_trees`]: the tree's index and the
    /// body's index in that tree's model (the universe: tree 0, body 0). `None` for a body
    /// index the model does not have.
    pub fn tree_body(&self, body: usize) -> Option<(usize, usize)> {
        if body >= self.nbodies() {
            return None;
        }
        if body == 0 || self.children[0].len() <= 1 {
            return Some((0, body));
        }
        let mut root = body;
        while self.parents[root] != 0 {
            root = self.parents[root];
        }
        let tree = self.children[0].iter().position(|&r| r == root)?;
        Some((tree, body - root + 1))
    }

    /// The tree of bodies `root..end` (one root tree) as a model; `with_universe`: also the
    /// frames and geometries on the universe.
    fn tree(&self, root: usize, end: usize, with_universe: bool) -> Model {
        let local = |b: usize| if b == 0 { 0 } else { b - root + 1 };
        let in_tree = |b: usize| (root..end).contains(&b) || (with_universe && b == 0);
        let (q0, v0) = (self.idx_q[root], self.idx_v[root]);
        let (q1, v1) = (self.idx_q.get(end).copied().unwrap_or(self.nq), self.subtree_dof_end[root]);
        let bodies = std::iter::once(0).chain(root..end);
        let dof = |k: usize| if k == NO_DOF { NO_DOF } else { k - v0 };
        let mut dof_path = Vec::new();
        let mut dof_path_start = vec![0];
        for k in v0..v1 {
            let path = &self.dof_path[self.dof_path_start[k]..self.dof_path_start[k + 1]];
            dof_path.extend(path.iter().map(|&j| j - v0));
            dof_path_start.push(dof_path.len());
        }
        let slice = |x: &DVector<f64>, a: usize, b: usize| DVector::from_column_slice(&x.as_slice()[a..b]);
        Model {
            name: self.name.clone(),
            nq: q1 - q0,
            nv: v1 - v0,
            body_names: bodies.clone().map(|b| self.body_names[b].clone()).collect(),
            joint_names: bodies.clone().map(|b| self.joint_names[b].clone()).collect(),
            joints: bodies.clone().map(|b| self.joints[b]).collect(),
            parents: bodies.clone().map(|b| local(self.parents[b])).collect(),
            children: std::iter::once(vec![1])
                .chain((root..end).map(|b| self.children[b].iter().map(|&c| local(c)).collect()))
                .collect(),
            placements: bodies.clone().map(|b| self.placements[b]).collect(),
            inertias: std::iter::once(if with_universe {
                self.inertias[0]
            } else {
                crate::math::SpatialInertia::zero()
            })
            .chain((root..end).map(|b| self.inertias[b]))
            .collect(),
            idx_q: std::iter::once(0).chain((root..end).map(|b| self.idx_q[b] - q0)).collect(),
            idx_v: std::iter::once(0).chain((root..end).map(|b| self.idx_v[b] - v0)).collect(),
            dof_joint: (v0..v1).map(|k| local(self.dof_joint[k])).collect(),
            dof_parent: (v0..v1).map(|k| dof(self.dof_parent[k])).collect(),
            dof_run_start: (v0..v1).map(|k| self.dof_run_start[k] - v0).collect(),
            dof_path,
            dof_path_start,
            subtree_dof_end: std::iter::once(v1 - v0)
                .chain((root..end).map(|b| self.subtree_dof_end[b] - v0))
                .collect(),
            lower_position_limit: slice(&self.lower_position_limit, q0, q1),
            upper_position_limit: slice(&self.upper_position_limit, q0, q1),
            velocity_limit: slice(&self.velocity_limit, v0, v1),
            effort_limit: slice(&self.effort_limit, v0, v1),
            damping: slice(&self.damping, v0, v1),
            friction: slice(&self.friction, v0, v1),
            ball_limits: bodies.map(|b| self.ball_limits[b]).collect(),
            frames: self
                .frames
                .iter()
                .filter(|f| in_tree(f.body) || (f.body == 0 && f.name == super::builder::UNIVERSE))
                .map(|f| Frame { body: local(f.body), ..f.clone() })
                .collect(),
            geometries: self
                .geometries
                .iter()
                .filter(|g| in_tree(g.body))
                .map(|g| super::GeometrySpec { body: local(g.body), ..g.clone() })
                .collect(),
            gravity: self.gravity,
            source_dir: self.source_dir.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::algorithms::{crba, rnea};
    use crate::math::{Transform, Vec3};
    use crate::model::{
        BodySpec, Joint, JointDynamics, JointLimits, Model, ModelBuilder, RigidInertia, Shape,
    };
    use crate::Data;
    use nalgebra::DVector;
    use rand::{Rng, SeedableRng};

    /// Three trees on the universe (a free torso with a limited hinge arm and a ball head; a
    /// damped pendulum; a free box) and a plate welded to the world.
    fn three_trees() -> Model {
        let at = |x: f64, y: f64, z: f64| Transform::from_translation(Vec3::new(x, y, z));
        let block = |m: f64| RigidInertia::solid_box(m, Vec3::new(0.2, 0.3, 0.4));
        let mut b = ModelBuilder::new();
        b.name("three");
        b.add_body(BodySpec::new("torso", "universe", Joint::Free, at(0.0, 0.0, 1.0), block(5.0)));
        b.add_body(
            BodySpec::new("arm", "torso", Joint::Hinge { axis: Vec3::y() }, at(0.2, 0.0, 0.1), block(1.0))
                .with_limits(JointLimits { lower: vec![-1.0], upper: vec![0.5], ..Default::default() })
                .with_collision(Shape::Sphere { radius: 0.05 }, at(0.0, 0.0, -0.1)),
        );
        b.add_body(BodySpec::new("head", "torso", Joint::Ball, at(0.0, 0.0, 0.3), block(2.0)));
        let mut pendulum =
            BodySpec::new("bob", "universe", Joint::Hinge { axis: Vec3::x() }, at(1.0, 0.0, 2.0), block(0.5));
        pendulum.dynamics = JointDynamics { damping: 0.3, friction: 0.1 };
        b.add_body(pendulum);
        b.add_body(
            BodySpec::new("plate", "universe", Joint::Fixed, at(0.0, 0.0, -0.1), block(1.0))
                .with_collision(Shape::Box { size: Vec3::new(2.0, 2.0, 0.1) }, Transform::identity()),
        );
        b.add_body(
            BodySpec::new("box", "universe", Joint::Free, at(-1.0, 0.0, 0.5), block(0.7))
                .with_collision(Shape::Box { size: Vec3::new(0.2, 0.3, 0.4) }, Transform::identity()),
        );
        b.build().unwrap()
    }

    #[test]
    fn the_trees_of_a_model_have_its_coordinates_bodies_and_dynamics() {
        let model = three_trees();
        let trees = model.split_trees();
        assert_eq!(trees.len(), 3);
        let names: Vec<Vec<&str>> =
            trees.iter().map(|t| (0..t.nbodies()).map(|i| t.body_name(i)).collect()).collect();
        assert_eq!(
            names,
            [vec!["universe", "torso", "arm", "head"], vec!["universe", "bob"], vec!["universe", "box"]]
        );
        assert_eq!(trees.iter().map(Model::nq).sum::<usize>(), model.nq());
        assert_eq!(trees.iter().map(Model::nv).sum::<usize>(), model.nv());
        // Limits and dynamics follow their joints.
        assert_eq!(trees[0].upper_position_limit()[7], 0.5);
        assert_eq!(trees[1].damping()[0], 0.3);
        assert_eq!(trees[1].friction()[0], 0.1);
        // The plate welded to the world stays with the first tree (its frames and its box), each
        // tree keeps its own geometry.
        let geometry =
            |t: &Model| t.geometries().iter().map(|g| (g.link.clone(), g.body)).collect::<Vec<_>>();
        assert_eq!(geometry(&trees[0]), [("arm".to_string(), 2), ("plate".to_string(), 0)]);
        assert_eq!(geometry(&trees[2]), [("box".to_string(), 1)]);
        assert!(trees[0].frame_id("plate").is_some() && trees[1].frame_id("plate").is_none());
        assert_eq!(trees[2].frame_id("universe"), Some(0));

        // Every body is found in its tree under its own name.
        for body in 0..model.nbodies() {
            let (tree, local) = model.tree_body(body).unwrap();
            assert_eq!(trees[tree].body_name(local), model.body_name(body));
        }
        assert_eq!(model.tree_body(model.nbodies()), None);

        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let mut data = Data::new(&model);
        for _ in 0..5 {
            let q = model.random_configuration(&mut rng);
            let v = DVector::from_fn(model.nv(), |_, _| rng.random_range(-2.0..2.0));
            let a = DVector::from_fn(model.nv(), |_, _| rng.random_range(-2.0..2.0));
            let tau = rnea(&model, &mut data, &q, &v, &a).unwrap().clone();
            let m = crba(&model, &mut data, &q).unwrap().clone();
            let (mut iq, mut iv) = (0, 0);
            for tree in &trees {
                let (nq, nv) = (tree.nq(), tree.nv());
                let qt = DVector::from_column_slice(&q.as_slice()[iq..iq + nq]);
                let vt = DVector::from_column_slice(&v.as_slice()[iv..iv + nv]);
                let at = DVector::from_column_slice(&a.as_slice()[iv..iv + nv]);
                let mut tree_data = Data::new(tree);
                let tau_tree = rnea(tree, &mut tree_data, &qt, &vt, &at).unwrap();
                let tau_whole = tau.rows(iv, nv);
                assert!(
                    (tau_tree - tau_whole).amax() <= 1e-12 * tau_whole.amax(),
                    "{tau_tree} vs {tau_whole}"
                );
                let m_tree = crba(tree, &mut tree_data, &qt).unwrap();
                let m_whole = m.view((iv, iv), (nv, nv));
                assert!((m_tree - m_whole).amax() <= 1e-12 * m_whole.amax(), "{m_tree} vs {m_whole}");
                // Nothing couples the tree to the others.
                let rows = m.view((iv, 0), (nv, model.nv()));
                let outside = (0..model.nv()).filter(|c| !(iv..iv + nv).contains(c));
                assert!(outside
                    .flat_map(|c| rows.column(c).iter().copied().collect::<Vec<_>>())
                    .all(|x| x == 0.0));
                iq += nq;
                iv += nv;
            }
        }
    }

    #[test]
    fn a_model_of_one_tree_is_its_only_tree() {
        let mut b = ModelBuilder::new();
        b.add_body(BodySpec::new(
            "ball",
            "universe",
            Joint::Free,
            Transform::identity(),
            RigidInertia::solid_sphere(1.0, 0.1),
        ));
        let model = b.build().unwrap();
        let trees = model.split_trees();
        assert_eq!(trees.len(), 1);
        assert_eq!(trees[0].nv(), 6);
        assert_eq!(ModelBuilder::new().build().unwrap().split_trees().len(), 1);
    }
}
