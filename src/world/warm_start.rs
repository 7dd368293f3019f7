//! The warm start of λ: each row's impulse of the last step, matched by its key (the row's
//! origin: a contact's collider pair and feature, a joint's limit, motor, friction, a loop).
//!
//! Rows mostly come in the same order as last step (collision pairs and their features are
//! enumerated in a stable order), so keys are matched by a cursor over last step's rows; only a
//! row that breaks the order is looked up in an index, built at most once per step. A contact
//! whose key is new takes the impulses of last step's contact of the same collider pair nearest
//! to it (within [`WARM_MATCH_DISTANCE`]) that no other contact took: parry's feature ids of one
//! resting contact change from step to step (a capsule's segment against a box edge reports its
//! features, then none), and in a pile of 20 ragdolls 5 % of the contacts with rows would lose
//! their impulses every step that way. When the rows are the last solve's (its kept contact
//! rows, the same other rows in the same order: a body at rest), λ holds their impulses already
//! and no key is formed.
//!
//! Softened rows ([`crate::world::WorldOptions::softness`]) carry a second value per row, the
//! elastic part of its impulse that the softening is centred on; it is matched with the impulse.

use crate::collision::Contact;
use crate::constraints::{ConstraintProblem, RowOrigin};
use crate::math::{FastHasher, Vec3};
use nalgebra::DVector;
use std::collections::HashMap;

/// How far (m) a contact's point may have moved since the last step for it to take that
/// step's impulses of its collider pair when its feature key changed (the world's warm start).
/// Below the spacing of two contacts of one pair (a box's corners, a capsule's two ends), above
/// what a resting contact moves.
pub const WARM_MATCH_DISTANCE: f64 = 0.005;

/// Last step's row keys and impulses, and the buffers that match this step's rows to them.
#[derive(Default)]
pub(crate) struct WarmStart {
    /// Last step's row keys and impulses, in row order.
    keys: Vec<u64>,
    values: Vec<f64>,
    /// Last step's elastic impulses of softened rows, in row order (empty without softness).
    centres: Vec<f64>,
    /// The origins of last solve's rows and the generation of its kept contact rows (see
    /// `contact_rows`), and whether this step's rows are those rows.
    origins: Vec<RowOrigin>,
    generation: Option<u64>,
    pub(crate) same_rows: bool,
    /// Key → position in `keys`, built only in steps whose rows came in another order.
    index: HashMap<u64, usize, FastHasher>,
    /// This step's row keys (become `keys` once solved).
    row_keys: Vec<u64>,
    /// Last step's contacts with rows, for those whose key changed.
    contacts: Vec<WarmContact>,
    /// Per entry of `contacts`: matched by a contact of this step.
    taken: Vec<bool>,
    /// This step's rows that matched a key (their positions in `keys`) and that did not.
    matched: Vec<usize>,
    missed: Vec<usize>,
}

/// A contact of the last step with rows, for the warm start's second pass.
#[derive(Clone, Copy, Debug)]
struct WarmContact {
    pair: (usize, usize),
    /// Its point on collider A (world, m).
    point: Vec3,
    /// Its first row and number of rows in last step's problem.
    first_row: usize,
    rows: usize,
}

impl WarmStart {
    /// Writes into `lambda` the warm start of `problem`'s rows (see the module documentation),
    /// and into `centre`, when given, their elastic impulses of the last step (0 for a row that
    /// had none). `contacts`: the step's contacts, which the problem's contact rows name;
    /// `generation`: that of the kept contact rows the rows start with.
    pub(crate) fn start(
        &mut self,
        problem: &ConstraintProblem,
        contacts: &[Contact],
        generation: Option<u64>,
        lambda: &mut DVector<f64>,
        mut centre: Option<&mut DVector<f64>>,
    ) {
        let n = problem.rows();
        let centres_kept = self.centres.len() == n && centre.as_ref().is_some_and(|c| c.len() == n);
        // The rows of the last solve, in its order (its kept contact rows, the same other rows):
        // λ (and the centre) hold their values already.
        self.same_rows = generation.is_some()
            && generation == self.generation
            && lambda.len() == n
            && self.values.len() == n
            && (centre.is_none() || centres_kept)
            && problem.origins == self.origins;
        if self.same_rows {
            return;
        }
        if lambda.len() != n {
            *lambda = DVector::zeros(n);
        }
        if let Some(c) = centre.as_deref_mut() {
            if c.len() != n {
                *c = DVector::zeros(n);
            }
        }
        let centres = (self.centres.len() == self.values.len()).then_some(self.centres.as_slice());
        let mut counter = (0, u64::MAX);
        self.row_keys.clear();
        self.row_keys.extend((0..n).map(|i| row_key(problem, contacts, i, &mut counter)));
        let (mut cursor, mut indexed) = (0, false);
        self.matched.clear();
        self.missed.clear();
        for (i, key) in self.row_keys.iter().enumerate() {
            let found = if self.keys.get(cursor) == Some(key) {
                Some(cursor)
            } else {
                if !indexed {
                    self.index.clear();
                    self.index.extend(self.keys.iter().enumerate().map(|(p, k)| (*k, p)));
                    indexed = true;
                }
                self.index.get(key).copied()
            };
            match found {
                Some(p) => {
                    lambda[i] = self.values[p];
                    if let Some(c) = centre.as_deref_mut() {
                        c[i] = centres.map_or(0.0, |v| v[p]);
                    }
                    cursor = p + 1;
                    self.matched.push(p);
                }
                None => {
                    lambda[i] = 0.0;
                    if let Some(c) = centre.as_deref_mut() {
                        c[i] = 0.0;
                    }
                    self.missed.push(i);
                }
            }
        }
        if !self.missed.is_empty() {
            self.match_moved_contacts(problem, contacts, lambda, centre);
        }
    }

