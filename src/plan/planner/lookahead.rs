//! The look-ahead that moves windows along the path and hands over between them (the
//! planner's step 5): where a window may hand over, the check that the next window can take
//! the handoff over, and the bounded reading of the path as a run goes.

use super::window::*;
use super::*;
impl LookAhead {
    /// Counts a window that ends so.
    pub(super) fn count(&mut self, end: WindowEnd) {
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
pub(super) enum WindowEnd {
    /// At a stop the program asks for (or the path's end).
    Stop,
    /// Handed over to the next window while moving; `slowed`: more slowly than this window
    /// planned, at the speed the next one admits.
    HandedOff { slowed: bool },
    /// At the window's last point, stopping there although the chain goes on (no handoff
    /// could be taken over).
    StopsShort,
}

/// Segments per window at a stop at first; a window grows until it holds a whole chain, up
/// to [`LOOKAHEAD_SEGMENTS`].
pub(in crate::plan) const WINDOW_SEGMENTS: usize = 512;

/// The planner's look-ahead (segments): a chain that ends within the window it starts in
/// (this many segments from the end of the chain before) is planned whole; a longer one is
/// planned this many segments at a time, each window assuming a stop at its end and handing
/// over to the next between one half and three quarters of the way in, so that every point is
/// planned with at least a quarter of this ahead of it (as a CNC's look-ahead queue of fixed
/// depth). A run's planning memory is bounded by it, however long the chain.
pub const LOOKAHEAD_SEGMENTS: usize = 4096;

/// Segments before a handoff that the window after it builds again (and does not use): its
/// pieces from the handoff on depend on them.
pub(super) const HANDOFF_MARGIN: usize = 16;

/// Places tried as a handoff per window: this many of those the plan passes at zero
/// acceleration anyway (the slowest first), then as many of the others.
pub(super) const HANDOFF_TRIES: usize = 3;

/// How far the look-ahead reaches, and how hard it tries to hand a long chain over.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Depth {
    /// [`LOOKAHEAD_SEGMENTS`], or another look-ahead (for comparing).
    pub(super) segments: usize,
    /// [`HANDOFF_TRIES`], or fewer (none: every window of a long chain stops at its end).
    pub(super) handoff_tries: usize,
}

impl Depth {
    /// A look-ahead of `segments` (at least `8 * HANDOFF_MARGIN`: each window after a handoff
    /// must reach past the margin before it), trying [`HANDOFF_TRIES`] places of each kind.
    pub(super) fn of(segments: usize) -> Self {
        Depth {
            segments: segments.max(8 * HANDOFF_MARGIN),
            handoff_tries: HANDOFF_TRIES,
        }
    }
}

/// Segments either side of a refused handoff place whose places are not tried: the smoothing
/// choice of a line depends on the lines up to two either side of it.
pub(super) const REFUSED_NEIGHBOURHOOD: usize = 3;

/// How many times a handoff the next window can take over only more slowly is tried at the
/// speed it admits (which itself changes with the speed: the limits it gives the curves
/// depend on it).
pub(super) const HANDOFF_SLOWDOWNS: usize = 3;

/// How much slower than its span would pass it a handoff inside a span is passed (relative):
/// the next window's limits for the same pieces may come out a few ulps lower.
pub(super) const HANDOFF_SPEED_MARGIN: f64 = 1e-9;

/// Where a stretch of a long chain hands over to the next window: at the start of a piece,
/// at zero path acceleration and a known speed.
#[derive(Debug, Clone)]
pub(super) struct Handoff {
    /// The segment the next window starts from ([`HANDOFF_MARGIN`] before the piece).
    pub(super) first: usize,
    /// What the next window's geometry takes over from the one before.
    pub(super) seed: Seed,
    /// The piece the next window starts with, as the window before made it.
    pub(super) piece: PieceKey,
    /// Path speed ṡ there.
    pub(super) speed: f64,
}

/// A piece as it is in the path, whatever window made it (segments as path segments, its
/// vectors copied).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct PieceKey {
    pub(super) kind: PieceKind,
    pub(super) length: f64,
    pub(super) data: Vec<f64>,
    pub(super) covered: Vec<usize>,
}

