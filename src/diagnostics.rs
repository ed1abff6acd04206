//! Errors that point into a user's file: `path:line:column: message`, as compilers print them.

use std::fmt;
use std::path::{Path, PathBuf};

/// A position in a text file, 1-based.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineColumn {
    /// Line number, from 1.
    pub line: usize,
    /// Column in characters (not bytes), from 1.
    pub column: usize,
}

impl LineColumn {
    /// Line and column (in characters) of a byte offset into `text`.
    pub fn of_offset(text: &str, offset: usize) -> Self {
        let offset = offset.min(text.len());
        let before = &text[..floor_char_boundary(text, offset)];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = before[line_start..].chars().count() + 1;
        LineColumn { line, column }
    }

    /// Position of the first occurrence of `needle` in `text`, if any.
    pub fn of_first(text: &str, needle: &str) -> Option<Self> {
        text.find(needle).map(|i| Self::of_offset(text, i))
    }
}

fn floor_char_boundary(text: &str, mut i: usize) -> usize {
    while !text.is_char_boundary(i) {
        i -= 1;
    }
    i
}

/// An error in a user's file, with the place it was found where there is one.
#[derive(Debug, Clone, PartialEq)]
pub struct FileError {
    /// The file the error is in.
    pub path: PathBuf,
    /// Where in the file; `None` when the error is about the file as a whole.
    pub at: Option<LineColumn>,
    /// What is wrong, without the place.
    pub message: String,
}

impl FileError {
    /// An error in `path`, at `at` if given.
    pub fn new(path: &Path, at: Option<LineColumn>, message: impl Into<String>) -> Self {
        FileError {
            path: path.to_path_buf(),
            at,
            message: message.into(),
        }
    }

    /// An error at a byte offset of `text` (the contents of `path`).
    pub fn at_offset(path: &Path, text: &str, offset: usize, message: impl Into<String>) -> Self {
        Self::new(path, Some(LineColumn::of_offset(text, offset)), message)
    }
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.at {
            Some(at) => write!(
                f,
                "{}:{}:{}: {}",
                self.path.display(),
                at.line,
                at.column,
                self.message
            ),
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

impl std::error::Error for FileError {}

/// Turns a `toml` deserialisation error into a located one. The toml crate's own message
/// repeats the offending line with a caret; we keep only its first sentence and give the place.
pub fn toml_error(path: &Path, text: &str, err: &toml::de::Error) -> FileError {
    let at = err
        .span()
        .map(|span| LineColumn::of_offset(text, span.start));
    FileError::new(path, at, err.message().trim().to_string())
}

/// Largest description file (scenario, URDF, drives) read: far above any real one, and a bound
/// on the memory a mistaken path (a log, a disk image) can take.
pub const MAX_DESCRIPTION_BYTES: u64 = 64 << 20;

/// Reads a file to a string, naming the file in the error.
pub fn read_text(path: &Path, what: &str) -> Result<String, FileError> {
    check_size(path, what)?;
    std::fs::read_to_string(path)
        .map_err(|e| FileError::new(path, None, format!("cannot read {what}: {e}")))
}

/// Refuses a file past [`MAX_DESCRIPTION_BYTES`] before it is read.
fn check_size(path: &Path, what: &str) -> Result<(), FileError> {
    let fail = |e: String| FileError::new(path, None, format!("cannot read {what}: {e}"));
    let size = std::fs::metadata(path)
        .map_err(|e| fail(e.to_string()))?
        .len();
    if size > MAX_DESCRIPTION_BYTES {
        return Err(fail(format!(
            "it has {size} bytes, more than the {} MiB a {what} may have",
            MAX_DESCRIPTION_BYTES >> 20
        )));
    }
    Ok(())
}

/// Reads an XML file as [`read_text`] does, decoding it as its declaration says: UTF-8, or
/// ISO-8859-1 (Latin-1) where `<?xml … encoding="ISO-8859-1"?>` names it (as XML readers such
/// as urdfdom's do). Bytes that are neither are refused at their line and column.
pub fn read_xml_text(path: &Path, what: &str) -> Result<String, FileError> {
    check_size(path, what)?;
    let bytes = std::fs::read(path)
        .map_err(|e| FileError::new(path, None, format!("cannot read {what}: {e}")))?;
    let bytes = match String::from_utf8(bytes) {
        Ok(text) => return Ok(text),
        Err(e) => e.into_bytes(),
    };
    let declaration = bytes
        .split(|&b| b == b'>')
        .next()
        .map(|d| String::from_utf8_lossy(d).to_ascii_lowercase())
        .unwrap_or_default();
    let latin1 = declaration.starts_with("<?xml")
        && ["iso-8859-1", "iso8859-1", "latin1", "latin-1"]
            .iter()
            .any(|name| declaration.contains(name));
    if latin1 {
        return Ok(bytes.iter().map(|&b| char::from(b)).collect());
    }
    let valid = std::str::from_utf8(&bytes).map_or_else(|e| e.valid_up_to(), |_| bytes.len());
    let before = String::from_utf8_lossy(&bytes[..valid]);
    Err(FileError::new(
        path,
        Some(LineColumn::of_offset(&before, valid)),
        format!("cannot read {what}: a byte that is not UTF-8, and the XML declaration names no other encoding (encoding=\"ISO-8859-1\" is read too)"),
    ))
}

/// Checks that `value` (named `name`, in `unit`) lies in `[min, max]`; the message says what was
/// expected and what was found. Numbers print in their shortest exact form (`1e300`, not 301
/// digits).
pub fn check_range(name: &str, value: f64, unit: &str, min: f64, max: f64) -> Result<(), String> {
    if value.is_finite() && value >= min && value <= max {
        return Ok(());
    }
    let unit = if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    };
    Err(format!(
        "{name} = {value:?}{unit}: expected a value from {min:?} to {max:?}{unit}"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_print_numbers_short() {
        assert_eq!(
            check_range("step", 1e300, "ms", 1e-3, 1e3).unwrap_err(),
            "step = 1e300 ms: expected a value from 0.001 to 1000.0 ms"
        );
        assert!(check_range("x", f64::NAN, "", 0.0, 1.0).is_err());
        assert!(check_range("x", 1.0, "", 0.0, 1.0).is_ok());
    }

    #[test]
    fn offsets_map_to_lines_and_columns() {
        let text = "a = 1\nbé = 2\n";
        assert_eq!(
            LineColumn::of_offset(text, 0),
            LineColumn { line: 1, column: 1 }
        );
        assert_eq!(
            LineColumn::of_offset(text, 6),
            LineColumn { line: 2, column: 1 }
        );
        // 'é' is two bytes: the '=' after "bé " is the 4th character of line 2.
        let eq = text.rfind('=').unwrap();
        assert_eq!(
            LineColumn::of_offset(text, eq),
            LineColumn { line: 2, column: 4 }
        );
        assert_eq!(
            LineColumn::of_offset(text, 10_000),
            LineColumn { line: 3, column: 1 }
        );
    }
}
