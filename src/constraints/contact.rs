//! Contact rows: one unilateral normal row and two friction rows per contact point, with the
//! target normal velocity from restitution (Newton's law with a threshold, ODE's bounce and
//! bounce_vel), position stabilisation (ODE's soft_erp with a surface layer) and speculative
//! approach for contacts still apart, and softness (ODE's soft_cfm).

use super::{ProblemBuilder, RowOrigin};
use crate::collision::{point_rates, tangents, Attachment, Contact};
use crate::data::Data;
use crate::model::Model;
use nalgebra::DVector;

/// Contact parameters of a pair of surfaces (ODE's `dSurfaceParameters`, in SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactParameters {
    /// Coulomb friction coefficient along the first tangent.
    pub mu: f64,
    /// Friction coefficient along the second tangent (`None`: isotropic, = `mu`).
    pub mu2: Option<f64>,
    /// Coefficient of restitution ε ∈ [0, 1] (ODE's bounce).
    pub restitution: f64,
    /// Approach speed (m/s) below which no bounce happens (ODE's bounce_vel).
    pub bounce_velocity: f64,
    /// Fraction of the penetration (beyond the surface layer) removed per step, in [0, 1]
    /// (ODE's soft_erp).
    pub erp: f64,
    /// Constraint force mixing (ODE's soft_cfm): the normal row becomes `w = (A + cfm/h) λ + b`,
    /// a spring-like softness; 0 = hard contact.
    pub cfm: f64,
    /// Penetration depth (m) left uncorrected, so that resting contacts stay in contact (ODE's
    /// contact surface layer).
    pub surface_layer: f64,
    /// Upper bound on the stabilisation velocity (m/s) (ODE's contact_max_correcting_vel).
    pub max_correcting_velocity: f64,
}

impl Default for ContactParameters {
    fn default() -> Self {
        Self {
            mu: 0.5,
            mu2: None,
            restitution: 0.0,
            bounce_velocity: 0.1,
            erp: 0.2,
            cfm: 0.0,
            surface_layer: 0.001,
            max_correcting_velocity: f64::INFINITY,
        }
    }
}

impl ContactParameters {
    /// The target normal velocity u* (m/s) for a contact at signed distance `distance` (m)
    /// approaching at normal velocity `approach` (m/s, negative = closing) over a step `h` (s):
    /// a bounce `−ε·approach` if the approach is faster than the threshold and the gap closes
    /// within the step; otherwise, if apart, the speed that just closes the gap (`−distance/h`,
    /// negative: a speculative contact lets the bodies approach); if penetrating beyond the
    /// surface layer, `erp·(depth − layer)/h` (capped); else 0.
    pub fn target_normal_velocity(&self, distance: f64, approach: f64, h: f64) -> f64 {
        let stabilization = if distance < -self.surface_layer {
            (self.erp * (-distance - self.surface_layer) / h).min(self.max_correcting_velocity)
        } else {
            0.0
        };
        let closes_this_step = distance <= -approach * h;
        if approach < -self.bounce_velocity && closes_this_step && self.restitution > 0.0 {
            (-self.restitution * approach).max(stabilization)
        } else if distance > 0.0 {
            -distance / h
        } else {
            stabilization
        }
    }
}

/// Appends the rows of `contacts` to `builder`. `systems[m]` is the model and data (with
/// `data.j_world` current) of multibody `m`, whose velocities start at column `offsets[m]`; `v`
/// is the current velocity of all systems (for the approach speed), `h` the step (s), and
/// `parameters(contact)` the surface parameters of a contact. Contact `i` of the slice gets
/// [`RowOrigin::Contact`]`(first_index + i)`.
#[allow(clippy::too_many_arguments)]
pub fn add_contact_rows(
    builder: &mut ProblemBuilder,
    systems: &[(&Model, &Data)],
    offsets: &[usize],
    contacts: &[Contact],
    first_index: usize,
    v: &DVector<f64>,
    h: f64,
    parameters: impl FnMut(&Contact) -> ContactParameters,
) {
    add_contact_rows_with(
        builder,
        |m| (systems[m].0, systems[m].1, offsets[m]),
        contacts,
        first_index,
        v,
        h,
        parameters,
        |_, _| true,
    );
}

