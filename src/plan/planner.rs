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

/// The working buffers of [`time_segments`]: the spans it times, and the scratch space of its
/// chains. [`Windows`] keeps one for all its windows, so that each window reuses the previous
/// one's allocations.
#[derive(Debug, Default)]
struct Timing {
    /// The spans of every chain timed, in order.
    spans: Vec<Span>,
    drafts: Vec<Draft>,
    /// The spans of the share cap being tried, and of the fastest so far, with its limits.
    trial: Vec<Span>,
    best: Vec<Span>,
    best_limits: Vec<Limits>,
    scratch: Vec<f64>,
}

/// What [`time_segments`] built and found besides the spans.
#[derive(Debug)]
struct Timed {
    shapes: Shapes,
    pieces: Pieces,
    /// When the last chain timed ends.
    end_time: f64,
    /// The segment after the last chain timed.
    next: usize,
    /// The window holds one chain, which runs on past it: a stretch, to be handed over
    /// inside it.
    stretch: bool,
}

impl LookAhead {
    /// Counts a window that ends so.
    fn count(&mut self, end: WindowEnd) {
        match end {
            WindowEnd::Stop => {}
            WindowEnd::HandedOff { slowed } => {
                self.handoffs += 1;
                self.slowed += usize::from(slowed);
            }
            WindowEnd::StopsShort => self.stops_added += 1,
        }
    }
}

/// How a window's last chain ends.
#[derive(Debug, Clone, Copy, PartialEq)]
enum WindowEnd {
    /// At a stop the program asks for (or the path's end).
    Stop,
    /// Handed over to the next window while moving; `slowed`: more slowly than this window
    /// planned, at the speed the next one admits.
    HandedOff { slowed: bool },
    /// At the window's last point, stopping there although the chain goes on (no handoff
    /// could be taken over).
    StopsShort,
}

/// Which chains of a window [`time_segments`] times.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Ending {
    /// The window reaches the path's end: all.
    PathEnd,
    /// All but the last, which may run on past the window (the next window plans it).
    Complete,
    /// As `Complete`, unless the last is the only one: then it is timed as a stretch, up to
    /// the window's end.
    CompleteOrStretch,
}

/// Why a window could not be timed.
#[derive(Debug)]
enum WindowError {
    Path(PathError),
    /// The handoff it starts from is not among the window's pieces (its geometry differs).
    Unmatched,
    /// The window cannot go on from the handoff's speed under any share cap: the fastest entry
    /// one of them admits where that was what failed (zero: none).
    Handoff {
        admissible: f64,
    },
}

impl From<PathError> for WindowError {
    fn from(error: PathError) -> Self {
        WindowError::Path(error)
    }
}

