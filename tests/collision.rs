//! Collision detection pins the geometry of contact: signed distances, unit world normals pointing from B to A (static geometry always B) and contact points equal to their closed forms — spheres, boxes and cylinders on (tilted) half-spaces and heightfields, boxes resting on a face or an edge, capsule–capsule and sphere–box closest points — plus mesh files (STL, OBJ) giving the contacts of the primitive they describe, invariance under a common rigid motion, the filtering rules, contact Jacobians equal to finite-difference relative velocities, URDF mesh handling and typed errors for bad input.

use gelenk::algorithms::{compute_joint_jacobians, forward_kinematics};
use gelenk::collision::{
    contact_frame, contact_jacobian, Attachment, CollisionFilter, CollisionOptions, CollisionWorld, Contact,
    MeshOptions, MissingMeshPolicy, ShapeKind,
};
use gelenk::io::urdf::{load_file, load_str, UrdfOptions};
use gelenk::math::{axis_angle, Mat3, Transform, Vec3};
use gelenk::model::{BodySpec, Joint, Model, ModelBuilder, RigidInertia, Shape};
use gelenk::{CollisionError, Data};
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};

/// The default contact margin (m), checked against `CollisionOptions::default()` below.
const MARGIN: f64 = 0.005;
/// Tolerance for quantities with a closed form (m, or unitless for normals).
const TOL: f64 = 1e-9;

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

fn v3(x: f64, y: f64, z: f64) -> Vec3 {
    Vec3::new(x, y, z)
}

fn rot(axis: Vec3, angle: f64) -> Mat3 {
    axis_angle(&axis.normalize(), angle)
}

fn deg(a: f64) -> f64 {
    a.to_radians()
}

/// A rotation taking z to the unit vector `dir` (dir must not be −z), then spun by `spin` about it.
fn z_to(dir: Vec3, spin: f64) -> Mat3 {
    let dir = dir.normalize();
    let base = nalgebra::Rotation3::rotation_between(&Vec3::z(), &dir).expect("dir is not -z").into_inner();
    base * rot(Vec3::z(), spin)
}

fn random_unit(rng: &mut StdRng) -> Vec3 {
    loop {
        let v = v3(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        if v.norm() > 0.2 && v.norm() < 1.0 {
            return v.normalize();
        }
    }
}

fn random_rotation(rng: &mut StdRng) -> Mat3 {
    let axis = random_unit(rng);
    rot(axis, rng.random_range(0.0..std::f64::consts::PI))
}

fn free_body(name: &str, shape: Shape) -> BodySpec {
    BodySpec::new(
        name,
        "universe",
        Joint::Free,
        Transform::identity(),
        RigidInertia::solid_box(1.0, v3(0.2, 0.2, 0.2)),
    )
    .with_collision(shape, Transform::identity())
}

/// Writes pose `x` into the free-joint coordinates of body `body` in `q`.
fn set_free_pose(model: &Model, q: &mut DVector<f64>, body: usize, x: &Transform) {
    assert_eq!(*model.joint(body), Joint::Free);
    let i = model.idx_q(body);
    for k in 0..3 {
        q[i + k] = x.translation[k];
    }
    let quat = x.quaternion_xyzw();
    for k in 0..4 {
        q[i + 3 + k] = quat[k];
    }
}

/// A collision world in which every moving shape is a one-body multibody on a free joint.
struct Scene {
    world: CollisionWorld,
    models: Vec<Model>,
}

impl Scene {
    fn new() -> Self {
        Self::with_options(CollisionOptions::default())
    }

    fn with_options(options: CollisionOptions) -> Self {
        Scene { world: CollisionWorld::new(options), models: Vec::new() }
    }

    /// Adds a free body carrying `shape` at pose `x`; returns its multibody index.
    fn body(&mut self, name: &str, shape: Shape, x: Transform) -> usize {
        self.placed_body(name, shape, Transform::identity(), x)
    }

    /// Adds a free body at pose `x` carrying `shape` at pose `placement` in the body frame.
    fn placed_body(&mut self, name: &str, shape: Shape, placement: Transform, x: Transform) -> usize {
        let mut spec = free_body(name, shape);
        spec.geometries[0].placement = placement;
        let model = ModelBuilder::new().add_body(spec).build().unwrap();
        let mb = self.world.add_model(&model, &MeshOptions::default()).unwrap();
        assert_eq!(mb, self.models.len());
        self.models.push(model);
        self.place(mb, x);
        mb
    }

    fn place(&mut self, mb: usize, x: Transform) {
        let model = &self.models[mb];
        let mut data = Data::new(model);
        let mut q = model.neutral_configuration();
        set_free_pose(model, &mut q, 1, &x);
        forward_kinematics(model, &mut data, &q).unwrap();
        self.world.update_multibody(mb, &data).unwrap();
    }

    fn fixed(&mut self, name: &str, shape: Shape, x: Transform) -> usize {
        self.world.add_static(name, &shape, x, &MeshOptions::default()).unwrap()
    }

    fn detect(&mut self) -> Vec<Contact> {
        let contacts = self.world.detect().to_vec();
        for c in &contacts {
            check_contact(c);
        }
        contacts
    }
}

#[track_caller]
fn close(got: Vec3, want: Vec3, tol: f64, what: &str) {
    let e = (got - want).norm();
    assert!(e <= tol, "{what}: got {got:?}, want {want:?} (|Δ| = {e:e})");
}

#[track_caller]
fn close_f(got: f64, want: f64, tol: f64, what: &str) {
    let e = (got - want).abs();
    assert!(e <= tol, "{what}: got {got:e}, want {want:e} (|Δ| = {e:e})");
}

/// What every contact satisfies: a unit normal, a distance within the margin, and the two
/// points separated by `distance` along the normal.
#[track_caller]
fn check_contact(c: &Contact) {
    close_f(c.normal.norm(), 1.0, 1e-12, "|normal|");
    assert!(c.distance <= MARGIN + 1e-12, "distance {} beyond the margin", c.distance);
    close(c.point_a - c.point_b, c.normal * c.distance, TOL, "point_a − point_b = distance · normal");
    assert!(c.body_b.is_static() || !c.body_a.is_static(), "static geometry must be B: {c:?}");
}

/// An expected contact: point_a, point_b, normal, distance.
type Expected = (Vec3, Vec3, Vec3, f64);

fn as_expected(c: &Contact) -> Expected {
    (c.point_a, c.point_b, c.normal, c.distance)
}

/// Same number of contacts and, up to ordering, the same points, normals and distances.
#[track_caller]
fn assert_same_contacts(got: &[Expected], want: &[Expected], tol: f64, what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: contact count\n got  {got:#?}\n want {want:#?}");
    let mut used = vec![false; got.len()];
    for w in want {
        let k = (0..got.len())
            .filter(|&k| !used[k])
            .min_by(|&i, &j| (got[i].0 - w.0).norm().total_cmp(&(got[j].0 - w.0).norm()))
            .unwrap();
        used[k] = true;
        let g = &got[k];
        let ctx = format!("{what}\n got  {got:#?}\n want {want:#?}");
        close(g.0, w.0, tol, &format!("point_a; {ctx}"));
        close(g.1, w.1, tol, &format!("point_b; {ctx}"));
        close(g.2, w.2, tol, &format!("normal; {ctx}"));
        close_f(g.3, w.3, tol, &format!("distance; {ctx}"));
    }
}

/// A fresh directory under the system temporary directory, unique to this process and `tag`.
fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("gelenk-collision-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The unit cube [−½, ½]³ as 8 vertices and 12 triangles, counter-clockwise seen from outside.
fn unit_cube() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let half = |bit: bool| if bit { 0.5 } else { -0.5 };
    let vertices: Vec<Vec3> =
        (0..8).map(|i| v3(half(i & 1 != 0), half(i & 2 != 0), half(i & 4 != 0))).collect();
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let mut triangles = Vec::new();
    for [a, b, c, d] in quads {
        for t in [[a, b, c], [a, c, d]] {
            let [p, q, r] = t.map(|i: u32| vertices[i as usize]);
            let outward = (q - p).cross(&(r - p)).dot(&((p + q + r) / 3.0)) > 0.0;
            assert!(outward, "cube triangle {t:?} is not counter-clockwise from outside");
            triangles.push(t);
        }
    }
    (vertices, triangles)
}

fn write_cube_stl(path: &Path) {
    let (v, t) = unit_cube();
    let mut s = String::from("solid cube\n");
    for tri in &t {
        let [p, q, r] = tri.map(|i| v[i as usize]);
        let n = (q - p).cross(&(r - p)).normalize();
        s += &format!("  facet normal {} {} {}\n    outer loop\n", n.x, n.y, n.z);
        for x in [p, q, r] {
            s += &format!("      vertex {} {} {}\n", x.x, x.y, x.z);
        }
        s += "    endloop\n  endfacet\n";
    }
    s += "endsolid cube\n";
    std::fs::write(path, s).unwrap();
}

fn write_cube_obj(path: &Path) {
    let (v, t) = unit_cube();
    let mut s = String::from("# unit cube\no cube\n");
    for x in &v {
        s += &format!("v {} {} {}\n", x.x, x.y, x.z);
    }
    for tri in &t {
        s += &format!("f {} {} {}\n", tri[0] + 1, tri[1] + 1, tri[2] + 1);
    }
    std::fs::write(path, s).unwrap();
}

/// Closest points of segments [p0, p1] and [q0, q1], independently of the library: the minimum
/// of the convex quadratic |p(s) − q(t)|² over the unit square is either its interior stationary
/// point or on an edge of the square, where it is an endpoint projected (clamped) onto the other
/// segment.
fn closest_segment_points(p0: Vec3, p1: Vec3, q0: Vec3, q1: Vec3) -> (Vec3, Vec3) {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, b, c, f) = (d1.dot(&d1), d2.dot(&d2), d1.dot(&d2), d1.dot(&r), d2.dot(&r));
    let mut best: Option<(f64, Vec3, Vec3)> = None;
    let mut consider = |s: f64, t: f64| {
        let (x, y) = (p0 + d1 * s, q0 + d2 * t);
        let d = (x - y).norm();
        if best.is_none_or(|(bd, _, _)| d < bd) {
            best = Some((d, x, y));
        }
    };
    let det = a * e - b * b;
    if det > 1e-12 * a * e {
        let (s, t) = ((b * f - c * e) / det, (a * f - b * c) / det);
        if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
            consider(s, t);
        }
    }
    for s in [0.0, 1.0] {
        let t = ((p0 + d1 * s - q0).dot(&d2) / e).clamp(0.0, 1.0);
        consider(s, t);
    }
    for t in [0.0, 1.0] {
        let s = ((q0 + d2 * t - p0).dot(&d1) / a).clamp(0.0, 1.0);
        consider(s, t);
    }
    let (_, x, y) = best.unwrap();
    // No sample of the square comes closer.
    for i in 0..=40 {
        for j in 0..=40 {
            let (s, t) = (i as f64 / 40.0, j as f64 / 40.0);
            assert!((p0 + d1 * s - q0 - d2 * t).norm() >= (x - y).norm() - 1e-12);
        }
    }
    (x, y)
}

/// Endpoints of a capsule's segment: centre ± axis · length/2 (axis = the pose's z).
fn capsule_segment(x: &Transform, length: f64) -> (Vec3, Vec3) {
    let axis = x.rotation * Vec3::z();
    (x.translation - axis * (length / 2.0), x.translation + axis * (length / 2.0))
}

