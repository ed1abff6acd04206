//! APT cutter-location (CL) data: `UNITS`, `FEDRAT`, `GOTO/x,y,z[,i,j,k]`, `GODLTA`, `FROM`,
//! `RAPID`, `SPINDL`, `FINI`, with `$$` comments and `$` continuation lines.
//!
//! CL data are in workpiece coordinates with the tool axis as a vector; converting them to
//! machine axes is the 5-axis kinematics' job, so the tool axis is kept in each move.

use std::path::Path;

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
    };
    for record in records(text) {
        if reader.finished {
            break;
        }
        reader.record(&record);
    }
    let AptReader {
        errors, program, ..
    } = reader;
    errors.finish(program)
}

/// One logical record: the byte ranges of its physical line pieces, comments and
/// continuation marks removed.
#[derive(Debug, Default)]
struct Record {
    pieces: Vec<(usize, usize)>,
}

/// Splits the text into records: `$$` starts a comment to the end of the line, a single `$`
/// ending a line's content continues the record on the next line.
fn records(text: &[u8]) -> Vec<Record> {
    let mut records = Vec::new();
    let mut current = Record::default();
    let mut line_start = 0;
    while line_start < text.len() {
        let line_end = text[line_start..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(text.len(), |i| line_start + i);
        // Content ends at a `$$` comment.
        let mut content_end = line_end;
        let mut index = line_start;
        while index + 1 < line_end {
            if text[index] == b'$' && text[index + 1] == b'$' {
                content_end = index;
                break;
            }
            index += 1;
        }
        // Trailing blanks (and a CR) do not count.
        while content_end > line_start && text[content_end - 1].is_ascii_whitespace() {
            content_end -= 1;
        }
        let continued = content_end > line_start && text[content_end - 1] == b'$';
        if continued {
            content_end -= 1;
        }
        if content_end > line_start {
            current.pieces.push((line_start, content_end));
        }
        if !continued && !current.pieces.is_empty() {
            records.push(std::mem::take(&mut current));
        }
        line_start = line_end + 1;
    }
    if !current.pieces.is_empty() {
        records.push(current);
    }
    records
}

#[derive(Debug, Clone, PartialEq)]
enum TokenKind {
    Word(String),
    Number(f64),
    Slash,
    Comma,
    Other,
}

#[derive(Debug, Clone)]
struct Token {
    kind: TokenKind,
    start: usize,
    end: usize,
}

/// Tokenises a record; words are upper-cased.
fn tokens(text: &[u8], record: &Record) -> Vec<Token> {
    let mut tokens = Vec::new();
    for &(start, end) in &record.pieces {
        let mut at = start;
        while at < end {
            let byte = text[at];
            let token_start = at;
            let kind = match byte {
                b' ' | b'\t' | b'\r' => {
                    at += 1;
                    continue;
                }
                b'/' => {
                    at += 1;
                    TokenKind::Slash
                }
                b',' => {
                    at += 1;
                    TokenKind::Comma
                }
                b'0'..=b'9' | b'+' | b'-' | b'.' => match scan_number(text, at, end) {
                    Some((value, next)) => {
                        at = next;
                        TokenKind::Number(value)
                    }
                    None => {
                        at += 1;
                        TokenKind::Other
                    }
                },
                _ if byte.is_ascii_alphabetic() => {
                    while at < end && (text[at].is_ascii_alphanumeric() || text[at] == b'_') {
                        at += 1;
                    }
                    TokenKind::Word(
                        String::from_utf8_lossy(&text[token_start..at]).to_ascii_uppercase(),
                    )
                }
                _ => {
                    at += 1;
                    while at < end && (text[at] & 0xC0) == 0x80 {
                        at += 1;
                    }
                    TokenKind::Other
                }
            };
            tokens.push(Token {
                kind,
                start: token_start,
                end: at,
            });
        }
    }
    tokens
}

/// A number with optional sign, point and exponent (`1.5E-3`), within `start..end`.
fn scan_number(text: &[u8], start: usize, end: usize) -> Option<(f64, usize)> {
    let mut at = start;
    if at < end && matches!(text[at], b'+' | b'-') {
        at += 1;
    }
    let mut digits = 0;
    let mut point = false;
    while at < end {
        match text[at] {
            b'0'..=b'9' => digits += 1,
            b'.' if !point => point = true,
            _ => break,
        }
        at += 1;
    }
    if digits == 0 {
        return None;
    }
    if at < end && matches!(text[at], b'e' | b'E') {
        let mut exponent_end = at + 1;
        if exponent_end < end && matches!(text[exponent_end], b'+' | b'-') {
            exponent_end += 1;
        }
        let digits_start = exponent_end;
        while exponent_end < end && text[exponent_end].is_ascii_digit() {
            exponent_end += 1;
        }
        if exponent_end > digits_start {
            at = exponent_end;
        }
    }
    let value: f64 = std::str::from_utf8(&text[start..at]).ok()?.parse().ok()?;
    // Far beyond any machine; keeps every later sum finite.
    (value.abs() <= 1e9).then_some((value, at))
}

/// Statements that carry no motion or free text and are passed over without comment.
const IGNORED: &[&str] = &[
    "MACHIN", "CUTTER", "LOADTL", "COOLNT", "END", "STOP", "OPSTOP", "TLAXIS", "MULTAX", "CIRCLE",
    "SELCTL", "TLON", "TLRGT", "TLLFT", "NOPOST", "CLEARP", "PLABEL", "DISPLY", "SEQNO", "OPSKIP",
    "TOOLNO", "ORIGIN", "AUTOPS", "INTOL", "OUTTOL", "NOPS",
];

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
        let major = major.clone();
        if TEXT_RECORDS.contains(&major.as_str()) {
            return Ok(());
        }
        let record_end = tokens.last().map_or(first.end, |t| t.end);
        // Parameters: after '/', separated by commas.
        let mut parameters: Vec<&Token> = Vec::new();
        if let Some(second) = tokens.get(1) {
            if second.kind != TokenKind::Slash {
                return Err(RecordError::at(
                    second,
                    format!("expected '/' or the end of the record after {major}"),
                ));
            }
            let mut expect_item = true;
            for token in &tokens[2..] {
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
                let mut end = self.position;
                for (coordinate, &value) in end.linear.iter_mut().zip(&values[..3]) {
                    let value = self.units.to_metres(value);
                    *coordinate = if major == "GODLTA" {
                        *coordinate + value
                    } else {
                        value
                    };
                }
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
                    self.tool_axis = Some(unit);
                }
                if major == "FROM" && self.program.moves.is_empty() {
                    self.program.start = end;
                    self.position = end;
                    return Ok(());
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
                self.program.moves.push(Move {
                    motion: Motion::Linear,
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
            _ if IGNORED.contains(&major.as_str()) => {}
            _ => self.program.warnings.push(Warning {
                span,
                message: format!(
                    "line {}: APT statement {major} is not used by cncsim and was ignored",
                    span.line
                ),
            }),
        }
        Ok(())
    }
}
