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

pub use self::apt::{parse_apt, CircleSense};
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
    Blend, Feed, FeedRule, Motion, Move, Plane, Position, Program, Span, Spindle, Warning,
};

/// The languages cncsim reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgramFormat {
    Gcode,
    Hpgl,
    Apt,
}

impl ProgramFormat {
    /// The format a file name's extension stands for (case-insensitive): `.ngc .nc .gcode
    /// .tap` G-code, `.plt .hpgl` HPGL, `.apt .cl .cls` APT CL data.
    pub fn from_path(path: &Path) -> Option<ProgramFormat> {
        let extension = path.extension()?.to_str()?.to_ascii_lowercase();
        match extension.as_str() {
            "ngc" | "nc" | "gcode" | "tap" => Some(ProgramFormat::Gcode),
            "plt" | "hpgl" => Some(ProgramFormat::Hpgl),
            "apt" | "cl" | "cls" => Some(ProgramFormat::Apt),
            _ => None,
        }
    }
}

/// A program read from a file, with the extra figures of its language.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadOutcome {
    pub format: ProgramFormat,
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
    let Some(format) = ProgramFormat::from_path(path) else {
        let extension = path.extension().map(|e| e.to_string_lossy().into_owned());
        let problem = match extension {
            Some(extension) => format!("expected a part program extension, not '.{extension}'"),
            None => "expected a part program extension, the file name has none".to_string(),
        };
        return Err(ProgramErrors::single(ProgramError::new(path, None, problem).hint(
            "use .ngc .nc .gcode .tap (G-code), .plt .hpgl (HPGL) or .apt .cl .cls (APT CL data)",
        )));
    };
    let open_error = |error: std::io::Error| {
        ProgramErrors::single(ProgramError::new(
            path,
            None,
            format!("could not read the program: {error}"),
        ))
    };
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
