//! Labels (`LB`, `PB`, symbol mode `SM`, `CP`) drawn through the Hershey stroke font, with the
//! character size (`SI`/`SR`), direction (`DI`/`DR`), slant (`SL`), extra space (`ES`) and
//! label origin (`LO`) of HP-GL.
//!
//! HP's character cell: a character `w` wide and `h` tall (cap height) sits in a cell 1.5 w
//! wide; lines are 2 h apart. Each Hershey glyph is centred in its character box and scaled so
//! that its cap height is `h` and 16 Hershey units are `w` (the font's capital width).

use super::font::{self, BASELINE, CAP_TOP};

/// Character size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Size {
    /// `SI w,h`: centimetres.
    Absolute { width_cm: f64, height_cm: f64 },
    /// `SR w,h`: percent of P2 − P1 (the default, 0.75 % and 1.5 %).
    Relative { width: f64, height: f64 },
}

/// Label direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Direction {
    /// `DI run,rise`.
    Absolute { run: f64, rise: f64 },
    /// `DR run,rise`: percent of P2 − P1.
    Relative { run: f64, rise: f64 },
}

/// The label settings in force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct LabelStyle {
    pub(super) size: Size,
    pub(super) direction: Direction,
    /// Tangent of the slant angle (`SL`).
    pub(super) slant: f64,
    /// `ES`: extra character and line spacing, in cells.
    pub(super) extra: [f64; 2],
    /// `LO`: 1–9 or 11–19.
    pub(super) origin: u32,
    /// `DT`: the label terminator.
    pub(super) terminator: u8,
    /// `DV`: the text path, each character placed 0, 90, 180 or 270° clockwise of the label
    /// direction from the one before (0: right, 1: down, 2: left, 3: up).
    pub(super) path: u8,
    /// `DV`'s second parameter: line feeds go 90° anticlockwise of the path, not clockwise.
    pub(super) reverse_line_feed: bool,
}

impl Default for LabelStyle {
    fn default() -> Self {
        LabelStyle {
            size: Size::Relative {
                width: 0.75,
                height: 1.5,
            },
            direction: Direction::Absolute {
                run: 1.0,
                rise: 0.0,
            },
            slant: 0.0,
            extra: [0.0, 0.0],
            origin: 1,
            terminator: super::scan::ETX,
            path: 0,
            reverse_line_feed: false,
        }
    }
}

/// The label geometry in plotter units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Geometry {
    pub(super) width: f64,
    pub(super) height: f64,
    /// Unit vector along the label.
    pub(super) along: [f64; 2],
    pub(super) slant: f64,
    /// From one character origin to the next.
    pub(super) advance: [f64; 2],
    /// From one line to the next (downwards).
    pub(super) line_feed: [f64; 2],
}

impl LabelStyle {
    /// The geometry under P1/P2 (`p1`, `p2`) with `units_per_cm` plotter units per centimetre.
    pub(super) fn geometry(&self, p1: [f64; 2], p2: [f64; 2], units_per_cm: f64) -> Geometry {
        let span = [p2[0] - p1[0], p2[1] - p1[1]];
        let (width, height) = match self.size {
            Size::Absolute {
                width_cm,
                height_cm,
            } => (width_cm * units_per_cm, height_cm * units_per_cm),
            Size::Relative { width, height } => (width / 100.0 * span[0], height / 100.0 * span[1]),
        };
        let angle = match self.direction {
            Direction::Absolute { run, rise } => rise.atan2(run),
            Direction::Relative { run, rise } => (rise * span[1]).atan2(run * span[0]),
        };
        let along = [angle.cos(), angle.sin()];
        let cell = 1.5 * width * (1.0 + self.extra[0]);
        let line = 2.0 * height * (1.0 + self.extra[1]);
        // The text path turns the advance clockwise from the label direction by 90° per step;
        // the characters stay upright along it. A vertical path stacks characters a line
        // apart and puts its lines a character cell apart.
        let clockwise =
            |v: [f64; 2], quarter_turns: u8| (0..quarter_turns % 4).fold(v, |v, _| [v[1], -v[0]]);
        let path = clockwise(along, self.path);
        let (step, line_step) = if self.path % 2 == 1 {
            (line, cell)
        } else {
            (cell, line)
        };
        let feed = clockwise(path, if self.reverse_line_feed { 3 } else { 1 });
        Geometry {
            width,
            height,
            along,
            slant: self.slant,
            advance: [step * path[0], step * path[1]],
            line_feed: [line_step * feed[0], line_step * feed[1]],
        }
    }
}

