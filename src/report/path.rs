//! Figures of the tool against the programmed path, tick by tick: the contour error (distance
//! of the actual tool point from the programmed path, not from the current setpoint) and the
//! commanded and actual path speed.

use crate::kinematics::ProgramFrame;
use crate::program::PathGeometry;
use nalgebra::{Point3, Vector3};

/// What the report needs to judge a tool point against the program.
#[derive(Debug, Clone, PartialEq)]
pub struct PathTracker {
    /// The programmed path, one segment per move with motion.
    pub geometry: PathGeometry,
    /// The program frame: the tool point and velocity come relative to its carrier link.
    pub frame: ProgramFrame,
    /// Machine-axis index of program X, Y, Z where the machine has them.
    pub linear_axes: [Option<usize>; 3],
}

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
}

impl PathTracker {
    /// The figures of a tick: the tool point and velocity (relative to the program frame's
    /// carrier link, in its frame) of program move `segment`, and the setpoint velocity per
    /// machine axis.
    pub fn sample(
        &self,
        tool_point: [f64; 3],
        tool_velocity: [f64; 3],
        segment: u32,
        setpoint_velocity: &[f64],
    ) -> PathSample {
        let tool = self.frame.program_point(&Point3::from(tool_point));
        let near = self
            .geometry
            .segment_of_move
            .get(segment as usize)
            .copied()
            .unwrap_or(0);
        let nearest = self.geometry.closest_near(&tool, near, 2);
        let mut v = Vector3::zeros();
        for (c, axis) in self.linear_axes.iter().enumerate() {
            if let Some(i) = axis {
                v[c] = setpoint_velocity[*i];
            }
        }
        PathSample {
            contour_error: nearest.map_or(f64::NAN, |q| (tool - q).norm()),
            commanded_speed: v.norm(),
            actual_speed: self
                .frame
                .program_vector(&Vector3::from(tool_velocity))
                .norm(),
            tool: tool.into(),
            nearest: nearest.map(Into::into),
        }
    }
}
