//! Canned cycles G73, G74, G81–G87, G89 with G98/G99 and L repeats (LinuxCNC
//! `convert_cycle`, `convert_cycle_xy` and the cycle bodies), in any of the three planes: the
//! cycle works along the plane's normal axis ("cc") at points of the plane ("aa", "bb").

use super::block::{format_g, Block, AXIS_LETTERS};
use super::codes::group;
use super::execute::too_many_moves;
use super::motion::plane_axes;
use super::state::{Interpreter, Turning};
use super::LineError;
use crate::program::options::LengthUnit;
use crate::program::types::{Blend, Plane, Span, Spindle};

/// How far G73 and G83 back off between pecks (LinuxCNC `G83_RAPID_DELTA`, inches).
const PECK_CLEARANCE_INCH: f64 = 0.010;

/// Most pecks of one G73/G83 hole: far beyond real programs, and it bounds the loop.
const MAX_PECKS: f64 = 100_000.0;

impl Interpreter<'_> {
    pub fn cycle(&mut self, code: u32, block: &Block, span: Span) -> Result<(), LineError> {
        let word = block.g[group::MOTION];
        let (at, at_end) = word.map_or((block.start, block.end), |w| (w.start, w.end));
        let name = format_g(code);
        let error = |problem: String| LineError::new(at, at_end, problem);
        if self.s.feed_rate == 0.0 {
            return Err(error(format!(
                "expected a non-zero feed rate (F word) before {name}"
            )));
        }
        if self.comp.side.is_some() {
            return Err(error(format!(
                "expected cutter radius compensation off (G40) for {name}"
            )));
        }
        if self.s.inverse_time {
            return Err(error(format!(
                "expected feed per minute (G94) with {name}: canned cycles cannot use inverse time"
            )));
        }
        let plane = self.s.plane;
        let (a_axis, b_axis, c_axis, _, _) = plane_axes(plane);
        let c_letter = AXIS_LETTERS[c_axis];
        let r_word = match block.value(b'r') {
            Some(r) => r,
            None if self.s.motion_mode == Some(code) => self.s.cycle.r,
            None => {
                return Err(error(format!(
                    "expected an R word (retract plane) with {name}"
                )));
            }
        };
        let repeats = match block.word(b'l') {
            None => 1.0,
            Some(l) => {
                let rounded = l.value.round();
                if (l.value - rounded).abs() > 0.0001 || rounded < 1.0 {
                    return Err(l.error("expected a whole number of repeats of 1 or more after L"));
                }
                rounded
            }
        };
        if self.s.motion_mode != Some(code) && !block.has(c_letter) {
            return Err(error(format!(
                "expected a {} word (the bottom of the hole) with {name} in the {} plane",
                c_letter.to_ascii_uppercase() as char,
                match plane {
                    Plane::XY => "G17",
                    Plane::ZX => "G18",
                    Plane::YZ => "G19",
                }
            )));
        }
        if code == 870 && plane != Plane::XY {
            return Err(error(
                "expected G87 (back boring) in the G17 plane; G87 in G18/G19 is not supported"
                    .into(),
            ));
        }
        if matches!(code, 740 | 840) && plane != Plane::XY {
            return Err(error(format!(
                "expected {name} (tapping) in the G17 plane; {name} in G18/G19 is not supported: LinuxCNC 2.9 exchanges the axes there"
            )));
        }
        let c_word = block.value(c_letter).unwrap_or(self.s.cycle.bottom);
        let mut current_cc = self.s.current[c_axis];
        let mut old_cc = match self.s.cycle.initial_level {
            Some(level) => level,
            None => {
                self.s.cycle.initial_level = Some(current_cc);
                current_cc
            }
        };
        let (mut aa, mut bb, r, cc, aa_step, bb_step);
        let (mut radius_step, mut angle_step) = (0.0, 0.0);
        if self.s.absolute {
            aa_step = 0.0;
            bb_step = 0.0;
            r = r_word;
            cc = c_word;
            let mut target = self.s.current;
            target[a_axis] = block.value(AXIS_LETTERS[a_axis]).unwrap_or(target[a_axis]);
            target[b_axis] = block.value(AXIS_LETTERS[b_axis]).unwrap_or(target[b_axis]);
            if block.polar_radius.is_some() || block.polar_angle.is_some() {
                target = self.find_ends(block)?;
            }
            aa = target[a_axis];
            bb = target[b_axis];
        } else {
            aa_step = block.value(AXIS_LETTERS[a_axis]).unwrap_or(0.0);
            bb_step = block.value(AXIS_LETTERS[b_axis]).unwrap_or(0.0);
            radius_step = block.polar_radius.map_or(0.0, |w| w.value);
            angle_step = block.polar_angle.map_or(0.0, |w| w.value.to_radians());
            r = r_word + old_cc;
            cc = r + c_word;
            aa = self.s.current[a_axis];
            bb = self.s.current[b_axis];
        }
        if r < cc {
            return Err(error(format!(
                "expected the R plane ({r:.4}) at or above the bottom of the hole ({cc:.4}) in {name}"
            )));
        }
        // Words the cycle needs, remembered for the next block of the same cycle.
        let p = match code {
            820 | 860 | 890 => match block.value(b'p') {
                Some(p) => p,
                None if self.s.motion_mode == Some(code) => self.s.cycle.p,
                None => {
                    return Err(error(format!(
                        "expected a P word (dwell seconds) with {name}"
                    )))
                }
            },
            740 | 840 => block.value(b'p').unwrap_or(self.s.cycle.p),
            _ => 0.0,
        };
        let q = match code {
            730 | 830 => {
                let q = match block.word(b'q') {
                    Some(q) => q.value,
                    None if self.s.motion_mode == Some(code) => self.s.cycle.q,
                    None => {
                        return Err(error(format!("expected a Q word (peck depth) with {name}")))
                    }
                };
                if q <= 0.0 {
                    return Err(error(format!(
                        "expected a positive Q (peck depth) with {name}"
                    )));
                }
                if (r - cc) / q > MAX_PECKS {
                    return Err(error(format!(
                        "expected at most {MAX_PECKS} pecks per hole; Q{q} makes {:.0}",
                        ((r - cc) / q).ceil()
                    )));
                }
                q
            }
            _ => 0.0,
        };
        let (i, j, k) = if code == 870 {
            let memory = self.s.cycle;
            let i = block
                .value(b'i')
                .or((self.s.motion_mode == Some(code)).then_some(memory.i));
            let j = block
                .value(b'j')
                .or((self.s.motion_mode == Some(code)).then_some(memory.j));
            let k = block
                .value(b'k')
                .or((self.s.motion_mode == Some(code)).then_some(memory.k));
            match (i, j, k) {
                (Some(i), Some(j), Some(k)) => (i, j, k),
                _ => return Err(error("expected I, J and K words with G87".into())),
            }
        } else {
            (0.0, 0.0, 0.0)
        };
        let spindle = self.s.turning;
        match code {
            840 if spindle != Turning::Clockwise => {
                return Err(error(
                    "expected the spindle turning clockwise (M3) in G84".into(),
                ));
            }
            740 if spindle != Turning::CounterClockwise => {
                return Err(error(
                    "expected the spindle turning counter-clockwise (M4) in G74".into(),
                ));
            }
            860 | 870 if spindle == Turning::Stopped => {
                return Err(error(format!("expected the spindle turning in {name}")));
            }
            _ => {}
        }
        let mut point = self.s.current;
        let mut go =
            |interp: &mut Self, a: f64, b: f64, c: f64, feed: bool| -> Result<(), LineError> {
                point[a_axis] = a;
                point[b_axis] = b;
                point[c_axis] = c;
                if feed {
                    interp.feed_to(&point, span)
                } else {
                    interp.traverse(&point, span)
                }
            };
        // First motion: climb to the R plane if below it.
        if old_cc < r {
            go(
                self,
                self.s.current[a_axis],
                self.s.current[b_axis],
                r,
                false,
            )?;
            old_cc = r;
            current_cc = r;
        }
        let clear = if self.s.retract_to_r { r } else { old_cc };
        let saved_blend = self.canon.blend;
        self.canon.blend = Blend::ExactStop;
        let peck_clearance = match self.s.units {
            LengthUnit::Millimetre => PECK_CLEARANCE_INCH * 25.4,
            LengthUnit::Inch => PECK_CLEARANCE_INCH,
        };
        let middle = if self.s.absolute { k } else { cc + k };
        let mut repeat = 0.0;
        let outcome = (|| -> Result<(), LineError> {
            while repeat < repeats {
                aa += aa_step;
                bb += bb_step;
                if radius_step != 0.0 || angle_step != 0.0 {
                    if aa == 0.0 && bb == 0.0 {
                        return Err(error("expected a polar step away from the origin: from there the direction is not defined".into()));
                    }
                    let radius = aa.hypot(bb) + radius_step;
                    let angle = bb.atan2(aa) + angle_step;
                    aa = radius * angle.cos();
                    bb = radius * angle.sin();
                }
                if repeat == 0.0 && current_cc > r {
                    go(self, aa, bb, current_cc, false)?;
                    go(self, aa, bb, r, false)?;
                } else {
                    go(self, aa, bb, clear, false)?;
                    if clear > r {
                        go(self, aa, bb, r, false)?;
                    }
                }
                match code {
                    810 => {
                        go(self, aa, bb, cc, true)?;
                        go(self, aa, bb, clear, false)?;
                    }
                    820 => {
                        go(self, aa, bb, cc, true)?;
                        self.cycle_dwell(p, span)?;
                        go(self, aa, bb, clear, false)?;
                    }
                    730 | 830 => {
                        let mut depth = r - q;
                        while depth > cc {
                            go(self, aa, bb, depth, true)?;
                            if code == 830 {
                                go(self, aa, bb, r, false)?;
                            }
                            go(self, aa, bb, depth + peck_clearance, false)?;
                            depth -= q;
                        }
                        go(self, aa, bb, cc, true)?;
                        go(self, aa, bb, clear, false)?;
                    }
                    740 | 840 => {
                        go(self, aa, bb, cc, true)?;
                        self.set_spindle_turning(if code == 840 {
                            Turning::CounterClockwise
                        } else {
                            Turning::Clockwise
                        });
                        self.cycle_dwell(p, span)?;
                        go(self, aa, bb, clear, true)?;
                        self.set_spindle_turning(spindle);
                    }
                    850 => {
                        go(self, aa, bb, cc, true)?;
                        go(self, aa, bb, r, true)?;
                        go(self, aa, bb, clear, false)?;
                    }
                    860 => {
                        go(self, aa, bb, cc, true)?;
                        self.cycle_dwell(p, span)?;
                        self.set_spindle_turning(Turning::Stopped);
                        go(self, aa, bb, clear, false)?;
                        self.set_spindle_turning(spindle);
                    }
                    870 => {
                        let (oa, ob) = (aa + i, bb + j);
                        go(self, oa, ob, r, false)?;
                        self.set_spindle_turning(Turning::Stopped);
                        go(self, oa, ob, cc, false)?;
                        go(self, aa, bb, cc, false)?;
                        self.set_spindle_turning(spindle);
                        go(self, aa, bb, middle, true)?;
                        go(self, aa, bb, cc, true)?;
                        self.set_spindle_turning(Turning::Stopped);
                        go(self, oa, ob, cc, false)?;
                        go(self, oa, ob, clear, false)?;
                        go(self, aa, bb, clear, false)?;
                        self.set_spindle_turning(spindle);
                    }
                    890 => {
                        go(self, aa, bb, cc, true)?;
                        self.cycle_dwell(p, span)?;
                        go(self, aa, bb, clear, true)?;
                    }
                    _ => unreachable!("not a cycle: {code}"),
                }
                repeat += 1.0;
            }
            Ok(())
        })();
        self.canon.blend = saved_blend;
        outcome?;
        self.s.current[a_axis] = aa;
        self.s.current[b_axis] = bb;
        self.s.current[c_axis] = clear;
        self.s.cycle.bottom = c_word;
        self.s.cycle.r = r_word;
        match code {
            820 | 860 | 890 | 740 | 840 => self.s.cycle.p = p,
            730 | 830 => self.s.cycle.q = q,
            870 => {
                self.s.cycle.i = i;
                self.s.cycle.j = j;
                self.s.cycle.k = k;
            }
            _ => {}
        }
        self.s.motion_mode = Some(code);
        Ok(())
    }

    fn cycle_dwell(&mut self, seconds: f64, span: Span) -> Result<(), LineError> {
        self.canon
            .dwell(seconds.max(0.0), span)
            .map_err(|limit| too_many_moves(limit.0))
    }

    fn set_spindle_turning(&mut self, turning: Turning) {
        self.s.turning = turning;
        self.canon.spindle = match turning {
            Turning::Stopped => Spindle::Off,
            Turning::Clockwise => Spindle::Clockwise { rpm: self.s.speed },
            Turning::CounterClockwise => Spindle::CounterClockwise { rpm: self.s.speed },
        };
    }
}
