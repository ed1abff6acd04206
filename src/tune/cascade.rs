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

use super::{LinearActuator, LinearAxis};
use crate::control::CascadeAxis;
use serde::Serialize;
use std::f64::consts::PI;

/// Phase margin the velocity loop is designed for (degrees).
pub const PHASE_MARGIN_DEG: f64 = 50.0;

/// A cascade design for one axis, with the figures it was derived from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CascadeDesign {
    /// Velocity-loop crossover (Hz) and the phase margin there (degrees).
    pub velocity_bandwidth_hz: f64,
    pub phase_margin_deg: f64,
    /// Position-loop bandwidth (Hz): Kpp/2π.
    pub position_bandwidth_hz: f64,
    /// Velocity-loop plant: joint force per command unit, mass, effective damping.
    pub force_per_command: f64,
    pub mass: f64,
    pub damping: f64,
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

/// The cascade of `axis` at servo period `period` with the velocity estimate filtered at
/// `velocity_filter_hz` (0: none). `bandwidth_hz` imposes the velocity-loop crossover; by
/// default it is the largest with [`PHASE_MARGIN_DEG`] of margin.
pub fn design_cascade(
    axis: &LinearAxis,
    period: f64,
    velocity_filter_hz: f64,
    bandwidth_hz: Option<f64>,
) -> Result<CascadeDesign, String> {
    let (b, c, lag) = velocity_plant(axis);
    let m = axis.mass;
    if !(b > 0.0 && m > 0.0 && period > 0.0) {
        return Err(
            "the axis has no drive gain or no inertia to design a velocity loop for".into(),
        );
    }
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
    let velocity_kp = (m * m * omega * omega + c * c).sqrt() / b;
    let velocity_ki = velocity_kp * omega / 4.0;
    let position_kp = omega / 4.0;
    Ok(CascadeDesign {
        velocity_bandwidth_hz: omega / (2.0 * PI),
        phase_margin_deg: (PI + phase(omega)).to_degrees(),
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
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tune::linear::xyz_table_x_axis;

    #[test]
    fn the_design_meets_its_phase_margin_and_crossover() {
        let axis = xyz_table_x_axis();
        let d = design_cascade(&axis, 1e-3, 0.0, None).unwrap();
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
        let slow = design_cascade(&axis, 4e-3, 0.0, None).unwrap();
        assert!(
            slow.velocity_bandwidth_hz < 0.7 * d.velocity_bandwidth_hz,
            "{} vs {} Hz",
            slow.velocity_bandwidth_hz,
            d.velocity_bandwidth_hz
        );
        assert!(design_cascade(&axis, 1e-3, 0.0, Some(600.0)).is_err());
    }
}
