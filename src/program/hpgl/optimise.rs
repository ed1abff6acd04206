//! Pen-up travel optimisation: strokes between pen changes are reordered and reversed (greedy
//! nearest neighbour over a uniform grid of stroke ends) and chained where they meet, never
//! changing a stroke's geometry.

use super::drawing::{distance, pen_up_travel, Element, Segment, Step, Stroke};

/// Points closer than this (m) count as the same point when chaining strokes; a tenth of a
/// plotter unit.
const CHAIN_TOLERANCE: f64 = 2.5e-6;

/// Reorders and reverses the strokes between pen changes to shorten pen-up travel (greedy
/// nearest neighbour from the current position), chains strokes that meet end to start, and
/// keeps the original order of any group the greedy order would not improve.
pub(super) fn optimise(drawing: Vec<Element>, start: [f64; 2]) -> Vec<Element> {
    let mut result = Vec::with_capacity(drawing.len());
    let mut position = start;
    let mut group: Vec<Element> = Vec::new();
    let flush = |group: &mut Vec<Element>, result: &mut Vec<Element>, position: &mut [f64; 2]| {
        if group.is_empty() {
            return;
        }
        let original = std::mem::take(group);
        let reordered = reorder_group(&original, *position);
        let chosen = if pen_up_travel(&reordered, *position).0
            < pen_up_travel(&original, *position).0 - 1e-12
        {
            reordered
        } else {
            original
        };
        *position = end_position(&chosen, *position);
        result.extend(chosen);
    };
    for element in drawing {
        match element {
            Element::Barrier => {
                flush(&mut group, &mut result, &mut position);
                result.push(Element::Barrier);
            }
            // A stroke the file leaves with the pen down must stay last.
            Element::Stroke(stroke) if stroke.open_at_end => {
                flush(&mut group, &mut result, &mut position);
                position = stroke.end();
                result.push(Element::Stroke(stroke));
            }
            other => group.push(other),
        }
    }
    flush(&mut group, &mut result, &mut position);
    result
}

fn end_position(elements: &[Element], start: [f64; 2]) -> [f64; 2] {
    elements
        .iter()
        .fold(start, |position, element| match element {
            Element::Travel { to, .. } => *to,
            Element::Stroke(stroke) => stroke.end(),
            Element::Barrier => position,
        })
}

/// Greedy order of one group's strokes, then chained; ends where the group ended.
fn reorder_group(group: &[Element], start: [f64; 2]) -> Vec<Element> {
    let mut remaining: Vec<&Stroke> = group
        .iter()
        .filter_map(|element| match element {
            Element::Stroke(stroke) => Some(stroke),
            _ => None,
        })
        .collect();
    let final_travel = match group.last() {
        Some(Element::Travel { to, span }) => Some(Element::Travel {
            to: *to,
            span: *span,
        }),
        _ => None,
    };
    let mut ordered: Vec<Stroke> = Vec::with_capacity(remaining.len());
    let mut position = start;
    let mut index = EntryIndex::new(&remaining);
    while let Some((stroke_index, reversed)) = index.take_nearest(position) {
        let stroke = remaining[stroke_index];
        let stroke = if reversed {
            stroke.reversed()
        } else {
            stroke.clone()
        };
        position = stroke.end();
        ordered.push(stroke);
    }
    remaining.clear();
    // Chain strokes that meet: the pen stays down.
    let mut chained: Vec<Stroke> = Vec::with_capacity(ordered.len());
    for stroke in ordered {
        match chained.last_mut() {
            Some(previous) if distance(previous.end(), stroke.start) <= CHAIN_TOLERANCE => {
                let joint = stroke.start;
                if distance(previous.end(), joint) > 0.0 {
                    // Close the sub-tolerance gap with a short line so nothing is skipped.
                    let speed = stroke.steps.first().map_or(0.0, |s| s.speed);
                    previous.steps.push(Step {
                        segment: Segment::Line,
                        to: joint,
                        speed,
                        span: stroke.down_span,
                    });
                }
                previous.steps.extend(stroke.steps);
                previous.up_span = stroke.up_span;
            }
            _ => chained.push(stroke),
        }
    }
    let mut result: Vec<Element> = chained.into_iter().map(Element::Stroke).collect();
    result.extend(final_travel);
    result
}

/// An entry point of a stroke: (stroke index, drawn reversed, point).
type Entry = (usize, bool, [f64; 2]);

/// The entry points of strokes (start: forwards, end: reversed) in a uniform grid, so that
/// the nearest-neighbour order costs about O(n) per plot rather than O(n²).
struct EntryIndex {
    cell_size: f64,
    origin: [f64; 2],
    /// Cells in use, each with its entries (stroke index, reversed, point).
    cells: std::collections::HashMap<(i64, i64), Vec<Entry>>,
    taken: Vec<bool>,
    left: usize,
    /// Cell index bounds of all entries.
    bounds: ((i64, i64), (i64, i64)),
}

