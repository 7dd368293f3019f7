//! The contacts' position correction after each step (`WorldOptions::contact_projection`,
//! docs/collision.md "Contact projection"): a penetration is pushed out to the slop by a change
//! of q alone, the velocity the step solved for stands, and the ragdoll pile at a game's rate
//! stays within 5 mm of penetration.

use gelenk::collision::MeshOptions;
use gelenk::io::scene::{self, RunOptions};
use gelenk::math::{Transform, Vec3};
use gelenk::model::{BodySpec, Joint, ModelBuilder, RigidInertia, Shape};
use gelenk::world::{ContactProjection, World, WorldOptions};

/// A world with a ground plane and a free 0.1 m, 0.5 kg box whose centre is `depth` m lower than
/// resting on the ground would put it, at rest.
fn sunk_box(depth: f64, projection: bool) -> World {
    let mut options = WorldOptions::default();
    options.contact_projection.enabled = projection;
    let mut w = World::new(options);
    w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    let side = Vec3::repeat(0.1);
    let mut b = ModelBuilder::new();
    b.add_body(
        BodySpec::new(
            "box",
            "universe",
            Joint::Free,
            Transform::identity(),
            RigidInertia::solid_box(0.5, side),
        )
        .with_collision(Shape::Box { size: side }, Transform::identity()),
    );
    let i = w.add_multibody("box", b.build().unwrap(), &MeshOptions::default()).unwrap();
    w.multibody_mut(i).state.q[2] = 0.05 - depth;
    w
}

/// A box 2 cm into the ground: one step lifts it to the slop (0.5 mm deep) with the projection,
/// and with the same velocity as without it (the contact's Baumgarte feedback alone, which lifts
/// it by `h · erp · depth / h` = 4 mm per step).
#[test]
fn a_sunk_box_is_lifted_to_the_slop_without_a_change_of_velocity() {
    let (mut on, mut off) = (sunk_box(0.02, true), sunk_box(0.02, false));
    let stats = on.step().unwrap().clone();
    off.step().unwrap();
    let slop = ContactProjection::default().slop;
    let (z_on, z_off) = (on.multibody(0).state.q[2], off.multibody(0).state.q[2]);
    assert!(stats.projection.contacts >= 4 && stats.projection.depth > 0.01, "{:?}", stats.projection);
    assert!((z_on - (0.05 - slop)).abs() < 2e-5, "with the projection the box is at z = {z_on}");
    assert!(z_off < 0.04, "without it, z = {z_off}");
    // The same velocity in world axes (the body's axes are turned by the correction's own small
    // turn, and its velocity with them).
    let world_velocity = |w: &World| {
        let (q, v) = (&w.multibody(0).state.q, &w.multibody(0).state.v);
        let turn =
            nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[6], q[3], q[4], q[5]));
        (turn * Vec3::new(v[0], v[1], v[2]), turn * Vec3::new(v[3], v[4], v[5]))
    };
    let ((v_on, w_on), (v_off, w_off)) = (world_velocity(&on), world_velocity(&off));
    assert!((v_on - v_off).norm() < 1e-12 && (w_on - w_off).norm() < 1e-12, "{v_on} {v_off} {w_on} {w_off}");
    // The next step finds the box at the slop and leaves it there.
    let next = on.step().unwrap().clone();
    assert!(next.max_penetration < slop + 2e-5, "{}", next.max_penetration);
}

/// A box resting on the ground is never projected: its contacts stay at their depth, within
/// the slop, and the step does nothing more than predict them.
#[test]
fn a_resting_box_is_left_alone() {
    let mut w = sunk_box(0.0, true);
    for _ in 0..500 {
        w.step().unwrap();
    }
    for _ in 0..100 {
        let stats = w.step().unwrap();
        assert_eq!(stats.projection.islands, 0, "{:?}", stats.projection);
        assert!(!stats.projection.end_check, "a resting box moves less than the slop");
    }
}

/// Twenty ragdolls dropped into a pile at 60 Hz (`models/ragdoll_pile.toml`, its Newton chain
/// on softened rows), through the impacts of the first 2.5 s: every step's contacts within 5 mm
/// of penetration (without the projection the deepest is about 2.4 cm), the steps certified.
#[test]
fn the_ragdoll_pile_at_60_hz_penetrates_less_than_2_mm() {
    // 24 mm without the projection; a hand turning fast enough that one correction at the end
    // poses (linear in its turn) leaves it 3 mm deep is detected and corrected again.
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/models/ragdoll_pile.toml");
    let mut loaded = scene::load_file(path).unwrap();
    let options =
        RunOptions { dt: Some(1.0 / 60.0), duration: Some(2.5), record_every: Some(0), ..Default::default() };
    let summary = scene::run(&mut loaded, &options, |_| {}).unwrap();
    assert!(summary.max_penetration < 2e-3, "deepest penetration {} m", summary.max_penetration);
    assert_eq!(summary.steps_above_tolerance, 0);
    assert_eq!(summary.fallbacks, 0);
}
