//! The jerk-limited look-ahead planner: a machine-axis path in, a timed trajectory out.
//!
//! 1. Geometry ([`super::pieces`]): the path becomes chains of pieces between stops: segment
//!    middles, corner blends between lines within the tolerance, tangent blends where a line or
//!    an arc continues another. Each piece has limits on the path coordinate `s` (ṡ, s̈, s⃛)
//!    under which every axis keeps its own limits, and the geometry is curvature-continuous
//!    along a chain, so the speed may change anywhere along it.
//! 2. Spans: consecutive pieces of a chain whose limits lie within [`SPAN_SPREAD`] of each
//!    other are timed as one stretch with the lowest of their limits: a run of short blocks on
//!    a smooth curve accelerates across the block boundaries as one motion.
//! 3. Look-ahead over the spans of a chain: a backward pass (every span boundary slow enough to
//!    slow down in time for the ones after it) and a forward pass (fast enough only as far as
//!    reachable from the ones before), with the jerk-limited transfer distance between two speeds
//!    at zero acceleration ([`super::profile::transfer_distance`]); each span boundary is also
//!    capped by both spans' speed limits.
//! 4. Each span is a time-optimal seven-phase profile ([`Recipe::plan`]) from its entry to its
//!    exit speed. Span boundaries are passed at zero path acceleration, so the axis
//!    acceleration is continuous everywhere and the jerk bounded.
//!
//! Every chain ends exactly on its programmed end point; the programmed points inside a chain
//! are passed within the corner tolerance (through them, on a tangent blend).

use super::geometry::{AxisJet, Metric, PathPoint, Shapes};
use super::path::{AxisPath, Blend, Geometry, PathError};
use super::pieces::{
    applied_feed, assign_limits, lowest_feed, Builder, Chain, Piece, PieceKind, Pieces, SHARE_CAPS,
};
use super::profile::{reachable_velocity, Limits, Profile, Recipe};
use super::quintic;
use super::setpoints::{sample_times, Setpoints};
use super::tangent::JetScratch;

/// Pieces whose speed, acceleration and jerk limits each lie within this fraction of one
/// another are timed as one span (with the lowest of them).
pub const SPAN_SPREAD: f64 = 0.05;

/// A piece shorter than this fraction of a neighbour does not split a span by itself.
const SHORT_PIECE: f64 = 0.25;

/// A timed trajectory over a whole path.
#[derive(Debug, Clone)]
pub struct Plan {
    axes: usize,
    shapes: Shapes,
    pieces: Pieces,
    spans: Vec<Span>,
    source_index: Vec<u32>,
    start: Vec<f64>,
    duration: f64,
}

/// A stretch of a chain timed by one profile.
#[derive(Debug, Clone, Copy)]
struct Span {
    /// Pieces `first..end`.
    first: usize,
    end: usize,
    chain: usize,
    /// Where the span starts in its chain's path coordinate.
    start: f64,
    start_time: f64,
    recipe: Recipe,
}

/// Timing of one segment in a plan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentTiming {
    pub source_index: u32,
    /// When the motion is at the segment's start (s): its programmed start point, or the
    /// middle of the blend into it.
    pub start_time: f64,
    pub duration: f64,
    /// Path limits of the segment on its own (its line or arc limits).
    pub limits: Limits,
}

/// Plans a path. See the module documentation for the method.
pub fn plan(path: &AxisPath) -> Result<Plan, PathError> {
    validate(path)?;
    plan_segments(path, 0, path.segments.len(), 0.0, false).map(|(plan, _)| plan)
}

/// Plans segments `first..end` of `path` (validated), its first chain starting at
/// `start_time`. With `complete_only`, the last chain (which ends where the segments are cut
/// off, not at a stop) is left out. Returns the plan and the segment after its last chain.
///
/// A chain's pieces depend only on its own segments and the shapes of the two segments around
/// it (every junction, blend and smoothing curve looks no further, and none crosses a stop),
/// so the chains planned here are exactly those of the whole path.
fn plan_segments(
    path: &AxisPath,
    first: usize,
    end: usize,
    start_time: f64,
    complete_only: bool,
) -> Result<(Plan, usize), PathError> {
    let mut timing = Timing::default();
    let timed = time_segments(path, first, end, start_time, complete_only, &mut timing)?;
    let start = match first.checked_sub(1) {
        Some(previous) => path.segments[previous].geometry.end(),
        None => &path.start,
    };
    let plan = Plan {
        axes: path.axes.len(),
        source_index: path.segments[first..end]
            .iter()
            .map(|s| s.source_index)
            .collect(),
        shapes: timed.shapes,
        pieces: timed.pieces,
        spans: timing.spans,
        start: start.to_vec(),
        duration: timed.end_time,
    };
    Ok((plan, timed.next))
}

