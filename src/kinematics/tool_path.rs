//! The programmed path of the tool point where rotary axes carry the tool (a swivel head, a
//! torch's tilt axis, a rotating mast). There the program's X Y Z are joint coordinates of the
//! slides (LinuxCNC's trivial kinematics), not where the tool point is: the point the tool
//! should follow is the forward kinematics of the programmed joint path. Comparing the actual
//! tool point with the programmed X Y Z instead would count the head's swing as error.

use super::{chain_joints, tool_in_link, AxisMap, ProgramFrame};
use crate::machine::{JointKind, Machine};
use crate::program::{Motion, PathGeometry, Position, Program, Segment};
use nalgebra::Point3;

/// Largest distance (m) of the straight pieces of the programmed tool path from the curve the
/// kinematics trace: below what a contour error worth reporting is.
pub const TOOL_PATH_TOLERANCE: f64 = 1e-7;
/// Most halvings of a piece of a move.
const MAX_DEPTH: u32 = 12;
/// Largest turn of a rotary axis (rad) and sweep of an arc within one starting piece, so that
/// a curve folding back on itself cannot hide from the midpoint test.
const START_PIECE_ANGLE: f64 = 2.0 * std::f64::consts::PI / 180.0;
/// Most starting pieces of one move.
const MAX_START_PIECES: usize = 4096;

/// Whether a turning joint moves the tool relative to the program frame's carrier: then the
/// programmed tool path is [`programmed_tool_path`], not the program's X Y Z.
pub fn rotary_axes_carry_tool(machine: &Machine, frame: &ProgramFrame) -> bool {
    let carrier_chain = chain_joints(machine, frame.carrier);
    chain_joints(machine, machine.tool_link)
        .iter()
        .filter(|j| !carrier_chain.contains(j))
        .any(|&j| machine.joints[j].kind == JointKind::Revolute)
}

/// The tool point in the program frame (machine coordinates along the program axes, m) at
/// joint coordinates `q`.
pub fn tool_in_program_frame(machine: &Machine, frame: &ProgramFrame, q: &[f64]) -> Point3<f64> {
    frame.program_point(&tool_in_link(machine, frame.carrier, q))
}

/// The path of the tool point in the program frame when the machine's axes follow `program`
/// (in machine coordinates; each move interpolated in joint space, the slides along its line
/// or arc and the rotary axes in proportion, as the interpolators move): straight pieces
/// within [`TOOL_PATH_TOLERANCE`] of it, one run of pieces per move.
pub fn programmed_tool_path(
    machine: &Machine,
    frame: &ProgramFrame,
    map: &AxisMap,
    program: &Program,
) -> PathGeometry {
    let slides = PathGeometry::of(program);
    let tool_at = |p: &Position| {
        let mut q = vec![0.0; map.axes()];
        map.machine_axes(p, &mut q);
        tool_in_program_frame(machine, frame, &q)
    };
    let mut at = program.start;
    let mut moves = Vec::with_capacity(program.moves.len());
    for (m, mv) in program.moves.iter().enumerate() {
        let mut points = Vec::new();
        if !matches!(mv.motion, Motion::Dwell { .. }) {
            let segment = slides.segments[slides.segment_of_move[m]];
            let (from, to) = (at, mv.end);
            let position = |s: f64| Position {
                linear: segment.point_at(s).into(),
                rotary: std::array::from_fn(|i| {
                    from.rotary[i] + s * (to.rotary[i] - from.rotary[i])
                }),
            };
            let turn = (0..3)
                .map(|i| (to.rotary[i] - from.rotary[i]).abs())
                .fold(0.0, f64::max);
            let sweep = match segment {
                Segment::Arc { sweep, .. } => sweep.abs(),
                Segment::Line { .. } => 0.0,
            };
            let pieces =
                ((turn.max(sweep) / START_PIECE_ANGLE).ceil() as usize).clamp(1, MAX_START_PIECES);
            let point = |s: f64| tool_at(&position(s));
            let mut start = point(0.0);
            for k in 1..=pieces {
                let (s0, s1) = ((k - 1) as f64 / pieces as f64, k as f64 / pieces as f64);
                let end = point(s1);
                refine(&point, (s0, start), (s1, end), 0, &mut points);
                start = end;
            }
        }
        moves.push(points);
        at = mv.end;
    }
    PathGeometry::from_pieces(tool_at(&program.start), &moves)
}

/// Pushes the points after `a` up to `b` of the curve `point`, halving where the midpoint
/// strays from the chord by more than the tolerance.
fn refine(
    point: &impl Fn(f64) -> Point3<f64>,
    a: (f64, Point3<f64>),
    b: (f64, Point3<f64>),
    depth: u32,
    out: &mut Vec<Point3<f64>>,
) {
    let s = 0.5 * (a.0 + b.0);
    let middle = point(s);
    let chord = Segment::Line {
        start: a.1,
        end: b.1,
    };
    if depth < MAX_DEPTH && chord.distance(&middle) > TOOL_PATH_TOLERANCE {
        refine(point, a, (s, middle), depth + 1, out);
        refine(point, (s, middle), b, depth + 1, out);
    } else {
        out.push(b.1);
    }
}
