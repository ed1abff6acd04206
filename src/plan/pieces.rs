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
use super::geometry::{norm, Metric, Shapes};
use super::path::{AxisLimits, AxisSpec, Blend, PathSegment};
use super::profile::{reachable_velocity, Limits, VelocityChange};
use super::quintic;
use super::tangent::{JetScratch, TangentBlend, TangentJunction};

/// Centripetal shares tried per curved piece.
const SHARES: [f64; 9] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];
/// Largest centripetal shares tried per chain (the planner keeps the fastest).
pub(super) const SHARE_CAPS: [f64; 2] = [0.95, 0.6];
/// Share assumed when sizing a blend for the speed it should allow.
const SIZING_SHARE: f64 = 0.8;
/// Ramp fractions tried per corner blend.
const RAMPS: [f64; 5] = [0.1, 0.2, 0.3, 0.4, 0.5];
/// Largest angle between the tangents of a line and an arc (or two arcs) that still counts as a
/// tangent junction (rad): about 3°. Larger corners involving an arc are stops.
pub const TANGENT_ANGLE: f64 = 0.05;
/// Most lines one smoothing curve runs through.
const MAX_CURVE_LINES: usize = 8;
/// Largest turn at either end of a line that is smoothed through its points (rad): 20°.
pub const SMOOTH_ANGLE: f64 = 0.35;
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
    /// A smoothed run of lines: the quintic whose coefficients are at `arena[data..]`, through
    /// the segments `covered[first..first + count]` of [`Pieces::covered`] (their lengths add up
    /// to the piece's).
    Quintic {
        data: usize,
        first: usize,
        count: usize,
    },
}

