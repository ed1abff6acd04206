//! Analytic reference model of the machine axes: an ODE model of each axis, run by the same
//! loop, controller and setpoints as the Rapier machine, so that the physics can be checked
//! against a plant whose equations are written down (see `docs/sources.md`, the XYZ table).
//!
//! # The plant, per axis (joint units: m, N, kg; motor units where the name says so)
//!
//! ```text
//!   amplifier   V = clamp(K_a·u, ±V_supply)                       (u held over the servo period)
//!   armature    L·di/dt = V − R·i − K_b·ω,    ω = k·v_drive,  T = K_m·i
//!   drive side  m_d·a_d = k·T − c_d·v_d − λ                       m_d = J·k², c_d = C·k²
//!   carriage    m_c·a_c = λ − c_c·v_c + m_c·g_axis − F_friction
//! ```
//!
//! k = [`Drive::ratio`] (motor rad per joint unit). The ideal torque actuator replaces the first
//! two lines by T = clamp(u, ±T_peak). λ is the force the transmission passes to the carriage.
//! Without backlash drive and carriage are one rigid body of mass m_d + m_c with damping
//! c_d + c_c, which is exactly the Rapier model (armature J·k², damping C·k² + joint damping).
//!
//! # Coulomb friction: a switching (Karnopp-type) stick/slip model with event location
//!
//! Friction acts on the carriage's guides. While sliding it is −F(|v|)·sign(v) with the sign
//! frozen for the mode, F the guide's [`StribeckCurve`] (F_c when static = kinetic), so each
//! mode is a smooth ODE that RK4 integrates at full order. The body sticks when its velocity
//! reaches zero and the applied force (everything but friction) is within ±F_s (breakaway); it
//! then has exactly zero velocity until the applied force leaves that band.
//! Both switching instants are located inside the step by bisection, so there is no chatter
//! (no sign flipping from step to step around v = 0) and no creep below breakaway, which a
//! regularised (tanh or linear-zone) model would show and which would hide exactly the
//! stick-slip effects the reference is meant to show.
//!
//! # Backlash: a dead zone of width b between drive and carriage, with rigid inelastic ends
//!
//! The drive side carries the motor and transmission inertia, the carriage the moved mass. The
//! gap δ = x_drive − x_carriage is free within [−b/2, +b/2] (δ = 0: drive and carriage
//! positions coincide, so the setpoint means the same thing for both). At a gap end the two
//! bodies collide inelastically (common velocity from momentum) and then move as one body
//! while the contact force pushes (λ·side ≥ 0); they separate when it would pull. This is what
//! a short-travel joint with rigid limits ±b/2 does (Rapier's joint limits are rigid and
//! without restitution), and unlike a stiff spring-damper it needs no stiffness that is not in
//! the source data and no step small enough to resolve a contact oscillation. The price is
//! the same as for friction: impacts and separations are events located inside the step.
//!
//! # Compliant transmissions: two masses, a spring and a damper, the backlash a dead zone
//!
//! With a transmission stiffness k and damping c (the drive file's `transmission_stiffness_*`)
//! the drive side and the carriage are two bodies for good, joined by
//!
//! ```text
//!   λ = k·(δ − side·b/2) + c·(v_d − v_c)   while |δ| > b/2 (side = sign δ),   λ = 0 within the gap
//! ```
//!
//! (side = 0 without backlash: the spring is always engaged). Entering and leaving the gap are
//! events located in the step like the others; in each mode the equations are linear, so they
//! are solved exactly as well.
//!
//! # Integration and the loop
//!
//! Fixed steps (the servo period over `steps_per_period`), restarted at every event. A mode
//! whose equations are linear (voltage-mode amplifier or ideal torque, friction without a
//! Stribeck drop) is solved exactly by its matrix exponential (`analytic::exact`); a mode that cannot
//! end (one rigid body, no Coulomb friction) in one step over the whole hold. The other modes
//! (current-mode amplifier, sliding on a Stribeck curve) are integrated by classical RK4. The
//! mean motor torque over a hold interval is the integral of the current (a quadrature state),
//! so it is exact to the method's order. [`AnalyticPlant`] puts the
//! models behind the loop's plant interface: the loop, the encoder, the trip and the
//! controller are the very ones the physics runs with.

use super::{Hold, Plant, Sensors};
use crate::kinematics::ORTHOGONALITY_TOLERANCE;
use crate::machine::{
    AmplifierMode, Compliance, Drive, Feedback, JointKind, Machine, StribeckCurve,
};
use nalgebra::{UnitQuaternion, Vector3};

mod exact;

/// Per-axis effects and actuator choice; all off by default.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AxisModelOptions {
    /// Friction force on the carriage guides (N or N·m): Coulomb, with stiction when its
    /// breakaway exceeds its kinetic level.
    pub friction: StribeckCurve,
    /// Lost motion between drive and carriage, ≥ 0 (m or rad, at the joint).
    pub backlash: f64,
    /// Command is motor torque clamped to `Drive::peak_torque_nm`, instead of amplifier input.
    pub ideal_actuator: bool,
    /// The transmission's stiffness and damping at the joint; `None`: rigid.
    pub compliance: Option<Compliance>,
    /// Which position the servo loop is closed on: the drive side or the carriage.
    pub feedback: Feedback,
}

