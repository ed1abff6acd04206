//! The machine side of the interpreter: LinuxCNC's canonical machining functions, turned
//! into [`Move`]s.
//!
//! The interpreter works in program coordinates and program units, like LinuxCNC's; as in
//! LinuxCNC's `emccanon`, this layer adds the offsets the interpreter announced
//! (G92 offset, then the XY rotation of the coordinate system, then its G54–G59.3 origin,
//! then the tool length offset) and converts to SI. A move's `end` is therefore the position
//! the machine is commanded to: program position plus every active offset.

// Axis loops index several parallel arrays (positions and offsets) at once.
#![allow(clippy::needless_range_loop)]

use crate::program::options::{LengthUnit, ReadOptions};
use crate::program::types::{
    Blend, Feed, FeedRule, Motion, Move, Plane, Position, Program, Span, Spindle,
};

/// A point in program coordinates: X Y Z (program units) and A B C (degrees).
pub(super) type Axes = [f64; 6];

/// Offsets as the interpreter announced them, in the units current when they were announced
/// (kept in step with [`Canon::use_length_units`]).
#[derive(Debug, Clone, Copy, Default)]
struct Offsets {
    g5x: Axes,
    g92: Axes,
    tool: Axes,
    /// Rotation of the XY plane of the coordinate system, degrees.
    rotation: f64,
}

/// Feed as programmed: the F number and the units current when it was set (LinuxCNC's
/// `SET_FEED_RATE` converts with the units of that moment).
#[derive(Debug, Clone, Copy)]
struct FeedSetting {
    number: f64,
    unit: LengthUnit,
}

pub(super) struct Canon {
    pub program: Program,
    feed_rule: FeedRule,
    units: LengthUnit,
    offsets: Offsets,
    feed: Option<FeedSetting>,
    pub blend: Blend,
    pub spindle: Spindle,
    /// The machine position (SI) after the last move.
    position: Position,
    /// The most moves a program may produce.
    max_moves: usize,
}

/// The settings a move takes from the canon when it is made: a move held back by cutter
/// compensation keeps those of the moment it was programmed (LinuxCNC queues the commands
/// that change them behind it).
#[derive(Debug, Clone, Copy)]
pub(super) struct Snapshot {
    feed: Option<FeedSetting>,
    spindle: Spindle,
}

/// Moves beyond the limit: the interpreter stops with this.
pub(super) struct TooManyMoves(pub usize);

