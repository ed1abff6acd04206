//! G-code (RS274/NGC) as LinuxCNC reads it.
//!
//! Each line is one block. A block is first compacted (comments taken out, spaces and tabs
//! dropped, letters lower-cased, as LinuxCNC's `read_text`/`close_and_downcase` does), then
//! split into words, then checked (one word per letter, one code per modal group, no word
//! left without a code that uses it) and finally executed in LinuxCNC's order of execution
//! against the modal state. Errors are collected per block; the interpreter then goes on with
//! the next line, so every bad block of a file is reported in one go.
//!
//! The reader is line-streaming: memory grows with the moves kept, not with the file.

use std::f64::consts::PI;
use std::io::BufRead;
use std::path::Path;

use super::error::{display_text, ErrorSink, Found, ProgramError, ProgramErrors};
use super::options::{LengthUnit, ReadOptions};
use super::source::{char_column, saturate};
use super::types::{Blend, Feed, FeedRule, Motion, Move, Plane, Position, Program, Span, Spindle};

/// Decodes G-code held in memory. `source` names the program in messages.
pub fn parse_gcode(
    text: impl AsRef<[u8]>,
    source: impl AsRef<Path>,
    options: &ReadOptions,
) -> Result<Program, ProgramErrors> {
    parse_gcode_reader(text.as_ref(), source, options)
}

/// Decodes G-code line by line from a reader (a 1-million-line file is never held whole).
pub fn parse_gcode_reader<R: BufRead>(
    mut reader: R,
    source: impl AsRef<Path>,
    options: &ReadOptions,
) -> Result<Program, ProgramErrors> {
    let source = source.as_ref();
    let mut interpreter = Interpreter::new(source, options);
    let mut line = Vec::new();
    let mut line_offset = 0usize;
    let mut line_number = 0usize;
    loop {
        line.clear();
        let read = match reader.read_until(b'\n', &mut line) {
            Ok(0) => break,
            Ok(read) => read,
            Err(error) => {
                interpreter.errors.push(ProgramError::new(
                    source,
                    None,
                    format!("could not read the program: {error}"),
                ));
                break;
            }
        };
        line_number += 1;
        let mut content: &[u8] = &line;
        if let Some(stripped) = content.strip_suffix(b"\n") {
            content = stripped;
        }
        if let Some(stripped) = content.strip_suffix(b"\r") {
            content = stripped;
        }
        interpreter.line(content, line_number, line_offset);
        line_offset += read;
        if interpreter.finished {
            break;
        }
    }
    interpreter.finish(line_number, line_offset)
}

/// Modal groups of G codes (LinuxCNC numbering; used as indices).
mod group {
    pub const NON_MODAL: usize = 0;
    pub const MOTION: usize = 1;
    pub const PLANE: usize = 2;
    pub const DISTANCE: usize = 3;
    pub const ARC_DISTANCE: usize = 4;
    pub const FEED_MODE: usize = 5;
    pub const UNITS: usize = 6;
    pub const CUTTER_COMP: usize = 7;
    pub const TOOL_LENGTH: usize = 8;
    pub const RETURN_MODE: usize = 10;
    pub const COORD_SYSTEM: usize = 12;
    pub const PATH_CONTROL: usize = 13;
    pub const SPINDLE_MODE: usize = 14;
    pub const LATHE: usize = 15;
    pub const COUNT: usize = 16;

    pub fn name(group: usize) -> &'static str {
        match group {
            NON_MODAL => "non-modal codes",
            MOTION => "motion",
            PLANE => "plane selection",
            DISTANCE => "distance mode",
            ARC_DISTANCE => "arc centre distance mode",
            FEED_MODE => "feed rate mode",
            UNITS => "units",
            CUTTER_COMP => "cutter compensation",
            TOOL_LENGTH => "tool length offset",
            RETURN_MODE => "canned cycle return mode",
            COORD_SYSTEM => "coordinate system",
            PATH_CONTROL => "path control mode",
            SPINDLE_MODE => "spindle speed mode",
            LATHE => "lathe diameter mode",
            _ => "modal group",
        }
    }
}

/// Modal groups of M codes.
mod mgroup {
    pub const STOP: usize = 0;
    pub const TOOL_CHANGE: usize = 1;
    pub const SPINDLE: usize = 2;
    pub const COOLANT: usize = 3;
    pub const OVERRIDE: usize = 4;
    pub const COUNT: usize = 5;

    pub fn name(group: usize) -> &'static str {
        match group {
            STOP => "stopping",
            TOOL_CHANGE => "tool change",
            SPINDLE => "spindle",
            COOLANT => "coolant",
            _ => "override switches",
        }
    }
}

