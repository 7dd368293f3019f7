//! Contact rows kept between steps while nothing they are made of has moved.
//!
//! A contact's three rows are its normal and tangents dotted with the point rates of its two
//! points ([`crate::collision::point_rates`]): the world velocity of each point per unit rate of
//! every dof on its body's path to the root, from the joint Jacobian columns at q. They depend on
//! the multibodies' coordinates q, on the contact points and normal, and on the contact's
//! parameters (friction, softness over h); only their targets (the approach speed, the gap)
//! change with the velocities and distances of a step. A ragdoll lying still forms the same
//! rows, to the last few digits, step after step (its W = J L⁻¹ D^{-1/2} is already kept, see
//! [`super::WorldOptions::mass_matrix_reuse`]); while every coordinate, contact point and normal
//! stays within that tolerance (rad, m) of where the rows were formed, and the contacts with rows
//! are the same (count, colliders, speculation), the step keeps the rows and forms only their
//! targets.

use super::Multibody;
use crate::collision::Contact;
use crate::constraints::RowsMark;
use crate::math::Vec3;

/// One contact of the step the kept rows were formed in.
#[derive(Clone, Copy, Debug)]
struct Formed {
    colliders: (usize, usize),
    has_rows: bool,
    point_a: Vec3,
    point_b: Vec3,
    normal: Vec3,
}

/// The contact rows at the start of the world's [`crate::constraints::ProblemBuilder`] and what
/// they were formed from.
#[derive(Clone, Debug, Default)]
pub(super) struct KeptContactRows {
    /// Whether the builder still starts with the rows recorded here.
    valid: bool,
    h: f64,
    /// Every multibody's q, one after the other.
    q: Vec<f64>,
    contacts: Vec<Formed>,
    /// Where the contact rows end in the builder.
    mark: RowsMark,
    /// Counts the records: rows of one generation are the same bits.
    generation: u64,
    /// Steps that kept the rows.
    pub(super) reuses: u64,
}

impl KeptContactRows {
    /// The builder no longer starts with the recorded rows (cleared, replaced, or what the rows
    /// depend on was edited).
    pub(super) fn invalidate(&mut self) {
        self.valid = false;
    }

    /// The generation of the contact rows the builder starts with and where they end, if
    /// recorded: rows of the same generation are the same bits.
    pub(super) fn current(&self) -> Option<(u64, RowsMark)> {
        self.valid.then_some((self.generation, self.mark))
    }

    /// Records the contact rows just formed from `contacts` (`has_rows[i]`: contact i got
    /// rows), ending at `mark` in the builder.
    pub(super) fn record(
        &mut self,
        h: f64,
        bodies: &[Multibody],
        contacts: &[Contact],
        has_rows: &[bool],
        mark: RowsMark,
    ) {
        self.valid = true;
        self.generation += 1;
        self.h = h;
        self.q.clear();
        for b in bodies {
            self.q.extend_from_slice(b.state.q.as_slice());
        }
        self.contacts.clear();
        self.contacts.extend(contacts.iter().zip(has_rows).map(|(c, &has_rows)| Formed {
            colliders: (c.collider_a, c.collider_b),
            has_rows,
            point_a: c.point_a,
            point_b: c.point_b,
            normal: c.normal,
        }));
        self.mark = mark;
    }

    /// Where the recorded rows end in the builder if they are this step's: the same step
    /// length, every coordinate within `tolerance` of the recorded one, the same contacts in the
    /// same order (colliders, and which get rows) with the points and normal of each that gets
    /// rows within `tolerance` (m; the normal's components). None otherwise.
    pub(super) fn hold(
        &self,
        tolerance: f64,
        h: f64,
        bodies: &[Multibody],
        contacts: &[Contact],
        has_rows: &[bool],
    ) -> Option<RowsMark> {
        if !self.valid || self.h != h || self.contacts.len() != contacts.len() {
            return None;
        }
        let close = |a: &Vec3, b: &Vec3| (a - b).amax() <= tolerance;
        let same_contacts = self.contacts.iter().zip(contacts).zip(has_rows).all(|((f, c), &rows)| {
            f.colliders == (c.collider_a, c.collider_b)
                && f.has_rows == rows
                && (!rows
                    || close(&f.point_a, &c.point_a)
                        && close(&f.point_b, &c.point_b)
                        && close(&f.normal, &c.normal))
        });
        if !same_contacts {
            return None;
        }
        let mut recorded = self.q.iter();
        let same_q = bodies
            .iter()
            .all(|b| b.state.q.iter().all(|x| recorded.next().is_some_and(|r| (x - r).abs() <= tolerance)));
        (same_q && recorded.next().is_none()).then_some(self.mark)
    }
}
