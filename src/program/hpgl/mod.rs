//! HPGL plot files as plotters and CAD packages write them, redirected to an XYZ table: pen
//! down/up become the tool's Z heights, VS the drawing speed.
//!
//! HP-GL/1 (AutoCAD's HP 7475 plots, instrument screen dumps) and HP-GL/2 (Windows plotter
//! drivers: `PE` encoded polylines, polygon fills, the PCL/PJL job wrapped around them) are
//! read. Commands that move the pen are drawn, labels through a Hershey stroke font, fills
//! as outlines plus the hatch `FT` asks for. Commands that do not move the pen are skipped
//! with one warning per kind (refused with `strict`); a command that would change the
//! drawing but cannot be honoured is an error, never dropped.
//!
//! The file is read in two stages. The plotter model ([`plotter`], [`pen`], [`commands`])
//! turns commands into a drawing ([`drawing`]): pen-up travels and pen-down strokes
//! (polylines of lines and arcs), with barriers where the pen is changed. Moves are then
//! generated from the drawing, either in the file's order or, with `optimise_pen_up`, with
//! strokes reordered and reversed to shorten pen-up travel ([`optimise`]).

mod commands;
mod drawing;
mod encoded;
mod fill;
mod font;
mod label;
mod optimise;
mod pen;
mod plotter;
mod scan;

use std::collections::BTreeMap;
use std::path::Path;

use self::drawing::{generate_moves, pen_up_travel, Element, Stroke};
use self::fill::Polygon;
use self::plotter::Plotter;
use self::scan::{Escape, ScanError, Scanner, ESC};
use super::error::{display_text, ErrorSink, Found, ProgramError, ProgramErrors};
use super::options::{HpglOptions, ReadOptions};
use super::report::PenUpTravel;
use super::source::LineIndex;
use super::types::{Program, Span, Warning};

/// The pages of a plot: the one being drawn (1 until the first page advance), where the
/// pages were first advanced, and the pages something is drawn on.
#[derive(Debug)]
struct Pages {
    /// Number of the page being drawn, from 1.
    number: u32,
    /// The first page advance (PG, FR, AF, AH) and where it is.
    first_advance: Option<(Span, String)>,
    /// The pages pen-down moves draw on, in order.
    drawn: Vec<u32>,
}

impl Default for Pages {
    fn default() -> Self {
        Pages {
            number: 1,
            first_advance: None,
            drawn: Vec::new(),
        }
    }
}

impl Pages {
    fn advance(&mut self, span: Span, command: &str) {
        self.number = self.number.saturating_add(1);
        self.first_advance
            .get_or_insert_with(|| (span, command.to_string()));
    }

    /// Notes a pen-down move on the current page.
    fn mark_drawn(&mut self) {
        if self.drawn.last() != Some(&self.number) {
            self.drawn.push(self.number);
        }
    }
}

/// A decoded HPGL program with its pen-up travel figures.
#[derive(Debug, Clone, PartialEq)]
pub struct HpglOutput {
    /// The decoded program: the plot on X and Y in metres, pen up and down as Z heights.
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
        scan: Scanner::new(text, !options.hpgl.strict),
        lines: LineIndex::new(text),
        source,
        options: &options.hpgl,
        errors: ErrorSink::new(options.max_errors),
        warnings: Vec::new(),
        warned: BTreeMap::new(),
        plotter: Plotter::new(&options.hpgl),
        drawing: Vec::new(),
        stroke: None,
        mode: Mode::Hpgl,
        polygon_mode: false,
        polygon: Polygon::default(),
        label_buffer: Vec::new(),
        carriage: [0.0, 0.0],
        pages: Pages::default(),
        fill_budget: options.hpgl.max_fill_lines,
        pen_down_records: (0, None),
    };
    reader.run();
    reader.warn_nothing_drawn();
    reader.count_skipped();
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
        optimise::optimise(drawing, start)
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

/// At most this many bytes after a plot's last command are passed over as trailing junk.
const MAX_TRAILING_JUNK: usize = 64;