/// The working buffers of [`time_segments`]: the spans it times, and the scratch space of its
/// chains. The timing pass of [`PlanWindows`] keeps one for all its windows, so that each
/// window reuses the previous one's allocations.
#[derive(Debug, Default)]
struct Timing {
    /// The spans of every complete chain timed, in order.
    spans: Vec<Span>,
    drafts: Vec<Draft>,
    /// The spans of the share cap being tried, and of the fastest so far, with its limits.
    trial: Vec<Span>,
    best: Vec<Span>,
    best_limits: Vec<Limits>,
    scratch: Vec<f64>,
}

/// What [`time_segments`] built and found besides the spans.
struct Timed {
    shapes: Shapes,
    pieces: Pieces,
    /// When the last chain ends.
    end_time: f64,
    /// The segment after the last chain.
    next: usize,
}

/// [`plan_segments`]' geometry and timing, with its spans in `timing.spans` (cleared first).
fn time_segments(
    path: &AxisPath,
    first: usize,
    end: usize,
    start_time: f64,
    complete_only: bool,
    timing: &mut Timing,
) -> Result<Timed, PathError> {
    let segments = &path.segments[first..end];
    let start = match first.checked_sub(1) {
        Some(previous) => path.segments[previous].geometry.end(),
        None => &path.start,
    };
    let shapes = Shapes::new(start, segments, &path.axes).map_err(|e| e.offset(first))?;
    let metric = Metric::new(&path.axes, &path.tool_lever_arms);
    let mut pieces = Builder::new(&path.axes, segments, &shapes, &metric).build();
    let next = if complete_only {
        pieces.chains.pop();
        pieces
            .chains
            .last()
            .map_or(first, |c| first + c.last_segment + 1)
    } else {
        end
    };
    let Timing {
        spans,
        drafts,
        trial,
        best,
        best_limits,
        scratch,
    } = timing;
    spans.clear();
    spans.reserve(pieces.pieces.len());
    let mut time = start_time;
    for c in 0..pieces.chains.len() {
        let chain = pieces.chains[c];
        let range = chain.first..chain.end;
        // The fastest of the share caps. A smaller cap changes nothing when no piece used more
        // than it.
        let mut fastest = f64::INFINITY;
        for (k, &cap) in SHARE_CAPS.iter().enumerate() {
            if k > 0 && largest_share_used(&pieces, range.clone()) <= cap {
                break;
            }
            assign_limits(
                &mut pieces.pieces[range.clone()],
                &pieces.budgets[range.clone()],
                &pieces.table,
                cap,
                scratch,
            );
            let duration =
                time_chain(&pieces, c, drafts, time, trial).map_err(|e| e.offset(first))?;
            if duration < fastest {
                fastest = duration;
                std::mem::swap(best, trial);
                best_limits.clear();
                best_limits.extend(pieces.pieces[range.clone()].iter().map(|p| p.limits));
            }
        }
        for (piece, limits) in pieces.pieces[range].iter_mut().zip(best_limits.iter()) {
            piece.limits = *limits;
        }
        time += fastest;
        spans.append(best);
    }
    Ok(Timed {
        shapes,
        pieces,
        end_time: time,
        next,
    })
}

/// Segments per window of [`PlanWindows`] at first; a window grows until it holds a whole
/// chain.
pub(super) const WINDOW_SEGMENTS: usize = 512;

/// Most segments whose window plans the timing pass of [`PlanWindows`] keeps for evaluation
/// (a path this short is planned once, not twice).
const KEPT_SEGMENTS: usize = 16_384;

/// A path planned window by window, as it is evaluated: the plans of a few hundred segments at
/// a time, never the whole path. Samples are bit-identical to [`plan`]'s: each window holds
/// whole chains of the path, timed from where the previous window ended.
#[derive(Debug)]
pub(super) struct PlanWindows {
    path: AxisPath,
    window: usize,
    duration: f64,
    /// Windows after the current one planned by the timing pass, with where each is followed
    /// (none when they would hold more than [`KEPT_SEGMENTS`]).
    kept: std::collections::VecDeque<(Plan, usize)>,
    /// The window being evaluated (None before the first evaluation, or when no chain moves),
    /// with its cursor; and where the next window starts.
    current: Option<(Plan, Cursor)>,
    next: usize,
    /// The start point and program move reported when nothing moves.
    rest: (Vec<f64>, u32),
    /// The program move the path starts with (for error messages).
    first_move: usize,
}

impl PlanWindows {
    /// Plans every window once for the path's duration (keeping the first, where the
    /// evaluation starts, and the rest only for a short path), and reports the errors [`plan`]
    /// would.
    pub fn new(path: AxisPath, window: usize, first_move: usize) -> Result<Self, PathError> {
        Self::keeping(path, window, first_move, KEPT_SEGMENTS)
    }

