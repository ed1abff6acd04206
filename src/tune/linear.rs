//! The ultimate gain and period of a linear axis under sampled P control, derived from its
//! equations rather than found by simulation: an independent check of the search.
//!
//! The axis at the joint (m or rad; m = J·k² + moved mass, c = C·k² + joint damping,
//! k = motor rad per joint unit):
//!
//! ```text
//!   q̇ = v
//!   m·v̇ = k·K_m·i − c·v                  (DC motor)    or  m·v̇ = k·u − c·v  (ideal torque)
//!   L·di/dt = K_a·u − R·i − K_b·k·v
//! ```
//!
//! i.e. G_p(s) = K_a·K_m·(1/k) / (L·J·s³ + (L·C + R·J)·s² + (R·C + K_b·K_m)·s) with J, C on the
//! motor side. The controller samples q at the start of each servo period T and holds
//! u = K·(r − q) over it (zero-order hold), so the loop is exactly the discrete system
//! x⁺ = (Φ − K·Γ·C)·x with Φ = e^(AT), Γ = ∫₀ᵀ e^(Aτ)dτ·B. The ultimate gain is where its
//! spectral radius crosses 1 (found by bisection); the angle θ of the critical eigenvalue gives
//! the period 2πT/θ.

use crate::control::ActuatorKind;
use crate::machine::Drive;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

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

/// A linear axis at the joint side (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LinearAxis {
    /// Total inertia at the joint, J·k² + moved mass (kg or kg·m²).
    pub mass: f64,
    /// Viscous damping at the joint (N·s/m or N·m·s/rad).
    pub damping: f64,
    /// Motor radians per joint unit.
    pub ratio: f64,
    /// How the controller output drives the axis.
    pub actuator: LinearActuator,
}

/// Ultimate gain (controller output per joint unit of error) and period (s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct UltimateCycle {
    /// Ultimate gain K_cr (controller output per joint unit of error).
    pub gain: f64,
    /// Ultimate period P_cr (s).
    pub period: f64,
}

impl LinearAxis {
    /// State-space (A, B) with state [q, v] or [q, v, i] and input u.
    fn state_space(&self) -> (DMatrix<f64>, DVector<f64>) {
        let (m, c, k) = (self.mass, self.damping, self.ratio);
        match self.actuator {
            LinearActuator::IdealTorque => (
                DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 0.0, -c / m]),
                DVector::from_column_slice(&[0.0, k / m]),
            ),
            LinearActuator::DcMotor {
                amplifier_gain: ka,
                torque_constant: km,
                back_emf_constant: kb,
                resistance: r,
                inductance: l,
            } => (
                DMatrix::from_row_slice(
                    3,
                    3,
                    &[
                        0.0,
                        1.0,
                        0.0,
                        0.0,
                        -c / m,
                        k * km / m,
                        0.0,
                        -kb * k / l,
                        -r / l,
                    ],
                ),
                DVector::from_column_slice(&[0.0, 0.0, ka / l]),
            ),
        }
    }

    /// (Φ, Γ) of the zero-order-hold discretisation at period `t`, from one matrix exponential
    /// of the augmented matrix [[A, B], [0, 0]]·t.
    pub(crate) fn discretise(&self, t: f64) -> (DMatrix<f64>, DVector<f64>) {
        let (a, b) = self.state_space();
        let n = a.nrows();
        let mut m = DMatrix::zeros(n + 1, n + 1);
        m.view_mut((0, 0), (n, n)).copy_from(&(a * t));
        m.view_mut((0, n), (n, 1)).copy_from(&(b * t));
        let e = m.exp();
        (
            e.view((0, 0), (n, n)).into_owned(),
            e.view((0, n), (n, 1)).column(0).into_owned(),
        )
    }

    /// Eigenvalue of largest modulus of the closed loop under P gain `gain` at period `t`.
    fn dominant_eigenvalue(phi: &DMatrix<f64>, gamma: &DVector<f64>, gain: f64) -> (f64, f64) {
        let mut closed = phi.clone();
        // u = K·(r − q): subtract K·Γ times the first state (position).
        for row in 0..closed.nrows() {
            closed[(row, 0)] -= gain * gamma[row];
        }
        closed
            .complex_eigenvalues()
            .iter()
            .map(|l| (l.norm(), l.arg().abs()))
            .fold((0.0, 0.0), |best, e| if e.0 > best.0 { e } else { best })
    }

    /// The ultimate gain and period of the sampled loop at servo period `t`, to a relative
    /// tolerance of 1e-9 on the gain. `None` when the loop stays stable up to 1e12 times the
    /// first gain tried (no crossing) or never is stable.
    pub fn discrete_ultimate(&self, t: f64) -> Option<UltimateCycle> {
        let (phi, gamma) = self.discretise(t);
        let radius = |g: f64| Self::dominant_eigenvalue(&phi, &gamma, g).0;
        // Start far below any crossing: at K → 0 the integrator's eigenvalue sits at 1 and
        // moves inside, so the first stable gain is tiny, not zero.
        let mut lo = self.continuous_ultimate_gain().unwrap_or(1.0) * 1e-6;
        if radius(lo) >= 1.0 {
            return None;
        }
        let mut hi = lo;
        for _ in 0..80 {
            hi *= 2.0;
            if radius(hi) > 1.0 {
                break;
            }
            lo = hi;
        }
        if radius(hi) <= 1.0 {
            return None;
        }
        while hi / lo - 1.0 > 1e-9 {
            let mid = (lo * hi).sqrt();
            if radius(mid) > 1.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let gain = (lo * hi).sqrt();
        let (_, angle) = Self::dominant_eigenvalue(&phi, &gamma, gain);
        Some(UltimateCycle {
            gain,
            period: std::f64::consts::TAU * t / angle,
        })
    }

    /// The continuous-time ultimate gain (T → 0) from Routh–Hurwitz on the cubic
    /// characteristic polynomial: K_cr = (L·C + R·J)(R·C + K_b·K_m) / (L·J·K_a·K_m/k), in
    /// joint-side terms. `None` for the ideal torque actuator (a double integrator with damping
    /// is stable at any continuous gain).
    pub fn continuous_ultimate_gain(&self) -> Option<f64> {
        let m = self.motor_side()?;
        Some(
            (m.l * m.c + m.r * m.j) * (m.r * m.c + m.kb * m.km)
                / (m.l * m.j * m.ka * m.km / self.ratio),
        )
    }

    /// Period of the continuous-time ultimate cycle: 2π/ω with ω² = (R·C + K_b·K_m)/(L·J).
    pub fn continuous_ultimate_period(&self) -> Option<f64> {
        let m = self.motor_side()?;
        Some(std::f64::consts::TAU / ((m.r * m.c + m.kb * m.km) / (m.l * m.j)).sqrt())
    }

    /// The DC-motor constants with J and C moved to the motor side; `None` for ideal torque.
    fn motor_side(&self) -> Option<MotorSide> {
        let LinearActuator::DcMotor {
            amplifier_gain: ka,
            torque_constant: km,
            back_emf_constant: kb,
            resistance: r,
            inductance: l,
        } = self.actuator
        else {
            return None;
        };
        let k2 = self.ratio * self.ratio;
        Some(MotorSide {
            ka,
            km,
            kb,
            r,
            l,
            j: self.mass / k2,
            c: self.damping / k2,
        })
    }
}

