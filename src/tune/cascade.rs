//! Tuning the cascade the way servo drives are commissioned: the velocity loop first, by the
//! bandwidth its phase budget allows, then the position loop at a quarter of it.
//!
//! The velocity loop's plant, from the linear model of the axis (inductance as a first-order
//! current lag, see [`LinearAxis`]): m·v̇ = b·u − c'·v, where b is the joint force per unit of
//! command (k·K_m·K_a/R for the DC motor, k for the ideal torque actuator) and c' the viscous
//! damping plus, in voltage mode, the back-EMF's k²·K_m·K_b/R. The PI velocity controller
//! Kpv + Kiv/s puts the crossover at ω_v (|b·Kpv/(j·m·ω_v + c')| = 1) with its integral zero at
//! ω_v/4. The largest ω_v is the one that keeps a phase margin of [`PHASE_MARGIN_DEG`] after
//! every lag in the loop: the plant's own, the servo period (a zero-order hold, T/2, and the
//! backward-difference velocity estimate, T/2), the current's L/R, the velocity filter and the
//! PI zero. The position loop is P with Kpp = ω_v/4 (its bandwidth a quarter of the velocity
//! loop's, so the two do not fight), with full velocity and acceleration feed-forward.
//!
//! A compliant drive train (a [`TwoMass`]) or command filters make the open loop's shape more
//! than a phase budget: the resonance lifts the gain where the phase has long passed −180°.
//! Then the crossover is the largest at which the whole frequency response of the open loop,
//! evaluated on a dense grid, keeps one gain crossover, [`PHASE_MARGIN_DEG`] of phase margin
//! and [`GAIN_MARGIN_DB`] of gain margin, and lies below the drive train's antiresonance (so
//! below its first resonance) unless a notch takes the resonance out.

use super::{LinearActuator, LinearAxis};
use crate::control::{CascadeAxis, TorqueFilters};
use nalgebra::Complex;
use serde::Serialize;
use std::f64::consts::PI;

/// Phase margin the velocity loop is designed for (degrees).
pub const PHASE_MARGIN_DEG: f64 = 50.0;
/// Gain margin the velocity loop keeps on a compliant drive train (dB).
pub const GAIN_MARGIN_DB: f64 = 6.0;

/// A compliant drive train: the drive side (reflected rotor and transmission inertia, with the
/// axis's viscous damping) joined to the rest of the axis's inertia through a spring and a
/// damper, at the joint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TwoMass {
    /// Inertia of the drive side at the joint (kg or kg·m²).
    pub drive_mass: f64,
    /// Stiffness of the spring at the joint (N/m or N·m/rad).
    pub stiffness: f64,
    /// Damping in parallel with the spring, at the joint (N·s/m or N·m·s/rad).
    pub damping: f64,
}

impl TwoMass {
    /// Resonance (drive and load against each other) and, seen from the motor, antiresonance
    /// (the load alone on the spring), Hz, for a total inertia `mass`.
    pub fn modes_hz(&self, mass: f64) -> (f64, f64) {
        let load = mass - self.drive_mass;
        let k = self.stiffness;
        (
            (k * (1.0 / self.drive_mass + 1.0 / load)).sqrt() / (2.0 * PI),
            (k / load).sqrt() / (2.0 * PI),
        )
    }
}

/// What lies in the velocity loop besides the plant's rigid inertia.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LoopShape {
    /// The velocity estimate's first-order low-pass (Hz; 0: none).
    pub velocity_filter_hz: f64,
    /// Low-pass and notch on the command.
    pub torque_filters: TorqueFilters,
    /// `None`: a rigid drive train.
    pub drive_train: Option<TwoMass>,
}

