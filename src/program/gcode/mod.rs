//! G-code (RS274/NGC) as LinuxCNC 2.9 runs it.
//!
//! Each line is one block. A block is compacted (comments out, blanks dropped, letters
//! lower-cased: [`lexer`]), read into words with its values evaluated ([`block`], [`expr`]),
//! then executed in LinuxCNC's order of execution against the modal state ([`execute`],
//! [`motion`], [`cycles`]). O-word lines steer which line comes next ([`control`]). The
//! interpreter works in program coordinates and units like LinuxCNC's; [`canon`] adds the
//! offsets and converts to SI, as LinuxCNC's canonical layer does.
//!
//! The reader streams: lines are read as they are needed and dropped once no loop can come
//! back to them, so memory follows the moves kept (plus the text of subroutines and of the
//! loops being run). Work is bounded: at most `GcodeOptions::max_blocks` blocks are executed
//! and at most `GcodeOptions::max_moves` moves produced, so an endless loop ends with an error.
//!
//! Errors are collected per block and the interpreter goes on with the next line, so every
//! bad block of a plain file is reported in one go; inside subroutines and loops the first
//! error ends the run (the rest would follow from it).

mod block;
mod canon;
mod codes;
mod comp;
mod control;
mod cycles;
mod execute;
mod expr;
mod lexer;
mod motion;
mod params;
mod state;
mod tool_table;

use std::collections::VecDeque;
use std::io::BufRead;
use std::path::Path;
use std::rc::Rc;

use super::error::{display_text, ErrorSink, Found, ProgramError, ProgramErrors};
use super::options::ReadOptions;
use super::source::{char_column, saturate};
use super::types::{Program, Span};

pub use self::tool_table::parse_tool_table;

/// Decodes G-code held in memory. `source` names the program in messages.
pub fn parse_gcode(
    text: impl AsRef<[u8]>,
    source: impl AsRef<Path>,
    options: &ReadOptions,
) -> Result<Program, ProgramErrors> {
    parse_gcode_reader(text.as_ref(), source, options)
}

/// Decodes G-code line by line from a reader (a 1-million-line file is never held whole).
pub fn parse_gcode_reader<R: BufRead>(
    reader: R,
    source: impl AsRef<Path>,
    options: &ReadOptions,
) -> Result<Program, ProgramErrors> {
    let source = source.as_ref();
    let mut lines = Lines::new(reader);
    let mut interpreter = state::Interpreter::new(source, options);
    control::run(&mut interpreter, &mut lines);
    if let Some(error) = lines.read_error.take() {
        interpreter.errors.push(ProgramError::new(
            source,
            None,
            format!("could not read the program: {error}"),
        ));
    }
    interpreter.finish(lines.line_count(), lines.byte_count())
}

/// One line of the source as read.
#[derive(Debug)]
pub(super) struct SourceLine {
    /// The text without its line end.
    pub text: Vec<u8>,
    /// 1-based line number.
    pub number: usize,
    /// Byte offset of the line's start in the file.
    pub offset: usize,
}

/// The main program's lines: read on demand, kept while a loop may come back to them.
pub(super) struct Lines<R> {
    reader: R,
    /// Lines from `base` on (global 0-based indices).
    kept: VecDeque<Rc<SourceLine>>,
    base: usize,
    next_offset: usize,
    eof: bool,
    read_error: Option<std::io::Error>,
    /// Buffers of dropped lines, reused for the next ones.
    spare: Vec<Vec<u8>>,
}

impl<R: BufRead> Lines<R> {
    fn new(reader: R) -> Self {
        Lines {
            reader,
            kept: VecDeque::new(),
            base: 0,
            next_offset: 0,
            eof: false,
            read_error: None,
            spare: Vec::new(),
        }
    }

    /// Line `index` (0-based), reading further as needed; `None` after the last line.
    pub fn get(&mut self, index: usize) -> Option<Rc<SourceLine>> {
        debug_assert!(index >= self.base, "line {index} was already dropped");
        while index >= self.base + self.kept.len() {
            if !self.read_one() {
                return None;
            }
        }
        self.kept.get(index - self.base).cloned()
    }

