//! The classic constant-velocity interpolators of the source documents, exactly as written:
//! straight lines by equal steps ΔS = V·T (docs/sources.md §1.4) and circles by equal chords
//! θ = acos((2r² − ΔS²)/(2r²)) (§1.6). Each sample is computed from the move's start, not by
//! repeated addition, so there is no drift, and every move ends exactly on its target with a
//! shorter last step. Velocity is a step function; acceleration is zero between samples.

use super::from_program::SampleBudget;
use super::setpoints::{SetpointSample, SetpointStream, Setpoints};
use super::stream::collect;
use super::PlanError;
use crate::kinematics::AxisMap;
use crate::program::{
    arc_segment, move_duration, move_length, rotary_travel_degrees, Feed, Motion, Position,
    Program, Segment,
};
use nalgebra::{Point3, Vector3};

/// Samples `program` at period `period` with the constant-velocity interpolators, all in
/// memory. `rapid_speed` (m/s) is used for rapid moves.
pub fn constant_velocity(
    program: &Program,
    axes: &AxisMap,
    period: f64,
    rapid_speed: f64,
) -> Result<Setpoints, PlanError> {
    if !(period.is_finite() && period > 0.0) {
        return Err(PlanError::BadPeriod(period));
    }
    let mut stream = ConstantVelocityStream::new(program, axes, period, rapid_speed)?;
    Ok(collect(&mut stream))
}

/// How one move is sampled: samples `1..=count` after the move's start.
#[derive(Debug, Clone, Copy)]
enum Steps {
    /// Equal steps along a straight move: `steps = duration/T` (fractional), constant velocity.
    Line {
        from: Position,
        to: Position,
        steps: f64,
        velocity: Position,
    },
    /// Equal chords of angle `theta` about `center` in the plane spanned by `u`, `v`.
    Arc {
        from: Position,
        to: Position,
        center: Point3<f64>,
        u: Vector3<f64>,
        v: Vector3<f64>,
        normal: Vector3<f64>,
        radius: f64,
        theta: f64,
        steps: f64,
        sweep: f64,
        rise: f64,
        period: f64,
    },
    /// Holding still (a dwell).
    Hold { at: Position },
}

#[derive(Debug, Clone, Copy)]
struct SampledMove {
    index: u32,
    count: usize,
    steps: Steps,
}

impl SampledMove {
    /// Sample `k` (1-based) of the move: position and velocity per second, as program
    /// positions; the last one lands exactly on the target.
    fn sample(&self, k: usize) -> (Position, Position) {
        match self.steps {
            Steps::Line {
                from,
                to,
                steps,
                velocity,
            } => {
                let p = if (k as f64) < steps {
                    lerp(&from, &to, k as f64 / steps)
                } else {
                    to
                };
                (p, velocity)
            }
            Steps::Arc {
                from,
                to,
                center,
                u,
                v,
                normal,
                radius,
                theta,
                steps,
                sweep,
                rise,
                period,
            } => {
                let dir = sweep.signum();
                let rate = theta / period; // rad/s along the arc
                let tangent = |a: f64| {
                    (v * a.cos() - u * a.sin()) * (dir * radius * rate)
                        + normal * (rise / (steps * period))
                };
                let as_position = |t: Vector3<f64>| Position {
                    linear: t.into(),
                    rotary: [0.0; 3],
                };
                if (k as f64) < steps {
                    let a = dir * theta * k as f64;
                    let fraction = k as f64 / steps;
                    let p =
                        center + (u * a.cos() + v * a.sin()) * radius + normal * (rise * fraction);
                    let mut pos = lerp(&from, &to, fraction);
                    pos.linear = p.into();
                    (pos, as_position(tangent(a)))
                } else {
                    (to, as_position(tangent(sweep)))
                }
            }
            Steps::Hold { at } => (at, Position::default()),
        }
    }
}

