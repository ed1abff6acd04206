//! Programs that give the tool tip on the part, put onto a five-axis machine's axes.
//!
//! * **Cutter-location data** (`GOTO/x,y,z,i,j,k`): each point and tool axis becomes machine
//!   coordinates by [`FiveAxisKinematics::inverse`], move end by move end, as a post-processor
//!   writes them for a machine without tool-tip control.
//! * **Tool-tip programs** (`[program] kinematics = "tcp"`, as G43.4, TRAORI and TCPM): X Y Z
//!   are the tip in part coordinates, the rotary words the axes' angles. The controller keeps
//!   the tip on the programmed line or arc while the rotary axes turn, so each move becomes
//!   joint-space pieces whose tip path stays within a tolerance of it, at the programmed
//!   speed of the tip on the part.

use super::five_axis::{FiveAxisKinematics, InverseError, Solution, ToolPose};
use crate::program::{
    move_duration, Blend, Feed, Motion, Move, PathGeometry, Position, Program, ProgramError,
    ProgramErrors, Warning,
};
use nalgebra::{Point3, Vector3};

/// Most halvings of a piece of a tool-tip move.
const MAX_DEPTH: u32 = 16;
/// Largest turn of a rotary axis (rad) or sweep of an arc within one starting piece.
const START_PIECE_ANGLE: f64 = 2.0 * std::f64::consts::PI / 180.0;
/// Most starting pieces of one move.
const MAX_START_PIECES: usize = 4096;

fn error(program: &Program, m: &Move, problem: String, hint: &str) -> ProgramError {
    ProgramError::new(program.source.clone(), Some(m.span), problem).hint(hint)
}

fn hint(e: &InverseError) -> &'static str {
    match e {
        InverseError::OutOfTravel { .. } | InverseError::OutOfReach { .. } => {
            "the tool pose is unreachable on this machine: change the tool axis or the part's set-up"
        }
        InverseError::LinearSingular => "change the rotary angles of this move",
        _ => "program a finite point and a non-zero tool-axis vector",
    }
}

/// Cutter-location moves (workpiece coordinates, `tool_axis: Some(..)`) as machine
/// coordinates, solved in program order from every axis at home, with the continuity rule.
/// Every move that cannot be converted is an error at its line; a move that had to take the
/// far solution, and the first of the moves at the pole, add warnings.
pub fn cl_to_machine(k: &FiveAxisKinematics, program: &Program) -> Result<Program, ProgramErrors> {
    let mut errors = Vec::new();
    let mut warnings = program.warnings.clone();
    let mut moves = Vec::with_capacity(program.moves.len());
    let mut previous = Position::default();
    let mut poles: Option<(Move, usize)> = None;
    for m in &program.moves {
        let mut converted = m.clone();
        converted.tool_axis = None;
        match cl_target(program, m) {
            Err(e) => {
                errors.push(e);
                continue;
            }
            Ok(None) => {}
            Ok(Some(target)) => match k.inverse(&target, &previous) {
                Ok(solved) => {
                    if solved.forced_by_travel {
                        let [first, second] = k.rotary_indices();
                        warnings.push(Warning {
                                span: m.span,
                                message: format!(
                                    "line {}: the solution nearest the previous position is outside the travel; took {} ({} = {:.3}°, {} = {:.3}°), a large rotary move",
                                    m.span.line,
                                    solved.solution,
                                    k.rotary_letters()[0],
                                    solved.position.rotary[first].to_degrees(),
                                    k.rotary_letters()[1],
                                    solved.position.rotary[second].to_degrees()
                                ),
                            });
                    }
                    if solved.solution == Solution::Pole {
                        let count = poles.as_ref().map_or(0, |p| p.1) + 1;
                        let first = poles.map_or_else(|| m.clone(), |p| p.0);
                        poles = Some((first, count));
                    }
                    previous = solved.position;
                }
                Err(e) => {
                    errors.push(error(program, m, e.to_string(), hint(&e)));
                    continue;
                }
            },
        }
        converted.end = previous;
        moves.push(converted);
    }
    if let Some((first, count)) = poles {
        warnings.push(pole_warning(k, &first, count));
    }
    if !errors.is_empty() {
        return Err(ProgramErrors {
            errors,
            suppressed: 0,
        });
    }
    Ok(Program {
        start: Position::default(),
        moves,
        warnings,
        ..program.clone()
    })
}

/// The tool point and axis a cutter-location move asks for; `None` for a dwell (the machine
/// stays). An arc, or a line without a tool axis, is an error at its line.
pub(crate) fn cl_target(program: &Program, m: &Move) -> Result<Option<ToolPose>, ProgramError> {
    match (m.motion, m.tool_axis) {
        (Motion::Dwell { .. }, _) => Ok(None),
        (Motion::Arc { .. }, _) => Err(error(
            program,
            m,
            "an arc in workpiece coordinates cannot be mapped to the machine's axes end point by end point".into(),
            "linearise arcs into GOTO points (with tool axes) first",
        )),
        (Motion::Linear, None) => Err(error(
            program,
            m,
            "expected a tool-axis vector for the five-axis machine, the move has none".into(),
            "program GOTO/x,y,z,i,j,k (the vector is modal after that)",
        )),
        (Motion::Linear, Some(axis)) => Ok(Some(ToolPose {
            point: Point3::from(m.end.linear),
            axis: Vector3::from(axis),
        })),
    }
}

