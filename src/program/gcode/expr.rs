//! Values of words: numbers, parameters (`#5`, `#<name>`, `#[#1+1]`), bracketed expressions
//! with LinuxCNC's binary operators and precedence, and its unary functions.
//!
//! Precedence, low to high (LinuxCNC `precedence`): `AND OR XOR`; `EQ NE GT GE LT LE`;
//! `+ -`; `* / MOD`; `**`. Operators of one level are applied left to right. Angles are in
//! degrees; comparisons return 1 or 0 and `EQ`/`NE` use LinuxCNC's 0.0001 tolerance.

use super::lexer::Significant;
use super::LineError;
use crate::program::error::{display_text, Found};

/// Highest numbered parameter plus one (LinuxCNC `RS274NGC_MAX_PARAMETERS`).
pub(super) const PARAMETER_COUNT: usize = 5602;

/// Two values compare equal when closer than this (LinuxCNC `TOLERANCE_EQUAL`).
const TOLERANCE_EQUAL: f64 = 0.0001;

/// Deepest nesting of brackets in one expression: far beyond real programs, and it keeps the
/// recursion of the reader bounded.
const MAX_NESTING: usize = 64;

/// Where the reader finds parameter values.
pub(super) trait Parameters {
    /// Numbered parameter `index` (1 ≤ index < [`PARAMETER_COUNT`]).
    fn numbered(&self, index: usize) -> f64;
    /// A named parameter (lower case, without blanks); `Err` says why it has no value.
    fn named(&self, name: &str) -> Result<f64, String>;
    /// Whether a named parameter exists (`EXISTS[#<name>]`).
    fn exists(&self, name: &str) -> bool;
}

/// A parameter to be set: `#12 = …` or `#<name> = …`.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum ParameterRef {
    Numbered(usize),
    Named(String),
}

/// Reads values from a compacted line.
pub(super) struct Cursor<'l> {
    pub line: &'l [u8],
    pub chars: &'l [Significant],
    pub index: usize,
    depth: usize,
}

impl<'l> Cursor<'l> {
    pub fn new(line: &'l [u8], chars: &'l [Significant], index: usize) -> Self {
        Cursor {
            line,
            chars,
            index,
            depth: 0,
        }
    }

    pub fn peek(&self) -> Option<u8> {
        self.chars.get(self.index).map(|c| c.byte)
    }

    fn peek_at(&self, ahead: usize) -> Option<u8> {
        self.chars.get(self.index + ahead).map(|c| c.byte)
    }

    /// Raw byte position of the current character (the line's end when there is none).
    pub fn at(&self) -> usize {
        self.chars.get(self.index).map_or(self.line.len(), |c| c.at)
    }

    /// Raw byte position just after the character before the current one.
    pub fn end_of_previous(&self) -> usize {
        if self.index == 0 {
            return self.at();
        }
        self.chars
            .get(self.index - 1)
            .map_or(self.line.len(), |c| c.at + 1)
    }

    /// An error pointing at the current character (or the end of the line).
    pub fn error_here(&self, problem: impl Into<String>) -> LineError {
        match self.chars.get(self.index) {
            Some(c) => LineError::new(c.at, c.at + 1, problem),
            None => {
                LineError::new(self.line.len(), self.line.len(), problem).found(Found::EndOfLine)
            }
        }
    }

    /// A real value: number, parameter, bracketed expression, unary function, or a sign
    /// before one of those.
    pub fn real_value(&mut self, params: &dyn Parameters) -> Result<f64, LineError> {
        let start = self.at();
        let value = match self.peek() {
            None => {
                return Err(self.error_here("expected a number, parameter or expression"));
            }
            Some(b'[') => self.expression(params)?,
            Some(b'#') => self.parameter_value(params)?,
            Some(sign @ (b'+' | b'-'))
                if self
                    .peek_at(1)
                    .is_some_and(|c| !c.is_ascii_digit() && c != b'.') =>
            {
                self.index += 1;
                self.nest()?;
                let value = self.real_value(params);
                self.depth -= 1;
                let value = value?;
                if sign == b'-' {
                    -value
                } else {
                    value
                }
            }
            Some(b'a'..=b'z') => self.unary(params)?,
            Some(_) => self.number()?,
        };
        if !value.is_finite() {
            return Err(LineError::new(
                start,
                self.end_of_previous(),
                if value.is_nan() {
                    "expected a calculation with a numeric result, it gives 'not a number'"
                } else {
                    "expected a calculation with a finite result, it gives infinity"
                },
            ));
        }
        Ok(value)
    }

