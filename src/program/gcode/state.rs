//! The interpreter's state: LinuxCNC's `_setup` in program units, the parameters, the call
//! frames, and the predefined named parameters computed from the state.

use std::collections::HashMap;
use std::path::Path;
use std::rc::Rc;

use super::canon::{Axes, Canon};
use super::comp::Compensation;
use super::control::{Frame, LoopFlags, Sub};
use super::expr::Parameters;
use super::params::{self, Store};
use super::Errors;
use crate::program::error::{Found, ProgramError, ProgramErrors};
use crate::program::options::{LengthUnit, ReadOptions};
use crate::program::source::saturate;
use crate::program::types::{Plane, Program, Span};

/// How the spindle turns (LinuxCNC `CANON_DIRECTION`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Turning {
    Stopped,
    Clockwise,
    CounterClockwise,
}

/// One tool table entry, in user (machine) units like LinuxCNC's table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ToolEntry {
    pub number: i64,
    /// X Y Z (user units) and A B C (degrees).
    pub offset: Axes,
    pub diameter: f64,
}

/// What the canned cycles remember between blocks (LinuxCNC `cycle_*`).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct CycleMemory {
    pub r: f64,
    pub bottom: f64,
    pub p: f64,
    pub q: f64,
    pub i: f64,
    pub j: f64,
    pub k: f64,
    /// The initial level (G98 returns here) while a series of cycles runs.
    pub initial_level: Option<f64>,
}

/// Modal state, positions and offsets in program units (mm or inch; A B C in degrees).
pub(super) struct State {
    pub units: LengthUnit,
    pub absolute: bool,
    pub ijk_absolute: bool,
    pub plane: Plane,
    pub inverse_time: bool,
    /// The F number in program units per minute.
    pub feed_rate: f64,
    /// Active motion code in tenths (G1 = 10, G81 = 810); `None` after G80.
    pub motion_mode: Option<u32>,
    pub current: Axes,
    pub origin_offset: Axes,
    pub axis_offset: Axes,
    pub tool_offset: Axes,
    pub rotation_xy: f64,
    /// 1 = G54 … 9 = G59.3.
    pub origin_index: usize,
    /// G99 (retract to R) when true, G98 (retract to the initial level) when false.
    pub retract_to_r: bool,
    pub cycle: CycleMemory,
    pub turning: Turning,
    pub speed: f64,
    pub mist: bool,
    pub flood: bool,
    /// The tool in the spindle (0 = none).
    pub current_tool: i64,
    /// The tool the last T word selected.
    pub selected_tool: Option<i64>,
    pub tools: Vec<ToolEntry>,
    pub block_delete: bool,
}

impl State {
    pub fn tool(&self, number: i64) -> Option<&ToolEntry> {
        self.tools.iter().find(|tool| tool.number == number)
    }
}

pub(super) struct Interpreter<'a> {
    pub source: &'a Path,
    pub options: &'a ReadOptions,
    pub errors: Errors,
    pub canon: Canon,
    pub s: State,
    pub params: Store,
    pub frames: Vec<Frame>,
    pub subs: HashMap<String, Rc<Sub>>,
    pub flow: LoopFlags,
    pub comp: Compensation,
    /// The value the last subroutine returned (`#<_value>`), and whether it returned one.
    pub returned: (f64, bool),
    pub percent_open: bool,
    pub seen_content: bool,
    /// Whether a line with anything but blanks has been read (a '%' opens the program only
    /// before that).
    pub seen_nonblank: bool,
    pub finished: bool,
    pub ended_by_program_end: bool,
    /// Blocks executed so far (bounded by `GcodeOptions::max_blocks`).
    pub blocks: u64,
    /// The line being executed (1-based), for `#<_line>`.
    pub line_number: usize,
}

