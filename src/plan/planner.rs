//! The jerk-limited look-ahead planner: a machine-axis path in, a timed trajectory out.
//!
//! 1. Each segment is parameterised by a path coordinate `s` (`geometry::SegmentShape`) and
//!    gets limits on ṡ, s̈, s⃛ under which every axis keeps its own limits (and ṡ the feed).
//! 2. Each junction gets a speed cap: zero for exact stop, at the path start and end, and next
//!    to arcs; for a continuous corner between two lines, the highest speed whose corner blend
//!    ([`super::blend`]) stays within the tolerance and uses at most a quarter of either line,
//!    lowered to the speed that loses least time ([`super::blend::best_corner_speed`]: with a
//!    jerk limit, a corner that only allows a crawl is faster taken as a stop).
//! 3. Look-ahead: a backward pass (every junction slow enough to stop in time for the ones after
//!    it) and a forward pass (fast enough only as far as reachable from the ones before), both
//!    with the jerk-limited transfer distance between two speeds at zero acceleration
//!    ([`super::profile::transfer_distance`]). The segment length used here excludes the blend
//!    cuts at their capped speeds; the final cuts are shorter, so every transfer stays feasible.
//! 4. Each leg between its blends is a time-optimal seven-phase profile ([`Profile::plan`])
//!    from its entry to its exit junction speed. A leg is usually one segment; collinear lines
//!    joined in continuous mode with the same limits form one leg, so that a straight line cut
//!    into many blocks accelerates across the block boundaries.
//!
//! Junctions are passed at zero acceleration, so the axis acceleration is continuous everywhere
//! and the jerk bounded: each piece stays within every axis limit on its own.

use super::blend::{best_corner_speed, max_corner_speed, CornerBlend, CornerSide, CornerTurn};
use super::geometry::SegmentShape;
use super::path::{AxisPath, Blend, Geometry, PathError};
use super::profile::{reachable_velocity, Limits, Profile};
use super::setpoints::Setpoints;
use super::trapezoid::sample_times;

/// Largest share of a line that one corner blend may use (so at least half of every line is
/// left for speed changes).
const MAX_BLEND_SHARE: f64 = 0.25;

/// A timed trajectory over a whole path.
#[derive(Debug, Clone)]
pub struct Plan {
    axes: usize,
    shapes: Vec<SegmentShape>,
    limits: Vec<Limits>,
    source_index: Vec<u32>,
    legs: Vec<Leg>,
    pieces: Vec<Piece>,
    start: Vec<f64>,
    duration: f64,
}

/// Consecutive segments planned as one profile: collinear lines joined in continuous mode with
/// the same path limits (a straight line cut into blocks is one motion, accelerating across the
/// block boundaries). Most legs are a single segment.
#[derive(Debug, Clone)]
struct Leg {
    /// Segments `first..=last`.
    first: usize,
    last: usize,
    /// Path coordinate at the start of each segment of the leg, and the leg length at the end.
    starts: Vec<f64>,
    limits: Limits,
}

impl Leg {
    fn length(&self) -> f64 {
        *self.starts.last().unwrap_or(&0.0)
    }

    /// The segment holding leg coordinate `s`, and `s` on that segment.
    fn locate(&self, s: f64) -> (usize, f64) {
        let segments = self.last - self.first + 1;
        let i = self.starts[1..segments].partition_point(|&start| start <= s);
        (self.first + i, s - self.starts[i])
    }
}

/// One piece of the timeline.
#[derive(Debug, Clone)]
struct Piece {
    start_time: f64,
    leg: usize,
    kind: PieceKind,
}

// Pieces live once in a Vec; boxing the profile would cost an allocation per leg for nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
enum PieceKind {
    /// Travel along a leg: s = offset + profile position. `to_end`: no blend follows, the
    /// travel ends on the programmed end point.
    Travel {
        offset: f64,
        profile: Profile,
        to_end: bool,
    },
    /// A corner blend from `leg` into `leg + 1`.
    Corner(CornerBlend),
}

