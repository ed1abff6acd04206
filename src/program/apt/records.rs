//! The text of a CL file split into records and tokens: `$$` starts a comment, a `$` ending
//! a line's content continues the record on the next line; words are upper-cased.

/// One logical record: the byte ranges of its physical line pieces, comments and
/// continuation marks removed.
#[derive(Debug, Default)]
pub(super) struct Record {
    pub(super) pieces: Vec<(usize, usize)>,
}

/// Splits the text into records: `$$` starts a comment to the end of the line, a single `$`
/// ending a line's content continues the record on the next line.
pub(super) fn records(text: &[u8]) -> Vec<Record> {
    let mut records = Vec::new();
    let mut current = Record::default();
    let mut line_start = 0;
    // A `$$` comment whose line ends in `$` goes on over the next line (Creo's
    // `$$-> CSYS / …, $` comments do).
    let mut comment_goes_on = false;
    while line_start < text.len() {
        let line_end = text[line_start..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(text.len(), |i| line_start + i);
        // A lone `$` ends the line (not `$$`, which closes a decorated comment).
        let ends_in_dollar = |end: usize| {
            let mut last = end;
            while last > line_start && text[last - 1].is_ascii_whitespace() {
                last -= 1;
            }
            last > line_start
                && text[last - 1] == b'$'
                && !(last > line_start + 1 && text[last - 2] == b'$')
        };
        if comment_goes_on {
            comment_goes_on = ends_in_dollar(line_end);
            line_start = line_end + 1;
            continue;
        }
        // Content ends at a `$$` comment.
        let mut content_end = line_end;
        let mut index = line_start;
        while index + 1 < line_end {
            if text[index] == b'$' && text[index + 1] == b'$' {
                content_end = index;
                // `$$` and a lone `$` at the end: the comment continues.
                comment_goes_on = line_end > index + 2 && ends_in_dollar(line_end);
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
pub(super) enum TokenKind {
    Word(String),
    Number(f64),
    Slash,
    Comma,
    Other,
}

#[derive(Debug, Clone)]
pub(super) struct Token {
    pub(super) kind: TokenKind,
    pub(super) start: usize,
    pub(super) end: usize,
}

/// Tokenises a record; words are upper-cased. Its lines are joined by a blank, except where
/// a line was wrapped inside a number or word (CATIA wraps at a fixed column: `…, 0$` then
/// `.752602` on the next line), which is joined as written.
pub(super) fn tokens(text: &[u8], record: &Record) -> Vec<Token> {
    let mut joined = Vec::new();
    // Where each byte of `joined` is in `text`.
    let mut origin = Vec::new();
    for (index, &(start, end)) in record.pieces.iter().enumerate() {
        if index > 0 {
            let previous_end = record.pieces[index - 1].1;
            let before = text[previous_end - 1];
            let wrapped = (before.is_ascii_alphanumeric() || before == b'.')
                && text.get(previous_end) == Some(&b'$')
                && (text[start].is_ascii_digit() || text[start] == b'.');
            if !wrapped {
                joined.push(b' ');
                origin.push(previous_end);
            }
        }
        joined.extend_from_slice(&text[start..end]);
        origin.extend(start..end);
    }
    scan_tokens(&joined)
        .into_iter()
        .map(|token| Token {
            start: origin[token.start],
            end: origin[token.end - 1] + 1,
            ..token
        })
        .collect()
}

/// The tokens of `text`, at their offsets in it.
fn scan_tokens(text: &[u8]) -> Vec<Token> {
    let mut tokens = Vec::new();
    {
        let (start, end) = (0, text.len());
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
                // A word may start with digits (`1STPECK`, NX names like `2_TORETC`).
                b'0'..=b'9' if digits_then_letter(text, at, end) => {
                    while at < end && (text[at].is_ascii_alphanumeric() || text[at] == b'_') {
                        at += 1;
                    }
                    TokenKind::Word(
                        String::from_utf8_lossy(&text[token_start..at]).to_ascii_uppercase(),
                    )
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
                    // Words may be hyphenated (NX's END-OF-PATH).
                    while at < end
                        && (text[at].is_ascii_alphanumeric()
                            || text[at] == b'_'
                            || (text[at] == b'-'
                                && text.get(at + 1).is_some_and(u8::is_ascii_alphabetic)
                                && at + 1 < end))
                    {
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

/// Whether the digits at `at` run straight into a letter or `_` (other than an exponent,
/// `1E5`, `2e-3`): then they start a word.
fn digits_then_letter(text: &[u8], mut at: usize, end: usize) -> bool {
    while at < end && text[at].is_ascii_digit() {
        at += 1;
    }
    let Some(&next) = text.get(at).filter(|_| at < end) else {
        return false;
    };
    if matches!(next, b'e' | b'E') {
        // An exponent needs digits (after an optional sign).
        let mut digit = at + 1;
        if digit < end && matches!(text[digit], b'+' | b'-') {
            digit += 1;
        }
        if digit < end && text[digit].is_ascii_digit() {
            return false;
        }
    }
    next.is_ascii_alphabetic() || next == b'_'
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