/// Why an axis model could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AxisModelError {
    /// A parameter that must be finite and ≥ 0 is not (gravity along the axis: not finite).
    #[error("{name} = {value}: expected a finite value ≥ 0")]
    Negative {
        /// The parameter's name.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// A parameter that must be finite and > 0 is not.
    #[error("{name} = {value}: expected a finite value > 0")]
    NotPositive {
        /// The parameter's name.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// The friction's breakaway level is below its kinetic level (or not finite).
    #[error("friction.breakaway = {breakaway}: expected a finite value ≥ the kinetic {kinetic}")]
    Breakaway {
        /// Breakaway (static) friction force (N or N·m).
        breakaway: f64,
        /// Kinetic (Coulomb) friction force (N or N·m).
        kinetic: f64,
    },
    /// Backlash or a compliant transmission on an axis whose carriage has no mass.
    #[error("backlash needs a carriage with mass (moved mass is 0)")]
    MasslessCarriage,
    /// Gravity pulls the carriage away from its guide, so there is no normal load.
    #[error("axis '{axis}': gravity pulls the carriage off its guide (check guide.normal)")]
    LiftsOff {
        /// Name of the axis.
        axis: String,
    },
    /// A revolute axis, or one below a revolute joint: its load and gravity would depend on
    /// the pose.
    #[error("axis '{axis}': the reference model takes prismatic axes on prismatic chains only (load and gravity would depend on the pose)")]
    PoseDependent {
        /// Name of the axis.
        axis: String,
    },
    /// Two axes move one body along directions not at right angles (through a `<mimic>`
    /// follower): their dynamics are coupled, which one model per axis cannot represent.
    #[error("axes '{}' and '{}' share {inertia:.6} kg of moving mass (a body moves with both along directions not at right angles, as a <mimic> follower of one can): the reference model has one uncoupled model per axis (run without [analytic])", axes[0], axes[1])]
    CoupledAxes {
        /// The two axes.
        axes: [String; 2],
        /// Their off-diagonal mass (kg).
        inertia: f64,
    },
    /// A `<mimic>` follower of an axis with backlash or a compliant transmission.
    #[error("joint '{follower}' follows axis '{axis}' through its <mimic>, and the axis has backlash or a compliant transmission: the reference model couples followers to rigid drive trains only")]
    FollowerOfSplitDrive {
        /// Name of the follower joint.
        follower: String,
        /// Name of the axis.
        axis: String,
    },
    /// The machine has a passive (undriven, unlocked) joint, which the reference model
    /// cannot represent.
    #[error("joint '{joint}' is passive: the reference model has one model per driven axis and no free joints (lock it in the drive file, or run without [analytic])")]
    PassiveJoint {
        /// Name of the passive joint.
        joint: String,
    },
}

/// What the actuator does over one hold interval.
#[derive(Debug, Clone, Copy, PartialEq)]
enum ActuatorInput {
    /// The amplifier's own output K_a·u (V); the armature voltage adds the back-EMF
    /// compensation of a current-mode amplifier and is clamped to the supply.
    Voltage(f64),
    /// Motor torque (N·m), already clamped to the peak torque.
    Torque(f64),
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Actuator {
    DcMotor {
        torque_constant: f64,
        back_emf_constant: f64,
        resistance: f64,
        inductance: f64,
        amplifier_gain: f64,
        supply_voltage: f64,
        amplifier_mode: AmplifierMode,
    },
    IdealTorque {
        peak_torque: f64,
        /// Only to report a current.
        torque_constant: f64,
    },
}

/// State of one axis. Positions and velocities in joint units; the drive side is the motor
/// divided by the ratio. `charge` is ∫i dt since the start of the hold interval.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct AxisState {
    drive_position: f64,
    drive_velocity: f64,
    carriage_position: f64,
    carriage_velocity: f64,
    current: f64,
    charge: f64,
}

impl AxisState {
    /// `self + h·rate`, component-wise.
    fn plus(&self, h: f64, rate: &AxisState) -> AxisState {
        AxisState {
            drive_position: self.drive_position + h * rate.drive_position,
            drive_velocity: self.drive_velocity + h * rate.drive_velocity,
            carriage_position: self.carriage_position + h * rate.carriage_position,
            carriage_velocity: self.carriage_velocity + h * rate.carriage_velocity,
            current: self.current + h * rate.current,
            charge: self.charge + h * rate.charge,
        }
    }
}

/// How drive and carriage are coupled.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Contact {
    /// No backlash: one rigid body.
    Rigid,
    /// Gap open: drive and carriage move independently.
    Open,
    /// Gap closed at δ = side·b/2 (side = +1: the drive pushes the carriage forward).
    Closed { side: f64 },
    /// A compliant transmission beyond the gap's end `side` (±1; 0 without backlash): the
    /// spring and damper pass λ to the carriage.
    Compliant { side: f64 },
}

/// State of the guide friction of the body that carries the carriage.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Guide {
    /// Friction −F_c·direction; direction is ±1, or 0 when there is no Coulomb friction.
    Sliding { direction: f64 },
    /// Held by static friction: velocity exactly zero.
    Stuck,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Mode {
    contact: Contact,
    guide: Guide,
}

/// Below this speed (joint units/s) a body at a switching point counts as at rest: 1 nm/s,
/// far below anything a servo commands, far above what bisection leaves at a zero crossing.
const REST_SPEED: f64 = 1e-9;
/// Tolerance on the gap at its ends (joint units), for the same reason: 0.1 nm.
const GAP_TOLERANCE: f64 = 1e-10;
/// Halvings of a step to locate an event: the instant to 2⁻⁴⁴ of the step.
const BISECTIONS: usize = 44;
/// Events handled within one step before the rest of the step is taken without switching
/// (guards a chain of simultaneous events, e.g. an impact that immediately sticks).
const MAX_EVENTS_PER_STEP: usize = 16;

/// One machine axis as an ODE model. See the module documentation for the equations.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisModel {
    ratio: f64,
    actuator: Actuator,
    /// Drive-side inertia and damping at the joint: J·k², C·k².
    drive_mass: f64,
    drive_damping: f64,
    /// Carriage (moved mass) and the guide's own viscous damping.
    carriage_mass: f64,
    carriage_damping: f64,
    /// Gravity force on the carriage along the joint axis (N).
    gravity_force: f64,
    /// A load on the carriage along the joint axis besides gravity (N or N·m: the cutting
    /// force), held over each [`AxisModel::advance`].
    load: f64,
    friction: StribeckCurve,
    backlash: f64,
    compliance: Option<Compliance>,
    feedback: Feedback,
    state: AxisState,
    mode: Mode,
    flows: exact::FlowCache,
}

