//! Cascaded position/velocity control, the structure of industrial servo drives:
//!
//! ```text
//!   ẋ_d ──────────────────── ×kvff ─┐                      M(x_d)·ẍ_d ── ×kaff ─┐
//!   x_d ─▶(+)─▶ Kpp + Kip/s ───────▶(+)─▶ clamp ±v_max ─▶(+)─▶ Kpv + Kiv/s ───▶(+)─▶ clamp ─▶ u
//!          ▲ −                                            ▲ −
//!          └──────── x̂ (encoder) ──── d/dt, low-pass ──── v̂
//! ```
//!
//! The position loop (P, or PI) turns the position error into a velocity command, plus the
//! setpoint velocity as velocity feed-forward (kvff = 1: all of it). The velocity loop (PI)
//! turns the velocity error into the actuator command (amplifier input in V, or motor torque),
//! plus the torque the machine's own inertia needs for the setpoint acceleration, from the
//! rigid-body model of the machine at the setpoint (kaff = 1: all of it), converted to the
//! actuator's command. Velocity is estimated from the encoder: the backward difference of two
//! samples (the velocity half a period ago), then a first-order low-pass at
//! `velocity_filter_hz` (none when 0), as drives do to tame quantisation noise. Both
//! integrators stop while their output is saturated in the direction of their error
//! (conditional integration: no windup). The command can pass a low-pass and a notch filter
//! (`super::filters`) before the clamp, as a drive's current-setpoint filters, against the drive
//! train's resonance.

use super::filters::{Biquad, TorqueFilters};
use super::{command_for_torque, ActuatorKind, Controller, ControllerInput};
use crate::dynamics::{AxisDynamics, DynamicsWorkspace};
use crate::machine::Drive;
use nalgebra::{DMatrix, DVector};

/// One axis's loop settings, joint units (m or rad): Kpp in 1/s, Kip in 1/s², Kpv in command
/// units per (m/s), Kiv in command units per m, the velocity limit in m/s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CascadeAxis {
    /// Kpp, position loop proportional gain (1/s).
    pub position_kp: f64,
    /// Kip, position loop integral gain (1/s²).
    pub position_ki: f64,
    /// Kpv, velocity loop proportional gain (command units per m/s, or per rad/s).
    pub velocity_kp: f64,
    /// Kiv, velocity loop integral gain (command units per m, or per rad).
    pub velocity_ki: f64,
    /// Share of the setpoint velocity fed into the velocity command (1 = all).
    pub velocity_ff: f64,
    /// Share of the model's inertia torque for the setpoint acceleration (1 = all).
    pub acceleration_ff: f64,
    /// |velocity command| limit (infinite for none).
    pub velocity_limit: f64,
    /// |output| limit (infinite for none).
    pub output_limit: f64,
    /// Filters on the command, after the velocity loop and the feed-forward.
    pub filters: TorqueFilters,
}

/// State of one axis's two loops.
#[derive(Debug, Clone, Copy, Default)]
struct AxisState {
    position_integral: f64,
    velocity_integral: f64,
    /// The motor encoder's previous sample, for the velocity estimate.
    previous_position: Option<f64>,
    velocity: f64,
}

/// The command filters of one axis, with their state.
#[derive(Debug, Clone, Default)]
struct FilterChain(Vec<Biquad>);

impl FilterChain {
    fn step(&mut self, x: f64) -> f64 {
        self.0.iter_mut().fold(x, |v, b| b.step(v))
    }
}

/// The cascaded position/velocity controller of every axis (see the module documentation).
pub struct Cascade {
    axes: Vec<CascadeAxis>,
    state: Vec<AxisState>,
    filters: Vec<FilterChain>,
    /// Low-pass coefficient of the velocity estimate (1 = no filter).
    smoothing: f64,
    model: AxisDynamics,
    workspace: DynamicsWorkspace,
    mass: DMatrix<f64>,
    torque: DVector<f64>,
    drives: Vec<Drive>,
    actuator: ActuatorKind,
    period: f64,
}