impl EntryIndex {
    fn new(strokes: &[&Stroke]) -> Self {
        let points: Vec<(usize, bool, [f64; 2])> = strokes
            .iter()
            .enumerate()
            .flat_map(|(index, stroke)| [(index, false, stroke.start), (index, true, stroke.end())])
            .collect();
        let (mut low, mut high) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (_, _, point) in &points {
            for axis in 0..2 {
                low[axis] = low[axis].min(point[axis]);
                high[axis] = high[axis].max(point[axis]);
            }
        }
        let extent = if points.is_empty() {
            0.0
        } else {
            (high[0] - low[0]).max(high[1] - low[1])
        };
        // About one stroke per cell.
        let cell_size = (extent / (strokes.len().max(1) as f64).sqrt()).max(1e-9);
        let origin = if points.is_empty() { [0.0, 0.0] } else { low };
        let mut index = EntryIndex {
            cell_size,
            origin,
            cells: std::collections::HashMap::new(),
            taken: vec![false; strokes.len()],
            left: strokes.len(),
            bounds: ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN)),
        };
        for entry in points {
            let cell = index.cell_of(entry.2);
            index.bounds.0 = (index.bounds.0 .0.min(cell.0), index.bounds.0 .1.min(cell.1));
            index.bounds.1 = (index.bounds.1 .0.max(cell.0), index.bounds.1 .1.max(cell.1));
            index.cells.entry(cell).or_default().push(entry);
        }
        index
    }

    fn cell_of(&self, point: [f64; 2]) -> (i64, i64) {
        let scaled = |axis: usize| {
            ((point[axis] - self.origin[axis]) / self.cell_size)
                .floor()
                .clamp(-1e15, 1e15) as i64
        };
        (scaled(0), scaled(1))
    }

    /// Removes and returns the stroke whose entry point is nearest to `from` (ties: the
    /// earlier stroke, forwards first), and whether to draw it reversed.
    fn take_nearest(&mut self, from: [f64; 2]) -> Option<(usize, bool)> {
        if self.left == 0 {
            return None;
        }
        let centre = self.cell_of(from);
        // Rings beyond this reach no cell in use.
        let reach = [
            (centre.0 - self.bounds.0 .0).abs(),
            (centre.0 - self.bounds.1 .0).abs(),
            (centre.1 - self.bounds.0 .1).abs(),
            (centre.1 - self.bounds.1 .1).abs(),
        ]
        .into_iter()
        .max()
        .unwrap_or(0);
        let mut best: Option<(f64, usize, bool)> = None;
        // Rings nearer than the nearest cell in use are empty.
        let gap = |low: i64, high: i64, at: i64| (low - at).max(at - high).max(0);
        let mut ring = gap(self.bounds.0 .0, self.bounds.1 .0, centre.0).max(gap(
            self.bounds.0 .1,
            self.bounds.1 .1,
            centre.1,
        ));
        // Cells looked at so far in this search.
        let mut looked_at = 0usize;
        while ring <= reach {
            // Once the rings would hold more cells than are in use (far from the strokes, or
            // in an emptied region), look at every cell in use instead.
            let ring_size = if ring == 0 { 1 } else { 8 * ring as usize };
            looked_at += ring_size;
            let cells: Vec<(i64, i64)> = if looked_at > self.cells.len() {
                ring = reach; // this is the last pass
                self.cells.keys().copied().collect()
            } else {
                ring_cells(centre, ring)
            };
            for cell in cells {
                let Some(entries) = self.cells.get_mut(&cell) else {
                    continue;
                };
                entries.retain(|(stroke, _, _)| !self.taken[*stroke]);
                if entries.is_empty() {
                    self.cells.remove(&cell);
                    continue;
                }
                let entries = &self.cells[&cell];
                for &(stroke, reversed, point) in entries.iter() {
                    let candidate = (distance(from, point), stroke, reversed);
                    let better = match best {
                        None => true,
                        Some(current) => {
                            candidate.0 < current.0
                                || (candidate.0 == current.0
                                    && (candidate.1, candidate.2) < (current.1, current.2))
                        }
                    };
                    if better {
                        best = Some(candidate);
                    }
                }
            }
            // Entries in ring r + 1 are at least r cells away.
            if let Some((distance_found, _, _)) = best {
                if distance_found < ring as f64 * self.cell_size {
                    break;
                }
            }
            ring += 1;
        }
        let (_, stroke, reversed) = best?;
        self.taken[stroke] = true;
        self.left -= 1;
        Some((stroke, reversed))
    }
}

/// The cells at Chebyshev distance `ring` from `centre`.
fn ring_cells(centre: (i64, i64), ring: i64) -> Vec<(i64, i64)> {
    if ring == 0 {
        return vec![centre];
    }
    let mut cells = Vec::with_capacity(8 * ring as usize);
    for dx in -ring..=ring {
        cells.push((centre.0 + dx, centre.1 - ring));
        cells.push((centre.0 + dx, centre.1 + ring));
    }
    for dy in -ring + 1..ring {
        cells.push((centre.0 - ring, centre.1 + dy));
        cells.push((centre.0 + ring, centre.1 + dy));
    }
    cells
}
