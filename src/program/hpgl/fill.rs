//! Polygons (polygon mode `PM`, rectangles, wedges) and how a pen fills them: parallel hatch
//! lines clipped to the polygon by the even-odd or non-zero winding rule, as `FT` asks.
//!
//! Everything here is in plotter units of the current rotation.

use std::f64::consts::TAU;

pub(super) use super::drawing::Segment as Piece;

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Edge {
    pub(super) piece: Piece,
    pub(super) to: [f64; 2],
}

/// One sub-polygon.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct SubPath {
    pub(super) start: [f64; 2],
    pub(super) edges: Vec<Edge>,
    /// Closed by PM1 or PM2 with the pen up: an edged polygon (EP) leaves its closing edge
    /// undrawn, as HP-GL/2 plotters and hp2xx do (plotutils draws open polylines so); a
    /// fill still closes it.
    pub(super) open: bool,
}

impl SubPath {
    pub(super) fn end(&self) -> [f64; 2] {
        self.edges.last().map_or(self.start, |edge| edge.to)
    }
}

/// The polygon buffer.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct Polygon {
    pub(super) paths: Vec<SubPath>,
}

/// Angle (rad, ≥ 0) an arc sweeps from `from` to `to` about `centre`; a full turn when they
/// coincide; plus its extra turns.
pub(super) fn sweep(
    from: [f64; 2],
    to: [f64; 2],
    centre: [f64; 2],
    clockwise: bool,
    turns: u32,
) -> f64 {
    let a0 = (from[1] - centre[1]).atan2(from[0] - centre[0]);
    let a1 = (to[1] - centre[1]).atan2(to[0] - centre[0]);
    let difference = if clockwise { a0 - a1 } else { a1 - a0 };
    let mut angle = difference.rem_euclid(TAU);
    if from == to || angle < 1e-12 {
        angle = TAU;
    }
    angle + TAU * f64::from(turns)
}

/// Largest distance (plotter units) between an arc and the chords that stand for it when a
/// fill boundary is computed: a hundredth of a millimetre.
const FLATNESS: f64 = 0.4;
/// At most this many chords per arc of a fill boundary.
const MAX_CHORDS: f64 = 4096.0;

/// Points along an arc (all its turns) from `from` to `to`, `to` last, `from` not given:
/// chords within `FLATNESS` of the arc.
pub(super) fn arc_points(
    from: [f64; 2],
    to: [f64; 2],
    centre: [f64; 2],
    clockwise: bool,
    turns: u32,
) -> Vec<[f64; 2]> {
    let radius = (from[0] - centre[0]).hypot(from[1] - centre[1]);
    let angle = sweep(from, to, centre, clockwise, turns);
    let step = if radius > FLATNESS {
        2.0 * (1.0 - FLATNESS / radius).acos()
    } else {
        TAU
    };
    let count = (angle / step).ceil().clamp(1.0, MAX_CHORDS * 64.0) as usize;
    let start = (from[1] - centre[1]).atan2(from[0] - centre[0]);
    let signed = if clockwise { -angle } else { angle };
    let mut points: Vec<[f64; 2]> = (1..count)
        .map(|index| {
            let a = start + signed * index as f64 / count as f64;
            [centre[0] + radius * a.cos(), centre[1] + radius * a.sin()]
        })
        .collect();
    points.push(to);
    points
}

/// The vertices of a sub-path with arcs replaced by chords (closing edge implied).
fn flatten(path: &SubPath) -> Vec<[f64; 2]> {
    let mut points = vec![path.start];
    let mut from = path.start;
    for edge in &path.edges {
        if let Piece::Arc {
            centre, clockwise, ..
        } = edge.piece
        {
            let radius = (from[0] - centre[0]).hypot(from[1] - centre[1]);
            // One revolution bounds the area, whatever the extra turns.
            let angle = sweep(from, edge.to, centre, clockwise, 0);
            let step = if radius > FLATNESS {
                2.0 * (1.0 - FLATNESS / radius).acos()
            } else {
                TAU
            };
            let count = (angle / step).ceil().clamp(1.0, MAX_CHORDS) as usize;
            let start = (from[1] - centre[1]).atan2(from[0] - centre[0]);
            let signed = if clockwise { -angle } else { angle };
            for index in 1..count {
                let a = start + signed * index as f64 / count as f64;
                points.push([centre[0] + radius * a.cos(), centre[1] + radius * a.sin()]);
            }
        }
        points.push(edge.to);
        from = edge.to;
    }
    points
}

/// The fill rule of `FP` (and of the rectangle and wedge commands: even-odd).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Rule {
    EvenOdd,
    NonZero,
}