/// Times segments `first..end` of a path (validated; its segment `k` is `path`'s `k - base`,
/// and `path.start` the point before segment `base`), its first chain starting at
/// `start_time` (after `entry`, from the handoff's piece on at the handoff's speed); the
/// spans go to `timing.spans` (cleared first), the chains `ending` says.
///
/// A chain's pieces depend only on its own segments and the shapes of the two segments around
/// it (every junction, blend and smoothing curve looks no further, and none crosses a stop),
/// so the whole chains timed here are exactly those of any window that holds them.
#[allow(clippy::too_many_arguments)]
fn time_segments(
    path: &AxisPath,
    base: usize,
    first: usize,
    end: usize,
    start_time: f64,
    ending: Ending,
    entry: Option<&Handoff>,
    timing: &mut Timing,
) -> Result<Timed, WindowError> {
    let segments = &path.segments[first - base..end - base];
    let start = point_before(path, base, first);
    let shapes = Shapes::new(start, segments, &path.axes).map_err(|e| e.offset(first))?;
    let metric = Metric::new(&path.axes, &path.tool_lever_arms);
    let seed = entry.map(|handoff| &handoff.seed);
    let mut pieces = Builder::new(&path.axes, segments, &shapes, &metric).build(seed);
    let entry_speed = match entry {
        Some(handoff) => {
            let (c, q) = handoff
                .find(&pieces, first, path.axes.len())
                .ok_or(WindowError::Unmatched)?;
            pieces.chains.drain(..c);
            pieces.chains[0].first = q;
            Some(handoff.speed)
        }
        None => None,
    };
    let mut stretch = false;
    let next = match ending {
        Ending::PathEnd => end,
        // Nothing moves in a window this long: it is complete.
        Ending::CompleteOrStretch if pieces.chains.is_empty() => end,
        Ending::CompleteOrStretch if pieces.chains.len() == 1 => {
            stretch = true;
            end
        }
        Ending::Complete | Ending::CompleteOrStretch => {
            pieces.chains.pop();
            pieces
                .chains
                .last()
                .map_or(first, |c| first + c.last_segment + 1)
        }
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
        let entry = if c == 0 { entry_speed } else { None };
        // The fastest of the share caps. A smaller cap changes nothing when no piece used more
        // than it.
        let mut fastest = f64::INFINITY;
        // The fastest entry any cap admits, where none admits the handoff's speed.
        let mut admissible: f64 = 0.0;
        for (k, &cap) in SHARE_CAPS.iter().enumerate() {
            if k > 0 && largest_share_used(&pieces, range.clone()) <= cap {
                break;
            }
            assign_limits(
                &mut pieces.pieces[range.clone()],
                &pieces.budgets[range.clone()],
                &pieces.table,
                cap,
                entry.unwrap_or(0.0),
                scratch,
            );
            let duration = match time_chain(&pieces, c, entry, drafts, time, trial) {
                Ok(duration) => duration,
                // Limits under which the handoff's speed cannot be held: try the next cap.
                Err(_) if entry.is_some() => {
                    let entry_limit = admissible_entry(drafts);
                    if entry.is_some_and(|speed| entry_limit < speed) {
                        admissible = admissible.max(entry_limit);
                    }
                    continue;
                }
                Err(error) => return Err(error.offset(first).into()),
            };
            if duration < fastest {
                fastest = duration;
                std::mem::swap(best, trial);
                best_limits.clear();
                best_limits.extend(pieces.pieces[range.clone()].iter().map(|p| p.limits));
            }
        }
        if fastest == f64::INFINITY {
            return Err(WindowError::Handoff { admissible });
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
        stretch,
    })
}

/// Where segment `first` starts, in a path whose segment `k` is `path`'s `k - base`.
fn point_before(path: &AxisPath, base: usize, first: usize) -> &[f64] {
    match first.checked_sub(base + 1) {
        Some(previous) => path.segments[previous].geometry.end(),
        None => &path.start,
    }
}

/// Segments per window at a stop at first; a window grows until it holds a whole chain, up
/// to [`LOOKAHEAD_SEGMENTS`].
pub(super) const WINDOW_SEGMENTS: usize = 512;

/// The planner's look-ahead (segments): a chain that ends within the window it starts in
/// (this many segments from the end of the chain before) is planned whole; a longer one is
/// planned this many segments at a time, each window assuming a stop at its end and handing
/// over to the next between one half and three quarters of the way in, so that every point is
/// planned with at least a quarter of this ahead of it (as a CNC's look-ahead queue of fixed
/// depth). A run's planning memory is bounded by it, however long the chain.
pub const LOOKAHEAD_SEGMENTS: usize = 4096;

/// Segments before a handoff that the window after it builds again (and does not use): its
/// pieces from the handoff on depend on them.
const HANDOFF_MARGIN: usize = 16;

/// Places tried as a handoff per window: this many of those the plan passes at zero
/// acceleration anyway (the slowest first), then as many of the others.
const HANDOFF_TRIES: usize = 3;

/// How far the look-ahead reaches, and how hard it tries to hand a long chain over.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Depth {
    /// [`LOOKAHEAD_SEGMENTS`], or another look-ahead (for comparing).
    segments: usize,
    /// [`HANDOFF_TRIES`], or fewer (none: every window of a long chain stops at its end).
    handoff_tries: usize,
}

impl Depth {
    /// A look-ahead of `segments` (at least `8 * HANDOFF_MARGIN`: each window after a handoff
    /// must reach past the margin before it), trying [`HANDOFF_TRIES`] places of each kind.
    fn of(segments: usize) -> Self {
        Depth {
            segments: segments.max(8 * HANDOFF_MARGIN),
            handoff_tries: HANDOFF_TRIES,
        }
    }
}

/// Segments either side of a refused handoff place whose places are not tried: the smoothing
/// choice of a line depends on the lines up to two either side of it.
const REFUSED_NEIGHBOURHOOD: usize = 3;

/// How many times a handoff the next window can take over only more slowly is tried at the
/// speed it admits (which itself changes with the speed: the limits it gives the curves
/// depend on it).
const HANDOFF_SLOWDOWNS: usize = 3;

