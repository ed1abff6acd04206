//! Turning a decoded program into a setpoint stream with any of the planners: the seed
//! constant-velocity and trapezoid interpolators, or the jerk-limited look-ahead planner on
//! the machine axes. Every planner times all moves first (counting the samples, refused beyond
//! [`MAX_SETPOINT_SAMPLES`]) and samples them as the stream is read.

use super::constant_velocity::ConstantVelocityStream;
use super::path::{AxisLimits, AxisPath, AxisSpec, Blend, Geometry, PathError, PathSegment};
use super::path_reader::{PathReader, SegmentSource};
use super::planner::{PlanWindows, KEPT_SEGMENTS, WINDOW_SEGMENTS};
use super::setpoints::{sample_count, SetpointStream, Setpoints, MAX_SETPOINT_SAMPLES};
use super::stream::{collect, Stretch, StretchStream};
use super::trapezoid::TrapezoidProfile;
use super::{plan, PlanError};
use crate::kinematics::{self, AxisMap};
use crate::machine::Machine;
use crate::program::{self, move_duration, plane_axes, Feed, FeedRule, Motion, Program};

/// Which planner, with its parameters (SI).
#[derive(Debug, Clone, PartialEq)]
pub enum Planner {
    /// Seed digest §1.4/§1.6: constant path speed, velocity steps at move ends.
    ConstantVelocity,
    /// Seed digest §1.5: trapezoidal speed along each straight move, stopping at every point.
    Trapezoid {
        /// Acceleration along the move (m/s²).
        acceleration: f64,
    },
    /// Jerk-limited, time-optimal look-ahead planner with these limits per machine axis.
    JerkLimited {
        /// One entry per machine axis, in axis order.
        limits: Vec<AxisLimits>,
    },
}

/// Corner behaviour: as programmed (G61/G64 P), or forced for the whole program.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum BlendChoice {
    /// Each move's own G61/G64 setting.
    #[default]
    Program,
    /// Stop exactly at every programmed point.
    ExactStop,
    /// Blend every corner.
    Continuous {
        /// Largest allowed deviation from the programmed corner (m at the tool tip); `None`:
        /// rounded as far as the adjacent segments allow.
        tolerance: Option<f64>,
    },
}

/// How to plan a program: the planner, the servo period and the corner behaviour.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanSettings {
    /// Which planner, with its parameters.
    pub planner: Planner,
    /// Servo period (s): the setpoints' sample period.
    pub period: f64,
    /// Path speed of rapid moves for the seed interpolators (m/s).
    pub rapid_speed: f64,
    /// Corner behaviour (the jerk-limited planner's; the seed interpolators ignore it).
    pub blend: BlendChoice,
    /// Machine axis names (for reports and errors).
    pub axis_names: Vec<String>,
    /// Naive-CAM collinearity tolerance (LinuxCNC's G64 Q, m): in continuous mode, a run of
    /// straight feed moves whose points all lie within it of one straight line is joined into
    /// that line (at most 100 points, rotary axes unchanged, one feed), as LinuxCNC joins them.
    /// It overrides the program's own G64 Q (zero: no joining); `None`: the program's G64 Q
    /// where it gives one (a run then stays within one G64 setting).
    pub naive_cam_tolerance: Option<f64>,
    /// Distance (m) of the tool tip from each rotary machine axis at the program's points
    /// ([`tool_lever_arms`]), so that corner tolerances are measured at the tool tip on the
    /// workpiece. Empty: in machine-axis space (1 rad counts as 1 m).
    pub tool_lever_arms: Vec<f64>,
}

/// (m per rad): the 5-axis study's feed rule counts 1 degree like 1 mm.
const DEGREE_AS_METRE: f64 = 1e-3 * 180.0 / std::f64::consts::PI;

/// Most points LinuxCNC's naive-CAM detector joins into one line.
const NAIVE_CAM_POINTS: usize = 100;