impl Piece {
    fn duration(&self) -> f64 {
        match &self.kind {
            PieceKind::Travel { profile, .. } => profile.duration(),
            PieceKind::Corner(blend) => blend.duration(),
        }
    }
}

/// Timing of one segment in a plan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentTiming {
    pub source_index: u32,
    /// When the segment starts (s); in continuous mode, halfway through the corner blend.
    pub start_time: f64,
    pub duration: f64,
    /// Path limits the segment was planned with.
    pub limits: Limits,
}

/// Plans a path. See the module documentation for the method.
pub fn plan(path: &AxisPath) -> Result<Plan, PathError> {
    validate(path)?;
    let n_axes = path.axes.len();
    let mut shapes = Vec::with_capacity(path.segments.len());
    let mut limits = Vec::with_capacity(path.segments.len());
    let mut from = path.start.clone();
    for (index, segment) in path.segments.iter().enumerate() {
        let shape = SegmentShape::new(index, &from, segment, &path.axes)?;
        limits.push(shape.path_limits(&path.axes, segment.feed));
        from.clone_from(&shape.end);
        shapes.push(shape);
    }
    let legs = group_into_legs(path, &shapes, &limits);
    let m = legs.len();

    // Speed caps and blend geometry at the junctions between legs (junction i + 1 joins legs i
    // and i + 1; junctions 0 and m are the path's start and end).
    let mut caps = vec![0.0; m + 1];
    let mut turns: Vec<Option<CornerTurn>> = vec![None; m + 1];
    for i in 0..m.saturating_sub(1) {
        let (a, b) = (&legs[i], &legs[i + 1]);
        let Blend::Continuous { tolerance } = path.segments[a.last].blend else {
            continue;
        };
        let (Some(u1), Some(u2)) = (
            shapes[a.last].line_direction(),
            shapes[b.first].line_direction(),
        ) else {
            continue;
        };
        if a.length() == 0.0 || b.length() == 0.0 {
            continue;
        }
        let turn = CornerTurn::new(u2.iter().zip(u1).map(|(x, y)| x - y).collect(), &path.axes);
        let speed_cap = a.limits.velocity.min(b.limits.velocity);
        let max_cut = MAX_BLEND_SHARE * a.length().min(b.length());
        let within_tolerance = max_corner_speed(
            &turn,
            tolerance.unwrap_or(f64::INFINITY),
            max_cut,
            speed_cap,
        );
        // Each side would cruise at most at what it reaches from rest in half its length.
        let side = |leg: &Leg| CornerSide {
            limits: leg.limits,
            cruise: reachable_velocity(0.0, 0.5 * leg.length(), &leg.limits),
        };
        caps[i + 1] = best_corner_speed(&turn, within_tolerance, &[side(a), side(b)]);
        if caps[i + 1] > 0.0 {
            turns[i + 1] = Some(turn);
        }
    }
    let cut_at = |turns: &[Option<CornerTurn>], junction: usize, speed: f64| -> f64 {
        match &turns[junction] {
            Some(turn) if speed > 0.0 => turn.timing(speed).cut_length(speed),
            _ => 0.0,
        }
    };

    // Look-ahead over the length left between the blends at their capped speeds.
    let spare: Vec<f64> = (0..m)
        .map(|i| {
            (legs[i].length() - cut_at(&turns, i, caps[i]) - cut_at(&turns, i + 1, caps[i + 1]))
                .max(0.0)
        })
        .collect();
    let mut speeds = caps.clone();
    for i in (0..m).rev() {
        if speeds[i] > 0.0 {
            speeds[i] = speeds[i].min(reachable_velocity(speeds[i + 1], spare[i], &legs[i].limits));
        }
    }
    for i in 0..m {
        if speeds[i + 1] > 0.0 {
            let reachable = reachable_velocity(speeds[i], spare[i], &legs[i].limits);
            speeds[i + 1] = speeds[i + 1].min(reachable);
        }
    }

    // The corner speeds came from a local estimate made before the look-ahead; now that the
    // neighbouring speeds are known, stop instead wherever that is faster for the two legs
    // around the corner (and feasible: the legs can slow down to and start from rest).
    let leg_time = |i: usize, v0: f64, v1: f64, cuts: f64| {
        Profile::plan((legs[i].length() - cuts).max(0.0), v0, v1, &legs[i].limits)
            .map_or(f64::INFINITY, |p| p.duration())
    };
    for j in 1..m {
        let v = speeds[j];
        let Some(turn) = turns[j].as_ref().filter(|_| v > 0.0) else {
            continue;
        };
        let (before, after) = (
            cut_at(&turns, j - 1, speeds[j - 1]),
            cut_at(&turns, j + 1, speeds[j + 1]),
        );
        let timing = turn.timing(v);
        let cut = timing.cut_length(v);
        let blended = leg_time(j - 1, speeds[j - 1], v, before + cut)
            + timing.duration
            + leg_time(j, v, speeds[j + 1], cut + after);
        let stopped =
            leg_time(j - 1, speeds[j - 1], 0.0, before) + leg_time(j, 0.0, speeds[j + 1], after);
        if stopped < blended {
            speeds[j] = 0.0;
            turns[j] = None;
        }
    }

    // Timeline: travel, corner, travel, corner, …
    let mut pieces = Vec::with_capacity(2 * m);
    let mut time = 0.0;
    let mut entry_cut = 0.0;
    let zero = vec![0.0; n_axes];
    for (i, leg) in legs.iter().enumerate() {
        let exit_cut = cut_at(&turns, i + 1, speeds[i + 1]);
        let length = (leg.length() - entry_cut - exit_cut).max(0.0);
        let profile = Profile::plan(length, speeds[i], speeds[i + 1], &leg.limits)
            .ok_or(PathError::Infeasible { segment: leg.first })?;
        pieces.push(Piece {
            start_time: time,
            leg: i,
            kind: PieceKind::Travel {
                offset: entry_cut,
                profile,
                to_end: exit_cut == 0.0,
            },
        });
        time += profile.duration();
        if let (Some(turn), true) = (&turns[i + 1], exit_cut > 0.0) {
            let speed = speeds[i + 1];
            let timing = turn.timing(speed);
            let mut start = zero.clone();
            let (segment, s) = leg.locate(leg.length() - exit_cut);
            shapes[segment].position(s, &mut start);
            let u1 = shapes[leg.last].line_direction().unwrap_or(&zero);
            let blend = CornerBlend {
                start,
                entry_velocity: u1.iter().map(|u| u * speed).collect(),
                velocity_change: turn.turn.iter().map(|d| d * speed).collect(),
                timing,
            };
            pieces.push(Piece {
                start_time: time,
                leg: i,
                kind: PieceKind::Corner(blend),
            });
            time += timing.duration;
        }
        entry_cut = exit_cut;
    }

    Ok(Plan {
        axes: n_axes,
        source_index: path.segments.iter().map(|s| s.source_index).collect(),
        shapes,
        limits,
        legs,
        pieces,
        start: path.start.clone(),
        duration: time,
    })
}

