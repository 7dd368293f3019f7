//! The tables a scene file may hold, as serde reads them: every table refuses unknown keys, and
//! every value is one of the checked types of [`super::values`]. The module documentation of
//! [`super`] describes each key.

use super::values::{
    Count, Count1, Finite, Fraction, FrictionName, IntegratorName, JointValue, MassReuseSetting, MaterialRef,
    NonNegative, Positive, PositiveOrInfinite, ReuseSetting, SolverList, V3,
};
use crate::constraints::ContactParameters;
use serde::Deserialize;
use std::collections::BTreeMap;
use toml::Spanned;

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Document {
    pub(super) name: Option<String>,
    pub(super) description: Option<String>,
    #[serde(default)]
    pub(super) world: WorldSection,
    #[serde(default)]
    pub(super) contact: ContactSection,
    #[serde(default)]
    pub(super) limits: LimitsSection,
    #[serde(default)]
    pub(super) material: Vec<Spanned<MaterialSection>>,
    #[serde(default)]
    pub(super) pair: Vec<Spanned<PairSection>>,
    #[serde(default)]
    pub(super) ground: Vec<Spanned<GroundSection>>,
    #[serde(default)]
    pub(super) urdf: Vec<Spanned<UrdfSection>>,
    #[serde(default)]
    pub(super) body: Vec<Spanned<BodySection>>,
    #[serde(default)]
    pub(super) vehicle: Vec<Spanned<VehicleSection>>,
    pub(super) record: Option<Spanned<RecordSection>>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct VehicleSection {
    pub(super) multibody: Spanned<String>,
    pub(super) front: Option<[String; 2]>,
    pub(super) rear: Option<[String; 2]>,
    pub(super) driven: Option<DrivenName>,
    pub(super) wheel_radius: Option<Positive>,
    pub(super) drive_torque: Option<Positive>,
    pub(super) brake_torque: Option<Positive>,
    pub(super) steering_gain: Option<Positive>,
    pub(super) steering_rate: Option<Positive>,
    pub(super) steering_torque: Option<Positive>,
    pub(super) patch_contact: Option<bool>,
    #[serde(default)]
    pub(super) command: Vec<Spanned<CommandSection>>,
}

/// `driven` of a `[[vehicle]]`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum DrivenName {
    Rear,
    Front,
    All,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CommandSection {
    pub(super) at: NonNegative,
    pub(super) speed: Option<Finite>,
    pub(super) coast: Option<bool>,
    pub(super) steering_deg: Option<Finite>,
    pub(super) brake: Option<bool>,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct WorldSection {
    pub(super) dt: Option<Positive>,
    pub(super) duration: Option<NonNegative>,
    pub(super) gravity: Option<V3>,
    pub(super) solver: Option<SolverList>,
    pub(super) tolerance: Option<Positive>,
    pub(super) softness: Option<NonNegative>,
    pub(super) softness_damping: Option<Fraction>,
    pub(super) accept_last: Option<bool>,
    pub(super) lemke_operations: Option<NonNegative>,
    pub(super) lemke_matrix_entries: Option<usize>,
    pub(super) friction: Option<FrictionName>,
    pub(super) margin: Option<NonNegative>,
    pub(super) speculative_within: Option<NonNegative>,
    pub(super) speculative_factor: Option<PositiveOrInfinite>,
    pub(super) collide_joined_bodies: Option<bool>,
    pub(super) continuous_collision: Option<bool>,
    pub(super) contact_projection: Option<bool>,
    pub(super) contact_reuse: Option<ReuseSetting>,
    pub(super) mass_matrix_reuse: Option<MassReuseSetting>,
    pub(super) sleep: Option<bool>,
    pub(super) integrator: Option<IntegratorName>,
    pub(super) threads: Option<Spanned<Count1>>,
}

/// Tables holding contact parameters: `[contact]`, `[[material]]`, `[[pair]]`.
macro_rules! contact_section {
    ($name:ident { $($extra:ident : $ty:ty),* $(,)? }) => {
        #[derive(Clone, Debug, Default, Deserialize)]
        #[serde(deny_unknown_fields)]
        pub(super) struct $name {
            $(pub(super) $extra: $ty,)*
            pub(super) mu: Option<NonNegative>,
            pub(super) mu2: Option<NonNegative>,
            pub(super) restitution: Option<Fraction>,
            pub(super) bounce_velocity: Option<NonNegative>,
            pub(super) erp: Option<Fraction>,
            pub(super) cfm: Option<NonNegative>,
            pub(super) surface_layer: Option<NonNegative>,
            pub(super) max_correcting_velocity: Option<PositiveOrInfinite>,
        }

        impl $name {
            /// `base` with the parameters this table sets.
            pub(super) fn apply(&self, base: ContactParameters) -> ContactParameters {
                ContactParameters {
                    mu: self.mu.map_or(base.mu, |x| x.0),
                    mu2: self.mu2.map(|x| x.0).or(base.mu2),
                    restitution: self.restitution.map_or(base.restitution, |x| x.0),
                    bounce_velocity: self.bounce_velocity.map_or(base.bounce_velocity, |x| x.0),
                    erp: self.erp.map_or(base.erp, |x| x.0),
                    cfm: self.cfm.map_or(base.cfm, |x| x.0),
                    surface_layer: self.surface_layer.map_or(base.surface_layer, |x| x.0),
                    max_correcting_velocity: self
                        .max_correcting_velocity
                        .map_or(base.max_correcting_velocity, |x| x.0),
                }
            }
        }
    };
}

contact_section!(ContactSection {});
contact_section!(MaterialSection { index: u32, name: Option<String>, });
contact_section!(PairSection { materials: [MaterialRef; 2] });

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LimitsSection {
    pub(super) erp: Option<Fraction>,
    pub(super) cfm: Option<NonNegative>,
    pub(super) restitution: Option<Fraction>,
    pub(super) bounce_velocity: Option<NonNegative>,
    pub(super) margin: Option<NonNegative>,
    pub(super) speculative_within: Option<NonNegative>,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum GroundKind {
    #[default]
    Plane,
    Slope,
    Heightfield,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct GroundSection {
    #[serde(default)]
    pub(super) kind: GroundKind,
    pub(super) name: Option<String>,
    pub(super) material: Option<Spanned<MaterialRef>>,
    pub(super) position: Option<V3>,
    pub(super) rpy: Option<V3>,
    pub(super) quaternion: Option<[Finite; 4]>,
    pub(super) normal: Option<V3>,
    pub(super) offset: Option<Finite>,
    pub(super) angle_deg: Option<Finite>,
    pub(super) direction: Option<V3>,
    pub(super) size: Option<[Positive; 2]>,
    pub(super) heights: Option<Vec<Vec<Finite>>>,
    pub(super) samples: Option<[Count1; 2]>,
    pub(super) bump_height: Option<Finite>,
    pub(super) bump_wavelength: Option<Positive>,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum MissingMeshes {
    #[default]
    Error,
    Skip,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ServoSection {
    pub(super) gain: Positive,
    pub(super) max_velocity: PositiveOrInfinite,
    pub(super) max_force: PositiveOrInfinite,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PoseServoSection {
    pub(super) gain: Positive,
    pub(super) max_velocity: PositiveOrInfinite,
    pub(super) torque_per_kg: Positive,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct UrdfSection {
    pub(super) pose_servo: Option<PoseServoSection>,
    pub(super) count: Option<Count>,
    pub(super) spacing: Option<V3>,
    pub(super) jitter: Option<NonNegative>,
    pub(super) seed: Option<u64>,
    #[serde(default)]
    pub(super) random_rotation: bool,
    pub(super) spin: Option<NonNegative>,
    pub(super) path: Spanned<String>,
    pub(super) name: Option<String>,
    #[serde(default)]
    pub(super) floating: bool,
    pub(super) position: Option<V3>,
    pub(super) rpy: Option<V3>,
    pub(super) quaternion: Option<[Finite; 4]>,
    pub(super) velocity: Option<V3>,
    pub(super) angular_velocity: Option<V3>,
    #[serde(default)]
    pub(super) joints: BTreeMap<String, Spanned<JointValue>>,
    #[serde(default)]
    pub(super) joint_velocities: BTreeMap<String, Spanned<JointValue>>,
    #[serde(default)]
    pub(super) limits: BTreeMap<String, Spanned<[Finite; 2]>>,
    pub(super) servo: Option<ServoSection>,
    #[serde(default)]
    pub(super) self_collision: bool,
    pub(super) material: Option<Spanned<MaterialRef>>,
    #[serde(default)]
    pub(super) missing_meshes: MissingMeshes,
    #[serde(default)]
    pub(super) package_paths: Vec<String>,
    #[serde(default)]
    pub(super) strict: bool,
    #[serde(default)]
    pub(super) balance_inertia: bool,
    #[serde(default)]
    pub(super) inertia_from_collision: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum ShapeName {
    Box,
    Sphere,
    Capsule,
    Cylinder,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BodySection {
    pub(super) name: Option<String>,
    pub(super) shape: ShapeName,
    pub(super) size: Option<[Positive; 3]>,
    pub(super) radius: Option<Positive>,
    pub(super) length: Option<Positive>,
    pub(super) mass: Option<Positive>,
    pub(super) density: Option<Positive>,
    pub(super) position: Option<V3>,
    pub(super) rpy: Option<V3>,
    pub(super) quaternion: Option<[Finite; 4]>,
    pub(super) velocity: Option<V3>,
    pub(super) angular_velocity: Option<V3>,
    pub(super) count: Option<Count>,
    pub(super) spacing: Option<V3>,
    pub(super) jitter: Option<NonNegative>,
    pub(super) seed: Option<u64>,
    pub(super) material: Option<Spanned<MaterialRef>>,
    #[serde(default)]
    pub(super) fixed: bool,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RecordSection {
    pub(super) every: Option<Count1>,
    pub(super) multibodies: Option<Vec<Spanned<String>>>,
    #[serde(default)]
    pub(super) velocities: bool,
    #[serde(default)]
    pub(super) energy: bool,
}
