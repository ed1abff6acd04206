//! The bytes of a plot file as HPGL sees them: two-letter commands with their parameters
//! (numbers, quoted strings, label text, encoded polylines), HP device-control escapes, and
//! the PCL / PJL wrappers that HP-GL/2 printer drivers put around the plot.
//!
//! The scanner only splits and decodes; what a command means is the reader's business.

/// ASCII ETX, the default label terminator.
pub(super) const ETX: u8 = 0x03;
pub(super) const ESC: u8 = 0x1b;

/// A numeric parameter and where it was.
#[derive(Debug, Clone, Copy)]
pub(super) struct Parameter {
    pub(super) value: f64,
    pub(super) start: usize,
    pub(super) end: usize,
}

/// A scanning problem: the byte range it points at and what was expected.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ScanError {
    pub(super) start: usize,
    pub(super) end: usize,
    pub(super) problem: String,
}

/// What an escape sequence was.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Escape {
    /// `ESC . x …`: HP plotter device control (handshake, buffers, plotter on/off).
    DeviceControl,
    /// `ESC % n B`: enter HP-GL/2 from PCL.
    EnterHpgl,
    /// `ESC % n A`: return to PCL.
    EnterPcl,
    /// `ESC % -12345 X`: the universal exit language; PJL lines may follow.
    UniversalExit,
    /// `ESC E`: PCL printer reset.
    PclReset,
    /// Any other PCL command (page size, resolution, colour set-up), data skipped.
    PclControl,
    /// PCL raster row data (`ESC * b n W`, `… V`) with `n` > 0 bytes: a raster image.
    PclRaster,
}

pub(super) struct Scanner<'a> {
    pub(super) text: &'a [u8],
    pub(super) at: usize,
    /// Read parameters as plotters and hp2xx do: empty parameters (`PA,PU`, `PD1,,2`) are
    /// passed over.
    lenient: bool,
}

impl<'a> Scanner<'a> {
    pub(super) fn new(text: &'a [u8], lenient: bool) -> Self {
        Scanner {
            text,
            at: 0,
            lenient,
        }
    }

    /// An unquoted `CO` comment (some drivers write `CO text;`): to the terminator, an
    /// escape or the end of the line. Returns whether there was one.
    pub(super) fn unquoted_comment(&mut self) -> bool {
        let mut at = self.at;
        while matches!(self.text.get(at), Some(b' ' | b'\t')) {
            at += 1;
        }
        match self.text.get(at) {
            None | Some(b'"' | b';') => return false,
            Some(_) => {}
        }
        while let Some(&byte) = self.text.get(at) {
            if byte == b';' {
                at += 1;
                break;
            }
            if byte == ESC || byte == b'\n' {
                break;
            }
            at += 1;
        }
        self.at = at;
        true
    }

    pub(super) fn peek(&self) -> Option<u8> {
        self.text.get(self.at).copied()
    }

    /// End of the UTF-8 character starting at `start` (for quoting it in messages).
    pub(super) fn char_end(&self, start: usize) -> usize {
        let mut end = (start + 1).min(self.text.len());
        while end < self.text.len() && end - start < 4 && (self.text[end] & 0xC0) == 0x80 {
            end += 1;
        }
        end
    }

