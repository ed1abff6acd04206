//! The seed trapezoidal velocity profile (docs/sources.md §1.5), exactly as the source documents
//! give it: constant acceleration `A` from rest to `V`, cruise at `V`, constant deceleration to
//! rest; a triangle without cruise when the move is too short to reach `V` (`|L| < V²/A`).
//! The acceleration jumps at the phase boundaries (unlimited jerk): that is the seed's
//! behaviour, which the jerk-limited planner ([`super::planner`]) improves on.

use super::setpoints::{sample_times, Setpoints};
use super::stream::{collect, Stretch, StretchStream};

/// A trapezoidal (or triangular) rest-to-rest profile over a signed distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrapezoidProfile {
    /// Signed distance L.
    pub distance: f64,
    /// Acceleration used in phases 1 and 3 (A, > 0).
    pub acceleration: f64,
    /// Velocity reached (V, or sqrt(|L|·A) in the triangular case), unsigned.
    pub peak_velocity: f64,
    /// Δt1: acceleration phase (s).
    pub accel_time: f64,
    /// Δt2: cruise phase (s); zero in the triangular case.
    pub cruise_time: f64,
    /// Δt3 = Δt1: deceleration phase (s).
    pub decel_time: f64,
}

impl TrapezoidProfile {
    /// Profile over the signed `distance` with cruise velocity `velocity` and acceleration
    /// `acceleration` (both > 0).
    pub fn new(distance: f64, velocity: f64, acceleration: f64) -> Self {
        let length = distance.abs();
        let (peak_velocity, accel_time, cruise_time) =
            if length < velocity * velocity / acceleration {
                // Triangle: Δt1 = Δt3 = sqrt(L/A), Δs1 = Δs3 = L/2, no cruise.
                let t1 = (length / acceleration).sqrt();
                (acceleration * t1, t1, 0.0)
            } else {
                // Trapezoid: Δt1 = V/A, Δs1 = Δs3 = V²/2A, Δs2 = L − Δs1 − Δs3, Δt2 = Δs2/V.
                let t1 = velocity / acceleration;
                let ramp_distance = velocity * velocity / (2.0 * acceleration);
                (velocity, t1, (length - 2.0 * ramp_distance) / velocity)
            };
        TrapezoidProfile {
            distance,
            acceleration,
            peak_velocity,
            accel_time,
            cruise_time,
            decel_time: accel_time,
        }
    }

    /// True when the move is too short to reach the cruise velocity.
    pub fn is_triangular(&self) -> bool {
        self.cruise_time == 0.0
    }

    /// Total duration Δt1 + Δt2 + Δt3 (s).
    pub fn duration(&self) -> f64 {
        self.accel_time + self.cruise_time + self.decel_time
    }

    /// Distance covered in each phase (Δs1, Δs2, Δs3), unsigned.
    pub fn phase_distances(&self) -> [f64; 3] {
        let ramp = 0.5 * self.acceleration * self.accel_time * self.accel_time;
        [ramp, self.distance.abs() - 2.0 * ramp, ramp]
    }

    /// Position, velocity and acceleration at time `t` (clamped: the target after the end).
    pub fn state(&self, t: f64) -> (f64, f64, f64) {
        let sign = self.distance.signum();
        let (a, v) = (self.acceleration, self.peak_velocity);
        let (t1, t2, total) = (
            self.accel_time,
            self.accel_time + self.cruise_time,
            self.duration(),
        );
        let (p, v, acc) = if t <= 0.0 {
            (0.0, 0.0, 0.0)
        } else if t < t1 {
            (0.5 * a * t * t, a * t, a)
        } else if t < t2 {
            (0.5 * a * t1 * t1 + v * (t - t1), v, 0.0)
        } else if t < total {
            // Measured back from the end, so that the last phase lands on the target.
            let r = total - t;
            (self.distance.abs() - 0.5 * a * r * r, a * r, -a)
        } else {
            return (self.distance, 0.0, 0.0);
        };
        (sign * p, sign * v, sign * acc)
    }

    /// Positions sampled every `period` from 0, the last sample exactly on the target (the
    /// final tick is the first one at or after the end of the profile).
    pub fn sample_positions(&self, period: f64) -> Vec<f64> {
        sample_times(self.duration(), period)
            .map(|t| self.state(t).0)
            .collect()
    }
}

/// A multi-axis straight move with the trapezoidal profile along the line: path speed `speed`
/// and path acceleration `acceleration` measured as the Euclidean norm over all axes (SI), every
/// axis scaled by its share of the move so that all start and finish together.
pub fn trapezoid_line(
    start: &[f64],
    end: &[f64],
    speed: f64,
    acceleration: f64,
    period: f64,
    segment: u32,
) -> Setpoints {
    assert_eq!(start.len(), end.len(), "start and end need the same axes");
    let length = start
        .iter()
        .zip(end)
        .map(|(s, e)| (e - s) * (e - s))
        .sum::<f64>()
        .sqrt();
    let profile = TrapezoidProfile::new(length, speed, acceleration);
    let ticks = sample_times(profile.duration(), period).count() - 1;
    let stretches = vec![
        Stretch::Start {
            at: start.to_vec(),
            segment,
        },
        Stretch::Trapezoid {
            from: start.to_vec(),
            to: end.to_vec(),
            profile,
            segment,
            ticks,
        },
    ];
    collect(&mut StretchStream::new(start.len(), period, stretches))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_times_end_at_or_after_the_end() {
        assert_eq!(sample_times(1.0, 0.25).count(), 5);
        assert_eq!(sample_times(1.1, 0.25).count(), 6);
        assert_eq!(sample_times(0.0, 0.25).count(), 1);
        // 2.5 s at 4 ms is 625 ticks even though 2.5/0.004 rounds above 625.
        assert_eq!(sample_times(2.5, 0.004).count(), 626);
    }
}