/// The coefficient α of the velocity estimate's first-order low-pass at `filter_hz` (0: none,
/// α = 1), sampled every `period`: v̂ ← v̂ + α·(v_raw − v̂), the pole of e^{−2π·f·T}.
pub fn velocity_smoothing(filter_hz: f64, period: f64) -> f64 {
    if filter_hz > 0.0 {
        1.0 - (-std::f64::consts::TAU * filter_hz * period).exp()
    } else {
        1.0
    }
}

impl Cascade {
    /// One loop pair per axis (the machine's axis order); `model` gives the inertia for the
    /// acceleration feed-forward (armature included).
    pub fn new(
        axes: Vec<CascadeAxis>,
        velocity_filter_hz: f64,
        model: AxisDynamics,
        drives: &[Drive],
        actuator: ActuatorKind,
        period: f64,
    ) -> Cascade {
        let n = axes.len();
        let smoothing = velocity_smoothing(velocity_filter_hz, period);
        Cascade {
            state: vec![AxisState::default(); n],
            filters: axes
                .iter()
                .map(|a| FilterChain(a.filters.biquads(period)))
                .collect(),
            axes,
            smoothing,
            workspace: model.workspace(),
            model,
            mass: DMatrix::zeros(n, n),
            torque: DVector::zeros(n),
            drives: drives.to_vec(),
            actuator,
            period,
        }
    }
}

/// Adds `t·error` to `integral` unless the output it feeds is saturated in the direction of
/// the error.
fn integrate(integral: &mut f64, period: f64, error: f64, unclamped: f64, clamped: f64) {
    let winding_up = clamped != unclamped && error.signum() == unclamped.signum();
    if !winding_up {
        *integral += period * error;
    }
}

impl Controller for Cascade {
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
        let t = self.period;
        // The inertia torque of the setpoint acceleration, at the setpoint.
        if self.axes.iter().any(|a| a.acceleration_ff != 0.0) {
            self.model
                .mass_matrix(&mut self.workspace, input.setpoint_position, &mut self.mass);
            let a = DVector::from_column_slice(input.setpoint_acceleration);
            self.mass.mul_to(&a, &mut self.torque);
        }
        let chains = self.filters.iter_mut();
        for (i, ((axis, s), chain)) in self
            .axes
            .iter()
            .zip(&mut self.state)
            .zip(chains)
            .enumerate()
        {
            let x = input.measured_position[i];
            let motor = input.motor_position[i];
            let raw = match s.previous_position {
                Some(p) => (motor - p) / t,
                None => 0.0,
            };
            s.previous_position = Some(motor);
            s.velocity += self.smoothing * (raw - s.velocity);

            let position_error = input.setpoint_position[i] - x;
            let unclamped_v = axis.position_kp * position_error
                + axis.position_ki * (s.position_integral + t * position_error)
                + axis.velocity_ff * input.setpoint_velocity[i];
            let velocity_command = unclamped_v.clamp(-axis.velocity_limit, axis.velocity_limit);
            integrate(
                &mut s.position_integral,
                t,
                position_error,
                unclamped_v,
                velocity_command,
            );

            let velocity_error = velocity_command - s.velocity;
            let drive = &self.drives[i];
            let feed_forward = if axis.acceleration_ff != 0.0 {
                let motor_torque = axis.acceleration_ff * self.torque[i] / drive.ratio();
                command_for_torque(self.actuator, drive, motor_torque, 0.0)
            } else {
                0.0
            };
            let unclamped_u = chain.step(
                axis.velocity_kp * velocity_error
                    + axis.velocity_ki * (s.velocity_integral + t * velocity_error)
                    + feed_forward,
            );
            let u = unclamped_u.clamp(-axis.output_limit, axis.output_limit);
            integrate(&mut s.velocity_integral, t, velocity_error, unclamped_u, u);
            command[i] = u;
        }
    }

    fn reset(&mut self) {
        self.state
            .iter_mut()
            .for_each(|s| *s = AxisState::default());
        for chain in &mut self.filters {
            chain.0.iter_mut().for_each(Biquad::reset);
        }
    }
}