/// Plans `program` on the machine axes given by `axes`, all samples in memory.
pub fn plan_program(
    program: &Program,
    axes: &AxisMap,
    settings: &PlanSettings,
) -> Result<Setpoints, PlanError> {
    let mut stream = plan_program_stream(program, axes, settings)?;
    Ok(collect(stream.as_mut()))
}

/// Plans `program` on the machine axes given by `axes` as a stream: every move is timed here
/// (so the stream's length is known), each sample is computed when it is read.
pub fn plan_program_stream<'a>(
    program: &'a Program,
    axes: &'a AxisMap,
    settings: &PlanSettings,
) -> Result<Box<dyn SetpointStream + Send + 'a>, PlanError> {
    let period = settings.period;
    if !(period.is_finite() && period > 0.0) {
        return Err(PlanError::BadPeriod(period));
    }
    let n = axes.axes();
    let stretches = match &settings.planner {
        Planner::ConstantVelocity => {
            return Ok(Box::new(ConstantVelocityStream::new(
                program,
                axes,
                period,
                settings.rapid_speed,
            )?))
        }
        Planner::Trapezoid { acceleration } => {
            trapezoid_stretches(program, axes, settings, *acceleration)?
        }
        Planner::JerkLimited { limits } => jerk_limited_stretches(program, axes, settings, limits)?,
    };
    Ok(Box::new(StretchStream::new(n, period, stretches)))
}

/// Plans a machine-axis `path` with the jerk-limited planner as a stream, as
/// [`plan_program_stream`] plans each motion of a program: every window of the path is timed
/// here (so the stream's length is known), and planned again when its samples are read.
/// Sample 0 is the path's start at rest; samples 1.. are bit-identical to those of
/// [`plan`]`(&path)?.sample(period)`. Errors name no program line (a path has none): a path
/// error comes as [`PlanError::Path`] from move 0, too many samples at the path's last segment.
pub fn plan_path_stream(
    path: AxisPath,
    period: f64,
) -> Result<Box<dyn SetpointStream + Send>, PlanError> {
    if !(period.is_finite() && period > 0.0) {
        return Err(PlanError::BadPeriod(period));
    }
    let n = path.axes.len();
    let (start, first, last) = (
        path.start.clone(),
        path.segments.first().map_or(0, |s| s.source_index),
        path.segments.last().map_or(0, |s| s.source_index as usize),
    );
    let reader = PathReader::Shared(std::sync::Arc::new(path));
    let windows = PlanWindows::new(reader, WINDOW_SEGMENTS, 0, &mut KEPT_SEGMENTS.clone())
        .map_err(|source| PlanError::Path {
            first_move: 0,
            line: 0,
            message: source.to_string(),
        })?;
    let ticks = SampleBudget::new(period).add_motion(windows.duration(), last, 0)?;
    let stretches = vec![
        Stretch::Start {
            at: start,
            segment: first,
        },
        Stretch::Windows {
            plan: Box::new(windows),
            ticks,
        },
    ];
    Ok(Box::new(StretchStream::new(n, period, stretches)))
}

/// The jerk-limited plans of a program's motions (one per stretch between dwells), each with
/// the machine-axis path it was planned from, for inspecting the planned geometry and timing;
/// `None` for another planner.
pub fn jerk_limited_plans(
    program: &Program,
    axes: &AxisMap,
    settings: &PlanSettings,
) -> Result<Option<Vec<(AxisPath, super::Plan)>>, PlanError> {
    let Planner::JerkLimited { limits } = &settings.planner else {
        return Ok(None);
    };
    let stretches = jerk_limited_stretches(program, axes, settings, limits)?;
    let mut plans = Vec::new();
    for stretch in stretches {
        if let Stretch::Windows { plan, .. } = stretch {
            // Whole: for inspecting the planned geometry and timing.
            let first_move = plan.first_move();
            let error = |source| path_error(program, first_move, source);
            let path = plan.whole_path().map_err(error)?;
            let plan = super::plan(&path).map_err(error)?;
            plans.push((path, plan));
        }
    }
    Ok(Some(plans))
}

