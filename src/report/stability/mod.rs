//! Numerical stability on hard cases: each [`Case`] is a scene plus a quantitative criterion,
//! run through the [`crate::world::World`] with the default solver chain or one solver alone and
//! one time step (a [`Setting`]) and returning the measured figure ([`Outcome`]).
//! `tests/hard_cases.rs` asserts the criteria at chosen settings; [`run`] fills the table of
//! every case × column × dt that `gelenk report stability` writes as markdown and CSV — the same
//! code measures both. Each cell's steps are timed and bounded by a wall-clock budget
//! ([`measure`]).
//!
//! A setting also names the world's integrator ([`WorldOptions::integrator`]): the default,
//! semi-implicit Euler, is the velocity-level step throughout; another scheme advances the
//! steps without contact ([`crate::world::smooth`]). Two criteria of the issue need it: the
//! Dzhanibekov spin (energy and angular momentum to 1e-6) and the four-bar's energy drift
//! (1e-4) hold with a smooth scheme ([`SMOOTH_CASES`], which the report also runs with
//! [`SMOOTH_INTEGRATORS`]); the velocity-level step has its own bounds for them. The 100-link chain
//! with a 1000:1 end mass (|ΔE/E| < 1e-6) is tested with RK4 outside the world, not a case.

use crate::integrators::IntegratorKind;
use crate::world::{integrator_name, SolverKind, WorldOptions};
use std::time::Duration;

mod cases;
mod meter;

pub use meter::{measure, CaseError, Meter};

/// The four-bar linkage of [`crate::scenes::four_bar_world`].
pub use crate::scenes::four_bar_world;
/// A model of one free body ([`crate::scenes::free_body`]).
pub use crate::scenes::free_body;

use cases::*;
pub use cases::{
    ball_on_incline, dzhanibekov_reference_period, sliding_distance, state_hash, t_body_inertia,
    tumbling_hash, tunnels,
};

/// One solver (alone in the chain, its answer always accepted) or the world's default solver
/// chain, one time step and the world's integrator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setting {
    /// The solver (ignored with `default_chain`).
    pub solver: SolverKind,
    /// The world's default solver chain, tolerance and fallback rule
    /// ([`WorldOptions::default`]), the settings a user gets without choosing, instead of
    /// `solver` alone.
    pub default_chain: bool,
    /// Time step (s).
    pub dt: f64,
    /// The integrator of steps without contact ([`WorldOptions::integrator`]).
    pub integrator: IntegratorKind,
}

impl Setting {
    /// Short solver label: `default`, `lemke`, `clarabel`, `newton`, `newton-exact`, `pgs10`,
    /// `pgs50`.
    pub fn solver_label(&self) -> String {
        if self.default_chain {
            return "default".into();
        }
        match self.solver {
            SolverKind::Lemke { .. } => "lemke".into(),
            SolverKind::Clarabel => "clarabel".into(),
            SolverKind::Newton => "newton".into(),
            SolverKind::NewtonExact => "newton-exact".into(),
            SolverKind::Pgs { iterations, .. } => format!("pgs{iterations}"),
        }
    }

    /// The setting of `solver` and `dt` with the world's default integrator (semi-implicit
    /// Euler, the velocity-level step).
    pub fn new(solver: SolverKind, dt: f64) -> Self {
        Self { solver, default_chain: false, dt, integrator: IntegratorKind::SemiImplicitEuler }
    }

    /// The setting of the world's default solver chain and `dt` with the default integrator.
    pub fn default_chain(dt: f64) -> Self {
        let solver = WorldOptions::default().solvers[0];
        Self { default_chain: true, ..Self::new(solver, dt) }
    }

    /// The setting of `column` and `dt` with the default integrator.
    pub fn of(column: Column, dt: f64) -> Self {
        match column {
            Column::Default => Self::default_chain(dt),
            Column::Solver(solver) => Self::new(solver, dt),
        }
    }
}

/// A column of the report: the world's default chain, or one solver alone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Column {
    /// The world's default solver chain ([`Setting::default_chain`]).
    Default,
    /// One solver alone, its answer always accepted.
    Solver(SolverKind),
}

impl Column {
    /// `default`, or a solver name ([`SolverKind::parse`]).
    pub fn parse(name: &str) -> Option<Self> {
        if name == "default" {
            Some(Column::Default)
        } else {
            SolverKind::parse(name).map(Column::Solver)
        }
    }
}

/// The cases without any contact, where the integrator decides the result: the report runs
/// them with each of [`SMOOTH_INTEGRATORS`] too.
pub const SMOOTH_CASES: [&str; 2] = ["dzhanibekov", "four_bar"];

/// The integrators the report tries on [`SMOOTH_CASES`] besides the default.
pub const SMOOTH_INTEGRATORS: [IntegratorKind; 1] = [IntegratorKind::Rk4];

