//! A thin vehicle controller over the world's motors and servos: four wheels on hinge2 joints of
//! one multibody whose root is a free-floating chassis (as `models/buggy.urdf`).
//!
//! - **Throttle** is a target speed v (m/s) of the rear-axle midpoint: velocity motors on the
//!   rear spin dofs with target ω = v / r and the drive torque bound. While steering, each rear
//!   wheel gets the speed of its own track on the turning circle, ω = v (R ∓ t/2) / (R r) (an
//!   open, "electronic" differential; R = L / tan δ from the bicycle model), so that the locked
//!   axle does not fight the turn.
//! - **Steering** δ (rad, positive = left, about the chassis z) is the bicycle-model angle: the
//!   front wheels get Ackermann angles `cot δ_left = cot δ − t/(2L)`, `cot δ_right = cot δ +
//!   t/(2L)` (both axes meet on the rear-axle line), each clamped to the joint's steering range,
//!   held by position servos. The rear steering dofs are held at 0 by servos.
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
    /// A wheel joint is not a hinge2 joint, or is not a child of the chassis.
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

/// How a vehicle is wired and driven.
#[derive(Clone, Debug, PartialEq)]
pub struct VehicleConfig {
    /// Hinge2 joints of the front wheels: left (+y side), right.
    pub front: [String; 2],
    /// Hinge2 joints of the rear (driven) wheels: left, right.
    pub rear: [String; 2],
    /// Rolling radius of the wheels (m).
    pub wheel_radius: f64,
    /// Torque bound of each rear drive motor (N·m).
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
            wheel_radius: 0.3,
            drive_torque: 300.0,
            brake_torque: 1500.0,
            steering_gain: 20.0,
            steering_rate: 3.0,
            steering_torque: 2000.0,
            patch_contact: true,
        }
    }
}

/// The dofs of one wheel.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Wheel {
    /// Steering dof (index into v).
    steer: usize,
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
        let wheel = |joint: &str| -> Result<Wheel, VehicleError> {
            let bad = |what| VehicleError::BadWheel { multibody: name.clone(), joint: joint.into(), what };
            let j = model
                .joint_id(joint)
                .filter(|&j| j > 0)
                .ok_or_else(|| VehicleError::NoJoint { multibody: name.clone(), joint: joint.into() })?;
            if model.parent(j) != chassis {
                return Err(bad("is not attached to the chassis"));
            }
            let Joint::Hinge2 { axis1, axis2, suspension } = *model.joint(j) else {
                return Err(bad("is not a hinge2 joint"));
            };
            let placement = model.placement(j);
            let (up, axle) = (placement.rotation * axis1, placement.rotation * axis2);
            let forward = axle.cross(&up);
            if up.z.abs() < 0.9 || forward.x.abs() < 0.9 {
                return Err(bad("needs axis 1 along the chassis z and axis 2 along its y"));
            }
            let off = usize::from(suspension.is_some());
            let (iv, iq) = (model.idx_v(j), model.idx_q(j));
            Ok(Wheel {
                steer: iv + off,
                spin: iv + off + 1,
                spin_sign: forward.x.signum(),
                steer_sign: up.z.signum(),
                steer_range: (model.lower_position_limit()[iq + off], model.upper_position_limit()[iq + off]),
                mount: placement.translation,
            })
        };
        let wheels = [
            wheel(&config.front[0])?,
            wheel(&config.front[1])?,
            wheel(&config.rear[0])?,
            wheel(&config.rear[1])?,
        ];
        let wheel_bodies: Vec<usize> =
            config.front.iter().chain(&config.rear).filter_map(|joint| model.joint_id(joint)).collect();
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
        let vehicle =
            Self { multibody, config, wheels, wheelbase, track, command: VehicleCommand::default() };
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

    /// Midpoint of the rear wheels' mount points, chassis frame (m): the point whose path the
    /// bicycle model predicts.
    pub fn rear_axle_center(&self) -> Vec3 {
        (self.wheels[2].mount + self.wheels[3].mount) / 2.0
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
        for (w, angle) in self.wheels.iter().zip([left, right, 0.0, 0.0]) {
            let target = (w.steer_sign * angle).clamp(w.steer_range.0, w.steer_range.1);
            mb.set_servo(w.steer, Some(steering_servo(target)));
        }
        let r = config.wheel_radius;
        for (i, w) in self.wheels.iter().enumerate() {
            let motor = if c.brake {
                Some(Motor { target_velocity: 0.0, max_force: config.brake_torque })
            } else if i >= 2 {
                c.speed.map(|v| {
                    // Each rear wheel's track on the turning circle: (R ∓ t/2)/R = 1 ∓ t tan δ/(2L).
                    let side = if i == 2 { -1.0 } else { 1.0 };
                    let rear_track = self.wheels[2].mount.y - self.wheels[3].mount.y;
                    let factor = 1.0 + side * rear_track * c.steering.tan() / (2.0 * self.wheelbase);
                    Motor { target_velocity: w.spin_sign * v * factor / r, max_force: config.drive_torque }
                })
            } else {
                None
            };
            mb.set_motor(w.spin, motor);
        }
    }
}