/// A file with this many PD records that draws nothing is said to.
const MANY_PEN_DOWN_RECORDS: usize = 10;

/// Which language the bytes are in: HPGL, or the PCL / PJL job around an HP-GL/2 plot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Hpgl,
    Pcl,
    Pjl,
}

/// A command that cannot be carried out: what was expected, and a hint.
#[derive(Debug, Clone, PartialEq)]
struct Problem {
    problem: String,
    hint: Option<String>,
}

impl Problem {
    fn new(problem: impl Into<String>) -> Self {
        Problem {
            problem: problem.into(),
            hint: None,
        }
    }

    fn hint(mut self, hint: impl Into<String>) -> Self {
        self.hint = Some(hint.into());
        self
    }
}

struct Reader<'a> {
    scan: Scanner<'a>,
    lines: LineIndex<'a>,
    source: &'a Path,
    options: &'a HpglOptions,
    errors: ErrorSink,
    warnings: Vec<Warning>,
    /// Kinds of skipped command: the index of the one warning about each, and how many
    /// there were.
    warned: BTreeMap<String, (usize, usize)>,
    plotter: Plotter,
    drawing: Vec<Element>,
    /// The stroke being drawn while the pen is down.
    stroke: Option<Stroke>,
    mode: Mode,
    /// Between PM0 and PM2: moves are recorded into `polygon`, not drawn.
    polygon_mode: bool,
    polygon: Polygon,
    /// The label buffered by BL for PB.
    label_buffer: Vec<u8>,
    /// Where a carriage return in a label goes (the last pen move's end).
    carriage: [f64; 2],
    /// The page being drawn and where the pages were advanced.
    pages: Pages,
    /// Hatch lines still allowed in this file.
    fill_budget: usize,
    /// PD records read, and where the first was.
    pen_down_records: (usize, Option<Span>),
}

impl<'a> Reader<'a> {
    fn run(&mut self) {
        while let Some(byte) = self.scan.peek() {
            match byte {
                ESC => self.escape(),
                b' ' | b'\t' | b'\r' | b'\n' | 0 | 0x0c => self.scan.at += 1,
                _ => match self.mode {
                    Mode::Hpgl => match byte {
                        b';' => self.scan.at += 1,
                        _ if byte.is_ascii_alphabetic() => self.command(),
                        // Control characters and stray punctuation between commands: HP
                        // plotters and hp2xx pass over them. A stray number is not passed
                        // over: it may be a coordinate whose command was lost.
                        _ if !self.options.strict
                            && (byte < 0x20 || byte == 0x7f || byte.is_ascii_punctuation())
                            && !matches!(byte, b'+' | b'-' | b'.') =>
                        {
                            let start = self.scan.at;
                            let end = self.scan.char_end(start);
                            self.skip(
                                "stray",
                                start,
                                end,
                                "a character between commands that is not part of one (a control character or stray punctuation) is not a pen move",
                                "was passed over, as plotters do",
                            );
                            self.scan.at = end;
                        }
                        _ if self.trailing_junk(self.scan.at) => {}
                        _ => {
                            let start = self.scan.at;
                            let end = self.scan.char_end(start);
                            self.error(
                                start,
                                end,
                                "expected an HPGL command (two letters) or ';'",
                                None,
                            );
                            self.scan.at = end;
                            self.scan.skip_to_terminator();
                        }
                    },
                    Mode::Pjl => self.pjl_line(),
                    Mode::Pcl => {
                        let start = self.scan.at;
                        self.error(
                            start,
                            self.scan.char_end(start),
                            "expected PCL commands or an HP-GL/2 plot (ESC%1B) in the PCL part of the file; PCL text is printed, not plotted",
                            Some("cncsim draws the HP-GL/2 vectors of a plot file; re-plot without text pages"),
                        );
                        // One error per run of text.
                        while !matches!(self.scan.peek(), None | Some(ESC)) {
                            self.scan.at += 1;
                        }
                    }
                },
            }
        }
        self.warn_pages();
        // End of file: a stroke still being drawn stays down.
        let at = self.scan.text.len();
        if let Some(mut stroke) = self.stroke.take() {
            stroke.open_at_end = true;
            stroke.up_span = self.lines.span(at);
            self.drawing.push(Element::Stroke(stroke));
        }
    }

