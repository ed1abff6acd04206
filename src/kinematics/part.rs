//! Where the tool stands on the part: the frame a stock is laid out in (the program frame at
//! the program's start, carried from then on by the link that carries the workpiece) and the
//! tool's axis, for the cutting process and the nominal part.

use super::{link_poses, ProgramFrame};
use crate::machine::Machine;
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// The stock's frame on the part and the tool's axis on the tool, fixed for a run.
#[derive(Debug, Clone, PartialEq)]
pub struct PartPlacement {
    /// The stock's frame (program axes at the program's start, origin at program zero: the
    /// work offset's point) in the frame of the link carrying the workpiece.
    pub stock_in_part: Isometry3<f64>,
    /// Unit vector along the tool's axis (tip toward spindle) in the tool link's frame: the
    /// direction program +Z has there with every axis at its home (ISO 841: +Z points from the
    /// part toward the tool).
    pub tool_axis: Vector3<f64>,
}

impl PartPlacement {
    /// The placement on `machine` whose program frame is `frame`, with program zero at
    /// `work_offset` in machine coordinates (m), the program starting at joint coordinates
    /// `start`.
    pub fn new(
        machine: &Machine,
        frame: &ProgramFrame,
        work_offset: [f64; 3],
        start: &[f64],
    ) -> PartPlacement {
        let home: Vec<f64> = machine.axes.iter().map(|a| a.drive.home).collect();
        let at_home = link_poses(machine, &home);
        let program_z = at_home[frame.carrier].rotation * frame.directions.column(2).into_owned();
        let tool_axis = at_home[machine.tool_link]
            .rotation
            .inverse_transform_vector(&program_z)
            .normalize();
        let poses = link_poses(machine, start);
        let carrier_from_program =
            program_to_carrier(frame) * Translation3::from(Vector3::from(work_offset));
        let stock_in_part =
            poses[machine.workpiece_link].inverse() * poses[frame.carrier] * carrier_from_program;
        PartPlacement {
            stock_in_part,
            tool_axis,
        }
    }

    /// The tool point and axis in the stock's frame at joint coordinates `q` (m, unit vector).
    pub fn tool_at(&self, machine: &Machine, q: &[f64]) -> (Point3<f64>, Vector3<f64>) {
        let poses = link_poses(machine, q);
        let tool = poses[machine.tool_link];
        let part = poses[machine.workpiece_link] * self.stock_in_part;
        let point = tool * Point3::from(machine.tool.offset_m);
        let axis = tool.rotation * self.tool_axis;
        (
            part.inverse_transform_point(&point),
            part.inverse_transform_vector(&axis),
        )
    }
}

/// The program frame as an isometry into its carrier's frame. Its directions are at right
/// angles to within round-off; the nearest rotation stands for them.
fn program_to_carrier(frame: &ProgramFrame) -> Isometry3<f64> {
    let m: Matrix3<f64> = frame.directions;
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&m));
    Isometry3::from_parts(Translation3::from(frame.origin.coords), rotation)
}