/// How much slower than its span would pass it a handoff inside a span is passed (relative):
/// the next window's limits for the same pieces may come out a few ulps lower.
const HANDOFF_SPEED_MARGIN: f64 = 1e-9;

/// Where a stretch of a long chain hands over to the next window: at the start of a piece,
/// at zero path acceleration and a known speed.
#[derive(Debug, Clone)]
struct Handoff {
    /// The segment the next window starts from ([`HANDOFF_MARGIN`] before the piece).
    first: usize,
    /// What the next window's geometry takes over from the one before.
    seed: Seed,
    /// The piece the next window starts with, as the window before made it.
    piece: PieceKey,
    /// Path speed ṡ there.
    speed: f64,
}

/// A piece as it is in the path, whatever window made it (segments as path segments, its
/// vectors copied).
#[derive(Debug, Clone, PartialEq)]
struct PieceKey {
    kind: PieceKind,
    length: f64,
    data: Vec<f64>,
    covered: Vec<usize>,
}

impl PieceKey {
    /// Piece `index` of `pieces`, made by a window from segment `first` on.
    fn of(pieces: &Pieces, index: usize, first: usize, axes: usize) -> PieceKey {
        let piece = &pieces.pieces[index];
        let (kind, data, covered) = match piece.kind {
            PieceKind::Segment { segment, from } => (
                PieceKind::Segment {
                    segment: first + segment,
                    from,
                },
                &[][..],
                Vec::new(),
            ),
            PieceKind::Corner {
                incoming,
                outgoing,
                blend,
                data,
            } => (
                PieceKind::Corner {
                    incoming: first + incoming,
                    outgoing: first + outgoing,
                    blend,
                    data: 0,
                },
                &pieces.arena[data..data + 3 * axes],
                Vec::new(),
            ),
            PieceKind::Tangent(t) => (
                PieceKind::Tangent(TangentBlend {
                    incoming: first + t.incoming,
                    outgoing: first + t.outgoing,
                    length: t.length,
                }),
                &[][..],
                Vec::new(),
            ),
            PieceKind::Quintic {
                data,
                first: covered,
                count,
            } => (
                PieceKind::Quintic {
                    data: 0,
                    first: 0,
                    count,
                },
                &pieces.arena[data..data + quintic::COEFFICIENTS * axes],
                pieces.covered[covered..covered + count]
                    .iter()
                    .map(|&k| first + k)
                    .collect(),
            ),
        };
        PieceKey {
            kind,
            length: piece.length,
            data: data.to_vec(),
            covered,
        }
    }
}

/// The first segment (of its window) piece `index` runs through.
fn first_segment_of(pieces: &Pieces, index: usize) -> usize {
    match pieces.pieces[index].kind {
        PieceKind::Segment { segment, .. } => segment,
        PieceKind::Corner { incoming, .. } => incoming,
        PieceKind::Tangent(t) => t.incoming,
        PieceKind::Quintic { first, .. } => pieces.covered[first],
    }
}

impl Handoff {
    /// The handoff at piece `index` of `pieces` (a window from segment `first`) at `speed`.
    fn at(pieces: &Pieces, first: usize, index: usize, speed: f64, axes: usize) -> Handoff {
        let at = first_segment_of(pieces, index);
        let margin = at.saturating_sub(HANDOFF_MARGIN);
        Handoff {
            first: first + margin,
            seed: Seed {
                smoothed: pieces.smoothed[margin..at].to_vec(),
                curve_start: at - margin,
            },
            piece: PieceKey::of(pieces, index, first, axes),
            speed,
        }
    }

    /// The chain and the index of the handoff's piece in `pieces` (a window from segment
    /// `first`), if it is there.
    fn find(&self, pieces: &Pieces, first: usize, axes: usize) -> Option<(usize, usize)> {
        let at = self.first + self.seed.curve_start;
        pieces.chains.iter().enumerate().find_map(|(c, chain)| {
            (chain.first..chain.end)
                .find(|&q| {
                    first + first_segment_of(pieces, q) == at
                        && PieceKey::of(pieces, q, first, axes) == self.piece
                })
                .map(|q| (c, q))
        })
    }
}

/// Where the next window starts.
#[derive(Debug, Clone)]
enum Next {
    /// At a stop: segment `0` starts a chain.
    Stop(usize),
    /// Inside a chain longer than the look-ahead.
    Handoff(Box<Handoff>),
}