    fn span(&self, at: usize) -> Span {
        self.lines.span(at)
    }

    /// Whether what is left from `start` is a stray letter and its terminator, not a command
    /// and holding none (no two letters in a row, no digit, ending in ';', at most
    /// [`MAX_TRAILING_JUNK`] bytes): `x;` after the last command, which plotters pass over.
    /// It is passed over with one warning (refused with `strict`), and the reading ends. A
    /// lone letter at the end (a cut-off file) or a stray number is not.
    fn trailing_junk(&mut self, start: usize) -> bool {
        let rest = &self.scan.text[start..];
        let letters_in_a_row = rest
            .windows(2)
            .any(|pair| pair[0].is_ascii_alphabetic() && pair[1].is_ascii_alphabetic());
        let junk = rest.len() <= MAX_TRAILING_JUNK
            && !letters_in_a_row
            && rest.iter().any(u8::is_ascii_alphabetic)
            && !rest.iter().any(u8::is_ascii_digit)
            && rest.trim_ascii_end().ends_with(b";");
        if self.options.strict || !junk {
            return false;
        }
        let shown = display_text(rest.trim_ascii());
        let span = self.span(start);
        self.warn(
            span,
            format!("`{shown}` after the plot's last command is not a command: passed over, as plotters pass over what they cannot read"),
        );
        self.scan.at = self.scan.text.len();
        true
    }

    /// Whether the current page is plotted: every page, or the one `page` chooses.
    fn page_plotted(&self) -> bool {
        self.options.page.is_none_or(|p| p == self.pages.number)
    }