/// What an axis did over one hold interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoldInterval {
    /// Mean motor torque over the interval (N·m).
    pub mean_torque: f64,
    /// Armature voltage (V); zero for the ideal actuator.
    pub voltage: f64,
}

impl AxisModel {
    /// An axis at rest at position 0 with the gap centred.
    ///
    /// `moved_mass`: mass the joint moves (kg; kg·m² for a rotary joint whose inertia does not
    /// depend on the pose). `gravity_along_axis`: component of gravity along the joint axis
    /// (m/s², e.g. −9.81 for a Z axis pointing up). `joint_damping`: the guide's own viscous
    /// damping (the URDF joint's), added to the drive's reflected damping.
    pub fn from_drive(
        drive: &Drive,
        moved_mass: f64,
        gravity_along_axis: f64,
        joint_damping: f64,
        options: AxisModelOptions,
    ) -> Result<AxisModel, AxisModelError> {
        let at_least_zero = [
            ("moved_mass", moved_mass),
            ("joint_damping", joint_damping),
            ("friction.kinetic", options.friction.kinetic),
            ("backlash", options.backlash),
            (
                "viscous_damping_nm_s_per_rad",
                drive.viscous_damping_nm_s_per_rad,
            ),
            ("back_emf_v_s_per_rad", drive.motor.back_emf_v_s_per_rad),
        ];
        for (name, value) in at_least_zero {
            if !(value.is_finite() && value >= 0.0) {
                return Err(AxisModelError::Negative { name, value });
            }
        }
        let f = options.friction;
        if !(f.breakaway.is_finite() && f.breakaway >= f.kinetic) {
            return Err(AxisModelError::Breakaway {
                breakaway: f.breakaway,
                kinetic: f.kinetic,
            });
        }
        if f.has_stiction() && !(f.stribeck_velocity.is_finite() && f.stribeck_velocity > 0.0) {
            return Err(AxisModelError::NotPositive {
                name: "friction.stribeck_velocity",
                value: f.stribeck_velocity,
            });
        }
        let m = &drive.motor;
        let positive = [
            ("ratio", drive.ratio()),
            ("motor-side inertia", drive.motor_side_inertia()),
            ("torque_constant_nm_per_a", m.torque_constant_nm_per_a),
            ("resistance_ohm", m.resistance_ohm),
            ("inductance_h", m.inductance_h),
            ("peak_torque_nm", drive.peak_torque_nm),
        ];
        for (name, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(AxisModelError::NotPositive { name, value });
            }
        }
        if !gravity_along_axis.is_finite() {
            return Err(AxisModelError::Negative {
                name: "gravity_along_axis",
                value: gravity_along_axis,
            });
        }
        if (options.backlash > 0.0 || options.compliance.is_some()) && moved_mass == 0.0 {
            return Err(AxisModelError::MasslessCarriage);
        }
        if let Some(c) = options.compliance {
            if !(c.stiffness.is_finite() && c.stiffness > 0.0) {
                return Err(AxisModelError::NotPositive {
                    name: "transmission stiffness",
                    value: c.stiffness,
                });
            }
            if !(c.damping.is_finite() && c.damping >= 0.0) {
                return Err(AxisModelError::Negative {
                    name: "transmission damping",
                    value: c.damping,
                });
            }
        }
        let actuator = if options.ideal_actuator {
            Actuator::IdealTorque {
                peak_torque: drive.peak_torque_nm,
                torque_constant: m.torque_constant_nm_per_a,
            }
        } else {
            Actuator::DcMotor {
                torque_constant: m.torque_constant_nm_per_a,
                back_emf_constant: m.back_emf_v_s_per_rad,
                resistance: m.resistance_ohm,
                inductance: m.inductance_h,
                amplifier_gain: drive.amplifier_gain,
                supply_voltage: drive.supply_voltage_v,
                amplifier_mode: drive.amplifier_mode,
            }
        };
        let mut model = AxisModel {
            ratio: drive.ratio(),
            actuator,
            drive_mass: drive.reflected_inertia(),
            drive_damping: drive.reflected_damping(),
            carriage_mass: moved_mass,
            carriage_damping: joint_damping,
            gravity_force: moved_mass * gravity_along_axis,
            load: 0.0,
            friction: options.friction,
            backlash: options.backlash,
            compliance: options.compliance,
            feedback: options.feedback,
            state: AxisState::default(),
            mode: Mode {
                contact: Contact::Rigid,
                guide: Guide::Stuck,
            },
            flows: exact::FlowCache::default(),
        };
        model.rest_at(0.0);
        Ok(model)
    }

    /// One model per machine axis, in the machine's axis order, with the machine's own
    /// backlash, guide friction and feedback per axis. The moved mass is every link downstream
    /// of the joint; gravity (base frame, m/s²) is projected on the joint axis, and on the guide
    /// normal for the friction load N (μ·N is the Coulomb force). Only prismatic axes below
    /// prismatic or fixed joints (Cartesian machines), where all of these are constants.
    pub fn for_machine(
        machine: &Machine,
        gravity: [f64; 3],
        ideal_actuator: bool,
    ) -> Result<Vec<AxisModel>, AxisModelError> {
        if let Some(&j) = machine.passive_joints().first() {
            return Err(AxisModelError::PassiveJoint {
                joint: machine.joints[j].name.clone(),
            });
        }
        let couplings = machine.couplings();
        if let Some((follower, axis)) = machine.follower_of_split_drive() {
            return Err(AxisModelError::FollowerOfSplitDrive { follower, axis });
        }
        let mut velocity_per_axis = Vec::with_capacity(machine.axes.len());
        let models = machine
            .axes
            .iter()
            .map(|axis| {
                let pose_dependent = || AxisModelError::PoseDependent {
                    axis: axis.name.clone(),
                };
                let joint = &machine.joints[axis.joint];
                // Orientation of the joint frame in the base at q = 0, constant as long as no
                // joint above it rotates.
                let rotation = fixed_orientation(machine, axis.joint).ok_or_else(pose_dependent)?;
                // The links this axis moves and how fast, per unit of its velocity: its own
                // subtree along its axis, plus the subtrees of its <mimic> followers along
                // theirs, scaled by their multipliers.
                let mut velocity = vec![Vector3::zeros(); machine.links.len()];
                let mut follower_damping = 0.0;
                let mut follower_friction = 0.0;
                let moved_along = |j: usize, scale: f64, velocity: &mut [Vector3<f64>]| {
                    let moved = &machine.joints[j];
                    let along = fixed_orientation(machine, j)
                        .filter(|_| moved.kind == JointKind::Prismatic)
                        .map(|r| r * moved.axis * scale)?;
                    for (v, below) in velocity.iter_mut().zip(machine.subtree(moved.child)) {
                        if below {
                            *v += along;
                        }
                    }
                    Some(())
                };
                moved_along(axis.joint, 1.0, &mut velocity).ok_or_else(pose_dependent)?;
                for c in couplings.iter().filter(|c| c.leader == axis.joint) {
                    moved_along(c.follower, c.multiplier, &mut velocity)
                        .ok_or_else(pose_dependent)?;
                    let follower = &machine.joints[c.follower];
                    follower_damping += c.multiplier.powi(2) * follower.damping;
                    follower_friction += c.multiplier.abs() * follower.friction;
                }
                let g = Vector3::from(gravity);
                let (inertia, weight) =
                    machine
                        .links
                        .iter()
                        .zip(&velocity)
                        .fold((0.0, 0.0), |(m, w), (link, u)| {
                            (m + link.mass * u.norm_squared(), w + link.mass * g.dot(u))
                        });
                velocity_per_axis.push((velocity, inertia));
                // The carriage's own load on its guide: the links it carries.
                let mass: f64 = (machine.links.iter())
                    .zip(machine.subtree(joint.child))
                    .filter(|(_, below)| *below)
                    .map(|(l, _)| l.mass)
                    .sum();
                let mut friction = match &axis.drive.guide {
                    None => StribeckCurve::default(),
                    Some(guide) => {
                        let normal = Vector3::from(guide.normal).normalize();
                        let load = -mass * gravity_component(&rotation, &normal, gravity);
                        if load < 0.0 {
                            return Err(AxisModelError::LiftsOff {
                                axis: axis.name.clone(),
                            });
                        }
                        guide.coefficient().scaled(load)
                    }
                };
                // The joint's own Coulomb friction (the URDF's `<dynamics friction>`), and a
                // follower's, reflected through its multiplier.
                let joint_friction = joint.friction + follower_friction;
                friction.kinetic += joint_friction;
                friction.breakaway += joint_friction;
                let options = AxisModelOptions {
                    friction,
                    backlash: axis.drive.backlash,
                    ideal_actuator,
                    compliance: axis.drive.compliance(),
                    feedback: axis.drive.feedback,
                };
                let along = if inertia > 0.0 { weight / inertia } else { 0.0 };
                AxisModel::from_drive(
                    &axis.drive,
                    inertia,
                    along,
                    joint.damping + follower_damping,
                    options,
                )
            })
            .collect::<Result<Vec<_>, _>>()?;
        // One model per axis holds only if no body moves with two axes at once along
        // directions that are not at right angles (a follower of X moving along Y would
        // couple X and Y through its mass). The off-diagonal mass, relative to the diagonal
        // ones, is a cosine in the mass metric: held to the tolerance the program axes have.
        for a in 0..models.len() {
            for b in a + 1..models.len() {
                let ((u, mass_a), (v, mass_b)) = (&velocity_per_axis[a], &velocity_per_axis[b]);
                let cross: f64 = (machine.links.iter())
                    .zip(u.iter().zip(v))
                    .map(|(link, (u, v))| link.mass * u.dot(v))
                    .sum();
                if cross.abs() > ORTHOGONALITY_TOLERANCE * (mass_a * mass_b).sqrt() {
                    return Err(AxisModelError::CoupledAxes {
                        axes: [machine.axes[a].name.clone(), machine.axes[b].name.clone()],
                        inertia: cross,
                    });
                }
            }
        }
        Ok(models)
    }

    /// Puts the axis at rest at `position` (drive and carriage, gap centred, no current).
    pub fn rest_at(&mut self, position: f64) {
        self.state = AxisState {
            drive_position: position,
            carriage_position: position,
            ..AxisState::default()
        };
        let mut state = self.state;
        self.mode = self.resolve(&mut state, self.input(0.0));
        self.state = state;
    }

    /// Carriage (joint) position: what the tool does.
    pub fn position(&self) -> f64 {
        self.state.carriage_position
    }

    /// Carriage (joint) velocity (m/s, or rad/s on a rotary axis).
    pub fn velocity(&self) -> f64 {
        self.state.carriage_velocity
    }

    /// Drive-side position: motor angle over the ratio (equals the position without backlash).
    pub fn drive_position(&self) -> f64 {
        self.state.drive_position
    }

    /// Drive-side velocity: motor speed over the ratio (m/s, or rad/s on a rotary axis).
    pub fn drive_velocity(&self) -> f64 {
        self.state.drive_velocity
    }

    /// The position the feedback sensor sees (before encoder rounding).
    pub fn feedback_position(&self) -> f64 {
        match self.feedback {
            Feedback::Motor => self.state.drive_position,
            Feedback::Carriage => self.state.carriage_position,
        }
    }

    /// Armature current (A); torque/K_m for the ideal actuator.
    pub fn current(&self) -> f64 {
        self.state.current
    }

    /// Inertia the motor accelerates with the gap closed, at the joint: J·k² + moved mass.
    pub fn effective_mass(&self) -> f64 {
        self.drive_mass + self.carriage_mass
    }

    /// Viscous damping at the joint: C·k² + the joint's own.
    pub fn effective_damping(&self) -> f64 {
        self.drive_damping + self.carriage_damping
    }

    /// Motor radians per joint unit.
    pub fn ratio(&self) -> f64 {
        self.ratio
    }

    /// Holds `command` (V at the amplifier input, or N·m for the ideal actuator) for
    /// `duration` seconds, in `steps` equal steps (exact or RK4, see the module documentation).
    pub fn advance(&mut self, command: f64, duration: f64, steps: usize) -> HoldInterval {
        assert!(
            steps > 0 && duration > 0.0,
            "advance needs steps ≥ 1 and a positive duration"
        );
        let input = self.input(command);
        let mut state = self.state;
        let start_voltage = match input {
            ActuatorInput::Voltage(v) => self.armature_voltage(&state, v),
            ActuatorInput::Torque(_) => 0.0,
        };
        if let (
            ActuatorInput::Torque(torque),
            Actuator::IdealTorque {
                torque_constant, ..
            },
        ) = (input, self.actuator)
        {
            state.current = torque / torque_constant;
        }
        state.charge = 0.0;
        // A new command is an event: the applied force may have left the stiction band or
        // reversed the contact force.
        self.mode = self.resolve(&mut state, input);
        if self.mode_cannot_end() && self.is_linear(self.mode) {
            // Nothing to locate inside the hold: one exact step over all of it.
            state = self.propagate(&state, input, duration, true);
            state = self.project(state);
        } else {
            let h = duration / steps as f64;
            for _ in 0..steps {
                state = self.step(state, input, h);
            }
        }
        self.state = state;
        match (self.actuator, input) {
            (
                Actuator::DcMotor {
                    torque_constant, ..
                },
                ActuatorInput::Voltage(_),
            ) => HoldInterval {
                mean_torque: torque_constant * state.charge / duration,
                voltage: start_voltage,
            },
            (Actuator::IdealTorque { .. }, ActuatorInput::Torque(torque)) => HoldInterval {
                mean_torque: torque,
                voltage: 0.0,
            },
            _ => unreachable!("input() matches the actuator"),
        }
    }

    fn input(&self, command: f64) -> ActuatorInput {
        match self.actuator {
            Actuator::DcMotor { amplifier_gain, .. } => {
                ActuatorInput::Voltage(amplifier_gain * command)
            }
            Actuator::IdealTorque { peak_torque, .. } => {
                ActuatorInput::Torque(command.clamp(-peak_torque, peak_torque))
            }
        }
    }

    /// Armature voltage (V) in state `y` for amplifier output `amplifier` (K_a·u).
    fn armature_voltage(&self, y: &AxisState, amplifier: f64) -> f64 {
        match self.actuator {
            Actuator::DcMotor {
                back_emf_constant,
                supply_voltage,
                amplifier_mode,
                ..
            } => {
                let omega = self.ratio * y.drive_velocity;
                amplifier_mode.armature_voltage(
                    amplifier,
                    back_emf_constant * omega,
                    supply_voltage,
                )
            }
            Actuator::IdealTorque { .. } => 0.0,
        }
    }

    /// Motor force at the joint (N) and di/dt in state `y`.
    fn motor(&self, y: &AxisState, input: ActuatorInput) -> (f64, f64) {
        match (self.actuator, input) {
            (
                Actuator::DcMotor {
                    torque_constant,
                    back_emf_constant,
                    resistance,
                    inductance,
                    ..
                },
                ActuatorInput::Voltage(amplifier),
            ) => {
                let omega = self.ratio * y.drive_velocity;
                let v = self.armature_voltage(y, amplifier);
                let di = (v - resistance * y.current - back_emf_constant * omega) / inductance;
                (self.ratio * torque_constant * y.current, di)
            }
            (Actuator::IdealTorque { .. }, ActuatorInput::Torque(t)) => (self.ratio * t, 0.0),
            _ => unreachable!("input() matches the actuator"),
        }
    }

    /// Acceleration of the combined body (gap closed or no backlash) while sliding.
    fn combined_acceleration(&self, y: &AxisState, motor_force: f64, direction: f64) -> f64 {
        let v = y.carriage_velocity;
        (motor_force - self.effective_damping() * v + self.carriage_force()
            - self.friction.sliding(v) * direction)
            / self.effective_mass()
    }

    /// Force the drive passes to the carriage with the gap closed.
    fn contact_force(&self, y: &AxisState, guide: Guide, input: ActuatorInput) -> f64 {
        let (motor_force, _) = self.motor(y, input);
        match guide {
            Guide::Stuck => motor_force,
            Guide::Sliding { direction } => {
                let a = self.combined_acceleration(y, motor_force, direction);
                motor_force - self.drive_damping * y.drive_velocity - self.drive_mass * a
            }
        }
    }

    /// Force a compliant transmission passes to the carriage beyond gap end `side`.
    fn spring_force(&self, y: &AxisState, side: f64) -> f64 {
        let Some(c) = self.compliance else { return 0.0 };
        let gap = y.drive_position - y.carriage_position;
        c.stiffness * (gap - side * self.backlash / 2.0)
            + c.damping * (y.drive_velocity - y.carriage_velocity)
    }

    /// Force on the friction-carrying body other than friction and damping, at rest.
    fn applied_force_at_rest(&self, y: &AxisState, contact: Contact, input: ActuatorInput) -> f64 {
        match contact {
            Contact::Open => self.carriage_force(),
            Contact::Compliant { side } => self.spring_force(y, side) + self.carriage_force(),
            Contact::Rigid | Contact::Closed { .. } => {
                self.motor(y, input).0 + self.carriage_force()
            }
        }
    }

    /// Time derivative of the state in a mode.
    fn rate(&self, y: &AxisState, mode: Mode, input: ActuatorInput) -> AxisState {
        let (motor_force, di) = self.motor(y, input);
        let mut rate = AxisState {
            current: di,
            charge: y.current,
            ..AxisState::default()
        };
        match mode.contact {
            Contact::Rigid | Contact::Closed { .. } => {
                let a = match mode.guide {
                    Guide::Stuck => 0.0,
                    Guide::Sliding { direction } => {
                        self.combined_acceleration(y, motor_force, direction)
                    }
                };
                rate.drive_position = y.carriage_velocity;
                rate.carriage_position = y.carriage_velocity;
                rate.drive_velocity = a;
                rate.carriage_velocity = a;
            }
            Contact::Open | Contact::Compliant { .. } => {
                // What the transmission passes to the carriage: nothing across an open gap.
                let lambda = match mode.contact {
                    Contact::Compliant { side } => self.spring_force(y, side),
                    _ => 0.0,
                };
                rate.drive_position = y.drive_velocity;
                rate.drive_velocity =
                    (motor_force - self.drive_damping * y.drive_velocity - lambda)
                        / self.drive_mass;
                rate.carriage_position = y.carriage_velocity;
                rate.carriage_velocity = match mode.guide {
                    Guide::Stuck => 0.0,
                    Guide::Sliding { direction } => {
                        (lambda + self.carriage_force()
                            - self.carriage_damping * y.carriage_velocity
                            - self.friction.sliding(y.carriage_velocity) * direction)
                            / self.carriage_mass
                    }
                };
            }
        }
        rate
    }

    /// The state `duration` after `y` in the current mode: exact where the mode is linear,
    /// RK4 otherwise. `keep`: the duration recurs (the standard step), so its flow is cached.
    fn propagate(
        &mut self,
        y: &AxisState,
        input: ActuatorInput,
        duration: f64,
        keep: bool,
    ) -> AxisState {
        let mode = self.mode;
        if !self.is_linear(mode) {
            return self.rk4(y, mode, input, duration);
        }
        let w = self.linear_input(input);
        // Flows are kept for the standard step under no load besides gravity; a cut's load
        // changes every step.
        let unloaded = self.load == 0.0;
        let keep = keep && unloaded;
        if let Some(flow) = self.flows.get(mode, duration).filter(|_| unloaded) {
            return flow.apply(y, w);
        }
        let flow = self
            .linear_flow(mode, duration)
            .expect("is_linear: the mode has a linear system");
        let next = flow.apply(y, w);
        if keep {
            self.flows.insert(flow);
        }
        next
    }

    /// Gravity and the load on the carriage along the joint axis (N or N·m).
    pub(super) fn carriage_force(&self) -> f64 {
        self.gravity_force + self.load
    }

    /// Holds `load` on the carriage (N or N·m along the joint axis, besides gravity) until
    /// changed: the cutting force the axis takes.
    pub fn set_load(&mut self, load: f64) {
        self.load = load;
    }

    /// Whether no guard of the current mode can fail: one rigid body, or a compliant
    /// transmission without backlash, without Coulomb friction.
    fn mode_cannot_end(&self) -> bool {
        matches!(
            self.mode.contact,
            Contact::Rigid | Contact::Compliant { side: 0.0 }
        ) && self.mode.guide == Guide::Sliding { direction: 0.0 }
    }

    fn rk4(&self, y: &AxisState, mode: Mode, input: ActuatorInput, h: f64) -> AxisState {
        let k1 = self.rate(y, mode, input);
        let k2 = self.rate(&y.plus(h / 2.0, &k1), mode, input);
        let k3 = self.rate(&y.plus(h / 2.0, &k2), mode, input);
        let k4 = self.rate(&y.plus(h, &k3), mode, input);
        let slope = k1.plus(2.0, &k2).plus(2.0, &k3).plus(1.0, &k4);
        y.plus(h / 6.0, &slope)
    }

    /// Whether `mode` is still the right description of state `y` (its guards hold).
    fn mode_holds(&self, y: &AxisState, mode: Mode, input: ActuatorInput) -> bool {
        let contact_holds = match mode.contact {
            Contact::Rigid => true,
            Contact::Open => (y.drive_position - y.carriage_position).abs() <= self.backlash / 2.0,
            Contact::Closed { side } => side * self.contact_force(y, mode.guide, input) >= 0.0,
            Contact::Compliant { side } => {
                side == 0.0
                    || side * (y.drive_position - y.carriage_position) >= self.backlash / 2.0
            }
        };
        let guide_holds = match mode.guide {
            Guide::Sliding { direction } => direction * y.carriage_velocity >= 0.0,
            Guide::Stuck => {
                self.applied_force_at_rest(y, mode.contact, input).abs() <= self.friction.breakaway
            }
        };
        contact_holds && guide_holds
    }

    /// Picks the mode that fits state `y`, applying the jumps a switch implies: the velocity
    /// jump of an inelastic impact, exact zero velocity on sticking.
    fn resolve(&self, y: &mut AxisState, input: ActuatorInput) -> Mode {
        if self.compliance.is_some() {
            // No impacts: the spring takes over smoothly where the gap ends.
            let gap = y.drive_position - y.carriage_position;
            let half = self.backlash / 2.0;
            let contact = if half == 0.0 {
                Contact::Compliant { side: 0.0 }
            } else if gap.abs() > half {
                Contact::Compliant { side: gap.signum() }
            } else {
                Contact::Open
            };
            return Mode {
                contact,
                guide: self.resolve_guide(y, contact, input),
            };
        }
        if self.backlash == 0.0 {
            let contact = Contact::Rigid;
            return Mode {
                contact,
                guide: self.resolve_guide(y, contact, input),
            };
        }
        let half = self.backlash / 2.0;
        let gap = y.drive_position - y.carriage_position;
        let closing = y.drive_velocity - y.carriage_velocity;
        let side = if gap >= half - GAP_TOLERANCE && closing >= -REST_SPEED {
            Some(1.0)
        } else if gap <= -half + GAP_TOLERANCE && closing <= REST_SPEED {
            Some(-1.0)
        } else {
            None
        };
        if let Some(side) = side {
            // Inelastic impact (or resting contact): common velocity conserving momentum.
            // Positions are put exactly at the gap end, moving the centre of mass not at all.
            let (md, mc) = (self.drive_mass, self.carriage_mass);
            let v = (md * y.drive_velocity + mc * y.carriage_velocity) / (md + mc);
            let excess = gap - side * half;
            let mut closed = *y;
            closed.drive_velocity = v;
            closed.carriage_velocity = v;
            closed.drive_position -= excess * mc / (md + mc);
            closed.carriage_position += excess * md / (md + mc);
            let contact = Contact::Closed { side };
            let guide = self.resolve_guide(&mut closed, contact, input);
            if side * self.contact_force(&closed, guide, input) >= 0.0 {
                *y = closed;
                return Mode { contact, guide };
            }
            // The drive pulls away: the bodies part (after the impact, if there was one).
            y.drive_velocity = closed.drive_velocity;
            y.carriage_velocity = closed.carriage_velocity;
        }
        let contact = Contact::Open;
        Mode {
            contact,
            guide: self.resolve_guide(y, contact, input),
        }
    }

    fn resolve_guide(&self, y: &mut AxisState, contact: Contact, input: ActuatorInput) -> Guide {
        if self.friction.breakaway == 0.0 {
            return Guide::Sliding { direction: 0.0 };
        }
        let v = y.carriage_velocity;
        if v.abs() > REST_SPEED {
            return Guide::Sliding {
                direction: v.signum(),
            };
        }
        y.carriage_velocity = 0.0;
        if matches!(contact, Contact::Rigid | Contact::Closed { .. }) {
            y.drive_velocity = 0.0;
        }
        let applied = self.applied_force_at_rest(y, contact, input);
        if applied.abs() <= self.friction.breakaway {
            Guide::Stuck
        } else {
            Guide::Sliding {
                direction: applied.signum(),
            }
        }
    }

    /// One integration step of length h, switching modes at located events.
    fn step(&mut self, start: AxisState, input: ActuatorInput, h: f64) -> AxisState {
        let mut y = start;
        let mut remaining = h;
        let mut events = 0;
        loop {
            let trial = self.propagate(&y, input, remaining, remaining == h);
            if events >= MAX_EVENTS_PER_STEP || self.mode_holds(&trial, self.mode, input) {
                return self.project(trial);
            }
            // Bisect for the first instant the mode stops holding.
            let (mut holds_until, mut fails_at, mut at_fail) = (0.0, remaining, trial);
            for _ in 0..BISECTIONS {
                let mid = 0.5 * (holds_until + fails_at);
                let y_mid = self.propagate(&y, input, mid, false);
                if self.mode_holds(&y_mid, self.mode, input) {
                    holds_until = mid;
                } else {
                    fails_at = mid;
                    at_fail = y_mid;
                }
            }
            y = self.project(at_fail);
            self.mode = self.resolve(&mut y, input);
            remaining -= fails_at;
            events += 1;
            if remaining <= 0.0 {
                return y;
            }
        }
    }

    /// Removes the round-off drift of the constraints a mode imposes.
    fn project(&self, mut y: AxisState) -> AxisState {
        match self.mode.contact {
            Contact::Rigid => {
                y.drive_position = y.carriage_position;
                y.drive_velocity = y.carriage_velocity;
            }
            Contact::Closed { side } => {
                y.drive_position = y.carriage_position + side * self.backlash / 2.0;
                y.drive_velocity = y.carriage_velocity;
            }
            Contact::Open | Contact::Compliant { .. } => {}
        }
        y
    }
}

