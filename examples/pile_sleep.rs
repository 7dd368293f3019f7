//! When does the pile of 20 ragdolls (`models/ragdoll_pile.toml`) fall asleep, for another
//! seed of its drop? The test asks for all asleep within 10 s; the shipped seed is one sample of
//! a chaotic pile, and this measures others.
//!
//! ```sh
//! cargo run --release --example pile_sleep -- 3 16    # seed, seconds to step at most
//! ```
//!
//! Prints the first time (s) at which every ragdoll is asleep, or that none came within the
//! time, the lowest point any body's collider reached (its bounding box, every step: the
//! scene's test allows 5 mm below the ground), and the wall time taken.

use gelenk::collision::Attachment;
use std::error::Error;
use std::time::Instant;

fn main() -> Result<(), Box<dyn Error>> {
    let mut args = std::env::args().skip(1);
    let seed: u64 = args.next().ok_or("usage: pile_sleep SEED [SECONDS]")?.parse()?;
    let seconds: f64 = args.next().map_or(Ok(16.0), |s| s.parse())?;
    let models = concat!(env!("CARGO_MANIFEST_DIR"), "/models");
    let text = std::fs::read_to_string(format!("{models}/ragdoll_pile.toml"))?;
    let shipped = "seed = 3";
    if !text.contains(shipped) {
        return Err(format!("models/ragdoll_pile.toml no longer has `{shipped}`").into());
    }
    let mut scene = gelenk::io::scene::load_str(&text.replace(shipped, &format!("seed = {seed}")), models)?;
    let count = scene.world.multibody_count();
    let dt = scene.world.options().dt;
    let start = Instant::now();
    let mut lowest = (f64::INFINITY, String::new(), 0.0);
    for step in 1..=(seconds / dt).round() as usize {
        let asleep = scene.world.step()?.asleep;
        for c in scene.world.collision().colliders() {
            if let Attachment::Body { .. } = c.attachment() {
                if c.aabb().0[2] < lowest.0 {
                    lowest = (c.aabb().0[2], c.name().to_string(), step as f64 * dt);
                }
            }
        }
        if asleep == count {
            println!(
                "seed {seed}: all {count} asleep at {:.3} s; lowest point {:.2} mm ({} at {:.3} s) ({:.1} s wall)",
                step as f64 * dt,
                lowest.0 * 1e3,
                lowest.1,
                lowest.2,
                start.elapsed().as_secs_f64()
            );
            return Ok(());
        }
    }
    println!(
        "seed {seed}: not all asleep within {seconds} s; lowest point {:.2} mm ({} at {:.3} s) ({:.1} s wall)",
        lowest.0 * 1e3,
        lowest.1,
        lowest.2,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
