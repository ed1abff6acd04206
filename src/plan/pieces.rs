//! The path as the planner times it: chains of pieces, each with limits on the path coordinate
//! under which every axis keeps its own limits.
//!
//! A chain runs from one stop to the next. Within it the path coordinate `s` is continuous and
//! the geometry is curvature-continuous, so the speed may change anywhere along it. Its pieces
//! are the parts of segments between blends, corner blends between lines ([`super::blend`]),
//! and tangent blends where a line or arc continues another with the same tangent
//! ([`super::tangent`]). Every other junction is a stop: exact stop (G61), zero tolerance, a
//! corner involving an arc, or a corner where stopping is faster than the blend it allows.
//!
//! Each piece bounds its axis derivatives along `s` by `K1 ≥ |q'|`, `K2 ≥ |q''|`, `K3 ≥ |q'''|`
//! per axis. A share ρ of each axis's acceleration and jerk budget goes to the terms that the
//! curvature adds at speed (`K2·ṡ² ≤ ρ·a`, `K3·ṡ³ ≤ ρ·j`, which cap ṡ); the rest is for
//! changing speed along the path (`K1·s̈ ≤ (1−ρ)·a`, `3·K2·ṡ·s̈ ≤ (1−ρ)·j/2`,
//! `K1·s⃛ ≤ (1−ρ)·j/2`), so the sum in `q⃛ = q'''·ṡ³ + 3·q''·ṡ·s̈ + q'·s⃛` stays within `j`.
//! On a line (`K2 = K3 = 0`) the limits are exactly `limit/|q'|`.

use super::blend::{CornerBlend, TurnShape};
use super::geometry::{Metric, Shapes};
use super::path::{AxisSpec, Blend, PathSegment};
use super::profile::{reachable_velocity, Limits, VelocityChange};
use super::tangent::{JetScratch, TangentBlend, TangentJunction};

/// Centripetal shares tried per curved piece.
const SHARES: [f64; 9] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];
/// Largest centripetal shares tried per chain (the planner keeps the fastest).
pub(super) const SHARE_CAPS: [f64; 3] = [0.9, 0.6, 0.3];
/// Share assumed when sizing a blend for the speed it should allow.
const SIZING_SHARE: f64 = 0.8;
/// Ramp fractions tried per corner blend.
const RAMPS: [f64; 5] = [0.1, 0.2, 0.3, 0.4, 0.5];
/// Largest angle between the tangents of a line and an arc (or two arcs) that still counts as a
/// tangent junction (rad): about 3°. Larger corners involving an arc are stops.
pub const TANGENT_ANGLE: f64 = 0.05;
/// Largest angle an arc may turn through within a tangent blend (rad), so that the blend stays
/// local and its bounds tight.
const MAX_BLEND_TURN: f64 = 0.5;

/// One piece of a chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Piece {
    pub kind: PieceKind,
    /// Where the piece starts in its chain's path coordinate.
    pub start: f64,
    pub length: f64,
    pub limits: Limits,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum PieceKind {
    /// Segment `segment` from its path coordinate `from` on.
    Segment {
        segment: usize,
        from: f64,
    },
    /// A corner blend from `incoming` into `outgoing`; `P_in`, `u1`, `Δu` at `arena[data..]`.
    Corner {
        incoming: usize,
        outgoing: usize,
        blend: CornerBlend,
        data: usize,
    },
    Tangent(TangentBlend),
}

impl PieceKind {
    /// The segment the piece belongs to at `u` into it (blends: half and half).
    pub fn segment_at(&self, u: f64, length: f64) -> usize {
        match *self {
            PieceKind::Segment { segment, .. } => segment,
            PieceKind::Corner {
                incoming, outgoing, ..
            } => {
                if u < 0.5 * length {
                    incoming
                } else {
                    outgoing
                }
            }
            PieceKind::Tangent(t) => {
                if u < 0.5 * length {
                    t.incoming
                } else {
                    t.outgoing
                }
            }
        }
    }
}

