//! The solid a tool sweeps on a straight move with a fixed axis, cut along axis-aligned rays.
//!
//! The tool (tip at the origin, axis `n`, heights `h` along it) is a union of simple convex
//! pieces: a cylinder of radius `R` for `h ∈ [r, reach]` (`r` the corner radius) and, at the
//! bottom, a ball of radius `R` centred at `h = R` (ball end) or a "puck": the disc of radius
//! `R − r` at `h = r` grown by a ball of radius `r` (bull nose). A flat end is the cylinder
//! alone from `h = 0`. The tool, and so its sweep, is convex, so a ray meets the sweep in one
//! interval: the hull of the intervals where it meets the pieces' sweeps.
//!
//! A piece at time `t ∈ [0, 1]` of the move is displaced by `t·d`. A ray point
//! `p + s·e` is in the piece's sweep iff some `t` puts it in the displaced piece, so the ray's
//! interval is the range of `s` over a convex region of the `(s, t)` plane. For cylinders and
//! balls that region is an ellipse (a convex quadratic `Q(s, t) ≤ c`) cut by strips (`t`
//! in `[0, 1]`, height in the piece's range): its extremes in `s` are found in closed form
//! among the polygon's vertices, the polygon edges' crossings of `Q = c`, and the ellipse's own
//! extremes. The puck's sweep is the set within `r` of a disc swept along `d`: its distance is
//! convex along the ray, and Newton's method from either end converges to the interval's ends
//! monotonically.
//!
//! Most rays need none of that. A piece `P` swept along `d` meets the ray where some
//! `P + t·d` does; where the ray meets `P + t·d` its entry `s₀(t)` is convex and its exit
//! `s₁(t)` concave in `t` (the set `{(s, t)}` is convex), with slopes `ν·d/ν·e` at the surface
//! points (outward normal `ν`). So an end whose surface point on the piece at the start
//! faces away from the motion (`ν·d ≤ 0`) is the start placement's own end, and one whose point
//! at the end of the move faces along it (`ν·d ≥ 0`) is the end placement's: only rays whose
//! end crosses the piece's silhouette against the motion during the move (and rays that miss
//! either placement) need the exact geometry. For cylinders and balls those placements are
//! closed forms; see [`RaySweep::interval`].

use nalgebra::{Point3, Vector3};

use super::super::tool::{Tool, ToolShape};

/// Tolerance for a candidate point lying in the strips' polygon (m or 1).
const INSIDE_TOL: f64 = 1e-12;

#[derive(Debug, Clone, Copy)]
enum Piece {
    /// Cylinder of squared radius `r2` for heights `[h0, h1]`.
    Cylinder { r2: f64, h0: f64, h1: f64 },
    /// Ball of squared radius `r2` centred at height `ch`.
    Ball { ch: f64, r2: f64 },
    /// Disc of radius `rho` at height `ch`, grown by a ball of radius `r`.
    Puck { ch: f64, rho: f64, r: f64 },
}

/// A tool swept on a straight move with a fixed axis.
#[derive(Debug, Clone)]
pub(crate) struct Sweep {
    tip: Point3<f64>,
    d: Vector3<f64>,
    n: Vector3<f64>,
    pieces: [Option<Piece>; 2],
    min: Point3<f64>,
    max: Point3<f64>,
    enclosing: Enclosing,
    /// A still ball holding the end piece's whole sweep (ball or puck): its centre and
    /// squared radius.
    end_ball: Option<(Point3<f64>, f64)>,
    /// The unit normal of the plane of the axis and the move, if they span one.
    across: Option<Vector3<f64>>,
}

/// A still cylinder holding the cylinder piece's whole sweep: the piece's at the move's middle,
/// its radius and height range grown by half the move across and along the axis. With
/// [`Sweep::end_ball`] it bounds the sweep: a ray that misses both, or whose material lies
/// outside them, needs no exact geometry.
#[derive(Debug, Clone, Copy)]
struct Enclosing {
    centre: Point3<f64>,
    radius2: f64,
    /// Heights along the axis from `centre`.
    lo: f64,
    hi: f64,
    /// Half the sweep's width across the plane of the axis and the move: the radius.
    slab: f64,
}

impl Sweep {
    /// The part of the tool between heights `lo` and `hi` above its tip (with the ball or
    /// puck at the bottom when `lo` is 0), moving its tip from `p0` to `p1` with the unit
    /// axis `n`. The caller has checked the tool and `hi ≥ max(R, 2r)` where `lo` is 0.
    pub(crate) fn new(
        tool: &Tool,
        lo: f64,
        hi: f64,
        p0: Point3<f64>,
        p1: Point3<f64>,
        n: Vector3<f64>,
    ) -> Sweep {
        let big = tool.radius();
        let r = tool.corner_radius();
        let cylinder = |h0: f64| Piece::Cylinder {
            r2: big * big,
            h0: h0.max(lo),
            h1: hi,
        };
        let pieces = match tool.shape {
            ToolShape::Flat => [Some(cylinder(0.0)), None],
            ToolShape::Ball if lo == 0.0 => [
                Some(cylinder(big)),
                Some(Piece::Ball {
                    ch: big,
                    r2: big * big,
                }),
            ],
            ToolShape::Bull { .. } if lo == 0.0 => [
                Some(cylinder(r)),
                Some(Piece::Puck {
                    ch: r,
                    rho: big - r,
                    r,
                }),
            ],
            ToolShape::Ball | ToolShape::Bull { .. } => [Some(cylinder(lo)), None],
        };
        // The tool lies in the cylinder of radius R over [lo, top] (the ball or puck may reach
        // above `hi`); its box per axis is the axis segment's widened by R·sin(angle to that
        // axis).
        let top = match pieces[1] {
            Some(Piece::Ball { .. }) => hi.max(2.0 * big),
            Some(Piece::Puck { .. }) => hi.max(2.0 * r),
            _ => hi,
        };
        let mut min = Point3::from(Vector3::repeat(f64::INFINITY));
        let mut max = Point3::from(Vector3::repeat(f64::NEG_INFINITY));
        for a in 0..3 {
            let ext = big * (1.0 - n[a] * n[a]).max(0.0).sqrt() + 1e-9;
            for p in [p0, p1] {
                for q in [p[a] + lo * n[a], p[a] + top * n[a]] {
                    min[a] = min[a].min(q - ext);
                    max[a] = max[a].max(q + ext);
                }
            }
        }
        let d = p1 - p0;
        let along = d.dot(&n);
        let across = (d - n * along).norm();
        let mid = p0 + d * 0.5;
        let (h0, h1) = match pieces[0] {
            Some(Piece::Cylinder { h0, h1, .. }) => (h0, h1),
            _ => (lo, hi),
        };
        // The end piece lies within its centre's ball of radius R (ball) or ρ + r (puck);
        // swept, within that ball at the move's middle grown by half the move.
        let end_ball = end_piece(pieces[1])
            .map(|(ch, radius)| (mid + n * ch, (radius + 0.5 * d.norm() + 1e-9).powi(2)));
        Sweep {
            tip: p0,
            d,
            n,
            pieces,
            min,
            max,
            enclosing: Enclosing {
                centre: mid,
                radius2: (big + 0.5 * across + 1e-9).powi(2),
                lo: h0 - 0.5 * along.abs() - 1e-9,
                hi: h1 + 0.5 * along.abs() + 1e-9,
                slab: big,
            },
            end_ball,
            across: n.cross(&d).try_normalize(1e-12 * (1.0 + d.norm())),
        }
    }

