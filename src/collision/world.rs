//! [`CollisionWorld`]: the colliders of several multibodies and of the static world, the
//! filtering rules, and the per-step detection (broad phase → narrow phase → reduced sets)
//! writing [`Contact`]s into a buffer that lives across steps.

use super::broad_phase::SweepAndPrune;
use super::convert::{from_pose, from_vector, to_pose, to_vector};
use super::mesh::{MeshOptions, MissingMeshPolicy};
use super::narrow_phase::{dispatch, pose_within, refresh_distances, PairCache};
use super::reduce::{merge_to_patch, reduce, Candidate, MAX_POINTS_PER_PAIR};
use super::shape::{self, ShapeKind, ShapeSource};
use crate::data::Data;
use crate::error::CollisionError;
use crate::math::{Transform, Vec3};
use crate::model::{GeometryRole, Model, Shape};
use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::math::Pose;
use parry3d_f64::shape::SharedShape;

mod sweep;
pub use sweep::{SweepDiagnostic, SweepStats, SweptMotion};

/// What a collider moves with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Attachment {
    /// Static world geometry (ground, terrain, walls): never moves.
    World,
    /// Body `body` of multibody `multibody` (body 0 is that multibody's universe: fixed, static).
    Body {
        /// Index of the multibody in the collision world (the order of [`CollisionWorld::add_model`]).
        multibody: usize,
        /// Body index in that multibody's [`Model`].
        body: usize,
    },
}

impl Attachment {
    /// Whether the collider can never move.
    pub fn is_static(&self) -> bool {
        matches!(self, Attachment::World | Attachment::Body { body: 0, .. })
    }
}

/// Collision groups and masks: two colliders may touch only if each one's group bits meet the
/// other's mask bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CollisionFilter {
    /// Groups this collider belongs to (bit set).
    pub group: u32,
    /// Groups this collider collides with (bit set).
    pub mask: u32,
}

impl Default for CollisionFilter {
    fn default() -> Self {
        Self { group: 1, mask: u32::MAX }
    }
}

impl CollisionFilter {
    /// Whether two filters allow contact.
    pub fn accepts(&self, other: &CollisionFilter) -> bool {
        self.group & other.mask != 0 && other.group & self.mask != 0
    }
}

/// A collision shape attached to a body or to the world.
#[derive(Clone)]
pub struct Collider {
    name: String,
    attachment: Attachment,
    kind: ShapeKind,
    placement: Transform,
    /// Groups and mask.
    pub filter: CollisionFilter,
    /// Material index (contact parameters are looked up per material pair by the world).
    pub material: u32,
    shape: SharedShape,
    /// Pose of parry's shape frame in the geometry frame (parry is y-up for some shapes).
    offset: Option<Transform>,
    /// Pose of parry's shape frame in the body frame, as parry's pose and as a transform.
    local_pose: Pose,
    local: Transform,
    world_pose: Pose,
    aabb: Aabb,
    /// Contacts of this collider stand for a patch: one point per pair (see
    /// [`CollisionWorld::set_patch_contact`]).
    patch: bool,
    /// Radius (m) of a ball about the shape frame's origin holding the shape (infinite for
    /// unbounded shapes): bounds the distance a point travels as the collider turns.
    radius: f64,
}