    fn nest(&mut self) -> Result<(), LineError> {
        self.depth += 1;
        if self.depth > MAX_NESTING {
            return Err(self.error_here(format!(
                "expected at most {MAX_NESTING} nested brackets, functions or signs"
            )));
        }
        Ok(())
    }

    /// A plain number: optional signs, digits and at most one decimal point.
    pub fn number(&mut self) -> Result<f64, LineError> {
        let first = self.index;
        let mut end = self.index;
        while let Some(b'+' | b'-') = self.chars.get(end).map(|c| c.byte) {
            end += 1;
        }
        let mut digits = 0;
        let mut points = 0;
        while let Some(c) = self.chars.get(end) {
            match c.byte {
                b'0'..=b'9' => digits += 1,
                b'.' => points += 1,
                _ => break,
            }
            end += 1;
        }
        let signs = end - first - digits - points;
        if digits == 0 || points > 1 || signs > 1 {
            let found_end = self.chars.get(end).map_or(self.line.len(), |c| c.at + 1);
            let start = self.at();
            let error = if digits == 0 && end == first {
                self.error_here("expected a number, parameter or expression")
            } else {
                LineError::new(start, found_end.max(start + 1), "expected a number")
            };
            return Err(error);
        }
        if let Some(value) = exact_decimal(&self.chars[first..end]) {
            self.index = end;
            return Ok(value);
        }
        // The compacted characters are ASCII digits, signs and a point: parse them directly.
        let mut text = [0u8; 64];
        let count = end - first;
        let value = if count <= text.len() {
            for (slot, c) in text.iter_mut().zip(&self.chars[first..end]) {
                *slot = c.byte;
            }
            std::str::from_utf8(&text[..count])
                .ok()
                .and_then(|t| t.parse::<f64>().ok())
        } else {
            let owned: String = self.chars[first..end]
                .iter()
                .map(|c| c.byte as char)
                .collect();
            owned.parse::<f64>().ok()
        };
        self.index = end;
        value.ok_or_else(|| {
            LineError::new(
                self.chars[first].at,
                self.end_of_previous(),
                "expected a number",
            )
        })
    }

    /// A value that must be a whole number (within 0.0001, as LinuxCNC's
    /// `read_integer_value`).
    pub fn integer_value(&mut self, params: &dyn Parameters) -> Result<i64, LineError> {
        let start = self.at();
        let value = self.real_value(params)?;
        whole_number(value)
            .ok_or_else(|| LineError::new(start, self.end_of_previous(), "expected a whole number"))
    }

    /// `#…` as a value.
    fn parameter_value(&mut self, params: &dyn Parameters) -> Result<f64, LineError> {
        let start = self.at();
        if self.peek_at(1) == Some(b'<') {
            // A named parameter, looked up without allocating for names of usual length.
            self.index += 1;
            let (first, end) = self.name_range()?;
            let mut buffer = [0u8; 64];
            let chars = &self.chars[first..end];
            let owned;
            let name = if chars.len() <= buffer.len() {
                for (slot, c) in buffer.iter_mut().zip(chars) {
                    *slot = c.byte;
                }
                std::str::from_utf8(&buffer[..chars.len()]).unwrap_or("")
            } else {
                owned = chars.iter().map(|c| c.byte as char).collect::<String>();
                owned.as_str()
            };
            return params.named(name).map_err(|problem| {
                LineError::new(start, self.end_of_previous(), problem)
                    .hint("assign it first, e.g. #<name> = 0 (names without '_' are local to their subroutine)")
            });
        }
        match self.parameter_ref(params)? {
            ParameterRef::Numbered(index) => Ok(params.numbered(index)),
            ParameterRef::Named(name) => params.named(&name).map_err(|problem| {
                LineError::new(start, self.end_of_previous(), problem)
                    .hint("assign it first, e.g. #<name> = 0 (names without '_' are local to their subroutine)")
            }),
        }
    }

    /// `#` followed by a number, an expression, another parameter or `<name>`.
    pub fn parameter_ref(&mut self, params: &dyn Parameters) -> Result<ParameterRef, LineError> {
        debug_assert_eq!(self.peek(), Some(b'#'));
        let hash = self.at();
        self.index += 1;
        if self.peek() == Some(b'<') {
            return Ok(ParameterRef::Named(self.name()?));
        }
        self.nest()?;
        let index = self.integer_value(params);
        self.depth -= 1;
        let index = index?;
        if index < 1 || index >= PARAMETER_COUNT as i64 {
            return Err(LineError::new(
                hash,
                self.end_of_previous(),
                format!(
                    "expected a parameter number from 1 to {}, not {index}",
                    PARAMETER_COUNT - 1
                ),
            ));
        }
        Ok(ParameterRef::Numbered(index as usize))
    }

