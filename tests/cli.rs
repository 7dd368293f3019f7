//! The `gelenk` command line: `inspect --json` reports Pinocchio's joint layout, `dynamics`
//! reproduces the reference values of tests/data/reference, and bad input gives one readable line
//! on stderr with a non-zero exit status, never a panic.

mod common;

use common::*;
use serde_json::Value;
use std::process::{Command, Output};

fn gelenk(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gelenk")).args(args).output().expect("gelenk runs")
}

fn model_path(name: &str) -> String {
    models_dir().join(name).display().to_string()
}

#[test]
fn inspect_json_reports_layout_and_mass() {
    let out = gelenk(&["inspect", &model_path("solo12.urdf"), "--floating", "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["nq"], 19);
    assert_eq!(v["nv"], 18);
    let joints = v["joints"].as_array().unwrap();
    assert_eq!(joints.len(), 13);
    assert_eq!(joints[0]["name"], "root_joint");
    assert_eq!(joints[0]["type"], "free");
    assert_eq!(joints[0]["parent"], "universe");
    assert_eq!((joints[1]["idx_q"].as_u64(), joints[1]["idx_v"].as_u64()), (Some(7), Some(6)));
    let reference: Value =
        serde_json::from_str(&std::fs::read_to_string(reference_dir().join("solo12_floating.json")).unwrap())
            .unwrap();
    let mass = reference["states"][0]["mass"].as_f64().unwrap();
    assert!((v["mass"].as_f64().unwrap() - mass).abs() < 1e-9 * mass);

    let table = gelenk(&["inspect", &model_path("panda.urdf")]);
    assert!(table.status.success());
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(text.contains("panda_joint1") && text.contains("nv = 9"), "{text}");
}

#[test]
fn dynamics_command_reproduces_reference() {
    let text = std::fs::read_to_string(reference_dir().join("ur5.json")).unwrap();
    let reference: Value = serde_json::from_str(&text).unwrap();
    let states: Vec<Value> = reference["states"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| serde_json::json!({"q": s["q"], "v": s["v"], "a": s["a"], "tau": s["tau"]}))
        .collect();
    let dir = std::env::temp_dir().join(format!("gelenk-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let states_file = dir.join("states.json");
    std::fs::write(&states_file, serde_json::json!({ "states": states }).to_string()).unwrap();
    let out = gelenk(&["dynamics", &model_path("ur5_robot.urdf"), "--states", states_file.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["nv"], 6);
    for (got, want) in v["results"].as_array().unwrap().iter().zip(reference["states"].as_array().unwrap()) {
        for key in ["nle", "gravity", "rnea", "aba", "com"] {
            assert!(max_rel_err(dvec(&got[key]).as_slice(), dvec(&want[key]).as_slice()) < 1e-9, "{key}");
        }
        let m = dmat(&got["mass_matrix"]);
        assert!(max_rel_err(m.as_slice(), dmat(&want["mass_matrix"]).as_slice()) < 1e-9);
        for key in ["kinetic_energy", "potential_energy", "mass"] {
            let (g, w) = (got[key].as_f64().unwrap(), want[key].as_f64().unwrap());
            assert!((g - w).abs() < 1e-9 * w.abs().max(1.0), "{key}");
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

fn assert_one_line_error(out: &Output, needle: &str) {
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "expected one line, got: {err}");
    assert!(err.starts_with("gelenk: error:") && err.contains(needle), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn bad_input_is_one_line_and_nonzero_exit() {
    assert_one_line_error(&gelenk(&["inspect", "/nonexistent/robot.urdf"]), "cannot read");
    let dir = std::env::temp_dir().join(format!("gelenk-cli-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let broken = dir.join("broken.urdf");
    std::fs::write(&broken, "<robot name='x'><link name='a'>").unwrap();
    assert_one_line_error(&gelenk(&["inspect", broken.to_str().unwrap()]), "broken.urdf");
    let states = dir.join("states.json");
    std::fs::write(&states, r#"{"states":[{"q":[0,0]}]}"#).unwrap();
    let out = gelenk(&["dynamics", &model_path("ur5_robot.urdf"), "--states", states.to_str().unwrap()]);
    assert_one_line_error(&out, "\"q\" has 2 entries");
    std::fs::write(&states, r#"{"states":[{"q":[0,0,0,0,0,0,0,0.1,0.2,0.3,0.4,0.5,0.6]}]}"#).unwrap();
    let out = gelenk(&[
        "dynamics",
        &model_path("ur5_robot.urdf"),
        "--floating",
        "--states",
        states.to_str().unwrap(),
    ]);
    assert_one_line_error(&out, "quaternion has norm 0");
    std::fs::write(&states, "not json").unwrap();
    let out = gelenk(&["dynamics", &model_path("ur5_robot.urdf"), "--states", states.to_str().unwrap()]);
    assert_one_line_error(&out, "not a states file");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn inspect_warns_about_massless_subtree() {
    let dir = std::env::temp_dir().join(format!("gelenk-cli-massless-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("massless.urdf");
    std::fs::write(
        &file,
        r#"<robot name="m"><link name="base"/><link name="tip"/>
           <joint name="spin" type="continuous"><parent link="base"/><child link="tip"/><axis xyz="0 0 1"/></joint>
           </robot>"#,
    )
    .unwrap();
    let out = gelenk(&["inspect", file.to_str().unwrap()]);
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("warning") && err.contains("spin"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn report_stability_writes_markdown_and_csv_for_a_quick_subset() {
    let dir = std::env::temp_dir().join(format!("gelenk-report-{}", std::process::id()));
    let out = gelenk(&[
        "report",
        "stability",
        "--out",
        dir.to_str().unwrap(),
        "--cases",
        "rolling_ball,cradle,fast_sphere,dzhanibekov",
        "--solvers",
        "lemke,pgs50",
        "--dt",
        "0.004166666666666667",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = std::fs::read_to_string(dir.join("stability.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "case,solver,dt,integrator,pass,figure,seconds,steps,us_per_step,detail");
    // Three contact cases with the default integrator, the Dzhanibekov spin with it and RK4.
    assert_eq!(lines.len(), 1 + 3 * 2 + 2 * 2, "{csv}");
    // The rolling ball passes with both solvers (5/7 g sin θ within 1 %); the 100 m/s sphere
    // is stopped by the 2 cm wall at dt = 1/240 s (v·dt / (thickness + 2r) = 10.4: swept).
    for solver in ["lemke", "pgs50"] {
        let row =
            |case: &str| lines.iter().find(|l| l.starts_with(&format!("{case},{solver},"))).copied().unwrap();
        assert!(row("rolling_ball").contains(",true,"), "{}", row("rolling_ball"));
        let tunnel: Vec<&str> = row("fast_sphere").split(',').collect();
        assert_eq!(tunnel[4], "true");
        // Steps and their mean cost are recorded.
        assert!(
            tunnel[7].parse::<u64>().unwrap() > 0 && tunnel[8].parse::<f64>().unwrap() > 0.0,
            "{tunnel:?}"
        );
        assert!((tunnel[5].parse::<f64>().unwrap() - 100.0 / 240.0 / 0.04).abs() < 1e-9);
        // The spin keeps L and E to 1e-6 with RK4 in the world; the velocity-level step meets
        // its own criterion (energy never grows, |ΔL|/L ≤ 1e-2, period within 5 %).
        let spin = |integrator: &str| {
            let prefix = format!("dzhanibekov,{solver},0.004166666666666667,{integrator},");
            lines.iter().find(|l| l.starts_with(&prefix)).copied().unwrap()
        };
        assert!(spin("rk4").contains(",true,"), "{}", spin("rk4"));
        assert!(spin("semi-implicit-euler").contains(",true,"), "{}", spin("semi-implicit-euler"));
    }
    let markdown = std::fs::read_to_string(dir.join("stability.md")).unwrap();
    assert!(markdown.starts_with("| case | dt (s) | integrator | lemke | pgs50 |"), "{markdown}");
    assert!(markdown.contains("| rolling_ball | 1/240 | semi-implicit-euler | pass"), "{markdown}");
    assert!(markdown.contains("| dzhanibekov | 1/240 | rk4 | pass"), "{markdown}");
    std::fs::remove_dir_all(&dir).ok();

    // --quick: the default chain at 1/60 s; a cell beyond its budget is a timeout, and the
    // files hold every finished cell.
    let quick = gelenk(&[
        "report",
        "stability",
        "--quick",
        "--out",
        dir.to_str().unwrap(),
        "--cases",
        "resting,pyramid10",
        "--budget",
        "0.2",
    ]);
    assert!(quick.status.success(), "{}", String::from_utf8_lossy(&quick.stderr));
    let csv = std::fs::read_to_string(dir.join("stability.csv")).unwrap();
    assert!(csv.contains("\nresting,default,0.016666666666666666,semi-implicit-euler,true,"), "{csv}");
    assert!(csv.contains("\npyramid10,default,0.016666666666666666,semi-implicit-euler,timeout,"), "{csv}");
    assert_eq!(csv.lines().count(), 3, "{csv}");
    std::fs::remove_dir_all(&dir).ok();
    let bad = gelenk(&["report", "stability", "--budget", "0"]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("budget 0 s"));

    let bad = gelenk(&["report", "stability", "--cases", "no_such_case"]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown case `no_such_case`"));
    let bad = gelenk(&["report", "stability", "--integrators", "rk5"]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown integrator `rk5`"));
}

#[test]
fn report_speed_error_quick_writes_sane_files() {
    let dir = std::env::temp_dir().join(format!("gelenk_speed_error_{}", std::process::id()));
    let peers = peers_dir();
    let out = gelenk(&[
        "report",
        "speed-error",
        "--quick",
        "--out",
        dir.to_str().unwrap(),
        "--peers",
        peers.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("goal"), "{stdout}");
    let csv = std::fs::read_to_string(dir.join("speed_error.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "scene,configuration,dt_s,cost_us_per_sim_s,error,energy,secondary,pareto"
    );
    let mut scenes = std::collections::BTreeSet::new();
    let mut rows = 0;
    for line in lines {
        let cells: Vec<&str> = line.split(',').collect();
        assert_eq!(cells.len(), 8, "{line}");
        scenes.insert(cells[0].to_string());
        let numbers: Vec<f64> = cells[2..7].iter().map(|c| c.parse().unwrap()).collect();
        assert!(numbers.iter().all(|x| x.is_finite()), "{line}");
        // dt in (0, 0.1] s, a positive cost below 10 s per simulated second, errors ≥ 0.
        assert!(numbers[0] > 0.0 && numbers[0] <= 0.1, "{line}");
        assert!(numbers[1] > 0.0 && numbers[1] < 1e7, "{line}");
        assert!(numbers[2] >= 0.0 && numbers[4] >= 0.0, "{line}");
        assert!(cells[7] == "true" || cells[7] == "false");
        rows += 1;
    }
    assert!(rows >= 20, "{rows} rows");
    for scene in
        ["pendulum5", "dzhanibekov", "chain30", "bouncing_ball", "sliding_box", "stack10", "four_bar"]
    {
        assert!(scenes.contains(scene), "{scene} missing from {scenes:?}");
    }
    // On the pendulum, RK4 at 2 ms is far more accurate than semi-implicit Euler at 1 ms.
    let error_of = |cfg: &str, dt: &str| -> f64 {
        csv.lines()
            .find(|l| l.starts_with(&format!("pendulum5,{cfg},{dt},")))
            .map(|l| l.split(',').nth(4).unwrap().parse().unwrap())
            .unwrap_or_else(|| panic!("no pendulum5 row for {cfg} {dt}"))
    };
    assert!(error_of("RK4", "2e-3") < 1e-3 * error_of("semi-implicit Euler", "1e-3"));
    // A step longer than the 40 ms sample interval is compared on its own grid: RK8 at 50 ms
    // reaches MuJoCo's RK4 at 10 ms (2.6e-4 rad; ours measures 1.5e-4), far above the quick
    // reference's own error (GBS 6 columns at 4 ms, below 1e-9 rad).
    let rk8_50ms = error_of("RK8", "5e-2");
    assert!(rk8_50ms > 1e-5 && rk8_50ms < 2.6e-4, "{rk8_50ms}");
    let md = std::fs::read_to_string(dir.join("speed_error.md")).unwrap();
    assert!(md.contains("MuJoCo") && md.contains("pendulum5") && md.contains('★'), "{md}");
    let png = std::fs::read(dir.join("speed_error.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let svg = std::fs::read_to_string(dir.join("speed_error.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("Pareto front"));
    std::fs::remove_dir_all(&dir).ok();
}

/// `bench world --controls` steps a scene as `simulate` does, its vehicle commands applied: the
/// buggy's motors then add rows that the standing buggy of a plain `bench world` never has.
#[test]
fn bench_world_applies_vehicle_commands_when_asked() {
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/buggy_drive.toml");
    let scene = scene.display().to_string();
    let max_rows = |controls: bool| {
        let mut args = vec!["bench", "world", &scene, "--rounds", "1", "--steps", "600", "--json"];
        if controls {
            args.push("--controls");
        }
        let out = gelenk(&args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        v["max_rows"].as_u64().unwrap()
    };
    let (standing, driven) = (max_rows(false), max_rows(true));
    assert!(driven > standing, "{driven} rows driven, {standing} standing");
    // Zero episodes or steps would time nothing: refused, not reported as a median of nothing.
    for option in ["--rounds", "--steps"] {
        let out = gelenk(&["bench", "world", &scene, option, "0"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains("at least 1"), "{option} 0: {err}");
    }
}

/// `bench world` reports what its timed episode answered as `simulate` does: the ragdoll's
/// fall from step 0 (its scene's chain, pgs30 with the last answer accepted) has the same
/// deepest penetration, steps above the tolerance, largest residual and islands in both.
#[test]
fn bench_world_reports_penetration_residuals_and_islands_as_simulate_does() {
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ragdoll_fall.toml");
    let scene = scene.display().to_string();
    let run = |args: &[&str]| -> Value {
        let out = gelenk(args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_slice(&out.stdout).unwrap()
    };
    // bench world turns sleeping off; the fall is awake for its first second anyway.
    let bench = run(&["bench", "world", &scene, "--rounds", "1", "--steps", "500", "--json"]);
    let simulate = run(&["simulate", &scene, "--duration", "1.0", "--json"]);
    for key in ["max_penetration", "steps_above_tolerance", "max_residual", "max_islands", "largest_island"] {
        assert_eq!(bench[key], simulate[key], "{key}: bench {} simulate {}", bench[key], simulate[key]);
    }
    assert!(bench["max_penetration"].as_f64().unwrap() > 0.0);
}

/// `simulate --json` prints the run's summary as `RunSummary` serializes itself, and `--out`
/// writes the recorded states: the initial state and every fifth step (the scene's `[record]`).
#[test]
fn simulate_prints_its_summary_and_records_the_states() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/models/ball_bounce.toml");
    let csv = std::env::temp_dir().join(format!("gelenk_simulate_{}.csv", std::process::id()));
    let out = gelenk(&[
        "simulate",
        scene,
        "--duration",
        "0.2",
        "--dt",
        "0.002",
        "--json",
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["steps"], 100);
    assert_eq!(v["dt"], 0.002);
    let solved = v["solved_steps"].as_u64().unwrap();
    let used: u64 = v["solver_usage"].as_object().unwrap().values().map(|n| n.as_u64().unwrap()).sum();
    assert_eq!(used, solved, "every step with rows took one solver's answer");
    assert_eq!(v["phase_time"].as_array().unwrap().len(), 7);
    let drift = v["energy_end"].as_f64().unwrap() - v["energy_start"].as_f64().unwrap();
    assert_eq!(v["energy_drift"].as_f64().unwrap(), drift);
    assert!(v.get("recording").is_none(), "the recording goes to --out, not into the summary");
    let text = std::fs::read_to_string(&csv).unwrap();
    std::fs::remove_file(&csv).ok();
    assert!(text.starts_with("step,time,"), "{text}");
    assert_eq!(text.lines().count(), 1 + 21, "header, steps 0, 5, …, 100");
    // The text summary names the same run.
    let out = gelenk(&["simulate", scene, "--duration", "0.2", "--dt", "0.002"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.starts_with("ball_bounce: 100 steps of 0.002 s"), "{text}");
    assert!(text.contains(&format!("solver: {solved} steps with rows")), "{text}");
    let phases = text.lines().find_map(|l| l.strip_prefix("mean µs per phase: ")).expect("the phases' line");
    let names: Vec<&str> = phases.split(", ").map(|p| p.split(' ').next().unwrap()).collect();
    assert_eq!(names, gelenk::world::PHASE_NAMES);
}

/// `--softness-damping` sets the rows' damper share for `simulate` and `bench world`; a value
/// outside [0, 1] is one line on stderr and a non-zero status.
#[test]
fn softness_damping_is_a_flag_checked_as_a_fraction() {
    let scene = model_path("ragdoll_fall.toml");
    let ok = gelenk(&[
        "simulate",
        &scene,
        "--duration",
        "0.05",
        "--softness",
        "0.05",
        "--softness-damping",
        "0.5",
        "--json",
    ]);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    for command in
        [&["simulate", &scene][..], &["bench", "world", &scene, "--steps", "2", "--rounds", "1"][..]]
    {
        let args: Vec<&str> = command.iter().copied().chain(["--softness-damping", "1.5"]).collect();
        let out = gelenk(&args);
        assert!(!out.status.success(), "{command:?} accepted 1.5");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.contains("softness") && stderr.contains("[0, 1]") && stderr.lines().count() == 1,
            "{stderr}"
        );
    }
}
