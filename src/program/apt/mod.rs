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
mod cycle;
mod nurbs;
mod records;
mod writer;

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::{Matrix3, Unit, Vector3};

pub use self::circle::CircleSense;
use self::circle::{ArcPath, Circle};
use self::cycle::{Cycle, CycleKind, HoleMove};
use self::nurbs::Spline;
use self::records::{records, tokens, Record, Token, TokenKind};
pub use self::writer::{is_ncl, ClWriter, Identification};
use super::error::{display_text, ErrorSink, Found, ProgramError, ProgramErrors};
use super::options::{FeedTimeBase, LengthUnit, ReadOptions};
use super::source::LineIndex;
use super::types::{
    Blend, Feed, Motion, Move, Position, Program, ProgramTool, Span, Spindle, Warning,
};

/// Decodes APT CL data held in memory. `source` names the program in messages.
pub fn parse_apt(
    text: impl AsRef<[u8]>,
    source: impl AsRef<Path>,
    options: &ReadOptions,
) -> Result<Program, ProgramErrors> {
    let text = text.as_ref();
    let source = source.as_ref();
    let writer = match options.apt.writer {
        Some(writer) => Identification {
            writer,
            reason: "named by the user: cl_writer, --cl-writer".into(),
        },
        None => writer::identify(text, source),
    };
    let mut reader = AptReader {
        text,
        lines: LineIndex::new(text),
        source,
        options,
        errors: ErrorSink::new(options.max_errors),
        program: Program {
            source: source.to_path_buf(),
            reading: Some(writer.describe()),
            ..Program::default()
        },
        writer,
        heading: None,
        open_arc: None,
        arc_readings: ArcReadings::default(),
        units: options.apt.initial_units,
        feed: None,
        rapid_next: false,
        spindle: Spindle::Off,
        tool_axis: None,
        position: Position::default(),
        finished: false,
        frame: None,
        circle: None,
        goto_continues: None,
        home: None,
        warned: BTreeMap::new(),
        cycle: None,
        last_cycle: None,
        nurbs: None,
        operation: None,
    };
    for record in records(text) {
        if reader.finished {
            break;
        }
        reader.record(&record);
    }
    reader.finish_nurbs();
    reader.count_skipped();
    reader.count_arcs_against_convention();
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
    ("LOADTL", "tool change"),
    ("LOAD", "tool change"),
    ("SELECT", "tool pre-selection"),
    ("SELCTL", "tool pre-selection"),
    ("TURRET", "turret selection"),
    ("TOOLNO", "tool number"),
    ("COOLNT", "coolant"),
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
    ("CSI_SET_FLUTE_LENGTH", "SolidWorks CAM tool data"),
    ("CSI_SET_EXTENSION_LENGTH", "SolidWorks CAM tool data"),
    ("SETUP", "set-up start"),
    ("CYCLE/INIT", "cycle initialisation"),
];

/// Records that change the tool path in ways cncsim does not carry out: refused.
const PATH_CHANGING: &[(&str, &str)] = &[
    ("ORIGIN", "origin shifts"),
    ("TRANS", "transformations"),
    ("TRACUT", "transformations of the cutter path"),
    ("COPY", "copied path sections"),
    ("INDEX", "copied path sections"),
    ("ROTABL", "rotary table positioning"),
    ("ROTHED", "rotary head positioning"),
    ("ROTATE", "rotary positioning"),
    ("DEFSUB", "subroutines (DEFSUB … ENDSUB, CALSUB)"),
    ("CALSUB", "subroutines (DEFSUB … ENDSUB, CALSUB)"),
];

/// Records and cycle words of lathe (turning) programs, and what each is: such a program is
/// refused as a whole, by name.
const LATHE: &[(&str, &str)] = &[
    ("HEAD", "selects a lathe's turret head"),
    ("LATHE", "sets up a lathe"),
    ("OP/THREAD", "is a threading pass on a lathe"),
    ("THREAD/TURN", "cuts a thread by turning"),
    ("CYCLE/TURN", "is a turning cycle"),
    ("CYCLE/LATHE", "is a turning cycle"),
    ("CYCLE/ROUGH", "is a lathe roughing cycle"),
    ("CYCLE/GROOVE", "is a lathe grooving cycle"),
    ("CYCLE/CUTOFF", "is a lathe parting-off cycle"),
];

/// What a CYCLE record does.
enum CycleSetting {
    Off,
    On,
    /// `CYCLE/INIT` (SolidWorks CAM, before each cycle): nothing.
    Init,
    Set(Cycle),
}

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
    /// After a GOTO: the CIRCLE its arc was on, if any. A record of bare numbers right
    /// after it is another point of it (Pro/ENGINEER writes an arc's points so).
    goto_continues: Option<Option<(Circle, Span)>>,
    /// The FROM point (where GOHOME returns).
    home: Option<Position>,
    /// Kinds of skipped record: the index of the one warning about each in the program's
    /// warnings, and how many there were.
    warned: BTreeMap<String, (usize, usize)>,
    /// The canned cycle every GOTO is a hole of, while one is on.
    cycle: Option<Cycle>,
    /// The last cycle set (CYCLE/ON turns it back on).
    last_cycle: Option<Cycle>,
    /// A NURBS being read: where it started, its knots and control points.
    nurbs: Option<NurbsRecords>,
    /// The operation and tool names of the last NX `TOOL PATH` record.
    operation: Option<(String, Option<String>)>,
    /// The CAM system the file is read as, whose conventions apply.
    writer: Identification,
    /// Unit direction of travel at the end of the last move, where known.
    heading: Option<Vector3<f64>>,
    /// The last arc, while the move leaving it may still say which way it turns.
    open_arc: Option<OpenArc>,
    /// What the tangents of the arcs said against the writer's convention.
    arc_readings: ArcReadings,
}

/// An arc read by the writer's convention because its entry move said nothing: the move that
/// leaves it may turn it round.
struct OpenArc {
    circle: Circle,
    start: Position,
    end: Position,
    feed: Feed,
    span: Span,
    /// Index of its first move in the program.
    first_move: usize,
    sense: CircleSense,
}

/// Arcs whose entry or exit move said which way they turn, and those against the writer's
/// convention.
#[derive(Default)]
struct ArcReadings {
    by_tangent: usize,
    against: usize,
    /// The warning about the first arc against the convention (its index in the warnings).
    first_against: Option<usize>,
}