/// A chain of pieces from a stop to the next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Chain {
    /// Pieces `first..end` of the plan.
    pub first: usize,
    pub end: usize,
    /// The segment the chain ends on (its last point is that segment's programmed end).
    pub last_segment: usize,
}

/// The pieces of a whole path.
#[derive(Debug, Clone, Default)]
pub(super) struct Pieces {
    pub pieces: Vec<Piece>,
    pub chains: Vec<Chain>,
    /// Vectors of the corner blends.
    pub arena: Vec<f64>,
    /// Per piece, the budget its limits are chosen from ([`assign_limits`]).
    pub budgets: Vec<Budget>,
}

/// How one junction is passed.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Junction {
    Stop,
    /// The segments continue each other (collinear lines, or one circle): nothing to blend.
    Smooth,
    Corner {
        blend: CornerBlend,
        budget: Budget,
    },
    Tangent {
        length: f64,
        budget: Budget,
    },
}

impl Junction {
    fn length(&self) -> f64 {
        match self {
            Junction::Corner { blend, .. } => blend.length,
            Junction::Tangent { length, .. } => *length,
            Junction::Stop | Junction::Smooth => 0.0,
        }
    }
}

/// The path budgets of a curved stretch, reduced over the axes so that every share costs O(1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Budget {
    /// min(feed, v_i/K1_i).
    velocity: f64,
    /// min a_i/K1_i, min j_i/K1_i.
    acceleration: f64,
    jerk: f64,
    /// min a_i/K2_i, min j_i/K3_i, min j_i/K2_i (infinite on a straight stretch).
    curve_acceleration: f64,
    curve_jerk: f64,
    cross_jerk: f64,
}

impl Budget {
    fn new(axes: &[AxisSpec], k1: &[f64], k2: &[f64], k3: &[f64], feed: Option<f64>) -> Budget {
        let mut b = Budget {
            velocity: feed.unwrap_or(f64::INFINITY),
            acceleration: f64::INFINITY,
            jerk: f64::INFINITY,
            curve_acceleration: f64::INFINITY,
            curve_jerk: f64::INFINITY,
            cross_jerk: f64::INFINITY,
        };
        for (i, axis) in axes.iter().enumerate() {
            let l = axis.limits;
            if k1[i] > 0.0 {
                b.velocity = b.velocity.min(l.velocity / k1[i]);
                b.acceleration = b.acceleration.min(l.acceleration / k1[i]);
                b.jerk = b.jerk.min(l.jerk / k1[i]);
            }
            if k2[i] > 0.0 {
                b.curve_acceleration = b.curve_acceleration.min(l.acceleration / k2[i]);
                b.cross_jerk = b.cross_jerk.min(l.jerk / k2[i]);
            }
            if k3[i] > 0.0 {
                b.curve_jerk = b.curve_jerk.min(l.jerk / k3[i]);
            }
        }
        b
    }

    pub fn is_straight(&self) -> bool {
        self.curve_acceleration == f64::INFINITY && self.curve_jerk == f64::INFINITY
    }

    /// Limits with centripetal share `rho` (see the module documentation).
    fn limits(&self, rho: f64) -> Limits {
        if self.is_straight() {
            return self.straight();
        }
        let v = self
            .velocity
            .min((rho * self.curve_acceleration).sqrt())
            .min((rho * self.curve_jerk).cbrt());
        let tangential = 1.0 - rho;
        let a = (tangential * self.acceleration).min(tangential * self.cross_jerk / (6.0 * v));
        Limits::new(v, a, tangential * self.jerk / 2.0)
    }

    /// The limits of the stretch if it were straight (no share to the curvature).
    pub fn straight(&self) -> Limits {
        if !self.velocity.is_finite() {
            // Nothing moves: any positive limits do.
            return Limits::new(1.0, 1.0, 1.0);
        }
        Limits::new(self.velocity, self.acceleration, self.jerk)
    }

