//! HP-GL/1 as AutoCAD writes it for an HP 7475 pen plotter, redirected to an XYZ table:
//! pen down/up become the tool's Z heights, VS the drawing speed.
//!
//! The file is read in two stages. The plotter model turns commands into a drawing: pen-up
//! travels and pen-down strokes (polylines of lines and arcs), with barriers where the pen is
//! changed. Moves are then generated from the drawing, either in the file's order or, with
//! `optimise_pen_up`, with strokes reordered and reversed to shorten pen-up travel (never
//! across a pen change, never changing a stroke's geometry).

use std::path::Path;

use super::error::{display_text, ErrorSink, Found, ProgramError, ProgramErrors};
use super::options::{HpglOptions, ReadOptions};
use super::report::PenUpTravel;
use super::source::LineIndex;
use super::types::{Feed, Motion, Move, Plane, Position, Program, Span, Warning};

/// A decoded HPGL program with its pen-up travel figures.
#[derive(Debug, Clone, PartialEq)]
pub struct HpglOutput {
    pub program: Program,
    /// Pen-up travel as drawn and (if `optimise_pen_up`) after reordering; without
    /// optimisation both figures are the file's.
    pub pen_up: PenUpTravel,
}

/// Decodes an HPGL plot file held in memory. `source` names it in messages.
pub fn parse_hpgl(
    text: impl AsRef<[u8]>,
    source: impl AsRef<Path>,
    options: &ReadOptions,
) -> Result<Program, ProgramErrors> {
    parse_hpgl_detailed(text, source, options).map(|output| output.program)
}

/// Like [`parse_hpgl`], also returning the pen-up travel before and after optimisation.
pub fn parse_hpgl_detailed(
    text: impl AsRef<[u8]>,
    source: impl AsRef<Path>,
    options: &ReadOptions,
) -> Result<HpglOutput, ProgramErrors> {
    let text = text.as_ref();
    let source = source.as_ref();
    let mut reader = Reader {
        text,
        at: 0,
        lines: LineIndex::new(text),
        source,
        options: &options.hpgl,
        errors: ErrorSink::new(options.max_errors),
        warnings: Vec::new(),
        plotter: Plotter::new(&options.hpgl),
        drawing: Vec::new(),
        stroke: None,
    };
    reader.run();
    let Reader {
        errors,
        warnings,
        drawing,
        options: hpgl,
        ..
    } = reader;
    if !errors.is_empty() {
        return errors.finish(HpglOutput {
            program: Program::default(),
            pen_up: PenUpTravel::default(),
        });
    }
    let start = [0.0, 0.0];
    let (travel_before, lifts_before) = pen_up_travel(&drawing, start);
    let drawing = if hpgl.optimise_pen_up {
        optimise(drawing, start)
    } else {
        drawing
    };
    let (travel_after, lifts_after) = pen_up_travel(&drawing, start);
    let mut program = generate_moves(&drawing, hpgl, options);
    program.source = source.to_path_buf();
    program.warnings = warnings;
    Ok(HpglOutput {
        program,
        pen_up: PenUpTravel {
            before: travel_before,
            after: travel_after,
            lifts_before,
            lifts_after,
        },
    })
}