    /// [`Self::new`], keeping the timing pass's windows for a path of at most `most` segments.
    fn keeping(
        path: AxisPath,
        window: usize,
        first_move: usize,
        most: usize,
    ) -> Result<Self, PathError> {
        validate(&path)?;
        let mut window = window.max(1);
        let count = path.segments.len();
        let keep = count <= most;
        // The first window is kept (the evaluation starts there), the rest only for a short
        // path; of the others only the end time is needed, and one set of buffers does for all.
        let mut first = None;
        let mut kept = std::collections::VecDeque::new();
        let mut duration = 0.0;
        let mut next = 0;
        let mut timing = Timing::default();
        while next < count {
            if first.is_none() || keep {
                let plan;
                (plan, next) =
                    Self::plan_window(&path, next, &mut window, |end, complete_only| {
                        plan_segments(&path, next, end, duration, complete_only)
                    })?;
                duration = plan.duration;
                if first.is_none() {
                    first = Some((plan, next));
                } else {
                    kept.push_back((plan, next));
                }
            } else {
                (duration, next) =
                    Self::plan_window(&path, next, &mut window, |end, complete_only| {
                        time_segments(&path, next, end, duration, complete_only, &mut timing)
                            .map(|timed| (timed.end_time, timed.next))
                    })?;
            }
        }
        let rest = (
            path.start.clone(),
            path.segments.first().map_or(0, |s| s.source_index),
        );
        let (current, next) = match first {
            Some((plan, next)) if !plan.spans.is_empty() => {
                let cursor = Cursor::new(&plan);
                (Some((plan, cursor)), next)
            }
            Some((_, next)) => (None, next),
            None => (None, 0),
        };
        Ok(PlanWindows {
            path,
            window,
            duration,
            kept,
            current,
            next,
            rest,
            first_move,
        })
    }

    /// The path, and the program move it starts with.
    pub fn into_path(self) -> (AxisPath, usize) {
        (self.path, self.first_move)
    }

    /// The plan of the whole chains from segment `first` on (made by `plan_until` from the
    /// segments up to the given end, with or without the last chain, as [`plan_segments`]
    /// makes it), and where the next window starts. A window of `window` segments grows
    /// eightfold until it holds a whole chain (each try is planned in full: a long chain costs
    /// about 8/7 of its planning again), and doubles when less than half of it is kept (the
    /// chain cut off at its end is planned again with the next window), so that no more than
    /// about half the work is repeated.
    fn plan_window<T>(
        path: &AxisPath,
        first: usize,
        window: &mut usize,
        mut plan_until: impl FnMut(usize, bool) -> Result<(T, usize), PathError>,
    ) -> Result<(T, usize), PathError> {
        let count = path.segments.len();
        loop {
            let end = first.saturating_add(*window).min(count);
            let last = end == count;
            let (plan, next) = plan_until(end, !last)?;
            if last {
                return Ok((plan, count));
            }
            if next > first {
                if 2 * (next - first) < end - first {
                    *window = window.saturating_mul(2);
                }
                return Ok((plan, next));
            }
            *window = window.saturating_mul(8);
        }
    }

    /// Total duration (s), the same as [`plan`]'s.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// Moves on to the next window that has spans, if there is one; false at the end (the
    /// current window stays).
    fn advance(&mut self) -> bool {
        let mut time = self.current.as_ref().map_or(0.0, |(p, _)| p.duration);
        while self.next < self.path.segments.len() {
            let window = match self.kept.pop_front() {
                Some(kept) => Ok(kept),
                None => Self::plan_window(
                    &self.path,
                    self.next,
                    &mut self.window,
                    |end, complete_only| {
                        plan_segments(&self.path, self.next, end, time, complete_only)
                    },
                ),
            };
            // The timing pass planned this window from the same inputs without error.
            let (plan, next) =
                window.expect("planning is deterministic: a window planned once plans again");
            self.next = next;
            time = plan.duration;
            if !plan.spans.is_empty() {
                let cursor = Cursor::new(&plan);
                self.current = Some((plan, cursor));
                return true;
            }
        }
        false
    }

    /// As [`Cursor::eval`] on the whole path's plan (times not decreasing).
    pub fn eval(
        &mut self,
        t: f64,
        position: &mut [f64],
        velocity: &mut [f64],
        acceleration: &mut [f64],
    ) -> u32 {
        if self.current.is_none() && !self.advance() {
            position.copy_from_slice(&self.rest.0);
            velocity.fill(0.0);
            acceleration.fill(0.0);
            return self.rest.1;
        }
        // The next window's first span starts where this one ends: move on once `t` is there
        // (as the whole plan's cursor moves on to a span starting at or before `t`).
        while self.current.as_ref().is_some_and(|(p, _)| p.duration <= t)
            && self.next < self.path.segments.len()
        {
            if !self.advance() {
                break;
            }
        }
        let Some((plan, cursor)) = self.current.as_mut() else {
            return self.rest.1;
        };
        cursor.eval(plan, t, position, velocity, acceleration)
    }
}

