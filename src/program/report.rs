//! Geometry and timing of decoded moves, and the text of `cncsim inspect`.

use std::fmt::Write as _;

use super::types::{Feed, FeedRule, Motion, Move, Plane, Position, Program};

/// (first, second, normal) axis indices of a plane, ordered so that counter-clockwise is
/// positive about the normal (G18: from Z towards X, about +Y).
pub fn plane_axes(plane: Plane) -> (usize, usize, usize) {
    match plane {
        Plane::XY => (0, 1, 2),
        Plane::ZX => (2, 0, 1),
        Plane::YZ => (1, 2, 0),
    }
}

/// Angle (rad, > 0) an arc sweeps about its centre from `start` to `end`, including its extra
/// full turns. An arc whose end lies at its start (in the plane) is a full circle.
pub fn arc_sweep(
    start: &[f64; 3],
    end: &[f64; 3],
    center: &[f64; 3],
    plane: Plane,
    clockwise: bool,
    turns: u32,
) -> f64 {
    let (first, second, _) = plane_axes(plane);
    let start_angle = (start[second] - center[second]).atan2(start[first] - center[first]);
    let end_angle = (end[second] - center[second]).atan2(end[first] - center[first]);
    let tau = std::f64::consts::TAU;
    let difference = if clockwise {
        start_angle - end_angle
    } else {
        end_angle - start_angle
    };
    let mut sweep = difference.rem_euclid(tau);
    let same_point = start[first] == end[first] && start[second] == end[second];
    if same_point || sweep < 1e-12 {
        sweep = tau;
    }
    sweep + tau * f64::from(turns)
}

/// Length (m) of the path of the linear axes in a move from `from`; 0 for a dwell.
pub fn move_length(from: &Position, mv: &Move) -> f64 {
    match mv.motion {
        Motion::Dwell { .. } => 0.0,
        Motion::Linear => distance(&from.linear, &mv.end.linear),
        Motion::Arc {
            center,
            plane,
            clockwise,
            turns,
        } => {
            let (first, second, normal) = plane_axes(plane);
            let radius =
                (from.linear[first] - center[first]).hypot(from.linear[second] - center[second]);
            let sweep = arc_sweep(
                &from.linear,
                &mv.end.linear,
                &center,
                plane,
                clockwise,
                turns,
            );
            let rise = mv.end.linear[normal] - from.linear[normal];
            (radius * sweep).hypot(rise)
        }
    }
}

/// Rotation (degrees) of the rotary axes in a move: the Euclidean norm of the A B C deltas.
pub fn rotary_travel_degrees(from: &Position, mv: &Move) -> f64 {
    distance(&from.rotary, &mv.end.rotary).to_degrees()
}

/// How long (s) a move takes at its programmed feed, from `from`; `None` for rapids, whose
/// speed is the machine's. The feed rule of the move decides how rotary axes count:
/// LinuxCNC's feeds the linear path (a purely rotary move at F in degrees per unit time);
/// the 5-axis study's divides the Euclidean norm of all axis deltas (linear in mm, rotary in
/// degrees) by F.
pub fn move_duration(from: &Position, mv: &Move) -> Option<f64> {
    if let Motion::Dwell { seconds } = mv.motion {
        return Some(seconds);
    }
    match mv.feed {
        Feed::Rapid => None,
        Feed::InverseTime(seconds) => Some(seconds),
        Feed::PathSpeed(speed) if speed > 0.0 => {
            let linear_mm = move_length(from, mv) * 1000.0;
            let rotary_degrees = rotary_travel_degrees(from, mv);
            // `PathSpeed` is m/s; feeds that apply to degrees use 1 mm ≡ 1 degree.
            let speed_per_second = speed * 1000.0;
            let path = match mv.feed_rule {
                FeedRule::LinuxCnc if linear_mm > 0.0 => linear_mm,
                FeedRule::LinuxCnc => rotary_degrees,
                FeedRule::EuclideanAllAxes => linear_mm.hypot(rotary_degrees),
            };
            Some(path / speed_per_second)
        }
        Feed::PathSpeed(_) => None,
    }
}

/// Whether a move is a rapid or pen-up travel rather than a cut.
pub fn is_rapid(mv: &Move) -> bool {
    !matches!(mv.motion, Motion::Dwell { .. })
        && (matches!(mv.feed, Feed::Rapid) || mv.tool_down == Some(false))
}