/// Running count of the samples a program needs, refused beyond [`MAX_SETPOINT_SAMPLES`].
pub(super) struct SampleBudget {
    period: f64,
    /// Samples so far (the start sample included) and the time they cover.
    samples: usize,
    duration: f64,
}

impl SampleBudget {
    pub fn new(period: f64) -> Self {
        SampleBudget {
            period,
            samples: 1,
            duration: 0.0,
        }
    }

    /// Adds a stretch of `duration` with `ticks` samples after its start (as a float: it may
    /// exceed any integer), for move `index` on `line`; the ticks as an integer.
    pub fn add(
        &mut self,
        ticks: f64,
        duration: f64,
        index: usize,
        line: u32,
    ) -> Result<usize, PlanError> {
        self.duration += duration;
        let needed = self.samples as f64 + ticks;
        if needed.is_nan() || needed > MAX_SETPOINT_SAMPLES as f64 {
            return Err(PlanError::TooManySamples {
                index,
                line,
                duration: self.duration,
                needed,
                period: self.period,
            });
        }
        self.samples = needed as usize;
        Ok(ticks as usize)
    }

    /// Adds a motion of `duration` sampled on its own grid ([`sample_count`]).
    pub fn add_motion(
        &mut self,
        duration: f64,
        index: usize,
        line: u32,
    ) -> Result<usize, PlanError> {
        let ticks = match sample_count(duration, self.period) {
            Ok(count) => (count - 1) as f64,
            Err(needed) => needed,
        };
        self.add(ticks, duration, index, line)
    }

    /// Adds a dwell of `seconds` (whole periods, rounded up).
    pub fn add_dwell(&mut self, seconds: f64, index: usize, line: u32) -> Result<usize, PlanError> {
        let ticks = (seconds / self.period).ceil();
        self.add(
            if ticks.is_nan() {
                f64::INFINITY
            } else {
                ticks.max(0.0)
            },
            seconds,
            index,
            line,
        )
    }
}

fn trapezoid_stretches<'a>(
    program: &Program,
    axes: &AxisMap,
    settings: &PlanSettings,
    acceleration: f64,
) -> Result<Vec<Stretch<'a>>, PlanError> {
    let n = axes.axes();
    let mut budget = SampleBudget::new(settings.period);
    let (mut from, mut to) = (vec![0.0; n], vec![0.0; n]);
    let mut at = program.start;
    axes.machine_axes(&at, &mut from);
    let mut stretches = vec![Stretch::Start {
        at: from.clone(),
        segment: 0,
    }];
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
                    let distance = from.iter().zip(&to).map(|(a, b)| (b - a) * (b - a)).sum::<f64>().sqrt();
                    let profile = TrapezoidProfile::new(distance, speed, acceleration);
                    let ticks = budget.add_motion(profile.duration(), index, line)?;
                    stretches.push(Stretch::Trapezoid { from: from.clone(), to: to.clone(), profile, segment: index as u32, ticks });
                } else if from != to {
                    return Err(PlanError::Unsupported { index, line, what: "a purely rotary move with the trapezoid profile (it is defined on path length)" });
                }
            }
            Motion::Arc { .. } => {
                return Err(PlanError::Unsupported { index, line, what: "an arc with the trapezoid profile (docs/sources.md §1.5 defines it for straight moves; use constant-velocity or jerk-limited)" })
            }
            Motion::Dwell { seconds } => {
                let ticks = budget.add_dwell(seconds, index, line)?;
                stretches.push(Stretch::Hold { at: from.clone(), segment: index as u32, ticks });
            }
        }
        from.clone_from(&to);
        at = m.end;
    }
    Ok(stretches)
}

