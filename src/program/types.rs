//! The program representation every front end produces and the planner consumes.
//!
//! Plain data, SI units: lengths in metres, angles in radians, times in seconds, feeds in
//! metres per second. Millimetres, inches, degrees, per-minute feeds and plotter units exist
//! only inside the parsers that read them.

use std::path::PathBuf;

/// Where a piece of program text came from: 1-based line and column, 0-based byte offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Span {
    /// Line number, counted from 1.
    pub line: u32,
    /// Column on the line, counted from 1.
    pub column: u32,
    /// Offset from the start of the text in bytes, counted from 0.
    pub byte_offset: u32,
}

/// Machine-independent target of a move: the three linear axes (m) and the three rotary axes
/// A, B, C (rad). Axes a program never mentions stay at the position they had.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Position {
    /// X, Y, Z (m).
    pub linear: [f64; 3],
    /// A, B, C (rad).
    pub rotary: [f64; 3],
}

/// The working plane of an arc (G17/G18/G19).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plane {
    /// The XY plane (G17), normal axis Z.
    XY,
    /// The ZX plane (G18), normal axis Y.
    ZX,
    /// The YZ plane (G19), normal axis X.
    YZ,
}

/// How fast a move is to be made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Feed {
    /// As fast as the machine allows (G0, pen-up travel, APT RAPID).
    Rapid,
    /// Programmed feed, converted to m/s (for moves with rotary axes see [`FeedRule`]).
    PathSpeed(f64),
    /// Inverse-time feed (G93): the move takes this many seconds.
    InverseTime(f64),
}

/// How the programmed feed is shared out when a move has rotary components.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FeedRule {
    /// LinuxCNC: the feed applies to the linear axes; a purely rotary move uses it in deg/min.
    /// For such a move `Feed::PathSpeed(v)` carries the angular rate with 1 mm ≡ 1 degree:
    /// the axes turn at v × 1000 degrees per second.
    #[default]
    LinuxCnc,
    /// The 5-axis study: the feed applies to the Euclidean norm of all axis deltas, linear in mm
    /// and rotary in degrees.
    EuclideanAllAxes,
}

/// Corner behaviour requested for the end of a move (G61 / G64 P Q).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Blend {
    /// Stop exactly at the programmed point.
    #[default]
    ExactStop,
    /// Pass the corner without stopping, staying within `tolerance` (m) of the programmed
    /// point; `None` = no tolerance given (G64 without P). `naive_cam`: LinuxCNC's naive-CAM
    /// collinearity tolerance (m, G64 Q), `None` when the program gives no Q.
    Continuous {
        /// Largest allowed deviation from the programmed point (m, G64 P); `None` when not given.
        tolerance: Option<f64>,
        /// Naive-CAM collinearity tolerance (m, G64 Q); `None` when not given.
        naive_cam: Option<f64>,
    },
}

/// The geometry of one move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Motion {
    /// Straight line in all axes from the previous position to `Move::end`.
    Linear,
    /// Circular arc in `plane` about `center` (m, absolute), helical when the axis normal to the
    /// plane changes; `turns` extra full turns (G2/G3 P − 1). An arc whose end lies at its
    /// start in the plane is a full circle (as in LinuxCNC). In `plane`'s own axis order
    /// (XY: X then Y; ZX: Z then X; YZ: Y then Z) counter-clockwise is positive about the
    /// normal axis. `center`'s coordinate along the normal axis is the arc's start value.
    Arc {
        /// Centre of the arc (m, absolute); along the normal axis, the arc's start value.
        center: [f64; 3],
        /// The plane the arc turns in.
        plane: Plane,
        /// Clockwise (G2) rather than counter-clockwise (G3), seen in `plane`'s axis order.
        clockwise: bool,
        /// Extra full turns beyond the first (G2/G3 P − 1).
        turns: u32,
    },
    /// Dwell in place (G4).
    Dwell {
        /// How long to dwell (s).
        seconds: f64,
    },
}

