//! Motion blocks: end points (LinuxCNC `find_ends`, with G53 and polar coordinates),
//! straight moves and arcs (`convert_straight`, `convert_arc`, `arc_data_ijk`, `arc_data_r`).

use std::f64::consts::PI;

use super::block::{Block, Word, AXIS_LETTERS};
use super::canon::{rotate, Axes};
use super::codes::group;
use super::execute::too_many_moves;
use super::state::Interpreter;
use super::{block_text_range, LineError};
use crate::program::error::{display_text, Found};
use crate::program::types::{Plane, Span};

/// (first axis, second axis, normal axis, centre-offset letters, axis names) of a plane, in
/// LinuxCNC's order: G18's arcs run from Z towards X, so that G2 is clockwise seen from +Y.
pub(super) fn plane_axes(plane: Plane) -> (usize, usize, usize, [u8; 2], [char; 2]) {
    match plane {
        Plane::XY => (0, 1, 2, [b'i', b'j'], ['X', 'Y']),
        Plane::ZX => (2, 0, 1, [b'k', b'i'], ['Z', 'X']),
        Plane::YZ => (1, 2, 0, [b'j', b'k'], ['Y', 'Z']),
    }
}

fn plane_name(plane: Plane) -> &'static str {
    match plane {
        Plane::XY => "XY (G17)",
        Plane::ZX => "ZX (G18)",
        Plane::YZ => "YZ (G19)",
    }
}