    fn skip_blanks(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\r' | b'\n')) {
            self.at += 1;
        }
    }

    /// After an error: resume at the next command terminator or escape.
    pub(super) fn skip_to_terminator(&mut self) {
        while let Some(byte) = self.peek() {
            if byte == b';' || byte == ESC {
                return;
            }
            self.at += 1;
        }
    }

    /// The two letters of a command, upper-cased; the scanner stands on the first.
    pub(super) fn mnemonic(&mut self) -> Result<[u8; 2], ScanError> {
        let start = self.at;
        let first = self.text[start].to_ascii_uppercase();
        match self.text.get(start + 1) {
            Some(b) if b.is_ascii_alphabetic() => {
                self.at = start + 2;
                Ok([first, b.to_ascii_uppercase()])
            }
            _ => {
                let end = self
                    .char_end(start + 1)
                    .max((start + 2).min(self.text.len()));
                self.at = start + 1;
                Err(ScanError {
                    start,
                    end,
                    problem: "expected a two-letter HPGL command".into(),
                })
            }
        }
    }

    /// The parameters of a command: numbers separated by commas or blanks (a sign also
    /// separates, `PA10-20`), ended by ';', the next command's letters, ESC or the end of the
    /// file. A comma before the end is allowed (`PD1,2,;`), as plotters allow it. With
    /// `strings`, quoted strings (`BP1,"name"`, `CO"text"`) are passed over.
    pub(super) fn parameters(
        &mut self,
        name: &str,
        strings: bool,
    ) -> Result<Vec<Parameter>, ScanError> {
        let mut parameters = Vec::new();
        let mut after_comma = false;
        loop {
            self.skip_blanks();
            match self.peek() {
                Some(b'0'..=b'9' | b'+' | b'-' | b'.') => {
                    let start = self.at;
                    match self.number() {
                        Some(value) => parameters.push(Parameter {
                            value,
                            start,
                            end: self.at,
                        }),
                        None => {
                            let end = self.char_end(start).max(self.at);
                            return Err(ScanError {
                                start,
                                end,
                                problem: format!("expected a number of at most 1e9 in magnitude in the parameters of {name}"),
                            });
                        }
                    }
                    after_comma = false;
                }
                Some(b'"') if strings => {
                    let start = self.at;
                    match self.text[start + 1..].iter().position(|&b| b == b'"') {
                        Some(length) => self.at = start + 1 + length + 1,
                        None => {
                            return Err(ScanError {
                                start,
                                end: self.text.len(),
                                problem: format!(
                                    "expected '\"' to close the string in the parameters of {name}"
                                ),
                            })
                        }
                    }
                    after_comma = false;
                }
                Some(b',') if !after_comma && (!parameters.is_empty() || strings) => {
                    self.at += 1;
                    after_comma = true;
                }
                // An empty parameter: passed over, as plotters and hp2xx do.
                Some(b',') if self.lenient => {
                    self.at += 1;
                    after_comma = true;
                }
                // A comma may stand before the terminator, not before the next command.
                Some(b';') => {
                    self.at += 1;
                    return Ok(parameters);
                }
                None | Some(ESC) => return Ok(parameters),
                // After a comma, only the next command's two letters end the parameters
                // (`PA,PU…`, lenient only).
                Some(b)
                    if b.is_ascii_alphabetic()
                        && (!after_comma
                            || (self.lenient
                                && self
                                    .text
                                    .get(self.at + 1)
                                    .is_some_and(u8::is_ascii_alphabetic))) =>
                {
                    return Ok(parameters)
                }
                // Stray punctuation (`PD:`) ends the parameters; the reader passes over it
                // between commands with a warning, as plotters and hp2xx do. Not before a
                // number (`PA10*20`): that is a damaged coordinate.
                Some(b)
                    if self.lenient
                        && !after_comma
                        && b.is_ascii_punctuation()
                        && b != b'"'
                        && !self.text.get(self.at + 1).is_some_and(|next| {
                            next.is_ascii_digit() || matches!(next, b'+' | b'-' | b'.')
                        }) =>
                {
                    return Ok(parameters)
                }
                _ => {
                    let what = if after_comma {
                        "a number after ','"
                    } else {
                        "',', ';' or a number"
                    };
                    let end = self.char_end(self.at);
                    return Err(ScanError {
                        start: self.at,
                        end,
                        problem: format!("expected {what} in the parameters of {name}"),
                    });
                }
            }
        }
    }

    /// A decimal number: optional sign, digits with an optional point; at most 1e9.
    fn number(&mut self) -> Option<f64> {
        let start = self.at;
        if matches!(self.peek(), Some(b'+' | b'-')) {
            self.at += 1;
        }
        let mut digits = 0;
        let mut point = false;
        while let Some(b) = self.peek() {
            match b {
                b'0'..=b'9' => digits += 1,
                b'.' if !point => point = true,
                _ => break,
            }
            self.at += 1;
        }
        if digits == 0 {
            return None;
        }
        let text = std::str::from_utf8(&self.text[start..self.at]).ok()?;
        // Far beyond any plotter; keeps every later sum finite.
        text.parse::<f64>().ok().filter(|v| v.abs() <= 1e9)
    }

    /// Label text up to `terminator` (which is consumed): the byte range of the text and
    /// whether the terminator was found before the end of the file.
    pub(super) fn label_text(&mut self, terminator: u8) -> (usize, usize, bool) {
        let start = self.at;
        match self.text[start..].iter().position(|&b| b == terminator) {
            Some(length) => {
                self.at = start + length + 1;
                (start, start + length, true)
            }
            None => {
                self.at = self.text.len();
                (start, self.text.len(), false)
            }
        }
    }

    /// The parameter of DT: the new label terminator and, in HP-GL/2, whether it is printed
    /// (mode 0) or not (mode 1). `None` for `DT;`, which restores ETX.
    pub(super) fn terminator_definition(&mut self) -> Result<Option<u8>, ScanError> {
        match self.peek() {
            None | Some(b';') => {
                if self.peek().is_some() {
                    self.at += 1;
                }
                Ok(None)
            }
            Some(byte) if byte == 0 || byte == b'\n' || byte == ESC => Err(ScanError {
                start: self.at,
                end: self.at + 1,
                problem: "expected a label terminator character after DT (not NUL, LF, ESC or ';')"
                    .into(),
            }),
            Some(byte) => {
                self.at += 1;
                // An optional mode: ",0" or ",1".
                if self.peek() == Some(b',') {
                    self.at += 1;
                    let start = self.at;
                    match self.number() {
                        Some(mode) if mode == 0.0 || mode == 1.0 => {}
                        _ => {
                            return Err(ScanError {
                                start,
                                end: self.char_end(start).max(self.at),
                                problem: "expected mode 0 or 1 after the DT terminator".into(),
                            })
                        }
                    }
                }
                if self.peek() == Some(b';') {
                    self.at += 1;
                }
                Ok(Some(byte))
            }
        }
    }

    /// The parameter of SM: the symbol character, or `None` for `SM;` (symbol mode off).
    pub(super) fn symbol(&mut self) -> Option<u8> {
        match self.peek() {
            None => None,
            Some(b';') => {
                self.at += 1;
                None
            }
            // A command letter right after SM would be read as the symbol on a plotter too;
            // files that turn symbol mode off write `SM;`.
            Some(byte) => {
                self.at += 1;
                if self.peek() == Some(b';') {
                    self.at += 1;
                }
                (byte > b' ' && byte != ESC).then_some(byte)
            }
        }
    }

    /// The data of PE up to its ';' (consumed): the byte range.
    pub(super) fn encoded(&mut self) -> (usize, usize) {
        let start = self.at;
        match self.text[start..]
            .iter()
            .position(|&b| b == b';' || b == ESC)
        {
            Some(length) => {
                self.at = start + length;
                if self.peek() == Some(b';') {
                    self.at += 1;
                }
                (start, start + length)
            }
            None => {
                self.at = self.text.len();
                (start, self.text.len())
            }
        }
    }

    /// A PJL line (`@PJL …`) up to and including its line feed; the text of the line.
    pub(super) fn line(&mut self) -> (usize, usize) {
        let start = self.at;
        let end = self.text[start..]
            .iter()
            .position(|&b| b == b'\n' || b == ESC)
            .map_or(self.text.len(), |length| start + length);
        self.at = if self.text.get(end) == Some(&b'\n') {
            end + 1
        } else {
            end
        };
        (start, end)
    }

    /// An escape sequence; the scanner stands on ESC.
    pub(super) fn escape(&mut self) -> Result<Escape, ScanError> {
        let start = self.at;
        let fail = |scanner: &mut Scanner, end: usize, problem: &str| {
            scanner.at = end.max(start + 1).min(scanner.text.len());
            Err(ScanError {
                start,
                end: end.min(scanner.text.len()),
                problem: problem.to_string(),
            })
        };
        let Some(&kind) = self.text.get(start + 1) else {
            return fail(self, start + 1, "expected an escape sequence after ESC");
        };
        match kind {
            b'.' => self.device_control(start),
            b'%' => {
                self.at = start + 2;
                let value_start = self.at;
                if matches!(self.peek(), Some(b'+' | b'-')) {
                    self.at += 1;
                }
                while matches!(self.peek(), Some(b'0'..=b'9')) {
                    self.at += 1;
                }
                let value = std::str::from_utf8(&self.text[value_start..self.at])
                    .ok()
                    .and_then(|v| v.parse::<i64>().ok());
                let terminator = self.peek();
                self.at = (self.at + 1).min(self.text.len());
                match (value, terminator) {
                    (Some(-12345), Some(b'X')) => Ok(Escape::UniversalExit),
                    (Some(_), Some(b'B')) => Ok(Escape::EnterHpgl),
                    (Some(_), Some(b'A')) => Ok(Escape::EnterPcl),
                    _ => {
                        let end = self.at;
                        fail(
                            self,
                            end,
                            "expected a PCL language switch (ESC%-12345X, ESC%nB or ESC%nA)",
                        )
                    }
                }
            }
            // Parameterised PCL: ESC, a parameterised character, a group character, then value
            // fields each ended by a parameter character (lower case continues, upper case
            // ends the sequence). Some carry binary data of the given byte count.
            b'!'..=b'/' => {
                self.at = start + 2;
                let group = self.peek();
                if !matches!(group, Some(b'`'..=b'~')) {
                    let end = self.char_end(self.at);
                    return fail(
                        self,
                        end,
                        "expected a PCL group character after ESC and a parameterised character",
                    );
                }
                self.at += 1;
                let mut raster = false;
                loop {
                    let value_start = self.at;
                    while matches!(self.peek(), Some(b'0'..=b'9' | b'+' | b'-' | b'.')) {
                        self.at += 1;
                    }
                    let value = std::str::from_utf8(&self.text[value_start..self.at])
                        .ok()
                        .and_then(|v| v.parse::<f64>().ok())
                        .unwrap_or(0.0);
                    let Some(parameter) = self.peek() else {
                        return fail(
                            self,
                            self.text.len(),
                            "expected a PCL parameter character, found the end of the file",
                        );
                    };
                    if !matches!(parameter, b'`'..=b'~' | b'@'..=b'^') {
                        let end = self.char_end(self.at);
                        return fail(self, end, "expected a PCL parameter character");
                    }
                    self.at += 1;
                    let upper = parameter.to_ascii_uppercase();
                    // Commands followed by `value` bytes of data.
                    let carries_data = upper == b'W'
                        || (kind == b'*' && group == Some(b'b') && upper == b'V')
                        || (kind == b'&' && group == Some(b'p') && upper == b'X');
                    if carries_data {
                        if !(0.0..=1e9).contains(&value) || value.fract() != 0.0 {
                            return fail(
                                self,
                                self.at,
                                "expected a whole byte count in a PCL data command",
                            );
                        }
                        let count = value as usize;
                        if count > self.text.len() - self.at {
                            return fail(self, self.text.len(), "expected as many data bytes as the PCL command announces, found the end of the file");
                        }
                        self.at += count;
                        if kind == b'*' && group == Some(b'b') && count > 0 {
                            raster = true;
                        }
                    }
                    if parameter.is_ascii_uppercase() || matches!(parameter, b'@'..=b'^') {
                        break;
                    }
                }
                Ok(if raster {
                    Escape::PclRaster
                } else {
                    Escape::PclControl
                })
            }
            b'E' => {
                self.at = start + 2;
                Ok(Escape::PclReset)
            }
            // Two-character PCL commands (display functions, half line feeds, …).
            b'0'..=b'~' => {
                self.at = start + 2;
                Ok(Escape::PclControl)
            }
            _ => {
                let end = self.char_end(start + 1);
                fail(
                    self,
                    end,
                    "expected '.' (HP device control), '%' (PCL language switch) or a PCL command after ESC",
                )
            }
        }
    }

    /// HP device-control sequences `ESC . x [params] [:]`, which start AutoCAD's HP 7475
    /// plot files.
    fn device_control(&mut self, start: usize) -> Result<Escape, ScanError> {
        let Some(&kind) = self.text.get(start + 2) else {
            self.at = self.text.len();
            return Err(ScanError {
                start,
                end: self.text.len(),
                problem: "expected a device-control command after ESC '.'".into(),
            });
        };
        self.at = start + 3;
        match kind.to_ascii_uppercase() {
            // Without parameters: plotter on/off, status and output requests, resets.
            b'(' | b')' | b'Y' | b'Z' | b'A' | b'B' | b'E' | b'J' | b'K' | b'L' | b'O' | b'R'
            | b'S' | b'U' => Ok(Escape::DeviceControl),
            // With parameters ending in ':' (handshake, buffer and output settings).
            b'@' | b'H' | b'I' | b'M' | b'N' | b'P' | b'Q' | b'T' => {
                loop {
                    match self.peek() {
                        Some(b':') => {
                            self.at += 1;
                            break;
                        }
                        Some(b) if b.is_ascii_digit() || b == b';' || b == b' ' => self.at += 1,
                        // The sequence may end without ':' when its parameters are left out.
                        _ => break,
                    }
                }
                Ok(Escape::DeviceControl)
            }
            _ => {
                let end = self.char_end(start + 2);
                Err(ScanError {
                    start,
                    end,
                    problem: "expected a known HP device-control sequence (ESC . followed by ( ) @ A B E H I J K L M N O P Q R S T U Y Z)".into(),
                })
            }
        }
    }
}
