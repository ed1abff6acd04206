//! Part programs: the one representation every front end produces ([`types`]), the front
//! ends, the geometry of the programmed path, and the reference paths of the source documents
//! that a scenario can name directly.
//!
//! Front ends: G-code (RS274/NGC as LinuxCNC reads it), HPGL (HP-GL/1 as
//! AutoCAD writes it for an HP 7475) and APT cutter-location data, all decoded into the one
//! [`Program`] representation that the planner consumes (SI units, see [`types`]).
//!
//! Each reader is a real parser with modal state and source positions. Errors name the file,
//! line, column, offending text, what was expected and a hint; a file's recoverable errors
//! are reported together ([`ProgramErrors`]). No input makes a reader panic or hang.

mod apt;
mod error;
mod gcode;
mod geometry;
mod hpgl;
mod options;
mod reference;
mod report;
mod source;
pub mod types;

#[cfg(test)]
mod tests;

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

pub use self::apt::{parse_apt, CircleSense, ClWriter, Identification};
pub use self::error::{display_text, Found, ProgramError, ProgramErrors};
pub use self::gcode::{parse_gcode, parse_gcode_reader, parse_tool_table};
pub use self::geometry::{arc_segment, PathGeometry, Segment};
pub use self::hpgl::{parse_hpgl, parse_hpgl_detailed, HpglOutput};
pub use self::options::{
    AptOptions, ArcTolerance, FeedTimeBase, GcodeOptions, HpglOptions, LengthUnit, ReadOptions,
    ToolSpec,
};
pub use self::reference::{circle, polyline, CircleSpec, PolylineSpec};
pub use self::report::{
    arc_sweep, inspect_report, is_rapid, move_duration, move_length, plane_axes,
    rotary_travel_degrees, summarize, InspectOptions, PenUpTravel, ProgramSummary,
};
pub use self::types::{
    Blend, Feed, FeedRule, Motion, Move, Plane, Position, Program, ProgramTool, Span, Spindle,
    Warning,
};

/// The languages cncsim reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgramFormat {
    /// G-code (RS274/NGC as LinuxCNC reads it).
    Gcode,
    /// HP-GL/1 plot files.
    Hpgl,
    /// APT cutter-location data.
    Apt,
}

impl ProgramFormat {
    /// The format a file name's extension stands for (case-insensitive): `.ngc .nc .gcode
    /// .tap` G-code, `.plt .hpgl .hpg .hgl .hp .hp2 .pl2 .prn` HPGL, `.apt .cl .cls .clsf
    /// .ncl` (and Creo's numbered `.ncl.N`) APT CL data.
    pub fn from_path(path: &Path) -> Option<ProgramFormat> {
        if apt::is_ncl(path) {
            return Some(ProgramFormat::Apt);
        }
        let extension = path.extension()?.to_str()?.to_ascii_lowercase();
        match extension.as_str() {
            "ngc" | "nc" | "gcode" | "tap" => Some(ProgramFormat::Gcode),
            "plt" | "hpgl" | "hpg" | "hgl" | "hp" | "hp2" | "pl2" | "prn" => {
                Some(ProgramFormat::Hpgl)
            }
            "apt" | "cl" | "cls" | "clsf" | "ncl" => Some(ProgramFormat::Apt),
            _ => None,
        }
    }