/// The solvers of the report: Lemke (8-facet pyramid), clarabel, PGS with 10 and 50 sweeps.
pub const SOLVERS: [SolverKind; 4] = [
    SolverKind::Lemke { facets: 8 },
    SolverKind::Clarabel,
    SolverKind::Pgs { iterations: 10, omega: 1.0 },
    SolverKind::Pgs { iterations: 50, omega: 1.0 },
];

/// The columns of the report: the default chain, then [`SOLVERS`].
pub const COLUMNS: [Column; 5] = [
    Column::Default,
    Column::Solver(SOLVERS[0]),
    Column::Solver(SOLVERS[1]),
    Column::Solver(SOLVERS[2]),
    Column::Solver(SOLVERS[3]),
];

/// The time steps of the report (s).
pub const TIME_STEPS: [f64; 3] = [1.0 / 60.0, 1.0 / 240.0, 1.0 / 1000.0];

/// What a case measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// The measured figure (in the case's unit).
    pub figure: f64,
    /// Whether the criterion holds.
    pub pass: bool,
    /// Secondary figures and observations (e.g. the cradle's final velocities).
    pub detail: String,
}

/// A hard case: a scene and its criterion.
#[derive(Clone, Copy, Debug)]
pub struct Case {
    /// Identifier (`stack10`, `cradle`, ...).
    pub name: &'static str,
    /// The criterion, in words, with its bound.
    pub criterion: &'static str,
    /// What [`Outcome::figure`] is.
    pub figure: &'static str,
    /// Whether the report runs Lemke on the case (false: skipped as too slow).
    pub lemke: bool,
    /// Runs the case.
    pub run: fn(&Setting) -> Result<Outcome, CaseError>,
}

/// Every case, in report order.
pub const CASES: [Case; 15] = [
    Case {
        name: "stack10",
        criterion: "10 boxes, 10 s: top drift < 1 % of the box (1 mm), penetration < margin; default chain: ≤ 1 % of steps fall back",
        figure: "top drift (m)",
        lemke: true,
        run: stack10,
    },
    Case {
        name: "stack20",
        criterion: "20 boxes, 10 s: top drift < 1 mm, penetration < margin; default chain: ≤ 1 % of steps fall back",
        figure: "top drift (m)",
        lemke: true,
        run: stack20,
    },
    Case {
        name: "pyramid10",
        criterion: "pyramid of 55 boxes (base 10), 10 s: top drift < 1 mm, penetration < margin; default chain: ≤ 1 % of steps fall back",
        figure: "top drift (m)",
        lemke: true,
        run: pyramid10,
    },
    Case {
        name: "heavy_on_light",
        criterion: "1000 kg box on a 1 kg box, 10 s: drift < 1 mm, penetration < margin; default chain: ≤ 1 % of steps fall back",
        figure: "top drift (m)",
        lemke: true,
        run: heavy_on_light,
    },
    Case {
        name: "cradle",
        criterion: "Newton's cradle, 5 balls, ε = 1: |Δp| < 1e-12, energy never grows (beyond round-off and the solve's residual tolerance τ: ΔE ≤ τ Σ m‖v‖)",
        figure: "|Δp| (kg·m/s)",
        lemke: true,
        run: cradle,
    },
    Case {
        name: "dzhanibekov",
        criterion: "T-body at ω = (10, 1, 0) rad/s, 10 s: velocity-level step: energy never grows, |ΔL|/L ≤ 1e-2, flip period within 5 %; other integrators: |ΔL|/L and |ΔE|/E < 1e-6, flip period within 1 %",
        figure: "max(|ΔL|/L, |ΔE|/E)",
        lemke: true,
        run: dzhanibekov,
    },
    Case {
        name: "four_bar",
        criterion: "four-bar, 10 s: closure < 1e-8 m, |ΔE| < 2 % (velocity-level step) or 1e-4 (other integrators) of the largest kinetic energy",
        figure: "closure error (m)",
        lemke: true,
        run: four_bar,
    },
    Case {
        name: "suspension",
        criterion: "hinge2 suspension, k·dt²/m = 1e-2 … 1e4: amplitude never grows",
        figure: "max |s − s₀| / |s₀|",
        lemke: true,
        run: suspension,
    },
    Case {
        name: "ramp5",
        criterion: "five boxes on a 20° ramp, μ = 0.25 … 0.5: stick iff μ ≥ tan θ (sliders within 5 %)",
        figure: "boxes right (of 5)",
        lemke: true,
        run: ramp5,
    },
    Case {
        name: "rolling_ball",
        criterion: "ball on a 20° incline, μ = 0.3: a = (5/7) g sin θ ± 1 %",
        figure: "relative error of a",
        lemke: true,
        run: rolling_ball,
    },
    Case {
        name: "sliding_box",
        criterion: "box at 2 m/s, μ = 0.5: stops after v₀²/(2μg) ± 2 %",
        figure: "relative error of the distance",
        lemke: true,
        run: sliding_box,
    },
    Case {
        name: "resting",
        criterion: "box resting on the ground, 10 s: |v| < 1e-6 m/s",
        figure: "max |v| (m/s)",
        lemke: true,
        run: resting,
    },
    Case {
        name: "fast_sphere",
        criterion: "1 cm sphere at 100 m/s against a 2 cm wall: does not tunnel",
        figure: "v·dt / (thickness + 2r)",
        lemke: true,
        run: fast_sphere,
    },
    Case {
        name: "far_origin",
        criterion: "ball thrown with spin at a (1e6, 1e6, 1e6) m offset = at the origin within 1e-6 relative",
        figure: "relative difference",
        lemke: true,
        run: far_origin,
    },
    Case {
        name: "determinism",
        criterion: "5 tumbling boxes: state hash after 1000 steps identical in two runs",
        figure: "runs differing (0/1)",
        lemke: true,
        run: determinism,
    },
];

