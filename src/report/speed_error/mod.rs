//! `gelenk report speed-error`: error against cost for scenes × integrators × time steps
//! (× solver settings for contact scenes), written as CSV, Markdown and a log–log plot with the
//! Pareto front of each scene, beside MuJoCo's figures for the 5-link pendulum.
//!
//! - Smooth scenes (no contact), each stepped by every [`IntegratorKind`] at several steps:
//!   `pendulum5` (benches/peers/pendulum5.xml through the MJCF reader, hinges at 0.3 rad, 5 s;
//!   error: largest joint-angle error at T, MuJoCo's measure; secondary: the largest over
//!   samples every 40 ms, or at every step for steps longer than 40 ms that do not divide it;
//!   energy: (E(T) − E₀)/(E₀ − E_rest)),
//!   `dzhanibekov` (free body near its intermediate axis, 20 s; error: relative flip-period
//!   error; energy: relative kinetic-energy drift; secondary: relative angular-momentum drift)
//!   and `chain30` (30 links, last 1000× heavier, 1 s; as the pendulum). The reference is
//!   Gragg–Bulirsch–Stoer with 8 columns (order 16), run on each sample grid the suite needs
//!   (its step the largest divisor of the sample interval not above the scene's reference
//!   step); the full report also runs it at half the step and prints the difference, the
//!   reference's own error.
//! - Contact scenes through the [`crate::world::World`] (its velocity-level step) with several
//!   solver chains and steps: bouncing ball (apex after 1–3 bounces against ε²ⁿh), sliding box
//!   (stopping distance against v₀²/(2μg)), 10-box stack (largest displacement; penetration),
//!   four-bar linkage (largest loop-closure error).
//!
//! Cost is measured wall time of the stepping loop (median of the repeats) per simulated second.

mod plot;
mod scenes;
mod types;

pub use types::{
    measures, pareto_front, GoalPoint, Measurement, PeerPoint, ReportError, SceneMeasures, SpeedErrorOptions,
    SpeedErrorReport, SCENES,
};

use crate::integrators::IntegratorKind;
use crate::world::SolverKind;
use plot::plot;
use scenes::{
    chain30, dzhanibekov, pendulum5, run_contact, run_smooth, sample_interval, smooth_errors, ContactScene,
    SmoothScene, Trajectory, MAX_EVALUATIONS, SAMPLE_INTERVAL,
};
use std::fmt::Write as _;
use std::path::Path;

/// The integrators and steps of the smooth scenes.
fn smooth_suite(quick: bool) -> Vec<(IntegratorKind, Vec<f64>)> {
    use IntegratorKind::*;
    if quick {
        return vec![
            (SemiImplicitEuler, vec![1e-2, 1e-3]),
            (Rk4, vec![1e-2, 2e-3]),
            (Rk8, vec![5e-2, 4e-2]),
            (DormandPrince45 { rtol: 1e-6, atol: 1e-6 }, vec![0.04]),
            (GraggBulirschStoer { columns: 6 }, vec![0.04]),
        ];
    }
    let dopri = |tol: f64| (DormandPrince45 { rtol: tol, atol: tol }, vec![0.04]);
    vec![
        (ExplicitEuler, vec![1e-3, 2e-4, 1e-4]),
        (SemiImplicitEuler, vec![2e-2, 1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4]),
        (ImplicitEuler, vec![1e-2, 2e-3, 1e-3, 2e-4]),
        (VelocityVerlet, vec![4e-2, 2e-2, 4e-2 / 3.0, 1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4]),
        (Rk4, vec![4e-2, 2e-2, 4e-2 / 3.0, 1e-2, 8e-3, 5e-3, 4e-3, 2e-3, 1e-3, 5e-4, 1e-4]),
        (Rk6, vec![4e-2, 2e-2, 4e-2 / 3.0, 1e-2, 8e-3, 5e-3, 4e-3, 2e-3]),
        // Steps that do not divide 40 ms (1/16, 1/18, 1/20, 1/30, 1/40 s) divide every scene's
        // duration and are sampled on their own grid: RK8 stays within 2e-4 rad on the pendulum
        // up to 50 ms, and the steps between 20 and 40 ms fill the front there.
        (
            Rk8,
            vec![
                1.0 / 16.0,
                1.0 / 18.0,
                5e-2,
                4e-2,
                1.0 / 30.0,
                2.5e-2,
                2e-2,
                4e-2 / 3.0,
                1e-2,
                8e-3,
                5e-3,
                4e-3,
                2e-3,
            ],
        ),
        dopri(1e-3),
        dopri(1e-4),
        dopri(1e-5),
        dopri(1e-6),
        dopri(1e-7),
        dopri(1e-9),
        dopri(1e-11),
        (GraggBulirschStoer { columns: 2 }, vec![4e-2, 2e-2, 1e-2]),
        (GraggBulirschStoer { columns: 3 }, vec![4e-2, 2e-2, 1e-2]),
        (GraggBulirschStoer { columns: 4 }, vec![4e-2, 2e-2, 1e-2, 5e-3]),
        (GraggBulirschStoer { columns: 6 }, vec![4e-2, 2e-2, 1e-2]),
        (GraggBulirschStoer { columns: 8 }, vec![4e-2, 2e-2]),
    ]
}