impl Collider {
    /// Name (the declaring link's, or the name given for static geometry).
    pub fn name(&self) -> &str {
        &self.name
    }
    /// What the collider moves with.
    pub fn attachment(&self) -> Attachment {
        self.attachment
    }
    /// Shape kind.
    pub fn kind(&self) -> ShapeKind {
        self.kind
    }
    /// Pose of the geometry frame in the body frame (in the world frame for static geometry).
    pub fn placement(&self) -> &Transform {
        &self.placement
    }
    /// Pose of the geometry frame in the world, as of the last update.
    pub fn world_pose(&self) -> Transform {
        let parry_frame = from_pose(&self.world_pose);
        self.offset.map_or(parry_frame, |o| parry_frame * o.inverse())
    }
    /// parry's shape and its world pose (parry's frame), for drawing ([`crate::render`]).
    #[cfg(feature = "render")]
    pub(crate) fn parry_shape(&self) -> (&SharedShape, &Pose) {
        (&self.shape, &self.world_pose)
    }
    /// parry's shape and the pose of parry's shape frame in the body frame (in the world frame for
    /// static geometry), for drawing ([`crate::viz`]).
    #[cfg(feature = "viewer")]
    pub(crate) fn parry_local(&self) -> (&SharedShape, &Transform) {
        (&self.shape, &self.local)
    }
    /// World axis-aligned bounding box (m), as of the last update, margin not included.
    pub fn aabb(&self) -> ([f64; 3], [f64; 3]) {
        (self.aabb.mins.to_array(), self.aabb.maxs.to_array())
    }
    /// Whether its contacts are one point per pair and normal ([`CollisionWorld::set_patch_contact`]).
    pub fn is_patch_contact(&self) -> bool {
        self.patch
    }
    /// The shape's frame in the body frame (world for static geometry) and the radius (m) of a
    /// ball about that frame's origin holding the shape (infinite for unbounded shapes): a
    /// motion of the body moves no point of the collider further than the frame's origin moves
    /// plus the turn (rad) times this radius.
    pub(crate) fn bounding_ball(&self) -> (&Transform, f64) {
        (&self.local, self.radius)
    }
}

/// One contact point between colliders A and B, in the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// Index of collider A.
    pub collider_a: usize,
    /// Index of collider B (static geometry is always B when one side is static).
    pub collider_b: usize,
    /// What A moves with.
    pub body_a: Attachment,
    /// What B moves with.
    pub body_b: Attachment,
    /// The point of A's surface nearest to B (world, m).
    pub point_a: Vec3,
    /// The point of B's surface nearest to A (world, m).
    pub point_b: Vec3,
    /// Unit contact normal in world axes, pointing from B to A: A moving along it separates.
    pub normal: Vec3,
    /// Signed distance along the normal (m): negative = penetration depth, positive = gap
    /// (reported up to the contact margin).
    pub distance: f64,
    /// Identifies the contact across steps (same features of the same pair), for warm starts.
    pub feature: u64,
}

/// Options of the collision pipeline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CollisionOptions {
    /// Contact margin (m): pairs closer than this are reported before they touch.
    pub margin: f64,
    /// Also test bodies joined directly by a joint (normally skipped: they overlap at the joint).
    pub collide_joined_bodies: bool,
    /// Reuse of a pair's contact points while the pair has hardly moved (None: every pair's
    /// manifolds are computed every step).
    pub reuse: Option<ManifoldReuse>,
}

/// How far a pair may move, relative to its pose when its manifolds were computed, before they
/// are computed again (PhysX's contact cache, Bullet's persistent manifolds); until then each
/// point stays where it is on A, its distance is recomputed from B's pose
/// (`narrow_phase::refresh_distances`) and the normal turns with A. A resting pair moves by
/// nanometres or less per step, so its manifolds are computed once and refreshed for hundreds
/// of steps; the error is of second order in the motion (δ²/2r for a sphere of radius r moved
/// sideways by δ: 5e-14 m for δ = 1e-8 m, r = 1 mm) plus the normal's tilt, at most `rotation`.
/// The default bounds are tight because a refresh is a small jump: with 1e-5 m and 1e-4 rad
/// the resting ragdoll's impulses had to move by more than the solver's tolerance at each one
/// (4.2 instead of 1.0 sweeps per resting step).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ManifoldReuse {
    /// Largest change of B's position in A's frame (m).
    pub translation: f64,
    /// Largest rotation of B relative to A (rad).
    pub rotation: f64,
}

impl Default for ManifoldReuse {
    fn default() -> Self {
        Self { translation: 1e-8, rotation: 1e-7 }
    }
}

impl Default for CollisionOptions {
    fn default() -> Self {
        Self { margin: 0.005, collide_joined_bodies: false, reuse: Some(ManifoldReuse::default()) }
    }
}

/// Counters of the last [`CollisionWorld::detect`] call.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CollisionStats {
    /// Pairs whose boxes overlapped and passed the filters.
    pub broad_pairs: usize,
    /// Pairs with at least one contact.
    pub touching_pairs: usize,
    /// Pairs whose manifolds were refreshed instead of computed ([`CollisionOptions::reuse`]).
    pub refreshed_pairs: usize,
    /// Contact points before reduction.
    pub raw_points: usize,
    /// Contact points after reduction.
    pub contacts: usize,
}