    /// `<name>` (the compacted characters: lower case, blanks removed).
    fn name(&mut self) -> Result<String, LineError> {
        let (start, end) = self.name_range()?;
        Ok(self.chars[start..end]
            .iter()
            .map(|c| c.byte as char)
            .collect())
    }

    /// The character range of a `<name>`, moving past its `>`.
    fn name_range(&mut self) -> Result<(usize, usize), LineError> {
        let open = self.at();
        self.index += 1;
        let start = self.index;
        let Some(length) = self.chars[start..].iter().position(|c| c.byte == b'>') else {
            return Err(LineError::new(
                open,
                self.line.len(),
                "expected '>' to close the parameter name",
            ));
        };
        self.index = start + length + 1;
        if length == 0 {
            return Err(LineError::new(
                open,
                self.end_of_previous(),
                "expected a parameter name between '<' and '>'",
            ));
        }
        Ok((start, start + length))
    }

    /// `[ value op value op … ]` with LinuxCNC's precedence.
    pub fn expression(&mut self, params: &dyn Parameters) -> Result<f64, LineError> {
        debug_assert_eq!(self.peek(), Some(b'['));
        self.index += 1;
        self.nest()?;
        let result = self.expression_body(params);
        self.depth -= 1;
        result
    }

    fn expression_body(&mut self, params: &dyn Parameters) -> Result<f64, LineError> {
        // Operators on the stack rise strictly in precedence (five levels), so fixed stacks
        // suffice.
        let mut values = [0.0f64; 8];
        let mut operators = [(Operator::Close, 0usize); 8];
        let (mut value_count, mut operator_count) = (1, 0);
        values[0] = self.real_value(params)?;
        loop {
            let at = self.at();
            let operator = self.operator()?;
            while operator_count > 0 {
                let (top, top_at) = operators[operator_count - 1];
                if top.precedence() < operator.precedence() {
                    break;
                }
                operator_count -= 1;
                let right = values[value_count - 1];
                let left = values[value_count - 2];
                value_count -= 1;
                values[value_count - 1] = apply(top, left, right, top_at, self)?;
            }
            if operator == Operator::Close {
                return Ok(values[value_count - 1]);
            }
            operators[operator_count] = (operator, at);
            operator_count += 1;
            values[value_count] = self.real_value(params)?;
            value_count += 1;
        }
    }

    fn operator(&mut self) -> Result<Operator, LineError> {
        let Some(first) = self.peek() else {
            return Err(self
                .error_here("expected ']' or an operator in the expression")
                .hint("every '[' needs a matching ']'"));
        };
        let next = self.peek_at(1);
        let next2 = self.peek_at(2);
        let (operator, length) = match (first, next, next2) {
            (b']', _, _) => (Operator::Close, 1),
            (b'+', _, _) => (Operator::Plus, 1),
            (b'-', _, _) => (Operator::Minus, 1),
            (b'/', _, _) => (Operator::Divide, 1),
            (b'*', Some(b'*'), _) => (Operator::Power, 2),
            (b'*', _, _) => (Operator::Times, 1),
            (b'a', Some(b'n'), Some(b'd')) => (Operator::And, 3),
            (b'm', Some(b'o'), Some(b'd')) => (Operator::Modulo, 3),
            (b'o', Some(b'r'), _) => (Operator::Or, 2),
            (b'x', Some(b'o'), Some(b'r')) => (Operator::Xor, 3),
            (b'e', Some(b'q'), _) => (Operator::Eq, 2),
            (b'n', Some(b'e'), _) => (Operator::Ne, 2),
            (b'g', Some(b'e'), _) => (Operator::Ge, 2),
            (b'g', Some(b't'), _) => (Operator::Gt, 2),
            (b'l', Some(b'e'), _) => (Operator::Le, 2),
            (b'l', Some(b't'), _) => (Operator::Lt, 2),
            _ => {
                return Err(self.error_here(
                    "expected ']' or an operator (+ - * / ** MOD AND OR XOR EQ NE GT GE LT LE)",
                ));
            }
        };
        self.index += length;
        Ok(operator)
    }