impl<'a> Interpreter<'a> {
    pub fn new(source: &'a Path, options: &'a ReadOptions) -> Self {
        let gcode = &options.gcode;
        let user = gcode.user_units;
        let mut params = Store::new();
        for (base, home) in [
            (params::G28_HOME, &gcode.g28_home),
            (params::G30_HOME, &gcode.g30_home),
        ] {
            for axis in 0..3 {
                params.set(base + axis, user.from_metres(home.linear[axis]));
                params.set(base + 3 + axis, home.rotary[axis].to_degrees());
            }
        }
        params.set(params::ACTIVE_SYSTEM, 1.0);
        // The work offset is G54's origin, as a control's offset table holds it.
        for (axis, offset) in options.work_offset.iter().enumerate() {
            params.set(
                params::coordinate_system_index(1, axis),
                user.from_metres(*offset),
            );
        }
        let tools = gcode
            .tools
            .iter()
            .map(|tool| {
                let mut offset = [0.0; 6];
                for axis in 0..3 {
                    offset[axis] = user.from_metres(tool.offset.linear[axis]);
                    offset[axis + 3] = tool.offset.rotary[axis].to_degrees();
                }
                ToolEntry {
                    number: i64::from(tool.number),
                    offset,
                    diameter: user.from_metres(tool.diameter),
                }
            })
            .collect();
        let program = Program {
            source: source.to_path_buf(),
            ..Program::default()
        };
        let mut interpreter = Interpreter {
            source,
            options,
            errors: Errors::new(options.max_errors),
            canon: Canon::new(program, options),
            s: State {
                units: gcode.initial_units,
                absolute: true,
                // LinuxCNC starts in G91.1: I J K are offsets from the arc's start point.
                ijk_absolute: false,
                plane: Plane::XY,
                inverse_time: false,
                feed_rate: 0.0,
                motion_mode: None,
                current: [0.0; 6],
                origin_offset: [0.0; 6],
                axis_offset: [0.0; 6],
                tool_offset: [0.0; 6],
                rotation_xy: 0.0,
                origin_index: 1,
                retract_to_r: true,
                cycle: CycleMemory::default(),
                turning: Turning::Stopped,
                speed: 0.0,
                mist: false,
                flood: false,
                current_tool: 0,
                selected_tool: None,
                tools,
                block_delete: gcode.block_delete,
            },
            params,
            frames: vec![Frame::main()],
            subs: HashMap::new(),
            flow: LoopFlags::default(),
            comp: Compensation::new(),
            returned: (0.0, false),
            percent_open: false,
            seen_content: false,
            seen_nonblank: false,
            finished: false,
            ended_by_program_end: false,
            blocks: 0,
            line_number: 0,
        };
        if options.work_offset != [0.0; 3] {
            // G54 active from the start: the machine is at its zero, which the program sees
            // at minus the offset.
            let (origin, _) = interpreter.system_origin(1);
            interpreter.s.origin_offset = origin;
            for (current, o) in interpreter.s.current.iter_mut().zip(origin) {
                *current = -o;
            }
            interpreter.announce_offsets();
        }
        interpreter
    }

    pub fn finish(
        mut self,
        line_count: usize,
        byte_count: usize,
    ) -> Result<Program, ProgramErrors> {
        if self.comp.holds_anything() {
            // The program ended with compensation holding a move back (LinuxCNC would drop
            // it with the file's missing end): send it.
            let _ = self.dequeue();
        }
        if self.percent_open && !self.ended_by_program_end && !self.finished {
            self.errors.push(
                ProgramError::new(
                    self.source,
                    Some(Span {
                        line: saturate(line_count + 1),
                        column: 1,
                        byte_offset: saturate(byte_count),
                    }),
                    "expected a closing '%' line (the program opened with '%')",
                )
                .found(Found::EndOfFile)
                .hint("end the program with M2/M30 or a '%' line"),
            );
        }
        self.errors.finish(self.canon.program)
    }

    /// A length in program units converted to user (machine) units, for the parameters.
    pub fn program_to_user(&self, value: f64) -> f64 {
        value * self.s.units.metres() / self.options.gcode.user_units.metres()
    }

    /// A length in user units converted to program units.
    pub fn user_to_program(&self, value: f64) -> f64 {
        value * self.options.gcode.user_units.metres() / self.s.units.metres()
    }

    /// The position in the active coordinate system, as #5420–#5428 report it.
    fn current_position(&self, axis: usize) -> f64 {
        self.s.current[axis]
    }