/// The solver chains and steps of the contact scenes.
fn contact_suite(quick: bool) -> (Vec<(&'static str, Vec<SolverKind>)>, Vec<f64>) {
    let pgs = |iterations| SolverKind::Pgs { iterations, omega: 1.0 };
    if quick {
        return (vec![("PGS 50", vec![pgs(50)])], vec![2e-3, 5e-3]);
    }
    (
        vec![
            ("PGS 10", vec![pgs(10)]),
            ("PGS 50", vec![pgs(50)]),
            ("PGS 100 → clarabel", vec![pgs(100), SolverKind::Clarabel]),
            ("Lemke → clarabel", vec![SolverKind::Lemke { facets: 8 }, SolverKind::Clarabel]),
        ],
        vec![1e-3, 2e-3, 5e-3, 1e-2],
    )
}

/// `dt` in scientific notation with up to three significant digits: `1e-2`, `1.33e-2`.
fn dt_label(dt: f64) -> String {
    let text = format!("{dt:.2e}");
    match text.split_once('e') {
        Some((mantissa, exponent)) if mantissa.contains('.') => {
            let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
            format!("{mantissa}e{exponent}")
        }
        _ => text,
    }
}

/// Runs the suite; `progress(what, fraction)` is called before each configuration.
pub fn run(
    options: &SpeedErrorOptions,
    mut progress: impl FnMut(&str, f64),
) -> Result<SpeedErrorReport, ReportError> {
    let quick = options.quick;
    let repeats = options.repeats.max(1);
    let mut report = SpeedErrorReport { quick, ..Default::default() };
    if let Some(unknown) = options.scenes.iter().find(|s| !SCENES.iter().any(|m| m.scene == s.as_str())) {
        return Err(ReportError::UnknownScene(unknown.clone()));
    }
    let wanted = |name: &str| options.scenes.is_empty() || options.scenes.iter().any(|s| s == name);
    let mut scenes: Vec<SmoothScene> = vec![pendulum5(&options.peers_dir)?, dzhanibekov()?, chain30()?];
    scenes.retain(|s| wanted(s.name));
    if quick {
        for s in &mut scenes {
            s.duration = match s.name {
                "pendulum5" => 5.0,
                "dzhanibekov" => 10.0,
                _ => 0.2,
            };
            s.reference_dt *= 2.0;
        }
    }
    let suite = smooth_suite(quick);
    let (chains, contact_dts) = contact_suite(quick);
    let mut contact_scenes = vec![
        ContactScene::BouncingBall,
        ContactScene::SlidingBox,
        ContactScene::Stack10,
        ContactScene::FourBar,
    ];
    contact_scenes.retain(|s| wanted(s.name()));
    let total = scenes.len() * suite.iter().map(|(_, d)| d.len()).sum::<usize>()
        + contact_scenes.len() * chains.len() * contact_dts.len();
    let mut done = 0usize;
    let columns = if quick { 6 } else { 8 };
    for scene in &scenes {
        progress(&format!("{}: reference", scene.name), done as f64 / total as f64);
        // One reference per sample interval, made on the first run that needs it.
        let mut references: Vec<Trajectory> = vec![reference_run(scene, columns, SAMPLE_INTERVAL, 1)?];
        if !quick {
            let half = reference_run(scene, columns, SAMPLE_INTERVAL, 2)?;
            let reference = &references[0];
            let (e, _, s) = smooth_errors(scene, &half, reference);
            report.notes.push(format!(
                "{}: reference GBS {columns} columns at dt = {}; against dt/2 it differs by {e:.1e} ({}) and {s:.1e} ({})",
                scene.name,
                dt_label(scene.reference_dt),
                measures(scene.name).error,
                measures(scene.name).secondary
            ));
        }
        for (kind, dts) in &suite {
            for &dt in dts {
                progress(
                    &format!("{} {} dt={}", scene.name, kind.label(), dt_label(dt)),
                    done as f64 / total as f64,
                );
                done += 1;
                let Some(interval) = sample_interval(dt, scene.duration) else {
                    report.failed.push((
                        scene.name.into(),
                        kind.label(),
                        dt,
                        format!("skipped: the step divides neither {SAMPLE_INTERVAL} s nor the duration"),
                    ));
                    continue;
                };
                let reference = match references.iter().position(|r| r.interval == interval) {
                    Some(k) => &references[k],
                    None => {
                        references.push(reference_run(scene, columns, interval, 1)?);
                        &references[references.len() - 1]
                    }
                };
                match run_smooth(scene, *kind, dt, interval, repeats, MAX_EVALUATIONS) {
                    Ok(Some(run)) => {
                        let (error, energy, secondary) = smooth_errors(scene, &run, reference);
                        if [error, energy, secondary, run.cost_us_per_s].iter().all(|x| x.is_finite()) {
                            report.rows.push(Measurement {
                                scene: scene.name.to_string(),
                                configuration: kind.label(),
                                dt: run.mean_step,
                                cost_us: run.cost_us_per_s,
                                error,
                                energy,
                                secondary,
                            });
                        } else {
                            report.failed.push((
                                scene.name.into(),
                                kind.label(),
                                dt,
                                "non-finite error".into(),
                            ));
                        }
                    }
                    Ok(None) => report.failed.push((
                        scene.name.into(),
                        kind.label(),
                        dt,
                        format!("skipped: more than {MAX_EVALUATIONS} dynamics evaluations"),
                    )),
                    Err(e) => report.failed.push((scene.name.into(), kind.label(), dt, e.to_string())),
                }
            }
        }
    }
    for scene in contact_scenes {
        for (label, chain) in &chains {
            for &dt in &contact_dts {
                progress(
                    &format!("{} {label} dt={}", scene.name(), dt_label(dt)),
                    done as f64 / total as f64,
                );
                done += 1;
                match run_contact(scene, dt, chain, quick, repeats) {
                    Ok(r)
                        if [r.error, r.energy, r.secondary, r.cost_us_per_s]
                            .iter()
                            .all(|x| x.is_finite()) =>
                    {
                        report.rows.push(Measurement {
                            scene: scene.name().to_string(),
                            configuration: label.to_string(),
                            dt,
                            cost_us: r.cost_us_per_s,
                            error: r.error,
                            energy: r.energy,
                            secondary: r.secondary,
                        })
                    }
                    Ok(_) => report.failed.push((
                        scene.name().into(),
                        label.to_string(),
                        dt,
                        "non-finite error".into(),
                    )),
                    Err(e) => report.failed.push((scene.name().into(), label.to_string(), dt, e.to_string())),
                }
            }
        }
    }
    progress("done", 1.0);
    report.mujoco = read_mujoco_points(&options.peers_dir.join("README.md"));
    report.goal = goal_check(&report.rows, &report.mujoco);
    report.notes.push(format!(
        "build: {}; {} timed repeat(s) per configuration, more for short runs until {} s are timed (at most {}), one for runs over {} s; median",
        if cfg!(debug_assertions) { "debug (timings not representative)" } else { "release" },
        repeats,
        scenes::MIN_TIMED,
        scenes::MAX_REPEATS,
        scenes::LONG_RUN
    ));
    Ok(report)
}

/// The reference trajectory of `scene` sampled every `interval` s: Gragg–Bulirsch–Stoer with
/// `columns` columns at the largest step that divides `interval` and is not above the scene's
/// reference step, divided by `refine` (2 for the reference's own error estimate).
fn reference_run(
    scene: &SmoothScene,
    columns: usize,
    interval: f64,
    refine: usize,
) -> Result<Trajectory, ReportError> {
    let per_sample = (interval / scene.reference_dt * (1.0 - 1e-9)).ceil().max(1.0) * refine as f64;
    let dt = interval / per_sample;
    run_smooth(scene, IntegratorKind::GraggBulirschStoer { columns }, dt, interval, 1, u64::MAX)?
        .ok_or_else(|| ReportError::Reference { scene: scene.name.to_string(), dt })
}

/// Parses MuJoCo's "Speed against error" table of the peers' README (rows
/// `| integrator | dt | ms per simulated s | energy drift | max joint error |`). Empty when the
/// file or the table is missing.
pub fn read_mujoco_points(readme: &Path) -> Vec<PeerPoint> {
    let Ok(text) = std::fs::read_to_string(readme) else {
        return Vec::new();
    };
    let Some(start) = text.find("## Speed against error") else {
        return Vec::new();
    };
    let mut points = Vec::new();
    for line in text[start..].lines().skip(1) {
        if line.starts_with("## ") {
            break;
        }
        let cells: Vec<&str> = line.trim().trim_matches('|').split('|').map(str::trim).collect();
        if cells.len() != 5 {
            continue;
        }
        let numbers: Vec<f64> =
            cells[1..].iter().filter_map(|c| c.trim_start_matches('+').parse().ok()).collect();
        if numbers.len() == 4 {
            points.push(PeerPoint {
                integrator: cells[0].to_string(),
                dt: numbers[0],
                cost_us: numbers[1] * 1e3,
                energy: numbers[2],
                error: numbers[3],
            });
        }
    }
    points
}

fn goal_check(rows: &[Measurement], mujoco: &[PeerPoint]) -> Vec<GoalPoint> {
    let peer: Vec<(f64, f64)> = mujoco.iter().map(|p| (p.cost_us, p.error)).collect();
    let ours: Vec<&Measurement> = rows.iter().filter(|r| r.scene == "pendulum5").collect();
    pareto_front(&peer)
        .into_iter()
        .map(|i| {
            let m = &mujoco[i];
            let best = ours
                .iter()
                .filter(|r| r.error <= m.error)
                .min_by(|a, b| a.cost_us.total_cmp(&b.cost_us))
                .map(|r| (*r).clone());
            GoalPoint { mujoco: m.clone(), gelenk: best }
        })
        .collect()
}

/// Writes `speed_error.csv`, `speed_error.md`, `speed_error.png` and `speed_error.svg` into
/// `dir` (created if missing).
pub fn write(report: &SpeedErrorReport, dir: &Path) -> Result<(), ReportError> {
    let io = |path: &Path| {
        let path = path.display().to_string();
        move |source| ReportError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let csv_path = dir.join("speed_error.csv");
    std::fs::write(&csv_path, csv(report)).map_err(io(&csv_path))?;
    let md_path = dir.join("speed_error.md");
    std::fs::write(&md_path, markdown(report)).map_err(io(&md_path))?;
    plot(report, &dir.join("speed_error.png"), &dir.join("speed_error.svg"))
}

/// The CSV: one row per measurement.
pub fn csv(report: &SpeedErrorReport) -> String {
    let mut out = String::from("scene,configuration,dt_s,cost_us_per_sim_s,error,energy,secondary,pareto\n");
    for m in &report.rows {
        let _ = writeln!(
            out,
            "{},{},{:e},{:.3},{:e},{:e},{:e},{}",
            m.scene,
            m.configuration,
            m.dt,
            m.cost_us,
            m.error,
            m.energy,
            m.secondary,
            on_front(report, m)
        );
    }
    out
}

fn on_front(report: &SpeedErrorReport, m: &Measurement) -> bool {
    let scene: Vec<&Measurement> = report.rows.iter().filter(|r| r.scene == m.scene).collect();
    let points: Vec<(f64, f64)> = scene.iter().map(|r| (r.cost_us, r.error)).collect();
    pareto_front(&points).into_iter().any(|i| scene[i] == m)
}

fn fmt_cost(us: f64) -> String {
    if us >= 1000.0 {
        format!("{:.2} ms", us / 1000.0)
    } else {
        format!("{us:.0} µs")
    }
}

/// The Markdown report: the goal check on the pendulum, then one table per scene.
pub fn markdown(report: &SpeedErrorReport) -> String {
    let mut out = String::new();
    let command =
        if report.quick { "gelenk report speed-error --quick" } else { "gelenk report speed-error" };
    let _ = writeln!(out, "# Speed against error\n\nMade by `{command}`. Cost: wall time of the stepping loop per simulated second (median of the repeats); ★ marks the Pareto front of each scene.\n");
    for note in &report.notes {
        let _ = writeln!(out, "- {note}");
    }
    let _ = writeln!(out, "\n## Pendulum (pendulum5.xml): gelenk beside MuJoCo\n");
    if report.mujoco.is_empty() {
        let _ = writeln!(out, "MuJoCo's figures were not found (peers/README.md).\n");
    } else {
        let _ = writeln!(out, "| MuJoCo integrator | dt | MuJoCo cost | max joint error | energy drift | gelenk's cheapest at that error or better | gelenk cost | gelenk error | cost ratio |");
        let _ = writeln!(out, "|---|---|---:|---:|---:|---|---:|---:|---:|");
        for p in &report.mujoco {
            let g = report.goal.iter().find(|g| g.mujoco == *p);
            let ours = report
                .rows
                .iter()
                .filter(|r| r.scene == "pendulum5" && r.error <= p.error)
                .min_by(|a, b| a.cost_us.total_cmp(&b.cost_us));
            let (cfg, cost, err, ratio) = match ours {
                Some(r) => (
                    format!("{} dt = {}", r.configuration, dt_label(r.dt)),
                    fmt_cost(r.cost_us),
                    format!("{:.1e}", r.error),
                    format!("{:.2}", r.cost_us / p.cost_us),
                ),
                None => ("none reaches it".into(), "—".into(), "—".into(), "—".into()),
            };
            let _ = writeln!(
                out,
                "| {}{} | {} | {} | {:.1e} | {:+.1e} | {cfg} | {cost} | {err} | {ratio} |",
                p.integrator,
                if g.is_some() { " ★" } else { "" },
                dt_label(p.dt),
                fmt_cost(p.cost_us),
                p.error,
                p.energy
            );
        }
        let verdict = if report.goal_met() { "holds" } else { "does not hold" };
        let worst = report.goal.iter().map(GoalPoint::ratio).fold(0.0, f64::max);
        let _ = writeln!(
            out,
            "\nGoal \"at every error level gelenk's best costs at most half of MuJoCo's best\", checked at MuJoCo's Pareto points (★): **{verdict}** (largest cost ratio {worst:.2}). MuJoCo's figures are from benches/peers/README.md (same machine kind, another run: ratios carry ±25 %).\n"
        );
    }
    for scene in SCENES {
        let rows: Vec<&Measurement> = report.rows.iter().filter(|r| r.scene == scene.scene).collect();
        if rows.is_empty() {
            continue;
        }
        let _ = writeln!(out, "## {}\n", scene.scene);
        let _ = writeln!(
            out,
            "| configuration | dt | cost per simulated s | {} | {} | {} |",
            scene.error, scene.energy, scene.secondary
        );
        let _ = writeln!(out, "|---|---|---:|---:|---:|---:|");
        for m in rows {
            let star = if on_front(report, m) { " ★" } else { "" };
            let _ = writeln!(
                out,
                "| {}{star} | {} | {} | {:.2e} | {:+.2e} | {:.2e} |",
                m.configuration,
                dt_label(m.dt),
                fmt_cost(m.cost_us),
                m.error,
                m.energy,
                m.secondary
            );
        }
        let _ = writeln!(out);
    }
    if !report.failed.is_empty() {
        let _ = writeln!(out, "## Failed (diverged) or skipped\n");
        for (scene, cfg, dt, why) in &report.failed {
            let _ = writeln!(out, "- {scene}, {cfg}, dt = {}: {why}", dt_label(*dt));
        }
    }
    out
}