#[derive(Clone, Debug)]
struct MultibodyEntry {
    parents: Vec<usize>,
    /// Per body, the child of the root its branch hangs from (0 for the root): bodies of two
    /// such trees (several free bodies in one model, as an MJCF file's bodies) always collide.
    trees: Vec<usize>,
    self_collision: bool,
    asleep: bool,
    colliders: Vec<usize>,
}

/// The collision scene: colliders, filters, broad-phase and pair state, and the contact buffer.
#[derive(Default)]
pub struct CollisionWorld {
    options: CollisionOptions,
    colliders: Vec<Collider>,
    multibodies: Vec<MultibodyEntry>,
    broad: SweepAndPrune,
    cache: PairCache,
    aabbs: Vec<Aabb>,
    pair_buffer: Vec<(u32, u32)>,
    candidates: Vec<Candidate>,
    contacts: Vec<Contact>,
    warnings: Vec<String>,
    step: u64,
    stats: CollisionStats,
    /// Per collider, its motion over the next step if it is swept ([`CollisionWorld::set_motion`]).
    motions: Vec<Option<SweptMotion>>,
    /// Per collider, how far (m) its points may travel in the next step, up to its radius: its
    /// pairs' margin grows by it ([`CollisionWorld::set_multibody_motions`]).
    reach: Vec<f64>,
    /// Per collider, its motion over the next step as last set, swept or not
    /// ([`CollisionWorld::set_multibody_motions`]): the manifold reduction counts a point that
    /// this motion closes within the step as touching.
    drift: Vec<Option<SweptMotion>>,
    sweep_diagnostics: Vec<SweepDiagnostic>,
    sweep_stats: SweepStats,
}

impl CollisionWorld {
    /// An empty collision world.
    pub fn new(options: CollisionOptions) -> Self {
        Self { options, ..Self::default() }
    }

    /// The options.
    pub fn options(&self) -> &CollisionOptions {
        &self.options
    }

    /// Adds the collision geometry of `model` (its [`GeometryRole::Collision`] entries) as a new
    /// multibody and returns its index. Meshes are read now; relative URIs resolve against
    /// [`Model::source_dir`]. Self-collision starts off.
    pub fn add_model(&mut self, model: &Model, meshes: &MeshOptions) -> Result<usize, CollisionError> {
        let multibody = self.multibodies.len();
        let mut new = Vec::new();
        for g in model.geometries().iter().filter(|g| g.role == GeometryRole::Collision) {
            let src = ShapeSource { link: &g.link, model_dir: model.source_dir(), on_body: g.body != 0 };
            let built = match shape::build(&g.shape, &src, meshes) {
                Ok(s) => s,
                Err(e @ (CollisionError::MeshNotFound { .. } | CollisionError::MeshUnreadable { .. }))
                    if meshes.missing == MissingMeshPolicy::Skip =>
                {
                    self.warnings.push(format!("skipped: {e}"));
                    continue;
                }
                Err(e) => return Err(e),
            };
            let attachment = Attachment::Body { multibody, body: g.body };
            new.push(make_collider(g.link.clone(), attachment, g.placement, built));
        }
        let first = self.colliders.len();
        self.colliders.extend(new);
        let parents: Vec<usize> = (0..model.nbodies()).map(|i| model.parent(i)).collect();
        let mut trees = vec![0; parents.len()];
        for i in 1..parents.len() {
            // Parents come before their children.
            trees[i] = if parents[i] == 0 { i } else { trees[parents[i]] };
        }
        self.multibodies.push(MultibodyEntry {
            parents,
            trees,
            self_collision: false,
            asleep: false,
            colliders: (first..self.colliders.len()).collect(),
        });
        self.broad.invalidate();
        Ok(multibody)
    }

    /// Adds a collider to body `body` of multibody `multibody`, at pose `placement` in the body
    /// frame, and returns its index.
    pub fn add_body_collider(
        &mut self,
        multibody: usize,
        body: usize,
        name: &str,
        geometry: &Shape,
        placement: Transform,
        meshes: &MeshOptions,
    ) -> Result<usize, CollisionError> {
        let count = self.multibodies.len();
        let entry = self.multibodies.get(multibody).ok_or(CollisionError::IndexOutOfRange {
            what: "multibodies",
            index: multibody,
            count,
        })?;
        if body >= entry.parents.len() {
            return Err(CollisionError::IndexOutOfRange {
                what: "bodies",
                index: body,
                count: entry.parents.len(),
            });
        }
        let built =
            shape::build(geometry, &ShapeSource { link: name, model_dir: None, on_body: body != 0 }, meshes)?;
        let index = self.colliders.len();
        self.colliders.push(make_collider(
            name.to_string(),
            Attachment::Body { multibody, body },
            placement,
            built,
        ));
        self.multibodies[multibody].colliders.push(index);
        self.broad.invalidate();
        Ok(index)
    }

