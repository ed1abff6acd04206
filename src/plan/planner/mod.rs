//! The jerk-limited look-ahead planner: a machine-axis path in, a timed trajectory out.
//!
//! 1. Geometry (`plan::pieces`): the path becomes chains of pieces between stops: segment
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
//! 5. Windows: the look-ahead reaches [`LOOKAHEAD_SEGMENTS`] segments. A chain that ends within
//!    the window it starts in (that many segments from the end of the previous chain, zero-length
//!    segments between them included) is planned whole, as above. A longer one is planned that
//!    many segments at a time, each window as if the chain stopped at its end, and handed over
//!    to the next window between one half and three quarters of the way in, at the start of a
//!    piece passed at zero path acceleration (a span boundary, a cruise, or a speed change
//!    planned again to end there). The next window builds its geometry from a margin before the
//!    handoff with the smoothing choices there frozen (`Seed`); a handoff is
//!    made only once that window, planned in full, holds the very same piece and can go on from
//!    the handoff's speed (else other places are tried, then the speeds the next window admits);
//!    if none can, the window stops at its last point (counted in
//!    [`LookAhead::stops_added`]). The geometry is continuous across every handoff, and a run's
//!    planning memory (`PlanWindows`, which reads the path as it is made) is bounded by the
//!    look-ahead, whatever the program; [`plan`] keeps every window, for inspection. Past a
//!    handoff a window chooses the smoothing of the lines itself: which lines can be smoothed
//!    depends on their neighbours (greedily, see `pieces`), so a choice can come out otherwise
//!    than with an unbounded look-ahead, always within the tolerance.
//!
//! Every chain ends exactly on its programmed end point; the programmed points inside a chain
//! are passed within the corner tolerance (through them, on a tangent blend).

use super::geometry::{AxisJet, Metric, PathPoint, Shapes};
use super::path::{AxisPath, PathError};
use super::path_reader::{validate, PathReader};
use super::pieces::{
    applied_feed, assign_limits, lowest_feed, Builder, Chain, Piece, PieceKind, Pieces, Seed,
    SHARE_CAPS,
};
use super::profile::{reachable_velocity, transfer_distance, Limits, Profile, Recipe};
use super::quintic;
use super::setpoints::{sample_times, LookAhead, Setpoints};
use super::tangent::{JetScratch, TangentBlend};

mod lookahead;
mod window;

pub use lookahead::LOOKAHEAD_SEGMENTS;
use lookahead::*;
pub(super) use lookahead::{PlanWindows, KEPT_SEGMENTS, WINDOW_SEGMENTS};

/// Pieces whose speed, acceleration and jerk limits each lie within this fraction of one
/// another are timed as one span (with the lowest of them).
pub const SPAN_SPREAD: f64 = 0.05;

/// A piece shorter than this fraction of a neighbour does not split a span by itself.
const SHORT_PIECE: f64 = 0.25;

/// A timed trajectory over a whole path: the parts its windows planned, one after the other
/// (a run plans the same windows as it reads them).
#[derive(Debug, Clone)]
pub struct Plan {
    axes: usize,
    start: Vec<f64>,
    /// Per path segment, the program move it comes from.
    source_index: Vec<u32>,
    parts: Vec<Part>,
}

/// The plan of one window of a path: its whole chains, or a stretch of a chain longer than
/// the look-ahead, from its start or a handoff to the next handoff.
#[derive(Debug, Clone)]
struct Part {
    axes: usize,
    shapes: Shapes,
    pieces: Pieces,
    spans: Vec<Span>,
    source_index: Vec<u32>,
    /// The path segment the window's first segment is.
    first_segment: usize,
    /// Where the window's first segment starts.
    start: Vec<f64>,
    /// When its last span ends.
    duration: f64,
    /// How its last chain ends: at a stop, handed over to the next part while moving, or
    /// stopping at the window's last point where no handoff could be made.
    end: WindowEnd,
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
    /// Index of the program move the segment comes from.
    pub source_index: u32,
    /// When the motion is at the segment's start (s): its programmed start point, or the
    /// middle of the blend into it.
    pub start_time: f64,
    /// Time from passing its start to passing its end (s).
    pub duration: f64,
    /// Path limits of the segment on its own (its line or arc limits).
    pub limits: Limits,
}