    /// The format the first bytes of a file are unmistakably in: a plot file (an HP-GL
    /// command, an escape sequence, PJL) or CL data (an APT statement word and '/' with or
    /// without blanks around it, `PARTNO` with its name after a blank, or GOTO records).
    /// `None` when they could be either or neither.
    pub fn from_content(head: &[u8]) -> Option<ProgramFormat> {
        let text = String::from_utf8_lossy(head);
        // CL data: the first statement is an APT word, or GOTO records come early.
        let mut lines = text
            .lines()
            .map(str::trim)
            .filter(|line| !line.is_empty() && !line.starts_with("$$"));
        if let Some(line) = lines.next() {
            let upper = line.to_ascii_uppercase();
            let word: String = upper
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '-' || *c == ' ')
                .collect();
            let word = word.trim();
            let rest = &upper[word.len()..].trim_start();
            const APT_WORDS: &[&str] = &[
                "TOOL PATH",
                "PARTNO",
                "UNITS",
                "MACHIN",
                "CUTTER",
                "TLDATA",
                "MSYS",
                "FROM",
                "GOTO",
                "FEDRAT",
                "SPINDL",
                "LOADTL",
                "CLPRNT",
                "PPRINT",
                "REMARK",
                "MULTAX",
                "COOLNT",
                "PAINT",
                "NOPOST",
                "INTOL",
                "OUTTOL",
                "TLAXIS",
            ];
            if APT_WORDS.contains(&word) && (rest.is_empty() || rest.starts_with('/')) {
                return Some(ProgramFormat::Apt);
            }
            // `PARTNO name`: APT's part name, which some writers give without a slash.
            let mut words = upper.split_whitespace();
            if words.next() == Some("PARTNO") && words.next().is_some() {
                return Some(ProgramFormat::Apt);
            }
        }
        // `GOTO/x` or `GOTO / x`.
        let is_goto = |line: &str| {
            let upper = line.trim_start().to_ascii_uppercase();
            upper
                .strip_prefix("GOTO")
                .is_some_and(|rest| rest.trim_start().starts_with('/'))
        };
        if text.lines().any(is_goto) {
            return Some(ProgramFormat::Apt);
        }
        // Plot files: past leading blanks and control characters, an escape, PJL, or an
        // HP-GL command that opens plots.
        let start = head
            .iter()
            .position(|&b| b == 0x1b || !(b.is_ascii_whitespace() || b < 0x20))?;
        let rest = &head[start..];
        if rest[0] == 0x1b || rest.starts_with(b"@PJL") {
            return Some(ProgramFormat::Hpgl);
        }
        let upper: Vec<u8> = rest.iter().take(3).map(u8::to_ascii_uppercase).collect();
        if upper.len() < 2 || !upper[0].is_ascii_alphabetic() || !upper[1].is_ascii_alphabetic() {
            return None;
        }
        const OPENERS: &[&[u8]] = &[
            b"IN", b"DF", b"BP", b"SP", b"PU", b"PD", b"PA", b"PR", b"IP", b"SC", b"CO", b"PS",
            b"RO", b"VS", b"PW", b"NP", b"IW", b"LT", b"WU", b"PC", b"PG", b"PT", b"SI", b"DT",
        ];
        if !OPENERS.contains(&&upper[..2]) {
            return None;
        }
        // What follows the mnemonic: parameters, a terminator, or (for commands that take
        // none) the next command's letters.
        match upper.get(2) {
            None => Some(ProgramFormat::Hpgl),
            Some(b';' | b',' | b'-' | b'+' | b'.' | b'"' | b'0'..=b'9') => {
                Some(ProgramFormat::Hpgl)
            }
            Some(b) if b.is_ascii_whitespace() => Some(ProgramFormat::Hpgl),
            Some(b)
                if b.is_ascii_alphabetic()
                    && matches!(&upper[..2], b"IN" | b"DF" | b"BP" | b"PU" | b"PD") =>
            {
                Some(ProgramFormat::Hpgl)
            }
            _ => None,
        }
    }

    /// G-code by its look: a first line that starts with '%', '(', ';' or a G-code word.
    fn looks_like_gcode(head: &[u8]) -> bool {
        let text = String::from_utf8_lossy(head);
        let Some(line) = text.lines().map(str::trim).find(|line| !line.is_empty()) else {
            return false;
        };
        let mut chars = line.chars();
        match chars.next().map(|c| c.to_ascii_uppercase()) {
            Some('%' | '(' | ';') => true,
            Some('G' | 'M' | 'N' | 'O' | 'T' | 'F' | 'S' | 'X' | 'Y' | 'Z') => {
                chars.next().is_some_and(|c| {
                    c.is_ascii_digit() || matches!(c, ' ' | '-' | '+' | '.' | '#' | '[')
                })
            }
            _ => false,
        }
    }
}

/// A program read from a file, with the extra figures of its language.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadOutcome {
    /// The language the file was read as.
    pub format: ProgramFormat,
    /// The decoded program.
    pub program: Program,
    /// Pen-up travel before and after optimisation (HPGL with `optimise_pen_up` only).
    pub pen_up: Option<PenUpTravel>,
}

