//! Diagnostics shared by the three front ends: one error type that names the file, line,
//! column, the offending text, what was expected and (where it helps) a hint, and a
//! collection of such errors so that a file's recoverable errors are reported together.

use std::fmt;
use std::path::PathBuf;

use super::types::Span;

/// What a diagnostic points at in the source.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Found {
    /// The message needs no "found" part (e.g. a missing file).
    Nothing,
    /// This text (already escaped for display, see [`display_text`]).
    Text(String),
    /// The end of the line came first.
    EndOfLine,
    /// The end of the file came first.
    EndOfFile,
}

/// One problem in a part program.
///
/// Displayed on one line as `file:line:column: problem, found 'text'; hint: …`, e.g.
/// `part.ngc:12:7: expected a number after 'X', found 'Q'`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct ProgramError {
    /// The file (or label) the program was read from.
    pub file: PathBuf,
    /// Where in the file; `None` for problems with the file as a whole.
    pub span: Option<Span>,
    /// What is wrong, usually phrased as what was expected.
    pub problem: String,
    /// The offending text.
    pub found: Found,
    /// How to fix it, where a hint helps.
    pub hint: Option<String>,
}

impl ProgramError {
    /// An error in `file` at `span` (`None`: the file as a whole), with no "found" part and
    /// no hint yet.
    pub fn new(file: impl Into<PathBuf>, span: Option<Span>, problem: impl Into<String>) -> Self {
        ProgramError {
            file: file.into(),
            span,
            problem: problem.into(),
            found: Found::Nothing,
            hint: None,
        }
    }

    /// The same error, pointing at `found`.
    pub fn found(mut self, found: Found) -> Self {
        self.found = found;
        self
    }

    /// The same error, pointing at the source bytes `text` (escaped with [`display_text`]).
    pub fn found_text(self, text: &[u8]) -> Self {
        self.found(Found::Text(display_text(text)))
    }

    /// The same error, with a hint on how to fix it.
    pub fn hint(mut self, hint: impl Into<String>) -> Self {
        self.hint = Some(hint.into());
        self
    }
}

impl fmt::Display for ProgramError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(span) = self.span {
            write!(f, ":{}:{}", span.line, span.column)?;
        }
        write!(f, ": {}", self.problem)?;
        match &self.found {
            Found::Nothing => {}
            Found::Text(text) => write!(f, ", found '{text}'")?,
            Found::EndOfLine => write!(f, ", found end of line")?,
            Found::EndOfFile => write!(f, ", found end of file")?,
        }
        if let Some(hint) = &self.hint {
            write!(f, "; hint: {hint}")?;
        }
        Ok(())
    }
}

/// All the errors found in one program (at least one).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct ProgramErrors {
    /// The errors kept, in source order.
    pub errors: Vec<ProgramError>,
    /// How many further errors were found but not kept (see `ReadOptions::max_errors`).
    pub suppressed: usize,
}

impl ProgramErrors {
    /// Just `error`, none suppressed.
    pub fn single(error: ProgramError) -> Self {
        ProgramErrors {
            errors: vec![error],
            suppressed: 0,
        }
    }
}

impl fmt::Display for ProgramErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (index, error) in self.errors.iter().enumerate() {
            if index > 0 {
                writeln!(f)?;
            }
            write!(f, "{error}")?;
        }
        if self.suppressed > 0 {
            write!(f, "\n… and {} more errors", self.suppressed)?;
        }
        Ok(())
    }
}

/// Collects the errors of one parse, keeping at most `limit` so that a garbage file of a
/// million lines cannot make the error list itself the memory problem.
#[derive(Debug)]
pub(super) struct ErrorSink {
    kept: Vec<ProgramError>,
    suppressed: usize,
    limit: usize,
}

impl ErrorSink {
    pub(super) fn new(limit: usize) -> Self {
        ErrorSink {
            kept: Vec::new(),
            suppressed: 0,
            limit: limit.max(1),
        }
    }

    pub(super) fn push(&mut self, error: ProgramError) {
        if self.kept.len() < self.limit {
            self.kept.push(error);
        } else {
            self.suppressed += 1;
        }
    }

    pub(super) fn is_empty(&self) -> bool {
        self.kept.is_empty()
    }

    /// `Ok(value)` if nothing was reported, else all the errors.
    pub(super) fn finish<T>(self, value: T) -> Result<T, ProgramErrors> {
        if self.kept.is_empty() {
            Ok(value)
        } else {
            Err(ProgramErrors {
                errors: self.kept,
                suppressed: self.suppressed,
            })
        }
    }
}

/// Longest offending text quoted in a message; longer text is cut with an ellipsis.
const MAX_QUOTED_CHARS: usize = 40;

/// Source bytes as they should appear inside quotes in a message: invalid UTF-8 replaced,
/// control characters escaped (`\x1b` for ESC), long text shortened.
pub fn display_text(bytes: &[u8]) -> String {
    let text = String::from_utf8_lossy(bytes);
    let mut out = String::new();
    for (count, ch) in text.chars().enumerate() {
        if count == MAX_QUOTED_CHARS {
            out.push('…');
            break;
        }
        match ch {
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            '\n' => out.push_str("\\n"),
            c if c.is_control() => out.push_str(&format!("\\x{:02x}", c as u32)),
            c => out.push(c),
        }
    }
    out
}
