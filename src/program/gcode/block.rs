//! Splitting a compacted line into a block: G and M codes by modal group, the other words by
//! letter, parameter settings and the O-word of a control line. Values are read (and
//! expressions evaluated) here, with the parameter values from before the line, as LinuxCNC
//! does; the settings take effect after the line has been read.

use super::codes::{g_code_info, group, m_code_info, mgroup, Support};
use super::expr::{Cursor, ParameterRef, Parameters};
use super::lexer::Significant;
use super::LineError;
use crate::program::error::display_text;

/// A word's value and where its text lies in the raw line (byte range).
#[derive(Debug, Clone, Copy)]
pub(super) struct Word {
    pub value: f64,
    pub start: usize,
    pub end: usize,
}

#[derive(Debug, Clone, Copy)]
pub(super) struct CodeWord {
    /// G codes in tenths, M codes whole.
    pub code: u32,
    pub start: usize,
    pub end: usize,
}

impl Word {
    /// An error pointing at this word.
    pub fn error(&self, problem: impl Into<String>) -> LineError {
        LineError::new(self.start, self.end, problem)
    }
}

impl CodeWord {
    /// An error pointing at this code.
    pub fn error(&self, problem: impl Into<String>) -> LineError {
        LineError::new(self.start, self.end, problem)
    }
}

/// The keyword of an O-word control line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Keyword {
    Sub,
    EndSub,
    Call,
    Return,
    Do,
    While,
    EndWhile,
    Repeat,
    EndRepeat,
    If,
    ElseIf,
    Else,
    EndIf,
    Break,
    Continue,
}

impl Keyword {
    pub fn name(self) -> &'static str {
        KEYWORDS
            .iter()
            .find(|(_, k)| *k == self)
            .map_or("?", |(text, _)| text)
    }
}

/// Longer keywords first where one is a prefix of another.
const KEYWORDS: [(&str, Keyword); 15] = [
    ("endsub", Keyword::EndSub),
    ("endwhile", Keyword::EndWhile),
    ("endrepeat", Keyword::EndRepeat),
    ("endif", Keyword::EndIf),
    ("elseif", Keyword::ElseIf),
    ("else", Keyword::Else),
    ("sub", Keyword::Sub),
    ("call", Keyword::Call),
    ("return", Keyword::Return),
    ("do", Keyword::Do),
    ("while", Keyword::While),
    ("repeat", Keyword::Repeat),
    ("if", Keyword::If),
    ("break", Keyword::Break),
    ("continue", Keyword::Continue),
];

/// An O-word control line: `o<label> keyword [value] …`.
#[derive(Debug, Clone)]
pub(super) struct OWord {
    /// The label as written, lower case: `<name>` → "name", `o100` → "100".
    pub label: String,
    pub keyword: Keyword,
    /// The bracketed values after the keyword (condition, count, return value, arguments),
    /// evaluated; `None` when the line is only scanned (skipped code).
    pub values: Vec<f64>,
    pub start: usize,
    pub end: usize,
}

/// One block after reading: at most one code per modal group, at most one word per letter.
#[derive(Debug, Default)]
pub(super) struct Block {
    pub g: [Option<CodeWord>; group::COUNT],
    pub m: [Option<CodeWord>; mgroup::COUNT],
    /// LinuxCNC allows M7 and M8 together; the second coolant code lands here.
    pub second_coolant: Option<CodeWord>,
    /// Words by letter (`a` = 0); G, M, N and O are kept elsewhere.
    pub words: [Option<Word>; 26],
    /// Polar coordinates: `@` radius and `^` angle (degrees).
    pub polar_radius: Option<Word>,
    pub polar_angle: Option<Word>,
    /// Parameter settings in the order written.
    pub settings: Vec<(ParameterRef, f64)>,
    pub o_word: Option<OWord>,
    /// Raw byte range of the block's text (for quoting).
    pub start: usize,
    pub end: usize,
    /// Whether the block has anything beyond parameter settings and a line number.
    pub has_codes: bool,
}

