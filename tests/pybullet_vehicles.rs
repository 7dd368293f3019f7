//! PyBullet's vehicles (`models/pybullet/`: racecar.urdf with steering hinges, racecar_differential.urdf
//! with its rear wheels on a differential's ring, husky.urdf skid-steered) driven through
//! `gelenk::vehicle` on flat ground (μ = 1): a commanded speed is reached within 5 % in a straight
//! line, and at a steering command the tracking point circles on the predicted radius L / tan δ
//! within 15 % (the bicycle model for the cars; for the skid-steered husky, the radius its wheel
//! speeds command, which its sideways-slipping wheels widen).

use gelenk::constraints::ContactParameters;
use gelenk::io::urdf::{self, UrdfOptions};
use gelenk::math::{Transform, Vec3};
use gelenk::model::Shape;
use gelenk::vehicle::{Vehicle, VehicleConfig};
use gelenk::world::{World, WorldOptions};
use std::path::Path;

/// A world with the vehicle of `file` (under models/pybullet/) standing on a plane of friction 1,
/// its chassis frame placed so that the wheels of radius `config.wheel_radius` touch the plane.
fn vehicle_world(file: &str, config: VehicleConfig) -> (World, Vehicle) {
    let mut options = WorldOptions {
        contact: ContactParameters { mu: 1.0, ..ContactParameters::default() },
        ..WorldOptions::default()
    };
    options.sleep.enabled = false;
    options.dt = 0.002;
    let mut world = World::new(options);
    world.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0).unwrap();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/pybullet").join(file);
    let model = urdf::load_file(path, &UrdfOptions::floating()).unwrap();
    let index = world.add_multibody("car", model, &Default::default()).unwrap();
    let radius = config.wheel_radius;
    let mut vehicle = Vehicle::attach(&mut world, index, config).unwrap();
    let mount_z = vehicle.rear_axle_center().z;
    let q = &mut world.multibody_mut(index).state.q;
    q[2] = radius - mount_z + 1e-3;
    vehicle.coast(&mut world);
    (world, vehicle)
}

fn run(world: &mut World, seconds: f64) {
    for _ in 0..(seconds / world.options().dt).round() as usize {
        world.step().unwrap();
    }
}

/// Velocity of the tracking point along the chassis x axis (m/s).
fn tracking_speed(world: &World, vehicle: &Vehicle) -> f64 {
    let mb = world.multibody(vehicle.multibody());
    let v = &mb.state.v;
    // Free joint: [v; ω] of the chassis frame in chassis axes; v_p = v + ω × p.
    let (lin, ang) = (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]));
    (lin + ang.cross(&vehicle.tracking_point())).x
}

/// Reaches `speed` within 5 % and keeps its heading within 0.05 rad over `seconds`.
fn reaches_speed(file: &str, config: VehicleConfig, speed: f64, seconds: f64) {
    let (mut world, mut vehicle) = vehicle_world(file, config);
    run(&mut world, 0.5);
    let heading = vehicle.heading(&world);
    vehicle.set_speed(&mut world, speed).unwrap();
    run(&mut world, seconds);
    let v = tracking_speed(&world, &vehicle);
    let turned = vehicle.heading(&world) - heading;
    println!("{file}: speed {v} m/s (commanded {speed}), heading change {turned} rad");
    assert!((v - speed).abs() < 0.05 * speed, "{file}: speed {v} m/s, commanded {speed}");
    assert!(turned.abs() < 0.05, "{file}: heading changed by {turned} rad driving straight");
}

/// Fits a circle to points in the plane (Kåsa's algebraic least squares): returns the radius.
fn fit_radius(points: &[(f64, f64)]) -> f64 {
    let mut a = nalgebra::Matrix3::zeros();
    let mut b = nalgebra::Vector3::zeros();
    for &(x, y) in points {
        let row = nalgebra::Vector3::new(x, y, 1.0);
        a += row * row.transpose();
        b -= row * (x * x + y * y);
    }
    let s = a.lu().solve(&b).expect("points not collinear");
    let (cx, cy) = (-s[0] / 2.0, -s[1] / 2.0);
    (cx * cx + cy * cy - s[2]).sqrt()
}

/// Circles at steering `delta` and `speed` on the predicted radius within 15 %; returns the
/// measured radius and the prediction.
fn circles(file: &str, config: VehicleConfig, speed: f64, delta: f64) -> (f64, f64) {
    let (mut world, mut vehicle) = vehicle_world(file, config);
    run(&mut world, 0.5);
    vehicle.set_steering(&mut world, delta).unwrap();
    vehicle.set_speed(&mut world, speed).unwrap();
    run(&mut world, 2.0); // steering and speed settle
    let point = vehicle.tracking_point();
    let mut points = Vec::new();
    for _ in 0..2000 {
        world.step().unwrap();
        let p = vehicle.pose(&world).act_point(&point);
        points.push((p.x, p.y));
    }
    let radius = fit_radius(&points);
    let predicted = vehicle.predicted_radius(delta);
    println!("{file}: radius {radius} m, predicted {predicted} m");
    assert!(
        (radius - predicted).abs() < 0.15 * predicted,
        "{file}: radius {radius} m, predicted {predicted} m"
    );
    (radius, predicted)
}

fn differential() -> VehicleConfig {
    VehicleConfig { rear: ["diff_sideA_ring".into(), "diff_sideB_ring".into()], ..VehicleConfig::racecar() }
}

#[test]
fn racecar_reaches_two_metres_per_second() {
    reaches_speed("racecar/racecar.urdf", VehicleConfig::racecar(), 2.0, 3.0);
}

#[test]
fn racecar_circles_on_the_bicycle_model_radius() {
    circles("racecar/racecar.urdf", VehicleConfig::racecar(), 1.5, 0.3);
}

#[test]
fn racecar_differential_reaches_two_metres_per_second() {
    // The side gears that carry the rear wheels have 60 times a wheel's inertia: 6 s to spin up.
    reaches_speed("racecar/racecar_differential.urdf", differential(), 2.0, 6.0);
}

#[test]
fn racecar_differential_circles_on_the_bicycle_model_radius() {
    circles("racecar/racecar_differential.urdf", differential(), 1.5, 0.3);
}

#[test]
fn husky_reaches_one_metre_per_second() {
    reaches_speed("husky/husky.urdf", VehicleConfig::husky(), 1.0, 3.0);
}

#[test]
fn husky_circles_on_the_commanded_radius() {
    circles("husky/husky.urdf", VehicleConfig::husky(), 1.0, 0.3);
}