    /// Adds static world geometry at pose `pose` (world frame) and returns its index.
    pub fn add_static(
        &mut self,
        name: &str,
        geometry: &Shape,
        pose: Transform,
        meshes: &MeshOptions,
    ) -> Result<usize, CollisionError> {
        let built =
            shape::build(geometry, &ShapeSource { link: name, model_dir: None, on_body: false }, meshes)?;
        let mut collider = make_collider(name.to_string(), Attachment::World, pose, built);
        collider.world_pose = collider.local_pose;
        collider.aabb = static_aabb(&collider);
        self.colliders.push(collider);
        self.broad.invalidate();
        Ok(self.colliders.len() - 1)
    }

    /// Turns collisions between bodies of one tree of the same multibody on or off (joined bodies
    /// stay excluded unless [`CollisionOptions::collide_joined_bodies`]); bodies of two trees on
    /// its root (several free bodies in one model) collide either way.
    pub fn set_self_collision(&mut self, multibody: usize, on: bool) -> Result<(), CollisionError> {
        let count = self.multibodies.len();
        let entry = self.multibodies.get_mut(multibody).ok_or(CollisionError::IndexOutOfRange {
            what: "multibodies",
            index: multibody,
            count,
        })?;
        entry.self_collision = on;
        Ok(())
    }

    /// Marks a multibody asleep (it does not move: pairs between sleeping or static colliders are
    /// not tested) or awake.
    pub fn set_asleep(&mut self, multibody: usize, asleep: bool) {
        if let Some(entry) = self.multibodies.get_mut(multibody) {
            entry.asleep = asleep;
        }
    }

    /// Sets the material index of a collider (out-of-range indices are ignored).
    pub fn set_material(&mut self, collider: usize, material: u32) {
        if let Some(c) = self.colliders.get_mut(collider) {
            c.material = material;
        }
    }

    /// Makes every contact of a collider one point per pair and contact normal, at the centre of
    /// the reduced points sharing that normal, with the deepest of their depths (a height field's
    /// triangles under a wheel keep a point each): a tyre's contact patch. A thin wheel (a cylinder on its rim) otherwise touches
    /// flat ground at both rim edges, and when it scrubs in a turn those two rows, coupled
    /// through the light wheel dofs, make the contact problem nearly singular (PGS then needs
    /// ~1000 sweeps). Not for shapes that must not tip about the point (a box on a face).
    pub fn set_patch_contact(&mut self, collider: usize, on: bool) -> Result<(), CollisionError> {
        self.collider_mut(collider)?.patch = on;
        Ok(())
    }

    fn collider_mut(&mut self, collider: usize) -> Result<&mut Collider, CollisionError> {
        let count = self.colliders.len();
        self.colliders.get_mut(collider).ok_or(CollisionError::IndexOutOfRange {
            what: "colliders",
            index: collider,
            count,
        })
    }

    /// Sets the groups and mask of a collider.
    pub fn set_filter(&mut self, collider: usize, filter: CollisionFilter) -> Result<(), CollisionError> {
        self.collider_mut(collider)?.filter = filter;
        Ok(())
    }

    /// The colliders, indexed as in [`Contact::collider_a`].
    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    /// Colliders of multibody `multibody`.
    pub fn colliders_of(&self, multibody: usize) -> &[usize] {
        self.multibodies.get(multibody).map_or(&[], |m| &m.colliders)
    }