impl PieceKey {
    /// Piece `index` of `pieces`, made by a window from segment `first` on.
    pub(super) fn of(pieces: &Pieces, index: usize, first: usize, axes: usize) -> PieceKey {
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
pub(super) fn first_segment_of(pieces: &Pieces, index: usize) -> usize {
    match pieces.pieces[index].kind {
        PieceKind::Segment { segment, .. } => segment,
        PieceKind::Corner { incoming, .. } => incoming,
        PieceKind::Tangent(t) => t.incoming,
        PieceKind::Quintic { first, .. } => pieces.covered[first],
    }
}

impl Handoff {
    /// The handoff at piece `index` of `pieces` (a window from segment `first`) at `speed`.
    pub(super) fn at(
        pieces: &Pieces,
        first: usize,
        index: usize,
        speed: f64,
        axes: usize,
    ) -> Handoff {
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
    pub(super) fn find(
        &self,
        pieces: &Pieces,
        first: usize,
        axes: usize,
    ) -> Option<(usize, usize)> {
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
pub(super) enum Next {
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
pub(super) struct Windows {
    /// How far the look-ahead reaches, and how hard it tries to hand a long chain over.
    pub(super) depth: Depth,
    /// Segments of the next window at a stop (it grows to hold a whole chain).
    pub(super) window: usize,
    /// Where the next window starts (`None`: after the last).
    pub(super) next: Option<Next>,
    /// When the windows planned so far end.
    pub(super) time: f64,
    pub(super) timing: Timing,
    /// Buffers for checking a handoff.
    pub(super) check: Timing,
    /// The window after the handoff in `next`, planned when the handoff was checked (its
    /// spans in `check`).
    pub(super) checked: Option<Timed>,
}

impl Windows {
    pub(super) fn new(window: usize, depth: Depth) -> Self {
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
    pub(super) fn resume(&self) -> Self {
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
    pub(super) fn next_part(&mut self, reader: &mut PathReader) -> Result<Option<Part>, PathError> {
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
    pub(super) fn next_time(
        &mut self,
        reader: &mut PathReader,
    ) -> Result<Option<WindowEnd>, PathError> {
        Ok(self.step(reader)?.map(|(_, _, end)| end))
    }

    /// The next window's geometry and timing (its spans in `self.timing.spans`), its first
    /// segment, and how it ends.
    pub(super) fn step(
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
                None => Window {
                    path: reader.view().0,
                    base: reader.view().1,
                    first,
                    end,
                    start_time: self.time,
                    ending,
                    entry: entry.as_deref(),
                }
                .time(&mut self.timing),
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
    pub(super) fn window_end(
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
    pub(super) fn hand_over(
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
    pub(super) fn try_handoff(
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
        let check = Window {
            path,
            base,
            first: handoff.first,
            end,
            start_time: time,
            ending,
            entry: Some(&handoff),
        }
        .time(&mut self.check);
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
pub(super) enum Tried {
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
pub(super) struct HandoffPlace {
    pub(super) span: usize,
    pub(super) piece: usize,
    pub(super) speed: f64,
    pub(super) exact: bool,
}

/// The places in `spans` (of one chain of `pieces`) at pieces that `wanted` accepts: every
/// span boundary and every piece boundary a span passes while cruising (exact), and every
/// other piece boundary, at the speed the span could pass it at without acceleration: the
/// lower of the fastest it reaches from its start and the fastest from which it still slows
/// to its exit in time.
pub(super) fn handoff_places(
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
pub(in crate::plan) struct PlanWindows<'a> {
    /// The path, read from its start again as the windows are evaluated.
    pub(super) reader: PathReader<'a>,
    /// What the timing pass's windows did with chains longer than the look-ahead.
    pub(super) look_ahead: LookAhead,
    pub(super) duration: f64,
    /// The first windows as the timing pass planned them, kept for the evaluation while the
    /// budget of [`KEPT_SEGMENTS`] lasted.
    pub(super) kept: std::collections::VecDeque<Part>,
    /// The window being evaluated (None before the first evaluation, or when no chain moves),
    /// with its cursor.
    pub(super) current: Option<(Part, Cursor)>,
    /// The windows after the kept ones, planned again as they are evaluated.
    pub(super) windows: Windows,
    /// The start point and program move reported when nothing moves.
    pub(super) rest: (Vec<f64>, u32),
    /// The path's end point and last program move.
    pub(super) end: (Vec<f64>, u32),
    /// The program move the path starts with (for error messages).
    pub(super) first_move: usize,
}

/// Most segments whose windows the timing passes of a program's [`PlanWindows`] keep for
/// evaluation, all motions together: a program this short is planned once, not twice.
pub(in crate::plan) const KEPT_SEGMENTS: usize = 16_384;

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
    pub(super) fn keeping(
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
    pub(super) fn has_more(&self) -> bool {
        !self.kept.is_empty() || self.windows.next.is_some()
    }

    /// Moves on to the next window that has spans, if there is one; false at the end (the
    /// current window stays).
    pub(super) fn advance(&mut self) -> bool {
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