/// Motor-side constants of a DC-motor axis (SI).
struct MotorSide {
    ka: f64,
    km: f64,
    kb: f64,
    r: f64,
    l: f64,
    j: f64,
    c: f64,
}

/// The X axis of the XYZ table (docs/sources.md §2.1), 20 kg moved: the tests' fixture.
#[cfg(test)]
pub(crate) fn xyz_table_x_axis() -> LinearAxis {
    let k = 100.0 / 0.025;
    LinearAxis {
        mass: 3.89e-5 * k * k + 20.0,
        damping: 6.7446e-6 * k * k,
        ratio: k,
        actuator: LinearActuator::DcMotor {
            amplifier_gain: 4.0,
            torque_constant: 0.055,
            back_emf_constant: 0.0554,
            resistance: 1.1,
            inductance: 2.3e-3,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn x_axis() -> LinearAxis {
        xyz_table_x_axis()
    }

    #[test]
    fn fast_sampling_approaches_the_continuous_ultimate_cycle() {
        let axis = x_axis();
        let kc = axis.continuous_ultimate_gain().unwrap();
        let pc = axis.continuous_ultimate_period().unwrap();
        let fine = axis.discrete_ultimate(1e-6).unwrap();
        assert!((fine.gain / kc - 1.0).abs() < 2e-3, "{fine:?} vs {kc}");
        assert!((fine.period / pc - 1.0).abs() < 2e-3, "{fine:?} vs {pc}");
        // Sampling adds phase lag (half a period of hold): the sampled loop goes unstable at a
        // lower gain, and lower still at a slower servo.
        let ms1 = axis.discrete_ultimate(1e-3).unwrap();
        let ms4 = axis.discrete_ultimate(4e-3).unwrap();
        assert!(
            ms4.gain < ms1.gain && ms1.gain < fine.gain,
            "{ms4:?} {ms1:?} {fine:?}"
        );
        assert!(ms4.period > ms1.period && ms1.period > fine.period);
    }

    #[test]
    fn ideal_torque_double_integrator_matches_its_closed_form() {
        // m·q̈ = k·u without damping: Φ = [[1, T], [0, 1]], Γ = (k/m)·[T²/2, T]; under
        // u = −K·q the closed loop has determinant 1 + K·k·T²/(2m) > 1, so it is unstable at
        // every gain and there is no crossing to find.
        let axis = LinearAxis {
            mass: 2.0,
            damping: 0.0,
            ratio: 1.0,
            actuator: LinearActuator::IdealTorque,
        };
        assert!(axis.discrete_ultimate(1e-3).is_none());
        let damped = LinearAxis {
            damping: 40.0,
            ..axis
        };
        let u = damped.discrete_ultimate(1e-3).unwrap();
        let (phi, gamma) = damped.discretise(1e-3);
        let r = |g: f64| LinearAxis::dominant_eigenvalue(&phi, &gamma, g).0;
        assert!(r(u.gain * 0.999) < 1.0 && r(u.gain * 1.001) > 1.0);
        // Continuous m·s² + c·s + K·k is stable at any gain; only the hold's lag makes a
        // crossing, at a period of some servo periods.
        assert!(u.period > 2.0 * 1e-3 && u.period < 1.0, "{u:?}");
    }
}