/// The constant-velocity interpolators as a stream: sample 0 is the start (with the velocity
/// of the first move), then each move's samples; the last sample is at rest.
pub(super) struct ConstantVelocityStream<'a> {
    axes: &'a AxisMap,
    period: f64,
    start: Position,
    moves: Vec<SampledMove>,
    len: usize,
    /// Samples written so far; the move being sampled and its next sample.
    emitted: usize,
    current: usize,
    k: usize,
}

impl<'a> ConstantVelocityStream<'a> {
    /// Times every move of `program` (refusing one whose feed gives no duration, a degenerate
    /// arc, or more samples than allowed).
    pub fn new(
        program: &Program,
        axes: &'a AxisMap,
        period: f64,
        rapid_speed: f64,
    ) -> Result<Self, PlanError> {
        let mut budget = SampleBudget::new(period);
        let mut moves = Vec::with_capacity(program.moves.len());
        let mut at = program.start;
        for (index, m) in program.moves.iter().enumerate() {
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
            let steps = match m.motion {
                Motion::Linear => {
                    if duration == 0.0 || at == m.end {
                        continue;
                    }
                    let mut velocity = Position::default();
                    for i in 0..3 {
                        velocity.linear[i] = (m.end.linear[i] - at.linear[i]) / duration;
                        velocity.rotary[i] = (m.end.rotary[i] - at.rotary[i]) / duration;
                    }
                    Steps::Line {
                        from: at,
                        to: m.end,
                        steps: duration / period,
                        velocity,
                    }
                }
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
                    arc_steps(&at, &m.end, &geometry, speed, period).ok_or(bad_arc)?
                }
                Motion::Dwell { .. } => Steps::Hold { at },
            };
            let count = match steps {
                Steps::Line { steps, .. } | Steps::Arc { steps, .. } => steps.ceil(),
                Steps::Hold { .. } => (duration / period).ceil(),
            };
            if count == 0.0 {
                continue;
            }
            let count = budget.add(count, duration, index, line)?;
            moves.push(SampledMove {
                index: index as u32,
                count,
                steps,
            });
            at = m.end;
        }
        let len = 1 + moves.iter().map(|m| m.count).sum::<usize>();
        Ok(ConstantVelocityStream {
            axes,
            period,
            start: program.start,
            moves,
            len,
            emitted: 0,
            current: 0,
            k: 1,
        })
    }
}

impl SetpointStream for ConstantVelocityStream<'_> {
    fn axes(&self) -> usize {
        self.axes.axes()
    }

    fn period(&self) -> f64 {
        self.period
    }

    fn len(&self) -> usize {
        self.len
    }

    fn next_sample(&mut self, out: &mut SetpointSample) -> bool {
        if self.emitted >= self.len {
            return false;
        }
        out.acceleration.fill(0.0);
        let (position, velocity, segment) = if self.emitted == 0 {
            // The start; its velocity is that of the first move.
            match self.moves.first() {
                Some(first) => (self.start, first.sample(1).1, first.index),
                None => (self.start, Position::default(), 0),
            }
        } else {
            while self.k > self.moves[self.current].count {
                self.current += 1;
                self.k = 1;
            }
            let m = &self.moves[self.current];
            let (p, v) = m.sample(self.k);
            self.k += 1;
            (p, v, m.index)
        };
        self.axes.machine_axes(&position, &mut out.position);
        self.axes.machine_vector(&velocity, &mut out.velocity);
        self.emitted += 1;
        if self.emitted == self.len {
            // Program end: the last setpoint is at rest.
            out.velocity.fill(0.0);
        }
        out.segment = segment;
        true
    }
}

/// Equal chords ΔS = V·T of an arc; `None` for a degenerate one.
fn arc_steps(
    from: &Position,
    to: &Position,
    seg: &Segment,
    speed: f64,
    period: f64,
) -> Option<Steps> {
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
    let u = r0 / radius;
    Some(Steps::Arc {
        from: *from,
        to: *to,
        center,
        u,
        v: normal.cross(&u),
        normal,
        radius,
        theta,
        steps: sweep.abs() / theta,
        sweep,
        rise,
        period,
    })
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