    /// Limits with the smallest share whose speed ceiling reaches `speed` (the rest of the
    /// budget is left for changing speed), or the largest share up to `largest` if none does.
    fn limits_for(&self, speed: f64, largest: f64) -> Limits {
        if self.is_straight() {
            return self.straight();
        }
        let mut chosen = self.limits(SHARES[0]);
        for &rho in SHARES.iter().filter(|&&rho| rho <= largest) {
            chosen = self.limits(rho);
            if chosen.velocity >= speed {
                break;
            }
        }
        chosen
    }

    /// Whether the stretch curves (its limits depend on the share).
    pub fn is_curved(&self) -> bool {
        !self.is_straight()
    }
}

/// Per-axis derivative bounds of one stretch (scratch, reused).
#[derive(Debug, Clone, Default)]
struct AxisBounds {
    k1: Vec<f64>,
    k2: Vec<f64>,
    k3: Vec<f64>,
}

impl AxisBounds {
    fn new(n: usize) -> Self {
        AxisBounds {
            k1: vec![0.0; n],
            k2: vec![0.0; n],
            k3: vec![0.0; n],
        }
    }

    fn budget(&self, axes: &[AxisSpec], feed: Option<f64>) -> Budget {
        Budget::new(axes, &self.k1, &self.k2, &self.k3, feed)
    }
}

/// Builds the pieces of a path whose segments have the given shapes.
pub(super) struct Builder<'a> {
    axes: &'a [AxisSpec],
    segments: &'a [PathSegment],
    shapes: &'a Shapes,
    metric: &'a Metric,
    bounds: AxisBounds,
    tangent: TangentJunction,
    scratch: JetScratch,
    /// Per segment: the budget of the segment on its own.
    budgets: Vec<Budget>,
}

impl<'a> Builder<'a> {
    pub fn new(
        axes: &'a [AxisSpec],
        segments: &'a [PathSegment],
        shapes: &'a Shapes,
        metric: &'a Metric,
    ) -> Self {
        let n = axes.len();
        Builder {
            axes,
            segments,
            shapes,
            metric,
            bounds: AxisBounds::new(n),
            tangent: TangentJunction::default(),
            scratch: JetScratch::new(n),
            budgets: Vec::with_capacity(segments.len()),
        }
    }

    fn feed(&self, k: usize) -> Option<f64> {
        if self.shapes.shapes[k].feed_applies {
            self.segments[k].feed
        } else {
            None
        }
    }

    /// The budget of segment `k` on its own.
    fn segment_budget(&mut self, k: usize) -> Budget {
        for i in 0..self.axes.len() {
            self.bounds.k1[i] = self.shapes.bound(k, i, 1);
            self.bounds.k2[i] = self.shapes.bound(k, i, 2);
            self.bounds.k3[i] = self.shapes.bound(k, i, 3);
        }
        self.bounds.budget(self.axes, self.feed(k))
    }

