//! The report's types: its rows, the measures of each scene, MuJoCo's points and the goal
//! check, and the error; shared by the runner, the scenes and the plot.

use crate::error::{MjcfError, ModelError};
use crate::integrators::IntegratorError;
use crate::world::StepError;
use std::path::PathBuf;
use thiserror::Error;

/// Why the report could not be made.
#[derive(Debug, Error)]
pub enum ReportError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The pendulum's MJCF could not be loaded.
    #[error("pendulum5.xml: {0}")]
    Mjcf(#[from] MjcfError),
    /// A scene's model is invalid (a bug in the scene).
    #[error("scene model: {0}")]
    Model(#[from] ModelError),
    /// The reference run failed.
    #[error("integration: {0}")]
    Integrator(#[from] IntegratorError),
    /// A world could not be built or stepped.
    #[error("world: {0}")]
    Step(#[from] StepError),
    /// The collision geometry of a scene is invalid.
    #[error("collision: {0}")]
    Collision(#[from] crate::error::CollisionError),
    /// The reference step does not divide the sample interval (a bug in the suite).
    #[error("{scene}: the reference step {dt} s does not divide the sample interval")]
    Reference {
        /// Scene name.
        scene: String,
        /// Reference step (s).
        dt: f64,
    },
    /// A scene asked for by name does not exist.
    #[error("unknown scene `{0}` (pendulum5, dzhanibekov, chain30, bouncing_ball, sliding_box, stack10, four_bar)")]
    UnknownScene(String),
    /// Drawing the plot failed.
    #[error("plot {path}: {message}")]
    Plot {
        /// The file.
        path: String,
        /// The backend's message.
        message: String,
    },
}

/// What to run.
#[derive(Clone, Debug)]
pub struct SpeedErrorOptions {
    /// A subset that runs in seconds (CI).
    pub quick: bool,
    /// Directory holding `pendulum5.xml` and MuJoCo's figures (`README.md`), normally
    /// `benches/peers`.
    pub peers_dir: PathBuf,
    /// Timed repeats per configuration; the median is reported.
    pub repeats: usize,
    /// Run only these scenes (names as in [`SCENES`]); empty runs them all.
    pub scenes: Vec<String>,
}

/// One configuration at one step size.
#[derive(Clone, Debug, PartialEq)]
pub struct Measurement {
    /// Scene name.
    pub scene: String,
    /// Integrator (smooth scenes) or solver chain (contact scenes).
    pub configuration: String,
    /// Time step (s); for the adaptive integrator the mean accepted step.
    pub dt: f64,
    /// Wall time per simulated second (µs).
    pub cost_us: f64,
    /// The scene's primary error (see [`SceneMeasures`]).
    pub error: f64,
    /// The scene's energy measure.
    pub energy: f64,
    /// The scene's secondary measure.
    pub secondary: f64,
}

/// What the three measure columns mean for a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneMeasures {
    /// Scene name.
    pub scene: &'static str,
    /// The primary error (plotted).
    pub error: &'static str,
    /// The energy measure.
    pub energy: &'static str,
    /// The secondary measure.
    pub secondary: &'static str,
}

/// The measures of every scene, in report order.
pub const SCENES: [SceneMeasures; 7] = [
    SceneMeasures {
        scene: "pendulum5",
        error: "max joint error at T (rad)",
        energy: "energy drift (E(T)−E₀)/(E₀−E_rest)",
        secondary: "max joint error over the run (rad)",
    },
    SceneMeasures {
        scene: "dzhanibekov",
        error: "flip period error (relative)",
        energy: "kinetic energy drift (relative)",
        secondary: "angular momentum drift (relative)",
    },
    SceneMeasures {
        scene: "chain30",
        error: "max joint error at T (rad)",
        energy: "energy drift (E(T)−E₀)/(E₀−E_rest)",
        secondary: "max joint error over the run (rad)",
    },
    SceneMeasures {
        scene: "bouncing_ball",
        error: "apex error vs ε²ⁿh, n ≤ 3 (relative)",
        energy: "energy change (relative)",
        secondary: "max penetration (m)",
    },
    SceneMeasures {
        scene: "sliding_box",
        error: "stopping distance error vs v₀²/(2μg) (relative)",
        energy: "energy change (relative)",
        secondary: "max penetration (m)",
    },
    SceneMeasures {
        scene: "stack10",
        error: "largest box displacement (m)",
        energy: "energy change (relative)",
        secondary: "max penetration (m)",
    },
    SceneMeasures {
        scene: "four_bar",
        error: "max loop-closure error (m)",
        energy: "energy change (relative)",
        secondary: "max penetration (m)",
    },
];

/// One of MuJoCo's points for the pendulum (benches/peers/README.md).
#[derive(Clone, Debug, PartialEq)]
pub struct PeerPoint {
    /// Integrator name as MuJoCo's table writes it.
    pub integrator: String,
    /// Time step (s).
    pub dt: f64,
    /// Milliseconds per simulated second, converted to µs.
    pub cost_us: f64,
    /// Relative energy drift.
    pub energy: f64,
    /// Max joint error (rad).
    pub error: f64,
}

/// The goal check at one of MuJoCo's Pareto points: gelenk's cheapest configuration with an
/// error no larger.
#[derive(Clone, Debug, PartialEq)]
pub struct GoalPoint {
    /// MuJoCo's point.
    pub mujoco: PeerPoint,
    /// gelenk's cheapest measurement at that error or better, if any.
    pub gelenk: Option<Measurement>,
}

impl GoalPoint {
    /// gelenk's cost over MuJoCo's (infinite when no gelenk configuration reaches the error).
    pub fn ratio(&self) -> f64 {
        self.gelenk.as_ref().map_or(f64::INFINITY, |g| g.cost_us / self.mujoco.cost_us)
    }
}

/// The whole report.
#[derive(Clone, Debug, Default)]
pub struct SpeedErrorReport {
    /// Every finished measurement.
    pub rows: Vec<Measurement>,
    /// Configurations that failed (diverged to a non-finite state) or were skipped as too
    /// expensive: scene, configuration, dt, why.
    pub failed: Vec<(String, String, f64, String)>,
    /// MuJoCo's pendulum figures, when the peers' README was found.
    pub mujoco: Vec<PeerPoint>,
    /// The goal check at each of MuJoCo's Pareto points.
    pub goal: Vec<GoalPoint>,
    /// Notes: reference accuracy, build profile.
    pub notes: Vec<String>,
    /// Whether this was the quick subset.
    pub quick: bool,
}

impl SpeedErrorReport {
    /// True when at every one of MuJoCo's Pareto points gelenk's best costs at most half.
    pub fn goal_met(&self) -> bool {
        !self.goal.is_empty() && self.goal.iter().all(|g| g.ratio() <= 0.5)
    }
}

/// The measure names of `scene`.
pub fn measures(scene: &str) -> SceneMeasures {
    SCENES.iter().copied().find(|m| m.scene == scene).unwrap_or(SceneMeasures {
        scene: "",
        error: "error",
        energy: "energy",
        secondary: "secondary",
    })
}

/// The Pareto front of (cost, error) points: indices sorted by cost, each with an error below
/// every cheaper one's.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| points[a].0.total_cmp(&points[b].0).then(points[a].1.total_cmp(&points[b].1)));
    let mut best = f64::INFINITY;
    let mut front = Vec::new();
    for i in order {
        if points[i].1 < best {
            best = points[i].1;
            front.push(i);
        }
    }
    front
}
