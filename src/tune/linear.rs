//! The ultimate gain and period of an axis under P control, derived from its linear model
//! ([`AxisPlant`], the one `bode` and `tune --cascade` use) rather than found by simulation:
//! an independent check of the search.
//!
//! The controller samples the feedback device's position y at the start of each servo period T
//! and holds u = K·(r − y) over it (zero-order hold), so the loop is exactly the discrete
//! system x⁺ = (Φ − K·Γ·c)·x with Φ = e^(AT), Γ = ∫₀ᵀ e^(Aτ)dτ·B and c the feedback row. The
//! ultimate gain is where its spectral radius crosses 1 (found by bisection); the angle θ of
//! the dominant eigenvalue gives the period 2πT/θ. The continuous loop (T → 0) is read off the
//! plant's frequency response: where its phase crosses −180°, K_cr = 1/|P(jω)|.

use crate::frequency::AxisPlant;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use std::f64::consts::TAU;

/// Ultimate gain (controller output per joint unit of error) and period (s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct UltimateCycle {
    /// Ultimate gain K_cr (controller output per joint unit of error).
    pub gain: f64,
    /// Ultimate period P_cr (s).
    pub period: f64,
}

/// The closed loop's matrix under P gain `gain`: `system − gain·input·feedback`.
fn closed_loop(
    system: &DMatrix<f64>,
    input: &DVector<f64>,
    feedback: &[f64],
    gain: f64,
) -> DMatrix<f64> {
    let mut closed = system.clone();
    for row in 0..closed.nrows() {
        for (col, c) in feedback.iter().enumerate() {
            closed[(row, col)] -= gain * input[row] * c;
        }
    }
    closed
}

/// A gain far below any crossing: the one that would put a rigid axis's undamped P loop at
/// 0.01 Hz (the loop's integrator eigenvalue starts on the stability boundary at K = 0 and moves
/// inside, so the first stable gain is tiny, not zero).
fn first_gain(plant: &AxisPlant) -> f64 {
    plant.command_per_force() * plant.total_mass() * (TAU * 0.01).powi(2)
}

/// Brackets and bisects the gain at which `unstable` turns true, to a relative width of 1e-9.
/// `None` when the loop is unstable at the first gain or stays stable up to 2⁸⁰ times it.
fn bisect_ultimate(first: f64, unstable: impl Fn(f64) -> bool) -> Option<f64> {
    let mut lo = first;
    if unstable(lo) {
        return None;
    }
    let mut hi = lo;
    for _ in 0..80 {
        hi *= 2.0;
        if unstable(hi) {
            break;
        }
        lo = hi;
    }
    if !unstable(hi) {
        return None;
    }
    Some(geometric_bisection(lo, hi, 1e-9, |g| !unstable(g)))
}