// ---------------------------------------------------------------------------------------------
// 1. Sphere on half-space
// ---------------------------------------------------------------------------------------------

#[test]
fn sphere_on_half_space_has_exact_distance_normal_and_points() {
    assert_eq!(CollisionOptions::default().margin, MARGIN);
    let r = 0.1;
    let tilt = deg(20.0);
    // (pose of the half-space, normal given in its frame)
    let grounds = [
        (Transform::identity(), Vec3::z()),
        // ground rotated by 20° about x
        (Transform::new(rot(Vec3::x(), tilt), v3(0.3, -0.2, 0.1)), Vec3::z()),
        // the same tilt given through the (non-unit) normal
        (Transform::from_translation(v3(0.0, 0.0, 0.25)), v3(0.0, -tilt.sin(), tilt.cos()) * 2.5),
        // ceiling and wall: normals along −z and +x (the broad phase bounds such half-spaces)
        (Transform::from_translation(v3(0.0, 0.0, 2.0)), -Vec3::z()),
        (Transform::from_translation(v3(1.0, 0.0, 0.0)), Vec3::x()),
        (Transform::from_translation(v3(0.0, -1.0, 0.0)), -Vec3::y()),
    ];
    for (pose, shape_normal) in grounds {
        let n = pose.rotation * shape_normal.normalize();
        let tangent = n.cross(&v3(0.3, 0.7, 0.1)).normalize();
        for gap in [-2e-3, -1e-6, 0.0, 1e-3, 4.9e-3] {
            let centre = pose.translation + tangent * 0.37 + n * (r + gap);
            let mut s = Scene::new();
            s.body("ball", Shape::Sphere { radius: r }, Transform::new(rot(v3(0.2, -0.5, 0.8), 1.1), centre));
            s.fixed("ground", Shape::HalfSpace { normal: shape_normal }, pose);
            let c = s.detect();
            let what = format!("ground normal {n:?}, gap {gap}");
            assert_eq!(c.len(), 1, "{what}: {c:#?}");
            let c = c[0];
            assert_eq!(c.body_a, Attachment::Body { multibody: 0, body: 1 });
            assert_eq!(c.body_b, Attachment::World);
            assert_eq!((c.collider_a, c.collider_b), (0, 1));
            close_f(c.distance, gap, 1e-12, &what);
            close(c.normal, n, 1e-12, &what);
            close(c.point_a, centre - n * r, TOL, &what);
            close(c.point_b, centre - n * (r + gap), TOL, &what);
        }
        // Beyond the margin, and far away: nothing.
        for gap in [MARGIN + 1e-4, 0.5, 30.0] {
            let mut s = Scene::new();
            s.body(
                "ball",
                Shape::Sphere { radius: r },
                Transform::from_translation(pose.translation + n * (r + gap)),
            );
            s.fixed("ground", Shape::HalfSpace { normal: shape_normal }, pose);
            assert!(s.detect().is_empty(), "gap {gap} beyond the margin must give no contact");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 2. Box resting flat on a half-space
// ---------------------------------------------------------------------------------------------

#[test]
fn box_resting_flat_touches_at_its_four_bottom_corners() {
    let size = v3(0.4, 0.3, 0.2);
    let depth = 1e-3;
    let grounds = [
        (Transform::identity(), 0.0),
        (Transform::identity(), 0.7),
        (Transform::new(rot(Vec3::x(), deg(20.0)), v3(0.1, 0.2, -0.3)), 0.4),
        (Transform::new(rot(v3(0.3, -1.0, 0.2), 0.5), v3(-2.0, 0.5, 1.0)), -1.2),
    ];
    for (ground, yaw) in grounds {
        let n = ground.rotation * Vec3::z();
        let r_box = ground.rotation * rot(Vec3::z(), yaw);
        let centre = ground.act_point(&v3(0.25, -0.1, size.z / 2.0 - depth));
        let mut s = Scene::new();
        s.body("box", Shape::Box { size }, Transform::new(r_box, centre));
        s.fixed("ground", Shape::HalfSpace { normal: Vec3::z() }, ground);
        let got: Vec<Expected> = s.detect().iter().map(as_expected).collect();
        let mut want = Vec::new();
        for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            let corner = centre + r_box * v3(sx * size.x / 2.0, sy * size.y / 2.0, -size.z / 2.0);
            want.push((corner, corner + n * depth, n, -depth));
        }
        assert_same_contacts(&got, &want, TOL, &format!("box flat, yaw {yaw}"));
    }
}

// ---------------------------------------------------------------------------------------------
// 3. Box tilted onto an edge
// ---------------------------------------------------------------------------------------------

#[test]
fn box_tilted_onto_an_edge_touches_at_the_edge_ends() {
    let size = v3(0.4, 0.3, 0.2);
    let depth = 1e-3;
    let tilt = deg(30.0);
    for yaw in [0.0, 0.9, -2.3] {
        let r_box = rot(Vec3::z(), yaw) * rot(Vec3::x(), tilt);
        // The lowest edge is y = −sy/2, z = −sz/2 in the box frame.
        let height = size.y / 2.0 * tilt.sin() + size.z / 2.0 * tilt.cos() - depth;
        let centre = v3(0.3, -0.7, height);
        let mut s = Scene::new();
        s.body("box", Shape::Box { size }, Transform::new(r_box, centre));
        s.fixed("ground", Shape::HalfSpace { normal: Vec3::z() }, Transform::identity());
        let got: Vec<Expected> = s.detect().iter().map(as_expected).collect();
        let want: Vec<Expected> = [-1.0, 1.0]
            .iter()
            .map(|sx| {
                let p = centre + r_box * v3(sx * size.x / 2.0, -size.y / 2.0, -size.z / 2.0);
                close_f(p.z, -depth, 1e-12, "edge end height");
                (p, v3(p.x, p.y, 0.0), Vec3::z(), -depth)
            })
            .collect();
        assert_same_contacts(&got, &want, TOL, &format!("box on edge, yaw {yaw}"));
    }
}

// ---------------------------------------------------------------------------------------------
// 4. Capsule–capsule and sphere–box closest points
// ---------------------------------------------------------------------------------------------

/// Contact of capsule A (pose xa) with capsule B (pose xb), from the closest points of the axes.
fn capsule_capsule_expected(xa: &Transform, la: f64, ra: f64, xb: &Transform, lb: f64, rb: f64) -> Expected {
    let (a0, a1) = capsule_segment(xa, la);
    let (b0, b1) = capsule_segment(xb, lb);
    let (pa, pb) = closest_segment_points(a0, a1, b0, b1);
    let n = (pa - pb).normalize();
    (pa - n * ra, pb + n * rb, n, (pa - pb).norm() - ra - rb)
}

#[test]
fn capsule_capsule_contacts_match_closest_points_of_the_axes() {
    let (ra, la, rb, lb) = (0.1, 0.5, 0.05, 0.7);
    // (pose of A before the gap is set, pose of B)
    let configurations = [
        // crossing at right angles, interior points of both axes
        (
            Transform::new(z_to(Vec3::x(), 0.0), v3(0.02, 0.01, 0.2)),
            Transform::new(z_to(Vec3::y(), 0.3), Vec3::zeros()),
        ),
        // skew, generic
        (
            Transform::new(z_to(v3(1.0, 0.3, 0.2), 0.1), v3(0.1, -0.05, 0.25)),
            Transform::new(z_to(v3(0.2, 1.0, -0.4), 1.0), v3(0.02, 0.0, 0.0)),
        ),
        // T: an end of A against the side of B
        (
            Transform::new(z_to(v3(0.1, 0.05, 1.0), 0.0), v3(0.05, 0.0, 0.45)),
            Transform::new(z_to(Vec3::x(), 0.0), Vec3::zeros()),
        ),
        // end against end
        (
            Transform::new(z_to(v3(1.0, 0.2, 0.1), 0.0), v3(0.65, 0.1, 0.05)),
            Transform::new(z_to(v3(1.0, -0.3, 0.1), 0.0), Vec3::zeros()),
        ),
    ];
    let motion = Transform::new(rot(v3(0.4, 0.1, -0.7), 0.8), v3(1.0, -0.5, 0.3));
    for (k, (xa0, xb)) in configurations.iter().enumerate() {
        for gap in [-1e-3, 0.0, 3e-3] {
            // Move A along the line of the closest points so that the surfaces are `gap` apart.
            let (_, _, n, d) = capsule_capsule_expected(xa0, la, ra, xb, lb, rb);
            let xa = Transform::new(xa0.rotation, xa0.translation + n * (gap - d));
            let (xa, xb) = (motion * xa, motion * *xb);
            let want = capsule_capsule_expected(&xa, la, ra, &xb, lb, rb);
            close_f(want.3, gap, 1e-12, "gap set up");
            let mut s = Scene::new();
            s.body("a", Shape::Capsule { radius: ra, length: la }, xa);
            s.body("b", Shape::Capsule { radius: rb, length: lb }, xb);
            let got: Vec<Expected> = s.detect().iter().map(as_expected).collect();
            assert_same_contacts(&got, &[want], TOL, &format!("capsules, configuration {k}, gap {gap}"));
        }
    }
}

#[test]
fn parallel_capsules_touch_along_the_overlap_of_their_axes() {
    let (ra, la, rb, lb) = (0.1, 0.4, 0.05, 0.4);
    let depth = 1e-3;
    let motion = Transform::new(rot(v3(-0.2, 0.9, 0.3), 2.0), v3(0.3, 0.1, -0.4));
    // A along x, shifted by 0.1 m: the axes overlap for x in [−0.1, 0.2].
    let xa = motion * Transform::new(z_to(Vec3::x(), 0.2), v3(0.1, 0.0, ra + rb - depth));
    let xb = motion * Transform::new(z_to(Vec3::x(), -0.5), Vec3::zeros());
    let mut s = Scene::new();
    s.body("a", Shape::Capsule { radius: ra, length: la }, xa);
    s.body("b", Shape::Capsule { radius: rb, length: lb }, xb);
    let contacts = s.detect();
    assert!(!contacts.is_empty() && contacts.len() <= 2, "{contacts:#?}");
    let n = motion.rotation * Vec3::z();
    for c in &contacts {
        close(c.normal, n, TOL, "normal");
        close_f(c.distance, -depth, TOL, "distance");
        let local = motion.act_inv_point(&c.point_a);
        assert!((-0.1 - TOL..=0.2 + TOL).contains(&local.x), "point outside the overlap: {local:?}");
        close_f(local.y, 0.0, TOL, "point_a y");
        close_f(local.z, rb - depth, TOL, "point_a z (bottom of A)");
        let local_b = motion.act_inv_point(&c.point_b);
        close(local_b, v3(local.x, 0.0, rb), TOL, "point_b (top of B)");
    }
}

#[test]
fn sphere_box_contacts_match_the_closest_point_of_the_box() {
    let size = v3(0.4, 0.3, 0.2);
    let h = size / 2.0;
    let r = 0.08;
    let x_box = Transform::new(rot(v3(0.3, -0.8, 0.5), 0.9), v3(0.1, -0.2, 0.3));
    // Sphere centres in the box frame as functions of the surface distance `gap`.
    let u = v3(1.0, 0.8, 1.2).normalize();
    type Place = Box<dyn Fn(f64) -> Vec3>;
    let places: [(&str, Place); 3] = [
        ("face", Box::new(move |gap| v3(0.05, -0.03, h.z + r + gap))),
        (
            "edge",
            Box::new(move |gap| v3(0.07, h.y + (r + gap) * 0.6f64.cos(), h.z + (r + gap) * 0.6f64.sin())),
        ),
        ("corner", Box::new(move |gap| h + u * (r + gap))),
    ];
    for (name, place) in &places {
        for gap in [-1e-3, 0.0, 2e-3] {
            let local = place(gap);
            let closest = v3(local.x.clamp(-h.x, h.x), local.y.clamp(-h.y, h.y), local.z.clamp(-h.z, h.z));
            let n = x_box.rotation * (local - closest).normalize();
            let centre = x_box.act_point(&local);
            let on_box = x_box.act_point(&closest);
            let dist = (local - closest).norm() - r;
            close_f(dist, gap, 1e-12, "set-up");
            let what = format!("sphere near a {name}, gap {gap}");
            // Sphere is A (added first).
            let mut s = Scene::new();
            s.body("ball", Shape::Sphere { radius: r }, Transform::from_translation(centre));
            s.body("box", Shape::Box { size }, x_box);
            let got: Vec<Expected> = s.detect().iter().map(as_expected).collect();
            assert_same_contacts(
                &got,
                &[(centre - n * r, on_box, n, dist)],
                TOL,
                &format!("{what}, sphere A"),
            );
            // Box is A: the normal flips and the points swap.
            let mut s = Scene::new();
            s.body("box", Shape::Box { size }, x_box);
            s.body("ball", Shape::Sphere { radius: r }, Transform::from_translation(centre));
            let got: Vec<Expected> = s.detect().iter().map(as_expected).collect();
            assert_same_contacts(&got, &[(on_box, centre - n * r, -n, dist)], TOL, &format!("{what}, box A"));
            // Static box (always B).
            let mut s = Scene::new();
            s.fixed("box", Shape::Box { size }, x_box);
            s.body("ball", Shape::Sphere { radius: r }, Transform::from_translation(centre));
            let got: Vec<Expected> = s.detect().iter().map(as_expected).collect();
            assert_same_contacts(
                &got,
                &[(centre - n * r, on_box, n, dist)],
                TOL,
                &format!("{what}, static box"),
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 5. Mesh files give the contacts of the primitive they describe
// ---------------------------------------------------------------------------------------------

/// Contacts of a cube (`shape`, a Box or a Mesh of it) in three scenes: resting on a half-space,
/// resting on a larger box, overlapping a box corner to corner.
fn cube_scenes(shape: &Shape, size: Vec3) -> Vec<Vec<Expected>> {
    let mut out = Vec::new();
    let yaw = rot(Vec3::z(), 0.3);
    let depth = 1e-3;
    // On a half-space.
    let mut s = Scene::new();
    s.body("cube", shape.clone(), Transform::new(yaw, v3(0.2, 0.1, size.z / 2.0 - depth)));
    s.fixed("ground", Shape::HalfSpace { normal: Vec3::z() }, Transform::identity());
    out.push(s.detect().iter().map(as_expected).collect());
    // On a larger box, entirely inside its top face (A = the cube).
    let base = Shape::Box { size: v3(4.0, 4.0, 1.0) * size.max() };
    let mut s = Scene::new();
    s.body("cube", shape.clone(), Transform::new(yaw, v3(0.01, -0.02, size.z / 2.0 - depth)));
    s.body("base", base.clone(), Transform::from_translation(v3(0.0, 0.0, -0.5 * size.max())));
    out.push(s.detect().iter().map(as_expected).collect());
    // Against a static box of the same size, offset diagonally (overlap polygon from both).
    let mut s = Scene::new();
    s.body(
        "cube",
        shape.clone(),
        Transform::from_translation(v3(0.4 * size.x, 0.3 * size.y, size.z - depth)),
    );
    s.fixed("block", Shape::Box { size }, Transform::identity());
    out.push(s.detect().iter().map(as_expected).collect());
    // Tilted onto an edge, on the half-space.
    let tilt = rot(Vec3::x(), deg(30.0));
    let height = size.y / 2.0 * deg(30.0).sin() + size.z / 2.0 * deg(30.0).cos() - depth;
    let mut s = Scene::new();
    s.body("cube", shape.clone(), Transform::new(yaw * tilt, v3(0.0, 0.0, height)));
    s.fixed("ground", Shape::HalfSpace { normal: Vec3::z() }, Transform::identity());
    out.push(s.detect().iter().map(as_expected).collect());
    out
}

#[test]
fn cube_meshes_from_stl_and_obj_give_the_contacts_of_the_box() {
    let dir = temp_dir("cube-meshes");
    let (stl, obj) = (dir.join("cube.stl"), dir.join("cube.obj"));
    write_cube_stl(&stl);
    write_cube_obj(&obj);
    for path in [&stl, &obj] {
        for scale in [v3(1.0, 1.0, 1.0), v3(0.2, 0.2, 0.2), v3(0.2, 0.3, 0.1)] {
            let mesh = Shape::Mesh { uri: path.display().to_string(), scale };
            // On a moving body the mesh becomes a convex hull.
            let mut s = Scene::new();
            s.body("cube", mesh.clone(), Transform::identity());
            assert_eq!(s.world.colliders()[0].kind(), ShapeKind::ConvexHull);
            let (mins, maxs) = s.world.colliders()[0].aabb();
            close(Vec3::from(maxs) - Vec3::from(mins), scale, TOL, "mesh extent");
            let from_mesh = cube_scenes(&mesh, scale);
            let from_box = cube_scenes(&Shape::Box { size: scale }, scale);
            for (k, (m, b)) in from_mesh.iter().zip(&from_box).enumerate() {
                assert!(!b.is_empty(), "scene {k} has contacts");
                assert_same_contacts(m, b, TOL, &format!("{}, scale {scale:?}, scene {k}", path.display()));
            }
        }
    }
    let _ = std::fs::remove_dir_all(dir);
}

// ---------------------------------------------------------------------------------------------
// 6. Invariance under a common rigid motion
// ---------------------------------------------------------------------------------------------

fn moved_scene_contacts(
    g: &Transform,
    bodies: &[(Shape, Transform)],
    statics: &[(Shape, Transform)],
) -> Vec<Contact> {
    let mut s = Scene::new();
    for (k, (shape, x)) in bodies.iter().enumerate() {
        s.body(&format!("body{k}"), shape.clone(), *g * *x);
    }
    for (k, (shape, x)) in statics.iter().enumerate() {
        s.fixed(&format!("static{k}"), shape.clone(), *g * *x);
    }
    s.detect()
}

#[test]
fn contacts_are_invariant_under_a_common_rigid_motion() {
    let depth = 1e-3;
    let slight = rot(v3(0.3, 1.0, 0.0), deg(0.4));
    let box_on_box = (
        vec![
            // A resting on the static slab, slightly tilted so that the corner depths differ
            (
                Shape::Box { size: v3(0.4, 0.3, 0.2) },
                Transform::new(rot(Vec3::z(), 0.3) * slight, v3(0.1, 0.05, 0.1 - depth)),
            ),
            // B on top of A, yawed and tilted the other way
            (
                Shape::Box { size: v3(0.2, 0.2, 0.2) },
                Transform::new(rot(Vec3::z(), 1.0) * slight.transpose(), v3(0.12, 0.02, 0.3 - 3.0 * depth)),
            ),
        ],
        vec![(Shape::Box { size: v3(2.0, 2.0, 0.5) }, Transform::from_translation(v3(0.0, 0.0, -0.25)))],
    );
    let capsule_on_box = (
        vec![
            // lying on the static slab, one end slightly lower
            (
                Shape::Capsule { radius: 0.05, length: 0.4 },
                Transform::new(
                    rot(Vec3::z(), 0.5) * z_to(Vec3::x(), 0.0) * rot(Vec3::y(), deg(0.3)),
                    v3(0.0, 0.3, 0.05 - depth),
                ),
            ),
            // a free box, and a capsule poking into its top face at an angle
            (
                Shape::Box { size: v3(0.3, 0.3, 0.3) },
                Transform::new(rot(Vec3::z(), -0.4), v3(-0.5, -0.4, 0.15 - depth)),
            ),
            (
                Shape::Capsule { radius: 0.04, length: 0.3 },
                // lowest point 2 mm below the box's top face (at 0.3 − depth)
                Transform::new(
                    z_to(v3(0.3, -0.2, 1.0), 0.7),
                    v3(-0.5, -0.4, 0.3 - 3.0 * depth + 0.15 / v3(0.3, -0.2, 1.0).norm() + 0.04),
                ),
            ),
        ],
        vec![(Shape::Box { size: v3(2.0, 2.0, 0.5) }, Transform::from_translation(v3(0.0, 0.0, -0.25)))],
    );
    let mut rng = StdRng::seed_from_u64(2024);
    // Touching pairs (A, B): static geometry is B, otherwise the lower collider index is A.
    let scenes = [
        ("box on box", box_on_box, vec![(0, 1), (0, 2)]),
        ("capsule on box", capsule_on_box, vec![(0, 3), (1, 2), (1, 3)]),
    ];
    for (name, (bodies, statics), designed) in scenes {
        let reference = moved_scene_contacts(&Transform::identity(), &bodies, &statics);
        let pairs = touching_pairs;
        assert_eq!(pairs(&reference), designed, "{name}: every designed pair touches: {reference:#?}");
        for trial in 0..6 {
            let g = Transform::new(
                random_rotation(&mut rng),
                v3(rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0)),
            );
            let moved = moved_scene_contacts(&g, &bodies, &statics);
            assert_eq!(pairs(&moved), pairs(&reference), "{name}, trial {trial}: touching pairs");
            for pair in pairs(&reference) {
                let of = |cs: &[Contact]| -> Vec<Contact> {
                    cs.iter().filter(|c| (c.collider_a, c.collider_b) == pair).copied().collect()
                };
                let got: Vec<Expected> = of(&moved).iter().map(as_expected).collect();
                let want: Vec<Expected> = of(&reference)
                    .iter()
                    .map(|c| {
                        (g.act_point(&c.point_a), g.act_point(&c.point_b), g.rotation * c.normal, c.distance)
                    })
                    .collect();
                assert_same_contacts(&got, &want, TOL, &format!("{name}, trial {trial}, pair {pair:?}"));
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 7. Filtering
// ---------------------------------------------------------------------------------------------

fn touching_pairs(contacts: &[Contact]) -> Vec<(usize, usize)> {
    let mut p: Vec<(usize, usize)> = contacts.iter().map(|c| (c.collider_a, c.collider_b)).collect();
    p.sort();
    p.dedup();
    p
}

fn touching_bodies(contacts: &[Contact]) -> Vec<(usize, usize)> {
    let body = |a: Attachment| match a {
        Attachment::Body { body, .. } => body,
        Attachment::World => usize::MAX,
    };
    let mut p: Vec<(usize, usize)> = contacts
        .iter()
        .map(|c| {
            let (a, b) = (body(c.body_a), body(c.body_b));
            (a.min(b), a.max(b))
        })
        .collect();
    p.sort();
    p.dedup();
    p
}

#[test]
fn groups_and_masks_exclude_pairs() {
    let size = v3(0.2, 0.2, 0.2);
    let mut s = Scene::new();
    s.body("one", Shape::Box { size }, Transform::from_translation(v3(0.0, 0.0, 0.099)));
    s.body("two", Shape::Box { size }, Transform::from_translation(v3(0.05, 0.02, 0.29)));
    let ground = s.fixed("ground", Shape::HalfSpace { normal: Vec3::z() }, Transform::identity());
    assert_eq!(ground, 2);
    assert_eq!(touching_pairs(&s.detect()), vec![(0, 1), (0, 2)]);

    // "two" only collides with group 4: neither "one" (group 1) nor the ground (group 1).
    s.world.set_filter(1, CollisionFilter { group: 2, mask: 4 }).unwrap();
    assert_eq!(touching_pairs(&s.detect()), vec![(0, 2)]);
    // Masks must accept each other both ways: "one" ignoring group 2 is enough to exclude the pair.
    s.world.set_filter(1, CollisionFilter { group: 2, mask: u32::MAX }).unwrap();
    assert_eq!(touching_pairs(&s.detect()), vec![(0, 1), (0, 2)]);
    s.world.set_filter(0, CollisionFilter { group: 1, mask: !2 }).unwrap();
    assert_eq!(touching_pairs(&s.detect()), vec![(0, 2)]);
    assert_eq!(s.world.stats().broad_pairs, 1, "filtered pairs never reach the narrow phase");
    // Ground in its own group, excluded by "one".
    s.world.set_filter(0, CollisionFilter { group: 1, mask: !(2 | 8) }).unwrap();
    s.world.set_filter(2, CollisionFilter { group: 8, mask: u32::MAX }).unwrap();
    assert!(s.detect().is_empty());
    assert_eq!(s.world.stats(), Default::default());
    // Back to the defaults: everything again.
    for k in 0..3 {
        s.world.set_filter(k, CollisionFilter::default()).unwrap();
    }
    assert_eq!(touching_pairs(&s.detect()), vec![(0, 1), (0, 2)]);
    assert!(matches!(
        s.world.set_filter(3, CollisionFilter::default()),
        Err(CollisionError::IndexOutOfRange { index: 3, count: 3, .. })
    ));
}

fn hinge_link(name: &str, parent: &str, at: Vec3, collider_at: Vec3, size: Vec3) -> BodySpec {
    BodySpec::new(
        name,
        parent,
        Joint::hinge(Vec3::z()),
        Transform::from_translation(at),
        RigidInertia::solid_box(1.0, size),
    )
    .with_collision(Shape::Box { size }, Transform::from_translation(collider_at))
}

fn chain_contacts(model: &Model, options: CollisionOptions, self_collision: bool) -> Vec<Contact> {
    let mut world = CollisionWorld::new(options);
    let mb = world.add_model(model, &MeshOptions::default()).unwrap();
    if self_collision {
        world.set_self_collision(mb, true).unwrap();
    }
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, &model.neutral_configuration()).unwrap();
    world.update_multibody(mb, &data).unwrap();
    let contacts = world.detect().to_vec();
    for c in &contacts {
        check_contact(c);
    }
    contacts
}

#[test]
fn bodies_joined_by_a_joint_collide_only_when_asked() {
    // Two links on hinges whose boxes overlap by 0.1 m around the second joint.
    let size = v3(0.5, 0.1, 0.1);
    let model = ModelBuilder::new()
        .add_body(hinge_link("link1", "universe", Vec3::zeros(), v3(0.25, 0.0, 0.0), size))
        .add_body(hinge_link("link2", "link1", v3(0.4, 0.0, 0.0), v3(0.25, 0.0, 0.0), size))
        .build()
        .unwrap();
    let joined = CollisionOptions { collide_joined_bodies: true, ..Default::default() };
    assert!(chain_contacts(&model, CollisionOptions::default(), false).is_empty());
    assert!(chain_contacts(&model, CollisionOptions::default(), true).is_empty());
    assert!(
        chain_contacts(&model, joined, false).is_empty(),
        "self-collision off excludes joined bodies too"
    );
    let contacts = chain_contacts(&model, joined, true);
    assert_eq!(touching_bodies(&contacts), vec![(1, 2)]);
    assert!(contacts.iter().all(|c| c.distance < 0.0), "the boxes overlap: {contacts:#?}");
}

#[test]
fn self_collision_is_off_by_default() {
    // link3's box sits on link1's box; link2 (joined to both) overlaps link1 only.
    let model = ModelBuilder::new()
        .add_body(hinge_link("link1", "universe", Vec3::zeros(), v3(0.25, 0.0, 0.0), v3(0.5, 0.1, 0.1)))
        .add_body(hinge_link("link2", "link1", v3(0.5, 0.0, 0.0), v3(0.0, 0.25, 0.0), v3(0.1, 0.5, 0.1)))
        .add_body(hinge_link("link3", "link2", v3(0.0, 0.5, 0.0), v3(-0.3, -0.5, 0.0), v3(0.1, 0.1, 0.1)))
        .build()
        .unwrap();
    assert!(chain_contacts(&model, CollisionOptions::default(), false).is_empty());
    assert_eq!(touching_bodies(&chain_contacts(&model, CollisionOptions::default(), true)), vec![(1, 3)]);
    let joined = CollisionOptions { collide_joined_bodies: true, ..Default::default() };
    assert_eq!(touching_bodies(&chain_contacts(&model, joined, true)), vec![(1, 2), (1, 3)]);
    // Separate multibodies always collide, self-collision or not.
    let mut s = Scene::new();
    s.body("one", Shape::Box { size: v3(0.2, 0.2, 0.2) }, Transform::identity());
    s.body("two", Shape::Box { size: v3(0.2, 0.2, 0.2) }, Transform::from_translation(v3(0.0, 0.0, 0.19)));
    assert_eq!(touching_pairs(&s.detect()), vec![(0, 1)]);
    assert!(matches!(
        s.world.set_self_collision(2, true),
        Err(CollisionError::IndexOutOfRange { index: 2, .. })
    ));
}

#[test]
fn static_geometry_is_never_tested_against_static_geometry() {
    let mut world = CollisionWorld::new(CollisionOptions::default());
    let opts = MeshOptions::default();
    world.add_static("a", &Shape::Box { size: v3(1.0, 1.0, 1.0) }, Transform::identity(), &opts).unwrap();
    world
        .add_static(
            "b",
            &Shape::Box { size: v3(1.0, 1.0, 1.0) },
            Transform::from_translation(v3(0.3, 0.0, 0.0)),
            &opts,
        )
        .unwrap();
    world
        .add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), &opts)
        .unwrap();
    world.add_static("sphere", &Shape::Sphere { radius: 0.4 }, Transform::identity(), &opts).unwrap();
    assert!(world.detect().is_empty());
    assert_eq!(world.stats().broad_pairs, 0);
    // Geometry welded to a multibody's universe (body 0) is static too.
    let model = ModelBuilder::new()
        .add_body(
            BodySpec::new(
                "pedestal",
                "universe",
                Joint::Fixed,
                Transform::identity(),
                RigidInertia::massless(),
            )
            .with_collision(Shape::Box { size: v3(0.5, 0.5, 0.5) }, Transform::identity()),
        )
        .build()
        .unwrap();
    let mb = world.add_model(&model, &opts).unwrap();
    assert_eq!(world.colliders()[4].attachment(), Attachment::Body { multibody: mb, body: 0 });
    assert!(world.colliders()[4].attachment().is_static());
    let data = Data::new(&model);
    world.update_multibody(mb, &data).unwrap();
    assert!(world.detect().is_empty());
    assert_eq!(world.stats().broad_pairs, 0);
}

// ---------------------------------------------------------------------------------------------
// 8. Contact Jacobians
// ---------------------------------------------------------------------------------------------

const HAND_BOX: Vec3 = Vec3::new(0.1, 0.08, 0.06);

fn hand_geometry() -> Transform {
    Transform::from_xyz_rpy([0.05, 0.0, 0.0], [0.1, 0.2, 0.3])
}

/// Free base, two hinges and a ball joint: base 1, upper 2, lower 3, hand 4.
fn jacobian_chain() -> Model {
    let b = |x: f64, y: f64, z: f64| RigidInertia::solid_box(1.0, v3(x, y, z));
    ModelBuilder::new()
        .add_body(
            BodySpec::new("base", "universe", Joint::Free, Transform::identity(), b(0.3, 0.2, 0.1))
                .with_collision(Shape::Box { size: v3(0.3, 0.2, 0.1) }, Transform::identity()),
        )
        .add_body(
            BodySpec::new(
                "upper",
                "base",
                Joint::hinge(Vec3::y()),
                Transform::from_translation(v3(0.15, 0.0, 0.0)),
                b(0.3, 0.05, 0.05),
            )
            .with_collision(
                Shape::Box { size: v3(0.3, 0.05, 0.05) },
                Transform::from_translation(v3(0.15, 0.0, 0.0)),
            ),
        )
        .add_body(
            BodySpec::new(
                "lower",
                "upper",
                Joint::hinge(v3(1.0, 1.0, 0.0)),
                Transform::from_translation(v3(0.3, 0.0, 0.0)),
                b(0.2, 0.05, 0.05),
            )
            .with_collision(Shape::Sphere { radius: 0.05 }, Transform::from_translation(v3(0.1, 0.0, 0.0))),
        )
        .add_body(
            BodySpec::new(
                "hand",
                "lower",
                Joint::Ball,
                Transform::from_translation(v3(0.2, 0.0, 0.0)),
                b(0.1, 0.08, 0.06),
            )
            .with_collision(Shape::Box { size: HAND_BOX }, hand_geometry()),
        )
        .build()
        .unwrap()
}

#[test]
fn contact_jacobian_gives_the_relative_velocity_of_the_contact_points() {
    let model = jacobian_chain();
    assert_eq!((model.nbodies(), model.nv()), (5, 11));
    let mut rng = StdRng::seed_from_u64(8);
    let (mut ground_contacts, mut self_contacts) = (0, 0);
    for trial in 0..5 {
        let mut q = model.neutral_configuration();
        set_free_pose(&model, &mut q, 1, &Transform::new(random_rotation(&mut rng), v3(0.1, -0.2, 0.5)));
        for body in [2, 3] {
            q[model.idx_q(body)] = rng.random_range(-1.5..1.5);
        }
        let ball = nalgebra::UnitQuaternion::from_axis_angle(
            &nalgebra::Unit::new_normalize(random_unit(&mut rng)),
            rng.random_range(0.0..2.0),
        );
        let iq = model.idx_q(4);
        for (k, c) in [ball.i, ball.j, ball.k, ball.w].into_iter().enumerate() {
            q[iq + k] = c;
        }
        let mut data = Data::new(&model);
        compute_joint_jacobians(&model, &mut data, &q).unwrap();

        let mut world = CollisionWorld::new(CollisionOptions::default());
        let mb = world.add_model(&model, &MeshOptions::default()).unwrap();
        world.set_self_collision(mb, true).unwrap();
        // A tilted ground 1 mm into the hand's lowest corner.
        let n_ground = v3(0.1, -0.2, 1.0).normalize();
        let x_hand = data.x_wb[4] * hand_geometry();
        let mut lowest = f64::INFINITY;
        for i in 0..8 {
            let s = |bit: usize| if i & bit != 0 { 0.5 } else { -0.5 };
            let corner = x_hand.act_point(&HAND_BOX.component_mul(&v3(s(1), s(2), s(4))));
            lowest = lowest.min(n_ground.dot(&corner));
        }
        let ground = Transform::from_translation(n_ground * (lowest + 1e-3));
        world
            .add_static("ground", &Shape::HalfSpace { normal: n_ground }, ground, &MeshOptions::default())
            .unwrap();
        // A static block under the sphere of "lower", 1 mm into it.
        let sphere = data.x_wb[3].act_point(&v3(0.1, 0.0, 0.0));
        let block = Transform::new(rot(Vec3::z(), 0.3), sphere - Vec3::z() * (0.05 - 1e-3 + 0.1));
        world
            .add_static("block", &Shape::Box { size: v3(0.2, 0.2, 0.2) }, block, &MeshOptions::default())
            .unwrap();
        // A probe sphere on "upper" pressing 1 mm into the hand's +z face (a self-contact of
        // bodies 2 and 4, which no joint joins).
        let probe_world = x_hand.act_point(&v3(0.01, 0.01, HAND_BOX.z / 2.0 + 0.03 - 1e-3));
        let probe = Transform::from_translation(data.x_wb[2].act_inv_point(&probe_world));
        world
            .add_body_collider(
                mb,
                2,
                "probe",
                &Shape::Sphere { radius: 0.03 },
                probe,
                &MeshOptions::default(),
            )
            .unwrap();
        world.update_multibody(mb, &data).unwrap();
        let contacts = world.detect().to_vec();

        let v = DVector::from_fn(model.nv(), |_, _| rng.random_range(-1.0..1.0));
        let h = 1e-6;
        let mut fd = Data::new(&model);
        let mut point_velocity = |side: Attachment, point: &Vec3| -> Vec3 {
            match side {
                Attachment::World | Attachment::Body { body: 0, .. } => Vec3::zeros(),
                Attachment::Body { body, .. } => {
                    let local = data.x_wb[body].act_inv_point(point);
                    let mut moved = |dt: f64| {
                        let mut qt = q.clone();
                        model.integrate(&q, &v, dt, &mut qt);
                        forward_kinematics(&model, &mut fd, &qt).unwrap();
                        fd.x_wb[body].act_point(&local)
                    };
                    (moved(h) - moved(-h)) / (2.0 * h)
                }
            }
        };
        let mut jac = DMatrix::zeros(3, model.nv());
        for c in &contacts {
            check_contact(c);
            contact_jacobian(&model, &data, mb, c, &mut jac).unwrap();
            let got = &jac * &v;
            let relative = point_velocity(c.body_a, &c.point_a) - point_velocity(c.body_b, &c.point_b);
            let want = contact_frame(&c.normal).transpose() * relative;
            let err = (v3(got[0], got[1], got[2]) - want).norm();
            assert!(
                err <= 1e-6 * want.norm().max(1.0),
                "trial {trial}: J v = {got:?}, finite differences {want:?}, contact {c:?}"
            );
            match (c.body_a, c.body_b) {
                (Attachment::Body { body: 4, .. }, Attachment::World) => ground_contacts += 1,
                (Attachment::Body { body: a, .. }, Attachment::Body { body: b, .. })
                    if a.min(b) == 2 && a.max(b) == 4 =>
                {
                    self_contacts += 1
                }
                _ => {}
            }
        }
        // A contact with a static side only sees A's motion: J is J_A alone.
        assert!(
            contacts.iter().any(|c| c.body_b == Attachment::World),
            "trial {trial}: no ground contact {contacts:#?}"
        );
    }
    assert!(ground_contacts >= 5, "hand on the ground in every trial ({ground_contacts})");
    assert!(self_contacts >= 5, "probe–hand self-contact in every trial ({self_contacts})");
}

#[test]
fn contact_jacobian_rejects_a_wrong_output_size() {
    let model = jacobian_chain();
    let mut s = Scene::new();
    s.body("ball", Shape::Sphere { radius: 0.1 }, Transform::from_translation(v3(0.0, 0.0, 0.099)));
    s.fixed("ground", Shape::HalfSpace { normal: Vec3::z() }, Transform::identity());
    let c = s.detect()[0];
    let data = Data::new(&model);
    let mut wrong = DMatrix::zeros(3, model.nv() + 1);
    assert!(matches!(
        contact_jacobian(&model, &data, 0, &c, &mut wrong),
        Err(CollisionError::IndexOutOfRange { .. })
    ));
    // The contact belongs to multibody 0; asking for multibody 1 is an error, not a silent zero.
    let mut right = DMatrix::zeros(3, model.nv());
    assert!(contact_jacobian(&model, &data, 1, &c, &mut right).is_err());
}

// ---------------------------------------------------------------------------------------------
// 9. URDF models and meshes
// ---------------------------------------------------------------------------------------------

/// (link, mesh URI) of every collision mesh, and the number of primitive collision shapes, read
/// from the file with a plain XML parser.
fn urdf_collisions(path: &Path) -> (Vec<(String, String)>, usize) {
    let text = std::fs::read_to_string(path).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let (mut meshes, mut primitives) = (Vec::new(), 0);
    for link in doc.root_element().children().filter(|n| n.has_tag_name("link")) {
        for collision in link.children().filter(|n| n.has_tag_name("collision")) {
            let geometry = collision.children().find(|n| n.has_tag_name("geometry")).unwrap();
            match geometry.children().find(|n| n.has_tag_name("mesh")) {
                Some(mesh) => meshes.push((
                    link.attribute("name").unwrap().to_string(),
                    mesh.attribute("filename").unwrap().to_string(),
                )),
                None => primitives += 1,
            }
        }
    }
    (meshes, primitives)
}

#[test]
fn urdf_models_load_with_missing_meshes_skipped_or_reported() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("models");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "urdf"))
        .collect();
    files.sort();
    let mut tested = 0;
    for path in &files {
        let (meshes, primitives) = urdf_collisions(path);
        if meshes.is_empty() && primitives == 0 {
            continue;
        }
        tested += 1;
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let model = load_file(path, &UrdfOptions::default()).unwrap_or_else(|e| panic!("{name}: {e}"));

        // Skip: loads, one warning per missing mesh, every primitive kept.
        let mut world = CollisionWorld::new(CollisionOptions::default());
        let skip = MeshOptions { missing: MissingMeshPolicy::Skip, ..Default::default() };
        let mb = world.add_model(&model, &skip).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(world.warnings().len(), meshes.len(), "{name}: {:#?}", world.warnings());
        for (link, uri) in &meshes {
            assert!(
                world.warnings().iter().any(|w| w.contains(link.as_str()) && w.contains(uri.as_str())),
                "{name}: no warning names {link} and {uri}: {:#?}",
                world.warnings()
            );
        }
        assert_eq!(world.colliders().len(), primitives, "{name}: primitive colliders");
        assert_eq!(world.colliders_of(mb).len(), primitives);
        // Detection runs on the loaded model, self-collision included.
        world.set_self_collision(mb, true).unwrap();
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &model.neutral_configuration()).unwrap();
        world.update_multibody(mb, &data).unwrap();
        for c in world.detect() {
            check_contact(c);
        }

        // Error (the default): the first missing mesh is reported with its link and URI.
        let mut world = CollisionWorld::new(CollisionOptions::default());
        match world.add_model(&model, &MeshOptions::default()) {
            Ok(_) => assert!(meshes.is_empty(), "{name}: missing meshes must be an error"),
            Err(CollisionError::MeshNotFound { link, uri, tried }) => {
                assert!(
                    meshes.contains(&(link.clone(), uri.clone())),
                    "{name}: ({link}, {uri}) is not a collision mesh"
                );
                assert!(!tried.is_empty());
                assert!(world.colliders().is_empty(), "{name}: a failed add_model leaves nothing behind");
            }
            Err(e) => panic!("{name}: unexpected error {e}"),
        }
    }
    assert!(tested >= 4, "the models with collision geometry were found ({tested})");
}

#[test]
fn package_uris_resolve_through_the_search_paths() {
    let dir = temp_dir("package-uri");
    std::fs::create_dir_all(dir.join("my_robot_pkg/meshes")).unwrap();
    write_cube_stl(&dir.join("my_robot_pkg/meshes/cube.stl"));
    let urdf = r#"<robot name="r">
        <link name="base">
          <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
          <collision><geometry><mesh filename="package://my_robot_pkg/meshes/cube.stl" scale="0.2 0.2 0.2"/></geometry></collision>
        </link>
      </robot>"#;
    let model = load_str(urdf, &UrdfOptions::floating()).unwrap();
    // Not found without search paths.
    let err = CollisionWorld::new(CollisionOptions::default())
        .add_model(&model, &MeshOptions::default())
        .unwrap_err();
    match err {
        CollisionError::MeshNotFound { link, uri, .. } => {
            assert_eq!(link, "base");
            assert_eq!(uri, "package://my_robot_pkg/meshes/cube.stl");
        }
        e => panic!("unexpected {e}"),
    }
    // Found with the package's parent, or the package itself, as a search path.
    for search in [dir.clone(), dir.join("my_robot_pkg")] {
        let mut world = CollisionWorld::new(CollisionOptions::default());
        let opts =
            MeshOptions { search_paths: vec![PathBuf::from("/nonexistent"), search], ..Default::default() };
        let mb = world.add_model(&model, &opts).unwrap();
        assert_eq!(world.colliders().len(), 1);
        assert_eq!(world.colliders()[0].kind(), ShapeKind::ConvexHull);
        world
            .add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), &opts)
            .unwrap();
        let mut data = Data::new(&model);
        let mut q = model.neutral_configuration();
        set_free_pose(&model, &mut q, 1, &Transform::from_translation(v3(0.0, 0.0, 0.099)));
        forward_kinematics(&model, &mut data, &q).unwrap();
        world.update_multibody(mb, &data).unwrap();
        let got: Vec<Expected> = world.detect().iter().map(as_expected).collect();
        let want: Vec<Expected> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .iter()
            .map(|(x, y)| (v3(0.1 * x, 0.1 * y, -1e-3), v3(0.1 * x, 0.1 * y, 0.0), Vec3::z(), -1e-3))
            .collect();
        assert_same_contacts(&got, &want, TOL, "package mesh cube on the ground");
    }
    let _ = std::fs::remove_dir_all(dir);
}

