//! APT cutter-location (CL) data as CAM systems write it: `UNITS`, `FEDRAT`,
//! `GOTO/x,y,z[,i,j,k]`, `GODLTA`, `FROM`, `RAPID`, `CIRCLE` arcs, `DELAY`, `SPINDL`,
//! `TLAXIS`, `FINI`, NX CLSF structure (`TOOL PATH/…`, `TLDATA`, `MSYS` applied as a
//! coordinate frame, `PAINT`, `LOAD/TOOL`, `END-OF-PATH`), with `$$` comments and `$`
//! continuation lines.
//!
//! Records that do not move the tool are skipped with one warning per kind (refused with
//! `strict`); a record that would change the tool path but cannot be honoured (canned
//! cycles, transformations, unknown words) is an error, never dropped.
//!
//! CL data are in workpiece coordinates with the tool axis as a vector; converting them to
//! machine axes is the 5-axis kinematics' job, so the tool axis is kept in each move.

mod circle;
mod records;

use std::collections::BTreeSet;
use std::path::Path;

use nalgebra::{Matrix3, Unit, Vector3};

pub use self::circle::CircleSense;
use self::circle::{ArcPath, Circle};
use self::records::{records, tokens, Record, Token, TokenKind};
use super::error::{display_text, ErrorSink, Found, ProgramError, ProgramErrors};
use super::options::{FeedTimeBase, LengthUnit, ReadOptions};
use super::source::LineIndex;
use super::types::{Blend, Feed, Motion, Move, Position, Program, Span, Spindle, Warning};

/// Decodes APT CL data held in memory. `source` names the program in messages.
pub fn parse_apt(
    text: impl AsRef<[u8]>,
    source: impl AsRef<Path>,
    options: &ReadOptions,
) -> Result<Program, ProgramErrors> {
    let text = text.as_ref();
    let source = source.as_ref();
    let mut reader = AptReader {
        text,
        lines: LineIndex::new(text),
        source,
        options,
        errors: ErrorSink::new(options.max_errors),
        program: Program {
            source: source.to_path_buf(),
            ..Program::default()
        },
        units: options.apt.initial_units,
        feed: None,
        rapid_next: false,
        spindle: Spindle::Off,
        tool_axis: None,
        position: Position::default(),
        finished: false,
        frame: None,
        circle: None,
        home: None,
        warned: BTreeSet::new(),
    };
    for record in records(text) {
        if reader.finished {
            break;
        }
        reader.record(&record);
    }
    if let Some((_, span)) = reader.circle.take() {
        reader.errors.push(ProgramError::new(
            source,
            Some(span),
            "expected a GOTO ending the arc of this CIRCLE, found the end of the program",
        ));
    }
    let AptReader {
        errors, program, ..
    } = reader;
    errors.finish(program)
}

