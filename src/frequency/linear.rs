//! The one linear model of a servo axis, from the drive data alone (not from any measurement):
//! the plant sampled with the loop's zero-order hold, the controller as the discrete law it
//! runs, and the loops they make. `bode` lays it over the measured response, `tune` takes the
//! ultimate cycle of its P loop ([`crate::tune::linear`]) and `tune --cascade` designs the
//! cascade on its velocity loop ([`crate::tune::cascade`]); python-control builds the same
//! loops in the tests (`tests/oracles/bode_oracle.py`).
//!
//! # The plant (joint units: m, N, kg, or rad, N·m, kg·m²)
//!
//! ```text
//!   amplifier + motor  L·di/dt = K_a·u − R·i − K_b'·k·v_d,   F = k·K_m·i     (K_b' = 0 in current mode)
//!   ideal torque       F = k·u
//!   drive side         m_d·a_d = F − c_d·v_d − λ                m_d = J·k², c_d = C·k²
//!   carriage           m_c·a_c = λ − c_c·v_c                     c_c: the joint's own damping
//!   transmission       λ = k_t·(x_d − x_c) + c_t·(v_d − v_c)     (compliant), or x_d ≡ x_c (rigid)
//! ```
//!
//! so that, from the drive force F, the drive side (motor encoder) and the carriage move as
//!
//! ```text
//!   x_d/F = (m_c·s² + (c_t + c_c)·s + k_t) / Δ,    x_c/F = (c_t·s + k_t) / Δ,
//!   Δ = (m_d·s² + (c_d + c_t)·s + k_t)·(m_c·s² + (c_c + c_t)·s + k_t) − (c_t·s + k_t)²,
//! ```
//!
//! with the resonance near √(k_t·(1/m_d + 1/m_c)) and the motor side's antiresonance near
//! √(k_t/m_c); the rigid axis is the limit k_t → ∞, one body of mass m_d + m_c. Gravity and
//! Coulomb friction are constant or switching forces, not part of the linearisation.
//!
//! # The sampled loop
//!
//! The servo loop samples the sensors at t = kT, computes the command at once and holds it over
//! [kT, (k+1)T): a zero-order hold with no further computation delay (`sim::run`). The plant
//! between command samples and position samples is therefore exactly the ZOH discretisation
//! x⁺ = Φ·x + Γ·u (Φ = e^{AT}, Γ = ∫₀ᵀ e^{Aτ}dτ·B), P(z) = C·(zI − Φ)⁻¹·Γ at z = e^{jωT}; the
//! hold's phase lag (about ωT/2) is in it. The controllers are their difference equations:
//!
//! ```text
//!   PID        C(z) = K_p + K_i·T·z/(z − 1) + K_d·(1 − z⁻¹)/T,  feed-forward FF0 + FF1·jω − FF2·ω²
//!   cascade    v_cmd = (K_pp + K_ip·T·z/(z − 1))·(r − x_fb) + kvff·ṙ
//!              v̂ = α/(1 − (1 − α)·z⁻¹) · (1 − z⁻¹)/T · x_motor        (α = 1 without filter)
//!              u = F(z)·[(K_pv + K_iv·T·z/(z − 1))·(v_cmd − v̂) + kaff·(m_d + m_c)/k·g_u·r̈]
//! ```
//!
//! (g_u: command per motor torque, R/(K_m·K_a) for the DC motor, 1 for ideal torque; F the
//! command filters' biquads, `control::filters`). Written
//! as u = R(ω)·r − B_fb(z)·x_fb − B_m(z)·x_motor, the loop broken at the plant input is
//! L = B_fb·P_fb + B_m·P_m, and the closed loop from the setpoint is x_fb/r = P_fb·R/(1 + L).

use crate::control::ActuatorKind;
use crate::dynamics::AxisDynamics;
use crate::machine::{Drive, Feedback, Machine};
use nalgebra::{Complex, DMatrix, DVector, Vector3};
use serde::Serialize;
use std::f64::consts::TAU;

/// How the controller output drives the axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum LinearActuator {
    /// Output in volts at the amplifier input.
    DcMotor {
        /// Amplifier gain K_a (V per volt of controller output).
        amplifier_gain: f64,
        /// Torque constant K_m (N·m/A).
        torque_constant: f64,
        /// Back-EMF constant K_b the loop sees (V·s/rad; 0 for a current-mode amplifier).
        back_emf_constant: f64,
        /// Armature resistance R (Ω).
        resistance: f64,
        /// Armature inductance L (H).
        inductance: f64,
    },
    /// Output is the motor torque (N·m).
    IdealTorque,
}

