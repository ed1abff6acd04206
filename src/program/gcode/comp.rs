//! Cutter radius compensation G41/G42 (tool diameter from the tool table, `D` = tool number)
//! and G41.1/G42.1 (`D` = diameter), in the XY and XZ planes, with LinuxCNC's rules
//! (`convert_straight_comp1/2`, `convert_arc_comp1/2`, `interp_queue.cc`):
//!
//! - the entry move (first move after G41/G42) goes to a point one tool radius beside the
//!   programmed end, perpendicular to the line from the start; an entry arc is offset the
//!   same way;
//! - every following move is offset to the programmed path's side; the last move is held
//!   back until the next one shows the corner: at a convex corner an arc about the programmed
//!   corner is added (a straight traverse for G0), at a concave corner the held move's end is
//!   pulled back to where the two offset paths meet (an error where the tool cannot fit);
//! - G40, a program stop or the end of the program sends the held move as it is; the move
//!   after G40 must be straight.
//!
//! Positions here are in "plane coordinates": (X, Y, Z) in G17, (Z, X, Y) in G18.

use std::f64::consts::{FRAC_PI_2, PI};

use super::block::Block;
use super::canon::{Axes, Snapshot};
use super::execute::too_many_moves;
use super::state::Interpreter;
use super::LineError;
use crate::program::types::{Plane, Span};

/// Angle (rad) within which corners count as straight (LinuxCNC `TOLERANCE_CONCAVE_CORNER`).
const CORNER_TOLERANCE: f64 = 0.05;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Side {
    Left,
    Right,
}

/// A canonical command held back while compensation waits for the next corner.
#[derive(Debug, Clone)]
enum Held {
    Straight {
        rapid: bool,
        /// Direction of the programmed motion (plane coordinates).
        direction: [f64; 2],
        end: Axes,
        inverse_time: Option<f64>,
        settings: Snapshot,
        span: Span,
    },
    Arc {
        /// Signed sweep of the arc as first computed (0: never moved).
        original_sweep: f64,
        end: Axes,
        centre: [f64; 2],
        /// LinuxCNC's turn: + counter-clockwise, − clockwise, magnitude = turns.
        turn: i32,
        inverse_time: Option<f64>,
        settings: Snapshot,
        span: Span,
    },
    Dwell {
        seconds: f64,
        span: Span,
    },
}

/// Cutter compensation state (LinuxCNC `cutter_comp_*`, `program_*`, the canon queue).
#[derive(Debug, Default)]
pub(super) struct Compensation {
    pub side: Option<Side>,
    pub radius: f64,
    pub first_move: bool,
    /// The programmed (uncompensated) point, program coordinates X Y Z.
    pub programmed: [f64; 3],
    pub arc_not_allowed: bool,
    held: Vec<Held>,
    /// Start of the held move (plane coordinates), for the gouge checks.
    endpoint: Option<[f64; 2]>,
}

impl Compensation {
    pub fn new() -> Self {
        Compensation {
            first_move: true,
            ..Compensation::default()
        }
    }

    pub fn active(&self) -> bool {
        self.side.is_some() && self.radius > 0.0
    }

    /// Scales held positions after a change of units (LinuxCNC `qc_scale`).
    pub fn scale(&mut self, factor: f64) {
        self.radius *= factor;
        for value in &mut self.programmed {
            *value *= factor;
        }
        if let Some(point) = &mut self.endpoint {
            point[0] *= factor;
            point[1] *= factor;
        }
        for held in &mut self.held {
            match held {
                Held::Straight { end, .. } => end.iter_mut().take(3).for_each(|v| *v *= factor),
                Held::Arc { end, centre, .. } => {
                    end.iter_mut().take(3).for_each(|v| *v *= factor);
                    centre[0] *= factor;
                    centre[1] *= factor;
                }
                Held::Dwell { .. } => {}
            }
        }
    }

    pub fn holds_anything(&self) -> bool {
        !self.held.is_empty()
    }
}