    /// Bounding box of the swept solid (m).
    pub(crate) fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        (self.min, self.max)
    }

    /// The sweep prepared for rays along axis `k`.
    pub(crate) fn for_axis(&self, k: usize) -> RaySweep<'_> {
        let e = Vector3::ith(k, 1.0);
        let n = self.n;
        let d = self.d;
        let pieces = self.pieces.map(|p| {
            p.map(|piece| match piece {
                Piece::Cylinder { .. } => {
                    let we = e - n * n[k];
                    let wd = d - n * d.dot(&n);
                    Prepared {
                        piece,
                        a: we.dot(&we),
                        b: -we.dot(&wd),
                        c: wd.dot(&wd),
                        we,
                        wd,
                        hs: n[k],
                        ht: -d.dot(&n),
                    }
                }
                Piece::Ball { .. } | Piece::Puck { .. } => Prepared {
                    piece,
                    a: 1.0,
                    b: -d[k],
                    c: d.dot(&d),
                    we: e,
                    wd: d,
                    hs: 0.0,
                    ht: 0.0,
                },
            })
        });
        RaySweep {
            sweep: self,
            k,
            pieces,
        }
    }
}

/// A bound on the union of many sweeps (moves of a path before its last): a ray that meets
/// none of it, or whose material within it the sweeps already looked at take, needs none of
/// those sweeps' geometry. It is the cylinder pieces' axis positions, taken
/// across a common axis `n̄`, within `ε` of the segment joining the first sweep's start and
/// the last sweep's end (so the pieces lie within `R + ε` of it, across `n̄`, between two
/// heights), and the end pieces' centres within `ε` of their own segment (so the end pieces
/// lie within a capsule). A path that stays near its chord has a tight bound; one that
/// wanders or turns much gets a loose one, and its sweeps are then looked at one by one.
#[derive(Debug, Clone)]
pub(crate) struct GroupBound {
    /// The common axis.
    n: Vector3<f64>,
    /// The axis segment's ends projected across `n̄`, and its radius.
    side: (Vector3<f64>, Vector3<f64>, f64),
    /// Heights along `n̄` (m, from the origin) the cylinder pieces lie between.
    heights: (f64, f64),
    /// The end pieces' capsule: segment ends and radius.
    end: Option<(Vector3<f64>, Vector3<f64>, f64)>,
}

impl GroupBound {
    /// The bound of `sweeps` (none if empty).
    pub(crate) fn of(sweeps: &[&Sweep]) -> Option<GroupBound> {
        let (first, last) = (sweeps.first()?, sweeps.last()?);
        let n = sweeps
            .iter()
            .map(|s| s.n)
            .sum::<Vector3<f64>>()
            .try_normalize(1e-12)?;
        let across = |v: Vector3<f64>| v - n * v.dot(&n);
        let (a, b) = (across(first.tip.coords), across((last.tip + last.d).coords));
        let (mut spread, mut lo, mut hi, mut radius) =
            (0.0f64, f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
        let mut ends = Vec::new();
        for sw in sweeps {
            let (h0, h1) = match sw.pieces[0] {
                Some(Piece::Cylinder { h0, h1, .. }) => (h0, h1),
                _ => (0.0, 0.0),
            };
            let tilt = across(sw.n).norm();
            let (cos, big) = (sw.n.dot(&n), sw.enclosing.slab);
            radius = radius.max(big);
            for tip in [sw.tip, sw.tip + sw.d] {
                let off = segment_distance(&across(tip.coords), &a, &b);
                spread = spread.max(off + h0.abs().max(h1.abs()) * tilt);
                let base = tip.coords.dot(&n);
                for h in [h0, h1] {
                    lo = lo.min(base + h * cos - big * tilt);
                    hi = hi.max(base + h * cos + big * tilt);
                }
                if let Some((centre, r)) = end_piece(sw.pieces[1]) {
                    ends.push((tip.coords + sw.n * centre, r));
                }
            }
        }
        let end = match (ends.first(), ends.last()) {
            (Some(&(ea, _)), Some(&(eb, _))) => {
                let r = ends
                    .iter()
                    .map(|(c, r)| segment_distance(c, &ea, &eb) + r)
                    .fold(0.0, f64::max);
                Some((ea, eb, r + 1e-9))
            }
            _ => None,
        };
        Some(GroupBound {
            n,
            side: (a, b, radius + spread + 1e-9),
            heights: (lo - 1e-9, hi + 1e-9),
            end,
        })
    }

    /// Where the ray `p + s·e_k` can meet any of the sweeps: a superset of the hull of their
    /// intervals.
    pub(crate) fn bound(&self, p: &Point3<f64>, k: usize) -> Option<(f64, f64)> {
        let e = Vector3::ith(k, 1.0);
        let n = &self.n;
        let side = {
            let (a, b, rho) = &self.side;
            let h = p.coords.dot(n);
            // Heights h + s·n_k within the pieces' heights.
            let (lo, hi) = if n[k].abs() > 1e-12 {
                let (x, y) = ((self.heights.0 - h) / n[k], (self.heights.1 - h) / n[k]);
                (x.min(y), x.max(y))
            } else if (self.heights.0..=self.heights.1).contains(&h) {
                (f64::NEG_INFINITY, f64::INFINITY)
            } else {
                (f64::INFINITY, f64::NEG_INFINITY)
            };
            (lo <= hi)
                .then(|| {
                    let (q0, w) = (p.coords - n * h, e - n * n[k]);
                    ray_capsule(&q0, &w, a, b, *rho)
                })
                .flatten()
                .and_then(|(x, y)| {
                    let (x, y) = (x.max(lo), y.min(hi));
                    (x <= y).then_some((x, y))
                })
        };
        let end = self
            .end
            .as_ref()
            .and_then(|(a, b, rho)| ray_capsule(&p.coords, &e, a, b, *rho));
        match (side, end) {
            (Some((a, b)), Some((c, d))) => Some((a.min(c), b.max(d))),
            (Some(i), None) | (None, Some(i)) => Some(i),
            (None, None) => None,
        }
    }
}

/// Group bounds over a path's moves, halved down to a few moves each: a ray the whole group
/// cannot add to costs one test; one it can is asked of each half, so that the sweeps looked
/// at one by one are the few near the ray.
#[derive(Debug, Clone)]
pub(crate) struct GroupTree {
    /// The nodes, the root first.
    pub(crate) nodes: Vec<GroupNode>,
}

/// A node of a [`GroupTree`].
#[derive(Debug, Clone)]
pub(crate) struct GroupNode {
    /// The sweeps it holds (indices into the sweeps the tree was built on).
    pub(crate) sweeps: std::ops::Range<usize>,
    /// Their bound (none: no common axis; every ray is asked of the sweeps).
    pub(crate) bound: Option<GroupBound>,
    /// Its halves (earlier, later), unless it is a leaf.
    pub(crate) halves: Option<(usize, usize)>,
}

/// Most sweeps of a leaf of a [`GroupTree`].
const LEAF_SWEEPS: usize = 4;

impl GroupTree {
    /// The tree over `sweeps` (no nodes if there are none).
    pub(crate) fn new(sweeps: &[&Sweep]) -> GroupTree {
        let mut tree = GroupTree { nodes: Vec::new() };
        if !sweeps.is_empty() {
            tree.build(sweeps, 0..sweeps.len());
        }
        tree
    }