/// A path's windows in order, each planned from where the one before ended: [`plan`] keeps
/// them all, [`PlanWindows`] one at a time. Windows at a stop hold whole chains; a chain
/// longer than [`LOOKAHEAD_SEGMENTS`] is planned a window at a time and handed over inside
/// each. A chain is planned whole or not whatever the windows around it (a window at a stop
/// is never longer than the look-ahead), so every sequence of windows plans the same.
#[derive(Debug)]
struct Windows {
    /// How far the look-ahead reaches, and how hard it tries to hand a long chain over.
    depth: Depth,
    /// Segments of the next window at a stop (it grows to hold a whole chain).
    window: usize,
    /// Where the next window starts (`None`: after the last).
    next: Option<Next>,
    /// When the windows planned so far end.
    time: f64,
    timing: Timing,
    /// Buffers for checking a handoff.
    check: Timing,
    /// The window after the handoff in `next`, planned when the handoff was checked (its
    /// spans in `check`).
    checked: Option<Timed>,
}

impl Windows {
    fn new(window: usize, depth: Depth) -> Self {
        let depth = Depth {
            segments: depth.segments.max(8 * HANDOFF_MARGIN),
            ..depth
        };
        Windows {
            depth,
            window: window.clamp(1, depth.segments),
            next: Some(Next::Stop(0)),
            time: 0.0,
            timing: Timing::default(),
            check: Timing::default(),
            checked: None,
        }
    }

    /// The windows after those planned so far, planned again from here.
    fn resume(&self) -> Self {
        Windows {
            depth: self.depth,
            window: self.window,
            next: self.next.clone(),
            time: self.time,
            timing: Timing::default(),
            check: Timing::default(),
            checked: None,
        }
    }

    /// Plans the next window; `None` after the last.
    fn next_part(&mut self, reader: &mut PathReader) -> Result<Option<Part>, PathError> {
        let Some((timed, first, window_end)) = self.step(reader)? else {
            return Ok(None);
        };
        let (path, base) = reader.view();
        let start = point_before(path, base, first);
        Ok(Some(Part {
            axes: path.axes.len(),
            source_index: path.segments[first - base..first - base + timed.shapes.len()]
                .iter()
                .map(|s| s.source_index)
                .collect(),
            shapes: timed.shapes,
            pieces: timed.pieces,
            spans: std::mem::take(&mut self.timing.spans),
            first_segment: first,
            start: start.to_vec(),
            duration: timed.end_time,
            end: window_end,
        }))
    }

    /// Times the next window (to `self.time`): how it ends; `None` after the last.
    fn next_time(&mut self, reader: &mut PathReader) -> Result<Option<WindowEnd>, PathError> {
        Ok(self.step(reader)?.map(|(_, _, end)| end))
    }

    /// The next window's geometry and timing (its spans in `self.timing.spans`), its first
    /// segment, and how it ends.
    fn step(
        &mut self,
        reader: &mut PathReader,
    ) -> Result<Option<(Timed, usize, WindowEnd)>, PathError> {
        let (first, entry) = match self.next.take() {
            None => return Ok(None),
            Some(Next::Stop(first)) => (first, None),
            Some(Next::Handoff(handoff)) => (handoff.first, Some(handoff)),
        };
        reader.release(first);
        if reader.reach(first + 1)? == first {
            return Ok(None);
        }
        loop {
            // After a handoff, always the whole look-ahead (where the handoff was checked).
            let size = if entry.is_some() {
                self.depth.segments
            } else {
                self.window
            };
            let (end, ending) = self.window_end(reader, first, size)?;
            // A window after a handoff was planned when the handoff was checked, from the same
            // inputs.
            let checked = self.checked.take().filter(|_| entry.is_some());
            let timed = match checked {
                Some(timed) => {
                    std::mem::swap(&mut self.timing, &mut self.check);
                    Ok(timed)
                }
                None => time_segments(
                    reader.view().0,
                    reader.view().1,
                    first,
                    end,
                    self.time,
                    ending,
                    entry.as_deref(),
                    &mut self.timing,
                ),
            };
            let timed = match timed {
                Ok(timed) => timed,
                Err(WindowError::Path(error)) => return Err(error),
                // The same call checked it when the handoff was made.
                Err(WindowError::Handoff { .. } | WindowError::Unmatched) => {
                    unreachable!("planning is deterministic: a handoff checked once holds")
                }
            };
            if timed.stretch {
                return self.hand_over(reader, first, timed).map(Some);
            }
            if timed.next > first {
                // Doubled when less than half of it is kept (the chain cut off at its end is
                // planned again with the next window), so that no more than about half the
                // work is repeated.
                if entry.is_none() && 2 * (timed.next - first) < end - first {
                    self.window = self.window.saturating_mul(2).min(self.depth.segments);
                }
                self.time = timed.end_time;
                self.next = Some(Next::Stop(timed.next));
                return Ok(Some((timed, first, WindowEnd::Stop)));
            }
            // No whole chain in the window: it grows (each try is planned in full: a long
            // chain costs about 8/7 of its planning again).
            self.window = self.window.saturating_mul(8).min(self.depth.segments);
        }
    }