    /// Messages about geometry that was left out (meshes skipped by [`MissingMeshPolicy::Skip`]).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Moves the colliders of `multibody` to the body poses `data.x_wb` of the last forward
    /// kinematics.
    pub fn update_multibody(&mut self, multibody: usize, data: &Data) -> Result<(), CollisionError> {
        let count = self.multibodies.len();
        let entry = self.multibodies.get(multibody).ok_or(CollisionError::IndexOutOfRange {
            what: "multibodies",
            index: multibody,
            count,
        })?;
        if data.x_wb.len() != entry.parents.len() {
            return Err(CollisionError::DataMismatch {
                multibody,
                expected: entry.parents.len(),
                got: data.x_wb.len(),
            });
        }
        for &c in &entry.colliders {
            let collider = &mut self.colliders[c];
            let Attachment::Body { body, .. } = collider.attachment else { continue };
            let x_wb = &data.x_wb[body];
            if !x_wb.is_finite() {
                return Err(CollisionError::NonFinitePose { collider: collider.name.clone() });
            }
            // One matrix product and one conversion to parry's quaternion, and the box of the
            // common shapes from the rotation matrix: parry composes quaternions and turns the
            // result back into a matrix or rotates points by it for each box.
            let x_wc = x_wb * &collider.local;
            collider.world_pose = to_pose(&x_wc);
            collider.aabb = primitive_aabb(&*collider.shape.0, &x_wc)
                .unwrap_or_else(|| collider.shape.compute_aabb(&collider.world_pose));
        }
        Ok(())
    }

    /// Statistics of the last detection.
    pub fn stats(&self) -> CollisionStats {
        self.stats
    }

    /// The contacts found by the last [`CollisionWorld::detect`].
    pub fn contacts(&self) -> &[Contact] {
        &self.contacts
    }

    /// Finds every contact within the margin: broad phase over the boxes of the current poses,
    /// filtering, narrow phase per pair, reduction to at most four points per pair. Buffers are
    /// reused, so in steady state (the same pairs near each other) nothing is allocated.
    pub fn detect(&mut self) -> &[Contact] {
        self.step += 1;
        self.contacts.clear();
        self.stats = CollisionStats::default();
        self.sweep_stats = SweepStats::default();
        self.sweep_diagnostics.clear();
        let margin = self.options.margin;
        self.aabbs.clear();
        for c in 0..self.colliders.len() {
            let aabb = self.swept_aabb(c, self.colliders[c].aabb.loosened(margin + self.reach_of(c)));
            self.sweep_stats.swept_colliders += usize::from(self.is_swept(c));
            self.aabbs.push(aabb);
        }
        self.pair_buffer.clear();
        let (colliders, multibodies, options) = (&self.colliders, &self.multibodies, &self.options);
        let pairs = &mut self.pair_buffer;
        self.broad.pairs(
            &self.aabbs,
            |i, j| may_collide(&colliders[i], &colliders[j], multibodies, options),
            |i, j| {
                // Static geometry is B; otherwise the lower index is A.
                let swap =
                    colliders[i].attachment.is_static() || (!colliders[j].attachment.is_static() && j < i);
                pairs.push(if swap { (j as u32, i as u32) } else { (i as u32, j as u32) });
            },
        );
        self.stats.broad_pairs = self.pair_buffer.len();
        for k in 0..self.pair_buffer.len() {
            let (a, b) = self.pair_buffer[k];
            self.narrow(a as usize, b as usize);
        }
        self.cache.forget_older_than(self.step);
        self.stats.contacts = self.contacts.len();
        &self.contacts
    }