// ---------------------------------------------------------------------------------------------
// 10. Bad input
// ---------------------------------------------------------------------------------------------

/// The error of adding a model whose one free body carries `shape`; the world stays empty.
fn body_shape_error(shape: Shape) -> CollisionError {
    let model = ModelBuilder::new().add_body(free_body("bad_link", shape)).build().unwrap();
    let mut world = CollisionWorld::new(CollisionOptions::default());
    let err = world.add_model(&model, &MeshOptions::default()).expect_err("the shape must be refused");
    assert!(world.colliders().is_empty());
    // The failed call left no half-registered multibody behind.
    let good =
        ModelBuilder::new().add_body(free_body("good", Shape::Sphere { radius: 0.1 })).build().unwrap();
    assert_eq!(world.add_model(&good, &MeshOptions::default()).unwrap(), 0);
    err
}

fn static_shape_error(shape: Shape) -> CollisionError {
    let mut world = CollisionWorld::new(CollisionOptions::default());
    let err = world
        .add_static("bad_static", &shape, Transform::identity(), &MeshOptions::default())
        .expect_err("refused");
    assert!(world.colliders().is_empty());
    err
}

#[track_caller]
fn assert_invalid(err: CollisionError, name: &str, says: &str) {
    match &err {
        CollisionError::InvalidShape { link, what } => {
            assert_eq!(link, name);
            assert!(what.contains(says), "message `{what}` should mention `{says}`");
        }
        e => panic!("expected InvalidShape for {name}, got {e:?}"),
    }
    assert!(err.to_string().contains(name));
}