    pub fn build(mut self) -> Pieces {
        let count = self.segments.len();
        let shapes = self.shapes;
        for k in 0..count {
            let budget = self.segment_budget(k);
            self.budgets.push(budget);
        }
        let moving: Vec<usize> = (0..count)
            .filter(|&k| shapes.shapes[k].length > 0.0)
            .collect();
        // Junction after each moving segment (the last one ends at a stop).
        let mut junctions = Vec::with_capacity(moving.len());
        for w in moving.windows(2) {
            let (p, k) = (w[0], w[1]);
            // The most restrictive blend of p and of any zero-length segments before k.
            let mut tolerance = Some(f64::INFINITY);
            for segment in &self.segments[p..k] {
                tolerance = match (tolerance, segment.blend) {
                    (None, _) | (_, Blend::ExactStop) => None,
                    (Some(t), Blend::Continuous { tolerance }) => {
                        Some(t.min(tolerance.unwrap_or(f64::INFINITY)))
                    }
                };
            }
            let junction = match tolerance {
                None => Junction::Stop,
                Some(tolerance) => self.junction(p, k, tolerance),
            };
            junctions.push(junction);
        }
        junctions.push(Junction::Stop);

        let mut out = Pieces {
            pieces: Vec::with_capacity(2 * moving.len()),
            chains: Vec::new(),
            arena: Vec::new(),
            budgets: Vec::with_capacity(2 * moving.len()),
        };
        // Each piece's budget; its limits follow once the chain's speeds are estimated.
        let budgets = &mut out.budgets;
        let placeholder = Limits::new(1.0, 1.0, 1.0);
        let mut s = 0.0;
        let mut chain_first = 0;
        let mut entry = 0.0;
        for (m, &k) in moving.iter().enumerate() {
            let junction = junctions[m];
            let exit = 0.5 * junction.length();
            let length = shapes.shapes[k].length;
            let middle = length - entry - exit;
            if middle > 0.0 {
                out.pieces.push(Piece {
                    kind: PieceKind::Segment {
                        segment: k,
                        from: entry,
                    },
                    start: s,
                    length: middle,
                    limits: placeholder,
                });
                budgets.push(self.budgets[k]);
                s += middle;
            }
            let next = moving.get(m + 1).copied().unwrap_or(k);
            match junction {
                Junction::Stop => {
                    out.chains.push(Chain {
                        first: chain_first,
                        end: out.pieces.len(),
                        last_segment: k,
                    });
                    chain_first = out.pieces.len();
                    s = 0.0;
                }
                Junction::Smooth => {}
                Junction::Corner { blend, budget } => {
                    let data = out.arena.len();
                    let n = self.axes.len();
                    let u1 = shapes.line_direction(k).unwrap_or(&[]);
                    let u2 = shapes.line_direction(next).unwrap_or(&[]);
                    let corner = shapes.end(k);
                    out.arena.extend((0..n).map(|i| corner[i] - u1[i] * exit));
                    out.arena.extend_from_slice(u1);
                    out.arena.extend((0..n).map(|i| u2[i] - u1[i]));
                    out.pieces.push(Piece {
                        kind: PieceKind::Corner {
                            incoming: k,
                            outgoing: next,
                            blend,
                            data,
                        },
                        start: s,
                        length: blend.length,
                        limits: placeholder,
                    });
                    budgets.push(budget);
                    s += blend.length;
                }
                Junction::Tangent { length, budget } => {
                    out.pieces.push(Piece {
                        kind: PieceKind::Tangent(TangentBlend {
                            incoming: k,
                            outgoing: next,
                            length,
                        }),
                        start: s,
                        length,
                        limits: placeholder,
                    });
                    budgets.push(budget);
                    s += length;
                }
            }
            entry = exit;
        }
        out
    }

    /// How the junction from segment `p` into segment `k` is passed, with the corner
    /// `tolerance` (m, infinite: as far as the segments allow).
    fn junction(&mut self, p: usize, k: usize, tolerance: f64) -> Junction {
        let shapes = self.shapes;
        let junction = match (shapes.line_direction(p), shapes.line_direction(k)) {
            (Some(u1), Some(u2)) => {
                if u1.iter().zip(u2).all(|(a, b)| (a - b).abs() <= 1e-12) {
                    return Junction::Smooth;
                }
                if tolerance == 0.0 {
                    return Junction::Stop;
                }
                self.corner(p, k, tolerance)
            }
            _ => {
                self.tangent
                    .new(shapes, p, k, self.metric, &mut self.scratch);
                if self.tangent.angle > TANGENT_ANGLE {
                    return Junction::Stop;
                }
                if self.tangent.is_smooth() {
                    return Junction::Smooth;
                }
                if tolerance == 0.0 {
                    return Junction::Stop;
                }
                self.tangent_blend(p, k, tolerance)
            }
        };
        match junction {
            Junction::Corner { budget, .. } | Junction::Tangent { budget, .. }
                if self.stop_is_faster(p, k, junction.length(), budget.limits(SIZING_SHARE)) =>
            {
                Junction::Stop
            }
            other => other,
        }
    }

