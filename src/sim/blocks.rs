//! The small blocks between plant and controller that every lane of the loop shares: the
//! encoder (position quantisation) and the drive's following-error trip with its divergence
//! check.

use super::{Sensors, Stop};

/// Position feedback as a drive reads it: rounded to whole counts where an encoder is
/// modelled.
#[derive(Debug, Clone, PartialEq)]
pub struct Encoder {
    /// Joint units per count, per axis; `None` = ideal feedback.
    pub resolution: Vec<Option<f64>>,
}

impl Encoder {
    /// The measured positions: the sensors' feedback positions, and the motor encoder's (the
    /// drive side), in whole counts.
    pub fn measure(&self, sensors: &Sensors, measured: &mut [f64], motor: &mut [f64]) {
        let count = |p: f64, res: &Option<f64>| match res {
            Some(r) => (p / r).round() * r,
            None => p,
        };
        for (i, res) in self.resolution.iter().enumerate() {
            measured[i] = count(sensors.feedback_position[i], res);
            motor[i] = count(sensors.drive_position[i], res);
        }
    }
}

/// The drive's following-error fault: it trips when |setpoint − position| exceeds the limit,
/// as a real drive does. A state that is no longer finite stops the run as diverged.
#[derive(Debug, Clone, PartialEq)]
pub struct FollowingErrorTrip {
    /// Limit per axis (joint units).
    pub limit: Vec<f64>,
    /// Axis names, for the stop's message.
    pub axis_names: Vec<String>,
}

impl FollowingErrorTrip {
    /// Checks the sampled state against the setpoint at time `time`.
    pub fn check(&self, time: f64, setpoint: &[f64], sensors: &Sensors) -> Result<(), Stop> {
        for (i, name) in self.axis_names.iter().enumerate() {
            let (q, v) = (sensors.position[i], sensors.velocity[i]);
            if !q.is_finite() || !v.is_finite() {
                return Err(Stop::Diverged {
                    time,
                    axis: name.clone(),
                    what: format!("position {q} / velocity {v} is not finite"),
                });
            }
            let error = setpoint[i] - q;
            if error.abs() > self.limit[i] {
                return Err(Stop::FollowingError {
                    time,
                    axis: name.clone(),
                    error: error.abs(),
                    limit: self.limit[i],
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_encoder_rounds_to_whole_counts() {
        let mut s = Sensors::new(2);
        s.feedback_position = vec![1.26e-3, 1.26e-3];
        let encoder = Encoder {
            resolution: vec![Some(0.5e-3), None],
        };
        s.drive_position = vec![0.74e-3, 0.74e-3];
        let (mut m, mut motor) = ([0.0; 2], [0.0; 2]);
        encoder.measure(&s, &mut m, &mut motor);
        assert_eq!(m, [1.5e-3, 1.26e-3]);
        assert_eq!(motor, [0.5e-3, 0.74e-3]);
    }

    #[test]
    fn the_trip_names_the_axis_and_time() {
        let trip = FollowingErrorTrip {
            limit: vec![1e-3],
            axis_names: vec!["x".into()],
        };
        let mut s = Sensors::new(1);
        s.position[0] = 0.5e-3;
        assert!(trip.check(0.0, &[1.0e-3], &s).is_ok());
        let stop = trip.check(2.5, &[2.0e-3], &s).unwrap_err();
        assert!(
            matches!(stop, Stop::FollowingError { time, ref axis, .. } if time == 2.5 && axis == "x")
        );
        s.velocity[0] = f64::NAN;
        assert!(matches!(
            trip.check(3.0, &[0.5e-3], &s),
            Err(Stop::Diverged { .. })
        ));
    }
}
