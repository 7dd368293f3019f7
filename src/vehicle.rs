//! A thin vehicle controller over the world's motors and servos: four wheels of one multibody
//! whose root is a free-floating chassis. A wheel is named by one joint: a hinge2 joint (steering
//! then spin, as `models/buggy.urdf`), or a hinge (revolute or continuous) joint that spins the
//! wheel, attached either to the chassis or to a steering hinge that is (as PyBullet's
//! `racecar.urdf`: steering hinge, then wheel), or to a carrier hinge on the chassis that turns
//! about the wheel's own axle (the ring of the differential in PyBullet's
//! `racecar_differential.urdf`, whose gears PyBullet adds as constraints in a script, not in the
//! file): the carrier is held at its initial angle by a servo of the brake torque bound, and the
//! wheel is driven on it as on the chassis. Steering axes must lie along the chassis z and spin
//! axes along its y, at the neutral configuration.
//!
//! - **Throttle** is a target speed v (m/s) of the tracking point ([`Vehicle::tracking_point`]):
//!   velocity motors on the driven wheels' spin dofs ([`Driven`]) with the drive torque bound.
//!   Each wheel of a steered vehicle turns at the speed of its own path about the turning centre,
//!   ω = v d / (R r), with d its distance from the centre and R = L / tan δ the radius of the
//!   tracking point (an open, "electronic" differential), so that no driven wheel fights the turn.
//! - **Steering** δ (rad, positive = left, about the chassis z) is the bicycle-model angle. Where
//!   the front wheels steer, they get Ackermann angles `cot δ_left = cot δ − t/(2L)`, `cot δ_right
//!   = cot δ + t/(2L)` (both axes meet on the rear-axle line), each clamped to the joint's steering
//!   range, held by position servos; rear steering dofs are held at 0. Where no wheel steers (a
//!   skid-steered vehicle such as PyBullet's `husky.urdf`), δ asks for the same radius L / tan δ
//!   of the tracking point through the side speeds alone ([`skid_speeds`]: its wheels must slip
//!   sideways, and the side speeds that give the radius follow from Coulomb friction).
//! - **Brake**: velocity motors at 0 on all four spin dofs with the brake torque bound.
//!
//! The controller does not own the world: it keeps indices, and every call takes the world.
//! Readings (speed, position, heading) come from the current state q, v.

use crate::collision::Attachment;
use crate::math::{Transform, Vec3};
use crate::model::Joint;
use crate::world::{Motor, Servo, World};
use thiserror::Error;

/// Why a vehicle cannot be attached to a multibody, or a command is refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum VehicleError {
    /// The multibody index is out of range.
    #[error("no multibody {index} ({count} in the world)")]
    NoMultibody {
        /// Index given.
        index: usize,
        /// Multibodies in the world.
        count: usize,
    },
    /// The multibody's root is not a free joint (the chassis must float).
    #[error("multibody `{multibody}`: the chassis must be attached to the world by a free joint")]
    NotFloating {
        /// Multibody name.
        multibody: String,
    },
    /// A wheel joint named in the configuration does not exist.
    #[error("multibody `{multibody}`: no joint `{joint}`")]
    NoJoint {
        /// Multibody name.
        multibody: String,
        /// Joint name.
        joint: String,
    },
    /// A wheel joint is neither a hinge2 joint nor a hinge on the chassis or on a steering hinge
    /// on the chassis, or its axes are not along the chassis z (steering) and y (spin).
    #[error("multibody `{multibody}`: joint `{joint}` {what}")]
    BadWheel {
        /// Multibody name.
        multibody: String,
        /// Joint name.
        joint: String,
        /// What is wrong.
        what: &'static str,
    },
    /// A parameter or command is not finite or out of range.
    #[error("{what} must be {expected}, got {value}")]
    BadValue {
        /// The parameter.
        what: &'static str,
        /// What it must be.
        expected: &'static str,
        /// The value given.
        value: f64,
    },
}

