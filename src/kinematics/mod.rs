//! Machine kinematics: how program coordinates become machine-axis coordinates.
//!
//! A Cartesian machine (the XYZ table) maps each program axis letter to the machine axis of the
//! same name one to one (LinuxCNC's "trivial kinematics"); five-axis machines add inverse
//! kinematics here: the A-C table's closed form ([`ac_table`]) and any chain's
//! ([`five_axis`]), which put cutter-location data and tool-tip programs on the axes
//! ([`tool_tip`]).

pub mod ac_table;
pub mod five_axis;
mod frame;
mod part;
pub mod tool_path;
pub mod tool_tip;

pub use frame::{carrier_link, chain_joints, ProgramFrame, ORTHOGONALITY_TOLERANCE};
pub use part::PartPlacement;

pub use ac_table::{
    AcAxes, AcAxis, AcInverseError, AcSolution, AcTableKinematics, AcTopologyError, Branch,
    CutterLocation, RotarySolutions, TravelViolation,
};

use crate::machine::Machine;
use crate::program::Position;

/// Where each machine axis takes its coordinate from in a program [`Position`] (in machine
/// coordinates: a work offset is the program reader's), and how: joint = home + sign ×
/// coordinate. On a plain machine (sign +1, home 0) the program's numbers are the joints'.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisMap {
    /// For machine axis i: (linear?, index into `Position::linear` or `Position::rotary`).
    sources: Vec<(bool, usize)>,
    /// For machine axis i: (sign, home), where not (1, 0).
    affine: Vec<Option<(f64, f64)>>,
}

/// A machine axis whose name is not a program axis letter (x, y, z, a, b, c); holds the name.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
#[error("machine axis '{0}' has no program coordinate (expected one of x, y, z, a, b, c)")]
pub struct UnknownAxis(pub String);

impl AxisMap {
    /// Trivial kinematics: machine axis `x` takes program X, and so on, each with its drive's
    /// sign and home.
    pub fn new(machine: &Machine) -> Result<AxisMap, UnknownAxis> {
        let mut map = Self::joint_coordinates(machine)?;
        for (affine, axis) in map.affine.iter_mut().zip(&machine.axes) {
            let (sign, home) = (f64::from(axis.drive.sign), axis.drive.home);
            if sign != 1.0 || home != 0.0 {
                *affine = Some((sign, home));
            }
        }
        Ok(map)
    }

    /// Program coordinates that are joint coordinates (the A-C table's inverse kinematics
    /// gives joint coordinates).
    pub fn joint_coordinates(machine: &Machine) -> Result<AxisMap, UnknownAxis> {
        let sources: Vec<(bool, usize)> = machine
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
        let affine = vec![None; sources.len()];
        Ok(AxisMap { sources, affine })
    }

    /// A map from explicit sources: (linear?, index) per machine axis.
    #[cfg(test)]
    pub(crate) fn from_sources(sources: Vec<(bool, usize)>) -> AxisMap {
        let affine = vec![None; sources.len()];
        AxisMap { sources, affine }
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

    /// Number of machine axes.
    pub fn axes(&self) -> usize {
        self.sources.len()
    }

    /// Machine-axis coordinates of a program position.
    pub fn machine_axes(&self, p: &Position, out: &mut [f64]) {
        for ((o, &(linear, i)), affine) in out.iter_mut().zip(&self.sources).zip(&self.affine) {
            let v = if linear { p.linear[i] } else { p.rotary[i] };
            *o = match affine {
                None => v,
                Some((sign, zero)) => zero + sign * v,
            };
        }
    }

    /// Machine-axis components of a program-frame vector (a velocity, a direction).
    pub fn machine_vector(&self, v: &Position, out: &mut [f64]) {
        for ((o, &(linear, i)), affine) in out.iter_mut().zip(&self.sources).zip(&self.affine) {
            let c = if linear { v.linear[i] } else { v.rotary[i] };
            *o = match affine {
                Some((sign, _)) if *sign < 0.0 => -c,
                _ => c,
            };
        }
    }

    /// An arc of the program in the plane of machine axes `plane` = (i, j): its centre on
    /// those axes and its sense there (a mirrored axis turns clockwise into anticlockwise).
    pub fn machine_arc(
        &self,
        plane: [usize; 2],
        center: [f64; 2],
        clockwise: bool,
    ) -> ([f64; 2], bool) {
        let mut mirrored = false;
        let mut out = center;
        for (o, &axis) in out.iter_mut().zip(&plane) {
            if let Some((sign, zero)) = self.affine[axis] {
                *o = zero + sign * *o;
                mirrored ^= sign < 0.0;
            }
        }
        (out, clockwise ^ mirrored)
    }

    /// Program position of machine-axis coordinates (axes the machine lacks stay at zero).
    pub fn program_position(&self, q: &[f64]) -> Position {
        let mut p = Position::default();
        for ((&v, &(linear, i)), affine) in q.iter().zip(&self.sources).zip(&self.affine) {
            let v = match affine {
                None => v,
                Some((sign, zero)) => sign * (v - zero),
            };
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
/// the forward kinematics of the URDF tree, `<mimic>` followers where their leaders put them.
pub fn link_poses(machine: &Machine, q: &[f64]) -> Vec<nalgebra::Isometry3<f64>> {
    let joint_value = machine.joint_coordinates(q);
    let mut poses = vec![nalgebra::Isometry3::identity(); machine.links.len()];
    for (j, joint) in machine.joints.iter().enumerate() {
        poses[joint.child] = poses[joint.parent] * joint.origin * joint.motion(joint_value[j]);
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
    tool_in_link(machine, machine.workpiece_link, q)
}

/// Tool point in the frame of `link` for joint coordinates `q`.
pub fn tool_in_link(machine: &Machine, link: usize, q: &[f64]) -> nalgebra::Point3<f64> {
    let poses = link_poses(machine, q);
    let tool = poses[machine.tool_link] * nalgebra::Point3::from(machine.tool.offset_m);
    if link == machine.root {
        // The base's frame is the world's.
        return tool;
    }
    poses[link].inverse_transform_point(&tool)
}
