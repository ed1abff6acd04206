//! The classic constant-velocity interpolators of the source documents, exactly as written:
//! straight lines by equal steps ΔS = V·T (docs/sources.md §1.4) and circles by equal chords
//! θ = acos((2r² − ΔS²)/(2r²)) (§1.6). Each sample is computed from the move's start, not by
//! repeated addition, so there is no drift, and every move ends exactly on its target with a
//! shorter last step. Velocity is a step function; acceleration is zero between samples.

use super::Setpoints;
use crate::kinematics::AxisMap;
use crate::program::{
    arc_segment, move_duration, move_length, rotary_travel_degrees, Feed, Motion, Position,
    Program, Segment,
};
use nalgebra::Point3;

#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum PlanError {
    #[error("move {index} (line {line}): feed {feed} gives no positive finite duration")]
    BadFeed { index: usize, line: u32, feed: f64 },
    #[error("move {index} (line {line}): arc radius {radius} m is degenerate")]
    BadArc {
        index: usize,
        line: u32,
        radius: f64,
    },
    #[error("the servo period must be a positive finite number of seconds, got {0}")]
    BadPeriod(f64),
    #[error("move {index} (line {line}): {what} is not supported")]
    Unsupported {
        index: usize,
        line: u32,
        what: &'static str,
    },
    #[error(
        "the stretch of moves from move {first_move} (line {line}) cannot be planned: {message}"
    )]
    Path {
        first_move: usize,
        line: u32,
        message: String,
    },
}

/// A sample of a move: position, and velocity per second (both as program positions).
type Sample = (Position, Position);

/// Samples `program` at period `period` with the constant-velocity interpolators.
/// `rapid_speed` (m/s) is used for rapid moves.
pub fn constant_velocity(
    program: &Program,
    axes: &AxisMap,
    period: f64,
    rapid_speed: f64,
) -> Result<Setpoints, PlanError> {
    if !(period.is_finite() && period > 0.0) {
        return Err(PlanError::BadPeriod(period));
    }
    let n = axes.axes();
    let mut out = Setpoints::new(period, n);
    let mut q = vec![0.0; n];
    let mut qd = vec![0.0; n];
    let zeros = vec![0.0; n];
    let mut at = program.start;
    axes.machine_axes(&at, &mut q);
    // Sample 0 is the start; its velocity is that of the first move.
    let mut pending_start = true;

    for (index, m) in program.moves.iter().enumerate() {
        let seg = index as u32;
        let line = m.span.line;
        // Duration at programmed feed under the move's feed rule; rapids at `rapid_speed`.
        let duration = match m.feed {
            Feed::Rapid if !matches!(m.motion, Motion::Dwell { .. }) => {
                let linear = move_length(&at, m);
                // As the feed rules do: 1 mm of travel ≙ 1° for a purely rotary move.
                let rotary = rotary_travel_degrees(&at, m) * 1e-3;
                Some(if linear > 0.0 { linear } else { rotary } / rapid_speed)
            }
            _ => move_duration(&at, m),
        };
        let duration = match duration {
            Some(d) if d.is_finite() && d >= 0.0 => d,
            _ => {
                let feed = match m.feed {
                    Feed::PathSpeed(v) | Feed::InverseTime(v) => v,
                    Feed::Rapid => rapid_speed,
                };
                return Err(PlanError::BadFeed { index, line, feed });
            }
        };
        let samples: Vec<Sample> = match m.motion {
            Motion::Linear => line_samples(&at, &m.end, duration, period),
            Motion::Arc {
                center,
                plane,
                clockwise,
                turns,
            } => {
                let geometry = arc_segment(
                    Point3::from(at.linear),
                    Point3::from(m.end.linear),
                    Point3::from(center),
                    plane,
                    clockwise,
                    turns,
                );
                let bad_arc = PlanError::BadArc {
                    index,
                    line,
                    radius: (Point3::from(at.linear) - Point3::from(center)).norm(),
                };
                if duration == 0.0 {
                    return Err(bad_arc);
                }
                let speed = move_length(&at, m) / duration;
                arc_samples(&at, &m.end, &geometry, speed, period).ok_or(bad_arc)?
            }
            Motion::Dwell { .. } => {
                let ticks = (duration / period).ceil() as usize;
                vec![(at, Position::default()); ticks]
            }
        };
        if samples.is_empty() {
            continue;
        }
        if pending_start {
            axes.machine_axes(&samples[0].1, &mut qd);
            out.push(&q, &qd, &zeros, seg);
            pending_start = false;
        }
        for (p, v) in &samples {
            axes.machine_axes(p, &mut q);
            axes.machine_axes(v, &mut qd);
            out.push(&q, &qd, &zeros, seg);
        }
        at = m.end;
    }
    if pending_start {
        out.push(&q, &zeros, &zeros, 0);
    } else {
        // Program end: the last setpoint is at rest.
        let k = out.len() - 1;
        out.velocity[k * n..].iter_mut().for_each(|v| *v = 0.0);
    }
    Ok(out)
}