/// Plans a path. See the module documentation for the method.
pub fn plan(path: &AxisPath) -> Result<Plan, PathError> {
    plan_with_lookahead(path, LOOKAHEAD_SEGMENTS)
}

/// [`plan`] with a look-ahead of `segments` (at least 128) instead of
/// [`LOOKAHEAD_SEGMENTS`]: for measuring what the look-ahead costs (a look-ahead longer than
/// the path plans every chain whole).
#[doc(hidden)]
pub fn plan_with_lookahead(path: &AxisPath, segments: usize) -> Result<Plan, PathError> {
    plan_at_depth(path, Depth::of(segments))
}

/// [`plan`] at a look-ahead `depth`.
fn plan_at_depth(path: &AxisPath, depth: Depth) -> Result<Plan, PathError> {
    validate(path)?;
    let mut reader = PathReader::Whole(path);
    let mut windows = Windows::new(WINDOW_SEGMENTS, depth);
    let mut parts = Vec::new();
    while let Some(part) = windows.next_part(&mut reader)? {
        parts.push(part);
    }
    Ok(Plan {
        axes: path.axes.len(),
        start: path.start.clone(),
        source_index: path.segments.iter().map(|s| s.source_index).collect(),
        parts,
    })
}

/// A position in a part for evaluating it at non-decreasing times: the current span with its
/// profile, the current piece, and scratch space.
#[derive(Debug, Clone)]
pub(super) struct Cursor {
    span: usize,
    profile: Option<Profile>,
    piece: usize,
    scratch: JetScratch,
}

impl Cursor {
    fn new(part: &Part) -> Self {
        Cursor {
            span: 0,
            profile: None,
            piece: 0,
            scratch: JetScratch::new(part.axes),
        }
    }

    /// Axis positions, velocities and accelerations at time `t` (not before the previous
    /// call's); returns the program move (`source_index`) the instant belongs to.
    fn eval(
        &mut self,
        part: &Part,
        t: f64,
        position: &mut [f64],
        velocity: &mut [f64],
        acceleration: &mut [f64],
    ) -> u32 {
        let spans = &part.spans;
        if spans.is_empty() {
            position.copy_from_slice(&part.start);
            velocity.fill(0.0);
            acceleration.fill(0.0);
            return part.source_index.first().copied().unwrap_or(0);
        }
        // Times only grow: walk the spans instead of searching.
        while self.span + 1 < spans.len() && spans[self.span + 1].start_time <= t {
            self.span += 1;
            self.profile = None;
        }
        let span = spans[self.span];
        let end_time = spans
            .get(self.span + 1)
            .map_or(part.duration, |next| next.start_time);
        let chain = &part.pieces.chains[span.chain];
        // Past the end of a span only at the end of the plan (otherwise the walk moved on).
        let done = t >= end_time;
        let chain_end = self.span + 1 == spans.len() || spans[self.span + 1].chain != span.chain;
        let handed_off = part.handed_off() && span.chain + 1 == part.pieces.chains.len();
        if done && chain_end && !handed_off {
            // Exactly on the programmed end point, at rest.
            position.copy_from_slice(part.shapes.end(chain.last_segment));
            velocity.fill(0.0);
            acceleration.fill(0.0);
            return part.source_index[chain.last_segment];
        }
        let profile = self.profile.get_or_insert_with(|| span.recipe.build());
        let state = profile.state(t - span.start_time);
        let s = span.start + state.position;
        self.piece = self.piece.max(span.first);
        let pieces = &part.pieces.pieces;
        while self.piece + 1 < span.end && pieces[self.piece + 1].start <= s {
            self.piece += 1;
        }
        let piece = &pieces[self.piece];
        let u = (s - piece.start).clamp(0.0, piece.length);
        part.eval_piece(
            piece,
            PathPoint::new(u, state.velocity, state.acceleration),
            &mut self.scratch,
            AxisJet::new(position, velocity, acceleration),
        );
        part.source_index[part.pieces.segment_at(piece, u)]
    }
}