/// The machine-axis segments of a program's moves `first..end` (a motion between dwells) for
/// the jerk-limited planner, made in order as the planner reads them: each move on the machine
/// axes, straight runs joined as LinuxCNC's naive-CAM detector joins them.
#[derive(Debug, Clone)]
struct MoveSegments<'a> {
    program: &'a Program,
    axes: &'a AxisMap,
    blend: BlendChoice,
    naive_cam_tolerance: Option<f64>,
    /// The moves, and where the motion starts (program and machine coordinates).
    first: usize,
    end: usize,
    start_at: program::Position,
    start: Vec<f64>,
    /// The next move to read, and where the previous one ended.
    next: usize,
    at: program::Position,
    /// The segment made last, held back until the next move shows whether it joins it, with
    /// the naive-CAM tolerance it was programmed with.
    last: Option<PathSegment>,
    last_q: Option<f64>,
    /// The naive-CAM run the last segment is: where it starts and the programmed points it
    /// has absorbed.
    run_start: Vec<f64>,
    run_points: Vec<Vec<f64>>,
}

impl<'a> MoveSegments<'a> {
    fn new(
        program: &'a Program,
        axes: &'a AxisMap,
        settings: &PlanSettings,
        moves: std::ops::Range<usize>,
        start_at: program::Position,
        start: Vec<f64>,
    ) -> Self {
        MoveSegments {
            program,
            axes,
            blend: settings.blend,
            naive_cam_tolerance: settings.naive_cam_tolerance,
            first: moves.start,
            end: moves.end,
            start_at,
            start,
            next: moves.start,
            at: start_at,
            last: None,
            last_q: None,
            run_start: Vec::new(),
            run_points: Vec::new(),
        }
    }

    /// Where the segments made so far end.
    fn path_end(&self) -> &[f64] {
        self.last.as_ref().map_or(&self.start, |s| s.geometry.end())
    }

    /// Move `index` (a line or an arc, its plane checked) as a segment from where the path
    /// ends, with its naive-CAM tolerance.
    fn segment(&self, index: usize) -> (PathSegment, Option<f64>) {
        let m = &self.program.moves[index];
        let (axes, n) = (self.axes, self.axes.axes());
        let mut end = vec![0.0; n];
        axes.machine_axes(&m.end, &mut end);
        let has_linear = program::move_length(&self.at, m) > 0.0;
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
            Motion::Arc {
                center,
                plane,
                clockwise,
                turns,
            } => {
                let (first, second, _) = plane_axes(plane);
                let (i, j) = arc_plane(axes, plane)
                    .expect("arc planes are checked before the motion is planned");
                let (center, clockwise) =
                    axes.machine_arc([i, j], [center[first], center[second]], clockwise);
                Geometry::Arc {
                    plane: [i, j],
                    center,
                    clockwise,
                    turns,
                    end,
                }
            }
            Motion::Linear | Motion::Dwell { .. } => Geometry::Line { end },
        };
        let feed = match m.feed {
            Feed::Rapid => None,
            Feed::PathSpeed(v) => Some(v),
            Feed::InverseTime(seconds) => {
                // Inverse time: the path speed that makes the move take `seconds`.
                let from = self.path_end();
                let length = if matches!(m.motion, Motion::Arc { .. }) {
                    program::move_length(&self.at, m)
                } else {
                    (0..n)
                        .map(|i| (weights[i] * (geometry.end()[i] - from[i])).powi(2))
                        .sum::<f64>()
                        .sqrt()
                };
                Some(length / seconds)
            }
        };
        let blend = match (self.blend, m.blend) {
            (BlendChoice::ExactStop, _) | (BlendChoice::Program, program::Blend::ExactStop) => {
                Blend::ExactStop
            }
            (BlendChoice::Continuous { tolerance }, _) => Blend::Continuous { tolerance },
            (BlendChoice::Program, program::Blend::Continuous { tolerance, .. }) => {
                Blend::Continuous { tolerance }
            }
        };
        let q = match (self.naive_cam_tolerance, m.blend) {
            (Some(q), _) => Some(q),
            (None, program::Blend::Continuous { naive_cam, .. }) => naive_cam,
            (None, program::Blend::ExactStop) => None,
        };
        let segment = PathSegment {
            geometry,
            feed,
            feed_metric: weights,
            blend,
            source_index: index as u32,
        };
        (segment, q)
    }

    fn joins_run(&self, next: &PathSegment, q: Option<f64>) -> bool {
        let Some(q) = q.filter(|q| *q > 0.0) else {
            return false;
        };
        if self.last_q != Some(q) {
            return false;
        }
        let Some(last) = self.last.as_ref() else {
            return false;
        };
        let continuous = |s: &PathSegment| matches!(s.blend, Blend::Continuous { .. });
        let (Geometry::Line { end: a }, Geometry::Line { end: b }) =
            (&last.geometry, &next.geometry)
        else {
            return false;
        };
        if !(continuous(last) && continuous(next))
            || last.feed != next.feed
            || last.feed_metric != next.feed_metric
            || self.run_points.len() >= NAIVE_CAM_POINTS
        {
            return false;
        }
        let n = a.len();
        let rotary_fixed = (0..n)
            .filter(|&i| self.axes.is_rotary(i))
            .all(|i| a[i] == b[i] && self.run_start[i] == a[i]);
        if !rotary_fixed || b.as_slice() == self.run_start.as_slice() {
            return false;
        }
        // Every point of the run, the last end included, within Q of the straight line from
        // the run's start to the new end (measured on the linear axes).
        let linear: Vec<usize> = (0..n).filter(|&i| !self.axes.is_rotary(i)).collect();
        let start = &self.run_start;
        let within = |p: &[f64]| {
            let m: Vec<f64> = linear.iter().map(|&i| b[i] - start[i]).collect();
            let d: Vec<f64> = linear.iter().map(|&i| p[i] - start[i]).collect();
            let mm: f64 = m.iter().map(|x| x * x).sum();
            let t = if mm > 0.0 {
                (m.iter().zip(&d).map(|(x, y)| x * y).sum::<f64>() / mm).clamp(0.0, 1.0)
            } else {
                0.0
            };
            m.iter()
                .zip(&d)
                .map(|(x, y)| (y - t * x).powi(2))
                .sum::<f64>()
                .sqrt()
                <= q
        };
        self.run_points.iter().all(|p| within(p)) && within(a)
    }
}