/// The records of a NURBS read so far (knots as written, control points in metres in the
/// frame the moves are in, with weights).
struct NurbsRecords {
    span: Span,
    start: usize,
    end: usize,
    knots: Vec<f64>,
    points: Vec<(Vector3<f64>, f64)>,
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
        let continued = self.goto_continues.take();
        if let (TokenKind::Number(_), Some(circle)) = (&first.kind, continued) {
            // `GOTO / x1,y1,z1` then `x2,y2,z2` on the next line: a GOTO to each point, on
            // the same CIRCLE when the first was an arc (Pro/ENGINEER's points along an arc).
            self.circle = circle;
            let at = |kind| Token {
                kind,
                start: first.start,
                end: first.start,
            };
            let mut goto = vec![at(TokenKind::Word("GOTO".into())), at(TokenKind::Slash)];
            goto.extend_from_slice(tokens);
            return self.statement(&goto, span);
        }
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
        // A NURBS ends at the first record that is not one of its KNOT or CNTRL records.
        if self.nurbs.is_some() && major != "KNOT" && major != "CNTRL" {
            self.finish_nurbs();
        }
        if TEXT_RECORDS.contains(&major.as_str()) {
            return Ok(());
        }
        let record_end = tokens.last().map_or(first.end, |t| t.end);
        if major == "TOOL PATH" {
            // NX names (operation, tool) are free text: digits first, '_', '-', '.'.
            let names_start = rest
                .iter()
                .find(|t| t.kind == TokenKind::Slash)
                .map_or(record_end, |t| t.end);
            let names =
                String::from_utf8_lossy(&self.text[names_start.min(record_end)..record_end])
                    .into_owned();
            let parts: Vec<&str> = names.split(',').map(str::trim).collect();
            let operation = parts.first().map(|s| s.to_string()).unwrap_or_default();
            let tool = match parts.as_slice() {
                [_, kind, name, ..] if kind.eq_ignore_ascii_case("TOOL") => Some(name.to_string()),
                _ => None,
            };
            self.operation = Some((operation, tool));
            return self.skip_record(&major, first, record_end, span);
        }
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
            let lenient = !self.options.apt.strict;
            for token in &rest[1..] {
                let follows_number = parameters
                    .last()
                    .is_some_and(|last| matches!(last.kind, TokenKind::Number(_)));
                match (&token.kind, expect_item) {
                    (TokenKind::Number(_) | TokenKind::Word(_), true) => {
                        parameters.push(token);
                        expect_item = false;
                    }
                    // Numbers separated by blanks (`GOTO/1.0 2.0 3.0`), as hand-written CL
                    // lists have them.
                    (TokenKind::Number(_), false) if lenient && follows_number => {
                        parameters.push(token);
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
            // `NURBS/` stands alone (its data follow in KNOT and CNTRL records); SolidWorks
            // CAM and CAMWorks write `RAPID/`.
            // A comma before the end (`CUTTER/10.,0,130.,`) is passed over.
            let trailing_comma = !parameters.is_empty() && !self.options.apt.strict;
            if expect_item
                && !trailing_comma
                && !(parameters.is_empty() && matches!(major.as_str(), "NURBS" | "RAPID"))
            {
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
        let first_word = parameters.first().and_then(|token| match &token.kind {
            TokenKind::Word(word) => Some(word.as_str()),
            _ => None,
        });
        let with_word = first_word.map(|word| format!("{major}/{word}"));
        let lathe = lookup(LATHE, &major)
            .map(|what| (major.clone(), what))
            .or_else(|| {
                let name = with_word?;
                lookup(LATHE, &name).map(|what| (name, what))
            });
        if let Some((name, what)) = lathe {
            // Nothing after it can be read as milling: one error, not one per record.
            self.finished = true;
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: format!("expected a milling program; {name} {what}: this is a lathe (turning) program, which cncsim does not simulate"),
                found: None,
                hint: Some("cncsim's machines are mills; post the milling operations alone"),
            });
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
            // SolidWorks CAM writes UNIT/MM.
            "UNITS" | "UNIT" => {
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
                if self.cycle.is_some() && major == "GODLTA" {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: "expected GOTO holes while a CYCLE is on; GODLTA under a cycle is not supported".into(),
                        found: None,
                        hint: Some("end the cycle with CYCLE/OFF first"),
                    });
                }
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
                if major == "GOTO" {
                    if let Some(cycle) = self.cycle.clone() {
                        self.rapid_next = false;
                        self.goto_continues = Some(None);
                        return self.hole(&cycle, target, span, first, record_end);
                    }
                }
                let feed = if self.rapid_next || major == "FROM" {
                    Feed::Rapid
                } else {
                    match (self.feed, self.options.apt.default_feed) {
                        (Some(speed), _) => Feed::PathSpeed(speed),
                        (None, Some(speed)) => {
                            self.warn_once(
                                "default feed",
                                span,
                                format!("no FEDRAT before this {major}: the moves run at the feed given for CL data without one, {:.3} mm/s, until a FEDRAT", speed * 1e3),
                            );
                            Feed::PathSpeed(speed)
                        }
                        (None, None) => {
                            return Err(RecordError {
                                start: first.start,
                                end: record_end,
                                problem: format!(
                                    "expected a FEDRAT (or RAPID) before the first {major}"
                                ),
                                found: None,
                                hint: Some("add e.g. FEDRAT/100 before the motion records, or give the feed (feed_mm_s in [program], inspect --feed)"),
                            });
                        }
                    }
                };
                self.rapid_next = false;
                let arc = self.circle.take();
                if major == "GOTO" {
                    self.goto_continues = Some(arc);
                }
                match arc {
                    None => self.push_move(Motion::Linear, end, feed, span),
                    Some((circle, _)) => {
                        self.arc(circle, end, feed, span)
                            .map_err(|problem| RecordError {
                                start: first.start,
                                end: record_end,
                                problem,
                                found: None,
                                hint: Some("check the CIRCLE record before this GOTO"),
                            })?;
                    }
                }
            }
            "CIRCLE" | "MOVARC" => {
                if self.circle.is_some() {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: format!("expected a GOTO to end the arc of the CIRCLE before, not another {major}"),
                        found: None,
                        hint: None,
                    });
                }
                let circle = if major == "MOVARC" {
                    self.movarc_record(&parameters, first, record_end)?
                } else {
                    self.circle_record(&parameters, first, record_end)?
                };
                self.circle = Some((circle, span));
            }
            // SolidWorks CAM: `TRNTYP/WORLD,0,0,0` before each CSYS says the CSYS is given in
            // the world frame, which is how cncsim reads it; other forms are not known.
            "TRNTYP" => match parameters.as_slice() {
                [kind, rest @ ..]
                    if kind.kind == TokenKind::Word("WORLD".into())
                        && rest.iter().all(|t| t.kind == TokenKind::Number(0.0)) =>
                {
                    self.skip_record(&major, first, record_end, span)?
                }
                _ => {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: "expected TRNTYP/WORLD,0,0,0; other transformation types may move the tool path and are not supported".into(),
                        found: None,
                        hint: None,
                    })
                }
            },
            "CSYS" => {
                // `CSYS/a11,a12,a13,d1,a21,a22,a23,d2,a31,a32,a33,d3` (APT's matrix form):
                // the set-up's frame, x' = A·x + d, applied to every point and tool axis that
                // follows (a part turned over for its second side reads with the tool axis
                // up again).
                let values = numbers(&[12])?;
                let rotation = Matrix3::new(
                    values[0], values[1], values[2], values[4], values[5], values[6], values[8],
                    values[9], values[10],
                );
                let orthonormal = (rotation * rotation.transpose() - Matrix3::identity()).norm()
                    <= 1e-4
                    && rotation.determinant() > 0.0;
                if !orthonormal {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: "expected a rotation (orthonormal, right-handed) in CSYS/a11,a12,a13,d1,a21,…,a33,d3; scaling, shearing and mirroring frames are not supported".into(),
                        found: None,
                        hint: None,
                    });
                }
                self.set_frame(
                    "CSYS",
                    rotation,
                    [values[3], values[7], values[11]],
                    span,
                    "the points and tool axes that follow are carried into this set-up's frame (x' = A·x + d",
                );
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
                self.set_frame(
                    "MSYS",
                    rotation,
                    [values[0], values[1], values[2]],
                    span,
                    "the coordinates that follow are in this machine coordinate system; they are transformed into the frame MSYS is given in (x' = R·x + origin",
                );
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
            "GOHOME" if !parameters.is_empty() => {
                // NX writes the point it returns to.
                let values = numbers(&[3, 6])?;
                let (rotation, origin) = self.frame_or_identity();
                let target = rotation
                    * Vector3::new(
                        self.units.to_metres(values[0]),
                        self.units.to_metres(values[1]),
                        self.units.to_metres(values[2]),
                    )
                    + origin;
                let mut end = self.position;
                end.linear = [target.x, target.y, target.z];
                self.rapid_next = false;
                self.push_move(Motion::Linear, end, Feed::Rapid, span);
            }
            "GOHOME" => {
                let Some(home) = self.home else {
                    if self.options.apt.strict {
                        return Err(RecordError {
                            start: first.start,
                            end: record_end,
                            problem: "expected a FROM point before GOHOME (it returns there)".into(),
                            found: None,
                            hint: None,
                        });
                    }
                    // Without FROM, GOHOME goes to the machine's home (Pro/E writes it at
                    // the end), which CL data does not give: left out, said once.
                    self.rapid_next = false;
                    self.warn_once(
                        "GOHOME without FROM",
                        span,
                        "GOHOME without a FROM point returns to the machine's home, which the CL data does not give: the move is left out (refused with --strict)".into(),
                    );
                    return Ok(());
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
            "TLDATA" => self.tool_data(&parameters, first, record_end, span)?,
            "CYCLE" => match self.cycle_record(&parameters, first, record_end, span)? {
                CycleSetting::Off => self.cycle = None,
                CycleSetting::Init => self.skip_record("CYCLE/INIT", first, record_end, span)?,
                CycleSetting::On => {
                    let Some(cycle) = self.last_cycle.clone() else {
                        return Err(RecordError {
                            start: first.start,
                            end: record_end,
                            problem:
                                "expected a CYCLE record that defines the cycle before CYCLE/ON"
                                    .into(),
                            found: None,
                            hint: None,
                        });
                    };
                    self.cycle = Some(cycle);
                }
                CycleSetting::Set(cycle) => {
                    self.last_cycle = Some(cycle.clone());
                    self.cycle = Some(cycle);
                }
            },
            "NURBS" => {
                if !parameters.is_empty() {
                    return Err(RecordError::at(
                        parameters[0],
                        "expected NURBS/ with no parameters (KNOT/ and CNTRL/ records follow)",
                    ));
                }
                if self.circle.is_some() {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: "expected a GOTO to end the arc of the CIRCLE before, not NURBS"
                            .into(),
                        found: None,
                        hint: None,
                    });
                }
                self.nurbs = Some(NurbsRecords {
                    span,
                    start: first.start,
                    end: record_end,
                    knots: Vec::new(),
                    points: Vec::new(),
                });
            }
            "KNOT" | "CNTRL" => {
                let values = if major == "KNOT" {
                    let count = parameters.len().max(1);
                    numbers(&[count])?
                } else {
                    numbers(&[3, 4])?
                };
                let (rotation, origin) = self.frame_or_identity();
                let units = self.units;
                let Some(nurbs) = self.nurbs.as_mut() else {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: format!("expected NURBS/ before {major}/"),
                        found: None,
                        hint: None,
                    });
                };
                if major == "KNOT" {
                    if !nurbs.points.is_empty() {
                        return Err(RecordError {
                            start: first.start,
                            end: record_end,
                            problem:
                                "expected the KNOT records of a NURBS before its CNTRL records"
                                    .into(),
                            found: None,
                            hint: None,
                        });
                    }
                    nurbs.knots.extend(values);
                } else {
                    let point = rotation
                        * Vector3::new(
                            units.to_metres(values[0]),
                            units.to_metres(values[1]),
                            units.to_metres(values[2]),
                        )
                        + origin;
                    nurbs
                        .points
                        .push((point, values.get(3).copied().unwrap_or(1.0)));
                }
                nurbs.end = record_end;
            }
            "CUTCOM" | "TLCOMP" => {
                self.compensation(&major, &parameters, first, record_end, span)?
            }
            _ => {
                if matches!(major.as_str(), "LOAD" | "LOADTL") && self.cycle.is_some() {
                    // A tool change ends a cycle left on (posts write G80 before M6).
                    self.cycle = None;
                    self.warn_once(
                        "cycle ended by tool change",
                        span,
                        format!("{major}: a tool change with a CYCLE still on ends the cycle, as a post ends it (G80) before the change"),
                    );
                }
                if lookup(NOT_MOTION, &major).is_some() {
                    self.skip_record(&major, first, record_end, span)?;
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

    /// MSYS, CSYS: the frame (`origin` in the file's units) applied to every point, centre and
    /// axis that follows; said once per kind of record when it is not the identity.
    fn set_frame(
        &mut self,
        record: &str,
        rotation: Matrix3<f64>,
        origin: [f64; 3],
        span: Span,
        what: &str,
    ) {
        let origin = Vector3::from(origin.map(|v| self.units.to_metres(v)));
        let identity = rotation == Matrix3::identity() && origin == Vector3::zeros();
        self.frame = (!identity).then_some((rotation, origin));
        if !identity {
            self.warn_once(
                record,
                span,
                format!("{record}: {what}; later {record} records without a warning)"),
            );
        }
    }

    /// One warning per `kind` of record.
    fn warn_once(&mut self, kind: &str, span: Span, message: String) {
        if !self.warned.contains_key(kind) {
            self.warned
                .insert(kind.to_string(), (self.program.warnings.len(), 0));
            self.program.warnings.push(Warning { span, message });
        }
    }

    /// A record that does not move the tool: skipped (counted in one warning per kind), or
    /// refused with `strict`.
    fn skip_record(
        &mut self,
        major: &str,
        first: &Token,
        record_end: usize,
        span: Span,
    ) -> Result<(), RecordError> {
        let what = lookup(NOT_MOTION, major).unwrap_or("record");
        if self.options.apt.strict {
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: format!("expected a motion record; {major} ({what}) does not move the tool (refused with --strict)"),
                found: None,
                hint: None,
            });
        }
        let key = format!("skipped {major}");
        self.warn_once(
            &key,
            span,
            format!("{major} ({what}) does not move the tool and was skipped"),
        );
        if let Some((_, count)) = self.warned.get_mut(&key) {
            *count += 1;
        }
        Ok(())
    }

    /// Puts the count of each kind of skipped record into its warning.
    fn count_skipped(&mut self) {
        for (key, (index, count)) in &self.warned {
            if key.starts_with("skipped ") {
                let warning = &mut self.program.warnings[*index];
                let noun = if *count == 1 { "record" } else { "records" };
                warning.message = format!("{} ({count} {noun} in the file)", warning.message);
            }
        }
    }

    /// `TLDATA/MILL,d,r,l,taper,tip[,…]`, `TLDATA/DRILL,MILL,d,r,l,point,flute`: the tool.
    fn tool_data(
        &mut self,
        parameters: &[&Token],
        first: &Token,
        record_end: usize,
        span: Span,
    ) -> Result<(), RecordError> {
        let mut words = Vec::new();
        let mut values = Vec::new();
        for token in parameters {
            match &token.kind {
                TokenKind::Word(word) if values.is_empty() => words.push(word.clone()),
                TokenKind::Number(value) => values.push(*value),
                _ => return Err(RecordError::at(
                    token,
                    "expected TLDATA/kind,diameter,corner radius,length,… (numbers after the kind)",
                )),
            }
        }
        let Some(kind) = words.first().cloned() else {
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: "expected the tool's kind (MILL, DRILL, …) first in TLDATA".into(),
                found: None,
                hint: None,
            });
        };
        if values.len() < 3 {
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: format!(
                    "expected at least diameter, corner radius and length in TLDATA/{kind}, found {} numbers",
                    values.len()
                ),
                found: None,
                hint: None,
            });
        }
        let metres = |v: f64| self.units.to_metres(v);
        let (diameter, corner_radius, length) =
            (metres(values[0]), metres(values[1]), metres(values[2]));
        if diameter <= 0.0
            || corner_radius < 0.0
            || length < 0.0
            || 2.0 * corner_radius > diameter + 1e-12
        {
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: "expected a positive diameter, a corner radius of at most half of it and a length of 0 or more in TLDATA".into(),
                found: None,
                hint: None,
            });
        }
        let (operation, name) = match &self.operation {
            Some((operation, name)) => (Some(operation.clone()), name.clone()),
            None => (None, None),
        };
        self.program.tools.push(ProgramTool {
            operation,
            name,
            kind: words.join(","),
            diameter,
            corner_radius,
            length,
            taper_angle: values.get(3).copied().unwrap_or(0.0).to_radians(),
            tip_angle: values.get(4).copied().unwrap_or(0.0).to_radians(),
            span,
        });
        Ok(())
    }

    /// `CUTCOM/LEFT|RIGHT|ON[,plane][,register]`, `CUTCOM/OFF`; `TLCOMP/ON|OFF[,register]`.
    ///
    /// NX writes the tool's centre ("centerline data") even with compensation on: the post
    /// outputs G41/G42, and the controller offsets the path by what is in the register,
    /// which is the wear (the difference from the programmed tool). cncsim takes that as
    /// 0 mm and follows the CL points as written, and says so once. Length compensation
    /// does not move the tool tip, which CL points are.
    fn compensation(
        &mut self,
        major: &str,
        parameters: &[&Token],
        first: &Token,
        record_end: usize,
        span: Span,
    ) -> Result<(), RecordError> {
        let mut on = None;
        for token in parameters {
            match &token.kind {
                TokenKind::Word(word) => match word.as_str() {
                    "OFF" => on = Some(false),
                    "ON" => on = Some(true),
                    "LEFT" | "RIGHT" if major == "CUTCOM" => on = Some(true),
                    "XYPLAN" | "YZPLAN" | "ZXPLAN" | "ADJUST" if major == "CUTCOM" => {}
                    _ => {
                        return Err(RecordError {
                            hint: Some("CUTCOM/LEFT|RIGHT|ON|OFF[,XYPLAN][,n] and TLCOMP/ON|OFF[,n] are read"),
                            ..RecordError::at(
                                token,
                                format!("expected a compensation setting cncsim can follow in {major}; {word} is not one"),
                            )
                        })
                    }
                },
                TokenKind::Number(_) => {}
                _ => return Err(RecordError::at(token, format!("expected a word or number in {major}"))),
            }
        }
        let Some(on) = on else {
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: format!(
                    "expected ON, OFF{} in {major}",
                    if major == "CUTCOM" {
                        ", LEFT or RIGHT"
                    } else {
                        ""
                    }
                ),
                found: None,
                hint: None,
            });
        };
        if on {
            let message = if major == "CUTCOM" {
                "CUTCOM: the CL points are the tool centre's; the controller's compensation offsets them by the register's wear only, taken as 0 mm: the points are followed as written"
            } else {
                "TLCOMP: tool length compensation does not move the tool tip the CL points give: they are followed as written"
            };
            self.warn_once(major, span, message.into());
        }
        Ok(())
    }

    /// `CYCLE/…`: a cycle, or switching one off or back on.
    fn cycle_record(
        &mut self,
        parameters: &[&Token],
        first: &Token,
        record_end: usize,
        span: Span,
    ) -> Result<CycleSetting, RecordError> {
        let whole = |problem: String| RecordError {
            start: first.start,
            end: record_end,
            problem,
            found: None,
            hint: None,
        };
        let Some(head) = parameters.first() else {
            return Err(whole("expected CYCLE/DRILL,… or CYCLE/OFF".into()));
        };
        let word_of = |token: &Token| match &token.kind {
            TokenKind::Word(word) => Some(word.clone()),
            _ => None,
        };
        match word_of(head).as_deref() {
            Some("OFF" | "CLEAR") if parameters.len() == 1 => return Ok(CycleSetting::Off),
            Some("ON") if parameters.len() == 1 => return Ok(CycleSetting::On),
            Some("INIT") if parameters.len() == 1 => return Ok(CycleSetting::Init),
            _ => {}
        }
        let mut name = String::new();
        let mut kind = None;
        let mut rapid_to = None;
        let mut feed_to = None;
        let mut retract_to = None;
        let mut steps = Vec::new();
        let mut dwell = 0.0;
        let mut feed = None;
        // A tap's thread pitch (m): `TPI,n` (threads per inch) or `PITCH,p`.
        let mut pitch = None;
        // Numbers without a keyword (APT's CYCLE/DRILL,depth,IPM,f,clearance): depth first.
        let mut positional = 0;
        let number_after = |index: usize, word: &str| -> Result<f64, RecordError> {
            match parameters.get(index + 1).map(|t| &t.kind) {
                Some(TokenKind::Number(value)) => Ok(*value),
                _ => Err(RecordError::at(
                    parameters[index],
                    format!("expected a number after {word} in CYCLE"),
                )),
            }
        };
        let metres = |v: f64| self.units.to_metres(v);
        let mut index = 0;
        while index < parameters.len() {
            let token = parameters[index];
            match &token.kind {
                TokenKind::Word(word) => match word.as_str() {
                    "DRILL" | "CSINK" | "FACE" | "BORE" | "REAM" | "TAP" | "DEEP" | "DEEP2"
                    | "BRKCHP" => {
                        let this = match word.as_str() {
                            "DEEP" | "DEEP2" => CycleKind::Deep,
                            "BRKCHP" => CycleKind::BreakChip,
                            "BORE" | "REAM" | "TAP" => CycleKind::FeedOut,
                            _ => CycleKind::Drill,
                        };
                        // DRILL,DEEP: the modifier decides.
                        kind = match (kind, this) {
                            (None, k) | (Some(CycleKind::Drill), k) => Some(k),
                            (Some(k), CycleKind::Drill) => Some(k),
                            (Some(_), _) => {
                                return Err(RecordError::at(token, format!("expected one kind of cycle in CYCLE, found {word} as well")))
                            }
                        };
                        if !name.is_empty() {
                            name.push(',');
                        }
                        name.push_str(word);
                    }
                    "RAPTO" => {
                        rapid_to = Some(metres(number_after(index, word)?));
                        index += 1;
                    }
                    "FEDTO" => {
                        feed_to = Some(metres(number_after(index, word)?));
                        index += 1;
                    }
                    // Creo: DEPTH below the GOTO point and CLEAR above it.
                    "DEPTH" => {
                        feed_to = Some(-metres(number_after(index, word)?));
                        index += 1;
                    }
                    "CLEAR" => {
                        rapid_to = Some(metres(number_after(index, word)?));
                        index += 1;
                    }
                    "RTRCTO" => {
                        // RTRCTO,AUTO | RTRCTO,v[,MANUAL] | RTRCTO,MANUAL,v
                        while let Some(TokenKind::Word(w)) = parameters.get(index + 1).map(|t| &t.kind) {
                            if w == "AUTO" || w == "MANUAL" {
                                index += 1;
                            } else {
                                break;
                            }
                        }
                        if let Some(TokenKind::Number(value)) = parameters.get(index + 1).map(|t| &t.kind) {
                            retract_to = Some(metres(*value));
                            index += 1;
                        }
                    }
                    "AUTO" | "MANUAL" => {}
                    // SolidWorks CAM: DEEP's peck (INCR), DEEP2's first peck and the ones
                    // after it.
                    "INCR" => {
                        let depth = number_after(index, word)?;
                        if depth <= 0.0 {
                            return Err(RecordError::at(parameters[index + 1], "expected a positive INCR depth in CYCLE"));
                        }
                        steps = vec![metres(depth)];
                        index += 1;
                    }
                    "1STPECK" | "SUBPECK" => {
                        let depth = number_after(index, word)?;
                        if depth <= 0.0 {
                            return Err(RecordError::at(parameters[index + 1], format!("expected a positive {word} depth in CYCLE")));
                        }
                        let slot = usize::from(word == "SUBPECK");
                        if steps.len() <= slot {
                            steps.resize(slot + 1, metres(depth));
                        }
                        steps[slot] = metres(depth);
                        index += 1;
                    }
                    "STEP" => {
                        number_after(index, word)?;
                        while let Some(TokenKind::Number(value)) = parameters.get(index + 1).map(|t| &t.kind) {
                            if *value <= 0.0 {
                                return Err(RecordError::at(parameters[index + 1], "expected positive STEP depths in CYCLE"));
                            }
                            steps.push(metres(*value));
                            index += 1;
                        }
                    }
                    "DWELL" => {
                        let seconds = number_after(index, word)?;
                        if !(0.0..=86_400.0).contains(&seconds) {
                            return Err(RecordError::at(parameters[index + 1], "expected a dwell of 0 to 86400 s in CYCLE"));
                        }
                        dwell = seconds;
                        index += 1;
                    }
                    "TPI" | "PITCH" => {
                        let value = number_after(index, word)?;
                        if !(value > 0.0 && value <= 1e4) {
                            return Err(RecordError::at(parameters[index + 1], format!("expected a positive {word} in CYCLE (at most 10000)")));
                        }
                        pitch = Some(if word == "TPI" { 0.0254 / value } else { metres(value) });
                        index += 1;
                    }
                    "MMPM" | "IPM" | "MMPR" | "IPR" => {
                        let value = number_after(index, word)?;
                        if value <= 0.0 {
                            return Err(RecordError::at(parameters[index + 1], "expected a positive feed in CYCLE"));
                        }
                        let per_minute = if matches!(word.as_str(), "MMPR" | "IPR") {
                            match self.spindle {
                                Spindle::Clockwise { rpm } | Spindle::CounterClockwise { rpm } if rpm > 0.0 => value * rpm,
                                _ => {
                                    return Err(RecordError {
                                        hint: Some("start the spindle (SPINDL) before a cycle fed per revolution"),
                                        ..RecordError::at(token, "expected a turning spindle for a cycle feed per revolution")
                                    })
                                }
                            }
                        } else {
                            value
                        };
                        feed = Some(metres(per_minute) / 60.0);
                        index += 1;
                    }
                    _ => {
                        return Err(RecordError {
                            hint: Some("CYCLE/DRILL (plain, DEEP, BRKCHP), CSINK, BORE, REAM and TAP are expanded; post other cycles as GOTO records"),
                            ..RecordError::at(token, format!("expected a cycle cncsim can expand; {word} in CYCLE is not one"))
                        })
                    }
                },
                TokenKind::Number(value) => {
                    match positional {
                        0 => feed_to = Some(-metres(*value)),
                        1 => rapid_to = Some(metres(*value)),
                        _ => return Err(RecordError::at(token, "expected at most depth and clearance as plain numbers in CYCLE")),
                    }
                    positional += 1;
                }
                _ => return Err(RecordError::at(token, "expected a word or number in CYCLE")),
            }
            index += 1;
        }
        let Some(kind) = kind else {
            return Err(whole(
                "expected the kind of cycle (DRILL, DEEP, BRKCHP, BORE, …) in CYCLE".into(),
            ));
        };
        if let Some(pitch) = pitch {
            // A tap advances one pitch per spindle revolution, whatever feed is written.
            let rpm = match self.spindle {
                Spindle::Clockwise { rpm } | Spindle::CounterClockwise { rpm } if rpm > 0.0 => rpm,
                _ => {
                    return Err(RecordError {
                        hint: Some("start the spindle (SPINDL) before a tapping cycle"),
                        ..whole(format!("expected a turning spindle for CYCLE/{name} with a thread pitch: the tap feeds one pitch per revolution"))
                    })
                }
            };
            let synchronised = pitch * rpm / 60.0;
            if let Some(written) = feed {
                if (written - synchronised).abs() > 0.01 * synchronised {
                    self.warn_once(
                        "tap feed",
                        span,
                        format!(
                            "CYCLE/{name}: the written feed {:.3} mm/min is not pitch × spindle speed ({:.4} mm × {rpm} rpm = {:.3} mm/min); the tap feeds at the latter",
                            written * 60e3,
                            pitch * 1e3,
                            synchronised * 60e3
                        ),
                    );
                }
            }
            feed = Some(synchronised);
        }
        let Some(feed_to) = feed_to else {
            return Err(whole(format!("expected FEDTO (the depth) in CYCLE/{name}")));
        };
        let rapid_to = rapid_to.unwrap_or(0.0);
        let mut feed_to = feed_to;
        if feed_to > rapid_to && feed_to > 0.0 {
            // NX's distances are signed along the tool axis from the GOTO point; SolidWorks
            // CAM and CAMWorks write the depth below it as a positive FEDTO. Above RAPTO it
            // cannot be a level the drill feeds to: it is that depth.
            self.warn_once(
                "CYCLE depth",
                span,
                format!(
                    "CYCLE/{name}: FEDTO {:.4} mm lies above RAPTO {:.4} mm, so it is read as a depth below the hole's GOTO point, as SolidWorks CAM and CAMWorks write it (NX writes it signed: FEDTO,-depth)",
                    feed_to * 1e3,
                    rapid_to * 1e3
                ),
            );
            feed_to = -feed_to;
        }
        if feed_to > rapid_to {
            return Err(whole(format!(
                "expected FEDTO ({:.4} mm) below RAPTO ({:.4} mm) along the tool axis in CYCLE/{name}",
                feed_to * 1e3,
                rapid_to * 1e3
            )));
        }
        Ok(CycleSetting::Set(Cycle {
            name,
            kind,
            rapid_to,
            feed_to,
            retract_to,
            steps,
            dwell,
            feed,
        }))
    }

    /// A GOTO under a cycle: the hole at `point`.
    fn hole(
        &mut self,
        cycle: &Cycle,
        point: Vector3<f64>,
        span: Span,
        first: &Token,
        record_end: usize,
    ) -> Result<(), RecordError> {
        let (rotation, _) = self.frame_or_identity();
        let axis = match self.tool_axis {
            Some(axis) => Vector3::from(axis),
            None => rotation * Vector3::z(),
        };
        let Some(feed) = cycle.feed.or(self.feed) else {
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: format!("expected a feed (in the CYCLE or a FEDRAT before it) for the holes of CYCLE/{}", cycle.name),
                found: None,
                hint: None,
            });
        };
        if cycle.pecks() > cycle::MAX_PECKS {
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: format!(
                    "expected at most {} pecks per hole; CYCLE/{} with its STEP needs {}",
                    cycle::MAX_PECKS,
                    cycle.name,
                    cycle.pecks()
                ),
                found: None,
                hint: Some("give a larger STEP"),
            });
        }
        let mut note = format!(
            "CYCLE/{}: each GOTO is a hole, expanded as NX's standard post does (rapid to RAPTO, feed to FEDTO, back to the retract point)",
            cycle.name
        );
        if matches!(cycle.kind, CycleKind::Deep | CycleKind::BreakChip) {
            if cycle.steps.is_empty() {
                note.push_str("; no STEP given: drilled in one peck");
            } else {
                note.push_str(&format!(
                    "; pecks of STEP, {:.3} mm peck clearance",
                    cycle::PECK_CLEARANCE * 1e3
                ));
            }
        }
        self.warn_once(&format!("cycle {}", cycle.name), span, note);
        let from = Vector3::from(self.position.linear);
        for step in cycle.hole(from, point, axis) {
            let mut end = self.position;
            match step {
                HoleMove::Rapid(p) => {
                    end.linear = [p.x, p.y, p.z];
                    self.push_move(Motion::Linear, end, Feed::Rapid, span);
                }
                HoleMove::Feed(p) => {
                    end.linear = [p.x, p.y, p.z];
                    self.push_move(Motion::Linear, end, Feed::PathSpeed(feed), span);
                }
                HoleMove::Dwell(seconds) => {
                    self.push_move(Motion::Dwell { seconds }, end, Feed::Rapid, span)
                }
            }
        }
        Ok(())
    }

    /// The NURBS read so far becomes chords from the tool's position (errors reported at
    /// the NURBS record).
    fn finish_nurbs(&mut self) {
        let Some(nurbs) = self.nurbs.take() else {
            return;
        };
        let start = Vector3::from(self.position.linear);
        let tolerance = self.options.apt.chord_tolerance;
        let result = Spline::new(start, &nurbs.knots, &nurbs.points)
            .and_then(|spline| spline.chords(tolerance, self.options.apt.max_chords));
        let feed = if self.rapid_next {
            Some(Feed::Rapid)
        } else {
            self.feed.map(Feed::PathSpeed)
        };
        match (result, feed) {
            (Ok(points), Some(feed)) => {
                self.rapid_next = false;
                self.warn_once(
                    "NURBS",
                    nurbs.span,
                    format!(
                        "NURBS: the B-spline is followed by chords within {:.4} mm of it",
                        tolerance * 1e3
                    ),
                );
                for point in points {
                    let mut to = self.position;
                    to.linear = [point.x, point.y, point.z];
                    self.push_move(Motion::Linear, to, feed, nurbs.span);
                }
            }
            (Err(problem), _) => self.errors.push(
                ProgramError::new(self.source, Some(nurbs.span), problem)
                    .found_text(&self.text[nurbs.start..nurbs.end.min(self.text.len())]),
            ),
            (Ok(_), None) => self.errors.push(
                ProgramError::new(
                    self.source,
                    Some(nurbs.span),
                    "expected a FEDRAT (or RAPID) before the first NURBS",
                )
                .found_text(&self.text[nurbs.start..nurbs.end.min(self.text.len())]),
            ),
        }
    }

    fn frame_or_identity(&self) -> (Matrix3<f64>, Vector3<f64>) {
        self.frame
            .unwrap_or_else(|| (Matrix3::identity(), Vector3::zeros()))
    }

    fn push_move(&mut self, motion: Motion, end: Position, feed: Feed, span: Span) {
        match motion {
            // A dwell leaves the tool where the arc ended.
            Motion::Dwell { .. } => {}
            Motion::Linear => {
                let direction = Vector3::from(end.linear) - Vector3::from(self.position.linear);
                if let Some(arc) = self.open_arc.take() {
                    self.reconsider(arc, &direction);
                }
                if direction.norm() > 1e-12 {
                    self.heading = Some(direction.normalize());
                }
            }
            _ => self.open_arc = None,
        }
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

    /// The arc of `circle` from the tool to `end`, turned the way its entry move runs along
    /// it, else the writer's way (until the move leaving it says otherwise: see
    /// [`AptReader::reconsider`]). A way the record names itself is not second-guessed.
    fn arc(&mut self, circle: Circle, end: Position, feed: Feed, span: Span) -> Result<(), String> {
        // An arc leaving an arc says nothing of the first's way round: its own may be unknown.
        self.open_arc = None;
        let start = self.position;
        let convention = self.writer.writer.circle_sense();
        let by_entry = match (circle.sense, self.heading) {
            (None, Some(heading)) => circle.tangent_sense(&Vector3::from(start.linear), &heading),
            _ => None,
        };
        let sense = circle.sense.or(by_entry).unwrap_or(convention);
        let first_move = self.program.moves.len();
        self.arc_moves(&circle, end, feed, span, sense)?;
        if circle.sense.is_none() {
            match by_entry {
                Some(sense) => self.tally_tangent_reading(sense, span, "entry"),
                None => {
                    // The way it leaves may be the other: not a heading to read the next
                    // arc by.
                    self.heading = None;
                    self.open_arc = Some(OpenArc {
                        circle,
                        start,
                        end,
                        feed,
                        span,
                        first_move,
                        sense,
                    })
                }
            }
        }
        Ok(())
    }

    /// The moves of the arc of `circle` from the tool to `end` going round the `sense` way.
    fn arc_moves(
        &mut self,
        circle: &Circle,
        end: Position,
        feed: Feed,
        span: Span,
        sense: CircleSense,
    ) -> Result<(), String> {
        let target = Vector3::from(end.linear);
        let path = circle.path(
            &Vector3::from(self.position.linear),
            &target,
            sense,
            self.options.apt.chord_tolerance,
            self.options.apt.max_chords,
        )?;
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
        self.heading = circle.tangent(&target, sense);
        Ok(())
    }

    /// The move leaving an arc whose entry said nothing: where it runs along the arc the
    /// other way than the arc was read, the arc is read again that way.
    fn reconsider(&mut self, arc: OpenArc, direction: &Vector3<f64>) {
        let Some(sense) = arc
            .circle
            .tangent_sense(&Vector3::from(arc.end.linear), direction)
        else {
            return;
        };
        if sense != arc.sense {
            let moves = self.program.moves.split_off(arc.first_move);
            let position = std::mem::replace(&mut self.position, arc.start);
            if self
                .arc_moves(&arc.circle, arc.end, arc.feed, arc.span, sense)
                .is_err()
            {
                // The other way cannot be followed (too many chords): the reading stays.
                self.program.moves.truncate(arc.first_move);
                self.program.moves.extend(moves);
                self.position = position;
                return;
            }
        }
        self.tally_tangent_reading(sense, arc.span, "exit");
    }

    /// Counts an arc whose entry or exit move said which way it turns; warns at the first
    /// that turns against the writer's convention.
    fn tally_tangent_reading(&mut self, sense: CircleSense, span: Span, which: &str) {
        self.arc_readings.by_tangent += 1;
        if sense == self.writer.writer.circle_sense() {
            return;
        }
        self.arc_readings.against += 1;
        if self.arc_readings.first_against.is_none() {
            self.arc_readings.first_against = Some(self.program.warnings.len());
            let way = match sense {
                CircleSense::ClockwiseAboutAxis => "clockwise",
                CircleSense::CounterClockwiseAboutAxis => "counter-clockwise",
            };
            self.program.warnings.push(Warning {
                span,
                message: format!(
                    "the arc ending here turns {way} about its CIRCLE's axis, as its {which} move runs along it, against the convention of {}: read as its {which} move says",
                    self.writer.writer.title()
                ),
            });
        }
    }

    /// Puts the count of arcs against the writer's convention into the first one's warning,
    /// and says once when most arcs are.
    fn count_arcs_against_convention(&mut self) {
        let ArcReadings {
            by_tangent,
            against,
            first_against,
        } = self.arc_readings;
        let Some(index) = first_against else {
            return;
        };
        let warning = &mut self.program.warnings[index];
        warning.message = format!(
            "{} ({against} of the {by_tangent} arcs whose entry or exit move runs along them turn against it)",
            warning.message
        );
        if 2 * against > by_tangent {
            let span = warning.span;
            self.program.warnings.push(Warning {
                span,
                message: format!(
                    "{against} of the {by_tangent} arcs whose entry or exit runs along them turn against the convention of {} ({}): the file is likely written by another CAM system; those arcs were read as their moves say, the others by that convention; name the writer with cl_writer in [program] or inspect --cl-writer ({})",
                    self.writer.writer.title(),
                    self.writer.reason,
                    ClWriter::names()
                ),
            });
        }
    }

    /// `MOVARC/x,y,z,i,j,k,r[,ANGLE,degrees]` (Autodesk's APT post): the arc of a CIRCLE
    /// through the angle given (more than 360°: whole turns besides).
    fn movarc_record(
        &self,
        parameters: &[&Token],
        first: &Token,
        record_end: usize,
    ) -> Result<Circle, RecordError> {
        let angle_at = parameters
            .iter()
            .position(|token| token.kind == TokenKind::Word("ANGLE".into()));
        let circle_part = &parameters[..angle_at.unwrap_or(parameters.len())];
        if circle_part.len() != 7 {
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: format!(
                    "expected MOVARC/x,y,z,i,j,k,r[,ANGLE,degrees]: 7 numbers before ANGLE, not {}",
                    circle_part.len()
                ),
                found: None,
                hint: None,
            });
        }
        let mut circle = self.circle_record(circle_part, first, record_end)?;
        if let Some(at) = angle_at {
            let degrees = match parameters.get(at + 1).map(|t| &t.kind) {
                Some(TokenKind::Number(value)) if value.abs() <= 360.0 * 1e6 => value.abs(),
                _ => {
                    return Err(RecordError::at(
                        parameters[at],
                        "expected the arc's angle in degrees after ANGLE in MOVARC",
                    ))
                }
            };
            circle.turns = ((degrees / 360.0) - 1e-9).floor().max(0.0) as u32;
        }
        Ok(circle)
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
        let mut sense = None;
        let mut index = 0;
        while index < parameters.len() {
            let token = parameters[index];
            match &token.kind {
                TokenKind::Number(value) if times.is_none() => values.push(*value),
                // CAMWorks names the direction, about the axis vector.
                TokenKind::Word(word)
                    if matches!(
                        word.as_str(),
                        "CLW" | "CLOCKWISE" | "CCLW" | "COUNTERCLOCKWISE"
                    ) =>
                {
                    sense = Some(if matches!(word.as_str(), "CLW" | "CLOCKWISE") {
                        CircleSense::ClockwiseAboutAxis
                    } else {
                        CircleSense::CounterClockwiseAboutAxis
                    });
                }
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
        if values.len() < 6 {
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: format!(
                    "expected at least 6 numbers after CIRCLE/ (centre, axis[, radius]), not {}",
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
        let radius = match values.get(6) {
            Some(&radius) => metres(radius),
            // SolidWorks CAM leaves the radius out: the arc starts at the tool, so it is the
            // tool's distance from the axis; the tool goes round counter-clockwise about the
            // axis vector, as APT defines CIRCLE (NX's records carry a radius).
            None => {
                sense = sense.or(Some(CircleSense::CounterClockwiseAboutAxis));
                let from_centre = Vector3::from(self.position.linear) - centre;
                let along = axis.normalize() * from_centre.dot(&axis.normalize());
                let radius = (from_centre - along).norm();
                if axis.norm() > 1e-12 && (radius.is_nan() || radius <= 0.0) {
                    return Err(RecordError {
                        start: first.start,
                        end: record_end,
                        problem: "expected the tool off the axis of a CIRCLE without a radius (the radius is the tool's distance from the axis), but it is on it".into(),
                        found: None,
                        hint: None,
                    });
                }
                radius
            }
        };
        if axis.norm() <= 1e-12 || radius <= 0.0 {
            return Err(RecordError {
                start: first.start,
                end: record_end,
                problem: "expected a non-zero axis vector and a positive radius in CIRCLE".into(),
                found: None,
                hint: None,
            });
        }
        // The record's own tolerance (NX: INTOL + OUTTOL), else 0.01 mm. CAMplete writes the
        // arc's sweep angle there instead.
        let tolerance = values
            .get(7)
            .copied()
            .filter(|_| self.writer.writer != ClWriter::Camplete)
            .filter(|t| *t > 0.0)
            .map_or(1e-5, metres);
        Ok(Circle {
            centre,
            axis: Unit::new_normalize(axis),
            radius,
            tolerance,
            turns: times.map_or(0, |n| n - 1),
            sense,
        })
    }
}