impl Geometry {
    /// A point `u` along and `v` up from `origin` in character units, slanted.
    fn point(&self, origin: [f64; 2], u: f64, v: f64) -> [f64; 2] {
        let u = u + v * self.slant;
        [
            origin[0] + u * self.along[0] - v * self.along[1],
            origin[1] + u * self.along[1] + v * self.along[0],
        ]
    }

    /// The strokes of one glyph whose character box has its lower-left corner at `origin`.
    pub(super) fn glyph_strokes(
        &self,
        glyph: &font::Glyph,
        origin: [f64; 2],
    ) -> Vec<Vec<[f64; 2]>> {
        let centre = f64::from(glyph.left + glyph.right) / 2.0;
        let x_scale = self.width / 16.0;
        let y_scale = self.height / f64::from(BASELINE - CAP_TOP);
        glyph
            .strokes
            .iter()
            .map(|stroke| {
                stroke
                    .iter()
                    .map(|&[x, y]| {
                        let u = (f64::from(x) - centre) * x_scale + self.width / 2.0;
                        let v = f64::from(BASELINE - y) * y_scale;
                        self.point(origin, u, v)
                    })
                    .collect()
            })
            .collect()
    }

    /// The strokes of a symbol (`SM`) centred on `point`.
    pub(super) fn symbol_strokes(
        &self,
        glyph: &font::Glyph,
        point: [f64; 2],
    ) -> Vec<Vec<[f64; 2]>> {
        let origin = self.point(point, -self.width / 2.0, -self.height / 2.0);
        self.glyph_strokes(glyph, origin)
    }
}

/// A laid-out label: pen-down polylines, where the pen ends and where a carriage return
/// would now go.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct Laid {
    pub(super) strokes: Vec<Vec<[f64; 2]>>,
    pub(super) end: [f64; 2],
    pub(super) carriage: [f64; 2],
}

const BS: u8 = 0x08;
const HT: u8 = 0x09;
const LF: u8 = 0x0a;
const VT: u8 = 0x0b;
const CR: u8 = 0x0d;
const SO: u8 = 0x0e;
const SI: u8 = 0x0f;

/// Character cells a line of text advances (to its CR or end): printable characters count
/// one, backspace minus one, HT minus a half (HP-GL's half backspace).
fn line_cells(text: &[u8]) -> f64 {
    let mut cells = 0.0;
    for &byte in text {
        match byte {
            CR => break,
            BS => cells -= 1.0,
            HT => cells -= 0.5,
            b' '..=b'~' => cells += 1.0,
            byte if byte >= 0x80 => cells += 1.0,
            _ => {}
        }
    }
    cells
}