/// Records that do not move the tool, passed over with one warning per kind: what each is.
const NOT_MOTION: &[(&str, &str)] = &[
    ("MACHIN", "post-processor selection"),
    ("CUTTER", "cutter description"),
    ("TLDATA", "tool data"),
    ("LOADTL", "tool change"),
    ("LOAD", "tool change"),
    ("SELECT", "tool pre-selection"),
    ("SELCTL", "tool pre-selection"),
    ("TURRET", "turret selection"),
    ("TOOLNO", "tool number"),
    ("COOLNT", "coolant"),
    (
        "CUTCOM",
        "cutter compensation, left to the controller: the CL points are followed as written",
    ),
    ("END", "program stop"),
    ("STOP", "program stop"),
    ("OPSTOP", "optional stop"),
    ("OPSKIP", "optional skip"),
    ("MULTAX", "multi-axis output switch"),
    ("TLON", "tool-on-path modifier"),
    ("TLRGT", "tool-on-path modifier"),
    ("TLLFT", "tool-on-path modifier"),
    ("NOPOST", "post-processor switch"),
    ("CLEARP", "clearance plane"),
    ("CLRSRF", "clearance surface"),
    ("PLABEL", "plot label"),
    ("DISPLY", "display"),
    ("PAINT", "display colour and speed"),
    ("SEQNO", "sequence numbering"),
    ("AUTOPS", "post-processor setting"),
    ("INTOL", "tolerance"),
    ("OUTTOL", "tolerance"),
    ("NOPS", "post-processor setting"),
    ("MODE", "machine mode"),
    ("PREFUN", "preparatory function"),
    ("AUXFUN", "auxiliary function"),
    ("OPTYPE", "operation type"),
    ("OPERATION", "operation name"),
    ("TOOL PATH", "start of an NX tool path"),
    ("END-OF-PATH", "end of an NX tool path"),
    ("CLAMP", "axis clamp"),
    ("SET", "post-processor setting"),
    ("ARCSLP", "arc output setting"),
    ("MCHTOL", "machine tolerance"),
    ("RETRCT", "retract setting"),
    ("THREAD", "threading setting"),
    ("OFSTNO", "offset register"),
    ("INDIRV", "direction for APT source geometry"),
];

/// Records that change the tool path in ways cncsim does not carry out: refused.
const PATH_CHANGING: &[(&str, &str)] = &[
    ("CYCLE", "canned cycles"),
    ("ORIGIN", "origin shifts"),
    ("TRANS", "transformations"),
    ("TRACUT", "transformations of the cutter path"),
    ("COPY", "copied path sections"),
    ("INDEX", "copied path sections"),
    ("ROTABL", "rotary table positioning"),
    ("ROTHED", "rotary head positioning"),
    ("ROTATE", "rotary positioning"),
    ("MOVARC", "arcs given by MOVARC"),
    ("HEAD", "head changes"),
];