impl Interpreter<'_> {
    /// The end point of a motion block in program coordinates.
    pub fn find_ends(&self, block: &Block) -> Result<Axes, LineError> {
        let s = &self.s;
        let mut end = s.current;
        if block.g_code(group::NON_MODAL) == Some(530) {
            // G53: axis words are machine coordinates.
            let (cx, cy) = rotate(
                s.current[0] + s.axis_offset[0],
                s.current[1] + s.axis_offset[1],
                s.rotation_xy,
            );
            let x = block
                .value(b'x')
                .map_or(cx, |x| x - s.origin_offset[0] - s.tool_offset[0]);
            let y = block
                .value(b'y')
                .map_or(cy, |y| y - s.origin_offset[1] - s.tool_offset[1]);
            let (x, y) = rotate(x, y, -s.rotation_xy);
            end[0] = x - s.axis_offset[0];
            end[1] = y - s.axis_offset[1];
            if let Some(z) = block.value(b'z') {
                end[2] = z - s.origin_offset[2] - s.axis_offset[2] - s.tool_offset[2];
            }
            for axis in 3..6 {
                if let Some(value) = block.value(AXIS_LETTERS[axis]) {
                    end[axis] = value - s.origin_offset[axis] - s.axis_offset[axis];
                }
            }
            return Ok(end);
        }
        // After the entry move, compensation works from the programmed point: X always,
        // Y in G17 and Z in G18 (LinuxCNC `find_ends`).
        if self.comp.side.is_some() && !self.comp.first_move {
            end[0] = self.comp.programmed[0];
            match s.plane {
                Plane::XY => end[1] = self.comp.programmed[1],
                Plane::ZX => end[2] = self.comp.programmed[2],
                Plane::YZ => {}
            }
        }
        for (axis, &letter) in AXIS_LETTERS.iter().enumerate() {
            if let Some(value) = block.value(letter) {
                if s.absolute {
                    end[axis] = value;
                } else {
                    end[axis] += value;
                }
            }
        }
        self.polar(block, &mut end)?;
        Ok(end)
    }

    /// `@` radius and `^` angle (degrees) about the origin of the XY plane.
    fn polar(&self, block: &Block, end: &mut Axes) -> Result<(), LineError> {
        let (radius, angle) = (block.polar_radius, block.polar_angle);
        if radius.is_none() && angle.is_none() {
            return Ok(());
        }
        let at = radius.or(angle).expect("a polar word");
        let (x, y) = (self.s.current[0], self.s.current[1]);
        let indeterminate =
            || at.error("expected a polar angle: from the origin the direction is not defined");
        if self.s.absolute {
            let (r, theta) = match (radius, angle) {
                (Some(r), Some(a)) => (r.value, a.value.to_radians()),
                (Some(r), None) => {
                    if x == 0.0 && y == 0.0 {
                        return Err(indeterminate());
                    }
                    (r.value, y.atan2(x))
                }
                (None, Some(a)) => (x.hypot(y), a.value.to_radians()),
                (None, None) => unreachable!(),
            };
            end[0] = r * theta.cos();
            end[1] = r * theta.sin();
        } else {
            if x == 0.0 && y == 0.0 {
                return Err(indeterminate());
            }
            let mut r = x.hypot(y);
            let mut theta = y.atan2(x);
            if let Some(dr) = radius {
                r += dr.value;
            }
            if let Some(da) = angle {
                theta += da.value.to_radians();
            }
            end[0] = r * theta.cos();
            end[1] = r * theta.sin();
        }
        Ok(())
    }

    pub fn traverse(&mut self, end: &Axes, span: Span) -> Result<(), LineError> {
        self.canon
            .straight_traverse(end, span)
            .map_err(|limit| too_many_moves(limit.0))?;
        self.s.current = *end;
        Ok(())
    }

    pub fn feed_to(&mut self, end: &Axes, span: Span) -> Result<(), LineError> {
        self.canon
            .straight_feed(end, None, span)
            .map_err(|limit| too_many_moves(limit.0))?;
        self.s.current = *end;
        Ok(())
    }

    /// G0 / G1.
    pub fn straight(&mut self, code: u32, block: &Block, span: Span) -> Result<(), LineError> {
        let (start, end) = block_text_range_of(block);
        let inverse_time = if code == 10 {
            self.feed_check(block, start, end)?
        } else {
            None
        };
        self.s.motion_mode = Some(code);
        self.comp.arc_not_allowed = false;
        let target = self.find_ends(block)?;
        if self.comp.active() {
            if block.g_code(group::NON_MODAL) == Some(530) {
                return Err(LineError::new(
                    start,
                    end,
                    "expected no G53 move while cutter radius compensation is on",
                ));
            }
            let inverse_time = self.comp_inverse_time_rate(inverse_time, &target);
            return self
                .straight_comp(code == 0, &target, inverse_time, span)
                .map_err(|e| e.located(start, end));
        }
        if code == 0 {
            self.traverse(&target, span)
        } else {
            self.canon
                .straight_feed(&target, inverse_time, span)
                .map_err(|limit| too_many_moves(limit.0))?;
            self.s.current = target;
            Ok(())
        }
    }

    /// Checks a feed move has a feed; in inverse time returns the move's duration (s).
    fn feed_check(
        &self,
        block: &Block,
        start: usize,
        end: usize,
    ) -> Result<Option<f64>, LineError> {
        if self.s.inverse_time {
            return match block.word(b'f') {
                Some(f) if f.value > 0.0 => Ok(Some(60.0 / f.value)),
                Some(f) => {
                    Err(f.error("expected a positive F word (inverse time: 1/minutes) in G93 mode"))
                }
                None => Err(LineError::new(
                    start,
                    end,
                    "expected an F word on every G1/G2/G3 block in inverse-time mode (G93)",
                )
                .hint("in G93 the F word is 1 / (move time in minutes) and is not modal")),
            };
        }
        if self.s.feed_rate <= 0.0 {
            return Err(LineError::new(
                start,
                end,
                "expected a non-zero feed rate (F word) before a G1/G2/G3 move",
            )
            .hint(format!(
                "add e.g. F300 ({} per minute in G94)",
                self.s.units.symbol()
            )));
        }
        Ok(None)
    }

    /// G2 / G3.
    pub fn arc(
        &mut self,
        line: &[u8],
        code: u32,
        block: &Block,
        span: Span,
    ) -> Result<(), LineError> {
        let range = block_text_range(line);
        let found = || Found::Text(display_text(&line[range.0..range.1]));
        if self.comp.arc_not_allowed {
            return Err(LineError::new(range.0, range.1, "expected a straight move just after turning cutter compensation off (G40), not an arc")
                .found(found()));
        }
        let inverse_time = self
            .feed_check(block, range.0, range.1)
            .map_err(|e| e.found(found()))?;
        self.s.motion_mode = Some(code);
        let end = self.find_ends(block)?;
        let clockwise = code == 20;
        let (first, second, _, _, _) = plane_axes(self.s.plane);
        let comp = self.comp.active() && matches!(self.s.plane, Plane::XY | Plane::ZX);
        // Compensated arcs after the entry start from the programmed point.
        let start = if comp && !self.comp.first_move {
            let p = self.comp.programmed;
            [p[first], p[second]]
        } else {
            [self.s.current[first], self.s.current[second]]
        };
        let (centre, turns) = self.arc_centre(line, block, start, &end, clockwise, range)?;
        if comp {
            let turn = if clockwise {
                -(turns as i32 + 1)
            } else {
                turns as i32 + 1
            };
            let inverse_time = match inverse_time {
                Some(_) => {
                    let radius = (centre[0] - start[0]).hypot(centre[1] - start[1]);
                    let angle = super::comp::sweep(start, centre, turn, [end[first], end[second]]);
                    let normal = 3 - first - second;
                    let rise = end[normal] - self.comp.programmed[normal];
                    let length = (radius * angle).hypot(rise);
                    self.comp_rate(block, length);
                    None
                }
                None => None,
            };
            return self
                .arc_comp(clockwise, &end, centre, turn, inverse_time, span)
                .map_err(|e| e.located(range.0, range.1));
        }
        let mut centre_axes = self.s.current;
        let (first, second, _, _, _) = plane_axes(self.s.plane);
        centre_axes[first] = centre[0];
        centre_axes[second] = centre[1];
        self.canon
            .arc_feed(
                &end,
                &centre_axes,
                (self.s.plane, clockwise, turns),
                inverse_time,
                span,
            )
            .map_err(|limit| too_many_moves(limit.0))?;
        self.s.current = end;
        Ok(())
    }

    /// Centre (in the plane, program units) and extra turns of an arc, checked as LinuxCNC
    /// checks them.
    fn arc_centre(
        &self,
        line: &[u8],
        block: &Block,
        start: [f64; 2],
        end: &Axes,
        clockwise: bool,
        block_range: (usize, usize),
    ) -> Result<([f64; 2], u32), LineError> {
        let (first, second, _normal, offset_letters, names) = plane_axes(self.s.plane);
        let tolerance = &self.options.gcode.arc_tolerance;
        let unit = self.s.units;
        let found = || Found::Text(display_text(&line[block_range.0..block_range.1]));
        let forbidden = [b'i', b'j', b'k']
            .into_iter()
            .find(|l| !offset_letters.contains(l));
        if let Some(word) = forbidden.and_then(|letter| block.word(letter)) {
            return Err(word.error(format!(
                "expected centre offsets {} and {} for an arc in the {} plane",
                offset_letters[0].to_ascii_uppercase() as char,
                offset_letters[1].to_ascii_uppercase() as char,
                plane_name(self.s.plane)
            )));
        }
        let turns = match block.word(b'p') {
            None => 0,
            Some(p) => {
                let rounded = p.value.round();
                if rounded > f64::from(u32::MAX) {
                    return Err(
                        p.error("expected a whole number of turns of 1 or more after P on an arc")
                    );
                }
                rounded as u32 - 1
            }
        };
        let stop = [end[first], end[second]];
        let radius_tolerance = tolerance.radius(unit);
        let describe = |c: [f64; 2]| format!("({}{:.4},{}{:.4})", names[0], c[0], names[1], c[1]);
        if let Some(r) = block.word(b'r') {
            if block.has(offset_letters[0]) || block.has(offset_letters[1]) {
                return Err(r
                    .error("expected either R or centre offsets on an arc, not both")
                    .found(found()));
            }
            if start == stop {
                return Err(LineError::new(
                    block_range.0,
                    block_range.1,
                    "expected an R-form arc to end somewhere other than its start",
                )
                .found(found())
                .hint("a full circle needs the centre form (I J K)"));
            }
            let radius = r.value.abs();
            if radius < radius_tolerance {
                return Err(r.error("expected a non-zero arc radius"));
            }
            let mid = [(start[0] + stop[0]) / 2.0, (start[1] + stop[1]) / 2.0];
            let mut half_chord = (mid[0] - stop[0]).hypot(mid[1] - stop[1]);
            if half_chord - radius > radius_tolerance {
                return Err(r.error(format!(
                    "expected an arc radius of at least {:.4} {} (half the distance from start {} to end {})",
                    half_chord, unit.symbol(), describe(start), describe(stop)
                )));
            }
            if half_chord / radius > 1.0 - 1e-12 {
                half_chord = radius; // a semicircle, allowing for rounding
            }
            let chord_angle = (stop[1] - start[1]).atan2(stop[0] - start[0]);
            // Negative R asks for the arc longer than a semicircle.
            let centre_right = clockwise == (r.value > 0.0);
            let theta = if centre_right {
                chord_angle - PI / 2.0
            } else {
                chord_angle + PI / 2.0
            };
            let offset = radius * (half_chord / radius).asin().cos();
            return Ok((
                [mid[0] + offset * theta.cos(), mid[1] + offset * theta.sin()],
                turns,
            ));
        }
        let i = block.word(offset_letters[0]);
        let j = block.word(offset_letters[1]);
        if i.is_none() && j.is_none() {
            return Err(LineError::new(
                block_range.0,
                block_range.1,
                format!(
                    "expected an R word or centre offsets {} {} on an arc",
                    offset_letters[0].to_ascii_uppercase() as char,
                    offset_letters[1].to_ascii_uppercase() as char
                ),
            )
            .found(found()));
        }
        let offset = |word: Option<Word>| word.map_or(0.0, |w| w.value);
        let centre = if self.s.ijk_absolute {
            [offset(i), offset(j)]
        } else {
            [start[0] + offset(i), start[1] + offset(j)]
        };
        let r1 = (centre[0] - start[0]).hypot(centre[1] - start[1]);
        let r2 = (centre[0] - stop[0]).hypot(centre[1] - stop[1]);
        let geometry = || {
            format!(
                "start={} center={} end={} r1={:.4} r2={:.4}",
                describe(start),
                describe(centre),
                describe(stop),
                r1,
                r2
            )
        };
        if r1 < radius_tolerance || r2 < radius_tolerance {
            return Err(LineError::new(
                block_range.0,
                block_range.1,
                format!(
                "expected an arc centre away from its start and end points (zero-radius arc: {})",
                geometry()
            ),
            )
            .found(found()));
        }
        let abs_err = (r1 - r2).abs();
        let rel_err = abs_err / r1.max(r2);
        let spiral = tolerance.spiral(unit);
        if abs_err > 100.0 * spiral || (abs_err > spiral && rel_err > tolerance.spiral_relative) {
            return Err(LineError::new(block_range.0, block_range.1, format!(
                "arc end point is off the circle by {:.4} {}: radius to end differs from radius to start ({}, rel_err={:.4}%); expected at most {:.4} {} (or {:.4} {} within {}% of the radius)",
                abs_err,
                unit.symbol(),
                geometry(),
                rel_err * 100.0,
                spiral,
                unit.symbol(),
                100.0 * spiral,
                unit.symbol(),
                tolerance.spiral_relative * 100.0
            ))
            .found(found())
            .hint(if self.s.ijk_absolute {
                "check the end point and the centre (G90.1: I J K are absolute)"
            } else {
                "check the end point and the centre offsets (G91.1: I J K are relative to the start point)"
            }));
        }
        Ok((centre, turns))
    }
}