/// Orientation in the base of joint `j`'s frame at zero, if no joint above it turns (then it
/// is the same in every pose).
fn fixed_orientation(machine: &Machine, j: usize) -> Option<UnitQuaternion<f64>> {
    let joint = &machine.joints[j];
    let mut rotation = joint.origin.rotation;
    let mut link = joint.parent;
    while let Some(above) = machine.parent_joint(link) {
        let above = &machine.joints[above];
        if above.kind == JointKind::Revolute {
            return None;
        }
        rotation = above.origin.rotation * rotation;
        link = above.parent;
    }
    Some(rotation)
}

fn gravity_component(
    rotation: &UnitQuaternion<f64>,
    axis: &Vector3<f64>,
    gravity: [f64; 3],
) -> f64 {
    (rotation * axis).dot(&Vector3::from(gravity))
}

/// The analytic axis models of a machine as a [`Plant`]: the same loop, controller and
/// setpoints as the Rapier machine, with a plant whose equations are written down. The tool
/// point follows from the axis positions (these models take Cartesian prismatic chains only,
/// where the tool point is affine in the joint coordinates).
pub struct AnalyticPlant {
    models: Vec<AxisModel>,
    period: f64,
    steps_per_period: usize,
    /// Tool point at zero joint coordinates and its displacement per joint unit of each axis.
    tool_origin: Vector3<f64>,
    tool_directions: Vec<Vector3<f64>>,
    steps: u64,
    /// The cut the tool makes: the cut, the tool's axis in the part's frame, and the sub-
    /// intervals of each period over which its force is held (the physics' steps).
    cut: Option<(super::cut::PlantCut, Vector3<f64>, usize)>,
}