/// The case named `name`.
pub fn case(name: &str) -> Option<&'static Case> {
    CASES.iter().find(|c| c.name == name)
}

/// World options of a setting: that solver alone (its answer accepted even above the
/// tolerance, so that the cell measures the solver, not a fallback) or the default chain as a
/// user gets it, sleeping off.
pub fn options(setting: &Setting) -> WorldOptions {
    let mut o = WorldOptions { dt: setting.dt, integrator: setting.integrator, ..Default::default() };
    if !setting.default_chain {
        o.solvers = vec![setting.solver];
        o.tolerance = 1e-8;
        o.accept_last = true;
    }
    o.sleep.enabled = false;
    o
}

/// What became of one cell.
#[derive(Clone, Debug, PartialEq)]
pub enum CellOutcome {
    /// The case ran: its figure and verdict.
    Done(Outcome),
    /// Not run (Lemke on the large problems, [`Case::lemke`]).
    Skipped,
    /// The cell's time budget was spent first (s).
    Timeout(f64),
    /// A step failed.
    Error(String),
}

/// One cell of the report.
#[derive(Clone, Debug)]
pub struct Cell {
    /// Case name.
    pub case: &'static str,
    /// Solver label.
    pub solver: String,
    /// Time step (s).
    pub dt: f64,
    /// Integrator name (`semi-implicit-euler`, `rk4`, ...).
    pub integrator: &'static str,
    /// What became of the cell.
    pub outcome: CellOutcome,
    /// Wall-clock seconds the cell took.
    pub seconds: f64,
    /// Its steps and the time spent in them.
    pub meter: Meter,
}

/// Runs `cases` for every column of `columns`, time step of `dts` and integrator of
/// `integrators` (a case outside [`SMOOTH_CASES`] only with the first integrator: its steps
/// have contacts, which the velocity-level step handles whatever the integrator), each cell
/// within `budget` of wall-clock time if given ([`CellOutcome::Timeout`] past it), calling
/// `progress` after each cell.
pub fn run(
    cases: &[Case],
    columns: &[Column],
    dts: &[f64],
    integrators: &[IntegratorKind],
    budget: Option<Duration>,
    mut progress: impl FnMut(&Cell),
) -> Vec<Cell> {
    let mut cells = Vec::new();
    for case in cases {
        let used = if SMOOTH_CASES.contains(&case.name) {
            integrators
        } else {
            &integrators[..1.min(integrators.len())]
        };
        for &dt in dts {
            for (&column, &integrator) in used.iter().flat_map(|i| columns.iter().map(move |c| (c, i))) {
                let setting = Setting { integrator, ..Setting::of(column, dt) };
                let start = std::time::Instant::now();
                let skipped = !setting.default_chain
                    && matches!(setting.solver, SolverKind::Lemke { .. })
                    && !case.lemke;
                let (outcome, meter) = if skipped {
                    (CellOutcome::Skipped, Meter::default())
                } else {
                    let (result, meter) = measure(budget, || (case.run)(&setting));
                    let outcome = match result {
                        Ok(o) => CellOutcome::Done(o),
                        Err(CaseError::Timeout { budget }) => CellOutcome::Timeout(budget),
                        Err(e) => CellOutcome::Error(e.to_string()),
                    };
                    (outcome, meter)
                };
                let cell = Cell {
                    case: case.name,
                    solver: setting.solver_label(),
                    dt,
                    integrator: integrator_name(&integrator),
                    outcome,
                    seconds: start.elapsed().as_secs_f64(),
                    meter,
                };
                progress(&cell);
                cells.push(cell);
            }
        }
    }
    cells
}