/// Which wheels the throttle drives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Driven {
    /// The rear wheels.
    #[default]
    Rear,
    /// The front wheels.
    Front,
    /// All four.
    All,
}

/// How a vehicle is wired and driven.
#[derive(Clone, Debug, PartialEq)]
pub struct VehicleConfig {
    /// Wheel joints of the front wheels: left (+y side), right (see the module documentation).
    pub front: [String; 2],
    /// Wheel joints of the rear wheels: left, right.
    pub rear: [String; 2],
    /// The driven wheels.
    pub driven: Driven,
    /// Rolling radius of the wheels (m).
    pub wheel_radius: f64,
    /// Torque bound of each drive motor (N·m).
    pub drive_torque: f64,
    /// Torque bound of each wheel's brake (N·m).
    pub brake_torque: f64,
    /// Proportional gain of the steering servos (1/s).
    pub steering_gain: f64,
    /// Largest steering rate (rad/s).
    pub steering_rate: f64,
    /// Torque bound of the steering servos (N·m), also holding the rear steering at 0.
    pub steering_torque: f64,
    /// Each wheel touches the ground at one point, the centre of its reduced contact set (a tyre's
    /// contact patch; [`crate::collision::CollisionWorld::set_patch_contact`]) instead of at both
    /// rim edges of its cylinder: a scrubbing turn then poses a well-conditioned problem that PGS
    /// solves (with two rim points it needed ~1000 sweeps or clarabel).
    pub patch_contact: bool,
}

impl VehicleConfig {
    /// The wiring of `models/buggy.urdf`: joints `front_left`, `front_right`, `rear_left`,
    /// `rear_right`, wheels of radius 0.3 m, 300 N·m drive and 1500 N·m brake per wheel,
    /// steering servos of gain 20 1/s, 3 rad/s and 2000 N·m, one contact point per wheel.
    pub fn buggy() -> Self {
        Self {
            front: ["front_left".into(), "front_right".into()],
            rear: ["rear_left".into(), "rear_right".into()],
            driven: Driven::Rear,
            wheel_radius: 0.3,
            drive_torque: 300.0,
            brake_torque: 1500.0,
            steering_gain: 20.0,
            steering_rate: 3.0,
            steering_torque: 2000.0,
            patch_contact: true,
        }
    }

    /// The wiring of PyBullet's `racecar/racecar.urdf` (a 1:10 model car): front wheels
    /// `left_front_wheel_joint`, `right_front_wheel_joint` on steering hinges, rear wheels
    /// `left_rear_wheel_joint`, `right_rear_wheel_joint` on the chassis, rear-driven, wheels of
    /// radius 0.05 m, 0.4 N·m drive (below what the tyres transmit: no wheelspin) and 1 N·m
    /// brake per wheel, steering servos of gain 20 1/s,
    /// 6 rad/s and 10 N·m, one contact point per wheel.
    pub fn racecar() -> Self {
        Self {
            front: ["left_front_wheel_joint".into(), "right_front_wheel_joint".into()],
            rear: ["left_rear_wheel_joint".into(), "right_rear_wheel_joint".into()],
            driven: Driven::Rear,
            wheel_radius: 0.05,
            drive_torque: 0.4,
            brake_torque: 1.0,
            steering_gain: 20.0,
            steering_rate: 6.0,
            steering_torque: 10.0,
            patch_contact: true,
        }
    }

    /// The wiring of PyBullet's `husky/husky.urdf` (Clearpath's skid-steered rover): wheels
    /// `front_left_wheel`, `front_right_wheel`, `rear_left_wheel`, `rear_right_wheel` on the
    /// chassis, all four driven, radius 0.17775 m, 50 N·m drive and 100 N·m brake per wheel,
    /// one contact point per wheel. No wheel steers: steering is by the wheel speeds.
    pub fn husky() -> Self {
        Self {
            front: ["front_left_wheel".into(), "front_right_wheel".into()],
            rear: ["rear_left_wheel".into(), "rear_right_wheel".into()],
            driven: Driven::All,
            wheel_radius: 0.17775,
            drive_torque: 50.0,
            brake_torque: 100.0,
            steering_gain: 20.0,
            steering_rate: 3.0,
            steering_torque: 100.0,
            patch_contact: true,
        }
    }
}

