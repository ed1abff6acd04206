//! The reference paths of the source documents (straight lines with corners and circles at
//! constant path speed), as programs.

use super::{Blend, Feed, FeedRule, Motion, Move, Plane, Position, Program, Span, Spindle};
use std::f64::consts::TAU;
use std::path::Path;

/// A full circle in the XY plane, starting and ending at `start_angle`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleSpec {
    /// Centre (m).
    pub center: [f64; 2],
    /// Radius (m).
    pub radius: f64,
    /// Angle of the start point from +X (rad).
    pub start_angle: f64,
    /// Turns clockwise seen from +Z (as G2) rather than counter-clockwise (G3).
    pub clockwise: bool,
    /// Height of the tool (m).
    pub z: f64,
    /// Path speed (m/s).
    pub speed: f64,
}

/// Straight lines through the given points (m) at constant path speed, stopping exactly at
/// each point.
#[derive(Debug, Clone, PartialEq)]
pub struct PolylineSpec {
    /// The points in order, X Y Z (m); the first is the start.
    pub points: Vec<[f64; 3]>,
    /// Path speed (m/s).
    pub speed: f64,
}

fn base_move(motion: Motion, end: [f64; 3], speed: f64) -> Move {
    Move {
        motion,
        end: Position {
            linear: end,
            rotary: [0.0; 3],
        },
        tool_axis: None,
        feed: Feed::PathSpeed(speed),
        feed_rule: FeedRule::LinuxCnc,
        blend: Blend::ExactStop,
        tool_down: None,
        spindle: Spindle::Off,
        span: Span::default(),
    }
}

/// The circle as a one-move program (end = start, a full circle), labelled `source`.
pub fn circle(spec: &CircleSpec, source: &Path) -> Program {
    let (s, c) = spec.start_angle.rem_euclid(TAU).sin_cos();
    let start = [
        spec.center[0] + spec.radius * c,
        spec.center[1] + spec.radius * s,
        spec.z,
    ];
    let arc = Motion::Arc {
        center: [spec.center[0], spec.center[1], spec.z],
        plane: Plane::XY,
        clockwise: spec.clockwise,
        turns: 0,
    };
    Program {
        source: source.to_path_buf(),
        start: Position {
            linear: start,
            rotary: [0.0; 3],
        },
        // End = start: a full circle, as G2/G3 read it.
        moves: vec![base_move(arc, start, spec.speed)],
        warnings: Vec::new(),
        tools: Vec::new(),
        reading: None,
    }
}

/// The polyline as a program of straight moves from its first point (the origin when it has
/// none), labelled `source`.
pub fn polyline(spec: &PolylineSpec, source: &Path) -> Program {
    let start = spec.points.first().copied().unwrap_or_default();
    Program {
        source: source.to_path_buf(),
        start: Position {
            linear: start,
            rotary: [0.0; 3],
        },
        moves: spec
            .points
            .iter()
            .skip(1)
            .map(|p| base_move(Motion::Linear, *p, spec.speed))
            .collect(),
        warnings: Vec::new(),
        tools: Vec::new(),
        reading: None,
    }
}