    /// A function: `ABS[…]`, `ATAN[…]/[…]`, `EXISTS[#<name>]`, …
    fn unary(&mut self, params: &dyn Parameters) -> Result<f64, LineError> {
        let start = self.at();
        let mut name = [0u8; 6];
        let mut length = 0;
        while let Some(byte @ b'a'..=b'z') = self.peek_at(length) {
            if length == name.len() {
                break;
            }
            name[length] = byte;
            length += 1;
        }
        let function = FUNCTIONS
            .iter()
            .find(|(text, _)| name[..length].starts_with(text.as_bytes()))
            .map(|&(text, function)| (text.len(), function));
        let Some((length, function)) = function else {
            return Err(LineError::new(
                start,
                start + 1,
                "expected a number, parameter, expression or function (ABS ACOS ASIN ATAN COS EXISTS EXP FIX FUP LN ROUND SIN SQRT TAN)",
            ));
        };
        self.index += length;
        if self.peek() != Some(b'[') {
            return Err(self.error_here(format!(
                "expected '[' after the function {}",
                display_text(&self.line[start..self.end_of_previous()]).to_uppercase()
            )));
        }
        if function == Function::Exists {
            self.index += 1;
            if self.peek() != Some(b'#') {
                return Err(self.error_here("expected a parameter (#…) inside EXISTS[…]"));
            }
            let exists = if self.peek_at(1) == Some(b'<') {
                match self.parameter_ref(params)? {
                    ParameterRef::Named(name) => params.exists(&name),
                    ParameterRef::Numbered(_) => true,
                }
            } else {
                // A number (LinuxCNC: whether it is in range); errors inside it count.
                self.index += 1;
                let index = self.integer_value(params)?;
                (1..PARAMETER_COUNT as i64).contains(&index)
            };
            if self.peek() != Some(b']') {
                return Err(self.error_here("expected ']' to close EXISTS[…]"));
            }
            self.index += 1;
            return Ok(if exists { 1.0 } else { 0.0 });
        }
        let argument = self.expression(params)?;
        let end = self.end_of_previous();
        let domain = |problem: &str| Err(LineError::new(start, end, problem.to_string()));
        let value = match function {
            Function::Abs => argument.abs(),
            Function::Acos if !(-1.0..=1.0).contains(&argument) => {
                return domain("expected an ACOS argument from -1 to 1");
            }
            Function::Acos => argument.acos().to_degrees(),
            Function::Asin if !(-1.0..=1.0).contains(&argument) => {
                return domain("expected an ASIN argument from -1 to 1");
            }
            Function::Asin => argument.asin().to_degrees(),
            Function::Atan => {
                if self.peek() != Some(b'/') {
                    return Err(self.error_here("expected '/' after ATAN[…] (ATAN[y]/[x])"));
                }
                self.index += 1;
                if self.peek() != Some(b'[') {
                    return Err(self.error_here("expected '[' for the second argument of ATAN"));
                }
                let x = self.expression(params)?;
                argument.atan2(x).to_degrees()
            }
            Function::Cos => argument.to_radians().cos(),
            Function::Exp => argument.exp(),
            Function::Fix => argument.floor(),
            Function::Fup => argument.ceil(),
            Function::Ln if argument <= 0.0 => {
                return domain("expected a positive argument to LN");
            }
            Function::Ln => argument.ln(),
            // LinuxCNC rounds halves away from zero.
            Function::Round => argument.round(),
            Function::Sin => argument.to_radians().sin(),
            Function::Sqrt if argument < 0.0 => {
                return domain("expected a SQRT argument of zero or more");
            }
            Function::Sqrt => argument.sqrt(),
            Function::Tan => argument.to_radians().tan(),
            Function::Exists => unreachable!("handled above"),
        };
        Ok(value)
    }
}