    fn build(&mut self, sweeps: &[&Sweep], range: std::ops::Range<usize>) -> usize {
        let at = self.nodes.len();
        self.nodes.push(GroupNode {
            sweeps: range.clone(),
            bound: GroupBound::of(&sweeps[range.clone()]),
            halves: None,
        });
        if range.len() > LEAF_SWEEPS {
            let mid = range.start + range.len() / 2;
            let earlier = self.build(sweeps, range.start..mid);
            let later = self.build(sweeps, mid..range.end);
            self.nodes[at].halves = Some((earlier, later));
        }
        at
    }
}

/// An end piece's centre height and the radius of a ball holding it (a ball's own, a puck's
/// disc radius plus its corner radius).
fn end_piece(piece: Option<Piece>) -> Option<(f64, f64)> {
    match piece {
        Some(Piece::Ball { ch, r2 }) => Some((ch, r2.sqrt())),
        Some(Piece::Puck { ch, rho, r }) => Some((ch, rho + r)),
        _ => None,
    }
}

/// Distance (m) from `p` to the segment `a`–`b`.
fn segment_distance(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let d = b - a;
    let l2 = d.norm_squared();
    let t = if l2 > 0.0 {
        ((p - a).dot(&d) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + d * t)).norm()
}

/// Where the line `q0 + s·w` lies within `rho` of the segment `a`–`b` (a capsule; all
/// vectors in one space): a range of `s`, unbounded when `w` is zero and `q0` inside.
fn ray_capsule(
    q0: &Vector3<f64>,
    w: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    rho: f64,
) -> Option<(f64, f64)> {
    let ww = w.norm_squared();
    if ww < 1e-24 {
        return (segment_distance(q0, a, b) <= rho).then_some((f64::NEG_INFINITY, f64::INFINITY));
    }
    // |r0 + s·r1|² ≤ rho² for s within [lo, hi].
    let quadratic = |r0: Vector3<f64>, r1: Vector3<f64>, lo: f64, hi: f64| {
        let (qa, qb, qc) = (
            r1.norm_squared(),
            r0.dot(&r1),
            r0.norm_squared() - rho * rho,
        );
        let (x, y) = if qa > 1e-24 {
            let disc = qb * qb - qa * qc;
            if disc < 0.0 {
                return None;
            }
            let root = disc.sqrt();
            ((-qb - root) / qa, (-qb + root) / qa)
        } else if qc <= 0.0 {
            (f64::NEG_INFINITY, f64::INFINITY)
        } else {
            return None;
        };
        let (x, y) = (x.max(lo), y.min(hi));
        (x <= y).then_some((x, y))
    };
    let ball = |c: &Vector3<f64>| quadratic(q0 - c, *w, f64::NEG_INFINITY, f64::INFINITY);
    let d = b - a;
    let length = d.norm();
    if length == 0.0 {
        return ball(a);
    }
    let dh = d / length;
    // The infinite cylinder around the segment's line holds both end balls: where the line
    // meets it within the segment's slab, that is the capsule; beyond the slab on either side
    // only that side's ball can add to it.
    let (t0, t1) = ((q0 - a).dot(&dh), w.dot(&dh));
    let (x, y) = quadratic(
        (q0 - a) - dh * t0,
        w - dh * t1,
        f64::NEG_INFINITY,
        f64::INFINITY,
    )?;
    // The slab, (q0 − a + s·w)·d̂ within [0, length], and its ends' balls in order of s.
    let (lo, hi, ends) = if t1.abs() > 1e-300 {
        let (p, q) = (-t0 / t1, (length - t0) / t1);
        if t1 > 0.0 {
            (p, q, [a, b])
        } else {
            (q, p, [b, a])
        }
    } else if t0 < 0.0 {
        (f64::INFINITY, f64::INFINITY, [a, a])
    } else if t0 > length {
        (f64::NEG_INFINITY, f64::NEG_INFINITY, [b, b])
    } else {
        (f64::NEG_INFINITY, f64::INFINITY, [a, b])
    };
    let middle = (x.max(lo) <= y.min(hi)).then_some((x.max(lo), y.min(hi)));
    let before = if x < lo { ball(ends[0]) } else { None };
    let after = if y > hi { ball(ends[1]) } else { None };
    [before, middle, after]
        .into_iter()
        .flatten()
        .reduce(|(p, q), (r, s)| (p.min(r), q.max(s)))
}

/// A piece with its ray-direction-dependent constants.
#[derive(Debug, Clone, Copy)]
struct Prepared {
    piece: Piece,
    /// Quadratic coefficients of `s²`, `2st`, `t²` (see [`Quadratic`]).
    a: f64,
    b: f64,
    c: f64,
    /// Transverse (to the axis) parts of the ray direction and the motion (cylinder), or the
    /// direction and motion themselves (ball, puck).
    we: Vector3<f64>,
    wd: Vector3<f64>,
    /// Height along the axis per unit `s` and per unit `t` (cylinder).
    hs: f64,
    ht: f64,
}

/// A sweep prepared for rays along one axis.
pub(crate) struct RaySweep<'a> {
    sweep: &'a Sweep,
    k: usize,
    pieces: [Option<Prepared>; 2],
}

/// `Q(s, t) = a s² + 2b st + c t² + 2d s + 2e t + f`.
#[derive(Debug, Clone, Copy)]
struct Quadratic {
    a: f64,
    b: f64,
    c: f64,
    d: f64,
    e: f64,
    f: f64,
}