impl AnalyticPlant {
    /// One axis model per machine axis (see [`AxisModel::for_machine`]), each at rest at
    /// `initial` (joint units), in `steps_per_period` steps per servo period.
    pub fn new(
        machine: &Machine,
        gravity: [f64; 3],
        ideal_actuator: bool,
        period: f64,
        steps_per_period: usize,
        initial: &[f64],
    ) -> Result<AnalyticPlant, AxisModelError> {
        let mut models = AxisModel::for_machine(machine, gravity, ideal_actuator)?;
        for (model, &p) in models.iter_mut().zip(initial) {
            model.rest_at(p);
        }
        Ok(Self::from_models(models, machine, period, steps_per_period))
    }

    /// A plant of given axis models (already placed), with the machine's tool kinematics.
    pub fn from_models(
        models: Vec<AxisModel>,
        machine: &Machine,
        period: f64,
        steps_per_period: usize,
    ) -> AnalyticPlant {
        let n = models.len();
        let zeros = vec![0.0; n];
        // The tool relative to the program frame's carrier (a moving table moves it back).
        let carrier = crate::kinematics::carrier_link(machine);
        let tool = |q: &[f64]| crate::kinematics::tool_in_link(machine, carrier, q).coords;
        let origin = tool(&zeros);
        let tool_directions = (0..n)
            .map(|i| {
                let mut unit = zeros.clone();
                unit[i] = 1.0;
                tool(&unit) - origin
            })
            .collect();
        AnalyticPlant {
            models,
            period,
            steps_per_period: steps_per_period.max(1),
            tool_origin: origin,
            tool_directions,
            steps: 0,
            cut: None,
        }
    }