impl LinearActuator {
    /// The actuator `kind` of `drive`: for the DC motor its amplifier and motor constants, with
    /// the back-EMF the amplifier mode lets the loop see.
    pub fn of_drive(drive: &Drive, kind: ActuatorKind) -> LinearActuator {
        match kind {
            ActuatorKind::IdealTorque => LinearActuator::IdealTorque,
            ActuatorKind::DcMotor => LinearActuator::DcMotor {
                amplifier_gain: drive.amplifier_gain,
                torque_constant: drive.motor.torque_constant_nm_per_a,
                back_emf_constant: drive.effective_back_emf(),
                resistance: drive.motor.resistance_ohm,
                inductance: drive.motor.inductance_h,
            },
        }
    }
}

/// Complex numbers of the frequency responses.
pub type C64 = Complex<f64>;

/// The transmission between drive side and carriage: rigid, or a spring and damper.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Transmission {
    /// k_t (N/m or N·m/rad at the joint); `f64::INFINITY` for a rigid transmission.
    pub stiffness: f64,
    /// c_t (N·s/m or N·m·s/rad at the joint).
    pub damping: f64,
}

impl Transmission {
    /// A rigid transmission (k_t → ∞).
    pub const RIGID: Transmission = Transmission {
        stiffness: f64::INFINITY,
        damping: 0.0,
    };

    /// Whether drive side and carriage move as one body.
    pub fn is_rigid(&self) -> bool {
        self.stiffness.is_infinite()
    }
}

/// One axis's linear plant at the joint (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AxisPlant {
    /// m_d = J·k² (kg or kg·m²).
    pub drive_mass: f64,
    /// c_d = C·k².
    pub drive_damping: f64,
    /// m_c, the moved mass.
    pub carriage_mass: f64,
    /// c_c, the joint's own damping.
    pub carriage_damping: f64,
    /// Motor radians per joint unit.
    pub ratio: f64,
    /// Between drive side and carriage: rigid, or a spring and damper.
    pub transmission: Transmission,
    /// The actuator the command drives: DC motor behind its amplifier, or ideal torque.
    pub actuator: LinearActuator,
    /// Where the position loop's feedback is measured.
    pub feedback: Feedback,
}

impl AxisPlant {
    /// The plant of `drive` moving `moved_mass` with the joint's damping, driven through the
    /// `actuator`.
    pub fn from_drive(
        drive: &Drive,
        moved_mass: f64,
        joint_damping: f64,
        transmission: Transmission,
        actuator: ActuatorKind,
    ) -> AxisPlant {
        AxisPlant {
            drive_mass: drive.reflected_inertia(),
            drive_damping: drive.reflected_damping(),
            carriage_mass: moved_mass,
            carriage_damping: joint_damping,
            ratio: drive.ratio(),
            transmission,
            actuator: LinearActuator::of_drive(drive, actuator),
            feedback: drive.feedback,
        }
    }

    /// The plant of axis `axis` of `machine` at joint position `q` (one value per axis): the
    /// rigid-body model's inertia of the axis there (armature, followers and every link it
    /// carries), of which the drive side is the drive's reflected inertia and the rest the
    /// carriage; the drive's reflected damping and the joint's own; the drive's transmission
    /// (compliant where the drive file gives a stiffness). Friction and backlash are not
    /// linear and not in it.
    pub fn of_axis(
        machine: &Machine,
        axis: usize,
        q: &[f64],
        actuator: ActuatorKind,
    ) -> Result<AxisPlant, String> {
        let mut model = AxisDynamics::of_machine(machine, Vector3::zeros())
            .map_err(|e| format!("the machine's rigid-body model: {e}"))?;
        let n = model.dof();
        let mut ws = model.workspace();
        let mut mass = DMatrix::zeros(n, n);
        model.mass_matrix(&mut ws, q, &mut mass);
        let a = &machine.axes[axis];
        let drive = &a.drive;
        let transmission = drive
            .compliance()
            .map_or(Transmission::RIGID, |c| Transmission {
                stiffness: c.stiffness,
                damping: c.damping,
            });
        let plant = AxisPlant::from_drive(
            drive,
            mass[(axis, axis)] - drive.reflected_inertia(),
            machine.joints[a.joint].damping,
            transmission,
            actuator,
        );
        if !(plant.carriage_mass > 0.0 && plant.drive_mass >= 0.0) {
            return Err(format!(
                "axis {}: the rigid-body model gives it {} kg (or kg·m²) beyond its drive's reflected {}: a linear model needs inertia the drive moves",
                a.name, plant.carriage_mass, plant.drive_mass
            ));
        }
        if !plant.transmission.is_rigid() && plant.drive_mass <= 0.0 {
            return Err(format!(
                "axis {}: a compliant transmission needs inertia on the drive side of its spring (the drive's rotor inertia is 0)",
                a.name
            ));
        }
        Ok(plant)
    }