fn pole_warning(k: &FiveAxisKinematics, first: &Move, count: usize) -> Warning {
    let [primary, _] = k.rotary_letters();
    Warning {
        span: first.span,
        message: format!(
            "line {}: the tool axis lies along the {primary} axis (the pole) here{}: {primary} is free there and kept where it was",
            first.span.line,
            if count > 1 {
                format!(" and in {} later moves", count - 1)
            } else {
                String::new()
            }
        ),
    }
}

/// A tool-tip program (X Y Z the tip in part coordinates, rotary words the axes' angles) as
/// joint coordinates: every move whose rotary axes turn (or whose arc does not map onto an arc
/// of the slides) becomes pieces whose tip path stays within `tolerance` (m) of the
/// programmed line or arc, timed so the tip moves on the part at the programmed feed.
pub fn tcp_to_machine(
    k: &FiveAxisKinematics,
    program: &Program,
    tolerance: f64,
) -> Result<Program, ProgramErrors> {
    let geometry = PathGeometry::of(program);
    let mut errors = Vec::new();
    let mut warnings = program.warnings.clone();
    let mut moves = Vec::with_capacity(program.moves.len());
    let place = |tip: &Point3<f64>, at: &Position| -> Result<Position, InverseError> {
        let linear = k.linear_axes(tip, at)?;
        Ok(Position {
            linear,
            rotary: at.rotary,
        })
    };
    let start = match place(&Point3::from(program.start.linear), &program.start) {
        Ok(p) => p,
        Err(e) => {
            let problem = format!("the program's start has no machine coordinates: {e}");
            return Err(ProgramErrors {
                errors: vec![ProgramError::new(program.source.clone(), None, problem)],
                suppressed: 0,
            });
        }
    };
    let mut at = program.start; // tool-tip coordinates
    let mut joints = start; // the machine's
    let mut tolerance_missed: Option<Move> = None;
    for (index, m) in program.moves.iter().enumerate() {
        let segment = geometry.segments[geometry.segment_of_move[index]];
        if let Motion::Dwell { .. } = m.motion {
            moves.push(Move {
                end: joints,
                ..m.clone()
            });
            continue;
        }
        let (from, to) = (at, m.end);
        let tip_at = |s: f64| -> (Point3<f64>, Position) {
            let mut p = from;
            p.linear = segment.point_at(s).into();
            for i in 0..3 {
                p.rotary[i] = from.rotary[i] + s * (to.rotary[i] - from.rotary[i]);
            }
            (Point3::from(p.linear), p)
        };
        let machine_at = |s: f64| -> Result<Position, InverseError> {
            let (tip, p) = tip_at(s);
            place(&tip, &p)
        };
        let mut motion = Motion::Linear;
        // Whether the move stays as programmed (its slides' path a copy of the tip's).
        let mut kept = false;
        let result = (|| -> Result<Vec<(f64, Position)>, InverseError> {
            let turns = (0..3).any(|i| from.rotary[i] != to.rotary[i]);
            let end = machine_at(1.0)?;
            if !turns {
                // The slides' map is affine: a line stays a line; an arc stays an arc where the
                // map moves its points without turning them.
                let offset = |p: &Position, s: f64| Vector3::from(p.linear) - tip_at(s).0.coords;
                match m.motion {
                    Motion::Linear => {
                        kept = true;
                        return Ok(vec![(1.0, end)]);
                    }
                    Motion::Arc { center, .. } => {
                        let shift = offset(&end, 1.0);
                        let middle = machine_at(0.5)?;
                        let rigid = [offset(&joints, 0.0), offset(&middle, 0.5)]
                            .iter()
                            .all(|o| (o - shift).norm() <= 1e-12);
                        if rigid {
                            motion = shifted_arc(m.motion, center, &shift);
                            kept = true;
                            return Ok(vec![(1.0, end)]);
                        }
                    }
                    Motion::Dwell { .. } => {}
                }
            }
            let sweep = match segment {
                crate::program::Segment::Arc { sweep, .. } => sweep.abs(),
                crate::program::Segment::Line { .. } => 0.0,
            };
            let turn = (0..3)
                .map(|i| (to.rotary[i] - from.rotary[i]).abs())
                .fold(0.0, f64::max);
            let count =
                ((turn.max(sweep) / START_PIECE_ANGLE).ceil() as usize).clamp(1, MAX_START_PIECES);
            let mut pieces = Pieces {
                kinematics: k,
                tip_at: &tip_at,
                machine_at: &machine_at,
                tolerance,
                out: Vec::new(),
                missed: false,
            };
            let mut a = (0.0, joints);
            for i in 1..=count {
                let s = i as f64 / count as f64;
                let b = (s, if i == count { end } else { machine_at(s)? });
                pieces.refine(a, b, 0)?;
                a = b;
            }
            if pieces.missed && tolerance_missed.is_none() {
                tolerance_missed = Some(m.clone());
            }
            Ok(pieces.out)
        })();
        let pieces = match result {
            Ok(pieces) => pieces,
            Err(e) => {
                errors.push(error(program, m, e.to_string(), hint(&e)));
                at = m.end;
                continue;
            }
        };
        for (_, p) in &pieces {
            let violations = k.travel_violations(p, None);
            if !violations.is_empty() {
                errors.push(error(
                    program,
                    m,
                    format!(
                        "with the tool tip held on the programmed path, {}",
                        violations.join("; ")
                    ),
                    "change the rotary angles or the part's set-up",
                ));
                break;
            }
        }
        let duration = move_duration(&from, m);
        let mut s0 = 0.0;
        let last = pieces.len() - 1;
        for (i, &(s, end)) in pieces.iter().enumerate() {
            let feed = match (m.feed, duration) {
                (Feed::Rapid, _) | (_, None) => m.feed,
                // The tip's time on the part, shared by the pieces as their share of it.
                (_, Some(t)) if !kept => Feed::InverseTime(t * (s - s0)),
                _ => m.feed,
            };
            let blend = if i == last {
                m.blend
            } else {
                Blend::Continuous {
                    tolerance: Some(tolerance),
                    naive_cam: None,
                }
            };
            moves.push(Move {
                motion,
                end,
                tool_axis: None,
                feed,
                blend,
                ..m.clone()
            });
            s0 = s;
        }
        joints = pieces[last].1;
        at = m.end;
    }
    if let Some(m) = tolerance_missed {
        warnings.push(Warning {
            span: m.span,
            message: format!(
                "line {}: the tool tip could not be held within {:.4} mm of the programmed path with the pieces cncsim allows",
                m.span.line,
                tolerance * 1e3
            ),
        });
    }
    if !errors.is_empty() {
        return Err(ProgramErrors {
            errors,
            suppressed: 0,
        });
    }
    Ok(Program {
        start,
        moves,
        warnings,
        ..program.clone()
    })
}