/// Axis indices of plane coordinates (first, second, third).
fn plane_indices(plane: Plane) -> [usize; 3] {
    match plane {
        Plane::ZX => [2, 0, 1],
        _ => [0, 1, 2],
    }
}

/// Signed sweep (rad) of an arc from `start` about `centre` to `end`, `turn` as LinuxCNC's
/// (`find_turn`).
pub(super) fn sweep(start: [f64; 2], centre: [f64; 2], turn: i32, end: [f64; 2]) -> f64 {
    if turn == 0 {
        return 0.0;
    }
    let mut alpha = (start[1] - centre[1]).atan2(start[0] - centre[0]);
    let mut beta = (end[1] - centre[1]).atan2(end[0] - centre[0]);
    if turn > 0 {
        if beta <= alpha {
            beta += 2.0 * PI;
        }
        (beta - alpha) + f64::from(turn - 1) * 2.0 * PI
    } else {
        if alpha <= beta {
            alpha += 2.0 * PI;
        }
        (beta - alpha) + f64::from(turn + 1) * 2.0 * PI
    }
}

fn tool_inside_arc(side: Side, turn: i32) -> bool {
    (side == Side::Left && turn > 0) || (side == Side::Right && turn < 0)
}

impl Interpreter<'_> {
    fn plane_point(&self, point: &Axes) -> [f64; 3] {
        let [a, b, c] = plane_indices(self.s.plane);
        [point[a], point[b], point[c]]
    }

    fn set_plane_point(&self, point: &mut Axes, value: [f64; 3]) {
        let [a, b, c] = plane_indices(self.s.plane);
        point[a] = value[0];
        point[b] = value[1];
        point[c] = value[2];
    }

    fn programmed_plane(&self) -> [f64; 3] {
        let p = self.comp.programmed;
        self.plane_point(&[p[0], p[1], p[2], 0.0, 0.0, 0.0])
    }

    fn set_programmed_plane(&mut self, value: [f64; 3]) {
        let mut axes = [0.0; 6];
        self.set_plane_point(&mut axes, value);
        self.comp.programmed = [axes[0], axes[1], axes[2]];
    }

    /// G40, G41, G42, G41.1, G42.1.
    pub fn cutter_compensation(
        &mut self,
        code: u32,
        block: &Block,
        span: Span,
    ) -> Result<(), LineError> {
        let word = block.g[super::codes::group::CUTTER_COMP].expect("comp code");
        let error = |problem: String| word.error(problem);
        if code == 400 {
            if self.comp.active() && !self.comp.first_move {
                let current = self.plane_point(&self.s.current);
                self.move_endpoint_and_flush([current[0], current[1]])?;
                let programmed = self.comp.programmed;
                self.s.current[..3].copy_from_slice(&programmed);
                self.comp.arc_not_allowed = true;
            }
            self.comp.side = None;
            self.comp.first_move = true;
            let _ = span;
            return Ok(());
        }
        if !matches!(self.s.plane, Plane::XY | Plane::ZX) {
            return Err(error(
                "expected the G17 or G18 plane for cutter radius compensation".into(),
            ));
        }
        if self.comp.side.is_some() {
            return Err(error(
                "expected G40 before turning cutter radius compensation on again".into(),
            ));
        }
        let mut side = if matches!(code, 410 | 411) {
            Side::Left
        } else {
            Side::Right
        };
        let radius = if matches!(code, 411 | 421) {
            let Some(d) = block.word(b'd') else {
                return Err(error(
                    "expected a D word (tool diameter) with G41.1/G42.1".into(),
                ));
            };
            if let Some(l) = block.value(b'l') {
                if !matches!(l.round() as i64, 0 | 9) {
                    return Err(error("expected lathe tool orientation L0 or L9; other orientations are not supported".into()));
                }
            }
            d.value / 2.0
        } else {
            let tool = match block.word(b'd') {
                Some(d) => {
                    let number = self.tool_number(d)?;
                    if number == 0 {
                        self.spindle_tool()
                    } else {
                        *self.s.tool(number).expect("checked")
                    }
                }
                None => self.spindle_tool(),
            };
            self.user_to_program(tool.diameter) / 2.0
        };
        let radius = if radius < 0.0 {
            // A negative diameter swaps the side (a nominal-diameter path with a smaller tool).
            side = if side == Side::Left {
                Side::Right
            } else {
                Side::Left
            };
            -radius
        } else {
            radius
        };
        self.comp.side = Some(side);
        self.comp.radius = radius;
        self.comp.first_move = true;
        Ok(())
    }

    /// Sends the held commands, the held moves ending at `point` (LinuxCNC
    /// `move_endpoint_and_flush`), checking that the move does not turn back (a gouge).
    pub fn move_endpoint_and_flush(&mut self, point: [f64; 2]) -> Result<(), LineError> {
        let tolerance = match self.s.units {
            crate::program::options::LengthUnit::Millimetre => 0.0254,
            crate::program::options::LengthUnit::Inch => 0.001,
        };
        let endpoint = self.comp.endpoint;
        let indices = plane_indices(self.s.plane);
        for held in &mut self.comp.held {
            match held {
                Held::Straight {
                    rapid,
                    direction,
                    end,
                    ..
                } => {
                    if let Some(start) = endpoint {
                        let dot = direction[0] * (point[0] - start[0])
                            + direction[1] * (point[1] - start[1]);
                        if dot < 0.0 {
                            return Err(LineError::new(0, 0, format!(
                                "expected a concave corner the compensated tool can reach; the {} into it would have to run backwards (gouging)",
                                if *rapid { "straight traverse" } else { "straight feed" }
                            )));
                        }
                    }
                    end[indices[0]] = point[0];
                    end[indices[1]] = point[1];
                }
                Held::Arc {
                    original_sweep,
                    end,
                    centre,
                    turn,
                    ..
                } => {
                    if let Some(start) = endpoint {
                        let new_sweep = sweep(start, *centre, *turn, point);
                        if *original_sweep != 0.0
                            && new_sweep.abs() > original_sweep.abs() + tolerance
                        {
                            return Err(LineError::new(0, 0, "expected an arc the compensated tool can reach in this concave corner without gouging"));
                        }
                    }
                    end[indices[0]] = point[0];
                    end[indices[1]] = point[1];
                }
                Held::Dwell { .. } => {}
            }
        }
        self.dequeue()?;
        self.comp.endpoint = Some(point);
        Ok(())
    }

    /// Sends the held commands as they are.
    pub fn dequeue(&mut self) -> Result<(), LineError> {
        let held = std::mem::take(&mut self.comp.held);
        self.comp.endpoint = None;
        let plane = self.s.plane;
        for command in held {
            let outcome = match command {
                Held::Straight {
                    rapid,
                    end,
                    inverse_time,
                    settings,
                    span,
                    ..
                } => self.canon.replay(settings, |canon| {
                    if rapid {
                        canon.straight_traverse(&end, span)
                    } else {
                        canon.straight_feed(&end, inverse_time, span)
                    }
                }),
                Held::Arc {
                    end,
                    centre,
                    turn,
                    inverse_time,
                    settings,
                    span,
                    ..
                } => {
                    let mut centre_axes = end;
                    let [a, b, _] = plane_indices(plane);
                    centre_axes[a] = centre[0];
                    centre_axes[b] = centre[1];
                    let turns = turn.unsigned_abs().saturating_sub(1);
                    self.canon.replay(settings, |canon| {
                        canon.arc_feed(
                            &end,
                            &centre_axes,
                            (plane, turn < 0, turns),
                            inverse_time,
                            span,
                        )
                    })
                }
                Held::Dwell { seconds, span } => self.canon.dwell(seconds, span),
            };
            outcome.map_err(|limit| too_many_moves(limit.0))?;
        }
        Ok(())
    }

    /// A dwell while compensation holds a move comes after it.
    pub fn comp_dwell(&mut self, seconds: f64, span: Span) -> bool {
        if self.comp.held.is_empty() {
            return false;
        }
        self.comp.held.push(Held::Dwell { seconds, span });
        true
    }

    /// Holds a move back with the feed and spindle of this moment.
    fn hold(&mut self, make: impl FnOnce(Snapshot) -> Held) {
        let settings = self.canon.snapshot();
        self.comp.held.push(make(settings));
    }

    fn hold_straight(
        &mut self,
        rapid: bool,
        direction: [f64; 2],
        end: Axes,
        inverse_time: Option<f64>,
        span: Span,
    ) {
        self.hold(|settings| Held::Straight {
            rapid,
            direction,
            end,
            inverse_time,
            settings,
            span,
        });
    }

    fn hold_arc(
        &mut self,
        original_sweep: f64,
        end: Axes,
        centre: [f64; 2],
        turn: i32,
        inverse_time: Option<f64>,
        span: Span,
    ) {
        self.hold(|settings| Held::Arc {
            original_sweep,
            end,
            centre,
            turn,
            inverse_time,
            settings,
            span,
        });
    }

    /// A compensated G0/G1 to the programmed point `target` (program coordinates).
    pub fn straight_comp(
        &mut self,
        rapid: bool,
        target: &Axes,
        inverse_time: Option<f64>,
        span: Span,
    ) -> Result<(), LineError> {
        let side = self.comp.side.expect("comp on");
        let radius = self.comp.radius;
        let [px, py, pz] = self.plane_point(target);
        let [cx, cy, cz] = self.plane_point(&self.s.current);
        let mut end = *target;
        if self.comp.first_move {
            let distance = (px - cx).hypot(py - cy);
            if distance <= radius {
                return Err(LineError::new(0, 0, format!(
                    "expected a cutter compensation entry move longer than the tool radius ({radius:.4}); it is {distance:.4}"
                )));
            }
            let alpha = (py - cy).atan2(px - cx)
                + if side == Side::Left {
                    FRAC_PI_2
                } else {
                    -FRAC_PI_2
                };
            let end_point = [px + radius * alpha.cos(), py + radius * alpha.sin(), pz];
            self.comp.endpoint = Some([cx, cy]);
            self.set_plane_point(&mut end, end_point);
            self.hold_straight(rapid, [alpha.cos(), alpha.sin()], end, inverse_time, span);
            self.comp.first_move = false;
            self.s.current = end;
            self.set_programmed_plane([px, py, pz]);
            return Ok(());
        }
        let [opx, opy, opz] = self.programmed_plane();
        if px == opx && py == opy {
            // No motion in the plane.
            self.set_plane_point(&mut end, [cx, cy, pz]);
            self.hold_straight(rapid, [px - opx, py - opy], end, inverse_time, span);
            let _ = opz;
        } else {
            let mut theta = (cy - opy).atan2(cx - opx);
            let mut alpha = (py - opy).atan2(px - opx);
            let (beta, gamma) = if side == Side::Left {
                if theta < alpha {
                    theta += 2.0 * PI;
                }
                (theta - alpha - FRAC_PI_2, FRAC_PI_2)
            } else {
                if alpha < theta {
                    alpha += 2.0 * PI;
                }
                (alpha - theta - FRAC_PI_2, -FRAC_PI_2)
            };
            let end_point = [
                px + radius * (alpha + gamma).cos(),
                py + radius * (alpha + gamma).sin(),
                pz,
            ];
            let front_arc_turn = match self.comp.held.first() {
                Some(Held::Arc { turn, .. }) => Some(*turn),
                _ => None,
            };
            let concave = !(-CORNER_TOLERANCE..=PI + CORNER_TOLERANCE).contains(&beta)
                || (beta > PI - CORNER_TOLERANCE
                    && front_arc_turn.is_some_and(|turn| {
                        (side == Side::Right && turn > 0) || (side == Side::Left && turn < 0)
                    }));
            if !concave && beta > CORNER_TOLERANCE {
                // Convex corner: go around the programmed corner.
                let mid = [
                    opx + radius * (alpha + gamma).cos(),
                    opy + radius * (alpha + gamma).sin(),
                ];
                self.move_endpoint_and_flush([cx, cy])?;
                let mut corner_end = self.s.current;
                self.set_plane_point(&mut corner_end, [mid[0], mid[1], cz]);
                corner_end[3..].copy_from_slice(&target[3..]);
                if rapid {
                    self.hold_straight(true, [0.0, 0.0], corner_end, None, span);
                } else {
                    let turn = if side == Side::Left { -1 } else { 1 };
                    self.hold_arc(0.0, corner_end, [opx, opy], turn, None, span);
                }
                self.dequeue()?;
                self.comp.endpoint = Some(mid);
            } else if concave {
                match self.comp.held.first().cloned() {
                    Some(Held::Arc {
                        end: prev_end,
                        centre,
                        turn: prev_turn,
                        ..
                    }) => {
                        let [e1, e2, _] = self.plane_point(&prev_end);
                        let old_radius = (centre[1] - e2).hypot(centre[0] - e1);
                        let base = (py - opy).atan2(px - opx);
                        let theta = if prev_turn > 0 {
                            base + FRAC_PI_2
                        } else {
                            base - FRAC_PI_2
                        };
                        let phi = (centre[1] - opy).atan2(centre[0] - opx);
                        let inside = tool_inside_arc(side, prev_turn);
                        let uncompensated = if inside {
                            old_radius + radius
                        } else {
                            old_radius - radius
                        };
                        let d = uncompensated * (theta - phi).cos();
                        let gouge = || {
                            LineError::new(0, 0, "expected an arc-to-line corner the compensated tool can fit in without gouging")
                        };
                        let angle = if inside {
                            let l = (d - radius) / old_radius;
                            if !(-1.0..=1.0).contains(&l) {
                                return Err(gouge());
                            }
                            if prev_turn > 0 {
                                -l.acos() + theta + PI
                            } else {
                                l.acos() + theta + PI
                            }
                        } else {
                            let l = (d + radius) / old_radius;
                            if !(-1.0..=1.0).contains(&l) {
                                return Err(gouge());
                            }
                            if prev_turn > 0 {
                                l.acos() + theta + PI
                            } else {
                                -l.acos() + theta + PI
                            }
                        };
                        let mid = [
                            centre[0] + old_radius * angle.cos(),
                            centre[1] + old_radius * angle.sin(),
                        ];
                        self.move_endpoint_and_flush(mid)?;
                    }
                    _ => {
                        let half_corner = (beta + PI) / 2.0;
                        if half_corner == 0.0 {
                            return Err(LineError::new(0, 0, "expected an inside corner of more than zero degrees for cutter compensation"));
                        }
                        let retreat = radius / half_corner.tan();
                        let mid = [
                            cx + retreat * (theta + gamma).cos(),
                            cy + retreat * (theta + gamma).sin(),
                        ];
                        self.move_endpoint_and_flush(mid)?;
                    }
                }
            } else {
                // Straight on (or a tangent arc into a line).
                self.dequeue()?;
                self.comp.endpoint = Some([cx, cy]);
            }
            self.set_plane_point(&mut end, end_point);
            self.hold_straight(rapid, [px - opx, py - opy], end, inverse_time, span);
        }
        self.s.current = end;
        self.set_programmed_plane([px, py, pz]);
        Ok(())
    }

    /// A compensated G2/G3 to the programmed point `target`, with the arc's centre and turn
    /// computed from the programmed start.
    pub fn arc_comp(
        &mut self,
        clockwise: bool,
        target: &Axes,
        centre: [f64; 2],
        turn: i32,
        inverse_time: Option<f64>,
        span: Span,
    ) -> Result<(), LineError> {
        let side = self.comp.side.expect("comp on");
        let radius = self.comp.radius;
        let [ex, ey, ez] = self.plane_point(target);
        let [cx, cy, cz] = self.plane_point(&self.s.current);
        let spiral = self.options.gcode.arc_tolerance.spiral(self.s.units);
        let too_small = || {
            LineError::new(0, 0, "expected an arc radius larger than the tool radius with cutter compensation on the inside of the arc")
        };
        let mut end = *target;
        if self.comp.first_move {
            if (ex - cx).hypot(ey - cy) <= radius {
                return Err(LineError::new(
                    0,
                    0,
                    "expected a cutter compensation entry arc longer than the tool radius",
                ));
            }
            let arc_radius = (centre[0] - cx).hypot(centre[1] - cy);
            if arc_radius <= radius && tool_inside_arc(side, turn) {
                return Err(too_small());
            }
            let gamma = if tool_inside_arc(side, turn) {
                (centre[1] - ey).atan2(centre[0] - ex)
            } else {
                (ey - centre[1]).atan2(ex - centre[0])
            };
            self.comp.first_move = false;
            self.set_programmed_plane([ex, ey, ez]);
            let new_end = [ex + radius * gamma.cos(), ey + radius * gamma.sin()];
            let b_len = (cy - new_end[1]).hypot(cx - new_end[0]) / 2.0;
            let ab_angle = (centre[1] - new_end[1]).atan2(centre[0] - new_end[0]);
            let a_angle = (cy - new_end[1]).atan2(cx - new_end[0]) - ab_angle;
            if a_angle.cos().abs() < 0.0001 {
                return Err(too_small());
            }
            let c_len = b_len / a_angle.cos();
            let new_centre = [
                new_end[0] + c_len * ab_angle.cos(),
                new_end[1] + c_len * ab_angle.sin(),
            ];
            if ((new_centre[0] - new_end[0]).hypot(new_centre[1] - new_end[1])
                - (new_centre[0] - cx).hypot(new_centre[1] - cy))
            .abs()
                > spiral
            {
                return Err(too_small());
            }
            self.set_plane_point(&mut end, [new_end[0], new_end[1], ez]);
            let original = sweep([cx, cy], new_centre, turn, new_end);
            self.hold_arc(original, end, new_centre, turn, inverse_time, span);
            self.s.current = end;
            let _ = (clockwise, cz);
            return Ok(());
        }
        let [opx, opy, _] = self.programmed_plane();
        let arc_radius = (centre[0] - ex).hypot(centre[1] - ey);
        let mut theta = (cy - opy).atan2(cx - opx);
        theta = if side == Side::Left {
            theta - FRAC_PI_2
        } else {
            theta + FRAC_PI_2
        };
        let mut delta = (centre[1] - opy).atan2(centre[0] - opx);
        let alpha = if clockwise {
            delta + FRAC_PI_2
        } else {
            delta - FRAC_PI_2
        };
        let mut beta = if side == Side::Left {
            theta - alpha
        } else {
            alpha - theta
        };
        if beta > 1.5 * PI {
            beta -= 2.0 * PI;
        } else if beta < -FRAC_PI_2 {
            beta += 2.0 * PI;
        }
        let gamma = if (side == Side::Left && !clockwise) || (side == Side::Right && clockwise) {
            if arc_radius <= radius {
                return Err(too_small());
            }
            (centre[1] - ey).atan2(centre[0] - ex)
        } else {
            delta += PI;
            (ey - centre[1]).atan2(ex - centre[0])
        };
        let new_end = [ex + radius * gamma.cos(), ey + radius * gamma.sin()];
        let original = sweep([opx, opy], centre, turn, [ex, ey]);
        self.set_plane_point(&mut end, [new_end[0], new_end[1], ez]);
        let inside = tool_inside_arc(side, turn);
        if !(-CORNER_TOLERANCE..=PI + CORNER_TOLERANCE).contains(&beta)
            || ((beta - PI).abs() < CORNER_TOLERANCE && !inside)
        {
            // Concave corner into the arc.
            match self.comp.held.first().cloned() {
                Some(Held::Arc {
                    end: prev_end,
                    centre: prev_centre,
                    turn: prev_turn,
                    ..
                }) => {
                    let [e1, e2, _] = self.plane_point(&prev_end);
                    let old_radius = (prev_centre[1] - e2).hypot(prev_centre[0] - e1);
                    let new_radius = if inside {
                        arc_radius - radius
                    } else {
                        arc_radius + radius
                    };
                    let centre_distance =
                        (prev_centre[1] - centre[1]).hypot(prev_centre[0] - centre[0]);
                    if old_radius == 0.0 || centre_distance == 0.0 {
                        return Err(LineError::new(0, 0, "expected arcs with different centres: arc-to-arc compensation with one centre is not defined"));
                    }
                    let a = (old_radius.powi(2) + centre_distance.powi(2) - new_radius.powi(2))
                        / (2.0 * old_radius * centre_distance);
                    if !(-1.0..=1.0).contains(&a) {
                        return Err(LineError::new(0, 0, "expected an arc-to-arc corner the compensated tool can fit in without gouging"));
                    }
                    let pullback = a.acos();
                    let direction = (centre[1] - prev_centre[1]).atan2(centre[0] - prev_centre[0]);
                    let dir = if tool_inside_arc(side, prev_turn) == (turn > 0) {
                        direction + pullback
                    } else {
                        direction - pullback
                    };
                    let mid = [
                        prev_centre[0] + old_radius * dir.cos(),
                        prev_centre[1] + old_radius * dir.sin(),
                    ];
                    self.move_endpoint_and_flush(mid)?;
                }
                _ => {
                    let offset = arc_radius * (beta - FRAC_PI_2).sin();
                    let gouge = || {
                        LineError::new(0, 0, "expected an arc the compensated tool can reach in this concave corner without gouging")
                    };
                    let (distance, angle) = if inside {
                        let distance = arc_radius - radius;
                        let l = (offset + radius) / distance;
                        if !(-1.0..=1.0).contains(&l) {
                            return Err(gouge());
                        }
                        (
                            distance,
                            if turn > 0 {
                                theta + l.asin()
                            } else {
                                theta - l.asin()
                            },
                        )
                    } else {
                        let distance = arc_radius + radius;
                        let l = (offset - radius) / distance;
                        if !(-1.0..=1.0).contains(&l) {
                            return Err(gouge());
                        }
                        (
                            distance,
                            if turn > 0 {
                                theta + PI - l.asin()
                            } else {
                                theta + PI + l.asin()
                            },
                        )
                    };
                    let mid = [
                        centre[0] + distance * angle.cos(),
                        centre[1] + distance * angle.sin(),
                    ];
                    self.move_endpoint_and_flush(mid)?;
                }
            }
            self.hold_arc(original, end, centre, turn, inverse_time, span);
        } else if beta > CORNER_TOLERANCE {
            // Convex corner: an arc about the programmed corner, then the arc.
            let mid = [opx + radius * delta.cos(), opy + radius * delta.sin()];
            self.dequeue()?;
            let mut corner_end = end;
            self.set_plane_point(&mut corner_end, [mid[0], mid[1], cz]);
            let corner_turn = if side == Side::Left { -1 } else { 1 };
            self.hold_arc(0.0, corner_end, [opx, opy], corner_turn, None, span);
            self.dequeue()?;
            self.comp.endpoint = Some(mid);
            self.hold_arc(original, end, centre, turn, inverse_time, span);
        } else {
            self.dequeue()?;
            self.comp.endpoint = Some([cx, cy]);
            self.hold_arc(original, end, centre, turn, inverse_time, span);
        }
        self.set_programmed_plane([ex, ey, ez]);
        self.s.current = end;
        Ok(())
    }
}