    /// Joint force per unit of command at standstill, k·K_m·K_a/R or k.
    pub fn force_per_command(&self) -> f64 {
        1.0 / self.command_per_force()
    }

    /// The viscous damping the axis shows at low frequency (N·s/m or N·m·s/rad): the drive's
    /// and the joint's, plus in voltage mode the back-EMF's k²·K_m·K_b/R.
    pub fn low_frequency_damping(&self) -> f64 {
        let viscous = self.drive_damping + self.carriage_damping;
        match self.actuator {
            LinearActuator::DcMotor {
                torque_constant,
                back_emf_constant,
                resistance,
                ..
            } => viscous + self.ratio.powi(2) * torque_constant * back_emf_constant / resistance,
            LinearActuator::IdealTorque => viscous,
        }
    }

    /// The compliant transmission's undamped resonance √(k_t·(1/m_d + 1/m_c)) and the motor
    /// side's antiresonance √(k_t/m_c) (Hz); `None` for a rigid one.
    pub fn modes_hz(&self) -> Option<(f64, f64)> {
        let k = self.transmission.stiffness;
        (!self.transmission.is_rigid()).then(|| {
            (
                (k * (1.0 / self.drive_mass + 1.0 / self.carriage_mass)).sqrt() / TAU,
                (k / self.carriage_mass).sqrt() / TAU,
            )
        })
    }

    /// Command per unit of drive force at standstill (V per N, or N·m per N): what a
    /// feed-forward of force F must command, R/(K_m·K_a·k) or 1/k.
    pub fn command_per_force(&self) -> f64 {
        match self.actuator {
            LinearActuator::DcMotor {
                amplifier_gain,
                torque_constant,
                resistance,
                ..
            } => resistance / (torque_constant * amplifier_gain * self.ratio),
            LinearActuator::IdealTorque => 1.0 / self.ratio,
        }
    }

    /// Total mass the motor moves at low frequency, m_d + m_c.
    pub fn total_mass(&self) -> f64 {
        self.drive_mass + self.carriage_mass
    }

    /// Continuous state space (A, B, C): states [x_d, v_d, (x_c, v_c,) (i)], input u, outputs
    /// [x_d, x_c].
    fn state_space(&self) -> (DMatrix<f64>, DVector<f64>, DMatrix<f64>) {
        let rigid = self.transmission.is_rigid();
        let mech = if rigid { 2 } else { 4 };
        let electric = matches!(self.actuator, LinearActuator::DcMotor { .. });
        let n = mech + usize::from(electric);
        let mut a = DMatrix::zeros(n, n);
        let mut b = DVector::zeros(n);
        let mut c = DMatrix::zeros(2, n);
        let k = self.ratio;
        let (md, cd, mc, cc) = (
            self.drive_mass,
            self.drive_damping,
            self.carriage_mass,
            self.carriage_damping,
        );
        // Drive-side force per unit of the force state (current) or per command.
        let (m_drive, c_drive) = if rigid { (md + mc, cd + cc) } else { (md, cd) };
        a[(0, 1)] = 1.0;
        a[(1, 1)] = -c_drive / m_drive;
        if !rigid {
            let (kt, ct) = (self.transmission.stiffness, self.transmission.damping);
            a[(1, 0)] = -kt / md;
            a[(1, 1)] = -(cd + ct) / md;
            a[(1, 2)] = kt / md;
            a[(1, 3)] = ct / md;
            a[(2, 3)] = 1.0;
            a[(3, 0)] = kt / mc;
            a[(3, 1)] = ct / mc;
            a[(3, 2)] = -kt / mc;
            a[(3, 3)] = -(cc + ct) / mc;
        }
        match self.actuator {
            LinearActuator::IdealTorque => b[1] = k / m_drive,
            LinearActuator::DcMotor {
                amplifier_gain,
                torque_constant,
                back_emf_constant,
                resistance,
                inductance,
            } => {
                let i = mech;
                a[(1, i)] = k * torque_constant / m_drive;
                a[(i, 1)] = -back_emf_constant * k / inductance;
                a[(i, i)] = -resistance / inductance;
                b[i] = amplifier_gain / inductance;
            }
        }
        c[(0, 0)] = 1.0;
        c[(1, if rigid { 0 } else { 2 })] = 1.0;
        (a, b, c)
    }

