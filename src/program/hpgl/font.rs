//! The stroke font HPGL labels are drawn with: Hershey Roman Simplex (public domain), read
//! from its `.jhf` text (`assets/fonts/hershey/rowmans.jhf`, ASCII 32–127 one glyph a line).
//!
//! Hershey coordinates: x to the right, y *down*, cap height from y = −12 to the baseline at
//! y = 9; each glyph carries its left and right bearing.

use std::sync::OnceLock;

const ROWMANS: &str = include_str!("../../../assets/fonts/hershey/rowmans.jhf");

/// One glyph: its bearings and pen-down polylines in Hershey units.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Glyph {
    pub left: i32,
    pub right: i32,
    pub strokes: Vec<Vec<[i32; 2]>>,
}

/// Baseline and cap line of the font (Hershey y, pointing down).
pub const BASELINE: i32 = 9;
pub const CAP_TOP: i32 = -12;

/// The glyph of a printable ASCII character (32–126); `None` for anything else.
pub fn glyph(character: u8) -> Option<&'static Glyph> {
    static GLYPHS: OnceLock<Vec<Glyph>> = OnceLock::new();
    let glyphs = GLYPHS.get_or_init(|| parse_jhf(ROWMANS).expect("the bundled font parses"));
    let index = usize::from(character.checked_sub(32)?);
    (character < 127).then(|| glyphs.get(index)).flatten()
}

/// Parses `.jhf` text: per glyph, a 5-column number, a 3-column count of coordinate pairs
/// (bearings included), then the pairs as letters offset from 'R'; " R" lifts the pen.
pub fn parse_jhf(text: &str) -> Result<Vec<Glyph>, String> {
    let mut glyphs = Vec::new();
    for (index, line) in text.lines().enumerate() {
        let bytes = line.as_bytes();
        if bytes.len() < 10 {
            if line.trim().is_empty() {
                continue;
            }
            return Err(format!("line {}: too short for a glyph", index + 1));
        }
        let count: usize = line[5..8]
            .trim()
            .parse()
            .map_err(|_| format!("line {}: bad pair count", index + 1))?;
        let pairs = &bytes[8..];
        if pairs.len() < 2 * count || count == 0 {
            return Err(format!(
                "line {}: {count} pairs announced, {} bytes given",
                index + 1,
                pairs.len()
            ));
        }
        let value = |b: u8| i32::from(b) - i32::from(b'R');
        let mut glyph = Glyph {
            left: value(pairs[0]),
            right: value(pairs[1]),
            strokes: Vec::new(),
        };
        let mut stroke: Vec<[i32; 2]> = Vec::new();
        for pair in pairs[2..2 * count].chunks_exact(2) {
            if pair == b" R" {
                if !stroke.is_empty() {
                    glyph.strokes.push(std::mem::take(&mut stroke));
                }
            } else {
                stroke.push([value(pair[0]), value(pair[1])]);
            }
        }
        if !stroke.is_empty() {
            glyph.strokes.push(stroke);
        }
        glyphs.push(glyph);
    }
    Ok(glyphs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bundled_font_covers_printable_ascii() {
        for character in 32..127u8 {
            let glyph = glyph(character).expect("glyph");
            assert!(glyph.left < glyph.right, "{}", character as char);
        }
        assert!(glyph(b' ').unwrap().strokes.is_empty());
        assert!(glyph(127).is_none() && glyph(31).is_none() && glyph(200).is_none());
        // 'A': three strokes, apex at the cap line, feet on the baseline.
        let a = glyph(b'A').unwrap();
        assert_eq!(a.strokes.len(), 3);
        assert_eq!(a.strokes[0], vec![[0, -12], [-8, 9]]);
    }
}
