//! Turning a decoded program into setpoints with any of the planners: the seed
//! constant-velocity and trapezoid interpolators, or the jerk-limited look-ahead planner on
//! the machine axes.

use super::path::{AxisLimits, AxisPath, AxisSpec, Blend, Geometry, PathError, PathSegment};
use super::{constant_velocity, plan, trapezoid_line, PlanError, Setpoints};
use crate::kinematics::AxisMap;
use crate::program::{self, move_duration, plane_axes, Feed, FeedRule, Motion, Program};

/// Which planner, with its parameters (SI).
#[derive(Debug, Clone, PartialEq)]
pub enum Planner {
    /// Seed digest §1.4/§1.6: constant path speed, velocity steps at move ends.
    ConstantVelocity,
    /// Seed digest §1.5: trapezoidal speed along each straight move, stopping at every point.
    Trapezoid { acceleration: f64 },
    /// Jerk-limited, time-optimal look-ahead planner with these limits per machine axis.
    JerkLimited { limits: Vec<AxisLimits> },
}

/// Corner behaviour: as programmed (G61/G64 P), or forced for the whole program.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum BlendChoice {
    #[default]
    Program,
    ExactStop,
    Continuous {
        tolerance: Option<f64>,
    },
}

#[derive(Debug, Clone, PartialEq)]
pub struct PlanSettings {
    pub planner: Planner,
    pub period: f64,
    /// Path speed of rapid moves for the seed interpolators (m/s).
    pub rapid_speed: f64,
    pub blend: BlendChoice,
    /// Machine axis names (for reports and errors).
    pub axis_names: Vec<String>,
}

/// (m per rad): the 5-axis study's feed rule counts 1 degree like 1 mm.
const DEGREE_AS_METRE: f64 = 1e-3 * 180.0 / std::f64::consts::PI;

/// Plans `program` on the machine axes given by `axes`.
pub fn plan_program(
    program: &Program,
    axes: &AxisMap,
    settings: &PlanSettings,
) -> Result<Setpoints, PlanError> {
    match &settings.planner {
        Planner::ConstantVelocity => {
            constant_velocity(program, axes, settings.period, settings.rapid_speed)
        }
        Planner::Trapezoid { acceleration } => {
            trapezoid_program(program, axes, settings, *acceleration)
        }
        Planner::JerkLimited { limits } => jerk_limited_program(program, axes, settings, limits),
    }
}

fn trapezoid_program(
    program: &Program,
    axes: &AxisMap,
    settings: &PlanSettings,
    acceleration: f64,
) -> Result<Setpoints, PlanError> {
    let n = axes.axes();
    let mut out = Setpoints::new(settings.period, n);
    let (mut from, mut to) = (vec![0.0; n], vec![0.0; n]);
    let mut at = program.start;
    axes.machine_axes(&at, &mut from);
    out.push(&from, &vec![0.0; n], &vec![0.0; n], 0);
    for (index, m) in program.moves.iter().enumerate() {
        let line = m.span.line;
        axes.machine_axes(&m.end, &mut to);
        match m.motion {
            Motion::Linear => {
                let length = program::move_length(&at, m);
                let duration = match m.feed {
                    Feed::Rapid => length / settings.rapid_speed,
                    _ => move_duration(&at, m).unwrap_or(f64::NAN),
                };
                let speed = length / duration;
                if length > 0.0 {
                    if !(speed.is_finite() && speed > 0.0) {
                        return Err(PlanError::BadFeed { index, line, feed: speed });
                    }
                    out.append_continuing(&trapezoid_line(&from, &to, speed, acceleration, settings.period, index as u32));
                } else if from != to {
                    return Err(PlanError::Unsupported { index, line, what: "a purely rotary move with the trapezoid profile (it is defined on path length)" });
                }
            }
            Motion::Arc { .. } => {
                return Err(PlanError::Unsupported { index, line, what: "an arc with the trapezoid profile (docs/sources.md §1.5 defines it for straight moves; use constant-velocity or jerk-limited)" })
            }
            Motion::Dwell { seconds } => out.hold((seconds / settings.period).ceil() as usize, index as u32),
        }
        from.clone_from(&to);
        at = m.end;
    }
    Ok(out)
}