    /// Where a window of `size` segments from `first` ends, and which of its chains are
    /// timed: all at the path's end; else, in a window of the whole look-ahead, a chain
    /// running on past it is a stretch when it is the only one.
    fn window_end(
        &self,
        reader: &mut PathReader,
        first: usize,
        size: usize,
    ) -> Result<(usize, Ending), PathError> {
        // One segment more than the window: whether the path ends with it.
        let reached = reader.reach(first.saturating_add(size).saturating_add(1))?;
        let end = reached.min(first.saturating_add(size));
        let ending = if reached == end {
            Ending::PathEnd
        } else if size >= self.depth.segments {
            Ending::CompleteOrStretch
        } else {
            Ending::Complete
        };
        Ok((end, ending))
    }

    /// A stretch of a long chain (`timed` from segment `first`, its spans in
    /// `self.timing.spans`) up to its handoff: the first place between one half and three
    /// quarters of the way in that the next window can take over from ([`handoff_places`],
    /// [`HANDOFF_TRIES`] of each kind, none within [`REFUSED_NEIGHBOURHOOD`] of one whose
    /// piece the next window does not hold); failing that, the first of them the next window
    /// can take over from more slowly (at the speed it admits there, [`HANDOFF_SLOWDOWNS`]
    /// times at most). If none can be taken over, the stretch stops at the window's last point,
    /// and the next window starts from rest there.
    fn hand_over(
        &mut self,
        reader: &mut PathReader,
        first: usize,
        mut timed: Timed,
    ) -> Result<(Timed, usize, WindowEnd), PathError> {
        let region = first.saturating_add(self.depth.segments / 2)
            ..first.saturating_add(self.depth.segments / 4 * 3);
        let places = handoff_places(&timed.pieces, &self.timing.spans, |piece| {
            region.contains(&(first + first_segment_of(&timed.pieces, piece)))
        });
        let (mut exact, mut others): (Vec<_>, Vec<_>) = places.into_iter().partition(|p| p.exact);
        // Among equally slow ones (a cruise), the latest: the most planned per window.
        exact.sort_by(|a, b| a.speed.total_cmp(&b.speed).then(b.piece.cmp(&a.piece)));
        // Of the others, the fastest: the least slowed down by the handoff.
        others.sort_by(|a, b| b.speed.total_cmp(&a.speed).then(b.piece.cmp(&a.piece)));
        // The places the next window could take over only more slowly, at the speed it admits.
        let mut slower = Vec::new();
        // Where the next window's pieces differ from this one's (its smoothing choices there
        // came out otherwise): the places near them are not tried.
        let mut refused: Vec<usize> = Vec::new();
        let mut tries = [0; 2];
        for cut in exact.into_iter().chain(others) {
            let at = first_segment_of(&timed.pieces, cut.piece);
            let kind = usize::from(!cut.exact);
            if tries[kind] == self.depth.handoff_tries
                || refused
                    .iter()
                    .any(|r| r.abs_diff(at) <= REFUSED_NEIGHBOURHOOD)
            {
                continue;
            }
            tries[kind] += 1;
            let handed_off = WindowEnd::HandedOff { slowed: false };
            match self.try_handoff(reader, first, &mut timed, cut, cut.speed)? {
                Tried::HandedOff => return Ok((timed, first, handed_off)),
                Tried::TooFast { admissible } => slower.push((cut, admissible)),
                Tried::Unmatched => refused.push(at),
                Tried::Refused => {}
            }
        }
        for (cut, mut admissible) in slower {
            for _ in 0..HANDOFF_SLOWDOWNS {
                let speed = admissible * (1.0 - HANDOFF_SPEED_MARGIN);
                match self.try_handoff(reader, first, &mut timed, cut, speed)? {
                    Tried::HandedOff => {
                        return Ok((timed, first, WindowEnd::HandedOff { slowed: true }))
                    }
                    // Its limits depend on the speed it starts at: they may come out lower.
                    Tried::TooFast { admissible: lower } => admissible = lower,
                    Tried::Unmatched | Tried::Refused => break,
                }
            }
        }
        self.time = timed.end_time;
        self.next = Some(Next::Stop(timed.next));
        Ok((timed, first, WindowEnd::StopsShort))
    }