impl<'a> SegmentSource<'a> for MoveSegments<'a> {
    fn next_segment(&mut self) -> Option<PathSegment> {
        while self.next < self.end {
            let index = self.next;
            self.next += 1;
            let (segment, q) = self.segment(index);
            self.at = self.program.moves[index].end;
            let joins = self.joins_run(&segment, q);
            self.last_q = q;
            if joins {
                let last = self.last.as_mut().expect("a run has a segment");
                self.run_points.push(last.geometry.end().to_vec());
                *last = segment;
                continue;
            }
            self.run_start = self.path_end().to_vec();
            self.run_points.clear();
            if let Some(made) = self.last.replace(segment) {
                return Some(made);
            }
        }
        self.last.take()
    }

    fn restart(&self) -> Box<dyn SegmentSource<'a> + 'a> {
        Box::new(MoveSegments {
            next: self.first,
            at: self.start_at,
            last: None,
            last_q: None,
            run_start: Vec::new(),
            run_points: Vec::new(),
            ..self.clone()
        })
    }
}

/// The machine axes of an arc's plane, if the machine has both.
fn arc_plane(axes: &AxisMap, plane: program::Plane) -> Option<(usize, usize)> {
    let (first, second, _) = plane_axes(plane);
    Some((
        axes.machine_axis(true, first)?,
        axes.machine_axis(true, second)?,
    ))
}

