//! The programmed path as geometry in the linear axes, for measuring how far the tool strays
//! from it (contour error) independently of when it should have been where.

use super::{arc_sweep, plane_axes, Motion, Plane, Program};
use nalgebra::{Point3, Vector3};
use std::f64::consts::TAU;

/// One piece of the programmed path (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Segment {
    /// Straight line from `start` to `end`.
    Line {
        /// Start point (m).
        start: Point3<f64>,
        /// End point (m).
        end: Point3<f64>,
    },
    /// Arc about `center` in the plane with unit normal `normal`, from `start` sweeping
    /// `sweep` rad (signed, right-handed about `normal`), rising `rise` along `normal` (helix).
    Arc {
        /// Centre (m), in the plane of `start`.
        center: Point3<f64>,
        /// Unit normal of the arc's plane.
        normal: Vector3<f64>,
        /// Start point (m).
        start: Point3<f64>,
        /// Angle swept (rad), signed right-handed about `normal`.
        sweep: f64,
        /// Travel along `normal` from start to end (m); 0 for a plane arc.
        rise: f64,
    },
}

impl Segment {
    /// Shortest distance from `p` to this piece of path.
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        (p - self.closest(p)).norm()
    }

    /// The point a `fraction` (0 to 1) of the way along this piece of path: by length on a
    /// line, by angle on an arc (its rise in proportion), as the interpolators move along it.
    pub fn point_at(&self, fraction: f64) -> Point3<f64> {
        match *self {
            Segment::Line { start, end } => start + (end - start) * fraction,
            Segment::Arc {
                center,
                normal,
                start,
                sweep,
                rise,
            } => {
                let basis = arc_basis(center, normal, start);
                on_arc(center, basis, normal, sweep * fraction, rise * fraction)
            }
        }
    }

    /// The point of this piece of path nearest to `p`.
    pub fn closest(&self, p: &Point3<f64>) -> Point3<f64> {
        match *self {
            Segment::Line { start, end } => {
                let d = end - start;
                let len2 = d.norm_squared();
                let t = if len2 > 0.0 {
                    ((p - start).dot(&d) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                start + d * t
            }
            Segment::Arc {
                center,
                normal,
                start,
                sweep,
                rise,
            } => {
                let (u, v, radius) = arc_basis(center, normal, start);
                let rel = p - center;
                let angle = rel.dot(&v).atan2(rel.dot(&u));
                // Candidate angles along the sweep: the projection's angle (and its turns), and
                // both ends; the arc is short enough in turns that this is exact for circles.
                let (mut best, mut nearest) = (f64::INFINITY, start);
                let (lo, hi) = if sweep >= 0.0 {
                    (0.0, sweep)
                } else {
                    (sweep, 0.0)
                };
                let mut candidates = vec![lo, hi];
                let mut a = angle - TAU * ((angle - lo) / TAU).ceil();
                while a <= hi + 1e-12 {
                    if a >= lo - 1e-12 {
                        candidates.push(a.clamp(lo, hi));
                    }
                    a += TAU;
                }
                for a in candidates {
                    let along = if sweep != 0.0 { a / sweep } else { 0.0 };
                    let q = on_arc(center, (u, v, radius), normal, a, rise * along);
                    let d = (p - q).norm();
                    if d < best {
                        (best, nearest) = (d, q);
                    }
                }
                nearest
            }
        }
    }
}

/// An arc's in-plane unit vectors (towards its start, and a quarter turn on about `normal`)
/// and its radius.
fn arc_basis(
    center: Point3<f64>,
    normal: Vector3<f64>,
    start: Point3<f64>,
) -> (Vector3<f64>, Vector3<f64>, f64) {
    let r0 = start - center;
    let radius = r0.norm();
    let u = r0 / radius;
    (u, normal.cross(&u), radius)
}

/// The point of an arc at `angle` from its start, risen `rise` along its normal.
fn on_arc(
    center: Point3<f64>,
    (u, v, radius): (Vector3<f64>, Vector3<f64>, f64),
    normal: Vector3<f64>,
    angle: f64,
    rise: f64,
) -> Point3<f64> {
    center + (u * angle.cos() + v * angle.sin()) * radius + normal * rise
}

/// The programmed path of a program: one segment per move with motion (dwells have none).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PathGeometry {
    /// The segments in program order.
    pub segments: Vec<Segment>,
    /// For each program move, the index of its segment (dwells point at the previous one); of
    /// its last segment where a move has several.
    pub segment_of_move: Vec<usize>,
    /// For each program move, the index of its first segment, where moves have several (a
    /// path through the machine's kinematics, [`PathGeometry::from_pieces`]); empty where every
    /// move has one.
    pub first_segment_of_move: Vec<usize>,
}

impl PathGeometry {
    /// The path of `program`'s linear axes, from its start through every move (a dwell before
    /// any motion gives a zero-length line).
    pub fn of(program: &Program) -> Self {
        let mut segments = Vec::new();
        let mut segment_of_move = Vec::with_capacity(program.moves.len());
        let mut at = Point3::from(program.start.linear);
        for m in &program.moves {
            let end = Point3::from(m.end.linear);
            match m.motion {
                Motion::Linear => segments.push(Segment::Line { start: at, end }),
                Motion::Arc {
                    center,
                    plane,
                    clockwise,
                    turns,
                } => segments.push(arc_segment(
                    at,
                    end,
                    Point3::from(center),
                    plane,
                    clockwise,
                    turns,
                )),
                Motion::Dwell { .. } => {
                    if segments.is_empty() {
                        segments.push(Segment::Line { start: at, end: at });
                    }
                }
            }
            segment_of_move.push(segments.len().saturating_sub(1));
            at = end;
        }
        PathGeometry {
            segments,
            segment_of_move,
            first_segment_of_move: Vec::new(),
        }
    }