    /// LinuxCNC's predefined read-only named parameters that mean something here.
    fn predefined(&self, name: &str) -> Option<f64> {
        let s = &self.s;
        let flag = |b: bool| if b { 1.0 } else { 0.0 };
        let value = match name {
            "_x" => self.current_position(0),
            "_y" => self.current_position(1),
            "_z" => self.current_position(2),
            "_a" => self.current_position(3),
            "_b" => self.current_position(4),
            "_c" => self.current_position(5),
            "_u" | "_v" | "_w" => 0.0,
            "_abs_x" | "_abs_y" | "_abs_z" | "_abs_a" | "_abs_b" | "_abs_c" => {
                let axis = match name.as_bytes()[5] {
                    b'x' => 0,
                    b'y' => 1,
                    b'z' => 2,
                    b'a' => 3,
                    b'b' => 4,
                    _ => 5,
                };
                let machine = self.canon.machine(&s.current);
                if axis < 3 {
                    self.options
                        .gcode
                        .user_units
                        .from_metres(machine.linear[axis])
                } else {
                    machine.rotary[axis - 3].to_degrees()
                }
            }
            "_line" => self.line_number as f64,
            "_motion_mode" => s.motion_mode.map_or(800.0, f64::from),
            "_plane" => match s.plane {
                Plane::XY => 170.0,
                Plane::ZX => 180.0,
                Plane::YZ => 190.0,
            },
            "_ccomp" => match self.comp.side {
                None => 400.0,
                Some(super::comp::Side::Left) => 410.0,
                Some(super::comp::Side::Right) => 420.0,
            },
            "_metric" => flag(s.units == LengthUnit::Millimetre),
            "_imperial" => flag(s.units == LengthUnit::Inch),
            "_absolute" => flag(s.absolute),
            "_incremental" => flag(!s.absolute),
            "_inverse_time" => flag(s.inverse_time),
            "_units_per_minute" => flag(!s.inverse_time),
            "_units_per_rev" => 0.0,
            "_coord_system" => match s.origin_index {
                1..=6 => 530.0 + 10.0 * s.origin_index as f64,
                index => 590.0 + (index - 6) as f64,
            },
            "_tool_offset" => flag(s.tool_offset.iter().any(|&v| v != 0.0)),
            "_retract_r_plane" => flag(s.retract_to_r),
            "_retract_old_z" => flag(!s.retract_to_r),
            "_spindle_rpm_mode" => 1.0,
            "_spindle_css_mode" => 0.0,
            "_ijk_absolute_mode" => flag(s.ijk_absolute),
            "_lathe_diameter_mode" => 0.0,
            "_lathe_radius_mode" => 1.0,
            "_spindle_on" => flag(s.turning != super::state::Turning::Stopped),
            "_spindle_cw" => flag(s.turning == super::state::Turning::Clockwise),
            "_mist" => flag(s.mist),
            "_flood" => flag(s.flood),
            "_speed_override" | "_feed_override" => 1.0,
            "_adaptive_feed" | "_feed_hold" => 0.0,
            "_feed" => s.feed_rate,
            "_rpm" => s.speed,
            "_current_tool" => s.current_tool as f64,
            "_current_pocket" => 0.0,
            "_selected_tool" => s.selected_tool.map_or(-1.0, |t| t as f64),
            "_selected_pocket" => -1.0,
            "_value" => self.returned.0,
            "_value_returned" => flag(self.returned.1),
            "_call_level" => (self.frames.len() - 1) as f64,
            "_remap_level" => 0.0,
            "_task" => 0.0,
            "_vmajor" => 2.0,
            "_vminor" => 9.0,
            _ => return None,
        };
        Some(value)
    }
}

impl Parameters for Interpreter<'_> {
    fn numbered(&self, index: usize) -> f64 {
        if (params::CURRENT_POSITION..params::CURRENT_POSITION + 6).contains(&index) {
            return self.current_position(index - params::CURRENT_POSITION);
        }
        self.params.get(index)
    }

    fn named(&self, name: &str) -> Result<f64, String> {
        if let Some(rest) = name.strip_prefix('_') {
            if let Some(value) = self.params.global(name) {
                return Ok(value);
            }
            if let Some(value) = self.predefined(name) {
                return Ok(value);
            }
            if rest.starts_with("ini[") || rest.starts_with("hal[") {
                return Err(format!(
                    "expected a parameter cncsim knows; #<{name}> reads the machine's INI file or HAL, which cncsim does not have"
                ));
            }
            return Err(format!(
                "expected a defined parameter; #<{name}> is not defined"
            ));
        }
        self.frames
            .last()
            .and_then(|frame| frame.locals.get(name).copied())
            .ok_or_else(|| format!("expected a defined parameter; #<{name}> is not defined"))
    }

    fn exists(&self, name: &str) -> bool {
        self.named(name).is_ok()
    }
}