/// The jerk-limited planner's stretches of a program: one motion per run of moves between
/// dwells, each planned window by window from its moves as it is read.
fn jerk_limited_stretches<'a>(
    program: &'a Program,
    axes: &'a AxisMap,
    settings: &PlanSettings,
    limits: &[AxisLimits],
) -> Result<Vec<Stretch<'a>>, PlanError> {
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
    let mut start = vec![0.0; n];
    axes.machine_axes(&program.start, &mut start);
    let mut budget = SampleBudget::new(settings.period);
    let mut stretches = vec![Stretch::Start {
        at: start.clone(),
        segment: 0,
    }];
    // The motions: the moves between dwells, where each starts, and the dwell after it.
    let mut motions = Vec::new();
    let (mut first, mut first_at, mut at) = (0, program.start, program.start);
    for (index, m) in program.moves.iter().enumerate() {
        match m.motion {
            Motion::Dwell { seconds } => {
                motions.push((first..index, first_at, Some((index, seconds))));
                (first, first_at) = (index + 1, at);
                continue;
            }
            Motion::Arc { plane, .. } if arc_plane(axes, plane).is_none() => {
                return Err(PlanError::Unsupported {
                    index,
                    line: m.span.line,
                    what: "an arc in a plane the machine has no axes for",
                });
            }
            Motion::Arc { .. } | Motion::Linear => {}
        }
        at = m.end;
    }
    motions.push((first..program.moves.len(), first_at, None));
    // Segments whose windows may be kept for evaluation, all motions together.
    let mut kept = KEPT_SEGMENTS;
    for (moves, first_at, dwell) in motions {
        if !moves.is_empty() {
            let first_move = moves.start;
            let header = AxisPath {
                axes: specs.clone(),
                start: start.clone(),
                segments: Vec::new(),
                tool_lever_arms: settings.tool_lever_arms.clone(),
            };
            let source = MoveSegments::new(program, axes, settings, moves, first_at, start.clone());
            let error = |source| path_error(program, first_move, source);
            let reader = PathReader::streamed(header, Box::new(source)).map_err(error)?;
            let windows =
                PlanWindows::new(reader, WINDOW_SEGMENTS, first_move, &mut kept).map_err(error)?;
            if std::env::var_os("CNCSIM_PLAN_DEBUG").is_some() {
                if let Ok(planned) = windows.whole_path().and_then(|path| plan(&path)) {
                    eprintln!("{}", planned.debug_dump());
                }
            }
            let (end, last) = windows.end();
            start.clear();
            start.extend_from_slice(end);
            let line = program.moves.get(last as usize).map_or(0, |m| m.span.line);
            let ticks = budget.add_motion(windows.duration(), last as usize, line)?;
            stretches.push(Stretch::Windows {
                plan: Box::new(windows),
                ticks,
            });
        }
        if let Some((index, seconds)) = dwell {
            let ticks = budget.add_dwell(seconds, index, program.moves[index].span.line)?;
            stretches.push(Stretch::Hold {
                at: start.clone(),
                segment: index as u32,
                ticks,
            });
        }
    }
    Ok(stretches)
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

/// The distance (m) of the tool tip from each rotary machine axis, the largest over the
/// program's start and move end points (zero for linear axes): a corner blend that moves
/// rotary axis `i` by δ moves the tool tip on the workpiece by at most that distance times δ.
pub fn tool_lever_arms(machine: &Machine, program: &Program, axes: &AxisMap) -> Vec<f64> {
    let n = axes.axes();
    let mut arms = vec![0.0; n];
    let rotary: Vec<usize> = (0..n).filter(|&i| axes.is_rotary(i)).collect();
    if rotary.is_empty() {
        return arms;
    }
    let mut q = vec![0.0; n];
    let points = std::iter::once(&program.start).chain(program.moves.iter().map(|m| &m.end));
    for p in points {
        axes.machine_axes(p, &mut q);
        let poses = kinematics::link_poses(machine, &q);
        let tool = poses[machine.tool_link] * nalgebra::Point3::from(machine.tool.offset_m);
        for &i in &rotary {
            let joint = &machine.joints[machine.axes[i].joint];
            let frame = poses[joint.parent] * joint.origin;
            let axis = frame.rotation * joint.axis;
            let offset = tool - nalgebra::Point3::from(frame.translation.vector);
            let distance = offset.cross(&axis).norm() / axis.norm();
            if distance.is_finite() {
                arms[i] = arms[i].max(distance);
            }
        }
    }
    arms
}