/// Totals over a program.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ProgramSummary {
    /// All moves, dwells included.
    pub moves: usize,
    /// Moves that cut (feed moves with the tool down or unspecified).
    pub cut_moves: usize,
    /// Rapid and pen-up moves ([`is_rapid`]).
    pub rapid_moves: usize,
    /// Dwells.
    pub dwells: usize,
    /// Linear path length (m) of cutting (pen-down) moves.
    pub cut_length: f64,
    /// Linear path length (m) of rapid and pen-up moves.
    pub rapid_length: f64,
    /// Time (s) of cutting moves and dwells at programmed feed; rapids are not timed.
    pub feed_time: f64,
    /// Smallest and largest linear coordinates reached (m), including the start.
    pub bounds: ([f64; 3], [f64; 3]),
}

/// Counts, lengths, feed time and bounds of `program`.
pub fn summarize(program: &Program) -> ProgramSummary {
    let mut summary = ProgramSummary {
        bounds: (program.start.linear, program.start.linear),
        ..ProgramSummary::default()
    };
    let mut position = program.start;
    for mv in &program.moves {
        summary.moves += 1;
        let length = move_length(&position, mv);
        if matches!(mv.motion, Motion::Dwell { .. }) {
            summary.dwells += 1;
        } else if is_rapid(mv) {
            summary.rapid_moves += 1;
            summary.rapid_length += length;
        } else {
            summary.cut_moves += 1;
            summary.cut_length += length;
        }
        if !is_rapid(mv) {
            summary.feed_time += move_duration(&position, mv).unwrap_or(0.0);
        }
        for axis in 0..3 {
            summary.bounds.0[axis] = summary.bounds.0[axis].min(mv.end.linear[axis]);
            summary.bounds.1[axis] = summary.bounds.1[axis].max(mv.end.linear[axis]);
        }
        position = mv.end;
    }
    summary
}

/// Pen-up travel of an HPGL program before and after stroke reordering.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PenUpTravel {
    /// Pen-up travel (m) in the order the file draws.
    pub before: f64,
    /// Pen-up travel (m) after reordering and chaining.
    pub after: f64,
    /// Pen lifts in the file's order and after chaining.
    pub lifts_before: usize,
    /// Pen lifts after reordering and chaining.
    pub lifts_after: usize,
}

/// How much `inspect` prints.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InspectOptions {
    /// Programs with at most this many moves are listed move by move; longer ones show their
    /// first and last moves only.
    pub list_limit: usize,
}

impl Default for InspectOptions {
    fn default() -> Self {
        InspectOptions { list_limit: 200 }
    }
}

