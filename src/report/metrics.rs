//! Accuracy and cost figures of a run.

use super::AxisLabel;
use crate::program::PathGeometry;
use crate::sim::Trace;
use nalgebra::{Point3, Vector3};
use serde::Serialize;
use std::collections::BTreeMap;

/// Per-tick quantities derived from the trace and the programmed path.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Derived {
    /// Distance of the actual tool point from the programmed path (m).
    pub contour_error: Vec<f64>,
    /// Commanded and actual path speed of the tool (m/s).
    pub commanded_speed: Vec<f64>,
    pub actual_speed: Vec<f64>,
}

impl Derived {
    /// `program_origin` is the tool point (machine frame) at program zero; `linear_axes` the
    /// machine-axis index of program X, Y, Z where the machine has them.
    pub fn compute(
        trace: &Trace,
        path: &PathGeometry,
        program_origin: &Point3<f64>,
        linear_axes: [Option<usize>; 3],
    ) -> Derived {
        let n = trace.len();
        let mut d = Derived {
            contour_error: Vec::with_capacity(n),
            commanded_speed: Vec::with_capacity(n),
            actual_speed: Vec::with_capacity(n),
        };
        for k in 0..n {
            let tool = Point3::from(trace.tool_point[k]) - program_origin.coords;
            let near = path
                .segment_of_move
                .get(trace.segment[k] as usize)
                .copied()
                .unwrap_or(0);
            d.contour_error.push(path.distance_near(&tool, near, 2));
            let mut v = Vector3::zeros();
            for (c, axis) in linear_axes.iter().enumerate() {
                if let Some(i) = axis {
                    v[c] = Trace::at(&trace.commanded_velocity, trace.axes, k, *i);
                }
            }
            d.commanded_speed.push(v.norm());
            d.actual_speed
                .push(Vector3::from(trace.tool_velocity[k]).norm());
        }
        d
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisMetrics {
    /// Linear axes: mm; rotary axes: the `_deg` fields instead.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_following_error_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms_following_error_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_following_error_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms_following_error_deg: Option<f64>,
    /// Time of the largest following error (s).
    pub max_following_error_time_s: f64,
    /// Largest difference between the physics and the analytic reference model (when run).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_physics_vs_analytic_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_physics_vs_analytic_deg: Option<f64>,
    pub peak_torque_nm: f64,
    pub rms_torque_nm: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_voltage_v: Option<f64>,
    /// Stick-slip: how often the axis stalled again after it had got going, while its setpoint
    /// kept moving (see `stick_slip_stalls`).
    pub stick_slip_stalls: usize,
}

/// Below this fraction of the axis's peak commanded speed the setpoint is slowing through a
/// reversal (or starting, or stopping): whatever the axis does there is not stick-slip.
const STALL_COMMAND_FLOOR: f64 = 0.2;
/// The axis is moving above this fraction of its peak commanded speed ...
const STALL_MOVING: f64 = 0.2;
/// ... and has stalled below this one.
const STALL_STOPPED: f64 = 0.02;

/// How often axis `axis` stalled (speed below 2 % of its peak commanded speed) after it had got
/// going (above 20 %), while its commanded speed stayed above 20 % of that peak: stick-slip
/// hunting. An axis that stands at a reversal while the drive takes up the backlash, or at the
/// start while friction holds it, is not counted: there the command itself is slow.
pub fn stick_slip_stalls(trace: &Trace, axis: usize) -> usize {
    let at = |v: &[f64], k: usize| Trace::at(v, trace.axes, k, axis).abs();
    let peak = (0..trace.len())
        .map(|k| at(&trace.commanded_velocity, k))
        .fold(0.0, f64::max);
    if peak <= 0.0 || trace.actual_velocity.len() < trace.commanded_velocity.len() {
        return 0;
    }
    let (mut moving, mut stalls) = (false, 0);
    for k in 0..trace.len() {
        let actual = at(&trace.actual_velocity, k);
        if at(&trace.commanded_velocity, k) <= STALL_COMMAND_FLOOR * peak {
            moving = false;
        } else if actual > STALL_MOVING * peak {
            moving = true;
        } else if moving && actual < STALL_STOPPED * peak {
            stalls += 1;
            moving = false;
        }
    }
    stalls
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metrics {
    pub scenario: String,
    /// True when the run reached the end of its setpoints.
    pub completed: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stopped: Option<String>,
    pub max_contour_error_mm: f64,
    pub rms_contour_error_mm: f64,
    pub max_path_speed_error_mm_s: f64,
    pub sim_time_s: f64,
    pub wall_time_s: f64,
    pub real_time_factor: f64,
    pub physics_steps: u64,
    pub servo_ticks: usize,
    pub axes: BTreeMap<String, AxisMetrics>,
}

impl Metrics {
    #[allow(clippy::too_many_arguments)]
    pub fn compute(
        scenario: &str,
        trace: &Trace,
        derived: &Derived,
        labels: &[AxisLabel],
        dc_motor: bool,
        physics_steps: u64,
        wall_time: f64,
        stopped: Option<String>,
    ) -> Metrics {
        let n = trace.len();
        let max = |v: &mut dyn Iterator<Item = f64>| {
            v.fold(0.0f64, |m, x| if x.is_nan() { f64::NAN } else { m.max(x) })
        };
        let rms = |v: &mut dyn Iterator<Item = f64>| {
            if n == 0 {
                0.0
            } else {
                (v.map(|x| x * x).sum::<f64>() / n as f64).sqrt()
            }
        };
        let mut axes = BTreeMap::new();
        for (i, label) in labels.iter().enumerate() {
            let err = |k: usize| {
                (Trace::at(&trace.commanded, trace.axes, k, i)
                    - Trace::at(&trace.actual, trace.axes, k, i))
                .abs()
            };
            let (mut worst, mut worst_k) = (0.0f64, 0usize);
            for k in 0..n {
                if err(k) > worst || err(k).is_nan() {
                    worst = err(k);
                    worst_k = k;
                }
            }
            let rms_err = rms(&mut (0..n).map(err));
            let torque = |k: usize| Trace::at(&trace.torque, trace.axes, k, i);
            let s = label.scale();
            let (mm, deg) = if label.rotary {
                (None, Some((worst * s, rms_err * s)))
            } else {
                (Some((worst * s, rms_err * s)), None)
            };
            axes.insert(
                label.name.clone(),
                AxisMetrics {
                    max_following_error_mm: mm.map(|v| v.0),
                    rms_following_error_mm: mm.map(|v| v.1),
                    max_following_error_deg: deg.map(|v| v.0),
                    rms_following_error_deg: deg.map(|v| v.1),
                    max_following_error_time_s: trace.time.get(worst_k).copied().unwrap_or(0.0),
                    max_physics_vs_analytic_mm: None,
                    max_physics_vs_analytic_deg: None,
                    peak_torque_nm: max(&mut (0..n).map(|k| torque(k).abs())),
                    rms_torque_nm: rms(&mut (0..n).map(torque)),
                    peak_voltage_v: dc_motor.then(|| {
                        max(&mut (0..n).map(|k| Trace::at(&trace.voltage, trace.axes, k, i).abs()))
                    }),
                    stick_slip_stalls: stick_slip_stalls(trace, i),
                },
            );
        }
        let sim_time = n as f64 * trace.period;
        Metrics {
            scenario: scenario.to_string(),
            completed: stopped.is_none(),
            stopped,
            max_contour_error_mm: max(&mut derived.contour_error.iter().copied()) * 1e3,
            rms_contour_error_mm: rms(&mut derived.contour_error.iter().copied()) * 1e3,
            max_path_speed_error_mm_s: max(&mut derived
                .commanded_speed
                .iter()
                .zip(&derived.actual_speed)
                .map(|(c, a)| (c - a).abs()))
                * 1e3,
            sim_time_s: sim_time,
            wall_time_s: wall_time,
            real_time_factor: if wall_time > 0.0 {
                sim_time / wall_time
            } else {
                f64::INFINITY
            },
            physics_steps,
            servo_ticks: n,
            axes,
        }
    }

    /// Records, per axis, the largest |physics − analytic| position difference; `analytic`
    /// holds the reference model's positions in the trace's layout.
    pub fn add_analytic_comparison(
        &mut self,
        trace: &Trace,
        analytic: &[f64],
        labels: &[AxisLabel],
    ) {
        for (i, label) in labels.iter().enumerate() {
            let worst = (0..trace.len().min(analytic.len() / trace.axes.max(1)))
                .map(|k| {
                    (Trace::at(&trace.actual, trace.axes, k, i) - analytic[k * trace.axes + i])
                        .abs()
                })
                .fold(0.0f64, f64::max)
                * label.scale();
            if let Some(m) = self.axes.get_mut(&label.name) {
                if label.rotary {
                    m.max_physics_vs_analytic_deg = Some(worst);
                } else {
                    m.max_physics_vs_analytic_mm = Some(worst);
                }
            }
        }
    }

    /// The metrics as JSON (what `metrics.json` holds and `[expect]` bounds refer to).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("metrics are plain numbers and strings")
    }

    /// Looks up a metric by its dotted path, e.g. `axes.x.max_following_error_mm`.
    pub fn lookup(json: &serde_json::Value, path: &str) -> Option<f64> {
        path.split('.')
            .try_fold(json, |v, key| v.get(key))?
            .as_f64()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-axis trace at 10 ms with the given commanded and actual velocities (m/s).
    fn trace(commanded: &[f64], actual: &[f64]) -> Trace {
        Trace {
            period: 0.01,
            axes: 1,
            time: (0..commanded.len()).map(|k| k as f64 * 0.01).collect(),
            commanded_velocity: commanded.to_vec(),
            actual_velocity: actual.to_vec(),
            ..Default::default()
        }
    }

    #[test]
    fn stalls_while_the_command_moves_are_counted() {
        let commanded = vec![5e-3; 60];
        let mut actual = vec![5e-3; 60];
        // Held at the start (not counted: it never got going), then stuck twice on the way.
        for k in (0..10).chain(20..25).chain(40..42) {
            actual[k] = 0.0;
        }
        assert_eq!(stick_slip_stalls(&trace(&commanded, &actual), 0), 2);
    }

    #[test]
    fn standing_at_a_reversal_is_not_a_stall() {
        // Command through zero as on a circle; the axis stands still on both sides of the
        // reversal while the backlash is taken up, until the command is back above 25 % speed.
        let commanded: Vec<f64> = (0..200)
            .map(|k| 5e-3 * (std::f64::consts::PI * k as f64 / 100.0).cos())
            .collect();
        let actual: Vec<f64> = commanded
            .iter()
            .enumerate()
            .map(|(k, &v)| if (45..60).contains(&k) { 0.0 } else { v })
            .collect();
        assert!(commanded[59].abs() > 0.25 * 5e-3);
        assert_eq!(stick_slip_stalls(&trace(&commanded, &actual), 0), 0);
    }

    #[test]
    fn an_axis_that_never_moves_has_no_stalls() {
        assert_eq!(stick_slip_stalls(&trace(&[0.0; 10], &[0.0; 10]), 0), 0);
        assert_eq!(stick_slip_stalls(&trace(&[], &[]), 0), 0);
    }
}
