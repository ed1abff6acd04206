//! Controllers (per-axis PID, inverse dynamics) and actuator models. A controller runs once per
//! servo period on sampled feedback and returns one command per axis; an actuator turns a held
//! command into motor torque at the physics rate.

mod actuator;
mod computed_torque;
mod pid;
mod task_space;

pub use actuator::{Actuator, ActuatorKind, ActuatorOutput};
pub use computed_torque::ComputedTorque;
pub use pid::{Pid, PidForm, PidGains};
pub use task_space::TaskSpace;

/// What a controller sees at a servo tick, per axis (joint units: m or rad).
#[derive(Debug, Clone, Copy)]
pub struct ControllerInput<'a> {
    pub setpoint_position: &'a [f64],
    pub setpoint_velocity: &'a [f64],
    pub setpoint_acceleration: &'a [f64],
    /// Measured position (quantised by the encoder if one is modelled).
    pub measured_position: &'a [f64],
}

/// A servo controller for all axes of a machine.
pub trait Controller {
    /// Computes the command of every axis into `command` (motor torque in N·m for an ideal
    /// torque actuator, amplifier input in V for the DC-motor model).
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]);
}

/// Independent PID loops, one per axis.
pub struct PidBank {
    loops: Vec<Pid>,
}

impl PidBank {
    pub fn new(loops: Vec<Pid>) -> Self {
        PidBank { loops }
    }
}

impl Controller for PidBank {
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
        for (i, pid) in self.loops.iter_mut().enumerate() {
            command[i] = pid.update(input.setpoint_position[i] - input.measured_position[i]);
        }
    }
}