    /// Hands the stretch `timed` (a window from segment `first`) over at `cut`, passed at
    /// `speed` (at most the place's own), if the next window, planned in full, takes it over:
    /// its spans then end there and the next window is kept for the next step.
    fn try_handoff(
        &mut self,
        reader: &mut PathReader,
        first: usize,
        timed: &mut Timed,
        cut: HandoffPlace,
        speed: f64,
    ) -> Result<Tried, PathError> {
        // The spans kept (those before `kept`, then `last`), and when the handoff is passed.
        let span = self.timing.spans[cut.span];
        let (kept, last, time) = if cut.piece == span.first && speed == cut.speed {
            // A span boundary as planned.
            (cut.span, None, span.start_time)
        } else {
            // The span that ends at the handoff, planned again to end there at `speed`: the
            // one before it at a span boundary, else its part up to the handoff.
            let (index, replanned) = if cut.piece == span.first {
                (cut.span - 1, self.timing.spans[cut.span - 1])
            } else {
                (cut.span, span)
            };
            let length = timed.pieces.pieces[cut.piece].start - replanned.start;
            let r = &replanned.recipe;
            let Some((recipe, duration)) = Recipe::plan_timed(length, r.v_start, speed, &r.limits)
            else {
                return Ok(Tried::Refused);
            };
            let last = Span {
                end: cut.piece,
                recipe,
                ..replanned
            };
            (index, Some(last), replanned.start_time + duration)
        };
        let axes = reader.view().0.axes.len();
        let handoff = Handoff::at(&timed.pieces, first, cut.piece, speed, axes);
        let (end, ending) = self.window_end(reader, handoff.first, self.depth.segments)?;
        let (path, base) = reader.view();
        let check = time_segments(
            path,
            base,
            handoff.first,
            end,
            time,
            ending,
            Some(&handoff),
            &mut self.check,
        );
        match check {
            Ok(checked) => {
                self.checked = Some(checked);
                self.timing.spans.truncate(kept);
                self.timing.spans.extend(last);
                timed.pieces.chains[0].end = cut.piece;
                timed.end_time = time;
                self.time = time;
                self.next = Some(Next::Handoff(Box::new(handoff)));
                Ok(Tried::HandedOff)
            }
            Err(WindowError::Unmatched) => Ok(Tried::Unmatched),
            Err(WindowError::Handoff { admissible }) if admissible > 0.0 && admissible < speed => {
                Ok(Tried::TooFast { admissible })
            }
            Err(WindowError::Handoff { .. }) => Ok(Tried::Refused),
            Err(WindowError::Path(error)) => Err(error),
        }
    }
}

/// What trying a handoff came to.
#[derive(Debug, Clone, Copy)]
enum Tried {
    HandedOff,
    /// The next window can go on from the handoff only at `admissible` or slower.
    TooFast {
        admissible: f64,
    },
    /// The next window does not hold the handoff's piece: its geometry differs there.
    Unmatched,
    /// The next window cannot go on from the handoff at all, or the stretch cannot slow down
    /// to the speed in time.
    Refused,
}

/// A place a stretch can hand over at: the start of piece `piece`, in span `span`, passed at
/// `speed` with zero path acceleration. Exact: the plan passes it so already (at a span's
/// start; or cruising, where the span is planned again to end there a hair slower, the same
/// motion up to it); otherwise the span is planned again up to it, to end there at `speed`.
#[derive(Debug, Clone, Copy)]
struct HandoffPlace {
    span: usize,
    piece: usize,
    speed: f64,
    exact: bool,
}

