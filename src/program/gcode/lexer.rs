//! The first step of reading a block: comments taken out, blanks dropped and letters
//! lower-cased, as LinuxCNC's `close_and_downcase` does, keeping where every character came
//! from so that messages point into the raw line.

use super::LineError;
use crate::program::error::Found;

/// A significant character of a compacted line: lower-cased byte and its index in the raw line.
#[derive(Debug, Clone, Copy)]
pub(super) struct Significant {
    pub byte: u8,
    pub at: usize,
}

/// A comment in parentheses that LinuxCNC acts on (`(MSG,…)`, `(DEBUG,…)`, `(PRINT,…)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ActiveComment {
    None,
    /// Byte range of the text after the comma, in the raw line.
    Message {
        start: usize,
        end: usize,
    },
    /// `(ABORT,…)`: LinuxCNC stops the program with this text as its error.
    Abort {
        start: usize,
        end: usize,
    },
}

/// Takes comments out of a line, drops blanks and lower-cases letters. Returns the first
/// `(MSG,…)` comment, which the interpreter turns into a warning.
pub(super) fn compact_line(
    line: &[u8],
    out: &mut Vec<Significant>,
) -> Result<ActiveComment, LineError> {
    let mut message = ActiveComment::None;
    let mut index = 0;
    while index < line.len() {
        let byte = line[index];
        match byte {
            b'(' => {
                let open = index;
                index += 1;
                loop {
                    match line.get(index) {
                        None => {
                            return Err(LineError::new(
                                open,
                                line.len(),
                                "expected ')' to close the comment",
                            )
                            .found(Found::EndOfLine)
                            .hint("comments in parentheses end on the line they start"));
                        }
                        Some(b')') => break,
                        Some(b'(') => {
                            return Err(LineError::new(
                                index,
                                index + 1,
                                "expected ')' before another '(' (comments do not nest)",
                            ));
                        }
                        Some(_) => index += 1,
                    }
                }
                if message == ActiveComment::None {
                    message = active_comment(line, open + 1, index);
                }
            }
            b';' => break,
            b' ' | b'\t' | b'\r' | b'\x0c' | b'\x0b' => {}
            _ if byte.is_ascii_graphic() => out.push(Significant {
                byte: byte.to_ascii_lowercase(),
                at: index,
            }),
            _ => {
                let end = utf8_char_end(line, index);
                return Err(LineError::new(
                    index,
                    end,
                    "expected a G-code word, comment or blank",
                ));
            }
        }
        index += 1;
    }
    Ok(message)
}

/// `(MSG, text)` (blanks allowed before the comma, any case) → the text's range.
fn active_comment(line: &[u8], start: usize, end: usize) -> ActiveComment {
    let inner = &line[start..end];
    let letters: Vec<(usize, u8)> = inner
        .iter()
        .enumerate()
        .filter(|(_, b)| !b.is_ascii_whitespace())
        .map(|(i, b)| (i, b.to_ascii_lowercase()))
        .take(4)
        .collect();
    let word: Vec<u8> = letters.iter().map(|&(_, b)| b).collect();
    let letters6: Vec<(usize, u8)> = inner
        .iter()
        .enumerate()
        .filter(|(_, b)| !b.is_ascii_whitespace())
        .map(|(i, b)| (i, b.to_ascii_lowercase()))
        .take(6)
        .collect();
    let word6: Vec<u8> = letters6.iter().map(|&(_, b)| b).collect();
    if word.starts_with(b"msg,") {
        let comma = letters[3].0;
        ActiveComment::Message {
            start: start + comma + 1,
            end,
        }
    } else if word6.starts_with(b"abort,") {
        let comma = letters6[5].0;
        ActiveComment::Abort {
            start: start + comma + 1,
            end,
        }
    } else {
        ActiveComment::None
    }
}

/// End of the (possibly multi-byte, possibly broken) UTF-8 character starting at `start`.
pub(super) fn utf8_char_end(bytes: &[u8], start: usize) -> usize {
    let mut end = start + 1;
    while end < bytes.len() && end - start < 4 && (bytes[end] & 0xC0) == 0x80 {
        end += 1;
    }
    end
}