/// Lays out `text` from the pen at `start` (carriage returns go back to `carriage`).
/// Fails with the offset of a character the font has no glyph for.
pub(super) fn lay_out(
    text: &[u8],
    start: [f64; 2],
    carriage: [f64; 2],
    geometry: &Geometry,
    origin: u32,
) -> Result<Laid, usize> {
    let mut laid = Laid {
        strokes: Vec::new(),
        end: start,
        carriage,
    };
    let (h, w) = (geometry.height, geometry.width);
    // Where each character is drawn relative to its cell (label origin), and the shift of
    // the line's start for centred and right-aligned origins.
    let along_shift = match origin {
        4..=6 | 14..=16 => 0.5,
        7..=9 | 17..=19 => 1.0,
        _ => 0.0,
    };
    let (du, dv) = {
        let du = match origin {
            11..=13 => w / 2.0,
            4..=6 | 14..=16 => w / 4.0,
            7..=9 => w / 2.0,
            _ => 0.0,
        };
        let dv = match origin {
            2 | 5 | 8 | 12 | 15 | 18 => -h / 2.0,
            3 | 6 | 9 => -h,
            11 | 14 | 17 => h / 2.0,
            13 | 16 | 19 => -1.5 * h,
            _ => 0.0,
        };
        (du, dv)
    };
    let shift_line = |point: [f64; 2], rest: &[u8]| {
        let cells = line_cells(rest) * along_shift;
        [
            point[0] - geometry.advance[0] * cells,
            point[1] - geometry.advance[1] * cells,
        ]
    };
    let mut reference = shift_line(start, text);
    for (index, &byte) in text.iter().enumerate() {
        match byte {
            b' ' => {
                reference = add(reference, geometry.advance);
            }
            CR => {
                reference = shift_line(laid.carriage, &text[index + 1..]);
            }
            LF => {
                laid.carriage = add(laid.carriage, geometry.line_feed);
                reference = add(reference, geometry.line_feed);
            }
            VT => {
                laid.carriage = sub(laid.carriage, geometry.line_feed);
                reference = sub(reference, geometry.line_feed);
            }
            BS => reference = sub(reference, geometry.advance),
            HT => reference = sub(reference, scale(geometry.advance, 0.5)),
            // Shift out / in between the standard and alternate sets: one font here.
            SO | SI => {}
            byte if byte < b' ' || byte == 0x7f => {}
            _ => {
                let glyph = font::glyph(byte).ok_or(index)?;
                let box_origin = geometry.point(reference, du, dv);
                laid.strokes
                    .extend(geometry.glyph_strokes(glyph, box_origin));
                reference = add(reference, geometry.advance);
            }
        }
    }
    laid.end = reference;
    Ok(laid)
}

fn add(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] + b[0], a[1] + b[1]]
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn scale(a: [f64; 2], k: f64) -> [f64; 2] {
    [a[0] * k, a[1] * k]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn geometry() -> Geometry {
        let style = LabelStyle {
            size: Size::Absolute {
                width_cm: 0.2,
                height_cm: 0.3,
            },
            ..LabelStyle::default()
        };
        style.geometry([0.0, 0.0], [10000.0, 7000.0], 400.0)
    }

    #[test]
    fn characters_advance_one_and_a_half_widths_and_lines_two_heights() {
        let g = geometry();
        assert_eq!((g.width, g.height), (80.0, 120.0));
        let laid = lay_out(b"AB", [100.0, 200.0], [100.0, 200.0], &g, 1).unwrap();
        assert_eq!(laid.end, [100.0 + 2.0 * 120.0, 200.0]);
        // 'A' spans its box: apex at the cap height, centred in the box.
        let apex = laid.strokes[0][0];
        assert!((apex[0] - 140.0).abs() < 1e-9 && (apex[1] - 320.0).abs() < 1e-9);
        let laid = lay_out(b"A\r\nB", [0.0, 0.0], [0.0, 0.0], &g, 1).unwrap();
        assert_eq!(laid.end, [120.0, -240.0]);
        assert_eq!(laid.carriage, [0.0, -240.0]);
    }

    #[test]
    fn centred_origin_and_direction() {
        let g = geometry();
        // LO 4: the line is centred on the pen; the pen ends half the line further on.
        let laid = lay_out(b"ABCD", [0.0, 0.0], [0.0, 0.0], &g, 4).unwrap();
        assert_eq!(laid.end, [240.0, 0.0]);
        // DI 0,1: the label runs up.
        let style = LabelStyle {
            direction: Direction::Absolute {
                run: 0.0,
                rise: 1.0,
            },
            size: Size::Absolute {
                width_cm: 0.2,
                height_cm: 0.3,
            },
            ..LabelStyle::default()
        };
        let g = style.geometry([0.0, 0.0], [1.0, 1.0], 400.0);
        let laid = lay_out(b"AB", [0.0, 0.0], [0.0, 0.0], &g, 1).unwrap();
        assert!((laid.end[0]).abs() < 1e-9 && (laid.end[1] - 240.0).abs() < 1e-9);
    }

    #[test]
    fn a_character_without_glyph_is_reported() {
        assert_eq!(
            lay_out(b"A\xb0C", [0.0; 2], [0.0; 2], &geometry(), 1),
            Err(1)
        );
    }
}