    fn narrow(&mut self, a: usize, b: usize) {
        // The margin of this pair: the contact margin grown by how far the two may travel
        // towards each other in the step, so that a fast pair gets its whole manifold as
        // speculative points before it meets.
        let margin = self.options.margin + self.reach_of(a) + self.reach_of(b);
        let (ca, cb) = (&self.colliders[a], &self.colliders[b]);
        let state = self.cache.pairs.entry((a as u32, b as u32)).or_default();
        state.last_step = self.step;
        let pos_ab = ca.world_pose.inv_mul(&cb.world_pose);
        let reuse = margin <= state.computed_margin
            && self
                .options
                .reuse
                .as_ref()
                .zip(state.computed_at.as_ref())
                .is_some_and(|(r, at)| pose_within(at, &pos_ab, r.translation, r.rotation));
        if reuse {
            refresh_distances(&mut state.manifolds, &pos_ab);
            self.stats.refreshed_pairs += 1;
        } else {
            let result = dispatch(ca.kind, &*ca.shape.0, cb.kind, &*cb.shape.0, &pos_ab, margin, state);
            if result.is_err() {
                // Unsupported pairs are excluded when colliders are created; nothing to report.
                state.computed_at = None;
                return;
            }
            state.computed_at = Some(pos_ab);
            state.computed_margin = margin;
        }
        self.candidates.clear();
        for m in &state.manifolds {
            let (pose_a, pose_b) = (
                m.subshape_pos1().map_or(ca.world_pose, |p| ca.world_pose * *p),
                m.subshape_pos2().map_or(cb.world_pose, |p| cb.world_pose * *p),
            );
            let normal = -from_vector(pose_a.rotation * m.local_n1);
            // Parry's polygon clipping keeps every clipped point of the incident face, however far;
            // only points within the margin are contacts.
            for p in m.points.iter().filter(|p| p.dist <= margin) {
                let sub = (u64::from(m.subshape1) << 20) ^ u64::from(m.subshape2);
                self.candidates.push(Candidate {
                    point_a: from_vector(pose_a * p.local_p1),
                    point_b: from_vector(pose_b * p.local_p2),
                    normal,
                    distance: p.dist,
                    predicted: p.dist,
                    feature: (u64::from(p.fid1.0) | (u64::from(p.fid2.0) << 32))
                        ^ sub.wrapping_mul(0x9E37_79B9_7F4A_7C15),
                });
            }
        }
        if self.candidates.is_empty() {
            if self.is_swept(a) || self.is_swept(b) {
                self.sweep_pair(a, b);
            }
            return;
        }
        self.stats.touching_pairs += 1;
        self.stats.raw_points += self.candidates.len();
        if self.candidates.len() > MAX_POINTS_PER_PAIR {
            let (drift_a, drift_b) = (self.drift_of(a), self.drift_of(b));
            if let Some(h) = drift_a.or(drift_b).map(|m| m.h) {
                let (origin_a, origin_b) =
                    (from_vector(ca.world_pose.translation), from_vector(cb.world_pose.translation));
                for c in &mut self.candidates {
                    let rate_a =
                        drift_a.map_or(0.0, |m| m.point_velocity(&origin_a, &c.point_a).dot(&c.normal));
                    let rate_b =
                        drift_b.map_or(0.0, |m| m.point_velocity(&origin_b, &c.point_b).dot(&c.normal));
                    c.predicted = c.distance + h * (rate_a - rate_b);
                }
            }
        }
        let mut kept = reduce(&mut self.candidates, self.options.margin);
        if ca.patch || cb.patch {
            kept = merge_to_patch(&mut self.candidates, kept);
        }
        for c in &self.candidates[..kept] {
            self.contacts.push(Contact {
                collider_a: a,
                collider_b: b,
                body_a: ca.attachment,
                body_b: cb.attachment,
                point_a: c.point_a,
                point_b: c.point_b,
                normal: c.normal,
                distance: c.distance,
                feature: c.feature,
            });
        }
    }
}

/// The bounding box of a ball, capsule or cuboid at `pose` (parry's shape frame in the world),
/// computed from the rotation matrix: ball centre ± r; a capsule's two end points' box grown by
/// its radius; a cuboid's centre ± |R| h. `None` for other shapes (parry's own then).
fn primitive_aabb(shape: &dyn parry3d_f64::shape::Shape, pose: &Transform) -> Option<Aabb> {
    let (r, t) = (&pose.rotation, &pose.translation);
    let boxed = |lo: Vec3, hi: Vec3| Aabb::new(to_vector(&lo), to_vector(&hi));
    if let Some(ball) = shape.as_ball() {
        let grow = Vec3::repeat(ball.radius);
        return Some(boxed(t - grow, t + grow));
    }
    if let Some(capsule) = shape.as_capsule() {
        let a = r * from_vector(capsule.segment.a) + t;
        let b = r * from_vector(capsule.segment.b) + t;
        let grow = Vec3::repeat(capsule.radius);
        return Some(boxed(a.inf(&b) - grow, a.sup(&b) + grow));
    }
    if let Some(cuboid) = shape.as_cuboid() {
        let half = r.abs() * from_vector(cuboid.half_extents);
        return Some(boxed(t - half, t + half));
    }
    None
}

