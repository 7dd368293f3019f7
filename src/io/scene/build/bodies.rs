//! `[[urdf]]` and `[[body]]` entries: models and primitive bodies placed in the world, with their
//! copies (`count`, `spacing`, `jitter`), initial state, servos and materials.

use super::{pose, Builder, Copies};
use crate::collision::{MeshOptions, MissingMeshPolicy};
use crate::io::scene::schema::{BodySection, MissingMeshes, ShapeName, UrdfSection};
use crate::io::scene::values::{Positive, V3};
use crate::io::scene::SceneError;
use crate::io::urdf::{self, UrdfOptions};
use crate::math::{Transform, Vec3};
use crate::model::{BodySpec, Joint, Model, ModelBuilder, RigidInertia, Shape};
use crate::world::{PoseServo, Servo, World};
use rand::{Rng, SeedableRng};
use std::ops::Range;
use toml::Spanned;

impl Builder<'_> {
    /// Adds the model(s) of a `[[urdf]]` entry; returns the URDF loader's warnings.
    pub(super) fn urdf(
        &mut self,
        world: &mut World,
        u: &Spanned<UrdfSection>,
    ) -> Result<Vec<String>, SceneError> {
        let span = u.span();
        let u = u.get_ref();
        let err = |message: String| self.src.invalid(span.clone(), message);
        let placement = pose(u.position, u.rpy, u.quaternion).map_err(err)?;
        let material = self.material_of(&u.material)?;
        let path = self.src.resolve(u.path.get_ref());
        let meshes = MeshOptions {
            search_paths: u.package_paths.iter().map(|p| self.src.resolve(p)).collect(),
            missing: match u.missing_meshes {
                MissingMeshes::Error => MissingMeshPolicy::Error,
                MissingMeshes::Skip => MissingMeshPolicy::Skip,
            },
            ..MeshOptions::default()
        };
        let options = UrdfOptions {
            floating_base: u.floating,
            strict: u.strict,
            balance_inertia: u.balance_inertia,
            inertia_from_collision: u.inertia_from_collision,
            meshes: meshes.clone(),
            ..UrdfOptions::default()
        };
        let loaded = urdf::load_file_with_warnings(&path, &options).map_err(|source| SceneError::Urdf {
            at: self.src.location(u.path.span()),
            source: Box::new(source),
        })?;
        let mut model = loaded.model;
        let file_name = u.path.get_ref();
        let warnings: Vec<String> = loaded.warnings.iter().map(|w| format!("{file_name}: {w}")).collect();
        if !u.floating && (u.velocity.is_some() || u.angular_velocity.is_some()) {
            return Err(err("`velocity` and `angular_velocity` need `floating = true`".to_string()));
        }
        let file = u.path.get_ref();
        let joint_of = |model: &Model, name: &str, span: Range<usize>| {
            model
                .joint_id(name)
                .filter(|&j| j > 0)
                .ok_or_else(|| self.src.invalid(span, format!("no moving joint `{name}` in {file}")))
        };
        // Limits first, so that initial positions are checked against them.
        for (name, value) in &u.limits {
            let j = joint_of(&model, name, value.span())?;
            if !matches!(model.joint(j), Joint::Hinge { .. } | Joint::Slider { .. }) {
                return Err(self.src.invalid(
                    value.span(),
                    format!(
                        "limits can be set on hinge and slider joints; `{name}` is {}",
                        model.joint(j).kind_name()
                    ),
                ));
            }
            let [lower, upper] = value.get_ref();
            if lower.0 > upper.0 {
                return Err(self
                    .src
                    .invalid(value.span(), format!("lower {} is above upper {}", lower.0, upper.0)));
            }
            let k = model.idx_q(j);
            model.lower_position_limit[k] = lower.0;
            model.upper_position_limit[k] = upper.0;
        }
        if !u.floating && (u.random_rotation || u.spin.is_some()) {
            return Err(err("`random_rotation` and `spin` need `floating = true`".to_string()));
        }
        let base_name = u.name.clone().unwrap_or_else(|| model.name().to_string());
        let base_name = if base_name.is_empty() { "robot".to_string() } else { base_name };

        let mut q = model.neutral_configuration();
        // A neutral position outside a joint's limits (Kinova's shoulder: [0.82, 5.46] rad) would
        // be pushed back by the limit rows at erp/h rad/s in the first step: start within them.
        for j in (1..model.nbodies()).filter(|&j| !matches!(model.joint(j), Joint::Free | Joint::Ball)) {
            for k in model.idx_q(j)..model.idx_q(j) + model.joint(j).nq() {
                let (lo, hi) = (model.lower_position_limit()[k], model.upper_position_limit()[k]);
                if lo <= hi {
                    q[k] = q[k].clamp(lo, hi);
                }
            }
        }
        let mut v = nalgebra::DVector::zeros(model.nv());
        let root = model.children(0).first().copied().filter(|&j| *model.joint(j) == Joint::Free);
        if u.floating && root.is_none() {
            return Err(err("the floating base has no free joint".to_string()));
        }
        for (name, value) in &u.joints {
            let j = joint_of(&model, name, value.span())?;
            let (iq, nq) = (model.idx_q(j), model.joint(j).nq());
            let x = &value.get_ref().0;
            if x.len() != nq {
                return Err(self.src.invalid(
                    value.span(),
                    format!("joint `{name}` has {nq} coordinate(s), {} given", x.len()),
                ));
            }
            for (k, &xk) in x.iter().enumerate() {
                let (lo, hi) = (model.lower_position_limit()[iq + k], model.upper_position_limit()[iq + k]);
                if xk < lo || xk > hi {
                    return Err(self.src.invalid(
                        value.span(),
                        format!("joint `{name}`: {xk} is outside its limits [{lo}, {hi}]"),
                    ));
                }
                q[iq + k] = xk;
            }
            if model.joint(j).quaternion_norm(x).is_some_and(|n| n < crate::model::MIN_QUATERNION_NORM) {
                return Err(self.src.invalid(
                    value.span(),
                    format!("joint `{name}`: a quaternion of norm (nearly) zero is no rotation"),
                ));
            }
            model.joint(j).normalize(&mut q.as_mut_slice()[iq..iq + nq]);
        }
        for (name, value) in &u.joint_velocities {
            let j = joint_of(&model, name, value.span())?;
            let (iv, nv) = (model.idx_v(j), model.joint(j).nv());
            let x = &value.get_ref().0;
            if x.len() != nv {
                return Err(self.src.invalid(
                    value.span(),
                    format!("joint `{name}` has {nv} velocity coordinate(s), {} given", x.len()),
                ));
            }
            v.rows_mut(iv, nv).copy_from_slice(x);
        }
        let servo_dofs: Vec<(usize, f64)> = (1..model.nbodies())
            .filter(|&j| {
                let joint = model.joint(j);
                joint.nq() == joint.nv() && !matches!(joint, Joint::Free | Joint::Ball)
            })
            .flat_map(|j| (0..model.joint(j).nv()).map(move |k| (j, k)))
            .map(|(j, k)| (model.idx_v(j) + k, q[model.idx_q(j) + k]))
            .collect();

        // Copies, placed as `[[body]]` copies are.
        let copies = Copies::new(u.count, u.spacing, u.jitter).map_err(err)?;
        self.claim_bodies(copies.len().saturating_mul(model.nbodies() - 1), span.clone())?;
        let mut rng = rand::rngs::StdRng::seed_from_u64(u.seed.unwrap_or(0));
        for cell in copies.cells() {
            let name = copies.name(&base_name, cell);
            self.claim_name(&name, span.clone())?;
            let offset = copies.offset(cell);
            let mut x = placement;
            if copies.jitter > 0.0 {
                let jitter = copies.jitter;
                x.translation += Vec3::from_fn(|_, _| rng.random_range(-jitter..=jitter));
            }
            x.translation += offset;
            if u.random_rotation {
                let turn = crate::model::joint::uniform_quaternion(&mut rng);
                let r = Transform::from_translation_quaternion(Vec3::zeros(), turn);
                x.rotation = r.rotation * x.rotation;
            }
            let mut angular = u.angular_velocity.map_or(Vec3::zeros(), |w| w.0);
            if let Some(spin) = u.spin {
                let axis = loop {
                    let a = Vec3::from_fn(|_, _| rng.random_range(-1.0..=1.0));
                    if a.norm() > 0.1 && a.norm() <= 1.0 {
                        break a.normalize();
                    }
                };
                angular += axis * spin.0;
            }
            let mut model = model.clone();
            let (mut q, mut v) = (q.clone(), v.clone());
            if let Some(root) = root.filter(|_| u.floating) {
                set_free_joint(&model, root, &x, u.velocity, Some(V3(angular)), &mut q, &mut v);
            } else {
                place_fixed_base(&mut model, &x);
            }
            let pose_servo = u.pose_servo.as_ref().map(|s| {
                PoseServo::scaled_by_subtree_mass(
                    &model,
                    q.clone(),
                    s.gain.0,
                    s.max_velocity.0,
                    s.torque_per_kg.0,
                )
            });
            let index =
                world.add_multibody(&name, model, &meshes).map_err(self.world_error(u.path.span()))?;
            world.set_self_collision(index, u.self_collision).map_err(self.world_error(span.clone()))?;
            for c in world.collision().colliders_of(index).to_vec() {
                world.collision_mut().set_material(c, material);
            }
            let mb = world.multibody_mut(index);
            mb.state.q = q;
            mb.state.v = v;
            if let Some(s) = &u.servo {
                for &(k, target) in &servo_dofs {
                    mb.set_servo(
                        k,
                        Some(Servo {
                            target_position: target,
                            gain: s.gain.0,
                            max_velocity: s.max_velocity.0,
                            max_force: s.max_force.0,
                        }),
                    );
                }
            }
            if let Some(servo) = pose_servo {
                mb.set_pose_servo(Some(servo)).map_err(|source| SceneError::Model {
                    at: self.src.location(span.clone()),
                    source: Box::new(source),
                })?;
            }
            self.built_one();
        }
        Ok(warnings)
    }

    pub(super) fn body(
        &mut self,
        world: &mut World,
        index: usize,
        body: &Spanned<BodySection>,
    ) -> Result<(), SceneError> {
        let span = body.span();
        let b = body.get_ref();
        let err = |message: String| self.src.invalid(span.clone(), message);
        let orientation = pose(b.position, b.rpy, b.quaternion).map_err(err)?;
        let material = self.material_of(&b.material)?;
        let need = |value: Option<Positive>, key: &str, shape: &str| {
            value.map(|x| x.0).ok_or_else(|| err(format!("a {shape} needs `{key}`")))
        };
        let refuse = |set: bool, key: &str, shape: &str| {
            if set {
                Err(err(format!("`{key}` does not apply to a {shape}")))
            } else {
                Ok(())
            }
        };
        let pi = std::f64::consts::PI;
        let (shape, volume) = match b.shape {
            ShapeName::Box => {
                refuse(b.radius.is_some(), "radius", "box")?;
                refuse(b.length.is_some(), "length", "box")?;
                let [x, y, z] = b.size.ok_or_else(|| err("a box needs `size = [x, y, z]`".to_string()))?;
                let size = Vec3::new(x.0, y.0, z.0);
                (Shape::Box { size }, size.x * size.y * size.z)
            }
            ShapeName::Sphere => {
                refuse(b.size.is_some(), "size", "sphere")?;
                refuse(b.length.is_some(), "length", "sphere")?;
                let r = need(b.radius, "radius", "sphere")?;
                (Shape::Sphere { radius: r }, 4.0 / 3.0 * pi * r.powi(3))
            }
            ShapeName::Capsule | ShapeName::Cylinder => {
                let what = if b.shape == ShapeName::Capsule { "capsule" } else { "cylinder" };
                refuse(b.size.is_some(), "size", what)?;
                let r = need(b.radius, "radius", what)?;
                let l = need(b.length, "length", what)?;
                if b.shape == ShapeName::Capsule {
                    (Shape::Capsule { radius: r, length: l }, pi * r * r * l + 4.0 / 3.0 * pi * r.powi(3))
                } else {
                    (Shape::Cylinder { radius: r, length: l }, pi * r * r * l)
                }
            }
        };
        let max = crate::model::ranges::MAX_LENGTH;
        if crate::model::ranges::shape_extent(&shape).is_some_and(|e| e > max) {
            return Err(err(format!("the shape's sizes must be at most {max:e} m")));
        }
        let mass = match (b.mass, b.density) {
            (Some(_), Some(_)) => return Err(err("give `mass` or `density`, not both".to_string())),
            (Some(m), None) => m.0,
            (None, d) => d.map_or(1000.0, |d| d.0) * volume,
        };
        let inertia = match &shape {
            Shape::Box { size } => RigidInertia::solid_box(mass, *size),
            Shape::Sphere { radius } => RigidInertia::solid_sphere(mass, *radius),
            Shape::Capsule { radius, length } => RigidInertia::solid_capsule(mass, *radius, *length),
            Shape::Cylinder { radius, length } => RigidInertia::solid_cylinder(mass, *radius, *length),
            _ => unreachable!("primitive shapes only"),
        };
        if b.fixed && (b.velocity.is_some() || b.angular_velocity.is_some()) {
            return Err(err("a fixed body has no `velocity` or `angular_velocity`".to_string()));
        }

        // Copies.
        let copies = Copies::new(b.count, b.spacing, b.jitter).map_err(err)?;
        if !b.fixed {
            self.claim_bodies(copies.len(), span.clone())?;
        }
        let mut rng = rand::rngs::StdRng::seed_from_u64(b.seed.unwrap_or(0));
        let base = b.name.clone().unwrap_or_else(|| format!("body{index}"));

        let model = if b.fixed {
            None
        } else {
            let spec = BodySpec::new(base.clone(), "universe", Joint::Free, Transform::identity(), inertia)
                .with_joint_name("free")
                .with_collision(shape.clone(), Transform::identity());
            let mut builder = ModelBuilder::new();
            builder.name(base.clone()).add_body(spec);
            Some(builder.build().map_err(|source| SceneError::Model {
                at: self.src.location(span.clone()),
                source: Box::new(source),
            })?)
        };
        for cell in copies.cells() {
            let name = copies.name(&base, cell);
            self.claim_name(&name, span.clone())?;
            let offset = copies.offset(cell);
            let mut noise = Vec3::zeros();
            if copies.jitter > 0.0 {
                let jitter = copies.jitter;
                noise = Vec3::from_fn(|_, _| rng.random_range(-jitter..=jitter));
            }
            let mut x = orientation;
            x.translation += offset + noise;
            match &model {
                None => {
                    world.add_static(&name, &shape, x, material).map_err(self.world_error(span.clone()))?;
                }
                Some(model) => {
                    let mut model = model.clone();
                    model.name = name.clone();
                    let index = world
                        .add_multibody(&name, model, &MeshOptions::default())
                        .map_err(self.world_error(span.clone()))?;
                    for c in world.collision().colliders_of(index).to_vec() {
                        world.collision_mut().set_material(c, material);
                    }
                    let mb = world.multibody_mut(index);
                    let (mut q, mut v) = (mb.state.q.clone(), mb.state.v.clone());
                    set_free_joint(mb.model(), 1, &x, b.velocity, b.angular_velocity, &mut q, &mut v);
                    mb.state.q = q;
                    mb.state.v = v;
                }
            }
            self.built_one();
        }
        Ok(())
    }
}

