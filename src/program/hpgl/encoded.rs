//! HP-GL/2 polyline encoded (`PE`) data, as Windows plotter drivers write nearly every vector:
//! flags (`:` pen, `<` pen up, `>` fractional bits, `=` absolute, `7` seven-bit mode) and
//! numbers in base 64 (or 32), least significant digit first, sign in the lowest bit.

use super::scan::ScanError;

/// One decoded element of a PE command, with the byte offset it started at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Encoded {
    /// `:` select this pen.
    Pen { number: f64, at: usize },
    /// A coordinate pair: relative to the pen unless `absolute`; drawn unless `pen_up`.
    Point {
        xy: [f64; 2],
        absolute: bool,
        pen_up: bool,
        at: usize,
    },
}

/// Decodes the data of one PE command (`text[start..end]`, without its ';').
/// With `lenient`, data that end in an unfinished number (no terminating digit before the
/// end) decode to what came before it, and the offset of the unfinished number is returned.
pub(super) fn decode(
    text: &[u8],
    start: usize,
    end: usize,
    lenient: bool,
) -> Result<(Vec<Encoded>, Option<usize>), ScanError> {
    let mut out = Vec::new();
    let mut at = start;
    let mut base: u64 = 64;
    let mut fraction_bits: u32 = 0;
    let mut pen_up_next = false;
    let mut absolute_next = false;
    // The first coordinate of a pair waiting for its second.
    let mut pending: Option<(f64, usize)> = None;
    let error = |at: usize, problem: &str| ScanError {
        start: at,
        end: (at + 1).min(end.max(at + 1)),
        problem: problem.to_string(),
    };
    while at < end {
        let byte = text[at];
        match byte {
            b':' | b'>' => {
                if pending.is_some() {
                    return Err(error(
                        at,
                        "expected the second coordinate of a pair in PE before a flag",
                    ));
                }
                let flag_at = at;
                let (value, next) = number(text, at + 1, end, base, 0)
                    .ok_or_else(|| error(at + 1, "expected a number after the PE flag"))??;
                at = next;
                if byte == b':' {
                    out.push(Encoded::Pen {
                        number: value,
                        at: flag_at,
                    });
                } else {
                    if !(0.0..=26.0).contains(&value) || value.fract() != 0.0 {
                        return Err(error(
                            flag_at,
                            "expected 0 to 26 fractional bits after '>' in PE",
                        ));
                    }
                    fraction_bits = value as u32;
                }
            }
            b'<' | b'=' | b'7' => {
                if pending.is_some() {
                    return Err(error(
                        at,
                        "expected the second coordinate of a pair in PE before a flag",
                    ));
                }
                match byte {
                    b'<' => pen_up_next = true,
                    b'=' => absolute_next = true,
                    _ => base = 32,
                }
                at += 1;
            }
            63..=254 => {
                let value_at = at;
                let (value, next) = match number(text, at, end, base, fraction_bits) {
                    None => return Err(error(at, "expected a PE number")),
                    Some(Err(problem)) if lenient && problem.problem == UNFINISHED => {
                        // Nothing after it decodes; the pair it would finish is dropped too.
                        let dropped = pending.map_or(value_at, |(_, x_at)| x_at);
                        return Ok((out, Some(dropped)));
                    }
                    Some(result) => result?,
                };
                at = next;
                match pending.take() {
                    None => pending = Some((value, value_at)),
                    Some((x, x_at)) => {
                        out.push(Encoded::Point {
                            xy: [x, value],
                            absolute: absolute_next,
                            pen_up: pen_up_next,
                            at: x_at,
                        });
                        absolute_next = false;
                        pen_up_next = false;
                    }
                }
            }
            // Blanks and line breaks inside the data are ignored, as plotters do.
            b' ' | b'\t' | b'\r' | b'\n' => at += 1,
            _ => {
                return Err(error(
                    at,
                    "expected PE data (a flag : < > = 7, or a digit byte of 63 or more)",
                ))
            }
        }
    }
    if let Some((_, x_at)) = pending {
        return Err(error(
            x_at,
            "expected x,y pairs in PE: an odd number of coordinates",
        ));
    }
    Ok((out, None))
}