impl Part {
    /// Its last chain runs on in the next part.
    fn handed_off(&self) -> bool {
        matches!(self.end, WindowEnd::HandedOff { .. })
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

    /// The pieces of each chain this part plans (after a handoff from its piece on, before one
    /// up to it).
    fn chains(&self) -> impl Iterator<Item = (usize, &[Piece])> {
        self.pieces
            .chains
            .iter()
            .enumerate()
            .map(|(c, chain)| (c, &self.pieces.pieces[chain.first..chain.end]))
    }

    /// Per segment of the window, the limits it is planned with here: those of its first
    /// piece (`None` for a segment with no piece in this part).
    fn segment_limits(&self) -> Vec<Option<Limits>> {
        let mut limits = vec![None; self.shapes.len()];
        for (_, pieces) in self.chains() {
            for piece in pieces {
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
        }
        limits
    }

    /// Per segment of the window, where it ends in this part: its chain and the chain's path
    /// coordinate there (its programmed end point, or the middle of the blend out of it),
    /// `None` at the chain's end; `None` altogether for segments that do not move or end in
    /// another part.
    fn segment_ends(&self) -> Vec<Option<(usize, Option<f64>)>> {
        let mut ends = vec![None; self.shapes.len()];
        let last = self.pieces.chains.len().saturating_sub(1);
        for (c, pieces) in self.chains() {
            for piece in pieces {
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
            if !(self.handed_off() && c == last) {
                ends[self.pieces.chains[c].last_segment] = Some((c, None));
            }
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

    /// Axis positions, velocities and accelerations at time `t` (clamped to the part).
    fn eval(
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

    /// Chain `chain`'s geometry ([`Plan::chain_geometry`]); `path` is the path planned.
    fn chain_geometry(&self, path: &AxisPath, chain: usize, max_step: f64) -> ChainGeometry {
        let n = self.axes;
        let (mut v, mut a) = (vec![0.0; n], vec![0.0; n]);
        let mut scratch = JetScratch::new(n);
        let segments = &path.segments[self.first_segment..self.first_segment + self.shapes.len()];
        let feed = |k: usize| applied_feed(segments, &self.shapes, k);
        let chain = self.pieces.chains[chain];
        let mut out = ChainGeometry::default();
        for (i, piece) in self.pieces.pieces[chain.first..chain.end]
            .iter()
            .enumerate()
        {
            // A blend or a smoothing curve is held to the lowest feed of the segments it
            // joins, as the planner holds it.
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
                let metric = &segments[self.pieces.segment_at(piece, u)].feed_metric;
                out.feeds.push(piece_feed.map(|speed| PointFeed {
                    speed,
                    weights: metric.clone(),
                }));
            }
        }
        out
    }
}

impl Plan {
    /// Number of machine axes.
    pub fn axes(&self) -> usize {
        self.axes
    }

    /// Total duration (s), exact (not rounded to a servo period).
    pub fn duration(&self) -> f64 {
        self.parts.last().map_or(0.0, |p| p.duration)
    }

    /// Where the path starts.
    pub fn start(&self) -> &[f64] {
        &self.start
    }

    /// Number of chains (stretches between stops; a chain handed over between windows counts
    /// once).
    pub fn chain_count(&self) -> usize {
        let chains: usize = self.parts.iter().map(|p| p.pieces.chains.len()).sum();
        chains - self.look_ahead().handoffs
    }

    /// What the look-ahead did with chains longer than [`LOOKAHEAD_SEGMENTS`]: its handoffs
    /// (slowed or not) and the stops it added, as a run's stream reports them.
    pub fn look_ahead(&self) -> LookAhead {
        let mut look_ahead = LookAhead::default();
        for part in &self.parts {
            look_ahead.count(part.end);
        }
        look_ahead
    }

    /// Most segments any window of the plan holds (at most [`LOOKAHEAD_SEGMENTS`]).
    pub fn largest_window(&self) -> usize {
        self.parts.iter().map(|p| p.shapes.len()).max().unwrap_or(0)
    }

    /// The parts that move, in order.
    fn moving_parts(&self) -> impl Iterator<Item = &Part> {
        self.parts.iter().filter(|p| !p.spans.is_empty())
    }

    /// Per path segment: its limits (its first piece's; zero-length segments: none, given as
    /// 1, 1, 1), and the part, chain and chain coordinate where it ends
    /// ([`Part::segment_ends`]).
    #[allow(clippy::type_complexity)]
    fn segment_data(&self) -> (Vec<Limits>, Vec<Option<(usize, usize, Option<f64>)>>) {
        let count = self.source_index.len();
        let mut limits = vec![None; count];
        let mut ends = vec![None; count];
        for (p, part) in self.parts.iter().enumerate() {
            let at = part.first_segment;
            for (k, l) in part.segment_limits().into_iter().enumerate() {
                if let Some(l) = l {
                    limits[at + k].get_or_insert(l);
                }
            }
            for (k, end) in part.segment_ends().into_iter().enumerate() {
                if let Some((c, s)) = end {
                    ends[at + k] = Some((p, c, s));
                }
            }
        }
        let limits = limits
            .into_iter()
            .map(|l| l.unwrap_or(Limits::new(1.0, 1.0, 1.0)))
            .collect();
        (limits, ends)
    }

    /// Path speed ṡ at every programmed point: the path start, then the end of every segment
    /// (zero at stops; on a blend, the speed of the path coordinate where the blend passes the
    /// corner).
    pub fn junction_speeds(&self) -> Vec<f64> {
        let mut speeds = vec![0.0];
        let mut previous = 0.0;
        for end in self.segment_data().1 {
            let v = match end {
                Some((p, chain, s)) => self.parts[p].crossing(chain, s).1,
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
        let (limits, ends) = self.segment_data();
        let mut previous = 0.0;
        ends.into_iter()
            .enumerate()
            .map(|(k, end)| {
                let t = match end {
                    Some((p, chain, s)) => self.parts[p].crossing(chain, s).0,
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
        // As a run moves on: to the next part once `t` is where it starts.
        let after = self.parts.partition_point(|p| p.duration <= t);
        let part = self.parts[after..]
            .iter()
            .find(|p| !p.spans.is_empty())
            .or_else(|| self.moving_parts().last());
        match part {
            Some(part) => part.eval(t, position, velocity, acceleration),
            None => {
                position.copy_from_slice(&self.start);
                velocity.fill(0.0);
                acceleration.fill(0.0);
                self.source_index.first().copied().unwrap_or(0)
            }
        }
    }

    /// The trajectory sampled every `period` from t = 0 up to the first tick at or after the
    /// end, where it is exactly at the last programmed point.
    pub fn sample(&self, period: f64) -> Setpoints {
        let n = self.axes;
        let mut out = Setpoints::new(period, n);
        let (mut p, mut v, mut a) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let moving: Vec<&Part> = self.moving_parts().collect();
        let mut k = 0;
        let mut cursor = moving.first().map(|part| Cursor::new(part));
        for t in sample_times(self.duration(), period) {
            let segment = match cursor.as_mut() {
                Some(cursor) => {
                    while moving[k].duration <= t && k + 1 < moving.len() {
                        k += 1;
                        *cursor = Cursor::new(moving[k]);
                    }
                    cursor.eval(moving[k], t, &mut p, &mut v, &mut a)
                }
                None => self.eval(t, &mut p, &mut v, &mut a),
            };
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
        let mut out: Vec<ChainGeometry> = Vec::new();
        let mut continued = false;
        for part in &self.parts {
            for c in 0..part.pieces.chains.len() {
                let geometry = part.chain_geometry(path, c, max_step);
                match out.last_mut() {
                    // A chain handed over goes on from its handoff point (already there).
                    Some(last) if c == 0 && continued => {
                        last.points.extend(geometry.points.into_iter().skip(1));
                        last.feeds.extend(geometry.feeds.into_iter().skip(1));
                    }
                    _ => out.push(geometry),
                }
            }
            continued = part.handed_off();
        }
        out
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
    /// The programmed path speed (SI, in the feed metric: m/s for linear motion).
    pub speed: f64,
    /// `W`: the feed metric's weight per machine axis.
    pub weights: Vec<f64>,
}

impl Plan {
    #[doc(hidden)]
    pub fn debug_dump(&self) -> String {
        let mut out = String::new();
        for (i, part) in self.parts.iter().enumerate() {
            out.push_str(&format!(
                "part {i}: segments from {}, handed off {}\n",
                part.first_segment,
                part.handed_off()
            ));
            out.push_str(&part.debug_dump());
        }
        out
    }
}

impl Part {
    fn debug_dump(&self) -> String {
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
    use crate::plan::path::{AxisKind, AxisLimits, AxisSpec, Blend, Geometry, PathSegment};
    use crate::plan::path_reader::SegmentSource;
    use std::sync::Arc;

    /// A path's segments made again one by one, as a program's are.
    #[derive(Debug, Clone)]
    struct Replay {
        segments: Arc<Vec<PathSegment>>,
        next: usize,
    }

    impl<'a> SegmentSource<'a> for Replay {
        fn next_segment(&mut self) -> Option<PathSegment> {
            let segment = self.segments.get(self.next).cloned();
            self.next += 1;
            segment
        }

        fn restart(&self) -> Box<dyn SegmentSource<'a> + 'a> {
            Box::new(Replay {
                next: 0,
                ..self.clone()
            })
        }
    }

    /// `path` read as a whole, and made as it is read.
    fn readers(path: &AxisPath) -> [PathReader<'static>; 2] {
        let header = AxisPath {
            segments: Vec::new(),
            ..path.clone()
        };
        let replay = Replay {
            segments: Arc::new(path.segments.clone()),
            next: 0,
        };
        [
            PathReader::Shared(Arc::new(path.clone())),
            PathReader::streamed(header, Box::new(replay)).unwrap(),
        ]
    }

    /// Lines with sharp corners (stops), gentle corners (blends), a smoothed run, a tangent arc,
    /// a zero-length segment and an exact stop, in a few hundred segments; without `stops`, a
    /// gentle corner, a blend and a line instead of the stops and the arc: one chain.
    fn mixed_path(stops: bool) -> AxisPath {
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
                0 if stops => [-1e-3, 2e-4, 0.0],
                0 => [1e-3, 1e-4, 0.0],
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
            let mode = if kind == 33 && stops {
                Blend::ExactStop
            } else {
                blend
            };
            push(Geometry::Line { end: end.clone() }, mode, &mut segments);
            if kind == 35 {
                // Nothing moves.
                push(Geometry::Line { end: end.clone() }, blend, &mut segments);
            }
            if kind == 37 && stops {
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
        // Many chains; one chain handed over between windows of a short look-ahead; and the
        // same chain stopped at the end of each window where no handoff is allowed.
        let no_handoffs = Depth {
            handoff_tries: 0,
            ..Depth::of(128)
        };
        for (path, depth) in [
            (mixed_path(true), Depth::of(LOOKAHEAD_SEGMENTS)),
            (mixed_path(false), Depth::of(128)),
            (mixed_path(false), no_handoffs),
        ] {
            let lookahead = depth.segments;
            let whole = plan_at_depth(&path, depth).unwrap();
            let look_ahead = whole.look_ahead();
            if lookahead == LOOKAHEAD_SEGMENTS {
                assert!(whole.chain_count() > 10, "{}", whole.chain_count());
            } else if depth.handoff_tries > 0 {
                assert_eq!(whole.chain_count(), 1);
                assert!(look_ahead.handoffs >= 2, "{look_ahead:?}");
                assert_eq!(look_ahead.stops_added, 0);
                assert!(whole.largest_window() <= lookahead);
            } else {
                assert_eq!(look_ahead.handoffs, 0);
                assert!(look_ahead.stops_added >= 2, "{look_ahead:?}");
                assert_eq!(whole.chain_count(), 1 + look_ahead.stops_added);
            }
            let period = 1e-3;
            let expected = whole.sample(period);
            let n = path.axes.len();
            // Windows planned again as they are evaluated, and kept from the timing pass; the
            // path whole, or made as it is read.
            for (window, most, streamed) in [1, 2, 3, 7, 64, 10_000]
                .into_iter()
                .flat_map(|w| [(w, 0), (w, usize::MAX)])
                .flat_map(|(w, most)| [(w, most, false), (w, most, true)])
            {
                let [whole_reader, streamed_reader] = readers(&path);
                let reader = if streamed {
                    streamed_reader
                } else {
                    whole_reader
                };
                let mut budget = most;
                let mut windows =
                    PlanWindows::keeping(reader, window, 0, &mut budget, depth).unwrap();
                assert_eq!(windows.duration().to_bits(), whole.duration().to_bits());
                let (mut p, mut v, mut a) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
                for (k, t) in sample_times(whole.duration(), period).enumerate() {
                    let segment = windows.eval(t, &mut p, &mut v, &mut a);
                    let row = k * n..(k + 1) * n;
                    let what = format!("{depth:?} window {window} streamed {streamed} sample {k}");
                    assert_eq!(segment, expected.segment[k], "{what}");
                    assert_eq!(p, expected.position[row.clone()], "{what}");
                    assert_eq!(v, expected.velocity[row.clone()], "{what}");
                    assert_eq!(a, expected.acceleration[row], "{what}");
                }
                let end = path.segments.last().unwrap();
                assert_eq!(windows.end(), (end.geometry.end(), end.source_index));
            }
        }
    }

    #[test]
    fn a_long_chain_that_cannot_be_handed_over_stops_at_the_end_of_each_window() {
        let path = mixed_path(false);
        let depth = Depth {
            handoff_tries: 0,
            ..Depth::of(128)
        };
        let windowed = plan_at_depth(&path, depth).unwrap();
        let whole = plan_with_lookahead(&path, usize::MAX).unwrap();
        assert_eq!(whole.chain_count(), 1);
        // Each window stops at its last programmed point, at rest, and nowhere else.
        let stops: Vec<usize> = windowed
            .parts
            .iter()
            .filter(|p| p.end == WindowEnd::StopsShort)
            .map(|p| p.first_segment + p.shapes.len())
            .collect();
        assert_eq!(stops.len(), windowed.look_ahead().stops_added);
        assert!(stops.len() >= 2, "{stops:?}");
        let speeds = windowed.junction_speeds();
        for (k, (v, w)) in speeds.iter().zip(whole.junction_speeds()).enumerate() {
            if stops.contains(&k) {
                assert_eq!(*v, 0.0, "point {k}");
            } else {
                assert!(
                    *v > 0.0 || w == 0.0,
                    "point {k}: stops, the whole plan does not"
                );
            }
        }
        let n = path.axes.len();
        let (mut p, mut v, mut a) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for part in windowed
            .parts
            .iter()
            .filter(|p| p.end == WindowEnd::StopsShort)
        {
            windowed.eval(part.duration, &mut p, &mut v, &mut a);
            let last = &path.segments[part.first_segment + part.shapes.len() - 1];
            assert_eq!(p, last.geometry.end(), "at {} s", part.duration);
            assert!(v.iter().chain(&a).all(|x| x.abs() < 1e-12), "{v:?} {a:?}");
        }
        // Every axis limit kept (third differences of the samples) and the stops cost time.
        let period = 2e-4;
        let samples = windowed.sample(period);
        let mut differences = crate::plan::FiniteDifferences::new(n, period);
        for k in 0..samples.len() {
            differences.push(samples.position(k));
        }
        for (e, axis) in differences.extremes().iter().zip(&path.axes) {
            let l = axis.limits;
            assert!(e.velocity <= l.velocity * (1.0 + 1e-9), "{e:?}");
            assert!(e.acceleration <= l.acceleration * (1.0 + 1e-6), "{e:?}");
            assert!(e.jerk <= l.jerk * (1.0 + 1e-3), "{e:?}");
        }
        assert!(windowed.duration() > whole.duration());
    }

    #[test]
    fn windows_of_a_path_that_does_not_move_hold_its_start() {
        let mut path = mixed_path(true);
        path.segments.truncate(3);
        for s in &mut path.segments {
            s.geometry = Geometry::Line {
                end: path.start.clone(),
            };
        }
        let whole = plan(&path).unwrap();
        let [_, reader] = readers(&path);
        let mut windows = PlanWindows::new(reader, 1, 0, &mut KEPT_SEGMENTS.clone()).unwrap();
        let (mut p, mut v, mut a) = (vec![1.0; 3], vec![1.0; 3], vec![1.0; 3]);
        let (mut q, mut w, mut b) = (vec![1.0; 3], vec![1.0; 3], vec![1.0; 3]);
        let segment = windows.eval(0.0, &mut p, &mut v, &mut a);
        assert_eq!(segment, whole.eval(0.0, &mut q, &mut w, &mut b));
        assert_eq!((p, v, a), (q, w, b));
    }
}
