//! A sweep of box pyramids stepped by Lemke's method alone: variants of the stability report's
//! `pyramid10` (0.1 m cubes of 1 kg on a plane, μ = 0.5 as the report sets it, rows `gap` apart)
//! with other gaps between the boxes of a row, other base widths and two time steps.
//!
//! ```sh
//! cargo run --profile ci --example lemke_pyramids -- [--seconds 6] [--only NAME] [--export DIR]
//! ```
//!
//! Per variant it prints the steps taken, the first step whose solve failed (and the error),
//! the steps whose certified residual is above the world's 1e-8 m/s, the largest residual, the
//! pivots and wall time per step and the top box's drift. With `--export DIR` the problem of
//! each variant's first failed step is written to `DIR/<variant>/problem.json`, and that of its
//! first step above 1e-8 m/s to `DIR/<variant>/above/problem.json` (`gelenk
//! solve-problem` reads it; its A is formed densely, so a solve of the file rounds differently
//! from the world's). `--only` runs the variants whose name (`base10-gap1.5mm-dt60`) contains
//! NAME. The exit status is 1 when any variant has a failed step.

use gelenk::collision::MeshOptions;
use gelenk::io::problem::{problem_to_json, PROBLEM_FILE};
use gelenk::math::{Transform, Vec3};
use gelenk::model::{RigidInertia, Shape};
use gelenk::report::stability::{free_body, options, Setting};
use gelenk::world::{SolverKind, World};
use std::error::Error;
use std::path::PathBuf;
use std::time::Instant;

/// One pyramid variant.
#[derive(Clone, Copy, Debug)]
struct Variant {
    /// Boxes in the bottom row (the pyramid has `base` rows).
    base: usize,
    /// Gap between neighbouring boxes of a row (m).
    gap: f64,
    /// Time step (s).
    dt: f64,
}

impl Variant {
    fn name(&self) -> String {
        format!("base{}-gap{}mm-dt{}", self.base, self.gap * 1e3, (1.0 / self.dt).round())
    }

    /// The world: a plane and the pyramid of 0.1 m cubes, Lemke alone with an 8-facet pyramid,
    /// as the stability report sets a Lemke cell; returns it with the top box's index.
    fn world(&self) -> Result<(World, usize), Box<dyn Error>> {
        let side = 0.1;
        let mut w = World::new(options(&Setting::new(SolverKind::Lemke { facets: 8 }, self.dt)));
        w.add_static("ground", &Shape::HalfSpace { normal: Vec3::z() }, Transform::identity(), 0)?;
        let mut top = 0;
        for row in 0..self.base {
            for k in 0..self.base - row {
                let name = format!("box{row}_{k}");
                let size = Vec3::repeat(side);
                let model = free_body(&name, Shape::Box { size }, RigidInertia::solid_box(1.0, size));
                top = w.add_multibody(&name, model, &MeshOptions::default())?;
                let q = &mut w.multibody_mut(top).state.q;
                q[0] = (k as f64 - (self.base - 1 - row) as f64 / 2.0) * (side + self.gap);
                q[2] = side / 2.0 + side * row as f64;
            }
        }
        Ok((w, top))
    }
}

/// What one run of a variant gave.
struct Run {
    steps: usize,
    failed: Option<(usize, String)>,
    above: usize,
    worst: f64,
    pivots: usize,
    seconds: f64,
    drift: f64,
    contacts: usize,
}

fn run(variant: Variant, seconds: f64, export: Option<&PathBuf>) -> Result<Run, Box<dyn Error>> {
    let (mut w, top) = variant.world()?;
    let tolerance = w.options().tolerance;
    let start = w.multibody(top).state.q.fixed_rows::<3>(0).into_owned();
    let steps = (seconds / variant.dt).round() as usize;
    let mut out = Run {
        steps: 0,
        failed: None,
        above: 0,
        worst: 0.0,
        pivots: 0,
        seconds: 0.0,
        drift: 0.0,
        contacts: 0,
    };
    let clock = Instant::now();
    for step in 0..steps {
        match w.step() {
            Ok(stats) => {
                let (iterations, contacts, residual) = (stats.iterations, stats.contacts, stats.residual);
                out.steps += 1;
                out.pivots += iterations;
                out.contacts = out.contacts.max(contacts);
                if residual > tolerance && out.above == 0 {
                    if let Some(dir) = export {
                        let dir = dir.join(variant.name()).join("above");
                        std::fs::create_dir_all(&dir)?;
                        std::fs::write(dir.join(PROBLEM_FILE), problem_to_json(w.problem())?)?;
                    }
                }
                out.above += usize::from(residual > tolerance);
                out.worst = out.worst.max(residual);
            }
            Err(e) => {
                if let Some(dir) = export {
                    let dir = dir.join(variant.name());
                    std::fs::create_dir_all(&dir)?;
                    std::fs::write(dir.join(PROBLEM_FILE), problem_to_json(w.problem())?)?;
                }
                out.failed = Some((step, e.to_string()));
                break;
            }
        }
    }
    out.seconds = clock.elapsed().as_secs_f64();
    out.drift = (w.multibody(top).state.q.fixed_rows::<3>(0) - start).norm();
    Ok(out)
}

fn main() -> Result<(), Box<dyn Error>> {
    let mut args = std::env::args().skip(1);
    let (mut seconds, mut export, mut only) = (6.0, None, None::<String>);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--seconds" => seconds = args.next().ok_or("--seconds needs a value")?.parse()?,
            "--export" => export = Some(PathBuf::from(args.next().ok_or("--export needs a directory")?)),
            "--only" => only = Some(args.next().ok_or("--only needs a variant name")?),
            other => return Err(format!("unknown argument {other}").into()),
        }
    }
    let mut variants = Vec::new();
    for dt in [1.0 / 60.0, 1.0 / 240.0] {
        for base in [6, 8, 10] {
            for gap in [0.0005, 0.001, 0.0015, 0.002, 0.003, 0.0] {
                variants.push(Variant { base, gap, dt });
            }
        }
    }
    println!("| variant | contacts | steps | failed at | above 1e-8 | worst residual | pivots/step | ms/step | top drift (m) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let mut failures = 0;
    for variant in variants {
        if only.as_ref().is_some_and(|only| !variant.name().contains(only.as_str())) {
            continue;
        }
        let r = run(variant, seconds, export.as_ref())?;
        let failed = match &r.failed {
            Some((step, e)) => {
                failures += 1;
                format!("{step}: {e}")
            }
            None => "-".into(),
        };
        println!(
            "| {} | {} | {} | {failed} | {} | {:.1e} | {:.1} | {:.2} | {:.1e} |",
            variant.name(),
            r.contacts,
            r.steps,
            r.above,
            r.worst,
            r.pivots as f64 / r.steps.max(1) as f64,
            1e3 * r.seconds / r.steps.max(1) as f64,
            r.drift
        );
    }
    if failures > 0 {
        eprintln!("{failures} variants with a failed step");
        std::process::exit(1);
    }
    Ok(())
}
