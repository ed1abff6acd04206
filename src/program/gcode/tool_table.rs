//! LinuxCNC tool table files (`tool.tbl`): one tool per line, `T1 P1 Z50.0 D6.0 ;comment`,
//! lengths in the machine's units. cncsim reads the tool number (T), the offsets (X Y Z, and
//! A B C in degrees) and the diameter (D); the pocket (P), lathe angles (I J) and orientation
//! (Q) are accepted and not used.

use std::path::Path;

use crate::program::error::{ErrorSink, ProgramError, ProgramErrors};
use crate::program::options::{LengthUnit, ToolSpec};
use crate::program::source::{char_column, saturate};
use crate::program::types::Span;

/// Reads a tool table whose lengths are in `units`.
pub fn parse_tool_table(
    text: &str,
    source: impl AsRef<Path>,
    units: LengthUnit,
) -> Result<Vec<ToolSpec>, ProgramErrors> {
    let source = source.as_ref();
    let mut errors = ErrorSink::new(100);
    let mut tools: Vec<ToolSpec> = Vec::new();
    let mut offset = 0;
    for (index, line) in text.split_inclusive('\n').enumerate() {
        let content = line.split(';').next().unwrap_or("");
        let span_at = |byte: usize| Span {
            line: saturate(index + 1),
            column: char_column(line.as_bytes(), byte),
            byte_offset: saturate(offset + byte),
        };
        let mut tool = ToolSpec::default();
        let mut number = None;
        let mut position = 0;
        for word in content.split_whitespace() {
            let at = content[position..]
                .find(word)
                .map_or(position, |p| p + position);
            position = at + word.len();
            let error = |problem: String| {
                ProgramError::new(source, Some(span_at(at)), problem).found_text(word.as_bytes())
            };
            let (letter, value) = word.split_at(word.chars().next().map_or(0, char::len_utf8));
            let Ok(value) = value.parse::<f64>() else {
                errors.push(error(
                    "expected a letter followed by a number (e.g. T1, Z50.0)".to_string(),
                ));
                continue;
            };
            if !value.is_finite() {
                errors.push(error("expected a finite number".to_string()));
                continue;
            }
            match letter.to_ascii_uppercase().as_str() {
                "T" => {
                    if value < 0.0 || value.fract() != 0.0 || value > f64::from(u32::MAX) {
                        errors.push(error(
                            "expected a whole tool number of 0 or more after T".to_string(),
                        ));
                        continue;
                    }
                    number = Some(value as u32);
                }
                "X" => tool.offset.linear[0] = units.to_metres(value),
                "Y" => tool.offset.linear[1] = units.to_metres(value),
                "Z" => tool.offset.linear[2] = units.to_metres(value),
                "A" => tool.offset.rotary[0] = value.to_radians(),
                "B" => tool.offset.rotary[1] = value.to_radians(),
                "C" => tool.offset.rotary[2] = value.to_radians(),
                "D" => tool.diameter = units.to_metres(value),
                "P" | "I" | "J" | "Q" | "U" | "V" | "W" => {}
                _ => errors.push(error(
                    "expected a tool table word (T P X Y Z A B C U V W D I J Q)".to_string(),
                )),
            }
        }
        match number {
            Some(number) => {
                tool.number = number;
                if tools.iter().any(|t| t.number == number) {
                    errors.push(ProgramError::new(
                        source,
                        Some(span_at(0)),
                        format!("expected each tool once; T{number} is listed again"),
                    ));
                } else {
                    tools.push(tool);
                }
            }
            None if !content.trim().is_empty() => errors.push(ProgramError::new(
                source,
                Some(span_at(0)),
                "expected a T word (tool number) on every tool table line",
            )),
            None => {}
        }
        offset += line.len();
    }
    errors.finish(tools)
}
