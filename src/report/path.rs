//! Figures of the tool against the programmed path, tick by tick: the contour error (distance
//! of the actual tool point from the programmed path, not from the current setpoint) and the
//! commanded and actual path speed.

use crate::kinematics::tool_path::tool_in_program_frame;
use crate::kinematics::ProgramFrame;
use crate::machine::Machine;
use crate::plan::SetpointSample;
use crate::program::PathGeometry;
use nalgebra::{Point3, Vector3};

/// What the report needs to judge a tool point against the program.
#[derive(Debug, Clone, PartialEq)]
pub struct PathTracker {
    /// The programmed path of the tool point, one run of segments per move with motion: the
    /// program's own lines and arcs, or where rotary axes carry the tool, the forward
    /// kinematics of the programmed joint path.
    pub geometry: PathGeometry,
    /// The program frame: the tool point and velocity come relative to its carrier link.
    pub frame: ProgramFrame,
    /// Machine-axis index of program X, Y, Z where the machine has them.
    pub linear_axes: [Option<usize>; 3],
    /// The machine: where the setpoints put the tool (its forward kinematics).
    pub machine: Machine,
    /// Per machine axis, how far one unit of its coordinate can move the tool: 1 on a linear
    /// axis (m/m), the tool's largest distance from a rotary one (m/rad).
    pub tool_reach: Vec<f64>,
    /// Per program move, how far the corners at its ends let the setpoints leave the
    /// programmed path (m: G64 P and Q; 0 at exact stops); `None` where nothing bounds it.
    pub corner_tolerance: Vec<Option<f64>>,
    /// Whether rotary axes carry the tool: then the commanded path speed is the commanded
    /// tool point's, through the kinematics, not the X Y Z setpoints'.
    pub rotary_axes_carry_tool: bool,
}

/// Time step (s) of the central difference that gives the commanded tool point's velocity
/// where rotary axes carry the tool: its error (of order the step squared) and its round-off
/// are both far below a µm/s.
const COMMANDED_VELOCITY_STEP_S: f64 = 1e-4;

/// The derived figures of one tick (SI).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PathSample {
    /// Distance of the tool point from the programmed path (m); NaN where no path point is
    /// near.
    pub contour_error: f64,
    /// Path speed of the setpoints: the norm of the X, Y, Z axes' setpoint velocities (m/s).
    pub commanded_speed: f64,
    /// Speed of the tool point in the program frame (m/s).
    pub actual_speed: f64,
    /// The tool point in the program frame, and the programmed path's point nearest to it.
    pub tool: [f64; 3],
    /// The programmed path's point nearest the tool (program frame, m), if one was found.
    pub nearest: Option<[f64; 3]>,
    /// Distance of the commanded tool point (where the setpoints put it) from the programmed
    /// path (m): the planner's corner rounding, seen at the tool.
    pub commanded_deviation: f64,
    /// How far the axes' following errors can move the tool (m): the linear ones' sum, and
    /// each rotary one times its lever arm.
    pub tool_following_error: f64,
    /// How far the corners of the current move let the setpoints leave the path (m).
    pub corner_tolerance: Option<f64>,
}

impl PathTracker {
    /// The figures of a tick: the tool point and velocity (relative to the program frame's
    /// carrier link, in its frame), the setpoint and the axes' positions.
    pub fn sample(
        &self,
        tool_point: [f64; 3],
        tool_velocity: [f64; 3],
        setpoint: &SetpointSample,
        position: &[f64],
    ) -> PathSample {
        let tool = self.frame.program_point(&Point3::from(tool_point));
        let on_move = setpoint.segment as usize;
        let nearest = self.geometry.closest_to_move(&tool, on_move, 2);
        let mut v = Vector3::zeros();
        for (c, axis) in self.linear_axes.iter().enumerate() {
            if let Some(i) = axis {
                v[c] = setpoint.velocity[*i];
            }
        }
        let commanded_at = |dt: f64| {
            let q: Vec<f64> = (setpoint.position.iter().zip(&setpoint.velocity))
                .map(|(p, v)| p + v * dt)
                .collect();
            tool_in_program_frame(&self.machine, &self.frame, &q)
        };
        let commanded = commanded_at(0.0);
        let commanded_speed = if self.rotary_axes_carry_tool {
            let h = COMMANDED_VELOCITY_STEP_S;
            (commanded_at(h) - commanded_at(-h)).norm() / (2.0 * h)
        } else {
            v.norm()
        };
        let commanded_deviation = self
            .geometry
            .closest_to_move(&commanded, on_move, 2)
            .map_or(f64::NAN, |q| (commanded - q).norm());
        let tool_following_error = (setpoint.position.iter().zip(position))
            .zip(&self.tool_reach)
            .map(|((s, p), reach)| (s - p).abs() * reach)
            .sum();
        PathSample {
            contour_error: nearest.map_or(f64::NAN, |q| (tool - q).norm()),
            commanded_speed,
            actual_speed: self
                .frame
                .program_vector(&Vector3::from(tool_velocity))
                .norm(),
            tool: tool.into(),
            nearest: nearest.map(Into::into),
            commanded_deviation,
            tool_following_error,
            corner_tolerance: self.corner_tolerance.get(on_move).copied().flatten(),
        }
    }
}