/// The dofs of one wheel.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Wheel {
    /// Steering dof (index into v), if the wheel steers.
    steer: Option<usize>,
    /// Spin dof (index into v).
    spin: usize,
    /// +1 if a positive spin rate rolls the wheel forward (+x of the chassis), else −1.
    spin_sign: f64,
    /// +1 if a positive steering angle turns the wheel left (about +z of the chassis), else −1.
    steer_sign: f64,
    /// Steering range (rad) of the joint.
    steer_range: (f64, f64),
    /// Wheel-centre mount point in the chassis frame (m).
    mount: Vec3,
    /// The body the wheel spins with.
    body: usize,
}

/// What the driver asked for last.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VehicleCommand {
    /// Target speed of the rear-axle midpoint (m/s, forward positive); `None`: coasting.
    pub speed: Option<f64>,
    /// Bicycle-model steering angle (rad, positive = left).
    pub steering: f64,
    /// Brakes on (overrides the throttle).
    pub brake: bool,
}

/// A four-wheeled vehicle driven through the motors and servos of one multibody.
#[derive(Clone, Debug, PartialEq)]
pub struct Vehicle {
    multibody: usize,
    config: VehicleConfig,
    /// Front left, front right, rear left, rear right.
    wheels: [Wheel; 4],
    wheelbase: f64,
    track: f64,
    /// Dofs of carriers the wheels spin on about their own axle (a differential's ring), held
    /// at their initial angle by servos.
    carriers: Vec<(usize, f64)>,
    /// Share of the weight on each wheel at rest (sums to 1), from the centre of mass.
    loads: [f64; 4],
    command: VehicleCommand,
}