    /// Drops the lines before `index`: nothing will come back to them.
    pub fn release_before(&mut self, index: usize) {
        while self.base < index {
            let Some(line) = self.kept.pop_front() else {
                break;
            };
            self.base += 1;
            if self.spare.len() < 4 {
                if let Ok(line) = Rc::try_unwrap(line) {
                    self.spare.push(line.text);
                }
            }
        }
    }

    fn read_one(&mut self) -> bool {
        if self.eof {
            return false;
        }
        let mut text = self.spare.pop().unwrap_or_default();
        text.clear();
        match self.reader.read_until(b'\n', &mut text) {
            Ok(0) => {
                self.eof = true;
                false
            }
            Ok(read) => {
                if text.last() == Some(&b'\n') {
                    text.pop();
                }
                if text.last() == Some(&b'\r') {
                    text.pop();
                }
                let number = self.base + self.kept.len() + 1;
                self.kept.push_back(Rc::new(SourceLine {
                    text,
                    number,
                    offset: self.next_offset,
                }));
                self.next_offset += read;
                true
            }
            Err(error) => {
                self.read_error = Some(error);
                self.eof = true;
                false
            }
        }
    }

    fn line_count(&self) -> usize {
        self.base + self.kept.len()
    }

    fn byte_count(&self) -> usize {
        self.next_offset
    }
}

/// A problem found while reading one line; converted to a [`ProgramError`] with the line's
/// position.
#[derive(Debug)]
pub(super) struct LineError {
    pub start: usize,
    pub end: usize,
    pub problem: String,
    pub found: Option<Found>,
    pub hint: Option<String>,
}

impl LineError {
    pub fn new(start: usize, end: usize, problem: impl Into<String>) -> Self {
        LineError {
            start,
            end,
            problem: problem.into(),
            found: None,
            hint: None,
        }
    }

    pub fn found(mut self, found: Found) -> Self {
        self.found = Some(found);
        self
    }

    pub fn hint(mut self, hint: impl Into<String>) -> Self {
        self.hint = Some(hint.into());
        self
    }

    /// An error found without a position (0..0) placed on `start..end` of the line.
    pub fn located(self, start: usize, end: usize) -> Self {
        if self.start == 0 && self.end == 0 {
            LineError { start, end, ..self }
        } else {
            self
        }
    }
}

/// The span of byte `byte_in_line` of a line.
pub(super) fn span_in_line(line: &SourceLine, byte_in_line: usize) -> Span {
    Span {
        line: saturate(line.number),
        column: char_column(&line.text, byte_in_line),
        byte_offset: saturate(line.offset + byte_in_line.min(line.text.len())),
    }
}

/// A [`LineError`] as a [`ProgramError`] of `source`.
pub(super) fn program_error(source: &Path, line: &SourceLine, error: LineError) -> ProgramError {
    let span = span_in_line(line, error.start);
    let found = error.found.unwrap_or_else(|| {
        let end = error.end.min(line.text.len());
        let start = error.start.min(end);
        if start == end {
            Found::EndOfLine
        } else {
            Found::Text(display_text(&line.text[start..end]))
        }
    });
    let mut program_error = ProgramError::new(source, Some(span), error.problem).found(found);
    program_error.hint = error.hint;
    program_error
}

/// The line without leading/trailing blanks and without a `;` comment, for quoting.
pub(super) fn block_text_range(line: &[u8]) -> (usize, usize) {
    let end = line.iter().position(|&b| b == b';').unwrap_or(line.len());
    let start = line[..end]
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(end);
    let trimmed_end = line[..end]
        .iter()
        .rposition(|b| !b.is_ascii_whitespace())
        .map_or(start, |i| i + 1);
    (start, trimmed_end.max(start))
}

/// Keeps the error sink's type in one place for the submodules.
pub(super) type Errors = ErrorSink;