#[test]
fn invalid_shapes_are_typed_errors() {
    let nan = f64::NAN;
    let bad = [
        (Shape::Box { size: v3(0.1, 0.0, 0.1) }, "size y"),
        (Shape::Box { size: v3(-0.1, 0.1, 0.1) }, "size x"),
        (Shape::Box { size: v3(0.1, 0.1, nan) }, "size z"),
        (Shape::Sphere { radius: 0.0 }, "radius"),
        (Shape::Sphere { radius: nan }, "radius"),
        (Shape::Sphere { radius: f64::INFINITY }, "radius"),
        (Shape::Capsule { radius: -0.1, length: 0.3 }, "radius"),
        (Shape::Capsule { radius: 0.1, length: nan }, "length"),
        (Shape::Cylinder { radius: 0.1, length: 0.0 }, "length"),
        (Shape::Cylinder { radius: nan, length: 0.2 }, "radius"),
        (Shape::ConvexHull { points: vec![Vec3::zeros(), Vec3::x(), Vec3::y()] }, "at least 4"),
        (
            Shape::ConvexHull { points: vec![Vec3::zeros(), Vec3::x(), Vec3::y(), v3(0.0, 0.0, nan)] },
            "not finite",
        ),
        (Shape::Mesh { uri: "/tmp/whatever.stl".into(), scale: v3(1.0, 0.0, 1.0) }, "scale"),
        (Shape::Mesh { uri: "/tmp/whatever.stl".into(), scale: v3(1.0, nan, 1.0) }, "scale"),
        (Shape::HalfSpace { normal: Vec3::z() }, "half-space"),
    ];
    for (shape, says) in &bad {
        assert_invalid(body_shape_error(shape.clone()), "bad_link", says);
        if !matches!(shape, Shape::HalfSpace { .. }) {
            assert_invalid(static_shape_error(shape.clone()), "bad_static", says);
        }
    }
    // Coplanar hull points (a rotated, translated square with an interior point).
    let r = rot(v3(0.3, 0.4, 0.5), 0.7);
    let square: Vec<Vec3> = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.3, 0.6)]
        .iter()
        .map(|(x, y)| r * v3(*x, *y, 0.0) + v3(2.0, -1.0, 0.5))
        .collect();
    assert_invalid(body_shape_error(Shape::ConvexHull { points: square.clone() }), "bad_link", "coplanar");
    assert_invalid(static_shape_error(Shape::ConvexHull { points: square }), "bad_static", "coplanar");
    let collinear: Vec<Vec3> = (0..6).map(|i| v3(1.0, 2.0, 3.0) * i as f64).collect();
    assert_invalid(body_shape_error(Shape::ConvexHull { points: collinear }), "bad_link", "coplanar");
    // Half-spaces: zero or NaN normal.
    assert_invalid(static_shape_error(Shape::HalfSpace { normal: Vec3::zeros() }), "bad_static", "normal");
    assert_invalid(
        static_shape_error(Shape::HalfSpace { normal: v3(0.0, nan, 1.0) }),
        "bad_static",
        "normal",
    );
    // Heightfields: too few samples, NaN heights, non-positive extent.
    let hf = |heights: DMatrix<f64>, sx: f64| Shape::HeightField { heights, size_x: sx, size_y: 1.0 };
    assert_invalid(static_shape_error(hf(DMatrix::zeros(1, 3), 1.0)), "bad_static", "2×2");
    assert_invalid(static_shape_error(hf(DMatrix::from_element(3, 3, nan), 1.0)), "bad_static", "not finite");
    assert_invalid(static_shape_error(hf(DMatrix::zeros(3, 3), 0.0)), "bad_static", "size_x");
    // Triangle meshes: no triangle, an index beyond the vertices, a NaN vertex.
    let tri = |vertices: Vec<Vec3>, triangles: Vec<[u32; 3]>| Shape::TriMesh { vertices, triangles };
    let three = vec![Vec3::zeros(), Vec3::x(), Vec3::y()];
    assert_invalid(static_shape_error(tri(three.clone(), vec![])), "bad_static", "triangle");
    assert_invalid(static_shape_error(tri(three.clone(), vec![[0, 1, 3]])), "bad_static", "beyond");
    assert_invalid(
        static_shape_error(tri(vec![Vec3::zeros(), Vec3::x(), v3(nan, 0.0, 0.0)], vec![[0, 1, 2]])),
        "bad_static",
        "not finite",
    );
}

