//! Compensation at axis reversals, around any controller:
//!
//! ```text
//!   setpoint ─▶ (+ backlash offset) ─▶ controller ─▶ (+ friction pulse) ─▶ command
//! ```
//!
//! - **Backlash compensation**, as LinuxCNC's motion controller applies it: the position
//!   command is offset by +b/2 while the axis is commanded forward and −b/2 backward, so the
//!   drive side runs ahead by half the lost motion each way and the carriage follows the
//!   setpoint. On a reversal the offset moves to its new side at a limited rate (m/s or rad/s),
//!   not as a step; its rate is added to the velocity setpoint. The direction is the sign of
//!   the commanded velocity (held while the command stands still).
//! - **Friction (quadrant-glitch) compensation**: when the commanded velocity changes sign,
//!   a pulse A·exp(−t/τ) in the new direction is added to the controller's output (command
//!   units: V at the amplifier input, or N·m), to break the carriage away from static
//!   friction at once instead of waiting for the integrator.

use super::{Controller, ControllerInput};

/// One axis's compensation (joint units: m or rad).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AxisCompensation {
    /// Lost motion to compensate (0: none).
    pub backlash: f64,
    /// Rate at which the backlash offset moves to its new side (per s).
    pub backlash_rate: f64,
    /// Friction pulse amplitude at a reversal (command units; 0: none).
    pub friction_pulse: f64,
    /// Its decay time constant (s).
    pub friction_decay: f64,
}

#[derive(Debug, Clone, Copy, Default)]
struct AxisState {
    /// Commanded direction: +1, −1, or 0 before the first motion.
    direction: f64,
    offset: f64,
    /// Time and direction of the last reversal, for the friction pulse.
    reversal: Option<(f64, f64)>,
}

/// A controller with backlash and friction compensation on the axes that ask for them.
pub struct Compensated {
    inner: Box<dyn Controller>,
    axes: Vec<AxisCompensation>,
    state: Vec<AxisState>,
    period: f64,
    position: Vec<f64>,
    velocity: Vec<f64>,
}

impl Compensated {
    /// `inner` with the compensation of `axes` (one per axis, machine order) around it, at servo
    /// period `period` (s).
    pub fn new(inner: Box<dyn Controller>, axes: Vec<AxisCompensation>, period: f64) -> Self {
        let n = axes.len();
        Compensated {
            inner,
            state: vec![AxisState::default(); n],
            axes,
            period,
            position: vec![0.0; n],
            velocity: vec![0.0; n],
        }
    }
}

impl Controller for Compensated {
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
        for (i, (c, s)) in self.axes.iter().zip(&mut self.state).enumerate() {
            let v = input.setpoint_velocity[i];
            let direction = if v > 0.0 {
                1.0
            } else if v < 0.0 {
                -1.0
            } else {
                s.direction
            };
            if direction != s.direction && s.direction != 0.0 {
                s.reversal = Some((input.time, direction));
            }
            s.direction = direction;
            let target = direction * c.backlash / 2.0;
            let step = c.backlash_rate * self.period;
            let previous = s.offset;
            s.offset += (target - s.offset).clamp(-step, step);
            self.position[i] = input.setpoint_position[i] + s.offset;
            self.velocity[i] = v + (s.offset - previous) / self.period;
        }
        let shifted = ControllerInput {
            setpoint_position: &self.position,
            setpoint_velocity: &self.velocity,
            ..*input
        };
        self.inner.update(&shifted, command);
        for (i, (c, s)) in self.axes.iter().zip(&self.state).enumerate() {
            if let (Some((at, direction)), true) = (s.reversal, c.friction_pulse != 0.0) {
                let age = input.time - at;
                command[i] += direction * c.friction_pulse * (-age / c.friction_decay).exp();
            }
        }
    }

    fn reset(&mut self) {
        self.inner.reset();
        self.state
            .iter_mut()
            .for_each(|s| *s = AxisState::default());
    }

    fn fault(&self) -> Option<&str> {
        self.inner.fault()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Passes the setpoint position out as the command, to watch what the controller sees.
    struct Echo;
    impl Controller for Echo {
        fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
            command[0] = input.setpoint_position[0];
        }
        fn reset(&mut self) {}
    }

    fn tick(c: &mut Compensated, time: f64, velocity: f64) -> f64 {
        let mut out = [0.0];
        c.update(
            &ControllerInput {
                time,
                setpoint_position: &[0.0],
                setpoint_velocity: &[velocity],
                setpoint_acceleration: &[0.0],
                measured_position: &[0.0],
                motor_position: &[0.0],
            },
            &mut out,
        );
        out[0]
    }

    #[test]
    fn the_backlash_offset_follows_the_direction_at_its_rate() {
        let axis = AxisCompensation {
            backlash: 0.4e-3,
            backlash_rate: 0.1,
            ..Default::default()
        };
        let mut c = Compensated::new(Box::new(Echo), vec![axis], 1e-3);
        // Forward: +0.2 mm, reached at 0.1 mm per tick.
        assert!((tick(&mut c, 0.0, 1.0) - 0.1e-3).abs() < 1e-15);
        assert!((tick(&mut c, 0.001, 1.0) - 0.2e-3).abs() < 1e-15);
        assert!((tick(&mut c, 0.002, 0.0) - 0.2e-3).abs() < 1e-15);
        // Backward: to −0.2 mm over four ticks.
        let offsets: Vec<f64> = (0..5)
            .map(|k| tick(&mut c, 0.003 + k as f64 * 1e-3, -1.0))
            .collect();
        assert!((offsets[3] + 0.2e-3).abs() < 1e-15, "{offsets:?}");
        assert!((offsets[1] - 0.0).abs() < 1e-15, "{offsets:?}");
    }

    #[test]
    fn a_friction_pulse_decays_after_each_reversal() {
        let axis = AxisCompensation {
            friction_pulse: 2.0,
            friction_decay: 0.01,
            ..Default::default()
        };
        let mut c = Compensated::new(Box::new(Echo), vec![axis], 1e-3);
        assert_eq!(tick(&mut c, 0.0, 1.0), 0.0, "no pulse before a reversal");
        assert!((tick(&mut c, 0.1, -1.0) + 2.0).abs() < 1e-12);
        let later = tick(&mut c, 0.11, -1.0);
        assert!((later + 2.0 * (-1.0f64).exp()).abs() < 1e-12, "{later}");
    }
}