    /// The corner blend between lines `p` and `k`.
    fn corner(&mut self, p: usize, k: usize, tolerance: f64) -> Junction {
        let shapes = self.shapes;
        let axes = self.axes;
        let n = axes.len();
        let u1 = shapes.line_direction(p).unwrap_or(&[]);
        let u2 = shapes.line_direction(k).unwrap_or(&[]);
        let du_norm = self.metric.norm_of(n, |i| u2[i] - u1[i]);
        let longest = shapes.shapes[p].length.min(shapes.shapes[k].length);
        let target = self.budgets[p]
            .straight()
            .velocity
            .min(self.budgets[k].straight().velocity);
        let feed = match (self.feed(p), self.feed(k)) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        let mut best: Option<(f64, CornerBlend)> = None;
        for &ramp in &RAMPS {
            let shape = TurnShape::new(ramp);
            let within = tolerance / (shape.midpoint_integral() * du_norm);
            // The shortest blend whose ceiling reaches the target speed, per axis.
            let mut needed: f64 = 0.0;
            for (i, axis) in axes.iter().enumerate() {
                let du = (u2[i] - u1[i]).abs();
                if du > 0.0 {
                    let l = axis.limits;
                    needed = needed
                        .max(target * target * shape.peak() * du / (SIZING_SHARE * l.acceleration))
                        .max(
                            (target.powi(3) * shape.peak_rate() * du / (SIZING_SHARE * l.jerk))
                                .sqrt(),
                        );
                }
            }
            let length = within.min(longest).min(needed);
            if !(length > 0.0) {
                continue;
            }
            self.corner_bounds(u1, u2, length, shape);
            let ceiling = self.bounds.budget(axes, feed).limits(SIZING_SHARE).velocity;
            if best.map_or(true, |(c, _)| ceiling > c) {
                best = Some((ceiling, CornerBlend { length, shape }));
            }
        }
        let Some((_, blend)) = best else {
            return Junction::Stop;
        };
        self.corner_bounds(u1, u2, blend.length, blend.shape);
        let budget = self.bounds.budget(axes, feed);
        Junction::Corner { blend, budget }
    }

    fn corner_bounds(&mut self, u1: &[f64], u2: &[f64], length: f64, shape: TurnShape) {
        for i in 0..u1.len() {
            let du = (u2[i] - u1[i]).abs();
            self.bounds.k1[i] = u1[i].abs().max(u2[i].abs());
            self.bounds.k2[i] = shape.peak() * du / length;
            self.bounds.k3[i] = shape.peak_rate() * du / (length * length);
        }
    }

    /// The tangent blend between segments `p` and `k` (self.tangent describes the junction).
    fn tangent_blend(&mut self, p: usize, k: usize, tolerance: f64) -> Junction {
        let shapes = self.shapes;
        let mut longest = shapes.shapes[p].length.min(shapes.shapes[k].length);
        if self.tangent.curvature > 0.0 {
            longest = longest.min(MAX_BLEND_TURN / self.tangent.curvature);
        }
        let length = self.tangent.length_within(tolerance, longest);
        if !(length > 0.0) {
            return Junction::Stop;
        }
        self.tangent.bounds(
            length,
            &mut self.bounds.k1,
            &mut self.bounds.k2,
            &mut self.bounds.k3,
        );
        let feed = match (self.feed(p), self.feed(k)) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        let budget = self.bounds.budget(self.axes, feed);
        Junction::Tangent { length, budget }
    }

