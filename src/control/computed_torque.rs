//! Inverse-dynamics (computed-torque) control in joint space, docs/sources.md §1.3:
//!
//!   ν = q̈_d + K_D(q̇_d − q̇) + K_P(q_d − q),   τ = M(q)ν + C(q,q̇)q̇ + F q̇ + g(q)
//!
//! With a perfect model the closed loop is ë + K_D ė + K_P e = 0 on every axis, whatever the
//! configuration of the tilting table; with the gains K_P = ωn², K_D = 2ζωn it is a
//! second-order system of natural frequency ωn and damping ζ. The model is whatever the
//! controller is given (it may be perturbed to study robustness); q̇ is estimated from the
//! sampled encoder positions, as a drive would, corrected for the half-period lag of the
//! difference by the acceleration last commanded.
//!
//! With a [`TaskSpace`] the acceleration ν is instead resolved at the tool tip (see
//! `task_space.rs`); the conversion to torque and to the actuator is the same.

use super::{command_for_torque, ActuatorKind, Controller, ControllerInput, TaskSpace};
use crate::dynamics::{AxisDynamics, DynamicsWorkspace};
use crate::machine::Drive;

/// The inverse-dynamics (computed-torque) controller of every axis, in joint space or, with a
/// [`TaskSpace`], at the tool tip (see the module documentation).
pub struct ComputedTorque {
    model: AxisDynamics,
    workspace: DynamicsWorkspace,
    kp: f64,
    kd: f64,
    period: f64,
    actuator: ActuatorKind,
    drives: Vec<Drive>,
    task: Option<TaskSpace>,
    previous_position: Option<Vec<f64>>,
    velocity: Vec<f64>,
    nu: Vec<f64>,
    /// The joint-space law's ν, kept for the task-space law's null space.
    joint_nu: Vec<f64>,
    tau: Vec<f64>,
}

impl ComputedTorque {
    /// `model` in the machine's axis order (its armature and damping should be the drives');
    /// closed-loop natural frequency `omega_n` (rad/s) and damping ratio `zeta` on every axis.
    pub fn new(
        model: AxisDynamics,
        drives: &[Drive],
        actuator: ActuatorKind,
        period: f64,
        omega_n: f64,
        zeta: f64,
    ) -> Self {
        let n = model.dof();
        ComputedTorque {
            workspace: model.workspace(),
            model,
            kp: omega_n * omega_n,
            kd: 2.0 * zeta * omega_n,
            period,
            actuator,
            drives: drives.to_vec(),
            task: None,
            previous_position: None,
            velocity: vec![0.0; n],
            nu: vec![0.0; n],
            joint_nu: vec![0.0; n],
            tau: vec![0.0; n],
        }
    }
}

impl ComputedTorque {
    /// Imposes the error dynamics on the tool tip and tool axis instead of on every joint.
    pub fn in_task_space(mut self, task: TaskSpace) -> Self {
        self.task = Some(task);
        self
    }
}

impl Controller for ComputedTorque {
    // Five parallel per-axis slices: one index reads clearer than zipped iterators.
    #[allow(clippy::needless_range_loop)]
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
        let q = input.measured_position;
        // Backward difference of the sampled positions, which is the velocity half a period
        // ago; the acceleration commanded over that period brings it up to now.
        match &mut self.previous_position {
            Some(previous) => {
                for i in 0..q.len() {
                    self.velocity[i] =
                        (q[i] - previous[i]) / self.period + self.nu[i] * self.period / 2.0;
                }
                previous.copy_from_slice(q);
            }
            None => self.previous_position = Some(q.to_vec()),
        }
        for i in 0..q.len() {
            self.nu[i] = input.setpoint_acceleration[i]
                + self.kd * (input.setpoint_velocity[i] - self.velocity[i])
                + self.kp * (input.setpoint_position[i] - q[i]);
        }
        if let Some(task) = &self.task {
            self.joint_nu.copy_from_slice(&self.nu);
            task.acceleration(
                q,
                &self.velocity,
                input.setpoint_position,
                input.setpoint_velocity,
                input.setpoint_acceleration,
                self.kp,
                self.kd,
                &self.joint_nu,
                &mut self.nu,
            );
        }
        self.model.inverse_dynamics(
            &mut self.workspace,
            q,
            &self.velocity,
            &self.nu,
            &mut self.tau,
        );
        for (i, drive) in self.drives.iter().enumerate() {
            // Joint force → motor torque through the transmission → actuator command.
            let motor_torque = self.tau[i] / drive.ratio();
            command[i] = command_for_torque(self.actuator, drive, motor_torque, self.velocity[i]);
        }
    }

    fn reset(&mut self) {
        self.previous_position = None;
        self.velocity.iter_mut().for_each(|v| *v = 0.0);
        self.nu.iter_mut().for_each(|v| *v = 0.0);
    }
}