    /// The second pass of [`WarmStart::start`]: a contact none of whose rows matched a key
    /// takes the impulses of the nearest untaken contact of its pair with as many rows.
    fn match_moved_contacts(
        &mut self,
        problem: &ConstraintProblem,
        contacts: &[Contact],
        lambda: &mut DVector<f64>,
        mut centre: Option<&mut DVector<f64>>,
    ) {
        let centres = (self.centres.len() == self.values.len()).then_some(self.centres.as_slice());
        // Last step's contacts that a key matched (by their first row) are taken.
        self.taken.clear();
        self.taken.resize(self.contacts.len(), false);
        for &p in &self.matched {
            if let Ok(e) = self.contacts.binary_search_by_key(&p, |c| c.first_row) {
                self.taken[e] = true;
            }
        }
        let origins = &problem.origins;
        let mut m = 0;
        while m < self.missed.len() {
            let i = self.missed[m];
            let origin = origins[i];
            // A contact's first row, and all its rows missed (consecutive in `missed`).
            let count = origin_run(origins, i);
            let whole = (i == 0 || origins[i - 1] != origin)
                && self.missed.get(m + count - 1) == Some(&(i + count - 1));
            let (RowOrigin::Contact(k), true) = (origin, whole) else {
                m += 1;
                continue;
            };
            m += count;
            let c = &contacts[k];
            let mut best = (WARM_MATCH_DISTANCE * WARM_MATCH_DISTANCE, None);
            for (e, w) in self.contacts.iter().enumerate() {
                if w.pair == (c.collider_a, c.collider_b) && w.rows == count && !self.taken[e] {
                    let d2 = (w.point - c.point_a).norm_squared();
                    if d2 <= best.0 {
                        best = (d2, Some(e));
                    }
                }
            }
            if let (_, Some(e)) = best {
                self.taken[e] = true;
                let first = self.contacts[e].first_row;
                for r in 0..count {
                    lambda[i + r] = self.values[first + r];
                    if let (Some(c), Some(v)) = (centre.as_deref_mut(), centres) {
                        c[i + r] = v[first + r];
                    }
                }
            }
        }
    }

    /// Keeps this step's impulses `lambda` of `problem`'s rows, and their elastic parts
    /// `centre` when the rows are softened, with their keys for the next step's warm start.
    pub(crate) fn remember(
        &mut self,
        problem: &ConstraintProblem,
        contacts: &[Contact],
        generation: Option<u64>,
        lambda: &DVector<f64>,
        centre: Option<&DVector<f64>>,
    ) {
        self.values.clear();
        self.values.extend_from_slice(lambda.as_slice());
        self.centres.clear();
        if let Some(c) = centre {
            self.centres.extend_from_slice(c.as_slice());
        }
        self.generation = generation;
        if self.same_rows {
            // Keys and contacts describe these rows already (a contact's point has moved by less
            // than the kept rows' tolerance).
            return;
        }
        std::mem::swap(&mut self.keys, &mut self.row_keys);
        self.origins.clone_from(&problem.origins);
        self.contacts.clear();
        let (n, origins) = (problem.rows(), &problem.origins);
        let mut i = 0;
        while i < n {
            let count = origin_run(origins, i);
            if let RowOrigin::Contact(k) = origins[i] {
                let c = &contacts[k];
                self.contacts.push(WarmContact {
                    pair: (c.collider_a, c.collider_b),
                    point: c.point_a,
                    first_row: i,
                    rows: count,
                });
            }
            i += count;
        }
    }
}

/// The key of row `i` of `problem`: its origin (a contact's colliders and feature, a joint's
/// index), with the rows of one origin numbered in order so that each gets its own key.
fn row_key(problem: &ConstraintProblem, contacts: &[Contact], i: usize, counter: &mut (usize, u64)) -> u64 {
    let origin = problem.origins[i];
    let base = match origin {
        RowOrigin::Contact(k) => {
            let c = &contacts[k];
            (c.collider_a as u64) << 40 ^ (c.collider_b as u64) << 20 ^ c.feature.rotate_left(7)
        }
        RowOrigin::LowerLimit(k) => 1 << 62 | k as u64,
        RowOrigin::UpperLimit(k) => 2 << 61 | k as u64,
        RowOrigin::SwingLimit(k) => 9 << 57 | k as u64,
        RowOrigin::TwistLowerLimit(k) => 11 << 56 | k as u64,
        RowOrigin::TwistUpperLimit(k) => 13 << 55 | k as u64,
        RowOrigin::AngleLimit(k) => 15 << 54 | k as u64,
        RowOrigin::Motor(k) => 3 << 60 | k as u64,
        RowOrigin::JointFriction(k) => 5 << 59 | k as u64,
        RowOrigin::Loop(k) => 7 << 58 | k as u64,
        RowOrigin::Other => 0,
    };
    if counter.1 == base && i > 0 {
        counter.0 += 1;
    } else {
        *counter = (0, base);
    }
    base.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ counter.0 as u64
}

/// The number of rows from row `i` on that share its origin (a contact's rows are consecutive).
fn origin_run(origins: &[RowOrigin], i: usize) -> usize {
    origins[i..].iter().take_while(|o| **o == origins[i]).count()
}