    /// A path of straight pieces: for each move, the points it passes through after its
    /// start (`start` is where the first move starts; a move without points stands still).
    pub fn from_pieces(start: Point3<f64>, moves: &[Vec<Point3<f64>>]) -> Self {
        let mut segments = Vec::new();
        let (mut segment_of_move, mut first_segment_of_move) = (Vec::new(), Vec::new());
        let mut at = start;
        for points in moves {
            first_segment_of_move.push(segments.len());
            if points.is_empty() {
                segments.push(Segment::Line { start: at, end: at });
            }
            for &p in points {
                segments.push(Segment::Line { start: at, end: p });
                at = p;
            }
            segment_of_move.push(segments.len() - 1);
        }
        PathGeometry {
            segments,
            segment_of_move,
            first_segment_of_move,
        }
    }

    /// The point of the path nearest to `p` among the segments of the moves within `window`
    /// of move `near` (the move the setpoints are on).
    pub fn closest_to_move(
        &self,
        p: &Point3<f64>,
        near: usize,
        window: usize,
    ) -> Option<Point3<f64>> {
        if self.first_segment_of_move.is_empty() {
            let segment = self.segment_of_move.get(near).copied().unwrap_or(0);
            return self.closest_near(p, segment, window);
        }
        let last_move = self.segment_of_move.len().checked_sub(1)?;
        let near = if near > last_move { 0 } else { near };
        let lo = self.first_segment_of_move[near.saturating_sub(window)];
        let hi = self.segment_of_move[(near + window).min(last_move)] + 1;
        self.segments[lo..hi]
            .iter()
            .map(|s| s.closest(p))
            .min_by(|a, b| (p - a).norm().total_cmp(&(p - b).norm()))
    }

    /// Distance from `p` to the path, searching the segments within `window` of `near`
    /// (the segment the tool is expected to be on).
    pub fn distance_near(&self, p: &Point3<f64>, near: usize, window: usize) -> f64 {
        self.closest_near(p, near, window)
            .map_or(f64::NAN, |q| (p - q).norm())
    }

    /// The point of the path nearest to `p` among the segments within `window` of `near`.
    pub fn closest_near(&self, p: &Point3<f64>, near: usize, window: usize) -> Option<Point3<f64>> {
        let lo = near.saturating_sub(window).min(self.segments.len());
        let hi = (near + window + 1).min(self.segments.len());
        self.segments[lo..hi]
            .iter()
            .map(|s| s.closest(p))
            .min_by(|a, b| (p - a).norm().total_cmp(&(p - b).norm()))
    }
}

/// Builds an arc from its start, end, centre and plane (G2/G3 semantics: end = start is a
/// full circle; the sweep is the front ends' [`arc_sweep`], signed about the plane normal).
pub fn arc_segment(
    start: Point3<f64>,
    end: Point3<f64>,
    center: Point3<f64>,
    plane: Plane,
    clockwise: bool,
    turns: u32,
) -> Segment {
    let normal = Vector3::ith(plane_axes(plane).2, 1.0);
    let magnitude = arc_sweep(
        &start.into(),
        &end.into(),
        &center.into(),
        plane,
        clockwise,
        turns,
    );
    let sweep = if clockwise { -magnitude } else { magnitude };
    let rise = (end - start).dot(&normal);
    Segment::Arc {
        center: center + normal * (start - center).dot(&normal),
        normal,
        start,
        sweep,
        rise,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_to_lines_and_arcs() {
        let line = Segment::Line {
            start: Point3::new(0.0, 0.0, 0.0),
            end: Point3::new(1.0, 0.0, 0.0),
        };
        assert!((line.distance(&Point3::new(0.5, 0.2, 0.0)) - 0.2).abs() < 1e-15);
        assert!((line.distance(&Point3::new(2.0, 0.0, 0.0)) - 1.0).abs() < 1e-15);
        let c = Point3::new(0.1, 0.1, 0.0);
        let full = arc_segment(
            Point3::new(0.13, 0.1, 0.0),
            Point3::new(0.13, 0.1, 0.0),
            c,
            Plane::XY,
            false,
            0,
        );
        match full {
            Segment::Arc { sweep, .. } => assert!((sweep - TAU).abs() < 1e-12),
            _ => unreachable!(),
        }
        // 1 µm outside the circle anywhere on it.
        for k in 0..12 {
            let a = k as f64 * 0.5;
            let p = c + Vector3::new(a.cos(), a.sin(), 0.0) * 0.030001;
            assert!((full.distance(&p) - 1e-6).abs() < 1e-12);
        }
        // A quarter arc clockwise from +X to -Y: a point at +Y is far from it.
        let quarter = arc_segment(
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, -1.0, 0.0),
            Point3::origin(),
            Plane::XY,
            true,
            0,
        );
        assert!((quarter.distance(&Point3::new(0.0, 1.0, 0.0)) - 2f64.sqrt()).abs() < 1e-12);
    }
}