    /// The plant cutting `cut` with the tool's axis `tool_axis` (in the frame of the link
    /// carrying the part, which these chains never turn), its force held over `substeps`
    /// equal parts of each period (the physics' steps, so both lanes sample the cut alike).
    pub fn with_cut(
        mut self,
        cut: super::cut::PlantCut,
        tool_axis: Vector3<f64>,
        substeps: usize,
    ) -> AnalyticPlant {
        self.cut = Some((cut, tool_axis, substeps.max(1)));
        self
    }

    /// The tool point and its velocity relative to the part (m, m/s).
    fn tool(&self) -> (Vector3<f64>, Vector3<f64>) {
        let mut tool = self.tool_origin;
        let mut velocity = Vector3::zeros();
        for (m, d) in self.models.iter().zip(&self.tool_directions) {
            tool += d * m.position();
            velocity += d * m.velocity();
        }
        (tool, velocity)
    }

    /// One period under a cut: the force computed from this plant's own tool motion at the
    /// start of each sub-interval and held over it, on every axis as its share (the force
    /// along the axis's tool direction: the Jacobian's transpose).
    fn hold_cutting(&mut self, command: &[f64], out: &mut Hold) {
        let Some((mut cut, axis, parts)) = self.cut.take() else {
            return;
        };
        let h = self.period / parts as f64;
        let steps = (self.steps_per_period / parts).max(1);
        out.mean_torque.iter_mut().for_each(|t| *t = 0.0);
        for part in 0..parts {
            let (tool, velocity) = self.tool();
            let load = cut.step(&tool.into(), &axis, &velocity, h);
            for (i, model) in self.models.iter_mut().enumerate() {
                model.set_load(load.on_tool.dot(&self.tool_directions[i]));
                let held = model.advance(command[i], h, steps);
                out.mean_torque[i] += held.mean_torque / parts as f64;
                if part == 0 {
                    out.voltage[i] = held.voltage;
                }
            }
            self.steps += steps as u64;
        }
        cut.end_period(&mut out.cut);
        self.cut = Some((cut, axis, parts));
    }

