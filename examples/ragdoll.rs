//! A ragdoll dropped from 1 m (models/ragdoll_fall.toml): prints when it lands, when it comes to
//! rest, its energy, the deepest penetration, the largest joint-limit overshoot and the cost of a
//! step. Run with `cargo run --release --example ragdoll [SCENE.toml]`.

use gelenk::io::scene;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/models/ragdoll_fall.toml").into());
    let mut s = scene::load_file(&path)?;
    let world = &mut s.world;
    let mass: f64 = (0..world.multibody_count()).map(|i| world.multibody(i).model().total_mass()).sum();
    let g = world.options().gravity.norm();
    let drop_energy = mass * g * 1.0; // m g h for the 1 m drop
    let steps = (s.duration / world.options().dt).round() as usize;
    println!(
        "{}: {} multibodies, {:.1} kg, {} steps of {} s",
        s.name,
        world.multibody_count(),
        mass,
        steps,
        world.options().dt
    );
    let e0 = world.total_energy();
    let (mut landed, mut rest) = (None::<f64>, None::<f64>);
    let (mut max_pen, mut max_violation, mut max_energy) = (0.0f64, 0.0f64, e0);
    let mut stepping = 0.0;
    for _ in 0..steps {
        let start = Instant::now();
        let stats = world.step()?;
        stepping += start.elapsed().as_secs_f64();
        let (contacts, pen, t) = (stats.contacts, stats.max_penetration, stats.time);
        max_pen = max_pen.max(pen);
        let ground_contact =
            world.contacts().iter().any(|c| c.body_b == gelenk::collision::Attachment::World);
        if landed.is_none() && ground_contact {
            landed = Some(t);
            println!("t = {t:.3} s: lands ({contacts} contacts)");
        }
        let energy = world.total_energy();
        max_energy = max_energy.max(energy);
        max_violation = max_violation.max(world.constraint_violation());
        let kinetic = world.kinetic_energy();
        // At rest from the last time the kinetic energy was at or above 1 % of the drop energy.
        match (landed.is_some() && kinetic < 0.01 * drop_energy, rest) {
            (true, None) => rest = Some(t),
            (false, Some(_)) => rest = None,
            _ => {}
        }
    }
    println!("energy {e0:.1} J -> {:.1} J (never above {max_energy:.1} J)", world.total_energy());
    println!(
        "deepest penetration {:.2} mm; largest joint-limit overshoot {:.3}°",
        max_pen * 1e3,
        max_violation.to_degrees()
    );
    match (landed, rest) {
        (Some(l), Some(r)) => println!(
            "at rest from t = {r:.3} s ({:.2} s after landing): kinetic energy below 1 % of the drop energy {drop_energy:.0} J from then on",
            r - l
        ),
        _ => println!("not at rest by the end"),
    }
    println!("{:.1} µs per step (World::step only)", stepping / steps as f64 * 1e6);
    Ok(())
}