    /// The plant sampled with the zero-order hold at period `t`.
    pub fn sampled(&self, t: f64) -> SampledPlant {
        let (a, b, c) = self.state_space();
        let n = a.nrows();
        let mut m = DMatrix::zeros(n + 1, n + 1);
        m.view_mut((0, 0), (n, n)).copy_from(&(&a * t));
        m.view_mut((0, n), (n, 1)).copy_from(&(&b * t));
        let e = m.exp();
        SampledPlant {
            phi: e.view((0, 0), (n, n)).into_owned(),
            gamma: e.view((0, n), (n, 1)).column(0).into_owned(),
            c,
            a,
            b,
            period: t,
            feedback: self.feedback,
        }
    }
}

/// The two frequency responses of the plant at one frequency (joint units per command unit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantResponse {
    /// To the drive side (the motor encoder).
    pub motor: C64,
    /// To the carriage.
    pub carriage: C64,
    /// To the position loop's feedback device (one of the two).
    pub feedback: C64,
}

/// A plant sampled with the zero-order hold (and its continuous form).
#[derive(Debug, Clone, PartialEq)]
pub struct SampledPlant {
    phi: DMatrix<f64>,
    gamma: DVector<f64>,
    c: DMatrix<f64>,
    a: DMatrix<f64>,
    b: DVector<f64>,
    /// Servo period (s).
    pub period: f64,
    feedback: Feedback,
}

impl SampledPlant {
    /// Φ = e^{AT} and Γ of the ZOH discretisation, x⁺ = Φ·x + Γ·u.
    pub fn discrete(&self) -> (&DMatrix<f64>, &DVector<f64>) {
        (&self.phi, &self.gamma)
    }

    /// The output row of the position loop's feedback device, y = c·x.
    pub fn feedback_row(&self) -> Vec<f64> {
        let row = match self.feedback {
            Feedback::Motor => 0,
            Feedback::Carriage => 1,
        };
        self.c.row(row).iter().copied().collect()
    }

    fn solve(&self, m: &DMatrix<f64>, v: &DVector<f64>, s: C64) -> PlantResponse {
        let n = m.nrows();
        let mut lhs = DMatrix::<C64>::zeros(n, n);
        for r in 0..n {
            for col in 0..n {
                lhs[(r, col)] = C64::new(-m[(r, col)], 0.0);
            }
            lhs[(r, r)] += s;
        }
        let rhs = v.map(|x| C64::new(x, 0.0));
        let x = lhs
            .lu()
            .solve(&rhs)
            .unwrap_or_else(|| DVector::from_element(n, C64::new(f64::NAN, f64::NAN)));
        let out = |row: usize| (0..n).map(|j| x[j] * self.c[(row, j)]).sum::<C64>();
        let (motor, carriage) = (out(0), out(1));
        PlantResponse {
            motor,
            carriage,
            feedback: match self.feedback {
                Feedback::Motor => motor,
                Feedback::Carriage => carriage,
            },
        }
    }

    /// The sampled plant P(z) = C·(zI − Φ)⁻¹·Γ at z = e^{jωT}, ω = 2πf.
    pub fn at(&self, frequency: f64) -> PlantResponse {
        let z = C64::from_polar(1.0, TAU * frequency * self.period);
        self.solve(&self.phi, &self.gamma, z)
    }

    /// The continuous plant C·(sI − A)⁻¹·B at s = jω (no hold): for comparison only.
    pub fn continuous_at(&self, frequency: f64) -> PlantResponse {
        self.solve(&self.a, &self.b, C64::new(0.0, TAU * frequency))
    }
}

