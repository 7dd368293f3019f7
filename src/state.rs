//! The simulation state the user owns.

use crate::model::Model;
use nalgebra::DVector;

/// The state of one multibody: configuration `q` (length nq), generalized velocity `v` (length
/// nv) and time `t` (s). Plain data: save it, copy it, restore it.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Generalized configuration, in the model's joint order.
    pub q: DVector<f64>,
    /// Generalized velocity, in the model's joint order.
    pub v: DVector<f64>,
    /// Time (s).
    pub t: f64,
}

impl State {
    /// The neutral configuration at rest at t = 0.
    pub fn new(model: &Model) -> Self {
        Self { q: model.neutral_configuration(), v: DVector::zeros(model.nv()), t: 0.0 }
    }
}