/// The point where `low` turns false between `lo` (true) and `hi` (false), bisected at
/// geometric midpoints to a relative width `tolerance`.
fn geometric_bisection(mut lo: f64, mut hi: f64, tolerance: f64, low: impl Fn(f64) -> bool) -> f64 {
    while hi / lo - 1.0 > tolerance {
        let mid = (lo * hi).sqrt();
        if low(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (lo * hi).sqrt()
}

/// The eigenvalue of `m` of largest modulus: the one that decides a sampled loop's stability.
fn dominant(m: &DMatrix<f64>) -> nalgebra::Complex<f64> {
    m.complex_eigenvalues()
        .iter()
        .copied()
        .fold(None, |best: Option<nalgebra::Complex<f64>>, l| match best {
            Some(b) if b.norm() >= l.norm() => Some(b),
            _ => Some(l),
        })
        .expect("a plant has states")
}

/// The ultimate gain and period of the P loop sampled at servo period `t`. `None` when the
/// loop has no such boundary (stable at every gain, or never).
pub fn discrete_ultimate(plant: &AxisPlant, t: f64) -> Option<UltimateCycle> {
    let sampled = plant.sampled(t);
    let (phi, gamma) = sampled.discrete();
    let feedback = sampled.feedback_row();
    let radius = |g: f64| dominant(&closed_loop(phi, gamma, &feedback, g));
    let gain = bisect_ultimate(first_gain(plant), |g| radius(g).norm() > 1.0)?;
    Some(UltimateCycle {
        gain,
        period: TAU * t / radius(gain).arg().abs(),
    })
}

/// The ultimate gain and period of the continuous P loop (T → 0): where the plant's phase
/// P(jω) crosses −180°, K_cr = 1/|P(jω)| and P_cr = 2π/ω, the smallest such gain where it
/// crosses more than once (a compliant drive train). Read off the frequency response rather
/// than the eigenvalues of A − K·B·c, whose real parts the armature's stiff current equation
/// leaves uncertain to 10⁻⁴ s⁻¹ near the boundary. `None` where the phase never crosses: a
/// rigid axis under an ideal torque actuator is a damped double integrator, stable at any
/// continuous gain.
pub fn continuous_ultimate(plant: &AxisPlant) -> Option<UltimateCycle> {
    let sampled = plant.sampled(1.0);
    let response = |f: f64| sampled.continuous_at(f).feedback;
    // Phase unwrapped along a log grid from 1 mHz to 1 MHz, 200 points per decade.
    let grid: Vec<f64> = (0..=1800)
        .map(|i| 1e-3 * 10f64.powf(i as f64 / 200.0))
        .collect();
    let mut previous = response(grid[0]).arg();
    let mut best: Option<UltimateCycle> = None;
    for pair in grid.windows(2) {
        let mut phase = response(pair[1]).arg();
        phase -= TAU * ((phase - previous) / TAU).round();
        let turns = |p: f64| ((p + std::f64::consts::PI) / TAU).floor();
        if turns(previous) != turns(phase) {
            // Bisect for the crossing of the odd multiple of π between the two points.
            let edge = turns(previous).max(turns(phase)) * TAU - std::f64::consts::PI;
            let below = |f: f64| {
                let mut p = response(f).arg();
                p -= TAU * ((p - edge) / TAU).round();
                (p < edge) == (previous < edge)
            };
            let f = geometric_bisection(pair[0], pair[1], 1e-12, below);
            let cycle = UltimateCycle {
                gain: 1.0 / response(f).norm(),
                period: 1.0 / f,
            };
            if best.is_none_or(|b| cycle.gain < b.gain) {
                best = Some(cycle);
            }
        }
        previous = phase;
    }
    best
}

/// The X axis of the XYZ table (docs/sources.md §2.1), 20 kg moved: the tests' fixture.
#[cfg(test)]
pub(crate) fn xyz_table_x_axis() -> AxisPlant {
    use crate::frequency::{LinearActuator, Transmission};
    let k = 100.0 / 0.025;
    AxisPlant {
        drive_mass: 3.89e-5 * k * k,
        drive_damping: 6.7446e-6 * k * k,
        carriage_mass: 20.0,
        carriage_damping: 0.0,
        ratio: k,
        transmission: Transmission::RIGID,
        actuator: LinearActuator::DcMotor {
            amplifier_gain: 4.0,
            torque_constant: 0.055,
            back_emf_constant: 0.0554,
            resistance: 1.1,
            inductance: 2.3e-3,
        },
        feedback: crate::machine::Feedback::Motor,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frequency::{LinearActuator, Transmission};

    /// Routh–Hurwitz on the rigid DC-motor axis's cubic characteristic polynomial, written out
    /// here on its own (J, C on the motor side): K_cr = (L·C + R·J)(R·C + K_b·K_m) /
    /// (L·J·K_a·K_m/k), ω² = (R·C + K_b·K_m)/(L·J).
    fn routh_hurwitz(p: &AxisPlant) -> (f64, f64) {
        let LinearActuator::DcMotor {
            amplifier_gain: ka,
            torque_constant: km,
            back_emf_constant: kb,
            resistance: r,
            inductance: l,
        } = p.actuator
        else {
            unreachable!()
        };
        let k = p.ratio;
        let j = p.total_mass() / (k * k);
        let c = (p.drive_damping + p.carriage_damping) / (k * k);
        let gain = (l * c + r * j) * (r * c + kb * km) / (l * j * ka * km / k);
        let period = TAU / ((r * c + kb * km) / (l * j)).sqrt();
        (gain, period)
    }

    #[test]
    fn the_continuous_search_finds_the_routh_hurwitz_cycle() {
        let axis = xyz_table_x_axis();
        let (kc, pc) = routh_hurwitz(&axis);
        let u = continuous_ultimate(&axis).unwrap();
        assert!((u.gain / kc - 1.0).abs() < 1e-6, "{u:?} vs {kc}");
        assert!((u.period / pc - 1.0).abs() < 1e-6, "{u:?} vs {pc}");
    }

    #[test]
    fn fast_sampling_approaches_the_continuous_ultimate_cycle() {
        let axis = xyz_table_x_axis();
        let (kc, pc) = routh_hurwitz(&axis);
        let fine = discrete_ultimate(&axis, 1e-6).unwrap();
        assert!((fine.gain / kc - 1.0).abs() < 2e-3, "{fine:?} vs {kc}");
        assert!((fine.period / pc - 1.0).abs() < 2e-3, "{fine:?} vs {pc}");
        // Sampling adds phase lag (half a period of hold): the sampled loop goes unstable at a
        // lower gain, and lower still at a slower servo.
        let ms1 = discrete_ultimate(&axis, 1e-3).unwrap();
        let ms4 = discrete_ultimate(&axis, 4e-3).unwrap();
        assert!(
            ms4.gain < ms1.gain && ms1.gain < fine.gain,
            "{ms4:?} {ms1:?} {fine:?}"
        );
        assert!(ms4.period > ms1.period && ms1.period > fine.period);
    }

    fn ideal(damping: f64) -> AxisPlant {
        AxisPlant {
            drive_mass: 0.5,
            drive_damping: damping,
            carriage_mass: 1.5,
            carriage_damping: 0.0,
            ratio: 1.0,
            transmission: Transmission::RIGID,
            actuator: LinearActuator::IdealTorque,
            feedback: crate::machine::Feedback::Motor,
        }
    }

    #[test]
    fn ideal_torque_double_integrator_matches_its_closed_form() {
        // m·q̈ = k·u without damping: Φ = [[1, T], [0, 1]], Γ = (k/m)·[T²/2, T]; under
        // u = −K·q the closed loop has determinant 1 + K·k·T²/(2m) > 1, so it is unstable at
        // every gain and there is no crossing to find.
        assert!(discrete_ultimate(&ideal(0.0), 1e-3).is_none());
        let damped = ideal(40.0);
        let u = discrete_ultimate(&damped, 1e-3).unwrap();
        let sampled = damped.sampled(1e-3);
        let (phi, gamma) = sampled.discrete();
        let r = |g: f64| dominant(&closed_loop(phi, gamma, &[1.0, 0.0], g)).norm();
        assert!(r(u.gain * 0.999) < 1.0 && r(u.gain * 1.001) > 1.0);
        // Continuous m·s² + c·s + K·k is stable at any gain; only the hold's lag makes a
        // crossing, at a period of some servo periods.
        assert!(u.period > 2.0 * 1e-3 && u.period < 1.0, "{u:?}");
        assert!(continuous_ultimate(&damped).is_none());
    }

    #[test]
    fn a_compliant_transmission_lowers_the_ultimate_gain_to_its_mode() {
        // The table's X axis with a belt: with the feedback on the carriage the P loop meets the
        // belt's mode long before the current's lag; the continuous loop then oscillates near
        // the two-mass resonance.
        let rigid = xyz_table_x_axis();
        let belt = AxisPlant {
            transmission: Transmission {
                stiffness: 2.0e5,
                damping: 20.0,
            },
            feedback: crate::machine::Feedback::Carriage,
            ..rigid
        };
        let (resonance, _) = belt.modes_hz().unwrap();
        let r = discrete_ultimate(&rigid, 1e-4).unwrap();
        let b = discrete_ultimate(&belt, 1e-4).unwrap();
        assert!(b.gain < r.gain, "{b:?} vs {r:?}");
        let f = 1.0 / continuous_ultimate(&belt).unwrap().period;
        assert!(
            f < resonance * 1.2 && f > resonance * 0.5,
            "{f} Hz vs {resonance} Hz"
        );
    }
}