/// Groups segments into legs: a segment joins the previous leg when the junction is continuous,
/// both are lines with the same direction (dq/ds, so also the same path metric) and the same
/// path limits (the same feed). A feed change starts a new leg (the corner between the legs is
/// then straight and passed at the lower cap, with zero acceleration).
fn group_into_legs(path: &AxisPath, shapes: &[SegmentShape], limits: &[Limits]) -> Vec<Leg> {
    let mut legs: Vec<Leg> = Vec::new();
    for (k, shape) in shapes.iter().enumerate() {
        let joins = k > 0 && {
            let previous = &shapes[k - 1];
            let continuous = matches!(path.segments[k - 1].blend, Blend::Continuous { .. });
            let same_direction = match (previous.line_direction(), shape.line_direction()) {
                (Some(u1), Some(u2)) => {
                    previous.length > 0.0
                        && shape.length > 0.0
                        && u1.iter().zip(u2).all(|(a, b)| (a - b).abs() <= 1e-12)
                }
                _ => false,
            };
            // Equal up to rounding (the limits come from the direction); the leg takes the lower.
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.max(b);
            let (a, b) = (limits[k - 1], limits[k]);
            let same_limits = close(a.velocity, b.velocity)
                && close(a.acceleration, b.acceleration)
                && close(a.jerk, b.jerk);
            continuous && same_direction && same_limits
        };
        match legs.last_mut() {
            Some(leg) if joins => {
                leg.last = k;
                let end = leg.length() + shape.length;
                leg.starts.push(end);
                let (a, b) = (leg.limits, limits[k]);
                leg.limits = Limits::new(
                    a.velocity.min(b.velocity),
                    a.acceleration.min(b.acceleration),
                    a.jerk.min(b.jerk),
                );
            }
            _ => legs.push(Leg {
                first: k,
                last: k,
                starts: vec![0.0, shape.length],
                limits: limits[k],
            }),
        }
    }
    legs
}