impl Quadratic {
    #[inline]
    fn at(&self, s: f64, t: f64) -> f64 {
        s * (self.a * s + 2.0 * (self.b * t + self.d)) + t * (self.c * t + 2.0 * self.e) + self.f
    }
}

impl RaySweep<'_> {
    /// Where the ray `p + s·e_k` can meet the swept solid at all: the hull of its intervals in
    /// the enclosing cylinder and the end piece's enclosing ball, within the slab across the
    /// move; a cheap superset of [`RaySweep::interval`]'s.
    pub(crate) fn bound(&self, p: &Point3<f64>) -> Option<(f64, f64)> {
        let k = self.k;
        let cylinder = self.enclosing_cylinder(p);
        let ball = self.sweep.end_ball.and_then(|(centre, radius2)| {
            // |y + s·e_k|² ≤ ρ²: s² + 2 y_k s + |y|² − ρ² ≤ 0.
            let y = p - centre;
            let (b, c) = (y[k], y.norm_squared() - radius2);
            let disc = b * b - c;
            (disc >= 0.0).then(|| {
                let root = disc.sqrt();
                (-b - root, -b + root)
            })
        });
        let (mut lo, mut hi) = match (cylinder, ball) {
            (Some((a, b)), Some((c, d))) => (a.min(c), b.max(d)),
            (Some(i), None) | (None, Some(i)) => i,
            (None, None) => return None,
        };
        // The slab across the move: no point of the sweep is farther than R from the plane of
        // the axis and the move.
        if let Some(m) = self.sweep.across {
            let (y0, mk) = ((p - self.sweep.tip).dot(&m), m[k]);
            let big = self.sweep.enclosing.slab;
            if mk.abs() > 1e-12 {
                let (a, b) = ((-big - y0) / mk, (big - y0) / mk);
                lo = lo.max(a.min(b));
                hi = hi.min(a.max(b));
            } else if y0.abs() > big {
                return None;
            }
        }
        (lo <= hi).then_some((lo, hi))
    }

    /// The rays of this family in the row at transverse coordinate `v` (m, along axis
    /// `(k + 2) % 3`) that can meet the bound: a range of their coordinate along `(k + 1) % 3`
    /// (m), from the shadows of the enclosing cylinder's capsule (its axis segment grown by
    /// its radius) and of the end piece's ball. A ray meets a capsule or a ball exactly where
    /// its transverse point lies within the radius of their shadows.
    pub(crate) fn row_span(&self, v: f64) -> Option<(f64, f64)> {
        let (iu, iv) = ((self.k + 1) % 3, (self.k + 2) % 3);
        let sw = self.sweep;
        let en = &sw.enclosing;
        let flat = |p: Point3<f64>| [p[iu], p[iv]];
        let cylinder = (en.lo <= en.hi).then(|| {
            capsule_row(
                flat(en.centre + sw.n * en.lo),
                flat(en.centre + sw.n * en.hi),
                en.radius2.sqrt(),
                v,
            )
        });
        let ball = sw
            .end_ball
            .map(|(centre, radius2)| capsule_row(flat(centre), flat(centre), radius2.sqrt(), v));
        [cylinder.flatten(), ball.flatten()]
            .into_iter()
            .flatten()
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
    }

    /// The ray's interval in the enclosing cylinder, if it meets it.
    fn enclosing_cylinder(&self, p: &Point3<f64>) -> Option<(f64, f64)> {
        let en = &self.sweep.enclosing;
        if en.lo > en.hi {
            return None;
        }
        let n = &self.sweep.n;
        let nk = n[self.k];
        let y = p - en.centre;
        let h0 = y.dot(n);
        // Heights h0 + s·nk within [lo, hi].
        let (mut lo, mut hi) = if nk.abs() > 1e-12 {
            let (a, b) = ((en.lo - h0) / nk, (en.hi - h0) / nk);
            (a.min(b), a.max(b))
        } else if (en.lo..=en.hi).contains(&h0) {
            (f64::NEG_INFINITY, f64::INFINITY)
        } else {
            return None;
        };
        // Radial: |w0 + s·(e − n·nk)|² ≤ ρ² with w0 = y − h0·n (so w0·(e − n·nk) = w0_k).
        let w0 = y - n * h0;
        let a = 1.0 - nk * nk;
        let (b, c) = (w0[self.k], w0.norm_squared() - en.radius2);
        if a > 1e-12 {
            let disc = b * b - a * c;
            if disc < 0.0 {
                return None;
            }
            let root = disc.sqrt();
            lo = lo.max((-b - root) / a);
            hi = hi.min((-b + root) / a);
        } else if c > 0.0 {
            return None;
        }
        (lo <= hi).then_some((lo, hi))
    }

    /// Where the ray `p + s·e_k`, `s ∈ [s_lo, s_hi]`, meets the swept solid.
    pub(crate) fn interval(&self, p: &Point3<f64>, s_lo: f64, s_hi: f64) -> Option<(f64, f64)> {
        let sw = self.sweep;
        let y = p - sw.tip;
        let hy = y.dot(&sw.n);
        let mut out: Option<(f64, f64)> = None;
        for pp in self.pieces.iter().flatten() {
            let got = match self.by_placements(pp, &y) {
                Some(Shortcut::Interval(a, b)) => {
                    let (a, b) = (a.max(s_lo), b.min(s_hi));
                    (a <= b).then_some((a, b))
                }
                Some(Shortcut::Exact) | None => self.exact(pp, &y, hy, s_lo, s_hi),
            };
            if let Some((a, b)) = got {
                out = Some(match out {
                    Some((x, y)) => (x.min(a), y.max(b)),
                    None => (a, b),
                });
            }
        }
        out
    }

    /// The piece's sweep on the ray by the exact geometry (see the module documentation).
    fn exact(
        &self,
        pp: &Prepared,
        y: &Vector3<f64>,
        hy: f64,
        s_lo: f64,
        s_hi: f64,
    ) -> Option<(f64, f64)> {
        let sw = self.sweep;
        let y = *y;
        {
            match pp.piece {
                Piece::Cylinder { r2, h0, h1 } => {
                    let wo = y - sw.n * hy;
                    let q = Quadratic {
                        a: pp.a,
                        b: pp.b,
                        c: pp.c,
                        d: wo.dot(&pp.we),
                        e: -wo.dot(&pp.wd),
                        f: wo.dot(&wo),
                    };
                    // h = hy + hs·s + ht·t within [h0, h1].
                    let strips = [[-pp.hs, -pp.ht, hy - h0], [pp.hs, pp.ht, h1 - hy]];
                    quadratic_extremes(&q, r2, &strips, s_lo, s_hi)
                }
                Piece::Ball { ch, r2 } => {
                    let vo = y - sw.n * ch;
                    let q = Quadratic {
                        a: 1.0,
                        b: pp.b,
                        c: pp.c,
                        d: vo[self.k],
                        e: -vo.dot(&sw.d),
                        f: vo.dot(&vo),
                    };
                    quadratic_extremes(&q, r2, &[], s_lo, s_hi)
                }
                Piece::Puck { ch, rho, r } => {
                    let vo = y - sw.n * ch;
                    puck_interval(&vo, self.k, &sw.n, &sw.d, rho, r, (s_lo, s_hi))
                }
            }
        }
    }

    /// The piece's sweep on the ray from its placements at the start and the end of the move
    /// (see the module documentation); `None` for a puck, [`Shortcut::Exact`] where an end
    /// crosses the silhouette or a placement misses the ray. `y`: the ray's origin relative
    /// to the tip at the start.
    fn by_placements(&self, pp: &Prepared, y: &Vector3<f64>) -> Option<Shortcut> {
        let Some(start) = self.placement(pp, y)? else {
            return Some(Shortcut::Exact);
        };
        // Ends facing away from the move are the start placement's; the end placement is
        // only wanted for the others (the leading side).
        if start.iter().all(|e| e.facing <= 0.0) {
            return Some(Shortcut::Interval(start[0].s, start[1].s));
        }
        let Some(end) = self.placement(pp, &(y - self.sweep.d))? else {
            return Some(Shortcut::Exact);
        };
        let pick = |a: End, b: End| {
            if a.facing <= 0.0 {
                Some(a.s)
            } else if b.facing >= 0.0 {
                Some(b.s)
            } else {
                None
            }
        };
        Some(match (pick(start[0], end[0]), pick(start[1], end[1])) {
            (Some(a), Some(b)) => Shortcut::Interval(a, b),
            _ => Shortcut::Exact,
        })
    }

    /// Where the ray `y + s·e_k` (relative to the piece's tip) meets the still piece: its entry
    /// and exit with how their surface points face the move (`ν·d`, sign only). `None` for a
    /// puck; `Some(None)` where the ray misses the piece or an end lies on an edge of it.
    fn placement(&self, pp: &Prepared, y: &Vector3<f64>) -> Option<Option<[End; 2]>> {
        let sw = self.sweep;
        let (n, k) = (&sw.n, self.k);
        match pp.piece {
            Piece::Cylinder { r2, h0, h1 } => {
                let hy = y.dot(n);
                let wo = y - n * hy;
                // Heights hy + s·n_k within [h0, h1].
                let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
                let mut cap = [0.0; 2];
                if pp.hs.abs() > 1e-12 {
                    let (a, b) = ((h0 - hy) / pp.hs, (h1 - hy) / pp.hs);
                    (lo, hi) = (a.min(b), a.max(b));
                    // The lower end is the bottom cap (ν = −n) when heights rise along the
                    // ray, else the top one.
                    let up = if pp.hs > 0.0 { 1.0 } else { -1.0 };
                    cap = [-up * sw.d.dot(n), up * sw.d.dot(n)];
                } else if !(h0..=h1).contains(&hy) {
                    return Some(None);
                }
                // Radial: |wo + s·we|² ≤ r2.
                let (a, b, c) = (pp.a, wo.dot(&pp.we), wo.norm_squared() - r2);
                let (r0, r1) = if a > 1e-12 {
                    let disc = b * b - a * c;
                    if disc < 0.0 {
                        return Some(None);
                    }
                    let q = -(b + b.signum() * disc.sqrt());
                    if q == 0.0 {
                        (0.0, 0.0)
                    } else {
                        let (x, z) = (q / a, c / q);
                        (x.min(z), x.max(z))
                    }
                } else if c > 0.0 {
                    return Some(None);
                } else {
                    (f64::NEG_INFINITY, f64::INFINITY)
                };
                let side = |s: f64| (wo + pp.we * s).dot(&pp.wd);
                // An end on the rim (both constraints binding) has no single normal.
                let rim =
                    |r: f64, h: f64| h.is_finite() && (r - h).abs() <= 1e-12 * (1.0 + h.abs());
                let entry = if rim(r0, lo) {
                    return Some(None);
                } else if r0 > lo {
                    End {
                        s: r0,
                        facing: side(r0),
                    }
                } else {
                    End {
                        s: lo,
                        facing: cap[0],
                    }
                };
                let exit = if rim(r1, hi) {
                    return Some(None);
                } else if r1 < hi {
                    End {
                        s: r1,
                        facing: side(r1),
                    }
                } else {
                    End {
                        s: hi,
                        facing: cap[1],
                    }
                };
                Some(
                    (entry.s <= exit.s && entry.s.is_finite() && exit.s.is_finite())
                        .then_some([entry, exit]),
                )
            }
            Piece::Ball { ch, r2 } => {
                let vo = y - n * ch;
                let (b, c) = (vo[k], vo.norm_squared() - r2);
                let disc = b * b - c;
                if disc < 0.0 {
                    return Some(None);
                }
                let q = -(b + b.signum() * disc.sqrt());
                let (x, z) = if q == 0.0 { (0.0, 0.0) } else { (q, c / q) };
                let facing = |s: f64| {
                    let mut v = vo;
                    v[k] += s;
                    v.dot(&sw.d)
                };
                let (s0, s1) = (x.min(z), x.max(z));
                Some(Some([
                    End {
                        s: s0,
                        facing: facing(s0),
                    },
                    End {
                        s: s1,
                        facing: facing(s1),
                    },
                ]))
            }
            Piece::Puck { .. } => None,
        }
    }
}