/// Samples 1..=⌈N⌉ of a straight move of the given duration, N = duration/T (= L/(V·T) at
/// path speed V); the last lands exactly on the target. Rotary axes move in proportion.
fn line_samples(from: &Position, to: &Position, duration: f64, period: f64) -> Vec<Sample> {
    if duration == 0.0 || from == to {
        return Vec::new();
    }
    let steps = duration / period;
    let count = steps.ceil() as usize;
    let mut velocity = Position::default();
    for i in 0..3 {
        velocity.linear[i] = (to.linear[i] - from.linear[i]) / duration;
        velocity.rotary[i] = (to.rotary[i] - from.rotary[i]) / duration;
    }
    (1..=count)
        .map(|k| {
            let p = if (k as f64) < steps {
                lerp(from, to, k as f64 / steps)
            } else {
                *to
            };
            (p, velocity)
        })
        .collect()
}

/// Samples of an arc by equal chords ΔS = V·T; the last lands exactly on the target.
fn arc_samples(
    from: &Position,
    to: &Position,
    seg: &Segment,
    speed: f64,
    period: f64,
) -> Option<Vec<Sample>> {
    let Segment::Arc {
        center,
        normal,
        start,
        sweep,
        rise,
    } = *seg
    else {
        return None;
    };
    let r0 = start - center;
    let radius = r0.norm();
    if !(radius > 0.0 && radius.is_finite() && speed > 0.0 && speed.is_finite()) {
        return None;
    }
    let chord = speed * period;
    // θ = acos((2r² − ΔS²)/(2r²)); a chord longer than the diameter is clamped to a half turn.
    let theta = ((2.0 * radius * radius - chord * chord) / (2.0 * radius * radius))
        .clamp(-1.0, 1.0)
        .acos();
    let steps = sweep.abs() / theta;
    let count = steps.ceil() as usize;
    let u = r0 / radius;
    let v = normal.cross(&u);
    let dir = sweep.signum();
    let rate = theta / period; // rad/s along the arc
    let tangent = |a: f64| {
        (v * a.cos() - u * a.sin()) * (dir * radius * rate) + normal * (rise / (steps * period))
    };
    let as_position = |t: nalgebra::Vector3<f64>| Position {
        linear: t.into(),
        rotary: [0.0; 3],
    };
    Some(
        (1..=count)
            .map(|k| {
                if (k as f64) < steps {
                    let a = dir * theta * k as f64;
                    let fraction = k as f64 / steps;
                    let p =
                        center + (u * a.cos() + v * a.sin()) * radius + normal * (rise * fraction);
                    let mut pos = lerp(from, to, fraction);
                    pos.linear = p.into();
                    (pos, as_position(tangent(a)))
                } else {
                    (*to, as_position(tangent(sweep)))
                }
            })
            .collect(),
    )
}