impl PieceKind {
    /// The segment the piece belongs to at `u` into it (blends: half and half).
    /// (Quintic pieces: see [`Pieces::segment_at`].)
    pub fn segment_at(&self, u: f64, length: f64) -> usize {
        match *self {
            PieceKind::Segment { segment, .. } => segment,
            PieceKind::Quintic { .. } => usize::MAX,
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
    /// Per piece, the budget its limits are chosen from ([`assign_limits`]), and the table
    /// of their per-axis bounds.
    pub budgets: Vec<Budget>,
    pub table: Budgets,
    /// The segments the quintic pieces run through.
    pub covered: Vec<usize>,
    /// Segment lengths (for finding the segment at a point of a quintic piece).
    pub lengths: Vec<f64>,
    /// Per segment: whether a smoothing curve runs through it (what a [`Seed`] freezes).
    pub smoothed: Vec<bool>,
}

/// What a window of a long chain planned after a handoff takes over from the window before
/// it, so that its pieces from the handoff on are the ones that window made: which of the
/// segments before the handoff that window smoothed (the data at a smoothing curve's ends
/// depends on them), and the segment a smoothing curve must start at (the first one the
/// window after the handoff plans; the curves before it are chosen again, and not used).
#[derive(Debug, Clone)]
pub(super) struct Seed {
    /// Per segment from the window's first on: smoothed in the window before.
    pub smoothed: Vec<bool>,
    /// The segment (of the window) no smoothing curve may start before and run into.
    pub curve_start: usize,
}

impl Pieces {
    /// The segment `piece` is on at `u` into it.
    pub fn segment_at(&self, piece: &Piece, u: f64) -> usize {
        let PieceKind::Quintic { first, count, .. } = piece.kind else {
            return piece.kind.segment_at(u, piece.length);
        };
        let covered = &self.covered[first..first + count];
        let mut end = 0.0;
        for &segment in covered {
            end += self.lengths[segment];
            if u < end {
                return segment;
            }
        }
        covered[count - 1]
    }
}

/// The smoothed lines of a path, grouped into curves that each span one or more of them.
struct Smoothing {
    /// Per moving segment: the curve it belongs to.
    curve_of: Vec<Option<usize>>,
    curves: Vec<SmoothCurve>,
    coefficients: Vec<f64>,
}

/// One quintic through a run of smoothed lines: moving segments `first..=last`.
#[derive(Debug, Clone, Copy)]
struct SmoothCurve {
    first: usize,
    last: usize,
    /// Where its coefficients start, and its length (the lines' lengths summed).
    offset: usize,
    length: f64,
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

/// The path budget of a stretch: its per-axis derivative bounds (kept in a shared table, see
/// [`Budgets`]) and their minima over the axes, which fix the speed ceiling of every share.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Budget {
    /// min(feed, v_i/K1_i).
    velocity: f64,
    /// min a_i/K1_i, min j_i/K1_i: the limits of a straight stretch.
    acceleration: f64,
    jerk: f64,
    /// min a_i/K2_i, min j_i/K3_i (infinite on a straight stretch).
    curve_acceleration: f64,
    curve_jerk: f64,
    /// Where K1, K2, K3 (one entry per axis each) start in the table (not stored for a
    /// straight stretch).
    bounds: usize,
}

/// The per-axis bounds of every budget, and the axes they are for.
#[derive(Debug, Clone, Default)]
pub(super) struct Budgets {
    axes: Vec<AxisLimits>,
    table: Vec<f64>,
}

impl Budgets {
    fn with_capacity(axes: &[AxisSpec], capacity: usize) -> Self {
        Budgets {
            axes: axes.iter().map(|a| a.limits).collect(),
            table: Vec::with_capacity(capacity),
        }
    }

    fn axes(&self) -> &[AxisLimits] {
        &self.axes
    }

    /// Stores the bounds of a stretch and returns its budget. A straight stretch's limits
    /// follow from its minima alone, so its bounds are not stored.
    fn add(&mut self, k1: &[f64], k2: &[f64], k3: &[f64], feed: Option<f64>) -> Budget {
        let b = Budget::reduce(&self.axes, k1, k2, k3, feed, self.table.len());
        if !b.is_straight() {
            self.table.extend_from_slice(k1);
            self.table.extend_from_slice(k2);
            self.table.extend_from_slice(k3);
        }
        b
    }

    /// The speed limit of [`Self::limits`] alone.
    fn velocity_limit(&self, b: &Budget, rho: f64) -> f64 {
        if b.is_straight() {
            b.straight().velocity
        } else {
            b.ceiling(rho)
        }
    }

    /// Limits with centripetal share `rho` (see the module documentation): the speed ceiling
    /// at which the curvature terms use at most `rho` of any axis's budgets, and, per axis, the
    /// acceleration and jerk along the path that what is left at that speed allows. An axis
    /// the path turns on little keeps most of its budget for speeding up and slowing down.
    pub fn limits(&self, b: &Budget, rho: f64) -> Limits {
        if b.is_straight() {
            return b.straight();
        }
        self.limits_at(b, b.ceiling(rho))
    }

    /// [`Self::limits`] of a curved stretch whose speed ceiling `v` is known.
    fn limits_at(&self, b: &Budget, v: f64) -> Limits {
        let n = self.axes.len();
        let k = &self.table[b.bounds..b.bounds + 3 * n];
        let (mut a, mut j) = (f64::INFINITY, f64::INFINITY);
        for (i, l) in self.axes.iter().enumerate() {
            let (k1, k2, k3) = (k[i], k[n + i], k[2 * n + i]);
            // What the curvature terms leave of this axis's budgets at speed v.
            let spare_acceleration = (l.acceleration - k2 * v * v).max(0.0);
            let spare_jerk = (l.jerk - k3 * v * v * v).max(0.0);
            // The jerk left is shared between the cross term 3·K2·v·s̈ and K1·s⃛.
            let cross_share = if k2 > 0.0 && k1 > 0.0 { 0.5 } else { 1.0 };
            if k1 > 0.0 {
                a = a.min(spare_acceleration / k1);
                j = j.min((1.0 - if k2 > 0.0 { 0.5 } else { 0.0 }) * spare_jerk / k1);
            }
            if k2 > 0.0 {
                a = a.min(cross_share * spare_jerk / (3.0 * k2 * v));
            }
        }
        Limits::new(v, a, j)
    }

    /// Limits with the smallest share whose speed ceiling reaches `speed` (the rest of the
    /// budget is left for changing speed), at least [`SHARES`]' smallest and at most `largest`,
    /// whose ceiling is `ceiling` (`b.ceiling(largest)`).
    fn limits_for(&self, b: &Budget, speed: f64, largest: f64, ceiling: f64) -> Limits {
        if b.is_straight() {
            return b.straight();
        }
        // The share each curvature term needs at `speed`: K2·v² ≤ ρ·a, K3·v³ ≤ ρ·j.
        let needed = (speed * speed / b.curve_acceleration).max(speed.powi(3) / b.curve_jerk);
        let rho = needed.clamp(SHARES[0], largest);
        if rho == largest {
            self.limits_at(b, ceiling)
        } else {
            self.limits(b, rho)
        }
    }
}

impl Budget {
    /// The minima over the axes of a stretch with bounds K1, K2, K3.
    fn reduce(
        axes: &[AxisLimits],
        k1: &[f64],
        k2: &[f64],
        k3: &[f64],
        feed: Option<f64>,
        bounds: usize,
    ) -> Budget {
        let mut b = Budget {
            velocity: feed.unwrap_or(f64::INFINITY),
            acceleration: f64::INFINITY,
            jerk: f64::INFINITY,
            curve_acceleration: f64::INFINITY,
            curve_jerk: f64::INFINITY,
            bounds,
        };
        for (i, l) in axes.iter().enumerate() {
            if k1[i] > 0.0 {
                b.velocity = b.velocity.min(l.velocity / k1[i]);
                b.acceleration = b.acceleration.min(l.acceleration / k1[i]);
                b.jerk = b.jerk.min(l.jerk / k1[i]);
            }
            if k2[i] > 0.0 {
                b.curve_acceleration = b.curve_acceleration.min(l.acceleration / k2[i]);
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

    /// The speed ceiling with centripetal share `rho`: `K2·v² ≤ rho·a`, `K3·v³ ≤ rho·j` on
    /// every axis, and the straight ceiling.
    fn ceiling(&self, rho: f64) -> f64 {
        let v = acceleration_ceiling(self.velocity, self.curve_acceleration, rho);
        jerk_ceiling(v, self.curve_jerk, rho)
    }

    /// The limits of the stretch if it were straight (no share to the curvature).
    pub fn straight(&self) -> Limits {
        if !self.velocity.is_finite() {
            // Nothing moves: any positive limits do.
            return Limits::new(1.0, 1.0, 1.0);
        }
        Limits::new(self.velocity, self.acceleration, self.jerk)
    }

    /// The centripetal share that `limits` (made by [`Budgets::limits`]) give the curvature
    /// terms: zero on a straight stretch.
    pub fn share_of(&self, limits: &Limits) -> f64 {
        if self.is_straight() {
            return 0.0;
        }
        let v = limits.velocity;
        (v * v / self.curve_acceleration).max(v.powi(3) / self.curve_jerk)
    }
}

/// The speed ceiling of [`Budget::ceiling`] before the jerk term: the straight ceiling
/// `velocity` and `K2·v² ≤ rho·a` on every axis.
fn acceleration_ceiling(velocity: f64, curve_acceleration: f64, rho: f64) -> f64 {
    velocity.min((rho * curve_acceleration).sqrt())
}

/// [`acceleration_ceiling`]'s `v` capped by the jerk term `K3·v³ ≤ rho·j` too. Never more than
/// one ulp above `v` (the cube root is taken only of a value below the rounded cube of `v`).
fn jerk_ceiling(v: f64, curve_jerk: f64, rho: f64) -> f64 {
    // The jerk term caps v only where v³ exceeds it (a cube is cheaper than a cube root).
    let jerk_cap = rho * curve_jerk;
    if v * v * v > jerk_cap {
        jerk_cap.cbrt()
    } else {
        v
    }
}

/// The feed that caps ṡ on segment `k` (of `segments`, whose shapes are `shapes`): its
/// programmed feed where its feed metric measures it, none where it does not (e.g. a purely
/// rotary move under the LinuxCNC rule).
pub(super) fn applied_feed(segments: &[PathSegment], shapes: &Shapes, k: usize) -> Option<f64> {
    segments[k].feed.filter(|_| shapes.shapes[k].feed_applies)
}

/// The lower of two feeds, either of which may not apply (a blend between two segments is
/// held to the lower).
pub(super) fn lowest_feed(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// Where [`binding_axes`]' rounding argument holds: numbers far from overflow and underflow.
const BINDING_RANGE: std::ops::RangeInclusive<f64> = 1e-50..=1e50;

/// The axes of a corner from direction `u1` to `u2` (as bits: axis `i` is bit `i`) that can
/// give the largest blend size and the lowest ceiling, whatever the ramp and the length: those
/// whose `a_i/|Δu_i|` (first mask) or `j_i/|Δu_i|` (second) is within 1e-9 of the lowest. Every
/// term of [`Builder::corner`] on an axis is its ratio times a factor common to all axes, to
/// within a few roundings (each of at most 2⁻⁵³ relative, while every number stays far from
/// overflow and underflow), so the other axes can neither hold the extreme nor tie with it.
/// All axes (every bit set) when the numbers are out of that range; axes past the 64th always
/// count.
fn binding_axes(axes: &[AxisSpec], u1: &[f64], u2: &[f64], target: f64) -> (u64, u64) {
    let all = (u64::MAX, u64::MAX);
    if !BINDING_RANGE.contains(&target) {
        return all;
    }
    let (mut lowest_a, mut lowest_j) = (f64::INFINITY, f64::INFINITY);
    for (i, axis) in axes.iter().enumerate() {
        let du = (u2[i] - u1[i]).abs();
        if du == 0.0 {
            continue;
        }
        let l = axis.limits;
        if !(BINDING_RANGE.contains(&du)
            && BINDING_RANGE.contains(&l.acceleration)
            && BINDING_RANGE.contains(&l.jerk))
        {
            return all;
        }
        lowest_a = lowest_a.min(l.acceleration / du);
        lowest_j = lowest_j.min(l.jerk / du);
    }
    let (mut by_acceleration, mut by_jerk) = (0u64, 0u64);
    for (i, axis) in axes.iter().enumerate().take(64) {
        let du = (u2[i] - u1[i]).abs();
        if du == 0.0 {
            continue;
        }
        if axis.limits.acceleration / du <= lowest_a * (1.0 + 1e-9) {
            by_acceleration |= 1 << i;
        }
        if axis.limits.jerk / du <= lowest_j * (1.0 + 1e-9) {
            by_jerk |= 1 << i;
        }
    }
    (by_acceleration, by_jerk)
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

    fn budget(&self, budgets: &mut Budgets, feed: Option<f64>) -> Budget {
        budgets.add(&self.k1, &self.k2, &self.k3, feed)
    }

    /// The budget's minima alone (not stored: for sizing).
    fn reduced(&self, axes: &[AxisLimits], feed: Option<f64>) -> Budget {
        Budget::reduce(axes, &self.k1, &self.k2, &self.k3, feed, usize::MAX)
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
    /// Per segment: the budget of the segment on its own (its per-axis bounds not stored).
    budgets: Vec<Budget>,
    /// Per segment: the speed it would cruise at between two stops ([`Self::stop_is_faster`]),
    /// once asked for (each segment is on two junctions).
    cruise: Vec<Option<f64>>,
    /// The per-axis bounds of every budget made.
    table: Budgets,
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
            cruise: vec![None; segments.len()],
            // A junction's budget and its segment's middle (or smoothing curve) per segment.
            table: Budgets::with_capacity(axes, 3 * axes.len() * 2 * segments.len()),
        }
    }

    fn feed(&self, k: usize) -> Option<f64> {
        applied_feed(self.segments, self.shapes, k)
    }

    /// The budget of segment `k` on its own. Only its minima are used (for sizing blends), so
    /// its per-axis bounds are not stored.
    fn segment_budget(&mut self, k: usize) -> Budget {
        self.range_bounds(k, 0.0, self.shapes.shapes[k].length);
        self.bounds.reduced(self.table.axes(), self.feed(k))
    }

    /// The budget of segment `k` over `s ∈ [lo, hi]`.
    fn range_budget(&mut self, k: usize, lo: f64, hi: f64) -> Budget {
        self.range_bounds(k, lo, hi);
        let feed = self.feed(k);
        self.bounds.budget(&mut self.table, feed)
    }

    /// The per-axis bounds of segment `k` over `s ∈ [lo, hi]`, into `self.bounds`.
    fn range_bounds(&mut self, k: usize, lo: f64, hi: f64) {
        for i in 0..self.axes.len() {
            self.bounds.k1[i] = self.shapes.bound_over(k, i, 1, lo, hi);
            self.bounds.k2[i] = self.shapes.bound_over(k, i, 2, lo, hi);
            self.bounds.k3[i] = self.shapes.bound_over(k, i, 3, lo, hi);
        }
    }

    /// The pieces of the segments; with a `seed`, the window starts at the margin before a
    /// handoff (see [`Seed`]).
    pub fn build(mut self, seed: Option<&Seed>) -> Pieces {
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
        let mut tolerances = Vec::with_capacity(moving.len());
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
            tolerances.push(tolerance.unwrap_or(0.0));
        }
        junctions.push(Junction::Stop);
        tolerances.push(0.0);
        let smooth = self.smooth_runs(&moving, &junctions, &tolerances, seed);
        let corners = junctions
            .iter()
            .filter(|j| matches!(j, Junction::Corner { .. }))
            .count();
        let n = self.axes.len();

        let mut out = Pieces {
            pieces: Vec::with_capacity(2 * moving.len()),
            chains: Vec::new(),
            arena: Vec::with_capacity(3 * n * corners + smooth.coefficients.len()),
            budgets: Vec::with_capacity(2 * moving.len()),
            covered: Vec::new(),
            lengths: shapes.shapes.iter().map(|s| s.length).collect(),
            table: Budgets::default(),
            smoothed: vec![false; count],
        };
        for (m, &k) in moving.iter().enumerate() {
            out.smoothed[k] = smooth.curve_of[m].is_some();
        }
        // Each piece's budget; its limits follow once the chain's speeds are estimated.
        let placeholder = Limits::new(1.0, 1.0, 1.0);
        let mut s = 0.0;
        let mut chain_first = 0;
        let mut entry = 0.0;
        for (m, &k) in moving.iter().enumerate() {
            // A junction next to a smoothed line is passed by the smoothing, not blended.
            let smoothed_next = smooth.curve_of.get(m + 1).is_some_and(|c| c.is_some());
            let junction = match junctions[m] {
                Junction::Corner { .. } | Junction::Tangent { .. }
                    if smooth.curve_of[m].is_some() || smoothed_next =>
                {
                    Junction::Smooth
                }
                other => other,
            };
            let exit = 0.5 * junction.length();
            let length = shapes.shapes[k].length;
            if let Some(c) = smooth.curve_of[m] {
                let curve = smooth.curves[c];
                if curve.first == m {
                    let n = self.axes.len();
                    let data = out.arena.len();
                    let width = n * quintic::COEFFICIENTS;
                    out.arena.extend_from_slice(
                        &smooth.coefficients[curve.offset..curve.offset + width],
                    );
                    let first = out.covered.len();
                    out.covered.extend(&moving[curve.first..=curve.last]);
                    out.pieces.push(Piece {
                        kind: PieceKind::Quintic {
                            data,
                            first,
                            count: curve.last - curve.first + 1,
                        },
                        start: s,
                        length: curve.length,
                        limits: placeholder,
                    });
                    quintic::bounds(
                        &out.arena[data..],
                        curve.length,
                        &mut self.bounds.k1,
                        &mut self.bounds.k2,
                        &mut self.bounds.k3,
                    );
                    let feed = moving[curve.first..=curve.last]
                        .iter()
                        .filter_map(|&q| self.feed(q))
                        .reduce(f64::min);
                    out.budgets.push(self.bounds.budget(&mut self.table, feed));
                    s += curve.length;
                }
            } else {
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
                    // A line's bounds are the same all along it: its own budget's.
                    let budget = match shapes.shapes[k].arc {
                        None => Budget {
                            bounds: self.table.table.len(),
                            ..self.budgets[k]
                        },
                        Some(_) => self.range_budget(k, entry, length - exit),
                    };
                    out.budgets.push(budget);
                    s += middle;
                }
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
                    out.budgets.push(budget);
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
                    out.budgets.push(budget);
                    s += length;
                }
            }
            entry = exit;
        }
        out.table = std::mem::take(&mut self.table);
        out
    }

    /// Chooses the lines to smooth ([`super::quintic`]) and their curves. A line is smoothed
    /// when both its junctions are continuous with a tolerance and turn by at most
    /// [`SMOOTH_ANGLE`] (or are tangent), and its curve stays within the tolerance of the
    /// programmed line; a line whose curve does not is left straight, which changes the data
    /// at the knots up to two lines away, so those are computed again (each line is dropped at
    /// most once, so the work stays linear). A `seed` fixes the choice on the segments it
    /// covers (the first stays straight: nothing before it is known) and where a curve starts.
    fn smooth_runs(
        &mut self,
        moving: &[usize],
        junctions: &[Junction],
        tolerances: &[f64],
        seed: Option<&Seed>,
    ) -> Smoothing {
        let shapes = self.shapes;
        let count = moving.len();
        let smoothable = |j: &Junction, p: usize, k: usize| match j {
            Junction::Corner { .. } => {
                let (Some(u1), Some(u2)) = (shapes.line_direction(p), shapes.line_direction(k))
                else {
                    return false;
                };
                let dot: f64 = u1.iter().zip(u2).map(|(a, b)| a * b).sum();
                let norms = norm(u1.iter().copied()) * norm(u2.iter().copied());
                dot >= norms * SMOOTH_ANGLE.cos()
            }
            Junction::Smooth | Junction::Tangent { .. } => true,
            Junction::Stop => false,
        };
        let frozen = |m: usize| seed.and_then(|seed| seed.smoothed.get(moving[m]).copied());
        let mut flags: Vec<bool> = (0..count)
            .map(|m| {
                if let Some(flag) = frozen(m) {
                    return m > 0 && flag;
                }
                m > 0
                    && m + 1 < count
                    && shapes.line_direction(moving[m]).is_some()
                    && tolerances[m - 1] > 0.0
                    && tolerances[m] > 0.0
                    && tolerances[m - 1].is_finite()
                    && tolerances[m].is_finite()
                    && smoothable(&junctions[m - 1], moving[m - 1], moving[m])
                    && smoothable(&junctions[m], moving[m], moving[m + 1])
            })
            .collect();
        let mut out = Smoothing {
            curve_of: vec![None; count],
            curves: Vec::new(),
            coefficients: Vec::new(),
        };
        if !flags.contains(&true) {
            return out;
        }
        let mut work: Vec<usize> = (0..count)
            .filter(|&m| flags[m] && frozen(m).is_none())
            .rev()
            .collect();
        let mut curve = Vec::new();
        // Stage 1: every line on its own must stay within its tolerance.
        while let Some(m) = work.pop() {
            if !flags[m] {
                continue;
            }
            if !self.fits(moving, &flags, m, m, tolerances, &mut curve) {
                // The data at the knots around depend on which lines are smoothed two
                // lines either way: those lines are checked again.
                flags[m] = false;
                let around = m.saturating_sub(2)..(m + 3).min(count);
                work.extend(around.filter(|&q| flags[q] && frozen(q).is_none()));
            }
        }
        // Stage 2: along each run, one curve through as many lines as stay within the
        // tolerance (a longer curve averages the points' rounding instead of turning with it).
        let curve_start = seed.map_or(0, |seed| moving.partition_point(|&k| k < seed.curve_start));
        let mut m = 0;
        while m < count {
            if !flags[m] {
                m += 1;
                continue;
            }
            let mut run_end = (m..count).find(|&q| !flags[q]).unwrap_or(count);
            if m < curve_start {
                run_end = run_end.min(curve_start);
            }
            let mut last = (m + MAX_CURVE_LINES - 1).min(run_end - 1);
            while last > m && !self.fits(moving, &flags, m, last, tolerances, &mut curve) {
                last -= 1;
            }
            if last == m {
                self.fits(moving, &flags, m, m, tolerances, &mut curve);
            }
            let c = out.curves.len();
            out.curves.push(SmoothCurve {
                first: m,
                last,
                offset: out.coefficients.len(),
                length: moving[m..=last]
                    .iter()
                    .map(|&q| shapes.shapes[q].length)
                    .sum(),
            });
            out.coefficients.extend_from_slice(&curve);
            for slot in &mut out.curve_of[m..=last] {
                *slot = Some(c);
            }
            m = last + 1;
        }
        out
    }

    /// Whether the curve through moving segments `first..=last` (into `curve`) stays within
    /// the tolerance: every programmed point it passes near, and the programmed lines.
    fn fits(
        &mut self,
        moving: &[usize],
        flags: &[bool],
        first: usize,
        last: usize,
        tolerances: &[f64],
        curve: &mut Vec<f64>,
    ) -> bool {
        let shapes = self.shapes;
        let start = self.knot(moving, flags, first - 1);
        let end = self.knot(moving, flags, last);
        let length: f64 = moving[first..=last]
            .iter()
            .map(|&q| shapes.shapes[q].length)
            .sum();
        curve.clear();
        quintic::coefficients(&start, &end, length, curve);
        quintic::bounds(
            curve,
            length,
            &mut self.bounds.k1,
            &mut self.bounds.k2,
            &mut self.bounds.k3,
        );
        let mut points: Vec<&[f64]> = Vec::with_capacity(last - first + 2);
        points.push(shapes.start(moving[first]));
        points.extend(moving[first..=last].iter().map(|&q| shapes.end(q)));
        let tolerance = tolerances[first - 1..=last]
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        quintic::deviation(curve, length, &points, &self.bounds.k1, self.metric) <= tolerance
    }

    /// The data at the point after moving segment `m`, for a smoothed line on either side.
    /// Between two smoothed lines: the least-squares parabola through the point and up to two
    /// neighbours on each side along the run (see [`quintic::Knot::fit`]).
    fn knot(&self, moving: &[usize], flags: &[bool], m: usize) -> quintic::Knot {
        let shapes = self.shapes;
        let (p, k) = (moving[m], moving[m + 1]);
        match (flags[m], flags[m + 1]) {
            (true, true) => {
                let mut points: Vec<&[f64]> = vec![shapes.start(p), shapes.end(p)];
                let mut s = vec![-shapes.shapes[p].length, 0.0];
                if m > 0 && flags[m - 1] {
                    let q = moving[m - 1];
                    points.insert(0, shapes.start(q));
                    s.insert(0, s[0] - shapes.shapes[q].length);
                }
                let at = points.len() - 1;
                points.push(shapes.end(k));
                s.push(shapes.shapes[k].length);
                if flags.get(m + 2).is_some_and(|&f| f) {
                    let q = moving[m + 2];
                    points.push(shapes.end(q));
                    s.push(s[s.len() - 1] + shapes.shapes[q].length);
                }
                quintic::Knot::fit(&points, &s, at)
            }
            // The other side continues as it is: a line, or an arc's own derivatives.
            (true, false) => self.end_knot(k, 0.0),
            _ => self.end_knot(p, shapes.shapes[p].length),
        }
    }

    /// The data of segment `k` itself at path coordinate `s`.
    fn end_knot(&self, k: usize, s: f64) -> quintic::Knot {
        let n = self.axes.len();
        let mut rows = vec![vec![0.0; n]; 3];
        {
            let mut refs: Vec<&mut [f64]> = rows.iter_mut().map(|r| r.as_mut_slice()).collect();
            self.shapes.jet(k, s, &mut refs);
        }
        let curvature = rows.pop().unwrap_or_default();
        let tangent = rows.pop().unwrap_or_default();
        let mut position = rows.pop().unwrap_or_default();
        // Exactly the programmed point (the jet of an arc rounds).
        let at_end = s > 0.0;
        position.copy_from_slice(if at_end {
            self.shapes.end(k)
        } else {
            self.shapes.start(k)
        });
        quintic::Knot {
            position,
            tangent,
            curvature,
        }
    }

    /// How the junction from segment `p` into segment `k` is passed, with the corner
    /// `tolerance` (m, infinite: as far as the segments allow).
    fn junction(&mut self, p: usize, k: usize, tolerance: f64) -> Junction {
        let shapes = self.shapes;
        // The blend, and its speed limit when sizing it found it.
        let (junction, sized_speed) = match (shapes.line_direction(p), shapes.line_direction(k)) {
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
                    .measure(shapes, p, k, self.metric, &mut self.scratch);
                if self.tangent.angle > TANGENT_ANGLE {
                    return Junction::Stop;
                }
                if self.tangent.is_smooth() {
                    return Junction::Smooth;
                }
                if tolerance == 0.0 {
                    return Junction::Stop;
                }
                (self.tangent_blend(p, k, tolerance), None)
            }
        };
        match junction {
            Junction::Corner { budget, .. } | Junction::Tangent { budget, .. } => {
                let speed = match sized_speed {
                    Some(speed) if !budget.is_straight() => speed,
                    _ => self.table.velocity_limit(&budget, SIZING_SHARE),
                };
                if self.stop_is_faster(p, k, junction.length(), speed) {
                    Junction::Stop
                } else {
                    junction
                }
            }
            other => other,
        }
    }

    /// The corner blend between lines `p` and `k`, and the speed ceiling of its budget with
    /// [`SIZING_SHARE`] (`Budget::ceiling`, found while sizing it).
    fn corner(&mut self, p: usize, k: usize, tolerance: f64) -> (Junction, Option<f64>) {
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
        let feed = lowest_feed(self.feed(p), self.feed(k));
        // The straight ceiling of every ramp's bounds (K1 = max(|u1|, |u2|) whatever the
        // blend's length), reduced as `Budget::reduce` reduces it.
        let mut velocity = feed.unwrap_or(f64::INFINITY);
        for (i, axis) in axes.iter().enumerate() {
            let k1 = u1[i].abs().max(u2[i].abs());
            if k1 > 0.0 {
                velocity = velocity.min(axis.limits.velocity / k1);
            }
        }
        // Only the axes that can hold the largest size or the lowest ceiling need computing.
        let (by_acceleration, by_jerk) = binding_axes(axes, u1, u2, target);
        let binds = |mask: u64, i: usize| i >= 64 || mask & (1 << i) != 0;
        let mut best: Option<(f64, CornerBlend)> = None;
        // The jerk cap whose cube root the best ceiling is, if it is one.
        let mut best_cap: Option<f64> = None;
        for &ramp in &RAMPS {
            let shape = TurnShape::new(ramp);
            let within = tolerance / (shape.midpoint_integral() * du_norm);
            // The shortest blend whose ceiling reaches the target speed, per axis: the largest
            // of the acceleration terms and of the jerk terms' square roots (the square root of
            // the largest, the same number: rounding keeps the square root monotonic).
            let (mut needed_by_acceleration, mut needed_by_jerk) = (0.0f64, 0.0f64);
            for (i, axis) in axes.iter().enumerate() {
                let du = (u2[i] - u1[i]).abs();
                if du > 0.0 {
                    let l = axis.limits;
                    if binds(by_acceleration, i) {
                        needed_by_acceleration = needed_by_acceleration.max(
                            target * target * shape.peak() * du / (SIZING_SHARE * l.acceleration),
                        );
                    }
                    if binds(by_jerk, i) {
                        needed_by_jerk = needed_by_jerk
                            .max(target.powi(3) * shape.peak_rate() * du / (SIZING_SHARE * l.jerk));
                    }
                }
            }
            let needed = needed_by_acceleration.max(needed_by_jerk.sqrt());
            let length = within.min(longest).min(needed);
            if length.is_nan() || length <= 0.0 {
                continue;
            }
            // The ceiling of the blend's budget (`corner_bounds`, then `Budget::reduce` and
            // `Budget::ceiling`), computed from the curvature bounds alone.
            let (mut curve_acceleration, mut curve_jerk) = (f64::INFINITY, f64::INFINITY);
            let in_range = BINDING_RANGE.contains(&length);
            for (i, axis) in axes.iter().enumerate() {
                let du = (u2[i] - u1[i]).abs();
                if !in_range || binds(by_acceleration, i) {
                    let k2 = shape.peak() * du / length;
                    if k2 > 0.0 {
                        curve_acceleration = curve_acceleration.min(axis.limits.acceleration / k2);
                    }
                }
                if !in_range || binds(by_jerk, i) {
                    let k3 = shape.peak_rate() * du / (length * length);
                    if k3 > 0.0 {
                        curve_jerk = curve_jerk.min(axis.limits.jerk / k3);
                    }
                }
            }
            let v = acceleration_ceiling(velocity, curve_acceleration, SIZING_SHARE);
            // The jerk term only lowers `v` (to at most one ulp above it): a `v` below the best
            // ceiling cannot beat it, and needs no cube root.
            if best.is_some_and(|(c, _)| v < c) {
                continue;
            }
            // Nor can a jerk cap no higher than the best's, when that is the cube root of its
            // own cap (rounding keeps the cube root monotonic).
            let jerk_cap = SIZING_SHARE * curve_jerk;
            let jerk_capped = v * v * v > jerk_cap;
            if jerk_capped && best_cap.is_some_and(|cap| jerk_cap <= cap) {
                continue;
            }
            let ceiling = jerk_ceiling(v, curve_jerk, SIZING_SHARE);
            if best.is_none_or(|(c, _)| ceiling > c) {
                best = Some((ceiling, CornerBlend { length, shape }));
                best_cap = jerk_capped.then_some(jerk_cap);
            }
        }
        let Some((ceiling, blend)) = best else {
            return (Junction::Stop, None);
        };
        self.corner_bounds(u1, u2, blend.length, blend.shape);
        let budget = self.bounds.budget(&mut self.table, feed);
        (Junction::Corner { blend, budget }, Some(ceiling))
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
        if length.is_nan() || length <= 0.0 {
            return Junction::Stop;
        }
        self.tangent.bounds(
            shapes,
            (p, k),
            length,
            &mut self.bounds.k1,
            &mut self.bounds.k2,
            &mut self.bounds.k3,
        );
        let feed = lowest_feed(self.feed(p), self.feed(k));
        let budget = self.bounds.budget(&mut self.table, feed);
        Junction::Tangent { length, budget }
    }

    /// Whether stopping at the junction between `p` and `k` loses less time than a blend of
    /// `length` with speed limit `speed`. Each side would cruise at what it reaches from rest in half its
    /// length; slowing from cruise `v` to `u` and back loses about `T·(v − u)/(2·v)` (a change
    /// lasting T covers its distance at the mean speed), and the blend itself takes
    /// `length/u` where cruising would take `length/v`.
    fn stop_is_faster(&mut self, p: usize, k: usize, length: f64, speed: f64) -> bool {
        let mut side = |segment: usize| {
            let l = self.budgets[segment].straight();
            let length = self.shapes.shapes[segment].length;
            let cruise = *self.cruise[segment]
                .get_or_insert_with(|| reachable_velocity(0.0, 0.5 * length, &l));
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
        let u = speed.min(cruise);
        let blend = loss(u) + (length / u - length / cruise).max(0.0);
        loss(0.0) < blend
    }
}

/// Chooses the centripetal share of every piece of a chain from the speed it will be passed
/// at, estimated by the acceleration-limited envelope of the chain (no jerk limit): zero at the
/// chain's ends (at its start, `entry_speed`: a window after a handoff), capped at the piece
/// boundaries by both neighbours' ceilings (each piece's largest with shares up to
/// `largest_share`), and reachable from either side with the tangential acceleration the
/// curvature leaves at each speed. With `A = min a_i/K1_i` and `W = min a_i/K2_i`, the
/// tangential acceleration at speed v is `A·(1 − v²/W)`, so
/// `d(v²)/ds = 2·A·(1 − v²/W)` and `v²(s) = W + (v0² − W)·e^(−2·A·s/W)` (on a straight piece
/// `v0² + 2·A·s`). Each piece then gets the share its envelope peak needs, leaving the rest of
/// its budget for speeding up and slowing down.
pub(super) fn assign_limits(
    pieces: &mut [Piece],
    budgets: &[Budget],
    table: &Budgets,
    largest_share: f64,
    entry_speed: f64,
    scratch: &mut Vec<f64>,
) {
    let m = pieces.len();
    scratch.clear();
    scratch.extend(budgets.iter().map(|b| b.ceiling(largest_share)));
    scratch.resize(2 * m + 1, 0.0);
    let (ceiling, speeds) = scratch.split_at_mut(m);
    // v² reached from v0² over `length` of piece `i`.
    let reach = |w0: f64, i: usize| -> f64 {
        let b = &budgets[i];
        let (a, w) = (b.acceleration, b.curve_acceleration);
        let length = pieces[i].length;
        let reached = if w.is_finite() {
            w + (w0 - w) * (-2.0 * a * length / w).exp()
        } else {
            w0 + 2.0 * a * length
        };
        reached.min(ceiling[i] * ceiling[i])
    };
    speeds[0] = entry_speed * entry_speed;
    speeds[m] = 0.0;
    for i in 1..m {
        speeds[i] = (ceiling[i - 1] * ceiling[i - 1]).min(ceiling[i] * ceiling[i]);
    }
    for i in (0..m).rev() {
        speeds[i] = speeds[i].min(reach(speeds[i + 1], i));
    }
    for i in 0..m {
        speeds[i + 1] = speeds[i + 1].min(reach(speeds[i], i));
    }
    for i in 0..m {
        let (w0, w1) = (speeds[i], speeds[i + 1]);
        let b = &budgets[i];
        let (a, w) = (b.acceleration, b.curve_acceleration);
        let length = pieces[i].length;
        // Where the rise from the entry meets the fall to the exit.
        let peak = if w.is_finite() {
            let rate = 2.0 * a / w;
            let (d0, d1) = ((w - w0).max(0.0), (w - w1).max(0.0));
            if d0 == 0.0 || d1 == 0.0 || rate * length == 0.0 {
                w0.max(w1)
            } else {
                let s = ((d0 / d1).ln() + rate * length) / (2.0 * rate);
                let s = s.clamp(0.0, length);
                (w - d0 * (-rate * s).exp()).max(w1.min(w0))
            }
        } else {
            (w0 + w1) / 2.0 + a * length
        };
        let peak = peak.min(ceiling[i] * ceiling[i]).sqrt();
        pieces[i].limits = table.limits_for(&budgets[i], peak, largest_share, ceiling[i]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budget_limits_keep_the_jerk_sum_within_every_axis_limit() {
        // Two axes with different bounds: every share keeps K3·v³ + 3·K2·v·a + K1·j within j
        // and K2·v² + K1·a within a on both, and the curvature terms take exactly the share
        // on one of them (or the speed limit binds).
        let axis = |v, a, j| AxisSpec {
            name: "q".into(),
            kind: super::super::path::AxisKind::Linear,
            limits: AxisLimits {
                velocity: v,
                acceleration: a,
                jerk: j,
            },
        };
        let axes = [axis(2.0, 3.0, 50.0), axis(1.0, 5.0, 20.0)];
        let mut table = Budgets::with_capacity(&axes, 6);
        let (k1, k2, k3) = ([1.0, 0.2], [4.0, 9.0], [9.0, 2.0]);
        let budget = table.add(&k1, &k2, &k3, None);
        for rho in SHARES {
            let l = table.limits(&budget, rho);
            let (v, a, j) = (l.velocity, l.acceleration, l.jerk);
            let mut share: f64 = 0.0;
            let mut speed: f64 = 0.0;
            for (i, axis) in axes.iter().enumerate() {
                let jerk = k3[i] * v.powi(3) + 3.0 * k2[i] * v * a + k1[i] * j;
                let acceleration = k2[i] * v * v + k1[i] * a;
                assert!(jerk <= axis.limits.jerk * (1.0 + 1e-12), "{rho} {i}");
                assert!(acceleration <= axis.limits.acceleration * (1.0 + 1e-12));
                assert!(k1[i] * v <= axis.limits.velocity * (1.0 + 1e-12));
                share = share
                    .max(k2[i] * v * v / axis.limits.acceleration)
                    .max(k3[i] * v.powi(3) / axis.limits.jerk);
                speed = speed.max(k1[i] * v / axis.limits.velocity);
            }
            assert!(
                (share - rho).abs() < 1e-12 || (speed - 1.0).abs() < 1e-12,
                "{rho}"
            );
        }
    }
}
