//! Executing a block in LinuxCNC's order (`execute_block`, `convert_m`, `convert_g`): feed
//! mode, F, S, T, M6, spindle, coolant, dwell, plane, units, cutter compensation, tool
//! length offset, coordinate system, path control, distance modes, retract mode, the
//! non-modal codes (G10, G28, G30, G52, G53, G92) and finally the motion, then the stops.

// Axis loops index several parallel arrays (positions, offsets, parameters) at once.
#![allow(clippy::needless_range_loop)]

use super::block::{format_g, Block};
use super::canon::{rotate, Axes};
use super::codes::{group, mgroup};
use super::expr::ParameterRef;
use super::params::{self, coordinate_system_index};
use super::state::{Interpreter, ToolEntry, Turning};
use super::LineError;
use crate::program::error::{display_text, Found};
use crate::program::options::LengthUnit;
use crate::program::types::{Blend, Plane, Span, Spindle, Warning};

/// Codes of group 0 that take axis words for themselves.
fn covets_axes(code: Option<u32>) -> bool {
    matches!(code, Some(100 | 280 | 300 | 520 | 920))
}

pub(super) fn is_cycle(code: u32) -> bool {
    matches!(code, 730 | 740 | 810..=890)
}

impl Interpreter<'_> {
    pub fn set_parameter(&mut self, target: &ParameterRef, value: f64) {
        match target {
            ParameterRef::Numbered(index) => self.params.set(*index, value),
            ParameterRef::Named(name) if name.starts_with('_') => {
                self.params.set_global(name, value)
            }
            ParameterRef::Named(name) => {
                let frame = self.frames.last_mut().expect("frame");
                frame.locals.insert(name.clone(), value);
            }
        }
    }

    /// The motion this block makes (LinuxCNC `enhance_block`), after checking that axis
    /// words have a code to use them.
    fn motion_to_be(&self, line: &[u8], block: &Block) -> Result<Option<u32>, LineError> {
        let mode0 = block.g_code(group::NON_MODAL);
        let axes = block.has_axis_words();
        let polar = block.polar_radius.is_some() || block.polar_angle.is_some();
        if polar {
            if self.s.plane != Plane::XY {
                return Err(self.word_error(
                    block.polar_radius.or(block.polar_angle),
                    "expected polar coordinates (@ ^) only in the G17 plane",
                ));
            }
            for letter in [b'x', b'y'] {
                if let Some(word) = block.word(letter) {
                    return Err(
                        word.error("expected either polar coordinates (@ ^) or X/Y, not both")
                    );
                }
            }
        }
        let g43_1 = matches!(block.g_code(group::TOOL_LENGTH), Some(431 | 432));
        if let Some(code) = block.g_code(group::MOTION) {
            let word = block.g[group::MOTION].expect("motion word");
            if code == 800 {
                if axes && !covets_axes(mode0) {
                    let axis = block.first_axis_word().expect("axis word");
                    return Err(axis
                        .error("expected no axis words with G80")
                        .hint("G80 cancels the motion mode; put the move in its own block"));
                }
            } else {
                if covets_axes(mode0) {
                    let g0 = block.g[group::NON_MODAL].expect("group 0 word");
                    return Err(g0.error(format!(
                        "expected only one code that uses the axis words, but {} and {} both do",
                        format_g(g0.code),
                        format_g(code)
                    )));
                }
                if !axes && !matches!(code, 0 | 10 | 20 | 30) {
                    return Err(word
                        .error(format!("expected axis words with {}", format_g(code)))
                        .found(Found::Text(display_text(&line[block.start..block.end]))));
                }
            }
            if matches!(mode0, Some(520 | 920)) && !axes {
                let g0 = block.g[group::NON_MODAL].expect("group 0 word");
                return Err(g0.error(format!("expected axis words with {}", format_g(g0.code))));
            }
            return Ok(if code == 800 { None } else { Some(code) });
        }
        if covets_axes(mode0) {
            if matches!(mode0, Some(520 | 920)) && !axes {
                let g0 = block.g[group::NON_MODAL].expect("group 0 word");
                return Err(g0.error(format!("expected axis words with {}", format_g(g0.code))));
            }
            return Ok(None);
        }
        if axes {
            if self.s.motion_mode.is_none() && !g43_1 {
                let axis = block.first_axis_word().expect("axis word");
                return Err(axis.error("expected a motion mode (G0, G1, G2, G3 or a canned cycle) for the axis words",
                )
                .hint("no motion mode is active (at program start or after G80); add G0 or G1"));
            }
            return Ok(if g43_1 { None } else { self.s.motion_mode });
        }
        let ijk = block.has(b'i') || block.has(b'j') || block.has(b'k');
        if ijk && matches!(self.s.motion_mode, Some(20 | 30)) {
            return Ok(self.s.motion_mode);
        }
        Ok(None)
    }

    fn word_error(&self, word: Option<super::block::Word>, problem: &str) -> LineError {
        match word {
            Some(word) => word.error(problem.to_string()),
            None => LineError::new(0, 0, problem.to_string()),
        }
    }

    /// LinuxCNC refuses words that no code in the block (or mode) uses (`check_g_codes`,
    /// `check_other_codes`).
    fn check_words(
        &self,
        line: &[u8],
        block: &Block,
        motion: Option<u32>,
    ) -> Result<(), LineError> {
        let mode0 = block.g_code(group::NON_MODAL);
        let motion = motion.unwrap_or(u32::MAX);
        let cycle = is_cycle(motion);
        let g10 = mode0 == Some(100);
        let arc = matches!(motion, 20 | 30);
        let comp = block.g_code(group::CUTTER_COMP);
        let comp_on = matches!(comp, Some(410 | 411 | 420 | 421));
        let unused = |letter: u8, users: &str| -> Result<(), LineError> {
            match block.word(letter) {
                Some(word) => Err(word
                    .error(format!(
                        "expected {} to come with {users}",
                        letter.to_ascii_uppercase() as char
                    ))
                    .hint(format!(
                        "no code in this block uses the {} word",
                        letter.to_ascii_uppercase() as char
                    ))),
                None => Ok(()),
            }
        };
        if cycle {
            for letter in [b'a', b'b', b'c'] {
                if let Some(word) = block.word(letter) {
                    return Err(word.error(format!(
                        "expected no {} word in a canned cycle",
                        letter.to_ascii_uppercase() as char
                    )));
                }
            }
        }
        if !comp_on {
            unused(b'd', "cutter compensation (G41, G42, G41.1, G42.1)")?;
        }
        if !matches!(block.g_code(group::TOOL_LENGTH), Some(430 | 432)) {
            unused(b'h', "a tool length offset (G43, G43.2)")?;
        }
        if !(arc || motion == 870 || g10) {
            unused(b'i', "an arc (G2/G3), G87 or G10")?;
            unused(b'j', "an arc (G2/G3), G87 or G10")?;
        }
        if !(arc || motion == 870) {
            unused(b'k', "an arc (G2/G3) or G87")?;
        }
        if !(cycle || g10 || comp_on) {
            unused(b'l', "G10, a canned cycle or cutter compensation")?;
        }
        let m_uses_p = matches!(block.m_code(mgroup::OVERRIDE), Some(50..=53));
        if !(g10
            || mode0 == Some(40)
            || block.g_code(group::PATH_CONTROL) == Some(640)
            || arc
            || matches!(motion, 740 | 820 | 840 | 860 | 880 | 890)
            || m_uses_p)
        {
            unused(
                b'p',
                "G2, G3, G4, G10, G64, G82, G84, G86, G88, G89 or M50-M53",
            )?;
        }
        if let (true, Some(p)) = (arc, block.word(b'p')) {
            let rounded = p.value.round();
            if (p.value - rounded).abs() > 0.001 || rounded < 1.0 {
                return Err(
                    p.error("expected a whole number of turns of 1 or more after P on an arc")
                );
            }
        }
        if !(matches!(motion, 730 | 830)
            || g10
            || block.m_code(mgroup::TOOL_CHANGE) == Some(61)
            || block.g_code(group::PATH_CONTROL) == Some(640))
        {
            unused(b'q', "G10, G64, G73, G83 or M61")?;
        }
        if !(arc || cycle || g10 || matches!(comp, Some(411 | 421))) {
            unused(b'r', "an arc (G2/G3), a canned cycle or G10")?;
        }
        match mode0 {
            Some(40) => {
                let g4 = block.g[group::NON_MODAL].expect("G4");
                if !block.has(b'p') {
                    return Err(g4
                        .error("expected a P word (dwell time in seconds) with G4")
                        .found(Found::Text(display_text(&line[block.start..block.end])))
                        .hint("write e.g. G4 P0.5 for half a second"));
                }
                if arc {
                    return Err(g4.error("expected G4 without G2 or G3 in its block: both use P"));
                }
            }
            Some(530) => {
                let g53 = block.g[group::NON_MODAL].expect("G53");
                if !matches!(motion, 0 | 10) {
                    return Err(g53.error("expected G0 or G1 with G53"));
                }
                let incremental = block.g_code(group::DISTANCE) == Some(910)
                    || (block.g_code(group::DISTANCE) != Some(900) && !self.s.absolute);
                if incremental {
                    return Err(g53.error("expected absolute distance mode (G90) with G53"));
                }
            }
            Some(100) => {
                let g10 = block.g[group::NON_MODAL].expect("G10");
                let l = block.value(b'l').map(|l| l.round() as i64);
                if !matches!(l, Some(1 | 2 | 10 | 11 | 20)) {
                    return Err(g10.error("expected G10 with L1, L2, L10, L11 or L20"));
                }
                let Some(p) = block.word(b'p') else {
                    return Err(
                        g10.error("expected a P word with G10 (coordinate system or tool number)")
                    );
                };
                let p_int = p.value.round();
                if (p.value - p_int).abs() > 0.0002 {
                    return Err(p.error("expected a whole-number P with G10"));
                }
                if matches!(l, Some(2 | 20)) && !(0.0..=9.0).contains(&p_int) {
                    return Err(p.error("expected P0 to P9 with G10 L2/L20 (0 = the active system, 1 = G54 … 9 = G59.3)"));
                }
                if matches!(l, Some(1 | 10 | 11)) && p_int < 1.0 {
                    return Err(
                        p.error("expected a tool number of 1 or more after P with G10 L1/L10/L11")
                    );
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// Executes a checked block in LinuxCNC's order of execution.
    pub fn execute(&mut self, line: &[u8], block: &Block, span: Span) -> Result<(), LineError> {
        let motion = self.motion_to_be(line, block)?;
        self.check_words(line, block, motion)?;

        // Feed rate mode.
        match block.g_code(group::FEED_MODE) {
            Some(930) => self.s.inverse_time = true,
            Some(940) => {
                // LinuxCNC clears the feed rate on every G94.
                self.s.inverse_time = false;
                self.s.feed_rate = 0.0;
                self.canon.set_feed_rate(0.0);
            }
            _ => {}
        }
        // F: in the units current before this block's G20/G21, as LinuxCNC does.
        if let Some(f) = block.word(b'f') {
            if f.value < 0.0 {
                return Err(f.error("expected a feed rate of zero or more"));
            }
            if !self.s.inverse_time {
                self.s.feed_rate = f.value;
                self.canon.set_feed_rate(f.value);
            }
        }
        // S.
        if let Some(s) = block.word(b's') {
            if s.value < 0.0 {
                return Err(s.error("expected a spindle speed of zero or more"));
            }
            self.s.speed = s.value;
            self.sync_spindle();
        }
        // T: select a tool from the table.
        if let Some(t) = block.word(b't') {
            let number = self.tool_number(t)?;
            self.s.selected_tool = Some(number);
        }
        // M6 / M61: tool change.
        match block.m[mgroup::TOOL_CHANGE] {
            Some(word) if word.code == 6 => {
                self.refuse_with_comp(word, "a tool change")?;
                let Some(selected) = self.s.selected_tool else {
                    return Err(word.error("expected a T word selecting the tool before M6"));
                };
                self.s.current_tool = selected;
                // LinuxCNC stops the spindle for a tool change.
                self.s.turning = Turning::Stopped;
                self.sync_spindle();
                self.set_tool_parameters();
                self.describe_spindle_tool(span);
            }
            Some(word) => {
                let Some(q) = block.word(b'q') else {
                    return Err(word.error("expected a Q word (tool number) with M61"));
                };
                self.s.current_tool = self.tool_number(q)?;
                self.set_tool_parameters();
                self.describe_spindle_tool(span);
            }
            None => {}
        }
        // Spindle.
        if let Some(word) = block.m[mgroup::SPINDLE] {
            self.s.turning = match word.code {
                3 => Turning::Clockwise,
                4 => Turning::CounterClockwise,
                _ => Turning::Stopped,
            };
            self.sync_spindle();
        }
        // Coolant.
        for word in block.m[mgroup::COOLANT].iter().chain(&block.second_coolant) {
            match word.code {
                7 => self.s.mist = true,
                8 => self.s.flood = true,
                _ => {
                    self.s.mist = false;
                    self.s.flood = false;
                }
            }
        }
        // Dwell.
        if block.g_code(group::NON_MODAL) == Some(40) {
            let p = block.word(b'p').expect("checked");
            if p.value < 0.0 {
                return Err(p.error("expected a dwell time of zero or more seconds"));
            }
            self.dwell(p.value, span)?;
        }
        // Plane.
        if let (Some(word), Some(_)) = (block.g[group::PLANE], self.comp.side) {
            let plane = match word.code {
                170 => Plane::XY,
                180 => Plane::ZX,
                _ => Plane::YZ,
            };
            if plane != self.s.plane {
                return Err(word
                    .error("expected no change of plane while cutter radius compensation is on"));
            }
        }
        match block.g_code(group::PLANE) {
            Some(170) => self.s.plane = Plane::XY,
            Some(180) => self.s.plane = Plane::ZX,
            Some(190) => self.s.plane = Plane::YZ,
            _ => {}
        }
        // Units.
        match block.g_code(group::UNITS) {
            Some(200) => self.set_units(LengthUnit::Inch),
            Some(210) => self.set_units(LengthUnit::Millimetre),
            _ => {}
        }
        // Cutter radius compensation.
        if let Some(code) = block.g_code(group::CUTTER_COMP) {
            let word = block.g[group::CUTTER_COMP].expect("comp word");
            self.cutter_compensation(code, block, span)
                .map_err(|e| e.located(word.start, word.end))?;
        }
        // Tool length offset.
        if let Some(word) = block.g[group::TOOL_LENGTH] {
            self.refuse_with_comp(word, "a change of tool length offset")?;
            self.tool_length_offset(word.code, block)?;
        }
        // Coordinate system.
        if let Some(word) = block.g[group::COORD_SYSTEM] {
            if word.code != 530 + 10 * self.s.origin_index as u32 {
                self.refuse_with_comp(word, "a change of coordinate system")?;
            }
        }
        if let Some(code) = block.g_code(group::COORD_SYSTEM) {
            let system = match code {
                540..=590 => (code / 10 - 53) as usize,
                _ => (code - 591 + 7) as usize,
            };
            self.select_coordinate_system(system);
        }
        // Path control.
        match block.g_code(group::PATH_CONTROL) {
            Some(610) | Some(611) => self.canon.blend = Blend::ExactStop,
            Some(640) => {
                let tolerance = match block.word(b'p') {
                    Some(p) if p.value < 0.0 => {
                        return Err(p.error("expected a G64 P tolerance of zero or more"));
                    }
                    Some(p) if p.value > 0.0 => Some(self.s.units.to_metres(p.value)),
                    _ => None,
                };
                let naive_cam = match block.word(b'q') {
                    Some(q) if q.value < 0.0 => {
                        return Err(q.error("expected a G64 Q tolerance of zero or more"));
                    }
                    Some(q) => (q.value > 0.0).then(|| self.s.units.to_metres(q.value)),
                    // As LinuxCNC: G64 P without Q sets the naive-CAM tolerance to P (its
                    // interpreter test g6164: `G64P1` → SET_NAIVECAM_TOLERANCE(1)).
                    None => tolerance,
                };
                self.canon.blend = Blend::Continuous {
                    tolerance,
                    naive_cam,
                };
            }
            _ => {}
        }
        // Distance modes.
        match block.g_code(group::DISTANCE) {
            Some(900) => self.s.absolute = true,
            Some(910) => self.s.absolute = false,
            _ => {}
        }
        match block.g_code(group::ARC_DISTANCE) {
            Some(901) => self.s.ijk_absolute = true,
            Some(911) => self.s.ijk_absolute = false,
            _ => {}
        }
        // Retract mode.
        match block.g_code(group::RETURN_MODE) {
            Some(980) => self.s.retract_to_r = false,
            Some(990) => self.s.retract_to_r = true,
            _ => {}
        }
        // Non-modal codes.
        if let Some(word) = block.g[group::NON_MODAL] {
            match word.code {
                280 | 300 => self.refuse_with_comp(word, "G28/G30")?,
                530 => self.refuse_with_comp(word, "G53")?,
                520 | 920..=923 => self.refuse_with_comp(word, "a change of axis offsets")?,
                _ => {}
            }
            match word.code {
                100 => self.g10(block)?,
                280 | 300 => self.go_home(word.code, block, span)?,
                281 | 301 => self.save_home(word.code),
                520 | 920..=923 => self.axis_offsets(word.code, block),
                _ => {} // G4 above, G53 with the motion
            }
        }
        // Motion.
        if let Some(code) = block.g_code(group::MOTION) {
            if code == 800 {
                self.s.motion_mode = None;
                self.s.cycle.initial_level = None;
            }
        }
        if let Some(code) = motion {
            if !is_cycle(code) {
                self.s.cycle.initial_level = None;
            }
            match code {
                0 | 10 => self.straight(code, block, span)?,
                20 | 30 => self.arc(line, code, block, span)?,
                _ => self.cycle(code, block, span)?,
            }
        }
        // After a tool change LinuxCNC re-reads the position from the machine.
        if block.m[mgroup::TOOL_CHANGE].is_some() {
            self.refresh_position();
        }
        // Stops: the move compensation holds back is sent first.
        if let Some(word) = block.m[mgroup::STOP] {
            if self.comp.holds_anything() {
                let current = self.s.current;
                let point = match self.s.plane {
                    Plane::ZX => [current[2], current[0]],
                    _ => [current[0], current[1]],
                };
                self.move_endpoint_and_flush(point)
                    .map_err(|e| word.error(e.problem))?;
            }
            match word.code {
                2 | 30 => {
                    self.ended_by_program_end = true;
                    self.finished = true;
                }
                _ => self.canon.program.warnings.push(Warning {
                    span,
                    message: format!(
                        "M{} (program pause) is ignored by the simulation",
                        word.code
                    ),
                }),
            }
        }
        Ok(())
    }

    fn dwell(&mut self, seconds: f64, span: Span) -> Result<(), LineError> {
        if self.comp_dwell(seconds, span) {
            return Ok(());
        }
        self.canon
            .dwell(seconds, span)
            .map_err(|limit| too_many_moves(limit.0))
    }

    /// LinuxCNC refuses some codes while cutter radius compensation is on.
    fn refuse_with_comp(&self, word: super::block::CodeWord, what: &str) -> Result<(), LineError> {
        if self.comp.side.is_some() {
            return Err(word.error(format!(
                "expected {what} only with cutter radius compensation off (G40)"
            )));
        }
        Ok(())
    }

    fn sync_spindle(&mut self) {
        self.canon.spindle = match self.s.turning {
            Turning::Stopped => Spindle::Off,
            Turning::Clockwise => Spindle::Clockwise { rpm: self.s.speed },
            Turning::CounterClockwise => Spindle::CounterClockwise { rpm: self.s.speed },
        };
    }

    /// A T/Q/P word naming a tool of the table (0: no tool).
    pub fn tool_number(&self, word: super::block::Word) -> Result<i64, LineError> {
        let rounded = word.value.round();
        if (word.value - rounded).abs() > 0.0001 || rounded < 0.0 {
            return Err(word.error("expected a whole tool number of 0 or more"));
        }
        let number = rounded as i64;
        if number != 0 && self.s.tool(number).is_none() {
            let known: Vec<String> = self.s.tools.iter().map(|t| t.number.to_string()).collect();
            return Err(word.error(format!("expected a tool of the tool table; tool {number} is not in it"),
            )
            .hint(if known.is_empty() {
                "the tool table is empty: name a LinuxCNC tool table with the scenario's [program] tool_table (or inspect --tool-table)".to_string()
            } else {
                format!("the table has tools {}", known.join(", "))
            }));
        }
        Ok(number)
    }

    pub fn spindle_tool(&self) -> ToolEntry {
        self.s
            .tool(self.s.current_tool)
            .copied()
            .unwrap_or(ToolEntry {
                number: 0,
                offset: [0.0; 6],
                diameter: 0.0,
            })
    }

    /// Records the tool now in the spindle among the program's tools (its table diameter in
    /// metres), once per tool, where it has one: what a cut uses when the scenario gives no
    /// diameter.
    fn describe_spindle_tool(&mut self, span: Span) {
        let tool = self.spindle_tool();
        if tool.number == 0 || tool.diameter <= 0.0 {
            return;
        }
        let name = format!("T{}", tool.number);
        let tools = &mut self.canon.program.tools;
        if tools
            .iter()
            .any(|t| t.name.as_deref() == Some(name.as_str()))
        {
            return;
        }
        let metres = self.options.gcode.user_units.metres();
        tools.push(crate::program::types::ProgramTool {
            name: Some(name),
            // A tool table says no more than the diameter and the length offset.
            kind: "tool table".into(),
            diameter: tool.diameter * metres,
            length: tool.offset[2] * metres,
            span,
            ..Default::default()
        });
    }

    fn set_tool_parameters(&mut self) {
        let tool = self.spindle_tool();
        self.params.set(params::TOOL_NUMBER, tool.number as f64);
        for axis in 0..6 {
            self.params
                .set(params::TOOL_OFFSET + axis, tool.offset[axis]);
        }
        self.params.set(params::TOOL_DIAMETER, tool.diameter);
    }

    fn set_units(&mut self, units: LengthUnit) {
        self.canon.use_length_units(units);
        if units == self.s.units {
            return;
        }
        let factor = self.s.units.metres() / units.metres();
        let s = &mut self.s;
        for values in [
            &mut s.current,
            &mut s.origin_offset,
            &mut s.axis_offset,
            &mut s.tool_offset,
        ] {
            for value in values.iter_mut().take(3) {
                *value *= factor;
            }
        }
        s.units = units;
        self.comp.scale(factor);
        // The feed stays what the machine was told; the interpreter's number follows it.
        self.s.feed_rate = self.canon.feed_rate_in(units);
    }

    fn tool_length_offset(&mut self, code: u32, block: &Block) -> Result<(), LineError> {
        let user = |interp: &Self, offset: &Axes| -> Axes {
            let mut out = *offset;
            for value in out.iter_mut().take(3) {
                *value = interp.user_to_program(*value);
            }
            out
        };
        let offset: Axes = match code {
            490 => [0.0; 6],
            430 => match block.word(b'h') {
                Some(h) => {
                    let number = self.tool_number(h)?;
                    let tool = if number == 0 {
                        self.spindle_tool()
                    } else {
                        *self.s.tool(number).expect("checked")
                    };
                    user(self, &tool.offset)
                }
                None => user(self, &self.spindle_tool().offset),
            },
            431 => {
                let mut offset = self.s.tool_offset;
                for (axis, letter) in super::block::AXIS_LETTERS.iter().enumerate() {
                    if let Some(value) = block.value(*letter) {
                        offset[axis] = value;
                    }
                }
                offset
            }
            _ => {
                let mut offset = self.s.tool_offset;
                match block.word(b'h') {
                    Some(h) => {
                        let number = self.tool_number(h)?;
                        let tool = if number == 0 {
                            self.spindle_tool()
                        } else {
                            *self.s.tool(number).expect("checked")
                        };
                        let add = user(self, &tool.offset);
                        for axis in 0..6 {
                            offset[axis] += add[axis];
                        }
                    }
                    None => {
                        // LinuxCNC 2.9 looks up tool -1 here and fails; so does cncsim.
                        let g43 = block.g[group::TOOL_LENGTH].expect("G43.2");
                        return Err(g43.error("expected an H word with G43.2")
                            .hint("LinuxCNC 2.9 refuses G43.2 with axis words alone; use G43.1 or G43.2 H"));
                    }
                }
                offset
            }
        };
        self.canon.use_tool_length_offset(offset);
        let old = self.s.tool_offset;
        let (dx, dy) = rotate(old[0] - offset[0], old[1] - offset[1], -self.s.rotation_xy);
        self.s.current[0] += dx;
        self.s.current[1] += dy;
        for axis in 2..6 {
            self.s.current[axis] += old[axis] - offset[axis];
        }
        self.s.tool_offset = offset;
        Ok(())
    }

    /// The coordinate system `system` (1 = G54) from the parameters, in program units.
    pub(super) fn system_origin(&self, system: usize) -> (Axes, f64) {
        let mut origin = [0.0; 6];
        for (axis, value) in origin.iter_mut().enumerate() {
            let stored = self.params.get(coordinate_system_index(system, axis));
            *value = if axis < 3 {
                self.user_to_program(stored)
            } else {
                stored
            };
        }
        (origin, self.params.get(coordinate_system_index(system, 9)))
    }

    pub(super) fn announce_offsets(&mut self) {
        self.canon.set_g5x_offset(self.s.origin_offset);
        self.canon.set_g92_offset(self.s.axis_offset);
        self.canon.set_xy_rotation(self.s.rotation_xy);
    }

    /// The current point expressed in coordinate system `system` (LinuxCNC
    /// `find_current_in_system`).
    fn current_in_system(&self, system: usize) -> Axes {
        let s = &self.s;
        let mut p = s.current;
        for axis in 0..6 {
            p[axis] += s.axis_offset[axis];
        }
        let (x, y) = rotate(p[0], p[1], s.rotation_xy);
        p[0] = x;
        p[1] = y;
        let (origin, rotation) = self.system_origin(system);
        for axis in 0..6 {
            p[axis] += s.origin_offset[axis] - origin[axis];
        }
        let (x, y) = rotate(p[0], p[1], -rotation);
        p[0] = x;
        p[1] = y;
        if self.params.get(params::G92_APPLIED) != 0.0 {
            for axis in 0..6 {
                let stored = self.params.get(params::G92_OFFSET + axis);
                p[axis] -= if axis < 3 {
                    self.user_to_program(stored)
                } else {
                    stored
                };
            }
        }
        p
    }

    fn select_coordinate_system(&mut self, system: usize) {
        if system == self.s.origin_index {
            return;
        }
        self.s.current = self.current_in_system(system);
        self.s.origin_index = system;
        self.params.set(params::ACTIVE_SYSTEM, system as f64);
        let (origin, rotation) = self.system_origin(system);
        self.s.origin_offset = origin;
        self.s.rotation_xy = rotation;
        self.announce_offsets();
    }

    /// G10 L2/L20 (coordinate systems) and L1/L10/L11 (tool table).
    fn g10(&mut self, block: &Block) -> Result<(), LineError> {
        let l = block.value(b'l').expect("checked").round() as i64;
        let p = block.value(b'p').expect("checked").round() as i64;
        match l {
            2 | 20 => self.g10_coordinate_system(l, p, block),
            _ => self.g10_tool(l, p, block),
        }
    }

    fn g10_coordinate_system(&mut self, l: i64, p: i64, block: &Block) -> Result<(), LineError> {
        for letter in [b'i', b'j'] {
            if let Some(word) = block.word(letter) {
                return Err(word.error("expected no I or J word with G10 L2/L20"));
            }
        }
        let system = if p == 0 {
            self.s.origin_index
        } else {
            p as usize
        };
        let current = self.current_in_system(system);
        let rotation_index = coordinate_system_index(system, 9);
        let r = match block.word(b'r') {
            Some(word) if l == 20 => {
                return Err(word.error("expected no R word with G10 L20"));
            }
            Some(word) => {
                self.params.set(rotation_index, word.value);
                word.value
            }
            None => self.params.get(rotation_index),
        };
        let stored = |interp: &Self, axis: usize| -> f64 {
            let value = interp.params.get(coordinate_system_index(system, axis));
            if axis < 3 {
                interp.user_to_program(value)
            } else {
                value
            }
        };
        let mut origin = [0.0; 6];
        if l == 20 {
            let (mut x, mut y) = (current[0], current[1]);
            if let Some(value) = block.value(b'x') {
                x = value;
            }
            if let Some(value) = block.value(b'y') {
                y = value;
            }
            let (old_x, old_y) = rotate(current[0], current[1], r);
            let (x, y) = rotate(x, y, r);
            origin[0] = old_x + stored(self, 0) - x;
            origin[1] = old_y + stored(self, 1) - y;
            for axis in 0..2 {
                let user = self.program_to_user(origin[axis]);
                self.params.set(coordinate_system_index(system, axis), user);
            }
            if system == self.s.origin_index {
                let (cx, cy) = rotate(self.s.current[0], self.s.current[1], self.s.rotation_xy);
                self.s.current[0] = cx;
                self.s.current[1] = cy;
                self.s.rotation_xy = 0.0;
            }
        } else {
            for axis in 0..2 {
                origin[axis] = match block.value(super::block::AXIS_LETTERS[axis]) {
                    Some(value) => {
                        let user = self.program_to_user(value);
                        self.params.set(coordinate_system_index(system, axis), user);
                        value
                    }
                    None => stored(self, axis),
                };
            }
        }
        for axis in 2..6 {
            origin[axis] = match block.value(super::block::AXIS_LETTERS[axis]) {
                Some(value) => {
                    let value = if l == 20 {
                        current[axis] + stored(self, axis) - value
                    } else {
                        value
                    };
                    let user = if axis < 3 {
                        self.program_to_user(value)
                    } else {
                        value
                    };
                    self.params.set(coordinate_system_index(system, axis), user);
                    value
                }
                None => stored(self, axis),
            };
        }
        if system == self.s.origin_index {
            let s = &mut self.s;
            let (cx, cy) = rotate(s.current[0], s.current[1], s.rotation_xy);
            s.current[0] = cx;
            s.current[1] = cy;
            for axis in 0..6 {
                s.current[axis] += s.origin_offset[axis] - origin[axis];
            }
            let (cx, cy) = rotate(s.current[0], s.current[1], -r);
            s.current[0] = cx;
            s.current[1] = cy;
            s.origin_offset = origin;
            s.rotation_xy = r;
            self.announce_offsets();
        }
        Ok(())
    }

    fn g10_tool(&mut self, l: i64, p: i64, block: &Block) -> Result<(), LineError> {
        let p_word = block.word(b'p').expect("checked");
        let number = self.tool_number(p_word)?;
        let has_values = super::block::AXIS_LETTERS.iter().any(|&l| block.has(l))
            || block.has(b'r')
            || block.has(b'q')
            || block.has(b'i')
            || block.has(b'j');
        let g10 = block.g[group::NON_MODAL].expect("G10");
        if !has_values {
            return Err(g10.error("expected offsets (X Y Z A B C) or R with G10 L1/L10/L11"));
        }
        let _ = p;
        let index = self
            .s
            .tools
            .iter()
            .position(|tool| tool.number == number)
            .expect("checked");
        let mut entry = self.s.tools[index];
        if l == 1 {
            for (axis, letter) in super::block::AXIS_LETTERS.iter().enumerate() {
                if let Some(value) = block.value(*letter) {
                    entry.offset[axis] = if axis < 3 {
                        self.program_to_user(value)
                    } else {
                        value
                    };
                }
            }
        } else {
            let system = if l == 11 { 9 } else { self.s.origin_index };
            // The current point in that system without the tool length offset.
            let mut t = self.current_in_system(system);
            for axis in 0..6 {
                t[axis] += self.s.tool_offset[axis];
            }
            if l == 11 && self.params.get(params::G92_APPLIED) != 0.0 {
                for axis in 0..6 {
                    let stored = self.params.get(params::G92_OFFSET + axis);
                    t[axis] += if axis < 3 {
                        self.user_to_program(stored)
                    } else {
                        stored
                    };
                }
            }
            let rotation = self.params.get(coordinate_system_index(system, 9));
            let old = [
                self.user_to_program(entry.offset[0]),
                self.user_to_program(entry.offset[1]),
            ];
            match (block.value(b'x'), block.value(b'y')) {
                (Some(x), Some(y)) => {
                    let (tx, ty) = rotate(t[0] - x, t[1] - y, rotation);
                    entry.offset[0] = self.program_to_user(tx);
                    entry.offset[1] = self.program_to_user(ty);
                }
                (Some(x), None) => {
                    let (_, oy) = rotate(old[0], old[1], -rotation);
                    let (ox, oy) = rotate(0.0, oy, rotation);
                    let (tx, ty) = rotate(t[0] - x, 0.0, rotation);
                    entry.offset[0] = self.program_to_user(tx + ox);
                    entry.offset[1] = self.program_to_user(ty + oy);
                }
                (None, Some(y)) => {
                    let (ox, _) = rotate(old[0], old[1], -rotation);
                    let (ox, oy) = rotate(ox, 0.0, rotation);
                    let (tx, ty) = rotate(0.0, t[1] - y, rotation);
                    entry.offset[0] = self.program_to_user(tx + ox);
                    entry.offset[1] = self.program_to_user(ty + oy);
                }
                (None, None) => {}
            }
            for axis in 2..6 {
                if let Some(value) = block.value(super::block::AXIS_LETTERS[axis]) {
                    let offset = t[axis] - value;
                    entry.offset[axis] = if axis < 3 {
                        self.program_to_user(offset)
                    } else {
                        offset
                    };
                }
            }
        }
        if let Some(r) = block.value(b'r') {
            entry.diameter = self.program_to_user(r) * 2.0;
        }
        self.s.tools[index] = entry;
        if number == self.s.current_tool {
            self.set_tool_parameters();
        }
        Ok(())
    }

    /// G28 / G30: through the programmed point to the stored home position.
    fn go_home(&mut self, code: u32, block: &Block, span: Span) -> Result<(), LineError> {
        let through = self.find_ends(block)?;
        self.traverse(&through, span)?;
        let base = if code == 280 {
            params::G28_HOME
        } else {
            params::G30_HOME
        };
        let mut home = [0.0; 6];
        for (axis, value) in home.iter_mut().enumerate() {
            let stored = self.params.get(base + axis);
            *value = if axis < 3 {
                self.user_to_program(stored)
            } else {
                stored
            };
        }
        let relative = self.relative_to_program(&home);
        let mut end = through;
        let any_axis = super::block::AXIS_LETTERS.iter().any(|&l| block.has(l));
        for (axis, &letter) in super::block::AXIS_LETTERS.iter().enumerate() {
            if !any_axis || block.has(letter) {
                end[axis] = relative[axis];
            }
        }
        self.traverse(&end, span)
    }

    /// The current point from the machine's position (LinuxCNC `refresh_actual_position`).
    fn refresh_position(&mut self) {
        let position = self.canon.position();
        let metres = self.s.units.metres();
        let mut machine = [0.0; 6];
        for axis in 0..3 {
            machine[axis] = position.linear[axis] / metres;
            machine[axis + 3] = position.rotary[axis].to_degrees();
        }
        self.s.current = self.relative_to_program(&machine);
    }

    /// A machine point (program units) in program coordinates (LinuxCNC `find_relative`).
    pub fn relative_to_program(&self, machine: &Axes) -> Axes {
        let s = &self.s;
        let mut p = [0.0; 6];
        let (x, y) = rotate(
            machine[0] - s.origin_offset[0] - s.tool_offset[0],
            machine[1] - s.origin_offset[1] - s.tool_offset[1],
            -s.rotation_xy,
        );
        p[0] = x - s.axis_offset[0];
        p[1] = y - s.axis_offset[1];
        p[2] = machine[2] - s.origin_offset[2] - s.axis_offset[2] - s.tool_offset[2];
        for axis in 3..6 {
            p[axis] = machine[axis] - s.origin_offset[axis] - s.axis_offset[axis];
        }
        p
    }

    /// G28.1 / G30.1: store the current machine position.
    fn save_home(&mut self, code: u32) {
        let s = &self.s;
        let (x, y) = rotate(
            s.current[0] + s.axis_offset[0],
            s.current[1] + s.axis_offset[1],
            s.rotation_xy,
        );
        let mut machine = [0.0; 6];
        machine[0] = x + s.tool_offset[0] + s.origin_offset[0];
        machine[1] = y + s.tool_offset[1] + s.origin_offset[1];
        for axis in 2..6 {
            machine[axis] =
                s.current[axis] + s.tool_offset[axis] + s.origin_offset[axis] + s.axis_offset[axis];
        }
        let base = if code == 281 {
            params::G28_HOME
        } else {
            params::G30_HOME
        };
        for (axis, value) in machine.iter().enumerate() {
            let user = if axis < 3 {
                self.program_to_user(*value)
            } else {
                *value
            };
            self.params.set(base + axis, user);
        }
    }

    /// G52, G92, G92.1, G92.2, G92.3.
    fn axis_offsets(&mut self, code: u32, block: &Block) {
        match code {
            520 | 920 => {
                self.params.set(params::G92_APPLIED, 1.0);
                for (axis, &letter) in super::block::AXIS_LETTERS.iter().enumerate() {
                    if let Some(value) = block.value(letter) {
                        let s = &mut self.s;
                        if code == 520 {
                            s.current[axis] += s.axis_offset[axis] - value;
                            s.axis_offset[axis] = value;
                        } else {
                            s.axis_offset[axis] = s.current[axis] + s.axis_offset[axis] - value;
                            s.current[axis] = value;
                        }
                    }
                }
                self.store_axis_offsets();
            }
            921 | 922 => {
                self.params.set(params::G92_APPLIED, 0.0);
                let s = &mut self.s;
                for axis in 0..6 {
                    s.current[axis] += s.axis_offset[axis];
                    s.axis_offset[axis] = 0.0;
                }
                if code == 921 {
                    for axis in 0..9 {
                        self.params.set(params::G92_OFFSET + axis, 0.0);
                    }
                }
            }
            _ => {
                self.params.set(params::G92_APPLIED, 1.0);
                for axis in 0..6 {
                    let stored = self.params.get(params::G92_OFFSET + axis);
                    let value = if axis < 3 {
                        self.user_to_program(stored)
                    } else {
                        stored
                    };
                    let s = &mut self.s;
                    s.current[axis] += s.axis_offset[axis] - value;
                    s.axis_offset[axis] = value;
                }
            }
        }
        self.canon.set_g92_offset(self.s.axis_offset);
    }

    fn store_axis_offsets(&mut self) {
        for axis in 0..6 {
            let value = self.s.axis_offset[axis];
            let user = if axis < 3 {
                self.program_to_user(value)
            } else {
                value
            };
            self.params.set(params::G92_OFFSET + axis, user);
        }
    }
}

pub(super) fn too_many_moves(limit: usize) -> LineError {
    LineError::new(
        0,
        0,
        format!(
        "expected at most {limit} moves from one program; this one makes more (an endless loop?)"
    ),
    )
    .hint("the limit is GcodeOptions::max_moves")
}
