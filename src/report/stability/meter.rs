//! The cost and the time budget of one cell: every step a case takes goes through [`step`],
//! which times [`World::step`] alone (not the scene's set-up nor the case's measurements) and
//! stops the case with [`CaseError::Timeout`] once the cell's budget is spent.
//!
//! The meter is per thread: [`measure`] arms it around one cell and returns what it counted; a
//! case called directly (as the tests do) runs unmetered and without a budget.

use crate::world::{StepError, StepStats, World};
use std::cell::Cell;
use std::fmt;
use std::time::{Duration, Instant};

/// Why a case ended without an outcome.
#[derive(Debug)]
pub enum CaseError {
    /// A step failed.
    Step(StepError),
    /// The cell's time budget ([`measure`]) was spent before the case finished.
    Timeout {
        /// The budget (s).
        budget: f64,
    },
}

impl fmt::Display for CaseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CaseError::Step(e) => write!(f, "{e}"),
            CaseError::Timeout { budget } => {
                write!(f, "timeout: the case needs more than its {budget} s budget")
            }
        }
    }
}

impl std::error::Error for CaseError {}

impl From<StepError> for CaseError {
    fn from(e: StepError) -> Self {
        CaseError::Step(e)
    }
}

/// What one cell's steps cost.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Meter {
    /// Steps taken (every world of the case).
    pub steps: u64,
    /// Wall-clock seconds inside [`World::step`].
    pub step_seconds: f64,
}

impl Meter {
    /// Mean wall-clock cost of one step (µs); `None` before any step.
    pub fn micros_per_step(&self) -> Option<f64> {
        (self.steps > 0).then(|| 1e6 * self.step_seconds / self.steps as f64)
    }
}

thread_local! {
    static METER: Cell<Meter> = const { Cell::new(Meter { steps: 0, step_seconds: 0.0 }) };
    static DEADLINE: Cell<Option<(Instant, f64)>> = const { Cell::new(None) };
}

/// Runs `f` (one cell) with the meter zeroed and, with `budget`, a deadline that far ahead:
/// its result and what its steps cost.
pub fn measure<T>(budget: Option<Duration>, f: impl FnOnce() -> T) -> (T, Meter) {
    METER.with(|m| m.set(Meter::default()));
    DEADLINE.with(|d| d.set(budget.map(|b| (Instant::now() + b, b.as_secs_f64()))));
    let result = f();
    DEADLINE.with(|d| d.set(None));
    (result, METER.with(Cell::get))
}

/// One step of `w`, timed, unless the cell's deadline has passed.
pub(super) fn step(w: &mut World) -> Result<&StepStats, CaseError> {
    if let Some((deadline, budget)) = DEADLINE.with(Cell::get) {
        if Instant::now() >= deadline {
            return Err(CaseError::Timeout { budget });
        }
    }
    let start = Instant::now();
    let result = w.step();
    let elapsed = start.elapsed().as_secs_f64();
    METER.with(|m| {
        let mut meter = m.get();
        meter.steps += 1;
        meter.step_seconds += elapsed;
        m.set(meter);
    });
    Ok(result?)
}