fn validate(path: &AxisPath) -> Result<(), PathError> {
    let n = path.axes.len();
    for (axis, spec) in path.axes.iter().enumerate() {
        let l = spec.limits;
        if !Limits::new(l.velocity, l.acceleration, l.jerk).is_valid() {
            return Err(PathError::InvalidLimits { axis });
        }
    }
    let check_len = |segment: Option<usize>, found: usize| {
        if found == n {
            Ok(())
        } else {
            Err(PathError::AxisCountMismatch {
                segment,
                expected: n,
                found,
            })
        }
    };
    let finite = |segment: Option<usize>, what: &'static str, values: &[f64]| {
        if values.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(PathError::InvalidValue { segment, what })
        }
    };
    check_len(None, path.start.len())?;
    finite(None, "start position", &path.start)?;
    for (k, segment) in path.segments.iter().enumerate() {
        let s = Some(k);
        check_len(s, segment.geometry.end().len())?;
        check_len(s, segment.feed_metric.len())?;
        finite(s, "end position", segment.geometry.end())?;
        finite(s, "feed metric", &segment.feed_metric)?;
        if let Geometry::Arc { center, .. } = &segment.geometry {
            finite(s, "arc centre", center)?;
        }
        if matches!(segment.feed, Some(f) if !(f.is_finite() && f > 0.0)) {
            return Err(PathError::InvalidValue {
                segment: s,
                what: "feed",
            });
        }
        let negative = |t: f64| t.is_nan() || t < 0.0;
        if matches!(segment.blend, Blend::Continuous { tolerance: Some(t) } if negative(t)) {
            return Err(PathError::InvalidValue {
                segment: s,
                what: "tolerance",
            });
        }
    }
    Ok(())
}

impl Plan {
    /// Number of machine axes.
    pub fn axes(&self) -> usize {
        self.axes
    }

    /// Total duration (s), exact (not rounded to a servo period).
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// Path speed at the start and end of every leg of the plan (a leg is a run of collinear
    /// blocks planned as one motion; usually one segment): zero at exact stops.
    pub fn junction_speeds(&self) -> Vec<f64> {
        let mut speeds = vec![0.0];
        for piece in &self.pieces {
            if let PieceKind::Travel { profile, .. } = &piece.kind {
                speeds.push(profile.boundary_velocities().1);
            }
        }
        speeds
    }