#[test]
fn half_space_on_a_moving_body_is_refused() {
    assert_invalid(body_shape_error(Shape::HalfSpace { normal: Vec3::z() }), "bad_link", "static");
    let model = ModelBuilder::new().add_body(free_body("b", Shape::Sphere { radius: 0.1 })).build().unwrap();
    let mut world = CollisionWorld::new(CollisionOptions::default());
    let mb = world.add_model(&model, &MeshOptions::default()).unwrap();
    let plane = Shape::HalfSpace { normal: Vec3::z() };
    let err = world
        .add_body_collider(mb, 1, "floor", &plane, Transform::identity(), &MeshOptions::default())
        .unwrap_err();
    assert_invalid(err, "floor", "static");
    // On body 0 (the multibody's universe) a half-space is static geometry and accepted.
    world.add_body_collider(mb, 0, "floor", &plane, Transform::identity(), &MeshOptions::default()).unwrap();
    // Out-of-range indices.
    assert!(matches!(
        world.add_body_collider(
            mb,
            2,
            "x",
            &Shape::Sphere { radius: 0.1 },
            Transform::identity(),
            &MeshOptions::default()
        ),
        Err(CollisionError::IndexOutOfRange { what: "bodies", index: 2, count: 2 })
    ));
    assert!(matches!(
        world.add_body_collider(
            3,
            1,
            "x",
            &Shape::Sphere { radius: 0.1 },
            Transform::identity(),
            &MeshOptions::default()
        ),
        Err(CollisionError::IndexOutOfRange { what: "multibodies", index: 3, count: 1 })
    ));
}