impl Vehicle {
    /// Wires `config` to multibody `multibody` of `world` and sets the initial command: coasting,
    /// straight ahead, brakes off (steering servos on, no drive motors).
    pub fn attach(world: &mut World, multibody: usize, config: VehicleConfig) -> Result<Self, VehicleError> {
        let count = world.multibody_count();
        if multibody >= count {
            return Err(VehicleError::NoMultibody { index: multibody, count });
        }
        for (what, value) in [
            ("wheel_radius", config.wheel_radius),
            ("drive_torque", config.drive_torque),
            ("brake_torque", config.brake_torque),
            ("steering_gain", config.steering_gain),
            ("steering_rate", config.steering_rate),
            ("steering_torque", config.steering_torque),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(VehicleError::BadValue { what, expected: "positive and finite", value });
            }
        }
        let name = world.multibody_name(multibody).to_string();
        let model = world.multibody(multibody).model();
        let chassis = model.children(0).first().copied().filter(|&j| *model.joint(j) == Joint::Free);
        let chassis = chassis.ok_or_else(|| VehicleError::NotFloating { multibody: name.clone() })?;
        let mut carriers: Vec<usize> = Vec::new();
        let mut wheel = |joint: &str| -> Result<Wheel, VehicleError> {
            let bad = |what| VehicleError::BadWheel { multibody: name.clone(), joint: joint.into(), what };
            let j = model
                .joint_id(joint)
                .filter(|&j| j > 0)
                .ok_or_else(|| VehicleError::NoJoint { multibody: name.clone(), joint: joint.into() })?;
            // (steering dof and its axis, spin dof and its axis), axes in the chassis frame.
            let placement = *model.placement(j);
            let (steer, spin, mount) = match *model.joint(j) {
                Joint::Hinge2 { axis1, axis2, suspension } if model.parent(j) == chassis => {
                    let off = usize::from(suspension.is_some());
                    let (iv, iq) = (model.idx_v(j), model.idx_q(j) + off);
                    let steer = (iv + off, iq, placement.rotation * axis1);
                    (Some(steer), (iv + off + 1, placement.rotation * axis2), placement.translation)
                }
                Joint::Hinge { axis } if model.parent(j) == chassis => {
                    (None, (model.idx_v(j), placement.rotation * axis), placement.translation)
                }
                Joint::Hinge { axis } => {
                    let s = model.parent(j);
                    let Joint::Hinge { axis: parent_axis } = *model.joint(s) else {
                        return Err(bad("spins on a body that is not a steering hinge"));
                    };
                    if model.parent(s) != chassis {
                        return Err(bad("is not attached to the chassis, directly or by a steering hinge"));
                    }
                    let x_cs = *model.placement(s);
                    let x_cw = x_cs * placement;
                    let (parent_axis, axle) = (x_cs.rotation * parent_axis, x_cw.rotation * axis);
                    if parent_axis.dot(&axle).abs() > 0.99 {
                        // A carrier on the same axle (a differential's ring): held, not steering.
                        carriers.push(model.idx_v(s));
                        (None, (model.idx_v(j), axle), x_cw.translation)
                    } else {
                        let steer = (model.idx_v(s), model.idx_q(s), parent_axis);
                        (Some(steer), (model.idx_v(j), axle), x_cw.translation)
                    }
                }
                Joint::Hinge2 { .. } => return Err(bad("is not attached to the chassis")),
                _ => return Err(bad("is neither a hinge2 joint nor a hinge")),
            };
            let (spin_dof, axle) = spin;
            let up = steer.map_or(Vec3::z(), |s| s.2);
            let forward = axle.cross(&up);
            if up.z.abs() < 0.9 || forward.x.abs() < 0.9 {
                return Err(bad("needs its steering axis along the chassis z and its spin axis along its y"));
            }
            Ok(Wheel {
                steer: steer.map(|s| s.0),
                spin: spin_dof,
                spin_sign: forward.x.signum(),
                steer_sign: up.z.signum(),
                steer_range: steer.map_or((0.0, 0.0), |s| {
                    (model.lower_position_limit()[s.1], model.upper_position_limit()[s.1])
                }),
                mount,
                body: model.dof_joint(spin_dof),
            })
        };
        let wheels = [
            wheel(&config.front[0])?,
            wheel(&config.front[1])?,
            wheel(&config.rear[0])?,
            wheel(&config.rear[1])?,
        ];
        let wheel_bodies: Vec<usize> = wheels.iter().map(|w| w.body).collect();
        let wheel_colliders: Vec<usize> = world
            .collision()
            .colliders_of(multibody)
            .iter()
            .copied()
            .filter(|&c| match world.collision().colliders()[c].attachment() {
                Attachment::Body { body, .. } => wheel_bodies.contains(&body),
                Attachment::World => false,
            })
            .collect();
        let carriers: Vec<(usize, f64)> = carriers
            .iter()
            .map(|&dof| (dof, world.multibody(multibody).state.q[model.idx_q(model.dof_joint(dof))]))
            .collect();
        let front_axle = (wheels[0].mount + wheels[1].mount) / 2.0;
        let rear_axle = (wheels[2].mount + wheels[3].mount) / 2.0;
        let wheelbase = front_axle.x - rear_axle.x;
        let track = wheels[0].mount.y - wheels[1].mount.y;
        if wheelbase.is_nan() || wheelbase <= 0.0 || track.is_nan() || track <= 0.0 {
            return Err(VehicleError::BadValue {
                what: "the front wheels' mount x minus the rear's, and the left wheels' mount y minus the right's",
                expected: "positive",
                value: wheelbase.min(track),
            });
        }
        for c in wheel_colliders {
            // The indices come from the collision world itself.
            world.collision_mut().set_patch_contact(c, config.patch_contact).ok();
        }
        // Static wheel loads: the least-squares split of the weight among four support points
        // that balances it and its moments, with the centre of mass at the neutral joint angles.
        let model = world.multibody(multibody).model();
        let mut q = model.neutral_configuration();
        let root_q = model.idx_q(chassis);
        q.rows_mut(root_q, 7).copy_from_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        let mut data = crate::data::Data::new(model);
        let com = crate::algorithms::center_of_mass(model, &mut data, &q).unwrap_or_default();
        let com = model.placement(chassis).inverse().act_point(&com);
        let centre = wheels.iter().map(|w| w.mount).sum::<Vec3>() / 4.0;
        let spread = wheels.map(|w| w.mount - centre);
        let (sx, sy) =
            (spread.iter().map(|p| p.x * p.x).sum::<f64>(), spread.iter().map(|p| p.y * p.y).sum::<f64>());
        let offset = com - centre;
        let loads = spread.map(|p| (0.25 + offset.x * p.x / sx + offset.y * p.y / sy).max(0.0));
        let vehicle = Self {
            multibody,
            config,
            wheels,
            wheelbase,
            track,
            carriers,
            loads,
            command: VehicleCommand::default(),
        };
        vehicle.apply(world);
        Ok(vehicle)
    }

    /// The multibody driven.
    pub fn multibody(&self) -> usize {
        self.multibody
    }

    /// The configuration.
    pub fn config(&self) -> &VehicleConfig {
        &self.config
    }

    /// The last command.
    pub fn command(&self) -> VehicleCommand {
        self.command
    }

    /// Wheelbase L (m): distance between the front and rear axles' mount points along x.
    pub fn wheelbase(&self) -> f64 {
        self.wheelbase
    }

    /// Track t (m): distance between left and right mount points of the front axle along y.
    pub fn track(&self) -> f64 {
        self.track
    }

    /// Midpoint of the rear wheels' mount points, chassis frame (m).
    pub fn rear_axle_center(&self) -> Vec3 {
        (self.wheels[2].mount + self.wheels[3].mount) / 2.0
    }

    /// Whether a front wheel steers (otherwise the vehicle is skid-steered).
    pub fn steers(&self) -> bool {
        self.wheels[0].steer.is_some() || self.wheels[1].steer.is_some()
    }

    /// The point whose speed the throttle sets and whose path has the radius
    /// [`Vehicle::predicted_radius`], chassis frame (m): the rear-axle midpoint where the front
    /// wheels steer (the bicycle model), the centre of the four wheel mounts where none does.
    pub fn tracking_point(&self) -> Vec3 {
        if self.steers() {
            self.rear_axle_center()
        } else {
            self.wheels.iter().map(|w| w.mount).sum::<Vec3>() / 4.0
        }
    }

    /// Rolling speed of each wheel per unit speed of the tracking point at steering `delta`.
    /// Steered vehicle: each wheel's point moves about the turning centre (at R = L / tan δ to
    /// the left of the tracking point); a steered wheel rolls at that point's whole speed, one
    /// that does not steer at its x component. Skid-steered vehicle: the wheels must slip
    /// sideways to turn, and the side speeds come from [`skid_speeds`].
    fn speed_factors(&self, delta: f64) -> [f64; 4] {
        if delta == 0.0 {
            return [1.0; 4];
        }
        let radius = self.predicted_radius(delta);
        let points = self.wheels.map(|w| w.mount - self.tracking_point());
        if !self.steers() {
            let (left, right) = skid_speeds(&points, &self.loads, radius);
            return [left, right, left, right];
        }
        std::array::from_fn(|i| {
            let p = points[i];
            if self.wheels[i].steer.is_some() {
                (p.x * p.x + (radius - p.y).powi(2)).sqrt() / radius.abs()
            } else {
                (radius - p.y) / radius
            }
        })
    }

    /// Throttle: drive the rear-axle midpoint at `speed` (m/s, negative = reverse) and release
    /// the brakes.
    pub fn set_speed(&mut self, world: &mut World, speed: f64) -> Result<(), VehicleError> {
        if !speed.is_finite() {
            return Err(VehicleError::BadValue { what: "speed", expected: "finite", value: speed });
        }
        self.command.speed = Some(speed);
        self.command.brake = false;
        self.apply(world);
        Ok(())
    }

    /// Coast: no drive torque, brakes released.
    pub fn coast(&mut self, world: &mut World) {
        self.command.speed = None;
        self.command.brake = false;
        self.apply(world);
    }

    /// Brakes on (`true`: every wheel held at zero spin rate with the brake torque bound) or off
    /// (back to the throttle command).
    pub fn set_brake(&mut self, world: &mut World, on: bool) {
        self.command.brake = on;
        self.apply(world);
    }

    /// Steering: the bicycle-model angle δ (rad, positive = left); the front wheels get the
    /// Ackermann angles, each within its joint's range.
    pub fn set_steering(&mut self, world: &mut World, angle: f64) -> Result<(), VehicleError> {
        if !(angle.is_finite() && angle.abs() < std::f64::consts::FRAC_PI_2) {
            return Err(VehicleError::BadValue {
                what: "steering angle",
                expected: "finite and within ±π/2",
                value: angle,
            });
        }
        self.command.steering = angle;
        self.apply(world);
        Ok(())
    }

    /// Ackermann angles (left, right) of the front wheels for the bicycle angle `delta` (rad),
    /// before clamping to the joints' ranges: `cot δ_l = cot δ − t/(2L)`, `cot δ_r = cot δ + t/(2L)`.
    pub fn ackermann(&self, delta: f64) -> (f64, f64) {
        if delta == 0.0 {
            return (0.0, 0.0);
        }
        let k = self.track / (2.0 * self.wheelbase);
        let cot = 1.0 / delta.tan();
        ((1.0 / (cot - k)).atan(), (1.0 / (cot + k)).atan())
    }

    /// Turning radius (m) of the rear-axle midpoint predicted by the bicycle model for the
    /// steering angle δ: R = L / tan δ (infinite when straight; negative = turning right).
    pub fn predicted_radius(&self, delta: f64) -> f64 {
        self.wheelbase / delta.tan()
    }

    /// Pose of the chassis frame in the world, from the current q.
    pub fn pose(&self, world: &World) -> Transform {
        let mb = world.multibody(self.multibody);
        let model = mb.model();
        let root = model.children(0)[0];
        let q = &mb.state.q;
        let iq = model.idx_q(root);
        let local = Transform::from_translation_quaternion(
            Vec3::new(q[iq], q[iq + 1], q[iq + 2]),
            [q[iq + 3], q[iq + 4], q[iq + 5], q[iq + 6]],
        );
        *model.placement(root) * local
    }

    /// Position of the chassis frame's origin, world frame (m).
    pub fn position(&self, world: &World) -> Vec3 {
        self.pose(world).translation
    }

    /// Heading (rad): the yaw of the chassis x axis in the world xy-plane, from +x toward +y.
    pub fn heading(&self, world: &World) -> f64 {
        let forward = self.pose(world).rotation.column(0).into_owned();
        forward.y.atan2(forward.x)
    }

    /// Forward speed (m/s): the velocity of the chassis origin along the chassis x axis.
    pub fn speed(&self, world: &World) -> f64 {
        let mb = world.multibody(self.multibody);
        let root = mb.model().children(0)[0];
        // The free joint's v is [v; ω] of the chassis frame in chassis axes.
        mb.state.v[mb.model().idx_v(root)]
    }

    /// Travel (m) of each wheel's suspension (front left, front right, rear left, rear right),
    /// positive = wheel pushed up toward the chassis; 0 for wheels without suspension.
    pub fn suspension_travel(&self, world: &World) -> [f64; 4] {
        let mb = world.multibody(self.multibody);
        let model = mb.model();
        self.wheels.map(|w| {
            let j = model.dof_joint(w.spin);
            match model.joint(j) {
                Joint::Hinge2 { suspension: Some(_), .. } => mb.state.q[model.idx_q(j)],
                _ => 0.0,
            }
        })
    }

    /// Sets the motors and servos of the current command.
    fn apply(&self, world: &mut World) {
        let c = self.command;
        let config = &self.config;
        let (left, right) = self.ackermann(c.steering);
        let mb = world.multibody_mut(self.multibody);
        let steering_servo = |target: f64| Servo {
            target_position: target,
            gain: config.steering_gain,
            max_velocity: config.steering_rate,
            max_force: config.steering_torque,
        };
        for &(dof, angle) in &self.carriers {
            let hold = Servo { max_force: config.brake_torque, ..steering_servo(angle) };
            mb.set_servo(dof, Some(hold));
        }
        for (w, angle) in self.wheels.iter().zip([left, right, 0.0, 0.0]) {
            if let Some(steer) = w.steer {
                let target = (w.steer_sign * angle).clamp(w.steer_range.0, w.steer_range.1);
                mb.set_servo(steer, Some(steering_servo(target)));
            }
        }
        let r = config.wheel_radius;
        let factors = self.speed_factors(c.steering);
        for (i, w) in self.wheels.iter().enumerate() {
            let driven = match config.driven {
                Driven::Rear => i >= 2,
                Driven::Front => i < 2,
                Driven::All => true,
            };
            let motor = if c.brake {
                Some(Motor { target_velocity: 0.0, max_force: config.brake_torque })
            } else if driven {
                c.speed.map(|v| Motor {
                    target_velocity: w.spin_sign * v * factors[i] / r,
                    max_force: config.drive_torque,
                })
            } else {
                None
            };
            mb.set_motor(w.spin, motor);
        }
    }
}