fn lerp(a: &Position, b: &Position, s: f64) -> Position {
    let mut p = *a;
    for i in 0..3 {
        p.linear[i] = a.linear[i] + (b.linear[i] - a.linear[i]) * s;
        p.rotary[i] = a.rotary[i] + (b.rotary[i] - a.rotary[i]) * s;
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::program::{circle, polyline, CircleSpec, PolylineSpec};
    use nalgebra::Vector3;
    use std::path::Path;

    fn xyz() -> AxisMap {
        AxisMap::from_sources(vec![(true, 0), (true, 1), (true, 2)])
    }

    #[test]
    fn seed_line_example_100mm_at_10mm_s_t4ms() {
        // Seed digest §1.1: 100 mm at 10 mm/s with T = 4 ms → 2500 ticks of 0.04 mm.
        let p = polyline(
            &PolylineSpec {
                points: vec![[0.0; 3], [0.1, 0.0, 0.0]],
                speed: 0.01,
            },
            Path::new("t"),
        );
        let sp = constant_velocity(&p, &xyz(), 0.004, 0.1).unwrap();
        assert_eq!(sp.len(), 2501);
        for k in 1..sp.len() {
            let step = sp.position(k)[0] - sp.position(k - 1)[0];
            assert!((step - 0.04e-3).abs() < 1e-15, "tick {k}: step {step}");
        }
        assert_eq!(sp.position(2500)[0], 0.1, "ends exactly on target");
    }

    #[test]
    fn seed_sampling_example_100mm_t20ms() {
        // Seed digest §1.7: 100 mm, T = 0.02 s, V = 10 mm/s → 10 s, 500 samples 0.2 mm apart.
        let p = polyline(
            &PolylineSpec {
                points: vec![[0.0; 3], [0.1, 0.0, 0.0]],
                speed: 0.01,
            },
            Path::new("t"),
        );
        let sp = constant_velocity(&p, &xyz(), 0.02, 0.1).unwrap();
        assert_eq!(sp.len() - 1, 500);
        assert!((sp.duration() - 10.0).abs() < 1e-12);
        assert!((sp.position(1)[0] - 0.2e-3).abs() < 1e-15);
    }

    #[test]
    fn diagonal_line_with_fractional_steps_ends_on_target() {
        let p = polyline(
            &PolylineSpec {
                points: vec![[0.0; 3], [0.03, 0.04, 0.0]],
                speed: 0.007,
            },
            Path::new("t"),
        );
        let sp = constant_velocity(&p, &xyz(), 0.001, 0.1).unwrap();
        // N = 50 mm / 7 µm = 7142.857… → 7143 steps, the last one shorter.
        assert_eq!(sp.len(), 7144);
        assert_eq!(sp.position(7143), &[0.03, 0.04, 0.0]);
        let full = (Vector3::from_column_slice(sp.position(10))
            - Vector3::from_column_slice(sp.position(9)))
        .norm();
        assert!((full - 7e-6).abs() < 1e-15);
    }

    #[test]
    fn equal_chord_circle() {
        let spec = CircleSpec {
            center: [0.1, 0.1],
            radius: 0.03,
            start_angle: 0.0,
            clockwise: false,
            z: 0.0,
            speed: 0.005,
        };
        let p = circle(&spec, Path::new("t"));
        let sp = constant_velocity(&p, &xyz(), 0.001, 0.1).unwrap();
        let chord = |k: usize| {
            (Vector3::from_column_slice(sp.position(k))
                - Vector3::from_column_slice(sp.position(k - 1)))
            .norm()
        };
        // Every full chord is ΔS = V·T (to rounding), every sample on the circle.
        for k in 1..sp.len() - 1 {
            assert!((chord(k) - 5e-6).abs() < 1e-13, "chord {k} = {}", chord(k));
            let r = ((sp.position(k)[0] - 0.1).powi(2) + (sp.position(k)[1] - 0.1).powi(2)).sqrt();
            assert!((r - 0.03).abs() < 1e-15);
        }
        // Circumference / ΔS = 37699.1… chords; ends exactly at the start point.
        let expected = (2.0 * std::f64::consts::PI
            / (1.0 - 5e-6f64.powi(2) / (2.0 * 0.03f64.powi(2))).acos())
        .ceil() as usize;
        assert_eq!(sp.len() - 1, expected);
        assert_eq!(sp.position(sp.len() - 1), &[0.13, 0.1, 0.0]);
    }
}