/// The controller of the measured axis as the linear law it runs (limits, deadband and
/// compensation left out: they are not linear).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "kebab-case")]
pub enum LinearController {
    /// PID (positional or incremental: the same law while unclamped) with feed-forward.
    Pid {
        /// Proportional gain (command per m, or per rad on a rotary axis).
        kp: f64,
        /// Integral gain (command per m·s, or per rad·s).
        ki: f64,
        /// Derivative gain (command per m/s, or per rad/s).
        kd: f64,
        /// Feed-forward of the setpoint position (command per m, or per rad).
        ff0: f64,
        /// Feed-forward of the setpoint velocity (command per m/s, or per rad/s).
        ff1: f64,
        /// Feed-forward of the setpoint acceleration (command per m/s², or per rad/s²).
        ff2: f64,
    },
    /// Cascade: PI position loop over a PI velocity loop on the differenced motor encoder.
    Cascade {
        /// K_pp, position loop proportional gain (1/s).
        position_kp: f64,
        /// K_ip, position loop integral gain (1/s²).
        position_ki: f64,
        /// K_pv, velocity loop proportional gain (command per m/s, or per rad/s).
        velocity_kp: f64,
        /// K_iv, velocity loop integral gain (command per m, or per rad).
        velocity_ki: f64,
        /// kvff, share of the setpoint velocity fed into the velocity command (1 = all).
        velocity_ff: f64,
        /// kaff, share of the inertia force for the setpoint acceleration (1 = all).
        acceleration_ff: f64,
        /// Low-pass coefficient α of the velocity estimate (1 = none).
        smoothing: f64,
        /// The command filters (low-pass, notch) after the velocity loop.
        #[serde(skip)]
        filters: crate::control::TorqueFilters,
    },
}

/// Where the excitation enters and what is measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Loop {
    /// Excitation added to the controller output (the plant input); the loop stays closed.
    Plant,
    /// Velocity command of a cascade with its position loop opened; response: motor velocity.
    Velocity,
    /// Position setpoint; response: the feedback device's position.
    Position,
}

/// The loops of one axis at one frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopResponse {
    /// The plant's own responses at this frequency.
    pub plant: PlantResponse,
    /// The loop broken at the plant input, L = B_fb·P_fb + B_m·P_m.
    pub open: C64,
    /// The closed loop from the excitation to the response (for [`Loop::Plant`]: the
    /// complementary sensitivity L/(1 + L) at the plant input).
    pub closed: C64,
    /// Command per unit of excitation, u/e.
    pub command: C64,
    /// Feedback-device (position loops) or motor (velocity loop) displacement per unit of
    /// excitation.
    pub displacement: C64,
}

impl LinearController {
    /// The law as u = R·r − B_fb·x_fb − B_m·x_m at z = e^{jωT}: (R, B_fb, B_m).
    fn terms(&self, lp: Loop, plant: &AxisPlant, frequency: f64, t: f64) -> (C64, C64, C64) {
        let w = TAU * frequency;
        let z = C64::from_polar(1.0, w * t);
        let jw = C64::new(0.0, w);
        let integral = |gain: f64| gain * t * z / (z - 1.0);
        match *self {
            LinearController::Pid {
                kp,
                ki,
                kd,
                ff0,
                ff1,
                ff2,
            } => {
                let c = kp + integral(ki) + kd * (1.0 - 1.0 / z) / t;
                let ff = ff0 + ff1 * jw + ff2 * jw * jw;
                (c + ff, c, C64::new(0.0, 0.0))
            }
            LinearController::Cascade {
                position_kp,
                position_ki,
                velocity_kp,
                velocity_ki,
                velocity_ff,
                acceleration_ff,
                smoothing,
                filters,
            } => {
                // The command filters act on everything the velocity loop puts out.
                let cv = filters.response(w, t) * (velocity_kp + integral(velocity_ki));
                let estimate = smoothing / (1.0 - (1.0 - smoothing) / z) * (1.0 - 1.0 / z) / t;
                if lp == Loop::Velocity {
                    // Position loop opened: the velocity command is the excitation itself.
                    return (cv, C64::new(0.0, 0.0), cv * estimate);
                }
                let cp = position_kp + integral(position_ki);
                let inertia = filters.response(w, t)
                    * acceleration_ff
                    * plant.total_mass()
                    * plant.command_per_force()
                    * jw
                    * jw;
                (
                    cv * (cp + velocity_ff * jw) + inertia,
                    cv * cp,
                    cv * estimate,
                )
            }
        }
    }