/// A number of at most 15 significant digits and 22 decimals, converted with one correctly
/// rounded division (the same value `str::parse` gives, faster); `None` for anything else.
fn exact_decimal(chars: &[Significant]) -> Option<f64> {
    const POWERS: [f64; 23] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
        1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
    ];
    let mut negative = false;
    let mut digits = chars;
    if let Some(first) = digits.first() {
        if first.byte == b'-' || first.byte == b'+' {
            negative = first.byte == b'-';
            digits = &digits[1..];
        }
    }
    let mut mantissa: u64 = 0;
    let mut significant = 0;
    let mut decimals: Option<usize> = None;
    for c in digits {
        match c.byte {
            b'0'..=b'9' => {
                if mantissa != 0 || c.byte != b'0' {
                    significant += 1;
                }
                mantissa = mantissa * 10 + u64::from(c.byte - b'0');
                if let Some(d) = &mut decimals {
                    *d += 1;
                }
                if significant > 15 {
                    return None;
                }
            }
            b'.' if decimals.is_none() => decimals = Some(0),
            _ => return None,
        }
    }
    let scale = *POWERS.get(decimals.unwrap_or(0))?;
    let value = mantissa as f64 / scale;
    Some(if negative { -value } else { value })
}

/// `value` as a whole number if it is one within LinuxCNC's tolerance.
pub(super) fn whole_number(value: f64) -> Option<i64> {
    if !value.is_finite() || value.abs() > 1e15 {
        return None;
    }
    let floor = value.floor();
    let fraction = value - floor;
    if fraction > 0.9999 {
        Some(value.ceil() as i64)
    } else if fraction > 0.0001 {
        None
    } else {
        Some(floor as i64)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Operator {
    Close,
    And,
    Or,
    Xor,
    Eq,
    Ne,
    Gt,
    Ge,
    Lt,
    Le,
    Plus,
    Minus,
    Times,
    Divide,
    Modulo,
    Power,
}

impl Operator {
    fn precedence(self) -> u8 {
        match self {
            Operator::Close => 1,
            Operator::And | Operator::Or | Operator::Xor => 2,
            Operator::Eq
            | Operator::Ne
            | Operator::Gt
            | Operator::Ge
            | Operator::Lt
            | Operator::Le => 3,
            Operator::Plus | Operator::Minus => 4,
            Operator::Times | Operator::Divide | Operator::Modulo => 5,
            Operator::Power => 6,
        }
    }
}

fn apply(
    operator: Operator,
    left: f64,
    right: f64,
    at: usize,
    cursor: &Cursor,
) -> Result<f64, LineError> {
    let truth = |b: bool| if b { 1.0 } else { 0.0 };
    let value = match operator {
        Operator::Close => unreachable!("never applied"),
        Operator::And => truth(left != 0.0 && right != 0.0),
        Operator::Or => truth(left != 0.0 || right != 0.0),
        Operator::Xor => truth((left != 0.0) != (right != 0.0)),
        Operator::Eq => truth((left - right).abs() < TOLERANCE_EQUAL),
        Operator::Ne => truth((left - right).abs() >= TOLERANCE_EQUAL),
        Operator::Gt => truth(left > right),
        Operator::Ge => truth(left >= right),
        Operator::Lt => truth(left < right),
        Operator::Le => truth(left <= right),
        Operator::Plus => left + right,
        Operator::Minus => left - right,
        Operator::Times => left * right,
        Operator::Divide if right == 0.0 => {
            return Err(LineError::new(
                at,
                cursor.end_of_previous(),
                "expected a non-zero divisor",
            )
            .found(Found::Text(format!("{left} / 0"))));
        }
        Operator::Divide => left / right,
        Operator::Modulo => {
            // LinuxCNC's MOD always gives a result of zero or more.
            let rest = left % right;
            if rest < 0.0 {
                rest + right.abs()
            } else {
                rest
            }
        }
        Operator::Power if left < 0.0 && right.floor() != right => {
            return Err(LineError::new(
                at,
                cursor.end_of_previous(),
                "expected a whole-number power of a negative number",
            )
            .found(Found::Text(format!("{left} ** {right}"))));
        }
        Operator::Power => left.powf(right),
    };
    Ok(value)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Function {
    Abs,
    Acos,
    Asin,
    Atan,
    Cos,
    Exists,
    Exp,
    Fix,
    Fup,
    Ln,
    Round,
    Sin,
    Sqrt,
    Tan,
}

/// Function names; longer names first where one is a prefix of another.
const FUNCTIONS: [(&str, Function); 14] = [
    ("abs", Function::Abs),
    ("acos", Function::Acos),
    ("asin", Function::Asin),
    ("atan", Function::Atan),
    ("cos", Function::Cos),
    ("exists", Function::Exists),
    ("exp", Function::Exp),
    ("fix", Function::Fix),
    ("fup", Function::Fup),
    ("ln", Function::Ln),
    ("round", Function::Round),
    ("sin", Function::Sin),
    ("sqrt", Function::Sqrt),
    ("tan", Function::Tan),
];