/// X Y Z A B C in axis order.
pub(super) const AXIS_LETTERS: [u8; 6] = [b'x', b'y', b'z', b'a', b'b', b'c'];

impl Block {
    pub fn word(&self, letter: u8) -> Option<Word> {
        self.words[usize::from(letter - b'a')]
    }

    pub fn has(&self, letter: u8) -> bool {
        self.word(letter).is_some()
    }

    pub fn value(&self, letter: u8) -> Option<f64> {
        self.word(letter).map(|w| w.value)
    }

    pub fn has_axis_words(&self) -> bool {
        AXIS_LETTERS.iter().any(|&letter| self.has(letter))
            || self.polar_radius.is_some()
            || self.polar_angle.is_some()
    }

    pub fn g_code(&self, group: usize) -> Option<u32> {
        self.g[group].map(|word| word.code)
    }

    pub fn m_code(&self, group: usize) -> Option<u32> {
        self.m[group].map(|word| word.code)
    }

    /// The first axis word written (for messages).
    pub fn first_axis_word(&self) -> Option<Word> {
        AXIS_LETTERS
            .iter()
            .filter_map(|&l| self.word(l))
            .chain(self.polar_radius)
            .chain(self.polar_angle)
            .min_by_key(|w| w.start)
    }
}

/// Reads only the O-word of a line, without evaluating anything: what skipped code needs.
pub(super) fn scan_o_word(line: &[u8], chars: &[Significant]) -> Option<(String, Keyword)> {
    let mut index = 0;
    if chars.first().map(|c| c.byte) == Some(b'/') {
        index += 1;
    }
    // An N word may come first.
    if chars.get(index).map(|c| c.byte) == Some(b'n') {
        index += 1;
        while chars
            .get(index)
            .is_some_and(|c| c.byte.is_ascii_digit() || c.byte == b'.')
        {
            index += 1;
        }
    }
    if chars.get(index).map(|c| c.byte) != Some(b'o') {
        return None;
    }
    index += 1;
    let label = if chars.get(index).map(|c| c.byte) == Some(b'<') {
        let close = chars[index..].iter().position(|c| c.byte == b'>')? + index;
        let label: String = chars[index + 1..close]
            .iter()
            .map(|c| c.byte as char)
            .collect();
        index = close + 1;
        label
    } else {
        let start = index;
        while chars.get(index).is_some_and(|c| c.byte.is_ascii_digit()) {
            index += 1;
        }
        let digits: String = chars[start..index].iter().map(|c| c.byte as char).collect();
        normalise_number_label(&digits)?
    };
    let _ = line;
    let rest: Vec<u8> = chars[index..].iter().take(9).map(|c| c.byte).collect();
    let keyword = KEYWORDS
        .iter()
        .find(|(text, _)| rest.starts_with(text.as_bytes()))?
        .1;
    Some((label, keyword))
}

/// `o0100` and `o100` are the same label.
fn normalise_number_label(digits: &str) -> Option<String> {
    if digits.is_empty() {
        return None;
    }
    let trimmed = digits.trim_start_matches('0');
    Some(if trimmed.is_empty() { "0" } else { trimmed }.to_string())
}