impl Canon {
    pub fn new(program: Program, options: &ReadOptions) -> Self {
        Canon {
            program,
            feed_rule: options.feed_rule,
            units: options.gcode.initial_units,
            offsets: Offsets::default(),
            feed: None,
            blend: Blend::Continuous {
                tolerance: None,
                naive_cam: None,
            },
            spindle: Spindle::Off,
            position: Position::default(),
            max_moves: options.gcode.max_moves,
        }
    }

    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            feed: self.feed,
            spindle: self.spindle,
        }
    }

    /// Runs `make` with the feed and spindle of `snapshot`, then restores the current ones.
    pub fn replay<T>(&mut self, snapshot: Snapshot, make: impl FnOnce(&mut Self) -> T) -> T {
        let now = self.snapshot();
        self.feed = snapshot.feed;
        self.spindle = snapshot.spindle;
        let result = make(self);
        self.feed = now.feed;
        self.spindle = now.spindle;
        result
    }

    pub fn use_length_units(&mut self, units: LengthUnit) {
        if units != self.units {
            let factor = self.units.metres() / units.metres();
            for offsets in [
                &mut self.offsets.g5x,
                &mut self.offsets.g92,
                &mut self.offsets.tool,
            ] {
                for value in offsets.iter_mut().take(3) {
                    *value *= factor;
                }
            }
            self.units = units;
        }
    }

    pub fn set_g5x_offset(&mut self, offset: Axes) {
        self.offsets.g5x = offset;
    }

    pub fn set_g92_offset(&mut self, offset: Axes) {
        self.offsets.g92 = offset;
    }

    pub fn set_xy_rotation(&mut self, degrees: f64) {
        self.offsets.rotation = degrees;
    }

    pub fn use_tool_length_offset(&mut self, offset: Axes) {
        self.offsets.tool = offset;
    }

    /// `SET_FEED_RATE`: the number in the units current now.
    pub fn set_feed_rate(&mut self, number: f64) {
        self.feed = Some(FeedSetting {
            number,
            unit: self.units,
        });
    }

    /// The feed rate as the interpreter sees it after a change of units.
    pub fn feed_rate_in(&self, units: LengthUnit) -> f64 {
        self.feed.map_or(0.0, |feed| {
            feed.number * feed.unit.metres() / units.metres()
        })
    }

    /// The machine position (SI) after the last move.
    pub fn position(&self) -> Position {
        self.position
    }

    /// The machine position (SI) of a point in program coordinates.
    pub fn machine(&self, point: &Axes) -> Position {
        let o = &self.offsets;
        let mut p = *point;
        for (value, offset) in p.iter_mut().zip(&o.g92) {
            *value += offset;
        }
        let (x, y) = rotate(p[0], p[1], o.rotation);
        p[0] = x;
        p[1] = y;
        for axis in 0..6 {
            p[axis] += o.g5x[axis] + o.tool[axis];
        }
        Position {
            linear: [
                self.units.to_metres(p[0]),
                self.units.to_metres(p[1]),
                self.units.to_metres(p[2]),
            ],
            rotary: [p[3].to_radians(), p[4].to_radians(), p[5].to_radians()],
        }
    }

    fn check_room(&self) -> Result<(), TooManyMoves> {
        if self.program.moves.len() >= self.max_moves {
            Err(TooManyMoves(self.max_moves))
        } else {
            Ok(())
        }
    }

    pub fn straight_traverse(&mut self, end: &Axes, span: Span) -> Result<(), TooManyMoves> {
        let end = self.machine(end);
        self.push(Motion::Linear, end, Feed::Rapid, span)
    }

    /// `STRAIGHT_FEED` at the current feed (or, in inverse time, taking `inverse_time` s).
    pub fn straight_feed(
        &mut self,
        end: &Axes,
        inverse_time: Option<f64>,
        span: Span,
    ) -> Result<(), TooManyMoves> {
        let end = self.machine(end);
        let feed = self.feed_for(&end, inverse_time);
        self.push(Motion::Linear, end, feed, span)
    }

    /// `ARC_FEED`: `centre` in program coordinates (its normal coordinate ignored), `turns`
    /// extra full turns.
    pub fn arc_feed(
        &mut self,
        end: &Axes,
        centre: &Axes,
        (plane, clockwise, turns): (Plane, bool, u32),
        inverse_time: Option<f64>,
        span: Span,
    ) -> Result<(), TooManyMoves> {
        let end = self.machine(end);
        let centre = self.machine(centre);
        let normal = match plane {
            Plane::XY => 2,
            Plane::ZX => 1,
            Plane::YZ => 0,
        };
        let mut center = centre.linear;
        center[normal] = self.position.linear[normal];
        let feed = self.feed_for(&end, inverse_time);
        self.push(
            Motion::Arc {
                center,
                plane,
                clockwise,
                turns,
            },
            end,
            feed,
            span,
        )
    }

    pub fn dwell(&mut self, seconds: f64, span: Span) -> Result<(), TooManyMoves> {
        self.push(Motion::Dwell { seconds }, self.position, Feed::Rapid, span)
    }

    fn feed_for(&self, end: &Position, inverse_time: Option<f64>) -> Feed {
        if let Some(seconds) = inverse_time {
            return Feed::InverseTime(seconds);
        }
        let Some(setting) = self.feed else {
            return Feed::PathSpeed(0.0);
        };
        let linear_moves = (0..3).any(|axis| end.linear[axis] != self.position.linear[axis]);
        let rotary_moves = (0..3).any(|axis| end.rotary[axis] != self.position.rotary[axis]);
        if self.feed_rule == FeedRule::LinuxCnc && rotary_moves && !linear_moves {
            // LinuxCNC applies the F number to a purely rotary move in degrees per minute.
            // `Feed::PathSpeed` carries it with 1 mm ≡ 1 degree (see `FeedRule::LinuxCnc`).
            return Feed::PathSpeed(setting.number / 60.0 / 1000.0);
        }
        Feed::PathSpeed(setting.unit.to_metres(setting.number) / 60.0)
    }

    fn push(
        &mut self,
        motion: Motion,
        end: Position,
        feed: Feed,
        span: Span,
    ) -> Result<(), TooManyMoves> {
        self.check_room()?;
        self.program.moves.push(Move {
            motion,
            end,
            tool_axis: None,
            feed,
            feed_rule: self.feed_rule,
            blend: self.blend,
            tool_down: None,
            spindle: self.spindle,
            span,
        });
        self.position = end;
        Ok(())
    }
}

/// (x, y) turned by `degrees` about the origin (LinuxCNC `rotate`).
pub(super) fn rotate(x: f64, y: f64, degrees: f64) -> (f64, f64) {
    if degrees == 0.0 {
        return (x, y);
    }
    let (sin, cos) = degrees.to_radians().sin_cos();
    (x * cos - y * sin, x * sin + y * cos)
}