/// The largest centripetal share any piece in `range` was given.
fn largest_share_used(pieces: &Pieces, range: std::ops::Range<usize>) -> f64 {
    pieces.pieces[range.clone()]
        .iter()
        .zip(&pieces.budgets[range])
        .map(|(p, b)| b.share_of(&p.limits))
        .fold(0.0, f64::max)
}

/// Times chain `c` from `start_time` into `spans` (cleared first); returns its duration.
fn time_chain(
    pieces: &Pieces,
    c: usize,
    drafts: &mut Vec<Draft>,
    start_time: f64,
    spans: &mut Vec<Span>,
) -> Result<f64, PathError> {
    spans.clear();
    group_into_spans(&pieces.pieces, &pieces.chains[c], drafts);
    let speeds = look_ahead(drafts);
    let mut time = start_time;
    for (i, d) in drafts.iter().enumerate() {
        let (recipe, duration) = Recipe::plan_timed(d.length, speeds[i], speeds[i + 1], &d.limits)
            .ok_or(PathError::Infeasible {
                segment: pieces.segment_at(&pieces.pieces[d.first], 0.0),
            })?;
        spans.push(Span {
            first: d.first,
            end: d.end,
            chain: c,
            start: d.start,
            start_time: time,
            recipe,
        });
        time += duration;
    }
    Ok(time - start_time)
}

/// A span before its speeds are known.
#[derive(Debug, Clone, Copy)]
struct Draft {
    first: usize,
    end: usize,
    start: f64,
    length: f64,
    limits: Limits,
}

/// Groups the pieces of a chain into spans of similar limits. A piece much shorter than a
/// neighbour (the sliver of a segment left between two blends) is compared with the lower of
/// its own and its neighbours' limits, so that it does not split a span.
fn group_into_spans(pieces: &[Piece], chain: &Chain, drafts: &mut Vec<Draft>) {
    drafts.clear();
    let chain_pieces = &pieces[chain.first..chain.end];
    let values = |l: Limits| [l.velocity, l.acceleration, l.jerk];
    let effective = |i: usize| {
        let mut v = values(chain_pieces[i].limits);
        let length = chain_pieces[i].length;
        for j in [i.wrapping_sub(1), i + 1] {
            if let Some(n) = chain_pieces.get(j) {
                if length < SHORT_PIECE * n.length {
                    let w = values(n.limits);
                    for k in 0..3 {
                        v[k] = v[k].min(w[k]);
                    }
                }
            }
        }
        v
    };
    // Running minimum and maximum of (v, a, j) over the current span.
    let mut low = [0.0f64; 3];
    let mut high = [0.0f64; 3];
    for (i, piece) in chain_pieces.iter().enumerate() {
        let index = chain.first + i;
        let v = effective(i);
        let joins = drafts.last().is_some()
            && (0..3).all(|k| low[k].min(v[k]) >= (1.0 - SPAN_SPREAD) * high[k].max(v[k]));
        match drafts.last_mut() {
            Some(d) if joins => {
                d.end = index + 1;
                d.length += piece.length;
                for k in 0..3 {
                    low[k] = low[k].min(v[k]);
                    high[k] = high[k].max(v[k]);
                }
            }
            _ => {
                low = v;
                high = v;
                drafts.push(Draft {
                    first: index,
                    end: index + 1,
                    start: piece.start,
                    length: piece.length,
                    limits: piece.limits,
                });
            }
        }
        // The span keeps the lowest actual limits of its pieces.
        let d = drafts.last_mut().expect("a span");
        let l = piece.limits;
        d.limits = Limits::new(
            d.limits.velocity.min(l.velocity),
            d.limits.acceleration.min(l.acceleration),
            d.limits.jerk.min(l.jerk),
        );
    }
}

