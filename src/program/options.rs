//! Settings that steer the readers: feed rule, G-code defaults, HPGL pen heights and
//! optimisation, APT feed units, error limits.

use super::apt::ClWriter;
use super::types::{FeedRule, Position};

/// Length units a G-code program starts in (before any G20/G21).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LengthUnit {
    /// Millimetres (G21).
    #[default]
    Millimetre,
    /// Inches (G20).
    Inch,
}

impl LengthUnit {
    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            LengthUnit::Millimetre => 1e-3,
            LengthUnit::Inch => 0.0254,
        }
    }

    /// A length in this unit converted to metres, rounded once.
    pub fn to_metres(self, value: f64) -> f64 {
        match self {
            // Division by 1000 is correctly rounded, so 5 mm becomes exactly 0.005 m.
            LengthUnit::Millimetre => value / 1000.0,
            LengthUnit::Inch => value * 0.0254,
        }
    }

    /// A length in metres expressed in this unit (for messages).
    pub fn from_metres(self, metres: f64) -> f64 {
        match self {
            LengthUnit::Millimetre => metres * 1000.0,
            LengthUnit::Inch => metres / 0.0254,
        }
    }

    /// The unit's symbol for messages: `mm` or `in`.
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Millimetre => "mm",
            LengthUnit::Inch => "in",
        }
    }
}

/// LinuxCNC's limits for how far an arc's geometry may be off before it is an error.
///
/// Centre format (I J K): with r1 the radius to the start and r2 the radius to the end, the
/// arc is refused when |r1 − r2| > 100 × `spiral_*`, or when |r1 − r2| > `spiral_*` and also
/// |r1 − r2| / max(r1, r2) > `spiral_relative` (LinuxCNC 2.8 onwards, `interp_arc.cc`
/// `arc_data_ijk`; defaults are `CENTER_ARC_RADIUS_TOLERANCE_*` and
/// `SPIRAL_RELATIVE_TOLERANCE` from `interp_internal.hh`). Radius format (R): refused when
/// half the chord exceeds |R| by more than `radius_*`; radii below `radius_*` count as zero.
/// All lengths in the program's own units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcTolerance {
    /// Allowed |r1 − r2| of a centre-format arc in a millimetre program (mm).
    pub spiral_mm: f64,
    /// Allowed |r1 − r2| of a centre-format arc in an inch program (in).
    pub spiral_inch: f64,
    /// Allowed |r1 − r2| / max(r1, r2) of a centre-format arc (a ratio).
    pub spiral_relative: f64,
    /// Allowed excess of half the chord over |R| of a radius-format arc in a millimetre
    /// program (mm).
    pub radius_mm: f64,
    /// Allowed excess of half the chord over |R| of a radius-format arc in an inch program (in).
    pub radius_inch: f64,
}

impl Default for ArcTolerance {
    fn default() -> Self {
        ArcTolerance {
            // 2 × the last printed digit × √2: any arc whose points were rounded to 0.01 mm
            // (0.001 in) passes.
            spiral_mm: 2.0 * 0.01 * std::f64::consts::SQRT_2,
            spiral_inch: 2.0 * 0.001 * std::f64::consts::SQRT_2,
            spiral_relative: 0.001,
            radius_inch: 0.00005,
            radius_mm: 0.00005 * 25.4,
        }
    }
}

impl ArcTolerance {
    /// The absolute spiral tolerance for a program in `unit` (in that unit).
    pub fn spiral(&self, unit: LengthUnit) -> f64 {
        match unit {
            LengthUnit::Millimetre => self.spiral_mm,
            LengthUnit::Inch => self.spiral_inch,
        }
    }

    /// The radius-format tolerance for a program in `unit` (in that unit).
    pub fn radius(&self, unit: LengthUnit) -> f64 {
        match unit {
            LengthUnit::Millimetre => self.radius_mm,
            LengthUnit::Inch => self.radius_inch,
        }
    }
}

/// One tool of the tool table G43 and M6 read (SI: metres, radians).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ToolSpec {
    /// The T number.
    pub number: u32,
    /// Tool length offset (Z, and X Y A B C where a machine needs them).
    pub offset: Position,
    /// Cutter diameter, for cutter radius compensation with `D`.
    pub diameter: f64,
}

/// G-code (RS274/NGC) settings.
#[derive(Debug, Clone, PartialEq)]
pub struct GcodeOptions {
    /// Units before the program's first G20/G21.
    pub initial_units: LengthUnit,
    /// The block-delete switch: when on, blocks starting with `/` are skipped.
    pub block_delete: bool,
    /// How far an arc's geometry may be off before it is an error.
    pub arc_tolerance: ArcTolerance,
    /// The machine's own length units (LinuxCNC `LINEAR_UNITS`): the units of the numbered
    /// parameters that hold offsets (#5161…, #5211…, #5221…, #5401…), as a program reads them.
    pub user_units: LengthUnit,
    /// Machine positions G28 and G30 go to (LinuxCNC #5161–#5166 and #5181–#5186).
    pub g28_home: Position,
    /// Machine position G30 goes to (LinuxCNC #5181–#5186).
    pub g30_home: Position,
    /// The tool table: T words must name a tool in it (or 0 for none).
    pub tools: Vec<ToolSpec>,
    /// At most this many blocks are executed (loops and subroutines count every pass): an
    /// endless loop stops with an error instead of hanging.
    pub max_blocks: u64,
    /// At most this many moves are produced: an endless loop that moves stops with an error
    /// instead of filling memory.
    pub max_moves: usize,
}