/// Splits a compacted block into words and checks letters, numbers and modal groups, into
/// `block` (reused from line to line: a block is large).
pub(super) fn read_block(
    line: &[u8],
    chars: &[Significant],
    params: &dyn Parameters,
    block: &mut Block,
) -> Result<(), LineError> {
    block.g = Default::default();
    block.m = Default::default();
    block.second_coolant = None;
    block.words = Default::default();
    block.polar_radius = None;
    block.polar_angle = None;
    block.settings.clear();
    block.o_word = None;
    block.start = chars.first().map_or(0, |c| c.at);
    block.end = chars.last().map_or(0, |c| c.at + 1);
    block.has_codes = false;
    let mut cursor = Cursor::new(line, chars, 0);
    while let Some(letter) = cursor.peek() {
        let word_start = cursor.at();
        let first = cursor.index == 0;
        match letter {
            b'n' if first => {
                cursor.index += 1;
                // Line numbers are labels: digits with an optional fraction.
                cursor.number()?;
                continue;
            }
            b'n' => {
                return Err(LineError::new(
                    word_start,
                    word_start + 1,
                    "expected the line number (N word) at the start of the block",
                ));
            }
            b'#' => {
                let target = cursor.parameter_ref(params)?;
                if cursor.peek() != Some(b'=') {
                    return Err(cursor
                        .error_here("expected '=' after the parameter (a parameter setting)")
                        .hint("a parameter used as a value must follow a word letter, e.g. X#1"));
                }
                cursor.index += 1;
                let value = cursor.real_value(params)?;
                block.settings.push((target, value));
                continue;
            }
            b'o' => {
                if block.has_codes || block.o_word.is_some() {
                    return Err(LineError::new(
                        word_start,
                        word_start + 1,
                        "expected the O-word at the start of the block",
                    ));
                }
                let o_word = read_o_word(&mut cursor, params)?;
                if let Some(extra) = cursor.peek() {
                    let _ = extra;
                    return Err(cursor.error_here(format!(
                        "expected nothing more after 'o{} {}' on its line",
                        display_label(&o_word.label),
                        o_word.keyword.name()
                    )));
                }
                block.o_word = Some(o_word);
                continue;
            }
            b'u' | b'v' | b'w' => {
                return Err(LineError::new(
                    word_start,
                    word_start + 1,
                    "expected an axis of X Y Z A B C; U V W axes are not supported",
                ));
            }
            b'e' => {
                return Err(LineError::new(
                    word_start,
                    word_start + 1,
                    "expected a word letter cncsim supports; E words (G76 threading, M66 inputs) are not supported",
                ));
            }
            b'$' => {
                return Err(LineError::new(
                    word_start,
                    word_start + 1,
                    "expected a word letter cncsim supports; spindle selection ($) is not supported",
                ));
            }
            b'a'..=b'd' | b'f'..=b'm' | b'p'..=b't' | b'x'..=b'z' | b'@' | b'^' => {}
            _ => {
                let end = crate::program::gcode::lexer::utf8_char_end(line, word_start);
                return Err(LineError::new(
                    word_start,
                    end,
                    "expected a word letter (G, M, X, Y, Z, …)",
                ));
            }
        }
        if block.o_word.is_some() {
            return Err(LineError::new(
                word_start,
                word_start + 1,
                "expected nothing more after the O-word on its line",
            ));
        }
        block.has_codes = true;
        cursor.index += 1;
        if cursor.peek().is_none() {
            return Err(cursor.error_here(format!(
                "expected a number after '{}'",
                letter.to_ascii_uppercase() as char
            )));
        }
        if cursor.peek().is_some_and(|b| b.is_ascii_alphabetic()) && !starts_function(&cursor) {
            return Err(cursor.error_here(format!(
                "expected a number after '{}'",
                letter.to_ascii_uppercase() as char
            )));
        }
        let value = cursor.real_value(params)?;
        let word_end = cursor.end_of_previous();
        let word = Word {
            value,
            start: word_start,
            end: word_end,
        };
        match letter {
            b'g' => add_g(block, line, word)?,
            b'm' => add_m(block, word)?,
            b'@' | b'^' => {
                let slot = if letter == b'@' {
                    &mut block.polar_radius
                } else {
                    &mut block.polar_angle
                };
                if slot.is_some() {
                    return Err(LineError::new(
                        word_start,
                        word_end,
                        format!("expected one {} word per block", letter as char),
                    ));
                }
                *slot = Some(word);
            }
            _ => {
                let slot = &mut block.words[usize::from(letter - b'a')];
                if let Some(previous) = slot {
                    return Err(LineError::new(
                        word_start,
                        word_end,
                        format!(
                            "expected one {} word per block, but {} is the second",
                            letter.to_ascii_uppercase() as char,
                            display_text(&line[word_start..word_end])
                        ),
                    )
                    .hint(format!(
                        "the first is '{}'",
                        display_text(&line[previous.start..previous.end])
                    )));
                }
                *slot = Some(word);
            }
        }
    }
    Ok(())
}