/// Whether cncsim executes a code LinuxCNC knows.
enum Support {
    Yes,
    /// Known to LinuxCNC, refused here, with the reason shown to the user.
    No(&'static str),
}

/// G code (in tenths: G64 = 640, G90.1 = 901) → modal group and support.
fn g_code_info(tenths: u32) -> Option<(usize, Support)> {
    use Support::{No, Yes};
    const CYCLES: &str =
        "canned cycles are not supported; expand the cycle into G0/G1 moves in the CAM post";
    const OFFSETS: &str = "cncsim does not know the machine's offset tables; post the program in G54 with offsets applied";
    let info = match tenths {
        0 | 10 | 20 | 30 | 800 => (group::MOTION, Yes),
        50..=53 => (group::MOTION, No("spline motion (G5.x) is not supported")),
        330 | 331 | 760 => (
            group::MOTION,
            No("spindle-synchronised motion is not supported"),
        ),
        382..=385 => (group::MOTION, No("probing moves are not supported")),
        730 | 810..=890 => (group::MOTION, No(CYCLES)),
        40 => (group::NON_MODAL, Yes),
        100 | 520 | 920..=923 => (group::NON_MODAL, No(OFFSETS)),
        280 | 281 | 300 | 301 => (
            group::NON_MODAL,
            No("home positions (G28/G30) are not known to cncsim"),
        ),
        530 => (
            group::NON_MODAL,
            No("machine-coordinate moves (G53) are not supported"),
        ),
        170 | 180 | 190 => (group::PLANE, Yes),
        171 | 181 | 191 => (group::PLANE, No("UVW planes are not supported")),
        900 | 910 => (group::DISTANCE, Yes),
        901 | 911 => (group::ARC_DISTANCE, Yes),
        930 | 940 => (group::FEED_MODE, Yes),
        950 => (
            group::FEED_MODE,
            No("feed per revolution (G95) is not supported"),
        ),
        200 | 210 => (group::UNITS, Yes),
        400 => (group::CUTTER_COMP, Yes),
        410 | 411 | 420 | 421 => (
            group::CUTTER_COMP,
            No("cutter radius compensation is not supported; post the tool-centre path"),
        ),
        490 => (group::TOOL_LENGTH, Yes),
        430..=432 => (
            group::TOOL_LENGTH,
            No("tool length offsets are not supported"),
        ),
        980 | 990 => (group::RETURN_MODE, Yes),
        540 => (group::COORD_SYSTEM, Yes),
        550 | 560 | 570 | 580 | 590..=593 => (group::COORD_SYSTEM, No(OFFSETS)),
        610 | 611 | 640 => (group::PATH_CONTROL, Yes),
        960 => (
            group::SPINDLE_MODE,
            No("constant surface speed (G96) is not supported"),
        ),
        970 => (group::SPINDLE_MODE, Yes),
        70 | 80 => (
            group::LATHE,
            No("lathe diameter/radius modes are not supported"),
        ),
        _ => return None,
    };
    Some(info)
}

/// M code → modal group and support.
fn m_code_info(code: u32) -> Option<(usize, Support)> {
    use Support::{No, Yes};
    let info = match code {
        0 | 1 | 2 | 30 | 60 => (mgroup::STOP, Yes),
        6 | 61 => (mgroup::TOOL_CHANGE, Yes),
        3..=5 => (mgroup::SPINDLE, Yes),
        19 => (
            mgroup::SPINDLE,
            No("spindle orientation (M19) is not supported"),
        ),
        7..=9 => (mgroup::COOLANT, Yes),
        48..=53 => (mgroup::OVERRIDE, Yes),
        62..=68 => (
            mgroup::OVERRIDE,
            No("digital and analog outputs are not supported"),
        ),
        70..=73 => (
            mgroup::OVERRIDE,
            No("saving and restoring modal state is not supported"),
        ),
        100..=199 => (
            mgroup::OVERRIDE,
            No("user-defined M codes are not supported"),
        ),
        _ => return None,
    };
    Some(info)
}

/// A word's value and where its text lies in the raw line (byte range).
#[derive(Debug, Clone, Copy)]
struct Word {
    value: f64,
    start: usize,
    end: usize,
}

#[derive(Debug, Clone, Copy)]
struct CodeWord {
    /// G codes in tenths, M codes whole.
    code: u32,
    start: usize,
    end: usize,
}

/// One block after checking: at most one code per modal group, at most one word per letter.
#[derive(Debug, Default)]
struct Block {
    g: [Option<CodeWord>; group::COUNT],
    m: [Option<CodeWord>; mgroup::COUNT],
    /// LinuxCNC allows M7 and M8 together; the second coolant code lands here.
    second_coolant: Option<CodeWord>,
    /// Words by letter (`a` = 0).
    words: [Option<Word>; 26],
}

impl Block {
    fn word(&self, letter: u8) -> Option<Word> {
        self.words[usize::from(letter - b'a')]
    }

    fn has(&self, letter: u8) -> bool {
        self.word(letter).is_some()
    }

    fn has_axis_words(&self) -> bool {
        AXIS_LETTERS.iter().any(|&letter| self.has(letter))
    }

    fn g_code(&self, group: usize) -> Option<u32> {
        self.g[group].map(|word| word.code)
    }
}

/// Largest magnitude of any number in a program: far beyond any machine (1000 km in mm),
/// small enough that no sum of coordinates overflows.
const MAX_MAGNITUDE: f64 = 1e9;

/// X Y Z A B C in axis order.
const AXIS_LETTERS: [u8; 6] = [b'x', b'y', b'z', b'a', b'b', b'c'];

/// A problem found while reading one line; converted to a [`ProgramError`] with the line's
/// position.
struct LineError {
    start: usize,
    end: usize,
    problem: String,
    found: Option<Found>,
    hint: Option<String>,
}

impl LineError {
    fn new(start: usize, end: usize, problem: impl Into<String>) -> Self {
        LineError {
            start,
            end,
            problem: problem.into(),
            found: None,
            hint: None,
        }
    }