/// Speeds at the span boundaries of a chain: zero at both ends, capped by both neighbours'
/// speed limits, and reachable from each other within the spans (backward, then forward).
fn look_ahead(drafts: &[Draft]) -> Vec<f64> {
    let m = drafts.len();
    let mut speeds = vec![0.0; m + 1];
    for i in 1..m {
        speeds[i] = drafts[i - 1].limits.velocity.min(drafts[i].limits.velocity);
    }
    // `reachable_velocity(v, ..)` is never below `v` (for `v` within the span's limit, as every
    // boundary speed is), so a boundary no faster than its neighbour keeps its speed without
    // solving for it.
    for i in (1..m).rev() {
        let d = &drafts[i];
        if speeds[i + 1] < speeds[i] {
            speeds[i] = speeds[i].min(reachable_velocity(speeds[i + 1], d.length, &d.limits));
        }
    }
    for i in 0..m.saturating_sub(1) {
        let d = &drafts[i];
        if speeds[i] < speeds[i + 1] {
            speeds[i + 1] = speeds[i + 1].min(reachable_velocity(speeds[i], d.length, &d.limits));
        }
    }
    speeds
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
    if !path.tool_lever_arms.is_empty() {
        check_len(None, path.tool_lever_arms.len())?;
        if !path
            .tool_lever_arms
            .iter()
            .all(|x| x.is_finite() && *x >= 0.0)
        {
            return Err(PathError::InvalidValue {
                segment: None,
                what: "tool lever arm",
            });
        }
    }
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

/// A position in a plan for evaluating it at non-decreasing times: the current span with its
/// profile, the current piece, and scratch space.
#[derive(Debug, Clone)]
pub(super) struct Cursor {
    span: usize,
    profile: Option<Profile>,
    piece: usize,
    scratch: JetScratch,
}

impl Cursor {
    pub fn new(plan: &Plan) -> Self {
        Cursor {
            span: 0,
            profile: None,
            piece: 0,
            scratch: JetScratch::new(plan.axes),
        }
    }

    /// Axis positions, velocities and accelerations at time `t` (not before the previous
    /// call's); returns the program move (`source_index`) the instant belongs to.
    pub fn eval(
        &mut self,
        plan: &Plan,
        t: f64,
        position: &mut [f64],
        velocity: &mut [f64],
        acceleration: &mut [f64],
    ) -> u32 {
        let spans = &plan.spans;
        if spans.is_empty() {
            position.copy_from_slice(&plan.start);
            velocity.fill(0.0);
            acceleration.fill(0.0);
            return plan.source_index.first().copied().unwrap_or(0);
        }
        // Times only grow: walk the spans instead of searching.
        while self.span + 1 < spans.len() && spans[self.span + 1].start_time <= t {
            self.span += 1;
            self.profile = None;
        }
        let span = spans[self.span];
        let end_time = spans
            .get(self.span + 1)
            .map_or(plan.duration, |next| next.start_time);
        let chain = &plan.pieces.chains[span.chain];
        // Past the end of a span only at the end of the plan (otherwise the walk moved on).
        let done = t >= end_time;
        let chain_end = self.span + 1 == spans.len() || spans[self.span + 1].chain != span.chain;
        if done && chain_end {
            // Exactly on the programmed end point, at rest.
            position.copy_from_slice(plan.shapes.end(chain.last_segment));
            velocity.fill(0.0);
            acceleration.fill(0.0);
            return plan.source_index[chain.last_segment];
        }
        let profile = self.profile.get_or_insert_with(|| span.recipe.build());
        let state = profile.state(t - span.start_time);
        let s = span.start + state.position;
        self.piece = self.piece.max(span.first);
        let pieces = &plan.pieces.pieces;
        while self.piece + 1 < span.end && pieces[self.piece + 1].start <= s {
            self.piece += 1;
        }
        let piece = &pieces[self.piece];
        let u = (s - piece.start).clamp(0.0, piece.length);
        plan.eval_piece(
            piece,
            PathPoint::new(u, state.velocity, state.acceleration),
            &mut self.scratch,
            AxisJet::new(position, velocity, acceleration),
        );
        plan.source_index[plan.pieces.segment_at(piece, u)]
    }
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

    /// Where the path starts.
    pub fn start(&self) -> &[f64] {
        &self.start
    }

    /// Evaluates `piece` at `at` (σ measured from the piece's start).
    fn eval_piece(&self, piece: &Piece, at: PathPoint, scratch: &mut JetScratch, out: AxisJet) {
        match piece.kind {
            PieceKind::Segment { segment, from } => self.shapes.eval(
                segment,
                PathPoint {
                    sigma: from + at.sigma,
                    ..at
                },
                out,
            ),
            PieceKind::Corner { blend, data, .. } => {
                blend.eval(&self.pieces.arena[data..data + 3 * self.axes], at, out)
            }
            PieceKind::Tangent(tangent) => tangent.eval(&self.shapes, scratch, at, out),
            PieceKind::Quintic { data, .. } => quintic::eval(
                &self.pieces.arena[data..data + quintic::COEFFICIENTS * self.axes],
                at,
                out,
            ),
        }
    }

    /// The limits each segment is planned with: those of its first piece (zero-length
    /// segments: none, given as 1, 1, 1).
    fn segment_limits(&self) -> Vec<Limits> {
        let mut limits = vec![None; self.shapes.len()];
        for piece in &self.pieces.pieces {
            match piece.kind {
                PieceKind::Segment { segment, .. } => {
                    limits[segment].get_or_insert(piece.limits);
                }
                PieceKind::Quintic { first, count, .. } => {
                    for &segment in &self.pieces.covered[first..first + count] {
                        limits[segment].get_or_insert(piece.limits);
                    }
                }
                _ => {}
            }
        }
        limits
            .into_iter()
            .map(|l| l.unwrap_or(Limits::new(1.0, 1.0, 1.0)))
            .collect()
    }

    /// Where each segment ends: its chain and the chain's path coordinate there (its
    /// programmed end point, or the middle of the blend out of it), `None` at the chain's end;
    /// `None` altogether for segments that do not move.
    fn segment_ends(&self) -> Vec<Option<(usize, Option<f64>)>> {
        let mut ends = vec![None; self.shapes.len()];
        for (c, chain) in self.pieces.chains.iter().enumerate() {
            for piece in &self.pieces.pieces[chain.first..chain.end] {
                let (segment, at) = match piece.kind {
                    PieceKind::Segment { segment, .. } => (segment, piece.start + piece.length),
                    PieceKind::Quintic { first, count, .. } => {
                        // Every segment it runs through ends where the lengths add up to.
                        let mut at = piece.start;
                        for &segment in &self.pieces.covered[first..first + count] {
                            at += self.shapes.shapes[segment].length;
                            ends[segment] = Some((c, Some(at.min(piece.start + piece.length))));
                        }
                        continue;
                    }
                    PieceKind::Corner { incoming, .. } => {
                        (incoming, piece.start + 0.5 * piece.length)
                    }
                    PieceKind::Tangent(t) => (t.incoming, piece.start + 0.5 * piece.length),
                };
                ends[segment] = Some((c, Some(at)));
            }
            ends[chain.last_segment] = Some((c, None));
        }
        ends
    }

    /// Time and path speed ṡ at chain coordinate `s` of chain `chain` (`None`: its end).
    fn crossing(&self, chain: usize, s: Option<f64>) -> (f64, f64) {
        let first = self.spans.partition_point(|sp| sp.chain < chain);
        let end = self.spans.partition_point(|sp| sp.chain <= chain);
        let spans = &self.spans[first..end];
        let Some(s) = s else {
            let last = &spans[spans.len() - 1];
            return (last.start_time + last.recipe.duration(), 0.0);
        };
        let i = spans
            .partition_point(|sp| sp.start + sp.recipe.length <= s)
            .min(spans.len() - 1);
        let span = &spans[i];
        let profile = span.recipe.build();
        let local = profile.time_at((s - span.start).max(0.0));
        (span.start_time + local, profile.state(local).velocity)
    }

    /// Path speed ṡ at every programmed point: the path start, then the end of every segment
    /// (zero at stops; on a blend, the speed of the path coordinate where the blend passes the
    /// corner).
    pub fn junction_speeds(&self) -> Vec<f64> {
        let mut speeds = vec![0.0];
        let mut previous = 0.0;
        for end in self.segment_ends() {
            let v = match end {
                Some((chain, s)) => self.crossing(chain, s).1,
                None => previous,
            };
            speeds.push(v);
            previous = v;
        }
        speeds
    }

    /// Timing of every segment: from the moment the motion passes its start (its programmed
    /// start point, or the middle of the blend into it) to the moment it passes its end.
    pub fn segment_timings(&self) -> Vec<SegmentTiming> {
        let limits = self.segment_limits();
        let mut previous = 0.0;
        self.segment_ends()
            .into_iter()
            .enumerate()
            .map(|(k, end)| {
                let t = match end {
                    Some((chain, s)) => self.crossing(chain, s).0,
                    None => previous,
                };
                let timing = SegmentTiming {
                    source_index: self.source_index[k],
                    start_time: previous,
                    duration: (t - previous).max(0.0),
                    limits: limits[k],
                };
                previous = t;
                timing
            })
            .collect()
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
        let mut cursor = Cursor::new(self);
        cursor.span = self
            .spans
            .partition_point(|s| s.start_time <= t)
            .saturating_sub(1);
        cursor.piece = self.spans.get(cursor.span).map_or(0, |s| s.first);
        cursor.eval(self, t, position, velocity, acceleration)
    }

    /// The trajectory sampled every `period` from t = 0 up to the first tick at or after the
    /// end, where it is exactly at the last programmed point.
    pub fn sample(&self, period: f64) -> Setpoints {
        let n = self.axes;
        let mut out = Setpoints::new(period, n);
        let (mut p, mut v, mut a) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut cursor = Cursor::new(self);
        for t in sample_times(self.duration, period) {
            let segment = cursor.eval(self, t, &mut p, &mut v, &mut a);
            out.push(&p, &v, &a, segment);
        }
        out
    }

    /// The planned path (blends included) as points along each chain, at most `max_step` apart
    /// in the path coordinate and at least four per piece, each with the programmed feed that
    /// holds there: the geometry and speed limit a time-optimal parameterisation of the same
    /// path would follow. `path` is the path this plan was made from ([`plan`]).
    pub fn chain_geometry(&self, path: &AxisPath, max_step: f64) -> Vec<ChainGeometry> {
        assert_eq!(
            path.segments.len(),
            self.source_index.len(),
            "chain_geometry needs the path the plan was made from"
        );
        let n = self.axes;
        let (mut v, mut a) = (vec![0.0; n], vec![0.0; n]);
        let mut scratch = JetScratch::new(n);
        let feed = |k: usize| applied_feed(&path.segments, &self.shapes, k);
        self.pieces
            .chains
            .iter()
            .map(|chain| {
                let mut out = ChainGeometry::default();
                for (i, piece) in self.pieces.pieces[chain.first..chain.end]
                    .iter()
                    .enumerate()
                {
                    // A blend or a smoothing curve is held to the lowest feed of the segments
                    // it joins, as the planner holds it.
                    let piece_feed = match piece.kind {
                        PieceKind::Segment { segment, .. } => feed(segment),
                        PieceKind::Corner {
                            incoming, outgoing, ..
                        } => lowest_feed(feed(incoming), feed(outgoing)),
                        PieceKind::Tangent(t) => lowest_feed(feed(t.incoming), feed(t.outgoing)),
                        PieceKind::Quintic { first, count, .. } => self.pieces.covered
                            [first..first + count]
                            .iter()
                            .map(|&k| feed(k))
                            .fold(None, lowest_feed),
                    };
                    let steps = ((piece.length / max_step).ceil() as usize).clamp(4, 1 << 24);
                    for k in usize::from(i > 0)..=steps {
                        let mut p = vec![0.0; n];
                        let u = piece.length * k as f64 / steps as f64;
                        self.eval_piece(
                            piece,
                            PathPoint::new(u, 0.0, 0.0),
                            &mut scratch,
                            AxisJet::new(&mut p, &mut v, &mut a),
                        );
                        out.points.push(p);
                        let metric = &path.segments[self.pieces.segment_at(piece, u)].feed_metric;
                        out.feeds.push(piece_feed.map(|speed| PointFeed {
                            speed,
                            weights: metric.clone(),
                        }));
                    }
                }
                out
            })
            .collect()
    }
}

/// One chain of a plan's geometry ([`Plan::chain_geometry`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ChainGeometry {
    /// Machine-axis positions along the chain (SI).
    pub points: Vec<Vec<f64>>,
    /// Per point, the programmed feed there; `None` where none applies (a rapid, or a move its
    /// feed metric does not measure): as fast as the axes allow.
    pub feeds: Vec<Option<PointFeed>>,
}

