//! What every section's check needs of the file it came from: its path (for messages and for
//! resolving the files it names), its text (for turning spans into lines and columns), and a
//! place to put warnings.

use crate::diagnostics::{check_range, FileError, LineColumn};
use std::cell::RefCell;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

pub(super) type Num = Spanned<f64>;

/// The scenario file being read.
pub(super) struct Source<'a> {
    pub path: &'a Path,
    pub text: &'a str,
    warnings: RefCell<Vec<FileError>>,
    /// Every path the file names, as resolved (what a run reads besides the file itself).
    named_files: RefCell<Vec<PathBuf>>,
}

/// A raw section together with the file it came from: what a section's `TryFrom` takes.
pub(super) struct InFile<'a, R> {
    pub raw: R,
    pub file: &'a Source<'a>,
}

impl<'a> Source<'a> {
    pub fn new(path: &'a Path, text: &'a str) -> Self {
        Source {
            path,
            text,
            warnings: RefCell::new(Vec::new()),
            named_files: RefCell::new(Vec::new()),
        }
    }

    /// `raw` as a section of this file.
    pub fn section<R>(&'a self, raw: R) -> InFile<'a, R> {
        InFile { raw, file: self }
    }

    /// Line and column of a byte offset.
    pub fn at(&self, offset: usize) -> Option<LineColumn> {
        Some(LineColumn::of_offset(self.text, offset))
    }

    /// Line and column of a value's span (`None` for a default, which has no place).
    pub fn place(&self, span: Range<usize>) -> Option<LineColumn> {
        if span == (0..0) {
            None
        } else {
            self.at(span.start)
        }
    }

    /// Where a table header such as `[program]` first appears.
    pub fn table(&self, header: &str) -> Option<LineColumn> {
        LineColumn::of_first(self.text, header)
    }

    /// An error at a value's span.
    pub fn error(&self, span: Range<usize>, message: impl Into<String>) -> FileError {
        FileError::new(self.path, self.place(span), message)
    }

    /// An error at a known place (or none).
    pub fn error_at(&self, at: Option<LineColumn>, message: impl Into<String>) -> FileError {
        FileError::new(self.path, at, message)
    }

    /// A number within its range, or an error at its place.
    pub fn ranged(
        &self,
        v: &Num,
        what: &str,
        unit: &str,
        (lo, hi): (f64, f64),
    ) -> Result<f64, FileError> {
        let x = *v.get_ref();
        check_range(what, x, unit, lo, hi)
            .map(|()| x)
            .map_err(|m| self.error(v.span(), m))
    }

    /// A number within its range if given.
    pub fn ranged_opt(
        &self,
        v: Option<&Num>,
        what: &str,
        unit: &str,
        range: (f64, f64),
    ) -> Result<Option<f64>, FileError> {
        v.map(|v| self.ranged(v, what, unit, range)).transpose()
    }

    /// A path written in the file, relative to the file's folder.
    pub fn resolve(&self, written: &str) -> PathBuf {
        let path = self.path.parent().unwrap_or(Path::new(".")).join(written);
        self.named_files.borrow_mut().push(path.clone());
        path
    }

    /// Keeps a value that is legal but looks wrong, to be reported with the scenario.
    pub fn warn(&self, warning: FileError) {
        self.warnings.borrow_mut().push(warning);
    }

    /// The warnings kept, and the files the scenario names.
    pub fn into_warnings_and_files(self) -> (Vec<FileError>, Vec<PathBuf>) {
        (self.warnings.into_inner(), self.named_files.into_inner())
    }
}