    /// Timing of every segment. A corner blend counts half to each of its two segments; inside
    /// a leg, a segment ends when the motion crosses its end point.
    pub fn segment_timings(&self) -> Vec<SegmentTiming> {
        let n = self.shapes.len();
        let mut durations = vec![0.0; n];
        for piece in &self.pieces {
            let leg = &self.legs[piece.leg];
            match &piece.kind {
                PieceKind::Travel {
                    offset, profile, ..
                } => {
                    // Time at which the travel crosses each segment boundary of the leg.
                    let mut previous = 0.0;
                    let segments = &mut durations[leg.first..=leg.last];
                    let count = segments.len();
                    for (i, duration) in segments.iter_mut().enumerate() {
                        let t = if i + 1 == count {
                            profile.duration()
                        } else {
                            profile.time_at((leg.starts[i + 1] - offset).max(0.0))
                        };
                        *duration += t - previous;
                        previous = t;
                    }
                }
                PieceKind::Corner(blend) => {
                    durations[leg.last] += 0.5 * blend.duration();
                    durations[self.legs[piece.leg + 1].first] += 0.5 * blend.duration();
                }
            }
        }
        let mut start_time = 0.0;
        (0..n)
            .map(|k| {
                let timing = SegmentTiming {
                    source_index: self.source_index[k],
                    start_time,
                    duration: durations[k],
                    limits: self.limits[k],
                };
                start_time += durations[k];
                timing
            })
            .collect()
    }

    /// Index of the piece active at time `t` (the first that ends after `t`, else the last).
    fn piece_at(&self, t: f64) -> Option<usize> {
        if self.pieces.is_empty() {
            return None;
        }
        let i = self
            .pieces
            .partition_point(|p| p.start_time + p.duration() <= t);
        Some(i.min(self.pieces.len() - 1))
    }

    /// Axis positions, velocities and accelerations at time `t` (clamped to the plan); returns
    /// the index of the program move (`source_index`) the instant belongs to.
    pub fn eval(
        &self,
        t: f64,
        position: &mut [f64],
        velocity: &mut [f64],
        acceleration: &mut [f64],
    ) -> u32 {
        match self.piece_at(t) {
            Some(i) => self.eval_piece(i, t, position, velocity, acceleration),
            None => {
                position.copy_from_slice(&self.start);
                velocity.fill(0.0);
                acceleration.fill(0.0);
                0
            }
        }
    }

    fn eval_piece(
        &self,
        i: usize,
        t: f64,
        position: &mut [f64],
        velocity: &mut [f64],
        acceleration: &mut [f64],
    ) -> u32 {
        let piece = &self.pieces[i];
        let leg = &self.legs[piece.leg];
        let local = t - piece.start_time;
        match &piece.kind {
            PieceKind::Travel {
                offset,
                profile,
                to_end,
            } => {
                let state = profile.state(local);
                // Compared as the timeline was summed (t − start can round below the duration).
                let done =
                    t >= piece.start_time + profile.duration() || local >= profile.duration();
                let (segment, s) = if done && *to_end {
                    // Exactly on the programmed end point.
                    (leg.last, self.shapes[leg.last].length)
                } else if done {
                    leg.locate(offset + profile.distance())
                } else {
                    leg.locate(offset + state.position)
                };
                self.shapes[segment].eval(
                    s,
                    state.velocity,
                    state.acceleration,
                    position,
                    velocity,
                    acceleration,
                );
                self.source_index[segment]
            }
            PieceKind::Corner(blend) => {
                blend.eval(local, position, velocity, acceleration);
                let segment = if local < 0.5 * blend.duration() {
                    leg.last
                } else {
                    self.legs[piece.leg + 1].first
                };
                self.source_index[segment]
            }
        }
    }

    /// The trajectory sampled every `period` from t = 0 up to the first tick at or after the
    /// end, where it is exactly at the last programmed point.
    pub fn sample(&self, period: f64) -> Setpoints {
        let n = self.axes;
        let mut out = Setpoints::new(period, n);
        let (mut p, mut v, mut a) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut piece = 0;
        for t in sample_times(self.duration, period) {
            // Times only grow: walk the pieces instead of searching.
            while piece + 1 < self.pieces.len()
                && self.pieces[piece].start_time + self.pieces[piece].duration() <= t
            {
                piece += 1;
            }
            let segment = if self.pieces.is_empty() {
                p.copy_from_slice(&self.start);
                v.fill(0.0);
                a.fill(0.0);
                0
            } else {
                self.eval_piece(piece, t, &mut p, &mut v, &mut a)
            };
            out.push(&p, &v, &a, segment);
        }
        out
    }
}