/// Hatch lines at `angle_deg` spaced `spacing` apart (halfway between multiples of the
/// spacing from `anchor`, the fill's anchor corner AC, so that none runs along an edge on
/// the grid) inside `polygon`, as segments in drawing order: alternate lines reversed when
/// `bidirectional`. Fails with the number of lines it would take when that exceeds `budget`.
pub(super) fn hatch(
    polygon: &Polygon,
    (angle_deg, spacing, anchor): (f64, f64, [f64; 2]),
    rule: Rule,
    bidirectional: bool,
    budget: usize,
) -> Result<Vec<[[f64; 2]; 2]>, f64> {
    let angle = angle_deg.to_radians();
    let along = [angle.cos(), angle.sin()];
    let across = [-along[1], along[0]];
    let rings: Vec<Vec<[f64; 2]>> = polygon
        .paths
        .iter()
        .map(flatten)
        .filter(|ring| ring.len() >= 3)
        .collect();
    let project = |p: [f64; 2], axis: [f64; 2]| p[0] * axis[0] + p[1] * axis[1];
    let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
    for point in rings.iter().flatten() {
        let s = project(*point, across);
        low = low.min(s);
        high = high.max(s);
    }
    if rings.is_empty() || high <= low {
        return Ok(Vec::new());
    }
    let base = project(anchor, across);
    let first = ((low - base) / spacing - 0.5).ceil();
    let last = ((high - base) / spacing - 0.5).floor();
    let lines = (last - first + 1.0).max(0.0);
    if lines > budget as f64 {
        return Err(lines);
    }
    let mut segments = Vec::new();
    let mut crossings: Vec<(f64, i32)> = Vec::new();
    for k in 0..lines as u64 {
        let level = base + (first + k as f64 + 0.5) * spacing;
        crossings.clear();
        for ring in &rings {
            for index in 0..ring.len() {
                let a = ring[index];
                let b = ring[(index + 1) % ring.len()];
                let (sa, sb) = (project(a, across), project(b, across));
                // Half-open rule: a vertex on the line counts for one of its two edges.
                let upward = sa <= level && sb > level;
                let downward = sb <= level && sa > level;
                if upward || downward {
                    let t = (level - sa) / (sb - sa);
                    let point = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
                    crossings.push((project(point, along), if upward { 1 } else { -1 }));
                }
            }
        }
        crossings.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut line_segments = Vec::new();
        let mut winding = 0;
        // Where the current inside run began: touching runs make one segment.
        let mut entered: Option<f64> = None;
        for &(t, direction) in &crossings {
            winding += direction;
            let inside = match rule {
                Rule::EvenOdd => winding % 2 != 0,
                Rule::NonZero => winding != 0,
            };
            match (inside, entered) {
                (true, None) => entered = Some(t),
                (false, Some(from)) => {
                    entered = None;
                    if t > from {
                        let point = |t: f64| {
                            [
                                along[0] * t + across[0] * level,
                                along[1] * t + across[1] * level,
                            ]
                        };
                        line_segments.push([point(from), point(t)]);
                    }
                }
                _ => {}
            }
        }
        if bidirectional && k % 2 == 1 {
            line_segments.reverse();
            for segment in &mut line_segments {
                segment.swap(0, 1);
            }
        }
        segments.extend(line_segments);
    }
    Ok(segments)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(low: f64, high: f64) -> SubPath {
        let corner = |x, y| Edge {
            piece: Piece::Line,
            to: [x, y],
        };
        SubPath {
            start: [low, low],
            edges: vec![
                corner(high, low),
                corner(high, high),
                corner(low, high),
                corner(low, low),
            ],
            open: false,
        }
    }

    #[test]
    fn hatching_a_square_with_a_hole() {
        let polygon = Polygon {
            paths: vec![square(0.0, 10.0), square(3.0, 7.0)],
        };
        let even_odd = hatch(&polygon, (0.0, 1.0, [0.0, 0.0]), Rule::EvenOdd, false, 100).unwrap();
        // Lines y = 0.5 … 9.5.
        assert_eq!(even_odd.len(), 10 + 4);
        let through_hole = even_odd.iter().filter(|s| s[0][1] == 5.5).count();
        assert_eq!(through_hole, 2);
        assert_eq!(even_odd.iter().filter(|s| s[0][1] == 1.5).count(), 1);
        // Same direction: the inner square runs the same way, so non-zero fills the hole.
        let non_zero = hatch(&polygon, (0.0, 1.0, [0.0, 0.0]), Rule::NonZero, false, 100).unwrap();
        assert_eq!(non_zero.iter().filter(|s| s[0][1] == 5.5).count(), 1);
        assert!(hatch(&polygon, (0.0, 1.0, [0.0, 0.0]), Rule::EvenOdd, false, 3).is_err());
        // Bidirectional: every other line is drawn right to left.
        let both = hatch(&polygon, (0.0, 1.0, [0.0, 0.0]), Rule::EvenOdd, true, 100).unwrap();
        assert!(both.iter().any(|s| s[0][0] > s[1][0]));
    }

    #[test]
    fn hatching_a_circle_stays_inside_it() {
        let polygon = Polygon {
            paths: vec![SubPath {
                start: [10.0, 0.0],
                edges: vec![Edge {
                    piece: Piece::Arc {
                        centre: [0.0, 0.0],
                        clockwise: false,
                        turns: 0,
                    },
                    to: [10.0, 0.0],
                }],
                open: false,
            }],
        };
        let lines = hatch(&polygon, (45.0, 0.5, [0.0, 0.0]), Rule::EvenOdd, true, 1000).unwrap();
        // Lines ±9.75 from the centre would touch the circle, but its chords (at most
        // FLATNESS inside it) pass within 9.66 at 45°.
        assert_eq!(lines.len(), 38);
        for segment in lines {
            for point in segment {
                assert!(point[0].hypot(point[1]) <= 10.0 + 1e-9);
            }
        }
    }
}
