//! What every command returns: a report that writes its files, shows itself on the terminal
//! (text or `--json`), and says how the command ended. The command line only chooses the form
//! and turns the ending into an exit status. Every stage may return one, so this sits beside
//! [`crate::diagnostics`] at the base of the crate.

use crate::diagnostics::FileError;
use std::path::{Path, PathBuf};

/// Why a report's files could not be written (its message names the file).
pub type WriteError = Box<dyn std::error::Error + Send + Sync>;

/// How a command ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Ending {
    /// It did what was asked.
    Done,
    /// It ran, but the result is a failure: a run stopped early, a bound was breached, a
    /// search found nothing. The message (if any) says why.
    Failed(Option<String>),
    /// Its input was wrong; the message says where (if not reported before).
    BadInput(Option<String>),
    /// Ctrl-C: what finished is written; the message says how far it got.
    Interrupted(Option<String>),
}

/// A command's result.
pub trait Report {
    /// Writes the report's files and returns every file the command wrote, in the order
    /// written (a run writes its own as it goes: those are listed too).
    fn write(&self) -> Result<Vec<PathBuf>, WriteError> {
        Ok(Vec::new())
    }

    /// What the terminal shows.
    fn text(&self) -> String;

    /// The report as data for `--json`; `None` for commands without a JSON form.
    fn json(&self) -> Option<serde_json::Value> {
        None
    }

    /// Lines for the error stream, shown before the report: values that loaded but look
    /// wrong, what the command did besides.
    fn messages(&self) -> Vec<String> {
        Vec::new()
    }

    /// How the command ended, which sets the exit status; by default it did what was asked.
    fn ending(&self) -> Ending {
        Ending::Done
    }
}

/// Writes `text` to `path`, as a report's file.
pub fn write_file(path: PathBuf, text: impl AsRef<[u8]>) -> Result<PathBuf, FileError> {
    std::fs::write(&path, text).map_err(|e| cannot_write(&path, e))?;
    Ok(path)
}

/// The error of a file a report could not write.
pub fn cannot_write(path: &Path, error: impl std::fmt::Display) -> FileError {
    FileError::new(path, None, format!("cannot write: {error}"))
}

/// Where a line a command shows as it goes belongs: the report stream or the error stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    /// The report stream (standard output).
    Out,
    /// The error stream (standard error): errors and warnings.
    Err,
}