/// One end of a still piece's interval on a ray.
#[derive(Debug, Clone, Copy)]
struct End {
    s: f64,
    /// `ν·d`: > 0 where the surface point faces along the move (only the sign is used).
    facing: f64,
}

/// What the placements say about a piece's sweep on a ray.
enum Shortcut {
    /// The sweep's interval (before clipping to the span asked for).
    Interval(f64, f64),
    /// An end crosses the silhouette, or a placement misses the ray: the exact geometry.
    Exact,
}

/// Range of `s` over `{Q ≤ c} ∩ {t ∈ [0, 1]} ∩ {s ∈ [s_lo, s_hi]} ∩ strips`, where each
/// strip row `[α, β, γ]` is the half-plane `α s + β t ≤ γ`. Exact up to rounding: the extremes
/// of a linear function over a convex region bounded by a conic and lines are at the
/// polygon's vertices, at the polygon edges' crossings of the conic, or at the conic's own
/// extremes.
fn quadratic_extremes(
    q: &Quadratic,
    c: f64,
    strips: &[[f64; 3]],
    s_lo: f64,
    s_hi: f64,
) -> Option<(f64, f64)> {
    // The polygon: the rectangle [s_lo, s_hi] × [0, 1] clipped by the strips.
    let mut poly = [[0.0f64; 2]; 8];
    poly[..4].copy_from_slice(&[[s_lo, 0.0], [s_hi, 0.0], [s_hi, 1.0], [s_lo, 1.0]]);
    let mut len = 4;
    for h in strips {
        let mut next = [[0.0f64; 2]; 8];
        let mut m = 0;
        for i in 0..len {
            let p = poly[i];
            let q2 = poly[(i + 1) % len];
            let fp = h[0] * p[0] + h[1] * p[1] - h[2];
            let fq = h[0] * q2[0] + h[1] * q2[1] - h[2];
            if fp <= 0.0 && m < 8 {
                next[m] = p;
                m += 1;
            }
            if (fp < 0.0 && fq > 0.0) || (fp > 0.0 && fq < 0.0) {
                let l = fp / (fp - fq);
                if m < 8 {
                    next[m] = [p[0] + l * (q2[0] - p[0]), p[1] + l * (q2[1] - p[1])];
                    m += 1;
                }
            }
        }
        poly = next;
        len = m;
        if len == 0 {
            return None;
        }
    }
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut take = |s: f64| {
        lo = lo.min(s);
        hi = hi.max(s);
    };
    let mut vals = [0.0f64; 8];
    for i in 0..len {
        vals[i] = q.at(poly[i][0], poly[i][1]) - c;
        if vals[i] <= 0.0 {
            take(poly[i][0]);
        }
    }
    for i in 0..len {
        let p = poly[i];
        let p2 = poly[(i + 1) % len];
        let (ds, dt) = (p2[0] - p[0], p2[1] - p[1]);
        let a2 = q.a * ds * ds + 2.0 * q.b * ds * dt + q.c * dt * dt;
        let a1 =
            2.0 * ((q.a * p[0] + q.b * p[1] + q.d) * ds + (q.b * p[0] + q.c * p[1] + q.e) * dt);
        let a0 = vals[i];
        for l in quadratic_roots(a2, a1, a0).into_iter().flatten() {
            if (0.0..=1.0).contains(&l) {
                take(p[0] + l * ds);
            }
        }
    }
    // The conic's own extremes in s, where ∂Q/∂t = 0; skipped when the conic is (nearly)
    // a strip, whose extremes over a bounded polygon lie on the polygon's boundary.
    if q.c > 0.0 {
        let a_red = q.a - q.b * q.b / q.c;
        if a_red > 1e-10 * q.a {
            let d_red = q.d - q.b * q.e / q.c;
            let f_red = q.f - q.e * q.e / q.c - c;
            let disc = d_red * d_red - a_red * f_red;
            if disc >= 0.0 {
                let root = disc.sqrt();
                for s in [(-d_red - root) / a_red, (-d_red + root) / a_red] {
                    let t = -(q.b * s + q.e) / q.c;
                    let inside = s >= s_lo - INSIDE_TOL
                        && s <= s_hi + INSIDE_TOL
                        && (-INSIDE_TOL..=1.0 + INSIDE_TOL).contains(&t)
                        && strips
                            .iter()
                            .all(|h| h[0] * s + h[1] * t <= h[2] + INSIDE_TOL);
                    if inside {
                        take(s.clamp(s_lo, s_hi));
                    }
                }
            }
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// Real roots of `a2 λ² + a1 λ + a0 = 0` (`a2 ≥ 0`), stable against cancellation.
#[inline]
fn quadratic_roots(a2: f64, a1: f64, a0: f64) -> [Option<f64>; 2] {
    if a2 == 0.0 {
        return if a1 != 0.0 {
            [Some(-a0 / a1), None]
        } else {
            [None, None]
        };
    }
    let disc = a1 * a1 - 4.0 * a2 * a0;
    if disc < 0.0 {
        return [None, None];
    }
    let qq = -0.5 * (a1 + a1.signum() * disc.sqrt());
    if qq == 0.0 {
        return [Some(0.0), None];
    }
    [Some(qq / a2), Some(a0 / qq)]
}

/// Where the ray `vo + s·e_k` (relative to the puck's disc centre at the move's start) meets
/// the set within `r` of the disc (radius `rho`, normal `n`) swept along `d`.
fn puck_interval(
    vo: &Vector3<f64>,
    k: usize,
    n: &Vector3<f64>,
    d: &Vector3<f64>,
    rho: f64,
    r: f64,
    (s_lo, s_hi): (f64, f64),
) -> Option<(f64, f64)> {
    // Distance to the swept disc minus r, and its derivative along the ray. Convex in s.
    let phi = |s: f64| -> (f64, f64) {
        let mut z0 = *vo;
        z0[k] += s;
        let res = swept_disc_residual(&z0, n, d, rho);
        let dist = res.norm();
        if dist == 0.0 {
            (-r, 0.0)
        } else {
            (dist - r, res[k] / dist)
        }
    };
    const MAX_ITER: usize = 100;
    const TOL: f64 = 1e-13;
    let (f0, _) = phi(s_lo);
    let entry = if f0 <= 0.0 {
        s_lo
    } else {
        let mut s = s_lo;
        let mut found = None;
        for _ in 0..MAX_ITER {
            let (f, df) = phi(s);
            if f <= TOL {
                found = Some(s);
                break;
            }
            if df >= 0.0 {
                return None; // Past the distance's minimum without reaching r: a miss.
            }
            let step = -f / df;
            s += step;
            if s > s_hi {
                return None;
            }
            if step < TOL {
                found = Some(s);
                break;
            }
        }
        found?
    };
    let (f1, _) = phi(s_hi);
    let exit = if f1 <= 0.0 {
        s_hi
    } else {
        let mut s = s_hi;
        let mut found = None;
        for _ in 0..MAX_ITER {
            let (f, df) = phi(s);
            if f <= TOL {
                found = Some(s);
                break;
            }
            if df <= 0.0 {
                return None;
            }
            let step = f / df;
            s -= step;
            if s < entry {
                s = entry;
                found = Some(s);
                break;
            }
            if step < TOL {
                found = Some(s);
                break;
            }
        }
        found?
    };
    (entry <= exit).then_some((entry, exit))
}

/// `z − k*` for `k*` the point of the disc (centre 0, unit normal `n`, radius `rho`) swept
/// along `t·d`, `t ∈ [0, 1]`, nearest to `z0`.
fn swept_disc_residual(
    z0: &Vector3<f64>,
    n: &Vector3<f64>,
    d: &Vector3<f64>,
    rho: f64,
) -> Vector3<f64> {
    let residual = |t: f64| {
        let z = z0 - d * t;
        let zh = z.dot(n);
        let zw = z - n * zh;
        let w = zw.norm();
        if w <= rho {
            n * zh
        } else {
            z - zw * (rho / w)
        }
    };
    // The squared distance at t is convex with derivative −2·residual(t)·d, so m(t) =
    // residual(t)·d falls with t; its root (or the end it does not cross) is the nearest t.
    let m = |t: f64| residual(t).dot(d);
    if d.norm_squared() == 0.0 {
        return residual(0.0);
    }
    let (mut t0, mut t1) = (0.0, 1.0);
    let (mut m0, mut m1) = (m(t0), m(t1));
    if m0 <= 0.0 {
        return residual(0.0);
    }
    if m1 >= 0.0 {
        return residual(1.0);
    }
    // Illinois regula falsi on the monotone m.
    let mut side = 0;
    let mut t = 0.5;
    for _ in 0..60 {
        t = (t0 * m1 - t1 * m0) / (m1 - m0);
        if !(t > t0 && t < t1) {
            t = 0.5 * (t0 + t1);
        }
        let mt = m(t);
        if mt > 0.0 {
            t0 = t;
            m0 = mt;
            if side == 1 {
                m1 *= 0.5;
            }
            side = 1;
        } else if mt < 0.0 {
            t1 = t;
            m1 = mt;
            if side == -1 {
                m0 *= 0.5;
            }
            side = -1;
        } else {
            break;
        }
        if t1 - t0 < 1e-12 {
            break;
        }
    }
    residual(t)
}

/// Where the line `{(u, v)}` at the given `v` meets the 2-D capsule of radius `rho` around
/// the segment `a`–`b`: a range of `u`.
fn capsule_row(a: [f64; 2], b: [f64; 2], rho: f64, v: f64) -> Option<(f64, f64)> {
    let disc = |c: [f64; 2]| {
        let h = rho * rho - (v - c[1]) * (v - c[1]);
        (h >= 0.0).then(|| (c[0] - h.sqrt(), c[0] + h.sqrt()))
    };
    // The band between the ends: the foot of the point on the segment's line within the
    // segment, and the point within `rho` of that line (both linear in `u`).
    let d = [b[0] - a[0], b[1] - a[1]];
    let length = d[0].hypot(d[1]);
    let band = if length > 0.0 {
        // t·length = d_u (u − a_u)/length + …, perp = (d_u (v − a_v) − d_v (u − a_u))/length.
        let linear = |slope: f64, at_a: f64, lo: f64, hi: f64| -> Option<(f64, f64)> {
            // lo ≤ at_a + slope·(u − a_u) ≤ hi.
            if slope.abs() < 1e-300 {
                return (lo <= at_a && at_a <= hi).then_some((f64::NEG_INFINITY, f64::INFINITY));
            }
            let (x, y) = ((lo - at_a) / slope, (hi - at_a) / slope);
            Some((a[0] + x.min(y), a[0] + x.max(y)))
        };
        let along = linear(d[0] / length, d[1] * (v - a[1]) / length, 0.0, length);
        let across = linear(-d[1] / length, d[0] * (v - a[1]) / length, -rho, rho);
        match (along, across) {
            (Some((p, q)), Some((r, s))) => {
                let (lo, hi) = (p.max(r), q.min(s));
                (lo <= hi).then_some((lo, hi))
            }
            _ => None,
        }
    } else {
        None
    };
    [disc(a), disc(b), band]
        .into_iter()
        .flatten()
        .reduce(|(p, q), (r, s)| (p.min(r), q.max(s)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn tool(shape: u8, radius: f64) -> Tool {
        Tool {
            diameter: 2.0 * radius,
            flutes: 2,
            helix: 0.0,
            flute_length: 0.02,
            shape: match shape {
                0 => ToolShape::Flat,
                1 => ToolShape::Ball,
                _ => ToolShape::Bull {
                    corner_radius: 0.3 * radius,
                },
            },
        }
    }

    /// Unit vector from two angles.
    fn unit(theta: f64, phi: f64) -> Vector3<f64> {
        Vector3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// The placements' shortcut gives the exact geometry's interval on every ray it
        /// answers: short moves (the co-simulation's steps, down to nanometres), long ones,
        /// any axis and direction, rays through and beside the tool, each band.
        #[test]
        fn the_placements_give_the_exact_interval(
            shape in 0u8..3,
            radius in 0.5e-3..8e-3,
            (theta, phi) in (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU),
            (mt, mp) in (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU),
            length_exp in -9.0f64..-2.0,
            band in 0u8..3,
            k in 0usize..3,
            (u, v, w) in (-1.5f64..1.5, -1.5f64..1.5, -0.5f64..2.5),
        ) {
            let t = tool(shape, radius);
            let n = unit(theta, phi);
            let d = unit(mt, mp) * 10f64.powf(length_exp);
            let (lo, hi) = match band {
                0 => (0.0, 0.02),
                1 => (0.0, 2.0 * radius),
                _ => (0.6 * radius, 3.0 * radius),
            };
            let hi = if lo == 0.0 { hi.max(2.0 * t.corner_radius()).max(radius) } else { hi };
            let p0 = Point3::new(0.001, -0.002, 0.003);
            let sweep = Sweep::new(&t, lo, hi, p0, p0 + d, n);
            let ray = sweep.for_axis(k);
            // A ray through a point near the tool, along axis k.
            let scale = radius + d.norm();
            let q = p0 + n * (w * radius) + unit(mt + 1.0, mp + 2.0) * (u * scale)
                + unit(mt + 2.0, mp + 0.5) * (v * scale);
            let mut origin = q;
            origin[k] -= 0.05;
            let (s_lo, s_hi) = (0.0, 0.1);
            let y = origin - sweep.tip;
            let hy = y.dot(&sweep.n);
            for pp in ray.pieces.iter().flatten() {
                if let Some(Shortcut::Interval(a, b)) = ray.by_placements(pp, &y) {
                    let exact = ray.exact(pp, &y, hy, s_lo, s_hi);
                    let (a, b) = (a.max(s_lo), b.min(s_hi));
                    let got = (a <= b).then_some((a, b));
                    match (got, exact) {
                        (Some((a, b)), Some((x, z))) => {
                            prop_assert!((a - x).abs() < 1e-10 && (b - z).abs() < 1e-10,
                                "{:?}: placements {:?}, exact {:?}", pp.piece, (a, b), (x, z));
                        }
                        (None, None) => {}
                        (g, e) => {
                            // A touching ray: an interval of (nearly) no length on one side.
                            let len = |i: Option<(f64, f64)>| i.map_or(0.0, |(a, b)| b - a);
                            prop_assert!(len(g) < 1e-10 && len(e) < 1e-10,
                                "{:?}: placements {g:?}, exact {e:?}", pp.piece);
                        }
                    }
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]

        /// Every bound holds the exact intervals it stands for: a sweep's own bound and its
        /// row span hold its interval on any ray; each node of a group tree over a wobbling,
        /// turning path of moves holds the interval of every move it holds.
        #[test]
        fn the_bounds_hold_the_sweeps(
            shape in 0u8..3,
            radius in 0.5e-3..8e-3,
            (theta, phi) in (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU),
            (mt, mp) in (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU),
            step_exp in -7.0f64..-4.0,
            wobble in 0.0f64..3.0,
            turn in 0.0f64..0.01,
            moves in 1usize..40,
            top in 1.0f64..4.0,
            seed in 0u64..1000,
        ) {
            let t = tool(shape, radius);
            let step = 10f64.powf(step_exp);
            let direction = unit(mt, mp);
            let p0 = Point3::new(0.001, -0.002, 0.003);
            // A path of `moves` steps along `direction`, each pose off the line by up to
            // `wobble` µm, the axis turning by `turn` rad per step.
            let pose = |i: usize| {
                let j = i as f64 + seed as f64;
                let off = Vector3::new((j * 1.7).sin(), (j * 2.3).cos(), (j * 0.9).sin());
                let tip = p0 + direction * (step * i as f64) + off * (wobble * 1e-6);
                (tip, unit(theta + turn * i as f64, phi))
            };
            let hi = (top * radius).max(2.0 * t.corner_radius()).max(radius);
            let sweeps: Vec<Sweep> = (0..moves)
                .map(|i| {
                    let ((a, na), (b, nb)) = (pose(i), pose(i + 1));
                    let n = (na + nb).normalize();
                    Sweep::new(&t, 0.0, hi, a, b, n)
                })
                .collect();
            let refs: Vec<&Sweep> = sweeps.iter().collect();
            let tree = GroupTree::new(&refs);
            let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
            let mut next = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            };
            let reach = hi + radius + step * moves as f64;
            for _ in 0..200 {
                let k = ((next() + 1.0) * 1.5) as usize % 3;
                let mut origin = p0 + Vector3::new(next(), next(), next()) * reach;
                origin[k] -= 0.05;
                let (u, v) = ((k + 1) % 3, (k + 2) % 3);
                for (i, sweep) in sweeps.iter().enumerate() {
                    let ray = sweep.for_axis(k);
                    let Some((a, b)) = ray.interval(&origin, 0.0, 0.1) else {
                        continue;
                    };
                    let within = |(lo, hi): (f64, f64), x: f64| lo - 1e-12 <= x && x <= hi + 1e-12;
                    let own = ray.bound(&origin);
                    prop_assert!(own.is_some_and(|o| within(o, a) && within(o, b)),
                        "sweep {i}: interval {:?}, bound {own:?}", (a, b));
                    let span = ray.row_span(origin[v]);
                    prop_assert!(span.is_some_and(|sp| within(sp, origin[u])),
                        "sweep {i}: row span {span:?} misses the ray at {}", origin[u]);
                    for node in tree.nodes.iter().filter(|n| n.sweeps.contains(&i)) {
                        if let Some(group) = &node.bound {
                            let g = group.bound(&origin, k);
                            prop_assert!(g.is_some_and(|g| within(g, a) && within(g, b)),
                                "node {:?} of sweep {i}: interval {:?}, bound {g:?}",
                                node.sweeps, (a, b));
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn the_shortcut_answers_most_rays_that_meet_both_placements() {
        // The property test's cases, drawn by a fixed generator, counting what was compared:
        // the shortcut must have been checked on many rays, not skipped.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut compared, mut asked) = (0, 0);
        for _ in 0..20_000 {
            let t = tool((next() * 3.0) as u8, 0.5e-3 + next() * 7.5e-3);
            let n = unit(
                next() * std::f64::consts::PI,
                next() * std::f64::consts::TAU,
            );
            let d = unit(
                next() * std::f64::consts::PI,
                next() * std::f64::consts::TAU,
            ) * 10f64.powf(-9.0 + 7.0 * next());
            let p0 = Point3::new(0.001, -0.002, 0.003);
            let sweep = Sweep::new(&t, 0.0, 0.02, p0, p0 + d, n);
            let k = (next() * 3.0) as usize;
            let ray = sweep.for_axis(k);
            let r = t.radius();
            let mut origin = p0
                + n * ((next() * 2.5 - 0.5) * r)
                + unit(
                    next() * std::f64::consts::PI,
                    next() * std::f64::consts::TAU,
                ) * (next() * 1.2 * r);
            origin[k] -= 0.05;
            let y = origin - sweep.tip;
            let hy = y.dot(&sweep.n);
            for pp in ray.pieces.iter().flatten() {
                asked += 1;
                if let Some(Shortcut::Interval(a, b)) = ray.by_placements(pp, &y) {
                    compared += 1;
                    let (x, z) = ray
                        .exact(pp, &y, hy, 0.0, 0.1)
                        .expect("the placements meet the ray");
                    let (a, b) = (a.max(0.0), b.min(0.1));
                    assert!(
                        (a - x).abs() < 1e-10 && (b - z).abs() < 1e-10,
                        "{:?}: placements {:?}, exact {:?}",
                        pp.piece,
                        (a, b),
                        (x, z)
                    );
                }
            }
        }
        assert!(compared * 3 > asked, "{compared} of {asked} compared");
    }

    #[test]
    fn most_rays_of_a_short_move_need_no_exact_geometry() {
        // A 10 mm flat tool moving 10 µm sideways: rays on a grid across it.
        let t = tool(0, 5e-3);
        let p0 = Point3::new(0.0, 0.0, 0.0);
        let sweep = Sweep::new(
            &t,
            0.0,
            0.02,
            p0,
            p0 + Vector3::new(1e-5, 0.0, 0.0),
            Vector3::z(),
        );
        let ray = sweep.for_axis(0);
        let (mut shortcut, mut exact) = (0, 0);
        for i in 0..50 {
            for j in 0..50 {
                let origin =
                    Point3::new(-0.05, -4.9e-3 + i as f64 * 0.2e-3, 1e-4 + j as f64 * 0.4e-3);
                let y = origin - sweep.tip;
                for pp in ray.pieces.iter().flatten() {
                    match ray.by_placements(pp, &y) {
                        Some(Shortcut::Interval(..)) => shortcut += 1,
                        _ => exact += 1,
                    }
                }
            }
        }
        // Only the rays whose ends cross the tool's silhouette against the move (its flanks,
        // within the move's length of ±R in y) need the exact geometry.
        assert!(
            shortcut > 20 * exact,
            "{shortcut} by placements, {exact} exact"
        );
    }
}
