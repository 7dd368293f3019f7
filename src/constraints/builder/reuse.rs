//! The rows a problem's W was built from, kept so that a step with the same rows (a body at
//! rest) keeps W and renews only the bias.

use super::{ProblemBuilder, RowForm, RowsMark};
use crate::constraints::RowLaw;
use crate::math::Vec3;

/// The Jacobian rows a problem's W was last built from, as the builder held them: when a
/// step's rows are the same up to a tolerance and the mass-matrix factors are the ones W was
/// built on, W = J L⁻¹ D^{-1/2} (and A = W Wᵀ, when formed) stand, and only the bias
/// J v_free − u* is new ([`ProblemBuilder::refresh_bias`]). The buffers are kept between steps.
#[derive(Clone, Debug, Default)]
pub(crate) struct BuiltRows {
    /// Whether the rows below are those of the problem's W.
    valid: bool,
    blocks: Vec<(usize, usize)>,
    forms: Vec<RowForm>,
    rates: Vec<(usize, Vec3)>,
    row_segments: Vec<usize>,
    segment_block: Vec<usize>,
    values: Vec<f64>,
    laws: Vec<RowLaw>,
}

impl BuiltRows {
    /// Records `builder`'s rows as those W was just built from (copies; no allocation once the
    /// buffers have grown to the rows' size).
    pub(crate) fn record(&mut self, builder: &ProblemBuilder) {
        self.valid = true;
        self.blocks.clone_from(&builder.blocks);
        self.forms.clone_from(&builder.forms);
        self.rates.clone_from(&builder.rates);
        self.row_segments.clone_from(&builder.row_segments);
        self.segment_block.clone_from(&builder.segment_block);
        self.values.clone_from(&builder.values);
        self.laws.clone_from(&builder.laws);
    }

    /// Forgets the recorded rows (the problem was replaced).
    pub(crate) fn forget(&mut self) {
        self.valid = false;
    }

    /// Whether `builder`'s rows are the recorded ones: the same rows, laws, blocks and columns,
    /// and every Jacobian entry (a contact's direction and point rates, a joint row's
    /// coefficients, stored entries) within `tolerance` of the recorded one, relative to the
    /// larger of 1 and its size (directions are unit, point rates m per rad or 1). The rows
    /// before `unchanged` (if given) are known to be the recorded ones bit for bit (kept from
    /// the step W was built in): their entries are not compared.
    pub(crate) fn same_rows(
        &self,
        builder: &ProblemBuilder,
        tolerance: f64,
        unchanged: Option<RowsMark>,
    ) -> bool {
        let from = unchanged.unwrap_or_default();
        // Branch-free (`&`, not `&&`) over the many point rates: one compare per entry.
        let close = |a: f64, b: f64| (a - b).abs() <= tolerance * b.abs().max(1.0);
        let close3 = |a: &Vec3, b: &Vec3| close(a.x, b.x) & close(a.y, b.y) & close(a.z, b.z);
        let same_form = |a: &RowForm, b: &RowForm| match (a, b) {
            (RowForm::Stored, RowForm::Stored) => true,
            (RowForm::Rates(a), RowForm::Rates(b)) => {
                a.sides == b.sides && close3(&a.direction, &b.direction)
            }
            (
                RowForm::Joint { first, coefficients, len },
                RowForm::Joint { first: first_b, coefficients: coefficients_b, len: len_b },
            ) => {
                first == first_b
                    && len == len_b
                    && coefficients[..*len].iter().zip(coefficients_b).all(|(a, b)| close(*a, *b))
            }
            _ => false,
        };
        self.valid
            && self.blocks == builder.blocks
            && self.laws == builder.laws
            && self.row_segments == builder.row_segments
            && self.segment_block == builder.segment_block
            && self.rates.len() == builder.rates.len()
            && self.values.len() == builder.values.len()
            && self.forms.len() == builder.forms.len()
            && builder.forms[from.rows..].iter().zip(&self.forms[from.rows..]).all(|(a, b)| same_form(a, b))
            && builder.rates[from.rates..]
                .iter()
                .zip(&self.rates[from.rates..])
                .fold(true, |same, (a, b)| same & (a.0 == b.0) & close3(&a.1, &b.1))
            && builder.values[from.values..]
                .iter()
                .zip(&self.values[from.values..])
                .fold(true, |same, (a, b)| same & close(*a, *b))
    }
}