    /// At the end of the file: one warning when several pages are drawn one over another,
    /// an error when the page chosen draws nothing.
    fn warn_pages(&mut self) {
        let list = |pages: &[u32]| {
            pages
                .iter()
                .map(u32::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        };
        let drawn = self.pages.drawn.clone();
        match (self.options.page, &self.pages.first_advance) {
            (Some(page), _) if !drawn.contains(&page) => {
                let end = self.scan.text.len();
                self.error(
                    end,
                    end,
                    format!(
                        "expected page {page} to draw something; the file draws on page{} {}",
                        if drawn.len() == 1 { "" } else { "s" },
                        list(&drawn)
                    ),
                    Some("choose one of those (page = N in [program], inspect --page N)"),
                );
            }
            (None, Some((span, command))) if drawn.len() > 1 && !self.options.strict => {
                let (span, command) = (*span, command.clone());
                self.warn(
                    span,
                    format!(
                        "the file draws on {} pages ({}; the first page advance, {command}, is here): they are drawn one over another, as hp2xx draws them; page = N in [program] (inspect --page N) plots one",
                        drawn.len(),
                        list(&drawn)
                    ),
                );
            }
            _ => {}
        }
    }

    fn error(&mut self, start: usize, end: usize, problem: impl Into<String>, hint: Option<&str>) {
        let text = self.scan.text;
        let end = end.min(text.len());
        let found = if start >= end {
            Found::EndOfFile
        } else {
            Found::Text(display_text(&text[start..end]))
        };
        let mut error =
            ProgramError::new(self.source, Some(self.span(start)), problem).found(found);
        error.hint = hint.map(str::to_string);
        self.errors.push(error);
    }

    fn scan_error(&mut self, error: ScanError) {
        self.error(error.start, error.end, error.problem, None);
    }

    fn warn(&mut self, span: Span, message: String) {
        self.warnings.push(Warning { span, message });
    }

    /// Something that does not move the pen is passed over: `what` it is, and what is
    /// `done` with it instead (e.g. "was skipped"). One warning per `kind`, or, with
    /// `strict`, an error for each.
    fn skip(&mut self, kind: &str, start: usize, end: usize, what: &str, done: &str) {
        if self.options.strict {
            self.error(
                start,
                end,
                format!("expected a command that draws; {what} (refused with --strict)"),
                None,
            );
        } else {
            let span = self.span(start);
            self.warn_counted(kind, span, || format!("{what} and {done}"));
        }
    }

    /// One warning per `kind`, made by `message` the first time, with the count of times put
    /// in at the end of the file.
    fn warn_counted(&mut self, kind: &str, span: Span, message: impl FnOnce() -> String) {
        let index = self.warnings.len();
        let entry = self.warned.entry(kind.to_string()).or_insert((index, 0));
        entry.1 += 1;
        if entry.0 == index && entry.1 == 1 {
            self.warn(span, message());
        }
    }

    /// At the end of the file: many PD records and not one stroke drawn is a reading that
    /// lost the drawing (or a file that has none), said once.
    fn warn_nothing_drawn(&mut self) {
        let (records, first) = self.pen_down_records;
        let drawn = self
            .drawing
            .iter()
            .any(|element| matches!(element, Element::Stroke(stroke) if !stroke.steps.is_empty()));
        if records >= MANY_PEN_DOWN_RECORDS && !drawn {
            let span = first.unwrap_or_else(|| self.span(0));
            self.warn(
                span,
                format!("{records} pen-down records (PD), the first here, and nothing drawn: every pen-down move is in polygon mode without EP or FP, off the page plotted, or clipped away"),
            );
        }
    }

    /// Puts the count of each kind of skipped command into its warning.
    fn count_skipped(&mut self) {
        for (index, count) in self.warned.values() {
            if let Some(warning) = self.warnings.get_mut(*index) {
                let times = if *count == 1 {
                    "once".to_string()
                } else {
                    format!("{count} times")
                };
                warning.message = format!("{} ({times} in the file)", warning.message);
            }
        }
    }

    /// The PCL/PJL job around an HP-GL/2 plot.
    fn skip_job_control(&mut self, start: usize, end: usize) {
        self.skip(
            "pcl",
            start,
            end,
            "PCL/PJL job control around the HP-GL/2 plot is not a pen move",
            "was skipped",
        );
    }

    fn escape(&mut self) {
        let start = self.scan.at;
        match self.scan.escape() {
            Err(error) => self.scan_error(error),
            Ok(Escape::DeviceControl) => {}
            Ok(Escape::EnterHpgl) => {
                self.skip_job_control(start, self.scan.at);
                self.mode = Mode::Hpgl;
            }
            Ok(escape) => {
                self.mode = match escape {
                    Escape::UniversalExit => Mode::Pjl,
                    Escape::EnterPcl | Escape::PclReset => Mode::Pcl,
                    _ => self.mode,
                };
                if escape == Escape::PclRaster {
                    self.error(
                        start,
                        self.scan.at.min(start + 8),
                        "expected PCL control or HP-GL/2 vectors; PCL raster graphics are an image, not pen moves",
                        Some("re-plot the drawing as vectors (HP-GL/2) without raster images"),
                    );
                } else {
                    self.skip_job_control(start, self.scan.at);
                }
            }
        }
    }

    /// A PJL line after the universal exit: skipped; `ENTER LANGUAGE` switches language.
    fn pjl_line(&mut self) {
        let (start, end) = self.scan.line();
        let line = String::from_utf8_lossy(&self.scan.text[start..end]).to_ascii_uppercase();
        if !line.starts_with("@PJL") {
            // Not PJL: the printer's default language, PCL.
            self.scan.at = start;
            self.mode = Mode::Pcl;
            return;
        }
        self.skip_job_control(start, end);
        if let Some(language) = line.split("LANGUAGE").nth(1) {
            let language = language.trim_start_matches([' ', '=']).trim();
            if language.starts_with("HPGL") {
                self.mode = Mode::Hpgl;
            } else if language.starts_with("PCL") {
                self.mode = Mode::Pcl;
            }
        }
    }
}