/// The places in `spans` (of one chain of `pieces`) at pieces that `wanted` accepts: every
/// span boundary and every piece boundary a span passes while cruising (exact), and every
/// other piece boundary, at the speed the span could pass it at without acceleration: the
/// lower of the fastest it reaches from its start and the fastest from which it still slows
/// to its exit in time.
fn handoff_places(
    pieces: &Pieces,
    spans: &[Span],
    wanted: impl Fn(usize) -> bool,
) -> Vec<HandoffPlace> {
    let mut places = Vec::new();
    for (i, span) in spans.iter().enumerate() {
        if i > 0 && wanted(span.first) {
            places.push(HandoffPlace {
                span: i,
                piece: span.first,
                speed: span.recipe.v_start,
                exact: true,
            });
        }
        let r = &span.recipe;
        let (a, j) = (r.limits.acceleration, r.limits.jerk);
        let cruise_from = transfer_distance(r.v_start, r.peak, a, j);
        let cruise_to = r.length - transfer_distance(r.peak, r.v_end, a, j);
        for q in span.first + 1..span.end {
            if !wanted(q) {
                continue;
            }
            let at = pieces.pieces[q].start - span.start;
            let exact = r.cruise > 0.0 && cruise_from < at && at < cruise_to;
            let speed = if exact {
                r.peak
            } else {
                reachable_velocity(r.v_start, at, &r.limits).min(reachable_velocity(
                    r.v_end,
                    r.length - at,
                    &r.limits,
                ))
            };
            places.push(HandoffPlace {
                span: i,
                piece: q,
                // A hair below: the next window's limits there may round lower.
                speed: speed * (1.0 - HANDOFF_SPEED_MARGIN),
                exact,
            });
        }
    }
    places
}

/// A path planned window by window, as it is evaluated: the plans of a few hundred segments at
/// a time (at most [`LOOKAHEAD_SEGMENTS`]), never the whole path, which may itself be made as
/// it is read ([`PathReader::Streamed`]). Samples are bit-identical to [`plan`]'s: the same
/// windows, each timed from where the previous one ended.
#[derive(Debug)]
pub(super) struct PlanWindows<'a> {
    /// The path, read from its start again as the windows are evaluated.
    reader: PathReader<'a>,
    /// What the timing pass's windows did with chains longer than the look-ahead.
    look_ahead: LookAhead,
    duration: f64,
    /// The first windows as the timing pass planned them, kept for the evaluation while the
    /// budget of [`KEPT_SEGMENTS`] lasted.
    kept: std::collections::VecDeque<Part>,
    /// The window being evaluated (None before the first evaluation, or when no chain moves),
    /// with its cursor.
    current: Option<(Part, Cursor)>,
    /// The windows after the kept ones, planned again as they are evaluated.
    windows: Windows,
    /// The start point and program move reported when nothing moves.
    rest: (Vec<f64>, u32),
    /// The path's end point and last program move.
    end: (Vec<f64>, u32),
    /// The program move the path starts with (for error messages).
    first_move: usize,
}

/// Most segments whose windows the timing passes of a program's [`PlanWindows`] keep for
/// evaluation, all motions together: a program this short is planned once, not twice.
pub(super) const KEPT_SEGMENTS: usize = 16_384;

impl<'a> PlanWindows<'a> {
    /// Plans every window once for the path's duration, keeping windows of up to `budget`
    /// segments in all for the evaluation (and taking them off it); reports the errors
    /// [`plan`] would.
    pub fn new(
        reader: PathReader<'a>,
        window: usize,
        first_move: usize,
        budget: &mut usize,
    ) -> Result<Self, PathError> {
        Self::keeping(
            reader,
            window,
            first_move,
            budget,
            Depth::of(LOOKAHEAD_SEGMENTS),
        )
    }

    /// [`Self::new`] at a look-ahead `depth`.
    fn keeping(
        mut reader: PathReader<'a>,
        window: usize,
        first_move: usize,
        budget: &mut usize,
        depth: Depth,
    ) -> Result<Self, PathError> {
        reader.validate()?;
        let mut timing_reader = reader.restart();
        // Of the windows after the kept ones only the end time is needed, and one set of
        // buffers does for all.
        let mut timing = Windows::new(window, depth);
        let mut kept = std::collections::VecDeque::new();
        // Where the evaluation goes on after the kept windows (none: they are all).
        let mut resume = None;
        let mut look_ahead = LookAhead::default();
        loop {
            if resume.is_none() {
                let before = timing.resume();
                let Some(part) = timing.next_part(&mut timing_reader)? else {
                    break;
                };
                look_ahead.count(part.end);
                let size = part.shapes.len();
                if size <= *budget {
                    *budget -= size;
                    kept.push_back(part);
                } else {
                    resume = Some(before);
                }
            } else {
                match timing.next_time(&mut timing_reader)? {
                    Some(end) => look_ahead.count(end),
                    None => break,
                }
            }
        }
        let duration = timing.time;
        let (path, _) = timing_reader.view();
        let end = match path.segments.last() {
            Some(last) => (last.geometry.end().to_vec(), last.source_index),
            None => (path.start.clone(), 0),
        };
        // The evaluation reads the path from its start: its first segment is made here.
        reader.reach(1)?;
        let (start, _) = reader.view();
        let rest = (
            start.start.clone(),
            start.segments.first().map_or(0, |s| s.source_index),
        );
        Ok(PlanWindows {
            reader,
            look_ahead,
            duration,
            kept,
            current: None,
            windows: resume.unwrap_or(timing),
            rest,
            end,
            first_move,
        })
    }