/// A cascade design for one axis, with the figures it was derived from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CascadeDesign {
    /// Velocity-loop crossover (Hz) and the phase margin there (degrees).
    pub velocity_bandwidth_hz: f64,
    /// Phase margin at the velocity-loop crossover (degrees).
    pub phase_margin_deg: f64,
    /// Position-loop bandwidth (Hz): Kpp/2π.
    pub position_bandwidth_hz: f64,
    /// Gain margin of the velocity loop (dB; infinite when the phase never reaches −180°)
    /// and the phase margin and gain margin figures' frequencies (Hz).
    pub gain_margin_db: f64,
    /// The drive train's resonance and antiresonance (Hz), when it is compliant.
    pub resonance_hz: Option<f64>,
    /// The drive train's antiresonance seen from the motor (Hz), when it is compliant.
    pub antiresonance_hz: Option<f64>,
    /// Velocity-loop plant: joint force per command unit, mass, effective damping.
    pub force_per_command: f64,
    /// Inertia of the velocity loop's plant at the joint (kg or kg·m²).
    pub mass: f64,
    /// Effective viscous damping c' of that plant (N·s/m or N·m·s/rad; back-EMF included in
    /// voltage mode).
    pub damping: f64,
    /// The gains as the cascade controller takes them: PI velocity loop, P position loop, full
    /// feed-forward, no limits, the shape's command filters.
    #[serde(skip)]
    pub axis: CascadeAxis,
}

/// Force per command unit and effective damping of the velocity loop's plant, and the current
/// lag (s).
fn velocity_plant(axis: &LinearAxis) -> (f64, f64, f64) {
    match axis.actuator {
        LinearActuator::IdealTorque => (axis.ratio, axis.damping, 0.0),
        LinearActuator::DcMotor {
            amplifier_gain,
            torque_constant,
            back_emf_constant,
            resistance,
            inductance,
        } => {
            let k = axis.ratio;
            (
                k * torque_constant * amplifier_gain / resistance,
                axis.damping + k * k * torque_constant * back_emf_constant / resistance,
                inductance / resistance,
            )
        }
    }
}

/// Phase of the velocity loop's open loop at ω (rad), PI zero at ω/4 included.
fn open_loop_phase(omega: f64, m: f64, c: f64, period: f64, lag: f64, filter: f64) -> f64 {
    let filter_lag = if filter > 0.0 {
        (omega / (2.0 * PI * filter)).atan()
    } else {
        0.0
    };
    -(m * omega).atan2(c) - omega * period - (omega * lag).atan() - filter_lag - (0.25f64).atan()
}