/// An arc moved by `shift` (its centre with it).
fn shifted_arc(motion: Motion, center: [f64; 3], shift: &Vector3<f64>) -> Motion {
    match motion {
        Motion::Arc {
            plane,
            clockwise,
            turns,
            ..
        } => Motion::Arc {
            center: std::array::from_fn(|i| center[i] + shift[i]),
            plane,
            clockwise,
            turns,
        },
        other => other,
    }
}

/// The joint-space pieces of one tool-tip move.
struct Pieces<'a, T, M> {
    kinematics: &'a FiveAxisKinematics,
    /// The programmed tip (part coordinates) and tool-tip position at a move parameter.
    tip_at: &'a T,
    /// Machine coordinates at a move parameter.
    machine_at: &'a M,
    tolerance: f64,
    /// (move parameter, machine coordinates) at each piece's end.
    out: Vec<(f64, Position)>,
    /// Whether the depth ran out somewhere before the tolerance held.
    missed: bool,
}

impl<T, M> Pieces<'_, T, M>
where
    T: Fn(f64) -> (Point3<f64>, Position),
    M: Fn(f64) -> Result<Position, InverseError>,
{
    /// Pushes the pieces after `a` up to `b` (move parameter, machine coordinates), halving
    /// where the tip of the joint-space straight piece strays from the programmed path by
    /// more than the tolerance at its quarter points.
    fn refine(
        &mut self,
        a: (f64, Position),
        b: (f64, Position),
        depth: u32,
    ) -> Result<(), InverseError> {
        let lerp = |t: f64| {
            let mut p = a.1;
            for i in 0..3 {
                p.linear[i] += t * (b.1.linear[i] - a.1.linear[i]);
                p.rotary[i] += t * (b.1.rotary[i] - a.1.rotary[i]);
            }
            p
        };
        let strays = [0.25, 0.5, 0.75].iter().any(|&t| {
            let programmed = (self.tip_at)(a.0 + t * (b.0 - a.0)).0;
            (self.kinematics.forward(&lerp(t)).point - programmed).norm() > self.tolerance
        });
        if !strays || depth >= MAX_DEPTH {
            self.missed |= strays;
            self.out.push(b);
            return Ok(());
        }
        let s = 0.5 * (a.0 + b.0);
        let middle = (s, (self.machine_at)(s)?);
        self.refine(a, middle, depth + 1)?;
        self.refine(middle, b, depth + 1)
    }
}