/// Reads a part program, choosing the reader by the file's extension.
pub fn read_program(path: &Path, options: &ReadOptions) -> Result<Program, ProgramErrors> {
    read_program_detailed(path, options).map(|outcome| outcome.program)
}

/// Like [`read_program`], also telling the format and (HPGL) the pen-up travel figures.
pub fn read_program_detailed(
    path: &Path,
    options: &ReadOptions,
) -> Result<ReadOutcome, ProgramErrors> {
    let open_error = |error: std::io::Error| {
        ProgramErrors::single(ProgramError::new(
            path,
            None,
            format!("could not read the program: {error}"),
        ))
    };
    // Recognised by content first (plot drivers write .prn, .hp, .000 …; CL data comes as
    // .txt or .clsf), by extension where the content could be either.
    let head = {
        use std::io::Read;
        let mut head = Vec::new();
        File::open(path)
            .map_err(open_error)?
            .take(8192)
            .read_to_end(&mut head)
            .map_err(open_error)?;
        head
    };
    let by_extension = ProgramFormat::from_path(path);
    let format = ProgramFormat::from_content(&head)
        .or(by_extension)
        .or_else(|| ProgramFormat::looks_like_gcode(&head).then_some(ProgramFormat::Gcode));
    let Some(format) = format else {
        let extension = path.extension().map(|e| e.to_string_lossy().into_owned());
        let problem = match extension {
            Some(extension) => format!("expected a part program (G-code, HPGL or APT CL data); the content is none of them and '.{extension}' names none"),
            None => "expected a part program (G-code, HPGL or APT CL data); the content is none of them and the file name has no extension".to_string(),
        };
        return Err(ProgramErrors::single(ProgramError::new(path, None, problem).hint(
            "use .ngc .nc .gcode .tap (G-code), .plt .hpgl .hpg .hgl .hp .prn (HPGL) or .apt .cl .cls .clsf .ncl (APT CL data)",
        )));
    };
    if options.apt.default_feed.is_some() && format != ProgramFormat::Apt {
        return Err(ProgramErrors::single(ProgramError::new(
            path,
            None,
            format!("expected CL data with the feed given for moves before any FEDRAT ([program] feed_mm_s, inspect --feed); this file is {}, which programs its own feed", match format {
                ProgramFormat::Gcode => "G-code",
                ProgramFormat::Hpgl => "HPGL",
                ProgramFormat::Apt => "CL data",
            }),
        )));
    }
    match format {
        ProgramFormat::Gcode => {
            // Streamed line by line: memory follows the moves kept, not the file size.
            let file = File::open(path).map_err(open_error)?;
            let program = parse_gcode_reader(BufReader::new(file), path, options)?;
            Ok(ReadOutcome {
                format,
                program,
                pen_up: None,
            })
        }
        ProgramFormat::Hpgl => {
            let text = std::fs::read(path).map_err(open_error)?;
            let mut output = parse_hpgl_detailed(&text, path, options)?;
            output.program.shift(options.work_offset);
            Ok(ReadOutcome {
                format,
                program: output.program,
                // Before/after figures mean something only when strokes were reordered.
                pen_up: options.hpgl.optimise_pen_up.then_some(output.pen_up),
            })
        }
        ProgramFormat::Apt => {
            let text = std::fs::read(path).map_err(open_error)?;
            let mut program = parse_apt(&text, path, options)?;
            program.shift(options.work_offset);
            Ok(ReadOutcome {
                format,
                program,
                pen_up: None,
            })
        }
    }
}

/// Reads a program and returns the `cncsim inspect` report text.
pub fn inspect(
    path: &Path,
    options: &ReadOptions,
    inspect_options: &InspectOptions,
) -> Result<Inspection, ProgramErrors> {
    let outcome = read_program_detailed(path, options)?;
    Ok(Inspection(inspect_report(
        &outcome.program,
        outcome.pen_up.as_ref(),
        inspect_options,
    )))
}

/// What `cncsim inspect` shows of a program: its moves, lengths and times.
#[derive(Debug, Clone, PartialEq)]
pub struct Inspection(pub String);

impl crate::command::Report for Inspection {
    fn text(&self) -> String {
        self.0.clone()
    }
}
