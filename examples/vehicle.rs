//! The buggy of `models/buggy.urdf` driven through `gelenk::vehicle`: it settles on its springs,
//! accelerates to 5 m/s, circles at 20° steering (measured radius against the bicycle model's
//! L / tan δ), and parks on a 20° slope with μ = 1 (holds) and μ = 0.3 (slides).
//!
//! `cargo run --release --example vehicle`

use gelenk::constraints::ContactParameters;
use gelenk::io::urdf::{self, UrdfOptions};
use gelenk::math::{Transform, Vec3};
use gelenk::model::Shape;
use gelenk::vehicle::{Vehicle, VehicleConfig};
use gelenk::world::{World, WorldOptions};
use std::error::Error;
use std::path::Path;
use std::time::Instant;

/// The buggy on a plane of friction `mu` tilted by `slope_deg` (rising along +x), at rest with
/// the wheels touching; sleeping off so that every step is simulated.
fn buggy_world(mu: f64, slope_deg: f64) -> Result<(World, Vehicle), Box<dyn Error>> {
    let mut options = WorldOptions {
        contact: ContactParameters { mu, ..ContactParameters::default() },
        ..WorldOptions::default()
    };
    options.sleep.enabled = false;
    options.time_phases = true; // where the step's time goes, printed below
    let mut world = World::new(options);
    let tilt = Transform::from_xyz_rpy([0.0; 3], [0.0, -slope_deg.to_radians(), 0.0]);
    world.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, tilt, 0)?;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/buggy.urdf");
    let model = urdf::load_file(path, &UrdfOptions::floating())?;
    let index = world.add_multibody("buggy", model, &Default::default())?;
    let pose = tilt * Transform::from_translation(Vec3::new(0.0, 0.0, 0.4));
    let q = &mut world.multibody_mut(index).state.q;
    q.rows_mut(0, 3).copy_from(&pose.translation);
    q.rows_mut(3, 4).copy_from_slice(&pose.quaternion_xyzw());
    let vehicle = Vehicle::attach(&mut world, index, VehicleConfig::buggy())?;
    Ok((world, vehicle))
}

fn run(world: &mut World, seconds: f64) -> Result<(), Box<dyn Error>> {
    timed(world, seconds)?;
    Ok(())
}

/// Steps for `seconds` and returns the mean wall time per step (µs) of each phase: kinematics,
/// collision, free motion, rows + assembly, solve, integration.
fn timed(world: &mut World, seconds: f64) -> Result<[f64; 6], Box<dyn Error>> {
    let steps = (seconds / world.options().dt).round() as usize;
    let mut total = [0.0; 6];
    for _ in 0..steps {
        let stats = world.step()?;
        for (t, ns) in total.iter_mut().zip(stats.phase_ns) {
            *t += ns as f64 * 1e-3 / steps as f64;
        }
    }
    Ok(total)
}

fn print_phases(what: &str, phases: &[f64; 6]) {
    println!(
        "{what}: {:.1} µs/step = kinematics {:.1} + collision {:.1} + free motion {:.1} + rows {:.1} + solve {:.1} + integration {:.1}",
        phases.iter().sum::<f64>(),
        phases[0],
        phases[1],
        phases[2],
        phases[3],
        phases[4],
        phases[5]
    );
}

/// Kåsa's algebraic circle fit: radius of the least-squares circle through `points`.
fn fit_radius(points: &[(f64, f64)]) -> f64 {
    let mut a = nalgebra::Matrix3::zeros();
    let mut b = nalgebra::Vector3::zeros();
    for &(x, y) in points {
        let row = nalgebra::Vector3::new(x, y, 1.0);
        a += row * row.transpose();
        b -= row * (x * x + y * y);
    }
    let s = a.lu().solve(&b).unwrap_or_default();
    let (cx, cy) = (-s[0] / 2.0, -s[1] / 2.0);
    (cx * cx + cy * cy - s[2]).sqrt()
}

fn main() -> Result<(), Box<dyn Error>> {
    // 1. Settle, then accelerate to 5 m/s.
    let (mut world, mut vehicle) = buggy_world(1.0, 0.0)?;
    run(&mut world, 1.0)?;
    let travel = vehicle.suspension_travel(&world);
    println!(
        "static sag: {:.4} m per wheel (m g / 4k = 400·9.81/(4·20000) = {:.4} m)",
        travel.iter().sum::<f64>() / 4.0,
        400.0 * 9.81 / 80_000.0
    );
    let start = vehicle.position(&world);
    vehicle.set_speed(&mut world, 5.0)?;
    println!("throttle: 5 m/s");
    println!("   t [s]   speed [m/s]   x [m]    y [m]");
    let clock = Instant::now();
    for k in 1..=6 {
        run(&mut world, 0.5)?;
        let p = vehicle.position(&world) - start;
        println!("   {:4.1}    {:8.3}    {:7.3}  {:7.4}", 0.5 * k as f64, vehicle.speed(&world), p.x, p.y);
    }
    let wall = clock.elapsed().as_secs_f64();
    let p = vehicle.position(&world) - start;
    println!(
        "lateral drift {:.2e} m over {:.2} m ({:.4} %); {:.1} µs per step while accelerating (this build)",
        p.y.abs(),
        p.x,
        100.0 * p.y.abs() / p.x,
        1e6 * wall / 1500.0
    );
    print_phases("cruising at 5 m/s", &timed(&mut world, 1.0)?);

    // 2. Circle at 20° steering, 3 m/s.
    let delta = 20f64.to_radians();
    vehicle.set_steering(&mut world, delta)?;
    vehicle.set_speed(&mut world, 3.0)?;
    let (left, right) = vehicle.ackermann(delta);
    println!(
        "\nsteering 20° (Ackermann: left {:.1}°, right {:.1}°), 3 m/s",
        left.to_degrees(),
        right.to_degrees()
    );
    run(&mut world, 4.0)?;
    let axle = vehicle.rear_axle_center();
    let mut points = Vec::new();
    let mut phases = [0.0; 6];
    for _ in 0..2000 {
        let stats = world.step()?;
        for (t, ns) in phases.iter_mut().zip(stats.phase_ns) {
            *t += ns as f64 * 1e-3 / 2000.0;
        }
        let p = vehicle.pose(&world).act_point(&axle);
        points.push((p.x, p.y));
    }
    let measured = fit_radius(&points);
    let predicted = vehicle.predicted_radius(delta);
    println!(
        "turn radius of the rear axle: measured {measured:.3} m, bicycle model L/tan δ = {predicted:.3} m ({:+.1} %)",
        100.0 * (measured - predicted) / predicted
    );
    print_phases("turning", &phases);

    // 3. Parked on a 20° slope.
    println!("\nparked on a 20° slope (brakes: motors at 0 rad/s, 1500 N·m each), 5 s:");
    for mu in [1.0, 0.3] {
        let (mut world, mut vehicle) = buggy_world(mu, 20.0)?;
        vehicle.set_brake(&mut world, true);
        run(&mut world, 1.0)?;
        let start = vehicle.position(&world);
        run(&mut world, 5.0)?;
        let moved = (vehicle.position(&world) - start).norm();
        let verdict = if moved < 1e-3 { "holds" } else { "slides" };
        println!("   μ = {mu}: moved {moved:.3e} m ({verdict}; tan 20° = {:.3})", 20f64.to_radians().tan());
    }
    Ok(())
}