fn dt_label(dt: f64) -> String {
    format!("1/{}", (1.0 / dt).round())
}

/// The text of a cell in the table: the verdict, the figure and the cost of a step (µs).
pub fn cell_text(cell: &Cell) -> String {
    let cost = cell.meter.micros_per_step().map_or(String::new(), |us| format!(" ({})", micros(us)));
    match &cell.outcome {
        CellOutcome::Skipped => "skipped".into(),
        CellOutcome::Error(_) => format!("error{cost}"),
        CellOutcome::Timeout(_) => format!("timeout{cost}"),
        CellOutcome::Done(o) => format!("{} {:.2e}{cost}", if o.pass { "pass" } else { "FAIL" }, o.figure),
    }
}

/// A cost in µs with three significant digits at most.
fn micros(us: f64) -> String {
    if us >= 100.0 {
        format!("{us:.0} µs")
    } else if us >= 10.0 {
        format!("{us:.1} µs")
    } else {
        format!("{us:.2} µs")
    }
}

/// The report as a markdown table (one row per case, dt and integrator, one column per solver)
/// followed by the criteria and each cell's detail.
pub fn markdown(cells: &[Cell], cases: &[Case]) -> String {
    let mut solvers: Vec<String> = Vec::new();
    for c in cells {
        if !solvers.contains(&c.solver) {
            solvers.push(c.solver.clone());
        }
    }
    let mut out = format!(
        "| case | dt (s) | integrator | {} |\n|---|---|---|{}\n",
        solvers.join(" | "),
        "---|".repeat(solvers.len())
    );
    let mut rows: Vec<(&str, u64, &str)> = Vec::new();
    for c in cells {
        let key = (c.case, c.dt.to_bits(), c.integrator);
        if !rows.contains(&key) {
            rows.push(key);
        }
    }
    for (case, dt, integrator) in rows {
        let texts: Vec<String> = solvers
            .iter()
            .map(|s| {
                cells
                    .iter()
                    .find(|c| {
                        c.case == case && c.dt.to_bits() == dt && c.integrator == integrator && &c.solver == s
                    })
                    .map_or("—".into(), cell_text)
            })
            .collect();
        out += &format!(
            "| {case} | {} | {integrator} | {} |\n",
            dt_label(f64::from_bits(dt)),
            texts.join(" | ")
        );
    }
    out += "\nEach cell: pass or FAIL, the figure, and the mean wall-clock cost of one step (µs, \
            World::step alone); `default` is the chain a user gets without choosing \
            (WorldOptions::default()), the other columns one solver alone.\n";
    out += "\nCriteria (the figure in each cell):\n\n";
    for case in cases {
        if cells.iter().any(|c| c.case == case.name) {
            out += &format!("- `{}`: {} — figure: {}\n", case.name, case.criterion, case.figure);
        }
    }
    out += "\nDetails:\n\n";
    for c in cells {
        let detail = match &c.outcome {
            CellOutcome::Done(o) => o.detail.clone(),
            CellOutcome::Error(e) => format!("error: {e}"),
            CellOutcome::Timeout(budget) => format!("timeout after {budget} s ({} steps)", c.meter.steps),
            CellOutcome::Skipped => String::new(),
        };
        if !detail.is_empty() {
            out += &format!("- {} {} dt {} {}: {}\n", c.case, c.solver, dt_label(c.dt), c.integrator, detail);
        }
    }
    out
}

/// The report as CSV: `case,solver,dt,integrator,pass,figure,seconds,steps,us_per_step,detail`
/// (pass is `skipped`, `timeout` or `error` when the cell has no verdict; `seconds` the whole
/// cell, `us_per_step` the mean cost of a step).
pub fn csv(cells: &[Cell]) -> String {
    let mut out = String::from("case,solver,dt,integrator,pass,figure,seconds,steps,us_per_step,detail\n");
    for c in cells {
        let (pass, figure, detail) = match &c.outcome {
            CellOutcome::Skipped => ("skipped".to_string(), String::new(), String::new()),
            CellOutcome::Error(e) => ("error".to_string(), String::new(), e.clone()),
            CellOutcome::Timeout(budget) => {
                ("timeout".to_string(), String::new(), format!("budget {budget} s"))
            }
            CellOutcome::Done(o) => (o.pass.to_string(), format!("{:e}", o.figure), o.detail.clone()),
        };
        let cost = c.meter.micros_per_step().map_or(String::new(), |us| format!("{us:.3}"));
        out += &format!(
            "{},{},{},{},{},{},{:.3},{},{},\"{}\"\n",
            c.case,
            c.solver,
            c.dt,
            c.integrator,
            pass,
            figure,
            c.seconds,
            c.meter.steps,
            cost,
            detail.replace('"', "'")
        );
    }
    out
}