    /// Whether stopping at the junction between `p` and `k` loses less time than a blend of
    /// `length` with `limits`. Each side would cruise at what it reaches from rest in half its
    /// length; slowing from cruise `v` to `u` and back loses about `T·(v − u)/(2·v)` (a change
    /// lasting T covers its distance at the mean speed), and the blend itself takes
    /// `length/u` where cruising would take `length/v`.
    fn stop_is_faster(&self, p: usize, k: usize, length: f64, limits: Limits) -> bool {
        let side = |segment: usize| {
            let l = self.budgets[segment].straight();
            let cruise = reachable_velocity(0.0, 0.5 * self.shapes.shapes[segment].length, &l);
            (l, cruise)
        };
        let sides = [side(p), side(k)];
        let loss = |u: f64| -> f64 {
            sides
                .iter()
                .map(|&(l, cruise)| {
                    if cruise <= u {
                        return 0.0;
                    }
                    let change = VelocityChange::new(cruise - u, l.acceleration, l.jerk);
                    change.duration() * (cruise - u) / (2.0 * cruise)
                })
                .sum()
        };
        let cruise = sides[0].1.max(sides[1].1);
        let u = limits.velocity.min(cruise);
        let blend = loss(u) + (length / u - length / cruise).max(0.0);
        loss(0.0) < blend
    }
}

/// Chooses the centripetal share of every piece of a chain from the speed it will be passed
/// at. The estimate is the acceleration-limited envelope (no jerk limit, the straight
/// acceleration, each piece's largest speed ceiling): zero at the chain's ends, capped at the
/// piece boundaries by both neighbours, `v² ≤ v0² + 2·A·s` from either side. Each piece then
/// gets the smallest share whose ceiling reaches the envelope's peak on it, leaving the rest of
/// its budget for speeding up and slowing down; a piece passed at its largest ceiling gets the
/// largest share.
pub(super) fn assign_limits(pieces: &mut [Piece], budgets: &[Budget], largest_share: f64) {
    let m = pieces.len();
    let optimistic: Vec<Limits> = budgets
        .iter()
        .map(|b| {
            let top = b.limits(SHARES[SHARES.len() - 1]);
            Limits::new(top.velocity, b.straight().acceleration, b.straight().jerk)
        })
        .collect();
    let mut speeds = vec![0.0; m + 1];
    for i in 1..m {
        speeds[i] = optimistic[i - 1].velocity.min(optimistic[i].velocity);
    }
    let reach =
        |v: f64, i: usize| (v * v + 2.0 * optimistic[i].acceleration * pieces[i].length).sqrt();
    for i in (0..m).rev() {
        speeds[i] = speeds[i].min(reach(speeds[i + 1], i));
    }
    for i in 0..m {
        speeds[i + 1] = speeds[i + 1].min(reach(speeds[i], i));
    }
    for i in 0..m {
        let (v0, v1) = (speeds[i], speeds[i + 1]);
        let peak = ((v0 * v0 + v1 * v1) / 2.0 + optimistic[i].acceleration * pieces[i].length)
            .sqrt()
            .min(optimistic[i].velocity);
        pieces[i].limits = budgets[i].limits_for(peak, largest_share);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budget_limits_keep_the_jerk_sum_within_the_axis_limit() {
        // One axis, bounds K1 = 1, K2 = 4, K3 = 9: every share keeps K3·v³ + 3·K2·v·a + K1·j
        // within j and K2·v² + K1·a within a.
        let axes = [AxisSpec {
            name: "x".into(),
            kind: super::super::path::AxisKind::Linear,
            limits: super::super::path::AxisLimits {
                velocity: 2.0,
                acceleration: 3.0,
                jerk: 50.0,
            },
        }];
        let budget = Budget::new(&axes, &[1.0], &[4.0], &[9.0], None);
        for rho in SHARES {
            let l = budget.limits(rho);
            assert!(
                9.0 * l.velocity.powi(3) + 12.0 * l.velocity * l.acceleration + l.jerk
                    <= 50.0 * (1.0 + 1e-12)
            );
            assert!(4.0 * l.velocity * l.velocity + l.acceleration <= 3.0 * (1.0 + 1e-12));
            assert!(l.velocity <= 2.0);
        }
    }
}