/// PE data whose bytes were re-encoded as UTF-8 after the driver wrote them (a text tool
/// read the file as Latin-1 and saved it as UTF-8): the bytes the driver wrote and, for each,
/// the offset in `text` it came from. `None` unless the data are exactly that: they hold a
/// byte no PE data can hold (0x80–0xBE, a UTF-8 continuation byte), and they are valid UTF-8
/// whose characters are all below U+0100, so undoing it is exact.
pub(super) fn undo_utf8(text: &[u8], start: usize, end: usize) -> Option<(Vec<u8>, Vec<usize>)> {
    let data = &text[start..end];
    if !data.iter().any(|b| (0x80..=0xBE).contains(b)) {
        return None;
    }
    let decoded = std::str::from_utf8(data).ok()?;
    let mut bytes = Vec::with_capacity(data.len());
    let mut offsets = Vec::with_capacity(data.len());
    for (index, ch) in decoded.char_indices() {
        let byte = u8::try_from(u32::from(ch)).ok()?;
        bytes.push(byte);
        offsets.push(start + index);
    }
    Some((bytes, offsets))
}

const UNFINISHED: &str = "expected a terminating digit to end the PE number";

/// One encoded number starting at `at`: its value and the index after it. `None` if no digit
/// byte is there; an error if the number does not end within the data or is too large.
fn number(
    text: &[u8],
    mut at: usize,
    end: usize,
    base: u64,
    fraction_bits: u32,
) -> Option<Result<(f64, usize), ScanError>> {
    // Non-terminating digits, then terminating digits (the last of a number).
    let (digits, terminating) = if base == 64 {
        (63..=126, 191..=254)
    } else {
        (63..=94, 95..=126)
    };
    let start = at;
    let mut magnitude: u64 = 0;
    let mut weight: u64 = 1;
    loop {
        let Some(&byte) = text.get(at).filter(|_| at < end) else {
            return (at > start).then(|| {
                Err(ScanError {
                    start,
                    end: at,
                    problem: UNFINISHED.into(),
                })
            });
        };
        let ends = terminating.contains(&byte);
        if !ends && !digits.contains(&byte) {
            return if at == start {
                None
            } else {
                Some(Err(ScanError {
                    start,
                    end: at,
                    problem: UNFINISHED.into(),
                }))
            };
        }
        let digit = if ends {
            u64::from(byte - terminating.start())
        } else {
            u64::from(byte - 63)
        };
        // Nine base-64 digits already exceed anything a plotter addresses.
        if at - start >= 9 {
            return Some(Err(ScanError {
                start,
                end: at + 1,
                problem: "expected a PE number of at most 9 digits".into(),
            }));
        }
        magnitude += digit * weight;
        weight *= base;
        at += 1;
        if ends {
            break;
        }
    }
    let half = (magnitude >> 1) as f64;
    let value = if magnitude & 1 == 1 { -half } else { half };
    Some(Ok((value / f64::from(1u32 << fraction_bits), at)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Encodes as HP's PCL 5 reference describes: sign in bit 0, base-64 digits.
    fn encode(value: i64) -> Vec<u8> {
        let mut n = (value.unsigned_abs() << 1) | u64::from(value < 0);
        let mut out = Vec::new();
        loop {
            let digit = (n % 64) as u8;
            n /= 64;
            if n == 0 {
                out.push(191 + digit);
                return out;
            }
            out.push(63 + digit);
        }
    }

    #[test]
    fn decodes_pairs_flags_and_signs() {
        let mut data = vec![b'<', b'='];
        data.extend(encode(1000));
        data.extend(encode(-2000));
        data.extend(encode(5));
        data.extend(encode(-7));
        data.push(b':');
        data.extend(encode(2));
        let decoded = decode(&data, 0, data.len(), false).unwrap().0;
        assert_eq!(
            decoded,
            vec![
                Encoded::Point {
                    xy: [1000.0, -2000.0],
                    absolute: true,
                    pen_up: true,
                    at: 2
                },
                Encoded::Point {
                    xy: [5.0, -7.0],
                    absolute: false,
                    pen_up: false,
                    at: 2 + encode(1000).len() + encode(-2000).len()
                },
                Encoded::Pen {
                    number: 2.0,
                    at: data.len() - 2
                },
            ]
        );
    }

    #[test]
    fn seven_bit_mode_and_fractions() {
        // 7-bit: digits 63..94 and terminators 95..126; 3 fractional bits: 12 / 8 = 1.5.
        // 3 is sent as 6 (sign bit), 12 as 24: single terminating digits 95 + 6 and 95 + 24.
        let data = [b'7', b'>', 95 + 6, 119, 119];
        let decoded = decode(&data, 0, data.len(), false).unwrap().0;
        assert_eq!(
            decoded,
            vec![Encoded::Point {
                xy: [1.5, 1.5],
                absolute: false,
                pen_up: false,
                at: 3
            }]
        );
    }

    #[test]
    fn broken_data_is_an_error() {
        assert!(decode(&[63, 63], 0, 2, false).is_err());
        assert!(decode(&[200], 0, 1, false).is_err());
        assert!(decode(b"!", 0, 1, false).is_err());
        assert!(decode(&[63; 12], 0, 12, false).is_err());
    }
}