/// [`add_contact_rows`] with the systems given by a function: `system(m)` is the model, the data
/// and the first velocity column of multibody `m`; and `keep(i, contact)` decides whether
/// contact `i` of the slice gets rows at all, before its Jacobian rows are formed: the world leaves out
/// speculative contacts that cannot close within the step ([`Speculation`]), judged from its
/// bodies' velocities in O(1) per contact (a resting ragdoll has 32 contacts in its margin and
/// keeps 14).
#[allow(clippy::too_many_arguments)]
pub fn add_contact_rows_with<'a>(
    builder: &mut ProblemBuilder,
    system: impl Fn(usize) -> (&'a Model, &'a Data, usize),
    contacts: &[Contact],
    first_index: usize,
    v: &DVector<f64>,
    h: f64,
    mut parameters: impl FnMut(&Contact) -> ContactParameters,
    mut keep: impl FnMut(usize, &Contact) -> bool,
) {
    for (i, contact) in contacts.iter().enumerate() {
        if !keep(i, contact) {
            continue;
        }
        let (t1, t2) = tangents(&contact.normal);
        let mut sides = [(0, 0); 2];
        for (range, (side, point, sign)) in sides
            .iter_mut()
            .zip([(contact.body_a, contact.point_a, 1.0), (contact.body_b, contact.point_b, -1.0)])
        {
            let start = builder.rates_mut().len();
            if let Attachment::Body { multibody, body } = side {
                let (model, data, col) = system(multibody);
                point_rates(model, data, body, &point, sign, col, builder.rates_mut());
            }
            *range = (start, builder.rates_mut().len());
        }
        let p = parameters(contact);
        let origin = RowOrigin::Contact(first_index + i);
        let normal_row = builder.push_point_contact(
            sides,
            [contact.normal, t1, t2],
            p.cfm / h,
            origin,
            p.mu,
            p.mu2.unwrap_or(p.mu),
        );
        let approach = builder.row_dot(normal_row, v.as_slice());
        let target = p.target_normal_velocity(contact.distance, approach, h);
        builder.set_target(normal_row, target);
    }
}

/// Which contacts still apart get rows (speculative contacts). The collision margin reports
/// pairs up to a fixed gap, so that a fast limb's contact is in the problem the step before it
/// touches; a slow or resting body's contacts with a gap it cannot close within the step would
/// only add rows whose impulse is zero (a ragdoll lying still has 26 contacts within its 2 cm
/// margin, 14 of them apart). A contact gets rows if its gap is at most `always_within`, or at
/// most `speed_factor` times the distance its two points close in one step at their relative
/// speed (|u|·h, the larger of u under the velocity at the start of the step and under the free
/// velocity, which has the step's gravity and forces in it): the factor covers the speed the
/// step's own impulses add (PhysX's speculative contact distance and Bullet's predictive
/// contacts grow with |v|·h in the same way).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Speculation {
    /// Gap (m) up to which a contact always gets rows.
    pub always_within: f64,
    /// Multiple of the one-step closing distance |u|·h up to which a contact further apart gets
    /// rows (`f64::INFINITY`: every contact within the collision margin does).
    pub speed_factor: f64,
}

impl Speculation {
    /// Every contact within the collision margin gets rows.
    pub const ALL: Self = Self { always_within: f64::INFINITY, speed_factor: f64::INFINITY };

    /// Whether a contact at signed distance `distance` (m) whose two points move relative to
    /// each other at up to `speed` (m/s) gets rows in a step of `h` (s).
    pub fn keeps(&self, distance: f64, speed: f64, h: f64) -> bool {
        distance <= self.always_within
            || self.speed_factor == f64::INFINITY
            || distance <= self.speed_factor * speed * h
    }
}

impl Default for Speculation {
    fn default() -> Self {
        Self { always_within: 2e-3, speed_factor: 2.0 }
    }
}
