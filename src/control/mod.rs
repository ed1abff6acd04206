//! Controllers (per-axis PID, inverse dynamics) and actuator models. A controller runs once per
//! servo period on sampled feedback and returns one command per axis; an actuator turns a held
//! command into motor torque at the physics rate.

mod actuator;
mod cascade;
mod compensation;
mod computed_torque;
pub mod filters;
mod pid;
mod task_space;

pub use actuator::{command_for_torque, Actuator, ActuatorKind, ActuatorOutput};
pub use cascade::{velocity_smoothing, Cascade, CascadeAxis};
pub use compensation::{AxisCompensation, Compensated};
pub use computed_torque::ComputedTorque;
pub use filters::{Notch, TorqueFilters};
pub use pid::{Pid, PidForm, PidGains, PidSettings};
pub use task_space::TaskSpace;

/// What a controller sees at a servo tick, per axis (joint units: m or rad).
#[derive(Debug, Clone, Copy)]
pub struct ControllerInput<'a> {
    /// Program time of the tick (s); negative while the machine settles before the program.
    pub time: f64,
    /// Setpoint position (m, or rad on a rotary axis).
    pub setpoint_position: &'a [f64],
    /// Setpoint velocity (m/s, or rad/s).
    pub setpoint_velocity: &'a [f64],
    /// Setpoint acceleration (m/s², or rad/s²).
    pub setpoint_acceleration: &'a [f64],
    /// Measured position of the axis's feedback device, the one its position loop closes on:
    /// the motor encoder, or a linear scale on the carriage (quantised by the encoder if one
    /// is modelled).
    pub measured_position: &'a [f64],
    /// The motor encoder's position (the drive side of any backlash, joint units), which a
    /// drive's velocity loop closes on; equals `measured_position` for a motor-encoder axis.
    pub motor_position: &'a [f64],
}

/// A servo controller for all axes of a machine: a block with one input (the setpoints and
/// the measured positions of a tick) and one output per axis. The loop calls [`update`] once
/// per servo period and holds the output until the next call.
///
/// [`update`]: Controller::update
pub trait Controller {
    /// Computes the command of every axis into `command` (motor torque in N·m for an ideal
    /// torque actuator, amplifier input in V for the DC-motor model).
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]);
    /// Forgets all state (integrators, previous samples), as after power-up.
    fn reset(&mut self);
    /// Why the controller could not compute its last command, if it could not (a controller
    /// FMU whose step failed): the loop stops the lane there. Built-in controllers never fail.
    fn fault(&self) -> Option<&str> {
        None
    }
}

/// Independent PID loops with feed-forward, one per axis.
pub struct PidBank {
    loops: Vec<Pid>,
}

impl PidBank {
    /// A bank of `loops`, one per axis in the machine's axis order.
    pub fn new(loops: Vec<Pid>) -> Self {
        PidBank { loops }
    }
}

impl Controller for PidBank {
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
        for (i, pid) in self.loops.iter_mut().enumerate() {
            let x = input.setpoint_position[i];
            command[i] = pid.update_with(
                x - input.measured_position[i],
                x,
                input.setpoint_velocity[i],
                input.setpoint_acceleration[i],
            );
        }
    }

    fn reset(&mut self) {
        self.loops.iter_mut().for_each(Pid::reset);
    }
}