    /// The whole path (made again, for inspecting it).
    pub fn whole_path(&self) -> Result<AxisPath, PathError> {
        let mut reader = self.reader.restart();
        let count = reader.reach(usize::MAX)?;
        let (path, base) = reader.view();
        debug_assert_eq!((base, path.segments.len()), (0, count));
        Ok(path.clone())
    }

    /// The program move the path starts with.
    pub fn first_move(&self) -> usize {
        self.first_move
    }

    /// Where the path ends, and the program move of its last segment.
    pub fn end(&self) -> (&[f64], u32) {
        (&self.end.0, self.end.1)
    }

    /// Total duration (s), the same as [`plan`]'s.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// What the look-ahead did with chains longer than it.
    pub fn look_ahead(&self) -> LookAhead {
        self.look_ahead
    }

    /// Whether windows after the current one remain.
    fn has_more(&self) -> bool {
        !self.kept.is_empty() || self.windows.next.is_some()
    }

    /// Moves on to the next window that has spans, if there is one; false at the end (the
    /// current window stays).
    fn advance(&mut self) -> bool {
        loop {
            let part = match self.kept.pop_front() {
                Some(part) => part,
                // The timing pass planned this window from the same inputs without error.
                None => match self
                    .windows
                    .next_part(&mut self.reader)
                    .expect("planning is deterministic: a window planned once plans again")
                {
                    Some(part) => part,
                    None => return false,
                },
            };
            if !part.spans.is_empty() {
                let cursor = Cursor::new(&part);
                self.current = Some((part, cursor));
                return true;
            }
        }
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
        while self.current.as_ref().is_some_and(|(p, _)| p.duration <= t) && self.has_more() {
            if !self.advance() {
                break;
            }
        }
        let Some((part, cursor)) = self.current.as_mut() else {
            return self.rest.1;
        };
        cursor.eval(part, t, position, velocity, acceleration)
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

/// Times chain `c` from `start_time` into `spans` (cleared first), from rest or from `entry`
/// (a handoff's speed); returns its duration.
fn time_chain(
    pieces: &Pieces,
    c: usize,
    entry: Option<f64>,
    drafts: &mut Vec<Draft>,
    start_time: f64,
    spans: &mut Vec<Span>,
) -> Result<f64, PathError> {
    spans.clear();
    group_into_spans(&pieces.pieces, &pieces.chains[c], drafts);
    let speeds = look_ahead(drafts, entry.unwrap_or(0.0));
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

/// Speeds at the span boundaries of a chain: `entry` at its start (zero, or a handoff's
/// speed, which the first span may not be able to hold: then its profile fails), zero at its
/// end, capped by both neighbours' speed limits, and reachable from each other within the
/// spans (backward, then forward).
fn look_ahead(drafts: &[Draft], entry: f64) -> Vec<f64> {
    let m = drafts.len();
    let mut speeds = vec![0.0; m + 1];
    speeds[0] = entry;
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

/// The fastest a chain of `drafts` (as [`time_chain`] grouped them) can be entered at: within
/// its first span's speed limit, and slow enough to slow down for every boundary after it and
/// stop at its end (the backward pass of [`look_ahead`]).
fn admissible_entry(drafts: &[Draft]) -> f64 {
    let Some(first) = drafts.first() else {
        return 0.0;
    };
    let mut next = 0.0;
    for (before, d) in drafts.iter().zip(&drafts[1..]).rev() {
        let boundary = before.limits.velocity.min(d.limits.velocity);
        next = boundary.min(reachable_velocity(next, d.length, &d.limits));
    }
    first
        .limits
        .velocity
        .min(reachable_velocity(next, first.length, &first.limits))
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
    pub speed: f64,
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
