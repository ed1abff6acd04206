//! Machine kinematics: how program coordinates become machine-axis coordinates.
//!
//! A Cartesian machine (the XYZ table) maps each program axis letter to the machine axis of the
//! same name one to one (LinuxCNC's "trivial kinematics"); the 5-axis table adds inverse
//! kinematics here.

pub mod ac_table;

pub use ac_table::{
    AcAxes, AcAxis, AcInverseError, AcSolution, AcTableKinematics, AcTopologyError, Branch,
    CutterLocation, RotarySolutions, TravelViolation,
};

use crate::machine::Machine;
use crate::program::Position;

/// Where each machine axis takes its coordinate from in a program [`Position`].
#[derive(Debug, Clone, PartialEq)]
pub struct AxisMap {
    /// For machine axis i: (linear?, index into `Position::linear` or `Position::rotary`).
    sources: Vec<(bool, usize)>,
}

#[derive(Debug, Clone, thiserror::Error, PartialEq)]
#[error("machine axis '{0}' has no program coordinate (expected one of x, y, z, a, b, c)")]
pub struct UnknownAxis(pub String);

impl AxisMap {
    /// Trivial kinematics: machine axis `x` takes program X, and so on.
    pub fn cartesian(machine: &Machine) -> Result<AxisMap, UnknownAxis> {
        let sources = machine
            .axes
            .iter()
            .map(|a| match a.name.as_str() {
                "x" => Ok((true, 0)),
                "y" => Ok((true, 1)),
                "z" => Ok((true, 2)),
                "a" => Ok((false, 0)),
                "b" => Ok((false, 1)),
                "c" => Ok((false, 2)),
                other => Err(UnknownAxis(other.to_string())),
            })
            .collect::<Result<_, _>>()?;
        Ok(AxisMap { sources })
    }

    /// A map from explicit sources: (linear?, index) per machine axis.
    #[cfg(test)]
    pub(crate) fn from_sources(sources: Vec<(bool, usize)>) -> AxisMap {
        AxisMap { sources }
    }

    /// The machine axis fed by a program coordinate (linear index 0–2 = X, Y, Z; rotary 0–2 =
    /// A, B, C), if the machine has one.
    pub fn machine_axis(&self, linear: bool, index: usize) -> Option<usize> {
        self.sources.iter().position(|&s| s == (linear, index))
    }

    /// Whether machine axis `i` takes a rotary program coordinate.
    pub fn is_rotary(&self, i: usize) -> bool {
        !self.sources[i].0
    }

    pub fn axes(&self) -> usize {
        self.sources.len()
    }

    /// Machine-axis coordinates of a program position.
    pub fn machine_axes(&self, p: &Position, out: &mut [f64]) {
        for (o, &(linear, i)) in out.iter_mut().zip(&self.sources) {
            *o = if linear { p.linear[i] } else { p.rotary[i] };
        }
    }

    /// Program position of machine-axis coordinates (axes the machine lacks stay at zero).
    pub fn program_position(&self, q: &[f64]) -> Position {
        let mut p = Position::default();
        for (&v, &(linear, i)) in q.iter().zip(&self.sources) {
            if linear {
                p.linear[i] = v;
            } else {
                p.rotary[i] = v;
            }
        }
        p
    }
}

/// World pose of every link for joint coordinates `q` (one per machine axis, in axis order):
/// the forward kinematics of the URDF tree.
pub fn link_poses(machine: &Machine, q: &[f64]) -> Vec<nalgebra::Isometry3<f64>> {
    use crate::machine::JointKind;
    use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion};
    let mut joint_value = vec![0.0; machine.joints.len()];
    for (axis, &v) in machine.axes.iter().zip(q) {
        joint_value[axis.joint] = v;
    }
    let mut poses = vec![Isometry3::identity(); machine.links.len()];
    for (j, joint) in machine.joints.iter().enumerate() {
        let motion = match joint.kind {
            JointKind::Fixed => Isometry3::identity(),
            JointKind::Prismatic => Isometry3::from_parts(
                Translation3::from(joint.axis * joint_value[j]),
                UnitQuaternion::identity(),
            ),
            JointKind::Revolute => Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&Unit::new_normalize(joint.axis), joint_value[j]),
            ),
        };
        poses[joint.child] = poses[joint.parent] * joint.origin * motion;
    }
    poses
}

/// Tool point in the machine base frame for joint coordinates `q`.
pub fn tool_point(machine: &Machine, q: &[f64]) -> nalgebra::Point3<f64> {
    link_poses(machine, q)[machine.tool_link] * nalgebra::Point3::from(machine.tool.offset_m)
}

/// Tool point in the workpiece link's frame for joint coordinates `q`: where the tool is on
/// the part, whichever of them the axes move.
pub fn tool_in_workpiece(machine: &Machine, q: &[f64]) -> nalgebra::Point3<f64> {
    let poses = link_poses(machine, q);
    let tool = poses[machine.tool_link] * nalgebra::Point3::from(machine.tool.offset_m);
    poses[machine.workpiece_link].inverse_transform_point(&tool)
}