/// One pen-down piece of a stroke (positions in metres on the table).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Segment {
    Line,
    Arc {
        centre: [f64; 2],
        clockwise: bool,
        turns: u32,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Step {
    segment: Segment,
    to: [f64; 2],
    /// Drawing speed (m/s) in force when the step was programmed.
    speed: f64,
    span: Span,
}

/// A pen-down polyline: the pen goes down at `start`, draws `steps`, and (unless the file
/// ends with the pen down) goes up at the end. A stroke without steps is a dot.
#[derive(Debug, Clone, PartialEq)]
struct Stroke {
    start: [f64; 2],
    steps: Vec<Step>,
    down_span: Span,
    up_span: Span,
    /// The file ends with this stroke's pen still down.
    open_at_end: bool,
}

impl Stroke {
    fn end(&self) -> [f64; 2] {
        self.steps.last().map_or(self.start, |step| step.to)
    }

    /// The same stroke drawn from its end to its start.
    fn reversed(&self) -> Stroke {
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
enum Element {
    /// Pen-up move to a point.
    Travel {
        to: [f64; 2],
        span: Span,
    },
    Stroke(Stroke),
    /// A pen change: strokes are never reordered across it.
    Barrier,
}

/// SC scaling: user units `min..max` map onto P1..P2.
#[derive(Debug, Clone, Copy)]
struct Scaling {
    user_min: [f64; 2],
    user_max: [f64; 2],
}

/// The plotter's state while reading.
struct Plotter {
    absolute: bool,
    pen_down: bool,
    /// Current pen position in plotter units.
    position: [f64; 2],
    scaling: Option<Scaling>,
    p1: [f64; 2],
    p2: [f64; 2],
    /// Drawing speed, m/s.
    speed: f64,
}

impl Plotter {
    fn new(options: &HpglOptions) -> Self {
        Plotter {
            absolute: true,
            pen_down: false,
            position: [0.0, 0.0],
            scaling: None,
            p1: options.default_p1,
            p2: options.default_p2,
            speed: options.default_speed,
        }
    }

    /// Plotter units per user unit along each axis.
    fn scale(&self) -> [f64; 2] {
        match self.scaling {
            None => [1.0, 1.0],
            Some(s) => [
                (self.p2[0] - self.p1[0]) / (s.user_max[0] - s.user_min[0]),
                (self.p2[1] - self.p1[1]) / (s.user_max[1] - s.user_min[1]),
            ],
        }
    }

    /// A point in user units as plotter units.
    fn to_plotter(&self, user: [f64; 2]) -> [f64; 2] {
        match self.scaling {
            None => user,
            Some(s) => {
                let scale = self.scale();
                [
                    self.p1[0] + (user[0] - s.user_min[0]) * scale[0],
                    self.p1[1] + (user[1] - s.user_min[1]) * scale[1],
                ]
            }
        }
    }

    /// Target of a coordinate pair under the current PA/PR mode, in plotter units.
    fn target(&self, pair: [f64; 2]) -> [f64; 2] {
        if self.absolute {
            self.to_plotter(pair)
        } else {
            let scale = self.scale();
            [
                self.position[0] + pair[0] * scale[0],
                self.position[1] + pair[1] * scale[1],
            ]
        }
    }
}

/// A parsed numeric parameter and where it was.
#[derive(Debug, Clone, Copy)]
struct Parameter {
    value: f64,
    start: usize,
    end: usize,
}

struct Reader<'a> {
    text: &'a [u8],
    at: usize,
    lines: LineIndex<'a>,
    source: &'a Path,
    options: &'a HpglOptions,
    errors: ErrorSink,
    warnings: Vec<Warning>,
    plotter: Plotter,
    drawing: Vec<Element>,
    /// The stroke being drawn while the pen is down.
    stroke: Option<Stroke>,
}

/// ASCII ETX, which ends label text.
const ETX: u8 = 0x03;
const ESC: u8 = 0x1b;

impl<'a> Reader<'a> {
    fn run(&mut self) {
        while self.at < self.text.len() {
            let byte = self.text[self.at];
            match byte {
                b' ' | b'\t' | b'\r' | b'\n' | b';' | 0 => self.at += 1,
                ESC => self.device_control(),
                _ if byte.is_ascii_alphabetic() => self.command(),
                _ => {
                    let end = self.char_end(self.at);
                    self.error(
                        self.at,
                        end,
                        "expected an HPGL command (two letters) or ';'",
                        None,
                    );
                    self.skip_to_terminator();
                }
            }
        }
        // End of file: a stroke still being drawn stays down.
        let at = self.text.len();
        if let Some(mut stroke) = self.stroke.take() {
            stroke.open_at_end = true;
            stroke.up_span = self.lines.span(at);
            self.drawing.push(Element::Stroke(stroke));
        }
    }

    fn span(&self, at: usize) -> Span {
        self.lines.span(at)
    }

    fn char_end(&self, start: usize) -> usize {
        let mut end = start + 1;
        while end < self.text.len() && end - start < 4 && (self.text[end] & 0xC0) == 0x80 {
            end += 1;
        }
        end
    }

    fn error(&mut self, start: usize, end: usize, problem: impl Into<String>, hint: Option<&str>) {
        let end = end.min(self.text.len());
        let found = if start >= end {
            Found::EndOfFile
        } else {
            Found::Text(display_text(&self.text[start..end]))
        };
        let mut error =
            ProgramError::new(self.source, Some(self.span(start)), problem).found(found);
        error.hint = hint.map(str::to_string);
        self.errors.push(error);
    }

    /// After an error: resume at the next command terminator.
    fn skip_to_terminator(&mut self) {
        while self.at < self.text.len() && !matches!(self.text[self.at], b';' | ESC) {
            self.at += 1;
        }
    }

    /// HP device-control sequences `ESC . x [params] [:]`, which start AutoCAD's plot files.
    fn device_control(&mut self) {
        let start = self.at;
        if self.text.get(start + 1) != Some(&b'.') {
            let end = self.char_end(start + 1).min(self.text.len()).max(start + 1);
            self.error(
                start,
                end,
                "expected '.' after ESC (an HP device-control sequence)",
                None,
            );
            self.at = start + 1;
            return;
        }
        let Some(&kind) = self.text.get(start + 2) else {
            self.error(
                start,
                self.text.len(),
                "expected a device-control command after ESC '.'",
                None,
            );
            self.at = self.text.len();
            return;
        };
        self.at = start + 3;
        match kind.to_ascii_uppercase() {
            // Without parameters: plotter on/off, status and output requests, resets.
            b'(' | b')' | b'Y' | b'Z' | b'A' | b'B' | b'E' | b'J' | b'K' | b'L' | b'O' | b'R'
            | b'S' | b'U' => {}
            // With parameters ending in ':' (handshake, buffer and output settings).
            b'@' | b'H' | b'I' | b'M' | b'N' | b'P' | b'Q' | b'T' => {
                loop {
                    match self.text.get(self.at) {
                        Some(b':') => {
                            self.at += 1;
                            break;
                        }
                        Some(b) if b.is_ascii_digit() || *b == b';' || *b == b' ' => self.at += 1,
                        // The sequence may end without ':' when its parameters are left out.
                        _ => break,
                    }
                }
            }
            _ => {
                let end = self.char_end(start + 2);
                self.error(start, end, "expected a known HP device-control sequence (ESC . followed by ( ) @ A B E H I J K L M N O P Q R S T U Y Z)", None);
            }
        }
    }

    fn command(&mut self) {
        let start = self.at;
        let first = self.text[start].to_ascii_uppercase();
        let second = match self.text.get(start + 1) {
            Some(b) if b.is_ascii_alphabetic() => b.to_ascii_uppercase(),
            _ => {
                let end = (start + 2).min(self.text.len());
                self.error(
                    start,
                    self.char_end(start + 1).min(self.text.len()).max(end),
                    "expected a two-letter HPGL command",
                    None,
                );
                self.at = start + 1;
                self.skip_to_terminator();
                return;
            }
        };
        self.at = start + 2;
        let mnemonic = [first, second];
        if &mnemonic == b"LB" {
            // Label text runs to ETX and may contain anything, including ';'.
            let end = self.text[self.at..]
                .iter()
                .position(|&b| b == ETX)
                .map_or(self.text.len(), |i| self.at + i + 1);
            self.error(
                start,
                (start + 2).min(end),
                "expected a drawing command; labels (LB) are not supported",
                Some("plot text as vectors (AutoCAD does this by default)"),
            );
            self.at = end;
            return;
        }
        let Some(parameters) = self.parameters(&mnemonic, start) else {
            self.skip_to_terminator();
            return;
        };
        let name = std::str::from_utf8(&mnemonic).unwrap_or("??").to_string();
        let span = self.span(start);
        if let Err((problem, hint)) = self.execute(&name, &parameters, start, span) {
            let end = parameters.last().map_or(start + 2, |p| p.end);
            self.error(start, end, problem, hint);
        }
    }

    /// Reads the parameters of a command: numbers separated by commas or blanks, ended by ';',
    /// the next command's letters, ESC or the end of the file.
    fn parameters(&mut self, mnemonic: &[u8; 2], command_start: usize) -> Option<Vec<Parameter>> {
        let mut parameters = Vec::new();
        let mut expecting_number = false;
        loop {
            while matches!(self.text.get(self.at), Some(b' ' | b'\t' | b'\r' | b'\n')) {
                self.at += 1;
            }
            match self.text.get(self.at) {
                Some(b'0'..=b'9' | b'+' | b'-' | b'.') => {
                    let start = self.at;
                    match self.number() {
                        Some(value) => parameters.push(Parameter {
                            value,
                            start,
                            end: self.at,
                        }),
                        None => {
                            let end = self.char_end(self.at.max(start)).max(start + 1);
                            self.error(start, end.max(self.at), format!("expected a number of at most 1e9 in magnitude in the parameters of {}", String::from_utf8_lossy(mnemonic)), None);
                            return None;
                        }
                    }
                    expecting_number = false;
                }
                Some(b',') if !parameters.is_empty() && !expecting_number => {
                    self.at += 1;
                    expecting_number = true;
                }
                Some(b';') if !expecting_number => {
                    self.at += 1;
                    return Some(parameters);
                }
                None | Some(&ESC) if !expecting_number => return Some(parameters),
                Some(b) if b.is_ascii_alphabetic() && !expecting_number => return Some(parameters),
                _ => {
                    let what = if expecting_number {
                        "a number after ','"
                    } else {
                        "',', ';' or a number"
                    };
                    let end = if self.at < self.text.len() {
                        self.char_end(self.at)
                    } else {
                        self.at
                    };
                    let _ = command_start;
                    self.error(
                        self.at,
                        end,
                        format!(
                            "expected {what} in the parameters of {}",
                            String::from_utf8_lossy(mnemonic)
                        ),
                        None,
                    );
                    return None;
                }
            }
        }
    }

    /// A decimal number: optional sign, digits with an optional point.
    fn number(&mut self) -> Option<f64> {
        let start = self.at;
        if matches!(self.text.get(self.at), Some(b'+' | b'-')) {
            self.at += 1;
        }
        let mut digits = 0;
        let mut point = false;
        while let Some(&b) = self.text.get(self.at) {
            match b {
                b'0'..=b'9' => digits += 1,
                b'.' if !point => point = true,
                _ => break,
            }
            self.at += 1;
        }
        if digits == 0 {
            return None;
        }
        let text = std::str::from_utf8(&self.text[start..self.at]).ok()?;
        // Far beyond any plotter; keeps every later sum finite.
        text.parse::<f64>().ok().filter(|v| v.abs() <= 1e9)
    }

    fn warn(&mut self, span: Span, message: String) {
        self.warnings.push(Warning { span, message });
    }

    fn execute(
        &mut self,
        name: &str,
        parameters: &[Parameter],
        start: usize,
        span: Span,
    ) -> Result<(), (String, Option<&'static str>)> {
        let values: Vec<f64> = parameters.iter().map(|p| p.value).collect();
        let count_error = |allowed: &str| {
            Err((
                format!(
                    "expected {allowed} parameters after {name}, not {}",
                    values.len()
                ),
                None,
            ))
        };
        match name {
            "IN" => {
                self.pen_up(span);
                self.plotter = Plotter {
                    position: self.plotter.position,
                    ..Plotter::new(self.options)
                };
            }
            "DF" => {
                self.plotter.absolute = true;
                self.plotter.scaling = None;
            }
            "SC" => match values.as_slice() {
                [] => self.plotter.scaling = None,
                &[xmin, xmax, ymin, ymax] => {
                    if xmin == xmax || ymin == ymax {
                        return Err((format!("expected SC limits with xmin ≠ xmax and ymin ≠ ymax, not {xmin},{xmax},{ymin},{ymax}"), None));
                    }
                    self.plotter.scaling = Some(Scaling {
                        user_min: [xmin, ymin],
                        user_max: [xmax, ymax],
                    });
                }
                _ => return count_error("0 or 4"),
            },
            "IP" => match values.as_slice() {
                [] => {
                    self.plotter.p1 = self.options.default_p1;
                    self.plotter.p2 = self.options.default_p2;
                }
                &[x1, y1] => {
                    // P2 keeps its distance from P1.
                    let shift = [x1 - self.plotter.p1[0], y1 - self.plotter.p1[1]];
                    self.plotter.p1 = [x1, y1];
                    self.plotter.p2 =
                        [self.plotter.p2[0] + shift[0], self.plotter.p2[1] + shift[1]];
                }
                &[x1, y1, x2, y2] => {
                    self.plotter.p1 = [x1, y1];
                    self.plotter.p2 = [x2, y2];
                }
                _ => return count_error("0, 2 or 4"),
            },
            "SP" => {
                if values.len() > 1 {
                    return count_error("0 or 1");
                }
                // Selecting (or putting away) a pen lifts it; strokes are not reordered
                // across a pen change.
                self.pen_up(span);
                self.drawing.push(Element::Barrier);
            }
            "VS" => match values.as_slice() {
                [] => self.plotter.speed = self.options.default_speed,
                &[speed] | &[speed, _] => {
                    if speed <= 0.0 {
                        return Err((
                            format!("expected a positive pen speed (cm/s) after VS, not {speed}"),
                            None,
                        ));
                    }
                    self.plotter.speed = speed / 100.0;
                }
                _ => return count_error("0, 1 or 2"),
            },
            "LT" => match values.as_slice() {
                [] => {}
                [pattern] | [pattern, _] => {
                    let message = format!("line type {pattern} (dashed) is drawn as a solid line");
                    self.warn(span, message);
                }
                _ => return count_error("0, 1 or 2"),
            },
            "PU" | "PD" | "PA" | "PR" => {
                match name {
                    "PU" => self.pen_up(span),
                    "PD" => self.pen_down(span),
                    "PA" => self.plotter.absolute = true,
                    _ => self.plotter.absolute = false,
                }
                let mut coordinates = parameters;
                if coordinates.len() % 2 == 1 {
                    let dangling = coordinates[coordinates.len() - 1];
                    if self.options.lenient {
                        let message = format!(
                            "{name} has {} coordinate{}: the dangling coordinate {} is dropped",
                            coordinates.len(),
                            if coordinates.len() == 1 { "" } else { "s" },
                            fmt_number(dangling.value)
                        );
                        self.warn(span, message);
                        coordinates = &coordinates[..coordinates.len() - 1];
                    } else {
                        let message = format!(
                            "expected x,y pairs after {name}: an even number of coordinates, not {} (byte offset {})",
                            coordinates.len(),
                            span.byte_offset
                        );
                        let end = dangling.end;
                        let mut error = ProgramError::new(self.source, Some(span), message)
                            .found(Found::Text(display_text(&self.text[start..end])));
                        error.hint = Some("the file may be damaged; the lenient option drops the dangling coordinate".to_string());
                        self.errors.push(error);
                        return Ok(());
                    }
                }
                for pair in coordinates.chunks_exact(2) {
                    let target = self.plotter.target([pair[0].value, pair[1].value]);
                    self.move_to(target, Segment::Line, self.span(pair[0].start));
                }
            }
            "CI" => {
                // The chord angle (second parameter) only matters to a plotter drawing the
                // circle as chords; the table follows the true circle.
                let radius = match *values.as_slice() {
                    [radius] | [radius, _] => radius,
                    _ => return count_error("1 or 2"),
                };
                let radius = radius * self.plotter.scale()[0];
                if radius == 0.0 {
                    self.warn(span, "CI with radius 0 draws nothing".to_string());
                    return Ok(());
                }
                // The pen goes up to the circumference (at 0°, or 180° for a negative
                // radius), down round the full circle, and back up to the centre; then the
                // pen state is restored.
                let centre = self.plotter.position;
                let was_down = self.plotter.pen_down;
                let on_circle = [centre[0] + radius, centre[1]];
                self.pen_up(span);
                self.move_to(on_circle, Segment::Line, span);
                self.pen_down(span);
                let centre_m = self.metres(centre);
                self.move_to(
                    on_circle,
                    Segment::Arc {
                        centre: centre_m,
                        clockwise: false,
                        turns: 0,
                    },
                    span,
                );
                self.pen_up(span);
                self.move_to(centre, Segment::Line, span);
                if was_down {
                    self.pen_down(span);
                }
            }
            "AA" | "AR" => {
                let (x, y, sweep) = match values.as_slice() {
                    &[x, y, sweep] | &[x, y, sweep, _] => (x, y, sweep),
                    _ => return count_error("3 or 4"),
                };
                let centre = if name == "AA" {
                    self.plotter.to_plotter([x, y])
                } else {
                    let scale = self.plotter.scale();
                    [
                        self.plotter.position[0] + x * scale[0],
                        self.plotter.position[1] + y * scale[1],
                    ]
                };
                let from = self.plotter.position;
                let radius = (from[0] - centre[0]).hypot(from[1] - centre[1]);
                if sweep == 0.0 || radius == 0.0 {
                    self.warn(
                        span,
                        format!("{name} with zero radius or zero sweep draws nothing"),
                    );
                    return Ok(());
                }
                let start_angle = (from[1] - centre[1]).atan2(from[0] - centre[0]);
                let end_angle = start_angle + sweep.to_radians();
                let to = [
                    centre[0] + radius * end_angle.cos(),
                    centre[1] + radius * end_angle.sin(),
                ];
                // Sweeps of 360° or more: the last partial (or full) turn plus extra turns.
                let full_turns = (sweep.abs() / 360.0 - 1e-12).ceil().max(1.0) - 1.0;
                let turns = full_turns.min(f64::from(u32::MAX)) as u32;
                let segment = Segment::Arc {
                    centre: self.metres(centre),
                    clockwise: sweep < 0.0,
                    turns,
                };
                self.move_to(to, segment, span);
            }
            // Output and status requests: answered by a plotter, no effect on the drawing.
            "OA" | "OC" | "OD" | "OE" | "OF" | "OH" | "OI" | "OO" | "OP" | "OS" | "OW" => {}
            // Character set and label settings: labels are refused on their own.
            "CA" | "CS" | "SS" | "SA" | "SI" | "SL" | "SR" | "DI" | "DR" | "DT" | "IM" => {}
            _ => {
                return Err((
                    format!("expected an HPGL command cncsim supports (IN DF SC IP SP PU PD PA PR VS LT CI AA AR); {name} is not"),
                    Some("re-plot from the CAD package for an HP 7475 with lines only"),
                ));
            }
        }
        Ok(())
    }

    fn metres(&self, plotter: [f64; 2]) -> [f64; 2] {
        let per_metre = self.options.units_per_mm * 1000.0;
        [plotter[0] / per_metre, plotter[1] / per_metre]
    }

    fn pen_up(&mut self, span: Span) {
        if let Some(mut stroke) = self.stroke.take() {
            stroke.up_span = span;
            self.drawing.push(Element::Stroke(stroke));
        }
        self.plotter.pen_down = false;
    }

    fn pen_down(&mut self, span: Span) {
        if self.stroke.is_none() {
            self.stroke = Some(Stroke {
                start: self.metres(self.plotter.position),
                steps: Vec::new(),
                down_span: span,
                up_span: span,
                open_at_end: false,
            });
        }
        self.plotter.pen_down = true;
    }

    /// Moves the pen (drawing if it is down) to `target` (plotter units).
    fn move_to(&mut self, target: [f64; 2], segment: Segment, span: Span) {
        let to = self.metres(target);
        let speed = self.plotter.speed;
        if let Some(stroke) = &mut self.stroke {
            stroke.steps.push(Step {
                segment,
                to,
                speed,
                span,
            });
        } else {
            self.drawing.push(Element::Travel { to, span });
        }
        self.plotter.position = target;
    }
}

fn fmt_number(value: f64) -> String {
    format!("{value}")
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// Pen-up travel (m) and pen lifts of a drawing started at `start` with the pen up.
fn pen_up_travel(drawing: &[Element], start: [f64; 2]) -> (f64, usize) {
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

/// Points closer than this (m) count as the same point when chaining strokes; a tenth of a
/// plotter unit.
const CHAIN_TOLERANCE: f64 = 2.5e-6;

/// Reorders and reverses the strokes between pen changes to shorten pen-up travel (greedy
/// nearest neighbour from the current position), chains strokes that meet end to start, and
/// keeps the original order of any group the greedy order would not improve.
fn optimise(drawing: Vec<Element>, start: [f64; 2]) -> Vec<Element> {
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

/// Moves of a drawing: the table starts at (0, 0) with the pen up.
fn generate_moves(drawing: &[Element], hpgl: &HpglOptions, options: &ReadOptions) -> Program {
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
            blend: super::types::Blend::ExactStop,
            tool_down: Some(tool_down),
            spindle: super::types::Spindle::Off,
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
