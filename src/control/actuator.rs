//! Actuator models: controller command in, motor torque out.

use crate::machine::Drive;

/// Which actuator model drives the axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ActuatorKind {
    /// The command is the motor torque (N·m), clamped to the drive's peak torque.
    IdealTorque,
    /// The command is the amplifier input (V): the drive's amplifier (voltage or current
    /// mode) sets the armature voltage V within the supply; L·di/dt + R·i + K_b·ω = V,
    /// T = K_m·i.
    #[default]
    DcMotor,
}

/// The command that makes the actuator of `drive` deliver `motor_torque` (N·m) with the joint
/// moving at `joint_velocity`: the torque itself for the ideal actuator; for the DC motor the
/// amplifier input whose armature voltage drives that current against the back-EMF the
/// amplifier leaves (inductance neglected: a servo loop is far slower than L/R).
pub fn command_for_torque(
    kind: ActuatorKind,
    drive: &Drive,
    motor_torque: f64,
    joint_velocity: f64,
) -> f64 {
    match kind {
        ActuatorKind::IdealTorque => motor_torque,
        ActuatorKind::DcMotor => {
            let m = &drive.motor;
            let current = motor_torque / m.torque_constant_nm_per_a;
            (m.resistance_ohm * current
                + drive.effective_back_emf() * drive.ratio() * joint_velocity)
                / drive.amplifier_gain
        }
    }
}

/// One axis's actuator with its electrical state.
#[derive(Debug, Clone, PartialEq)]
pub struct Actuator {
    kind: ActuatorKind,
    drive: Drive,
    /// Armature current (A).
    current: f64,
}

/// What an actuator did over one physics step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ActuatorOutput {
    /// Mean motor torque over the step (N·m).
    pub torque: f64,
    /// Armature voltage (V); zero for the ideal actuator.
    pub voltage: f64,
    /// Armature current at the end of the step (A); torque/K_m for the ideal actuator.
    pub current: f64,
}

impl Actuator {
    /// The actuator of `kind` for `drive`, at rest (no current).
    pub fn new(kind: ActuatorKind, drive: &Drive) -> Self {
        Actuator {
            kind,
            drive: drive.clone(),
            current: 0.0,
        }
    }

    /// Advances the actuator by `dt` with command `u` held and motor speed `omega` (rad/s).
    pub fn step(&mut self, u: f64, omega: f64, dt: f64) -> ActuatorOutput {
        match self.kind {
            ActuatorKind::IdealTorque => {
                let torque = u.clamp(-self.drive.peak_torque_nm, self.drive.peak_torque_nm);
                self.current = torque / self.drive.motor.torque_constant_nm_per_a;
                ActuatorOutput {
                    torque,
                    voltage: 0.0,
                    current: self.current,
                }
            }
            ActuatorKind::DcMotor => {
                let m = &self.drive.motor;
                let voltage = self.drive.armature_voltage(u, omega);
                // Exact solution of the armature equation over the step with V and ω held:
                // i(t) = i∞ + (i0 − i∞)·e^(−t/τ), τ = L/R. The torque is the step's mean current.
                let tau = m.inductance_h / m.resistance_ohm;
                let i_inf = (voltage - m.back_emf_v_s_per_rad * omega) / m.resistance_ohm;
                let decay = (-dt / tau).exp();
                let i0 = self.current;
                let mean = i_inf + (i0 - i_inf) * tau / dt * (1.0 - decay);
                self.current = i_inf + (i0 - i_inf) * decay;
                ActuatorOutput {
                    torque: m.torque_constant_nm_per_a * mean,
                    voltage,
                    current: self.current,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::{DcMotor, Transmission};

    fn drive() -> Drive {
        Drive {
            joint: "x".into(),
            transmission: Transmission::Belt {
                gear_ratio: 100.0,
                pulley_radius_m: 0.025,
            },
            rotor_inertia_kg_m2: 3.89e-5,
            transmission_inertia_kg_m2: 0.0,
            viscous_damping_nm_s_per_rad: 6.7446e-6,
            motor: DcMotor {
                torque_constant_nm_per_a: 0.055,
                back_emf_v_s_per_rad: 0.0554,
                resistance_ohm: 1.1,
                inductance_h: 2.3e-3,
            },
            amplifier_gain: 4.0,
            amplifier_mode: Default::default(),
            supply_voltage_v: 24.0,
            peak_torque_nm: 1.2,
            backlash: 0.0,
            transmission_stiffness_n_per_m: None,
            transmission_damping_n_s_per_m: None,
            transmission_stiffness_nm_per_rad: None,
            transmission_damping_nm_s_per_rad: None,
            guide: None,
            feedback: Default::default(),
            encoder_counts_per_rev: None,
            sign: 1,
            home: 0.0,
        }
    }

    #[test]
    fn dc_motor_current_follows_the_armature_equation() {
        // Stalled rotor, 1 V command → 4 V armature: i(t) = (4/1.1)(1 − e^(−t R/L)).
        let mut a = Actuator::new(ActuatorKind::DcMotor, &drive());
        let dt = 1e-4;
        let mut t = 0.0;
        for _ in 0..50 {
            a.step(1.0, 0.0, dt);
            t += dt;
        }
        let expected = 4.0 / 1.1 * (1.0 - (-t * 1.1 / 2.3e-3).exp());
        assert!(
            (a.current - expected).abs() < 1e-12 * expected.max(1.0),
            "{} vs {expected}",
            a.current
        );
    }

    #[test]
    fn dc_motor_saturates_at_the_supply_and_feels_back_emf() {
        let mut a = Actuator::new(ActuatorKind::DcMotor, &drive());
        let out = a.step(100.0, 0.0, 1e-3);
        assert_eq!(out.voltage, 24.0);
        // At the no-load speed V/K_b the steady current is zero.
        let omega = 24.0 / 0.0554;
        let mut b = Actuator::new(ActuatorKind::DcMotor, &drive());
        for _ in 0..1000 {
            b.step(100.0, omega, 1e-3);
        }
        assert!(b.current.abs() < 1e-9);
    }

    #[test]
    fn current_mode_cancels_back_emf_within_the_supply() {
        let mut d = drive();
        d.amplifier_mode = crate::machine::AmplifierMode::Current;
        // Running at 300 rad/s (K_b·ω = 16.6 V): the current still settles at K_a·u/R.
        let mut a = Actuator::new(ActuatorKind::DcMotor, &d);
        let omega = 300.0;
        let mut out = ActuatorOutput::default();
        for _ in 0..1000 {
            out = a.step(1.0, omega, 1e-3);
        }
        assert!((a.current - 4.0 / 1.1).abs() < 1e-9, "{}", a.current);
        assert!((out.voltage - (4.0 + 0.0554 * omega)).abs() < 1e-12);
        // Beyond the supply the back-EMF wins again: at 24 V and 400 rad/s (22.16 V of
        // back-EMF) only (24 − 22.16)/R flows.
        let mut b = Actuator::new(ActuatorKind::DcMotor, &d);
        for _ in 0..1000 {
            out = b.step(5.0, 400.0, 1e-3);
        }
        assert_eq!(out.voltage, 24.0);
        assert!((b.current - (24.0 - 0.0554 * 400.0) / 1.1).abs() < 1e-9);
    }

    #[test]
    fn ideal_actuator_clamps_to_peak_torque() {
        let mut a = Actuator::new(ActuatorKind::IdealTorque, &drive());
        assert_eq!(a.step(5.0, 0.0, 1e-3).torque, 1.2);
        assert_eq!(a.step(-0.5, 0.0, 1e-3).torque, -0.5);
    }
}