impl Interpreter<'_> {
    /// In inverse time with compensation LinuxCNC sets the feed rate from the programmed
    /// length (F × length per minute) and feeds the compensated move at that rate.
    fn comp_inverse_time_rate(&mut self, inverse_time: Option<f64>, target: &Axes) -> Option<f64> {
        let seconds = inverse_time?;
        let programmed = if self.comp.first_move {
            [self.s.current[0], self.s.current[1], self.s.current[2]]
        } else {
            self.comp.programmed
        };
        let length = (0..3)
            .map(|axis| (target[axis] - programmed[axis]).powi(2))
            .sum::<f64>()
            .sqrt();
        let length = if length > 0.0 {
            length
        } else {
            (3..6)
                .map(|axis| (target[axis] - self.s.current[axis]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        self.set_inverse_rate(60.0 / seconds, length);
        None
    }

    fn comp_rate(&mut self, block: &Block, length: f64) {
        if let Some(f) = block.value(b'f') {
            self.set_inverse_rate(f, length);
        }
    }

    fn set_inverse_rate(&mut self, f: f64, length: f64) {
        let rate = (length * f).max(0.1);
        self.s.feed_rate = rate;
        self.canon.set_feed_rate(rate);
    }
}

/// The block's own text range (for messages about the whole block).
fn block_text_range_of(block: &Block) -> (usize, usize) {
    (block.start, block.end)
}
