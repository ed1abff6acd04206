//! The drawing an HPGL file makes: pen-up travels and pen-down strokes (polylines of lines and
//! arcs, in metres on the table) with barriers at pen changes, and the moves generated from it.

use super::super::options::{HpglOptions, ReadOptions};
use super::super::types::{Blend, Feed, Motion, Move, Plane, Position, Program, Span, Spindle};

/// How a piece of a stroke or an edge of a polygon runs to its end point (the centre in
/// metres on the table in a stroke, in plotter units in a polygon).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Segment {
    Line,
    Arc {
        centre: [f64; 2],
        clockwise: bool,
        turns: u32,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Step {
    pub(super) segment: Segment,
    pub(super) to: [f64; 2],
    /// Drawing speed (m/s) in force when the step was programmed.
    pub(super) speed: f64,
    pub(super) span: Span,
}

/// A pen-down polyline: the pen goes down at `start`, draws `steps`, and (unless the file
/// ends with the pen down) goes up at the end. A stroke without steps is a dot.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Stroke {
    pub(super) start: [f64; 2],
    pub(super) steps: Vec<Step>,
    pub(super) down_span: Span,
    pub(super) up_span: Span,
    /// The file ends with this stroke's pen still down.
    pub(super) open_at_end: bool,
}

impl Stroke {
    pub(super) fn end(&self) -> [f64; 2] {
        self.steps.last().map_or(self.start, |step| step.to)
    }

    /// The same stroke drawn from its end to its start.
    pub(super) fn reversed(&self) -> Stroke {
        let mut points = Vec::with_capacity(self.steps.len() + 1);
        points.push(self.start);
        points.extend(self.steps.iter().map(|step| step.to));
        let steps = self
            .steps
            .iter()
            .enumerate()
            .rev()
            .map(|(index, step)| Step {
                segment: match step.segment {
                    Segment::Line => Segment::Line,
                    Segment::Arc {
                        centre,
                        clockwise,
                        turns,
                    } => Segment::Arc {
                        centre,
                        clockwise: !clockwise,
                        turns,
                    },
                },
                to: points[index],
                speed: step.speed,
                span: step.span,
            })
            .collect();
        Stroke {
            start: self.end(),
            steps,
            ..self.clone()
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub(super) enum Element {
    /// Pen-up move to a point.
    Travel {
        to: [f64; 2],
        span: Span,
    },
    Stroke(Stroke),
    /// A pen change: strokes are never reordered across it.
    Barrier,
}

pub(super) fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// Pen-up travel (m) and pen lifts of a drawing started at `start` with the pen up.
pub(super) fn pen_up_travel(drawing: &[Element], start: [f64; 2]) -> (f64, usize) {
    let mut position = start;
    let mut travel = 0.0;
    let mut lifts = 0;
    for element in drawing {
        match element {
            Element::Travel { to, .. } => {
                travel += distance(position, *to);
                position = *to;
            }
            Element::Stroke(stroke) => {
                travel += distance(position, stroke.start);
                position = stroke.end();
                if !stroke.open_at_end {
                    lifts += 1;
                }
            }
            Element::Barrier => {}
        }
    }
    (travel, lifts)
}

/// Moves of a drawing: the table starts at (0, 0) with the pen up.
pub(super) fn generate_moves(
    drawing: &[Element],
    hpgl: &HpglOptions,
    options: &ReadOptions,
) -> Program {
    let mut program = Program {
        start: Position {
            linear: [0.0, 0.0, hpgl.pen_up_z],
            rotary: [0.0; 3],
        },
        ..Program::default()
    };
    let mut position = [0.0, 0.0];
    let base =
        |to: [f64; 2], z: f64, feed: Feed, tool_down: bool, span: Span, motion: Motion| Move {
            motion,
            end: Position {
                linear: [to[0], to[1], z],
                rotary: [0.0; 3],
            },
            tool_axis: None,
            feed,
            feed_rule: options.feed_rule,
            blend: Blend::ExactStop,
            tool_down: Some(tool_down),
            spindle: Spindle::Off,
            span,
        };
    let up = hpgl.pen_up_z;
    let down = hpgl.pen_down_z;
    for element in drawing {
        match element {
            Element::Travel { to, span } => {
                if *to != position {
                    program
                        .moves
                        .push(base(*to, up, Feed::Rapid, false, *span, Motion::Linear));
                    position = *to;
                }
            }
            Element::Stroke(stroke) => {
                if stroke.start != position {
                    program.moves.push(base(
                        stroke.start,
                        up,
                        Feed::Rapid,
                        false,
                        stroke.down_span,
                        Motion::Linear,
                    ));
                }
                // Plunge: the move that brings the tool into the work.
                program.moves.push(base(
                    stroke.start,
                    down,
                    Feed::Rapid,
                    true,
                    stroke.down_span,
                    Motion::Linear,
                ));
                for step in &stroke.steps {
                    let motion = match step.segment {
                        Segment::Line => Motion::Linear,
                        Segment::Arc {
                            centre,
                            clockwise,
                            turns,
                        } => Motion::Arc {
                            center: [centre[0], centre[1], down],
                            plane: Plane::XY,
                            clockwise,
                            turns,
                        },
                    };
                    program.moves.push(base(
                        step.to,
                        down,
                        Feed::PathSpeed(step.speed),
                        true,
                        step.span,
                        motion,
                    ));
                }
                position = stroke.end();
                if !stroke.open_at_end {
                    program.moves.push(base(
                        position,
                        up,
                        Feed::Rapid,
                        false,
                        stroke.up_span,
                        Motion::Linear,
                    ));
                }
            }
            Element::Barrier => {}
        }
    }
    program
}