    fn found(mut self, found: Found) -> Self {
        self.found = Some(found);
        self
    }

    fn hint(mut self, hint: impl Into<String>) -> Self {
        self.hint = Some(hint.into());
        self
    }
}

/// A significant character of a compacted line: lower-cased byte and its index in the raw line.
#[derive(Debug, Clone, Copy)]
struct Significant {
    byte: u8,
    at: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MotionMode {
    Rapid,
    Linear,
    Arc { clockwise: bool },
}

/// Feed as programmed: the F number and the units it was given in.
#[derive(Debug, Clone, Copy)]
struct FeedSetting {
    number: f64,
    unit: LengthUnit,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Percent {
    /// No `%` line seen (LinuxCNC does not require them).
    None,
    /// The file opened with `%`; a closing `%` ends it.
    Open,
}

struct Interpreter<'a> {
    source: &'a Path,
    options: &'a ReadOptions,
    errors: ErrorSink,
    program: Program,
    // Modal state.
    units: LengthUnit,
    absolute: bool,
    arc_centre_absolute: bool,
    plane: Plane,
    inverse_time: bool,
    feed: Option<FeedSetting>,
    motion_mode: Option<MotionMode>,
    blend: Blend,
    spindle_rpm: f64,
    spindle: Spindle,
    position: Position,
    // File structure.
    percent: Percent,
    seen_content: bool,
    finished: bool,
    ended_by_program_end: bool,
    // Scratch buffer reused for every line.
    compact: Vec<Significant>,
}

impl<'a> Interpreter<'a> {
    fn new(source: &'a Path, options: &'a ReadOptions) -> Self {
        Interpreter {
            source,
            options,
            errors: ErrorSink::new(options.max_errors),
            program: Program {
                source: source.to_path_buf(),
                ..Program::default()
            },
            units: options.gcode.initial_units,
            absolute: true,
            // LinuxCNC starts in G91.1: I J K are offsets from the arc's start point.
            arc_centre_absolute: false,
            plane: Plane::XY,
            inverse_time: false,
            feed: None,
            motion_mode: None,
            // LinuxCNC's start-up path mode is G64 without a tolerance.
            blend: Blend::Continuous { tolerance: None },
            spindle_rpm: 0.0,
            spindle: Spindle::Off,
            position: Position::default(),
            percent: Percent::None,
            seen_content: false,
            finished: false,
            ended_by_program_end: false,
            compact: Vec::new(),
        }
    }

