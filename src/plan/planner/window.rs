//! Timing one window of the look-ahead: its segments become pieces and spans (see the
//! planner's steps 1 to 4), each chain timed under the fastest share cap, starting from a
//! handoff where the window takes over from the one before.

use super::*;
/// The working buffers of [`Window::time`]: the spans it times, and the scratch space of its
/// chains. [`Windows`] keeps one for all its windows, so that each window reuses the previous
/// one's allocations.
#[derive(Debug, Default)]
pub(super) struct Timing {
    /// The spans of every chain timed, in order.
    pub(super) spans: Vec<Span>,
    pub(super) drafts: Vec<Draft>,
    /// The spans of the share cap being tried, and of the fastest so far, with its limits.
    pub(super) trial: Vec<Span>,
    pub(super) best: Vec<Span>,
    pub(super) best_limits: Vec<Limits>,
    pub(super) scratch: Vec<f64>,
}

/// What [`Window::time`] built and found besides the spans.
#[derive(Debug)]
pub(super) struct Timed {
    pub(super) shapes: Shapes,
    pub(super) pieces: Pieces,
    /// When the last chain timed ends.
    pub(super) end_time: f64,
    /// The segment after the last chain timed.
    pub(super) next: usize,
    /// The window holds one chain, which runs on past it: a stretch, to be handed over
    /// inside it.
    pub(super) stretch: bool,
}

/// Which chains of a window [`Window::time`] times.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Ending {
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
pub(super) enum WindowError {
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

/// One window of the look-ahead: segments `first..end` of a path (validated; its segment `k`
/// is `path`'s `k - base`, and `path.start` the point before segment `base`), its first chain
/// starting at `start_time` (after `entry`, from the handoff's piece on at the handoff's
/// speed); `ending` says which of its chains it times.
pub(super) struct Window<'a> {
    pub(super) path: &'a AxisPath,
    pub(super) base: usize,
    pub(super) first: usize,
    pub(super) end: usize,
    pub(super) start_time: f64,
    pub(super) ending: Ending,
    pub(super) entry: Option<&'a Handoff>,
}

impl Window<'_> {
    /// Times the window; the spans go to `timing.spans` (cleared first).
    ///
    /// A chain's pieces depend only on its own segments and the shapes of the two segments
    /// around it (every junction, blend and smoothing curve looks no further, and none crosses
    /// a stop), so the whole chains timed here are exactly those of any window that holds them.
    pub(super) fn time(&self, timing: &mut Timing) -> Result<Timed, WindowError> {
        let Window {
            path,
            base,
            first,
            end,
            start_time,
            ending,
            entry,
        } = *self;
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
}

/// Where segment `first` starts, in a path whose segment `k` is `path`'s `k - base`.
pub(super) fn point_before(path: &AxisPath, base: usize, first: usize) -> &[f64] {
    match first.checked_sub(base + 1) {
        Some(previous) => path.segments[previous].geometry.end(),
        None => &path.start,
    }
}

/// The largest centripetal share any piece in `range` was given.
pub(super) fn largest_share_used(pieces: &Pieces, range: std::ops::Range<usize>) -> f64 {
    pieces.pieces[range.clone()]
        .iter()
        .zip(&pieces.budgets[range])
        .map(|(p, b)| b.share_of(&p.limits))
        .fold(0.0, f64::max)
}

/// Times chain `c` from `start_time` into `spans` (cleared first), from rest or from `entry`
/// (a handoff's speed); returns its duration.
pub(super) fn time_chain(
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
pub(super) struct Draft {
    pub(super) first: usize,
    pub(super) end: usize,
    pub(super) start: f64,
    pub(super) length: f64,
    pub(super) limits: Limits,
}

/// Groups the pieces of a chain into spans of similar limits. A piece much shorter than a
/// neighbour (the sliver of a segment left between two blends) is compared with the lower of
/// its own and its neighbours' limits, so that it does not split a span.
pub(super) fn group_into_spans(pieces: &[Piece], chain: &Chain, drafts: &mut Vec<Draft>) {
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
pub(super) fn look_ahead(drafts: &[Draft], entry: f64) -> Vec<f64> {
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
pub(super) fn admissible_entry(drafts: &[Draft]) -> f64 {
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