/// Side speeds (left, right) of a skid-steered vehicle, per unit forward speed of its tracking
/// point, that turn the tracking point on a circle of `radius` (m, positive = left) in the
/// quasi-static Coulomb model: four wheels at `points` (front left, front right, rear left, rear
/// right; chassis frame, from the tracking point) carry the shares `loads` of the weight, each contact's friction
/// opposes its slip (the contact point's velocity minus the wheel's rolling speed along x), and
/// the friction forces and their moment about z sum to zero. Unknowns: the two side speeds and
/// the lateral velocity; damped Newton's method from twice the kinematic difference, 1 ∓ t/R
/// (at the kinematic speeds 1 ∓ t/(2R) no wheel slips along x and the Jacobian is singular).
/// When it does not converge, the kinematic speeds are the answer. The friction coefficient
/// cancels.
pub fn skid_speeds(points: &[Vec3; 4], loads: &[f64; 4], radius: f64) -> (f64, f64) {
    let yaw_rate = 1.0 / radius;
    let half_track = (points[0].y - points[1].y + points[2].y - points[3].y) / 4.0;
    let kinematic = (1.0 - half_track / radius, 1.0 + half_track / radius);
    let guess = nalgebra::Vector3::new(1.0 - 2.0 * half_track / radius, 1.0 + 2.0 * half_track / radius, 0.0);
    // Net force (x, y) and moment about z for side speeds z[0], z[1] and lateral velocity z[2].
    let residual = |z: &nalgebra::Vector3<f64>| {
        let mut r = nalgebra::Vector3::zeros();
        for (k, p) in points.iter().enumerate() {
            let side = if k % 2 == 0 { z[0] } else { z[1] };
            let slip = nalgebra::Vector2::new(1.0 - yaw_rate * p.y - side, z[2] + yaw_rate * p.x);
            let f = -slip * loads[k] / slip.norm().max(1e-12);
            r += nalgebra::Vector3::new(f.x, f.y, p.x * f.y - p.y * f.x);
        }
        r
    };
    let mut z = guess;
    for _ in 0..100 {
        let r = residual(&z);
        if r.amax() < 1e-11 {
            return (z[0], z[1]);
        }
        let mut jacobian = nalgebra::Matrix3::zeros();
        for k in 0..3 {
            let mut dz = z;
            dz[k] += 1e-7;
            jacobian.set_column(k, &((residual(&dz) - r) / 1e-7));
        }
        let Some(step) = jacobian.lu().solve(&r) else { break };
        z -= 0.5 * step;
    }
    if residual(&z).amax() < 1e-9 {
        (z[0], z[1])
    } else {
        kinematic
    }
}
