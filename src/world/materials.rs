//! Contact materials: the parameters of each material index, the pairs given their own, and the
//! rule that combines two materials.

use crate::collision::{Collider, Contact};
use crate::constraints::ContactParameters;
use crate::math::FastHasher;
use std::collections::HashMap;

/// The contact parameters of a world's materials.
pub(super) struct Materials {
    /// The parameters of a material never defined ([`super::WorldOptions::contact`]).
    default: ContactParameters,
    /// Per material index (0 is every collider's default material).
    list: Vec<ContactParameters>,
    /// Parameters of a pair of materials (smaller index first), overriding the combination.
    pairs: HashMap<(u32, u32), ContactParameters, FastHasher>,
}

impl Materials {
    /// Material 0 (and every undefined one) has the parameters `default`.
    pub(super) fn new(default: ContactParameters) -> Self {
        Self { default, list: vec![default], pairs: HashMap::default() }
    }

    /// Defines material `index`.
    pub(super) fn set(&mut self, index: u32, parameters: ContactParameters) {
        let i = index as usize;
        if self.list.len() <= i {
            self.list.resize(i + 1, self.default);
        }
        self.list[i] = parameters;
    }

    /// Parameters used when materials `a` and `b` touch.
    pub(super) fn set_pair(&mut self, a: u32, b: u32, parameters: ContactParameters) {
        self.pairs.insert((a.min(b), a.max(b)), parameters);
    }

    /// The parameters of contact `c` between two of `colliders`: the pair's own, else the
    /// material's when both colliders have one material, else the combination of the two.
    pub(super) fn parameters_of(&self, colliders: &[Collider], c: &Contact) -> ContactParameters {
        let (ma, mb) = (colliders[c.collider_a].material, colliders[c.collider_b].material);
        if !self.pairs.is_empty() {
            if let Some(p) = self.pairs.get(&(ma.min(mb), ma.max(mb))) {
                return *p;
            }
        }
        let get = |m: u32| self.list.get(m as usize).copied().unwrap_or(self.default);
        let (a, b) = (get(ma), get(mb));
        if ma == mb {
            return a;
        }
        // Combination: geometric mean of friction, the livelier bounce, the softer contact.
        ContactParameters {
            mu: (a.mu * b.mu).sqrt(),
            mu2: match (a.mu2, b.mu2) {
                (None, None) => None,
                (x, y) => Some((x.unwrap_or(a.mu) * y.unwrap_or(b.mu)).sqrt()),
            },
            restitution: a.restitution.max(b.restitution),
            bounce_velocity: a.bounce_velocity.min(b.bounce_velocity),
            erp: a.erp.min(b.erp),
            cfm: a.cfm.max(b.cfm),
            surface_layer: a.surface_layer.max(b.surface_layer),
            max_correcting_velocity: a.max_correcting_velocity.min(b.max_correcting_velocity),
        }
    }
}
