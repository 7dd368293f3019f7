//! Soak test: a crowd of 128 boxes and balls in a walled pen, kicked at random for a long time.
//!
//! ```sh
//! cargo run --release --example soak -- --minutes 30 [--seed 1]
//! ```
//!
//! Every 0.5 s of simulated time eight random bodies get a random velocity of up to 4 m/s. The
//! run fails (exit status 1) on the first of: a step error (a NaN or infinity is one), energy
//! growing between two kicks by more than 1 % of the energy after the first of them (plus 1 mJ),
//! a body outside the pen (it escaped through a wall or the ground: the walls are 4 m high, and a
//! kick of at most 4 m/s per axis, 6.9 m/s, lifts a body by at most 2.45 m), or resident memory growing
//! by more than 16 MiB after the first minute (read from `/proc/self/statm`). A line per minute
//! and a summary are printed.

use gelenk::io::scene;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::error::Error;
use std::time::Instant;

/// Half the pen's inner width (m); bodies are dropped inside it.
const PEN: f64 = 1.0;

const SCENE: &str = r#"
name = "soak"
[world]
dt = 0.004
solver = "pgs50"
[contact]
mu = 0.5
[[ground]]
kind = "plane"
[[body]]
name = "wall_x"
shape = "box"
size = [0.2, 2.4, 4.0]
position = [-1.1, 0, 2.0]
count = [2, 1, 1]
spacing = [2.2, 0, 0]
fixed = true
[[body]]
name = "wall_y"
shape = "box"
size = [2.4, 0.2, 4.0]
position = [0, -1.1, 2.0]
count = [1, 2, 1]
spacing = [0, 2.2, 0]
fixed = true
[[body]]
name = "box"
shape = "box"
size = [0.12, 0.12, 0.12]
density = 600
position = [-0.7, -0.7, 0.2]
count = [8, 8, 1]
spacing = [0.2, 0.2, 0]
jitter = 0.02
[[body]]
name = "ball"
shape = "sphere"
radius = 0.06
density = 800
position = [-0.7, -0.7, 0.45]
count = [8, 8, 1]
spacing = [0.2, 0.2, 0]
jitter = 0.02
"#;

/// Resident memory (bytes) from `/proc/self/statm` (0 where there is none).
fn resident_bytes() -> u64 {
    let pages = std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1).and_then(|p| p.parse::<u64>().ok()))
        .unwrap_or(0);
    pages * 4096
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str, default: f64| -> Result<f64, Box<dyn Error>> {
        match args.iter().position(|a| a == flag) {
            Some(i) => Ok(args.get(i + 1).ok_or(format!("{flag} needs a value"))?.parse()?),
            None => Ok(default),
        }
    };
    let minutes = value("--minutes", 1.0)?;
    let seed = value("--seed", 1.0)? as u64;
    let mut scene = scene::load_str(SCENE, ".")?;
    let world = &mut scene.world;
    let moving: Vec<usize> = (0..world.multibody_count()).collect();
    let dt = world.options().dt;
    let kick_every = (0.5 / dt).round() as u64;
    let mut rng = StdRng::seed_from_u64(seed);
    let start = Instant::now();
    let (mut steps, mut kicks, mut minute) = (0u64, 0u64, 0u64);
    let mut energy_after_kick = world.total_energy();
    let (mut worst_growth, mut memory_base, mut memory_peak) = (0.0f64, 0u64, 0u64);
    let failure = loop {
        if start.elapsed().as_secs_f64() >= minutes * 60.0 {
            break None;
        }
        if let Err(e) = world.step() {
            break Some(format!("step {steps}: {e}"));
        }
        steps += 1;
        if let Some(&i) = moving.iter().find(|&&i| {
            let q = &world.multibody(i).state.q;
            !(q[0].abs() < PEN && q[1].abs() < PEN && q[2] > -0.05 && q[2] < 20.0)
        }) {
            let q = &world.multibody(i).state.q;
            break Some(format!(
                "step {steps}: `{}` left the pen at ({:.3}, {:.3}, {:.3}) m",
                world.multibody_name(i),
                q[0],
                q[1],
                q[2]
            ));
        }
        if steps % kick_every == 0 {
            let energy = world.total_energy();
            if !energy.is_finite() {
                break Some(format!("step {steps}: total energy {energy}"));
            }
            let growth = (energy - energy_after_kick) / energy_after_kick.abs().max(1e-9);
            worst_growth = worst_growth.max(growth);
            if energy > energy_after_kick + 0.01 * energy_after_kick.abs() + 1e-3 {
                break Some(format!(
                    "step {steps}: energy grew from {energy_after_kick:.6} J to {energy:.6} J between two kicks"
                ));
            }
            for _ in 0..8 {
                let i = moving[rng.random_range(0..moving.len())];
                let v = &mut world.multibody_mut(i).state.v;
                for k in 0..3 {
                    v[k] = rng.random_range(-4.0..4.0);
                }
                v[2] = v[2].abs();
                world.wake(i);
            }
            kicks += 1;
            energy_after_kick = world.total_energy();
        }
        let elapsed = start.elapsed().as_secs_f64();
        if elapsed >= (minute + 1) as f64 * 60.0 {
            minute += 1;
            let memory = resident_bytes();
            if minute == 1 {
                memory_base = memory;
            }
            memory_peak = memory_peak.max(memory);
            println!(
                "{minute} min: {steps} steps ({:.0} s simulated), {kicks} kicks, energy {:.4} J, resident {:.1} MiB",
                steps as f64 * dt,
                world.total_energy(),
                memory as f64 / (1 << 20) as f64
            );
            if memory_base > 0 && memory > memory_base + (16 << 20) {
                break Some(format!(
                    "resident memory grew from {:.1} MiB to {:.1} MiB",
                    memory_base as f64 / (1 << 20) as f64,
                    memory as f64 / (1 << 20) as f64
                ));
            }
        }
    };
    println!(
        "soak: {} bodies, {steps} steps ({:.0} s simulated) in {:.0} s, {kicks} kicks; largest energy change between kicks {:+.3}%; resident memory {:.1} MiB after 1 min, peak {:.1} MiB",
        moving.len(),
        steps as f64 * dt,
        start.elapsed().as_secs_f64(),
        100.0 * worst_growth,
        memory_base as f64 / (1 << 20) as f64,
        memory_peak.max(resident_bytes()) as f64 / (1 << 20) as f64
    );
    match failure {
        None => {
            println!("soak: passed (no NaN, no energy growth, no body out of the pen, flat memory)");
            Ok(())
        }
        Some(why) => {
            eprintln!("soak: FAILED: {why}");
            std::process::exit(1);
        }
    }
}