/// The programmed path speed at a point: `|W·q̇| ≤ speed`, `W` the per-axis weights of the
/// feed metric (e.g. 1 on X, Y, Z and 0 on the rotary axes of a move with linear motion).
#[derive(Debug, Clone, PartialEq)]
pub struct PointFeed {
    pub speed: f64,
    pub weights: Vec<f64>,
}

impl Plan {
    #[doc(hidden)]
    pub fn debug_dump(&self) -> String {
        let mut out = String::new();
        for (c, chain) in self.pieces.chains.iter().enumerate() {
            out.push_str(&format!(
                "chain {c}: pieces {}..{} last seg {}\n",
                chain.first, chain.end, chain.last_segment
            ));
        }
        for p in &self.pieces.pieces {
            out.push_str(&format!(
                "  piece {:?} start {:.6} len {:.6} lim v {:.4} a {:.3} j {:.1}\n",
                match p.kind {
                    PieceKind::Segment { segment, .. } => format!("S{segment}"),
                    PieceKind::Corner { incoming, .. } => format!("C{incoming}"),
                    PieceKind::Tangent(t) => format!("T{}", t.incoming),
                    PieceKind::Quintic { first, .. } => format!("Q{}", self.pieces.covered[first]),
                },
                p.start,
                p.length,
                p.limits.velocity,
                p.limits.acceleration,
                p.limits.jerk
            ));
        }
        for s in &self.spans {
            out.push_str(&format!("span chain {} pieces {}..{} start {:.6} t {:.4} len {:.6} v0 {:.4} peak {:.4} v1 {:.4} dur {:.4}\n", s.chain, s.first, s.end, s.start, s.start_time, s.recipe.length, s.recipe.v_start, s.recipe.peak, s.recipe.v_end, s.recipe.duration()));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::path::{AxisKind, AxisLimits, AxisSpec, PathSegment};

    /// Lines with sharp corners (stops), gentle corners (blends), a smoothed run, a tangent arc,
    /// a zero-length segment and an exact stop, in a few hundred segments.
    fn mixed_path() -> AxisPath {
        let axes = (0..3)
            .map(|i| AxisSpec {
                name: format!("q{i}"),
                kind: AxisKind::Linear,
                limits: AxisLimits {
                    velocity: 0.2,
                    acceleration: 2.0,
                    jerk: 50.0 + 10.0 * i as f64,
                },
            })
            .collect();
        let blend = Blend::Continuous {
            tolerance: Some(5e-5),
        };
        let mut segments = Vec::new();
        let mut at = [0.0f64; 3];
        let push = |geometry: Geometry, blend: Blend, segments: &mut Vec<PathSegment>| {
            let index = segments.len() as u32;
            segments.push(PathSegment {
                geometry,
                feed: Some(0.1),
                feed_metric: vec![1.0; 3],
                blend,
                source_index: index,
            });
        };
        for k in 0..300 {
            let kind = k % 40;
            let step = match kind {
                // A sharp reversal: a stop.
                0 => [-1e-3, 2e-4, 0.0],
                // A short run on a smooth curve.
                1..=15 => {
                    let x = k as f64 * 0.1;
                    [1e-3, 0.0, 1e-4 * x.sin()]
                }
                // Gentle corners.
                16..=30 => [1e-3, if k % 2 == 0 { 2e-4 } else { -2e-4 }, 0.0],
                _ => [2e-3, 0.0, 0.0],
            };
            let end: Vec<f64> = (0..3).map(|i| at[i] + step[i]).collect();
            let mode = if kind == 33 { Blend::ExactStop } else { blend };
            push(Geometry::Line { end: end.clone() }, mode, &mut segments);
            if kind == 35 {
                // Nothing moves.
                push(Geometry::Line { end: end.clone() }, blend, &mut segments);
            }
            if kind == 37 {
                // A tangent quarter arc (the line runs along +x; the centre is to the left).
                let center = [end[0], end[1] + 2e-3];
                let arc_end = vec![end[0] + 2e-3, end[1] + 2e-3, end[2]];
                push(
                    Geometry::Arc {
                        plane: [0, 1],
                        center,
                        clockwise: false,
                        turns: 0,
                        end: arc_end.clone(),
                    },
                    blend,
                    &mut segments,
                );
                at.copy_from_slice(&arc_end);
                continue;
            }
            at.copy_from_slice(&end);
        }
        AxisPath {
            axes,
            start: vec![0.0; 3],
            segments,
            tool_lever_arms: Vec::new(),
        }
    }

    #[test]
    fn windows_evaluate_bit_identically_to_the_whole_plan() {
        let path = mixed_path();
        let whole = plan(&path).unwrap();
        assert!(
            whole.pieces.chains.len() > 10,
            "{}",
            whole.pieces.chains.len()
        );
        let period = 1e-3;
        let expected = whole.sample(period);
        let n = path.axes.len();
        // Windows planned again as they are evaluated, and kept from the timing pass.
        for (window, most) in [1, 2, 3, 7, 64, 10_000]
            .into_iter()
            .flat_map(|w| [(w, 0), (w, usize::MAX)])
        {
            let mut windows = PlanWindows::keeping(path.clone(), window, 0, most).unwrap();
            assert_eq!(windows.duration().to_bits(), whole.duration().to_bits());
            let (mut p, mut v, mut a) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            for (k, t) in sample_times(whole.duration(), period).enumerate() {
                let segment = windows.eval(t, &mut p, &mut v, &mut a);
                let row = k * n..(k + 1) * n;
                assert_eq!(segment, expected.segment[k], "window {window} sample {k}");
                assert_eq!(
                    p,
                    expected.position[row.clone()],
                    "window {window} sample {k}"
                );
                assert_eq!(
                    v,
                    expected.velocity[row.clone()],
                    "window {window} sample {k}"
                );
                assert_eq!(a, expected.acceleration[row], "window {window} sample {k}");
            }
        }
    }

    #[test]
    fn windows_of_a_path_that_does_not_move_hold_its_start() {
        let mut path = mixed_path();
        path.segments.truncate(3);
        for s in &mut path.segments {
            s.geometry = Geometry::Line {
                end: path.start.clone(),
            };
        }
        let whole = plan(&path).unwrap();
        let mut windows = PlanWindows::new(path.clone(), 1, 0).unwrap();
        let (mut p, mut v, mut a) = (vec![1.0; 3], vec![1.0; 3], vec![1.0; 3]);
        let (mut q, mut w, mut b) = (vec![1.0; 3], vec![1.0; 3], vec![1.0; 3]);
        let segment = windows.eval(0.0, &mut p, &mut v, &mut a);
        assert_eq!(segment, whole.eval(0.0, &mut q, &mut w, &mut b));
        assert_eq!((p, v, a), (q, w, b));
    }
}