    /// The axis models, in the machine's axis order.
    pub fn models(&self) -> &[AxisModel] {
        &self.models
    }
}

impl Plant for AnalyticPlant {
    fn axes(&self) -> usize {
        self.models.len()
    }

    fn sample(&mut self, out: &mut Sensors) {
        for (i, m) in self.models.iter().enumerate() {
            out.position[i] = m.position();
            out.velocity[i] = m.velocity();
            out.drive_position[i] = m.drive_position();
            out.feedback_position[i] = m.feedback_position();
            out.current[i] = m.current();
        }
        let (tool, tool_velocity) = self.tool();
        out.tool_point = tool.into();
        out.tool_velocity = tool_velocity.into();
    }

    fn hold(&mut self, command: &[f64], out: &mut Hold) {
        if self.cut.is_some() {
            return self.hold_cutting(command, out);
        }
        for (i, model) in self.models.iter_mut().enumerate() {
            let h = model.advance(command[i], self.period, self.steps_per_period);
            out.mean_torque[i] = h.mean_torque;
            out.voltage[i] = h.voltage;
        }
        self.steps += self.steps_per_period as u64;
    }

    fn steps(&self) -> u64 {
        self.steps
    }

    fn set_spindle(&mut self, speed: f64) {
        if let Some((cut, _, _)) = &mut self.cut {
            cut.set_spindle(speed);
        }
    }

    fn fault(&self) -> Option<String> {
        self.cut.as_ref().and_then(|(cut, _, _)| cut.fault())
    }

    fn stock(&self) -> Option<&crate::cutting::Stock> {
        self.cut.as_ref().map(|(cut, _, _)| cut.stock())
    }

    fn take_cut(&mut self) -> Option<crate::cutting::Cut> {
        self.cut.take().map(|(cut, _, _)| cut.into_cut())
    }
}

#[cfg(test)]
mod tests;