/// The box of static geometry; a half-space whose normal is along a world axis is bounded on
/// that side (parry bounds no side of any half-space), so bodies far above the ground skip it.
fn static_aabb(collider: &Collider) -> Aabb {
    let mut aabb = collider.shape.compute_aabb(&collider.world_pose);
    if let Some(half_space) = collider.shape.as_halfspace() {
        let n = from_vector(collider.world_pose.rotation * half_space.normal);
        let origin = from_vector(collider.world_pose.translation);
        for axis in 0..3 {
            if (n[axis].abs() - 1.0).abs() < 1e-12 {
                if n[axis] > 0.0 {
                    aabb.maxs[axis] = origin[axis];
                } else {
                    aabb.mins[axis] = origin[axis];
                }
            }
        }
    }
    aabb
}

fn make_collider(
    name: String,
    attachment: Attachment,
    placement: Transform,
    built: shape::ParryShape,
) -> Collider {
    let local = built.offset.map_or(placement, |offset| placement * offset);
    let local_pose = to_pose(&local);
    let aabb = built.shape.compute_aabb(&local_pose);
    let sphere = built.shape.compute_local_bounding_sphere();
    let radius = from_vector(sphere.center).norm() + sphere.radius;
    Collider {
        name,
        attachment,
        kind: built.kind,
        placement,
        filter: CollisionFilter::default(),
        material: 0,
        shape: built.shape,
        offset: built.offset,
        local_pose,
        local,
        world_pose: local_pose,
        aabb,
        patch: false,
        radius,
    }
}

/// The filtering rules: never static or sleeping against static or sleeping; never two colliders of one body; within
/// one tree of a multibody only with self-collision on (two trees on its root always), and bodies
/// joined by a joint only if asked; groups and masks always.
fn may_collide(
    a: &Collider,
    b: &Collider,
    multibodies: &[MultibodyEntry],
    options: &CollisionOptions,
) -> bool {
    let still = |c: &Collider| match c.attachment {
        Attachment::World => true,
        Attachment::Body { multibody, body } => body == 0 || multibodies[multibody].asleep,
    };
    if still(a) && still(b) {
        return false;
    }
    if !a.filter.accepts(&b.filter) {
        return false;
    }
    if let (Attachment::Body { multibody: ma, body: ba }, Attachment::Body { multibody: mb, body: bb }) =
        (a.attachment, b.attachment)
    {
        if ma == mb {
            let entry = &multibodies[ma];
            if ba == bb || (!entry.self_collision && entry.trees[ba] == entry.trees[bb]) {
                return false;
            }
            let joined = entry.parents[ba] == bb || entry.parents[bb] == ba;
            if joined && !options.collide_joined_bodies {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use parry3d_f64::shape::{Ball, Capsule, Cuboid, Cylinder};

    /// The boxes from the rotation matrix are parry's, to rounding, for balls, capsules and
    /// cuboids at turned and shifted poses; other shapes are left to parry.
    #[test]
    fn primitive_boxes_are_parrys_boxes() {
        let shapes: [(&str, Box<dyn parry3d_f64::shape::Shape>); 3] = [
            ("ball", Box::new(Ball::new(0.07))),
            (
                "capsule",
                Box::new(Capsule::new(
                    to_vector(&Vec3::new(0.0, -0.2, 0.0)),
                    to_vector(&Vec3::new(0.01, 0.15, 0.02)),
                    0.05,
                )),
            ),
            ("cuboid", Box::new(Cuboid::new(to_vector(&Vec3::new(0.1, 0.2, 0.05))))),
        ];
        for k in 0..50 {
            let angle = 0.37 * k as f64;
            let pose = Transform::from_xyz_rpy(
                [0.3 * angle.sin(), -1.0 + 0.1 * k as f64, 0.5],
                [angle, 0.5 * angle, -angle],
            );
            for (name, shape) in &shapes {
                let ours = primitive_aabb(shape.as_ref(), &pose).expect(name);
                let theirs = shape.compute_aabb(&to_pose(&pose));
                let gap = (ours.mins - theirs.mins)
                    .abs()
                    .max_element()
                    .max((ours.maxs - theirs.maxs).abs().max_element());
                assert!(gap < 1e-12, "{name} at pose {k}: boxes differ by {gap:e}");
            }
        }
        let cylinder = Cylinder::new(0.1, 0.2);
        assert!(primitive_aabb(&cylinder, &Transform::identity()).is_none());
    }
}