    /// The loops of `plant` (sampled at its period) under this law at `frequency` (Hz).
    pub fn response(
        &self,
        lp: Loop,
        plant: &AxisPlant,
        sampled: &SampledPlant,
        frequency: f64,
    ) -> LoopResponse {
        let t = sampled.period;
        let p = sampled.at(frequency);
        let (r, b_fb, b_m) = self.terms(lp, plant, frequency, t);
        let open = b_fb * p.feedback + b_m * p.motor;
        let one = C64::new(1.0, 0.0);
        let jw = C64::new(0.0, TAU * frequency);
        let (closed, command, displacement) = match lp {
            Loop::Plant => (
                open / (one + open),
                one / (one + open),
                p.feedback / (one + open),
            ),
            Loop::Position => {
                let u = r / (one + open);
                (p.feedback * u, u, p.feedback * u)
            }
            Loop::Velocity => {
                let u = r / (one + open);
                (jw * p.motor * u, u, p.motor * u)
            }
        };
        LoopResponse {
            plant: p,
            open,
            closed,
            command,
            displacement,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_mass(kt: f64, ct: f64) -> AxisPlant {
        AxisPlant {
            drive_mass: 2.0,
            drive_damping: 3.0,
            carriage_mass: 5.0,
            carriage_damping: 7.0,
            ratio: 1.0,
            transmission: Transmission {
                stiffness: kt,
                damping: ct,
            },
            actuator: LinearActuator::IdealTorque,
            feedback: Feedback::Motor,
        }
    }

    /// The two-mass formulas of the module documentation, written out here on their own.
    fn formulas(p: &AxisPlant, f: f64) -> (C64, C64) {
        let s = C64::new(0.0, TAU * f);
        let (md, cd, mc, cc) = (
            p.drive_mass,
            p.drive_damping,
            p.carriage_mass,
            p.carriage_damping,
        );
        let (k, c) = (p.transmission.stiffness, p.transmission.damping);
        let delta = (md * s * s + (cd + c) * s + k) * (mc * s * s + (cc + c) * s + k)
            - (c * s + k) * (c * s + k);
        ((mc * s * s + (c + cc) * s + k) / delta, (c * s + k) / delta)
    }

    #[test]
    fn the_state_space_is_the_two_mass_transfer_function() {
        let p = two_mass(4.0e6, 120.0);
        let sampled = p.sampled(1e-3);
        for f in [0.5, 3.0, 40.0, 180.0, 230.0, 900.0] {
            let r = sampled.continuous_at(f);
            let (xd, xc) = formulas(&p, f);
            assert!(
                (r.motor / xd - 1.0).norm() < 1e-9,
                "{f} Hz: {} vs {xd}",
                r.motor
            );
            assert!((r.carriage / xc - 1.0).norm() < 1e-9, "{f} Hz");
        }
    }

    #[test]
    fn undamped_resonance_and_antiresonance_are_where_the_formulas_put_them() {
        let mut p = two_mass(4.0e6, 0.0);
        p.drive_damping = 0.0;
        p.carriage_damping = 0.0;
        let s = p.sampled(1e-4);
        let resonance = (4.0e6_f64 * (1.0 / 2.0 + 1.0 / 5.0)).sqrt() / TAU;
        let antiresonance = (4.0e6_f64 / 5.0).sqrt() / TAU;
        // The motor side's response has a pole at the resonance and a zero at the
        // antiresonance: it blows up at one and vanishes at the other.
        let near = |f: f64| s.continuous_at(f).motor.norm();
        assert!(near(resonance * (1.0 + 1e-9)) > 1e3 * near(resonance * 1.1));
        assert!(near(antiresonance) < 1e-9 * near(antiresonance * 1.1));
        // The carriage has no antiresonance.
        assert!(s.continuous_at(antiresonance).carriage.norm() > 1e-9);
    }

    #[test]
    fn a_stiff_transmission_tends_to_the_rigid_axis() {
        let rigid = two_mass(f64::INFINITY, 0.0).sampled(1e-3);
        let stiff = two_mass(1e13, 1.0).sampled(1e-3);
        for f in [1.0, 20.0, 200.0] {
            let (a, b) = (rigid.at(f), stiff.at(f));
            assert!((a.motor / b.motor - 1.0).norm() < 1e-4, "{f} Hz");
            assert!((a.carriage / b.carriage - 1.0).norm() < 1e-4, "{f} Hz");
        }
    }

    #[test]
    fn the_hold_adds_half_a_period_of_lag() {
        // A rigid mass: P(s) = 1/(m s² + c s); the sampled plant lags it by about ωT/2.
        let p = two_mass(f64::INFINITY, 0.0);
        let t = 1e-3;
        let s = p.sampled(t);
        let f = 20.0;
        let lag = (s.at(f).motor / s.continuous_at(f).motor).arg();
        assert!((lag + TAU * f * t / 2.0).abs() < 2e-3, "{lag}");
    }
}