#[test]
fn unreadable_mesh_files_are_typed_errors() {
    let dir = temp_dir("garbage-meshes");
    let files: [(&str, &[u8]); 6] = [
        ("garbage.stl", b"this is definitely not a mesh\n"),
        ("empty.stl", b""),
        ("garbage.obj", &[0xff, 0xfe, 0x00, 0x13, 0x37, 0x80, 0x81, 0x0a, 0x66, 0x20, 0x39, 0x0a]),
        ("faces_only.obj", b"f 1 2 3\nf 4 5 6\n"),
        ("garbage.dae", b"<COLLADA><unclosed"),
        ("solid.stl", b"solid broken\n  facet normal 0 0 1\n    outer loop\n      vertex 0 0 oops\n"),
    ];
    for (name, bytes) in files {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let shape = Shape::Mesh { uri: path.display().to_string(), scale: v3(1.0, 1.0, 1.0) };
        for err in [body_shape_error(shape.clone()), static_shape_error(shape.clone())] {
            match err {
                CollisionError::MeshUnreadable { link, path: p, message } => {
                    assert!(link == "bad_link" || link == "bad_static");
                    assert!(p.ends_with(name), "{p}");
                    assert!(!message.is_empty());
                }
                e => panic!("{name}: expected MeshUnreadable, got {e:?}"),
            }
        }
        // Skipping drops it with a warning.
        let model = ModelBuilder::new().add_body(free_body("skipped", shape)).build().unwrap();
        let mut world = CollisionWorld::new(CollisionOptions::default());
        let skip = MeshOptions { missing: MissingMeshPolicy::Skip, ..Default::default() };
        let mb = world.add_model(&model, &skip).unwrap();
        assert!(world.colliders_of(mb).is_empty(), "{name}");
        assert_eq!(world.warnings().len(), 1, "{name}");
        assert!(world.warnings()[0].contains("skipped") && world.warnings()[0].contains(name));
    }
    // A readable but flat mesh: no convex hull on a body, a valid triangle mesh as static geometry.
    let flat = dir.join("flat.obj");
    std::fs::write(&flat, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n").unwrap();
    let shape = Shape::Mesh { uri: flat.display().to_string(), scale: v3(1.0, 1.0, 1.0) };
    assert_invalid(body_shape_error(shape.clone()), "bad_link", "coplanar");
    let mut world = CollisionWorld::new(CollisionOptions::default());
    let c = world.add_static("floor", &shape, Transform::identity(), &MeshOptions::default()).unwrap();
    assert_eq!(world.colliders()[c].kind(), ShapeKind::TriMesh);
    // A missing file.
    let shape = Shape::Mesh { uri: dir.join("absent.stl").display().to_string(), scale: v3(1.0, 1.0, 1.0) };
    assert!(
        matches!(body_shape_error(shape), CollisionError::MeshNotFound { link, .. } if link == "bad_link")
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn non_finite_poses_and_mismatched_data_are_typed_errors() {
    let model = ModelBuilder::new().add_body(free_body("b", Shape::Sphere { radius: 0.1 })).build().unwrap();
    let mut world = CollisionWorld::new(CollisionOptions::default());
    let mb = world.add_model(&model, &MeshOptions::default()).unwrap();
    let mut data = Data::new(&model);
    data.x_wb[1].translation.x = f64::NAN;
    assert!(
        matches!(world.update_multibody(mb, &data), Err(CollisionError::NonFinitePose { collider }) if collider == "b")
    );
    let two = ModelBuilder::new()
        .add_body(free_body("b", Shape::Sphere { radius: 0.1 }))
        .add_body(free_body("c", Shape::Sphere { radius: 0.1 }))
        .build()
        .unwrap();
    assert!(matches!(
        world.update_multibody(mb, &Data::new(&two)),
        Err(CollisionError::DataMismatch { multibody: 0, expected: 2, got: 3 })
    ));
    assert!(matches!(world.update_multibody(1, &data), Err(CollisionError::IndexOutOfRange { .. })));
    // Detection still works afterwards.
    assert!(world.detect().is_empty());
}

// ---------------------------------------------------------------------------------------------
// 11. Heightfields
// ---------------------------------------------------------------------------------------------

/// A heightfield over [−sx/2, sx/2] × [−sy/2, sy/2] with `nx`×`ny` samples of `height(x, y)`.
fn heightfield_grid(nx: usize, ny: usize, sx: f64, sy: f64, height: impl Fn(f64, f64) -> f64) -> Shape {
    let at = |i: usize, n: usize, size: f64| -size / 2.0 + i as f64 * size / (n - 1) as f64;
    Shape::HeightField {
        heights: DMatrix::from_fn(nx, ny, |i, j| height(at(i, nx, sx), at(j, ny, sy))),
        size_x: sx,
        size_y: sy,
    }
}

fn heightfield(n: usize, size: f64, height: impl Fn(f64, f64) -> f64) -> Shape {
    heightfield_grid(n, n, size, size, height)
}

/// The contact of a sphere of radius `r` whose centre is `r + gap` from the plane through `foot`
/// with unit normal `n`.
fn sphere_on_plane(foot: Vec3, n: Vec3, r: f64, gap: f64) -> (Vec3, Expected) {
    let centre = foot + n * (r + gap);
    (centre, (centre - n * r, foot, n, gap))
}

#[test]
fn sphere_on_a_flat_heightfield() {
    let r = 0.1;
    // One cell, and a 21×21 grid of 0.2 m cells with the sphere far from every triangle edge.
    for (n, xy, radius) in [(2, (1.0, 0.1), r), (21, (0.5, 0.235), 0.05)] {
        for gap in [-1e-3, 0.0, 2e-3] {
            let foot = v3(xy.0, xy.1, 0.3);
            let (centre, want) = sphere_on_plane(foot, Vec3::z(), radius, gap);
            let mut s = Scene::new();
            s.body("ball", Shape::Sphere { radius }, Transform::from_translation(centre));
            s.fixed("terrain", heightfield(n, 4.0, |_, _| 0.3), Transform::identity());
            let got: Vec<Expected> = s.detect().iter().map(as_expected).collect();
            assert_same_contacts(&got, &[want], TOL, &format!("flat heightfield {n}×{n}, gap {gap}"));
            close_f(got[0].3, centre.z - radius - 0.3, TOL, "distance = z − r − 0.3");
        }
    }
    // A flat field at height 0 placed 0.3 m up and yawed gives the same contact.
    let (centre, want) = sphere_on_plane(v3(1.0, 0.1, 0.3), Vec3::z(), r, -1e-3);
    let mut s = Scene::new();
    s.body("ball", Shape::Sphere { radius: r }, Transform::from_translation(centre));
    s.fixed(
        "terrain",
        heightfield(2, 4.0, |_, _| 0.0),
        Transform::new(rot(Vec3::z(), 0.2), v3(0.0, 0.0, 0.3)),
    );
    let got: Vec<Expected> = s.detect().iter().map(as_expected).collect();
    assert_same_contacts(&got, &[want], TOL, "placed heightfield");
}

#[test]
fn sloped_heightfields_tilt_the_normal() {
    let (r, theta) = (0.1, deg(20.0));
    let t = theta.tan();
    // heights = x tan θ: normal (−sin θ, 0, cos θ); heights = y tan θ: normal (0, −sin θ, cos θ).
    type Height = Box<dyn Fn(f64, f64) -> f64>;
    let slopes: [(&str, Height, Vec3); 4] = [
        ("x", Box::new(move |x, _| x * t), v3(-theta.sin(), 0.0, theta.cos())),
        ("y", Box::new(move |_, y| y * t), v3(0.0, -theta.sin(), theta.cos())),
        ("-x", Box::new(move |x, _| -x * t), v3(theta.sin(), 0.0, theta.cos())),
        ("-y", Box::new(move |_, y| 0.2 - y * t), v3(0.0, theta.sin(), theta.cos())),
    ];
    for (name, height, n) in &slopes {
        // One cell; 1 m cells; a non-square grid of 2 m × 0.5 m cells.
        for (nx, ny, sx, sy, xy) in
            [(2, 2, 4.0, 4.0, (1.0, 0.05)), (5, 5, 4.0, 4.0, (0.5, 0.27)), (3, 5, 4.0, 2.0, (0.7, 0.23))]
        {
            let foot = v3(xy.0, xy.1, height(xy.0, xy.1));
            let (centre, want) = sphere_on_plane(foot, *n, r, -1e-3);
            let mut s = Scene::new();
            s.body("ball", Shape::Sphere { radius: r }, Transform::from_translation(centre));
            s.fixed("terrain", heightfield_grid(nx, ny, sx, sy, height), Transform::identity());
            let (mins, maxs) = s.world.colliders()[1].aabb();
            close(Vec3::from(mins).xy().push(0.0), v3(-sx / 2.0, -sy / 2.0, 0.0), TOL, "terrain box");
            close(Vec3::from(maxs).xy().push(0.0), v3(sx / 2.0, sy / 2.0, 0.0), TOL, "terrain box");
            let got: Vec<Expected> = s.detect().iter().map(as_expected).collect();
            assert_same_contacts(&got, &[want], TOL, &format!("slope along {name}, {nx}×{ny} samples"));
            close_f(got[0].2.dot(&Vec3::z()).acos(), theta, 1e-9, "tilt of the normal");
        }
    }
    // A box resting on the slope along x, aligned with it: four corners.
    let size = v3(0.4, 0.3, 0.2);
    let r_box = rot(Vec3::y(), -theta);
    let n = slopes[0].2;
    let centre = v3(0.5, 0.2, 0.5 * t) + n * (size.z / 2.0 - 1e-3);
    let mut s = Scene::new();
    s.body("box", Shape::Box { size }, Transform::new(r_box, centre));
    s.fixed("terrain", heightfield(2, 4.0, |x, _| x * t), Transform::identity());
    let contacts = s.detect();
    assert!(!contacts.is_empty());
    for c in &contacts {
        close(c.normal, n, TOL, "box on slope: normal");
        close_f(c.distance, -1e-3, TOL, "box on slope: distance");
    }
}

/// Resting a sphere 1 mm deep on flat ground `ground` (surface at height `level`) above each
/// point of `places`: the deepest contact must be the exact one, and every contact must push
/// straight up. Returns a description of each contact that does not.
fn tilted_contacts_on_flat_ground(ground: &Shape, level: f64, places: &[(f64, f64)]) -> Vec<String> {
    let r = 0.1;
    let mut bad = Vec::new();
    for &(x, y) in places {
        let (centre, want) = sphere_on_plane(v3(x, y, level), Vec3::z(), r, -1e-3);
        let mut s = Scene::new();
        s.body("ball", Shape::Sphere { radius: r }, Transform::from_translation(centre));
        s.fixed("ground", ground.clone(), Transform::identity());
        let contacts = s.detect();
        let deepest = contacts.iter().min_by(|a, b| a.distance.total_cmp(&b.distance)).expect("a contact");
        assert_same_contacts(
            &[as_expected(deepest)],
            &[want],
            TOL,
            &format!("deepest contact at ({x}, {y})"),
        );
        for c in contacts.iter().filter(|c| (c.normal - Vec3::z()).norm() > 1e-6) {
            bad.push(format!(
                "sphere above ({x}, {y}): extra contact with normal tilted {:.1}° ({:.4?}), distance {:.2e} m",
                c.normal.z.acos().to_degrees(),
                c.normal.as_slice(),
                c.distance
            ));
        }
    }
    bad
}

#[test]
fn flat_heightfield_gives_vertical_normals_near_internal_edges() {
    // 0.2 m cells; sphere centres 1 cm from a cell edge or near a cell diagonal.
    let terrain = heightfield(21, 4.0, |_, _| 0.3);
    let bad =
        tilted_contacts_on_flat_ground(&terrain, 0.3, &[(0.41, 0.13), (0.4, 0.4), (0.39, 0.21), (0.5, 0.51)]);
    assert!(bad.is_empty(), "flat heightfield:\n{}", bad.join("\n"));
}

#[test]
fn flat_static_triangle_mesh_gives_vertical_normals_near_internal_edges() {
    // The same flat ground as a static triangle mesh: a 2×2 grid of 1 m cells.
    let mut vertices = Vec::new();
    for i in 0..3 {
        for j in 0..3 {
            vertices.push(v3(i as f64 - 1.0, j as f64 - 1.0, 0.0));
        }
    }
    let mut triangles = Vec::new();
    for i in 0..2u32 {
        for j in 0..2u32 {
            let (a, b, c, d) = (i * 3 + j, (i + 1) * 3 + j, (i + 1) * 3 + j + 1, i * 3 + j + 1);
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    let ground = Shape::TriMesh { vertices, triangles };
    // Far from every edge; 2 cm from the edge x = 0; 1 cm from the diagonal x = y.
    let bad = tilted_contacts_on_flat_ground(&ground, 0.0, &[(0.5, 0.2), (0.02, 0.3), (0.3, 0.31)]);
    assert!(bad.is_empty(), "flat static triangle mesh:\n{}", bad.join("\n"));
}

// ---------------------------------------------------------------------------------------------
// 12. Cylinders
// ---------------------------------------------------------------------------------------------

#[test]
fn cylinder_lying_on_its_side_touches_along_a_line() {
    let (r, length, depth) = (0.1, 0.4, 1e-3);
    for yaw in [0.0, 0.4, -1.9] {
        let rotation = rot(Vec3::z(), yaw) * rot(Vec3::x(), deg(90.0));
        let centre = v3(0.3, -0.2, r - depth);
        let mut s = Scene::new();
        s.body("roller", Shape::Cylinder { radius: r, length }, Transform::new(rotation, centre));
        s.fixed("ground", Shape::HalfSpace { normal: Vec3::z() }, Transform::identity());
        let axis = rotation * Vec3::z();
        let want: Vec<Expected> = [-0.5, 0.5]
            .iter()
            .map(|t| {
                let p = centre + axis * (t * length) - Vec3::z() * r;
                (p, v3(p.x, p.y, 0.0), Vec3::z(), -depth)
            })
            .collect();
        let got: Vec<Expected> = s.detect().iter().map(as_expected).collect();
        assert_same_contacts(&got, &want, TOL, &format!("lying cylinder, yaw {yaw}"));
    }
}

#[test]
fn upright_cylinder_touches_on_its_rim() {
    let (r, length, depth) = (0.1, 0.4, 1e-3);
    for yaw in [0.0, 0.4, 2.2] {
        let x = Transform::new(rot(Vec3::z(), yaw), v3(0.3, -0.2, length / 2.0 - depth));
        let mut s = Scene::new();
        s.body("can", Shape::Cylinder { radius: r, length }, x);
        s.fixed("ground", Shape::HalfSpace { normal: Vec3::z() }, Transform::identity());
        // The collider's reported pose and box are those of the z-up geometry.
        let collider = &s.world.colliders()[0];
        assert_eq!(collider.kind(), ShapeKind::Cylinder);
        let pose = collider.world_pose();
        close(pose.translation, x.translation, TOL, "cylinder pose");
        assert!((pose.rotation - x.rotation).amax() < TOL, "cylinder rotation {:?}", pose.rotation);
        let (mins, maxs) = collider.aabb();
        close_f(maxs[2] - mins[2], length, TOL, "cylinder box height");
        close_f(maxs[0] - mins[0], 2.0 * r, TOL, "cylinder box width");
        let contacts = s.detect();
        assert!((3..=4).contains(&contacts.len()), "{contacts:#?}");
        let mut centroid = Vec3::zeros();
        for c in &contacts {
            close(c.normal, Vec3::z(), TOL, "normal");
            close_f(c.distance, -depth, TOL, "distance");
            close_f(c.point_a.z, -depth, TOL, "rim height");
            let radial = c.point_a - x.translation;
            close_f(v3(radial.x, radial.y, 0.0).norm(), r, TOL, "on the rim");
            close(c.point_b, v3(c.point_a.x, c.point_a.y, 0.0), TOL, "point_b on the ground");
            centroid += c.point_a / contacts.len() as f64;
        }
        // The points surround the axis (a stable support).
        assert!(v3(centroid.x - x.translation.x, centroid.y - x.translation.y, 0.0).norm() < r / 2.0);
    }
}

// ---------------------------------------------------------------------------------------------
// Convex hulls with many-sided faces, collider placements, contact features
// ---------------------------------------------------------------------------------------------

/// The least, over horizontal directions u, of the largest u·(p − c) over the points: positive
/// when c lies inside the points' convex hull (in xy), and then its distance to the boundary.
fn support_depth(points: &[Vec3], c: Vec3) -> f64 {
    (0..3600)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 3600.0;
            let u = v3(a.cos(), a.sin(), 0.0);
            points.iter().map(|p| u.dot(&(p - c))).fold(f64::NEG_INFINITY, f64::max)
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn convex_hull_prism_resting_on_a_face_is_supported_around_its_centre() {
    // A right prism over a regular polygon of circumradius R (a typical mesh foot or puck),
    // resting flat 1 mm deep. Four well-chosen vertices of its base put the centre at least
    // R/4 inside the support polygon (R cos 72° ≈ 0.31 R for a pentagon, R/√2 for an octagon).
    let (radius, height, depth) = (0.1, 0.1, 1e-3);
    let mut failures = Vec::new();
    for sides in [5usize, 6, 8, 12] {
        let mut points = Vec::new();
        for k in 0..sides {
            let a = (k as f64 + 0.5) * std::f64::consts::TAU / sides as f64;
            for z in [-height / 2.0, height / 2.0] {
                points.push(v3(radius * a.cos(), radius * a.sin(), z));
            }
        }
        let centre = v3(0.2, -0.1, height / 2.0 - depth);
        let hull = Shape::ConvexHull { points };
        let supports: [(&str, Shape, Transform); 2] = [
            ("half-space", Shape::HalfSpace { normal: Vec3::z() }, Transform::identity()),
            ("box", Shape::Box { size: v3(2.0, 2.0, 0.2) }, Transform::from_translation(v3(0.0, 0.0, -0.1))),
        ];
        for (name, support, pose) in supports {
            let mut s = Scene::new();
            s.body("prism", hull.clone(), Transform::from_translation(centre));
            s.fixed(name, support, pose);
            let contacts = s.detect();
            assert!(!contacts.is_empty());
            for c in &contacts {
                close(c.normal, Vec3::z(), TOL, "normal");
                close_f(c.distance, -depth, TOL, "distance");
                close_f(c.point_a.z, -depth, TOL, "on the base");
            }
            let points: Vec<Vec3> = contacts.iter().map(|c| c.point_a).collect();
            let inside = support_depth(&points, centre);
            if inside < radius / 4.0 {
                let angles: Vec<f64> = points
                    .iter()
                    .map(|p| (p.y - centre.y).atan2(p.x - centre.x).to_degrees().round())
                    .collect();
                failures.push(format!(
                    "{sides}-sided prism on a {name}: centre {inside:.4} m inside the support polygon \
                     (want ≥ {:.4}); contact azimuths {angles:?}°",
                    radius / 4.0
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn collider_placements_in_the_body_frame_move_the_contacts() {
    let placement = Transform::from_xyz_rpy([0.1, -0.05, 0.02], [0.3, -0.2, 0.5]);
    let body = Transform::new(rot(v3(0.2, 0.3, -1.0), 0.8), v3(0.3, 0.1, 0.0));
    let hull_points: Vec<Vec3> = (0..8)
        .map(|i| {
            v3(
                if i & 1 != 0 { 0.1 } else { -0.1 },
                if i & 2 != 0 { 0.07 } else { -0.07 },
                if i & 4 != 0 { 0.05 } else { -0.05 },
            )
        })
        .collect();
    let shapes = [
        Shape::Box { size: v3(0.2, 0.14, 0.1) },
        Shape::Cylinder { radius: 0.06, length: 0.2 },
        Shape::Capsule { radius: 0.05, length: 0.15 },
        Shape::ConvexHull { points: hull_points },
        Shape::Sphere { radius: 0.08 },
    ];
    let n = v3(0.1, 0.2, 1.0).normalize();
    for shape in &shapes {
        // Lower the geometry until its lowest point is 1 mm below a tilted ground through the origin.
        let x_geom = body * placement;
        // The lowest point along n: point_a of the contacts with a ground 10 m below, seen with
        // a 20 m margin.
        let lowest = {
            let mut far = Scene::with_options(CollisionOptions { margin: 20.0, ..Default::default() });
            far.body("probe", shape.clone(), x_geom);
            far.fixed("far", Shape::HalfSpace { normal: n }, Transform::from_translation(-n * 10.0));
            far.world.detect().iter().map(|c| n.dot(&c.point_a)).fold(f64::INFINITY, f64::min)
        };
        let lift = Transform::from_translation(-n * (lowest + 1e-3));
        let scenes = |placed: bool| {
            let mut s = Scene::new();
            if placed {
                s.placed_body("probe", shape.clone(), placement, lift * body);
            } else {
                s.body("probe", shape.clone(), lift * body * placement);
            }
            s.fixed("ground", Shape::HalfSpace { normal: n }, Transform::identity());
            s.fixed(
                "block",
                Shape::Box { size: v3(0.3, 0.3, 0.3) },
                Transform::from_translation((lift * body * placement).translation + v3(0.23, 0.0, 0.0)),
            );
            let pose = s.world.colliders()[0].world_pose();
            (s.detect().iter().map(as_expected).collect::<Vec<_>>(), pose)
        };
        let (placed, pose) = scenes(true);
        let (direct, _) = scenes(false);
        let want = lift * body * placement;
        close(pose.translation, want.translation, TOL, "collider pose");
        assert!((pose.rotation - want.rotation).amax() < TOL);
        assert!(
            placed.iter().any(|c| (c.2 - n).norm() < TOL && (c.3 + 1e-3).abs() < TOL),
            "{shape:?} touches the ground"
        );
        assert_same_contacts(&placed, &direct, TOL, &format!("{shape:?} placed in its body"));
    }
}

#[test]
fn features_identify_contacts_across_steps() {
    let scenes: [(&str, Shape, Transform, Shape, Transform); 3] = [
        (
            "box on ground",
            Shape::Box { size: v3(0.4, 0.3, 0.2) },
            Transform::new(rot(Vec3::z(), 0.3), v3(0.0, 0.0, 0.099)),
            Shape::HalfSpace { normal: Vec3::z() },
            Transform::identity(),
        ),
        (
            "box on box",
            Shape::Box { size: v3(0.2, 0.2, 0.2) },
            Transform::new(rot(Vec3::z(), 0.3), v3(0.0, 0.0, 0.099)),
            Shape::Box { size: v3(1.0, 1.0, 0.2) },
            Transform::from_translation(v3(0.0, 0.0, -0.1)),
        ),
        (
            "cylinder on ground",
            Shape::Cylinder { radius: 0.1, length: 0.3 },
            Transform::new(rot(Vec3::x(), deg(90.0)), v3(0.0, 0.0, 0.099)),
            Shape::HalfSpace { normal: Vec3::z() },
            Transform::identity(),
        ),
    ];
    for (name, shape, x, support, pose) in scenes {
        let mut s = Scene::new();
        let mb = s.body("probe", shape, x);
        s.fixed("support", support, pose);
        let mut first: Vec<u64> = s.detect().iter().map(|c| c.feature).collect();
        first.sort();
        let count = first.len();
        first.dedup();
        assert_eq!(first.len(), count, "{name}: features are distinct within a pair");
        // Sliding by 0.1 mm keeps the same features.
        s.place(mb, Transform::new(x.rotation, x.translation + v3(1e-4, -5e-5, 0.0)));
        let mut second: Vec<u64> = s.detect().iter().map(|c| c.feature).collect();
        second.sort();
        assert_eq!(second, first, "{name}: features after a small motion");
    }
}

// ---------------------------------------------------------------------------------------------
// Reuse of a resting pair's manifolds
// ---------------------------------------------------------------------------------------------

/// A pair that moved less than `CollisionOptions::reuse` allows keeps its contact points and
/// refreshes their distances: the same distances as a fresh detection to 1e-12 m (the motion's
/// second order is far below that), and beyond the bounds the manifolds are computed again.
/// Body on body too, with the pair moved as a whole (the relative pose decides).
#[test]
fn a_pair_that_hardly_moved_refreshes_its_contacts() {
    let cases = [
        (
            "box on ground",
            Shape::Box { size: v3(0.3, 0.2, 0.1) },
            Transform::new(rot(v3(0.2, 0.1, 1.0), 0.4), v3(0.1, 0.0, 0.0499)),
            Shape::HalfSpace { normal: Vec3::z() },
            None,
        ),
        (
            "capsule on a box body",
            Shape::Capsule { radius: 0.05, length: 0.3 },
            // Tilted by 3°: its lower end on the box (lying parallel, parry's extra closest
            // point comes and goes with rounding, 2 or 3 points).
            Transform::new(rot(Vec3::x(), deg(87.0)), v3(0.0, 0.02, 0.1499 + 0.15 * deg(3.0).sin())),
            Shape::Box { size: v3(1.0, 1.0, 0.2) },
            Some(Transform::identity()),
        ),
    ];
    for (name, shape, x, support, support_pose) in cases {
        let build = |x: Transform, reuse: bool| {
            let options = CollisionOptions { reuse: reuse.then(Default::default), ..Default::default() };
            let mut s = Scene::with_options(options);
            let mb = s.body("probe", shape.clone(), x);
            match support_pose {
                Some(pose) => {
                    s.body("support", support.clone(), pose);
                }
                None => {
                    s.fixed("support", support.clone(), Transform::identity());
                }
            }
            (s, mb)
        };
        let (mut s, mb) = build(x, true);
        let first = s.detect();
        assert!(!first.is_empty(), "{name}: no contacts");
        assert_eq!(s.world.stats().refreshed_pairs, 0, "{name}: the first detection computes");
        // Within the default bounds (1e-8 m, 1e-7 rad).
        let nudged =
            Transform::new(rot(v3(1.0, -0.5, 0.3), 5e-8) * x.rotation, x.translation + v3(4e-9, -3e-9, 5e-9));
        s.place(mb, nudged);
        let refreshed: Vec<Expected> = s.detect().iter().map(as_expected).collect();
        assert_eq!(s.world.stats().refreshed_pairs, 1, "{name}: a nudged pair is refreshed");
        let (mut fresh_scene, _) = build(nudged, false);
        let fresh: Vec<Expected> = fresh_scene.detect().iter().map(as_expected).collect();
        // The distance is exact to second order in the motion. The points are A's material
        // points, where a fresh detection takes the closest ones: on a curved surface those
        // move by the turn times the radius (5e-8 rad × 0.05 m); the normal turned with A (by
        // at most the 1e-7 rad bound), and B's point lies on it.
        assert_eq!(refreshed.len(), fresh.len(), "{name}: contact count");
        for f in &fresh {
            let r =
                refreshed.iter().min_by(|a, b| (a.0 - f.0).norm().total_cmp(&(b.0 - f.0).norm())).unwrap();
            close(r.0, f.0, 1e-8, &format!("{name}: point_a"));
            close(r.1, f.1, 1e-8, &format!("{name}: point_b"));
            close(r.2, f.2, 1e-7, &format!("{name}: normal"));
            close_f(r.3, f.3, 1e-12, &format!("{name}: distance"));
        }
        // Beyond them: computed again.
        s.place(mb, Transform::new(x.rotation, x.translation + v3(0.0, 0.0, -2e-8)));
        s.detect();
        assert_eq!(s.world.stats().refreshed_pairs, 0, "{name}: a pair moved by 2e-8 m is computed again");
    }
}