fn jerk_limited_program(
    program: &Program,
    axes: &AxisMap,
    settings: &PlanSettings,
    limits: &[AxisLimits],
) -> Result<Setpoints, PlanError> {
    let n = axes.axes();
    let specs: Vec<AxisSpec> = (0..n)
        .map(|i| AxisSpec {
            name: settings.axis_names[i].clone(),
            kind: if axes.is_rotary(i) {
                super::AxisKind::Rotary
            } else {
                super::AxisKind::Linear
            },
            limits: limits[i],
        })
        .collect();
    let mut out = Setpoints::new(settings.period, n);
    let mut start = vec![0.0; n];
    axes.machine_axes(&program.start, &mut start);
    let mut path = AxisPath {
        axes: specs.clone(),
        start: start.clone(),
        segments: Vec::new(),
    };
    let mut at = program.start;
    // First program move of the path being collected, for error messages.
    let mut first_move = 0;

    let flush =
        |path: &mut AxisPath, out: &mut Setpoints, first_move: usize| -> Result<(), PlanError> {
            if path.segments.is_empty() {
                if out.is_empty() {
                    out.push(&path.start, &vec![0.0; n], &vec![0.0; n], 0);
                }
                return Ok(());
            }
            let planned = plan(path).map_err(|source| path_error(program, first_move, source))?;
            out.append_continuing(&planned.sample(settings.period));
            let end = path
                .segments
                .last()
                .map(|s| s.geometry.end().to_vec())
                .unwrap_or_default();
            path.start = end;
            path.segments.clear();
            Ok(())
        };

    for (index, m) in program.moves.iter().enumerate() {
        if path.segments.is_empty() {
            first_move = index;
        }
        let mut end = vec![0.0; n];
        axes.machine_axes(&m.end, &mut end);
        let has_linear = program::move_length(&at, m) > 0.0;
        let weights: Vec<f64> = (0..n)
            .map(|i| match (axes.is_rotary(i), m.feed_rule) {
                (false, _) => 1.0,
                (true, FeedRule::EuclideanAllAxes) => DEGREE_AS_METRE,
                (true, FeedRule::LinuxCnc) => {
                    if has_linear {
                        0.0
                    } else {
                        DEGREE_AS_METRE
                    }
                }
            })
            .collect();
        let geometry = match m.motion {
            Motion::Linear => Geometry::Line { end },
            Motion::Arc {
                center,
                plane,
                clockwise,
                turns,
            } => {
                let (first, second, _) = plane_axes(plane);
                let (Some(i), Some(j)) = (
                    axes.machine_axis(true, first),
                    axes.machine_axis(true, second),
                ) else {
                    return Err(PlanError::Unsupported {
                        index,
                        line: m.span.line,
                        what: "an arc in a plane the machine has no axes for",
                    });
                };
                Geometry::Arc {
                    plane: [i, j],
                    center: [center[first], center[second]],
                    clockwise,
                    turns,
                    end,
                }
            }
            Motion::Dwell { seconds } => {
                flush(&mut path, &mut out, first_move)?;
                out.hold((seconds / settings.period).ceil() as usize, index as u32);
                continue;
            }
        };
        let feed = match m.feed {
            Feed::Rapid => None,
            Feed::PathSpeed(v) => Some(v),
            Feed::InverseTime(seconds) => {
                // Inverse time: the path speed that makes the move take `seconds`.
                let length: f64 = (0..n)
                    .map(|i| (weights[i] * (geometry.end()[i] - path_end(&path)[i])).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let length = if matches!(m.motion, Motion::Arc { .. }) {
                    program::move_length(&at, m)
                } else {
                    length
                };
                Some(length / seconds)
            }
        };
        let blend = match (settings.blend, m.blend) {
            (BlendChoice::ExactStop, _) | (BlendChoice::Program, program::Blend::ExactStop) => {
                Blend::ExactStop
            }
            (BlendChoice::Continuous { tolerance }, _) => Blend::Continuous { tolerance },
            (BlendChoice::Program, program::Blend::Continuous { tolerance }) => {
                Blend::Continuous { tolerance }
            }
        };
        path.segments.push(PathSegment {
            geometry,
            feed,
            feed_metric: weights,
            blend,
            source_index: index as u32,
        });
        at = m.end;
    }
    flush(&mut path, &mut out, first_move)?;
    Ok(out)
}

/// Where the path being collected currently ends.
fn path_end(path: &AxisPath) -> &[f64] {
    path.segments
        .last()
        .map_or(&path.start, |s| s.geometry.end())
}

fn path_error(program: &Program, first_move: usize, source: PathError) -> PlanError {
    // Segment indices in the error are counted from the first move of the planned stretch.
    let line = program.moves.get(first_move).map_or(0, |m| m.span.line);
    PlanError::Path {
        first_move,
        line,
        message: source.to_string(),
    }
}