fn lookup(table: &[(&str, &'static str)], word: &str) -> Option<&'static str> {
    table
        .iter()
        .find(|(name, _)| *name == word)
        .map(|(_, what)| *what)
}

/// Statements whose parameters are free text.
const TEXT_RECORDS: &[&str] = &[
    "PARTNO", "PPRINT", "INSERT", "CLPRNT", "TPRINT", "REMARK", "PAGE",
];

struct AptReader<'a> {
    text: &'a [u8],
    lines: LineIndex<'a>,
    source: &'a Path,
    options: &'a ReadOptions,
    errors: ErrorSink,
    program: Program,
    units: LengthUnit,
    /// Feed (m/s) set by FEDRAT.
    feed: Option<f64>,
    /// RAPID applies to the next motion record only.
    rapid_next: bool,
    spindle: Spindle,
    /// Tool axis is modal: a GOTO with three values keeps the last one.
    tool_axis: Option<[f64; 3]>,
    position: Position,
    finished: bool,
    /// MSYS: the frame the coordinates are in (rotation, origin), applied to every point.
    frame: Option<(Matrix3<f64>, Vector3<f64>)>,
    /// A CIRCLE waiting for the GOTO that ends its arc, and where it was.
    circle: Option<(Circle, Span)>,
    /// The FROM point (where GOHOME returns).
    home: Option<Position>,
    /// Kinds of skipped record already warned about.
    warned: BTreeSet<String>,
}

struct RecordError {
    start: usize,
    end: usize,
    problem: String,
    found: Option<Found>,
    hint: Option<&'static str>,
}

impl RecordError {
    fn at(token: &Token, problem: impl Into<String>) -> Self {
        RecordError {
            start: token.start,
            end: token.end,
            problem: problem.into(),
            found: None,
            hint: None,
        }
    }
}

impl<'a> AptReader<'a> {
    fn record(&mut self, record: &Record) {
        let tokens = tokens(self.text, record);
        let Some(first) = tokens.first() else {
            return;
        };
        let span = self.lines.span(first.start);
        if let Err(error) = self.statement(&tokens, span) {
            let found = error.found.unwrap_or_else(|| {
                if error.start >= error.end {
                    Found::EndOfLine
                } else {
                    Found::Text(display_text(
                        &self.text[error.start..error.end.min(self.text.len())],
                    ))
                }
            });
            let mut program_error = ProgramError::new(
                self.source,
                Some(self.lines.span(error.start)),
                error.problem,
            )
            .found(found);
            program_error.hint = error.hint.map(str::to_string);
            self.errors.push(program_error);
        }
    }

    fn statement(&mut self, tokens: &[Token], span: Span) -> Result<(), RecordError> {
        let first = &tokens[0];
        let TokenKind::Word(major) = &first.kind else {
            return Err(RecordError::at(
                first,
                "expected an APT statement word (GOTO, FEDRAT, …)",
            ));
        };
        // NX's two-word major word: `TOOL PATH/…`.
        let (major, rest) = match (major.as_str(), tokens.get(1).map(|t| &t.kind)) {
            ("TOOL", Some(TokenKind::Word(path))) if path == "PATH" => {
                ("TOOL PATH".to_string(), &tokens[2..])
            }
            _ => (major.clone(), &tokens[1..]),
        };
        if TEXT_RECORDS.contains(&major.as_str()) {
            return Ok(());
        }
        let record_end = tokens.last().map_or(first.end, |t| t.end);
        // Parameters: after '/', separated by commas.
        let mut parameters: Vec<&Token> = Vec::new();
        if let Some(second) = rest.first() {
            if second.kind != TokenKind::Slash {
                return Err(RecordError::at(
                    second,
                    format!("expected '/' or the end of the record after {major}"),
                ));
            }
            let mut expect_item = true;
            for token in &rest[1..] {
                match (&token.kind, expect_item) {
                    (TokenKind::Number(_) | TokenKind::Word(_), true) => {
                        parameters.push(token);
                        expect_item = false;
                    }
                    (TokenKind::Comma, false) => expect_item = true,
                    (_, true) => {
                        return Err(RecordError::at(
                            token,
                            format!("expected a number or word in the parameters of {major}"),
                        ))
                    }
                    (_, false) => {
                        return Err(RecordError::at(
                            token,
                            format!("expected ',' between the parameters of {major}"),
                        ))
                    }
                }
            }
            if expect_item {
                return Err(RecordError {
                    start: record_end,
                    end: record_end,
                    problem: format!(
                        "expected a parameter after '{}' in {major}",
                        if parameters.is_empty() { "/" } else { "," }
                    ),
                    found: Some(Found::EndOfLine),
                    hint: None,
                });
            }
        }
        let numbers = |count_ok: &[usize]| -> Result<Vec<f64>, RecordError> {
            let mut values = Vec::new();
            for token in &parameters {
                match token.kind {
                    TokenKind::Number(value) => values.push(value),
                    _ => {
                        return Err(RecordError::at(
                            token,
                            format!("expected a number in {major}"),
                        ))
                    }
                }
            }
            if !count_ok.contains(&values.len()) {
                let allowed: Vec<String> = count_ok.iter().map(|c| c.to_string()).collect();
                return Err(RecordError {
                    start: first.start,
                    end: record_end,
                    problem: format!(
                        "expected {} numbers after {major}/, not {}",
                        allowed.join(" or "),
                        values.len()
                    ),
                    found: None,
                    hint: None,
                });
            }
            Ok(values)
        };
        match major.as_str() {
            "UNITS" => {
                let [token] = parameters.as_slice() else {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: "expected UNITS/MM or UNITS/INCHES".into(),
                        found: None,
                        hint: None,
                    });
                };
                self.units = match &token.kind {
                    TokenKind::Word(word) if word == "MM" => LengthUnit::Millimetre,
                    TokenKind::Word(word) if word == "INCHES" || word == "INCH" => LengthUnit::Inch,
                    _ => return Err(RecordError::at(token, "expected MM or INCHES after UNITS/")),
                };
            }
            "FEDRAT" => {
                let mut value = None;
                let mut per_second = self.options.apt.feed_time_base == FeedTimeBase::PerSecond;
                for token in &parameters {
                    match &token.kind {
                        TokenKind::Number(number) if value.is_none() => {
                            value = Some((*number, *token))
                        }
                        TokenKind::Word(word)
                            if matches!(word.as_str(), "IPM" | "MMPM" | "PERMIN") =>
                        {
                            per_second = false
                        }
                        TokenKind::Word(word) if matches!(word.as_str(), "MMPS" | "IPS") => {
                            per_second = true
                        }
                        TokenKind::Word(word)
                            if matches!(word.as_str(), "IPR" | "MMPR" | "PERREV") =>
                        {
                            return Err(RecordError { hint: Some("post the feed per minute"), ..RecordError::at(token, "expected a feed per minute; feed per revolution is not supported") });
                        }
                        _ => return Err(RecordError::at(token, "expected FEDRAT/feed[,IPM|MMPM]")),
                    }
                }
                let Some((number, token)) = value else {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: "expected a feed value in FEDRAT".into(),
                        found: None,
                        hint: None,
                    });
                };
                if number <= 0.0 {
                    return Err(RecordError::at(token, "expected a positive feed in FEDRAT"));
                }
                let per_minute_factor = if per_second { 1.0 } else { 60.0 };
                self.feed = Some(self.units.to_metres(number) / per_minute_factor);
            }
            "RAPID" => self.rapid_next = true,
            "GOTO" | "GODLTA" | "FROM" => {
                let values = numbers(&[3, 6])?;
                let (rotation, origin) = self.frame_or_identity();
                let programmed = Vector3::new(
                    self.units.to_metres(values[0]),
                    self.units.to_metres(values[1]),
                    self.units.to_metres(values[2]),
                );
                let mut end = self.position;
                let target = if major == "GODLTA" {
                    Vector3::from(end.linear) + rotation * programmed
                } else {
                    rotation * programmed + origin
                };
                end.linear = [target.x, target.y, target.z];
                if values.len() == 6 {
                    let vector = [values[3], values[4], values[5]];
                    let length =
                        (vector[0] * vector[0] + vector[1] * vector[1] + vector[2] * vector[2])
                            .sqrt();
                    if length.is_nan() || length <= 1e-12 {
                        return Err(RecordError {
                            start: parameters[3].start,
                            end: parameters[5].end,
                            problem: "expected a non-zero tool-axis vector".into(),
                            found: None,
                            hint: Some("the tool-axis vector (i,j,k) must point along the tool"),
                        });
                    }
                    let unit = [vector[0] / length, vector[1] / length, vector[2] / length];
                    if (length - 1.0).abs() > 1e-6 {
                        self.program.warnings.push(Warning {
                            span,
                            message: format!(
                                "line {}: tool-axis vector ({}, {}, {}) has length {:.6}, normalised to ({:.6}, {:.6}, {:.6})",
                                span.line, vector[0], vector[1], vector[2], length, unit[0], unit[1], unit[2]
                            ),
                        });
                    }
                    let axis = rotation * Vector3::from(unit);
                    self.tool_axis = Some([axis.x, axis.y, axis.z]);
                }
                if major != "GOTO" && self.circle.is_some() {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: format!(
                            "expected a GOTO to end the arc of the CIRCLE before, not {major}"
                        ),
                        found: None,
                        hint: None,
                    });
                }
                if major == "FROM" {
                    self.home = Some(end);
                    if self.program.moves.is_empty() {
                        self.program.start = end;
                        self.position = end;
                        return Ok(());
                    }
                }
                let feed = if self.rapid_next || major == "FROM" {
                    Feed::Rapid
                } else {
                    match self.feed {
                        Some(speed) => Feed::PathSpeed(speed),
                        None => {
                            return Err(RecordError {
                                start: first.start,
                                end: record_end,
                                problem: format!(
                                    "expected a FEDRAT (or RAPID) before the first {major}"
                                ),
                                found: None,
                                hint: Some("add e.g. FEDRAT/100 before the motion records"),
                            });
                        }
                    }
                };
                self.rapid_next = false;
                match self.circle.take() {
                    None => self.push_move(Motion::Linear, end, feed, span),
                    Some((circle, _)) => {
                        let start = Vector3::from(self.position.linear);
                        let path = circle
                            .path(
                                &start,
                                &target,
                                self.options.apt.circle_sense,
                                self.options.apt.chord_tolerance,
                                self.options.apt.max_chords,
                            )
                            .map_err(|problem| RecordError {
                                start: first.start,
                                end: record_end,
                                problem,
                                found: None,
                                hint: Some("check the CIRCLE record before this GOTO"),
                            })?;
                        match path {
                            ArcPath::Plane(motion) => self.push_move(motion, end, feed, span),
                            ArcPath::Chords(points) => {
                                self.warn_once(
                                    "tilted CIRCLE",
                                    span,
                                    format!(
                                        "CIRCLE about an axis other than X, Y or Z: the arc is followed by chords within {:.4} mm of it",
                                        self.options.apt.chord_tolerance * 1e3
                                    ),
                                );
                                for point in points {
                                    let mut to = end;
                                    to.linear = [point.x, point.y, point.z];
                                    self.push_move(Motion::Linear, to, feed, span);
                                }
                            }
                        }
                    }
                }
            }
            "CIRCLE" => {
                if self.circle.is_some() {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: "expected a GOTO to end the arc of the CIRCLE before, not another CIRCLE".into(),
                        found: None,
                        hint: None,
                    });
                }
                let circle = self.circle_record(&parameters, first, record_end)?;
                self.circle = Some((circle, span));
            }
            "MSYS" => {
                let values = numbers(&[9])?;
                let x = Vector3::new(values[3], values[4], values[5]);
                let y = Vector3::new(values[6], values[7], values[8]);
                let (x_length, y_length) = (x.norm(), y.norm());
                let orthogonal = x_length > 0.0
                    && y_length > 0.0
                    && (x.dot(&y) / (x_length * y_length)).abs() <= 1e-6;
                if !orthogonal || (x_length - 1.0).abs() > 1e-4 || (y_length - 1.0).abs() > 1e-4 {
                    return Err(RecordError {
                        start: parameters[3].start,
                        end: parameters[8].end,
                        problem: "expected unit, perpendicular X and Y axis vectors in MSYS/x,y,z,xi,xj,xk,yi,yj,yk".into(),
                        found: None,
                        hint: None,
                    });
                }
                let (x, y) = (x / x_length, y / y_length);
                let z = x.cross(&y);
                let rotation = Matrix3::from_columns(&[x, y, z]);
                let origin = Vector3::new(
                    self.units.to_metres(values[0]),
                    self.units.to_metres(values[1]),
                    self.units.to_metres(values[2]),
                );
                let identity = rotation == Matrix3::identity() && origin == Vector3::zeros();
                self.frame = (!identity).then_some((rotation, origin));
                if !identity {
                    self.warn_once(
                        "MSYS",
                        span,
                        "MSYS: the coordinates that follow are in this machine coordinate system; they are transformed into the frame MSYS is given in (later MSYS records without a warning)".into(),
                    );
                }
            }
            "TLAXIS" => {
                let values = numbers(&[3])?;
                let length =
                    (values[0] * values[0] + values[1] * values[1] + values[2] * values[2]).sqrt();
                if length.is_nan() || length <= 1e-12 {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: "expected a non-zero tool-axis vector in TLAXIS/i,j,k".into(),
                        found: None,
                        hint: None,
                    });
                }
                let (rotation, _) = self.frame_or_identity();
                let axis = rotation * Vector3::new(values[0], values[1], values[2]) / length;
                self.tool_axis = Some([axis.x, axis.y, axis.z]);
            }
            "DELAY" => {
                let seconds = match parameters.as_slice() {
                    [token] => match token.kind {
                        TokenKind::Number(seconds) => seconds,
                        _ => {
                            return Err(RecordError::at(
                                token,
                                "expected DELAY/seconds or DELAY/REV,n",
                            ))
                        }
                    },
                    [word, count] if word.kind == TokenKind::Word("REV".into()) => {
                        let TokenKind::Number(revolutions) = count.kind else {
                            return Err(RecordError::at(
                                count,
                                "expected a number of revolutions after DELAY/REV,",
                            ));
                        };
                        match self.spindle {
                            Spindle::Clockwise { rpm } | Spindle::CounterClockwise { rpm }
                                if rpm > 0.0 =>
                            {
                                revolutions * 60.0 / rpm
                            }
                            _ => return Err(RecordError {
                                hint: Some(
                                    "program DELAY in seconds or start the spindle (SPINDL) first",
                                ),
                                ..RecordError::at(
                                    count,
                                    "expected a turning spindle for a delay in revolutions",
                                )
                            }),
                        }
                    }
                    _ => {
                        return Err(RecordError {
                            start: first.start,
                            end: record_end,
                            problem: "expected DELAY/seconds or DELAY/REV,n".into(),
                            found: None,
                            hint: None,
                        })
                    }
                };
                if !(0.0..=86_400.0).contains(&seconds) {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: format!("expected a delay of 0 to 86400 s, not {seconds}"),
                        found: None,
                        hint: None,
                    });
                }
                let end = self.position;
                self.push_move(Motion::Dwell { seconds }, end, Feed::Rapid, span);
            }
            "GOHOME" => {
                let Some(home) = self.home else {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: "expected a FROM point before GOHOME (it returns there)".into(),
                        found: None,
                        hint: None,
                    });
                };
                self.rapid_next = false;
                self.push_move(Motion::Linear, home, Feed::Rapid, span);
            }
            "SPINDL" => {
                let mut rpm = None;
                let mut clockwise = true;
                let mut off = false;
                for token in &parameters {
                    match &token.kind {
                        TokenKind::Number(value) if *value >= 0.0 => rpm = Some(*value),
                        TokenKind::Word(word) if word == "RPM" => {}
                        TokenKind::Word(word) if word == "CLW" || word == "ON" => clockwise = true,
                        TokenKind::Word(word) if word == "CCLW" => clockwise = false,
                        TokenKind::Word(word) if word == "OFF" => off = true,
                        _ => {
                            return Err(RecordError::at(
                                token,
                                "expected SPINDL/rpm[,CLW|CCLW] or SPINDL/ON|OFF",
                            ))
                        }
                    }
                }
                let previous_rpm = match self.spindle {
                    Spindle::Clockwise { rpm } | Spindle::CounterClockwise { rpm } => rpm,
                    Spindle::Off => 0.0,
                };
                let rpm = rpm.unwrap_or(previous_rpm);
                self.spindle = if off {
                    Spindle::Off
                } else if clockwise {
                    Spindle::Clockwise { rpm }
                } else {
                    Spindle::CounterClockwise { rpm }
                };
            }
            "FINI" => self.finished = true,
            _ => {
                if let Some(what) = lookup(NOT_MOTION, &major) {
                    if self.options.apt.strict {
                        return Err(RecordError {
                            start: first.start,
                            end: record_end,
                            problem: format!("expected a motion record; {major} ({what}) does not move the tool (refused with --strict)"),
                            found: None,
                            hint: None,
                        });
                    }
                    self.warn_once(
                        &major,
                        span,
                        format!("{major} ({what}) does not move the tool and was skipped; further ones without a warning"),
                    );
                } else if let Some(what) = lookup(PATH_CHANGING, &major) {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: format!("expected records cncsim can follow; {major} changes the tool path and {what} are not supported"),
                        found: None,
                        hint: Some("post the CL data with the path written out as GOTO (and CIRCLE) records"),
                    });
                } else {
                    return Err(RecordError {
                        start: first.start,
                        end: first.end,
                        problem: format!("expected an APT record cncsim knows; {major} is not one"),
                        found: None,
                        hint: Some("a record that may change the tool path is not skipped; remove it if it does not"),
                    });
                }
            }
        }
        Ok(())
    }

    /// One warning per `kind` of record.
    fn warn_once(&mut self, kind: &str, span: Span, message: String) {
        if self.warned.insert(kind.to_string()) {
            self.program.warnings.push(Warning { span, message });
        }
    }

    fn frame_or_identity(&self) -> (Matrix3<f64>, Vector3<f64>) {
        self.frame
            .unwrap_or_else(|| (Matrix3::identity(), Vector3::zeros()))
    }

    fn push_move(&mut self, motion: Motion, end: Position, feed: Feed, span: Span) {
        self.program.moves.push(Move {
            motion,
            end,
            tool_axis: self.tool_axis,
            feed,
            feed_rule: self.options.feed_rule,
            blend: Blend::ExactStop,
            tool_down: None,
            spindle: self.spindle,
            span,
        });
        self.position = end;
    }

    /// `CIRCLE/x,y,z,i,j,k,r[,t,f,d,e][,TIMES,n]` in the current units and frame.
    fn circle_record(
        &self,
        parameters: &[&Token],
        first: &Token,
        record_end: usize,
    ) -> Result<Circle, RecordError> {
        let mut values = Vec::new();
        let mut times = None;
        let mut index = 0;
        while index < parameters.len() {
            let token = parameters[index];
            match &token.kind {
                TokenKind::Number(value) if times.is_none() => values.push(*value),
                TokenKind::Word(word) if word == "TIMES" => {
                    let count = parameters.get(index + 1).and_then(|t| match t.kind {
                        TokenKind::Number(n) if n >= 1.0 && n.fract() == 0.0 && n <= 1e6 => {
                            Some(n as u32)
                        }
                        _ => None,
                    });
                    let Some(count) = count else {
                        return Err(RecordError::at(
                            token,
                            "expected a whole number of turns of 1 or more after TIMES",
                        ));
                    };
                    times = Some(count);
                    index += 1;
                }
                _ => {
                    return Err(RecordError::at(
                        token,
                        "expected CIRCLE/x,y,z,i,j,k,r[,tolerance,…][,TIMES,n]",
                    ))
                }
            }
            index += 1;
        }
        if values.len() < 7 {
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: format!(
                    "expected at least 7 numbers after CIRCLE/ (centre, axis, radius), not {}",
                    values.len()
                ),
                found: None,
                hint: None,
            });
        }
        let (rotation, origin) = self.frame_or_identity();
        let metres = |value: f64| self.units.to_metres(value);
        let centre = rotation
            * Vector3::new(metres(values[0]), metres(values[1]), metres(values[2]))
            + origin;
        let axis = rotation * Vector3::new(values[3], values[4], values[5]);
        let radius = metres(values[6]);
        if axis.norm() <= 1e-12 || radius <= 0.0 {
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: "expected a non-zero axis vector and a positive radius in CIRCLE".into(),
                found: None,
                hint: None,
            });
        }
        // The record's own tolerance (NX: INTOL + OUTTOL), else 0.01 mm.
        let tolerance = values
            .get(7)
            .copied()
            .filter(|t| *t > 0.0)
            .map_or(1e-5, metres);
        Ok(Circle {
            centre,
            axis: Unit::new_normalize(axis),
            radius,
            tolerance,
            turns: times.map_or(0, |n| n - 1),
        })
    }
}