/// Whether the cursor is at the name of a function (`ABS[`, `SIN[`, …).
fn starts_function(cursor: &Cursor) -> bool {
    const NAMES: [&str; 14] = [
        "abs", "acos", "asin", "atan", "cos", "exists", "exp", "fix", "fup", "ln", "round", "sin",
        "sqrt", "tan",
    ];
    let ahead: Vec<u8> = cursor.chars[cursor.index..]
        .iter()
        .take(6)
        .map(|c| c.byte)
        .collect();
    NAMES.iter().any(|name| ahead.starts_with(name.as_bytes()))
}

fn display_label(label: &str) -> String {
    if label.bytes().all(|b| b.is_ascii_digit()) {
        label.to_string()
    } else {
        format!("<{label}>")
    }
}

fn read_o_word(cursor: &mut Cursor, params: &dyn Parameters) -> Result<OWord, LineError> {
    let start = cursor.at();
    cursor.index += 1;
    let label = if cursor.peek() == Some(b'<') {
        let open = cursor.index;
        let close = cursor.chars[open..]
            .iter()
            .position(|c| c.byte == b'>')
            .map(|p| p + open)
            .ok_or_else(|| {
                LineError::new(
                    cursor.at(),
                    cursor.line.len(),
                    "expected '>' to close the O-word name",
                )
            })?;
        let label: String = cursor.chars[open + 1..close]
            .iter()
            .map(|c| c.byte as char)
            .collect();
        if label.is_empty() {
            return Err(cursor.error_here("expected a name between '<' and '>'"));
        }
        cursor.index = close + 1;
        label
    } else if matches!(cursor.peek(), Some(b'#' | b'[')) {
        // A numbered label computed from a parameter or expression.
        cursor.integer_value(params)?.to_string()
    } else {
        let number_start = cursor.index;
        while cursor.peek().is_some_and(|b| b.is_ascii_digit()) {
            cursor.index += 1;
        }
        let digits: String = cursor.chars[number_start..cursor.index]
            .iter()
            .map(|c| c.byte as char)
            .collect();
        match normalise_number_label(&digits) {
            Some(label) => label,
            None => {
                return Err(cursor.error_here("expected an O-word number or <name> after 'O'"));
            }
        }
    };
    let rest: Vec<u8> = cursor.chars[cursor.index..]
        .iter()
        .take(9)
        .map(|c| c.byte)
        .collect();
    let Some(&(text, keyword)) = KEYWORDS
        .iter()
        .find(|(text, _)| rest.starts_with(text.as_bytes()))
    else {
        let error = cursor.error_here(
            "expected an O-word keyword (sub endsub call return do while endwhile repeat endrepeat if elseif else endif break continue)",
        );
        return Err(if rest.is_empty() {
            error.hint("Fanuc-style programs (O100 … M99, M98 P100) are not supported; use o100 sub / o100 call")
        } else {
            error
        });
    };
    cursor.index += text.len();
    let mut values = Vec::new();
    while cursor.peek() == Some(b'[') {
        values.push(cursor.expression(params)?);
        if values.len() > 30 {
            return Err(cursor.error_here("expected at most 30 arguments to a subroutine call"));
        }
    }
    let needs_value = matches!(
        keyword,
        Keyword::While | Keyword::If | Keyword::ElseIf | Keyword::Repeat
    );
    if needs_value && values.len() != 1 {
        return Err(LineError::new(
            start,
            cursor.end_of_previous(),
            format!(
                "expected one bracketed condition after '{}', e.g. o{} {} [#1 LT 3]",
                keyword.name(),
                display_label(&label),
                keyword.name()
            ),
        ));
    }
    let takes_values =
        needs_value || matches!(keyword, Keyword::Call | Keyword::Return | Keyword::EndSub);
    if !takes_values && !values.is_empty() {
        return Err(LineError::new(
            start,
            cursor.end_of_previous(),
            format!("expected no value after '{}'", keyword.name()),
        ));
    }
    if matches!(keyword, Keyword::Return | Keyword::EndSub) && values.len() > 1 {
        return Err(LineError::new(
            start,
            cursor.end_of_previous(),
            format!(
                "expected at most one return value after '{}'",
                keyword.name()
            ),
        ));
    }
    Ok(OWord {
        label,
        keyword,
        values,
        start,
        end: cursor.end_of_previous(),
    })
}