impl Default for GcodeOptions {
    fn default() -> Self {
        GcodeOptions {
            initial_units: LengthUnit::Millimetre,
            block_delete: true,
            arc_tolerance: ArcTolerance::default(),
            user_units: LengthUnit::Millimetre,
            g28_home: Position::default(),
            g30_home: Position::default(),
            tools: Vec::new(),
            max_blocks: 20_000_000,
            max_moves: 10_000_000,
        }
    }
}

/// HPGL settings.
#[derive(Debug, Clone, PartialEq)]
pub struct HpglOptions {
    /// Machine Z (m) while the pen is up (tool clear of the work).
    pub pen_up_z: f64,
    /// Machine Z (m) while the pen is down (tool engaged).
    pub pen_down_z: f64,
    /// Plotter units per millimetre (HP plotters: 40, i.e. 0.025 mm per unit).
    pub units_per_mm: f64,
    /// Drawing speed (m/s) until the program's first VS. HP 7475 default: 38.1 cm/s.
    pub default_speed: f64,
    /// Accept damaged files: a dangling single coordinate is dropped with a warning instead
    /// of being an error.
    pub lenient: bool,
    /// Reorder and reverse pen-down strokes to shorten pen-up travel.
    pub optimise_pen_up: bool,
    /// P1 and P2 (plotter units) after IN / a bare IP: the HP 7475's A-size defaults.
    pub default_p1: [f64; 2],
    /// P2 (plotter units) after IN / a bare IP; see `default_p1`.
    pub default_p2: [f64; 2],
    /// The page (hard-clip limits, plotter units) until a PS: the HP 7475's A size. RO
    /// turns the plot about it and IR places P1 and P2 in it.
    pub default_page: [f64; 2],
    /// Refuse commands that do not move the pen (PS CO PW NP EC PG …, PCL wrappers) instead
    /// of skipping them with one warning per kind.
    pub strict: bool,
    /// Fills (RA RR WG FP) are outlines plus the hatch lines FT asks for; `false` draws
    /// the outlines only.
    pub hatch_fills: bool,
    /// At most this many fill hatch lines per file: a bound on the work and memory a file
    /// can ask for (each line is four moves).
    pub max_fill_lines: usize,
    /// Plot only this page (from 1, counted at each PG, FR, AF, AH, as hp2xx's `-P n:n`
    /// counts them); `None` plots every page, one over another, as hp2xx does.
    pub page: Option<u32>,
}

impl Default for HpglOptions {
    fn default() -> Self {
        HpglOptions {
            pen_up_z: 0.005,
            pen_down_z: 0.0,
            units_per_mm: 40.0,
            default_speed: 0.381,
            lenient: false,
            optimise_pen_up: false,
            default_p1: [250.0, 596.0],
            default_p2: [10250.0, 7796.0],
            default_page: [10365.0, 7962.0],
            strict: false,
            hatch_fills: true,
            max_fill_lines: 250_000,
            page: None,
        }
    }
}

/// Time base of APT `FEDRAT` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FeedTimeBase {
    /// APT's convention (IPM / MMPM): units per minute.
    #[default]
    PerMinute,
    /// Units per second, as some CL listings (e.g. the 5-axis study's tables) print them.
    PerSecond,
}

/// APT CL settings.
#[derive(Debug, Clone, PartialEq)]
pub struct AptOptions {
    /// Units before the first `UNITS` record.
    pub initial_units: LengthUnit,
    /// How to read a `FEDRAT` value that carries no IPM/MMPM word.
    pub feed_time_base: FeedTimeBase,
    /// The CAM system whose conventions apply (which way CIRCLE arcs turn, …); `None`: the
    /// one the file's header names.
    pub writer: Option<ClWriter>,
    /// Largest distance (m) of the chords standing for an arc about a tilted axis.
    pub chord_tolerance: f64,
    /// At most this many chords for one such arc.
    pub max_chords: usize,
    /// Refuse records that do not move the tool instead of skipping them with a warning.
    pub strict: bool,
    /// Feed (m/s) of the moves before the first FEDRAT, for CL data that programs none (a
    /// list of GOTO records); `None` refuses such a move.
    pub default_feed: Option<f64>,
}

impl Default for AptOptions {
    fn default() -> Self {
        AptOptions {
            initial_units: LengthUnit::default(),
            feed_time_base: FeedTimeBase::default(),
            writer: None,
            chord_tolerance: 1e-6,
            max_chords: 1_000_000,
            strict: false,
            default_feed: None,
        }
    }
}

/// Everything the readers can be told.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadOptions {
    /// How feeds are shared out over rotary axes; recorded in every move.
    pub feed_rule: FeedRule,
    /// Settings of the G-code reader.
    pub gcode: GcodeOptions,
    /// Settings of the HPGL reader.
    pub hpgl: HpglOptions,
    /// Settings of the APT CL reader.
    pub apt: AptOptions,
    /// At most this many errors are kept per file (the rest are counted).
    pub max_errors: usize,
    /// The work offset (m): machine coordinates of program zero along X, Y, Z. G-code starts
    /// with it as its G54 origin (so G53, G28 and G30 still name machine positions); the
    /// other formats are moved by it.
    pub work_offset: [f64; 3],
}

impl Default for ReadOptions {
    fn default() -> Self {
        ReadOptions {
            feed_rule: FeedRule::default(),
            gcode: GcodeOptions::default(),
            hpgl: HpglOptions::default(),
            apt: AptOptions::default(),
            max_errors: 100,
            work_offset: [0.0; 3],
        }
    }
}