/// The cascade of `axis` at servo period `period` with what `shape` puts in the velocity loop.
/// `bandwidth_hz` imposes the velocity-loop crossover; by default it is the largest with
/// [`PHASE_MARGIN_DEG`] of margin (and, on a compliant drive train or with command filters,
/// [`GAIN_MARGIN_DB`] as well).
pub fn design_cascade(
    axis: &LinearAxis,
    period: f64,
    shape: &LoopShape,
    bandwidth_hz: Option<f64>,
) -> Result<CascadeDesign, String> {
    let (b, c, lag) = velocity_plant(axis);
    let m = axis.mass;
    if !(b > 0.0 && m > 0.0 && period > 0.0) {
        return Err(
            "the axis has no drive gain or no inertia to design a velocity loop for".into(),
        );
    }
    if let Some(t) = shape.drive_train {
        if !(t.drive_mass > 0.0 && t.drive_mass < m && t.stiffness > 0.0) {
            return Err("a compliant drive train needs inertia on both sides of its spring".into());
        }
    }
    let velocity_filter_hz = shape.velocity_filter_hz;
    let open_loop = OpenLoop {
        b,
        c,
        m,
        lag,
        period,
        shape: *shape,
    };
    let shaped = shape.drive_train.is_some() || !shape.torque_filters.is_empty();
    let phase = |w: f64| open_loop_phase(w, m, c, period, lag, velocity_filter_hz);
    let target = -(PI - PHASE_MARGIN_DEG.to_radians());
    let omega = match bandwidth_hz {
        Some(f) => {
            if !(f > 0.0 && f < 0.5 / period) {
                return Err(format!(
                    "velocity bandwidth {f} Hz: expected a value above 0 and below the Nyquist frequency {} Hz",
                    0.5 / period
                ));
            }
            2.0 * PI * f
        }
        None if shaped => open_loop.largest_crossover()?,
        None => {
            // The phase falls monotonically with ω: bisect for the target between 0 and Nyquist.
            let (mut lo, mut hi) = (1e-6, PI / period);
            if phase(hi) > target {
                hi
            } else {
                for _ in 0..200 {
                    let mid = (lo * hi).sqrt();
                    if phase(mid) > target {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                lo
            }
        }
    };
    // The rigid plant's crossover is |b·Kpv/(j·m·ω + c')| = 1; a shaped loop's is |L| = 1.
    let velocity_kp = if shaped {
        1.0 / open_loop.at(1.0, omega / 4.0, omega).norm()
    } else {
        (m * m * omega * omega + c * c).sqrt() / b
    };
    let velocity_ki = velocity_kp * omega / 4.0;
    let position_kp = omega / 4.0;
    let margins = open_loop.margins(velocity_kp, omega / 4.0);
    let (resonance_hz, antiresonance_hz) = match shape.drive_train {
        Some(t) => {
            let (r, a) = t.modes_hz(m);
            (Some(r), Some(a))
        }
        None => (None, None),
    };
    Ok(CascadeDesign {
        velocity_bandwidth_hz: omega / (2.0 * PI),
        phase_margin_deg: if shaped {
            margins.phase_margin_deg
        } else {
            (PI + phase(omega)).to_degrees()
        },
        gain_margin_db: margins.gain_margin_db,
        resonance_hz,
        antiresonance_hz,
        position_bandwidth_hz: position_kp / (2.0 * PI),
        force_per_command: b,
        mass: m,
        damping: c,
        axis: CascadeAxis {
            position_kp,
            position_ki: 0.0,
            velocity_kp,
            velocity_ki,
            velocity_ff: 1.0,
            acceleration_ff: 1.0,
            velocity_limit: f64::INFINITY,
            output_limit: f64::INFINITY,
            filters: shape.torque_filters,
        },
    })
}

/// The velocity loop's open loop L(jω) = PI · filters · e^(−jωT) · current lag · b · v/F.
struct OpenLoop {
    b: f64,
    c: f64,
    m: f64,
    lag: f64,
    period: f64,
    shape: LoopShape,
}

/// Phase and gain margin of an open loop, and whether it crosses 0 dB once.
struct Margins {
    phase_margin_deg: f64,
    gain_margin_db: f64,
    crossovers: usize,
}

/// Points per decade of the grid the margins are read on.
const GRID_PER_DECADE: f64 = 400.0;

impl OpenLoop {
    /// L(jω) for PI gain `kp` with its integral zero at `zero` rad/s.
    fn at(&self, kp: f64, zero: f64, omega: f64) -> Complex<f64> {
        let s = Complex::new(0.0, omega);
        let one = Complex::new(1.0, 0.0);
        let pi = kp * (one + zero / s);
        let velocity_filter = if self.shape.velocity_filter_hz > 0.0 {
            one / (one + s / (2.0 * PI * self.shape.velocity_filter_hz))
        } else {
            one
        };
        // Zero-order hold (T/2) and the backward-difference velocity estimate (T/2).
        let delay = Complex::from_polar(1.0, -omega * self.period);
        let current = one / (one + s * self.lag);
        // Motor velocity per joint force.
        let velocity = match self.shape.drive_train {
            None => one / (s * self.m + self.c),
            Some(t) => {
                let (md, mc, k, ct) = (t.drive_mass, self.m - t.drive_mass, t.stiffness, t.damping);
                let load = s * s * mc + s * ct + k;
                let coupling = s * ct + k;
                let det = (s * s * md + s * (self.c + ct) + k) * load - coupling * coupling;
                s * load / det
            }
        };
        pi * velocity_filter
            * self.shape.torque_filters.response(omega, self.period)
            * delay
            * current
            * self.b
            * velocity
    }

    /// The grid of frequencies (rad/s) from 0.01 Hz to the Nyquist frequency.
    fn grid(&self) -> Vec<f64> {
        let (lo, hi) = (2.0 * PI * 0.01, PI / self.period);
        let n = ((hi / lo).log10() * GRID_PER_DECADE).ceil() as usize;
        (0..=n)
            .map(|i| lo * (hi / lo).powf(i as f64 / n as f64))
            .collect()
    }

    fn margins(&self, kp: f64, zero: f64) -> Margins {
        let grid = self.grid();
        let values: Vec<Complex<f64>> = grid.iter().map(|&w| self.at(kp, zero, w)).collect();
        // Unwrapped phase along the grid, in degrees.
        let mut phase = Vec::with_capacity(values.len());
        let mut previous: f64 = values[0].arg().to_degrees();
        for v in &values {
            let mut p = v.arg().to_degrees();
            while p - previous > 180.0 {
                p -= 360.0;
            }
            while p - previous < -180.0 {
                p += 360.0;
            }
            phase.push(p);
            previous = p;
        }
        let mut crossovers = 0;
        let mut phase_margin_deg = f64::INFINITY;
        let mut gain_margin_db = f64::INFINITY;
        for i in 1..grid.len() {
            let (g0, g1) = (values[i - 1].norm().log10(), values[i].norm().log10());
            if (g0 >= 0.0) != (g1 >= 0.0) {
                crossovers += 1;
                let f = g0 / (g0 - g1);
                let p = phase[i - 1] + f * (phase[i] - phase[i - 1]);
                // The margin to the nearest odd multiple of −180°, negative past it.
                let margin = (p + 180.0).rem_euclid(360.0);
                let margin = if margin > 180.0 {
                    margin - 360.0
                } else {
                    margin
                };
                phase_margin_deg = phase_margin_deg.min(margin);
            }
            // Phase crossings of −180° (mod 360°).
            let (k0, k1) = (
                ((phase[i - 1] + 180.0) / 360.0).floor(),
                ((phase[i] + 180.0) / 360.0).floor(),
            );
            if k0 != k1 {
                let edge = k0.max(k1) * 360.0 - 180.0;
                let f = (edge - phase[i - 1]) / (phase[i] - phase[i - 1]);
                let g = g0 + f * (g1 - g0);
                gain_margin_db = gain_margin_db.min(-20.0 * g);
            }
        }
        Margins {
            phase_margin_deg,
            gain_margin_db,
            crossovers,
        }
    }

    /// Whether the loop with its crossover at ω meets both margins with one crossover.
    fn meets_margins(&self, omega: f64) -> bool {
        let zero = omega / 4.0;
        let kp = 1.0 / self.at(1.0, zero, omega).norm();
        let m = self.margins(kp, zero);
        m.crossovers == 1
            && m.phase_margin_deg >= PHASE_MARGIN_DEG
            && m.gain_margin_db >= GAIN_MARGIN_DB
    }

    /// The largest crossover that meets the margins: scanned on a grid, then bisected.
    fn largest_crossover(&self) -> Result<f64, String> {
        // Without a notch the loop stays below the antiresonance: above it the motor moves
        // while the load rings on the spring, a mode the motor-side loop can neither see nor
        // damp (its pole and zero nearly cancel where the drive side is the heavier).
        let mut hi = 0.9 * PI / self.period;
        if let (Some(t), None) = (self.shape.drive_train, self.shape.torque_filters.notch) {
            hi = hi.min(2.0 * PI * t.modes_hz(self.m).1);
        }
        let lo = 2.0 * PI * 0.1;
        let n = 200;
        let candidates: Vec<f64> = (0..=n)
            .map(|i| lo * (hi / lo).powf(i as f64 / n as f64))
            .collect();
        let Some(best) = candidates.iter().rposition(|&w| self.meets_margins(w)) else {
            let modes = match self.shape.drive_train {
                Some(t) => format!(
                    " (the drive train resonates at {:.1} Hz: a notch there, or a low-pass below it, lets the loop through)",
                    t.modes_hz(self.m).0
                ),
                None => String::new(),
            };
            return Err(format!(
                "no velocity-loop crossover above 0.1 Hz keeps {PHASE_MARGIN_DEG}° of phase margin and {GAIN_MARGIN_DB} dB of gain margin{modes}"
            ));
        };
        let (mut good, mut bad) = (candidates[best], *candidates.get(best + 1).unwrap_or(&hi));
        if best == n {
            return Ok(good);
        }
        for _ in 0..40 {
            let mid = (good * bad).sqrt();
            if self.meets_margins(mid) {
                good = mid;
            } else {
                bad = mid;
            }
        }
        Ok(good)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tune::linear::xyz_table_x_axis;

    #[test]
    fn the_design_meets_its_phase_margin_and_crossover() {
        let axis = xyz_table_x_axis();
        let d = design_cascade(&axis, 1e-3, &LoopShape::default(), None).unwrap();
        assert!(
            (d.phase_margin_deg - PHASE_MARGIN_DEG).abs() < 1e-6,
            "{d:?}"
        );
        // |b·Kpv/(j·m·ω + c')| = 1 at the crossover.
        let w = 2.0 * PI * d.velocity_bandwidth_hz;
        let gain = d.force_per_command * d.axis.velocity_kp
            / (d.mass * d.mass * w * w + d.damping * d.damping).sqrt();
        assert!((gain - 1.0).abs() < 1e-12);
        // A slower servo period allows less bandwidth (the current's L/R = 2.1 ms lags too).
        let slow = design_cascade(&axis, 4e-3, &LoopShape::default(), None).unwrap();
        assert!(
            slow.velocity_bandwidth_hz < 0.7 * d.velocity_bandwidth_hz,
            "{} vs {} Hz",
            slow.velocity_bandwidth_hz,
            d.velocity_bandwidth_hz
        );
        assert!(design_cascade(&axis, 1e-3, &LoopShape::default(), Some(600.0)).is_err());
        // The rigid loop's margins, read off its frequency response: the design's phase
        // margin, and a gain margin from the delays.
        assert!(d.gain_margin_db > GAIN_MARGIN_DB, "{d:?}");
    }

    /// The X axis with its drive side joined to its 20 kg carriage by a spring of stiffness k.
    fn compliant(k: f64) -> (LinearAxis, LoopShape) {
        let axis = xyz_table_x_axis();
        let shape = LoopShape {
            drive_train: Some(TwoMass {
                drive_mass: axis.mass - 20.0,
                stiffness: k,
                damping: 20.0,
            }),
            ..LoopShape::default()
        };
        (axis, shape)
    }

    #[test]
    fn on_a_compliant_drive_train_the_crossover_stays_below_the_resonance() {
        // A belt of 2·10⁵ N/m: a 16 Hz mode, lightly damped (ζ ≈ 0.5 %).
        let (axis, shape) = compliant(2.0e5);
        let rigid = design_cascade(&axis, 1e-3, &LoopShape::default(), None).unwrap();
        let d = design_cascade(&axis, 1e-3, &shape, None).unwrap();
        let resonance = d.resonance_hz.unwrap();
        assert!((resonance - 16.5).abs() < 0.5, "{resonance}");
        assert!(d.velocity_bandwidth_hz < resonance, "{d:?}");
        assert!(
            d.velocity_bandwidth_hz < rigid.velocity_bandwidth_hz,
            "{d:?}"
        );
        assert!(d.phase_margin_deg >= PHASE_MARGIN_DEG - 1e-6, "{d:?}");
        assert!(d.gain_margin_db >= GAIN_MARGIN_DB - 1e-6, "{d:?}");
        // A notch on the resonance lets the loop through to a higher crossover.
        let notched = LoopShape {
            torque_filters: TorqueFilters {
                lowpass_hz: None,
                notch: Some(crate::control::Notch {
                    hz: resonance,
                    width_hz: 0.5 * resonance,
                    depth: 0.0,
                }),
            },
            ..shape
        };
        let n = design_cascade(&axis, 1e-3, &notched, None).unwrap();
        assert!(
            n.velocity_bandwidth_hz > d.velocity_bandwidth_hz,
            "{n:?} vs {d:?}"
        );
        // A stiff screw, its mode far above the loop: the rigid design's crossover.
        let (axis, stiff) = compliant(1.0e10);
        let s = design_cascade(&axis, 1e-3, &stiff, None).unwrap();
        assert!(
            (s.velocity_bandwidth_hz / rigid.velocity_bandwidth_hz - 1.0).abs() < 0.05,
            "{s:?} vs {rigid:?}"
        );
    }
}