/// The text `cncsim inspect PROGRAM` prints: the decoded moves (or the first and last of a
/// long program), warnings, total cut and rapid/pen-up lengths and the program time at the
/// programmed feed.
pub fn inspect_report(
    program: &Program,
    pen_up: Option<&PenUpTravel>,
    options: &InspectOptions,
) -> String {
    let mut out = String::new();
    let summary = summarize(program);
    let _ = writeln!(out, "program: {}", program.source.display());
    if let Some(reading) = &program.reading {
        let _ = writeln!(out, "read as: {reading}");
    }
    let _ = writeln!(
        out,
        "moves: {} ({} cutting, {} rapid/pen-up, {} dwell)",
        summary.moves, summary.cut_moves, summary.rapid_moves, summary.dwells
    );
    for tool in &program.tools {
        let mut names = Vec::new();
        if let Some(operation) = &tool.operation {
            names.push(format!("operation {operation}"));
        }
        if let Some(name) = &tool.name {
            names.push(format!("tool {name}"));
        }
        let _ = writeln!(
            out,
            "tool: {}:{}: {} diameter {:.4} mm, corner radius {:.4} mm, length {:.4} mm, taper {:.3} deg, tip {:.3} deg{}",
            tool.span.line,
            tool.span.column,
            tool.kind,
            tool.diameter * 1e3,
            tool.corner_radius * 1e3,
            tool.length * 1e3,
            tool.taper_angle.to_degrees(),
            tool.tip_angle.to_degrees(),
            if names.is_empty() {
                String::new()
            } else {
                format!(" ({})", names.join(", "))
            }
        );
    }
    let listed: Vec<usize> = if program.moves.len() <= options.list_limit {
        (0..program.moves.len()).collect()
    } else {
        let head = options.list_limit.div_ceil(2).max(1);
        let tail = (options.list_limit / 2).max(1);
        (0..head)
            .chain(program.moves.len() - tail..program.moves.len())
            .collect()
    };
    let _ = writeln!(
        out,
        "{:>7}  {:>10}  {:<6} {:>10} {:>10} {:>10} {:>9} {:>9} {:>9}  {:>10}  {:>9}",
        "#",
        "line:col",
        "kind",
        "X mm",
        "Y mm",
        "Z mm",
        "A deg",
        "B deg",
        "C deg",
        "feed mm/s",
        "time s"
    );
    let mut position = program.start;
    let mut previous_listed: Option<usize> = None;
    let mut listed_iter = listed.iter().peekable();
    for (index, mv) in program.moves.iter().enumerate() {
        if listed_iter.peek() == Some(&&index) {
            listed_iter.next();
            if let Some(previous) = previous_listed {
                if index > previous + 1 {
                    let _ = writeln!(
                        out,
                        "{:>7}  … {} moves not listed",
                        "",
                        index - previous - 1
                    );
                }
            }
            previous_listed = Some(index);
            let kind = match mv.motion {
                Motion::Dwell { .. } => "dwell",
                Motion::Arc {
                    clockwise: true, ..
                } => "arc cw",
                Motion::Arc {
                    clockwise: false, ..
                } => "arc ccw",
                Motion::Linear if is_rapid(mv) => "rapid",
                Motion::Linear => "line",
            };
            let feed = match mv.feed {
                Feed::Rapid => "rapid".to_string(),
                Feed::PathSpeed(speed) => format!("{:.3}", speed * 1000.0),
                Feed::InverseTime(seconds) => format!("1/{seconds:.3}s"),
            };
            let time =
                move_duration(&position, mv).map_or_else(|| "-".to_string(), |t| format!("{t:.3}"));
            let location = format!("{}:{}", mv.span.line, mv.span.column);
            let _ = write!(
                out,
                "{:>7}  {:>10}  {:<6} {:>10.4} {:>10.4} {:>10.4} {:>9.4} {:>9.4} {:>9.4}  {:>10}  {:>9}",
                index + 1,
                location,
                kind,
                mv.end.linear[0] * 1000.0,
                mv.end.linear[1] * 1000.0,
                mv.end.linear[2] * 1000.0,
                mv.end.rotary[0].to_degrees(),
                mv.end.rotary[1].to_degrees(),
                mv.end.rotary[2].to_degrees(),
                feed,
                time
            );
            // Arcs also show their centre, so the listing is the whole decoded geometry.
            if let Motion::Arc { center, turns, .. } = mv.motion {
                let _ = write!(
                    out,
                    "  centre {:.4} {:.4} {:.4}",
                    center[0] * 1000.0,
                    center[1] * 1000.0,
                    center[2] * 1000.0
                );
                if turns > 0 {
                    let _ = write!(out, " +{turns} turns");
                }
            }
            let _ = writeln!(out);
        }
        position = mv.end;
    }
    for warning in &program.warnings {
        let _ = writeln!(
            out,
            "warning: {}:{}:{}: {}",
            program.source.display(),
            warning.span.line,
            warning.span.column,
            warning.message
        );
    }
    let _ = writeln!(out, "cut length: {:.3} mm", summary.cut_length * 1000.0);
    let _ = writeln!(
        out,
        "rapid/pen-up length: {:.3} mm",
        summary.rapid_length * 1000.0
    );
    let _ = writeln!(
        out,
        "program time at programmed feed: {:.3} s (rapids not included)",
        summary.feed_time
    );
    if let Some(pen_up) = pen_up {
        let _ = writeln!(
            out,
            "pen-up travel: {:.3} mm with {} lifts as drawn, {:.3} mm with {} lifts after reordering",
            pen_up.before * 1000.0,
            pen_up.lifts_before,
            pen_up.after * 1000.0,
            pen_up.lifts_after
        );
    }
    out
}

fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let dx = b[0] - a[0];
    let dy = b[1] - a[1];
    let dz = b[2] - a[2];
    (dx * dx + dy * dy + dz * dz).sqrt()
}