fn add_g(block: &mut Block, _line: &[u8], word: Word) -> Result<(), LineError> {
    let value = word.value;
    let tenths = (value * 10.0).floor();
    let fraction = value * 10.0 - tenths;
    let tenths = if fraction > 0.999 {
        tenths + 1.0
    } else if fraction > 0.001 {
        return Err(LineError::new(
            word.start,
            word.end,
            "expected a G code with at most one decimal (e.g. G1, G90.1)",
        ));
    } else {
        tenths
    };
    if !(0.0..=999.0).contains(&tenths) {
        return Err(LineError::new(
            word.start,
            word.end,
            "expected a G code from G0 to G99.9",
        ));
    }
    let code = tenths as u32;
    let name = format_g(code);
    let Some((group, support)) = g_code_info(code) else {
        return Err(LineError::new(
            word.start,
            word.end,
            format!("expected a G code LinuxCNC knows; {name} is not one"),
        ));
    };
    if let Support::No(reason) = support {
        return Err(LineError::new(
            word.start,
            word.end,
            format!("expected a supported G code; {name} is not supported"),
        )
        .hint(reason));
    }
    let entry = CodeWord {
        code,
        start: word.start,
        end: word.end,
    };
    match block.g[group] {
        None => block.g[group] = Some(entry),
        // LinuxCNC: G80 gives way to another motion code in the same block.
        Some(_) if code == 800 => {}
        Some(previous) if previous.code == 800 => block.g[group] = Some(entry),
        Some(previous) => {
            return Err(LineError::new(
                word.start,
                word.end,
                format!(
                "expected one G code of the {} group per block, but {} and {name} are both in it",
                group::name(group),
                format_g(previous.code)
            ),
            )
            .hint("LinuxCNC refuses two codes of one modal group in a block; split the block"));
        }
    }
    Ok(())
}

fn add_m(block: &mut Block, word: Word) -> Result<(), LineError> {
    let value = word.value;
    let rounded = value.round();
    if (value - rounded).abs() > 1e-4 || !(0.0..=10_000.0).contains(&rounded) {
        return Err(LineError::new(
            word.start,
            word.end,
            "expected a whole-number M code",
        ));
    }
    let code = rounded as u32;
    let Some((group, support)) = m_code_info(code) else {
        return Err(LineError::new(
            word.start,
            word.end,
            format!("expected an M code LinuxCNC knows; M{code} is not one"),
        ));
    };
    if let Support::No(reason) = support {
        return Err(LineError::new(
            word.start,
            word.end,
            format!("expected a supported M code; M{code} is not supported"),
        )
        .hint(reason));
    }
    let count = block.m.iter().flatten().count() + usize::from(block.second_coolant.is_some());
    if count >= 5 {
        return Err(LineError::new(
            word.start,
            word.end,
            "expected at most five M codes in one block",
        ));
    }
    let entry = CodeWord {
        code,
        start: word.start,
        end: word.end,
    };
    match block.m[group] {
        None => block.m[group] = Some(entry),
        // M7 and M8 may share a block (mist and flood together).
        Some(previous)
            if group == mgroup::COOLANT
                && block.second_coolant.is_none()
                && matches!((previous.code, code), (7, 8) | (8, 7)) =>
        {
            block.second_coolant = Some(entry)
        }
        Some(previous) => {
            return Err(LineError::new(
                word.start,
                word.end,
                format!(
                "expected one M code of the {} group per block, but M{} and M{code} are both in it",
                mgroup::name(group),
                previous.code
            ),
            )
            .hint("LinuxCNC refuses two codes of one modal group in a block; split the block"));
        }
    }
    Ok(())
}

pub(super) fn format_g(tenths: u32) -> String {
    if tenths.is_multiple_of(10) {
        format!("G{}", tenths / 10)
    } else {
        format!("G{}.{}", tenths / 10, tenths % 10)
    }
}