/// Spindle / tool state that the program switches.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Spindle {
    /// Spindle stopped (M5).
    #[default]
    Off,
    /// Turning clockwise (M3).
    Clockwise {
        /// Spindle speed (revolutions per minute, as programmed).
        rpm: f64,
    },
    /// Turning counter-clockwise (M4).
    CounterClockwise {
        /// Spindle speed (revolutions per minute, as programmed).
        rpm: f64,
    },
}

/// One move of a program.
#[derive(Debug, Clone, PartialEq)]
pub struct Move {
    /// Its geometry: line, arc or dwell.
    pub motion: Motion,
    /// Position at the end of the move (m, rad); a dwell's is where it stands.
    pub end: Position,
    /// Tool-axis unit vector in workpiece coordinates (APT CL data); `None` = not programmed.
    pub tool_axis: Option<[f64; 3]>,
    /// How fast the move is to be made.
    pub feed: Feed,
    /// How `feed` is shared out when the move has rotary components.
    pub feed_rule: FeedRule,
    /// Corner behaviour at the end of the move.
    pub blend: Blend,
    /// Tool engaged (pen down in HPGL); `None` where the program does not say.
    pub tool_down: Option<bool>,
    /// Spindle state during the move.
    pub spindle: Spindle,
    /// Where in the source this move was programmed.
    pub span: Span,
}

/// A diagnostic that did not stop decoding (e.g. a normalised tool vector).
#[derive(Debug, Clone, PartialEq)]
pub struct Warning {
    /// Where in the source it arose.
    pub span: Span,
    /// What happened, as shown to the user.
    pub message: String,
}

/// A tool the program describes (APT `TLDATA`), in metres and radians.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ProgramTool {
    /// The operation it is used in (NX `TOOL PATH/operation,TOOL,tool`), where given.
    pub operation: Option<String>,
    /// The tool's name, where given.
    pub name: Option<String>,
    /// The kind as the record names it (`MILL`, `DRILL`, …).
    pub kind: String,
    /// Cutting diameter (m).
    pub diameter: f64,
    /// Corner radius of the cutting edge (m); 0 for a flat end mill.
    pub corner_radius: f64,
    /// Tool length (m).
    pub length: f64,
    /// Taper angle of the flank (rad).
    pub taper_angle: f64,
    /// Tip angle (rad): the bottom's angle for mills, the point angle for drills.
    pub tip_angle: f64,
    /// Where it was described.
    pub span: Span,
}

/// A decoded part program.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Program {
    /// The file it was read from (or a label such as `<scenario path>` for built-in paths).
    pub source: PathBuf,
    /// Position the program assumes before its first move (m, rad).
    pub start: Position,
    /// The moves, in program order.
    pub moves: Vec<Move>,
    /// Diagnostics that did not stop decoding.
    pub warnings: Vec<Warning>,
    /// The tools the program describes, in the order described: APT `TLDATA`; in G-code the
    /// tools M6 or M61 put in the spindle that the tool table gives a diameter.
    pub tools: Vec<ProgramTool>,
    /// How the reader read a file whose conventions depend on its writer (CL data: the CAM
    /// system it assumed and why), as shown to the user.
    pub reading: Option<String>,
}

impl Program {
    /// Moves every point of the program, its start included, by `offset` (m, along X, Y, Z):
    /// program coordinates to machine coordinates under a work offset.
    pub fn shift(&mut self, offset: [f64; 3]) {
        if offset == [0.0; 3] {
            return;
        }
        for (v, o) in self.start.linear.iter_mut().zip(offset) {
            *v += o;
        }
        for m in &mut self.moves {
            for (v, o) in m.end.linear.iter_mut().zip(offset) {
                *v += o;
            }
            if let Motion::Arc { center, .. } = &mut m.motion {
                for (v, o) in center.iter_mut().zip(offset) {
                    *v += o;
                }
            }
        }
    }
}
