//! `CYCLE/DRILL` (and `BORE`, `REAM`, `TAP`) as NX writes them, expanded into the moves the
//! standard post makes for each hole: NX's posts put the rapid-to, feed-to and retract-to
//! points at the hole's `GOTO` point plus the record's signed distances along the tool axis
//! (`mom_cycle_*_to_pos = mom_pos + mom_cycle_*_to · spindle axis`).
//!
//! For each `GOTO` while a cycle is on: rapid to the rapid-to point (across at the current
//! height when above it, else up first), feed to the feed-to point (`DEEP`: in `STEP` pecks
//! with a rapid back to the rapid-to point after each and a rapid down to the last depth
//! less the peck clearance; `BRKCHP`: the same pecks, backing off by the peck clearance
//! only), dwell, then out to the retract-to point (rapid, or at the feed for `BORE`, `REAM`
//! and `TAP`).

use nalgebra::Vector3;

/// How far (m) a peck backs off (`BRKCHP`) and how far short of the last depth the rapid
/// back down stops (`DEEP`): LinuxCNC's G73/G83 figure, 0.010 in.
pub(crate) const PECK_CLEARANCE: f64 = 0.000_254;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum CycleKind {
    Drill,
    Deep,
    BreakChip,
    /// Fed back out (BORE, REAM, TAP).
    FeedOut,
}

/// A cycle as its record sets it, in metres and seconds.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Cycle {
    pub(super) name: String,
    pub(super) kind: CycleKind,
    /// Signed distances along the tool axis from the hole's GOTO point.
    pub(super) rapid_to: f64,
    pub(super) feed_to: f64,
    /// `None`: back to the rapid-to point.
    pub(super) retract_to: Option<f64>,
    /// Peck depths: the first, then the next, the last repeated.
    pub(super) steps: Vec<f64>,
    pub(super) dwell: f64,
    /// The cycle's own feed (m/s); `None`: the last FEDRAT.
    pub(super) feed: Option<f64>,
}

/// One move of an expanded hole.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum HoleMove {
    Rapid(Vector3<f64>),
    Feed(Vector3<f64>),
    Dwell(f64),
}

/// At most this many pecks per hole (as the G-code reader allows).
pub(super) const MAX_PECKS: f64 = 100_000.0;

impl Cycle {
    /// How many pecks a hole takes (1 unless DEEP or BRKCHP with STEP).
    pub(super) fn pecks(&self) -> f64 {
        if !matches!(self.kind, CycleKind::Deep | CycleKind::BreakChip) || self.steps.is_empty() {
            return 1.0;
        }
        let total = self.rapid_to - self.feed_to;
        let (last, first) = self.steps.split_last().expect("steps");
        let listed: f64 = first.iter().sum();
        first.len() as f64 + ((total - listed).max(0.0) / last).ceil()
    }

    /// The moves that make the hole at `point` with the tool along `axis` (unit), from the
    /// tool's position `from`.
    pub(super) fn hole(
        &self,
        from: Vector3<f64>,
        point: Vector3<f64>,
        axis: Vector3<f64>,
    ) -> Vec<HoleMove> {
        let mut moves = Vec::new();
        let at = |distance: f64| point + axis * distance;
        let rapid_point = at(self.rapid_to);
        // Height of the tool above the hole's point, along the axis.
        let height = (from - point).dot(&axis);
        if height > self.rapid_to {
            // Across at the current height, then down to the rapid-to point.
            moves.push(HoleMove::Rapid(at(height)));
        } else {
            // Up (or along) the axis to the rapid-to height first, then across.
            moves.push(HoleMove::Rapid(from + axis * (self.rapid_to - height)));
        }
        moves.push(HoleMove::Rapid(rapid_point));
        match self.kind {
            CycleKind::Drill | CycleKind::FeedOut => moves.push(HoleMove::Feed(at(self.feed_to))),
            CycleKind::Deep | CycleKind::BreakChip => {
                let total = self.rapid_to - self.feed_to;
                let mut depth = 0.0;
                let mut index = 0;
                while depth < total {
                    let step = self
                        .steps
                        .get(index)
                        .or(self.steps.last())
                        .copied()
                        .unwrap_or(total);
                    index += 1;
                    let next = (depth + step).min(total);
                    if depth > 0.0 {
                        if self.kind == CycleKind::Deep {
                            moves.push(HoleMove::Rapid(rapid_point));
                            let back = (depth - PECK_CLEARANCE).max(0.0);
                            moves.push(HoleMove::Rapid(at(self.rapid_to - back)));
                        } else {
                            let back = (depth - PECK_CLEARANCE).max(0.0);
                            moves.push(HoleMove::Rapid(at(self.rapid_to - back)));
                        }
                    }
                    moves.push(HoleMove::Feed(at(self.rapid_to - next)));
                    depth = next;
                }
            }
        }
        if self.dwell > 0.0 {
            moves.push(HoleMove::Dwell(self.dwell));
        }
        let out = at(self.retract_to.unwrap_or(self.rapid_to));
        moves.push(match self.kind {
            CycleKind::FeedOut => HoleMove::Feed(out),
            _ => HoleMove::Rapid(out),
        });
        // Moves of no length say nothing.
        let mut position = from;
        moves.retain(|m| match m {
            HoleMove::Rapid(p) | HoleMove::Feed(p) => {
                let keep = (p - position).norm() > 1e-12;
                position = *p;
                keep
            }
            HoleMove::Dwell(_) => true,
        });
        moves
    }
}