/// Sets the free joint `j` (a child of the universe) so that its body is at world pose `x`, moving
/// with world-axes `velocity` (of the body origin) and `angular_velocity`.
fn set_free_joint(
    model: &Model,
    j: usize,
    x: &Transform,
    velocity: Option<V3>,
    angular_velocity: Option<V3>,
    q: &mut nalgebra::DVector<f64>,
    v: &mut nalgebra::DVector<f64>,
) {
    let local = model.placement(j).inverse() * *x;
    let (iq, iv) = (model.idx_q(j), model.idx_v(j));
    q.rows_mut(iq, 3).copy_from(&local.translation);
    q.rows_mut(iq + 3, 4).copy_from_slice(&local.quaternion_xyzw());
    let rt = x.rotation.transpose();
    v.rows_mut(iv, 3).copy_from(&(rt * velocity.map_or(Vec3::zeros(), |w| w.0)));
    v.rows_mut(iv + 3, 3).copy_from(&(rt * angular_velocity.map_or(Vec3::zeros(), |w| w.0)));
}

/// Moves a fixed-base model so that its root link (fused into the universe) sits at world pose `x`:
/// the joints attached to the universe, the universe's geometry and its frames are moved.
fn place_fixed_base(model: &mut Model, x: &Transform) {
    for i in 1..model.nbodies() {
        if model.parents[i] == 0 {
            model.placements[i] = x * &model.placements[i];
        }
    }
    for g in model.geometries.iter_mut().filter(|g| g.body == 0) {
        g.placement = x * &g.placement;
    }
    for f in model.frames.iter_mut().skip(1).filter(|f| f.body == 0) {
        f.placement = x * &f.placement;
    }
}