    fn finish(mut self, line_count: usize, byte_count: usize) -> Result<Program, ProgramErrors> {
        if self.percent == Percent::Open && !self.ended_by_program_end && !self.finished {
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
        self.errors.finish(self.program)
    }

    /// Reads and executes one line.
    fn line(&mut self, line: &[u8], line_number: usize, line_offset: usize) {
        let mut compact = std::mem::take(&mut self.compact);
        compact.clear();
        let outcome = compact_line(line, &mut compact)
            .and_then(|()| self.block(line, &compact, line_number, line_offset));
        if let Err(error) = outcome {
            self.report(line, line_number, line_offset, error);
        }
        self.compact = compact;
    }

    fn report(&mut self, line: &[u8], line_number: usize, line_offset: usize, error: LineError) {
        let span = span_in_line(line, line_number, line_offset, error.start);
        let found = error.found.unwrap_or_else(|| {
            let end = error.end.min(line.len());
            let start = error.start.min(end);
            if start == end {
                Found::EndOfLine
            } else {
                Found::Text(display_text(&line[start..end]))
            }
        });
        let mut program_error =
            ProgramError::new(self.source, Some(span), error.problem).found(found);
        program_error.hint = error.hint;
        self.errors.push(program_error);
    }

    fn block(
        &mut self,
        line: &[u8],
        compact: &[Significant],
        line_number: usize,
        line_offset: usize,
    ) -> Result<(), LineError> {
        let Some(first) = compact.first() else {
            return Ok(());
        };
        // `%` lines delimit the program.
        if first.byte == b'%' {
            if compact.len() > 1 {
                return Err(LineError::new(
                    first.at,
                    line.len(),
                    "expected nothing after '%' on its line",
                ));
            }
            if !self.seen_content && self.percent == Percent::None {
                self.percent = Percent::Open;
            } else {
                // LinuxCNC stops reading at the second '%' (or at a '%' after content).
                self.finished = true;
            }
            self.seen_content = true;
            return Ok(());
        }
        self.seen_content = true;
        let mut words = compact;
        if first.byte == b'/' {
            if self.options.gcode.block_delete {
                return Ok(());
            }
            words = &words[1..];
        }
        let block = read_block(line, words)?;
        let span = span_in_line(line, line_number, line_offset, first.at);
        self.execute(line, &block, span)
    }

    /// Executes a checked block in LinuxCNC's order of execution.
    fn execute(&mut self, line: &[u8], block: &Block, span: Span) -> Result<(), LineError> {
        let block_text = block_text_range(line);
        // Units and modes are applied to all words of the block: a block `G20 G1 X1 F10`
        // means one inch at 10 inch/min.
        self.check_word_usage(block)?;

        // 2. Feed rate mode.
        match block.g_code(group::FEED_MODE) {
            Some(930) => self.inverse_time = true,
            Some(940) => self.inverse_time = false,
            _ => {}
        }
        // Units come before F here (see above).
        match block.g_code(group::UNITS) {
            Some(200) => self.units = LengthUnit::Inch,
            Some(210) => self.units = LengthUnit::Millimetre,
            _ => {}
        }
        // 3. F. In inverse-time mode F belongs to its block only.
        if let Some(f) = block.word(b'f') {
            if f.value < 0.0 {
                return Err(LineError::new(
                    f.start,
                    f.end,
                    "expected a feed rate of zero or more",
                ));
            }
            if !self.inverse_time {
                self.feed = Some(FeedSetting {
                    number: f.value,
                    unit: self.units,
                });
            }
        }
        // 4. S.
        if let Some(s) = block.word(b's') {
            if s.value < 0.0 {
                return Err(LineError::new(
                    s.start,
                    s.end,
                    "expected a spindle speed of zero or more",
                ));
            }
            self.spindle_rpm = s.value;
            self.spindle = match self.spindle {
                Spindle::Off => Spindle::Off,
                Spindle::Clockwise { .. } => Spindle::Clockwise { rpm: s.value },
                Spindle::CounterClockwise { .. } => Spindle::CounterClockwise { rpm: s.value },
            };
        }
        // 5-6. T and M6/M61: no geometry; the tool table is the machine's business.
        // 7. Spindle.
        if let Some(word) = block.m[mgroup::SPINDLE] {
            self.spindle = match word.code {
                3 => Spindle::Clockwise {
                    rpm: self.spindle_rpm,
                },
                4 => Spindle::CounterClockwise {
                    rpm: self.spindle_rpm,
                },
                _ => Spindle::Off,
            };
        }
        // 8-9. Coolant and overrides: no geometry.
        // 10. Dwell.
        if block.g_code(group::NON_MODAL) == Some(40) {
            let Some(p) = block.word(b'p') else {
                let word = block.g[group::NON_MODAL].expect("G4 present");
                return Err(LineError::new(
                    word.start,
                    word.end,
                    "expected a P word (dwell time in seconds) with G4",
                )
                .found(Found::Text(display_text(&line[block_text.0..block_text.1])))
                .hint("write e.g. G4 P0.5 for half a second"));
            };
            if p.value < 0.0 {
                return Err(LineError::new(
                    p.start,
                    p.end,
                    "expected a dwell time of zero or more seconds",
                ));
            }
            self.push_move(
                Motion::Dwell { seconds: p.value },
                self.position,
                Feed::Rapid,
                span,
            );
        }
        // 11. Plane.
        match block.g_code(group::PLANE) {
            Some(170) => self.plane = Plane::XY,
            Some(180) => self.plane = Plane::ZX,
            Some(190) => self.plane = Plane::YZ,
            _ => {}
        }
        // 12-15. Units (done above), cutter compensation off, tool length off, G54: no effect.
        // 16. Path control.
        match block.g_code(group::PATH_CONTROL) {
            Some(610) | Some(611) => self.blend = Blend::ExactStop,
            Some(640) => {
                let tolerance = match block.word(b'p') {
                    Some(p) if p.value < 0.0 => {
                        return Err(LineError::new(
                            p.start,
                            p.end,
                            "expected a G64 P tolerance of zero or more",
                        ));
                    }
                    Some(p) => Some(self.units.to_metres(p.value)),
                    None => None,
                };
                self.blend = Blend::Continuous { tolerance };
            }
            _ => {}
        }
        // 17. Distance modes.
        match block.g_code(group::DISTANCE) {
            Some(900) => self.absolute = true,
            Some(910) => self.absolute = false,
            _ => {}
        }
        match block.g_code(group::ARC_DISTANCE) {
            Some(901) => self.arc_centre_absolute = true,
            Some(911) => self.arc_centre_absolute = false,
            _ => {}
        }
        // 20. Motion.
        match block.g_code(group::MOTION) {
            Some(0) => self.motion_mode = Some(MotionMode::Rapid),
            Some(10) => self.motion_mode = Some(MotionMode::Linear),
            Some(20) => self.motion_mode = Some(MotionMode::Arc { clockwise: true }),
            Some(30) => self.motion_mode = Some(MotionMode::Arc { clockwise: false }),
            Some(800) => self.motion_mode = None,
            _ => {}
        }
        if block.has_axis_words() {
            let Some(mode) = self.motion_mode else {
                let first_axis = AXIS_LETTERS
                    .iter()
                    .filter_map(|&l| block.word(l))
                    .min_by_key(|w| w.start)
                    .expect("axis word present");
                return Err(LineError::new(
                    first_axis.start,
                    first_axis.end,
                    "expected a motion mode (G0, G1, G2 or G3) for the axis words",
                )
                .hint("no motion mode is active (at program start or after G80); add G0 or G1"));
            };
            self.motion(line, block, mode, span)?;
        } else if let Some(word) = block.g[group::MOTION] {
            if matches!(word.code, 20 | 30)
                && (block.has(b'i') || block.has(b'j') || block.has(b'k') || block.has(b'r'))
            {
                return Err(LineError::new(
                    word.start,
                    block_text.1,
                    "expected at least one axis word giving the arc's end point",
                )
                .hint("for a full circle repeat the start point, e.g. G2 X0 Y0 I5"));
            }
        }
        // 21. Stop codes.
        if let Some(word) = block.m[mgroup::STOP] {
            match word.code {
                2 | 30 => {
                    self.ended_by_program_end = true;
                    self.finished = true;
                }
                _ => self.program.warnings.push(super::types::Warning {
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

    /// LinuxCNC refuses words that no code in the block (or mode) uses.
    fn check_word_usage(&self, block: &Block) -> Result<(), LineError> {
        let motion_after = match block.g_code(group::MOTION) {
            Some(0) => Some(MotionMode::Rapid),
            Some(10) => Some(MotionMode::Linear),
            Some(20) => Some(MotionMode::Arc { clockwise: true }),
            Some(30) => Some(MotionMode::Arc { clockwise: false }),
            Some(_) => None,
            None => self.motion_mode,
        };
        let arc_in_block = matches!(motion_after, Some(MotionMode::Arc { .. }))
            && (block.has_axis_words() || matches!(block.g_code(group::MOTION), Some(20 | 30)));
        let dwell = block.g_code(group::NON_MODAL) == Some(40);
        let g64 = block.g_code(group::PATH_CONTROL) == Some(640);
        let unused = |letter: u8, users: &str| -> Result<(), LineError> {
            match block.word(letter) {
                Some(word) => Err(LineError::new(
                    word.start,
                    word.end,
                    format!(
                        "expected {} to come with {users}",
                        letter.to_ascii_uppercase() as char
                    ),
                )
                .hint(format!(
                    "no code in this block uses the {} word",
                    letter.to_ascii_uppercase() as char
                ))),
                None => Ok(()),
            }
        };
        if !arc_in_block {
            unused(b'i', "an arc (G2/G3)")?;
            unused(b'j', "an arc (G2/G3)")?;
            unused(b'k', "an arc (G2/G3)")?;
            unused(b'r', "an arc (G2/G3)")?;
        }
        if !(arc_in_block || dwell || g64) {
            unused(b'p', "G4, G64 or an arc (G2/G3)")?;
        }
        if !g64 {
            unused(b'q', "G64")?;
        }
        for letter in [b'd', b'h', b'l'] {
            if let Some(word) = block.word(letter) {
                return Err(LineError::new(
                    word.start,
                    word.end,
                    format!(
                        "expected no {} word: it belongs to codes cncsim does not support",
                        letter.to_ascii_uppercase() as char
                    ),
                )
                .hint("D, H and L go with cutter compensation, tool length offsets and G10"));
            }
        }
        Ok(())
    }

    /// The end point of a motion block (SI), from the axis words and the distance mode.
    fn end_point(&self, block: &Block) -> Position {
        let mut end = self.position;
        for (axis, &letter) in AXIS_LETTERS.iter().enumerate() {
            if let Some(word) = block.word(letter) {
                let (slot, value) = if axis < 3 {
                    (&mut end.linear[axis], self.units.to_metres(word.value))
                } else {
                    (&mut end.rotary[axis - 3], word.value.to_radians())
                };
                if self.absolute {
                    *slot = value;
                } else {
                    *slot += value;
                }
            }
        }
        end
    }

    fn motion(
        &mut self,
        line: &[u8],
        block: &Block,
        mode: MotionMode,
        span: Span,
    ) -> Result<(), LineError> {
        let end = self.end_point(block);
        let block_range = block_text_range(line);
        match mode {
            MotionMode::Rapid => {
                self.push_move(Motion::Linear, end, Feed::Rapid, span);
            }
            MotionMode::Linear => {
                let feed = self.feed_for(line, block, &end, block_range)?;
                self.push_move(Motion::Linear, end, feed, span);
            }
            MotionMode::Arc { clockwise } => {
                let motion = self.arc(line, block, &end, clockwise, block_range)?;
                let feed = self.feed_for(line, block, &end, block_range)?;
                self.push_move(motion, end, feed, span);
            }
        }
        Ok(())
    }

    /// The feed of a G1/G2/G3 block.
    fn feed_for(
        &self,
        line: &[u8],
        block: &Block,
        end: &Position,
        block_range: (usize, usize),
    ) -> Result<Feed, LineError> {
        let found = || Found::Text(display_text(&line[block_range.0..block_range.1]));
        if self.inverse_time {
            return match block.word(b'f') {
                Some(f) if f.value > 0.0 => Ok(Feed::InverseTime(60.0 / f.value)),
                Some(f) => Err(LineError::new(
                    f.start,
                    f.end,
                    "expected a positive F word (inverse time: 1/minutes) in G93 mode",
                )),
                None => Err(LineError::new(
                    block_range.0,
                    block_range.1,
                    "expected an F word on every G1/G2/G3 block in inverse-time mode (G93)",
                )
                .found(found())
                .hint("in G93 the F word is 1 / (move time in minutes) and is not modal")),
            };
        }
        let setting = match self.feed {
            Some(setting) if setting.number > 0.0 => setting,
            _ => {
                return Err(LineError::new(
                    block_range.0,
                    block_range.1,
                    "expected a non-zero feed rate (F word) before a G1/G2/G3 move",
                )
                .found(found())
                .hint(format!(
                    "add e.g. F300 ({} per minute in G94)",
                    self.units.symbol()
                )));
            }
        };
        let linear_moves = (0..3).any(|axis| end.linear[axis] != self.position.linear[axis]);
        let rotary_moves = (0..3).any(|axis| end.rotary[axis] != self.position.rotary[axis]);
        if self.options.feed_rule == FeedRule::LinuxCnc && rotary_moves && !linear_moves {
            // LinuxCNC applies the F number to a purely rotary move in degrees per minute.
            // `Feed::PathSpeed` carries it with 1 mm ≡ 1 degree (see `FeedRule::LinuxCnc`).
            return Ok(Feed::PathSpeed(setting.number / 60.0 / 1000.0));
        }
        Ok(Feed::PathSpeed(
            setting.unit.to_metres(setting.number) / 60.0,
        ))
    }

    /// Centre, turns and checks of a G2/G3 block (LinuxCNC `arc_data_ijk` / `arc_data_r`).
    fn arc(
        &self,
        line: &[u8],
        block: &Block,
        end: &Position,
        clockwise: bool,
        block_range: (usize, usize),
    ) -> Result<Motion, LineError> {
        let (first, second, normal, offset_letters, names) = plane_axes(self.plane);
        let tolerance = &self.options.gcode.arc_tolerance;
        let unit = self.units;
        let found = || Found::Text(display_text(&line[block_range.0..block_range.1]));
        let forbidden = [b'i', b'j', b'k']
            .into_iter()
            .find(|l| !offset_letters.contains(l));
        if let Some(word) = forbidden.and_then(|letter| block.word(letter)) {
            return Err(LineError::new(
                word.start,
                word.end,
                format!(
                    "expected centre offsets {} and {} for an arc in the {} plane",
                    offset_letters[0].to_ascii_uppercase() as char,
                    offset_letters[1].to_ascii_uppercase() as char,
                    plane_name(self.plane)
                ),
            ));
        }
        let turns = match block.word(b'p') {
            None => 0,
            Some(p) => {
                let rounded = p.value.round();
                if (p.value - rounded).abs() > 1e-9
                    || rounded < 1.0
                    || rounded > f64::from(u32::MAX)
                {
                    return Err(LineError::new(
                        p.start,
                        p.end,
                        "expected a whole number of turns of 1 or more after P on an arc",
                    ));
                }
                rounded as u32 - 1
            }
        };
        let start = [self.position.linear[first], self.position.linear[second]];
        let stop = [end.linear[first], end.linear[second]];
        let radius_tolerance = unit.to_metres(tolerance.radius(unit));
        let describe = |c: [f64; 2]| {
            format!(
                "({}{:.4},{}{:.4})",
                names[0],
                unit.from_metres(c[0]),
                names[1],
                unit.from_metres(c[1])
            )
        };
        let centre = if let Some(r) = block.word(b'r') {
            if block.has(offset_letters[0]) || block.has(offset_letters[1]) {
                return Err(LineError::new(
                    r.start,
                    r.end,
                    "expected either R or centre offsets on an arc, not both",
                )
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
            let radius = unit.to_metres(r.value.abs());
            if radius < radius_tolerance {
                return Err(LineError::new(
                    r.start,
                    r.end,
                    "expected a non-zero arc radius",
                ));
            }
            let mid = [(start[0] + stop[0]) / 2.0, (start[1] + stop[1]) / 2.0];
            let mut half_chord = (mid[0] - stop[0]).hypot(mid[1] - stop[1]);
            if half_chord - radius > radius_tolerance {
                return Err(LineError::new(r.start, r.end, format!(
                    "expected an arc radius of at least {:.4} {} (half the distance from start {} to end {})",
                    unit.from_metres(half_chord), unit.symbol(), describe(start), describe(stop)
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
            [mid[0] + offset * theta.cos(), mid[1] + offset * theta.sin()]
        } else {
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
            let offset = |word: Option<Word>| word.map_or(0.0, |w| unit.to_metres(w.value));
            let centre = if self.arc_centre_absolute {
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
                    unit.from_metres(r1),
                    unit.from_metres(r2)
                )
            };
            if r1 < radius_tolerance || r2 < radius_tolerance {
                return Err(LineError::new(block_range.0, block_range.1, format!(
                    "expected an arc centre away from its start and end points (zero-radius arc: {})",
                    geometry()
                ))
                .found(found()));
            }
            let abs_err = (r1 - r2).abs();
            let rel_err = abs_err / r1.max(r2);
            let spiral = unit.to_metres(tolerance.spiral(unit));
            if abs_err > 100.0 * spiral || (abs_err > spiral && rel_err > tolerance.spiral_relative)
            {
                return Err(LineError::new(block_range.0, block_range.1, format!(
                    "arc end point is off the circle by {:.4} {}: radius to end differs from radius to start ({}, rel_err={:.4}%); expected at most {:.4} {} (or {:.4} {} within {}% of the radius)",
                    unit.from_metres(abs_err),
                    unit.symbol(),
                    geometry(),
                    rel_err * 100.0,
                    unit.from_metres(spiral),
                    unit.symbol(),
                    unit.from_metres(100.0 * spiral),
                    unit.symbol(),
                    tolerance.spiral_relative * 100.0
                ))
                .found(found())
                .hint(if self.arc_centre_absolute {
                    "check the end point and the centre (G90.1: I J K are absolute)"
                } else {
                    "check the end point and the centre offsets (G91.1: I J K are relative to the start point)"
                }));
            }
            centre
        };
        let mut centre_3d = [0.0; 3];
        centre_3d[first] = centre[0];
        centre_3d[second] = centre[1];
        centre_3d[normal] = self.position.linear[normal];
        Ok(Motion::Arc {
            center: centre_3d,
            plane: self.plane,
            clockwise,
            turns,
        })
    }

    fn push_move(&mut self, motion: Motion, end: Position, feed: Feed, span: Span) {
        self.program.moves.push(Move {
            motion,
            end,
            tool_axis: None,
            feed,
            feed_rule: self.options.feed_rule,
            blend: self.blend,
            tool_down: None,
            spindle: self.spindle,
            span,
        });
        self.position = end;
    }
}

/// (first axis, second axis, normal axis, centre-offset letters, axis names) of a plane, in
/// LinuxCNC's order: G18's arcs run from Z towards X, so that G2 is clockwise seen from +Y.
fn plane_axes(plane: Plane) -> (usize, usize, usize, [u8; 2], [char; 2]) {
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

fn span_in_line(line: &[u8], line_number: usize, line_offset: usize, byte_in_line: usize) -> Span {
    Span {
        line: saturate(line_number),
        column: char_column(line, byte_in_line),
        byte_offset: saturate(line_offset + byte_in_line.min(line.len())),
    }
}

/// The line without leading/trailing blanks and without a `;` comment, for quoting.
fn block_text_range(line: &[u8]) -> (usize, usize) {
    let end = line.iter().position(|&b| b == b';').unwrap_or(line.len());
    let start = line[..end]
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(end);
    let trimmed_end = line[..end]
        .iter()
        .rposition(|b| !b.is_ascii_whitespace())
        .map_or(start, |i| i + 1);
    (start, trimmed_end.max(start))
}

/// Takes comments out of a line, drops blanks and lower-cases letters.
fn compact_line(line: &[u8], out: &mut Vec<Significant>) -> Result<(), LineError> {
    let mut index = 0;
    while index < line.len() {
        let byte = line[index];
        match byte {
            b'(' => {
                let open = index;
                index += 1;
                loop {
                    match line.get(index) {
                        None => {
                            return Err(LineError::new(
                                open,
                                line.len(),
                                "expected ')' to close the comment",
                            )
                            .found(Found::EndOfLine)
                            .hint("comments in parentheses end on the line they start"));
                        }
                        Some(b')') => break,
                        Some(b'(') => {
                            return Err(LineError::new(
                                index,
                                index + 1,
                                "expected ')' before another '(' (comments do not nest)",
                            ));
                        }
                        Some(_) => index += 1,
                    }
                }
            }
            b';' => break,
            b' ' | b'\t' | b'\r' | b'\x0c' | b'\x0b' => {}
            _ if byte.is_ascii_graphic() => out.push(Significant {
                byte: byte.to_ascii_lowercase(),
                at: index,
            }),
            _ => {
                let end = utf8_char_end(line, index);
                return Err(LineError::new(
                    index,
                    end,
                    "expected a G-code word, comment or blank",
                ));
            }
        }
        index += 1;
    }
    Ok(())
}

/// End of the (possibly multi-byte, possibly broken) UTF-8 character starting at `start`.
fn utf8_char_end(bytes: &[u8], start: usize) -> usize {
    let mut end = start + 1;
    while end < bytes.len() && end - start < 4 && (bytes[end] & 0xC0) == 0x80 {
        end += 1;
    }
    end
}

/// Splits a compacted block into words and checks letters, numbers and modal groups.
fn read_block(line: &[u8], chars: &[Significant]) -> Result<Block, LineError> {
    let mut block = Block::default();
    let mut index = 0;
    let raw_after = |i: usize| chars.get(i).map_or(line.len(), |c| c.at + 1);
    while index < chars.len() {
        let letter_char = chars[index];
        let letter = letter_char.byte;
        let word_start = letter_char.at;
        match letter {
            b'n' if index == 0 => {}
            b'n' => {
                return Err(LineError::new(
                    word_start,
                    word_start + 1,
                    "expected the line number (N word) at the start of the block",
                ));
            }
            b'o' => {
                return Err(LineError::new(
                    word_start,
                    word_start + 1,
                    "expected a G-code word; O-words (subroutines, loops) are not supported",
                ));
            }
            b'u' | b'v' | b'w' => {
                return Err(LineError::new(
                    word_start,
                    word_start + 1,
                    "expected an axis of X Y Z A B C; U V W axes are not supported",
                ));
            }
            b'#' | b'[' => {
                return Err(LineError::new(
                    word_start,
                    word_start + 1,
                    "expected a G-code word; parameters and expressions are not supported",
                )
                .hint("post the program with numeric values"));
            }
            b'a'..=b'd' | b'f'..=b'm' | b'p'..=b't' | b'x'..=b'z' => {}
            _ => {
                return Err(LineError::new(
                    word_start,
                    raw_after(index),
                    "expected a word letter (G, M, X, Y, Z, …)",
                ));
            }
        }
        index += 1;
        // The value.
        match chars.get(index).map(|c| c.byte) {
            Some(b'#') | Some(b'[') => {
                let at = chars[index].at;
                return Err(LineError::new(
                    at,
                    at + 1,
                    format!(
                    "expected a number after '{}'; parameters and expressions are not supported",
                    letter.to_ascii_uppercase() as char
                ),
                )
                .hint("post the program with numeric values"));
            }
            _ => {}
        }
        let mut text = String::new();
        if let Some(sign) = chars
            .get(index)
            .filter(|c| c.byte == b'+' || c.byte == b'-')
        {
            text.push(sign.byte as char);
            index += 1;
        }
        let mut digits = 0;
        let mut points = 0;
        while let Some(c) = chars.get(index) {
            match c.byte {
                b'0'..=b'9' => digits += 1,
                b'.' if points == 0 => points += 1,
                _ => break,
            }
            text.push(c.byte as char);
            index += 1;
        }
        if digits == 0 {
            // Point at the character that is not a number (or at the end of the line).
            let (found_at, found_end) = chars
                .get(index)
                .map_or((line.len(), line.len()), |c| (c.at, c.at + 1));
            return Err(LineError::new(
                found_at,
                found_end,
                format!(
                    "expected a number after '{}'",
                    letter.to_ascii_uppercase() as char
                ),
            ));
        }
        let word_end = chars[index - 1].at + 1;
        let value: f64 = text.parse().unwrap_or(f64::INFINITY);
        if value.is_nan() || value.abs() > MAX_MAGNITUDE {
            return Err(LineError::new(
                word_start,
                word_end,
                "expected a number of at most 1e9 in magnitude",
            ));
        }
        let word = Word {
            value,
            start: word_start,
            end: word_end,
        };
        match letter {
            b'n' => {} // line numbers are only labels
            b'g' => {
                let tenths = (value * 10.0).round();
                if (value * 10.0 - tenths).abs() > 1e-6 || !(0.0..=10_000.0).contains(&tenths) {
                    return Err(LineError::new(
                        word_start,
                        word_end,
                        "expected a G code with at most one decimal (e.g. G1, G90.1)",
                    ));
                }
                let code = tenths as u32;
                let name = format_g(code);
                let Some((group, support)) = g_code_info(code) else {
                    return Err(LineError::new(
                        word_start,
                        word_end,
                        format!("expected a G code LinuxCNC knows; {name} is not one"),
                    ));
                };
                if let Support::No(reason) = support {
                    return Err(LineError::new(
                        word_start,
                        word_end,
                        format!("expected a supported G code; {name} is not supported"),
                    )
                    .hint(reason));
                }
                if let Some(previous) = block.g[group] {
                    return Err(LineError::new(word_start, word_end, format!(
                        "expected one G code of the {} group per block, but {} and {name} are both in it",
                        group::name(group),
                        format_g(previous.code)
                    ))
                    .hint("LinuxCNC refuses two codes of one modal group in a block; split the block"));
                }
                block.g[group] = Some(CodeWord {
                    code,
                    start: word_start,
                    end: word_end,
                });
            }
            b'm' => {
                let rounded = value.round();
                if (value - rounded).abs() > 1e-9 || !(0.0..=10_000.0).contains(&rounded) {
                    return Err(LineError::new(
                        word_start,
                        word_end,
                        "expected a whole-number M code",
                    ));
                }
                let code = rounded as u32;
                let Some((group, support)) = m_code_info(code) else {
                    return Err(LineError::new(
                        word_start,
                        word_end,
                        format!("expected an M code LinuxCNC knows; M{code} is not one"),
                    ));
                };
                if let Support::No(reason) = support {
                    return Err(LineError::new(
                        word_start,
                        word_end,
                        format!("expected a supported M code; M{code} is not supported"),
                    )
                    .hint(reason));
                }
                let count =
                    block.m.iter().flatten().count() + usize::from(block.second_coolant.is_some());
                if count >= 4 {
                    return Err(LineError::new(
                        word_start,
                        word_end,
                        "expected at most four M codes in one block",
                    ));
                }
                let entry = CodeWord {
                    code,
                    start: word_start,
                    end: word_end,
                };
                match block.m[group] {
                    None => block.m[group] = Some(entry),
                    // M7 and M8 may share a block (mist and flood together).
                    Some(previous)
                        if group == mgroup::COOLANT
                            && block.second_coolant.is_none()
                            && matches!((previous.code, code), (7, 8) | (8, 7)) =>
                    {
                        block.second_coolant = Some(entry)
                    }
                    Some(previous) => {
                        return Err(LineError::new(word_start, word_end, format!(
                            "expected one M code of the {} group per block, but M{} and M{code} are both in it",
                            mgroup::name(group),
                            previous.code
                        ))
                        .hint("LinuxCNC refuses two codes of one modal group in a block; split the block"));
                    }
                }
            }
            _ => {
                let slot = &mut block.words[usize::from(letter - b'a')];
                if let Some(previous) = slot {
                    return Err(LineError::new(
                        word_start,
                        word_end,
                        format!(
                            "expected one {} word per block, but {} is the second",
                            letter.to_ascii_uppercase() as char,
                            display_text(&line[word_start..word_end])
                        ),
                    )
                    .hint(format!(
                        "the first is '{}'",
                        display_text(&line[previous.start..previous.end])
                    )));
                }
                *slot = Some(word);
            }
        }
    }
    Ok(block)
}

fn format_g(tenths: u32) -> String {
    if tenths.is_multiple_of(10) {
        format!("G{}", tenths / 10)
    } else {
        format!("G{}.{}", tenths / 10, tenths % 10)
    }
}
