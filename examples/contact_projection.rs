//! The table of docs/collision.md's section "Contact projection": the three pile scenes
//! (`models/ragdoll_pile.toml`, `models/pile.toml`, `models/ragdoll_crowd.toml`) with their own
//! solver chains at dt = 1/60, 1/240 and 1/500 s, each run for 10 s from the drop with the
//! contact projection off and then on (`WorldOptions::contact_projection`), and written in
//! place between the section's `projection:begin` and `projection:end` markers.
//!
//! ```sh
//! cargo run --release --example contact_projection                 # the table (about an hour on 2 shared cores)
//! cargo run --release --example contact_projection -- --quick      # 1/60 s only, printed
//! cargo run --release --example contact_projection -- --no-write   # print instead of writing
//! ```
//!
//! Per run: the deepest penetration of any step's contacts, the steps whose accepted answer is
//! above the chain's tolerance, the fallbacks, the largest total energy after a step minus the
//! energy at the start, when every multibody is first asleep, the CPU time per step (the
//! stepping thread's clock around `World::step` alone; the energy is read outside it) and the
//! contact projection's share of the step's time (its phase in `StepStats::phase_ns`).

use gelenk::io::scene::{self, RunOptions};
use gelenk::world::ContactProjection;
use std::error::Error;
use std::fmt::Write as _;

const DOC: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/collision.md");
const BEGIN: &str = "<!-- projection:begin -->";
const END: &str = "<!-- projection:end -->";
const SCENES: [&str; 3] = ["ragdoll_pile", "pile", "ragdoll_crowd"];
const STEPS: [(&str, f64); 3] = [("1/60", 1.0 / 60.0), ("1/240", 1.0 / 240.0), ("1/500", 1.0 / 500.0)];
/// Simulated time of every run (s).
const SECONDS: f64 = 10.0;

/// CPU time of the calling thread (s).
fn thread_cpu() -> f64 {
    let mut t = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes the timespec it is given and nothing else.
    let status = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
    assert_eq!(status, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID) failed");
    t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
}

/// What one run measured.
struct Measured {
    steps: usize,
    penetration: f64,
    above_tolerance: usize,
    fallbacks: usize,
    energy_rise: f64,
    asleep_at: Option<f64>,
    cpu: f64,
    projection_share: f64,
}

fn measure(name: &str, dt: f64, projection: bool) -> Result<Measured, Box<dyn Error>> {
    let path = format!("{}/models/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    let mut loaded = scene::load_file(&path)?;
    // The world rebuilt at this dt (zero steps taken).
    let rebuild =
        RunOptions { dt: Some(dt), duration: Some(0.0), record_every: Some(0), ..Default::default() };
    scene::run(&mut loaded, &rebuild, |_| {})?;
    let world = &mut loaded.world;
    let settings = world.options().contact_projection;
    world.set_contact_projection(ContactProjection { enabled: projection, ..settings });
    world.set_phase_timing(true);
    let tolerance = world.options().tolerance;
    let count = world.multibody_count();
    let start_energy = world.total_energy();
    let steps = (SECONDS / dt).round() as usize;
    let mut m = Measured {
        steps,
        penetration: 0.0,
        above_tolerance: 0,
        fallbacks: 0,
        energy_rise: f64::NEG_INFINITY,
        asleep_at: None,
        cpu: 0.0,
        projection_share: 0.0,
    };
    let (mut phases, mut projection_ns) = (0u64, 0u64);
    for step in 1..=steps {
        let before = thread_cpu();
        let stats = world.step()?;
        m.cpu += thread_cpu() - before;
        m.penetration = m.penetration.max(stats.max_penetration);
        m.above_tolerance += usize::from(stats.rows > 0 && stats.residual > tolerance);
        m.fallbacks += stats.fallbacks.len();
        phases += stats.phase_ns.iter().sum::<u64>();
        projection_ns += stats.phase_ns[6];
        if m.asleep_at.is_none() && stats.asleep == count {
            m.asleep_at = Some(step as f64 * dt);
        }
        m.energy_rise = m.energy_rise.max(world.total_energy() - start_energy);
    }
    m.projection_share = projection_ns as f64 / phases.max(1) as f64;
    Ok(m)
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|a| a == "--quick");
    let write = !quick && !args.iter().any(|a| a == "--no-write");
    let steps = if quick { &STEPS[..1] } else { &STEPS[..] };
    let mut table = String::new();
    writeln!(
        table,
        "`cargo run --release --example contact_projection` ({SECONDS} s from the drop per run, each scene's own \
         solver chain; the projection off, then on, back to back):\n"
    )?;
    table.push_str(
        "| scene | dt | projection | deepest penetration (mm) | steps above tolerance | fallbacks \
         | largest energy over the start (J) | all asleep at (s) | CPU ms per step \
         | CPU on / off | projection's share of the step |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for name in SCENES {
        for &(label, dt) in steps {
            let off = measure(name, dt, false)?;
            let on = measure(name, dt, true)?;
            for (which, m) in [("off", &off), ("on", &on)] {
                let ratio = if which == "on" { format!("{:.2}", on.cpu / off.cpu) } else { String::new() };
                let share = if which == "on" {
                    format!("{:.1} %", 100.0 * m.projection_share)
                } else {
                    String::new()
                };
                let line = format!(
                    "| {name} | {label} | {which} | {:.2} | {} of {} | {} | {:.3} | {} | {:.2} | {ratio} | {share} |",
                    1e3 * m.penetration,
                    m.above_tolerance,
                    m.steps,
                    m.fallbacks,
                    m.energy_rise,
                    m.asleep_at.map_or("not in 10 s".to_string(), |t| format!("{t:.2}")),
                    1e3 * m.cpu / m.steps as f64,
                );
                println!("{line}");
                table.push_str(&line);
                table.push('\n');
            }
        }
    }
    if write {
        let text = std::fs::read_to_string(DOC)?;
        let (head, rest) =
            text.split_once(BEGIN).ok_or("docs/collision.md has no projection:begin marker")?;
        let (_, tail) = rest.split_once(END).ok_or("docs/collision.md has no projection:end marker")?;
        std::fs::write(DOC, format!("{head}{BEGIN}\n{table}{END}{tail}"))?;
        println!("written to docs/collision.md");
    }
    Ok(())
}
